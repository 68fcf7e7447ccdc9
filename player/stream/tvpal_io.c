/* tvpal_io.c: io_uring and pread read backends (see tvpal_io.h). */
#include "tvpal_io.h"
#include "tvpal_clock.h"

#include <errno.h>
#include <inttypes.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/uio.h>
#include <unistd.h>
#ifdef HAVE_LIBURING
#include <liburing.h>
#endif

struct tvpal_io {
    enum tvpal_io_kind kind;
    unsigned depth, inflight;
    /* pread: FIFO of pending requests */
    struct tvpal_io_req *q;
    unsigned head;
    uint64_t submits;     /* io_uring_submit calls (tvpal_io_submits) */
    uint64_t fixed_reads; /* reads queued into registered buffers */
    unsigned nfixed;      /* entries of the fixed-buffer table (0: none), */
    unsigned nfilled;     /* how many of them are filled */
    /* tvpal_io_busy: the figures other threads read (__atomic, relaxed),
     * and the start of the interval open now (tvpal_now; 0: none), which
     * only the reading thread touches. */
    uint64_t busy_bytes, busy_ns;
    double busy_since;
#ifdef HAVE_LIBURING
    struct io_uring ring;
    int ring_ok;
    /* io_uring may complete a read short (part of it cached, or split by
     * the block layer): the rest is resubmitted until done or EOF. */
    struct pend {
        struct tvpal_io_req r;
        uint64_t done;
        int used;
    } *pend;
    /* The fixed-buffer table (tvpal_io_register): fixed[i] NULL where
     * entry i is empty. */
    unsigned char **fixed;
    uint64_t *fixed_len;
#endif
};

/* Test hook (tvpal_io.h): the byte offset whose reads fail, or -1. */
static int64_t g_fault_off = -1;
static pthread_once_t g_fault_once = PTHREAD_ONCE_INIT;

static void fault_read_env(void)
{
    const char *v = getenv("TVPAL_IO_FAULT_OFFSET");
    char *end;
    if (v && *v) {
        long long x = strtoll(v, &end, 10);
        if (!*end && x >= 0)
            g_fault_off = x;
    }
}

/* A completed read of r: EIO instead when it covers the fault offset. */
static int64_t fault_filter(const struct tvpal_io_req *r, int64_t result)
{
    if (g_fault_off >= 0 && (uint64_t)g_fault_off >= r->off &&
        (uint64_t)g_fault_off < r->off + r->len)
        return -EIO;
    return result;
}

/* The disk becomes busy with this io's reads (tvpal_io_busy). */
static void busy_open(struct tvpal_io *io)
{
    if (io->busy_since <= 0)
        io->busy_since = tvpal_now();
}

/* A read of `bytes` completed; `idle`: none is left with the kernel.
 * The time since the last mark is counted at every completion, so that
 * the figures hold up to it even while the disk never idles. */
static void busy_done(struct tvpal_io *io, int64_t bytes, int idle)
{
    const double now = tvpal_now();
    if (io->busy_since > 0 && now > io->busy_since)
        __atomic_fetch_add(&io->busy_ns,
                           (uint64_t)((now - io->busy_since) * 1e9),
                           __ATOMIC_RELAXED);
    if (bytes > 0)
        __atomic_fetch_add(&io->busy_bytes, (uint64_t)bytes, __ATOMIC_RELAXED);
    io->busy_since = idle ? 0 : now;
}

void tvpal_io_busy(const struct tvpal_io *io, uint64_t *bytes,
                   double *seconds)
{
    *bytes = __atomic_load_n(&io->busy_bytes, __ATOMIC_RELAXED);
    *seconds = (double)__atomic_load_n(&io->busy_ns, __ATOMIC_RELAXED) * 1e-9;
}

int tvpal_io_create(struct tvpal_io **out, enum tvpal_io_kind kind,
                    unsigned depth, struct tvpal_diag *diag)
{
    pthread_once(&g_fault_once, fault_read_env);
    if (depth < 1)
        depth = 1;
    struct tvpal_io *io = calloc(1, sizeof *io);
    if (!io)
        return TVPAL_E_NOMEM;
    io->kind = kind;
    io->depth = depth;
    io->q = calloc(depth, sizeof *io->q);
    if (!io->q) {
        free(io);
        return TVPAL_E_NOMEM;
    }
    if (kind == TVPAL_IO_URING) {
#ifdef HAVE_LIBURING
        int rc = io_uring_queue_init(depth, &io->ring, 0);
        if (rc < 0) {
            free(io->q);
            free(io);
            return tvpal_diag_set(diag, TVPAL_E_SYS,
                                  "io_uring is unavailable: %s",
                                  strerror(-rc));
        }
        io->ring_ok = 1;
        io->pend = calloc(depth, sizeof *io->pend);
        if (!io->pend) {
            io_uring_queue_exit(&io->ring);
            free(io->q);
            free(io);
            return TVPAL_E_NOMEM;
        }
#else
        free(io->q);
        free(io);
        return tvpal_diag_set(diag, TVPAL_E_SYS,
                              "built without liburing");
#endif
    }
    *out = io;
    return 0;
}

void tvpal_io_free(struct tvpal_io *io)
{
    if (!io)
        return;
#ifdef HAVE_LIBURING
    if (io->ring_ok) {
        /* Reap what is still in flight: the buffers may be freed next. */
        while (io->inflight) {
            struct io_uring_cqe *cqe;
            if (io_uring_wait_cqe(&io->ring, &cqe) < 0)
                break;
            io_uring_cqe_seen(&io->ring, cqe);
            io->inflight--;
        }
        io_uring_queue_exit(&io->ring); /* drops the registration */
    }
    free(io->pend);
    free(io->fixed);
    free(io->fixed_len);
#endif
    free(io->q);
    free(io);
}

const char *tvpal_io_name(const struct tvpal_io *io)
{
    return io->kind == TVPAL_IO_URING ? "uring" : "pread";
}

unsigned tvpal_io_inflight(const struct tvpal_io *io)
{
    return io->inflight;
}

unsigned tvpal_io_depth(const struct tvpal_io *io)
{
    return io->depth;
}

#ifdef HAVE_LIBURING
/* The registered buffer holding all of [p, p + len), or -1. */
static int fixed_index(const struct tvpal_io *io, const unsigned char *p,
                       uint64_t len)
{
    for (unsigned i = 0; i < io->nfixed; i++)
        if (io->fixed[i] && p >= io->fixed[i] &&
            (uint64_t)(p - io->fixed[i]) + len <= io->fixed_len[i])
            return (int)i;
    return -1;
}

/* Queues the remaining part of pending read k. */
static int uring_queue(struct tvpal_io *io, unsigned k,
                       struct tvpal_diag *diag)
{
    struct pend *pd = &io->pend[k];
    struct io_uring_sqe *sqe = io_uring_get_sqe(&io->ring);
    if (!sqe)
        return TVPAL_E_INVAL;
    unsigned char *dst = (unsigned char *)pd->r.buf + pd->done;
    unsigned len = (unsigned)(pd->r.len - pd->done);
    int fi = fixed_index(io, dst, len);
    if (fi >= 0) {
        io_uring_prep_read_fixed(sqe, pd->r.fd, dst, len,
                                 pd->r.off + pd->done, fi);
        io->fixed_reads++;
    } else {
        io_uring_prep_read(sqe, pd->r.fd, dst, len, pd->r.off + pd->done);
    }
    io_uring_sqe_set_data64(sqe, k);
    (void)diag;
    return 0; /* submitted by tvpal_io_flush or the next wait */
}

/* Hands every queued read to the kernel in one system call. */
static int uring_flush(struct tvpal_io *io, struct tvpal_diag *diag)
{
    if (!io_uring_sq_ready(&io->ring))
        return 0;
    io->submits++;
    busy_open(io);
    int rc = io_uring_submit(&io->ring);
    if (rc < 0)
        return tvpal_diag_set(diag, TVPAL_E_READ, "io_uring_submit: %s",
                              strerror(-rc));
    return 0;
}
#endif

int tvpal_io_register(struct tvpal_io *io, unsigned n,
                      struct tvpal_diag *diag)
{
#ifdef HAVE_LIBURING
    if (io->kind == TVPAL_IO_URING && !io->nfixed && n && !io->inflight) {
        io->fixed = calloc(n, sizeof *io->fixed);
        io->fixed_len = calloc(n, sizeof *io->fixed_len);
        int rc = io->fixed && io->fixed_len
                     ? io_uring_register_buffers_sparse(&io->ring, n)
                     : -ENOMEM;
        if (rc < 0) {
            free(io->fixed);
            free(io->fixed_len);
            io->fixed = NULL;
            io->fixed_len = NULL;
            return tvpal_diag_set(diag, TVPAL_E_SYS,
                                  "io_uring_register_buffers_sparse (%u): %s",
                                  n, strerror(-rc));
        }
        io->nfixed = n;
        return 0;
    }
#endif
    (void)n;
    return tvpal_diag_set(diag, TVPAL_E_SYS, io->kind == TVPAL_IO_URING
                          ? "a table already registered, or reads queued"
                          : "the pread backend has no fixed buffers");
}

int tvpal_io_register_buffer(struct tvpal_io *io, unsigned i, void *buf,
                             uint64_t len, struct tvpal_diag *diag)
{
#ifdef HAVE_LIBURING
    if (i < io->nfixed && !io->fixed[i]) {
        struct iovec iov = {.iov_base = buf, .iov_len = len};
        int rc = io_uring_register_buffers_update_tag(&io->ring, i, &iov,
                                                      NULL, 1);
        if (rc < 0)
            return tvpal_diag_set(diag, TVPAL_E_SYS,
                                  "io_uring_register_buffers_update_tag "
                                  "(%llu bytes): %s%s",
                                  (unsigned long long)len, strerror(-rc),
                                  rc == -ENOMEM
                                      ? "; RLIMIT_MEMLOCK (ulimit -l) too low"
                                      : "");
        io->fixed[i] = buf;
        io->fixed_len[i] = len;
        io->nfilled++;
        return 0;
    }
#endif
    (void)io, (void)i, (void)buf, (void)len;
    return tvpal_diag_set(diag, TVPAL_E_SYS, "no table entry %u to fill", i);
}

unsigned tvpal_io_table(const struct tvpal_io *io)
{
    return io->nfixed;
}

unsigned tvpal_io_registered(const struct tvpal_io *io)
{
    return io->nfilled;
}

uint64_t tvpal_io_fixed_reads(const struct tvpal_io *io)
{
    return io->fixed_reads;
}

int tvpal_io_flush(struct tvpal_io *io, struct tvpal_diag *diag)
{
#ifdef HAVE_LIBURING
    if (io->kind == TVPAL_IO_URING)
        return uring_flush(io, diag);
#endif
    (void)io, (void)diag;
    return 0;
}

uint64_t tvpal_io_submits(const struct tvpal_io *io)
{
    return io->submits;
}

int tvpal_io_submit(struct tvpal_io *io, const struct tvpal_io_req *r,
                    struct tvpal_diag *diag)
{
    if (io->inflight >= io->depth)
        return TVPAL_E_INVAL;
#ifdef HAVE_LIBURING
    if (io->kind == TVPAL_IO_URING) {
        unsigned k = 0;
        while (k < io->depth && io->pend[k].used)
            k++;
        if (k == io->depth)
            return TVPAL_E_INVAL;
        io->pend[k] = (struct pend){.r = *r, .done = 0, .used = 1};
        int rc = uring_queue(io, k, diag);
        if (rc < 0) {
            io->pend[k].used = 0;
            return rc;
        }
        io->inflight++;
        return 0;
    }
#endif
    io->q[(io->head + io->inflight) % io->depth] = *r;
    io->inflight++;
    return 0;
}

int tvpal_io_wait(struct tvpal_io *io, uint64_t *tag, int64_t *result,
                  struct tvpal_diag *diag)
{
    return tvpal_io_wait_timed(io, -1, tag, result, diag);
}

int tvpal_io_wait_timed(struct tvpal_io *io, double ms, uint64_t *tag,
                        int64_t *result, struct tvpal_diag *diag)
{
    if (!io->inflight)
        return TVPAL_E_INVAL;
#ifdef HAVE_LIBURING
    if (io->kind == TVPAL_IO_URING) {
        for (;;) {
            struct io_uring_cqe *cqe;
            int rc = uring_flush(io, diag);
            if (rc < 0)
                return rc;
            if (ms >= 0) {
                const long long ns = (long long)(ms * 1e6);
                struct __kernel_timespec ts = {.tv_sec = ns / 1000000000,
                                               .tv_nsec = ns % 1000000000};
                rc = io_uring_wait_cqe_timeout(&io->ring, &cqe, &ts);
                if (rc == -ETIME)
                    return 1;   /* nothing landed within ms */
            } else {
                rc = io_uring_wait_cqe(&io->ring, &cqe);
            }
            if (rc < 0)
                return tvpal_diag_set(diag, TVPAL_E_READ,
                                      "io_uring_wait_cqe: %s", strerror(-rc));
            unsigned k = (unsigned)io_uring_cqe_get_data64(cqe);
            int res = cqe->res;
            io_uring_cqe_seen(&io->ring, cqe);
            struct pend *pd = &io->pend[k];
            if (res > 0 && pd->done + (uint64_t)res < pd->r.len) {
                pd->done += (uint64_t)res;
                if (uring_queue(io, k, NULL) == 0)
                    continue; /* short read: the rest is on its way */
                res = -EIO; /* the rest could not be queued: a failed read */
            }
            if (res > 0)
                pd->done += (uint64_t)res;
            busy_done(io, res < 0 ? 0 : (int64_t)pd->done, io->inflight == 1);
            *tag = pd->r.tag;
            *result = fault_filter(&pd->r, res < 0 ? res : (int64_t)pd->done);
            pd->used = 0;
            io->inflight--;
            return 0;
        }
    }
#endif
    struct tvpal_io_req *r = &io->q[io->head];
    io->head = (io->head + 1) % io->depth;
    io->inflight--;
    uint64_t got = 0;
    int64_t res = 0;
    busy_open(io);
    while (got < r->len) {
        ssize_t k = pread(r->fd, (char *)r->buf + got, r->len - got,
                          (off_t)(r->off + got));
        if (k < 0 && errno == EINTR)
            continue;
        if (k < 0) {
            res = -errno;
            break;
        }
        if (k == 0)
            break;
        got += (uint64_t)k;
    }
    busy_done(io, (int64_t)got, 1);
    *tag = r->tag;
    *result = fault_filter(r, res < 0 ? res : (int64_t)got);
    return 0;
}
