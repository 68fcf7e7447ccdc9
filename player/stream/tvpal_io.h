/* tvpal_io.h: asynchronous reads behind one interface, two backends:
 *   - io_uring (liburing): reads queued to the kernel, many in flight;
 *   - pread: the same calls, each read done synchronously when its
 *     completion is waited for (used where io_uring is unavailable: old
 *     kernel, seccomp, container; and selectable for comparison).
 * Only tvpal_io.c includes liburing.  Callers own the buffers; for O_DIRECT
 * files they must be aligned to TVPAL_ALIGN with aligned offsets and
 * lengths.
 */
#ifndef TVPAL_IO_H
#define TVPAL_IO_H

#include <stdint.h>

#include "tvpal_error.h"

enum tvpal_io_kind { TVPAL_IO_PREAD, TVPAL_IO_URING };

struct tvpal_io_req {
    int fd;
    uint64_t off, len;
    void *buf;
    uint64_t tag;          /* returned with the completion */
};

struct tvpal_io;

/* depth: most reads in flight.  TVPAL_E_SYS when io_uring cannot be set up
 * (diag says why); the caller may fall back to TVPAL_IO_PREAD. */
int tvpal_io_create(struct tvpal_io **out, enum tvpal_io_kind kind,
                    unsigned depth, struct tvpal_diag *diag);
void tvpal_io_free(struct tvpal_io *io);   /* NULL is a no-op */
const char *tvpal_io_name(const struct tvpal_io *io);
unsigned tvpal_io_inflight(const struct tvpal_io *io);
unsigned tvpal_io_depth(const struct tvpal_io *io);

/* Queues a read.  TVPAL_E_INVAL when depth reads are in flight.  With
 * io_uring the queued reads go to the kernel together, in one system
 * call, at tvpal_io_flush or at the next tvpal_io_wait. */
int tvpal_io_submit(struct tvpal_io *io, const struct tvpal_io_req *r,
                    struct tvpal_diag *diag);

/* Submits the queued reads now (io_uring: one io_uring_submit; pread:
 * nothing).  0 or TVPAL_E_READ when the kernel refuses the submission
 * (diag: the call and its errno text). */
int tvpal_io_flush(struct tvpal_io *io, struct tvpal_diag *diag);

/* Submission system calls made so far (io_uring; 0 for pread). */
uint64_t tvpal_io_submits(const struct tvpal_io *io);

/* Waits for one completion: *tag of its request, *result the bytes read or
 * -errno of that read.  TVPAL_E_INVAL when nothing is in flight;
 * TVPAL_E_READ when waiting itself fails (diag: the call and its errno
 * text). */
int tvpal_io_wait(struct tvpal_io *io, uint64_t *tag, int64_t *result,
                  struct tvpal_diag *diag);

/* What the disk gave these reads: the bytes of the reads completed so
 * far and the seconds during which at least one read was with the kernel
 * (io_uring: from the submission that found none there to the
 * completion that left none; pread: inside pread), so that bytes over
 * seconds is the rate the device served them at, whatever the caller did
 * between its reads (the rate from a step's own reads and the time to
 * prepare it counts that work too).  A completion taken late by a busy
 * caller counts the wait as busy: the rate errs low, never high.  Safe to
 * call from another thread than the one reading (a snapshot; the two
 * figures may be one completion apart). */
void tvpal_io_busy(const struct tvpal_io *io, uint64_t *bytes,
                   double *seconds);

/* tvpal_io_wait for at most ms milliseconds (ms < 0: as long as it
 * takes): 1 when no read completed by then (io_uring; a pread backend's
 * read is done in the call, so it never times out), else as
 * tvpal_io_wait.  For a waiter that must notice, within ms, that it is
 * to stop (a slow disk can take a throttle slice, 100 ms or more, to
 * complete the next read). */
int tvpal_io_wait_timed(struct tvpal_io *io, double ms, uint64_t *tag,
                        int64_t *result, struct tvpal_diag *diag);

/* io_uring fixed buffers: a table of n entries, empty at first
 * (tvpal_io_register), each filled once with tvpal_io_register_buffer.
 * The kernel faults a buffer's pages in and pins them when it is filled,
 * instead of for every read into it: for O_DIRECT reads that per-read
 * work (page faults, zeroing, pinning) was most of the reading thread's
 * kernel time.  A read whose whole range lies in a filled entry uses it
 * (IORING_OP_READ_FIXED); other reads are as before.  Filling an entry
 * when its buffer is first used, not all at once, keeps the cost where
 * the memory is first needed: measured, 13 buffers of 269 MB (1024^3,
 * N = 4) filled at once took 4.7 s in 4 KiB pages.
 * register: at most once per io, before any read is queued.  0, or
 * TVPAL_E_SYS with diag saying why (the pread backend; a kernel without
 * sparse tables, before 5.19): reads then work unregistered.
 * register_buffer: entry i (< n) not yet filled; the buffer must outlive
 * the io.  0, or TVPAL_E_SYS with diag saying why (RLIMIT_MEMLOCK without
 * CAP_IPC_LOCK, a buffer over 1 GiB): reads into it work unregistered. */
int tvpal_io_register(struct tvpal_io *io, unsigned n,
                      struct tvpal_diag *diag);
int tvpal_io_register_buffer(struct tvpal_io *io, unsigned i, void *buf,
                             uint64_t len, struct tvpal_diag *diag);

/* Entries of the table (0: none) and how many are filled. */
unsigned tvpal_io_table(const struct tvpal_io *io);
unsigned tvpal_io_registered(const struct tvpal_io *io);

/* Reads queued into registered buffers so far (a test asserts that the
 * fixed path is really taken). */
uint64_t tvpal_io_fixed_reads(const struct tvpal_io *io);

/* Test hook: with TVPAL_IO_FAULT_OFFSET=N in the environment (read once,
 * at the first tvpal_io_create), every read through either backend that
 * covers byte N of its file completes with -EIO, as on a failing disk; the
 * kernel offers no portable way to make a file's reads fail.  Unset: no
 * effect. */

#endif
