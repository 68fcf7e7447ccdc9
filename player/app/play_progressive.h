/* play_progressive.h: --progressive, the frames that never wait for the
 * disk (issue 32).  Shared by the headless loop and the window.
 *
 * Each frame has a view whose own level of detail ("full": --level, or
 * play_level_auto's choice) is drawn when its records for the frame's
 * step are in memory, or arrive within the frame's slack.  Otherwise (a
 * jump, or reads fallen behind the clock) the frame draws at once the
 * finest coarser level whose reads fit the frame's budget at the read
 * rate measured so far (the coarser levels are in RAM, play_levels.c, or
 * their steps around the playhead are, play_prog_keep: so in practice the
 * next coarser one), and the full level's player prepares,
 * off the frame's thread, the step steady playback reaches when those
 * reads are expected done, d frames on.  The frames until then draw the
 * coarser level; the frame at that step the full one, its prepared
 * records installed: waited for when there is no clock (headless without
 * --fps: the image sequence is exact, and only jumps are refined), else,
 * when they are late, drawn coarse until they are in, installed then,
 * and the rest planned from there.  A still view (dir 0: the window paused) prepares its own step
 * and draws it at full level as soon as it is in.
 *
 * The clock: frames are due every period_ms (--fps), or, with none (the
 * window without --fps), as fast as they are drawn; a frame's slack is
 * what is left of its period after the full level's measured drawing
 * time (a quarter of that time as fast as drawn).  play_prog_pace keeps the clock.
 *
 * One process only: a cluster's frames exchange ghost rows at the frame,
 * which a prepared step cannot (tvpal_player_prepare). */
#ifndef PLAY_PROGRESSIVE_H
#define PLAY_PROGRESSIVE_H

#include <stdint.h>

#include "play.h"
#include "tvpal_stream.h"

struct play_prog {
    /* Set by play_prog_init. */
    double period_ms;           /* the clock's frame period; 0: none */
    double budget_ms;           /* a frame's budget before one is measured
                                 * (--budget-ms) */
    uint32_t first, last;       /* the steps played, in play order: steady
                                 * playback goes from last to first */
    int exact;                  /* the full level's return is waited for
                                 * (headless without a clock: the frame
                                 * sequence is reproducible) */
    /* Measured (0: not yet). */
    double rate;                /* bytes per ms the disk gives the full
                                 * level's reads (stored bytes) */
    double inflate_ms;          /* ms per plain byte inflating coded
                                 * records (wall, on the stream's pool) */
    int metered;                /* rate from the stream's meter (the
                                 * disk's busy time), not from a frame's
                                 * waits */
    struct tvpal_stream_meter meter;    /* the meter when last sampled
                                         * (play_prog_frame): its reads
                                         * and its inflating each from
                                         * the sample that counted them, */
    unsigned meter_of;                  /* of this level and axis (1 + 4
                                         * level + axis; 0: none) */
    double steady_ms;           /* a steady full-level frame's time */
    double draw_ms;             /* of it, drawing (not waiting for reads) */
    /* The refinement under way. */
    int active;
    unsigned full, coarse, axis;    /* the view's level and axis, the
                                     * level drawn meanwhile */
    uint32_t target;                /* the step prepared at the full
                                     * level, */
    uint32_t due, frames;           /* frames after the start it comes,
                                     * and frames so far */
    double t0;                      /* the start's frame began (s) */
    uint32_t late;                  /* frames the last plans missed by,
                                     * added to the next */
    int planned_rate;               /* the plan had a measured rate */
    uint32_t since;                 /* steps the full level's slabs are
                                     * behind the frame's (large after a
                                     * jump) */
    /* The clock: when the next frame is due (s; 0: unset). */
    double next_due;
    /* Counts: frames drawn below their full level, refinements started
     * by a jump and by reads behind the clock. */
    uint32_t below, jumps, stalls;
    int load_rc;                /* this frame's install (play_prog_frame) */
};

/* period_ms: 1000 / fps, 0 for none; steps played from first to last (as
 * --steps A:B: last may be below first, playing backwards); exact: the
 * frame a refinement plans its return at waits for the records (else it
 * is drawn coarse again when they are late, as in the window). */
void play_prog_init(struct play_prog *p, double period_ms, double budget_ms,
                    uint32_t first, uint32_t last, int exact);

/* The step steady playback draws after t in direction dir (0: t, still):
 * the next of first..last, round to the other end past one.  Steps outside the range
 * (a window's slider) move by dir within the dataset's T steps. */
uint32_t play_prog_next(const struct play_prog *p, uint32_t t, int dir,
                        uint32_t steps);

/* The level the frame at step t draws, before it is drawn; full is the
 * level of its view v0 (level 0's view, set up), dir the play direction
 * (0: still), jump 1 when t is not the step steady playback came to.
 * *refined is set to the milliseconds from the jump or stall to this
 * frame's start when it is the full level's return (else 0; the caller
 * adds the frame's own).  Returns the level.  When a prepared step was
 * installed with a record that failed to load (its slices keep their
 * last good window), p->load_rc has the error and diag says which: the
 * caller reports it as the frame's own load error. */
int play_prog_frame(struct play_prog *p, struct play_session *s,
                    const struct tvpal_view *v0, unsigned full, uint32_t t,
                    int dir, int jump, double *refined,
                    struct tvpal_diag *diag);

/* After the frame at step t (its view v0, full level, play direction
 * dir: 0 still): the coarser levels streamed with a neighbourhood keep
 * the steps around t, and, once reads have fallen behind the clock, the
 * full level reads ahead from the step a refinement plans for (or t),
 * within its read-ahead memory (tvpal_player_keep: off the frame's
 * thread, a few records in flight at a time, cut short by the next
 * frame's seek). */
void play_prog_keep(struct play_prog *p, struct play_session *s,
                    const struct tvpal_view *v0, unsigned full, uint32_t t,
                    int dir);

/* What the frame just drawn measured: its milliseconds waiting for reads,
 * the stager's preparing them (tvpal_frame_stats) and in all, the bytes
 * of its own records (bytes_needed: not the prefetch), and the level it
 * drew against its full one.  The read rate is
 * the bytes over the longer of the two waits. */
void play_prog_measured(struct play_prog *p, double io_ms, double stage_ms,
                        double total_ms, uint64_t bytes, unsigned level,
                        unsigned full);

/* With a clock: the first frame is due a period from now (each frame is
 * shown for its period, so n frames take n periods). */
void play_prog_clock_start(struct play_prog *p);
/* With a clock, after a frame: sleeps until it is due; a frame later
 * than a whole period moves the clock to now (the time is not made up),
 * as does the first without play_prog_clock_start. */
void play_prog_pace(struct play_prog *p);

#endif
