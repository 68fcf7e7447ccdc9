/* tvpal_quant.c: Lloyd-Max and uniform scalar quantizers (see tvpal_quant.h). */
#include "tvpal_quant.h"
#include "tvpal_error.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

/* Iteration limits: Lloyd converges linearly; past ~60 iterations the gain is
 * far below what the float decoder table can represent. */
#define LLOYD_MAX_ITER 200
/* Both starts run this many iterations; only the better one continues.
 * Lloyd stops once an iteration lowers the distortion by less than
 * LLOYD_REL_TOL of it (4e-6 dB).  Against 24 and 1e-8 these cut the
 * encoder's instructions by 8% on the viscous-fingers series (64^3 x 99,
 * N = 4), for a PSNR 0.004 dB higher there and 0.0015 dB lower on 256^3
 * turbulence: an earlier race picks the other start now and then, either
 * way. */
#define LLOYD_RACE_ITER 8
#define LLOYD_REL_TOL 1e-6

/* From this many samples on, the radix sort takes 2 passes of 16-bit
 * digits instead of 3 of 11 bits: its 2 x 65536 counters cost more than
 * the pass they save below it (256^3 turbulence's DCT coefficients, this
 * 2-core EPYC: 9.4 against 12.4 ns a key at 65536 keys, 5.9 against 10.4
 * at 262144; 13.5 against 12.5 at 16384). */
#define RADIX16_MIN 32768

/* Up to this many samples it takes 4 passes of 8-bit digits: the 11-bit
 * sort clears and scans 4608 counters whatever n, more than its passes
 * cost on the small slices of a coarse level (32^2, 16^2) or a small
 * volume; 4 x 256 counters cost little, and a pass whose digit is the
 * same for every key is skipped as in the others.  (Callgrind, viscous
 * fingers 64^3 x 30 with --levels 2, whose slices are 64^2, 32^2, 16^2:
 * 1868M instructions before, 1854M after; at 4096 it costs more: 1435M
 * against 1415M without levels.) */
#define RADIX8_MAX 2048

struct tvpal_quantws {
    size_t capacity;
    size_t n;
    uint32_t *keys, *tmp;   /* radix sort buffers */
    uint32_t *hist16;       /* 2 x 65536 counters, when capacity reaches
                             * RADIX16_MIN (and n fits 32 bits) */
    float *s;               /* sorted samples */
    double *p1, *p2;        /* prefix sums of (s - mean) and its square, n+1 */
    double mean;            /* centre of p1/p2: the median (robust to outliers) */
    size_t distinct;
};

int tvpal_quantws_create(struct tvpal_quantws **out, size_t capacity)
{
    struct tvpal_quantws *ws = calloc(1, sizeof *ws);
    if (!ws)
        return TVPAL_E_NOMEM;
    size_t cap = capacity ? capacity : 1;
    ws->capacity = capacity;
    ws->keys = malloc(cap * sizeof *ws->keys);
    ws->tmp = malloc(cap * sizeof *ws->tmp);
    ws->s = malloc(cap * sizeof *ws->s);
    ws->p1 = malloc((cap + 1) * sizeof *ws->p1);
    ws->p2 = malloc((cap + 1) * sizeof *ws->p2);
    const int sort16 = cap >= RADIX16_MIN && cap <= UINT32_MAX;
    if (sort16)
        ws->hist16 = malloc(2 * 65536 * sizeof *ws->hist16);
    if (!ws->keys || !ws->tmp || !ws->s || !ws->p1 || !ws->p2 ||
        (sort16 && !ws->hist16)) {
        tvpal_quantws_free(ws);
        return TVPAL_E_NOMEM;
    }
    *out = ws;
    return 0;
}

void tvpal_quantws_free(struct tvpal_quantws *ws)
{
    if (!ws)
        return;
    free(ws->keys);
    free(ws->tmp);
    free(ws->hist16);
    free(ws->s);
    free(ws->p1);
    free(ws->p2);
    free(ws);
}

/* Order-preserving map float -> uint32 (finite values). */
static inline uint32_t float_key(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

static inline float key_float(uint32_t k)
{
    uint32_t u = (k & 0x80000000u) ? (k & 0x7FFFFFFFu) : ~k;
    float f;
    memcpy(&f, &u, 4);
    return f;
}

/* Exclusive prefix sums of h[0..bins) in place (bins a multiple of 4):
 * h[b] becomes the sum of the counts before it.  Four counts a step with
 * SSE2 (the same sums: integers), where the loop of one count a step was
 * an eighth of a 256^2 slice's sort at 16-bit digits. */
static void exclusive_scan(uint32_t *h, int bins)
{
    int b = 0;
    uint32_t sum = 0;
#if defined(__SSE2__)
    __m128i run = _mm_setzero_si128(); /* the sum so far, in every lane */
    for (; b + 4 <= bins; b += 4) {
        __m128i c = _mm_loadu_si128((const __m128i *)(h + b));
        __m128i x = _mm_add_epi32(c, _mm_slli_si128(c, 4));
        x = _mm_add_epi32(x, _mm_slli_si128(x, 8)); /* inclusive sums */
        /* exclusive: the inclusive sums shifted up a lane, plus the run */
        _mm_storeu_si128((__m128i *)(h + b),
                         _mm_add_epi32(run, _mm_slli_si128(x, 4)));
        run = _mm_add_epi32(run, _mm_shuffle_epi32(x, 0xFF));
    }
    sum = (uint32_t)_mm_cvtsi128_si32(run);
#endif
    for (; b < bins; b++) {
        uint32_t c = h[b];
        h[b] = sum;
        sum += c;
    }
}

/* One LSD pass over the digit (k >> shift) & mask, counts h (COUNT_T *)
 * with prefix sums SCAN over bins: scatters src into dst and swaps them,
 * or does nothing when every key has the same digit (h holds n there). */
#define RADIX_PASS(h, SCAN, bins, shift, mask, src, dst, n)                  \
    do {                                                                     \
        if (h[(src[0] >> (shift)) & (mask)] == (n))                          \
            break;                                                           \
        SCAN(h, bins);                                                       \
        for (size_t i_ = 0; i_ < (n); i_++) {                                \
            uint32_t k_ = src[i_];                                           \
            dst[h[(k_ >> (shift)) & (mask)]++] = k_;                         \
        }                                                                    \
        uint32_t *t_ = src;                                                  \
        src = dst;                                                           \
        dst = t_;                                                            \
    } while (0)

/* LSD radix sort, 3 passes of 11, 11 and 10 bits; a pass whose digit is
 * the same for all keys is skipped (common: coefficient values often share
 * exponent bits).  Returns the buffer that holds the sorted keys (keys or
 * tmp: no copy back).  One body for two counter types (COUNT_T, with its
 * prefix sums SCAN): 32-bit counters, a smaller histogram that sorts 5-10%
 * faster, whenever n fits them, and size_t otherwise. */
#define RADIX_SORT_BODY(COUNT_T, SCAN)                                       \
    {                                                                        \
        COUNT_T hist[3][2048];                                               \
        memset(hist, 0, sizeof hist[0] * 2 + sizeof hist[2] / 2);            \
        for (size_t i = 0; i < n; i++) {                                     \
            uint32_t k = keys[i];                                            \
            hist[0][k & 0x7FF]++;                                            \
            hist[1][(k >> 11) & 0x7FF]++;                                    \
            hist[2][k >> 22]++;                                              \
        }                                                                    \
        uint32_t *src = keys, *dst = tmp;                                    \
        for (int pass = 0; pass < 3; pass++) {                               \
            COUNT_T *h = hist[pass];                                         \
            RADIX_PASS(h, SCAN, pass < 2 ? 2048 : 1024, 11u * (unsigned)pass, \
                       0x7FFu, src, dst, n);                                 \
        }                                                                    \
        return src;                                                          \
    }

/* Exclusive prefix sums of size_t counts (radix_sort_size). */
static void exclusive_scan_size(size_t *h, int bins)
{
    size_t sum = 0;
    for (int b = 0; b < bins; b++) {
        size_t c = h[b];
        h[b] = sum;
        sum += c;
    }
}

static const uint32_t *radix_sort_u32(uint32_t *keys, uint32_t *tmp,
                                      size_t n)
RADIX_SORT_BODY(uint32_t, exclusive_scan)

static const uint32_t *radix_sort_size(uint32_t *keys, uint32_t *tmp,
                                       size_t n)
RADIX_SORT_BODY(size_t, exclusive_scan_size)

/* LSD radix sort in 2 passes of 16-bit digits with the 2 x 65536
 * counters hist (n <= UINT32_MAX); otherwise as above. */
static const uint32_t *radix_sort16(uint32_t *keys, uint32_t *tmp, size_t n,
                                    uint32_t *hist)
{
    memset(hist, 0, 2 * 65536 * sizeof *hist);
    for (size_t i = 0; i < n; i++) {
        uint32_t k = keys[i];
        hist[k & 0xFFFF]++;
        hist[65536 + (k >> 16)]++;
    }
    uint32_t *src = keys, *dst = tmp;
    for (int pass = 0; pass < 2; pass++) {
        uint32_t *h = hist + 65536 * pass;
        RADIX_PASS(h, exclusive_scan, 65536, 16u * (unsigned)pass, 0xFFFFu,
                   src, dst, n);
    }
    return src;
}

/* LSD radix sort in 4 passes of 8-bit digits (n <= RADIX8_MAX). */
static const uint32_t *radix_sort8(uint32_t *keys, uint32_t *tmp, size_t n)
{
    uint32_t hist[4][256];
    memset(hist, 0, sizeof hist);
    for (size_t i = 0; i < n; i++) {
        uint32_t k = keys[i];
        hist[0][k & 0xFF]++;
        hist[1][(k >> 8) & 0xFF]++;
        hist[2][(k >> 16) & 0xFF]++;
        hist[3][k >> 24]++;
    }
    uint32_t *src = keys, *dst = tmp;
    for (int pass = 0; pass < 4; pass++) {
        uint32_t *h = hist[pass];
        RADIX_PASS(h, exclusive_scan, 256, 8u * (unsigned)pass, 0xFFu, src,
                   dst, n);
    }
    return src;
}

static const uint32_t *radix_sort(struct tvpal_quantws *ws, size_t n)
{
    if (n <= RADIX8_MAX)
        return radix_sort8(ws->keys, ws->tmp, n);
    if (n >= RADIX16_MIN && ws->hist16)
        return radix_sort16(ws->keys, ws->tmp, n, ws->hist16);
    if (n <= UINT32_MAX)
        return radix_sort_u32(ws->keys, ws->tmp, n);
    return radix_sort_size(ws->keys, ws->tmp, n);
}

int tvpal_quantws_load(struct tvpal_quantws *ws, const float *x, size_t n)
{
    if (n > ws->capacity)
        return TVPAL_E_INVAL;
    ws->n = n;
    ws->distinct = 0;
    ws->mean = 0.0;
    if (n == 0)
        return 0;
    for (size_t i = 0; i < n; i++)
        ws->keys[i] = float_key(x[i]);
    const uint32_t *keys = radix_sort(ws, n);
    /* Centre on the median: prefix sums of squares around it stay small in
     * the bulk of the data even when far outliers shift the mean. */
    double mean = key_float(keys[n / 2]);
    ws->mean = mean;
    double a1 = 0.0, a2 = 0.0;
    size_t distinct = 0;
    uint32_t prev = ~keys[0];
    ws->p1[0] = 0.0;
    ws->p2[0] = 0.0;
    for (size_t i = 0; i < n; i++) {
        uint32_t k = keys[i];
        distinct += (k != prev);
        prev = k;
        float f = key_float(k);
        ws->s[i] = f;
        double c = (double)f - mean;
        a1 += c;
        a2 += c * c;
        ws->p1[i + 1] = a1;
        ws->p2[i + 1] = a2;
    }
    ws->distinct = distinct;
    return 0;
}

size_t tvpal_quantws_distinct(const struct tvpal_quantws *ws)
{
    return ws->distinct;
}

/* First index i in [lo, n) with s[i] >= t (n if none).  Branch-free
 * halving (the answer stays in [b, b + len]): the comparisons of a search
 * are unpredictable, and a mispredicted branch costs more than the select. */
static size_t lower_bound(const float *s, size_t lo, size_t n, double t)
{
    size_t len = n - lo;
    const float *b = s + lo;
    if (len == 0)
        return lo;
    while (len > 1) {
        size_t half = len >> 1;
        b = (double)b[half] < t ? b + half : b;
        len -= half;
    }
    return (size_t)(b - s) + ((double)b[0] < t);
}

/* Sample count as double.  Through int64_t, which converts in one
 * instruction where size_t does not; exact for any count below 2^53. */
static inline double count_d(size_t c)
{
    return (double)(int64_t)c;
}

/* Sum of squared deviations from level yc (centred coordinate) of a cell of
 * cnt samples whose centred sum and sum of squares are s1 and s2. */
static inline double sse_of(double cnt, double s1, double s2, double yc)
{
    double d = s2 - 2.0 * yc * s1 + cnt * yc * yc;
    return d > 0.0 ? d : 0.0;
}

/* The same for the samples s[a..b), from the prefix sums. */
static inline double cell_sse(const struct tvpal_quantws *ws, size_t a,
                              size_t b, double yc)
{
    return sse_of(count_d(b - a), ws->p1[b] - ws->p1[a],
                  ws->p2[b] - ws->p2[a], yc);
}

/* First index i in [lo, n) with s[i] >= t, searched outward from hint (the
 * answer of the previous Lloyd iteration, usually within a few places). */
static size_t gallop(const float *s, size_t lo, size_t n, double t,
                     size_t hint)
{
    if (hint < lo)
        hint = lo;
    if (hint >= n)
        hint = n;
    if (hint < n && (double)s[hint] < t) {
        /* answer in (hint, n]: gallop right */
        size_t step = 1, a = hint + 1;
        while (a + step < n && (double)s[a + step - 1] < t) {
            a += step;
            step <<= 1;
        }
        size_t b = a + step < n ? a + step : n;
        return lower_bound(s, a, b, t);
    }
    /* answer in [lo, hint]: gallop left */
    size_t step = 1, b = hint;
    while (b > lo + step && (double)s[b - step] >= t) {
        b -= step;
        step <<= 1;
    }
    size_t a = b > lo + step ? b - step : lo;
    return lower_bound(s, a, b, t);
}

/* Linear steps tried from the hint before galloping: late in a Lloyd run
 * most boundaries move by zero or one sample. */
#define NEAR_STEPS 4

/* The answer of gallop() (and lower_bound()), found by walking a few steps
 * from the hint first.  Samples and t are finite, so !(x < t) is x >= t. */
static inline size_t search_near(const float *s, size_t lo, size_t n,
                                 double t, size_t hint)
{
    size_t h = hint < lo ? lo : hint > n ? n : hint;
    if (h < n && (double)s[h] < t) {
        /* invariant: s[h] < t */
        for (int k = 0; k < NEAR_STEPS; k++) {
            h++;
            if (h == n || !((double)s[h] < t))
                return h;
        }
        return gallop(s, lo, n, t, h);
    }
    /* invariant: h == n or s[h] >= t */
    for (int k = 0; k < NEAR_STEPS; k++) {
        if (h == lo || !((double)s[h - 1] >= t))
            return h;
        h--;
    }
    return gallop(s, lo, n, t, h);
}

/* Nearest-neighbour partition of the sorted samples for levels y (centred,
 * sorted): bnd[0] = 0, bnd[L] = n, cell i = [bnd[i], bnd[i+1]).  With
 * use_hint, bnd holds the previous partition on entry; without, each
 * boundary is searched from the one before (cells are short when there are
 * many levels, where the search matters).  Either way each boundary is the
 * lower bound of its threshold in s[bnd[i-1] ..), as a plain binary search
 * would find it.  Returns the total
 * squared error (summed over cells in order) and the number of empty cells
 * in *nempty.  The prefix sums at each boundary are read once and carried
 * to the next cell. */
static double partition(const struct tvpal_quantws *ws, const double *y,
                        unsigned L, size_t *bnd, int use_hint,
                        unsigned *nempty)
{
    const double mean = ws->mean;
    const float *s = ws->s;
    const double *p1 = ws->p1, *p2 = ws->p2;
    const size_t n = ws->n;
    size_t a = 0;
    double a1 = p1[0], a2 = p2[0];
    double d = 0.0;
    unsigned ne = 0;
    bnd[0] = 0;
    for (unsigned i = 1; i < L; i++) {
        double t = 0.5 * (y[i - 1] + y[i]) + mean;
        size_t b = search_near(s, a, n, t, use_hint ? bnd[i] : a);
        double b1 = p1[b], b2 = p2[b];
        bnd[i] = b;
        d += sse_of(count_d(b - a), b1 - a1, b2 - a2, y[i - 1]);
        ne += b == a;
        a = b;
        a1 = b1;
        a2 = b2;
    }
    bnd[L] = n;
    d += sse_of(count_d(n - a), p1[n] - a1, p2[n] - a2, y[L - 1]);
    ne += n == a;
    *nempty = ne;
    return d;
}

/* Insertion sort: the levels are nearly sorted after every Lloyd step, so
 * this is linear in practice (and much cheaper than qsort's callbacks). */
static void sort_levels(double *y, unsigned L)
{
    for (unsigned i = 1; i < L; i++) {
        double v = y[i];
        unsigned j = i;
        while (j > 0 && y[j - 1] > v) {
            y[j] = y[j - 1];
            j--;
        }
        y[j] = v;
    }
}

/* Squared errors of the samples of two cells from their levels, each
 * summed in sample order from 0.0 (as a loop over one cell would), the
 * two dependency chains interleaved. */
static void cells_sse2(const float *s, size_t a0, size_t b0, double lv0,
                       size_t a1, size_t b1, double lv1, double *c0,
                       double *c1)
{
    const size_t n0 = b0 - a0, n1 = b1 - a1, m = n0 < n1 ? n0 : n1;
    double x0 = 0.0, x1 = 0.0;
    for (size_t k = 0; k < m; k++) {
        double e0 = (double)s[a0 + k] - lv0;
        double e1 = (double)s[a1 + k] - lv1;
        x0 += e0 * e0;
        x1 += e1 * e1;
    }
    for (size_t k = a0 + m; k < b0; k++) {
        double e = (double)s[k] - lv0;
        x0 += e * e;
    }
    for (size_t k = a1 + m; k < b1; k++) {
        double e = (double)s[k] - lv1;
        x1 += e * e;
    }
    *c0 = x0;
    *c1 = x1;
}

/* Exact total squared error of levels y (centred, sorted) under the
 * nearest-neighbour partition, summed cell by cell from the samples (no
 * prefix-sum cancellation), the cell totals added in cell order.  Cells i
 * and i + h are summed together for speed (independent chains).  Also
 * returns the partition in bnd, which holds a hint on entry if hinted. */
static double exact_sse(const struct tvpal_quantws *ws, const double *y,
                        unsigned L, size_t *bnd, int hinted)
{
    double c[TVPAL_LEVELS_MAX];
    unsigned nempty;
    partition(ws, y, L, bnd, hinted, &nempty);
    const unsigned h = (L + 1) / 2;
    for (unsigned i = 0; i + h < L; i++)
        cells_sse2(ws->s, bnd[i], bnd[i + 1], y[i] + ws->mean, bnd[i + h],
                   bnd[i + h + 1], y[i + h] + ws->mean, &c[i], &c[i + h]);
    if (L & 1) { /* cell h - 1 has no partner: pair it with an empty one */
        double unused;
        cells_sse2(ws->s, bnd[h - 1], bnd[h], y[h - 1] + ws->mean, 0, 0, 0.0,
                   &c[h - 1], &unused);
    }
    double d = 0.0;
    for (unsigned i = 0; i < L; i++)
        d += c[i];
    return d;
}

/* Final centroid step: each level becomes the mean of its cell (the
 * centroid condition), which cannot raise the distortion.  Cell sums come
 * from the median-centred prefix sums, exact to rounding in the bulk.
 * bnd (L + 1) holds a hint partition on entry and the partition of the
 * levels before the step on return. */
static void centroid_step(const struct tvpal_quantws *ws, double *y,
                          unsigned L, size_t *bnd)
{
    unsigned nempty;
    partition(ws, y, L, bnd, 1, &nempty);
    for (unsigned i = 0; i < L; i++) {
        size_t a = bnd[i], b = bnd[i + 1];
        if (b > a)
            y[i] = (ws->p1[b] - ws->p1[a]) / count_d(b - a);
    }
    sort_levels(y, L);
}

static void finish(const struct tvpal_quantws *ws, const double *yc,
                   unsigned L, double sse, const size_t *bnd,
                   struct tvpal_quant *q)
{
    q->nlevels = L;
    for (unsigned i = 0; i < L; i++) {
        q->level[i] = yc[i] + ws->mean;
        q->count[i] = bnd[i + 1] - bnd[i];
    }
    for (unsigned i = 0; i + 1 < L; i++)
        q->thresh[i] = 0.5 * (q->level[i] + q->level[i + 1]);
    q->mse = ws->n ? sse / (double)ws->n : 0.0;
}

/* Centroid condition with no empty cell: nxt[i] = mean of cell i of the
 * partition bnd (sorted).  With omega > 0 the over-relaxed step is taken
 * as well: the centroids go to cent and nxt[i] = cur[i] + omega * (cent[i]
 * - cur[i]) (sorted).  One pass when the centroids come out sorted, as
 * they nearly always do; otherwise they are sorted and the step redone. */
static void centroid_relax(const struct tvpal_quantws *ws,
                           const size_t *bnd, unsigned L, const double *cur,
                           double omega, double *cent, double *nxt)
{
    const double *p1 = ws->p1;
    double *c = omega > 0.0 ? cent : nxt;
    int c_sorted = 1, n_sorted = 1;
    double a1 = p1[0];
    for (unsigned i = 0; i < L; i++) {
        double b1 = p1[bnd[i + 1]];
        double v = (b1 - a1) / count_d(bnd[i + 1] - bnd[i]);
        a1 = b1;
        c[i] = v;
        c_sorted &= i == 0 || c[i - 1] <= v;
        if (omega > 0.0) {
            nxt[i] = cur[i] + omega * (v - cur[i]);
            n_sorted &= i == 0 || nxt[i - 1] <= nxt[i];
        }
    }
    if (c_sorted && n_sorted)
        return;
    sort_levels(c, L);
    if (omega > 0.0) {
        for (unsigned i = 0; i < L; i++)
            nxt[i] = cur[i] + omega * (cent[i] - cur[i]);
        sort_levels(nxt, L);
    }
}

/* Whether cell a goes before cell b as the next to split: the larger
 * distortion, of equal ones the lower index (the first maximum a scan
 * finds). */
static inline int split_before(const double *sse, unsigned a, unsigned b)
{
    return sse[a] > sse[b] || (sse[a] == sse[b] && a < b);
}

/* Restores the max-heap h[0..n) (by split_before) below position i. */
static void sift_down(unsigned *h, unsigned n, unsigned i, const double *sse)
{
    for (;;) {
        unsigned c = 2 * i + 1;
        if (c >= n)
            return;
        if (c + 1 < n && split_before(sse, h[c + 1], h[c]))
            c++;
        if (!split_before(sse, h[c], h[i]))
            return;
        const unsigned t = h[i];
        h[i] = h[c];
        h[c] = t;
        i = c;
    }
}

/* Centroid condition with empty cells: non-empty cells go to their means;
 * each empty cell, in order, splits the cell of largest distortion at its
 * centroid into two halves, each at its own centroid.  A split cell is not
 * split again and an exact one (distortion 0) never is, so the cells
 * split are those of positive distortion, largest first (of equal ones
 * the lowest index): they come off a heap, O(L + nempty log L) where a
 * scan per empty cell was O(L nempty), with the same result.  nxt
 * receives the levels (sorted); cur holds the current ones. */
static void centroid_split(const struct tvpal_quantws *ws, const size_t *bnd,
                           unsigned L, const double *cur, unsigned nempty,
                           double *nxt)
{
    double sse[TVPAL_LEVELS_MAX];
    unsigned heap[TVPAL_LEVELS_MAX], nh = 0;
    for (unsigned i = 0; i < L; i++) {
        size_t a = bnd[i], b = bnd[i + 1];
        if (b > a) {
            nxt[i] = (ws->p1[b] - ws->p1[a]) / count_d(b - a);
            sse[i] = cell_sse(ws, a, b, nxt[i]);
            if (sse[i] > 0.0)
                heap[nh++] = i;
        } else {
            nxt[i] = cur[i];
            sse[i] = -1.0;
        }
    }
    for (unsigned i = nh / 2; i-- > 0;)
        sift_down(heap, nh, i, sse);
    for (unsigned i = 0; i < L && nempty; i++) {
        if (sse[i] >= 0.0)
            continue;
        if (nh == 0)
            break; /* every cell is exact: nothing left to split */
        const unsigned w = heap[0];
        heap[0] = heap[--nh];
        sift_down(heap, nh, 0, sse);
        size_t a = bnd[w], b = bnd[w + 1];
        size_t p = lower_bound(ws->s, a, b, nxt[w] + ws->mean);
        if (p <= a || p >= b)
            break; /* cannot happen with sse > 0; be safe */
        double lo = (ws->p1[p] - ws->p1[a]) / count_d(p - a);
        double hi = (ws->p1[b] - ws->p1[p]) / count_d(b - p);
        nxt[w] = lo;
        nxt[i] = hi;
        nempty--;
    }
    sort_levels(nxt, L);
}

/* Lloyd iterations from y (centred, sorted, L entries); y is overwritten with
 * the best levels seen.  Returns the best total squared error.  bnd (L + 1
 * entries) holds a hint partition on entry if hinted, and the last
 * partition computed on return (hints change no result, only speed).
 * Each iteration computes the next levels from the current ones into the
 * other of two buffers, and the best levels are remembered by pointer; they
 * are copied aside only when the buffer holding them is about to be
 * overwritten (when an iteration did not improve on the best). */
static double lloyd(const struct tvpal_quantws *ws, double *y, unsigned L,
                    int max_iter, size_t *bnd, int hinted)
{
    double buf[3][TVPAL_LEVELS_MAX], cent[TVPAL_LEVELS_MAX];
    double *cur = buf[0], *nxt = buf[1], *best = buf[2];
    double best_d = DBL_MAX, prev_d = DBL_MAX;
    /* Over-relaxation (y += omega (centroid - y), omega > 1) speeds up
     * Lloyd's slow linear convergence several-fold; a relaxed step that
     * does not lower the distortion is replaced by the plain centroid step,
     * so the sequence of distortions still never increases. */
    double omega = 1.8;
    int relaxed = 0;

    memcpy(cur, y, L * sizeof *y);
    memcpy(best, y, L * sizeof *y);
    for (int it = 0;; it++) {
        unsigned nempty;
        double d = partition(ws, cur, L, bnd, hinted || it > 0, &nempty);
        if (relaxed && d >= prev_d) {
            memcpy(cur, cent, L * sizeof *cur);
            omega = 1.0 + 0.5 * (omega - 1.0);
            d = partition(ws, cur, L, bnd, 1, &nempty);
        }
        relaxed = 0;
        if (d < best_d) {
            best_d = d;
            best = cur;
        }
        if (d <= 0.0 || it >= max_iter ||
            (prev_d - d) <= LLOYD_REL_TOL * prev_d)
            break;
        prev_d = d;
        if (best == nxt) {
            memcpy(buf[2], nxt, L * sizeof *nxt);
            best = buf[2];
        }
        if (nempty) {
            centroid_split(ws, bnd, L, cur, nempty, nxt);
        } else {
            relaxed = omega > 1.01;
            centroid_relax(ws, bnd, L, cur, relaxed ? omega : 0.0, cent,
                           nxt);
        }
        double *t = cur;
        cur = nxt;
        nxt = t;
    }
    memcpy(y, best, L * sizeof *y);
    return best_d;
}

static void fit_exact(const struct tvpal_quantws *ws, struct tvpal_quant *q)
{
    unsigned L = 0;
    for (size_t i = 0; i < ws->n; i++) {
        if (i == 0 || ws->s[i] != ws->s[i - 1]) {
            q->level[L] = ws->s[i]; /* the values themselves, exactly */
            q->count[L] = 0;
            L++;
        }
        q->count[L - 1]++;
    }
    q->nlevels = L;
    for (unsigned i = 0; i + 1 < L; i++)
        q->thresh[i] = 0.5 * (q->level[i] + q->level[i + 1]);
    q->mse = 0.0;
}

static void uniform_levels(const struct tvpal_quantws *ws, unsigned L,
                           double *y)
{
    double lo = ws->s[0], hi = ws->s[ws->n - 1];
    double w = (hi - lo) / L;
    for (unsigned i = 0; i < L; i++)
        y[i] = lo + (i + 0.5) * w - ws->mean;
}

static void fit_single(const struct tvpal_quantws *ws, struct tvpal_quant *q)
{
    q->nlevels = 1;
    q->level[0] = ws->n ? ws->s[0] : 0.0;
    q->count[0] = ws->n;
    q->mse = 0.0;
}

void tvpal_quant_fit_uniform(struct tvpal_quantws *ws, unsigned levels,
                             struct tvpal_quant *q)
{
    double y[TVPAL_LEVELS_MAX];
    size_t bnd[TVPAL_LEVELS_MAX + 1];
    if (levels < 1)
        levels = 1;
    if (levels > TVPAL_LEVELS_MAX)
        levels = TVPAL_LEVELS_MAX;
    if (ws->distinct <= 1) {
        fit_single(ws, q);
        return;
    }
    uniform_levels(ws, levels, y);
    double d = exact_sse(ws, y, levels, bnd, 0);
    finish(ws, y, levels, d, bnd, q);
}

void tvpal_quant_fit_from(struct tvpal_quantws *ws, const double *start,
                          unsigned levels, struct tvpal_quant *q)
{
    double y[TVPAL_LEVELS_MAX];
    size_t bnd[TVPAL_LEVELS_MAX + 1];
    if (ws->distinct <= 1) {
        fit_single(ws, q);
        return;
    }
    for (unsigned i = 0; i < levels; i++)
        y[i] = start[i] - ws->mean;
    lloyd(ws, y, levels, LLOYD_MAX_ITER, bnd, 0);
    centroid_step(ws, y, levels, bnd);
    double d = exact_sse(ws, y, levels, bnd, 1);
    finish(ws, y, levels, d, bnd, q);
}

void tvpal_quant_fit_lloyd(struct tvpal_quantws *ws, unsigned levels,
                           struct tvpal_quant *q)
{
    double y0[TVPAL_LEVELS_MAX], yu[TVPAL_LEVELS_MAX], yq[TVPAL_LEVELS_MAX];
    size_t b0[TVPAL_LEVELS_MAX + 1], bu[TVPAL_LEVELS_MAX + 1],
        bq[TVPAL_LEVELS_MAX + 1];
    const size_t n = ws->n;
    if (levels < 1)
        levels = 1;
    if (levels > TVPAL_LEVELS_MAX)
        levels = TVPAL_LEVELS_MAX;
    if (ws->distinct <= 1) {
        fit_single(ws, q);
        return;
    }
    if (ws->distinct <= levels) {
        fit_exact(ws, q);
        return;
    }
    uniform_levels(ws, levels, y0);
    memcpy(yu, y0, levels * sizeof *yu);
    /* The uniform quantizer's exact distortion, for the final decision;
     * its partition is the uniform start's first, given as a hint. */
    double d0 = exact_sse(ws, y0, levels, b0, 0);
    memcpy(bu, b0, (levels + 1) * sizeof *bu);
    /* Quantile start: level i is the mean of the i-th equal-count block;
     * the blocks are the hint for its first partition. */
    for (unsigned i = 0; i < levels; i++) {
        size_t a = n * i / levels, b = n * (i + 1) / levels;
        yq[i] = b > a ? (ws->p1[b] - ws->p1[a]) / count_d(b - a) : 0.0;
        bq[i] = a;
    }
    bq[levels] = n;
    /* Race: both starts run a few iterations, the better one (by the
     * prefix-sum estimate) runs on; the other is dropped. */
    double eu = lloyd(ws, yu, levels, LLOYD_RACE_ITER, bu, 1);
    double eq = lloyd(ws, yq, levels, LLOYD_RACE_ITER, bq, 1);
    double *yb = eq < eu ? yq : yu;
    size_t *bb = eq < eu ? bq : bu;
    lloyd(ws, yb, levels, LLOYD_MAX_ITER - LLOYD_RACE_ITER, bb, 1);
    centroid_step(ws, yb, levels, bb);
    /* Decide against the uniform quantizer on exact distortions: the result
     * is never worse than uniform, whatever rounding did in the
     * iterations. */
    double db = exact_sse(ws, yb, levels, bb, 1);
    if (db <= d0)
        finish(ws, yb, levels, db, bb, q);
    else
        finish(ws, y0, levels, d0, b0, q);
}

unsigned tvpal_quant_code(const struct tvpal_quant *q, double v)
{
    unsigned lo = 0, hi = q->nlevels - 1; /* number of thresholds <= v */
    while (lo < hi) {
        unsigned mid = (lo + hi) / 2;
        if (v >= q->thresh[mid])
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

double tvpal_quant_mse(const struct tvpal_quant *q, const float *x, size_t n)
{
    double d = 0.0;
    for (size_t i = 0; i < n; i++) {
        double e = (double)x[i] - q->level[tvpal_quant_code(q, x[i])];
        d += e * e;
    }
    return n ? d / (double)n : 0.0;
}

void tvpal_qcoder_init(struct tvpal_qcoder *c, const struct tvpal_quant *q,
                       unsigned bits)
{
    unsigned P = 1u << bits;
    c->bits = bits;
    for (unsigned i = 0; i + 1 < P; i++)
        c->th[i] = (i + 1 < q->nlevels) ? (float)q->thresh[i] : INFINITY;
}

/* Codes of up to 3 bits (T = 2^bits - 1 <= 7 thresholds): the number of
 * thresholds <= v, which is what the binary search finds in sorted
 * thresholds (for any v: NaN counts none, +inf all, like the search).
 * With T a constant the threshold loop unrolls and the voxel loop
 * vectorizes. */
static inline void pack_count(const float *th, unsigned T, unsigned bits,
                              const float *x, size_t n, uint8_t *idx)
{
    for (size_t v = 0; v < n; v++) {
        const float xv = x[v];
        uint8_t code = 0;
        for (unsigned k = 0; k < T; k++)
            code += xv >= th[k];
        idx[v] = (uint8_t)((idx[v] << bits) | code);
    }
}

void tvpal_qcoder_pack(const struct tvpal_qcoder *c, const float *x, size_t n,
                       uint8_t *idx)
{
    enum { B = 64 };
    const unsigned bits = c->bits;
    const float *th = c->th;
    switch (bits) {
    case 1: pack_count(th, 1, 1, x, n, idx); return;
    case 2: pack_count(th, 3, 2, x, n, idx); return;
    case 3: pack_count(th, 7, 3, x, n, idx); return;
    default: break;
    }
    /* The first 3 steps of the binary search compare v with the coarse
     * thresholds th[k * S - 1], k = 1..7 (S = 2^(bits - 3)), and leave S
     * times the number of them <= v: counted as above. */
    const unsigned S = 1u << (bits - 3);
    const float c1 = th[S - 1], c2 = th[2 * S - 1], c3 = th[3 * S - 1],
                c4 = th[4 * S - 1], c5 = th[5 * S - 1], c6 = th[6 * S - 1],
                c7 = th[7 * S - 1];
    unsigned code[B];
    for (size_t v0 = 0; v0 < n; v0 += B) {
        size_t m = n - v0 < B ? n - v0 : B;
        const float *xb = x + v0;
        for (size_t i = 0; i < m; i++) {
            const float xv = xb[i];
            unsigned k = (xv >= c1) + (xv >= c2) + (xv >= c3) + (xv >= c4) +
                         (xv >= c5) + (xv >= c6) + (xv >= c7);
            code[i] = k * S;
        }
        for (unsigned step = S >> 1; step; step >>= 1)
            for (size_t i = 0; i < m; i++)
                code[i] += (xb[i] >= th[code[i] + step - 1]) ? step : 0;
        for (size_t i = 0; i < m; i++)
            idx[v0 + i] = (uint8_t)((idx[v0 + i] << bits) | code[i]);
    }
}
