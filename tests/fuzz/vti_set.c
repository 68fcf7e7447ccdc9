/* Harness: VTK XML files that name others, assembled by the vti reader
 * through tvpal_input.h: a .pvti and its pieces, a .pvd and its DataSets.
 * The input is a small set of files, each after a line "=== NAME" (the
 * first one is opened; NAME is letters, digits, '.', '_', '-', with at
 * most one folder: "pieces/p0.vti"), written into a fresh folder so that
 * the references between them resolve.  Besides not crashing, what the
 * reader accepts must be a grid and times a dataset can hold
 * (input_common.h, check_grid). */
#include "input_common.h"

#include <stdio.h>
#include <sys/stat.h>

#define SET_MAX 16

/* Whether name[0..n) is a file name the set may use. */
static int good_name(const uint8_t *name, size_t n)
{
    int slashes = 0;
    if (n == 0 || n > 64 || name[0] == '/' || name[0] == '.')
        return 0;
    for (size_t i = 0; i < n; i++) {
        uint8_t c = name[i];
        if (c == '/') {
            if (++slashes > 1 || i + 1 == n || name[i + 1] == '.')
                return 0;
            continue;
        }
        if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
              (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-'))
            return 0;
    }
    return 1;
}

/* Writes the entry NAME with its bytes under set/ (its folder made). */
static void put(const uint8_t *name, size_t n, const uint8_t *data,
                size_t size)
{
    char rel[80] = "set/";
    memcpy(rel + 4, name, n);
    rel[4 + n] = 0;
    char *slash = strchr(rel + 4, '/');
    if (slash) {
        char dir[8192];
        *slash = 0;
        snprintf(dir, sizeof dir, "%s/%s", fuzz_dir(), rel);
        mkdir(dir, 0700);
        *slash = '/';
    }
    fuzz_write(rel, data, size);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char mark[] = "=== ";
    fuzz_remove("set");
    char top[8192];
    snprintf(top, sizeof top, "%s/set", fuzz_dir());
    if (mkdir(top, 0700) < 0)
        abort();
    char *first = NULL;
    const uint8_t *p = data, *end = data + size;
    for (int k = 0; k < SET_MAX && end - p >= 4 && !memcmp(p, mark, 4); k++) {
        const uint8_t *name = p + 4;
        const uint8_t *nl = memchr(name, '\n', (size_t)(end - name));
        if (!nl)
            break;
        /* the bytes up to the next "\n=== " or the end */
        const uint8_t *body = nl + 1, *next = end;
        for (const uint8_t *q = body; end - q >= 5; q++)
            if (q[0] == '\n' && !memcmp(q + 1, mark, 4)) {
                next = q;
                break;
            }
        if (good_name(name, (size_t)(nl - name))) {
            put(name, (size_t)(nl - name), body, (size_t)(next - body));
            if (!first) {
                char path[8192];
                snprintf(path, sizeof path, "%s/%.*s", top,
                         (int)(nl - name), (const char *)name);
                if (!(first = strdup(path)))
                    abort();
            }
        }
        p = next + (next < end);
    }
    if (first) {
        open_and_read(&first, 1, TVPAL_IN_VTI);
        char *text = NULL;
        struct tvpal_diag d;
        if (tvpal_input_describe(first, TVPAL_IN_VTI, &text, &d) == 0)
            free(text);
        free(first);
    }
    return 0;
}
