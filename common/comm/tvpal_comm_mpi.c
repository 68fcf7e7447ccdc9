/* tvpal_comm_mpi.c: tvpal_comm over MPI (the only file including mpi.h). */
#include "tvpal_comm.h"

#include <mpi.h>
#include <stdlib.h>
#include <string.h>

#define TAG_SIZE 71
#define TAG_DATA 72

static MPI_Comm comm_of(struct tvpal_comm *c)
{
    return *(MPI_Comm *)c->impl;
}

/* Messages may exceed INT_MAX bytes only for absurd images; refuse. */
static int fits(size_t n)
{
    return n <= (size_t)0x7FFFFFFF;
}

static int mpi_sendrecv(struct tvpal_comm *c, int peer, const void *sbuf,
                        size_t sbytes, void *rbuf, size_t rcap, size_t *rbytes)
{
    unsigned long long s = sbytes, r = 0;
    if (!fits(sbytes) || !fits(rcap))
        return TVPAL_E_OVERFLOW;
    if (MPI_Sendrecv(&s, 1, MPI_UNSIGNED_LONG_LONG, peer, TAG_SIZE, &r, 1,
                     MPI_UNSIGNED_LONG_LONG, peer, TAG_SIZE, comm_of(c),
                     MPI_STATUS_IGNORE) != MPI_SUCCESS)
        return TVPAL_E_SYS;
    if (r > rcap)
        return TVPAL_E_OVERFLOW;
    if (MPI_Sendrecv(sbuf, (int)sbytes, MPI_BYTE, peer, TAG_DATA, rbuf, (int)r,
                     MPI_BYTE, peer, TAG_DATA, comm_of(c),
                     MPI_STATUS_IGNORE) != MPI_SUCCESS)
        return TVPAL_E_SYS;
    c->bytes_sent += sbytes;
    *rbytes = r;
    return 0;
}

static int mpi_send(struct tvpal_comm *c, int peer, const void *buf,
                    size_t bytes)
{
    unsigned long long s = bytes;
    if (!fits(bytes))
        return TVPAL_E_OVERFLOW;
    if (MPI_Send(&s, 1, MPI_UNSIGNED_LONG_LONG, peer, TAG_SIZE, comm_of(c)) !=
            MPI_SUCCESS ||
        MPI_Send(buf, (int)bytes, MPI_BYTE, peer, TAG_DATA, comm_of(c)) !=
            MPI_SUCCESS)
        return TVPAL_E_SYS;
    c->bytes_sent += bytes;
    return 0;
}

static int mpi_recv(struct tvpal_comm *c, int peer, void *buf, size_t cap,
                    size_t *bytes)
{
    unsigned long long r = 0;
    if (MPI_Recv(&r, 1, MPI_UNSIGNED_LONG_LONG, peer, TAG_SIZE, comm_of(c),
                 MPI_STATUS_IGNORE) != MPI_SUCCESS)
        return TVPAL_E_SYS;
    if (r > cap)
        return TVPAL_E_OVERFLOW;
    if (MPI_Recv(buf, (int)r, MPI_BYTE, peer, TAG_DATA, comm_of(c),
                 MPI_STATUS_IGNORE) != MPI_SUCCESS)
        return TVPAL_E_SYS;
    *bytes = r;
    return 0;
}

static int mpi_gatherv(struct tvpal_comm *c, const void *sbuf, size_t sbytes,
                       void *rbuf, const size_t *counts, const size_t *displs)
{
    int *ic = NULL, *id = NULL;
    int rc = 0;
    if (!fits(sbytes))
        return TVPAL_E_OVERFLOW;
    if (c->rank == 0) {
        ic = malloc(sizeof *ic * (size_t)c->size);
        id = malloc(sizeof *id * (size_t)c->size);
        if (!ic || !id) {
            free(ic);
            free(id);
            return TVPAL_E_NOMEM;
        }
        for (int i = 0; i < c->size; i++) {
            if (!fits(counts[i]) || !fits(displs[i]))
                rc = TVPAL_E_OVERFLOW;
            ic[i] = (int)counts[i];
            id[i] = (int)displs[i];
        }
    }
    if (rc == 0 && MPI_Gatherv(sbuf, (int)sbytes, MPI_BYTE, rbuf, ic, id,
                               MPI_BYTE, 0, comm_of(c)) != MPI_SUCCESS)
        rc = TVPAL_E_SYS;
    if (c->rank != 0)
        c->bytes_sent += sbytes;
    free(ic);
    free(id);
    return rc;
}

static int mpi_gather(struct tvpal_comm *c, const void *sbuf, size_t bytes,
                      void *rbuf)
{
    return MPI_Gather(sbuf, (int)bytes, MPI_BYTE, rbuf, (int)bytes, MPI_BYTE, 0,
                      comm_of(c)) == MPI_SUCCESS ? 0 : TVPAL_E_SYS;
}

static int mpi_bcast(struct tvpal_comm *c, void *buf, size_t bytes, int root)
{
    return MPI_Bcast(buf, (int)bytes, MPI_BYTE, root, comm_of(c)) ==
                   MPI_SUCCESS ? 0 : TVPAL_E_SYS;
}

static int mpi_allmax(struct tvpal_comm *c, double *v, int n)
{
    return MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_DOUBLE, MPI_MAX,
                         comm_of(c)) == MPI_SUCCESS ? 0 : TVPAL_E_SYS;
}

static void mpi_barrier(struct tvpal_comm *c)
{
    MPI_Barrier(comm_of(c));
}

static void mpi_abort(struct tvpal_comm *c, int code)
{
    MPI_Abort(comm_of(c), code);
    exit(code);
}

/* Ends the communicator and MPI (collective). */
static void mpi_finalize(struct tvpal_comm *c)
{
    if (c->impl) {
        MPI_Comm_free((MPI_Comm *)c->impl);
        free(c->impl);
        c->impl = NULL;
    }
    int done = 0;
    MPI_Finalized(&done);
    if (!done)
        MPI_Finalize();
}

int tvpal_comm_mpi_open(struct tvpal_comm *c, int *argc, char ***argv,
                        struct tvpal_diag *diag)
{
    int ok = 0;
    memset(c, 0, sizeof *c);
    MPI_Initialized(&ok);
    if (!ok && MPI_Init(argc, argv) != MPI_SUCCESS)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "MPI_Init failed");
    MPI_Comm *dup = malloc(sizeof *dup);
    if (!dup)
        return TVPAL_E_NOMEM;
    if (MPI_Comm_dup(MPI_COMM_WORLD, dup) != MPI_SUCCESS) {
        free(dup);
        return tvpal_diag_set(diag, TVPAL_E_SYS, "MPI_Comm_dup failed");
    }
    /* Errors come back as codes, not as an abort inside the library. */
    MPI_Comm_set_errhandler(*dup, MPI_ERRORS_RETURN);
    c->impl = dup;
    c->name = "mpi";
    MPI_Comm_rank(*dup, &c->rank);
    MPI_Comm_size(*dup, &c->size);
    c->sendrecv = mpi_sendrecv;
    c->send = mpi_send;
    c->recv = mpi_recv;
    c->gatherv = mpi_gatherv;
    c->gather = mpi_gather;
    c->bcast = mpi_bcast;
    c->allmax = mpi_allmax;
    c->barrier = mpi_barrier;
    c->abort = mpi_abort;
    c->finalize = mpi_finalize;
    return 0;
}

int tvpal_comm_mpi_built(void)
{
    return 1;
}
