/* tvpal_quant.h: scalar quantizers for DCT coefficients: Lloyd-Max fitted to
 * one slice-window's values, and the uniform quantizer it must never lose to.
 *
 * Lloyd-Max (Lloyd 1982, Max 1960) alternates the nearest-neighbour condition
 * (thresholds halfway between levels) and the centroid condition (each level
 * the mean of its cell).  Textbook versions break on real slices; this one:
 *  - sorts the samples once (radix sort) and keeps prefix sums, so each
 *    iteration costs O(levels * log n) whatever n is, and cell means and
 *    distortions are exact up to rounding;
 *  - fits exactly (MSE 0) when there are no more distinct values than levels,
 *    which covers constant and two-valued slices;
 *  - re-seeds an empty cell by splitting the cell of largest distortion at its
 *    centroid, a move that can only lower the distortion;
 *  - runs from two starts (uniform over [min, max], and equal-count quantiles)
 *    and keeps the lowest distortion seen, including the uniform start itself,
 *    so the result is never worse than the uniform quantizer with as many
 *    levels (quantile starts alone overfit: 256 levels on a 64x64 slice end up
 *    several dB below uniform);
 *  - is deterministic: same samples, same levels, bit for bit.
 * Arithmetic is in double on samples centred on their mean, so prefix sums do
 * not cancel catastrophically for data with a large offset.
 */
#ifndef TVPAL_QUANT_H
#define TVPAL_QUANT_H

#include <stddef.h>
#include <stdint.h>

#define TVPAL_LEVELS_MAX 256

struct tvpal_quant {
    unsigned nlevels;                       /* 1..256 */
    double level[TVPAL_LEVELS_MAX];         /* non-decreasing */
    double thresh[TVPAL_LEVELS_MAX - 1];    /* thresh[i] = (level[i]+level[i+1])/2 */
    double mse;                             /* on the fitted samples */
    size_t count[TVPAL_LEVELS_MAX];         /* samples per cell */
};

/* Fitting workspace for up to `capacity` samples.  Owned by the caller; one
 * per thread.  tvpal_quantws_free(NULL) is a no-op. */
struct tvpal_quantws;
int tvpal_quantws_create(struct tvpal_quantws **out, size_t capacity);
void tvpal_quantws_free(struct tvpal_quantws *ws);

/* Sorts x[0..n-1] (n <= capacity, finite values) into the workspace.  Must
 * precede the fit functions below, which all use the loaded samples. */
int tvpal_quantws_load(struct tvpal_quantws *ws, const float *x, size_t n);

/* Number of distinct values among the loaded samples. */
size_t tvpal_quantws_distinct(const struct tvpal_quantws *ws);

/* Lloyd-Max quantizer with at most `levels` (1..256) levels.  n = 0 gives one
 * level at 0 and mse 0.  Never fails after a successful load. */
void tvpal_quant_fit_lloyd(struct tvpal_quantws *ws, unsigned levels,
                           struct tvpal_quant *q);

/* Uniform quantizer: `levels` cells of equal width over [min, max] of the
 * loaded samples, each level the cell midpoint (the baseline). */
void tvpal_quant_fit_uniform(struct tvpal_quantws *ws, unsigned levels,
                             struct tvpal_quant *q);

/* Lloyd iterations from given starting levels (sorted ascending, `levels`
 * of them); for tests of the init strategies.  Result as fit_lloyd. */
void tvpal_quant_fit_from(struct tvpal_quantws *ws, const double *start,
                          unsigned levels, struct tvpal_quant *q);

/* Cell index of v: the number of thresholds <= v (0..nlevels-1). */
unsigned tvpal_quant_code(const struct tvpal_quant *q, double v);

/* MSE of q over x[0..n-1], evaluated directly (reference for tests). */
double tvpal_quant_mse(const struct tvpal_quant *q, const float *x, size_t n);

/* Fast coder: thresholds as float, padded with +inf to 2^bits - 1 entries so
 * that a branch-free binary search of `bits` steps finds the code. */
struct tvpal_qcoder {
    unsigned bits;
    float th[TVPAL_LEVELS_MAX];
};
void tvpal_qcoder_init(struct tvpal_qcoder *c, const struct tvpal_quant *q,
                       unsigned bits);

static inline unsigned tvpal_qcoder_code(const struct tvpal_qcoder *c, float v)
{
    unsigned code = 0;
    for (unsigned step = (1u << c->bits) >> 1; step; step >>= 1)
        code += (v >= c->th[code + step - 1]) ? step : 0;
    return code;
}

/* Appends the codes of x[0..n-1] to the indices: idx[v] = idx[v] << bits |
 * code(x[v]), the same codes as tvpal_qcoder_code.  The high code bits come
 * from counting thresholds (vectorized), the rest from the binary search
 * in interleaved blocks so that the dependent comparisons of different
 * voxels overlap. */
void tvpal_qcoder_pack(const struct tvpal_qcoder *c, const float *x, size_t n,
                       uint8_t *idx);

#endif
