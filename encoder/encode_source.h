/* encode_source.h: tvpal-encode's input (encode_source.c): the files in
 * order, the checks made before any work, the times and units they
 * carry, and the input as libtvpal's source (raw files read with pread,
 * self-describing readers, tvpal_input.h).  Above encode_output.h;
 * program code.
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
/* r's input as libtvpal's source (tvpal.h): raw files read concurrently
 * with pread, or a self-describing reader (host float32) read a box at a
 * time; its ctx is r, its identity and progress the caller's to set.  A
 * failed open or read is TVPAL_E_OPEN or TVPAL_E_READ ("... (rerun to
 * resume)"), a file that shrank or a reader's failure TVPAL_E_FORMAT. */
struct tvpal_source encode_source_of(struct run *r);
/* Closes the files the source keeps open (NULL-safe: none). */
void encode_source_close(struct run *r);

#endif
