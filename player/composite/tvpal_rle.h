/* tvpal_rle.h: run-length coding of premultiplied float RGBA images, the
 * messages of the compositing strategies.  Transparent pixels (alpha 0) are
 * not sent; the others travel as 4 x 16-bit unsigned normalized values
 * (half the bytes of float; a step of 1.5e-5, far below the 8-bit output's
 * 1/255).  Pure functions: no allocation, no communication. */
#ifndef TVPAL_RLE_H
#define TVPAL_RLE_H

#include <stddef.h>
#include <stdint.h>

/* Rows [y0, y1) of an image of `width` premultiplied RGBA floats per row:
 * tvpal_rle_encode writes them to buf, which must hold
 * tvpal_rle_bound(width, y1 - y0) bytes, and returns the bytes written;
 * tvpal_rle_blend blends such an encoding (a message of `bytes` bytes)
 * into the same rows of img, received in front of img (front = 1) or
 * behind it, and adds the number of pixels blended to *blended.  It checks
 * the whole message before it blends: the span count and every span lie
 * within `bytes`, the spans are non-empty, ascending, not overlapping and
 * inside the rows, and their pixels fill the message exactly.  0, or
 * TVPAL_E_FORMAT for a malformed message, which then changes nothing; no
 * byte outside buf[0, bytes) is read and nothing outside the rows is
 * written. */
size_t tvpal_rle_bound(unsigned width, unsigned rows);
size_t tvpal_rle_encode(const float *img, unsigned width, unsigned y0,
                        unsigned y1, unsigned char *buf);
int tvpal_rle_blend(float *img, unsigned width, unsigned y0, unsigned y1,
                    const unsigned char *buf, size_t bytes, int front,
                    uint64_t *blended);

#endif
