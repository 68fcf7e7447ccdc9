/* tvpal_shard.c: shard file writer, reader and slab decoding state. */
#include "tvpal_shard.h"
#include "tvpal_chunkz.h"
#include "tvpal_crc32c.h"
#include "tvpal_schedule.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* pwrite/pread the whole range, retrying short transfers and EINTR.  A
 * failed write puts its cause (errno's text) in diag. */
static int pwrite_all(int fd, const void *buf, uint64_t n, uint64_t off,
                      struct tvpal_diag *diag)
{
    const unsigned char *p = buf;
    while (n) {
        ssize_t k = pwrite(fd, p, n > (1u << 30) ? (1u << 30) : n, (off_t)off);
        if (k < 0) {
            if (errno == EINTR)
                continue;
            return tvpal_diag_set(diag, TVPAL_E_WRITE, "write at byte %llu: %s",
                                  (unsigned long long)off, strerror(errno));
        }
        p += k;
        n -= (uint64_t)k;
        off += (uint64_t)k;
    }
    return 0;
}

static int pread_all(int fd, void *buf, uint64_t n, uint64_t off)
{
    unsigned char *p = buf;
    while (n) {
        ssize_t k = pread(fd, p, n > (1u << 30) ? (1u << 30) : n, (off_t)off);
        if (k < 0) {
            if (errno == EINTR)
                continue;
            return TVPAL_E_READ;
        }
        if (k == 0)
            return TVPAL_E_TRUNC;
        p += k;
        n -= (uint64_t)k;
        off += (uint64_t)k;
    }
    return 0;
}

/* ------------------------------------------------------------------ writer */

struct tvpal_shardw {
    int fd;
    struct tvpal_shard_header h;
    struct tvpal_index_entry *index;  /* h.steps entries */
    uint32_t done;                    /* records appended */
    uint64_t end;                     /* file offset after them */
    int missing;                      /* a chunk flagged missing entries */
    /* Placed writing (NULL arrays when appending): per record its offset,
     * payload bytes, chunk count and progress; per slab slice its chunk's
     * offset in record 0's payload.  A per-chunk shard (table_format 4,
     * 5) is laid out with float32 room for every chunk until finish packs
     * it (placed_pack), which moves the records and sets packed. */
    uint64_t *rec_off, *payload, *filled;
    uint32_t *count, *crc;
    uint64_t *first_off;
    int packed;
    /* Coded chunks (FORMAT.md 6.11): coding, the caller may put them
     * (tvpal_shardw_set_coding), so finish packs; coded, packing found
     * one (put_chunk takes them only with coding), so the shard is
     * format_version 2; plain[t], record t's payload inflated. */
    int coding, coded;
    uint64_t *plain;
    uint8_t *rcoded;                  /* record t has a coded chunk */
};

/* Whether a chunk of the sealed record buf says its table has missing
 * entries: the shard's table_format then gets TVPAL_TABLE_MISSING. */
static int record_has_missing(const unsigned char *buf, uint32_t table_format)
{
    uint64_t pos = 0;
    struct tvpal_chunk c;
    while (tvpal_record_next_chunk(buf, &pos, table_format, &c))
        if (c.h.flags & TVPAL_CHUNK_MISSING)
            return 1;
    return 0;
}

static int shardw_alloc(struct tvpal_shardw **out,
                        const struct tvpal_shard_header *h)
{
    struct tvpal_shardw *w = calloc(1, sizeof *w);
    if (!w)
        return TVPAL_E_NOMEM;
    w->fd = -1;
    w->h = *h;
    w->index = calloc(h->steps, sizeof *w->index);
    if (!w->index) {
        free(w);
        return TVPAL_E_NOMEM;
    }
    w->end = TVPAL_SHARD_HEADER_BYTES;
    *out = w;
    return 0;
}

int tvpal_shardw_create(struct tvpal_shardw **out, const char *path,
                        const struct tvpal_shard_header *h)
{
    struct tvpal_shardw *w;
    int rc = shardw_alloc(&w, h);
    if (rc < 0)
        return rc;
    w->fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (w->fd < 0) {
        tvpal_shardw_free(w);
        return TVPAL_E_OPEN;
    }
    static const unsigned char zero[TVPAL_SHARD_HEADER_BYTES];
    rc = pwrite_all(w->fd, zero, sizeof zero, 0, NULL);
    if (rc < 0) {
        tvpal_shardw_free(w);
        return rc;
    }
    *out = w;
    return 0;
}

int tvpal_shardw_resume(struct tvpal_shardw **out, const char *path,
                        const struct tvpal_shard_header *h,
                        uint32_t steps_done, struct tvpal_diag *diag)
{
    struct tvpal_shardw *w;
    unsigned char *buf = NULL;
    uint64_t cap = 0;
    if (steps_done > h->steps)
        return TVPAL_E_INVAL;
    int rc = shardw_alloc(&w, h);
    if (rc < 0)
        return rc;
    w->fd = open(path, O_RDWR | O_CLOEXEC);
    if (w->fd < 0) {
        rc = tvpal_diag_set(diag, TVPAL_E_OPEN, "cannot reopen partial shard");
        goto err;
    }
    for (uint32_t t = 0; t < steps_done; t++) {
        unsigned char hb[TVPAL_RECORD_HEADER_BYTES];
        struct tvpal_record_header rh;
        rc = pread_all(w->fd, hb, sizeof hb, w->end);
        if (rc < 0) {
            tvpal_diag_set(diag, rc, "record %u: cannot read header", t);
            goto err;
        }
        rc = tvpal_record_header_decode(hb, &rh, diag);
        if (rc < 0)
            goto err;
        uint64_t bytes = tvpal_round_up(TVPAL_RECORD_HEADER_BYTES +
                                            rh.payload_bytes, TVPAL_ALIGN);
        if (bytes > cap) {
            free(buf);
            cap = bytes;
            buf = malloc(cap);
            if (!buf) {
                rc = TVPAL_E_NOMEM;
                goto err;
            }
        }
        rc = pread_all(w->fd, buf, bytes, w->end);
        if (rc < 0) {
            tvpal_diag_set(diag, rc, "record %u: cannot read", t);
            goto err;
        }
        rc = tvpal_record_verify(buf, bytes, t, h, diag);
        if (rc < 0)
            goto err;
        w->index[t] = (struct tvpal_index_entry){
            .offset = w->end, .bytes = bytes, .step = t,
            .chunk_count = rh.chunk_count, .crc = rh.payload_crc};
        w->missing |= record_has_missing(buf, h->table_format);
        w->end += bytes;
    }
    w->done = steps_done;
    if (ftruncate(w->fd, (off_t)w->end) < 0) {
        rc = TVPAL_E_WRITE;
        goto err;
    }
    free(buf);
    *out = w;
    return 0;
err:
    free(buf);
    tvpal_shardw_free(w);
    return rc;
}

void tvpal_shardw_set_range(struct tvpal_shardw *w, double lo, double hi)
{
    w->h.value_min = lo;
    w->h.value_max = hi;
}

uint64_t tvpal_shardw_size(const struct tvpal_shardw *w)
{
    return w->end;
}

int tvpal_shardw_append(struct tvpal_shardw *w, const unsigned char *buf,
                        uint64_t bytes, struct tvpal_diag *diag)
{
    if (w->rec_off || w->done >= w->h.steps || bytes % TVPAL_ALIGN)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "record %u of %u, %llu "
                              "bytes", w->done, w->h.steps,
                              (unsigned long long)bytes);
    int rc = pwrite_all(w->fd, buf, bytes, w->end, diag);
    if (rc < 0)
        return rc;
    struct tvpal_record_header rh;
    tvpal_record_header_decode(buf, &rh, NULL);
    w->index[w->done] = (struct tvpal_index_entry){
        .offset = w->end, .bytes = bytes, .step = w->done,
        .chunk_count = rh.chunk_count, .crc = rh.payload_crc};
    w->missing |= record_has_missing(buf, w->h.table_format);
    w->done++;
    w->end += bytes;
    return 0;
}

static int placed_seal(struct tvpal_shardw *w, struct tvpal_diag *diag);

int tvpal_shardw_finish(struct tvpal_shardw *w, struct tvpal_diag *diag)
{
    int rc = 0;
    unsigned char *ib = NULL;
    if (w->rec_off && (rc = placed_seal(w, diag)) < 0)
        goto out;
    if (w->done != w->h.steps) {
        rc = tvpal_diag_set(diag, TVPAL_E_INVAL, "%u of %u records written",
                            w->done, w->h.steps);
        goto out;
    }
    uint64_t ibytes = tvpal_round_up((uint64_t)w->h.steps *
                                         TVPAL_INDEX_ENTRY_BYTES, TVPAL_ALIGN);
    ib = calloc(1, ibytes);
    if (!ib) {
        rc = TVPAL_E_NOMEM;
        goto out;
    }
    for (uint32_t t = 0; t < w->h.steps; t++)
        tvpal_index_entry_encode(&w->index[t],
                                 ib + (size_t)t * TVPAL_INDEX_ENTRY_BYTES);
    w->h.index_offset = w->end;
    w->h.file_bytes = w->end + ibytes;
    w->h.index_crc = tvpal_crc32c(0, ib, ibytes);
    w->h.version = w->h.group > 1 ? TVPAL_FORMAT_VERSION_GROUPED
                   : w->h.schedule == TVPAL_SCHEDULE_JOINED
                       ? TVPAL_FORMAT_VERSION_JOINED
                   : w->coded ? TVPAL_FORMAT_VERSION_CODED
                              : TVPAL_FORMAT_VERSION;
    if (w->missing)
        w->h.table_format = tvpal_table_with_missing(w->h.table_format);
    rc = pwrite_all(w->fd, ib, ibytes, w->end, diag);
    if (rc < 0)
        goto out;
    /* A packed shard is shorter than the room it was written in. */
    if (w->packed && ftruncate(w->fd, (off_t)w->h.file_bytes) < 0) {
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "cannot cut to %llu bytes: "
                            "%s", (unsigned long long)w->h.file_bytes,
                            strerror(errno));
        goto out;
    }
    unsigned char hb[TVPAL_SHARD_HEADER_BYTES];
    tvpal_shard_header_encode(&w->h, hb);
    /* Header last: the file becomes valid only once everything is there. */
    if (fdatasync(w->fd) < 0) {
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "fdatasync: %s",
                            strerror(errno));
        goto out;
    }
    rc = pwrite_all(w->fd, hb, sizeof hb, 0, diag);
    if (rc == 0 && fsync(w->fd) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "fsync: %s", strerror(errno));
out:
    free(ib);
    if (w->fd >= 0 && close(w->fd) < 0 && rc == 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "close: %s", strerror(errno));
    w->fd = -1;
    tvpal_shardw_free(w);
    return rc;
}

void tvpal_shardw_free(struct tvpal_shardw *w)
{
    if (!w)
        return;
    if (w->fd >= 0)
        close(w->fd);
    free(w->index);
    free(w->rec_off);
    free(w->payload);
    free(w->filled);
    free(w->count);
    free(w->crc);
    free(w->first_off);
    free(w->plain);
    free(w->rcoded);
    free(w);
}

/* ---------------------------------------------------------- placed writer */

/* Room of the chunk of slice s in record t: its size, or in a per-chunk
 * shard the size of a float32 chunk. */
static uint64_t placed_chunk_bytes(const struct tvpal_shardw *w, uint32_t s,
                                   uint32_t t)
{
    const struct tvpal_shard_header *h = &w->h;
    const struct tvpal_schedule sc = tvpal_shard_schedule(h);
    return tvpal_chunk_bytes(tvpal_schedule_len(&sc, s, t), h->slice_w,
                             h->slice_h, h->table_format);
}

/* The layout of every record (FORMAT.md 6.3) from the header alone. */
static int placed_layout(struct tvpal_shardw *w)
{
    const struct tvpal_shard_header *h = &w->h;
    const uint32_t T = h->steps;
    const struct tvpal_schedule sc = tvpal_shard_schedule(h);
    w->rec_off = calloc(T, sizeof *w->rec_off);
    w->payload = calloc(T, sizeof *w->payload);
    w->filled = calloc(T, sizeof *w->filled);
    w->count = calloc(T, sizeof *w->count);
    w->crc = calloc(T, sizeof *w->crc);
    w->first_off = calloc(h->slice_count, sizeof *w->first_off);
    w->plain = calloc(T, sizeof *w->plain);
    w->rcoded = calloc(T, sizeof *w->rcoded);
    if (!w->rec_off || !w->payload || !w->filled || !w->count || !w->crc ||
        !w->first_off || !w->plain || !w->rcoded)
        return TVPAL_E_NOMEM;
    uint64_t at = TVPAL_SHARD_HEADER_BYTES;
    for (uint32_t t = 0; t < T; t++) {
        uint64_t pay = 0;
        uint32_t n = 0;
        for (uint32_t k = 0; k < h->slice_count; k++) {
            uint32_t s = h->slice_begin + k;
            if (!tvpal_schedule_starts(&sc, s, t))
                continue;
            if (t == 0)
                w->first_off[k] = pay;
            pay += placed_chunk_bytes(w, s, t);
            n++;
        }
        w->rec_off[t] = at;
        w->payload[t] = pay;
        w->count[t] = n;
        at += tvpal_round_up(TVPAL_RECORD_HEADER_BYTES + pay, TVPAL_ALIGN);
    }
    w->end = at;
    return 0;
}

/* Slices of [lo, hi) in the palette groups of phase r. */
static uint64_t phase_slices(const struct tvpal_schedule *sc, uint32_t lo,
                             uint32_t hi, uint32_t r)
{
    const uint64_t G = sc->G, N = sc->N;
    uint64_t n = 0, g = lo / G;
    g += (r + N - g % N) % N;
    for (; g * G < hi; g += N) {
        const uint64_t a = g * G < lo ? lo : g * G;
        const uint64_t b = g * G + G < hi ? g * G + G : hi;
        n += b - a;
    }
    return n;
}

/* Offset of slice s's chunk (its room) inside record t's payload, or
 * UINT64_MAX when s has no window starting at t or is not in the slab.
 * After record 0 every chunk of a record has the same room, one per
 * slice: a chunk of k slices of a palette group takes their k rooms. */
static uint64_t placed_offset(const struct tvpal_shardw *w, uint32_t t,
                              uint32_t s)
{
    const struct tvpal_shard_header *h = &w->h;
    const struct tvpal_schedule sc = tvpal_shard_schedule(h);
    if (t >= h->steps || s < h->slice_begin ||
        s - h->slice_begin >= h->slice_count ||
        !tvpal_schedule_starts(&sc, s, t))
        return UINT64_MAX;
    if (t == 0)
        return w->first_off[s - h->slice_begin];
    /* The slab's slices of phase t mod N before s. */
    return phase_slices(&sc, h->slice_begin, s, t % h->window) *
           placed_chunk_bytes(w, s, t);
}

/* The rooms of the k slices from s in record t: 0 unless all k are in
 * the slab and in s's palette group (they then start together). */
static uint64_t placed_rooms(const struct tvpal_shardw *w, uint32_t t,
                             uint32_t s, uint32_t k)
{
    const struct tvpal_shard_header *h = &w->h;
    const uint32_t G = h->group ? h->group : 1;
    if (k < 1 || k > G || s < h->slice_begin ||
        k > h->slice_begin + h->slice_count - s || s / G != (s + k - 1) / G)
        return 0;
    return k * placed_chunk_bytes(w, s, t);
}

static int placed_open(struct tvpal_shardw **out, const char *path,
                       const struct tvpal_shard_header *h, int create,
                       struct tvpal_diag *diag)
{
    struct tvpal_shardw *w = NULL;
    int rc = shardw_alloc(&w, h);
    if (rc == 0)
        rc = placed_layout(w);
    if (rc < 0) {
        tvpal_shardw_free(w);
        return rc;
    }
    w->fd = create ? open(path, O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)
                   : open(path, O_RDWR | O_CLOEXEC);
    if (w->fd < 0) {
        rc = tvpal_diag_set(diag, TVPAL_E_OPEN, "%s", strerror(errno));
        tvpal_shardw_free(w);
        return rc;
    }
    struct stat st;
    if (create) {
        /* The records' room, all zeros (headers included) until finish. */
        if (ftruncate(w->fd, (off_t)w->end) < 0)
            rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "cannot size to %llu "
                                "bytes: %s", (unsigned long long)w->end,
                                strerror(errno));
    } else if (fstat(w->fd, &st) < 0) {
        rc = tvpal_diag_set(diag, TVPAL_E_READ, "%s", strerror(errno));
    } else if ((uint64_t)st.st_size != w->end) {
        rc = tvpal_diag_set(diag, (uint64_t)st.st_size < w->end
                                      ? TVPAL_E_TRUNC : TVPAL_E_MISMATCH,
                            "%lld bytes; expected %llu",
                            (long long)st.st_size,
                            (unsigned long long)w->end);
    }
    if (rc < 0) {
        tvpal_shardw_free(w);
        return rc;
    }
    *out = w;
    return 0;
}

int tvpal_shardw_create_placed(struct tvpal_shardw **out, const char *path,
                               const struct tvpal_shard_header *h,
                               struct tvpal_diag *diag)
{
    return placed_open(out, path, h, 1, diag);
}

int tvpal_shardw_reopen_placed(struct tvpal_shardw **out, const char *path,
                               const struct tvpal_shard_header *h,
                               struct tvpal_diag *diag)
{
    return placed_open(out, path, h, 0, diag);
}

int tvpal_shardw_put_chunk(struct tvpal_shardw *w, uint32_t t, uint32_t s,
                           const unsigned char *chunk, uint64_t bytes,
                           uint32_t *crc, struct tvpal_diag *diag)
{
    uint64_t off = w->rec_off ? placed_offset(w, t, s) : UINT64_MAX;
    struct tvpal_chunk_header ch;
    int have = tvpal_chunk_header_decode(chunk, &ch, NULL) == 0;
    const uint32_t k = have ? tvpal_chunk_slices(&ch, &w->h) : 1;
    if (off == UINT64_MAX || bytes != placed_rooms(w, t, s, k))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "no chunk of %llu bytes "
                              "for %u slices from %u in record %u",
                              (unsigned long long)bytes, k, s, t);
    /* The missing flag is what finish adds to the format: allow it; a
     * coded chunk makes the shard format_version 2, when the writer takes
     * them (its room: the chunk, zeros after it). */
    const uint32_t coded = w->coding ? TVPAL_CHUNK_CODED_BITS : 0u;
    if (have && (ch.flags & ~(tvpal_chunk_flags_allowed(w->h.table_format) |
                              TVPAL_CHUNK_MISSING | coded)))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "chunk of slice %u in "
                              "record %u: flags 0x%x in a shard of "
                              "table_format %u", s, t, ch.flags,
                              w->h.table_format);
    int rc = pwrite_all(w->fd, chunk, bytes,
                        w->rec_off[t] + TVPAL_RECORD_HEADER_BYTES + off, diag);
    if (rc < 0)
        return rc;
    *crc = tvpal_crc32c(0, chunk, bytes);
    if (have && (ch.flags & TVPAL_CHUNK_MISSING))
        __atomic_store_n(&w->missing, 1, __ATOMIC_RELAXED);
    return 0;
}

void tvpal_shardw_set_coding(struct tvpal_shardw *w, int on)
{
    w->coding = on != 0;
}

int tvpal_shardw_extend(struct tvpal_shardw *w, uint32_t t, uint32_t s,
                        uint32_t slices, uint32_t crc)
{
    uint64_t off = w->rec_off ? placed_offset(w, t, s) : UINT64_MAX;
    const uint64_t bytes = off == UINT64_MAX ? 0
                                             : placed_rooms(w, t, s, slices);
    if (!bytes || off != w->filled[t])
        return TVPAL_E_INVAL;
    w->crc[t] = tvpal_crc32c_combine(w->crc[t], crc, bytes);
    w->filled[t] += bytes;
    return 0;
}

void tvpal_shardw_progress(const struct tvpal_shardw *w, uint32_t t,
                           uint64_t *filled, uint32_t *crc)
{
    *filled = w->filled[t];
    *crc = w->crc[t];
}

int tvpal_shardw_set_progress(struct tvpal_shardw *w, uint32_t t,
                              uint64_t filled, uint32_t crc,
                              struct tvpal_diag *diag)
{
    if (!w->rec_off || t >= w->h.steps || filled > w->payload[t])
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "record %u: %llu payload "
                              "bytes is more than it has", t,
                              (unsigned long long)filled);
    /* Read back what the checkpoint says is there: chunks written after
     * the last sync may be lost (power loss), and a record must not get a
     * header whose CRC its bytes do not have. */
    static const uint64_t block = 1u << 20;
    unsigned char *buf = malloc(filled < block ? (filled ? filled : 1)
                                               : block);
    if (!buf)
        return TVPAL_E_NOMEM;
    uint32_t c = 0;
    uint64_t base = w->rec_off[t] + TVPAL_RECORD_HEADER_BYTES;
    int rc = 0;
    for (uint64_t at = 0; at < filled && rc == 0; at += block) {
        uint64_t n = filled - at < block ? filled - at : block;
        rc = pread_all(w->fd, buf, n, base + at);
        c = tvpal_crc32c(c, buf, n);
    }
    free(buf);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "record %u: cannot read back", t);
    if (c != crc)
        return tvpal_diag_set(diag, TVPAL_E_CHECKSUM, "record %u: the %llu "
                              "bytes written do not have the checkpoint's "
                              "CRC", t, (unsigned long long)filled);
    w->filled[t] = filled;
    w->crc[t] = crc;
    return 0;
}

int tvpal_shardw_missing(const struct tvpal_shardw *w)
{
    return __atomic_load_n(&w->missing, __ATOMIC_RELAXED);
}

void tvpal_shardw_set_missing(struct tvpal_shardw *w, int missing)
{
    w->missing = missing != 0;
}

/* Packs a per-chunk shard (table_format 4, 5), written with float32 room
 * for every chunk, into the layout of FORMAT.md 6.3 where each chunk takes
 * its own size (9.1).  In file order, each chunk's room is read and added
 * to its record's CRC as written (checked against w->crc once the record
 * is read), and the chunk is written at its packed place.  A packed place
 * is never after the room it comes from, and a chunk ends no later than
 * its room, so nothing is overwritten before it is read.  Sets the
 * records' offsets, payloads and CRCs to the packed ones, w->end and
 * w->packed.  0, TVPAL_E_NOMEM, TVPAL_E_READ, TVPAL_E_TRUNC,
 * TVPAL_E_CHECKSUM or TVPAL_E_WRITE, named in diag. */
static int placed_pack(struct tvpal_shardw *w, struct tvpal_diag *diag)
{
    static const unsigned char zero[TVPAL_ALIGN];
    const struct tvpal_shard_header *h = &w->h;
    const struct tvpal_schedule sc = tvpal_shard_schedule(h);
    const uint32_t G = sc.G;
    unsigned char *buf = malloc(tvpal_chunk_bytes(
        tvpal_schedule_max_len(&sc), h->slice_w, h->slice_h,
        h->table_format) * G);
    if (!buf)
        return TVPAL_E_NOMEM;
    int rc = 0;
    uint64_t at = TVPAL_SHARD_HEADER_BYTES; /* record t's packed offset */
    for (uint32_t t = 0; t < h->steps && rc == 0; t++) {
        uint64_t src = w->rec_off[t] + TVPAL_RECORD_HEADER_BYTES, pay = 0;
        uint64_t plain = 0;
        uint32_t room_crc = 0, crc = 0, chunks = 0;
        for (uint32_t k = 0; k < h->slice_count && rc == 0; k++) {
            const uint32_t s = h->slice_begin + k;
            if (!tvpal_schedule_starts(&sc, s, t))
                continue;
            /* A chunk of a palette group's slices takes their rooms. */
            struct tvpal_chunk_header ch = {0};
            uint64_t room = placed_chunk_bytes(w, s, t);
            rc = pread_all(w->fd, buf, room, src);
            (void)tvpal_chunk_header_decode(buf, &ch, NULL);
            uint32_t nsl = tvpal_chunk_slices(&ch, h);
            const uint64_t rooms = placed_rooms(w, t, s, nsl);
            if (rc == 0 && rooms > room) {
                rc = pread_all(w->fd, buf + room, rooms - room, src + room);
                room = rooms;
            } else if (rooms < room) {
                nsl = 1;
            }
            if (rc < 0) {
                tvpal_diag_set(diag, rc, "record %u: cannot read back the "
                               "chunk of slice %u", t, s);
                break;
            }
            room_crc = tvpal_crc32c(room_crc, buf, room);
            /* The size from the schedule and the chunk's flags (a coded
             * one: its frame's, within the room); a damaged room fails the
             * CRC below. */
            ch.wlen = tvpal_schedule_len(&sc, s, t);
            ch.w = h->slice_w;
            ch.h = h->slice_h * nsl;
            k += nsl - 1;
            chunks++;
            const uint32_t ctf = tvpal_chunk_table_format(h->table_format,
                                                          ch.flags);
            uint64_t n = tvpal_chunk_stored_bytes(&ch, ctf);
            if (n > room)
                n = room;
            if (ch.flags & TVPAL_CHUNK_ZSTD)
                w->coded = w->rcoded[t] = 1;
            plain += tvpal_chunk_bytes(ch.wlen, ch.w, ch.h, ctf);
            rc = pwrite_all(w->fd, buf, n,
                            at + TVPAL_RECORD_HEADER_BYTES + pay, diag);
            crc = tvpal_crc32c(crc, buf, n);
            pay += n;
            src += room;
        }
        if (rc == 0 && room_crc != w->crc[t])
            rc = tvpal_diag_set(diag, TVPAL_E_CHECKSUM, "record %u: the "
                                "chunks read back do not have the CRC they "
                                "were written with", t);
        /* The padding held room of the chunks: zero it (no CRC covers
         * it, and readers require zeros). */
        const uint64_t used = TVPAL_RECORD_HEADER_BYTES + pay;
        const uint64_t total = tvpal_round_up(used, TVPAL_ALIGN);
        if (rc == 0 && total > used)
            rc = pwrite_all(w->fd, zero, total - used, at + used, diag);
        w->rec_off[t] = at;
        w->payload[t] = w->filled[t] = pay;
        w->crc[t] = crc;
        w->plain[t] = plain;
        w->count[t] = chunks;
        at += total;
    }
    free(buf);
    if (rc == 0) {
        w->end = at;
        w->packed = 1;
    }
    return rc;
}

/* Writes every record header of a placed shard once all payloads are in
 * (a per-chunk shard packed first), and fills the index as appending
 * would have. */
static int placed_seal(struct tvpal_shardw *w, struct tvpal_diag *diag)
{
    for (uint32_t t = 0; t < w->h.steps; t++)
        if (w->filled[t] != w->payload[t])
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "record %u: %llu of "
                                  "%llu payload bytes written", t,
                                  (unsigned long long)w->filled[t],
                                  (unsigned long long)w->payload[t]);
    if (w->h.table_format >= TVPAL_TABLE_CHUNK || w->coding ||
        w->h.group > 1) {
        int rc = placed_pack(w, diag);
        if (rc < 0)
            return rc;
    } else {
        for (uint32_t t = 0; t < w->h.steps; t++)
            w->plain[t] = w->payload[t];
    }
    for (uint32_t t = 0; t < w->h.steps; t++) {
        /* Format version 1 keeps bytes 32..39 zero (FORMAT.md 6.4). */
        struct tvpal_record_header rh = {
            .step = t, .chunk_count = w->count[t], .axis = w->h.axis,
            .payload_bytes = w->payload[t], .payload_crc = w->crc[t],
            .plain_bytes = w->coded ? w->plain[t] : 0};
        const uint64_t plain_rec = tvpal_round_up(
            TVPAL_RECORD_HEADER_BYTES + w->plain[t], TVPAL_ALIGN);
        if (plain_rec / TVPAL_ALIGN > UINT32_MAX)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "record %u: %llu "
                                  "bytes inflated, more than an index entry "
                                  "holds", t, (unsigned long long)plain_rec);
        unsigned char hb[TVPAL_RECORD_HEADER_BYTES];
        tvpal_record_header_encode(&rh, hb);
        int rc = pwrite_all(w->fd, hb, sizeof hb, w->rec_off[t], diag);
        if (rc < 0)
            return rc;
        w->index[t] = (struct tvpal_index_entry){
            .offset = w->rec_off[t],
            .bytes = tvpal_round_up(TVPAL_RECORD_HEADER_BYTES +
                                        w->payload[t], TVPAL_ALIGN),
            .step = t, .chunk_count = w->count[t], .crc = w->crc[t]};
        w->index[t].coded = w->rcoded[t];
        w->index[t].plain_bytes = w->rcoded[t] ? plain_rec : w->index[t].bytes;
    }
    w->done = w->h.steps;
    return 0;
}

uint64_t tvpal_record_seal(unsigned char *buf, uint32_t step, uint32_t axis,
                           uint32_t chunk_count, uint64_t payload_bytes)
{
    struct tvpal_record_header rh = {
        .step = step, .chunk_count = chunk_count, .axis = axis,
        .payload_bytes = payload_bytes,
        .payload_crc = tvpal_crc32c(0, buf + TVPAL_RECORD_HEADER_BYTES,
                                    payload_bytes)};
    tvpal_record_header_encode(&rh, buf);
    uint64_t used = TVPAL_RECORD_HEADER_BYTES + payload_bytes;
    uint64_t total = tvpal_round_up(used, TVPAL_ALIGN);
    memset(buf + used, 0, total - used);
    return total;
}

/* ------------------------------------------------------------------ reader */

struct tvpal_shard {
    int fd;
    char *path;
    struct tvpal_shard_header h;
    struct tvpal_index_entry *index;
    uint64_t max_record;        /* of the records' buffers */
    int coded;                  /* some record has coded chunks */
    uint64_t ram_bytes;         /* all the records' buffers */
    struct tvpal_chunkz *z;     /* read_record's inflater, at first need */
    struct tvpal_table_count counted;   /* count_tables' result, once */
    int have_counted;
};

/* Smallest record bytes for step t that the header's geometry implies:
 * the 64-byte record header plus, for every palette group (a slice
 * without groups) whose window starts at t, one chunk (tvpal_chunk_bytes)
 * of its slab slices: a group's slices may share one (FORMAT.md 6.3).
 * Stops counting once the sum exceeds cap (returning a value > cap), so
 * the work is bounded by cap and not by a forged slice_count, and the sum
 * never overflows. */
static uint64_t record_min_bytes(const struct tvpal_shard_header *h,
                                 uint32_t t, uint64_t cap)
{
    uint64_t need = TVPAL_RECORD_HEADER_BYTES;
    const struct tvpal_schedule sc = tvpal_shard_schedule(h);
    const uint64_t N = h->window, G = sc.G, begin = h->slice_begin,
                   end = begin + h->slice_count;
    /* Groups with starts(s, t): all at t == 0, else every N-th from the
     * first of tvpal_schedule_phase's phase (none: an empty record). */
    uint64_t g = begin / G, stride = 1;
    uint32_t r;
    if (t > 0) {
        if (!tvpal_schedule_phase(&sc, t, &r))
            return need;
        stride = N;
        g += (r + N - g % N) % N;
    }
    /* In a per-chunk shard a chunk is at least a 16-bit one. */
    const uint32_t tf = h->table_format >= TVPAL_TABLE_CHUNK ? TVPAL_TABLE_U16
                                                             : h->table_format;
    for (; g * G < end; g += stride) {
        const uint64_t lo = g * G < begin ? begin : g * G;
        const uint64_t hi = g * G + G < end ? g * G + G : end;
        uint32_t len = tvpal_schedule_len(&sc, (uint32_t)lo, t);
        uint64_t cb = tvpal_chunk_bytes(len, h->slice_w,
                                        h->slice_h * (uint32_t)(hi - lo), tf);
        if (cb > cap - need)
            return cap + 1;
        need += cb;
    }
    return need;
}

/* Every record of the index is large enough for the chunks the header's
 * slice geometry implies (8.1 rule 18), so the file size bounds
 * slice_count * slice_w * slice_h and what a slab allocates from them.
 * 0, or TVPAL_E_FORMAT naming the first record too small. */
static int check_record_sizes(const struct tvpal_shard *s,
                              struct tvpal_diag *diag)
{
    for (uint32_t t = 0; t < s->h.steps; t++) {
        uint64_t have = s->index[t].plain_bytes;
        uint64_t need = record_min_bytes(&s->h, t, have);
        if (need > have)
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "record index: entry %u holds %llu bytes, "
                                  "too small for the chunks of %u slices of "
                                  "%ux%u the header implies", t,
                                  (unsigned long long)have,
                                  s->h.slice_count, s->h.slice_w,
                                  s->h.slice_h);
    }
    return 0;
}

int tvpal_shard_open(struct tvpal_shard **out, const char *path,
                     struct tvpal_diag *diag)
{
    int rc;
    unsigned char *ib = NULL;
    unsigned char hb[TVPAL_SHARD_HEADER_BYTES];
    struct tvpal_shard *s = calloc(1, sizeof *s);
    if (!s)
        return TVPAL_E_NOMEM;
    s->fd = open(path, O_RDONLY | O_CLOEXEC);
    int open_errno = errno;
    s->path = strdup(path);
    if (!s->path) {
        rc = TVPAL_E_NOMEM;
        goto err;
    }
    if (s->fd < 0) {
        rc = tvpal_diag_set(diag, TVPAL_E_OPEN, "%s", strerror(open_errno));
        goto err;
    }
    struct stat st;
    if (fstat(s->fd, &st) < 0) {
        rc = TVPAL_E_READ;
        goto err;
    }
    if ((uint64_t)st.st_size < TVPAL_SHARD_HEADER_BYTES) {
        rc = tvpal_diag_set(diag, TVPAL_E_TRUNC,
                            "%lld bytes, shorter than the %u-byte header",
                            (long long)st.st_size, TVPAL_SHARD_HEADER_BYTES);
        goto err;
    }
    rc = pread_all(s->fd, hb, sizeof hb, 0);
    if (rc < 0)
        goto err;
    rc = tvpal_shard_header_decode(hb, &s->h, diag);
    if (rc < 0)
        goto err;
    if ((uint64_t)st.st_size != s->h.file_bytes) {
        rc = tvpal_diag_set(diag, (uint64_t)st.st_size < s->h.file_bytes ?
                            TVPAL_E_TRUNC : TVPAL_E_FORMAT,
                            "file is %lld bytes, header says %llu",
                            (long long)st.st_size,
                            (unsigned long long)s->h.file_bytes);
        goto err;
    }
    uint64_t ibytes = s->h.file_bytes - s->h.index_offset;
    ib = malloc(ibytes);
    s->index = calloc(s->h.steps, sizeof *s->index);
    if (!ib || !s->index) {
        rc = TVPAL_E_NOMEM;
        goto err;
    }
    rc = pread_all(s->fd, ib, ibytes, s->h.index_offset);
    if (rc < 0)
        goto err;
    if (tvpal_crc32c(0, ib, ibytes) != s->h.index_crc) {
        rc = tvpal_diag_set(diag, TVPAL_E_CHECKSUM,
                            "record index: CRC-32C mismatch");
        goto err;
    }
    uint64_t expect = TVPAL_SHARD_HEADER_BYTES;
    for (uint32_t t = 0; t < s->h.steps; t++) {
        struct tvpal_index_entry *e = &s->index[t];
        tvpal_index_entry_decode(ib + (size_t)t * TVPAL_INDEX_ENTRY_BYTES, e);
        if (e->step != t || e->offset != expect || !e->bytes ||
            e->bytes % TVPAL_ALIGN || e->bytes > s->h.index_offset - expect) {
            rc = tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                "record index: entry %u (offset %llu, %llu "
                                "bytes) out of place", t,
                                (unsigned long long)e->offset,
                                (unsigned long long)e->bytes);
            goto err;
        }
        /* Inflated, a record is at least what it is stored as and at
         * most TVPAL_CODED_MAX_RATIO times that (6.11); version 1 has no
         * coded records. */
        if (e->coded && (s->h.version == TVPAL_FORMAT_VERSION ||
                         e->plain_bytes < e->bytes ||
                         e->plain_bytes / TVPAL_CODED_MAX_RATIO > e->bytes)) {
            rc = tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                "record index: entry %u: %llu bytes "
                                "inflated from %llu (format_version %u)", t,
                                (unsigned long long)e->plain_bytes,
                                (unsigned long long)e->bytes, s->h.version);
            goto err;
        }
        expect += e->bytes;
        s->ram_bytes += tvpal_record_buffer_bytes(e);
        if (tvpal_record_buffer_bytes(e) > s->max_record)
            s->max_record = tvpal_record_buffer_bytes(e);
        s->coded |= e->coded != 0;
    }
    if (expect != s->h.index_offset) {
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT,
                            "record index: records end at %llu, index at %llu",
                            (unsigned long long)expect,
                            (unsigned long long)s->h.index_offset);
        goto err;
    }
    rc = check_record_sizes(s, diag);
    if (rc < 0)
        goto err;
    free(ib);
    *out = s;
    return 0;
err:
    free(ib);
    tvpal_shard_close(s);
    return rc;
}

void tvpal_shard_close(struct tvpal_shard *s)
{
    if (!s)
        return;
    if (s->fd >= 0)
        close(s->fd);
    free(s->path);
    free(s->index);
    tvpal_chunkz_free(s->z);
    free(s);
}

const struct tvpal_shard_header *tvpal_shard_hdr(const struct tvpal_shard *s)
{
    return &s->h;
}

const struct tvpal_index_entry *tvpal_shard_entry(const struct tvpal_shard *s,
                                                  uint32_t step)
{
    return step < s->h.steps ? &s->index[step] : NULL;
}

const char *tvpal_shard_path(const struct tvpal_shard *s)
{
    return s->path;
}

int tvpal_shard_fd(const struct tvpal_shard *s)
{
    return s->fd;
}

uint64_t tvpal_shard_max_record(const struct tvpal_shard *s)
{
    return s->max_record;
}

int tvpal_shard_coded(const struct tvpal_shard *s)
{
    return s->coded;
}

uint64_t tvpal_shard_ram_bytes(const struct tvpal_shard *s)
{
    return s->ram_bytes;
}

int tvpal_shard_read_record(struct tvpal_shard *s, uint32_t step,
                            unsigned char *buf, uint64_t cap,
                            struct tvpal_diag *diag)
{
    if (step >= s->h.steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "record %u: no such step "
                              "(%u steps)", step, s->h.steps);
    const struct tvpal_index_entry *e = &s->index[step];
    if (tvpal_record_buffer_bytes(e) > cap)
        return TVPAL_E_INVAL;
    const uint64_t at = tvpal_record_stored_at(e);
    int rc = pread_all(s->fd, buf + at, e->bytes, e->offset);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "record %u: %s", step,
                              tvpal_strerror(rc));
    if (!e->coded)
        return tvpal_record_verify(buf, e->bytes, step, &s->h, diag);
    if (!s->z && tvpal_chunkz_create(&s->z, tvpal_shard_max_chunk(&s->h)) < 0)
        return TVPAL_E_NOMEM;
    return tvpal_record_inflate(s->z, buf, e, step, &s->h, diag);
}

int tvpal_shard_count_tables(struct tvpal_shard *s,
                             struct tvpal_table_count *out,
                             struct tvpal_diag *diag)
{
    const struct tvpal_shard_header *h = &s->h;
    /* Each chunk's header is read where the table format varies by chunk,
     * some record is coded (its chunks' stored sizes vary) or a chunk may
     * hold a palette group's slices. */
    const int per_chunk = h->table_format >= TVPAL_TABLE_CHUNK || s->coded ||
                          h->group > 1;
    const uint32_t allowed =
        tvpal_chunk_flags_allowed(h->table_format) |
        (h->version >= TVPAL_FORMAT_VERSION_CODED ? TVPAL_CHUNK_CODED_BITS
                                                  : 0u);
    if (s->have_counted) { /* the file is read-only: it stays so */
        *out = s->counted;
        return 0;
    }
    *out = (struct tvpal_table_count){{0}, {0}, 0, 0, 0};
    const struct tvpal_schedule sc = tvpal_shard_schedule(h);
    for (uint32_t t = 0; t < h->steps; t++) {
        const struct tvpal_index_entry *e = &s->index[t];
        uint64_t pos = e->offset + TVPAL_RECORD_HEADER_BYTES;
        const uint64_t end = e->offset + e->bytes;
        for (uint32_t k = 0; k < h->slice_count; k++) {
            const uint32_t sl = h->slice_begin + k;
            if (!tvpal_schedule_starts(&sc, sl, t))
                continue;
            const uint32_t len = tvpal_schedule_len(&sc, sl, t);
            uint32_t tf = h->table_format;
            if (per_chunk) {
                unsigned char b[TVPAL_CHUNK_HEADER_BYTES];
                struct tvpal_chunk_header ch;
                int rc = end - pos < sizeof b ? TVPAL_E_FORMAT
                                              : pread_all(s->fd, b, sizeof b,
                                                          pos);
                uint32_t nsl = 0;
                if (rc == 0 && tvpal_chunk_header_decode(b, &ch, NULL) == 0)
                    nsl = tvpal_chunk_slices(&ch, h);
                if (rc == 0 && (!nsl || ch.slice != sl || ch.wlen != len ||
                                ch.w != h->slice_w ||
                                ch.h != nsl * h->slice_h ||
                                nsl > h->slice_count - k ||
                                (ch.flags & ~allowed)))
                    rc = TVPAL_E_FORMAT;
                if (rc < 0)
                    return tvpal_diag_set(diag, rc, "record %u: no chunk "
                                          "header of slice %u at byte %llu",
                                          t, sl, (unsigned long long)pos);
                tf = tvpal_chunk_table_format(h->table_format, ch.flags);
                const uint64_t cb = tvpal_chunk_stored_bytes(&ch, tf);
                if (ch.flags & TVPAL_CHUNK_ZSTD) {
                    out->coded_chunks++;
                    out->coded_bytes += cb;
                    out->coded_plain += tvpal_chunk_bytes(len, h->slice_w,
                                                          ch.h, tf);
                }
                pos += cb;
                k += nsl - 1;
                if (pos > end)
                    return tvpal_diag_set(diag, TVPAL_E_FORMAT, "record %u: "
                                          "the chunk of slice %u overruns "
                                          "the record", t, sl);
            }
            const unsigned u = (tf & TVPAL_TABLE_U16) != 0;
            out->chunks[u]++;
            out->bytes[u] += (uint64_t)len * 256 * tvpal_table_entry_bytes(tf);
        }
    }
    s->counted = *out;
    s->have_counted = 1;
    return 0;
}

/* -------------------------------------------------------------------- slab */

struct slab_slice {
    uint32_t wstart, wlen;  /* loaded window; wlen 0 = nothing loaded */
    uint32_t gen;           /* windows installed so far */
    float *table;           /* window * 256 */
    uint8_t *idx;           /* w * h, the slice's own */
    const uint8_t *view;    /* the indices shown: idx, or (borrowing)
                             * those of record wstart */
    /* A window staged for the next install (tvpal_slab_stage): buffers
     * from the slab's pool, NULL when none; st_view as view. */
    uint32_t st_wstart, st_wlen;
    float *st_table;
    uint8_t *st_idx;
    const uint8_t *st_view;
};

/* A pair of slice buffers not in use (the pool of staged windows). */
struct slab_buf {
    float *table;
    uint8_t *idx;
};

struct tvpal_slab {
    struct tvpal_shard *sh;
    struct slab_slice *sl;
    unsigned char *rec;     /* record buffer of tvpal_slab_seek, max_record
                             * bytes, allocated by its first call: the
                             * player feeds records itself (slab_apply) and
                             * never needs it */
    uint64_t bytes_read;
    uint32_t *staged;       /* slices with a staged window, nstaged of them */
    uint32_t nstaged;
    struct slab_buf *pool;  /* free buffer pairs, npool of them (at most
                             * slice_count) */
    uint32_t npool;
    int borrow;             /* tvpal_slab_borrow */
};

/* A window's buffers for the slab's slices: its table and indices. */
static int slice_buffers(const struct tvpal_shard_header *h, float **table,
                         uint8_t **idx)
{
    size_t nvox = (size_t)h->slice_w * h->slice_h;
    const struct tvpal_schedule sc = tvpal_shard_schedule(h);
    *table = malloc((size_t)tvpal_schedule_max_len(&sc) * 256 * sizeof(float));
    *idx = malloc(nvox ? nvox : 1);
    if (*table && *idx)
        return 0;
    free(*table);
    free(*idx);
    *table = NULL;
    *idx = NULL;
    return TVPAL_E_NOMEM;
}

int tvpal_slab_create(struct tvpal_slab **out, struct tvpal_shard *sh)
{
    const struct tvpal_shard_header *h = &sh->h;
    struct tvpal_slab *s = calloc(1, sizeof *s);
    if (!s)
        return TVPAL_E_NOMEM;
    s->sh = sh;
    s->sl = calloc(h->slice_count, sizeof *s->sl);
    s->staged = malloc((h->slice_count ? h->slice_count : 1) * sizeof *s->staged);
    s->pool = malloc((h->slice_count ? h->slice_count : 1) * sizeof *s->pool);
    if (!s->sl || !s->staged || !s->pool)
        goto nomem;
    for (uint32_t k = 0; k < h->slice_count; k++) {
        if (slice_buffers(h, &s->sl[k].table, &s->sl[k].idx) < 0)
            goto nomem;
        s->sl[k].view = s->sl[k].idx;
    }
    *out = s;
    return 0;
nomem:
    tvpal_slab_free(s);
    return TVPAL_E_NOMEM;
}

void tvpal_slab_free(struct tvpal_slab *s)
{
    if (!s)
        return;
    if (s->sl)
        for (uint32_t k = 0; k < s->sh->h.slice_count; k++) {
            free(s->sl[k].table);
            free(s->sl[k].idx);
            free(s->sl[k].st_table);
            free(s->sl[k].st_idx);
        }
    for (uint32_t i = 0; s->pool && i < s->npool; i++) {
        free(s->pool[i].table);
        free(s->pool[i].idx);
    }
    free(s->pool);
    free(s->staged);
    free(s->sl);
    free(s->rec);
    free(s);
}

unsigned tvpal_slab_needed(const struct tvpal_slab *s, uint32_t t,
                           uint32_t steps[TVPAL_SCHEDULE_RECORDS_MAX])
{
    const struct tvpal_shard_header *h = &s->sh->h;
    const struct tvpal_schedule sc = tvpal_shard_schedule(h);
    /* bit d: record t - d is needed (d < max_len <= 31) */
    uint32_t need_mask = 0;
    for (uint32_t k = 0; k < h->slice_count; k++) {
        uint32_t ws = tvpal_schedule_start(&sc, h->slice_begin + k, t);
        const struct slab_slice *sl = &s->sl[k];
        if (sl->wlen && sl->wstart == ws)
            continue;
        need_mask |= 1u << (t - ws);
    }
    return tvpal_schedule_mask_steps(t, need_mask, steps);
}

/* Whether chunk c is the window of its slice that holds t.  Record 0,
 * say, also holds the short first windows of slices that need a later
 * record at t. */
static int chunk_holds(const struct tvpal_slab *s, const struct tvpal_chunk *c,
                       uint32_t t)
{
    const struct tvpal_schedule sc = tvpal_shard_schedule(&s->sh->h);
    return tvpal_schedule_start(&sc, c->h.slice, t) == c->h.wstart;
}

/* The next chunk of rec (from *pos) that holds t: 1 with c, 0 at the end. */
static int next_chunk_at(const struct tvpal_slab *s, const unsigned char *rec,
                         uint64_t *pos, uint32_t t, struct tvpal_chunk *c)
{
    while (tvpal_record_next_chunk(rec, pos, s->sh->h.table_format, c))
        if (chunk_holds(s, c, t))
            return 1;
    return 0;
}

/* Slice j of chunk c's table into dst: decoded for the first (into
 * first, then = dst), copied from it for the others of a palette group. */
static void copy_table(const struct tvpal_chunk *c, uint32_t j,
                       const float *first, float *dst)
{
    if (j == 0)
        tvpal_chunk_table(c, dst);
    else
        memcpy(dst, first, (size_t)c->h.wlen * 256 * sizeof *dst);
}

/* apply, borrowing the record's indices or (borrow = 0) copying them */
static void apply_record(struct tvpal_slab *s, const unsigned char *rec,
                         uint32_t t, int borrow)
{
    const struct tvpal_shard_header *h = &s->sh->h;
    size_t nvox = (size_t)h->slice_w * h->slice_h;
    uint64_t pos = 0;
    struct tvpal_chunk c;
    while (next_chunk_at(s, rec, &pos, t, &c)) {
        const uint32_t nsl = tvpal_chunk_slices(&c.h, h);
        for (uint32_t j = 0; j < nsl; j++) {
            struct slab_slice *sl = &s->sl[c.h.slice + j - h->slice_begin];
            const uint8_t *idx = c.indices + (size_t)j * nvox;
            sl->wstart = c.h.wstart;
            sl->wlen = c.h.wlen;
            sl->gen++;
            copy_table(&c, j, s->sl[c.h.slice - h->slice_begin].table,
                       sl->table);
            if (borrow) {
                sl->view = idx;
            } else {
                memcpy(sl->idx, idx, nvox);
                sl->view = sl->idx;
            }
        }
    }
}

void tvpal_slab_apply(struct tvpal_slab *s, const unsigned char *rec,
                      uint32_t t)
{
    apply_record(s, rec, t, s->borrow);
}

/* Gives slice sl staging buffers (from the pool, else new ones). */
static int stage_buffers(struct tvpal_slab *s, struct slab_slice *sl)
{
    if (sl->st_idx)
        return 0;
    if (s->npool) {
        s->npool--;
        sl->st_table = s->pool[s->npool].table;
        sl->st_idx = s->pool[s->npool].idx;
        return 0;
    }
    return slice_buffers(&s->sh->h, &sl->st_table, &sl->st_idx);
}

/* Returns the staging buffers of slice sl to the pool. */
static void unstage_slice(struct tvpal_slab *s, struct slab_slice *sl)
{
    s->pool[s->npool++] = (struct slab_buf){sl->st_table, sl->st_idx};
    sl->st_table = NULL;
    sl->st_idx = NULL;
    sl->st_view = NULL;
}

/* Stages chunk c into the staging buffers of its slices (k of a palette
 * group share its table).  With crc, the indices are copied with their
 * CRC summed on the way, onto *crc. */
static int stage_chunk(struct tvpal_slab *s, const struct tvpal_chunk *c,
                       uint32_t *crc)
{
    const struct tvpal_shard_header *h = &s->sh->h;
    const size_t nvox = (size_t)h->slice_w * h->slice_h;
    const uint32_t nsl = tvpal_chunk_slices(&c->h, h);
    for (uint32_t j = 0; j < nsl; j++) {
        const uint32_t k = c->h.slice + j - h->slice_begin;
        const uint8_t *idx = c->indices + (size_t)j * nvox;
        struct slab_slice *sl = &s->sl[k];
        if (!sl->st_idx) {
            int rc = stage_buffers(s, sl);
            if (rc < 0)
                return rc;
            s->staged[s->nstaged++] = k;
        }
        sl->st_wstart = c->h.wstart;
        sl->st_wlen = c->h.wlen;
        copy_table(c, j, s->sl[c->h.slice - h->slice_begin].st_table,
                   sl->st_table);
        if (s->borrow) {
            if (crc)
                *crc = tvpal_crc32c(*crc, idx, nvox);
            sl->st_view = idx;
        } else {
            if (crc)
                *crc = tvpal_crc32c_copy(*crc, sl->st_idx, idx, nvox);
            else
                memcpy(sl->st_idx, idx, nvox);
            sl->st_view = sl->st_idx;
        }
    }
    return 0;
}

/* Takes back what stage_chunk staged of every chunk of rec whose window
 * holds t: those slices show their installed window again. */
static void unstage_record(struct tvpal_slab *s, const unsigned char *rec,
                           uint32_t t)
{
    const struct tvpal_shard_header *h = &s->sh->h;
    uint64_t pos = 0;
    struct tvpal_chunk c;
    while (next_chunk_at(s, rec, &pos, t, &c)) {
        const uint32_t nsl = tvpal_chunk_slices(&c.h, h);
        for (uint32_t j = 0; j < nsl; j++) {
            uint32_t k = c.h.slice + j - h->slice_begin;
            if (!s->sl[k].st_idx)
                continue;
            unstage_slice(s, &s->sl[k]);
            for (uint32_t n = 0; n < s->nstaged; n++)
                if (s->staged[n] == k) {
                    s->staged[n] = s->staged[--s->nstaged];
                    break;
                }
        }
    }
}

int tvpal_slab_stage(struct tvpal_slab *s, const unsigned char *rec,
                     uint32_t t)
{
    uint64_t pos = 0;
    struct tvpal_chunk c;
    while (next_chunk_at(s, rec, &pos, t, &c)) {
        int rc = stage_chunk(s, &c, NULL);
        if (rc < 0)
            return rc;
    }
    return 0;
}

int tvpal_slab_stage_verify(struct tvpal_slab *s, const unsigned char *rec,
                            uint32_t t)
{
    const struct tvpal_shard_header *h = &s->sh->h;
    struct tvpal_record_header rh;
    tvpal_record_header_decode(rec, &rh, NULL);
    /* One pass over the record: a staged chunk's header and table (and
     * the chunks before it that this step does not stage) are summed just
     * before the table is converted, from cache; its indices, most of its
     * bytes, are summed as they are copied. */
    const size_t nvox = (size_t)h->slice_w * h->slice_h;
    uint64_t pos = 0, summed = TVPAL_RECORD_HEADER_BYTES;
    uint32_t crc = 0;
    struct tvpal_chunk c;
    while (tvpal_record_next_chunk(rec, &pos, h->table_format, &c)) {
        if (!chunk_holds(s, &c, t))
            continue; /* summed with what follows */
        const uint64_t at = (uint64_t)(c.indices - rec);
        crc = tvpal_crc32c(crc, rec + summed, at - summed);
        int rc = stage_chunk(s, &c, &crc);
        if (rc < 0)
            return rc;
        summed = at + nvox * tvpal_chunk_slices(&c.h, h);
    }
    crc = tvpal_crc32c(crc, rec + summed,
                       TVPAL_RECORD_HEADER_BYTES + rh.payload_bytes - summed);
    if (crc != rh.payload_crc) {
        unstage_record(s, rec, t);
        return TVPAL_E_CHECKSUM;
    }
    return 0;
}

void tvpal_slab_install(struct tvpal_slab *s)
{
    for (uint32_t n = 0; n < s->nstaged; n++) {
        struct slab_slice *sl = &s->sl[s->staged[n]];
        float *t = sl->table;
        uint8_t *i = sl->idx;
        sl->view = sl->st_view; /* st_idx, which becomes idx, or borrowed */
        sl->table = sl->st_table;
        sl->idx = sl->st_idx;
        sl->st_table = t;
        sl->st_idx = i;
        sl->wstart = sl->st_wstart;
        sl->wlen = sl->st_wlen;
        sl->gen++;
        unstage_slice(s, sl);
    }
    s->nstaged = 0;
}

void tvpal_slab_unstage(struct tvpal_slab *s)
{
    for (uint32_t n = 0; n < s->nstaged; n++)
        unstage_slice(s, &s->sl[s->staged[n]]);
    s->nstaged = 0;
}

int tvpal_slab_seek(struct tvpal_slab *s, uint32_t t, struct tvpal_diag *diag)
{
    uint32_t steps[TVPAL_SCHEDULE_RECORDS_MAX];
    if (t >= s->sh->h.steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL,
                              "step %u out of range (0..%u)", t,
                              s->sh->h.steps - 1);
    if (!s->rec && !(s->rec = malloc(s->sh->max_record)))
        return TVPAL_E_NOMEM;
    unsigned n = tvpal_slab_needed(s, t, steps);
    for (unsigned i = 0; i < n; i++) {
        int rc = tvpal_shard_read_record(s->sh, steps[i], s->rec,
                                         s->sh->max_record, diag);
        if (rc < 0)
            return rc;
        s->bytes_read += s->sh->index[steps[i]].bytes;
        apply_record(s, s->rec, t, 0); /* s->rec is reused: copied */
    }
    return 0;
}

const uint8_t *tvpal_slab_indices(const struct tvpal_slab *s, uint32_t k)
{
    return s->sl[k].view;
}

void tvpal_slab_borrow(struct tvpal_slab *s, int on)
{
    s->borrow = on;
}

/* Whether slice sl shows or has staged a window borrowed from the record
 * of `step` (any record: UINT32_MAX): 1 shown, 2 staged, 3 both. */
static int slice_borrows(const struct slab_slice *sl, uint32_t step)
{
    int b = 0;
    if (sl->view != sl->idx && (step == UINT32_MAX || sl->wstart == step))
        b |= 1;
    if (sl->st_view && sl->st_view != sl->st_idx &&
        (step == UINT32_MAX || sl->st_wstart == step))
        b |= 2;
    return b;
}

int tvpal_slab_borrows(const struct tvpal_slab *s, uint32_t step)
{
    for (uint32_t k = 0; k < s->sh->h.slice_count; k++)
        if (slice_borrows(&s->sl[k], step))
            return 1;
    return 0;
}

void tvpal_slab_detach_stale(struct tvpal_slab *s, uint32_t t)
{
    const struct tvpal_shard_header *h = &s->sh->h;
    const struct tvpal_schedule sc = tvpal_shard_schedule(h);
    const size_t nvox = (size_t)h->slice_w * h->slice_h;
    for (uint32_t k = 0; k < h->slice_count; k++) {
        struct slab_slice *sl = &s->sl[k];
        if (sl->view != sl->idx &&
            tvpal_schedule_start(&sc, h->slice_begin + k, t) != sl->wstart) {
            memcpy(sl->idx, sl->view, nvox);
            sl->view = sl->idx;
        }
    }
}

void tvpal_slab_detach(struct tvpal_slab *s, uint32_t step)
{
    const struct tvpal_shard_header *h = &s->sh->h;
    const size_t nvox = (size_t)h->slice_w * h->slice_h;
    for (uint32_t k = 0; k < h->slice_count; k++) {
        struct slab_slice *sl = &s->sl[k];
        int b = slice_borrows(sl, step);
        if (b & 1) {
            memcpy(sl->idx, sl->view, nvox);
            sl->view = sl->idx;
        }
        if (b & 2) {
            memcpy(sl->st_idx, sl->st_view, nvox);
            sl->st_view = sl->st_idx;
        }
    }
}

const float *tvpal_slab_row(const struct tvpal_slab *s, uint32_t k,
                            uint32_t t)
{
    const struct slab_slice *sl = &s->sl[k];
    if (!sl->wlen)
        return NULL;
    uint32_t j = t < sl->wstart ? 0 : t - sl->wstart;
    if (j >= sl->wlen)
        j = sl->wlen - 1;
    return sl->table + (size_t)j * 256;
}

uint32_t tvpal_slab_generation(const struct tvpal_slab *s, uint32_t k)
{
    return s->sl[k].gen;
}

struct tvpal_shard *tvpal_slab_shard(const struct tvpal_slab *s)
{
    return s->sh;
}

void tvpal_slab_scatter(const struct tvpal_slab *s, uint32_t t, float *vol)
{
    const struct tvpal_shard_header *h = &s->sh->h;
    const size_t nx = h->dims[0], ny = h->dims[1];
    const uint32_t w = h->slice_w, hh = h->slice_h;
    for (uint32_t k = 0; k < h->slice_count; k++) {
        const uint32_t sidx = h->slice_begin + k;
        const float *row = tvpal_slab_row(s, k, t);
        const uint8_t *idx = s->sl[k].view;
        if (!row)
            continue;
        for (uint32_t b = 0; b < hh; b++)
            for (uint32_t a = 0; a < w; a++) {
                size_t v;
                switch (h->axis) {
                case 0: v = sidx + nx * (a + ny * (size_t)b); break;
                case 1: v = a + nx * (sidx + ny * (size_t)b); break;
                default: v = a + nx * (b + ny * (size_t)sidx); break;
                }
                vol[v] = row[idx[a + (size_t)w * b]];
            }
    }
}

uint64_t tvpal_slab_bytes_read(const struct tvpal_slab *s)
{
    return s->bytes_read;
}
