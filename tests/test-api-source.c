/* test-api-source: libtvpal's encode from a source (tvpal_encoder_encode,
 * tvpal_encoder_plan), through the shared library and tvpal.h only.
 *  - a source read a box at a time (on the encoder's reader thread) and
 *    one read concurrently in pieces give the shards, manifest and levels
 *    that pushes of the same values give, byte for byte: in one pass, and
 *    under a memory limit in several passes over slabs of every axis
 *    (levels then made after level 0 from the source read again);
 *  - integer sources (uint16 in this host's order and big-endian, int16,
 *    uint8) give the shards of their values pushed as float32;
 *  - the plan: one pass without a limit, passes on every axis under a
 *    small one, the boxes read each step's voxels once per pass, a limit
 *    below the smallest refused (TVPAL_E_RANGE) with the smallest that
 *    would do, which then works;
 *  - stopped by its progress callback (TVPAL_SAVE_AND_STOP) in the middle
 *    of a pass, then encoded again with the same identity: it continues
 *    after the checkpoint (the steps before are not read again) and the
 *    dataset is the uninterrupted one's, byte for byte; with another
 *    identity it starts over; without one nothing is kept;
 *  - provenance (tvpal_encoder_set_provenance) read back through the
 *    reader: the encoder, the format, variable and files, a raw source's
 *    type and byte order; a format, a line or files that do not fit
 *    refused;
 *  - ranks of a collective (threads here) that each read the whole
 *    source write the dataset of one process with --nodes, every axis and
 *    the levels (rank 0's, after level 0), with and without a memory
 *    limit; a rank whose read fails fails every rank's finish with its
 *    words, and nothing is left;
 *  - every value missing, pulled or pushed: refused at finish, saying so,
 *    nothing left;
 *  - a read that fails (its code and words come back, DIR.partial kept for
 *    a resume), an infinite value (named by its voxel, nothing kept), a
 *    second encode, a push after one, a collective, a source without read
 *    or of an unknown type: refused with a diag. */
#define _GNU_SOURCE
#include "tvpal.h"
#include "tvpal_test.h"
#include "tt_ranks.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define NX 20
#define NY 14
#define NZ 11
#define T 9
#define NV (NX * NY * NZ)

static const char *W = "tests/work/test-api-source";
static const uint32_t dims[3] = {NX, NY, NZ};

static char *path(const char *fmt, const char *a)
{
    static char buf[8][512];
    static int k;
    char *b = buf[k++ % 8];
    snprintf(b, 512, fmt, W, a);
    return b;
}

static int exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0;
}

/* Value (x, y, z) of step t: a moving front, noise, a missing corner. */
static double value(unsigned t, unsigned x, unsigned y, unsigned z)
{
    if (x < 2 && y < 2 && z == 0)
        return NAN;
    const unsigned h = (x * 73856093u) ^ (y * 19349663u) ^ (z * 83492791u) ^
                       (t * 2654435761u);
    return 300 + 40 * tanh(0.6 * (x - 1.7 * t - 0.3 * y)) +
           5 * sin(0.9 * z + 0.2 * t) + (double)(h % 1000) / 250.0;
}

/* The series, as float32, the values pushed and read. */
static float series[T][NV];

static void make_series(void)
{
    for (unsigned t = 0; t < T; t++)
        for (unsigned z = 0; z < NZ; z++)
            for (unsigned y = 0; y < NY; y++)
                for (unsigned x = 0; x < NX; x++)
                    series[t][x + NX * (y + NY * z)] =
                        (float)value(t, x, y, z);
}

/* ----------------------------------------------------------- a source */

struct src {
    enum tvpal_scalar type;
    int big;
    unsigned reads_lo;      /* reads of steps below this */
    unsigned reads;         /* every read (atomically) */
    int fail_step;          /* read of this step fails (-1: none) */
    int inf_step;           /* this step has an infinity (-1: none) */
    int all_nan;            /* every value is missing */
    uint64_t stop_unit;     /* the progress callback stops here (0: no) */
    unsigned stop_level;    /* or at the end of this level (0: no) */
    struct tvpal_progress first; /* what the first progress call saw */
    uint64_t first_unit;    /* the unit the first progress call saw */
    int seen;
    unsigned ticks, ends;
};

static void put(const struct src *s, double v, unsigned char *dst)
{
    unsigned char b[8];
    size_t n;
    switch (s->type) {
    case TVPAL_FLOAT64: { double w = v; memcpy(b, &w, n = 8); break; }
    case TVPAL_UINT8: { uint8_t w = (uint8_t)v; memcpy(b, &w, n = 1); break; }
    case TVPAL_UINT16: { uint16_t w = (uint16_t)v; memcpy(b, &w, n = 2); break; }
    case TVPAL_INT16: { int16_t w = (int16_t)v; memcpy(b, &w, n = 2); break; }
    default: { float w = (float)v; memcpy(b, &w, n = 4); break; }
    }
    for (size_t i = 0; i < n; i++)
        dst[i] = s->big ? b[n - 1 - i] : b[i];
}

static size_t esize(enum tvpal_scalar t)
{
    return t == TVPAL_FLOAT64 ? 8 : t == TVPAL_UINT8 ? 1
           : t == TVPAL_UINT16 || t == TVPAL_INT16 ? 2 : 4;
}

/* What an integer source holds for a value (the float series, in range). */
static double as_type(enum tvpal_scalar t, float v)
{
    if (isnan(v))
        return t == TVPAL_FLOAT32 || t == TVPAL_FLOAT64 ? NAN : 0;
    return t == TVPAL_UINT8 ? floor(v - 250) : t == TVPAL_INT16
           ? floor(v * 10 - 3400) : t == TVPAL_UINT16 ? floor(v * 100) : v;
}

static int src_read(void *ctx, uint32_t t, const uint32_t lo[3],
                    const uint32_t n[3], void *dst, struct tvpal_diag *d)
{
    struct src *s = ctx;
    __atomic_add_fetch(&s->reads, 1, __ATOMIC_RELAXED);
    if (t < s->reads_lo)
        __atomic_add_fetch(&s->seen, 1, __ATOMIC_RELAXED);
    if ((int)t == s->fail_step)
        return tvpal_diag_set(d, TVPAL_E_READ, "series.raw: step %u: "
                              "input/output error", t);
    unsigned char *o = dst;
    const size_t es = esize(s->type);
    for (uint32_t z = 0; z < n[2]; z++)
        for (uint32_t y = 0; y < n[1]; y++)
            for (uint32_t x = 0; x < n[0]; x++, o += es) {
                const uint32_t gx = lo[0] + x, gy = lo[1] + y, gz = lo[2] + z;
                double v = as_type(s->type,
                                   series[t][gx + NX * (gy + NY * gz)]);
                if ((int)t == s->inf_step && gx == 5 && gy == 6 && gz == 7)
                    v = INFINITY;
                if (s->all_nan)
                    v = NAN;
                put(s, v, o);
            }
    return 0;
}

static int src_progress(void *ctx, const struct tvpal_progress *p)
{
    struct src *s = ctx;
    if (!s->ends && !s->ticks) {
        s->first_unit = p->unit;
        s->first = *p;
    }
    if (!p->unit_end) {
        s->ticks++;
        return TVPAL_STOP; /* ignored at a tick */
    }
    s->ends++;
    if (s->stop_level && p->level == s->stop_level)
        return TVPAL_STOP;
    return s->stop_unit && p->unit == s->stop_unit ? TVPAL_SAVE_AND_STOP
                                                    : TVPAL_GO_ON;
}

static struct tvpal_source source_of(struct src *s, int concurrent,
                                     const char *identity)
{
    return (struct tvpal_source){
        .type = s->type, .big_endian = s->big, .concurrent = concurrent,
        .identity = identity, .ctx = s, .read = src_read,
        .progress = src_progress};
}

static struct src plain(enum tvpal_scalar type)
{
    return (struct src){.type = type, .fail_step = -1, .inf_step = -1};
}

/* ----------------------------------------------------------- encoders */

struct job {
    unsigned window, levels, axes;
    uint64_t limit;
    unsigned nodes;          /* 0: 1 (a collective sets its own) */
    unsigned group;          /* 0: the default; else TVPAL_PARAM_GROUP */
    int group_auto;          /* TVPAL_PARAM_GROUP TVPAL_GROUP_AUTO */
};

static int open_job(struct tvpal_encoder **out, const char *dir,
                    const struct job *j, struct tvpal_diag *d)
{
    struct tvpal_encoder *e = NULL;
    int rc = tvpal_encoder_open(&e, dir, dims, T, d);
    *out = NULL;
    if (rc < 0)
        return rc;
    const double sp[3] = {0.5, 1, 2}, or[3] = {-1, 0, 3};
    if ((rc = tvpal_encoder_set(e, TVPAL_PARAM_WINDOW, j->window, d)) < 0 ||
        (rc = tvpal_encoder_set(e, TVPAL_PARAM_AXES, j->axes, d)) < 0 ||
        (rc = tvpal_encoder_set(e, TVPAL_PARAM_LEVELS, j->levels, d)) < 0 ||
        (rc = tvpal_encoder_set(e, TVPAL_PARAM_MEM_LIMIT, (double)j->limit,
                                d)) < 0 ||
        (rc = tvpal_encoder_set(e, TVPAL_PARAM_THREADS, 2, d)) < 0 ||
        (j->nodes && (rc = tvpal_encoder_set(e, TVPAL_PARAM_NODES, j->nodes,
                                             d)) < 0) ||
        ((j->group || j->group_auto) &&
         (rc = tvpal_encoder_set(e, TVPAL_PARAM_GROUP,
                                 j->group_auto ? TVPAL_GROUP_AUTO : j->group,
                                 d)) < 0) ||
        (rc = tvpal_encoder_set_grid(e, sp, or, d)) < 0 ||
        (rc = tvpal_encoder_set_units(e, "K", d)) < 0) {
        tvpal_encoder_abort(e);
        return rc;
    }
    *out = e;
    return 0;
}

/* The series pushed, as float32 values of type t (as_type). */
static int push_all(const char *dir, const struct job *j,
                    enum tvpal_scalar t, struct tvpal_diag *d)
{
    struct tvpal_encoder *e = NULL;
    int rc = open_job(&e, dir, j, d);
    static float v[NV];
    for (unsigned s = 0; s < T && rc == 0; s++) {
        for (unsigned i = 0; i < NV; i++)
            v[i] = t == TVPAL_FLOAT32 ? series[s][i]
                                      : (float)as_type(t, series[s][i]);
        rc = tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, d);
    }
    if (rc < 0) {
        tvpal_encoder_abort(e);
        return rc;
    }
    return tvpal_encoder_finish(e, d);
}

/* Encodes from s; finish, or abort on failure. */
static int pull_all(const char *dir, const struct job *j,
                    const struct tvpal_source *s, struct tvpal_diag *d)
{
    struct tvpal_encoder *e = NULL;
    int rc = open_job(&e, dir, j, d);
    if (rc == 0)
        rc = tvpal_encoder_encode(e, s, d);
    if (rc < 0) {
        tvpal_encoder_abort(e);
        return rc;
    }
    return tvpal_encoder_finish(e, d);
}

/* Every file of datasets a and b agrees byte for byte (the shards of each
 * axis, the manifests, each level's), and a has the shards it should. */
static int same_dataset(const char *a, const char *b, unsigned levels,
                        unsigned axes)
{
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "diff -r %s %s > %s/diff.txt 2>&1", a, b, W);
    int rc = system(cmd);
    if (rc != 0) {
        snprintf(cmd, sizeof cmd, "head -n 5 %s/diff.txt >&2", W);
        if (system(cmd) != 0)
            return 0;
    }
    int shards = 0;
    for (unsigned k = 0; k <= levels; k++)
        for (unsigned ax = 0; ax < 3; ax++) {
            char p[600];
            if (!(axes & (1u << ax)))
                continue;
            if (k)
                snprintf(p, sizeof p, "%s/level-%u/node-0/axis-%c.tvps", a, k,
                         "xyz"[ax]);
            else
                snprintf(p, sizeof p, "%s/node-0/axis-%c.tvps", a, "xyz"[ax]);
            shards += exists(p);
        }
    unsigned want = 0;
    for (unsigned ax = 0; ax < 3; ax++)
        want += (axes >> ax) & 1;
    return rc == 0 && shards == (int)(want * (levels + 1));
}

/* --------------------------------------------------------------- tests */

static const struct job base = {.window = 4, .axes = 7};

/* A limit below the one-pass peak of job j by `below` of level 0's ring:
 * 3/4 takes several passes; with levels, 1/4 leaves level 0 one pass but
 * not the levels beside it.  The plans without and with it. */
static uint64_t limit_below(const struct job *j, int concurrent,
                            double below, struct tvpal_plan *one,
                            struct tvpal_plan *some)
{
    struct tvpal_encoder *e = NULL;
    struct tvpal_diag d = {{0}};
    struct src s = plain(TVPAL_FLOAT32);
    const struct tvpal_source so = source_of(&s, concurrent, NULL);
    REQUIRE(open_job(&e, path("%s/plan%s", ""), j, &d) == 0, "%s", d.msg);
    int rc = tvpal_encoder_plan(e, &so, one, &d);
    REQUIRE(rc == 0, "plan without a limit: %s", d.msg);
    uint64_t ring = (uint64_t)j->window * NV * 4;
    uint64_t limit = one->peak_bytes - (uint64_t)(below * (double)ring);
    tvpal_encoder_set(e, TVPAL_PARAM_MEM_LIMIT, (double)limit, &d);
    rc = tvpal_encoder_plan(e, &so, some, &d);
    REQUIRE(rc == 0, "plan under %llu: %s", (unsigned long long)limit, d.msg);
    tvpal_encoder_abort(e);
    return limit;
}

static void test_same_as_pushed(void)
{
    struct tvpal_diag d = {{0}};
    int rc = push_all(path("%s/pushed%s", ""), &base, TVPAL_FLOAT32, &d);
    REQUIRE(rc == 0, "push: %s %s", tvpal_strerror(rc), d.msg);
    for (int conc = 0; conc < 2; conc++) {
        struct src s = plain(TVPAL_FLOAT32);
        const struct tvpal_source so = source_of(&s, conc, NULL);
        char *dir = path(conc ? "%s/conc%s" : "%s/whole%s", "");
        rc = pull_all(dir, &base, &so, &d);
        CHECK(rc == 0, "encode (concurrent %d): %s %s", conc,
              tvpal_strerror(rc), d.msg);
        CHECK(same_dataset(path("%s/pushed%s", ""), dir, 0, 7),
              "one pass, concurrent %d: not the pushed dataset", conc);
        CHECK(s.first_unit == 0 && s.ticks >= 1,
              "no progress call before the first read");
        CHECK(s.reads == (conc ? NZ * T : T) && s.ends == T,
              "one pass, concurrent %d: %u reads, %u unit ends; %u, %u "
              "expected", conc, s.reads, s.ends, conc ? NZ * T : T, T);
    }
    /* Several passes. */
    for (int conc = 0; conc < 2; conc++) {
        struct tvpal_plan one, some;
        struct job j = base;
        j.limit = limit_below(&j, conc, 0.75, &one, &some);
        CHECK(one.passes == 1 && one.passes_axis[2] == 0 &&
                  one.read_voxels == (uint64_t)NV * T,
              "plan without a limit: %u passes, %llu voxels read",
              one.passes, (unsigned long long)one.read_voxels);
        CHECK(some.passes > 3 && some.passes_axis[0] > 1 &&
                  some.passes_axis[1] > 1 && some.passes_axis[2] > 1 &&
                  some.peak_bytes <= j.limit &&
                  some.read_voxels > (uint64_t)NV * T,
              "plan under %llu: %u passes (x %u, y %u, z %u), peak %llu",
              (unsigned long long)j.limit, some.passes,
              some.passes_axis[0], some.passes_axis[1],
              some.passes_axis[2], (unsigned long long)some.peak_bytes);
        struct src s = plain(TVPAL_FLOAT32);
        const struct tvpal_source so = source_of(&s, conc, NULL);
        char *dir = path(conc ? "%s/conc-passes%s" : "%s/whole-passes%s",
                         "");
        rc = pull_all(dir, &j, &so, &d);
        CHECK(rc == 0, "encode in passes: %s %s", tvpal_strerror(rc), d.msg);
        CHECK(same_dataset(path("%s/pushed%s", ""), dir, 0, 7),
              "%u passes, concurrent %d: not the pushed dataset",
              some.passes, conc);
        CHECK(s.ends == some.passes * T, "%u unit ends, %u expected",
              s.ends, some.passes * T);
    }
}

/* TVPAL_GROUP_AUTO: refused with pushes; from a source each axis' G is
 * measured (small slices here: groups on some axis), the same from a
 * whole or a concurrent source, and each axis' shard is the one an encode
 * with that G writes (passes: tests/group-auto.sh, on a larger volume). */
static void test_group_auto(void)
{
    struct tvpal_diag d = {{0}};
    struct job j = base;
    j.group_auto = 1;
    int rc = push_all(path("%s/ga-pushed%s", ""), &j, TVPAL_FLOAT32, &d);
    CHECK(rc == TVPAL_E_INVAL && strstr(d.msg, "TVPAL_GROUP_AUTO"),
          "auto with pushes: %s %s", tvpal_strerror(rc), d.msg);
    CHECK(!exists(path("%s/ga-pushed%s", "")), "a refused push wrote");
    struct src s = plain(TVPAL_FLOAT32);
    struct tvpal_source so = source_of(&s, 0, NULL);
    rc = pull_all(path("%s/ga%s", ""), &j, &so, &d);
    REQUIRE(rc == 0, "encode auto: %s %s", tvpal_strerror(rc), d.msg);
    struct tvpal_reader *r = NULL;
    REQUIRE(tvpal_reader_open(&r, path("%s/ga%s", ""), &d) == 0, "%s",
            d.msg);
    uint32_t G[3];
    memcpy(G, tvpal_reader_info(r)->group, sizeof G);
    tvpal_reader_close(r);
    CHECK(G[0] * G[1] * G[2] > 1 && G[0] <= 16 && G[1] <= 16 && G[2] <= 16,
          "groups chosen %u %u %u", G[0], G[1], G[2]);
    struct src sc = plain(TVPAL_FLOAT32);
    so = source_of(&sc, 1, NULL);
    rc = pull_all(path("%s/ga-conc%s", ""), &j, &so, &d);
    CHECK(rc == 0 && same_dataset(path("%s/ga%s", ""),
                                  path("%s/ga-conc%s", ""), 0, 7),
          "auto from a concurrent source: %s", d.msg);
    for (unsigned a = 0; a < 3; a++) {
        struct job ja = base;
        ja.axes = 1u << a;
        ja.group = G[a];
        struct src sa = plain(TVPAL_FLOAT32);
        so = source_of(&sa, 0, NULL);
        char *dir = path("%s/ga-axis%s", "");
        rc = pull_all(dir, &ja, &so, &d);
        char cmd[1200];
        snprintf(cmd, sizeof cmd, "cmp -s %s/ga/node-0/axis-%c.tvps "
                 "%s/node-0/axis-%c.tvps", W, "xyz"[a], dir, "xyz"[a]);
        CHECK(rc == 0 && system(cmd) == 0, "axis %c: not the shard of "
              "group %u", "xyz"[a], G[a]);
        snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
        CHECK(system(cmd) == 0, "%s", cmd);
    }
}

static void test_integers(void)
{
    static const enum tvpal_scalar types[] = {TVPAL_UINT16, TVPAL_UINT16,
                                              TVPAL_INT16, TVPAL_UINT8,
                                              TVPAL_FLOAT64};
    struct job j = base;
    j.axes = TVPAL_AXIS_Z;
    for (unsigned i = 0; i < sizeof types / sizeof *types; i++) {
        struct tvpal_diag d = {{0}};
        char name[32];
        snprintf(name, sizeof name, "/int-%u", i);
        int rc = push_all(path("%s%s-pushed", name), &j, types[i], &d);
        REQUIRE(rc == 0, "push %u: %s", i, d.msg);
        struct src s = plain(types[i]);
        s.big = i == 1;
        const struct tvpal_source so = source_of(&s, i % 2, NULL);
        rc = pull_all(path("%s%s", name), &j, &so, &d);
        CHECK(rc == 0, "type %d (big-endian %d): %s", (int)types[i], s.big,
              d.msg);
        /* The manifests name their source types; the shards agree. */
        char a[600], b[600];
        snprintf(a, sizeof a, "cmp -s %s%s-pushed/node-0/axis-z.tvps "
                 "%s%s/node-0/axis-z.tvps", W, name, W, name);
        CHECK(system(a) == 0, "type %d (big-endian %d): shards differ from "
              "its values pushed as float32", (int)types[i], s.big);
        snprintf(b, sizeof b, "grep -q '^options = .*--type %s' "
                 "%s%s/manifest.txt", types[i] == TVPAL_UINT16 ? "u16"
                 : types[i] == TVPAL_INT16 ? "i16" : types[i] == TVPAL_UINT8
                 ? "u8" : "f64", W, name);
        CHECK(system(b) == 0, "type %d: the manifest's options do not name "
              "it", (int)types[i]);
    }
}

static void test_levels(void)
{
    struct tvpal_diag d = {{0}};
    struct job j = base;
    j.levels = 2;
    int rc = push_all(path("%s/lv-pushed%s", ""), &j, TVPAL_FLOAT32, &d);
    REQUIRE(rc == 0, "push with levels: %s", d.msg);
    struct src s = plain(TVPAL_FLOAT32);
    struct tvpal_source so = source_of(&s, 0, NULL);
    rc = pull_all(path("%s/lv-inline%s", ""), &j, &so, &d);
    CHECK(rc == 0 && same_dataset(path("%s/lv-pushed%s", ""),
                                  path("%s/lv-inline%s", ""), 2, 7),
          "levels beside one pass: %s", d.msg);
    CHECK(s.reads == T, "levels beside one pass: %u reads, %u expected",
          s.reads, T);
    struct tvpal_plan one, some;
    for (int conc = 0; conc < 2; conc++) {
        j.limit = limit_below(&j, conc, 0.25, &one, &some);
        CHECK(one.levels_inline && !some.levels_inline,
              "levels inline: %d without a limit, %d under one",
              one.levels_inline, some.levels_inline);
        s = plain(TVPAL_FLOAT32);
        so = source_of(&s, conc, NULL);
        char *dir = path(conc ? "%s/lv-after-c%s" : "%s/lv-after%s", "");
        rc = pull_all(dir, &j, &so, &d);
        CHECK(rc == 0 && same_dataset(path("%s/lv-pushed%s", ""), dir, 2, 7),
              "levels after %u passes (concurrent %d): %s", some.passes,
              conc, d.msg);
    }
}

/* Stops at unit `stop` (0: never), then encodes again with identity id2:
 * the reads of steps below `lo` in the second run, into *seen. */
static int stop_and_continue(const char *dir, const struct job *j,
                             uint64_t stop, const char *id1, const char *id2,
                             unsigned lo, unsigned *seen, uint64_t *first)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_encoder *e = NULL;
    struct src s = plain(TVPAL_FLOAT32);
    s.stop_unit = stop;
    struct tvpal_source so = source_of(&s, 1, id1);
    REQUIRE(open_job(&e, dir, j, &d) == 0, "%s", d.msg);
    int rc = tvpal_encoder_encode(e, &so, &d);
    CHECK(rc == TVPAL_E_CANCELED && strstr(d.msg, "checkpoint saved"),
          "stopped at unit %llu: %s %s", (unsigned long long)stop,
          tvpal_strerror(rc), d.msg);
    CHECK(tvpal_encoder_finish(e, &d) == TVPAL_E_INVAL,
          "finish after a stopped encode");
    char partial[600];
    snprintf(partial, sizeof partial, "%s.partial", dir);
    CHECK(!exists(dir) && (exists(partial) == (id1 != NULL)),
          "after the stop (identity %s): %s %s", id1 ? id1 : "none",
          exists(dir) ? "DIR exists" : "",
          exists(partial) ? "DIR.partial kept" : "no DIR.partial");
    s = plain(TVPAL_FLOAT32);
    s.reads_lo = lo;
    so = source_of(&s, 1, id2);
    rc = pull_all(dir, j, &so, &d);
    CHECK(rc == 0, "encode again: %s %s", tvpal_strerror(rc), d.msg);
    *seen = s.seen;
    *first = s.first_unit;
    return rc;
}

static void test_stop_and_continue(void)
{
    struct tvpal_plan one, some;
    struct job j = base;
    j.limit = limit_below(&j, 1, 0.75, &one, &some);
    const char *ref = path("%s/conc-passes%s", "");
    /* Stopped in the second pass at step 5: the second run starts there. */
    const uint64_t stop = T + 5;
    unsigned seen = 0;
    uint64_t first = 0;
    char *dir = path("%s/resumed%s", "");
    stop_and_continue(dir, &j, stop, "series v1", "series v1", 0, &seen,
                      &first);
    CHECK(first == stop, "continued at unit %llu, %llu expected",
          (unsigned long long)first, (unsigned long long)stop);
    CHECK(same_dataset(ref, dir, 0, 7), "continued: not the dataset of an "
          "encode without a stop");
    /* Another identity: from the start (steps below 5 read again). */
    dir = path("%s/other-id%s", "");
    stop_and_continue(dir, &j, stop, "series v1", "series v2", 5, &seen,
                      &first);
    CHECK(first == 0 && seen > 0, "another identity continued (unit %llu)",
          (unsigned long long)first);
    CHECK(same_dataset(ref, dir, 0, 7), "started over: not the dataset");
    /* Levels beside one pass, stopped at step 5, continued. */
    struct job jl = base;
    jl.levels = 2;
    dir = path("%s/resumed-lv%s", "");
    stop_and_continue(dir, &jl, 5, "series", "series", 0, &seen, &first);
    CHECK(first == 5, "levels: continued at unit %llu, 5 expected",
          (unsigned long long)first);
    CHECK(same_dataset(path("%s/lv-pushed%s", ""), dir, 2, 7),
          "levels, continued: not the dataset of an encode without a stop");
}

/* The modification time of a file, in nanoseconds (0: none). */
static long long mtime_ns(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0
               ? (long long)st.st_mtim.tv_sec * 1000000000LL +
                     st.st_mtim.tv_nsec
               : 0;
}

/* An encode with levels stopped at the end of level 1 (level 0 finished,
 * level 2 not), beside level 0's one pass and after it: the next encode
 * of the job keeps level 0 (its shard is not written again) and level 1,
 * makes level 2 alone, and gives the dataset of an encode without a stop;
 * one asking for fewer levels reads nothing, and its manifests name
 * them. */
static void test_level0_kept(void)
{
    struct tvpal_plan one, some;
    struct job j = base;
    j.levels = 2;
    for (int after = 0; after < 2; after++) {
        j.limit = after ? limit_below(&j, 1, 0.25, &one, &some) : 0;
        struct tvpal_diag d = {{0}};
        struct tvpal_encoder *e = NULL;
        char *dir = path(after ? "%s/kept-after%s" : "%s/kept-inline%s", "");
        char partial[600], shard[700], mk[700], lv[700];
        snprintf(partial, sizeof partial, "%s.partial", dir);
        snprintf(shard, sizeof shard, "%s/node-0/axis-z.tvps", partial);
        snprintf(mk, sizeof mk, "%s/levels.job", partial);
        snprintf(lv, sizeof lv, "%s/level-1/manifest.txt", partial);
        struct src s = plain(TVPAL_FLOAT32);
        s.stop_level = 1;
        struct tvpal_source so = source_of(&s, 1, "series");
        REQUIRE(open_job(&e, dir, &j, &d) == 0, "%s", d.msg);
        int rc = tvpal_encoder_encode(e, &so, &d);
        tvpal_encoder_abort(e);
        CHECK(rc == TVPAL_E_CANCELED && strstr(d.msg, "after level 1 of 2"),
              "stopped after level 1 (after %d): %s %s", after,
              tvpal_strerror(rc), d.msg);
        snprintf(lv + strlen(partial), sizeof lv - strlen(partial),
                 "/level-2");
        CHECK(!exists(dir) && exists(mk) && exists(shard) && !exists(lv),
              "after the stop at level 1 (after %d): DIR %d, marker %d, "
              "level 0 %d, level 2 %d", after, exists(dir), exists(mk),
              exists(shard), exists(lv));
        snprintf(lv + strlen(partial), sizeof lv - strlen(partial),
                 "/level-1/manifest.txt");
        CHECK(exists(lv), "level 1 not complete after the stop");
        const long long t0 = mtime_ns(shard);
        s = plain(TVPAL_FLOAT32);
        so = source_of(&s, 1, "series");
        rc = pull_all(dir, &j, &so, &d);
        CHECK(rc == 0 && same_dataset(path("%s/lv-pushed%s", ""), dir, 2, 7),
              "continued after level 1 (after %d): %s %s", after,
              tvpal_strerror(rc), d.msg);
        snprintf(shard, sizeof shard, "%s/node-0/axis-z.tvps", dir);
        CHECK(s.first.resumed && s.first.level0_kept &&
                  s.first.levels_before == 2 && s.first.unit == s.first.units &&
                  mtime_ns(shard) == t0 && s.reads > 0,
              "continued after level 1 (after %d): resumed %d, level 0 kept "
              "%d, levels before %u, unit %llu of %llu, shard rewritten %d, "
              "%u reads", after, s.first.resumed, s.first.level0_kept,
              s.first.levels_before, (unsigned long long)s.first.unit,
              (unsigned long long)s.first.units, mtime_ns(shard) != t0,
              s.reads);
    }
    /* Fewer levels than the stopped encode asked for: nothing to read. */
    j.limit = 0;
    struct tvpal_diag d = {{0}};
    struct tvpal_encoder *e = NULL;
    char *dir = path("%s/kept-fewer%s", "");
    struct src s = plain(TVPAL_FLOAT32);
    s.stop_level = 1;
    struct tvpal_source so = source_of(&s, 0, "series");
    REQUIRE(open_job(&e, dir, &j, &d) == 0, "%s", d.msg);
    CHECK(tvpal_encoder_encode(e, &so, &d) == TVPAL_E_CANCELED, "%s", d.msg);
    tvpal_encoder_abort(e);
    j.levels = 1;
    s = plain(TVPAL_FLOAT32);
    so = source_of(&s, 0, "series");
    int rc = pull_all(dir, &j, &so, &d);
    char cmd[800];
    snprintf(cmd, sizeof cmd, "test \"$(grep -c '^levels = 1$' %s/manifest.txt "
             "%s/node-0/manifest.txt | grep -c ':1$')\" = 2", dir, dir);
    CHECK(rc == 0 && s.reads == 0 && s.first.level0_kept &&
              s.first.levels_before == 2 && system(cmd) == 0 &&
              !exists(path("%s/kept-fewer%s", "/level-2")),
          "continued with 1 level after 2: %s %s, %u reads, levels before "
          "%u", tvpal_strerror(rc), d.msg, s.reads, s.first.levels_before);
    struct tvpal_reader *r = NULL;
    rc = tvpal_reader_open(&r, dir, &d);
    CHECK(rc == 0, "the dataset with 1 level kept does not open: %s", d.msg);
    tvpal_reader_close(r);
}

/* A partial output that is not continued says so at the first progress
 * call: of another identity, or with a shard damaged since its checkpoint
 * (which started over gives the dataset all the same). */
static void test_started_over(void)
{
    struct tvpal_plan one, some;
    struct job j = base;
    j.limit = limit_below(&j, 1, 0.75, &one, &some);
    const char *ref = path("%s/conc-passes%s", "");
    for (int damaged = 0; damaged < 2; damaged++) {
        char *dir = path(damaged ? "%s/damaged%s" : "%s/other-job%s", "");
        struct tvpal_diag d = {{0}};
        struct tvpal_encoder *e = NULL;
        struct src s = plain(TVPAL_FLOAT32);
        s.stop_unit = T + 5;
        struct tvpal_source so = source_of(&s, 1, "series v1");
        REQUIRE(open_job(&e, dir, &j, &d) == 0, "%s", d.msg);
        CHECK(tvpal_encoder_encode(e, &so, &d) == TVPAL_E_CANCELED, "%s",
              d.msg);
        tvpal_encoder_abort(e);
        char cmd[700];
        snprintf(cmd, sizeof cmd, "truncate -s 100 %s.partial/node-0/"
                 "axis-z.tvps", dir);
        CHECK(!damaged || system(cmd) == 0, "%s", cmd);
        s = plain(TVPAL_FLOAT32);
        so = source_of(&s, 1, damaged ? "series v1" : "series v2");
        int rc = pull_all(dir, &j, &so, &d);
        CHECK(rc == 0 && s.first.started_over && !s.first.resumed &&
                  s.first.unit == 0 && same_dataset(ref, dir, 0, 7),
              "%s: %s %s, started over %d, resumed %d, unit %llu",
              damaged ? "a damaged shard" : "another identity",
              tvpal_strerror(rc), d.msg, s.first.started_over,
              s.first.resumed, (unsigned long long)s.first.unit);
    }
}

/* The statistics of an encode before its finish, and the progress
 * parameter's range. */
static void test_stats(void)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_encoder *e = NULL;
    struct tvpal_stats st;
    REQUIRE(open_job(&e, path("%s/stats%s", ""), &base, &d) == 0, "%s",
            d.msg);
    CHECK(tvpal_encoder_stats(e, &st) == TVPAL_E_INVAL, "stats before the "
          "encode");
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_PROGRESS, 0, &d) ==
              TVPAL_E_INVAL &&
              tvpal_encoder_set(e, TVPAL_PARAM_PROGRESS, 3601, &d) ==
                  TVPAL_E_INVAL &&
              tvpal_encoder_set(e, TVPAL_PARAM_PROGRESS, 0.001, &d) == 0,
          "TVPAL_PARAM_PROGRESS's range: %s", d.msg);
    struct src s = plain(TVPAL_FLOAT32);
    struct tvpal_source so = source_of(&s, 1, NULL);
    int rc = tvpal_encoder_encode(e, &so, &d);
    REQUIRE(rc == 0, "%s", d.msg);
    float lo = INFINITY, hi = -INFINITY;
    uint64_t nan = 0;
    for (unsigned t = 0; t < T; t++)
        for (unsigned i = 0; i < NV; i++) {
            const float v = series[t][i];
            if (isnan(v)) {
                nan++;
                continue;
            }
            lo = v < lo ? v : lo;
            hi = v > hi ? v : hi;
        }
    CHECK(tvpal_encoder_stats(e, &st) == 0 &&
              st.values == (uint64_t)T * NV && st.missing == nan &&
              st.value_min == lo && st.value_max == hi && st.replaced == 0 &&
              st.dropped == 0 && st.beyond_1e30 == 0 &&
              st.p_low >= lo - 1e-3 * (hi - lo) &&
              st.p_high <= hi + 1e-3 * (hi - lo) && st.p_low < st.p_high,
          "stats: %llu values, %llu missing (%llu), range %g .. %g (%g .. "
          "%g), percentiles %g .. %g, %llu dropped",
          (unsigned long long)st.values, (unsigned long long)st.missing,
          (unsigned long long)nan, st.value_min, st.value_max, lo, hi,
          st.p_low, st.p_high, (unsigned long long)st.dropped);
    CHECK(tvpal_encoder_finish(e, &d) == 0, "%s", d.msg);
}

/* Provenance: recorded in the manifest and read back; refused when it
 * cannot be. */
static void test_provenance(void)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_encoder *e = NULL;
    const char *files[T] = {"/data/s0.f32", "/data/s1.f32", "/data/s2.f32",
                            "/data/s3.f32", "/data/s4.f32", "/data/s5.f32",
                            "/data/s6.f32", "/data/s7.f32", "/data/s8.f32"};
    struct tvpal_provenance p = {.encoder = "mysim 2.1", .format = "netcdf",
                                 .var = "theta", .sources = files,
                                 .nsources = 1, .single_file = 1};
    REQUIRE(open_job(&e, path("%s/prov%s", ""), &base, &d) == 0, "%s", d.msg);
    const struct tvpal_provenance bad[] = {
        {.format = "grib"}, {.var = "a\nb"},
        {.sources = files, .nsources = 2},
        {.sources = files, .nsources = T, .series = 1},
        {.sources = files, .nsources = 2, .single_file = 1}};
    for (unsigned i = 0; i < sizeof bad / sizeof *bad; i++)
        CHECK(tvpal_encoder_set_provenance(e, &bad[i], &d) == TVPAL_E_INVAL &&
                  d.msg[0], "provenance %u accepted", i);
    CHECK(tvpal_encoder_set_provenance(e, &p, &d) == 0, "%s", d.msg);
    struct src s = plain(TVPAL_FLOAT32);
    struct tvpal_source so = source_of(&s, 1, NULL);
    CHECK(tvpal_encoder_encode(e, &so, &d) == 0, "%s", d.msg);
    CHECK(tvpal_encoder_set_provenance(e, &p, &d) == TVPAL_E_INVAL,
          "provenance set after the encode");
    CHECK(tvpal_encoder_finish(e, &d) == 0, "%s", d.msg);
    struct tvpal_reader *r = NULL;
    REQUIRE(tvpal_reader_open(&r, path("%s/prov%s", ""), &d) == 0, "%s",
            d.msg);
    const struct tvpal_info *in = tvpal_reader_info(r);
    CHECK(!strcmp(in->encoder, "mysim 2.1") &&
              !strcmp(in->source_format, "netcdf") &&
              !strcmp(in->source_var, "theta") && in->nsources == 1 &&
              !strcmp(in->sources[0], files[0]) && in->source_single_file,
          "read back: encoder '%s' format '%s' var '%s' %u sources",
          in->encoder, in->source_format, in->source_var, in->nsources);
    tvpal_reader_close(r);
    /* Raw, a file per step, uint16 big-endian: the manifest says so. */
    p = (struct tvpal_provenance){.format = "raw", .sources = files,
                                  .nsources = T};
    s = plain(TVPAL_UINT16);
    s.big = 1;
    so = source_of(&s, 0, NULL);
    struct job j = base;
    j.axes = TVPAL_AXIS_Z;
    REQUIRE(open_job(&e, path("%s/prov-raw%s", ""), &j, &d) == 0, "%s",
            d.msg);
    CHECK(tvpal_encoder_set_provenance(e, &p, &d) == 0 &&
              tvpal_encoder_encode(e, &so, &d) == 0 &&
              tvpal_encoder_finish(e, &d) == 0, "raw: %s", d.msg);
    REQUIRE(tvpal_reader_open(&r, path("%s/prov-raw%s", ""), &d) == 0, "%s",
            d.msg);
    in = tvpal_reader_info(r);
    CHECK(!strcmp(in->source_format, "raw") &&
              !strcmp(in->source_type, "u16") && in->source_big_endian &&
              in->nsources == T && !in->source_single_file &&
              !strncmp(in->encoder, "libtvpal ", 9),
          "raw read back: format '%s' type '%s' big %d, %u sources",
          in->source_format, in->source_type, in->source_big_endian,
          in->nsources);
    tvpal_reader_close(r);
}

static void test_failures(void)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_encoder *e = NULL;
    /* A read that fails: its code and words; kept with an identity. */
    for (int id = 0; id < 2; id++) {
        struct src s = plain(TVPAL_FLOAT32);
        s.fail_step = 6;
        struct tvpal_source so = source_of(&s, id, id ? "series" : NULL);
        REQUIRE(open_job(&e, path("%s/readfail%s", ""), &base, &d) == 0,
                "%s", d.msg);
        int rc = tvpal_encoder_encode(e, &so, &d);
        CHECK(rc == TVPAL_E_READ && strstr(d.msg, "series.raw: step 6"),
              "a failed read: %s %s", tvpal_strerror(rc), d.msg);
        tvpal_encoder_abort(e);
        CHECK(!exists(path("%s/readfail%s", "")) &&
                  exists(path("%s/readfail%s", ".partial")) == id &&
                  !exists(path("%s/readfail%s", ".partial.lock")),
              "a failed read (identity %d): DIR.partial %s", id,
              id ? "removed" : "kept");
    }
    /* A value refused: named; nothing kept even with an identity. */
    struct src s = plain(TVPAL_FLOAT32);
    s.inf_step = 3;
    struct tvpal_source so = source_of(&s, 1, "series");
    REQUIRE(open_job(&e, path("%s/inf%s", ""), &base, &d) == 0, "%s", d.msg);
    int rc = tvpal_encoder_encode(e, &so, &d);
    CHECK(rc == TVPAL_E_NAN && strstr(d.msg, "step 3") &&
              strstr(d.msg, "(5,6,7)"), "an infinity: %s %s",
          tvpal_strerror(rc), d.msg);
    CHECK(tvpal_encoder_push(e, series[0], TVPAL_FLOAT32, NV, NULL, &d) ==
              TVPAL_E_INVAL, "a push after a failed encode");
    tvpal_encoder_abort(e);
    CHECK(!exists(path("%s/inf%s", ".partial")) &&
              !exists(path("%s/inf%s", "")), "an infinity left output");
    /* Every value missing, pulled or pushed: refused (where level 0 is
     * finished: at the end of the encode, or at finish), saying so (it
     * was a "malformed manifest" of the library's own), nothing left. */
    s = plain(TVPAL_FLOAT32);
    s.all_nan = 1;
    so = source_of(&s, 1, "series");
    REQUIRE(open_job(&e, path("%s/nan%s", ""), &base, &d) == 0, "%s", d.msg);
    rc = tvpal_encoder_encode(e, &so, &d);
    tvpal_encoder_abort(e);
    CHECK(rc == TVPAL_E_INVAL && strstr(d.msg, "every value of the 9 steps "
                                        "is missing"),
          "all missing, encode: %s %s", tvpal_strerror(rc), d.msg);
    CHECK(!exists(path("%s/nan%s", ".partial")) &&
              !exists(path("%s/nan%s", "")), "all missing left output");
    static float nan_step[NV];
    for (unsigned i = 0; i < NV; i++)
        nan_step[i] = NAN;
    REQUIRE(open_job(&e, path("%s/nan-push%s", ""), &base, &d) == 0, "%s",
            d.msg);
    rc = 0;
    for (unsigned t = 0; t < T && rc == 0; t++)
        rc = tvpal_encoder_push(e, nan_step, TVPAL_FLOAT32, NV, NULL, &d);
    rc = rc == 0 ? tvpal_encoder_finish(e, &d) : rc;
    CHECK(rc == TVPAL_E_INVAL && strstr(d.msg, "is missing"),
          "all missing, pushed: %s %s", tvpal_strerror(rc), d.msg);
    CHECK(!exists(path("%s/nan%s", "")) &&
              !exists(path("%s/nan%s", ".partial")) &&
              !exists(path("%s/nan-push%s", "")) &&
              !exists(path("%s/nan-push%s", ".partial")),
          "all missing left output");
    /* A limit below the smallest: refused, with the smallest, which
     * works. */
    struct job j = base;
    j.limit = 1 << 20;
    so = source_of(&s, 1, NULL);
    s = plain(TVPAL_FLOAT32);
    struct tvpal_plan p;
    REQUIRE(open_job(&e, path("%s/small%s", ""), &j, &d) == 0, "%s", d.msg);
    rc = tvpal_encoder_plan(e, &so, &p, &d);
    CHECK(rc == TVPAL_E_RANGE && p.min_limit > j.limit &&
              strstr(d.msg, "one slice per pass needs"),
          "1 MiB: %s %s", tvpal_strerror(rc), d.msg);
    rc = tvpal_encoder_encode(e, &so, &d);
    CHECK(rc == TVPAL_E_RANGE, "encode under 1 MiB: %s", tvpal_strerror(rc));
    tvpal_encoder_abort(e);
    CHECK(!exists(path("%s/small%s", ".partial")), "1 MiB left output");
    j.limit = p.min_limit;
    rc = pull_all(path("%s/small%s", ""), &j, &so, &d);
    CHECK(rc == 0 && same_dataset(path("%s/pushed%s", ""),
                                  path("%s/small%s", ""), 0, 7),
          "the smallest limit: %s %s", tvpal_strerror(rc), d.msg);
    /* Refused calls. */
    REQUIRE(open_job(&e, path("%s/twice%s", ""), &base, &d) == 0, "%s",
            d.msg);
    so = source_of(&s, 0, NULL);
    so.read = NULL;
    CHECK(tvpal_encoder_encode(e, &so, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "read"), "a source without read: %s", d.msg);
    so = source_of(&s, 0, NULL);
    so.type = (enum tvpal_scalar)9;
    CHECK(tvpal_encoder_encode(e, &so, &d) == TVPAL_E_INVAL,
          "a source of type 9");
    so = source_of(&s, 0, NULL);
    CHECK(tvpal_encoder_encode(e, &so, &d) == 0, "encode: %s", d.msg);
    CHECK(tvpal_encoder_encode(e, &so, &d) == TVPAL_E_INVAL,
          "a second encode");
    CHECK(tvpal_encoder_push(e, series[0], TVPAL_FLOAT32, NV, NULL, &d) ==
              TVPAL_E_INVAL, "a push after an encode");
    CHECK(tvpal_encoder_finish(e, &d) == 0, "finish after the refusals: %s",
          d.msg);
    REQUIRE(open_job(&e, path("%s/pushfirst%s", ""), &base, &d) == 0, "%s",
            d.msg);
    CHECK(tvpal_encoder_push(e, series[0], TVPAL_FLOAT32, NV, NULL, &d) == 0,
          "push: %s", d.msg);
    CHECK(tvpal_encoder_encode(e, &so, &d) == TVPAL_E_INVAL,
          "an encode after a push");
    tvpal_encoder_abort(e);
}

/* ----------------------------------------------------------- ranks */

#define RANKS 3  /* NZ = 11: slabs of 4, 4, 3 planes */

struct rank_run {
    struct tt_member m;
    const char *dir;
    struct job j;
    int concurrent;
    int fail_step;           /* this rank's read of it fails (-1: none) */
    const char *shard_pat;   /* tvpal_encoder_set_shard_dir's, or NULL */
    const char *identity;    /* the source's, or NULL */
    unsigned stop_level;     /* rank 0 stops at this level's end (0: no) */
    struct tvpal_progress first; /* what its first progress call saw */
    int encode_rc, finish_rc;
    struct tvpal_diag d;
};

/* One rank: its encoder on the collective, the whole source, finish (or
 * abort when its encode failed). */
static void *rank_encode(void *arg)
{
    struct rank_run *r = arg;
    struct tvpal_encoder *e = NULL;
    const struct tvpal_collective c = {r->m.rank, RANKS, &r->m, tt_gather,
                                       tt_bcast, NULL};
    uint32_t z0, nz;
    tvpal_slab(NZ, RANKS, (uint32_t)r->m.rank, &z0, &nz);
    r->encode_rc = r->finish_rc = TVPAL_E_INVAL;
    if (open_job(&e, r->dir, &r->j, &r->d) < 0)
        return NULL;
    if (tvpal_encoder_set_collective(e, &c, z0, nz, &r->d) < 0 ||
        (r->shard_pat &&
         tvpal_encoder_set_shard_dir(e, r->shard_pat, &r->d) < 0)) {
        tvpal_encoder_abort(e);
        return NULL;
    }
    struct src s = plain(TVPAL_FLOAT32);
    s.fail_step = r->fail_step;
    s.stop_level = r->m.rank == 0 ? r->stop_level : 0;
    const struct tvpal_source so = source_of(&s, r->concurrent, r->identity);
    r->encode_rc = tvpal_encoder_encode(e, &so, &r->d);
    r->first = s.first;
    if (r->encode_rc < 0) {
        tvpal_encoder_abort(e);
        return NULL;
    }
    r->finish_rc = tvpal_encoder_finish(e, &r->d);
    return NULL;
}

/* RANKS ranks as runs[] say (their member set here). */
static void start_ranks(struct rank_run *runs)
{
    struct tt_group g;
    tt_group_init(&g, RANKS);
    pthread_t th[RANKS];
    for (int k = 0; k < RANKS; k++) {
        runs[k].m = (struct tt_member){&g, k};
        pthread_create(&th[k], NULL, rank_encode, &runs[k]);
    }
    for (int k = 0; k < RANKS; k++)
        pthread_join(th[k], NULL);
    pthread_barrier_destroy(&g.bar);
}

/* RANKS ranks of job j into dir; rank `who` fails its reads of step 4. */
static void run_ranks(struct rank_run *runs, const char *dir,
                      const struct job *j, int concurrent, int who)
{
    for (int k = 0; k < RANKS; k++)
        runs[k] = (struct rank_run){.dir = dir, .j = *j,
                                    .concurrent = concurrent,
                                    .fail_step = k == who ? 4 : -1};
    start_ranks(runs);
}

static void test_ranks(void)
{
    struct tvpal_diag d = {{0}};
    struct job j = base;
    j.levels = 2;
    j.nodes = RANKS;
    char one[600];  /* path()'s buffers turn over */
    snprintf(one, sizeof one, "%s", path("%s/ranks-one%s", ""));
    int rc = push_all(one, &j, TVPAL_FLOAT32, &d);
    REQUIRE(rc == 0, "push with %d nodes: %s", RANKS, d.msg);
    struct rank_run runs[RANKS];
    struct tvpal_plan p1, p2;
    struct job jr = j;
    jr.nodes = 0;
    for (int conc = 0; conc < 2; conc++) {
        /* Under a limit that holds level 0 and then the levels, not the
         * levels beside level 0 (a rank's passes are per axis anyway). */
        struct job jl = base;
        jl.levels = 2;
        jr.limit = conc ? 0 : limit_below(&jl, 0, 0.25, &p1, &p2);
        char *dir = path(conc ? "%s/ranks-c%s" : "%s/ranks-limit%s", "");
        run_ranks(runs, dir, &jr, conc, -1);
        for (int k = 0; k < RANKS; k++)
            CHECK(runs[k].encode_rc == 0 && runs[k].finish_rc == 0,
                  "rank %d (concurrent %d, limit %llu): %s %s", k, conc,
                  (unsigned long long)jr.limit,
                  tvpal_strerror(runs[k].encode_rc ? runs[k].encode_rc
                                                   : runs[k].finish_rc),
                  runs[k].d.msg);
        char cmd[1300];
        snprintf(cmd, sizeof cmd, "diff -r %s %s > /dev/null", one, dir);
        CHECK(system(cmd) == 0, "%d ranks, axes xyz, 2 levels (concurrent "
              "%d, limit %llu): not one process's --nodes %d dataset",
              RANKS, conc, (unsigned long long)jr.limit, RANKS);
    }
    /* A rank's read fails: its encode says so, and every rank's encode or
     * finish fails with its words (with levels, the others' encodes, in
     * level 0's finish before the levels), nothing is left. */
    char *dir = path("%s/ranks-fail%s", "");
    jr.limit = 0;
    run_ranks(runs, dir, &jr, 1, 1);
    CHECK(runs[1].encode_rc == TVPAL_E_READ, "rank 1: %s %s",
          tvpal_strerror(runs[1].encode_rc), runs[1].d.msg);
    for (int k = 0; k < RANKS; k += 2)
        CHECK((runs[k].encode_rc == TVPAL_E_READ ||
               (runs[k].encode_rc == 0 && runs[k].finish_rc == TVPAL_E_READ)) &&
                  strstr(runs[k].d.msg, "rank 1: series.raw: step 4"),
              "rank %d after rank 1's failed read: %s %s", k,
              tvpal_strerror(runs[k].finish_rc), runs[k].d.msg);
    CHECK(!exists(dir) && !exists(path("%s/ranks-fail%s", ".partial")),
          "a failed rank left output");
    /* Node directories of their own (node-local disks): each rank's node
     * directory at the pattern, the one process's node-R byte for byte;
     * DIR holds the manifest and the levels. */
    dir = path("%s/ranks-sd%s", "");
    char pat[600];
    snprintf(pat, sizeof pat, "%s/local%%r/ds", W);
    for (int k = 0; k < RANKS; k++)
        runs[k] = (struct rank_run){.dir = dir, .j = jr, .concurrent = 1,
                                    .fail_step = -1, .shard_pat = pat};
    start_ranks(runs);
    int same = 1;
    for (int k = 0; k < RANKS; k++) {
        char cmd[1400];
        snprintf(cmd, sizeof cmd, "diff -r %s/node-%d %s/local%d/ds > "
                 "/dev/null && test ! -e %s/local%d/ds.partial", one, k, W, k,
                 W, k);
        same &= runs[k].encode_rc == 0 && runs[k].finish_rc == 0 &&
                system(cmd) == 0;
    }
    char cmd[1400];
    snprintf(cmd, sizeof cmd, "cmp -s %s/manifest.txt %s/manifest.txt && "
             "diff -r %s/level-1 %s/level-1 > /dev/null && test ! -e "
             "%s/node-0", one, dir, one, dir, dir);
    CHECK(same && system(cmd) == 0, "shard directories: not the one "
          "process's nodes, or DIR not its manifest and levels: %s %s",
          tvpal_strerror(runs[0].finish_rc), runs[0].d.msg);
    /* Rank 0 stops at the end of level 1: every rank fails, level 0 and
     * level 1 stay; the ranks' next encode keeps them on every rank,
     * makes level 2 alone and gives the one process's dataset. */
    char kdir[600];  /* path()'s buffers turn over */
    snprintf(kdir, sizeof kdir, "%s", path("%s/ranks-kept%s", ""));
    dir = kdir;
    for (int k = 0; k < RANKS; k++)
        runs[k] = (struct rank_run){.dir = dir, .j = jr, .concurrent = 1,
                                    .fail_step = -1, .identity = "series",
                                    .stop_level = 1};
    start_ranks(runs);
    int failed = 1;
    for (int k = 0; k < RANKS; k++)
        failed &= runs[k].encode_rc < 0 || runs[k].finish_rc < 0;
    CHECK(failed && exists(path("%s/ranks-kept%s", ".partial/levels.job")) &&
              exists(path("%s/ranks-kept%s",
                          ".partial/level-1/manifest.txt")),
          "stopped at level 1 on rank 0: every rank fails, level 0 and 1 "
          "stay (%s %s)", tvpal_strerror(runs[0].encode_rc), runs[0].d.msg);
    for (int k = 0; k < RANKS; k++)
        runs[k] = (struct rank_run){.dir = dir, .j = jr, .concurrent = 1,
                                    .fail_step = -1, .identity = "series"};
    start_ranks(runs);
    int kept = 1;
    for (int k = 0; k < RANKS; k++)
        kept &= runs[k].encode_rc == 0 && runs[k].finish_rc == 0 &&
                runs[k].first.level0_kept && runs[k].first.resumed;
    snprintf(cmd, sizeof cmd, "diff -r %s %s > /dev/null", one, dir);
    CHECK(kept && system(cmd) == 0, "continued on %d ranks after level 1: "
          "level 0 kept on every rank %d, the one process's dataset: %s %s",
          RANKS, kept, tvpal_strerror(runs[0].finish_rc), runs[0].d.msg);
    /* Refused: no %r; and without a collective, at the encode. */
    struct tvpal_encoder *e = NULL;
    REQUIRE(open_job(&e, path("%s/sd-one%s", ""), &base, &d) == 0, "%s",
            d.msg);
    CHECK(tvpal_encoder_set_shard_dir(e, "/tmp/node", &d) == TVPAL_E_INVAL,
          "a shard directory without %%r");
    CHECK(tvpal_encoder_set_shard_dir(e, pat, &d) == 0, "%s", d.msg);
    struct src s = plain(TVPAL_FLOAT32);
    const struct tvpal_source so = source_of(&s, 1, NULL);
    rc = tvpal_encoder_encode(e, &so, &d);
    tvpal_encoder_abort(e);
    CHECK(rc == TVPAL_E_INVAL && strstr(d.msg, "without a collective") &&
              !exists(path("%s/sd-one%s", ".partial")),
          "a shard directory in one process: %s %s", tvpal_strerror(rc),
          d.msg);
}

int main(void)
{
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf %s && mkdir -p %s", W, W);
    REQUIRE(system(cmd) == 0, "cannot make %s", W);
    make_series();
    test_same_as_pushed();
    test_group_auto();
    test_integers();
    test_levels();
    test_stop_and_continue();
    test_level0_kept();
    test_started_over();
    test_stats();
    test_provenance();
    test_ranks();
    test_failures();
    int rc = tt_done("test-api-source");
    if (rc == 0) {
        snprintf(cmd, sizeof cmd, "rm -rf %s", W);
        if (system(cmd) != 0)
            return 99;
    }
    return rc;
}
