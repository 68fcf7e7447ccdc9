/* tvpal_win_none.c: the window front end of a build without GLFW or
 * OSMesa (the window's GL comes through Mesa): the window cannot be
 * opened, and says why; nothing else is reachable. */
#include "tvpal_win.h"

int tvpal_win_open(struct tvpal_win **out, unsigned width, unsigned height,
                   const char *title, struct tvpal_diag *diag)
{
    return tvpal_diag_set(diag, TVPAL_E_SYS,
                          "cannot open a window: built without GLFW or OSMesa "
                          "(install libglfw3-dev and libosmesa6-dev and "
                          "reconfigure), use --headless");
}

void tvpal_win_close(struct tvpal_win *w) {}
int tvpal_win_should_close(const struct tvpal_win *w) { return 1; }
void tvpal_win_poll(struct tvpal_win *w, int wait, struct tvpal_input *in) {}
void tvpal_win_present(struct tvpal_win *w, double pos) {}
void tvpal_win_title(struct tvpal_win *w, const char *title) {}
void tvpal_win_read(struct tvpal_win *w, uint8_t *rgb) {}
void tvpal_win_show(struct tvpal_win *w, const uint8_t *rgba8,
                    unsigned width, unsigned height) {}
