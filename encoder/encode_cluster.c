/* encode_cluster.c: tvpal-encode as an MPI job (encode_cluster.h and the
 * comment below). */
#define _GNU_SOURCE
#include "encode_cluster.h"
#include "encode_say.h"
#include "tvpal.h"
#include "tvpal_comm.h"
#include "tvpal_cli.h"
#include "tvpal_fs.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* Under mpirun -np K --nodes K, rank R encodes only node R's shards (one
 * per axis encoded), reading only the boxes of the input its slabs need,
 * into its own node directory (OUTDIR.partial/node-R, or --shard-dir's on
 * a node-local disk): libtvpal's encoder with the job's communicator as
 * its collective (cluster_collective), whose rounds end every rank with
 * the failing rank's words.  Before it, the checks of the options and the
 * input run on every rank; a rank that fails one joins this program's
 * single round (cluster_ready) with its message through the relay of
 * encode_say.h, so that rank 0 says it once and every rank ends, none
 * left waiting.  A rank killed outright is ended by the launcher (mpirun
 * ends the job when a process dies); the checkpoints in the node
 * directories let the same command resume every rank.  After the
 * dataset is in place, rank 0 gathers every rank's sizes for the summary
 * (cluster_sizes). */

/* What a rank tells rank 0: in the round before the encode its failure,
 * after it its sizes. */
struct round_head {
    int32_t code;            /* 0 ok, else the exit status */
    int32_t how;             /* enum ending of a failure */
    char text[900];          /* its message */
    uint64_t bytes;          /* after: bytes of the rank's node directory
                              * (its files), */
    uint64_t shard_bytes;    /* of its shards, */
    uint64_t work;           /* voxel-samples it encoded, */
    double seconds;          /* in this many seconds */
};

/* Rank 0's decision. */
struct round_decision {
    int32_t code, how, bad_rank, nbad;
};

/* The job: this process's communicator and rank 0's heads of a round. */
struct cluster {
    struct tvpal_comm comm;
    struct round_head *heads;  /* rank 0: one per rank */
};

/* Gathers mine to rank 0, which decides: the failure of the lowest rank
 * wins.  The decision is rank 0's only (cluster_decide sends it). */
static struct round_decision cluster_gather(struct cluster *cl,
                                            const struct round_head *mine)
{
    struct tvpal_comm *c = &cl->comm;
    struct round_decision dec = {0};
    const size_t K = (size_t)c->size;
    if (c->rank == 0 && !cl->heads &&
        !(cl->heads = calloc(K, sizeof *cl->heads)))
        c->abort(c, TVPAL_EXIT_FAIL);
    if (c->gather(c, mine, sizeof *mine, cl->heads) < 0)
        c->abort(c, TVPAL_EXIT_FAIL);
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

/* Sends rank 0's decision to every rank. */
static void cluster_decide(struct cluster *cl, struct round_decision *dec)
{
    struct tvpal_comm *c = &cl->comm;
    if (c->bcast(c, dec, sizeof *dec, 0) < 0)
        c->abort(c, TVPAL_EXIT_FAIL);
}

/* Rank 0 reports the failure decided; every rank ends with its code. */
static void cluster_end_failed(struct cluster *cl,
                               const struct round_decision *dec)
    __attribute__((noreturn));
static void cluster_end_failed(struct cluster *cl,
                               const struct round_decision *dec)
{
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
    tvpal_comm_close(&cl->comm);
    exit(dec->code);
}

/* The relay of encode_say.h before the encode: a failing rank joins the
 * round the others will reach (cluster_ready), with its message. */
static void cluster_fail(void *ctx, enum ending how, const char *text)
    __attribute__((noreturn));
static void cluster_fail(void *ctx, enum ending how, const char *text)
{
    struct cluster *cl = ctx;
    struct round_head h = {0};
    h.code = how == DIE_FAIL ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE;
    h.how = how;
    snprintf(h.text, sizeof h.text, "%s", text);
    struct round_decision dec = cluster_gather(cl, &h);
    cluster_decide(cl, &dec);
    cluster_end_failed(cl, &dec);
}

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
        /* failures go through cluster_ready's round */
        say_as_rank(cl->comm.rank);
        say_relay(cluster_fail, cl);
    }
}

int cluster_size(const struct run *r)
{
    return r->cl->comm.size;
}

/* The collective of tvpal.h over the job's communicator. */
static int coll_gather(void *ctx, const void *send, size_t bytes, void *recv)
{
    struct tvpal_comm *c = ctx;
    return c->gather(c, send, bytes, recv) < 0;
}

static int coll_bcast(void *ctx, void *buf, size_t bytes)
{
    struct tvpal_comm *c = ctx;
    return c->bcast(c, buf, bytes, 0) < 0;
}

struct tvpal_collective cluster_collective(struct run *r)
{
    struct tvpal_comm *c = &r->cl->comm;
    return (struct tvpal_collective){c->rank, c->size, c, coll_gather,
                                     coll_bcast, NULL};
}

void cluster_ready(struct run *r)
{
    struct cluster *cl = r->cl;
    if (!r->mpi)
        return;
    const struct round_head h = {0};
    struct round_decision dec = cluster_gather(cl, &h);
    cluster_decide(cl, &dec);
    if (dec.code)
        cluster_end_failed(cl, &dec);
    say_relay(NULL, NULL);
}

/* Bytes of the shard files in directory dir (its axis-A.tvps). */
static uint64_t shard_files_bytes(const char *dir)
{
    uint64_t n = 0;
    for (unsigned a = 0; a < 3; a++) {
        char *p = NULL;
        struct stat st;
        if (asprintf(&p, "%s/axis-%c.tvps", dir, "xyz"[a]) >= 0 &&
            stat(p, &st) == 0)
            n += (uint64_t)st.st_size;
        free(p);
    }
    return n;
}

/* Rank 0: what the summary says of the whole job, from every rank's
 * sizes, OUTDIR's own manifest and the levels rank 0 wrote inside OUTDIR
 * (the node directories are the ranks'). */
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

void cluster_sizes(struct run *r)
{
    struct cluster *cl = r->cl;
    struct round_head h = {0};
    /* This rank's node directory, in place. */
    char *nd = tvpal_node_dir(r->o.shard_pat ? NULL : r->o.outdir,
                              r->o.shard_pat, r->node);
    if (!nd)
        die_fail("out of memory");
    if (tvpal_tree_bytes(nd, &h.bytes, NULL) < 0)
        h.bytes = 0;
    h.shard_bytes = shard_files_bytes(nd);
    free(nd);
    h.work = r->prog.work - r->prog.work_at_start;
    h.seconds = r->t_encode;
    if (cl->comm.rank == 0 && !cl->heads &&
        !(cl->heads = calloc((size_t)cl->comm.size, sizeof *cl->heads)))
        cl->comm.abort(&cl->comm, TVPAL_EXIT_FAIL);
    if (cl->comm.gather(&cl->comm, &h, sizeof h, cl->heads) < 0)
        cl->comm.abort(&cl->comm, TVPAL_EXIT_FAIL);
    if (cl->comm.rank == 0)
        sum_cluster_sizes(r);
}

void cluster_say(const struct run *r, const char *text)
{
    if (r->node)
        fprintf(stderr, PROG ": rank %u: %s\n", r->node, text);
    else
        fprintf(stderr, PROG ": %s\n", text);
}

void cluster_end(struct run *r, int code)
{
    struct tvpal_comm *c = &r->cl->comm;
    fflush(stderr);
    c->barrier(c);
    tvpal_comm_close(c);
    exit(code);
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
