/* tvpal_rle.c: the run-length image codec of the compositing messages (see
 * tvpal_rle.h). */
#include "tvpal_rle.h"
#include "tvpal_error.h"

#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

/* Encoding: u32 span count, then per span u32 start (pixel offset from the
 * first pixel of row y0) and u32 length, then the spans' pixels in order,
 * each 4 x 16-bit unsigned normalized values (premultiplied RGBA in
 * [0, 1], v = round(x * 65535)): half the bytes of float, and a step of
 * 1.5e-5, far below the 8-bit output's 1/255.  A pixel is transparent
 * (skipped) when all four values are 0. */
size_t tvpal_rle_bound(unsigned width, unsigned rows)
{
    size_t n = (size_t)width * rows;
    /* worst case: alternating pixels, one span per 2 pixels */
    return 4 + (n / 2 + 1) * 8 + n * 8;
}

static inline uint16_t to16(float v)
{
    v = v < 0.0f ? 0.0f : v > 1.0f ? 1.0f : v;
    return (uint16_t)(v * 65535.0f + 0.5f);
}

/* Clamp to [0, 1], scale, round: n floats to 16 bits.  SSE2 (every
 * x86-64) does 8 values per step; the scalar tail and other CPUs
 * give the same results (round half up of a value in [0, scale]). */
static void conv16(const float *p, uint16_t *d, size_t n)
{
    size_t i = 0;
#ifdef __SSE2__
    const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f),
                 sc = _mm_set1_ps(65535.0f), half = _mm_set1_ps(0.5f);
    const __m128i bias = _mm_set1_epi32(32768), flip = _mm_set1_epi16((short)0x8000);
    for (; i + 8 <= n; i += 8) {
        __m128 a = _mm_loadu_ps(p + i), b = _mm_loadu_ps(p + i + 4);
        a = _mm_min_ps(_mm_max_ps(a, zero), one);
        b = _mm_min_ps(_mm_max_ps(b, zero), one);
        __m128i ia = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(a, sc), half));
        __m128i ib = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(b, sc), half));
        /* unsigned 16-bit pack with SSE2: shift to signed, pack, shift back */
        __m128i pk = _mm_packs_epi32(_mm_sub_epi32(ia, bias),
                                     _mm_sub_epi32(ib, bias));
        _mm_storeu_si128((__m128i *)(void *)(d + i), _mm_xor_si128(pk, flip));
    }
#endif
    for (; i < n; i++)
        d[i] = to16(p[i]);
}

/* Premultiplied pixels: alpha 0 means nothing to add (colour is 0 too), so
 * spans are found on alpha alone. */
size_t tvpal_rle_encode(const float *img, unsigned width, unsigned y0,
                        unsigned y1, unsigned char *buf)
{
    const size_t n = (size_t)width * (y1 - y0);
    const float *base = img + (size_t)4 * width * y0;
    uint32_t nspans = 0;
    unsigned char *hdr = buf + 4;
    for (size_t i = 0; i < n;) {
        while (i < n && base[4 * i + 3] == 0.0f)
            i++;
        if (i >= n)
            break;
        size_t s = i;
        while (i < n && base[4 * i + 3] != 0.0f)
            i++;
        uint32_t se[2] = {(uint32_t)s, (uint32_t)(i - s)};
        memcpy(hdr + 8 * (size_t)nspans, se, 8);
        nspans++;
    }
    memcpy(buf, &nspans, 4);
    uint16_t *data = (uint16_t *)(void *)(hdr + 8 * (size_t)nspans);
    for (uint32_t k = 0; k < nspans; k++) {
        uint32_t se[2];
        memcpy(se, hdr + 8 * (size_t)k, 8);
        const float *p = base + 4 * (size_t)se[0];
        const size_t m = 4 * (size_t)se[1];
        conv16(p, data, m);
        data += m;
    }
    return (size_t)((unsigned char *)data - buf);
}

/* Checks the message buf[0, bytes) against rows of n pixels (see
 * tvpal_rle.h) without reading past bytes; on success *nspans is its span
 * count.  0 or TVPAL_E_FORMAT. */
static int rle_check(const unsigned char *buf, size_t bytes, size_t n,
                     uint32_t *nspans)
{
    uint32_t ns;
    if (bytes < 4)
        return TVPAL_E_FORMAT;
    memcpy(&ns, buf, 4);
    if (ns > (bytes - 4) / 8)
        return TVPAL_E_FORMAT;
    size_t left = bytes - 4 - 8 * (size_t)ns; /* pixel bytes */
    size_t end = 0;                          /* end of the previous span */
    for (uint32_t k = 0; k < ns; k++) {
        uint32_t se[2];
        memcpy(se, buf + 4 + 8 * (size_t)k, 8);
        if (!se[1] || se[0] < end || se[0] > n || se[1] > n - se[0] ||
            se[1] > left / 8)
            return TVPAL_E_FORMAT;
        left -= 8 * (size_t)se[1];
        end = (size_t)se[0] + se[1];
    }
    if (left)
        return TVPAL_E_FORMAT;
    *nspans = ns;
    return 0;
}

int tvpal_rle_blend(float *img, unsigned width, unsigned y0, unsigned y1,
                    const unsigned char *buf, size_t bytes, int front,
                    uint64_t *blended)
{
    uint32_t nspans;
    const size_t n = (size_t)width * (y1 - y0);
    float *base = img + (size_t)4 * width * y0;
    const float k16 = 1.0f / 65535.0f;
    int rc = rle_check(buf, bytes, n, &nspans);
    if (rc < 0)
        return rc;
    const unsigned char *hdr = buf + 4;
    const uint16_t *src = (const uint16_t *)(const void *)(hdr + 8 * (size_t)nspans);
    for (uint32_t k = 0; k < nspans; k++) {
        uint32_t se[2];
        memcpy(se, hdr + 8 * (size_t)k, 8);
        float *d = base + 4 * (size_t)se[0];
        for (uint32_t i = 0; i < se[1]; i++, d += 4, src += 4) {
            float s0 = src[0] * k16, s1 = src[1] * k16, s2 = src[2] * k16,
                  s3 = src[3] * k16;
            if (front) { /* received over own */
                float keep = 1.0f - s3;
                d[0] = s0 + keep * d[0];
                d[1] = s1 + keep * d[1];
                d[2] = s2 + keep * d[2];
                d[3] = s3 + keep * d[3];
            } else { /* own over received */
                float keep = 1.0f - d[3];
                d[0] += keep * s0;
                d[1] += keep * s1;
                d[2] += keep * s2;
                d[3] += keep * s3;
            }
        }
        *blended += se[1];
    }
    return 0;
}
