/* tvpal_dct.h: orthonormal DCT-II along time, window lengths 1..TVPAL_NMAX.
 *
 * C(u) = a(u) * sum_{x=0}^{n-1} f(x) cos((2x+1) u pi / 2n),
 * a(0) = sqrt(1/n), a(u>0) = sqrt(2/n)      (paper, section III.C).
 * The transform is orthonormal, so the inverse is the transpose and energy
 * (sum of squares) is preserved: quantization error in the coefficients equals
 * the error in the time samples.
 */
#ifndef TVPAL_DCT_H
#define TVPAL_DCT_H

#include <stddef.h>

/* The longest window: 2N - 1 for N = 16, the joined schedule's first
 * windows (TVPAL_SCHEDULE_LEN_MAX, common/format/tvpal_schedule.h). */
#define TVPAL_NMAX 31

/* Basis matrix for length n (1 <= n <= TVPAL_NMAX), row u = basis function u:
 * m[u * n + x] = a(u) cos((2x+1) u pi / 2n).  Tables are computed in double
 * once per process and are read-only afterwards; returns NULL for bad n. */
const double *tvpal_dct_matrix(unsigned n);
const float *tvpal_dct_matrix_f(unsigned n);

/* Forward transform of `count` independent series stored time-major:
 * in[x * stride + v] is sample x of series v (v < count), and the coefficients
 * go to out[u * stride + v].  in and out must not overlap.  Float arithmetic
 * with the float matrix (relative error ~1e-6 of the series' magnitude). */
void tvpal_dct_forward_f(unsigned n, const float *in, float *out,
                         size_t count, size_t stride);

/* The same product with any basis m (row u = basis function u, n x n):
 * out[u * stride + v] = sum_x m[u * n + x] in[x * stride + v]. */
void tvpal_basis_forward_f(const float *m, unsigned n, const float *in,
                           float *out, size_t count, size_t stride);

/* Double-precision single-series forward and inverse (reference use). */
void tvpal_dct_forward(unsigned n, const double *in, double *out);
void tvpal_dct_inverse(unsigned n, const double *in, double *out);

#endif
