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
    const char *name;          /* "self" or "mpi" */
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
     * others waiting); does not return. */
    void (*abort)(struct tvpal_comm *c, int code);
    /* Ends the communicator (collective; for MPI, MPI_Finalize).  Called
     * through tvpal_comm_close. */
    void (*finalize)(struct tvpal_comm *c);
    uint64_t bytes_sent;       /* counted by the implementation */
};

/* The trivial communicator of one process. */
void tvpal_comm_self(struct tvpal_comm *c);

/* Which communicator tvpal_comm_open starts. */
enum tvpal_comm_kind {
    TVPAL_COMM_AUTO,   /* MPI when an MPI launcher started the process */
    TVPAL_COMM_SELF,   /* one process */
    TVPAL_COMM_MPI     /* MPI (the process may be a singleton) */
};

/* Whether an MPI launcher started this process, from the environment
 * the launchers set: Open MPI's mpirun (OMPI_COMM_WORLD_SIZE), the PMI of
 * MPICH's and Intel MPI's Hydra and of Slurm's srun (PMI_SIZE, PMI_RANK),
 * PMIx (PMIX_RANK: Open MPI 5, srun --mpi=pmix), MVAPICH
 * (MV2_COMM_WORLD_SIZE).  TVPAL_COMM=self or TVPAL_COMM=mpi in the
 * environment overrides the guess.  When *launcher is non-NULL it gets the
 * variable that decided (static text), or NULL. */
int tvpal_comm_launched(const char **launcher);

/* Starts the communicator of `kind` in *c (AUTO: tvpal_comm_launched
 * decides).  argc/argv are given to MPI_Init, which may remove its own
 * arguments.  TVPAL_E_SYS when MPI cannot start or was not built (diag
 * says which and what to install).  Every open is ended by
 * tvpal_comm_close. */
int tvpal_comm_open(struct tvpal_comm *c, enum tvpal_comm_kind kind,
                    int *argc, char ***argv, struct tvpal_diag *diag);

/* Ends what tvpal_comm_open started (collective under MPI); c is then the
 * one-process communicator, so a late abort or close stays safe.  A
 * zeroed struct is a no-op. */
void tvpal_comm_close(struct tvpal_comm *c);

/* The MPI communicator (tvpal_comm_mpi.c, or tvpal_comm_mpi_none.c in a
 * build without MPI, which refuses): a duplicate of MPI_COMM_WORLD, after
 * MPI_Init when it has not run. */
int tvpal_comm_mpi_open(struct tvpal_comm *c, int *argc, char ***argv,
                        struct tvpal_diag *diag);
/* Whether this build has MPI (1) or refuses it (0). */
int tvpal_comm_mpi_built(void);

#endif
