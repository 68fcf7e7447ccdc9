/* tvpal_png.c: PNG frames (see tvpal_png.h). */
#define _GNU_SOURCE
#include "tvpal_png.h"
#include "tvpal_fs.h"

#include <errno.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static int write_rgb(const char *path, unsigned width, unsigned height,
                     const uint8_t *rgb8, struct tvpal_diag *diag);

int tvpal_png_write(const char *path, const float *rgba, unsigned width,
                    unsigned height, const float bg[3], uint8_t *rgb8,
                    struct tvpal_diag *diag)
{
    for (unsigned y = 0; y < height; y++) {
        const float *src = rgba + 4 * (size_t)(height - 1 - y) * width;
        uint8_t *dst = rgb8 + 3 * (size_t)y * width;
        for (unsigned x = 0; x < width; x++) {
            float keep = 1.0f - src[4 * x + 3];
            for (int c = 0; c < 3; c++) {
                float v = src[4 * x + c] + keep * bg[c];
                v = v < 0 ? 0 : v > 1 ? 1 : v;
                dst[3 * x + c] = (uint8_t)(v * 255.0f + 0.5f);
            }
        }
    }
    return write_rgb(path, width, height, rgb8, diag);
}

void tvpal_png_rgb8(const uint8_t *rgba8, unsigned width, unsigned height,
                    const float bg[3], uint8_t *rgb8)
{
    for (unsigned y = 0; y < height; y++) {
        const uint8_t *src = rgba8 + 4 * (size_t)(height - 1 - y) * width;
        uint8_t *dst = rgb8 + 3 * (size_t)y * width;
        for (unsigned x = 0; x < width; x++)
            for (int c = 0; c < 3; c++)
                dst[3 * x + c] = tvpal_png_over8(src[4 * x + c],
                                                 src[4 * x + 3], bg[c]);
    }
}

int tvpal_png_write8(const char *path, const uint8_t *rgba8, unsigned width,
                     unsigned height, const float bg[3], uint8_t *rgb8,
                     struct tvpal_diag *diag)
{
    tvpal_png_rgb8(rgba8, width, height, bg, rgb8);
    return write_rgb(path, width, height, rgb8, diag);
}

static int write_rgb(const char *path, unsigned width, unsigned height,
                     const uint8_t *rgb8, struct tvpal_diag *diag)
{
    /* Through tvpal_out like every output: a unique temporary, renamed
     * when complete; a device or link at path is refused. */
    struct tvpal_out o;
    int rc = tvpal_out_open(&o, path, diag);
    if (rc < 0)
        return rc;
    FILE *f = tvpal_out_stream(&o);
    if (!f) {
        tvpal_out_abort(&o);
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "%s: out of memory", path);
    }
    rc = TVPAL_E_WRITE;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL,
                                              NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (png && info && !setjmp(png_jmpbuf(png))) {
        png_init_io(png, f);
        png_set_compression_level(png, 3);
        png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB,
                     PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                     PNG_FILTER_TYPE_DEFAULT);
        png_write_info(png, info);
        for (unsigned y = 0; y < height; y++)
            png_write_row(png, rgb8 + 3 * (size_t)y * width);
        png_write_end(png, NULL);
        rc = 0;
    }
    /* libpng reports a failed fwrite through its error jump; errno still
     * holds the cause. */
    int werr = rc < 0 ? errno : 0;
    png_destroy_write_struct(&png, &info);
    if (rc < 0) {
        tvpal_out_abort(&o);
        return tvpal_diag_set(diag, rc, "%s: %s", path,
                              werr ? strerror(werr) : "PNG encoding failed");
    }
    return tvpal_out_commit(&o, diag);
}

int tvpal_png_read(const char *path, uint8_t **out, unsigned *width,
                   unsigned *height)
{
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path))
        return TVPAL_E_OPEN;
    img.format = PNG_FORMAT_RGB;
    uint8_t *buf = malloc(PNG_IMAGE_SIZE(img));
    if (!buf) {
        png_image_free(&img);
        return TVPAL_E_NOMEM;
    }
    if (!png_image_finish_read(&img, NULL, buf, 0, NULL)) {
        free(buf);
        return TVPAL_E_FORMAT;
    }
    *out = buf;
    *width = img.width;
    *height = img.height;
    return 0;
}
