/* test-pool: tvpal_pool's parallel loop runs every index exactly once,
 * with thread ids in range and the caller as thread 0, for loops shorter
 * and longer than the team (a NULL pool: the caller alone), back to back;
 * tvpal_pool_lowest finds the first failing index; the environment's
 * thread count;
 * and idle threads sleep instead of spinning (the reason the pool exists):
 * a 4-thread team left idle for 200 ms of serial gaps uses a small share
 * of one CPU, where libgomp's default spin burns them whole. */
#define _GNU_SOURCE
#include "tvpal_error.h"
#include "tvpal_pool.h"
#include "tvpal_test.h"

#include <pthread.h>
#include <sys/resource.h>
#include <time.h>

#define MAXN 5000

struct ctx {
    unsigned nthreads;
    unsigned char hits[MAXN];       /* per index: how often it ran */
    unsigned bad_tid;
    unsigned tid0_ran;
    pthread_t caller;
    unsigned caller_not_tid0;
};

static void body(void *arg, size_t i, unsigned tid)
{
    struct ctx *c = arg;
    __atomic_add_fetch(&c->hits[i], 1, __ATOMIC_RELAXED);
    if (tid >= c->nthreads)
        __atomic_add_fetch(&c->bad_tid, 1, __ATOMIC_RELAXED);
    if (tid == 0) {
        c->tid0_ran++;
        if (!pthread_equal(pthread_self(), c->caller))
            c->caller_not_tid0++;
    } else if (pthread_equal(pthread_self(), c->caller)) {
        __atomic_add_fetch(&c->caller_not_tid0, 1, __ATOMIC_RELAXED);
    }
}

static void nothing(void *arg, size_t i, unsigned tid)
{
    (void)arg, (void)i, (void)tid;
}

static double cpu_seconds(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 +
           ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6;
}

/* Fails (tvpal_pool_lowest) at i >= from and at every positive multiple
 * of 7, the later ones first in time where threads race. */
struct low {
    int64_t lowest;
    size_t from;
};

static void fail_some(void *arg, size_t i, unsigned tid)
{
    struct low *l = arg;
    (void)tid;
    if (i >= l->from || (i && i % 7 == 0))
        tvpal_pool_lowest(&l->lowest, (int64_t)i);
}

int main(void)
{
    struct tvpal_pool *p = NULL;
    CHECK(tvpal_pool_create(&p, 0) == TVPAL_E_INVAL && !p, "0 threads");
    CHECK(tvpal_pool_create(&p, TVPAL_POOL_THREADS_MAX + 1) ==
              TVPAL_E_INVAL, "too many threads");
    tvpal_pool_free(NULL);

    /* team 0: a NULL pool, the caller alone */
    static const unsigned teams[] = {0, 1, 2, 3, 8};
    static const size_t sizes[] = {0, 1, 2, 3, 7, 64, MAXN};
    static struct ctx c;
    for (size_t k = 0; k < sizeof teams / sizeof *teams; k++) {
        p = NULL;
        if (teams[k])
            REQUIRE(tvpal_pool_create(&p, teams[k]) == 0, "create %u",
                    teams[k]);
        CHECK(tvpal_pool_threads(p) == (teams[k] ? teams[k] : 1), "threads");
        /* Back to back, twice over, so a late thread of one loop would
         * show in the next. */
        for (int rep = 0; rep < 2; rep++)
            for (size_t s = 0; s < sizeof sizes / sizeof *sizes; s++) {
                memset(&c, 0, sizeof c);
                c.nthreads = teams[k] ? teams[k] : 1;
                c.caller = pthread_self();
                tvpal_pool_for(p, sizes[s], body, &c);
                size_t wrong = 0;
                for (size_t i = 0; i < MAXN; i++)
                    wrong += c.hits[i] != (i < sizes[s]);
                CHECK(wrong == 0, "team %u, n %zu: %zu indices not run "
                      "exactly once", teams[k], sizes[s], wrong);
                CHECK(c.bad_tid == 0 && c.caller_not_tid0 == 0,
                      "team %u, n %zu: tids", teams[k], sizes[s]);
            }
        tvpal_pool_free(p);
    }

    /* tvpal_pool_lowest: the first failing index, whichever thread met it
     * first (every index from 1000 on fails, and every 7th below). */
    REQUIRE(tvpal_pool_create(&p, 4) == 0, "create 4");
    for (int rep = 0; rep < 20; rep++) {
        struct low l = {.lowest = INT64_MAX, .from = 1000 - rep};
        tvpal_pool_for(p, MAXN, fail_some, &l);
        CHECK(l.lowest == 7, "lowest failing index %lld, expected 7",
              (long long)l.lowest);
        struct low none = {.lowest = INT64_MAX, .from = MAXN};
        tvpal_pool_for(p, 6, fail_some, &none);
        CHECK(none.lowest == INT64_MAX, "no failure: %lld",
              (long long)none.lowest);
    }
    tvpal_pool_free(p);

    /* Idle threads sleep: 40 loops with 5 ms of serial sleep between. */
    REQUIRE(tvpal_pool_create(&p, 4) == 0, "create 4");
    double c0 = cpu_seconds();
    struct timespec gap = {0, 5000000};
    for (int i = 0; i < 40; i++) {
        tvpal_pool_for(p, 4, nothing, NULL);
        nanosleep(&gap, NULL);
    }
    double used = cpu_seconds() - c0;
    /* Spinning threads would use up to 3 x 0.2 s; waking costs microseconds. */
    CHECK(used < 0.1, "idle team used %.3f s of CPU in 0.2 s of gaps", used);
    tvpal_pool_free(p);

    setenv("OMP_NUM_THREADS", "3", 1);
    CHECK(tvpal_pool_default_threads() == 3, "OMP_NUM_THREADS=3");
    setenv("OMP_NUM_THREADS", "junk", 1);
    unsigned d = tvpal_pool_default_threads();
    CHECK(d >= 1 && d <= TVPAL_POOL_THREADS_MAX, "affinity count %u", d);
    return tt_done("test-pool");
}
