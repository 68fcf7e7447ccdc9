/* tvpal_render_ref.h: the CPU reference renderer every other renderer is
 * tested against (slow on purpose: per pixel and slice, the ray meets the
 * slice plane in double precision). */
#ifndef TVPAL_RENDER_REF_H
#define TVPAL_RENDER_REF_H
#include "tvpal_frame.h"

/* Reference renderer, in double precision: writes width * height RGBA
 * (premultiplied) doubles, row 0 at the bottom (GL convention). */
void tvpal_render_ref(const struct tvpal_frame *f, double *rgba);

/* The same with interpolation of indices instead of colours (what a
 * dependent texture lookup would do; for tests and demonstrations). */
void tvpal_render_ref_index_interp(const struct tvpal_frame *f,
                                   double *rgba);

#endif
