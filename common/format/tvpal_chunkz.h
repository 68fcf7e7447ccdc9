/* tvpal_chunkz.h: coded chunks (common/format/FORMAT.md 6.11), the one
 * adapter of libzstd.
 *
 * A coded chunk keeps its 64-byte header and stores its decoder table and
 * its indices, after reversible transforms, as one zstd frame: the table
 * as differences along time (row 0: along the index), zigzagged, each
 * index's entries together, in byte planes (T2); the indices as
 * differences from the voxel before, or as gradients (G) where that looks
 * smaller.  Inflating also takes the first transforms (FORMAT.md 1.8: no
 * zigzag, row-major; no G), which 0.4.0 wrote first.  A record holding coded
 * chunks is inflated once, where it is read, into exactly the record a
 * writer without coding would have written (its CRC recomputed), so
 * everything after the read (the slab, the renderers) sees plain records
 * only.
 *
 * Inflating in place.  A reader gives a coded record a buffer of its
 * plain bytes (the index entry's plain_bytes) and reads the stored bytes
 * into its tail, at tvpal_record_stored_at; tvpal_record_inflate then
 * rewrites the buffer front to back.  Every chunk is no larger stored than
 * plain, so a chunk's plain form never reaches the stored bytes of the
 * chunks after it; a chunk whose plain form would reach its own stored
 * bytes is inflated through the coder's scratch.
 */
#ifndef TVPAL_CHUNKZ_H
#define TVPAL_CHUNKZ_H

#include <stdint.h>

#include "tvpal_error.h"
#include "tvpal_format.h"

/* zstd level of tvpal-encode --index-coding unless --index-level says
 * otherwise: at 512^3 turbulence 25% of the indices at 220 MB/s of
 * coding, against 18% at 4 MB/s for level 19. */
#define TVPAL_CHUNKZ_LEVEL 3

/* A coder's state: zstd contexts and scratch for chunks of up to max_chunk
 * plain bytes (tvpal_chunk_bytes).  One per thread that codes, or
 * inflates without a pool.  0 or TVPAL_E_NOMEM; *out owned by the caller
 * (tvpal_chunkz_free, NULL a no-op). */
struct tvpal_chunkz;
int tvpal_chunkz_create(struct tvpal_chunkz **out, uint64_t max_chunk);
/* The same with `ways` (1..TVPAL_CHUNKZ_WAYS_MAX) scratches and contexts,
 * for tvpal_record_inflate_pool: a wave inflates that many chunks at once.
 * TVPAL_E_INVAL for ways out of range. */
#define TVPAL_CHUNKZ_WAYS_MAX 64
int tvpal_chunkz_create_ways(struct tvpal_chunkz **out, uint64_t max_chunk,
                             unsigned ways);
unsigned tvpal_chunkz_ways(const struct tvpal_chunkz *z);
void tvpal_chunkz_free(struct tvpal_chunkz *z);

/* Codes the plain chunk at chunk (header, table in its own format ctf
 * 0..3, indices, padding; at most max_chunk bytes) with zstd at level
 * (1..19) into dst, which has room for the plain chunk: its table in
 * transform T2 and its indices in G where that looks smaller (FORMAT.md
 * 6.11, flags bits 3 and 4).  1: dst holds the coded chunk, *stored its
 * bytes (header, frame, zeros up to a multiple of 64), fewer than the
 * plain chunk's; 0: coding does not make it smaller (dst unspecified:
 * store it plain); TVPAL_E_INVAL (larger than max_chunk, a level out of
 * range, or flags of a coded chunk already set); TVPAL_E_NOMEM. */
int tvpal_chunkz_code(struct tvpal_chunkz *z, int level,
                      const unsigned char *chunk, uint32_t ctf,
                      unsigned char *dst, uint64_t *stored);

/* The bytes of a reader's buffer for the record of index entry e: its
 * bytes, or for a coded record its plain bytes and TVPAL_ALIGN more, so
 * that the stored bytes, read at the buffer's end, start at least as far
 * in as the plain record is longer (the roundings to TVPAL_ALIGN could
 * otherwise take up to 4095 bytes of that lead). */
static inline uint64_t tvpal_record_buffer_bytes(const struct tvpal_index_entry *e)
{
    return e->coded ? e->plain_bytes + TVPAL_ALIGN : e->bytes;
}

/* Where in that buffer the record's stored bytes are read (a multiple of
 * TVPAL_ALIGN; 0: a record without coded chunks, nothing to inflate). */
static inline uint64_t tvpal_record_stored_at(const struct tvpal_index_entry *e)
{
    return tvpal_record_buffer_bytes(e) - e->bytes;
}

/* Record `step` of shard sh, stored (e->bytes) at buf + stored_at(e) of a
 * buffer of tvpal_record_buffer_bytes(e), checked (tvpal_record_verify: CRC of what is
 * stored, layout, every frame's size) and inflated into its plain form at
 * buf[0 .. e->plain_bytes): chunks not coded, payload CRC over the plain
 * payload.  A record without coded chunks (stored_at 0) is left as it is,
 * unchecked.  z: chunks up to the shard's largest plain chunk.  0;
 * TVPAL_E_CHECKSUM, TVPAL_E_FORMAT (a frame that is not zstd, or decodes
 * to other than its chunk's table and indices: diag names the record and
 * the slice; or the entry's plain_bytes that do not fit the record
 * header's), TVPAL_E_TRUNC, TVPAL_E_INVAL (a chunk larger than z takes);
 * on error buf holds nothing usable. */
int tvpal_record_inflate(struct tvpal_chunkz *z, unsigned char *buf,
                         const struct tvpal_index_entry *e, uint32_t step,
                         const struct tvpal_shard_header *sh,
                         struct tvpal_diag *diag);

/* tvpal_record_inflate on the threads of pool (tvpal_pool.h; NULL, a pool
 * of one or z of one way: the same as tvpal_record_inflate): chunks are
 * inflated in waves of tvpal_chunkz_ways(z), each wave's chunks first all
 * read into z's scratches, then all written to their places, so no chunk
 * overwrites what another has still to read.  The same bytes and codes as
 * tvpal_record_inflate (the first failing chunk's).  Called by one thread
 * at a time, the pool's driver. */
struct tvpal_pool;
int tvpal_record_inflate_pool(struct tvpal_chunkz *z, struct tvpal_pool *pool,
                              unsigned char *buf,
                              const struct tvpal_index_entry *e, uint32_t step,
                              const struct tvpal_shard_header *sh,
                              struct tvpal_diag *diag);

/* The largest plain chunk of shard sh (the room of a float32 chunk of its
 * longest window): what tvpal_chunkz_create needs for any of its chunks. */
static inline uint64_t tvpal_shard_max_chunk(const struct tvpal_shard_header *sh)
{
    const struct tvpal_schedule sc = tvpal_shard_schedule(sh);
    return tvpal_chunk_bytes(tvpal_schedule_max_len(&sc), sh->slice_w,
                             sh->slice_h * sc.G, TVPAL_TABLE_F32);
}

/* The name and version of the zstd library in use, e.g. "zstd 1.5.4". */
const char *tvpal_chunkz_library(void);

#endif
