/* tvpal_player.c: the player core (see tvpal_player.h). */
#include "tvpal_cli.h"
#include "tvpal_player.h"
#include "tvpal_clock.h"
#include "tvpal_format.h"
#include "tvpal_stream.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct axis_state {
    struct tvpal_slab **slabs;       /* one per shard held; NULL for an
                                      * axis the dataset does not store */
    uint32_t begin, held;            /* slices held: [begin, begin + held) */
    struct tvpal_stream *stream;     /* created on first use */
    uint32_t n, w, h;
    uint32_t *slab_of, *local_of;    /* slice -> (shard, local index) */
};

struct tvpal_player {
    struct tvpal_dataset *ds;
    struct tvpal_player_opts opts;
    struct axis_state ax[3];
    struct tvpal_tf tf;
    double opacity_scale;
    unsigned reduce;
    /* renderer state */
    struct tvpal_renderer *last_r;
    int r_axis;
    uint32_t *uploaded_gen;          /* per slice of r_axis; 0 = never */
    /* frame scratch */
    struct tvpal_frame_slice *fs;
    float *pal;
    uint8_t *state;                  /* per held slice: enum slice_state */
    const uint8_t *zero_idx;         /* cross frames: the indices of a z
                                        slice with no data yet (zeros, with
                                        the zero palette) */
    /* Ghost rows (cluster cross frames, tvpal_player.h): [0] below the
     * slab, [1] above; their indices, palettes, and the generations sent
     * to and uploaded from each side. */
    struct tvpal_ghost_row gmine[2], gtheirs[2];
    uint8_t *ghost_idx[2];
    float *ghost_pal;                /* 2 x 1024 */
    uint32_t ghost_sent[2], ghost_upl[2];
    /* tvpal_player_loop: the steps playback goes round (set: 1). */
    int loop_set;
    uint32_t loop_first, loop_last;
};

/* Ghost rows are exchanged (a cluster node with an exchange). */
static int ghosts_on(const struct tvpal_player *p)
{
    return p->opts.ghosts && p->opts.nranks > 1;
}

/* Layer of the first held slice of axis a: 1 for z with ghost rows (layer
 * 0 and held + 1 are the ghosts: a cross frame's rows stay in consecutive
 * layers), else 0. */
static uint32_t layer0(const struct tvpal_player *p, unsigned a)
{
    return a == 2 && ghosts_on(p) ? 1 : 0;
}

/* A palette of zeros: a row with no data draws nothing. */
static const float zero_palette[1024];

/* What the frame does with a held slice (palette pass). */
enum slice_state { SL_STRIDE, SL_NODATA, SL_CLEAR, SL_DRAW };

int tvpal_player_open(struct tvpal_player **out, const char *dir,
                      const struct tvpal_player_opts *opts,
                      struct tvpal_diag *diag)
{
    struct tvpal_player *p = calloc(1, sizeof *p);
    if (!p)
        return TVPAL_E_NOMEM;
    p->opts = *opts;
    p->r_axis = -1;
    p->opacity_scale = 1.0;
    p->reduce = 1;
    int rc = opts->nranks
                 ? tvpal_dataset_open_node(&p->ds, dir, opts->rank,
                                           opts->nranks, diag)
                 : tvpal_dataset_open(&p->ds, dir, diag);
    if (rc < 0)
        goto err;
    uint32_t nmax = 0;
    for (unsigned a = 0; a < 3; a++) {
        struct axis_state *x = &p->ax[a];
        tvpal_axis_geometry(p->ds->m.dims, a, &x->n, &x->w, &x->h);
        nmax = x->n > nmax ? x->n : nmax;
        x->slabs = calloc(p->ds->nshards, sizeof *x->slabs);
        x->slab_of = calloc(x->n, sizeof *x->slab_of);
        x->local_of = calloc(x->n, sizeof *x->local_of);
        if (!x->slabs || !x->slab_of || !x->local_of) {
            rc = TVPAL_E_NOMEM;
            goto err;
        }
        x->begin = UINT32_MAX;
        x->held = 0;
        if (!tvpal_dataset_has_axis(p->ds, a))
            continue;                /* not stored (single copy) */
        for (uint32_t k = 0; k < p->ds->nshards; k++) {
            rc = tvpal_slab_create(&x->slabs[k], p->ds->shards[a][k]);
            if (rc < 0)
                goto err;
            const struct tvpal_shard_header *h =
                tvpal_shard_hdr(p->ds->shards[a][k]);
            for (uint32_t i = 0; i < h->slice_count; i++) {
                x->slab_of[h->slice_begin + i] = k;
                x->local_of[h->slice_begin + i] = i;
            }
            /* Shards held are consecutive slabs: one range of slices. */
            if (h->slice_begin < x->begin)
                x->begin = h->slice_begin;
            x->held += h->slice_count;
        }
    }
    p->fs = calloc(nmax + 2, sizeof *p->fs);   /* + ghost rows */
    p->pal = malloc(sizeof(float) * 1024 * nmax);
    p->uploaded_gen = calloc(nmax, sizeof *p->uploaded_gen);
    p->state = malloc(nmax);
    const size_t zbytes = (size_t)p->ds->m.dims[0] * p->ds->m.dims[1];
    p->zero_idx = calloc(zbytes, 1);
    if (ghosts_on(p)) {
        p->ghost_idx[0] = calloc(zbytes, 1);
        p->ghost_idx[1] = calloc(zbytes, 1);
        p->ghost_pal = calloc(2048, sizeof(float));
        if (!p->ghost_idx[0] || !p->ghost_idx[1] || !p->ghost_pal) {
            rc = TVPAL_E_NOMEM;
            goto err;
        }
    }
    if (!p->fs || !p->pal || !p->uploaded_gen || !p->state || !p->zero_idx) {
        rc = TVPAL_E_NOMEM;
        goto err;
    }
    tvpal_tf_default(p->ds->m.value_min, p->ds->m.value_max,
                     p->ds->m.histogram, TVPAL_HIST_BINS, &p->tf);
    *out = p;
    return 0;
err:
    tvpal_player_close(p);
    return rc;
}

void tvpal_player_close(struct tvpal_player *p)
{
    if (!p)
        return;
    for (unsigned a = 0; a < 3; a++) {
        struct axis_state *x = &p->ax[a];
        tvpal_stream_free(x->stream);
        if (x->slabs && p->ds)
            for (uint32_t k = 0; k < p->ds->nshards; k++)
                tvpal_slab_free(x->slabs[k]);
        free(x->slabs);
        free(x->slab_of);
        free(x->local_of);
    }
    tvpal_dataset_close(p->ds);
    free(p->fs);
    free(p->pal);
    free(p->uploaded_gen);
    free(p->state);
    free((void *)p->zero_idx);
    free(p->ghost_idx[0]);
    free(p->ghost_idx[1]);
    free(p->ghost_pal);
    free(p);
}

const struct tvpal_manifest *tvpal_player_manifest(const struct tvpal_player *p)
{
    return &p->ds->m;
}

const char *tvpal_player_dir(const struct tvpal_player *p)
{
    return p->ds->dir;
}

const char *tvpal_player_io_name(const struct tvpal_player *p)
{
    if (p->opts.incore)
        return "incore";
    for (unsigned a = 0; a < 3; a++)
        if (p->ax[a].stream)
            return tvpal_stream_io_name(p->ax[a].stream);
    return p->opts.io == TVPAL_IO_URING ? "uring" : "pread";
}

static int open_axis(struct tvpal_player *p, unsigned a,
                     struct tvpal_diag *diag);
static int data_axis(const struct tvpal_player *p, unsigned view_axis);
static int no_data_axis(const struct tvpal_player *p, unsigned view_axis,
                        struct tvpal_diag *diag);

/* An axis the dataset does not store: TVPAL_E_INVAL, saying which it has
 * (until views are drawn from another axis's slices). */
int tvpal_player_open_axis(struct tvpal_player *p, unsigned axis,
                           struct tvpal_diag *diag)
{
    if (axis > 2)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "axis %u", axis);
    int da = data_axis(p, axis);
    if (da < 0)
        return no_data_axis(p, axis, diag);
    return p->ax[da].stream ? 0 : open_axis(p, (unsigned)da, diag);
}

/* The stream of view v's data axis, opened, for step t, into *s; 0, or
 * the code with diag set (an axis not stored, t out of range, a failed
 * open). */
static int stream_at(struct tvpal_player *p, const struct tvpal_view *v,
                     uint32_t t, struct tvpal_stream **s,
                     struct tvpal_diag *diag)
{
    int rc = tvpal_player_open_axis(p, v->axis, diag);
    if (rc < 0)
        return rc;
    if (t >= p->ds->m.steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u out of range "
                              "(0..%u)", t, p->ds->m.steps - 1);
    *s = p->ax[data_axis(p, v->axis)].stream;
    return 0;
}

int tvpal_player_prepare(struct tvpal_player *p, const struct tvpal_view *v,
                         uint32_t t, int dir, int prefetch,
                         struct tvpal_diag *diag)
{
    struct tvpal_stream *s = NULL;
    int rc = stream_at(p, v, t, &s, diag);
    if (rc < 0)
        return rc;
    return tvpal_stream_prepare(s, t, dir, prefetch) < 0
               ? tvpal_diag_set(diag, TVPAL_E_INVAL, "no stager to prepare "
                                "step %u (in-core, or prefetch 0)", t)
               : 0;
}

int tvpal_player_seek(struct tvpal_player *p, const struct tvpal_view *v,
                      uint32_t t, int dir, struct tvpal_stream_stats *st,
                      struct tvpal_diag *diag)
{
    struct tvpal_stream *s = NULL;
    struct tvpal_diag d = {{0}};
    int rc = stream_at(p, v, t, &s, diag);
    if (rc == 0 && (rc = tvpal_stream_seek(s, t, dir, st, &d)) < 0)
        tvpal_diag_set(diag, rc, "%s", d.msg);
    return rc;
}

int tvpal_player_keep(struct tvpal_player *p, const struct tvpal_view *v,
                      uint32_t t, int dir, struct tvpal_diag *diag)
{
    struct tvpal_stream *s = NULL;
    int rc = stream_at(p, v, t, &s, diag);
    if (rc == 0 && (rc = tvpal_stream_keep(s, t, dir)) < 0)
        tvpal_diag_set(diag, rc, "step %u: no stager", t);
    return rc;
}

/* The stream of view v's data axis when it is open, else NULL (the
 * queries below open nothing). */
static struct tvpal_stream *open_stream(const struct tvpal_player *p,
                                        const struct tvpal_view *v)
{
    const int da = v->axis <= 2 ? data_axis(p, v->axis) : -1;
    return da >= 0 ? p->ax[da].stream : NULL;
}

unsigned tvpal_player_kept(const struct tvpal_player *p,
                           const struct tvpal_view *v, uint32_t t, int *near)
{
    const struct tvpal_stream *s = open_stream(p, v);
    if (near)
        *near = s && tvpal_stream_kept(s, t);
    return s ? tvpal_stream_around(s) : 0;
}

int tvpal_player_loop(struct tvpal_player *p, uint32_t first, uint32_t last)
{
    if (first >= p->ds->m.steps || last >= p->ds->m.steps)
        return TVPAL_E_INVAL;
    p->loop_set = 1;
    p->loop_first = first;
    p->loop_last = last;
    for (unsigned a = 0; a < 3; a++)
        if (p->ax[a].stream)
            (void)tvpal_stream_loop(p->ax[a].stream, first, last);
    return 0;
}

void tvpal_player_meter(const struct tvpal_player *p,
                        const struct tvpal_view *v,
                        struct tvpal_stream_meter *m)
{
    const struct tvpal_stream *s = open_stream(p, v);
    if (s)
        tvpal_stream_meter(s, m);
    else
        memset(m, 0, sizeof *m);
}

void tvpal_player_step_bytes(const struct tvpal_player *p,
                             const struct tvpal_view *v, uint64_t *stored,
                             uint64_t *plain)
{
    const struct tvpal_stream *s = open_stream(p, v);
    *stored = *plain = 0;
    if (s)
        tvpal_stream_step_bytes(s, stored, plain);
}

int tvpal_player_busy(struct tvpal_player *p, const struct tvpal_view *v)
{
    struct tvpal_stream *s = open_stream(p, v);
    return s && tvpal_stream_busy(s);
}

int tvpal_player_ready(struct tvpal_player *p, const struct tvpal_view *v,
                       uint32_t t, double wait_ms)
{
    struct tvpal_stream *s = open_stream(p, v);
    return s && tvpal_stream_ready(s, t, wait_ms);
}

uint64_t tvpal_player_io_submits(const struct tvpal_player *p)
{
    uint64_t n = 0;
    for (unsigned a = 0; a < 3; a++)
        if (p->ax[a].stream)
            n += tvpal_stream_submits(p->ax[a].stream);
    return n;
}

void tvpal_player_io_path(const struct tvpal_player *p,
                          struct tvpal_io_path *out)
{
    unsigned on = 0, files = 0, fixed = 0, streams = 0;
    *out = (struct tvpal_io_path){
        .io = p->opts.io == TVPAL_IO_URING ? "uring" : "pread",
        .why = "", .fixed_why = ""};
    for (unsigned a = 0; a < 3; a++) {
        if (!p->ax[a].stream)
            continue;
        struct tvpal_stream_path sp;
        tvpal_stream_path(p->ax[a].stream, &sp);
        if (!streams++)
            out->io = sp.io;
        on += sp.direct_files;
        files += sp.files;
        fixed += sp.fixed > 0;
        out->fixed_reads += sp.fixed_reads;
        out->buffers += sp.buffers;
        if (!out->why[0])
            out->why = sp.why;
        if (!out->fixed_why[0])
            out->fixed_why = sp.fixed_why;
    }
    out->direct = !on ? "no" : on == files ? "yes" : "some";
    out->fixed = !fixed ? "no" : fixed == streams ? "yes" : "some";
}

void tvpal_player_set_tf(struct tvpal_player *p, const struct tvpal_tf *tf,
                         double opacity_scale)
{
    p->tf = *tf;
    p->opacity_scale = opacity_scale;
}

uint64_t tvpal_player_incore_bytes(const struct tvpal_player *p)
{
    uint64_t b = 0;
    for (unsigned a = 0; a < 3; a++)
        if (p->ax[a].stream)
            b += tvpal_stream_incore_bytes(p->ax[a].stream);
    return b;
}

void tvpal_player_set_reduce(struct tvpal_player *p, unsigned k)
{
    p->reduce = k ? k : 1;
}

uint64_t tvpal_player_axis_bytes(const struct tvpal_player *p)
{
    uint64_t b = 0;
    unsigned stored = 0;
    for (unsigned a = 0; a < 3; a++) {
        if (!tvpal_dataset_has_axis(p->ds, a))
            continue;
        stored++;
        for (uint32_t k = 0; k < p->ds->nshards; k++) {
            b += tvpal_shard_ram_bytes(p->ds->shards[a][k]);
        }
    }
    return stored ? b / stored : 0;
}

/* The axis whose slices draw a view along view_axis: its own where it is
 * stored, else z (a single-copy dataset: cross frames); -1 when neither
 * is stored. */
static int data_axis(const struct tvpal_player *p, unsigned view_axis)
{
    const int z = tvpal_dataset_has_axis(p->ds, 2);
    if (p->opts.z_only && z)
        return 2;
    if (tvpal_dataset_has_axis(p->ds, view_axis))
        return (int)view_axis;
    return z ? 2 : -1;
}

static int no_data_axis(const struct tvpal_player *p, unsigned view_axis,
                        struct tvpal_diag *diag)
{
    char axes[4];
    return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s stores axes %s only: a "
                          "view along %c needs its own axis or z", p->ds->dir,
                          tvpal_axes_format(p->ds->m.axes_mask, axes),
                          "xyz"[view_axis]);
}

int tvpal_player_data_axis(const struct tvpal_player *p, unsigned view_axis)
{
    return view_axis > 2 ? -1 : data_axis(p, view_axis);
}

uint32_t tvpal_player_group(const struct tvpal_player *p, unsigned a)
{
    if (a > 2 || !tvpal_dataset_has_axis(p->ds, a))
        return 0;
    return tvpal_shard_hdr(p->ds->shards[a][0])->group;
}

int tvpal_player_slabs_descending(const struct tvpal_player *p,
                                  const struct tvpal_view *v)
{
    if (data_axis(p, v->axis) == (int)v->axis)
        return v->descending;
    return -v->rot[2][2] > 0;   /* the view direction's z component */
}

/* First use of axis a: opens its stream (in-core: loads it).  With a
 * memory budget, other axes' in-core records are given back first when
 * needed (their slabs keep their decoded state); an axis larger than the
 * whole budget is streamed instead. */
static int open_axis(struct tvpal_player *p, unsigned a,
                     struct tvpal_diag *diag)
{
    int incore = p->opts.incore;
    if (incore && p->opts.mem_budget) {
        uint64_t need = 0;
        for (uint32_t k = 0; k < p->ds->nshards; k++) {
            need += tvpal_shard_ram_bytes(p->ds->shards[a][k]);
        }
        if (need > p->opts.mem_budget) {
            incore = 0;
        } else {
            uint64_t held = 0;
            for (unsigned b = 0; b < 3; b++)
                if (p->ax[b].stream)
                    held += tvpal_stream_incore_bytes(p->ax[b].stream);
            for (unsigned b = 0; b < 3 && held + need > p->opts.mem_budget; b++)
                if (b != a && p->ax[b].stream &&
                    tvpal_stream_incore_bytes(p->ax[b].stream)) {
                    held -= tvpal_stream_incore_bytes(p->ax[b].stream);
                    tvpal_stream_free(p->ax[b].stream);
                    p->ax[b].stream = NULL;
                }
        }
    }
    struct axis_state *x = &p->ax[a];
    const unsigned policy =
        (p->opts.direct ? TVPAL_STREAM_DIRECT : 0) |
        (p->opts.io_strict ? TVPAL_STREAM_STRICT_IO : 0) |
        (p->opts.direct_strict ? TVPAL_STREAM_STRICT_DIRECT : 0) |
        (!p->opts.incore && p->opts.keep_ahead ? TVPAL_STREAM_KEEP_AHEAD : 0);
    /* Streamed for want of memory: the steps around the playhead in it. */
    const uint64_t keep = incore ? 0
                          : p->opts.incore && p->opts.keep_around
                              ? p->opts.mem_budget
                              : p->opts.keep_ahead;
    int rc = tvpal_stream_create(&x->stream, x->slabs, p->ds->nshards,
                                 p->opts.io, incore, p->opts.prefetch,
                                 p->opts.read_ahead ? p->opts.read_ahead
                                                    : TVPAL_STREAM_READ_AHEAD,
                                 keep, policy, diag);
    if (rc == 0 && p->loop_set)
        (void)tvpal_stream_loop(x->stream, p->loop_first, p->loop_last);
    return rc; /* the range was checked by tvpal_player_loop */
}

/* The renderer is told the slices of the axis when it, its owner or the
 * axis changed (texture layers: the slices held, layer = slice - begin);
 * every slice is then uploaded again. */
static int prepare_renderer(struct tvpal_player *p, unsigned a,
                            struct tvpal_renderer *r, struct tvpal_diag *diag)
{
    const struct axis_state *x = &p->ax[a];
    if (r == p->last_r && r->owner == p && p->r_axis == (int)a)
        return 0;
    int rc = r->set_slices(r->ctx, x->w, x->h, x->held + 2 * layer0(p, a),
                           diag);
    if (rc < 0)
        return rc;
    memset(p->uploaded_gen, 0, sizeof(uint32_t) * x->n);
    p->ghost_upl[0] = p->ghost_upl[1] = 0;
    p->last_r = r;
    r->owner = p;
    p->r_axis = (int)a;
    return 0;
}

/* No more slices than the image can resolve: when a pixel spans k voxels,
 * every k-th slice is enough along the ray too; times the reduction. */
static unsigned slice_stride(const struct tvpal_player *p,
                             const struct tvpal_view *v, uint32_t n)
{
    uint32_t nmax = p->ds->m.dims[0];
    for (int i = 1; i < 3; i++)
        nmax = p->ds->m.dims[i] > nmax ? p->ds->m.dims[i] : nmax;
    /* Slices per pixel along the view's axis: on a physical grid, the
     * axis' slices per eye unit, dims / (2 half), times the pixel's 2 s /
     * size; on the unit grid that is nmax s / size (kept as it was). */
    const int iso = v->spacing[0] == 0 && v->spacing[1] == 0 &&
                    v->spacing[2] == 0;
    double per_unit = iso ? nmax : v->dims[v->axis] / v->half[v->axis];
    double vpp = fmin(v->sx / v->width, v->sy / v->height) * per_unit;
    /* Converted only once in [2, n]: any view (huge, zero or NaN vpp)
     * gives a stride in 1..n, never 0 (s % stride). */
    unsigned stride = !(vpp >= 2.0) ? 1 : vpp >= n ? n : (unsigned)vpp;
    if (p->reduce > 1)
        stride = stride > n / p->reduce ? n : stride * p->reduce;
    return stride > n ? n : stride < 1 ? 1 : stride;
}

/* The held slice drawn i-th (back to front). */
static inline uint32_t slice_in_order(const struct axis_state *x,
                                      const struct tvpal_view *v, uint32_t i)
{
    return v->descending ? x->begin + x->held - 1 - i : x->begin + i;
}

/* Palettes of every held slice at t, in parallel (the TF is evaluated 256
 * times per slice), and what the frame does with each slice. */
static void build_palettes(struct tvpal_player *p, const struct axis_state *x,
                           const struct tvpal_view *v, uint32_t t,
                           unsigned stride, int cross)
{
    const double expo = tvpal_view_opacity_exponent(v) * stride;
    const int held = (int)x->held;
#ifdef _OPENMP
#pragma omp parallel for schedule(static)
#endif
    for (int i = 0; i < held; i++) {
        /* Cross frames: every z slice held, ascending (each is a row of
         * every slice drawn). */
        uint32_t s = cross ? x->begin + (uint32_t)i
                           : slice_in_order(x, v, (uint32_t)i);
        if (!cross && s % stride != (x->n / 2) % stride) {
            p->state[i] = SL_STRIDE;
            continue;
        }
        const float *row = tvpal_slab_row(x->slabs[x->slab_of[s]],
                                          x->local_of[s], t);
        if (!row) {
            p->state[i] = SL_NODATA;
            continue;
        }
        float *pal = p->pal + (size_t)1024 * (s - x->begin);
        p->state[i] = tvpal_palette_build(&p->tf, row, expo, p->opacity_scale,
                                          pal) ? SL_CLEAR : SL_DRAW;
    }
}

/* Cross frames: every z slice held, ascending, uploaded when its window
 * changed; one with no data yet draws as zeros with the zero palette.  A
 * transparent one stays: it is the palette of a row. */
/* The ghost row of `side` (0 below, 1 above the slab) in `layer`,
 * uploaded when the neighbour sent new indices. */
static struct tvpal_frame_slice ghost_slice(struct tvpal_player *p, int side,
                                            uint32_t layer,
                                            struct tvpal_renderer *r,
                                            struct tvpal_frame_stats *st)
{
    if (p->ghost_upl[side] != p->gtheirs[side].gen) {
        r->upload(r->ctx, layer, p->ghost_idx[side]);
        p->ghost_upl[side] = p->gtheirs[side].gen;
        st->uploads++;
    }
    return (struct tvpal_frame_slice){.slice = p->gtheirs[side].slice,
                                      .layer = layer,
                                      .idx = p->ghost_idx[side],
                                      .palette = p->ghost_pal + 1024 * side};
}

static uint32_t list_rows(struct tvpal_player *p, const struct axis_state *x,
                          uint32_t lay0, struct tvpal_renderer *r,
                          struct tvpal_frame_stats *st)
{
    uint32_t count = 0;
    /* The ghost row below the slab (cluster nodes), in layer 0. */
    const int lo = lay0 && x->begin > 0 && p->gtheirs[0].slice == x->begin - 1;
    const int hi = lay0 && p->gtheirs[1].slice == x->begin + x->held;
    if (lo)
        p->fs[count++] = ghost_slice(p, 0, 0, r, st);
    for (uint32_t i = 0; i < x->held; i++) {
        const uint32_t s = x->begin + i;
        struct tvpal_slab *slab = x->slabs[x->slab_of[s]];
        const uint32_t k = x->local_of[s];
        const uint8_t *idx = tvpal_slab_indices(slab, k);
        const float *pal = p->pal + (size_t)1024 * i;
        if (p->state[i] == SL_NODATA || !idx) {
            idx = p->zero_idx;
            pal = zero_palette;
        } else if (p->state[i] == SL_CLEAR) {
            st->skipped++;
        }
        /* UINT32_MAX: the zeros (0 is "never uploaded"). */
        uint32_t gen = idx == p->zero_idx ? UINT32_MAX
                                          : tvpal_slab_generation(slab, k);
        if (p->uploaded_gen[s] != gen) {
            r->upload(r->ctx, i + lay0, idx);
            p->uploaded_gen[s] = gen;
            st->uploads++;
        }
        p->fs[count++] = (struct tvpal_frame_slice){
            .slice = s, .layer = i + lay0, .idx = idx, .palette = pal};
    }
    if (hi)
        p->fs[count++] = ghost_slice(p, 1, x->held + 1, r, st);
    return count;
}

/* Cluster cross frames: this slab's boundary rows out, the neighbours'
 * in (tvpal_player.h).  Right after the records are read, before anything
 * that could fail on one node only, so that every node exchanges. */
static int exchange_ghosts(struct tvpal_player *p, const struct axis_state *x,
                           uint32_t t, struct tvpal_diag *diag)
{
    for (int side = 0; side < 2; side++) {
        struct tvpal_ghost_row *m = &p->gmine[side];
        const uint32_t s = side ? x->begin + x->held - 1 : x->begin;
        struct tvpal_slab *slab = x->slabs[x->slab_of[s]];
        const uint32_t k = x->local_of[s];
        const uint8_t *idx = tvpal_slab_indices(slab, k);
        const float *row = tvpal_slab_row(slab, k, t);
        m->slice = idx && row && x->held ? s : UINT32_MAX;
        m->gen = m->slice == UINT32_MAX ? 0 : tvpal_slab_generation(slab, k);
        m->send_idx = m->slice != UINT32_MAX && m->gen != p->ghost_sent[side];
        m->idx = (uint8_t *)idx;   /* read only: the exchange sends it */
        if (row)
            memcpy(m->row, row, sizeof m->row);
        p->gtheirs[side].slice = UINT32_MAX;
        p->gtheirs[side].idx = p->ghost_idx[side];
    }
    const size_t bytes = (size_t)p->ds->m.dims[0] * p->ds->m.dims[1];
    int rc = p->opts.ghosts(p->opts.ghosts_ctx, p->gmine, p->gtheirs, bytes,
                            diag);
    if (rc < 0)
        return rc;
    for (int side = 0; side < 2; side++)
        if (p->gmine[side].send_idx)
            p->ghost_sent[side] = p->gmine[side].gen;
    return 0;
}

/* In drawing order: uploads of slices whose window changed (serial: a GL
 * context is not shared among threads) and the frame's slice list.
 * Returns the slices to draw. */
static uint32_t list_slices(struct tvpal_player *p, const struct axis_state *x,
                            const struct tvpal_view *v, uint32_t lay0,
                            struct tvpal_renderer *r,
                            struct tvpal_frame_stats *st)
{
    uint32_t count = 0;
    for (uint32_t i = 0; i < x->held; i++) {
        if (p->state[i] == SL_STRIDE)
            continue;
        if (p->state[i] != SL_DRAW) {
            st->skipped++; /* no data, or fully transparent */
            continue;
        }
        uint32_t s = slice_in_order(x, v, i);
        struct tvpal_slab *slab = x->slabs[x->slab_of[s]];
        uint32_t k = x->local_of[s];
        const uint32_t layer = s - x->begin + lay0;
        uint32_t gen = tvpal_slab_generation(slab, k);
        if (p->uploaded_gen[s] != gen) {
            r->upload(r->ctx, layer, tvpal_slab_indices(slab, k));
            p->uploaded_gen[s] = gen;
            st->uploads++;
        }
        p->fs[count++] = (struct tvpal_frame_slice){
            .slice = s, .layer = layer, .idx = tvpal_slab_indices(slab, k),
            .palette = p->pal + (size_t)1024 * (s - x->begin)};
    }
    return count;
}

int tvpal_player_frame(struct tvpal_player *p, const struct tvpal_view *v,
                       uint32_t t, int dir, struct tvpal_renderer *r,
                       float *rgba, struct tvpal_frame_stats *st,
                       struct tvpal_diag *diag)
{
    struct tvpal_frame_stats local;
    if (!st)
        st = &local;
    memset(st, 0, sizeof *st);
    st->step = t;
    st->axis = v->axis;
    double t0 = tvpal_now();
    if (t >= p->ds->m.steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u out of range "
                              "(0..%u)", t, p->ds->m.steps - 1);
    const int da = v->axis <= 2 ? data_axis(p, v->axis) : -1;
    if (da < 0)
        return v->axis <= 2 ? no_data_axis(p, v->axis, diag)
                            : tvpal_diag_set(diag, TVPAL_E_INVAL, "axis %u",
                                             v->axis);
    const int cross = da != (int)v->axis;
    struct axis_state *x = &p->ax[da];
    if (!x->stream) {
        int rc = open_axis(p, (unsigned)da, diag);
        if (rc < 0)
            return rc;
        st->axis_switch_ms = (tvpal_now() - t0) * 1e3;
    }
    /* A record that fails to load leaves its slices with their last good
     * data: the frame is drawn, and the error returned. */
    struct tvpal_stream_stats ss;
    struct tvpal_diag d = {{0}};
    int load_rc = tvpal_stream_seek(x->stream, t, dir, &ss, &d);
    if (load_rc < 0)
        tvpal_diag_set(diag, load_rc, "%s", d.msg);
    st->io_ms = ss.io_wait_ms;
    st->bytes_read = ss.bytes_read;
    st->staged = ss.records_staged;
    st->stage_ms = ss.stage_ms;
    st->bytes_needed = ss.bytes_needed;

    double t1 = tvpal_now();
    st->stream_ms = (t1 - t0) * 1e3 - st->axis_switch_ms;
    const uint32_t lay0 = cross ? layer0(p, (unsigned)da) : 0;
    if (lay0) {
        int rc = exchange_ghosts(p, x, t, diag);
        if (rc < 0)
            return rc;
    }
    int rc = prepare_renderer(p, (unsigned)da, r, diag);
    if (rc < 0)
        return rc;
    const uint32_t n = v->dims[v->axis];   /* slices along the view */
    st->stride = slice_stride(p, v, n);
    build_palettes(p, x, v, t, st->stride, cross);
    uint32_t count = cross ? list_rows(p, x, lay0, r, st)
                           : list_slices(p, x, v, layer0(p, (unsigned)da), r, st);
    if (lay0) {   /* the ghost rows' palettes, as the slab's */
        const double expo = tvpal_view_opacity_exponent(v) * st->stride;
        for (int side = 0; side < 2; side++)
            if (p->gtheirs[side].slice < p->ds->m.dims[2])
                tvpal_palette_build(&p->tf, p->gtheirs[side].row, expo,
                                    p->opacity_scale, p->ghost_pal + 1024 * side);
    }
    st->drawn = cross ? (n + st->stride - 1 - (n / 2) % st->stride) / st->stride
                      : count;
    double t2 = tvpal_now();
    struct tvpal_frame f = {.view = v, .w = x->w, .h = x->h, .count = count,
                            .sl = p->fs, .cross = cross, .stride = st->stride,
                            .phase = (n / 2) % st->stride,
                            .draw_begin = lay0 ? x->begin : 0,
                            .draw_end = lay0 ? x->begin + x->held : 0};
    rc = r->draw(r->ctx, &f, rgba, diag);
    double t3 = tvpal_now();
    st->rendered = rc == 0;
    st->upload_ms = (t2 - t1) * 1e3;
    st->draw_ms = (t3 - t2) * 1e3;
    st->total_ms = (t3 - t0) * 1e3;
    return rc < 0 ? rc : load_rc;
}
