/* tvpal-play: plays a tvpal dataset through the per-frame palette
 * renderers (cpu shear-warp, GLSL on OSMesa or a GLFW window, the
 * reference), headless to PNG frames and a timing CSV or in an interactive
 * window, on one process or on the ranks of an MPI job.
 *
 * The steps: start the job's communicator, read the options, open this
 * rank's part of the dataset, load the transfer functions, then run the
 * headless or the window loop.  play.h says where each part lives. */
#include "play.h"
#include "play_cluster.h"
#include "tvpal_cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG PLAY_PROG

/* This rank's shards: the dataset, or under MPI the node shard of the
 * rank (OUTDIR/node-r or --shard-dir). */
static void open_dataset(struct play_session *s)
{
    struct play_opts *o = s->o;
    struct tvpal_diag d = {{0}};
    char *node_dir = NULL;
    if (play_cluster_mpi()) {
        if (!(node_dir = play_shard_dir(o->dir, o->shard_pat, play_comm.rank)))
            play_die_rank(1, "out of memory");
        o->po.rank = (uint32_t)play_comm.rank;
        o->po.nranks = (uint32_t)play_comm.size;
        o->po.ghosts = play_ghost_exchange;
    }
    /* --progressive: level 0 streamed reads ahead within a quarter of the
     * levels' memory when reads fall behind the clock (play_prog_keep). */
    if (o->progressive && !play_cluster_multi() && !o->po.incore)
        o->po.keep_ahead = play_levels_memory(o) / 4;
    int rc = tvpal_player_open(&s->pl, node_dir ? node_dir : o->dir, &o->po,
                               &d);
    free(node_dir);
    play_check_all(rc, d.msg, 2);
    s->m = tvpal_player_manifest(s->pl);
    play_levels_init(s);
    if (o->level_given && o->level >= s->nlevels)
        play_die(2, "--level %u: expected 0..%u (the dataset has %u coarser "
                 "level%s)", o->level, s->nlevels - 1, s->nlevels - 1,
                 s->nlevels == 2 ? "" : "s");
    s->a = 0;
    s->b = s->m->steps - 1;
    uint32_t ab[2];
    /* T alone is the one step T:T. */
    if (o->steps && (strchr(o->steps, ':')
                         ? tvpal_parse_u32_pair(o->steps, ':', 0,
                                                s->m->steps - 1, ab)
                         : tvpal_parse_u32(o->steps, 0, s->m->steps - 1,
                                           &ab[0])) < 0)
        play_die(2, "--steps \"%s\": expected T or A:B within 0..%u",
                 o->steps, s->m->steps - 1);
    if (o->steps && !strchr(o->steps, ':'))
        ab[1] = ab[0];
    if (o->steps) {
        s->a = ab[0];
        s->b = ab[1];
    }
}

/* Every --tf file (checked now, on every rank), then the default from the
 * data's histogram, each with what the options change (--nan-color,
 * --tf-range). */
static void load_tfs(struct play_session *s)
{
    const struct tvpal_manifest *m = s->m;
    s->ntf = s->o->ntf;
    for (unsigned i = 0; i < s->ntf; i++) {
        struct tvpal_diag d = {{0}};
        char em[TVPAL_DIAG_MAX + 4096] = ""; /* a path and a detail */
        int rc = play_tf_load(s->o, m, i, &s->tfs[i], &d);
        if (rc < 0)
            snprintf(em, sizeof em, "%s: %s", s->o->tf_files[i], d.msg);
        play_check_all(rc, em, 2);
    }
    tvpal_tf_default(m->value_min, m->value_max, m->histogram,
                     TVPAL_HIST_BINS, &s->tfs[s->ntf]);
    play_tf_apply_options(s->o, &s->tfs[s->ntf]);
    play_set_tf(s, &s->tfs[0], s->o->opacity);
}

/* --mem: how many timesteps of one axis the budget holds. */
static void report_memory(const struct play_session *s)
{
    const uint32_t mib = s->o->mem_mib;
    if (!mib || play_comm.rank != 0)
        return;
    double per_step = (double)tvpal_player_axis_bytes(s->pl) / s->m->steps;
    double fit = (double)mib * 1048576.0 / per_step;
    printf("memory: %u MiB holds %.0f timesteps of one axis (%.2f MiB per "
           "timestep; %u in the dataset%s)\n", mib, floor(fit),
           per_step / 1048576.0, s->m->steps,
           fit >= s->m->steps ? ": in-core fits" : ": stream from disk");
}

int main(int argc, char **argv)
{
    static struct play_opts o;
    static struct play_session s = {.o = &o};
    play_cluster_start(&argc, &argv);
    if (play_options_parse(&o, argc, argv) > 0) {
        play_cluster_end();
        return 0;   /* --help, --version */
    }
    play_options_check(&o, play_comm.size);
    open_dataset(&s);
    load_tfs(&s);
    report_memory(&s);
    int status = o.window ? play_run_window(&s) : play_run_headless(&s);
    play_cluster_end();
    return status;
}
