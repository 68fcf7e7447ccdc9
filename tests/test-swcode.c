/* test-swcode: one slice-window: the decoder table holds, for every used
 * index and timestep, the mean of the original samples of the voxels with
 * that index; unused entries are finite; constant and two-valued slices are
 * exact; N = 1 is the plain 8-bit Lloyd-Max code; deterministic.  Missing
 * values (NaN samples) decode as NaN exactly where they were, whatever
 * their pattern in time, also when the finite code uses every index. */
#include "tvpal_dct.h"
#include "tvpal_error.h"
#include "tvpal_swcode.h"
#include "tvpal_test.h"

#include <string.h>

#define W 61
#define H 37
#define NV (W * H)

static float samples[TVPAL_NMAX * NV];
static uint8_t idx[NV], idx2[NV];
static float table[TVPAL_NMAX * 256], table2[TVPAL_NMAX * 256];

static double recon_mse(unsigned len)
{
    double e = 0;
    for (unsigned j = 0; j < len; j++)
        for (size_t v = 0; v < NV; v++) {
            double d = table[j * 256 + idx[v]] - samples[j * NV + v];
            e += d * d;
        }
    return e / ((double)len * NV);
}

/* Checks the code of the current samples: a decoded entry is NaN exactly
 * where the sample is, except for `dropped` present samples; returns the
 * PSNR (peak 20) of the present samples decoded finite. */
static double check_missing(unsigned len, const struct tvpal_swinfo *info,
                            const char *what)
{
    uint64_t nan_src = 0, extra = 0, lost = 0;
    double e = 0;
    size_t n = 0;
    for (unsigned j = 0; j < len; j++)
        for (size_t v = 0; v < NV; v++) {
            float s = samples[j * NV + v], d = table[j * 256 + idx[v]];
            nan_src += isnan(s);
            if (isnan(s) && !isnan(d))
                lost++;
            if (!isnan(s) && isnan(d))
                extra++;
            if (!isnan(s) && !isnan(d)) {
                e += (double)(d - s) * (d - s);
                n++;
            }
        }
    CHECK(lost == 0, "%s: %llu missing samples decode finite", what,
          (unsigned long long)lost);
    CHECK(extra == info->dropped, "%s: %llu present samples decode NaN, "
          "info says %llu dropped", what, (unsigned long long)extra,
          (unsigned long long)info->dropped);
    CHECK(info->missing == nan_src, "%s: info counts %llu missing of %llu",
          what, (unsigned long long)info->missing,
          (unsigned long long)nan_src);
    return n ? 10 * log10(400.0 / (e / (double)n)) : INFINITY;
}

static void smooth(unsigned len, double noise)
{
    for (unsigned j = 0; j < len; j++)
        for (size_t v = 0; v < NV; v++) {
            double a = (double)(v % W) / W, b = (double)(v / W) / H;
            samples[j * NV + v] = (float)(10 * sin(4 * a + 0.3 * j) *
                                              cos(3 * b - 0.2 * j) +
                                          noise * tt_gauss() + 100);
        }
}

/* PSNR (peak 20) over the samples `mask_src` has present, of the code of
 * `full` (the same field with nothing missing). */
static float ref_samples[TVPAL_NMAX * NV];
static double ref_psnr(struct tvpal_swenc *e, unsigned len)
{
    memcpy(ref_samples, samples, sizeof samples);
    for (size_t i = 0; i < (size_t)len * NV; i++)
        if (isnan(ref_samples[i]))
            ref_samples[i] = 100; /* any finite value */
    tvpal_swenc_encode(e, ref_samples, NV, len, idx2, table2, NULL);
    double err = 0;
    size_t n = 0;
    for (unsigned j = 0; j < len; j++)
        for (size_t v = 0; v < NV; v++) {
            if (isnan(samples[j * NV + v]))
                continue;
            double d = table2[j * 256 + idx2[v]] - samples[j * NV + v];
            err += d * d;
            n++;
        }
    return 10 * log10(400.0 / (err / (double)n));
}

static void test_missing(struct tvpal_swenc *e)
{
    struct tvpal_swinfo info;
    /* A land mask (missing throughout), a region missing at steps 1 and 2
     * only, and values beyond a valid range here and there. */
    const unsigned len = 4;
    smooth(len, 0.05);
    for (size_t v = 0; v < NV; v++) {
        size_t x = v % W, y = v / W;
        for (unsigned j = 0; j < len; j++) {
            float *s = &samples[j * NV + v];
            if (x < 10 && y < 12)
                *s = NAN;
            if (x > 40 && y > 20 && (j == 1 || j == 2))
                *s = NAN;
            if ((v * 7 + j * 13) % 101 == 0)
                *s = NAN;
        }
    }
    CHECK(tvpal_swenc_encode(e, samples, NV, len, idx, table, &info) == 0,
          "encode with missing");
    double p = check_missing(len, &info, "mask"), r = ref_psnr(e, len);
    printf("missing mask: present samples %.2f dB (filled in: %.2f dB)\n",
           p, r);
    CHECK(p > r - 1, "mask: present samples at %.2f dB, filled %.2f", p, r);
    CHECK(info.dropped == 0, "mask: nothing dropped");
    tvpal_swenc_encode(e, samples, NV, len, idx2, table2, NULL);
    CHECK(!memcmp(idx, idx2, NV) && !memcmp(table, table2, len * 1024),
          "missing: deterministic");

    /* Noise fills all 256 indices: missing voxels get merged ones. */
    smooth(8, 3.0);
    for (size_t v = 0; v < NV; v += 17)
        samples[(v % 8) * NV + v] = NAN;
    for (size_t v = 0; v < 40; v++)
        for (unsigned j = 0; j < 8; j++)
            samples[j * NV + v] = NAN;
    tvpal_swenc_encode(e, samples, NV, 8, idx, table, &info);
    p = check_missing(8, &info, "merge");
    r = ref_psnr(e, 8);
    printf("missing merge: used %u, present samples %.2f dB (filled in: "
           "%.2f dB)\n", info.used, p, r);
    CHECK(p > r - 1, "merge: present samples at %.2f dB, filled %.2f", p, r);

    /* Every voxel missing: a table of NaN. */
    for (size_t i = 0; i < (size_t)len * NV; i++)
        samples[i] = NAN;
    tvpal_swenc_encode(e, samples, NV, len, idx, table, &info);
    check_missing(len, &info, "all missing");
    int all = 1;
    for (unsigned i = 0; i < len * 256; i++)
        all &= isnan(table[i]);
    CHECK(all && info.used == 1, "all missing: NaN table, one index (%u)",
          info.used);

    /* N = 16 with a random pattern per voxel: more patterns than indices,
     * the rare ones dropped and counted. */
    smooth(16, 0.05);
    for (size_t v = 0; v < NV; v++)
        for (unsigned j = 0; j < 16; j++)
            if (tt_rand64() % 4 == 0)
                samples[j * NV + v] = NAN;
    tvpal_swenc_encode(e, samples, NV, 16, idx, table, &info);
    check_missing(16, &info, "patterns");
    CHECK(info.dropped > 0, "patterns: some dropped");

    /* With refinement and the KLT the finite part is refined alone. */
    tvpal_swenc_set_refine(e, 4);
    smooth(len, 0.05);
    for (size_t v = 0; v < NV; v += 3)
        samples[2 * NV + v] = NAN;
    tvpal_swenc_encode(e, samples, NV, len, idx, table, &info);
    p = check_missing(len, &info, "refine");
    r = ref_psnr(e, len);
    printf("missing refine: present samples %.2f dB (filled in: %.2f dB)\n",
           p, r);
    CHECK(p > r - 1, "refine: present samples at %.2f dB, filled %.2f", p, r);
    tvpal_swenc_set_refine(e, 0);
}

int main(void)
{
    struct tvpal_swenc *e;
    REQUIRE(tvpal_swenc_create(&e, NV, TVPAL_NMAX) == 0, "create");
    struct tvpal_swinfo info;

    for (unsigned len = 1; len <= TVPAL_NMAX; len++) {
        /* Smooth field moving in time plus a little noise. */
        for (unsigned j = 0; j < len; j++)
            for (size_t v = 0; v < NV; v++) {
                double a = (double)(v % W) / W, b = (double)(v / W) / H;
                samples[j * NV + v] = (float)(10 * sin(4 * a + 0.3 * j) *
                                                  cos(3 * b - 0.2 * j) +
                                              0.05 * tt_gauss() + 100);
            }
        REQUIRE(tvpal_swenc_encode(e, samples, NV, len, idx, table, &info) == 0,
                "encode len %u", len);
        unsigned sum = 0;
        for (unsigned u = 0; u < len; u++)
            sum += info.bits[u];
        CHECK(sum == 8, "len %u: bits sum %u", len, sum);
        /* Table semantics. */
        static double s[256][TVPAL_NMAX];
        static size_t cnt[256];
        memset(s, 0, sizeof s);
        memset(cnt, 0, sizeof cnt);
        for (size_t v = 0; v < NV; v++) {
            cnt[idx[v]]++;
            for (unsigned j = 0; j < len; j++)
                s[idx[v]][j] += samples[j * NV + v];
        }
        unsigned used = 0;
        for (unsigned i = 0; i < 256; i++) {
            used += cnt[i] > 0;
            for (unsigned j = 0; j < len; j++) {
                float t = table[j * 256 + i];
                CHECK(isfinite(t), "len %u entry %u,%u finite", len, i, j);
                if (cnt[i])
                    CHECK(fabs(t - s[i][j] / cnt[i]) <= 1e-5 * (1 + fabs(t)),
                          "len %u index %u step %u: %g vs mean %g", len, i, j,
                          t, s[i][j] / cnt[i]);
                else
                    CHECK(t > 80 && t < 120, "unused entry %g out of range",
                          t);
            }
        }
        CHECK(used == info.used, "used count %u vs %u", used, info.used);
        double mse = recon_mse(len);
        double psnr = 10 * log10(20.0 * 20.0 / mse);
        /* 8 bits for len samples: accuracy falls with len but stays usable
         * on smooth data: floor 38 dB minus 3 dB per doubling of the window
         * (measured: 60 dB at len 1, 34.7 at 4, 30.7 at 8, 27.5 at 16). */
        double floor_db = 38.0 - 3.0 * log2((double)len);
        CHECK(psnr >= floor_db, "len %u: psnr %.2f < %.2f", len, psnr,
              floor_db);
        printf("len %2u: bits", len);
        for (unsigned u = 0; u < len; u++)
            printf(" %u", info.bits[u]);
        printf("  used %3u  psnr %.2f dB\n", info.used, psnr);
        /* Determinism. */
        tvpal_swenc_encode(e, samples, NV, len, idx2, table2, NULL);
        CHECK(!memcmp(idx, idx2, NV) && !memcmp(table, table2, len * 1024),
              "len %u: not deterministic", len);
    }

    /* Constant slice-window: exact, all voxels share index 0. */
    for (size_t i = 0; i < 8 * NV; i++)
        samples[i] = -3.75f;
    tvpal_swenc_encode(e, samples, NV, 8, idx, table, &info);
    CHECK(recon_mse(8) == 0, "constant exact");
    CHECK(info.used == 1 && idx[0] == 0, "constant: one index");
    /* Constant in time, varying in space with 2 values: exact. */
    for (unsigned j = 0; j < 4; j++)
        for (size_t v = 0; v < NV; v++)
            samples[j * NV + v] = (v % 7 == 0) ? 5.0f : 1e-3f;
    tvpal_swenc_encode(e, samples, NV, 4, idx, table, &info);
    CHECK(recon_mse(4) == 0, "two-valued exact: mse %g", recon_mse(4));
    /* A single outlier voxel: finite, and the rest stays accurate. */
    for (unsigned j = 0; j < 4; j++)
        for (size_t v = 0; v < NV; v++)
            samples[j * NV + v] = (float)(v % 100) * 0.01f + 0.1f * j;
    samples[2 * NV + 500] = 1e30f;
    tvpal_swenc_encode(e, samples, NV, 4, idx, table, &info);
    for (unsigned i = 0; i < 4 * 256; i++)
        CHECK(isfinite(table[i]), "outlier: finite table");
    /* N = 1 reduces to the 8-bit Lloyd-Max code of the values. */
    for (size_t v = 0; v < NV; v++)
        samples[v] = (float)tt_gauss();
    tvpal_swenc_encode(e, samples, NV, 1, idx, table, &info);
    CHECK(info.bits[0] == 8, "N=1: 8 bits");
    CHECK(10 * log10(1.0 / recon_mse(1)) > 35, "N=1 gaussian SNR %.2f",
          10 * log10(1.0 / recon_mse(1)));
    CHECK(tvpal_swenc_encode(e, samples, NV + 1, 1, idx, table, NULL) ==
              TVPAL_E_INVAL, "capacity");

    /* --refine: each generalized-Lloyd iteration can only lower the
     * distortion; the result is deterministic and the table still holds
     * the per-index means. */
    REQUIRE(tvpal_swenc_set_refine(e, 12) == 0, "set refine");
    CHECK(tvpal_swenc_set_refine(e, TVPAL_REFINE_MAX + 1) == TVPAL_E_INVAL,
          "refine bound");
    for (unsigned len = 2; len <= 8; len *= 2) {
        for (unsigned j = 0; j < len; j++)
            for (size_t v = 0; v < NV; v++) {
                double a = (double)(v % W) / W, b = (double)(v / W) / H;
                samples[j * NV + v] = (float)(10 * sin(7 * a + 0.5 * j) *
                                              cos(5 * b - 0.4 * j) +
                                              tt_gauss());
            }
        tvpal_swenc_encode(e, samples, NV, len, idx, table, NULL);
        double sse[TVPAL_REFINE_MAX + 1];
        unsigned n = tvpal_swenc_refine_sse(e, sse);
        CHECK(n >= 2, "len %u: %u refine steps", len, n);
        for (unsigned k = 1; k < n; k++)
            CHECK(sse[k] <= sse[k - 1] * (1 + 1e-12), "len %u: iteration %u "
                  "raised the error %.9g -> %.9g", len, k, sse[k - 1], sse[k]);
        CHECK(fabs(recon_mse(len) * len * NV - sse[n - 1]) <=
                  1e-6 * sse[n - 1], "final error matches the table");
        printf("refine len %u: %u steps, error %.4g -> %.4g (%.2f dB)\n", len,
               n - 1, sse[0], sse[n - 1], 10 * log10(sse[0] / sse[n - 1]));
        CHECK(sse[n - 1] < sse[0], "refinement gains");
        tvpal_swenc_encode(e, samples, NV, len, idx2, table2, NULL);
        CHECK(!memcmp(idx, idx2, NV) && !memcmp(table, table2, len * 1024),
              "refine deterministic");
    }
    /* The k-means++ start: voxels drawn from 200 prototype time series
     * (random, wide apart) with a little noise, which 256 codewords can
     * hold but the DCT code's product of per-coefficient quantizers
     * cannot: the k-means++ start wins its race, and the error ends far
     * below the DCT start's alone. */
    REQUIRE(tvpal_swenc_set_refine(e, 5) == 0, "set refine");
    for (unsigned len = 4; len <= 8; len *= 2) {
        static float proto[200][TVPAL_NMAX];
        for (unsigned k = 0; k < 200; k++)
            for (unsigned j = 0; j < len; j++)
                proto[k][j] = (float)(20 * tt_gauss());
        for (size_t v = 0; v < NV; v++) {
            const unsigned k = (unsigned)(tt_rand64() % 200);
            for (unsigned j = 0; j < len; j++)
                samples[j * NV + v] = proto[k][j] + (float)(0.01 * tt_gauss());
        }
        double both[TVPAL_REFINE_MAX + 1], dct[TVPAL_REFINE_MAX + 1];
        const uint64_t won = tvpal_swenc_kpp_kept(e);
        tvpal_swenc_encode(e, samples, NV, len, idx, table, NULL);
        unsigned nb = tvpal_swenc_refine_sse(e, both);
        const int kept = tvpal_swenc_kpp_kept(e) > won;
        tvpal_swenc_set_kpp(e, 0);
        tvpal_swenc_encode(e, samples, NV, len, idx2, table2, NULL);
        unsigned nd = tvpal_swenc_refine_sse(e, dct);
        tvpal_swenc_set_kpp(e, 1);
        printf("k-means++ len %u: error %.4g, from the DCT code alone %.4g\n",
               len, both[nb - 1], dct[nd - 1]);
        CHECK(nb && nd && kept && both[nb - 1] < 0.5 * dct[nd - 1],
              "len %u: k-means++ start %.4g (kept %d) against %.4g", len,
              both[nb - 1], kept, dct[nd - 1]);
        CHECK(fabs(recon_mse(len) * len * NV - both[nb - 1]) <=
                  1e-6 * both[nb - 1], "len %u: the kept code's table", len);
        /* The refined codewords are numbered by their mean over the
         * window (so that neighbouring voxels of similar values get near
         * indices, which coded chunks store in fewer bytes). */
        int ordered = 1;
        double prev = -INFINITY;
        for (unsigned i = 0; i < 256; i++) {
            double m = 0;
            for (unsigned j = 0; j < len; j++)
                m += table[j * 256 + i];
            ordered &= m >= prev;
            prev = m;
        }
        CHECK(ordered, "len %u: refined codewords not in order of their "
              "means", len);
    }
    /* A smooth field: not worse than the DCT start alone run to the end
     * (the race only bounds it by that start's error after two
     * iterations, so this is a check on data). */
    for (unsigned len = 2; len <= 8; len *= 2) {
        smooth(len, 0.5);
        double both[TVPAL_REFINE_MAX + 1], dct[TVPAL_REFINE_MAX + 1];
        tvpal_swenc_encode(e, samples, NV, len, idx, table, NULL);
        unsigned nb = tvpal_swenc_refine_sse(e, both);
        tvpal_swenc_set_kpp(e, 0);
        tvpal_swenc_encode(e, samples, NV, len, idx2, table2, NULL);
        unsigned nd = tvpal_swenc_refine_sse(e, dct);
        tvpal_swenc_set_kpp(e, 1);
        CHECK(nb && nd && both[nb - 1] <= dct[nd - 1], "smooth len %u: %.6g "
              "against the DCT start's %.6g", len, both[nb - 1], dct[nd - 1]);
    }
    tvpal_swenc_set_refine(e, 0);
    test_missing(e);
    tvpal_swenc_free(e);
    tvpal_swenc_free(NULL);
    return tt_done("test-swcode");
}
