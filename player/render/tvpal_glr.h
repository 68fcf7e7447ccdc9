/* tvpal_glr.h: the GL palette renderer (needs a current OpenGL 3.3 core
 * context: OSMesa headless, see tvpal_osmesa.h, or a GLFW window).
 *
 * Slice indices live in a 2D texture array of R8UI, one layer per slice of
 * the current axis, uploaded only when a slice's window changes; palettes
 * (256 x RGBA32F per layer) are one small texture re-uploaded every frame.
 * The fragment shader emulates a paletted texture exactly as
 * tvpal_render_ref does (four texelFetch, palette lookup, bilinear mix of
 * the colours) and blending is "over" into an RGBA32F framebuffer, so 8-bit
 * accumulation does not band.
 *
 * Cross frames (tvpal_frame.h; single-copy datasets): the layers are the z
 * slices held (set_slices(nx, ny, count), as for a z view), so the same
 * texture array is the volume.  The renderer draws one quad per x or y
 * slice s drawn, cut to the rows held, and its own program (one for y, one
 * for x slices) fetches texel (a, b): for y slices at (a, s) of layer b -
 * z0 + (z0's layer); for x slices from a transposed copy (layer s, row b -
 * z0: a z layer's column is a row apart per texel), cut on the CPU and
 * uploaded row by row only where a layer changed since (a byte per voxel
 * on the CPU and in GL); each texel is looked up in its z slice's palette
 * row, the rows clamped to those held; interpolation and blending are the
 * plain path's.  Crossing between z, x and y views of the same z slices
 * uploads no z layer again (the first x view cuts the transposed copy).
 * A cross frame's z slices
 * must sit in consecutive layers in ascending order (the player's layer =
 * slice - first held).  This file is the only one that includes GL
 * headers (with tvpal_osmesa.c and the GLFW front end).
 */
#ifndef TVPAL_GLR_H
#define TVPAL_GLR_H

#include <stdint.h>

#include "tvpal_error.h"
#include "tvpal_frame.h"

struct tvpal_glr;

/* Creates the renderer for images of width x height (a framebuffer it owns)
 * in the current context.  diag says what failed (shader log, FBO status). */
int tvpal_glr_create(struct tvpal_glr **out, unsigned width, unsigned height,
                     struct tvpal_diag *diag);

/* The same with the colour buffer's precision chosen: 32 (RGBA32F, the
 * default), 16 (RGBA16F) or 8 (RGBA8: blending rounds every layer to 1/255,
 * which bands over many translucent slices; for comparison). */
int tvpal_glr_create_fb(struct tvpal_glr **out, unsigned width,
                        unsigned height, unsigned fb_bits,
                        struct tvpal_diag *diag);
void tvpal_glr_free(struct tvpal_glr *r);   /* NULL is a no-op */

/* (Re)allocates the index texture array for `count` slices of w x h (on
 * axis changes of a three-copy dataset; z slices serve every view of a
 * single-copy one); all layers are then undefined until uploaded. */
int tvpal_glr_set_slices(struct tvpal_glr *r, uint32_t w, uint32_t h,
                         uint32_t count, struct tvpal_diag *diag);

/* Uploads the indices of slice `layer`. */
void tvpal_glr_upload(struct tvpal_glr *r, uint32_t layer,
                      const uint8_t *idx);

/* Draws the frame (palettes uploaded here) and reads the image back as
 * width * height RGBA floats, row 0 at the bottom, when rgba is non-NULL.
 * A cross frame the layers do not hold as above (other slice size, more
 * slices than layers, layers not consecutive), along z or with stride 0
 * is refused with TVPAL_E_INVAL and draws nothing. */
int tvpal_glr_draw(struct tvpal_glr *r, const struct tvpal_frame *f,
                   float *rgba, struct tvpal_diag *diag);

/* Copies the last frame to the default framebuffer at (x, y) (window
 * front end); the premultiplied colours show over black. */
void tvpal_glr_blit(struct tvpal_glr *r, int x, int y);

/* The GL renderer string of the current context (e.g. "llvmpipe ..."). */
const char *tvpal_glr_gl_name(void);

/* Slice texture uploads so far (tests: a TF change must upload none). */
uint64_t tvpal_glr_uploads(const struct tvpal_glr *r);

/* Phase times of the last draw in milliseconds (palette upload, draw with
 * glFinish, readback). */
void tvpal_glr_times(const struct tvpal_glr *r, double *upload_ms,
                     double *draw_ms, double *readback_ms);

/* r behind the renderer interface (name "gl"; times: upload, draw,
 * readback; described by the GL renderer's name).  r stays owned by the
 * caller. */
void tvpal_glr_renderer(struct tvpal_glr *r, struct tvpal_renderer *out);

#endif
