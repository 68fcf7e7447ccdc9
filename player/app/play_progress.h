/* play_progress.h: headless tvpal-play's progress on stderr.  On a
 * terminal one line that updates in place (a bar, frames, fps, ETA), at
 * most PLAY_PROGRESS_TTY_S apart and erased at the end; otherwise (a log,
 * a pipe, mpirun's forwarding) a plain line every `every` seconds; with
 * --quiet nothing.  Rank 0 only. */
#ifndef PLAY_PROGRESS_H
#define PLAY_PROGRESS_H

#include <stdint.h>
#include <stdio.h>

#define PLAY_PROGRESS_TTY_S 0.2     /* the bar's redraw period, seconds */
#define PLAY_PROGRESS_EVERY_S 10.0  /* --progress default, seconds */

struct play_progress {
    FILE *f;             /* NULL: off */
    int tty;             /* f is a terminal */
    double every;        /* seconds between plain lines (0: every frame) */
    double t0, last;     /* start, last output (tvpal_now) */
    uint32_t total;      /* frames to draw */
    int drawn;           /* a bar is on the terminal line */
};

/* Starts counting total frames now.  quiet: no output at all. */
void play_progress_start(struct play_progress *p, FILE *f, int quiet,
                         double every, uint32_t total);
/* After frame `done` (1..total) is written; output when it is time. */
void play_progress_update(struct play_progress *p, uint32_t done);
/* Erases the bar (the summary follows on a clean line). */
void play_progress_end(struct play_progress *p);

#endif
