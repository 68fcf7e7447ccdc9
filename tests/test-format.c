/* test-format: shard header, record and index (de)serialization round trips;
 * every kind of corruption is detected with the right code; slab split;
 * the manifest's axes key and the format_version it implies; the table
 * format per chunk (table_format 4, 5): mixed chunk sizes, flag
 * rules, the placed writer's packing, the table count; staging with the
 * CRC summed on the way (tvpal_slab_stage_verify) against plain staging,
 * and its refusal of a corrupt record. */
#include "tvpal_cli.h"
#include "tvpal_crc32c.h"
#include "tvpal_format.h"
#include "tvpal_manifest.h"
#include "tvpal_shard.h"
#include "tvpal_test.h"
#include "tvpal_schedule.h"

/* The schedule of shard header h (tvpal_shard_schedule), as a pointer. */
#define SCHED(h)                                                              \
    (&(struct tvpal_schedule){(h)->window, (h)->steps, (h)->schedule, 1})
/* N = 4, T = 9, staggered. */
#define STAGGERED_4_9                                                         \
    (&(struct tvpal_schedule){4, 9, TVPAL_SCHEDULE_STAGGERED, 1})

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static struct tvpal_shard_header sample_header(void)
{
    struct tvpal_shard_header h = {
        .version = TVPAL_FORMAT_VERSION, .dims = {10, 7, 5}, .steps = 9,
        .window = 4, .nodes = 3, .rank = 1, .axis = 0, .table_format = 0,
        .value_min = -1.5, .value_max = 2.25};
    uint32_t n;
    tvpal_axis_geometry(h.dims, 0, &n, &h.slice_w, &h.slice_h);
    tvpal_slab_range(n, 3, 1, &h.slice_begin, &h.slice_count);
    h.index_offset = 8 * 4096;
    h.file_bytes = h.index_offset + 4096;
    h.index_crc = 0x12345678;
    return h;
}

/* The flags build_record gives the chunk of slice s: in a per-chunk shard
 * odd slices have 16-bit tables. */
static uint32_t test_flags(const struct tvpal_shard_header *h, uint32_t s)
{
    return h->table_format >= TVPAL_TABLE_CHUNK && s % 2 ? TVPAL_CHUNK_U16 : 0;
}

/* Builds record `step` for header h into buf (chunks with a recognizable
 * fill); returns its size. */
static uint64_t build_record(const struct tvpal_shard_header *h, uint32_t step,
                             unsigned char *buf)
{
    uint64_t off = TVPAL_RECORD_HEADER_BYTES;
    uint32_t n = 0;
    for (uint32_t s = h->slice_begin; s < h->slice_begin + h->slice_count; s++) {
        if (!tvpal_schedule_starts(SCHED(h), s, step))
            continue;
        struct tvpal_chunk_header ch = {
            .slice = s, .wstart = step,
            .wlen = tvpal_schedule_len(SCHED(h), s, step),
            .w = h->slice_w, .h = h->slice_h, .used = 7, .bits = {5, 3},
            .flags = test_flags(h, s)};
        tvpal_chunk_header_encode(&ch, buf + off);
        uint64_t cb = tvpal_chunk_bytes(
            ch.wlen, ch.w, ch.h,
            tvpal_chunk_table_format(h->table_format, ch.flags));
        memset(buf + off + TVPAL_CHUNK_HEADER_BYTES, (int)(s + 1),
               cb - TVPAL_CHUNK_HEADER_BYTES);
        off += cb;
        n++;
    }
    return tvpal_record_seal(buf, step, h->axis, n, off - TVPAL_RECORD_HEADER_BYTES);
}

/* Writes a valid shard (4x3x2, axis z, T = 3, N = 2, one node) to path. */
static void write_small_shard(const char *path)
{
    struct tvpal_shard_header h = {
        .dims = {4, 3, 2}, .steps = 3, .window = 2, .nodes = 1, .axis = 2};
    uint32_t n;
    tvpal_axis_geometry(h.dims, 2, &n, &h.slice_w, &h.slice_h);
    tvpal_slab_range(n, 1, 0, &h.slice_begin, &h.slice_count);
    struct tvpal_shardw *w;
    struct tvpal_diag d = {{0}};
    static unsigned char buf[4 * 4096];
    REQUIRE(tvpal_shardw_create(&w, path, &h) == 0, "create %s", path);
    for (uint32_t t = 0; t < h.steps; t++) {
        uint64_t bytes = build_record(&h, t, buf);
        REQUIRE(tvpal_shardw_append(w, buf, bytes, &d) == 0, "append: %s",
                d.msg);
    }
    REQUIRE(tvpal_shardw_finish(w, &d) == 0, "finish: %s", d.msg);
}

/* Reads a whole file into a malloc'ed buffer; *n its size. */
static unsigned char *slurp(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    REQUIRE(f, "open %s", path);
    fseek(f, 0, SEEK_END);
    *n = (size_t)ftell(f);
    rewind(f);
    unsigned char *b = malloc(*n + 1);
    REQUIRE(b && fread(b, 1, *n, f) == *n, "read %s", path);
    fclose(f);
    return b;
}

/* Placed writing gives the appending writer's file byte for byte, with the
 * chunks put in a shuffled order and joined in slice order; an
 * incomplete record, an out-of-order join and a chunk of the wrong size or
 * slice are refused; progress restored on a reopened file finishes it.  A
 * per-chunk shard (table_format 4, 16-bit chunks at odd slices) is put in
 * float32 rooms and packed by finish into the same bytes. */
static void test_placed(void)
{
    static const uint32_t dims[][3] = {{10, 7, 5}, {3, 4, 9}, {17, 2, 6}};
    static const uint32_t formats[] = {TVPAL_TABLE_F32, TVPAL_TABLE_U16,
                                       TVPAL_TABLE_CHUNK};
    static unsigned char rec[1 << 18], room[1 << 16];
    for (unsigned v = 0; v < 3 * 3 * 2; v++) {
        struct tvpal_shard_header h = {
            .version = TVPAL_FORMAT_VERSION, .steps = 2 + v % 7,
            .window = 1 + v % 5, .nodes = 1 + v % 2, .rank = v % 2,
            .axis = v / 2 % 3, .table_format = formats[v % 3]};
        memcpy(h.dims, dims[v / 6], sizeof h.dims);
        uint32_t n;
        tvpal_axis_geometry(h.dims, h.axis, &n, &h.slice_w, &h.slice_h);
        tvpal_slab_range(n, h.nodes, h.rank, &h.slice_begin, &h.slice_count);
        const char *pa = "test-format-append.tvps", *pp = "test-format-placed.tvps";
        struct tvpal_shardw *w, *p;
        struct tvpal_diag d = {{0}};
        REQUIRE(tvpal_shardw_create(&w, pa, &h) == 0, "create");
        REQUIRE(tvpal_shardw_create_placed(&p, pp, &h, &d) == 0, "placed: %s",
                d.msg);
        for (uint32_t t = 0; t < h.steps; t++) {
            uint64_t bytes = build_record(&h, t, rec);
            REQUIRE(tvpal_shardw_append(w, rec, bytes, &d) == 0, "append");
            /* The record's chunks, put last to first, joined in order. */
            uint64_t off[64];
            uint32_t sl[64], crc[64], k = 0;
            uint64_t pos = TVPAL_RECORD_HEADER_BYTES;
            for (uint32_t s = h.slice_begin; s < h.slice_begin + h.slice_count;
                 s++) {
                if (!tvpal_schedule_starts(SCHED(&h), s, t))
                    continue;
                off[k] = pos;
                sl[k++] = s;
                pos += tvpal_chunk_bytes(
                    tvpal_schedule_len(SCHED(&h), s, t), h.slice_w,
                    h.slice_h,
                    tvpal_chunk_table_format(h.table_format,
                                             test_flags(&h, s)));
            }
            for (uint32_t i = k; i-- > 0;) {
                /* The chunk in its room (its own size but in a per-chunk
                 * shard), zeros after it. */
                uint64_t cb = (i + 1 < k ? off[i + 1] : pos) - off[i];
                uint64_t rb = tvpal_chunk_bytes(
                    tvpal_schedule_len(SCHED(&h), sl[i], t),
                    h.slice_w, h.slice_h, h.table_format);
                REQUIRE(rb <= sizeof room && cb <= rb, "room %llu",
                        (unsigned long long)rb);
                memset(room, 0, rb);
                memcpy(room, rec + off[i], cb);
                CHECK(tvpal_shardw_put_chunk(p, t, sl[i], room, rb, &crc[i],
                                             &d) == 0,
                      "put %u/%u: %s", t, sl[i], d.msg);
                CHECK(tvpal_shardw_put_chunk(p, t, sl[i], room, rb + 64,
                                             &crc[i], NULL) ==
                          TVPAL_E_INVAL, "wrong size refused");
            }
            if (k > 1)
                CHECK(tvpal_shardw_extend(p, t, sl[1], 1, crc[1]) ==
                          TVPAL_E_INVAL, "out of order join refused");
            for (uint32_t i = 0; i < k; i++)
                CHECK(tvpal_shardw_extend(p, t, sl[i], 1, crc[i]) == 0, "join");
        }
        uint32_t foreign = h.slice_begin + h.slice_count;
        uint32_t c0;
        CHECK(tvpal_shardw_put_chunk(p, 0, foreign, rec, 64, &c0, NULL) ==
                  TVPAL_E_INVAL, "slice outside the slab refused");
        REQUIRE(tvpal_shardw_finish(w, &d) == 0, "finish append: %s", d.msg);
        /* Reopen: progress from the first writer, as a checkpoint keeps it. */
        uint64_t filled[16];
        uint32_t crcs[16];
        for (uint32_t t = 0; t < h.steps; t++)
            tvpal_shardw_progress(p, t, &filled[t], &crcs[t]);
        tvpal_shardw_free(p);
        REQUIRE(tvpal_shardw_reopen_placed(&p, pp, &h, &d) == 0, "reopen: %s",
                d.msg);
        CHECK(tvpal_shardw_finish(p, &d) == TVPAL_E_INVAL &&
                  strstr(d.msg, "record 0"), "incomplete refused: %s", d.msg);
        REQUIRE(tvpal_shardw_reopen_placed(&p, pp, &h, &d) == 0, "reopen");
        for (uint32_t t = 0; t < h.steps; t++)
            CHECK(tvpal_shardw_set_progress(p, t, filled[t], crcs[t], &d) ==
                      0, "set progress: %s", d.msg);
        if (filled[0] > 0)
            CHECK(tvpal_shardw_set_progress(p, 0, filled[0], crcs[0] ^ 1,
                                            NULL) == TVPAL_E_CHECKSUM,
                  "progress whose bytes differ refused");
        REQUIRE(tvpal_shardw_finish(p, &d) == 0, "finish placed: %s", d.msg);
        size_t na, np;
        unsigned char *a = slurp(pa, &na), *b = slurp(pp, &np);
        CHECK(na == np && !memcmp(a, b, na), "variant %u (table_format %u): "
              "placed file = appended file (%zu, %zu bytes)", v,
              h.table_format, na, np);
        free(a);
        free(b);
        /* A file of another size is not reopened. */
        truncate(pp, 4096);
        CHECK(tvpal_shardw_reopen_placed(&p, pp, &h, NULL) == TVPAL_E_TRUNC,
              "short file refused");
        unlink(pa);
        unlink(pp);
    }
}

/* Sets the flags of record rec's first chunk (at byte 64) and reseals the
 * record's payload CRC. */
static void set_first_flags(unsigned char *rec, uint32_t step,
                            const struct tvpal_shard_header *h, uint32_t flags)
{
    struct tvpal_record_header rh;
    tvpal_record_header_decode(rec, &rh, NULL);
    rec[64 + 28] = (unsigned char)flags;
    tvpal_record_seal(rec, step, h->axis, rh.chunk_count, rh.payload_bytes);
}

/* Writes the records build_record makes for h (with the first chunk of
 * record 0 given flags0) through the appending writer. */
static void write_shard(const char *path, const struct tvpal_shard_header *h,
                        uint32_t flags0)
{
    static unsigned char rec[1 << 18];
    struct tvpal_shardw *w;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_shardw_create(&w, path, h) == 0, "create %s", path);
    for (uint32_t t = 0; t < h->steps; t++) {
        uint64_t bytes = build_record(h, t, rec);
        if (t == 0)
            set_first_flags(rec, 0, h, test_flags(h, h->slice_begin) | flags0);
        REQUIRE(tvpal_shardw_append(w, rec, bytes, &d) == 0, "append: %s",
                d.msg);
    }
    REQUIRE(tvpal_shardw_finish(w, &d) == 0, "finish: %s", d.msg);
}

/* The table format per chunk (FORMAT.md 6.5-6.7, 8.2): records of mixed
 * chunk sizes verify and iterate, each chunk with its own format; a flag
 * the shard's table_format does not define is refused; the missing flag
 * turns 4 into 5; the table count reads every chunk header; a room that
 * changed after it was written fails the placed writer's packing. */
static void test_per_chunk(void)
{
    static unsigned char rec[1 << 20];
    struct tvpal_diag d = {{0}};
    struct tvpal_shard_header h = sample_header();
    h.table_format = TVPAL_TABLE_CHUNK;
    for (uint32_t t = 0; t < h.steps; t++) {
        uint64_t bytes = build_record(&h, t, rec);
        CHECK(tvpal_record_verify(rec, bytes, t, &h, &d) == 0,
              "per-chunk record %u: %s", t, d.msg);
        uint64_t pos = 0;
        struct tvpal_chunk c;
        while (tvpal_record_next_chunk(rec, &pos, h.table_format, &c))
            CHECK(c.table_format == (c.h.slice % 2 ? TVPAL_TABLE_U16
                                                   : TVPAL_TABLE_F32) &&
                      c.indices[0] == (uint8_t)(c.h.slice + 1) &&
                      c.indices - c.table ==
                          (ptrdiff_t)c.h.wlen * 256 *
                              (c.h.slice % 2 ? 2 : 4),
                  "step %u slice %u: its own format and place", t,
                  c.h.slice);
    }
    /* Flags by table_format: bit 0 in 2, 3, 5; bit 1 in 4, 5; no other.
     * The first chunk of the sample slab (slice 4) has a float32 table, so
     * bit 1 is what a table_format 0..3 shard refuses before any size. */
    static const struct {
        uint32_t tf, flags;
        int ok;
    } rules[] = {{0, 0, 1}, {0, 1, 0}, {0, 2, 0}, {1, 2, 0}, {2, 1, 1},
                 {3, 1, 1}, {3, 2, 0}, {4, 1, 0}, {5, 1, 1}, {0, 4, 0},
                 {2, 5, 0}, {5, 4, 0}, {4, 0x80000000u, 0}};
    for (size_t i = 0; i < sizeof rules / sizeof *rules; i++) {
        struct tvpal_shard_header g = sample_header();
        g.table_format = rules[i].tf;
        REQUIRE(!test_flags(&g, g.slice_begin), "slice %u float32",
                g.slice_begin);
        uint64_t bytes = build_record(&g, 0, rec);
        set_first_flags(rec, 0, &g, rules[i].flags);
        if (rules[i].flags & 0x80000000u) {
            rec[64 + 31] = 0x80;
            struct tvpal_record_header rh;
            tvpal_record_header_decode(rec, &rh, NULL);
            tvpal_record_seal(rec, 0, g.axis, rh.chunk_count, rh.payload_bytes);
        }
        int rc = tvpal_record_verify(rec, bytes, 0, &g, &d);
        char want[64];
        snprintf(want, sizeof want, "flags 0x%x, table_format %u",
                 rules[i].flags, rules[i].tf);
        CHECK(rules[i].ok ? rc == 0
                          : rc == TVPAL_E_FORMAT && strstr(d.msg, want),
              "table_format %u, flags 0x%x: rc %d (%s)", rules[i].tf,
              rules[i].flags, rc, rc ? d.msg : "");
    }
    /* A 16-bit chunk said float32 no longer fits its record. */
    {
        struct tvpal_shard_header g = sample_header();
        g.table_format = TVPAL_TABLE_CHUNK;
        uint64_t bytes = build_record(&g, 1, rec); /* slice 5 alone */
        struct tvpal_chunk c;
        uint64_t pos = 0, last = 0;
        while (tvpal_record_next_chunk(rec, &pos, g.table_format, &c))
            last = (uint64_t)(c.table - rec) - TVPAL_CHUNK_HEADER_BYTES;
        REQUIRE(c.table_format == TVPAL_TABLE_U16, "last chunk 16-bit");
        rec[last + 28] = 0;
        struct tvpal_record_header rh;
        tvpal_record_header_decode(rec, &rh, NULL);
        tvpal_record_seal(rec, 1, g.axis, rh.chunk_count, rh.payload_bytes);
        CHECK(tvpal_record_verify(rec, bytes, 1, &g, &d) == TVPAL_E_FORMAT &&
                  strstr(d.msg, "overruns the payload") &&
                  strstr(d.msg, "float32 table (flags 0x0)"),
              "16-bit chunk said float32: %s", d.msg);
    }
    /* Shards: the count of tables, the missing flag, the packing. */
    const char *path = "test-format-per-chunk.tvps";
    for (uint32_t tf = 0; tf <= TVPAL_TABLE_CHUNK; tf += 4) {
        for (uint32_t miss = 0; miss <= 1; miss++) {
            struct tvpal_shard_header g = sample_header();
            g.table_format = tf;
            write_shard(path, &g, miss ? TVPAL_CHUNK_MISSING : 0);
            struct tvpal_shard *sh;
            REQUIRE(tvpal_shard_open(&sh, path, &d) == 0, "open: %s", d.msg);
            const uint32_t want_tf = miss ? tvpal_table_with_missing(tf) : tf;
            CHECK(tvpal_shard_hdr(sh)->table_format == want_tf,
                  "table_format %u written as %u (missing %u)", tf,
                  tvpal_shard_hdr(sh)->table_format, miss);
            uint64_t want[2] = {0, 0}, wb[2] = {0, 0};
            for (uint32_t t = 0; t < g.steps; t++) {
                CHECK(tvpal_shard_read_record(sh, t, rec, sizeof rec, &d) == 0,
                      "tf %u record %u: %s", want_tf, t, d.msg);
                uint64_t pos = 0;
                struct tvpal_chunk c;
                while (tvpal_record_next_chunk(rec, &pos, want_tf, &c)) {
                    unsigned u = c.table_format & TVPAL_TABLE_U16;
                    want[u]++;
                    wb[u] += (uint64_t)c.h.wlen * 256 * (u ? 2 : 4);
                }
            }
            struct tvpal_table_count n;
            CHECK(tvpal_shard_count_tables(sh, &n, &d) == 0, "count: %s",
                  d.msg);
            CHECK(n.chunks[0] == want[0] && n.chunks[1] == want[1] &&
                      n.bytes[0] == wb[0] && n.bytes[1] == wb[1] &&
                      (tf == 0 ? !want[1] : want[0] && want[1]),
                  "tf %u: count %llu/%llu chunks, expected %llu/%llu",
                  want_tf, (unsigned long long)n.chunks[0],
                  (unsigned long long)n.chunks[1],
                  (unsigned long long)want[0], (unsigned long long)want[1]);
            tvpal_shard_close(sh);
        }
    }
    /* A damaged chunk header in a per-chunk shard: the count names it. */
    {
        struct tvpal_shard_header g = sample_header();
        g.table_format = TVPAL_TABLE_CHUNK;
        write_shard(path, &g, 0);
        int fd = open(path, O_RDWR);
        REQUIRE(fd >= 0, "open %s", path);
        unsigned char x = 0;
        REQUIRE(pwrite(fd, &x, 1, 4096 + 64) == 1, "damage");
        close(fd);
        struct tvpal_shard *sh;
        struct tvpal_table_count n;
        REQUIRE(tvpal_shard_open(&sh, path, &d) == 0, "open: %s", d.msg);
        CHECK(tvpal_shard_count_tables(sh, &n, &d) == TVPAL_E_FORMAT &&
                  strstr(d.msg, "record 0: no chunk header of slice 4"),
              "damaged chunk header: %s", d.msg);
        tvpal_shard_close(sh);
    }
    /* Packing reads every room back: one that changed since it was put
     * (the checkpoint's CRC no longer holds) fails the finish; a 16-bit
     * flag in a shard of table_format 0 is refused at put. */
    {
        struct tvpal_shard_header g = sample_header();
        g.table_format = TVPAL_TABLE_CHUNK;
        struct tvpal_shardw *w;
        REQUIRE(tvpal_shardw_create_placed(&w, path, &g, &d) == 0, "placed");
        static unsigned char room[1 << 16];
        for (uint32_t t = 0; t < g.steps; t++) {
            build_record(&g, t, rec);
            uint64_t pos = 0;
            struct tvpal_chunk c;
            while (tvpal_record_next_chunk(rec, &pos, g.table_format, &c)) {
                const unsigned char *ch = c.table - TVPAL_CHUNK_HEADER_BYTES;
                uint64_t cb = tvpal_chunk_bytes(c.h.wlen, c.h.w, c.h.h,
                                                c.table_format);
                uint64_t rb = tvpal_chunk_bytes(c.h.wlen, c.h.w, c.h.h,
                                                g.table_format);
                memset(room, 0, rb);
                memcpy(room, ch, cb);
                uint32_t crc;
                CHECK(tvpal_shardw_put_chunk(w, t, c.h.slice, room, rb, &crc,
                                             &d) == 0 &&
                          tvpal_shardw_extend(w, t, c.h.slice, 1, crc) == 0,
                      "put: %s", d.msg);
            }
        }
        int fd = open(path, O_RDWR);
        REQUIRE(fd >= 0, "open %s", path);
        unsigned char x = 0x5A;
        REQUIRE(pwrite(fd, &x, 1, 4096 + 64 + 200) == 1, "damage");
        close(fd);
        CHECK(tvpal_shardw_finish(w, &d) == TVPAL_E_CHECKSUM &&
                  strstr(d.msg, "record 0: the chunks read back"),
              "damaged room: %s", d.msg);
        g.table_format = TVPAL_TABLE_F32;
        REQUIRE(tvpal_shardw_create_placed(&w, path, &g, &d) == 0, "placed");
        build_record(&g, 0, rec);
        set_first_flags(rec, 0, &g, TVPAL_CHUNK_U16);
        uint32_t crc;
        uint64_t cb = tvpal_chunk_bytes(tvpal_schedule_len(SCHED(&g), g.slice_begin, 0),
                                        g.slice_w, g.slice_h, g.table_format);
        CHECK(tvpal_shardw_put_chunk(w, 0, g.slice_begin, rec + 64, cb, &crc,
                                     &d) == TVPAL_E_INVAL &&
                  strstr(d.msg, "flags 0x2"),
              "16-bit flag in a float32 shard: %s", d.msg);
        tvpal_shardw_free(w);
    }
    unlink(path);
}

/* A shard whose header (valid CRC) claims dims 1x1x100000000 over records
 * of a 4x3x2 shard: the open must refuse it before anything sized by the
 * header is allocated (FORMAT.md 8.1 rule 18), not hand a slab 100 GB. */
static void test_huge_dims(void)
{
    const char *tmp = getenv("TMPDIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/tvpal-fmt-XXXXXX",
             tmp && *tmp ? tmp : "/tmp");
    int fd = mkstemp(path);
    REQUIRE(fd >= 0, "mkstemp %s", path);
    close(fd);
    write_small_shard(path);
    struct tvpal_shard *s = NULL;
    struct tvpal_diag d = {{0}};
    CHECK(tvpal_shard_open(&s, path, &d) == 0, "valid shard: %s", d.msg);
    tvpal_shard_close(s);

    unsigned char hb[TVPAL_SHARD_HEADER_BYTES];
    struct tvpal_shard_header h;
    fd = open(path, O_RDWR);
    REQUIRE(fd >= 0 && pread(fd, hb, sizeof hb, 0) == (ssize_t)sizeof hb,
            "read back %s", path);
    REQUIRE(tvpal_shard_header_decode(hb, &h, &d) == 0, "header: %s", d.msg);
    h.dims[0] = h.dims[1] = 1;
    h.dims[2] = 100000000;
    uint32_t n;
    tvpal_axis_geometry(h.dims, 2, &n, &h.slice_w, &h.slice_h);
    tvpal_slab_range(n, 1, 0, &h.slice_begin, &h.slice_count);
    tvpal_shard_header_encode(&h, hb);
    REQUIRE(pwrite(fd, hb, sizeof hb, 0) == (ssize_t)sizeof hb, "rewrite");
    close(fd);
    s = NULL;
    d.msg[0] = 0;
    int rc = tvpal_shard_open(&s, path, &d);
    CHECK(rc == TVPAL_E_FORMAT && s == NULL && strstr(d.msg, "too small"),
          "huge dims: rc %d, \"%s\"", rc, d.msg);
    if (rc == 0)
        tvpal_shard_close(s);
    unlink(path);
}

/* tvpal_axes_parse and _format (FORMAT.md 3.2), and a manifest of a subset
 * of the axes: written with format_version 3, read back with its mask. */
static void test_axes(void)
{
    static const struct { const char *s; uint32_t mask; } good[] = {
        {"z", 4}, {"x", 1}, {"y", 2}, {"xz", 5}, {"zx", 5}, {"xyz", 7},
        {"zyx", 7}, {"x y z", 7}, {" z\t", 4}, {"y z", 6}};
    static const char *const bad[] = {"", " ", "q", "zz", "xzx", "x,z",
                                      "X", "xyzw", "z-", "xy z x"};
    char buf[4];
    for (size_t i = 0; i < sizeof good / sizeof *good; i++) {
        uint32_t m = 99;
        CHECK(tvpal_axes_parse(good[i].s, &m) == 0 && m == good[i].mask,
              "axes \"%s\": mask %u, expected %u", good[i].s, m,
              good[i].mask);
    }
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        uint32_t m = 99;
        CHECK(tvpal_axes_parse(bad[i], &m) == TVPAL_E_INVAL && m == 99,
              "axes \"%s\" taken (mask %u)", bad[i], m);
    }
    CHECK(!strcmp(tvpal_axes_format(5, buf), "xz"), "format 5: %s", buf);
    CHECK(!strcmp(tvpal_axes_format(4, buf), "z"), "format 4: %s", buf);
    CHECK(!strcmp(tvpal_axes_format(7, buf), "xyz"), "format 7: %s", buf);
    CHECK(!strcmp(tvpal_axes_format(0, buf), ""), "format 0: %s", buf);
    CHECK(tvpal_axes_count(5) == 2 && tvpal_axes_count(7) == 3,
          "axes count");

    /* format_version: 1 plain, 2 levels, 3 a subset (levels or not). */
    static const struct { uint32_t mask, levels; const char *version,
                          *axes; } cases[] = {
        {7, 0, "format_version = 1\n", NULL},
        {7, 2, "format_version = 2\n", NULL},
        {4, 0, "format_version = 3\n", "axes = z\n"},
        {5, 1, "format_version = 3\n", "axes = xz\n"}};
    const char *tmp = getenv("TMPDIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/tvpal-man-XXXXXX",
             tmp && *tmp ? tmp : "/tmp");
    int fd = mkstemp(path);
    REQUIRE(fd >= 0, "mkstemp %s", path);
    close(fd);
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        struct tvpal_manifest m = {.dims = {4, 3, 2}, .steps = 3,
                                   .window = 2, .nodes = 1,
                                   .axes_mask = cases[i].mask,
                                   .levels = cases[i].levels};
        char *text = NULL;
        REQUIRE(tvpal_manifest_format(&m, &text) == 0, "format");
        CHECK(strstr(text, cases[i].version), "case %zu: no \"%s\"", i,
              cases[i].version);
        CHECK(cases[i].axes ? strstr(text, cases[i].axes) != NULL
                            : strstr(text, "\naxes") == NULL,
              "case %zu: axes line wrong:\n%s", i, text);
        FILE *f = fopen(path, "w");
        REQUIRE(f && fputs(text, f) >= 0 && fclose(f) == 0, "write");
        free(text);
        struct tvpal_manifest back;
        struct tvpal_diag d = {{0}};
        CHECK(tvpal_manifest_load(path, &back, &d) == 0, "load: %s", d.msg);
        CHECK(back.axes_mask == cases[i].mask, "case %zu: mask %u back", i,
              back.axes_mask);
        tvpal_manifest_clear(&back);
    }
    struct tvpal_manifest none = {.dims = {4, 3, 2}, .steps = 1,
                                  .window = 1, .nodes = 1};
    char *text = NULL;
    CHECK(tvpal_manifest_format(&none, &text) == TVPAL_E_INVAL && !text,
          "a manifest without axes formatted");
    unlink(path);
}

/* Whether slabs a and b show the same thing at t: every slice's
 * generation, and the indices and palette row (bit for bit) of those
 * ever loaded. */
static int slabs_equal(const struct tvpal_slab *a, const struct tvpal_slab *b,
                       const struct tvpal_shard_header *h, uint32_t t)
{
    const size_t nvox = (size_t)h->slice_w * h->slice_h;
    for (uint32_t k = 0; k < h->slice_count; k++) {
        if (tvpal_slab_generation(a, k) != tvpal_slab_generation(b, k))
            return 0;
        if (!tvpal_slab_generation(a, k))
            continue; /* never loaded: nothing shown */
        if (memcmp(tvpal_slab_indices(a, k), tvpal_slab_indices(b, k), nvox) ||
            memcmp(tvpal_slab_row(a, k, t), tvpal_slab_row(b, k, t),
                   256 * sizeof(float)))
            return 0;
    }
    return 1;
}

/* Moves slab `ref` (tvpal_slab_stage of the records read and verified)
 * and slab `chk` (tvpal_slab_stage_verify after tvpal_record_verify_layout)
 * to t; the record of step `bad` gets payload byte `flip` flipped first
 * (none when bad is UINT32_MAX): chk must refuse it with
 * TVPAL_E_CHECKSUM, ref is not given it.  Then both install. */
static void stage_both(struct tvpal_shard *sh, struct tvpal_slab *ref,
                       struct tvpal_slab *chk, uint32_t t, uint32_t bad,
                       uint64_t flip, unsigned *refused)
{
    static unsigned char rec[1 << 20];
    const struct tvpal_shard_header *h = tvpal_shard_hdr(sh);
    struct tvpal_diag d = {{0}};
    uint32_t need[16], need2[16];
    unsigned n = tvpal_slab_needed(ref, t, need);
    CHECK(tvpal_slab_needed(chk, t, need2) == n &&
          !memcmp(need, need2, n * sizeof *need), "t %u: needed differs", t);
    for (unsigned i = 0; i < n; i++) {
        REQUIRE(tvpal_shard_read_record(sh, need[i], rec, sizeof rec, &d) == 0,
                "record %u: %s", need[i], d.msg);
        uint64_t bytes = tvpal_shard_entry(sh, need[i])->bytes;
        if (need[i] == bad) {
            rec[TVPAL_RECORD_HEADER_BYTES + flip] ^= 0x08;
            CHECK(tvpal_record_verify_layout(rec, bytes, need[i], h, &d) == 0,
                  "layout of record %u with a flipped payload byte: %s",
                  need[i], d.msg);
            CHECK(tvpal_slab_stage_verify(chk, rec, t) == TVPAL_E_CHECKSUM,
                  "t %u: record %u with byte %llu flipped staged", t, need[i],
                  (unsigned long long)flip);
            (*refused)++;
            continue;
        }
        CHECK(tvpal_record_verify_layout(rec, bytes, need[i], h, &d) == 0,
              "layout of record %u: %s", need[i], d.msg);
        CHECK(tvpal_slab_stage(ref, rec, t) == 0, "stage %u", need[i]);
        CHECK(tvpal_slab_stage_verify(chk, rec, t) == 0,
              "t %u: stage_verify of record %u", t, need[i]);
    }
    tvpal_slab_install(ref);
    tvpal_slab_install(chk);
}

/* The payload offset of the first table byte of the chunk of `slice` in
 * record `step` of sh. */
static uint64_t chunk_data_offset(struct tvpal_shard *sh, uint32_t step,
                                  uint32_t slice)
{
    static unsigned char rec[1 << 20];
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_shard_read_record(sh, step, rec, sizeof rec, &d) == 0, "%s",
            d.msg);
    uint64_t pos = 0;
    struct tvpal_chunk c;
    while (tvpal_record_next_chunk(rec, &pos, tvpal_shard_hdr(sh)->table_format, &c))
        if (c.h.slice == slice)
            return (uint64_t)(c.table - rec) - TVPAL_RECORD_HEADER_BYTES;
    REQUIRE(0, "record %u has no chunk of slice %u", step, slice);
    return 0;
}

/* Writes a one-node shard of sample_header() with table format tf to
 * path, opens it (*sh) and creates two slabs of it (*a, *b). */
static void open_two_slabs(const char *path, uint32_t tf,
                           struct tvpal_shard **sh, struct tvpal_slab **a,
                           struct tvpal_slab **b)
{
    struct tvpal_shard_header g = sample_header();
    uint32_t n;
    g.table_format = tf;
    g.nodes = 1;
    g.rank = 0;
    tvpal_axis_geometry(g.dims, 0, &n, &g.slice_w, &g.slice_h);
    tvpal_slab_range(n, 1, 0, &g.slice_begin, &g.slice_count);
    write_shard(path, &g, 0);
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_shard_open(sh, path, &d) == 0, "open: %s", d.msg);
    REQUIRE(tvpal_slab_create(a, *sh) == 0 && tvpal_slab_create(b, *sh) == 0,
            "slabs");
}

/* tvpal_slab_stage_verify stages what tvpal_slab_stage stages, bit for bit,
 * through forward play and jumps, in a float32 and a per-chunk shard; a
 * record whose payload CRC fails leaves nothing staged (its slices show
 * their last window; the other records of the same step go in), also when
 * the flipped byte is in a chunk the step does not stage (record 0 at a
 * later step): the CRC covers the whole payload. */
static void test_stage_verify(void)
{
    const char *path = "test-format-stage.tvps";
    for (uint32_t tf = 0; tf <= TVPAL_TABLE_CHUNK; tf += 4) {
        struct tvpal_shard *sh;
        struct tvpal_slab *ref, *chk;
        struct tvpal_diag d = {{0}};
        open_two_slabs(path, tf, &sh, &ref, &chk);
        const struct tvpal_shard_header *h = tvpal_shard_hdr(sh);
        unsigned refused = 0;
        /* A fresh slab jumping to t = 1 needs records 0 and 1.  A byte
         * flipped in record 0's chunk of a slice whose first window is
         * [0, 1), not staged at t = 1: refused; record 1 goes in. */
        uint32_t s1 = 0;
        while (s1 < h->slice_count &&
               tvpal_schedule_len(SCHED(h), s1, 0) != 1)
            s1++;
        REQUIRE(s1 < h->slice_count, "no slice with a first window of 1");
        stage_both(sh, ref, chk, 1, 0, chunk_data_offset(sh, 0, s1), &refused);
        CHECK(refused == 1 && slabs_equal(ref, chk, h, 1),
              "tf %u: a bad record 0 at t = 1", tf);
        /* Forward; record 5 bad (its last payload byte) at t = 5, read
         * again good at t = 6. */
        struct tvpal_record_header rh;
        static unsigned char r5[1 << 20];
        REQUIRE(tvpal_shard_read_record(sh, 5, r5, sizeof r5, &d) == 0, "%s", d.msg);
        tvpal_record_header_decode(r5, &rh, NULL);
        for (uint32_t t = 2; t < h->steps; t++) {
            stage_both(sh, ref, chk, t, t == 5 ? 5 : UINT32_MAX,
                       rh.payload_bytes - 1, &refused);
            CHECK(slabs_equal(ref, chk, h, t), "tf %u: forward t %u", tf, t);
        }
        CHECK(refused == 2, "tf %u: %u refusals", tf, refused);
        /* Jumps back and forth, all good. */
        static const uint32_t jumps[] = {2, 8, 0, 6, 3};
        for (size_t j = 0; j < sizeof jumps / sizeof *jumps; j++) {
            stage_both(sh, ref, chk, jumps[j], UINT32_MAX, 0, &refused);
            CHECK(slabs_equal(ref, chk, h, jumps[j]), "tf %u: jump to %u", tf,
                  jumps[j]);
        }
        /* A record refused while others of the same step were staged
         * before it: theirs stay staged. */
        tvpal_slab_free(ref);
        tvpal_slab_free(chk);
        REQUIRE(tvpal_slab_create(&ref, sh) == 0 && tvpal_slab_create(&chk, sh) == 0,
                "slabs");
        uint32_t need[16];
        unsigned nn = tvpal_slab_needed(ref, 7, need);
        CHECK(nn >= 2, "t 7 from nothing needs %u records", nn);
        const uint64_t pos = TVPAL_CHUNK_HEADER_BYTES + 10; /* chunk 0's data */
        stage_both(sh, ref, chk, 7, need[nn - 1], pos, &refused);
        CHECK(refused == 3 && slabs_equal(ref, chk, h, 7),
              "tf %u: the last of %u records bad", tf, nn);
        tvpal_slab_free(ref);
        tvpal_slab_free(chk);
        tvpal_shard_close(sh);
    }
    unlink(path);
}

/* Borrowing (tvpal_slab_borrow): a slab that points its slices at the
 * records shows what a copying slab shows, bit for bit, through applied
 * and staged steps, jumps and a refused record; tvpal_slab_borrows names
 * the records it points into; detaching a record copies its windows in
 * (the record may then be overwritten without a change), and detaching
 * all leaves nothing borrowed. */
static void test_borrow(void)
{
    const char *path = "test-format-borrow.tvps";
    struct tvpal_shard *sh;
    struct tvpal_slab *cp, *bw;
    struct tvpal_diag d = {{0}};
    open_two_slabs(path, TVPAL_TABLE_CHUNK, &sh, &cp, &bw);
    tvpal_slab_borrow(bw, 1);
    const struct tvpal_shard_header *h = tvpal_shard_hdr(sh);
    REQUIRE(h->steps <= 16, "%u steps", h->steps);
    static unsigned char recs[16][1 << 16];
    for (uint32_t r = 0; r < h->steps; r++)
        REQUIRE(tvpal_shard_read_record(sh, r, recs[r], sizeof recs[r], &d) == 0,
                "record %u: %s", r, d.msg);
    /* t: applied in place (odd steps of the walk) or staged and installed */
    static const uint32_t walk[] = {0, 1, 2, 3, 4, 5, 2, 8, 7, 0, 6, 7, 3};
    for (size_t w = 0; w < sizeof walk / sizeof *walk; w++) {
        const uint32_t t = walk[w];
        uint32_t need[16];
        unsigned nn = tvpal_slab_needed(bw, t, need);
        for (unsigned i = 0; i < nn; i++) {
            if (w % 2) {
                tvpal_slab_apply(cp, recs[need[i]], t);
                tvpal_slab_apply(bw, recs[need[i]], t);
            } else {
                CHECK(tvpal_slab_stage(cp, recs[need[i]], t) == 0 &&
                          tvpal_slab_stage_verify(bw, recs[need[i]], t) == 0,
                      "t %u: staging record %u", t, need[i]);
            }
        }
        tvpal_slab_install(cp);
        tvpal_slab_install(bw);
        CHECK(slabs_equal(cp, bw, h, t), "walk %zu: t %u differs", w, t);
        /* exactly the records whose windows hold t */
        for (uint32_t r = 0; r < h->steps; r++) {
            int holds = 0;
            for (uint32_t k = 0; k < h->slice_count && !holds; k++)
                holds = tvpal_schedule_start(SCHED(h), h->slice_begin + k, t) == r;
            CHECK(tvpal_slab_borrows(bw, r) == holds, "t %u: record %u borrowed %d, "
                  "holds a window at t %d", t, r, tvpal_slab_borrows(bw, r), holds);
        }
        CHECK(!tvpal_slab_borrows(cp, UINT32_MAX), "the copying slab borrows");
    }
    /* A refused record leaves its slices on their borrowed windows. */
    const uint32_t t = 4;
    uint32_t need[16];
    unsigned nn = tvpal_slab_needed(bw, t, need);
    REQUIRE(nn > 0, "nothing needed at t %u", t);
    static unsigned char bad[1 << 16];
    memcpy(bad, recs[need[0]], sizeof bad);
    bad[TVPAL_RECORD_HEADER_BYTES + TVPAL_CHUNK_HEADER_BYTES + 10] ^= 0x10;
    CHECK(tvpal_slab_stage_verify(bw, bad, t) == TVPAL_E_CHECKSUM,
          "a flipped byte staged");
    for (unsigned i = 1; i < nn; i++) {
        CHECK(tvpal_slab_stage(cp, recs[need[i]], t) == 0 &&
                  tvpal_slab_stage_verify(bw, recs[need[i]], t) == 0,
              "staging record %u", need[i]);
    }
    tvpal_slab_install(cp);
    tvpal_slab_install(bw);
    CHECK(slabs_equal(cp, bw, h, t), "a refused record: the slabs differ");
    memset(bad, 0xA5, sizeof bad);
    CHECK(slabs_equal(cp, bw, h, t), "the refused record is shown");
    /* Detach one record, then scribble over it: nothing changes. */
    uint32_t r = UINT32_MAX;
    for (uint32_t q = 0; q < h->steps && r == UINT32_MAX; q++)
        if (tvpal_slab_borrows(bw, q))
            r = q;
    REQUIRE(r != UINT32_MAX, "nothing borrowed at t %u", t);
    static unsigned char keep[1 << 16];
    memcpy(keep, recs[r], sizeof keep);
    tvpal_slab_detach(bw, r);
    CHECK(!tvpal_slab_borrows(bw, r), "record %u borrowed after detach", r);
    memset(recs[r], 0x5A, sizeof recs[r]);
    CHECK(slabs_equal(cp, bw, h, t), "record %u overwritten after detach", r);
    memcpy(recs[r], keep, sizeof keep);
    /* Detach everything; then no record shows through. */
    tvpal_slab_detach(bw, UINT32_MAX);
    CHECK(!tvpal_slab_borrows(bw, UINT32_MAX), "borrowed after detaching all");
    for (uint32_t q = 0; q < h->steps; q++)
        memset(recs[q], 0x77, sizeof recs[q]);
    CHECK(slabs_equal(cp, bw, h, t), "records overwritten after detaching all");
    tvpal_slab_free(cp);
    tvpal_slab_free(bw);
    tvpal_shard_close(sh);
    unlink(path);
}

/* Palette groups (FORMAT.md 5.1) in the shard header: version 4 with G
 * in 2 .. n (x: n = 10 slices of 7x5), either schedule; the field is 0
 * before. */
static void test_group_header(void)
{
    const struct tvpal_shard_header h = sample_header();
    struct tvpal_shard_header g;
    struct tvpal_diag d = {{0}};
    unsigned char hb[TVPAL_SHARD_HEADER_BYTES];
    const uint32_t cases[][4] = {/* version, schedule, group, ok */
                                 {4, 0, 2, 1}, {4, 1, 10, 1},
                                 {4, 1, 1, 0}, {4, 0, 11, 0},
                                 {4, 2, 2, 0}, {3, 1, 2, 0},
                                 {1, 0, 3, 0}};
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        struct tvpal_shard_header j = h;
        j.version = cases[i][0];
        j.schedule = cases[i][1];
        j.group = cases[i][2];
        tvpal_shard_header_encode(&j, hb);
        /* The writer keeps the field 0 before version 4: set it. */
        hb[92] = (unsigned char)j.group;
        const uint32_t crc = tvpal_crc32c(0, hb, 4092);
        for (int b = 0; b < 4; b++)
            hb[4092 + b] = (unsigned char)(crc >> (8 * b));
        d.msg[0] = 0;
        const int rc = tvpal_shard_header_decode(hb, &g, &d);
        CHECK(cases[i][3] ? rc == 0 && g.group == j.group
                          : rc == TVPAL_E_FORMAT &&
                                (strstr(d.msg, "group") ||
                                 strstr(d.msg, "schedule")),
              "version %u schedule %u group %u: %d %s", j.version,
              j.schedule, j.group, rc, d.msg);
    }
    /* A version 1 header decodes with G = 1. */
    tvpal_shard_header_encode(&h, hb);
    CHECK(tvpal_shard_header_decode(hb, &g, NULL) == 0 && g.group == 1,
          "no group: G = 1");
}

int main(void)
{
    test_placed();
    test_axes();
    test_per_chunk();
    test_stage_verify();
    test_borrow();
    unsigned char hb[TVPAL_SHARD_HEADER_BYTES];
    struct tvpal_shard_header h = sample_header(), g;
    struct tvpal_diag d;

    tvpal_shard_header_encode(&h, hb);
    CHECK(tvpal_shard_header_decode(hb, &g, &d) == 0, "decode: %s", d.msg);
    CHECK(!memcmp(g.dims, h.dims, sizeof h.dims) && g.steps == h.steps &&
          g.window == h.window && g.nodes == 3 && g.rank == 1 &&
          g.slice_begin == h.slice_begin && g.slice_count == h.slice_count &&
          g.index_offset == h.index_offset && g.index_crc == h.index_crc &&
          g.value_min == -1.5 && g.value_max == 2.25, "round trip");
    /* Each corruption gives its own error. */
    hb[0] ^= 1;
    CHECK(tvpal_shard_header_decode(hb, &g, NULL) == TVPAL_E_MAGIC, "magic");
    hb[0] ^= 1;
    hb[20] ^= 0x40;
    CHECK(tvpal_shard_header_decode(hb, &g, NULL) == TVPAL_E_CHECKSUM, "crc");
    hb[20] ^= 0x40;
    hb[8] = 5; /* version 5, CRC left stale: version is checked first */
    CHECK(tvpal_shard_header_decode(hb, &g, NULL) == TVPAL_E_VERSION,
          "version");
    /* The schedule field goes with the version: 1 (joined) in version 3,
     * 0 before it. */
    {
        struct tvpal_shard_header j = h;
        const uint32_t pairs[4][3] = {{3, 1, 0}, {1, 0, 0}, {3, 0, 1},
                                      {2, 1, 1}};
        for (int i = 0; i < 4; i++) {
            j.version = pairs[i][0];
            j.schedule = pairs[i][1];
            tvpal_shard_header_encode(&j, hb);
            const int rc = tvpal_shard_header_decode(hb, &g, &d);
            CHECK(pairs[i][2]
                      ? rc == TVPAL_E_FORMAT && strstr(d.msg, "schedule")
                      : rc == 0 && g.schedule == j.schedule,
                  "version %u schedule %u: %d %s", j.version, j.schedule, rc,
                  d.msg);
        }
    }
    test_group_header();
    /* A field out of range with a valid CRC. */
    h.window = 17;
    tvpal_shard_header_encode(&h, hb);
    CHECK(tvpal_shard_header_decode(hb, &g, &d) == TVPAL_E_FORMAT &&
          strstr(d.msg, "window"), "window range: %s", d.msg);
    h = sample_header();
    h.slice_count++;
    tvpal_shard_header_encode(&h, hb);
    CHECK(tvpal_shard_header_decode(hb, &g, &d) == TVPAL_E_FORMAT &&
          strstr(d.msg, "slab"), "slab: %s", d.msg);
    h = sample_header();
    h.file_bytes += 4096;
    tvpal_shard_header_encode(&h, hb);
    CHECK(tvpal_shard_header_decode(hb, &g, &d) == TVPAL_E_FORMAT, "size");
    /* table_format 0..5 are defined (2, 3, 5: with missing values; 4, 5:
     * per chunk). */
    for (uint32_t tf = 0; tf <= 7; tf++) {
        h = sample_header();
        h.table_format = tf;
        tvpal_shard_header_encode(&h, hb);
        int rc = tvpal_shard_header_decode(hb, &g, &d);
        CHECK(tf <= 5 ? rc == 0 && g.table_format == tf
                      : rc == TVPAL_E_FORMAT && strstr(d.msg, "table_format"),
              "table_format %u: %d", tf, rc);
    }

    /* Records: every step of the sample header, verify, iterate chunks. */
    h = sample_header();
    static unsigned char rec[1 << 20];
    for (uint32_t t = 0; t < h.steps; t++) {
        uint64_t bytes = build_record(&h, t, rec);
        CHECK(bytes % TVPAL_ALIGN == 0, "aligned");
        CHECK(tvpal_record_verify(rec, bytes, t, &h, &d) == 0,
              "verify step %u: %s", t, d.msg);
        CHECK(tvpal_record_verify(rec, bytes, t + 1, &h, NULL) ==
                  TVPAL_E_FORMAT, "wrong step");
        uint64_t pos = 0;
        struct tvpal_chunk c;
        unsigned k = 0;
        while (tvpal_record_next_chunk(rec, &pos, h.table_format, &c)) {
            CHECK(c.h.wstart == t && c.indices[0] == (uint8_t)(c.h.slice + 1),
                  "chunk %u of step %u", k, t);
            k++;
        }
        /* Flip one payload byte: CRC mismatch (records of steps where no
         * slice of this slab starts hold no chunk: the byte is padding). */
        struct tvpal_record_header rh;
        tvpal_record_header_decode(rec, &rh, NULL);
        rec[TVPAL_RECORD_HEADER_BYTES + 100] ^= 0x10;
        CHECK(tvpal_record_verify(rec, bytes, t, &h, &d) ==
                  (rh.payload_bytes > 100 ? TVPAL_E_CHECKSUM : TVPAL_E_FORMAT),
              "payload/padding corruption step %u", t);
        rec[TVPAL_RECORD_HEADER_BYTES + 100] ^= 0x10;
        rec[bytes - 1] ^= 0x01;
        CHECK(tvpal_record_verify(rec, bytes, t, &h, &d) == TVPAL_E_FORMAT,
              "padding corruption step %u", t);
        rec[bytes - 1] ^= 0x01;
        rec[5] ^= 1; /* header byte */
        char want[64];
        snprintf(want, sizeof want, "record %u: record header: CRC", t);
        CHECK(tvpal_record_verify(rec, bytes, t, &h, &d) == TVPAL_E_CHECKSUM &&
                  strstr(d.msg, want), "record header corruption: %s", d.msg);
        rec[5] ^= 1;
        CHECK(tvpal_record_verify(rec, 32, t, &h, NULL) == TVPAL_E_TRUNC,
              "truncated record");
    }
    /* A record that omits a slice is rejected even with a valid CRC. */
    {
        uint64_t bytes = build_record(&h, 0, rec);
        struct tvpal_record_header rh;
        tvpal_record_header_decode(rec, &rh, NULL);
        uint64_t first = tvpal_chunk_bytes(tvpal_schedule_len(STAGGERED_4_9, h.slice_begin, 0),
                                           h.slice_w, h.slice_h, 0);
        memmove(rec + 64, rec + 64 + first, rh.payload_bytes - first);
        tvpal_record_seal(rec, 0, 0, rh.chunk_count - 1, rh.payload_bytes - first);
        CHECK(tvpal_record_verify(rec, bytes, 0, &h, &d) == TVPAL_E_FORMAT,
              "missing slice: %s", d.msg);
    }
    /* A chunk with a bad magic (CRCs valid) names the record and chunk. */
    {
        uint64_t bytes = build_record(&h, 0, rec);
        struct tvpal_record_header rh;
        tvpal_record_header_decode(rec, &rh, NULL);
        uint64_t first = tvpal_chunk_bytes(tvpal_schedule_len(STAGGERED_4_9, h.slice_begin, 0),
                                           h.slice_w, h.slice_h, 0);
        rec[64 + first] ^= 1; /* magic of chunk 1 */
        tvpal_record_seal(rec, 0, 0, rh.chunk_count, rh.payload_bytes);
        CHECK(tvpal_record_verify(rec, bytes, 0, &h, &d) == TVPAL_E_MAGIC &&
                  strstr(d.msg, "record 0: chunk 1: bad magic"),
              "chunk magic: %s", d.msg);
    }
    /* Index entries. */
    struct tvpal_index_entry e = {.offset = 1ull << 40, .bytes = 8192,
                                  .step = 77, .chunk_count = 5, .crc = 99,
                                  .plain_bytes = 8192}, f;
    unsigned char ib[TVPAL_INDEX_ENTRY_BYTES];
    tvpal_index_entry_encode(&e, ib);
    tvpal_index_entry_decode(ib, &f);
    CHECK(f.offset == e.offset && f.bytes == e.bytes && f.step == e.step &&
              f.chunk_count == e.chunk_count && f.crc == e.crc && !f.coded &&
              f.plain_bytes == e.bytes && ib[28] == 0 && ib[29] == 0,
          "index entry round trip");
    /* A coded record's: plain_pages at byte 28 (FORMAT.md 6.9). */
    e.coded = 1;
    e.plain_bytes = 5 * 4096;
    tvpal_index_entry_encode(&e, ib);
    tvpal_index_entry_decode(ib, &f);
    CHECK(f.coded && f.plain_bytes == 5 * 4096 && ib[28] == 5,
          "coded index entry: %d %llu", f.coded,
          (unsigned long long)f.plain_bytes);

    /* 16-bit tables: round trip within half a step, constants exact. */
    {
        static float tab[16 * 256], back[16 * 256];
        static unsigned char store[16 * 256 * 2];
        for (int i = 0; i < 4 * 256; i++)
            tab[i] = (float)(-3.0 + 1e3 * tt_uniform());
        struct tvpal_chunk_header ch = {.wlen = 4};
        tvpal_table_store(tab, 4, TVPAL_TABLE_U16, store, &ch);
        struct tvpal_chunk c = {.h = ch, .table_format = TVPAL_TABLE_U16,
                                .table = store};
        tvpal_chunk_table(&c, back);
        double lo = tab[0], hi = tab[0], err = 0;
        for (int i = 0; i < 4 * 256; i++) {
            lo = fmin(lo, tab[i]);
            hi = fmax(hi, tab[i]);
        }
        for (int i = 0; i < 4 * 256; i++)
            err = fmax(err, fabs(back[i] - tab[i]));
        CHECK(err <= (hi - lo) / 65535 * 0.5 + 1e-4 * (hi - lo) / 65535 + 1e-5,
              "u16 table error %g for range %g", err, hi - lo);
        for (int i = 0; i < 256; i++)
            tab[i] = 7.25f;
        ch.wlen = 1;
        tvpal_table_store(tab, 1, TVPAL_TABLE_U16, store, &ch);
        c.h = ch;
        tvpal_chunk_table(&c, back);
        CHECK(back[0] == 7.25f && back[255] == 7.25f, "constant table exact");
        CHECK(tvpal_chunk_bytes(4, 10, 10, TVPAL_TABLE_U16) ==
                  64 + 4 * 512 + 128, "u16 chunk size");
    }

    /* Missing entries (FORMAT.md 6.7, table_format 2 and 3): NaN in f32
     * tables; in u16 tables q = 65535 in a chunk flagged missing, the
     * finite entries scaled over 65534 steps.  The flag is byte 28. */
    {
        static float tab[4 * 256], back[4 * 256];
        static unsigned char store[4 * 256 * 4];
        for (int i = 0; i < 4 * 256; i++)
            tab[i] = i % 7 == 3 ? NAN : (float)(-3.0 + 1e3 * tt_uniform());
        tab[5] = -3.5f; /* the extremes, finite */
        tab[6] = 1000.5f;
        struct tvpal_chunk_header ch = {.wlen = 4};
        tvpal_table_store(tab, 4, TVPAL_TABLE_U16, store, &ch);
        CHECK(ch.flags == TVPAL_CHUNK_MISSING, "u16 with NaN: chunk flagged");
        struct tvpal_chunk c = {.h = ch, .table = store,
                                .table_format = TVPAL_TABLE_U16 |
                                                TVPAL_TABLE_MISSING};
        tvpal_chunk_table(&c, back);
        int same_nan = 1;
        double err = 0;
        for (int i = 0; i < 4 * 256; i++) {
            same_nan &= !isnan(tab[i]) == !isnan(back[i]);
            if (!isnan(tab[i]))
                err = fmax(err, fabs(back[i] - tab[i]));
        }
        CHECK(same_nan, "u16: NaN exactly where stored");
        CHECK(err <= 1004.0 / 65534 * 0.5 * (1 + 1e-4) + 1e-5,
              "u16 missing table error %g", err);
        CHECK(back[6] <= 1000.5f + 1e-3 && back[6] >= 1000.5f - 0.008,
              "u16 largest finite entry below the missing code (%g)",
              back[6]);
        /* A shard of table_format 1 knows no flag: 65535 is a value. */
        c.table_format = TVPAL_TABLE_U16;
        tvpal_chunk_table(&c, back);
        CHECK(!isnan(back[3]), "table_format 1 ignores byte 28");
        tvpal_table_store(tab, 4, TVPAL_TABLE_F32, store, &ch);
        c = (struct tvpal_chunk){.h = ch, .table = store,
                                 .table_format = TVPAL_TABLE_F32 |
                                                 TVPAL_TABLE_MISSING};
        tvpal_chunk_table(&c, back);
        same_nan = ch.flags == TVPAL_CHUNK_MISSING;
        for (int i = 0; i < 4 * 256; i++)
            same_nan &= isnan(tab[i]) ? isnan(back[i]) : back[i] == tab[i];
        CHECK(same_nan, "f32 with NaN: flagged, exact, NaN kept");
        unsigned char chb[TVPAL_CHUNK_HEADER_BYTES];
        tvpal_chunk_header_encode(&ch, chb);
        CHECK(chb[28] == 1 && !chb[29] && !chb[30] && !chb[31],
              "chunk flags at byte 28");
        for (int i = 0; i < 256; i++)
            tab[i] = 1.0f;
        tvpal_table_store(tab, 1, TVPAL_TABLE_F32, store, &ch);
        CHECK(ch.flags == 0, "no NaN: no flag");
    }

    /* FORMAT.md 6.6/6.7: tmin and tscale are f32 at chunk bytes 48 and 52,
     * 56..63 stay zero; a u16 entry decodes as float32(tmin + float32(q *
     * tscale)), two roundings, never a fused multiply-add.  The q chosen are
     * ones where the fused result differs, so a contracted decoder fails. */
    {
        struct tvpal_chunk_header ch = {.slice = 1, .wstart = 0, .wlen = 1,
                                        .w = 2, .h = 2, .used = 1,
                                        .tmin = 0.1f, .tscale = 1e-3f / 3};
        unsigned char cb[TVPAL_CHUNK_HEADER_BYTES + 512];
        tvpal_chunk_header_encode(&ch, cb);
        float f48, f52;
        memcpy(&f48, cb + 48, 4); /* little-endian host assumed by the test */
        memcpy(&f52, cb + 52, 4);
        int zero = 1;
        for (int i = 56; i < 64; i++)
            zero &= cb[i] == 0;
        CHECK(f48 == ch.tmin && f52 == ch.tscale && zero,
              "chunk header tmin/tscale at 48/52, 56..63 zero");
        float want[256];
        unsigned found = 0;
        for (unsigned q = 1; q < 65536 && found < 256; q++) {
            volatile float p = (float)q * ch.tscale;
            float two = ch.tmin + p;
            if (two == fmaf((float)q, ch.tscale, ch.tmin))
                continue;
            cb[64 + 2 * found] = (unsigned char)q;
            cb[64 + 2 * found + 1] = (unsigned char)(q >> 8);
            want[found++] = two;
        }
        CHECK(found == 256, "%u q where fma differs", found);
        float got[256];
        struct tvpal_chunk c = {.h = ch, .table_format = TVPAL_TABLE_U16,
                                .table = cb + 64};
        tvpal_chunk_table(&c, got);
        CHECK(!memcmp(got, want, sizeof got),
              "u16 entries rounded twice (no fused multiply-add)");
    }

    /* Slab split: covers all slices, sizes differ by at most one. */
    for (uint32_t n = 1; n < 70; n++)
        for (uint32_t k = 1; k <= n; k++) {
            uint32_t next = 0, mn = UINT32_MAX, mx = 0;
            for (uint32_t r = 0; r < k; r++) {
                uint32_t b, c;
                tvpal_slab_range(n, k, r, &b, &c);
                CHECK(b == next && c >= 1, "n %u k %u r %u", n, k, r);
                next = b + c;
                mn = c < mn ? c : mn;
                mx = c > mx ? c : mx;
            }
            CHECK(next == n && mx - mn <= 1, "n %u k %u", n, k);
        }
    test_huge_dims();
    return tt_done("test-format");
}
