/* test-io: the read layer (tvpal_io) on a file of known bytes:
 *  - both backends read what the file holds, whole, in pieces, and short
 *    at its end;
 *  - io_uring fixed buffers (a table, tvpal_io_register, whose entries
 *    are filled one by one, tvpal_io_register_buffer): a read whose whole
 *    range lies in a filled entry takes the fixed path, counted by
 *    tvpal_io_fixed_reads, and reads the same bytes; a read into the
 *    unregistered tail of a buffer, one straddling the end of the
 *    registered part, and one into a buffer whose entry is empty take
 *    the plain path; a second table, an entry filled twice or out of
 *    range, and the pread backend are refused with TVPAL_E_SYS, and reads
 *    go on working after a refusal;
 *  - the fault hook fails a fixed read as it fails a plain one;
 *  - tvpal_io_busy counts the bytes of the reads completed and the time a
 *    read was with the kernel: on a pipe that has no data yet, a timed
 *    wait (tvpal_io_wait_timed) returns 1 without a completion, the read
 *    still counts as busy, and when data comes the read completes with
 *    it and the busy time covers the wait; the pread backend counts its
 *    reads too and never times out.
 * O_DIRECT where the file system offers it (the player's path), else the
 * page cache, said.  io_uring missing: its part skipped, said; exit 77
 * when nothing but pread could be checked.  Registration refused to a
 * user without CAP_IPC_LOCK (RLIMIT_MEMLOCK): said, its checks skipped;
 * as root it must work. */
#define _GNU_SOURCE
#include "tvpal_clock.h"
#include "tvpal_io.h"
#include "tvpal_test.h"

#include <errno.h>
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#define MIB (1u << 20)
#define FILE_BYTES (4 * MIB)

static unsigned char expect_byte(uint64_t i)
{
    return (unsigned char)(i * 7 + (i >> 12) * 13 + 1);
}

/* Reads [off, off + len) of fd into buf through io, waits for it; the
 * bytes it got (or -errno).  *fixed: whether the read took the fixed
 * path. */
static int64_t read_one(struct tvpal_io *io, int fd, uint64_t off,
                        uint64_t len, void *buf, int *fixed)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_io_req r = {.fd = fd, .off = off, .len = len, .buf = buf,
                             .tag = 42};
    uint64_t before = tvpal_io_fixed_reads(io), tag = 0;
    int64_t res = 0;
    REQUIRE(tvpal_io_submit(io, &r, &d) == 0, "submit: %s", d.msg);
    REQUIRE(tvpal_io_wait(io, &tag, &res, &d) == 0, "wait: %s", d.msg);
    CHECK(tag == 42, "tag %llu", (unsigned long long)tag);
    if (fixed)
        *fixed = tvpal_io_fixed_reads(io) > before;
    return res;
}

/* Whether buf holds the file's bytes [off, off + len). */
static int holds(const unsigned char *buf, uint64_t off, uint64_t len)
{
    for (uint64_t i = 0; i < len; i++)
        if (buf[i] != expect_byte(off + i))
            return 0;
    return 1;
}

static void *aligned_buf(size_t bytes)
{
    void *p = NULL;
    REQUIRE(posix_memalign(&p, 4096, bytes) == 0, "out of memory");
    memset(p, 0xEE, bytes);
    return p;
}

static void check_pread(int fd, unsigned char *buf)
{
    struct tvpal_io *io;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_io_create(&io, TVPAL_IO_PREAD, 4, &d) == 0, "%s", d.msg);
    CHECK(tvpal_io_register(io, 1, &d) == TVPAL_E_SYS,
          "pread registered a table");
    CHECK(tvpal_io_register_buffer(io, 0, buf, MIB, &d) == TVPAL_E_SYS,
          "pread registered a buffer");
    CHECK(tvpal_io_registered(io) == 0, "pread: %u registered",
          tvpal_io_registered(io));
    int fixed = -1;
    CHECK(read_one(io, fd, MIB, MIB, buf, &fixed) == MIB, "pread: 1 MiB");
    CHECK(holds(buf, MIB, MIB) && !fixed, "pread: bytes or path wrong");
    CHECK(read_one(io, fd, FILE_BYTES - MIB, 2 * MIB, buf, NULL) == MIB,
          "pread: short read at the end");
    tvpal_io_free(io);
}

/* io_uring with two registered buffers: a, of which the first MiB is
 * registered (2 MiB long), and b (2 MiB, all registered); c is not. */
static int check_fixed(int fd, unsigned char *a, unsigned char *b,
                       unsigned char *c)
{
    struct tvpal_io *io;
    struct tvpal_diag d = {{0}};
    if (tvpal_io_create(&io, TVPAL_IO_URING, 8, &d) < 0) {
        printf("test-io: io_uring unavailable here (%s): its checks skipped\n",
               d.msg);
        return 0;
    }
    int rc = tvpal_io_register(io, 3, &d), table = rc == 0;
    CHECK(tvpal_io_table(io) == (table ? 3u : 0u) && tvpal_io_registered(io) == 0,
          "table %u, %u filled", tvpal_io_table(io), tvpal_io_registered(io));
    /* Entry 2 stays empty: reads into c never use it. */
    if (rc == 0)
        rc = tvpal_io_register_buffer(io, 0, a, MIB, &d);
    if (rc == 0)
        rc = tvpal_io_register_buffer(io, 1, b, 2 * MIB, &d);
    if (rc < 0 && (!table || geteuid() != 0)) {
        /* A kernel before 5.19 (no sparse tables), or a user whose
         * RLIMIT_MEMLOCK is too low. */
        printf("test-io: fixed buffers refused (%s): their checks skipped\n",
               d.msg);
        CHECK(rc == TVPAL_E_SYS, "refusal code %d", rc);
        int fixed = -1;
        CHECK(read_one(io, fd, 0, 2 * MIB, b, &fixed) == 2 * MIB &&
              holds(b, 0, 2 * MIB) && !fixed, "a read after the refusal");
        tvpal_io_free(io);
        return 1;
    }
    CHECK(rc == 0, "register: %s", d.msg);
    CHECK(tvpal_io_registered(io) == 2, "%u registered",
          tvpal_io_registered(io));
    CHECK(tvpal_io_register(io, 2, &d) == TVPAL_E_SYS,
          "a second table accepted");
    CHECK(tvpal_io_register_buffer(io, 0, b, MIB, &d) == TVPAL_E_SYS,
          "entry 0 filled twice");
    CHECK(tvpal_io_register_buffer(io, 3, c, MIB, &d) == TVPAL_E_SYS,
          "entry 3 of 3 filled");
    CHECK(tvpal_io_registered(io) == 2 && tvpal_io_table(io) == 3,
          "refusals changed the table");

    int fixed = -1;
    CHECK(read_one(io, fd, 0, MIB, a, &fixed) == MIB, "into a");
    CHECK(holds(a, 0, MIB), "a: wrong bytes");
    CHECK(fixed == 1, "a's registered part: not the fixed path");

    CHECK(read_one(io, fd, MIB, MIB, a + MIB, &fixed) == MIB, "a's tail");
    CHECK(holds(a + MIB, MIB, MIB), "a's tail: wrong bytes");
    CHECK(fixed == 0, "a's unregistered tail took the fixed path");

    CHECK(read_one(io, fd, 2 * MIB, MIB, a + MIB / 2, &fixed) == MIB,
          "straddling");
    CHECK(holds(a + MIB / 2, 2 * MIB, MIB), "straddling: wrong bytes");
    CHECK(fixed == 0, "a read over the registered end took the fixed path");

    CHECK(read_one(io, fd, MIB, 2 * MIB, b, &fixed) == 2 * MIB, "into b");
    CHECK(holds(b, MIB, 2 * MIB), "b: wrong bytes");
    CHECK(fixed == 1, "b: not the fixed path");

    /* At the end of the file: short, on the fixed path. */
    CHECK(read_one(io, fd, FILE_BYTES - MIB, 2 * MIB, b, &fixed) == MIB,
          "short read at the end");
    CHECK(holds(b, FILE_BYTES - MIB, MIB) && fixed == 1,
          "short fixed read: bytes or path wrong");

    CHECK(read_one(io, fd, 3 * MIB, 4096, c, &fixed) == 4096, "into c");
    CHECK(holds(c, 3 * MIB, 4096) && fixed == 0,
          "unregistered c: bytes or path wrong");
    tvpal_io_free(io);
    return 1;
}

/* The fault hook (TVPAL_IO_FAULT_OFFSET, read at the first create) fails
 * a fixed read that covers the offset, and only that one. */
static void check_fault(int fd, unsigned char *b)
{
    struct tvpal_io *io;
    struct tvpal_diag d = {{0}};
    if (tvpal_io_create(&io, TVPAL_IO_URING, 8, &d) < 0)
        return;
    if (tvpal_io_register(io, 1, &d) == 0 &&
        tvpal_io_register_buffer(io, 0, b, 2 * MIB, &d) == 0) {
        int fixed = -1;
        CHECK(read_one(io, fd, 2 * MIB, MIB, b, &fixed) == -EIO && fixed == 1,
              "a fixed read over the fault offset did not fail");
        CHECK(read_one(io, fd, 0, MIB, b, &fixed) == MIB && fixed == 1,
              "a fixed read away from the fault offset failed");
    }
    tvpal_io_free(io);
}

/* tvpal_io_busy and tvpal_io_wait_timed on backend kind: two reads of the
 * file, then (io_uring) a read of an empty pipe, timed out, then fed. */
static void check_busy(enum tvpal_io_kind kind, int fd, unsigned char *buf)
{
    struct tvpal_io *io;
    struct tvpal_diag d = {{0}};
    if (tvpal_io_create(&io, kind, 4, &d) < 0)
        return; /* io_uring unavailable: said by check_fixed */
    const char *name = tvpal_io_name(io);
    uint64_t bytes = 1;
    double sec = 1;
    tvpal_io_busy(io, &bytes, &sec);
    CHECK(bytes == 0 && sec == 0, "%s: busy %llu bytes %.6f s before a read",
          name, (unsigned long long)bytes, sec);
    CHECK(read_one(io, fd, 0, MIB, buf, NULL) == MIB &&
          read_one(io, fd, 3 * MIB, 2 * MIB, buf, NULL) == MIB,
          "%s: reads", name);
    tvpal_io_busy(io, &bytes, &sec);
    CHECK(bytes == 2 * MIB && sec > 0, "%s: busy %llu bytes in %.6f s after "
          "reading 2 MiB", name, (unsigned long long)bytes, sec);
    if (kind == TVPAL_IO_PREAD) {
        uint64_t tag = 0;
        int64_t res = 0;
        struct tvpal_io_req r = {.fd = fd, .off = 0, .len = 4096, .buf = buf,
                                 .tag = 7};
        REQUIRE(tvpal_io_submit(io, &r, &d) == 0, "submit: %s", d.msg);
        CHECK(tvpal_io_wait_timed(io, 0, &tag, &res, &d) == 0 && tag == 7 &&
              res == 4096, "pread: a timed wait did not read");
        tvpal_io_free(io);
        return;
    }
    int pfd[2];
    REQUIRE(pipe(pfd) == 0, "pipe: %s", strerror(errno));
    unsigned char msg[100], got[100] = {0};
    for (unsigned i = 0; i < sizeof msg; i++)
        msg[i] = (unsigned char)(i * 3 + 1);
    struct tvpal_io_req r = {.fd = pfd[0], .off = 0, .len = sizeof got,
                             .buf = got, .tag = 9};
    uint64_t tag = 0;
    int64_t res = 0;
    double before = 0;
    tvpal_io_busy(io, &bytes, &before);
    REQUIRE(tvpal_io_submit(io, &r, &d) == 0, "submit: %s", d.msg);
    const double t0 = tvpal_now();
    CHECK(tvpal_io_wait_timed(io, 20, &tag, &res, &d) == 1,
          "uring: a read of an empty pipe completed");
    const double waited = tvpal_now() - t0;
    CHECK(waited >= 0.019, "uring: the timed wait returned after %.4f s",
          waited);
    CHECK(tvpal_io_inflight(io) == 1, "uring: %u in flight after the "
          "timeout", tvpal_io_inflight(io));
    REQUIRE(write(pfd[1], msg, sizeof msg) == (ssize_t)sizeof msg, "write");
    CHECK(tvpal_io_wait_timed(io, 5000, &tag, &res, &d) == 0 && tag == 9 &&
          res == (int64_t)sizeof msg && !memcmp(got, msg, sizeof msg),
          "uring: the pipe's read after the write: %lld", (long long)res);
    tvpal_io_busy(io, &bytes, &sec);
    CHECK(bytes == 2 * MIB + sizeof msg, "uring: busy %llu bytes",
          (unsigned long long)bytes);
    CHECK(sec - before >= 0.019, "uring: busy %.4f s over a read that took "
          "more than 20 ms", sec - before);
    close(pfd[0]);
    close(pfd[1]);
    tvpal_io_free(io);
}

/* Opens path for the checks: O_DIRECT where offered. */
static int open_file(const char *path, int say)
{
    int fd = open(path, O_RDONLY | O_DIRECT);
    if (fd < 0 && errno == EINVAL) {
        if (say)
            printf("test-io: the file system of %s refuses O_DIRECT: "
                   "reading through the page cache\n", path);
        fd = open(path, O_RDONLY);
    }
    REQUIRE(fd >= 0, "open %s: %s", path, strerror(errno));
    return fd;
}

int main(int argc, char **argv)
{
    if (argc == 3 && !strcmp(argv[1], "--fault")) {
        /* The child of the fault check, its environment set. */
        unsigned char *b = aligned_buf(2 * MIB);
        int fd = open_file(argv[2], 0);
        check_fault(fd, b);
        close(fd);
        free(b);
        return tt_failures ? 1 : 0;
    }
    const char *dir = getenv("TMPDIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/test-io.XXXXXX",
             dir && *dir ? dir : "/tmp");
    int wfd = mkstemp(path);
    REQUIRE(wfd >= 0, "mkstemp %s: %s", path, strerror(errno));
    unsigned char *all = aligned_buf(FILE_BYTES);
    for (uint64_t i = 0; i < FILE_BYTES; i++)
        all[i] = expect_byte(i);
    REQUIRE(write(wfd, all, FILE_BYTES) == (ssize_t)FILE_BYTES, "write %s",
            path);
    close(wfd);
    free(all);

    int fd = open_file(path, 1);
    unsigned char *a = aligned_buf(2 * MIB), *b = aligned_buf(2 * MIB),
                  *c = aligned_buf(2 * MIB);
    check_pread(fd, a);
    int uring = check_fixed(fd, a, b, c);
    check_busy(TVPAL_IO_PREAD, fd, a);
    check_busy(TVPAL_IO_URING, fd, a);
    close(fd);
    free(a);
    free(b);
    free(c);

    /* The hook is read once per process, at its first create: checked in
     * a fresh one. */
    if (uring) {
        fflush(stdout);
        pid_t pid = fork();
        REQUIRE(pid >= 0, "fork");
        if (pid == 0) {
            char off[32];
            snprintf(off, sizeof off, "%u", 2 * MIB + 4096);
            setenv("TVPAL_IO_FAULT_OFFSET", off, 1);
            execl("/proc/self/exe", argv[0], "--fault", path, (char *)NULL);
            _exit(99);
        }
        int status = 0;
        REQUIRE(waitpid(pid, &status, 0) == pid, "waitpid");
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0,
              "fault hook on fixed reads (status %d)", status);
    }
    unlink(path);
    int rc = tt_done("test-io");
    return rc ? rc : uring ? 0 : 77;
}
