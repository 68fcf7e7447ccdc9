/* tvpal_engine.h: the encoding engine, from timesteps in memory to chunks
 * written in place in their shards.
 *
 * The engine holds the shards of a job (an axis-major list: the axes
 * encoded x the node shards this process writes), a ring of `window`
 * boxes of steps (step t in tvpal_engine_slot(e, t)) and the per-thread
 * workspaces of the slice-window coder.  The caller fills the ring with
 * converted steps (tvpal_values.h) and asks for step t to be encoded once
 * steps t .. t + N - 1 (or the last) are in: every slice-window that starts
 * at t (common/format/tvpal_schedule.h) is coded on the caller's pool and
 * its chunk written at its place in its shard (tvpal_shard.h, placed
 * writing), then the chunks' CRCs join their records in slice order.
 *
 * A job too big for memory is encoded in passes over boxes of the volume
 * (encode_plan.h): the caller sets the pass before its steps, and the
 * ring holds that pass's box.  The shard writers are the caller's to
 * create, resume and finish (it knows the paths and the checkpoint); the
 * engine only writes chunks through them.
 *
 * Library code: error convention of tvpal_error.h; nothing here prints or
 * exits.  Not thread-safe: one caller thread drives an engine.
 */
#ifndef TVPAL_ENGINE_H
#define TVPAL_ENGINE_H

#include "encode_plan.h"
#include "tvpal_error.h"
#include "tvpal_pool.h"
#include "tvpal_raw.h"
#include "tvpal_shard.h"

#include <stddef.h>
#include <stdint.h>

/* The most Lloyd-Max refinement passes (the codec's TVPAL_REFINE_MAX;
 * tvpal_engine.c checks that they agree). */
#define TVPAL_ENGINE_REFINE_MAX 64

/* What a job encodes. */
struct tvpal_engine_params {
    uint32_t dims[3];
    uint32_t steps, window;        /* T >= 1, N in 1..TVPAL_WINDOW_MAX */
    uint32_t axes;                 /* TVPAL_AXIS_BIT mask, 1..7 */
    uint32_t nodes;                /* K node shards per axis */
    uint32_t node_first, node_count; /* those this engine writes */
    uint32_t table_format;         /* TVPAL_TABLE_F32, _U16 or _CHUNK */
    uint32_t refine;               /* Lloyd-Max refinement passes, at
                                    * most TVPAL_ENGINE_REFINE_MAX */
    int naive, klt, alloc_mse;     /* coder choices (tvpal_swcode.h) */
    /* Coded chunks (FORMAT.md 6.11): index_level 0 stores every chunk
     * plain; 1..19 codes each chunk with zstd at that level where that
     * makes it smaller (tvpal_chunkz_code). */
    int index_level;
    uint32_t schedule;             /* TVPAL_SCHEDULE_* (FORMAT.md 5) */
    /* Palette groups (FORMAT.md 5.1): 0 or 1 none (the paper's table per
     * slice-window); G >= 2 the slices gG .. gG + G - 1 of an axis share
     * one table per window (fewer where the axis has fewer slices, or G
     * slices would exceed TVPAL_GROUP_VOXELS_MAX voxels:
     * tvpal_engine_group). */
    uint32_t group;
    /* Per axis, where nonzero, G in place of `group` (so capped too):
     * the sizes --group auto measured (tvpal_groupauto.h), which the
     * options line then calls `--group auto` (group_auto). */
    uint32_t group_axis[3];
    int group_auto;
};

/* The largest G --group auto tries (tvpal_groupauto.h). */
#define TVPAL_ENGINE_GROUP_AUTO_MAX 16u

/* 1 while --group auto has not yet set the groups it measured. */
static inline int tvpal_engine_groups_unmeasured(
    const struct tvpal_engine_params *p)
{
    return p->group_auto && !p->group_axis[0] && !p->group_axis[1] &&
           !p->group_axis[2];
}

/* The palette group size of axis a for p: 1 (none) or 2 .. G, G its
 * group_axis[a] where set, else p->group; with group_auto before the
 * measure has set group_axis, the largest it may choose (so that a plan
 * made before it holds whatever it chooses). */
uint32_t tvpal_engine_group(const struct tvpal_engine_params *p,
                            unsigned a);

/* The schedule of p's series, and its longest window: the steps the ring
 * holds (tvpal_engine_slot) and a step is encoded after. */
static inline struct tvpal_schedule
tvpal_engine_schedule(const struct tvpal_engine_params *p)
{
    return tvpal_schedule_of(p->window, p->steps, p->schedule, 1);
}
static inline uint32_t tvpal_engine_span(const struct tvpal_engine_params *p)
{
    const struct tvpal_schedule sc = tvpal_engine_schedule(p);
    return tvpal_schedule_max_len(&sc);
}

/* One shard of the job: its header, set by tvpal_engine_create, and its
 * writer, the caller's (NULL until it opens one). */
struct tvpal_engine_shard {
    unsigned axis;
    uint32_t rank;
    struct tvpal_shard_header h;
    struct tvpal_shardw *w;
};

struct tvpal_engine;

/* Makes the shard headers of p (steps, window, slabs) and works out the
 * sizes the workspaces will have.  0, TVPAL_E_INVAL (p out of range) or
 * TVPAL_E_NOMEM.  Free with tvpal_engine_free. */
int tvpal_engine_create(struct tvpal_engine **out,
                        const struct tvpal_engine_params *p);

/* Frees the engine, its workspaces and ring, and any writer still in its
 * shards (tvpal_shardw_free: an unfinished shard stays as it is on disk).
 * NULL is a no-op. */
void tvpal_engine_free(struct tvpal_engine *e);

/* The shards, axis-major (n of them); the caller sets and clears their
 * writers. */
struct tvpal_engine_shard *tvpal_engine_shards(struct tvpal_engine *e,
                                               uint32_t *n);

/* Bytes of one worker thread's workspace once started (the coder's
 * largest, with missing values, refinement or KLT; samples; tables; a
 * chunk), and of the largest chunk; for memory plans. */
uint64_t tvpal_engine_thread_bytes(const struct tvpal_engine *e);
uint64_t tvpal_engine_max_chunk(const struct tvpal_engine *e);
/* Bytes of the job lists and the shards' record tables. */
uint64_t tvpal_engine_table_bytes(const struct tvpal_engine *e);

/* Allocates the workspaces for every thread of pool (which must outlive
 * the engine's use of it) and a ring of min(N, T) boxes of box_voxels
 * floats.  0; TVPAL_E_NOMEM (diag says of what); TVPAL_E_INVAL when
 * p->klt and the library was built without LAPACK ("no LAPACK"). */
int tvpal_engine_start(struct tvpal_engine *e, struct tvpal_pool *pool,
                       uint64_t box_voxels, struct tvpal_diag *diag);

/* Where step t of the current pass's box goes (box voxels, x fastest):
 * ring slot t mod N.  NULL before tvpal_engine_start or after
 * tvpal_engine_release_ring. */
float *tvpal_engine_slot(struct tvpal_engine *e, uint32_t t);

/* Frees the ring (the caller is done with steps); the rest stays. */
void tvpal_engine_release_ring(struct tvpal_engine *e);

/* The pass whose box the ring holds (the whole volume, every axis, for a
 * job in one pass).  ps must outlive its steps. */
void tvpal_engine_set_pass(struct tvpal_engine *e,
                           const struct encode_pass *ps);

/* While steps are encoded: *work gains the voxel-samples of every coded
 * job (atomically), and tick(ctx) is called by the caller's thread between
 * jobs (a progress line within a long step).  Both optional. */
void tvpal_engine_set_progress(struct tvpal_engine *e, uint64_t *work,
                               void (*tick)(void *ctx), void *ctx);

/* Encodes every slice-window of the pass that starts at step t (steps t ..
 * min(t + N, T) - 1 in the ring) and writes its chunks.  0, or the first
 * write error's code with its detail in diag and the index of the shard it
 * was writing in *fail_shard (optional); the step is then lost, and the
 * shards stay as written. */
int tvpal_engine_encode_step(struct tvpal_engine *e, uint32_t t,
                             struct tvpal_diag *diag, uint32_t *fail_shard);

/* What one slice-window of k slices of the engine's first shard costs as
 * the encoder would store it, for --group auto (tvpal_groupauto.h):
 * samples holds its len steps (len <= the span, k slices each, x fastest,
 * the chunk of k * slice_h rows a palette group stores), coded on thread
 * tid's workspace (the engine started, k * slice_w * slice_h at most its
 * largest group).  *bytes: the stored chunk (coded where that pays);
 * *sse: the squared error of the values present against the decoder table;
 * *present: how many there are.  0, or the coder's error. */
int tvpal_engine_price(struct tvpal_engine *e, unsigned tid,
                       const float *samples, uint32_t k, uint32_t len,
                       uint64_t *bytes, double *sse, uint64_t *present);

/* How the source of a job came, for the manifest's options line. */
struct tvpal_engine_source {
    enum tvpal_type type;          /* as stored by the caller */
    int big_endian;
    uint32_t steps_single;         /* T of one raw file of all steps, or 0 */
    const double *nan_as;          /* or NULL */
    const double *missing;
    unsigned nmissing;
};

/* The manifest's "options" line (FORMAT.md 7): the tvpal-encode options
 * that give the same shards, "--dims NXxNYxNZ --type T --endian E --window
 * N --nodes K" and those that differ from their defaults. */
void tvpal_engine_options_line(const struct tvpal_engine_params *p,
                               const struct tvpal_engine_source *src,
                               char *buf, size_t cap);

/* The manifest's fields that follow from the job (FORMAT.md 7): dims,
 * type, steps, window, nodes, axes, table, the source statistics st (range,
 * replaced and missing values, the histogram), the missing values and
 * --nan-as, the source bytes, times (T values or NULL) and their units, the
 * values' units, the encoder's name and the options line.  *m is set whole
 * (what the caller adds: grid, levels, the sources) and owns its strings;
 * 0 or TVPAL_E_NOMEM (clear m with tvpal_manifest_clear either way). */
struct tvpal_checkpoint_stats;
struct tvpal_manifest;
int tvpal_engine_manifest(const struct tvpal_engine_params *p,
                          const struct tvpal_engine_source *src,
                          const struct tvpal_checkpoint_stats *st,
                          const double *times, const char *time_units,
                          const char *units, const char *encoder,
                          struct tvpal_manifest *m);

/* The shards' progress as a checkpoint keeps it (tvpal_checkpoint.h):
 * progress_alloc sizes pr for the engine's shards and steps (0 or
 * TVPAL_E_NOMEM; free with tvpal_checkpoint_progress_free), progress_get
 * copies every writer's progress into pr, and progress_restore gives shard
 * q's reopened writer (tvpal_shardw_reopen_placed) the progress of pr,
 * reading its bytes back (the codes of tvpal_shardw_set_progress). */
struct tvpal_checkpoint_progress;
int tvpal_engine_progress_alloc(const struct tvpal_engine *e,
                                struct tvpal_checkpoint_progress *pr);
void tvpal_engine_progress_get(const struct tvpal_engine *e,
                               struct tvpal_checkpoint_progress *pr);
int tvpal_engine_progress_restore(struct tvpal_engine *e, uint32_t q,
                                  const struct tvpal_checkpoint_progress *pr,
                                  struct tvpal_diag *diag);

/* Values coded missing that were present in the source (the coder dropped
 * them: a slice whose indices could not hold a missing class), so far. */
uint64_t tvpal_engine_dropped(const struct tvpal_engine *e);

#endif
