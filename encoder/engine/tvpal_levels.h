/* tvpal_levels.h: levels of detail (FORMAT.md 3.3), the 2x2x2 block means.
 *
 * Level k (1..L) is the 2x2x2 average of level k - 1 (level 0: the source
 * as encoded), each mean over the present voxels of its block (a block all
 * missing is missing: NaN), dims ceil(d / 2) per axis, over the same box as
 * level 0.  Each block's values are added in double, plane by plane, row by
 * row, x within a row: the order the levels' bytes are defined by, which
 * every writer (tvpal-encode, libtvpal) shares through these functions.
 *
 * Library code: pure functions, nothing allocated.
 */
#ifndef TVPAL_LEVELS_H
#define TVPAL_LEVELS_H

#include <stdint.h>

/* The dims of level k of a volume of dims d0. */
void tvpal_level_dims(const uint32_t d0[3], unsigned k, uint32_t out[3]);

/* The spacing sk and origin ok of a level of dims dk over level 0's grid
 * (s0, o0, dims d0): the same extent, its voxels' centres inside. */
void tvpal_level_grid(const double s0[3], const double o0[3],
                      const uint32_t d0[3], const uint32_t dk[3],
                      double sk[3], double ok[3]);

/* The coarse plane out ((nx + 1) / 2 x (ny + 1) / 2) of the block means
 * of fine planes f0 and f1 (nx x ny; f1 NULL past an odd nz). */
void tvpal_level_average_planes(const float *f0, const float *f1,
                                uint32_t nx, uint32_t ny, float *out);

/* The next level (dims ceil(fd / 2)) of the volume fine (dims fd) into
 * coarse. */
void tvpal_level_make(const float *fine, const uint32_t fd[3], float *coarse);

#endif
