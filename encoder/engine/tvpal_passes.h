/* tvpal_passes.h: the sums of a job encoded in passes (encode_plan.h) that
 * every driver of the engine shares, tvpal-encode and libtvpal's encode
 * from a source (lib/tvpal_encoder_source.c), so that the two make the
 * same plan, count the same work and check a checkpoint alike:
 *  - the rows a raw read takes at once, and so the reading scratch;
 *  - the bytes beside the ring the plan is made with;
 *  - the bytes of the levels of detail, beside level 0's one pass or after
 *    it;
 *  - the work of the units before a unit, and the statistics a checkpoint
 *    at a unit must hold.
 * A unit is one step of one pass: u = p T + t + 1 once step t of pass p is
 * encoded.
 *
 * Library code: pure functions (levels_bytes makes and frees engines to
 * size them); nothing prints.
 */
#ifndef TVPAL_PASSES_H
#define TVPAL_PASSES_H

#include "encode_plan.h"
#include "tvpal_engine.h"

#include <stddef.h>
#include <stdint.h>

/* Bytes of one thread's reading scratch at most: a raw read takes whole
 * rows of one plane up to this much (one row at least). */
#define TVPAL_READ_BLOCK ((size_t)8 << 20)

/* Rows of row_bytes one read takes: TVPAL_READ_BLOCK's worth, at least
 * one, at most rows_max (a plane's). */
size_t tvpal_passes_read_rows(uint64_t row_bytes, uint32_t rows_max);

/* Bytes of everything but the ring and the box buffers, for the plan: the
 * program and its libraries (16 MiB: 13 measured), per thread the codec's
 * largest workspace, `scratch` bytes of reading scratch and the
 * histogram; the job lists and record tables, `reader` bytes a source's
 * reader holds of its own, and a chunk's buffer for packing a per-chunk
 * shard at the end.  An estimate on the safe side, which tests hold
 * against the measured peak. */
uint64_t tvpal_passes_fixed_bytes(const struct tvpal_engine *e,
                                  unsigned nthreads, uint64_t scratch,
                                  uint64_t reader);

/* Bytes the levels 1 .. levels of level 0's job p hold beside level 0's
 * fixed bytes: per level N of its steps and the one being made, an
 * encoder's workspaces and histograms for nthreads threads, its tables;
 * with slab_voxels > 0 (levels made after level 0, from the source read
 * again in slabs) that many floats and two planes.  0 when out of
 * memory. */
uint64_t tvpal_passes_levels_bytes(const struct tvpal_engine_params *p,
                                   unsigned levels, unsigned nthreads,
                                   uint64_t slab_voxels);

/* The work (voxel-samples, every axis a pass encodes; a voxel of a window
 * of L steps counts L) of the units before u of a plan for dims and T
 * steps: the whole job's at u = npasses T. */
uint64_t tvpal_passes_work_before(const struct encode_plan *plan,
                                  const uint32_t dims[3], uint32_t T,
                                  uint64_t u);

/* The values a checkpoint at unit u must have counted: every stats pass
 * before u's, and `loaded` steps of u's own when it is one. */
uint64_t tvpal_passes_counted_at(const struct encode_plan *plan, uint32_t T,
                                 uint64_t u, uint32_t loaded);

#endif
