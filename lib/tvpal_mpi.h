/* tvpal_mpi.h: libtvpal's collective encode over MPI (tvpal.h, "encoding
 * on many ranks"), header-only.
 *
 * libtvpal itself links no MPI: an MPI program includes this header, which
 * builds the two operations of struct tvpal_collective from MPI_Gather and
 * MPI_Bcast on a duplicate of the caller's communicator (the encoder's
 * messages never meet the program's), owned by the encoder and freed with
 * it.  Build with `pkg-config --cflags --libs ompi-c tvpal` (or mpicc).
 *
 *     uint32_t z0, nz;
 *     tvpal_slab(NZ, size, rank, &z0, &nz);   // this rank's planes
 *     tvpal_encoder_open(&e, "out.tvpal", dims, T, &d);  // the whole grid
 *     tvpal_encoder_set_mpi(e, MPI_COMM_WORLD, z0, nz, &d);
 *     for each step: tvpal_encoder_push(e, slab, TVPAL_FLOAT32,
 *                                       (size_t)NX * NY * nz, NULL, &d);
 *     tvpal_encoder_finish(e, &d);            // on every rank
 */
#ifndef TVPAL_MPI_H
#define TVPAL_MPI_H

#include <limits.h>
#include <stdlib.h>

#include <mpi.h>

#include "tvpal.h"

static inline int tvpal_mpi_gather_(void *ctx, const void *send,
                                    size_t bytes, void *recv)
{
    if (bytes > INT_MAX)
        return -1;
    return MPI_Gather(send, (int)bytes, MPI_BYTE, recv, (int)bytes, MPI_BYTE,
                      0, *(MPI_Comm *)ctx) == MPI_SUCCESS
               ? 0
               : -1;
}

static inline int tvpal_mpi_bcast_(void *ctx, void *buf, size_t bytes)
{
    if (bytes > INT_MAX)
        return -1;
    return MPI_Bcast(buf, (int)bytes, MPI_BYTE, 0, *(MPI_Comm *)ctx) ==
                   MPI_SUCCESS
               ? 0
               : -1;
}

static inline void tvpal_mpi_release_(void *ctx)
{
    MPI_Comm_free((MPI_Comm *)ctx);
    free(ctx);
}

/* Makes e this process's rank of comm in a collective encode of the
 * planes z0 .. z0 + nz - 1 (tvpal_slab's for its rank in comm):
 * tvpal_encoder_set_collective with comm's rank and size.  Collective over
 * comm (it duplicates comm): every rank calls it.  0, or the codes of
 * tvpal_encoder_set_collective, or TVPAL_E_SYS (an MPI call failed). */
static inline int tvpal_encoder_set_mpi(struct tvpal_encoder *e,
                                        MPI_Comm comm, uint32_t z0,
                                        uint32_t nz, struct tvpal_diag *diag)
{
    MPI_Comm dup;
    int rank, size;
    if (MPI_Comm_dup(comm, &dup) != MPI_SUCCESS)
        return TVPAL_E_SYS;
    MPI_Comm *own = (MPI_Comm *)malloc(sizeof *own);
    if (!own || MPI_Comm_rank(dup, &rank) != MPI_SUCCESS ||
        MPI_Comm_size(dup, &size) != MPI_SUCCESS) {
        free(own);
        MPI_Comm_free(&dup);
        return own ? TVPAL_E_SYS : TVPAL_E_NOMEM;
    }
    *own = dup;
    const struct tvpal_collective c = {rank, size, own, tvpal_mpi_gather_,
                                       tvpal_mpi_bcast_, tvpal_mpi_release_};
    return tvpal_encoder_set_collective(e, &c, z0, nz, diag);
}

#endif
