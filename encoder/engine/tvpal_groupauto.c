/* tvpal_groupauto.c: palette group sizes chosen by measurement
 * (tvpal_groupauto.h). */
#include "tvpal_groupauto.h"
#include "tvpal_format.h"
#include "tvpal_manifest.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* decide() and the report hold a candidate per power of two up to the
 * largest. */
_Static_assert(TVPAL_GROUPAUTO_MAX <= 128,
               "at most 8 candidates (struct tvpal_groupauto_report)");

/* The sample: `windows` group-windows of S slices (S the largest
 * candidate) and L steps, window i at samples + i * L * S * w * h, step
 * by step, each step's S slices one after the other (a group's chunk
 * layout). */
struct sample {
    uint32_t axis, n, w, h, S, L, windows;
    float *v;
};

/* One pricing job: candidate c's subgroup `sub` (slices sub * G ..) of
 * sample window i; its results, added in job order afterwards. */
struct price_job {
    uint32_t i, c, G, sub;
    uint64_t bytes, present;
    double sse;
    int rc;
};

struct price_ctx {
    struct tvpal_engine *eng;
    const struct sample *s;
    struct price_job *jobs;
    float **scratch;              /* per thread: S * w * h * L floats */
};

/* Where window i of the sample starts: its first slice and step, spread
 * evenly along the axis' whole groups and over the series' windows. */
static void window_at(const struct sample *s, uint32_t T, uint32_t i,
                      uint32_t *slice, uint32_t *t0)
{
    const uint64_t groups = s->n / s->S, starts = T - s->L + 1;
    *slice = (uint32_t)((2 * (uint64_t)i + 1) * groups / (2 * s->windows)) *
             s->S;
    *t0 = (uint32_t)((2 * (uint64_t)i + 1) * starts / (2 * s->windows));
}

/* The box of slices s0 .. s0 + S - 1 of the sample's axis. */
static void slices_box(const struct sample *s, const uint32_t dims[3],
                       uint32_t s0, uint32_t lo[3], uint32_t n[3])
{
    for (unsigned k = 0; k < 3; k++) {
        lo[k] = 0;
        n[k] = dims[k];
    }
    lo[s->axis] = s0;
    n[s->axis] = s->S;
}

/* A box of S slices (x fastest) into slice order: slice g's w x h values
 * at out + g * w * h, in the order of a slice of the axis (the engine's
 * gather): x then y for z slices, x then z for y slices, y then z for x
 * slices. */
static void box_to_slices(const struct sample *s, const uint32_t dims[3],
                          const float *box, float *out)
{
    const size_t nx = dims[0], ny = dims[1], nz = dims[2], S = s->S;
    const size_t wh = (size_t)s->w * s->h;
    if (s->axis == 2) {
        memcpy(out, box, S * wh * sizeof *out);
        return;
    }
    for (size_t z = 0; z < nz; z++)
        for (size_t g = 0; g < S; g++) {
            float *dst = out + g * wh;
            if (s->axis == 1) {
                memcpy(dst + nx * z, box + nx * (g + S * z),
                       nx * sizeof *out);
                continue;
            }
            for (size_t y = 0; y < ny; y++)
                dst[y + ny * z] = box[g + S * (y + ny * z)];
        }
}

/* Reads the sample's windows (rd), each step through one box buffer. */
static int read_sample(struct sample *s, const uint32_t dims[3], uint32_t T,
                       const struct tvpal_groupauto_reader *rd,
                       struct tvpal_diag *diag)
{
    const size_t step = (size_t)s->S * s->w * s->h;
    float *box = malloc(step * sizeof *box);
    if (!box)
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "the group sample");
    int rc = 0;
    for (uint32_t i = 0; rc == 0 && i < s->windows; i++) {
        uint32_t s0, t0, lo[3], n[3];
        window_at(s, T, i, &s0, &t0);
        slices_box(s, dims, s0, lo, n);
        for (uint32_t j = 0; rc == 0 && j < s->L; j++) {
            rc = rd->read(rd->ctx, t0 + j, lo, n, box, diag);
            if (rc == 0)
                box_to_slices(s, dims, box,
                              s->v + ((size_t)i * s->L + j) * step);
        }
    }
    free(box);
    return rc;
}

/* Job k: its subgroup's steps gathered into the thread's scratch (a
 * chunk of G slices), then priced. */
static void price_one(void *arg, size_t k, unsigned tid)
{
    struct price_ctx *c = arg;
    struct price_job *jb = &c->jobs[k];
    const struct sample *s = c->s;
    const size_t wh = (size_t)s->w * s->h, step = s->S * wh;
    const float *win = s->v + (size_t)jb->i * s->L * step;
    float *dst = c->scratch[tid];
    for (uint32_t j = 0; j < s->L; j++)
        memcpy(dst + (size_t)j * jb->G * wh,
               win + j * step + (size_t)jb->sub * jb->G * wh,
               jb->G * wh * sizeof *dst);
    jb->rc = tvpal_engine_price(c->eng, tid, dst, jb->G, s->L, &jb->bytes,
                                &jb->sse, &jb->present);
}

/* The jobs of every candidate (G = 1, 2, 4, .. S) over every window. */
static size_t list_jobs(const struct sample *s, struct price_job *jobs,
                        struct tvpal_groupauto_report *rep)
{
    size_t n = 0;
    uint32_t c = 0;
    for (uint32_t G = 1; G <= s->S; G *= 2, c++) {
        rep->G[c] = G;
        for (uint32_t i = 0; i < s->windows; i++)
            for (uint32_t sub = 0; sub < s->S / G; sub++)
                jobs[n++] = (struct price_job){.i = i, .c = c, .G = G,
                                               .sub = sub};
    }
    rep->ncand = c;
    return n;
}

/* The candidates' sums in job order, their rates and errors into rep, and
 * the G of the least D + 2 ln 2 D(1) R (fewer bits on a tie). */
static uint32_t decide(const struct sample *s, const struct price_job *jobs,
                       size_t njobs, struct tvpal_groupauto_report *rep)
{
    double sse[8] = {0};
    uint64_t bytes[8] = {0}, present[8] = {0};
    for (size_t k = 0; k < njobs; k++) {
        sse[jobs[k].c] += jobs[k].sse;
        bytes[jobs[k].c] += jobs[k].bytes;
        present[jobs[k].c] += jobs[k].present;
    }
    const double vox = (double)s->windows * s->S * s->w * s->h * s->L;
    for (uint32_t c = 0; c < rep->ncand; c++) {
        rep->bpv[c] = 8.0 * (double)bytes[c] / vox;
        rep->mse[c] = present[c] ? sse[c] / (double)present[c] : 0;
    }
    const double lambda = 2 * log(2) * rep->mse[0];
    uint32_t best = 0;
    double jbest = rep->mse[0] + lambda * rep->bpv[0];
    for (uint32_t c = 1; c < rep->ncand; c++) {
        const double j = rep->mse[c] + lambda * rep->bpv[c];
        if (j < jbest || (j == jbest && rep->bpv[c] < rep->bpv[best])) {
            best = c;
            jbest = j;
        }
    }
    return rep->G[best];
}

/* The parameters of the engine that prices axis a's candidates: that
 * axis alone, one node, its largest group S slices. */
static struct tvpal_engine_params price_params(
    const struct tvpal_engine_params *p, unsigned a, uint32_t S)
{
    struct tvpal_engine_params q = *p;
    q.axes = TVPAL_AXIS_BIT(a);
    q.nodes = q.node_count = 1;
    q.node_first = 0;
    q.group = 1;
    q.group_auto = 0;
    memset(q.group_axis, 0, sizeof q.group_axis);
    q.group_axis[a] = S;
    return q;
}

/* Bytes the measure holds with S slices and m windows on nt threads: the
 * sample, the box one step of it is read through, and per thread a
 * window and the pricing engine's workspace. */
static uint64_t measure_bytes(const struct tvpal_engine_params *p,
                              unsigned a, const struct sample *s,
                              uint32_t m, unsigned nt)
{
    const struct tvpal_engine_params q = price_params(p, a, s->S);
    struct tvpal_engine *e = NULL;
    if (tvpal_engine_create(&e, &q) < 0)
        return UINT64_MAX;
    const uint64_t win = (uint64_t)s->S * s->w * s->h * s->L * sizeof(float);
    const uint64_t b = m * win + win / s->L +
                       nt * (win + tvpal_engine_thread_bytes(e));
    tvpal_engine_free(e);
    return b;
}

/* The sample's shape for axis a of p: S the largest power of two within
 * the cap, L the window (the series if shorter), windows within the
 * budget; S and the windows fewer where the measure would hold more than
 * mem_limit bytes (0: no limit).  0: no measure (no G >= 2 possible, or
 * none fits the limit). */
static int plan_sample(const struct tvpal_engine_params *p, unsigned a,
                       uint64_t mem_limit, unsigned nt, struct sample *s)
{
    struct tvpal_engine_params q = *p;
    q.group = TVPAL_GROUPAUTO_MAX;
    memset(q.group_axis, 0, sizeof q.group_axis);
    const uint32_t cap = tvpal_engine_group(&q, a);
    *s = (struct sample){.axis = a};
    tvpal_axis_geometry(p->dims, a, &s->n, &s->w, &s->h);
    s->L = p->window < p->steps ? p->window : p->steps;
    for (s->S = 1; s->S * 2 <= cap;)
        s->S *= 2;
    for (; s->S >= 2; s->S /= 2) {
        const uint64_t one = (uint64_t)s->S * s->w * s->h * s->L;
        uint64_t budget = (uint64_t)s->n * s->w * s->h * p->steps / 8;
        budget = budget < TVPAL_GROUPAUTO_SAMPLE ? budget
                                                 : TVPAL_GROUPAUTO_SAMPLE;
        uint64_t m = budget / one;
        const uint64_t most = (uint64_t)(s->n / s->S) *
                              (p->steps - s->L + 1);
        m = m < most ? m : most;
        s->windows = m < 1 ? 1 : (uint32_t)m;
        while (mem_limit && s->windows > 1 &&
               measure_bytes(p, a, s, s->windows, nt) > mem_limit)
            s->windows /= 2;
        if (!mem_limit || measure_bytes(p, a, s, s->windows, nt) <= mem_limit)
            return 1;
    }
    return 0;
}

/* Prices every job on the pool with an engine of axis a alone, its
 * largest group S slices. */
static int price_all(const struct tvpal_engine_params *p, unsigned a,
                     struct tvpal_pool *pool, const struct sample *s,
                     struct price_job *jobs, size_t njobs,
                     struct tvpal_diag *diag)
{
    const struct tvpal_engine_params q = price_params(p, a, s->S);
    const unsigned nt = (unsigned)tvpal_pool_threads(pool);
    struct price_ctx c = {.s = s, .jobs = jobs};
    int rc = tvpal_engine_create(&c.eng, &q);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "the group measure's parameters");
    if ((rc = tvpal_engine_start(c.eng, pool, 1, diag)) == 0 &&
        !(c.scratch = calloc(nt, sizeof *c.scratch)))
        rc = tvpal_diag_set(diag, TVPAL_E_NOMEM, "the group measure");
    const size_t win = (size_t)s->S * s->w * s->h * s->L;
    for (unsigned i = 0; rc == 0 && i < nt; i++)
        if (!(c.scratch[i] = malloc(win * sizeof(float))))
            rc = tvpal_diag_set(diag, TVPAL_E_NOMEM, "the group measure");
    if (rc == 0)
        tvpal_pool_for(pool, njobs, price_one, &c);
    for (size_t k = 0; rc == 0 && k < njobs; k++)
        if (jobs[k].rc < 0)
            rc = tvpal_diag_set(diag, jobs[k].rc, "coding the group sample");
    for (unsigned i = 0; c.scratch && i < nt; i++)
        free(c.scratch[i]);
    free(c.scratch);
    tvpal_engine_free(c.eng);
    return rc;
}

int tvpal_groupauto_choose(const struct tvpal_engine_params *p, unsigned a,
                           uint64_t mem_limit, struct tvpal_pool *pool,
                           const struct tvpal_groupauto_reader *rd,
                           uint32_t *G, struct tvpal_groupauto_report *rep,
                           struct tvpal_diag *diag)
{
    struct tvpal_groupauto_report own;
    rep = rep ? rep : &own;
    *rep = (struct tvpal_groupauto_report){0};
    *G = 1;
    struct sample s;
    if (!plan_sample(p, a, mem_limit, (unsigned)tvpal_pool_threads(pool),
                     &s))
        return 0;
    rep->windows = s.windows;
    rep->slices = s.S;
    rep->steps = s.L;
    const size_t floats = (size_t)s.windows * s.S * s.w * s.h * s.L;
    const size_t njobs = (size_t)s.windows * (2 * s.S - 1);
    struct price_job *jobs = calloc(njobs, sizeof *jobs);
    if (!jobs || !(s.v = malloc(floats * sizeof *s.v))) {
        free(jobs);
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "the group sample: %zu "
                              "values", floats);
    }
    int rc = read_sample(&s, p->dims, p->steps, rd, diag);
    const size_t n = list_jobs(&s, jobs, rep);
    if (rc == 0)
        rc = price_all(p, a, pool, &s, jobs, n, diag);
    if (rc == 0)
        *G = decide(&s, jobs, n, rep);
    free(jobs);
    free(s.v);
    return rc;
}
