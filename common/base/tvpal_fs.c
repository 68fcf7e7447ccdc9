/* tvpal_fs.c: file-system helpers (see tvpal_fs.h). */
#define _GNU_SOURCE
#include "tvpal_fs.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

int tvpal_mkdirs(const char *path, struct tvpal_diag *diag)
{
    if (!path[0])
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "empty path");
    char *p = strdup(path);
    if (!p)
        return TVPAL_E_NOMEM;
    int rc = 0;
    for (char *s = p + 1;; s++) {
        if (*s == '/' || *s == 0) {
            char c = *s;
            *s = 0;
            if (mkdir(p, 0755) < 0 && errno != EEXIST) {
                rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "mkdir %s: %s", p,
                                    strerror(errno));
                break;
            }
            *s = c;
            if (!c)
                break;
        }
    }
    free(p);
    return rc;
}

/* Calls fn(PATH/NAME, ctx) for every entry of the open directory d but .
 * and .., until fn returns an error; closes d.  0 or the first error. */
static int each_entry(DIR *d, const char *path,
                      int (*fn)(const char *sub, void *ctx), void *ctx)
{
    int rc = 0;
    struct dirent *e;
    while (rc == 0 && (e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        char *sub;
        if (asprintf(&sub, "%s/%s", path, e->d_name) < 0) {
            rc = TVPAL_E_NOMEM;
            break;
        }
        rc = fn(sub, ctx);
        free(sub);
    }
    closedir(d);
    return rc;
}

static int rmtree_entry(const char *sub, void *ctx)
{
    (void)ctx;
    return tvpal_rmtree(sub);
}

int tvpal_rmtree(const char *path)
{
    struct stat st;
    if (lstat(path, &st) < 0)
        return errno == ENOENT ? 0 : TVPAL_E_SYS;
    if (!S_ISDIR(st.st_mode))
        return unlink(path) < 0 ? TVPAL_E_SYS : 0;
    DIR *d = opendir(path);
    if (!d)
        return TVPAL_E_SYS;
    int rc = each_entry(d, path, rmtree_entry, NULL);
    if (rc == 0 && rmdir(path) < 0)
        rc = TVPAL_E_SYS;
    return rc;
}

/* tvpal_tree_bytes below depth levels of directories. */
struct tree_sum {
    unsigned depth;
    uint64_t sum;
    struct tvpal_diag *diag;
};

static int tree_bytes(const char *path, struct tree_sum *t);

static int tree_entry(const char *sub, void *ctx)
{
    struct tree_sum *t = ctx;
    t->depth++;
    int rc = tree_bytes(sub, t);
    t->depth--;
    return rc;
}

static int tree_bytes(const char *path, struct tree_sum *t)
{
    struct stat st;
    if (stat(path, &st) < 0)
        return tvpal_diag_set(t->diag, TVPAL_E_OPEN, "%s: %s", path,
                              strerror(errno));
    if (S_ISREG(st.st_mode)) {
        t->sum += (uint64_t)st.st_size;
        return 0;
    }
    if (!S_ISDIR(st.st_mode))
        return 0;
    if (t->depth >= 16)
        return tvpal_diag_set(t->diag, TVPAL_E_OPEN, "%s: more than 16 "
                              "directories deep", path);
    DIR *d = opendir(path);
    if (!d)
        return tvpal_diag_set(t->diag, TVPAL_E_OPEN, "%s: %s", path,
                              strerror(errno));
    return each_entry(d, path, tree_entry, t);
}

int tvpal_tree_bytes(const char *path, uint64_t *bytes,
                     struct tvpal_diag *diag)
{
    struct tree_sum t = {0, 0, diag};
    int rc = tree_bytes(path, &t);
    if (rc == 0)
        *bytes = t.sum;
    return rc;
}

/* The target may be absent or a regular file (lstat: a link is not). */
int tvpal_out_check(const char *path, struct tvpal_diag *diag)
{
    struct stat st;
    if (lstat(path, &st) < 0)
        return errno == ENOENT ? 0
               : tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s", path,
                                strerror(errno));
    if (S_ISREG(st.st_mode))
        return 0;
    return tvpal_diag_set(diag, TVPAL_E_EXIST, "%s: exists and is not a "
                          "regular file (%s); not replaced", path,
                          S_ISLNK(st.st_mode) ? "a symbolic link"
                          : S_ISDIR(st.st_mode) ? "a directory"
                          : S_ISFIFO(st.st_mode) ? "a FIFO"
                          : S_ISCHR(st.st_mode) ? "a character device"
                          : S_ISBLK(st.st_mode) ? "a block device"
                          : "a special file");
}

int tvpal_out_open(struct tvpal_out *o, const char *path,
                   struct tvpal_diag *diag)
{
    *o = (struct tvpal_out){.fd = -1};
    int rc = tvpal_out_check(path, diag);
    if (rc < 0)
        return rc;
    if (!(o->path = strdup(path)) ||
        asprintf(&o->tmp, "%s.XXXXXX", path) < 0) {
        free(o->path);
        *o = (struct tvpal_out){.fd = -1};
        return TVPAL_E_NOMEM;
    }
    if ((o->fd = mkostemp(o->tmp, O_CLOEXEC)) < 0) {
        rc = tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: cannot create: %s", path,
                            strerror(errno));
        free(o->tmp);
        free(o->path);
        *o = (struct tvpal_out){.fd = -1};
        return rc;
    }
    fchmod(o->fd, 0644); /* mkstemp makes 0600; outputs are for sharing */
    return 0;
}

FILE *tvpal_out_stream(struct tvpal_out *o)
{
    if (!o->stream && o->fd >= 0)
        o->stream = fdopen(o->fd, "wb");
    return o->stream;
}

int tvpal_out_write(struct tvpal_out *o, const void *data, size_t n,
                    struct tvpal_diag *diag)
{
    const char *p = data;
    while (n) {
        ssize_t k = write(o->fd, p, n);
        if (k < 0) {
            if (errno == EINTR)
                continue;
            return tvpal_diag_set(diag, TVPAL_E_WRITE, "write %s: %s",
                                  o->path, strerror(errno));
        }
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

static void out_clear(struct tvpal_out *o)
{
    free(o->tmp);
    free(o->path);
    *o = (struct tvpal_out){.fd = -1};
}

void tvpal_out_abort(struct tvpal_out *o)
{
    if (o->stream)
        fclose(o->stream);
    else if (o->fd >= 0)
        close(o->fd);
    if (o->tmp)
        unlink(o->tmp);
    out_clear(o);
}

int tvpal_out_commit(struct tvpal_out *o, struct tvpal_diag *diag)
{
    /* Each failure names the step and errno's text at once: the next
     * system call (close, unlink) may change errno. */
    int rc = 0;
    if (o->stream && fflush(o->stream) != 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "write %s: %s", o->path,
                            strerror(errno));
    if (rc == 0 && fsync(o->fd) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "fsync %s: %s", o->path,
                            strerror(errno));
    int closed = o->stream ? fclose(o->stream) : close(o->fd);
    o->stream = NULL;
    o->fd = -1;
    if (closed != 0 && rc == 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "close %s: %s", o->path,
                            strerror(errno));
    /* Checked again: something may have been put there meanwhile. */
    if (rc == 0)
        rc = tvpal_out_check(o->path, diag);
    if (rc == 0 && rename(o->tmp, o->path) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "rename to %s: %s", o->path,
                            strerror(errno));
    if (rc < 0)
        unlink(o->tmp);
    out_clear(o);
    return rc;
}

FILE *tvpal_open_log(const char *path, int *rc, struct tvpal_diag *diag)
{
    *rc = tvpal_out_check(path, diag);
    if (*rc < 0)
        return NULL;
    int fd = open(path, O_WRONLY | O_CREAT | O_NOFOLLOW | O_NONBLOCK |
                            O_CLOEXEC, 0644);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) < 0 || !S_ISREG(st.st_mode) ||
        ftruncate(fd, 0) < 0) {
        *rc = tvpal_diag_set(diag, fd < 0 ? TVPAL_E_OPEN : TVPAL_E_EXIST,
                             "%s: %s", path, fd < 0 ? strerror(errno)
                             : "not a regular file; not written");
        if (fd >= 0)
            close(fd);
        return NULL;
    }
    int fl = fcntl(fd, F_GETFL);
    if (fl >= 0)
        fcntl(fd, F_SETFL, fl & ~O_NONBLOCK);
    FILE *f = fdopen(fd, "w");
    if (!f) {
        *rc = tvpal_diag_set(diag, TVPAL_E_NOMEM, "%s: %s", path,
                             strerror(errno));
        close(fd);
    }
    return f;
}

int tvpal_path_inside(const char *path, const char *dir)
{
    char *copy = strdup(path);
    if (!copy)
        return 0;
    char *slash = strrchr(copy, '/');
    const char *pdir = slash ? (slash == copy ? "/" : (*slash = 0, copy)) : ".";
    char *rp = realpath(pdir, NULL), *rd = realpath(dir, NULL);
    int inside = 0;
    if (rp && rd) {
        size_t n = strlen(rd);
        inside = !strncmp(rp, rd, n) &&
                 (rp[n] == 0 || rp[n] == '/' || (n == 1 && rd[0] == '/'));
    }
    free(rp);
    free(rd);
    free(copy);
    return inside;
}

int tvpal_write_file_atomic(const char *path, const void *data, size_t len,
                            struct tvpal_diag *diag)
{
    struct tvpal_out o;
    int rc = tvpal_out_open(&o, path, diag);
    if (rc < 0)
        return rc;
    if ((rc = tvpal_out_write(&o, data, len, diag)) < 0) {
        tvpal_out_abort(&o);
        return rc;
    }
    return tvpal_out_commit(&o, diag);
}

int tvpal_open_regular(const char *path, struct tvpal_diag *diag)
{
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s", path,
                              strerror(errno));
    struct stat st;
    if (fstat(fd, &st) < 0 || !S_ISREG(st.st_mode)) {
        const char *what = S_ISFIFO(st.st_mode) ? " (a FIFO)"
                           : S_ISCHR(st.st_mode) ? " (a character device)"
                           : S_ISBLK(st.st_mode) ? " (a block device)"
                           : S_ISDIR(st.st_mode) ? " (a directory)"
                           : S_ISSOCK(st.st_mode) ? " (a socket)" : "";
        close(fd);
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: not a regular file%s",
                              path, what);
    }
    int fl = fcntl(fd, F_GETFL);
    if (fl >= 0)
        fcntl(fd, F_SETFL, fl & ~O_NONBLOCK);
    return fd;
}

/* A regular file of at most TVPAL_TEXT_MAX bytes, open; else < 0. */
static int open_text(const char *path, struct tvpal_diag *diag)
{
    int fd = tvpal_open_regular(path, diag);
    struct stat st;
    if (fd >= 0 && fstat(fd, &st) == 0 && (uint64_t)st.st_size > TVPAL_TEXT_MAX) {
        close(fd);
        return tvpal_diag_set(diag, TVPAL_E_RANGE, "%s: %llu bytes; a text "
                              "input is at most %zu MiB", path,
                              (unsigned long long)st.st_size,
                              TVPAL_TEXT_MAX >> 20);
    }
    return fd;
}

FILE *tvpal_fopen_text(const char *path, int *rc, struct tvpal_diag *diag)
{
    int fd = open_text(path, diag);
    FILE *f = fd >= 0 ? fdopen(fd, "r") : NULL;
    if (fd >= 0 && !f) {
        close(fd);
        fd = tvpal_diag_set(diag, TVPAL_E_NOMEM, "%s: %s", path,
                            strerror(errno));
    }
    *rc = f ? 0 : fd;
    return f;
}

int tvpal_read_file(const char *path, char **out, size_t *len,
                    struct tvpal_diag *diag)
{
    int rc = 0;
    FILE *f = tvpal_fopen_text(path, &rc, diag);
    if (!f)
        return rc;
    char *buf = NULL;
    size_t n = 0, cap = 0;
    for (;;) {
        if (cap - n < 4096) {
            cap = cap ? cap * 2 : 8192;
            char *nb = realloc(buf, cap);
            if (!nb) {
                rc = TVPAL_E_NOMEM;
                break;
            }
            buf = nb;
        }
        size_t k = fread(buf + n, 1, cap - n - 1, f);
        n += k;
        if (n > TVPAL_TEXT_MAX) { /* grew since the check */
            rc = tvpal_diag_set(diag, TVPAL_E_RANGE, "%s: more than %zu MiB",
                                path, TVPAL_TEXT_MAX >> 20);
            break;
        }
        if (k == 0) {
            if (ferror(f))
                rc = tvpal_diag_set(diag, TVPAL_E_READ, "%s: %s", path,
                                    strerror(errno));
            break;
        }
    }
    fclose(f);
    if (rc < 0) {
        free(buf);
        return rc;
    }
    buf[n] = 0;
    *out = buf;
    if (len)
        *len = n;
    return 0;
}

int tvpal_fsync_dir(const char *path)
{
    int fd = open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return TVPAL_E_OPEN;
    int rc = fsync(fd) < 0 ? TVPAL_E_WRITE : 0;
    close(fd);
    return rc;
}

int tvpal_exists(const char *path)
{
    struct stat st;
    return lstat(path, &st) == 0;
}

char *tvpal_node_dir(const char *dir, const char *pattern, uint32_t r)
{
    char rs[16], *out = NULL;
    snprintf(rs, sizeof rs, "%u", r);
    if (!pattern)
        return asprintf(&out, "%s/node-%s", dir, rs) < 0 ? NULL : out;
    size_t cap = strlen(pattern) * 4 + 32, o = 0;
    if (!(out = malloc(cap)))
        return NULL;
    for (const char *q = pattern; *q && o + 16 < cap; q++) {
        if (q[0] == '%' && q[1] == 'r') {
            o += (size_t)snprintf(out + o, cap - o, "%s", rs);
            q++;
        } else {
            out[o++] = *q;
        }
    }
    out[o] = 0;
    return out;
}

/* The holder's id from the lock file, as text ("by process 123"). */
static void lock_holder(int fd, char *out, size_t cap)
{
    char b[32];
    ssize_t k = pread(fd, b, sizeof b - 1, 0);
    long pid = 0;
    if (k > 0) {
        b[k] = 0;
        pid = strtol(b, NULL, 10);
    }
    if (pid > 0)
        snprintf(out, cap, "by process %ld", pid);
    else
        snprintf(out, cap, "by another process");
}

int tvpal_lock_take(const char *path, int *fd, struct tvpal_diag *diag)
{
    *fd = -1;
    for (int tries = 0; tries < 8; tries++) {
        int f = open(path, O_RDWR | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0644);
        if (f < 0)
            return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: cannot create "
                                  "the lock: %s", path, strerror(errno));
        if (flock(f, LOCK_EX | LOCK_NB) < 0) {
            int e = errno;
            char who[48];
            lock_holder(f, who, sizeof who);
            close(f);
            if (e == EWOULDBLOCK)
                return tvpal_diag_set(diag, TVPAL_E_EXIST, "%s: held %s",
                                      path, who);
            return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: flock: %s", path,
                                  strerror(e));
        }
        /* The file locked must still be the one at path: a holder that
         * finished removed it, and a third process may have made a new
         * one meanwhile. */
        struct stat a, b;
        if (fstat(f, &a) == 0 && stat(path, &b) == 0 && a.st_dev == b.st_dev &&
            a.st_ino == b.st_ino) {
            char pid[32];
            int n = snprintf(pid, sizeof pid, "%ld\n", (long)getpid());
            if (ftruncate(f, 0) < 0 || pwrite(f, pid, (size_t)n, 0) != n) {
                /* the id is for messages only: the lock holds */
            }
            *fd = f;
            return 0;
        }
        close(f);
    }
    return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: the lock file keeps "
                          "changing", path);
}

void tvpal_lock_release(const char *path, int fd)
{
    if (fd < 0)
        return;
    unlink(path);
    close(fd);
}
