/* test-schedule: both window schedules (FORMAT.md 5) cover every timestep
 * exactly once for every slice at any T (T < N, T % N != 0), a jump needs
 * at most N records, all within the longest window, and one phase at most
 * changes per step; the staggered schedule is the paper's (starts where
 * t mod N is the phase), the joined one the same without the starts in
 * (0, N), its first windows N..2N - 1 steps; and the joined one's indices
 * cost at most 8 / min(N, T) bits per voxel-step, exactly 8/N at T >= N
 * (issue 35's bound), which the staggered one exceeds; with palette
 * groups of G slices (FORMAT.md 5.1) all of this holds with the phase
 * r = (s / G) mod N, so that a group's slices start every window
 * together. */
#include "tvpal_test.h"
#include "tvpal_schedule.h"

/* Windows of slice s: each start's length, against starts/start. */
static unsigned check_slice(const struct tvpal_schedule *sc, unsigned s)
{
    const unsigned N = sc->N, T = sc->T, L = tvpal_schedule_max_len(sc);
    unsigned covered = 0, windows = 0;
    for (unsigned t = 0; t < T; t++) {
        if (!tvpal_schedule_starts(sc, s, t))
            continue;
        unsigned len = tvpal_schedule_len(sc, s, t);
        CHECK(len >= 1 && len <= L && t + len <= T,
              "kind %u N=%u T=%u s=%u t=%u len=%u (max %u)", sc->kind, N, T,
              s, t, len, L);
        /* Joined: the first window is [0, N + r), cut at T. */
        if (sc->kind == TVPAL_SCHEDULE_JOINED && t == 0)
            CHECK(len == (N + s / sc->G % N < T ? N + s / sc->G % N : T),
                  "first %u", len);
        CHECK(covered == t, "gap before t=%u (s=%u N=%u T=%u)", t, s, N, T);
        for (unsigned j = 0; j < len; j++)
            CHECK(tvpal_schedule_start(sc, s, t + j) == t,
                  "kind %u N=%u T=%u s=%u: start of %u", sc->kind, N, T, s,
                  t + j);
        covered = t + len;
        windows++;
    }
    CHECK(covered == T, "kind %u N=%u T=%u s=%u covers %u", sc->kind, N, T,
          s, covered);
    /* The paper's phases; joined, none in (0, N). */
    for (unsigned t = 1; t < T; t++)
        CHECK(tvpal_schedule_starts(sc, s, t) ==
                  (t % N == s / sc->G % N &&
                   (sc->kind == TVPAL_SCHEDULE_STAGGERED || t >= N)),
              "phase");
    return windows;
}

/* Records a jump to t needs: distinct window starts over the slices, at
 * most N, within the longest window, and tvpal_schedule_records lists
 * exactly them. */
static void check_jumps(const struct tvpal_schedule *sc)
{
    const unsigned N = sc->N, T = sc->T, L = tvpal_schedule_max_len(sc);
    for (unsigned t = 0; t < T; t++) {
        uint32_t mask = 0;
        for (unsigned s = 0; s < 64 || s < N * sc->G; s++) {
            unsigned ws = tvpal_schedule_start(sc, s, t);
            CHECK(ws <= t && t - ws < L, "ws %u t %u", ws, t);
            mask |= 1u << (t - ws);
        }
        CHECK((unsigned)__builtin_popcount(mask) <= N, "records");
        uint32_t rec[TVPAL_SCHEDULE_RECORDS_MAX];
        unsigned n = tvpal_schedule_records(sc, t, rec), k = 0;
        CHECK(n == (unsigned)__builtin_popcount(mask), "records listed");
        for (int d = 31; d >= 0; d--)
            if (mask & (1u << d))
                CHECK(rec[k++] == t - (unsigned)d, "record %u", k - 1);
    }
}

/* At t > 0 the slices that change are those of tvpal_schedule_phase. */
static void check_phases(const struct tvpal_schedule *sc)
{
    const unsigned N = sc->N, T = sc->T;
    for (unsigned t = 1; t < T; t++) {
        uint32_t r = 0;
        const int any = tvpal_schedule_phase(sc, t, &r);
        for (unsigned s = 0; s < 64; s++)
            CHECK(tvpal_schedule_starts(sc, s, t) ==
                      (any && s / sc->G % N == r),
                  "kind %u N=%u T=%u G=%u t=%u s=%u: phase %d %u", sc->kind,
                  N, T, sc->G, t, s, any, r);
    }
}

int main(void)
{
    unsigned over = 0;
    for (unsigned kind = 0; kind < 2; kind++)
        for (unsigned N = 1; N <= 16; N++)
            for (unsigned T = 1; T <= 70; T++) {
                const struct tvpal_schedule sc =
                    tvpal_schedule_of(N, T, kind, 1);
                const unsigned L = tvpal_schedule_max_len(&sc);
                CHECK(L == (T < N ? T : kind ? (T < 2 * N - 1 ? T : 2 * N - 1)
                                             : N),
                      "max_len %u", L);
                CHECK(L <= TVPAL_SCHEDULE_LEN_MAX, "max_len %u", L);
                /* Over the N phases: index bits per voxel-step are
                 * 8 * windows / (N * T); joined, exactly 8 / min(N, T). */
                unsigned windows = 0;
                for (unsigned s = 0; s < N; s++)
                    windows += check_slice(&sc, s);
                for (unsigned s = N; s < 2 * N + 3; s++)
                    check_slice(&sc, s);
                const unsigned n = T < N ? T : N;
                if (kind == TVPAL_SCHEDULE_JOINED)
                    CHECK(windows * n == N * T || (T < N && windows == N),
                          "N=%u T=%u: %u windows over %u phases", N, T,
                          windows, N);
                else
                    over += windows * n > N * T;
                check_jumps(&sc);
                check_phases(&sc);
            }
    /* The staggered schedule pays more wherever a phase has a short first
     * window: every N > 1 and T > 1 (15 * 69 series here). */
    CHECK(over == 15 * 69, "staggered over the bound in %u series", over);
    /* Palette groups: the same with r = (s / G) mod N; the slices of a
     * group share every window, and over N G slices (one group per
     * phase) the joined bound holds as above. */
    static const unsigned groups[] = {2, 3, 5};
    for (unsigned kind = 0; kind < 2; kind++)
        for (unsigned gi = 0; gi < 3; gi++)
            for (unsigned N = 1; N <= 16; N += 3)
                for (unsigned T = 1; T <= 40; T++) {
                    const unsigned G = groups[gi];
                    const struct tvpal_schedule sc =
                        tvpal_schedule_of(N, T, kind, G);
                    unsigned windows = 0;
                    for (unsigned s = 0; s < N * G + 7; s++) {
                        const unsigned w = check_slice(&sc, s);
                        if (s < N * G && s % G == 0)
                            windows += w;
                        for (unsigned t = 0; t < T; t++)
                            CHECK(tvpal_schedule_start(&sc, s, t) ==
                                      tvpal_schedule_start(&sc, s / G * G, t),
                                  "G=%u s=%u t=%u: the group's window", G, s,
                                  t);
                    }
                    const unsigned n = T < N ? T : N;
                    if (kind == TVPAL_SCHEDULE_JOINED)
                        CHECK(windows * n == N * T || (T < N && windows == N),
                              "G=%u N=%u T=%u: %u windows", G, N, T, windows);
                    check_jumps(&sc);
                    check_phases(&sc);
                }
    /* The example of FORMAT.md 5: N = 4, T = 10, joined. */
    const struct tvpal_schedule ex = tvpal_schedule_of(4, 10, 1, 1);
    static const unsigned starts[4][3] = {
        {0, 4, 8}, {0, 5, 9}, {0, 6, 0}, {0, 7, 0}};
    for (unsigned r = 0; r < 4; r++)
        for (unsigned t = 0; t < 10; t++)
            CHECK(tvpal_schedule_starts(&ex, r, t) ==
                      (t == starts[r][0] || t == starts[r][1] ||
                       t == starts[r][2]),
                  "example: phase %u, t %u", r, t);
    return tt_done("test-schedule");
}
