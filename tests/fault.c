/* fault.c: a shared object for LD_PRELOAD that makes one kind of system
 * call fail, so that a test can reach an error path that a healthy
 * machine never takes: the failures an encoder meets after it has
 * written (a dataset that does not read back, a rename that fails).
 *
 *   TVPAL_FAULT=open:SUFFIX     open()/open64() of a path ending in SUFFIX
 *                               for reading fails with EIO
 *   TVPAL_FAULT=rename:SUFFIX   rename() whose source ends in SUFFIX fails
 *                               with EXDEV
 *   TVPAL_FAULT=shrink:SUFFIX   the first pread()/pread64() of a file
 *   TVPAL_SHRINK_AT=BYTES       ending in SUFFIX that reaches past BYTES
 *                               first truncates the file to BYTES: a file
 *                               that shrinks while it is read (rewritten
 *                               by a simulation, a copy in progress)
 *
 * Every other call goes through to the C library untouched.  Built by
 * `make check` as tests/fault.so (tests/hostile-files.sh). */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stdatomic.h>
#include <stdint.h>
#include <sys/types.h>
#include <unistd.h>

/* Whether TVPAL_FAULT names kind and s ends with its suffix. */
static int hit(const char *kind, const char *s)
{
    const char *f = getenv("TVPAL_FAULT");
    size_t k = strlen(kind);
    if (!f || !s || strncmp(f, kind, k) || f[k] != ':')
        return 0;
    const char *suf = f + k + 1;
    size_t n = strlen(s), m = strlen(suf);
    return m > 0 && n >= m && !strcmp(s + n - m, suf);
}

static int open_as(const char *name, const char *path, int flags,
                   va_list ap)
{
    mode_t mode = (flags & (O_CREAT | O_TMPFILE)) ? va_arg(ap, mode_t) : 0;
    if ((flags & O_ACCMODE) == O_RDONLY && hit("open", path)) {
        errno = EIO;
        return -1;
    }
    int (*real)(const char *, int, ...) =
        (int (*)(const char *, int, ...))dlsym(RTLD_NEXT, name);
    return real(path, flags, mode);
}

int open(const char *path, int flags, ...)
{
    va_list ap;
    va_start(ap, flags);
    int fd = open_as("open", path, flags, ap);
    va_end(ap);
    return fd;
}

int open64(const char *path, int flags, ...)
{
    va_list ap;
    va_start(ap, flags);
    int fd = open_as("open64", path, flags, ap);
    va_end(ap);
    return fd;
}

int rename(const char *from, const char *to)
{
    if (hit("rename", from)) {
        errno = EXDEV;
        return -1;
    }
    int (*real)(const char *, const char *) =
        (int (*)(const char *, const char *))dlsym(RTLD_NEXT, "rename");
    return real(from, to);
}

static atomic_int shrunk;

/* shrink: truncates fd's file when this read reaches past the size. */
static void maybe_shrink(int fd, size_t n, off_t off)
{
    const char *at = getenv("TVPAL_SHRINK_AT");
    if (!at || atomic_load(&shrunk))
        return;
    char link[64], path[4096];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t k = readlink(link, path, sizeof path - 1);
    if (k <= 0)
        return;
    path[k] = 0;
    const long long to = atoll(at);
    if (!hit("shrink", path) || (long long)off + (long long)n <= to)
        return;
    if (atomic_exchange(&shrunk, 1))
        return;
    int (*real_truncate)(const char *, off_t) =
        (int (*)(const char *, off_t))dlsym(RTLD_NEXT, "truncate");
    real_truncate(path, (off_t)to);
}

ssize_t pread(int fd, void *buf, size_t n, off_t off)
{
    maybe_shrink(fd, n, off);
    ssize_t (*real)(int, void *, size_t, off_t) =
        (ssize_t (*)(int, void *, size_t, off_t))dlsym(RTLD_NEXT, "pread");
    return real(fd, buf, n, off);
}

ssize_t pread64(int fd, void *buf, size_t n, off_t off)
{
    maybe_shrink(fd, n, off);
    ssize_t (*real)(int, void *, size_t, off_t) =
        (ssize_t (*)(int, void *, size_t, off_t))dlsym(RTLD_NEXT, "pread64");
    return real(fd, buf, n, off);
}
