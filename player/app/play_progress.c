/* play_progress.c: progress of headless tvpal-play (see play_progress.h). */
#include "play_progress.h"
#include "play.h"
#include "tvpal_clock.h"

#include <math.h>
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

/* "1:02:03", "2:03" or "3 s" for s seconds; "?" when unknown. */
static void hms(double s, char *out, size_t cap)
{
    if (!(s >= 0) || s > 1e8) {
        snprintf(out, cap, "?");
        return;
    }
    unsigned long t = (unsigned long)(s + 0.5);
    if (t >= 3600)
        snprintf(out, cap, "%lu:%02lu:%02lu", t / 3600, t / 60 % 60, t % 60);
    else if (t >= 60)
        snprintf(out, cap, "%lu:%02lu", t / 60, t % 60);
    else
        snprintf(out, cap, "%lu s", t);
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
    char eta[32];
    hms(fps > 0 ? (p->total - done) / fps : NAN, eta, sizeof eta);
    const unsigned pct = (unsigned)(100.0 * done / (p->total ? p->total : 1));
    if (!p->tty) {
        fprintf(p->f, PROG ": %u/%u frames (%u%%), %.2f fps, ETA %s\n", done,
                p->total, pct, fps, eta);
        return;
    }
    char bar[BAR + 1];
    const unsigned full = (unsigned)((uint64_t)BAR * done / (p->total ? p->total : 1));
    for (unsigned i = 0; i < BAR; i++)
        bar[i] = i < full ? '#' : '.';
    bar[BAR] = 0;
    fprintf(p->f, "\r[%s] %u/%u frames %3u%% %.2f fps ETA %s\033[K", bar,
            done, p->total, pct, fps, eta);
    fflush(p->f);
    p->drawn = 1;
}

void play_progress_end(struct play_progress *p)
{
    if (p->f && p->drawn)
        fputs("\r\033[K", p->f);
    p->drawn = 0;
}
