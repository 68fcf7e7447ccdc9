/* tvpal-report: accuracy and size of a tvpal dataset against its source.
 *
 * Per timestep and axis: RMSE, PSNR, max |error| and temporal flicker; per
 * axis and overall: the same plus compression ratio and bits per
 * voxel-timestep, always counting the decoder tables and every byte of the
 * files.  The overall ratio and bits are of the bytes on disk (every file
 * of the dataset directory: all stored axes, manifests, levels); the
 * per-axis ones (axis_ratio) of one axis's shards.  PSNR uses peak = max - min of the original over all
 * timesteps: PSNR = 10 log10(peak^2 / MSE).  Flicker at t >= 1 is
 * mean |(R[t] - R[t-1]) - (V[t] - V[t-1])| / peak: it exposes jumps at window
 * boundaries that a per-frame error hides.
 *
 * Only the axes the dataset stores are decoded and reported (FORMAT.md 2.2):
 * per-axis figures, rows and keys of the others are left out.
 *
 * A thin program: the dataset is read through libtvpal's reader (tvpal.h),
 * the source through the input readers (common/input, tvpal_raw.h).
 * The steps of main: parse and check the options, open the dataset, one pass
 * over the timesteps (read the reference, decode the stored axes, accumulate
 * the per-step errors), the per-axis and overall figures, then the outputs:
 * the text report, the CSV, the JSON and the closing key=value line.  The
 * CSV columns and the keys of the closing line are tables (csv_columns,
 * summary_keys): header and rows come from the same entries.
 */
#define _GNU_SOURCE
#include "tvpal.h"
#include "tvpal_cli.h"
#include "tvpal_fs.h"
#include "tvpal_input.h"
#include "tvpal_levels.h"
#include "tvpal_pool.h"
#include "tvpal_raw.h"
#include "tvpal_schedule.h"

#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define PROG "tvpal-report"
/* --level's bound: TVPAL_PARAM_LEVELS's (tvpal.h). */
#define LEVELS_MAX 8

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " OUTDIR [--reference INPUT...] [--csv FILE] [--json FILE]\n"
"Compare the dataset OUTDIR with the original data, per timestep and overall:\n"
"PSNR (peak = max - min of the original over all timesteps), RMSE, max\n"
"absolute error, temporal flicker, compression ratio and bits per\n"
"voxel-timestep (decoder tables and all file overhead included), per stored\n"
"axis.\n"
"\n"
"  -r, --reference     the remaining arguments are the original files (same\n"
"                      layout as at encoding); default: the manifest's sources\n"
"                      (a source_var \"NAME (magnitude)\" is read as the\n"
"                      length of NAME's vectors, as tvpal-encode --magnitude\n"
"                      read it)\n"
"  -c, --csv FILE      per-timestep figures as CSV\n"
"  -j, --json FILE     everything as JSON\n"
"  -l, --level K       report level of detail K (tvpal-encode --levels)\n"
"                      against the source averaged 2x2x2 K times, as the\n"
"                      encoder made it (default 0: the dataset itself)\n"
"  -q, --quiet         only the closing summary line\n"
"      --allow-external HDF5 references whose data lives in other files\n"
"                      (as tvpal-encode --allow-external read them)\n"
"  -h, --help          this help\n"
"  -V, --version       version\n"
"\n"
"The last line is a key=value summary: psnr (worst axis), psnr_x, psnr_y,\n"
"psnr_z (the stored axes'), psnr_min (worst timestep and axis), rmse,\n"
"max_abs_error and flicker (worst axis), ratio (source bytes / bytes on\n"
"disk: every file of OUTDIR, all stored axes, manifests and levels),\n"
"ratio_f32 (the same with the values as float32, whatever the source),\n"
"axis_ratio (source bytes / mean bytes of one stored axis), ratio_8bit,\n"
"bpv (bits on disk per voxel-timestep), index_bpv and table_bpv (theirs\n"
"for the indices and the decoder tables, plain: coded chunks store them\n"
"in fewer bytes, which bpv counts), bytes, steps, window, missing,\n"
"missing_mismatch, tables_u16 and tables_f32 (chunks of the stored axes\n"
"with 16-bit and float32 decoder tables: tvpal-encode --table).\n"
"Exit status: 0 success, 1 failure, 2 bad input.\n");
}

/* ------------------------------------------------------------------------
 * Options
 */

struct options {
    const char *dir;                   /* OUTDIR */
    const char *csv_path, *json_path;  /* NULL: not written */
    int use_ref, quiet;
    int allow_external;                /* --allow-external (HDF5) */
    unsigned level;                    /* --level K */
    char *const *refs;  /* the reference files: the arguments after OUTDIR,
                         * or the manifest's sources (validate_options) */
    size_t nrefs;
    enum tvpal_type src_type;  /* of raw references (the source's type) */
    struct tvpal_input *src;  /* self-describing references (NetCDF, VTK),
                               * or NULL for raw ones */
    char src_var[TVPAL_INPUT_VAR_MAX];  /* their array, when the manifest's
                               * source_var says more (src reads it by this
                               * name while it is open) */
    struct tvpal_pool *src_pool;  /* inflates their compressed chunks (all
                                   * cores), or NULL */
};

static const struct option long_options[] = {
    {"reference", no_argument, 0, 'r'},
    {"csv", required_argument, 0, 'c'},
    {"json", required_argument, 0, 'j'},
    {"level", required_argument, 0, 'l'},
    {"quiet", no_argument, 0, 'q'},
    {"allow-external", no_argument, 0, 'X'},
    {"help", no_argument, 0, 'h'},
    {"version", no_argument, 0, 'V'},
    {0, 0, 0, 0}};
static const char short_options[] = "rc:j:l:qhV";

/* Fills o from argv.  Returns -1 to go on, or the exit status when the
 * program is done: --help, --version or a usage error (message printed). */
static int parse_options(int argc, char **argv, struct options *o)
{
    int c;
    *o = (struct options){0};
    while ((c = getopt_long(argc, argv, short_options, long_options, NULL)) != -1) {
        switch (c) {
        case 'r': o->use_ref = 1; break;
        case 'c': o->csv_path = optarg; break;
        case 'j': o->json_path = optarg; break;
        case 'l': {
            uint32_t k;
            if (tvpal_parse_u32(optarg, 0, LEVELS_MAX, &k) < 0) {
                fprintf(stderr, PROG ": --level \"%s\": expected 0..%d\n",
                        optarg, LEVELS_MAX);
                return TVPAL_EXIT_USAGE;
            }
            o->level = k;
            break;
        }
        case 'q': o->quiet = 1; break;
        case 'X': o->allow_external = 1; break;
        case 'h': usage(stdout); return TVPAL_EXIT_OK;
        case 'V': printf(PROG " " PACKAGE_VERSION "\n"); return TVPAL_EXIT_OK;
        default:
            fprintf(stderr, "Try '" PROG " --help'.\n");
            return TVPAL_EXIT_USAGE;
        }
    }
    if (optind >= argc) {
        fprintf(stderr, PROG ": expected OUTDIR (try --help)\n");
        return TVPAL_EXIT_USAGE;
    }
    o->dir = argv[optind];
    o->refs = argv + optind + 1;
    o->nrefs = (size_t)(argc - optind - 1);
    return -1;
}

/* What tvpal-encode writes after the array's name in source_var when it
 * encoded a vector's length (--magnitude). */
#define MAGNITUDE_SUFFIX " (magnitude)"

/* The variable of source_var into var (cap bytes): "NAME (magnitude)" is
 * NAME read with --magnitude (returns 1), anything else the name itself
 * (0). */
static int source_variable(const char *source_var, char *var, size_t cap)
{
    const size_t n = strlen(source_var), k = strlen(MAGNITUDE_SUFFIX);
    const int mag = n > k && !strcmp(source_var + n - k, MAGNITUDE_SUFFIX);
    snprintf(var, cap, "%.*s", (int)(mag ? n - k : n), source_var);
    return mag;
}

/* References in the format the encoder read (source_format, source_var):
 * the same reader, which must find the dataset's dims and steps (and, for
 * a vector's length, a vector).  Returns 0 or TVPAL_EXIT_USAGE
 * (printed). */
static int open_self_describing(struct options *o,
                                const struct tvpal_info *m)
{
    enum tvpal_input_format f;
    struct tvpal_diag d = {{0}};
    const int mag = source_variable(m->source_var, o->src_var,
                                    sizeof o->src_var);
    struct tvpal_input_opts io = {.var = mag ? o->src_var
                                       : m->source_var[0] ? m->source_var
                                                          : NULL,
                                  .allow_external = o->allow_external,
                                  .magnitude = mag};
    int rc = tvpal_input_format_parse(m->source_format, &f);
    if (rc < 0) {
        fprintf(stderr, PROG ": source_format \"%s\": expected raw, netcdf, "
                "hdf5, vti or vtk\n", m->source_format);
        return TVPAL_EXIT_USAGE;
    }
    if (o->nrefs < 1) {
        fprintf(stderr, PROG ": no reference files\n");
        return TVPAL_EXIT_USAGE;
    }
    const unsigned nt = tvpal_pool_default_threads();
    rc = nt > 1 ? tvpal_pool_create(&o->src_pool, nt) : 0;
    if (rc < 0) {
        fprintf(stderr, PROG ": %u threads to read %s: %s\n", nt, o->refs[0],
                tvpal_strerror(rc));
        return TVPAL_EXIT_FAIL;
    }
    io.pool = o->src_pool;
    rc = tvpal_input_open(&o->src, f, o->refs, (int)o->nrefs, &io, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_USAGE;
    }
    const struct tvpal_input_info *in = tvpal_input_info(o->src);
    if (mag && in->components < 2) {
        fprintf(stderr, PROG ": %s: variable %s has one component; the "
                "dataset holds a vector's length (source_var %s)\n",
                o->refs[0], in->var, m->source_var);
        return TVPAL_EXIT_USAGE;
    }
    if (memcmp(in->dims, m->dims, sizeof m->dims) || in->steps != m->steps) {
        fprintf(stderr, PROG ": %s: variable %s is %ux%ux%u with %u steps; "
                "the dataset is %ux%ux%u with %u\n", o->refs[0], in->var,
                in->dims[0], in->dims[1], in->dims[2], in->steps, m->dims[0],
                m->dims[1], m->dims[2], m->steps);
        return TVPAL_EXIT_USAGE;
    }
    return 0;
}

/* The manifest's missing_values become NaN (missing), or its nan_as, as
 * the encoder made them. */
static void apply_missing_values(const struct tvpal_info *m, float *v,
                                 size_t n)
{
    tvpal_missing_apply(v, n, m->missing_values, m->nmissing_values,
                        m->has_nan_as ? &m->nan_as : NULL);
}

/* Timestep t of a self-describing reference, with the dataset's NaN
 * policy (--nan-as) applied as the encoder applied it. */
static int read_input_step(const struct tvpal_info *m,
                           struct tvpal_input *src, uint32_t t, float *dst,
                           size_t nvox)
{
    struct tvpal_diag d = {{0}};
    size_t bad;
    int rc = tvpal_input_read(src, t, dst, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": timestep %u: %s\n", t,
                d.msg[0] ? d.msg : tvpal_strerror(rc));
        return -1;
    }
    rc = tvpal_raw_convert(dst, TVPAL_F32, m->source_big_endian, nvox, dst,
                           m->has_nan_as ? &m->nan_as : NULL, &bad, NULL);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s: timestep %u: %s at element %zu\n",
                tvpal_input_file(src, t, NULL), t, tvpal_strerror(rc), bad);
        return -1;
    }
    apply_missing_values(m, dst, nvox);
    return 0;
}

/* Checks the options against the dataset, whose layout says how many
 * reference files there must be (one holding every timestep, or one per
 * timestep).  Without --reference no argument may follow OUTDIR and the
 * manifest's sources are read.  Returns 0 or TVPAL_EXIT_USAGE (printed). */
static int validate_options(struct options *o, const struct tvpal_info *m)
{
    if (!o->use_ref) {
        if (o->nrefs) {
            fprintf(stderr, PROG ": unexpected argument \"%s\" (reference "
                    "files follow --reference)\n", o->refs[0]);
            return TVPAL_EXIT_USAGE;
        }
        if (m->nsources == 0) {
            fprintf(stderr, PROG ": %s names no source (encoded from "
                    "memory?): give the original values with --reference\n",
                    o->dir);
            return TVPAL_EXIT_USAGE;
        }
        /* The reader's strings, read only (tvpal_input_open keeps its
         * files as char *const *). */
        o->refs = (char *const *)m->sources;
        o->nrefs = m->nsources;
    }
    if (m->source_format[0] && strcmp(m->source_format, "raw"))
        return open_self_describing(o, m);
    if (tvpal_type_parse(m->source_type, &o->src_type) < 0) {
        fprintf(stderr, PROG ": %s: source type \"%s\": expected f32, "
                "f64, u8, u16 or i16\n", o->dir, m->source_type);
        return TVPAL_EXIT_USAGE;
    }
    size_t want = m->source_single_file ? 1 : m->steps;
    if (o->nrefs != want) {
        fprintf(stderr, PROG ": %zu reference file%s; expected %zu (%s)\n",
                o->nrefs, o->nrefs == 1 ? "" : "s", want,
                m->source_single_file ? "one file holding every timestep"
                               : "one file per timestep");
        return TVPAL_EXIT_USAGE;
    }
    return 0;
}

/* A library error: the diag when the function filled it, else the code's
 * text (the library promises nothing about errno). */
static void print_lib_error(int rc, const struct tvpal_diag *diag)
{
    fprintf(stderr, PROG ": %s\n", diag->msg[0] ? diag->msg : tvpal_strerror(rc));
}

/* ------------------------------------------------------------------------
 * The report: errors per timestep and axis, then per axis and overall
 */

/* Error of one decoded timestep of one axis against the reference. */
struct step_err {
    double sse, maxabs;
    double flick;                 /* sum of |.| over voxels; 0 at t = 0 */
    /* Missing values (NaN in the reference) are in no sum: n voxels are
     * measured, nfl in flick (present at t and t - 1); `missing` are NaN
     * in the reference, `mismatch` NaN in exactly one of the reference
     * and the decoded volume (a defect: decoding keeps them in place). */
    double n, nfl, missing, mismatch;
};

/* One axis over all timesteps. */
struct axis_sum {
    double psnr, rmse, maxabs, flicker;
    double idx_bytes, tab_bytes;  /* payload: indices from the window
                                   * schedule, tables as the chunks hold
                                   * them (tvpal_shard_count_tables) */
    double tables[2];             /* chunks with float32, 16-bit tables */
};

struct report {
    struct tvpal_reader *rd;      /* the dataset reported: OUTDIR, or its
                                   * level-K (itself a dataset) */
    const struct tvpal_info *m;   /* its description */
    /* The source read: m's, or with --level K level 0's (src_nvox voxels
     * of src_dims, averaged K times into the reference), of type
     * src_type when raw. */
    const struct tvpal_info *src_m;
    enum tvpal_type src_type;
    unsigned level;
    size_t src_nvox;
    const char *dir;
    uint32_t steps;
    size_t nvox;
    /* Source size from dims, type and steps (not the manifest's
     * informational source_bytes, which could be stale or edited). */
    uint64_t src_bytes;
    double vts;                   /* voxel-timesteps */
    double vmin, vmax, peak;      /* of the reference, over all timesteps */
    struct step_err *per;         /* [t * 3 + axis] */
    struct axis_sum axis[3];
    double psnr;                  /* worst axis */
    double psnr_min;              /* worst timestep and axis: */
    uint32_t psnr_min_t;
    unsigned psnr_min_a;
    double worst_rmse, worst_max, worst_flick;   /* worst axis */
    struct tvpal_sizes sz;        /* where the bytes of m go */
    double bytes_axis;            /* mean shard bytes of a stored axis */
    double idx_bytes, tab_bytes;  /* indices and tables, all stored axes */
    double coded_saved;           /* bytes coding saves them (FORMAT.md
                                   * 6.11: plain minus stored size of the
                                   * coded chunks), all stored axes */
    uint64_t disk_bytes;          /* every file of the directory reported */
    double tables[2];             /* chunks of the stored axes with float32
                                   * and 16-bit tables */
    double missing, mismatch;     /* reference NaN voxel-steps (per axis
                                   * the same); mismatches, worst axis */
    double ratio;                 /* source bytes / disk_bytes */
};

/* Whether the dataset stores axis a (only those are decoded). */
static int stored(const struct report *r, unsigned a)
{
    return (r->m->axes >> a) & 1u;   /* TVPAL_AXIS_X << a */
}

static double psnr_of(double mse, double peak)
{
    if (mse <= 0)
        return INFINITY;
    if (peak <= 0)
        return -INFINITY;
    return 10.0 * log10(peak * peak / mse);
}

static const struct step_err *step_at(const struct report *r, uint32_t t,
                                      unsigned a)
{
    return &r->per[(size_t)t * 3 + a];
}

/* Mean squared error of a step over its measured voxels (0 when every
 * voxel is missing). */
static double step_mse(const struct report *r, uint32_t t, unsigned a)
{
    const struct step_err *p = step_at(r, t, a);
    return p->n > 0 ? p->sse / p->n : 0.0;
}

static double step_rmse(const struct report *r, uint32_t t, unsigned a)
{
    return sqrt(step_mse(r, t, a));
}

static double step_psnr(const struct report *r, uint32_t t, unsigned a)
{
    return psnr_of(step_mse(r, t, a), r->peak);
}

/* Mean flicker of step t (none at t = 0, nor without contrast). */
static double step_flicker(const struct report *r, uint32_t t, unsigned a)
{
    const struct step_err *p = step_at(r, t, a);
    return t && r->peak > 0 && p->nfl > 0 ? p->flick / p->nfl / r->peak : 0.0;
}

/* Sets the sizes and allocates r->per.  Returns 0 or -1 (out of memory). */
static int report_init(struct report *r, struct tvpal_reader *rd,
                       enum tvpal_type src_type, const char *dir)
{
    const struct tvpal_info *m = tvpal_reader_info(rd);
    *r = (struct report){.rd = rd, .m = m, .src_m = m, .src_type = src_type,
                         .dir = dir, .steps = m->steps};
    r->nvox = (size_t)m->dims[0] * m->dims[1] * m->dims[2];
    r->src_nvox = r->nvox;
    r->src_bytes = (uint64_t)r->nvox * r->steps * m->source_value_bytes;
    r->vts = (double)r->nvox * r->steps;
    r->vmin = INFINITY;
    r->vmax = -INFINITY;
    r->per = calloc((size_t)r->steps * 3, sizeof *r->per);
    return r->per ? 0 : -1;
}

/* ------------------------------------------------------------------------
 * Reading the reference and the decoded steps
 */

/* Working memory of the pass over the timesteps: the raw bytes of one
 * reference step; the reference and each stored axis's decoded volume at t
 * and t - 1 (for flicker), alternating by the parity of t. */
struct scan_buffers {
    void *raw;
    float *full[2];          /* --level: the source step, then averages */
    float *ref[2], *dec[3][2];
};

static void buffers_free(struct scan_buffers *b)
{
    for (unsigned a = 0; a < 3; a++) {
        free(b->dec[a][0]);
        free(b->dec[a][1]);
    }
    free(b->ref[0]);
    free(b->ref[1]);
    free(b->full[0]);
    free(b->full[1]);
    free(b->raw);
}

/* Returns 0 or -1 (out of memory; what was allocated is in b for
 * buffers_free). */
static int buffers_alloc(struct scan_buffers *b, const struct report *r)
{
    const size_t nvox = r->nvox;
    *b = (struct scan_buffers){0};
    b->raw = malloc(r->src_nvox * r->src_m->source_value_bytes);
    if (r->level && (!(b->full[0] = malloc(r->src_nvox * sizeof(float))) ||
                     !(b->full[1] = malloc(r->src_nvox * sizeof(float)))))
        return -1;
    b->ref[0] = malloc(nvox * sizeof(float));
    b->ref[1] = malloc(nvox * sizeof(float));
    if (!b->raw || !b->ref[0] || !b->ref[1])
        return -1;
    for (unsigned a = 0; a < 3; a++) {
        if (!stored(r, a))
            continue;
        b->dec[a][0] = malloc(nvox * sizeof(float));
        b->dec[a][1] = malloc(nvox * sizeof(float));
        if (!b->dec[a][0] || !b->dec[a][1])
            return -1;
    }
    return 0;
}

/* Reads timestep t of the reference into dst (nvox floats), raw being
 * scratch for the file's bytes.  The file's size must be what dims, type and
 * steps say (checked once for a single file).  Returns 0 or -1 (printed). */
static int read_reference_step(const struct tvpal_info *m,
                               enum tvpal_type type, char *const *files,
                               uint32_t t, void *raw, float *dst, size_t nvox)
{
    size_t esz = tvpal_type_size(type), bytes = nvox * esz;
    const char *path = m->source_single_file ? files[0] : files[t];
    off_t off = m->source_single_file ? (off_t)t * (off_t)bytes : 0;
    struct tvpal_diag d = {{0}};
    int fd = tvpal_open_regular(path, &d);
    if (fd < 0) {
        fprintf(stderr, PROG ": cannot open reference %s\n", d.msg);
        return -1;
    }
    size_t got = 0;
    while (got < bytes) {
        ssize_t k = pread(fd, (char *)raw + got, bytes - got, off + (off_t)got);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0) {
            fprintf(stderr, PROG ": %s: timestep %u: %s\n", path, t,
                    k < 0 ? strerror(errno) : "file is shorter than expected");
            close(fd);
            return -1;
        }
        got += (size_t)k;
    }
    struct stat st;
    uint64_t want = m->source_single_file ? (uint64_t)bytes * m->steps
                                          : bytes;
    if (t == 0 || !m->source_single_file) {
        if (fstat(fd, &st) == 0 && (uint64_t)st.st_size != want) {
            fprintf(stderr, PROG ": %s: size is %lld bytes; expected %llu "
                    "(dims and type of the manifest)\n", path,
                    (long long)st.st_size, (unsigned long long)want);
            close(fd);
            return -1;
        }
    }
    close(fd);
    size_t bad;
    int rc = tvpal_raw_convert(raw, type, m->source_big_endian, nvox, dst,
                               m->has_nan_as ? &m->nan_as : NULL, &bad, NULL);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s: timestep %u: %s at element %zu\n", path,
                t, tvpal_strerror(rc), bad);
        return -1;
    }
    apply_missing_values(m, dst, nvox);
    return 0;
}

/* Widens [vmin, vmax] to the reference step R. */
static void update_range(struct report *r, const float *R)
{
    double vmin = r->vmin, vmax = r->vmax;
    for (size_t i = 0; i < r->nvox; i++) {
        if (R[i] != R[i])
            continue; /* missing */
        vmin = R[i] < vmin ? R[i] : vmin;
        vmax = R[i] > vmax ? R[i] : vmax;
    }
    r->vmin = vmin;
    r->vmax = vmax;
}

/* Error of the decoded step V against the reference R; the previous steps
 * Rp, Vp count only when t > 0 (flicker).  A voxel missing (NaN) in R or
 * V is left out; NaN in only one of them is a mismatch. */
static void measure_step(struct step_err *p, size_t nvox, uint32_t t,
                         const float *R, const float *Rp, const float *V,
                         const float *Vp)
{
    double sse = 0, mx = 0, fl = 0;
    size_t n = 0, nfl = 0, miss = 0, bad = 0;
    for (size_t i = 0; i < nvox; i++) {
        const int rn = R[i] != R[i], vn = V[i] != V[i];
        miss += rn;
        bad += rn != vn;
        if (rn || vn)
            continue;
        double e = (double)V[i] - (double)R[i];
        sse += e * e;
        mx = fabs(e) > mx ? fabs(e) : mx;
        n++;
    }
    if (t > 0)
        for (size_t i = 0; i < nvox; i++) {
            double d = ((double)R[i] - Rp[i]) - ((double)V[i] - Vp[i]);
            if (d != d)
                continue; /* missing at t or t - 1 */
            fl += fabs(d);
            nfl++;
        }
    *p = (struct step_err){.sse = sse, .maxabs = mx, .flick = fl,
                           .n = (double)n, .nfl = (double)nfl,
                           .missing = (double)miss, .mismatch = (double)bad};
}

/* Step t of the reference into dst: the source, or with --level K the
 * source averaged K times.  0 or -1 (printed). */
static int reference_step(struct report *r, char *const *refs,
                          struct tvpal_input *src, struct scan_buffers *b,
                          uint32_t t, float *dst)
{
    float *into = r->level ? b->full[0] : dst;
    if ((src ? read_input_step(r->src_m, src, t, into, r->src_nvox)
             : read_reference_step(r->src_m, r->src_type, refs, t, b->raw,
                                   into, r->src_nvox)) < 0)
        return -1;
    /* Each level the 2x2x2 means of the one before, as tvpal-encode
     * --levels makes it (tvpal_levels.h). */
    for (unsigned k = 0; k < r->level; k++) {
        uint32_t d[3];
        tvpal_level_dims(r->src_m->dims, k, d);
        float *out = k + 1 == r->level ? dst : b->full[(k + 1) & 1];
        tvpal_level_make(b->full[k & 1], d, out);
    }
    return 0;
}

/* The one pass over the timesteps: per step, the reference and the
 * decoded stored axes.  Returns 0 or TVPAL_EXIT_USAGE (a reference or a record that
 * cannot be read; printed). */
static int scan_steps(struct report *r, char *const *refs,
                      struct tvpal_input *src,
                      struct scan_buffers *b)
{
    struct tvpal_diag diag = {{0}};
    for (uint32_t t = 0; t < r->steps; t++) {
        const unsigned cur = t & 1, prev = cur ^ 1;
        if (reference_step(r, refs, src, b, t, b->ref[cur]) < 0)
            return TVPAL_EXIT_USAGE;
        update_range(r, b->ref[cur]);
        for (unsigned a = 0; a < 3; a++) {
            if (!stored(r, a))
                continue;
            int rc = tvpal_reader_decode(r->rd, t, TVPAL_AXIS_X << a, 0,
                                         b->dec[a][cur], &diag);
            if (rc < 0) {
                print_lib_error(rc, &diag);
                return TVPAL_EXIT_USAGE;
            }
            measure_step(&r->per[(size_t)t * 3 + a], r->nvox, t, b->ref[cur],
                         b->ref[prev], b->dec[a][cur], b->dec[a][prev]);
        }
    }
    r->peak = r->vmax - r->vmin;
    return 0;
}

/* ------------------------------------------------------------------------
 * Per-axis and overall figures
 */

/* Errors per stored axis over all timesteps, the worst axis, the worst
 * step. */
static void summarize_errors(struct report *r)
{
    const uint32_t T = r->steps;
    r->psnr_min = INFINITY;
    r->psnr = INFINITY;
    for (unsigned a = 0; a < 3; a++) {
        if (!stored(r, a))
            continue;
        struct axis_sum *x = &r->axis[a];
        double sse = 0, mx = 0, fl = 0, n = 0, nfl = 0, miss = 0, bad = 0;
        for (uint32_t t = 0; t < T; t++) {
            const struct step_err *p = step_at(r, t, a);
            sse += p->sse;
            mx = p->maxabs > mx ? p->maxabs : mx;
            fl += p->flick;
            n += p->n;
            nfl += p->nfl;
            miss += p->missing;
            bad += p->mismatch;
            double ps = step_psnr(r, t, a);
            if (ps < r->psnr_min) {
                r->psnr_min = ps;
                r->psnr_min_t = t;
                r->psnr_min_a = a;
            }
        }
        const double mse = n > 0 ? sse / n : 0.0;
        x->rmse = sqrt(mse);
        x->psnr = psnr_of(mse, r->peak);
        x->maxabs = mx;
        x->flicker = T > 1 && r->peak > 0 && nfl > 0 ? fl / nfl / r->peak
                                                     : 0.0;
        r->missing = miss;
        r->mismatch = bad > r->mismatch ? bad : r->mismatch;
        r->worst_rmse = x->rmse > r->worst_rmse ? x->rmse : r->worst_rmse;
        r->worst_max = mx > r->worst_max ? mx : r->worst_max;
        r->worst_flick = x->flicker > r->worst_flick ? x->flicker : r->worst_flick;
        r->psnr = fmin(r->psnr, x->psnr);
    }
}

/* The bytes on disk (every file under the directory reported), per
 * stored axis its files, indices (width * height per slice-window) and
 * tables (as the chunks store them), and the chunks by table format:
 * tvpal_reader_sizes.  0, or a library error (diag). */
static int summarize_sizes(struct report *r, struct tvpal_diag *diag)
{
    const uint64_t *ab = r->sz.axis_bytes;
    const unsigned na = tvpal_axes_count(r->m->axes);
    int rc = tvpal_reader_sizes(r->rd, 0, &r->sz, diag);
    if (rc < 0)
        return rc;
    r->disk_bytes = r->sz.disk_bytes;
    r->bytes_axis = r->idx_bytes = r->tab_bytes = 0;
    r->tables[0] = r->tables[1] = 0;
    for (unsigned a = 0; a < 3; a++) {
        if (!stored(r, a))
            continue;
        r->axis[a].idx_bytes = (double)r->sz.index_bytes[a];
        r->axis[a].tab_bytes = (double)r->sz.table_bytes[a];
        r->axis[a].tables[0] = (double)r->sz.chunks_f32[a];
        r->axis[a].tables[1] = (double)r->sz.chunks_u16[a];
        r->bytes_axis += (double)ab[a] / na;
        r->idx_bytes += r->axis[a].idx_bytes;
        r->tab_bytes += r->axis[a].tab_bytes;
        r->tables[0] += r->axis[a].tables[0];
        r->tables[1] += r->axis[a].tables[1];
    }
    struct tvpal_coding c;
    if ((rc = tvpal_reader_coding(r->rd, 0, &c, diag)) < 0)
        return rc;
    r->coded_saved = 0;
    for (unsigned a = 0; a < 3; a++)
        if (stored(r, a))
            r->coded_saved += (double)c.coded_plain_bytes[a] -
                              (double)c.coded_bytes[a];
    r->ratio = (double)r->src_bytes / (double)r->disk_bytes;
    return 0;
}

/* ------------------------------------------------------------------------
 * Outputs
 */

/* The manifest's name of a table format (TVPAL_TABLE_*). */
static const char *table_name(uint32_t table)
{
    return table == TVPAL_TABLE_UINT16 ? "u16"
           : table == TVPAL_TABLE_AUTO ? "auto" : "f32";
}

/* Text report on stdout (without --quiet). */
/* The line that splits the bits on disk: the indices and the tables as
 * plain chunks hold them, what coding saves of them (FORMAT.md 6.11 codes
 * a chunk's table and indices as one frame, so the saving is not split
 * between them), and the rest: chunk and record headers, padding, the
 * record index, manifests (and levels), never negative. */
static void print_bpv_split(const struct report *r)
{
    const double k = 8 / r->vts;
    const double rest = (double)r->disk_bytes - r->idx_bytes - r->tab_bytes +
                        r->coded_saved;
    printf("bits per voxel-timestep on disk: %.4f = indices %.4f + tables "
           "%.4f", k * (double)r->disk_bytes, k * r->idx_bytes,
           k * r->tab_bytes);
    if (r->coded_saved > 0)
        printf(" - saved by coding them %.4f", k * r->coded_saved);
    printf(" + headers, padding and manifests%s %.4f\n",
           r->m->levels ? " and levels" : "", k * rest);
}

static void print_text(const struct report *r)
{
    const struct tvpal_info *m = r->m;
    const uint64_t *ab = r->sz.axis_bytes;
    printf("dataset %s: %ux%ux%u %s, %u steps, window %u (%s), %u node%s",
           r->dir, m->dims[0], m->dims[1], m->dims[2], m->source_type,
           r->steps, m->window,
           tvpal_schedule_name(m->schedule),
           m->nodes, m->nodes == 1 ? "" : "s");
    for (unsigned a = 0, first = 1; a < 3; a++)
        if (m->group[a] > 1) {
            printf("%s %c %u", first ? ", palette groups:" : ",",
                   "xyz"[a], m->group[a]);
            first = 0;
        }
    printf("\n");
    printf("peak (max - min of the original) = %.9g  [%.9g, %.9g]\n",
           r->peak, r->vmin, r->vmax);
    printf("%6s", "step");
    for (unsigned a = 0; a < 3; a++)
        if (stored(r, a))
            printf(" %8s%c", "psnr_", "xyz"[a]);
    printf(" %12s %10s\n", "max_abs_err", "flicker");
    for (uint32_t t = 0; t < r->steps; t++) {
        double mx = 0, fl = 0;
        printf("%6u", t);
        for (unsigned a = 0; a < 3; a++) {
            if (!stored(r, a))
                continue;
            printf(" %9.3f", step_psnr(r, t, a));
            mx = step_at(r, t, a)->maxabs > mx ? step_at(r, t, a)->maxabs : mx;
            double f = step_flicker(r, t, a);
            fl = f > fl ? f : fl;
        }
        printf(" %12.6g %10.3g\n", mx, fl);
    }
    printf("%4s %9s %12s %12s %10s %14s %10s %9s\n", "axis", "psnr",
           "rmse", "max_abs_err", "flicker", "bytes", "axis_ratio",
           "axis_bpv");
    for (unsigned a = 0; a < 3; a++)
        if (stored(r, a))
            printf("%4c %9.3f %12.6g %12.6g %10.3g %14llu %10.3f %9.4f\n",
               "xyz"[a], r->axis[a].psnr, r->axis[a].rmse, r->axis[a].maxabs,
               r->axis[a].flicker, (unsigned long long)ab[a],
               (double)r->src_bytes / (double)ab[a],
               8.0 * (double)ab[a] / r->vts);
    char axes[4];
    printf("on disk: %llu bytes (axes %s: shards, manifests%s), ratio "
           "%.3f\n", (unsigned long long)r->disk_bytes,
           tvpal_axes_format(m->axes, axes), m->levels ? ", levels" : "",
           r->ratio);
    print_bpv_split(r);
    const double chunks = r->tables[0] + r->tables[1];
    printf("decoder tables: %.0f of %.0f chunks 16-bit (%.1f%%), %.0f "
           "float32 (table = %s)\n", r->tables[1], chunks,
           chunks > 0 ? 100 * r->tables[1] / chunks : 0.0, r->tables[0],
           table_name(m->table));
    printf("worst timestep: %u on axis %c (%.3f dB)\n", r->psnr_min_t,
           "xyz"[r->psnr_min_a], r->psnr_min);
    if (r->missing)
        printf("missing values: %.0f of %.0f voxel-timesteps (%.3g%%), left "
               "out of every figure\n", r->missing, r->vts,
               100.0 * r->missing / r->vts);
}

/* A column of the CSV or a key of the summary line: its name, the printf
 * conversion of its value and where the value is in its record (a struct of
 * doubles).  kind says how the double is handed to the conversion: counts
 * and characters are exact in a double. */
enum col_kind { COL_UINT, COL_CHAR, COL_REAL, COL_COUNT };
struct column {
    const char *name;
    const char *fmt;
    enum col_kind kind;
    size_t off;
    unsigned axis1;            /* 1 + the axis a per-axis key is of (left
                                * out for an axis not stored), or 0 */
};

static void put_value(FILE *f, const struct column *c, const void *rec)
{
    const double v = *(const double *)((const char *)rec + c->off);
    switch (c->kind) {
    case COL_UINT: fprintf(f, c->fmt, (unsigned)v); break;
    case COL_CHAR: fprintf(f, c->fmt, (int)v); break;
    case COL_REAL: fprintf(f, c->fmt, v); break;
    case COL_COUNT: fprintf(f, "%.0f", v); break; /* exact below 2^53 */
    }
}

/* One CSV row: a timestep of one axis. */
struct csv_row {
    double step, axis, rmse, psnr, max_abs_error, flicker, time, missing;
};
#define CSV_COL(name, fmt, kind) {#name, fmt, kind, offsetof(struct csv_row, name), 0}
static const struct column csv_columns[] = {
    CSV_COL(step, "%u", COL_UINT),
    CSV_COL(axis, "%c", COL_CHAR),
    CSV_COL(rmse, "%.9g", COL_REAL),
    CSV_COL(psnr, "%.6f", COL_REAL),
    CSV_COL(max_abs_error, "%.9g", COL_REAL),
    CSV_COL(flicker, "%.9g", COL_REAL),
    CSV_COL(time, "%.17g", COL_REAL),   /* the manifest's, else the step */
    CSV_COL(missing, "", COL_COUNT),    /* voxels missing in the reference */
};
#undef CSV_COL
#define NCSV (sizeof csv_columns / sizeof csv_columns[0])

static struct csv_row csv_row_of(const struct report *r, uint32_t t, unsigned a)
{
    return (struct csv_row){
        .step = t, .axis = "xyz"[a], .rmse = step_rmse(r, t, a),
        .psnr = step_psnr(r, t, a), .max_abs_error = step_at(r, t, a)->maxabs,
        .flicker = step_flicker(r, t, a),
        .time = r->m->times ? r->m->times[t] : (double)t,
        .missing = step_at(r, t, a)->missing};
}

/* The header (the column names), then one row per timestep and stored
 * axis. */
static void write_csv_rows(FILE *f, const struct report *r)
{
    for (size_t c = 0; c < NCSV; c++)
        fprintf(f, "%s%s", c ? "," : "", csv_columns[c].name);
    fputc('\n', f);
    for (uint32_t t = 0; t < r->steps; t++)
        for (unsigned a = 0; a < 3; a++) {
            if (!stored(r, a))
                continue;
            const struct csv_row row = csv_row_of(r, t, a);
            for (size_t c = 0; c < NCSV; c++) {
                if (c)
                    fputc(',', f);
                put_value(f, &csv_columns[c], &row);
            }
            fputc('\n', f);
        }
}

static void jstr(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            fprintf(f, "\\%c", c);
        else if (c < 0x20)
            fprintf(f, "\\u%04x", c);
        else
            fputc(c, f);
    }
    fputc('"', f);
}

/* JSON has no infinities: null stands for them. */
static void jnum(FILE *f, double v)
{
    if (isfinite(v))
        fprintf(f, "%.6g", v);
    else
        fputs("null", f);
}

static void write_json_axes(FILE *f, const struct report *r)
{
    const uint64_t *ab = r->sz.axis_bytes;
    fprintf(f, ",\n  \"source_bytes\": %llu,\n  \"axes\": {",
            (unsigned long long)r->src_bytes);
    const char *sep = "";
    for (unsigned a = 0; a < 3; a++) {
        if (!stored(r, a))
            continue;
        const struct axis_sum *x = &r->axis[a];
        fprintf(f, "%s\n    \"%c\": {\"psnr\": ", sep, "xyz"[a]);
        sep = ",";
        jnum(f, x->psnr);
        fprintf(f, ", \"rmse\": %.9g, \"max_abs_error\": %.9g, "
                "\"flicker\": %.9g, \"bytes\": %llu, \"axis_ratio\": %.6f, "
                "\"axis_bpv\": %.6f, \"index_bpv\": %.6f, "
                "\"table_bpv\": %.6f, \"tables_u16\": %.0f, "
                "\"tables_f32\": %.0f}",
                x->rmse, x->maxabs, x->flicker, (unsigned long long)ab[a],
                (double)r->src_bytes / (double)ab[a],
                8.0 * (double)ab[a] / r->vts, 8 * x->idx_bytes / r->vts,
                8 * x->tab_bytes / r->vts, x->tables[1], x->tables[0]);
    }
    fprintf(f, "\n  }");
}

static void write_json_steps(FILE *f, const struct report *r)
{
    fprintf(f, ",\n  \"per_step\": [");
    for (uint32_t t = 0; t < r->steps; t++) {
        fprintf(f, "%s\n    {\"step\": %u", t ? "," : "", t);
        for (unsigned a = 0; a < 3; a++) {
            if (!stored(r, a))
                continue;
            fprintf(f, ", \"psnr_%c\": ", "xyz"[a]);
            jnum(f, step_psnr(r, t, a));
            fprintf(f, ", \"max_abs_error_%c\": %.9g, \"flicker_%c\": %.9g",
                    "xyz"[a], step_at(r, t, a)->maxabs, "xyz"[a],
                    step_flicker(r, t, a));
        }
        fputc('}', f);
    }
    fprintf(f, "\n  ]");
}

/* Everything as one JSON object. */
static void write_json_doc(FILE *f, const struct report *r)
{
    const struct tvpal_info *m = r->m;
    fprintf(f, "{\n  \"dataset\": ");
    jstr(f, r->dir);
    fprintf(f, ",\n  \"dims\": [%u, %u, %u],\n"
            "  \"steps\": %u,\n  \"window\": %u,\n  \"schedule\": \"%s\",\n"
            "  \"groups\": [%u, %u, %u],\n"
            "  \"nodes\": %u,\n  \"peak\": ", m->dims[0], m->dims[1],
            m->dims[2], r->steps, m->window,
            tvpal_schedule_name(m->schedule), m->group[0], m->group[1],
            m->group[2], m->nodes);
    jnum(f, r->peak);
    write_json_axes(f, r);
    write_json_steps(f, r);
    fprintf(f, ",\n  \"summary\": {\"psnr\": ");
    jnum(f, r->psnr);
    fprintf(f, ", \"psnr_min\": ");
    jnum(f, r->psnr_min);
    fprintf(f, ", \"bytes\": %llu, \"ratio\": %.6f, \"axis_ratio\": %.6f, "
            "\"bpv\": %.6f, \"missing\": %.0f, \"missing_mismatch\": "
            "%.0f}\n}\n", (unsigned long long)r->disk_bytes, r->ratio,
            (double)r->src_bytes / r->bytes_axis,
            8 * (double)r->disk_bytes / r->vts, r->missing, r->mismatch);
}

/* Writes path with fn, through tvpal_out (a temporary renamed when
 * complete; never over the dataset or a device).  Returns 0 or
 * TVPAL_EXIT_FAIL (printed). */
static int write_file(const char *path, const struct report *r,
                      void (*fn)(FILE *, const struct report *))
{
    struct tvpal_diag d = {{0}};
    struct tvpal_out o;
    if (tvpal_path_inside(path, r->dir)) {
        fprintf(stderr, PROG ": %s: inside the dataset %s; write it "
                "elsewhere\n", path, r->dir);
        return TVPAL_EXIT_FAIL;
    }
    int rc = tvpal_out_open(&o, path, &d);
    FILE *f = rc == 0 ? tvpal_out_stream(&o) : NULL;
    if (!f) {
        tvpal_out_abort(&o);
        fprintf(stderr, PROG ": cannot write %s\n",
                d.msg[0] ? d.msg : path);
        return TVPAL_EXIT_FAIL;
    }
    fn(f, r);
    if ((rc = tvpal_out_commit(&o, &d)) < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_FAIL;
    }
    return 0;
}

/* The closing line's values, in a record for the summary_keys table. */
struct summary {
    double psnr, psnr_x, psnr_y, psnr_z, psnr_min, rmse, max_abs_error;
    double flicker, ratio, ratio_f32, axis_ratio, ratio_8bit, bpv, index_bpv;
    double table_bpv;
    double bytes;
    double steps, window, missing, missing_mismatch, tables_u16, tables_f32;
};
#define KEY(name, fmt, kind) {#name, fmt, kind, offsetof(struct summary, name), 0}
#define AXIS_KEY(name, a) {#name, "%.4f", COL_REAL, offsetof(struct summary, name), a + 1}
static const struct column summary_keys[] = {
    KEY(psnr, "%.4f", COL_REAL),
    AXIS_KEY(psnr_x, 0),
    AXIS_KEY(psnr_y, 1),
    AXIS_KEY(psnr_z, 2),
    KEY(psnr_min, "%.4f", COL_REAL),
    KEY(rmse, "%.6g", COL_REAL),
    KEY(max_abs_error, "%.6g", COL_REAL),
    KEY(flicker, "%.6g", COL_REAL),
    KEY(ratio, "%.4f", COL_REAL),
    KEY(ratio_f32, "%.4f", COL_REAL),
    KEY(axis_ratio, "%.4f", COL_REAL),
    KEY(ratio_8bit, "%.4f", COL_REAL),
    KEY(bpv, "%.4f", COL_REAL),
    KEY(index_bpv, "%.4f", COL_REAL),
    KEY(table_bpv, "%.4f", COL_REAL),
    KEY(bytes, "", COL_COUNT),
    KEY(steps, "%u", COL_UINT),
    KEY(window, "%u", COL_UINT),
    KEY(missing, "", COL_COUNT),
    KEY(missing_mismatch, "", COL_COUNT),
    KEY(tables_u16, "", COL_COUNT),
    KEY(tables_f32, "", COL_COUNT),
};
#undef KEY
#undef AXIS_KEY

static struct summary summary_of(const struct report *r)
{
    return (struct summary){
        .psnr = r->psnr, .psnr_x = r->axis[0].psnr, .psnr_y = r->axis[1].psnr,
        .psnr_z = r->axis[2].psnr, .psnr_min = r->psnr_min,
        .rmse = r->worst_rmse, .max_abs_error = r->worst_max,
        .flicker = r->worst_flick, .ratio = r->ratio,
        .ratio_f32 = 4 * r->vts / (double)r->disk_bytes,
        .axis_ratio = (double)r->src_bytes / r->bytes_axis,
        .ratio_8bit = r->vts / (double)r->disk_bytes,
        .bpv = 8 * (double)r->disk_bytes / r->vts,
        .index_bpv = 8 * r->idx_bytes / r->vts,
        .table_bpv = 8 * r->tab_bytes / r->vts,
        .bytes = (double)r->disk_bytes,
        .steps = r->steps, .window = r->m->window, .missing = r->missing,
        .missing_mismatch = r->mismatch, .tables_u16 = r->tables[1],
        .tables_f32 = r->tables[0]};
}

/* The closing key=value line on stdout. */
static void print_summary_line(const struct report *r)
{
    const struct summary s = summary_of(r);
    const char *sep = "";
    for (size_t k = 0; k < sizeof summary_keys / sizeof summary_keys[0]; k++) {
        if (summary_keys[k].axis1 && !stored(r, summary_keys[k].axis1 - 1))
            continue;
        printf("%s%s=", sep, summary_keys[k].name);
        sep = " ";
        put_value(stdout, &summary_keys[k], &s);
    }
    putchar('\n');
}

/* The outputs in their order; the first that fails stops the others.
 * Returns 0 or TVPAL_EXIT_FAIL (printed). */
static int write_outputs(const struct report *r, const struct options *o)
{
    if (!o->quiet)
        print_text(r);
    if (o->csv_path && write_file(o->csv_path, r, write_csv_rows) != 0)
        return TVPAL_EXIT_FAIL;
    if (o->json_path && write_file(o->json_path, r, write_json_doc) != 0)
        return TVPAL_EXIT_FAIL;
    print_summary_line(r);
    return 0;
}

/* Opens OUTDIR (*top) and the dataset reported (*rd: OUTDIR, or with
 * --level K its level-K directory, a dataset of its own; *level_dir owns
 * that path).  Returns 0 or TVPAL_EXIT_USAGE (printed). */
static int open_readers(const struct options *o, struct tvpal_reader **top,
                        struct tvpal_reader **rd, char **level_dir)
{
    struct tvpal_diag diag = {{0}};
    int rc = tvpal_reader_open(top, o->dir, &diag);
    if (rc < 0) {
        print_lib_error(rc, &diag);
        return TVPAL_EXIT_USAGE;
    }
    *rd = *top;
    if (!o->level)
        return 0;
    /* Level K decodes from OUTDIR/level-K; its reference is level 0's
     * source, averaged. */
    const uint32_t levels = tvpal_reader_info(*top)->levels;
    if (o->level > levels) {
        fprintf(stderr, PROG ": --level %u: %s has %u coarser level%s\n",
                o->level, o->dir, levels, levels == 1 ? "" : "s");
        return TVPAL_EXIT_USAGE;
    }
    if (asprintf(level_dir, "%s/level-%u", o->dir, o->level) < 0) {
        *level_dir = NULL;
        fprintf(stderr, PROG ": out of memory\n");
        return TVPAL_EXIT_USAGE;
    }
    if ((rc = tvpal_reader_open(rd, *level_dir, &diag)) < 0) {
        *rd = NULL;
        print_lib_error(rc, &diag);
        return TVPAL_EXIT_USAGE;
    }
    return 0;
}

/* The pass over the steps, the figures, the outputs; the report's
 * verdict on missing values.  Returns the exit status. */
static int run_report(struct report *r, struct options *o)
{
    struct scan_buffers b = {0};
    struct tvpal_diag diag = {{0}};
    int status = 0;
    if (buffers_alloc(&b, r) < 0) {
        fprintf(stderr, PROG ": out of memory\n");
        status = TVPAL_EXIT_FAIL;
    }
    if (status == 0)
        status = scan_steps(r, o->refs, o->src, &b);
    buffers_free(&b);
    if (status == 0) {
        summarize_errors(r);
        int rc = summarize_sizes(r, &diag);
        if (rc < 0) {
            print_lib_error(rc, &diag);
            status = TVPAL_EXIT_USAGE;
        }
    }
    if (status == 0)
        status = write_outputs(r, o);
    if (status == 0 && r->mismatch > 0) {
        /* The dataset does not hold the reference's missing values where
         * they are (another reference, or a defect). */
        fprintf(stderr, PROG ": %s: %.0f voxel-timesteps are missing (NaN) "
                "in only one of the reference and the decoded dataset\n",
                o->dir, r->mismatch);
        status = TVPAL_EXIT_FAIL;
    }
    return status;
}

int main(int argc, char **argv)
{
    struct options o;
    int status = parse_options(argc, argv, &o);
    if (status >= 0)
        return status;
    struct tvpal_reader *top = NULL, *rd = NULL;
    char *level_dir = NULL;
    struct report r = {0};
    status = open_readers(&o, &top, &rd, &level_dir);
    if (status == 0)
        status = validate_options(&o, tvpal_reader_info(top));
    if (status == 0 &&
        report_init(&r, rd, o.src_type, level_dir ? level_dir : o.dir) < 0) {
        fprintf(stderr, PROG ": out of memory\n");
        status = TVPAL_EXIT_FAIL;
    }
    if (status == 0 && o.level) {
        const struct tvpal_info *in0 = tvpal_reader_info(top);
        r.src_m = in0;
        r.level = o.level;
        r.src_nvox = (size_t)in0->dims[0] * in0->dims[1] * in0->dims[2];
    }
    if (status == 0)
        status = run_report(&r, &o);
    free(r.per);
    tvpal_input_close(o.src);
    tvpal_pool_free(o.src_pool);
    if (rd != top)
        tvpal_reader_close(rd);
    tvpal_reader_close(top);
    free(level_dir);
    return status;
}
