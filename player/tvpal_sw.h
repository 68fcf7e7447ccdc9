/* tvpal_sw.h: the CPU palette renderer by shear-warp factorization
 * (Lacroute & Levoy, SIGGRAPH 1994), for nodes without a GPU.
 *
 * Axis-aligned slices under an orthographic view make the factorization
 * exact: each slice is translated onto an intermediate image aligned with
 * the slices (the translation grows linearly with the slice's depth), and
 * one 2D affine warp maps that image to the output.  Slices are composited
 * front to back into the intermediate image with the same palette
 * semantics as tvpal_render_ref (four nearest texels looked up in the
 * slice's palette, colours interpolated, premultiplied "over"), so only the
 * resampling differs.  The intermediate image has up to as many pixels per
 * voxel as the output needs (zoomed-in views stay sharp).  Empty space is
 * skipped (texel quads whose four palette entries are transparent) and a
 * pixel stops accumulating once fully opaque; neither changes a pixel.
 * Rows of the intermediate image are split among threads (OpenMP): the
 * result is the same for any thread count.  No allocation per frame once
 * the largest image has been seen.
 */
#ifndef TVPAL_SW_H
#define TVPAL_SW_H

#include "tvpal_error.h"
#include "tvpal_render.h"

struct tvpal_sw;

int tvpal_sw_create(struct tvpal_sw **out);
void tvpal_sw_free(struct tvpal_sw *r);   /* NULL is a no-op */

/* Options for tests: threads (0 = all), skip (empty-space skipping and
 * early termination; 1 by default). */
void tvpal_sw_options(struct tvpal_sw *r, int threads, int skip);

/* Renders the frame (slices in back-to-front order, as for the other
 * renderers) into width * height RGBA floats, row 0 at the bottom. */
int tvpal_sw_draw(struct tvpal_sw *r, const struct tvpal_frame *f,
                  float *rgba, struct tvpal_diag *diag);

/* Phase times of the last draw (ms): classification, compositing, warp. */
void tvpal_sw_times(const struct tvpal_sw *r, double *classify_ms,
                    double *composite_ms, double *warp_ms);

#endif
