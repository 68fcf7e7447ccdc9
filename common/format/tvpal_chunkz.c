/* tvpal_chunkz.c: coded chunks (FORMAT.md 6.11) with libzstd. */
#include "tvpal_chunkz.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zstd.h>
#include <zstd_errors.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "tvpal_crc32c.h"

/* The largest table: 16 rows of 256 float32 entries. */
#define TABLE_MAX (16u * 256u * 4u)

struct tvpal_chunkz {
    ZSTD_CCtx *cctx;            /* created at the first code */
    ZSTD_DCtx *dctx;            /* created at the first inflate */
    unsigned char *scratch;     /* a chunk's transformed table + indices */
    uint64_t max_chunk;
    unsigned char table[TABLE_MAX];   /* a table's planes, moved aside */
};

int tvpal_chunkz_create(struct tvpal_chunkz **out, uint64_t max_chunk)
{
    struct tvpal_chunkz *z = calloc(1, sizeof *z);
    if (!z || max_chunk > SIZE_MAX || !(z->scratch = malloc(max_chunk))) {
        free(z);
        return TVPAL_E_NOMEM;
    }
    z->max_chunk = max_chunk;
    *out = z;
    return 0;
}

void tvpal_chunkz_free(struct tvpal_chunkz *z)
{
    if (!z)
        return;
    ZSTD_freeCCtx(z->cctx);
    ZSTD_freeDCtx(z->dctx);
    free(z->scratch);
    free(z);
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

/* The table's n = rows * 256 entries of E bytes (src) as their
 * differences, the entry of the row before (row 0: the entry before, the
 * first as it is), modulo 2^(8E), in E byte planes (dst, n * E bytes). */
static void table_forward(const unsigned char *src, uint32_t n, unsigned E,
                          unsigned char *dst)
{
    for (uint32_t k = 0; k < n; k++) {
        uint32_t e = load_le(src + (size_t)k * E, E);
        uint32_t p = k >= 256 ? load_le(src + (size_t)(k - 256) * E, E)
                   : k ? load_le(src + (size_t)(k - 1) * E, E) : 0u;
        uint32_t d = e - p;
        for (unsigned b = 0; b < E; b++)
            dst[(size_t)b * n + k] = (unsigned char)(d >> (8 * b));
    }
}

/* The inverse of table_forward: planes (src) to entries (dst); src and
 * dst do not overlap. */
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

/* ---------------------------------------------------------------- code */

int tvpal_chunkz_code(struct tvpal_chunkz *z, int level,
                      const unsigned char *chunk, uint32_t ctf,
                      unsigned char *dst, uint64_t *stored)
{
    struct tvpal_chunk_header h;
    if (level < 1 || level > ZSTD_maxCLevel() ||
        tvpal_chunk_header_decode(chunk, &h, NULL) < 0 || h.wlen < 1 ||
        h.wlen > 16 || (h.flags & TVPAL_CHUNK_ZSTD))
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
    table_forward(table, n, E, z->scratch);
    index_forward(table + tb, wh, z->scratch + tb);
    /* Room for a frame that makes the chunk smaller by at least 64. */
    if (plain < 2 * TVPAL_CHUNK_HEADER_BYTES)
        return 0;
    const size_t room = (size_t)(plain - 2 * TVPAL_CHUNK_HEADER_BYTES);
    size_t f = ZSTD_compressCCtx(z->cctx, dst + TVPAL_CHUNK_HEADER_BYTES,
                                 room, z->scratch, tb + wh, level);
    if (ZSTD_isError(f))   /* dstSize_tooSmall: coding does not pay */
        return ZSTD_getErrorCode(f) == ZSTD_error_dstSize_tooSmall
                   ? 0 : TVPAL_E_NOMEM;
    h.flags |= TVPAL_CHUNK_ZSTD;
    h.coded_bytes = (uint32_t)f;
    tvpal_chunk_header_encode(&h, dst);
    *stored = tvpal_chunk_stored_bytes(&h, ctf);
    memset(dst + TVPAL_CHUNK_HEADER_BYTES + f, 0,
           (size_t)(*stored - TVPAL_CHUNK_HEADER_BYTES - f));
    return *stored < plain ? 1 : 0;
}

/* ------------------------------------------------------------- inflate */

/* Inflates the coded chunk (header h, frame at src) into its plain form at
 * dst (header included, plain bytes): straight into dst when that does
 * not reach src + its frame, else through the scratch. */
static int inflate_chunk(struct tvpal_chunkz *z, struct tvpal_chunk_header h,
                         uint32_t ctf, const unsigned char *src,
                         unsigned char *dst, uint32_t step,
                         struct tvpal_diag *diag)
{
    const unsigned E = tvpal_table_entry_bytes(ctf);
    const uint32_t n = h.wlen * 256u;
    const size_t tb = (size_t)n * E, wh = (size_t)h.w * h.h;
    const uint64_t plain = tvpal_chunk_bytes(h.wlen, h.w, h.h, ctf);
    const unsigned char *frame = src + TVPAL_CHUNK_HEADER_BYTES;
    if (plain > z->max_chunk)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "record %u: slice %u: "
                              "a chunk of %llu bytes, more than the shard's "
                              "largest", step, h.slice,
                              (unsigned long long)plain);
    const int direct = dst + plain <= src;
    unsigned char *out = direct ? dst + TVPAL_CHUNK_HEADER_BYTES : z->scratch;
    size_t got = ZSTD_decompressDCtx(z->dctx, out, tb + wh, frame,
                                     h.coded_bytes);
    if (ZSTD_isError(got) || got != tb + wh)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "record %u: slice %u: "
                              "coded chunk: %s (its frame must decode to "
                              "%zu bytes of table and indices)", step,
                              h.slice, ZSTD_isError(got)
                                  ? ZSTD_getErrorName(got)
                                  : "wrong size", tb + wh);
    unsigned char *table = dst + TVPAL_CHUNK_HEADER_BYTES;
    if (direct) {
        /* The planes sit where the entries go: move them aside first. */
        memcpy(z->table, out, tb);
        table_inverse(z->table, n, E, table);
        index_inverse(out + tb, wh, table + tb);
    } else {
        table_inverse(out, n, E, table);
        index_inverse(out + tb, wh, table + tb);
    }
    memset(table + tb + wh, 0,
           (size_t)(plain - TVPAL_CHUNK_HEADER_BYTES - tb - wh));
    h.flags &= ~TVPAL_CHUNK_ZSTD;
    h.coded_bytes = 0;
    tvpal_chunk_header_encode(&h, dst);
    return 0;
}

int tvpal_record_inflate(struct tvpal_chunkz *z, unsigned char *buf,
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
    if (!z->dctx && !(z->dctx = ZSTD_createDCtx()))
        return TVPAL_E_NOMEM;
    /* Front to back: dst never passes src (every chunk is no larger
     * stored than plain), and a chunk's plain form ends before the stored
     * chunks after it start. */
    const unsigned char *src = rec + TVPAL_RECORD_HEADER_BYTES;
    unsigned char *dst = buf + TVPAL_RECORD_HEADER_BYTES;
    uint32_t crc = 0;
    for (uint32_t k = 0; k < rh.chunk_count; k++) {
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
    (void)at;
    return 0;
}
