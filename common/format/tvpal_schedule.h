/* tvpal_schedule.h: the interleaved window schedule (paper, Fig. 2).
 *
 * Slice s of an axis has phase r = s mod N.  Its windows start at time 0 and
 * at every t > 0 with t mod N == r, so at each timestep only the slices of
 * one phase (about 1/N of them) get a new window, and the window-boundary
 * jumps are spread across slices instead of hitting the whole volume at once.
 * The first window of a slice with r > 0 is the short [0, r); the last is cut
 * at T.  Every window therefore has length 1..N, and every t in [0, T) lies in
 * exactly one window of every slice.
 */
#ifndef TVPAL_SCHEDULE_H
#define TVPAL_SCHEDULE_H

/* Does a window of slice s start at time t? */
static inline int tvpal_schedule_starts(unsigned s, unsigned t, unsigned N)
{
    return t == 0 || t % N == s % N;
}

/* Start of the window of slice s that holds time t. */
static inline unsigned tvpal_schedule_start(unsigned s, unsigned t, unsigned N)
{
    unsigned r = s % N;
    if (t < r)
        return 0;
    return t - (t - r) % N;
}

/* Length of the window of slice s that starts at ws (a valid start), for a
 * series of T timesteps. */
static inline unsigned tvpal_schedule_len(unsigned s, unsigned ws, unsigned N,
                                        unsigned T)
{
    unsigned r = s % N;
    unsigned end = (ws < r) ? r : ws + N;
    if (end > T)
        end = T;
    return end - ws;
}

#endif
