/* shard_walk.h: what the shard and dataset harnesses do with a shard that
 * opened: read and verify every record (at most 64), walk its chunks and
 * decode their tables, then seek a slab through the first steps. */
#ifndef TVPAL_FUZZ_SHARD_WALK_H
#define TVPAL_FUZZ_SHARD_WALK_H
#include "tvpal_format.h"
#include "tvpal_shard.h"

#include <stdlib.h>

/* Walks the chunks of the verified record rec of a shard with header h,
 * decoding the tables of the plain ones (a coded chunk's table is its
 * frame until the record is inflated: tvpal_record_next_chunk). */
static inline void walk_chunks(const unsigned char *rec,
                        const struct tvpal_shard_header *h)
{
    uint64_t pos = 0;
    struct tvpal_chunk c;
    while (tvpal_record_next_chunk(rec, &pos, h->table_format, &c)) {
        if (c.h.flags & TVPAL_CHUNK_ZSTD)
            continue;
        float *t = malloc((size_t)c.h.wlen * 256 * sizeof *t + 1);
        if (!t)
            abort();
        tvpal_chunk_table(&c, t);
        free(t);
    }
}

static inline void walk_shard(struct tvpal_shard *s)
{
    const struct tvpal_shard_header *h = tvpal_shard_hdr(s);
    uint64_t cap = tvpal_shard_max_record(s);
    if (cap > (64u << 20))
        return;
    unsigned char *rec = malloc(cap ? (size_t)cap : 1);
    if (!rec)
        abort();
    struct tvpal_diag d;
    for (uint32_t t = 0; t < h->steps && t < 64; t++)
        if (tvpal_shard_read_record(s, t, rec, cap, &d) == 0)
            walk_chunks(rec, h);
    free(rec);
    struct tvpal_slab *slab;
    if (tvpal_slab_create(&slab, s) < 0)
        return;
    for (uint32_t t = 0; t < h->steps && t < 4; t++) {
        if (tvpal_slab_seek(slab, t, &d) < 0)
            continue;
        for (uint32_t k = 0; k < h->slice_count && k < 4; k++) {
            (void)tvpal_slab_indices(slab, k);
            (void)tvpal_slab_row(slab, k, t);
        }
    }
    tvpal_slab_free(slab);
}
#endif
