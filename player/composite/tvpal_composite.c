/* tvpal_composite.c: binary swap and gather-to-root compositing (see
 * tvpal_composite.h).  No MPI here: messages go through tvpal_comm. */
#include "tvpal_composite.h"
#include "tvpal_clock.h"
#include "tvpal_rle.h"

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

/* Clamp to [0, 1], scale by 255, round half up: what the PNG writer does.
 * SSE2 (every x86-64) does 16 values per step; the scalar tail and other
 * CPUs give the same results. */
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
        rc = tvpal_rle_blend(img, W, 0, cx->height, cx->rbuf, got, 0,
                             &st->pixels_blended);
        st->blend_ms += (tvpal_now() - t) * 1e3;
        if (rc < 0)
            return rc;
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
        rc = tvpal_rle_blend(img, W, ky0, ky1, cx->rbuf, got, pp < vp,
                             &st->pixels_blended);
        st->blend_ms += (tvpal_now() - t) * 1e3;
        if (rc < 0)
            return rc;
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
        rc = tvpal_rle_blend(out, W, 0, H, buf, got, 0, &st->pixels_blended);
        st->blend_ms += (tvpal_now() - t) * 1e3;
        if (rc < 0)
            return rc;
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
