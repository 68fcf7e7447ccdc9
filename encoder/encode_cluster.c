/* encode_cluster.c: tvpal-encode as an MPI job (encode_cluster.h and the
 * comment below). */
#define _GNU_SOURCE
#include "encode_cluster.h"
#include "encode_levels.h"
#include "encode_output.h"
#include "encode_say.h"
#include "tvpal_comm.h"
#include "tvpal_cli.h"
#include "tvpal_dataset.h"
#include "tvpal_fs.h"
#include "tvpal_manifest.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---------------------------------------------------------------- cluster */

/* Under mpirun -np K --nodes K, rank R encodes only node R's shards (one
 * per axis encoded), reading only the boxes of the input its slabs need,
 * into its own node directory (OUTDIR.partial/node-R, or --shard-dir's on
 * a node-local disk).  The ranks then agree in ROUNDS rounds, each a
 * gather of every rank's state to rank 0 and rank 0's decision sent back:
 *   1. statistics: rank 0 sums them (each voxel is in one rank's slab of
 *      the axis that takes the statistics, encode_plan.c: z if encoded)
 *      and sends the source range and the manifest;
 *   2. every rank has finished and verified its shards and node manifest;
 *   3. every node directory is in place: rank 0 writes OUTDIR and renames
 *      it into place, the commit.
 * A rank that fails joins the round it would have reached with its
 * message: rank 0 prints it, and every rank ends with its code, none left
 * waiting.  A rank killed outright is ended by the launcher (mpirun ends
 * the job when a process dies); the checkpoints in the node directories
 * let the same command resume every rank. */

/* What a rank tells rank 0 in a round. */
struct round_head {
    int32_t code;            /* 0 ok, else the exit status */
    int32_t how;             /* enum ending of a failure */
    char text[900];          /* its message */
    double vmin, vmax;       /* round 1: statistics */
    uint64_t nonfinite, missing, counted, dropped;
    uint64_t bytes;          /* round 3: bytes of the rank's node
                              * directory (its files), */
    uint64_t shard_bytes;    /* of its shards, */
    uint64_t work;           /* voxel-samples it encoded, */
    double seconds;          /* in this many seconds */
};

/* Rank 0's decision. */
struct round_decision {
    int32_t code, how, bad_rank, nbad;
    double vmin, vmax;
    uint64_t bytes, text_len; /* round 1: the manifest's length */
};

#define ROUNDS 3

/* The job: this process's communicator, and the next round of the job's
 * agreement that a rank which fails joins with its message (0: one
 * process; above ROUNDS: the rounds are over). */
struct cluster {
    struct tvpal_comm comm;
    int round;
    struct round_head *heads;  /* rank 0: one per rank */
};

/* Gathers mine (and in round 1 the histogram fine, may be NULL on a
 * failing rank) to rank 0, which decides; returns the decision on every
 * rank.  The failure of the lowest rank wins; rank 0 prints it. */
static struct round_decision cluster_gather(struct cluster *cl,
                                            const struct round_head *mine,
                                            const uint64_t *fine,
                                            uint64_t *fine_sum)
{
    struct tvpal_comm *c = &cl->comm;
    struct round_decision dec = {0};
    const size_t K = (size_t)c->size;
    if (c->rank == 0 && !cl->heads && !(cl->heads = calloc(K, sizeof *cl->heads)))
        c->abort(c, TVPAL_EXIT_FAIL);
    if (c->gather(c, mine, sizeof *mine, cl->heads) < 0)
        c->abort(c, TVPAL_EXIT_FAIL);
    if (cl->round == 1) {
        /* The fine histograms, one rank at a time into rank 0's sum. */
        static uint64_t zero[TVPAL_CHECKPOINT_BINS];
        const size_t hb = sizeof zero;
        uint64_t *buf = c->rank == 0 ? malloc(hb * K) : NULL;
        if (c->rank == 0 && !buf)
            c->abort(c, TVPAL_EXIT_FAIL);
        if (c->gather(c, fine ? fine : zero, hb, buf) < 0)
            c->abort(c, TVPAL_EXIT_FAIL);
        for (size_t k = 0; c->rank == 0 && k < K; k++)
            for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++)
                fine_sum[b] = (k ? fine_sum[b] : 0) + buf[k * TVPAL_CHECKPOINT_BINS + b];
        free(buf);
    }
    if (c->rank == 0) {
        dec.bad_rank = -1;
        for (size_t k = 0; k < K; k++)
            if (cl->heads[k].code) {
                if (dec.bad_rank < 0) {
                    dec.bad_rank = (int32_t)k;
                    dec.code = cl->heads[k].code;
                    dec.how = cl->heads[k].how;
                }
                dec.nbad++;
            }
    }
    return dec;
}

/* Sends rank 0's decision (and round 1's manifest text) to every rank. */
static void cluster_decide(struct cluster *cl, struct round_decision *dec,
                           char **text)
{
    struct tvpal_comm *c = &cl->comm;
    if (c->bcast(c, dec, sizeof *dec, 0) < 0)
        c->abort(c, TVPAL_EXIT_FAIL);
    if (!dec->code && text && dec->text_len) {
        if (c->rank != 0 && !(*text = calloc(1, dec->text_len + 1)))
            c->abort(c, TVPAL_EXIT_FAIL);
        if (c->bcast(c, *text, dec->text_len, 0) < 0)
            c->abort(c, TVPAL_EXIT_FAIL);
    }
}

/* Rank 0 reports the failure decided; every rank removes its node's
 * partial output when the input was bad (a rerun would fail the same
 * way), and ends. */
static void cluster_end_failed(struct cluster *cl,
                               const struct round_decision *dec)
    __attribute__((noreturn));
static void cluster_end_failed(struct cluster *cl,
                               const struct round_decision *dec)
{
    cl->round = ROUNDS + 1;
    if (cl->comm.rank == 0) {
        const struct round_head *h = &cl->heads[dec->bad_rank];
        if (dec->bad_rank > 0)
            fprintf(stderr, PROG ": rank %d: %s\n", dec->bad_rank, h->text);
        else
            fprintf(stderr, PROG ": %s\n", h->text);
        if (dec->nbad > 1)
            fprintf(stderr, PROG ": %d ranks failed; the lowest is shown\n",
                    dec->nbad);
    }
    if (dec->how == DIE_INPUT)
        say_remove_bad_input_output();
    tvpal_comm_close(&cl->comm);
    exit(dec->code);
}

/* The relay of encode_say.h while the rounds run: a failing rank joins
 * the round the others will reach, with its message. */
static void cluster_fail(void *ctx, enum ending how, const char *text)
    __attribute__((noreturn));
static void cluster_fail(void *ctx, enum ending how, const char *text)
{
    struct cluster *cl = ctx;
    struct round_head h = {0};
    h.code = how == DIE_FAIL ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE;
    h.how = how;
    snprintf(h.text, sizeof h.text, "%s", text);
    uint64_t *sum = cl->comm.rank == 0 ? calloc(TVPAL_CHECKPOINT_BINS, 8)
                                       : NULL;
    struct round_decision dec = cluster_gather(cl, &h, NULL, sum);
    free(sum);
    cluster_decide(cl, &dec, NULL);
    cluster_end_failed(cl, &dec);
}

/* Bytes of this process's shard files (the rest of its node directory is
 * its manifest). */
static uint64_t own_shard_bytes(const struct run *r)
{
    uint64_t n = 0;
    for (uint32_t q = 0; q < r->nshard; q++) {
        char *p = shard_path(r, &r->sj[q]);
        struct stat st;
        if (p && stat(p, &st) == 0)
            n += (uint64_t)st.st_size;
        free(p);
    }
    return n;
}

/* Puts this rank's --shard-dir node directory in place (with --force an
 * existing one goes first). */
static void place_node_dir(const struct run *r)
{
    const char *fin = r->node_final;
    if (tvpal_exists(fin) && tvpal_rmtree(fin) < 0)
        die_fail("%s: cannot replace: %s", fin, strerror(errno));
    if (rename(r->ckdir, fin) < 0)
        die_fail("%s: cannot rename %s into place: %s", fin, r->ckdir,
                 strerror(errno));
}

/* Rank 0, round 1: the job's statistics from every rank's; a failure to
 * report goes into dec (and the lowest rank's text). */
static void cluster_stats(struct run *r, struct round_decision *dec,
                          const uint64_t *fine_sum, char **text)
{
    const struct cluster *cl = r->cl;
    struct tvpal_checkpoint_stats *st = &r->st;
    uint64_t dropped = 0;
    st->vmin = INFINITY;
    st->vmax = -INFINITY;
    st->nonfinite = st->missing = st->counted = 0;
    for (int k = 0; k < cl->comm.size; k++) {
        const struct round_head *h = &cl->heads[k];
        st->vmin = h->vmin < st->vmin ? h->vmin : st->vmin;
        st->vmax = h->vmax > st->vmax ? h->vmax : st->vmax;
        st->nonfinite += h->nonfinite;
        st->missing += h->missing;
        st->counted += h->counted;
        dropped += h->dropped;
    }
    memcpy(st->fine, fine_sum, TVPAL_CHECKPOINT_BINS * sizeof *st->fine);
    if (all_missing(r, cl->heads[0].text, sizeof cl->heads[0].text)) {
        *dec = (struct round_decision){TVPAL_EXIT_USAGE, DIE_INPUT, 0, 1,
                                       0, 0, 0, 0};
        return;
    }
    warn_dropped(dropped);
    warn_dominating_values(r);
    *text = manifest_text(r);
    dec->vmin = st->vmin;
    dec->vmax = st->vmax;
    dec->text_len = strlen(*text);
}

/* Rank 0, round 3, the commit: OUTDIR's manifest written, read back
 * (the nodes verified their own directories) and OUTDIR put in place,
 * last.  0, or < 0 with the reason in the round's text (the other ranks
 * wait for the decision). */
static int commit_output(struct run *r)
{
    struct cluster *cl = r->cl;
    char *why = cl->heads[0].text;
    const size_t cap = sizeof cl->heads[0].text;
    struct tvpal_diag wd = {{0}};
    char *path = NULL, *text = manifest_text(r);
    int rc = asprintf(&path, "%s/manifest.txt", r->partial) < 0
                 ? TVPAL_E_NOMEM
                 : tvpal_write_file_atomic(path, text, strlen(text), &wd);
    free(text);
    tvpal_fsync_dir(r->partial);
    if (rc < 0)
        snprintf(why, cap, "%s: cannot write manifest: %s", r->partial,
                 lib_error(rc, &wd));
    struct tvpal_manifest m = {0};
    if (rc == 0 && (rc = tvpal_manifest_load(path, &m, &wd)) < 0)
        snprintf(why, cap, "%s: written manifest does not verify: %s (%s)",
                 r->partial, lib_error(rc, &wd), tvpal_exists(r->o.outdir)
                     ? "the existing dataset is left as it was"
                     : "nothing was put in place");
    tvpal_manifest_clear(&m);
    free(path);
    if (rc == 0 && place_output(r, why, cap) < 0)
        rc = -1;
    return rc;
}

/* Rank 0, after the commit: what the summary says of the whole job, from
 * every rank's round head, OUTDIR's own manifest and the levels rank 0
 * wrote inside OUTDIR (the node directories are the ranks'). */
static void sum_cluster_sizes(struct run *r)
{
    const struct cluster *cl = r->cl;
    char *p = NULL;
    uint64_t b = 0;
    if (asprintf(&p, "%s/manifest.txt", r->o.outdir) >= 0 &&
        tvpal_tree_bytes(p, &b, NULL) == 0)
        r->cluster_bytes = b;
    free(p);
    for (unsigned k = 1; k <= r->o.levels; k++) {
        b = 0;
        if (asprintf(&p, "%s/level-%u", r->o.outdir, k) >= 0 &&
            tvpal_tree_bytes(p, &b, NULL) == 0)
            r->cluster_level_bytes += b;
        free(p);
    }
    r->cluster_bytes += r->cluster_level_bytes;
    for (int k = 0; k < cl->comm.size; k++) {
        r->cluster_bytes += cl->heads[k].bytes;
        r->cluster_shard_bytes += cl->heads[k].shard_bytes;
        r->cluster_work += cl->heads[k].work;
        if (cl->heads[k].seconds > r->cluster_seconds)
            r->cluster_seconds = cl->heads[k].seconds;
    }
}

/* MPI: the rounds after encoding (see "cluster" above): statistics, then
 * every rank's shards and node manifest finished and verified, then the
 * node directories in place and rank 0's commit of OUTDIR. */
void cluster_finish(struct run *r)
{
    struct cluster *cl = r->cl;
    const int root = cl->comm.rank == 0;
    /* --levels: rank 0 makes every level of every node from the source
     * read again and encodes them in this process (1/7 of the work), as
     * one process does after level 0, while the other ranks wait in round
     * 1 with their shards as their checkpoints left them: a failure here
     * ends every rank through that round, and a rerun resumes every rank
     * at its last step and keeps the levels that were complete. */
    if (root) /* an earlier run's levels beyond this run's go */
        remove_levels_beyond(r);
    if (root && r->o.levels)
        encode_levels(r);
    struct round_head h = {0};
    h.vmin = r->st.vmin;
    h.vmax = r->st.vmax;
    h.nonfinite = r->st.nonfinite;
    h.missing = r->st.missing;
    h.counted = r->st.counted;
    h.dropped = dropped_values(r);
    uint64_t *sum = root ? calloc(TVPAL_CHECKPOINT_BINS, sizeof *sum) : NULL;
    if (root && !sum)
        cl->comm.abort(&cl->comm, TVPAL_EXIT_FAIL);
    struct round_decision dec = cluster_gather(cl, &h, r->st.fine, sum);
    char *text = NULL;
    if (root && !dec.code)
        cluster_stats(r, &dec, sum, &text);
    free(sum);
    cluster_decide(cl, &dec, &text);
    if (dec.code)
        cluster_end_failed(cl, &dec);
    cl->round = 2;
    r->st.vmin = dec.vmin;
    r->st.vmax = dec.vmax;
    finish_shards(r);
    write_manifest(r->ckdir, text);
    free(text);
    struct tvpal_dataset *ds = NULL;
    struct tvpal_diag d = {{0}};
    if (tvpal_dataset_open_node(&ds, r->ckdir, r->node, r->o.nodes, &d) < 0)
        die_fail("%s: written node directory does not verify: %s", r->ckdir,
                 d.msg);
    tvpal_dataset_close(ds);
    memset(&h, 0, sizeof h);
    dec = cluster_gather(cl, &h, NULL, NULL);
    cluster_decide(cl, &dec, NULL);
    if (dec.code)
        cluster_end_failed(cl, &dec);
    cl->round = 3;
    memset(&h, 0, sizeof h);
    h.work = r->prog.work - r->prog.work_at_start;
    h.seconds = r->t_encode;
    tvpal_checkpoint_remove(r->ckdir, NULL);
    tvpal_fsync_dir(r->ckdir);
    /* Sizes (the checkpoint gone) before a rename moves the files. */
    h.shard_bytes = own_shard_bytes(r);
    if (tvpal_tree_bytes(r->ckdir, &h.bytes, &d) < 0)
        die_fail("%s: cannot size: %s", r->ckdir, d.msg);
    if (r->node_final)
        place_node_dir(r);
    dec = cluster_gather(cl, &h, NULL, NULL);
    if (root && !dec.code) {
        if (commit_output(r) < 0)
            dec = (struct round_decision){TVPAL_EXIT_FAIL, DIE_FAIL, 0, 1,
                                          0, 0, 0, 0};
        else
            sum_cluster_sizes(r);
    }
    cluster_decide(cl, &dec, NULL);
    if (dec.code)
        cluster_end_failed(cl, &dec);
    cl->round = ROUNDS + 1;
    say_relay(NULL, NULL);
}

/* Under an MPI launcher (tvpal_comm_launched): joins the job, one rank
 * per node shard.  One process otherwise, or as a job of one rank. */
void open_cluster(struct run *r, int *argc, char ***argv)
{
    struct tvpal_diag d = {{0}};
    struct cluster *cl = calloc(1, sizeof *cl);
    if (!cl)
        die_fail("out of memory");
    r->cl = cl;
    tvpal_comm_self(&cl->comm);
    if (!tvpal_comm_launched(NULL))
        return;
    if (tvpal_comm_open(&cl->comm, TVPAL_COMM_MPI, argc, argv, &d) < 0)
        die_usage("started by an MPI launcher, but %s", d.msg);
    if (cl->comm.size > 1) {
        r->mpi = 1;
        r->node = (uint32_t)cl->comm.rank;
        cl->round = 1; /* failures from here on go through the rounds */
        say_as_rank(cl->comm.rank);
        say_relay(cluster_fail, cl);
    }
}

int cluster_size(const struct run *r)
{
    return r->cl->comm.size;
}

void cluster_bcast(struct run *r, void *buf, size_t bytes)
{
    if (r->mpi && r->cl->comm.bcast(&r->cl->comm, buf, bytes, 0) < 0)
        die_fail("cannot share state between the ranks");
}

/* This process's checkpoint directory and, under MPI, its node's final
 * directory (--shard-dir); the rules --nodes and --shard-dir obey. */
void setup_cluster_dirs(struct run *r)
{
    const struct opts *o = &r->o;
    if (o->shard_pat && !r->mpi)
        die_usage("--shard-dir: for MPI runs (mpirun -np K " PROG
                  " --nodes K ...); one process writes OUTDIR/node-R");
    if (r->mpi && o->nodes != (uint32_t)r->cl->comm.size)
        die_usage("--nodes %u under %d MPI ranks: expected --nodes %d (one "
                  "rank per node shard)", o->nodes, r->cl->comm.size,
                  r->cl->comm.size);
    if (o->shard_pat && !strstr(o->shard_pat, "%r"))
        die_usage("--shard-dir \"%s\": expected %%r (the rank) in it",
                  o->shard_pat);
    r->ckdir = r->mpi ? node_partial(r, r->node) : strdup(r->partial);
    if (!r->ckdir)
        die_fail("out of memory");
    if (o->shard_pat) {
        if (!(r->node_final = tvpal_node_dir(NULL, o->shard_pat, r->node)))
            die_fail("out of memory");
        if (tvpal_exists(r->node_final) && !o->force)
            die_usage("%s: node directory already exists (use --force to "
                      "replace it)", r->node_final);
    }
    if (r->mpi && r->node == 0 && !o->dry_run) {
        /* OUTDIR.partial holds the node directories (or, with
         * --shard-dir, only the manifest): a one-process job's checkpoint
         * there is not this job's. */
        struct tvpal_diag d = {{0}};
        if (tvpal_mkdirs(r->partial, &d) < 0)
            die_usage("%s: cannot create output directory: %s", r->partial,
                      d.msg);
        tvpal_checkpoint_remove(r->partial, NULL);
    }
}

void cluster_close(struct run *r)
{
    struct cluster *cl = r->cl;
    if (!cl)
        return;
    say_relay(NULL, NULL);
    tvpal_comm_close(&cl->comm);
    free(cl->heads);
    free(cl);
    r->cl = NULL;
}
