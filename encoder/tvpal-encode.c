/* tvpal-encode: encodes a time series of raw volumes into a tvpal dataset
 * (paper section III; format: common/format/FORMAT.md).
 *
 * Streaming: timestep t + N - 1 is read when the records of step t are
 * built, so memory holds N float volumes (a ring) plus the records of one
 * step, never T.  Output goes to OUTDIR.partial/ and is renamed to OUTDIR
 * only when complete; a checkpoint written after every step lets a rerun of
 * the same command continue an interrupted job.
 */
#define _GNU_SOURCE
#include "tvpal_checkpoint.h"
#include "tvpal_cli.h"
#include "tvpal_clock.h"
#include "tvpal_crc32c.h"
#include "tvpal_dataset.h"
#include "tvpal_error.h"
#include "tvpal_format.h"
#include "tvpal_fs.h"
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
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define PROG "tvpal-encode"
#define FINE_BINS TVPAL_CHECKPOINT_BINS /* source histogram classes */

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " --dims NXxNYxNZ [options] -o OUTDIR INPUT...\n"
"Encode a time series of raw volumes (one file per timestep, in time order,\n"
"or one file holding all timesteps with --steps) into a tvpal dataset: for\n"
"each axis, 8-bit indexed slices with per-window decoder tables.\n"
"\n"
"Input:\n"
"  -d, --dims NXxNYxNZ    volume size, x fastest (required)\n"
"  -t, --type TYPE        f32 (default), f64, u8, u16, i16\n"
"  -e, --endian ORDER     little (default) or big\n"
"  -s, --steps T          INPUT is one file holding T timesteps\n"
"      --nan-as VALUE     replace NaN and infinite values by VALUE\n"
"                         (default: refuse them, naming file and timestep)\n"
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

/* ------------------------------------------------------------------ state */

struct opts {
    uint32_t dims[3];
    enum tvpal_type type;
    int big_endian;
    uint32_t window, nodes, steps_single, threads;
    uint32_t table_format;
    uint32_t refine;
    int naive, klt, alloc_mse;
    int has_nan_as;
    double nan_as;
    const char *outdir;
    int force, quiet;
    char **inputs;
    int ninputs;
};

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

static size_t g_nvox;
static int g_nthreads = 1;
static size_t g_group_cap; /* floats of samples per thread */
static uint64_t **g_fine_local; /* per-thread source histograms */

/* Reads timestep t of the source into dst (converted), accounting stats
 * when t is not yet in them. */
static void load_step(const struct opts *o, uint32_t t, void *raw, float *dst,
                      struct tvpal_checkpoint_stats *st)
{
    const size_t esz = tvpal_type_size(o->type);
    const size_t bytes = g_nvox * esz;
    const char *path = o->steps_single ? o->inputs[0] : o->inputs[t];
    off_t off = o->steps_single ? (off_t)t * (off_t)bytes : 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) /* maybe transient (NFS, permissions): keep the partial */
        die_fail("%s: cannot open: %s (rerun to resume)", path,
                 strerror(errno));
    /* Reading, conversion and statistics in parallel over contiguous
     * chunks (each thread reads its own part: the page-cache copy is as
     * costly as the conversion); the first bad element is the lowest index
     * any chunk reports. */
    const int stats = t >= st->loaded;
    size_t nrep = 0, bad = SIZE_MAX;
    int rc_all = 0, read_err = 0;
    double lo = st->vmin, hi = st->vmax;
#ifdef _OPENMP
#pragma omp parallel reduction(min : lo) reduction(max : hi) reduction(+ : nrep)
#endif
    {
        int id = 0, nt = 1;
#ifdef _OPENMP
        id = omp_get_thread_num();
        nt = omp_get_num_threads();
#endif
        size_t a = g_nvox * (size_t)id / (size_t)nt;
        size_t b = g_nvox * (size_t)(id + 1) / (size_t)nt;
        size_t mybad = 0, myrep = 0;
        int rc = 0;
        for (size_t got = a * esz; got < b * esz;) {
            ssize_t k = pread(fd, (char *)raw + got, b * esz - got,
                              off + (off_t)got);
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
            rc = tvpal_raw_convert((const char *)raw + a * esz, o->type,
                                   o->big_endian, b - a, dst + a,
                                   o->has_nan_as ? &o->nan_as : NULL, &mybad,
                                   &myrep);
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
            uint64_t *fine = g_fine_local[id];
            nrep += myrep;
            for (size_t i = a; i < b; i++) {
                float v = dst[i];
                lo = v < lo ? v : lo;
                hi = v > hi ? v : hi;
                fine[fine_bin(v)]++;
            }
        }
    }
    close(fd);
    if (read_err > 0)
        die_fail("%s: timestep %u: %s (rerun to resume)", path, t,
                 strerror(read_err));
    if (read_err)
        die_input("%s: timestep %u: file shrank while encoding (truncated)",
                  path, t);
    if (rc_all < 0) {
        size_t x = bad % o->dims[0], y = bad / o->dims[0] % o->dims[1],
               z = bad / o->dims[0] / o->dims[1];
        if (rc_all == TVPAL_E_NAN)
            die_input("%s: timestep %u: NaN or infinite value at voxel "
                      "(%zu,%zu,%zu); expected finite values (use --nan-as "
                      "VALUE to replace them)", path, t, x, y, z);
        die_input("%s: timestep %u: value at voxel (%zu,%zu,%zu) exceeds "
                  "the supported magnitude %g", path, t, x, y, z,
                  TVPAL_VALUE_MAX);
    }
    if (!stats)
        return;
    for (int id = 0; id < g_nthreads; id++)
        for (uint32_t k = 0; k < FINE_BINS; k++) {
            st->fine[k] += g_fine_local[id][k];
            g_fine_local[id][k] = 0;
        }
    st->nonfinite += nrep;
    st->vmin = lo;
    st->vmax = hi;
    st->loaded = t + 1;
}

/* ------------------------------------------------------------- checkpoint */

/* Identity of the job: options and inputs (path, size, mtime).  A partial
 * output is resumed only by the same job. */
static char *fingerprint(const struct opts *o)
{
    char *params = NULL, *fp = NULL;
    if (asprintf(&params, "table=%u refine=%u naive=%d klt=%d alloc=%d "
                 "dims=%ux%ux%u type=%s endian=%s window=%u nodes=%u "
                 "steps=%u nan_as=%s%.17g", o->table_format, o->refine,
                 o->naive, o->klt, o->alloc_mse, o->dims[0], o->dims[1],
                 o->dims[2], tvpal_type_name(o->type),
                 o->big_endian ? "big" : "little", o->window, o->nodes,
                 o->steps_single, o->has_nan_as ? "" : "none:",
                 o->has_nan_as ? o->nan_as : 0.0) < 0)
        return NULL;
    if (tvpal_checkpoint_fingerprint(params, o->inputs, o->ninputs, &fp) < 0)
        fp = NULL;
    free(params);
    return fp;
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
                         unsigned char *chunk)
{
    const size_t nvox = (size_t)j->h.slice_w * j->h.slice_h;
    const uint32_t tf = j->h.table_format;
    const size_t tbytes = (size_t)len * 256 * tvpal_table_entry_bytes(tf);
    struct tvpal_swinfo info;
    tvpal_swenc_encode(enc, samples, nvox, len,
                       chunk + TVPAL_CHUNK_HEADER_BYTES + tbytes, table, &info);
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

/* Creates (start = 0) or resumes the shard writers; reports and returns
 * < 0 on the first failure. */
static int open_writers(struct shardjob *sj, uint32_t nshard,
                        const char *partial, uint32_t start)
{
    for (uint32_t q = 0; q < nshard; q++) {
        struct shardjob *j = &sj[q];
        struct tvpal_diag d = {{0}};
        char *path = tvpal_shard_filename(partial, j->rank, j->axis);
        int rc;
        if (!path)
            return TVPAL_E_NOMEM;
        if (start)
            rc = tvpal_shardw_resume(&j->w, path, &j->h, start, &d);
        else
            rc = tvpal_shardw_create(&j->w, path, &j->h);
        if (rc < 0)
            msg("%s: cannot %s: %s%s%s%s", path, start ? "resume" : "create",
                tvpal_strerror(rc), d.msg[0] ? " (" : "", d.msg,
                d.msg[0] ? ")" : "");
        if (rc < 0 && start)
            msg("starting the job over");
        free(path);
        if (rc < 0)
            return rc;
    }
    return 0;
}


int main(int argc, char **argv)
{
    struct opts o = {.type = TVPAL_F32, .window = 4, .nodes = 1};
    int have_dims = 0;
    static const struct option lopts[] = {
        {"dims", required_argument, 0, 'd'},
        {"type", required_argument, 0, 't'},
        {"endian", required_argument, 0, 'e'},
        {"steps", required_argument, 0, 's'},
        {"nan-as", required_argument, 0, 'N'},
        {"window", required_argument, 0, 'w'},
        {"nodes", required_argument, 0, 'k'},
        {"threads", required_argument, 0, 'j'},
        {"table", required_argument, 0, 'T'},
        {"refine", required_argument, 0, 'R'},
        {"naive", no_argument, 0, 'Z'},
        {"transform", required_argument, 0, 'X'},
        {"alloc", required_argument, 0, 'A'},
        {"output", required_argument, 0, 'o'},
        {"force", no_argument, 0, 'f'},
        {"quiet", no_argument, 0, 'q'},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0}};
    int c;
    struct tvpal_diag diag = {{0}};
    while ((c = getopt_long(argc, argv, "d:t:e:s:w:k:j:o:fqhV", lopts, NULL)) != -1) {
        switch (c) {
        case 'd':
            if (tvpal_dims_parse(optarg, o.dims, &diag) < 0)
                die_usage("--dims: %s", diag.msg);
            have_dims = 1;
            break;
        case 't':
            if (tvpal_type_parse(optarg, &o.type) < 0)
                die_usage("--type \"%s\": expected f32, f64, u8, u16 or i16",
                          optarg);
            break;
        case 'e':
            if (strcmp(optarg, "little") && strcmp(optarg, "big"))
                die_usage("--endian \"%s\": expected little or big", optarg);
            o.big_endian = !strcmp(optarg, "big");
            break;
        case 's':
            if (tvpal_parse_u32(optarg, 1, UINT32_MAX, &o.steps_single) < 0)
                die_usage("--steps \"%s\": expected a whole number >= 1",
                          optarg);
            break;
        case 'N':
            if (tvpal_parse_double(optarg, &o.nan_as) < 0 ||
                fabs(o.nan_as) > TVPAL_VALUE_MAX)
                die_usage("--nan-as \"%s\": expected a finite number", optarg);
            o.has_nan_as = 1;
            break;
        case 'w':
            if (tvpal_parse_u32(optarg, 1, TVPAL_NMAX, &o.window) < 0)
                die_usage("--window \"%s\": expected a whole number from 1 "
                          "to %d", optarg, TVPAL_NMAX);
            break;
        case 'k':
            if (tvpal_parse_u32(optarg, 1, UINT32_MAX, &o.nodes) < 0)
                die_usage("--nodes \"%s\": expected a whole number >= 1",
                          optarg);
            break;
        case 'j':
            if (tvpal_parse_u32(optarg, 1, 1024, &o.threads) < 0)
                die_usage("--threads \"%s\": expected 1..1024", optarg);
            break;
        case 'A':
            if (!strcmp(optarg, "greedy-mse"))
                o.alloc_mse = 1;
            else if (strcmp(optarg, "variance"))
                die_usage("--alloc \"%s\": expected variance or greedy-mse",
                          optarg);
            break;
        case 'X':
            if (!strcmp(optarg, "klt"))
                o.klt = 1;
            else if (strcmp(optarg, "dct"))
                die_usage("--transform \"%s\": expected dct or klt", optarg);
            break;
        case 'Z':
            o.naive = 1;
            break;
        case 'R':
            if (tvpal_parse_u32(optarg, 0, TVPAL_REFINE_MAX, &o.refine) < 0)
                die_usage("--refine \"%s\": expected 0..%d", optarg,
                          TVPAL_REFINE_MAX);
            break;
        case 'T':
            if (!strcmp(optarg, "u16"))
                o.table_format = TVPAL_TABLE_U16;
            else if (!strcmp(optarg, "f32"))
                o.table_format = TVPAL_TABLE_F32;
            else
                die_usage("--table \"%s\": expected f32 or u16", optarg);
            break;
        case 'o':
            o.outdir = optarg;
            break;
        case 'f':
            o.force = 1;
            break;
        case 'q':
            o.quiet = 1;
            break;
        case 'h':
            usage(stdout);
            return 0;
        case 'V':
            printf(PROG " " PACKAGE_VERSION " (format %u)\n",
                   TVPAL_FORMAT_VERSION);
            return 0;
        default:
            fprintf(stderr, "Try '" PROG " --help'.\n");
            return TVPAL_EXIT_USAGE;
        }
    }
    if (!have_dims)
        die_usage("--dims NXxNYxNZ is required (try --help)");
    if (!o.outdir || !*o.outdir)
        die_usage("-o OUTDIR is required (try --help)");
    o.inputs = argv + optind;
    o.ninputs = argc - optind;
    if (o.ninputs < 1)
        die_usage("no INPUT files given (one raw file per timestep)");
    if (o.steps_single && o.ninputs != 1)
        die_usage("--steps T takes exactly one INPUT holding all T timesteps "
                  "(%d given)", o.ninputs);
    for (unsigned a = 0; a < 3; a++)
        if (o.nodes > o.dims[a])
            die_usage("--nodes %u: larger than the %c axis (%u slices); "
                      "expected at most %u", o.nodes, "xyz"[a], o.dims[a],
                      o.dims[0] < o.dims[1] ? (o.dims[0] < o.dims[2] ? o.dims[0] : o.dims[2])
                                            : (o.dims[1] < o.dims[2] ? o.dims[1] : o.dims[2]));
    if (strchr(o.outdir, '\n'))
        die_usage("-o: a newline in the path is not supported");

    g_nvox = (size_t)o.dims[0] * o.dims[1] * o.dims[2];
    const size_t esz = tvpal_type_size(o.type);
    const uint64_t step_bytes = (uint64_t)g_nvox * esz;
    const uint32_t T = o.steps_single ? o.steps_single : (uint32_t)o.ninputs;
    const uint32_t N = o.window;
    if (step_bytes > (uint64_t)INT64_MAX / T)
        die_usage("--steps %u of %ux%ux%u %s: total size overflows", T,
                  o.dims[0], o.dims[1], o.dims[2], tvpal_type_name(o.type));

    /* Inputs: absolute paths (the manifest must name them from anywhere),
     * regular readable files of the expected size. */
    char **abs_inputs = calloc((size_t)o.ninputs, sizeof *abs_inputs);
    if (!abs_inputs)
        die_fail("out of memory");
    for (int i = 0; i < o.ninputs; i++) {
        struct stat st;
        const char *p = o.inputs[i];
        if (strchr(p, '\n'))
            die_usage("%s: a newline in a file name is not supported", p);
        if (stat(p, &st) < 0)
            die_usage("%s: cannot read input: %s", p, strerror(errno));
        if (!S_ISREG(st.st_mode))
            die_usage("%s: not a regular file", p);
        if (access(p, R_OK) < 0)
            die_usage("%s: cannot read input: %s", p, strerror(errno));
        uint64_t want = o.steps_single ? step_bytes * T : step_bytes;
        if ((uint64_t)st.st_size != want) {
            if (o.steps_single)
                die_usage("%s: size is %lld bytes; expected %llu (%u timesteps "
                          "of %ux%ux%u %s)", p, (long long)st.st_size,
                          (unsigned long long)want, T, o.dims[0], o.dims[1],
                          o.dims[2], tvpal_type_name(o.type));
            die_usage("%s: size is %lld bytes; expected %llu (one %ux%ux%u %s "
                      "timestep)", p, (long long)st.st_size,
                      (unsigned long long)want, o.dims[0], o.dims[1],
                      o.dims[2], tvpal_type_name(o.type));
        }
        abs_inputs[i] = realpath(p, NULL);
        if (!abs_inputs[i])
            die_usage("%s: %s", p, strerror(errno));
    }
    o.inputs = abs_inputs;

    /* Output directories. */
    char *partial = NULL;
    if (asprintf(&partial, "%s.partial", o.outdir) < 0)
        die_fail("out of memory");
    if (tvpal_exists(o.outdir) && !o.force)
        die_usage("%s: output already exists (use --force to replace it)",
                  o.outdir);
    {
        /* Inputs stay intact: no input may be, or lie inside, the output,
         * its .partial or its .old (all of which may be removed). */
        static const char *const sfx[] = {"", ".partial", ".old"};
        for (int k = 0; k < 3; k++) {
            char *p = NULL, *abs_p;
            if (asprintf(&p, "%s%s", o.outdir, sfx[k]) < 0)
                die_fail("out of memory");
            if ((abs_p = realpath(p, NULL))) {
                size_t n = strlen(abs_p);
                for (int i = 0; i < o.ninputs; i++)
                    if (!strncmp(o.inputs[i], abs_p, n) &&
                        (o.inputs[i][n] == '/' || o.inputs[i][n] == 0))
                        die_usage("%s: input %s is or lies inside %s; "
                                  "refusing to replace it", o.outdir,
                                  o.inputs[i], p);
                free(abs_p);
            }
            free(p);
        }
        /* --force replaces only a tvpal dataset, never another file. */
        if (tvpal_exists(o.outdir)) {
            char *mp = NULL;
            struct tvpal_manifest old;
            if (asprintf(&mp, "%s/manifest.txt", o.outdir) < 0)
                die_fail("out of memory");
            if (tvpal_manifest_load(mp, &old, NULL) < 0)
                die_usage("%s: exists and is not a tvpal dataset (no valid "
                          "manifest.txt); refusing to replace it", o.outdir);
            tvpal_manifest_clear(&old);
            free(mp);
        }
    }

    char *fp = fingerprint(&o);
    struct tvpal_checkpoint_stats st;
    if (!fp || tvpal_checkpoint_stats_init(&st) < 0)
        die_fail("out of memory");
    uint32_t start = 0;
    if (tvpal_exists(partial)) {
        /* Missing, another job's or damaged: start over (FORMAT.md 9.2). */
        if (tvpal_checkpoint_load(partial, fp, T, g_nvox, &start, &st,
                                  NULL) < 0 || start == 0) {
            start = 0;
            tvpal_checkpoint_stats_reset(&st);
            if (tvpal_rmtree(partial) < 0)
                die_usage("%s: cannot remove stale partial output", partial);
        }
    }
    for (uint32_t r = 0; r < o.nodes; r++) {
        char *nd;
        if (asprintf(&nd, "%s/node-%u", partial, r) < 0 || tvpal_mkdirs(nd) < 0)
            die_usage("%s: cannot create output directory: %s", partial,
                      strerror(errno));
        free(nd);
    }
    g_partial = partial;

    /* Shards and their writers. */
    const uint32_t nshard = 3 * o.nodes;
    struct shardjob *sj = calloc(nshard, sizeof *sj);
    if (!sj)
        die_fail("out of memory");
    size_t max_slice_vox = 0;
    size_t max_jobs = 0;
    for (unsigned a = 0; a < 3; a++) {
        uint32_t n, w, h;
        tvpal_axis_geometry(o.dims, a, &n, &w, &h);
        if ((size_t)w * h > max_slice_vox)
            max_slice_vox = (size_t)w * h;
        max_jobs += n;
        for (uint32_t r = 0; r < o.nodes; r++) {
            struct shardjob *j = &sj[a * o.nodes + r];
            j->axis = a;
            j->rank = r;
            j->h = (struct tvpal_shard_header){
                .version = TVPAL_FORMAT_VERSION, .steps = T, .window = N,
                .nodes = o.nodes, .rank = r, .axis = a, .slice_w = w,
                .slice_h = h, .table_format = o.table_format};
            memcpy(j->h.dims, o.dims, sizeof o.dims);
            tvpal_slab_range(n, o.nodes, r, &j->h.slice_begin,
                             &j->h.slice_count);
            /* Largest record: every slice of the slab with a full window. */
            j->rec_cap = tvpal_round_up(TVPAL_RECORD_HEADER_BYTES +
                                            (uint64_t)j->h.slice_count *
                                                tvpal_chunk_bytes(N, w, h, o.table_format),
                                        TVPAL_ALIGN);
            j->rec = malloc(j->rec_cap);
            if (!j->rec)
                die_fail("out of memory");
        }
    }
    while (open_writers(sj, nshard, partial, start) < 0) {
        /* A partial output that does not verify is started over. */
        for (uint32_t q = 0; q < nshard; q++) {
            tvpal_shardw_free(sj[q].w);
            sj[q].w = NULL;
        }
        if (!start)
            die_input("%s: cannot create the output files", partial);
        start = 0;
        tvpal_checkpoint_stats_reset(&st);
        tvpal_rmtree(partial);
        for (uint32_t r = 0; r < o.nodes; r++) {
            char *nd;
            if (asprintf(&nd, "%s/node-%u", partial, r) < 0 ||
                tvpal_mkdirs(nd) < 0)
                die_usage("%s: cannot create output directory: %s", partial,
                          strerror(errno));
            free(nd);
        }
        g_partial = partial;
    }

    /* Threads and their workspaces. */
    int nthreads = 1;
#ifdef _OPENMP
    if (o.threads)
        omp_set_num_threads((int)o.threads);
    nthreads = omp_get_max_threads();
#endif
    g_nthreads = nthreads;
    g_fine_local = calloc((size_t)nthreads, sizeof *g_fine_local);
    if (!g_fine_local)
        die_fail("out of memory");
    for (int i = 0; i < nthreads; i++)
        if (!(g_fine_local[i] = calloc(FINE_BINS, sizeof(uint64_t))))
            die_fail("out of memory");
    /* Samples per thread: one slice-window, or a group of x slices up to
     * 8 MiB (a group never exceeds GROUP_SPAN slices). */
    g_group_cap = max_slice_vox * N;
    if (g_group_cap < (size_t)2 << 20)
        g_group_cap = (size_t)2 << 20 < max_slice_vox * N * GROUP_SPAN
                          ? (size_t)2 << 20 : max_slice_vox * N * GROUP_SPAN;
    struct tvpal_swenc **enc = calloc((size_t)nthreads, sizeof *enc);
    float **samples = calloc((size_t)nthreads, sizeof *samples);
    float **tables = calloc((size_t)nthreads, sizeof *tables);
    struct slicejob *jobs = calloc(max_jobs, sizeof *jobs);
    float **ring = calloc(N, sizeof *ring);
    void *raw = malloc(step_bytes);
    if (!enc || !samples || !tables || !jobs || !ring || !raw)
        die_fail("out of memory");
    for (int i = 0; i < nthreads; i++) {
        if (tvpal_swenc_create(&enc[i], max_slice_vox, N) < 0 ||
            tvpal_swenc_set_refine(enc[i], o.refine) < 0 ||
            (tvpal_swenc_set_naive(enc[i], o.naive), 0) ||
            tvpal_swenc_set_alloc_mse(enc[i], o.alloc_mse) < 0 ||
            (o.klt && tvpal_swenc_set_klt(enc[i], 1) < 0 &&
             (die_usage("--transform klt: built without LAPACK (install "
                        "liblapack-dev and reconfigure)"), 1)) ||
            !(samples[i] = malloc(g_group_cap * sizeof(float))) ||
            !(tables[i] = malloc(N * 256 * sizeof(float))))
            die_fail("out of memory");
    }
    for (uint32_t i = 0; i < N; i++)
        if (!(ring[i] = malloc(g_nvox * sizeof(float))))
            die_fail("out of memory for %u timesteps of %zu voxels", N,
                      g_nvox);

    const int tty = isatty(STDERR_FILENO);
    const double t0 = tvpal_now();
    double last_report = t0;
    uint32_t loaded = start;
    const char *fault = getenv("TVPAL_ENCODE_FAULT_AFTER");
    const long fault_after = fault ? atol(fault) : -1;
    if (start && !o.quiet)
        msg("resuming %s at timestep %u of %u", partial, start, T);

    for (uint32_t t = start; t < T; t++) {
        uint32_t need = t + N < T ? t + N : T;
        while (loaded < need) {
            load_step(&o, loaded, raw, ring[loaded % N], &st);
            loaded++;
        }
        /* Every slice of every shard whose window starts at t. */
        size_t njobs = 0;
        for (uint32_t q = 0; q < nshard; q++) {
            struct shardjob *j = &sj[q];
            uint64_t off = TVPAL_RECORD_HEADER_BYTES;
            j->nchunks = 0;
            const size_t sv = (size_t)j->h.slice_w * j->h.slice_h;
            for (uint32_t k = 0; k < j->h.slice_count; k++) {
                uint32_t s = j->h.slice_begin + k;
                if (!tvpal_schedule_starts(s, t, N))
                    continue;
                uint32_t len = tvpal_schedule_len(s, t, N, T);
                uint64_t cb = tvpal_chunk_bytes(len, j->h.slice_w, j->h.slice_h,
                                                j->h.table_format);
                struct slicejob *prev = njobs ? &jobs[njobs - 1] : NULL;
                /* Extend the previous x group when this slice is the next of
                 * its phase, in the same line, with the same window, and the
                 * group's samples stay within the workspace. */
                if (j->axis == 0 && prev && prev->sj == j && prev->len == len &&
                    s == prev->slice + prev->count * N &&
                    s / GROUP_SPAN == prev->slice / GROUP_SPAN &&
                    (uint64_t)(prev->count + 1) * len * sv <= g_group_cap)
                    prev->count++;
                else
                    jobs[njobs++] = (struct slicejob){j, s, 1, len, off};
                off += cb;
                j->nchunks++;
            }
            j->payload = off - TVPAL_RECORD_HEADER_BYTES;
        }
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1)
#endif
        for (size_t i = 0; i < njobs; i++) {
            int tid = 0;
#ifdef _OPENMP
            tid = omp_get_thread_num();
#endif
            const struct slicejob *jb = &jobs[i];
            const struct shardjob *j = jb->sj;
            const size_t sv = (size_t)j->h.slice_w * j->h.slice_h;
            const uint64_t cb = tvpal_chunk_bytes(jb->len, j->h.slice_w,
                                                  j->h.slice_h,
                                                  j->h.table_format);
            gather(&o, ring, jb, t, samples[tid]);
            for (uint32_t g = 0; g < jb->count; g++)
                encode_chunk(enc[tid], tables[tid],
                             samples[tid] + (size_t)g * jb->len * sv, j,
                             jb->slice + g * N, t, jb->len,
                             j->rec + jb->off + g * cb);
        }
        for (uint32_t q = 0; q < nshard; q++) {
            struct shardjob *j = &sj[q];
            uint64_t bytes = tvpal_record_seal(j->rec, t, j->axis, j->nchunks,
                                               j->payload);
            struct tvpal_diag d = {{0}};
            int rc = tvpal_shardw_append(j->w, j->rec, bytes, &d);
            if (rc < 0) {
                msg("%s/node-%u/axis-%c.tvps: %s (%s)", partial, j->rank,
                    "xyz"[j->axis], tvpal_strerror(rc), d.msg);
                return TVPAL_EXIT_FAIL;
            }
        }
        if (t == 0 && T > 1) {
            /* Record 0 holds every slice; later records hold one phase
             * (at most ceil(n / N) slices): give the rest back. */
            for (uint32_t q = 0; q < nshard; q++) {
                struct shardjob *j = &sj[q];
                uint64_t cap = tvpal_round_up(
                    TVPAL_RECORD_HEADER_BYTES +
                        (uint64_t)((j->h.slice_count + N - 1) / N + 1) *
                            tvpal_chunk_bytes(N, j->h.slice_w, j->h.slice_h,
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
        struct tvpal_diag cd = {{0}};
        int crc = tvpal_checkpoint_save(partial, fp, t + 1, &st, &cd);
        if (crc < 0) {
            msg("%s/checkpoint: cannot write: %s (%s)", partial,
                tvpal_strerror(crc), cd.msg);
            return TVPAL_EXIT_FAIL;
        }
        if (fault_after >= 0 && (long)(t + 1) >= fault_after)
            raise(SIGKILL); /* test hook: simulate an interruption */

        double now = tvpal_now();
        if (!o.quiet && (t + 1 == T || now - last_report >= (tty ? 0.2 : 30.0))) {
            char line[256];
            double el = now - t0;
            double done = (double)(t + 1 - start);
            double rate = done * (double)g_nvox / (el > 0 ? el : 1e-9) / 1e6;
            double eta = el / done * (double)(T - t - 1);
            tvpal_progress_format(line, sizeof line, t + 1, T, "steps", rate,
                                  "Mvox-steps/s", eta, tty ? 30 : 0);
            if (tty)
                fprintf(stderr, "\r%s\033[K%s", line, t + 1 == T ? "\n" : "");
            else
                fprintf(stderr, PROG ": %s\n", line);
            last_report = now;
        }
    }
    const double t_encode = tvpal_now() - t0;

    /* Finish shards, then the manifest; rename into place last. */
    uint64_t total_bytes = 0;
    for (uint32_t q = 0; q < nshard; q++) {
        tvpal_shardw_set_range(sj[q].w, st.vmin, st.vmax);
        struct tvpal_diag d = {{0}};
        int rc = tvpal_shardw_finish(sj[q].w, &d);
        sj[q].w = NULL;
        if (rc < 0) {
            msg("%s/node-%u/axis-%c.tvps: cannot finish: %s (%s)", partial,
                sj[q].rank, "xyz"[sj[q].axis], tvpal_strerror(rc), d.msg);
            return TVPAL_EXIT_FAIL;
        }
    }
    struct tvpal_manifest m = {0};
    memcpy(m.dims, o.dims, sizeof o.dims);
    m.type = o.type;
    m.big_endian = o.big_endian;
    m.steps = T;
    m.window = N;
    m.nodes = o.nodes;
    m.value_min = st.vmin;
    m.value_max = st.vmax;
    m.has_nan_as = o.has_nan_as;
    m.nan_as = o.nan_as;
    m.nonfinite = st.nonfinite;
    m.single_file = o.steps_single != 0;
    m.source_bytes = step_bytes * T;
    for (uint32_t b = 0; b < FINE_BINS; b++) {
        if (!st.fine[b])
            continue;
        double v = fine_bin_value(b);
        double span = st.vmax - st.vmin;
        int bin = span > 0 ? (int)((v - st.vmin) / span * TVPAL_HIST_BINS) : 0;
        bin = bin < 0 ? 0 : bin >= TVPAL_HIST_BINS ? TVPAL_HIST_BINS - 1 : bin;
        m.histogram[bin] += st.fine[b];
    }
    char optstr[256];
    snprintf(optstr, sizeof optstr, "--dims %ux%ux%u --type %s --endian %s "
             "--window %u --nodes %u%s", o.dims[0], o.dims[1], o.dims[2],
             tvpal_type_name(o.type), o.big_endian ? "big" : "little", N,
             o.nodes, o.steps_single ? " --steps" : "");
    if (o.steps_single)
        snprintf(optstr + strlen(optstr), sizeof optstr - strlen(optstr),
                 " %u", T);
    if (o.has_nan_as)
        snprintf(optstr + strlen(optstr), sizeof optstr - strlen(optstr),
                 " --nan-as %.17g", o.nan_as);
    if (o.table_format == TVPAL_TABLE_U16)
        snprintf(optstr + strlen(optstr), sizeof optstr - strlen(optstr),
                 " --table u16");
    if (o.refine)
        snprintf(optstr + strlen(optstr), sizeof optstr - strlen(optstr),
                 " --refine %u", o.refine);
    if (o.naive)
        snprintf(optstr + strlen(optstr), sizeof optstr - strlen(optstr),
                 " --naive");
    if (o.klt)
        snprintf(optstr + strlen(optstr), sizeof optstr - strlen(optstr),
                 " --transform klt");
    if (o.alloc_mse)
        snprintf(optstr + strlen(optstr), sizeof optstr - strlen(optstr),
                 " --alloc greedy-mse");
    m.table_format = o.table_format;
    m.encoder = strdup(PROG " " PACKAGE_VERSION);
    m.options = strdup(optstr);
    for (int i = 0; i < o.ninputs; i++)
        if (tvpal_manifest_add_source(&m, o.inputs[i]) < 0)
            die_fail("out of memory");
    char *text = NULL;
    if (!m.encoder || !m.options || tvpal_manifest_format(&m, &text) < 0)
        die_fail("out of memory");
    for (int r = -1; r < (int)o.nodes; r++) {
        char *path;
        int ok = r < 0 ? asprintf(&path, "%s/manifest.txt", partial)
                       : asprintf(&path, "%s/node-%d/manifest.txt", partial, r);
        if (ok < 0 || tvpal_write_file_atomic(path, text, strlen(text)) < 0) {
            msg("%s: cannot write manifest", partial);
            return TVPAL_EXIT_FAIL;
        }
        free(path);
    }
    tvpal_checkpoint_remove(partial, NULL);
    tvpal_fsync_dir(partial);
    if (tvpal_exists(o.outdir)) {
        char *old;
        if (asprintf(&old, "%s.old", o.outdir) < 0)
            die_fail("out of memory");
        tvpal_rmtree(old);
        if (rename(o.outdir, old) < 0 || rename(partial, o.outdir) < 0) {
            msg("%s: cannot replace: %s", o.outdir, strerror(errno));
            return TVPAL_EXIT_FAIL;
        }
        tvpal_rmtree(old);
        free(old);
    } else if (rename(partial, o.outdir) < 0) {
        msg("%s: cannot rename %s into place: %s", o.outdir, partial,
            strerror(errno));
        return TVPAL_EXIT_FAIL;
    }

    /* Summary. */
    struct tvpal_dataset *ds = NULL;
    if (tvpal_dataset_open(&ds, o.outdir, &diag) < 0) {
        msg("%s: written dataset does not verify: %s", o.outdir, diag.msg);
        return TVPAL_EXIT_FAIL;
    }
    for (unsigned a = 0; a < 3; a++)
        total_bytes += ds->axis_bytes[a];
    double axis_bytes = (double)total_bytes / 3.0;
    double vts = (double)g_nvox * T;
    printf("encoded %s: steps=%u window=%u nodes=%u bytes=%llu ratio=%.3f "
           "bpv=%.4f seconds=%.3f rate=%.2fM vox-steps/s threads=%d\n",
           o.outdir, T, N, o.nodes, (unsigned long long)total_bytes,
           (double)m.source_bytes / axis_bytes, axis_bytes * 8.0 / vts,
           t_encode, (double)(T - start) * g_nvox / (t_encode > 0 ? t_encode : 1e-9) / 1e6,
           nthreads);
    tvpal_dataset_close(ds);

    for (uint32_t q = 0; q < nshard; q++)
        free(sj[q].rec);
    free(sj);
    for (int i = 0; i < nthreads; i++) {
        tvpal_swenc_free(enc[i]);
        free(samples[i]);
        free(tables[i]);
    }
    for (uint32_t i = 0; i < N; i++)
        free(ring[i]);
    free(ring);
    free(raw);
    free(enc);
    free(samples);
    free(tables);
    free(jobs);
    free(text);
    free(fp);
    tvpal_checkpoint_stats_free(&st);
    free(partial);
    tvpal_manifest_clear(&m);
    for (int i = 0; i < o.ninputs; i++)
        free(abs_inputs[i]);
    free(abs_inputs);
    return 0;
}
