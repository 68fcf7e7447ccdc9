/* tvpal_comm_self.c: the one-process communicator (see tvpal_comm.h). */
#include "tvpal_comm.h"

#include <stdlib.h>
#include <string.h>

static int self_sendrecv(struct tvpal_comm *c, int peer, const void *sbuf,
                         size_t sbytes, void *rbuf, size_t rcap,
                         size_t *rbytes)
{
    if (peer != 0 || sbytes > rcap)
        return TVPAL_E_INVAL;
    memcpy(rbuf, sbuf, sbytes);
    *rbytes = sbytes;
    return 0;
}

static int self_send(struct tvpal_comm *c, int peer, const void *buf,
                     size_t bytes)
{
    return TVPAL_E_INVAL; /* no other rank */
}

static int self_recv(struct tvpal_comm *c, int peer, void *buf, size_t cap,
                     size_t *bytes)
{
    return TVPAL_E_INVAL;
}

static int self_gatherv(struct tvpal_comm *c, const void *sbuf, size_t sbytes,
                        void *rbuf, const size_t *counts, const size_t *displs)
{
    memmove((char *)rbuf + displs[0], sbuf, sbytes);
    return 0;
}

static int self_gather(struct tvpal_comm *c, const void *sbuf, size_t bytes,
                       void *rbuf)
{
    memmove(rbuf, sbuf, bytes);
    return 0;
}

static int self_bcast(struct tvpal_comm *c, void *buf, size_t bytes, int root)
{
    return 0;
}

static int self_allmax(struct tvpal_comm *c, double *v, int n)
{
    return 0;
}

static void self_barrier(struct tvpal_comm *c) {}

static void self_abort(struct tvpal_comm *c, int code)
{
    exit(code);
}

void tvpal_comm_self(struct tvpal_comm *c)
{
    memset(c, 0, sizeof *c);
    c->name = "self";
    c->rank = 0;
    c->size = 1;
    c->sendrecv = self_sendrecv;
    c->send = self_send;
    c->recv = self_recv;
    c->gatherv = self_gatherv;
    c->gather = self_gather;
    c->bcast = self_bcast;
    c->allmax = self_allmax;
    c->barrier = self_barrier;
    c->abort = self_abort;
}
