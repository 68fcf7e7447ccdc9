/* tvpal_checkpoint.c: the encoder's resume record (see tvpal_checkpoint.h;
 * the text layout is common/format/FORMAT.md 9.2). */
#define _GNU_SOURCE
#include "tvpal_checkpoint.h"
#include "tvpal_crc32c.h"
#include "tvpal_fs.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int tvpal_checkpoint_stats_init(struct tvpal_checkpoint_stats *st)
{
    st->fine = calloc(TVPAL_CHECKPOINT_BINS, sizeof *st->fine);
    if (!st->fine)
        return TVPAL_E_NOMEM;
    tvpal_checkpoint_stats_reset(st);
    return 0;
}

void tvpal_checkpoint_stats_reset(struct tvpal_checkpoint_stats *st)
{
    st->vmin = INFINITY;
    st->vmax = -INFINITY;
    st->nonfinite = 0;
    st->missing = 0;
    st->loaded = 0;
    st->counted = 0;
    if (st->fine)
        memset(st->fine, 0, TVPAL_CHECKPOINT_BINS * sizeof *st->fine);
}

void tvpal_checkpoint_stats_free(struct tvpal_checkpoint_stats *st)
{
    free(st->fine);
    st->fine = NULL;
}

void tvpal_checkpoint_progress_free(struct tvpal_checkpoint_progress *pr)
{
    free(pr->filled);
    free(pr->crc);
    free(pr->missing);
    pr->filled = NULL;
    pr->crc = NULL;
    pr->missing = NULL;
}

/* The CRC-32C of the first n bytes of path (fewer where it is shorter;
 * 0 where it cannot be read). */
static uint32_t head_crc(const char *path, unsigned n)
{
    unsigned char buf[4096];
    if (n > sizeof buf)
        n = sizeof buf;
    int fd = tvpal_open_regular(path, NULL);
    if (fd < 0)
        return 0;
    ssize_t k = pread(fd, buf, n, 0);
    close(fd);
    return k > 0 ? tvpal_crc32c(0, buf, (size_t)k) : 0;
}

int tvpal_checkpoint_fingerprint(const char *params, char *const *inputs,
                                 int ninputs, unsigned head_bytes, char **out)
{
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    if (!f)
        return TVPAL_E_NOMEM;
    fputs(params, f);
    for (int i = 0; i < ninputs; i++) {
        struct stat st;
        if (stat(inputs[i], &st) < 0)
            memset(&st, 0, sizeof st);
        fprintf(f, " %s:%lld:%lld.%09ld", inputs[i], (long long)st.st_size,
                (long long)st.st_mtim.tv_sec, st.st_mtim.tv_nsec);
        if (head_bytes)
            fprintf(f, ":%08x", head_crc(inputs[i], head_bytes));
    }
    if (fclose(f) != 0) {
        free(buf);
        return TVPAL_E_NOMEM;
    }
    *out = buf;
    return 0;
}

/* The checkpoint keeps a hash of the fingerprint, not the fingerprint (which
 * names every input and would make each checkpoint O(T)): FNV-1a, 64 bits,
 * plus the length, as "%016llx-%zu" into out[40]. */
static void fp_hash(const char *fp, char out[40])
{
    uint64_t h = 0xcbf29ce484222325ull;
    size_t n = 0;
    for (const unsigned char *p = (const unsigned char *)fp; *p; p++, n++)
        h = (h ^ *p) * 0x100000001b3ull;
    snprintf(out, 40, "%016llx-%zu", (unsigned long long)h, n);
}

/* Digits of v at the end of buf (which ends at end); returns the first. */
static char *digits(char *end, uint64_t v)
{
    do
        *--end = (char)('0' + v % 10);
    while (v /= 10);
    return end;
}

/* "bin B COUNT\n": up to 65536 lines a save, after every timestep, so
 * without printf's format parsing (it was 6% of a small encode). */
static void put_bin(FILE *f, uint32_t b, uint64_t count)
{
    char line[64], *end = line + sizeof line, *p;
    *--end = '\n';
    p = digits(end, count);
    *--p = ' ';
    p = digits(p, b);
    p -= 4;
    memcpy(p, "bin ", 4);
    fwrite(p, 1, (size_t)(line + sizeof line - p), f);
}

static char *checkpoint_path(const char *dir)
{
    char *path = NULL;
    return asprintf(&path, "%s/checkpoint", dir) < 0 ? NULL : path;
}

int tvpal_checkpoint_save(const char *dir, const char *fingerprint,
                          uint64_t done,
                          const struct tvpal_checkpoint_stats *st,
                          const struct tvpal_checkpoint_progress *pr,
                          struct tvpal_diag *diag)
{
    char hash[40], *buf = NULL, *path = NULL;
    size_t len = 0;
    fp_hash(fingerprint, hash);
    FILE *f = open_memstream(&buf, &len);
    if (!f)
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "checkpoint text");
    fprintf(f, "fingerprint %s\ndone %llu\nloaded %u\ncounted %llu\n"
            "min %a\nmax %a\nnonfinite %llu\nmissing %llu\n", hash,
            (unsigned long long)done, st->loaded,
            (unsigned long long)st->counted, st->vmin, st->vmax,
            (unsigned long long)st->nonfinite,
            (unsigned long long)st->missing);
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++)
        if (st->fine[b])
            put_bin(f, b, st->fine[b]);
    for (uint32_t q = 0; pr && q < pr->nshard; q++) {
        if (pr->missing[q])
            fprintf(f, "missing-in %u\n", q);
        for (uint32_t t = 0; t < pr->steps; t++) {
            size_t i = (size_t)q * pr->steps + t;
            if (pr->filled[i])
                fprintf(f, "record %u %u %llu %08x\n", q, t,
                        (unsigned long long)pr->filled[i], pr->crc[i]);
        }
    }
    int rc = fclose(f) != 0 ? TVPAL_E_NOMEM : 0;
    if (rc == 0 && !(path = checkpoint_path(dir)))
        rc = TVPAL_E_NOMEM;
    if (rc == 0)
        rc = tvpal_write_file_atomic(path, buf, len, diag);
    else
        tvpal_diag_set(diag, rc, "checkpoint text");
    free(path);
    free(buf);
    return rc;
}

/* A whole decimal number <= max at *p (digits only: no sign, space or
 * wrap past max), *p moved past it; 0 or -1. */
static int take_u64(const char **p, uint64_t max, uint64_t *out)
{
    char *end;
    if (**p < '0' || **p > '9')
        return -1;
    errno = 0;
    unsigned long long v = strtoull(*p, &end, 10);
    if (errno || v > max)
        return -1;
    *p = end;
    *out = v;
    return 0;
}

/* "KEY N" exactly (N as take_u64 takes it, nothing after); 0 or -1. */
static int keyed_u64(const char *line, const char *key, uint64_t max,
                     uint64_t *out)
{
    size_t n = strlen(key);
    const char *p = line + n + 1;
    if (strncmp(line, key, n) || line[n] != ' ' || take_u64(&p, max, out) ||
        *p)
        return -1;
    return 0;
}

/* "KEY X" with X a double as the writer's %a writes it; 0 or -1. */
static int keyed_double(const char *line, const char *key, double *out)
{
    size_t n = strlen(key);
    char *end;
    if (strncmp(line, key, n) || line[n] != ' ' || !line[n + 1])
        return -1;
    *out = strtod(line + n + 1, &end);
    return *end ? -1 : 0;
}

/* Parses the fixed lines after the fingerprint into *done and st.  Returns
 * 0 or TVPAL_E_FORMAT naming the first bad line. */
static int parse_head(char **save, uint64_t *done,
                      struct tvpal_checkpoint_stats *st,
                      struct tvpal_diag *diag)
{
    static const char *const key[] = {"done", "loaded", "counted", "min",
                                      "max", "nonfinite", "missing"};
    static const uint64_t max[] = {UINT64_MAX, UINT32_MAX, UINT64_MAX, 0, 0,
                                   UINT64_MAX, UINT64_MAX};
    uint64_t u[7] = {0};
    double lo = 0, hi = 0;
    for (int i = 0; i < 7; i++) {
        char *line = strtok_r(NULL, "\n", save);
        int bad = !line;
        if (!bad && (i == 3 || i == 4))
            bad = keyed_double(line, key[i], i == 3 ? &lo : &hi) < 0;
        else if (!bad)
            bad = keyed_u64(line, key[i], max[i], &u[i]) < 0;
        if (bad)
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "line %d: expected "
                                  "\"%s\"", i + 2, key[i]);
    }
    *done = u[0];
    st->loaded = (uint32_t)u[1];
    st->counted = u[2];
    const uint64_t nf = u[5], miss = u[6];
    st->vmin = lo;
    st->vmax = hi;
    st->nonfinite = nf;
    st->missing = miss;
    return 0;
}

/* "record Q T FILLED CRC" into pr (bounds checked); 0 or -1. */
static int parse_record(const char *line, struct tvpal_checkpoint_progress *pr)
{
    uint64_t q, t, filled;
    const char *p = line + 7;
    char *end;
    if (take_u64(&p, UINT32_MAX, &q) < 0 || *p++ != ' ' ||
        take_u64(&p, UINT32_MAX, &t) < 0 || *p++ != ' ' ||
        take_u64(&p, UINT64_MAX, &filled) < 0 || *p++ != ' ')
        return -1;
    for (int i = 0; i < 8; i++) /* exactly 8 hex digits: no sign, no 0x */
        if (!((p[i] >= '0' && p[i] <= '9') || (p[i] >= 'a' && p[i] <= 'f')))
            return -1;
    errno = 0;
    unsigned long crc = strtoul(p, &end, 16);
    if (errno || end != p + 8 || *end || crc > UINT32_MAX || !pr ||
        q >= pr->nshard || t >= pr->steps)
        return -1;
    size_t i = (size_t)q * pr->steps + t;
    pr->filled[i] = filled;
    pr->crc[i] = (uint32_t)crc;
    return 0;
}

/* Parses the "bin CLASS COUNT" lines (classes ascending) into st->fine and
 * their total into *sum, then the shards' "missing-in Q" and "record Q T
 * FILLED CRC" lines into pr.  Returns 0 or TVPAL_E_FORMAT. */
static int parse_rest(char **save, struct tvpal_checkpoint_stats *st,
                      struct tvpal_checkpoint_progress *pr, uint64_t *sum,
                      struct tvpal_diag *diag)
{
    char *line;
    long prev = -1;
    *sum = 0;
    memset(st->fine, 0, TVPAL_CHECKPOINT_BINS * sizeof *st->fine);
    if (pr) {
        memset(pr->filled, 0, sizeof *pr->filled * pr->nshard * pr->steps);
        memset(pr->crc, 0, sizeof *pr->crc * pr->nshard * pr->steps);
        memset(pr->missing, 0, pr->nshard);
    }
    while ((line = strtok_r(NULL, "\n", save))) {
        uint64_t b, c;
        const char *p = line + 4;
        if (!strncmp(line, "record ", 7)) {
            if (parse_record(line, pr) < 0)
                return tvpal_diag_set(diag, TVPAL_E_FORMAT, "bad progress "
                                      "line \"%.40s\"", line);
            prev = TVPAL_CHECKPOINT_BINS; /* no bin after progress */
            continue;
        }
        if (!strncmp(line, "missing-in ", 11)) {
            p = line + 11;
            if (take_u64(&p, UINT32_MAX, &b) < 0 || *p || !pr ||
                b >= pr->nshard)
                return tvpal_diag_set(diag, TVPAL_E_FORMAT, "bad line "
                                      "\"%.40s\"", line);
            pr->missing[b] = 1;
            prev = TVPAL_CHECKPOINT_BINS;
            continue;
        }
        if (strncmp(line, "bin ", 4) ||
            take_u64(&p, TVPAL_CHECKPOINT_BINS - 1, &b) < 0 || *p++ != ' ' ||
            take_u64(&p, UINT64_MAX, &c) < 0 || *p || (long)b <= prev)
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "bad histogram "
                                  "line \"%.40s\"", line);
        if (__builtin_add_overflow(*sum, (uint64_t)c, sum))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "histogram count "
                                  "overflows");
        st->fine[b] = c;
        prev = (long)b;
    }
    return 0;
}

/* Parses a checkpoint's text (modified in place); see tvpal_checkpoint_load
 * for what is checked. */
static int parse_checkpoint(char *text, const char *fingerprint,
                            uint64_t max_done, uint32_t steps,
                            uint64_t step_voxels, uint64_t *done,
                            struct tvpal_checkpoint_stats *st,
                            struct tvpal_checkpoint_progress *pr,
                            struct tvpal_diag *diag)
{
    char hash[40], *save = NULL;
    size_t n = strlen(text);
    /* Every line the writer writes ends in a newline: a file cut inside a
     * line is refused here, one cut between lines by the sum below. */
    if (n == 0 || text[n - 1] != '\n')
        return tvpal_diag_set(diag, TVPAL_E_TRUNC, "last line incomplete");
    fp_hash(fingerprint, hash);
    char *line = strtok_r(text, "\n", &save);
    if (!line || strncmp(line, "fingerprint ", 12))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "line 1: expected "
                              "\"fingerprint\"");
    if (strcmp(line + 12, hash))
        return tvpal_diag_set(diag, TVPAL_E_MISMATCH, "written by another "
                              "job (other options or inputs)");
    uint64_t sum = 0, most;
    int rc = parse_head(&save, done, st, diag);
    if (rc == 0)
        rc = parse_rest(&save, st, pr, &sum, diag);
    if (rc < 0)
        return rc;
    if (*done > max_done || st->loaded > steps)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "done %llu of %llu, "
                              "loaded %u of %u steps",
                              (unsigned long long)*done,
                              (unsigned long long)max_done, st->loaded, steps);
    if (__builtin_mul_overflow((uint64_t)steps, step_voxels, &most) ||
        st->counted > most || st->missing > st->counted ||
        sum != st->counted - st->missing)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "histogram holds %llu "
                              "values; expected %llu counted, %llu of them "
                              "missing (at most %u steps of %llu voxels)",
                              (unsigned long long)sum,
                              (unsigned long long)st->counted,
                              (unsigned long long)st->missing, steps,
                              (unsigned long long)step_voxels);
    if (sum && !(st->vmin <= st->vmax))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "min %g > max %g",
                              st->vmin, st->vmax);
    return 0;
}

int tvpal_checkpoint_load(const char *dir, const char *fingerprint,
                          uint64_t max_done, uint32_t steps,
                          uint64_t step_voxels, uint64_t *done,
                          struct tvpal_checkpoint_stats *st,
                          struct tvpal_checkpoint_progress *pr,
                          struct tvpal_diag *diag)
{
    char *path = checkpoint_path(dir), *text = NULL;
    int rc = path ? tvpal_read_file(path, &text, NULL, NULL) : TVPAL_E_NOMEM;
    if (rc < 0)
        tvpal_diag_set(diag, rc, "%s/checkpoint: %s", dir,
                       tvpal_strerror(rc));
    else
        rc = parse_checkpoint(text, fingerprint, max_done, steps, step_voxels,
                              done, st, pr, diag);
    if (rc < 0) {
        *done = 0;
        tvpal_checkpoint_stats_reset(st);
    }
    free(text);
    free(path);
    return rc;
}

int tvpal_checkpoint_remove(const char *dir, struct tvpal_diag *diag)
{
    char *path = checkpoint_path(dir);
    if (!path)
        return TVPAL_E_NOMEM;
    int rc = 0;
    if (unlink(path) < 0 && errno != ENOENT)
        rc = tvpal_diag_set(diag, TVPAL_E_SYS, "unlink %s: %s", path,
                            strerror(errno));
    free(path);
    /* The temporaries of saves a kill interrupted ("checkpoint.XXXXXX"). */
    DIR *dp = opendir(dir);
    struct dirent *e;
    while (dp && (e = readdir(dp))) {
        char *tmp = NULL;
        if (strncmp(e->d_name, "checkpoint.", 11) ||
            asprintf(&tmp, "%s/%s", dir, e->d_name) < 0)
            continue;
        if (unlink(tmp) < 0 && errno != ENOENT && rc == 0)
            rc = tvpal_diag_set(diag, TVPAL_E_SYS, "unlink %s: %s", tmp,
                                strerror(errno));
        free(tmp);
    }
    if (dp)
        closedir(dp);
    return rc;
}
