/* tvpal_schedule.h: the interleaved window schedule (paper, Fig. 2;
 * FORMAT.md Section 5).
 *
 * Slice s of an axis has phase r = s mod N (with palette groups of G
 * slices, r = (s / G) mod N).  Its windows start at time 0
 * and at times t with t mod N == r, so at each timestep only the slices of
 * one phase (about 1/N of them) get a new window, and the window-boundary
 * jumps are spread across slices instead of hitting the whole volume at
 * once.  Every t in [0, T) lies in exactly one window of every slice.
 * Two kinds:
 *
 *   TVPAL_SCHEDULE_STAGGERED (the paper's; every dataset before format
 *   1.11): starts at 0 and at every t > 0 with t mod N == r.  The first
 *   window of a slice with r > 0 is the short [0, r), the last is cut at T:
 *   windows of 1..N steps.  Each costs a whole index per voxel, so the
 *   short first windows cost N - 1 indices per N slices beyond T/N: the
 *   indices take 1.13 bits per voxel-step at N = 16 on 12 steps and 0.62
 *   on 64, against 8/N = 0.5.
 *
 *   TVPAL_SCHEDULE_JOINED: the same without the starts in (0, N), so the
 *   short first window joins the next one: [0, N + r), then every N steps
 *   as before, the last cut at T.  Over the N phases that makes exactly
 *   T/N windows per slice on average for any T >= N (T = kN + m: phase r
 *   has k windows, one more when r < m), so the indices cost 8/N bits per
 *   voxel-step at any length (8/T below N: one window, [0, T)).  The
 *   price: first windows of N..2N - 1 steps (the encoder holds 2N - 1
 *   steps, not N), and no slice starts a window at steps 1..N - 1.
 *
 * Everything here is O(1) and allocation-free: the readers call it per
 * slice and step. */
#ifndef TVPAL_SCHEDULE_H
#define TVPAL_SCHEDULE_H

#include <stdint.h>

/* As lib/tvpal.h defines them (an identical definition is allowed). */
#define TVPAL_SCHEDULE_STAGGERED 0
#define TVPAL_SCHEDULE_JOINED 1

/* The longest window of any series: 2N - 1 at N = 16 (joined). */
#define TVPAL_SCHEDULE_LEN_MAX 31

/* The most records a step needs (tvpal_schedule_records): one per phase. */
#define TVPAL_SCHEDULE_RECORDS_MAX 16

/* A series' schedule: N (1..16) the window, T >= 1 the steps, kind one of
 * the above, G >= 1 the slices of a palette group (FORMAT.md 5.1): the G
 * slices gG .. gG + G - 1 share a phase, r = (s / G) mod N, so that one
 * chunk may hold them all under one decoder table.  G = 1 is the paper's
 * r = s mod N. */
struct tvpal_schedule {
    uint32_t N, T, kind, G;
};

static inline struct tvpal_schedule tvpal_schedule_of(uint32_t N, uint32_t T,
                                                      uint32_t kind,
                                                      uint32_t G)
{
    struct tvpal_schedule sc = {N, T, kind, G ? G : 1};
    return sc;
}

/* The phase of slice s. */
static inline uint32_t tvpal_schedule_slice_phase(
    const struct tvpal_schedule *sc, uint32_t s)
{
    return s / sc->G % sc->N;
}

/* Does a window of slice s start at time t (t < T)? */
static inline int tvpal_schedule_starts(const struct tvpal_schedule *sc,
                                        uint32_t s, uint32_t t)
{
    const uint32_t N = sc->N;
    if (t == 0)
        return 1;
    if (sc->kind == TVPAL_SCHEDULE_JOINED && t < N)
        return 0;
    return t % N == tvpal_schedule_slice_phase(sc, s);
}

/* Start of the window of slice s that holds time t (t < T). */
static inline uint32_t tvpal_schedule_start(const struct tvpal_schedule *sc,
                                            uint32_t s, uint32_t t)
{
    const uint32_t N = sc->N, r = tvpal_schedule_slice_phase(sc, s);
    const uint32_t first = sc->kind == TVPAL_SCHEDULE_JOINED ? N + r : r;
    return t < first ? 0 : t - (t - r) % N;
}

/* Length of the window of slice s that starts at ws (a valid start). */
static inline uint32_t tvpal_schedule_len(const struct tvpal_schedule *sc,
                                          uint32_t s, uint32_t ws)
{
    const uint32_t N = sc->N, T = sc->T,
                   r = tvpal_schedule_slice_phase(sc, s);
    const uint32_t first = sc->kind == TVPAL_SCHEDULE_JOINED ? N + r : r;
    const uint32_t end = ws < first ? first : ws + N;
    return (end < T ? end : T) - ws;
}

/* The longest window of the series: min(N, T) staggered, min(2N - 1, T)
 * joined.  A step's windows all start in (t - max_len, t]. */
static inline uint32_t tvpal_schedule_max_len(const struct tvpal_schedule *sc)
{
    const uint32_t L = sc->kind == TVPAL_SCHEDULE_JOINED ? 2 * sc->N - 1
                                                         : sc->N;
    return sc->T < L ? sc->T : L;
}

/* The name of a kind, as the manifest key and the tools write it. */
static inline const char *tvpal_schedule_name(uint32_t kind)
{
    return kind == TVPAL_SCHEDULE_JOINED ? "joined" : "staggered";
}

/* Records t - d for the bits d set in mask (d <= 31), ascending into
 * steps; returns how many: the tail of tvpal_schedule_records and of a
 * slab's own count of what it needs (tvpal_slab_needed). */
static inline unsigned tvpal_schedule_mask_steps(uint32_t t, uint32_t mask,
                                                 uint32_t *steps)
{
    unsigned k = 0;
    for (int d = 31; d >= 0; d--)
        if (mask & (1u << d))
            steps[k++] = t - (uint32_t)d;
    return k;
}

/* The records step t (< T) needs, one per window start of any slice
 * (every phase's), ascending into steps: at most N, all in
 * (t - max_len, t].  Returns how many. */
static inline unsigned tvpal_schedule_records(const struct tvpal_schedule *sc,
                                              uint32_t t, uint32_t *steps)
{
    uint32_t mask = 0;   /* bit d: record t - d; d < max_len <= 31 */
    /* Phases r >= T (T < N) hold t < T <= r in their first window, at 0,
     * as phase 0 does. */
    const uint32_t n = sc->N < sc->T ? sc->N : sc->T;
    for (uint32_t r = 0; r < n; r++) /* slice r G has phase r */
        mask |= 1u << (t - tvpal_schedule_start(sc, r * sc->G, t));
    return tvpal_schedule_mask_steps(t, mask, steps);
}

/* The phase whose slices start a window at t, 0 < t < T, in *r; 0 when
 * none (the joined schedule's steps 1..N - 1). */
static inline int tvpal_schedule_phase(const struct tvpal_schedule *sc,
                                       uint32_t t, uint32_t *r)
{
    if (t == 0 || t >= sc->T ||
        (sc->kind == TVPAL_SCHEDULE_JOINED && t < sc->N))
        return 0;
    *r = t % sc->N;
    return 1;
}

#endif
