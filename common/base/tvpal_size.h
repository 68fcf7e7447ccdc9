/* tvpal_size.h: sizes from counts that a file claims, multiplied with
 * overflow checks.
 *
 * A count read from a file (extents, dims, steps, block and chunk counts)
 * is never multiplied with a bare `*`: a product that wraps passes every
 * bound checked after it (2^21 x 2^21 x 2^22 points is 2^64, which reads as
 * 0) and the buffer allocated for it is too small for the loops that
 * trust the factors.  Every such product goes through these helpers, which
 * return 0 with the product, or TVPAL_E_OVERFLOW (and leave *out as it
 * was) when it does not fit. */
#ifndef TVPAL_SIZE_H
#define TVPAL_SIZE_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_error.h"

/* *out = a * b. */
static inline int tvpal_mul(uint64_t a, uint64_t b, uint64_t *out)
{
    uint64_t p;
    if (__builtin_mul_overflow(a, b, &p))
        return TVPAL_E_OVERFLOW;
    *out = p;
    return 0;
}

/* *out = a * b * c. */
static inline int tvpal_mul3(uint64_t a, uint64_t b, uint64_t c,
                             uint64_t *out)
{
    uint64_t p;
    if (tvpal_mul(a, b, &p) < 0 || tvpal_mul(p, c, &p) < 0)
        return TVPAL_E_OVERFLOW;
    *out = p;
    return 0;
}

/* *out = dims[0] * dims[1] * dims[2] points, when an array of that many
 * elements of elem bytes each can be addressed (its bytes fit in size_t);
 * else TVPAL_E_OVERFLOW. */
static inline int tvpal_points(const uint32_t dims[3], uint64_t elem,
                               size_t *out)
{
    uint64_t n, bytes;
    if (tvpal_mul3(dims[0], dims[1], dims[2], &n) < 0 ||
        tvpal_mul(n, elem ? elem : 1, &bytes) < 0 || bytes > SIZE_MAX)
        return TVPAL_E_OVERFLOW;
    *out = (size_t)n;
    return 0;
}

#endif
