/* tvpal_comm.h: the communication the cluster player needs, behind a table
 * of functions (after IceT's src/communication): compositing strategies
 * and the player call these, never MPI directly.  tvpal_comm_mpi.c is the
 * only file that includes mpi.h; it talks on a duplicate of the caller's
 * communicator.  A single-process communicator (size 1) needs no MPI.
 * All functions return 0 or a negative TVPAL_E_* code.
 */
#ifndef TVPAL_COMM_H
#define TVPAL_COMM_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_error.h"

struct tvpal_comm {
    int rank, size;
    void *impl;
    /* Exchange with one partner: send sbytes, receive into rbuf (capacity
     * rcap); *rbytes gets the size received.  Sizes may differ. */
    int (*sendrecv)(struct tvpal_comm *c, int peer, const void *sbuf,
                    size_t sbytes, void *rbuf, size_t rcap, size_t *rbytes);
    /* One-way messages (fold of extra ranks, gather-to-root baseline). */
    int (*send)(struct tvpal_comm *c, int peer, const void *buf,
                size_t bytes);
    int (*recv)(struct tvpal_comm *c, int peer, void *buf, size_t cap,
                size_t *bytes);
    /* Variable-size gather of bytes to rank 0 (rbuf, counts, displs used
     * on rank 0 only; counts in bytes, one per rank). */
    int (*gatherv)(struct tvpal_comm *c, const void *sbuf, size_t sbytes,
                   void *rbuf, const size_t *counts, const size_t *displs);
    /* Gather of one fixed-size record per rank to rank 0 (sizes of the
     * variable gather, per-rank timings). */
    int (*gather)(struct tvpal_comm *c, const void *sbuf, size_t bytes,
                  void *rbuf);
    int (*bcast)(struct tvpal_comm *c, void *buf, size_t bytes, int root);
    /* Maximum over ranks of n doubles, result everywhere. */
    int (*allmax)(struct tvpal_comm *c, double *v, int n);
    void (*barrier)(struct tvpal_comm *c);
    /* Ends the whole job (a rank that cannot go on must not leave the
     * others waiting). */
    void (*abort)(struct tvpal_comm *c, int code);
    uint64_t bytes_sent;       /* counted by the implementation */
};

/* The trivial communicator of one process. */
void tvpal_comm_self(struct tvpal_comm *c);

#ifdef HAVE_MPI
/* MPI over a duplicate of MPI_COMM_WORLD (MPI_Init must have run:
 * tvpal_comm_mpi_init does it).  Returns 0 or TVPAL_E_SYS. */
int tvpal_comm_mpi_init(int *argc, char ***argv);
int tvpal_comm_mpi(struct tvpal_comm *c);
void tvpal_comm_mpi_finalize(struct tvpal_comm *c);
#endif

#endif
