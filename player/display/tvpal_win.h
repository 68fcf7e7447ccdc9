/* tvpal_win.h: the GLFW window of the interactive front end (the only
 * file with tvpal_glr.c and tvpal_osmesa.c that includes GL headers).
 * The window shows the rendered image above a time slider. */
#ifndef TVPAL_WIN_H
#define TVPAL_WIN_H

#include <stdint.h>

#include "tvpal_error.h"

#define TVPAL_SLIDER_HEIGHT 20

/* Input gathered since the last poll. */
struct tvpal_input {
    int keys[16];          /* TVPAL_KEY_* pressed (queue) */
    int nkeys;
    int mods_shift;
    double drag_dx, drag_dy;   /* left-drag on the image, pixels */
    int dragging;              /* button held on the image */
    double scroll;             /* wheel steps */
    int scrubbing;             /* button held on the slider */
    double scrub_pos;          /* 0..1 along the slider */
    int resized;               /* new image size in width/height */
    unsigned width, height;    /* image area (window minus the slider) */
};

enum {
    TVPAL_KEY_NONE, TVPAL_KEY_PLAY, TVPAL_KEY_NEXT, TVPAL_KEY_PREV,
    TVPAL_KEY_FIRST, TVPAL_KEY_LAST, TVPAL_KEY_REVERSE, TVPAL_KEY_TF_NEXT,
    TVPAL_KEY_TF_RELOAD, TVPAL_KEY_OPACITY_UP, TVPAL_KEY_OPACITY_DOWN,
    TVPAL_KEY_MODE, TVPAL_KEY_ZOOM_IN, TVPAL_KEY_ZOOM_OUT, TVPAL_KEY_SHOT,
    TVPAL_KEY_QUIT, TVPAL_KEY_SCALE_Z_UP, TVPAL_KEY_SCALE_Z_DOWN,
    TVPAL_KEY_HUD,
    /* Named views: keys 1..6 are TVPAL_KEY_VIEW + 0..5 (+x -x +y -y +z
     * -z, tvpal_view_name's order), key 0 is TVPAL_KEY_VIEW + 6 (iso). */
    TVPAL_KEY_VIEW
};
#define TVPAL_KEY_VIEWS 7

struct tvpal_win;

/* Opens a window with an OpenGL 3.3 core context (made current) whose
 * image area is width x height.  diag says why it failed (no display, no
 * GL 3.3, size). */
int tvpal_win_open(struct tvpal_win **out, unsigned width, unsigned height,
                   const char *title, struct tvpal_diag *diag);
void tvpal_win_close(struct tvpal_win *w);   /* NULL is a no-op */

int tvpal_win_should_close(const struct tvpal_win *w);

/* Processes events (wait: block until one arrives) into in. */
void tvpal_win_poll(struct tvpal_win *w, int wait, struct tvpal_input *in);

/* Draws the slider (position 0..1) and swaps buffers; the image must have
 * been blitted (tvpal_glr_blit at (0, TVPAL_SLIDER_HEIGHT)) before. */
void tvpal_win_present(struct tvpal_win *w, double pos);

void tvpal_win_title(struct tvpal_win *w, const char *title);

/* Shows an image computed elsewhere (the cluster's composited frame):
 * width x height premultiplied 8-bit RGBA, row 0 at the bottom, over
 * black, in the image area.  Call before present. */
void tvpal_win_show(struct tvpal_win *w, const uint8_t *rgba8,
                    unsigned width, unsigned height);

/* Reads the image area of the back buffer as 8-bit RGB, top row first
 * (before present; tests compare it with the headless image). */
void tvpal_win_read(struct tvpal_win *w, uint8_t *rgb);

#endif
