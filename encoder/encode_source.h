/* encode_source.h: tvpal-encode's input (encode_source.c): the files in
 * order, raw boxes read in blocks and converted into the ring,
 * self-describing readers (tvpal_input.h) with a read-ahead thread, the
 * times and units they carry, and the checks made before any work.
 * Above encode_output.h (its progress lines); program code.
 */
#ifndef TVPAL_ENCODE_SOURCE_H
#define TVPAL_ENCODE_SOURCE_H

#include "encode.h"
#include "tvpal.h"

void order_inputs(struct opts *o);
int open_source(struct run *r, int have_dims);
void load_times(struct run *r);
void warn_irregular_times(const struct run *r);
void check_inputs(struct run *r);
/* The read-ahead thread of r's self-describing input (tvpal_readahead.h)
 * with boxes of `voxels` floats; NULL without threads (steps are then read
 * in place).  Stopped with tvpal_readahead_stop. */
struct tvpal_readahead *prefetch_start(const struct run *r, uint64_t voxels);
/* The current pass's box of step t (r->pass), converted, into dst. */
void load_step(struct run *r, uint32_t t, float *dst);
/* Per-thread findings of a box read for n threads (r->found_local);
 * NULL when out of memory.  Freed with free(). */
struct tvpal_found *encode_found_alloc(size_t n);
/* r's input as libtvpal's source (tvpal.h): raw files read concurrently
 * with pread, or a self-describing reader (host float32) read a box at a
 * time; its ctx is r, its identity and progress the caller's to set.  A
 * failed open or read is TVPAL_E_OPEN or TVPAL_E_READ ("... (rerun to
 * resume)"), a file that shrank or a reader's failure TVPAL_E_FORMAT. */
struct tvpal_source encode_source_of(struct run *r);
/* Closes the files the source keeps open (NULL-safe: none). */
void encode_source_close(struct run *r);

#endif
