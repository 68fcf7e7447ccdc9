/* tvpal_format.c: (de)serialization of the shard format (common/format/FORMAT.md). */
#include "tvpal_format.h"
#include "tvpal_crc32c.h"
#include "tvpal_schedule.h"

#include <math.h>
#include <string.h>

static void put32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
    p[2] = (unsigned char)(v >> 16);
    p[3] = (unsigned char)(v >> 24);
}

static void put64(unsigned char *p, uint64_t v)
{
    put32(p, (uint32_t)v);
    put32(p + 4, (uint32_t)(v >> 32));
}

static uint32_t get32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
           (uint32_t)p[3] << 24;
}

static uint64_t get64(const unsigned char *p)
{
    return (uint64_t)get32(p) | (uint64_t)get32(p + 4) << 32;
}

static void putd(unsigned char *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, 8);
    put64(p, u);
}

static double getd(const unsigned char *p)
{
    uint64_t u = get64(p);
    double d;
    memcpy(&d, &u, 8);
    return d;
}

void tvpal_axis_geometry(const uint32_t dims[3], unsigned axis,
                         uint32_t *count, uint32_t *w, uint32_t *h)
{
    switch (axis) {
    case 0: *count = dims[0]; *w = dims[1]; *h = dims[2]; break;
    case 1: *count = dims[1]; *w = dims[0]; *h = dims[2]; break;
    default: *count = dims[2]; *w = dims[0]; *h = dims[1]; break;
    }
}

void tvpal_slab_range(uint32_t n, uint32_t k, uint32_t r, uint32_t *begin,
                      uint32_t *count)
{
    uint32_t base = n / k, extra = n % k;
    *begin = r * base + (r < extra ? r : extra);
    *count = base + (r < extra ? 1 : 0);
}

/* Shard header layout (offsets in bytes):
 *   0 magic[8]  8 version  12 header_bytes  16 nx 20 ny 24 nz  28 steps
 *  32 window  36 nodes  40 rank  44 axis  48 slice_begin  52 slice_count
 *  56 slice_w  60 slice_h  64 table_format  68 schedule (version 3; 0 before)
 *  72 index_offset(u64)  80 file_bytes(u64)  88 index_crc
 *  92 group (version 4; 0 before)
 *  96 value_min(f64)  104 value_max(f64)  112..4091 zero  4092 header_crc */
void tvpal_shard_header_encode(const struct tvpal_shard_header *h,
                               unsigned char *b)
{
    memset(b, 0, TVPAL_SHARD_HEADER_BYTES);
    memcpy(b, TVPAL_SHARD_MAGIC, 8);
    put32(b + 8, h->version);
    put32(b + 12, TVPAL_SHARD_HEADER_BYTES);
    put32(b + 16, h->dims[0]);
    put32(b + 20, h->dims[1]);
    put32(b + 24, h->dims[2]);
    put32(b + 28, h->steps);
    put32(b + 32, h->window);
    put32(b + 36, h->nodes);
    put32(b + 40, h->rank);
    put32(b + 44, h->axis);
    put32(b + 48, h->slice_begin);
    put32(b + 52, h->slice_count);
    put32(b + 56, h->slice_w);
    put32(b + 60, h->slice_h);
    put32(b + 64, h->table_format);
    put32(b + 68, h->schedule);
    put64(b + 72, h->index_offset);
    put64(b + 80, h->file_bytes);
    put32(b + 88, h->index_crc);
    put32(b + 92, h->version == TVPAL_FORMAT_VERSION_GROUPED ? h->group : 0);
    putd(b + 96, h->value_min);
    putd(b + 104, h->value_max);
    put32(b + 4092, tvpal_crc32c(0, b, 4092));
}

int tvpal_shard_header_decode(const unsigned char *b,
                              struct tvpal_shard_header *h,
                              struct tvpal_diag *diag)
{
    if (memcmp(b, TVPAL_SHARD_MAGIC, 8) != 0)
        return tvpal_diag_set(diag, TVPAL_E_MAGIC,
                              "header: magic is not \"" TVPAL_SHARD_MAGIC "\"");
    h->version = get32(b + 8);
    if (h->version < TVPAL_FORMAT_VERSION ||
        h->version > TVPAL_FORMAT_VERSION_GROUPED)
        return tvpal_diag_set(diag, TVPAL_E_VERSION,
                              "header: format version %u, expected %u..%u",
                              h->version, TVPAL_FORMAT_VERSION,
                              TVPAL_FORMAT_VERSION_GROUPED);
    if (get32(b + 4092) != tvpal_crc32c(0, b, 4092))
        return tvpal_diag_set(diag, TVPAL_E_CHECKSUM,
                              "header: CRC-32C mismatch");
    if (get32(b + 12) != TVPAL_SHARD_HEADER_BYTES)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "header: header_bytes %u, expected %u",
                              get32(b + 12), TVPAL_SHARD_HEADER_BYTES);
    for (int i = 0; i < 3; i++)
        h->dims[i] = get32(b + 16 + 4 * i);
    h->steps = get32(b + 28);
    h->window = get32(b + 32);
    h->nodes = get32(b + 36);
    h->rank = get32(b + 40);
    h->axis = get32(b + 44);
    h->slice_begin = get32(b + 48);
    h->slice_count = get32(b + 52);
    h->slice_w = get32(b + 56);
    h->slice_h = get32(b + 60);
    h->table_format = get32(b + 64);
    h->schedule = get32(b + 68);
    h->index_offset = get64(b + 72);
    h->file_bytes = get64(b + 80);
    h->index_crc = get32(b + 88);
    h->group = get32(b + 92);
    h->value_min = getd(b + 96);
    h->value_max = getd(b + 104);

    if (!h->dims[0] || !h->dims[1] || !h->dims[2])
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "header: dims %ux%ux%u "
                              "has a zero", h->dims[0], h->dims[1], h->dims[2]);
    if (!h->steps)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "header: steps is 0");
    if (h->window < 1 || h->window > 16)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "header: window %u, expected 1..16", h->window);
    if (h->axis > 2)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "header: axis %u, expected 0..2", h->axis);
    uint32_t n, w, hh, begin, count;
    tvpal_axis_geometry(h->dims, h->axis, &n, &w, &hh);
    if (!h->nodes || h->nodes > n || h->rank >= h->nodes)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "header: rank %u of %u nodes for %u slices",
                              h->rank, h->nodes, n);
    tvpal_slab_range(n, h->nodes, h->rank, &begin, &count);
    if (h->slice_begin != begin || h->slice_count != count ||
        h->slice_w != w || h->slice_h != hh)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "header: slab %u+%u of %ux%u slices, expected "
                              "%u+%u of %ux%u", h->slice_begin, h->slice_count,
                              h->slice_w, h->slice_h, begin, count, w, hh);
    if (h->table_format > TVPAL_TABLE_MAX)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "header: table_format %u, expected 0 (float32), "
                              "1 (16-bit scaled), 4 (per chunk), or 2, 3, 5 "
                              "(the same with missing values)",
                              h->table_format);
    /* Version 3 is the joined schedule, version 4 either; before them
     * the field was a reserved 0. */
    if (h->version == TVPAL_FORMAT_VERSION_GROUPED
            ? h->schedule > TVPAL_SCHEDULE_JOINED
            : h->schedule != (h->version == TVPAL_FORMAT_VERSION_JOINED
                                  ? TVPAL_SCHEDULE_JOINED
                                  : TVPAL_SCHEDULE_STAGGERED))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "header: schedule %u with format version %u, "
                              "expected 1 with version 3, 0 or 1 with 4, 0 "
                              "before", h->schedule, h->version);
    /* Version 4 has palette groups of G >= 2 slices, no more than the
     * axis has, and at most TVPAL_GROUP_VOXELS_MAX voxels; before it the
     * field was a reserved 0 (G = 1). */
    if (h->version == TVPAL_FORMAT_VERSION_GROUPED
            ? h->group < 2 || h->group > n || h->group > TVPAL_GROUP_MAX ||
                  (uint64_t)h->group * w * hh > TVPAL_GROUP_VOXELS_MAX
            : h->group != 0)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "header: group %u with format version %u, "
                              "expected 2..%u slices of %ux%u (at most %u "
                              "voxels) with version 4, 0 before", h->group,
                              h->version,
                              n < TVPAL_GROUP_MAX ? n : TVPAL_GROUP_MAX, w, hh,
                              TVPAL_GROUP_VOXELS_MAX);
    if (!h->group)
        h->group = 1;
    if (h->index_offset % TVPAL_ALIGN || h->index_offset < TVPAL_ALIGN ||
        h->index_offset > ((uint64_t)1 << 62) ||
        h->file_bytes != h->index_offset + tvpal_round_up(
                             (uint64_t)h->steps * TVPAL_INDEX_ENTRY_BYTES,
                             TVPAL_ALIGN))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "header: index_offset %llu / file_bytes %llu "
                              "inconsistent",
                              (unsigned long long)h->index_offset,
                              (unsigned long long)h->file_bytes);
    return 0;
}

/* Record header: 0 magic 4 step 8 chunk_count 12 axis 16 payload_bytes(u64)
 * 24 payload_crc 28 zero 32 plain_bytes(u64; 0 in format_version 1)
 * 40..59 zero 60 header_crc (over bytes 0..59). */
void tvpal_record_header_encode(const struct tvpal_record_header *h,
                                unsigned char *b)
{
    memset(b, 0, TVPAL_RECORD_HEADER_BYTES);
    put32(b, TVPAL_RECORD_MAGIC);
    put32(b + 4, h->step);
    put32(b + 8, h->chunk_count);
    put32(b + 12, h->axis);
    put64(b + 16, h->payload_bytes);
    put32(b + 24, h->payload_crc);
    put64(b + 32, h->plain_bytes);
    put32(b + 60, tvpal_crc32c(0, b, 60));
}

int tvpal_record_header_decode(const unsigned char *b,
                               struct tvpal_record_header *h,
                               struct tvpal_diag *diag)
{
    if (get32(b) != TVPAL_RECORD_MAGIC)
        return tvpal_diag_set(diag, TVPAL_E_MAGIC,
                              "record header: bad magic");
    if (get32(b + 60) != tvpal_crc32c(0, b, 60))
        return tvpal_diag_set(diag, TVPAL_E_CHECKSUM,
                              "record header: CRC-32C mismatch");
    h->step = get32(b + 4);
    h->chunk_count = get32(b + 8);
    h->axis = get32(b + 12);
    h->payload_bytes = get64(b + 16);
    h->payload_crc = get32(b + 24);
    /* 0 (format_version 1): nothing is coded. */
    h->plain_bytes = get64(b + 32) ? get64(b + 32) : h->payload_bytes;
    return 0;
}

/* Chunk header: 0 magic 4 slice 8 wstart 12 wlen 16 w 20 h 24 used
 * 28 flags 32 bits[16] 48 tmin(f32) 52 tscale(f32) 56 coded_bytes
 * 60..63 zero. */
void tvpal_chunk_header_encode(const struct tvpal_chunk_header *h,
                               unsigned char *b)
{
    memset(b, 0, TVPAL_CHUNK_HEADER_BYTES);
    put32(b, TVPAL_CHUNK_MAGIC);
    put32(b + 4, h->slice);
    put32(b + 8, h->wstart);
    put32(b + 12, h->wlen);
    put32(b + 16, h->w);
    put32(b + 20, h->h);
    put32(b + 24, h->used);
    put32(b + 28, h->flags);
    memcpy(b + 32, h->bits, 16);
    uint32_t u;
    memcpy(&u, &h->tmin, 4);
    put32(b + 48, u);
    memcpy(&u, &h->tscale, 4);
    put32(b + 52, u);
    put32(b + 56, h->coded_bytes);
}

int tvpal_chunk_header_decode(const unsigned char *b,
                              struct tvpal_chunk_header *h,
                              struct tvpal_diag *diag)
{
    if (get32(b) != TVPAL_CHUNK_MAGIC)
        return tvpal_diag_set(diag, TVPAL_E_MAGIC, "chunk: bad magic");
    h->slice = get32(b + 4);
    h->wstart = get32(b + 8);
    h->wlen = get32(b + 12);
    h->w = get32(b + 16);
    h->h = get32(b + 20);
    h->used = get32(b + 24);
    h->flags = get32(b + 28);
    memcpy(h->bits, b + 32, 16);
    uint32_t u = get32(b + 48);
    memcpy(&h->tmin, &u, 4);
    u = get32(b + 52);
    memcpy(&h->tscale, &u, 4);
    h->coded_bytes = get32(b + 56);
    return 0;
}

/* Index entry: 0 offset(u64) 8 bytes(u64) 16 step 20 chunk_count 24 crc
 * 28 plain_pages (plain_bytes / 4096; 0 in format_version 1). */
void tvpal_index_entry_encode(const struct tvpal_index_entry *e,
                              unsigned char *b)
{
    memset(b, 0, TVPAL_INDEX_ENTRY_BYTES);
    put64(b, e->offset);
    put64(b + 8, e->bytes);
    put32(b + 16, e->step);
    put32(b + 20, e->chunk_count);
    put32(b + 24, e->crc);
    put32(b + 28, e->coded ? (uint32_t)(e->plain_bytes / TVPAL_ALIGN) : 0u);
}

void tvpal_index_entry_decode(const unsigned char *b,
                              struct tvpal_index_entry *e)
{
    e->offset = get64(b);
    e->bytes = get64(b + 8);
    e->step = get32(b + 16);
    e->chunk_count = get32(b + 20);
    e->crc = get32(b + 24);
    e->coded = get32(b + 28) != 0;
    e->plain_bytes = e->coded ? (uint64_t)get32(b + 28) * TVPAL_ALIGN
                              : e->bytes;
}

/* The bytes chunk k of record `step` (header ch) takes as stored (*cb)
 * and inflated (*plain), checked: a coded chunk's frame is there and
 * claims no more than a zstd frame can hold, any other has no frame size
 * (FORMAT.md 6.11), and the chunk fits in the `left` bytes of the
 * payload.  0 or TVPAL_E_FORMAT naming record, chunk and slice. */
static int chunk_sizes(const struct tvpal_chunk_header *ch,
                       const struct tvpal_shard_header *sh, uint32_t step,
                       uint32_t k, uint64_t left, uint64_t *cb,
                       uint64_t *plain, struct tvpal_diag *diag)
{
    const uint32_t ctf = tvpal_chunk_table_format(sh->table_format,
                                                  ch->flags);
    *plain = tvpal_chunk_bytes(ch->wlen, ch->w, ch->h, ctf);
    *cb = tvpal_chunk_stored_bytes(ch, ctf);
    const int coded = (ch->flags & TVPAL_CHUNK_ZSTD) != 0;
    if (coded ? (ch->coded_bytes == 0 || *cb >= *plain ||
                 *plain / TVPAL_CODED_MAX_RATIO > *cb)
              : ch->coded_bytes != 0)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "record %u: chunk %u (slice %u): a frame of %u "
                              "bytes for %llu bytes %s", step, k, ch->slice,
                              ch->coded_bytes, (unsigned long long)*plain,
                              coded ? "(a coded chunk is smaller than its "
                                      "plain form, and at most 32768 times "
                                      "smaller)"
                                    : "in a chunk not coded (flags bit 2 "
                                      "clear)");
    if (*cb > left)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "record %u: chunk %u (slice %u) overruns the "
                              "payload: %llu bytes with a %s table (flags "
                              "0x%x), %llu left", step, k, ch->slice,
                              (unsigned long long)*cb,
                              (ctf & TVPAL_TABLE_U16) ? "16-bit" : "float32",
                              ch->flags, (unsigned long long)left);
    return 0;
}

/* The checks of FORMAT.md 8.2 item 7 on chunk k of record `step`, whose
 * header ch was read where slice `expect` was due after slice prev:
 * position, window, geometry and flags; *nsl gets the slices it holds.
 * 0 or TVPAL_E_FORMAT naming record, chunk and slice. */
static int check_chunk(const struct tvpal_chunk_header *ch,
                       const struct tvpal_shard_header *sh,
                       const struct tvpal_schedule *sc, uint32_t step,
                       uint32_t k, uint32_t prev, uint32_t expect,
                       uint32_t allowed, uint32_t *nsl,
                       struct tvpal_diag *diag)
{
    const uint32_t slab_end = sh->slice_begin + sh->slice_count;
    if (ch->slice < sh->slice_begin ||
        ch->slice >= sh->slice_begin + sh->slice_count ||
        (k > 0 && ch->slice <= prev) || ch->wstart != step ||
        ch->wlen < 1 || ch->wlen > tvpal_schedule_max_len(sc) ||
        ch->wstart + ch->wlen > sh->steps || ch->w != sh->slice_w ||
        ch->slice != expect ||
        ch->wlen != tvpal_schedule_len(sc, ch->slice, step))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "record %u: chunk %u (slice %u, window "
                              "%u+%u, %ux%u) inconsistent with the shard",
                              step, k, ch->slice, ch->wstart, ch->wlen, ch->w,
                              ch->h);
    /* Its rows are those of k slices of one palette group and of the
     * slab (FORMAT.md 6.5): k = 1 without groups. */
    *nsl = tvpal_chunk_slices(ch, sh);
    if (ch->h != *nsl * sh->slice_h || *nsl < 1 || *nsl > sc->G ||
        *nsl > slab_end - ch->slice ||
        ch->slice / sc->G != (ch->slice + *nsl - 1) / sc->G)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "record %u: chunk %u (slice %u): %u rows, "
                              "expected those of 1 to %u slices of %u "
                              "rows within one palette group of the "
                              "slab", step, k, ch->slice, ch->h, sc->G,
                              sh->slice_h);
    /* A flag the shard's format does not define would be misread:
     * bit 1 changes the chunk's size, and a later bit could change
     * its decoding (FORMAT.md 6.6). */
    if (ch->flags & ~allowed)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "record %u: chunk %u (slice %u): flags "
                              "0x%x, table_format %u allows 0x%x", step,
                              k, ch->slice, ch->flags, sh->table_format,
                              allowed);
    /* The transform bits say how a frame is laid out: no frame, no
     * transform. */
    if ((ch->flags & (TVPAL_CHUNK_TABLE_T2 | TVPAL_CHUNK_INDEX_G)) &&
        !(ch->flags & TVPAL_CHUNK_ZSTD))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "record %u: chunk %u (slice %u): flags "
                              "0x%x: bits 3 and 4 (a coded chunk's "
                              "transform) without bit 2 (coded)", step,
                              k, ch->slice, ch->flags);
    return 0;
}

/* tvpal_record_verify, with (crc = 1) or without the payload CRC. */
static int record_verify(const unsigned char *buf, uint64_t bytes,
                         uint32_t step, const struct tvpal_shard_header *sh,
                         int crc, struct tvpal_diag *diag)
{
    struct tvpal_record_header rh;
    if (bytes < TVPAL_RECORD_HEADER_BYTES)
        return tvpal_diag_set(diag, TVPAL_E_TRUNC, "record %u: %llu bytes",
                              step, (unsigned long long)bytes);
    struct tvpal_diag hd = {{0}};
    int rc = tvpal_record_header_decode(buf, &rh, &hd);
    if (rc < 0) /* name the record: the header's own step is not trusted */
        return tvpal_diag_set(diag, rc, "record %u: %s", step, hd.msg);
    if (rh.step != step || rh.axis != sh->axis)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "record %u: header says step %u axis %u", step,
                              rh.step, rh.axis);
    if (rh.payload_bytes > bytes - TVPAL_RECORD_HEADER_BYTES)
        return tvpal_diag_set(diag, TVPAL_E_TRUNC,
                              "record %u: payload of %llu bytes exceeds the "
                              "record", step,
                              (unsigned long long)rh.payload_bytes);
    if (crc && tvpal_crc32c(0, buf + TVPAL_RECORD_HEADER_BYTES,
                            rh.payload_bytes) != rh.payload_crc)
        return tvpal_diag_set(diag, TVPAL_E_CHECKSUM,
                              "record %u: payload CRC-32C mismatch", step);
    uint64_t pos = TVPAL_RECORD_HEADER_BYTES;
    uint64_t end = pos + rh.payload_bytes;
    uint32_t prev = 0, expect = sh->slice_begin;
    const uint32_t slab_end = sh->slice_begin + sh->slice_count;
    const uint32_t allowed =
        tvpal_chunk_flags_allowed(sh->table_format) |
        (sh->version >= TVPAL_FORMAT_VERSION_CODED ? TVPAL_CHUNK_CODED_BITS
                                                   : 0u);
    const struct tvpal_schedule sc = tvpal_shard_schedule(sh);
    uint64_t plain = 0;  /* the payload once inflated */
    uint32_t nsl = 1;    /* slices of the chunk */
    for (uint32_t k = 0;; k++) {
        /* The chunks are exactly the slab's slices whose window starts at
         * this step, ascending. */
        while (expect < slab_end &&
               !tvpal_schedule_starts(&sc, expect, step))
            expect++;
        if (k == rh.chunk_count) {
            if (expect < slab_end)
                return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                      "record %u: %u chunks, slice %u is "
                                      "missing", step, k, expect);
            break;
        }
        struct tvpal_chunk_header ch;
        if (end - pos < TVPAL_CHUNK_HEADER_BYTES)
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "record %u: chunk %u beyond payload", step,
                                  k);
        rc = tvpal_chunk_header_decode(buf + pos, &ch, NULL);
        if (rc < 0)
            return tvpal_diag_set(diag, rc, "record %u: chunk %u: bad magic",
                                  step, k);
        rc = check_chunk(&ch, sh, &sc, step, k, prev, expect, allowed, &nsl,
                         diag);
        if (rc < 0)
            return rc;
        prev = ch.slice;
        expect += nsl;
        uint64_t cb, plain_cb;
        rc = chunk_sizes(&ch, sh, step, k, end - pos, &cb, &plain_cb, diag);
        if (rc < 0)
            return rc;
        plain += plain_cb;
        pos += cb;
    }
    if (pos != end)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "record %u: %llu payload bytes after the last "
                              "chunk", step,
                              (unsigned long long)(end - pos));
    if (plain != rh.plain_bytes)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "record %u: header says %llu bytes inflated, "
                              "its chunks make %llu", step,
                              (unsigned long long)rh.plain_bytes,
                              (unsigned long long)plain);
    /* The alignment padding is outside the CRC: it must be zeros. */
    for (uint64_t i = end; i < bytes; i++)
        if (buf[i])
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "record %u: non-zero padding at byte %llu",
                                  step, (unsigned long long)i);
    return 0;
}

int tvpal_record_verify(const unsigned char *buf, uint64_t bytes,
                        uint32_t step, const struct tvpal_shard_header *sh,
                        struct tvpal_diag *diag)
{
    return record_verify(buf, bytes, step, sh, 1, diag);
}

int tvpal_record_verify_layout(const unsigned char *buf, uint64_t bytes,
                               uint32_t step,
                               const struct tvpal_shard_header *sh,
                               struct tvpal_diag *diag)
{
    return record_verify(buf, bytes, step, sh, 0, diag);
}

int tvpal_record_next_chunk(const unsigned char *buf, uint64_t *pos,
                            uint32_t table_format, struct tvpal_chunk *c)
{
    uint64_t end = TVPAL_RECORD_HEADER_BYTES + get64(buf + 16);
    if (*pos < TVPAL_RECORD_HEADER_BYTES)
        *pos = TVPAL_RECORD_HEADER_BYTES;
    if (*pos >= end)
        return 0;
    tvpal_chunk_header_decode(buf + *pos, &c->h, NULL);
    c->table_format = tvpal_chunk_table_format(table_format, c->h.flags);
    c->table = buf + *pos + TVPAL_CHUNK_HEADER_BYTES;
    c->indices = c->table + (size_t)c->h.wlen * 256u *
                                tvpal_table_entry_bytes(c->table_format);
    *pos += tvpal_chunk_stored_bytes(&c->h, c->table_format);
    return 1;
}

void tvpal_chunk_table(const struct tvpal_chunk *c, float *out)
{
    const size_t n = (size_t)c->h.wlen * 256;
    if (!(c->table_format & TVPAL_TABLE_U16)) {
        tvpal_load_f32le(c->table, out, n);
        return;
    }
    /* The flag means something only in shards that say so (a version 1
     * reader ignored byte 28). */
    const int missing = (c->table_format & TVPAL_TABLE_MISSING) &&
                        (c->h.flags & TVPAL_CHUNK_MISSING);
    const float t0 = c->h.tmin, ts = c->h.tscale;
    for (size_t i = 0; i < n; i++) {
        unsigned q = (unsigned)c->table[2 * i] | (unsigned)c->table[2 * i + 1] << 8;
        if (missing && q == TVPAL_U16_MISSING) {
            out[i] = NAN;
            continue;
        }
        /* FORMAT.md 6.7: the product rounded to float32, then the sum.  A
         * fused multiply-add (GCC contracts by default on aarch64, and on
         * x86 with -mfma) would change the last bit on some targets; the
         * volatile keeps the two roundings. */
        volatile float p = (float)q * ts;
        out[i] = t0 + p;
    }
}

int tvpal_table_range(const float *table, size_t n, float *lo, float *hi)
{
    int nan = 0, any = 0;
    float a = 0, b = 0;
    for (size_t i = 0; i < n; i++) {
        float v = table[i];
        if (v != v) {
            nan = 1;
            continue;
        }
        if (!any || v < a)
            a = v;
        if (!any || v > b)
            b = v;
        any = 1;
    }
    *lo = a;
    *hi = b;
    return nan;
}

void tvpal_table_store(const float *table, uint32_t len,
                       uint32_t table_format, unsigned char *dst,
                       struct tvpal_chunk_header *h)
{
    tvpal_table_store_steps(table, len, table_format, 0, dst, h);
}

void tvpal_table_store_steps(const float *table, uint32_t len,
                             uint32_t table_format, uint32_t steps,
                             unsigned char *dst, struct tvpal_chunk_header *h)
{
    const size_t n = (size_t)len * 256;
    float lo, hi;
    const int missing = tvpal_table_range(table, n, &lo, &hi);
    h->tmin = 0.0f;
    h->tscale = 0.0f;
    h->flags = missing ? TVPAL_CHUNK_MISSING : 0;
    if (!(table_format & TVPAL_TABLE_U16)) {
        tvpal_store_f32le(table, dst, n);
        return;
    }
    /* Scale in double so that lo + top * scale reaches hi; with missing
     * entries the top code is theirs. */
    const uint32_t most = missing ? 65534u : 65535u;
    const double top = steps && steps < most ? (double)steps : (double)most;
    double scale = ((double)hi - (double)lo) / top;
    h->tmin = lo;
    h->tscale = (float)scale;
    for (size_t i = 0; i < n; i++) {
        unsigned v;
        if (table[i] != table[i]) {
            v = TVPAL_U16_MISSING;
        } else {
            double q = scale > 0 ? ((double)table[i] - lo) / scale + 0.5 : 0.0;
            v = q < 0 ? 0 : q > top ? (unsigned)top : (unsigned)q;
        }
        dst[2 * i] = (unsigned char)v;
        dst[2 * i + 1] = (unsigned char)(v >> 8);
    }
}

void tvpal_load_f32le(const unsigned char *src, float *dst, size_t n)
{
#ifdef WORDS_BIGENDIAN
    for (size_t i = 0; i < n; i++) {
        uint32_t u = get32(src + 4 * i);
        memcpy(dst + i, &u, 4);
    }
#else
    memcpy(dst, src, n * 4);
#endif
}

void tvpal_store_f32le(const float *src, unsigned char *dst, size_t n)
{
#ifdef WORDS_BIGENDIAN
    for (size_t i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, src + i, 4);
        put32(dst + 4 * i, u);
    }
#else
    memcpy(dst, src, n * 4);
#endif
}
