/* encode_cluster.h: tvpal-encode as an MPI job (encode_cluster.c): one
 * rank per node shard, libtvpal's collective over the job's
 * communicator, the round before the encode in which a rank that fails
 * the checks ends every rank, and the sizes rank 0 sums for the summary.
 * One process is a job of one rank.  The job's state is r->cl, made by
 * open_cluster and freed by cluster_close.  Above encode_output.h;
 * program code.
 */
#ifndef TVPAL_ENCODE_CLUSTER_H
#define TVPAL_ENCODE_CLUSTER_H

#include "encode.h"
#include "tvpal.h"

/* Joins the job under an MPI launcher (r->mpi, r->node), else one
 * process; from here on a failure on any rank ends every rank (through
 * cluster_ready's round until the encode). */
void open_cluster(struct run *r, int *argc, char ***argv);
/* The ranks of the job (1 for one process). */
int cluster_size(const struct run *r);
/* The job's communicator as libtvpal's collective (tvpal.h). */
struct tvpal_collective cluster_collective(struct run *r);
/* MPI: every rank has got through the checks before the encode (a rank
 * that failed them joined this round with its message through the relay:
 * rank 0 says it, every rank ends); from here on failures are the
 * library's, which every rank learns from its rounds. */
void cluster_ready(struct run *r);
/* MPI, after the dataset is in place: rank 0 learns every rank's bytes,
 * shard bytes, work and seconds for the summary (r->cluster_*). */
void cluster_sizes(struct run *r);
/* MPI, a failure every rank has from the library's rounds: cluster_say
 * prints text on stderr as this rank's ("rank R: " above 0); cluster_end
 * waits until every rank is there (so that rank 0 has said it before any
 * rank exits: the launcher ends the job at the first failed exit), leaves
 * the job and exits with code. */
void cluster_say(const struct run *r, const char *text);
void cluster_end(struct run *r, int code) __attribute__((noreturn));
/* Leaves the job (MPI_Finalize) and frees r->cl; NULL r->cl is a no-op. */
void cluster_close(struct run *r);

#endif
