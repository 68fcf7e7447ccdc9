/* tvpal.h: libtvpal, the public API of tvpal.
 *
 * tvpal encodes time-varying volume data with the palette-DCT method of
 * Lum, Ma & Clyne (IEEE TVCG 2002): per axis-aligned slice, windows of N
 * timesteps get a temporal DCT, and each voxel becomes one 8-bit index
 * into a per-slice-window decoder table.  The result is a dataset
 * directory (manifest.txt and node shards, FORMAT.md) that tvpal-play
 * plays and the tvpal tools read.
 *
 * This header offers two objects:
 *  - an encoder, which takes a series of timesteps from the caller's
 *    memory, one at a time, and writes a dataset (for a simulation that
 *    encodes its output while it runs, in situ);
 *  - a reader, which opens a dataset and decodes any stored step into the
 *    caller's memory.
 *
 * Conventions:
 *  - Every fallible function returns int: 0 on success, or a negative
 *    TVPAL_E_* code (tvpal_error.h); tvpal_strerror() names it.  Where a
 *    code alone cannot say what went wrong, a function takes an optional
 *    caller-owned struct tvpal_diag (may be NULL) into which it writes a
 *    sentence naming the file, the parameter or the value at fault.
 *  - The library never prints, never exits and does not report through
 *    errno.
 *  - Objects are created by *_open and released by exactly one of the
 *    calls documented as releasing them; the caller owns what it passes
 *    in, and may reuse its buffers as soon as a call returns.
 *  - Volumes are nx * ny * nz values, x fastest, unless strides say
 *    otherwise.  An object is not thread-safe: one thread drives it (the
 *    encoder uses its own worker threads inside).
 *
 * Build with `pkg-config --cflags --libs tvpal`.
 */
#ifndef TVPAL_H
#define TVPAL_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- version */

#define TVPAL_VERSION_MAJOR 0
#define TVPAL_VERSION_MINOR 4
#define TVPAL_VERSION_RELEASE 0
/* 100 * (100 * MAJOR + MINOR) + RELEASE: 300 for 0.3.0.  History:
 *  0.1.0  the encoder from memory, the reader (open, info, decode);
 *  0.2.0  struct tvpal_info's provenance, source and histogram fields,
 *         tvpal_reader_open_manifest, tvpal_reader_sizes,
 *         tvpal_reader_verify (what tvpal-info and tvpal-report need);
 *  0.3.0  encoding from a source in passes under a memory limit
 *         (tvpal_encoder_plan, tvpal_encoder_encode), integer scalars,
 *         TVPAL_E_CANCELED, tvpal_encoder_set_provenance,
 *         tvpal_encoder_stats, tvpal_encoder_set_shard_dir,
 *         TVPAL_PARAM_PROGRESS (what tvpal-encode needs to drive it). */
#define TVPAL_VERSION_NUMBER                                                  \
    ((TVPAL_VERSION_MAJOR * 100 + TVPAL_VERSION_MINOR) * 100 +               \
     TVPAL_VERSION_RELEASE)

/* The library's TVPAL_VERSION_NUMBER and "MAJOR.MINOR.RELEASE": a program
 * may compare them with the header's it was built against. */
TVPAL_API unsigned tvpal_version_number(void);
TVPAL_API const char *tvpal_version_string(void);

/* ---------------------------------------------------------------- encoder */

/* Axes, as a mask: the slices a dataset stores (tvpal_encoder_set
 * TVPAL_PARAM_AXES).  Z alone is the default: the player draws every view
 * from the z slices. */
#define TVPAL_AXIS_X 1u
#define TVPAL_AXIS_Y 2u
#define TVPAL_AXIS_Z 4u

/* The scalar type of the values pushed or read from a source.  Integers
 * (since 0.3.0) are taken as their values (a uint16 of 1000 is 1000.0). */
enum tvpal_scalar {
    TVPAL_FLOAT32 = 1,
    TVPAL_FLOAT64 = 2,
    TVPAL_UINT8 = 3,
    TVPAL_UINT16 = 4,
    TVPAL_INT16 = 5
};

/* Parameters of an encoder, set with tvpal_encoder_set before the first
 * push; each is the tvpal-encode option of the same name (tvpal-encode(1)
 * says what it does). */
enum tvpal_param {
    TVPAL_PARAM_WINDOW = 1,   /* N, timesteps per DCT window: 1..16;
                               * default 4 */
    TVPAL_PARAM_AXES,         /* mask of TVPAL_AXIS_*; default Z */
    TVPAL_PARAM_NODES,        /* node shards per axis (for a cluster
                               * player), 1..4096; default 1 */
    TVPAL_PARAM_TABLE,        /* decoder tables: TVPAL_TABLE_AUTO (each
                               * chunk 16-bit where that costs less than
                               * 1e-4 of its error; default), _FLOAT32, _UINT16 */
    TVPAL_PARAM_REFINE,       /* Lloyd-Max refinement passes, 0..64;
                               * default 0 (from the DCT code and from
                               * k-means++ seeds: the better after two
                               * passes goes on) */
    TVPAL_PARAM_TRANSFORM,    /* TVPAL_TRANSFORM_DCT (default) or _KLT
                               * (needs a build with LAPACK) */
    TVPAL_PARAM_ALLOC,        /* TVPAL_ALLOC_VARIANCE (default) or
                               * _GREEDY_MSE */
    TVPAL_PARAM_THREADS,      /* worker threads; 0 (default): every CPU
                               * this process may run on */
    TVPAL_PARAM_MEM_LIMIT,    /* bytes the encoder may hold, 0 (default):
                               * no limit of its own.  It holds the
                               * longest window's steps of float32 (2N - 1,
                               * N staggered) and its workspaces; a job
                               * over the limit is refused at the first
                               * push */
    TVPAL_PARAM_NAN_AS,       /* missing values become this value (and
                               * count as replaced) instead of missing */
    TVPAL_PARAM_NAIVE,        /* 1: the paper's naive variant (uniform
                               * quantizers, no bit allocation: a
                               * baseline); default 0 */
    TVPAL_PARAM_FORCE,        /* 1: replace an existing dataset at the
                               * output directory (only a tvpal dataset;
                               * it is replaced when the new one is
                               * complete); default 0 */
    TVPAL_PARAM_CHECKPOINT,   /* a checkpoint (what tvpal_encoder_resume
                               * continues from) after every this many
                               * steps encoded, and after the last; 0:
                               * none; default 1 */
    TVPAL_PARAM_LEVELS,       /* coarser levels of detail, 0..8: level k
                               * the 2x2x2 means of level k - 1, made from
                               * each step as it is pushed and stored in
                               * DIR/level-k (the player answers jumps from
                               * them; the reader decodes them); under a
                               * collective rank 0 encodes every node's
                               * levels and every push is collective (see
                               * there); default 0 */
    TVPAL_PARAM_PROGRESS,     /* seconds, 0.001..3600: the least time
                               * between two calls of an encode's
                               * progress callback within a unit (struct
                               * tvpal_source); default 0.2.  Since
                               * 0.3.0 */
    TVPAL_PARAM_INDEX_CODING, /* TVPAL_CODING_ZSTD (default): each chunk's
                               * table and indices stored as a zstd frame
                               * where that is smaller (a dataset readers
                               * before 0.4.0 refuse); TVPAL_CODING_NONE:
                               * plain, as before 0.4.0.  Since 0.4.0 */
    TVPAL_PARAM_INDEX_LEVEL,  /* the zstd level of TVPAL_CODING_ZSTD,
                               * 1..19; default 3 (higher: smaller, slower
                               * to encode, as fast to read).  Since
                               * 0.4.0 */
    TVPAL_PARAM_SCHEDULE,     /* TVPAL_SCHEDULE_JOINED (default): a
                               * slice's short first window joins the
                               * next (first windows of N..2N - 1 steps),
                               * so the indices cost 8/N bits per
                               * voxel-step at any T >= N; the encoder
                               * holds 2N - 1 steps instead of N, and
                               * readers before 0.4.0 refuse it.
                               * TVPAL_SCHEDULE_STAGGERED: the paper's,
                               * windows of 1..N steps, as before 0.4.0.
                               * Since 0.4.0 */
    TVPAL_PARAM_GROUP         /* palette groups: 1 (default) a decoder
                               * table per slice-window, the paper's; G in
                               * 2..1024 one table per window for the G
                               * slices gG .. gG + G - 1 of an axis (at
                               * most 262144 voxels together: fewer
                               * slices where they are larger), which
                               * share a phase of the schedule.  Fewer
                               * bits (the tables of small slices are
                               * most of them) for some error; readers
                               * before 0.4.0 refuse it.
                               * TVPAL_GROUP_AUTO: each axis' G (1, 2, 4
                               * .. 16) measured on sample windows of the
                               * source before anything is written, the
                               * least error + 2 ln 2 error(1) x bits
                               * (tvpal-encode(1), --group auto); only an
                               * encode from a source (a push is refused:
                               * TVPAL_E_INVAL); the levels take level 0's.
                               * Since 0.4.0 */
};
#define TVPAL_GROUP_AUTO 0
#define TVPAL_SCHEDULE_STAGGERED 0
#define TVPAL_SCHEDULE_JOINED 1
#define TVPAL_CODING_NONE 0
#define TVPAL_CODING_ZSTD 1
#define TVPAL_TABLE_FLOAT32 0
#define TVPAL_TABLE_UINT16 1
#define TVPAL_TABLE_AUTO 4
#define TVPAL_TRANSFORM_DCT 0
#define TVPAL_TRANSFORM_KLT 1
#define TVPAL_ALLOC_VARIANCE 0
#define TVPAL_ALLOC_GREEDY_MSE 1

struct tvpal_encoder;

/* Opens an encoder of `steps` timesteps of dims[0] x dims[1] x dims[2]
 * voxels into the dataset directory `dir`.  Nothing is written until the
 * first push.  0, or TVPAL_E_INVAL (dims, steps or dir out of range; diag
 * says which) or TVPAL_E_NOMEM.  *out is released by tvpal_encoder_finish
 * or tvpal_encoder_abort. */
TVPAL_API int tvpal_encoder_open(struct tvpal_encoder **out, const char *dir,
                                 const uint32_t dims[3], uint32_t steps,
                                 struct tvpal_diag *diag);

/* Sets a parameter (enum tvpal_param) before the first push.  0, or
 * TVPAL_E_INVAL for an unknown parameter, a value out of its range or a
 * call after the first push. */
TVPAL_API int tvpal_encoder_set(struct tvpal_encoder *e,
                                enum tvpal_param param, double value,
                                struct tvpal_diag *diag);

/* The physical grid: the voxels' spacing (each finite and > 0) and the
 * first voxel's centre; default 1, 1, 1 and 0, 0, 0.  Before the first
 * push; 0 or TVPAL_E_INVAL. */
TVPAL_API int tvpal_encoder_set_grid(struct tvpal_encoder *e,
                                     const double spacing[3],
                                     const double origin[3],
                                     struct tvpal_diag *diag);

/* The time of every step (steps values, increasing, finite) and their
 * units (e.g. "hours since 2005-08-28 00:00:00", or NULL).  Copied.
 * Before the first push; 0 or TVPAL_E_INVAL. */
TVPAL_API int tvpal_encoder_set_times(struct tvpal_encoder *e,
                                      const double *times,
                                      const char *time_units,
                                      struct tvpal_diag *diag);

/* The values' units (e.g. "K"), or NULL; copied.  Before the first push. */
TVPAL_API int tvpal_encoder_set_units(struct tvpal_encoder *e,
                                      const char *units,
                                      struct tvpal_diag *diag);

/* Values that mean "no data" (up to 16, beside NaN, which always does);
 * copied.  Before the first push; 0 or TVPAL_E_INVAL. */
TVPAL_API int tvpal_encoder_set_missing(struct tvpal_encoder *e,
                                        const double *values, unsigned n,
                                        struct tvpal_diag *diag);

/* Where the values came from, for the dataset's manifest (FORMAT.md 7),
 * so that a tool can read them again (tvpal-report compares a dataset with
 * its sources, tvpal-info shows them).  Strings are copied, one line
 * each. */
struct tvpal_provenance {
    const char *encoder;      /* the program and its version, e.g.
                               * "mysim 2.1"; NULL: "libtvpal VERSION" */
    const char *format;       /* the sources' format: "raw", "netcdf",
                               * "hdf5", "vti" or "vtk"; NULL: none */
    const char *var;          /* the variable read, or NULL (raw) */
    const char *const *sources;  /* nsources files, in the order of the */
    uint32_t nsources;           /* steps (as given: relative or not) */
    int single_file;          /* 1: one file holds every step */
    int series;               /* 1: files of several steps each (else one
                               * file per step) */
};

/* Records p in the manifest (since 0.3.0).  Before the first push or
 * encode; 0, TVPAL_E_INVAL (an unknown format, a string of several lines,
 * sources that do not fit the steps: one file, one per step, or a series)
 * or TVPAL_E_NOMEM.  A raw source's type and byte order are those pushed
 * or read (struct tvpal_source). */
TVPAL_API int tvpal_encoder_set_provenance(struct tvpal_encoder *e,
                                           const struct tvpal_provenance *p,
                                           struct tvpal_diag *diag);

/* ------------------------------------------------ encoding on many ranks
 *
 * In an MPI program (or any other set of processes), each of `size` ranks
 * holds a slab of the volume decomposed along z and pushes only its slab;
 * each writes its own node shard (DIR.partial/node-RANK, FORMAT.md 3.2),
 * and rank 0 writes the manifest once and moves the dataset into place.
 * The dataset is byte-identical to tvpal-encode --nodes SIZE of the same
 * steps.  DIR must be on a file system every rank sees.  The ranks agree
 * at their first push and in tvpal_encoder_finish through the two
 * operations below, which the caller provides (lib/tvpal_mpi.h gives them
 * for MPI); a failure on any rank fails every rank, with that rank's
 * message, and leaves nothing at DIR.
 *
 * With a collective set, the first push, tvpal_encoder_finish and
 * tvpal_encoder_abort are collective: every rank calls one of the last
 * two at the same point of its program (after its last push, or where
 * every rank gives up).  A rank whose push failed keeps its encoder until
 * then (its later pushes are refused; a simulation goes on feeding its
 * neighbours' halos), and its finish fails every rank's with its message;
 * a rank that aborts early waits for the others' finish.  With
 * TVPAL_PARAM_LEVELS every push is collective too: each step every rank
 * sends rank 0 its slab's part of level 1 (the planes of a 2x2x2 block
 * split between two slabs as they are), and rank 0 makes and encodes
 * every node's levels, so every rank pushes every step (a failed rank's
 * later pushes and an early abort still take part), and every rank must
 * set the same levels (else every rank fails at the first push). */
struct tvpal_collective {
    int rank, size;           /* this process's rank, 0 .. size - 1 */
    void *ctx;                /* the caller's; passed to both */
    /* Every rank sends `bytes` bytes at send; rank 0 receives rank k's at
     * recv + k * bytes (recv is NULL on the other ranks).  0 or nonzero
     * (the encoder then fails with TVPAL_E_SYS). */
    int (*gather)(void *ctx, const void *send, size_t bytes, void *recv);
    /* Rank 0's `bytes` bytes at buf replace every other rank's.  0 or
     * nonzero. */
    int (*bcast)(void *ctx, void *buf, size_t bytes);
    /* Optional (may be NULL): called once with ctx when the encoder no
     * longer needs it, so that the encoder may own ctx. */
    void (*release)(void *ctx);
};

/* Each rank's node directory on a disk of its own (a node-local disk of
 * its machine) instead of DIR/node-RANK: `pattern` with %r replaced by
 * the rank, written as PATTERN.partial and renamed into place when the
 * dataset is complete (an older one replaced under TVPAL_PARAM_FORCE);
 * DIR then holds the manifest and the levels.  tvpal-encode --shard-dir
 * and tvpal-play --shard-dir use the same pattern.  With a collective of
 * several ranks only, before the first push or encode; 0, TVPAL_E_INVAL
 * (no %r, several lines) or TVPAL_E_NOMEM.  Since 0.3.0. */
TVPAL_API int tvpal_encoder_set_shard_dir(struct tvpal_encoder *e,
                                          const char *pattern,
                                          struct tvpal_diag *diag);

/* The z-slab of rank `rank` of `size` for nz planes: planes *z0 .. *z0 +
 * *count - 1 (as equal as possible, the first nz % size one plane
 * larger: the slabs of tvpal-encode --nodes SIZE).  A rank must push
 * exactly this slab. */
TVPAL_API void tvpal_slab(uint32_t nz, uint32_t size, uint32_t rank,
                          uint32_t *z0, uint32_t *count);

/* Makes e one rank of a collective encode (before the first push): this
 * rank pushes planes z0 .. z0 + nz - 1 of each step, which must be
 * tvpal_slab's for its rank, and writes node shard c->rank of c->size
 * (TVPAL_PARAM_NODES becomes c->size).  *c is copied; c->ctx must stay
 * valid until c->release is called (once: when e is released, or before
 * this call returns if it refuses c), or, without release, until e is
 * released.  Ranks that push may encode only TVPAL_AXIS_Z (x and y slices
 * cross the slabs); ranks that encode from a source (tvpal_encoder_encode)
 * any axes.  0 or TVPAL_E_INVAL (diag says what: a size or rank out of
 * range, a missing operation; or a slab that is not the rank's, which the
 * encoder keeps all the same, so that its first push or its abort makes
 * every rank fail rather than wait) or TVPAL_E_NOMEM. */
TVPAL_API int tvpal_encoder_set_collective(struct tvpal_encoder *e,
                                           const struct tvpal_collective *c,
                                           uint32_t z0, uint32_t nz,
                                           struct tvpal_diag *diag);

/* Pushes the next timestep (steps 0, 1, ... in order): count values of
 * `type` at data, which must be dims[0] * dims[1] * dims[2] (with a
 * collective, tvpal_encoder_set_collective: dims[0] * dims[1] * the
 * slab's nz, its z counted from the slab's first plane), where value
 * (x, y, z) is at
 * data[x * strides[0] + y * strides[1] + z * strides[2]] (in elements; may
 * be negative), or with strides NULL at data[x + nx * (y + ny * z)].  The
 * values are copied (converted to float32) before the call returns; NaN and
 * the missing values are missing; an infinity or a value beyond 1e37 is
 * refused (TVPAL_E_NAN, TVPAL_E_RANGE: diag names the voxel; an encode
 * from a source says "step S: an infinite value at voxel (X,Y,Z)" or
 * "step S: a value beyond 1e37 at voxel (X,Y,Z)", which a program may
 * read back to name its file).
 *
 * The first push takes the output's lock (DIR.partial.lock) and creates
 * DIR.partial, where the dataset is written until tvpal_encoder_finish
 * moves it into place.  A push may encode and write the windows that its
 * step completes, on the encoder's threads.
 *
 * 0; TVPAL_E_INVAL (a push after the last step, an unknown type, NULL
 * data, a count that is not the step's); TVPAL_E_EXIST (DIR exists and TVPAL_PARAM_FORCE is not set, or
 * another encoder holds the lock); TVPAL_E_RANGE (the job needs more than
 * TVPAL_PARAM_MEM_LIMIT); TVPAL_E_NAN, TVPAL_E_RANGE (a value refused);
 * TVPAL_E_OPEN, TVPAL_E_WRITE, TVPAL_E_SYS (the output: diag names the
 * file); TVPAL_E_NOMEM.  A push refused for its arguments (TVPAL_E_INVAL)
 * changes nothing; after any other failure the encoder only accepts
 * tvpal_encoder_abort (and tvpal_encoder_finish, which then fails). */
TVPAL_API int tvpal_encoder_push(struct tvpal_encoder *e, const void *data,
                                 enum tvpal_scalar type, size_t count,
                                 const ptrdiff_t strides[3],
                                 struct tvpal_diag *diag);

/* Continues a job that was interrupted (the process killed, the machine
 * down) instead of starting it over: call it on an encoder opened and set
 * as the interrupted one was (the same dims, steps, parameters, slab and
 * collective; the grid, times and units may be set anew), before any
 * push, with the type its pushes have.  Where DIR.partial holds a
 * checkpoint of this job (TVPAL_PARAM_CHECKPOINT), its shards are kept
 * and *next_step is the first step to push (the steps before it are
 * encoded and counted); the caller pushes steps *next_step, ... T - 1 and
 * finishes, and the dataset is byte-identical to one encoded without the
 * interruption.  They must be the interrupted job's steps: a checkpoint
 * knows the job's parameters, not the values it was given.  Without one, *next_step is 0 and the job starts over, as
 * a first push would.  With a collective it is collective: each rank
 * continues from its own checkpoint (a kill stops ranks at different
 * steps), *next_step is the earliest of them on every rank, and a rank
 * passes over the pushes of steps its checkpoint already has (a rank
 * without one starts its shard over; the others keep theirs).  Takes the
 * lock and does what a first push does before its step.  0, or the codes
 * of a first push (TVPAL_E_EXIST, ...); a checkpoint whose shard files do
 * not match it (changed since) gives TVPAL_E_CHECKSUM, TVPAL_E_TRUNC or
 * TVPAL_E_MISMATCH naming the file: abort, and encode again from step 0. */
TVPAL_API int tvpal_encoder_resume(struct tvpal_encoder *e,
                                   enum tvpal_scalar type,
                                   uint32_t *next_step,
                                   struct tvpal_diag *diag);

/* After the last step: encodes what is left, finishes the shards, writes
 * the manifest, reads the dataset back to verify it and renames DIR.partial
 * to DIR (replacing an older DIR with TVPAL_PARAM_FORCE).  Releases e,
 * whatever the result; on failure nothing at DIR looks complete (an older
 * dataset there stays as it was).  0; TVPAL_E_INVAL (fewer steps pushed
 * than opened with, or every value missing: the partial output is
 * removed); the codes of tvpal_encoder_push. */
TVPAL_API int tvpal_encoder_finish(struct tvpal_encoder *e,
                                   struct tvpal_diag *diag);

/* What the values of an encode held, for a program's report. */
struct tvpal_stats {
    double value_min, value_max; /* the present values' range (min > max
                                  * when none) */
    uint64_t values;          /* values counted (steps x voxels) */
    uint64_t missing;         /* of them missing (NaN or a missing value) */
    uint64_t replaced;        /* non-finite values TVPAL_PARAM_NAN_AS
                               * replaced */
    uint64_t dropped;         /* present values coded as missing: a
                               * slice-window with more than 128 patterns
                               * of missing steps (a smaller window avoids
                               * it) */
    double p_low, p_high;     /* the 0.1 and 99.9 percentiles of the
                               * present values (to a class of 65536 over
                               * the float range) */
    uint64_t beyond_1e30;     /* present values beyond +-1e30: a fill value
                               * left in the data? */
    uint64_t far;             /* present values more than 100 times
                               * p_high - p_low outside [p_low, p_high]:
                               * they set the range the quantizers and the
                               * colours spend */
};

/* The statistics of every step e has taken, into *out: after the last
 * push or tvpal_encoder_encode, before tvpal_encoder_finish (or earlier,
 * of the steps so far).  Under a collective, after pushes this rank's
 * share (the manifest has the sums), after an encode from a source every
 * rank's (level 0 is finished then).  0, or
 * TVPAL_E_INVAL before the first push or encode.  Since 0.3.0. */
TVPAL_API int tvpal_encoder_stats(struct tvpal_encoder *e,
                                  struct tvpal_stats *out);

/* Stops: removes DIR.partial and its lock, and releases e.  An older DIR
 * stays as it was.  NULL is a no-op. */
TVPAL_API void tvpal_encoder_abort(struct tvpal_encoder *e);

/* ------------------------------------------------- encoding from a source
 *
 * Instead of pushing steps, a caller may hand the encoder a source to read
 * from (files, another library's reader).  The encoder then fits the job
 * into TVPAL_PARAM_MEM_LIMIT: when N whole steps and the workspaces do not
 * fit, it encodes the volume in passes over boxes of it (z slabs, y slabs,
 * x slabs of the slices of each axis; tvpal-encode(1), "memory"), each
 * pass reading its box of every step, so a limit below a window's steps
 * costs reading the source more than once, never more memory.  It asks
 * for the boxes it needs as it needs them, and continues an interrupted
 * job from its checkpoint where the source names itself (identity).  With
 * TVPAL_PARAM_LEVELS the levels are made from each step as it is read when
 * the plan is one pass; otherwise after level 0, from the source read
 * again in slabs of planes.  Level 0 is finished before the levels are
 * (DIR.partial/levels.job then names the job), and each level is finished
 * in turn, the end of a unit for the progress callback (level: which): in
 * one process, an encode of the same job and identity after a stop or a
 * failure there keeps level 0 and every complete level, and makes only
 * the others, also for another TVPAL_PARAM_LEVELS (the manifests then
 * name those; levels beyond them go).  The dataset is byte-identical to
 * one pushed from the same values, and to tvpal-encode's from the same
 * files.  With a collective (every rank calls it,
 * with the whole source), each rank reads what its node shard of every
 * axis needs, in passes per axis over its slabs, and rank 0 makes the
 * levels after level 0: the dataset is one process's with
 * TVPAL_PARAM_NODES set to the ranks. */

/* Where an encode from a source stands, for its progress callback. */
struct tvpal_progress {
    uint64_t work, total;     /* voxel-samples encoded (every axis; a voxel
                               * of a window of L steps counts L), of the
                               * job's; a resumed job starts at its share */
    uint64_t unit, units;     /* steps of passes done (pass * steps + step
                               * + 1 once a step is encoded), of passes *
                               * steps */
    uint32_t pass, passes;    /* the pass, from 0, of the plan's */
    uint32_t level;           /* 0 while level 0 is encoded; k while the
                               * levels are made after it (the step is
                               * then `step`) */
    uint32_t step;            /* the step being read or encoded */
    int unit_end;             /* 1: a unit has just ended (its checkpoint
                               * is saved when due), or with levels a
                               * level is complete (level: which; see
                               * below); 0: a tick, once before the
                               * first read of a step (unit: where the
                               * encode starts, 0 or the checkpoint's;
                               * TVPAL_GROUP_AUTO's sample is read
                               * before it) and at most 5 times a
                               * second within a unit */
    /* Set from the first tick on. */
    int resumed;              /* 1: the encode continues an earlier one
                               * of the job in DIR.partial (from `unit`) */
    int level0_kept;          /* 1: level 0 was finished by an earlier
                               * encode of the job and is kept: only the
                               * levels not complete are made (unit is
                               * then units) */
    uint32_t levels_before;   /* with level0_kept: the levels that encode
                               * asked for (its manifest's) */
    int started_over;         /* 1: a partial output in DIR.partial was
                               * not continued (another job's or
                               * identity's, a checkpoint that does not
                               * match, a shard damaged since) and is
                               * gone: the encode starts at unit 0 */
};

/* What a progress callback returns at the end of a unit (its return at a
 * tick is ignored). */
#define TVPAL_GO_ON 0              /* go on */
#define TVPAL_SAVE_AND_GO_ON 1     /* save a checkpoint now, then go on */
#define TVPAL_SAVE_AND_STOP 2      /* save a checkpoint and return
                                    * TVPAL_E_CANCELED; DIR.partial stays,
                                    * and an encode of the same job and
                                    * identity continues from it */
#define TVPAL_STOP 3               /* return TVPAL_E_CANCELED without
                                    * saving (as if killed now) */

/* A source of timesteps.  The caller owns it and what it points to, until
 * tvpal_encoder_encode returns. */
struct tvpal_source {
    enum tvpal_scalar type;   /* of the values read */
    int big_endian;           /* 1: the values are big-endian (files of
                               * another machine), 0: this host's order */
    int concurrent;           /* 1: read may run on several of the
                               * encoder's threads at once, for different
                               * boxes (a file read with pread); it is then
                               * asked for whole rows of one plane at a
                               * time, at most 8 MiB.  0: one call at a
                               * time, each for a whole box, on a reader
                               * thread of the encoder's that reads the
                               * next step while this one is encoded (a
                               * library that is not thread-safe: calls
                               * never overlap) */
    const char *identity;     /* text that names the values (the files and
                               * what identifies their contents): the
                               * encode continues from a checkpoint in
                               * DIR.partial only of the same job and
                               * identity.  NULL: it never continues (an
                               * older DIR.partial is removed) */
    uint64_t held_bytes;      /* memory the source holds of its own while
                               * it reads, for the plan; 0 if none */
    void *ctx;                /* the caller's; passed to both */
    /* Reads step `step`'s box of voxels lo[a] .. lo[a] + n[a] - 1 into
     * dst: n[0] * n[1] * n[2] values of `type`, x fastest.  0, or a
     * negative TVPAL_E_* code with diag set (naming the file); the encode
     * then fails with that code and diag, keeping DIR.partial as its last
     * checkpoint left it (TVPAL_E_READ, TVPAL_E_OPEN: a rerun may
     * continue), or removing it (any other code: the source is bad). */
    int (*read)(void *ctx, uint32_t step, const uint32_t lo[3],
                const uint32_t n[3], void *dst, struct tvpal_diag *diag);
    /* Optional (may be NULL): where the encode stands, on the calling
     * thread, before it starts, at the end of every unit and a few times
     * a second within one; returns TVPAL_GO_ON or another of the answers
     * above. */
    int (*progress)(void *ctx, const struct tvpal_progress *p);
};

/* The plan of an encode from a source under TVPAL_PARAM_MEM_LIMIT. */
struct tvpal_plan {
    uint32_t passes;          /* passes over the volume */
    uint32_t passes_axis[3];  /* of them per axis (all 0: one pass encodes
                               * every axis from one read of each step) */
    uint64_t peak_bytes;      /* estimated bytes of the largest pass */
    uint64_t min_limit;       /* the smallest limit this job can have */
    uint64_t ring_bytes;      /* what one pass over the whole volume
                               * needs: N steps and the workspaces (the
                               * reader thread's boxes aside) */
    uint64_t read_voxels;     /* voxels read over all passes and steps
                               * (the source's voxels * steps when one
                               * pass) */
    int levels_inline;        /* 1: the levels are made from each step of
                               * level 0's one pass; 0: after level 0 */
    int levels_over;          /* with TVPAL_E_RANGE: 1 when level 0 fits
                               * and the levels made after it do not
                               * (min_limit is what they need) */
};

/* The plan tvpal_encoder_encode would make for src with e's parameters,
 * into *out; nothing is read or written.  0; TVPAL_E_RANGE: the limit is
 * too small for even one slice per pass (out->min_limit says what would
 * do; diag says so); TVPAL_E_INVAL, TVPAL_E_NOMEM. */
TVPAL_API int tvpal_encoder_plan(struct tvpal_encoder *e,
                                 const struct tvpal_source *src,
                                 struct tvpal_plan *out,
                                 struct tvpal_diag *diag);

/* Encodes every step of src, reading it as the plan (tvpal_encoder_plan)
 * needs, in place of pushes: call it once, on an encoder with no push,
 * then tvpal_encoder_finish (or, on failure, tvpal_encoder_abort).  With
 * src->identity, a checkpoint of the same job and identity in DIR.partial
 * is continued (the steps before it are not read again), and
 * TVPAL_PARAM_CHECKPOINT counts units (steps of passes).  Level 0 is
 * finished when it returns (under a collective the statistics are every
 * rank's: every value missing is refused here, TVPAL_E_INVAL), and so are
 * the levels; tvpal_encoder_finish then reads the dataset back and puts
 * it in place.  0; the codes of a first push and of src->read;
 * TVPAL_E_RANGE (the limit is too small: diag gives the smallest that
 * would do); TVPAL_E_CANCELED (the progress callback stopped it);
 * TVPAL_E_INVAL (a push before, a second call, every value missing). */
TVPAL_API int tvpal_encoder_encode(struct tvpal_encoder *e,
                                   const struct tvpal_source *src,
                                   struct tvpal_diag *diag);

/* ----------------------------------------------------------------- reader */

/* What a dataset holds.  Strings and arrays belong to the reader. */
struct tvpal_info {
    uint32_t dims[3];
    uint32_t steps, window, nodes;
    uint32_t axes;            /* mask of TVPAL_AXIS_*: the axes stored */
    uint32_t levels;          /* coarser levels of detail: 1 .. levels */
    double spacing[3], origin[3];
    double value_min, value_max;   /* of the source's present values */
    const double *times;      /* steps values, or NULL (none known) */
    const char *time_units;   /* "" when none */
    const char *units;        /* "" when none */
    uint64_t missing;         /* missing values in the source */
    uint64_t source_bytes;    /* bytes of the source as encoded */
    /* Since 0.2.0 (the reader owns the struct: later versions append). */
    uint32_t table;           /* TVPAL_TABLE_FLOAT32, _UINT16 or _AUTO */
    int has_nan_as;           /* 1: the source's non-finite values were */
    double nan_as;            /* replaced by nan_as (TVPAL_PARAM_NAN_AS) */
    uint64_t nonfinite;       /* how many were */
    const double *missing_values;  /* nmissing_values source values that */
    uint32_t nmissing_values;      /* meant missing (compared as float32) */
    const uint64_t *histogram;     /* histogram_bins counts of the present */
    uint32_t histogram_bins;       /* values, bins linear over [value_min,
                                    * value_max], the last holding its top */
    /* Provenance, "" when not recorded. */
    const char *encoder;      /* the program and version that encoded it */
    const char *options;      /* the options it was given */
    const char *manifest;     /* manifest.txt as it is on disk */
    /* The source as the encoder read it, so that a tool can read it again
     * (tvpal-report): "" and no sources for one encoded from memory. */
    const char *source_format;     /* "raw", "netcdf", "hdf5", "vti", "vtk" */
    const char *source_var;   /* the variable read; "NAME (magnitude)": the
                               * length of NAME's vectors; "" for raw */
    const char *source_type;  /* raw: "f32", "f64", "u8", "u16", "i16"
                               * (tvpal-encode --type) */
    uint32_t source_value_bytes;   /* bytes of one source value (its type) */
    int source_big_endian;    /* raw: the values are big-endian */
    int source_single_file;   /* raw: one file holds every step (else one
                               * file per step) */
    const char *const *sources;    /* nsources paths, as given */
    uint32_t nsources;
    /* Since 0.4.0. */
    uint32_t schedule;        /* TVPAL_SCHEDULE_STAGGERED or _JOINED */
    uint32_t group[3];        /* palette group size G of each axis (1:
                               * none; TVPAL_PARAM_GROUP), from its shards;
                               * 0 for an axis not stored, and for every
                               * axis from tvpal_reader_open_manifest */
};

struct tvpal_reader;

/* Opens the dataset directory dir and checks that its files agree.  0;
 * TVPAL_E_OPEN (no dataset: diag names the file), TVPAL_E_MANIFEST,
 * TVPAL_E_FORMAT, TVPAL_E_MISMATCH, TVPAL_E_CHECKSUM (diag names the file
 * and what is wrong), TVPAL_E_NOMEM.  Release with tvpal_reader_close. */
TVPAL_API int tvpal_reader_open(struct tvpal_reader **out, const char *dir,
                                struct tvpal_diag *diag);

/* Opens the dataset directory dir reading only its manifest: for a
 * dataset whose shards may be damaged, to describe it (tvpal_reader_info)
 * or verify it (tvpal_reader_verify).  Decode and sizes open the shards
 * when first called and fail as tvpal_reader_open would.  0;
 * TVPAL_E_OPEN (no dataset directory), TVPAL_E_MANIFEST (diag names the
 * file and the key at fault), TVPAL_E_NOMEM. */
TVPAL_API int tvpal_reader_open_manifest(struct tvpal_reader **out,
                                         const char *dir,
                                         struct tvpal_diag *diag);

/* NULL is a no-op. */
TVPAL_API void tvpal_reader_close(struct tvpal_reader *r);

/* The dataset's description; valid until tvpal_reader_close. */
TVPAL_API const struct tvpal_info *tvpal_reader_info(
    const struct tvpal_reader *r);

/* The dims of level `level` (0: the dataset's; k: ceil(d / 2^k) per axis).
 * 0 or TVPAL_E_INVAL (level > levels). */
TVPAL_API int tvpal_reader_level_dims(const struct tvpal_reader *r,
                                      uint32_t level, uint32_t dims[3]);

/* Decodes step t from the slices of `axis` (TVPAL_AXIS_X, _Y or _Z, one
 * the dataset stores; 0: the default, z when stored) of level `level`
 * into dst: the level's nx * ny * nz floats, x fastest, NaN where the
 * source was missing.  Sequential steps read one record per shard; a jump
 * reads at most N.  0; TVPAL_E_INVAL (t, axis or level out of range);
 * TVPAL_E_READ, TVPAL_E_CHECKSUM, TVPAL_E_FORMAT (the file: diag names
 * it); TVPAL_E_NOMEM. */
TVPAL_API int tvpal_reader_decode(struct tvpal_reader *r, uint32_t t,
                                  unsigned axis, uint32_t level, float *dst,
                                  struct tvpal_diag *diag);

/* Where the bytes of one level go.  Per axis x, y, z (index 0, 1, 2; all
 * 0 for an axis not stored): its shards' bytes, the 8-bit indices (width *
 * height per slice-window) and the decoder tables as the chunks hold them
 * plain (with coded chunks, TVPAL_PARAM_INDEX_CODING, the file holds them
 * in fewer bytes: then they may add up to more than axis_bytes); the
 * chunks by table format. */
struct tvpal_sizes {
    uint64_t axis_bytes[3];
    uint64_t index_bytes[3];
    uint64_t table_bytes[3];
    uint64_t chunks_f32[3];   /* chunks with float32 decoder tables */
    uint64_t chunks_u16[3];   /* chunks with 16-bit decoder tables */
    uint64_t disk_bytes;      /* every file under the level's directory
                               * (level 0: the dataset's, its levels and
                               * manifests included) */
};

/* The sizes of level `level` (0 .. levels) into *out.  With tables
 * chosen per chunk (TVPAL_TABLE_AUTO) it reads every chunk's header.  0;
 * TVPAL_E_INVAL (level out of range); the codes of tvpal_reader_open and
 * TVPAL_E_READ (diag names the file). */
TVPAL_API int tvpal_reader_sizes(struct tvpal_reader *r, uint32_t level,
                                 struct tvpal_sizes *out,
                                 struct tvpal_diag *diag);

/* How the chunks of one level are stored (FORMAT.md 6.11), per axis x, y,
 * z as in struct tvpal_sizes.  Since 0.4.0. */
struct tvpal_coding {
    uint64_t chunks[3];            /* every chunk (slice-window) */
    uint64_t chunks_coded[3];      /* of them, stored as zstd frames */
    uint64_t coded_bytes[3];       /* what those take in the files
                                    * (headers, frames, padding) */
    uint64_t coded_plain_bytes[3]; /* what those take inflated */
};

/* The coding of level `level` (0 .. levels) into *out: reads every
 * chunk's header.  0; TVPAL_E_INVAL (level out of range); the codes of
 * tvpal_reader_open and TVPAL_E_READ, TVPAL_E_FORMAT (diag names the
 * file).  Since 0.4.0. */
TVPAL_API int tvpal_reader_coding(struct tvpal_reader *r, uint32_t level,
                                  struct tvpal_coding *out,
                                  struct tvpal_diag *diag);

/* One finding of tvpal_reader_verify, valid during the call it is passed
 * to. */
struct tvpal_check {
    const char *path;         /* the file: a shard, or a level's directory */
    int code;                 /* 0: the file is sound; else TVPAL_E_* */
    int64_t record;           /* the record at fault, or -1: the file */
    uint64_t offset;          /* the record's offset in the file */
    uint32_t records;         /* code 0: the records read */
    const char *msg;          /* code != 0: a sentence naming the file (and
                               * the record) and what is wrong */
};
typedef void (*tvpal_check_fn)(void *ctx, const struct tvpal_check *c);

/* Checks every file of the dataset, whatever else is damaged: every shard
 * of the stored axes (it opens, its header agrees with the manifest, every
 * record reads with its CRC-32C and layout), then every level the
 * manifest names (its manifest, then its shards).  Calls fn(ctx, c) once
 * per sound shard and once per problem, in the order of the files (fn
 * may be NULL), and sets *problems (when not NULL) to the number of
 * problems.  Works on a reader of either open.  0 (the verdict is
 * *problems); TVPAL_E_NOMEM. */
TVPAL_API int tvpal_reader_verify(struct tvpal_reader *r, tvpal_check_fn fn,
                                  void *ctx, uint64_t *problems,
                                  struct tvpal_diag *diag);

#ifdef __cplusplus
}
#endif

#endif
