/* tvpal_sw.c: shear-warp CPU palette renderer (see tvpal_sw.h). */
#include "tvpal_sw.h"
#include "tvpal_cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#ifdef _OPENMP
#include <omp.h>
#endif

struct tvpal_sw {
    float *im;            /* intermediate image, RGBA premultiplied */
    size_t cap;           /* floats */
    int threads, skip;
    double t_classify, t_composite, t_warp;
};

int tvpal_sw_create(struct tvpal_sw **out)
{
    struct tvpal_sw *r = calloc(1, sizeof *r);
    if (!r)
        return TVPAL_E_NOMEM;
    r->skip = 1;
    *out = r;
    return 0;
}

void tvpal_sw_free(struct tvpal_sw *r)
{
    if (!r)
        return;
    free(r->im);
    free(r);
}

void tvpal_sw_options(struct tvpal_sw *r, int threads, int skip)
{
    r->threads = threads;
    r->skip = skip;
}

void tvpal_sw_times(const struct tvpal_sw *r, double *classify_ms,
                    double *composite_ms, double *warp_ms)
{
    *classify_ms = r->t_classify;
    *composite_ms = r->t_composite;
    *warp_ms = r->t_warp;
}

/* Geometry of the factorization, in texel units of the slices. */
struct geom {
    double minv[2][2];    /* eye xy -> in-slice object coords (a, b) */
    double ha, hb;        /* half extents along the slice's two axes */
    double sx, sy;        /* texel shift per object unit of depth */
    double u0, v0;        /* base texel coords of intermediate pixel 0 */
    double sc;            /* intermediate pixels per texel */
    unsigned wi, hi;      /* intermediate image size */
};

static double slice_depth(const struct tvpal_view *v, uint32_t s)
{
    return ((s + 0.5) / v->dims[v->axis] * 2.0 - 1.0) * v->half[v->axis];
}

/* Eye (x, y) -> base texel coords (the slice at depth 0). */
static inline void eye_to_base(const struct geom *g, unsigned w, unsigned h,
                               double ex, double ey, double *tu, double *tv)
{
    double a = g->minv[0][0] * ex + g->minv[0][1] * ey;
    double b = g->minv[1][0] * ex + g->minv[1][1] * ey;
    *tu = (a + g->ha) / (2 * g->ha) * w;
    *tv = (b + g->hb) / (2 * g->hb) * h;
}

static int setup(const struct tvpal_frame *f, struct geom *g)
{
    const struct tvpal_view *v = f->view;
    const unsigned ax = v->axis;
    const unsigned ua = ax == 0 ? 1 : 0, ub = ax == 2 ? 1 : 2;
    double m00 = v->rot[0][ua], m01 = v->rot[0][ub];
    double m10 = v->rot[1][ua], m11 = v->rot[1][ub];
    double det = m00 * m11 - m01 * m10;
    if (fabs(det) < 1e-12)
        return TVPAL_E_INVAL;
    g->minv[0][0] = m11 / det;
    g->minv[0][1] = -m01 / det;
    g->minv[1][0] = -m10 / det;
    g->minv[1][1] = m00 / det;
    g->ha = v->half[ua];
    g->hb = v->half[ub];
    /* A point at depth c appears where the base point is shifted by
     * c * Minv * Ra: slice texel = base texel - c * shift. */
    double ra = v->rot[0][ax], rb = v->rot[1][ax];
    double da = g->minv[0][0] * ra + g->minv[0][1] * rb;
    double db = g->minv[1][0] * ra + g->minv[1][1] * rb;
    g->sx = da / (2 * g->ha) * f->w;
    g->sy = db / (2 * g->hb) * f->h;
    /* Resolution: as many intermediate pixels per texel as the output
     * shows (at least 1, at most 4). */
    double texel = 2 * g->ha / f->w;
    double texel_b = 2 * g->hb / f->h;
    texel = texel > texel_b ? texel : texel_b;
    double pix = fmin(2 * v->sx / v->width, 2 * v->sy / v->height);
    /* Not rounded up to a whole factor: a volume 15% larger than its voxel
     * count gets 1.15 pixels per texel, not twice the work. */
    double sc = texel / pix;
    g->sc = sc < 1 ? 1 : sc > 4 ? 4 : sc;
    /* Extent: every slice's footprint, shifted. */
    double c0 = slice_depth(v, 0), c1 = slice_depth(v, v->dims[ax] - 1);
    double umin = fmin(c0 * g->sx, c1 * g->sx), umax = fmax(c0 * g->sx, c1 * g->sx);
    double vmin = fmin(c0 * g->sy, c1 * g->sy), vmax = fmax(c0 * g->sy, c1 * g->sy);
    g->u0 = floor(umin) - 1;
    g->v0 = floor(vmin) - 1;
    g->wi = (unsigned)ceil((umax + f->w + 1 - g->u0) * g->sc);
    g->hi = (unsigned)ceil((vmax + f->h + 1 - g->v0) * g->sc);
    return 0;
}

int tvpal_sw_draw(struct tvpal_sw *r, const struct tvpal_frame *f,
                  float *rgba, struct tvpal_diag *diag)
{
    const struct tvpal_view *v = f->view;
    struct geom g;
    double t0 = tvpal_now();
    if (setup(f, &g) < 0)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "degenerate view");
    size_t need = (size_t)g.wi * g.hi * 4;
    if (need > r->cap) {
        float *n = realloc(r->im, need * sizeof *n);
        if (!n)
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "intermediate image");
        r->im = n;
        r->cap = need;
    }
    float *im = r->im;
    memset(im, 0, need * sizeof *im);
    const int w = (int)f->w, h = (int)f->h;
    const unsigned wi = g.wi, hi = g.hi;
    const double sc = g.sc;
    const int skip = r->skip;
    double t1 = tvpal_now();
    r->t_classify = (t1 - t0) * 1e3;
#ifdef _OPENMP
    int nt = r->threads > 0 ? r->threads : omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(nt)
#endif
    for (unsigned j = 0; j < hi; j++) {
        float *row = im + (size_t)4 * wi * j;
        /* Front to back: the frame lists slices back to front. */
        for (uint32_t k = f->count; k-- > 0;) {
            const struct tvpal_frame_slice *sl = &f->sl[k];
            const double c = slice_depth(v, sl->slice);
            const double ty = g.v0 + (j + 0.5) / sc - c * g.sy;
            if (!(ty >= 0 && ty < h))
                continue;
            const double ta = g.u0 - c * g.sx; /* tx = ta + (i + 0.5) / sc */
            double ilo = ceil((0 - ta) * sc - 0.5), ihi = ceil((w - ta) * sc - 0.5);
            int i0 = ilo < 0 ? 0 : (int)ilo, i1 = ihi > wi ? (int)wi : (int)ihi;
            const double yy = ty - 0.5;
            int y0 = (int)floor(yy);
            const float fy = (float)(yy - y0);
            int ya = y0 < 0 ? 0 : y0, yb = y0 + 1 >= h ? h - 1 : y0 + 1;
            const uint8_t *ra = sl->idx + (size_t)w * ya, *rb = sl->idx + (size_t)w * yb;
            const float *pal = sl->palette;
            /* x = (i + 0.5) / sc + ta - 0.5; floor by an offset cast (x >
             * -1 here, the inside test guards the edges). */
            const float xoff = (float)(ta - 0.5), inv = (float)(1.0 / sc);
#ifdef __SSE2__
            const __m128 vfy = _mm_set1_ps(fy);
#endif
            for (int i = i0; i < i1; i++) {
                float *d = row + 4 * i;
                if (skip && 1.0f - d[3] == 0.0f)
                    continue; /* opaque: nothing can show through */
                float xx = ((float)i + 0.5f) * inv + xoff;
                int x0 = (int)(xx + 1.0f) - 1;
                float fx = xx - (float)x0;
                int xa = x0 < 0 ? 0 : x0, xb = x0 + 1 >= w ? w - 1 : x0 + 1;
                const float *p00 = pal + 4 * ra[xa], *p10 = pal + 4 * ra[xb];
                const float *p01 = pal + 4 * rb[xa], *p11 = pal + 4 * rb[xb];
                if (skip && p00[3] == 0.0f && p10[3] == 0.0f && p01[3] == 0.0f &&
                    p11[3] == 0.0f)
                    continue; /* empty space: adds exactly nothing */
                float keep = 1.0f - d[3];
#ifdef __SSE2__
                __m128 vfx = _mm_set1_ps(fx);
                __m128 a00 = _mm_loadu_ps(p00), a10 = _mm_loadu_ps(p10);
                __m128 a01 = _mm_loadu_ps(p01), a11 = _mm_loadu_ps(p11);
                __m128 a = _mm_add_ps(a00, _mm_mul_ps(vfx, _mm_sub_ps(a10, a00)));
                __m128 b = _mm_add_ps(a01, _mm_mul_ps(vfx, _mm_sub_ps(a11, a01)));
                __m128 cv = _mm_add_ps(a, _mm_mul_ps(vfy, _mm_sub_ps(b, a)));
                _mm_storeu_ps(d, _mm_add_ps(_mm_loadu_ps(d),
                                            _mm_mul_ps(_mm_set1_ps(keep), cv)));
#else
                for (int ch = 0; ch < 4; ch++) {
                    float a = p00[ch] + fx * (p10[ch] - p00[ch]);
                    float b = p01[ch] + fx * (p11[ch] - p01[ch]);
                    d[ch] += keep * (a + fy * (b - a));
                }
#endif
            }
        }
    }
    double t2 = tvpal_now();
    r->t_composite = (t2 - t1) * 1e3;
    /* Warp: every output pixel samples the intermediate image. */
    const unsigned W = v->width, H = v->height;
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(nt)
#endif
    for (unsigned py = 0; py < H; py++)
        for (unsigned px = 0; px < W; px++) {
            double ex, ey, tu, tv;
            tvpal_view_pixel_to_eye(v, px + 0.5, py + 0.5, &ex, &ey);
            eye_to_base(&g, f->w, f->h, ex, ey, &tu, &tv);
            double xi = (tu - g.u0) * sc - 0.5, yi = (tv - g.v0) * sc - 0.5;
            float *o = rgba + 4 * ((size_t)py * W + px);
            int x0 = (int)floor(xi), y0 = (int)floor(yi);
            float fx = (float)(xi - x0), fy = (float)(yi - y0);
            float acc[4] = {0, 0, 0, 0};
            for (int dy = 0; dy < 2; dy++)
                for (int dx = 0; dx < 2; dx++) {
                    int x = x0 + dx, y = y0 + dy;
                    if (x < 0 || y < 0 || x >= (int)wi || y >= (int)hi)
                        continue;
                    float wgt = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
                    const float *s = im + 4 * ((size_t)y * wi + x);
                    for (int ch = 0; ch < 4; ch++)
                        acc[ch] += wgt * s[ch];
                }
            memcpy(o, acc, sizeof acc);
        }
    r->t_warp = (tvpal_now() - t2) * 1e3;
    return 0;
}
