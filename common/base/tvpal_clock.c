/* tvpal_clock.c: see tvpal_clock.h. */
#include "tvpal_clock.h"

#include <time.h>

double tvpal_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
