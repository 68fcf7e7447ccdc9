/* test-bitalloc: greedy variance allocation: sums to 8, follows the
 * variances, zero variances get nothing, known example. */
#include "tvpal_bitalloc.h"
#include "tvpal_test.h"

int main(void)
{
    uint8_t b[16];
    double v1[4] = {16, 4, 1, 0};
    CHECK(tvpal_bitalloc_variance(v1, 4, 8, b) == 8, "sum");
    CHECK(b[0] == 4 && b[1] == 3 && b[2] == 1 && b[3] == 0,
          "known example: got %u %u %u %u, expected 4 3 1 0", b[0], b[1],
          b[2], b[3]);
    double one[1] = {3.5};
    CHECK(tvpal_bitalloc_variance(one, 1, 8, b) == 8 && b[0] == 8,
          "single coefficient gets all 8 bits");
    double zeros[8] = {0};
    CHECK(tvpal_bitalloc_variance(zeros, 8, 8, b) == 0, "all zero: no bits");
    for (int i = 0; i < 8; i++)
        CHECK(b[i] == 0, "zero variance %d", i);
    double huge[2] = {1e300, 1e-300};
    tvpal_bitalloc_variance(huge, 2, 8, b);
    CHECK(b[0] == 8 && b[1] == 0, "capped at 8 bits: %u %u", b[0], b[1]);
    for (int trial = 0; trial < 2000; trial++) {
        unsigned n = 1 + (unsigned)(tt_rand64() % 16);
        double v[16];
        for (unsigned u = 0; u < n; u++)
            v[u] = (tt_rand64() % 5 == 0) ? 0.0 : exp(tt_gauss() * 4);
        unsigned got = tvpal_bitalloc_variance(v, n, 8, b);
        unsigned sum = 0, nonzero = 0;
        for (unsigned u = 0; u < n; u++) {
            sum += b[u];
            nonzero += v[u] > 0;
            CHECK(v[u] > 0 || b[u] == 0, "zero variance got bits");
            for (unsigned w = 0; w < n; w++)
                CHECK(!(v[u] > v[w]) || b[u] >= b[w],
                      "var %g > %g but bits %u < %u", v[u], v[w], b[u], b[w]);
        }
        CHECK(sum == got, "returned count");
        CHECK(sum == (nonzero ? 8u : 0u), "sum %u (nonzero %u)", sum, nonzero);
    }
    return tt_done("test-bitalloc");
}
