/* play_levels.c: the levels of detail of the dataset being played (see
 * play.h). */
#define _GNU_SOURCE
#include "play.h"
#include "play_cluster.h"
#include "tvpal_cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>
#include <string.h>

#define PROG PLAY_PROG

uint64_t play_levels_memory(const struct play_opts *o)
{
    const long pages = sysconf(_SC_PHYS_PAGES), psz = sysconf(_SC_PAGE_SIZE);
    return o->mem_mib ? (uint64_t)o->mem_mib << 20
           : pages > 0 && psz > 0 ? (uint64_t)pages * (uint64_t)psz / 4
                                  : (uint64_t)256 << 20;
}

void play_levels_init(struct play_session *s)
{
    s->nlevels = 1 + s->m->levels;
    memset(s->lvl, 0, sizeof s->lvl);
    s->lvl[0] = s->pl;
    s->reduce = 1;
}

/* Output pixels per voxel of level 0 under view v (set up): the voxel's
 * side as the geometric mean of its three, in eye units, over a pixel's. */
double play_level0_pixels_per_voxel(const struct tvpal_view *v)
{
    double pix = fmin(2 * v->sx / v->width, 2 * v->sy / v->height);
    double vox = 1;
    for (int i = 0; i < 3; i++)
        vox *= 2 * v->half[i] / (v->dims[i] ? v->dims[i] : 1);
    vox = cbrt(vox);
    return pix > 0 ? vox / pix : 1;
}

unsigned play_level_auto(const struct play_session *s,
                         const struct tvpal_view *v0)
{
    double ppv = play_level0_pixels_per_voxel(v0);
    unsigned k = 0;
    /* The finest level whose voxels are at least half a pixel wide: no
     * pixel spans more than two of them along an axis (a finer level's
     * detail the image cannot show).  A cube seen whole at zoom 1 spans
     * the image with its diagonal, sqrt 3 sides: 512^3 into 512 pixels
     * has voxels of 0.58 pixel and draws level 0, 1024^3 its 512^3
     * level. */
    while (k + 1 < s->nlevels && !(ppv * (double)(1u << k) >= 0.5))
        k++;
    return k;
}

struct tvpal_player *play_level_player(struct play_session *s, unsigned k)
{
    if (k >= s->nlevels)
        k = s->nlevels - 1;
    if (s->lvl[k])
        return s->lvl[k];
    char *dir = NULL, *node_dir = NULL;
    if (asprintf(&dir, "%s/level-%u", s->o->dir, k) < 0)
        play_die_rank(1, "out of memory");
    /* Under MPI: the level's node directory in the dataset (the encoder's
     * layout; --shard-dir names level 0's alone). */
    if (play_cluster_mpi() && !(node_dir = play_shard_dir(dir, NULL, play_comm.rank)))
        play_die_rank(1, "out of memory");
    struct tvpal_diag d = {{0}};
    struct tvpal_player *p = NULL;
    struct tvpal_player_opts po = s->o->po;
    if (k > 0 && s->o->progressive) {
        /* --progressive: a coarser level's records in RAM, so that a jump
         * drawn from it reads nothing: level k within 1/2^k of --mem (else
         * of a quarter of the machine's memory), the levels together
         * within it; an axis that does not fit is streamed, keeping the
         * steps around the playhead within that memory (kept by
         * play_prog_keep as playback moves): a jump near the slider
         * still reads nothing. */
        const uint64_t all = play_levels_memory(s->o);
        po.keep_ahead = 0;
        po.incore = 1;
        po.keep_around = 1;
        po.mem_budget = all >> k ? all >> k : 1;
    }
    int rc = tvpal_player_open(&p, node_dir ? node_dir : dir, &po, &d);
    if (rc == 0) {
        const struct tvpal_manifest *m = tvpal_player_manifest(p);
        if (m->steps != s->m->steps || m->nodes != s->m->nodes ||
            m->axes_mask != s->m->axes_mask) {
            char ak[4], a0[4];
            tvpal_diag_set(&d, TVPAL_E_FORMAT, "%u steps on %u nodes, axes "
                           "%s; level 0 has %u on %u, axes %s", m->steps,
                           m->nodes, tvpal_axes_format(m->axes_mask, ak),
                           s->m->steps, s->m->nodes,
                           tvpal_axes_format(s->m->axes_mask, a0));
            rc = TVPAL_E_FORMAT;
        }
    }
    if (rc < 0)
        play_die_rank(1, "%s: level %u: %s", node_dir ? node_dir : dir, k,
                      d.msg);
    free(dir);
    free(node_dir);
    if (s->tf)
        tvpal_player_set_tf(p, s->tf, s->tf_opacity);
    tvpal_player_set_reduce(p, s->reduce);
    if (s->loop_set)
        (void)tvpal_player_loop(p, s->loop_first, s->loop_last);
    s->lvl[k] = p;
    return p;
}

void play_levels_loop(struct play_session *s, uint32_t first, uint32_t last)
{
    s->loop_set = 1;
    s->loop_first = first;
    s->loop_last = last;
    for (unsigned k = 0; k < s->nlevels; k++)
        if (s->lvl[k])
            (void)tvpal_player_loop(s->lvl[k], first, last);
}

void play_level_view(const struct play_session *s, unsigned k,
                     const struct tvpal_view *v0, struct tvpal_view *vk)
{
    *vk = *v0;
    if (k == 0)
        return;
    const struct tvpal_manifest *mk = tvpal_player_manifest(s->lvl[k]);
    /* The same box: level k's voxels are d0 / dk of level 0's; level 0's
     * spacing (1 on the unit grid) stays the opacity's unit. */
    double smin = 0;
    for (int i = 0; i < 3; i++) {
        double s0 = v0->spacing[i] > 0 ? v0->spacing[i] : 1.0;
        vk->dims[i] = mk->dims[i];
        vk->spacing[i] = s0 * v0->dims[i] / mk->dims[i];
        smin = i == 0 || s0 < smin ? s0 : smin;
    }
    vk->opacity_unit = smin;
    tvpal_view_setup(vk);
}

void play_levels_preload(struct play_session *s, const struct tvpal_view *v0)
{
    struct tvpal_diag d = {{0}};
    for (unsigned k = s->nlevels; k-- > 1;) {
        struct tvpal_view vk;
        struct tvpal_player *pk = play_level_player(s, k);
        play_level_view(s, k, v0, &vk);
        if (tvpal_player_open_axis(pk, vk.axis, &d) < 0)
            play_die_rank(1, "%s: level %u: %s", s->o->dir, k,
                          d.msg[0] ? d.msg : "cannot open");
    }
}

void play_levels_describe(const struct play_session *s,
                          const struct tvpal_view *v0, char *buf, size_t n)
{
    size_t at = 0;
    buf[0] = 0;
    for (unsigned k = 1; k < s->nlevels && at < n; k++) {
        if (!s->lvl[k])
            continue;
        struct tvpal_view vk;
        play_level_view(s, k, v0, &vk);
        const uint64_t held = tvpal_player_incore_bytes(s->lvl[k]);
        const unsigned kept = tvpal_player_kept(s->lvl[k], &vk, 0, NULL);
        int w = held ? snprintf(buf + at, n - at, "%slevel %u in RAM (%.1f MiB)",
                                at ? ", " : "", k, held / 1048576.0)
                     : snprintf(buf + at, n - at, "%slevel %u streamed (%u "
                                "steps each way kept)", at ? ", " : "", k,
                                kept);
        at += w > 0 ? (size_t)w : 0;
    }
}

void play_set_tf(struct play_session *s, const struct tvpal_tf *tf,
                 double opacity)
{
    s->tf = tf;
    s->tf_opacity = opacity;
    for (unsigned k = 0; k < s->nlevels; k++)
        if (s->lvl[k])
            tvpal_player_set_tf(s->lvl[k], tf, opacity);
}

void play_set_reduce(struct play_session *s, unsigned reduce)
{
    s->reduce = reduce;
    for (unsigned k = 0; k < s->nlevels; k++)
        if (s->lvl[k])
            tvpal_player_set_reduce(s->lvl[k], reduce);
}

uint64_t play_levels_incore_bytes(const struct play_session *s)
{
    uint64_t b = 0;
    for (unsigned k = 0; k < s->nlevels; k++)
        if (s->lvl[k])
            b += tvpal_player_incore_bytes(s->lvl[k]);
    return b;
}

void play_levels_close(struct play_session *s)
{
    for (unsigned k = 1; k < s->nlevels; k++) {
        tvpal_player_close(s->lvl[k]);
        s->lvl[k] = NULL;
    }
    s->lvl[0] = s->pl;
}
