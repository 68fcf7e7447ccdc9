/* tvpal_sw.c: shear-warp CPU palette renderer (see tvpal_sw.h).
 *
 * Three phases per frame, each a parallel loop:
 *   classify:  the visible tiles of every slice (a probe or its index set
 *              meets the palette's non-zero entries), building the sets
 *              a probe could not spare;
 *   composite: per band of intermediate rows, front to back through the
 *              slices (each slice through the band's rows), runs of
 *              visible tiles only; per texel one vertical lerp
 *              (constant weight fy for the row), then K horizontal lerps
 *              (constant weights fx[q]) and K blends;
 *   warp:      per output pixel, bilinear from the intermediate image.
 * The float operations and their order are fixed (sample = A + fy (B - A),
 * then C + fx (Cn - C), then dst + (1 - dst.a) sample) so every inner loop
 * variant gives the same bits. */
#include "tvpal_sw.h"
#include "tvpal_clock.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__SSE2__) && defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#include <immintrin.h>
#define SW_AVX2 1
#endif
#ifdef _OPENMP
#include <omp.h>
#endif

#define KAUTO 4       /* most intermediate pixels per texel chosen alone */
#define KMAX 8        /* most that can be asked for (tvpal_sw_set_scale) */
#define TILE_MIN 16   /* tile side; doubled until a row has <= 64 tiles */
#define BAND_MIN 4    /* intermediate rows composited together, at least by
                         default (band_rows) */
#define BAND_MAX 32   /* most that tvpal_sw_set_band takes */

/* The transposed indices of the held z slices for one view axis (cross
 * frames): slice s of w' texels a row, rows k = 0 .. rows - 1 (z slice z0
 * + k) at idx + (s * rows + k) * w'.  Row k was cut from layer layer[k]
 * at its generation gen[k] (0: nothing yet); only rows whose layer or
 * generation changed are cut again, so steady playback re-transposes the
 * 1/N of the slices whose windows changed. */
struct cross_copy {
    uint8_t *idx;
    size_t cap;           /* bytes */
    uint32_t *layer, *gen;
    uint32_t rows, rows_cap, wp, n;   /* layout: rows, w', slices */
};

/* Per-frame scratch of cross frames (grown, then kept). */
struct cross_scratch {
    struct tvpal_frame_slice *sl;   /* the slices drawn */
    size_t sl_cap;
    const float **rowpal;           /* per row: its z slice's palette */
    size_t rowpal_cap;
    uint64_t *gvis;                 /* z tile groups x rows of cross
                                       tiles: visible tile columns */
    size_t gvis_cap;                /* words */
    uint8_t *hit;                   /* per thread: a byte per z tile row */
    size_t hit_cap;
    uint32_t *todo;                 /* rows to cut again */
    size_t todo_cap;
};

struct tvpal_sw {
    float *im;            /* intermediate image, RGBA premultiplied */
    size_t cap;           /* floats */
    int32_t *cov;         /* per intermediate row: covered pixels [lo, hi) */
    size_t cov_cap;       /* rows */
    int threads, skip, simd;
    int exact;            /* stop only at alpha 1 (tvpal_sw_set_exact) */
    int runs;             /* skip stopped runs by maps (tvpal_sw_set_runs) */
    unsigned band;        /* rows composited together (tvpal_sw_set_band);
                             0: band_rows chooses */
    size_t l2;            /* bytes of L2 cache per core, 0: unknown */
    unsigned band_last;   /* the band of the last draw */
    float stop;           /* this draw's alpha at which a pixel stops */
    uint64_t *maps;       /* per thread: stopped pixels of one row */
    size_t maps_cap;      /* words */
    unsigned force_k;     /* 0: K from the view; else 1..KMAX */
    int avx2;             /* the AVX2 loops run (simd and the CPU has it) */
    uint32_t w, h, layers;
    unsigned tile, tcols, trows;
    uint64_t *sets;       /* layers x trows x tcols x 4 words: index sets */
    uint64_t *built;      /* layers x trows: tile columns whose set is
                             current (cleared by tvpal_sw_upload) */
    uint8_t *wit;         /* layers x trows x tcols: a visible index a
                             probe found in the tile (its witness) */
    uint64_t *witv;       /* layers x trows: tiles whose witness is
                             current (cleared by tvpal_sw_upload) */
    uint32_t *first;      /* layers: the layer's first frame slice (scratch) */
    uint32_t *todo;       /* layers: those first frame slices (scratch) */
    struct tvpal_sw_counts counts;   /* of the last draw */
    uint64_t *vis;        /* frame slices x trows: visible tile columns */
    size_t vis_cap;       /* frame slices vis holds */
    uint32_t *ugen;       /* layers: generation of the indices, bumped by
                             each upload (cross copies compare it) */
    struct cross_copy xc[2];   /* cross frames: x (0) and y (1) slices */
    struct cross_scratch xs;
    unsigned k_last;
    double t_classify, t_composite, t_warp;
};

int tvpal_sw_create(struct tvpal_sw **out)
{
    struct tvpal_sw *r = calloc(1, sizeof *r);
    if (!r)
        return TVPAL_E_NOMEM;
    r->skip = 1;
    r->simd = 1;
    r->runs = 1;
#ifdef _SC_LEVEL2_CACHE_SIZE
    long l2 = sysconf(_SC_LEVEL2_CACHE_SIZE);
    r->l2 = l2 > 0 ? (size_t)l2 : 0;
#endif
    *out = r;
    return 0;
}

void tvpal_sw_free(struct tvpal_sw *r)
{
    if (!r)
        return;
    free(r->im);
    free(r->cov);
    free(r->maps);
    free(r->sets);
    free(r->built);
    free(r->wit);
    free(r->witv);
    free(r->first);
    free(r->todo);
    free(r->vis);
    free(r->ugen);
    for (int a = 0; a < 2; a++) {
        free(r->xc[a].idx);
        free(r->xc[a].layer);
        free(r->xc[a].gen);
    }
    free(r->xs.sl);
    free(r->xs.rowpal);
    free(r->xs.gvis);
    free(r->xs.hit);
    free(r->xs.todo);
    free(r);
}

void tvpal_sw_options(struct tvpal_sw *r, int threads, int skip, int simd)
{
    r->threads = threads;
    r->skip = skip;
    r->simd = simd;
}

void tvpal_sw_set_exact(struct tvpal_sw *r, int exact)
{
    r->exact = exact;
}

void tvpal_sw_set_runs(struct tvpal_sw *r, int runs)
{
    r->runs = runs;
}

unsigned tvpal_sw_band(const struct tvpal_sw *r)
{
    return r->band_last;
}

/* Rows composited together for an intermediate row of wc pixels: the one
 * set, else the largest power of two from BAND_MIN to BAND_MAX whose rows
 * (16 bytes a pixel) take at most a quarter of the L2 cache.  A band's
 * rows are read and written by every slice and must stay in L2 while the
 * slices' palettes (4 KiB each) and index rows stream through it; a larger
 * band fetches each palette fewer times a frame (once per band).
 * Measured on 512^3 frames of the default view (2 threads, rows of 828
 * pixels, 13 KiB): with 2 MiB of L2 (Xeon) bands of 8, 16 and 32 composite
 * in x0.92, x0.90 and x0.85 the time of 4 (21 interleaved runs; 32 rows
 * are 20% of L2); with 512 KiB (EPYC, an earlier session, 5 runs) 8, 16
 * and 32 took x1.03, x1.14 and x1.10 (8 rows are 20% of L2, 16 are 41%).
 * Unknown L2: BAND_MIN. */
static unsigned band_rows(const struct tvpal_sw *r, unsigned wc)
{
    if (r->band)
        return r->band;
    unsigned rows = BAND_MIN;
    while (rows * 2 <= BAND_MAX && (size_t)rows * 2 * wc * 16 <= r->l2 / 4)
        rows *= 2;
    return rows;
}

int tvpal_sw_set_band(struct tvpal_sw *r, unsigned rows)
{
    if (rows < 1 || rows > BAND_MAX)
        return TVPAL_E_INVAL;
    r->band = rows;
    return 0;
}

int tvpal_sw_set_scale(struct tvpal_sw *r, unsigned k)
{
    if (k > KMAX)
        return TVPAL_E_INVAL;
    r->force_k = k;
    return 0;
}

void tvpal_sw_times(const struct tvpal_sw *r, double *classify_ms,
                    double *composite_ms, double *warp_ms)
{
    *classify_ms = r->t_classify;
    *composite_ms = r->t_composite;
    *warp_ms = r->t_warp;
}

void tvpal_sw_counts(const struct tvpal_sw *r, struct tvpal_sw_counts *c)
{
    *c = r->counts;
}

unsigned tvpal_sw_scale(const struct tvpal_sw *r)
{
    return r->k_last;
}

static int cpu_avx2(void)
{
#ifdef SW_AVX2
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
    return 0;
#endif
}

const char *tvpal_sw_simd_name(const struct tvpal_sw *r)
{
#if defined(__SSE2__)
    return r->simd && cpu_avx2() ? "avx2" : "sse2";
#else
    (void)r;
    return "scalar";
#endif
}

int tvpal_sw_set_slices(struct tvpal_sw *r, uint32_t w, uint32_t h,
                        uint32_t layers, struct tvpal_diag *diag)
{
    if (w == 0 || h == 0 || w > (1u << 20) || h > (1u << 20))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "slices of %ux%u (expected "
                              "1 to 2^20 texels a side)", w, h);
    unsigned tile = TILE_MIN;
    while ((w + tile - 1) / tile > 64)
        tile *= 2;
    unsigned tcols = (w + tile - 1) / tile, trows = (h + tile - 1) / tile;
    const size_t nl = layers ? layers : 1;
    if (nl > SIZE_MAX / 32 / trows / tcols)
        return tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "tile index sets for "
                              "%u slices of %ux%u", layers, w, h);
    uint64_t *sets = malloc(nl * trows * tcols * 4 * sizeof *sets);
    uint64_t *built = calloc(nl * trows, sizeof *built);   /* none built */
    uint8_t *wit = malloc(nl * trows * tcols);
    uint64_t *witv = calloc(nl * trows, sizeof *witv);     /* none found */
    uint32_t *first = malloc(nl * sizeof *first);
    uint32_t *todo = malloc(nl * sizeof *todo);
    uint32_t *ugen = malloc(nl * sizeof *ugen);
    if (!sets || !built || !wit || !witv || !first || !todo || !ugen) {
        free(sets);
        free(built);
        free(wit);
        free(witv);
        free(first);
        free(todo);
        free(ugen);
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "tile index sets for "
                              "%u slices of %ux%u", layers, w, h);
    }
    free(r->sets);
    free(r->built);
    free(r->wit);
    free(r->witv);
    free(r->first);
    free(r->todo);
    free(r->ugen);
    for (size_t i = 0; i < nl; i++)
        ugen[i] = 1;
    r->ugen = ugen;
    r->xc[0].rows = r->xc[1].rows = 0;   /* cut every row again */
    r->sets = sets;
    r->built = built;
    r->wit = wit;
    r->witv = witv;
    r->first = first;
    r->todo = todo;
    r->w = w;
    r->h = h;
    r->layers = layers;
    r->tile = tile;
    r->tcols = tcols;
    r->trows = trows;
    r->vis_cap = 0; /* rows per slice may have changed */
    return 0;
}

void tvpal_sw_upload(struct tvpal_sw *r, uint32_t layer)
{
    if (layer < r->layers) {
        memset(r->built + (size_t)layer * r->trows, 0, sizeof *r->built * r->trows);
        memset(r->witv + (size_t)layer * r->trows, 0, sizeof *r->witv * r->trows);
        if (++r->ugen[layer] == 0)
            r->ugen[layer] = 1;   /* 0 means "nothing cut" */
    }
}

/* Classification, lazily.  A tile is visible for a palette iff it holds an
 * index whose entry is not all zero.  Its exact index set (256 bits, bit i
 * set iff some texel holds index i) answers that for any palette, but
 * building it reads every texel.  So a tile whose set is not current is
 * first probed: 16 texels spread over it (centres of a 4 x 4 grid of
 * blocks) are looked up in the palette's non-zero table, and one non-zero
 * entry proves the tile visible with no set at all.  Only a tile none of
 * whose probes is visible gets its set built (then kept until the layer's
 * next upload) and tested.  Either way the answer is exactly the set's:
 * the visible tiles, and so the image, are those of building every set.
 * Under a dense TF most tiles of changed slices are decided by their first
 * probe, which is what stops a steady frame from reading all of 1/N of
 * the volume to classify it.  The visible index a probe found is kept as
 * the tile's witness until the layer's next upload: while the palettes of
 * later frames keep it visible, the tile is decided by one byte, with no
 * read of the slice's indices (1/16 of a slice's bytes for its probes). */

/* Marks of the texels of tile (tx, ty) of `idx` in seen (a byte per
 * index: mark where present), packed into the tile's set m[0..3]. */
static void build_tile(const struct tvpal_sw *r, const uint8_t *idx,
                       unsigned tx, unsigned ty, uint8_t seen[256],
                       uint8_t mark, uint64_t m[4])
{
    const uint32_t w = r->w, tile = r->tile;
    const uint32_t x0 = tx * tile, x1 = x0 + tile < w ? x0 + tile : w;
    const uint32_t y1 = (ty + 1) * tile < r->h ? (ty + 1) * tile : r->h;
    for (uint32_t y = ty * tile; y < y1; y++) {
        const uint8_t *row = idx + (size_t)w * y;
        uint32_t x = x0;
        /* Eight indices per 64-bit load (tiles are 16 or more wide): a
         * store per texel, no loop step per texel. */
        for (; x + 8 <= x1; x += 8) {
            uint64_t v;
            memcpy(&v, row + x, 8);
            seen[v & 255] = mark;
            seen[(v >> 8) & 255] = mark;
            seen[(v >> 16) & 255] = mark;
            seen[(v >> 24) & 255] = mark;
            seen[(v >> 32) & 255] = mark;
            seen[(v >> 40) & 255] = mark;
            seen[(v >> 48) & 255] = mark;
            seen[v >> 56] = mark;
        }
        for (; x < x1; x++)
            seen[row[x]] = mark;
    }
    for (int q = 0; q < 4; q++) {
        uint64_t bits = 0;
#if defined(__SSE2__)
        const __m128i vm = _mm_set1_epi8((char)mark);
        for (int c = 0; c < 4; c++) {
            __m128i v = _mm_loadu_si128((const __m128i *)&seen[64 * q + 16 * c]);
            bits |= (uint64_t)(unsigned)_mm_movemask_epi8(_mm_cmpeq_epi8(v, vm))
                    << (16 * c);
        }
#else
        for (int i = 0; i < 64; i++)
            bits |= (uint64_t)(seen[64 * q + i] == mark) << i;
#endif
        m[q] = bits;
    }
}

/* The first of the 16 probes of tile (tx, ty) that holds an index nz[]
 * says is visible: that index, or -1 when none does. */
static int probe_tile(const struct tvpal_sw *r, const uint8_t *idx,
                      unsigned tx, unsigned ty, const uint8_t nz[256])
{
    const uint32_t w = r->w, tile = r->tile;
    const uint32_t x0 = tx * tile, y0 = ty * tile;
    const uint32_t nx = (x0 + tile < w ? x0 + tile : w) - x0;
    const uint32_t ny = (y0 + tile < r->h ? y0 + tile : r->h) - y0;
    for (uint32_t i = 0; i < 4; i++) {
        const uint8_t *row = idx + (size_t)w * (y0 + (2 * i + 1) * ny / 8);
        for (uint32_t j = 0; j < 4; j++)
            if (nz[row[x0 + (2 * j + 1) * nx / 8]])
                return row[x0 + (2 * j + 1) * nx / 8];
    }
    return -1;
}

/* Visible tile columns of each tile row of one slice for its palette,
 * lazily (above); counts what decided each tile.  Writes the layer's sets
 * and built bits: a layer is classified by one thread at a time. */
static void classify(const struct tvpal_sw *r, const struct tvpal_frame_slice *sl,
                     uint64_t *out, struct tvpal_sw_counts *cnt)
{
    const uint64_t all = r->tcols == 64 ? ~0ull : (1ull << r->tcols) - 1;
    if (!r->skip) {
        for (unsigned ty = 0; ty < r->trows; ty++)
            out[ty] = all;
        return;
    }
    uint64_t vm[4] = {0, 0, 0, 0};
    uint8_t nz[256];
    const float *p = sl->palette;
    for (int i = 0; i < 256; i++) {
        nz[i] = p[4 * i] != 0.0f || p[4 * i + 1] != 0.0f ||
                p[4 * i + 2] != 0.0f || p[4 * i + 3] != 0.0f;
        vm[i >> 6] |= (uint64_t)nz[i] << (i & 63);
    }
    if (!(vm[0] | vm[1] | vm[2] | vm[3])) {   /* a transparent palette */
        memset(out, 0, sizeof *out * r->trows);
        return;
    }
    if (!~(vm[0] & vm[1] & vm[2] & vm[3])) {
        /* Every entry is visible, so every tile is (each holds at least
         * one texel): nothing to probe.  A dense TF's palettes are so;
         * witnesses and sets stay as they were, still true of the
         * indices. */
        for (unsigned ty = 0; ty < r->trows; ty++)
            out[ty] = all;
        return;
    }
    _Alignas(16) uint8_t seen[256];
    uint8_t mark = 0;
    uint64_t *sets = r->sets + (size_t)sl->layer * r->trows * r->tcols * 4;
    uint64_t *built = r->built + (size_t)sl->layer * r->trows;
    uint64_t *witv = r->witv + (size_t)sl->layer * r->trows;
    uint8_t *wit = r->wit + (size_t)sl->layer * r->trows * r->tcols;
    for (unsigned ty = 0; ty < r->trows; ty++) {
        uint64_t bits = 0;
        for (unsigned tx = 0; tx < r->tcols; tx++) {
            uint64_t *s = sets + 4 * ((size_t)ty * r->tcols + tx);
            if (!(built[ty] >> tx & 1)) {
                uint8_t *wt = wit + (size_t)ty * r->tcols + tx;
                if (witv[ty] >> tx & 1 && nz[*wt]) {
                    bits |= 1ull << tx;
                    cnt->witnessed++;
                    continue;
                }
                const int found = probe_tile(r, sl->idx, tx, ty, nz);
                if (found >= 0) {
                    *wt = (uint8_t)found;
                    witv[ty] |= 1ull << tx;
                    bits |= 1ull << tx;
                    cnt->probed++;
                    continue;
                }
                if (mark++ == 0) {   /* marks 1..255, then clear */
                    memset(seen, 0, sizeof seen);
                    mark = 1;
                }
                build_tile(r, sl->idx, tx, ty, seen, mark, s);
                built[ty] |= 1ull << tx;
                cnt->built++;
            }
            if ((s[0] & vm[0]) | (s[1] & vm[1]) | (s[2] & vm[2]) | (s[3] & vm[3]))
                bits |= 1ull << tx;
        }
        out[ty] = bits;
    }
}

/* Geometry of the factorization, in texel units of the slices. */
struct geom {
    double minv[2][2];    /* eye xy -> in-slice object coords (a, b) */
    double ha, hb;        /* half extents along the slice's two axes */
    double sx, sy;        /* texel shift per object unit of depth */
    double u0, v0;        /* base texel coords of intermediate pixel 0 */
    unsigned k;           /* intermediate pixels per texel */
    unsigned wi, hi;      /* intermediate image size (every slice) */
    long io, jo;          /* the part the output shows: origin, */
    unsigned wc, hc;      /* and size (pixels composited and stored) */
};

static double slice_depth(const struct tvpal_view *v, uint32_t s)
{
    return ((s + 0.5) / v->dims[v->axis] * 2.0 - 1.0) * v->half[v->axis];
}

/* Eye (x, y) -> base texel coords (the slice at depth 0). */
static void eye_to_base(const struct geom *g, unsigned w, unsigned h,
                        double ex, double ey, double *tu, double *tv)
{
    double a = g->minv[0][0] * ex + g->minv[0][1] * ey;
    double b = g->minv[1][0] * ex + g->minv[1][1] * ey;
    *tu = (a + g->ha) / (2 * g->ha) * w;
    *tv = (b + g->hb) / (2 * g->hb) * h;
}

/* Largest intermediate image side setup accepts (fits int and long). */
#define SW_EXTENT_MAX (1 << 24)

/* The frame's geometry; 0, or TVPAL_E_INVAL for a degenerate or extreme
 * view (no conversion out of range). */
static int setup(const struct tvpal_view *v, unsigned w, unsigned h,
                 unsigned force_k, struct geom *g)
{
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
    g->sx = da / (2 * g->ha) * w;
    g->sy = db / (2 * g->hb) * h;
    /* K: intermediate pixels per texel, a whole number (the weights of a
     * slice row stay constant), about what the output shows (1 to KAUTO):
     * up to K = KAUTO the warp magnifies by at most 1.25, so zoomed-in views
     * keep their detail and silhouettes their sharpness; beyond (more than
     * 4.25 output pixels per texel) it magnifies, bilinearly. */
    double texel = 2 * g->ha / w;
    double texel_b = 2 * g->hb / h;
    texel = texel > texel_b ? texel : texel_b;
    double pix = fmin(2 * v->sx / v->width, 2 * v->sy / v->height);
    double kk = ceil(texel / pix - 0.25);
    g->k = !(kk >= 1) ? 1 : kk > KAUTO ? KAUTO : (unsigned)kk;   /* NaN: 1 */
    if (force_k)
        g->k = force_k;
    /* Extent: every slice's footprint, shifted, with a pixel of margin. */
    double c0 = slice_depth(v, 0), c1 = slice_depth(v, v->dims[ax] - 1);
    double umin = fmin(c0 * g->sx, c1 * g->sx), umax = fmax(c0 * g->sx, c1 * g->sx);
    double vmin = fmin(c0 * g->sy, c1 * g->sy), vmax = fmax(c0 * g->sy, c1 * g->sy);
    g->u0 = floor(umin) - 1;
    g->v0 = floor(vmin) - 1;
    /* Converted only when in range: a NaN or huge extent (an extreme
     * view) refuses the frame instead. */
    double wi = ceil((umax + w + 1 - g->u0) * g->k);
    double hi = ceil((vmax + h + 1 - g->v0) * g->k);
    if (!(wi >= 1 && wi <= SW_EXTENT_MAX && hi >= 1 && hi <= SW_EXTENT_MAX))
        return TVPAL_E_INVAL;
    g->wi = (unsigned)wi;
    g->hi = (unsigned)hi;
    return 0;
}

/* Words of a stopped-pixel map for a row of wc pixels, with one to spare
 * (scans and the two-word reads of map_all may touch the word past the
 * last pixel). */
static inline size_t map_words(size_t wc)
{
    return wc / 64 + 2;
}

/* One slice row's share of an intermediate row: texels x0..x1 (inclusive,
 * x0 >= 0, x1 + 1 < w), pixel of texel x and phase q at K x + c0 + q.
 *
 * Stopped pixels (early termination).  A pixel is never blended again once
 * its alpha has reached `stop` (TVPAL_SW_ALPHA_STOP; NaN, which stops none,
 * without skipping), or with `exact` once its alpha is exactly 1 (an alpha
 * that overshot 1 goes on blending, as it always did).  Every kernel leaves
 * a stopped pixel's bits alone, so testing each pixel and skipping runs
 * give the same image.
 *
 * Opaque runs.  With `map`, a bitmap of the row's stopped pixels (bit i of
 * word i / 64), a kernel finds the next live pixel and the next stopped one
 * by bit scans (64 pixels a word), jumps over each run of stopped pixels at
 * once and composites each run of live pixels with no test per pixel,
 * marking the pixels it stops (behind it: the runs ahead of the scan do not
 * change during a slice).  This is the job of Lacroute & Levoy's run links
 * over opaque pixels of the intermediate image.  Without map each pixel's
 * alpha is tested.  The kernels are instantiated for exact = 0 and 1 (a
 * constant in each), so the stopping test is one comparison. */
struct span {
    float *row;           /* intermediate row */
    long c0;
    unsigned k;
    unsigned wi;          /* row length (edge pixels are bounds-checked) */
    float fx[KMAX], fy;
    const uint8_t *ra, *rb;   /* texel rows below and above the sample */
    const float *pala, *palb; /* their palettes (the same but in cross
                                 frames, where each row has its own) */
    float stop;           /* alpha at which a pixel stops (not exact) */
    int exact;            /* stop only at alpha 1 */
    uint64_t *map;        /* stopped pixels of the row, or NULL */
};

#define INLINE static inline __attribute__((always_inline))
#define STOPPED(exact, a, stop) ((exact) ? (a) == 1.0f : (a) >= (stop))

static inline void map_set(uint64_t *map, long i)
{
    map[i >> 6] |= 1ull << (i & 63);
}

/* The first pixel in [i, end) whose bit is `want` (1: stopped, 0: live),
 * or end.  The map has a word past end. */
static inline long map_next(const uint64_t *map, long i, long end, int want)
{
    if (i >= end)
        return end;
    const uint64_t flip = want ? 0 : ~0ull;
    long w = i >> 6;
    uint64_t b = (map[w] ^ flip) & (~0ull << (i & 63));
    while (!b) {
        if (++w << 6 >= end)
            return end;
        b = map[w] ^ flip;
    }
    long r = (w << 6) + __builtin_ctzll(b);
    return r < end ? r : end;
}

/* Whether every one of pixels [i, i + n) (n <= 8) has stopped, none has,
 * or some: 1, 0, -1. */
static inline int map_all(const uint64_t *map, long i, unsigned n)
{
    unsigned b = (unsigned)(i & 63);
    uint64_t v = map[i >> 6] >> b;
    if (b + n > 64)
        v |= map[(i >> 6) + 1] << (64 - b);
    v &= (1ull << n) - 1;
    return v == 0 ? 0 : v == (1ull << n) - 1 ? 1 : -1;
}

/* Pixel q of texel x (-1 .. w - 1) when it is to be blended: inside the
 * stored row and inside the slice (x = -1 and x = w - 1 clamp their texel
 * coordinates: only samples with fx >= 0.5, resp. < 0.5, lie inside); its
 * index in the row, else -1. */
static inline long texel_pixel(const struct span *s, int x, int w, unsigned q)
{
    long i = s->c0 + (long)s->k * x + q;
    if (i < 0 || i >= (long)s->wi || (x < 0 && s->fx[q] < 0.5f) ||
        (x == w - 1 && s->fx[q] >= 0.5f))
        return -1;
    return i;
}

/* Palette entry i (RGBA): the offset in size_t, so that it costs one
 * shift of the loaded byte, not a shift and a sign extension. */
static inline const float *entry(const float *pal, uint8_t i)
{
    return pal + 4 * (size_t)i;
}

/* span_v4 and texel_v4 blend one RGBA pixel at a time: with SSE2 where the
 * compiler targets it, else in scalar code (the same operations).  The
 * pixel is tested unless `live` says it is live. */
#if defined(__SSE2__)
static inline __m128 vlerp_sse(const struct span *s, int x, __m128 vfy)
{
    __m128 a = _mm_loadu_ps(entry(s->pala, s->ra[x]));
    __m128 b = _mm_loadu_ps(entry(s->palb, s->rb[x]));
    return _mm_add_ps(a, _mm_mul_ps(vfy, _mm_sub_ps(b, a)));
}

/* Pixel i = dst + (1 - dst.a) * (C + fx (Cn - C)), with D = Cn - C, unless
 * it has stopped; marks it when it stops. */
INLINE void blend_px(const struct span *s, long i, __m128 c, __m128 dd,
                     float fx, const int exact, const int live)
{
    float *d = s->row + 4 * i;
    if (!live && STOPPED(exact, d[3], s->stop))
        return;
    const __m128 one = _mm_set1_ps(1.0f);
    __m128 sm = _mm_add_ps(c, _mm_mul_ps(_mm_set1_ps(fx), dd));
    __m128 dv = _mm_loadu_ps(d);
    __m128 keep = _mm_sub_ps(one, _mm_shuffle_ps(dv, dv, 0xFF));
    __m128 nd = _mm_add_ps(dv, _mm_mul_ps(keep, sm));
    _mm_storeu_ps(d, nd);
    float a = _mm_cvtss_f32(_mm_shuffle_ps(nd, nd, 0xFF));
    if (s->map && STOPPED(exact, a, s->stop))
        map_set(s->map, i);
}

INLINE void span_v4_m(const struct span *s, int x0, int x1, const int exact)
{
    const __m128 vfy = _mm_set1_ps(s->fy);
    const long k = (long)s->k, c0 = s->c0;
    uint64_t *const map = s->map;
    int x = x0;
    __m128 c = vlerp_sse(s, x, vfy);
    while (x <= x1) {
        long i = c0 + k * x;
        int all = map ? map_all(map, i, s->k) : -1;
        if (all == 1) { /* every pixel of the texel has stopped */
            long e = map_next(map, i, c0 + k * (x1 + 1), 0);
            x = (int)((e - c0) / k);
            if (x > x1)
                return;
            c = vlerp_sse(s, x, vfy);
            continue;
        }
        __m128 cn = vlerp_sse(s, x + 1, vfy);
        __m128 dd = _mm_sub_ps(cn, c);
        if (all == 0)
            for (unsigned q = 0; q < s->k; q++)
                blend_px(s, i + q, c, dd, s->fx[q], exact, 1);
        else
            for (unsigned q = 0; q < s->k; q++)
                blend_px(s, i + q, c, dd, s->fx[q], exact, 0);
        c = cn;
        x++;
    }
}

/* One texel x (-1 .. w - 1) pixel by pixel: pixels outside the stored row
 * are left out, and at the slice's edges (x = -1, x = w - 1, where the
 * texel coordinates clamp) only the samples inside the slice are blended.
 * The same operations as span_v4. */
INLINE void texel_v4_m(const struct span *s, int x, int w, const int exact)
{
    const __m128 vfy = _mm_set1_ps(s->fy);
    const int xa = x < 0 ? 0 : x, xb = x + 1 > w - 1 ? w - 1 : x + 1;
    __m128 c = vlerp_sse(s, xa, vfy), cn = vlerp_sse(s, xb, vfy);
    __m128 dd = _mm_sub_ps(cn, c);
    for (unsigned q = 0; q < s->k; q++) {
        long i = texel_pixel(s, x, w, q);
        if (i >= 0)
            blend_px(s, i, c, dd, s->fx[q], exact, 0);
    }
}
#else
static inline void vlerp_sc(const struct span *s, int x, float *o)
{
    const float *a = entry(s->pala, s->ra[x]), *b = entry(s->palb, s->rb[x]);
    for (int ch = 0; ch < 4; ch++)
        o[ch] = a[ch] + s->fy * (b[ch] - a[ch]);
}

INLINE void blend_px(const struct span *s, long i, const float *c,
                     const float *dd, float fx, const int exact, const int live)
{
    float *d = s->row + 4 * i;
    if (!live && STOPPED(exact, d[3], s->stop))
        return;
    float keep = 1.0f - d[3];
    for (int ch = 0; ch < 4; ch++)
        d[ch] = d[ch] + keep * (c[ch] + fx * dd[ch]);
    if (s->map && STOPPED(exact, d[3], s->stop))
        map_set(s->map, i);
}

INLINE void span_v4_m(const struct span *s, int x0, int x1, const int exact)
{
    float c[4], cn[4], dd[4];
    const long k = (long)s->k, c0 = s->c0;
    uint64_t *const map = s->map;
    int x = x0;
    vlerp_sc(s, x, c);
    while (x <= x1) {
        long i = c0 + k * x;
        int all = map ? map_all(map, i, s->k) : -1;
        if (all == 1) {
            long e = map_next(map, i, c0 + k * (x1 + 1), 0);
            x = (int)((e - c0) / k);
            if (x > x1)
                return;
            vlerp_sc(s, x, c);
            continue;
        }
        vlerp_sc(s, x + 1, cn);
        for (int ch = 0; ch < 4; ch++)
            dd[ch] = cn[ch] - c[ch];
        for (unsigned q = 0; q < s->k; q++)
            blend_px(s, i + q, c, dd, s->fx[q], exact, all == 0);
        memcpy(c, cn, sizeof c);
        x++;
    }
}

INLINE void texel_v4_m(const struct span *s, int x, int w, const int exact)
{
    float c[4], cn[4], dd[4];
    const int xa = x < 0 ? 0 : x, xb = x + 1 > w - 1 ? w - 1 : x + 1;
    vlerp_sc(s, xa, c);
    vlerp_sc(s, xb, cn);
    for (int ch = 0; ch < 4; ch++)
        dd[ch] = cn[ch] - c[ch];
    for (unsigned q = 0; q < s->k; q++) {
        long i = texel_pixel(s, x, w, q);
        if (i >= 0)
            blend_px(s, i, c, dd, s->fx[q], exact, 0);
    }
}
#endif

static void span_v4(const struct span *s, int x0, int x1)
{
    if (s->exact)
        span_v4_m(s, x0, x1, 1);
    else
        span_v4_m(s, x0, x1, 0);
}

/* Whether texel x has nothing to blend: each of its pixels lies outside
 * the row or the slice, or (with a map) has stopped.  Asked before the
 * texel's indices and palette entries are read: the edge texels are the
 * first read of their index rows, a miss to memory at each of the 512 x
 * 512 row visits of a 512^3 frame, and at one edge of the sheared slices
 * their pixels have long stopped. */
static inline int texel_done(const struct span *s, int x, int w)
{
    if (!s->map)
        return 0;
    for (unsigned q = 0; q < s->k; q++) {
        const long i = texel_pixel(s, x, w, q);
        if (i >= 0 && !(s->map[i >> 6] >> (i & 63) & 1))
            return 0;
    }
    return 1;
}

/* Blends the pixels of texel x (-1 .. w - 1) that lie inside, by
 * texel_v4_m. */
static void texel_blend(const struct span *s, int x, int w)
{
    if (s->exact)
        texel_v4_m(s, x, w, 1);
    else
        texel_v4_m(s, x, w, 0);
}

/* Texel x pixel by pixel, its pixels tested before anything is read.  The
 * slice's edge texels come at every row visit: at K = 1 (one pixel) the
 * test is inline, where texel_done's loop over K pixels cost as much as
 * the blend at 512^3. */
INLINE void texel_v4(const struct span *s, int x, int w)
{
    if (s->k == 1) {
        const long i = texel_pixel(s, x, w, 0);
        if (i < 0 || (s->map && s->map[i >> 6] >> (i & 63) & 1))
            return;
    } else if (texel_done(s, x, w)) {
        return;
    }
    texel_blend(s, x, w);
}

#ifdef SW_AVX2
/* The AVX2 loops (K = 1 and 2) fuse each multiply with its add (FMA, on
 * every CPU with AVX2 that cpu_avx2 accepts): six instructions fewer per
 * four blends, and one rounding instead of two.  So their pixels differ
 * from the SSE2 loops' in the last bits (and, where a pixel's alpha ends
 * next to the stop, by whether one more sample is blended: less than
 * 1/272).  Every operation on a pixel's way through these loops is fused
 * the same way, the single pixels and run starts as the pairs (vlerp_fma,
 * blend_fma), so that the runs, the per-pixel tests, threads and bands give
 * the same bits among themselves.  Edge texels (texel_v4) take the SSE2
 * operations in every mode. */
#define AVX2 __attribute__((target("avx2,fma")))

/* V(x) = A + fy (B - A), fused: vlerp_sse's value as the AVX2 loops
 * compute it. */
AVX2 static inline __m128 vlerp_fma(const struct span *s, int x, __m128 vfy)
{
    __m128 a = _mm_loadu_ps(entry(s->pala, s->ra[x]));
    __m128 b = _mm_loadu_ps(entry(s->palb, s->rb[x]));
    return _mm_fmadd_ps(vfy, _mm_sub_ps(b, a), a);
}

/* blend_px with fused operations: pixel i = dst + (1 - dst.a) (C + fx D),
 * unless it has stopped (tested unless live); marks it when it stops. */
AVX2 INLINE void blend_fma(const struct span *s, long i, __m128 c, __m128 dd,
                           float fx, const int exact, const int live)
{
    float *d = s->row + 4 * i;
    if (!live && STOPPED(exact, d[3], s->stop))
        return;
    __m128 sm = _mm_fmadd_ps(_mm_set1_ps(fx), dd, c);
    __m128 dv = _mm_loadu_ps(d);
    __m128 keep = _mm_sub_ps(_mm_set1_ps(1.0f), _mm_shuffle_ps(dv, dv, 0xFF));
    __m128 nd = _mm_fmadd_ps(keep, sm, dv);
    _mm_storeu_ps(d, nd);
    float a = _mm_cvtss_f32(_mm_shuffle_ps(nd, nd, 0xFF));
    if (s->map && STOPPED(exact, a, s->stop))
        map_set(s->map, i);
}

AVX2 static inline __m256 load2(const float *lo, const float *hi)
{
    return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(lo)),
                                _mm_loadu_ps(hi), 1);
}

/* Live pixels i, i + 1 = dst + (1 - dst.a) * sm.  Returns the lanes of
 * the new pixels that are at or past the stop, all lanes compared (only
 * lanes 3 and 7, the alphas, say anything: pixel i, i + 1); zero without a
 * map. */
AVX2 INLINE __m256 blend2v(float *row, uint64_t *map, float stop, long i,
                           __m256 sm, const int exact)
{
    float *d = row + 4 * i;
    __m256 dv = _mm256_loadu_ps(d);
    __m256 keep = _mm256_sub_ps(_mm256_set1_ps(1.0f), _mm256_permute_ps(dv, 0xFF));
    __m256 nd = _mm256_fmadd_ps(keep, sm, dv);
    _mm256_storeu_ps(d, nd);
    if (!map)
        return _mm256_setzero_ps();
    return exact ? _mm256_cmp_ps(nd, _mm256_set1_ps(1.0f), _CMP_EQ_OQ)
                 : _mm256_cmp_ps(nd, _mm256_set1_ps(stop), _CMP_GE_OQ);
}

/* The stops of blend2v's lanes as bits (0x08: pixel i, 0x80: i + 1), for
 * mark_stops. */
AVX2 static inline unsigned stop_bits(__m256 now)
{
    return (unsigned)_mm256_movemask_ps(now) & 0x88;
}

/* Whether any alpha lane of now is set: one test for several pairs' stops
 * (their compare masks or-ed), which are rare, before taking them apart. */
AVX2 static inline int any_stop(__m256 now)
{
    const __m256 alpha = _mm256_castsi256_ps(_mm256_set_epi32(-1, 0, 0, 0, -1, 0, 0, 0));
    return !_mm256_testz_ps(now, alpha);
}

AVX2 INLINE unsigned blend2(float *row, uint64_t *map, float stop, long i,
                            __m256 sm, const int exact)
{
    return stop_bits(blend2v(row, map, stop, i, sm, exact));
}

/* Marks the pixels blend2 said stopped: lane bit 4 q + 3 of m is pixel
 * i + q (the masks of consecutive pairs shifted by 8 each). */
static inline void mark_stops(uint64_t *map, long i, unsigned m)
{
    for (; m; m &= m - 1)
        map_set(map, i + (__builtin_ctz(m) >> 2));
}

/* The live run at or after texel *x, for kernels whose texel x has pixels
 * [c0 + k x, c0 + k x + k): *x moves past stopped pixels to the texel of
 * the first live one, and *xe gets the last texel all of whose pixels are
 * live before the next stopped one (x1 at most; *x - 1 when texel *x is
 * itself partly stopped).  0 when the span has no live pixel left. */
static inline int live_run(const uint64_t *map, long c0, long k, int *x,
                           int x1, int *xe)
{
    const long end = c0 + k * (x1 + 1);
    long e = map_next(map, c0 + k * *x, end, 0);
    if (e >= end)
        return 0;
    *x = (int)((e - c0) / k);
    if ((e - c0) % k) {
        *xe = *x - 1;
        return 1;
    }
    long st = map_next(map, e, end, 1);
    *xe = (int)((st - c0) / k) - 1;
    return 1;
}

/* K = 1, the pair of texels x, x + 1: vp holds V(x) in its high half on
 * entry and [V(x+1) | V(x+2)] on return; both pixels are blended (live);
 * returns blend2v's compare lanes (the stops, unmarked). */
struct k1_ctx {      /* a span's K = 1 constants, read once per span */
    __m256 vfy, vfx;
    const uint8_t *ra, *rb;
    const float *pala, *palb;
    float *row;
    float stop;
    long c0;
};

AVX2 INLINE __m256 pair_k1(const struct k1_ctx *k, int x, __m256 *vp,
                           uint64_t *map, const int exact)
{
    __m256 a = load2(entry(k->pala, k->ra[x + 1]), entry(k->pala, k->ra[x + 2]));
    __m256 b = load2(entry(k->palb, k->rb[x + 1]), entry(k->palb, k->rb[x + 2]));
    __m256 vn = _mm256_fmadd_ps(k->vfy, _mm256_sub_ps(b, a), a);
    __m256 cur = _mm256_permute2f128_ps(*vp, vn, 0x21); /* [V(x) | V(x+1)] */
    __m256 now = blend2v(k->row, map, k->stop, k->c0 + x,
                         _mm256_fmadd_ps(k->vfx, _mm256_sub_ps(vn, cur), cur),
                         exact);
    *vp = vn;
    return now;
}

/* K = 1, texel x alone (tested unless live); vp as for pair_k1, holding
 * [V(x+1) | V(x+1)] on return. */
AVX2 INLINE void single_k1(const struct span *s, int x, __m256 *vp,
                           const int exact, const int live)
{
    __m128 cc = _mm256_extractf128_ps(*vp, 1);
    __m128 cn = vlerp_fma(s, x + 1, _mm_set1_ps(s->fy));
    blend_fma(s, s->c0 + x, cc, _mm_sub_ps(cn, cc), s->fx[0], exact, live);
    *vp = _mm256_insertf128_ps(_mm256_castps128_ps256(cn), cn, 1);
}

AVX2 static inline __m256 dup_v(__m128 c)
{
    return _mm256_insertf128_ps(_mm256_castps128_ps256(c), c, 1);
}

/* K = 1: two texels (pixels) per step over each run of live pixels; with
 * no map, a pair with a stopped pixel goes pixel by pixel. */
AVX2 INLINE void span_avx2_k1_m(const struct span *s, int x0, int x1,
                                const int exact)
{
    const __m128 vfy1 = _mm_set1_ps(s->fy);
    uint64_t *const map = s->map;
    const long c0 = s->c0;
    const struct k1_ctx k = {_mm256_set1_ps(s->fy), _mm256_set1_ps(s->fx[0]),
                             s->ra, s->rb, s->pala, s->palb, s->row, s->stop,
                             c0};
    int x = x0;
    if (!map) {
        __m256 vp = dup_v(vlerp_fma(s, x, vfy1));
        while (x <= x1) {
            const float *d = s->row + 4 * (c0 + x);
            if (x == x1 || STOPPED(exact, d[3], s->stop) ||
                STOPPED(exact, d[7], s->stop)) {
                single_k1(s, x, &vp, exact, 0);
                x++;
            } else {
                pair_k1(&k, x, &vp, NULL, exact);
                x += 2;
            }
        }
        return;
    }
    int xe;
    while (x <= x1 && live_run(map, c0, 1, &x, x1, &xe)) {
        __m256 vp = dup_v(vlerp_fma(s, x, vfy1));
        /* Two pairs a step: one test of their stops, one loop step. */
        for (; x + 3 <= xe; x += 4) {
            __m256 n0 = pair_k1(&k, x, &vp, map, exact);
            __m256 n1 = pair_k1(&k, x + 2, &vp, map, exact);
            if (any_stop(_mm256_or_ps(n0, n1)))
                mark_stops(map, c0 + x, stop_bits(n0) | stop_bits(n1) << 8);
        }
        for (; x + 1 <= xe; x += 2) {
            unsigned m = stop_bits(pair_k1(&k, x, &vp, map, exact));
            if (m)
                mark_stops(map, c0 + x, m);
        }
        if (x == xe)
            single_k1(s, x++, &vp, exact, 1);
    }
}

/* K = 2, the texel x, both pixels live: C = V(x) in, V(x+1) out. */
AVX2 INLINE void texel_k2(const struct span *s, int x, __m128 *c,
                          __m128 vfy, __m256 vfx, uint64_t *map,
                          const int exact)
{
    __m128 cn = vlerp_fma(s, x + 1, vfy);
    __m256 d2 = dup_v(_mm_sub_ps(cn, *c));
    unsigned m = blend2(s->row, map, s->stop, s->c0 + 2L * x,
                        _mm256_fmadd_ps(vfx, d2, dup_v(*c)), exact);
    if (m)
        mark_stops(map, s->c0 + 2L * x, m);
    *c = cn;
}

/* K = 2: the two pixels of a texel in one step, over each run of texels
 * whose pixels are live; a texel with a stopped pixel goes pixel by
 * pixel. */
AVX2 INLINE void span_avx2_k2_m(const struct span *s, int x0, int x1,
                                const int exact)
{
    const __m128 vfy = _mm_set1_ps(s->fy);
    const __m256 vfx = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_set1_ps(s->fx[0])),
                                            _mm_set1_ps(s->fx[1]), 1);
    uint64_t *const map = s->map;
    const long c0 = s->c0;
    int x = x0, xe = x1;
    while (x <= x1) {
        if (map && !live_run(map, c0, 2, &x, x1, &xe))
            return;
        __m128 c = vlerp_fma(s, x, vfy);
        const float *d = s->row + 4 * (c0 + 2L * x);
        if (map ? xe < x : STOPPED(exact, d[3], s->stop) || STOPPED(exact, d[7], s->stop)) {
            __m128 dd = _mm_sub_ps(vlerp_fma(s, x + 1, vfy), c);
            blend_fma(s, c0 + 2L * x, c, dd, s->fx[0], exact, 0);
            blend_fma(s, c0 + 2L * x + 1, c, dd, s->fx[1], exact, 0);
            x++;
            continue;
        }
        if (!map) {
            texel_k2(s, x++, &c, vfy, vfx, NULL, exact);
            continue;
        }
        for (; x <= xe; x++)
            texel_k2(s, x, &c, vfy, vfx, map, exact);
    }
}

AVX2 static void span_avx2_k1(const struct span *s, int x0, int x1)
{
    if (s->exact)
        span_avx2_k1_m(s, x0, x1, 1);
    else
        span_avx2_k1_m(s, x0, x1, 0);
}

AVX2 static void span_avx2_k2(const struct span *s, int x0, int x1)
{
    if (s->exact)
        span_avx2_k2_m(s, x0, x1, 1);
    else
        span_avx2_k2_m(s, x0, x1, 0);
}
#endif

/* floor(a / b) for b > 0. */
static inline long floordiv(long a, long b)
{
    return a >= 0 ? a / b : -((-a + b - 1) / b);
}

/* What composite_row draws: the frame's slices (plain frames), or the
 * view-axis slices cut from the z slices (cross frames). */
struct drawable {
    const struct tvpal_frame_slice *sl;   /* drawing order, back to front */
    uint32_t count;
    int w, h;              /* slice texels; h counts every row of the axis */
    int rb0, rb1;          /* rows held: [rb0, rb1); idx holds row rb0 first */
    int db0, db1;          /* rows whose samples are drawn, within them */
    const float *const *rowpal;   /* NULL: each slice's palette; else row
                                     b's palette is rowpal[b - rb0] */
    const uint64_t *vis;   /* rows of trows words: visible tile columns */
    unsigned vis_group;    /* 0: slice n's row is vis + n trows; else the
                              slices of one group (slice / vis_group) share
                              row vis + group trows (cross frames) */
    unsigned tile, trows;  /* tile: a power of two (tile_for) */
};

/* What every row of a band shares for one slice: its depth, the texel
 * shift, the first pixel c0 whose sample lies at or right of texel 0, the
 * K phase weights and the pixels the slice covers. */
struct slice_step {
    double c, csy, ta;    /* csy = c * sy, the row offset's slice term */
    long sc0;             /* c0 in stored-row pixels */
    float fx[KMAX];
    long first, end;      /* covered pixels [first, end) of any row it meets */
    long xmin, xmax;      /* texels whose K pixels all lie inside a row */
};

static void slice_step(const struct geom *g, const struct tvpal_view *v,
                       int w, uint32_t slice, struct slice_step *st)
{
    const unsigned k = g->k;
    st->c = slice_depth(v, slice);
    st->csy = st->c * g->sy;
    st->ta = g->u0 - st->c * g->sx;
    /* Pixel i samples x = (i + 0.5) / K + ta - 0.5. */
    const double c0 = ceil(k * (0.5 - st->ta) - 0.5);
    st->sc0 = (long)c0 - g->io;
    unsigned qs = 0; /* phases with fx < 0.5 (fx grows with q) */
    for (unsigned q = 0; q < k; q++) {
        double fx = (c0 + q + 0.5) / k + st->ta - 0.5;
        st->fx[q] = (float)(fx < 0 ? 0 : fx > 1 ? 1 : fx);
        qs += st->fx[q] < 0.5f;
    }
    /* The slice covers pixels c0 - K + qs .. c0 + K (w - 1) + qs - 1
     * (the same tests as texel_v4), whatever its palette; a row of the
     * slice that another node holds (cross frames of a slab) is covered
     * too, by nothing: the warp filters across the slab's boundary as
     * inside the volume, and the silhouette stays where the volume ends. */
    st->first = st->sc0 - (long)k + qs;
    st->end = st->sc0 + (long)k * (w - 1) + qs;
    st->xmin = -floordiv(st->sc0, (long)k);
    st->xmax = floordiv((long)g->wc - (long)k - st->sc0, (long)k);
}

/* The visible texel runs `bits` (tile columns) of one slice row, through
 * the inner loops; edge texels (the slice's, and those only partly inside
 * the stored row, outside xmin..xmax) pixel by pixel. */
static void draw_runs(const struct tvpal_sw *r, const struct span *s,
                      uint64_t bits, int w, unsigned tile, long xmin, long xmax)
{
    while (bits) {
        unsigned t0 = (unsigned)__builtin_ctzll(bits);
        uint64_t sh = bits >> t0;
        unsigned len = ~sh == 0 ? 64 - t0 : (unsigned)__builtin_ctzll(~sh);
        unsigned t1 = t0 + len;
        bits = t1 >= 64 ? 0 : bits & ~((1ull << t1) - 1);
        /* Texels [a, b) are visible: pixels whose x0 is a - 1 .. b - 1
         * may sample them (x0 = -1 and w - 1 are the clamped edges). */
        long a = (long)t0 * tile, b = (long)t1 * tile < w ? (long)t1 * tile : w;
        long lo = a - 1, hi = b - 1;
        if (lo < 0) {
            texel_v4(s, -1, w);         /* samples with fx >= 0.5 */
            lo = 0;
        }
        if (hi == w - 1) {
            texel_v4(s, w - 1, w);      /* samples with fx < 0.5 */
            hi = w - 2;
        }
        /* Texels only partly inside the stored row (clipping). */
        if (lo < xmin) {
            if (xmin - 1 >= lo && xmin - 1 <= hi)
                texel_v4(s, (int)(xmin - 1), w);
            lo = xmin;
        }
        if (hi > xmax) {
            if (xmax + 1 <= hi && xmax + 1 >= lo)
                texel_v4(s, (int)(xmax + 1), w);
            hi = xmax;
        }
        if (lo > hi)
            continue;
#ifdef SW_AVX2
        if (r->avx2 && s->k == 1) {
            span_avx2_k1(s, (int)lo, (int)hi);
            continue;
        }
        if (r->avx2 && s->k == 2) {
            span_avx2_k2(s, (int)lo, (int)hi);
            continue;
        }
#endif
        span_v4(s, (int)lo, (int)hi);
    }
}

/* One row of the band through slice n: widens the row's coverage
 * [*lo, *hi) and composites what it samples.  yrow: the row's term of the
 * slice row it samples, v0 + (jo + j + 0.5) / K for stored row j (global
 * jo + j), computed once per band. */
static void slice_row(const struct tvpal_sw *r, const struct drawable *dr,
                      const struct geom *g, const struct slice_step *st,
                      uint32_t n, double yrow, float *row, uint64_t *map,
                      long *lo, long *hi)
{
    const struct tvpal_frame_slice *sl = &dr->sl[n];
    const int w = dr->w, rb0 = dr->rb0, rb1 = dr->rb1;
    const unsigned k = g->k;
    const double ty = yrow - st->csy;
    if (!(ty >= 0 && ty < dr->h))
        return;
    *lo = st->first < *lo ? st->first : *lo;
    *hi = st->end > *hi ? st->end : *hi;
    if (!(ty >= dr->db0 && ty < dr->db1))
        return;
    const double yy = ty - 0.5, yf = floor(yy);
    const int y0 = (int)yf;
    const int ya = y0 < rb0 ? rb0 : y0, yb = y0 + 1 >= rb1 ? rb1 - 1 : y0 + 1;
    const float *pa = dr->rowpal ? dr->rowpal[ya - rb0] : sl->palette;
    const float *pb = dr->rowpal ? dr->rowpal[yb - rb0] : sl->palette;
    struct span s = {.row = row, .c0 = st->sc0, .k = k, .wi = g->wc,
                     .fy = (float)(yy - yf),
                     .ra = sl->idx + (size_t)w * (ya - rb0),
                     .rb = sl->idx + (size_t)w * (yb - rb0),
                     .pala = pa, .palb = pb,
                     .stop = r->stop, .exact = r->exact && r->skip,
                     .map = map};
    memcpy(s.fx, st->fx, sizeof s.fx);
    const uint64_t *vr = dr->vis + (size_t)dr->trows *
                         (dr->vis_group ? sl->slice / dr->vis_group : n);
    const unsigned ts = (unsigned)__builtin_ctz(dr->tile);
    const uint64_t bits = vr[(unsigned)(ya - rb0) >> ts] | vr[(unsigned)(yb - rb0) >> ts];
    draw_runs(r, &s, bits, w, dr->tile, st->xmin, st->xmax);
}

/* Composites the band of stored rows j0 .. j0 + nb - 1 (nb <= BAND_MAX)
 * through every slice, front to back: slices outside, rows inside, so a
 * slice's palette (4 KiB) and index rows are fetched once per band, not
 * once per row (a row through 512 slices meets 2 MiB of palettes, more
 * than L2 holds).  Each pixel still meets the slices in the same order
 * with the same operations: the bits of row-by-row compositing.  maps:
 * nb stopped-pixel maps of map_words(wc) words, or NULL. */
static void composite_band(const struct tvpal_sw *r, const struct drawable *dr,
                           const struct tvpal_view *v, const struct geom *g,
                           unsigned j0, unsigned nb, float *im, int32_t *cov,
                           uint64_t *maps)
{
    const size_t mw = map_words(g->wc);
    long lo[BAND_MAX], hi[BAND_MAX];
    double yrow[BAND_MAX];
    unsigned live = 0;   /* rows not yet all stopped: bit b */
    for (unsigned b = 0; b < nb; b++) {
        yrow[b] = g->v0 + (g->jo + j0 + b + 0.5) / g->k;
        memset(im + (size_t)4 * g->wc * (j0 + b), 0, sizeof(float) * 4 * g->wc);
        if (maps)
            memset(maps + mw * b, 0, sizeof *maps * mw);
        lo[b] = g->wc;
        hi[b] = 0;
        live |= 1u << b;
    }
    for (uint32_t n = dr->count; n-- > 0 && live;) {
        struct slice_step st;
        slice_step(g, v, dr->w, dr->sl[n].slice, &st);
        for (unsigned b = 0; b < nb; b++) {
            if (!(live >> b & 1))
                continue;
            uint64_t *map = maps ? maps + mw * b : NULL;
            if (map && map_next(map, 0, g->wc, 0) >= (long)g->wc) {
                /* Every pixel of the row has stopped: nothing behind can
                 * change it, and every pixel is covered (it was blended). */
                lo[b] = 0;
                hi[b] = g->wc;
                live &= ~(1u << b);
                continue;
            }
            slice_row(r, dr, g, &st, n, yrow[b], im + (size_t)4 * g->wc * (j0 + b),
                      map, &lo[b], &hi[b]);
        }
    }
    for (unsigned b = 0; b < nb; b++) {
        int32_t *c = cov + 2 * (size_t)(j0 + b);
        c[0] = (int32_t)(lo[b] < 0 ? 0 : lo[b]);
        c[1] = (int32_t)(hi[b] > (long)g->wc ? (long)g->wc : hi[b]);
        if (c[1] < c[0])
            c[0] = c[1] = 0;
    }
}

/* Output row py from the stored part of the intermediate image (origin
 * io, jo), pixel (px, py) at global xi = ox + ax px + bx py, likewise yi.  Coverage keeps the silhouette as
 * sharp as the slice rasterization of the other renderers: a pixel whose
 * nearest intermediate pixel no slice covers is transparent, and at the
 * silhouette the bilinear weights of the uncovered taps go to the covered
 * ones (as clamping to the edge does for one slice).  Inside, plain
 * bilinear. */
struct warp {
    double ox, ax, bx, oy, ay, by;
};

static inline int covered(const int32_t *cov, long x, long y, unsigned hi)
{
    return y >= 0 && y < (long)hi && x >= cov[2 * y] && x < cov[2 * y + 1];
}

static void warp_row(const float *im, const int32_t *cov, long io, long jo,
                     unsigned wi, unsigned hi, const struct warp *wp,
                     unsigned W, unsigned py, float *o)
{
    const double rx = wp->ox + wp->bx * py, ry = wp->oy + wp->by * py;
    for (unsigned px = 0; px < W; px++, o += 4) {
        /* Global coordinates first (the weights do not depend on the
         * clipping), then relative to the stored part. */
        const double xi = rx + wp->ax * px, yi = ry + wp->ay * px;
        const double xf = floor(xi) - (double)io, yf = floor(yi) - (double)jo;
        const long x0 = (long)fmax(fmin(xf, wi), -2), y0 = (long)fmax(fmin(yf, hi), -2);
        const float fx = (float)(xi - floor(xi)), fy = (float)(yi - floor(yi));
        const long xn = x0 + (fx >= 0.5f), yn = y0 + (fy >= 0.5f);
        if (!covered(cov, xn, yn, hi)) {
            memset(o, 0, 4 * sizeof *o);
            continue;
        }
        if (y0 >= 0 && y0 + 1 < (long)hi && x0 >= cov[2 * y0] &&
            x0 >= cov[2 * y0 + 2] && x0 + 1 < cov[2 * y0 + 1] &&
            x0 + 1 < cov[2 * y0 + 3]) {
            const float *p00 = im + 4 * ((size_t)y0 * wi + x0), *p10 = p00 + 4;
            const float *p01 = p00 + 4 * (size_t)wi, *p11 = p01 + 4;
#if defined(__SSE2__)
            __m128 vfx = _mm_set1_ps(fx), vfy = _mm_set1_ps(fy);
            __m128 a = _mm_loadu_ps(p00), b = _mm_loadu_ps(p10);
            __m128 c = _mm_loadu_ps(p01), d = _mm_loadu_ps(p11);
            __m128 top = _mm_add_ps(a, _mm_mul_ps(vfx, _mm_sub_ps(b, a)));
            __m128 bot = _mm_add_ps(c, _mm_mul_ps(vfx, _mm_sub_ps(d, c)));
            _mm_storeu_ps(o, _mm_add_ps(top, _mm_mul_ps(vfy, _mm_sub_ps(bot, top))));
#else
            for (int ch = 0; ch < 4; ch++) {
                float top = p00[ch] + fx * (p10[ch] - p00[ch]);
                float bot = p01[ch] + fx * (p11[ch] - p01[ch]);
                o[ch] = top + fy * (bot - top);
            }
#endif
            continue;
        }
        /* Silhouette: the covered taps, weights renormalized. */
        float acc[4] = {0, 0, 0, 0}, wsum = 0;
        for (int dy = 0; dy < 2; dy++)
            for (int dx = 0; dx < 2; dx++) {
                long x = x0 + dx, y = y0 + dy;
                if (!covered(cov, x, y, hi))
                    continue;
                float wt = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
                const float *p = im + 4 * ((size_t)y * wi + x);
                for (int ch = 0; ch < 4; ch++)
                    acc[ch] += wt * p[ch];
                wsum += wt;
            }
        for (int ch = 0; ch < 4; ch++)
            o[ch] = wsum > 0 ? acc[ch] / wsum : 0;
    }
}

/* The frame must be what the renderer was prepared for and lie in the
 * view's volume. */
static int check_frame(const struct tvpal_sw *r, const struct tvpal_frame *f,
                       struct tvpal_diag *diag)
{
    const struct tvpal_view *v = f->view;
    if (f->w != r->w || f->h != r->h)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "frame slices %ux%u, "
                              "renderer prepared for %ux%u", f->w, f->h,
                              r->w, r->h);
    const unsigned ax = f->cross ? 2 : v->axis;
    if (v->axis > 2 || f->w != v->dims[ax == 0 ? 1 : 0] || f->h != v->dims[ax == 2 ? 1 : 2])
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "frame slices %ux%u do not "
                              "match the view's volume", f->w, f->h);
    if (f->cross && (v->axis == 2 || f->stride < 1 || f->phase >= f->stride))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "cross frame along axis "
                              "%u, stride %u phase %u (expected axis x or y, "
                              "phase < stride)", v->axis, f->stride, f->phase);
    for (uint32_t n = 0; n < f->count; n++) {
        if (f->sl[n].layer >= r->layers)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "slice layer %u, "
                                  "renderer prepared for %u", f->sl[n].layer,
                                  r->layers);
        if (f->sl[n].slice >= v->dims[ax])
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "slice %u of an axis "
                                  "of %u", f->sl[n].slice, v->dims[ax]);
        if (f->cross && n == 0 && f->draw_end > f->draw_begin &&
            (f->draw_begin < f->sl[0].slice ||
             f->draw_end > f->sl[0].slice + f->count))
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "cross frame: rows "
                                  "%u..%u drawn, %u..%u held", f->draw_begin,
                                  f->draw_end, f->sl[0].slice,
                                  f->sl[0].slice + f->count);
        if (f->cross && f->sl[n].slice != f->sl[0].slice + n)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "cross frame: z slice "
                                  "%u at position %u after %u (expected "
                                  "consecutive slices)", f->sl[n].slice, n,
                                  f->sl[0].slice);
    }
    return 0;
}

/* ------------------------------------------------------- cross frames */

/* Tile side of slices w texels wide (as tvpal_sw_set_slices). */
static unsigned tile_for(uint32_t w)
{
    unsigned tile = TILE_MIN;
    while ((w + tile - 1) / tile > 64)
        tile *= 2;
    return tile;
}

static int grow(void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return 0;
    void *q = realloc(*p, need * elem);
    if (!q)
        return TVPAL_E_NOMEM;
    *p = q;
    *cap = need;
    return 0;
}

/* Scratch and the transposed copy of a cross frame; the copy's rows are
 * marked for cutting again when its layout changes. */
static int reserve_cross(struct tvpal_sw *r, const struct tvpal_frame *f,
                         int nt, struct tvpal_diag *diag)
{
    uint32_t wp, h, n;
    tvpal_frame_cross_geometry(f, &wp, &h, &n);
    struct cross_copy *x = &r->xc[f->view->axis];
    const uint32_t rows = f->count;
    const unsigned tile = tile_for(wp);
    const size_t trows = (rows + tile - 1) / tile;
    const size_t groups = (n + r->tile - 1) / r->tile;
    struct cross_scratch *xs = &r->xs;
    if ((size_t)n * rows > SIZE_MAX / (wp ? wp : 1))
        return tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "transposed indices");
    if (grow((void **)&x->idx, &x->cap, (size_t)n * rows * wp, 1) < 0)
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "transposed indices of "
                              "%u slices of %ux%u", n, wp, rows);
    if (rows > x->rows_cap) {
        uint32_t *g = realloc(x->gen, sizeof *g * rows);
        uint32_t *l = realloc(x->layer, sizeof *l * rows);
        if (g)
            x->gen = g;
        if (l)
            x->layer = l;
        if (!g || !l)
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "transposed indices");
        x->rows_cap = rows;
    }
    if (x->rows != rows || x->wp != wp || x->n != n) {
        memset(x->gen, 0, sizeof *x->gen * rows);
        x->rows = rows;
        x->wp = wp;
        x->n = n;
    }
    if (grow((void **)&xs->sl, &xs->sl_cap, n, sizeof *xs->sl) < 0 ||
        grow((void **)&xs->rowpal, &xs->rowpal_cap, rows, sizeof *xs->rowpal) < 0 ||
        grow((void **)&xs->gvis, &xs->gvis_cap, groups * trows, sizeof *xs->gvis) < 0 ||
        grow((void **)&xs->hit, &xs->hit_cap, (size_t)nt * r->trows, 1) < 0 ||
        grow((void **)&xs->todo, &xs->todo_cap, rows, sizeof *xs->todo) < 0)
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "cross frame scratch");
    return 0;
}

/* Visible cross tiles, from the visible z tiles (r->vis, classified for
 * the z slices' own palettes): a cross tile is drawn when some z tile
 * under it is visible.  That is conservative (a z tile covers tile-many
 * slices of the view's axis), never wrong: a transparent texel drawn adds
 * exactly zero.  Slices of one z tile group (s / tile) share their tiles,
 * so they are computed per group: gvis[g * trows' + tb]. */
static void cross_vis(struct tvpal_sw *r, const struct tvpal_frame *f,
                      uint32_t wp, uint32_t n, int nt, struct drawable *dr)
{
    const unsigned axis = f->view->axis, zt = r->tile;
    const uint32_t rows = f->count;
    const unsigned tile = dr->tile, trows = dr->trows;
    const unsigned tcols = (wp + tile - 1) / tile;
    const uint64_t all = tcols == 64 ? ~0ull : (1ull << tcols) - 1;
    const int groups = (int)((n + zt - 1) / zt);
    uint64_t *gv = r->xs.gvis;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(nt)
#endif
    for (int g = 0; g < groups; g++) {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        uint8_t *hit = r->xs.hit + (size_t)tid * r->trows;
        for (unsigned tb = 0; tb < trows; tb++) {
            const uint32_t k0 = tb * tile, k1 = k0 + tile < rows ? k0 + tile : rows;
            uint64_t bits = 0;
            if (!r->skip) {
                bits = all;
            } else if (axis == 1) {
                /* y slices: cross tile columns are the z tile columns (both
                 * tile nx texels alike); z tile row g. */
                for (uint32_t k = k0; k < k1; k++)
                    bits |= r->vis[(size_t)k * r->trows + g];
            } else {
                /* x slices: z tile column g; cross tile ta spans y, that is
                 * z tile rows ta tile / zt .. ((ta + 1) tile - 1) / zt. */
                memset(hit, 0, r->trows);
                for (uint32_t k = k0; k < k1; k++) {
                    const uint64_t *zv = r->vis + (size_t)k * r->trows;
                    for (unsigned ty = 0; ty < r->trows; ty++)
                        hit[ty] |= (uint8_t)((zv[ty] >> g) & 1);
                }
                for (unsigned ta = 0; ta < tcols; ta++) {
                    unsigned y0 = ta * tile, y1 = y0 + tile < wp ? y0 + tile : wp;
                    for (unsigned ty = y0 / zt; ty <= (y1 - 1) / zt; ty++)
                        if (hit[ty]) {
                            bits |= 1ull << ta;
                            break;
                        }
                }
            }
            gv[(size_t)g * trows + tb] = bits;
        }
    }
}

/* A cross frame as a drawable: the rows to cut again are cut (in
 * parallel), the slices to draw listed in drawing order, rows given their
 * palettes, and the visible tiles derived. */
static void prepare_cross(struct tvpal_sw *r, const struct tvpal_frame *f,
                          int nt, struct drawable *dr)
{
    const struct tvpal_view *v = f->view;
    const unsigned axis = v->axis;
    uint32_t wp, h, n;
    tvpal_frame_cross_geometry(f, &wp, &h, &n);
    struct cross_copy *x = &r->xc[axis];
    struct cross_scratch *xs = &r->xs;
    const uint32_t rows = f->count;
    uint32_t d0, d1;
    tvpal_frame_cross_draw_rows(f, &d0, &d1);
    int ntodo = 0;
    for (uint32_t k = 0; k < rows; k++) {
        const uint32_t layer = f->sl[k].layer;
        xs->rowpal[k] = f->sl[k].palette;
        if (x->gen[k] != r->ugen[layer] || x->layer[k] != layer)
            xs->todo[ntodo++] = k;
    }
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 2) num_threads(nt)
#endif
    for (int m = 0; m < ntodo; m++) {
        const uint32_t k = xs->todo[m], layer = f->sl[k].layer;
        tvpal_frame_cut_row(x->idx, axis, x->rows, k, f->sl[k].idx, f->w, f->h);
        x->layer[k] = layer;
        x->gen[k] = r->ugen[layer];
    }
    uint32_t count = 0;
    for (uint32_t i = 0; i < n; i++) {
        const uint32_t s = v->descending ? n - 1 - i : i;
        if (s % f->stride == f->phase)
            xs->sl[count++] = (struct tvpal_frame_slice){
                .slice = s, .idx = x->idx + (size_t)s * rows * wp};
    }
    const unsigned tile = tile_for(wp);
    *dr = (struct drawable){.sl = xs->sl, .count = count, .w = (int)wp,
                            .h = (int)h, .rb0 = (int)f->sl[0].slice,
                            .rb1 = (int)(f->sl[0].slice + rows),
                            .db0 = (int)d0, .db1 = (int)d1,
                            .rowpal = xs->rowpal, .vis = xs->gvis,
                            .vis_group = r->tile, .tile = tile,
                            .trows = (rows + tile - 1) / tile};
    cross_vis(r, f, wp, n, nt, dr);
}

/* Warp: output pixel centre -> eye -> base texel -> intermediate. */
static void setup_warp(const struct tvpal_view *v, unsigned w, unsigned h,
                       const struct geom *g, struct warp *wp)
{
    double e0[2], e1[2], e2[2], b0[2], b1[2], b2[2];
    tvpal_view_pixel_to_eye(v, 0.5, 0.5, &e0[0], &e0[1]);
    tvpal_view_pixel_to_eye(v, 1.5, 0.5, &e1[0], &e1[1]);
    tvpal_view_pixel_to_eye(v, 0.5, 1.5, &e2[0], &e2[1]);
    eye_to_base(g, w, h, e0[0], e0[1], &b0[0], &b0[1]);
    eye_to_base(g, w, h, e1[0], e1[1], &b1[0], &b1[1]);
    eye_to_base(g, w, h, e2[0], e2[1], &b2[0], &b2[1]);
    wp->ox = (b0[0] - g->u0) * g->k - 0.5;
    wp->oy = (b0[1] - g->v0) * g->k - 0.5;
    wp->ax = (b1[0] - b0[0]) * g->k;
    wp->ay = (b1[1] - b0[1]) * g->k;
    wp->bx = (b2[0] - b0[0]) * g->k;
    wp->by = (b2[1] - b0[1]) * g->k;
}

/* Only the part of the intermediate image the output samples (with a pixel
 * of margin around every tap) is composited: a zoomed-in view does not pay
 * for what it does not show.  Pixels keep their global coordinates, so
 * clipping changes no bit.  Without skipping: all of it. */
static void clip_to_output(const struct tvpal_view *v, const struct warp *wp,
                           int skip, struct geom *g)
{
    g->io = g->jo = 0;
    g->wc = g->wi;
    g->hc = g->hi;
    if (!skip)
        return;
    const double W1 = v->width - 1.0, H1 = v->height - 1.0;
    double xs[4] = {wp->ox, wp->ox + wp->ax * W1, wp->ox + wp->bx * H1,
                    wp->ox + wp->ax * W1 + wp->bx * H1};
    double ys[4] = {wp->oy, wp->oy + wp->ay * W1, wp->oy + wp->by * H1,
                    wp->oy + wp->ay * W1 + wp->by * H1};
    double x0 = xs[0], x1 = xs[0], y0 = ys[0], y1 = ys[0];
    for (int i = 1; i < 4; i++) {
        x0 = fmin(x0, xs[i]);
        x1 = fmax(x1, xs[i]);
        y0 = fmin(y0, ys[i]);
        y1 = fmax(y1, ys[i]);
    }
    double ilo = fmax(0, floor(x0) - 1), ihi = fmin(g->wi, floor(x1) + 3);
    double jlo = fmax(0, floor(y0) - 1), jhi = fmin(g->hi, floor(y1) + 3);
    g->io = (long)ilo;
    g->jo = (long)jlo;
    g->wc = ihi > ilo ? (unsigned)(ihi - ilo) : 0;
    g->hc = jhi > jlo ? (unsigned)(jhi - jlo) : 0;
}

/* Scratch grows to the largest frame seen, then stays: no allocation per
 * frame in steady playback.  band: rows composited together (a map each,
 * per thread). */
static int reserve_scratch(struct tvpal_sw *r, const struct tvpal_frame *f,
                           const struct geom *g, unsigned band, int nt,
                           struct tvpal_diag *diag)
{
    size_t nwords = map_words(g->wc) * band * (size_t)nt;
    if (nwords > r->maps_cap) {
        uint64_t *nm = realloc(r->maps, sizeof *nm * nwords);
        if (!nm)
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "stopped-pixel maps");
        r->maps = nm;
        r->maps_cap = nwords;
    }
    if (f->count > r->vis_cap) {
        uint64_t *nv = realloc(r->vis, sizeof *nv * f->count * r->trows);
        if (!nv)
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "visible tiles");
        r->vis = nv;
        r->vis_cap = f->count;
    }
    size_t need = (size_t)(g->wc ? g->wc : 1) * (g->hc ? g->hc : 1) * 4;
    if (need > r->cap) {
        float *nim = realloc(r->im, need * sizeof *nim);
        if (!nim)
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "intermediate image "
                                  "%ux%u", g->wc, g->hc);
        r->im = nim;
        r->cap = need;
    }
    if (g->hc + 1 > r->cov_cap) {
        int32_t *nc = realloc(r->cov, sizeof(int32_t) * 2 * (g->hc + 1));
        if (!nc)
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "coverage rows");
        r->cov = nc;
        r->cov_cap = g->hc + 1;
    }
    return 0;
}

/* Classify: the visible tiles of every frame slice for its own palette,
 * building the sets it needs (classify).  A layer's sets are written by
 * one thread: the first frame slice of each layer is classified in
 * parallel, any further one (a layer shown twice, which the player never
 * does) after, in order. */
static void classify_frame(struct tvpal_sw *r, const struct tvpal_frame *f,
                           int nt)
{
    const int count = (int)f->count;
    int nfirst = 0;
    for (int n = 0; n < count; n++)
        r->first[f->sl[n].layer] = UINT32_MAX;
    for (int n = 0; n < count; n++)
        if (r->first[f->sl[n].layer] == UINT32_MAX) {
            r->first[f->sl[n].layer] = (uint32_t)n;
            r->todo[nfirst++] = (uint32_t)n;
        }
    unsigned long witnessed = 0, probed = 0, built = 0;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 8) num_threads(nt) reduction(+ : witnessed, probed, built)
#endif
    for (int m = 0; m < nfirst; m++) {
        struct tvpal_sw_counts c = {0, 0, 0};
        const uint32_t n = r->todo[m];
        classify(r, &f->sl[n], r->vis + (size_t)n * r->trows, &c);
        witnessed += c.witnessed;
        probed += c.probed;
        built += c.built;
    }
    r->counts = (struct tvpal_sw_counts){witnessed, probed, built};
    for (int n = 0; n < count; n++)
        if (r->first[f->sl[n].layer] != (uint32_t)n)
            classify(r, &f->sl[n], r->vis + (size_t)n * r->trows, &r->counts);
}

int tvpal_sw_draw(struct tvpal_sw *r, const struct tvpal_frame *f,
                  float *rgba, struct tvpal_diag *diag)
{
    const struct tvpal_view *v = f->view;
    struct geom g;
    struct warp wp;
    double t0 = tvpal_now();
    int rc = check_frame(r, f, diag);
    if (rc < 0)
        return rc;
    uint32_t w = f->w, h = f->h, n;
    if (f->cross)
        tvpal_frame_cross_geometry(f, &w, &h, &n);
    if (setup(v, w, h, r->force_k, &g) < 0)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "degenerate view");
    setup_warp(v, w, h, &g, &wp);
    clip_to_output(v, &wp, r->skip, &g);
    int nt = 1;
#ifdef _OPENMP
    nt = r->threads > 0 ? r->threads : omp_get_max_threads();
#endif
    const unsigned band = band_rows(r, g.wc);
    if ((rc = reserve_scratch(r, f, &g, band, nt, diag)) < 0)
        return rc;
    if (f->cross && f->count && (rc = reserve_cross(r, f, nt, diag)) < 0)
        return rc;
    r->avx2 = r->simd && cpu_avx2();
    r->k_last = g.k;
    r->stop = !r->skip ? NAN : TVPAL_SW_ALPHA_STOP;
    const int use_maps = r->skip && r->runs;
    classify_frame(r, f, nt);
    struct drawable dr = {.sl = f->sl, .count = f->count, .w = (int)w,
                          .h = (int)h, .rb0 = 0, .rb1 = (int)h,
                          .db0 = 0, .db1 = (int)h,
                          .vis = r->vis, .tile = r->tile, .trows = r->trows};
    if (f->cross && f->count)
        prepare_cross(r, f, nt, &dr);
    else if (f->cross)
        dr.count = 0;
    double t1 = tvpal_now();
    r->t_classify = (t1 - t0) * 1e3;
    /* Composite: bands of rows of the intermediate image, handed out
     * dynamically (rows near the edges meet fewer slices). */
    r->band_last = band;
    const int nbands = (int)((g.hc + band - 1) / band);
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(nt)
#endif
    for (int m = 0; m < nbands; m++) {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        const unsigned j0 = (unsigned)m * band;
        composite_band(r, &dr, v, &g, j0, g.hc - j0 < band ? g.hc - j0 : band,
                       r->im, r->cov,
                       use_maps ? r->maps + map_words(g.wc) * band * tid : NULL);
    }
    double t2 = tvpal_now();
    r->t_composite = (t2 - t1) * 1e3;
    const int H = (int)v->height;
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(nt)
#endif
    for (int py = 0; py < H; py++)
        warp_row(r->im, r->cov, g.io, g.jo, g.wc, g.hc, &wp, v->width, (unsigned)py,
                 rgba + (size_t)4 * v->width * py);
    r->t_warp = (tvpal_now() - t2) * 1e3;
    return 0;
}

/* ------------------------------------------------ the renderer interface */

static int sw_set(void *c, uint32_t w, uint32_t h, uint32_t n,
                  struct tvpal_diag *d)
{
    return tvpal_sw_set_slices(c, w, h, n, d);
}

static void sw_up(void *c, uint32_t layer, const uint8_t *idx)
{
    (void)idx; /* read from the frame when drawn */
    tvpal_sw_upload(c, layer);
}

static int sw_draw(void *c, const struct tvpal_frame *f, float *rgba,
                   struct tvpal_diag *d)
{
    return tvpal_sw_draw(c, f, rgba, d);
}

static void sw_times(const void *c, struct tvpal_render_times *t)
{
    tvpal_sw_times(c, &t->classify_ms, &t->composite_ms, &t->warp_ms);
}

static void sw_describe(const void *c, char *buf, size_t cap)
{
    int nt = 1;
#ifdef _OPENMP
    nt = omp_get_max_threads();
#endif
    const struct tvpal_sw *r = c;
    char band[48];
    if (r->band)
        snprintf(band, sizeof band, "bands of %u rows", r->band);
    else if (r->l2)
        snprintf(band, sizeof band, "bands for %zu KiB of L2", r->l2 >> 10);
    else
        snprintf(band, sizeof band, "bands of %u rows (L2 unknown)", BAND_MIN);
    snprintf(buf, cap, "shear-warp, %s, %d thread%s, %s", tvpal_sw_simd_name(r),
             nt, nt == 1 ? "" : "s", band);
}

void tvpal_sw_renderer(struct tvpal_sw *r, struct tvpal_renderer *out)
{
    *out = (struct tvpal_renderer){.name = "cpu", .ctx = r,
                                   .set_slices = sw_set, .upload = sw_up,
                                   .draw = sw_draw, .times = sw_times,
                                   .describe = sw_describe};
}
