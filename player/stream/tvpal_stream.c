/* tvpal_stream.c: record feeding, in-core and out-of-core (see
 * tvpal_stream.h). */
#define _GNU_SOURCE
#include "tvpal_stream.h"
#include "tvpal_clock.h"
#include "tvpal_format.h"
#include "tvpal_chunkz.h"
#include "tvpal_pool.h"

#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

enum { SLOT_FREE, SLOT_INFLIGHT, SLOT_READY };

/* A record is read in pieces of at most PIECE bytes, all queued at once:
 * devices serve several moderate requests in parallel faster than one huge
 * one (measured: 16 MiB records at 1.2 GiB/s whole, near fio's rate in
 * 1 MiB pieces). */
#define PIECE (1u << 20)

/* A slot's state, step and verified are written with __atomic:
 * tvpal_stream_ready reads them on the caller's thread while a keep job
 * may run. */
struct slot {
    int state;
    uint32_t step;
    unsigned pending;        /* pieces in flight */
    int64_t result;          /* bytes read, or -errno of a failed piece */
    int verified;
    unsigned char *buf;
    unsigned fx;             /* its entry in the fixed-buffer table */
    int filled;              /* the entry was filled (or refused) */
    int touched;             /* read into at least once: its pages are in */
};

struct part {                /* one shard */
    struct tvpal_slab *slab;
    struct tvpal_shard *sh;
    int fd;
    unsigned char *all;      /* in-core: records region [4096, index) */
    int *bad;                /* in-core, per step: 0, the errno of a failed
                              * read, or (< 0) the code of a failed check */
    struct slot *slots;
    unsigned nslots;         /* in use: nslots_all, or ahead (until a
                              * keep) those of plain streaming */
    unsigned nslots_all;
    uint64_t steady_bytes;   /* the largest record after record 0 */
    /* Coded records (FORMAT.md 6.11): each is read into the tail of a
     * buffer of its plain bytes and inflated there, once, by whichever
     * thread checks it first (the stager or the seek's, never both at
     * once): z is that inflater, created with the part when its shard has
     * coded records.  In-core, plain_off[t] is record t's place in all
     * (NULL: its offset in the file less the header, nothing coded) and
     * why[t] what was wrong with a record that did not inflate. */
    struct tvpal_chunkz *z;
    uint64_t *plain_off;
    uint64_t stored_base;    /* in-core: where in all the file's records
                              * region is read (0 when nothing is coded) */
    char **why;
    /* Coded records inflated by the stream's threads (not in-core):
     * their plain bytes and the wall time it took (tvpal_stream_meter;
     * __atomic, relaxed: read by other threads). */
    uint64_t inflated_bytes, inflate_ns;
};

/* The stager: a thread that prepares the next step (reads, verification,
 * decoding into the slabs' staging buffers) while the current one is drawn.
 * It and the caller of tvpal_stream_seek never touch the stream at the
 * same time: seek first waits until the stager is idle, and the stager
 * only runs between seeks. */
enum { STAGER_IDLE, STAGER_PENDING, STAGER_RUNNING };

struct stager {
    pthread_t th;
    int started, quit;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int state;                   /* STAGER_*, under mu */
    int keep;                    /* the job is keep_around's, not a
                                  * step's staging */
    int keep_after;              /* a keep asked for while a step was
                                  * staged: run when that is done, */
    uint32_t keep_after_t;       /* around this step, */
    int keep_after_dir;          /* in this direction; */
    int keep_dir;                /* the keep job's direction */
    int cancel;                  /* a keep job is to stop (stager_wait) */
    uint32_t t;                  /* the job: stage step t, */
    int dir;                     /* prefetching in direction dir */
    int alone;                   /* the step's reads only, no prefetch
                                  * beyond it (tvpal_stream_prepare) */
    int have;                    /* a staged step waits for install: */
    uint32_t staged_t;
    int next;                    /* a job posted while one ran (a jump's
                                  * target, tvpal_stream_prepare): */
    uint32_t next_t;             /* run after it, which is dropped */
    int next_dir, next_alone;
    int rc;                      /* its result, */
    struct tvpal_diag diag;
    struct tvpal_stream_stats st;
};

struct tvpal_stream {
    struct part *p;
    unsigned n;
    /* Coded records: the threads that inflate one in waves, driven by
     * the thread that checks it (the stager, or the caller's in a seek:
     * never both at once).  The stager's waves share the CPUs with the
     * frame being drawn: on 2 cores streamed 512^3 played at 10.3 fps
     * with them against 9.5 with the stager inflating alone (medians of
     * 5), and with more cores the stager's one thread no longer bounds
     * the rate (about 11 steps a second at 512^3).  NULL: no coded
     * record, or one CPU. */
    struct tvpal_pool *pool;
    struct stager w;             /* with prefetch > 0 */
    int have_cur;                /* a seek has brought the slabs to cur_t */
    uint32_t cur_t;
    struct tvpal_io *io;
    int incore;
    unsigned prefetch;
    unsigned around;             /* steps kept on each side of the
                                  * playhead (tvpal_stream_create's
                                  * keep_bytes; 0: none), or with ahead
                                  * beyond it in the keep's direction */
    int ahead;                   /* TVPAL_STREAM_KEEP_AHEAD, */
    int ahead_on;                /* and a keep asked for since: the steps
                                  * ahead are wanted (set once by the
                                  * caller, read by the stager too:
                                  * __atomic, relaxed) */
    unsigned keep_dir_neg;       /* the last keep was backwards (ahead) */
    unsigned keep_cap;           /* a keep job's pieces in flight, most */
    uint32_t *want;              /* scratch: wanted_steps' list */
    int kept;                    /* the neighbourhood of keep_t was asked
                                  * for (tvpal_stream_keep; a seek's
                                  * prefetch is its P nearest only) */
    uint32_t keep_t;
    unsigned want_cap;
    uint64_t ahead_bytes;        /* a step's reads in flight (read_ahead) */
    uint32_t loop_lo, loop_hi;   /* tvpal_stream_loop (lo > hi: none) */
    uint64_t step_stored;        /* tvpal_stream_step_bytes */
    uint64_t step_plain;
    uint64_t incore_bytes;
    unsigned policy;             /* TVPAL_STREAM_* bits */
    unsigned direct_files;       /* parts opened with O_DIRECT */
    char why[TVPAL_DIAG_MAX + 128]; /* the first fallback, or "" */
    char fixed_why[200];         /* why record buffers are not
                                  * registered, or "" */
    unsigned fixed_refused;      /* buffers the kernel refused */
};

static void *stager_main(void *arg);
static void fill_slot(struct tvpal_stream *s, struct part *p, struct slot *sl);
static void stager_wait(struct tvpal_stream *s);
static void unstage_all(struct tvpal_stream *s);

/* Notes the first fallback (for the start-up line and the summary). */
static void fell_back(struct tvpal_stream *s, const char *fmt, const char *a,
                      const char *b)
{
    if (!s->why[0])
        snprintf(s->why, sizeof s->why, fmt, a, b);
}

/* A record buffer, or in-core a shard's records: on 2 MiB boundaries,
 * offered to the kernel for huge pages (transparent huge pages in
 * "madvise" mode or "always").  Its pages are faulted in when it is
 * first read into (and a record buffer's pinned then, by fill_slot):
 * measured, 13 buffers of 269 MB (1024^3, N = 4) took 4.7 s to pin in
 * 4 KiB pages, 0.68 s in huge pages.  The slices' indices are drawn
 * from there (the slab borrows them), and on huge pages the TLB covers
 * them: a 512^3 in-core frame took x0.94 the time of 4 KiB pages. */
static void *record_buffer(uint64_t bytes)
{
    const uint64_t huge = (uint64_t)2 << 20;
    bytes = (bytes + huge - 1) & ~(huge - 1);
    void *p = NULL;
    if (posix_memalign(&p, huge, bytes ? bytes : huge))
        return NULL;
#ifdef MADV_HUGEPAGE
    (void)madvise(p, bytes, MADV_HUGEPAGE); /* a hint: refused is fine */
#endif
    return p;
}

/* Runs one completion, waited for at most ms (< 0: as long as it
 * takes); marks its slot.  0, 1 when none landed within ms, or an
 * error. */
static int reap_for(struct tvpal_stream *s, double ms, double *wait_ms,
                    struct tvpal_diag *diag)
{
    uint64_t tag;
    int64_t res;
    double t0 = tvpal_now();
    int rc = tvpal_io_wait_timed(s->io, ms, &tag, &res, diag);
    if (wait_ms)
        *wait_ms += (tvpal_now() - t0) * 1e3;
    if (rc != 0)
        return rc;
    struct part *p = &s->p[tag >> 32];
    struct slot *sl = &p->slots[tag & 0xFFFFFFFFu];
    if (res < 0)
        sl->result = res;
    else if (sl->result >= 0)
        sl->result += res;
    if (--sl->pending == 0)
        __atomic_store_n(&sl->state, SLOT_READY, __ATOMIC_RELEASE);
    return 0;
}

static int reap(struct tvpal_stream *s, double *wait_ms,
                struct tvpal_diag *diag)
{
    return reap_for(s, -1, wait_ms, diag);
}

/* How long a keep job waits for a read before it looks again whether it
 * is to stop: the seek that stops it waits for it (measured on a disk
 * throttled to half of 512^3 playback's need: seeks waited 14-166 ms
 * for a keep job blocked on its next completion, a third of a frame). */
#define KEEP_POLL_MS 1.0

static int submit(struct tvpal_stream *s, unsigned pi, unsigned si,
                  uint32_t step, double *wait_ms, struct tvpal_diag *diag)
{
    struct part *p = &s->p[pi];
    struct slot *sl = &p->slots[si];
    const struct tvpal_index_entry *e = tvpal_shard_entry(p->sh, step);
    fill_slot(s, p, sl);
    sl->touched = 1;
    __atomic_store_n(&sl->state, SLOT_INFLIGHT, __ATOMIC_RELAXED);
    __atomic_store_n(&sl->step, step, __ATOMIC_RELAXED);
    __atomic_store_n(&sl->verified, 0, __ATOMIC_RELAXED);
    sl->result = 0;
    sl->pending = 0;
    unsigned char *const into = sl->buf + tvpal_record_stored_at(e);
    for (uint64_t off = 0; off < e->bytes; off += PIECE) {
        while (tvpal_io_inflight(s->io) >= tvpal_io_depth(s->io)) {
            int rc = reap(s, wait_ms, diag);
            if (rc < 0)
                return rc;
        }
        uint64_t len = e->bytes - off < PIECE ? e->bytes - off : PIECE;
        struct tvpal_io_req r = {.fd = p->fd, .off = e->offset + off,
                                 .len = len, .buf = into + off,
                                 .tag = (uint64_t)pi << 32 | si};
        int rc = tvpal_io_submit(s->io, &r, diag);
        if (rc < 0)
            return rc;
        sl->pending++;
    }
    return 0;
}

/* In-core: where record t is in p->all, inflated. */
static unsigned char *incore_rec(const struct part *p, uint32_t t)
{
    const struct tvpal_index_entry *e = tvpal_shard_entry(p->sh, t);
    return p->all + (p->plain_off ? p->plain_off[t]
                                  : e->offset - TVPAL_SHARD_HEADER_BYTES);
}

/* In-core pieces: the records region is read in pieces of this size. */
#define INCORE_PIECE ((uint64_t)64 << 20)

/* Marks the records of p that overlap [off, off + len) of its records
 * region as unreadable (err: the read's errno). */
static void incore_mark(struct part *p, uint64_t off, uint64_t len, int err)
{
    const struct tvpal_shard_header *h = tvpal_shard_hdr(p->sh);
    for (uint32_t t = 0; t < h->steps; t++) {
        const struct tvpal_index_entry *e = tvpal_shard_entry(p->sh, t);
        uint64_t a = e->offset - TVPAL_SHARD_HEADER_BYTES, b = a + e->bytes;
        if (a < off + len && off < b && !p->bad[t])
            p->bad[t] = err;
    }
}

/* One completion of an in-core load (the tag is the piece's offset in the
 * records region).  A failed read marks its records, as stream mode does
 * for a record it cannot read; only waiting itself failing is an error. */
static int incore_reap(struct tvpal_io *io, struct part *p, uint64_t total,
                       struct tvpal_diag *diag)
{
    uint64_t tag;
    int64_t res;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_io_wait(io, &tag, &res, &d);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "%s: %s", tvpal_shard_path(p->sh),
                              d.msg);
    uint64_t len = total - tag < INCORE_PIECE ? total - tag : INCORE_PIECE;
    if (res != (int64_t)len)
        incore_mark(p, tag, len, res < 0 ? (int)-res : EIO);
    return 0;
}

static int open_part(struct tvpal_stream *s, struct part *p,
                     struct tvpal_diag *diag)
{
    const char *path = tvpal_shard_path(p->sh);
    p->fd = -1;
    if (s->policy & TVPAL_STREAM_DIRECT) {
        p->fd = open(path, O_RDONLY | O_CLOEXEC | O_DIRECT);
        if (p->fd < 0 && errno != EINVAL)
            return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s", path,
                                  strerror(errno));
        if (p->fd < 0 && (s->policy & TVPAL_STREAM_STRICT_DIRECT))
            return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: the file system "
                                  "refuses O_DIRECT (EINVAL)", path);
        if (p->fd < 0)
            fell_back(s, "O_DIRECT refused by the file system of %s%s: "
                      "reading through the page cache", path, "");
        else
            s->direct_files++;
    }
    if (p->fd < 0) {
        /* e.g. tmpfs: no O_DIRECT; read through the page cache */
        p->fd = open(path, O_RDONLY | O_CLOEXEC);
        if (p->fd < 0)
            return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s", path,
                                  strerror(errno));
    }
    return 0;
}

/* Reads in-core record t of p alone; clears its mark when that works.
 * Only the I/O layer failing is an error. */
static int incore_reread(struct tvpal_io *io, struct part *p, uint32_t t,
                         struct tvpal_diag *diag)
{
    const struct tvpal_index_entry *e = tvpal_shard_entry(p->sh, t);
    struct tvpal_io_req r = {
        .fd = p->fd, .off = e->offset, .len = e->bytes,
        .buf = p->all + p->stored_base + e->offset - TVPAL_SHARD_HEADER_BYTES,
        .tag = t};
    struct tvpal_diag d = {{0}};
    uint64_t tag;
    int64_t res;
    int rc = tvpal_io_submit(io, &r, &d);
    if (rc == 0)
        rc = tvpal_io_wait(io, &tag, &res, &d);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "%s: %s", tvpal_shard_path(p->sh),
                              d.msg);
    if (res == (int64_t)e->bytes)
        p->bad[t] = 0;
    else
        p->bad[t] = res < 0 ? (int)-res : EIO;
    return 0;
}

/* In-core, coded records: moves record t, as read, to the tail of its
 * place and inflates it there (records in step order: a record's plain
 * form never reaches the stored bytes of the records after it, as inside
 * a record, FORMAT.md 6.11).  A record that does not inflate is marked,
 * with what was wrong.  0 or TVPAL_E_NOMEM. */
static int place_incore(struct part *p, uint32_t t, struct tvpal_pool *pool)
{
    const struct tvpal_index_entry *e = tvpal_shard_entry(p->sh, t);
    unsigned char *dst = incore_rec(p, t);
    memmove(dst + tvpal_record_stored_at(e),
            p->all + p->stored_base + e->offset - TVPAL_SHARD_HEADER_BYTES,
            e->bytes);
    struct tvpal_diag d = {{0}};
    int rc = e->coded
                 ? tvpal_record_inflate_pool(p->z, pool, dst, e, t,
                                             tvpal_shard_hdr(p->sh), &d)
                 : tvpal_record_verify(dst, e->bytes, t,
                                       tvpal_shard_hdr(p->sh), &d);
    if (rc == TVPAL_E_NOMEM)
        return rc;
    if (rc < 0) {
        p->bad[t] = rc;
        p->why[t] = strdup(d.msg);
    }
    return 0;
}

/* In-core: the shard's records region [4096, index) read into RAM, in
 * pieces of at most 64 MiB (aligned), all queued; then every record
 * verified once. */
static int load_incore(struct tvpal_stream *s, struct part *p,
                       struct tvpal_diag *diag)
{
    const struct tvpal_shard_header *h = tvpal_shard_hdr(p->sh);
    struct tvpal_io *io = s->io;
    uint64_t bytes = h->index_offset - TVPAL_SHARD_HEADER_BYTES;
    int rc = 0;
    /* Coded records: the records inflated, back to back; the file's
     * records region is read into the tail and inflated front to back
     * (place_incore). */
    uint64_t plain = bytes;
    if (p->z) {
        if (!(p->plain_off = calloc(h->steps, sizeof *p->plain_off)) ||
            !(p->why = calloc(h->steps, sizeof *p->why)))
            return TVPAL_E_NOMEM;
        plain = 0;
        for (uint32_t t = 0; t < h->steps; t++) {
            p->plain_off[t] = plain;
            plain += tvpal_record_buffer_bytes(tvpal_shard_entry(p->sh, t));
        }
        p->stored_base = plain - bytes;
    }
    if (!(p->all = record_buffer(plain)))
        return tvpal_diag_set(diag, TVPAL_E_NOMEM,
                              "in-core: cannot hold %llu bytes of %s",
                              (unsigned long long)plain,
                              tvpal_shard_path(p->sh));
    s->incore_bytes += plain;
    if (!(p->bad = calloc(h->steps, sizeof *p->bad)))
        return TVPAL_E_NOMEM;
    for (uint64_t off = 0; off < bytes && rc == 0; off += INCORE_PIECE) {
        uint64_t len = bytes - off < INCORE_PIECE ? bytes - off : INCORE_PIECE;
        struct tvpal_io_req r = {
            .fd = p->fd, .off = TVPAL_SHARD_HEADER_BYTES + off,
            .len = len, .buf = p->all + p->stored_base + off, .tag = off};
        while (rc == 0 && tvpal_io_inflight(io) >= tvpal_io_depth(io))
            rc = incore_reap(io, p, bytes, diag);
        if (rc == 0) {
            struct tvpal_diag qd = {{0}};
            rc = tvpal_io_submit(io, &r, &qd);
            if (rc < 0)
                tvpal_diag_set(diag, rc, "%s: %s", tvpal_shard_path(p->sh),
                               qd.msg);
        }
    }
    while (rc == 0 && tvpal_io_inflight(io))
        rc = incore_reap(io, p, bytes, diag);
    /* A failed piece took all its records with it: each is read again on
     * its own, so only those that are really unreadable stay marked. */
    for (uint32_t t = 0; t < h->steps && rc == 0; t++)
        if (p->bad[t] > 0)
            rc = incore_reread(io, p, t, diag);
    /* Each record checked once; a bad one is reported when a frame needs
     * it (the slices keep their previous window), as in stream mode. */
    for (uint32_t t = 0; t < h->steps && rc == 0; t++) {
        const struct tvpal_index_entry *e = tvpal_shard_entry(p->sh, t);
        if (p->bad[t])
            continue;
        if (p->plain_off)
            rc = place_incore(p, t, s->pool);
        else
            p->bad[t] = tvpal_record_verify(incore_rec(p, t), e->bytes, t, h,
                                            NULL);
    }
    return rc;
}

/* The error of bad in-core record t of p, for the caller's diag. */
static int incore_error(const struct part *p, uint32_t t,
                        struct tvpal_diag *diag)
{
    const struct tvpal_index_entry *e = tvpal_shard_entry(p->sh, t);
    if (p->bad[t] > 0)
        return tvpal_diag_set(diag, TVPAL_E_READ, "%s: record %u: %s",
                              tvpal_shard_path(p->sh), t,
                              strerror(p->bad[t]));
    if (p->why && p->why[t])
        return tvpal_diag_set(diag, p->bad[t], "%s: %s",
                              tvpal_shard_path(p->sh), p->why[t]);
    struct tvpal_diag d = {{0}};
    int rc = tvpal_record_verify(incore_rec(p, t), e->bytes, t,
                                 tvpal_shard_hdr(p->sh), &d);
    return tvpal_diag_set(diag, rc < 0 ? rc : p->bad[t], "%s: %s",
                          tvpal_shard_path(p->sh), d.msg);
}

/* A part whose shard has coded records: its inflater, and the stream's
 * pool at the first such part.  Waves of 4 chunks a thread: a 512^3
 * record (128 chunks of 256 KiB) inflated on 2 threads in 38 ms, against
 * 64 alone and 86 in waves of 2 (a wave's two hand-offs cost more than
 * its work).  0 or TVPAL_E_NOMEM. */
static int open_inflater(struct tvpal_stream *s, struct part *p)
{
    const unsigned nt = tvpal_pool_default_threads();
    if (!s->pool && nt > 1 && tvpal_pool_create(&s->pool, nt) < 0)
        s->pool = NULL;   /* inflated by one thread: slower, as sound */
    const unsigned ways = 4 * tvpal_pool_threads(s->pool);
    return tvpal_chunkz_create_ways(
        &p->z, tvpal_shard_max_chunk(tvpal_shard_hdr(p->sh)),
        ways < TVPAL_CHUNKZ_WAYS_MAX ? ways : TVPAL_CHUNKZ_WAYS_MAX);
}

/* The most bytes (inflated: what a buffer holds) of any record but record 0 (record 0 alone when it is the
 * only one).  Record 0 holds the first window of every slice, N times a
 * later record's slices, and is read at a start or a jump to it only. */
static uint64_t steady_record_bytes(const struct tvpal_shard *sh)
{
    const uint32_t steps = tvpal_shard_hdr(sh)->steps;
    uint64_t m = 0;
    for (uint32_t t = steps > 1 ? 1 : 0; t < steps; t++) {
        uint64_t b = tvpal_record_buffer_bytes(tvpal_shard_entry(sh, t));
        m = b > m ? b : m;
    }
    return m;
}

/* Out-of-core: record buffers (nslots) for the N records whose windows
 * are shown (the slab borrows their indices) + N needed by a jump + P
 * prefetched + P of an old prefetch window still in flight after a jump
 * + 1 (the step staged). */
static int alloc_slots(struct part *p, unsigned nslots)
{
    p->nslots = p->nslots_all = nslots;
    p->steady_bytes = steady_record_bytes(p->sh);
    if (!(p->slots = calloc(p->nslots, sizeof *p->slots)))
        return TVPAL_E_NOMEM;
    for (unsigned k = 0; k < p->nslots; k++)
        if (!(p->slots[k].buf = record_buffer(tvpal_shard_max_record(p->sh))))
            return TVPAL_E_NOMEM;
    return 0;
}

/* Out-of-core: a fixed-buffer table with an entry per record buffer,
 * each filled when its buffer is first read into (fill_slot); refused:
 * the reason in s->fixed_why. */
static void register_table(struct tvpal_stream *s)
{
    unsigned n = 0;
    for (unsigned i = 0; i < s->n; i++)
        for (unsigned k = 0; k < s->p[i].nslots_all; k++)
            s->p[i].slots[k].fx = n++;
    struct tvpal_diag d = {{0}};
    if (n && tvpal_io_register(s->io, n, &d) < 0)
        tvpal_diag_copy(s->fixed_why, sizeof s->fixed_why, d.msg);
}

/* Before the first read into slot sl of p: its buffer goes into the
 * fixed-buffer table, so the kernel faults in and pins its pages once,
 * now, instead of under every read.  Only the part a record after record
 * 0 can fill: the rest only ever holds record 0.  Refused (memory lock
 * limit): said once, and its reads go as before. */
static void fill_slot(struct tvpal_stream *s, struct part *p, struct slot *sl)
{
    if (sl->filled || !tvpal_io_table(s->io))
        return;
    sl->filled = 1;
    struct tvpal_diag d = {{0}};
    if (tvpal_io_register_buffer(s->io, sl->fx, sl->buf, p->steady_bytes,
                                 &d) < 0) {
        s->fixed_refused++;
        if (!s->fixed_why[0])
            tvpal_diag_copy(s->fixed_why, sizeof s->fixed_why, d.msg);
    }
}

/* Streamed with keep_bytes: the steps kept on each side of the playhead,
 * so that the record buffers (each holding a step's record of a shard,
 * at most the largest after record 0 in use) fit keep_bytes beside the
 * 2N + 2P + 1 of plain streaming and the N shown after a jump away; 0
 * when not even one more step fits. */
static unsigned around_of(const struct tvpal_stream *s, uint64_t keep_bytes,
                          uint64_t step_bytes, int ahead)
{
    const struct tvpal_shard_header *h = tvpal_shard_hdr(s->p[0].sh);
    if (!keep_bytes || !step_bytes)
        return 0;
    const uint64_t fit = keep_bytes / step_bytes,
                   fixed = 3 * (uint64_t)h->window + 2 * s->prefetch + 1;
    if (fit <= fixed + 1)
        return 0;
    uint64_t k = ahead ? fit - fixed : (fit - fixed) / 2;
    return k < h->steps ? (unsigned)k : h->steps;
}

/* No loop (tvpal_stream_loop) yet, and the bytes of one
 * step's records from scratch, over the shards (tvpal_stream_step_bytes).
 * Step t needs the record of each window that covers it, one per window
 * start in (t - N, t]: over the series that is N records of the T, so the
 * mean is the N/T of all the records' bytes. */
static void series_of(struct tvpal_stream *s)
{
    s->loop_lo = 1;
    s->loop_hi = 0;
    uint64_t stored = 0, plain = 0;
    for (unsigned i = 0; i < s->n; i++) {
        const struct tvpal_shard_header *h = tvpal_shard_hdr(s->p[i].sh);
        uint64_t a = 0, b = 0;
        for (uint32_t t = 0; t < h->steps; t++) {
            const struct tvpal_index_entry *e = tvpal_shard_entry(s->p[i].sh, t);
            a += e->bytes;
            b += e->plain_bytes;
        }
        const uint32_t n = h->window < h->steps ? h->window : h->steps;
        if (h->steps) {
            stored += a / h->steps * n;
            plain += b / h->steps * n;
        }
    }
    s->step_stored = stored;
    s->step_plain = plain;
}

void tvpal_stream_step_bytes(const struct tvpal_stream *s, uint64_t *stored,
                             uint64_t *plain)
{
    *stored = s->step_stored;
    *plain = s->step_plain;
}

int tvpal_stream_loop(struct tvpal_stream *s, uint32_t first, uint32_t last)
{
    const uint32_t lo = first < last ? first : last;
    const uint32_t hi = first < last ? last : first;
    if (!s->n || hi >= tvpal_shard_hdr(s->p[0].sh)->steps)
        return TVPAL_E_INVAL;
    stager_wait(s);   /* the stager reads these */
    s->loop_lo = lo;
    s->loop_hi = hi;
    return 0;
}

void tvpal_stream_meter(const struct tvpal_stream *s,
                        struct tvpal_stream_meter *m)
{
    memset(m, 0, sizeof *m);
    tvpal_io_busy(s->io, &m->read_bytes, &m->read_s);
    for (unsigned i = 0; i < s->n; i++) {
        m->inflated_bytes += __atomic_load_n(&s->p[i].inflated_bytes,
                                             __ATOMIC_RELAXED);
        m->inflate_s += (double)__atomic_load_n(&s->p[i].inflate_ns,
                                                __ATOMIC_RELAXED) * 1e-9;
    }
}

/* Starts the stager thread of s (its lock and condition first).  0, or
 * TVPAL_E_SYS with diag saying what could not be created. */
static int start_stager(struct tvpal_stream *s, struct tvpal_diag *diag)
{
    struct stager *w = &s->w;
    /* The condition on the monotonic clock: tvpal_stream_ready's timed
     * wait must not move with the wall clock. */
    pthread_condattr_t ca;
    int cv_ok = 0;
    if (pthread_condattr_init(&ca) == 0) {
        cv_ok = pthread_condattr_setclock(&ca, CLOCK_MONOTONIC) == 0 &&
                pthread_cond_init(&w->cv, &ca) == 0;
        pthread_condattr_destroy(&ca);
    }
    if (!cv_ok || pthread_mutex_init(&w->mu, NULL)) {
        if (cv_ok)
            pthread_cond_destroy(&w->cv);
        return tvpal_diag_set(diag, TVPAL_E_SYS,
                              "cannot create the stager's lock");
    }
    if (pthread_create(&w->th, NULL, stager_main, s)) {
        pthread_cond_destroy(&w->cv);
        pthread_mutex_destroy(&w->mu);
        return tvpal_diag_set(diag, TVPAL_E_SYS,
                              "cannot start the stager thread");
    }
    w->started = 1;
    return 0;
}

int tvpal_stream_create(struct tvpal_stream **out, struct tvpal_slab **slabs,
                        unsigned nslabs, enum tvpal_io_kind kind, int incore,
                        unsigned prefetch, uint64_t read_ahead,
                        uint64_t keep_bytes, unsigned policy,
                        struct tvpal_diag *diag)
{
    int rc = 0;
    struct tvpal_io *io = NULL;
    struct tvpal_diag d = {{0}};
    struct tvpal_stream *s = calloc(1, sizeof *s);
    if (!s)
        return TVPAL_E_NOMEM;
    rc = tvpal_io_create(&io, kind, 256, &d);
    if (rc < 0 && kind == TVPAL_IO_URING && (policy & TVPAL_STREAM_STRICT_IO)) {
        free(s);
        return tvpal_diag_set(diag, TVPAL_E_SYS, "io_uring unavailable: %s",
                              d.msg[0] ? d.msg : tvpal_strerror(rc));
    }
    if (rc < 0 && kind == TVPAL_IO_URING) { /* kernel, seccomp, container */
        fell_back(s, "io_uring unavailable (%s%s): reading with pread",
                  d.msg[0] ? d.msg : tvpal_strerror(rc), "");
        rc = tvpal_io_create(&io, TVPAL_IO_PREAD, 256, diag);
    }
    if (rc < 0) {
        free(s);
        return rc;
    }
    s->policy = policy;
    s->p = calloc(nslabs, sizeof *s->p);
    s->n = nslabs;
    s->io = io;
    s->incore = incore;
    s->prefetch = prefetch;
    s->ahead_bytes = read_ahead;
    if (!s->p) {
        tvpal_io_free(io);
        free(s);
        return TVPAL_E_NOMEM;
    }
    for (unsigned i = 0; i < nslabs; i++) {
        struct part *p = &s->p[i];
        p->slab = slabs[i];
        p->sh = tvpal_slab_shard(slabs[i]);
        p->fd = -1;
    }
    if (!incore && nslabs > 0) {
        const struct tvpal_schedule sc =
            tvpal_shard_schedule(tvpal_shard_hdr(s->p[0].sh));
        const unsigned win = tvpal_schedule_max_len(&sc);
        /* A step's records over the shards (the largest after record 0
         * of each). */
        uint64_t step_bytes = 0;
        for (unsigned i = 0; i < nslabs; i++)
            step_bytes += steady_record_bytes(s->p[i].sh);
        s->ahead = (policy & TVPAL_STREAM_KEEP_AHEAD) != 0;
        s->around = prefetch > 0 ? around_of(s, keep_bytes, step_bytes,
                                             s->ahead) : 0;
        /* A keep job's reads in flight at once: two records of a step
         * (at least 8 MiB).  Queued further, they would be read even when
         * the steps they are for are skipped (a slow disk's catch-up),
         * before what the next plan needs. */
        const uint64_t cap = (2 * step_bytes + PIECE - 1) / PIECE;
        s->keep_cap = cap < 8 ? 8 : cap > 192 ? 192 : (unsigned)cap;
        s->want_cap = 16 + prefetch + (s->around ? 2 * s->around + win : 0);
        if (!(s->want = calloc(s->want_cap, sizeof *s->want)))
            rc = TVPAL_E_NOMEM;
    }
    for (unsigned i = 0; i < nslabs && rc == 0; i++) {
        struct part *p = &s->p[i];
        const struct tvpal_shard_header *h = tvpal_shard_hdr(p->sh);
        rc = open_part(s, p, diag);
        if (rc == 0 && tvpal_shard_coded(p->sh))
            rc = open_inflater(s, p);
        if (rc < 0)
            break;
        /* The neighbourhood's records beside the others, and the N a
         * slab shows after a jump away from it. */
        const unsigned kept = !s->around ? 0
                              : s->ahead ? s->around + 2 * h->window
                                         : 2 * s->around + 2 * h->window;
        rc = incore ? load_incore(s, p, diag)
                    : alloc_slots(p, 2 * h->window + 2 * prefetch + 1 + kept);
        /* Ahead, the read-ahead's buffers are used from its first keep
         * on: a buffer's first read faults in and pins its pages (see
         * victim), which jumps would otherwise spread over all of them. */
        if (rc == 0 && !incore && s->ahead)
            p->nslots = 2 * h->window + 2 * prefetch + 1;
        /* The slices show their indices where the records are, not a
         * copy: in-core in RAM for as long as the stream; streamed in the
         * record buffers, which are not reused while a slice shows or
         * has staged a window from them (victim). */
        if (rc == 0)
            tvpal_slab_borrow(p->slab, 1);
    }
    if (rc == 0 && !incore)
        register_table(s);
    if (rc == 0)
        series_of(s);
    if (rc == 0 && prefetch > 0 && nslabs > 0)
        rc = start_stager(s, diag);
    if (rc < 0) {
        tvpal_stream_free(s);
        return rc;
    }
    *out = s;
    return 0;
}

void tvpal_stream_free(struct tvpal_stream *s)
{
    if (!s)
        return;
    if (s->w.started) {
        stager_wait(s);
        pthread_mutex_lock(&s->w.mu);
        s->w.quit = 1;
        pthread_cond_broadcast(&s->w.cv);
        pthread_mutex_unlock(&s->w.mu);
        pthread_join(s->w.th, NULL);
        pthread_cond_destroy(&s->w.cv);
        pthread_mutex_destroy(&s->w.mu);
        unstage_all(s);
    }
    /* Nothing may stay in flight into buffers freed here, and the slabs
     * (which outlive the stream) must not show them. */
    while (s->io && tvpal_io_inflight(s->io) && reap(s, NULL, NULL) == 0)
        ;
    for (unsigned i = 0; i < s->n; i++)
        if (s->p[i].slab) {
            tvpal_slab_detach(s->p[i].slab, UINT32_MAX);
            tvpal_slab_borrow(s->p[i].slab, 0);
        }
    for (unsigned i = 0; i < s->n; i++) {
        struct part *p = &s->p[i];
        if (p->fd >= 0)
            close(p->fd);
        free(p->all);
        free(p->bad);
        tvpal_chunkz_free(p->z);
        free(p->plain_off);
        for (uint32_t t = 0; p->why && t < tvpal_shard_hdr(p->sh)->steps; t++)
            free(p->why[t]);
        free(p->why);
        for (unsigned k = 0; p->slots && k < p->nslots_all; k++)
            free(p->slots[k].buf);
        free(p->slots);
    }
    tvpal_io_free(s->io);
    tvpal_pool_free(s->pool);
    free(s->p);
    free(s->want);
    free(s);
}

const char *tvpal_stream_io_name(const struct tvpal_stream *s)
{
    return tvpal_io_name(s->io);
}

void tvpal_stream_path(const struct tvpal_stream *s,
                       struct tvpal_stream_path *out)
{
    stager_wait((struct tvpal_stream *)s); /* its reads count too */
    out->io = tvpal_io_name(s->io);
    out->direct_files = s->direct_files;
    out->files = s->n;
    out->why = s->why;
    out->fixed = tvpal_io_table(s->io) > 0 && !s->fixed_refused;
    out->fixed_reads = tvpal_io_fixed_reads(s->io);
    out->buffers = 0;
    for (unsigned pi = 0; pi < s->n; pi++)
        for (unsigned k = 0; k < s->p[pi].nslots; k++)
            out->buffers += s->p[pi].slots[k].touched != 0;
    out->fixed_why = s->fixed_why;
}

/* The slot holding or reading `step` (at most one: queue_step reads a
 * step only where none has it), or -1.  Over all the slots, those not in
 * use yet being free: tvpal_stream_ready asks on the caller's thread
 * while the stager may widen p->nslots. */
static int find_slot(const struct part *p, uint32_t step)
{
    for (unsigned k = 0; k < p->nslots_all; k++)
        if (__atomic_load_n(&p->slots[k].state, __ATOMIC_ACQUIRE) !=
                SLOT_FREE &&
            __atomic_load_n(&p->slots[k].step, __ATOMIC_RELAXED) == step)
            return (int)k;
    return -1;
}

/* The steps a part wants at a step t (wanted_steps): step[0..nn) the
 * records t needs, ascending, then the others in the order they are read
 * (the prefetch window in the play direction, or the kept neighbourhood
 * nearest first), all of which lie in [lo, hi] (none: lo > hi).  step is
 * the stream's scratch (one list at a time: the stager and the caller
 * never run the stream together). */
struct want {
    uint32_t *step;
    unsigned n, nn;
    uint32_t lo, hi;
    uint32_t t;     /* the step they are wanted at, */
    int dir;        /* playing in this direction (0: paused) */
    int list;       /* the steps ahead wrap round the loop
                     * (tvpal_stream_loop): they are not one interval, and
                     * all of step[0..n) are wanted, lo > hi */
};

static int wanted(const struct want *w, uint32_t step)
{
    if (w->lo <= step && step <= w->hi)
        return 1;
    for (unsigned i = 0; i < (w->list ? w->n : w->nn); i++)
        if (w->step[i] == step)
            return 1;
    return 0;
}

/* How far playback from w->t in direction w->dir is from showing
 * record q again, in steps (q is shown from step q on): round the loop
 * (tvpal_stream_loop) where t lies in it, the N - 1 records before its
 * first step being shown there, and records outside it never; otherwise
 * records behind the playhead after every one ahead, the farthest behind
 * last.  A neighbourhood around t (no read-ahead): the distance from t.
 * victim reuses the buffer shown again last, as Belady's rule would: a
 * loop longer than the buffers then keeps as many of its records as
 * they hold from one round to the next (reusing the first landed one
 * found, as before, kept few: each round read nearly every record
 * again). */
static uint64_t next_use(const struct tvpal_stream *s, const struct want *w,
                         uint32_t q)
{
    const uint32_t t = w->t;
    const uint64_t T = tvpal_shard_hdr(s->p[0].sh)->steps;
    if (s->around && !s->ahead)
        return q > t ? q - t : t - q;
    const uint32_t lo = s->loop_lo, hi = s->loop_hi;
    if (lo <= hi && t >= lo && t <= hi) {
        const struct tvpal_schedule sc =
            tvpal_shard_schedule(tvpal_shard_hdr(s->p[0].sh));
        if (q < lo && q + tvpal_schedule_max_len(&sc) > lo)
            q = lo;
        else if (q < lo || q > hi)
            return 2 * T;
        const uint64_t L = (uint64_t)hi - lo + 1;
        return w->dir < 0 ? ((uint64_t)t + L - q) % L
                          : ((uint64_t)q + L - t) % L;
    }
    if (w->dir < 0)
        return q <= t ? t - q : T + q - t;
    return q >= t ? q - t : T + t - q;
}

/* A slot to reuse: free, or landed, not wanted (w: steps needed
 * now, in the prefetch window or the kept neighbourhood) and not shown or staged by the slab
 * (which borrows the records' indices).  With detach (the caller's
 * thread, while nothing draws), failing that, a landed unwanted slot the
 * slab borrows from, its windows copied into the slab first: cannot
 * happen with the slots alloc_slots counts, unless records failed.
 *
 * A record a step needs now (need) takes a buffer never read into before
 * a landed record: the buffers then keep what jumps have read, for the
 * jumps after.  A prefetched record takes a landed one first: a buffer's
 * first read faults in and pins its pages, on a Firecracker VM 60-80 ms
 * of CPU for a 34 MB buffer (512^3, N = 4), and steady playback, which
 * only prefetches, went through all 2N + 2P + 1 buffers in its first 12
 * frames (100-400 ms each) instead of the N + P + 1 it uses. */
static int victim(const struct tvpal_stream *s, const struct part *p,
                  const struct want *w, int need, int detach)
{
    int fresh = -1; /* a free buffer never read into */
    for (unsigned k = 0; k < p->nslots; k++)
        if (p->slots[k].state == SLOT_FREE) {
            if (need || p->slots[k].touched)
                return (int)k;
            if (fresh < 0)
                fresh = (int)k;
        }
    int borrowed = -1; /* landed, unwanted, but shown or staged */
    int last = -1;     /* landed, unwanted, shown again last */
    uint64_t last_use = 0;
    for (unsigned k = 0; k < p->nslots; k++) {
        const struct slot *sl = &p->slots[k];
        if (sl->state != SLOT_READY || wanted(w, sl->step))
            continue;
        if (!tvpal_slab_borrows(p->slab, sl->step)) {
            const uint64_t u = next_use(s, w, sl->step);
            if (last < 0 || u > last_use) {
                last = (int)k;
                last_use = u;
            }
        } else if (borrowed < 0) {
            borrowed = (int)k;
        }
    }
    /* Where the stream keeps records (a neighbourhood, or a read-ahead
     * once asked for: its buffers are there to be filled), a landed
     * record playback shows again (round a loop) stays while a buffer
     * never read into is left: its first read costs the page faults
     * once, reading the record again costs the disk each round.  Not for
     * coded records: inflating them, not the disk, bounds playback on 2
     * cores, and the faults' CPU cost more than the reads they save
     * (512^3 at half the disk rate: 92% of the frames below full level
     * against 70%).  Plain streaming keeps to the buffers it has touched
     * (see above). */
    const int keeps = s->around && !p->z &&
                      (!s->ahead ||
                       __atomic_load_n(&s->ahead_on, __ATOMIC_RELAXED));
    if (last >= 0 && (fresh < 0 || !keeps ||
                      last_use >= tvpal_shard_hdr(p->sh)->steps))
        return last;
    if (fresh >= 0)
        return fresh;
    if (detach && borrowed >= 0)
        tvpal_slab_detach(p->slab, p->slots[borrowed].step);
    return detach ? borrowed : -1;
}

/* Applies (stage = 0) or stages (1) the verified record of `step` into
 * the part's slab for timestep t.  0 or TVPAL_E_NOMEM (staging). */
static int feed_record(struct part *p, const unsigned char *rec, uint32_t t,
                       uint32_t step, int stage, struct tvpal_diag *diag)
{
    if (!stage) {
        tvpal_slab_apply(p->slab, rec, t);
        return 0;
    }
    int rc = tvpal_slab_stage(p->slab, rec, t);
    return rc < 0 ? tvpal_diag_set(diag, rc, "staging record %u", step) : 0;
}

/* In-core: the records that hold t, from RAM (verified when loaded).  A
 * record that failed to load is the first error; the others still go in. */
static int seek_incore(struct tvpal_stream *s, uint32_t t,
                       struct tvpal_stream_stats *st, struct tvpal_diag *diag,
                       int stage)
{
    int err = 0;
    for (unsigned pi = 0; pi < s->n; pi++) {
        struct part *p = &s->p[pi];
        uint32_t need[TVPAL_SCHEDULE_RECORDS_MAX];
        unsigned nn = tvpal_slab_needed(p->slab, t, need);
        for (unsigned i = 0; i < nn; i++) {
            if (p->bad[need[i]]) {
                if (!err)
                    err = incore_error(p, need[i], diag);
                continue;
            }
            int rc = feed_record(p, incore_rec(p, need[i]), t, need[i], stage,
                                 diag);
            if (rc < 0)
                return rc;
            st->records_applied++;
        }
    }
    return err;
}

/* The step steady playback reaches after t in direction dir: round the
 * loop (tvpal_stream_loop) from its last step to its first, else the
 * next in the series; -1 past its end. */
static int64_t step_after(const struct tvpal_stream *s, uint32_t t, int dir)
{
    const int64_t q = (int64_t)t + (dir < 0 ? -1 : 1);
    if (s->loop_lo <= s->loop_hi && t >= s->loop_lo && t <= s->loop_hi) {
        if (q > s->loop_hi)
            return s->loop_lo;
        if (q < s->loop_lo)
            return s->loop_hi;
    }
    return q < 0 || q >= tvpal_shard_hdr(s->p[0].sh)->steps ? -1 : q;
}

/* The steps part p wants at t (struct want): those it needs, then,
 * streamed with a neighbourhood (s->around), every record a step within
 * around of t needs, nearest first (the play direction first at equal
 * distance), or ahead (s->ahead) the steps after t in direction dir,
 * nearest first; else the prefetch window in direction dir. */
static void wanted_steps(const struct tvpal_stream *s, const struct part *p,
                         uint32_t t, int dir, struct want *w)
{
    const struct tvpal_shard_header *h = tvpal_shard_hdr(p->sh);
    const uint32_t steps = h->steps;
    w->step = s->want;
    w->t = t;
    w->dir = dir;
    w->n = w->nn = tvpal_slab_needed(p->slab, t, w->step);
    w->lo = 1;
    w->hi = 0;
    w->list = 0;
    if (s->around && !s->ahead) {
        /* Step q shows windows that start in [q - L + 1, q], L the
         * longest window (or at 0, record 0's first windows, when
         * q < L): the records of [t - around - L + 1, t + around]. */
        const struct tvpal_schedule sc = tvpal_shard_schedule(h);
        const uint32_t back = s->around + tvpal_schedule_max_len(&sc) - 1,
                       fwd = s->around;
        w->lo = t > back ? t - back : 0;
        w->hi = steps - 1 - t > fwd ? t + fwd : steps - 1;
        const int64_t sgn = dir < 0 ? -1 : 1;
        for (uint32_t d = 0; d <= (back > fwd ? back : fwd); d++)
            for (int side = 0; side < (d ? 2 : 1); side++) {
                const int64_t q = (int64_t)t + (side ? -sgn : sgn) * d;
                if (q < w->lo || q > w->hi || w->n >= s->want_cap)
                    continue;
                int dup = 0;
                for (unsigned i = 0; i < w->nn && !dup; i++)
                    dup = w->step[i] == (uint32_t)q;
                if (!dup)
                    w->step[w->n++] = (uint32_t)q;
            }
        return;
    }
    /* The prefetch window, or ahead, once a keep was asked for, the
     * kept steps (the records of the steps after t: each starts the
     * windows t + k shows new).  Until then a stream with a read-ahead
     * wants what one without it wants. */
    const int on = __atomic_load_n(&s->ahead_on, __ATOMIC_RELAXED);
    const unsigned far = on && s->around > s->prefetch ? s->around
                                                       : s->prefetch;
    uint32_t q = t;
    for (unsigned k = 1; k <= far && w->n < s->want_cap; k++) {
        const int64_t next = step_after(s, q, dir);
        if (next < 0 || next == t)
            break;
        if (dir < 0 ? next > q : next < q) {
            /* Round the loop: the step there needs every window that
             * covers it, the records of its windows' starts. */
            w->list = 1;
            const struct tvpal_schedule sc = tvpal_shard_schedule(h);
            uint32_t rec[TVPAL_SCHEDULE_RECORDS_MAX];
            const unsigned nrec =
                tvpal_schedule_records(&sc, (uint32_t)next, rec);
            for (unsigned i = 0; i < nrec && rec[i] < next &&
                                 w->n + 1 < s->want_cap; i++)
                w->step[w->n++] = rec[i];
        }
        q = (uint32_t)next;
        w->step[w->n++] = q;
        w->lo = k == 1 || q < w->lo ? q : w->lo;
        w->hi = k == 1 || q > w->hi ? q : w->hi;
    }
    if (w->list) {
        w->lo = 1;
        w->hi = 0;
    }
}

/* Queues the read of w->step[i] (the first w->nn needed) into a record
 * buffer of part pi, unless one holds it or has it in flight.  A needed
 * record waits for a buffer to come free (here: on the caller's thread,
 * see victim); a prefetched one is not queued (1) when none is free or
 * the queue is nearly full.  0, 1, or an error. */
static int queue_step(struct tvpal_stream *s, unsigned pi,
                      const struct want *w, unsigned i, int here,
                      struct tvpal_stream_stats *st, struct tvpal_diag *diag)
{
    struct part *p = &s->p[pi];
    const unsigned nn = w->nn;
    const uint32_t step = w->step[i];
    if (find_slot(p, step) >= 0)
        return 0;
    const int detach = here && i < nn; /* only for a needed record */
    int v = victim(s, p, w, i < nn, detach);
    /* After a jump the old prefetches may hold every free slot: wait for
     * them to land, then they can be reused. */
    while (v < 0 && i < nn && tvpal_io_inflight(s->io)) {
        int rc = reap(s, &st->io_wait_ms, diag);
        if (rc < 0)
            return rc;
        v = victim(s, p, w, i < nn, detach);
    }
    if (v < 0) {
        if (i < nn) /* cannot happen: 2N + 2P + 1 slots */
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "no free record buffer");
        return 1;
    }
    if (i >= nn && tvpal_io_inflight(s->io) + 8 > tvpal_io_depth(s->io))
        return 1; /* prefetch only while the queue has room */
    struct tvpal_diag qd = {{0}};
    int rc = submit(s, pi, (unsigned)v, step, &st->io_wait_ms, &qd);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "%s: cannot queue a read%s%s",
                              tvpal_shard_path(p->sh), qd.msg[0] ? ": " : "",
                              qd.msg);
    st->bytes_read += tvpal_shard_entry(p->sh, step)->bytes;
    if (i < nn)
        st->bytes_needed += tvpal_shard_entry(p->sh, step)->bytes;
    return 0;
}

/* Queues the reads of part pi: the first `ahead` of the records t needs
 * (prefetch = 0; feed_part queues the others as these land), or (1)
 * those of the prefetch window in direction dir not held yet, while the
 * queue has room.  The buffers of both stay reserved either way. */
static int queue_part(struct tvpal_stream *s, unsigned pi, uint32_t t,
                      int dir, int prefetch, unsigned ahead, int here,
                      struct tvpal_stream_stats *st, struct tvpal_diag *diag)
{
    struct want w;
    wanted_steps(s, &s->p[pi], t, dir, &w);
    unsigned from = prefetch ? w.nn : 0;
    /* With a neighbourhood, a seek queues the P nearest of it; keep
     * jobs read the rest, a few records in flight at a time. */
    const unsigned most = w.nn + s->prefetch < w.n ? w.nn + s->prefetch : w.n;
    unsigned to = prefetch ? most : ahead < w.nn ? ahead : w.nn;
    for (unsigned i = from; i < to; i++) {
        int rc = queue_step(s, pi, &w, i, here, st, diag);
        if (rc != 0)
            return rc < 0 ? rc : 0;
    }
    return 0;
}

/* Inflates coded record `step` in place in buf (tvpal_record_inflate_pool),
 * counting its plain bytes and wall time for tvpal_stream_meter. */
static int inflate_metered(struct part *p, struct tvpal_pool *pool,
                           unsigned char *buf,
                           const struct tvpal_index_entry *e, uint32_t step,
                           struct tvpal_diag *d)
{
    const double t0 = tvpal_now();
    const int rc = tvpal_record_inflate_pool(p->z, pool, buf, e, step,
                                             tvpal_shard_hdr(p->sh), d);
    const double s = tvpal_now() - t0;
    if (rc == 0) {
        __atomic_fetch_add(&p->inflated_bytes, e->plain_bytes,
                           __ATOMIC_RELAXED);
        __atomic_fetch_add(&p->inflate_ns, (uint64_t)(s > 0 ? s * 1e9 : 0),
                           __ATOMIC_RELAXED);
    }
    return rc;
}

/* Checks a landed slot holding `step` once: its length and CRCs.  0, or
 * the error in d (the slot is then freed, to be read again later). */
static int verify_slot(struct part *p, struct slot *sl, uint32_t step,
                       struct tvpal_pool *pool, struct tvpal_diag *d)
{
    if (sl->verified)
        return 0;
    const struct tvpal_index_entry *e = tvpal_shard_entry(p->sh, step);
    int rc;
    if (sl->result != (int64_t)e->bytes)
        rc = tvpal_diag_set(d, TVPAL_E_READ, "record %u: %s", step,
                            sl->result < 0 ? strerror((int)-sl->result)
                                           : "short read (truncated)");
    else if (e->coded)
        rc = inflate_metered(p, pool, sl->buf, e, step, d);
    else
        rc = tvpal_record_verify(sl->buf, e->bytes, step,
                                 tvpal_shard_hdr(p->sh), d);
    if (rc < 0) {
        __atomic_store_n(&sl->state, SLOT_FREE, __ATOMIC_RELAXED);
        return rc;
    }
    __atomic_store_n(&sl->verified, 1, __ATOMIC_RELEASE);
    return 0;
}

/* Stages the landed, unchecked record of `step` in slot sl for timestep
 * t, checking it on the way: its layout first, then its CRC summed chunk
 * by chunk as the chunks are staged (tvpal_slab_stage_verify), so the
 * record is read from memory once, not once to check it and again to
 * stage it.  0: staged and the slot verified.  A failed check: as
 * verify_slot (the same message; nothing of the record stays staged).
 * Staging out of memory: 0 with *fatal set. */
static int stage_checked(struct part *p, struct slot *sl, uint32_t t,
                         uint32_t step, struct tvpal_pool *pool,
                         struct tvpal_diag *d, int *fatal)
{
    const struct tvpal_index_entry *e = tvpal_shard_entry(p->sh, step);
    /* A coded record is checked as it is inflated; the plain record it
     * becomes is consistent by construction, so it is staged as it is. */
    if (e->coded || sl->verified) {
        int rc = verify_slot(p, sl, step, pool, d);
        if (rc < 0)
            return rc;
        rc = tvpal_slab_stage(p->slab, sl->buf, t);
        if (rc < 0)
            *fatal = rc;
        return 0;
    }
    if (sl->result != (int64_t)e->bytes ||
        tvpal_record_verify_layout(sl->buf, e->bytes, step,
                                   tvpal_shard_hdr(p->sh), NULL) < 0)
        return verify_slot(p, sl, step, NULL, d); /* its message, CRC first */
    int rc = tvpal_slab_stage_verify(p->slab, sl->buf, t);
    if (rc == TVPAL_E_CHECKSUM) {
        __atomic_store_n(&sl->state, SLOT_FREE, __ATOMIC_RELAXED);
        return tvpal_diag_set(d, rc, "record %u: payload CRC-32C mismatch",
                              step);
    }
    if (rc < 0)
        *fatal = rc;
    else
        __atomic_store_n(&sl->verified, 1, __ATOMIC_RELEASE);
    return 0;
}

/* How many of the records a step needs are in flight at once, counting
 * the one being waited for: enough for s->ahead_bytes, at least one.
 *
 * A device may finish a submission as a whole: on a Firecracker VM the 4
 * records of a 512^3 jump (N = 4, 34 MB each) all landed after 62 ms,
 * and the CPU then checked and staged them in another 17; one at a time,
 * each landed about 13 ms after the one before (the same rate) and was
 * staged while the next was read: 55 ms in all instead of 71.  A fast
 * NVMe device wants a few dozen 1 MiB reads in flight to reach its rate,
 * so small records go several at a time (the default, 32 MiB). */
static unsigned read_ahead(const struct tvpal_stream *s, const struct part *p)
{
    uint64_t b = p->steady_bytes ? p->steady_bytes : 1;
    uint64_t k = (s->ahead_bytes + b - 1) / b;
    return k < 1 ? 1 : k < 16 ? (unsigned)k : 16;
}

/* Waits for the records t needs from part pi, verifies and feeds them in
 * step order, queueing the reads of the later ones `ahead` records in
 * advance (seek_into queued the first); the first failing record goes to
 * *err, the others still go in.  0, or a failure that ends the seek. */
static int feed_part(struct tvpal_stream *s, unsigned pi, uint32_t t,
                     int dir, unsigned ahead, int here,
                     struct tvpal_stream_stats *st, struct tvpal_diag *diag,
                     int stage, int *err)
{
    struct part *p = &s->p[pi];
    /* what t needs before anything is fed (applying changes the answer) */
    struct want w;
    wanted_steps(s, p, t, dir, &w);
    const uint32_t *wanted = w.step;
    const unsigned nn = w.nn;
    for (unsigned i = 0; i < nn; i++) {
        int k = find_slot(p, wanted[i]);
        if (k < 0)
            continue; /* cannot happen: queued by queue_part */
        struct slot *sl = &p->slots[k];
        while (sl->state == SLOT_INFLIGHT) {
            int rc = reap(s, &st->io_wait_ms, diag);
            if (rc < 0)
                return rc;
        }
        if (i + ahead < nn) {
            struct tvpal_diag fd = {{0}};
            int rc = queue_step(s, pi, &w, i + ahead, here, st, diag);
            if (rc == 0 && (rc = tvpal_io_flush(s->io, &fd)) < 0)
                tvpal_diag_set(diag, rc, "%s", fd.msg);
            if (rc < 0)
                return rc;
        }
        struct tvpal_diag d = {{0}};
        int fatal = 0, fed = stage && !sl->verified;
        int rc = fed ? stage_checked(p, sl, t, wanted[i], s->pool, &d, &fatal)
                     : verify_slot(p, sl, wanted[i], s->pool, &d);
        if (fatal)
            return tvpal_diag_set(diag, fatal, "staging record %u", wanted[i]);
        if (rc < 0) {
            if (!*err)
                *err = tvpal_diag_set(diag, rc, "%s: %s",
                                      tvpal_shard_path(p->sh), d.msg);
            continue;
        }
        if (!fed && (rc = feed_record(p, sl->buf, t, wanted[i], stage, diag)) < 0)
            return rc;
        st->records_applied++;
    }
    return 0;
}

/* How seek_into feeds: applied in place, or staged (each unchecked record
 * summed as it is staged: one pass over it, not two); and whether it
 * queues the prefetch after. */
enum { SEEK_APPLY = 0, SEEK_STAGE = 1, SEEK_PREFETCH = 2,
       SEEK_HERE = 4 /* on the caller's thread: nothing draws meanwhile */ };

/* Applies or stages (how & SEEK_STAGE) into every slab the records that
 * hold timestep t, reading them first out-of-core (read_ahead of them at
 * a time; all parts' first ones in one submission); with SEEK_PREFETCH
 * queues the prefetch after. */
static int seek_into(struct tvpal_stream *s, uint32_t t, int dir,
                     struct tvpal_stream_stats *st, struct tvpal_diag *diag,
                     unsigned how)
{
    const int stage = (how & SEEK_STAGE) != 0, here = (how & SEEK_HERE) != 0;
    memset(st, 0, sizeof *st);
    if (s->incore)
        return seek_incore(s, t, st, diag, stage);
    /* The records t needs go to the device alone, and the prefetch only
     * once they are in: reads queued together share the device, and a
     * 512^3 jump at N = 4 waited for 169 MB instead of its 136 (the next
     * step, staged after it, for 5 records instead of 1). */
    for (unsigned pi = 0; pi < s->n; pi++) {
        int rc = queue_part(s, pi, t, dir, 0, read_ahead(s, &s->p[pi]), here,
                            st, diag);
        if (rc < 0)
            return rc;
    }
    struct tvpal_diag fd = {{0}};
    int rc = tvpal_io_flush(s->io, &fd);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "%s", fd.msg);
    int err = 0;
    for (unsigned pi = 0; pi < s->n; pi++)
        if ((rc = feed_part(s, pi, t, dir, read_ahead(s, &s->p[pi]), here, st,
                            diag, stage, &err)) < 0)
            return rc;
    if (!(how & SEEK_PREFETCH))
        return err;
    for (unsigned pi = 0; pi < s->n; pi++)
        if ((rc = queue_part(s, pi, t, dir, 1, 0, here, st, diag)) < 0)
            return rc;
    if ((rc = tvpal_io_flush(s->io, &fd)) < 0)
        return tvpal_diag_set(diag, rc, "%s", fd.msg);
    return err;
}

/* A keep job is to stop: the caller wants the stream (stager_wait), or
 * another job was posted. */
static int keep_cancelled(struct stager *w)
{
    pthread_mutex_lock(&w->mu);
    int c = w->cancel || w->next || w->quit;
    pthread_mutex_unlock(&w->mu);
    return c;
}

/* The stager's keep job (tvpal_stream_keep): the records of the steps
 * within s->around of t (ahead: after t in direction dir) read into
 * buffers not shown or staged, then (around) checked, so that a seek to
 * any of them only applies.  Stops early when
 * cancelled; its reads still in flight then land at a later wait.  A
 * failed read or check frees the slot: the seek that needs the record
 * reads it again and reports it, as in plain streaming. */
static void keep_around(struct tvpal_stream *s, uint32_t t, int dir)
{
    struct tvpal_stream_stats st = {0};
    struct tvpal_diag d = {{0}};
    for (unsigned pi = 0; pi < s->n; pi++)  /* the stager's thread: */
        s->p[pi].nslots = s->p[pi].nslots_all; /* no seek runs now */
    for (unsigned pi = 0; pi < s->n && !keep_cancelled(&s->w); pi++) {
        struct want w;
        wanted_steps(s, &s->p[pi], t, dir, &w);
        /* Around: the needed lie in [lo, hi], and nothing is needed
         * now.  Ahead: they are kept too, t being the step playback will
         * be at (a plan's target) or is at. */
        for (unsigned i = 0; i < w.nn && !w.list; i++) {
            w.lo = w.step[i] < w.lo || w.lo > w.hi ? w.step[i] : w.lo;
            w.hi = w.step[i] > w.hi ? w.step[i] : w.hi;
        }
        w.nn = 0;   /* in the list, wanted still */
        for (unsigned i = 0; i < w.n; i++) {
            int rc;
            while (((rc = tvpal_io_inflight(s->io) >= s->keep_cap) ||
                    (rc = queue_step(s, pi, &w, i, 0, &st, &d)) == 1) &&
                   tvpal_io_inflight(s->io)) {
                if (keep_cancelled(&s->w) || tvpal_io_flush(s->io, &d) < 0 ||
                    reap_for(s, KEEP_POLL_MS, NULL, &d) < 0)
                    return;
            }
            if (rc != 0 || keep_cancelled(&s->w))
                break;  /* no buffer left (1), or the I/O layer failed */
        }
    }
    if (tvpal_io_flush(s->io, &d) < 0)
        return;
    while (tvpal_io_inflight(s->io) && !keep_cancelled(&s->w))
        if (reap_for(s, KEEP_POLL_MS, NULL, &d) < 0)
            return;
    /* Ahead, a record is checked as it is staged (one pass over it,
     * stage_checked); around, a jump applies it on the caller's thread,
     * so it is checked here. */
    for (unsigned pi = 0; pi < s->n && !s->ahead; pi++) {
        struct part *p = &s->p[pi];
        for (unsigned k = 0; k < p->nslots && !keep_cancelled(&s->w); k++) {
            struct slot *sl = &p->slots[k];
            if (sl->state == SLOT_READY && !sl->verified)
                (void)verify_slot(p, sl, sl->step, s->pool, &d);
        }
    }
}

/* With w->mu held: the stager's next job is the keep of t in direction
 * dir. */
static void keep_post(struct stager *w, uint32_t t, int dir)
{
    w->keep = 1;
    w->cancel = 0;
    w->t = t;
    w->keep_dir = dir;
    w->state = STAGER_PENDING;
    pthread_cond_broadcast(&w->cv);
}

/* With w->mu held, on the caller's thread: a keep waiting to run after a
 * staged step is dropped and one running is cut short; either is asked
 * for again by the next tvpal_stream_keep of its step (which reads what
 * is missing). */
static void keep_drop(struct tvpal_stream *s)
{
    struct stager *w = &s->w;
    const int running = w->keep && w->state != STAGER_IDLE;
    if (w->keep_after || running)
        s->kept = 0;
    w->keep_after = 0;
    if (running)
        w->cancel = 1;
}

/* After a job, with w->mu held: a step posted meanwhile
 * (tvpal_stream_prepare) is run next, from the step the slabs show. */
static void run_next(struct tvpal_stream *s)
{
    struct stager *w = &s->w;
    pthread_mutex_unlock(&w->mu);
    unstage_all(s);
    pthread_mutex_lock(&w->mu);
    w->t = w->next_t;
    w->dir = w->next_dir;
    w->alone = w->next_alone;
    w->next = 0;
    w->state = STAGER_PENDING;
}

static void *stager_main(void *arg)
{
    struct tvpal_stream *s = arg;
    struct stager *w = &s->w;
    pthread_mutex_lock(&w->mu);
    for (;;) {
        while (w->state != STAGER_PENDING && !w->quit)
            pthread_cond_wait(&w->cv, &w->mu);
        if (w->quit)
            break;
        w->state = STAGER_RUNNING;
        uint32_t t = w->t;
        int dir = w->dir;
        const unsigned how = SEEK_STAGE | (w->alone ? 0 : SEEK_PREFETCH);
        if (w->keep) {
            const int kdir = w->keep_dir;
            pthread_mutex_unlock(&w->mu);
            keep_around(s, t, kdir);
            pthread_mutex_lock(&w->mu);
            w->keep = 0;
            w->cancel = 0;
            if (w->next) {
                run_next(s);
                continue;
            }
            w->state = STAGER_IDLE;  /* what is staged, if anything, stays */
            pthread_cond_broadcast(&w->cv);
            continue;
        }
        pthread_mutex_unlock(&w->mu);
        struct tvpal_stream_stats st;
        struct tvpal_diag d = {{0}};
        const double s0 = tvpal_now();
        int rc = seek_into(s, t, dir, &st, &d, how);
        st.stage_ms = (tvpal_now() - s0) * 1e3;
        pthread_mutex_lock(&w->mu);
        if (w->next) {
            /* Another step was asked for meanwhile: this one goes. */
            run_next(s);
            continue;
        }
        w->rc = rc;
        w->diag = d;
        w->st = st;
        w->have = 1;
        w->staged_t = t;
        if (w->keep_after) {
            /* The step is staged (tvpal_stream_ready says so); the keep
             * asked for meanwhile runs now, cut short by the next seek. */
            w->keep_after = 0;
            keep_post(w, w->keep_after_t, w->keep_after_dir);
            continue;
        }
        w->state = STAGER_IDLE;
        pthread_cond_broadcast(&w->cv);
    }
    pthread_mutex_unlock(&w->mu);
    return NULL;
}

/* Waits until the stager is idle (it then touches nothing); a keep job
 * is cut short. */
static void stager_wait(struct tvpal_stream *s)
{
    struct stager *w = &s->w;
    if (!w->started)
        return;
    pthread_mutex_lock(&w->mu);
    keep_drop(s);
    while (w->state != STAGER_IDLE)
        pthread_cond_wait(&w->cv, &w->mu);
    pthread_mutex_unlock(&w->mu);
}

int tvpal_stream_keep(struct tvpal_stream *s, uint32_t t, int dir)
{
    struct stager *w = &s->w;
    if (s->incore || !s->around)
        return 0;
    if (!w->started || t >= tvpal_shard_hdr(s->p[0].sh)->steps)
        return TVPAL_E_INVAL;
    dir = dir < 0 ? -1 : 1;
    int posted = 0;
    if (s->ahead)
        __atomic_store_n(&s->ahead_on, 1, __ATOMIC_RELAXED);
    pthread_mutex_lock(&w->mu);
    if (s->kept && s->keep_t == t && s->keep_dir_neg == (dir < 0)) {
        /* asked for already */
    } else if (w->state == STAGER_IDLE) {
        keep_post(w, t, dir);
        posted = 1;
    } else if (!w->keep && !w->next) {
        /* A step being staged: after it (the frame's own comes first). */
        w->keep_after = 1;
        w->keep_after_t = t;
        w->keep_after_dir = dir;
        posted = 1;
    }
    pthread_mutex_unlock(&w->mu);
    if (posted) {
        s->kept = 1;
        s->keep_t = t;
        s->keep_dir_neg = dir < 0;
    }
    return posted;
}

int tvpal_stream_busy(struct tvpal_stream *s)
{
    struct stager *w = &s->w;
    if (!w->started)
        return 0;
    pthread_mutex_lock(&w->mu);
    const int busy = w->state != STAGER_IDLE;
    pthread_mutex_unlock(&w->mu);
    return busy;
}

unsigned tvpal_stream_around(const struct tvpal_stream *s)
{
    return s->around;
}

int tvpal_stream_kept(const struct tvpal_stream *s, uint32_t t)
{
    if (!s->around || !s->kept)
        return 0;
    if (s->ahead) { /* the steps after keep_t in its direction */
        uint32_t q = s->keep_t;
        for (unsigned k = 0; k <= s->around; k++) {
            if (q == t)
                return 1;
            const int64_t next = step_after(s, q, s->keep_dir_neg ? -1 : 1);
            if (next < 0 || next == s->keep_t)
                return 0;
            q = (uint32_t)next;
        }
        return 0;
    }
    return t <= s->keep_t ? s->keep_t - t <= s->around
                          : t - s->keep_t <= s->around;
}

/* Posts the job of staging step t: the next step in steady playback,
 * with the prefetch beyond it, or a prepared one (alone). */
static void stager_post(struct tvpal_stream *s, uint32_t t, int dir, int alone)
{
    struct stager *w = &s->w;
    pthread_mutex_lock(&w->mu);
    w->keep = 0;
    w->t = t;
    w->dir = dir;
    w->alone = alone;
    w->state = STAGER_PENDING;
    pthread_cond_broadcast(&w->cv);
    pthread_mutex_unlock(&w->mu);
}

int tvpal_stream_prepare(struct tvpal_stream *s, uint32_t t, int dir,
                         int prefetch)
{
    const int alone = !prefetch;
    struct stager *w = &s->w;
    if (!w->started || t >= tvpal_shard_hdr(s->p[0].sh)->steps)
        return TVPAL_E_INVAL;
    pthread_mutex_lock(&w->mu);
    if ((w->state == STAGER_IDLE || (w->keep && !w->next)) && w->have &&
        w->staged_t == t) {             /* already there (a keep may go on) */
        pthread_mutex_unlock(&w->mu);
        return 0;
    }
    if (w->state == STAGER_IDLE) {
        /* Idle: the staging buffers are the caller's until it posts. */
        pthread_mutex_unlock(&w->mu);
        if (w->have)
            unstage_all(s);
        stager_post(s, t, dir, alone);
        return 0;
    }
    if (w->state == STAGER_PENDING && !w->keep) { /* not begun: take its
                                                  * place */
        w->t = t;
        w->dir = dir;
        w->alone = alone;
        w->next = 0;
    } else {        /* running, or a keep (which a step staged may
                     * precede): after it, from the step shown */
        keep_drop(s);
        w->next = 1;
        w->next_t = t;
        w->next_dir = dir;
        w->next_alone = alone;
    }
    pthread_mutex_unlock(&w->mu);
    return 0;
}

/* Whether every record step t needs in part p's slab (tvpal_slab_needed,
 * from what the slab shows) has landed in a record buffer, and a coded
 * one been inflated there: a seek to t then reads nothing, and inflates
 * nothing on the caller's thread (at 512^3, 40-80 ms a record).  The
 * caller's thread, while a keep job may run on the stager's: a buffer
 * that job takes meanwhile for another step only makes the seek read
 * that record again. */
static int part_holds(const struct part *p, uint32_t t)
{
    uint32_t need[TVPAL_SCHEDULE_RECORDS_MAX];
    const unsigned nn = tvpal_slab_needed(p->slab, t, need);
    for (unsigned i = 0; i < nn; i++) {
        const int k = find_slot(p, need[i]);
        if (k < 0 ||
            __atomic_load_n(&p->slots[k].state, __ATOMIC_ACQUIRE) !=
                SLOT_READY ||
            (tvpal_shard_entry(p->sh, need[i])->coded &&
             !__atomic_load_n(&p->slots[k].verified, __ATOMIC_ACQUIRE)))
            return 0;
    }
    return 1;
}

int tvpal_stream_ready(struct tvpal_stream *s, uint32_t t, double wait_ms)
{
    struct stager *w = &s->w;
    if (s->incore || (!w->started && s->have_cur && s->cur_t == t))
        return 1;
    if (!w->started)
        return 0;
    struct timespec until;
    clock_gettime(CLOCK_MONOTONIC, &until);
    if (wait_ms > 0) {
        const long long ns = until.tv_nsec + (long long)(wait_ms * 1e6);
        until.tv_sec += (time_t)(ns / 1000000000);
        until.tv_nsec = (long)(ns % 1000000000);
    }
    pthread_mutex_lock(&w->mu);
    /* A job for t still to finish (or t after the job running) is
     * waited for; anything else staged will not become t. */
    int ready;
    while (!(ready = (w->state == STAGER_IDLE || (w->keep && !w->next)) &&
                     w->have && w->staged_t == t) &&
           wait_ms > 0 && w->state != STAGER_IDLE && !(w->keep && !w->next) &&
           (w->next ? w->next_t : w->t) == t &&
           pthread_cond_timedwait(&w->cv, &w->mu, &until) == 0)
        ;
    /* Not staged, but shown already, or in the record buffers (read
     * ahead, or kept from a round before): a seek reads nothing once the
     * stager is idle or only keeping (which the seek stops); not while
     * it stages or prepares a step, which the seek would wait for. */
    const int quiet = w->state == STAGER_IDLE || (w->keep && !w->next);
    pthread_mutex_unlock(&w->mu);
    if (!ready && quiet && s->have_cur && s->cur_t == t)
        return 1;
    if (!ready && quiet) {
        ready = 1;
        for (unsigned pi = 0; pi < s->n && ready; pi++)
            ready = part_holds(&s->p[pi], t);
    }
    return ready;
}

static void unstage_all(struct tvpal_stream *s)
{
    for (unsigned pi = 0; pi < s->n; pi++)
        tvpal_slab_unstage(s->p[pi].slab);
    s->w.have = 0;
}

/* Streamed, the slices show their indices in the record buffers: those
 * of slices whose record for t failed (an older window) are copied in,
 * so that the buffers pinned for what is shown stay the N records of t
 * (alloc_slots counts on it). */
static void detach_stale(struct tvpal_stream *s, uint32_t t)
{
    for (unsigned pi = 0; pi < s->n && !s->incore; pi++)
        tvpal_slab_detach_stale(s->p[pi].slab, t);
}

/* A step the stager did not prepare (a jump, the first frame, a redraw),
 * on the caller's thread; the stager, posted right after, prefetches.
 * Streamed, once the slabs show a step and nothing is staged, the records
 * are staged and installed: each is then read from memory once, its CRC
 * summed as it is copied, and a bad one still leaves its slices their
 * last good window.  Measured on a 512^3 jump (N = 4, Firecracker VM):
 * 4.5 ms a record against 6.5 checked and then applied, and reads landing
 * every 12.5 ms against 14 (the two passes slow the virtual disk too).
 * The price: the pool of spare windows grows to one per slice at the
 * first such jump (their tables; their index buffers stay untouched
 * while the slab borrows the records').  Otherwise (in-core: the
 * records were checked when loaded; the first frame: no window to keep;
 * something staged for the next step, which an install would show too),
 * or where staging runs out of memory, the records are checked, then
 * applied in place. */
static int seek_here(struct tvpal_stream *s, uint32_t t, int dir,
                     struct tvpal_stream_stats *st, struct tvpal_diag *diag)
{
    if (s->incore || !s->have_cur || s->w.have)
        return seek_into(s, t, dir, st, diag, SEEK_APPLY | SEEK_HERE);
    int rc = seek_into(s, t, dir, st, diag, SEEK_STAGE | SEEK_HERE);
    if (rc == TVPAL_E_NOMEM) {
        unstage_all(s);
        return seek_into(s, t, dir, st, diag, SEEK_APPLY | SEEK_HERE);
    }
    for (unsigned pi = 0; pi < s->n; pi++)
        tvpal_slab_install(s->p[pi].slab);
    return rc;
}

int tvpal_stream_seek(struct tvpal_stream *s, uint32_t t, int dir,
                      struct tvpal_stream_stats *st, struct tvpal_diag *diag)
{
    struct tvpal_stream_stats local;
    if (!st)
        st = &local;
    struct stager *w = &s->w;
    int rc;
    if (!w->started) {
        rc = seek_into(s, t, dir, st, diag,
                       SEEK_APPLY | SEEK_PREFETCH | SEEK_HERE);
        detach_stale(s, t);
        return rc;
    }
    stager_wait(s);
    if (w->have && w->staged_t == t) {
        /* Prepared while the previous step was drawn: swap it in. */
        for (unsigned pi = 0; pi < s->n; pi++)
            tvpal_slab_install(s->p[pi].slab);
        *st = w->st;
        st->records_staged = st->records_applied;
        rc = w->rc;
        if (rc < 0)
            tvpal_diag_set(diag, rc, "%s", w->diag.msg);
        w->have = 0;
    } else {
        /* The same step again (a redraw, or a retry of a failed record)
         * leaves what is staged for the next one: seeking cur_t can only
         * add windows, so what was staged stays what the next step needs
         * or more.  Anything else (a jump) drops it. */
        if (w->have && !(s->have_cur && t == s->cur_t))
            unstage_all(s);
        rc = seek_here(s, t, dir ? dir : 1, st, diag);
    }
    s->have_cur = 1;
    s->cur_t = t;
    detach_stale(s, t);
    const int64_t next = s->n ? step_after(s, t, dir) : -1;
    if (w->have && (int64_t)w->staged_t != next)
        unstage_all(s);
    if (dir != 0 && !w->have && next >= 0)
        stager_post(s, (uint32_t)next, dir, 0);
    return rc;
}

uint64_t tvpal_stream_submits(const struct tvpal_stream *s)
{
    stager_wait((struct tvpal_stream *)s); /* its reads count too */
    return tvpal_io_submits(s->io);
}

uint64_t tvpal_stream_incore_bytes(const struct tvpal_stream *s)
{
    return s->incore_bytes;
}
