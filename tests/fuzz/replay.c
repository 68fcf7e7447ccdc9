/* replay: feeds every file of the given directories (or the given files)
 * to LLVMFuzzerTestOneInput, once each, in name order: the regression
 * driver of a harness when built without libFuzzer (make check).  Exits 0
 * when every input ran (a harness bug aborts), 1 on an unreadable
 * argument. */
#include "fuzz_util.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* Reads path whole into a malloc'ed buffer; NULL on error. */
static uint8_t *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    size_t cap = 4096, n = 0;
    uint8_t *b = malloc(cap);
    size_t got;
    while (b && (got = fread(b + n, 1, cap - n, f)) > 0) {
        n += got;
        if (n == cap) {
            uint8_t *nb = realloc(b, cap *= 2);
            if (!nb) {
                free(b);
                b = NULL;
            }
            b = nb;
        }
    }
    int err = ferror(f);
    fclose(f);
    if (err) {
        free(b);
        return NULL;
    }
    *size = n;
    return b;
}

static int run_file(const char *path)
{
    size_t n = 0;
    uint8_t *b = slurp(path, &n);
    if (!b) {
        perror(path);
        return 1;
    }
    LLVMFuzzerTestOneInput(b, n);
    free(b);
    return 0;
}

static int cmp(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Runs every regular file of dir; returns the number of failures, adds
 * the inputs run to *count. */
static int run_dir(const char *dir, unsigned *count)
{
    struct dirent **list;
    int n = scandir(dir, &list, NULL, NULL);
    if (n < 0) {
        perror(dir);
        return 1;
    }
    char **names = malloc(sizeof *names * (size_t)(n ? n : 1));
    int m = 0, bad = 0;
    for (int i = 0; i < n; i++) {
        if (list[i]->d_name[0] != '.')
            names[m++] = strdup(list[i]->d_name);
        free(list[i]);
    }
    free(list);
    qsort(names, (size_t)m, sizeof *names, cmp);
    for (int i = 0; i < m; i++) {
        char path[8192];
        struct stat st;
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        if (stat(path, &st) == 0 && S_ISREG(st.st_mode)) {
            bad += run_file(path);
            ++*count;
        }
        free(names[i]);
    }
    free(names);
    return bad;
}

int main(int argc, char **argv)
{
    unsigned count = 0;
    int bad = 0;
    for (int i = 1; i < argc; i++) {
        struct stat st;
        if (stat(argv[i], &st) == 0 && S_ISDIR(st.st_mode)) {
            bad += run_dir(argv[i], &count);
        } else {
            bad += run_file(argv[i]);
            count++;
        }
    }
    printf("%s: %u inputs replayed%s\n", argc ? argv[0] : "replay", count,
           bad ? ", some unreadable" : "");
    return bad ? 1 : 0;
}
