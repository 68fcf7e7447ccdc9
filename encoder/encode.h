/* encode.h: the state of one tvpal-encode run, which its modules share.
 *
 * struct run is set up by main's steps in order (tvpal-encode.c) and
 * released by run_free.  The modules, bottom to top, each including only
 * the headers below it (tests/layers.sh checks the order LAYERS.md gives):
 *   encode_say.h      messages and how a failure ends the program
 *   encode.h          this header: the options and the run (data only)
 *   encode_output.h   the grid recorded, the warnings and progress
 *   encode_source.h   the input: its files and checks, and the input as
 *                     libtvpal's source (raw files, self-describing
 *                     readers)
 *   encode_cluster.h  the MPI job (one rank per node shard): libtvpal's
 *                     collective, the round before the encode, the sizes
 *   tvpal-encode.c    the options, the encoder and its progress
 *                     callback, the reports
 *
 * Program code, not library code: the modules report and end the program
 * themselves (encode_say.h).
 */
#ifndef TVPAL_ENCODE_H
#define TVPAL_ENCODE_H

#include "encode_plan.h"
#include "encode_say.h"
#include "tvpal_checkpoint.h"
#include "tvpal_error.h"
#include "tvpal_format.h"
#include "tvpal_input.h"
#include "tvpal_manifest.h"
#include "tvpal_pool.h"
#include "tvpal_raw.h"
#include "tvpal_swcode.h"

#include <stddef.h>
#include <stdint.h>


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
    int index_none;            /* --index-coding none */
    int staggered;             /* --schedule staggered */
    uint32_t group;            /* --group G: palette groups (1: none) */
    uint32_t index_level;      /* --index-level (zstd) */
    int has_nan_as;
    double nan_as;
    double missing[TVPAL_MISSING_VALUES_MAX];   /* --missing V */
    unsigned nmissing;
    const char *outdir;
    int force, quiet;
    int allow_external;               /* HDF5 data in other files read */
    int magnitude;                    /* --magnitude: a VTK array of
                                       * several components read as its
                                       * length at each point */
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




/* Progress on stderr: a bar redrawn at most 5 times a second on a terminal,
 * otherwise a line every 30 s, whether a timestep takes a second or an
 * hour; always at the end.  `work` counts voxel-samples encoded (all axes;
 * a voxel of a window of length L counts L), out of `total`. */
struct progress {
    int tty, quiet;
    double t0, last, interval;  /* seconds between lines */
    uint64_t work, total;    /* as the library's progress calls say */
    uint64_t work_at_start;  /* a resumed job's share already done */
    uint64_t unit, units;    /* the step being done (pass * T + step), of */
};

/* One encoding run: the job, its input and output, set up by main's steps
 * in order and released by run_free. */
struct raw_files;
struct drive;
struct cluster;

struct run {
    struct opts o;
    uint32_t T, N;           /* timesteps, window */
    size_t nvox;             /* voxels per timestep */
    uint64_t step_bytes;     /* source bytes per timestep */
    char **abs_inputs;       /* o.inputs points here once checked */
    char *partial;           /* OUTDIR.partial */
    int nthreads;            /* worker threads (-j) */
    uint64_t limit;          /* the memory limit, */
    char limit_why[128];     /* and where it comes from */
    uint32_t passes;         /* the plan's passes (this rank's) */
    uint64_t missing;        /* missing values the encode found */
    struct tvpal_input *in;  /* self-describing input, or NULL (raw) */
    struct tvpal_pool *in_pool;  /* its reading thread's team (-j threads)
                                  * for compressed chunks, or NULL */
    struct raw_files *rawf;  /* the raw files the library's source keeps
                              * open (encode_source.c) */
    double *times;           /* [T] time values, or NULL (none known) */
    char time_units[128];
    char units[64];          /* the values' units, or "" (load_times) */
    double t_encode;         /* seconds of the encode */
    struct progress prog;
    double ckpt_last;        /* when the last checkpoint was saved (or the
                              * encode began) */
    struct drive *drive;     /* the library's progress callback's state
                              * (tvpal-encode.c) */
    /* MPI: this rank encodes node `node`; rank 0 learns the others'
     * sizes for the summary (cluster_sizes). */
    int mpi;
    uint32_t node;
    uint64_t cluster_bytes;  /* rank 0: bytes of every rank's files and
                              * OUTDIR's manifest, */
    uint64_t cluster_shard_bytes; /* of every rank's shards, */
    uint64_t cluster_level_bytes; /* of the levels (rank 0's, inside
                                   * OUTDIR), */
    uint64_t cluster_work;   /* the voxel-samples they encoded, */
    double cluster_seconds;  /* in this many seconds (the slowest) */
    struct cluster *cl;      /* the MPI job (encode_cluster.h) */
};


#endif
