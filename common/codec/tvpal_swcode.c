/* tvpal_swcode.c: slice-window encoder (see tvpal_swcode.h). */
#include "tvpal_swcode.h"
#include "tvpal_bitalloc.h"
#include "tvpal_eig.h"
#include "tvpal_error.h"
#include "tvpal_quant.h"

#include <stdlib.h>
#include <string.h>

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

void tvpal_swenc_free(struct tvpal_swenc *e)
{
    if (!e)
        return;
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
                  unsigned len, uint8_t *idx, float *table)
{
    const unsigned L = len, K = TVPAL_TABLE_ENTRIES;
    double *xd = e->xd;
    if (!xd)
        return TVPAL_E_INVAL;
    /* Voxel vectors in the DCT domain, voxel-major. */
    for (size_t v = 0; v < nvox; v++) {
        double x[TVPAL_NMAX];
        for (unsigned j = 0; j < L; j++)
            x[j] = samples[(size_t)j * nvox + v];
        tvpal_dct_forward(L, x, xd + v * L);
    }
    e->sse[0] = code_sse(samples, nvox, len, idx, table);
    e->nsse = 1;
    for (unsigned it = 0; it < e->refine; it++) {
        for (unsigned i = 0; i < K; i++) {
            double c[TVPAL_NMAX];
            for (unsigned j = 0; j < L; j++)
                c[j] = table[j * K + i];
            tvpal_dct_forward(L, c, e->cd[i]);
            e->ord[i] = i;
        }
        /* Insertion sort by cd0 (ties by index): 256 entries, mostly
         * ordered already after the first iteration. */
        for (unsigned a = 1; a < K; a++) {
            unsigned key = e->ord[a], b = a;
            while (b > 0 && cmp_cd0(e, e->ord[b - 1], key) > 0) {
                e->ord[b] = e->ord[b - 1];
                b--;
            }
            e->ord[b] = key;
        }
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
            unsigned lo = 0, hi = K;
            while (lo < hi) {
                unsigned mid = (lo + hi) / 2;
                if (e->cd[e->ord[mid]][0] < x[0])
                    lo = mid + 1;
                else
                    hi = mid;
            }
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
        double s[4] = {0}, q[4] = {0};
        size_t v = 0;
        for (; v + 4 <= nvox; v += 4)
            for (int l = 0; l < 4; l++) {
                double d = (double)c[v + l] - k;
                s[l] += d;
                q[l] += d * d;
            }
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

/* Decoder table: per-index means of the original samples; returns the
 * number of indices used. */
static unsigned table_build(struct tvpal_swenc *e, const float *samples,
                            size_t nvox, unsigned len, const uint8_t *idx,
                            const uint8_t *bits, const double *mean,
                            float *table)
{
    memset(e->cnt, 0, sizeof e->cnt);
    memset(e->sums, 0, TVPAL_TABLE_ENTRIES * len * sizeof *e->sums);
    for (size_t v = 0; v < nvox; v++) {
        unsigned i = idx[v];
        double *s = e->sums + (size_t)i * len;
        e->cnt[i]++;
        for (unsigned j = 0; j < len; j++)
            s[j] += samples[(size_t)j * nvox + v];
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

int tvpal_swenc_encode(struct tvpal_swenc *e, const float *samples,
                       size_t nvox, unsigned len, uint8_t *idx, float *table,
                       struct tvpal_swinfo *info)
{
    if (len < 1 || len > e->max_len || nvox > e->max_vox)
        return TVPAL_E_INVAL;
    uint8_t bits[TVPAL_NMAX];
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
        uint8_t bits2[TVPAL_NMAX];
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
        rc = refine(e, samples, nvox, len, idx, table);
        if (rc < 0)
            return rc;
        used = 0;
        for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++)
            used += e->cnt[i] > 0;
    }
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
    e->refine = iterations;
    return 0;
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
