/* tvpal_swcode.c: slice-window encoder (see tvpal_swcode.h). */
#include "tvpal_swcode.h"
#include "tvpal_bitalloc.h"
#include "tvpal_eig.h"
#include "tvpal_error.h"
#include "tvpal_quant.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* k-means++ draws its seeds from at most this many voxels. */
#define KPP_SAMPLE 1024
/* --refine: iterations from both starts before the better goes on. */
#define RACE 2

struct tvpal_swenc {
    size_t max_vox;
    unsigned max_len;
    float *coef;                 /* max_len * max_vox */
    struct tvpal_quantws *qws;
    double *sums;                /* 256 * max_len, index-major */
    size_t cnt[TVPAL_TABLE_ENTRIES];
    struct tvpal_quant q;        /* scratch (large: keep off the stack) */
    double levels[TVPAL_NMAX][TVPAL_LEVELS_MAX];
    unsigned nlevels[TVPAL_NMAX];
    struct tvpal_qcoder coder;
    /* --refine: generalized Lloyd on the voxel vectors */
    unsigned refine;
    int naive;                   /* uniform quantizers, IDCT tables */
    int klt;                     /* also try the KLT per slice-window */
    int alloc_mse;               /* bits by measured quantizer error */
    uint8_t *idx2;               /* max_vox: the KLT code */
    float *table2;               /* max_len * 256 */
    double basis[TVPAL_NMAX * TVPAL_NMAX];   /* rows: basis functions */
    float basis_f[TVPAL_NMAX * TVPAL_NMAX];
    double *xd;                  /* max_vox * max_len: voxel DCTs (double) */
    double cd[TVPAL_TABLE_ENTRIES][TVPAL_NMAX];  /* codeword DCTs */
    unsigned ord[TVPAL_TABLE_ENTRIES];           /* codewords by cd[.][0] */
    double sse[TVPAL_REFINE_MAX + 1];            /* per iteration */
    unsigned nsse;
    double kd[KPP_SAMPLE];       /* k-means++: a sample's distances */
    struct missing_ws *miss;     /* NULL until a slice has missing values */
    int no_kpp;                  /* refine from the DCT code only */
    uint64_t kpp_won;            /* refined codes from k-means++ kept */
};

int tvpal_swenc_create(struct tvpal_swenc **out, size_t max_vox,
                       unsigned max_len)
{
    if (max_len < 1 || max_len > TVPAL_NMAX)
        return TVPAL_E_INVAL;
    struct tvpal_swenc *e = calloc(1, sizeof *e);
    if (!e)
        return TVPAL_E_NOMEM;
    e->max_vox = max_vox;
    e->max_len = max_len;
    e->coef = malloc((max_vox ? max_vox : 1) * max_len * sizeof *e->coef);
    e->sums = malloc(TVPAL_TABLE_ENTRIES * max_len * sizeof *e->sums);
    int rc = tvpal_quantws_create(&e->qws, max_vox);
    if (rc < 0 || !e->coef || !e->sums) {
        tvpal_swenc_free(e);
        return TVPAL_E_NOMEM;
    }
    *out = e;
    return 0;
}

static void missing_ws_free(struct missing_ws *m);

void tvpal_swenc_free(struct tvpal_swenc *e)
{
    if (!e)
        return;
    missing_ws_free(e->miss);
    free(e->xd);
    free(e->idx2);
    free(e->table2);
    free(e->coef);
    free(e->sums);
    tvpal_quantws_free(e->qws);
    free(e);
}

/* Squared error of the current code, summed over voxels and timesteps, in
 * double from the samples. */
static double code_sse(const float *samples, size_t nvox, unsigned len,
                       const uint8_t *idx, const float *table)
{
    double s = 0.0;
    for (unsigned j = 0; j < len; j++) {
        const float *x = samples + (size_t)j * nvox;
        const float *row = table + j * TVPAL_TABLE_ENTRIES;
        for (size_t v = 0; v < nvox; v++) {
            double d = (double)x[v] - row[idx[v]];
            s += d * d;
        }
    }
    return s;
}

static int cmp_cd0(const struct tvpal_swenc *e, unsigned i, unsigned j);

/* e->ord (a permutation of the codewords) sorted by cd[.][0], ties by
 * index: an insertion sort of 256 entries, mostly ordered already after
 * refine's first iteration. */
static void sort_codewords(struct tvpal_swenc *e)
{
    for (unsigned a = 1; a < TVPAL_TABLE_ENTRIES; a++) {
        unsigned key = e->ord[a], b = a;
        while (b > 0 && cmp_cd0(e, e->ord[b - 1], key) > 0) {
            e->ord[b] = e->ord[b - 1];
            b--;
        }
        e->ord[b] = key;
    }
}

/* The position in e->ord of the first codeword with cd0 >= x0 (256: none). */
static unsigned first_at_least(const struct tvpal_swenc *e, double x0)
{
    unsigned lo = 0, hi = TVPAL_TABLE_ENTRIES;
    while (lo < hi) {
        unsigned mid = (lo + hi) / 2;
        if (e->cd[e->ord[mid]][0] < x0)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* The voxel vectors in the DCT domain, voxel-major, into e->xd (refine's
 * and kpp_seed's input). */
static void voxel_dcts(struct tvpal_swenc *e, const float *samples,
                       size_t nvox, unsigned L)
{
    for (size_t v = 0; v < nvox; v++) {
        double x[TVPAL_NMAX];
        for (unsigned j = 0; j < L; j++)
            x[j] = samples[(size_t)j * nvox + v];
        tvpal_dct_forward(L, x, e->xd + v * L);
    }
}

/* k-means++ seeding (Arthur & Vassilvitskii 2007) of the 256 codewords,
 * as refine's other start: drawn from an even sample of at most
 * KPP_SAMPLE voxel vectors, each next one with probability proportional
 * to its squared distance from those drawn (a sample all drawn or all at
 * distance 0 repeats the last).  Deterministic: xorshift from the
 * slice-window's size.  The codewords go to table (time domain), and
 * each voxel's index to the codeword nearest it in coefficient 0: refine's
 * first pass finds its nearest from there. */
static void kpp_seed(struct tvpal_swenc *e, size_t nvox, unsigned L,
                     uint8_t *idx, float *table)
{
    const unsigned K = TVPAL_TABLE_ENTRIES;
    const size_t stride = nvox / KPP_SAMPLE + 1;
    const size_t ns = (nvox + stride - 1) / stride;
    uint64_t r = 0x9E3779B97F4A7C15ull ^ nvox ^ (uint64_t)L << 40;
    size_t pick = 0;
    double total = 0.0;     /* of kd[], kept as they fall */
    for (unsigned c = 0; c < K; c++) {
        if (c > 0) {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            double u = (double)(r >> 11) * 0x1.0p-53 * total, acc = 0.0;
            for (size_t i = 0; i < ns && total > 0.0; i++) {
                acc += e->kd[i];
                pick = i;
                if (acc > u && e->kd[i] > 0.0)
                    break;
            }
        }
        const double *x = e->xd + pick * stride * L;
        memcpy(e->cd[c], x, L * sizeof *x);
        double t[TVPAL_NMAX];
        tvpal_dct_inverse(L, x, t);
        for (unsigned j = 0; j < L; j++)
            table[j * K + c] = (float)t[j];
        total = 0.0;
        for (size_t i = 0; i < ns; i++) {
            const double *y = e->xd + i * stride * L;
            double d = 0.0;
            for (unsigned j = 0; j < L && (c == 0 || d < e->kd[i]); j++) {
                double q = y[j] - x[j];
                d += q * q;
            }
            e->kd[i] = c == 0 || d < e->kd[i] ? d : e->kd[i];
            total += e->kd[i];
        }
    }
    /* Each voxel starts at the codeword nearest in coefficient 0 (not
     * the nearest: refine finds it, from a distance that prunes its
     * search at once). */
    for (unsigned i = 0; i < K; i++)
        e->ord[i] = i;
    sort_codewords(e);
    for (size_t v = 0; v < nvox; v++) {
        const double x0 = e->xd[v * L];
        unsigned lo = first_at_least(e, x0);
        if (lo == K || (lo > 0 && x0 - e->cd[e->ord[lo - 1]][0] <
                                      e->cd[e->ord[lo]][0] - x0))
            lo--;
        idx[v] = (uint8_t)e->ord[lo];
    }
}

/* Renumbers a refined code's codewords in ascending order of their mean
 * over the window (ties: the old number), moving the table's columns and
 * every voxel's index with them: the same values decode, but neighbouring
 * voxels of similar values get near indices, as the DCT code's do (its
 * coefficient 0 is the index's high bits).  k-means++ seeds come in no
 * order, and their indices took about a third more bytes once coded
 * (FORMAT.md 6.11: viscous fingers, N = 4, --refine 10; NEWS). */
static void relabel_by_mean(struct tvpal_swenc *e, uint8_t *idx, float *table,
                            unsigned len, size_t nvox)
{
    const unsigned K = TVPAL_TABLE_ENTRIES;
    for (unsigned i = 0; i < K; i++) {
        double m = 0;
        for (unsigned j = 0; j < len; j++)
            m += table[j * K + i];
        e->cd[i][0] = m;   /* cmp_cd0's key; refine is done with cd */
        e->ord[i] = i;
    }
    sort_codewords(e);
    uint8_t to[TVPAL_TABLE_ENTRIES];
    float row[TVPAL_TABLE_ENTRIES];
    for (unsigned r = 0; r < K; r++)
        to[e->ord[r]] = (uint8_t)r;
    for (unsigned j = 0; j < len; j++) {
        float *t = table + (size_t)j * K;
        for (unsigned r = 0; r < K; r++)
            row[r] = t[e->ord[r]];
        memcpy(t, row, sizeof row);
    }
    for (size_t v = 0; v < nvox; v++)
        idx[v] = to[idx[v]];
    size_t cnt[TVPAL_TABLE_ENTRIES];   /* the counts follow their codewords */
    for (unsigned r = 0; r < K; r++)
        cnt[r] = e->cnt[e->ord[r]];
    memcpy(e->cnt, cnt, sizeof cnt);
}

/* Generalized Lloyd (k-means) on the slice-window's voxel vectors, seeded
 * with the 256 codewords the DCT/Lloyd-Max code produced (Linde, Buzo &
 * Gray 1980).  Each iteration assigns every voxel to its nearest codeword
 * and moves each codeword used to the mean of its voxels (which is what
 * the decoder table holds anyway), so the distortion cannot rise.  The
 * nearest-codeword search runs in the DCT domain (an orthonormal transform
 * keeps distances) where most energy is in coefficient 0: codewords sorted
 * by it are searched outward from the voxel's value and the search stops
 * once (c0 - x0)^2 alone exceeds the best distance; partial sums stop a
 * candidate early.  A voxel moves only for a strictly better codeword
 * (ties keep the current one: deterministic). */
static int refine(struct tvpal_swenc *e, const float *samples, size_t nvox,
                  unsigned len, uint8_t *idx, float *table, unsigned iters,
                  int append)
{
    const unsigned L = len, K = TVPAL_TABLE_ENTRIES;
    const double *xd = e->xd;   /* voxel_dcts */
    if (!xd)
        return TVPAL_E_INVAL;
    if (!append) {  /* else the history goes on (the same code) */
        e->sse[0] = code_sse(samples, nvox, len, idx, table);
        e->nsse = 1;
    }
    for (unsigned it = 0; it < iters && e->nsse <= TVPAL_REFINE_MAX; it++) {
        for (unsigned i = 0; i < K; i++) {
            double c[TVPAL_NMAX];
            for (unsigned j = 0; j < L; j++)
                c[j] = table[j * K + i];
            tvpal_dct_forward(L, c, e->cd[i]);
            e->ord[i] = i;
        }
        sort_codewords(e);
        unsigned changed = 0;
        for (size_t v = 0; v < nvox; v++) {
            const double *x = xd + v * L;
            unsigned best = idx[v];
            double bd = 0.0;
            for (unsigned j = 0; j < L; j++) {
                double d = x[j] - e->cd[best][j];
                bd += d * d;
            }
            /* First codeword with cd0 >= x0, then outward. */
            const unsigned lo = first_at_least(e, x[0]);
            int up = (int)lo, dn = (int)lo - 1;
            while (up < (int)K || dn >= 0) {
                int pick;
                double d0u = up < (int)K ? e->cd[e->ord[up]][0] - x[0] : 1e300;
                double d0d = dn >= 0 ? x[0] - e->cd[e->ord[dn]][0] : 1e300;
                if (d0u <= d0d) {
                    if (d0u * d0u >= bd) {
                        if (d0d * d0d >= bd)
                            break;
                        pick = dn--;
                    } else {
                        pick = up++;
                    }
                } else {
                    if (d0d * d0d >= bd) {
                        if (d0u * d0u >= bd)
                            break;
                        pick = up++;
                    } else {
                        pick = dn--;
                    }
                }
                unsigned ci = e->ord[pick];
                if (ci == best)
                    continue;
                const double *c = e->cd[ci];
                double d = 0.0;
                for (unsigned j = 0; j < L && d < bd; j++) {
                    double t = x[j] - c[j];
                    d += t * t;
                }
                if (d < bd) {
                    bd = d;
                    best = ci;
                }
            }
            if (best != idx[v]) {
                idx[v] = (uint8_t)best;
                changed++;
            }
        }
        /* Centroids: the decoder table's means, recomputed. */
        memset(e->cnt, 0, sizeof e->cnt);
        memset(e->sums, 0, K * L * sizeof *e->sums);
        for (size_t v = 0; v < nvox; v++) {
            unsigned i = idx[v];
            double *s = e->sums + (size_t)i * L;
            e->cnt[i]++;
            for (unsigned j = 0; j < L; j++)
                s[j] += samples[(size_t)j * nvox + v];
        }
        for (unsigned i = 0; i < K; i++)
            if (e->cnt[i]) {
                double inv = 1.0 / (double)e->cnt[i];
                for (unsigned j = 0; j < L; j++)
                    table[j * K + i] = (float)(e->sums[(size_t)i * L + j] * inv);
            }
        e->sse[e->nsse++] = code_sse(samples, nvox, len, idx, table);
        if (!changed)
            break;
    }
    return 0;
}

static int cmp_cd0(const struct tvpal_swenc *e, unsigned i, unsigned j)
{
    double x = e->cd[i][0], y = e->cd[j][0];
    return x < y ? -1 : x > y ? 1 : (int)i - (int)j;
}

/* --alloc greedy-mse: the same greedy marginal-return allocation as the
 * variance rule, but each step's gain is measured: D_u(b) is the MSE of the
 * Lloyd-Max quantizer of coefficient u with 2^b levels (D_u(0) = its
 * variance), fitted for b = 1..8 once per coefficient.  Distortion adds up
 * over coefficients (orthonormal transform), so the greedy step gives the
 * bit where it lowers the total error most. */
static void alloc_mse(struct tvpal_swenc *e, unsigned len, size_t nvox,
                      const double *var, uint8_t *bits)
{
    double D[TVPAL_NMAX][TVPAL_INDEX_BITS + 1];
    for (unsigned u = 0; u < len; u++) {
        bits[u] = 0;
        D[u][0] = var[u];
        if (!(var[u] > 0.0)) {
            for (unsigned b = 1; b <= TVPAL_INDEX_BITS; b++)
                D[u][b] = 0.0;
            continue;
        }
        tvpal_quantws_load(e->qws, e->coef + (size_t)u * nvox, nvox);
        for (unsigned b = 1; b <= TVPAL_INDEX_BITS; b++) {
            tvpal_quant_fit_lloyd(e->qws, 1u << b, &e->q);
            D[u][b] = e->q.mse;
        }
    }
    for (unsigned k = 0; k < TVPAL_INDEX_BITS; k++) {
        unsigned best = len;
        double gain = 0.0;
        for (unsigned u = 0; u < len; u++) {
            if (bits[u] >= TVPAL_INDEX_BITS)
                continue;
            double g = D[u][bits[u]] - D[u][bits[u] + 1];
            if (g > gain) {
                gain = g;
                best = u;
            }
        }
        if (best == len)
            break;
        bits[best]++;
    }
}

/* The transform into e->basis (and its float copy): DCT-II, or with use_klt
 * the slice-window's KLT (eigenvectors of the temporal covariance of its
 * voxels, by decreasing variance).  0 or tvpal_eig_sym's error. */
static int basis_choose(struct tvpal_swenc *e, const float *samples,
                        size_t nvox, unsigned len, int use_klt)
{
    if (use_klt) {
        double cov[TVPAL_NMAX * TVPAL_NMAX], m[TVPAL_NMAX], w[TVPAL_NMAX];
        for (unsigned j = 0; j < len; j++) {
            double s = 0.0;
            for (size_t v = 0; v < nvox; v++)
                s += samples[(size_t)j * nvox + v];
            m[j] = nvox ? s / (double)nvox : 0.0;
        }
        for (unsigned j = 0; j < len; j++)
            for (unsigned k = j; k < len; k++) {
                const float *a = samples + (size_t)j * nvox;
                const float *b = samples + (size_t)k * nvox;
                double s = 0.0;
                for (size_t v = 0; v < nvox; v++)
                    s += ((double)a[v] - m[j]) * ((double)b[v] - m[k]);
                cov[j * len + k] = cov[k * len + j] = nvox ? s / (double)nvox : 0.0;
            }
        int rc = tvpal_eig_sym((int)len, cov, w);
        if (rc < 0)
            return rc;
        memcpy(e->basis, cov, sizeof(double) * len * len);
    } else {
        memcpy(e->basis, tvpal_dct_matrix(len), sizeof(double) * len * len);
    }
    for (unsigned i = 0; i < len * len; i++)
        e->basis_f[i] = (float)e->basis[i];
    return 0;
}

/* Mean and variance of each coefficient u of e->coef over the voxels. */
static void coef_stats(const struct tvpal_swenc *e, size_t nvox,
                       unsigned len, double *mean, double *var_u)
{
    for (unsigned u = 0; u < len; u++) {
        /* One pass, shifted by the first value (no cancellation for data
         * with a large offset), four accumulators for speed. */
        const float *c = e->coef + (size_t)u * nvox;
        const double k = nvox ? c[0] : 0.0;
        /* Accumulator l takes the samples v = l mod 4; as a 4-lane vector
         * (GCC/Clang vector extension) the same per-lane operations
         * vectorize, which the compilers do not find themselves. */
        typedef double v4d __attribute__((vector_size(4 * sizeof(double))));
        const v4d kv = {k, k, k, k};
        v4d sv = {0.0, 0.0, 0.0, 0.0}, qv = sv;
        size_t v = 0;
        for (; v + 4 <= nvox; v += 4) {
            v4d d = {c[v], c[v + 1], c[v + 2], c[v + 3]};
            d -= kv;
            sv += d;
            qv += d * d;
        }
        double s[4] = {sv[0], sv[1], sv[2], sv[3]};
        double q[4] = {qv[0], qv[1], qv[2], qv[3]};
        for (; v < nvox; v++) {
            double d = (double)c[v] - k;
            s[0] += d;
            q[0] += d * d;
        }
        double S = (s[0] + s[1]) + (s[2] + s[3]);
        double Q = (q[0] + q[1]) + (q[2] + q[3]);
        double m = nvox ? S / (double)nvox : 0.0;
        double var = nvox ? Q / (double)nvox - m * m : 0.0;
        mean[u] = k + m;
        var = var > 0.0 ? var : 0.0;
        /* Rounding noise of a constant coefficient is no variance. */
        if (var <= 1e-24 * (k * k + m * m))
            var = 0.0;
        var_u[u] = var;
    }
}

/* Fits a quantizer of 2^bits[u] levels to each coefficient (levels kept in
 * e->levels) and packs the codes of all coefficients into idx. */
static void quantize_coefs(struct tvpal_swenc *e, size_t nvox, unsigned len,
                           const uint8_t *bits, uint8_t *idx)
{
    memset(idx, 0, nvox);
    for (unsigned u = 0; u < len; u++) {
        e->nlevels[u] = 0;
        if (!bits[u])
            continue;
        const float *c = e->coef + (size_t)u * nvox;
        tvpal_quantws_load(e->qws, c, nvox);
        if (e->naive)
            tvpal_quant_fit_uniform(e->qws, 1u << bits[u], &e->q);
        else
            tvpal_quant_fit_lloyd(e->qws, 1u << bits[u], &e->q);
        e->nlevels[u] = e->q.nlevels;
        memcpy(e->levels[u], e->q.level, e->q.nlevels * sizeof(double));
        tvpal_qcoder_init(&e->coder, &e->q, bits[u]);
        tvpal_qcoder_pack(&e->coder, c, nvox, idx);
    }
}

/* Decoder table entry i of an unused index (or of every index in the
 * naive variant): unpacks its codes, dequantizes, inverse transform. */
static void table_decode(const struct tvpal_swenc *e, unsigned len,
                         const uint8_t *bits, const double *mean, unsigned i,
                         float *table)
{
    double co[TVPAL_NMAX], val[TVPAL_NMAX];
    unsigned rest = i;
    for (int u = (int)len - 1; u >= 0; u--) {
        if (!bits[u]) {
            co[u] = mean[u];
            continue;
        }
        unsigned code = rest & ((1u << bits[u]) - 1);
        rest >>= bits[u];
        if (code >= e->nlevels[u])
            code = e->nlevels[u] - 1;
        co[u] = e->levels[u][code];
    }
    for (unsigned x = 0; x < len; x++) {
        double s = 0.0;
        for (unsigned u = 0; u < len; u++)
            s += e->basis[u * len + x] * co[u];
        val[x] = s;
    }
    for (unsigned j = 0; j < len; j++)
        table[j * TVPAL_TABLE_ENTRIES + i] = (float)val[j];
}

/* Per index i: e->cnt[i] voxels, and e->sums[i * len + j] the sum of their
 * samples j, added in voxel order from 0.0.  Neighbouring voxels often
 * hold the same index (flat regions); the sums of such a run are kept in
 * registers (an inline function, so len is a constant in the calls below)
 * and written back when the index changes, instead of each addition
 * waiting for the previous one's store.  Where runs are short (turbulent
 * data) that costs more than it saves, and the plain loop runs instead.
 * Either way the additions are the same, in the same order. */
static inline void index_sums(struct tvpal_swenc *e, const float *samples,
                              size_t nvox, unsigned len, const uint8_t *idx)
{
    double acc[TVPAL_NMAX];
    memset(e->cnt, 0, sizeof e->cnt);
    memset(e->sums, 0, TVPAL_TABLE_ENTRIES * len * sizeof *e->sums);
    if (!nvox)
        return;
    size_t changes = 0;
    for (size_t v = 1; v < nvox; v++)
        changes += idx[v] != idx[v - 1];
    if (changes * 3 > nvox) { /* runs shorter than 3 voxels on average */
        for (size_t v = 0; v < nvox; v++) {
            double *s = e->sums + (size_t)idx[v] * len;
            e->cnt[idx[v]]++;
            for (unsigned j = 0; j < len; j++)
                s[j] += samples[(size_t)j * nvox + v];
        }
        return;
    }
    unsigned cur = idx[0];
    size_t run = 0;
    for (unsigned j = 0; j < len; j++)
        acc[j] = 0.0;
    for (size_t v = 0; v < nvox; v++) {
        const unsigned i = idx[v];
        if (i != cur) {
            double *s = e->sums + (size_t)cur * len;
            const double *r = e->sums + (size_t)i * len;
            for (unsigned j = 0; j < len; j++)
                s[j] = acc[j];
            for (unsigned j = 0; j < len; j++)
                acc[j] = r[j];
            e->cnt[cur] += run;
            cur = i;
            run = 0;
        }
        run++;
        for (unsigned j = 0; j < len; j++)
            acc[j] += samples[(size_t)j * nvox + v];
    }
    for (unsigned j = 0; j < len; j++)
        e->sums[(size_t)cur * len + j] = acc[j];
    e->cnt[cur] += run;
}

/* Decoder table: per-index means of the original samples; returns the
 * number of indices used. */
static unsigned table_build(struct tvpal_swenc *e, const float *samples,
                            size_t nvox, unsigned len, const uint8_t *idx,
                            const uint8_t *bits, const double *mean,
                            float *table)
{
    switch (len) {
    case 4: index_sums(e, samples, nvox, 4, idx); break;
    case 8: index_sums(e, samples, nvox, 8, idx); break;
    default: index_sums(e, samples, nvox, len, idx); break;
    }
    unsigned used = 0;
    for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++) {
        used += e->cnt[i] > 0;
        if (e->cnt[i] && !e->naive) {
            double inv = 1.0 / (double)e->cnt[i];
            for (unsigned j = 0; j < len; j++)
                table[j * TVPAL_TABLE_ENTRIES + i] =
                    (float)(e->sums[(size_t)i * len + j] * inv);
            continue;
        }
        table_decode(e, len, bits, mean, i, table);
    }
    return used;
}

/* The code of one slice-window with one transform (DCT-II, or with
 * use_klt the slice-window's KLT); writes idx, table, bits and the number
 * of indices used. */
static int encode_basis(struct tvpal_swenc *e, const float *samples,
                        size_t nvox, unsigned len, uint8_t *idx, float *table,
                        uint8_t *bits, unsigned *used_out, int use_klt,
                        int use_mse)
{
    double mean[TVPAL_NMAX], var_u[TVPAL_NMAX];
    int rc = basis_choose(e, samples, nvox, len, use_klt);
    if (rc < 0)
        return rc;
    tvpal_basis_forward_f(e->basis_f, len, samples, e->coef, nvox, nvox);
    coef_stats(e, nvox, len, mean, var_u);
    if (use_mse)
        alloc_mse(e, len, nvox, var_u, bits);
    else
        tvpal_bitalloc_variance(var_u, len, TVPAL_INDEX_BITS, bits);
    quantize_coefs(e, nvox, len, bits, idx);
    *used_out = table_build(e, samples, nvox, len, idx, bits, mean, table);
    return 0;
}

/* The code of a slice-window without missing values: the DCT code and
 * the alternatives the options ask for, the best kept, then refined. */
static int encode_finite(struct tvpal_swenc *e, const float *samples,
                         size_t nvox, unsigned len, uint8_t *idx,
                         float *table, uint8_t *bits, unsigned *used_out)
{
    unsigned used;
    int rc = encode_basis(e, samples, nvox, len, idx, table, bits, &used, 0,
                          0);
    if (rc < 0)
        return rc;
    /* Alternatives (the KLT, the measured-error allocation, both): each is
     * coded too and kept only where it errs less, so no option is ever
     * worse than the plain code on any slice-window.  (The KLT's quantized
     * code, and a greedy allocation on per-coefficient errors, are not
     * always better than the DCT and the variance rule.) */
    double best = -1.0;
    for (int alt = 1; alt < 4; alt++) {
        int klt = alt & 1, mse = alt >> 1;
        if ((klt && !(e->klt && len > 1)) || (mse && !e->alloc_mse))
            continue;
        if (best < 0.0)
            best = code_sse(samples, nvox, len, idx, table);
        uint8_t bits2[TVPAL_NMAX] = {0};
        unsigned used2;
        rc = encode_basis(e, samples, nvox, len, e->idx2, e->table2, bits2,
                          &used2, klt, mse);
        if (rc < 0)
            return rc;
        double sse2 = code_sse(samples, nvox, len, e->idx2, e->table2);
        if (sse2 < best) {
            best = sse2;
            memcpy(idx, e->idx2, nvox);
            memcpy(table, e->table2, sizeof(float) * len * TVPAL_TABLE_ENTRIES);
            memcpy(bits, bits2, sizeof bits2);
            used = used2;
        }
    }
    e->nsse = 0;
    if (e->refine && nvox) {
        voxel_dcts(e, samples, nvox, len);
        /* Refined from k-means++ seeds too: both starts race for RACE
         * iterations, the one that errs less then goes on alone (with its
         * history of errors), so this is never worse than the DCT start
         * alone over those iterations, and costs about RACE more.
         * Viscous fingers 64^3 x 99, N = 4, --refine 5: see NEWS. */
        const unsigned race = e->no_kpp ? e->refine
                              : e->refine < RACE ? e->refine : RACE;
        double kpp_sse[TVPAL_REFINE_MAX + 1];
        unsigned kpp_n = 0;
        size_t kpp_cnt[TVPAL_TABLE_ENTRIES];
        if (!e->no_kpp) {
            kpp_seed(e, nvox, len, e->idx2, e->table2);
            rc = refine(e, samples, nvox, len, e->idx2, e->table2, race, 0);
            if (rc < 0)
                return rc;
            kpp_n = e->nsse;
            memcpy(kpp_sse, e->sse, sizeof kpp_sse);
            memcpy(kpp_cnt, e->cnt, sizeof kpp_cnt);
        }
        rc = refine(e, samples, nvox, len, idx, table, race, 0);
        if (rc < 0)
            return rc;
        if (kpp_n && kpp_sse[kpp_n - 1] < e->sse[e->nsse - 1]) {
            memcpy(idx, e->idx2, nvox);
            memcpy(table, e->table2, sizeof(float) * len * TVPAL_TABLE_ENTRIES);
            memcpy(e->sse, kpp_sse, sizeof kpp_sse);
            memcpy(e->cnt, kpp_cnt, sizeof kpp_cnt);
            e->nsse = kpp_n;
            e->kpp_won++;
        }
        /* The winner goes on, unless it stopped (no voxel moved). */
        if (e->refine > race && e->nsse == race + 1) {
            rc = refine(e, samples, nvox, len, idx, table, e->refine - race, 1);
            if (rc < 0)
                return rc;
        }
        used = 0;
        for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++)
            used += e->cnt[i] > 0;
        relabel_by_mean(e, idx, table, len, nvox);
    }
    *used_out = used;
    return 0;
}

/* ------------------------------------------------------- missing values */

/* A slice-window with missing samples (NaN) is coded in groups.  The
 * voxels with every sample present are one group, coded as above as a
 * slice of their own.  The others are grouped by their pattern of missing
 * timesteps (a bit per timestep); each pattern is coded the same way over
 * the timesteps it has, and its table rows are NaN at the timesteps it
 * misses, so a decoder finds NaN exactly where the source had it.  Voxels
 * missing throughout share one index of NaN.  When the groups' codes need
 * more than the 256 indices, each group gets a share in proportion to its
 * voxels (at least one index) and merges its least used indices into the
 * nearest ones (by table row) down to its share.  At most
 * MISSING_PATTERNS_MAX patterns are coded; the voxels of rarer ones
 * (possible only for N >= 8) are coded as missing throughout the window,
 * and their present samples counted in tvpal_swinfo.dropped. */
#define MISSING_PATTERNS_MAX 128

struct missing_vox {
    uint32_t mask;      /* bit j: sample j is missing */
    uint32_t v;         /* voxel */
};

/* A group of voxels coded together: the finite ones (mask 0) or those of
 * one pattern. */
struct missing_group {
    uint32_t mask;
    uint32_t start, n;  /* patterns: their voxels are mv[start .. +n) */
    uint8_t *code;      /* n codes: fidx, or pcode + start */
    float *table;       /* 256 * len entries, row stride 256 */
    unsigned len;       /* timesteps it has */
    unsigned used, share;
};

struct missing_ws {
    uint32_t *mask;                  /* max_vox */
    float *samples;                  /* max_len * max_vox: one group's */
    uint8_t *fidx;                   /* max_vox: finite voxels' codes */
    uint8_t *pcode;                  /* max_vox: pattern voxels' codes */
    struct missing_vox *mv;          /* max_vox */
    struct missing_group *grp;       /* max_vox + 1 (the finite group,
                                      * a pattern per missing voxel) */
    size_t ngrp;
    float *ptables;                  /* MISSING_PATTERNS_MAX * 256 * len */
};

static void missing_ws_free(struct missing_ws *m)
{
    if (!m)
        return;
    free(m->mask);
    free(m->samples);
    free(m->fidx);
    free(m->pcode);
    free(m->mv);
    free(m->grp);
    free(m->ptables);
    free(m);
}

/* Allocated on the first slice-window with missing values, kept for the
 * next ones (never per slice). */
static int missing_ws_get(struct tvpal_swenc *e)
{
    if (e->miss)
        return 0;
    const size_t n = e->max_vox ? e->max_vox : 1;
    struct missing_ws *m = calloc(1, sizeof *m);
    if (!m)
        return TVPAL_E_NOMEM;
    m->mask = malloc(n * sizeof *m->mask);
    m->samples = malloc(n * e->max_len * sizeof *m->samples);
    m->fidx = malloc(n);
    m->pcode = malloc(n);
    m->mv = malloc(n * sizeof *m->mv);
    m->grp = malloc((n + 1) * sizeof *m->grp);
    m->ptables = malloc((size_t)MISSING_PATTERNS_MAX * TVPAL_TABLE_ENTRIES *
                        e->max_len * sizeof *m->ptables);
    if (!m->mask || !m->samples || !m->fidx || !m->pcode || !m->mv ||
        !m->grp || !m->ptables) {
        missing_ws_free(m);
        return TVPAL_E_NOMEM;
    }
    e->miss = m;
    return 0;
}

/* Any NaN among the n samples?  (A plain scan: vectorized, and cheaper
 * than the DCT that follows when there is none.) */
static int has_nan(const float *s, size_t n)
{
    int any = 0;
    for (size_t i = 0; i < n; i++)
        any |= s[i] != s[i];
    return any;
}

static int cmp_missing_vox(const void *pa, const void *pb)
{
    const struct missing_vox *a = pa, *b = pb;
    if (a->mask != b->mask)
        return a->mask < b->mask ? -1 : 1;
    return a->v < b->v ? -1 : a->v > b->v;
}

/* Fills m->mask and the list of missing voxels (by mask, then voxel);
 * returns the number of finite voxels; *nmiss voxels and *nsamples
 * samples are missing. */
static size_t missing_scan(struct missing_ws *m, const float *samples,
                           size_t nvox, unsigned len, size_t *nmiss,
                           uint64_t *nsamples)
{
    uint64_t ns = 0;
    memset(m->mask, 0, nvox * sizeof *m->mask);
    for (unsigned j = 0; j < len; j++) {
        const float *row = samples + (size_t)j * nvox;
        for (size_t v = 0; v < nvox; v++)
            if (row[v] != row[v]) {
                m->mask[v] |= 1u << j;
                ns++;
            }
    }
    size_t nm = 0;
    for (size_t v = 0; v < nvox; v++)
        if (m->mask[v])
            m->mv[nm++] = (struct missing_vox){m->mask[v], (uint32_t)v};
    qsort(m->mv, nm, sizeof *m->mv, cmp_missing_vox);
    *nmiss = nm;
    *nsamples = ns;
    return nvox - nm;
}

/* Most voxels first; ties by mask (deterministic). */
static int cmp_group_count(const void *pa, const void *pb)
{
    const struct missing_group *a = pa, *b = pb;
    if (a->n != b->n)
        return a->n > b->n ? -1 : 1;
    return a->mask < b->mask ? -1 : a->mask > b->mask;
}

/* Lists the partial patterns of the sorted missing voxels as groups after
 * m->grp[0 .. m->ngrp); sets *full when some voxel is missing throughout. */
static void missing_group_patterns(struct missing_ws *m, size_t nmiss,
                                   uint32_t all, int *full)
{
    *full = 0;
    for (size_t i = 0; i < nmiss;) {
        size_t k = i;
        while (k < nmiss && m->mv[k].mask == m->mv[i].mask)
            k++;
        if (m->mv[i].mask == all)
            *full = 1;
        else
            m->grp[m->ngrp++] = (struct missing_group){
                .mask = m->mv[i].mask, .start = (uint32_t)i,
                .n = (uint32_t)(k - i)};
        i = k;
    }
}

/* The partial patterns as groups (after the finite group, if any), at most
 * MISSING_PATTERNS_MAX: the voxels of rarer ones are given the full pattern
 * and their present samples added to *dropped. */
static void missing_patterns(struct missing_ws *m, size_t nmiss,
                             unsigned len, int *full, uint64_t *dropped)
{
    const uint32_t all = (1u << len) - 1;
    const size_t first = m->ngrp;
    missing_group_patterns(m, nmiss, all, full);
    size_t np = m->ngrp - first;
    if (np <= MISSING_PATTERNS_MAX)
        return;
    struct missing_group *pat = m->grp + first;
    qsort(pat, np, sizeof *pat, cmp_group_count);
    for (size_t p = MISSING_PATTERNS_MAX; p < np; p++) {
        unsigned present = len - (unsigned)__builtin_popcount(pat[p].mask);
        *dropped += (uint64_t)present * pat[p].n;
        for (uint32_t i = 0; i < pat[p].n; i++)
            m->mv[pat[p].start + i].mask = all;
    }
    qsort(m->mv, nmiss, sizeof *m->mv, cmp_missing_vox);
    m->ngrp = first;
    missing_group_patterns(m, nmiss, all, full);
}

/* Codes the voxels of pattern group g over the timesteps it has. */
static int missing_code_pattern(struct tvpal_swenc *e, const float *samples,
                                size_t nvox, unsigned len,
                                struct missing_group *g)
{
    struct missing_ws *m = e->miss;
    unsigned lp = 0;
    for (unsigned j = 0; j < len; j++) {
        if (g->mask >> j & 1)
            continue;
        const float *row = samples + (size_t)j * nvox;
        float *dst = m->samples + (size_t)lp * g->n;
        for (uint32_t k = 0; k < g->n; k++)
            dst[k] = row[m->mv[g->start + k].v];
        lp++;
    }
    uint8_t bits[TVPAL_NMAX];
    g->len = lp;
    g->code = m->pcode + g->start;
    return encode_finite(e, m->samples, g->n, lp, g->code, g->table, bits,
                         &g->used);
}

/* Shares out `budget` indices: each group at least one, the rest one at a
 * time to the group with the most voxels per index, never more than its
 * code uses.  (Only called when the codes need more than the budget.) */
static void missing_share(struct missing_group *grp, size_t ng,
                          unsigned budget)
{
    for (size_t g = 0; g < ng; g++) {
        grp[g].share = 1;
        budget--;
    }
    for (; budget; budget--) {
        size_t best = ng;
        for (size_t g = 0; g < ng; g++)
            if (grp[g].share < grp[g].used &&
                (best == ng || (double)grp[g].n / grp[g].share >
                                   (double)grp[best].n / grp[best].share))
                best = g;
        if (best == ng)
            return;
        grp[best].share++;
    }
}

/* Merges group g's least held index into the index with the nearest table
 * row (squared distance over its timesteps), again, until it holds
 * g->share indices; its codes are rewritten once at the end. */
static void missing_merge_down(struct missing_group *g)
{
    size_t cnt[TVPAL_TABLE_ENTRIES] = {0};
    uint8_t to[TVPAL_TABLE_ENTRIES];
    for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++)
        to[i] = (uint8_t)i;
    for (uint32_t k = 0; k < g->n; k++)
        cnt[g->code[k]]++;
    const float *t = g->table;
    for (unsigned used = g->used; used > g->share; used--) {
        unsigned a = TVPAL_TABLE_ENTRIES, b = TVPAL_TABLE_ENTRIES;
        for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++)
            if (cnt[i] && (a == TVPAL_TABLE_ENTRIES || cnt[i] < cnt[a]))
                a = i;
        double best = 0;
        for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++) {
            if (!cnt[i] || i == a)
                continue;
            double d = 0;
            for (unsigned j = 0; j < g->len; j++) {
                double x = (double)t[j * TVPAL_TABLE_ENTRIES + i] -
                           t[j * TVPAL_TABLE_ENTRIES + a];
                d += x * x;
            }
            if (b == TVPAL_TABLE_ENTRIES || d < best) {
                best = d;
                b = i;
            }
        }
        const double wa = (double)cnt[a], wb = (double)cnt[b];
        for (unsigned j = 0; j < g->len; j++) {
            float *r = g->table + j * TVPAL_TABLE_ENTRIES;
            r[b] = (float)((wa * r[a] + wb * r[b]) / (wa + wb));
        }
        cnt[b] += cnt[a];
        cnt[a] = 0;
        for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++)
            if (to[i] == a)
                to[i] = (uint8_t)b;
    }
    for (uint32_t k = 0; k < g->n; k++)
        g->code[k] = to[g->code[k]];
    g->used = g->share;
}

/* Places group g's codes at free indices (taken[] marks those in use,
 * *next the lowest candidate): its table rows go there, NaN at the
 * timesteps it misses, and its voxels' indices are set. */
static void missing_place(const struct missing_ws *m,
                          const struct missing_group *g, unsigned len,
                          uint8_t *taken, unsigned *next, uint8_t *idx,
                          float *table)
{
    uint8_t at[TVPAL_TABLE_ENTRIES];
    uint8_t held[TVPAL_TABLE_ENTRIES] = {0};
    for (uint32_t k = 0; k < g->n; k++)
        held[g->code[k]] = 1;
    for (unsigned c = 0; c < TVPAL_TABLE_ENTRIES; c++) {
        if (!held[c])
            continue;
        while (taken[*next])
            (*next)++;
        const unsigned i = *next;
        taken[i] = 1;
        at[c] = (uint8_t)i;
        for (unsigned j = 0, jp = 0; j < len; j++)
            table[j * TVPAL_TABLE_ENTRIES + i] =
                (g->mask >> j & 1) ? NAN
                                   : g->table[jp++ * TVPAL_TABLE_ENTRIES + c];
    }
    for (uint32_t k = 0; k < g->n; k++)
        idx[m->mv[g->start + k].v] = at[g->code[k]];
}

/* The finite voxels as group 0 (when there are any), coded into table. */
static int missing_code_finite(struct tvpal_swenc *e, const float *samples,
                               size_t nvox, unsigned len, size_t nf,
                               float *table, uint8_t *bits)
{
    struct missing_ws *m = e->miss;
    m->ngrp = 0;
    if (!nf) {
        for (size_t i = 0; i < (size_t)len * TVPAL_TABLE_ENTRIES; i++)
            table[i] = NAN;
        return 0;
    }
    for (unsigned j = 0; j < len; j++) {
        const float *row = samples + (size_t)j * nvox;
        float *dst = m->samples + (size_t)j * nf;
        for (size_t v = 0, k = 0; v < nvox; v++)
            if (!m->mask[v])
                dst[k++] = row[v];
    }
    struct missing_group *g = &m->grp[m->ngrp++];
    *g = (struct missing_group){.n = (uint32_t)nf, .code = m->fidx,
                                .table = table, .len = len};
    return encode_finite(e, m->samples, nf, len, m->fidx, table, bits,
                         &g->used);
}

static int encode_missing(struct tvpal_swenc *e, const float *samples,
                          size_t nvox, unsigned len, uint8_t *idx,
                          float *table, struct tvpal_swinfo *info)
{
    int rc = missing_ws_get(e);
    if (rc < 0)
        return rc;
    struct missing_ws *m = e->miss;
    size_t nmiss;
    uint64_t nsamples, dropped = 0;
    uint8_t bits[TVPAL_NMAX] = {0};
    const size_t nf = missing_scan(m, samples, nvox, len, &nmiss, &nsamples);
    if ((rc = missing_code_finite(e, samples, nvox, len, nf, table, bits)) < 0)
        return rc;
    const int has_finite = m->ngrp == 1;
    int full;
    missing_patterns(m, nmiss, len, &full, &dropped);
    unsigned demand = full;
    for (size_t g = 0; g < m->ngrp; g++) {
        struct missing_group *gr = &m->grp[g];
        if (g >= (size_t)has_finite) {
            gr->table = m->ptables + (g - has_finite) * TVPAL_TABLE_ENTRIES *
                                         (size_t)len;
            if ((rc = missing_code_pattern(e, samples, nvox, len, gr)) < 0)
                return rc;
        }
        demand += gr->used;
    }
    if (demand > TVPAL_TABLE_ENTRIES) {
        missing_share(m->grp, m->ngrp, TVPAL_TABLE_ENTRIES - full);
        for (size_t g = 0; g < m->ngrp; g++)
            if (m->grp[g].used > m->grp[g].share)
                missing_merge_down(&m->grp[g]);
    }
    /* The finite voxels keep their indices; the others take free ones. */
    uint8_t taken[TVPAL_TABLE_ENTRIES] = {0};
    for (size_t v = 0, k = 0; v < nvox && has_finite; v++)
        if (!m->mask[v])
            taken[idx[v] = m->fidx[k++]] = 1;
    unsigned next = 0;
    const uint32_t all = (1u << len) - 1;
    if (full) {
        while (taken[next])
            next++;
        taken[next] = 1;
        for (unsigned j = 0; j < len; j++)
            table[j * TVPAL_TABLE_ENTRIES + next] = NAN;
        for (size_t q = 0; q < nmiss; q++)
            if (m->mv[q].mask == all)
                idx[m->mv[q].v] = (uint8_t)next;
    }
    for (size_t g = (size_t)has_finite; g < m->ngrp; g++)
        missing_place(m, &m->grp[g], len, taken, &next, idx, table);
    if (info) {
        memset(info, 0, sizeof *info);
        memcpy(info->bits, bits, len);
        for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++)
            info->used += taken[i];
        info->missing = nsamples;
        info->dropped = dropped;
    }
    return 0;
}

int tvpal_swenc_encode(struct tvpal_swenc *e, const float *samples,
                       size_t nvox, unsigned len, uint8_t *idx, float *table,
                       struct tvpal_swinfo *info)
{
    if (len < 1 || len > e->max_len || nvox > e->max_vox)
        return TVPAL_E_INVAL;
    if (has_nan(samples, nvox * len))
        return encode_missing(e, samples, nvox, len, idx, table, info);
    uint8_t bits[TVPAL_NMAX] = {0};
    unsigned used;
    int rc = encode_finite(e, samples, nvox, len, idx, table, bits, &used);
    if (rc < 0)
        return rc;
    if (info) {
        memset(info, 0, sizeof *info);
        memcpy(info->bits, bits, len);
        info->used = used;
    }
    return 0;
}

int tvpal_swenc_set_refine(struct tvpal_swenc *e, unsigned iterations)
{
    if (iterations > TVPAL_REFINE_MAX)
        return TVPAL_E_INVAL;
    if (iterations && !e->xd) {
        e->xd = malloc((e->max_vox ? e->max_vox : 1) * e->max_len *
                       sizeof *e->xd);
        if (!e->xd)
            return TVPAL_E_NOMEM;
    }
    if (iterations && !e->idx2) {   /* the k-means++ start's code */
        e->idx2 = malloc(e->max_vox ? e->max_vox : 1);
        e->table2 = malloc(sizeof(float) * e->max_len * TVPAL_TABLE_ENTRIES);
        if (!e->idx2 || !e->table2)
            return TVPAL_E_NOMEM;
    }
    e->refine = iterations;
    return 0;
}

void tvpal_swenc_set_kpp(struct tvpal_swenc *e, int on)
{
    e->no_kpp = !on;
}

uint64_t tvpal_swenc_kpp_kept(const struct tvpal_swenc *e)
{
    return e->kpp_won;
}

void tvpal_swenc_set_naive(struct tvpal_swenc *e, int naive)
{
    e->naive = naive;
}

int tvpal_swenc_set_alloc_mse(struct tvpal_swenc *e, int on)
{
    if (on && !e->idx2) {
        e->idx2 = malloc(e->max_vox ? e->max_vox : 1);
        e->table2 = malloc(sizeof(float) * e->max_len * TVPAL_TABLE_ENTRIES);
        if (!e->idx2 || !e->table2)
            return TVPAL_E_NOMEM;
    }
    e->alloc_mse = on;
    return 0;
}

int tvpal_swenc_set_klt(struct tvpal_swenc *e, int klt)
{
    if (klt && !tvpal_eig_available())
        return TVPAL_E_SYS;
    if (klt && !e->idx2) {
        e->idx2 = malloc(e->max_vox ? e->max_vox : 1);
        e->table2 = malloc(sizeof(float) * e->max_len * TVPAL_TABLE_ENTRIES);
        if (!e->idx2 || !e->table2)
            return TVPAL_E_NOMEM;
    }
    e->klt = klt;
    return 0;
}

unsigned tvpal_swenc_refine_sse(const struct tvpal_swenc *e, double *sse)
{
    memcpy(sse, e->sse, e->nsse * sizeof *sse);
    return e->nsse;
}
