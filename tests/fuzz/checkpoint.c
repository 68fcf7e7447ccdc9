/* Harness: the encoder's resume record (tvpal_checkpoint_load, FORMAT.md
 * 9.2), as a rerun of `tvpal-encode --resume` finds it after a crash or on
 * a damaged disk.  A checkpoint that loads must satisfy what the loader
 * promises (done, loaded and counted in bounds, the histogram holding the
 * values it says), and saving what was loaded must load again to the same
 * job state (a round trip).  The job: the fingerprint "fuzz job", 4 steps
 * of 1000 voxels, 2 shards, at most 8 units done; the seed corpus carries
 * that fingerprint's hash, so mutations reach the lines after it. */
#include "fuzz_util.h"
#include "tvpal_checkpoint.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define FP "fuzz job"
#define STEPS 4u
#define VOXELS 1000u
#define SHARDS 2u
#define MAX_DONE 8u

struct state {
    uint64_t done;
    struct tvpal_checkpoint_stats st;
    struct tvpal_checkpoint_progress pr;
    uint64_t filled[SHARDS * STEPS];
    uint32_t crc[SHARDS * STEPS];
    uint8_t missing[SHARDS];
};

static void state_init(struct state *s)
{
    memset(s, 0, sizeof *s);
    if (tvpal_checkpoint_stats_init(&s->st) < 0)
        abort();
    s->pr = (struct tvpal_checkpoint_progress){SHARDS, STEPS, s->filled,
                                               s->crc, s->missing};
}

/* Loads fuzz_dir()/dir/checkpoint into s: the loader's return code. */
static int load(const char *dir, struct state *s)
{
    struct tvpal_diag d;
    return tvpal_checkpoint_load(dir, FP, MAX_DONE, STEPS, VOXELS, &s->done,
                                 &s->st, &s->pr, &d);
}

/* Whether two loaded states are the same job state (NaN bounds equal to
 * NaN: the writer's %a keeps them NaN). */
static int same(const struct state *a, const struct state *b)
{
    const struct tvpal_checkpoint_stats *x = &a->st, *y = &b->st;
#define SAME_D(u, v) ((u) == (v) || ((u) != (u) && (v) != (v)))
    return a->done == b->done && x->loaded == y->loaded &&
           x->counted == y->counted && x->nonfinite == y->nonfinite &&
           x->missing == y->missing && SAME_D(x->vmin, y->vmin) &&
           SAME_D(x->vmax, y->vmax) &&
           !memcmp(x->fine, y->fine,
                   TVPAL_CHECKPOINT_BINS * sizeof *x->fine) &&
           !memcmp(a->filled, b->filled, sizeof a->filled) &&
           !memcmp(a->crc, b->crc, sizeof a->crc) &&
           !memcmp(a->missing, b->missing, sizeof a->missing);
#undef SAME_D
}

/* What tvpal_checkpoint_load promises of a checkpoint it accepts. */
static void check_promises(const struct state *s)
{
    uint64_t sum = 0;
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++)
        sum += s->st.fine[b];
    if (s->done > MAX_DONE || s->st.loaded > STEPS ||
        s->st.counted > (uint64_t)STEPS * VOXELS ||
        s->st.missing > s->st.counted ||
        sum != s->st.counted - s->st.missing)
        abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static char in_dir[4096], out_dir[4096];
    if (!in_dir[0]) {
        snprintf(in_dir, sizeof in_dir, "%s/in", fuzz_dir());
        snprintf(out_dir, sizeof out_dir, "%s/out", fuzz_dir());
        if (mkdir(in_dir, 0700) < 0 || mkdir(out_dir, 0700) < 0)
            abort();
    }
    fuzz_write("in/checkpoint", data, size);
    struct state a, b;
    state_init(&a);
    state_init(&b);
    if (load(in_dir, &a) == 0) {
        check_promises(&a);
        struct tvpal_diag d;
        if (tvpal_checkpoint_save(out_dir, FP, a.done, &a.st, &a.pr, &d) < 0)
            abort();    /* the scratch directory is writable */
        if (load(out_dir, &b) < 0 || !same(&a, &b))
            abort();    /* what save writes, load must read back */
    } else if (a.done != 0 || a.st.loaded != 0 || a.st.counted != 0) {
        abort();        /* a refused checkpoint leaves the job empty */
    }
    tvpal_checkpoint_stats_free(&a.st);
    tvpal_checkpoint_stats_free(&b.st);
    return 0;
}
