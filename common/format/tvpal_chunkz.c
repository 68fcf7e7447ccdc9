/* tvpal_chunkz.c: coded chunks (FORMAT.md 6.11) with libzstd. */
#include "tvpal_chunkz.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zstd.h>
#include <zstd_errors.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "tvpal_crc32c.h"
#include "tvpal_pool.h"

/* The largest table: a row of 256 float32 entries per step of the longest
 * window. */
#define TABLE_MAX (TVPAL_SCHEDULE_LEN_MAX * 256u * 4u)

/* One chunk of a wave (inflate_waves): where it is and goes, and what its
 * worker found. */
struct wave_item {
    struct tvpal_chunk_header h;
    uint32_t ctf;
    const unsigned char *src;
    unsigned char *dst;
    uint64_t cb, pb;            /* stored, plain bytes */
    uint32_t crc;               /* of the plain chunk */
    int rc;
    char why[TVPAL_DIAG_MAX];
};

struct tvpal_chunkz {
    ZSTD_CCtx *cctx;            /* created at the first code */
    ZSTD_DCtx **dctx;           /* per way, created at the first inflate */
    unsigned char **scratch;    /* per way: a chunk's transformed table and
                                 * indices, or a plain chunk's copy */
    unsigned ways;
    uint64_t max_chunk;
    struct wave_item *item;     /* ways of them */
    unsigned char table[TABLE_MAX];   /* a table's planes, moved aside */
};

int tvpal_chunkz_create_ways(struct tvpal_chunkz **out, uint64_t max_chunk,
                             unsigned ways)
{
    if (ways < 1 || ways > TVPAL_CHUNKZ_WAYS_MAX || max_chunk > SIZE_MAX)
        return TVPAL_E_INVAL;
    struct tvpal_chunkz *z = calloc(1, sizeof *z);
    if (!z)
        return TVPAL_E_NOMEM;
    z->ways = ways;
    z->max_chunk = max_chunk;
    z->dctx = calloc(ways, sizeof *z->dctx);
    z->scratch = calloc(ways, sizeof *z->scratch);
    z->item = calloc(ways, sizeof *z->item);
    int ok = z->dctx && z->scratch && z->item;
    for (unsigned i = 0; ok && i < ways; i++)
        ok = (z->scratch[i] = malloc(max_chunk)) != NULL;
    if (!ok) {
        tvpal_chunkz_free(z);
        return TVPAL_E_NOMEM;
    }
    *out = z;
    return 0;
}

int tvpal_chunkz_create(struct tvpal_chunkz **out, uint64_t max_chunk)
{
    return tvpal_chunkz_create_ways(out, max_chunk, 1);
}

void tvpal_chunkz_free(struct tvpal_chunkz *z)
{
    if (!z)
        return;
    ZSTD_freeCCtx(z->cctx);
    for (unsigned i = 0; i < z->ways; i++) {
        if (z->dctx)
            ZSTD_freeDCtx(z->dctx[i]);
        if (z->scratch)
            free(z->scratch[i]);
    }
    free(z->dctx);
    free(z->scratch);
    free(z->item);
    free(z);
}

unsigned tvpal_chunkz_ways(const struct tvpal_chunkz *z)
{
    return z->ways;
}

const char *tvpal_chunkz_library(void)
{
    static char name[32];
    if (!name[0])
        snprintf(name, sizeof name, "zstd %s", ZSTD_versionString());
    return name;
}

/* ---------------------------------------------------------- transforms */

static uint32_t load_le(const unsigned char *p, unsigned E)
{
    return E == 2 ? (uint32_t)p[0] | (uint32_t)p[1] << 8
                  : (uint32_t)p[0] | (uint32_t)p[1] << 8 |
                        (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* A table of the first transform (flags bit 3 clear: what 0.4.0's first
 * coded chunks hold) from its planes (src) into its n = rows * 256
 * entries of E bytes (dst): each plane position k holds the delta of
 * entry k from the entry of the row before (row 0: the entry before, the
 * first as it is), modulo 2^(8E).  src and dst do not overlap. */
static void table_inverse(const unsigned char *src, uint32_t n, unsigned E,
                          unsigned char *dst)
{
    const uint32_t mask = E == 2 ? 0xFFFFu : 0xFFFFFFFFu;
    for (uint32_t k = 0; k < n; k++) {
        uint32_t d = 0;
        for (unsigned b = 0; b < E; b++)
            d |= (uint32_t)src[(size_t)b * n + k] << (8 * b);
        uint32_t p = k >= 256 ? load_le(dst + (size_t)(k - 256) * E, E)
                   : k ? load_le(dst + (size_t)(k - 1) * E, E) : 0u;
        uint32_t e = (p + d) & mask;
        for (unsigned b = 0; b < E; b++)
            dst[(size_t)k * E + b] = (unsigned char)(e >> (8 * b));
    }
}

/* dst[k] = src[k] - src[k - 1] (mod 256), dst[0] = src[0]. */
static void index_forward(const uint8_t *src, size_t n, uint8_t *dst)
{
    uint8_t prev = 0;
    for (size_t k = 0; k < n; k++) {
        dst[k] = (uint8_t)(src[k] - prev);
        prev = src[k];
    }
}

/* The running sum (mod 256) of src into dst; they may be the same.  The
 * inflate's one pass over every index besides zstd's own: 16 bytes at a
 * time where SSE2 is there (a prefix sum in four shifted adds). */
static void index_inverse(const uint8_t *src, size_t n, uint8_t *dst)
{
    size_t k = 0;
    uint8_t run = 0;
#if defined(__SSE2__)
    __m128i carry = _mm_setzero_si128();
    for (; k + 16 <= n; k += 16) {
        __m128i v = _mm_loadu_si128((const __m128i *)(src + k));
        v = _mm_add_epi8(v, _mm_slli_si128(v, 1));
        v = _mm_add_epi8(v, _mm_slli_si128(v, 2));
        v = _mm_add_epi8(v, _mm_slli_si128(v, 4));
        v = _mm_add_epi8(v, _mm_slli_si128(v, 8));
        v = _mm_add_epi8(v, carry);
        _mm_storeu_si128((__m128i *)(dst + k), v);
        /* byte 15 into every lane */
        __m128i t = _mm_srli_si128(v, 15);
        t = _mm_unpacklo_epi8(t, t);
        t = _mm_unpacklo_epi16(t, t);
        carry = _mm_shuffle_epi32(t, 0);
    }
    if (k)
        run = dst[k - 1];
#endif
    for (; k < n; k++) {
        run = (uint8_t)(run + src[k]);
        dst[k] = run;
    }
}

/* A table delta as an unsigned number that is small when the delta is
 * small either way: the E-byte d read as signed, 2d for d >= 0, -2d - 1
 * below (zigzag), and back. */
static uint32_t zigzag(uint32_t d, unsigned E)
{
    const uint32_t mask = E == 2 ? 0xFFFFu : 0xFFFFFFFFu;
    const uint32_t neg = (d >> (8 * E - 1)) & 1u;
    return ((d << 1) ^ (neg ? mask : 0u)) & mask;
}

static uint32_t unzigzag(uint32_t z, unsigned E)
{
    const uint32_t mask = E == 2 ? 0xFFFFu : 0xFFFFFFFFu;
    return ((z >> 1) ^ ((z & 1u) ? mask : 0u)) & mask;
}

/* Transform T2 of a table (flags bit 3): table_inverse's deltas d[k],
 * zigzagged, in E byte planes ordered index-major: plane position
 * i * rows + j holds entry k = j * 256 + i, so each index's entries over
 * the window lie together (an index's value moves smoothly in time; a
 * row's neighbouring indices need not). */
static void table_forward_t2(const unsigned char *src, uint32_t rows,
                             unsigned E, unsigned char *dst)
{
    const uint32_t n = rows * 256u;
    for (uint32_t k = 0; k < n; k++) {
        uint32_t e = load_le(src + (size_t)k * E, E);
        uint32_t p = k >= 256 ? load_le(src + (size_t)(k - 256) * E, E)
                   : k ? load_le(src + (size_t)(k - 1) * E, E) : 0u;
        uint32_t z = zigzag(e - p, E);
        size_t at = (size_t)(k % 256u) * rows + k / 256u;
        for (unsigned b = 0; b < E; b++)
            dst[(size_t)b * n + at] = (unsigned char)(z >> (8 * b));
    }
}

/* The inverse of table_forward_t2; src and dst do not overlap. */
static void table_inverse_t2(const unsigned char *src, uint32_t rows,
                             unsigned E, unsigned char *dst)
{
    const uint32_t n = rows * 256u;
    const uint32_t mask = E == 2 ? 0xFFFFu : 0xFFFFFFFFu;
    for (uint32_t k = 0; k < n; k++) {
        size_t at = (size_t)(k % 256u) * rows + k / 256u;
        uint32_t z = 0;
        for (unsigned b = 0; b < E; b++)
            z |= (uint32_t)src[(size_t)b * n + at] << (8 * b);
        uint32_t p = k >= 256 ? load_le(dst + (size_t)(k - 256) * E, E)
                   : k ? load_le(dst + (size_t)(k - 1) * E, E) : 0u;
        uint32_t e = (p + unzigzag(z, E)) & mask;
        for (unsigned b = 0; b < E; b++)
            dst[(size_t)k * E + b] = (unsigned char)(e >> (8 * b));
    }
}

/* Transform G of the indices (flags bit 4), w per row, h rows: row 0 as
 * index_forward; in a later row each index's difference from the one
 * above (u), as a difference from its left neighbour's u (the first u as
 * it is).  Where edges run down the slice, u is smooth along the row. */
static void index_forward_g(const uint8_t *src, size_t w, size_t h,
                            uint8_t *dst)
{
    index_forward(src, w, dst);
    for (size_t b = 1; b < h; b++) {
        const uint8_t *x = src + b * w, *up = x - w;
        uint8_t *d = dst + b * w;
        uint8_t prev = 0;
        for (size_t a = 0; a < w; a++) {
            uint8_t u = (uint8_t)(x[a] - up[a]);
            d[a] = (uint8_t)(u - prev);
            prev = u;
        }
    }
}

/* The inverse of index_forward_g; src and dst may be the same.  Per row
 * index_inverse's running sum, then the row above added, 16 bytes at a
 * time where SSE2 is there. */
static void index_inverse_g(const uint8_t *src, size_t w, size_t h,
                            uint8_t *dst)
{
    index_inverse(src, w, dst);
    for (size_t b = 1; b < h; b++) {
        uint8_t *x = dst + b * w;
        const uint8_t *up = x - w;
        index_inverse(src + b * w, w, x);
        size_t a = 0;
#if defined(__SSE2__)
        for (; a + 16 <= w; a += 16)
            _mm_storeu_si128((__m128i *)(x + a),
                             _mm_add_epi8(_mm_loadu_si128((__m128i *)(x + a)),
                                          _mm_loadu_si128(
                                              (const __m128i *)(up + a))));
#endif
        for (; a < w; a++)
            x[a] = (uint8_t)(x[a] + up[a]);
    }
}

/* The sum of c log2 c over the histogram of v[0..n): order-0 coding
 * takes n log2 n minus it in bits, so of two transforms of the same
 * values the larger sum codes smaller (within a percent or two of trying
 * both with zstd, at a fraction of the cost). */
static double order0_sum(const uint8_t *v, size_t n)
{
    uint32_t hist[256] = {0};
    for (size_t m = 0; m < n; m++)
        hist[v[m]]++;
    double s = 0;
    for (unsigned i = 0; i < 256; i++)
        if (hist[i])
            s += hist[i] * log2(hist[i]);
    return s;
}

/* ---------------------------------------------------------------- code */

int tvpal_chunkz_code(struct tvpal_chunkz *z, int level,
                      const unsigned char *chunk, uint32_t ctf,
                      unsigned char *dst, uint64_t *stored)
{
    struct tvpal_chunk_header h;
    if (level < 1 || level > ZSTD_maxCLevel() ||
        tvpal_chunk_header_decode(chunk, &h, NULL) < 0 || h.wlen < 1 ||
        h.wlen > TVPAL_SCHEDULE_LEN_MAX ||
        (h.flags & TVPAL_CHUNK_CODED_BITS))
        return TVPAL_E_INVAL;
    const uint64_t plain = tvpal_chunk_bytes(h.wlen, h.w, h.h, ctf);
    if (plain > z->max_chunk)
        return TVPAL_E_INVAL;
    if (!z->cctx && !(z->cctx = ZSTD_createCCtx()))
        return TVPAL_E_NOMEM;
    const unsigned E = tvpal_table_entry_bytes(ctf);
    const uint32_t n = h.wlen * 256u;
    const size_t tb = (size_t)n * E, wh = (size_t)h.w * h.h;
    const unsigned char *table = chunk + TVPAL_CHUNK_HEADER_BYTES;
    /* Transform T2 always (it codes tables smaller on every series
     * measured), G where it looks smaller (FORMAT.md 6.11). */
    table_forward_t2(table, h.wlen, E, z->scratch[0]);
    const uint8_t *x = table + tb;
    uint8_t *d = z->scratch[0] + tb;
    index_forward(x, wh, d);
    const double left = order0_sum(d, wh);
    index_forward_g(x, h.w, h.h, d);
    const int g = order0_sum(d, wh) > left;
    if (!g)
        index_forward(x, wh, d);
    /* Room for a frame that makes the chunk smaller by at least 64. */
    if (plain < 2 * TVPAL_CHUNK_HEADER_BYTES)
        return 0;
    const size_t room = (size_t)(plain - 2 * TVPAL_CHUNK_HEADER_BYTES);
    size_t f = ZSTD_compressCCtx(z->cctx, dst + TVPAL_CHUNK_HEADER_BYTES,
                                 room, z->scratch[0], tb + wh, level);
    if (ZSTD_isError(f))   /* dstSize_tooSmall: coding does not pay */
        return ZSTD_getErrorCode(f) == ZSTD_error_dstSize_tooSmall
                   ? 0 : TVPAL_E_NOMEM;
    h.flags |= TVPAL_CHUNK_ZSTD | TVPAL_CHUNK_TABLE_T2 |
               (g ? TVPAL_CHUNK_INDEX_G : 0u);
    h.coded_bytes = (uint32_t)f;
    tvpal_chunk_header_encode(&h, dst);
    *stored = tvpal_chunk_stored_bytes(&h, ctf);
    memset(dst + TVPAL_CHUNK_HEADER_BYTES + f, 0,
           (size_t)(*stored - TVPAL_CHUNK_HEADER_BYTES - f));
    return *stored < plain ? 1 : 0;
}

/* ------------------------------------------------------------- inflate */

/* The zstd frame of coded chunk h (at its stored bytes src) into out (tb
 * + wh bytes: the transformed table and indices).  0, or TVPAL_E_FORMAT
 * with why (naming record and slice) when the frame does not decode to
 * exactly that. */
static int decompress(ZSTD_DCtx *d, const struct tvpal_chunk_header *h,
                      const unsigned char *src, unsigned char *out,
                      size_t want, uint32_t step, char *why, size_t cap)
{
    size_t got = ZSTD_decompressDCtx(d, out, want,
                                     src + TVPAL_CHUNK_HEADER_BYTES,
                                     h->coded_bytes);
    if (!ZSTD_isError(got) && got == want)
        return 0;
    snprintf(why, cap, "record %u: slice %u: coded chunk: %s (its frame "
             "must decode to %zu bytes of table and indices)", step,
             h->slice, ZSTD_isError(got) ? ZSTD_getErrorName(got)
                                         : "wrong size", want);
    return TVPAL_E_FORMAT;
}

/* The plain chunk h at dst from its transformed table (planes: n entries
 * of E bytes, not overlapping the table's place at dst + 64, since
 * table_inverse reads the planes while it writes the entries) and indices
 * (wh bytes, possibly already in their place). */
static void unpack(struct tvpal_chunk_header h, uint32_t ctf,
                   const unsigned char *planes, const uint8_t *indices,
                   unsigned char *dst)
{
    const unsigned E = tvpal_table_entry_bytes(ctf);
    const uint32_t n = h.wlen * 256u;
    const size_t tb = (size_t)n * E, wh = (size_t)h.w * h.h;
    const uint64_t plain = tvpal_chunk_bytes(h.wlen, h.w, h.h, ctf);
    unsigned char *table = dst + TVPAL_CHUNK_HEADER_BYTES;
    if (h.flags & TVPAL_CHUNK_TABLE_T2)
        table_inverse_t2(planes, h.wlen, E, table);
    else
        table_inverse(planes, n, E, table);
    if (h.flags & TVPAL_CHUNK_INDEX_G)
        index_inverse_g(indices, h.w, h.h, table + tb);
    else
        index_inverse(indices, wh, table + tb);
    memset(table + tb + wh, 0,
           (size_t)(plain - TVPAL_CHUNK_HEADER_BYTES - tb - wh));
    h.flags &= ~TVPAL_CHUNK_CODED_BITS;
    h.coded_bytes = 0;
    tvpal_chunk_header_encode(&h, dst);
}

/* Inflates the coded chunk (header h, frame at src) into its plain form at
 * dst (header included, plain bytes): straight into dst when that does
 * not reach src + its frame, else through the scratch. */
static int inflate_chunk(struct tvpal_chunkz *z, struct tvpal_chunk_header h,
                         uint32_t ctf, const unsigned char *src,
                         unsigned char *dst, uint32_t step,
                         struct tvpal_diag *diag)
{
    const size_t tb = (size_t)h.wlen * 256u * tvpal_table_entry_bytes(ctf);
    const size_t wh = (size_t)h.w * h.h;
    const uint64_t plain = tvpal_chunk_bytes(h.wlen, h.w, h.h, ctf);
    if (plain > z->max_chunk)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "record %u: slice %u: "
                              "a chunk of %llu bytes, more than the shard's "
                              "largest", step, h.slice,
                              (unsigned long long)plain);
    const int direct = dst + plain <= src;
    unsigned char *out = direct ? dst + TVPAL_CHUNK_HEADER_BYTES
                                : z->scratch[0];
    char why[TVPAL_DIAG_MAX];
    if (decompress(z->dctx[0], &h, src, out, tb + wh, step, why, sizeof why))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s", why);
    if (direct) {
        /* The planes sit where the entries go: moved aside first; the
         * indices are summed in place. */
        memcpy(z->table, out, tb);
        unpack(h, ctf, z->table, out + tb, dst);
    } else {
        unpack(h, ctf, out, out + tb, dst);
    }
    return 0;
}

/* A wave of the parallel inflate: its items and where they come from. */
struct wave_ctx {
    struct tvpal_chunkz *z;
    uint32_t step;
};

/* Phase one of a wave: item i's stored bytes read into scratch i (a coded
 * chunk's frame decompressed, a plain chunk copied), the record buffer
 * only read. */
static void wave_read(void *ctx, size_t i, unsigned tid)
{
    const struct wave_ctx *c = ctx;
    struct wave_item *it = &c->z->item[i];
    unsigned char *s = c->z->scratch[i];
    (void)tid;
    if (!(it->h.flags & TVPAL_CHUNK_ZSTD)) {
        memcpy(s, it->src, (size_t)it->cb);
        return;
    }
    const size_t want = (size_t)it->h.wlen * 256u *
                            tvpal_table_entry_bytes(it->ctf) +
                        (size_t)it->h.w * it->h.h;
    it->rc = decompress(c->z->dctx[i], &it->h, it->src, s, want, c->step,
                        it->why, sizeof it->why);
}

/* Phase two: item i's plain chunk written from scratch i to its place, and
 * its CRC. */
static void wave_write(void *ctx, size_t i, unsigned tid)
{
    const struct wave_ctx *c = ctx;
    struct wave_item *it = &c->z->item[i];
    (void)tid;
    if (it->rc)
        return;
    const unsigned char *s = c->z->scratch[i];
    const size_t tb = (size_t)it->h.wlen * 256u *
                      tvpal_table_entry_bytes(it->ctf);
    if (it->h.flags & TVPAL_CHUNK_ZSTD)
        unpack(it->h, it->ctf, s, s + tb, it->dst);
    else
        memcpy(it->dst, c->z->scratch[i], (size_t)it->cb);
    it->crc = tvpal_crc32c(0, it->dst, it->pb);
}

/* The chunks of a checked record (rh; stored from src, plain from dst),
 * inflated in waves of z->ways chunks on the pool: each wave first reads
 * all its chunks into the scratches, then writes all their plain forms.
 * A wave's plain forms end before the stored chunks after it start (as a
 * chunk's do, 6.11), so once its reads are done its writes clobber
 * nothing still to be read, whichever thread does which.  *crc: the plain
 * payload's. */
static int inflate_waves(struct tvpal_chunkz *z, struct tvpal_pool *pool,
                         const struct tvpal_record_header *rh,
                         const unsigned char *src, unsigned char *dst,
                         uint32_t step, const struct tvpal_shard_header *sh,
                         uint32_t *crc, struct tvpal_diag *diag)
{
    struct wave_ctx c = {z, step};
    *crc = 0;
    for (uint32_t k = 0; k < rh->chunk_count;) {
        unsigned n = 0;
        for (; n < z->ways && k < rh->chunk_count; n++, k++) {
            struct wave_item *it = &z->item[n];
            (void)tvpal_chunk_header_decode(src, &it->h, NULL);
            it->ctf = tvpal_chunk_table_format(sh->table_format, it->h.flags);
            it->cb = tvpal_chunk_stored_bytes(&it->h, it->ctf);
            it->pb = tvpal_chunk_bytes(it->h.wlen, it->h.w, it->h.h, it->ctf);
            it->src = src;
            it->dst = dst;
            it->rc = 0;
            if (it->pb > z->max_chunk)
                return tvpal_diag_set(diag, TVPAL_E_INVAL, "record %u: "
                                      "slice %u: a chunk of %llu bytes, "
                                      "more than the shard's largest", step,
                                      it->h.slice,
                                      (unsigned long long)it->pb);
            src += it->cb;
            dst += it->pb;
        }
        tvpal_pool_for(pool, n, wave_read, &c);
        for (unsigned i = 0; i < n; i++)
            if (z->item[i].rc)
                return tvpal_diag_set(diag, z->item[i].rc, "%s",
                                      z->item[i].why);
        tvpal_pool_for(pool, n, wave_write, &c);
        for (unsigned i = 0; i < n; i++)
            *crc = tvpal_crc32c_combine(*crc, z->item[i].crc, z->item[i].pb);
    }
    return 0;
}

int tvpal_record_inflate(struct tvpal_chunkz *z, unsigned char *buf,
                         const struct tvpal_index_entry *e, uint32_t step,
                         const struct tvpal_shard_header *sh,
                         struct tvpal_diag *diag)
{
    return tvpal_record_inflate_pool(z, NULL, buf, e, step, sh, diag);
}

int tvpal_record_inflate_pool(struct tvpal_chunkz *z, struct tvpal_pool *pool,
                              unsigned char *buf,
                              const struct tvpal_index_entry *e, uint32_t step,
                              const struct tvpal_shard_header *sh,
                              struct tvpal_diag *diag)
{
    const uint64_t at = tvpal_record_stored_at(e);
    if (!e->coded)
        return 0;
    unsigned char *rec = buf + at;
    int rc = tvpal_record_verify(rec, e->bytes, step, sh, diag);
    if (rc < 0)
        return rc;
    struct tvpal_record_header rh;
    (void)tvpal_record_header_decode(rec, &rh, NULL);
    const uint64_t header_says = tvpal_round_up(
        TVPAL_RECORD_HEADER_BYTES + rh.plain_bytes, TVPAL_ALIGN);
    if (header_says != e->plain_bytes)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "record %u: the index "
                              "says %llu bytes inflated, the record "
                              "header's plain_bytes make %llu", step,
                              (unsigned long long)e->plain_bytes,
                              (unsigned long long)header_says);
    const int waves = z->ways > 1 && tvpal_pool_threads(pool) > 1;
    for (unsigned i = 0; i < (waves ? z->ways : 1u); i++)
        if (!z->dctx[i] && !(z->dctx[i] = ZSTD_createDCtx()))
            return TVPAL_E_NOMEM;
    /* Front to back: dst never passes src (every chunk is no larger
     * stored than plain), and a chunk's plain form ends before the stored
     * chunks after it start. */
    const unsigned char *src = rec + TVPAL_RECORD_HEADER_BYTES;
    unsigned char *dst = buf + TVPAL_RECORD_HEADER_BYTES;
    uint32_t crc = 0;
    if (waves) {
        rc = inflate_waves(z, pool, &rh, src, dst, step, sh, &crc, diag);
        if (rc < 0)
            return rc;
        dst += rh.plain_bytes;
    }
    for (uint32_t k = 0; !waves && k < rh.chunk_count; k++) {
        struct tvpal_chunk_header h;
        (void)tvpal_chunk_header_decode(src, &h, NULL);
        const uint32_t ctf = tvpal_chunk_table_format(sh->table_format,
                                                      h.flags);
        const uint64_t cb = tvpal_chunk_stored_bytes(&h, ctf);
        const uint64_t pb = tvpal_chunk_bytes(h.wlen, h.w, h.h, ctf);
        if (h.flags & TVPAL_CHUNK_ZSTD) {
            rc = inflate_chunk(z, h, ctf, src, dst, step, diag);
            if (rc < 0)
                return rc;
        } else {
            memmove(dst, src, cb);
        }
        crc = tvpal_crc32c(crc, dst, pb);
        src += cb;
        dst += pb;
    }
    rh.payload_bytes = rh.plain_bytes;
    rh.payload_crc = crc;
    tvpal_record_header_encode(&rh, buf);
    memset(dst, 0, (size_t)(buf + e->plain_bytes - dst));
    return 0;
}
