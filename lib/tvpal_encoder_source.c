/* tvpal_encoder_source.c: tvpal_encoder_encode, an encode that reads its
 * steps from the caller's source, in passes under the memory limit.
 *
 * The plan (encode_plan.h) is made from the sizes alone before anything is
 * read: one pass over the whole volume when N steps of it and the
 * workspaces fit the limit, else passes over slabs of each axis's slices.
 * Each pass streams every step of its box through the engine's ring of N
 * boxes: step t + N - 1 is read when the windows starting at t are coded.
 * A unit of work is one step of one pass (u = p T + t + 1 once done); the
 * checkpoint names the units done, the statistics of the steps counted so
 * far (only the "stats" passes count, whose boxes partition the volume
 * once) and the shards' progress, so that an encode of the same job and
 * source identity continues after the last one saved.
 *
 * A concurrent source is read by the encoder's threads in pieces of whole
 * rows of one plane (at most READ_BLOCK bytes each, into the thread's
 * scratch), converted into the ring as they come; any other source is read
 * a box at a time on a reader thread, which reads the next step while this
 * one is converted and encoded.
 *
 * Levels (TVPAL_PARAM_LEVELS): with a plan of one pass, every step read
 * also makes the step of each level (tvpal_levels.h) and goes to the
 * level's encoder at once, and the levels' checkpoints are saved with
 * level 0's (so a resume finds them at its unit); otherwise the levels
 * are made after level 0, from the source read again in slabs of planes,
 * and a resume makes them again (they are 1/7 of the work).
 */
#define _GNU_SOURCE
#include "tvpal_encoder_impl.h"

#include "tvpal_clock.h"
#include "tvpal_fs.h"
#include "tvpal_groupauto.h"
#include "tvpal_levels.h"
#include "tvpal_passes.h"
#include "tvpal_pool.h"
#include "tvpal_readahead.h"
#include "tvpal_raw.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct pull {
    struct encode_plan plan;
    int levels_inline;
    uint64_t units, start;   /* passes * T; the unit resumed after */
    const struct encode_pass *pass;
    unsigned nthreads;
    size_t esize;            /* bytes of a source value */
    size_t rows;             /* a concurrent read's rows per piece */
    unsigned char **scratch; /* per thread (concurrent), READ_BLOCK */
    int *rc;                 /* per thread: a failed read's code, */
    struct tvpal_diag *diag; /* and its words */
    struct tvpal_readahead *rd; /* not concurrent: the reader thread */
    void *box;               /* not concurrent: the box as read */
    struct tvpal_progress pr;
    uint64_t work;           /* added to atomically by the engine */
    double last_tick;
    int kept;                /* level 0 is an earlier encode's, kept */
    char *fp0;               /* with levels: level 0's fingerprint, which
                              * DIR.partial/levels.job holds while the
                              * levels are made */
};

/* With levels, DIR.partial/levels.job names the job (level 0's
 * fingerprint: its options, ranks and source identity, not the plan or
 * the levels, which do not change level 0's shards) from the moment level
 * 0 is finished until every level is: an encode of the same job then
 * keeps level 0 and every level complete in DIR.partial, and makes only
 * the others. */
#define LEVELS_MARKER "levels.job"

/* ------------------------------------------------------------------ plan */

/* The steps the ring holds: the longest window's. */
static uint32_t ring_slots(const struct tvpal_encoder *e)
{
    return tvpal_engine_span(&e->ep);
}

static uint64_t scratch_bytes(const struct tvpal_encoder *e)
{
    if (!e->src->concurrent)
        return 0;
    const uint64_t row = (uint64_t)e->ep.dims[0] *
                         tvpal_type_size(tvpal_enc_scalar_type(e->src->type));
    return tvpal_passes_read_rows(row, e->ep.dims[1]) * row;
}

/* Bytes beside the ring and the box buffers (tvpal_passes.h) of e's
 * engine and source with nt threads. */
static uint64_t fixed_bytes(const struct tvpal_encoder *e, unsigned nt)
{
    return tvpal_passes_fixed_bytes(e->eng, nt, scratch_bytes(e),
                                    e->src->held_bytes);
}

/* The plan of e (its engine made) with nt threads into *plan and
 * *levels_inline.  0, TVPAL_E_RANGE (diag: the smallest
 * limit that would do, also in plan->min_limit), TVPAL_E_NOMEM. */
static int make_plan(const struct tvpal_encoder *e, unsigned nt,
                     struct encode_plan *plan, int *levels_inline,
                     struct tvpal_diag *diag)
{
    const uint32_t *d = e->ep.dims;
    const uint64_t limit = e->mem_limit ? e->mem_limit : UINT64_MAX >> 2;
    const size_t esize = tvpal_type_size(tvpal_enc_scalar_type(e->src->type));
    struct encode_job j = {
        .dims = {d[0], d[1], d[2]}, .N = e->ep.window, .T = e->ep.steps,
        .slab_n = {d[0], d[1], d[2]}, .axes = e->ep.axes, .limit = limit,
        .fixed = fixed_bytes(e, nt),
        .box_bytes_per_voxel = (uint32_t)(4 * ring_slots(e) +
                                          (e->src->concurrent ? 0
                                                              : 2 * esize))};
    for (unsigned a = 0; a < 3; a++)
        j.group[a] = tvpal_engine_group(&e->ep, a);
    /* A rank of a collective encodes its node's slabs of every axis, in
     * passes per axis; rank 0 makes the levels after level 0. */
    const int ranks = e->coll.size > 1;
    j.split = ranks;
    for (unsigned a = 0; ranks && a < 3; a++)
        tvpal_slab_range(d[a], e->ep.nodes, e->ep.node_first, &j.slab_lo[a],
                         &j.slab_n[a]);
    const unsigned levels = e->coll.rank == 0 ? e->levels : 0;
    *levels_inline = 0;
    memset(plan, 0, sizeof *plan);
    if (levels && !ranks) {
        /* The levels beside level 0's one pass, when that fits: each step
         * is then read once. */
        struct encode_job jl = j;
        const uint64_t lb = tvpal_passes_levels_bytes(&e->ep, e->levels, nt,
                                                      0);
        jl.fixed += lb;
        if (lb && encode_plan_make(&jl, plan) == 0 && plan->npasses == 1)
            *levels_inline = 1;
        encode_plan_free(plan);
        if (*levels_inline)
            j = jl;
    }
    int rc = encode_plan_make(&j, plan);
    if (rc == TVPAL_E_RANGE)
        return tvpal_diag_set(diag, rc, "memory limit of %llu bytes is too "
                              "small for %ux%ux%u at window %u with %u "
                              "thread%s: one slice per pass needs %llu%s",
                              (unsigned long long)limit, d[0], d[1], d[2],
                              e->ep.window, nt, nt == 1 ? "" : "s",
                              (unsigned long long)plan->min_limit,
                              j.group[0] > 1 || j.group[1] > 1 ||
                                      j.group[2] > 1
                                  ? " (a palette group's slices together)"
                                  : "");
    if (rc < 0 || !levels || *levels_inline)
        return rc;
    /* After level 0, with its ring freed, the levels are encoded in one
     * pass each; with level 0's fixed bytes they must fit. */
    const uint64_t lb = tvpal_passes_levels_bytes(&e->ep, e->levels, nt,
                                                  plan->box_voxels_max);
    if (!lb)
        return TVPAL_E_NOMEM;
    if (lb + j.fixed > limit) {
        plan->min_limit = lb + j.fixed;
        return tvpal_diag_set(diag, TVPAL_E_RANGE, "memory limit of %llu "
                              "bytes is too small for %u levels: they are "
                              "encoded after level 0, in one pass each, "
                              "together about %llu bytes",
                              (unsigned long long)limit, e->levels,
                              (unsigned long long)plan->min_limit);
    }
    return 0;
}

static unsigned thread_count(const struct tvpal_encoder *e)
{
    return e->threads ? e->threads : tvpal_pool_default_threads();
}

static int check_source(const struct tvpal_encoder *e,
                        const struct tvpal_source *src,
                        struct tvpal_diag *diag)
{
    if (!src || !src->read)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "a source needs its "
                              "read function");
    if (src->type < TVPAL_FLOAT32 || src->type > TVPAL_INT16)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "source type %d: a "
                              "TVPAL_FLOAT32 .. TVPAL_INT16 expected",
                              (int)src->type);
    if (e->state != OPENED)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "an encode from a source "
                              "after a push or another encode");
    return 0;
}

int tvpal_encoder_plan(struct tvpal_encoder *e,
                       const struct tvpal_source *src, struct tvpal_plan *out,
                       struct tvpal_diag *diag)
{
    memset(out, 0, sizeof *out);
    int rc = check_source(e, src, diag);
    if (rc < 0)
        return rc;
    struct tvpal_engine *eng = NULL;
    if ((rc = tvpal_engine_create(&eng, &e->ep)) < 0)
        return tvpal_diag_set(diag, rc, "the encoding parameters");
    /* The encoder's own engine and source only for the plan's sums. */
    e->eng = eng;
    e->src = src;
    struct encode_plan p;
    const unsigned nt = thread_count(e);
    rc = make_plan(e, nt, &p, &out->levels_inline, diag);
    const uint64_t nvox = (uint64_t)e->ep.dims[0] * e->ep.dims[1] *
                          e->ep.dims[2];
    out->ring_bytes = ring_slots(e) * nvox * sizeof(float) +
                      fixed_bytes(e, nt);
    e->eng = NULL;
    e->src = NULL;
    tvpal_engine_free(eng);
    out->min_limit = p.min_limit;
    out->levels_over = rc == TVPAL_E_RANGE && p.npasses > 0;
    if (rc == 0) {
        out->passes = p.npasses;
        memcpy(out->passes_axis, p.per_axis, sizeof out->passes_axis);
        out->peak_bytes = p.peak;
        out->read_voxels = p.voxels_read;
    }
    encode_plan_free(&p);
    return rc;
}

/* A box of the source for the reader thread (tvpal_readahead.h). */
static int read_for_reader(void *ctx, uint32_t t, const struct encode_box *b,
                           void *dst, struct tvpal_diag *d)
{
    const struct tvpal_source *src = ctx;
    return src->read(src->ctx, t, b->lo, b->n, dst, d);
}

/* ------------------------------------------------------------- progress */

/* The progress callback, within a unit: at most every
 * TVPAL_PARAM_PROGRESS seconds. */
static void tick(struct tvpal_encoder *e)
{
    struct pull *pl = e->pull;
    if (!e->src->progress)
        return;
    const double now = tvpal_now();
    if (now - pl->last_tick < e->tick_seconds)
        return;
    pl->last_tick = now;
    pl->pr.work = __atomic_load_n(&pl->work, __ATOMIC_RELAXED);
    pl->pr.unit_end = 0;
    e->src->progress(e->src->ctx, &pl->pr);
}

static void engine_tick(void *ctx)
{
    tick(ctx);
}

/* The work of the units before u (tvpal_passes.h). */
static uint64_t work_before(const struct tvpal_encoder *e, uint64_t u)
{
    return tvpal_passes_work_before(&e->pull->plan, e->ep.dims, e->ep.steps,
                                    u);
}

/* ---------------------------------------------------------------- setup */

int tvpal_enc_source_plan(struct tvpal_encoder *e, unsigned nt,
                          uint64_t *ring_voxels, struct tvpal_diag *diag)
{
    struct pull *pl = calloc(1, sizeof *pl);
    if (!pl)
        return TVPAL_E_NOMEM;
    e->pull = pl;
    pl->nthreads = nt;
    pl->esize = tvpal_type_size(tvpal_enc_scalar_type(e->src->type));
    int rc = make_plan(e, nt, &pl->plan, &pl->levels_inline, diag);
    if (rc < 0)
        return rc;
    pl->units = (uint64_t)pl->plan.npasses * e->ep.steps;
    *ring_voxels = pl->plan.box_voxels_max;
    return 0;
}

/* The job's identity in its checkpoints: the options that make its
 * shards (the schedule said outright, as in tvpal_encoder.c), the plan (a
 * resumed job must find the same passes) and the source's identity. */
static int make_fingerprint(struct tvpal_encoder *e)
{
    const struct tvpal_engine_source src = {
        .type = e->type, .big_endian = e->src->big_endian,
        .nan_as = e->has_nan_as ? &e->nan_as : NULL,
        .missing = e->missing, .nmissing = e->nmissing};
    char opts[1100], key[96], *params = NULL;
    tvpal_engine_options_line(&e->ep, &src, opts, sizeof opts - 64);
    tvpal_enc_groups_said(&e->ep, opts, sizeof opts);
    encode_plan_key(&e->pull->plan, key, sizeof key);
    if (asprintf(&params, "libtvpal source %s schedule=%u %s levels=%u "
                 "rank=%d/%d identity=%s", opts, e->ep.schedule, key,
                 e->levels, e->coll.rank, e->coll.size,
                 e->src->identity) < 0)
        return TVPAL_E_NOMEM;
    int rc = tvpal_checkpoint_fingerprint(params, NULL, 0, 0, &e->fp);
    free(params);
    if (rc == 0 && e->levels) {
        if (asprintf(&params, "libtvpal level 0 %s ranks=%d identity=%s",
                     opts, e->coll.size, e->src->identity) < 0)
            return TVPAL_E_NOMEM;
        rc = tvpal_checkpoint_fingerprint(params, NULL, 0, 0,
                                          &e->pull->fp0);
        free(params);
    }
    return rc;
}

static char *marker_path(const struct tvpal_encoder *e)
{
    char *p = NULL;
    return asprintf(&p, "%s/" LEVELS_MARKER, e->partial) < 0 ? NULL : p;
}

/* Whether DIR.partial holds level 0 of this job, finished (the marker
 * names it), with a manifest that reads: then *m is that manifest. */
static int level0_kept(const struct tvpal_encoder *e, struct tvpal_manifest *m)
{
    char *p = marker_path(e), *mp = NULL, *text = NULL;
    size_t n = 0;
    int kept = 0;
    if (p && tvpal_read_file(p, &text, &n, NULL) == 0 &&
        n == strlen(e->pull->fp0) && !memcmp(text, e->pull->fp0, n) &&
        asprintf(&mp, "%s/manifest.txt", e->partial) >= 0 &&
        tvpal_manifest_load(mp, m, NULL) == 0)
        kept = 1;
    free(text);
    free(mp);
    free(p);
    return kept;
}

/* Resuming: the unit this job's checkpoint has done (0: none that is this
 * job's and consistent), its statistics and its shards' progress. */
static uint64_t load_checkpoint(struct tvpal_encoder *e)
{
    struct pull *pl = e->pull;
    const uint64_t nvox = (uint64_t)e->ep.dims[0] * e->ep.dims[1] *
                          e->ep.dims[2];
    uint64_t done = 0;
    if (tvpal_checkpoint_load(e->ckdir, e->fp, pl->units, e->ep.steps, nvox,
                              &done, &e->st, &e->ckp, NULL) < 0 ||
        done == 0 ||
        e->st.counted != tvpal_passes_counted_at(&pl->plan, e->ep.steps, done,
                                                 e->st.loaded)) {
        tvpal_checkpoint_stats_reset(&e->st);
        return 0;
    }
    return done;
}

/* The levels beyond e->levels that an earlier encode of the job made in
 * DIR.partial go (whole, partial, and the lock beside). */
static void remove_levels_beyond(const struct tvpal_encoder *e)
{
    for (uint32_t k = e->levels + 1; k <= TVPAL_LEVELS_MAX; k++) {
        static const char *const sfx[] = {"", ".partial", ".partial.lock"};
        for (int i = 0; i < 3; i++) {
            char *p = NULL;
            if (asprintf(&p, "%s/level-%u%s", e->partial, k, sfx[i]) < 0)
                continue;
            if (i == 2)
                unlink(p);
            else
                tvpal_rmtree(p);
            free(p);
        }
    }
}

/* One process, with levels and an identity: level 0 finished by an earlier
 * encode of this job (the marker) is kept.  Its manifests are made to
 * name this encode's levels where that one asked for others, whose levels
 * beyond these go; the statistics are the manifest's.  Then nothing of
 * level 0 is read or written again (pl->start: every unit). */
static int keep_level0(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    struct pull *pl = e->pull;
    struct tvpal_manifest m = {0};
    if (!level0_kept(e, &m)) {
        tvpal_manifest_clear(&m);
        return 0;
    }
    pl->pr.levels_before = m.levels;
    m.levels = e->levels;
    e->st.vmin = m.value_min, e->st.vmax = m.value_max;
    e->st.missing = m.missing, e->st.nonfinite = m.nonfinite;
    int rc = tvpal_manifest_format(&m, &e->text);
    tvpal_manifest_clear(&m);
    if (rc < 0)
        return TVPAL_E_NOMEM;
    if (pl->pr.levels_before != e->levels) {
        /* DIR.partial's (rank 0's) and this rank's node directories'. */
        for (uint32_t k = e->coll.rank ? 1 : 0;
             rc == 0 && k <= e->ep.node_count; k++) {
            char *d = k ? tvpal_enc_node_dir(e, e->ep.node_first + k - 1)
                        : strdup(e->partial), *mp = NULL;
            rc = d && asprintf(&mp, "%s/manifest.txt", d) >= 0
                     ? tvpal_write_file_atomic(mp, e->text, strlen(e->text),
                                               diag)
                     : TVPAL_E_NOMEM;
            free(mp);
            free(d);
        }
        if (e->coll.rank == 0)
            remove_levels_beyond(e);
    }
    pl->kept = e->level0_finished = 1;
    pl->start = pl->units;
    return rc;
}

/* This rank's partial output removed (whole in one process, an earlier
 * job's node directories and levels with it, then made again empty; a
 * rank's own node directory under a collective, the others being
 * theirs); `what` says why, in the message. */
static int remove_stale(struct tvpal_encoder *e, const char *what,
                        struct tvpal_diag *diag)
{
    const char *stale = e->coll.size > 1 ? e->ckdir : e->partial;
    int rc = 0;
    if (tvpal_rmtree(stale) < 0 ||
        (e->coll.size == 1 && (rc = tvpal_mkdirs(stale, diag)) < 0))
        return rc < 0 ? rc
                      : tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot remove "
                                       "the partial output %s", stale, what);
    return 0;
}

int tvpal_enc_source_ready(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    struct pull *pl = e->pull;
    const unsigned nt = pl->nthreads;
    if (!(pl->rc = calloc(nt, sizeof *pl->rc)) ||
        !(pl->diag = calloc(nt, sizeof *pl->diag)) ||
        !(pl->scratch = calloc(nt, sizeof *pl->scratch)))
        return TVPAL_E_NOMEM;
    const size_t sb = scratch_bytes(e);
    for (unsigned i = 0; sb && i < nt; i++)
        if (!(pl->scratch[i] = malloc(sb)))
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "the reading "
                                  "scratch of %u threads", nt);
    if (!e->src->concurrent) {
        /* The plan's largest box, or a plane of the levels made after
         * level 0 (levels_after). */
        const uint64_t plane = (uint64_t)e->ep.dims[0] * e->ep.dims[1];
        uint64_t vox = pl->plan.box_voxels_max;
        if (e->levels && !pl->levels_inline && plane > vox)
            vox = plane;
        const size_t box = (size_t)vox * pl->esize;
        if (!(pl->box = malloc(box)) ||
            !(pl->rd = tvpal_readahead_start(read_for_reader,
                                             (void *)e->src, box)))
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "two boxes of %llu "
                                  "bytes for the reader thread",
                                  (unsigned long long)box);
    }
    int rc = 0;
    if (make_fingerprint(e) < 0 ||
        tvpal_engine_progress_alloc(e->eng, &e->ckp) < 0)
        return TVPAL_E_NOMEM;
    if (e->src->identity)
        pl->start = load_checkpoint(e);
    if (!pl->start && e->src->identity && e->levels &&
        (rc = keep_level0(e, diag)) < 0)
        return rc;
    e->done_local = pl->start;
    /* A partial output that is not continued goes (remove_stale). */
    if (!pl->start && e->resuming) {
        pl->pr.started_over = e->coll.size > 1 ? tvpal_exists(e->ckdir)
                                                : e->had_partial;
        return remove_stale(e, "of an earlier job", diag);
    }
    return 0;
}

int tvpal_enc_source_start_over(struct tvpal_encoder *e,
                                struct tvpal_diag *diag)
{
    uint32_t n;
    struct tvpal_engine_shard *sj = tvpal_engine_shards(e->eng, &n);
    for (uint32_t q = 0; q < n; q++) {
        tvpal_shardw_free(sj[q].w);
        sj[q].w = NULL;
    }
    tvpal_checkpoint_stats_reset(&e->st);
    e->pull->start = 0;
    e->pull->pr.started_over = 1;
    return remove_stale(e, "that does not resume", diag);
}

int tvpal_enc_source_levels_inline(const struct tvpal_encoder *e)
{
    return e->pull && e->pull->levels_inline && !e->pull->kept;
}

void tvpal_enc_source_free(struct tvpal_encoder *e)
{
    struct pull *pl = e->pull;
    if (!pl)
        return;
    tvpal_readahead_stop(pl->rd);
    for (unsigned i = 0; pl->scratch && i < pl->nthreads; i++)
        free(pl->scratch[i]);
    free(pl->scratch);
    free(pl->rc);
    free(pl->diag);
    free(pl->box);
    free(pl->fp0);
    encode_plan_free(&pl->plan);
    free(pl);
    e->pull = NULL;
}

/* -------------------------------------------------------------- reading */

/* One box read, shared by the pool's threads; each thread counts into
 * e->found[tid] and keeps its read failure in pl->rc[tid]. */
struct box_job {
    struct tvpal_encoder *e;
    uint32_t t;
    const struct encode_box *b;
    float *dst;
    int stats;
    size_t pieces_per_plane;
};

/* Converts n source values at src into dst, counting them when stats;
 * vox0 is the volume index of the first. */
static void convert(const struct box_job *j, const void *src, size_t n,
                    float *dst, uint64_t vox0, unsigned tid)
{
    struct tvpal_encoder *e = j->e;
    const struct tvpal_values_rules rules = {
        e->missing, e->nmissing, e->has_nan_as ? &e->nan_as : NULL};
    tvpal_values_convert(&rules, src, e->type, e->src->big_endian, n, dst,
                         vox0, j->stats ? e->fine[tid] : NULL,
                         &e->found[tid]);
}

/* Piece p of a concurrent read: rows of one plane, whole, read into the
 * thread's scratch and the box's part of them converted into place. */
static void read_piece(void *arg, size_t p, unsigned tid)
{
    const struct box_job *j = arg;
    struct tvpal_encoder *e = j->e;
    struct pull *pl = e->pull;
    if (pl->rc[tid]) /* this thread already failed: the step is lost */
        return;
    const struct encode_box *b = j->b;
    const size_t nx = e->ep.dims[0], ny = e->ep.dims[1];
    const uint32_t z = b->lo[2] + (uint32_t)(p / j->pieces_per_plane);
    const uint32_t y0 = b->lo[1] + (uint32_t)(p % j->pieces_per_plane *
                                              pl->rows);
    uint32_t yn = b->lo[1] + b->n[1] - y0;
    yn = yn < pl->rows ? yn : (uint32_t)pl->rows;
    const uint32_t lo[3] = {0, y0, z}, n[3] = {(uint32_t)nx, yn, 1};
    unsigned char *buf = pl->scratch[tid];
    int rc = e->src->read(e->src->ctx, j->t, lo, n, buf, &pl->diag[tid]);
    if (rc < 0) {
        pl->rc[tid] = rc;
        return;
    }
    for (uint32_t k = 0; k < yn; k++) {
        const size_t yb = y0 + k - b->lo[1], zb = z - b->lo[2];
        float *out = j->dst + (size_t)b->n[0] * (yb + (size_t)b->n[1] * zb);
        convert(j, buf + (k * nx + b->lo[0]) * pl->esize, b->n[0], out,
                b->lo[0] + nx * (y0 + k + ny * z), tid);
    }
    if (tid == 0) /* the caller's thread: a step of many GiB takes long */
        tick(e);
}

/* Row k of a box read whole (pl->box) converted into place. */
static void convert_row(void *arg, size_t k, unsigned tid)
{
    const struct box_job *j = arg;
    struct tvpal_encoder *e = j->e;
    const struct encode_box *b = j->b;
    const size_t nx = e->ep.dims[0], ny = e->ep.dims[1];
    const size_t y = b->lo[1] + k % b->n[1], z = b->lo[2] + k / b->n[1];
    const size_t at = k * b->n[0];
    convert(j, (const unsigned char *)e->pull->box + at * e->pull->esize,
            b->n[0], j->dst + at, b->lo[0] + nx * (y + ny * z), tid);
}

/* Box b of step t of the source into dst, converted, counted into the
 * statistics when `stats`; `next`: the step to read ahead (-1: none).  A
 * refused value is named by its voxel. */
static int read_box(struct tvpal_encoder *e, uint32_t t, int64_t next,
                    const struct encode_box *b, float *dst, int stats,
                    struct tvpal_diag *diag)
{
    struct pull *pl = e->pull;
    const unsigned nt = pl->nthreads;
    struct box_job j = {.e = e, .t = t, .b = b, .dst = dst, .stats = stats};
    struct tvpal_found all = tvpal_found_empty(e->st.vmin, e->st.vmax);
    for (unsigned i = 0; i < nt; i++) {
        e->found[i] = all;
        pl->rc[i] = 0;
    }
    int rc = 0;
    if (e->src->concurrent) {
        const uint64_t row = (uint64_t)e->ep.dims[0] * pl->esize;
        pl->rows = tvpal_passes_read_rows(row, b->n[1]);
        j.pieces_per_plane = (b->n[1] + pl->rows - 1) / pl->rows;
        tvpal_pool_for(e->pool, j.pieces_per_plane * b->n[2], read_piece, &j);
        for (unsigned i = 0; i < nt && rc == 0; i++)
            if ((rc = pl->rc[i]) < 0 && diag)
                *diag = pl->diag[i];
    } else if ((rc = tvpal_readahead_take(pl->rd, t, next, b, &pl->box,
                                          engine_tick, e, diag)) == 0) {
        tvpal_pool_for(e->pool, (size_t)b->n[1] * b->n[2], convert_row, &j);
    }
    if (rc < 0)
        return rc;
    for (unsigned i = 0; i < nt; i++)
        tvpal_found_merge(&all, &e->found[i]);
    if (all.rc < 0) {
        const uint32_t *d = e->ep.dims;
        const uint64_t x = all.bad % d[0], y = all.bad / d[0] % d[1],
                       z = all.bad / d[0] / d[1];
        return tvpal_diag_set(diag, all.rc, "step %u: %s at voxel "
                              "(%llu,%llu,%llu)", t,
                              all.rc == TVPAL_E_NAN ? "an infinite value"
                                                    : "a value beyond 1e37",
                              (unsigned long long)x, (unsigned long long)y,
                              (unsigned long long)z);
    }
    if (stats) {
        tvpal_values_account(&e->st, e->fine, nt, &all,
                             encode_box_voxels(b));
        e->st.loaded = t + 1;
    }
    return 0;
}

/* ------------------------------------- palette groups (TVPAL_GROUP_AUTO) */

/* The sample reader of tvpal_groupauto: a box read as whole rows of one
 * plane at a time, as the source's contract has it (rows of at most
 * 8 MiB), converted as the encode converts (not counted). */
struct group_read {
    struct tvpal_encoder *e;
    unsigned char *rows;
    size_t nrows;
};

static int read_group_box(void *ctx, uint32_t t, const uint32_t lo[3],
                          const uint32_t n[3], float *dst,
                          struct tvpal_diag *diag)
{
    struct group_read *g = ctx;
    struct tvpal_encoder *e = g->e;
    const struct tvpal_values_rules rules = {
        e->missing, e->nmissing, e->has_nan_as ? &e->nan_as : NULL};
    const size_t nx = e->ep.dims[0], ny = e->ep.dims[1];
    const size_t esize = tvpal_type_size(e->type);
    for (uint32_t z = lo[2]; z < lo[2] + n[2]; z++)
        for (uint32_t y0 = lo[1]; y0 < lo[1] + n[1];) {
            uint32_t yn = lo[1] + n[1] - y0;
            yn = yn < g->nrows ? yn : (uint32_t)g->nrows;
            const uint32_t rlo[3] = {0, y0, z}, rn[3] = {(uint32_t)nx, yn, 1};
            int rc = e->src->read(e->src->ctx, t, rlo, rn, g->rows, diag);
            if (rc < 0)
                return rc;
            for (uint32_t k = 0; k < yn; k++) {
                const size_t yb = y0 + k - lo[1], zb = z - lo[2];
                struct tvpal_found f = tvpal_found_empty(0, 0);
                tvpal_values_convert(&rules, g->rows + (k * nx + lo[0]) * esize,
                                     e->type, e->src->big_endian, n[0],
                                     dst + n[0] * (yb + (size_t)n[1] * zb),
                                     lo[0] + nx * (y0 + k + ny * z), NULL, &f);
            }
            y0 += yn;
        }
    return 0;
}

int tvpal_enc_source_groups(struct tvpal_encoder *e, uint32_t G[3],
                            struct tvpal_diag *diag)
{
    const size_t row = (size_t)e->ep.dims[0] * tvpal_type_size(e->type);
    struct group_read g = {.e = e,
                           .nrows = tvpal_passes_read_rows(row,
                                                           e->ep.dims[1])};
    const struct tvpal_groupauto_reader rd = {read_group_box, &g};
    struct tvpal_pool *pool = NULL;
    int rc = tvpal_pool_create(&pool, thread_count(e));
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "cannot start %u threads",
                              thread_count(e));
    if (!(g.rows = malloc(g.nrows * row)))
        rc = tvpal_diag_set(diag, TVPAL_E_NOMEM, "the group sample's rows");
    for (unsigned a = 0; a < 3; a++) {
        G[a] = 1;
        if (rc == 0 && (e->ep.axes & TVPAL_AXIS_BIT(a)))
            rc = tvpal_groupauto_choose(&e->ep, a, e->mem_limit, pool, &rd,
                                        &G[a], NULL, diag);
    }
    free(g.rows);
    tvpal_pool_free(pool);
    return rc;
}

/* ------------------------------------------------------------- encoding */

/* Step t of the current pass into its ring slot, and with inline levels
 * into every level. */
static int load_step(struct tvpal_encoder *e, uint32_t t,
                     struct tvpal_diag *diag)
{
    struct pull *pl = e->pull;
    const struct encode_pass *ps = pl->pass;
    float *slot = tvpal_engine_slot(e->eng, t);
    pl->pr.step = t;
    const int64_t next = t + 1 < e->ep.steps ? (int64_t)t + 1 : -1;
    int rc = read_box(e, t, next, &ps->box, slot,
                      ps->stats && t >= e->st.loaded, diag);
    if (rc == 0 && pl->levels_inline) {
        tvpal_level_make(slot, e->ep.dims, e->lvol[1]);
        rc = tvpal_enc_push_levels(e, t, diag);
    }
    return rc;
}

/* Saves the checkpoint after unit u; with inline levels theirs first, at
 * the same step, so that a resume finds them there. */
static int save_unit(struct tvpal_encoder *e, uint64_t u,
                     struct tvpal_diag *diag)
{
    for (uint32_t k = 1; e->pull->levels_inline && k <= e->levels; k++) {
        struct tvpal_encoder *c = e->lv[k];
        int rc = tvpal_enc_save_checkpoint(c, c->encoded, diag);
        if (rc < 0)
            return rc;
    }
    return tvpal_enc_save_checkpoint(e, u, diag);
}

/* The end of unit u: the caller's answer, then the checkpoint when due or
 * asked for.  0, or TVPAL_E_CANCELED (asked to stop), or a save's code. */
static int end_unit(struct tvpal_encoder *e, uint64_t u,
                    struct tvpal_diag *diag)
{
    struct pull *pl = e->pull;
    int answer = TVPAL_GO_ON;
    pl->pr.unit = u;
    pl->pr.work = __atomic_load_n(&pl->work, __ATOMIC_RELAXED);
    pl->pr.unit_end = 1;
    if (e->src->progress)
        answer = e->src->progress(e->src->ctx, &pl->pr);
    const int due = e->ckpt_every && (u % e->ckpt_every == 0 ||
                                      u == pl->units);
    int rc = 0;
    if (answer != TVPAL_STOP &&
        (due || answer == TVPAL_SAVE_AND_GO_ON ||
         answer == TVPAL_SAVE_AND_STOP))
        rc = save_unit(e, u, diag);
    if (rc == 0 && (answer == TVPAL_STOP || answer == TVPAL_SAVE_AND_STOP))
        rc = tvpal_diag_set(diag, TVPAL_E_CANCELED, "stopped after %llu of "
                            "%llu steps of passes%s",
                            (unsigned long long)u,
                            (unsigned long long)pl->units,
                            answer == TVPAL_STOP ? "" : " (checkpoint saved)");
    return rc;
}

/* Encodes step t of the pass; a write error names the shard. */
static int encode_step(struct tvpal_encoder *e, uint32_t t,
                       struct tvpal_diag *diag)
{
    struct tvpal_diag d = {{0}};
    uint32_t q = 0, n;
    int rc = tvpal_engine_encode_step(e->eng, t, &d, &q);
    if (rc < 0) {
        struct tvpal_engine_shard *sj = tvpal_engine_shards(e->eng, &n);
        char *nd = tvpal_enc_node_dir(e, sj[q].rank);
        rc = tvpal_diag_set(diag, rc, "%s/axis-%c.tvps: %s",
                            nd ? nd : e->partial, "xyz"[sj[q].axis], d.msg);
        free(nd);
    }
    return rc;
}

/* Every pass of the plan, from the unit after pl->start: each step read
 * when the windows that need it are next (step t + L - 1 at most, L the
 * longest window: tvpal_engine_span), each
 * step's windows encoded, each unit ended (progress, checkpoint). */
static int encode_passes(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    struct pull *pl = e->pull;
    const uint32_t T = e->ep.steps, L = tvpal_engine_span(&e->ep);
    uint64_t u = pl->start;
    for (uint32_t pi = (uint32_t)(u / T); pi < pl->plan.npasses; pi++) {
        pl->pass = &pl->plan.pass[pi];
        pl->pr.pass = pi;
        tvpal_engine_set_pass(e->eng, pl->pass);
        uint32_t loaded = (uint32_t)(u - (uint64_t)pi * T);
        for (uint32_t t = loaded; t < T; t++) {
            const uint32_t need = t + L < T ? t + L : T;
            for (; loaded < need; loaded++) {
                int rc = load_step(e, loaded, diag);
                if (rc < 0)
                    return rc;
                tick(e);
            }
            pl->pr.step = t;
            int rc = encode_step(e, t, diag);
            if (rc < 0)
                return rc;
            u = (uint64_t)pi * T + t + 1;
            if (t + 1 == T) /* the next pass has none of its steps */
                e->st.loaded = 0;
            if ((rc = end_unit(e, u, diag)) < 0)
                return rc;
        }
    }
    return 0;
}

static int level_complete(const struct tvpal_encoder *e, uint32_t k);
static int keep_level(struct tvpal_encoder *e, uint32_t k);

/* After level 0: every level made from the source read again in slabs of
 * planes (as many as the ring held), level 1 plane by plane from pairs of
 * source planes, and pushed to the levels' encoders. */
static int levels_after(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    struct pull *pl = e->pull;
    const uint32_t *d = e->ep.dims;
    const uint64_t plane = (uint64_t)d[0] * d[1];
    uint64_t planes = pl->plan.box_voxels_max / plane;
    planes = planes < 1 ? 1 : planes > d[2] ? d[2] : planes;
    /* Slabs of an even number of planes, so that a block's two planes are
     * in one slab: within the plan's box and the two planes it keeps for
     * this (levels_bytes). */
    const uint32_t sn = planes >= 2 ? (uint32_t)(planes & ~1ull) : 2;
    tvpal_engine_release_ring(e->eng);
    float *slab = malloc((size_t)(sn * plane) * sizeof *slab);
    int rc = slab ? 0 : tvpal_diag_set(diag, TVPAL_E_NOMEM, "%u planes of "
                                       "%llu voxels for the levels", sn,
                                       (unsigned long long)plane);
    for (uint32_t k = 1; rc == 0 && k <= e->levels; k++)
        rc = level_complete(e, k) ? keep_level(e, k)
                                  : tvpal_enc_open_level(e, k, 0, 0, diag);
    pl->pr.level = 1;
    const size_t cplane = (size_t)e->ldims[1][0] * e->ldims[1][1];
    for (uint32_t t = 0; rc == 0 && t < e->ep.steps; t++) {
        pl->pr.step = t;
        for (uint32_t z0 = 0; rc == 0 && z0 < d[2]; z0 += sn) {
            const uint32_t n = d[2] - z0 < sn ? d[2] - z0 : sn;
            /* A reader thread's box holds the plan's box or a plane. */
            const uint32_t rn = planes >= 2 ? n : 1;
            for (uint32_t zr = 0; rc == 0 && zr < n; zr += rn) {
                const struct encode_box b = {{0, 0, z0 + zr},
                                             {d[0], d[1], rn}};
                rc = read_box(e, t, -1, &b, slab + zr * plane, 0, diag);
            }
            for (uint32_t z = 0; rc == 0 && z < n; z += 2)
                tvpal_level_average_planes(
                    slab + z * plane, z + 1 < n ? slab + (z + 1) * plane : NULL,
                    d[0], d[1], e->lvol[1] + (size_t)(z0 + z) / 2 * cplane);
        }
        if (rc == 0)
            rc = tvpal_enc_push_levels(e, t, diag);
        tick(e);
    }
    free(slab);
    return rc;
}

/* Whether level k is in DIR.partial complete, from an earlier encode of
 * the job whose level 0 is kept. */
static int level_complete(const struct tvpal_encoder *e, uint32_t k)
{
    char *p = NULL;
    int done = e->pull->kept &&
               asprintf(&p, "%s/level-%u/manifest.txt", e->partial, k) >= 0 &&
               tvpal_exists(p);
    free(p);
    return done;
}

/* A complete level kept: only its step volume, for the levels after it. */
static int keep_level(struct tvpal_encoder *e, uint32_t k)
{
    uint32_t *dk = e->ldims[k];
    tvpal_level_dims(e->ep.dims, k, dk);
    e->lnext[k] = e->ep.steps; /* nothing pushed to it */
    e->lvol[k] = malloc((size_t)dk[0] * dk[1] * dk[2] * sizeof(float));
    return e->lvol[k] ? 0 : TVPAL_E_NOMEM;
}

/* The end of level k (complete in DIR.partial): the caller's answer, as at
 * a unit's end; a stop leaves level 0 and levels 1 .. k for the next
 * encode of the job. */
static int end_level(struct tvpal_encoder *e, uint32_t k,
                     struct tvpal_diag *diag)
{
    struct pull *pl = e->pull;
    pl->pr.level = k;
    pl->pr.unit_end = 1;
    pl->pr.work = __atomic_load_n(&pl->work, __ATOMIC_RELAXED);
    const int answer = e->src->progress ? e->src->progress(e->src->ctx,
                                                           &pl->pr)
                                        : TVPAL_GO_ON;
    if (answer == TVPAL_STOP || answer == TVPAL_SAVE_AND_STOP)
        return tvpal_diag_set(diag, TVPAL_E_CANCELED, "stopped after level "
                              "%u of %u (level 0 and the levels up to %u "
                              "are kept)", k, e->levels, k);
    return 0;
}

/* Rank 0, after level 0 is finished: the levels made (after it, reading
 * the source again, unless they were made beside its one pass) and
 * finished one at a time, each the end of a unit for the progress
 * callback; then the marker goes. */
static int make_levels(struct tvpal_encoder *e, struct tvpal_diag *diag)
{
    int rc = 0, missing = 0;
    for (uint32_t k = 1; k <= e->levels; k++)
        missing += !level_complete(e, k);
    if (!tvpal_enc_source_levels_inline(e) && missing)
        rc = levels_after(e, diag);
    for (uint32_t k = 1; rc == 0 && k <= e->levels; k++)
        if ((rc = tvpal_enc_finish_level(e, k, diag)) == 0)
            rc = end_level(e, k, diag);
    char *mk = marker_path(e);
    if (rc == 0 && (!mk || (unlink(mk) < 0 && errno != ENOENT)))
        rc = tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot remove",
                            mk ? mk : LEVELS_MARKER);
    free(mk);
    return rc;
}

/* After the passes: level 0 finished on every rank (unless kept), and
 * with levels the marker written and rank 0's levels. */
static int levels_after_level0(struct tvpal_encoder *e,
                               struct tvpal_diag *diag)
{
    int rc = 0;
    const int root = e->coll.rank == 0;
    if (!e->level0_finished) {
        if ((rc = tvpal_enc_finish_level0(e, diag)) < 0)
            return rc;
        char *mk = root && e->levels ? marker_path(e) : NULL;
        if (root && e->levels)
            rc = mk ? tvpal_write_file_atomic(mk, e->pull->fp0,
                                              strlen(e->pull->fp0), diag)
                    : TVPAL_E_NOMEM;
        free(mk);
    }
    return rc == 0 && root && e->levels ? make_levels(e, diag) : rc;
}

int tvpal_enc_failure_may_pass(int code)
{
    return code == TVPAL_E_CANCELED || code == TVPAL_E_OPEN ||
           code == TVPAL_E_READ || code == TVPAL_E_WRITE ||
           code == TVPAL_E_SYS || code == TVPAL_E_NOMEM;
}

int tvpal_encoder_encode(struct tvpal_encoder *e,
                         const struct tvpal_source *src,
                         struct tvpal_diag *diag)
{
    int rc = check_source(e, src, diag);
    if (rc < 0)
        return rc;
    struct tvpal_diag d = {{0}};
    e->src = src;
    e->src_big_endian = src->big_endian;
    e->resuming = e->keep_identity = src->identity != NULL;
    e->state = STARTED;
    rc = tvpal_enc_start(e, tvpal_enc_scalar_type(src->type), &d);
    if (rc == 0) {
        struct pull *pl = e->pull;
        pl->pr = (struct tvpal_progress){
            .total = work_before(e, pl->units), .units = pl->units,
            .passes = pl->plan.npasses, .unit = pl->start,
            .resumed = pl->start > 0, .level0_kept = pl->kept,
            .levels_before = pl->pr.levels_before,
            .started_over = pl->pr.started_over};
        pl->work = pl->pr.work = work_before(e, pl->start);
        tvpal_engine_set_progress(e->eng, &pl->work, engine_tick, e);
        tick(e); /* where it starts, before any read */
        rc = encode_passes(e, &d);
    }
    if (rc == 0)
        rc = levels_after_level0(e, &d);
    /* The reader may be reading ahead: it stops before the call returns,
     * after which src is the caller's again. */
    if (e->pull) {
        tvpal_readahead_stop(e->pull->rd);
        e->pull->rd = NULL;
    }
    e->src = NULL;
    if (rc == 0) {
        e->next_in = e->pushed = e->ep.steps;
        return 0;
    }
    e->state = FAILED;
    e->own_rc = rc;
    memcpy(e->own_msg, d.msg, sizeof d.msg);
    /* A failure that may pass keeps DIR.partial for an encode of the same
     * identity to continue (tvpal_encoder_abort leaves it). */
    if (src->identity && tvpal_enc_failure_may_pass(rc))
        e->keep_partial = 1;
    if (diag)
        *diag = d;
    return rc;
}
