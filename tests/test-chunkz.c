/* test-chunkz: coded chunks (FORMAT.md 6.11).  Chunks of every kind (16-bit
 * and float32 tables, smooth, noisy and constant indices, slices whose
 * size is no multiple of 16 or 64) code where that makes them smaller and
 * inflate back to their plain bytes exactly; a record mixing coded and
 * plain chunks, read into the tail of its buffer, inflates in place into
 * the record a writer without coding makes, also when a chunk's plain form
 * overlaps its own frame (the scratch path); the readers' refusals: a
 * broken frame, a frame of the wrong size, an index entry whose plain size
 * is not the record header's, a coded chunk in a format_version 1 shard,
 * a frame that claims more than it may.  Inflated in waves on a pool
 * (tvpal_record_inflate_pool: 3 threads, 2 and 5 ways), every record gives
 * the same bytes and every refusal the same code and message. */

static struct tvpal_pool *g_pool;       /* 3 threads */
#include "tvpal_chunkz.h"
#include "tvpal_crc32c.h"
#include "tvpal_format.h"
#include "tvpal_pool.h"
#include "tvpal_schedule.h"

/* The schedule of shard header h (tvpal_shard_schedule), as a pointer. */
#define SCHED(h)                                                              \
    (&(struct tvpal_schedule){(h)->window, (h)->steps, (h)->schedule, 1})
#include "tvpal_shard.h"
#include "tvpal_test.h"

#include <stdlib.h>
#include <string.h>

/* COLUMNS: each column one random index (edges running down the slice:
 * transform G codes it, FORMAT.md 6.11); NIBBLES: random indices 0..15
 * (no row like the one above: G does not pay). */
enum kind { SMOOTH, NOISY, CONSTANT, NIBBLES, COLUMNS };

/* A plain chunk of slice s starting at t into buf: its table (16-bit when
 * u16, else float32) and indices of the given kind (NOISY: uniform random
 * indices and a 16-bit table of uniform values, which no coding shrinks).
 * Returns its bytes. */
static uint64_t make_chunk(const struct tvpal_shard_header *h, uint32_t s,
                           uint32_t t, int u16, enum kind k,
                           unsigned char *buf)
{
    const uint32_t len = tvpal_schedule_len(SCHED(h), s, t);
    if (k == NOISY)
        u16 = 1;
    struct tvpal_chunk_header ch = {
        .slice = s, .wstart = t, .wlen = len, .w = h->slice_w,
        .h = h->slice_h, .used = 200, .bits = {4, 4}};
    float table[16 * 256];
    for (uint32_t j = 0; j < len; j++)
        for (unsigned i = 0; i < 256; i++)
            table[j * 256 + i] = k == NOISY
                ? (float)tt_uniform() * 100.0f
                : (float)(i * 0.37 + j * 0.05 + 1e-3 * (i % 7));
    const uint32_t tf = u16 ? TVPAL_TABLE_U16 : TVPAL_TABLE_F32;
    tvpal_table_store(table, len, tf, buf + 64, &ch);
    if (u16)
        ch.flags |= TVPAL_CHUNK_U16;
    tvpal_chunk_header_encode(&ch, buf);
    const size_t tb = (size_t)len * 256 * (u16 ? 2 : 4);
    const size_t wh = (size_t)h->slice_w * h->slice_h;
    uint8_t *idx = buf + 64 + tb;
    for (size_t v = 0; v < wh; v++) {
        size_t a = v % h->slice_w, b = v / h->slice_w;
        idx[v] = k == SMOOTH ? (uint8_t)((a + 2 * b) / 3 + s)
               : k == NOISY ? (uint8_t)tt_rand64()
               : k == NIBBLES ? (uint8_t)(tt_rand64() & 15)
               : k == COLUMNS ? (uint8_t)(a * 2654435761u >> 13)
               : (uint8_t)42;
    }
    const uint64_t cb = tvpal_chunk_bytes(len, h->slice_w, h->slice_h, tf);
    memset(idx + wh, 0, (size_t)(cb - 64 - tb - wh));
    return cb;
}

static struct tvpal_shard_header header(uint32_t w, uint32_t hh,
                                        uint32_t slices)
{
    struct tvpal_shard_header h = {
        .version = TVPAL_FORMAT_VERSION_CODED, .dims = {w, hh, slices},
        .steps = 6, .window = 4, .nodes = 1, .axis = 2,
        .table_format = TVPAL_TABLE_CHUNK};
    uint32_t n;
    tvpal_axis_geometry(h.dims, 2, &n, &h.slice_w, &h.slice_h);
    tvpal_slab_range(n, 1, 0, &h.slice_begin, &h.slice_count);
    return h;
}

/* Every chunk kind and table codes and inflates back exactly, alone. */
static void test_chunks(void)
{
    const struct tvpal_shard_header h = header(37, 23, 4); /* 851 voxels */
    const uint64_t max = tvpal_shard_max_chunk(&h);
    unsigned char *plain = malloc(max), *coded = malloc(max);
    struct tvpal_chunkz *z = NULL;
    REQUIRE(plain && coded && tvpal_chunkz_create(&z, max) == 0, "alloc");
    for (int u16 = 0; u16 < 2; u16++)
        for (int k = SMOOTH; k <= COLUMNS; k++) {
            uint64_t pb = make_chunk(&h, 1, 0, u16, (enum kind)k, plain);
            uint64_t stored = 0;
            const uint32_t ctf = u16 || k == NOISY ? TVPAL_TABLE_U16
                                                   : TVPAL_TABLE_F32;
            int rc = tvpal_chunkz_code(z, 3, plain, ctf, coded, &stored);
            CHECK(rc >= 0, "kind %d u16 %d: code %d", k, u16, rc);
            if (k == NOISY) {
                CHECK(rc == 0, "noisy table and indices coded smaller (%llu "
                      "of %llu)", (unsigned long long)stored,
                      (unsigned long long)pb);
                continue;
            }
            CHECK(rc == 1 && stored < pb && stored % 64 == 0,
                  "kind %d u16 %d: rc %d, %llu stored of %llu", k, u16, rc,
                  (unsigned long long)stored, (unsigned long long)pb);
            if (rc != 1)
                continue;
            struct tvpal_chunk_header ch;
            tvpal_chunk_header_decode(coded, &ch, NULL);
            CHECK((ch.flags & TVPAL_CHUNK_ZSTD) && ch.coded_bytes > 0 &&
                  tvpal_chunk_stored_bytes(&ch, ctf) == stored,
                  "header: flags 0x%x coded_bytes %u", ch.flags,
                  ch.coded_bytes);
            /* Tables always in T2; indices in G where it pays. */
            CHECK(ch.flags & TVPAL_CHUNK_TABLE_T2, "kind %d: flags 0x%x, "
                  "no T2", k, ch.flags);
            if (k == COLUMNS || k == NIBBLES)
                CHECK(!(ch.flags & TVPAL_CHUNK_INDEX_G) == (k == NIBBLES),
                      "kind %d: flags 0x%x: G %s", k, ch.flags,
                      k == COLUMNS ? "not chosen for columns"
                                   : "chosen for random nibbles");
        }
    CHECK(tvpal_chunkz_code(z, 0, plain, TVPAL_TABLE_F32, coded, &(uint64_t){0})
          == TVPAL_E_INVAL, "level 0 refused");
    tvpal_chunkz_free(z);
    free(plain);
    free(coded);
}

/* A record of h at step t with chunk kinds kinds[] (cycled): builds its
 * plain form (plain, a sealed version-2 record) and its stored form
 * (stored: coded chunks where smaller), and the index entry. */
static void make_record(const struct tvpal_shard_header *h, uint32_t t,
                        const enum kind *kinds, unsigned nk,
                        struct tvpal_chunkz *z, unsigned char *plain,
                        unsigned char *stored, struct tvpal_index_entry *e,
                        unsigned *ncoded)
{
    const uint64_t max = tvpal_shard_max_chunk(h);
    unsigned char *c = malloc(max), *cz = malloc(max);
    REQUIRE(c && cz, "alloc");
    uint64_t pp = 64, sp = 64;
    uint32_t n = 0;
    *ncoded = 0;
    for (uint32_t s = h->slice_begin; s < h->slice_begin + h->slice_count; s++) {
        if (!tvpal_schedule_starts(SCHED(h), s, t))
            continue;
        const enum kind k = kinds[n % nk];
        const int u16 = s % 2 || k == NOISY;
        uint64_t pb = make_chunk(h, s, t, u16, k, c);
        memcpy(plain + pp, c, pb);
        pp += pb;
        uint64_t cb = 0;
        if (tvpal_chunkz_code(z, 3, c, u16 ? 1u : 0u, cz, &cb) == 1) {
            memcpy(stored + sp, cz, cb);
            sp += cb;
            ++*ncoded;
        } else {
            memcpy(stored + sp, c, pb);
            sp += pb;
        }
        n++;
    }
    struct tvpal_record_header rh = {
        .step = t, .chunk_count = n, .axis = h->axis,
        .payload_bytes = pp - 64,
        .payload_crc = tvpal_crc32c(0, plain + 64, pp - 64),
        .plain_bytes = pp - 64};
    tvpal_record_header_encode(&rh, plain);
    memset(plain + pp, 0, tvpal_round_up(pp, TVPAL_ALIGN) - pp);
    rh.payload_bytes = sp - 64;
    rh.payload_crc = tvpal_crc32c(0, stored + 64, sp - 64);
    tvpal_record_header_encode(&rh, stored);
    memset(stored + sp, 0, tvpal_round_up(sp, TVPAL_ALIGN) - sp);
    *e = (struct tvpal_index_entry){
        .offset = TVPAL_SHARD_HEADER_BYTES,
        .bytes = tvpal_round_up(sp, TVPAL_ALIGN), .step = t,
        .chunk_count = n, .crc = rh.payload_crc, .coded = *ncoded > 0,
        .plain_bytes = tvpal_round_up(pp, TVPAL_ALIGN)};
    if (!*ncoded)
        e->plain_bytes = e->bytes;
    free(c);
    free(cz);
}

/* Stores record e (stored bytes) at the tail of a fresh buffer, inflates
 * it in place (on pool with z's ways); returns the code, the buffer in
 * *out (caller frees). */
static int inflate_on(struct tvpal_pool *pool, const struct tvpal_shard_header *h,
                      uint32_t t, const struct tvpal_index_entry *e,
                      const unsigned char *stored, struct tvpal_chunkz *z,
                      unsigned char **out, struct tvpal_diag *d)
{
    const uint64_t bb = tvpal_record_buffer_bytes(e);
    unsigned char *buf = malloc(bb);
    REQUIRE(buf, "alloc");
    memset(buf, 0xA5, bb);   /* no byte of the result may come from here */
    memcpy(buf + tvpal_record_stored_at(e), stored, e->bytes);
    *out = buf;
    return tvpal_record_inflate_pool(z, pool, buf, e, t, h, d);
}

/* inflate_on serially, then in waves of 2 and of 5 chunks on g_pool: the
 * same code, message and (when 0) bytes each time. */
static int inflate_copy(const struct tvpal_shard_header *h, uint32_t t,
                        const struct tvpal_index_entry *e,
                        const unsigned char *stored, struct tvpal_chunkz *z,
                        unsigned char **out, struct tvpal_diag *d)
{
    int rc = inflate_on(NULL, h, t, e, stored, z, out, d);
    for (unsigned ways = 2; ways <= 5; ways += 3) {
        struct tvpal_chunkz *zw = NULL;
        unsigned char *b = NULL;
        struct tvpal_diag dw = {{0}};
        REQUIRE(tvpal_chunkz_create_ways(&zw, tvpal_shard_max_chunk(h),
                                         ways) == 0, "ways");
        int rw = inflate_on(g_pool, h, t, e, stored, zw, &b, &dw);
        CHECK(rw == rc && (rc != 0 || !strcmp(dw.msg, d->msg)) &&
                  (rc != 0 || !memcmp(b, *out, e->plain_bytes)),
              "record %u, %u ways on 3 threads: %d (%s) against %d (%s)", t,
              ways, rw, dw.msg, rc, d->msg);
        CHECK(rc == 0 || !strcmp(dw.msg, d->msg), "ways %u: message \"%s\" "
              "against \"%s\"", ways, dw.msg, d->msg);
        free(b);
        tvpal_chunkz_free(zw);
    }
    return rc;
}

static void test_record(const char *what, struct tvpal_shard_header h,
                        uint32_t t, const enum kind *kinds, unsigned nk,
                        unsigned want_coded_min)
{
    const uint64_t room = 64 + h.slice_count * tvpal_shard_max_chunk(&h) +
                          2 * TVPAL_ALIGN;
    unsigned char *plain = calloc(1, room), *stored = calloc(1, room);
    struct tvpal_chunkz *z = NULL;
    REQUIRE(plain && stored &&
            tvpal_chunkz_create(&z, tvpal_shard_max_chunk(&h)) == 0, "alloc");
    struct tvpal_index_entry e;
    unsigned ncoded;
    make_record(&h, t, kinds, nk, z, plain, stored, &e, &ncoded);
    CHECK(ncoded >= want_coded_min, "%s: %u chunks coded", what, ncoded);
    struct tvpal_diag d = {{0}};
    CHECK(tvpal_record_verify(stored, e.bytes, t, &h, &d) == 0,
          "%s: stored record verifies: %s", what, d.msg);
    unsigned char *buf = NULL;
    int rc = inflate_copy(&h, t, &e, stored, z, &buf, &d);
    CHECK(rc == 0, "%s: inflate: %s", what, d.msg);
    CHECK(rc != 0 || memcmp(buf, plain, e.plain_bytes) == 0,
          "%s: inflated record differs from the plain one", what);
    CHECK(rc != 0 || tvpal_record_verify(buf, e.plain_bytes, t, &h, &d) == 0,
          "%s: inflated record verifies: %s", what, d.msg);
    free(buf);
    if (ncoded) {
        /* A frame byte broken, the CRCs made valid again: the frame's own
         * error, naming record and slice. */
        uint64_t pos = 0;
        struct tvpal_chunk c;
        unsigned char *bad = malloc(e.bytes);
        REQUIRE(bad, "alloc");
        memcpy(bad, stored, e.bytes);
        while (tvpal_record_next_chunk(bad, &pos, h.table_format, &c))
            if (c.h.flags & TVPAL_CHUNK_ZSTD)
                break;
        ((unsigned char *)c.table)[0] ^= 0x01;   /* the zstd magic */
        struct tvpal_record_header rh;
        tvpal_record_header_decode(bad, &rh, NULL);
        rh.payload_crc = tvpal_crc32c(0, bad + 64, rh.payload_bytes);
        tvpal_record_header_encode(&rh, bad);
        char want[64];
        snprintf(want, sizeof want, "record %u: slice %u: coded chunk", t,
                 c.h.slice);
        rc = inflate_copy(&h, t, &e, bad, z, &buf, &d);
        CHECK(rc == TVPAL_E_FORMAT && strstr(d.msg, want),
              "%s: broken frame: %d %s", what, rc, d.msg);
        free(buf);
        /* Without the CRC fixed: a checksum error, before any frame. */
        memcpy(bad, stored, e.bytes);
        bad[e.bytes - 1 - (e.bytes - 64 - rh.payload_bytes)] ^= 0x10;
        rc = inflate_copy(&h, t, &e, bad, z, &buf, &d);
        CHECK(rc == TVPAL_E_CHECKSUM, "%s: damaged payload: %d %s", what, rc,
              d.msg);
        free(buf);
        /* The index's plain size one page more than the header's. */
        struct tvpal_index_entry e2 = e;
        e2.plain_bytes += TVPAL_ALIGN;
        rc = inflate_copy(&h, t, &e2, stored, z, &buf, &d);
        CHECK(rc == TVPAL_E_FORMAT && strstr(d.msg, "inflated"),
              "%s: plain size: %d %s", what, rc, d.msg);
        free(buf);
        /* The same record in a shard of format_version 1: bit 2 refused. */
        struct tvpal_shard_header h1 = h;
        h1.version = TVPAL_FORMAT_VERSION;
        CHECK(tvpal_record_verify(stored, e.bytes, t, &h1, &d) ==
                  TVPAL_E_FORMAT && strstr(d.msg, "flags 0x"),
              "%s: coded chunk in version 1: %s", what, d.msg);
        free(bad);
    }
    tvpal_chunkz_free(z);
    free(plain);
    free(stored);
}

/* A coded chunk that claims a frame larger than its plain form, or none. */
static void test_frame_size_rules(void)
{
    struct tvpal_shard_header h = header(64, 64, 1);
    const uint64_t max = tvpal_shard_max_chunk(&h);
    unsigned char *c = malloc(max), *rec = calloc(1, 64 + max + TVPAL_ALIGN);
    struct tvpal_chunkz *z = NULL;
    REQUIRE(c && rec && tvpal_chunkz_create(&z, max) == 0, "alloc");
    make_chunk(&h, 0, 0, 1, SMOOTH, c);
    uint64_t cb = 0;
    REQUIRE(tvpal_chunkz_code(z, 3, c, 1, rec + 64, &cb) == 1, "code");
    struct tvpal_chunk_header ch;
    tvpal_chunk_header_decode(rec + 64, &ch, NULL);
    const uint32_t claims[] = {0, 1u << 20};
    for (unsigned i = 0; i < 2; i++) {
        ch.coded_bytes = claims[i];
        tvpal_chunk_header_encode(&ch, rec + 64);
        uint64_t pay = i ? cb : 64;
        struct tvpal_record_header rh = {
            .step = 0, .chunk_count = 1, .axis = 2, .payload_bytes = pay,
            .payload_crc = tvpal_crc32c(0, rec + 64, pay),
            .plain_bytes = tvpal_chunk_bytes(h.window, 64, 64, 1)};
        tvpal_record_header_encode(&rh, rec);
        struct tvpal_diag d = {{0}};
        CHECK(tvpal_record_verify(rec, tvpal_round_up(64 + pay, TVPAL_ALIGN),
                                  0, &h, &d) == TVPAL_E_FORMAT &&
                  strstr(d.msg, "a frame of"),
              "coded_bytes %u: %s", claims[i], d.msg);
    }
    tvpal_chunkz_free(z);
    free(c);
    free(rec);
}

int main(void)
{
    REQUIRE(tvpal_pool_create(&g_pool, 3) == 0, "pool");
    test_chunks();
    /* Record 0 of 37x23 slices, N = 4: every slice, all kinds mixed, so
     * coded and plain chunks alternate. */
    const enum kind mix[] = {SMOOTH, NOISY, CONSTANT, NIBBLES, NOISY,
                             COLUMNS};
    test_record("mixed", header(37, 23, 9), 0, mix, 6, 3);
    test_record("mixed, step 3", header(37, 23, 9), 3, mix, 6, 1);
    /* One large chunk coded to about half: its plain form reaches its
     * own frame, so it inflates through the scratch. */
    const enum kind nib[] = {NIBBLES};
    test_record("overlap", header(160, 128, 1), 0, nib, 1, 1);
    /* Nothing coded: the record stays as it is. */
    const enum kind noisy[] = {NOISY};
    test_record("none coded", header(37, 23, 4), 0, noisy, 1, 0);
    test_frame_size_rules();
    tvpal_pool_free(g_pool);
    return tt_done("test-chunkz");
}
