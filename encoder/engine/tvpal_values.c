/* tvpal_values.c: source values converted, checked and counted
 * (tvpal_values.h). */
#include "tvpal_values.h"
#include "tvpal_raw.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <math.h>
#include <string.h>

/* The fine histogram's class of f: the top 16 bits of its order-preserving
 * encoding. */
static uint32_t fine_bin(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    /* (u & sign) ? ~u : u | sign, as u ^ (all ones or the sign bit) */
    u ^= (0u - (u >> 31)) | 0x80000000u;
    return u >> 16;
}

float tvpal_values_bin_value(uint32_t b)
{
    uint32_t k = (b << 16) | 0x8000u, u;
    u = (k & 0x80000000u) ? (k & 0x7FFFFFFFu) : ~k;
    float f;
    memcpy(&f, &u, 4);
    return f;
}

struct tvpal_found tvpal_found_empty(double lo, double hi)
{
    return (struct tvpal_found){UINT64_MAX, 0, 0, 0, 0, lo, hi};
}

void tvpal_found_merge(struct tvpal_found *all, const struct tvpal_found *f)
{
    if (f->bad < all->bad) {
        all->bad = f->bad;
        all->rc = f->rc;
    }
    if (f->read_err && !all->read_err)
        all->read_err = f->read_err;
    all->nrep += f->nrep;
    all->nmiss += f->nmiss;
    all->lo = f->lo < all->lo ? f->lo : all->lo;
    all->hi = f->hi > all->hi ? f->hi : all->hi;
}

void tvpal_values_fold(struct tvpal_checkpoint_stats *st,
                       uint64_t *const *fine, unsigned n)
{
    for (unsigned i = 0; i < n; i++)
        for (uint32_t k = 0; k < TVPAL_CHECKPOINT_BINS; k++) {
            st->fine[k] += fine[i][k];
            fine[i][k] = 0;
        }
}

void tvpal_values_account(struct tvpal_checkpoint_stats *st,
                          uint64_t *const *fine, unsigned n,
                          const struct tvpal_found *all, uint64_t voxels)
{
    tvpal_values_fold(st, fine, n);
    st->nonfinite += all->nrep;
    st->missing += all->nmiss;
    st->counted += voxels;
    st->vmin = all->lo;
    st->vmax = all->hi;
}

void tvpal_values_histogram(const struct tvpal_checkpoint_stats *st,
                            uint64_t hist[TVPAL_HIST_BINS])
{
    const double span = st->vmax - st->vmin;
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++) {
        if (!st->fine[b])
            continue;
        double v = tvpal_values_bin_value(b);
        int bin = span > 0 ? (int)((v - st->vmin) / span * TVPAL_HIST_BINS)
                           : 0;
        bin = bin < 0 ? 0 : bin >= TVPAL_HIST_BINS ? TVPAL_HIST_BINS - 1 : bin;
        hist[bin] += st->fine[b];
    }
}

/* The largest float32 whose value is at most TVPAL_VALUE_MAX: for a float
 * f, fabs(f) <= TVPAL_VALUE_MAX exactly when fabsf(f) <= VALUE_MAX_F
 * (false for NaN and infinities too). */
#define VALUE_MAX_F 9.99999993e36f
/* In [2^122, 2^123), where floats are 2^99 apart. */
_Static_assert((double)VALUE_MAX_F >= 0x1p122 &&
                   (double)VALUE_MAX_F < 0x1p123 &&
                   (double)VALUE_MAX_F <= TVPAL_VALUE_MAX &&
                   (double)VALUE_MAX_F + 0x1p99 > TVPAL_VALUE_MAX,
               "VALUE_MAX_F is the largest float <= TVPAL_VALUE_MAX");

/* The common case of convert_run, host float32 with no --missing, in one
 * pass: copies src to dst if every value is finite and within
 * TVPAL_VALUE_MAX, and returns 0 otherwise (dst partly written, nothing
 * counted: the general path then does it all).  The minimum and maximum go
 * into *lo and *hi as the general path's loop would set them ("v < lo ? v :
 * lo" in order); values compare equal only as -0 and +0, where a vector's
 * lanes could pick another zero than the first, so a zero extreme is found
 * again in order when the run holds zeros of both signs.  With fine, each
 * value is counted into its class. */
static int convert_f32_plain(const float *src, size_t n, float *dst,
                             uint64_t *fine, double *lo, double *hi)
{
    size_t i = 0;
    float mn = INFINITY, mx = -INFINITY;
    int bad = 0, negzero = 0, poszero = 0;
#if defined(__SSE2__)
    const __m128 lim = _mm_set1_ps(VALUE_MAX_F);
    const __m128 absmask = _mm_castsi128_ps(_mm_set1_epi32(0x7FFFFFFF));
    const __m128 zero = _mm_setzero_ps();
    __m128 vmin = _mm_set1_ps(INFINITY), vmax = _mm_set1_ps(-INFINITY);
    __m128 vbad = zero, vneg0 = zero, vpos0 = zero;
    for (; i + 4 <= n; i += 4) {
        __m128 x = _mm_loadu_ps(src + i);
        _mm_storeu_ps(dst + i, x);
        /* not (|x| <= lim): true for NaN as well */
        vbad = _mm_or_ps(vbad, _mm_cmpnle_ps(_mm_and_ps(x, absmask), lim));
        vmin = _mm_min_ps(vmin, x);
        vmax = _mm_max_ps(vmax, x);
        /* zeros, by the sign bit: set for -0 in vneg0, for +0 in vpos0 */
        __m128 z = _mm_cmpeq_ps(x, zero);
        vneg0 = _mm_or_ps(vneg0, _mm_and_ps(z, x));
        vpos0 = _mm_or_ps(vpos0, _mm_andnot_ps(x, z));
    }
    bad = _mm_movemask_ps(vbad) != 0;
    negzero = _mm_movemask_ps(vneg0) != 0;
    poszero = _mm_movemask_ps(vpos0) != 0;
    float l[4], h[4];
    _mm_storeu_ps(l, vmin);
    _mm_storeu_ps(h, vmax);
    for (int k = 0; k < 4; k++) {
        mn = l[k] < mn ? l[k] : mn;
        mx = h[k] > mx ? h[k] : mx;
    }
#endif
    for (; i < n; i++) {
        float v = src[i];
        dst[i] = v;
        bad |= !(fabsf(v) <= VALUE_MAX_F);
        mn = v < mn ? v : mn;
        mx = v > mx ? v : mx;
        negzero |= v == 0.0f && signbit(v);
        poszero |= v == 0.0f && !signbit(v);
    }
    if (bad)
        return 0;
    double l0 = *lo, h0 = *hi;
    if (negzero && poszero && (mn == 0.0f || mx == 0.0f)) {
        /* which zero came first */
        for (size_t k = 0; k < n; k++) {
            l0 = src[k] < l0 ? src[k] : l0;
            h0 = src[k] > h0 ? src[k] : h0;
        }
    } else if (n) {
        l0 = mn < l0 ? mn : l0;
        h0 = mx > h0 ? mx : h0;
    }
    *lo = l0;
    *hi = h0;
    if (fine)
        for (size_t k = 0; k < n; k++)
            fine[fine_bin(src[k])]++;
    return 1;
}

void tvpal_values_convert(const struct tvpal_values_rules *rules,
                          const void *src, enum tvpal_type type,
                          int big_endian, size_t n, float *dst,
                          uint64_t vox0, uint64_t *fine,
                          struct tvpal_found *f)
{
    size_t bad = 0, rep = 0;
#ifdef WORDS_BIGENDIAN
    const int host_order = big_endian;
#else
    const int host_order = !big_endian;
#endif
    if (type == TVPAL_F32 && host_order && !rules->nmissing &&
        convert_f32_plain(src, n, dst, fine, &f->lo, &f->hi))
        return;
    int rc = tvpal_raw_convert(src, type, big_endian, n, dst, rules->nan_as,
                               &bad, &rep);
    if (rc < 0) {
        if (vox0 + bad < f->bad) {
            f->bad = vox0 + bad;
            f->rc = rc;
        }
        return;
    }
    if (rules->nmissing) {
        size_t hits = tvpal_missing_apply(dst, n, rules->missing,
                                          rules->nmissing, rules->nan_as);
        rep += rules->nan_as ? hits : 0;
    }
    if (!fine)
        return;
    double lo = f->lo, hi = f->hi;
    f->nrep += rep;
    for (size_t i = 0; i < n; i++) {
        float v = dst[i];
        if (v != v) { /* missing: in no figure */
            f->nmiss++;
            continue;
        }
        lo = v < lo ? v : lo;
        hi = v > hi ? v : hi;
        fine[fine_bin(v)]++;
    }
    f->lo = lo;
    f->hi = hi;
}

void tvpal_values_spread(const struct tvpal_checkpoint_stats *st, double *lo,
                         double *hi, uint64_t *huge, uint64_t *far)
{
    const uint64_t *fine = st->fine;
    uint64_t total = 0, cum = 0;
    *lo = *hi = 0;
    *huge = *far = 0;
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++)
        total += fine[b];
    if (!total)
        return;
    uint32_t blo = 0, bhi = 0;
    int have_lo = 0, have_hi = 0;
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS && !have_hi; b++) {
        cum += fine[b];
        if (!have_lo && cum * 1000 > total)
            blo = b, have_lo = 1;
        if (cum * 1000 >= total * 999)
            bhi = b, have_hi = 1;
    }
    *lo = tvpal_values_bin_value(blo);
    *hi = tvpal_values_bin_value(bhi);
    const double span = *hi - *lo;
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++) {
        const double v = tvpal_values_bin_value(b);
        if (fine[b] && fabs(v) > 1e30)
            *huge += fine[b];
        if (fine[b] && (v < *lo - 100 * span || v > *hi + 100 * span))
            *far += fine[b];
    }
}
