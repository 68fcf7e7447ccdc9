/* tvpal-check: helper for the shell tests (not installed).
 *   tvpal-check seqjump DIR   decoding by random jumps equals sequential
 *                             decoding, bit for bit, on every stored axis
 *                             (the others refused); forward
 *                             playback reads one record per step and shard
 *                             (none where no window starts: the joined
 *                             schedule's steps 1..N-1), a jump at most N.
 *   tvpal-check cmp A B       RMSE, max |A-B| and PSNR (peak of A) of two raw
 *                             float32 files, as key=value.
 *   tvpal-check peakrss CMD...  runs CMD, prints its peak resident memory
 *                             (getrusage of the child) as maxrss_kb=N on
 *                             stderr and exits with CMD's status. */
#include "tvpal_dataset.h"
#include "tvpal_test.h"

#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

static int seqjump(const char *dir)
{
    struct tvpal_dataset *ds;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_dataset_open(&ds, dir, &d) == 0, "%s", d.msg);
    const uint32_t T = ds->m.steps, N = ds->m.window;
    const size_t nvox = (size_t)ds->m.dims[0] * ds->m.dims[1] * ds->m.dims[2];
    float *seq = malloc(nvox * T * sizeof *seq), *v = malloc(nvox * sizeof *v);
    REQUIRE(seq && v, "memory");
    for (unsigned a = 0; a < 3; a++) {
        struct tvpal_volreader *r;
        if (!tvpal_dataset_has_axis(ds, a)) {
            CHECK(tvpal_volreader_create(&r, ds, a, &d) == TVPAL_E_INVAL,
                  "axis %u is not stored, yet a reader was made", a);
            continue;
        }
        REQUIRE(tvpal_volreader_create(&r, ds, a, &d) == 0, "reader: %s",
                d.msg);
        uint64_t maxrec = 0;
        for (uint32_t k = 0; k < ds->m.nodes; k++)
            maxrec += tvpal_shard_max_record(ds->shards[a][k]);
        for (uint32_t t = 0; t < T; t++) {
            uint64_t before = tvpal_volreader_bytes_read(r), rec = 0;
            CHECK(tvpal_volreader_read(r, t, seq + nvox * t, &d) == 0,
                  "axis %u step %u: %s", a, t, d.msg);
            for (uint32_t k = 0; k < ds->m.nodes; k++) {
                const struct tvpal_index_entry *e =
                    tvpal_shard_entry(ds->shards[a][k], t);
                rec += e->chunk_count ? e->bytes : 0;
            }
            if (t > 0)
                CHECK(tvpal_volreader_bytes_read(r) - before == rec,
                      "axis %u step %u: forward step read %llu bytes, its "
                      "records are %llu", a, t,
                      (unsigned long long)(tvpal_volreader_bytes_read(r) - before),
                      (unsigned long long)rec);
        }
        /* Random jumps, on the same reader and on fresh ones. */
        for (unsigned i = 0; i < 3 * T + 5; i++) {
            uint32_t t = (uint32_t)(tt_rand64() % T);
            struct tvpal_volreader *fresh = NULL, *use = r;
            if (i % 3 == 0) {
                REQUIRE(tvpal_volreader_create(&fresh, ds, a, &d) == 0,
                        "reader: %s", d.msg);
                use = fresh;
            }
            uint64_t before = tvpal_volreader_bytes_read(use);
            CHECK(tvpal_volreader_read(use, t, v, &d) == 0, "jump: %s", d.msg);
            CHECK(tvpal_volreader_bytes_read(use) - before <= N * maxrec,
                  "jump to %u read more than N records", t);
            CHECK(!memcmp(v, seq + nvox * t, nvox * sizeof *v),
                  "axis %u: jump to step %u differs from sequential decode",
                  a, t);
            tvpal_volreader_free(fresh);
        }
        /* Backward playback. */
        for (uint32_t t = T; t-- > 0;) {
            CHECK(tvpal_volreader_read(r, t, v, &d) == 0, "back: %s", d.msg);
            CHECK(!memcmp(v, seq + nvox * t, nvox * sizeof *v),
                  "axis %u: backward step %u differs", a, t);
        }
        tvpal_volreader_free(r);
    }
    free(seq);
    free(v);
    tvpal_dataset_close(ds);
    return tt_done("seqjump");
}

static float *load(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    REQUIRE(f, "cannot open %s", path);
    fseek(f, 0, SEEK_END);
    long sz = ftell(f);
    fseek(f, 0, SEEK_SET);
    float *v = malloc((size_t)sz);
    REQUIRE(v && fread(v, 1, (size_t)sz, f) == (size_t)sz, "read %s", path);
    fclose(f);
    *n = (size_t)sz / 4;
    return v;
}

static int cmp(const char *pa, const char *pb)
{
    size_t na, nb;
    float *a = load(pa, &na), *b = load(pb, &nb);
    REQUIRE(na == nb, "%s and %s differ in size", pa, pb);
    double lo = a[0], hi = a[0], sse = 0, mx = 0;
    for (size_t i = 0; i < na; i++) {
        lo = a[i] < lo ? a[i] : lo;
        hi = a[i] > hi ? a[i] : hi;
        double e = (double)a[i] - b[i];
        sse += e * e;
        mx = fabs(e) > mx ? fabs(e) : mx;
    }
    double mse = sse / (double)na;
    printf("rmse=%.9g max_abs_error=%.9g psnr=%.4f\n", sqrt(mse), mx,
           mse > 0 ? 10 * log10((hi - lo) * (hi - lo) / mse) : INFINITY);
    free(a);
    free(b);
    return 0;
}

static int peakrss(char **cmd)
{
    pid_t pid = fork();
    if (pid < 0)
        return 99;
    if (pid == 0) {
        execvp(cmd[0], cmd);
        _exit(127);
    }
    int status;
    struct rusage ru;
    if (wait4(pid, &status, 0, &ru) != pid)
        return 99;
    fprintf(stderr, "maxrss_kb=%ld\n", ru.ru_maxrss);
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

int main(int argc, char **argv)
{
    if (argc >= 3 && !strcmp(argv[1], "peakrss"))
        return peakrss(argv + 2);
    if (argc == 3 && !strcmp(argv[1], "seqjump"))
        return seqjump(argv[2]);
    if (argc == 4 && !strcmp(argv[1], "cmp"))
        return cmp(argv[2], argv[3]);
    fprintf(stderr, "usage: tvpal-check seqjump DIR | cmp A B | peakrss "
            "CMD...\n");
    return 99;
}
