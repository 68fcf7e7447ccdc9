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
#include "tvpal_checkpoint.h"
#include "tvpal_cli.h"
#include "tvpal_clock.h"
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

static void say(enum ending how, const char *fmt, va_list ap)
{
    fputs(PROG ": ", stderr);
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
        printf(PROG " " PACKAGE_VERSION " (format %u; inflate: %s)\n",
               TVPAL_FORMAT_VERSION, tvpal_input_inflate_library());
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
    struct tvpal_shardw *w;
    unsigned char *rec;      /* record buffer */
    uint64_t rec_cap;
    uint64_t payload;        /* bytes of chunks this step */
    uint32_t nchunks;
};

/* A group of `count` slices slice, slice + N, ... of one shard, all with
 * windows of length len starting at the current step, whose chunks follow
 * each other in the record from offset off.  Slices of the x axis are
 * grouped so that one pass over the volume rows gathers them all (they
 * share cache lines); other axes use groups of one. */
struct slicejob {
    struct shardjob *sj;
    uint32_t slice;
    uint32_t count;
    uint32_t len;
    uint64_t off;            /* first chunk's offset in sj->rec */
};

/* Most slices per group: those of one 64-byte line of x (16 floats). */
#define GROUP_SPAN 16u

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
    uint32_t start;          /* first step to encode (> 0: resumed) */
    /* Shards: 3 axes x K nodes, axis-major. */
    struct shardjob *sj;
    uint32_t nshard;
    size_t max_slice_vox, max_jobs;
    /* Workspaces: per thread, then shared. */
    int nthreads;
    uint64_t **fine_local;   /* per-thread source histograms */
    size_t group_cap;        /* floats of samples per thread */
    struct tvpal_swenc **enc;
    float **samples, **tables;
    struct slicejob *jobs;   /* max_jobs */
    float **ring;            /* N converted timesteps, step t at t % N */
    void *raw;               /* one source timestep */
    struct tvpal_input *in;  /* self-describing input, or NULL (raw) */
    struct prefetch *pf;     /* reads the input's next step meanwhile */
    uint64_t *dropped;       /* per thread: present values coded missing */
    double *times;           /* [T] time values, or NULL (none known) */
    char time_units[128];
    double t_encode;         /* seconds of the streaming loop */
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

/* What the threads of read_convert found. */
struct loaded {
    size_t bad;              /* lowest voxel index of a data error */
    int rc;                  /* its code (TVPAL_E_NAN or _RANGE), or 0 */
    int read_err;            /* errno of a failed read, -1 at end of file */
    size_t nrep;             /* values replaced by --nan-as */
    size_t nmiss;            /* missing values (NaN after conversion) */
    double lo, hi;           /* range including the stats' so far */
};

/* Reads the timestep at off of fd into r->raw and converts it into dst, in
 * parallel over contiguous chunks (each thread reads its own part: the
 * page-cache copy is as costly as the conversion); when `stats`, counts
 * the values into the per-thread histograms and res's range. */
static void read_convert(struct run *r, int fd, off_t off, float *dst,
                         int stats, struct loaded *res)
{
    /* fd < 0: the timestep is in r->raw already (a reader put it there). */
    const struct opts *o = &r->o;
    const size_t esz = tvpal_type_size(o->type), nvox = r->nvox;
    char *raw = r->raw;
    size_t nrep = 0, nmiss = 0, bad = SIZE_MAX;
    int rc_all = 0, read_err = 0;
    double lo = r->st.vmin, hi = r->st.vmax;
#ifdef _OPENMP
#pragma omp parallel reduction(min : lo) reduction(max : hi) \
    reduction(+ : nrep, nmiss)
#endif
    {
        int id = 0, nt = 1;
#ifdef _OPENMP
        id = omp_get_thread_num();
        nt = omp_get_num_threads();
#endif
        size_t a = nvox * (size_t)id / (size_t)nt;
        size_t b = nvox * (size_t)(id + 1) / (size_t)nt;
        size_t mybad = 0, myrep = 0;
        int rc = 0;
        for (size_t got = a * esz; fd >= 0 && got < b * esz;) {
            ssize_t k = pread(fd, raw + got, b * esz - got, off + (off_t)got);
            if (k < 0 && errno == EINTR)
                continue;
            if (k <= 0) {
#ifdef _OPENMP
#pragma omp atomic write
#endif
                read_err = k < 0 ? errno : -1;
                rc = TVPAL_E_READ;
                break;
            }
            got += (size_t)k;
        }
        if (rc == 0)
            rc = tvpal_raw_convert(raw + a * esz, o->type, o->big_endian,
                                   b - a, dst + a,
                                   o->has_nan_as ? &o->nan_as : NULL, &mybad,
                                   &myrep);
        if (rc == 0)
            /* --missing V: NaN, or counted as replaced by --nan-as */
            if (o->nmissing) {
                size_t hits = tvpal_missing_apply(dst + a, b - a, o->missing,
                                                  o->nmissing,
                                                  o->has_nan_as ? &o->nan_as
                                                                : NULL);
                myrep += o->has_nan_as ? hits : 0;
            }
        if (rc < 0 && rc != TVPAL_E_READ) {
            /* The data error at the lowest index wins, with its code. */
#ifdef _OPENMP
#pragma omp critical(tvpal_bad)
#endif
            if (a + mybad < bad) {
                bad = a + mybad;
                rc_all = rc;
            }
        } else if (rc == 0 && stats) {
            uint64_t *fine = r->fine_local[id];
            nrep += myrep;
            for (size_t i = a; i < b; i++) {
                float v = dst[i];
                if (v != v) { /* missing: in no figure */
                    nmiss++;
                    continue;
                }
                lo = v < lo ? v : lo;
                hi = v > hi ? v : hi;
                fine[fine_bin(v)]++;
            }
        }
    }
    *res = (struct loaded){bad, rc_all, read_err, nrep, nmiss, lo, hi};
}

/* A self-describing input is read (and inflated) by its library on one
 * thread; the encoding of a step runs on all of them.  One reader thread
 * reads step t + 1 while step t is converted and encoded, so the two
 * overlap.  The reader is the only thread that calls the input library once
 * it runs (HDF5 and libnetcdf builds need not be thread-safe). */
struct prefetch {
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    struct tvpal_input *in;
    void *buf;               /* nvox floats: the step being read or read */
    int64_t want, ready;     /* step asked for / in buf (-1: none) */
    int busy, quit, rc;
    struct tvpal_diag d;
};

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
        pthread_mutex_unlock(&pf->mu);
        struct tvpal_diag d = {{0}};
        int rc = tvpal_input_read(pf->in, (uint32_t)t, pf->buf, &d);
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

/* Starts the reader (NULL when threads are not available: then every step
 * is read in place). */
static struct prefetch *prefetch_start(struct tvpal_input *in, size_t bytes)
{
    struct prefetch *pf = calloc(1, sizeof *pf);
    if (!pf || !(pf->buf = malloc(bytes))) {
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

/* Step t of the input into *raw: from the reader when it has it (the
 * buffers are swapped), else read here; then step t + 1 is asked for. */
static int input_step(struct run *r, uint32_t t, struct tvpal_diag *d)
{
    struct prefetch *pf = r->pf;
    int rc = 1;
    if (pf) {
        pthread_mutex_lock(&pf->mu);
        while (pf->busy || pf->want >= 0)
            pthread_cond_wait(&pf->cv, &pf->mu);
        if (pf->ready == (int64_t)t) {
            void *tmp = r->raw;
            r->raw = pf->buf;
            pf->buf = tmp;
            rc = pf->rc;
            *d = pf->d;
        }
        pf->ready = -1;
        pthread_mutex_unlock(&pf->mu);
    }
    if (rc > 0) /* not read ahead: the reader is idle, so this is safe */
        rc = tvpal_input_read(r->in, t, r->raw, d);
    if (pf && t + 1 < r->T) {
        pthread_mutex_lock(&pf->mu);
        pf->want = t + 1;
        pthread_cond_broadcast(&pf->cv);
        pthread_mutex_unlock(&pf->mu);
    }
    return rc;
}

/* Reads timestep t of the source into dst (converted), accounting stats
 * when t is not yet in them.  A read error ends the program keeping the
 * partial output (maybe transient); bad data ends it removing it. */
static void load_step(struct run *r, uint32_t t, float *dst)
{
    const struct opts *o = &r->o;
    /* Raw: a file per step, or one of them all; a reader knows its own. */
    const char *path = r->in || o->steps_single ? o->inputs[0] : o->inputs[t];
    const off_t off = o->steps_single ? (off_t)t * (off_t)r->step_bytes : 0;
    const int stats = t >= r->st.loaded;
    struct loaded res;
    int fd = -1;
    if (r->in) {
        uint32_t k;
        struct tvpal_diag d = {{0}};
        path = tvpal_input_file(r->in, t, &k);
        int rc = input_step(r, t, &d);
        if (rc < 0) /* the file changed or is corrupt: a rerun fails too */
            die_input("timestep %u (step %u of %s): %s", t, k, path,
                      lib_error(rc, &d));
    } else {
        struct tvpal_diag d = {{0}};
        if ((fd = tvpal_open_regular(path, &d)) < 0)
            /* maybe transient (NFS, permissions): keep the partial */
            die_fail("cannot open %s (rerun to resume)", d.msg);
    }
    read_convert(r, fd, off, dst, stats, &res);
    if (fd >= 0)
        close(fd);
    if (res.read_err > 0)
        die_fail("%s: timestep %u: %s (rerun to resume)", path, t,
                 strerror(res.read_err));
    if (res.read_err)
        die_input("%s: timestep %u: file shrank while encoding (truncated)",
                  path, t);
    if (res.rc < 0) {
        size_t x = res.bad % o->dims[0], y = res.bad / o->dims[0] % o->dims[1],
               z = res.bad / o->dims[0] / o->dims[1];
        if (res.rc == TVPAL_E_NAN)
            die_input("%s: timestep %u: infinite value at voxel "
                      "(%zu,%zu,%zu); expected finite values or NaN for "
                      "missing ones (use --nan-as VALUE to replace them)",
                      path, t, x, y, z);
        die_input("%s: timestep %u: value at voxel (%zu,%zu,%zu) exceeds "
                  "the supported magnitude %g", path, t, x, y, z,
                  TVPAL_VALUE_MAX);
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
static void make_node_dirs(struct run *r)
{
    for (uint32_t k = 0; k < r->o.nodes; k++) {
        struct tvpal_diag d = {{0}};
        char *nd;
        int rc = asprintf(&nd, "%s/node-%u", r->partial, k) < 0
                     ? TVPAL_E_NOMEM : tvpal_mkdirs(nd, &d);
        if (rc < 0)
            die_usage("%s: cannot create output directory: %s", r->partial,
                      lib_error(rc, &d));
        free(nd);
    }
    g_partial = r->partial;
}

/* Resumes the partial output of the same job from its checkpoint, or
 * removes a partial output that has none usable; then makes the node
 * directories.  Sets r->fp, r->st and r->start. */
static void open_partial(struct run *r)
{
    char *params = job_params(&r->o, r->in);
    if (!params ||
        tvpal_checkpoint_fingerprint(params, r->o.inputs, r->o.ninputs,
                                     &r->fp) < 0 ||
        tvpal_checkpoint_stats_init(&r->st) < 0)
        die_fail("out of memory");
    free(params);
    r->start = 0;
    if (tvpal_exists(r->partial)) {
        /* A checkpoint that is missing, of another job or damaged is not
         * an error: the job starts over (FORMAT.md 9.2). */
        if (tvpal_checkpoint_load(r->partial, r->fp, r->T, r->nvox, &r->start,
                                  &r->st, NULL) < 0 || r->start == 0) {
            r->start = 0;
            tvpal_checkpoint_stats_reset(&r->st);
            if (tvpal_rmtree(r->partial) < 0)
                die_usage("%s: cannot remove stale partial output",
                          r->partial);
        }
    }
    make_node_dirs(r);
}

/* Describes the 3K shards (axis-major) and allocates their record
 * buffers; sets the largest slice and the most slice-windows of a step. */
static void setup_shards(struct run *r)
{
    const struct opts *o = &r->o;
    r->nshard = 3 * o->nodes;
    if (!(r->sj = calloc(r->nshard, sizeof *r->sj)))
        die_fail("out of memory");
    for (unsigned a = 0; a < 3; a++) {
        uint32_t n, w, h;
        tvpal_axis_geometry(o->dims, a, &n, &w, &h);
        if ((size_t)w * h > r->max_slice_vox)
            r->max_slice_vox = (size_t)w * h;
        r->max_jobs += n;
        for (uint32_t k = 0; k < o->nodes; k++) {
            struct shardjob *j = &r->sj[a * o->nodes + k];
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
            /* Largest record: every slice of the slab with a full window. */
            j->rec_cap = tvpal_round_up(
                TVPAL_RECORD_HEADER_BYTES +
                    (uint64_t)j->h.slice_count *
                        tvpal_chunk_bytes(r->N, w, h, j->h.table_format),
                TVPAL_ALIGN);
            if (!(j->rec = malloc(j->rec_cap)))
                die_fail("out of memory");
        }
    }
}

/* Creates (start = 0) or resumes the shard writers; reports and returns
 * < 0 on the first failure. */
static int open_writers(struct run *r)
{
    for (uint32_t q = 0; q < r->nshard; q++) {
        struct shardjob *j = &r->sj[q];
        struct tvpal_diag d = {{0}};
        char *path = tvpal_shard_filename(r->partial, j->rank, j->axis);
        int rc;
        if (!path)
            return TVPAL_E_NOMEM;
        if (r->start)
            rc = tvpal_shardw_resume(&j->w, path, &j->h, r->start, &d);
        else
            rc = tvpal_shardw_create(&j->w, path, &j->h);
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

/* Opens the writers; a partial output that does not verify is removed and
 * the job started over, from empty statistics. */
static void open_or_restart_writers(struct run *r)
{
    while (open_writers(r) < 0) {
        for (uint32_t q = 0; q < r->nshard; q++) {
            tvpal_shardw_free(r->sj[q].w);
            r->sj[q].w = NULL;
        }
        if (!r->start)
            die_input("%s: cannot create the output files", r->partial);
        r->start = 0;
        tvpal_checkpoint_stats_reset(&r->st);
        tvpal_rmtree(r->partial);
        make_node_dirs(r);
    }
}

/* ------------------------------------------------------------- workspace */

/* Threads and their workspaces, the ring of N timesteps and the raw
 * buffer: everything the streaming loop uses, allocated once. */
static void setup_workspace(struct run *r)
{
    const uint32_t N = r->N;
    r->nthreads = 1;
#ifdef _OPENMP
    if (r->o.threads)
        omp_set_num_threads((int)r->o.threads);
    r->nthreads = omp_get_max_threads();
#endif
    const size_t nt = (size_t)r->nthreads;
    if (!(r->fine_local = calloc(nt, sizeof *r->fine_local)))
        die_fail("out of memory");
    for (size_t i = 0; i < nt; i++)
        if (!(r->fine_local[i] = calloc(TVPAL_CHECKPOINT_BINS,
                                        sizeof(uint64_t))))
            die_fail("out of memory");
    /* Samples per thread: one slice-window, or a group of x slices up to
     * 8 MiB (a group never exceeds GROUP_SPAN slices). */
    const size_t sw = r->max_slice_vox * N;
    r->group_cap = sw;
    if (r->group_cap < (size_t)2 << 20)
        r->group_cap = (size_t)2 << 20 < sw * GROUP_SPAN ? (size_t)2 << 20
                                                         : sw * GROUP_SPAN;
    r->enc = calloc(nt, sizeof *r->enc);
    r->dropped = calloc(nt, sizeof *r->dropped);
    r->samples = calloc(nt, sizeof *r->samples);
    r->tables = calloc(nt, sizeof *r->tables);
    r->jobs = calloc(r->max_jobs, sizeof *r->jobs);
    r->ring = calloc(N, sizeof *r->ring);
    r->raw = malloc(r->step_bytes);
    if (!r->enc || !r->dropped || !r->samples || !r->tables || !r->jobs || !r->ring ||
        !r->raw)
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
            !(r->tables[i] = malloc(N * 256 * sizeof(float))))
            die_fail("out of memory");
    }
    for (uint32_t i = 0; i < N; i++)
        if (!(r->ring[i] = malloc(r->nvox * sizeof(float))))
            die_fail("out of memory for %u timesteps of %zu voxels", N,
                     r->nvox);
}

/* ---------------------------------------------------------------- encoding */

/* Copies the slices of job jb (timesteps t..t+len-1) from the ring into
 * samples: slice g of the group at samples + g * len * w*h, time-major. */
static void gather(const struct opts *o, float *const *ring,
                   const struct slicejob *jb, uint32_t t, float *samples)
{
    const size_t nx = o->dims[0], ny = o->dims[1], nz = o->dims[2];
    const unsigned axis = jb->sj->axis;
    const size_t sv = (size_t)jb->sj->h.slice_w * jb->sj->h.slice_h;
    const uint32_t s = jb->slice, len = jb->len, N = o->window;
    for (uint32_t j = 0; j < len; j++) {
        const float *vol = ring[(t + j) % N];
        float *out = samples + (size_t)j * sv;
        switch (axis) {
        case 0:
            for (size_t z = 0; z < nz; z++)
                for (size_t y = 0; y < ny; y++) {
                    const float *row = vol + nx * (y + ny * z) + s;
                    float *dst = out + y + ny * z;
                    for (uint32_t g = 0; g < jb->count; g++)
                        dst[(size_t)g * len * sv] = row[(size_t)g * N];
                }
            break;
        case 1:
            for (size_t z = 0; z < nz; z++)
                memcpy(out + nx * z, vol + nx * (s + ny * z),
                       nx * sizeof *out);
            break;
        default:
            memcpy(out, vol + nx * ny * (size_t)s, nx * ny * sizeof *out);
            break;
        }
    }
}

/* Encodes one slice-window from samples into its chunk at `chunk`. */
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

/* Lists the slice-windows of every shard that start at step t, in record
 * order, into r->jobs (x slices grouped), and lays out each shard's
 * record.  Returns the number of jobs. */
static size_t plan_step(struct run *r, uint32_t t)
{
    const uint32_t N = r->N;
    struct slicejob *jobs = r->jobs;
    size_t njobs = 0;
    for (uint32_t q = 0; q < r->nshard; q++) {
        struct shardjob *j = &r->sj[q];
        uint64_t off = TVPAL_RECORD_HEADER_BYTES;
        j->nchunks = 0;
        const size_t sv = (size_t)j->h.slice_w * j->h.slice_h;
        for (uint32_t k = 0; k < j->h.slice_count; k++) {
            uint32_t s = j->h.slice_begin + k;
            if (!tvpal_schedule_starts(s, t, N))
                continue;
            uint32_t len = tvpal_schedule_len(s, t, N, r->T);
            uint64_t cb = tvpal_chunk_bytes(len, j->h.slice_w, j->h.slice_h,
                                            j->h.table_format);
            struct slicejob *prev = njobs ? &jobs[njobs - 1] : NULL;
            /* Extend the previous x group when this slice is the next of
             * its phase, in the same line, with the same window, and the
             * group's samples stay within the workspace. */
            if (j->axis == 0 && prev && prev->sj == j && prev->len == len &&
                s == prev->slice + prev->count * N &&
                s / GROUP_SPAN == prev->slice / GROUP_SPAN &&
                (uint64_t)(prev->count + 1) * len * sv <= r->group_cap)
                prev->count++;
            else
                jobs[njobs++] = (struct slicejob){j, s, 1, len, off};
            off += cb;
            j->nchunks++;
        }
        j->payload = off - TVPAL_RECORD_HEADER_BYTES;
    }
    return njobs;
}

/* Encodes the planned slice-windows of step t into the record buffers,
 * one job per thread at a time. */
static void encode_step(struct run *r, uint32_t t, size_t njobs)
{
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
        gather(&r->o, r->ring, jb, t, r->samples[tid]);
        for (uint32_t g = 0; g < jb->count; g++)
            encode_chunk(r->enc[tid], r->tables[tid],
                         r->samples[tid] + (size_t)g * jb->len * sv, j,
                         jb->slice + g * r->N, t, jb->len,
                         j->rec + jb->off + g * cb, &r->dropped[tid]);
    }
}

/* Record 0 holds every slice; later records hold one phase (at most
 * ceil(n / N) slices): gives the rest of the record buffers back. */
static void shrink_records(struct run *r)
{
    for (uint32_t q = 0; q < r->nshard; q++) {
        struct shardjob *j = &r->sj[q];
        uint64_t cap = tvpal_round_up(
            TVPAL_RECORD_HEADER_BYTES +
                (uint64_t)((j->h.slice_count + r->N - 1) / r->N + 1) *
                    tvpal_chunk_bytes(r->N, j->h.slice_w, j->h.slice_h,
                                      j->h.table_format),
            TVPAL_ALIGN);
        if (cap < j->rec_cap) {
            unsigned char *nb = realloc(j->rec, cap);
            if (nb) {
                j->rec = nb;
                j->rec_cap = cap;
            }
        }
    }
}

/* Seals and appends step t's record to every shard, then saves the
 * checkpoint: after it, a rerun resumes at t + 1. */
static void write_step(struct run *r, uint32_t t)
{
    struct tvpal_diag d = {{0}};
    int rc;
    for (uint32_t q = 0; q < r->nshard; q++) {
        struct shardjob *j = &r->sj[q];
        uint64_t bytes = tvpal_record_seal(j->rec, t, j->axis, j->nchunks,
                                           j->payload);
        if ((rc = tvpal_shardw_append(j->w, j->rec, bytes, &d)) < 0)
            die_fail("%s/node-%u/axis-%c.tvps: %s", r->partial, j->rank,
                     "xyz"[j->axis], lib_error(rc, &d));
    }
    if (t == 0 && r->T > 1)
        shrink_records(r);
    if ((rc = tvpal_checkpoint_save(r->partial, r->fp, t + 1, &r->st, &d)) < 0)
        die_fail("%s/checkpoint: cannot write: %s", r->partial,
                 lib_error(rc, &d));
}

/* Progress on stderr: a bar redrawn at most 5 times a second on a terminal,
 * otherwise a line every 30 s; always at the last step. */
struct progress {
    int tty;
    double t0, last;
};

static void report_progress(const struct run *r, struct progress *p,
                            uint32_t t)
{
    double now = tvpal_now();
    if (r->o.quiet || (t + 1 != r->T && now - p->last < (p->tty ? 0.2 : 30.0)))
        return;
    char line[256];
    double el = now - p->t0;
    double done = (double)(t + 1 - r->start);
    double rate = done * (double)r->nvox / (el > 0 ? el : 1e-9) / 1e6;
    double eta = el / done * (double)(r->T - t - 1);
    tvpal_progress_format(line, sizeof line, t + 1, r->T, "steps", rate,
                          "Mvox-steps/s", eta, p->tty ? 30 : 0);
    if (p->tty)
        fprintf(stderr, "\r%s\033[K%s", line, t + 1 == r->T ? "\n" : "");
    else
        fprintf(stderr, PROG ": %s\n", line);
    p->last = now;
}

/* The streaming driver: for each step from r->start, reads what its
 * windows need (step t + N - 1 at most), encodes and writes its records
 * and checkpoints.  TVPAL_ENCODE_FAULT_AFTER=S (a test hook) kills the
 * process after S steps, as an interruption would. */
static void encode_steps(struct run *r)
{
    struct progress p = {isatty(STDERR_FILENO), tvpal_now(), 0};
    const char *fault = getenv("TVPAL_ENCODE_FAULT_AFTER");
    const long fault_after = fault ? atol(fault) : -1;
    uint32_t loaded = r->start;
    p.last = p.t0;
    if (r->start && !r->o.quiet)
        msg("resuming %s at timestep %u of %u", r->partial, r->start, r->T);
    for (uint32_t t = r->start; t < r->T; t++) {
        uint32_t need = t + r->N < r->T ? t + r->N : r->T;
        for (; loaded < need; loaded++)
            load_step(r, loaded, r->ring[loaded % r->N]);
        encode_step(r, t, plan_step(r, t));
        write_step(r, t);
        if (fault_after >= 0 && (long)(t + 1) >= fault_after)
            raise(SIGKILL);
        report_progress(r, &p, t);
    }
    r->t_encode = tvpal_now() - p.t0;
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

/* Finishes the shards, then writes the manifest to OUTDIR.partial and to
 * every node directory, and removes the checkpoint (FORMAT.md 9.2, 4). */
static void finish_partial(struct run *r)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_manifest m;
    char *text = NULL;
    int rc;
    for (uint32_t q = 0; q < r->nshard; q++) {
        tvpal_shardw_set_range(r->sj[q].w, r->st.vmin, r->st.vmax);
        rc = tvpal_shardw_finish(r->sj[q].w, &d);
        r->sj[q].w = NULL;
        if (rc < 0)
            die_fail("%s/node-%u/axis-%c.tvps: cannot finish: %s", r->partial,
                     r->sj[q].rank, "xyz"[r->sj[q].axis], lib_error(rc, &d));
    }
    build_manifest(r, &m);
    if (tvpal_manifest_format(&m, &text) < 0)
        die_fail("out of memory");
    for (int k = -1; k < (int)r->o.nodes; k++) {
        char *path;
        int ok = k < 0 ? asprintf(&path, "%s/manifest.txt", r->partial)
                       : asprintf(&path, "%s/node-%d/manifest.txt",
                                  r->partial, k);
        rc = ok < 0 ? TVPAL_E_NOMEM
                    : tvpal_write_file_atomic(path, text, strlen(text),
                                                   &d);
        if (rc < 0)
            die_fail("%s: cannot write manifest: %s", r->partial,
                     lib_error(rc, &d));
        free(path);
    }
    free(text);
    tvpal_manifest_clear(&m);
    tvpal_checkpoint_remove(r->partial, NULL);
    tvpal_fsync_dir(r->partial);
}

/* Renames OUTDIR.partial to OUTDIR; with --force an existing OUTDIR goes
 * to OUTDIR.old first and is removed after. */
static void move_into_place(const struct run *r)
{
    const char *out = r->o.outdir;
    if (tvpal_exists(out)) {
        char *old;
        if (asprintf(&old, "%s.old", out) < 0)
            die_fail("out of memory");
        tvpal_rmtree(old);
        if (rename(out, old) < 0 || rename(r->partial, out) < 0)
            die_fail("%s: cannot replace: %s", out, strerror(errno));
        tvpal_rmtree(old);
        free(old);
    } else if (rename(r->partial, out) < 0) {
        die_fail("%s: cannot rename %s into place: %s", out, r->partial,
                 strerror(errno));
    }
}

/* Every value missing leaves nothing to encode or draw; present values
 * coded as missing (more missing-value patterns in a slice-window than the
 * code has indices for) are reported. */
static void check_missing(const struct run *r)
{
    if (!(r->st.vmin <= r->st.vmax))
        die_input("%s: every value is missing (NaN%s); expected some "
                  "present values", r->o.inputs[0],
                  r->o.nmissing ? " or a --missing value" : "");
    uint64_t dropped = 0;
    for (int i = 0; i < r->nthreads; i++)
        dropped += r->dropped[i];
    if (dropped)
        msg("warning: %llu present value%s coded as missing: slice-windows "
            "with more than 128 patterns of missing timesteps (a smaller "
            "--window avoids it)", (unsigned long long)dropped,
            dropped == 1 ? "" : "s");
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
    uint64_t total_bytes = 0;
    if (tvpal_dataset_open(&ds, r->o.outdir, &d) < 0)
        die_fail("%s: written dataset does not verify: %s", r->o.outdir,
                 d.msg);
    for (unsigned a = 0; a < 3; a++)
        total_bytes += ds->axis_bytes[a];
    tvpal_dataset_close(ds);
    const double axis_bytes = (double)total_bytes / 3.0;
    const double vts = (double)r->nvox * r->T, te = r->t_encode;
    printf("encoded %s: steps=%u window=%u nodes=%u bytes=%llu ratio=%.3f "
           "bpv=%.4f seconds=%.3f rate=%.2fM vox-steps/s threads=%d "
           "missing=%llu\n",
           r->o.outdir, r->T, r->N, r->o.nodes,
           (unsigned long long)total_bytes,
           (double)(r->step_bytes * r->T) / axis_bytes,
           axis_bytes * 8.0 / vts, te,
           (double)(r->T - r->start) * r->nvox / (te > 0 ? te : 1e-9) / 1e6,
           r->nthreads, (unsigned long long)r->st.missing);
}

static void run_free(struct run *r)
{
    prefetch_stop(r->pf);   /* before the input it reads is closed */
    for (uint32_t q = 0; q < r->nshard; q++)
        free(r->sj[q].rec);
    free(r->sj);
    for (int i = 0; i < r->nthreads; i++) {
        tvpal_swenc_free(r->enc[i]);
        free(r->samples[i]);
        free(r->tables[i]);
        free(r->fine_local[i]);
    }
    for (uint32_t i = 0; i < r->N; i++)
        free(r->ring[i]);
    free(r->ring);
    free(r->raw);
    free(r->enc);
    free(r->dropped);
    free(r->samples);
    free(r->tables);
    free(r->fine_local);
    free(r->jobs);
    free(r->fp);
    tvpal_checkpoint_stats_free(&r->st);
    free(r->partial);
    for (int i = 0; i < r->o.ninputs; i++)
        free(r->abs_inputs[i]);
    free(r->abs_inputs);
    tvpal_input_close(r->in);
    free(r->times);
}

/* Each step ends the program itself on failure (see `enum ending`). */
int main(int argc, char **argv)
{
    struct run r = {0};
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
    open_partial(&r);
    setup_shards(&r);
    open_or_restart_writers(&r);
    setup_workspace(&r);
    if (r.in)
        r.pf = prefetch_start(r.in, r.step_bytes);
    encode_steps(&r);
    check_missing(&r);
    warn_dominating_values(&r);
    finish_partial(&r);
    move_into_place(&r);
    print_summary(&r);
    run_free(&r);
    return 0;
}
