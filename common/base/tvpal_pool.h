/* tvpal_pool.h: a fixed team of threads for parallel loops, whose idle
 * threads sleep.
 *
 * Why not OpenMP: libgomp's idle threads spin between parallel regions
 * (about 300000 pause loops, several milliseconds, unless the user sets
 * OMP_WAIT_POLICY=passive before the program starts: it is read once, when
 * the library loads).  The encoder runs two parallel loops per timestep
 * with serial work between them (checkpoint fsync, progress, record CRCs),
 * so on a small volume the spinning thread burned as much CPU as the
 * encoding itself: 2.3 s of user time at 2 threads against 0.9 s at one
 * (viscous fingers 64^3 x 99, N = 4).  Here a thread with nothing to do
 * waits on a condition variable, and CPU time stays the work's.
 *
 * Contract: tvpal_pool_for runs fn(ctx, i, tid) once for every i in
 * [0, n), handing out indices one at a time in increasing order (a dynamic
 * schedule), on the calling thread (tid 0) and the pool's threads
 * (tid 1 .. nthreads - 1); it returns when all have returned, and what
 * they wrote is then visible to the caller.  Which tid runs which i is not
 * fixed: results must not depend on it.  One loop at a time: the pool is
 * not reentrant and is driven by one thread at a time.  A NULL pool is a
 * team of one: the caller runs the loop (tid 0), so code that may or may
 * not be given threads has one loop for both.
 */
#ifndef TVPAL_POOL_H
#define TVPAL_POOL_H

#include <stddef.h>
#include <stdint.h>

#define TVPAL_POOL_THREADS_MAX 1024

struct tvpal_pool;

typedef void (*tvpal_pool_fn)(void *ctx, size_t i, unsigned tid);

/* Starts nthreads - 1 threads (nthreads 1..TVPAL_POOL_THREADS_MAX; the
 * caller is the first).  Returns 0, TVPAL_E_INVAL (nthreads out of
 * range), TVPAL_E_NOMEM or TVPAL_E_SYS (a thread could not be started); *out owned by the caller, released
 * with tvpal_pool_free. */
int tvpal_pool_create(struct tvpal_pool **out, unsigned nthreads);

/* Ends the threads and frees the pool; NULL is a no-op. */
void tvpal_pool_free(struct tvpal_pool *p);

/* Its threads, the caller included; 1 for NULL. */
unsigned tvpal_pool_threads(const struct tvpal_pool *p);

/* The parallel loop (see the contract above); n 0 returns at once; p NULL
 * runs it on the caller. */
void tvpal_pool_for(struct tvpal_pool *p, size_t n, tvpal_pool_fn fn,
                    void *ctx);

/* For a loop body that fails at index i: lowers *lowest to i (atomically;
 * start it at INT64_MAX), so that after the loop it holds the first
 * failing index, the one a serial loop would have stopped at. */
static inline void tvpal_pool_lowest(int64_t *lowest, int64_t i)
{
    int64_t cur = __atomic_load_n(lowest, __ATOMIC_RELAXED);
    while (i < cur && !__atomic_compare_exchange_n(lowest, &cur, i, 0,
                                                   __ATOMIC_RELAXED,
                                                   __ATOMIC_RELAXED))
        ;
}

/* The threads the machine offers this process: OMP_NUM_THREADS when set
 * to a whole number 1..TVPAL_POOL_THREADS_MAX (as the OpenMP programs of
 * a job honour it), else the CPUs of the process's affinity mask. */
unsigned tvpal_pool_default_threads(void);

#endif
