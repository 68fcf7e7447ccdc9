/* tvpal_levels.c: levels of detail, 2x2x2 block means (tvpal_levels.h). */
#include "tvpal_levels.h"

#include <math.h>
#include <stddef.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

void tvpal_level_dims(const uint32_t d0[3], unsigned k, uint32_t out[3])
{
    for (int a = 0; a < 3; a++) {
        uint32_t d = d0[a];
        for (unsigned i = 0; i < k; i++)
            d = (d + 1) / 2;
        out[a] = d;
    }
}

void tvpal_level_grid(const double s0[3], const double o0[3],
                      const uint32_t d0[3], const uint32_t dk[3],
                      double sk[3], double ok[3])
{
    for (int i = 0; i < 3; i++) {
        sk[i] = s0[i] * d0[i] / dk[i];
        ok[i] = o0[i] + 0.5 * (sk[i] - s0[i]);
    }
}

/* One value into a block's sum: a missing one (NaN) is left out of the
 * mean.  Branchless: adding +0.0 changes no sum (a sum that starts at +0.0
 * is never -0.0), so the bytes are those of adding present values only. */
#define ADD_VALUE(s, c, v)                                                   \
    do {                                                                     \
        const float v_ = (v);                                                \
        const int ok_ = v_ == v_;                                            \
        (s) += ok_ ? (double)v_ : 0.0;                                       \
        (c) += (uint32_t)ok_;                                                \
    } while (0)

/* The block of coarse voxel (i, yo) from fine planes f[0 .. np-1]: its
 * values added plane by plane, row by row, x within a row (the order the
 * levels' bytes were defined with), nxx x ny2 of each plane at its edge. */
static float block_mean(const float *const f[2], int np, size_t at,
                        uint32_t nx, uint32_t nxx, uint32_t ny2)
{
    double s = 0.0;
    uint32_t c = 0;
    for (int p = 0; p < np; p++)
        for (uint32_t dy = 0; dy < ny2; dy++)
            for (uint32_t dx = 0; dx < nxx; dx++)
                ADD_VALUE(s, c, f[p][at + (size_t)dy * nx + dx]);
    return c ? (float)(s / c) : NAN;
}

#ifdef __SSE2__
/* Two values of row r per lane (x and x + 1 of two blocks) into the lanes'
 * sums and counts, in that order. */
static inline void add_row_sse2(const float *r, __m128d *s, __m128i *c)
{
    const __m128 v = _mm_loadu_ps(r);
    const __m128d lo = _mm_cvtps_pd(_mm_shuffle_ps(v, v, _MM_SHUFFLE(2, 0, 2, 0)));
    const __m128d hi = _mm_cvtps_pd(_mm_shuffle_ps(v, v, _MM_SHUFFLE(3, 1, 3, 1)));
    const __m128d mlo = _mm_cmpord_pd(lo, lo), mhi = _mm_cmpord_pd(hi, hi);
    *s = _mm_add_pd(*s, _mm_and_pd(lo, mlo));
    *c = _mm_sub_epi64(*c, _mm_castpd_si128(mlo));
    *s = _mm_add_pd(*s, _mm_and_pd(hi, mhi));
    *c = _mm_sub_epi64(*c, _mm_castpd_si128(mhi));
}

/* Whole blocks two at a time, each lane a block, its values added in the
 * order of block_mean (a missing one as +0.0, as ADD_VALUE does): the
 * same bytes.  Returns the blocks done (an even number). */
static uint32_t average_pairs_sse2(const float *a0, const float *a1,
                                   const float *b0, const float *b1,
                                   uint32_t pairs, float *o)
{
    uint32_t i = 0;
    for (; i + 2 <= pairs; i += 2) {
        const size_t x = 2 * (size_t)i;
        __m128d s = _mm_setzero_pd();
        __m128i c = _mm_setzero_si128();
        add_row_sse2(a0 + x, &s, &c);
        add_row_sse2(a1 + x, &s, &c);
        add_row_sse2(b0 + x, &s, &c);
        add_row_sse2(b1 + x, &s, &c);
        double sv[2];
        int64_t cv[2];
        _mm_storeu_pd(sv, s);
        _mm_storeu_si128((__m128i *)cv, c);
        o[i] = cv[0] ? (float)(sv[0] / (double)cv[0]) : NAN;
        o[i + 1] = cv[1] ? (float)(sv[1] / (double)cv[1]) : NAN;
    }
    return i;
}
#endif

/* The coarse plane out ((nx + 1) / 2 x (ny + 1) / 2) of the 2x2x2 block
 * means of fine planes f0 and f1 (nx x ny; f1 NULL past an odd nz): each
 * block once, in one pass, whole blocks by straight-line code (it was a
 * third of the levels' cost as sums over planes). */
void tvpal_level_average_planes(const float *f0, const float *f1, uint32_t nx,
                           uint32_t ny, float *out)
{
    const uint32_t cx = (nx + 1) / 2, cy = (ny + 1) / 2, pairs = nx / 2;
    const float *const f[2] = {f0, f1};
    const int np = f1 ? 2 : 1;
    for (uint32_t yo = 0; yo < cy; yo++) {
        const size_t r0 = (size_t)2 * yo * nx;
        const uint32_t ny2 = 2 * yo + 1 < ny ? 2 : 1;
        float *o = out + (size_t)yo * cx;
        if (np == 2 && ny2 == 2) {
            const float *a0 = f0 + r0, *a1 = a0 + nx, *b0 = f1 + r0,
                        *b1 = b0 + nx;
            uint32_t i = 0;
#ifdef __SSE2__
            i = average_pairs_sse2(a0, a1, b0, b1, pairs, o);
#endif
            for (; i < pairs; i++) {
                const size_t x = 2 * (size_t)i;
                double s = 0.0;
                uint32_t c = 0;
                ADD_VALUE(s, c, a0[x]);
                ADD_VALUE(s, c, a0[x + 1]);
                ADD_VALUE(s, c, a1[x]);
                ADD_VALUE(s, c, a1[x + 1]);
                ADD_VALUE(s, c, b0[x]);
                ADD_VALUE(s, c, b0[x + 1]);
                ADD_VALUE(s, c, b1[x]);
                ADD_VALUE(s, c, b1[x + 1]);
                o[i] = c ? (float)(s / c) : NAN;
            }
        } else {
            for (uint32_t i = 0; i < pairs; i++)
                o[i] = block_mean(f, np, r0 + 2 * (size_t)i, nx, 2, ny2);
        }
        if (nx & 1)
            o[pairs] = block_mean(f, np, r0 + nx - 1, nx, 1, ny2);
    }
}

void tvpal_level_make(const float *fine, const uint32_t fd[3], float *coarse)
{
    const size_t fplane = (size_t)fd[0] * fd[1];
    const size_t cplane = (size_t)((fd[0] + 1) / 2) * ((fd[1] + 1) / 2);
    for (uint32_t z = 0; 2 * z < fd[2]; z++) {
        const float *f0 = fine + (size_t)2 * z * fplane;
        const float *f1 = 2 * z + 1 < fd[2] ? f0 + fplane : NULL;
        tvpal_level_average_planes(f0, f1, fd[0], fd[1], coarse + z * cplane);
    }
}
