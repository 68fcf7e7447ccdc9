/* tvpal_readahead.h: a reader thread that reads the next box of a source
 * while the encoder encodes this one.
 *
 * A source read by a library that is not thread-safe (libnetcdf, HDF5, a
 * caller's reader) is read a box at a time on this one thread, which is
 * then the only one that calls it; the encoding team works meanwhile.
 * The caller takes step t's box (asked for now when it was not read ahead)
 * by swapping its buffer with the reader's, and asks for the next; a long
 * read ticks the caller's progress about once a second while it waits.
 *
 * Library code: error convention of tvpal_error.h; nothing prints.
 */
#ifndef TVPAL_READAHEAD_H
#define TVPAL_READAHEAD_H

#include "encode_plan.h"
#include "tvpal_error.h"

#include <stddef.h>
#include <stdint.h>

/* Reads box b of step t into dst; 0 or a TVPAL_E_* code with d set. */
typedef int (*tvpal_readahead_fn)(void *ctx, uint32_t t,
                                  const struct encode_box *b, void *dst,
                                  struct tvpal_diag *d);

struct tvpal_readahead;

/* Starts the reader of fn(ctx, ...) with a buffer of `bytes`.  NULL when
 * out of memory or threads.  Stop with tvpal_readahead_stop. */
struct tvpal_readahead *tvpal_readahead_start(tvpal_readahead_fn fn,
                                              void *ctx, size_t bytes);

/* Waits for a read in progress, stops the thread and frees the reader.
 * NULL is a no-op. */
void tvpal_readahead_stop(struct tvpal_readahead *ra);

/* Box b of step t: *buf (the caller's buffer of the reader's size) is
 * exchanged for the reader's, which holds it; then box b of step `next` is
 * asked for (-1: none).  tick(tick_ctx) runs about once a second while
 * this waits (may be NULL).  The read's code, with d set on failure. */
int tvpal_readahead_take(struct tvpal_readahead *ra, uint32_t t,
                         int64_t next, const struct encode_box *b,
                         void **buf, void (*tick)(void *), void *tick_ctx,
                         struct tvpal_diag *d);

#endif
