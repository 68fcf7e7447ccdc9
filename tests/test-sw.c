/* test-sw: the shear-warp CPU renderer.
 *
 * Against the CPU reference renderer: PSNR at least 35 dB for views on
 * every axis, zoomed out and in (K = 1..4).  Tolerance: shear-warp
 * resamples twice (each slice onto the intermediate image, then the warp),
 * so it is a little blurrier than the reference's direct sampling of each
 * slice at the output pixel; 35 dB is about 2/255 RMS on [0,1] images, far
 * below what a wrong shear, order or palette would give (those land under
 * 20 dB).
 *
 * Exact (bit-identical) comparisons, within one SIMD path: 1, 2 and 3
 * threads; empty-space skipping and early termination on and off (with a
 * sparse transfer function that leaves most tiles empty and an opaque one
 * that saturates pixels); bands of 1, 7 and 32 rows composited together
 * against the default (4 to 32, from the L2 cache's size: a power of two,
 * 7 when set to 7); a TF change every frame vs a fresh renderer with that
 * TF; new slice data announced by upload vs a fresh renderer; lazily built
 * tile sets (a palette with every entry visible decides every tile with no
 * probe; a dense TF with one transparent entry decides every tile by a
 * probe, then by the index it found; tiles whose visible texels no probe
 * reads get sets, drawn as without skipping; sets kept until an upload); a
 * block of missing (NaN) values with the default transparent NaN colour vs
 * the same block transparent by the TF.  These run in --exact mode, where
 * stopping changes no bit.  The AVX2 loops (FMA) against the SSE2 loops:
 * within SIMD_TOL per channel in --exact mode (below).
 *
 * Early termination (the default, a pixel stops at transmittance 1/272):
 * over 48 random views and TFs, a third of them with opaque plateaus, no
 * 8-bit pixel differs from --exact by more than one level and no channel
 * by more than 1/272, and some channel by more than 0.9 / 272 (the bound
 * is nearly reached); the stopped-pixel maps (opaque runs skipped) against
 * a test per pixel, threads and bands of 1 and 5 rows give the same bits,
 * SSE2 against AVX2 within 1/272; each opaque TF really stops early.
 *
 * Odd shapes: one-texel-wide and one-row slices, slices wider than 64
 * tiles of 16.  Slice edges: a one-colour slice draws as that colour or
 * nothing, no partial pixel (an undrawn edge texel leaves some).  Errors: a
 * frame that does not match the prepared slices is refused; extreme views
 * (NaN, infinite, huge angles and zooms) keep the view finite and draw or
 * are refused, never undefined. */
#include "tvpal_render_ref.h"
#include "tvpal_sw.h"
#include "tvpal_test.h"

#include <string.h>

static uint8_t *idx_store;
static float *pal_store;
static struct tvpal_frame_slice *sl;

struct vol {
    uint32_t n[3];
    unsigned W, H;
    int pattern;         /* 0 radial, 1 noisy */
};

static void make_frame(const struct vol *vo, struct tvpal_view *v,
                       struct tvpal_frame *f, const struct tvpal_tf *tf)
{
    tvpal_view_setup(v);
    unsigned a = v->axis;
    uint32_t n = vo->n[a], w = a == 0 ? vo->n[1] : vo->n[0],
             h = a == 2 ? vo->n[1] : vo->n[2];
    f->view = v;
    f->w = w;
    f->h = h;
    f->count = n;
    f->sl = sl;
    uint64_t rng = 12345;
    for (uint32_t k = 0; k < n; k++) {
        uint32_t s = v->descending ? n - 1 - k : k;
        uint8_t *I = idx_store + (size_t)s * w * h;
        for (uint32_t b = 0; b < h; b++)
            for (uint32_t x = 0; x < w; x++) {
                double r = hypot((x - w / 2.0) / w, (b - h / 2.0) / h) +
                           0.3 * fabs((double)s / n - 0.5);
                double val = 255 * fmax(0, 1 - 2 * r);
                if (vo->pattern) {
                    rng = rng * 6364136223846793005ull + 1442695040888963407ull;
                    val = fmin(255, val + (double)(rng >> 58));
                }
                I[x + w * b] = (uint8_t)val;
            }
        float row[256];
        for (int i = 0; i < 256; i++)
            row[i] = (float)i / 255.0f;
        tvpal_palette_build(tf, row, tvpal_view_opacity_exponent(v), 1.0,
                            pal_store + (size_t)1024 * s);
        sl[k] = (struct tvpal_frame_slice){s, s, I, pal_store + (size_t)1024 * s};
    }
}

/* make_frame, then a box of voxels (the middle third of the volume on
 * every axis) drawn with palette entry 1 alone, whose row value is v1
 * (NaN: missing values); the voxels that had index 1 move to 2. */
static void make_block_frame(const struct vol *vo, struct tvpal_view *v,
                             struct tvpal_frame *f, const struct tvpal_tf *tf,
                             float v1)
{
    make_frame(vo, v, f, tf);
    const uint32_t n = f->count, w = f->w, h = f->h;
    for (uint32_t s = 0; s < n; s++) {
        uint8_t *I = idx_store + (size_t)s * w * h;
        for (uint32_t b = 0; b < h; b++)
            for (uint32_t x = 0; x < w; x++) {
                uint8_t *q = I + x + (size_t)w * b;
                if (*q == 1)
                    *q = 2;
                if (s >= n / 3 && s < 2 * n / 3 && x >= w / 3 &&
                    x < 2 * w / 3 && b >= h / 3 && b < 2 * h / 3)
                    *q = 1;
            }
        float row[256];
        for (int i = 0; i < 256; i++)
            row[i] = (float)i / 255.0f;
        row[1] = v1;
        tvpal_palette_build(tf, row, tvpal_view_opacity_exponent(v), 1.0,
                            pal_store + (size_t)1024 * s);
    }
}

static double psnr(const float *a, const double *b, size_t n)
{
    double e = 0;
    for (size_t i = 0; i < n; i++)
        e += (a[i] - b[i]) * (a[i] - b[i]);
    e /= (double)n;
    return e > 0 ? 10 * log10(1.0 / e) : INFINITY;
}

/* Draws f with a fresh renderer and the given options; exact: stop only
 * at alpha 1; runs: skip stopped pixels by links; band: rows composited
 * together (0: the default). */
static void draw_band_mode(const struct tvpal_frame *f, uint32_t layers,
                           int threads, int skip, int simd, int exact, int runs,
                           unsigned band, float *img)
{
    struct tvpal_sw *sw;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_sw_create(&sw) == 0, "create");
    tvpal_sw_options(sw, threads, skip, simd);
    tvpal_sw_set_exact(sw, exact);
    tvpal_sw_set_runs(sw, runs);
    REQUIRE(band == 0 || tvpal_sw_set_band(sw, band) == 0, "band %u", band);
    REQUIRE(tvpal_sw_set_slices(sw, f->w, f->h, layers, &d) == 0, "%s", d.msg);
    REQUIRE(tvpal_sw_draw(sw, f, img, &d) == 0, "%s", d.msg);
    tvpal_sw_free(sw);
}

static void draw_mode(const struct tvpal_frame *f, uint32_t layers, int threads,
                      int skip, int simd, int exact, int runs, float *img)
{
    draw_band_mode(f, layers, threads, skip, simd, exact, runs, 0, img);
}

/* The identity tests of skipping, SIMD and threads against drawing every
 * sample: with --exact, where stopping changes no bit. */
static void draw_fresh(const struct tvpal_frame *f, uint32_t layers, int threads,
                       int skip, int simd, float *img)
{
    draw_mode(f, layers, threads, skip, simd, 1, 1, img);
}

/* The SSE2 and AVX2 loops: the AVX2 ones fuse multiply and add (FMA), so
 * an image drawn with the other SIMD path differs in the last bits of a
 * sample's rounding, accumulated over the slices: at most SIMD_TOL per
 * channel here (volumes of at most 48 slices, values within [0, 1]; seen:
 * below 1e-6).  With early termination a pixel whose alpha ends next to
 * the stop may take one more sample in one path, which changes it by
 * less than the bound, 1/272.  simd_diff returns the largest difference
 * and records it in *worst.  Every other comparison stays bit for bit
 * within one path. */
#define SIMD_TOL 1e-5
static double simd_worst, simd_worst_stop;

static double simd_diff(const float *a, const float *b, size_t n, double *worst)
{
    double dm = 0;
    for (size_t i = 0; i < n; i++)
        dm = fmax(dm, fabs((double)a[i] - b[i]));
    *worst = fmax(*worst, dm);
    return dm;
}

/* The largest difference between the 8-bit pixels (as tvpal_png writes
 * them) of two images, over black and white backgrounds; *dmax gets the
 * largest float difference of any channel. */
static int max_level_diff(const float *a, const float *b, size_t npix,
                          double *dmax)
{
    int worst = 0;
    double dm = 0;
    for (size_t i = 0; i < npix; i++)
        for (int bg = 0; bg < 2; bg++)
            for (int c = 0; c < 4; c++) {
                float ka = 1.0f - a[4 * i + 3], kb = 1.0f - b[4 * i + 3];
                float va = c < 3 ? a[4 * i + c] + ka * bg : a[4 * i + 3];
                float vb = c < 3 ? b[4 * i + c] + kb * bg : b[4 * i + 3];
                dm = fmax(dm, fabs((double)va - vb));
                va = va < 0 ? 0 : va > 1 ? 1 : va;
                vb = vb < 0 ? 0 : vb > 1 ? 1 : vb;
                int la = (int)(uint8_t)(va * 255.0f + 0.5f);
                int lb = (int)(uint8_t)(vb * 255.0f + 0.5f);
                worst = abs(la - lb) > worst ? abs(la - lb) : worst;
            }
    *dmax = dm;
    return worst;
}

static uint64_t rng_state = 88172645463325252ull;
static double urand(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (double)(rng_state >> 11) / 9007199254740992.0;
}

/* A random transfer function of 2 to 6 points over the normalized domain;
 * every third one has an opaque plateau (alpha 1) from some value up. */
static void random_tf(int n, struct tvpal_tf *tf)
{
    char text[1024];
    int pts = 2 + (int)(urand() * 5), len;
    int opaque = n % 3 == 2;
    double plateau = 0.2 + 0.6 * urand();
    len = snprintf(text, sizeof text, "domain normalized\n");
    for (int i = 0; i < pts; i++) {
        double x = (double)i / (pts - 1);
        double a = opaque && x >= plateau ? 1.0 : urand() * urand();
        len += snprintf(text + len, sizeof text - (size_t)len, "%.6f %.4f %.4f %.4f %.4f\n",
                        x, urand(), urand(), urand(), a);
    }
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_tf_parse_text(text, 0, 1, tf, &d) == 0, "%s: %s", text, d.msg);
}

static int cpu_has_avx2(void)
{
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
    return __builtin_cpu_supports("avx2");
#else
    return 0;
#endif
}

int main(void)
{
    const size_t maxvox = (size_t)1100 * 24 * 7 + 48 * 40 * 32;
    idx_store = malloc(maxvox);
    pal_store = malloc(sizeof(float) * 1024 * 1100);
    sl = calloc(1100, sizeof *sl);
    const size_t maxpix = (size_t)4 * 300 * 260;
    float *img = malloc(sizeof(float) * maxpix), *img2 = malloc(sizeof(float) * maxpix);
    double *ref = malloc(sizeof(double) * maxpix);
    REQUIRE(idx_store && pal_store && sl && img && img2 && ref, "memory");
    struct tvpal_tf tf, tf2, tf3;
    struct tvpal_diag d = {{0}};
    /* tf: transparent below 0.2 (most tiles empty); tf2: dense; tf3:
     * opaque above 0.4 (pixels saturate: early termination). */
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 0 0 0 0\n0.2 0 0 1 0\n"
                                "0.5 0 1 0 0.08\n1 1 0.2 0 0.5\n", 0, 1, &tf, &d) == 0,
            "%s", d.msg);
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 1 1 1 0.02\n1 1 0 1 0.2\n",
                                0, 1, &tf2, &d) == 0, "%s", d.msg);
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 0 0 0 0\n0.3 0 0 1 0\n"
                                "0.4 1 1 1 1\n1 1 0.5 0 1\n", 0, 1, &tf3, &d) == 0,
            "%s", d.msg);
    const int avx2 = cpu_has_avx2();
    if (!avx2)
        printf("no AVX2 on this CPU: the SSE2 loop only\n");

    /* Views: every axis, zoom from 0.8 (K = 1) to 8 (K = 4). */
    static const double views[][3] = {{0, 0, 1}, {25, 35, 1}, {-40, 10, 1.3},
                                      {90, 5, 1}, {5, 95, 1}, {60, -120, 1},
                                      {170, 20, 2.5}, {15, 200, 0.8},
                                      {30, 40, 4}, {-20, 100, 5.5}, {80, 10, 8},
                                      {35, -25, 1.8}, {100, 60, 0.6}};
    const struct vol vo = {{48, 40, 32}, 120, 104, 0};
    unsigned axes = 0, ks = 0;
    struct tvpal_sw *sw;
    REQUIRE(tvpal_sw_create(&sw) == 0, "create");
    printf("inner loops: %s\n", tvpal_sw_simd_name(sw));
    for (size_t vi = 0; vi < sizeof views / sizeof *views; vi++) {
        struct tvpal_view v = {.dims = {48, 40, 32}, .width = vo.W, .height = vo.H,
                               .ax_deg = views[vi][0], .ay_deg = views[vi][1],
                               .zoom = views[vi][2]};
        struct tvpal_frame f = {0};
        const size_t np = (size_t)4 * vo.W * vo.H;
        make_frame(&vo, &v, &f, &tf);
        axes |= 1u << v.axis;
        tvpal_render_ref(&f, ref);
        tvpal_sw_options(sw, 1, 1, 1);
        tvpal_sw_set_exact(sw, 1);
        REQUIRE(tvpal_sw_set_slices(sw, f.w, f.h, f.count, &d) == 0, "%s", d.msg);
        REQUIRE(tvpal_sw_draw(sw, &f, img, &d) == 0, "%s", d.msg);
        unsigned k = tvpal_sw_scale(sw);
        ks |= 1u << k;
        double p = psnr(img, ref, np);
        CHECK(p >= 35.0, "view (%g,%g) zoom %g axis %c K %u: %.2f dB", views[vi][0],
              views[vi][1], views[vi][2], "xyz"[v.axis], k, p);
        printf("view (%4g,%4g) zoom %.1f axis %c K %u: shear-warp vs reference %.2f dB\n",
               views[vi][0], views[vi][1], views[vi][2], "xyz"[v.axis], k, p);
        for (int threads = 2; threads <= 3; threads++) {
            draw_fresh(&f, f.count, threads, 1, 1, img2);
            CHECK(!memcmp(img, img2, sizeof(float) * np), "1 vs %d threads differ", threads);
        }
        draw_fresh(&f, f.count, 2, 0, 1, img2);
        CHECK(!memcmp(img, img2, sizeof(float) * np), "skipping changed pixels (sparse TF)");
        for (unsigned band = 1; band <= 32; band += band == 1 ? 6 : 25) {
            draw_band_mode(&f, f.count, 2, 1, 1, 1, 1, band, img2);
            CHECK(!memcmp(img, img2, sizeof(float) * np), "band %u changed pixels", band);
        }
        if (avx2) {
            draw_fresh(&f, f.count, 2, 1, 0, img2);
            CHECK(simd_diff(img, img2, np, &simd_worst) <= SIMD_TOL, "SSE2 vs AVX2 differ (K %u)", k);
        }
        /* A TF change every frame: the same image as a fresh start. */
        const struct tvpal_tf *tfs[2] = {&tf2, &tf3};
        for (int t = 0; t < 2; t++) {
            struct tvpal_frame f2 = {0};
            make_frame(&vo, &v, &f2, tfs[t]);
            tvpal_sw_options(sw, 2, 1, 1);
            REQUIRE(tvpal_sw_draw(sw, &f2, img2, &d) == 0, "%s", d.msg);
            draw_fresh(&f2, f2.count, 1, 1, 1, img);
            CHECK(!memcmp(img, img2, sizeof(float) * np), "TF change differs from fresh");
            draw_fresh(&f2, f2.count, 1, 0, 1, img);
            CHECK(!memcmp(img, img2, sizeof(float) * np),
                  "skipping (tf%d) changed pixels", t + 2);
            draw_fresh(&f2, f2.count, 1, 0, 0, img);
            CHECK(simd_diff(img, img2, np, &simd_worst) <= SIMD_TOL,
                  "skipping (tf%d) and SSE2 changed pixels", t + 2);
            tvpal_render_ref(&f2, ref);
            p = psnr(img, ref, np);
            CHECK(p >= 35.0, "tf%d view %zu: %.2f dB", t + 2, vi, p);
            printf("    tf%d (%s): %.2f dB\n", t + 2, t ? "opaque" : "dense", p);
        }
    }
    CHECK(axes == 7, "all axes (%u)", axes);

    /* Physical grids (anisotropic spacing): the same geometry through the
     * view, so shear-warp still matches the reference, on every axis. */
    static const double grids[][3] = {{1, 1, 4}, {2, 1, 0.5}, {0.3, 3, 1}};
    for (size_t gi = 0; gi < sizeof grids / sizeof *grids; gi++)
        for (size_t vi = 0; vi < 5; vi++) {
            struct tvpal_view v = {.dims = {48, 40, 32}, .width = vo.W,
                                   .height = vo.H, .ax_deg = views[vi][0],
                                   .ay_deg = views[vi][1],
                                   .zoom = views[vi][2]};
            memcpy(v.spacing, grids[gi], sizeof v.spacing);
            struct tvpal_frame f = {0};
            const size_t np = (size_t)4 * vo.W * vo.H;
            make_frame(&vo, &v, &f, &tf);
            tvpal_render_ref(&f, ref);
            tvpal_sw_options(sw, 2, 1, 1);
            REQUIRE(tvpal_sw_set_slices(sw, f.w, f.h, f.count, &d) == 0, "%s",
                    d.msg);
            REQUIRE(tvpal_sw_draw(sw, &f, img, &d) == 0, "%s", d.msg);
            double p = psnr(img, ref, np);
            CHECK(p >= 35.0, "spacing %g,%g,%g view %zu axis %c: %.2f dB",
                  grids[gi][0], grids[gi][1], grids[gi][2], vi, "xyz"[v.axis],
                  p);
            printf("spacing %g,%g,%g view (%g,%g) axis %c gap %.2f: %.2f dB\n",
                   grids[gi][0], grids[gi][1], grids[gi][2], views[vi][0],
                   views[vi][1], "xyz"[v.axis], v.gap, p);
        }

    /* A forced K (speed against sharpness): 8 at close zoom is at least as
     * close to the reference as the automatic 4, options change no bit;
     * 1 still passes the floor; 9 is refused. */
    {
        struct tvpal_view v = {.dims = {48, 40, 32}, .width = vo.W, .height = vo.H,
                               .ax_deg = 30, .ay_deg = 40, .zoom = 6};
        struct tvpal_frame f = {0};
        const size_t np = (size_t)4 * vo.W * vo.H;
        make_frame(&vo, &v, &f, &tf3);
        tvpal_render_ref(&f, ref);
        double p[9] = {0};
        for (unsigned k = 0; k <= 8; k += 1) {
            if (k != 0 && k != 1 && k != 8)
                continue;
            struct tvpal_sw *fk;
            REQUIRE(tvpal_sw_create(&fk) == 0, "create");
            REQUIRE(tvpal_sw_set_scale(fk, k) == 0, "scale %u", k);
            tvpal_sw_options(fk, 1, 1, 1);
            tvpal_sw_set_exact(fk, 1);
            REQUIRE(tvpal_sw_set_slices(fk, f.w, f.h, f.count, &d) == 0, "%s", d.msg);
            REQUIRE(tvpal_sw_draw(fk, &f, img, &d) == 0, "%s", d.msg);
            CHECK(k == 0 ? tvpal_sw_scale(fk) == 4 : tvpal_sw_scale(fk) == k,
                  "K %u asked, %u used", k, tvpal_sw_scale(fk));
            p[k] = psnr(img, ref, np);
            printf("zoom 6, opaque TF, K %s%u: %.2f dB\n", k ? "" : "auto = ",
                   tvpal_sw_scale(fk), p[k]);
            tvpal_sw_options(fk, 3, 0, 1);
            REQUIRE(tvpal_sw_draw(fk, &f, img2, &d) == 0, "%s", d.msg);
            CHECK(!memcmp(img, img2, sizeof(float) * np), "K %u: options changed pixels", k);
            tvpal_sw_options(fk, 3, 0, 0);
            REQUIRE(tvpal_sw_draw(fk, &f, img2, &d) == 0, "%s", d.msg);
            CHECK(simd_diff(img, img2, np, &simd_worst) <= SIMD_TOL, "K %u: options and SSE2 "
                  "changed pixels", k);
            CHECK(k != 0 || tvpal_sw_set_scale(fk, 9) == TVPAL_E_INVAL, "K 9 accepted");
            const unsigned band = tvpal_sw_band(fk);
            CHECK(band >= 4 && band <= 32 && !(band & (band - 1)),
                  "default band %u", band);
            REQUIRE(tvpal_sw_set_band(fk, 7) == 0, "band 7");
            REQUIRE(tvpal_sw_draw(fk, &f, img2, &d) == 0, "%s", d.msg);
            CHECK(tvpal_sw_band(fk) == 7, "band 7 set, %u used", tvpal_sw_band(fk));
            CHECK(k != 0 || (tvpal_sw_set_band(fk, 0) == TVPAL_E_INVAL &&
                             tvpal_sw_set_band(fk, 33) == TVPAL_E_INVAL),
                  "band 0 or 33 accepted");
            tvpal_sw_free(fk);
        }
        CHECK(p[8] >= p[0] - 0.01, "K 8 (%.2f dB) worse than auto (%.2f dB)", p[8], p[0]);
        CHECK(p[1] >= 35.0, "K 1: %.2f dB", p[1]);
    }
    CHECK(ks == (1u << 1 | 1u << 2 | 1u << 3 | 1u << 4), "K = 1..4 covered (%#x)", ks);

    /* New slice data: upload marks the layer, the next draw sees it. */
    {
        struct tvpal_view v = {.dims = {48, 40, 32}, .width = vo.W, .height = vo.H,
                               .ax_deg = 25, .ay_deg = 35, .zoom = 1};
        struct tvpal_frame f = {0};
        const size_t np = (size_t)4 * vo.W * vo.H;
        make_frame(&vo, &v, &f, &tf);
        tvpal_sw_options(sw, 2, 1, 1);
        REQUIRE(tvpal_sw_set_slices(sw, f.w, f.h, f.count, &d) == 0, "%s", d.msg);
        REQUIRE(tvpal_sw_draw(sw, &f, img, &d) == 0, "%s", d.msg);
        /* Slices 3 and 17 change: a blob where they were empty. */
        for (uint32_t s = 3; s < 20; s += 14) {
            uint8_t *I = idx_store + (size_t)s * f.w * f.h;
            for (uint32_t y = 0; y < 6; y++)
                memset(I + (size_t)f.w * y, 250, 9);
            tvpal_sw_upload(sw, s);
        }
        REQUIRE(tvpal_sw_draw(sw, &f, img2, &d) == 0, "%s", d.msg);
        CHECK(memcmp(img, img2, sizeof(float) * np) != 0, "new data not drawn");
        draw_fresh(&f, f.count, 1, 1, 1, img);
        CHECK(!memcmp(img, img2, sizeof(float) * np), "upload differs from fresh");
        draw_fresh(&f, f.count, 1, 0, 1, img);
        CHECK(!memcmp(img, img2, sizeof(float) * np), "upload: skipping changed pixels");

        /* Errors: slice size or layer that the renderer was not set for. */
        struct tvpal_frame bad = f;
        bad.w = f.w + 1;
        CHECK(tvpal_sw_draw(sw, &bad, img, &d) == TVPAL_E_INVAL && strstr(d.msg, "prepared"),
              "size mismatch: %s", d.msg);
        REQUIRE(tvpal_sw_set_slices(sw, f.w, f.h, 4, &d) == 0, "%s", d.msg);
        CHECK(tvpal_sw_draw(sw, &f, img, &d) == TVPAL_E_INVAL && strstr(d.msg, "layer"),
              "layer out of range: %s", d.msg);
        CHECK(tvpal_sw_set_slices(sw, 0, 5, 4, &d) == TVPAL_E_INVAL, "empty slices");
    }

    /* Lazy classification (tile sets built only where probes cannot
     * decide).  A dense TF, every palette entry visible: every tile is
     * visible, decided with no probe and no set, the image that of drawing
     * every tile.  The same with one entry (255) made transparent: every
     * tile is proved visible by a probe, no set is built; drawn again, by
     * the index its probe found (no probe).  Then slices transparent but for two texels of each tile
     * that no probe reads (its corners): every tile's set is built, the
     * corners are drawn, the image is that of drawing every tile; the
     * next frame builds none (the sets are kept) and after an upload only
     * that layer's are built again. */
    {
        struct tvpal_view v = {.dims = {48, 40, 32}, .width = vo.W, .height = vo.H,
                               .ax_deg = 25, .ay_deg = 35, .zoom = 1};
        struct tvpal_frame f = {0};
        struct tvpal_sw_counts c;
        const size_t np = (size_t)4 * vo.W * vo.H;
        struct tvpal_sw *lz;
        REQUIRE(tvpal_sw_create(&lz) == 0, "create");
        tvpal_sw_options(lz, 2, 1, 1);
        make_frame(&vo, &v, &f, &tf2);
        const unsigned long tiles = (unsigned long)f.count * ((f.w + 15) / 16) *
                                    ((f.h + 15) / 16);
        REQUIRE(tvpal_sw_set_slices(lz, f.w, f.h, f.count, &d) == 0, "%s", d.msg);
        REQUIRE(tvpal_sw_draw(lz, &f, img, &d) == 0, "%s", d.msg);
        tvpal_sw_counts(lz, &c);
        draw_fresh(&f, f.count, 1, 0, 1, img2);
        CHECK(c.witnessed == 0 && c.probed == 0 && c.built == 0 &&
              !memcmp(img, img2, sizeof(float) * np), "every entry visible: "
              "%lu witnessed, %lu probed, %lu built, or pixels changed",
              c.witnessed, c.probed, c.built);
        for (uint32_t k = 0; k < f.count; k++)
            memset(pal_store + (size_t)1024 * sl[k].slice + 4 * 255, 0, 4 * sizeof(float));
        REQUIRE(tvpal_sw_draw(lz, &f, img, &d) == 0, "%s", d.msg);
        tvpal_sw_counts(lz, &c);
        CHECK(c.probed == tiles && c.built == 0, "dense TF: %lu of %lu tiles "
              "probed, %lu sets built", c.probed, tiles, c.built);
        REQUIRE(tvpal_sw_draw(lz, &f, img2, &d) == 0, "%s", d.msg);
        tvpal_sw_counts(lz, &c);
        CHECK(c.witnessed == tiles && c.probed == 0 && c.built == 0 &&
              !memcmp(img, img2, sizeof(float) * np), "dense TF again: %lu "
              "witnessed, %lu probed, %lu built of %lu, or pixels changed",
              c.witnessed, c.probed, c.built, tiles);
        make_frame(&vo, &v, &f, &tf);   /* index 0 transparent, 255 not */
        for (uint32_t k = 0; k < f.count; k++) {
            uint8_t *I = idx_store + (size_t)sl[k].slice * f.w * f.h;
            memset(I, 0, (size_t)f.w * f.h);
            for (uint32_t y = 0; y < f.h; y += 16)
                for (uint32_t x = 0; x < f.w; x += 16) {
                    I[x + (size_t)f.w * y] = 255;
                    uint32_t x1 = x + 15 < f.w ? x + 15 : f.w - 1;
                    uint32_t y1 = y + 15 < f.h ? y + 15 : f.h - 1;
                    I[x1 + (size_t)f.w * y1] = 255;
                }
            tvpal_sw_upload(lz, sl[k].layer);
        }
        REQUIRE(tvpal_sw_draw(lz, &f, img, &d) == 0, "%s", d.msg);
        tvpal_sw_counts(lz, &c);
        CHECK(c.witnessed == 0 && c.probed == 0 && c.built == tiles, "probes "
              "missed: %lu witnessed, %lu probed, %lu of %lu sets built",
              c.witnessed, c.probed, c.built, tiles);
        draw_fresh(&f, f.count, 1, 0, 1, img2);
        CHECK(!memcmp(img, img2, sizeof(float) * np), "lazy sets changed pixels");
        double energy = 0;
        for (size_t i = 3; i < np; i += 4)
            energy += img[i];
        CHECK(energy > 0, "the corner texels were not drawn");
        REQUIRE(tvpal_sw_draw(lz, &f, img2, &d) == 0, "%s", d.msg);
        tvpal_sw_counts(lz, &c);
        CHECK(c.probed == 0 && c.built == 0 && !memcmp(img, img2, sizeof(float) * np),
              "kept sets: %lu probed, %lu built, or pixels changed", c.probed, c.built);
        tvpal_sw_upload(lz, sl[3].layer);
        REQUIRE(tvpal_sw_draw(lz, &f, img2, &d) == 0, "%s", d.msg);
        tvpal_sw_counts(lz, &c);
        CHECK(c.built == tiles / f.count && !memcmp(img, img2, sizeof(float) * np),
              "one upload: %lu sets built (expected %lu), or pixels changed",
              c.built, tiles / f.count);
        tvpal_sw_free(lz);
    }

    /* Extreme views (NaN, infinite or huge angles and zooms): the view's
     * derived fields stay finite, and a draw either succeeds or refuses
     * the frame; no conversion out of range on the way. */
    {
        static const double xv[][3] = {
            {NAN, 0, 1}, {0, NAN, 1}, {INFINITY, -INFINITY, 1},
            {1e308, -1e308, 1}, {1e12, 7e15, 1}, {20, 30, 1e-300},
            {20, 30, 1e-20}, {20, 30, 1e300}, {20, 30, NAN}, {20, 30, -5},
            {20, 30, INFINITY}, {20, 30, 0}};
        for (size_t i = 0; i < sizeof xv / sizeof *xv; i++) {
            struct tvpal_view v = {.dims = {48, 40, 32}, .width = vo.W,
                                   .height = vo.H, .ax_deg = xv[i][0],
                                   .ay_deg = xv[i][1], .zoom = xv[i][2]};
            struct tvpal_frame f = {0};
            make_frame(&vo, &v, &f, &tf);
            int finite = isfinite(v.sx) && isfinite(v.sy) && v.sx > 0 &&
                         v.sy > 0 && isfinite(v.dcos) && v.dcos > 0 &&
                         isfinite(v.gap) && v.axis < 3;
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++)
                    finite &= isfinite(v.rot[r][c]);
            CHECK(finite, "view %g,%g zoom %g: derived fields not finite "
                  "(sx %g sy %g dcos %g)", xv[i][0], xv[i][1], xv[i][2],
                  v.sx, v.sy, v.dcos);
            REQUIRE(tvpal_sw_set_slices(sw, f.w, f.h, f.count, &d) == 0,
                    "%s", d.msg);
            int rc = tvpal_sw_draw(sw, &f, img, &d);
            CHECK(rc == 0 || rc == TVPAL_E_INVAL, "view %g,%g zoom %g: "
                  "draw %d: %s", xv[i][0], xv[i][1], xv[i][2], rc, d.msg);
        }
        /* Spacing that breaks the contract counts as isotropic. */
        struct tvpal_view v = {.dims = {48, 40, 32}, .spacing = {1, NAN, 2},
                               .width = vo.W, .height = vo.H, .ax_deg = 20,
                               .ay_deg = 30, .zoom = 1};
        tvpal_view_setup(&v);
        CHECK(v.spacing[0] == 0 && v.spacing[1] == 0 && v.spacing[2] == 0 &&
              isfinite(v.sx) && v.gap == 1, "NaN spacing kept");
    }

    /* Unusual frames the player does not make but the contract allows:
     * one layer drawn by two frame slices with different palettes, and
     * palettes with alpha above 1 (early termination must then not stop
     * a pixel whose alpha overshot).  Options still change no bit. */
    {
        struct tvpal_view v = {.dims = {48, 40, 32}, .width = vo.W, .height = vo.H,
                               .ax_deg = 25, .ay_deg = 35, .zoom = 1};
        struct tvpal_frame f = {0};
        const size_t np = (size_t)4 * vo.W * vo.H;
        make_frame(&vo, &v, &f, &tf);
        /* Every other slice shows the layer of its neighbour, with the
         * dense palette of slice 0. */
        for (uint32_t k = 1; k < f.count; k += 2) {
            sl[k].layer = sl[k - 1].layer;
            sl[k].idx = sl[k - 1].idx;
            sl[k].palette = pal_store; /* tf's palette of slice 0 */
        }
        float *hot = pal_store + (size_t)1024 * (f.count + 1);
        for (int i = 0; i < 256; i++) {
            float a = 1.5f * (float)i / 255.0f;
            hot[4 * i] = a * 0.9f;
            hot[4 * i + 1] = a * 0.5f;
            hot[4 * i + 2] = a * 0.1f;
            hot[4 * i + 3] = a;
        }
        sl[2].palette = hot;
        draw_fresh(&f, f.count, 1, 1, 1, img);
        draw_fresh(&f, f.count, 2, 0, 1, img2);
        CHECK(!memcmp(img, img2, sizeof(float) * np), "shared layer / alpha > 1: options "
              "changed pixels");
        draw_fresh(&f, f.count, 3, 1, 0, img2);
        CHECK(simd_diff(img, img2, np, &simd_worst) <= SIMD_TOL, "shared layer / alpha > 1: SSE2 "
              "vs AVX2 or threads changed pixels");
    }

    /* Missing values: a block whose palette entry comes from a NaN row
     * value, with the default transparent NaN colour, draws exactly as
     * the same block made transparent by the TF (value 0): what lies
     * behind it shows, in the shear-warp (skipping on and off) and the
     * reference renderer; an opaque NaN colour hides it. */
    {
        const size_t np = (size_t)4 * vo.W * vo.H;
        struct tvpal_tf tfn = tf;
        const float red[4] = {1, 0, 0, 1};
        memcpy(tfn.nan_rgba, red, sizeof red);
        double *ref2 = malloc(sizeof(double) * np);
        REQUIRE(ref2 && tf.nan_rgba[3] == 0, "memory, transparent NaN");
        for (size_t vi = 0; vi < 5; vi++) {
            struct tvpal_view v = {.dims = {48, 40, 32}, .width = vo.W,
                                   .height = vo.H, .ax_deg = views[vi][0],
                                   .ay_deg = views[vi][1],
                                   .zoom = views[vi][2]};
            struct tvpal_frame f = {0};
            for (int skip = 0; skip < 2; skip++) {
                make_block_frame(&vo, &v, &f, &tf, 0.0f);
                draw_fresh(&f, f.count, 2, skip, 1, img);
                tvpal_render_ref(&f, ref);
                make_block_frame(&vo, &v, &f, &tf, NAN);
                draw_fresh(&f, f.count, 2, skip, 1, img2);
                CHECK(!memcmp(img, img2, sizeof(float) * np), "view %zu skip %d: "
                      "NaN block differs from a transparent one", vi, skip);
                tvpal_render_ref(&f, ref2);
                CHECK(!memcmp(ref, ref2, sizeof(double) * np), "view %zu: "
                      "reference: NaN block differs from a transparent one", vi);
                make_block_frame(&vo, &v, &f, &tfn, NAN);
                draw_fresh(&f, f.count, 2, skip, 1, img2);
                CHECK(memcmp(img, img2, sizeof(float) * np) != 0, "view %zu: "
                      "an opaque NaN colour draws nothing", vi);
                tvpal_render_ref(&f, ref2);
                CHECK(memcmp(ref, ref2, sizeof(double) * np) != 0, "view %zu: "
                      "reference: an opaque NaN colour draws nothing", vi);
                /* Where the opaque block shows, the transparent one shows
                 * what lies behind it. */
                double behind = 0;
                for (size_t i = 0; i < np / 4; i++)
                    if (memcmp(img + 4 * i, img2 + 4 * i, sizeof(float) * 4))
                        behind += img[4 * i + 3];
                CHECK(behind > 1.0, "view %zu: nothing behind the block (%g)",
                      vi, behind);
            }
        }
        free(ref2);
    }

    /* Early termination with its bound (the default).  Over many random
     * views and TFs, opaque ones included, on smooth and noisy volumes: no
     * 8-bit pixel differs from --exact by more than one level, and no
     * channel by more than the stopping transmittance 1/272 (+ float
     * rounding), and the largest difference comes near it (a threshold
     * that silently moved, or termination turned off, fails); the image is
     * the same for 1, 2 and 3 threads, SSE2 and AVX2, and with the
     * opaque-run links or a test per pixel; on every opaque TF it really
     * stops early (the image differs from --exact). */
    {
        int worst = 0, opaque_cases = 0, opaque_differs = 0;
        double dworst = 0;
        for (int n = 0; n < 48; n++) {
            struct tvpal_tf rt;
            random_tf(n, &rt);
            const struct vol rv = {{48, 40, 32}, 96, 88, n & 1};
            struct tvpal_view v = {.dims = {48, 40, 32}, .width = rv.W,
                                   .height = rv.H,
                                   .ax_deg = 360 * urand() - 180,
                                   .ay_deg = 360 * urand() - 180,
                                   .zoom = 0.6 + 5 * urand() * urand()};
            struct tvpal_frame f = {0};
            const size_t npix = (size_t)rv.W * rv.H, np = 4 * npix;
            make_frame(&rv, &v, &f, &rt);
            draw_mode(&f, f.count, 1, 1, 1, 0, 1, img);
            draw_mode(&f, f.count, 2, 1, 1, 0, 0, img2);
            CHECK(!memcmp(img, img2, sizeof(float) * np),
                  "case %d: the opaque-run links changed pixels", n);
            draw_mode(&f, f.count, 3, 1, 1, 0, 1, img2);
            CHECK(!memcmp(img, img2, sizeof(float) * np),
                  "case %d: threads changed pixels", n);
            draw_mode(&f, f.count, 3, 1, 0, 0, 1, img2);
            CHECK(simd_diff(img, img2, np, &simd_worst_stop) <= 1.0 / 272 + SIMD_TOL,
                  "case %d: SSE2 changed pixels", n);
            draw_band_mode(&f, f.count, 2, 1, 1, 0, 1, n % 2 ? 1 : 5, img2);
            CHECK(!memcmp(img, img2, sizeof(float) * np),
                  "case %d: band %d changed pixels", n, n % 2 ? 1 : 5);
            draw_mode(&f, f.count, 2, 1, 1, 1, 1, img2);
            double dm;
            int lv = max_level_diff(img, img2, npix, &dm);
            CHECK(lv <= 1 && dm <= 1.0 / 272 + 1e-6, "case %d view (%g,%g) "
                  "zoom %g: %d levels, %g from --exact", n, v.ax_deg, v.ay_deg,
                  v.zoom, lv, dm);
            worst = lv > worst ? lv : worst;
            dworst = fmax(dworst, dm);
            if (n % 3 == 2) {
                opaque_cases++;
                opaque_differs += memcmp(img, img2, sizeof(float) * np) != 0;
            }
        }
        CHECK(opaque_differs == opaque_cases, "early termination stopped "
              "early on %d of %d opaque TFs", opaque_differs, opaque_cases);
        CHECK(dworst > 0.9 / 272, "early termination: at most %g from "
              "--exact, the bound 1/272 = %g is not nearly reached", dworst,
              1.0 / 272);
        printf("early termination, 48 random views and TFs: at most %d 8-bit "
               "level(s), %.3g (%.2f levels) from --exact; stopped early on "
               "%d of %d opaque TFs\n", worst, dworst, dworst * 255,
               opaque_differs, opaque_cases);
    }

    /* Odd shapes: 1 x H, W x 1 and 1100-wide slices (tiles of 32), views
     * that see them edge-on and face-on. */
    static const struct vol odd[] = {{{1, 40, 32}, 90, 80, 1},
                                     {{48, 1, 32}, 90, 80, 1},
                                     {{48, 40, 1}, 90, 80, 1},
                                     {{1100, 24, 7}, 300, 60, 1}};
    static const double oddv[][3] = {{20, 30, 1}, {60, 10, 6}, {10, 80, 1.7},
                                     {0, 0, 3}};
    for (size_t oi = 0; oi < sizeof odd / sizeof *odd; oi++)
        for (size_t vi = 0; vi < sizeof oddv / sizeof *oddv; vi++) {
            struct tvpal_view v = {.width = odd[oi].W, .height = odd[oi].H,
                                   .ax_deg = oddv[vi][0], .ay_deg = oddv[vi][1],
                                   .zoom = oddv[vi][2]};
            memcpy(v.dims, odd[oi].n, sizeof v.dims);
            struct tvpal_frame f = {0};
            const size_t np = (size_t)4 * v.width * v.height;
            make_frame(&odd[oi], &v, &f, &tf2);
            draw_fresh(&f, f.count, 1, 1, 1, img);
            draw_fresh(&f, f.count, 2, 0, 1, img2);
            CHECK(!memcmp(img, img2, sizeof(float) * np),
                  "odd %ux%ux%u view %zu: skipping changed pixels", v.dims[0],
                  v.dims[1], v.dims[2], vi);
            draw_fresh(&f, f.count, 2, 0, 0, img2);
            CHECK(simd_diff(img, img2, np, &simd_worst) <= SIMD_TOL,
                  "odd %ux%ux%u view %zu: options changed pixels", v.dims[0],
                  v.dims[1], v.dims[2], vi);
            tvpal_render_ref(&f, ref);
            double energy = 0;
            for (size_t i = 0; i < np; i++)
                energy += ref[i];
            CHECK(energy > 0,
                  "odd %ux%ux%u view %zu: empty reference image", v.dims[0],
                  v.dims[1], v.dims[2], vi);
            double p = psnr(img, ref, np);
            /* One-texel-thin slices have no interior to interpolate: the
             * edge texels carry the whole image; 30 dB there. */
            double floor_db = f.w == 1 || f.h == 1 ? 30.0 : 35.0;
            CHECK(p >= floor_db, "odd %ux%ux%u view %zu axis %c: %.2f dB",
                  v.dims[0], v.dims[1], v.dims[2], vi, "xyz"[v.axis], p);
            printf("odd %4ux%ux%u view (%g,%g) zoom %.1f axis %c: %.2f dB\n",
                   v.dims[0], v.dims[1], v.dims[2], oddv[vi][0], oddv[vi][1],
                   oddv[vi][2], "xyz"[v.axis], p);
        }
    /* Slice edges: one slice of one colour C drawn alone (a frame of one
     * of the volume's 3 slices, as the player leaves transparent slices
     * out).  Compositing puts C on every intermediate pixel the slice
     * covers, its edge texels' included (the clamped samples of texels -1
     * and w - 1), and the warp mixes covered taps only, so every output
     * pixel is C or 0: a partial pixel means an edge sample went undrawn
     * (dropping texel -1 or w - 1 gives thousands).  K = 1, 2 and 3, with
     * and without stopped-pixel maps, both SIMD paths, views turned and
     * zoomed a little; the slice drawn moves from view to view, so that
     * the shear puts it at fractions of a pixel and both phases of the
     * edge texels (fx < 0.5: texel w - 1 has a sample inside the slice;
     * fx >= 0.5: texel -1 has) occur at every K. */
    {
        const uint32_t ew = 37, eh = 23, ed = 3;
        const float C[4] = {0.3f, 0.2f, 0.1f, 0.5f};
        for (int i = 0; i < 1024; i++)
            pal_store[i] = C[i % 4];
        memset(idx_store, 0, (size_t)ew * eh);
        int partial = 0, full = 0, runs = 0;
        for (int vi = 0; vi < 24; vi++) {
            struct tvpal_view v = {.dims = {ew, eh, ed}, .width = 97, .height = 71,
                                   .ax_deg = -9 + 0.77 * vi, .ay_deg = 7 - 0.61 * vi,
                                   .zoom = 1.1 + 0.013 * vi};
            tvpal_view_setup(&v);
            REQUIRE(v.axis == 2, "view %d: axis %c, not z", vi, "xyz"[v.axis]);
            sl[0] = (struct tvpal_frame_slice){(uint32_t)vi % ed, 0, idx_store, pal_store};
            struct tvpal_frame f = {.view = &v, .w = ew, .h = eh, .count = 1, .sl = sl};
            const size_t npix = (size_t)v.width * v.height;
            for (int mode = 0; mode < 12; mode++) {
                const int simd = mode & 1, maps = mode >> 1 & 1;
                const unsigned k = 1 + (unsigned)mode / 4;
                if (simd && !avx2)
                    continue;
                struct tvpal_sw *es;
                REQUIRE(tvpal_sw_create(&es) == 0, "create");
                tvpal_sw_options(es, 1, 1, simd);
                tvpal_sw_set_runs(es, maps);
                REQUIRE(tvpal_sw_set_scale(es, k) == 0, "K %u", k);
                REQUIRE(tvpal_sw_set_slices(es, ew, eh, 1, &d) == 0, "%s", d.msg);
                REQUIRE(tvpal_sw_draw(es, &f, img, &d) == 0, "%s", d.msg);
                tvpal_sw_free(es);
                runs++;
                for (size_t i = 0; i < npix; i++) {
                    int is_c = 1, is_0 = 1;
                    for (int c = 0; c < 4; c++) {
                        is_c &= fabsf(img[4 * i + c] - C[c]) <= 1e-5f;
                        is_0 &= fabsf(img[4 * i + c]) <= 1e-5f;
                    }
                    full += is_c;
                    if (!is_c && !is_0 && partial++ < 3)
                        printf("slice edges view %d K %u simd %d maps %d: pixel "
                               "(%zu, %zu) = %g %g %g %g\n", vi, k, simd, maps,
                               i % v.width, i / v.width, img[4 * i],
                               img[4 * i + 1], img[4 * i + 2], img[4 * i + 3]);
                }
            }
        }
        CHECK(partial == 0 && full > 0, "slice edges: %d partial pixels "
              "(%d full) over %d draws", partial, full, runs);
        printf("slice edges: %d draws, %d pixels C, %d partial\n", runs, full,
               partial);
    }

    if (avx2)
        printf("SSE2 against AVX2 (FMA): largest channel difference %.3g "
               "(--exact), %.3g (early termination)\n", simd_worst,
               simd_worst_stop);
    tvpal_sw_free(sw);
    free(idx_store);
    free(pal_store);
    free(sl);
    free(img);
    free(img2);
    free(ref);
    return tt_done("test-sw");
}
