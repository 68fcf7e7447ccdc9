/* fuzz_util.c: see fuzz_util.h. */
#include "fuzz_util.h"
#include "tvpal_crc32c.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[4096];

static void rm_tree(const char *path)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return;
    if (S_ISDIR(st.st_mode)) {
        DIR *d = opendir(path);
        struct dirent *e;
        while (d && (e = readdir(d))) {
            if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
                continue;
            char sub[8192];
            snprintf(sub, sizeof sub, "%s/%s", path, e->d_name);
            rm_tree(sub);
        }
        if (d)
            closedir(d);
        rmdir(path);
    } else {
        unlink(path);
    }
}

static void rm_dir(void)
{
    rm_tree(dir);
}

const char *fuzz_dir(void)
{
    if (dir[0])
        return dir;
    const char *t = getenv("TMPDIR");
    snprintf(dir, sizeof dir, "%s/tvpal-fuzz-XXXXXX", t && *t ? t : "/tmp");
    if (!mkdtemp(dir)) {
        perror("fuzz: mkdtemp");
        abort();
    }
    atexit(rm_dir);
    return dir;
}

const char *fuzz_write(const char *name, const void *data, size_t size)
{
    static char path[8192];
    snprintf(path, sizeof path, "%s/%s", fuzz_dir(), name);
    FILE *f = fopen(path, "wb");
    if (!f || (size && fwrite(data, 1, size, f) != size) || fclose(f)) {
        perror(path);
        abort();
    }
    return path;
}

void fuzz_remove(const char *name)
{
    char path[8192];
    snprintf(path, sizeof path, "%s/%s", fuzz_dir(), name);
    rm_tree(path);
}

char *fuzz_strdup(const uint8_t *data, size_t size)
{
    char *s = malloc(size + 1);
    if (!s)
        abort();
    if (size)
        memcpy(s, data, size);
    s[size] = 0;
    return s;
}

static uint64_t get64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = v << 8 | p[i];
    return v;
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
           (uint32_t)p[3] << 24;
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

int fuzz_seal_record(uint8_t *buf, size_t size, uint64_t r, uint32_t *crc)
{
    if (r > size || size - r < 64)
        return 0;
    uint64_t n = get64(buf + r + 16);
    if (n > size - r - 64)
        return 0;
    *crc = tvpal_crc32c(0, buf + r + 64, (size_t)n);
    put32(buf + r + 24, *crc);
    put32(buf + r + 60, tvpal_crc32c(0, buf + r, 60));
    return 1;
}

void fuzz_seal_header(uint8_t *buf, size_t size)
{
    if (size >= 4096)
        put32(buf + 4092, tvpal_crc32c(0, buf, 4092));
}

void fuzz_seal_shard(uint8_t *buf, size_t size)
{
    if (size < 4096)
        return;
    uint32_t steps = get32(buf + 28);
    uint64_t idx = get64(buf + 72);
    if (idx <= size) {
        uint64_t room = (size - idx) / 32;
        for (uint64_t t = 0; t < steps && t < room; t++) {
            uint8_t *e = buf + idx + 32 * t;
            uint32_t pc;
            if (fuzz_seal_record(buf, size, get64(e), &pc))
                put32(e + 24, pc);
        }
        put32(buf + 88, tvpal_crc32c(0, buf + idx, (size_t)(size - idx)));
    }
    fuzz_seal_header(buf, size);
}
