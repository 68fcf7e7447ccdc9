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

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

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
    int free_i = -1, fd = -1;
    *slot = -1;
    pthread_mutex_lock(&rf->lock);
    for (int i = 0; i < 2 && *slot < 0; i++) {
        if (rf->slot[i].step == (int64_t)t)
            *slot = i;
        else if (!rf->slot[i].users && free_i < 0)
            free_i = i;
    }
    if (*slot < 0 && free_i >= 0) { /* the step's file into a free slot */
        if (rf->slot[free_i].fd >= 0)
            close(rf->slot[free_i].fd);
        rf->slot[free_i].step = -1;
        if ((rf->slot[free_i].fd = tvpal_open_regular(path, d)) >= 0) {
            rf->slot[free_i].step = t;
            *slot = free_i;
        }
    }
    if (*slot >= 0) {
        rf->slot[*slot].users++;
        fd = rf->slot[*slot].fd;
    }
    pthread_mutex_unlock(&rf->lock);
    /* Both slots busy with other steps: a file of its own. */
    return *slot >= 0 || free_i >= 0 ? fd : tvpal_open_regular(path, d);
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
