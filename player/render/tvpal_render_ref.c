/* tvpal_render_ref.c: the CPU reference renderer (see tvpal_render_ref.h).
 * Slow on purpose: per pixel and slice it intersects the ray with the slice
 * plane in double precision; it defines what the fast renderers must draw. */
#include "tvpal_render_ref.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Slice plane in eye space: corner c0 and edge vectors along a and b. */
struct plane {
    double o[3], ea[3], eb[3];
    double inv[2][2]; /* inverse of [ea.xy eb.xy] */
};

static void plane_of(const struct tvpal_view *v, uint32_t s, struct plane *p)
{
    double c1[3], c3[3];
    tvpal_view_slice_corner(v, s, 0, p->o);
    tvpal_view_slice_corner(v, s, 1, c1);
    tvpal_view_slice_corner(v, s, 3, c3);
    for (int i = 0; i < 3; i++) {
        p->ea[i] = c1[i] - p->o[i];
        p->eb[i] = c3[i] - p->o[i];
    }
    double det = p->ea[0] * p->eb[1] - p->eb[0] * p->ea[1];
    p->inv[0][0] = p->eb[1] / det;
    p->inv[0][1] = -p->eb[0] / det;
    p->inv[1][0] = -p->ea[1] / det;
    p->inv[1][1] = p->ea[0] / det;
}

/* One drawable slice as the sampler sees it: texel (a, b) of rows
 * [b0, b1) (b in slice texels) is idx(a, b), looked up in pal(b). */
struct src {
    const struct tvpal_frame *f;
    const struct tvpal_frame_slice *sl;   /* plain frames: the slice */
    uint32_t s;                           /* cross frames: view-axis slice */
    int w, h, b0, b1;                     /* rows held (taps) */
    int d0, d1;                           /* rows whose samples are drawn */
};

static unsigned texel(const struct src *q, int a, int b)
{
    if (!q->f->cross)
        return q->sl->idx[a + (size_t)q->w * b];
    const struct tvpal_frame_slice *z = &q->f->sl[b - q->b0];
    const size_t nx = q->f->w;
    return q->f->view->axis == 0 ? z->idx[q->s + nx * (size_t)a]
                                 : z->idx[(size_t)a + nx * q->s];
}

static const float *palette(const struct src *q, int b)
{
    return q->f->cross ? q->f->sl[b - q->b0].palette : q->sl->palette;
}

static void draw_slice(const struct tvpal_frame *f, const struct src *q,
                       uint32_t s, double *rgba, int index_interp)
{
    const struct tvpal_view *v = f->view;
    const unsigned W = v->width, H = v->height;
    const int w = q->w, h = q->h;
    struct plane p;
    plane_of(v, s, &p);
    for (unsigned py = 0; py < H; py++)
        for (unsigned px = 0; px < W; px++) {
            double ex, ey;
            tvpal_view_pixel_to_eye(v, px + 0.5, py + 0.5, &ex, &ey);
            double dx = ex - p.o[0], dy = ey - p.o[1];
            double u = p.inv[0][0] * dx + p.inv[0][1] * dy;
            double t = p.inv[1][0] * dx + p.inv[1][1] * dy;
            if (!(u >= 0 && u < 1 && t >= 0 && t < 1))
                continue;
            double tx = u * w - 0.5, ty = t * h - 0.5;
            if (!(t * h >= q->d0 && t * h < q->d1))
                continue;                   /* a row another slab holds */
            int i0 = (int)floor(tx), j0 = (int)floor(ty);
            double fx = tx - i0, fy = ty - j0;
            int ia = i0 < 0 ? 0 : i0, ib = i0 + 1 >= w ? w - 1 : i0 + 1;
            int ja = j0 < q->b0 ? q->b0 : j0;
            int jb = j0 + 1 >= q->b1 ? q->b1 - 1 : j0 + 1;
            if (ia > w - 1) ia = w - 1;
            if (ja > q->b1 - 1) ja = q->b1 - 1;
            if (ib < 0) ib = 0;
            if (jb < q->b0) jb = q->b0;
            unsigned q00 = texel(q, ia, ja), q10 = texel(q, ib, ja),
                     q01 = texel(q, ia, jb), q11 = texel(q, ib, jb);
            const float *pa = palette(q, ja), *pb = palette(q, jb);
            double c[4];
            if (index_interp) {
                /* Indices mixed across rows of different palettes mean
                 * nothing; this mode is for plain frames (it takes the
                 * nearer row's palette). */
                double qq = (1 - fy) * ((1 - fx) * q00 + fx * q10) +
                            fy * ((1 - fx) * q01 + fx * q11);
                unsigned qi = (unsigned)floor(qq + 0.5);
                const float *pn = fy < 0.5 ? pa : pb;
                for (int ch = 0; ch < 4; ch++)
                    c[ch] = pn[4 * qi + ch];
            } else {
                for (int ch = 0; ch < 4; ch++)
                    c[ch] = (1 - fy) * ((1 - fx) * pa[4 * q00 + ch] +
                                        fx * pa[4 * q10 + ch]) +
                            fy * ((1 - fx) * pb[4 * q01 + ch] +
                                  fx * pb[4 * q11 + ch]);
            }
            double *d = rgba + 4 * ((size_t)py * W + px);
            double keep = 1.0 - c[3];
            for (int ch = 0; ch < 4; ch++)
                d[ch] = c[ch] + keep * d[ch];
        }
}

static void render(const struct tvpal_frame *f, double *rgba, int index_interp)
{
    const struct tvpal_view *v = f->view;
    memset(rgba, 0, sizeof(double) * 4 * v->width * v->height);
    if (!f->cross) {
        for (uint32_t k = 0; k < f->count; k++) {
            const struct src q = {f, &f->sl[k], 0, (int)f->w, (int)f->h, 0,
                                  (int)f->h, 0, (int)f->h};
            draw_slice(f, &q, f->sl[k].slice, rgba, index_interp);
        }
        return;
    }
    if (!f->count || f->stride < 1)
        return;
    uint32_t w, h, n;
    tvpal_frame_cross_geometry(f, &w, &h, &n);
    const int b0 = (int)f->sl[0].slice;
    uint32_t d0, d1;
    tvpal_frame_cross_draw_rows(f, &d0, &d1);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t s = v->descending ? n - 1 - i : i;
        if (s % f->stride != f->phase)
            continue;
        const struct src q = {f, NULL, s, (int)w, (int)h, b0,
                              b0 + (int)f->count, (int)d0, (int)d1};
        draw_slice(f, &q, s, rgba, index_interp);
    }
}

void tvpal_render_ref(const struct tvpal_frame *f, double *rgba)
{
    render(f, rgba, 0);
}

void tvpal_render_ref_index_interp(const struct tvpal_frame *f,
                                   double *rgba)
{
    render(f, rgba, 1);
}

/* ------------------------------------------------ the renderer interface */

struct tvpal_ref {
    double *img;
    size_t max_pixels;
};

int tvpal_ref_create(struct tvpal_ref **out, size_t max_pixels)
{
    if (max_pixels > SIZE_MAX / (4 * sizeof(double)))
        return TVPAL_E_OVERFLOW;
    struct tvpal_ref *ref = calloc(1, sizeof *ref);
    if (!ref)
        return TVPAL_E_NOMEM;
    ref->img = malloc(4 * sizeof(double) * (max_pixels ? max_pixels : 1));
    if (!ref->img) {
        free(ref);
        return TVPAL_E_NOMEM;
    }
    ref->max_pixels = max_pixels;
    *out = ref;
    return 0;
}

void tvpal_ref_free(struct tvpal_ref *ref)
{
    if (!ref)
        return;
    free(ref->img);
    free(ref);
}

const double *tvpal_ref_image(const struct tvpal_ref *ref)
{
    return ref->img;
}

static int ref_set(void *c, uint32_t w, uint32_t h, uint32_t n,
                   struct tvpal_diag *d)
{
    return 0; /* draws straight from the frame's slices */
}

static void ref_up(void *c, uint32_t layer, const uint8_t *idx)
{
}

static int ref_draw(void *c, const struct tvpal_frame *f, float *rgba,
                    struct tvpal_diag *d)
{
    struct tvpal_ref *ref = c;
    const size_t np = (size_t)f->view->width * f->view->height;
    if (np > ref->max_pixels)
        return tvpal_diag_set(d, TVPAL_E_INVAL, "reference renderer: %ux%u "
                              "image, made for %zu pixels", f->view->width,
                              f->view->height, ref->max_pixels);
    tvpal_render_ref(f, ref->img);
    for (size_t i = 0; i < 4 * np; i++)
        rgba[i] = (float)ref->img[i];
    return 0;
}

static void ref_describe(const void *c, char *buf, size_t cap)
{
    snprintf(buf, cap, "double-precision reference");
}

void tvpal_ref_renderer(struct tvpal_ref *ref, struct tvpal_renderer *out)
{
    *out = (struct tvpal_renderer){.name = "ref", .ctx = ref,
                                   .set_slices = ref_set, .upload = ref_up,
                                   .draw = ref_draw, .describe = ref_describe};
}
