/* tvpal_checkpoint.h: the encoder's resume record (common/format/FORMAT.md
 * 9.2).
 *
 * tvpal-encode writes OUTDIR.partial/checkpoint after every timestep: which
 * steps are in every shard, and the source statistics gathered so far (range,
 * replaced values, the fine histogram), which the manifest needs at the end
 * and which a resumed run cannot recompute without reading the steps again.
 * The checkpoint belongs to one job, named by a fingerprint of its options
 * and inputs; a rerun with other options or changed inputs is refused.
 *
 * Error convention of tvpal_error.h: 0 or a negative TVPAL_E_* code, detail
 * in an optional caller-owned diag; nothing here prints or exits.
 */
#ifndef TVPAL_CHECKPOINT_H
#define TVPAL_CHECKPOINT_H

#include <stdint.h>

#include "tvpal_error.h"

/* Classes of the fine source histogram: keyed by the top 16 bits of the
 * float value's order-preserving encoding. */
#define TVPAL_CHECKPOINT_BINS 65536u

/* Statistics of the source timesteps 0 .. loaded-1, in their converted
 * (float) values.  Every voxel of every loaded step is in `fine` exactly
 * once, so the counts sum to loaded * voxels per step. */
struct tvpal_checkpoint_stats {
    double vmin, vmax;       /* range; +inf, -inf while loaded == 0 */
    uint64_t nonfinite;      /* NaN/inf values replaced (--nan-as) */
    uint64_t missing;        /* missing values (not in the histogram) */
    uint64_t *fine;          /* TVPAL_CHECKPOINT_BINS counters, owned */
    uint32_t loaded;         /* timesteps of the current pass accounted */
    uint64_t counted;        /* values accounted: the histogram's sum plus
                              * missing */
};

/* What the shards written so far hold (placed writing, tvpal_shard.h):
 * for each of nshard shards and each of its `steps` records the payload
 * bytes written and their CRC, and whether a chunk had missing entries.
 * Arrays shard-major (shard q, record t at q * steps + t), caller-owned. */
struct tvpal_checkpoint_progress {
    uint32_t nshard, steps;
    uint64_t *filled;
    uint32_t *crc;
    uint8_t *missing;
};

/* Frees pr's arrays and sets them NULL; safe on a zeroed or freed pr. */
void tvpal_checkpoint_progress_free(struct tvpal_checkpoint_progress *pr);

/* Allocates st->fine and sets st empty.  0 or TVPAL_E_NOMEM (then st->fine
 * is NULL).  Release with tvpal_checkpoint_stats_free. */
int tvpal_checkpoint_stats_init(struct tvpal_checkpoint_stats *st);

/* Sets st empty (no step accounted), keeping its array. */
void tvpal_checkpoint_stats_reset(struct tvpal_checkpoint_stats *st);

/* Frees st->fine and sets it NULL; safe on a zeroed or freed st. */
void tvpal_checkpoint_stats_free(struct tvpal_checkpoint_stats *st);

/* Builds the identity of a job: params (the encoding options as text, no
 * newline) followed by " PATH:SIZE:MTIME_SEC.MTIME_NSEC" for each input (an
 * input that cannot be stat'ed counts as size 0, time 0), and with
 * head_bytes > 0 ":CRC" of the CRC-32C of its first head_bytes bytes (a
 * file rewritten within the clock's resolution, to the same size).
 * *out is malloc'ed, freed by the caller.  0 or TVPAL_E_NOMEM. */
int tvpal_checkpoint_fingerprint(const char *params, char *const *inputs,
                                 int ninputs, unsigned head_bytes, char **out);

/* Atomically replaces DIR/checkpoint (via a temporary, tvpal_out) with: the
 * first `done` units of work (pass p, step t counts as p * T + t + 1) are
 * in the shards, statistics st, the shards' progress pr (may be NULL: none
 * kept), job fingerprint.  Only a hash and the length of the fingerprint
 * are stored.  0, TVPAL_E_NOMEM, TVPAL_E_OPEN or TVPAL_E_WRITE, with the
 * cause in diag (optional). */
int tvpal_checkpoint_save(const char *dir, const char *fingerprint,
                          uint64_t done,
                          const struct tvpal_checkpoint_stats *st,
                          const struct tvpal_checkpoint_progress *pr,
                          struct tvpal_diag *diag);

/* Reads DIR/checkpoint of the job `fingerprint` of at most max_done units,
 * with `steps` timesteps of `step_voxels` voxels.  On success sets *done,
 * overwrites st (whose array must be allocated) and, when pr is non-NULL,
 * pr's arrays (sized by pr->nshard and pr->steps; entries not in the
 * checkpoint are 0); the checkpoint is consistent: done <= max_done,
 * loaded <= steps, counted <= steps * step_voxels, the histogram holds
 * counted - missing values and every progress line names a shard and
 * record of pr.  On failure *done is 0 and st is empty, so the caller can
 * start the job over.
 * Returns 0, TVPAL_E_OPEN or TVPAL_E_READ (no readable checkpoint),
 * TVPAL_E_MISMATCH (the checkpoint of another job), TVPAL_E_TRUNC (its last
 * line is incomplete), TVPAL_E_FORMAT (a malformed or inconsistent line,
 * named in diag) or TVPAL_E_NOMEM. */
int tvpal_checkpoint_load(const char *dir, const char *fingerprint,
                          uint64_t max_done, uint32_t steps,
                          uint64_t step_voxels, uint64_t *done,
                          struct tvpal_checkpoint_stats *st,
                          struct tvpal_checkpoint_progress *pr,
                          struct tvpal_diag *diag);

/* Removes DIR/checkpoint and the temporaries of interrupted saves
 * (DIR/checkpoint.*), done when the output is complete.  A missing file is
 * fine.  0, TVPAL_E_NOMEM or TVPAL_E_SYS (diag has the cause). */
int tvpal_checkpoint_remove(const char *dir, struct tvpal_diag *diag);

#endif
