/* tvpal_bitalloc.c: greedy variance-based bit allocation (Gersho & Gray,
 * "Vector Quantization and Signal Compression", 8.4: greedy integer
 * allocation). */
#include "tvpal_bitalloc.h"

#include <math.h>

unsigned tvpal_bitalloc_variance(const double *var, unsigned n,
                                 unsigned total_bits, uint8_t *bits)
{
    unsigned given = 0;
    for (unsigned u = 0; u < n; u++)
        bits[u] = 0;
    for (unsigned k = 0; k < total_bits; k++) {
        unsigned best = n;
        double gain = 0.0;
        for (unsigned u = 0; u < n; u++) {
            if (!(var[u] > 0.0) || bits[u] >= 8)
                continue;
            double g = ldexp(var[u], -2 * (int)bits[u]);
            if (g > gain) {
                gain = g;
                best = u;
            }
        }
        if (best == n)
            break;
        bits[best]++;
        given++;
    }
    return given;
}
