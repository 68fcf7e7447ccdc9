/* tvpal_composite.h: sort-last compositing of the ranks' partial images
 * (paper section IV.B; binary swap after Ma et al., SC'94, and IceT's
 * src/strategies/bswap.c).
 *
 * Each rank renders its slab into a width x height premultiplied RGBA float
 * image.  Slabs are contiguous along the view axis and owned in rank order,
 * so depth order is rank order (reverse = 0: rank 0 in front) or its
 * reverse.  Strategies, behind one call:
 *   - binary swap (default): log2 P rounds in which partners exchange half
 *     of their current region and "over" it in depth order; a rank count K
 *     that is not a power of two is first folded: ranks adjacent in depth
 *     pair up and one sends its whole image to the other, leaving P = 2^k;
 *   - gather to root: every rank sends its whole image to rank 0, which
 *     blends them in depth order (the baseline).
 * Only the active part travels: a sent region is run-length encoded (runs
 * of fully transparent pixels are skipped) as 16-bit RGBA and blended (in
 * float) only where the sender has data (Strengert et al. 2004, section 4).  The composited
 * pieces are gathered on rank 0 (gatherv) as 8-bit RGBA: blending is over
 * by then, and the frame is written at 8 bits anyway.
 */
#ifndef TVPAL_COMPOSITE_H
#define TVPAL_COMPOSITE_H

#include <stdint.h>

#include "tvpal_comm.h"
#include "tvpal_error.h"

enum tvpal_compose_kind { TVPAL_COMPOSE_BSWAP, TVPAL_COMPOSE_GATHER };

struct tvpal_compose_stats {
    double encode_ms, exchange_ms, blend_ms, gather_ms;
    uint64_t bytes_sent;        /* compositing messages of this rank */
    uint64_t gather_bytes;      /* its share of the final gather */
    uint64_t pixels_blended;
};

struct tvpal_compositor;

/* Scratch for images of width x height on a communicator of `size`. */
int tvpal_compositor_create(struct tvpal_compositor **out, unsigned width,
                            unsigned height, int size);
void tvpal_compositor_free(struct tvpal_compositor *cx);

/* Composites img (this rank's image; used as work space, clobbered) over
 * all ranks; on rank 0 the result goes to out8: width * height
 * premultiplied RGBA bytes, row 0 at the bottom, v = round(x * 255) as the
 * PNG writer rounds.  Collective: every rank calls it. */
int tvpal_composite(struct tvpal_compositor *cx, struct tvpal_comm *c,
                    enum tvpal_compose_kind kind, int reverse, float *img,
                    uint8_t *out8, struct tvpal_compose_stats *st);

#endif
