/* play_timing.h: tvpal-play's per-frame figures.  Each rank measures a
 * play_rank_rec; rank 0 gathers them into one play_row per frame (the
 * slowest rank per phase, as the paper reports, bytes per rank and in all).
 * The columns of the timing CSV are described once, as a table (name,
 * format, value), from which the CSV header, its rows and the closing
 * summary line are all generated. */
#ifndef PLAY_TIMING_H
#define PLAY_TIMING_H

#include <stdint.h>
#include <stdio.h>

/* One rank's figures for one frame (gathered on rank 0; plain bytes). */
struct play_rank_rec {
    double io, stream, up, draw, read, enc, exch, blend, comp, gath, total;
    double classify, accum, warp;   /* cpu renderer phases (0 otherwise) */
    uint64_t bytes_read, bytes_sent, bytes_sent_total, gather_bytes, pixels;
    uint64_t bytes_needed;          /* of bytes_read, the step's own records
                                     * (tvpal_frame_stats) */
    int rc, fatal;
    char msg[200];
};

/* One frame as the CSV shows it. */
struct play_row {
    uint32_t step;
    char axis;
    struct play_rank_rec agg;       /* over ranks (play_timing_aggregate) */
    uint32_t drawn, skipped, uploads, stride, staged;
    uint32_t level;                 /* level of detail drawn */
    double full_ms;                 /* --progressive: on the first frame
                                     * at the full level after a jump,
                                     * the time from the jump's frame */
    double axis_switch_ms;
    int jump, ranks;
    double psnr;                    /* against the reference, or NAN */
    double time;                    /* the step's time value (manifest),
                                     * else the step */
};

/* Slowest rank per phase; bytes read and sent summed, sent also as the
 * maximum; pixels the maximum; the first error. */
void play_timing_aggregate(const struct play_rank_rec *r, int n,
                           struct play_rank_rec *out);

/* Sums over the frames of a run, for the summary line. */
struct play_totals {
    double sum[40];
    uint32_t frames;
};

void play_timing_csv_header(FILE *f);
void play_timing_csv_row(FILE *f, const struct play_row *row);
void play_timing_add(struct play_totals *t, const struct play_row *row);
/* "fps=... frames=... io_ms=... ... bytes_read=..." (no newline): means
 * over the frames of the per-frame phases, the sum of bytes read. */
void play_timing_summary(FILE *f, const struct play_totals *t, double fps);
/* Mean of the psnr_ref column over the frames. */
double play_timing_mean_psnr(const struct play_totals *t);

#endif
