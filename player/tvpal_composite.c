/* tvpal_composite.c: binary swap and gather-to-root compositing (see
 * tvpal_composite.h).  No MPI here: messages go through tvpal_comm. */
#include "tvpal_composite.h"
#include "tvpal_cli.h"

#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

struct tvpal_compositor {
    unsigned width, height;
    float *acc;                   /* gather-to-root accumulation (rank 0) */
    int size;
    unsigned char *sbuf, *rbuf;   /* encoded messages */
    size_t cap;
    size_t *counts, *displs;      /* gather bookkeeping (rank 0) */
    uint32_t *rows;               /* [2 * size]: final row range per rank */
};

/* Encoding: u32 span count, then per span u32 start (pixel offset from the
 * first pixel of row y0) and u32 length, then the spans' pixels in order,
 * each 4 x 16-bit unsigned normalized values (premultiplied RGBA in
 * [0, 1], v = round(x * 65535)): half the bytes of float, and a step of
 * 1.5e-5, far below the 8-bit output's 1/255.  A pixel is transparent
 * (skipped) when all four values are 0. */
size_t tvpal_rle_bound(unsigned width, unsigned rows)
{
    size_t n = (size_t)width * rows;
    /* worst case: alternating pixels, one span per 2 pixels */
    return 4 + (n / 2 + 1) * 8 + n * 8;
}

static inline uint16_t to16(float v)
{
    v = v < 0.0f ? 0.0f : v > 1.0f ? 1.0f : v;
    return (uint16_t)(v * 65535.0f + 0.5f);
}

/* Clamp to [0, 1], scale, round: n floats to 16 or 8 bits.  SSE2 (every
 * x86-64) does 8 or 16 values per step; the scalar tail and other CPUs
 * give the same results (round half up of a value in [0, scale]). */
static void conv16(const float *p, uint16_t *d, size_t n)
{
    size_t i = 0;
#ifdef __SSE2__
    const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f),
                 sc = _mm_set1_ps(65535.0f), half = _mm_set1_ps(0.5f);
    const __m128i bias = _mm_set1_epi32(32768), flip = _mm_set1_epi16((short)0x8000);
    for (; i + 8 <= n; i += 8) {
        __m128 a = _mm_loadu_ps(p + i), b = _mm_loadu_ps(p + i + 4);
        a = _mm_min_ps(_mm_max_ps(a, zero), one);
        b = _mm_min_ps(_mm_max_ps(b, zero), one);
        __m128i ia = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(a, sc), half));
        __m128i ib = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(b, sc), half));
        /* unsigned 16-bit pack with SSE2: shift to signed, pack, shift back */
        __m128i pk = _mm_packs_epi32(_mm_sub_epi32(ia, bias),
                                     _mm_sub_epi32(ib, bias));
        _mm_storeu_si128((__m128i *)(void *)(d + i), _mm_xor_si128(pk, flip));
    }
#endif
    for (; i < n; i++)
        d[i] = to16(p[i]);
}

static void conv8(const float *p, uint8_t *d, size_t n)
{
    size_t i = 0;
#ifdef __SSE2__
    const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f),
                 sc = _mm_set1_ps(255.0f), half = _mm_set1_ps(0.5f);
    for (; i + 16 <= n; i += 16) {
        __m128i q[4];
        for (int k = 0; k < 4; k++) {
            __m128 a = _mm_min_ps(_mm_max_ps(_mm_loadu_ps(p + i + 4 * k), zero), one);
            q[k] = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(a, sc), half));
        }
        __m128i lo = _mm_packs_epi32(q[0], q[1]), hi = _mm_packs_epi32(q[2], q[3]);
        _mm_storeu_si128((__m128i *)(void *)(d + i), _mm_packus_epi16(lo, hi));
    }
#endif
    for (; i < n; i++) {
        float v = p[i];
        v = v < 0.0f ? 0.0f : v > 1.0f ? 1.0f : v;
        d[i] = (uint8_t)(v * 255.0f + 0.5f);
    }
}

/* Premultiplied pixels: alpha 0 means nothing to add (colour is 0 too), so
 * spans are found on alpha alone. */
size_t tvpal_rle_encode(const float *img, unsigned width, unsigned y0,
                        unsigned y1, unsigned char *buf)
{
    const size_t n = (size_t)width * (y1 - y0);
    const float *base = img + (size_t)4 * width * y0;
    uint32_t nspans = 0;
    unsigned char *hdr = buf + 4;
    for (size_t i = 0; i < n;) {
        while (i < n && base[4 * i + 3] == 0.0f)
            i++;
        if (i >= n)
            break;
        size_t s = i;
        while (i < n && base[4 * i + 3] != 0.0f)
            i++;
        uint32_t se[2] = {(uint32_t)s, (uint32_t)(i - s)};
        memcpy(hdr + 8 * (size_t)nspans, se, 8);
        nspans++;
    }
    memcpy(buf, &nspans, 4);
    uint16_t *data = (uint16_t *)(void *)(hdr + 8 * (size_t)nspans);
    for (uint32_t k = 0; k < nspans; k++) {
        uint32_t se[2];
        memcpy(se, hdr + 8 * (size_t)k, 8);
        const float *p = base + 4 * (size_t)se[0];
        const size_t m = 4 * (size_t)se[1];
        conv16(p, data, m);
        data += m;
    }
    return (size_t)((unsigned char *)data - buf);
}

uint64_t tvpal_rle_blend(float *img, unsigned width, unsigned y0, unsigned y1,
                         const unsigned char *buf, size_t bytes, int front)
{
    uint32_t nspans;
    uint64_t blended = 0;
    const size_t n = (size_t)width * (y1 - y0);
    float *base = img + (size_t)4 * width * y0;
    const float k16 = 1.0f / 65535.0f;
    if (bytes < 4)
        return 0;
    memcpy(&nspans, buf, 4);
    const unsigned char *hdr = buf + 4;
    const uint16_t *src = (const uint16_t *)(const void *)(hdr + 8 * (size_t)nspans);
    for (uint32_t k = 0; k < nspans; k++) {
        uint32_t se[2];
        memcpy(se, hdr + 8 * (size_t)k, 8);
        if (se[0] + (size_t)se[1] > n)
            break; /* malformed: stop rather than write out of bounds */
        float *d = base + 4 * (size_t)se[0];
        for (uint32_t i = 0; i < se[1]; i++, d += 4, src += 4) {
            float s0 = src[0] * k16, s1 = src[1] * k16, s2 = src[2] * k16,
                  s3 = src[3] * k16;
            if (front) { /* received over own */
                float keep = 1.0f - s3;
                d[0] = s0 + keep * d[0];
                d[1] = s1 + keep * d[1];
                d[2] = s2 + keep * d[2];
                d[3] = s3 + keep * d[3];
            } else { /* own over received */
                float keep = 1.0f - d[3];
                d[0] += keep * s0;
                d[1] += keep * s1;
                d[2] += keep * s2;
                d[3] += keep * s3;
            }
        }
        blended += se[1];
    }
    return blended;
}

int tvpal_compositor_create(struct tvpal_compositor **out, unsigned width,
                            unsigned height, int size)
{
    struct tvpal_compositor *cx = calloc(1, sizeof *cx);
    if (!cx)
        return TVPAL_E_NOMEM;
    cx->width = width;
    cx->height = height;
    cx->size = size;
    cx->cap = tvpal_rle_bound(width, height);
    cx->sbuf = malloc(cx->cap);
    cx->rbuf = malloc(cx->cap);
    cx->counts = calloc((size_t)size, sizeof *cx->counts);
    cx->displs = calloc((size_t)size, sizeof *cx->displs);
    cx->rows = calloc((size_t)size * 2, sizeof *cx->rows);
    cx->acc = malloc(sizeof(float) * 4 * width * height);
    if (!cx->acc || !cx->sbuf || !cx->rbuf || !cx->counts || !cx->displs || !cx->rows) {
        tvpal_compositor_free(cx);
        return TVPAL_E_NOMEM;
    }
    *out = cx;
    return 0;
}

void tvpal_compositor_free(struct tvpal_compositor *cx)
{
    if (!cx)
        return;
    free(cx->sbuf);
    free(cx->rbuf);
    free(cx->counts);
    free(cx->displs);
    free(cx->rows);
    free(cx->acc);
    free(cx);
}

/* Rank of depth position v (0 = front) and back. */
static inline int rank_of(int v, int K, int reverse)
{
    return reverse ? K - 1 - v : v;
}

static int bswap(struct tvpal_compositor *cx, struct tvpal_comm *c,
                 int reverse, float *img, unsigned *y0out, unsigned *y1out,
                 int *active, struct tvpal_compose_stats *st)
{
    const int K = c->size;
    const int v = reverse ? K - 1 - c->rank : c->rank;
    int P = 1;
    while (P * 2 <= K)
        P *= 2;
    const int E = K - P;
    const unsigned W = cx->width;
    unsigned y0 = 0, y1 = cx->height;
    int rc;
    double t;
    /* Fold: depth positions 2j and 2j+1 (j < E) pair; 2j+1 sends all. */
    int vp; /* position among the P participants, or -1 */
    if (v < 2 * E) {
        if (v & 1) {
            t = tvpal_now();
            size_t n = tvpal_rle_encode(img, W, 0, cx->height, cx->sbuf);
            st->encode_ms += (tvpal_now() - t) * 1e3;
            t = tvpal_now();
            rc = c->send(c, rank_of(v - 1, K, reverse), cx->sbuf, n);
            st->exchange_ms += (tvpal_now() - t) * 1e3;
            st->bytes_sent += n;
            *active = 0;
            return rc;
        }
        size_t got;
        t = tvpal_now();
        rc = c->recv(c, rank_of(v + 1, K, reverse), cx->rbuf, cx->cap, &got);
        st->exchange_ms += (tvpal_now() - t) * 1e3;
        if (rc < 0)
            return rc;
        t = tvpal_now();
        st->pixels_blended += tvpal_rle_blend(img, W, 0, cx->height, cx->rbuf,
                                              got, 0);
        st->blend_ms += (tvpal_now() - t) * 1e3;
        vp = v / 2;
    } else {
        vp = v - E;
    }
    /* Participant vp <-> depth position of its partner. */
    for (int bit = 1; bit < P; bit <<= 1) {
        int pp = vp ^ bit;
        int pv = pp < E ? 2 * pp : pp + E;
        int peer = rank_of(pv, K, reverse);
        unsigned mid = y0 + (y1 - y0) / 2;
        /* The lower position keeps the first half of the rows. */
        int keep_low = !(vp & bit);
        unsigned ky0 = keep_low ? y0 : mid, ky1 = keep_low ? mid : y1;
        unsigned sy0 = keep_low ? mid : y0, sy1 = keep_low ? y1 : mid;
        t = tvpal_now();
        size_t n = tvpal_rle_encode(img, W, sy0, sy1, cx->sbuf);
        st->encode_ms += (tvpal_now() - t) * 1e3;
        size_t got;
        t = tvpal_now();
        rc = c->sendrecv(c, peer, cx->sbuf, n, cx->rbuf, cx->cap, &got);
        st->exchange_ms += (tvpal_now() - t) * 1e3;
        if (rc < 0)
            return rc;
        st->bytes_sent += n;
        t = tvpal_now();
        /* Partner's block is in front when its position is lower. */
        st->pixels_blended += tvpal_rle_blend(img, W, ky0, ky1, cx->rbuf,
                                              got, pp < vp);
        st->blend_ms += (tvpal_now() - t) * 1e3;
        y0 = ky0;
        y1 = ky1;
    }
    *y0out = y0;
    *y1out = y1;
    *active = 1;
    return 0;
}

/* Premultiplied float -> 8-bit, rounded as the PNG writer rounds. */
static void to8(const float *src, size_t n, uint8_t *dst)
{
    conv8(src, dst, n);
}

static int gather_root(struct tvpal_compositor *cx, struct tvpal_comm *c,
                       int reverse, float *img, uint8_t *out8,
                       struct tvpal_compose_stats *st)
{
    const int K = c->size;
    const unsigned W = cx->width, H = cx->height;
    double t;
    int rc = 0;
    if (c->rank != 0) {
        t = tvpal_now();
        size_t n = tvpal_rle_encode(img, W, 0, H, cx->sbuf);
        st->encode_ms += (tvpal_now() - t) * 1e3;
        t = tvpal_now();
        rc = c->send(c, 0, cx->sbuf, n);
        st->exchange_ms += (tvpal_now() - t) * 1e3;
        st->bytes_sent += n;
        return rc;
    }
    /* Rank 0: accumulate front to back ("under"): out = out + (1 - a) img. */
    float *out = cx->acc;
    memset(out, 0, sizeof(float) * 4 * W * H);
    for (int v = 0; v < K; v++) {
        int r = rank_of(v, K, reverse);
        size_t got;
        const unsigned char *buf;
        if (r == 0) {
            t = tvpal_now();
            got = tvpal_rle_encode(img, W, 0, H, cx->rbuf);
            st->encode_ms += (tvpal_now() - t) * 1e3;
        } else {
            t = tvpal_now();
            rc = c->recv(c, r, cx->rbuf, cx->cap, &got);
            st->exchange_ms += (tvpal_now() - t) * 1e3;
            if (rc < 0)
                return rc;
        }
        buf = cx->rbuf;
        t = tvpal_now();
        /* Received piece lies behind what is accumulated so far. */
        st->pixels_blended += tvpal_rle_blend(out, W, 0, H, buf, got, 0);
        st->blend_ms += (tvpal_now() - t) * 1e3;
    }
    to8(out, (size_t)4 * W * H, out8);
    return 0;
}

int tvpal_composite(struct tvpal_compositor *cx, struct tvpal_comm *c,
                    enum tvpal_compose_kind kind, int reverse, float *img,
                    uint8_t *out8, struct tvpal_compose_stats *st)
{
    const unsigned W = cx->width, H = cx->height;
    memset(st, 0, sizeof *st);
    if (c->size == 1) {
        to8(img, (size_t)4 * W * H, out8);
        return 0;
    }
    if (kind == TVPAL_COMPOSE_GATHER)
        return gather_root(cx, c, reverse, img, out8, st);
    unsigned y0 = 0, y1 = 0;
    int active = 0;
    int rc = bswap(cx, c, reverse, img, &y0, &y1, &active, st);
    if (rc < 0)
        return rc;
    /* Gather the pieces: first every rank's row range, then the rows. */
    double t = tvpal_now();
    uint32_t mine[2] = {active ? y0 : 0, active ? y1 : 0};
    rc = c->gather(c, mine, sizeof mine, cx->rows);
    if (rc < 0)
        return rc;
    /* Compositing is over: the pieces travel as 8-bit premultiplied RGBA
     * (a quarter of the floats), rounded exactly as the PNG writer rounds,
     * straight into rank 0's output. */
    if (c->rank == 0)
        for (int r = 0; r < c->size; r++) {
            cx->counts[r] = (size_t)(cx->rows[2 * r + 1] - cx->rows[2 * r]) *
                            W * 4;
            cx->displs[r] = (size_t)cx->rows[2 * r] * W * 4;
        }
    size_t npx = (size_t)(mine[1] - mine[0]) * W;
    to8(img + (size_t)4 * W * mine[0], 4 * npx, cx->sbuf);
    rc = c->gatherv(c, cx->sbuf, 4 * npx, out8, cx->counts, cx->displs);
    st->gather_ms = (tvpal_now() - t) * 1e3;
    if (c->rank != 0)
        st->gather_bytes = 4 * npx;
    return rc;
}
