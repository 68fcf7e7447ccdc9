/* tvpal_annot.h: annotations drawn into tvpal-play's final 8-bit frame
 * (a colour legend, the time, the volume's outline, an orientation triad)
 * and the window's HUD, with cairo.  tvpal_annot.c is the only file that
 * includes cairo; without cairo tvpal_annot_none.c answers every create
 * with TVPAL_E_SYS and a message naming the Debian package.
 *
 * The frame is what tvpal_composite gives rank 0: width x height
 * premultiplied 8-bit RGBA, row 0 at the BOTTOM.  Annotations are drawn
 * with cairo into an overlay of the module's own (ARGB32, top row first,
 * made once by create), then blended "over" the frame where the overlay
 * is not transparent, so one call annotates whatever writes the frame
 * afterwards (PNG, window, movie) and the background still shows where
 * nothing is drawn.  Text and lines are in fg with a halo in halo (the
 * background colour), so they read over the volume and the background.
 *
 * The legend is a vertical bar at the right: its left half (the swatch)
 * is the colour at full opacity, its right half the colour at its opacity
 * over a grey checkerboard.  Every row of the bar is the colour function at
 * the value of the row's centre, rounded to 8 bits; tick values are round
 * numbers (1, 2 or 5 times a power of ten apart: Heckbert, "Nice numbers
 * for graph labels", Graphics Gems, 1990) and the bar's scale is chosen so
 * that each tick falls exactly on a row's centre, so the row beside a
 * label shows the colour of the labelled value itself.
 *
 * The legend is kept from frame to frame (in a second layer) and drawn
 * again only when its range, its rows' colours, its title or the text
 * colours change: its labels are most of the drawing's cost.  Nothing
 * here allocates per frame except what cairo does inside (paths, glyphs).
 * About 0.7 ms of CPU per 512x512 frame with everything on.  Not
 * thread-safe per handle. */
#ifndef TVPAL_ANNOT_H
#define TVPAL_ANNOT_H

#include <stdint.h>

#include "tvpal_error.h"

/* What a frame shows: bits of tvpal_annot_frame.what. */
#define TVPAL_ANNOT_LEGEND 1u
#define TVPAL_ANNOT_TIME 2u
#define TVPAL_ANNOT_OUTLINE 4u
#define TVPAL_ANNOT_TRIAD 8u

#define TVPAL_ANNOT_MAX_TICKS 16
#define TVPAL_ANNOT_MAX_SIDE 16384   /* width and height, each */

/* Where the legend goes (tvpal_annot_frame.legend_place).  AUTO, the
 * default: of right (middle), right top, right bottom and left (middle),
 * in that order, the first that covers the least of the volume's
 * projection (the hull of the outline's corners), so that an oblique or
 * map view keeps its data clear of the bar where the image has room; the
 * left places leave the time (top left) and the triad (bottom left)
 * alone. */
enum tvpal_annot_place {
    TVPAL_ANNOT_PLACE_AUTO = 0,
    TVPAL_ANNOT_PLACE_RIGHT,
    TVPAL_ANNOT_PLACE_RIGHT_TOP,
    TVPAL_ANNOT_PLACE_RIGHT_BOTTOM,
    TVPAL_ANNOT_PLACE_LEFT,
    TVPAL_ANNOT_PLACES
};

/* Straight (not premultiplied) colour and opacity at a value, each in
 * [0, 1] (an opacity above 1 counts as 1). */
typedef void (*tvpal_annot_colour_fn)(void *ctx, double value,
                                      float rgba[4]);

struct tvpal_annot_frame {
    unsigned what;                  /* TVPAL_ANNOT_* bits; 0: draw nothing */
    float fg[3], halo[3];           /* text and line colour, its halo; 0..1 */
    /* legend: the bar spans [vmin, vmax] (finite, vmin < vmax); with
     * log_scale (a log-scale TF: vmin > 0) its rows and ticks are evenly
     * spaced in log10 of the value, the ticks at powers of ten where the
     * range holds two or more, and the colour function is still called
     * with values, not their logs */
    double vmin, vmax;
    int log_scale;
    tvpal_annot_colour_fn colour;
    void *colour_ctx;
    const char *title;              /* above the bar, or NULL */
    enum tvpal_annot_place legend_place;
    const char *time_text;          /* top left (TVPAL_ANNOT_TIME) */
    /* outline: the volume box's corners in pixel coordinates as
     * tvpal_view_eye_to_pixel gives them (x to the right, y up from the
     * bottom edge, pixel centres at integer + 0.5); corner c is at +x when
     * bit 0 of c is set, +y bit 1, +z bit 2.  Edges join corners one bit
     * apart.  Also what the legend's AUTO place keeps clear of (all zero:
     * nothing to keep clear of), whether or not the outline is drawn. */
    double corner[8][2];
    /* triad: the object axes x, y, z as eye-space (x, y) directions (the
     * projection of unit vectors; up is +y), drawn from the bottom left */
    double axis_dir[3][2];
};

/* Where the last tvpal_annot_draw put the legend, in image pixels with
 * row 0 at the TOP (a PNG's rows): tests sample the frame there. */
struct tvpal_annot_legend {
    int shown;                      /* 0: no legend was drawn */
    unsigned x0, y0, w, h;          /* the bar */
    unsigned swatch_x0, swatch_w;   /* its opaque half */
    unsigned nticks;
    double tick_value[TVPAL_ANNOT_MAX_TICKS];
    unsigned tick_row[TVPAL_ANNOT_MAX_TICKS]; /* the row whose centre is
                                               * tick_value */
    char tick_label[TVPAL_ANNOT_MAX_TICKS][32];
};

struct tvpal_annot;

/* Whether annotations are built in (cairo), and the library's version
 * ("cairo 1.16.0"), or why not ("built without cairo: ..."). */
int tvpal_annot_available(void);
const char *tvpal_annot_describe(void);

/* Makes the overlay and cairo context for frames of width x height (each
 * 1..TVPAL_ANNOT_MAX_SIDE).  TVPAL_E_INVAL for a size out of range,
 * TVPAL_E_NOMEM, TVPAL_E_SYS (no cairo, a cairo failure) with diag. */
int tvpal_annot_create(struct tvpal_annot **out, unsigned width,
                       unsigned height, struct tvpal_diag *diag);
void tvpal_annot_free(struct tvpal_annot *a);   /* NULL is a no-op */

/* Draws f's annotations into frame (width x height as created, see
 * above).  A legend needs f->colour and vmin < vmax (else TVPAL_E_INVAL,
 * nothing drawn); text that is NULL or "" is left out.  TVPAL_E_SYS with
 * cairo's message when cairo fails. */
int tvpal_annot_draw(struct tvpal_annot *a, const struct tvpal_annot_frame *f,
                     uint8_t *frame, struct tvpal_diag *diag);

/* The window's HUD: nlines lines of text, in fg on a translucent dark
 * box at the top left of frame, under the time's line (same layout as
 * tvpal_annot_draw's frame).  *box (may be NULL) gets the box as x0, y0, w, h with row 0 at
 * the top. */
int tvpal_annot_hud(struct tvpal_annot *a, const char *const *lines,
                    unsigned nlines, const float fg[3], uint8_t *frame,
                    unsigned box[4], struct tvpal_diag *diag);

/* The legend of the last tvpal_annot_draw (shown = 0 before any). */
void tvpal_annot_legend(const struct tvpal_annot *a,
                        struct tvpal_annot_legend *out);

/* Tick values for a legend over [vmin, vmax]: at most max (2..
 * TVPAL_ANNOT_MAX_TICKS) multiples of a round step (1, 2 or 5 times a
 * power of ten) inside the range, about `want` of them; 0 when the range
 * is not finite with vmin < vmax.  Returns the count; *step gets the
 * step.  (No cairo needed: built in both variants.) */
unsigned tvpal_annot_ticks(double vmin, double vmax, unsigned want,
                           unsigned max, double *ticks, double *step);

/* The label of tick value v of a legend whose ticks are step apart, as
 * few digits as tell the ticks apart ("0", "0.05", "1.5e+06"). */
void tvpal_annot_tick_label(double v, double step, char *buf, unsigned cap);

#endif
