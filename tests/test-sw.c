/* test-sw: the shear-warp CPU renderer against the CPU reference: PSNR at
 * least 35 dB on every axis and several views (shear-warp resamples twice:
 * slices onto the intermediate image, then the warp, so it is a little
 * blurrier than the reference's direct ray-slice sampling; 35 dB is about
 * 2/255 RMS on [0,1] images); the same image for 1 and 2 threads; empty
 * space skipping and early termination change no pixel; a transfer
 * function change gives the image a fresh start with it gives. */
#include "tvpal_render.h"
#include "tvpal_sw.h"
#include "tvpal_test.h"

#include <string.h>

#define W 120
#define H 104
#define NX 48
#define NY 40
#define NZ 32

static uint8_t *idx_store;
static float *pal_store;

static void make_frame(struct tvpal_view *v, struct tvpal_frame *f,
                       struct tvpal_frame_slice *sl, const struct tvpal_tf *tf)
{
    const uint32_t dims[3] = {NX, NY, NZ};
    tvpal_view_setup(v);
    unsigned a = v->axis;
    uint32_t n = dims[a], w = a == 0 ? NY : NX, h = a == 2 ? NY : NZ;
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
                double r = hypot((x - w / 2.0) / w, (b - h / 2.0) / h) +
                           0.3 * fabs((double)s / n - 0.5);
                I[x + w * b] = (uint8_t)(255 * fmax(0, 1 - 2 * r));
            }
        float row[256];
        for (int i = 0; i < 256; i++)
            row[i] = (float)i / 255.0f;
        tvpal_palette_build(tf, row, tvpal_view_opacity_exponent(v), 1.0,
                            pal_store + (size_t)1024 * s);
        sl[k] = (struct tvpal_frame_slice){s, s, I, pal_store + (size_t)1024 * s};
    }
}

static double psnr(const float *a, const double *b)
{
    double e = 0;
    for (size_t i = 0; i < (size_t)W * H * 4; i++)
        e += (a[i] - b[i]) * (a[i] - b[i]);
    e /= (double)W * H * 4;
    return e > 0 ? 10 * log10(1.0 / e) : INFINITY;
}

int main(void)
{
    idx_store = malloc((size_t)NX * NY * NZ);
    pal_store = malloc(sizeof(float) * 1024 * NX);
    static struct tvpal_frame_slice sl[NX];
    static float img[W * H * 4], img2[W * H * 4];
    static double ref[W * H * 4];
    struct tvpal_tf tf, tf2;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 0 0 0 0\n0.2 0 0 1 0\n"
                                "0.5 0 1 0 0.08\n1 1 0.2 0 0.5\n", 0, 1, &tf, &d) == 0,
            "%s", d.msg);
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 1 1 1 0.02\n1 1 0 1 0.2\n",
                                0, 1, &tf2, &d) == 0, "%s", d.msg);
    struct tvpal_sw *sw;
    REQUIRE(tvpal_sw_create(&sw) == 0, "create");
    static const double views[][3] = {{0, 0, 1}, {25, 35, 1}, {-40, 10, 1.3},
                                      {90, 5, 1}, {5, 95, 1}, {60, -120, 1},
                                      {170, 20, 2.5}, {15, 200, 0.8}};
    unsigned axes = 0;
    for (size_t vi = 0; vi < sizeof views / sizeof *views; vi++) {
        struct tvpal_view v = {.dims = {NX, NY, NZ}, .width = W, .height = H,
                               .ax_deg = views[vi][0], .ay_deg = views[vi][1],
                               .zoom = views[vi][2]};
        struct tvpal_frame f;
        make_frame(&v, &f, sl, &tf);
        axes |= 1u << v.axis;
        tvpal_render_ref(&f, ref);
        tvpal_sw_options(sw, 1, 1);
        REQUIRE(tvpal_sw_draw(sw, &f, img, &d) == 0, "%s", d.msg);
        double p = psnr(img, ref);
        CHECK(p >= 35.0, "view (%g,%g) zoom %g axis %c: %.2f dB", views[vi][0],
              views[vi][1], views[vi][2], "xyz"[v.axis], p);
        printf("view (%4g,%4g) zoom %.1f axis %c: shear-warp vs reference %.2f dB\n",
               views[vi][0], views[vi][1], views[vi][2], "xyz"[v.axis], p);
        tvpal_sw_options(sw, 2, 1);
        tvpal_sw_draw(sw, &f, img2, &d);
        CHECK(!memcmp(img, img2, sizeof img), "1 vs 2 threads differ");
        tvpal_sw_options(sw, 2, 0);
        tvpal_sw_draw(sw, &f, img2, &d);
        CHECK(!memcmp(img, img2, sizeof img), "skipping changed pixels");
        /* A TF change every frame: the same image as a fresh start. */
        struct tvpal_frame f2;
        make_frame(&v, &f2, sl, &tf2);
        tvpal_sw_options(sw, 2, 1);
        tvpal_sw_draw(sw, &f2, img2, &d);
        struct tvpal_sw *fresh;
        tvpal_sw_create(&fresh);
        tvpal_sw_draw(fresh, &f2, img, &d);
        CHECK(!memcmp(img, img2, sizeof img), "TF change differs from fresh");
        tvpal_sw_free(fresh);
    }
    CHECK(axes == 7, "all axes (%u)", axes);
    tvpal_sw_free(sw);
    free(idx_store);
    free(pal_store);
    return tt_done("test-sw");
}
