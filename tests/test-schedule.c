/* test-schedule: the interleaved schedule covers every timestep exactly once
 * for every slice, any T (T < N, T % N != 0), and a jump needs <= N
 * records. */
#include "tvpal_test.h"
#include "tvpal_schedule.h"

int main(void)
{
    for (unsigned N = 1; N <= 16; N++)
        for (unsigned T = 1; T <= 40; T++) {
            for (unsigned s = 0; s < 40; s++) {
                unsigned covered = 0;
                for (unsigned t = 0; t < T; t++) {
                    if (!tvpal_schedule_starts(s, t, N))
                        continue;
                    unsigned len = tvpal_schedule_len(s, t, N, T);
                    CHECK(len >= 1 && len <= N && t + len <= T,
                          "N=%u T=%u s=%u t=%u len=%u", N, T, s, t, len);
                    CHECK(covered == t, "gap before t=%u (s=%u N=%u)", t, s,
                          N);
                    for (unsigned j = 0; j < len; j++)
                        CHECK(tvpal_schedule_start(s, t + j, N) == t,
                              "start of %u", t + j);
                    covered = t + len;
                }
                CHECK(covered == T, "N=%u T=%u s=%u covers %u", N, T, s,
                      covered);
                /* Phase: after the first window, starts are t == s mod N. */
                for (unsigned t = 1; t < T; t++)
                    CHECK(tvpal_schedule_starts(s, t, N) == (t % N == s % N),
                          "phase");
            }
            /* A jump to t needs the records of distinct window starts:
             * at most N of them, all in (t - N, t]. */
            for (unsigned t = 0; t < T; t++) {
                unsigned mask = 0;
                for (unsigned s = 0; s < 64; s++) {
                    unsigned ws = tvpal_schedule_start(s, t, N);
                    CHECK(ws <= t && t - ws < N, "ws %u t %u", ws, t);
                    mask |= 1u << (t - ws);
                }
                CHECK((unsigned)__builtin_popcount(mask) <= N, "records");
            }
            /* Forward playback: at t > 0 only one phase class changes. */
            for (unsigned t = 1; t < T; t++) {
                unsigned changed = 0;
                for (unsigned s = 0; s < 64; s++)
                    changed += tvpal_schedule_starts(s, t, N);
                CHECK(changed == 64 / N + (t % N < 64 % N),
                      "N=%u t=%u: %u slices change", N, t, changed);
            }
        }
    return tt_done("test-window");
}
