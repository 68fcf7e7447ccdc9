/* test-quant: Lloyd-Max meets the nearest-neighbour and centroid conditions,
 * is never worse than the uniform quantizer with the same levels (on many
 * distributions, including heavy tails and 256 levels on a 64x64 slice),
 * handles degenerate inputs exactly, and is deterministic; the fast coder
 * agrees with the reference coder. */
#include "tvpal_error.h"
#include "tvpal_quant.h"
#include "tvpal_test.h"

#include <float.h>
#include <string.h>

#define NMAX 65536

static float x[NMAX];
static struct tvpal_quantws *ws;

enum dist { D_UNIFORM, D_GAUSS, D_LAPLACE, D_CAUCHY, D_BIMODAL, D_EXP,
            D_DISCRETE, D_SPIKE, D_COUNT };
static const char *dist_name[] = {"uniform", "gauss", "laplace", "cauchy",
                                  "bimodal", "exp", "discrete", "spike"};

static void fill(enum dist d, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        double v;
        switch (d) {
        case D_UNIFORM: v = tt_uniform() * 10 - 3; break;
        case D_GAUSS: v = 1000 + tt_gauss(); break; /* large offset */
        case D_LAPLACE: {
            double u = tt_uniform() - 0.5;
            v = (u < 0 ? 1 : -1) * log(1 - 2 * fabs(u));
            break;
        }
        case D_CAUCHY: v = tan(M_PI * (tt_uniform() - 0.5)); break;
        case D_BIMODAL: v = (tt_uniform() < 0.7 ? -5 : 5) + 0.3 * tt_gauss(); break;
        case D_EXP: v = -log(1 - tt_uniform()); break;
        case D_DISCRETE: v = (double)(tt_rand64() % 300); break;
        default: v = (i % 997 == 0) ? 1e6 : tt_gauss(); break; /* outliers */
        }
        if (v > 1e30) v = 1e30;
        if (v < -1e30) v = -1e30;
        x[i] = (float)v;
    }
}

/* NN: each sample's code is a nearest level (ties either way). Centroid:
 * each non-empty cell's level is within 0.5% of its width of the cell
 * mean: Lloyd stops when an iteration gains less than 1e-6 relative, which
 * leaves the levels that close to the fixed point.  The cells' counts are
 * those of the sorted samples, so a bad sort fails here. */
static void check_conditions(const struct tvpal_quant *q, size_t n,
                             const char *what)
{
    double lo = x[0], hi = x[0];
    for (size_t i = 0; i < n; i++) {
        lo = x[i] < lo ? x[i] : lo;
        hi = x[i] > hi ? x[i] : hi;
    }
    double span = hi - lo;
    static double sum[TVPAL_LEVELS_MAX];
    static size_t cnt[TVPAL_LEVELS_MAX];
    memset(sum, 0, sizeof sum);
    memset(cnt, 0, sizeof cnt);
    int nn_bad = 0;
    for (size_t i = 0; i < n; i++) {
        unsigned c = tvpal_quant_code(q, x[i]);
        double dc = fabs(x[i] - q->level[c]);
        for (unsigned k = 0; k < q->nlevels; k++)
            if (fabs(x[i] - q->level[k]) < dc - 1e-12 * (1 + span))
                nn_bad++;
        sum[c] += x[i];
        cnt[c]++;
    }
    CHECK(nn_bad == 0, "%s: %d samples not at a nearest level", what, nn_bad);
    for (unsigned k = 0; k < q->nlevels; k++) {
        CHECK(cnt[k] == q->count[k], "%s: count of cell %u", what, k);
        if (!cnt[k])
            continue;
        double mean = sum[k] / cnt[k];
        double w = (k + 1 < q->nlevels ? q->thresh[k] : hi) -
                   (k > 0 ? q->thresh[k - 1] : lo);
        CHECK(fabs(mean - q->level[k]) <= 5e-3 * w + 1e-9 * (1 + fabs(mean)),
              "%s: cell %u level %.9g centroid %.9g (width %g)", what, k,
              q->level[k], mean, w);
    }
}

static struct tvpal_quant q, qu, q2;

int main(void)
{
    REQUIRE(tvpal_quantws_create(&ws, NMAX) == 0, "workspace");

    /* Never worse than uniform, many distributions, sizes and levels
     * (4096 samples sort with 11-bit digits, 65536 with 16-bit ones). */
    static const size_t sizes[] = {1000, 4096, 65536};
    static const unsigned levels[] = {2, 4, 16, 64, 256};
    for (int d = 0; d < D_COUNT; d++)
        for (size_t si = 0; si < 3; si++)
            for (size_t li = 0; li < 5; li++) {
                size_t n = sizes[si];
                unsigned L = levels[li];
                char what[96];
                snprintf(what, sizeof what, "%s n=%zu L=%u", dist_name[d], n, L);
                fill((enum dist)d, n);
                REQUIRE(tvpal_quantws_load(ws, x, n) == 0, "load");
                tvpal_quant_fit_lloyd(ws, L, &q);
                tvpal_quant_fit_uniform(ws, L, &qu);
                double ml = tvpal_quant_mse(&q, x, n);
                double mu = tvpal_quant_mse(&qu, x, n);
                CHECK(ml <= mu * (1 + 1e-9) + 1e-30,
                      "%s: lloyd mse %.6g > uniform %.6g", what, ml, mu);
                CHECK(fabs(ml - q.mse) <= 1e-6 * ml + 1e-20,
                      "%s: reported mse %.9g vs direct %.9g", what, q.mse, ml);
                if (L <= 16 && d != D_CAUCHY && d != D_SPIKE)
                    check_conditions(&q, n, what);
                /* Deterministic. */
                tvpal_quant_fit_lloyd(ws, L, &q2);
                CHECK(!memcmp(q.level, q2.level, L * sizeof(double)),
                      "%s: not deterministic", what);
                /* Fast coder agrees with the reference coder. */
                unsigned bits = 0;
                while ((1u << bits) < L)
                    bits++;
                struct tvpal_qcoder c;
                tvpal_qcoder_init(&c, &q, bits);
                static uint8_t idx[NMAX];
                memset(idx, 0, n);
                tvpal_qcoder_pack(&c, x, n, idx);
                /* Float thresholds may send a sample lying within an ulp of
                 * a midpoint to the other neighbour: allow 2 ulps. */
                size_t mism = 0;
                for (size_t i = 0; i < n; i++) {
                    double dfast = fabs(q.level[idx[i]] - x[i]);
                    double dref =
                        fabs(q.level[tvpal_quant_code(&q, x[i])] - x[i]);
                    mism += dfast > dref + 2 * FLT_EPSILON * fabs(x[i]) + 1e-30;
                }
                CHECK(mism == 0, "%s: %zu fast codes farther than reference",
                      what, mism);
                /* pack (counting for the high bits) and the binary search
                 * of tvpal_qcoder_code give the same codes, exactly. */
                size_t pdiff = 0;
                for (size_t i = 0; i < n; i++)
                    pdiff += idx[i] != tvpal_qcoder_code(&c, x[i]);
                CHECK(pdiff == 0, "%s: %zu packed codes differ from "
                      "tvpal_qcoder_code", what, pdiff);
            }

    /* The case that breaks quantile-started Lloyd: 256 levels on a 64x64
     * slice of smooth data.  Ours must not lose to uniform. */
    for (int trial = 0; trial < 5; trial++) {
        size_t n = 4096;
        for (size_t i = 0; i < n; i++) {
            double a = (double)(i % 64) / 64, b = (double)(i / 64) / 64;
            x[i] = (float)(sin(6 * a + trial) * cos(5 * b) +
                           0.01 * tt_gauss());
        }
        tvpal_quantws_load(ws, x, n);
        double start[256];
        tvpal_quant_fit_uniform(ws, 256, &qu);
        tvpal_quant_fit_lloyd(ws, 256, &q);
        /* quantile start alone */
        float sorted[4096];
        memcpy(sorted, x, sizeof sorted);
        for (size_t i = 1; i < n; i++) { /* insertion sort, small n */
            float v = sorted[i];
            size_t j = i;
            while (j > 0 && sorted[j - 1] > v) {
                sorted[j] = sorted[j - 1];
                j--;
            }
            sorted[j] = v;
        }
        for (int k = 0; k < 256; k++)
            start[k] = sorted[(2 * k + 1) * n / 512];
        tvpal_quant_fit_from(ws, start, 256, &q2);
        double ml = tvpal_quant_mse(&q, x, n), mu = tvpal_quant_mse(&qu, x, n),
               mq = tvpal_quant_mse(&q2, x, n);
        CHECK(ml <= mu * (1 + 1e-9), "64x64/256: lloyd %.4g > uniform %.4g",
              ml, mu);
        CHECK(ml <= mq * (1 + 1e-9), "64x64/256: lloyd %.4g > quantile-started "
              "%.4g", ml, mq);
        printf("64x64 slice, 256 levels: uniform %.3f dB, quantile-started "
               "Lloyd %.3f dB, ours %.3f dB (relative to uniform)\n", 0.0,
               10 * log10(mu / mq), 10 * log10(mu / ml));
    }

    /* Degenerate inputs. */
    tvpal_quantws_load(ws, x, 0);
    tvpal_quant_fit_lloyd(ws, 256, &q);
    CHECK(q.nlevels == 1 && q.mse == 0, "empty input");
    x[0] = 42.5f;
    tvpal_quantws_load(ws, x, 1);
    tvpal_quant_fit_lloyd(ws, 256, &q);
    CHECK(q.nlevels == 1 && q.level[0] == 42.5 && q.mse == 0, "one sample");
    for (size_t i = 0; i < 4096; i++)
        x[i] = -7.25f;
    tvpal_quantws_load(ws, x, 4096);
    CHECK(tvpal_quantws_distinct(ws) == 1, "distinct of constant");
    tvpal_quant_fit_lloyd(ws, 16, &q);
    CHECK(q.mse == 0 && q.level[0] == -7.25 && q.nlevels == 1, "constant");
    for (size_t i = 0; i < 4096; i++)
        x[i] = (i % 3) ? 1e-3f : 5e3f;
    tvpal_quantws_load(ws, x, 4096);
    tvpal_quant_fit_lloyd(ws, 256, &q);
    CHECK(q.mse == 0 && q.nlevels == 2, "two values, 256 levels: mse %g "
          "levels %u", q.mse, q.nlevels);
    for (size_t i = 0; i < 4096; i++)
        x[i] = (float)(i % 200) * 0.5f;
    tvpal_quantws_load(ws, x, 4096);
    tvpal_quant_fit_lloyd(ws, 256, &q);
    CHECK(q.mse == 0 && q.nlevels == 200, "200 distinct values, 256 levels");
    for (size_t i = 0; i < 4096; i++)
        CHECK(q.level[tvpal_quant_code(&q, x[i])] == x[i], "exact code");
    /* Huge dynamic range: finite and no worse than uniform. */
    for (size_t i = 0; i < 4096; i++)
        x[i] = (float)(pow(10.0, -30 + 60 * tt_uniform()) *
                       (tt_rand64() & 1 ? 1 : -1));
    tvpal_quantws_load(ws, x, 4096);
    tvpal_quant_fit_lloyd(ws, 64, &q);
    tvpal_quant_fit_uniform(ws, 64, &qu);
    CHECK(isfinite(q.mse) && q.mse <= qu.mse * (1 + 1e-9),
          "1e-30..1e30: %g vs %g", q.mse, qu.mse);
    /* Single outlier among constants. */
    for (size_t i = 0; i < 4096; i++)
        x[i] = 1.0f;
    x[1234] = 1e20f;
    tvpal_quantws_load(ws, x, 4096);
    tvpal_quant_fit_lloyd(ws, 4, &q);
    CHECK(q.mse == 0, "outlier + constant with 4 levels is exact");

    CHECK(tvpal_quantws_load(ws, x, NMAX + 1) == TVPAL_E_INVAL,
          "over capacity");
    tvpal_quantws_free(ws);
    tvpal_quantws_free(NULL);
    return tt_done("test-quant");
}
