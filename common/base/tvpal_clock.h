/* tvpal_clock.h: the one clock of the tree, for phase timings and rates.
 * Seconds on CLOCK_MONOTONIC (never jumps with the wall clock); only
 * differences are meaningful. */
#ifndef TVPAL_CLOCK_H
#define TVPAL_CLOCK_H

double tvpal_now(void);

#endif
