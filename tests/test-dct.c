/* test-dct: DCT-II against a direct long-double evaluation of the paper's
 * formula; orthonormality; inverse round trip; float batch variant. */
#include "tvpal_dct.h"
#include "tvpal_test.h"

int main(void)
{
    for (unsigned n = 1; n <= TVPAL_NMAX; n++) {
        const double *m = tvpal_dct_matrix(n);
        REQUIRE(m, "matrix for n=%u", n);
        /* M M^T = I (orthonormal). */
        for (unsigned a = 0; a < n; a++)
            for (unsigned b = 0; b < n; b++) {
                double s = 0;
                for (unsigned x = 0; x < n; x++)
                    s += m[a * n + x] * m[b * n + x];
                CHECK(fabs(s - (a == b)) < 1e-14, "n=%u (%u,%u) %g", n, a, b,
                      s);
            }
        for (int trial = 0; trial < 20; trial++) {
            double in[TVPAL_NMAX], out[TVPAL_NMAX], back[TVPAL_NMAX];
            for (unsigned x = 0; x < n; x++)
                in[x] = tt_gauss() * 100 + 50;
            tvpal_dct_forward(n, in, out);
            for (unsigned u = 0; u < n; u++) {
                long double a = u == 0 ? sqrtl(1.0L / n) : sqrtl(2.0L / n);
                long double s = 0;
                for (unsigned x = 0; x < n; x++)
                    s += (long double)in[x] *
                         cosl((2.0L * x + 1) * u * 3.14159265358979323846264L /
                              (2.0L * n));
                double ref = (double)(a * s);
                CHECK(fabs(out[u] - ref) < 1e-11 * (1 + fabs(ref)),
                      "n=%u u=%u %.17g vs %.17g", n, u, out[u], ref);
            }
            tvpal_dct_inverse(n, out, back);
            for (unsigned x = 0; x < n; x++)
                CHECK(fabs(back[x] - in[x]) < 1e-11, "inverse n=%u x=%u", n,
                      x);
            /* Float batch: 3 series, stride 5 (tests the layout). */
            float fin[TVPAL_NMAX * 5], fout[TVPAL_NMAX * 5];
            for (unsigned x = 0; x < n; x++)
                for (unsigned v = 0; v < 5; v++)
                    fin[x * 5 + v] = (float)(in[x] * (v + 1));
            tvpal_dct_forward_f(n, fin, fout, 3, 5);
            for (unsigned u = 0; u < n; u++)
                for (unsigned v = 0; v < 3; v++)
                    CHECK(fabs(fout[u * 5 + v] - out[u] * (v + 1)) <
                              2e-5 * (1 + fabs(out[0]) * (v + 1)),
                          "float n=%u u=%u v=%u %g vs %g", n, u, v,
                          fout[u * 5 + v], out[u] * (v + 1));
        }
    }
    CHECK(tvpal_dct_matrix(0) == NULL &&
              tvpal_dct_matrix(TVPAL_NMAX + 1) == NULL &&
              tvpal_dct_matrix(TVPAL_NMAX) != NULL,
          "out-of-range n");
    return tt_done("test-dct");
}
