/* encode_source.c: tvpal-encode's input (see encode.h): the source
 * checked, its times, and each pass's box of every timestep read,
 * converted to float, checked and counted into the statistics. */
#define _GNU_SOURCE
#include "encode_output.h"
#include "encode_say.h"
#include "encode_source.h"
#include "tvpal.h"
#include "tvpal_cli.h"
#include "tvpal_fs.h"
#include "tvpal_passes.h"
#include "tvpal_readahead.h"
#include "tvpal_values.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* ------------------------------------------------------------- input I/O */

struct tvpal_found *encode_found_alloc(size_t n)
{
    return calloc(n, sizeof(struct tvpal_found));
}

/* Converts n source values at src (type and byte order of the job, or
 * host float32 when `host_f32`) into dst, applies --missing, and counts
 * them into the thread's statistics when `stats`.  vox0 is the volume
 * index of the first, for the error message. */
static void convert_run(const struct run *r, const void *src, int host_f32,
                        size_t n, float *dst, uint64_t vox0, int stats,
                        int tid, struct tvpal_found *f)
{
    const struct opts *o = &r->o;
    const struct tvpal_values_rules rules = {
        o->missing, o->nmissing, o->has_nan_as ? &o->nan_as : NULL};
#ifdef WORDS_BIGENDIAN
    const int host_big = 1;
#else
    const int host_big = 0;
#endif
    tvpal_values_convert(&rules, src, host_f32 ? TVPAL_F32 : o->type,
                         host_f32 ? host_big : o->big_endian, n, dst, vox0,
                         stats ? r->fine_local[tid] : NULL, f);
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

/* One box read or conversion, shared by the pool's threads; each thread
 * counts into r->found_local[tid], merged after the loop. */
struct box_ctx {
    struct run *r;
    const struct encode_box *b;
    float *dst;
    int stats;
    int fd;                         /* read_box_raw: the file, */
    off_t base;                     /* the step's offset in it, */
    size_t rows;                    /* rows per piece, */
    size_t pieces_per_plane;
    const float *src;               /* convert_box: the box as read */
};

/* Runs fn over n pieces of c's box on the pool and merges the threads'
 * findings into *res. */
static void for_box_threads(struct box_ctx *c, tvpal_pool_fn fn, size_t n,
                            struct tvpal_found *res)
{
    struct run *r = c->r;
    struct tvpal_found all = tvpal_found_empty(r->st.vmin, r->st.vmax);
    for (int tid = 0; tid < r->nthreads; tid++)
        r->found_local[tid] = all;
    tvpal_pool_for(r->pool, n, fn, c);
    for (int tid = 0; tid < r->nthreads; tid++)
        tvpal_found_merge(&all, &r->found_local[tid]);
    *res = all;
}

/* read_box_raw's piece p: rows of one plane of the box, read with one
 * pread into the thread's scratch and converted into place. */
static void read_piece(void *arg, size_t p, unsigned tid)
{
    const struct box_ctx *c = arg;
    struct run *r = c->r;
    const struct encode_box *b = c->b;
    struct tvpal_found *f = &r->found_local[tid];
    if (f->read_err) /* this thread already failed: the step is lost */
        return;
    const size_t esz = tvpal_type_size(r->o.type);
    const size_t nx = r->o.dims[0], ny = r->o.dims[1];
    const size_t row_bytes = nx * esz;
    unsigned char *buf = r->scratch[tid];
    const size_t z = b->lo[2] + p / c->pieces_per_plane;
    const size_t y0 = b->lo[1] + p % c->pieces_per_plane * c->rows;
    size_t yn = b->lo[1] + b->n[1] - y0;
    yn = yn < c->rows ? yn : c->rows;
    /* From the first row's first voxel to the last row's last. */
    const uint64_t v0 = b->lo[0] + nx * (y0 + ny * z);
    const size_t span = ((yn - 1) * nx + b->n[0]) * esz;
    int err = pread_full(c->fd, buf, span, c->base + (off_t)(v0 * esz));
    if (err) {
        f->read_err = err;
        return;
    }
    for (size_t k = 0; k < yn; k++) {
        const size_t yb = y0 + k - b->lo[1], zb = z - b->lo[2];
        float *out = c->dst + (size_t)b->n[0] * (yb + (size_t)b->n[1] * zb);
        convert_run(r, buf + k * row_bytes, 0, b->n[0], out, v0 + k * nx,
                    c->stats, (int)tid, f);
    }
    if (tid == 0) /* a step of hundreds of GiB takes minutes */
        report_progress(r, 0);
}

/* The box b of the raw timestep at file offset base of fd into dst (box
 * voxels, x fastest), converted, in parallel over blocks of rows: each
 * z-plane of the box is read as the one file range that holds its rows
 * (a y or z slab: only its bytes; an x slab: whole rows, its part used),
 * in pieces of at most TVPAL_READ_BLOCK bytes, into the reading thread's
 * scratch. */
static void read_box_raw(struct run *r, int fd, off_t base,
                         const struct encode_box *b, float *dst, int stats,
                         struct tvpal_found *res)
{
    const size_t row_bytes = (size_t)r->o.dims[0] *
                             tvpal_type_size(r->o.type);
    /* Rows per piece: a piece spans whole rows of one plane. */
    const size_t rows = tvpal_passes_read_rows(row_bytes, b->n[1]);
    const size_t pieces_per_plane = (b->n[1] + rows - 1) / rows;
    struct box_ctx c = {.r = r, .b = b, .dst = dst, .stats = stats, .fd = fd,
                        .base = base, .rows = rows,
                        .pieces_per_plane = pieces_per_plane};
    for_box_threads(&c, read_piece, pieces_per_plane * b->n[2], res);
}

/* convert_box's piece k: row k of the box, from c->src. */
static void convert_row(void *arg, size_t k, unsigned tid)
{
    const struct box_ctx *c = arg;
    const struct encode_box *b = c->b;
    const size_t nx = c->r->o.dims[0], ny = c->r->o.dims[1];
    const size_t y = b->lo[1] + k % b->n[1], z = b->lo[2] + k / b->n[1];
    const size_t at = k * b->n[0];
    convert_run(c->r, c->src + at, 1, b->n[0], c->dst + at,
                b->lo[0] + nx * (y + ny * z), c->stats, (int)tid,
                &c->r->found_local[tid]);
}

/* The box b of a self-describing step, already read into src (host
 * float32, box voxels), checked and converted into dst in parallel. */
static void convert_box(struct run *r, const float *src,
                        const struct encode_box *b, float *dst, int stats,
                        struct tvpal_found *res)
{
    struct box_ctx c = {.r = r, .b = b, .dst = dst, .stats = stats,
                        .fd = -1, .src = src};
    for_box_threads(&c, convert_row, (size_t)b->n[1] * b->n[2], res);
}

/* Whether box b is the whole volume (read with tvpal_input_read). */
static int box_is_whole(const struct run *r, const struct encode_box *b)
{
    return b->n[0] == r->o.dims[0] && b->n[1] == r->o.dims[1] &&
           b->n[2] == r->o.dims[2];
}

/* A self-describing input is read (and inflated) by its library on one
 * thread; the encoding of a step runs on all of them.  One reader thread
 * (tvpal_readahead.h) reads the box of step t + 1 while step t is
 * converted and encoded, so the two overlap; it is the only thread that
 * calls the input library once it runs (HDF5 and libnetcdf builds need
 * not be thread-safe). */
static int read_input_box(struct tvpal_input *in, uint32_t t,
                          const struct encode_box *b, int whole, float *dst,
                          struct tvpal_diag *d)
{
    return whole ? tvpal_input_read(in, t, dst, d)
                 : tvpal_input_read_box(in, t, b->lo, b->n, dst, d);
}

/* The reader thread's read: box b of step t of the run's input (it only
 * reads r->in and the dims, which do not change while it runs). */
static int read_ahead_box(void *ctx, uint32_t t, const struct encode_box *b,
                          void *dst, struct tvpal_diag *d)
{
    const struct run *r = ctx;
    return read_input_box(r->in, t, b, box_is_whole(r, b), dst, d);
}

struct tvpal_readahead *prefetch_start(const struct run *r, uint64_t voxels)
{
    return tvpal_readahead_start(read_ahead_box, (void *)r,
                                 (size_t)voxels * sizeof(float));
}

/* The pass's box of step t of the input into r->boxbuf: from the reader
 * (the buffers are swapped; asked for now when it was not read ahead; every
 * read goes to it, so that a long one still gets progress lines here),
 * then step t + 1 of the same pass is asked for. */
static int input_step(struct run *r, uint32_t t, struct tvpal_diag *d)
{
    const struct encode_box *b = &r->pass->box;
    if (!r->pf) /* no reader thread: read here */
        return read_input_box(r->in, t, b, box_is_whole(r, b), r->boxbuf, d);
    void *buf = r->boxbuf;
    int rc = tvpal_readahead_take(r->pf, t, t + 1 < r->T ? (int64_t)t + 1 : -1,
                                  b, &buf, tick_progress, r, d);
    r->boxbuf = buf;
    return rc;
}

/* Reads the pass's box of timestep t of the source into dst (converted),
 * accounting stats when the pass keeps them and t is not yet in them.  A
 * read error ends the program keeping the partial output (maybe
 * transient); bad data ends it removing it. */
void load_step(struct run *r, uint32_t t, float *dst)
{
    const struct opts *o = &r->o;
    const struct encode_box *b = &r->pass->box;
    /* Raw: a file per step, or one of them all; a reader knows its own. */
    const char *path = r->in || o->steps_single ? o->inputs[0] : o->inputs[t];
    const off_t off = o->steps_single ? (off_t)t * (off_t)r->step_bytes : 0;
    const int stats = r->pass->stats && t >= r->st.loaded;
    struct tvpal_found res;
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
    tvpal_values_account(&r->st, r->fine_local, (unsigned)r->nthreads, &res,
                         encode_box_voxels(b));
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
void order_inputs(struct opts *o)
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
int open_source(struct run *r, int have_dims)
{
    struct opts *o = &r->o;
    struct tvpal_diag d = {{0}};
    enum tvpal_input_format f = o->format;
    struct tvpal_input_opts io = {.var = o->var, .time_dim = o->time_dim,
                                  .allow_external = o->allow_external,
                                  .magnitude = o->magnitude};
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
        if (o->magnitude)
            die_usage("--magnitude: for VTK input (vti, vtk), whose arrays "
                      "say their components; %s is raw", o->inputs[0]);
        return have_dims;
    }
    /* Compressed blocks and chunks inflate on a team of their own: the
     * prefetch thread drives it while the encoding team works. */
    unsigned nt = o->threads ? o->threads : tvpal_pool_default_threads();
    int prc = nt > 1 ? tvpal_pool_create(&r->in_pool, nt) : 0;
    if (prc < 0)
        die_fail("%u threads to read %s: %s", nt, o->inputs[0],
                 lib_error(prc, NULL));
    io.pool = r->in_pool;
    /* AUTO again when the format was found here: the reader then checks
     * that every file is of the first one's format. */
    int rc = tvpal_input_open(&r->in, o->format == TVPAL_IN_AUTO
                                          ? TVPAL_IN_AUTO : f,
                              o->inputs, o->ninputs, &io, &d);
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

/* Control characters of s (a manifest value) become spaces: one line. */
static void one_line(char *s)
{
    for (; *s; s++)
        if ((unsigned char)*s < ' ')
            *s = ' ';
}

/* The steps' time values: --times FILE (T rising numbers, any white
 * space between them), else a time coordinate of the input, else none
 * (the manifest then says nothing and the steps are their indices); and
 * the values' units: --units, else the input variable's. */
void load_times(struct run *r)
{
    const struct opts *o = &r->o;
    const struct tvpal_input_info *in = r->in ? tvpal_input_info(r->in) : NULL;
    /* The values' units go with the times: what the manifest says of the
     * physical meaning of the data. */
    snprintf(r->units, sizeof r->units, "%s",
             o->units ? o->units : in ? in->units : "");
    one_line(r->units);
    if (!o->times_file && !(in && in->has_times))
        return;
    if (!(r->times = malloc(sizeof *r->times * r->T)))
        die_fail("out of memory");
    snprintf(r->time_units, sizeof r->time_units, "%s",
             o->time_units ? o->time_units : in ? in->time_units : "");
    one_line(r->time_units);
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
    /* Every number is read (the count says how many there are). */
    while (fscanf(f, "%lf", &v) == 1) {
        if (n < r->T && (!isfinite(v) || (n > 0 && v <= r->times[n - 1])))
            die_usage("--times %s: value %u (%g): expected a finite number "
                      "larger than the one before", o->times_file, n + 1, v);
        if (n < r->T)
            r->times[n] = v;
        if (n < UINT32_MAX)
            n++;
    }
    int junk = !feof(f);
    fclose(f);
    if (junk)
        die_usage("--times %s: not a number after %u numbers (one per step "
                  "expected, %u of them)", o->times_file, n, r->T);
    if (n != r->T)
        die_usage("--times %s: %u numbers; expected %u, one per step",
                  o->times_file, n, r->T);
}

/* Windows that straddle a gap in time cost accuracy there (the DCT sees a
 * jump): warn when an interval is more than twice a neighbouring one,
 * naming the steps. */
void warn_irregular_times(const struct run *r)
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
void check_inputs(struct run *r)
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

/* ------------------------------------------------- the library's source */

/* The raw files being read, each opened once per step read: the library
 * reads the pieces of a step's box on several threads at once, a step
 * after another, so two open files serve every call (a third, if ever,
 * opens its own). */
struct raw_files {
    pthread_mutex_t lock;
    struct {
        int64_t step;        /* -1: none */
        int fd;
        unsigned users;
    } slot[2];
};

/* The file of step t open (*slot: which, -1 its own); -1 with diag. */
static int raw_open(struct raw_files *rf, const char *path, uint32_t t,
                    int *slot, struct tvpal_diag *d)
{
    int fd = -1;
    *slot = -1;
    pthread_mutex_lock(&rf->lock);
    for (int i = 0; i < 2 && fd < 0; i++)
        if (rf->slot[i].step == (int64_t)t) {
            rf->slot[i].users++;
            fd = rf->slot[i].fd, *slot = i;
        }
    for (int i = 0; i < 2 && fd < 0; i++)
        if (!rf->slot[i].users) {
            if (rf->slot[i].fd >= 0)
                close(rf->slot[i].fd);
            rf->slot[i].step = -1;
            if ((rf->slot[i].fd = tvpal_open_regular(path, d)) < 0)
                break;
            rf->slot[i].step = t;
            rf->slot[i].users = 1;
            fd = rf->slot[i].fd, *slot = i;
        }
    pthread_mutex_unlock(&rf->lock);
    return fd >= 0 || *slot >= 0 ? fd : tvpal_open_regular(path, d);
}

static void raw_close(struct raw_files *rf, int fd, int slot)
{
    if (slot < 0) {
        close(fd);
        return;
    }
    pthread_mutex_lock(&rf->lock);
    rf->slot[slot].users--;
    pthread_mutex_unlock(&rf->lock);
}

void encode_source_close(struct run *r)
{
    struct raw_files *rf = r->rawf;
    for (int i = 0; rf && i < 2; i++)
        if (rf->slot[i].fd >= 0)
            close(rf->slot[i].fd);
    if (rf)
        pthread_mutex_destroy(&rf->lock);
    free(rf);
    r->rawf = NULL;
}

/* Raw files (tvpal.h's source, concurrent): box lo, n of step t, as the
 * file holds it, read with pread: each plane's rows as one range when they
 * are whole (a z or y slab), else row by row (an x slab). */
static int raw_read(void *ctx, uint32_t t, const uint32_t lo[3],
                    const uint32_t n[3], void *dst, struct tvpal_diag *d)
{
    const struct run *r = ctx;
    const struct opts *o = &r->o;
    const char *path = o->steps_single ? o->inputs[0] : o->inputs[t];
    const off_t base = o->steps_single ? (off_t)t * (off_t)r->step_bytes : 0;
    struct tvpal_diag od = {{0}};
    int slot;
    const int fd = raw_open(r->rawf, path, o->steps_single ? 0 : t, &slot,
                            &od);
    if (fd < 0) /* maybe transient (NFS, permissions): the partial stays */
        return tvpal_diag_set(d, TVPAL_E_OPEN, "cannot open %s (rerun to "
                              "resume)", od.msg);
    const size_t es = tvpal_type_size(o->type), nx = o->dims[0],
                 ny = o->dims[1], row = (size_t)n[0] * es;
    unsigned char *out = dst;
    int err = 0;
    for (uint32_t z = 0; z < n[2] && !err; z++) {
        const uint64_t v0 = lo[0] + nx * (lo[1] + ny * (uint64_t)(lo[2] + z));
        if (n[0] == nx) {
            err = pread_full(fd, out, row * n[1], base + (off_t)(v0 * es));
            out += row * n[1];
        } else {
            for (uint32_t y = 0; y < n[1] && !err; y++, out += row)
                err = pread_full(fd, out, row,
                                 base + (off_t)((v0 + y * nx) * es));
        }
    }
    raw_close(r->rawf, fd, slot);
    if (err > 0)
        return tvpal_diag_set(d, TVPAL_E_READ, "%s: timestep %u: %s (rerun "
                              "to resume)", path, t, strerror(err));
    if (err)
        return tvpal_diag_set(d, TVPAL_E_FORMAT, "%s: timestep %u: file "
                              "shrank while encoding (truncated)", path, t);
    return 0;
}

/* A self-describing input (tvpal_input.h), on the library's reader thread,
 * the only one that calls the input's library once the encode runs. */
static int input_read(void *ctx, uint32_t t, const uint32_t lo[3],
                      const uint32_t n[3], void *dst, struct tvpal_diag *d)
{
    const struct run *r = ctx;
    const uint32_t *dm = r->o.dims;
    struct tvpal_diag id = {{0}};
    const int whole = n[0] == dm[0] && n[1] == dm[1] && n[2] == dm[2];
    int rc = whole ? tvpal_input_read(r->in, t, dst, &id)
                   : tvpal_input_read_box(r->in, t, lo, n, dst, &id);
    if (rc < 0) { /* the file changed or is corrupt: a rerun fails too */
        uint32_t k;
        const char *path = tvpal_input_file(r->in, t, &k);
        return tvpal_diag_set(d, TVPAL_E_FORMAT, "timestep %u (step %u of "
                              "%s): %s", t, k, path, lib_error(rc, &id));
    }
    return 0;
}

struct tvpal_source encode_source_of(struct run *r)
{
    const struct opts *o = &r->o;
    if (!r->in && !r->rawf) {
        if (!(r->rawf = calloc(1, sizeof *r->rawf)))
            die_fail("out of memory");
        pthread_mutex_init(&r->rawf->lock, NULL);
        for (int i = 0; i < 2; i++)
            r->rawf->slot[i].step = -1, r->rawf->slot[i].fd = -1;
    }
    static const enum tvpal_scalar types[] = {
        [TVPAL_F32] = TVPAL_FLOAT32, [TVPAL_F64] = TVPAL_FLOAT64,
        [TVPAL_U8] = TVPAL_UINT8, [TVPAL_U16] = TVPAL_UINT16,
        [TVPAL_I16] = TVPAL_INT16};
    return (struct tvpal_source){
        .type = r->in ? TVPAL_FLOAT32 : types[o->type],
        .big_endian = r->in ? 0 : o->big_endian,
        .concurrent = !r->in,
        .held_bytes = r->in ? tvpal_input_box_scratch(r->in, o->dims) : 0,
        .ctx = r,
        .read = r->in ? input_read : raw_read};
}
