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

static void render(const struct tvpal_frame *f, double *rgba, int index_interp)
{
    const struct tvpal_view *v = f->view;
    const unsigned W = v->width, H = v->height;
    const int w = (int)f->w, h = (int)f->h;
    memset(rgba, 0, sizeof(double) * 4 * W * H);
    for (uint32_t k = 0; k < f->count; k++) {
        const struct tvpal_frame_slice *sl = &f->sl[k];
        struct plane p;
        plane_of(v, sl->slice, &p);
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
                int i0 = (int)floor(tx), j0 = (int)floor(ty);
                double fx = tx - i0, fy = ty - j0;
                int ia = i0 < 0 ? 0 : i0, ib = i0 + 1 >= w ? w - 1 : i0 + 1;
                int ja = j0 < 0 ? 0 : j0, jb = j0 + 1 >= h ? h - 1 : j0 + 1;
                if (ia > w - 1) ia = w - 1;
                if (ja > h - 1) ja = h - 1;
                if (ib < 0) ib = 0;
                if (jb < 0) jb = 0;
                const uint8_t *I = sl->idx;
                unsigned q00 = I[ia + (size_t)w * ja], q10 = I[ib + (size_t)w * ja],
                         q01 = I[ia + (size_t)w * jb], q11 = I[ib + (size_t)w * jb];
                double c[4];
                if (index_interp) {
                    double q = (1 - fy) * ((1 - fx) * q00 + fx * q10) +
                               fy * ((1 - fx) * q01 + fx * q11);
                    unsigned qi = (unsigned)floor(q + 0.5);
                    for (int ch = 0; ch < 4; ch++)
                        c[ch] = sl->palette[4 * qi + ch];
                } else {
                    for (int ch = 0; ch < 4; ch++)
                        c[ch] = (1 - fy) * ((1 - fx) * sl->palette[4 * q00 + ch] +
                                            fx * sl->palette[4 * q10 + ch]) +
                                fy * ((1 - fx) * sl->palette[4 * q01 + ch] +
                                      fx * sl->palette[4 * q11 + ch]);
                }
                double *d = rgba + 4 * ((size_t)py * W + px);
                double keep = 1.0 - c[3];
                for (int ch = 0; ch < 4; ch++)
                    d[ch] = c[ch] + keep * d[ch];
            }
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
