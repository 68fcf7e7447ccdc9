/* tvpal_png.h: writes frames as PNG (libpng; the only file including it). */
#ifndef TVPAL_PNG_H
#define TVPAL_PNG_H

#include <stdint.h>

#include "tvpal_error.h"

/* Writes width x height premultiplied RGBA floats (row 0 at the bottom)
 * composited over an opaque background bg[3] as 8-bit RGB, top row first,
 * atomically (path.tmp, rename).  rgb8 is caller scratch of 3 * width *
 * height bytes (no allocation per frame).  On failure diag (may be NULL)
 * names the file and the cause; no file is left at path.tmp. */
int tvpal_png_write(const char *path, const float *rgba, unsigned width,
                    unsigned height, const float bg[3], uint8_t *rgb8,
                    struct tvpal_diag *diag);

/* One channel c of a premultiplied 8-bit colour of alpha a over an opaque
 * background channel bg (0..1), rounded to 8 bits: how tvpal_png_write8
 * flattens a frame (the window flattens its frames the same way, so that
 * its screenshots equal the headless PNGs). */
static inline uint8_t tvpal_png_over8(uint8_t c, uint8_t a, float bg)
{
    float keep = 1.0f - a * (1.0f / 255.0f);
    float v = c * (1.0f / 255.0f) + keep * bg;
    v = v < 0 ? 0 : v > 1 ? 1 : v;
    return (uint8_t)(v * 255.0f + 0.5f);
}

/* The same from premultiplied 8-bit RGBA (tvpal_composite's output). */
int tvpal_png_write8(const char *path, const uint8_t *rgba8, unsigned width,
                     unsigned height, const float bg[3], uint8_t *rgb8,
                    struct tvpal_diag *diag);

/* The 8-bit RGB rows (top row first) that tvpal_png_write8 writes, into
 * rgb8 (3 * width * height bytes): the frame a movie shows. */
void tvpal_png_rgb8(const uint8_t *rgba8, unsigned width, unsigned height,
                    const float bg[3], uint8_t *rgb8);

/* Reads an 8-bit RGB or RGBA PNG (tests): *out malloc'ed, 3 bytes per
 * pixel, top row first. */
int tvpal_png_read(const char *path, uint8_t **out, unsigned *width,
                   unsigned *height);

#endif
