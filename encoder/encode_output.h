/* encode_output.h: what tvpal-encode writes, and the lines it reports as
 * it goes.
 *
 * The node directories and shard files of a run, the manifest (its text
 * from the run's job and statistics), the rename into place, and the
 * warnings and progress lines the statistics and the work give.  Above
 * encode_say.h and the run's types (encode.h); below the input, levels
 * and cluster modules and the program, which all use it.
 * Program code: reports and ends the program itself (encode_say.h).
 */
#ifndef TVPAL_ENCODE_OUTPUT_H
#define TVPAL_ENCODE_OUTPUT_H

#include "encode.h"

/* The engine's view of the job (tvpal_engine.h) and how its source came
 * (for the manifest). */
struct tvpal_engine_params run_engine_params(const struct run *r);
struct tvpal_engine_source run_engine_source(const struct run *r);

/* Node k's directory while the job runs, and shard j's file in it
 * (malloc'ed; NULL when out of memory). */
char *node_partial(const struct run *r, uint32_t k);
char *shard_path(const struct run *r, const struct tvpal_engine_shard *j);

/* The physical grid of level 0 (options, else the input's, else unit). */
void grid_of(const struct run *r, double spacing[3], double origin[3]);

/* Finishes this process's shards with the source's range. */
void finish_shards(struct run *r);
/* The manifest's text (malloc'ed), and it written as DIR/manifest.txt. */
char *manifest_text(const struct run *r);
void write_manifest(const char *dir, const char *text);
/* OUTDIR.partial renamed to OUTDIR (an older one replaced with --force):
 * 0, or -1 with what went wrong in err. */
int place_output(const struct run *r, char *err, size_t cap);

/* 1 when every value is missing (why says so), and the warnings the
 * statistics give. */
int all_missing(const struct run *r, char *why, size_t cap);
uint64_t dropped_values(const struct run *r);
void warn_dropped(uint64_t dropped);
void warn_dominating_values(const struct run *r);
/* The warning of a few values far from all the others (a fill value such
 * as 1e35 left in the data) that set the value range, so that the
 * quantizers and the default transfer function spend it on them and the
 * report's PSNR, relative to that range, looks excellent: when a value is
 * beyond +-1e30 (huge of them) or the range is more than 1000 times the
 * 0.1..99.9 percentile range [plo, phi] (far of the total values lie
 * outside it; tvpal_values_spread). */
void warn_spread(double vmin, double vmax, double plo, double phi,
                 uint64_t huge, uint64_t far, uint64_t total);

/* A progress line when one is due (every 30 s, 0.2 s on a terminal), or
 * the closing one when `last`; from thread 0 only. */
void report_progress(struct run *r, int last);
/* report_progress(run, 0) as a callback (the engine's and the reader's
 * ticks). */
void tick_progress(void *run);

/* Frees the ring's boxes (the program frees the rest). */
void release_ring(struct run *r);

#endif
