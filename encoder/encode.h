/* encode.h: the parts of tvpal-encode and what they share.
 *
 * tvpal-encode.c has the options, the output directories, the plan's glue,
 * the workspaces, the streaming driver (passes over steps, chunks written
 * in place, checkpoints) and the finishing; encode_source.c reads the
 * input (raw boxes in blocks, self-describing readers with a read-ahead
 * thread) and checks it; encode_cluster.c is the MPI job (one rank per
 * node shard) and how its ranks agree on the end.  struct run is the one
 * state of a run, set up by main's steps in order and released by
 * run_free.
 *
 * Program code, not library code: the functions here report and end the
 * program themselves (msg, die_*: see enum ending).
 */
#ifndef TVPAL_ENCODE_H
#define TVPAL_ENCODE_H

#include "encode_plan.h"
#include "tvpal_checkpoint.h"
#include "tvpal_engine.h"
#include "tvpal_comm.h"
#include "tvpal_error.h"
#include "tvpal_format.h"
#include "tvpal_input.h"
#include "tvpal_manifest.h"
#include "tvpal_pool.h"
#include "tvpal_raw.h"
#include "tvpal_shard.h"
#include "tvpal_swcode.h"

#include <stddef.h>
#include <stdint.h>

#define PROG "tvpal-encode"

/* The axes encoded without --axes (a mask of TVPAL_AXIS_BIT, tvpal_manifest.h):
 * z alone, since the player draws every view from the z slices within 10%
 * of the three-copy speed with both renderers (scripts/bench-play section
 * i; NEWS has the figures).  --help and tvpal-encode.1 name it in words.
 * The manifest's options line records --axes when it differs. */
#define ENCODE_AXES_DEFAULT TVPAL_AXIS_BIT(2)

struct opts {
    uint32_t dims[3];
    enum tvpal_type type;
    int big_endian;
    uint32_t window, nodes, steps_single, threads;
    int table_format;          /* the shards': TVPAL_TABLE_F32, _U16 or
                                * _CHUNK (--table auto, each chunk's own) */
    uint32_t refine;
    int naive, klt, alloc_mse;
    int has_nan_as;
    double nan_as;
    double missing[TVPAL_MISSING_VALUES_MAX];   /* --missing V */
    unsigned nmissing;
    const char *outdir;
    int force, quiet;
    int allow_external;               /* HDF5 data in other files read */
    int dry_run;                      /* --dry-run: the plan, then exit */
    char **inputs;
    int ninputs;
    enum tvpal_input_format format;   /* --format; AUTO until detected */
    const char *var, *time_dim;       /* --var, --time-dim */
    int have_type, have_endian;       /* given on the command line */
    int sort_natural;                 /* --sort natural */
    double spacing[3], origin[3];     /* --spacing, --origin */
    int have_spacing, have_origin;
    const char *times_file;           /* --times FILE */
    const char *time_units;           /* --time-units TEXT */
    const char *units;                /* --units TEXT */
    uint64_t mem_limit;               /* --mem-limit SIZE, or 0 */
    uint32_t checkpoint_every;        /* --checkpoint-every SECONDS: the
                                       * least time between checkpoints
                                       * (0: after every step) */
    const char *shard_pat;            /* --shard-dir PATTERN (MPI) */
    uint32_t levels;                  /* --levels L: coarser levels */
    uint32_t axes;                    /* --axes: the axes encoded, a mask
                                       * of TVPAL_AXIS_BIT (1..7) */
};

/* How a message ends the program: MSG_ONLY returns; the others exit with
 * code 2 (usage or bad input, before any output), 1 (output or system
 * failure: a partial output is kept for a rerun to resume) or 2 after
 * removing the partial output (bad input found mid-run: a rerun would fail
 * the same way, so nothing partial stays behind). */
enum ending { MSG_ONLY, DIE_USAGE, DIE_FAIL, DIE_INPUT };


/* Bytes of the reading scratch of one thread (raw input is read in blocks
 * of at most this much, converted into the ring as it comes). */
#define READ_BLOCK ((size_t)8 << 20)

/* Progress on stderr: a bar redrawn at most 5 times a second on a terminal,
 * otherwise a line every 30 s, whether a timestep takes a second or an
 * hour; always at the end.  `work` counts voxel-samples encoded (all axes;
 * a voxel of a window of length L counts L), out of `total`. */
struct progress {
    int tty, quiet;
    double t0, last, interval;  /* seconds between lines */
    uint64_t work, total;    /* work is added to atomically */
    uint64_t work_at_start;  /* a resumed job's share already done */
    uint64_t unit, units;    /* the step being done (pass * T + step), of */
};

/* One encoding run: the job, its output and the workspaces, set up by
 * main's steps in order and released by run_free. */
struct prefetch;
struct tvpal_found;

struct run {
    struct opts o;
    uint32_t T, N;           /* timesteps, window */
    size_t nvox;             /* voxels per timestep */
    uint64_t step_bytes;     /* source bytes per timestep */
    char **abs_inputs;       /* o.inputs points here once checked */
    char *partial;           /* OUTDIR.partial */
    char *fp;                /* job fingerprint */
    struct tvpal_checkpoint_stats st;
    uint64_t start;          /* first unit of work (pass * T + step) */
    /* The engine (tvpal_engine.h), and its shards: the axes encoded x K
     * nodes, axis-major (every node's, or one rank's). */
    struct tvpal_engine *eng;
    struct tvpal_engine_shard *sj;
    uint32_t nshard;
    /* The memory plan and the pass being encoded. */
    uint64_t limit;
    char limit_why[128];
    struct encode_plan plan;
    const struct encode_pass *pass;
    /* Workspaces: per thread, then shared. */
    int nthreads;
    struct tvpal_pool *pool; /* nthreads threads (the main one is 0) */
    uint64_t **fine_local;   /* per-thread source histograms */
    struct tvpal_found *found_local; /* per thread: what a box read found */
    unsigned char **scratch;    /* per thread: READ_BLOCK bytes (raw) */
    float *boxbuf;           /* a self-describing input's box, as read */
    struct tvpal_input *in;  /* self-describing input, or NULL (raw) */
    struct tvpal_pool *in_pool;  /* its reading thread's team (-j threads)
                                  * for compressed chunks, or NULL */
    struct prefetch *pf;     /* reads the input's next step meanwhile */
    double *times;           /* [T] time values, or NULL (none known) */
    char time_units[128];
    char units[64];          /* the values' units, or "" (load_times) */
    double t_encode;         /* seconds of the streaming loop */
    struct progress prog;
    double ckpt_last;        /* when the last checkpoint was saved (or the
                              * steps began) */
    /* Checkpoint copies of the writers' progress (tvpal_checkpoint.h). */
    struct tvpal_checkpoint_progress ckp;
    /* MPI: this rank encodes node `node` only; its node directory while
     * the job runs (also its checkpoint's), and where it goes at the end
     * (--shard-dir; NULL: it stays inside OUTDIR). */
    int mpi;
    uint32_t node;
    char *ckdir;
    char *node_final;
    uint64_t cluster_bytes;  /* rank 0: bytes of every rank's files and
                              * OUTDIR's manifest, */
    uint64_t cluster_shard_bytes; /* of every rank's shards, */
    uint64_t cluster_work;   /* the voxel-samples they encoded, */
    double cluster_seconds;  /* in this many seconds (the slowest) */
    int level0_done;         /* --levels: level 0 finished by an earlier
                              * run of the same job (levels.job) */
    int levels_inline;       /* --levels: the plan holds the levels beside
                              * level 0's one pass */
    struct levels *lvs;      /* the levels made as level 0's steps are
                              * read, or NULL */
};


/* ------------------------------------------------------------ diagnostics */

/* Under MPI (mpirun -np K, one rank per node shard): this process's
 * communicator, and the next round of the job's agreement
 * (encode_cluster.c) that a rank which fails joins with its message, so
 * that rank 0 reports it and every rank ends, none left waiting.  g_round
 * 0: one process; above ROUNDS: the rounds are over. */
extern struct tvpal_comm g_comm;
extern int g_round;
#define ROUNDS 3
extern char *g_partial;    /* removed on bad input found mid-run */

void msg(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
void die_usage(const char *fmt, ...)
    __attribute__((format(printf, 1, 2), noreturn));
void die_fail(const char *fmt, ...)
    __attribute__((format(printf, 1, 2), noreturn));
void die_input(const char *fmt, ...)
    __attribute__((format(printf, 1, 2), noreturn));
/* The text of a library error (a static buffer). */
const char *lib_error(int rc, const struct tvpal_diag *d);

/* ----------------------------------------------- tvpal-encode.c (output) */

char *node_partial(const struct run *r, uint32_t k);
char *shard_path(const struct run *r, const struct tvpal_engine_shard *j);
void finish_shards(struct run *r);
char *manifest_text(const struct run *r);
void write_manifest(const char *dir, const char *text);
int place_output(const struct run *r, char *err, size_t cap);
int all_missing(const struct run *r, char *why, size_t cap);
uint64_t dropped_values(const struct run *r);
void warn_dropped(uint64_t dropped);
void warn_dominating_values(const struct run *r);
/* A progress line when one is due (every 30 s, 0.2 s on a terminal), or
 * the closing one when `last`; from thread 0 only. */
void report_progress(struct run *r, int last);

/* ------------------------------------------- encode_source.c (the input) */

void order_inputs(struct opts *o);
int open_source(struct run *r, int have_dims);
void load_times(struct run *r);
void warn_irregular_times(const struct run *r);
void check_inputs(struct run *r);
struct prefetch *prefetch_start(struct tvpal_input *in, uint64_t voxels);
void prefetch_stop(struct prefetch *pf);
void load_step(struct run *r, uint32_t t, float *dst);
/* Per-thread findings of a box read for n threads (r->found_local);
 * NULL when out of memory.  Freed with free(). */
struct tvpal_found *encode_found_alloc(size_t n);

/* ---------------------------------------------------------------- levels */
/* encode_levels.c.  The dims of level k of a volume of dims d0. */
void level_dims(const uint32_t d0[3], unsigned k, uint32_t out[3]);
/* The spacing sk and origin ok of a level of dims dk over level 0's grid
 * (s0, o0, dims d0): the same extent, its voxels' centres inside. */
void level_grid(const double s0[3], const double o0[3], const uint32_t d0[3],
                const uint32_t dk[3], double sk[3], double ok[3]);
/* After level 0 is finished in OUTDIR.partial: levels 1..L into
 * OUTDIR.partial/level-k/ (encode_levels.c says how): those made beside
 * level 0 (r->lvs) finished, or made now from the source read again. */
void encode_levels(struct run *r);
/* The levels' encoders (the levels not yet complete), their steps made
 * from whole source steps given to levels_step (inline_steps: level 0's
 * single pass) or from the source read again (vol0 NULL); levels_close
 * finishes them and frees ls (ending the program on failure); levels_free
 * aborts them (a level's partial output goes) and frees ls. */
struct levels;
struct levels *levels_open(struct run *r, int inline_steps);
void levels_step(struct run *r, struct levels *ls, uint32_t t,
                 const float *vol0);
void levels_close(struct run *r, struct levels *ls);
void levels_free(struct levels *ls);
void grid_of(const struct run *r, double spacing[3], double origin[3]);
void check_grid(const struct run *r);
/* Frees the ring's boxes (run_free frees the rest). */
void release_ring(struct run *r);
/* Rows of row_bytes a raw read takes at once: READ_BLOCK's worth, at
 * least one, at most rows_max (a plane's).  Sizes the reading scratch. */
size_t read_rows(uint64_t row_bytes, uint32_t rows_max);

/* -------------------------------------------- encode_cluster.c (the job) */

void open_cluster(struct run *r, int *argc, char ***argv);
void setup_cluster_dirs(struct run *r);
void cluster_finish(struct run *r);
void cluster_fail(enum ending how, const char *text)
    __attribute__((noreturn));
void cluster_free(void);

#endif
