/* play_progress.c: progress of headless tvpal-play (see play_progress.h). */
#include "play_progress.h"
#include "play.h"
#include "tvpal_cli.h"
#include "tvpal_clock.h"

#include <unistd.h>

#define PROG PLAY_PROG
#define BAR 30      /* the bar's cells */

void play_progress_start(struct play_progress *p, FILE *f, int quiet,
                         double every, uint32_t total)
{
    *p = (struct play_progress){.f = quiet ? NULL : f, .every = every,
                                .total = total};
    p->tty = p->f && isatty(fileno(p->f));
    p->t0 = p->last = tvpal_now();
}

void play_progress_update(struct play_progress *p, uint32_t done)
{
    if (!p->f)
        return;
    const double now = tvpal_now(), el = now - p->t0;
    const int last = done >= p->total;
    if (p->tty ? (now - p->last < PLAY_PROGRESS_TTY_S && !last)
               : (now - p->last < p->every || last))
        return;   /* a log gets no line for the end: the summary says it */
    p->last = now;
    const double fps = el > 0 ? done / el : 0;
    /* The encoder's line, so both programs report alike. */
    char line[256];
    tvpal_progress_format(line, sizeof line, done, p->total, "frames", fps,
                          "fps", fps > 0 ? (p->total - done) / fps : -1,
                          p->tty ? BAR : 0);
    if (!p->tty) {
        fprintf(p->f, PROG ": %s\n", line);
        return;
    }
    fprintf(p->f, "\r%s\033[K", line);
    fflush(p->f);
    p->drawn = 1;
}

void play_progress_end(struct play_progress *p)
{
    if (p->f && p->drawn)
        fputs("\r\033[K", p->f);
    p->drawn = 0;
}
