/* tvpal_swcode.c: slice-window encoder (see tvpal_swcode.h). */
#include "tvpal_swcode.h"
#include "tvpal_bitalloc.h"
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
    free(e->coef);
    free(e->sums);
    tvpal_quantws_free(e->qws);
    free(e);
}

int tvpal_swenc_encode(struct tvpal_swenc *e, const float *samples,
                       size_t nvox, unsigned len, uint8_t *idx, float *table,
                       struct tvpal_swinfo *info)
{
    if (len < 1 || len > e->max_len || nvox > e->max_vox)
        return TVPAL_E_INVAL;

    double mean[TVPAL_NMAX], var_u[TVPAL_NMAX];
    uint8_t bits[TVPAL_NMAX];

    tvpal_dct_forward_f(len, samples, e->coef, nvox, nvox);
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
    tvpal_bitalloc_variance(var_u, len, TVPAL_INDEX_BITS, bits);

    memset(idx, 0, nvox);
    for (unsigned u = 0; u < len; u++) {
        e->nlevels[u] = 0;
        if (!bits[u])
            continue;
        const float *c = e->coef + (size_t)u * nvox;
        tvpal_quantws_load(e->qws, c, nvox);
        tvpal_quant_fit_lloyd(e->qws, 1u << bits[u], &e->q);
        e->nlevels[u] = e->q.nlevels;
        memcpy(e->levels[u], e->q.level, e->q.nlevels * sizeof(double));
        tvpal_qcoder_init(&e->coder, &e->q, bits[u]);
        tvpal_qcoder_pack(&e->coder, c, nvox, idx);
    }

    /* Decoder table: per-index means of the original samples. */
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
        if (e->cnt[i]) {
            used++;
            double inv = 1.0 / (double)e->cnt[i];
            for (unsigned j = 0; j < len; j++)
                table[j * TVPAL_TABLE_ENTRIES + i] =
                    (float)(e->sums[(size_t)i * len + j] * inv);
            continue;
        }
        /* Unused index: unpack its codes, dequantize, inverse DCT. */
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
        tvpal_dct_inverse(len, co, val);
        for (unsigned j = 0; j < len; j++)
            table[j * TVPAL_TABLE_ENTRIES + i] = (float)val[j];
    }
    if (info) {
        memset(info, 0, sizeof *info);
        memcpy(info->bits, bits, len);
        info->used = used;
    }
    return 0;
}
