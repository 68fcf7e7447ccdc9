/* tvpal_encoder.c: the encoder of tvpal.h, timesteps from memory into a
 * dataset, in one pass.
 *
 * The steps pushed go, converted, into the engine's ring of L whole
 * volumes (tvpal_engine.h; L the longest window, tvpal_engine_span: 2N - 1
 * in the joined schedule, N staggered); once step p is in, every
 * slice-window that starts at p - L + 1 has its steps and is encoded, so
 * the encoder holds L steps and its workspaces whatever T is.  The shards
 * are written in place under DIR.partial as they are coded, the manifest
 * at the end, and the dataset is read back before DIR.partial becomes DIR
 * (the order of tvpal-encode: no file at DIR looks complete before it
 * is).  The shards are those tvpal-encode writes from the same values in
 * files.
 */
#define _GNU_SOURCE
#include "tvpal_encoder_impl.h"
#include "tvpal_chunkz.h"

#include "tvpal_checkpoint.h"
#include "tvpal_dataset.h"
#include "tvpal_engine.h"
#include "tvpal_fs.h"
#include "tvpal_levels.h"
#include "tvpal_manifest.h"
#include "tvpal_output.h"
#include "tvpal_raw.h"
#include "tvpal_size.h"
#include "tvpal_values.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <errno.h>
#include <string.h>

/* One process: its gather is a copy, its broadcast nothing. */
static int self_gather(void *ctx, const void *send, size_t bytes, void *recv)
{
    (void)ctx;
    memcpy(recv, send, bytes);
    return 0;
}

static int self_bcast(void *ctx, void *buf, size_t bytes)
{
    (void)ctx, (void)buf, (void)bytes;
    return 0;
}

/* Rank 0's buffers for size ranks' votes and histogram pieces. */
static int alloc_round_buffers(struct tvpal_encoder *e, int size)
{
    free(e->votes);
    free(e->pieces);
    e->votes = calloc((size_t)size, sizeof *e->votes);
    e->pieces = calloc((size_t)size * HIST_PIECE, sizeof *e->pieces);
    return e->votes && e->pieces ? 0 : TVPAL_E_NOMEM;
}

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
        .table_format = TVPAL_TABLE_CHUNK, .index_level = TVPAL_CHUNKZ_LEVEL,
        .schedule = TVPAL_SCHEDULE_JOINED};
    for (int a = 0; a < 3; a++)
        e->spacing[a] = 1;
    e->coll = (struct tvpal_collective){0, 1, NULL, self_gather, self_bcast,
                                        NULL};
    e->slab_n = dims[2];
    e->round = R_START;
    e->ckpt_every = 1;
    e->tick_seconds = 0.2;
    if (alloc_round_buffers(e, 1) < 0) {
        free(e->votes);
        free(e->partial);
        free(e->dir);
        free(e);
        return TVPAL_E_NOMEM;
    }
    *out = e;
    return 0;
}

void tvpal_slab(uint32_t nz, uint32_t size, uint32_t rank, uint32_t *z0,
                uint32_t *count)
{
    if (size < 1 || rank >= size) {
        *z0 = *count = 0;
        return;
    }
    tvpal_slab_range(nz, size, rank, z0, count);
}

int tvpal_encoder_set_collective(struct tvpal_encoder *e,
                                 const struct tvpal_collective *c,
                                 uint32_t z0, uint32_t nz,
                                 struct tvpal_diag *diag)
{
    int rc = 0;
    if (e->state != OPENED)
        rc = tvpal_diag_set(diag, TVPAL_E_INVAL, "collective set after "
                            "the first push");
    else if (!c->gather || !c->bcast)
        rc = tvpal_diag_set(diag, TVPAL_E_INVAL, "a collective needs its "
                            "gather and bcast");
    else if (c->size < 1 || c->size > 4096 || c->rank < 0 ||
             c->rank >= c->size)
        rc = tvpal_diag_set(diag, TVPAL_E_INVAL, "rank %d of %d: 0 .. size "
                            "- 1 of 1 .. 4096 ranks expected", c->rank,
                            c->size);
    else if (c->rank == 0 && alloc_round_buffers(e, c->size) < 0)
        rc = TVPAL_E_NOMEM;
    if (rc < 0) {
        if (c->release)
            c->release(c->ctx);
        return rc;
    }
    if (e->coll.release)
        e->coll.release(e->coll.ctx);
    e->coll = *c;
    e->ep.nodes = (uint32_t)c->size;
    e->ep.node_first = (uint32_t)c->rank;
    e->ep.node_count = 1;
    uint32_t want0, wantn;
    tvpal_slab(e->ep.dims[2], (uint32_t)c->size, (uint32_t)c->rank, &want0,
               &wantn);
    e->slab_z0 = want0;
    e->slab_n = wantn;
    e->own_rc = 0;
    struct tvpal_diag d = {{0}};
    if (z0 != want0 || nz != wantn)
        e->own_rc = tvpal_diag_set(&d, TVPAL_E_INVAL, "rank %d of %d "
                                    "pushes planes %u .. %u, not its slab "
                                    "of the %u planes, %u .. %u "
                                    "(tvpal_slab)", c->rank, c->size, z0,
                                    z0 + nz - 1, e->ep.dims[2], want0,
                                    want0 + wantn - 1);
    else if (wantn == 0)
        e->own_rc = tvpal_diag_set(&d, TVPAL_E_INVAL, "%d ranks for %u "
                                    "planes: every rank needs at least "
                                    "one", c->size, e->ep.dims[2]);
    if (!e->own_rc)
        return 0;
    /* Kept as the rank's collective all the same: its first push or its
     * abort tells the other ranks, which would otherwise wait. */
    memcpy(e->own_msg, d.msg, sizeof d.msg);
    if (diag)
        *diag = d;
    return e->own_rc;
}

/* value is a whole number in [lo, hi]. */
static int whole_in(double value, double lo, double hi)
{
    return value >= lo && value <= hi && value == floor(value);
}

/* TVPAL_PARAM_INDEX_CODING and _INDEX_LEVEL: the level is remembered
 * (e->index_level) while coding is off, so that the two may be set in
 * either order; ep.index_level is 0 without coding.  A value out of range
 * sets *name and *range for the caller's message. */
static void set_index_coding(struct tvpal_encoder *e, enum tvpal_param param,
                             double value, const char **name,
                             const char **range)
{
    struct tvpal_engine_params *p = &e->ep;
    if (param == TVPAL_PARAM_INDEX_CODING) {
        if (value != TVPAL_CODING_NONE && value != TVPAL_CODING_ZSTD)
            *name = "index_coding", *range = "TVPAL_CODING_NONE or _ZSTD";
        else
            p->index_level = value == TVPAL_CODING_NONE ? 0
                           : e->index_level ? e->index_level
                                            : TVPAL_CHUNKZ_LEVEL;
    } else if (!whole_in(value, 1, 19)) {
        *name = "index_level", *range = "1..19";
    } else {
        e->index_level = (int)value;
        if (p->index_level)
            p->index_level = (int)value;
    }
}

/* The coder's two-way choices: TVPAL_PARAM_TRANSFORM, _ALLOC, _NAIVE and
 * _SCHEDULE.  A value that is neither sets *name and *range for the
 * caller's message. */
static void set_coder_choice(struct tvpal_engine_params *p,
                             enum tvpal_param param, double value,
                             const char **name, const char **range)
{
    switch (param) {
    case TVPAL_PARAM_TRANSFORM:
        if (value != TVPAL_TRANSFORM_DCT && value != TVPAL_TRANSFORM_KLT)
            *name = "transform", *range = "TVPAL_TRANSFORM_DCT or _KLT";
        else
            p->klt = value == TVPAL_TRANSFORM_KLT;
        break;
    case TVPAL_PARAM_ALLOC:
        if (value != TVPAL_ALLOC_VARIANCE && value != TVPAL_ALLOC_GREEDY_MSE)
            *name = "alloc", *range = "TVPAL_ALLOC_VARIANCE or _GREEDY_MSE";
        else
            p->alloc_mse = value == TVPAL_ALLOC_GREEDY_MSE;
        break;
    case TVPAL_PARAM_NAIVE:
        if (value != 0 && value != 1)
            *name = "naive", *range = "0 or 1";
        else
            p->naive = value == 1;
        break;
    default: /* TVPAL_PARAM_SCHEDULE */
        if (value != TVPAL_SCHEDULE_STAGGERED &&
            value != TVPAL_SCHEDULE_JOINED)
            *name = "schedule", *range = "TVPAL_SCHEDULE_STAGGERED or _JOINED";
        else
            p->schedule = (uint32_t)value;
        break;
    }
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
        else if (e->coll.size > 1 && value != e->coll.size)
            name = "nodes", range = "the collective's size (one node "
                                    "shard per rank)";
        else if (e->coll.size == 1)
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
        if (!whole_in(value, 0, TVPAL_ENGINE_REFINE_MAX))
            name = "refine", range = "0..64";
        else
            p->refine = (uint32_t)value;
        break;
    case TVPAL_PARAM_TRANSFORM:
    case TVPAL_PARAM_ALLOC:
    case TVPAL_PARAM_NAIVE:
    case TVPAL_PARAM_SCHEDULE:
        set_coder_choice(p, param, value, &name, &range);
        break;
    case TVPAL_PARAM_GROUP:
        if (!whole_in(value, TVPAL_GROUP_AUTO, TVPAL_GROUP_MAX))
            name = "group", range = "0 (auto)..1024";
        else {
            p->group = (uint32_t)value;
            p->group_auto = value == TVPAL_GROUP_AUTO;
        }
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
    case TVPAL_PARAM_FORCE:
        if (value != 0 && value != 1)
            name = "force", range = "0 or 1";
        else
            e->force = value == 1;
        break;
    case TVPAL_PARAM_LEVELS:
        if (!whole_in(value, 0, TVPAL_LEVELS_MAX))
            name = "levels", range = "0..8";
        else
            e->levels = (uint32_t)value;
        break;
    case TVPAL_PARAM_PROGRESS:
        if (!(value >= 0.001 && value <= 3600))
            name = "progress", range = "0.001..3600 seconds";
        else
            e->tick_seconds = value;
        break;
    case TVPAL_PARAM_INDEX_CODING:
    case TVPAL_PARAM_INDEX_LEVEL:
        set_index_coding(e, param, value, &name, &range);
        break;
    case TVPAL_PARAM_CHECKPOINT:
        if (!whole_in(value, 0, UINT32_MAX))
            name = "checkpoint", range = "steps between checkpoints, 0 for "
                                         "none";
        else
            e->ckpt_every = (uint32_t)value;
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

/* A string the manifest can hold on one line. */
static int one_line(const char *s, size_t cap)
{
    return !s || (strlen(s) < cap && !strpbrk(s, "\n\r"));
}

static void free_provenance(struct tvpal_encoder *e)
{
    for (uint32_t i = 0; i < e->prov_nsources; i++)
        free(e->prov_sources[i]);
    free(e->prov_sources);
    free(e->prov_var);
    e->prov_sources = NULL;
    e->prov_var = NULL;
    e->prov_nsources = 0;
}

/* Whether p's sources fit T steps: one file (of every step, or of one),
 * one per step, or a series of files of several steps each. */
static int sources_fit(const struct tvpal_provenance *p, uint32_t T)
{
    if (p->nsources == 0)
        return !p->single_file && !p->series;
    if (p->single_file)
        return p->nsources == 1 && !p->series;
    if (p->series)
        return p->nsources > 1 && p->nsources < T;
    return p->nsources == T;
}

int tvpal_encoder_set_provenance(struct tvpal_encoder *e,
                                 const struct tvpal_provenance *p,
                                 struct tvpal_diag *diag)
{
    static const char *const formats[] = {"raw", "netcdf", "hdf5", "vti",
                                          "vtk"};
    if (e->state != OPENED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "provenance set after "
                              "the first push");
    int known = !p->format;
    for (size_t i = 0; p->format && i < sizeof formats / sizeof *formats; i++)
        known |= !strcmp(p->format, formats[i]);
    if (!known)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "format \"%s\": raw, "
                              "netcdf, hdf5, vti or vtk expected", p->format);
    if (!one_line(p->encoder, sizeof e->prov_encoder) ||
        !one_line(p->var, 4096))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "encoder or var: one "
                              "line expected");
    if ((p->nsources && !p->sources) || !sources_fit(p, e->ep.steps))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%u sources%s for %u "
                              "steps: one file of every step, one per step "
                              "or a series of fewer expected", p->nsources,
                              p->single_file ? " (single file)"
                              : p->series ? " (series)" : "", e->ep.steps);
    for (uint32_t i = 0; i < p->nsources; i++)
        if (!p->sources[i] || !*p->sources[i] || !one_line(p->sources[i], 4096))
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "source %u: a path "
                                  "of one line expected", i);
    free_provenance(e);
    if ((p->var && !(e->prov_var = strdup(p->var))) ||
        (p->nsources &&
         !(e->prov_sources = calloc(p->nsources, sizeof *e->prov_sources))))
        return TVPAL_E_NOMEM;
    for (uint32_t i = 0; i < p->nsources; i++, e->prov_nsources++)
        if (!(e->prov_sources[i] = strdup(p->sources[i])))
            return TVPAL_E_NOMEM;
    snprintf(e->prov_encoder, sizeof e->prov_encoder, "%s",
             p->encoder ? p->encoder : "");
    snprintf(e->prov_format, sizeof e->prov_format, "%s",
             p->format ? p->format : "");
    e->prov_single_file = p->single_file;
    e->prov_series = p->series;
    return 0;
}

/* Node k's directory while the job runs: DIR.partial/node-k, or with
 * tvpal_encoder_set_shard_dir the pattern's directory plus ".partial"
 * (malloc'ed; NULL out of memory). */
char *tvpal_enc_node_dir(const struct tvpal_encoder *e, uint32_t k)
{
    char *d = tvpal_node_dir(e->partial, e->shard_pat, k), *p = NULL;
    if (!d || !e->shard_pat)
        return d;
    int n = asprintf(&p, "%s.partial", d);
    free(d);
    return n < 0 ? NULL : p;
}

int tvpal_encoder_set_shard_dir(struct tvpal_encoder *e, const char *pattern,
                                struct tvpal_diag *diag)
{
    if (e->state != OPENED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "shard directory set "
                              "after the first push");
    if (!pattern || !strstr(pattern, "%r") || strchr(pattern, '\n'))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "shard directory \"%s\": "
                              "a path of one line with %%r (the rank) "
                              "expected", pattern ? pattern : "(null)");
    char *p = strdup(pattern);
    if (!p)
        return TVPAL_E_NOMEM;
    free(e->shard_pat);
    e->shard_pat = p;
    return 0;
}

/* --------------------------------------------------------------- rounds */

static int is_root(const struct tvpal_encoder *e)
{
    return e->coll.rank == 0;
}

/* Rank 0 sends v to every rank; a failed send is this rank's failure. */
static int tell(struct tvpal_encoder *e, struct verdict *v)
{
    if (e->coll.bcast(e->coll.ctx, v, sizeof *v) != 0) {
        v->code = TVPAL_E_SYS;
        snprintf(v->msg, sizeof v->msg, "rank %d: the collective's bcast "
                 "failed", e->coll.rank);
    }
    if (v->code < 0) {
        e->decided = 1;
        e->decided_code = v->code;
    }
    return v->code;
}

/* Round `round`: every rank sends its code (and message, and statistics)
 * to rank 0, which decides: the failure of the lowest failing rank, its
 * message "rank R: ..." where there are several ranks.  The verdict (the
 * statistics summed) is every rank's; its code is returned. */
static int agree(struct tvpal_encoder *e, enum round round, int rc,
                 const char *msg, struct verdict *v)
{
    const struct tvpal_checkpoint_stats *st = &e->st;
    struct vote me = {.round = (int32_t)round, .code = rc,
                      .done = e->done_local, .levels = e->levels,
                      .kept = e->level0_finished,
                      .vmin = st->vmin, .vmax = st->vmax,
                      .nonfinite = st->nonfinite, .missing = st->missing,
                      .counted = st->counted};
    snprintf(me.msg, sizeof me.msg, "%s", msg ? msg : "");
    memset(v, 0, sizeof *v);
    e->round = round + 1;
    if (e->coll.gather(e->coll.ctx, &me, sizeof me,
                       is_root(e) ? e->votes : NULL) != 0) {
        v->code = TVPAL_E_SYS;
        snprintf(v->msg, sizeof v->msg, "rank %d: the collective's gather "
                 "failed", e->coll.rank);
        e->decided = 1;
        return v->code;
    }
    if (is_root(e)) {
        v->vmin = INFINITY, v->vmax = -INFINITY;
        v->done = e->votes[0].done;
        for (int k = 0; k < e->coll.size; k++) {
            const struct vote *o = &e->votes[k];
            if (o->done < v->done)
                v->done = o->done; /* the caller's first step: the
                                    * earliest any rank needs */
            const int other_levels = round == R_START &&
                                     o->levels != e->levels;
            const int other_kept = round == R_SETUP &&
                                   o->kept != e->votes[0].kept;
            if (v->code == 0 && (o->code < 0 ||
                                 o->round != (int32_t)round ||
                                 other_levels || other_kept)) {
                v->code = o->code < 0 ? o->code : TVPAL_E_INVAL;
                if (e->coll.size == 1)
                    snprintf(v->msg, sizeof v->msg, "%s", o->msg);
                else if (o->code < 0)
                    snprintf(v->msg, sizeof v->msg, "rank %d: %.1000s", k, o->msg);
                else if (o->round != (int32_t)round)
                    snprintf(v->msg, sizeof v->msg, "rank %d is in round %d "
                             "of the encode, rank 0 in round %d", k,
                             (int)o->round, (int)round);
                else if (other_levels)
                    snprintf(v->msg, sizeof v->msg, "rank %d has levels %u, "
                             "rank 0 %u: the same on every rank expected",
                             k, o->levels, e->levels);
                else
                    snprintf(v->msg, sizeof v->msg, "rank %d %s level 0 of "
                             "an earlier encode in %s, rank 0 %s: a file "
                             "system every rank sees expected", k,
                             o->kept ? "finds" : "does not find", e->partial,
                             o->kept ? "does not" : "does");
            }
            v->vmin = o->vmin < v->vmin ? o->vmin : v->vmin;
            v->vmax = o->vmax > v->vmax ? o->vmax : v->vmax;
            v->nonfinite += o->nonfinite;
            v->missing += o->missing;
            v->counted += o->counted;
        }
    }
    return tell(e, v);
}

/* The verdict's failure (or rc, a local one) into diag. */
static int report(int rc, const struct verdict *v, struct tvpal_diag *diag)
{
    if (rc < 0 && v->code == 0)
        return rc;
    return v->code < 0 ? tvpal_diag_set(diag, v->code, "%s", v->msg) : 0;
}

/* Rank 0 sums every rank's fine histogram into its own, HIST_PIECE bins
 * at a time. */
static int sum_histograms(struct tvpal_encoder *e)
{
    const size_t K = (size_t)e->coll.size;
    for (uint32_t b0 = 0; b0 < TVPAL_CHECKPOINT_BINS; b0 += HIST_PIECE) {
        uint64_t *mine = e->st.fine + b0;
        if (e->coll.gather(e->coll.ctx, mine, HIST_PIECE * sizeof *mine,
                           is_root(e) ? e->pieces : NULL) != 0)
            return TVPAL_E_SYS;
        for (uint32_t b = 0; is_root(e) && b < HIST_PIECE; b++) {
            uint64_t sum = 0;
            for (size_t k = 0; k < K; k++)
                sum += e->pieces[k * HIST_PIECE + b];
            mine[b] = sum;
        }
    }
    return 0;
}
_Static_assert(TVPAL_CHECKPOINT_BINS % HIST_PIECE == 0,
               "the histogram goes in whole pieces");

/* ---------------------------------------------------------------- start */

/* Bytes of a rank's part of level 1 at each step, with levels and a
 * collective ("levels of a collective" below). */
static size_t x_bytes(const struct tvpal_encoder *e);

/* What this rank can refuse before anything is made. */
static int check_job(const struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    if (e->own_rc)
        return tvpal_diag_set(diag, e->own_rc, "%s", e->own_msg);
    if (e->coll.size > 1 && e->ep.axes != TVPAL_AXIS_Z && !e->src)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "axes mask %u with %d "
                              "ranks pushing: only TVPAL_AXIS_Z (the x and "
                              "y slices cross the ranks' slabs; an encode "
                              "from a source reads them)", e->ep.axes,
                              e->coll.size);
    if (e->shard_pat && e->coll.size < 2)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "a shard directory "
                              "without a collective: for ranks on machines "
                              "of their own (one process writes "
                              "DIR/node-R)");
    if (!e->src && tvpal_engine_groups_unmeasured(&e->ep))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "TVPAL_PARAM_GROUP "
                              "TVPAL_GROUP_AUTO with pushes: the groups are "
                              "measured before the first window is written, "
                              "which only an encode from a source "
                              "(tvpal_encoder_encode) can read ahead");
    if (e->coll.size > 1 && e->ep.nodes != (uint32_t)e->coll.size)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "nodes %u with %d ranks: "
                              "one node shard per rank", e->ep.nodes,
                              e->coll.size);
    return 0;
}

/* Rank 0: the output checked and locked, an earlier partial output gone,
 * DIR.partial made. */
static int prepare_output(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    int rc = tvpal_output_check(e->dir, e->force, "TVPAL_PARAM_FORCE would",
                                diag);
    if (rc < 0)
        return rc;
    if (asprintf(&e->lock_path, "%s.lock", e->partial) < 0)
        return TVPAL_E_NOMEM;
    if ((rc = tvpal_lock_take(e->lock_path, &e->lock_fd, diag)) < 0) {
        free(e->lock_path);
        e->lock_path = NULL;
        return rc;
    }
    e->had_partial = tvpal_exists(e->partial);
    /* A partial output of an earlier job goes, unless it is resumed (its
     * checkpoints say whether it is this job's). */
    if (!e->resuming && tvpal_exists(e->partial) &&
        tvpal_rmtree(e->partial) < 0)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot remove the "
                              "partial output of an earlier job",
                              e->partial);
    if ((rc = tvpal_mkdirs(e->partial, diag)) < 0)
        return rc;
    e->made_partial = 1;
    return 0;
}

/* Bytes the job holds: the ring, the threads' workspaces, the tables. */
static uint64_t job_bytes(const struct tvpal_encoder *e, unsigned nthreads,
                          uint64_t nvox)
{
    const uint64_t span = tvpal_engine_span(&e->ep);
    const uint64_t ring = span * nvox * sizeof(float);
    const uint64_t per_thread = tvpal_engine_thread_bytes(e->eng) +
                                TVPAL_CHECKPOINT_BINS * sizeof(uint64_t) +
                                (uint64_t)e->ep.dims[0] * 8;
    /* Each level's volume and its encoder's ring, rank 0's; with a
     * collective every rank's part of level 1, and rank 0 every rank's. */
    uint64_t levels = e->xbytes * (is_root(e) ? (uint64_t)e->coll.size + 1
                                              : 1);
    for (uint32_t k = 1; is_root(e) && k <= e->levels; k++) {
        uint32_t dk[3];
        tvpal_level_dims(e->ep.dims, k, dk);
        levels += (span + 1) * dk[0] * dk[1] * dk[2] * sizeof(float);
    }
    return ring + levels + nthreads * per_thread +
           tvpal_engine_table_bytes(e->eng);
}

/* This rank's node directories and shard writers: resumed at the
 * checkpoint's progress when done > 0, else new (an older checkpoint
 * removed first, so that it cannot outlive the files it described). */
static int open_writers(struct tvpal_encoder *e, uint64_t done,
                        struct tvpal_diag *diag)
{
    uint32_t n;
    struct tvpal_engine_shard *sj = tvpal_engine_shards(e->eng, &n);
    for (uint32_t k = 0; k < e->ep.node_count; k++) {
        char *nd = tvpal_enc_node_dir(e, e->ep.node_first + k);
        int rc = nd ? tvpal_mkdirs(nd, diag) : TVPAL_E_NOMEM;
        free(nd);
        if (rc < 0)
            return rc;
    }
    if (!done && tvpal_checkpoint_remove(e->ckdir, diag) < 0)
        return TVPAL_E_SYS;
    for (uint32_t q = 0; q < n; q++) {
        char *nd = tvpal_enc_node_dir(e, sj[q].rank), *path = NULL;
        int rc = TVPAL_E_NOMEM;
        if (nd && asprintf(&path, "%s/axis-%c.tvps", nd,
                           "xyz"[sj[q].axis]) >= 0)
            rc = done ? tvpal_shardw_reopen_placed(&sj[q].w, path, &sj[q].h,
                                                   diag)
                      : tvpal_shardw_create_placed(&sj[q].w, path, &sj[q].h,
                                                   diag);
        if (rc == 0)
            tvpal_shardw_set_coding(sj[q].w, e->ep.index_level != 0);
        if (rc == 0 && done)
            rc = tvpal_engine_progress_restore(e->eng, q, &e->ckp, diag);
        if (rc < 0 && done && path) {
            /* diag has the shard's own words; say which file. */
            char why[TVPAL_DIAG_MAX];
            snprintf(why, sizeof why, "%s", diag ? diag->msg : "");
            rc = tvpal_diag_set(diag, rc, "%s: cannot resume: %s (abort "
                                "and encode again from step 0)", path, why);
        }
        free(nd);
        free(path);
        if (rc < 0)
            return rc;
    }
    return 0;
}

void tvpal_enc_groups_said(const struct tvpal_engine_params *p, char *opts,
                           size_t cap)
{
    const size_t n = strlen(opts);
    if (p->group_auto && n < cap)
        snprintf(opts + n, cap - n, " groups=%u,%u,%u", p->group_axis[0],
                 p->group_axis[1], p->group_axis[2]);
}

/* The job's identity in its checkpoints: the options that make its shards
 * (the schedule said outright: the options line names only staggered, and
 * a partial output of the other schedule must start over), and the rank. */
static int make_fingerprint(struct tvpal_encoder *e)
{
    const struct tvpal_engine_source src = {
        .type = e->type, .nan_as = e->has_nan_as ? &e->nan_as : NULL,
        .missing = e->missing, .nmissing = e->nmissing};
    char opts[1100], params[1300];
    tvpal_engine_options_line(&e->ep, &src, opts, sizeof opts - 64);
    tvpal_enc_groups_said(&e->ep, opts, sizeof opts);
    snprintf(params, sizeof params, "libtvpal %s schedule=%u rank=%d/%d",
             opts, e->ep.schedule, e->coll.rank, e->coll.size);
    return tvpal_checkpoint_fingerprint(params, NULL, 0, 0, &e->fp);
}

/* Resuming: the steps this rank's checkpoint has done (0: none that is
 * this job's and consistent), its statistics and its shards' progress. */
static uint64_t load_checkpoint(struct tvpal_encoder *e)
{
    const uint64_t slab = (uint64_t)e->ep.dims[0] * e->ep.dims[1] * e->slab_n;
    uint64_t done = 0;
    if (tvpal_checkpoint_load(e->ckdir, e->fp, e->ep.steps, e->ep.steps,
                              slab, &done, &e->st, &e->ckp, NULL) < 0 ||
        e->st.counted != (uint64_t)e->st.loaded * slab ||
        e->st.loaded < done) {
        tvpal_checkpoint_stats_reset(&e->st);
        return 0;
    }
    return done;
}

/* This rank's engine, threads and workspaces, and its shard writers. */
static int setup(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    const uint32_t *d = e->ep.dims;
    const uint64_t nvox = (uint64_t)d[0] * d[1] * e->slab_n;
    int rc;
    if ((rc = tvpal_engine_create(&e->eng, &e->ep)) < 0)
        return tvpal_diag_set(diag, rc, "the encoding parameters");
    if (e->levels && e->coll.size > 1 && !e->src)
        e->xbytes = x_bytes(e);
    const unsigned nt = e->threads ? e->threads
                                   : tvpal_pool_default_threads();
    uint64_t ring_voxels = nvox;
    const uint64_t need = e->src ? 0 : job_bytes(e, nt, nvox);
    if (e->src && (rc = tvpal_enc_source_plan(e, nt, &ring_voxels,
                                              diag)) < 0)
        return rc;
    if (e->mem_limit && need > e->mem_limit)
        return tvpal_diag_set(diag, TVPAL_E_RANGE, "%ux%ux%u at window %u "
                              "needs about %llu bytes (%u steps and the "
                              "workspaces of %u threads), over the memory "
                              "limit of %llu", d[0], d[1], e->slab_n,
                              e->ep.window, (unsigned long long)need,
                              tvpal_engine_span(&e->ep), nt,
                              (unsigned long long)e->mem_limit);
    if ((rc = tvpal_pool_create(&e->pool, nt)) < 0)
        return tvpal_diag_set(diag, rc, "cannot start %u threads", nt);
    if ((rc = tvpal_engine_start(e->eng, e->pool, ring_voxels, diag)) < 0)
        return rc == TVPAL_E_INVAL
                   ? tvpal_diag_set(diag, rc, "TVPAL_TRANSFORM_KLT: built "
                                    "without LAPACK")
                   : rc;
    if (!(e->fine = calloc(nt, sizeof *e->fine)) ||
        !(e->found = calloc(nt, sizeof *e->found)) ||
        !(e->rows = calloc(nt, sizeof *e->rows)))
        return TVPAL_E_NOMEM;
    for (unsigned i = 0; i < nt; i++)
        if (!(e->fine[i] = calloc(TVPAL_CHECKPOINT_BINS, sizeof(uint64_t))) ||
            (!e->src && !(e->rows[i] = malloc((size_t)d[0] * 8))))
            return TVPAL_E_NOMEM;
    if (e->xbytes &&
        (!(e->xbuf = calloc(1, e->xbytes)) ||
         (is_root(e) && !(e->xall = calloc((size_t)e->coll.size,
                                           e->xbytes)))))
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "the levels' exchange: "
                              "%zu bytes per rank", e->xbytes);
    e->ckdir = e->coll.size > 1
                   ? tvpal_enc_node_dir(e, e->ep.node_first)
                   : strdup(e->partial);
    if (!e->ckdir)
        return TVPAL_E_NOMEM;
    if (e->src) /* its passes, fingerprint and checkpoint */
        return tvpal_enc_source_ready(e, diag);
    /* One pass over this rank's slab: every axis for one process, z of
     * the slab for a rank (x and y are refused then). */
    const uint32_t z0 = e->slab_z0, z1 = e->slab_z0 + e->slab_n;
    e->pass = (struct encode_pass){
        .box = {{0, 0, z0}, {d[0], d[1], e->slab_n}},
        .s0 = {0, 0, z0}, .s1 = {d[0], d[1], z1}, .axes = 7, .stats = 1};
    tvpal_engine_set_pass(e->eng, &e->pass);
    if (make_fingerprint(e) < 0 ||
        tvpal_engine_progress_alloc(e->eng, &e->ckp) < 0)
        return TVPAL_E_NOMEM;
    if (e->resuming)
        e->done_local = load_checkpoint(e);
    return 0;
}

/* Level k's encoder: level 0's parameters, the grid over the same box,
 * the times and units; resumed when level 0 is (resume), where its
 * checkpoint must be at least level 0's (done).  A pulled encode's levels
 * save their checkpoints with level 0's (tvpal_encoder_source.c). */
int tvpal_enc_open_level(struct tvpal_encoder *e, uint32_t k, int resume,
                         uint64_t done, struct tvpal_diag *diag)
{
    uint32_t *dk = e->ldims[k];
    tvpal_level_dims(e->ep.dims, k, dk);
    char *dir = NULL;
    if (asprintf(&dir, "%s/level-%u", e->partial, k) < 0)
        return TVPAL_E_NOMEM;
    struct tvpal_encoder *c = NULL;
    int rc = tvpal_encoder_open(&c, dir, dk, e->ep.steps, diag);
    free(dir);
    if (rc < 0)
        return rc;
    e->lv[k] = c;
    const struct tvpal_engine_params *p = &e->ep;
    const struct { enum tvpal_param p; double v; } set[] = {
        {TVPAL_PARAM_WINDOW, p->window}, {TVPAL_PARAM_NODES, p->nodes},
        {TVPAL_PARAM_SCHEDULE, p->schedule},
        {TVPAL_PARAM_GROUP, p->group_auto ? 1 : p->group ? p->group : 1},
        {TVPAL_PARAM_AXES, p->axes}, {TVPAL_PARAM_THREADS, e->threads},
        {TVPAL_PARAM_TABLE, p->table_format}, {TVPAL_PARAM_REFINE, p->refine},
        {TVPAL_PARAM_INDEX_LEVEL, p->index_level ? p->index_level
                                                 : TVPAL_CHUNKZ_LEVEL},
        {TVPAL_PARAM_INDEX_CODING, p->index_level ? TVPAL_CODING_ZSTD
                                                  : TVPAL_CODING_NONE},
        {TVPAL_PARAM_NAIVE, p->naive},
        {TVPAL_PARAM_TRANSFORM, p->klt ? TVPAL_TRANSFORM_KLT
                                       : TVPAL_TRANSFORM_DCT},
        {TVPAL_PARAM_ALLOC, p->alloc_mse ? TVPAL_ALLOC_GREEDY_MSE
                                         : TVPAL_ALLOC_VARIANCE},
        {TVPAL_PARAM_CHECKPOINT, e->src ? 0 : e->ckpt_every},
        /* an older level-k (of an earlier job in DIR.partial) goes */
        {TVPAL_PARAM_FORCE, 1}};
    for (size_t i = 0; rc == 0 && i < sizeof set / sizeof *set; i++)
        rc = tvpal_encoder_set(c, set[i].p, set[i].v, diag);
    if (p->group_auto) { /* level 0's measured groups, per axis */
        c->ep.group_auto = 1;
        memcpy(c->ep.group_axis, p->group_axis, sizeof p->group_axis);
    }
    double sk[3], ok[3];
    tvpal_level_grid(e->spacing, e->origin, e->ep.dims, dk, sk, ok);
    if (rc == 0)
        rc = tvpal_encoder_set_grid(c, sk, ok, diag);
    if (rc == 0 && e->times)
        rc = tvpal_encoder_set_times(c, e->times, e->time_units, diag);
    if (rc == 0)
        rc = tvpal_encoder_set_units(c, e->units, diag);
    if (rc == 0 && !(e->lvol[k] = malloc((size_t)dk[0] * dk[1] * dk[2] *
                                         sizeof(float))))
        rc = TVPAL_E_NOMEM;
    e->lnext[k] = 0;
    if (rc == 0 && resume) {
        rc = tvpal_encoder_resume(c, TVPAL_FLOAT32, &e->lnext[k], diag);
        if (rc == 0 && e->lnext[k] < done)
            rc = tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s/level-%u: its "
                                "checkpoint is at step %u, level 0's at "
                                "%llu: abort and encode again from step 0",
                                e->partial, k, e->lnext[k],
                                (unsigned long long)done);
    }
    if (rc < 0 && diag && !strstr(diag->msg, "level-")) {
        char why[TVPAL_DIAG_MAX];
        snprintf(why, sizeof why, "%s", diag->msg);
        tvpal_diag_set(diag, rc, "level %u: %s", k, why);
    }
    return rc;
}

/* Step t to every level: level 1 from lvol[1] (made already), each next
 * level the block means of the one before. */
int tvpal_enc_push_levels(struct tvpal_encoder *e, uint32_t t,
                          struct tvpal_diag *diag)
{
    for (uint32_t k = 1; k <= e->levels; k++) {
        if (k > 1)
            tvpal_level_make(e->lvol[k - 1], e->ldims[k - 1], e->lvol[k]);
        const uint32_t *dk = e->ldims[k];
        int rc = t < e->lnext[k]
                     ? 0
                     : tvpal_encoder_push(e->lv[k], e->lvol[k], TVPAL_FLOAT32,
                                          (size_t)dk[0] * dk[1] * dk[2], NULL,
                                          diag);
        if (rc < 0) {
            char why[TVPAL_DIAG_MAX];
            snprintf(why, sizeof why, "%s", diag ? diag->msg : "");
            return tvpal_diag_set(diag, rc, "level %u: %s", k, why);
        }
    }
    return 0;
}

/* ------------------------------------------------ levels of a collective
 *
 * Level 1's 2x2x2 blocks cross the ranks' slabs where a slab starts or
 * ends between the two planes of a block.  So at each step every rank
 * sends rank 0, through the collective's gather, the level-1 planes its
 * slab holds whole and, where a block is split, its plane of it as it
 * is; rank 0 averages each split block's two planes with the function
 * one process uses (tvpal_level_average_planes), so level 1 is one
 * process's bit for bit, and encodes every level, every node shard of
 * it, in its own process (the levels are 1/7 of the work).  Every step is
 * then a collective call: every rank sends each step once, in order,
 * whatever became of its push (a failed rank's step goes marked failed,
 * and an abort or a failed finish first sends the steps left), so that
 * no rank waits for one that will not come. */

/* What a rank's part holds, ahead of its planes. */
struct xhead {
    int32_t ok;              /* the step's values were taken */
    uint32_t c0, nc;         /* whole level-1 planes c0 .. c0 + nc - 1 */
    uint32_t first, last;    /* its first plane (its slab starts at an odd
                              * plane) and its last (a block goes on in
                              * the next slab) follow */
    uint32_t pad[3];
};

/* Rank k's part of level 1, for the collective's slabs of nz planes. */
static void x_part(const struct tvpal_encoder *e, uint32_t k,
                   struct xhead *h, uint32_t *z0)
{
    const uint32_t nz = e->ep.dims[2];
    uint32_t n;
    tvpal_slab(nz, (uint32_t)e->coll.size, k, z0, &n);
    const uint32_t end = *z0 + n;
    const uint32_t c_end = end == nz ? (nz + 1) / 2 : end / 2;
    memset(h, 0, sizeof *h);
    h->c0 = (*z0 + 1) / 2;
    h->nc = c_end > h->c0 ? c_end - h->c0 : 0;
    h->first = *z0 & 1;
    h->last = (end & 1) && end < nz;
}

/* Bytes of a level-1 plane, of a level-0 plane, and of a rank's part:
 * the head, room for the most whole planes any rank has, two planes. */
static size_t x_cplane(const struct tvpal_encoder *e)
{
    return (size_t)((e->ep.dims[0] + 1) / 2) * ((e->ep.dims[1] + 1) / 2) *
           sizeof(float);
}
static size_t x_fplane(const struct tvpal_encoder *e)
{
    return (size_t)e->ep.dims[0] * e->ep.dims[1] * sizeof(float);
}
static size_t x_bytes(const struct tvpal_encoder *e)
{
    uint32_t ncmax = 0, z0;
    struct xhead h;
    for (int k = 0; k < e->coll.size; k++) {
        x_part(e, (uint32_t)k, &h, &z0);
        ncmax = h.nc > ncmax ? h.nc : ncmax;
    }
    return sizeof h + ncmax * x_cplane(e) + 2 * x_fplane(e);
}

/* Where a part's planes are: whole planes, then the first, the last. */
static size_t x_first_at(const struct tvpal_encoder *e)
{
    return e->xbytes - 2 * x_fplane(e);
}

/* Rank 0: level 1 of the step from every rank's part into lvol[1]; 0, or
 * 1 where a rank's step was not taken (nothing to encode then). */
static int x_assemble(struct tvpal_encoder *e)
{
    const size_t cp = x_cplane(e), fp = x_fplane(e);
    unsigned char *lv1 = (unsigned char *)e->lvol[1];
    for (int k = 0; k < e->coll.size; k++) {
        const unsigned char *part = e->xall + (size_t)k * e->xbytes;
        struct xhead h;
        memcpy(&h, part, sizeof h);
        if (!h.ok)
            return 1;
        memcpy(lv1 + h.c0 * cp, part + sizeof h, h.nc * cp);
        if (!h.last)
            continue;
        /* The block of this slab's last plane and the next's first: the
         * one after its whole planes. */
        const unsigned char *next = part + e->xbytes;
        tvpal_level_average_planes(
            (const float *)(part + x_first_at(e) + fp),
            (const float *)(next + x_first_at(e)), e->ep.dims[0],
            e->ep.dims[1], (float *)(lv1 + (size_t)(h.c0 + h.nc) * cp));
    }
    return 0;
}

/* Sends this rank's part of the next step (slab: its values, as
 * converted; NULL: not taken) and, on rank 0, makes the step's level 1
 * and pushes every level.  0, TVPAL_E_SYS (the gather failed) or a
 * level's code. */
static int x_step(struct tvpal_encoder *e, const float *slab,
                  struct tvpal_diag *diag)
{
    const size_t fp = x_fplane(e);
    const size_t fvox = fp / sizeof(float);
    const size_t cvox = x_cplane(e) / sizeof(float);
    struct xhead h;
    uint32_t z0;
    x_part(e, (uint32_t)e->coll.rank, &h, &z0);
    h.ok = slab != NULL;
    if (slab) {
        float *out = (float *)(e->xbuf + sizeof h);
        const uint32_t nz = e->ep.dims[2];
        for (uint32_t i = 0; i < h.nc; i++) {
            const uint32_t fz = 2 * (h.c0 + i); /* in the volume */
            const float *f0 = slab + (size_t)(fz - z0) * fvox;
            tvpal_level_average_planes(f0, fz + 1 < nz ? f0 + fvox : NULL,
                                       e->ep.dims[0], e->ep.dims[1],
                                       out + i * cvox);
        }
        if (h.first)
            memcpy(e->xbuf + x_first_at(e), slab, fp);
        if (h.last)
            memcpy(e->xbuf + x_first_at(e) + fp,
                   slab + (size_t)(e->slab_n - 1) * fvox, fp);
    }
    memcpy(e->xbuf, &h, sizeof h);
    const uint32_t t = e->xsent++;
    if (e->coll.gather(e->coll.ctx, e->xbuf, e->xbytes,
                       is_root(e) ? e->xall : NULL) != 0)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "rank %d: the "
                              "collective's gather failed", e->coll.rank);
    if (!is_root(e) || e->state == FAILED || e->xfailed)
        return 0;
    if (x_assemble(e)) {
        e->xfailed = 1;
        return 0;
    }
    return tvpal_enc_push_levels(e, t, diag);
}

/* Whether the steps go through x_step: levels, several ranks, and no
 * round has decided a failure (every rank knows it then, and none
 * sends). */
static int x_on(const struct tvpal_encoder *e)
{
    return e->xbytes && !e->decided;
}

/* The steps this rank has not sent, sent as not taken (before it leaves
 * for a round or aborts). */
static void x_send_rest(struct tvpal_encoder *e)
{
    while (x_on(e) && e->state != OPENED && e->xsent < e->ep.steps)
        if (x_step(e, NULL, NULL) < 0)
            break;
}

/* The levels finished (each renames its DIR.partial/level-k.partial to
 * DIR.partial/level-k), before level 0's manifest names them. */
int tvpal_enc_finish_level(struct tvpal_encoder *e, uint32_t k,
                           struct tvpal_diag *diag)
{
    struct tvpal_encoder *c = e->lv[k];
    e->lv[k] = NULL;
    int rc = c ? tvpal_encoder_finish(c, diag) : 0;
    if (rc < 0) {
        char why[TVPAL_DIAG_MAX];
        snprintf(why, sizeof why, "%s", diag ? diag->msg : "");
        return tvpal_diag_set(diag, rc, "level %u: %s", k, why);
    }
    return 0;
}

static int finish_levels(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    for (uint32_t k = 1; k <= e->levels; k++) {
        int rc = tvpal_enc_finish_level(e, k, diag);
        if (rc < 0)
            return rc;
    }
    return 0;
}

/* The first push, on every rank: START (nobody refused; rank 0 prepares
 * the output) and SETUP (every rank ready).  The first failure is every
 * rank's. */
int tvpal_enc_start(struct tvpal_encoder *e, enum tvpal_type type,
                    struct tvpal_diag *diag)
{
    struct tvpal_diag d = {{0}};
    struct verdict v;
    e->type = type;
    int rc = check_job(e, &d);
    if (agree(e, R_START, rc, d.msg, &v) < 0)
        return report(rc, &v, diag);
    if ((rc = tvpal_checkpoint_stats_init(&e->st)) < 0)
        snprintf(d.msg, sizeof d.msg, "out of memory");
    if (is_root(e)) {
        /* Rank 0 alone touches DIR and DIR.partial, and says how it went. */
        memset(&v, 0, sizeof v);
        v.code = rc == 0 ? prepare_output(e, &d) : rc;
        if (v.code == 0 && e->src && e->ep.group_auto)
            v.code = tvpal_enc_source_groups(e, v.groups, &d);
        snprintf(v.msg, sizeof v.msg, "%s%.1000s",
                 e->coll.size > 1 ? "rank 0: " : "", d.msg);
    }
    if (tell(e, &v) < 0)
        return report(0, &v, diag);
    if (e->src && e->ep.group_auto) /* rank 0's measure, every rank's */
        memcpy(e->ep.group_axis, v.groups, sizeof v.groups);
    rc = rc == 0 ? setup(e, &d) : rc;
    if (agree(e, R_SETUP, rc, d.msg, &v) < 0)
        return report(rc, &v, diag);
    /* Each rank continues from its own checkpoint (a kill stops the ranks
     * at different steps); the caller pushes from the earliest, and a rank
     * passes over the steps before its own. */
    uint64_t done = e->done_local;
    e->next_in = (uint32_t)v.done;
    if (!e->level0_finished) /* else an earlier encode's, kept */
        rc = open_writers(e, done, &d);
    if (rc < 0 && e->src && done) {
        /* A pulled encode's partial output that does not resume (a shard
         * damaged since its checkpoint) is started over, as when its
         * checkpoint is not this job's. */
        done = e->done_local = 0;
        if ((rc = tvpal_enc_source_start_over(e, &d)) == 0)
            rc = open_writers(e, 0, &d);
    }
    /* The levels are rank 0's (with a collective it encodes every node's
     * of them, x_step), opened before the round, which tells every rank
     * of a failure. */
    const int levels_now = !e->src || tvpal_enc_source_levels_inline(e);
    for (uint32_t k = 1; rc == 0 && is_root(e) && levels_now &&
                         k <= e->levels; k++)
        rc = tvpal_enc_open_level(e, k, done > 0, done, &d);
    if (agree(e, R_WRITERS, rc, d.msg, &v) < 0)
        return report(rc, &v, diag);
    e->encoded = e->pushed = (uint32_t)done;
    e->recount_to = done ? e->st.loaded : 0;
    e->xsent = e->next_in;
    return 0;
}

/* ----------------------------------------------------------------- push */

enum tvpal_type tvpal_enc_scalar_type(enum tvpal_scalar s)
{
    return s == TVPAL_FLOAT64 ? TVPAL_F64 : s == TVPAL_UINT8 ? TVPAL_U8
           : s == TVPAL_UINT16 ? TVPAL_U16 : s == TVPAL_INT16 ? TVPAL_I16
                                                               : TVPAL_F32;
}

/* One push's conversion, a plane per job on the pool. */
struct push_ctx {
    struct tvpal_encoder *e;
    const unsigned char *data;
    size_t esize;
    ptrdiff_t s[3];
    float *dst;
    int count;               /* into the statistics (not a step a resumed
                              * job counted before) */
};

static void convert_plane(void *arg, size_t z, unsigned tid)
{
    const struct push_ctx *c = arg;
    struct tvpal_encoder *e = c->e;
    const uint32_t nx = e->ep.dims[0], ny = e->ep.dims[1];
    const struct tvpal_values_rules rules = {
        e->missing, e->nmissing, e->has_nan_as ? &e->nan_as : NULL};
    uint64_t *fine = c->count ? e->fine[tid] : NULL;
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
                             c->dst + v0, v0, fine, &e->found[tid]);
    }
}

/* Converts this rank's slab of the step at data into the ring's slot of
 * step t, into the statistics of *all (and the threads' histograms where
 * count). */
static void convert_step(struct tvpal_encoder *e, const void *data,
                         const ptrdiff_t *strides, uint32_t t, int count,
                         struct tvpal_found *all)
{
    const uint32_t *d = e->ep.dims;
    const unsigned nt = tvpal_pool_threads(e->pool);
    struct push_ctx c = {
        .e = e, .data = data, .esize = tvpal_type_size(e->type),
        .s = {1, (ptrdiff_t)d[0], (ptrdiff_t)d[0] * d[1]},
        .dst = tvpal_engine_slot(e->eng, t), .count = count};
    if (strides)
        memcpy(c.s, strides, sizeof c.s);
    *all = tvpal_found_empty(e->st.vmin, e->st.vmax);
    for (unsigned i = 0; i < nt; i++)
        e->found[i] = *all;
    tvpal_pool_for(e->pool, e->slab_n, convert_plane, &c);
    for (unsigned i = 0; i < nt; i++)
        tvpal_found_merge(all, &e->found[i]);
}

/* Converts the step (this rank's slab of it) at data into the ring and
 * counts it; a refused value is named by its voxel in the volume. */
static int take_step(struct tvpal_encoder *e, const void *data,
                     const ptrdiff_t *strides, struct tvpal_diag *diag)
{
    const uint32_t *d = e->ep.dims;
    const int count = e->pushed >= e->recount_to;
    struct tvpal_found all;
    convert_step(e, data, strides, e->pushed, count, &all);
    if (all.rc < 0) {
        const uint64_t x = all.bad % d[0], y = all.bad / d[0] % d[1],
                       z = all.bad / d[0] / d[1] + e->slab_z0;
        return tvpal_diag_set(diag, all.rc, "step %u: %s at voxel "
                              "(%llu,%llu,%llu); finite values within 1e37 "
                              "expected, NaN for missing ones", e->pushed,
                              all.rc == TVPAL_E_NAN ? "an infinite value"
                                                    : "a value beyond 1e37",
                              (unsigned long long)x, (unsigned long long)y,
                              (unsigned long long)z);
    }
    if (!count) {
        e->pushed++;
        return 0;
    }
    /* The threads' histograms are folded into st only when it is needed
     * (a checkpoint, the end): a small step (a level's) has fewer values
     * than their 65536 classes. */
    tvpal_values_account(&e->st, e->fine, 0, &all,
                         (uint64_t)d[0] * d[1] * e->slab_n);
    e->st.loaded = ++e->pushed;
    return 0;
}

/* A checkpoint of what is encoded: the shards' progress, the statistics
 * (of the steps pushed), in this rank's directory. */
/* The threads' histograms into e->st's (before it is saved or sent). */
static void fold_histograms(struct tvpal_encoder *e)
{
    if (e->pool && e->fine)
        tvpal_values_fold(&e->st, e->fine, tvpal_pool_threads(e->pool));
}

int tvpal_enc_save_checkpoint(struct tvpal_encoder *e, uint64_t unit,
                              struct tvpal_diag *diag)
{
    fold_histograms(e);
    tvpal_engine_progress_get(e->eng, &e->ckp);
    return tvpal_checkpoint_save(e->ckdir, e->fp, unit, &e->st, &e->ckp,
                                 diag);
}

/* Encodes every step whose windows' steps are all in. */
static int encode_ready(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    const uint32_t T = e->ep.steps, L = tvpal_engine_span(&e->ep);
    while (e->encoded < T &&
           (e->pushed == T || e->encoded + L <= e->pushed)) {
        uint32_t q = 0, n;
        struct tvpal_diag d = {{0}};
        int rc = tvpal_engine_encode_step(e->eng, e->encoded, &d, &q);
        if (rc < 0) {
            struct tvpal_engine_shard *sj = tvpal_engine_shards(e->eng, &n);
            char *nd = tvpal_enc_node_dir(e, sj[q].rank);
            rc = tvpal_diag_set(diag, rc, "%s/axis-%c.tvps: %s",
                                nd ? nd : e->partial, "xyz"[sj[q].axis],
                                d.msg);
            free(nd);
            return rc;
        }
        e->encoded++;
        if (e->ckpt_every && (e->encoded % e->ckpt_every == 0 ||
                              e->encoded == T) &&
            (rc = tvpal_enc_save_checkpoint(e, e->encoded, diag)) < 0)
            return rc;
    }
    return 0;
}

int tvpal_encoder_push(struct tvpal_encoder *e, const void *data,
                       enum tvpal_scalar type, size_t count,
                       const ptrdiff_t strides[3], struct tvpal_diag *diag)
{
    if (e->state == FAILED) {
        if (x_on(e) && e->xsent < e->ep.steps)
            x_step(e, NULL, NULL); /* its step, not taken, to rank 0 */
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "a push after a failed "
                              "one: only tvpal_encoder_abort is left");
    }
    if (type < TVPAL_FLOAT32 || type > TVPAL_INT16)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "type %d: TVPAL_FLOAT32 "
                              ".. TVPAL_INT16 expected", (int)type);
    if (!data)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "no data");
    const uint64_t want = (uint64_t)e->ep.dims[0] * e->ep.dims[1] * e->slab_n;
    if (count != want)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u: %zu values "
                              "pushed, %llu expected (%ux%ux%u)", e->next_in,
                              count, (unsigned long long)want, e->ep.dims[0],
                              e->ep.dims[1], e->slab_n);
    if (e->next_in == e->ep.steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u pushed: the "
                              "encoder was opened for %u", e->next_in + 1,
                              e->ep.steps);
    const enum tvpal_type t = tvpal_enc_scalar_type(type);
    int rc = 0;
    struct tvpal_diag d = {{0}};
    if (e->state == OPENED) {
        e->state = STARTED;
        rc = tvpal_enc_start(e, t, &d);
    } else if (t != e->type) {
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u is %s, step 0 "
                              "was %s: one type for the series", e->next_in,
                              tvpal_type_name(t), tvpal_type_name(e->type));
    }
    if (rc == 0 && e->next_in < e->pushed) {
        /* A step this rank's checkpoint has: passed over, but for its
         * part of the levels, which rank 0 may not have. */
        if (x_on(e)) {
            struct tvpal_found all;
            convert_step(e, data, strides, e->next_in, 0, &all);
            rc = x_step(e, tvpal_engine_slot(e->eng, e->next_in), &d);
        }
        if (rc == 0) {
            e->next_in++;
            return 0;
        }
    } else if (rc == 0) {
        rc = take_step(e, data, strides, &d);
        if (rc == 0)
            e->next_in++;
        /* The levels first: their checkpoints are then never behind level
         * 0's, so that a resume finds every level at or past level 0's
         * step. */
        if (x_on(e)) {
            /* The step goes to rank 0 whatever became of it (rank 0
             * makes the levels). */
            const int xrc = x_step(e, rc == 0 ? tvpal_engine_slot(
                                                    e->eng, e->pushed - 1)
                                              : NULL, rc == 0 ? &d : NULL);
            rc = rc == 0 ? xrc : rc;
        } else if (rc == 0 && e->levels) {
            tvpal_level_make(tvpal_engine_slot(e->eng, e->pushed - 1),
                             e->ep.dims, e->lvol[1]);
            rc = tvpal_enc_push_levels(e, e->pushed - 1, &d);
        }
    }
    if (rc == 0)
        rc = encode_ready(e, &d);
    if (rc < 0 && e->state != FAILED) {
        e->state = FAILED;
        if (!e->decided && !e->own_rc) {
            e->own_rc = rc;
            memcpy(e->own_msg, d.msg, sizeof d.msg);
        }
        if (diag)
            *diag = d;
    }
    return rc;
}

int tvpal_encoder_resume(struct tvpal_encoder *e, enum tvpal_scalar type,
                         uint32_t *next_step, struct tvpal_diag *diag)
{
    if (e->state != OPENED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "resume after the first "
                              "push");
    *next_step = 0;
    if (type < TVPAL_FLOAT32 || type > TVPAL_INT16)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "type %d: TVPAL_FLOAT32 "
                              ".. TVPAL_INT16 expected", (int)type);
    struct tvpal_diag d = {{0}};
    e->resuming = 1;
    e->state = STARTED;
    int rc = tvpal_enc_start(e, tvpal_enc_scalar_type(type), &d);
    if (rc < 0) {
        e->state = FAILED;
        if (diag)
            *diag = d;
        return rc;
    }
    *next_step = e->next_in;
    return 0;
}

/* --------------------------------------------------------------- finish */

/* tvpal_encoder_set_provenance's into m (raw sources keep format "",
 * which the manifest writes as raw). */
static int add_provenance(const struct tvpal_encoder *e,
                          struct tvpal_manifest *m)
{
    m->single_file = e->prov_single_file;
    m->series = e->prov_series;
    if (strcmp(e->prov_format, "raw"))
        snprintf(m->source_format, sizeof m->source_format, "%s",
                 e->prov_format);
    if (e->prov_var && !(m->source_var = strdup(e->prov_var)))
        return TVPAL_E_NOMEM;
    for (uint32_t i = 0; i < e->prov_nsources; i++)
        if (tvpal_manifest_add_source(m, e->prov_sources[i]) < 0)
            return TVPAL_E_NOMEM;
    return 0;
}

/* The manifest: the job's fields (tvpal_engine_manifest) and the grid;
 * source_format stays "" (raw): the values as host float32 or float64,
 * which tvpal-report --reference compares with raw files of them. */
static int build_manifest(const struct tvpal_encoder *e, char **text)
{
    /* A raw source of one file of every step says so in the options line
     * (tvpal-encode --steps T). */
    const int raw = !strcmp(e->prov_format, "raw");
    const struct tvpal_engine_source src = {
        .type = e->type, .big_endian = e->src_big_endian,
        .steps_single = raw && e->prov_single_file ? e->ep.steps : 0,
        .nan_as = e->has_nan_as ? &e->nan_as : NULL,
        .missing = e->missing, .nmissing = e->nmissing};
    struct tvpal_manifest m;
    int rc = tvpal_engine_manifest(&e->ep, &src, &e->st, e->times,
                                   e->time_units, e->units,
                                   e->prov_encoder[0] ? e->prov_encoder
                                                      : LIB_NAME, &m);
    memcpy(m.spacing, e->spacing, sizeof m.spacing);
    memcpy(m.origin, e->origin, sizeof m.origin);
    m.levels = e->levels;
    rc = rc == 0 ? add_provenance(e, &m) : rc;
    if (rc == 0)
        rc = tvpal_manifest_format(&m, text);
    tvpal_manifest_clear(&m);
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

/* STATS: every rank has pushed every step; the statistics summed on rank
 * 0 become every rank's, with the manifest's text (*text, malloc'ed). */
static int agree_stats(struct tvpal_encoder *e, int rc, const char *msg,
                       char **text, struct tvpal_diag *diag)
{
    struct verdict v;
    if (agree(e, R_STATS, rc, msg, &v) < 0)
        return report(rc, &v, diag);
    if (sum_histograms(e) < 0) {
        e->decided = 1;
        return tvpal_diag_set(diag, TVPAL_E_SYS, "rank %d: the collective's "
                              "gather failed", e->coll.rank);
    }
    e->st.vmin = v.vmin, e->st.vmax = v.vmax;
    e->st.nonfinite = v.nonfinite, e->st.missing = v.missing;
    e->st.counted = v.counted;
    if (is_root(e)) {
        const double keep[2] = {v.vmin, v.vmax};
        memset(&v, 0, sizeof v);
        v.vmin = keep[0], v.vmax = keep[1];
        v.code = build_manifest(e, text);
        if (v.code < 0)
            snprintf(v.msg, sizeof v.msg, "rank 0: the manifest: out of "
                     "memory");
        else
            v.text_len = (uint32_t)strlen(*text);
    }
    if (tell(e, &v) < 0)
        return report(0, &v, diag);
    if (!is_root(e) && !(*text = calloc(1, (size_t)v.text_len + 1)))
        rc = tvpal_diag_set(diag, TVPAL_E_NOMEM, "rank %d: the manifest's "
                            "%u bytes", e->coll.rank, v.text_len);
    /* The text in pieces through a buffer of the stack, so that a rank
     * that could not hold it still takes part (and fails in PLACE). */
    char piece[4096];
    for (uint32_t o = 0; o < v.text_len; o += sizeof piece) {
        const size_t n = v.text_len - o < sizeof piece ? v.text_len - o
                                                       : sizeof piece;
        if (is_root(e))
            memcpy(piece, *text + o, n);
        if (e->coll.bcast(e->coll.ctx, piece, n) != 0) {
            e->decided = 1;
            return tvpal_diag_set(diag, TVPAL_E_SYS, "rank %d: the "
                                  "collective's bcast failed", e->coll.rank);
        }
        if (!is_root(e) && *text)
            memcpy(*text + o, piece, n);
    }
    return rc;
}

/* Nothing present leaves nothing to draw (and no range to write); the
 * statistics are every rank's sum, so every rank says it. */
static int all_missing(const struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    return tvpal_diag_set(diag, TVPAL_E_INVAL, "every value of the %u steps "
                          "is missing (NaN%s): some present values "
                          "expected; nothing was written at %s", e->ep.steps,
                          e->nmissing ? " or a missing value" : "", e->dir);
}

/* This rank's shards finished, with the source's range, and its node
 * directories' manifests. */
static int finish_shards(struct tvpal_encoder *e, const char *text,
                         struct tvpal_diag *diag)
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
    int rc = tvpal_checkpoint_remove(e->ckdir, diag);
    for (uint32_t k = 0; rc == 0 && k < e->ep.node_count; k++) {
        char *nd = tvpal_enc_node_dir(e, e->ep.node_first + k);
        rc = nd ? write_manifest(nd, text, diag) : TVPAL_E_NOMEM;
        free(nd);
    }
    return rc;
}

/* The manifest in DIR.partial, which is read back as a dataset, then
 * renamed to DIR (tvpal_output_place). */
static int place(struct tvpal_encoder *e, const char *text,
                 struct tvpal_diag *diag)
{
    int rc = write_manifest(e->partial, text, diag);
    if (rc < 0)
        return rc;
    tvpal_fsync_dir(e->partial);
    /* Read back, every level of it: what fails here (a value the
     * manifest reader refuses, a file that does not open) must not
     * replace a good dataset. */
    for (uint32_t k = 0; rc == 0 && k <= e->levels; k++) {
        char *dir = NULL;
        struct tvpal_dataset *ds = NULL;
        struct tvpal_diag d = {{0}};
        if (k ? asprintf(&dir, "%s/level-%u", e->partial, k) < 0
              : !(dir = strdup(e->partial)))
            return TVPAL_E_NOMEM;
        if (k == 0 && e->shard_pat) { /* the node directories are the
                                       * ranks' (place_node_dir) */
            struct tvpal_manifest m = {0};
            char *mp = NULL;
            rc = asprintf(&mp, "%s/manifest.txt", dir) < 0
                     ? TVPAL_E_NOMEM : tvpal_manifest_load(mp, &m, &d);
            tvpal_manifest_clear(&m);
            free(mp);
        } else {
            rc = tvpal_dataset_open(&ds, dir, &d);
            tvpal_dataset_close(ds);
        }
        if (rc < 0)
            tvpal_diag_set(diag, rc, "%s: written %s does not verify: %s "
                           "(%s)", dir, k ? "level" : "dataset", d.msg,
                           tvpal_exists(e->dir) ? "the existing dataset is "
                           "left as it was" : "nothing was put in place");
        free(dir);
    }
    if (rc == 0 && (rc = tvpal_output_place(e->partial, e->dir, diag)) == 0)
        e->made_partial = 0;
    return rc;
}

/* With a shard directory: this rank's node directory read back, then
 * renamed from PATTERN.partial into place (an older one replaced under
 * TVPAL_PARAM_FORCE). */
static int place_node_dir(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    const uint32_t k = e->ep.node_first;
    char *fin = tvpal_node_dir(NULL, e->shard_pat, k);
    struct tvpal_dataset *ds = NULL;
    struct tvpal_diag d = {{0}};
    if (!fin)
        return TVPAL_E_NOMEM;
    int rc = tvpal_dataset_open_node(&ds, e->ckdir, k, e->ep.nodes, &d);
    tvpal_dataset_close(ds);
    if (rc < 0)
        rc = tvpal_diag_set(diag, rc, "%s: written node directory does not "
                            "verify: %s", e->ckdir, d.msg);
    else if (tvpal_exists(fin) && (!e->force || tvpal_rmtree(fin) < 0))
        rc = tvpal_diag_set(diag, e->force ? TVPAL_E_SYS : TVPAL_E_EXIST,
                            "%s: node directory already exists%s", fin,
                            e->force ? " and cannot be removed" : "");
    else if (rename(e->ckdir, fin) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot rename %s into "
                            "place: %s", fin, e->ckdir, strerror(errno));
    free(fin);
    return rc;
}

/* Frees e; on rank 0, a partial output left (a failure) goes first, and
 * the lock with it. */
static void release(struct tvpal_encoder *e)
{
    const unsigned nt = e->pool ? tvpal_pool_threads(e->pool) : 0;
    for (uint32_t k = 1; k <= e->levels; k++) {
        if (e->lv[k] && e->keep_partial) /* its checkpoint with level 0's */
            e->lv[k]->keep_partial = 1;
        tvpal_encoder_abort(e->lv[k]);
        free(e->lvol[k]);
    }
    tvpal_enc_source_free(e);  /* its reader thread first */
    tvpal_engine_free(e->eng);
    tvpal_pool_free(e->pool);
    /* A source's job whose failure may pass (on any rank) is continued
     * from DIR.partial by the next encode of the same identity. */
    if (e->keep_identity && tvpal_enc_failure_may_pass(e->decided_code))
        e->keep_partial = 1;
    if (e->made_partial && !e->keep_partial)
        tvpal_rmtree(e->partial);
    for (unsigned i = 0; i < nt; i++) {
        if (e->fine)
            free(e->fine[i]);
        if (e->rows)
            free(e->rows[i]);
    }
    free(e->fine);
    free(e->rows);
    free(e->found);
    free(e->votes);
    free(e->pieces);
    free(e->xbuf);
    free(e->xall);
    free(e->ckdir);
    free(e->fp);
    tvpal_checkpoint_progress_free(&e->ckp);
    if (e->coll.release)
        e->coll.release(e->coll.ctx);
    tvpal_checkpoint_stats_free(&e->st);
    if (e->lock_path)
        tvpal_lock_release(e->lock_path, e->lock_fd);
    free(e->lock_path);
    free(e->times);
    free(e->text);
    free(e->shard_pat);
    free_provenance(e);
    free(e->partial);
    free(e->dir);
    free(e);
}

/* This rank fails: it joins the round the others will reach (START before
 * the first push, STATS after), so that every rank ends. */
static void join_failing(struct tvpal_encoder *e, int rc, const char *msg)
{
    struct verdict v;
    if (e->decided || e->round >= R_DONE)
        return;
    if (e->own_rc)
        rc = e->own_rc, msg = e->own_msg;
    x_send_rest(e); /* the other ranks are still pushing */
    if (e->round == R_START || e->round == R_STATS ||
        (e->round == R_PLACE && e->level0_finished))
        agree(e, e->round, rc, msg, &v);
}

int tvpal_enc_finish_level0(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    struct tvpal_diag d = {{0}};
    fold_histograms(e);
    int rc = agree_stats(e, 0, NULL, &e->text, &d);
    if (rc == 0 && !(e->st.vmin <= e->st.vmax))
        rc = all_missing(e, &d);
    if (rc == 0)
        rc = finish_shards(e, e->text, &d);
    if (!e->decided) {
        /* Every rank's shards finished before DIR.partial says level 0 is
         * (its manifest, then the caller's marker). */
        struct verdict v;
        if (agree(e, R_LEVEL0, rc, d.msg, &v) == 0 && is_root(e))
            rc = write_manifest(e->partial, e->text, &d);
        else
            rc = report(rc, &v, &d);
    }
    if (rc == 0)
        e->level0_finished = 1;
    else if (diag)
        *diag = d;
    return rc;
}

int tvpal_encoder_finish(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    struct tvpal_diag d = {{0}};
    int rc = 0;
    if (e->state == FAILED)
        rc = tvpal_diag_set(&d, TVPAL_E_INVAL, "finish after a failed "
                            "push: nothing was written at %s", e->dir);
    else if (e->next_in < e->ep.steps)
        rc = tvpal_diag_set(&d, TVPAL_E_INVAL, "finish after %u of %u "
                            "steps: nothing was written at %s", e->next_in,
                            e->ep.steps, e->dir);
    if (rc < 0 || e->decided) {
        join_failing(e, rc ? rc : TVPAL_E_INVAL, d.msg);
        if (diag)
            *diag = d;
        release(e);
        return rc ? rc : TVPAL_E_INVAL;
    }
    char *text = e->text;
    e->text = NULL;
    if (!e->level0_finished) { /* else tvpal_enc_finish_level0 did it */
        fold_histograms(e);
        /* The levels are rank 0's; with a collective, levels a failed
         * rank left short are not finished (that rank's failure is said
         * in the round). */
        rc = e->xfailed ? 0 : finish_levels(e, &d);
        rc = agree_stats(e, rc, d.msg, &text, &d);
        if (rc == 0 && !(e->st.vmin <= e->st.vmax))
            rc = all_missing(e, &d);
        if (rc == 0)
            rc = finish_shards(e, text, &d);
    }
    if (rc == 0 && e->shard_pat)
        rc = place_node_dir(e, &d);
    if (!e->decided) {
        struct verdict v;
        if (agree(e, R_PLACE, rc, d.msg, &v) == 0) {
            if (is_root(e)) {
                memset(&v, 0, sizeof v);
                v.code = place(e, text, &d);
                snprintf(v.msg, sizeof v.msg, "%s", d.msg);
            }
            tell(e, &v);
        }
        rc = report(rc, &v, &d);
    }
    free(text);
    if (diag)
        *diag = d;
    release(e);
    return rc;
}

int tvpal_encoder_stats(struct tvpal_encoder *e,
                        struct tvpal_stats *out)
{
    memset(out, 0, sizeof *out);
    if (e->state == OPENED || !e->st.fine)
        return TVPAL_E_INVAL;
    /* The threads' histograms are folded in at each checkpoint and at
     * level 0's finish; those since are folded in here (the encoder is
     * between calls, its threads idle). */
    fold_histograms(e);
    const struct tvpal_checkpoint_stats *st = &e->st;
    out->value_min = st->vmin;
    out->value_max = st->vmax;
    out->values = st->counted;
    out->missing = st->missing;
    out->replaced = st->nonfinite;
    out->dropped = e->eng ? tvpal_engine_dropped(e->eng) : 0;
    tvpal_values_spread(st, &out->p_low, &out->p_high, &out->beyond_1e30,
                        &out->far);
    return 0;
}

void tvpal_encoder_abort(struct tvpal_encoder *e)
{
    if (!e)
        return;
    char msg[64];
    snprintf(msg, sizeof msg, "the encode was aborted");
    join_failing(e, TVPAL_E_INVAL, msg);
    release(e);
}
