/* tvpal_dct.c: DCT-II by matrix product.  For n <= 16 a direct n x n product
 * per voxel is as fast as a fast algorithm and vectorizes across voxels, which
 * is the dimension we batch over. */
#include "tvpal_dct.h"

#include <math.h>
#include <pthread.h>

static double mat_d[TVPAL_NMAX + 1][TVPAL_NMAX * TVPAL_NMAX];
static float mat_f[TVPAL_NMAX + 1][TVPAL_NMAX * TVPAL_NMAX];
static pthread_once_t mat_once = PTHREAD_ONCE_INIT;

static void mat_init(void)
{
    for (unsigned n = 1; n <= TVPAL_NMAX; n++)
        for (unsigned u = 0; u < n; u++) {
            double a = sqrt((u == 0 ? 1.0 : 2.0) / n);
            for (unsigned x = 0; x < n; x++) {
                double v = a * cos((2.0 * x + 1.0) * u * M_PI / (2.0 * n));
                mat_d[n][u * n + x] = v;
                mat_f[n][u * n + x] = (float)v;
            }
        }
}

const double *tvpal_dct_matrix(unsigned n)
{
    if (n < 1 || n > TVPAL_NMAX)
        return NULL;
    pthread_once(&mat_once, mat_init);
    return mat_d[n];
}

const float *tvpal_dct_matrix_f(unsigned n)
{
    if (n < 1 || n > TVPAL_NMAX)
        return NULL;
    pthread_once(&mat_once, mat_init);
    return mat_f[n];
}

void tvpal_dct_forward_f(unsigned n, const float *in, float *out,
                         size_t count, size_t stride)
{
    tvpal_basis_forward_f(tvpal_dct_matrix_f(n), n, in, out, count, stride);
}

/* Outputs u0 .. u0+U-1 for a window length N known at compile time, in
 * one pass over the voxels: each voxel's N inputs are read once and its U
 * outputs accumulated in registers, the voxel loop vectorizing.  Each
 * output is summed in the same order and from the same 0.0f start as the
 * generic loop below, ((0 + m0 x0) + m1 x1) + ..., so the results are
 * identical (0.0f + -0.0f is +0.0f in both). */
static inline void forward_fixed(const float *m, unsigned N, unsigned u0,
                                 unsigned U, const float *restrict in,
                                 float *restrict out, size_t count,
                                 size_t stride)
{
    /* A local copy of the rows: out cannot alias it, so its entries stay
     * in registers. */
    float w[4 * TVPAL_NMAX];
    for (unsigned k = 0; k < U * N; k++)
        w[k] = m[u0 * N + k];
    for (size_t v = 0; v < count; v++) {
        float x[TVPAL_NMAX];
        for (unsigned k = 0; k < N; k++)
            x[k] = in[(size_t)k * stride + v];
        for (unsigned u = 0; u < U; u++) {
            float o = 0.0f;
            for (unsigned k = 0; k < N; k++)
                o += w[u * N + k] * x[k];
            out[(size_t)(u0 + u) * stride + v] = o;
        }
    }
}

void tvpal_basis_forward_f(const float *m, unsigned n, const float *in,
                           float *out, size_t count, size_t stride)
{
    switch (n) {
    case 2: forward_fixed(m, 2, 0, 2, in, out, count, stride); return;
    case 4: forward_fixed(m, 4, 0, 4, in, out, count, stride); return;
    case 8:
        forward_fixed(m, 8, 0, 4, in, out, count, stride);
        forward_fixed(m, 8, 4, 4, in, out, count, stride);
        return;
    default: break;
    }
    for (unsigned u = 0; u < n; u++) {
        float *o = out + (size_t)u * stride;
        const float *row = m + u * n;
        for (size_t v = 0; v < count; v++)
            o[v] = 0.0f;
        for (unsigned x = 0; x < n; x++) {
            const float w = row[x];
            const float *src = in + (size_t)x * stride;
            for (size_t v = 0; v < count; v++)
                o[v] += w * src[v];
        }
    }
}

void tvpal_dct_forward(unsigned n, const double *in, double *out)
{
    const double *m = tvpal_dct_matrix(n);
    for (unsigned u = 0; u < n; u++) {
        double s = 0.0;
        for (unsigned x = 0; x < n; x++)
            s += m[u * n + x] * in[x];
        out[u] = s;
    }
}

void tvpal_dct_inverse(unsigned n, const double *in, double *out)
{
    const double *m = tvpal_dct_matrix(n);
    for (unsigned x = 0; x < n; x++) {
        double s = 0.0;
        for (unsigned u = 0; u < n; u++)
            s += m[u * n + x] * in[u];
        out[x] = s;
    }
}
