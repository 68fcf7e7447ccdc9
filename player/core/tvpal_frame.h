/* tvpal_frame.h: what a renderer draws in one frame, the palette of a
 * slice, and the interface every renderer implements (tvpal_renderer).
 *
 * A frame is the slices of one axis, in drawing order (back to front),
 * each an 8-bit index image with its palette for this frame:
 * palette[i] = opacity-corrected, premultiplied TF(decoder[t][i]) (the
 * TF's NaN colour where decoder[t][i] is NaN: a missing value).  The
 * renderer emulates a paletted texture: it fetches the four texels nearest
 * the sample point (texel centres at (i + 0.5) / w, clamped to the edge),
 * looks each index up in the palette and interpolates the RGBA bilinearly
 * (after the lookup: interpolating indices would mix unrelated values), then
 * blends "over" back to front: dst = src + (1 - src.a) dst.
 */
#ifndef TVPAL_FRAME_H
#define TVPAL_FRAME_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_tf.h"
#include "tvpal_view.h"
#include "tvpal_error.h"

struct tvpal_frame_slice {
    uint32_t slice;           /* index along the view's axis (position) */
    uint32_t layer;           /* texture layer holding it (renderers) */
    const uint8_t *idx;       /* w * h indices, a fastest */
    const float *palette;     /* 256 x RGBA, premultiplied, corrected */
};

struct tvpal_frame {
    const struct tvpal_view *view;
    uint32_t w, h;                        /* slice size */
    uint32_t count;                       /* slices to draw */
    const struct tvpal_frame_slice *sl;   /* in drawing order */
    /* Cross frames (a single-copy dataset: only z slices stored, the view's
     * axis x or y).  cross = 0: sl are slices of the view's axis, as above.
     * cross = 1: sl are the z slices held, [z0, z0 + count) with z0 =
     * sl[0].slice, in ascending order, every one with its palette (a fully
     * transparent one too: it is the palette of a row); w x h = nx x ny.
     * The renderer draws the view axis' slices s (0 <= s < dims[axis])
     * with s % stride == phase, back to front, each cut from the z slices:
     * texel (a, b) of x slice s is index (s, a) of z slice b, of y slice s
     * index (a, s) of z slice b, and takes the palette of z slice b.  Only
     * rows b in [z0, z0 + count) exist: samples outside are not drawn and
     * the bilinear taps clamp to those rows (a slab of a cluster node draws
     * its own rows; at a slab boundary the taps across it clamp, unless
     * the frame also holds the neighbours' boundary rows, below).  The
     * palette semantics are those of every frame: each of the four texels
     * is looked up in its own row's palette, then the colours are
     * interpolated. */
    int cross;
    uint32_t stride, phase;               /* cross frames: s % stride ==
                                             phase is drawn; stride >= 1 */
    /* Cross frames: the rows whose samples are drawn, [draw_begin,
     * draw_end) within the rows held; draw_end == 0: all rows held.  A
     * cluster node holds its slab and a ghost row on each side (its
     * neighbours' boundary z slices) and draws its slab's samples: the
     * taps of those within half a row of the boundary reach the ghost
     * row, so the nodes' samples are exactly the one node's. */
    uint32_t draw_begin, draw_end;
};

/* Cuts row k of a transposed copy of a cross frame's z slices: copy holds
 * the slices of view axis `axis` (0 x, 1 y), slice s at copy + s * rows * w'
 * (w' = ny for x, nx for y), rows of w' texels; row k gets z slice idx (nx
 * x ny): for x slices its columns (texel (s, a) = idx[s + nx a]), for y
 * slices its rows.  What both renderers keep for x views (a column of a z
 * slice is a row apart per texel), and the cpu renderer for y views. */
void tvpal_frame_cut_row(uint8_t *copy, unsigned axis, uint32_t rows,
                         uint32_t k, const uint8_t *idx, uint32_t nx,
                         uint32_t ny);

/* The rows of a cross frame whose samples are drawn (see above). */
static inline void tvpal_frame_cross_draw_rows(const struct tvpal_frame *f,
                                               uint32_t *d0, uint32_t *d1)
{
    const uint32_t z0 = f->count ? f->sl[0].slice : 0;
    if (f->draw_end > f->draw_begin) {
        *d0 = f->draw_begin;
        *d1 = f->draw_end;
    } else {
        *d0 = z0;
        *d1 = z0 + f->count;
    }
}

/* The view-axis slice geometry of a cross frame: slices of w x h texels
 * (h = the volume's nz, of which the frame holds rows [z0, z0 + count))
 * and the count of slices along the view's axis. */
static inline void tvpal_frame_cross_geometry(const struct tvpal_frame *f,
                                              uint32_t *w, uint32_t *h,
                                              uint32_t *n)
{
    const struct tvpal_view *v = f->view;
    *w = v->axis == 0 ? v->dims[1] : v->dims[0];
    *h = v->dims[2];
    *n = v->dims[v->axis];
}

/* palette[i] for i < 256 from the decoded values row[256] of one slice at
 * one timestep; a NaN row[i] (a missing value) takes tf->nan_rgba, scaled,
 * corrected and premultiplied like any other colour, so the default
 * transparent NaN colour gives exactly {0, 0, 0, 0}.  Returns 1 when every
 * entry is fully transparent (the slice can be skipped), else 0. */
int tvpal_palette_build(const struct tvpal_tf *tf, const float *row,
                        double opacity_exponent, double opacity_scale,
                        float *palette);

/* Phase times of a renderer's last draw, in ms; a renderer fills the
 * phases it has and leaves the others as the caller set them. */
struct tvpal_render_times {
    double upload_ms, draw_ms, readback_ms;     /* gl */
    double classify_ms, composite_ms, warp_ms;  /* cpu shear-warp */
};

/* The interface every renderer implements (render/: cpu shear-warp, gl, the
 * reference; tvpal_renderer_none below).  Each renderer module fills one
 * with its own function (tvpal_sw_renderer, tvpal_glr_renderer,
 * tvpal_ref_renderer); ctx stays owned by that module's create/free.  The
 * player that drew last owns the renderer's slice data (owner); another
 * player drawing with it re-uploads everything first. */
struct tvpal_renderer {
    const char *name;    /* "cpu", "gl", "ref" or "none" */
    void *ctx;
    const void *owner;   /* set by the player; start with NULL */
    /* Prepare for `count` slices of w x h (axis change). */
    int (*set_slices)(void *ctx, uint32_t w, uint32_t h, uint32_t count,
                      struct tvpal_diag *diag);
    /* Slice data of `layer` changed; idx (w * h indices) stays valid
     * until the next upload of that layer. */
    void (*upload)(void *ctx, uint32_t layer, const uint8_t *idx);
    /* Draw and read back into rgba (width * height * 4 floats of the
     * frame's view, premultiplied, row 0 at the bottom). */
    int (*draw)(void *ctx, const struct tvpal_frame *f, float *rgba,
                struct tvpal_diag *diag);
    /* Phase times of the last draw (NULL: none but the caller's). */
    void (*times)(const void *ctx, struct tvpal_render_times *t);
    /* What runs, for the start-up line: "shear-warp, avx2, 2 threads",
     * the GL renderer's name, ...; written to buf (cap bytes). */
    void (*describe)(const void *ctx, char *buf, size_t cap);
};

/* A renderer that draws nothing (an all-transparent image): for reading
 * and decoding alone, as I/O benchmarks do. */
void tvpal_renderer_none(struct tvpal_renderer *r);

#endif
