/* tvpal_encoder.c: the encoder of tvpal.h, timesteps from memory into a
 * dataset, in one pass.
 *
 * The steps pushed go, converted, into the engine's ring of N whole
 * volumes (tvpal_engine.h); once step p is in, every slice-window that
 * starts at p - N + 1 has its steps and is encoded, so the encoder holds N
 * steps and its workspaces whatever T is.  The shards are written in
 * place under DIR.partial as they are coded, the manifest at the end, and
 * the dataset is read back before DIR.partial becomes DIR (the order of
 * tvpal-encode: no file at DIR looks complete before it is).  The shards
 * are those tvpal-encode writes from the same values in files.
 */
#define _GNU_SOURCE
#include "tvpal.h"

#include "tvpal_checkpoint.h"
#include "tvpal_dataset.h"
#include "tvpal_engine.h"
#include "tvpal_fs.h"
#include "tvpal_manifest.h"
#include "tvpal_raw.h"
#include "tvpal_size.h"
#include "tvpal_values.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MISSING_MAX 16u
#define LIB_NAME "libtvpal " PACKAGE_VERSION

enum state { OPENED, STARTED, FAILED };

struct tvpal_encoder {
    char *dir, *partial, *lock_path;
    int lock_fd;
    struct tvpal_engine_params ep;
    unsigned threads;
    uint64_t mem_limit;
    int force, has_nan_as;
    double nan_as;
    double spacing[3], origin[3];
    double *times;
    char time_units[128], units[64];
    double missing[MISSING_MAX];
    unsigned nmissing;
    enum state state;
    enum tvpal_type type;            /* of the first push */
    uint32_t pushed, encoded;        /* steps in, steps' windows coded */
    struct tvpal_engine *eng;
    struct tvpal_pool *pool;
    struct encode_pass pass;         /* the whole volume, every axis */
    struct tvpal_checkpoint_stats st;
    uint64_t **fine;                 /* per thread */
    struct tvpal_found *found;       /* per thread */
    void **rows;                     /* per thread: a row of 8-byte values
                                      * (strided pushes) */
};

unsigned tvpal_version_number(void)
{
    return TVPAL_VERSION_NUMBER;
}

const char *tvpal_version_string(void)
{
    return PACKAGE_VERSION;
}

/* ------------------------------------------------------------ open, set */

int tvpal_encoder_open(struct tvpal_encoder **out, const char *dir,
                       const uint32_t dims[3], uint32_t steps,
                       struct tvpal_diag *diag)
{
    *out = NULL;
    if (!dir || !*dir)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "no output directory");
    for (int a = 0; a < 3; a++)
        if (dims[a] < 1 || dims[a] > INT32_MAX)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "dims[%d] is %u: "
                                  "1 .. 2^31 - 1 expected", a, dims[a]);
    uint64_t v;
    if (tvpal_mul3(dims[0], dims[1], dims[2], &v) < 0 ||
        v > SIZE_MAX / 8)
        return tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "%ux%ux%u voxels: "
                              "too many for this machine", dims[0], dims[1],
                              dims[2]);
    if (steps < 1)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "steps is 0: at least "
                              "one timestep expected");
    struct tvpal_encoder *e = calloc(1, sizeof *e);
    if (!e || !(e->dir = strdup(dir)) ||
        asprintf(&e->partial, "%s.partial", dir) < 0) {
        if (e)
            free(e->dir);
        free(e);
        return TVPAL_E_NOMEM;
    }
    e->lock_fd = -1;
    e->ep = (struct tvpal_engine_params){
        .dims = {dims[0], dims[1], dims[2]}, .steps = steps, .window = 4,
        .axes = TVPAL_AXIS_Z, .nodes = 1, .node_first = 0, .node_count = 1,
        .table_format = TVPAL_TABLE_CHUNK};
    for (int a = 0; a < 3; a++)
        e->spacing[a] = 1;
    *out = e;
    return 0;
}

/* value is a whole number in [lo, hi]. */
static int whole_in(double value, double lo, double hi)
{
    return value >= lo && value <= hi && value == floor(value);
}

int tvpal_encoder_set(struct tvpal_encoder *e, enum tvpal_param param,
                      double value, struct tvpal_diag *diag)
{
    if (e->state != OPENED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "parameter %d set after "
                              "the first push", (int)param);
    struct tvpal_engine_params *p = &e->ep;
    const char *name = NULL, *range = NULL;
    switch (param) {
    case TVPAL_PARAM_WINDOW:
        if (!whole_in(value, 1, 16))
            name = "window", range = "1..16";
        else
            p->window = (uint32_t)value;
        break;
    case TVPAL_PARAM_AXES:
        if (!whole_in(value, 1, 7))
            name = "axes", range = "a mask of TVPAL_AXIS_X, _Y, _Z";
        else
            p->axes = (uint32_t)value;
        break;
    case TVPAL_PARAM_NODES:
        if (!whole_in(value, 1, 4096))
            name = "nodes", range = "1..4096";
        else
            p->nodes = p->node_count = (uint32_t)value;
        break;
    case TVPAL_PARAM_TABLE:
        if (value != TVPAL_TABLE_FLOAT32 && value != TVPAL_TABLE_UINT16 &&
            value != TVPAL_TABLE_AUTO)
            name = "table", range = "TVPAL_TABLE_FLOAT32, _UINT16 or _AUTO";
        else
            p->table_format = (uint32_t)value;
        break;
    case TVPAL_PARAM_REFINE:
        if (!whole_in(value, 0, 8))
            name = "refine", range = "0..8";
        else
            p->refine = (uint32_t)value;
        break;
    case TVPAL_PARAM_TRANSFORM:
        if (value != TVPAL_TRANSFORM_DCT && value != TVPAL_TRANSFORM_KLT)
            name = "transform", range = "TVPAL_TRANSFORM_DCT or _KLT";
        else
            p->klt = value == TVPAL_TRANSFORM_KLT;
        break;
    case TVPAL_PARAM_ALLOC:
        if (value != TVPAL_ALLOC_VARIANCE && value != TVPAL_ALLOC_GREEDY_MSE)
            name = "alloc", range = "TVPAL_ALLOC_VARIANCE or _GREEDY_MSE";
        else
            p->alloc_mse = value == TVPAL_ALLOC_GREEDY_MSE;
        break;
    case TVPAL_PARAM_THREADS:
        if (!whole_in(value, 0, 1024))
            name = "threads", range = "0..1024";
        else
            e->threads = (unsigned)value;
        break;
    case TVPAL_PARAM_MEM_LIMIT:
        if (!whole_in(value, 0, 0x1p62))
            name = "mem_limit", range = "bytes, 0 for none";
        else
            e->mem_limit = (uint64_t)value;
        break;
    case TVPAL_PARAM_NAN_AS:
        if (!(fabs(value) <= TVPAL_VALUE_MAX))
            name = "nan_as", range = "a finite value within 1e37";
        else
            e->has_nan_as = 1, e->nan_as = value;
        break;
    case TVPAL_PARAM_NAIVE:
        if (value != 0 && value != 1)
            name = "naive", range = "0 or 1";
        else
            p->naive = value == 1;
        break;
    case TVPAL_PARAM_FORCE:
        if (value != 0 && value != 1)
            name = "force", range = "0 or 1";
        else
            e->force = value == 1;
        break;
    default:
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "unknown parameter %d",
                              (int)param);
    }
    if (name)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s %.17g: %s expected",
                              name, value, range);
    return 0;
}

int tvpal_encoder_set_grid(struct tvpal_encoder *e, const double spacing[3],
                           const double origin[3], struct tvpal_diag *diag)
{
    if (e->state != OPENED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "grid set after the "
                              "first push");
    for (int a = 0; a < 3; a++)
        if (!(spacing[a] > 0) || !isfinite(spacing[a]))
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "spacing[%d] is "
                                  "%.17g: finite and > 0 expected", a,
                                  spacing[a]);
    int rc = tvpal_manifest_check_grid(spacing, origin, NULL, 0, diag);
    if (rc < 0)
        return rc;
    memcpy(e->spacing, spacing, sizeof e->spacing);
    memcpy(e->origin, origin, sizeof e->origin);
    return 0;
}

int tvpal_encoder_set_times(struct tvpal_encoder *e, const double *times,
                            const char *time_units, struct tvpal_diag *diag)
{
    const uint32_t T = e->ep.steps;
    if (e->state != OPENED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "times set after the "
                              "first push");
    if (!times)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "no times");
    for (uint32_t t = 1; t < T; t++)
        if (!(times[t] > times[t - 1]))
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "the time of step %u "
                                  "(%.17g) is not after step %u's (%.17g): "
                                  "times must increase", t, times[t], t - 1,
                                  times[t - 1]);
    const double s[3] = {1, 1, 1}, o[3] = {0, 0, 0};
    int rc = tvpal_manifest_check_grid(s, o, times, T, diag);
    if (rc < 0)
        return rc;
    if (time_units && (strlen(time_units) >= sizeof e->time_units ||
                       strpbrk(time_units, "\n\r")))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "time units: one line "
                              "of at most %zu bytes expected",
                              sizeof e->time_units - 1);
    double *copy = malloc(sizeof *copy * T);
    if (!copy)
        return TVPAL_E_NOMEM;
    memcpy(copy, times, sizeof *copy * T);
    free(e->times);
    e->times = copy;
    snprintf(e->time_units, sizeof e->time_units, "%s",
             time_units ? time_units : "");
    return 0;
}

int tvpal_encoder_set_units(struct tvpal_encoder *e, const char *units,
                            struct tvpal_diag *diag)
{
    if (e->state != OPENED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "units set after the "
                              "first push");
    if (units && (strlen(units) >= sizeof e->units ||
                  strpbrk(units, "\n\r")))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "units: one line of at "
                              "most %zu bytes expected",
                              sizeof e->units - 1);
    snprintf(e->units, sizeof e->units, "%s", units ? units : "");
    return 0;
}

int tvpal_encoder_set_missing(struct tvpal_encoder *e, const double *values,
                              unsigned n, struct tvpal_diag *diag)
{
    if (e->state != OPENED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "missing values set "
                              "after the first push");
    if (n > MISSING_MAX || (n && !values))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%u missing values: at "
                              "most %u expected", n, MISSING_MAX);
    for (unsigned i = 0; i < n; i++)
        if (!(fabs(values[i]) <= TVPAL_VALUE_MAX))
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "missing value %u is "
                                  "%.17g: finite within 1e37 expected", i,
                                  values[i]);
    memcpy(e->missing, values, n * sizeof *values);
    e->nmissing = n;
    return 0;
}

/* ---------------------------------------------------------------- start */

/* DIR may be replaced: absent, or with force a tvpal dataset. */
static int check_output(const struct tvpal_encoder *e,
                        struct tvpal_diag *diag)
{
    if (!tvpal_exists(e->dir))
        return 0;
    if (!e->force)
        return tvpal_diag_set(diag, TVPAL_E_EXIST, "%s: output already "
                              "exists (TVPAL_PARAM_FORCE replaces it)",
                              e->dir);
    char *mp = NULL;
    struct tvpal_manifest old;
    if (asprintf(&mp, "%s/manifest.txt", e->dir) < 0)
        return TVPAL_E_NOMEM;
    int rc = tvpal_manifest_load(mp, &old, NULL);
    free(mp);
    if (rc < 0)
        return tvpal_diag_set(diag, TVPAL_E_EXIST, "%s: exists and is not a "
                              "tvpal dataset (no valid manifest.txt); "
                              "refusing to replace it", e->dir);
    tvpal_manifest_clear(&old);
    return 0;
}

/* Bytes the job holds: the ring, the threads' workspaces, the tables. */
static uint64_t job_bytes(const struct tvpal_encoder *e, unsigned nthreads,
                          uint64_t nvox)
{
    const uint32_t T = e->ep.steps, N = e->ep.window;
    const uint64_t ring = (uint64_t)(T < N ? T : N) * nvox * sizeof(float);
    const uint64_t per_thread = tvpal_engine_thread_bytes(e->eng) +
                                TVPAL_CHECKPOINT_BINS * sizeof(uint64_t) +
                                (uint64_t)e->ep.dims[0] * 8;
    return ring + nthreads * per_thread + tvpal_engine_table_bytes(e->eng);
}

static int open_writers(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    uint32_t n;
    struct tvpal_engine_shard *sj = tvpal_engine_shards(e->eng, &n);
    for (uint32_t k = 0; k < e->ep.nodes; k++) {
        char *nd = tvpal_node_dir(e->partial, NULL, k);
        int rc = nd ? tvpal_mkdirs(nd, diag) : TVPAL_E_NOMEM;
        free(nd);
        if (rc < 0)
            return rc;
    }
    for (uint32_t q = 0; q < n; q++) {
        char *nd = tvpal_node_dir(e->partial, NULL, sj[q].rank), *path = NULL;
        int rc = nd && asprintf(&path, "%s/axis-%c.tvps", nd,
                                "xyz"[sj[q].axis]) >= 0
                     ? tvpal_shardw_create_placed(&sj[q].w, path, &sj[q].h,
                                                  diag)
                     : TVPAL_E_NOMEM;
        free(nd);
        free(path);
        if (rc < 0)
            return rc;
    }
    return 0;
}

/* The first push: the output checked and locked, the engine and its
 * workspaces, DIR.partial and the shard writers. */
static int start(struct tvpal_encoder *e, enum tvpal_type type,
                 struct tvpal_diag *diag)
{
    const uint32_t *d = e->ep.dims;
    const uint64_t nvox = (uint64_t)d[0] * d[1] * d[2];
    e->type = type;
    int rc = check_output(e, diag);
    if (rc < 0)
        return rc;
    if (asprintf(&e->lock_path, "%s.lock", e->partial) < 0)
        return TVPAL_E_NOMEM;
    if ((rc = tvpal_lock_take(e->lock_path, &e->lock_fd, diag)) < 0) {
        free(e->lock_path);
        e->lock_path = NULL;
        return rc;
    }
    if ((rc = tvpal_engine_create(&e->eng, &e->ep)) < 0)
        return tvpal_diag_set(diag, rc, "the encoding parameters");
    const unsigned nt = e->threads ? e->threads
                                   : tvpal_pool_default_threads();
    const uint64_t need = job_bytes(e, nt, nvox);
    if (e->mem_limit && need > e->mem_limit)
        return tvpal_diag_set(diag, TVPAL_E_RANGE, "%ux%ux%u at window %u "
                              "needs about %llu bytes (%u steps and the "
                              "workspaces of %u threads), over the memory "
                              "limit of %llu", d[0], d[1], d[2],
                              e->ep.window, (unsigned long long)need,
                              e->ep.window, nt,
                              (unsigned long long)e->mem_limit);
    if ((rc = tvpal_pool_create(&e->pool, nt)) < 0)
        return tvpal_diag_set(diag, rc, "cannot start %u threads", nt);
    if ((rc = tvpal_engine_start(e->eng, e->pool, nvox, diag)) < 0)
        return rc == TVPAL_E_INVAL
                   ? tvpal_diag_set(diag, rc, "TVPAL_TRANSFORM_KLT: built "
                                    "without LAPACK")
                   : rc;
    if ((rc = tvpal_checkpoint_stats_init(&e->st)) < 0)
        return rc;
    if (!(e->fine = calloc(nt, sizeof *e->fine)) ||
        !(e->found = calloc(nt, sizeof *e->found)) ||
        !(e->rows = calloc(nt, sizeof *e->rows)))
        return TVPAL_E_NOMEM;
    for (unsigned i = 0; i < nt; i++)
        if (!(e->fine[i] = calloc(TVPAL_CHECKPOINT_BINS, sizeof(uint64_t))) ||
            !(e->rows[i] = malloc((size_t)d[0] * 8)))
            return TVPAL_E_NOMEM;
    e->pass = (struct encode_pass){
        .box = {{0, 0, 0}, {d[0], d[1], d[2]}},
        .s0 = {0, 0, 0}, .s1 = {d[0], d[1], d[2]}, .axes = 7, .stats = 1};
    tvpal_engine_set_pass(e->eng, &e->pass);
    /* A partial output of an earlier job is not resumed (yet): it goes. */
    if (tvpal_exists(e->partial) && tvpal_rmtree(e->partial) < 0)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot remove the "
                              "partial output of an earlier job",
                              e->partial);
    return open_writers(e, diag);
}

/* ----------------------------------------------------------------- push */

/* One push's conversion, a plane per job on the pool. */
struct push_ctx {
    struct tvpal_encoder *e;
    const unsigned char *data;
    size_t esize;
    ptrdiff_t s[3];
    float *dst;
};

static void convert_plane(void *arg, size_t z, unsigned tid)
{
    const struct push_ctx *c = arg;
    struct tvpal_encoder *e = c->e;
    const uint32_t nx = e->ep.dims[0], ny = e->ep.dims[1];
    const struct tvpal_values_rules rules = {
        e->missing, e->nmissing, e->has_nan_as ? &e->nan_as : NULL};
#ifdef WORDS_BIGENDIAN
    const int host_big = 1;
#else
    const int host_big = 0;
#endif
    for (uint32_t y = 0; y < ny; y++) {
        const unsigned char *row =
            c->data + ((ptrdiff_t)y * c->s[1] + (ptrdiff_t)z * c->s[2]) *
                          (ptrdiff_t)c->esize;
        if (c->s[0] != 1) { /* gathered into the thread's row first */
            unsigned char *g = e->rows[tid];
            for (uint32_t x = 0; x < nx; x++)
                memcpy(g + (size_t)x * c->esize,
                       row + (ptrdiff_t)x * c->s[0] * (ptrdiff_t)c->esize,
                       c->esize);
            row = g;
        }
        const uint64_t v0 = (uint64_t)nx * (y + (uint64_t)ny * z);
        tvpal_values_convert(&rules, row, e->type, host_big, nx,
                             c->dst + v0, v0, e->fine[tid], &e->found[tid]);
    }
}

/* Converts the step at data into the ring and counts it; a refused value
 * is named by its voxel. */
static int take_step(struct tvpal_encoder *e, const void *data,
                     const ptrdiff_t *strides, struct tvpal_diag *diag)
{
    const uint32_t *d = e->ep.dims;
    const unsigned nt = tvpal_pool_threads(e->pool);
    struct push_ctx c = {
        .e = e, .data = data, .esize = tvpal_type_size(e->type),
        .s = {1, (ptrdiff_t)d[0], (ptrdiff_t)d[0] * d[1]},
        .dst = tvpal_engine_slot(e->eng, e->pushed)};
    if (strides)
        memcpy(c.s, strides, sizeof c.s);
    struct tvpal_found all = tvpal_found_empty(e->st.vmin, e->st.vmax);
    for (unsigned i = 0; i < nt; i++)
        e->found[i] = all;
    tvpal_pool_for(e->pool, d[2], convert_plane, &c);
    for (unsigned i = 0; i < nt; i++)
        tvpal_found_merge(&all, &e->found[i]);
    if (all.rc < 0) {
        const uint64_t x = all.bad % d[0], y = all.bad / d[0] % d[1],
                       z = all.bad / d[0] / d[1];
        return tvpal_diag_set(diag, all.rc, "step %u: %s at voxel "
                              "(%llu,%llu,%llu); finite values within 1e37 "
                              "expected, NaN for missing ones", e->pushed,
                              all.rc == TVPAL_E_NAN ? "an infinite value"
                                                    : "a value beyond 1e37",
                              (unsigned long long)x, (unsigned long long)y,
                              (unsigned long long)z);
    }
    tvpal_values_account(&e->st, e->fine, nt, &all,
                         (uint64_t)d[0] * d[1] * d[2]);
    e->st.loaded = ++e->pushed;
    return 0;
}

/* Encodes every step whose windows' steps are all in. */
static int encode_ready(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    const uint32_t T = e->ep.steps, N = e->ep.window;
    while (e->encoded < T &&
           (e->pushed == T || e->encoded + N <= e->pushed)) {
        uint32_t q = 0, n;
        struct tvpal_diag d = {{0}};
        int rc = tvpal_engine_encode_step(e->eng, e->encoded, &d, &q);
        if (rc < 0) {
            struct tvpal_engine_shard *sj = tvpal_engine_shards(e->eng, &n);
            char *nd = tvpal_node_dir(e->partial, NULL, sj[q].rank);
            rc = tvpal_diag_set(diag, rc, "%s/axis-%c.tvps: %s",
                                nd ? nd : e->partial, "xyz"[sj[q].axis],
                                d.msg);
            free(nd);
            return rc;
        }
        e->encoded++;
    }
    return 0;
}

int tvpal_encoder_push(struct tvpal_encoder *e, const void *data,
                       enum tvpal_scalar type, const ptrdiff_t strides[3],
                       struct tvpal_diag *diag)
{
    if (e->state == FAILED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "a push after a failed "
                              "one: only tvpal_encoder_abort is left");
    if (type != TVPAL_FLOAT32 && type != TVPAL_FLOAT64)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "type %d: TVPAL_FLOAT32 "
                              "or TVPAL_FLOAT64 expected", (int)type);
    if (!data)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "no data");
    if (e->pushed == e->ep.steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u pushed: the "
                              "encoder was opened for %u", e->pushed + 1,
                              e->ep.steps);
    const enum tvpal_type t = type == TVPAL_FLOAT32 ? TVPAL_F32 : TVPAL_F64;
    int rc = 0;
    if (e->state == OPENED) {
        e->state = STARTED;
        rc = start(e, t, diag);
    } else if (t != e->type) {
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u is %s, step 0 "
                              "was %s: one type for the series", e->pushed,
                              tvpal_type_name(t), tvpal_type_name(e->type));
    }
    if (rc == 0)
        rc = take_step(e, data, strides, diag);
    if (rc == 0)
        rc = encode_ready(e, diag);
    if (rc < 0)
        e->state = FAILED;
    return rc;
}

/* --------------------------------------------------------------- finish */

/* The manifest: the job's fields (tvpal_engine_manifest) and the grid;
 * source_format stays "" (raw): the values as host float32 or float64,
 * which tvpal-report --reference compares with raw files of them. */
static int build_manifest(const struct tvpal_encoder *e,
                          struct tvpal_manifest *m)
{
    const struct tvpal_engine_source src = {
        .type = e->type, .nan_as = e->has_nan_as ? &e->nan_as : NULL,
        .missing = e->missing, .nmissing = e->nmissing};
    int rc = tvpal_engine_manifest(&e->ep, &src, &e->st, e->times,
                                   e->time_units, e->units, LIB_NAME, m);
    memcpy(m->spacing, e->spacing, sizeof m->spacing);
    memcpy(m->origin, e->origin, sizeof m->origin);
    return rc;
}

static int write_manifest(const char *dir, const char *text,
                          struct tvpal_diag *diag)
{
    char *path = NULL;
    int rc = asprintf(&path, "%s/manifest.txt", dir) < 0
                 ? TVPAL_E_NOMEM
                 : tvpal_write_file_atomic(path, text, strlen(text), diag);
    free(path);
    return rc;
}

/* The shards finished, the manifest in DIR.partial and every node
 * directory. */
static int finish_partial(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    uint32_t n;
    struct tvpal_engine_shard *sj = tvpal_engine_shards(e->eng, &n);
    for (uint32_t q = 0; q < n; q++) {
        tvpal_shardw_set_range(sj[q].w, e->st.vmin, e->st.vmax);
        int rc = tvpal_shardw_finish(sj[q].w, diag);
        sj[q].w = NULL;
        if (rc < 0)
            return rc;
    }
    struct tvpal_manifest m;
    char *text = NULL;
    int rc = build_manifest(e, &m);
    if (rc == 0)
        rc = tvpal_manifest_format(&m, &text);
    tvpal_manifest_clear(&m);
    if (rc == 0)
        rc = write_manifest(e->partial, text, diag);
    for (uint32_t k = 0; rc == 0 && k < e->ep.nodes; k++) {
        char *nd = tvpal_node_dir(e->partial, NULL, k);
        rc = nd ? write_manifest(nd, text, diag) : TVPAL_E_NOMEM;
        free(nd);
    }
    free(text);
    if (rc == 0)
        tvpal_fsync_dir(e->partial);
    return rc;
}

/* DIR.partial read back as a dataset, then renamed to DIR; an older DIR
 * (force) goes to DIR.old first and is removed after. */
static int place(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    struct tvpal_dataset *ds = NULL;
    int rc = tvpal_dataset_open(&ds, e->partial, diag);
    tvpal_dataset_close(ds);
    if (rc < 0)
        return rc;
    char *old = NULL;
    if (asprintf(&old, "%s.old", e->dir) < 0)
        return TVPAL_E_NOMEM;
    const int had = tvpal_exists(e->dir);
    if (had && (tvpal_rmtree(old), rename(e->dir, old) < 0)) {
        free(old);
        return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot move aside",
                              e->dir);
    }
    if (rename(e->partial, e->dir) < 0) {
        if (had)
            rename(old, e->dir);
        free(old);
        return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot rename to %s",
                              e->partial, e->dir);
    }
    char *parent = strdup(e->dir), *slash = parent ? strrchr(parent, '/')
                                                   : NULL;
    if (slash)
        *slash = 0;
    tvpal_fsync_dir(slash ? (slash == parent ? "/" : parent) : ".");
    free(parent);
    if (had)
        tvpal_rmtree(old);
    free(old);
    return 0;
}

static void release(struct tvpal_encoder *e)
{
    const unsigned nt = e->pool ? tvpal_pool_threads(e->pool) : 0;
    tvpal_engine_free(e->eng);
    tvpal_pool_free(e->pool);
    for (unsigned i = 0; i < nt; i++) {
        if (e->fine)
            free(e->fine[i]);
        if (e->rows)
            free(e->rows[i]);
    }
    free(e->fine);
    free(e->rows);
    free(e->found);
    tvpal_checkpoint_stats_free(&e->st);
    if (e->lock_path)
        tvpal_lock_release(e->lock_path, e->lock_fd);
    free(e->lock_path);
    free(e->times);
    free(e->partial);
    free(e->dir);
    free(e);
}

int tvpal_encoder_finish(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    int rc = 0;
    if (e->state == FAILED)
        rc = tvpal_diag_set(diag, TVPAL_E_INVAL, "finish after a failed "
                            "push: nothing was written at %s", e->dir);
    else if (e->pushed < e->ep.steps)
        rc = tvpal_diag_set(diag, TVPAL_E_INVAL, "finish after %u of %u "
                            "steps: nothing was written at %s", e->pushed,
                            e->ep.steps, e->dir);
    if (rc == 0)
        rc = finish_partial(e, diag);
    if (rc == 0)
        rc = place(e, diag);
    if (rc < 0 && e->state != OPENED && e->lock_path)
        tvpal_rmtree(e->partial);
    release(e);
    return rc;
}

void tvpal_encoder_abort(struct tvpal_encoder *e)
{
    if (!e)
        return;
    if (e->state != OPENED && e->lock_path)
        tvpal_rmtree(e->partial);
    release(e);
}
