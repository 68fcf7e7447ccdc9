/* tvpal-bench-composite: compositing speed under mpirun (scripts/
 * bench-cluster runs it).  Every rank makes a dense partial image (every
 * pixel non-transparent: the worst case for the run-length encoding) of
 * WxH, then each strategy composites it R times; rank 0 prints the median
 * time, the bytes the busiest rank sent, the model image bytes x (1 - 1/K)
 * and a memory-bandwidth bound: (bytes the busiest rank moves: sent +
 * received + blended reads and writes) / memcpy bandwidth measured here. */
#include "tvpal_clock.h"
#include "tvpal_comm.h"
#include "tvpal_composite.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int cmpd(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    unsigned W = 512, H = 512, R = 9;
    if (argc >= 3) {
        W = (unsigned)atoi(argv[1]);
        H = (unsigned)atoi(argv[2]);
    }
    if (argc >= 4)
        R = (unsigned)atoi(argv[3]);
    struct tvpal_comm c;
    struct tvpal_diag d = {{0}};
    if (tvpal_comm_open(&c, TVPAL_COMM_AUTO, &argc, &argv, &d) < 0) {
        fprintf(stderr, "tvpal-bench-composite: %s\n", d.msg);
        return 1;
    }
    size_t n = (size_t)W * H * 4;
    float *img = malloc(n * sizeof *img), *work = malloc(n * sizeof *img);
    uint8_t *out = malloc(n);
    struct tvpal_compositor *cx;
    if (!img || !work || !out ||
        tvpal_compositor_create(&cx, W, H, c.size) < 0) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    for (size_t i = 0; i < (size_t)W * H; i++) {
        float a = 0.2f + 0.6f * (float)((i * 2654435761u + (unsigned)c.rank) % 1000) / 1000.0f;
        img[4 * i] = 0.5f * a;
        img[4 * i + 1] = 0.3f * a;
        img[4 * i + 2] = 0.1f * a;
        img[4 * i + 3] = a;
    }
    /* memcpy bandwidth of one core, measured by rank 0 alone while the
     * others wait at the barrier. */
    double bw = 0;
    c.barrier(&c);
    if (c.rank == 0) {
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
    c.barrier(&c);
    double med[2];
    uint64_t sent[2], gath[2];
    for (int k = 0; k < 2; k++) {
        double *times = calloc(R, sizeof *times);
        struct tvpal_compose_stats st = {0};
        for (unsigned r = 0; r < R; r++) {
            memcpy(work, img, n * sizeof *img);
            c.barrier(&c);
            double t0 = tvpal_now();
            if (tvpal_composite(cx, &c, k ? TVPAL_COMPOSE_GATHER
                                          : TVPAL_COMPOSE_BSWAP, 0, work, out,
                                &st) < 0) {
                fprintf(stderr, "composite failed\n");
                return 1;
            }
            double el = tvpal_now() - t0;
            c.allmax(&c, &el, 1);
            times[r] = el;
        }
        if (getenv("TVPAL_BENCH_VERBOSE"))
            fprintf(stderr, "rank %d %s: encode %.2f exchange %.2f blend %.2f "
                    "gather %.2f ms\n", c.rank, k ? "gather" : "bswap",
                    st.encode_ms, st.exchange_ms, st.blend_ms, st.gather_ms);
        qsort(times, R, sizeof *times, cmpd);
        med[k] = times[R / 2];
        double s[2] = {(double)st.bytes_sent, (double)st.gather_bytes};
        c.allmax(&c, s, 2);
        sent[k] = (uint64_t)s[0];
        gath[k] = (uint64_t)s[1];
        free(times);
    }
    if (c.rank == 0) {
        const double img_bytes = (double)n * sizeof(uint16_t); /* on the wire */
        const int K = c.size;
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
               K, W, H, med[0] * 1e3, med[1] * 1e3, med[1] / med[0],
               (unsigned long long)sent[0], model,
               100.0 * ((double)sent[0] - model) / model,
               (unsigned long long)gath[0], (unsigned long long)sent[1],
               bound * 1e3, bw / 1e9, med[0] / bound);
    }
    tvpal_compositor_free(cx);
    free(img);
    free(work);
    free(out);
    tvpal_comm_close(&c);
    return 0;
}
