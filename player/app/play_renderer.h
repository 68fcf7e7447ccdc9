/* play_renderer.h: the renderer tvpal-play draws with, made from the
 * --renderer choice; each kind is its module's own tvpal_renderer. */
#ifndef PLAY_RENDERER_H
#define PLAY_RENDERER_H

#include <stddef.h>

#include "tvpal_frame.h"
#include "tvpal_glr.h"
#include "tvpal_osmesa.h"
#include "tvpal_render_ref.h"
#include "tvpal_sw.h"

struct play_renderer {
    struct tvpal_renderer r;      /* what the player draws with */
    struct tvpal_sw *sw;          /* the module behind r (one of these) */
    struct tvpal_glr *glr;
    struct tvpal_ref *ref;
    struct tvpal_osmesa *osmesa;  /* gl without a window: its context */
    unsigned fb_bits;
};

/* Opens `kind` (enum play_renderer_kind, not AUTO) for images of
 * width x height.  gl draws into a framebuffer of fb_bits per channel and,
 * with need_context, first makes its own OSMesa context (headless; a window
 * has its GL context already).  cpu_scale: the shear-warp K, 0 for auto;
 * exact: the shear-warp stops a pixel only at alpha 1 (tvpal_sw_set_exact).
 * 0 or a TVPAL_E_* code with diag; *pr is then safe to close. */
int play_renderer_open(struct play_renderer *pr, int kind, unsigned width,
                       unsigned height, unsigned fb_bits, unsigned cpu_scale,
                       int exact, int need_context, struct tvpal_diag *diag);
/* A new image size (the window was resized): gl gets a new framebuffer. */
int play_renderer_resize(struct play_renderer *pr, unsigned width,
                         unsigned height, struct tvpal_diag *diag);
void play_renderer_close(struct play_renderer *pr);

/* "cpu (shear-warp, avx2, 2 threads" ... into buf: name and what runs. */
const char *play_renderer_describe(const struct play_renderer *pr,
                                   char *buf, size_t cap);

/* Whether a GL_RENDERER string names one of Mesa's software rasterizers
 * (llvmpipe, softpipe, swrast), on which the cpu renderer is faster. */
int play_gl_is_software(const char *name);

#endif
