/* tvpal_frame.c: per-slice palettes (see tvpal_frame.h). */
#include "tvpal_frame.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* Opacity correction 1 - (1 - a)^e through a table over a in [0, 1],
 * rebuilt when e changes (once per view, not 65536 pow() per frame).
 * Linear interpolation in 4096 cells: error < 1e-6 for e <= 16, a < 1;
 * a = 1 stays exactly 1 and a = 0 exactly 0.  One table per thread. */
#define ALPHA_CELLS 4096
static _Thread_local double lut_e = -1.0;
static _Thread_local float lut[ALPHA_CELLS + 1];

static inline double corrected(double a, double e)
{
    if (e != lut_e) {
        for (int k = 0; k <= ALPHA_CELLS; k++)
            lut[k] = (float)(1.0 - pow(1.0 - (double)k / ALPHA_CELLS, e));
        lut_e = e;
    }
    double x = a * ALPHA_CELLS;
    int k = (int)x;
    if (k >= ALPHA_CELLS)
        return 1.0;
    double f = x - k;
    return lut[k] + f * (lut[k + 1] - lut[k]);
}

int tvpal_palette_build(const struct tvpal_tf *tf, const float *row,
                        double opacity_exponent, double opacity_scale,
                        float *palette)
{
    int clear = 1;
    for (unsigned i = 0; i < 256; i++) {
        float ev[4];
        const float *c = tf->nan_rgba; /* a missing value */
        if (!isnan(row[i])) {
            tvpal_tf_eval(tf, row[i], ev);
            c = ev;
        }
        double a = c[3] * opacity_scale;
        a = a < 0 ? 0 : a > 1 ? 1 : a;
        a = corrected(a, opacity_exponent);
        float *p = palette + 4 * i;
        p[0] = (float)(c[0] * a);
        p[1] = (float)(c[1] * a);
        p[2] = (float)(c[2] * a);
        p[3] = (float)a;
        clear &= p[3] == 0.0f;
    }
    return clear;
}

static int none_set(void *ctx, uint32_t w, uint32_t h, uint32_t n,
                    struct tvpal_diag *diag)
{
    return 0;
}

static void none_upload(void *ctx, uint32_t layer, const uint8_t *idx)
{
}

static int none_draw(void *ctx, const struct tvpal_frame *f, float *rgba,
                     struct tvpal_diag *diag)
{
    memset(rgba, 0, sizeof(float) * 4 * f->view->width * f->view->height);
    return 0;
}

static void none_describe(const void *ctx, char *buf, size_t cap)
{
    snprintf(buf, cap, "read and decode only");
}

void tvpal_renderer_none(struct tvpal_renderer *r)
{
    *r = (struct tvpal_renderer){.name = "none", .set_slices = none_set,
                                 .upload = none_upload, .draw = none_draw,
                                 .describe = none_describe};
}

void tvpal_frame_cut_row(uint8_t *copy, unsigned axis, uint32_t rows,
                         uint32_t k, const uint8_t *idx, uint32_t nx,
                         uint32_t ny)
{
    if (axis == 1) {       /* y slice s, row k = z row s */
        for (uint32_t s = 0; s < ny; s++)
            memcpy(copy + ((size_t)s * rows + k) * nx, idx + (size_t)s * nx, nx);
        return;
    }
    enum { B = 16 };       /* x slice s, row k: texel a = idx[s + nx a] */
    for (uint32_t s0 = 0; s0 < nx; s0 += B) {
        const uint32_t s1 = s0 + B < nx ? s0 + B : nx;
        for (uint32_t a0 = 0; a0 < ny; a0 += B) {
            const uint32_t a1 = a0 + B < ny ? a0 + B : ny;
            for (uint32_t s = s0; s < s1; s++) {
                uint8_t *dst = copy + ((size_t)s * rows + k) * ny;
                for (uint32_t a = a0; a < a1; a++)
                    dst[a] = idx[s + (size_t)nx * a];
            }
        }
    }
}
