/* tvpal_passes.c: see tvpal_passes.h. */
#include "tvpal_passes.h"

#include "tvpal_checkpoint.h"
#include "tvpal_format.h"
#include "tvpal_levels.h"

#include <string.h>

size_t tvpal_passes_read_rows(uint64_t row_bytes, uint32_t rows_max)
{
    uint64_t rows = TVPAL_READ_BLOCK / row_bytes;
    rows = rows < 1 ? 1 : rows > rows_max ? rows_max : rows;
    return (size_t)rows;
}

uint64_t tvpal_passes_fixed_bytes(const struct tvpal_engine *e,
                                  unsigned nthreads, uint64_t scratch,
                                  uint64_t reader)
{
    const uint64_t per_thread = tvpal_engine_thread_bytes(e) + scratch +
                                TVPAL_CHECKPOINT_BINS * sizeof(uint64_t);
    return ((uint64_t)16 << 20) + nthreads * per_thread +
           tvpal_engine_table_bytes(e) + reader + tvpal_engine_max_chunk(e);
}

uint64_t tvpal_passes_levels_bytes(const struct tvpal_engine_params *p,
                                   unsigned levels, unsigned nthreads,
                                   uint64_t slab_voxels)
{
    const uint64_t plane = (uint64_t)p->dims[0] * p->dims[1];
    const uint64_t ring = tvpal_engine_span(p);
    uint64_t b = slab_voxels ? slab_voxels * sizeof(float) + 2 * plane * 4
                             : 0;
    for (unsigned k = 1; k <= levels; k++) {
        /* A level stores level 0's axes and node shards, one process's. */
        struct tvpal_engine_params pk = *p;
        tvpal_level_dims(p->dims, k, pk.dims);
        pk.node_first = 0;
        pk.node_count = p->nodes;
        const uint64_t vox = (uint64_t)pk.dims[0] * pk.dims[1] * pk.dims[2];
        struct tvpal_engine *e = NULL;
        if (tvpal_engine_create(&e, &pk) < 0)
            return 0;
        b += (ring + 1) * vox * sizeof(float) +
             (uint64_t)nthreads *
                 (tvpal_engine_thread_bytes(e) +
                  TVPAL_CHECKPOINT_BINS * sizeof(uint64_t) + pk.dims[0] * 8) +
             tvpal_engine_table_bytes(e) + ((uint64_t)1 << 20);
        tvpal_engine_free(e);
    }
    return b;
}

uint64_t tvpal_passes_work_before(const struct encode_plan *plan,
                                  const uint32_t dims[3], uint32_t T,
                                  uint64_t u)
{
    uint64_t w = 0;
    for (uint32_t p = 0; p < plan->npasses; p++) {
        const struct encode_pass *ps = &plan->pass[p];
        uint64_t per_step = 0;
        for (unsigned a = 0; a < 3; a++)
            if (ps->axes & (1u << a)) {
                uint32_t n, sw, sh;
                tvpal_axis_geometry(dims, a, &n, &sw, &sh);
                per_step += (uint64_t)(ps->s1[a] - ps->s0[a]) * sw * sh;
            }
        /* Every slice has one sample per step, over its windows. */
        const uint64_t steps = u >= (uint64_t)(p + 1) * T ? T
                               : u > (uint64_t)p * T ? u - (uint64_t)p * T
                                                     : 0;
        w += per_step * steps;
    }
    return w;
}

uint64_t tvpal_passes_counted_at(const struct encode_plan *plan, uint32_t T,
                                 uint64_t u, uint32_t loaded)
{
    const uint32_t p = (uint32_t)(u / T);
    uint64_t c = 0;
    for (uint32_t i = 0; i < p && i < plan->npasses; i++)
        if (plan->pass[i].stats)
            c += encode_box_voxels(&plan->pass[i].box) * T;
    if (p < plan->npasses && plan->pass[p].stats)
        c += encode_box_voxels(&plan->pass[p].box) * loaded;
    return c;
}
