/* test-checkpoint: the encoder's resume record (encoder/tvpal_checkpoint.h):
 * save/load round trip, refusal of another job's checkpoint, of truncated
 * and tampered files and of a missing one, each leaving empty statistics. */
#define _GNU_SOURCE
#include "tvpal_test.h"

#include <dirent.h>
#include "tvpal_checkpoint.h"
#include "tvpal_fs.h"

#include <string.h>
#include <unistd.h>

#define STEPS 6u
#define VOX 10u /* voxels per step */

static char g_dir[256];

static char *path_in(const char *name)
{
    static char buf[512];
    snprintf(buf, sizeof buf, "%s/%s", g_dir, name);
    return buf;
}

/* Whether a temporary of the checkpoint ("checkpoint.XXXXXX") is left. */
static int temporaries_left(void)
{
    DIR *dir = opendir(g_dir);
    struct dirent *e;
    int left = 0;
    while (dir && (e = readdir(dir)))
        left |= !strncmp(e->d_name, "checkpoint.", 11);
    if (dir)
        closedir(dir);
    return left;
}

/* Three steps of ten voxels, two of the values missing: counts summing to
 * 28. */
static void fill(struct tvpal_checkpoint_stats *st)
{
    tvpal_checkpoint_stats_reset(st);
    st->vmin = -1.5;
    st->vmax = 0x1.23456789abcdep+3; /* needs every bit of %a */
    st->nonfinite = 7;
    st->loaded = 3;
    st->counted = 30;
    st->fine[0] = 1;
    st->fine[5] = 12;
    st->fine[40000] = 14;
    st->fine[TVPAL_CHECKPOINT_BINS - 1] = 1;
    st->missing = 2;
}

static int is_empty(const struct tvpal_checkpoint_stats *st)
{
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++)
        if (st->fine[b])
            return 0;
    return st->loaded == 0 && st->nonfinite == 0 && isinf(st->vmin) &&
           st->vmin > 0 && isinf(st->vmax) && st->vmax < 0;
}

static char *read_text(void)
{
    char *text = NULL;
    REQUIRE(tvpal_read_file(path_in("checkpoint"), &text, NULL, NULL) == 0,
            "read checkpoint back");
    return text;
}

static void write_text(const char *text, size_t len)
{
    REQUIRE(tvpal_write_file_atomic(path_in("checkpoint"), text, len, NULL) == 0,
            "rewrite checkpoint");
}

/* Loads the checkpoint of job fp; expects code want, and on refusal done 0
 * and empty statistics, with a diag that says something. */
static void expect_load(const char *what, const char *fp, uint32_t steps,
                        uint64_t vox, int want)
{
    struct tvpal_checkpoint_stats st;
    struct tvpal_diag d = {{0}};
    uint64_t done = 99;
    REQUIRE(tvpal_checkpoint_stats_init(&st) == 0, "init");
    fill(&st);
    int rc = tvpal_checkpoint_load(g_dir, fp, steps, steps, vox, &done, &st,
                                   NULL, &d);
    CHECK(rc == want, "%s: rc %d (%s), expected %d (%s); diag \"%s\"", what,
          rc, tvpal_strerror(rc), want, tvpal_strerror(want), d.msg);
    if (want < 0) {
        CHECK(done == 0, "%s: done %llu after refusal", what,
              (unsigned long long)done);
        CHECK(is_empty(&st), "%s: statistics not reset", what);
        CHECK(d.msg[0] != 0, "%s: no detail in diag", what);
    }
    tvpal_checkpoint_stats_free(&st);
}

static void test_round_trip(void)
{
    struct tvpal_checkpoint_stats a, b;
    struct tvpal_diag d = {{0}};
    uint64_t done = 0;
    REQUIRE(tvpal_checkpoint_stats_init(&a) == 0 &&
                tvpal_checkpoint_stats_init(&b) == 0, "init");
    CHECK(is_empty(&a), "init gives empty statistics");
    fill(&a);
    CHECK(tvpal_checkpoint_save(g_dir, "job A", 2, &a, NULL, &d) == 0, "save: %s",
          d.msg);
    CHECK(!temporaries_left(), "temporary file left");
    int rc = tvpal_checkpoint_load(g_dir, "job A", STEPS, STEPS, VOX, &done,
                                   &b, NULL, &d);
    CHECK(rc == 0, "load: %s (%s)", tvpal_strerror(rc), d.msg);
    CHECK(done == 2, "done %llu", (unsigned long long)done);
    CHECK(b.counted == 30, "counted %llu", (unsigned long long)b.counted);
    CHECK(b.missing == 2, "missing %llu", (unsigned long long)b.missing);
    CHECK(b.loaded == 3 && b.nonfinite == 7, "loaded %u nonfinite %llu",
          b.loaded, (unsigned long long)b.nonfinite);
    CHECK(b.vmin == a.vmin && b.vmax == a.vmax, "range %a %a", b.vmin,
          b.vmax);
    CHECK(!memcmp(a.fine, b.fine, TVPAL_CHECKPOINT_BINS * sizeof *a.fine),
          "histogram differs");
    /* Saving again replaces it; diag may be NULL. */
    a.loaded = 4;
    a.fine[7] = 10;
    a.counted += 10;
    CHECK(tvpal_checkpoint_save(g_dir, "job A", 4, &a, NULL, NULL) == 0,
          "resave");
    CHECK(tvpal_checkpoint_load(g_dir, "job A", STEPS, STEPS, VOX, &done, &b,
                                NULL, NULL) == 0 && done == 4 &&
              b.fine[7] == 10,
          "second checkpoint: done %llu", (unsigned long long)done);
    /* Nothing loaded yet: the infinite range survives the text form. */
    tvpal_checkpoint_stats_reset(&a);
    CHECK(tvpal_checkpoint_save(g_dir, "job A", 0, &a, NULL, NULL) == 0,
          "save 0");
    CHECK(tvpal_checkpoint_load(g_dir, "job A", STEPS, STEPS, VOX, &done, &b,
                                NULL, NULL) == 0 && done == 0 && is_empty(&b),
          "empty checkpoint round trip");
    tvpal_checkpoint_stats_free(&a);
    tvpal_checkpoint_stats_free(&b);
    tvpal_checkpoint_stats_free(&a); /* twice is safe */
}

static void test_fingerprint(void)
{
    char in0[512], in1[512];
    snprintf(in0, sizeof in0, "%s", path_in("in0"));
    snprintf(in1, sizeof in1, "%s", path_in("in1"));
    char *ins[2] = {in0, in1};
    REQUIRE(tvpal_write_file_atomic(in0, "abcd", 4, NULL) == 0 &&
                tvpal_write_file_atomic(in1, "efgh", 4, NULL) == 0, "inputs");
    char *f1 = NULL, *f2 = NULL, *f3 = NULL, *f4 = NULL;
    CHECK(tvpal_checkpoint_fingerprint("window=4", ins, 2, 0, &f1) == 0 &&
              tvpal_checkpoint_fingerprint("window=4", ins, 2, 0, &f2) == 0 &&
              tvpal_checkpoint_fingerprint("window=2", ins, 2, 0, &f3) == 0,
          "fingerprint");
    CHECK(f1 && f2 && !strcmp(f1, f2), "same job, different fingerprints");
    CHECK(f1 && f3 && strcmp(f1, f3), "other options, same fingerprint");
    CHECK(f1 && !strncmp(f1, "window=4 ", 9) && strstr(f1, ":4:"),
          "layout: \"%s\"", f1 ? f1 : "");
    /* An input that changed size is another job. */
    REQUIRE(tvpal_write_file_atomic(in1, "efghij", 6, NULL) == 0, "input changed");
    CHECK(tvpal_checkpoint_fingerprint("window=4", ins, 2, 0, &f4) == 0 && f4 &&
              strcmp(f1, f4), "changed input, same fingerprint");
    /* The checkpoint of one job is refused by the other. */
    struct tvpal_checkpoint_stats st;
    REQUIRE(tvpal_checkpoint_stats_init(&st) == 0, "init");
    fill(&st);
    CHECK(tvpal_checkpoint_save(g_dir, f1, 3, &st, NULL, NULL) == 0, "save");
    expect_load("other options", f3, STEPS, VOX, TVPAL_E_MISMATCH);
    expect_load("changed input", f4, STEPS, VOX, TVPAL_E_MISMATCH);
    expect_load("same job", f1, STEPS, VOX, 0);
    tvpal_checkpoint_stats_free(&st);
    free(f1);
    free(f2);
    free(f3);
    free(f4);
    unlink(in0);
    unlink(in1);
}

/* Saves a good checkpoint, replaces one line's text (or cuts the file) and
 * expects the load to fail with want. */
static void tamper(const char *what, const char *from, const char *to,
                   int want)
{
    struct tvpal_checkpoint_stats st;
    REQUIRE(tvpal_checkpoint_stats_init(&st) == 0, "init");
    fill(&st);
    REQUIRE(tvpal_checkpoint_save(g_dir, "job", 3, &st, NULL, NULL) == 0, "save");
    tvpal_checkpoint_stats_free(&st);
    char *text = read_text(), *p = strstr(text, from);
    REQUIRE(p, "%s: \"%s\" not in the checkpoint", what, from);
    char *out = NULL;
    REQUIRE(asprintf(&out, "%.*s%s%s", (int)(p - text), text, to,
                     p + strlen(from)) >= 0, "asprintf");
    write_text(out, strlen(out));
    expect_load(what, "job", STEPS, VOX, want);
    free(out);
    free(text);
}

static void test_damaged(void)
{
    struct tvpal_checkpoint_stats st;
    REQUIRE(tvpal_checkpoint_stats_init(&st) == 0, "init");
    fill(&st);
    REQUIRE(tvpal_checkpoint_save(g_dir, "job", 3, &st, NULL, NULL) == 0, "save");
    char *text = read_text();
    size_t len = strlen(text);
    /* Truncated inside the last line, at a line end (a histogram line
     * lost), and after the fixed lines. */
    write_text(text, len - 3);
    expect_load("cut inside a line", "job", STEPS, VOX, TVPAL_E_TRUNC);
    char *last = text + len - 1;
    while (last > text && last[-1] != '\n')
        last--;
    write_text(text, (size_t)(last - text));
    expect_load("last bin line lost", "job", STEPS, VOX, TVPAL_E_FORMAT);
    write_text(text, (size_t)(strstr(text, "max ") - text));
    expect_load("cut after min", "job", STEPS, VOX, TVPAL_E_FORMAT);
    write_text("", 0);
    expect_load("empty file", "job", STEPS, VOX, TVPAL_E_TRUNC);
    /* The same good file against another job size. */
    write_text(text, len);
    expect_load("intact", "job", STEPS, VOX, 0);
    expect_load("fewer steps than loaded", "job", 2, VOX, TVPAL_E_FORMAT);
    expect_load("more values than steps of voxels", "job", STEPS, 4,
                TVPAL_E_FORMAT);
    free(text);
    tvpal_checkpoint_stats_free(&st);
    /* Tampered lines. */
    tamper("count changed", "bin 5 12\n", "bin 5 13\n", TVPAL_E_FORMAT);
    tamper("classes out of order", "bin 5 12\nbin 40000 14\n",
           "bin 40000 14\nbin 5 12\n", TVPAL_E_FORMAT);
    tamper("class out of range", "bin 65535 1\n", "bin 65536 1\n",
           TVPAL_E_FORMAT);
    tamper("missing changed", "missing 2\n", "missing 3\n", TVPAL_E_FORMAT);
    tamper("missing line gone", "missing 2\n", "", TVPAL_E_FORMAT);
    tamper("done beyond the job", "done 3\n", "done 99\n", TVPAL_E_FORMAT);
    tamper("counted changed", "counted 30\n", "counted 31\n",
           TVPAL_E_FORMAT);
    tamper("done missing", "done 3\n", "", TVPAL_E_FORMAT);
    tamper("fingerprint line", "fingerprint ", "fingerprnt ", TVPAL_E_FORMAT);
    tamper("hash changed", "fingerprint ", "fingerprint 0", TVPAL_E_MISMATCH);
    tamper("garbage line", "nonfinite 7\n", "nonfinite 7\nbin x\n",
           TVPAL_E_FORMAT);
    /* Numbers that sscanf's %u and %llu took wrapped, signed or followed
     * by text: each would read as the good value. */
    tamper("done wrapping past 2^64", "done 3\n",
           "done 18446744073709551619\n",
           TVPAL_E_FORMAT);
    tamper("done with trailing text", "done 3\n", "done 3 x\n",
           TVPAL_E_FORMAT);
    tamper("class wrapping past 2^32", "bin 5 12\n", "bin 4294967301 12\n",
           TVPAL_E_FORMAT);
    tamper("negative count", "bin 5 12\n", "bin 5 -18446744073709551604\n",
           TVPAL_E_FORMAT);
    tamper("signed nonfinite", "nonfinite 7\n", "nonfinite +7\n",
           TVPAL_E_FORMAT);
    tamper("nonfinite overflowing", "nonfinite 7\n",
           "nonfinite 18446744073709551623\n", TVPAL_E_FORMAT);
}

/* Shard progress lines round trip; one naming a shard or record the job
 * does not have is refused. */
static void test_progress(void)
{
    struct tvpal_checkpoint_stats st;
    uint64_t filled[2 * 5] = {0}, f2[2 * 5];
    uint32_t crc[2 * 5] = {0}, c2[2 * 5];
    uint8_t miss[2] = {0, 1}, m2[2];
    struct tvpal_checkpoint_progress pr = {2, 5, filled, crc, miss},
                                     back = {2, 5, f2, c2, m2};
    filled[0] = 4096;
    crc[0] = 0xdeadbeef;
    filled[7] = 128;
    crc[7] = 0x00000001;
    REQUIRE(tvpal_checkpoint_stats_init(&st) == 0, "init");
    fill(&st);
    REQUIRE(tvpal_checkpoint_save(g_dir, "job", 3, &st, &pr, NULL) == 0,
            "save");
    uint64_t done = 0;
    memset(f2, 0xff, sizeof f2);
    CHECK(tvpal_checkpoint_load(g_dir, "job", STEPS, STEPS, VOX, &done, &st,
                                &back, NULL) == 0 && done == 3, "load");
    CHECK(!memcmp(f2, filled, sizeof f2) && !memcmp(c2, crc, sizeof c2) &&
              m2[0] == 0 && m2[1] == 1, "progress round trip");
    struct tvpal_checkpoint_progress small = {1, 5, f2, c2, m2};
    CHECK(tvpal_checkpoint_load(g_dir, "job", STEPS, STEPS, VOX, &done, &st,
                                &small, NULL) == TVPAL_E_FORMAT,
          "record of a shard the job lacks refused");
    fill(&st);
    char *text = read_text();
    char *p = strstr(text, "record 1 2 128 00000001");
    REQUIRE(p, "record line written: %s", text);
    memcpy(p + 16, "x", 1);
    write_text(text, strlen(text));
    CHECK(tvpal_checkpoint_load(g_dir, "job", STEPS, STEPS, VOX, &done, &st,
                                &back, NULL) == TVPAL_E_FORMAT,
          "bad CRC text refused");
    free(text);
    tvpal_checkpoint_stats_free(&st);
}

static void test_missing(void)
{
    struct tvpal_diag d = {{0}};
    CHECK(tvpal_checkpoint_remove(g_dir, &d) == 0, "remove: %s", d.msg);
    CHECK(access(path_in("checkpoint"), F_OK) != 0, "checkpoint remains");
    CHECK(tvpal_checkpoint_remove(g_dir, &d) == 0, "remove when missing");
    expect_load("missing file", "job", STEPS, VOX, TVPAL_E_OPEN);
    /* A directory that does not exist: the cause is in the diag. */
    struct tvpal_checkpoint_stats st;
    REQUIRE(tvpal_checkpoint_stats_init(&st) == 0, "init");
    fill(&st);
    char nodir[300];
    snprintf(nodir, sizeof nodir, "%s/none", g_dir);
    int rc = tvpal_checkpoint_save(nodir, "job", 1, &st, NULL, &d);
    CHECK(rc == TVPAL_E_OPEN, "save into a missing directory: %d", rc);
    CHECK(strstr(d.msg, "none/checkpoint: cannot create") &&
              strstr(d.msg, "No such file"),
          "diag \"%s\"", d.msg);
    tvpal_checkpoint_stats_free(&st);
}

int main(void)
{
    const char *tmp = getenv("TMPDIR");
    snprintf(g_dir, sizeof g_dir, "%s/tvpal-ckpt-XXXXXX",
             tmp && *tmp ? tmp : "/tmp");
    REQUIRE(mkdtemp(g_dir), "mkdtemp %s", g_dir);
    test_round_trip();
    test_fingerprint();
    test_damaged();
    test_progress();
    test_missing();
    tvpal_rmtree(g_dir);
    return tt_done("test-checkpoint");
}
