/* tvpal_pool.c: the thread team of tvpal_pool.h.  The loop's indices are
 * handed out by an atomic counter; the team meets only at the start and
 * the end of a loop, under one mutex, and between loops every thread but
 * the caller sleeps on `go`. */
#define _GNU_SOURCE
#include "tvpal_pool.h"
#include "tvpal_error.h"

#include <pthread.h>
#include <sched.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

struct worker {
    struct tvpal_pool *p;
    unsigned tid;
};

struct tvpal_pool {
    unsigned nthreads;
    unsigned started;               /* threads running (tid 1..started) */
    pthread_t *threads;
    struct worker *workers;
    pthread_mutex_t mu;
    pthread_cond_t go;              /* a loop starts, or quit */
    pthread_cond_t done;            /* the last thread left the loop */
    /* The loop, written under mu before gen changes. */
    uint64_t gen;
    int quit;
    tvpal_pool_fn fn;
    void *ctx;
    size_t n;
    size_t next;                    /* atomic: the next index to hand out */
    unsigned busy;                  /* threads (not the caller) in the loop */
};

/* Runs indices until none are left. */
static void drain(struct tvpal_pool *p, tvpal_pool_fn fn, void *ctx, size_t n,
                  unsigned tid)
{
    for (;;) {
        size_t i = __atomic_fetch_add(&p->next, 1, __ATOMIC_RELAXED);
        if (i >= n)
            return;
        fn(ctx, i, tid);
    }
}

static void *worker_main(void *arg)
{
    struct worker *w = arg;
    struct tvpal_pool *p = w->p;
    /* Generation 0 is the pool's creation: a loop may have started before
     * this thread first took the lock, and it must still join it. */
    uint64_t seen = 0;
    pthread_mutex_lock(&p->mu);
    for (;;) {
        while (p->gen == seen && !p->quit)
            pthread_cond_wait(&p->go, &p->mu);
        if (p->quit)
            break;
        seen = p->gen;
        tvpal_pool_fn fn = p->fn;
        void *ctx = p->ctx;
        size_t n = p->n;
        pthread_mutex_unlock(&p->mu);
        drain(p, fn, ctx, n, w->tid);
        pthread_mutex_lock(&p->mu);
        if (--p->busy == 0)
            pthread_cond_signal(&p->done);
    }
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

int tvpal_pool_create(struct tvpal_pool **out, unsigned nthreads)
{
    *out = NULL;
    if (nthreads < 1 || nthreads > TVPAL_POOL_THREADS_MAX)
        return TVPAL_E_INVAL;
    struct tvpal_pool *p = calloc(1, sizeof *p);
    if (!p)
        return TVPAL_E_NOMEM;
    p->nthreads = nthreads;
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->go, NULL);
    pthread_cond_init(&p->done, NULL);
    if (nthreads > 1 &&
        (!(p->threads = calloc(nthreads, sizeof *p->threads)) ||
         !(p->workers = calloc(nthreads, sizeof *p->workers)))) {
        tvpal_pool_free(p);
        return TVPAL_E_NOMEM;
    }
    for (unsigned t = 1; t < nthreads; t++) {
        p->workers[t] = (struct worker){p, t};
        if (pthread_create(&p->threads[t], NULL, worker_main,
                           &p->workers[t]) != 0) {
            tvpal_pool_free(p);
            return TVPAL_E_SYS;
        }
        p->started = t;
    }
    *out = p;
    return 0;
}

void tvpal_pool_free(struct tvpal_pool *p)
{
    if (!p)
        return;
    pthread_mutex_lock(&p->mu);
    p->quit = 1;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    for (unsigned t = 1; t <= p->started; t++)
        pthread_join(p->threads[t], NULL);
    pthread_cond_destroy(&p->done);
    pthread_cond_destroy(&p->go);
    pthread_mutex_destroy(&p->mu);
    free(p->workers);
    free(p->threads);
    free(p);
}

unsigned tvpal_pool_threads(const struct tvpal_pool *p)
{
    return p ? p->nthreads : 1;
}

void tvpal_pool_for(struct tvpal_pool *p, size_t n, tvpal_pool_fn fn,
                    void *ctx)
{
    if (n == 0)
        return;
    /* One index, or one thread (or none but the caller): no one to wake. */
    if (!p || p->nthreads == 1 || n == 1) {
        for (size_t i = 0; i < n; i++)
            fn(ctx, i, 0);
        return;
    }
    pthread_mutex_lock(&p->mu);
    p->fn = fn;
    p->ctx = ctx;
    p->n = n;
    p->next = 0;
    p->busy = p->nthreads - 1;
    p->gen++;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    drain(p, fn, ctx, n, 0);
    pthread_mutex_lock(&p->mu);
    while (p->busy)
        pthread_cond_wait(&p->done, &p->mu);
    pthread_mutex_unlock(&p->mu);
}

unsigned tvpal_pool_default_threads(void)
{
    const char *env = getenv("OMP_NUM_THREADS");
    if (env && *env) {
        char *end;
        unsigned long v = strtoul(env, &end, 10);
        if ((*end == '\0' || *end == ',') && v >= 1 &&
            v <= TVPAL_POOL_THREADS_MAX)
            return (unsigned)v;
    }
    cpu_set_t set;
    if (sched_getaffinity(0, sizeof set, &set) == 0) {
        int c = CPU_COUNT(&set);
        if (c >= 1)
            return c > TVPAL_POOL_THREADS_MAX ? TVPAL_POOL_THREADS_MAX
                                              : (unsigned)c;
    }
    return 1;
}
