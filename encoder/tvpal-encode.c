/* tvpal-encode: encodes a time series of raw volumes into a tvpal dataset
 * (paper section III; format: common/format/FORMAT.md).
 *
 * Streaming: timestep t + N - 1 is read when the records of step t are
 * built, so memory holds N float volumes (a ring) plus the records of one
 * step, never T.  Output goes to OUTDIR.partial/ and is renamed to OUTDIR
 * only when complete; a checkpoint written after every step
 * (tvpal_checkpoint.h) lets a rerun of the same command continue an
 * interrupted job.
 *
 * main runs the steps in order: options (g_optspec, validate_opts), input
 * and output checks, the partial output (resumed or new), shards and
 * workspaces, the streaming driver (encode_steps) and the finishing
 * (finish_partial, move_into_place, print_summary).  A step that fails ends
 * the program with the exit code of `enum ending`.
 */
#define _GNU_SOURCE
#include "encode_plan.h"
#include "tvpal_checkpoint.h"
#include "tvpal_cli.h"
#include "tvpal_clock.h"
#include "tvpal_comm.h"
#include "tvpal_dataset.h"
#include "tvpal_eig.h"
#include "tvpal_error.h"
#include "tvpal_format.h"
#include "tvpal_fs.h"
#include "tvpal_input.h"
#include "tvpal_manifest.h"
#include "tvpal_raw.h"
#include "tvpal_shard.h"
#include "tvpal_swcode.h"
#include "tvpal_schedule.h"

#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define PROG "tvpal-encode"

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " [--dims NXxNYxNZ] [options] -o OUTDIR INPUT...\n"
"Encode a time series of volumes into a tvpal dataset: for each axis, 8-bit\n"
"indexed slices with per-window decoder tables.  INPUT is raw (one file per\n"
"timestep, in time order, or one file holding all timesteps with --steps),\n"
"or NetCDF, VTK ImageData (.vti, .pvti, a .pvd collection) or legacy VTK\n"
"files, which say their own dims, type and steps (a NetCDF file may hold\n"
"several timesteps: a time dimension; a .pvd lists its files and times).\n"
"\n"
"Input:\n"
"      --format F         auto (default: from each file's own bytes), raw,\n"
"                         netcdf, hdf5, vti (also .pvti, .pvd) or vtk\n"
"                         (legacy)\n"
"      --var NAME         the variable (NetCDF), dataset (HDF5:\n"
"                         /group/dataset), point array (vti) or SCALARS\n"
"                         (vtk) to encode (default: the only one, or the\n"
"                         active scalars; tvpal-info --inspect FILE lists\n"
"                         them)\n"
"      --time-dim NAME    NetCDF: the time dimension (default: the\n"
"                         unlimited one, or the one a CF time coordinate\n"
"                         names)\n"
"      --sort ORDER       none (default: as given; a warning names the first\n"
"                         pair of numbered names out of natural order) or\n"
"                         natural (density_2 before density_10)\n"
"  -d, --dims NXxNYxNZ    volume size, x fastest (required for raw input;\n"
"                         must agree with a self-describing file)\n"
"  -t, --type TYPE        raw: f32 (default), f64, u8, u16, i16\n"
"  -e, --endian ORDER     raw: little (default) or big\n"
"  -s, --steps T          raw: INPUT is one file holding T timesteps\n"
"      --spacing DX,DY,DZ voxel size per axis (default: from the file's\n"
"                         evenly spaced coordinates, else 1,1,1); the\n"
"                         player draws the physical shape\n"
"      --origin OX,OY,OZ  position of the first voxel (default: from the\n"
"                         file, else 0,0,0)\n"
"      --times FILE       the time value of every step (T numbers, rising;\n"
"                         default: a NetCDF time coordinate, else 0..T-1)\n"
"      --time-units TEXT  their units (default: the coordinate's)\n"
"      --missing V        source value V marks a missing value (repeatable,\n"
"                         up to 16; compared as float32).  Missing values\n"
"                         (also NaN, and NetCDF/HDF5 _FillValue,\n"
"                         missing_value and values outside valid_range)\n"
"                         decode as NaN, are left out of the value range\n"
"                         and the histogram, and are drawn transparent\n"
"      --nan-as VALUE     replace NaN, infinite and missing values by VALUE\n"
"                         instead (default: infinite values are refused,\n"
"                         naming file, timestep and voxel)\n"
"Encoding:\n"
"  -w, --window N         timesteps per DCT window, 1..16 (default 4;\n"
"                         N = 1 is the plain 8-bit Lloyd-Max baseline)\n"
"  -k, --nodes K          split every axis into K slabs, one per node,\n"
"                         written to OUTDIR/node-R/ (default 1)\n"
"  -j, --threads J        worker threads (default: all cores)\n"
"      --refine K         up to K iterations of generalized Lloyd (k-means)\n"
"                         on each slice-window's voxel series after the DCT\n"
"                         code (0..64, default 0): higher PSNR, same format\n"
"      --transform T      dct (default) or klt (per slice-window principal\n"
"                         components, LAPACK)\n"
"      --alloc A          bit allocation: variance (default, the paper's\n"
"                         rule) or greedy-mse (by measured quantizer error)\n"
"      --naive            the paper's naive variant (uniform quantizers,\n"
"                         inverse-DCT tables): a floor for comparisons\n"
"      --table FMT        decoder tables: f32 (default: float32) or u16\n"
"                         (16-bit scaled per slice-window: half the table\n"
"                         bytes, error <= (max - min) / 131070 per entry)\n"
"Output:\n"
"  -o, --output OUTDIR    dataset directory (must not exist)\n"
"  -f, --force            replace an existing OUTDIR\n"
"  -q, --quiet            no progress output\n"
"  -h, --help             this help\n"
"  -V, --version          version\n"
"\n"
"An interrupted run leaves OUTDIR.partial/; running the same command again\n"
"continues it.  Exit status: 0 success, 1 failure, 2 bad input or usage.\n");
}

/* ------------------------------------------------------------ diagnostics */

static char *g_partial; /* removed on fatal input errors */

/* How a message ends the program: MSG_ONLY returns; the others exit with
 * code 2 (usage or bad input, before any output), 1 (output or system
 * failure: a partial output is kept for a rerun to resume) or 2 after
 * removing the partial output (bad input found mid-run: a rerun would fail
 * the same way, so nothing partial stays behind). */
enum ending { MSG_ONLY, DIE_USAGE, DIE_FAIL, DIE_INPUT };

/* Under MPI (mpirun -np K, one rank per node shard): this process's
 * communicator, and the next round of the job's agreement (cluster_round)
 * that a rank which fails joins with its message, so that rank 0 reports
 * it and every rank ends, none left waiting.  g_round 0: one process. */
static struct tvpal_comm g_comm;
static int g_round;
#define ROUNDS 3

static void cluster_fail(enum ending how, const char *text)
    __attribute__((noreturn));

static void say(enum ending how, const char *fmt, va_list ap)
{
    if (g_round && g_round <= ROUNDS && how != MSG_ONLY) {
        char text[900];
        vsnprintf(text, sizeof text, fmt, ap);
        cluster_fail(how, text);
    }
    if (how == MSG_ONLY && g_round && g_comm.rank > 0)
        return; /* warnings are the same on every rank: rank 0 says them */
    fputs(PROG ": ", stderr);
    if (g_round && g_comm.rank > 0)
        fprintf(stderr, "rank %d: ", g_comm.rank);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    if (how == MSG_ONLY)
        return;
    if (how == DIE_INPUT && g_partial)
        tvpal_rmtree(g_partial);
    exit(how == DIE_FAIL ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE);
}

#define TVPAL_SAY_FN(name, how, attr)                                         \
    static void name(const char *fmt, ...)                                    \
        __attribute__((format(printf, 1, 2))) attr;                           \
    static void name(const char *fmt, ...)                                    \
    {                                                                         \
        va_list ap;                                                           \
        va_start(ap, fmt);                                                    \
        say(how, fmt, ap);                                                    \
        if (how != MSG_ONLY)                                                  \
            exit(TVPAL_EXIT_FAIL); /* not reached: say() exited */         \
        va_end(ap);                                                           \
    }
TVPAL_SAY_FN(msg, MSG_ONLY, )
TVPAL_SAY_FN(die_usage, DIE_USAGE, __attribute__((noreturn)))
TVPAL_SAY_FN(die_fail, DIE_FAIL, __attribute__((noreturn)))
TVPAL_SAY_FN(die_input, DIE_INPUT, __attribute__((noreturn)))

/* The text of a library error for a message: the code's message, then the
 * diag's detail in parentheses when it has one.  Library calls promise
 * nothing about errno, so their cause comes from here, never strerror(errno).
 * Returns a static buffer (reports are made by one thread). */
static const char *lib_error(int rc, const struct tvpal_diag *d)
{
    static char buf[sizeof ((struct tvpal_diag *)0)->msg + 64];
    if (d && d->msg[0])
        snprintf(buf, sizeof buf, "%s (%s)", tvpal_strerror(rc), d->msg);
    else
        snprintf(buf, sizeof buf, "%s", tvpal_strerror(rc));
    return buf;
}

/* ---------------------------------------------------------------- options */

struct opts {
    uint32_t dims[3];
    enum tvpal_type type;
    int big_endian;
    uint32_t window, nodes, steps_single, threads;
    int table_format;          /* TVPAL_TABLE_F32 or TVPAL_TABLE_U16 */
    uint32_t refine;
    int naive, klt, alloc_mse;
    int has_nan_as;
    double nan_as;
    double missing[TVPAL_MISSING_VALUES_MAX];   /* --missing V */
    unsigned nmissing;
    const char *outdir;
    int force, quiet;
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
    uint64_t mem_limit;               /* --mem-limit SIZE, or 0 */
    const char *shard_pat;            /* --shard-dir PATTERN (MPI) */
};

/* How an option's argument is parsed (parse_option). */
enum optkind {
    OPT_DIMS,      /* NXxNYxNZ into dims */
    OPT_TYPE,      /* sample type into type */
    OPT_U32,       /* whole number in [lo, hi] into the uint32_t at field */
    OPT_CHOICE,    /* choice[i] sets the int at field to i */
    OPT_FLAG,      /* no argument: sets the int at field to 1 */
    OPT_NAN_AS,    /* finite |value| <= TVPAL_VALUE_MAX into nan_as */
    OPT_MISSING,   /* a finite value appended to missing[] */
    OPT_OUTPUT,    /* OUTDIR */
    OPT_FORMAT,    /* input format into format */
    OPT_TEXT,      /* the argument into the const char * at field */
    OPT_SPACING,   /* DX,DY,DZ > 0 into spacing */
    OPT_ORIGIN,    /* OX,OY,OZ into origin */
    OPT_SIZE,      /* bytes ("12G") into the uint64_t at field */
    OPT_HELP,
    OPT_VERSION
};

#define OPT_LONG_ONLY 256 /* keys from here on have no short form */
#define STR_(x) #x
#define STR(x) STR_(x)

/* One row per option: its names, how it is parsed and where it goes.  The
 * getopt_long table and the short-option string are made from it; --help
 * (usage) lists the same options grouped by purpose. */
static const struct optspec {
    const char *name;
    int key;                   /* short letter, or OPT_LONG_ONLY + n */
    enum optkind kind;
    size_t field;              /* offsetof in struct opts (U32, CHOICE, FLAG) */
    uint32_t lo, hi;           /* OPT_U32 */
    const char *choice[2];     /* OPT_CHOICE */
    const char *expect;        /* the usage error's "expected ..." */
} g_optspec[] = {
    {"dims", 'd', OPT_DIMS, 0, 0, 0, {0}, NULL},
    {"type", 't', OPT_TYPE, 0, 0, 0, {0}, "f32, f64, u8, u16 or i16"},
    {"endian", 'e', OPT_CHOICE, offsetof(struct opts, big_endian), 0, 0,
     {"little", "big"}, "little or big"},
    {"steps", 's', OPT_U32, offsetof(struct opts, steps_single), 1,
     UINT32_MAX, {0}, "a whole number >= 1"},
    {"nan-as", OPT_LONG_ONLY + 0, OPT_NAN_AS, 0, 0, 0, {0},
     "a finite number"},
    {"missing", OPT_LONG_ONLY + 14, OPT_MISSING, 0, 0, 0, {0},
     "a finite number (at most 16 of them)"},
    {"window", 'w', OPT_U32, offsetof(struct opts, window), 1, TVPAL_NMAX,
     {0}, "a whole number from 1 to " STR(TVPAL_NMAX)},
    {"nodes", 'k', OPT_U32, offsetof(struct opts, nodes), 1, UINT32_MAX,
     {0}, "a whole number >= 1"},
    {"threads", 'j', OPT_U32, offsetof(struct opts, threads), 1, 1024, {0},
     "1..1024"},
    {"table", OPT_LONG_ONLY + 1, OPT_CHOICE,
     offsetof(struct opts, table_format), 0, 0, {"f32", "u16"},
     "f32 or u16"},
    {"refine", OPT_LONG_ONLY + 2, OPT_U32, offsetof(struct opts, refine), 0,
     TVPAL_REFINE_MAX, {0}, "0.." STR(TVPAL_REFINE_MAX)},
    {"naive", OPT_LONG_ONLY + 3, OPT_FLAG, offsetof(struct opts, naive), 0,
     0, {0}, NULL},
    {"transform", OPT_LONG_ONLY + 4, OPT_CHOICE, offsetof(struct opts, klt),
     0, 0, {"dct", "klt"}, "dct or klt"},
    {"alloc", OPT_LONG_ONLY + 5, OPT_CHOICE,
     offsetof(struct opts, alloc_mse), 0, 0, {"variance", "greedy-mse"},
     "variance or greedy-mse"},
    {"format", OPT_LONG_ONLY + 6, OPT_FORMAT, 0, 0, 0, {0},
     "auto, raw, netcdf, hdf5, vti or vtk"},
    {"var", OPT_LONG_ONLY + 7, OPT_TEXT, offsetof(struct opts, var), 0, 0,
     {0}, NULL},
    {"time-dim", OPT_LONG_ONLY + 8, OPT_TEXT, offsetof(struct opts, time_dim),
     0, 0, {0}, NULL},
    {"sort", OPT_LONG_ONLY + 9, OPT_CHOICE, offsetof(struct opts, sort_natural),
     0, 0, {"none", "natural"}, "none or natural"},
    {"spacing", OPT_LONG_ONLY + 12, OPT_SPACING, 0, 0, 0, {0},
     "DX,DY,DZ, three numbers > 0"},
    {"origin", OPT_LONG_ONLY + 13, OPT_ORIGIN, 0, 0, 0, {0},
     "OX,OY,OZ, three numbers"},
    {"times", OPT_LONG_ONLY + 10, OPT_TEXT, offsetof(struct opts, times_file),
     0, 0, {0}, NULL},
    {"time-units", OPT_LONG_ONLY + 11, OPT_TEXT,
     offsetof(struct opts, time_units), 0, 0, {0}, NULL},
    {"mem-limit", OPT_LONG_ONLY + 15, OPT_SIZE,
     offsetof(struct opts, mem_limit), 0, 0, {0},
     "a size such as 12G, 800M or 1073741824 (bytes)"},
    {"shard-dir", OPT_LONG_ONLY + 16, OPT_TEXT,
     offsetof(struct opts, shard_pat), 0, 0, {0}, NULL},
    {"output", 'o', OPT_OUTPUT, 0, 0, 0, {0}, NULL},
    {"force", 'f', OPT_FLAG, offsetof(struct opts, force), 0, 0, {0}, NULL},
    {"quiet", 'q', OPT_FLAG, offsetof(struct opts, quiet), 0, 0, {0}, NULL},
    {"help", 'h', OPT_HELP, 0, 0, 0, {0}, NULL},
    {"version", 'V', OPT_VERSION, 0, 0, 0, {0}, NULL},
};
#define NOPTS (sizeof g_optspec / sizeof *g_optspec)

/* --table's choices are the format's codes, in order. */
_Static_assert(TVPAL_TABLE_F32 == 0 && TVPAL_TABLE_U16 == 1,
               "g_optspec: --table choice i must be table format i");

/* Applies one option's argument to o; a bad one ends the program (exit 2).
 * --help and --version print and exit 0. */
static void parse_option(const struct optspec *sp, const char *arg,
                         struct opts *o)
{
    char *base = (char *)o;
    struct tvpal_diag diag = {{0}};
    switch (sp->kind) {
    case OPT_DIMS:
        if (tvpal_dims_parse(arg, o->dims, &diag) < 0)
            die_usage("--dims: %s", diag.msg);
        return;
    case OPT_TYPE:
        if (tvpal_type_parse(arg, &o->type) < 0)
            break;
        return;
    case OPT_U32:
        if (tvpal_parse_u32(arg, sp->lo, sp->hi,
                            (uint32_t *)(base + sp->field)) < 0)
            break;
        return;
    case OPT_CHOICE:
        for (int i = 0; i < 2; i++)
            if (!strcmp(arg, sp->choice[i])) {
                *(int *)(base + sp->field) = i;
                return;
            }
        break;
    case OPT_FLAG:
        *(int *)(base + sp->field) = 1;
        return;
    case OPT_NAN_AS:
        if (tvpal_parse_double(arg, &o->nan_as) < 0 ||
            fabs(o->nan_as) > TVPAL_VALUE_MAX)
            break;
        o->has_nan_as = 1;
        return;
    case OPT_MISSING: {
        double v;
        if (o->nmissing == TVPAL_MISSING_VALUES_MAX ||
            tvpal_parse_double(arg, &v) < 0 || !isfinite(v))
            break;
        o->missing[o->nmissing++] = v;
        return;
    }
    case OPT_OUTPUT:
        o->outdir = arg;
        return;
    case OPT_SIZE:
        if (encode_parse_size(arg, (uint64_t *)(void *)(base + sp->field)) < 0)
            break;
        return;
    case OPT_FORMAT:
        if (tvpal_input_format_parse(arg, &o->format) < 0)
            break;
        return;
    case OPT_TEXT:
        *(const char **)(void *)(base + sp->field) = arg;
        return;
    case OPT_SPACING:
    case OPT_ORIGIN: {
        double *v = sp->kind == OPT_SPACING ? o->spacing : o->origin;
        if (tvpal_parse_doubles(arg, ',', 3, v) < 0)
            break;
        int good = 1;
        for (int i = 0; i < 3; i++)
            good &= isfinite(v[i]) && fabs(v[i]) <= 1e300 &&
                    (sp->kind == OPT_ORIGIN || v[i] > 0);
        if (!good)
            break;
        *(sp->kind == OPT_SPACING ? &o->have_spacing : &o->have_origin) = 1;
        return;
    }
    case OPT_HELP:
        usage(stdout);
        exit(0);
    case OPT_VERSION:
        printf(PROG " " PACKAGE_VERSION " (format %u; inflate: %s; mpi: %s)\n",
               TVPAL_FORMAT_VERSION, tvpal_input_inflate_library(),
               tvpal_comm_mpi_built() ? "yes" : "no");
        exit(0);
    }
    die_usage("--%s \"%s\": expected %s", sp->name, arg, sp->expect);
}

/* Parses the command line into o (defaults first); INPUT... are the
 * arguments after the options.  Returns whether --dims was given. */
static int parse_options(int argc, char **argv, struct opts *o)
{
    struct option lopts[NOPTS + 1];
    char shortopts[2 * NOPTS + 1], *so = shortopts;
    int have_dims = 0, c;
    *o = (struct opts){.type = TVPAL_F32, .window = 4, .nodes = 1,
                       .table_format = TVPAL_TABLE_F32};
    for (size_t i = 0; i < NOPTS; i++) {
        const struct optspec *sp = &g_optspec[i];
        int arg = sp->kind != OPT_FLAG && sp->kind != OPT_HELP &&
                  sp->kind != OPT_VERSION;
        lopts[i] = (struct option){sp->name, arg ? required_argument
                                                  : no_argument, 0, sp->key};
        if (sp->key < OPT_LONG_ONLY) {
            *so++ = (char)sp->key;
            if (arg)
                *so++ = ':';
        }
    }
    lopts[NOPTS] = (struct option){0, 0, 0, 0};
    *so = 0;
    while ((c = getopt_long(argc, argv, shortopts, lopts, NULL)) != -1) {
        size_t i = 0;
        while (i < NOPTS && g_optspec[i].key != c)
            i++;
        if (i == NOPTS) { /* getopt_long has said what was wrong */
            fprintf(stderr, "Try '" PROG " --help'.\n");
            exit(TVPAL_EXIT_USAGE);
        }
        parse_option(&g_optspec[i], optarg, o);
        have_dims |= g_optspec[i].kind == OPT_DIMS;
        o->have_type |= g_optspec[i].kind == OPT_TYPE;
        o->have_endian |= g_optspec[i].key == 'e';
    }
    o->inputs = argv + optind;
    o->ninputs = argc - optind;
    return have_dims;
}

/* Every rule between options and arguments: what is required, what
 * conflicts, what the build cannot do.  Ends the program (exit 2) on the
 * first broken rule, before anything is read or written. */
static void validate_opts(const struct opts *o, int have_dims,
                          uint32_t input_steps)
{
    if (!have_dims)
        die_usage("--dims NXxNYxNZ is required for raw input (try --help)");
    if (!o->outdir || !*o->outdir)
        die_usage("-o OUTDIR is required (try --help)");
    if (o->ninputs < 1)
        die_usage("no INPUT files given (one raw file per timestep, or "
                  "NetCDF or VTK files)");
    if (o->steps_single && o->ninputs != 1)
        die_usage("--steps T takes exactly one INPUT holding all T timesteps "
                  "(%d given)", o->ninputs);
    const uint32_t *d = o->dims;
    const uint32_t mind = d[0] < d[1] ? (d[0] < d[2] ? d[0] : d[2])
                                      : (d[1] < d[2] ? d[1] : d[2]);
    for (unsigned a = 0; a < 3; a++)
        if (o->nodes > d[a])
            die_usage("--nodes %u: larger than the %c axis (%u slices); "
                      "expected at most %u", o->nodes, "xyz"[a], d[a], mind);
    if (strchr(o->outdir, '\n'))
        die_usage("-o: a newline in the path is not supported");
    const uint64_t step_bytes = (uint64_t)d[0] * d[1] * d[2] *
                                tvpal_type_size(o->type);
    const uint32_t T = input_steps ? input_steps
                       : o->steps_single ? o->steps_single
                                         : (uint32_t)o->ninputs;
    if (step_bytes > (uint64_t)INT64_MAX / T)
        die_usage("--steps %u of %ux%ux%u %s: total size overflows", T,
                  d[0], d[1], d[2], tvpal_type_name(o->type));
    if (o->klt && !tvpal_eig_available())
        die_usage("--transform klt: built without LAPACK (install "
                  "liblapack-dev and reconfigure)");
}

/* Text of the options that decide the output bytes: with the inputs, the
 * job's fingerprint (tvpal_checkpoint_fingerprint).  Malloc'ed. */
static char *job_params(const struct opts *o, const struct tvpal_input *in)
{
    char *s = NULL, *t = NULL;
    int n = asprintf(&s, "table=%d refine=%u naive=%d klt=%d alloc=%d "
                     "dims=%ux%ux%u type=%s endian=%s window=%u nodes=%u "
                     "steps=%u nan_as=%s%.17g", o->table_format, o->refine,
                     o->naive, o->klt, o->alloc_mse, o->dims[0], o->dims[1],
                     o->dims[2], tvpal_type_name(o->type),
                     o->big_endian ? "big" : "little", o->window, o->nodes,
                     o->steps_single, o->has_nan_as ? "" : "none:",
                     o->has_nan_as ? o->nan_as : 0.0);
    if (n < 0)
        return NULL;
    for (unsigned i = 0; i < o->nmissing; i++) {
        n = asprintf(&t, "%s missing=%.9g", s, (double)(float)o->missing[i]);
        free(s);
        if (n < 0)
            return NULL;
        s = t;
    }
    if (!in)
        return s;
    /* Raw jobs keep the fingerprint of earlier versions (their partial
     * outputs still resume). */
    n = asprintf(&t, "%s format=%s var=%s", s, tvpal_input_format_name(o->format),
                 tvpal_input_info(in)->var);
    free(s);
    return n < 0 ? NULL : t;
}

/* The manifest's "options" line: the command-line form of job_params. */
static void options_line(const struct opts *o, uint32_t T, char *buf,
                         size_t cap)
{
    size_t n = (size_t)snprintf(
        buf, cap, "--dims %ux%ux%u --type %s --endian %s --window %u "
        "--nodes %u%s", o->dims[0], o->dims[1], o->dims[2],
        tvpal_type_name(o->type), o->big_endian ? "big" : "little",
        o->window, o->nodes, o->steps_single ? " --steps" : "");
#define OPTS_ADD(...)                                                         \
    do {                                                                      \
        if (n < cap)                                                          \
            n += (size_t)snprintf(buf + n, cap - n, __VA_ARGS__);             \
    } while (0)
    if (o->steps_single)
        OPTS_ADD(" %u", T);
    if (o->has_nan_as)
        OPTS_ADD(" --nan-as %.17g", o->nan_as);
    for (unsigned i = 0; i < o->nmissing; i++)
        OPTS_ADD(" --missing %.9g", (double)(float)o->missing[i]);
    if ((uint32_t)o->table_format == TVPAL_TABLE_U16)
        OPTS_ADD(" --table u16");
    if (o->refine)
        OPTS_ADD(" --refine %u", o->refine);
    if (o->naive)
        OPTS_ADD(" --naive");
    if (o->klt)
        OPTS_ADD(" --transform klt");
    if (o->alloc_mse)
        OPTS_ADD(" --alloc greedy-mse");
#undef OPTS_ADD
}

/* ------------------------------------------------------------------ state */

struct shardjob {
    unsigned axis;
    uint32_t rank;
    struct tvpal_shard_header h;
    struct tvpal_shardw *w;  /* placed writer (tvpal_shard.h) */
};

/* A group of `count` slices slice, slice + N, ... of one shard, all with
 * windows of length len starting at the current step; their chunks' CRCs
 * go to jcrc[crc_at ..].  Slices of the x axis are grouped so that one pass
 * over the box rows gathers them all (they share cache lines); other axes
 * use groups of one. */
struct slicejob {
    struct shardjob *sj;
    uint32_t slice;
    uint32_t count;
    uint32_t len;
    size_t crc_at;
};

/* Most slices per group: those of one 64-byte line of x (16 floats). */
#define GROUP_SPAN 16u

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
    /* Shards: 3 axes x K nodes, axis-major (every node's, or one rank's). */
    struct shardjob *sj;
    uint32_t nshard;
    size_t max_slice_vox, max_jobs;
    uint64_t max_chunk;      /* bytes of the largest chunk */
    /* The memory plan and the pass being encoded. */
    uint64_t limit;
    char limit_why[128];
    struct encode_plan plan;
    const struct encode_pass *pass;
    /* Workspaces: per thread, then shared. */
    int nthreads;
    uint64_t **fine_local;   /* per-thread source histograms */
    size_t group_cap;        /* floats of samples per thread */
    struct tvpal_swenc **enc;
    float **samples, **tables;
    unsigned char **chunkbuf;   /* per thread: one chunk */
    unsigned char **scratch;    /* per thread: READ_BLOCK bytes (raw) */
    struct slicejob *jobs;   /* max_jobs */
    uint32_t *jcrc;          /* CRC of every chunk of a step */
    float **ring;            /* N timesteps of the pass's box, step t at
                              * t % N, box voxels x fastest */
    float *boxbuf;           /* a self-describing input's box, as read */
    struct tvpal_input *in;  /* self-describing input, or NULL (raw) */
    struct prefetch *pf;     /* reads the input's next step meanwhile */
    uint64_t *dropped;       /* per thread: present values coded missing */
    double *times;           /* [T] time values, or NULL (none known) */
    char time_units[128];
    double t_encode;         /* seconds of the streaming loop */
    struct progress prog;
    /* Checkpoint copies of the writers' progress (tvpal_checkpoint.h). */
    struct tvpal_checkpoint_progress ckp;
    /* MPI: this rank encodes node `node` only; its node directory while
     * the job runs (also its checkpoint's), and where it goes at the end
     * (--shard-dir; NULL: it stays inside OUTDIR). */
    int mpi;
    uint32_t node;
    char *ckdir;
    char *node_final;
    uint64_t cluster_bytes;  /* rank 0: bytes of every rank's shards, */
    uint64_t cluster_work;   /* the voxel-samples they encoded, */
    double cluster_seconds;  /* in this many seconds (the slowest) */
};

static uint32_t fine_bin(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
    return u >> 16;
}

static float fine_bin_value(uint32_t b)
{
    uint32_t k = (b << 16) | 0x8000u, u;
    u = (k & 0x80000000u) ? (k & 0x7FFFFFFFu) : ~k;
    float f;
    memcpy(&f, &u, 4);
    return f;
}

/* ------------------------------------------------------------- input I/O */

/* What the threads reading a box found. */
struct loaded {
    uint64_t bad;            /* lowest volume voxel index of a data error */
    int rc;                  /* its code (TVPAL_E_NAN or _RANGE), or 0 */
    int read_err;            /* errno of a failed read, -1 at end of file */
    size_t nrep;             /* values replaced by --nan-as */
    size_t nmiss;            /* missing values (NaN after conversion) */
    double lo, hi;           /* range including the stats' so far */
};

/* Per-thread findings, merged into struct loaded after the loop. */
struct found {
    uint64_t bad;
    int rc, read_err;
    size_t nrep, nmiss;
    double lo, hi;
};

/* Converts n source values at src (type and byte order of the job, or
 * host float32 when `host_f32`) into dst, applies --missing, and counts
 * them into the thread's statistics when `stats`.  vox0 is the volume
 * index of the first, for the error message. */
static void convert_run(const struct run *r, const void *src, int host_f32,
                        size_t n, float *dst, uint64_t vox0, int stats,
                        int tid, struct found *f)
{
    const struct opts *o = &r->o;
    size_t bad = 0, rep = 0;
    int rc = tvpal_raw_convert(src, host_f32 ? TVPAL_F32 : o->type,
#ifdef WORDS_BIGENDIAN
                               host_f32 ? 1 : o->big_endian,
#else
                               host_f32 ? 0 : o->big_endian,
#endif
                               n, dst, o->has_nan_as ? &o->nan_as : NULL,
                               &bad, &rep);
    if (rc < 0) {
        if (vox0 + bad < f->bad) {
            f->bad = vox0 + bad;
            f->rc = rc;
        }
        return;
    }
    if (o->nmissing) {
        size_t hits = tvpal_missing_apply(dst, n, o->missing, o->nmissing,
                                          o->has_nan_as ? &o->nan_as : NULL);
        rep += o->has_nan_as ? hits : 0;
    }
    if (!stats)
        return;
    uint64_t *fine = r->fine_local[tid];
    double lo = f->lo, hi = f->hi;
    f->nrep += rep;
    for (size_t i = 0; i < n; i++) {
        float v = dst[i];
        if (v != v) { /* missing: in no figure */
            f->nmiss++;
            continue;
        }
        lo = v < lo ? v : lo;
        hi = v > hi ? v : hi;
        fine[fine_bin(v)]++;
    }
    f->lo = lo;
    f->hi = hi;
}

/* Reads file range [off, off + n) into buf; 0, or errno (-1: the file
 * ended first). */
static int pread_full(int fd, void *buf, size_t n, off_t off)
{
    for (size_t got = 0; got < n;) {
        ssize_t k = pread(fd, (char *)buf + got, n - got, off + (off_t)got);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return k < 0 ? errno : -1;
        got += (size_t)k;
    }
    return 0;
}

/* The box b of the raw timestep at file offset base of fd into dst (box
 * voxels, x fastest), converted, in parallel over blocks of rows: each
 * z-plane of the box is read as the one file range that holds its rows
 * (a y or z slab: only its bytes; an x slab: whole rows, its part used),
 * in pieces of at most READ_BLOCK bytes, into the reading thread's
 * scratch. */
static void read_box_raw(struct run *r, int fd, off_t base,
                         const struct encode_box *b, float *dst, int stats,
                         struct loaded *res)
{
    const struct opts *o = &r->o;
    const size_t esz = tvpal_type_size(o->type);
    const size_t nx = o->dims[0], ny = o->dims[1];
    const size_t row_bytes = nx * esz;
    /* Rows per piece: a piece spans whole rows of one plane. */
    size_t rows = READ_BLOCK / row_bytes;
    if (rows < 1)
        rows = 1;
    if (rows > b->n[1])
        rows = b->n[1];
    const size_t pieces_per_plane = (b->n[1] + rows - 1) / rows;
    const size_t npieces = pieces_per_plane * b->n[2];
    struct found all = {UINT64_MAX, 0, 0, 0, 0, r->st.vmin, r->st.vmax};
#ifdef _OPENMP
#pragma omp parallel
#endif
    {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        struct found f = {UINT64_MAX, 0, 0, 0, 0, all.lo, all.hi};
        unsigned char *buf = r->scratch[tid];
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 1)
#endif
        for (size_t p = 0; p < npieces; p++) {
            if (f.read_err)
                continue;
            const size_t z = b->lo[2] + p / pieces_per_plane;
            const size_t y0 = b->lo[1] + p % pieces_per_plane * rows;
            size_t yn = b->lo[1] + b->n[1] - y0;
            yn = yn < rows ? yn : rows;
            /* From the first row's first voxel to the last row's last. */
            const uint64_t v0 = b->lo[0] + nx * (y0 + ny * z);
            const size_t span = ((yn - 1) * nx + b->n[0]) * esz;
            int err = pread_full(fd, buf, span, base + (off_t)(v0 * esz));
            if (err) {
                f.read_err = err;
                continue;
            }
            for (size_t k = 0; k < yn; k++) {
                const size_t yb = y0 + k - b->lo[1], zb = z - b->lo[2];
                float *out = dst + (size_t)b->n[0] * (yb + (size_t)b->n[1] * zb);
                convert_run(r, buf + k * row_bytes, 0, b->n[0], out,
                            v0 + k * nx, stats, tid, &f);
            }
        }
#ifdef _OPENMP
#pragma omp critical(tvpal_found)
#endif
        {
            if (f.bad < all.bad) {
                all.bad = f.bad;
                all.rc = f.rc;
            }
            if (f.read_err && !all.read_err)
                all.read_err = f.read_err;
            all.nrep += f.nrep;
            all.nmiss += f.nmiss;
            all.lo = f.lo < all.lo ? f.lo : all.lo;
            all.hi = f.hi > all.hi ? f.hi : all.hi;
        }
    }
    *res = (struct loaded){all.bad, all.rc, all.read_err, all.nrep,
                           all.nmiss, all.lo, all.hi};
}

/* The box b of a self-describing step, already read into src (host
 * float32, box voxels), checked and converted into dst in parallel. */
static void convert_box(struct run *r, const float *src,
                        const struct encode_box *b, float *dst, int stats,
                        struct loaded *res)
{
    const size_t rows = (size_t)b->n[1] * b->n[2];
    const size_t nx = r->o.dims[0], ny = r->o.dims[1];
    struct found all = {UINT64_MAX, 0, 0, 0, 0, r->st.vmin, r->st.vmax};
#ifdef _OPENMP
#pragma omp parallel
#endif
    {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        struct found f = {UINT64_MAX, 0, 0, 0, 0, all.lo, all.hi};
#ifdef _OPENMP
#pragma omp for schedule(static)
#endif
        for (size_t k = 0; k < rows; k++) {
            const size_t y = b->lo[1] + k % b->n[1], z = b->lo[2] + k / b->n[1];
            const size_t at = k * b->n[0];
            convert_run(r, src + at, 1, b->n[0], dst + at,
                        b->lo[0] + nx * (y + ny * z), stats, tid, &f);
        }
#ifdef _OPENMP
#pragma omp critical(tvpal_found)
#endif
        {
            if (f.bad < all.bad) {
                all.bad = f.bad;
                all.rc = f.rc;
            }
            all.nrep += f.nrep;
            all.nmiss += f.nmiss;
            all.lo = f.lo < all.lo ? f.lo : all.lo;
            all.hi = f.hi > all.hi ? f.hi : all.hi;
        }
    }
    *res = (struct loaded){all.bad, all.rc, 0, all.nrep, all.nmiss, all.lo,
                           all.hi};
}

/* Whether box b is the whole volume (read with tvpal_input_read). */
static int box_is_whole(const struct run *r, const struct encode_box *b)
{
    return b->n[0] == r->o.dims[0] && b->n[1] == r->o.dims[1] &&
           b->n[2] == r->o.dims[2];
}

/* A self-describing input is read (and inflated) by its library on one
 * thread; the encoding of a step runs on all of them.  One reader thread
 * reads the box of step t + 1 while step t is converted and encoded, so
 * the two overlap.  The reader is the only thread that calls the input
 * library once it runs (HDF5 and libnetcdf builds need not be
 * thread-safe). */
struct prefetch {
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    struct tvpal_input *in;
    float *buf;              /* box floats: the step being read or read */
    struct encode_box box;   /* what to read */
    int whole;               /* the box is the volume */
    int64_t want, ready;     /* step asked for / in buf (-1: none) */
    int busy, quit, rc;
    struct tvpal_diag d;
};

static int read_input_box(struct tvpal_input *in, uint32_t t,
                          const struct encode_box *b, int whole, float *dst,
                          struct tvpal_diag *d)
{
    return whole ? tvpal_input_read(in, t, dst, d)
                 : tvpal_input_read_box(in, t, b->lo, b->n, dst, d);
}

static void *prefetch_main(void *arg)
{
    struct prefetch *pf = arg;
    pthread_mutex_lock(&pf->mu);
    for (;;) {
        while (!pf->quit && pf->want < 0)
            pthread_cond_wait(&pf->cv, &pf->mu);
        if (pf->quit)
            break;
        int64_t t = pf->want;
        pf->want = -1;
        pf->busy = 1;
        struct encode_box box = pf->box;
        int whole = pf->whole;
        pthread_mutex_unlock(&pf->mu);
        struct tvpal_diag d = {{0}};
        int rc = read_input_box(pf->in, (uint32_t)t, &box, whole, pf->buf, &d);
        pthread_mutex_lock(&pf->mu);
        pf->busy = 0;
        pf->ready = t;
        pf->rc = rc;
        pf->d = d;
        pthread_cond_broadcast(&pf->cv);
    }
    pthread_mutex_unlock(&pf->mu);
    return NULL;
}

/* Starts the reader with a buffer of `voxels` floats (NULL when threads
 * are not available: then every step is read in place). */
static struct prefetch *prefetch_start(struct tvpal_input *in, uint64_t voxels)
{
    struct prefetch *pf = calloc(1, sizeof *pf);
    if (!pf || !(pf->buf = malloc(voxels * sizeof(float)))) {
        free(pf);
        return NULL;
    }
    pf->in = in;
    pf->want = pf->ready = -1;
    pthread_mutex_init(&pf->mu, NULL);
    pthread_cond_init(&pf->cv, NULL);
    if (pthread_create(&pf->thread, NULL, prefetch_main, pf) != 0) {
        free(pf->buf);
        free(pf);
        return NULL;
    }
    return pf;
}

static void prefetch_stop(struct prefetch *pf)
{
    if (!pf)
        return;
    pthread_mutex_lock(&pf->mu);
    pf->quit = 1;
    pthread_cond_broadcast(&pf->cv);
    pthread_mutex_unlock(&pf->mu);
    pthread_join(pf->thread, NULL);
    pthread_mutex_destroy(&pf->mu);
    pthread_cond_destroy(&pf->cv);
    free(pf->buf);
    free(pf);
}

/* The pass's box of step t of the input into r->boxbuf: from the reader
 * when it has it (the buffers are swapped), else read here; then step
 * t + 1 of the same pass is asked for. */
static int input_step(struct run *r, uint32_t t, struct tvpal_diag *d)
{
    struct prefetch *pf = r->pf;
    const struct encode_box *b = &r->pass->box;
    const int whole = box_is_whole(r, b);
    int rc = 1;
    if (pf) {
        pthread_mutex_lock(&pf->mu);
        while (pf->busy || pf->want >= 0)
            pthread_cond_wait(&pf->cv, &pf->mu);
        if (pf->ready == (int64_t)t &&
            !memcmp(&pf->box, b, sizeof *b)) {
            float *tmp = r->boxbuf;
            r->boxbuf = pf->buf;
            pf->buf = tmp;
            rc = pf->rc;
            *d = pf->d;
        }
        pf->ready = -1;
        pthread_mutex_unlock(&pf->mu);
    }
    if (rc > 0) /* not read ahead: the reader is idle, so this is safe */
        rc = read_input_box(r->in, t, b, whole, r->boxbuf, d);
    if (pf && t + 1 < r->T) {
        pthread_mutex_lock(&pf->mu);
        pf->box = *b;
        pf->whole = whole;
        pf->want = t + 1;
        pthread_cond_broadcast(&pf->cv);
        pthread_mutex_unlock(&pf->mu);
    }
    return rc;
}

/* Reads the pass's box of timestep t of the source into dst (converted),
 * accounting stats when the pass keeps them and t is not yet in them.  A
 * read error ends the program keeping the partial output (maybe
 * transient); bad data ends it removing it. */
static void load_step(struct run *r, uint32_t t, float *dst)
{
    const struct opts *o = &r->o;
    const struct encode_box *b = &r->pass->box;
    /* Raw: a file per step, or one of them all; a reader knows its own. */
    const char *path = r->in || o->steps_single ? o->inputs[0] : o->inputs[t];
    const off_t off = o->steps_single ? (off_t)t * (off_t)r->step_bytes : 0;
    const int stats = r->pass->stats && t >= r->st.loaded;
    struct loaded res;
    if (r->in) {
        uint32_t k;
        struct tvpal_diag d = {{0}};
        path = tvpal_input_file(r->in, t, &k);
        int rc = input_step(r, t, &d);
        if (rc < 0) /* the file changed or is corrupt: a rerun fails too */
            die_input("timestep %u (step %u of %s): %s", t, k, path,
                      lib_error(rc, &d));
        convert_box(r, r->boxbuf, b, dst, stats, &res);
    } else {
        struct tvpal_diag d = {{0}};
        int fd = tvpal_open_regular(path, &d);
        if (fd < 0)
            /* maybe transient (NFS, permissions): keep the partial */
            die_fail("cannot open %s (rerun to resume)", d.msg);
        read_box_raw(r, fd, off, b, dst, stats, &res);
        close(fd);
    }
    if (res.read_err > 0)
        die_fail("%s: timestep %u: %s (rerun to resume)", path, t,
                 strerror(res.read_err));
    if (res.read_err)
        die_input("%s: timestep %u: file shrank while encoding (truncated)",
                  path, t);
    if (res.rc < 0) {
        uint64_t x = res.bad % o->dims[0], y = res.bad / o->dims[0] % o->dims[1],
                 z = res.bad / o->dims[0] / o->dims[1];
        if (res.rc == TVPAL_E_NAN)
            die_input("%s: timestep %u: infinite value at voxel "
                      "(%llu,%llu,%llu); expected finite values or NaN for "
                      "missing ones (use --nan-as VALUE to replace them)",
                      path, t, (unsigned long long)x, (unsigned long long)y,
                      (unsigned long long)z);
        die_input("%s: timestep %u: value at voxel (%llu,%llu,%llu) exceeds "
                  "the supported magnitude %g", path, t,
                  (unsigned long long)x, (unsigned long long)y,
                  (unsigned long long)z, TVPAL_VALUE_MAX);
    }
    if (!stats)
        return;
    for (int id = 0; id < r->nthreads; id++)
        for (uint32_t k = 0; k < TVPAL_CHECKPOINT_BINS; k++) {
            r->st.fine[k] += r->fine_local[id][k];
            r->fine_local[id][k] = 0;
        }
    r->st.nonfinite += res.nrep;
    r->st.missing += res.nmiss;
    r->st.counted += encode_box_voxels(b);
    r->st.vmin = res.lo;
    r->st.vmax = res.hi;
    r->st.loaded = t + 1;
}

static int natural_qsort_cmp(const void *a, const void *b)
{
    return tvpal_natural_cmp(*(char *const *)a, *(char *const *)b);
}

/* Inputs are encoded in the order given.  A shell glob sorts density_10
 * before density_2: --sort natural puts them in numeric order; without it
 * the first pair out of that order is named (a warning, not an error:
 * the order may be meant). */
static void order_inputs(struct opts *o)
{
    if (o->sort_natural) {
        qsort(o->inputs, (size_t)o->ninputs, sizeof *o->inputs,
              natural_qsort_cmp);
        return;
    }
    for (int i = 0; i + 1 < o->ninputs; i++)
        if (tvpal_natural_cmp(o->inputs[i], o->inputs[i + 1]) > 0) {
            msg("warning: the inputs are not in natural order: %s comes "
                "before %s (they are encoded in the order given; --sort "
                "natural sorts them)", o->inputs[i], o->inputs[i + 1]);
            return;
        }
}

/* A self-describing input (NetCDF, VTK ImageData: tvpal_input.h) says its
 * dims and steps itself; --dims and --type, for raw input, must then agree
 * with it, and --steps and --endian do not apply.  The reader delivers
 * float32 in host order, which the encoder then takes as a raw f32 source.
 * Sets r->in, or leaves it NULL for raw input; returns whether the dims are
 * known. */
static int open_source(struct run *r, int have_dims)
{
    struct opts *o = &r->o;
    struct tvpal_diag d = {{0}};
    enum tvpal_input_format f = o->format;
    struct tvpal_input_opts io = {.var = o->var, .time_dim = o->time_dim};
    if (o->ninputs < 1)
        return have_dims;
    if (f == TVPAL_IN_AUTO && tvpal_input_detect(o->inputs[0], &io, &f, &d) < 0)
    {
        /* d says "PATH: cause" */
        size_t n = strlen(o->inputs[0]);
        const char *cause = !strncmp(d.msg, o->inputs[0], n) &&
                                    !strncmp(d.msg + n, ": ", 2)
                                ? d.msg + n + 2 : d.msg;
        die_usage("%s: cannot read input: %s", o->inputs[0], cause);
    }
    if (f == TVPAL_IN_RAW) {
        if (o->var || o->time_dim)
            die_usage("--var and --time-dim: for self-describing input "
                      "(NetCDF, VTK); %s is raw", o->inputs[0]);
        return have_dims;
    }
    int rc = tvpal_input_open(&r->in, f, o->inputs, o->ninputs, &io, &d);
    if (rc < 0)
        die_usage("%s", lib_error(rc, &d));
    const struct tvpal_input_info *in = tvpal_input_info(r->in);
    if (have_dims && memcmp(o->dims, in->dims, sizeof in->dims))
        die_usage("%s: variable %s is %ux%ux%u; --dims says %ux%ux%u",
                  o->inputs[0], in->var, in->dims[0], in->dims[1],
                  in->dims[2], o->dims[0], o->dims[1], o->dims[2]);
    if (o->have_type && o->type != in->type)
        die_usage("%s: variable %s is %s; --type says %s", o->inputs[0],
                  in->var, tvpal_type_name(in->type),
                  tvpal_type_name(o->type));
    if (o->steps_single || o->have_endian)
        die_usage("--steps and --endian: for raw input only (%s is %s: it "
                  "says its own steps and byte order)", o->inputs[0],
                  tvpal_input_format_name(f));
    for (unsigned a = 0; a < 3; a++)
        if (in->nonuniform[a])
            msg("warning: %s: the %c axis (%s) is not evenly spaced; the "
                "grid is taken as evenly spaced in index", o->inputs[0],
                "xyz"[a], in->dim_names[a][0] ? in->dim_names[a] : "?");
    memcpy(o->dims, in->dims, sizeof o->dims);
    o->type = TVPAL_F32;
    o->big_endian = 0;
    o->format = tvpal_input_format(r->in);
#ifdef WORDS_BIGENDIAN
    o->big_endian = 1;
#endif
    return 1;
}

/* The steps' time values: --times FILE (T rising numbers, any white
 * space between them), else a time coordinate of the input, else none
 * (the manifest then says nothing and the steps are their indices). */
static void load_times(struct run *r)
{
    const struct opts *o = &r->o;
    const struct tvpal_input_info *in = r->in ? tvpal_input_info(r->in) : NULL;
    if (!o->times_file && !(in && in->has_times))
        return;
    if (!(r->times = malloc(sizeof *r->times * r->T)))
        die_fail("out of memory");
    snprintf(r->time_units, sizeof r->time_units, "%s",
             o->time_units ? o->time_units : in ? in->time_units : "");
    for (char *c = r->time_units; *c; c++) /* one manifest line */
        if ((unsigned char)*c < ' ')
            *c = ' ';
    if (!o->times_file) {
        for (uint32_t t = 0; t < r->T; t++)
            r->times[t] = tvpal_input_time(r->in, t);
        return;
    }
    struct tvpal_diag d = {{0}};
    int rc;
    FILE *f = tvpal_fopen_text(o->times_file, &rc, &d);
    if (!f)
        die_usage("--times %s", d.msg);
    uint32_t n = 0;
    double v;
    while (n <= r->T && fscanf(f, "%lf", &v) == 1) {
        if (!isfinite(v) || (n > 0 && n < r->T && v <= r->times[n - 1]))
            die_usage("--times %s: value %u (%g): expected a finite number "
                      "larger than the one before", o->times_file, n + 1, v);
        if (n < r->T)
            r->times[n] = v;
        n++;
    }
    int junk = !feof(f);
    fclose(f);
    if (junk || n != r->T)
        die_usage("--times %s: %s%u numbers; expected %u, one per step",
                  o->times_file, junk ? "not a number after " : "", n, r->T);
}

/* Windows that straddle a gap in time cost accuracy there (the DCT sees a
 * jump): warn when an interval is more than twice a neighbouring one,
 * naming the steps. */
static void warn_irregular_times(const struct run *r)
{
    char list[160] = "";
    size_t len = 0;
    unsigned found = 0;
    for (uint32_t i = 0; r->times && i + 1 < r->T; i++) {
        double d = r->times[i + 1] - r->times[i];
        int gap = (i > 0 && d > 2 * (r->times[i] - r->times[i - 1])) ||
                  (i + 2 < r->T && d > 2 * (r->times[i + 2] - r->times[i + 1]));
        if (!gap)
            continue;
        if (found++ < 4 && len < sizeof list)
            len += (size_t)snprintf(list + len, sizeof list - len, "%s%u-%u",
                                    found > 1 ? ", " : "", i, i + 1);
    }
    if (found)
        msg("warning: irregular time intervals: %u interval%s more than twice "
            "a neighbour's (steps %s%s); windows that straddle a gap lose "
            "accuracy there", found, found == 1 ? " is" : "s are", list,
            found > 4 ? ", ..." : "");
}

/* Checks the inputs before any output exists: regular readable files of
 * the expected size, named by absolute paths from then on (the manifest
 * must name them from anywhere). */
static void check_inputs(struct run *r)
{
    struct opts *o = &r->o;
    const uint64_t want = o->steps_single ? r->step_bytes * r->T
                                          : r->step_bytes;
    if (!(r->abs_inputs = calloc((size_t)o->ninputs, sizeof *r->abs_inputs)))
        die_fail("out of memory");
    for (int i = 0; i < o->ninputs; i++) {
        struct stat st;
        const char *p = o->inputs[i];
        if (strchr(p, '\n'))
            die_usage("%s: a newline in a file name is not supported", p);
        if (stat(p, &st) < 0)
            die_usage("%s: cannot read input: %s", p, strerror(errno));
        if (!S_ISREG(st.st_mode))
            die_usage("%s: not a regular file", p);
        if (access(p, R_OK) < 0)
            die_usage("%s: cannot read input: %s", p, strerror(errno));
        if (!r->in && (uint64_t)st.st_size != want) {
            if (o->steps_single)
                die_usage("%s: size is %lld bytes; expected %llu (%u timesteps "
                          "of %ux%ux%u %s)", p, (long long)st.st_size,
                          (unsigned long long)want, r->T, o->dims[0],
                          o->dims[1], o->dims[2], tvpal_type_name(o->type));
            die_usage("%s: size is %lld bytes; expected %llu (one %ux%ux%u %s "
                      "timestep)", p, (long long)st.st_size,
                      (unsigned long long)want, o->dims[0], o->dims[1],
                      o->dims[2], tvpal_type_name(o->type));
        }
        if (!(r->abs_inputs[i] = realpath(p, NULL)))
            die_usage("%s: %s", p, strerror(errno));
    }
    o->inputs = r->abs_inputs;
}

/* ---------------------------------------------------------------- output */

/* Refuses an output that would destroy what it must not: an existing
 * OUTDIR without --force, any input (OUTDIR, its .partial and .old may all
 * be removed), or with --force anything but a tvpal dataset.  Sets
 * r->partial. */
static void check_output(struct run *r)
{
    const struct opts *o = &r->o;
    static const char *const sfx[] = {"", ".partial", ".old"};
    if (asprintf(&r->partial, "%s.partial", o->outdir) < 0)
        die_fail("out of memory");
    if (tvpal_exists(o->outdir) && !o->force)
        die_usage("%s: output already exists (use --force to replace it)",
                  o->outdir);
    for (int k = 0; k < 3; k++) {
        char *p = NULL, *abs_p;
        if (asprintf(&p, "%s%s", o->outdir, sfx[k]) < 0)
            die_fail("out of memory");
        if ((abs_p = realpath(p, NULL))) {
            size_t n = strlen(abs_p);
            for (int i = 0; i < o->ninputs; i++)
                if (!strncmp(o->inputs[i], abs_p, n) &&
                    (o->inputs[i][n] == '/' || o->inputs[i][n] == 0))
                    die_usage("%s: input %s is or lies inside %s; "
                              "refusing to replace it", o->outdir,
                              o->inputs[i], p);
            free(abs_p);
        }
        free(p);
    }
    if (tvpal_exists(o->outdir)) {
        char *mp = NULL;
        struct tvpal_manifest old;
        if (asprintf(&mp, "%s/manifest.txt", o->outdir) < 0)
            die_fail("out of memory");
        if (tvpal_manifest_load(mp, &old, NULL) < 0)
            die_usage("%s: exists and is not a tvpal dataset (no valid "
                      "manifest.txt); refusing to replace it", o->outdir);
        tvpal_manifest_clear(&old);
        free(mp);
    }
}

/* Creates OUTDIR.partial/node-R/ for every node (after which bad input
 * removes the partial output, see die_input). */
static char *node_partial(const struct run *r, uint32_t k);

static void make_node_dirs(struct run *r)
{
    for (uint32_t k = r->mpi ? r->node : 0;
         k < (r->mpi ? r->node + 1 : r->o.nodes); k++) {
        struct tvpal_diag d = {{0}};
        char *nd = node_partial(r, k);
        int rc = !nd ? TVPAL_E_NOMEM : tvpal_mkdirs(nd, &d);
        if (rc < 0)
            die_usage("%s: cannot create output directory: %s", r->partial,
                      lib_error(rc, &d));
        free(nd);
    }
    g_partial = r->mpi ? r->ckdir : r->partial;
}

/* Node k's directory while the job runs: OUTDIR.partial/node-k, or with
 * --shard-dir the pattern's directory plus ".partial".  Malloc'ed. */
static char *node_partial(const struct run *r, uint32_t k)
{
    char *d = tvpal_node_dir(r->partial, r->o.shard_pat, k), *p = NULL;
    if (!d || !r->o.shard_pat)
        return d;
    int n = asprintf(&p, "%s.partial", d);
    free(d);
    return n < 0 ? NULL : p;
}

/* Forgets a partial output: statistics and the start go back to nothing,
 * and this process's partial directory is removed (the next steps make
 * the node directories again). */
static void start_over(struct run *r)
{
    r->start = 0;
    tvpal_checkpoint_stats_reset(&r->st);
    if (tvpal_exists(r->ckdir) && tvpal_rmtree(r->ckdir) < 0)
        die_usage("%s: cannot remove stale partial output", r->ckdir);
}

/* Resumes the partial output of the same job from its checkpoint, or
 * removes a partial output that has none usable; then makes the node
 * directories.  Sets r->fp, r->st, r->ckp and r->start.  The plan is part
 * of the job: a rerun under another limit or thread count starts over. */
static void open_partial(struct run *r)
{
    char *params = job_params(&r->o, r->in), *withplan = NULL;
    char key[96];
    encode_plan_key(&r->plan, key, sizeof key);
    if (r->mpi)
        snprintf(key + strlen(key), sizeof key - strlen(key),
                 " rank=%u", r->node);
    if (!params || asprintf(&withplan, "%s %s", params, key) < 0 ||
        tvpal_checkpoint_fingerprint(withplan, r->o.inputs, r->o.ninputs,
                                     &r->fp) < 0 ||
        tvpal_checkpoint_stats_init(&r->st) < 0)
        die_fail("out of memory");
    free(params);
    free(withplan);
    const size_t n = (size_t)r->nshard * r->T;
    r->ckp = (struct tvpal_checkpoint_progress){
        r->nshard, r->T, calloc(n, sizeof(uint64_t)), calloc(n, sizeof(uint32_t)),
        calloc(r->nshard, 1)};
    if (!r->ckp.filled || !r->ckp.crc || !r->ckp.missing)
        die_fail("out of memory");
    r->start = 0;
    if (tvpal_exists(r->ckdir)) {
        /* A checkpoint that is missing, of another job or damaged is not
         * an error: the job starts over (FORMAT.md 9.2). */
        const uint64_t units = (uint64_t)r->plan.npasses * r->T;
        if (tvpal_checkpoint_load(r->ckdir, r->fp, units, r->T, r->nvox,
                                  &r->start, &r->st, &r->ckp, NULL) < 0 ||
            r->start == 0 || r->start > units)
            start_over(r);
    }
    make_node_dirs(r);
}

/* Describes the 3K shards (axis-major; a rank's 3 under MPI) and the
 * largest slice, chunk and number of slice-windows of a step. */
static void setup_shards(struct run *r)
{
    const struct opts *o = &r->o;
    const uint32_t k0 = r->mpi ? r->node : 0, nk = r->mpi ? 1 : o->nodes;
    r->nshard = 3 * nk;
    if (!(r->sj = calloc(r->nshard, sizeof *r->sj)))
        die_fail("out of memory");
    for (unsigned a = 0; a < 3; a++) {
        uint32_t n, w, h;
        tvpal_axis_geometry(o->dims, a, &n, &w, &h);
        if ((size_t)w * h > r->max_slice_vox)
            r->max_slice_vox = (size_t)w * h;
        r->max_jobs += n;
        uint64_t cb = tvpal_chunk_bytes(r->N, w, h, (uint32_t)o->table_format);
        if (cb > r->max_chunk)
            r->max_chunk = cb;
        for (uint32_t k = k0; k < k0 + nk; k++) {
            struct shardjob *j = &r->sj[a * nk + (k - k0)];
            j->axis = a;
            j->rank = k;
            j->h = (struct tvpal_shard_header){
                .version = TVPAL_FORMAT_VERSION, .steps = r->T,
                .window = r->N, .nodes = o->nodes, .rank = k, .axis = a,
                .slice_w = w, .slice_h = h,
                .table_format = (uint32_t)o->table_format};
            memcpy(j->h.dims, o->dims, sizeof o->dims);
            tvpal_slab_range(n, o->nodes, k, &j->h.slice_begin,
                             &j->h.slice_count);
        }
    }
}

/* ------------------------------------------------------------------ plan */

/* The worker threads: -j, else all cores. */
static void choose_threads(struct run *r)
{
    r->nthreads = 1;
#ifdef _OPENMP
    if (r->o.threads)
        omp_set_num_threads((int)r->o.threads);
    r->nthreads = omp_get_max_threads();
#endif
}

/* Samples per thread: one slice-window, or a group of x slices up to
 * 8 MiB (a group never exceeds GROUP_SPAN slices). */
static size_t group_floats(const struct run *r)
{
    const size_t sw = r->max_slice_vox * r->N;
    if (sw >= (size_t)2 << 20)
        return sw;
    return (size_t)2 << 20 < sw * GROUP_SPAN ? (size_t)2 << 20
                                             : sw * GROUP_SPAN;
}

/* Bytes of a thread's reading scratch (raw input): whole rows of one
 * plane, up to READ_BLOCK (one row at least). */
static uint64_t scratch_bytes(const struct run *r)
{
    const uint64_t row = (uint64_t)r->o.dims[0] * tvpal_type_size(r->o.type);
    uint64_t rows = READ_BLOCK / row;
    rows = rows < 1 ? 1 : rows > r->o.dims[1] ? r->o.dims[1] : rows;
    return rows * row;
}

/* Bytes of everything but the ring and the box buffers: the program and
 * its libraries, and per thread the codec's workspace (its largest: with
 * missing values, --refine or KLT), the samples, a table, a chunk, the
 * reading scratch and the histogram.  An estimate on the safe side, which
 * tests hold against the measured peak. */
static uint64_t fixed_bytes(const struct run *r)
{
    const uint64_t sv = r->max_slice_vox, N = r->N;
    const uint64_t codec = sv * (16 * N + 64) + N * 256 * 16 + (1u << 16);
    const uint64_t scratch = r->in ? 0 : scratch_bytes(r);
    const uint64_t per_thread = codec + group_floats(r) * sizeof(float) +
                                N * 256 * sizeof(float) + r->max_chunk +
                                scratch +
                                TVPAL_CHECKPOINT_BINS * sizeof(uint64_t);
    const uint64_t shards = (uint64_t)r->nshard * r->T * 40 +
                            (uint64_t)r->max_jobs * 40;
    /* A reader's scratch (tvpal_input_box_scratch): the largest box's. */
    const uint64_t reader = r->in ? tvpal_input_box_scratch(r->in, r->o.dims)
                                  : 0;
    /* 16 MiB: the program and its libraries (13 MiB measured). */
    return ((uint64_t)16 << 20) + (uint64_t)r->nthreads * per_thread +
           shards + reader;
}

static void print_size(char *buf, size_t cap, uint64_t b)
{
    if (b >= (uint64_t)1 << 30)
        snprintf(buf, cap, "%.2f GiB", (double)b / (1u << 30));
    else
        snprintf(buf, cap, "%.1f MiB", (double)b / (1u << 20));
}

/* Ranks of this job on this machine, from what the launchers set (Open
 * MPI, MPICH/Hydra, Slurm); 1 outside MPI. */
static unsigned local_ranks(const struct run *r)
{
    static const char *const vars[] = {"OMPI_COMM_WORLD_LOCAL_SIZE",
                                       "MPI_LOCALNRANKS",
                                       "SLURM_NTASKS_PER_NODE"};
    for (unsigned i = 0; r->mpi && i < 3; i++) {
        const char *v = getenv(vars[i]);
        if (v && atoi(v) > 0)
            return (unsigned)atoi(v);
    }
    return 1;
}

/* Makes the memory plan (encode_plan.h) before anything is read or
 * written, and says it; a limit too small for even one slice per pass
 * ends the program (exit 2) with the smallest that would do. */
static void make_plan(struct run *r)
{
    const struct opts *o = &r->o;
    if (o->mem_limit)
        snprintf(r->limit_why, sizeof r->limit_why, "--mem-limit");
    r->limit = o->mem_limit ? o->mem_limit
                            : encode_default_limit(local_ranks(r),
                                                   r->limit_why,
                                                   sizeof r->limit_why);
    struct encode_job j = {
        .N = r->N, .T = r->T, .limit = r->limit, .fixed = fixed_bytes(r),
        .box_bytes_per_voxel = 4 * r->N + (r->in ? 8 : 0), .split = r->mpi};
    memcpy(j.dims, o->dims, sizeof j.dims);
    memcpy(j.slab_n, o->dims, sizeof j.slab_n);
    /* An MPI rank encodes its node's slab of each axis only. */
    for (unsigned a = 0; r->mpi && a < 3; a++)
        tvpal_slab_range(o->dims[a], o->nodes, r->node, &j.slab_lo[a],
                         &j.slab_n[a]);
    char lim[32], need[32], ring[32];
    int rc = encode_plan_make(&j, &r->plan);
    if (rc == TVPAL_E_NOMEM)
        die_fail("out of memory");
    print_size(lim, sizeof lim, r->limit);
    if (rc < 0) {
        print_size(need, sizeof need, r->plan.min_limit);
        die_usage("memory limit %s (%s) is too small for %ux%ux%u at "
                  "--window %u with %d thread%s: one slice per pass needs "
                  "%s; give --mem-limit %lluK or more (or fewer --threads)",
                  lim, r->limit_why, o->dims[0], o->dims[1], o->dims[2],
                  r->N, r->nthreads, r->nthreads == 1 ? "" : "s", need,
                  (unsigned long long)((r->plan.min_limit + 1023) >> 10));
    }
    if (o->quiet || (r->mpi && r->node != 0))
        return;
    char desc[96];
    encode_plan_describe(&r->plan, desc, sizeof desc);
    print_size(need, sizeof need, r->plan.peak);
    print_size(ring, sizeof ring,
               (uint64_t)r->N * r->nvox * sizeof(float) + j.fixed);
    if (r->plan.npasses == 1)
        msg("plan: %s; about %s of the memory limit %s (%s)", desc, need,
            lim, r->limit_why);
    else if (r->mpi)
        msg("plan of rank 0 of %d: %s over its node's slabs, reading %.2f "
            "times the input's bytes (its z and y slabs, and whole rows for "
            "its x slab); about %s of the memory limit %s (%s)",
            g_comm.size, desc,
            (double)r->plan.voxels_read / ((double)r->nvox * r->T), need, lim,
            r->limit_why);
    else
        msg("plan: %s, reading the input %.2f times: one ring of all %u "
            "timesteps of a window would need %s, over the memory limit %s "
            "(%s); each pass needs about %s", desc,
            (double)r->plan.voxels_read / ((double)r->nvox * r->T), r->N,
            ring, lim, r->limit_why, need);
}

/* ---------------------------------------------------------------- output */

/* The file of shard j in its node's directory (malloc'ed). */
static char *shard_path(const struct run *r, const struct shardjob *j)
{
    char *nd = node_partial(r, j->rank), *p = NULL;
    int n = nd ? asprintf(&p, "%s/axis-%c.tvps", nd, "xyz"[j->axis]) : -1;
    free(nd);
    return n < 0 ? NULL : p;
}

/* Creates (start = 0) or reopens the shard writers, restoring a resumed
 * job's progress (read back and verified); reports and returns < 0 on the
 * first failure. */
static int open_writers(struct run *r)
{
    for (uint32_t q = 0; q < r->nshard; q++) {
        struct shardjob *j = &r->sj[q];
        struct tvpal_diag d = {{0}};
        char *path = shard_path(r, j);
        int rc;
        if (!path)
            return TVPAL_E_NOMEM;
        if (r->start)
            rc = tvpal_shardw_reopen_placed(&j->w, path, &j->h, &d);
        else
            rc = tvpal_shardw_create_placed(&j->w, path, &j->h, &d);
        for (uint32_t t = 0; rc == 0 && r->start && t < r->T; t++) {
            size_t i = (size_t)q * r->T + t;
            if (r->ckp.filled[i])
                rc = tvpal_shardw_set_progress(j->w, t, r->ckp.filled[i],
                                               r->ckp.crc[i], &d);
        }
        if (rc == 0 && r->start)
            tvpal_shardw_set_missing(j->w, r->ckp.missing[q]);
        if (rc < 0)
            msg("%s: cannot %s: %s%s%s%s", path,
                r->start ? "resume" : "create", tvpal_strerror(rc),
                d.msg[0] ? " (" : "", d.msg, d.msg[0] ? ")" : "");
        if (rc < 0 && r->start)
            msg("starting the job over");
        free(path);
        if (rc < 0)
            return rc;
    }
    return 0;
}

/* The statistics a checkpoint at unit `u` must hold: every stats pass
 * before it, and the loaded steps of its own. */
static uint64_t expected_counted(const struct run *r, uint64_t u)
{
    uint64_t c = 0;
    const uint32_t p = (uint32_t)(u / r->T);
    for (uint32_t i = 0; i < p && i < r->plan.npasses; i++)
        if (r->plan.pass[i].stats)
            c += encode_box_voxels(&r->plan.pass[i].box) * r->T;
    if (p < r->plan.npasses && r->plan.pass[p].stats)
        c += encode_box_voxels(&r->plan.pass[p].box) * r->st.loaded;
    return c;
}

/* Opens the writers; a partial output that does not verify is removed and
 * the job started over, from empty statistics. */
static void open_or_restart_writers(struct run *r)
{
    if (r->start && r->st.counted != expected_counted(r, r->start)) {
        msg("%s: the checkpoint's statistics do not match its position; "
            "starting the job over", r->ckdir);
        start_over(r);
        make_node_dirs(r);
    }
    while (open_writers(r) < 0) {
        for (uint32_t q = 0; q < r->nshard; q++) {
            tvpal_shardw_free(r->sj[q].w);
            r->sj[q].w = NULL;
        }
        if (!r->start)
            die_input("%s: cannot create the output files", r->ckdir);
        start_over(r);
        make_node_dirs(r);
    }
}

/* ------------------------------------------------------------- workspace */

/* Workspaces of the threads, the ring of N boxes and the box buffers:
 * everything the streaming loop uses, allocated once, for the plan's
 * largest box. */
static void setup_workspace(struct run *r)
{
    const uint32_t N = r->N;
    const size_t nt = (size_t)r->nthreads;
    const uint64_t box = r->plan.box_voxels_max;
    if (!(r->fine_local = calloc(nt, sizeof *r->fine_local)))
        die_fail("out of memory");
    for (size_t i = 0; i < nt; i++)
        if (!(r->fine_local[i] = calloc(TVPAL_CHECKPOINT_BINS,
                                        sizeof(uint64_t))))
            die_fail("out of memory");
    r->group_cap = group_floats(r);
    r->enc = calloc(nt, sizeof *r->enc);
    r->dropped = calloc(nt, sizeof *r->dropped);
    r->samples = calloc(nt, sizeof *r->samples);
    r->tables = calloc(nt, sizeof *r->tables);
    r->chunkbuf = calloc(nt, sizeof *r->chunkbuf);
    r->scratch = calloc(nt, sizeof *r->scratch);
    r->jobs = calloc(r->max_jobs, sizeof *r->jobs);
    r->jcrc = calloc(r->max_jobs, sizeof *r->jcrc);
    r->ring = calloc(N, sizeof *r->ring);
    if (!r->enc || !r->dropped || !r->samples || !r->tables || !r->jobs ||
        !r->ring || !r->chunkbuf || !r->scratch || !r->jcrc)
        die_fail("out of memory");
    for (size_t i = 0; i < nt; i++) {
        if (tvpal_swenc_create(&r->enc[i], r->max_slice_vox, N) < 0 ||
            tvpal_swenc_set_refine(r->enc[i], r->o.refine) < 0 ||
            (tvpal_swenc_set_naive(r->enc[i], r->o.naive),
             tvpal_swenc_set_alloc_mse(r->enc[i], r->o.alloc_mse) < 0))
            die_fail("out of memory");
        if (r->o.klt && tvpal_swenc_set_klt(r->enc[i], 1) < 0)
            die_usage("--transform klt: built without LAPACK (install "
                      "liblapack-dev and reconfigure)");
        if (!(r->samples[i] = malloc(r->group_cap * sizeof(float))) ||
            !(r->tables[i] = malloc(N * 256 * sizeof(float))) ||
            !(r->chunkbuf[i] = malloc(r->max_chunk)) ||
            (!r->in && !(r->scratch[i] = malloc(scratch_bytes(r)))))
            die_fail("out of memory");
    }
    if (r->in && !(r->boxbuf = malloc(box * sizeof(float))))
        die_fail("out of memory for a box of %llu voxels",
                 (unsigned long long)box);
    for (uint32_t i = 0; i < N; i++)
        if (!(r->ring[i] = malloc(box * sizeof(float))))
            die_fail("out of memory for %u timesteps of %llu voxels", N,
                     (unsigned long long)box);
}

/* ---------------------------------------------------------------- encoding */

/* Copies the slices of job jb (timesteps t..t+len-1) from the ring of the
 * pass's box into samples: slice g of the group at samples + g * len *
 * w*h, time-major.  The box holds the slices whole. */
static void gather(const struct run *r, const struct slicejob *jb, uint32_t t,
                   float *samples)
{
    const struct encode_box *b = &r->pass->box;
    const size_t bx = b->n[0], by = b->n[1], bz = b->n[2];
    const unsigned axis = jb->sj->axis;
    const size_t sv = (size_t)jb->sj->h.slice_w * jb->sj->h.slice_h;
    const uint32_t s = jb->slice - b->lo[axis], len = jb->len, N = r->N;
    for (uint32_t j = 0; j < len; j++) {
        const float *vol = r->ring[(t + j) % N];
        float *out = samples + (size_t)j * sv;
        switch (axis) {
        case 0:
            for (size_t z = 0; z < bz; z++)
                for (size_t y = 0; y < by; y++) {
                    const float *row = vol + bx * (y + by * z) + s;
                    float *dst = out + y + by * z;
                    for (uint32_t g = 0; g < jb->count; g++)
                        dst[(size_t)g * len * sv] = row[(size_t)g * N];
                }
            break;
        case 1:
            for (size_t z = 0; z < bz; z++)
                memcpy(out + bx * z, vol + bx * (s + by * z),
                       bx * sizeof *out);
            break;
        default:
            memcpy(out, vol + bx * by * (size_t)s, bx * by * sizeof *out);
            break;
        }
    }
}

/* Encodes one slice-window from samples into the chunk buffer. */
static void encode_chunk(struct tvpal_swenc *enc, float *table,
                         const float *samples, const struct shardjob *j,
                         uint32_t slice, uint32_t t, uint32_t len,
                         unsigned char *chunk, uint64_t *dropped)
{
    const size_t nvox = (size_t)j->h.slice_w * j->h.slice_h;
    const uint32_t tf = j->h.table_format;
    const size_t tbytes = (size_t)len * 256 * tvpal_table_entry_bytes(tf);
    struct tvpal_swinfo info;
    tvpal_swenc_encode(enc, samples, nvox, len,
                       chunk + TVPAL_CHUNK_HEADER_BYTES + tbytes, table, &info);
    *dropped += info.dropped;
    struct tvpal_chunk_header ch = {
        .slice = slice, .wstart = t, .wlen = len, .w = j->h.slice_w,
        .h = j->h.slice_h, .used = info.used};
    tvpal_table_store(table, len, tf, chunk + TVPAL_CHUNK_HEADER_BYTES, &ch);
    memcpy(ch.bits, info.bits, sizeof ch.bits);
    tvpal_chunk_header_encode(&ch, chunk);
    /* Zero the index padding so output bytes are deterministic. */
    size_t ib = TVPAL_CHUNK_HEADER_BYTES + tbytes + nvox;
    size_t cb = tvpal_chunk_bytes(len, j->h.slice_w, j->h.slice_h, tf);
    memset(chunk + ib, 0, cb - ib);
}

/* Lists the slice-windows of the pass that start at step t, shard by
 * shard in slice order (the order their CRCs join), into r->jobs (x slices
 * grouped).  Returns the number of jobs. */
static size_t plan_step(struct run *r, uint32_t t)
{
    const uint32_t N = r->N;
    const struct encode_pass *ps = r->pass;
    struct slicejob *jobs = r->jobs;
    size_t njobs = 0, chunks = 0;
    for (uint32_t q = 0; q < r->nshard; q++) {
        struct shardjob *j = &r->sj[q];
        const unsigned a = j->axis;
        if (!(ps->axes & (1u << a)))
            continue;
        const size_t sv = (size_t)j->h.slice_w * j->h.slice_h;
        uint32_t lo = j->h.slice_begin, hi = lo + j->h.slice_count;
        lo = lo > ps->s0[a] ? lo : ps->s0[a];
        hi = hi < ps->s1[a] ? hi : ps->s1[a];
        for (uint32_t s = lo; s < hi; s++) {
            if (!tvpal_schedule_starts(s, t, N))
                continue;
            uint32_t len = tvpal_schedule_len(s, t, N, r->T);
            struct slicejob *prev = njobs ? &jobs[njobs - 1] : NULL;
            /* Extend the previous x group when this slice is the next of
             * its phase, in the same line, with the same window, and the
             * group's samples stay within the workspace. */
            if (a == 0 && prev && prev->sj == j && prev->len == len &&
                s == prev->slice + prev->count * N &&
                s / GROUP_SPAN == prev->slice / GROUP_SPAN &&
                (uint64_t)(prev->count + 1) * len * sv <= r->group_cap)
                prev->count++;
            else
                jobs[njobs++] = (struct slicejob){j, s, 1, len, chunks};
            chunks++;
        }
    }
    return njobs;
}

static void report_progress(struct run *r, int last);

/* Encodes the planned slice-windows of step t and writes each chunk in
 * its place as it is made, one job per thread at a time; then joins the
 * chunks' CRCs into their records in slice order.  Thread 0 reports
 * progress between jobs, so a line comes within a long step too. */
static void encode_step(struct run *r, uint32_t t, size_t njobs)
{
    int failed = 0;
    struct tvpal_diag fail_d = {{0}};
    const struct shardjob *fail_j = NULL;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1)
#endif
    for (size_t i = 0; i < njobs; i++) {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        const struct slicejob *jb = &r->jobs[i];
        const struct shardjob *j = jb->sj;
        const size_t sv = (size_t)j->h.slice_w * j->h.slice_h;
        const uint64_t cb = tvpal_chunk_bytes(jb->len, j->h.slice_w,
                                              j->h.slice_h, j->h.table_format);
        gather(r, jb, t, r->samples[tid]);
        for (uint32_t g = 0; g < jb->count; g++) {
            struct tvpal_diag d = {{0}};
            encode_chunk(r->enc[tid], r->tables[tid],
                         r->samples[tid] + (size_t)g * jb->len * sv, j,
                         jb->slice + g * r->N, t, jb->len, r->chunkbuf[tid],
                         &r->dropped[tid]);
            if (tvpal_shardw_put_chunk(j->w, t, jb->slice + g * r->N,
                                       r->chunkbuf[tid], cb,
                                       &r->jcrc[jb->crc_at + g], &d) < 0) {
#ifdef _OPENMP
#pragma omp critical(tvpal_fail)
#endif
                if (!failed) {
                    failed = 1;
                    fail_d = d;
                    fail_j = j;
                }
            }
        }
        __atomic_add_fetch(&r->prog.work, (uint64_t)sv * jb->len * jb->count,
                           __ATOMIC_RELAXED);
        if (tid == 0)
            report_progress(r, 0);
    }
    if (failed)
        die_fail("%s/axis-%c.tvps: %s", r->ckdir, "xyz"[fail_j->axis],
                 fail_d.msg);
    for (size_t i = 0; i < njobs; i++) {
        const struct slicejob *jb = &r->jobs[i];
        for (uint32_t g = 0; g < jb->count; g++)
            if (tvpal_shardw_extend(jb->sj->w, t, jb->slice + g * r->N,
                                    r->jcrc[jb->crc_at + g]) < 0)
                die_fail("internal error: chunk of slice %u, step %u out of "
                         "order", jb->slice + g * r->N, t);
    }
}

/* Saves the checkpoint after unit u (pass p, step t: u = p T + t + 1): a
 * rerun resumes after it. */
static void save_checkpoint(struct run *r, uint64_t u)
{
    struct tvpal_diag d = {{0}};
    for (uint32_t q = 0; q < r->nshard; q++) {
        for (uint32_t t = 0; t < r->T; t++) {
            size_t i = (size_t)q * r->T + t;
            tvpal_shardw_progress(r->sj[q].w, t, &r->ckp.filled[i],
                                  &r->ckp.crc[i]);
        }
        r->ckp.missing[q] = (uint8_t)tvpal_shardw_missing(r->sj[q].w);
    }
    int rc = tvpal_checkpoint_save(r->ckdir, r->fp, u, &r->st, &r->ckp, &d);
    if (rc < 0)
        die_fail("%s/checkpoint: cannot write: %s", r->ckdir,
                 lib_error(rc, &d));
}

/* The work (voxel-samples, all axes) of the whole job, and of the units
 * before u. */
static uint64_t work_before(const struct run *r, uint64_t u)
{
    uint64_t w = 0;
    for (uint32_t p = 0; p < r->plan.npasses; p++) {
        const struct encode_pass *ps = &r->plan.pass[p];
        uint64_t per_step = 0;
        for (unsigned a = 0; a < 3; a++)
            if (ps->axes & (1u << a)) {
                uint32_t n, sw, sh;
                tvpal_axis_geometry(r->o.dims, a, &n, &sw, &sh);
                per_step += (uint64_t)(ps->s1[a] - ps->s0[a]) * sw * sh;
            }
        /* Every slice has one sample per step, over its windows. */
        uint64_t steps = u >= (uint64_t)(p + 1) * r->T ? r->T
                         : u > (uint64_t)p * r->T ? u - (uint64_t)p * r->T : 0;
        w += per_step * steps;
    }
    return w;
}

/* Progress: `last` forces the closing line.  Work done counts the
 * slice-windows encoded; reading counts as time, so the rate and ETA are
 * of the whole job. */
static void report_progress(struct run *r, int last)
{
    struct progress *p = &r->prog;
    double now = tvpal_now();
    if (p->quiet || (!last && now - p->last < p->interval))
        return;
    p->last = now;
    char line[256];
    const uint64_t done = __atomic_load_n(&p->work, __ATOMIC_RELAXED);
    const double el = now - p->t0;
    const double frac = p->total ? (double)done / (double)p->total : 1;
    const double mine = (double)(done - p->work_at_start);
    const double rate = mine / 3.0 / (el > 0 ? el : 1e-9) / 1e6;
    const double eta = mine > 0 ? el / mine * (double)(p->total - done) : -1;
    (void)frac;
    /* Steps over all passes ("pass-steps" when there are several). */
    tvpal_progress_format(line, sizeof line, last ? p->units : p->unit,
                          p->units, r->plan.npasses > 1 ? "pass-steps"
                                                        : "steps",
                          rate, "Mvox-steps/s", eta, p->tty ? 30 : 0);
    if (p->tty)
        fprintf(stderr, "\r%s\033[K%s", line, last ? "\n" : "");
    else
        fprintf(stderr, PROG ": %s\n", line);
}

/* The streaming driver: for each pass of the plan, for each step from
 * the start, reads the box of what its windows need (step t + N - 1 at
 * most), encodes and writes its chunks and checkpoints.
 * TVPAL_ENCODE_FAULT_AFTER=S (a test hook) kills the process after S
 * units (steps of passes), as an interruption would; with
 * TVPAL_ENCODE_FAULT_RANK=R only MPI rank R, and with
 * TVPAL_ENCODE_FAULT=fail it fails with a message instead. */
static void encode_steps(struct run *r)
{
    struct progress *p = &r->prog;
    const char *fault = getenv("TVPAL_ENCODE_FAULT_AFTER");
    const char *fault_rank = getenv("TVPAL_ENCODE_FAULT_RANK");
    const char *fault_how = getenv("TVPAL_ENCODE_FAULT");
    long fault_after = fault ? atol(fault) : -1;
    if (fault_rank && atol(fault_rank) != (long)r->node)
        fault_after = -1;
    p->tty = isatty(STDERR_FILENO);
    p->quiet = r->o.quiet || (r->mpi && r->node != 0);
    p->interval = p->tty ? 0.2 : 30.0;
    /* TVPAL_PROGRESS_INTERVAL=S (a test hook): a line every S seconds. */
    const char *iv = getenv("TVPAL_PROGRESS_INTERVAL");
    if (iv && atof(iv) > 0)
        p->interval = atof(iv);
    p->t0 = p->last = tvpal_now();
    p->total = work_before(r, (uint64_t)r->plan.npasses * r->T);
    p->work = p->work_at_start = work_before(r, r->start);
    p->units = (uint64_t)r->plan.npasses * r->T;
    if (r->start && r->start == p->units && !r->o.quiet)
        msg("resuming %s: every step is encoded; finishing", r->ckdir);
    else if (r->start && !r->o.quiet)
        msg("resuming %s at pass %llu of %u, timestep %llu of %u", r->ckdir,
            (unsigned long long)(r->start / r->T) + 1, r->plan.npasses,
            (unsigned long long)(r->start % r->T), r->T);
    uint64_t u = r->start;
    for (uint32_t pi = (uint32_t)(u / r->T); pi < r->plan.npasses; pi++) {
        r->pass = &r->plan.pass[pi];
        if (u == (uint64_t)pi * r->T)
            r->st.loaded = 0; /* a new pass: none of its steps counted */
        uint32_t loaded = (uint32_t)(u - (uint64_t)pi * r->T);
        for (uint32_t t = loaded; t < r->T; t++) {
            uint32_t need = t + r->N < r->T ? t + r->N : r->T;
            p->unit = (uint64_t)pi * r->T + t;
            for (; loaded < need; loaded++) {
                load_step(r, loaded, r->ring[loaded % r->N]);
                report_progress(r, 0);
            }
            encode_step(r, t, plan_step(r, t));
            u = (uint64_t)pi * r->T + t + 1;
            if (t + 1 == r->T)
                r->st.loaded = 0;
            save_checkpoint(r, u);
            if (fault_after >= 0 && (long)u >= fault_after) {
                if (fault_how && !strcmp(fault_how, "fail"))
                    die_fail("test fault after %llu steps (rerun to resume)",
                             (unsigned long long)u);
                raise(SIGKILL);
            }
            report_progress(r, 0);
        }
    }
    report_progress(r, 1);
    r->t_encode = tvpal_now() - p->t0;
}

/* ---------------------------------------------------------------- cluster */

/* Under mpirun -np K --nodes K, rank R encodes only node R's three shards,
 * reading only the boxes of the input its slabs need, into its own node
 * directory (OUTDIR.partial/node-R, or --shard-dir's on a node-local
 * disk).  The ranks then agree in ROUNDS rounds, each a gather of every
 * rank's state to rank 0 and rank 0's decision sent back:
 *   1. statistics: rank 0 sums them (each voxel is in one rank's z slab)
 *      and sends the source range and the manifest;
 *   2. every rank has finished and verified its shards and node manifest;
 *   3. every node directory is in place: rank 0 writes OUTDIR and renames
 *      it into place, the commit.
 * A rank that fails joins the round it would have reached with its
 * message: rank 0 prints it, and every rank ends with its code, none left
 * waiting.  A rank killed outright is ended by the launcher (mpirun ends
 * the job when a process dies); the checkpoints in the node directories
 * let the same command resume every rank. */

/* What a rank tells rank 0 in a round. */
struct round_head {
    int32_t code;            /* 0 ok, else the exit status */
    int32_t how;             /* enum ending of a failure */
    char text[900];          /* its message */
    double vmin, vmax;       /* round 1: statistics */
    uint64_t nonfinite, missing, counted, dropped;
    uint64_t bytes;          /* round 3: bytes of the rank's shards, */
    uint64_t work;           /* voxel-samples it encoded, */
    double seconds;          /* in this many seconds */
};

/* Rank 0's decision. */
struct round_decision {
    int32_t code, how, bad_rank, nbad;
    double vmin, vmax;
    uint64_t bytes, text_len; /* round 1: the manifest's length */
};

static struct round_head *g_heads;   /* rank 0: one per rank */

/* Gathers mine (and in round 1 the histogram fine, may be NULL on a
 * failing rank) to rank 0, which decides; returns the decision on every
 * rank.  The failure of the lowest rank wins; rank 0 prints it. */
static struct round_decision cluster_gather(const struct round_head *mine,
                                            const uint64_t *fine,
                                            uint64_t *fine_sum)
{
    struct tvpal_comm *c = &g_comm;
    struct round_decision dec = {0};
    const size_t K = (size_t)c->size;
    if (c->rank == 0 && !g_heads && !(g_heads = calloc(K, sizeof *g_heads)))
        c->abort(c, TVPAL_EXIT_FAIL);
    if (c->gather(c, mine, sizeof *mine, g_heads) < 0)
        c->abort(c, TVPAL_EXIT_FAIL);
    if (g_round == 1) {
        /* The fine histograms, one rank at a time into rank 0's sum. */
        static uint64_t zero[TVPAL_CHECKPOINT_BINS];
        const size_t hb = sizeof zero;
        uint64_t *buf = c->rank == 0 ? malloc(hb * K) : NULL;
        if (c->rank == 0 && !buf)
            c->abort(c, TVPAL_EXIT_FAIL);
        if (c->gather(c, fine ? fine : zero, hb, buf) < 0)
            c->abort(c, TVPAL_EXIT_FAIL);
        for (size_t k = 0; c->rank == 0 && k < K; k++)
            for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++)
                fine_sum[b] = (k ? fine_sum[b] : 0) + buf[k * TVPAL_CHECKPOINT_BINS + b];
        free(buf);
    }
    if (c->rank == 0) {
        dec.bad_rank = -1;
        for (size_t k = 0; k < K; k++)
            if (g_heads[k].code) {
                if (dec.bad_rank < 0) {
                    dec.bad_rank = (int32_t)k;
                    dec.code = g_heads[k].code;
                    dec.how = g_heads[k].how;
                }
                dec.nbad++;
            }
    }
    return dec;
}

/* Sends rank 0's decision (and round 1's manifest text) to every rank. */
static void cluster_decide(struct round_decision *dec, char **text)
{
    struct tvpal_comm *c = &g_comm;
    if (c->bcast(c, dec, sizeof *dec, 0) < 0)
        c->abort(c, TVPAL_EXIT_FAIL);
    if (!dec->code && text && dec->text_len) {
        if (c->rank != 0 && !(*text = calloc(1, dec->text_len + 1)))
            c->abort(c, TVPAL_EXIT_FAIL);
        if (c->bcast(c, *text, dec->text_len, 0) < 0)
            c->abort(c, TVPAL_EXIT_FAIL);
    }
}

/* Rank 0 reports the failure decided; every rank removes its node's
 * partial output when the input was bad (a rerun would fail the same
 * way), and ends. */
static void cluster_end_failed(const struct round_decision *dec)
    __attribute__((noreturn));
static void cluster_end_failed(const struct round_decision *dec)
{
    g_round = ROUNDS + 1;
    if (g_comm.rank == 0) {
        const struct round_head *h = &g_heads[dec->bad_rank];
        if (dec->bad_rank > 0)
            fprintf(stderr, PROG ": rank %d: %s\n", dec->bad_rank, h->text);
        else
            fprintf(stderr, PROG ": %s\n", h->text);
        if (dec->nbad > 1)
            fprintf(stderr, PROG ": %d ranks failed; the lowest is shown\n",
                    dec->nbad);
    }
    if (dec->how == DIE_INPUT && g_partial)
        tvpal_rmtree(g_partial);
    tvpal_comm_close(&g_comm);
    exit(dec->code);
}

static void cluster_fail(enum ending how, const char *text)
{
    struct round_head h = {0};
    h.code = how == DIE_FAIL ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE;
    h.how = how;
    snprintf(h.text, sizeof h.text, "%s", text);
    uint64_t *sum = g_comm.rank == 0 ? calloc(TVPAL_CHECKPOINT_BINS, 8) : NULL;
    struct round_decision dec = cluster_gather(&h, NULL, sum);
    free(sum);
    cluster_decide(&dec, NULL);
    cluster_end_failed(&dec);
}

/* ------------------------------------------------------------- finishing */

/* The manifest of the encoded dataset (FORMAT.md 7); m owns its strings. */
/* The physical grid: --spacing/--origin, else what a self-describing input
 * says (the size of a falling coordinate's step; an axis not evenly spaced
 * counts 1, origin 0), else the unit grid. */
static void grid_of(const struct run *r, double spacing[3], double origin[3])
{
    const struct opts *o = &r->o;
    const struct tvpal_input_info *in = r->in ? tvpal_input_info(r->in) : NULL;
    for (int i = 0; i < 3; i++) {
        int known = in && !in->nonuniform[i] && in->spacing[i] != 0;
        spacing[i] = o->have_spacing ? o->spacing[i]
                     : known ? fabs(in->spacing[i]) : 1.0;
        origin[i] = o->have_origin ? o->origin[i]
                    : in && !in->nonuniform[i] ? in->origin[i] : 0.0;
    }
}

static void build_manifest(const struct run *r, struct tvpal_manifest *m)
{
    const struct opts *o = &r->o;
    const struct tvpal_checkpoint_stats *st = &r->st;
    char optstr[256];
    *m = (struct tvpal_manifest){0};
    memcpy(m->dims, o->dims, sizeof o->dims);
    m->type = o->type;
    m->big_endian = o->big_endian;
    m->steps = r->T;
    m->window = r->N;
    m->nodes = o->nodes;
    m->value_min = st->vmin;
    m->value_max = st->vmax;
    m->has_nan_as = o->has_nan_as;
    m->nan_as = o->nan_as;
    m->nonfinite = st->nonfinite;
    m->missing = st->missing;
    for (unsigned i = 0; i < o->nmissing; i++)
        m->missing_values[i] = (float)o->missing[i];
    m->nmissing_values = o->nmissing;
    m->single_file = o->steps_single != 0;
    m->source_bytes = r->step_bytes * r->T;
    grid_of(r, m->spacing, m->origin);
    if (r->times) {
        if (!(m->times = malloc(sizeof *m->times * r->T)))
            die_fail("out of memory");
        memcpy(m->times, r->times, sizeof *m->times * r->T);
        m->ntimes = r->T;
        snprintf(m->time_units, sizeof m->time_units, "%s", r->time_units);
    }
    if (r->in) {
        /* One file of all steps, one file per step, or files of several
         * steps each (series). */
        m->single_file = o->ninputs == 1 && r->T > 1;
        m->series = o->ninputs > 1 && (uint32_t)o->ninputs != r->T;
        snprintf(m->source_format, sizeof m->source_format, "%s",
                 tvpal_input_format_name(o->format));
        if (!(m->source_var = strdup(tvpal_input_info(r->in)->var)))
            die_fail("out of memory");
    }
    /* The manifest's histogram: the fine classes into TVPAL_HIST_BINS
     * equal bins over [min, max]. */
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++) {
        if (!st->fine[b])
            continue;
        double v = fine_bin_value(b);
        double span = st->vmax - st->vmin;
        int bin = span > 0 ? (int)((v - st->vmin) / span * TVPAL_HIST_BINS) : 0;
        bin = bin < 0 ? 0 : bin >= TVPAL_HIST_BINS ? TVPAL_HIST_BINS - 1 : bin;
        m->histogram[bin] += st->fine[b];
    }
    options_line(o, r->T, optstr, sizeof optstr);
    m->table_format = (uint32_t)o->table_format;
    m->encoder = strdup(PROG " " PACKAGE_VERSION);
    m->options = strdup(optstr);
    for (int i = 0; i < o->ninputs; i++)
        if (tvpal_manifest_add_source(m, o->inputs[i]) < 0)
            die_fail("out of memory");
    if (!m->encoder || !m->options)
        die_fail("out of memory");
}

/* Finishes this process's shards with the source range (9.1). */
static void finish_shards(struct run *r)
{
    struct tvpal_diag d = {{0}};
    for (uint32_t q = 0; q < r->nshard; q++) {
        tvpal_shardw_set_range(r->sj[q].w, r->st.vmin, r->st.vmax);
        int rc = tvpal_shardw_finish(r->sj[q].w, &d);
        r->sj[q].w = NULL;
        if (rc < 0) {
            char *path = shard_path(r, &r->sj[q]);
            die_fail("%s: cannot finish: %s", path ? path : "shard",
                     lib_error(rc, &d));
        }
    }
}

/* The manifest's text (malloc'ed). */
static char *manifest_text(const struct run *r)
{
    struct tvpal_manifest m;
    char *text = NULL;
    build_manifest(r, &m);
    if (tvpal_manifest_format(&m, &text) < 0)
        die_fail("out of memory");
    tvpal_manifest_clear(&m);
    return text;
}

static void write_manifest(const char *dir, const char *text)
{
    struct tvpal_diag d = {{0}};
    char *path = NULL;
    int rc = asprintf(&path, "%s/manifest.txt", dir) < 0
                 ? TVPAL_E_NOMEM
                 : tvpal_write_file_atomic(path, text, strlen(text), &d);
    if (rc < 0)
        die_fail("%s: cannot write manifest: %s", dir, lib_error(rc, &d));
    free(path);
}

/* Finishes the shards, then writes the manifest to OUTDIR.partial and to
 * every node directory, and removes the checkpoint (FORMAT.md 9.2, 4). */
static void finish_partial(struct run *r)
{
    finish_shards(r);
    char *text = manifest_text(r);
    write_manifest(r->partial, text);
    for (uint32_t k = 0; k < r->o.nodes; k++) {
        char *nd = node_partial(r, k);
        if (!nd)
            die_fail("out of memory");
        write_manifest(nd, text);
        free(nd);
    }
    free(text);
    tvpal_checkpoint_remove(r->partial, NULL);
    tvpal_fsync_dir(r->partial);
}

/* Renames OUTDIR.partial to OUTDIR; with --force an existing OUTDIR goes
 * to OUTDIR.old first and is removed after.  place_output says what went
 * wrong in err and returns -1; move_into_place ends the program. */
static int place_output(const struct run *r, char *err, size_t cap)
{
    const char *out = r->o.outdir;
    if (tvpal_exists(out)) {
        char *old;
        if (asprintf(&old, "%s.old", out) < 0)
            return snprintf(err, cap, "out of memory"), -1;
        tvpal_rmtree(old);
        if (rename(out, old) < 0 || rename(r->partial, out) < 0) {
            snprintf(err, cap, "%s: cannot replace: %s", out, strerror(errno));
            free(old);
            return -1;
        }
        tvpal_rmtree(old);
        free(old);
    } else if (rename(r->partial, out) < 0) {
        snprintf(err, cap, "%s: cannot rename %s into place: %s", out,
                 r->partial, strerror(errno));
        return -1;
    }
    return 0;
}

static void move_into_place(const struct run *r)
{
    char err[600];
    if (place_output(r, err, sizeof err) < 0)
        die_fail("%s", err);
}

/* Every value missing leaves nothing to encode or draw; present values
 * coded as missing (more missing-value patterns in a slice-window than the
 * code has indices for) are reported. */
static int all_missing(const struct run *r, char *why, size_t cap)
{
    snprintf(why, cap, "%s: every value is missing (NaN%s); expected some "
             "present values", r->o.inputs[0],
             r->o.nmissing ? " or a --missing value" : "");
    return !(r->st.vmin <= r->st.vmax);
}

static uint64_t dropped_values(const struct run *r)
{
    uint64_t dropped = 0;
    for (int i = 0; i < r->nthreads; i++)
        dropped += r->dropped[i];
    return dropped;
}

static void warn_dropped(uint64_t dropped)
{
    if (dropped)
        msg("warning: %llu present value%s coded as missing: slice-windows "
            "with more than 128 patterns of missing timesteps (a smaller "
            "--window avoids it)", (unsigned long long)dropped,
            dropped == 1 ? "" : "s");
}

static void check_missing(const struct run *r)
{
    char why[600];
    if (all_missing(r, why, sizeof why))
        die_input("%s", why);
    warn_dropped(dropped_values(r));
}

/* A few voxels far from all the others (a fill value such as 1e35 left in
 * the data) set the value range, so the quantizers and the default transfer
 * function spend it on them and the report's PSNR, relative to that range,
 * looks excellent.  Warns, naming how many, when the range is more than
 * 1000 times the 0.1..99.9 percentile range or a value is beyond +-1e30
 * (from the source histogram's 65536 classes). */
static void warn_dominating_values(const struct run *r)
{
    const uint64_t *fine = r->st.fine;
    uint64_t total = 0, cum = 0, far = 0, huge = 0;
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++)
        total += fine[b];
    if (!total)
        return;
    /* lo, hi: the classes holding the 0.1th and 99.9th percentiles. */
    uint32_t lo = 0, hi = 0;
    int have_lo = 0, have_hi = 0;
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS && !have_hi; b++) {
        cum += fine[b];
        if (!have_lo && cum * 1000 > total)
            lo = b, have_lo = 1;
        if (cum * 1000 >= total * 999)
            hi = b, have_hi = 1;
    }
    const double plo = fine_bin_value(lo), phi = fine_bin_value(hi);
    const double span = phi - plo, range = r->st.vmax - r->st.vmin;
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++) {
        double v = fine_bin_value(b);
        if (fine[b] && fabs(v) > 1e30)
            huge += fine[b];
        if (fine[b] && (v < plo - 100 * span || v > phi + 100 * span))
            far += fine[b];
    }
    if (huge)
        msg("warning: %llu value%s beyond +-1e30 (the range is %g .. %g): a "
            "fill value? It sets the quantizers' and the colours' range "
            "(--missing V marks a value as missing)",
            (unsigned long long)huge, huge == 1 ? "" : "s", r->st.vmin,
            r->st.vmax);
    else if (range > 1000 * span && far)
        msg("warning: %llu value%s (%.3g%%) lie far outside the bulk of the "
            "data (0.1..99.9 percentiles %.4g .. %.4g, range %g .. %g): they "
            "set the quantizers' and the colours' range; missing values? "
            "(--missing V marks a value as missing)",
            (unsigned long long)far, far == 1 ? "" : "s",
            100.0 * (double)far / (double)total, plo, phi, r->st.vmin,
            r->st.vmax);
}

/* Reopens the dataset with the reader (it must verify) and prints the
 * closing key=value line on stdout. */
static void print_summary(const struct run *r)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_dataset *ds = NULL;
    uint64_t total_bytes = r->cluster_bytes;
    /* Under MPI every rank has verified its own node directory. */
    if (!r->mpi && tvpal_dataset_open(&ds, r->o.outdir, &d) < 0)
        die_fail("%s: written dataset does not verify: %s", r->o.outdir,
                 d.msg);
    for (unsigned a = 0; !r->mpi && a < 3; a++)
        total_bytes += ds->axis_bytes[a];
    tvpal_dataset_close(ds);
    const double axis_bytes = (double)total_bytes / 3.0;
    const double vts = (double)r->nvox * r->T;
    const double te = r->mpi ? r->cluster_seconds : r->t_encode;
    const uint64_t work = r->mpi ? r->cluster_work
                                 : r->prog.work - r->prog.work_at_start;
    printf("encoded %s: steps=%u window=%u nodes=%u bytes=%llu ratio=%.3f "
           "bpv=%.4f seconds=%.3f rate=%.2fM vox-steps/s threads=%d "
           "missing=%llu passes=%u\n",
           r->o.outdir, r->T, r->N, r->o.nodes,
           (unsigned long long)total_bytes,
           (double)(r->step_bytes * r->T) / axis_bytes,
           axis_bytes * 8.0 / vts, te,
           (double)work / 3.0 / (te > 0 ? te : 1e-9) / 1e6,
           r->nthreads * (r->mpi ? g_comm.size : 1),
           (unsigned long long)r->st.missing, r->plan.npasses);
}

/* Bytes of this process's shard files. */
static uint64_t own_shard_bytes(const struct run *r)
{
    uint64_t n = 0;
    for (uint32_t q = 0; q < r->nshard; q++) {
        char *p = shard_path(r, &r->sj[q]);
        struct stat st;
        if (p && stat(p, &st) == 0)
            n += (uint64_t)st.st_size;
        free(p);
    }
    return n;
}

/* Puts this rank's --shard-dir node directory in place (with --force an
 * existing one goes first). */
static void place_node_dir(const struct run *r)
{
    const char *fin = r->node_final;
    if (tvpal_exists(fin) && tvpal_rmtree(fin) < 0)
        die_fail("%s: cannot replace: %s", fin, strerror(errno));
    if (rename(r->ckdir, fin) < 0)
        die_fail("%s: cannot rename %s into place: %s", fin, r->ckdir,
                 strerror(errno));
}

/* Rank 0, round 1: the job's statistics from every rank's; a failure to
 * report goes into dec (and the lowest rank's text). */
static void cluster_stats(struct run *r, struct round_decision *dec,
                          const uint64_t *fine_sum, char **text)
{
    struct tvpal_checkpoint_stats *st = &r->st;
    uint64_t dropped = 0;
    st->vmin = INFINITY;
    st->vmax = -INFINITY;
    st->nonfinite = st->missing = st->counted = 0;
    for (int k = 0; k < g_comm.size; k++) {
        const struct round_head *h = &g_heads[k];
        st->vmin = h->vmin < st->vmin ? h->vmin : st->vmin;
        st->vmax = h->vmax > st->vmax ? h->vmax : st->vmax;
        st->nonfinite += h->nonfinite;
        st->missing += h->missing;
        st->counted += h->counted;
        dropped += h->dropped;
    }
    memcpy(st->fine, fine_sum, TVPAL_CHECKPOINT_BINS * sizeof *st->fine);
    if (all_missing(r, g_heads[0].text, sizeof g_heads[0].text)) {
        *dec = (struct round_decision){TVPAL_EXIT_USAGE, DIE_INPUT, 0, 1,
                                       0, 0, 0, 0};
        return;
    }
    warn_dropped(dropped);
    warn_dominating_values(r);
    *text = manifest_text(r);
    dec->vmin = st->vmin;
    dec->vmax = st->vmax;
    dec->text_len = strlen(*text);
}

/* MPI: the rounds after encoding (see "cluster" above): statistics, then
 * every rank's shards and node manifest finished and verified, then the
 * node directories in place and rank 0's commit of OUTDIR. */
static void cluster_finish(struct run *r)
{
    const int root = g_comm.rank == 0;
    struct round_head h = {0};
    h.vmin = r->st.vmin;
    h.vmax = r->st.vmax;
    h.nonfinite = r->st.nonfinite;
    h.missing = r->st.missing;
    h.counted = r->st.counted;
    h.dropped = dropped_values(r);
    uint64_t *sum = root ? calloc(TVPAL_CHECKPOINT_BINS, sizeof *sum) : NULL;
    if (root && !sum)
        g_comm.abort(&g_comm, TVPAL_EXIT_FAIL);
    struct round_decision dec = cluster_gather(&h, r->st.fine, sum);
    char *text = NULL;
    if (root && !dec.code)
        cluster_stats(r, &dec, sum, &text);
    free(sum);
    cluster_decide(&dec, &text);
    if (dec.code)
        cluster_end_failed(&dec);
    g_round = 2;
    r->st.vmin = dec.vmin;
    r->st.vmax = dec.vmax;
    finish_shards(r);
    write_manifest(r->ckdir, text);
    free(text);
    struct tvpal_dataset *ds = NULL;
    struct tvpal_diag d = {{0}};
    if (tvpal_dataset_open_node(&ds, r->ckdir, r->node, r->o.nodes, &d) < 0)
        die_fail("%s: written node directory does not verify: %s", r->ckdir,
                 d.msg);
    tvpal_dataset_close(ds);
    memset(&h, 0, sizeof h);
    dec = cluster_gather(&h, NULL, NULL);
    cluster_decide(&dec, NULL);
    if (dec.code)
        cluster_end_failed(&dec);
    g_round = 3;
    tvpal_checkpoint_remove(r->ckdir, NULL);
    tvpal_fsync_dir(r->ckdir);
    if (r->node_final)
        place_node_dir(r);
    memset(&h, 0, sizeof h);
    h.work = r->prog.work - r->prog.work_at_start;
    h.seconds = r->t_encode;
    h.bytes = own_shard_bytes(r);
    if (r->node_final) { /* the files have moved */
        char *keep = r->ckdir;
        r->ckdir = r->node_final;
        h.bytes = 0;
        for (uint32_t q = 0; q < r->nshard; q++) {
            char *p = NULL;
            struct stat st;
            if (asprintf(&p, "%s/axis-%c.tvps", r->node_final,
                         "xyz"[r->sj[q].axis]) >= 0 && stat(p, &st) == 0)
                h.bytes += (uint64_t)st.st_size;
            free(p);
        }
        r->ckdir = keep;
    }
    dec = cluster_gather(&h, NULL, NULL);
    if (root && !dec.code) {
        /* The commit: OUTDIR with its manifest, last.  Its failure is
         * decided here (the other ranks wait for the decision). */
        struct tvpal_diag wd = {{0}};
        char *path = NULL;
        text = manifest_text(r);
        int rc = asprintf(&path, "%s/manifest.txt", r->partial) < 0
                     ? TVPAL_E_NOMEM
                     : tvpal_write_file_atomic(path, text, strlen(text), &wd);
        free(path);
        free(text);
        tvpal_fsync_dir(r->partial);
        if (rc < 0)
            snprintf(g_heads[0].text, sizeof g_heads[0].text, "%s: cannot "
                     "write manifest: %s", r->partial, lib_error(rc, &wd));
        else if (place_output(r, g_heads[0].text, sizeof g_heads[0].text) < 0)
            rc = -1;
        if (rc < 0)
            dec = (struct round_decision){TVPAL_EXIT_FAIL, DIE_FAIL, 0, 1,
                                          0, 0, 0, 0};
        for (int k = 0; k < g_comm.size; k++) {
            r->cluster_bytes += g_heads[k].bytes;
            r->cluster_work += g_heads[k].work;
            if (g_heads[k].seconds > r->cluster_seconds)
                r->cluster_seconds = g_heads[k].seconds;
        }
    }
    cluster_decide(&dec, NULL);
    if (dec.code)
        cluster_end_failed(&dec);
    g_round = ROUNDS + 1;
}

static void run_free(struct run *r)
{
    prefetch_stop(r->pf);   /* before the input it reads is closed */
    for (uint32_t q = 0; q < r->nshard; q++)
        tvpal_shardw_free(r->sj[q].w);
    free(r->sj);
    for (int i = 0; i < r->nthreads && r->enc; i++) {
        tvpal_swenc_free(r->enc[i]);
        free(r->samples[i]);
        free(r->tables[i]);
        free(r->chunkbuf[i]);
        free(r->scratch[i]);
        free(r->fine_local[i]);
    }
    for (uint32_t i = 0; r->ring && i < r->N; i++)
        free(r->ring[i]);
    free(r->ring);
    free(r->boxbuf);
    free(r->enc);
    free(r->dropped);
    free(r->samples);
    free(r->tables);
    free(r->chunkbuf);
    free(r->scratch);
    free(r->fine_local);
    free(r->jobs);
    free(r->jcrc);
    free(r->fp);
    free(r->ckp.filled);
    free(r->ckp.crc);
    free(r->ckp.missing);
    encode_plan_free(&r->plan);
    tvpal_checkpoint_stats_free(&r->st);
    free(r->partial);
    free(r->ckdir);
    free(r->node_final);
    free(g_heads);
    g_heads = NULL;
    for (int i = 0; i < r->o.ninputs; i++)
        free(r->abs_inputs[i]);
    free(r->abs_inputs);
    tvpal_input_close(r->in);
    free(r->times);
}

/* Under an MPI launcher (tvpal_comm_launched): joins the job, one rank
 * per node shard.  One process otherwise, or as a job of one rank. */
static void open_cluster(struct run *r, int *argc, char ***argv)
{
    struct tvpal_diag d = {{0}};
    tvpal_comm_self(&g_comm);
    if (!tvpal_comm_launched(NULL))
        return;
    if (tvpal_comm_open(&g_comm, TVPAL_COMM_MPI, argc, argv, &d) < 0)
        die_usage("started by an MPI launcher, but %s", d.msg);
    if (g_comm.size > 1) {
        r->mpi = 1;
        r->node = (uint32_t)g_comm.rank;
        g_round = 1; /* failures from here on go through the rounds */
    }
}

/* This process's checkpoint directory and, under MPI, its node's final
 * directory (--shard-dir); the rules --nodes and --shard-dir obey. */
static void setup_cluster_dirs(struct run *r)
{
    const struct opts *o = &r->o;
    if (o->shard_pat && !r->mpi)
        die_usage("--shard-dir: for MPI runs (mpirun -np K " PROG
                  " --nodes K ...); one process writes OUTDIR/node-R");
    if (r->mpi && o->nodes != (uint32_t)g_comm.size)
        die_usage("--nodes %u under %d MPI ranks: expected --nodes %d (one "
                  "rank per node shard)", o->nodes, g_comm.size, g_comm.size);
    if (o->shard_pat && !strstr(o->shard_pat, "%r"))
        die_usage("--shard-dir \"%s\": expected %%r (the rank) in it",
                  o->shard_pat);
    r->ckdir = r->mpi ? node_partial(r, r->node) : strdup(r->partial);
    if (!r->ckdir)
        die_fail("out of memory");
    if (o->shard_pat) {
        if (!(r->node_final = tvpal_node_dir(NULL, o->shard_pat, r->node)))
            die_fail("out of memory");
        if (tvpal_exists(r->node_final) && !o->force)
            die_usage("%s: node directory already exists (use --force to "
                      "replace it)", r->node_final);
    }
    if (r->mpi && r->node == 0) {
        /* OUTDIR.partial holds the node directories (or, with
         * --shard-dir, only the manifest): a one-process job's checkpoint
         * there is not this job's. */
        struct tvpal_diag d = {{0}};
        if (tvpal_mkdirs(r->partial, &d) < 0)
            die_usage("%s: cannot create output directory: %s", r->partial,
                      d.msg);
        tvpal_checkpoint_remove(r->partial, NULL);
    }
}

/* Each step ends the program itself on failure (see `enum ending`). */
int main(int argc, char **argv)
{
    struct run r = {0};
    open_cluster(&r, &argc, &argv);
    int have_dims = parse_options(argc, argv, &r.o);
    order_inputs(&r.o);
    have_dims = open_source(&r, have_dims);
    const uint32_t input_steps = r.in ? tvpal_input_info(r.in)->steps : 0;
    validate_opts(&r.o, have_dims, input_steps);
    r.T = input_steps ? input_steps
          : r.o.steps_single ? r.o.steps_single : (uint32_t)r.o.ninputs;
    r.N = r.o.window;
    r.nvox = (size_t)r.o.dims[0] * r.o.dims[1] * r.o.dims[2];
    r.step_bytes = (uint64_t)r.nvox * tvpal_type_size(r.o.type);
    check_inputs(&r);
    load_times(&r);
    warn_irregular_times(&r);
    check_output(&r);
    setup_cluster_dirs(&r);
    setup_shards(&r);
    choose_threads(&r);
    make_plan(&r);
    open_partial(&r);
    open_or_restart_writers(&r);
    setup_workspace(&r);
    if (r.in)
        r.pf = prefetch_start(r.in, r.plan.box_voxels_max);
    encode_steps(&r);
    if (r.mpi) {
        cluster_finish(&r);
    } else {
        check_missing(&r);
        warn_dominating_values(&r);
        finish_partial(&r);
        move_into_place(&r);
    }
    if (!r.mpi || r.node == 0)
        print_summary(&r);
    run_free(&r);
    tvpal_comm_close(&g_comm);
    return 0;
}
