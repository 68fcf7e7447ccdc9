/* tvpal_stream.h: feeds the slabs of one axis with records, in-core or
 * out-of-core (paper III.D, V.A).
 *
 * In-core: every record of the axis is read once (through the I/O backend)
 * and verified; seeking then only copies from RAM.  Out-of-core: records
 * are read on demand into aligned buffers (O_DIRECT where the file system
 * allows it, so the page cache does not hide the disk) with a prefetch
 * queue of several timesteps ahead of the playhead in the play direction;
 * a jump requests all the (at most N) records it needs at once.
 *
 * With prefetch > 0 the work of the next step is done off the caller's
 * thread: after each seek a stager thread reads, verifies and decodes the
 * records of the next step in the play direction into the slabs' staging
 * buffers (tvpal_slab_stage), and the seek to that step only swaps them in
 * (tvpal_slab_install), while the current step is drawn.  A seek that is
 * not to the staged step (a jump, a turn) drops it and works as without
 * a stager.  Images are the same either way.  Not thread-safe otherwise:
 * one thread calls a stream's functions; the slabs may be read between
 * seeks (the stager writes only their staging buffers).
 */
#ifndef TVPAL_STREAM_H
#define TVPAL_STREAM_H

#include <stdint.h>

#include "tvpal_error.h"
#include "tvpal_io.h"
#include "tvpal_shard.h"

struct tvpal_stream_stats {
    uint64_t bytes_read;     /* from disk, this seek (prefetch included) */
    double io_wait_ms;       /* time spent waiting for reads (by the
                                stager, when it prepared the step) */
    unsigned records_applied;
    unsigned records_staged; /* of those, prepared ahead by the stager */
    uint64_t bytes_needed;   /* of bytes_read, the records of the step
                                itself (not its prefetch) */
    double stage_ms;         /* the stager's time preparing the step (its
                                reads, checks and decoding; 0 when the
                                caller's thread read it): with
                                bytes_needed, the rate the disk gave it */
};

struct tvpal_stream;

/* How a stream reads (tvpal_stream_create's policy, bits). */
#define TVPAL_STREAM_DIRECT 1u  /* O_DIRECT where the file system takes it */
#define TVPAL_STREAM_STRICT_IO 2u     /* io_uring asked for but not
                                       * available is an error */
#define TVPAL_STREAM_STRICT_DIRECT 4u /* O_DIRECT refused is an error */
#define TVPAL_STREAM_KEEP_AHEAD 8u    /* keep_bytes: the steps kept lie
                                       * ahead of the playhead only, in the
                                       * keep's direction (a read-ahead for
                                       * a disk slower than playback) */

/* slabs[i] decodes a shard of the axis (borrowed, outlive the stream).
 * The stream owns its I/O backend of the given kind, so reads in flight
 * never cross streams.  Without TVPAL_STREAM_STRICT io_uring falls back to
 * pread and O_DIRECT to the page cache, and tvpal_stream_path says so.
 * incore: load everything now.  prefetch: timesteps read ahead
 * (out-of-core).  read_ahead: bytes of the records one step needs that
 * are read at once (out-of-core): they go in turn, each checked while the
 * next is read, as many together as fit in read_ahead, at least one;
 * TVPAL_STREAM_READ_AHEAD is the player's default.  keep_bytes
 * (out-of-core with prefetch; 0: none): the records of the steps around
 * the playhead, both ways, are kept in record buffers within keep_bytes
 * (tvpal_stream_around says how many steps each way; 0 when not one more
 * fits), filled by tvpal_stream_keep, so that a jump among them reads
 * nothing: a coarse level of detail that does not fit in RAM whole, for
 * jumps near the slider. */
#define TVPAL_STREAM_READ_AHEAD ((uint64_t)32 << 20)
int tvpal_stream_create(struct tvpal_stream **out, struct tvpal_slab **slabs,
                        unsigned nslabs, enum tvpal_io_kind io, int incore,
                        unsigned prefetch, uint64_t read_ahead,
                        uint64_t keep_bytes, unsigned policy,
                        struct tvpal_diag *diag);

/* The steps kept on each side of the playhead (keep_bytes; ahead: on
 * one), 0: none. */
unsigned tvpal_stream_around(const struct tvpal_stream *s);

/* With a neighbourhood: the stager reads and checks, off the caller's
 * thread, the records of the steps within tvpal_stream_around of t (with
 * TVPAL_STREAM_KEEP_AHEAD: t and those after it in direction dir) that
 * are not held yet, nearest first, into buffers not shown or staged,
 * a few records in flight at a time; a later seek to any of those steps
 * reads nothing.  Returns at once: run when the stager is idle, or
 * after the step it stages (which tvpal_stream_ready then reports
 * meanwhile); not while a prepared jump waits to run; cut short by the
 * next seek, prepare or free.  1 when set to run, 0 when not (busy, t's
 * asked for already, or no neighbourhood), or TVPAL_E_INVAL (t out of
 * range). */
int tvpal_stream_keep(struct tvpal_stream *s, uint32_t t, int dir);

/* 1 while the stager works (a step staged, a keep), 0 when idle. */
int tvpal_stream_busy(struct tvpal_stream *s);

/* 1 when step t lies within the neighbourhood the last tvpal_stream_keep
 * asked for (not cut short since): a seek to it reads nothing once that
 * job is done. */
int tvpal_stream_kept(const struct tvpal_stream *s, uint32_t t);

/* What a stream really does: its backend ("uring" or "pread"), on how
 * many of its files O_DIRECT is on, and its first fallback ("" when none;
 * borrowed from the stream). */
struct tvpal_stream_path {
    const char *io;
    unsigned direct_files, files;
    const char *why;
    unsigned fixed;             /* 1: the record buffers go into an io_uring
                                 * fixed-buffer table as they are first
                                 * used, none refused so far */
    uint64_t fixed_reads;       /* reads queued into them so far */
    unsigned buffers;           /* record buffers read into so far (their
                                 * pages are in): out-of-core, about
                                 * N + P + 1 a file in steady playback */
    const char *fixed_why;      /* out-of-core without them (or some of
                                 * them): why, or "" */
};
void tvpal_stream_path(const struct tvpal_stream *s,
                       struct tvpal_stream_path *out);

/* "uring" or "pread": the backend in use. */
const char *tvpal_stream_io_name(const struct tvpal_stream *s);
void tvpal_stream_free(struct tvpal_stream *s);   /* NULL is a no-op */

/* Brings every slab to timestep t; dir (+1 or -1) steers the prefetch
 * and the step the stager prepares next; 0 prepares none (the caller
 * prepares another step: tvpal_stream_prepare), prefetching forward.
 * On a read or checksum error the other records are still applied, the
 * failing slices keep their previous window, and the error (file, record)
 * is returned. */
int tvpal_stream_seek(struct tvpal_stream *s, uint32_t t, int dir,
                      struct tvpal_stream_stats *st, struct tvpal_diag *diag);

/* A jump's target prepared off the caller's thread: the stager reads,
 * checks and stages the records of step t (up to one per window start,
 * from what the slabs show now), as it prepares the next step in steady
 * playback, and returns at once; a job it was running is finished and
 * dropped.  With prefetch, the prefetch beyond t in direction dir is
 * queued after t's reads, as a steady step's is (for frames after t);
 * without, the disk reads nothing beyond t (a still view).  The slabs keep showing their step meanwhile, so the caller may
 * draw another level while this one loads.  A later tvpal_stream_seek(t)
 * only installs the records once tvpal_stream_ready(s, t, 0) says so (it
 * waits for them otherwise); a seek to another step drops them.  0, or
 * TVPAL_E_INVAL (no stager: prefetch 0 or in-core, where a seek reads
 * nothing or must; t out of range). */
int tvpal_stream_prepare(struct tvpal_stream *s, uint32_t t, int dir,
                         int prefetch);

/* 1 when a seek to t neither reads nor waits for the stager: in-core;
 * or, while the stager is idle or only keeping, the slabs show t
 * already, its records are staged, or they are all in record buffers
 * (read ahead, or kept from before; coded ones inflated there).  0 when
 * the seek would read, inflate, or wait for a step the stager is
 * staging or preparing.  With wait_ms > 0
 * a stager job for t still running is waited for, at most wait_ms (a
 * frame's slack before its deadline); 0 never waits. */
int tvpal_stream_ready(struct tvpal_stream *s, uint32_t t, double wait_ms);

/* Submission system calls of the stream's reads so far (io_uring: a seek
 * submits its reads, the records it needs and its prefetch, in one). */
uint64_t tvpal_stream_submits(const struct tvpal_stream *s);

/* Steady playback goes round the steps first..last (either order; both
 * within the series): the step after the last of them is the first, in
 * the play direction, for the prefetch, the step the stager prepares
 * next and the read-ahead (TVPAL_STREAM_KEEP_AHEAD), so that reads never
 * stop at the loop's end, where a frame would otherwise wait for a whole
 * step's records.  None at first: the prefetch stops at the series' ends.
 * Waits for the stager.  0, or TVPAL_E_INVAL (a step out of range). */
int tvpal_stream_loop(struct tvpal_stream *s, uint32_t first, uint32_t last);

/* What the stream's reads and inflating have cost so far, for a planner
 * that must know how long a step's records take to arrive: the disk's
 * side (tvpal_io_busy: bytes completed, seconds with a read at the
 * device) and the CPU's (coded records, out-of-core: plain bytes
 * inflated, seconds of wall time inflating).  A snapshot, safe to take
 * from another thread than the one reading. */
struct tvpal_stream_meter {
    uint64_t read_bytes;
    double read_s;
    uint64_t inflated_bytes;
    double inflate_s;
};
void tvpal_stream_meter(const struct tvpal_stream *s,
                        struct tvpal_stream_meter *m);

/* The bytes one step's records take from scratch (a jump: the record of
 * every window that covers it, over the stream's shards; the mean over
 * the steps), as stored and as inflated (equal where nothing is
 * coded). */
void tvpal_stream_step_bytes(const struct tvpal_stream *s, uint64_t *stored,
                             uint64_t *plain);

/* Bytes held in RAM by an in-core stream (0 out-of-core). */
uint64_t tvpal_stream_incore_bytes(const struct tvpal_stream *s);

#endif
