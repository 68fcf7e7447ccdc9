/* tvpal_format.h: the on-disk shard format (spec: common/format/FORMAT.md).
 *
 * A dataset directory holds, for each node R of K, node-R/axis-{x,y,z}.tvps:
 * the slab of consecutive slices of that axis owned by node R.  A shard file
 * is a 4096-byte header, then one record per timestep t = 0..T-1 (the
 * slice-windows of the slab that start at t, each with its decoder table and
 * its indices), each record starting on a 4096-byte boundary, then the record
 * index.  All integers and floats are little-endian.  Every record, the index
 * and the header carry a CRC-32C.
 *
 * This header has the layout constants and pure (no I/O) encode/decode
 * functions; tvpal_shard.h does the I/O.
 */
#ifndef TVPAL_FORMAT_H
#define TVPAL_FORMAT_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_error.h"
#include "tvpal_schedule.h"

#define TVPAL_FORMAT_VERSION 1u
/* Shards with coded chunks (FORMAT.md 6.11): a chunk's table and indices
 * stored as one zstd frame.  A writer writes 2 exactly when some chunk is
 * coded, so a reader before specification 1.8 rejects such a shard as an
 * unknown version instead of misreading it. */
#define TVPAL_FORMAT_VERSION_CODED 2u
/* Shards of the joined window schedule (FORMAT.md 5, 6.2: header field
 * "schedule" 1; since specification 1.11), coded chunks or not: a reader
 * before 1.11 rejects them as an unknown version instead of misreading
 * their windows. */
#define TVPAL_FORMAT_VERSION_JOINED 3u
/* Shards with palette groups (FORMAT.md 5.1, 6.3: header field "group"
 * G >= 2; since specification 1.12), either schedule: a chunk may hold
 * up to G slices under one table, which a reader before 1.12 would
 * misread. */
#define TVPAL_FORMAT_VERSION_GROUPED 4u
/* The most slices of a palette group, and the most voxels one chunk's
 * slices may have together (FORMAT.md 6.2): bounds the encoder's
 * workspace, which codes a group as one slice. */
#define TVPAL_GROUP_MAX 1024u
#define TVPAL_GROUP_VOXELS_MAX (1u << 18)
#define TVPAL_ALIGN 4096u               /* record alignment (O_DIRECT) */
#define TVPAL_SHARD_HEADER_BYTES 4096u
#define TVPAL_RECORD_HEADER_BYTES 64u
#define TVPAL_CHUNK_HEADER_BYTES 64u
#define TVPAL_INDEX_ENTRY_BYTES 32u
#define TVPAL_CHUNK_ALIGN 64u

#define TVPAL_SHARD_MAGIC "TVPALSHD"    /* 8 bytes at offset 0 */
#define TVPAL_RECORD_MAGIC 0x43525654u  /* "TVRC" */
#define TVPAL_CHUNK_MAGIC 0x4B435654u   /* "TVCK" */
#define TVPAL_TABLE_F32 0u              /* decoder table as float32 */
#define TVPAL_TABLE_U16 1u              /* 16-bit, scaled per chunk */
/* Added to 0 or 1 when some chunk holds missing entries (FORMAT.md 6.7):
 * 2 = float32 with NaN entries, 3 = 16-bit with q = 65535 missing in the
 * chunks flagged TVPAL_CHUNK_MISSING.  Readers before spec 1.5 reject
 * them, as 10.2 says they reject an unknown table_format. */
#define TVPAL_TABLE_MISSING 2u
/* Per chunk (FORMAT.md 6.7): 4 = each chunk's flags say whether its table
 * is 16-bit (TVPAL_CHUNK_U16) or float32; 5 = the same with missing values
 * (a 16-bit chunk is then read as format 3, a float32 one as format 2).
 * Readers before spec 1.6 reject them as unknown. */
#define TVPAL_TABLE_CHUNK 4u
#define TVPAL_TABLE_CHUNK_MISSING 5u
#define TVPAL_TABLE_MAX 5u
/* Chunk header flags (byte 28): the chunk's table has missing entries
 * (table_format 2, 3, 5); the chunk's table is 16-bit scaled (4, 5). */
#define TVPAL_CHUNK_MISSING 1u
#define TVPAL_CHUNK_U16 2u
/* The chunk's table and indices are one zstd frame of coded_bytes
 * (FORMAT.md 6.11); only in a shard of format_version 2. */
#define TVPAL_CHUNK_ZSTD 4u
/* Of a coded chunk only (with TVPAL_CHUNK_ZSTD, FORMAT.md 6.11, since
 * specification 1.10): its table's deltas are zigzagged and stored
 * index-major (each index's entries over the window together), and its
 * indices are gradients (the difference from the voxel above, from its
 * left neighbour's). */
#define TVPAL_CHUNK_TABLE_T2 8u
#define TVPAL_CHUNK_INDEX_G 16u
#define TVPAL_CHUNK_CODED_BITS \
    (TVPAL_CHUNK_ZSTD | TVPAL_CHUNK_TABLE_T2 | TVPAL_CHUNK_INDEX_G)
/* A coded chunk decodes to at most this many times its stored bytes: a
 * zstd block of up to 128 KiB costs at least 4 bytes, so no real frame
 * goes beyond it, and a reader refuses a chunk that claims more (FORMAT.md
 * 8.2): what a record inflates to stays bounded by the file. */
#define TVPAL_CODED_MAX_RATIO 32768u
#define TVPAL_U16_MISSING 65535u        /* q of a missing u16 entry */

static inline uint64_t tvpal_round_up(uint64_t x, uint64_t a)
{
    return (x + a - 1) / a * a;
}

struct tvpal_shard_header {
    uint32_t version;
    uint32_t dims[3];         /* nx, ny, nz of the whole volume */
    uint32_t steps;           /* T */
    uint32_t window;          /* N */
    uint32_t nodes;           /* K */
    uint32_t rank;            /* R, 0..K-1 */
    uint32_t axis;            /* 0 = x, 1 = y, 2 = z */
    uint32_t slice_begin;     /* first slice of the slab (global index) */
    uint32_t slice_count;     /* slices in the slab (>= 1) */
    uint32_t slice_w, slice_h;/* slice size: in-slice index = a + w * b */
    uint32_t table_format;    /* TVPAL_TABLE_F32 .. TVPAL_TABLE_MAX */
    uint32_t schedule;        /* TVPAL_SCHEDULE_*: 1 in version 3; either
                               * in version 4 */
    uint32_t group;           /* G, slices of a palette group: >= 2 iff
                               * version 4, else 1 (0 on disk) */
    uint64_t index_offset;    /* aligned; index of `steps` entries */
    uint64_t file_bytes;      /* total file size */
    uint32_t index_crc;
    double value_min, value_max; /* of the whole source */
};

struct tvpal_record_header {
    uint32_t step;            /* t */
    uint32_t chunk_count;
    uint32_t axis;
    uint64_t payload_bytes;   /* chunks, after the 64-byte header */
    uint32_t payload_crc;
    /* The payload once its coded chunks are inflated (FORMAT.md 6.11):
     * stored in a shard of format_version 2; = payload_bytes in one of
     * version 1 and in a record without coded chunks. */
    uint64_t plain_bytes;
};

struct tvpal_chunk_header {
    uint32_t slice;           /* global slice index */
    uint32_t wstart, wlen;    /* window [wstart, wstart + wlen) */
    uint32_t w, h;            /* slice size */
    uint32_t used;            /* distinct indices held by voxels */
    uint32_t flags;           /* TVPAL_CHUNK_MISSING, TVPAL_CHUNK_U16 */
    uint8_t bits[16];         /* bits per coefficient */
    float tmin, tscale;       /* 16-bit table: value = tmin + q tscale */
    uint32_t coded_bytes;     /* TVPAL_CHUNK_ZSTD: bytes of its frame */
};

struct tvpal_index_entry {
    uint64_t offset;          /* aligned record offset */
    uint64_t bytes;           /* record bytes including padding (aligned) */
    uint32_t step;
    uint32_t chunk_count;
    uint32_t crc;             /* payload CRC, as in the record header */
    /* A record with coded chunks (FORMAT.md 6.11; format_version 2): coded
     * is 1 and plain_bytes its bytes once inflated (a multiple of
     * TVPAL_ALIGN); else coded 0 and plain_bytes = bytes. */
    int coded;
    uint64_t plain_bytes;
};

/* Geometry of axis a's slices for volume dims: count, w, h.  In-slice voxel
 * (a_, b_) of slice s is volume voxel:
 *   axis x: (s, a_, b_)   axis y: (a_, s, b_)   axis z: (a_, b_, s). */
void tvpal_axis_geometry(const uint32_t dims[3], unsigned axis,
                         uint32_t *count, uint32_t *w, uint32_t *h);

/* Slab of node r of k along an axis of n slices: [*begin, *begin + *count),
 * as equal as possible, the first n % k slabs one slice larger. */
void tvpal_slab_range(uint32_t n, uint32_t k, uint32_t r, uint32_t *begin,
                      uint32_t *count);

/* Whether a shard of table_format has missing values (2, 3, 5). */
static inline int tvpal_table_has_missing(uint32_t table_format)
{
    return table_format == TVPAL_TABLE_CHUNK_MISSING ||
           (table_format < TVPAL_TABLE_CHUNK &&
            (table_format & TVPAL_TABLE_MISSING));
}

/* The table_format of a shard of format 0, 1 or 4 once some chunk has
 * missing entries: 2, 3 or 5 (others unchanged). */
static inline uint32_t tvpal_table_with_missing(uint32_t table_format)
{
    return table_format >= TVPAL_TABLE_CHUNK ? TVPAL_TABLE_CHUNK_MISSING
                                             : table_format | TVPAL_TABLE_MISSING;
}

/* The table format (0..3) one chunk is stored in: the shard's own for 0..3;
 * in a per-chunk shard (4, 5) 1 or 0 as the chunk's flags have
 * TVPAL_CHUNK_U16 or not, plus TVPAL_TABLE_MISSING in a shard of 5. */
static inline uint32_t tvpal_chunk_table_format(uint32_t table_format,
                                                uint32_t flags)
{
    if (table_format < TVPAL_TABLE_CHUNK)
        return table_format;
    return ((flags & TVPAL_CHUNK_U16) ? TVPAL_TABLE_U16 : TVPAL_TABLE_F32) |
           (table_format == TVPAL_TABLE_CHUNK_MISSING ? TVPAL_TABLE_MISSING
                                                      : 0u);
}

/* The chunk flags a shard of table_format defines (FORMAT.md 6.6): a chunk
 * with any other bit set is malformed (8.2). */
static inline uint32_t tvpal_chunk_flags_allowed(uint32_t table_format)
{
    uint32_t f = tvpal_table_has_missing(table_format) ? TVPAL_CHUNK_MISSING
                                                       : 0u;
    return table_format >= TVPAL_TABLE_CHUNK ? f | TVPAL_CHUNK_U16 : f;
}

/* Bytes of one table entry of a chunk stored in table format 0..3 (4 or
 * 2).  For a per-chunk shard (4, 5) the larger, 4: the room any of its
 * chunks needs (tvpal_chunk_table_format gives a chunk's own). */
static inline uint32_t tvpal_table_entry_bytes(uint32_t table_format)
{
    return table_format < TVPAL_TABLE_CHUNK && (table_format & TVPAL_TABLE_U16)
               ? 2u : 4u;
}

/* Bytes of one chunk with window length len, w*h indices and tables in
 * table_format (tvpal_table_entry_bytes: a per-chunk format gives the
 * room of a float32 chunk). */
static inline uint64_t tvpal_chunk_bytes(uint32_t len, uint32_t w, uint32_t h,
                                         uint32_t table_format)
{
    return TVPAL_CHUNK_HEADER_BYTES +
           (uint64_t)len * 256u * tvpal_table_entry_bytes(table_format) +
           tvpal_round_up((uint64_t)w * h, TVPAL_CHUNK_ALIGN);
}

/* Bytes chunk h takes in its record as stored: a coded one (TVPAL_CHUNK_ZSTD)
 * its header and frame, rounded up to TVPAL_CHUNK_ALIGN; any other
 * tvpal_chunk_bytes of its own table format (ctf, 0..3). */
static inline uint64_t tvpal_chunk_stored_bytes(
    const struct tvpal_chunk_header *h, uint32_t ctf)
{
    if (h->flags & TVPAL_CHUNK_ZSTD)
        return TVPAL_CHUNK_HEADER_BYTES +
               tvpal_round_up(h->coded_bytes, TVPAL_CHUNK_ALIGN);
    return tvpal_chunk_bytes(h->wlen, h->w, h->h, ctf);
}

/* The window schedule of shard h's series (FORMAT.md 5). */
static inline struct tvpal_schedule
tvpal_shard_schedule(const struct tvpal_shard_header *h)
{
    return tvpal_schedule_of(h->window, h->steps, h->schedule, h->group);
}

/* The slices chunk header c holds (FORMAT.md 6.5): its rows are theirs,
 * h = k * slice_h; 1 in shards without palette groups. */
static inline uint32_t tvpal_chunk_slices(const struct tvpal_chunk_header *c,
                                          const struct tvpal_shard_header *sh)
{
    return sh->slice_h ? c->h / sh->slice_h : 1;
}

/* Serialization.  *_encode write exactly the fixed size into buf (CRCs
 * included); *_decode validate magic, version, CRC and field ranges, and
 * describe the first bad field in diag. */
void tvpal_shard_header_encode(const struct tvpal_shard_header *h,
                               unsigned char *buf);
int tvpal_shard_header_decode(const unsigned char *buf,
                              struct tvpal_shard_header *h,
                              struct tvpal_diag *diag);

void tvpal_record_header_encode(const struct tvpal_record_header *h,
                                unsigned char *buf);
int tvpal_record_header_decode(const unsigned char *buf,
                               struct tvpal_record_header *h,
                               struct tvpal_diag *diag);

void tvpal_chunk_header_encode(const struct tvpal_chunk_header *h,
                               unsigned char *buf);
int tvpal_chunk_header_decode(const unsigned char *buf,
                              struct tvpal_chunk_header *h,
                              struct tvpal_diag *diag);

void tvpal_index_entry_encode(const struct tvpal_index_entry *e,
                              unsigned char *buf);
void tvpal_index_entry_decode(const unsigned char *buf,
                              struct tvpal_index_entry *e);

/* A parsed chunk inside a record buffer (pointers borrow the buffer). */
struct tvpal_chunk {
    struct tvpal_chunk_header h;
    uint32_t table_format;        /* this chunk's, 0..3 (see
                                   * tvpal_chunk_table_format) */
    const unsigned char *table;   /* wlen * 256 entries LE, row per step */
    const uint8_t *indices;       /* w * h */
};

/* The chunk's decoder table as floats: out[j * 256 + i]; a missing entry
 * is NaN. */
void tvpal_chunk_table(const struct tvpal_chunk *c, float *out);

/* Stores a table (len * 256 floats) in table_format (0 or 1) at dst,
 * filling the header's tmin/tscale for TVPAL_TABLE_U16 (q = round((v -
 * tmin) / tscale), tscale = (max - min) / 65535, 0 for a constant table).
 * NaN entries are missing: the header gets TVPAL_CHUNK_MISSING, a u16
 * table is then scaled over the finite entries with 65534 steps and a
 * missing entry stored as TVPAL_U16_MISSING.  The shard's table_format
 * must then include TVPAL_TABLE_MISSING (tvpal_shardw_set_missing).  In a
 * per-chunk shard (4, 5) the caller picks 0 or 1 for each chunk and sets
 * TVPAL_CHUNK_U16 in h->flags after this call for a 16-bit one. */
void tvpal_table_store(const float *table, uint32_t len,
                       uint32_t table_format, unsigned char *dst,
                       struct tvpal_chunk_header *h);

/* The smallest and largest finite entry of table[0..n) into *lo, *hi;
 * returns 1 when some entry is NaN (missing).  An all-NaN table gives
 * lo = hi = 0. */
int tvpal_table_range(const float *table, size_t n, float *lo, float *hi);

/* As tvpal_table_store, with a 16-bit table scaled over `steps` steps
 * instead of the most its codes allow: tscale = (max - min) / steps, so q
 * takes steps + 1 values (a coarser table, whose deltas code smaller:
 * FORMAT.md 6.7).  steps 0, or more than the most (65535; 65534 with
 * missing entries), means the most.  Ignored for a float32 table. */
void tvpal_table_store_steps(const float *table, uint32_t len,
                             uint32_t table_format, uint32_t steps,
                             unsigned char *dst, struct tvpal_chunk_header *h);

/* Verifies a whole record held in buf[0..bytes): header, payload CRC, the
 * expected step, and that every chunk lies inside the payload with sizes
 * consistent with sh.  Call before tvpal_record_chunk. */
int tvpal_record_verify(const unsigned char *buf, uint64_t bytes,
                        uint32_t step, const struct tvpal_shard_header *sh,
                        struct tvpal_diag *diag);

/* All of tvpal_record_verify but the payload CRC, for a reader that sums
 * the CRC itself as it consumes the chunks (tvpal_slab_stage_verify), so
 * that the record is read from memory once.  Until that CRC is checked
 * the chunks' contents are unverified; their placement is safe to walk
 * with tvpal_record_next_chunk. */
int tvpal_record_verify_layout(const unsigned char *buf, uint64_t bytes,
                               uint32_t step,
                               const struct tvpal_shard_header *sh,
                               struct tvpal_diag *diag);

/* Iterates the chunks of a verified record of a shard with table_format
 * (a coded chunk's table points at its frame and its indices at nothing:
 * inflate the record first, tvpal_record_inflate):
 * *pos starts at 0; returns 1 and fills c for each chunk (c->table_format
 * the chunk's own, 0..3), 0 at the end. */
int tvpal_record_next_chunk(const unsigned char *buf, uint64_t *pos,
                            uint32_t table_format, struct tvpal_chunk *c);

/* Little-endian float32 row -> host floats. */
void tvpal_load_f32le(const unsigned char *src, float *dst, size_t n);
void tvpal_store_f32le(const float *src, unsigned char *dst, size_t n);

#endif
