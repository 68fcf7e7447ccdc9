/* Harness: a whole dataset directory (tvpal_dataset_open,
 * tvpal_dataset_open_node, and the volume readers of the three axes).
 *
 * Input: parts separated by the line FUZZ_SPLIT: the manifest text, then
 * the shards node-0/axis-x, -y, -z, node-1/axis-x, ... (at most 6), each
 * re-sealed as a forger would (fuzz_seal_shard).  The manifest is written
 * to the dataset directory and to node-0/. */
#define _GNU_SOURCE 1  /* memmem */
#include "fuzz_util.h"
#include "shard_walk.h"
#include "tvpal_dataset.h"

#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

#define FUZZ_SPLIT "\n--tvpal-fuzz-part--\n"
#define MAX_SHARDS 6

/* Writes part k (0: the manifest) of the dataset "ds". */
static void write_part(unsigned k, const uint8_t *p, size_t n)
{
    char name[64];
    if (k == 0) {
        fuzz_write("ds/manifest.txt", p, n);
        fuzz_write("ds/node-0/manifest.txt", p, n);
        return;
    }
    uint8_t *b = malloc(n ? n : 1);
    if (!b)
        abort();
    memcpy(b, p, n);
    fuzz_seal_shard(b, n);
    snprintf(name, sizeof name, "ds/node-%u/axis-%c.tvps", (k - 1) / 3,
             "xyz"[(k - 1) % 3]);
    fuzz_write(name, b, n);
    free(b);
}

/* Makes fuzz_dir()/ds afresh with node-0 and node-1. */
static void make_dirs(void)
{
    char path[8192];
    fuzz_remove("ds");
    const char *sub[] = {"ds", "ds/node-0", "ds/node-1"};
    for (int i = 0; i < 3; i++) {
        snprintf(path, sizeof path, "%s/%s", fuzz_dir(), sub[i]);
        if (mkdir(path, 0700) != 0)
            abort();
    }
}

static void split_and_write(const uint8_t *data, size_t size)
{
    const size_t sl = strlen(FUZZ_SPLIT);
    unsigned k = 0;
    while (k <= MAX_SHARDS) {
        const uint8_t *e = memmem(data, size, FUZZ_SPLIT, sl);
        size_t n = e ? (size_t)(e - data) : size;
        write_part(k++, data, n);
        if (!e)
            break;
        data += n + sl;
        size -= n + sl;
    }
}

/* Decodes the first steps along every axis when the volume is small (the
 * axes not stored must be refused, not read). */
static void read_volumes(struct tvpal_dataset *ds)
{
    const uint32_t *dm = ds->m.dims;
    uint64_t n = (uint64_t)dm[0] * dm[1] * dm[2];
    if (n == 0 || n > (1u << 20))
        return;
    float *vol = malloc((size_t)n * sizeof *vol);
    if (!vol)
        abort();
    struct tvpal_diag d;
    for (unsigned a = 0; a < 3; a++) {
        struct tvpal_volreader *r;
        if (tvpal_volreader_create(&r, ds, a, &d) < 0)
            continue; /* an axis not stored is refused */
        for (uint32_t t = 0; t < ds->m.steps && t < 3; t++)
            (void)tvpal_volreader_read(r, t, vol, &d);
        tvpal_volreader_free(r);
    }
    free(vol);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    make_dirs();
    split_and_write(data, size);
    char dir[8192];
    snprintf(dir, sizeof dir, "%s/ds", fuzz_dir());
    struct tvpal_dataset *ds;
    struct tvpal_diag d;
    if (tvpal_dataset_open(&ds, dir, &d) == 0) {
        read_volumes(ds);
        tvpal_dataset_close(ds);
    }
    snprintf(dir, sizeof dir, "%s/ds/node-0", fuzz_dir());
    if (tvpal_dataset_open_node(&ds, dir, 0, 1, &d) == 0) {
        read_volumes(ds);
        tvpal_dataset_close(ds);
    }
    return 0;
}
