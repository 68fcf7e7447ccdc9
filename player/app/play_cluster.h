/* play_cluster.h: tvpal-play's cluster glue: the job's communicator, and
 * how a rank reports an error so that no rank waits forever.
 *
 * Under MPI only rank 0 reports what every rank finds alike (options,
 * dataset-wide errors: play_die); a failure of one rank is reported by that
 * rank and ends the whole job (play_die_rank); a step that may fail on some
 * ranks only is settled by play_check_all.  With one process all three
 * simply print and exit. */
#ifndef PLAY_CLUSTER_H
#define PLAY_CLUSTER_H

#include "tvpal_comm.h"
#include "tvpal_player.h"

/* The job's communicator: size 1 without an MPI launcher. */
extern struct tvpal_comm play_comm;

/* Starts play_comm (MPI when a launcher started this process); on failure
 * reports and exits 1. */
void play_cluster_start(int *argc, char ***argv);
/* Ends it (collective). */
void play_cluster_end(void);
/* Whether more than one rank plays. */
int play_cluster_multi(void);
/* Whether the job runs under MPI (then each rank plays its node shard,
 * even as the only rank). */
int play_cluster_mpi(void);

/* printf-style message on rank 0, then every rank ends with `code`. */
void play_die(int code, const char *fmt, ...)
    __attribute__((format(printf, 2, 3), noreturn));
/* Message from this rank (naming it under MPI), then the whole job ends. */
void play_die_rank(int code, const char *fmt, ...)
    __attribute__((format(printf, 2, 3), noreturn));
/* Collective: every rank's rc and msg; rank 0 prints each failure naming
 * its rank, and all ranks exit with `code` when any rc < 0. */
void play_check_all(int rc, const char *msg, int code);

/* The ghost row exchange of cross frames (tvpal_player.h) over play_comm:
 * rank r swaps its boundary rows with ranks r - 1 and r + 1, pairs (2i,
 * 2i + 1) first, then (2i + 1, 2i + 2), so no rank waits on a chain.  A
 * row travels as a 16-byte header (slice, generation, has indices), its
 * 256 values, and its indices only when they changed since last sent.
 * ctx is unused. */
int play_ghost_exchange(void *ctx, const struct tvpal_ghost_row mine[2],
                        struct tvpal_ghost_row theirs[2], size_t idx_bytes,
                        struct tvpal_diag *diag);

/* Where rank `rank` finds its shard: pattern with %r replaced by the rank,
 * or DIR/node-RANK without a pattern.  malloc'd; NULL when out of memory. */
char *play_shard_dir(const char *dir, const char *pattern, int rank);

#endif
