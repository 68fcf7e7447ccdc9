/* tvpal_player.h: the player core shared by every front end: one node's
 * shards of a dataset, the decoding state of each axis, the record stream
 * (in-core or out-of-core), per-frame palettes and the renderer.
 *
 * A frame at timestep t with a view: the axis most orthogonal to the view
 * is chosen; its slabs are brought to t (one record per shard during steady
 * playback, at most N after a jump); for every slice, palette =
 * TF(decoder[t]) with opacity corrected for the view; slices whose palette
 * is fully transparent are skipped; a slice's indices go to the renderer
 * (GL textures, the cpu renderer's tile index sets) only when the slice's
 * window changed since the last upload.  No allocation per frame: scratch
 * is sized when the player is opened.
 */
#ifndef TVPAL_PLAYER_H
#define TVPAL_PLAYER_H

#include <stdint.h>

#include "tvpal_dataset.h"
#include "tvpal_io.h"
#include "tvpal_frame.h"
#include "tvpal_tf.h"

struct tvpal_stream_stats; /* tvpal_stream.h */

/* Ghost rows of cross frames on a cluster node.  A node holds a slab of z
 * slices; a view along x or y cuts every slice across the slab's
 * boundaries, and the samples within half a row of a boundary need the
 * neighbour's boundary row (tvpal_frame.h, draw_begin).  Each such frame,
 * the player hands its own first and last z slice to the exchange (mine)
 * and gets its neighbours' last and first (theirs[0]: the slice below its
 * slab, theirs[1]: above). */
struct tvpal_ghost_row {
    uint32_t slice;       /* z slice; UINT32_MAX: none (no neighbour, or
                             no data yet) */
    uint32_t gen;         /* generation of idx (tvpal_slab_generation) */
    int send_idx;         /* mine: idx changed since it was last sent on
                             this side, so it must go with the row */
    uint8_t *idx;         /* nx * ny indices.  mine: the node's (read);
                             theirs: the player's buffer, which the
                             exchange fills when the neighbour sends them */
    float row[256];       /* decoded values at the frame's step */
};

/* The exchange (the cluster front end's, over its communicator; every
 * node of the job calls it for the same frames).  Fills theirs[i].slice,
 * gen and row, and theirs[i].idx when the neighbour sent its indices;
 * idx_bytes = nx * ny.  0 or a TVPAL_E_* code with diag set. */
typedef int (*tvpal_ghost_fn)(void *ctx, const struct tvpal_ghost_row mine[2],
                              struct tvpal_ghost_row theirs[2],
                              size_t idx_bytes, struct tvpal_diag *diag);

struct tvpal_player_opts {
    int incore;                   /* all records of an axis in RAM */
    enum tvpal_io_kind io;        /* out-of-core backend */
    unsigned prefetch;            /* timesteps read ahead */
    uint64_t read_ahead;          /* bytes of a step's records read at
                                   * once (tvpal_stream_create; 0: its
                                   * default) */
    int direct;                   /* O_DIRECT where possible */
    int io_strict;                /* io == URING: io_uring or fail (no
                                   * fallback to pread) */
    int direct_strict;            /* O_DIRECT refused is an error */
    uint32_t rank, nranks;        /* nranks > 0: open only node `rank`'s
                                     shards, from the directory given to
                                     tvpal_player_open (cluster mode) */
    tvpal_ghost_fn ghosts;        /* nranks > 1: the ghost row exchange of
                                     cross frames (NULL: taps clamp at the
                                     slab boundaries, a seam) */
    void *ghosts_ctx;
    int z_only;                   /* draw every view from the z slices
                                     (cross frames), as for a single-copy
                                     dataset, even where x and y are
                                     stored: for comparisons */
    uint64_t mem_budget;          /* in-core: bytes of records kept in RAM
                                     over all axes (0: no limit); an axis
                                     that does not fit is streamed */
    int keep_around;              /* such an axis keeps the records of the
                                     steps around the playhead within
                                     mem_budget (tvpal_player_keep) */
    uint64_t keep_ahead;          /* streamed: bytes of records kept ahead
                                     of the playhead when asked
                                     (tvpal_player_keep; 0: none) */
};

struct tvpal_frame_stats {
    uint32_t step;
    unsigned axis;
    double io_ms, upload_ms, draw_ms, total_ms, axis_switch_ms;
    double stream_ms;      /* the frame's thread in the stream: waiting for,
                              verifying and applying records (io_ms is
                              the waiting part) */
    uint64_t bytes_read;
    uint32_t drawn, skipped, uploads;
    uint32_t staged;       /* records of the step prepared ahead, off the
                              frame's thread (tvpal_stream.h) */
    double stage_ms;       /* the time the stager took to prepare them */
    uint64_t bytes_needed; /* of bytes_read, the step's own records (the
                              rest is prefetch) */
    unsigned stride;       /* slices drawn: every stride-th */
    int rendered;          /* 1 when the frame was drawn (maybe with stale
                              slices after a load error) */
};

struct tvpal_player;

/* Opens dir; opts as above.  On error diag names the file and problem. */
int tvpal_player_open(struct tvpal_player **out, const char *dir,
                      const struct tvpal_player_opts *opts,
                      struct tvpal_diag *diag);
void tvpal_player_close(struct tvpal_player *p);   /* NULL is a no-op */

const struct tvpal_manifest *tvpal_player_manifest(const struct tvpal_player *p);
const char *tvpal_player_io_name(const struct tvpal_player *p);

/* What the player's streams really do (axes opened so far).  Borrowed
 * strings. */
struct tvpal_io_path {
    const char *io;        /* "uring" or "pread" (the configured one before
                            * any axis is open) */
    const char *direct;    /* O_DIRECT: "yes", "no", or "some" when only
                            * some files took it */
    const char *why;       /* the first fallback, "" when none */
    const char *fixed;     /* record buffers registered with io_uring:
                            * "yes", "no", "some"; "no" in-core (no record
                            * buffers) */
    const char *fixed_why; /* streamed without them: why, or "" */
    uint64_t fixed_reads;  /* reads into registered buffers so far */
    unsigned buffers;      /* streamed record buffers read into so far */
};
void tvpal_player_io_path(const struct tvpal_player *p,
                          struct tvpal_io_path *out);

/* Read submissions (system calls) of the open axes' streams so far. */
uint64_t tvpal_player_io_submits(const struct tvpal_player *p);

/* The directory the player was opened on (node directory in cluster
 * mode). */
const char *tvpal_player_dir(const struct tvpal_player *p);

/* Opens the stream of the data axis of views along axis (0..2) now
 * rather than at the first frame that needs it, so that an I/O path refused (TVPAL_E_SYS: io_uring or
 * O_DIRECT unavailable under io_strict / direct_strict) or a fallback is
 * known before playing.  0 or the error, diag saying why (TVPAL_E_INVAL
 * for an axis the dataset does not store). */
int tvpal_player_open_axis(struct tvpal_player *p, unsigned axis,
                           struct tvpal_diag *diag);

/* The axis whose stored slices draw views along view_axis: view_axis
 * itself, or 2 for a dataset that does not store it (a single-copy
 * dataset: the frame is a cross frame, tvpal_frame.h); -1 when neither is
 * stored (tvpal_player_frame then fails with TVPAL_E_INVAL). */
int tvpal_player_data_axis(const struct tvpal_player *p, unsigned view_axis);

/* The palette group size G of axis a's shards (FORMAT.md 5.1; 1: none),
 * 0 for an axis the dataset does not store. */
uint32_t tvpal_player_group(const struct tvpal_player *p, unsigned a);

/* 1 when this node's slabs lie in depth order from the highest to the
 * lowest slice of the data axis (the order of sort-last compositing):
 * v->descending for the view's own axis, the sign of the view direction's
 * z component for cross frames (z slabs). */
int tvpal_player_slabs_descending(const struct tvpal_player *p,
                                  const struct tvpal_view *v);

/* Transfer function and opacity scale used from the next frame on (no
 * slice is uploaded again for a TF change). */
void tvpal_player_set_tf(struct tvpal_player *p, const struct tvpal_tf *tf,
                         double opacity_scale);

/* Draw every k-th slice only (opacity corrected for the wider spacing):
 * the reduced-quality mode while the user drags or scrubs.  k >= 1. */
void tvpal_player_set_reduce(struct tvpal_player *p, unsigned k);

/* Renders timestep t for view v (v->axis etc. must be set up by
 * tvpal_view_setup) into rgba.  dir steers prefetch (+1/-1).  A record
 * that fails to load is reported through the return code and diag; the
 * frame is still drawn with the last good data of the affected slices.
 * A view whose axis the dataset does not store (tvpal-encode --axes;
 * tvpal_dataset_has_axis) is not drawn: TVPAL_E_INVAL, diag "axis x:
 * dataset stores axes z only". */
int tvpal_player_frame(struct tvpal_player *p, const struct tvpal_view *v,
                       uint32_t t, int dir, struct tvpal_renderer *r,
                       float *rgba, struct tvpal_frame_stats *st,
                       struct tvpal_diag *diag);

/* A jump's target prepared off the caller's thread (tvpal_stream_prepare):
 * the records the data axis of view v needs at step t are read, checked
 * and staged while the caller draws something else (another level's
 * player), and tvpal_player_frame(t) then only installs them; with
 * prefetch the steps after t in direction dir are queued to be read
 * after them, as in steady playback, else nothing beyond t is read.  Returns at
 * once: 0, or TVPAL_E_INVAL (t out of range, an axis not stored, no
 * stager: in-core or prefetch 0) or the axis's open error, diag saying
 * which.  tvpal_player_ready
 * says whether a frame at t would read nothing (1) or still wait for
 * records (0), after waiting at most wait_ms for a prepared step still
 * being read (0: not at all; tvpal_stream_ready).  Not with ghost rows (a
 * cluster's cross frames exchange them at the frame). */
int tvpal_player_prepare(struct tvpal_player *p, const struct tvpal_view *v,
                         uint32_t t, int dir, int prefetch,
                         struct tvpal_diag *diag);
int tvpal_player_ready(struct tvpal_player *p, const struct tvpal_view *v,
                       uint32_t t, double wait_ms);
/* The data axis of view v brought to step t without drawing (a prepared
 * step installed before the frame moves on from it; dir 0 leaves the
 * stager idle for the caller's next tvpal_player_prepare); st (NULL:
 * not wanted) gets what it read, the stager's reads for a prepared step
 * included.  0, or the load's error as tvpal_player_frame's. */
int tvpal_player_seek(struct tvpal_player *p, const struct tvpal_view *v,
                      uint32_t t, int dir, struct tvpal_stream_stats *st,
                      struct tvpal_diag *diag);

/* Out-of-core with keep_around (keep_ahead: t and the steps after it in
 * direction dir): the records of the steps around t that the data axis
 * of view v keeps are read off the caller's thread, so that
 * a later frame at any of them reads nothing (tvpal_stream_keep).  Call
 * after each frame drawn at another player (it returns at once): 1 when
 * the stager was set on it, 0 when not (busy, or nothing to keep), or
 * stream_at's errors (axis, step, open).  tvpal_player_kept: the steps
 * kept on each side of the playhead (0: none, or in-core), and whether
 * step t lies among those last asked for (*near; a frame there reads
 * nothing once they are in). */
int tvpal_player_keep(struct tvpal_player *p, const struct tvpal_view *v,
                      uint32_t t, int dir, struct tvpal_diag *diag);
unsigned tvpal_player_kept(const struct tvpal_player *p,
                           const struct tvpal_view *v, uint32_t t, int *near);
/* Playback goes round the steps first..last (tvpal_stream_loop), on the
 * axes open now and those opened later: the reads ahead go on from the
 * last of them to the first.  0, or TVPAL_E_INVAL (a step out of
 * range). */
int tvpal_player_loop(struct tvpal_player *p, uint32_t first, uint32_t last);

/* The cost so far of the reads and inflating of view v's data axis
 * (tvpal_stream_meter), and the bytes one of its steps takes from
 * scratch, stored and inflated (tvpal_stream_step_bytes): zeros while
 * the axis is not open. */
struct tvpal_stream_meter; /* tvpal_stream.h */
void tvpal_player_meter(const struct tvpal_player *p,
                        const struct tvpal_view *v,
                        struct tvpal_stream_meter *m);
void tvpal_player_step_bytes(const struct tvpal_player *p,
                             const struct tvpal_view *v, uint64_t *stored,
                             uint64_t *plain);

/* 1 while the stager of view v's data axis works (tvpal_stream_busy). */
int tvpal_player_busy(struct tvpal_player *p, const struct tvpal_view *v);

/* Bytes of records one axis holds in RAM in-core (mean over the stored
 * axes) and per timestep: how many timesteps fit in a memory budget. */
uint64_t tvpal_player_axis_bytes(const struct tvpal_player *p);

/* Bytes of records held in RAM now (all axes). */
uint64_t tvpal_player_incore_bytes(const struct tvpal_player *p);

#endif
