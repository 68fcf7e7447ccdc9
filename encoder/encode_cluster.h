/* encode_cluster.h: tvpal-encode as an MPI job (encode_cluster.c): one
 * rank per node shard, and the rounds in which the ranks agree on the end
 * (a failing rank's message reaches rank 0 and every rank ends).  One
 * process is a job of one rank.  The job's state is r->cl, made by
 * open_cluster and freed by cluster_close.  Above encode_output.h;
 * program code.
 */
#ifndef TVPAL_ENCODE_CLUSTER_H
#define TVPAL_ENCODE_CLUSTER_H

#include "encode.h"

/* Joins the job under an MPI launcher (r->mpi, r->node), else one
 * process; from here on a failure on any rank ends every rank. */
void open_cluster(struct run *r, int *argc, char ***argv);
/* The ranks of the job (1 for one process). */
int cluster_size(const struct run *r);
/* Rank 0's bytes at buf replace every rank's (one process: nothing);
 * ends the program if it cannot. */
void cluster_bcast(struct run *r, void *buf, size_t bytes);
/* This process's checkpoint directory and its node's final directory
 * (--shard-dir); the rules --nodes and --shard-dir obey. */
void setup_cluster_dirs(struct run *r);
/* MPI: the rounds after encoding: statistics, every rank's shards and
 * node manifest verified, then the node directories in place and rank
 * 0's commit of OUTDIR. */
void cluster_finish(struct run *r);
/* Leaves the job (MPI_Finalize) and frees r->cl; NULL r->cl is a no-op. */
void cluster_close(struct run *r);

#endif
