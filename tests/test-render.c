/* test-render: the GL palette renderer (OSMesa, GLSL 3.3) matches the CPU
 * reference renderer for several views on all three axes, for N = 1-like
 * (smooth) and noisy index data; index interpolation differs measurably
 * from colour interpolation on a sharp transfer function; a block of
 * missing (NaN) values with the default transparent NaN colour draws as
 * the same block transparent by the TF; uploads are counted only when
 * indices change.
 * Cross frames (z slices only, drawn along x or y, each row with its z
 * slice's palette) on a 40 x 36 x 28 volume: views along and between x and
 * y, stride 1 and 2, a partial slab; GL against the reference within the
 * tolerance below; crossing between a z view and x and y views uploads no
 * layer again, nor does a TF change; with one palette on every slice the
 * cross frame equals the plain frame of the transposed data (reference:
 * exactly; GL: within the tolerance).
 * Tolerance: RGBA32F blending in single precision vs double: max |diff|
 * 2e-3 per channel except along quad edges, where rasterization rules and
 * the reference's half-open edge test may disagree on a pixel: at most 2%
 * of the pixels may exceed it (in any channel; a quad edge that runs along
 * a row of pixel centres, as the cross view (-55, 35) has, moves a whole
 * row), and the mean |diff| over the channels stays below 2e-4. */
#include "tvpal_glr.h"
#include "tvpal_osmesa.h"
#include "tvpal_render_ref.h"
#include "tvpal_test.h"

#include <string.h>

#define W 96
#define H 80

static uint8_t *idx_store;
static float *pal_store;

static void make_frame(const uint32_t dims[3], struct tvpal_view *v,
                       struct tvpal_frame *f, struct tvpal_frame_slice *sl,
                       const struct tvpal_tf *tf, int noisy)
{
    tvpal_view_setup(v);
    uint32_t n, w, h;
    unsigned a = v->axis;
    n = dims[a];
    w = a == 0 ? dims[1] : dims[0];
    h = a == 2 ? dims[1] : dims[2];
    f->view = v;
    f->w = w;
    f->h = h;
    f->count = n;
    f->sl = sl;
    for (uint32_t k = 0; k < n; k++) {
        uint32_t s = v->descending ? n - 1 - k : k;
        uint8_t *I = idx_store + (size_t)s * w * h;
        for (uint32_t b = 0; b < h; b++)
            for (uint32_t x = 0; x < w; x++) {
                double val = 128 + 100 * sin(0.3 * x + 0.2 * s) * cos(0.25 * b);
                if (noisy)
                    val = (double)(tt_rand64() & 255);
                I[x + w * b] = (uint8_t)val;
            }
        float row[256];
        for (int i = 0; i < 256; i++)
            row[i] = (float)i / 255.0f + 0.001f * s;
        tvpal_palette_build(tf, row, tvpal_view_opacity_exponent(v), 1.0,
                            pal_store + (size_t)1024 * s);
        sl[k].slice = s;
        sl[k].layer = s;
        sl[k].idx = I;
        sl[k].palette = pal_store + (size_t)1024 * s;
    }
}

/* make_frame (smooth), then a box of voxels (the middle third of the
 * volume on every axis) drawn with palette entry 1 alone, whose row value
 * is v1 (NaN: missing values); the voxels that had index 1 move to 2. */
static void make_block_frame(const uint32_t dims[3], struct tvpal_view *v,
                             struct tvpal_frame *f, struct tvpal_frame_slice *sl,
                             const struct tvpal_tf *tf, float v1)
{
    make_frame(dims, v, f, sl, tf, 0);
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
            row[i] = (float)i / 255.0f + 0.001f * s;
        row[1] = v1;
        tvpal_palette_build(tf, row, tvpal_view_opacity_exponent(v), 1.0,
                            pal_store + (size_t)1024 * s);
    }
}

/* Compares a GL image with the reference within the tolerance above;
 * what names the case in messages; *maxd and *psnr (over every channel,
 * peak 1) are what was measured. */
static void check_close(const float *gl, const double *ref, const char *what,
                        double *maxd_out, double *psnr_out)
{
    size_t over = 0;      /* pixels with a channel off by more than 2e-3 */
    double maxd = 0, sum = 0, sq = 0, energy = 0;
    for (size_t px = 0; px < (size_t)W * H; px++) {
        int off = 0;
        for (size_t i = 4 * px; i < 4 * px + 4; i++) {
            double e = fabs(gl[i] - ref[i]);
            off |= e > 2e-3;
            maxd = e > maxd ? e : maxd;
            sum += e;
            sq += e * e;
            energy += ref[i];
        }
        over += off;
    }
    CHECK(energy > 1.0, "%s: empty image", what);
    CHECK(over <= (size_t)(0.02 * W * H), "%s: %zu pixels differ by > 2e-3 "
          "(max %g)", what, over, maxd);
    CHECK(sum / (W * H * 4) < 2e-4, "%s: mean difference %g", what,
          sum / (W * H * 4));
    const double psnr = sq > 0 ? 10 * log10((double)W * H * 4 / sq) : INFINITY;
    printf("%s: max diff %.2e, mean %.2e, %zu px > 2e-3, PSNR %.1f dB\n", what,
           maxd, sum / (W * H * 4), over, psnr);
    *maxd_out = maxd;
    *psnr_out = psnr;
}

/* Draws f with r after uploading every slice. */
static void draw_gl(struct tvpal_glr *r, const struct tvpal_frame *f,
                    uint32_t layers, float *img)
{
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_glr_set_slices(r, f->w, f->h, layers, &d) == 0, "%s", d.msg);
    for (uint32_t k = 0; k < f->count; k++)
        tvpal_glr_upload(r, f->sl[k].slice, f->sl[k].idx);
    REQUIRE(tvpal_glr_draw(r, f, img, &d) == 0, "%s", d.msg);
}

/* ------------------------------------------------------- cross frames */

/* A volume stored as z slices only (as a single-copy dataset), non-cubic
 * so that an x/y/z mix-up shows. */
#define CX 40
#define CY 36
#define CZ 28

static uint8_t cvol[CX * CY * CZ];          /* x fastest, then y, then z */
static uint8_t ctr[CX * CY * CZ];           /* the volume cut along x or y */
static float cpal[CZ * 1024];               /* one palette per z slice */

static void make_volume(int noisy)
{
    for (uint32_t z = 0; z < CZ; z++)
        for (uint32_t y = 0; y < CY; y++)
            for (uint32_t x = 0; x < CX; x++) {
                double val = 128 + 110 * sin(0.27 * x + 0.05 * y) *
                                       cos(0.21 * y - 0.3 * z);
                if (noisy)
                    val = (double)(tt_rand64() & 255);
                cvol[x + CX * (y + CY * (size_t)z)] = (uint8_t)val;
            }
}

/* Palettes of the z slices for view v; equal = 0: each slice its own
 * (offsets that jump between neighbouring rows, so the wrong row's palette
 * shows), else one palette for all. */
static void make_zpal(const struct tvpal_tf *tf, const struct tvpal_view *v,
                      int equal)
{
    for (uint32_t z = 0; z < CZ; z++) {
        float row[256];
        const double off = equal ? 0.05 : 0.3 * ((7 * z) % CZ) / CZ;
        for (int i = 0; i < 256; i++)
            row[i] = (float)(off + (1 - 0.3) * i / 255.0);
        tvpal_palette_build(tf, row, tvpal_view_opacity_exponent(v), 1.0,
                            cpal + (size_t)1024 * z);
    }
}

/* The cross frame of z slices [z0, z0 + count) in layers 0.. (as the player
 * numbers them: slice - first held). */
static void make_cross(const struct tvpal_view *v, struct tvpal_frame *f,
                       struct tvpal_frame_slice *sl, uint32_t z0,
                       uint32_t count, uint32_t stride, uint32_t phase)
{
    for (uint32_t k = 0; k < count; k++)
        sl[k] = (struct tvpal_frame_slice){
            .slice = z0 + k, .layer = k,
            .idx = cvol + (size_t)CX * CY * (z0 + k),
            .palette = cpal + (size_t)1024 * (z0 + k)};
    *f = (struct tvpal_frame){.view = v, .w = CX, .h = CY, .count = count,
                              .sl = sl, .cross = 1, .stride = stride,
                              .phase = phase};
}

/* The plain z frame of the same slices, in drawing order. */
static void make_zframe(const struct tvpal_view *v, struct tvpal_frame *f,
                        struct tvpal_frame_slice *sl, uint32_t z0,
                        uint32_t count)
{
    for (uint32_t k = 0; k < count; k++) {
        const uint32_t z = z0 + (v->descending ? count - 1 - k : k);
        sl[k] = (struct tvpal_frame_slice){
            .slice = z, .layer = z - z0,
            .idx = cvol + (size_t)CX * CY * z,
            .palette = cpal + (size_t)1024 * z};
    }
    *f = (struct tvpal_frame){.view = v, .w = CX, .h = CY, .count = count,
                              .sl = sl};
}

/* The plain frame of the view axis' (x or y) slices s % stride == phase,
 * cut from the volume into ctr by plain indexing (no cross code): texel
 * (a, b) of x slice s is cvol(s, a, b), of y slice s cvol(a, s, b); every
 * slice takes palette pal. */
static void make_transposed(const struct tvpal_view *v, struct tvpal_frame *f,
                            struct tvpal_frame_slice *sl, uint32_t stride,
                            uint32_t phase, const float *pal)
{
    const unsigned ax = v->axis;
    const uint32_t n = ax == 0 ? CX : CY, w = ax == 0 ? CY : CX, h = CZ;
    uint32_t count = 0;
    for (uint32_t i = 0; i < n; i++) {
        const uint32_t s = v->descending ? n - 1 - i : i;
        uint8_t *T = ctr + (size_t)s * w * h;
        for (uint32_t b = 0; b < h; b++)
            for (uint32_t a = 0; a < w; a++)
                T[a + w * b] = ax == 0 ? cvol[s + CX * (a + CY * (size_t)b)]
                                       : cvol[a + CX * (s + CY * (size_t)b)];
        if (s % stride == phase)
            sl[count++] = (struct tvpal_frame_slice){
                .slice = s, .layer = s, .idx = T, .palette = pal};
    }
    *f = (struct tvpal_frame){.view = v, .w = w, .h = h, .count = count,
                              .sl = sl};
}

static void upload_zslices(struct tvpal_glr *r, uint32_t z0, uint32_t count)
{
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_glr_set_slices(r, CX, CY, count, &d) == 0, "%s", d.msg);
    for (uint32_t k = 0; k < count; k++)
        tvpal_glr_upload(r, k, cvol + (size_t)CX * CY * (z0 + k));
}

static void test_cross(const struct tvpal_tf *tf, const struct tvpal_tf *tf2)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_glr *r, *rp;
    REQUIRE(tvpal_glr_create(&r, W, H, &d) == 0, "%s", d.msg);
    REQUIRE(tvpal_glr_create(&rp, W, H, &d) == 0, "%s", d.msg);
    static struct tvpal_frame_slice sl[CX], slp[CX];
    static float gl[W * H * 4], gl2[W * H * 4];
    static double ref[W * H * 4], ref2[W * H * 4];
    /* along x and y, both directions, between axes, one zoomed in */
    static const double views[][3] = {
        {0, 90, 1}, {0, -90, 1}, {90, 0, 1}, {-90, 0, 1},
        {20, 60, 1}, {60, -130, 1}, {70, 15, 2}, {-55, 35, 1}};
    /* z0, count, stride, phase: the volume, every other slice, a slab of
     * a cluster node (rows 9..19), a slab with every other slice */
    static const uint32_t cfg[][4] = {
        {0, CZ, 1, 0}, {0, CZ, 2, 1}, {9, 11, 1, 0}, {9, 11, 2, 0}};
    unsigned seen = 0;
    double worst = 0, worst_psnr = INFINITY;
    for (size_t vi = 0; vi < sizeof views / sizeof *views; vi++)
        for (int noisy = 0; noisy < 2; noisy++) {
            struct tvpal_view v = {.dims = {CX, CY, CZ}, .width = W,
                                   .height = H, .ax_deg = views[vi][0],
                                   .ay_deg = views[vi][1],
                                   .zoom = views[vi][2]};
            tvpal_view_setup(&v);
            REQUIRE(v.axis < 2, "view %zu is along z", vi);
            seen |= 1u << (2 * v.axis + (v.descending != 0));
            make_volume(noisy);
            make_zpal(tf, &v, 0);
            for (size_t ci = 0; ci < sizeof cfg / sizeof *cfg; ci++) {
                struct tvpal_frame f;
                make_cross(&v, &f, sl, cfg[ci][0], cfg[ci][1], cfg[ci][2],
                           cfg[ci][3]);
                upload_zslices(r, cfg[ci][0], cfg[ci][1]);
                REQUIRE(tvpal_glr_draw(r, &f, gl, &d) == 0, "%s", d.msg);
                tvpal_render_ref(&f, ref);
                char what[120];
                snprintf(what, sizeof what, "cross (%4g,%4g) x%g axis %c%s "
                         "noisy %d rows [%u,%u) stride %u phase %u",
                         views[vi][0], views[vi][1], views[vi][2],
                         "xyz"[v.axis], v.descending ? "-" : "+", noisy,
                         cfg[ci][0], cfg[ci][0] + cfg[ci][1], cfg[ci][2],
                         cfg[ci][3]);
                double maxd, psnr;
                check_close(gl, ref, what, &maxd, &psnr);
                worst = fmax(worst, maxd);
                worst_psnr = fmin(worst_psnr, psnr);
            }
        }
    CHECK(seen == 15, "cross views along +x, -x, +y and -y (mask %u)", seen);
    printf("cross frames: max diff %.2e, lowest PSNR %.1f dB\n", worst,
           worst_psnr);

    /* One palette on every slice: the cross frame is the plain frame of the
     * transposed data (the index mapping checked apart from the shader's
     * and the reference's own cross code). */
    make_volume(1);
    for (size_t vi = 0; vi < sizeof views / sizeof *views; vi++)
        for (uint32_t stride = 1; stride <= 2; stride++) {
            struct tvpal_view v = {.dims = {CX, CY, CZ}, .width = W,
                                   .height = H, .ax_deg = views[vi][0],
                                   .ay_deg = views[vi][1],
                                   .zoom = views[vi][2]};
            tvpal_view_setup(&v);
            make_zpal(tf, &v, 1);
            struct tvpal_frame f, fp;
            make_cross(&v, &f, sl, 0, CZ, stride, stride - 1);
            make_transposed(&v, &fp, slp, stride, stride - 1, cpal);
            tvpal_render_ref(&f, ref);
            tvpal_render_ref(&fp, ref2);
            CHECK(!memcmp(ref, ref2, sizeof ref), "view (%g,%g) stride %u: "
                  "reference: the cross frame differs from the plain frame "
                  "of the transposed data", views[vi][0], views[vi][1],
                  stride);
            upload_zslices(r, 0, CZ);
            REQUIRE(tvpal_glr_draw(r, &f, gl, &d) == 0, "%s", d.msg);
            REQUIRE(tvpal_glr_set_slices(rp, fp.w, fp.h, v.dims[v.axis], &d)
                    == 0, "%s", d.msg);
            for (uint32_t k = 0; k < fp.count; k++)
                tvpal_glr_upload(rp, slp[k].layer, slp[k].idx);
            REQUIRE(tvpal_glr_draw(rp, &fp, gl2, &d) == 0, "%s", d.msg);
            for (size_t i = 0; i < (size_t)W * H * 4; i++)
                ref2[i] = gl2[i];
            char what[120];
            snprintf(what, sizeof what, "equal palettes (%4g,%4g) axis %c "
                     "stride %u: gl cross vs gl transposed", views[vi][0],
                     views[vi][1], "xyz"[v.axis], stride);
            double maxd, psnr;
            check_close(gl, ref2, what, &maxd, &psnr);
        }

    /* Crossing between z, x and y views of the same z slices (the volume
     * and a slab) uploads no layer again, nor does a TF change; every
     * image still matches the reference. */
    static const double cross_views[][2] = {{25, 20}, {0, 90}, {90, 0},
                                            {-55, 35}, {0, 0}, {20, 60}};
    for (size_t ci = 0; ci < 3; ci += 2) {
        const uint32_t z0 = cfg[ci][0], count = cfg[ci][1];
        make_volume(0);
        upload_zslices(r, z0, count);
        const uint64_t up = tvpal_glr_uploads(r);
        for (int pass = 0; pass < 2; pass++)
            for (size_t vi = 0; vi < 6; vi++) {
                struct tvpal_view v = {.dims = {CX, CY, CZ}, .width = W,
                                       .height = H,
                                       .ax_deg = cross_views[vi][0],
                                       .ay_deg = cross_views[vi][1],
                                       .zoom = 1};
                tvpal_view_setup(&v);
                make_zpal(pass ? tf2 : tf, &v, 0);
                struct tvpal_frame f;
                if (v.axis == 2)
                    make_zframe(&v, &f, sl, z0, count);
                else
                    make_cross(&v, &f, sl, z0, count, 1, 0);
                REQUIRE(tvpal_glr_draw(r, &f, gl, &d) == 0, "%s", d.msg);
                tvpal_render_ref(&f, ref);
                char what[120];
                snprintf(what, sizeof what, "switch rows [%u,%u) tf %d "
                         "(%4g,%4g) axis %c", z0, z0 + count, pass,
                         cross_views[vi][0], cross_views[vi][1],
                         "xyz"[v.axis]);
                double maxd, psnr;
                check_close(gl, ref, what, &maxd, &psnr);
            }
        CHECK(tvpal_glr_uploads(r) == up, "rows [%u,%u): %llu uploads while "
              "crossing axes and changing the TF", z0, z0 + count,
              (unsigned long long)(tvpal_glr_uploads(r) - up));
    }

    /* Frames the layers do not fit are refused, not drawn from the wrong
     * layers. */
    {
        struct tvpal_view v = {.dims = {CX, CY, CZ}, .width = W, .height = H,
                               .ax_deg = 0, .ay_deg = 90, .zoom = 1};
        tvpal_view_setup(&v);
        struct tvpal_frame f;
        upload_zslices(r, 9, 11);
        make_cross(&v, &f, sl, 0, CZ, 1, 0);
        CHECK(tvpal_glr_draw(r, &f, gl, &d) == TVPAL_E_INVAL,
              "28 z slices drawn from 11 layers");
        make_cross(&v, &f, sl, 9, 11, 1, 0);
        sl[3].layer = 7;
        CHECK(tvpal_glr_draw(r, &f, gl, &d) == TVPAL_E_INVAL,
              "z slices in layers out of order");
        make_cross(&v, &f, sl, 9, 11, 0, 0);
        CHECK(tvpal_glr_draw(r, &f, gl, &d) == TVPAL_E_INVAL, "stride 0");
    }
    tvpal_glr_free(rp);
    tvpal_glr_free(r);
}

int main(void)
{
    struct tvpal_osmesa *ctx;
    struct tvpal_diag d = {{0}};
    if (tvpal_osmesa_create(&ctx, &d) < 0) {
        fprintf(stderr, "no OSMesa GL 3.3 context: %s\n", d.msg);
        return 99;
    }
    struct tvpal_glr *r;
    REQUIRE(tvpal_glr_create(&r, W, H, &d) == 0, "%s", d.msg);
    const uint32_t dims[3] = {24, 20, 16};
    idx_store = malloc(24 * 20 * 24);
    pal_store = malloc(sizeof(float) * 1024 * 24);
    struct tvpal_frame_slice sl[24];
    static float gl[W * H * 4];
    static double ref[W * H * 4], ref2[W * H * 4];
    struct tvpal_tf smooth, sharp;
    const char *ts = "domain normalized\n0 0 0 1 0\n0.5 0 1 0 0.05\n1 1 0 0 0.3\n";
    const char *tsh = "domain normalized\n0 0 0 0 0\n0.49 0 0 0 0\n0.5 1 1 1 0.9\n"
                      "0.51 0 0 0 0\n1 0 0 0 0\n";
    REQUIRE(tvpal_tf_parse_text(ts, 0, 1, &smooth, &d) == 0, "%s", d.msg);
    REQUIRE(tvpal_tf_parse_text(tsh, 0, 1, &sharp, &d) == 0, "%s", d.msg);
    static const double views[][2] = {{0, 0}, {20, 30}, {-35, 10}, {90, 0},
                                      {0, 90}, {60, -120}, {180, 0}, {10, 200}};
    unsigned axes_seen = 0;
    for (size_t vi = 0; vi < sizeof views / sizeof *views; vi++)
        for (int noisy = 0; noisy < 2; noisy++) {
            struct tvpal_view v = {.dims = {24, 20, 16}, .width = W,
                                   .height = H, .ax_deg = views[vi][0],
                                   .ay_deg = views[vi][1], .zoom = 1.0};
            struct tvpal_frame f = {0};
            make_frame(dims, &v, &f, sl, &smooth, noisy);
            axes_seen |= 1u << v.axis;
            REQUIRE(tvpal_glr_set_slices(r, f.w, f.h, dims[v.axis], &d) == 0,
                    "%s", d.msg);
            for (uint32_t k = 0; k < f.count; k++)
                tvpal_glr_upload(r, sl[k].slice, sl[k].idx);
            REQUIRE(tvpal_glr_draw(r, &f, gl, &d) == 0, "%s", d.msg);
            tvpal_render_ref(&f, ref);
            char what[80];
            snprintf(what, sizeof what, "view (%4g,%4g) axis %c noisy %d",
                     views[vi][0], views[vi][1], "xyz"[v.axis], noisy);
            double maxd, psnr;
            check_close(gl, ref, what, &maxd, &psnr);
        }
    CHECK(axes_seen == 7, "views cover all three axes (mask %u)", axes_seen);

    /* Index interpolation vs colour interpolation on a sharp TF. */
    struct tvpal_view v = {.dims = {24, 20, 16}, .width = W, .height = H,
                           .ax_deg = 15, .ay_deg = 25, .zoom = 1.0};
    struct tvpal_frame f = {0};
    make_frame(dims, &v, &f, sl, &sharp, 0);
    tvpal_render_ref(&f, ref);
    tvpal_render_ref_index_interp(&f, ref2);
    double diff = 0;
    for (size_t i = 0; i < (size_t)W * H * 4; i++)
        diff += fabs(ref[i] - ref2[i]);
    diff /= W * H * 4;
    CHECK(diff > 1e-3, "index interpolation should differ on a sharp TF "
          "(mean %g)", diff);
    printf("sharp TF: mean |colour interp - index interp| = %.4f\n", diff);

    /* 8-bit accumulation bands: many translucent layers of the same colour
     * (alpha 0.01 each, 24 slices) vs the double reference, for 8-bit,
     * 16-bit float and 32-bit float colour buffers. */
    {
        struct tvpal_tf faint;
        REQUIRE(tvpal_tf_parse_text("domain normalized\n0 0.3 0.5 0.9 0.01\n"
                                    "1 0.9 0.6 0.2 0.012\n", 0, 1, &faint, &d) == 0,
                "%s", d.msg);
        struct tvpal_view vb = {.dims = {24, 20, 16}, .width = W, .height = H,
                                .ax_deg = 0, .ay_deg = 90, .zoom = 1.0};
        make_frame(dims, &vb, &f, sl, &faint, 0);
        tvpal_render_ref(&f, ref);
        double err[3];
        static const unsigned bits[3] = {8, 16, 32};
        for (int k = 0; k < 3; k++) {
            struct tvpal_glr *rb;
            REQUIRE(tvpal_glr_create_fb(&rb, W, H, bits[k], &d) == 0, "%s", d.msg);
            REQUIRE(tvpal_glr_set_slices(rb, f.w, f.h, dims[vb.axis], &d) == 0, "%s", d.msg);
            for (uint32_t q = 0; q < f.count; q++)
                tvpal_glr_upload(rb, sl[q].slice, sl[q].idx);
            REQUIRE(tvpal_glr_draw(rb, &f, gl, &d) == 0, "%s", d.msg);
            double e = 0;
            for (size_t i = 0; i < (size_t)W * H * 4; i++)
                e = fmax(e, fabs(gl[i] - ref[i]));
            err[k] = e;
            tvpal_glr_free(rb);
        }
        printf("24 faint layers: max |error| vs double reference: RGBA8 %.2e "
               "(%.1f levels of 255), RGBA16F %.2e, RGBA32F %.2e\n", err[0],
               err[0] * 255, err[1], err[2]);
        CHECK(err[2] < 1e-5, "float buffer accurate (%g)", err[2]);
        CHECK(err[0] > 10 * err[1] && err[0] > 1.0 / 255,
              "8-bit accumulation should err by more than a level (%g)", err[0]);
        /* tvpal_glr_create_fb changed the current program state: rebind. */
        tvpal_glr_free(r);
        REQUIRE(tvpal_glr_create(&r, W, H, &d) == 0, "%s", d.msg);
    }

    /* Changing palettes uploads nothing. */
    uint64_t up = tvpal_glr_uploads(r);
    REQUIRE(tvpal_glr_set_slices(r, f.w, f.h, dims[v.axis], &d) == 0, "%s", d.msg);
    for (uint32_t k = 0; k < f.count; k++)
        tvpal_glr_upload(r, sl[k].slice, sl[k].idx);
    CHECK(tvpal_glr_uploads(r) == up + f.count, "upload count");
    up = tvpal_glr_uploads(r);
    make_frame(dims, &v, &f, sl, &smooth, 0);
    tvpal_glr_draw(r, &f, gl, &d);
    CHECK(tvpal_glr_uploads(r) == up, "drawing with new palettes uploads "
          "no slice");

    /* Missing values: a block whose palette entry comes from a NaN row
     * value, with the default transparent NaN colour, draws exactly as
     * the same block made transparent by the TF (value 0, below the
     * sharp TF's band): what lies behind it shows, in GL and in the
     * reference; an opaque NaN colour hides it. */
    {
        static float gl2[W * H * 4];
        struct tvpal_tf nanred = sharp;
        const float red[4] = {1, 0, 0, 1};
        memcpy(nanred.nan_rgba, red, sizeof red);
        REQUIRE(sharp.nan_rgba[3] == 0, "transparent NaN by default");
        for (size_t vi = 0; vi < 4; vi++) {
            struct tvpal_view vn = {.dims = {24, 20, 16}, .width = W,
                                    .height = H, .ax_deg = views[vi][0],
                                    .ay_deg = views[vi][1], .zoom = 1.0};
            make_block_frame(dims, &vn, &f, sl, &sharp, 0.0f);
            draw_gl(r, &f, dims[vn.axis], gl);
            tvpal_render_ref(&f, ref);
            make_block_frame(dims, &vn, &f, sl, &sharp, NAN);
            draw_gl(r, &f, dims[vn.axis], gl2);
            tvpal_render_ref(&f, ref2);
            CHECK(!memcmp(gl, gl2, sizeof gl), "view %zu: gl: NaN block "
                  "differs from a transparent one", vi);
            CHECK(!memcmp(ref, ref2, sizeof ref), "view %zu: reference: NaN "
                  "block differs from a transparent one", vi);
            make_block_frame(dims, &vn, &f, sl, &nanred, NAN);
            draw_gl(r, &f, dims[vn.axis], gl2);
            tvpal_render_ref(&f, ref2);
            CHECK(memcmp(gl, gl2, sizeof gl) != 0, "view %zu: gl: an opaque "
                  "NaN colour draws nothing", vi);
            CHECK(memcmp(ref, ref2, sizeof ref) != 0, "view %zu: reference: "
                  "an opaque NaN colour draws nothing", vi);
            /* Where the opaque block shows, the transparent one shows
             * what lies behind it. */
            double behind = 0;
            for (size_t i = 0; i < (size_t)W * H; i++)
                if (memcmp(gl + 4 * i, gl2 + 4 * i, sizeof(float) * 4))
                    behind += gl[4 * i + 3];
            CHECK(behind > 1.0, "view %zu: nothing behind the block (%g)", vi,
                  behind);
        }
    }
    tvpal_glr_free(r);
    test_cross(&smooth, &sharp);
    tvpal_osmesa_free(ctx);
    free(idx_store);
    free(pal_store);
    return tt_done("test-render");
}
