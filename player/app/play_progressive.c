/* play_progressive.c: which level each frame draws under --progressive
 * (see play_progressive.h). */
#define _GNU_SOURCE
#include "play_progressive.h"
#include "tvpal_clock.h"
#include "tvpal_stream.h"

#include <errno.h>
#include <math.h>
#include <string.h>
#include <time.h>

void play_prog_init(struct play_prog *p, double period_ms, double budget_ms,
                    uint32_t first, uint32_t last, int exact)
{
    memset(p, 0, sizeof *p);
    p->exact = exact;
    p->period_ms = period_ms > 0 ? period_ms : 0;
    p->budget_ms = budget_ms > 0 ? budget_ms : 1;
    p->first = first;
    p->last = last;
}

uint32_t play_prog_next(const struct play_prog *p, uint32_t t, int dir,
                        uint32_t steps)
{
    const uint32_t lo = p->first < p->last ? p->first : p->last;
    const uint32_t hi = p->first < p->last ? p->last : p->first;
    if (dir == 0)
        return t;
    const int64_t next = (int64_t)t + (dir < 0 ? -1 : 1);
    if (t >= lo && t <= hi) /* the range played: round again */
        return next < lo ? hi : next > hi ? lo : (uint32_t)next;
    return next < 0 || next >= steps ? t : (uint32_t)next;
}

/* The milliseconds level k's records of a step take from scratch (the
 * record of every window that covers it) under view v0 (level 0's), at
 * what was measured: their stored bytes at the disk's rate, or inflating
 * their plain bytes where that takes longer (coded records: one is
 * inflated while the next is read, so the slower of the two sets the
 * pace).  0 while the rate is unknown, and for a level in RAM. */
static double step_reads_ms(const struct play_prog *p,
                            struct play_session *s, unsigned k,
                            const struct tvpal_view *v0)
{
    struct tvpal_player *pk = play_level_player(s, k);
    if (p->rate <= 0 || tvpal_player_incore_bytes(pk))
        return 0;
    uint64_t stored = 0, plain = 0;
    struct tvpal_view vk;
    play_level_view(s, k, v0, &vk);
    tvpal_player_step_bytes(pk, &vk, &stored, &plain);
    if (!stored) { /* the axis not open yet: a byte per voxel */
        const uint32_t *d = tvpal_player_manifest(pk)->dims;
        stored = plain = (uint64_t)d[0] * d[1] * d[2];
    }
    return fmax((double)stored / p->rate, (double)plain * p->inflate_ms);
}

/* step_reads_ms for step t, 0 also for a step among those a coarser level
 * keeps around the playhead (a frame there reads nothing). */
static double level_reads_ms(const struct play_prog *p,
                             struct play_session *s, unsigned k,
                             const struct tvpal_view *v0, uint32_t t)
{
    if (k > 0) {
        struct tvpal_view vk;
        int near = 0;
        play_level_view(s, k, v0, &vk);
        if (tvpal_player_kept(play_level_player(s, k), &vk, t, &near) &&
            near)
            return 0;
    }
    return step_reads_ms(p, s, k, v0);
}

/* Whether the full level reads ahead once reads have fallen behind
 * (play_prog_keep): playing, with a clock to fall behind. */
static int reads_ahead(const struct play_prog *p, int dir)
{
    return p->period_ms > 0 && dir != 0;
}

/* The budget one frame's reads are planned against: the clock's period,
 * else a steady frame's measured time, else --budget-ms. */
static double frame_budget(const struct play_prog *p)
{
    return p->period_ms > 0 ? p->period_ms
           : p->steady_ms > 0 ? p->steady_ms : p->budget_ms;
}

/* How long this frame may wait for the full level's records: what is
 * left of its period after drawing (with a clock), else a quarter of a
 * drawing's time. */
static double frame_slack(const struct play_prog *p)
{
    if (p->period_ms <= 0)
        return 0.25 * p->draw_ms;
    const double left = p->next_due > 0 ? (p->next_due - tvpal_now()) * 1e3
                                        : p->period_ms;
    return left > p->draw_ms ? left - p->draw_ms : 0;
}

/* The read rate from a step's reads: its bytes over the longer of the
 * time waited for them and the stager's time preparing them, for a MiB or
 * more; a smaller read counts only when waiting for it took 10 ms or more
 * (a slow disk): otherwise it measures latency and the stager's own work,
 * not the disk. */
static void measure_rate(struct play_prog *p, double io_ms, double stage_ms,
                         uint64_t bytes)
{
    if (p->metered)
        return; /* the meter's figure is the disk's own */
    const double ms = bytes >= (1u << 20) ? fmax(io_ms, stage_ms)
                      : bytes >= (64u << 10) && io_ms >= 10 ? io_ms : 0;
    if (ms > 0.1) {
        const double r = (double)bytes / ms;
        p->rate = p->rate > 0 ? 0.8 * p->rate + 0.2 * r : r;
    }
}

/* The meter's figures count once this many more bytes are read (or
 * inflated) since the last sample: a few records (a step's at 512^3 are
 * 34 MB to 136 MB), so that one read's latency is not taken for a
 * rate. */
#define METER_MIN ((uint64_t)16 << 20)

/* An estimate moved towards a new measurement x (the first: x). */
static double ewma(double old, double x)
{
    return old > 0 ? 0.7 * old + 0.3 * x : x;
}

/* The full level's read rate and inflating cost from its stream's meter
 * (tvpal_player_meter: the disk's busy time, not the frame's waits,
 * which also count the stager's other work and the reads queued before
 * the step's own), over what was read since the last sample.  A view of
 * another level or axis reads through another stream: its meter is
 * sampled afresh. */
static void meter_sample(struct play_prog *p, struct play_session *s,
                         unsigned full, const struct tvpal_view *vf)
{
    struct tvpal_stream_meter m;
    struct tvpal_stream_meter *last = &p->meter;
    tvpal_player_meter(play_level_player(s, full), vf, &m);
    const unsigned of = 1 + 4 * full + vf->axis;
    if (p->meter_of != of || m.read_bytes < last->read_bytes) {
        p->meter_of = of;
        *last = m;
        return;
    }
    const double ds = m.read_s - last->read_s;
    if (m.read_bytes - last->read_bytes >= METER_MIN && ds > 1e-3) {
        p->rate = ewma(p->metered ? p->rate : 0,
                       (double)(m.read_bytes - last->read_bytes) / (ds * 1e3));
        p->metered = 1;
        last->read_bytes = m.read_bytes;
        last->read_s = m.read_s;
    }
    const double di = m.inflate_s - last->inflate_s;
    if (m.inflated_bytes - last->inflated_bytes >= METER_MIN && di > 0) {
        p->inflate_ms = ewma(p->inflate_ms,
                             di * 1e3 / (double)(m.inflated_bytes -
                                                 last->inflated_bytes));
        last->inflated_bytes = m.inflated_bytes;
        last->inflate_s = m.inflate_s;
    }
}

/* Frames until the full level's step can be ready, starting lag steps
 * behind t: the reads of the windows begun over lag + d steps (all of
 * them from N on, N the window), and those of `run` steps after it, must
 * fit d frames' budgets. */
static uint32_t frames_ahead(const struct play_prog *p,
                             struct play_session *s, unsigned full,
                             const struct tvpal_view *v0, uint32_t lag,
                             uint32_t run)
{
    const double budget = frame_budget(p);
    const double all = step_reads_ms(p, s, full, v0);
    const uint32_t n = s->m->window ? s->m->window : 1;
    const uint32_t most = n + 1 + (uint32_t)fmin(ceil(all / budget) *
                                                 (1 + (double)run / n), 1e6);
    for (uint32_t d = 1; d < most; d++) {
        const double share = (lag + (double)d >= n ? 1 : (lag + (double)d) / n) +
                             (double)run / n;
        if (share * all <= d * budget)
            return d;
    }
    return most;
}

/* Starts or goes on with a refinement at step t, whose full level shows
 * a step lag steps behind (a jump: any): the coarser level drawn
 * meanwhile, and the full level's step prepared d frames on.  A new one
 * (fresh: a jump, or reads behind) starts the clock of *refined.
 * Returns 0, or -1 when the full level has nothing coarser or cannot
 * prepare (in-core, it has nothing to read). */
static int start_refine(struct play_prog *p, struct play_session *s,
                        unsigned full, const struct tvpal_view *v0,
                        const struct tvpal_view *vf, uint32_t t, int dir,
                        uint32_t lag, int fresh, int jump)
{
    const unsigned nl = s->nlevels;
    if (full + 1 >= nl)
        return -1;
    const double budget = frame_budget(p);
    unsigned k = full + 1;
    while (k + 1 < nl && level_reads_ms(p, s, k, v0, t) > budget)
        k++;
    /* A jump plans for its step's reads (the soonest it can be back);
     * reads behind the clock plan for a run of frames from it: the
     * stream's prefetch beyond it, or the full level's read-ahead
     * (play_prog_keep) where it has one, is read before it is due, so
     * that the full level then holds for that many frames and longer
     * (the disk goes on reading ahead, at its rate, while they are drawn:
     * at a rate r of the need a run of B steps read ahead lasts about
     * B / (1 - r) frames, and the share of frames at full level tends to
     * r as B grows).  Either way the prefetch is
     * queued after the step's own reads (which it does not delay), so
     * the frames after the return find their records.  Plus what the
     * last plan missed by: the stager may still be busy with a steady
     * step's reads (and their prefetch) when asked. */
    uint32_t run = jump || dir == 0 ? 0 : s->o->po.prefetch;
    if (run && reads_ahead(p, dir)) {
        /* The full level reads ahead (play_prog_keep, from this stall
         * on): the run is planned for what it keeps.  Without a clock
         * (the window without --fps) it does not, and the run is the
         * prefetch's. */
        const unsigned ahead = tvpal_player_kept(play_level_player(s, full),
                                                 vf, t, NULL);
        run = ahead > run ? ahead : run;
    }
    /* Within the range played: a plan past its length would meet its
     * step a round early, before the read-ahead it planned for; the run
     * is shortened until it fits. */
    const uint32_t lo = p->first < p->last ? p->first : p->last;
    const uint32_t hi = p->first < p->last ? p->last : p->first;
    const uint32_t len = t >= lo && t <= hi ? hi - lo + 1 : s->m->steps;
    uint32_t d = frames_ahead(p, s, full, v0, lag, run) + p->late;
    while (run > 0 && d >= len) {
        run /= 2;
        d = frames_ahead(p, s, full, v0, lag, run) + p->late;
    }
    uint32_t tp = t;
    for (uint32_t i = 0; i < d; i++)
        tp = play_prog_next(p, tp, dir, s->m->steps);
    struct tvpal_diag dd = {{0}};
    if (tvpal_player_prepare(play_level_player(s, full), vf, tp, dir, dir != 0,
                             &dd) < 0)
        return -1;
    p->active = 1;
    p->planned_rate = p->rate > 0;
    p->full = full;
    p->coarse = k;
    p->axis = vf->axis;
    p->target = tp;
    /* A later frame: d on (round the range back to t, if so), or still
     * the next. */
    p->due = dir == 0 ? 1 : d;
    p->frames = 0;
    if (fresh) {
        p->t0 = tvpal_now();
        if (jump)
            p->jumps++;
        else
            p->stalls++;
    }
    return 0;
}

/* The frame is the full level's: nothing pending, no lag. */
static int draw_full(struct play_prog *p, unsigned full)
{
    p->active = 0;
    p->since = 0;
    return (int)full;
}

int play_prog_frame(struct play_prog *p, struct play_session *s,
                    const struct tvpal_view *v0, unsigned full, uint32_t t,
                    int dir, int jump, double *refined,
                    struct tvpal_diag *diag)
{
    *refined = 0;
    p->load_rc = 0;
    const int waits = p->exact;
    struct tvpal_view vf;
    struct tvpal_player *pf = play_level_player(s, full);
    play_level_view(s, full, v0, &vf);
    meter_sample(p, s, full, &vf);
    if (p->active && (jump || p->full != full || p->axis != vf.axis))
        p->active = 0;  /* another step or view: planned again */
    p->since = jump || p->since >= UINT32_MAX / 2 ? UINT32_MAX / 2
                                                  : p->since + 1;
    int fresh = 1;
    if (p->active) {
        p->frames++;
        if (t == p->target) {
            /* The step planned for: its records waited for in an exact
             * sequence (the frame installs them); late otherwise, the
             * frame after installs them and goes on from there (still,
             * the same step is drawn again then). */
            const double slack = dir ? frame_slack(p) : p->budget_ms;
            if (waits || tvpal_player_ready(pf, &vf, t, slack)) {
                p->late /= 2; /* on time: the margin shrinks again */
                *refined = (tvpal_now() - p->t0) * 1e3;
                return draw_full(p, full);
            }
            return (int)p->coarse;
        }
        /* A step whose records are in already (read ahead, or kept
         * round a loop) is drawn at full level on the way, which ends
         * the refinement (full_ms); the plan is made again at the next
         * step that is not. */
        if (!waits && tvpal_player_ready(pf, &vf, t, 0)) {
            *refined = (tvpal_now() - p->t0) * 1e3;
            return draw_full(p, full);
        }
        if (p->frames < p->due)
            return (int)p->coarse;
        /* Past the step planned (late, or the range wrapped): once its
         * reads are in, it is installed (nothing read; the stager left
         * idle, not set on the step after it) and what is left is
         * planned from here; in an exact sequence it is installed at
         * once, and the frame reads the rest. */
        if (!waits && !tvpal_player_ready(pf, &vf, p->target, 0))
            return (int)p->coarse;
        struct tvpal_stream_stats st = {0};
        /* A record that fails leaves its slices at their last good
         * window, as a frame's load does; the error is the frame's. */
        p->load_rc = tvpal_player_seek(pf, &vf, p->target, waits ? dir : 0,
                                       &st, diag);
        const uint32_t past = p->frames - p->due;
        if (p->planned_rate) /* a plan made without a rate is no margin */
            p->late = past > p->late ? past : p->late;
        p->active = 0;
        measure_rate(p, st.io_wait_ms, st.stage_ms, st.bytes_needed);
        p->since = past;
        if (waits) {
            *refined = (tvpal_now() - p->t0) * 1e3;
            return draw_full(p, full);
        }
        fresh = 0;
    }
    /* In an exact sequence only a jump is refined: a steady frame waits
     * for its records, so that which frames are coarse does not depend on
     * the disk's timing. */
    if ((waits && !jump) ||
        tvpal_player_ready(pf, &vf, t, jump ? 0 : frame_slack(p))) {
        if (!fresh)
            *refined = (tvpal_now() - p->t0) * 1e3;
        return draw_full(p, full);
    }
    if (start_refine(p, s, full, v0, &vf, t, dir, p->since, fresh, jump) < 0)
        return draw_full(p, full); /* nothing coarser, or nothing to read */
    return (int)p->coarse;
}

void play_prog_keep(struct play_prog *p, struct play_session *s,
                    const struct tvpal_view *v0, unsigned full, uint32_t t,
                    int dir)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_view vk;
    /* Errors are not this frame's: a frame that needs the step says
     * them. */
    for (unsigned k = full + 1; k < s->nlevels; k++) {
        struct tvpal_player *pk = s->lvl[k];
        if (!pk)
            continue;
        play_level_view(s, k, v0, &vk);
        if (tvpal_player_kept(pk, &vk, t, NULL))
            (void)tvpal_player_keep(pk, &vk, t, dir, &d);
    }
    /* The full level reads ahead once reads have fallen behind the
     * clock: from the step a refinement plans for, else from this one. */
    struct tvpal_player *pf = s->lvl[full];
    if (!pf || !p->stalls || !reads_ahead(p, dir))
        return;
    play_level_view(s, full, v0, &vk);
    const uint32_t from = p->active ? p->target : t;
    if (tvpal_player_kept(pf, &vk, from, NULL))
        (void)tvpal_player_keep(pf, &vk, from, dir, &d);
}

void play_prog_measured(struct play_prog *p, double io_ms, double stage_ms,
                        double total_ms, uint64_t bytes, unsigned level,
                        unsigned full)
{
    measure_rate(p, io_ms, stage_ms, bytes);
    if (level > full) {
        p->below++;
        return;
    }
    const double draw = total_ms > io_ms ? total_ms - io_ms : 0;
    p->steady_ms = p->steady_ms > 0 ? 0.8 * p->steady_ms + 0.2 * total_ms
                                    : total_ms;
    p->draw_ms = p->draw_ms > 0 ? 0.8 * p->draw_ms + 0.2 * draw : draw;
}

void play_prog_clock_start(struct play_prog *p)
{
    if (p->period_ms > 0)
        p->next_due = tvpal_now() + p->period_ms * 1e-3;
}

void play_prog_pace(struct play_prog *p)
{
    if (p->period_ms <= 0)
        return;
    const double now = tvpal_now(), period = p->period_ms * 1e-3;
    if (p->next_due <= 0 || now > p->next_due + period) {
        p->next_due = now + period;     /* start, or too late to catch up */
        return;
    }
    if (now < p->next_due) {
        const double w = p->next_due - now;
        struct timespec ts = {(time_t)w, (long)((w - floor(w)) * 1e9)};
        while (nanosleep(&ts, &ts) != 0 && errno == EINTR)
            ;
    }
    p->next_due += period;
}
