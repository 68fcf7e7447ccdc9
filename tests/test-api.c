/* test-api: the contracts of libtvpal's public API (lib/tvpal.h), through
 * the shared library as a user's program links it, using tvpal.h only.
 *  - parameters out of range, set after the first push, wrong type, NULL
 *    data: TVPAL_E_INVAL with a diag, and nothing changed;
 *  - the same values pushed as float32 contiguous and as float64 through
 *    strides (a z-y-x transposed array) give byte-identical shards;
 *  - the reader gives back the grid, times and units, and each step
 *    within the codec's error (PSNR floor); a step, axis or level out of
 *    range is refused;
 *  - nothing that looks complete after: abort halfway, finish with steps
 *    missing, a refused value (an infinity: the voxel named), an output
 *    that exists (TVPAL_E_EXIST, unless forced over a dataset), a lock
 *    another encoder holds, a memory limit too small;
 *  - ranks (threads here, with a collective of shared memory) that each
 *    push their z-slab write the shards and manifest one process writes
 *    with TVPAL_PARAM_NODES, byte for byte; a wrong slab, an abort
 *    halfway, a refused value on one rank, an output that exists: every
 *    rank fails with the failing rank's message, nothing left at DIR;
 *  - a dataset's description, sizes and verification: the manifest's
 *    provenance and histogram, index bytes by the window schedule and disk
 *    bytes by a walk of the tree, each checked independently; a damaged
 *    record, a truncated shard and a missing level each found and named,
 *    a reader of the manifest alone opening what the full open refuses. */
#define _GNU_SOURCE   /* nftw */
#include "tvpal.h"
#include "tvpal_test.h"
#include "tt_ranks.h"

#include <ftw.h>
#include <pthread.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#define NX 9
#define NY 7
#define NZ 6
#define T 7
#define NV (NX * NY * NZ)

static const char *W = "tests/work/test-api";

static int exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0;
}

static char *path(const char *fmt, const char *a)
{
    static char buf[8][512];
    static int k;
    char *b = buf[k++ % 8];
    snprintf(b, 512, fmt, W, a);
    return b;
}

static float value(unsigned t, unsigned x, unsigned y, unsigned z)
{
    return (float)(10 + sin(0.7 * x + 0.3 * t) * cos(0.5 * y) + 0.25 * z +
                   (x == t % NX) * 4.0);
}

/* Step t of the series on a grid of NX x NY x nz. */
static void fill_nz(float *v, unsigned t, unsigned nz)
{
    for (unsigned z = 0; z < nz; z++)
        for (unsigned y = 0; y < NY; y++)
            for (unsigned x = 0; x < NX; x++)
                v[x + NX * (y + NY * z)] = value(t, x, y, z);
}

static void fill(float *v, unsigned t)
{
    fill_nz(v, t, NZ);
}

/* The bytes of a file into a malloc'ed buffer; *n its size. */
static unsigned char *slurp(const char *p, size_t *n)
{
    FILE *f = fopen(p, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *b = malloc((size_t)len + 1);
    if (b && fread(b, 1, (size_t)len, f) != (size_t)len) {
        free(b);
        b = NULL;
    }
    fclose(f);
    *n = (size_t)len;
    return b;
}

static const uint32_t dims[3] = {NX, NY, NZ};

/* Opens the encoder of the series (window 3, axes x and z, a grid, times
 * and units) into dir: 0, or a code with e released. */
static int open_series(struct tvpal_encoder **out, const char *dir,
                       unsigned window, struct tvpal_diag *d)
{
    struct tvpal_encoder *e = NULL;
    int rc = tvpal_encoder_open(&e, dir, dims, T, d);
    *out = NULL;
    if (rc < 0)
        return rc;
    double times[T];
    for (unsigned t = 0; t < T; t++)
        times[t] = 1.5 * t;
    const double sp[3] = {0.5, 1, 2}, or[3] = {-1, 0, 3};
    if ((rc = tvpal_encoder_set(e, TVPAL_PARAM_WINDOW, window, d)) < 0 ||
        (rc = tvpal_encoder_set(e, TVPAL_PARAM_AXES,
                                TVPAL_AXIS_X | TVPAL_AXIS_Z, d)) < 0 ||
        (rc = tvpal_encoder_set(e, TVPAL_PARAM_THREADS, 2, d)) < 0 ||
        (rc = tvpal_encoder_set_grid(e, sp, or, d)) < 0 ||
        (rc = tvpal_encoder_set_times(e, times, "hours", d)) < 0 ||
        (rc = tvpal_encoder_set_units(e, "K", d)) < 0) {
        tvpal_encoder_abort(e);
        return rc;
    }
    *out = e;
    return 0;
}

/* Encodes the series into dir: float32 contiguous, or float64 from an
 * array stored z fastest (strides). */
static int encode(const char *dir, int f64, struct tvpal_diag *d)
{
    struct tvpal_encoder *e = NULL;
    int rc = open_series(&e, dir, 3, d);
    if (rc < 0)
        return rc;
    float v[NV];
    double w[NV];
    const ptrdiff_t zfast[3] = {NY * NZ, NZ, 1};
    for (unsigned t = 0; t < T && rc == 0; t++) {
        fill(v, t);
        for (unsigned z = 0; z < NZ; z++)
            for (unsigned y = 0; y < NY; y++)
                for (unsigned x = 0; x < NX; x++)
                    w[z + NZ * (y + NY * x)] = v[x + NX * (y + NY * z)];
        rc = f64 ? tvpal_encoder_push(e, w, TVPAL_FLOAT64, NV, zfast, d)
                 : tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, d);
    }
    if (rc < 0) {
        tvpal_encoder_abort(e);
        return rc;
    }
    return tvpal_encoder_finish(e, d);
}

static void test_params(void)
{
    struct tvpal_encoder *e = NULL;
    struct tvpal_diag d = {{0}};
    const uint32_t zero[3] = {NX, 0, NZ};
    CHECK(tvpal_encoder_open(&e, path("%s/p%s", ""), zero, T, &d) ==
              TVPAL_E_INVAL && e == NULL && strstr(d.msg, "dims[1]"),
          "dims 0: %s", d.msg);
    CHECK(tvpal_encoder_open(&e, path("%s/p%s", ""), dims, 0, &d) ==
              TVPAL_E_INVAL, "steps 0 taken");
    REQUIRE(tvpal_encoder_open(&e, path("%s/p%s", ""), dims, T, &d) == 0,
            "open: %s", d.msg);
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_WINDOW, 17, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "window"), "window 17: %s", d.msg);
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_WINDOW, 2.5, &d) == TVPAL_E_INVAL,
          "window 2.5 taken");
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_SCHEDULE, 2, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "schedule"), "schedule 2: %s", d.msg);
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_GROUP, -1, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "group") && strstr(d.msg, "0 (auto)..1024"),
          "group -1: %s", d.msg);
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_GROUP, TVPAL_GROUP_AUTO, &d) == 0 &&
              tvpal_encoder_set(e, TVPAL_PARAM_GROUP, 1, &d) == 0,
          "group auto, then 1: %s", d.msg);
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_GROUP, 1025, &d) ==
              TVPAL_E_INVAL, "group 1025 taken");
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_GROUP, 2.5, &d) == TVPAL_E_INVAL,
          "group 2.5 taken");
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_AXES, 8, &d) == TVPAL_E_INVAL,
          "axes 8 taken");
    CHECK(tvpal_encoder_set(e, (enum tvpal_param)99, 1, &d) ==
              TVPAL_E_INVAL, "parameter 99 taken");
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_INDEX_CODING, 2, &d) ==
              TVPAL_E_INVAL && strstr(d.msg, "index_coding"),
          "index coding 2: %s", d.msg);
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_INDEX_LEVEL, 20, &d) ==
              TVPAL_E_INVAL && strstr(d.msg, "1..19"), "level 20: %s", d.msg);
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_INDEX_LEVEL, 0, &d) ==
              TVPAL_E_INVAL, "level 0 taken");
    const double bad_sp[3] = {1, 0, 1}, o[3] = {0, 0, 0};
    CHECK(tvpal_encoder_set_grid(e, bad_sp, o, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "spacing[1]"), "spacing 0: %s", d.msg);
    double falling[T] = {0, 1, 2, 2, 3, 4, 5};
    CHECK(tvpal_encoder_set_times(e, falling, NULL, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "step 3"), "times repeat: %s", d.msg);
    float v[NV];
    fill(v, 0);
    CHECK(tvpal_encoder_push(e, v, (enum tvpal_scalar)7, NV, NULL, &d) ==
              TVPAL_E_INVAL, "type 7 taken");
    CHECK(tvpal_encoder_push(e, NULL, TVPAL_FLOAT32, NV, NULL, &d) ==
              TVPAL_E_INVAL, "NULL data taken");
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV - 1, NULL, &d) ==
              TVPAL_E_INVAL && strstr(d.msg, "377 values pushed, 378 "
                                      "expected (9x7x6)"),
          "a push of the wrong size: %s", d.msg);
    CHECK(!exists(path("%s/p%s", ".partial")), "a refused push wrote");
    REQUIRE(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == 0,
            "push: %s", d.msg);
    CHECK(exists(path("%s/p%s", ".partial")) &&
              exists(path("%s/p%s", ".partial.lock")),
          "no partial output and lock after the first push");
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_WINDOW, 2, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "after the first push"), "set after push: %s",
          d.msg);
    double w[NV];
    CHECK(tvpal_encoder_push(e, w, TVPAL_FLOAT64, NV, NULL, &d) ==
              TVPAL_E_INVAL && strstr(d.msg, "one type"),
          "a second type: %s", d.msg);
    /* A push refused for its arguments changes nothing. */
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == 0,
          "a push after a refused type: %s", d.msg);
    tvpal_encoder_abort(e);
    CHECK(!exists(path("%s/p%s", "")) && !exists(path("%s/p%s", ".partial")) &&
              !exists(path("%s/p%s", ".partial.lock")),
          "abort left files");
}

static void test_identical_and_read(void)
{
    struct tvpal_diag d = {{0}};
    int rc = encode(path("%s/f32%s", ""), 0, &d);
    REQUIRE(rc == 0, "encode f32: %s %s", tvpal_strerror(rc), d.msg);
    rc = encode(path("%s/f64%s", ""), 1, &d);
    REQUIRE(rc == 0, "encode f64: %s %s", tvpal_strerror(rc), d.msg);
    CHECK(!exists(path("%s/f32%s", ".partial")) &&
              !exists(path("%s/f32%s", ".partial.lock")),
          "finish left its partial output or lock");
    for (int a = 0; a < 2; a++) {
        char f[64];
        snprintf(f, sizeof f, "/node-0/axis-%c.tvps", "xz"[a]);
        size_t n1 = 0, n2 = 0;
        unsigned char *b1 = slurp(path("%s/f32%s", f), &n1);
        unsigned char *b2 = slurp(path("%s/f64%s", f), &n2);
        CHECK(b1 && b2 && n1 == n2 && !memcmp(b1, b2, n1),
              "axis %c: float64 through strides differs from float32 "
              "(%zu, %zu bytes)", "xz"[a], n1, n2);
        free(b1);
        free(b2);
    }
    struct tvpal_reader *r = NULL;
    rc = tvpal_reader_open(&r, path("%s/f64%s", ""), &d);
    REQUIRE(rc == 0, "reader: %s %s", tvpal_strerror(rc), d.msg);
    const struct tvpal_info *in = tvpal_reader_info(r);
    CHECK(in->dims[0] == NX && in->dims[1] == NY && in->dims[2] == NZ &&
              in->steps == T && in->window == 3 &&
              in->axes == (TVPAL_AXIS_X | TVPAL_AXIS_Z) && in->levels == 0 &&
              in->schedule == TVPAL_SCHEDULE_JOINED,
          "info: %ux%ux%u steps %u window %u axes %u schedule %u",
          in->dims[0], in->dims[1], in->dims[2], in->steps, in->window,
          in->axes, in->schedule);
    CHECK(in->spacing[0] == 0.5 && in->spacing[2] == 2 &&
              in->origin[0] == -1 && in->origin[2] == 3,
          "grid: %g %g, %g %g", in->spacing[0], in->spacing[2],
          in->origin[0], in->origin[2]);
    CHECK(in->times && in->times[6] == 9 && !strcmp(in->time_units, "hours") &&
              !strcmp(in->units, "K"), "times or units lost");
    float v[NV], o[NV];
    double se = 0, lo = 1e9, hi = -1e9;
    for (unsigned t = 0; t < T; t++) {
        fill(o, t);
        for (unsigned axis = TVPAL_AXIS_X; axis <= TVPAL_AXIS_Z; axis *= 4) {
            rc = tvpal_reader_decode(r, t, axis, 0, v, &d);
            CHECK(rc == 0, "decode %u: %s", t, d.msg);
            for (unsigned i = 0; i < NV; i++) {
                se += (double)(v[i] - o[i]) * (v[i] - o[i]);
                lo = o[i] < lo ? o[i] : lo;
                hi = o[i] > hi ? o[i] : hi;
            }
        }
    }
    const double psnr = 10 * log10((hi - lo) * (hi - lo) / (se / (2.0 * T * NV)));
    CHECK(psnr > 30, "PSNR %.2f dB, 30 expected at least", psnr);
    CHECK(tvpal_reader_decode(r, T, 0, 0, v, &d) == TVPAL_E_INVAL,
          "step T decoded");
    CHECK(tvpal_reader_decode(r, 0, TVPAL_AXIS_Y, 0, v, &d) == TVPAL_E_INVAL,
          "axis y (not stored) decoded");
    CHECK(tvpal_reader_decode(r, 0, 0, 1, v, &d) == TVPAL_E_INVAL,
          "level 1 (none) decoded");
    tvpal_reader_close(r);
    CHECK(tvpal_reader_open(&r, path("%s/none%s", ""), &d) < 0 && r == NULL &&
              d.msg[0], "a missing dataset opened");
}

/* A series stopped early, by abort or by finish: nothing left. */
static void test_nothing_left(void)
{
    struct tvpal_encoder *e = NULL;
    struct tvpal_diag d = {{0}};
    float v[NV];
    REQUIRE(tvpal_encoder_open(&e, path("%s/short%s", ""), dims, T, &d) == 0,
            "open");
    for (unsigned t = 0; t < 4; t++) {
        fill(v, t);
        CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == 0,
              "push %u: %s", t, d.msg);
    }
    CHECK(tvpal_encoder_finish(e, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "4 of 7"), "finish after 4 of 7: %s", d.msg);
    CHECK(!exists(path("%s/short%s", "")) &&
              !exists(path("%s/short%s", ".partial")) &&
              !exists(path("%s/short%s", ".partial.lock")),
          "finish of a short series left files");
    /* An infinity: refused, naming its voxel; then only abort. */
    REQUIRE(tvpal_encoder_open(&e, path("%s/inf%s", ""), dims, T, &d) == 0,
            "open");
    fill(v, 0);
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == 0, "push");
    v[3 + NX * (2 + NY * 1)] = INFINITY;
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == TVPAL_E_NAN &&
              strstr(d.msg, "(3,2,1)") && strstr(d.msg, "step 1"),
          "an infinity: %s", d.msg);
    fill(v, 1);
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == TVPAL_E_INVAL,
          "a push after a refused value taken");
    tvpal_encoder_abort(e);
    CHECK(!exists(path("%s/inf%s", ".partial")), "abort left the partial");
}

static void test_output_rules(void)
{
    struct tvpal_encoder *e = NULL, *e2 = NULL;
    struct tvpal_diag d = {{0}};
    float v[NV];
    fill(v, 0);
    /* f32 exists (test_identical_and_read): refused, then forced. */
    REQUIRE(tvpal_encoder_open(&e, path("%s/f32%s", ""), dims, 1, &d) == 0,
            "open");
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == TVPAL_E_EXIST,
          "an existing dataset replaced without force");
    tvpal_encoder_abort(e);
    CHECK(exists(path("%s/f32%s", "/manifest.txt")), "abort removed the "
          "existing dataset");
    REQUIRE(tvpal_encoder_open(&e, path("%s/f32%s", ""), dims, 1, &d) == 0,
            "open");
    tvpal_encoder_set(e, TVPAL_PARAM_FORCE, 1, &d);
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == 0 &&
              tvpal_encoder_finish(e, &d) == 0, "forced: %s", d.msg);
    struct tvpal_reader *r = NULL;
    CHECK(tvpal_reader_open(&r, path("%s/f32%s", ""), &d) == 0 &&
              tvpal_reader_info(r)->steps == 1, "the forced dataset");
    tvpal_reader_close(r);
    CHECK(!exists(path("%s/f32%s", ".old")), "the old dataset left behind");
    /* A directory that is not a dataset: never replaced. */
    mkdir(path("%s/notds%s", ""), 0755);
    REQUIRE(tvpal_encoder_open(&e, path("%s/notds%s", ""), dims, 1, &d) == 0,
            "open");
    tvpal_encoder_set(e, TVPAL_PARAM_FORCE, 1, &d);
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) ==
              TVPAL_E_EXIST && strstr(d.msg, "not a tvpal dataset"),
          "a directory that is no dataset: %s", d.msg);
    tvpal_encoder_abort(e);
    CHECK(exists(path("%s/notds%s", "")), "the directory was removed");
    /* Two encoders of one output: the second is refused by the lock. */
    REQUIRE(tvpal_encoder_open(&e, path("%s/two%s", ""), dims, 2, &d) == 0 &&
                tvpal_encoder_open(&e2, path("%s/two%s", ""), dims, 2, &d) ==
                    0, "open");
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == 0, "push");
    CHECK(tvpal_encoder_push(e2, v, TVPAL_FLOAT32, NV, NULL, &d) ==
              TVPAL_E_EXIST, "a second encoder of one output: %s", d.msg);
    tvpal_encoder_abort(e2);
    CHECK(exists(path("%s/two%s", ".partial")), "the second encoder's abort "
          "removed the first's partial output");
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == 0,
          "the first: %s", d.msg);
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) ==
              TVPAL_E_INVAL && strstr(d.msg, "opened for 2"),
          "a push past the last step: %s", d.msg);
    CHECK(tvpal_encoder_finish(e, &d) == 0, "finish: %s", d.msg);
    /* A memory limit below N steps. */
    REQUIRE(tvpal_encoder_open(&e, path("%s/mem%s", ""), dims, T, &d) == 0,
            "open");
    tvpal_encoder_set(e, TVPAL_PARAM_MEM_LIMIT, 4096, &d);
    CHECK(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == TVPAL_E_RANGE &&
              strstr(d.msg, "memory limit"), "limit 4096: %s", d.msg);
    tvpal_encoder_abort(e);
    CHECK(!exists(path("%s/mem%s", ".partial")), "left a partial");
}

/* ------------------------------------------------------------ collective
 *
 * Ranks as threads of this process, and a collective of shared memory: a
 * gather or bcast is a barrier, the copies, a barrier. */
#define RANKS 4  /* NZ = 6: slabs of 2, 2, 1, 1 planes */

/* What a rank does, and what came of it. */
struct rank_job {
    struct tt_member m;
    const char *dir;
    uint32_t nz;             /* the series' planes (NX x NY x nz) */
    unsigned levels;         /* TVPAL_PARAM_LEVELS */
    int wrong_slab;          /* declares the next rank's slab */
    int abort_at;            /* aborts before pushing this step (-1: no) */
    int inf_at;              /* pushes an infinity at this step (-1: no) */
    int stop_at;             /* returns before pushing this step, without
                              * finish or abort, as if killed (-1: no) */
    int exit_at;             /* ends the process (every rank) before
                              * pushing this step (-1: no): a kill of a job
                              * whose ranks wait for each other at every
                              * step (levels) */
    int resume;              /* tvpal_encoder_resume first, and pushes
                              * from the step it gives (in next) */
    uint32_t next;
    int set_rc, push_rc, finish_rc, resume_rc;
    struct tvpal_diag d;
};

static void *rank_main(void *arg)
{
    struct rank_job *j = arg;
    struct tvpal_encoder *e = NULL;
    struct tvpal_diag *d = &j->d;
    const struct tvpal_collective c = {j->m.rank, RANKS, &j->m, tt_gather,
                                       tt_bcast, NULL};
    uint32_t z0, nz;
    const uint32_t dj[3] = {NX, NY, j->nz};
    tvpal_slab(j->nz, RANKS, (uint32_t)j->m.rank + (j->wrong_slab ? 1 : 0),
               &z0, &nz);
    if (tvpal_encoder_open(&e, j->dir, dj, T, d) < 0)
        return NULL;
    tvpal_encoder_set(e, TVPAL_PARAM_WINDOW, 3, d);
    /* Staggered: a step is encoded once the N = 3 after it are in (the
     * steps the kills below count on). */
    tvpal_encoder_set(e, TVPAL_PARAM_SCHEDULE, TVPAL_SCHEDULE_STAGGERED, d);
    tvpal_encoder_set(e, TVPAL_PARAM_THREADS, 1, d);
    tvpal_encoder_set(e, TVPAL_PARAM_LEVELS, j->levels, d);
    j->set_rc = tvpal_encoder_set_collective(e, &c, z0, nz, d);
    j->next = 0;
    if (j->resume &&
        (j->resume_rc = tvpal_encoder_resume(e, TVPAL_FLOAT32, &j->next, d)) <
            0) {
        tvpal_encoder_abort(e);
        return NULL;
    }
    float *v = malloc(sizeof *v * NX * NY * j->nz);
    for (unsigned t = j->next; v && t < T; t++) {
        if ((int)t == j->exit_at)
            _exit(0);
        if ((int)t == j->stop_at) {
            free(v);
            return NULL; /* killed: the process exits next */
        }
        if ((int)t == j->abort_at) {
            tvpal_encoder_abort(e);
            free(v);
            return NULL;
        }
        fill_nz(v, t, j->nz);
        if ((int)t == j->inf_at)
            v[NX * NY * z0 + 5] = INFINITY;
        j->push_rc = tvpal_encoder_push(e, v + NX * NY * z0, TVPAL_FLOAT32,
                                        (size_t)NX * NY * nz, NULL, d);
        if (j->push_rc < 0) {
            tvpal_encoder_abort(e);
            free(v);
            return NULL;
        }
    }
    j->finish_rc = v ? tvpal_encoder_finish(e, d) : TVPAL_E_NOMEM;
    free(v);
    return NULL;
}

/* Runs RANKS ranks of the series of nz planes with `levels` levels into
 * dir; rank `who` does what `how` says. */
static void run_ranks_of(struct rank_job *jobs, const char *dir, int who,
                         const char *how, uint32_t nz, unsigned levels)
{
    struct tt_group g;
    tt_group_init(&g, RANKS);
    pthread_t th[RANKS];
    for (int k = 0; k < RANKS; k++) {
        jobs[k] = (struct rank_job){.m = {&g, k}, .dir = dir, .nz = nz,
                                    .levels = levels,
                                    .abort_at = -1, .inf_at = -1,
                                    .stop_at = -1, .exit_at = -1,
                                    .resume = !strcmp(how, "resume")};
        if (!strcmp(how, "killed apart"))
            jobs[k].stop_at = 6 - k; /* the ranks at different steps */
        if (k == RANKS - 1 && !strcmp(how, "killed"))
            jobs[k].exit_at = 5;
        if (k == who && !strcmp(how, "wrong slab"))
            jobs[k].wrong_slab = 1;
        if (k == who && !strcmp(how, "abort"))
            jobs[k].abort_at = 3;
        if (k == who && !strcmp(how, "infinity"))
            jobs[k].inf_at = 4;
        if (k == who && !strcmp(how, "other levels"))
            jobs[k].levels = levels + 1;
        pthread_create(&th[k], NULL, rank_main, &jobs[k]);
    }
    for (int k = 0; k < RANKS; k++)
        pthread_join(th[k], NULL);
    pthread_barrier_destroy(&g.bar);
}

/* The same for the series of test_collective: NZ planes, no levels. */
static void run_ranks(struct rank_job *jobs, const char *dir, int who,
                      const char *how)
{
    run_ranks_of(jobs, dir, who, how, NZ, 0);
}

static int same_file(const char *a, const char *b)
{
    size_t n1 = 0, n2 = 0;
    unsigned char *b1 = slurp(a, &n1), *b2 = slurp(b, &n2);
    int same = b1 && b2 && n1 == n2 && !memcmp(b1, b2, n1);
    free(b1);
    free(b2);
    return same;
}

/* W/NAME, encoded by the ranks, against W/one (one process, --nodes
 * RANKS): the manifest, and every node's shard and manifest, byte for
 * byte. */
static void check_like_one(const char *name)
{
    char f[64], mine[700];
    for (int i = 0; i <= 2 * RANKS; i++) {
        if (i == 0)
            snprintf(f, sizeof f, "/manifest.txt");
        else
            snprintf(f, sizeof f, i % 2 ? "/node-%d/axis-z.tvps"
                                        : "/node-%d/manifest.txt", (i - 1) / 2);
        snprintf(mine, sizeof mine, "%s/%s%s", W, name, f);
        CHECK(same_file(path("%s/one%s", f), mine),
              "%s: %s differs from one process's", name, f);
    }
}

static void test_collective(void)
{
    struct tvpal_diag d = {{0}};
    uint32_t z0, nz;
    tvpal_slab(NZ, RANKS, 3, &z0, &nz);
    CHECK(z0 == 5 && nz == 1, "slab 3 of 4 of 6 planes: %u, %u", z0, nz);
    /* The reference: one process, --nodes RANKS. */
    struct tvpal_encoder *e = NULL;
    REQUIRE(tvpal_encoder_open(&e, path("%s/one%s", ""), dims, T, &d) == 0,
            "open");
    tvpal_encoder_set(e, TVPAL_PARAM_WINDOW, 3, &d);
    tvpal_encoder_set(e, TVPAL_PARAM_SCHEDULE, TVPAL_SCHEDULE_STAGGERED, &d);
    tvpal_encoder_set(e, TVPAL_PARAM_NODES, RANKS, &d);
    float v[NV];
    for (unsigned t = 0; t < T; t++) {
        fill(v, t);
        REQUIRE(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, &d) == 0,
                "push: %s", d.msg);
    }
    REQUIRE(tvpal_encoder_finish(e, &d) == 0, "finish: %s", d.msg);
    struct tvpal_reader *r = NULL;
    CHECK(tvpal_reader_open(&r, path("%s/one%s", ""), &d) == 0 &&
              tvpal_reader_info(r)->schedule == TVPAL_SCHEDULE_STAGGERED,
          "TVPAL_SCHEDULE_STAGGERED: %s", d.msg);
    tvpal_reader_close(r);

    struct rank_job j[RANKS];
    run_ranks(j, path("%s/ranks%s", ""), -1, "");
    for (int k = 0; k < RANKS; k++)
        CHECK(j[k].set_rc == 0 && j[k].push_rc == 0 && j[k].finish_rc == 0,
              "rank %d: %d %d %d %s", k, j[k].set_rc, j[k].push_rc,
              j[k].finish_rc, j[k].d.msg);
    check_like_one("ranks");
    CHECK(!exists(path("%s/ranks%s", ".partial")) &&
              !exists(path("%s/ranks%s", ".partial.lock")),
          "the ranks left their partial output or lock");

    /* Every failure fails every rank, with the failing rank's message, and
     * leaves nothing at DIR. */
    static const struct {
        int who;
        const char *how, *says;
    } bad[] = {{1, "wrong slab", "rank 1: rank 1 of 4 pushes planes"},
               {2, "abort", "rank 2: the encode was aborted"},
               {3, "infinity", "rank 3: step 4: an infinite value at voxel "
                               "(5,0,5)"},
               {0, "exists", "rank 0: "}};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        const char *dir = path("%s/bad%s", "");
        char cmd[600];
        snprintf(cmd, sizeof cmd, "rm -rf %s %s.partial", dir, dir);
        REQUIRE(system(cmd) == 0, "rm");
        if (!strcmp(bad[i].how, "exists"))
            mkdir(dir, 0755);
        run_ranks(j, dir, bad[i].who, bad[i].how);
        for (int k = 0; k < RANKS; k++) {
            if (k == bad[i].who && bad[i].who != 0)
                continue;
            const int rc = j[k].finish_rc ? j[k].finish_rc : j[k].push_rc;
            CHECK(rc < 0 && strstr(j[k].d.msg, bad[i].says),
                  "%s on rank %d: rank %d got %d \"%s\"", bad[i].how,
                  bad[i].who, k, rc, j[k].d.msg);
        }
        CHECK(!exists(path("%s/bad%s", ".partial")) &&
                  !exists(path("%s/bad%s", ".partial.lock")),
              "%s: a partial output or lock left", bad[i].how);
        CHECK(!strcmp(bad[i].how, "exists") ? !exists(path("%s/bad%s",
                                                            "/manifest.txt"))
                                                  && exists(dir)
                                            : !exists(dir),
              "%s: something at DIR", bad[i].how);
    }
    CHECK(j[0].push_rc == TVPAL_E_EXIST, "an existing DIR: %d",
          j[0].push_rc);

    /* Refused outright: an operation missing, a rank out of range, x
     * slices across the slabs. */
    REQUIRE(tvpal_encoder_open(&e, path("%s/c%s", ""), dims, T, &d) == 0,
            "open");
    struct tvpal_collective c = {0, 2, NULL, tt_gather, NULL, NULL};
    CHECK(tvpal_encoder_set_collective(e, &c, 0, 3, &d) == TVPAL_E_INVAL,
          "a collective without bcast");
    c.bcast = tt_bcast, c.rank = 2;
    CHECK(tvpal_encoder_set_collective(e, &c, 0, 3, &d) == TVPAL_E_INVAL &&
              strstr(d.msg, "rank 2 of 2"), "rank 2 of 2: %s", d.msg);
    tvpal_encoder_abort(e);
}

/* The ranks killed at different steps (as a kill -9 of an MPI job finds
 * them) and resumed: each continues from its own checkpoint, the caller
 * from the earliest, and the dataset is the uninterrupted one's (the
 * reference of test_collective). */
static void test_collective_resume(void)
{
    const char *dir = path("%s/apart%s", "");
    struct rank_job j[RANKS];
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        run_ranks(j, dir, -1, "killed apart");
        _exit(0);
    }
    int status = 0;
    REQUIRE(pid > 0 && waitpid(pid, &status, 0) == pid &&
                WIFEXITED(status) && WEXITSTATUS(status) == 0,
            "the killed ranks' process failed (status %d)", status);
    CHECK(!exists(dir) && exists(path("%s/apart%s", ".partial/node-0/"
                                                    "checkpoint")) &&
              exists(path("%s/apart%s", ".partial/node-3/checkpoint")),
          "the kill left no partial output with the ranks' checkpoints");
    run_ranks(j, dir, -1, "resume");
    /* Window 3: rank 3 pushed 3 steps (step 0 encoded), rank 0 six (0..3):
     * the caller resumes at 1; rank 0 passes over steps 1..3. */
    for (int k = 0; k < RANKS; k++)
        CHECK(j[k].resume_rc == 0 && j[k].next == 1 && j[k].push_rc == 0 &&
                  j[k].finish_rc == 0,
              "rank %d: resume %d at %u, push %d, finish %d: %s", k,
              j[k].resume_rc, j[k].next, j[k].push_rc, j[k].finish_rc,
              j[k].d.msg);
    check_like_one("apart");
}

/* Levels with a collective: rank 0 makes level 1 from every rank's part
 * (LNZ planes in slabs of 4, 3, 3, 3: a block split between ranks 1 and
 * 2, a last block of one plane) and encodes every node's levels; the
 * dataset is one process's NODES RANKS, LEVELS 1 (level 2 would have
 * fewer than RANKS slices), file for file.  A rank
 * failing or aborting mid-way ends every rank with its message (none
 * waits for it), a kill and a resume give the same bytes, and a rank with
 * other levels is refused. */
#define LNZ 13
static void test_collective_levels(void)
{
    struct tvpal_diag d = {{0}};
    const uint32_t dl[3] = {NX, NY, LNZ};
    struct tvpal_encoder *e = NULL;
    REQUIRE(tvpal_encoder_open(&e, path("%s/lone%s", ""), dl, T, &d) == 0,
            "open");
    tvpal_encoder_set(e, TVPAL_PARAM_WINDOW, 3, &d);
    tvpal_encoder_set(e, TVPAL_PARAM_SCHEDULE, TVPAL_SCHEDULE_STAGGERED, &d);
    tvpal_encoder_set(e, TVPAL_PARAM_NODES, RANKS, &d);
    tvpal_encoder_set(e, TVPAL_PARAM_LEVELS, 1, &d);
    static float v[NX * NY * LNZ];
    for (unsigned t = 0; t < T; t++) {
        fill_nz(v, t, LNZ);
        REQUIRE(tvpal_encoder_push(e, v, TVPAL_FLOAT32, NX * NY * LNZ, NULL,
                                   &d) == 0, "push: %s", d.msg);
    }
    REQUIRE(tvpal_encoder_finish(e, &d) == 0, "finish: %s", d.msg);
    char cmd[1200];
    struct rank_job j[RANKS];
    static const char *const runs[] = {"", "killed"};
    for (int i = 0; i < 2; i++) {
        const char *dir = path("%s/lranks%s", "");
        snprintf(cmd, sizeof cmd, "rm -rf %s %s.partial", dir, dir);
        REQUIRE(system(cmd) == 0, "rm");
        if (i == 1) {
            fflush(NULL);
            pid_t pid = fork();
            if (pid == 0) {
                run_ranks_of(j, dir, -1, runs[i], LNZ, 1);
                _exit(0);
            }
            int status = 0;
            REQUIRE(pid > 0 && waitpid(pid, &status, 0) == pid &&
                        WIFEXITED(status) && WEXITSTATUS(status) == 0,
                    "the killed ranks' process failed (status %d)", status);
            CHECK(!exists(dir) &&
                      exists(path("%s/lranks%s", ".partial/level-1.partial")),
                  "the kill left no partial levels");
        }
        run_ranks_of(j, dir, -1, i ? "resume" : "", LNZ, 1);
        for (int k = 0; k < RANKS; k++)
            CHECK(j[k].set_rc == 0 && j[k].push_rc == 0 &&
                      j[k].finish_rc == 0 && j[k].resume_rc == 0,
                  "levels%s, rank %d: %d %d %d %d %s", i ? " resumed" : "",
                  k, j[k].set_rc, j[k].push_rc, j[k].finish_rc,
                  j[k].resume_rc, j[k].d.msg);
        snprintf(cmd, sizeof cmd, "diff -r %s %s > /dev/null",
                 path("%s/lone%s", ""), dir);
        CHECK(system(cmd) == 0, "levels on %d ranks%s: the dataset differs "
              "from one process's", RANKS, i ? ", killed and resumed" : "");
    }
    static const struct {
        int who;
        const char *how, *says;
    } bad[] = {{3, "infinity", "rank 3: step 4: an infinite value"},
               {2, "abort", "rank 2: the encode was aborted"},
               {1, "other levels", "rank 1 has levels 2, rank 0 1"}};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        const char *dir = path("%s/lbad%s", "");
        snprintf(cmd, sizeof cmd, "rm -rf %s %s.partial", dir, dir);
        REQUIRE(system(cmd) == 0, "rm");
        run_ranks_of(j, dir, bad[i].who, bad[i].how, LNZ, 1);
        for (int k = 0; k < RANKS; k++) {
            if (k == bad[i].who && strcmp(bad[i].how, "other levels"))
                continue;
            const int rc = j[k].finish_rc ? j[k].finish_rc : j[k].push_rc;
            CHECK(rc < 0 && strstr(j[k].d.msg, bad[i].says),
                  "levels, %s on rank %d: rank %d got %d \"%s\"",
                  bad[i].how, bad[i].who, k, rc, j[k].d.msg);
        }
        CHECK(!exists(dir) && !exists(path("%s/lbad%s", ".partial")),
              "levels, %s: something left", bad[i].how);
    }
}

/* Pushes steps first .. last - 1 of the series (float32). */
static int push_steps(struct tvpal_encoder *e, unsigned first, unsigned last,
                      struct tvpal_diag *d)
{
    float v[NV];
    int rc = 0;
    for (unsigned t = first; t < last && rc == 0; t++) {
        fill(v, t);
        rc = tvpal_encoder_push(e, v, TVPAL_FLOAT32, NV, NULL, d);
    }
    return rc;
}

/* A process that pushes `steps` steps into dir and dies (no finish, no
 * abort), as a crash would. */
static void crash_after(const char *dir, unsigned steps)
{
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        struct tvpal_encoder *e = NULL;
        struct tvpal_diag d = {{0}};
        if (open_series(&e, dir, 3, &d) < 0 || push_steps(e, 0, steps, &d) < 0)
            _exit(3);
        _exit(0);
    }
    int status = 0;
    REQUIRE(pid > 0 && waitpid(pid, &status, 0) == pid &&
                WIFEXITED(status) && WEXITSTATUS(status) == 0,
            "the crashing child failed (status %d)", status);
}

/* tvpal_encoder_resume: after a crash, the steps from the checkpoint on
 * give the dataset of an uninterrupted encode; with no partial output, or that of another
 * job, it starts over. */
static void test_resume(void)
{
    struct tvpal_diag d = {{0}};
    REQUIRE(encode(path("%s/whole%s", ""), 0, &d) == 0, "encode: %s", d.msg);
    const char *dir = path("%s/resumed%s", "");
    crash_after(dir, 5);
    CHECK(!exists(dir) && exists(path("%s/resumed%s", ".partial/checkpoint")),
          "the crash left no partial output with a checkpoint");
    struct tvpal_encoder *e = NULL;
    uint32_t next = 99;
    REQUIRE(open_series(&e, dir, 3, &d) == 0, "open: %s", d.msg);
    REQUIRE(tvpal_encoder_resume(e, TVPAL_FLOAT32, &next, &d) == 0,
            "resume: %s", d.msg);
    /* Window 3, the joined schedule (the default): a step is encoded once
     * the 5 steps of its longest window are in: 5 steps in, step 0
     * encoded, the checkpoint at 1. */
    CHECK(next == 1, "resumed at step %u, 1 expected", next);
    CHECK(tvpal_encoder_resume(e, TVPAL_FLOAT32, &next, &d) == TVPAL_E_INVAL,
          "a second resume taken");
    CHECK(push_steps(e, next, T, &d) == 0, "push: %s", d.msg);
    CHECK(tvpal_encoder_finish(e, &d) == 0, "finish: %s", d.msg);
    static const char *files[] = {"/manifest.txt", "/node-0/manifest.txt",
                                  "/node-0/axis-x.tvps", "/node-0/axis-z.tvps"};
    for (int i = 0; i < 4; i++)
        CHECK(same_file(path("%s/whole%s", files[i]),
                        path("%s/resumed%s", files[i])),
              "%s of the resumed encode differs from the uninterrupted one's",
              files[i]);
    CHECK(!exists(path("%s/resumed%s", "/checkpoint")) &&
              !exists(path("%s/resumed%s", ".partial")),
          "a checkpoint or the partial output left");
    /* No partial output: a fresh start. */
    REQUIRE(open_series(&e, path("%s/fresh%s", ""), 3, &d) == 0, "open");
    CHECK(tvpal_encoder_resume(e, TVPAL_FLOAT32, &next, &d) == 0 && next == 0,
          "resume of nothing: %u %s", next, d.msg);
    CHECK(push_steps(e, 0, T, &d) == 0 && tvpal_encoder_finish(e, &d) == 0,
          "fresh: %s", d.msg);
    CHECK(same_file(path("%s/whole%s", "/node-0/axis-z.tvps"),
                    path("%s/fresh%s", "/node-0/axis-z.tvps")),
          "a resume of nothing differs");
    /* Another job's checkpoint (window 4): not resumed, started over. */
    dir = path("%s/other%s", "");
    crash_after(dir, 5);
    REQUIRE(open_series(&e, dir, 4, &d) == 0, "open");
    CHECK(tvpal_encoder_resume(e, TVPAL_FLOAT32, &next, &d) == 0 && next == 0,
          "another job's checkpoint resumed at %u", next);
    CHECK(push_steps(e, 0, T, &d) == 0 && tvpal_encoder_finish(e, &d) == 0,
          "started over: %s", d.msg);
    struct tvpal_reader *r = NULL;
    CHECK(tvpal_reader_open(&r, dir, &d) == 0 &&
              tvpal_reader_info(r)->window == 4, "the started-over dataset");
    tvpal_reader_close(r);
    /* A checkpoint of the other schedule (joined, the same window):
     * started over too, its shards' layout being another. */
    dir = path("%s/othersched%s", "");
    crash_after(dir, 6);
    REQUIRE(open_series(&e, dir, 3, &d) == 0 &&
                tvpal_encoder_set(e, TVPAL_PARAM_SCHEDULE,
                                  TVPAL_SCHEDULE_STAGGERED, &d) == 0,
            "open: %s", d.msg);
    CHECK(tvpal_encoder_resume(e, TVPAL_FLOAT32, &next, &d) == 0 && next == 0,
          "the other schedule's checkpoint resumed at %u", next);
    CHECK(push_steps(e, 0, T, &d) == 0 && tvpal_encoder_finish(e, &d) == 0,
          "started over: %s", d.msg);
    CHECK(tvpal_reader_open(&r, dir, &d) == 0 &&
              tvpal_reader_info(r)->schedule == TVPAL_SCHEDULE_STAGGERED,
          "the started-over dataset's schedule");
    tvpal_reader_close(r);
    /* A shard changed since its checkpoint: refused, naming the file. */
    dir = path("%s/changed%s", "");
    crash_after(dir, 6);
    FILE *f = fopen(path("%s/changed%s", ".partial/node-0/axis-z.tvps"), "r+b");
    REQUIRE(f != NULL, "the crashed shard");
    fseek(f, 0, SEEK_END);
    const long size = ftell(f); /* records 0..3 are in: spoil the middle */
    fseek(f, size / 4, SEEK_SET);
    for (long i = 0; i < size / 2; i++)
        fputc(0x5a, f);
    fclose(f);
    REQUIRE(open_series(&e, dir, 3, &d) == 0, "open");
    const int rc = tvpal_encoder_resume(e, TVPAL_FLOAT32, &next, &d);
    CHECK(rc < 0 && strstr(d.msg, "axis-z.tvps: cannot resume"),
          "a changed shard resumed: %d %s", rc, d.msg);
    tvpal_encoder_abort(e);
    CHECK(!exists(path("%s/changed%s", ".partial")), "abort left the partial");
}

/* TVPAL_PARAM_LEVELS: level 1 of a series pushed from memory decodes to
 * the 2x2x2 means of the values pushed (within the codec's error). */
static void test_levels(void)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_encoder *e = NULL;
    REQUIRE(open_series(&e, path("%s/levels%s", ""), 3, &d) == 0, "open");
    CHECK(tvpal_encoder_set(e, TVPAL_PARAM_LEVELS, 9, &d) == TVPAL_E_INVAL,
          "9 levels taken");
    REQUIRE(tvpal_encoder_set(e, TVPAL_PARAM_LEVELS, 2, &d) == 0, "levels");
    REQUIRE(push_steps(e, 0, T, &d) == 0, "push: %s", d.msg);
    REQUIRE(tvpal_encoder_finish(e, &d) == 0, "finish: %s", d.msg);
    struct tvpal_reader *r = NULL;
    REQUIRE(tvpal_reader_open(&r, path("%s/levels%s", ""), &d) == 0,
            "reader: %s", d.msg);
    uint32_t l1[3], l2[3];
    CHECK(tvpal_reader_info(r)->levels == 2 &&
              tvpal_reader_level_dims(r, 1, l1) == 0 &&
              tvpal_reader_level_dims(r, 2, l2) == 0 && l1[0] == 5 &&
              l1[1] == 4 && l1[2] == 3 && l2[0] == 3 && l2[1] == 2 &&
              l2[2] == 2, "levels: %u, level 1 %ux%ux%u",
          tvpal_reader_info(r)->levels, l1[0], l1[1], l1[2]);
    float v[NV], got[5 * 4 * 3];
    double se = 0, lo = 1e9, hi = -1e9;
    for (unsigned t = 0; t < T; t++) {
        fill(v, t);
        REQUIRE(tvpal_reader_decode(r, t, 0, 1, got, &d) == 0, "decode: %s",
                d.msg);
        for (unsigned z = 0; z < 3; z++)
            for (unsigned y = 0; y < 4; y++)
                for (unsigned x = 0; x < 5; x++) {
                    double s = 0;
                    int n = 0;
                    for (unsigned k = 0; k < 8; k++) {
                        const unsigned xx = 2 * x + (k & 1),
                                       yy = 2 * y + (k >> 1 & 1),
                                       zz = 2 * z + (k >> 2);
                        if (xx < NX && yy < NY && zz < NZ)
                            s += v[xx + NX * (yy + NY * zz)], n++;
                    }
                    const double m = s / n,
                                 g = got[x + 5 * (y + 4 * z)];
                    se += (g - m) * (g - m);
                    lo = m < lo ? m : lo;
                    hi = m > hi ? m : hi;
                }
    }
    const double psnr = 10 * log10((hi - lo) * (hi - lo) / (se / (T * 60.0)));
    CHECK(psnr > 30, "level 1: PSNR %.2f dB against the block means, 30 "
          "expected at least", psnr);
    tvpal_reader_close(r);
}

/* ------------------------------------------------ describe, sizes, verify */

static uint64_t walked;

static int add_file(const char *p, const struct stat *st, int type,
                    struct FTW *f)
{
    (void)p;
    (void)f;
    walked += type == FTW_F ? (uint64_t)st->st_size : 0;
    return 0;
}

/* Bytes of every file under p, by a walk of our own. */
static uint64_t tree_bytes(const char *p)
{
    walked = 0;
    return nftw(p, add_file, 16, FTW_PHYS) == 0 ? walked : 0;
}

/* Slice-windows of an axis of n slices over T steps, window N, in the
 * joined schedule (the default, FORMAT.md 5): one per slice at step 0,
 * then one at each t >= N with t mod N == s mod N. */
static uint64_t windows_of(unsigned n, unsigned N)
{
    uint64_t w = 0;
    for (unsigned s = 0; s < n; s++)
        for (unsigned t = 0; t < T; t++)
            w += t == 0 || (t >= N && t % N == s % N);
    return w;
}

struct findings {
    unsigned ok, bad;
    char paths[8][512];   /* the problems' paths (first 8) */
    int64_t records[8];
    int codes[8];
};

static void note(void *ctx, const struct tvpal_check *c)
{
    struct findings *f = ctx;
    if (c->code == 0) {
        f->ok++;
        return;
    }
    if (f->bad < 8) {
        snprintf(f->paths[f->bad], sizeof f->paths[0], "%s", c->path);
        f->records[f->bad] = c->record;
        f->codes[f->bad] = c->code;
    }
    f->bad += !!c->msg[0];   /* a problem always says what is wrong */
}

/* The levels dataset (test_levels: window 3, axes x and z, levels 2) as
 * its reader describes and sizes it. */
static void check_describe_and_sizes(struct tvpal_reader *r, const char *dir)
{
    const struct tvpal_info *in = tvpal_reader_info(r);
    uint64_t count = 0;
    for (unsigned i = 0; i < in->histogram_bins; i++)
        count += in->histogram[i];
    CHECK(in->histogram_bins == 64 && count == (uint64_t)NV * T &&
              in->missing == 0, "histogram: %u bins, %llu values (%u "
          "expected)", in->histogram_bins, (unsigned long long)count,
          NV * T);
    CHECK(in->table == TVPAL_TABLE_AUTO && !in->has_nan_as &&
              in->nmissing_values == 0 && !in->missing_values,
          "table %u, nan_as %d, missing values %u", in->table,
          in->has_nan_as, in->nmissing_values);
    CHECK(!strncmp(in->encoder, "libtvpal ", 9) &&
              strstr(in->manifest, "\nwindow = 3\n") &&
              strstr(in->manifest, in->encoder),
          "provenance: encoder \"%s\"", in->encoder);
    CHECK(!strcmp(in->source_format, "") && in->nsources == 0 &&
              !strcmp(in->source_type, "f32") &&
              in->source_value_bytes == 4, "source: \"%s\" %u files, %s",
          in->source_format, in->nsources, in->source_type);
    struct tvpal_sizes z0, z1;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_reader_sizes(r, 0, &z0, &d) == 0, "sizes: %s", d.msg);
    REQUIRE(tvpal_reader_sizes(r, 1, &z1, &d) == 0, "sizes 1: %s", d.msg);
    const uint64_t wx = windows_of(NX, 3), wz = windows_of(NZ, 3);
    CHECK(z0.index_bytes[0] == wx * NY * NZ &&
              z0.index_bytes[2] == wz * NX * NY && z0.axis_bytes[1] == 0 &&
              z0.index_bytes[1] == 0 && z0.table_bytes[1] == 0,
          "index bytes %llu %llu, %llu and %llu expected",
          (unsigned long long)z0.index_bytes[0],
          (unsigned long long)z0.index_bytes[2],
          (unsigned long long)(wx * NY * NZ),
          (unsigned long long)(wz * NX * NY));
    CHECK(z0.chunks_f32[0] + z0.chunks_u16[0] == wx &&
              z0.chunks_f32[2] + z0.chunks_u16[2] == wz,
          "chunks: %llu + %llu on x, %llu expected",
          (unsigned long long)z0.chunks_f32[0],
          (unsigned long long)z0.chunks_u16[0], (unsigned long long)wx);
    /* Coded chunks (the default): the plain indices and tables are more
     * than what the file holds of them on x, where they compress enough to
     * save whole pages (z's 4 records of a page or two each do not). */
    for (unsigned a = 0; a < 3; a += 2)
        CHECK(z0.table_bytes[a] > 0 &&
                  (a != 0 || z0.index_bytes[a] + z0.table_bytes[a] >
                                 z0.axis_bytes[a]),
              "axis %u: %llu index and %llu table bytes in %llu", a,
              (unsigned long long)z0.index_bytes[a],
              (unsigned long long)z0.table_bytes[a],
              (unsigned long long)z0.axis_bytes[a]);
    struct tvpal_coding c0;
    REQUIRE(tvpal_reader_coding(r, 0, &c0, &d) == 0, "coding: %s", d.msg);
    CHECK(c0.chunks[0] == z0.chunks_f32[0] + z0.chunks_u16[0] &&
              c0.chunks[1] == 0 && c0.chunks_coded[0] > 0 &&
              c0.chunks_coded[0] <= c0.chunks[0] &&
              c0.coded_bytes[0] < c0.coded_plain_bytes[0],
          "coding: %llu of %llu chunks coded, %llu bytes for %llu",
          (unsigned long long)c0.chunks_coded[0],
          (unsigned long long)c0.chunks[0],
          (unsigned long long)c0.coded_bytes[0],
          (unsigned long long)c0.coded_plain_bytes[0]);
    CHECK(tvpal_reader_coding(r, 9, &c0, &d) == TVPAL_E_INVAL,
          "coding of level 9");
    char l1[600];
    snprintf(l1, sizeof l1, "%s/level-1", dir);
    CHECK(z0.disk_bytes == tree_bytes(dir) && z1.disk_bytes == tree_bytes(l1)
              && z1.disk_bytes < z0.disk_bytes,
          "disk bytes %llu, level 1 %llu; walked %llu, %llu",
          (unsigned long long)z0.disk_bytes, (unsigned long long)z1.disk_bytes,
          (unsigned long long)tree_bytes(dir),
          (unsigned long long)tree_bytes(l1));
    CHECK(z1.index_bytes[2] == windows_of(3, 3) * 5 * 4,
          "level 1 index bytes %llu", (unsigned long long)z1.index_bytes[2]);
    CHECK(tvpal_reader_sizes(r, 3, &z1, &d) == TVPAL_E_INVAL && d.msg[0],
          "sizes of level 3 (of 2) given");
}

/* Damage a copy: a record's byte, a shard cut short, a level's manifest
 * gone.  Each is found and named, the rest still verified. */
static void check_verify_damage(const char *dir)
{
    char cmd[1600], bad[600], p[700];
    snprintf(bad, sizeof bad, "%s.damaged", dir);
    snprintf(cmd, sizeof cmd, "rm -rf %s && cp -r %s %s", bad, dir, bad);
    REQUIRE(system(cmd) == 0, "copy");
    snprintf(p, sizeof p, "%s/node-0/axis-z.tvps", bad);
    FILE *f = fopen(p, "r+b");
    REQUIRE(f && fseek(f, 4096 + 300, SEEK_SET) == 0, "open %s", p);
    int c = fgetc(f);
    fseek(f, 4096 + 300, SEEK_SET);
    fputc(c ^ 0x5a, f);
    fclose(f);
    snprintf(p, sizeof p, "%s/node-0/axis-x.tvps", bad);
    REQUIRE((f = fopen(p, "r+b")) && fseek(f, 40, SEEK_SET) == 0, "open");
    fputc(7, f);   /* the rank: the header's CRC no longer holds */
    fclose(f);
    snprintf(p, sizeof p, "%s/level-1/node-0/axis-x.tvps", bad);
    REQUIRE(truncate(p, 4096 + 100) == 0, "truncate");
    snprintf(p, sizeof p, "%s/level-2/manifest.txt", bad);
    REQUIRE(unlink(p) == 0, "unlink");
    struct tvpal_reader *r = NULL;
    struct tvpal_diag d = {{0}};
    CHECK(tvpal_reader_open(&r, bad, &d) < 0 && !r, "a damaged dataset "
          "opened in full");
    REQUIRE(tvpal_reader_open_manifest(&r, bad, &d) == 0,
            "open the manifest: %s", d.msg);
    struct findings fd = {0};
    uint64_t problems = 0;
    REQUIRE(tvpal_reader_verify(r, note, &fd, &problems, &d) == 0,
            "verify: %s", d.msg);
    CHECK(problems == 4 && fd.bad == 4 && fd.ok == 1,
          "%llu problems (%u named), %u shards sound; 4 and 1 expected",
          (unsigned long long)problems, fd.bad, fd.ok);
    CHECK(fd.bad == 4 && strstr(fd.paths[0], "damaged/node-0/axis-x.tvps") &&
              fd.records[0] == -1 && fd.codes[0] == TVPAL_E_CHECKSUM &&
              strstr(fd.paths[1], "damaged/node-0/axis-z.tvps") &&
              fd.records[1] == 0 && fd.codes[1] == TVPAL_E_CHECKSUM &&
              strstr(fd.paths[2], "level-1/node-0/axis-x.tvps") &&
              fd.records[2] == -1 && strstr(fd.paths[3], "level-2") &&
              fd.records[3] == -1,
          "findings: %s %lld %d; %s record %lld code %d; %s; %s",
          fd.paths[0], (long long)fd.records[0], fd.codes[0], fd.paths[1],
          (long long)fd.records[1], fd.codes[1], fd.paths[2], fd.paths[3]);
    float v[NV];
    CHECK(tvpal_reader_decode(r, 0, 0, 0, v, &d) < 0 &&
              strstr(d.msg, "axis-x.tvps"), "a damaged level 0 decoded: %s",
          d.msg);
    CHECK(tvpal_reader_decode(r, 0, 0, 1, v, &d) < 0 &&
              strstr(d.msg, "axis-x.tvps"), "a cut level decoded: %s",
          d.msg);
    tvpal_reader_close(r);
}

static void test_describe_sizes_verify(void)
{
    const char *dir = path("%s/levels%s", "");
    struct tvpal_reader *r = NULL;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_reader_open(&r, dir, &d) == 0, "reader: %s", d.msg);
    check_describe_and_sizes(r, dir);
    struct findings fd = {0};
    uint64_t problems = 9;
    CHECK(tvpal_reader_verify(r, note, &fd, &problems, &d) == 0 &&
              problems == 0 && fd.bad == 0 && fd.ok == 6,
          "clean: %llu problems, %u shards sound (6 expected)",
          (unsigned long long)problems, fd.ok);
    tvpal_reader_close(r);
    check_verify_damage(dir);
}

int main(void)
{
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf %s && mkdir -p %s", W, W);
    REQUIRE(system(cmd) == 0, "cannot make %s", W);
    CHECK(tvpal_version_number() == TVPAL_VERSION_NUMBER &&
              !strcmp(tvpal_version_string(), "0.4.0"),
          "version %u %s", tvpal_version_number(), tvpal_version_string());
    test_params();
    test_identical_and_read();
    test_nothing_left();
    test_output_rules();
    test_collective();
    test_collective_resume();
    test_collective_levels();
    test_resume();
    test_levels();
    test_describe_sizes_verify();
    int rc = tt_done("test-api");
    if (rc == 0) {
        snprintf(cmd, sizeof cmd, "rm -rf %s", W);
        if (system(cmd) != 0)
            return 99;
    }
    return rc;
}
