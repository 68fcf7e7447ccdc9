/* test-sw-cross: cross frames (a single-copy dataset's z slices drawn
 * along x or y) in the shear-warp renderer and the reference renderer.
 *
 * The index mapping, independently: with one palette for every slice, a
 * cross frame of the z slices draws exactly (reference: every double; cpu:
 * every bit) what a plain frame of the transposed x or y slices draws,
 * with stride 1 and with stride 2; that also checks that the cpu
 * renderer's conservative tiles (derived from the z slices' tiles) skip
 * only transparent texels.  With a palette per z slice (each row of a
 * cross slice its own): cpu against the reference within the plain path's
 * floor, 35 dB (see test-sw), for whole volumes and for a slab of rows
 * (a cluster node's); 1 and 2 threads give the same bits; new indices of
 * one z slice (upload) and a palette change give what a fresh renderer
 * draws; one renderer drawing x, y, z, x in turn gives what fresh ones
 * draw (its transposed copies stay right).  Errors: a cross frame along z,
 * non-consecutive z slices, a phase not below the stride are refused. */
#include "tvpal_render_ref.h"
#include "tvpal_sw.h"
#include "tvpal_test.h"

#include <string.h>

enum { NX = 40, NY = 36, NZ = 28, W = 112, H = 96 };

static uint8_t zdata[NZ][NY][NX];
static uint8_t tdata[NX > NY ? NX : NY][NZ * (NX > NY ? NX : NY)];   /* slice s: NZ rows of w */
static float pals[NZ][1024], one_pal[1024];
static struct tvpal_frame_slice zsl[NZ], psl[NX > NY ? NX : NY];

static void fill_volume(int noisy)
{
    for (int z = 0; z < NZ; z++)
        for (int y = 0; y < NY; y++)
            for (int x = 0; x < NX; x++) {
                double r = hypot((x - NX / 2.0) / NX, (y - NY / 2.0) / NY) +
                           0.4 * fabs((double)z / NZ - 0.5);
                double v = 255 * fmax(0, 1 - 2 * r);
                if (noisy)
                    v = fmin(255, v + (double)(tt_rand64() & 63));
                zdata[z][y][x] = (uint8_t)v;
            }
}

/* Palettes: one per z slice (distinct values per slice) or, with same,
 * every slice the same. */
static void fill_palettes(const struct tvpal_tf *tf, const struct tvpal_view *v,
                          int same)
{
    float row[256];
    for (int z = 0; z < NZ; z++) {
        for (int i = 0; i < 256; i++)
            row[i] = (float)i / 255.0f + (same ? 0.0f : 0.004f * z);
        tvpal_palette_build(tf, row, tvpal_view_opacity_exponent(v), 1.0, pals[z]);
    }
    for (int i = 0; i < 256; i++)
        row[i] = (float)i / 255.0f;
    tvpal_palette_build(tf, row, tvpal_view_opacity_exponent(v), 1.0, one_pal);
}

/* The cross frame of z slices [z0, z0 + count); same: one palette. */
static void cross_frame(const struct tvpal_view *v, uint32_t z0, uint32_t count,
                        uint32_t stride, uint32_t phase, int same,
                        struct tvpal_frame *f)
{
    for (uint32_t k = 0; k < count; k++)
        zsl[k] = (struct tvpal_frame_slice){z0 + k, k, &zdata[z0 + k][0][0],
                                            same ? one_pal : pals[z0 + k]};
    *f = (struct tvpal_frame){.view = v, .w = NX, .h = NY, .count = count,
                              .sl = zsl, .cross = 1, .stride = stride,
                              .phase = phase};
}

/* The plain frame of the transposed slices of the view's axis with one
 * palette, the slices s % stride == phase, back to front. */
static void plain_frame(const struct tvpal_view *v, uint32_t stride,
                        uint32_t phase, struct tvpal_frame *f)
{
    const unsigned a = v->axis;
    const uint32_t n = a == 0 ? NX : NY, w = a == 0 ? NY : NX;
    uint32_t count = 0;
    for (uint32_t s = 0; s < n; s++)
        for (uint32_t b = 0; b < NZ; b++)
            for (uint32_t t = 0; t < w; t++)
                tdata[s][b * w + t] = a == 0 ? zdata[b][t][s] : zdata[b][s][t];
    for (uint32_t i = 0; i < n; i++) {
        uint32_t s = v->descending ? n - 1 - i : i;
        if (s % stride == phase)
            psl[count++] = (struct tvpal_frame_slice){s, s, tdata[s], one_pal};
    }
    *f = (struct tvpal_frame){.view = v, .w = w, .h = NZ, .count = count, .sl = psl};
}

static void draw(struct tvpal_sw *sw, const struct tvpal_frame *f, float *img)
{
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_sw_draw(sw, f, img, &d) == 0, "%s", d.msg);
}

/* A fresh renderer prepared for f's slices draws f. */
static void draw_fresh(const struct tvpal_frame *f, int threads, int exact,
                       float *img)
{
    struct tvpal_sw *sw;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_sw_create(&sw) == 0, "create");
    tvpal_sw_options(sw, threads, 1, 1);
    tvpal_sw_set_exact(sw, exact);
    REQUIRE(tvpal_sw_set_slices(sw, f->w, f->h, f->cross ? NZ : 64, &d) == 0,
            "%s", d.msg);
    draw(sw, f, img);
    tvpal_sw_free(sw);
}

static double psnr(const float *a, const double *b, size_t n)
{
    double e = 0;
    for (size_t i = 0; i < n; i++)
        e += (a[i] - b[i]) * (a[i] - b[i]);
    e /= (double)n;
    return e > 0 ? 10 * log10(1.0 / e) : INFINITY;
}

int main(void)
{
    const size_t np = (size_t)4 * W * H;
    float *img = malloc(sizeof(float) * np), *img2 = malloc(sizeof(float) * np);
    double *ref = malloc(sizeof(double) * np), *ref2 = malloc(sizeof(double) * np);
    REQUIRE(img && img2 && ref && ref2, "memory");
    struct tvpal_tf tf, dense;
    struct tvpal_diag d = {{0}};
    /* tf: transparent below 0.25 (empty tiles to skip); dense: none. */
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 0 0 0 0\n0.25 0 0 1 0\n"
                                "0.5 0 1 0 0.1\n1 1 0.2 0 0.6\n", 0, 1, &tf, &d) == 0,
            "%s", d.msg);
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 1 1 1 0.03\n1 1 0 1 0.3\n",
                                0, 1, &dense, &d) == 0, "%s", d.msg);
    /* Views whose principal axis is x or y, between axes and zoomed. */
    static const double views[][3] = {{0, 90, 1}, {0, -70, 1.2}, {90, 0, 1},
                                      {-80, 20, 1}, {30, 60, 2.5}, {60, -20, 0.8},
                                      {100, 30, 4}, {10, 130, 1.5}};
    unsigned axes = 0;
    for (int noisy = 0; noisy <= 1; noisy++) {
        fill_volume(noisy);
        for (size_t vi = 0; vi < sizeof views / sizeof *views; vi++) {
            const struct tvpal_tf *t = vi % 2 ? &dense : &tf;
            struct tvpal_view v = {.dims = {NX, NY, NZ}, .width = W, .height = H,
                                   .ax_deg = views[vi][0], .ay_deg = views[vi][1],
                                   .zoom = views[vi][2]};
            tvpal_view_setup(&v);
            REQUIRE(v.axis != 2, "view %zu is along z", vi);
            axes |= 1u << v.axis;
            struct tvpal_frame f, pf;
            /* One palette: cross = plain of the transposed slices. */
            fill_palettes(t, &v, 1);
            for (uint32_t stride = 1; stride <= 2; stride++) {
                cross_frame(&v, 0, NZ, stride, stride - 1, 1, &f);
                plain_frame(&v, stride, stride - 1, &pf);
                tvpal_render_ref(&f, ref);
                tvpal_render_ref(&pf, ref2);
                CHECK(!memcmp(ref, ref2, sizeof(double) * np),
                      "view %zu stride %u: reference cross != plain", vi, stride);
                for (int exact = 0; exact <= 1; exact++) {
                    draw_fresh(&f, 1, exact, img);
                    draw_fresh(&pf, 1, exact, img2);
                    CHECK(!memcmp(img, img2, sizeof(float) * np),
                          "view %zu stride %u exact %d: cpu cross != plain", vi,
                          stride, exact);
                }
            }
            /* A palette per z slice: against the reference. */
            fill_palettes(t, &v, 0);
            cross_frame(&v, 0, NZ, 1, 0, 0, &f);
            tvpal_render_ref(&f, ref);
            draw_fresh(&f, 1, 1, img);
            double p = psnr(img, ref, np);
            CHECK(p >= 35.0, "view %zu axis %c: %.2f dB", vi, "xyz"[v.axis], p);
            draw_fresh(&f, 2, 1, img2);
            CHECK(!memcmp(img, img2, sizeof(float) * np), "view %zu: 1 vs 2 threads", vi);
            /* A slab of rows, as a cluster node holds. */
            cross_frame(&v, 7, 12, 1, 0, 0, &f);
            tvpal_render_ref(&f, ref2);
            draw_fresh(&f, 1, 1, img2);
            double ps = psnr(img2, ref2, np);
            CHECK(ps >= 35.0, "view %zu slab 7+12: %.2f dB", vi, ps);
            if (!noisy)
                printf("view (%4g,%4g) zoom %.1f axis %c: cross vs reference "
                       "%.2f dB, slab of rows %.2f dB\n", views[vi][0],
                       views[vi][1], views[vi][2], "xyz"[v.axis], p, ps);
        }
    }
    CHECK(axes == 3, "views cover x and y (mask %u)", axes);

    /* One renderer: new indices of a z slice, a palette change, and axis
     * changes x, y, z, x give what fresh renderers draw. */
    fill_volume(1);
    struct tvpal_sw *sw;
    REQUIRE(tvpal_sw_create(&sw) == 0, "create");
    tvpal_sw_options(sw, 2, 1, 1);
    REQUIRE(tvpal_sw_set_slices(sw, NX, NY, NZ, &d) == 0, "%s", d.msg);
    static const double seq[][2] = {{0, 90}, {90, 0}, {0, 0}, {0, 80}, {85, 10}};
    for (int round = 0; round < 2; round++)
        for (size_t i = 0; i < sizeof seq / sizeof *seq; i++) {
            struct tvpal_view v = {.dims = {NX, NY, NZ}, .width = W, .height = H,
                                   .ax_deg = seq[i][0], .ay_deg = seq[i][1], .zoom = 1};
            tvpal_view_setup(&v);
            fill_palettes(round ? &dense : &tf, &v, 0);
            struct tvpal_frame f;
            cross_frame(&v, 0, NZ, 1, 0, 0, &f);
            if (v.axis == 2) {   /* the same z slices as a plain frame */
                f.cross = 0;
                if (v.descending)
                    for (uint32_t k = 0; k < NZ / 2; k++) {
                        struct tvpal_frame_slice tmp = zsl[k];
                        zsl[k] = zsl[NZ - 1 - k];
                        zsl[NZ - 1 - k] = tmp;
                    }
            }
            if (i == 3) {        /* z slice 5 gets new indices */
                for (int y = 0; y < NY; y++)
                    for (int x = 0; x < NX; x++)
                        zdata[5][y][x] = (uint8_t)(255 - zdata[5][y][x]);
                tvpal_sw_upload(sw, 5);
            }
            draw(sw, &f, img);
            draw_fresh(&f, 2, 0, img2);
            CHECK(!memcmp(img, img2, sizeof(float) * np),
                  "round %d view %zu (axis %c): reused renderer != fresh", round,
                  i, "xyz"[v.axis]);
        }

    /* Slabs with ghost rows (cluster nodes): three nodes each draw the
     * samples of their own rows, their taps reaching one row of each
     * neighbour; composited "over" in depth order along z they give the
     * one node's image: the reference exactly (to rounding), the cpu
     * renderer within the cluster tolerance of tests/cluster.sh (each
     * node warps its own image).  Without the ghost rows the taps clamp
     * at the boundaries, which the reference shows. */
    fill_volume(0);
    {
        static const uint32_t cut[4] = {0, 9, 19, NZ};
        double *acc = malloc(sizeof(double) * np), *part = malloc(sizeof(double) * np);
        float *facc = malloc(sizeof(float) * np);
        REQUIRE(acc && part && facc, "memory");
        static const double sv[][2] = {{0, 90}, {90, 0}, {30, 60}, {-80, 20}};
        for (size_t vi = 0; vi < sizeof sv / sizeof *sv; vi++)
            for (int ghosts = 1; ghosts >= 0; ghosts--) {
                struct tvpal_view v = {.dims = {NX, NY, NZ}, .width = W, .height = H,
                                       .ax_deg = sv[vi][0], .ay_deg = sv[vi][1], .zoom = 1};
                tvpal_view_setup(&v);
                fill_palettes(&dense, &v, 0);
                struct tvpal_frame f;
                cross_frame(&v, 0, NZ, 1, 0, 0, &f);
                tvpal_render_ref(&f, ref);
                draw_fresh(&f, 1, 1, img);
                const int far_high = -v.rot[2][2] > 0;   /* high z is farther */
                memset(acc, 0, sizeof(double) * np);
                memset(facc, 0, sizeof(float) * np);
                for (int i = 0; i < 3; i++) {
                    int node = far_high ? i : 2 - i;     /* front to back */
                    uint32_t r0 = cut[node], r1 = cut[node + 1];
                    uint32_t h0 = ghosts && r0 > 0 ? r0 - 1 : r0;
                    uint32_t h1 = ghosts && r1 < NZ ? r1 + 1 : r1;
                    cross_frame(&v, h0, h1 - h0, 1, 0, 0, &f);
                    f.draw_begin = r0;
                    f.draw_end = r1;
                    tvpal_render_ref(&f, part);
                    draw_fresh(&f, 1, 1, img2);
                    for (size_t p = 0; p < (size_t)W * H; p++) {
                        double keep = 1 - acc[4 * p + 3];
                        float fkeep = 1 - facc[4 * p + 3];
                        for (int c = 0; c < 4; c++) {
                            acc[4 * p + c] += keep * part[4 * p + c];
                            facc[4 * p + c] += fkeep * img2[4 * p + c];
                        }
                    }
                }
                double dmax = 0;
                for (size_t i = 0; i < np; i++)
                    dmax = fmax(dmax, fabs(acc[i] - ref[i]));
                if (ghosts) {
                    CHECK(dmax < 1e-9, "view %zu: three slabs with ghosts %.3g from one", vi, dmax);
                    double pc = 0;
                    for (size_t i = 0; i < np; i++)
                        part[i] = img[i];
                    pc = psnr(facc, part, np);
                    CHECK(pc >= 40.0, "view %zu: cpu three slabs vs one %.2f dB", vi, pc);
                    printf("view (%g,%g) three slabs with ghost rows: reference %.2g from "
                           "one node, cpu %.2f dB against one node\n", sv[vi][0], sv[vi][1],
                           dmax, pc);
                } else {
                    CHECK(dmax > 1e-3, "view %zu: clamped slabs %.3g from one (no seam?)", vi, dmax);
                    printf("view (%g,%g) three slabs without ghosts: %.3g from one node\n",
                           sv[vi][0], sv[vi][1], dmax);
                }
            }
        free(acc);
        free(part);
        free(facc);
    }

    /* Refused frames. */
    {
        struct tvpal_view v = {.dims = {NX, NY, NZ}, .width = W, .height = H,
                               .zoom = 1};
        tvpal_view_setup(&v);
        struct tvpal_frame f;
        cross_frame(&v, 0, NZ, 1, 0, 0, &f);
        CHECK(v.axis == 2 && tvpal_sw_draw(sw, &f, img, &d) == TVPAL_E_INVAL,
              "a cross frame along z is refused");
        v.ay_deg = 90;
        tvpal_view_setup(&v);
        cross_frame(&v, 0, NZ, 2, 2, 0, &f);
        CHECK(tvpal_sw_draw(sw, &f, img, &d) == TVPAL_E_INVAL, "phase 2 of stride 2");
        cross_frame(&v, 0, NZ, 1, 0, 0, &f);
        zsl[3].slice = 9;
        CHECK(tvpal_sw_draw(sw, &f, img, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "consecutive"), "non-consecutive z slices: %s", d.msg);
    }
    tvpal_sw_free(sw);
    free(img);
    free(img2);
    free(ref);
    free(ref2);
    return tt_done("test-sw-cross");
}
