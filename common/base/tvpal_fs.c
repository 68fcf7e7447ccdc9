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
    int rc = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        char *sub;
        if (asprintf(&sub, "%s/%s", path, e->d_name) < 0) {
            rc = TVPAL_E_NOMEM;
            break;
        }
        rc = tvpal_rmtree(sub);
        free(sub);
        if (rc < 0)
            break;
    }
    closedir(d);
    if (rc == 0 && rmdir(path) < 0)
        rc = TVPAL_E_SYS;
    return rc;
}

int tvpal_write_file_atomic(const char *path, const void *data, size_t len,
                            struct tvpal_diag *diag)
{
    char *tmp;
    if (asprintf(&tmp, "%s.tmp", path) < 0)
        return TVPAL_E_NOMEM;
    int rc = 0;
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) {
        rc = tvpal_diag_set(diag, TVPAL_E_OPEN, "create %s: %s", tmp,
                            strerror(errno));
        free(tmp);
        return rc;
    }
    /* Each failure names the step and errno's text at once: the next
     * system call (close, unlink) may change errno. */
    const char *p = data;
    while (len) {
        ssize_t k = write(fd, p, len);
        if (k < 0) {
            if (errno == EINTR)
                continue;
            rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "write %s: %s", tmp,
                                strerror(errno));
            break;
        }
        p += k;
        len -= (size_t)k;
    }
    if (rc == 0 && fsync(fd) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "fsync %s: %s", tmp,
                            strerror(errno));
    if (close(fd) < 0 && rc == 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "close %s: %s", tmp,
                            strerror(errno));
    if (rc == 0 && rename(tmp, path) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "rename %s: %s", tmp,
                            strerror(errno));
    if (rc < 0)
        unlink(tmp);
    free(tmp);
    return rc;
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
