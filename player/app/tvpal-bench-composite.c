/* tvpal-bench-composite: compositing speed under mpirun (scripts/
 * bench-cluster runs it).  Every rank makes a dense partial image (every
 * pixel non-transparent: the worst case for the run-length encoding) of
 * WxH, then each strategy composites it R times; rank 0 prints the median
 * time, the bytes the busiest rank sent, the model image bytes x (1 - 1/K)
 * and a memory-bandwidth bound: (bytes the busiest rank moves: sent +
 * received + blended reads and writes) / memcpy bandwidth measured here.
 *
 * Usage: tvpal-bench-composite [W H [R]]  (default 512 512 9).
 * The steps of main: the arguments, the communicator, the partial image,
 * the memcpy bandwidth, each strategy timed, rank 0's line. */
#include "tvpal_clock.h"
#include "tvpal_comm.h"
#include "tvpal_composite.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG "tvpal-bench-composite"

struct bench_args {
    unsigned width, height;
    unsigned reps;            /* repetitions per strategy; the median counts */
};

/* W H [R] from the command line, as atoi reads them (no checks: a helper
 * of scripts/bench-cluster, which passes sane values). */
static struct bench_args parse_args(int argc, char **argv)
{
    struct bench_args a = {512, 512, 9};
    if (argc >= 3) {
        a.width = (unsigned)atoi(argv[1]);
        a.height = (unsigned)atoi(argv[2]);
    }
    if (argc >= 4)
        a.reps = (unsigned)atoi(argv[3]);
    return a;
}

/* The communicator: MPI when built with it (a run without mpirun is a job
 * of one), else the single process.  Returns 0 or -1 (printed). */
/* MPI when a launcher started this process, else one process. */
static int comm_start(int *argc, char ***argv, struct tvpal_comm *c)
{
    struct tvpal_diag d = {{0}};
    if (tvpal_comm_open(c, TVPAL_COMM_AUTO, argc, argv, &d) < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg);
        return -1;
    }
    return 0;
}

static void comm_stop(struct tvpal_comm *c)
{
    tvpal_comm_close(c);
}

/* A dense premultiplied RGBA image (w*h pixels), different on each rank. */
static void make_partial_image(float *img, unsigned w, unsigned h, int rank)
{
    for (size_t i = 0; i < (size_t)w * h; i++) {
        float a = 0.2f + 0.6f * (float)((i * 2654435761u + (unsigned)rank) % 1000) /
                             1000.0f;
        img[4 * i] = 0.5f * a;
        img[4 * i + 1] = 0.3f * a;
        img[4 * i + 2] = 0.1f * a;
        img[4 * i + 3] = a;
    }
}

/* memcpy bandwidth of one core in bytes/s, measured by rank 0 alone while
 * the others wait at the barrier (0 on the other ranks, or when the buffers
 * cannot be had). */
static double memcpy_bandwidth(struct tvpal_comm *c)
{
    double bw = 0;
    c->barrier(c);
    if (c->rank == 0) {
        /* 128 MiB each way: larger than the caches, so DRAM is measured. */
        size_t big = (size_t)128 << 20;
        char *x = malloc(big), *y = malloc(big);
        if (x && y) {
            memset(x, 1, big);
            memset(y, 2, big);
            volatile char sink = 0;
            double t0 = tvpal_now();
            for (int k = 0; k < 4; k++) {
                char *dst = k & 1 ? x : y, *src = k & 1 ? y : x;
                memcpy(dst, src, big);
                sink = (char)(sink + dst[(size_t)k * 4099 % big]);
            }
            bw = 4.0 * big / (tvpal_now() - t0);
            (void)sink;
        }
        free(x);
        free(y);
    }
    c->barrier(c);
    return bw;
}

static int cmpd(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* One strategy over all ranks: the median time (slowest rank of each
 * repetition) and the bytes of the busiest rank. */
struct strategy_result {
    double median_s;
    uint64_t sent, gathered;
};

/* Composites img (copied into work first, as compositing consumes it)
 * a->reps times with kind.  Returns 0 or -1 (printed). */
static int time_strategy(struct tvpal_compositor *cx, struct tvpal_comm *c,
                         enum tvpal_compose_kind kind, const struct bench_args *a,
                         const float *img, float *work, uint8_t *out,
                         struct strategy_result *res)
{
    const size_t n = (size_t)a->width * a->height * 4;
    const char *name = kind == TVPAL_COMPOSE_GATHER ? "gather" : "bswap";
    double *times = calloc(a->reps, sizeof *times);
    struct tvpal_compose_stats st = {0};
    if (!times) {
        fprintf(stderr, "out of memory\n");
        return -1;
    }
    for (unsigned r = 0; r < a->reps; r++) {
        memcpy(work, img, n * sizeof *img);
        c->barrier(c);
        double t0 = tvpal_now();
        if (tvpal_composite(cx, c, kind, 0, work, out, &st) < 0) {
            fprintf(stderr, "composite failed\n");
            free(times);
            return -1;
        }
        double el = tvpal_now() - t0;
        c->allmax(c, &el, 1);
        times[r] = el;
    }
    if (getenv("TVPAL_BENCH_VERBOSE"))
        fprintf(stderr, "rank %d %s: encode %.2f exchange %.2f blend %.2f "
                "gather %.2f ms\n", c->rank, name, st.encode_ms,
                st.exchange_ms, st.blend_ms, st.gather_ms);
    qsort(times, a->reps, sizeof *times, cmpd);
    res->median_s = times[a->reps / 2];
    double s[2] = {(double)st.bytes_sent, (double)st.gather_bytes};
    c->allmax(c, s, 2);
    res->sent = (uint64_t)s[0];
    res->gathered = (uint64_t)s[1];
    free(times);
    return 0;
}

/* Rank 0's line: both strategies against the byte model and the memory
 * bound.  K ranks, bw the memcpy bandwidth (bytes/s). */
static void print_result(const struct bench_args *a, int K, double bw,
                         const struct strategy_result *bswap,
                         const struct strategy_result *gather)
{
    const size_t n = (size_t)a->width * a->height * 4;
    const double img_bytes = (double)n * sizeof(uint16_t); /* on the wire */
    double model = img_bytes * (1.0 - 1.0 / K);
    /* Busiest rank under binary swap moves its sent bytes, the same
     * received, and blends the received part (read + write own). */
    double moved = 2 * model + 2 * model + img_bytes / K;
    double bound = moved / bw;
    printf("K=%d %ux%u: bswap %.2f ms, gather-to-root %.2f ms (bswap "
           "%.2fx faster); busiest rank sends %llu compositing bytes "
           "(model (1-1/K) x image = %.0f, %+.2f%%) + %llu final-gather "
           "bytes under bswap, %llu under gather-to-root; memory bound "
           "%.2f ms (one core's memcpy %.1f GB/s): bswap at %.2fx of it\n",
           K, a->width, a->height, bswap->median_s * 1e3,
           gather->median_s * 1e3, gather->median_s / bswap->median_s,
           (unsigned long long)bswap->sent, model,
           100.0 * ((double)bswap->sent - model) / model,
           (unsigned long long)bswap->gathered,
           (unsigned long long)gather->sent, bound * 1e3, bw / 1e9,
           bswap->median_s / bound);
}

int main(int argc, char **argv)
{
    const struct bench_args a = parse_args(argc, argv);
    struct tvpal_comm c;
    if (comm_start(&argc, &argv, &c) < 0)
        return 1;
    size_t n = (size_t)a.width * a.height * 4;
    float *img = malloc(n * sizeof *img), *work = malloc(n * sizeof *img);
    uint8_t *out = malloc(n);
    struct tvpal_compositor *cx;
    if (!img || !work || !out ||
        tvpal_compositor_create(&cx, a.width, a.height, c.size) < 0) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    make_partial_image(img, a.width, a.height, c.rank);
    double bw = memcpy_bandwidth(&c);
    struct strategy_result bswap, gather;
    /* A rank that fails returns at once, without finalizing: the launcher
     * then ends the job instead of leaving the others in a collective. */
    if (time_strategy(cx, &c, TVPAL_COMPOSE_BSWAP, &a, img, work, out, &bswap) < 0 ||
        time_strategy(cx, &c, TVPAL_COMPOSE_GATHER, &a, img, work, out, &gather) < 0)
        return 1;
    if (c.rank == 0)
        print_result(&a, c.size, bw, &bswap, &gather);
    tvpal_compositor_free(cx);
    free(img);
    free(work);
    free(out);
    comm_stop(&c);
    return 0;
}
