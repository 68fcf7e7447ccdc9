/* tt_ranks.h: a collective of threads for the API tests (struct
 * tvpal_collective over shared memory and a barrier): each thread is one
 * rank of `size`, its gather and broadcast as MPI's would be. */
#ifndef TT_RANKS_H
#define TT_RANKS_H

#include <pthread.h>
#include <string.h>

#define TT_RANKS_MAX 16

struct tt_group {
    pthread_barrier_t bar;
    int size;
    const void *send[TT_RANKS_MAX];
};

/* One rank: the collective's ctx. */
struct tt_member {
    struct tt_group *g;
    int rank;
};

static inline void tt_group_init(struct tt_group *g, int size)
{
    g->size = size;
    pthread_barrier_init(&g->bar, NULL, (unsigned)size);
}

static inline int tt_gather(void *ctx, const void *send, size_t bytes,
                            void *recv)
{
    struct tt_member *m = ctx;
    m->g->send[m->rank] = send;
    pthread_barrier_wait(&m->g->bar);
    if (m->rank == 0)
        for (int k = 0; k < m->g->size; k++)
            memcpy((char *)recv + k * bytes, m->g->send[k], bytes);
    pthread_barrier_wait(&m->g->bar);
    return 0;
}

static inline int tt_bcast(void *ctx, void *buf, size_t bytes)
{
    struct tt_member *m = ctx;
    if (m->rank == 0)
        m->g->send[0] = buf;
    pthread_barrier_wait(&m->g->bar);
    if (m->rank != 0)
        memcpy(buf, m->g->send[0], bytes);
    pthread_barrier_wait(&m->g->bar);
    return 0;
}

#endif
