/* tvpal_readahead.c: see tvpal_readahead.h. */
#include "tvpal_readahead.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct tvpal_readahead {
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    tvpal_readahead_fn fn;
    void *ctx;
    void *buf;               /* the box being read or read */
    struct encode_box box;   /* what to read */
    int64_t want, ready;     /* step asked for / in buf (-1: none) */
    int busy, quit, rc;
    struct tvpal_diag d;
};

static void *reader_main(void *arg)
{
    struct tvpal_readahead *ra = arg;
    pthread_mutex_lock(&ra->mu);
    for (;;) {
        while (!ra->quit && ra->want < 0)
            pthread_cond_wait(&ra->cv, &ra->mu);
        if (ra->quit)
            break;
        const int64_t t = ra->want;
        const struct encode_box box = ra->box;
        ra->want = -1;
        ra->busy = 1;
        pthread_mutex_unlock(&ra->mu);
        struct tvpal_diag d = {{0}};
        int rc = ra->fn(ra->ctx, (uint32_t)t, &box, ra->buf, &d);
        pthread_mutex_lock(&ra->mu);
        ra->busy = 0;
        ra->ready = t;
        ra->rc = rc;
        ra->d = d;
        pthread_cond_broadcast(&ra->cv);
    }
    pthread_mutex_unlock(&ra->mu);
    return NULL;
}

struct tvpal_readahead *tvpal_readahead_start(tvpal_readahead_fn fn,
                                              void *ctx, size_t bytes)
{
    struct tvpal_readahead *ra = calloc(1, sizeof *ra);
    if (!ra || !(ra->buf = malloc(bytes))) {
        free(ra);
        return NULL;
    }
    ra->fn = fn;
    ra->ctx = ctx;
    ra->want = ra->ready = -1;
    pthread_mutex_init(&ra->mu, NULL);
    pthread_cond_init(&ra->cv, NULL);
    if (pthread_create(&ra->thread, NULL, reader_main, ra) != 0) {
        pthread_mutex_destroy(&ra->mu);
        pthread_cond_destroy(&ra->cv);
        free(ra->buf);
        free(ra);
        return NULL;
    }
    return ra;
}

void tvpal_readahead_stop(struct tvpal_readahead *ra)
{
    if (!ra)
        return;
    pthread_mutex_lock(&ra->mu);
    ra->quit = 1;
    pthread_cond_broadcast(&ra->cv);
    pthread_mutex_unlock(&ra->mu);
    pthread_join(ra->thread, NULL);
    pthread_mutex_destroy(&ra->mu);
    pthread_cond_destroy(&ra->cv);
    free(ra->buf);
    free(ra);
}

/* Waits, holding ra->mu, until the reader is idle, ticking about once a
 * second (the mutex let go meanwhile). */
static void wait_idle(struct tvpal_readahead *ra, void (*tick)(void *),
                      void *tick_ctx)
{
    while (ra->busy || ra->want >= 0) {
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        until.tv_sec += 1;
        if (pthread_cond_timedwait(&ra->cv, &ra->mu, &until) != 0 && tick) {
            pthread_mutex_unlock(&ra->mu);
            tick(tick_ctx);
            pthread_mutex_lock(&ra->mu);
        }
    }
}

static void ask(struct tvpal_readahead *ra, int64_t t,
                const struct encode_box *b)
{
    ra->box = *b;
    ra->want = t;
    pthread_cond_broadcast(&ra->cv);
}

int tvpal_readahead_take(struct tvpal_readahead *ra, uint32_t t,
                         int64_t next, const struct encode_box *b,
                         void **buf, void (*tick)(void *), void *tick_ctx,
                         struct tvpal_diag *d)
{
    pthread_mutex_lock(&ra->mu);
    wait_idle(ra, tick, tick_ctx);
    if (ra->ready != (int64_t)t || memcmp(&ra->box, b, sizeof *b)) {
        ask(ra, t, b);
        wait_idle(ra, tick, tick_ctx);
    }
    void *tmp = *buf;
    *buf = ra->buf;
    ra->buf = tmp;
    const int rc = ra->rc;
    if (d)
        *d = ra->d;
    ra->ready = -1;
    if (next >= 0)
        ask(ra, next, b);
    pthread_mutex_unlock(&ra->mu);
    return rc;
}
