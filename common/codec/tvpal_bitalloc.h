/* tvpal_bitalloc.h: allocation of an index's bits among DCT coefficients.
 *
 * Greedy marginal return under the high-rate model D_u(b) = var_u * 4^-b
 * (each extra bit quarters a coefficient's distortion): each of the
 * total_bits goes, one at a time, to the coefficient whose distortion it
 * lowers most, i.e. the largest var_u / 4^bits_u (ties: lowest u, the
 * lower frequency).  Coefficients with zero variance get no bits; so if every
 * variance is zero no bit is given (sum 0), otherwise the bits sum to
 * total_bits.  No coefficient gets more than 8 bits.
 */
#ifndef TVPAL_BITALLOC_H
#define TVPAL_BITALLOC_H

#include <stdint.h>

/* var[0..n-1] >= 0 (n <= 16), total_bits <= 8; writes bits[0..n-1].
 * Returns the number of bits given. */
unsigned tvpal_bitalloc_variance(const double *var, unsigned n,
                                 unsigned total_bits, uint8_t *bits);

#endif
