/* encode_levels.c: tvpal-encode --levels L, the coarser levels of detail.
 *
 * Level k (1..L) is the 2x2x2 average of level k - 1 (level 0: the source
 * as encoded), each mean over the present voxels of its block (a block all
 * missing is missing: NaN), dims ceil(d / 2) per axis.  A step's levels
 * are made in memory one from the other, from the whole step as level 0's
 * single pass reads it (levels_step from encode_steps: every step read
 * once), or, where the plan cannot hold the levels beside that pass or
 * level 0 was resumed, after level 0 from the source read again in slabs
 * of planes.  Each level's step goes straight to that level's encoder, a
 * libtvpal encoder (tvpal.h) in this process with the same encoding
 * options, which writes
 * OUTDIR.partial/level-k/, a complete dataset of its own (FORMAT.md 3.3),
 * through OUTDIR.partial/level-k.partial.  Nothing else is written, and no
 * second process runs.  A level already complete (an earlier run of the
 * job) is kept; one interrupted is encoded again.
 *
 * Its grid covers the same box as level 0: spacing s0 * d0 / dk per axis
 * and the first voxel's centre at the centre of the first block. */
#define _GNU_SOURCE
#include "encode_levels.h"
#include "encode_output.h"
#include "encode_say.h"
#include "encode_source.h"
#include "tvpal.h"
#include "tvpal_fs.h"
#include "tvpal_levels.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>



/* Level 0's planes, through load_step (the source, converted as encoded):
 * a slab of planes of step t read at once. */
struct plane_src {
    struct run *r;
    uint32_t dims[3];
    float *slab;
    uint32_t slab_planes, slab_z0, slab_n;
    int64_t slab_t;
    struct encode_pass pass;
};

/* Plane z of step t into out (nx * ny floats). */
static void read_plane(struct plane_src *ps, uint32_t t, uint32_t z,
                       float *out)
{
    const size_t plane = (size_t)ps->dims[0] * ps->dims[1];
    if (ps->slab_t != (int64_t)t || z < ps->slab_z0 ||
        z >= ps->slab_z0 + ps->slab_n) {
        struct run *r = ps->r;
        uint32_t n = ps->dims[2] - z < ps->slab_planes ? ps->dims[2] - z
                                                       : ps->slab_planes;
        ps->pass.box = (struct encode_box){{0, 0, z},
                                           {ps->dims[0], ps->dims[1], n}};
        ps->pass.stats = 0;
        const struct encode_pass *keep = r->pass;
        r->pass = &ps->pass;
        load_step(r, t, ps->slab);
        r->pass = keep;
        ps->slab_t = t;
        ps->slab_z0 = z;
        ps->slab_n = n;
    }
    memcpy(out, ps->slab + (size_t)(z - ps->slab_z0) * plane,
           plane * sizeof *out);
}


/* One coarser level being made: its step in memory, and its encoder
 * (NULL: complete already, or not encoded in this run). */
struct level {
    uint32_t dims[3];
    float *vol;
    struct tvpal_encoder *enc;
    char *out;
};

/* Ends the program for a failed call of level k's encoder. */
static void __attribute__((noreturn))
level_failed(unsigned k, const char *what, int rc, const struct tvpal_diag *d)
{
    die_fail("level %u: %s: %s (rerun to resume)", k, what,
             lib_error(rc, d));
}

/* Level k's encoder: the options of level 0, the level's grid, the
 * times and units. */
static struct tvpal_encoder *open_level(const struct run *r, unsigned k,
                                        const struct level *lv)
{
    const struct opts *o = &r->o;
    struct tvpal_encoder *e = NULL;
    struct tvpal_diag d = {{0}};
    double s0[3], o0[3], sk[3], ok[3];
    grid_of(r, s0, o0);
    tvpal_level_grid(s0, o0, o->dims, lv->dims, sk, ok);
    int rc = tvpal_encoder_open(&e, lv->out, lv->dims, r->T, &d);
    /* Every level stores level 0's axes (FORMAT.md 2.1). */
    const struct { enum tvpal_param p; double v; } set[] = {
        {TVPAL_PARAM_WINDOW, o->window}, {TVPAL_PARAM_NODES, o->nodes},
        {TVPAL_PARAM_AXES, o->axes}, {TVPAL_PARAM_THREADS, r->nthreads},
        {TVPAL_PARAM_TABLE, o->table_format}, {TVPAL_PARAM_REFINE, o->refine},
        {TVPAL_PARAM_NAIVE, o->naive},
        {TVPAL_PARAM_TRANSFORM, o->klt ? TVPAL_TRANSFORM_KLT
                                       : TVPAL_TRANSFORM_DCT},
        {TVPAL_PARAM_ALLOC, o->alloc_mse ? TVPAL_ALLOC_GREEDY_MSE
                                         : TVPAL_ALLOC_VARIANCE},
        /* A level interrupted is encoded again (it is 1/7 of the work),
         * so its steps need no checkpoints. */
        {TVPAL_PARAM_CHECKPOINT, 0}};
    for (size_t i = 0; rc == 0 && i < sizeof set / sizeof *set; i++)
        rc = tvpal_encoder_set(e, set[i].p, set[i].v, &d);
    if (rc == 0)
        rc = tvpal_encoder_set_grid(e, sk, ok, &d);
    if (rc == 0 && r->times)
        rc = tvpal_encoder_set_times(e, r->times, r->time_units, &d);
    if (rc == 0)
        rc = tvpal_encoder_set_units(e, r->units, &d);
    if (rc < 0) {
        tvpal_encoder_abort(e);
        level_failed(k, "its encoder", rc, &d);
    }
    return e;
}

/* The levels being made: up to `last`, the last one encoded in this run;
 * the source planes of level 1 come from a whole step in memory (level 0
 * encoding, one pass) or from ps (read again after level 0). */
struct levels {
    struct level lv[TVPAL_LEVELS_MAX + 1];
    unsigned encoded, last, fault_k;
    struct plane_src ps;
    float *fine[2];
};

/* Step t of levels 1..last into lv[k].vol: level 1 from vol0 (the whole
 * step) or the source's planes, each next level from the one before. */
static void make_levels(struct levels *ls, uint32_t t, const float *vol0)
{
    struct level *lv = ls->lv;
    for (unsigned k = 1; k <= ls->last; k++) {
        const uint32_t *fd = k == 1 ? ls->ps.dims : lv[k - 1].dims;
        const size_t fplane = (size_t)fd[0] * fd[1];
        const size_t cplane = (size_t)lv[k].dims[0] * lv[k].dims[1];
        for (uint32_t z = 0; z < lv[k].dims[2]; z++) {
            const float *f[2] = {NULL, NULL};
            for (uint32_t dz = 0; dz < 2 && 2 * z + dz < fd[2]; dz++) {
                const size_t fz = 2 * z + dz;
                if (k > 1) {
                    f[dz] = lv[k - 1].vol + fz * fplane;
                } else if (vol0) {
                    f[dz] = vol0 + fz * fplane;
                } else {
                    read_plane(&ls->ps, t, (uint32_t)fz, ls->fine[dz]);
                    f[dz] = ls->fine[dz];
                }
            }
            tvpal_level_average_planes(f[0], f[1], fd[0], fd[1],
                                       lv[k].vol + z * cplane);
        }
    }
}

struct levels *levels_open(struct run *r, int inline_steps)
{
    const unsigned L = r->o.levels;
    struct levels *ls = calloc(1, sizeof *ls);
    if (!ls)
        die_fail("out of memory");
    /* Test hook: TVPAL_ENCODE_FAULT_LEVEL=k fails the run as level k's
     * encode would, once the levels before it are complete. */
    const char *fault = getenv("TVPAL_ENCODE_FAULT_LEVEL");
    ls->fault_k = fault ? (unsigned)atoi(fault) : 0;
    ls->encoded = ls->fault_k >= 1 && ls->fault_k <= L ? ls->fault_k - 1 : L;
    struct level *lv = ls->lv;
    for (unsigned k = 1; k <= ls->encoded; k++) {
        tvpal_level_dims(r->o.dims, k, lv[k].dims);
        if (asprintf(&lv[k].out, "%s/level-%u", r->partial, k) < 0)
            die_fail("out of memory");
        if (!tvpal_exists(lv[k].out))
            ls->last = k;
    }
    ls->ps = (struct plane_src){.r = r, .slab_t = -1};
    memcpy(ls->ps.dims, r->o.dims, sizeof ls->ps.dims);
    if (!ls->last)
        return ls;
    const uint64_t plane = (uint64_t)r->o.dims[0] * r->o.dims[1];
    if (!inline_steps) {
        uint64_t planes = r->plan.box_voxels_max / plane;
        ls->ps.slab_planes = (uint32_t)(planes < 1 ? 1
                                        : planes > r->o.dims[2] ? r->o.dims[2]
                                                                : planes);
        if (!(ls->ps.slab = malloc(ls->ps.slab_planes * plane *
                                   sizeof(float))) ||
            !(ls->fine[0] = malloc(plane * sizeof(float))) ||
            !(ls->fine[1] = malloc(plane * sizeof(float))))
            die_fail("out of memory (%u planes of %llu voxels)",
                     ls->ps.slab_planes, (unsigned long long)plane);
    }
    for (unsigned k = 1; k <= ls->last; k++) {
        const uint32_t *d = lv[k].dims;
        if (!(lv[k].vol = malloc((size_t)d[0] * d[1] * d[2] * sizeof(float))))
            die_fail("out of memory (a step of level %u)", k);
        if (tvpal_exists(lv[k].out))
            continue;
        if (!r->o.quiet)
            msg("level %u of %u: %ux%ux%u%s", k, L, d[0], d[1], d[2],
                inline_steps ? ", beside level 0" : "");
        lv[k].enc = open_level(r, k, &lv[k]);
    }
    return ls;
}

void levels_step(struct run *r, struct levels *ls, uint32_t t,
                 const float *vol0)
{
    if (!ls->last)
        return;
    make_levels(ls, t, vol0);
    for (unsigned k = 1; k <= ls->last; k++) {
        struct tvpal_diag d = {{0}};
        const uint32_t *dk = ls->lv[k].dims;
        int rc = ls->lv[k].enc
                     ? tvpal_encoder_push(ls->lv[k].enc, ls->lv[k].vol,
                                          TVPAL_FLOAT32,
                                          (size_t)dk[0] * dk[1] * dk[2],
                                          NULL, &d)
                     : 0;
        if (rc < 0)
            level_failed(k, "its encode", rc, &d);
    }
}

void levels_close(struct run *r, struct levels *ls)
{
    for (unsigned k = 1; k <= ls->last; k++) {
        struct tvpal_diag d = {{0}};
        int rc = ls->lv[k].enc ? tvpal_encoder_finish(ls->lv[k].enc, &d) : 0;
        ls->lv[k].enc = NULL;
        if (rc < 0)
            level_failed(k, "its dataset", rc, &d);
    }
    const unsigned encoded = ls->encoded, fault_k = ls->fault_k;
    levels_free(ls);
    if (encoded < r->o.levels)
        die_fail("level %u: failed as TVPAL_ENCODE_FAULT_LEVEL asks (rerun "
                 "to resume)", fault_k);
}

void levels_free(struct levels *ls)
{
    if (!ls)
        return;
    for (unsigned k = 1; k <= TVPAL_LEVELS_MAX; k++) {
        tvpal_encoder_abort(ls->lv[k].enc);
        free(ls->lv[k].vol);
        free(ls->lv[k].out);
    }
    free(ls->ps.slab);
    free(ls->fine[0]);
    free(ls->fine[1]);
    free(ls);
}

void remove_levels_beyond(const struct run *r)
{
    for (unsigned k = r->o.levels + 1; k <= TVPAL_LEVELS_MAX; k++) {
        static const char *const sfx[] = {"", ".src", ".partial",
                                          ".partial.lock"};
        for (int i = 0; i < 4; i++) {
            char *p = NULL;
            if (asprintf(&p, "%s/level-%u%s", r->partial, k, sfx[i]) < 0)
                die_fail("out of memory");
            if (i == 3)
                unlink(p);
            else
                tvpal_rmtree(p);
            free(p);
        }
    }
}

void encode_levels(struct run *r)
{
    if (r->lvs) {   /* made beside level 0: only finished here */
        struct levels *ls = r->lvs;
        r->lvs = NULL;
        levels_close(r, ls);
        return;
    }
    /* The ring is done with: its memory goes to the slabs and levels. */
    release_ring(r);
    struct levels *ls = levels_open(r, 0);
    for (uint32_t t = 0; ls->last && t < r->T; t++)
        levels_step(r, ls, t, NULL);
    levels_close(r, ls);
}
