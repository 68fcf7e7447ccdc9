/* tvpal_groupauto.h: palette group sizes chosen by measurement
 * (tvpal-encode --group auto, TVPAL_PARAM_GROUP 0; FORMAT.md 5.1).
 *
 * A palette group of G slices shares one decoder table per window: the
 * tables cost 1/G of the bits, and one quantizer fitted to G slices errs
 * more than G fitted to one each.  Which G pays depends on the slice size
 * (the tables of 64^2 slices are a third of the bits, of 512^2 slices
 * under 1%) and on how alike neighbouring slices are, so it is measured:
 * sample group-windows of the axis (spread along the axis and over the
 * series), each coded as the encoder would store it with every candidate
 * G (1, 2, 4, ... up to TVPAL_GROUPAUTO_MAX, capped as tvpal_engine_group
 * caps), give each G's bits R and squared error D per voxel-step, and the
 * G with the least D + lambda R is taken, lambda = 2 ln 2 D(1): the slope
 * of a quantizer's error against its rate (6.02 dB per bit) at the
 * sample's own error.  The measured slope of the window-size curve is
 * steeper (on viscous fingers, N = 4 to 8 costs 3.3 D per bit saved), so
 * a G taken by this rule stores fewer bits than a larger N would at the
 * same error.
 *
 * The result depends only on the values, the parameters and this rule:
 * not on threads, ranks or the memory plan (the sample's sums are added
 * in a fixed order).
 *
 * Library code: error convention of tvpal_error.h; nothing prints.
 */
#ifndef TVPAL_GROUPAUTO_H
#define TVPAL_GROUPAUTO_H

#include "tvpal_engine.h"
#include "tvpal_error.h"
#include "tvpal_pool.h"

#include <stdint.h>

/* The largest G tried. */
#define TVPAL_GROUPAUTO_MAX TVPAL_ENGINE_GROUP_AUTO_MAX
/* Voxel-steps sampled per candidate at most (an eighth of the axis' at
 * most): the sample's floats, and the coding work per candidate. */
#define TVPAL_GROUPAUTO_SAMPLE (1u << 22)

/* Reads step t's box of voxels lo[a] .. lo[a] + n[a] - 1, converted to
 * float32 as the encoder converts its steps (missing values NaN), x
 * fastest, into dst.  0, or a negative TVPAL_E_* code with diag set. */
struct tvpal_groupauto_reader {
    int (*read)(void *ctx, uint32_t t, const uint32_t lo[3],
                const uint32_t n[3], float *dst, struct tvpal_diag *diag);
    void *ctx;
};

/* What was measured of each candidate, for tests and reports. */
struct tvpal_groupauto_report {
    uint32_t ncand;               /* candidates tried (0: none needed) */
    uint32_t G[8];
    double bpv[8];                /* stored bits per voxel-step */
    double mse[8];                /* squared error per present value */
    uint32_t windows;             /* sample group-windows of each */
    uint32_t slices, steps;       /* slices per sample window, its steps */
};

/* The group size of axis a for the job p (its window, schedule, table
 * format, coding and coder choices; its group fields are ignored) into
 * *G, measured on the values rd reads, coded on pool's threads, holding
 * at most mem_limit bytes (0: no limit; at most about 4 * 2^22 bytes of
 * sample and one group-window and a coder's workspace per thread).  *G
 * is 1 without reading where no G >= 2 is possible (tvpal_engine_group:
 * 512^2 slices, one slice) or the limit leaves no room for the measure.
 * rep: optional.  0; the reader's code; TVPAL_E_NOMEM (diag says of
 * what). */
int tvpal_groupauto_choose(const struct tvpal_engine_params *p, unsigned a,
                           uint64_t mem_limit, struct tvpal_pool *pool,
                           const struct tvpal_groupauto_reader *rd,
                           uint32_t *G, struct tvpal_groupauto_report *rep,
                           struct tvpal_diag *diag);

#endif
