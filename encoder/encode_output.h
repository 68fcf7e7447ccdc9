/* encode_output.h: what tvpal-encode says of its output as it goes: the
 * grid it records, the warnings the values' statistics give, and the
 * progress lines.  Above encode_say.h and the run's types (encode.h);
 * below the input and cluster modules and the program, which use it.
 * Program code: reports through encode_say.h.
 */
#ifndef TVPAL_ENCODE_OUTPUT_H
#define TVPAL_ENCODE_OUTPUT_H

#include "encode.h"

/* The physical grid of level 0: --spacing and --origin, else the input's,
 * else the unit grid. */
void grid_of(const struct run *r, double spacing[3], double origin[3]);

/* The warning of present values coded as missing (more patterns of
 * missing steps in a slice-window than the code has indices for). */
void warn_dropped(uint64_t dropped);
/* The warning of a few values far from all the others (a fill value such
 * as 1e35 left in the data) that set the value range, so that the
 * quantizers and the default transfer function spend it on them and the
 * report's PSNR, relative to that range, looks excellent: when a value is
 * beyond +-1e30 (huge of them) or the range is more than 1000 times the
 * 0.1..99.9 percentile range [plo, phi] (far of the total values lie
 * outside it; struct tvpal_stats). */
void warn_spread(double vmin, double vmax, double plo, double phi,
                 uint64_t huge, uint64_t far, uint64_t total);

/* A progress line when one is due (every 30 s, 0.2 s on a terminal), or
 * the closing one when `last`, from r->prog. */
void report_progress(struct run *r, int last);

#endif
