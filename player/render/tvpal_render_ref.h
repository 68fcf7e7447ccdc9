/* tvpal_render_ref.h: the CPU reference renderer every other renderer is
 * tested against (slow on purpose: per pixel and slice, the ray meets the
 * slice plane in double precision). */
#ifndef TVPAL_RENDER_REF_H
#define TVPAL_RENDER_REF_H
#include <stddef.h>

#include "tvpal_frame.h"

/* Reference renderer, in double precision: writes width * height RGBA
 * (premultiplied) doubles, row 0 at the bottom (GL convention). */
void tvpal_render_ref(const struct tvpal_frame *f, double *rgba);

/* The same with interpolation of indices instead of colours (what a
 * dependent texture lookup would do; for tests and demonstrations). */
void tvpal_render_ref_index_interp(const struct tvpal_frame *f,
                                   double *rgba);

/* The reference renderer behind the renderer interface (name "ref"): it
 * keeps its double-precision image, which tvpal_ref_image returns after a
 * draw (for PSNR against the float image a fast renderer drew). */
struct tvpal_ref;
/* Images of at most max_pixels pixels.  Owns *out on success (free with
 * tvpal_ref_free); TVPAL_E_NOMEM or TVPAL_E_OVERFLOW. */
int tvpal_ref_create(struct tvpal_ref **out, size_t max_pixels);
void tvpal_ref_free(struct tvpal_ref *ref);   /* NULL is a no-op */
void tvpal_ref_renderer(struct tvpal_ref *ref, struct tvpal_renderer *out);
/* The last image drawn: width * height RGBA doubles, row 0 at the bottom. */
const double *tvpal_ref_image(const struct tvpal_ref *ref);

#endif
