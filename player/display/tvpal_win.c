/* tvpal_win.c: GLFW window (see tvpal_win.h). */
#define GL_GLEXT_PROTOTYPES 1
#define GLFW_INCLUDE_NONE
#include "tvpal_win.h"

#include <GL/gl.h>
#include <GL/glext.h>
#include <GLFW/glfw3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct tvpal_win {
    GLFWwindow *win;
    GLuint show_tex, show_fbo;   /* tvpal_win_show */
    unsigned show_w, show_h;
    unsigned width, height;      /* image area */
    struct tvpal_input *in;      /* during poll */
    int button;                  /* 0 none, 1 on image, 2 on slider */
    double lx, ly;
};

static char glfw_err[200];

static void on_error(int code, const char *msg)
{
    snprintf(glfw_err, sizeof glfw_err, "%s (GLFW error 0x%x)", msg, code);
}

static void push_key(struct tvpal_input *in, int k)
{
    if (in && in->nkeys < 16)
        in->keys[in->nkeys++] = k;
}

static void on_key(GLFWwindow *gw, int key, int sc, int action, int mods)
{
    struct tvpal_win *w = glfwGetWindowUserPointer(gw);
    if (action == GLFW_RELEASE || !w->in)
        return;
    w->in->mods_shift = (mods & GLFW_MOD_SHIFT) != 0;
    switch (key) {
    case GLFW_KEY_SPACE: push_key(w->in, TVPAL_KEY_PLAY); break;
    case GLFW_KEY_RIGHT: case GLFW_KEY_PERIOD: push_key(w->in, TVPAL_KEY_NEXT); break;
    case GLFW_KEY_LEFT: case GLFW_KEY_COMMA: push_key(w->in, TVPAL_KEY_PREV); break;
    case GLFW_KEY_HOME: push_key(w->in, TVPAL_KEY_FIRST); break;
    case GLFW_KEY_END: push_key(w->in, TVPAL_KEY_LAST); break;
    case GLFW_KEY_B: push_key(w->in, TVPAL_KEY_REVERSE); break;
    case GLFW_KEY_T: push_key(w->in, TVPAL_KEY_TF_NEXT); break;
    case GLFW_KEY_R: push_key(w->in, TVPAL_KEY_TF_RELOAD); break;
    case GLFW_KEY_UP: push_key(w->in, TVPAL_KEY_OPACITY_UP); break;
    case GLFW_KEY_DOWN: push_key(w->in, TVPAL_KEY_OPACITY_DOWN); break;
    case GLFW_KEY_M: push_key(w->in, TVPAL_KEY_MODE); break;
    case GLFW_KEY_EQUAL: case GLFW_KEY_KP_ADD: push_key(w->in, TVPAL_KEY_ZOOM_IN); break;
    case GLFW_KEY_MINUS: case GLFW_KEY_KP_SUBTRACT: push_key(w->in, TVPAL_KEY_ZOOM_OUT); break;
    case GLFW_KEY_S: push_key(w->in, TVPAL_KEY_SHOT); break;
    case GLFW_KEY_H: push_key(w->in, TVPAL_KEY_HUD); break;
    case GLFW_KEY_Q: case GLFW_KEY_ESCAPE: push_key(w->in, TVPAL_KEY_QUIT); break;
    case GLFW_KEY_RIGHT_BRACKET: push_key(w->in, TVPAL_KEY_SCALE_Z_UP); break;
    case GLFW_KEY_LEFT_BRACKET: push_key(w->in, TVPAL_KEY_SCALE_Z_DOWN); break;
    case GLFW_KEY_1: case GLFW_KEY_2: case GLFW_KEY_3: case GLFW_KEY_4:
    case GLFW_KEY_5: case GLFW_KEY_6:
        push_key(w->in, TVPAL_KEY_VIEW + (key - GLFW_KEY_1));
        break;
    case GLFW_KEY_0: push_key(w->in, TVPAL_KEY_VIEW + 6); break;
    default: break;
    }
}

static double slider_pos(const struct tvpal_win *w, double x)
{
    double p = (x - 8.0) / ((double)w->width - 16.0);
    return p < 0 ? 0 : p > 1 ? 1 : p;
}

static void on_button(GLFWwindow *gw, int button, int action, int mods)
{
    struct tvpal_win *w = glfwGetWindowUserPointer(gw);
    if (button != GLFW_MOUSE_BUTTON_LEFT)
        return;
    double x, y;
    glfwGetCursorPos(gw, &x, &y);
    if (action == GLFW_PRESS) {
        /* Window y grows downward; the slider is the bottom strip. */
        w->button = y >= (double)w->height ? 2 : 1;
        w->lx = x;
        w->ly = y;
        if (w->button == 2 && w->in) {
            w->in->scrubbing = 1;
            w->in->scrub_pos = slider_pos(w, x);
        }
    } else {
        w->button = 0;
    }
}

static void on_cursor(GLFWwindow *gw, double x, double y)
{
    struct tvpal_win *w = glfwGetWindowUserPointer(gw);
    if (!w->in)
        return;
    if (w->button == 1) {
        w->in->drag_dx += x - w->lx;
        w->in->drag_dy += y - w->ly;
        w->in->dragging = 1;
    } else if (w->button == 2) {
        w->in->scrubbing = 1;
        w->in->scrub_pos = slider_pos(w, x);
    }
    w->lx = x;
    w->ly = y;
}

static void on_scroll(GLFWwindow *gw, double dx, double dy)
{
    struct tvpal_win *w = glfwGetWindowUserPointer(gw);
    if (w->in)
        w->in->scroll += dy;
}

static void on_resize(GLFWwindow *gw, int fw, int fh)
{
    struct tvpal_win *w = glfwGetWindowUserPointer(gw);
    if (fw < 16 || fh < TVPAL_SLIDER_HEIGHT + 16)
        return;
    w->width = (unsigned)fw;
    w->height = (unsigned)(fh - TVPAL_SLIDER_HEIGHT);
    if (w->in) {
        w->in->resized = 1;
        w->in->width = w->width;
        w->in->height = w->height;
    }
}

int tvpal_win_open(struct tvpal_win **out, unsigned width, unsigned height,
                   const char *title, struct tvpal_diag *diag)
{
    glfwSetErrorCallback(on_error);
    if (!glfwInit())
        return tvpal_diag_set(diag, TVPAL_E_SYS, "cannot open a window: %s",
                              glfw_err[0] ? glfw_err : "GLFW init failed");
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_DOUBLEBUFFER, GLFW_TRUE);
    struct tvpal_win *w = calloc(1, sizeof *w);
    if (!w) {
        glfwTerminate();
        return TVPAL_E_NOMEM;
    }
    w->win = glfwCreateWindow((int)width, (int)(height + TVPAL_SLIDER_HEIGHT),
                              title, NULL, NULL);
    if (!w->win) {
        free(w);
        glfwTerminate();
        return tvpal_diag_set(diag, TVPAL_E_SYS,
                              "cannot create a %ux%u window with OpenGL 3.3 "
                              "core: %s", width, height + TVPAL_SLIDER_HEIGHT,
                              glfw_err[0] ? glfw_err : "unknown reason");
    }
    glfwMakeContextCurrent(w->win);
    glfwSwapInterval(0);
    glfwSetWindowUserPointer(w->win, w);
    glfwSetKeyCallback(w->win, on_key);
    glfwSetMouseButtonCallback(w->win, on_button);
    glfwSetCursorPosCallback(w->win, on_cursor);
    glfwSetScrollCallback(w->win, on_scroll);
    glfwSetFramebufferSizeCallback(w->win, on_resize);
    int fw, fh;
    glfwGetFramebufferSize(w->win, &fw, &fh);
    w->width = (unsigned)fw;
    w->height = fh > TVPAL_SLIDER_HEIGHT ? (unsigned)(fh - TVPAL_SLIDER_HEIGHT) : 1;
    *out = w;
    return 0;
}

void tvpal_win_close(struct tvpal_win *w)
{
    if (!w)
        return;
    if (w->show_tex) {
        glDeleteTextures(1, &w->show_tex);
        glDeleteFramebuffers(1, &w->show_fbo);
    }
    glfwDestroyWindow(w->win);
    free(w);
    glfwTerminate();
}

int tvpal_win_should_close(const struct tvpal_win *w)
{
    return glfwWindowShouldClose(w->win);
}

void tvpal_win_poll(struct tvpal_win *w, int wait, struct tvpal_input *in)
{
    memset(in, 0, sizeof *in);
    in->width = w->width;
    in->height = w->height;
    w->in = in;
    if (wait)
        glfwWaitEventsTimeout(0.1);
    else
        glfwPollEvents();
    if (w->button == 1)
        in->dragging = 1;
    if (w->button == 2)
        in->scrubbing = 1;
    w->in = NULL;
}

/* Filled rectangle by a scissored clear (no extra shader needed). */
static void rect(int x, int y, int ww, int hh, float r, float g, float b)
{
    glScissor(x, y, ww, hh);
    glClearColor(r, g, b, 1);
    glClear(GL_COLOR_BUFFER_BIT);
}

void tvpal_win_present(struct tvpal_win *w, double pos)
{
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glEnable(GL_SCISSOR_TEST);
    const int W = (int)w->width;
    rect(0, 0, W, TVPAL_SLIDER_HEIGHT, 0.12f, 0.12f, 0.12f);
    rect(8, TVPAL_SLIDER_HEIGHT / 2 - 2, W - 16, 4, 0.35f, 0.35f, 0.35f);
    int x = 8 + (int)(pos * (W - 16));
    rect(x - 3, 3, 7, TVPAL_SLIDER_HEIGHT - 6, 0.95f, 0.85f, 0.3f);
    glDisable(GL_SCISSOR_TEST);
    glfwSwapBuffers(w->win);
}

void tvpal_win_show(struct tvpal_win *w, const uint8_t *rgba8,
                    unsigned width, unsigned height)
{
    /* Unit 7: the renderer's textures live on units 0 and 1. */
    glActiveTexture(GL_TEXTURE7);
    if (!w->show_tex || w->show_w != width || w->show_h != height) {
        if (!w->show_tex) {
            glGenTextures(1, &w->show_tex);
            glGenFramebuffers(1, &w->show_fbo);
        }
        glBindTexture(GL_TEXTURE_2D, w->show_tex);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, (GLsizei)width,
                     (GLsizei)height, 0, GL_RGBA, GL_UNSIGNED_BYTE, NULL);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        glBindFramebuffer(GL_READ_FRAMEBUFFER, w->show_fbo);
        glFramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0,
                               GL_TEXTURE_2D, w->show_tex, 0);
        w->show_w = width;
        w->show_h = height;
    }
    glBindTexture(GL_TEXTURE_2D, w->show_tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, (GLsizei)width, (GLsizei)height,
                    GL_RGBA, GL_UNSIGNED_BYTE, rgba8);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, w->show_fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    glBlitFramebuffer(0, 0, (GLint)width, (GLint)height, 0,
                      TVPAL_SLIDER_HEIGHT, (GLint)width,
                      TVPAL_SLIDER_HEIGHT + (GLint)height,
                      GL_COLOR_BUFFER_BIT, GL_NEAREST);
}

void tvpal_win_title(struct tvpal_win *w, const char *title)
{
    glfwSetWindowTitle(w->win, title);
}

void tvpal_win_read(struct tvpal_win *w, uint8_t *rgb)
{
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    glReadBuffer(GL_BACK);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    for (unsigned y = 0; y < w->height; y++)
        glReadPixels(0, (GLint)(TVPAL_SLIDER_HEIGHT + w->height - 1 - y),
                     (GLsizei)w->width, 1, GL_RGB, GL_UNSIGNED_BYTE,
                     rgb + 3 * (size_t)y * w->width);
}
