/* tvpal_swcode.h: encoding of one slice-window (paper, section III.C).
 *
 * Input: the L time samples (L = window length, 1..16) of each of the nvox
 * voxels of one slice.  Output: one 8-bit index per voxel and the decoder
 * table: table[j * 256 + i] is the value of index i at timestep j of the
 * window, i.e. the mean original value at timestep j of the voxels holding
 * index i.  An index no voxel holds gets the inverse DCT of its dequantized
 * coefficients, so every table entry is a sensible value.
 *
 * Steps: orthonormal DCT-II along time per voxel; mean and variance of each
 * coefficient over the slice; 8 bits allocated by variance; one Lloyd-Max
 * quantizer per coefficient that got bits (a coefficient with 0 bits is
 * reconstructed by its slice mean); the codes concatenated into the index,
 * coefficient 0 in the high bits.  Deterministic.
 */
#ifndef TVPAL_SWCODE_H
#define TVPAL_SWCODE_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_dct.h"

#define TVPAL_INDEX_BITS 8
#define TVPAL_TABLE_ENTRIES 256

/* What the encoder decided for one slice-window (informational). */
struct tvpal_swinfo {
    uint8_t bits[TVPAL_NMAX];   /* bits per coefficient, sum 8 or 0 */
    unsigned used;              /* distinct indices held by voxels */
    uint64_t missing;           /* NaN samples (missing values) */
    uint64_t dropped;           /* present samples coded as missing */
};

/* Workspace for slices of up to max_vox voxels and windows up to max_len.
 * One per thread; owned by the caller; free(NULL) is a no-op. */
struct tvpal_swenc;
int tvpal_swenc_create(struct tvpal_swenc **out, size_t max_vox,
                       unsigned max_len);
void tvpal_swenc_free(struct tvpal_swenc *e);

/* samples[j * nvox + v]: sample j (< len) of voxel v (< nvox); finite, or
 * NaN for a missing value (|value| <= TVPAL_VALUE_MAX otherwise).
 * Writes idx[0..nvox-1] and table[0..len*256-1]; info may be NULL.
 *
 * Missing values: table[j * 256 + idx[v]] is NaN exactly where sample j
 * of voxel v is NaN, and finite elsewhere, except in a slice-window whose
 * voxels show more than 128 different patterns of missing timesteps
 * (possible for len >= 8): the voxels of the rarest patterns are then
 * missing throughout the window, and info->dropped counts the present
 * samples lost so.  The voxels with no missing sample are coded as a
 * slice of their own (the indices they leave free go to the others; when
 * too few are free, their least used indices are merged).  A slice that
 * is missing throughout gets a table of NaN.
 *
 * Returns 0, TVPAL_E_INVAL (sizes beyond the workspace) or TVPAL_E_NOMEM
 * (the missing-value workspace, allocated on the first slice-window that
 * needs it). */
int tvpal_swenc_encode(struct tvpal_swenc *e, const float *samples,
                       size_t nvox, unsigned len, uint8_t *idx, float *table,
                       struct tvpal_swinfo *info);

/* --refine: after the DCT/Lloyd-Max code, up to `iterations` (0..
 * TVPAL_REFINE_MAX) of generalized Lloyd (k-means) on the voxels' time
 * series, seeded with the 256 codewords; stops early when no voxel moves.
 * It starts from k-means++ seeds too (drawn from an even sample of the
 * voxels): both starts run two iterations, and the one that errs less
 * then goes on alone (so the code errs less than the DCT start's after
 * two; tvpal_swenc_set_kpp(e, 0) asks for the DCT start alone, for
 * comparisons); tvpal_swenc_kpp_kept counts the slice-windows where the
 * k-means++ start won.  The decoder format is unchanged.  Allocates its scratch here,
 * not per slice. */
#define TVPAL_REFINE_MAX 64
int tvpal_swenc_set_refine(struct tvpal_swenc *e, unsigned iterations);
void tvpal_swenc_set_kpp(struct tvpal_swenc *e, int on);
uint64_t tvpal_swenc_kpp_kept(const struct tvpal_swenc *e);

/* The paper's naive variant, as a floor for comparisons: uniform
 * quantizers instead of Lloyd-Max, and decoder tables holding the inverse
 * DCT of the dequantized coefficients instead of the per-index means. */
void tvpal_swenc_set_naive(struct tvpal_swenc *e, int naive);

/* --transform klt: also code each slice-window with its Karhunen-Loeve
 * transform (principal components of its voxels' time series, from the
 * temporal covariance via LAPACK) and keep whichever of the DCT and KLT
 * codes errs less, so it is never worse than the DCT; degenerate (constant,
 * rank-deficient) covariances work.  TVPAL_E_SYS when built without
 * LAPACK. */
int tvpal_swenc_set_klt(struct tvpal_swenc *e, int klt);

/* --alloc greedy-mse: also allocate the 8 bits by the measured error of
 * each coefficient's Lloyd-Max quantizer at every bit count (greedy
 * marginal return on measured distortions) and keep that code where it
 * errs less than the variance rule's. */
int tvpal_swenc_set_alloc_mse(struct tvpal_swenc *e, int on);

/* Squared error (summed over voxels and timesteps) before refinement and
 * after each iteration of the last encode, from the start kept (the DCT
 * code, or the k-means++ seeds); returns the count (0 without
 * refinement). */
unsigned tvpal_swenc_refine_sse(const struct tvpal_swenc *e, double *sse);

#endif
