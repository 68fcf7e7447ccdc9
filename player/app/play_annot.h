/* play_annot.h: tvpal-play's annotations (--annotate, --background) and
 * the window's HUD: what a frame shows, made from the session (manifest,
 * transfer function) and the view, drawn by tvpal_annot into rank 0's
 * final 8-bit frame, the one every output (PNG, window, movie) writes. */
#ifndef PLAY_ANNOT_H
#define PLAY_ANNOT_H

#include <stdint.h>

#include "play.h"
#include "tvpal_annot.h"
#include "tvpal_view.h"

struct play_annot {
    struct tvpal_annot *a;          /* NULL: no annotations, no HUD */
    unsigned what;                  /* TVPAL_ANNOT_* of --annotate */
    unsigned place;                 /* --legend (enum tvpal_annot_place) */
    float fg[3], halo[3];           /* from --background */
    const struct tvpal_tf *tf;      /* the legend's: the frame's TF, */
    double opacity;                 /* at its opacity scale */
    char title[160], time[192];
    int warned_text;                /* a label not valid UTF-8 was said */
};

/* What --annotate LEVEL draws (TVPAL_ANNOT_* bits): none 0, minimal the
 * legend and the time, full those, the outline and the triad. */
unsigned play_annot_bits(int level);

/* Opens pa for frames of width x height with o's --annotate and
 * --background; with nothing to draw and want_hud 0, pa->a stays NULL and
 * nothing is made.  0 or a TVPAL_E_* code with diag (cairo failed). */
int play_annot_open(struct play_annot *pa, const struct play_opts *o,
                    int want_hud, unsigned width, unsigned height,
                    struct tvpal_diag *diag);
void play_annot_close(struct play_annot *pa);

/* Annotates frame (premultiplied RGBA, row 0 at the bottom; the
 * compositor's output) of step t of the session as seen by v, level 0's
 * view; nothing when pa->what is 0. */
int play_annot_frame(struct play_annot *pa, const struct play_session *s,
                     const struct tvpal_view *v, uint32_t t, uint8_t *frame,
                     struct tvpal_diag *diag);

/* The eight corners of v's volume box in pixel coordinates (as
 * tvpal_view_eye_to_pixel gives them), corner c at +x with bit 0, +y bit
 * 1, +z bit 2: where the outline's lines meet. */
void play_annot_box_corners(const struct tvpal_view *v, double corner[8][2]);

#endif
