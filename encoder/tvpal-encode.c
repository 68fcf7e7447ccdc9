/* tvpal-encode: encodes a time series of volumes (raw files, NetCDF,
 * HDF5, VTK) into a tvpal dataset (paper section III; format:
 * common/format/FORMAT.md), through libtvpal's encoder (tvpal.h).
 *
 * The program is the options, the input and the reports; the encode is
 * the library's tvpal_encoder_encode, which reads the input as
 * encode_source_of presents it, in passes under the memory limit, writes
 * OUTDIR.partial/ and renames it to OUTDIR only when complete, and keeps
 * checkpoints that let a rerun of the same command continue an
 * interrupted job.  main runs the steps in order: options (g_optspec,
 * validate_opts), the input and its checks (encode_source.c), the output
 * and cluster checks, then encode_with_library: the encoder set up from
 * the options (open_encoder), the plan said (library_plan), the encode
 * with this program's progress callback (progress lines, checkpoints by
 * time, the test hooks: on_progress), the warnings, the finish and the
 * summary.  Under MPI every rank does the same with the job's
 * communicator as the library's collective (encode_cluster.c).  A step
 * that fails ends the program with the exit code of `enum ending`
 * (encode_say.h); the library's failures are mapped to them
 * (die_library).
 */
#define _GNU_SOURCE
#include "encode.h"
#include "encode_cluster.h"
#include "encode_output.h"
#include "encode_say.h"
#include "encode_source.h"
#include "tvpal_cli.h"
#include "tvpal_schedule.h"
#include "tvpal_chunkz.h"
#include "tvpal_clock.h"
#include "tvpal_comm.h"
#include "tvpal_engine.h"
#include "tvpal_eig.h"
#include "tvpal_error.h"
#include "tvpal_fs.h"
#include "tvpal_input.h"
#include "tvpal_levels.h"
#include "tvpal_output.h"

#include <getopt.h>
#include <math.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>


/* --help, in its sections: what the program does, then the options for
 * the input, the encoding and the output. */
static void usage_input(FILE *f)
{
    fputs(
"Input:\n"
"      --format F         auto (default: from each file's own bytes), raw,\n"
"                         netcdf, hdf5, vti (also .pvti, .pvd) or vtk\n"
"                         (legacy)\n"
"      --var NAME         the variable (NetCDF), dataset (HDF5:\n"
"                         /group/dataset) or point array (vti; vtk:\n"
"                         SCALARS, VECTORS, FIELD arrays) to encode\n"
"                         (default: the only one, or the active scalars;\n"
"                         tvpal-info --inspect FILE lists them)\n"
"      --time-dim NAME    NetCDF: the time dimension (default: the\n"
"                         unlimited one, or the one a CF time coordinate\n"
"                         names)\n"
"      --allow-external   HDF5: read a dataset whose data lives in other\n"
"                         files (an external link on its path, external\n"
"                         storage, a virtual dataset's sources); refused\n"
"                         by default, naming the file\n"
"      --magnitude        VTK (vti, vtk): encode a point array of several\n"
"                         components (a vector: NumberOfComponents, VECTORS)\n"
"                         as its length at each point, sqrt(x^2 + y^2 +\n"
"                         ...) in double rounded to float32 (refused by\n"
"                         default, naming the array); a scalar array is\n"
"                         read as it is\n"
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
"      --units TEXT       the values' units, shown by the player's legend\n"
"                         (default: the variable's units attribute, else\n"
"                         none)\n"
"      --missing V        source value V marks a missing value (repeatable,\n"
"                         up to 16; compared as float32).  Missing values\n"
"                         (also NaN, and NetCDF/HDF5 _FillValue,\n"
"                         missing_value and values outside valid_range)\n"
"                         decode as NaN, are left out of the value range\n"
"                         and the histogram, and are drawn transparent\n"
"      --nan-as VALUE     replace NaN, infinite and missing values by VALUE\n"
"                         instead (default: infinite values are refused,\n"
"                         naming file, timestep and voxel)\n", f);
}

static void usage_encoding(FILE *f)
{
    fputs(
"Encoding:\n"
"  -w, --window N         timesteps per DCT window, 1..16 (default 4;\n"
"                         N = 1 is the plain 8-bit Lloyd-Max baseline)\n"
"      --schedule S       joined (default: a slice's short first window\n"
"                         joins the next, so the indices take 8/N bits\n"
"                         per voxel-step at any length; first windows of\n"
"                         N..2N-1 steps, 2N-1 steps held in memory; needs\n"
"                         tvpal 0.4.0 to read) or staggered (the paper's:\n"
"                         windows of 1..N steps, N steps held, as before)\n"
"      --group G          palette groups: the G slices gG..gG+G-1 of an\n"
"                         axis share one decoder table per window (at most\n"
"                         262144 voxels: fewer slices where they are\n"
"                         larger).  Default 1, a table per slice-window.\n"
"                         Small slices' tables are most of the bits: 64^2\n"
"                         slices at N = 4, G = 8 store half the bits for\n"
"                         1 dB less (needs tvpal 0.4.0 to read).  auto:\n"
"                         each axis' G of 1, 2, 4 .. 16 measured on sample\n"
"                         windows (the least error + 2 ln 2 error(G=1) x\n"
"                         bits)\n"
"  -k, --nodes K          split every axis into K slabs, one per node,\n"
"                         written to OUTDIR/node-R/ (default 1)\n"
"      --axes LIST        the axes to encode: x, y and z, each at most\n"
"                         once, in any order (z, xz, xyz; default z: the\n"
"                         player draws every view from it); each is a full\n"
"                         copy of the data, so xyz takes three times the\n"
"                         time and the bytes\n"
"  -j, --threads J        worker threads (default: all cores)\n"
"      --refine K         up to K iterations of generalized Lloyd (k-means)\n"
"                         on each slice-window's voxel series, from the DCT\n"
"                         code and from k-means++ seeds (the better after 2\n"
"                         goes on; 0..64, default 0): higher PSNR, same\n"
"                         format\n"
"      --index-coding C   zstd (default: each slice-window's table and\n"
"                         indices stored as a zstd frame where that makes\n"
"                         it smaller; the player inflates it as it reads\n"
"                         it; datasets need tvpal 0.4.0 or later) or none\n"
"                         (every slice-window stored plain, as before)\n"
"      --index-level L    zstd level of --index-coding zstd, 1..19\n"
"                         (default 3; higher: smaller files, slower\n"
"                         encoding, the same reading speed)\n"
"      --transform T      dct (default) or klt (per slice-window principal\n"
"                         components, LAPACK)\n"
"      --alloc A          bit allocation: variance (default, the paper's\n"
"                         rule) or greedy-mse (by measured quantizer error)\n"
"      --naive            the paper's naive variant (uniform quantizers,\n"
"                         inverse-DCT tables): a floor for comparisons\n"
"      --table FMT        decoder tables: auto (default: per slice-window,\n"
"                         16-bit with the coarsest step that adds under\n"
"                         1e-4 of the window's own squared error, float32\n"
"                         where a wide range or exact values need it),\n"
"                         f32 (float32 everywhere)\n"
"                         or u16 (16-bit scaled per slice-window\n"
"                         everywhere: half the table bytes, error <= (max -\n"
"                         min) / 131070 per entry)\n"
"      --levels L         also L coarser levels of detail (0..8, default\n"
"                         0), each the 2x2x2 average of the one before\n"
"                         (missing values left out), encoded the same way\n"
"                         into OUTDIR/level-1 .. level-L; the player draws\n"
"                         from the finest whose voxels cover about a pixel\n", f);
}

static void usage(FILE *f)
{
    fputs(
"Usage: " PROG " [--dims NXxNYxNZ] [options] -o OUTDIR INPUT...\n"
"Encode a time series of volumes into a tvpal dataset: for each axis (or\n"
"those of --axes), 8-bit indexed slices with per-window decoder tables.  INPUT is raw (one file per\n"
"timestep, in time order, or one file holding all timesteps with --steps),\n"
"or NetCDF, VTK ImageData (.vti, .pvti, a .pvd collection) or legacy VTK\n"
"files, which say their own dims, type and steps (a NetCDF file may hold\n"
"several timesteps: a time dimension; a .pvd lists its files and times).\n"
"\n", f);
    usage_input(f);
    usage_encoding(f);
    fprintf(f,
"Output:\n"
"  -o, --output OUTDIR    dataset directory (must not exist)\n"
"  -f, --force            replace an existing OUTDIR\n"
"  -q, --quiet            no progress output\n"
"      --checkpoint-every S  save the resume checkpoint at most every S\n"
"                         seconds (default 10; 0: after every timestep)\n"
"      --mem-limit SIZE   memory to stay under, e.g. 12G (default: 3/4 of\n"
"                         the physical memory, the cgroup's limit or what\n"
"                         ulimit -v leaves, the smallest); more passes when\n"
"                         a window does not fit, the same bytes\n"
"      --dry-run          print the plan (passes, memory) and exit\n"
"      --shard-dir PAT    under MPI: each rank's node directory, %%r the\n"
"                         rank (node-local disks)\n"
"  -h, --help             this help\n"
"  -V, --version          version\n"
"\n"
"An interrupted run leaves OUTDIR.partial/; running the same command again\n"
"continues it.  Exit status: 0 success, 1 failure, 2 bad input or usage.\n");
}

/* ---------------------------------------------------------------- options */


/* How an option's argument is parsed (parse_option). */
enum optkind {
    OPT_DIMS,      /* NXxNYxNZ into dims */
    OPT_TYPE,      /* sample type into type */
    OPT_U32,       /* whole number in [lo, hi] into the uint32_t at field */
    OPT_U32_AUTO,  /* OPT_U32, or "auto": 0 */
    OPT_CHOICE,    /* choice[i] sets the int at field to i */
    OPT_TABLE,     /* f32, u16 or auto into table_format (its code) */
    OPT_FLAG,      /* no argument: sets the int at field to 1 */
    OPT_NAN_AS,    /* finite |value| <= TVPAL_VALUE_MAX into nan_as */
    OPT_MISSING,   /* a finite value appended to missing[] */
    OPT_OUTPUT,    /* OUTDIR */
    OPT_FORMAT,    /* input format into format */
    OPT_TEXT,      /* the argument into the const char * at field */
    OPT_SPACING,   /* DX,DY,DZ > 0 into spacing */
    OPT_ORIGIN,    /* OX,OY,OZ into origin */
    OPT_SIZE,      /* bytes ("12G") into the uint64_t at field */
    OPT_AXES,      /* a set of axes ("xz") into axes */
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
    {"window", 'w', OPT_U32, offsetof(struct opts, window), 1, 16,
     {0}, "a whole number from 1 to 16"},
    {"schedule", OPT_LONG_ONLY + 26, OPT_CHOICE,
     offsetof(struct opts, staggered), 0, 0, {"joined", "staggered"},
     "joined or staggered"},
    {"group", OPT_LONG_ONLY + 27, OPT_U32_AUTO, offsetof(struct opts, group),
     1, TVPAL_GROUP_MAX, {0}, "auto or a whole number from 1 to 1024"},
    {"nodes", 'k', OPT_U32, offsetof(struct opts, nodes), 1, UINT32_MAX,
     {0}, "a whole number >= 1"},
    {"axes", OPT_LONG_ONLY + 19, OPT_AXES, 0, 0, 0, {0},
     "one or more of the axes x, y, z, each once (z, xz, xyz)"},
    {"threads", 'j', OPT_U32, offsetof(struct opts, threads), 1, 1024, {0},
     "1..1024"},
    {"table", OPT_LONG_ONLY + 1, OPT_TABLE, 0, 0, 0, {0},
     "f32, u16 or auto"},
    {"index-coding", OPT_LONG_ONLY + 24, OPT_CHOICE,
     offsetof(struct opts, index_none), 0, 0, {"zstd", "none"},
     "zstd or none"},
    {"index-level", OPT_LONG_ONLY + 25, OPT_U32,
     offsetof(struct opts, index_level), 1, 19, {0}, "1..19"},
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
     "DX,DY,DZ, three numbers > 0, each from 2.2250738585072014e-308 to "
     "1.7976931348623157e+308 (what a manifest holds)"},
    {"origin", OPT_LONG_ONLY + 13, OPT_ORIGIN, 0, 0, 0, {0},
     "OX,OY,OZ, three finite numbers, each 0 or of magnitude from "
     "2.2250738585072014e-308 to 1.7976931348623157e+308"},
    {"times", OPT_LONG_ONLY + 10, OPT_TEXT, offsetof(struct opts, times_file),
     0, 0, {0}, NULL},
    {"time-units", OPT_LONG_ONLY + 11, OPT_TEXT,
     offsetof(struct opts, time_units), 0, 0, {0}, NULL},
    {"units", OPT_LONG_ONLY + 20, OPT_TEXT, offsetof(struct opts, units), 0,
     0, {0}, NULL},
    {"mem-limit", OPT_LONG_ONLY + 15, OPT_SIZE,
     offsetof(struct opts, mem_limit), 0, 0, {0},
     "a size such as 12G, 800M or 1073741824 (bytes)"},
    {"checkpoint-every", OPT_LONG_ONLY + 21, OPT_U32,
     offsetof(struct opts, checkpoint_every), 0, 86400, {0},
     "a whole number of seconds, 0..86400"},
    {"shard-dir", OPT_LONG_ONLY + 16, OPT_TEXT,
     offsetof(struct opts, shard_pat), 0, 0, {0}, NULL},
    {"output", 'o', OPT_OUTPUT, 0, 0, 0, {0}, NULL},
    {"force", 'f', OPT_FLAG, offsetof(struct opts, force), 0, 0, {0}, NULL},
    {"allow-external", OPT_LONG_ONLY + 22, OPT_FLAG,
     offsetof(struct opts, allow_external), 0, 0, {0}, NULL},
    {"magnitude", OPT_LONG_ONLY + 23, OPT_FLAG,
     offsetof(struct opts, magnitude), 0, 0, {0}, NULL},
    {"dry-run", OPT_LONG_ONLY + 17, OPT_FLAG, offsetof(struct opts, dry_run), 0,
     0, {0}, NULL},
    {"levels", OPT_LONG_ONLY + 18, OPT_U32, offsetof(struct opts, levels), 0,
     8, {0}, "0..8"},
    {"quiet", 'q', OPT_FLAG, offsetof(struct opts, quiet), 0, 0, {0}, NULL},
    {"help", 'h', OPT_HELP, 0, 0, 0, {0}, NULL},
    {"version", 'V', OPT_VERSION, 0, 0, 0, {0}, NULL},
};
#define NOPTS (sizeof g_optspec / sizeof *g_optspec)

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
    case OPT_U32_AUTO:
        if (!strcmp(arg, "auto")) {
            *(uint32_t *)(base + sp->field) = 0;
            return;
        }
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
    case OPT_TABLE: {
        /* The manifest's names for the shard formats (FORMAT.md 3.2). */
        static const uint32_t formats[] = {TVPAL_TABLE_F32, TVPAL_TABLE_U16,
                                           TVPAL_TABLE_CHUNK};
        for (size_t i = 0; i < sizeof formats / sizeof *formats; i++)
            if (!strcmp(arg, tvpal_manifest_table_name(formats[i]))) {
                o->table_format = (int)formats[i];
                return;
            }
        break;
    }
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
    case OPT_AXES:
        if (tvpal_axes_parse(arg, &o->axes) < 0)
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
            /* the manifest's rule: what it would not read back is
             * refused here (and a level's grid in check_grid) */
            good &= tvpal_manifest_number_ok(v[i]) &&
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
                       .group = 1, .index_level = TVPAL_CHUNKZ_LEVEL,
                       .table_format = TVPAL_TABLE_CHUNK,
                       .checkpoint_every = 10,
                       .axes = ENCODE_AXES_DEFAULT};
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
    for (unsigned k = 1; k <= o->levels; k++) {
        uint32_t a[3], b[3];
        tvpal_level_dims(d, k - 1, a);
        tvpal_level_dims(d, k, b);
        if (a[0] == b[0] && a[1] == b[1] && a[2] == b[2])
            die_usage("--levels %u: level %u would be %ux%ux%u again; at "
                      "most %u level(s) for %ux%ux%u", o->levels, k, b[0],
                      b[1], b[2], k - 1, d[0], d[1], d[2]);
        for (unsigned x = 0; x < 3; x++)
            if (b[x] < o->nodes)
                die_usage("--levels %u: level %u (%ux%ux%u) has fewer %c "
                          "slices than --nodes %u", o->levels, k, b[0], b[1],
                          b[2], "xyz"[x], o->nodes);
    }
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
                     "steps=%u nan_as=%s%.17g coding=%u schedule=%d "
                     "group=%u",
                     o->table_format,
                     o->refine,
                     o->naive, o->klt, o->alloc_mse, o->dims[0], o->dims[1],
                     o->dims[2], tvpal_type_name(o->type),
                     o->big_endian ? "big" : "little", o->window, o->nodes,
                     o->steps_single, o->has_nan_as ? "" : "none:",
                     o->has_nan_as ? o->nan_as : 0.0,
                     o->index_none ? 0u : o->index_level, o->staggered,
                     o->group);
    if (n < 0)
        return NULL;
    for (unsigned i = 0; i < o->nmissing; i++) {
        n = asprintf(&t, "%s missing=%.9g", s, (double)(float)o->missing[i]);
        free(s);
        if (n < 0)
            return NULL;
        s = t;
    }
    /* The axes encoded decide which shards exist (a resume with others
     * starts over); all three keep the fingerprint of earlier versions,
     * whatever the default. */
    if (o->axes != TVPAL_AXES_ALL) {
        char axes[4];
        n = asprintf(&t, "%s axes=%s", s, tvpal_axes_format(o->axes, axes));
        free(s);
        if (n < 0)
            return NULL;
        s = t;
    }
    if (!in)
        return s;
    /* Raw jobs keep the fingerprint of earlier versions (their partial
     * outputs still resume); so do scalar arrays, --magnitude or not (the
     * same values).  A vector read as its length (--magnitude) is another
     * job than any read of a scalar array of its name. */
    const struct tvpal_input_info *ii = tvpal_input_info(in);
    n = asprintf(&t, "%s format=%s var=%s%s", s,
                 tvpal_input_format_name(o->format), ii->var,
                 ii->components > 1 ? " magnitude=1" : "");
    free(s);
    return n < 0 ? NULL : t;
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
    struct tvpal_diag d = {{0}};
    int rc = tvpal_output_check(o->outdir, 0, "use --force to", &d);
    if (rc < 0 && (rc != TVPAL_E_EXIST || !o->force))
        die_usage("%s", d.msg[0] ? d.msg : "out of memory");
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
    /* With --force, only a tvpal dataset is replaced. */
    if ((rc = tvpal_output_check(o->outdir, o->force, "use --force to",
                                 &d)) < 0)
        die_usage("%s", d.msg);
}

/* The files a job reads, for its fingerprint: the inputs given, then (a
 * self-describing series) every file of the series in order, those a .pvd
 * lists included: a rewritten DataSet resumed the job with old and new
 * steps mixed.  *files (malloc'ed) borrows the names; their count, or -1
 * out of memory. */
static int job_files(const struct run *r, char ***files)
{
    const uint32_t T = r->in ? tvpal_input_info(r->in)->steps : 0;
    char **f = malloc(sizeof *f * ((size_t)r->o.ninputs + T + 1));
    if (!f)
        return -1;
    int n = 0;
    for (int i = 0; i < r->o.ninputs; i++)
        f[n++] = r->o.inputs[i];
    const char *last = NULL;
    for (uint32_t t = 0; t < T; t++) {
        const char *p = tvpal_input_file(r->in, t, NULL);
        if (p != last)
            f[n++] = (char *)p;
        last = p;
    }
    *files = f;
    return n;
}

/* ------------------------------------------------------------------ plan */

/* The worker threads: -j, else all cores (tvpal_pool_default_threads:
 * OMP_NUM_THREADS, else the CPUs this process may run on). */
static void choose_threads(struct run *r)
{
    r->nthreads = r->o.threads ? (int)r->o.threads
                               : (int)tvpal_pool_default_threads();
}

static void print_size(char *buf, size_t cap, uint64_t b)
{
    if (b >= (uint64_t)1 << 30)
        snprintf(buf, cap, "%.2f GiB", (double)b / (1u << 30));
    else
        snprintf(buf, cap, "%.1f MiB", (double)b / (1u << 20));
}

/* Boxes in the ring: the longest window's steps. */
static uint32_t ring_slots(const struct run *r)
{
    const struct tvpal_schedule sc = tvpal_schedule_of(
        r->N, r->T, r->o.staggered ? TVPAL_SCHEDULE_STAGGERED
                                   : TVPAL_SCHEDULE_JOINED, 1);
    return tvpal_schedule_max_len(&sc);
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
/* The memory limit: --mem-limit, else what this process's share of the
 * machine or its cgroup allows (encode_default_limit); r->limit_why says
 * which. */
static void choose_limit(struct run *r)
{
    const struct opts *o = &r->o;
    if (o->mem_limit)
        snprintf(r->limit_why, sizeof r->limit_why, "--mem-limit");
    r->limit = o->mem_limit ? o->mem_limit
                            : encode_default_limit(local_ranks(r),
                                                   r->limit_why,
                                                   sizeof r->limit_why);
}

/* ------------------------------------------------------------- finishing */

/* The grid and times of every manifest this job writes (level 0's and
 * each coarser level's), by the reader's rule (tvpal_manifest_check_grid),
 * before any work: a value a dataset could not read back is refused,
 * naming where it came from. */
static void check_grid(const struct run *r)
{
    const struct opts *o = &r->o;
    double s0[3], o0[3];
    grid_of(r, s0, o0);
    for (unsigned k = 0; k <= o->levels; k++) {
        double sk[3], ok[3];
        uint32_t dk[3];
        tvpal_level_dims(o->dims, k, dk);
        tvpal_level_grid(s0, o0, o->dims, dk, sk, ok);
        if (k == 0) {   /* level 0's own, not through a product */
            memcpy(sk, s0, sizeof sk);
            memcpy(ok, o0, sizeof ok);
        }
        struct tvpal_diag d = {{0}};
        if (tvpal_manifest_check_grid(sk, ok, k ? NULL : r->times,
                                      k || !r->times ? 0 : r->T, &d) == 0)
            continue;
        const char *from = !strncmp(d.msg, "spacing", 7)
                               ? (o->have_spacing ? "--spacing" : o->inputs[0])
                           : !strncmp(d.msg, "origin", 6)
                               ? (o->have_origin ? "--origin" : o->inputs[0])
                           : o->times_file ? o->times_file : o->inputs[0];
        if (k)
            die_usage("%s: level %u (--levels): %s", from, k, d.msg);
        die_usage("%s: %s", from, d.msg);
    }
}





/* What the written dataset takes, found by reading it back. */
struct written {
    uint64_t disk, shards;      /* every file; the stored axes' shards */
    uint64_t tables[2];         /* chunks with float32, 16-bit tables */
    uint64_t level_bytes;       /* the coarser levels' files */
    uint32_t group[3];          /* each axis' palette group size */
};

/* What the dataset at OUTDIR takes on disk, from the reader's sizes
 * (tvpal.h; the library read it back before it put it in place): disk
 * counts every file (the stored axes' shards of every node, the
 * manifests, the levels).  One process: under MPI the node directories
 * may be on other machines (cluster_sizes). */
static void measure_written(const struct run *r, struct written *w)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_reader *rd = NULL;
    struct tvpal_sizes sz;
    *w = (struct written){0};
    int rc = tvpal_reader_open(&rd, r->o.outdir, &d);
    if (rc == 0)
        memcpy(w->group, tvpal_reader_info(rd)->group, sizeof w->group);
    for (uint32_t k = 0; rc == 0 && k <= r->o.levels; k++) {
        if ((rc = tvpal_reader_sizes(rd, k, &sz, &d)) < 0)
            break;
        if (k == 0) {
            w->disk = sz.disk_bytes;
            for (unsigned a = 0; a < 3; a++) {
                w->shards += sz.axis_bytes[a];
                w->tables[0] += sz.chunks_f32[a];
                w->tables[1] += sz.chunks_u16[a];
            }
        } else {
            w->level_bytes += sz.disk_bytes;
        }
    }
    tvpal_reader_close(rd);
    if (rc < 0)
        die_fail("%s: cannot size the dataset: %s", r->o.outdir,
                 lib_error(rc, &d));
}

/* The bytes of the files the job read (each once, however it was named:
 * a NetCDF file of many steps, a .pvd and its DataSets, an input given
 * relative and found again absolute), as they are on disk: what the
 * user's input takes; 0 where unknown. */
struct file_id {
    dev_t dev;
    ino_t ino;
    off_t size;
};

static int cmp_file_id(const void *a, const void *b)
{
    const struct file_id *x = a, *y = b;
    if (x->dev != y->dev)
        return x->dev < y->dev ? -1 : 1;
    return x->ino < y->ino ? -1 : x->ino > y->ino;
}

static uint64_t input_bytes(const struct run *r)
{
    char **f = NULL;
    const int n = job_files(r, &f);
    struct file_id *id = n > 0 ? malloc(sizeof *id * (size_t)n) : NULL;
    size_t k = 0;
    for (int i = 0; id && i < n; i++) {
        struct stat st;
        if (stat(f[i], &st) == 0 && S_ISREG(st.st_mode))
            id[k++] = (struct file_id){st.st_dev, st.st_ino, st.st_size};
    }
    free(f);
    if (k)
        qsort(id, k, sizeof *id, cmp_file_id); /* a file's names meet */
    uint64_t sum = 0;
    for (size_t i = 0; i < k; i++)
        if (i == 0 || cmp_file_id(&id[i], &id[i - 1]))
            sum += (uint64_t)id[i].size;
    free(id);
    return sum;
}

/* Prints the closing key=value line on stdout: ratio is the source bytes
 * over the dataset's bytes on disk and bpv their bits per voxel-timestep
 * (under MPI every rank's node directory, wherever --shard-dir put it,
 * and OUTDIR's manifest).  axis_ratio is the source bytes over the bytes
 * of one stored axis of level 0 (the mean over the stored axes), the
 * figure ratio was before FORMAT.md 1.6. */
static void print_summary(const struct run *r, const struct written *w)
{
    const uint64_t disk = r->mpi ? r->cluster_bytes : w->disk;
    const uint64_t shards = r->mpi ? r->cluster_shard_bytes : w->shards;
    char tb[96] = "";
    if (!r->mpi)   /* under MPI the shards may be on other machines */
        snprintf(tb, sizeof tb, " tables_u16=%llu tables_f32=%llu",
                 (unsigned long long)w->tables[1],
                 (unsigned long long)w->tables[0]);
    const unsigned naxes = tvpal_axes_count(r->o.axes);
    const double src = (double)(r->step_bytes * r->T);
    const double axis_bytes = (double)shards / naxes;
    const double vts = (double)r->nvox * r->T;
    const double te = r->mpi ? r->cluster_seconds : r->t_encode;
    const uint64_t work = r->mpi ? r->cluster_work
                                 : r->prog.work - r->prog.work_at_start;
    /* The coarser levels' files, also part of bytes (and of ratio and
     * bpv): what they add is said apart. */
    char lv[96] = "", axes[4], gr[48] = "";
    /* The palette groups (measured with --group auto), per stored axis. */
    for (unsigned a = 0, n = 0; r->o.group != 1 && !r->mpi && a < 3; a++)
        if (r->o.axes & TVPAL_AXIS_BIT(a))
            n += (unsigned)snprintf(gr + n, sizeof gr - n, "%s%c:%u",
                                    n ? "," : " groups=", "xyz"[a],
                                    w->group[a]);
    if (r->o.levels)
        snprintf(lv, sizeof lv, " levels=%u levels_bytes=%llu", r->o.levels,
                 (unsigned long long)(r->mpi ? r->cluster_level_bytes
                                             : w->level_bytes));
    /* The two other bases a user compares with: the values as float32
     * (the same for any input format), and the input files on disk. */
    const uint64_t in = input_bytes(r);
    char rin[48] = "";
    if (in)
        snprintf(rin, sizeof rin, " ratio_input=%.3f", (double)in / disk);
    printf("encoded %s: steps=%u window=%u nodes=%u axes=%s bytes=%llu "
           "ratio=%.3f ratio_f32=%.3f%s axis_ratio=%.3f bpv=%.4f "
           "seconds=%.3f rate=%.2fM "
           "vox-steps/s threads=%d missing=%llu passes=%u%s%s%s\n",
           r->o.outdir, r->T, r->N, r->o.nodes,
           tvpal_axes_format(r->o.axes, axes), (unsigned long long)disk,
           src / (double)disk, vts * 4.0 / (double)disk, rin,
           src / axis_bytes, (double)disk * 8.0 / vts,
           te, (double)work / naxes / (te > 0 ? te : 1e-9) / 1e6,
           r->nthreads * cluster_size(r),
           (unsigned long long)r->missing, r->passes, tb, gr, lv);
}


static void run_free(struct run *r)
{
    encode_source_close(r);
    for (int i = 0; i < r->o.ninputs; i++)
        free(r->abs_inputs[i]);
    free(r->abs_inputs);
    free(r->partial);
    tvpal_input_close(r->in);
    tvpal_pool_free(r->in_pool);
    free(r->times);
}

/* ------------------------------------------------------ through libtvpal
 *
 * One process encodes through the library's encoder (tvpal.h): the
 * options become its parameters, the input its source (encode_source_of),
 * and its progress callback draws the progress lines, saves checkpoints
 * by time and runs the test hooks; its failures become this program's
 * messages and exit codes. */

/* The progress callback's state. */
struct drive {
    long fault_after;        /* TVPAL_ENCODE_FAULT_AFTER: stop after this
                              * unit (-1: never), */
    int fault_nosave;        /* without saving its checkpoint, */
    int fault_fail;          /* failing with a message (else killed); */
    unsigned fault_level;    /* TVPAL_ENCODE_FAULT_LEVEL: stop before
                              * this level is complete (0: never) */
    int faulted;             /* 1: stopped by the unit hook, 2: by the
                              * level hook */
    uint64_t fault_unit;
    int seen;                /* the first call came */
    int all_missing;         /* the encode failed finding every value
                              * missing (its statistics say so) */
    int levels_inline;       /* the plan's */
};

/* The job's identity for the library's checkpoints: the options that
 * decide the shards and the files read (every file of a series, those a
 * .pvd lists, with a CRC of their first 4 KiB), so that a rerun of the
 * same command continues and another input starts over. */
static char *job_identity(const struct run *r)
{
    char *params = job_params(&r->o, r->in), *id = NULL;
    char **files = NULL;
    const int n = job_files(r, &files);
    if (!params || n < 0 ||
        tvpal_checkpoint_fingerprint(params, files, n, r->in ? 4096 : 0,
                                     &id) < 0)
        die_fail("out of memory");
    free(files);
    free(params);
    return id;
}

/* The first call: where the encode starts, and the levels it makes. */
static void say_start(struct run *r, const struct drive *dv,
                      const struct tvpal_progress *p)
{
    const struct opts *o = &r->o;
    r->prog.work_at_start = p->work;
    r->prog.total = p->total;
    r->prog.units = p->units;
    if (p->started_over)  /* said with -q too: work is done again */
        msg("%s: its partial output is another job's or does not resume; "
            "starting the job over", r->partial);
    if (o->quiet)
        return;
    if (p->level0_kept && p->levels_before != o->levels)
        msg("resuming with --levels %u (the earlier run asked for %u): level "
            "0 kept", o->levels, p->levels_before);
    if (p->resumed && p->unit == p->units)
        msg("resuming %s: every step is encoded; finishing", r->partial);
    else if (p->resumed)
        msg("resuming %s at pass %llu of %u, timestep %llu of %u", r->partial,
            (unsigned long long)(p->unit / r->T) + 1, p->passes,
            (unsigned long long)(p->unit % r->T), r->T);
    for (unsigned k = 1; k <= o->levels; k++) {
        char *lv = NULL;
        if (asprintf(&lv, "%s/level-%u", r->partial, k) < 0)
            die_fail("out of memory");
        const int done = p->level0_kept && tvpal_exists(lv);
        free(lv);
        uint32_t dk[3];
        tvpal_level_dims(o->dims, k, dk);
        if (!done)
            msg("level %u of %u: %ux%ux%u%s", k, o->levels, dk[0], dk[1],
                dk[2], dv->levels_inline && !p->level0_kept
                           ? ", beside level 0" : "");
    }
}

/* The library's progress callback: progress lines; at a unit's end a
 * checkpoint once --checkpoint-every seconds have passed since the last
 * (a rerun after a crash redoes at most that much work; a checkpoint is
 * text of O(histogram classes + shards x steps) and an fsync: saved after
 * every step it took 0.13 of 0.90 CPU-seconds of a small encode), after
 * the last unit (a rerun then only finishes), and at a test fault, so that
 * the hooks' resume points stay where they say.  The test hooks:
 * TVPAL_ENCODE_FAULT_AFTER=S stops after S units (steps of passes) as an
 * interruption would (killed, or with TVPAL_ENCODE_FAULT=fail failing with
 * a message, both after saving the checkpoint of unit S; with
 * TVPAL_ENCODE_FAULT=nosave killed without saving it);
 * TVPAL_ENCODE_FAULT_LEVEL=k stops once the levels before k are complete
 * (k = 1: after level 0's last unit). */
static int on_progress(void *ctx, const struct tvpal_progress *p)
{
    struct run *r = ctx;
    struct drive *dv = r->drive;
    if (!dv->seen) {
        dv->seen = 1;
        say_start(r, dv, p);
        r->prog.t0 = r->prog.last = r->ckpt_last = tvpal_now();
    }
    r->prog.work = p->work;
    r->prog.unit = p->unit;
    report_progress(r, 0);
    if (!p->unit_end)
        return TVPAL_GO_ON;
    if (p->level) {
        if (dv->fault_level == p->level + 1) {
            dv->faulted = 2;
            return TVPAL_STOP;
        }
        return TVPAL_GO_ON;
    }
    if (dv->fault_level == 1 && p->unit == p->units) {
        dv->faulted = 2;
        return TVPAL_SAVE_AND_STOP;
    }
    if (dv->fault_after >= 0 && (long)p->unit >= dv->fault_after) {
        dv->faulted = 1;
        dv->fault_unit = p->unit;
        return dv->fault_nosave ? TVPAL_STOP : TVPAL_SAVE_AND_STOP;
    }
    const double now = tvpal_now();
    if (p->unit == p->units ||
        now - r->ckpt_last >= (double)r->o.checkpoint_every) {
        r->ckpt_last = now;
        return TVPAL_SAVE_AND_GO_ON;
    }
    return TVPAL_GO_ON;
}

/* The encoder with the run's options, grid, times, units, missing values
 * and provenance.  The options were checked: a refusal here is a bug or
 * out of memory. */
static struct tvpal_encoder *open_encoder(struct run *r)
{
    const struct opts *o = &r->o;
    struct tvpal_encoder *e = NULL;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_encoder_open(&e, o->outdir, o->dims, r->T, &d);
    const struct { enum tvpal_param p; double v; } set[] = {
        {TVPAL_PARAM_WINDOW, o->window}, {TVPAL_PARAM_AXES, o->axes},
        {TVPAL_PARAM_SCHEDULE, o->staggered ? TVPAL_SCHEDULE_STAGGERED
                                            : TVPAL_SCHEDULE_JOINED},
        {TVPAL_PARAM_GROUP, o->group},  /* 0: auto, TVPAL_GROUP_AUTO */
        {TVPAL_PARAM_NODES, o->nodes}, {TVPAL_PARAM_TABLE, o->table_format},
        {TVPAL_PARAM_REFINE, o->refine}, {TVPAL_PARAM_NAIVE, o->naive},
        {TVPAL_PARAM_INDEX_LEVEL, o->index_level},
        {TVPAL_PARAM_INDEX_CODING, o->index_none ? TVPAL_CODING_NONE
                                                 : TVPAL_CODING_ZSTD},
        {TVPAL_PARAM_TRANSFORM, o->klt ? TVPAL_TRANSFORM_KLT
                                       : TVPAL_TRANSFORM_DCT},
        {TVPAL_PARAM_ALLOC, o->alloc_mse ? TVPAL_ALLOC_GREEDY_MSE
                                         : TVPAL_ALLOC_VARIANCE},
        {TVPAL_PARAM_THREADS, r->nthreads},
        {TVPAL_PARAM_MEM_LIMIT, (double)r->limit},
        {TVPAL_PARAM_FORCE, o->force},
        {TVPAL_PARAM_CHECKPOINT, 0}, /* saved by time (on_progress) */
        {TVPAL_PARAM_LEVELS, o->levels}};
    for (size_t i = 0; rc == 0 && i < sizeof set / sizeof *set; i++)
        rc = tvpal_encoder_set(e, set[i].p, set[i].v, &d);
    if (rc == 0 && o->has_nan_as)
        rc = tvpal_encoder_set(e, TVPAL_PARAM_NAN_AS, o->nan_as, &d);
    double sp[3], or[3];
    grid_of(r, sp, or);
    if (rc == 0)
        rc = tvpal_encoder_set_grid(e, sp, or, &d);
    if (rc == 0 && r->times)
        rc = tvpal_encoder_set_times(e, r->times, r->time_units, &d);
    if (rc == 0)
        rc = tvpal_encoder_set_units(e, r->units, &d);
    if (rc == 0 && o->nmissing)
        rc = tvpal_encoder_set_missing(e, o->missing, o->nmissing, &d);
    /* Where the values came from: the files as given (absolute once
     * checked), one of every step, one per step, or a series. */
    char *var = NULL;
    struct tvpal_provenance pv = {
        .encoder = PROG " " PACKAGE_VERSION, .format = "raw",
        .sources = (const char *const *)o->inputs,
        .nsources = (uint32_t)o->ninputs,
        .single_file = o->steps_single != 0};
    if (r->in) {
        const struct tvpal_input_info *in = tvpal_input_info(r->in);
        pv.format = tvpal_input_format_name(o->format);
        pv.single_file = o->ninputs == 1 && r->T > 1;
        pv.series = o->ninputs > 1 && (uint32_t)o->ninputs != r->T;
        /* a vector's length says so (tvpal-report reads "NAME
         * (magnitude)" back as NAME with --magnitude) */
        if (asprintf(&var, "%s%s", in->var,
                     in->components > 1 ? " (magnitude)" : "") < 0)
            die_fail("out of memory");
        pv.var = var;
    }
    if (rc == 0)
        rc = tvpal_encoder_set_provenance(e, &pv, &d);
    free(var);
    if (rc == TVPAL_E_NOMEM)
        die_fail("out of memory");
    if (rc < 0)
        die_usage("%s: %s", o->outdir, lib_error(rc, &d));
    return e;
}

static void say_plan(const struct run *r, const struct tvpal_plan *pl,
                     double read_factor);

/* The plan, said (or printed: --dry-run); a limit too small ends the
 * program (exit 2) with the smallest that would do. */
static void library_plan(struct run *r, struct tvpal_encoder *e,
                         const struct tvpal_source *src, struct tvpal_plan *pl)
{
    const struct opts *o = &r->o;
    struct tvpal_diag d = {{0}};
    char lim[32], need[32];
    int rc = tvpal_encoder_plan(e, src, pl, &d);
    print_size(lim, sizeof lim, r->limit);
    print_size(need, sizeof need, pl->min_limit);
    if (rc == TVPAL_E_RANGE && pl->levels_over)
        die_usage("memory limit %s (%s) is too small for --levels %u: the "
                  "levels are encoded after level 0 in this process, in one "
                  "pass each, together about %s; give --mem-limit %lluK or "
                  "more", lim, r->limit_why, o->levels, need,
                  (unsigned long long)((pl->min_limit + 1023) >> 10));
    if (rc == TVPAL_E_RANGE)
        die_usage("memory limit %s (%s) is too small for %ux%ux%u at "
                  "--window %u with %d thread%s: one slice per pass needs "
                  "%s%s; give --mem-limit %lluK or more (or fewer --threads)",
                  lim, r->limit_why, o->dims[0], o->dims[1], o->dims[2],
                  r->N, r->nthreads, r->nthreads == 1 ? "" : "s", need,
                  o->group != 1 ? " (a palette group's slices together)" : "",
                  (unsigned long long)((pl->min_limit + 1023) >> 10));
    if (rc == TVPAL_E_NOMEM)
        die_fail("out of memory");
    if (rc < 0)
        die_usage("%s", lib_error(rc, &d));
    const double read_factor = (double)pl->read_voxels /
                               ((double)r->nvox * r->T);
    if (o->dry_run && !o->quiet)
        say_plan(r, pl, read_factor);
    if (o->dry_run && r->mpi && r->node != 0)
        return;
    if (o->dry_run) {
        printf("plan %s: passes=%u passes_x=%u passes_y=%u passes_z=%u "
               "peak_bytes=%llu limit_bytes=%llu input_bytes=%.0f "
               "read_bytes=%.0f read_factor=%.2f\n", o->outdir, pl->passes,
               pl->passes_axis[0], pl->passes_axis[1], pl->passes_axis[2],
               (unsigned long long)pl->peak_bytes,
               (unsigned long long)r->limit, (double)r->step_bytes * r->T,
               (double)pl->read_voxels * tvpal_type_size(o->type),
               read_factor);
        return;
    }
    if (!o->quiet)
        say_plan(r, pl, read_factor);
}

/* The plan in words, on stderr. */
static void say_plan(const struct run *r, const struct tvpal_plan *pl,
                     double read_factor)
{
    const struct opts *o = &r->o;
    char lim[32], need[32], ring[32], desc[96];
    print_size(lim, sizeof lim, r->limit);
    if (pl->passes == 1) {
        char names[4];
        snprintf(desc, sizeof desc, "1 pass (%s%s from one ring)",
                 o->axes == TVPAL_AXES_ALL ? "all axes" : "axes ",
                 o->axes == TVPAL_AXES_ALL ? ""
                 : tvpal_axes_format(o->axes, names));
    } else {
        size_t n = (size_t)snprintf(desc, sizeof desc, "%u passes (",
                                    pl->passes);
        const char *sep = "";
        for (unsigned a = 0; a < 3 && n < sizeof desc; a++)
            if (pl->passes_axis[a]) {
                n += (size_t)snprintf(desc + n, sizeof desc - n, "%s%c %u",
                                      sep, "xyz"[a], pl->passes_axis[a]);
                sep = ", ";
            }
        if (n < sizeof desc)
            snprintf(desc + n, sizeof desc - n, ")");
    }
    print_size(need, sizeof need, pl->peak_bytes);
    print_size(ring, sizeof ring, pl->ring_bytes);
    if (pl->passes == 1)
        msg("plan: %s; about %s of the memory limit %s (%s)", desc, need,
            lim, r->limit_why);
    else if (r->mpi)
        msg("plan of rank 0 of %d: %s over its node's slabs, reading %.2f "
            "times the input's bytes (its z and y slabs, and whole rows for "
            "its x slab); about %s of the memory limit %s (%s)",
            cluster_size(r), desc, read_factor, need, lim, r->limit_why);
    else
        msg("plan: %s, reading the input %.2f times: one ring of all %u "
            "timesteps of the longest window would need %s, over the "
            "memory limit %s (%s); each pass needs about %s", desc,
            read_factor,
            ring_slots(r), ring, lim, r->limit_why, need);
    if (r->o.group == 0) /* --group auto: the plan before the measure */
        msg("plan: for palette groups of up to %u slices; the groups are "
            "measured first (their sample is read before the encode), and "
            "the encode plans again for the groups chosen",
            TVPAL_ENGINE_GROUP_AUTO_MAX);
}

/* A failed encode or finish: e released (the library keeps the partial
 * output where a rerun may continue it, and removes it after bad input),
 * then the program ends with the message and exit code of the failure. */
static void die_library(struct run *r, const struct drive *dv, int rc,
                        const struct tvpal_diag *d)
{
    const struct opts *o = &r->o;
    char text[TVPAL_DIAG_MAX + 1024];
    const char *msg_ = d->msg[0] ? d->msg : tvpal_strerror(rc);
    enum ending how = DIE_INPUT;
    int own = 0;             /* this rank's own words (a test hook) */
    unsigned t;
    unsigned long long x, y, z;
    if (dv && dv->faulted == 1 && !dv->fault_fail)
        raise(SIGKILL);
    if (r->mpi && !strncmp(msg_, "rank 0: ", 8))
        msg_ += 8;
    /* A refused value: the library names its step and voxel. */
    const int inf = sscanf(msg_, "step %u: an infinite value at voxel "
                           "(%llu,%llu,%llu)", &t, &x, &y, &z) == 4;
    const int big = !inf && sscanf(msg_, "step %u: a value beyond 1e37 at "
                                   "voxel (%llu,%llu,%llu)", &t, &x, &y,
                                   &z) == 4;
    const char *path = inf || big ? r->in ? tvpal_input_file(r->in, t, NULL)
                                  : o->inputs[o->steps_single ? 0 : t]
                                  : NULL;
    if (dv && dv->faulted == 2) {
        how = DIE_FAIL, own = 1;
        snprintf(text, sizeof text, "level %u: failed as "
                 "TVPAL_ENCODE_FAULT_LEVEL asks (rerun to resume)",
                 dv->fault_level);
    } else if (dv && dv->faulted == 1) {
        how = DIE_FAIL, own = 1;
        snprintf(text, sizeof text, "test fault after %llu steps (rerun to "
                 "resume)", (unsigned long long)dv->fault_unit);
    } else if (inf) {
        snprintf(text, sizeof text, "%s: timestep %u: infinite value at "
                 "voxel (%llu,%llu,%llu); expected finite values or NaN for "
                 "missing ones (use --nan-as VALUE to replace them)", path, t,
                 x, y, z);
    } else if (big) {
        snprintf(text, sizeof text, "%s: timestep %u: value at voxel "
                 "(%llu,%llu,%llu) exceeds the supported magnitude %g", path,
                 t, x, y, z, TVPAL_VALUE_MAX);
    } else if (dv && dv->all_missing) {
        snprintf(text, sizeof text, "%s: every value is missing (NaN%s); "
                 "expected some present values", o->inputs[0],
                 o->nmissing ? " or a --missing value" : "");
    } else if (rc == TVPAL_E_EXIST && strstr(msg_, ".lock")) {
        how = DIE_FAIL; /* the other job may end */
        snprintf(text, sizeof text, "%s: another encode is writing it (its "
                 "lock %s); wait for it or stop it", r->partial, msg_);
    } else {
        /* Before the first read the output cannot be made (no such
         * directory, not writable), as the checks before would say; a
         * failure that may pass keeps the partial output for a rerun. */
        snprintf(text, sizeof text, "%s", msg_);
        if (rc == TVPAL_E_EXIST || (dv && !dv->seen && rc != TVPAL_E_NOMEM))
            how = DIE_USAGE;
        else if (rc == TVPAL_E_OPEN || rc == TVPAL_E_READ ||
                 rc == TVPAL_E_WRITE || rc == TVPAL_E_SYS ||
                 rc == TVPAL_E_NOMEM || rc == TVPAL_E_CANCELED)
            how = DIE_FAIL;
    }
    if (!r->mpi) {
        if (how == DIE_FAIL)
            die_fail("%s", text);
        if (how == DIE_USAGE)
            die_usage("%s", text);
        die_input("%s", text);
    }
    /* Under MPI every rank has the failure from the library's rounds, in
     * the failing rank's words: rank 0 says it (and a rank its own test
     * hook's), and no rank leaves before it has (the launcher ends the
     * job at the first rank that exits with a failure). */
    if (r->node == 0 || own)
        cluster_say(r, text);
    cluster_end(r, how == DIE_FAIL ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE);
}

/* The warnings of the values' statistics (before the finish places the
 * dataset). */
static void warn_values(struct run *r, struct tvpal_encoder *e)
{
    struct tvpal_stats st;
    if (tvpal_encoder_stats(e, &st) < 0)
        return;
    r->missing = st.missing;
    warn_dropped(st.dropped);
    warn_spread(st.value_min, st.value_max, st.p_low, st.p_high,
                st.beyond_1e30, st.far, st.values - st.missing);
}

/* The progress lines' state and the test hooks' (see on_progress) in *dv
 * and r->prog: a bar on a terminal, else a line every 30 s;
 * TVPAL_PROGRESS_INTERVAL=S (a test hook) a line every S seconds, and the
 * library's calls as often. */
static void start_progress(struct run *r, struct tvpal_encoder *e,
                           const struct tvpal_plan *pl, struct drive *dv)
{
    const char *fault = getenv("TVPAL_ENCODE_FAULT_AFTER");
    const char *fault_rank = getenv("TVPAL_ENCODE_FAULT_RANK");
    if (fault_rank && atol(fault_rank) != (long)r->node)
        fault = NULL; /* TVPAL_ENCODE_FAULT_RANK=R: that MPI rank alone */
    const char *how = getenv("TVPAL_ENCODE_FAULT");
    const char *flevel = getenv("TVPAL_ENCODE_FAULT_LEVEL");
    *dv = (struct drive){
        .fault_after = fault ? atol(fault) : -1,
        .fault_nosave = how && !strcmp(how, "nosave"),
        .fault_fail = how && !strcmp(how, "fail"),
        .fault_level = flevel ? (unsigned)atoi(flevel) : 0,
        .levels_inline = pl->levels_inline};
    struct progress *p = &r->prog;
    p->tty = isatty(STDERR_FILENO);
    p->quiet = r->o.quiet || (r->mpi && r->node != 0);
    p->interval = p->tty ? 0.2 : 30.0;
    const char *iv = getenv("TVPAL_PROGRESS_INTERVAL");
    if (iv && atof(iv) > 0) {
        p->interval = atof(iv);
        tvpal_encoder_set(e, TVPAL_PARAM_PROGRESS,
                          p->interval < 0.001 ? 0.001 : p->interval, NULL);
    }
}

/* The whole job through the library's encoder: one process, or this
 * rank's part of the MPI job. */
static void encode_with_library(struct run *r, struct written *w)
{
    struct tvpal_encoder *e = open_encoder(r);
    struct tvpal_source src = encode_source_of(r);
    struct tvpal_plan pl;
    if (r->mpi) { /* every rank its node shard, node = rank */
        struct tvpal_diag d = {{0}};
        const struct tvpal_collective c = cluster_collective(r);
        uint32_t z0, nz;
        tvpal_slab(r->o.dims[2], r->o.nodes, r->node, &z0, &nz);
        int rc = tvpal_encoder_set_collective(e, &c, z0, nz, &d);
        if (rc == 0 && r->o.shard_pat)
            rc = tvpal_encoder_set_shard_dir(e, r->o.shard_pat, &d);
        if (rc < 0)
            die_usage("%s", lib_error(rc, &d));
    }
    library_plan(r, e, &src, &pl);
    if (r->o.dry_run) {
        tvpal_encoder_abort(e);
        return;
    }
    /* Every rank got here: the encode's rounds are the library's now. */
    cluster_ready(r);
    r->passes = pl.passes;
    struct drive dv;
    start_progress(r, e, &pl, &dv);
    char *id = job_identity(r);
    src.identity = id;
    src.progress = on_progress;
    r->drive = &dv; /* on_progress's, beside the reads' run */
    struct tvpal_diag d = {{0}};
    const double t0 = tvpal_now();
    int rc = tvpal_encoder_encode(e, &src, &d);
    free(id);
    r->t_encode = tvpal_now() - t0;
    r->drive = NULL;
    if (rc < 0 && dv.faulted == 1 && !dv.fault_fail)
        raise(SIGKILL); /* as an interruption would: nothing cleaned up */
    if (rc < 0) {
        struct tvpal_stats vs;
        dv.all_missing = rc == TVPAL_E_INVAL &&
                         tvpal_encoder_stats(e, &vs) == 0 && vs.values &&
                         !(vs.value_min <= vs.value_max);
        tvpal_encoder_abort(e); /* under MPI: joins the others' round */
        die_library(r, &dv, rc, &d);
    }
    report_progress(r, 1);
    warn_values(r, e);
    if ((rc = tvpal_encoder_finish(e, &d)) < 0)
        die_library(r, NULL, rc, &d);
    if (r->mpi) /* the node directories may be on other machines */
        cluster_sizes(r);
    else
        measure_written(r, w);
}

/* The rules --nodes and --shard-dir obey (MPI: one rank per node). */
static void check_cluster(const struct run *r)
{
    const struct opts *o = &r->o;
    if (o->shard_pat && !r->mpi)
        die_usage("--shard-dir: for MPI runs (mpirun -np K " PROG
                  " --nodes K ...); one process writes OUTDIR/node-R");
    if (r->mpi && o->nodes != (uint32_t)cluster_size(r))
        die_usage("--nodes %u under %d MPI ranks: expected --nodes %d (one "
                  "rank per node shard)", o->nodes, cluster_size(r),
                  cluster_size(r));
    if (o->shard_pat && !strstr(o->shard_pat, "%r"))
        die_usage("--shard-dir \"%s\": expected %%r (the rank) in it",
                  o->shard_pat);
    char *fin = o->shard_pat ? tvpal_node_dir(NULL, o->shard_pat, r->node)
                             : NULL;
    if (o->shard_pat && !fin)
        die_fail("out of memory");
    if (fin && tvpal_exists(fin) && !o->force)
        die_usage("%s: node directory already exists (use --force to "
                  "replace it)", fin);
    free(fin);
}

/* Each step ends the program itself on failure (see `enum ending`). */
int main(int argc, char **argv)
{
    struct run r = {0};
    struct written w = {0};
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
    check_grid(&r);
    warn_irregular_times(&r);
    check_output(&r);
    check_cluster(&r);
    choose_threads(&r);
    choose_limit(&r);
    encode_with_library(&r, &w);
    if (!r.o.dry_run && (!r.mpi || r.node == 0))
        print_summary(&r, &w);
    run_free(&r);
    cluster_close(&r);
    return 0;
}
