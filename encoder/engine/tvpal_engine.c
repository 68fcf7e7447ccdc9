/* tvpal_engine.c: the encoding engine (tvpal_engine.h).
 *
 * A step's work is a list of jobs, each a group of slice-windows of one
 * shard that start at the step (x slices of one cache line grouped: one
 * pass over the box rows gathers them all); the pool's threads take jobs
 * in turn, gather their samples from the ring, code each slice-window
 * into the thread's chunk buffer and write it in place.  Everything a step
 * uses is allocated by tvpal_engine_start, none per step or per voxel. */
#include "tvpal_cli.h"
#include "tvpal_engine.h"
#include "tvpal_checkpoint.h"
#include "tvpal_values.h"
#include "tvpal_format.h"
#include "tvpal_chunkz.h"
#include "tvpal_manifest.h"
#include "tvpal_schedule.h"
#include "tvpal_swcode.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

_Static_assert(TVPAL_ENGINE_REFINE_MAX == TVPAL_REFINE_MAX,
               "the engine's refinement bound is the codec's");

/* Most slices per group: those of one 64-byte line of x (16 floats). */
#define GROUP_SPAN 16u

/* A job of `count` slices slice, slice + stride, ... of one shard, all
 * with windows of length len starting at the current step: x slices of
 * one phase (stride N), or the slices of one palette group in the slab
 * and the pass (stride 1, shared when there are several: one chunk under
 * one table).  Their chunks' CRCs go to jcrc[crc_at ..]. */
struct slicejob {
    struct tvpal_engine_shard *sj;
    uint32_t slice;
    uint32_t count;
    uint32_t stride;
    uint32_t len;
    size_t crc_at;
    int shared;
};

/* One pass over a slice-window that prices any rounding of its float32
 * table t32 without another: per entry e = j * 256 + i, held[e] voxels
 * decode it with a value (sample and entry not missing) and resid[e] is the
 * sum of their errors x - t32[e]; count[i] voxels hold index i at all.
 * Then a table t decoding t[e] = t32[e] - d[e] errs by
 * SSE32 + sum_e (held[e] d[e]^2 + 2 d[e] resid[e]): exactly the sum over
 * the voxels, up to rounding in double. */
struct table_fit {
    double sse32;
    double resid[TVPAL_NMAX * TVPAL_TABLE_ENTRIES];
    uint32_t held[TVPAL_NMAX * TVPAL_TABLE_ENTRIES];
    uint32_t count[TVPAL_TABLE_ENTRIES];
};

struct tvpal_engine {
    struct tvpal_engine_params p;
    struct tvpal_engine_shard *sj;
    uint32_t nshard;
    size_t max_slice_vox, max_jobs;  /* voxels of a group's slices */
    uint32_t max_group;          /* the largest G of the axes */
    uint64_t max_chunk;          /* bytes of the largest chunk */
    size_t group_cap;            /* floats of samples per thread */
    /* Started: */
    struct tvpal_pool *pool;
    unsigned nthreads;
    struct tvpal_swenc **enc;
    float **samples;
    float **gsamples;            /* a palette group's samples as one
                                  * slice (groups only) */
    float **tables;              /* a table, then (--table auto) the
                                  * values its 16-bit form decodes to */
    struct table_fit **fit;      /* --table auto's measure of a table */
    unsigned char **chunkbuf;    /* one chunk */
    unsigned char **codedbuf;    /* it coded (index_level > 0) */
    struct tvpal_chunkz **z;     /* its coder (index_level > 0) */
    uint64_t *dropped;
    struct slicejob *jobs;       /* max_jobs */
    uint32_t *jcrc;              /* CRC of every chunk of a step */
    float **ring;                /* ring_slots boxes */
    uint32_t nring;
    const struct encode_pass *pass;
    uint64_t *work;
    void (*tick)(void *ctx);
    void *tick_ctx;
};

/* Samples per thread: one slice-window, or a group of x slices up to
 * 8 MiB (a group never exceeds GROUP_SPAN slices). */
static size_t group_floats(const struct tvpal_engine *e)
{
    const size_t sw = e->max_slice_vox * tvpal_engine_span(&e->p);
    if (sw >= (size_t)2 << 20)
        return sw;
    return (size_t)2 << 20 < sw * GROUP_SPAN ? (size_t)2 << 20
                                             : sw * GROUP_SPAN;
}

uint32_t tvpal_engine_group(const struct tvpal_engine_params *p,
                            unsigned a)
{
    uint32_t n, w, h;
    tvpal_axis_geometry(p->dims, a, &n, &w, &h);
    const uint32_t want = p->group_axis[a] ? p->group_axis[a]
                          : p->group_auto ? TVPAL_ENGINE_GROUP_AUTO_MAX
                                          : p->group;
    uint64_t G = want < n ? want : n;
    if (G * w * h > TVPAL_GROUP_VOXELS_MAX)
        G = TVPAL_GROUP_VOXELS_MAX / ((uint64_t)w * h);
    return G >= 2 ? (uint32_t)G : 1;
}

static int params_ok(const struct tvpal_engine_params *p)
{
    return p->dims[0] && p->dims[1] && p->dims[2] && p->steps &&
           p->window >= 1 && p->window <= 16 &&
           tvpal_engine_span(p) <= TVPAL_NMAX &&
           (p->schedule == TVPAL_SCHEDULE_STAGGERED ||
            p->schedule == TVPAL_SCHEDULE_JOINED) && p->axes >= 1 &&
           p->axes <= 7 && p->nodes >= 1 && p->node_count >= 1 &&
           p->node_first < p->nodes &&
           p->node_count <= p->nodes - p->node_first &&
           p->group <= TVPAL_GROUP_MAX &&
           p->group_axis[0] <= TVPAL_GROUP_MAX &&
           p->group_axis[1] <= TVPAL_GROUP_MAX &&
           p->group_axis[2] <= TVPAL_GROUP_MAX &&
           (p->table_format == TVPAL_TABLE_F32 ||
            p->table_format == TVPAL_TABLE_U16 ||
            p->table_format == TVPAL_TABLE_CHUNK);
}

int tvpal_engine_create(struct tvpal_engine **out,
                        const struct tvpal_engine_params *p)
{
    *out = NULL;
    if (!params_ok(p))
        return TVPAL_E_INVAL;
    struct tvpal_engine *e = calloc(1, sizeof *e);
    if (!e)
        return TVPAL_E_NOMEM;
    e->p = *p;
    const uint32_t k0 = p->node_first, nk = p->node_count;
    e->nshard = tvpal_axes_count(p->axes) * nk;
    if (!(e->sj = calloc(e->nshard, sizeof *e->sj))) {
        free(e);
        return TVPAL_E_NOMEM;
    }
    for (unsigned a = 0, ia = 0; a < 3; a++) {
        if (!(p->axes & TVPAL_AXIS_BIT(a)))
            continue;
        uint32_t n, w, h;
        tvpal_axis_geometry(p->dims, a, &n, &w, &h);
        const uint32_t G = tvpal_engine_group(p, a);
        if ((size_t)G * w * h > e->max_slice_vox)
            e->max_slice_vox = (size_t)G * w * h;
        if (G > e->max_group)
            e->max_group = G;
        e->max_jobs += n;
        /* A group's chunk takes the rooms of its slices. */
        uint64_t cb = G * tvpal_chunk_bytes(tvpal_engine_span(p), w, h,
                                            p->table_format);
        if (cb > e->max_chunk)
            e->max_chunk = cb;
        for (uint32_t k = k0; k < k0 + nk; k++) {
            struct tvpal_engine_shard *j = &e->sj[ia * nk + (k - k0)];
            j->axis = a;
            j->rank = k;
            j->h = (struct tvpal_shard_header){
                .version = G > 1 ? TVPAL_FORMAT_VERSION_GROUPED
                           : p->schedule == TVPAL_SCHEDULE_JOINED
                               ? TVPAL_FORMAT_VERSION_JOINED
                               : TVPAL_FORMAT_VERSION,
                .steps = p->steps, .group = G,
                .window = p->window, .schedule = p->schedule,
                .nodes = p->nodes, .rank = k,
                .axis = a, .slice_w = w, .slice_h = h,
                .table_format = p->table_format};
            memcpy(j->h.dims, p->dims, sizeof p->dims);
            tvpal_slab_range(n, p->nodes, k, &j->h.slice_begin,
                             &j->h.slice_count);
        }
        ia++;
    }
    e->group_cap = group_floats(e);
    *out = e;
    return 0;
}

struct tvpal_engine_shard *tvpal_engine_shards(struct tvpal_engine *e,
                                               uint32_t *n)
{
    *n = e->nshard;
    return e->sj;
}

uint64_t tvpal_engine_thread_bytes(const struct tvpal_engine *e)
{
    const uint64_t sv = e->max_slice_vox, N = tvpal_engine_span(&e->p);
    const uint64_t codec = sv * (16 * N + 64) + N * 256 * 16 + (1u << 16);
    const uint64_t groups = e->max_group > 1 ? e->group_cap * sizeof(float)
                                             : 0;
    return codec + e->group_cap * sizeof(float) +
           2 * N * 256 * sizeof(float) + e->max_chunk + groups;
}

uint64_t tvpal_engine_max_chunk(const struct tvpal_engine *e)
{
    return e->max_chunk;
}

uint64_t tvpal_engine_table_bytes(const struct tvpal_engine *e)
{
    return (uint64_t)e->nshard * e->p.steps * 40 + (uint64_t)e->max_jobs * 40;
}

static uint32_t ring_slots(const struct tvpal_engine *e)
{
    return tvpal_engine_span(&e->p);
}

static int start_thread(struct tvpal_engine *e, unsigned i,
                        struct tvpal_diag *diag)
{
    const uint32_t N = tvpal_engine_span(&e->p);
    if (tvpal_swenc_create(&e->enc[i], e->max_slice_vox, N) < 0 ||
        tvpal_swenc_set_refine(e->enc[i], e->p.refine) < 0 ||
        (tvpal_swenc_set_naive(e->enc[i], e->p.naive),
         tvpal_swenc_set_alloc_mse(e->enc[i], e->p.alloc_mse) < 0))
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "the coder's workspace");
    if (e->p.klt && tvpal_swenc_set_klt(e->enc[i], 1) < 0)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "no LAPACK");
    if (!(e->samples[i] = malloc(e->group_cap * sizeof(float))) ||
        !(e->tables[i] = malloc(2 * N * 256 * sizeof(float))) ||
        !(e->fit[i] = malloc(sizeof *e->fit[i])) ||
        !(e->chunkbuf[i] = malloc(e->max_chunk)) ||
        (e->p.index_level &&
         (!(e->codedbuf[i] = malloc(e->max_chunk)) ||
          tvpal_chunkz_create(&e->z[i], e->max_chunk) < 0)))
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "a thread's workspace");
    if (e->max_group > 1 &&
        !(e->gsamples[i] = malloc(e->group_cap * sizeof(float))))
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "a thread's workspace");
    return 0;
}

int tvpal_engine_start(struct tvpal_engine *e, struct tvpal_pool *pool,
                       uint64_t box_voxels, struct tvpal_diag *diag)
{
    const size_t nt = tvpal_pool_threads(pool);
    e->pool = pool;
    e->nthreads = (unsigned)nt;
    e->nring = ring_slots(e);
    e->enc = calloc(nt, sizeof *e->enc);
    e->dropped = calloc(nt, sizeof *e->dropped);
    e->samples = calloc(nt, sizeof *e->samples);
    e->gsamples = calloc(nt, sizeof *e->gsamples);
    e->tables = calloc(nt, sizeof *e->tables);
    e->fit = calloc(nt, sizeof *e->fit);
    e->chunkbuf = calloc(nt, sizeof *e->chunkbuf);
    e->codedbuf = calloc(nt, sizeof *e->codedbuf);
    e->z = calloc(nt, sizeof *e->z);
    e->jobs = calloc(e->max_jobs, sizeof *e->jobs);
    e->jcrc = calloc(e->max_jobs, sizeof *e->jcrc);
    e->ring = calloc(e->nring, sizeof *e->ring);
    if (!e->enc || !e->dropped || !e->samples || !e->tables || !e->fit ||
        !e->gsamples ||
        !e->jobs || !e->ring || !e->chunkbuf || !e->jcrc || !e->codedbuf ||
        !e->z)
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "the job lists");
    for (unsigned i = 0; i < nt; i++) {
        int rc = start_thread(e, i, diag);
        if (rc < 0)
            return rc;
    }
    if (box_voxels > SIZE_MAX / sizeof(float))
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "%u timesteps of %llu "
                              "voxels", e->nring,
                              (unsigned long long)box_voxels);
    for (uint32_t i = 0; i < e->nring; i++)
        if (!(e->ring[i] = malloc(box_voxels * sizeof(float))))
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "%u timesteps of %llu "
                                  "voxels", e->nring,
                                  (unsigned long long)box_voxels);
    return 0;
}

float *tvpal_engine_slot(struct tvpal_engine *e, uint32_t t)
{
    return e->ring ? e->ring[t % e->nring] : NULL;
}

void tvpal_engine_release_ring(struct tvpal_engine *e)
{
    for (uint32_t i = 0; e->ring && i < e->nring; i++) {
        free(e->ring[i]);
        e->ring[i] = NULL;
    }
}

void tvpal_engine_set_pass(struct tvpal_engine *e,
                           const struct encode_pass *ps)
{
    e->pass = ps;
}

void tvpal_engine_set_progress(struct tvpal_engine *e, uint64_t *work,
                               void (*tick)(void *ctx), void *ctx)
{
    e->work = work;
    e->tick = tick;
    e->tick_ctx = ctx;
}

uint64_t tvpal_engine_dropped(const struct tvpal_engine *e)
{
    uint64_t d = 0;
    for (unsigned i = 0; e->dropped && i < e->nthreads; i++)
        d += e->dropped[i];
    return d;
}

void tvpal_engine_free(struct tvpal_engine *e)
{
    if (!e)
        return;
    for (uint32_t q = 0; q < e->nshard; q++)
        tvpal_shardw_free(e->sj[q].w);
    free(e->sj);
    for (unsigned i = 0; i < e->nthreads && e->enc; i++) {
        tvpal_swenc_free(e->enc[i]);
        free(e->samples[i]);
        free(e->gsamples[i]);
        free(e->tables[i]);
        free(e->fit[i]);
        free(e->chunkbuf[i]);
        free(e->codedbuf[i]);
        tvpal_chunkz_free(e->z[i]);
    }
    tvpal_engine_release_ring(e);
    free(e->ring);
    free(e->enc);
    free(e->dropped);
    free(e->samples);
    free(e->gsamples);
    free(e->tables);
    free(e->fit);
    free(e->chunkbuf);
    free(e->codedbuf);
    free(e->z);
    free(e->jobs);
    free(e->jcrc);
    free(e);
}

/* The axes without --axes (tvpal-encode's ENCODE_AXES_DEFAULT). */
#define AXES_DEFAULT TVPAL_AXIS_BIT(2)

void tvpal_engine_options_line(const struct tvpal_engine_params *p,
                               const struct tvpal_engine_source *src,
                               char *buf, size_t cap)
{
    size_t n = (size_t)snprintf(
        buf, cap, "--dims %ux%ux%u --type %s --endian %s --window %u "
        "--nodes %u%s", p->dims[0], p->dims[1], p->dims[2],
        tvpal_type_name(src->type), src->big_endian ? "big" : "little",
        p->window, p->nodes, src->steps_single ? " --steps" : "");
#define OPTS_ADD(...)                                                         \
    do {                                                                      \
        if (n < cap)                                                          \
            n += (size_t)snprintf(buf + n, cap - n, __VA_ARGS__);             \
    } while (0)
    if (src->steps_single)
        OPTS_ADD(" %u", src->steps_single);
    if (src->nan_as)
        OPTS_ADD(" --nan-as %.17g", *src->nan_as);
    for (unsigned i = 0; i < src->nmissing; i++)
        OPTS_ADD(" --missing %.9g", (double)(float)src->missing[i]);
    /* --table auto is the default; the others say so, so that the line
     * gives the same output. */
    if (p->table_format != TVPAL_TABLE_CHUNK)
        OPTS_ADD(" --table %s", tvpal_manifest_table_name(p->table_format));
    if (p->refine)
        OPTS_ADD(" --refine %u", p->refine);
    if (p->naive)
        OPTS_ADD(" --naive");
    if (p->klt)
        OPTS_ADD(" --transform klt");
    if (p->alloc_mse)
        OPTS_ADD(" --alloc greedy-mse");
    if (p->schedule == TVPAL_SCHEDULE_STAGGERED)
        OPTS_ADD(" --schedule staggered");
    if (p->group_auto)
        OPTS_ADD(" --group auto");
    else if (p->group > 1)
        OPTS_ADD(" --group %u", p->group);
    if (p->index_level == 0)
        OPTS_ADD(" --index-coding none");
    else if (p->index_level != TVPAL_CHUNKZ_LEVEL)
        OPTS_ADD(" --index-level %d", p->index_level);
    if (p->axes != AXES_DEFAULT) {
        char axes[4];
        OPTS_ADD(" --axes %s", tvpal_axes_format(p->axes, axes));
    }
#undef OPTS_ADD
}

int tvpal_engine_manifest(const struct tvpal_engine_params *p,
                          const struct tvpal_engine_source *src,
                          const struct tvpal_checkpoint_stats *st,
                          const double *times, const char *time_units,
                          const char *units, const char *encoder,
                          struct tvpal_manifest *m)
{
    char optstr[256];
    *m = (struct tvpal_manifest){0};
    memcpy(m->dims, p->dims, sizeof m->dims);
    m->type = src->type;
    m->big_endian = src->big_endian;
    m->steps = p->steps;
    m->window = p->window;
    m->schedule = p->schedule;
    m->nodes = p->nodes;
    m->axes_mask = p->axes;
    m->table_format = p->table_format;
    m->value_min = st->vmin;
    m->value_max = st->vmax;
    m->has_nan_as = src->nan_as != NULL;
    m->nan_as = src->nan_as ? *src->nan_as : 0;
    m->nonfinite = st->nonfinite;
    m->missing = st->missing;
    for (unsigned i = 0; i < src->nmissing; i++)
        m->missing_values[i] = (float)src->missing[i];
    m->nmissing_values = src->nmissing;
    m->source_bytes = (uint64_t)p->dims[0] * p->dims[1] * p->dims[2] *
                      tvpal_type_size(src->type) * p->steps;
    tvpal_values_histogram(st, m->histogram);
    if (times) {
        if (!(m->times = malloc(sizeof *m->times * p->steps)))
            return TVPAL_E_NOMEM;
        memcpy(m->times, times, sizeof *m->times * p->steps);
        m->ntimes = p->steps;
        snprintf(m->time_units, sizeof m->time_units, "%s",
                 time_units ? time_units : "");
    }
    snprintf(m->units, sizeof m->units, "%s", units ? units : "");
    tvpal_engine_options_line(p, src, optstr, sizeof optstr);
    m->encoder = strdup(encoder);
    m->options = strdup(optstr);
    return m->encoder && m->options ? 0 : TVPAL_E_NOMEM;
}

/* ---------------------------------------------------------------- a step */

/* Copies the slices of job jb (timesteps t..t+len-1) from the ring of the
 * pass's box into samples: slice g of the group at samples + g * len *
 * w*h, time-major.  The box holds the slices whole. */
static void gather(const struct tvpal_engine *e, const struct slicejob *jb,
                   uint32_t t, float *samples)
{
    const struct encode_box *b = &e->pass->box;
    const size_t bx = b->n[0], by = b->n[1], bz = b->n[2];
    const unsigned axis = jb->sj->axis;
    const size_t sv = (size_t)jb->sj->h.slice_w * jb->sj->h.slice_h;
    const uint32_t s0 = jb->slice - b->lo[axis], len = jb->len,
                   stride = jb->stride;
    for (uint32_t j = 0; j < len; j++) {
        const float *vol = e->ring[(t + j) % e->nring];
        float *out = samples + (size_t)j * sv;
        if (axis == 0) {
            for (size_t z = 0; z < bz; z++)
                for (size_t y = 0; y < by; y++) {
                    const float *row = vol + bx * (y + by * z) + s0;
                    float *dst = out + y + by * z;
                    for (uint32_t g = 0; g < jb->count; g++)
                        dst[(size_t)g * len * sv] = row[(size_t)g * stride];
                }
            continue;
        }
        for (uint32_t g = 0; g < jb->count; g++) {
            const size_t s = s0 + (size_t)g * stride;
            float *dst = out + (size_t)g * len * sv;
            if (axis == 1)
                for (size_t z = 0; z < bz; z++)
                    memcpy(dst + bx * z, vol + bx * (s + by * z),
                           bx * sizeof *out);
            else
                memcpy(dst, vol + bx * by * s, bx * by * sizeof *out);
        }
    }
}

/* --table auto's criterion (FORMAT.md 6.7).  A 16-bit entry is off by up
 * to half a step, (max - min) / steps of its table, adding about step^2 /
 * 12 to the squared error of every voxel that holds it.  That is
 * negligible where it stays within TABLE_U16_BUDGET of the slice-window's
 * own coding error: SSE16 - SSE32 <= 1e-4 SSE32, both summed over the
 * voxels and timesteps with a value, so no window's error grows by more
 * than 1e-4 of itself and the PSNR of the whole dataset drops by less than
 * 10 log10(1 + 1e-4) = 0.0005 dB.  The error is measured, not bounded
 * (table_fit below).  So float32 stays where 16 bits are coarse against
 * the coding error: a wide range (one outlier widens every step of its
 * window), and an exact window (SSE32 = 0: integer data with few distinct
 * values, whose float32 table holds them exactly) unless the 16-bit table
 * decodes what its voxels hold exactly too.
 *
 * Within the same budget the table takes the coarsest step that fits:
 * steps = 2^k - 1, TABLE_MIN_BITS <= k <= 16, searched from a guess
 * (store_table_auto).  The entries are means of thousands of voxels, and
 * 16 bits of them are mostly noise below the coding error: on the viscous
 * fingers series k = 10-12 fits, and the coded table shrinks by a third
 * (FORMAT.md 6.11 codes its deltas).  A decoder sees only tmin and tscale,
 * as always. */
#define TABLE_U16_BUDGET 1e-4
#define TABLE_MIN_BITS 4

static void table_fit_measure(struct table_fit *f, const float *samples,
                              const uint8_t *idx, size_t nvox, uint32_t len,
                              const float *t32)
{
    const size_t n = (size_t)len * TVPAL_TABLE_ENTRIES;
    memset(f->resid, 0, n * sizeof *f->resid);
    memset(f->count, 0, sizeof f->count);
    f->sse32 = 0;
    for (size_t v = 0; v < nvox; v++)
        f->count[idx[v]]++;
    for (uint32_t j = 0; j < len; j++) {
        const float *x = samples + (size_t)j * nvox;
        const float *a = t32 + (size_t)j * TVPAL_TABLE_ENTRIES;
        double *r = f->resid + (size_t)j * TVPAL_TABLE_ENTRIES;
        uint32_t *h = f->held + (size_t)j * TVPAL_TABLE_ENTRIES;
        /* held starts at count; a missing value (NaN sample or entry)
         * has no error and leaves it (rare: no increment per voxel). */
        for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++)
            h[i] = f->count[i];
        double sse = 0;
        for (size_t v = 0; v < nvox; v++) {
            const double e = (double)x[v] - a[idx[v]];
            if (e == e) {
                sse += e * e;
                r[idx[v]] += e;
            } else {
                h[idx[v]]--;
            }
        }
        f->sse32 += sse;
    }
}

/* Whether t, the values a 16-bit table decodes to, errs within the budget
 * of t32's error (the fit's). */
static int table_fit_within(const struct table_fit *f, uint32_t len,
                            const float *t32, const float *t)
{
    double added = 0;
    for (size_t e = 0; e < (size_t)len * TVPAL_TABLE_ENTRIES; e++) {
        if (!f->held[e])
            continue;
        const double d = (double)t32[e] - t[e];
        added += f->held[e] * d * d + 2 * d * f->resid[e];
    }
    return added <= TABLE_U16_BUDGET * f->sse32;
}

/* Gives the entries of indices no voxel of the window holds (decoded by
 * none) the value their deltas code in nothing (FORMAT.md 6.11): in row 0
 * the entry to their left (the first held index's for index 0), in later
 * rows the row above.  The encoder filled them with inverse transforms
 * (6.7), which cost as much to store as any entry.  They stay within the
 * range of the held entries, so they cannot widen a 16-bit step. */
static void table_fill_unheld(const struct table_fit *f, uint32_t len,
                              float *table)
{
    unsigned first = 0;
    while (first < TVPAL_TABLE_ENTRIES && !f->count[first])
        first++;
    if (first == TVPAL_TABLE_ENTRIES)
        return;
    for (unsigned i = 0; i < TVPAL_TABLE_ENTRIES; i++) {
        if (f->count[i])
            continue;
        table[i] = i ? table[i - 1] : table[first];
        for (uint32_t j = 1; j < len; j++)
            table[j * TVPAL_TABLE_ENTRIES + i] =
                table[(j - 1) * TVPAL_TABLE_ENTRIES + i];
    }
}

/* Stores the table in 16 bits over `steps` steps at dst (header h) and
 * decodes it into dec; returns whether it errs within the budget. */
static int table_try_u16(const struct table_fit *f, const float *table,
                         uint32_t len, uint32_t steps, float *dec,
                         unsigned char *dst, struct tvpal_chunk_header *h)
{
    tvpal_table_store_steps(table, len, TVPAL_TABLE_U16, steps, dst, h);
    const struct tvpal_chunk c = {
        .h = *h, .table = dst,
        .table_format = TVPAL_TABLE_U16 | ((h->flags & TVPAL_CHUNK_MISSING)
                                               ? TVPAL_TABLE_MISSING : 0u)};
    tvpal_chunk_table(&c, dec);
    return table_fit_within(f, len, table, dec);
}

/* The steps of a 16-bit table of k bits: 2^k - 1, and 0 (the most) for
 * 16. */
static uint32_t table_steps(unsigned k)
{
    return k >= 16 ? 0 : (1u << k) - 1;
}

/* Where the search for the table's bits starts: rounding to a step D adds
 * about D^2 / 12 per voxel-step with a value, so the budget allows D up
 * to sqrt(12 budget SSE32 / n) over the table's range.  A guess only:
 * table_try_u16 measures each step tried. */
static unsigned table_bits_guess(const struct table_fit *f,
                                 const float *table, uint32_t len)
{
    const size_t entries = (size_t)len * TVPAL_TABLE_ENTRIES;
    double n = 0;
    for (size_t e = 0; e < entries; e++)
        n += f->held[e];
    float lo, hi;
    (void)tvpal_table_range(table, entries, &lo, &hi);
    if (!(n > 0) || !(f->sse32 > 0) || !(hi > lo))
        return 16;
    const double d = sqrt(12 * TABLE_U16_BUDGET * f->sse32 / n);
    const double steps = ((double)hi - lo) / d;
    unsigned k = TABLE_MIN_BITS;
    while (k < 16 && (double)((1u << k) - 1) < steps)
        k++;
    return k;
}

/* --table auto: stores the table of a coded slice-window at dst, its
 * unheld entries filled (table_fill_unheld), as 16-bit over the fewest
 * steps within the budget, setting TVPAL_CHUNK_U16 in h->flags, or as
 * float32 when even 65535 steps err too much; returns the chunk's format
 * (TVPAL_TABLE_U16 or TVPAL_TABLE_F32).  dec: len * 256 floats of
 * scratch.  dst has a float32 table's room, before the indices. */
static uint32_t store_table_auto(struct table_fit *f, float *table,
                                 float *dec, const float *samples,
                                 const uint8_t *idx, size_t nvox,
                                 uint32_t len, unsigned char *dst,
                                 struct tvpal_chunk_header *h)
{
    table_fit_measure(f, samples, idx, nvox, len, table);
    table_fill_unheld(f, len, table);
    if (!table_try_u16(f, table, len, 0, dec, dst, h)) {
        tvpal_table_store(table, len, TVPAL_TABLE_F32, dst, h);
        return TVPAL_TABLE_F32;
    }
    /* From the guess, down while the next coarser fits, or up until one
     * fits (16 bits, the most steps, has: the try above).  last: the bits
     * of the table in dst. */
    unsigned k = table_bits_guess(f, table, len), last = 16;
    if (k == 16 || table_try_u16(f, table, len, table_steps(last = k), dec,
                                 dst, h)) {
        while (k > TABLE_MIN_BITS &&
               table_try_u16(f, table, len, table_steps(last = k - 1), dec,
                             dst, h))
            k--;
    } else {
        while (++k < 16 &&
               !table_try_u16(f, table, len, table_steps(last = k), dec,
                              dst, h))
            ;
    }
    if (last != k)
        (void)table_try_u16(f, table, len, table_steps(k), dec, dst, h);
    h->flags |= TVPAL_CHUNK_U16;
    return TVPAL_TABLE_U16;
}

/* Encodes one slice-window from samples into the chunk buffer: a chunk of
 * the shard's table format, or in a per-chunk shard (--table auto) one of
 * the format store_table_auto picks, in a float32 chunk's room (the rest
 * zeros: tvpal_shardw_put_chunk).  table: 2 * len * 256 floats of
 * scratch; fit: --table auto's. */
static void encode_chunk(struct tvpal_swenc *enc, struct table_fit *fit,
                         float *table, const float *samples,
                         const struct tvpal_shard_header *sh,
                         uint32_t slice, uint32_t t, uint32_t len,
                         unsigned char *chunk, uint64_t *dropped)
{
    const size_t nvox = (size_t)sh->slice_w * sh->slice_h;
    const uint32_t tf = sh->table_format;
    unsigned char *const dst = chunk + TVPAL_CHUNK_HEADER_BYTES;
    /* The indices follow a table of the shard's entry size (a float32
     * one's in a per-chunk shard: moved down for a 16-bit table). */
    uint8_t *idx = dst + (size_t)len * 256 * tvpal_table_entry_bytes(tf);
    struct tvpal_swinfo info;
    tvpal_swenc_encode(enc, samples, nvox, len, idx, table, &info);
    *dropped += info.dropped;
    struct tvpal_chunk_header ch = {
        .slice = slice, .wstart = t, .wlen = len, .w = sh->slice_w,
        .h = sh->slice_h, .used = info.used};
    uint32_t ctf = tf;
    if (tf == TVPAL_TABLE_CHUNK) {
        ctf = store_table_auto(fit, table, table + (size_t)len * 256,
                               samples, idx, nvox, len, dst, &ch);
        uint8_t *to = dst + (size_t)len * 256 * tvpal_table_entry_bytes(ctf);
        memmove(to, idx, nvox);
        idx = to;
    } else {
        tvpal_table_store(table, len, tf, dst, &ch);
    }
    memcpy(ch.bits, info.bits, sizeof ch.bits);
    tvpal_chunk_header_encode(&ch, chunk);
    /* Zero the index padding (and a 16-bit chunk's unused room) so output
     * bytes are deterministic. */
    unsigned char *end = idx + nvox;
    size_t cb = tvpal_chunk_bytes(len, sh->slice_w, sh->slice_h, tf);
    memset(end, 0, (size_t)(chunk + cb - end));
}

/* Codes thread tid's chunk (e->chunkbuf, in a room of cb bytes) with
 * zstd where that makes it smaller: the coded chunk, zeros after it, then
 * takes the buffer's place (a swap).  0, or the coder's error. */
static int code_chunk(struct tvpal_engine *e, unsigned tid,
                      const struct tvpal_shard_header *sh, uint64_t cb)
{
    struct tvpal_chunk_header ch;
    (void)tvpal_chunk_header_decode(e->chunkbuf[tid], &ch, NULL);
    uint64_t stored = 0;
    int rc = tvpal_chunkz_code(e->z[tid], e->p.index_level, e->chunkbuf[tid],
                               tvpal_chunk_table_format(sh->table_format,
                                                        ch.flags),
                               e->codedbuf[tid], &stored);
    if (rc <= 0)
        return rc;
    memset(e->codedbuf[tid] + stored, 0, (size_t)(cb - stored));
    unsigned char *b = e->chunkbuf[tid];
    e->chunkbuf[tid] = e->codedbuf[tid];
    e->codedbuf[tid] = b;
    return 0;
}

/* Lists the slice-windows of the pass that start at step t, shard by
 * shard in slice order (the order their CRCs join), into e->jobs (x slices
 * grouped).  Returns the number of jobs. */
static size_t plan_step(struct tvpal_engine *e, uint32_t t)
{
    const uint32_t N = e->p.window;
    const struct encode_pass *ps = e->pass;
    struct slicejob *jobs = e->jobs;
    size_t njobs = 0, chunks = 0;
    for (uint32_t q = 0; q < e->nshard; q++) {
        struct tvpal_engine_shard *j = &e->sj[q];
        const unsigned a = j->axis;
        const struct tvpal_schedule sc = tvpal_shard_schedule(&j->h);
        if (!(ps->axes & (1u << a)))
            continue;
        const size_t sv = (size_t)j->h.slice_w * j->h.slice_h;
        uint32_t lo = j->h.slice_begin, hi = lo + j->h.slice_count;
        lo = lo > ps->s0[a] ? lo : ps->s0[a];
        hi = hi < ps->s1[a] ? hi : ps->s1[a];
        for (uint32_t s = lo; s < hi; s++) {
            if (!tvpal_schedule_starts(&sc, s, t))
                continue;
            uint32_t len = tvpal_schedule_len(&sc, s, t);
            if (sc.G > 1) {
                /* The group's slices in the slab and the pass. */
                uint32_t end = (s / sc.G + 1) * sc.G;
                end = end < hi ? end : hi;
                jobs[njobs++] = (struct slicejob){
                    .sj = j, .slice = s, .count = end - s, .stride = 1,
                    .len = len, .crc_at = chunks, .shared = end - s > 1};
                chunks += end - s;
                s = end - 1;
                continue;
            }
            struct slicejob *prev = njobs ? &jobs[njobs - 1] : NULL;
            /* Extend the previous x group when this slice is the next of
             * its phase, in the same line, with the same window, and the
             * group's samples stay within the workspace. */
            if (a == 0 && prev && prev->sj == j && prev->len == len &&
                s == prev->slice + prev->count * N &&
                s / GROUP_SPAN == prev->slice / GROUP_SPAN &&
                (uint64_t)(prev->count + 1) * len * sv <= e->group_cap)
                prev->count++;
            else
                jobs[njobs++] = (struct slicejob){
                    .sj = j, .slice = s, .count = 1, .stride = N, .len = len,
                    .crc_at = chunks};
            chunks++;
        }
    }
    return njobs;
}

/* One step's encoding, shared by the pool's threads (encode_job). */
struct step_ctx {
    struct tvpal_engine *e;
    uint32_t t;
    int failed;                     /* atomic: the first failure claims it */
    int fail_rc;
    struct tvpal_diag fail_d;       /* written by that thread only */
    uint32_t fail_q;
};

/* Records the first failure of the step (c->fail_*). */
static void step_failed(struct step_ctx *c, int rc,
                        const struct tvpal_diag *d,
                        const struct tvpal_engine_shard *j)
{
    if (!__atomic_exchange_n(&c->failed, 1, __ATOMIC_RELAXED)) {
        c->fail_rc = rc;
        c->fail_d = *d;
        c->fail_q = (uint32_t)(j - c->e->sj);
    }
}

/* Codes slice-window samples (header sh: a group's as one slice of
 * k * slice_h rows) into thread tid's chunk buffer, in a room of cb bytes
 * (zeros after the chunk), with zstd where that pays.  0 or the coder's
 * error. */
static int code_window(struct tvpal_engine *e, unsigned tid,
                       const float *samples,
                       const struct tvpal_shard_header *sh, uint32_t slice,
                       uint32_t t, uint32_t len, uint64_t cb)
{
    unsigned char *chunk = e->chunkbuf[tid];
    encode_chunk(e->enc[tid], e->fit[tid], e->tables[tid], samples, sh, slice,
                 t, len, chunk, &e->dropped[tid]);
    const uint64_t own = tvpal_chunk_bytes(len, sh->slice_w, sh->slice_h,
                                           sh->table_format);
    memset(chunk + own, 0, (size_t)(cb - own));
    return e->p.index_level ? code_chunk(e, tid, sh, cb) : 0;
}

/* Codes one chunk of job jb (code_window: slice-window samples under
 * header sh, from slice, in a room of cb bytes) and writes it in place,
 * its CRC to *crc; a failure is the step's (step_failed). */
static void write_window(struct step_ctx *c, unsigned tid,
                         const struct slicejob *jb, const float *samples,
                         const struct tvpal_shard_header *sh, uint32_t slice,
                         uint64_t cb, uint32_t *crc)
{
    struct tvpal_engine *e = c->e;
    struct tvpal_diag d = {{0}};
    int rc = code_window(e, tid, samples, sh, slice, c->t, jb->len, cb);
    if (rc == 0)
        rc = tvpal_shardw_put_chunk(jb->sj->w, c->t, slice, e->chunkbuf[tid],
                                    cb, crc, &d);
    else
        tvpal_diag_set(&d, rc, "coding the chunk of slices %u..%u, step %u",
                       slice, slice + (sh->slice_h / jb->sj->h.slice_h) - 1,
                       c->t);
    if (rc < 0)
        step_failed(c, rc, &d, jb->sj);
}

/* A palette group's slices, gathered in samples (slice g at g len w h),
 * as one slice of k h rows, time-major, into gs. */
static void group_samples(const struct slicejob *jb, const float *in,
                          float *gs)
{
    const size_t sv = (size_t)jb->sj->h.slice_w * jb->sj->h.slice_h;
    for (uint32_t jt = 0; jt < jb->len; jt++)
        for (uint32_t g = 0; g < jb->count; g++)
            memcpy(gs + ((size_t)jt * jb->count + g) * sv,
                   in + ((size_t)g * jb->len + jt) * sv, sv * sizeof *gs);
}

/* The header of a chunk of a group's k slices: k slice_h rows. */
static struct tvpal_shard_header group_header(const struct slicejob *jb)
{
    struct tvpal_shard_header gh = jb->sj->h;
    gh.slice_h *= jb->count;
    return gh;
}

/* Job i of the step: gathers its slices, encodes each slice-window (a
 * palette group's as one, under one table) and writes its chunks in
 * place.  Thread 0 (the caller's) ticks between jobs, so a progress line
 * comes within a long step too. */
static void encode_job(void *arg, size_t i, unsigned tid)
{
    struct step_ctx *c = arg;
    struct tvpal_engine *e = c->e;
    const uint32_t t = c->t;
    const struct slicejob *jb = &e->jobs[i];
    const struct tvpal_engine_shard *j = jb->sj;
    const size_t sv = (size_t)j->h.slice_w * j->h.slice_h;
    const uint64_t cb = tvpal_chunk_bytes(jb->len, j->h.slice_w,
                                          j->h.slice_h, j->h.table_format);
    gather(e, jb, t, e->samples[tid]);
    if (jb->shared) {
        const struct tvpal_shard_header gh = group_header(jb);
        group_samples(jb, e->samples[tid], e->gsamples[tid]);
        write_window(c, tid, jb, e->gsamples[tid], &gh, jb->slice,
                     jb->count * cb, &e->jcrc[jb->crc_at]);
    }
    for (uint32_t g = 0; !jb->shared && g < jb->count; g++)
        write_window(c, tid, jb, e->samples[tid] + (size_t)g * jb->len * sv,
                     &j->h, jb->slice + g * jb->stride, cb,
                     &e->jcrc[jb->crc_at + g]);
    if (e->work)
        __atomic_add_fetch(e->work, (uint64_t)sv * jb->len * jb->count,
                           __ATOMIC_RELAXED);
    if (tid == 0 && e->tick)
        e->tick(e->tick_ctx);
}

int tvpal_engine_encode_step(struct tvpal_engine *e, uint32_t t,
                             struct tvpal_diag *diag, uint32_t *fail_shard)
{
    if (!e->ring || !e->pass || t >= e->p.steps)
        return TVPAL_E_INVAL;
    struct step_ctx c = {.e = e, .t = t};
    const size_t njobs = plan_step(e, t);
    tvpal_pool_for(e->pool, njobs, encode_job, &c);
    if (c.failed) {
        if (fail_shard)
            *fail_shard = c.fail_q;
        return tvpal_diag_set(diag, c.fail_rc, "%s", c.fail_d.msg);
    }
    for (size_t i = 0; i < njobs; i++) {
        const struct slicejob *jb = &e->jobs[i];
        const uint32_t nchunks = jb->shared ? 1 : jb->count,
                       slices = jb->shared ? jb->count : 1;
        for (uint32_t g = 0; g < nchunks; g++)
            if (tvpal_shardw_extend(jb->sj->w, t, jb->slice + g * jb->stride,
                                    slices, e->jcrc[jb->crc_at + g]) < 0)
                return tvpal_diag_set(diag, TVPAL_E_INVAL, "chunk of slice "
                                      "%u, step %u out of order",
                                      jb->slice + g * jb->stride, t);
    }
    return 0;
}

/* The squared error of samples (len steps of nvox) against their decoder
 * table (len x 256 floats) through idx, over the values present (a
 * missing sample or entry has none). */
static double window_sse(const float *samples, const float *table,
                         const uint8_t *idx, size_t nvox, uint32_t len,
                         uint64_t *present)
{
    double sse = 0;
    uint64_t n = 0;
    for (uint32_t j = 0; j < len; j++) {
        const float *x = samples + (size_t)j * nvox;
        const float *t = table + (size_t)j * TVPAL_TABLE_ENTRIES;
        for (size_t v = 0; v < nvox; v++) {
            const double d = (double)x[v] - t[idx[v]];
            if (d == d) { /* neither is NaN */
                sse += d * d;
                n++;
            }
        }
    }
    *present = n;
    return sse;
}

int tvpal_engine_price(struct tvpal_engine *e, unsigned tid,
                       const float *samples, uint32_t k, uint32_t len,
                       uint64_t *bytes, double *sse, uint64_t *present)
{
    const struct tvpal_shard_header *sh = &e->sj[0].h;
    struct tvpal_shard_header gh = *sh;
    gh.slice_h *= k;
    const size_t nvox = (size_t)gh.slice_w * gh.slice_h;
    if (tid >= e->nthreads || !k || !len || nvox > e->max_slice_vox ||
        len > tvpal_engine_span(&e->p))
        return TVPAL_E_INVAL;
    const uint64_t cb = tvpal_chunk_bytes(len, gh.slice_w, gh.slice_h,
                                          gh.table_format);
    uint64_t dropped = 0;
    unsigned char *chunk = e->chunkbuf[tid];
    encode_chunk(e->enc[tid], e->fit[tid], e->tables[tid], samples, &gh, 0, 0,
                 len, chunk, &dropped);
    struct tvpal_chunk_header ch;
    (void)tvpal_chunk_header_decode(chunk, &ch, NULL);
    const uint32_t ctf = tvpal_chunk_table_format(gh.table_format, ch.flags);
    const uint8_t *idx = chunk + TVPAL_CHUNK_HEADER_BYTES +
                         (size_t)len * 256 * tvpal_table_entry_bytes(ctf);
    *sse = window_sse(samples, e->tables[tid], idx, nvox, len, present);
    int rc = e->p.index_level ? code_chunk(e, tid, &gh, cb) : 0;
    if (rc < 0)
        return rc;
    (void)tvpal_chunk_header_decode(e->chunkbuf[tid], &ch, NULL);
    *bytes = tvpal_chunk_stored_bytes(&ch, ctf);
    return 0;
}

int tvpal_engine_progress_alloc(const struct tvpal_engine *e,
                                struct tvpal_checkpoint_progress *pr)
{
    const size_t n = (size_t)e->nshard * e->p.steps;
    *pr = (struct tvpal_checkpoint_progress){
        e->nshard, e->p.steps, calloc(n, sizeof *pr->filled),
        calloc(n, sizeof *pr->crc), calloc(e->nshard, sizeof *pr->missing)};
    if (pr->filled && pr->crc && pr->missing)
        return 0;
    tvpal_checkpoint_progress_free(pr);
    return TVPAL_E_NOMEM;
}

void tvpal_engine_progress_get(const struct tvpal_engine *e,
                               struct tvpal_checkpoint_progress *pr)
{
    const uint32_t T = e->p.steps;
    for (uint32_t q = 0; q < e->nshard; q++) {
        const struct tvpal_shardw *w = e->sj[q].w;
        for (uint32_t t = 0; t < T; t++)
            tvpal_shardw_progress(w, t, &pr->filled[(size_t)q * T + t],
                                  &pr->crc[(size_t)q * T + t]);
        pr->missing[q] = (uint8_t)tvpal_shardw_missing(w);
    }
}

int tvpal_engine_progress_restore(struct tvpal_engine *e, uint32_t q,
                                  const struct tvpal_checkpoint_progress *pr,
                                  struct tvpal_diag *diag)
{
    const uint32_t T = e->p.steps;
    struct tvpal_shardw *w = e->sj[q].w;
    for (uint32_t t = 0; t < T; t++) {
        const size_t i = (size_t)q * T + t;
        int rc = pr->filled[i] ? tvpal_shardw_set_progress(w, t, pr->filled[i],
                                                            pr->crc[i], diag)
                               : 0;
        if (rc < 0)
            return rc;
    }
    tvpal_shardw_set_missing(w, pr->missing[q]);
    return 0;
}
