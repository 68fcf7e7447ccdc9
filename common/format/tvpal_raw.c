/* tvpal_raw.c: raw element conversion (see tvpal_raw.h). */
#include "tvpal_raw.h"
#include "tvpal_size.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const struct {
    const char *name;
    size_t size;
} types[] = {
    [TVPAL_F32] = {"f32", 4}, [TVPAL_F64] = {"f64", 8}, [TVPAL_U8] = {"u8", 1},
    [TVPAL_U16] = {"u16", 2}, [TVPAL_I16] = {"i16", 2},
};

int tvpal_type_parse(const char *s, enum tvpal_type *t)
{
    for (size_t i = 0; i < sizeof types / sizeof *types; i++)
        if (strcmp(s, types[i].name) == 0) {
            *t = (enum tvpal_type)i;
            return 0;
        }
    return TVPAL_E_INVAL;
}

const char *tvpal_type_name(enum tvpal_type t)
{
    return types[t].name;
}

size_t tvpal_type_size(enum tvpal_type t)
{
    return types[t].size;
}

int tvpal_dims_parse(const char *s, uint32_t dims[3], struct tvpal_diag *diag)
{
    const char *p = s;
    uint64_t total = 1;
    for (int i = 0; i < 3; i++) {
        char *end;
        if (*p < '0' || *p > '9')
            return tvpal_diag_set(diag, TVPAL_E_INVAL,
                                  "dims \"%s\": expected NXxNYxNZ, e.g. "
                                  "64x64x64", s);
        errno = 0;
        unsigned long long v = strtoull(p, &end, 10);
        if (errno == ERANGE || v > 0x7FFFFFFFull)
            return tvpal_diag_set(diag, TVPAL_E_OVERFLOW,
                                  "dims \"%s\": %s is too large", s,
                                  "a dimension");
        if (v == 0)
            return tvpal_diag_set(diag, TVPAL_E_INVAL,
                                  "dims \"%s\": every dimension must be at "
                                  "least 1", s);
        dims[i] = (uint32_t)v;
        if (tvpal_mul(total, v, &total) < 0 || total > UINT64_MAX / 8)
            return tvpal_diag_set(diag, TVPAL_E_OVERFLOW,
                                  "dims \"%s\": volume size overflows", s);
        p = end;
        if (i < 2) {
            if (*p != 'x' && *p != 'X')
                return tvpal_diag_set(diag, TVPAL_E_INVAL,
                                      "dims \"%s\": expected NXxNYxNZ, e.g. "
                                      "64x64x64", s);
            p++;
        }
    }
    if (*p)
        return tvpal_diag_set(diag, TVPAL_E_INVAL,
                              "dims \"%s\": trailing characters", s);
    if (total > (uint64_t)SIZE_MAX / 8)
        return tvpal_diag_set(diag, TVPAL_E_OVERFLOW,
                              "dims \"%s\": volume too large for memory", s);
    return 0;
}

static inline uint16_t ld16(const unsigned char *p, int be)
{
    return be ? (uint16_t)(p[0] << 8 | p[1]) : (uint16_t)(p[1] << 8 | p[0]);
}

static inline uint32_t ld32(const unsigned char *p, int be)
{
    return be ? (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 |
                    (uint32_t)p[2] << 8 | p[3]
              : (uint32_t)p[3] << 24 | (uint32_t)p[2] << 16 |
                    (uint32_t)p[1] << 8 | p[0];
}

int tvpal_raw_convert(const void *src, enum tvpal_type t, int big_endian,
                      size_t n, float *dst, const double *nan_as, size_t *bad,
                      size_t *replaced)
{
    size_t nrep = 0;
    const unsigned char *p = src;
    switch (t) {
    case TVPAL_U8:
        for (size_t i = 0; i < n; i++)
            dst[i] = p[i];
        return 0;
    case TVPAL_U16:
        for (size_t i = 0; i < n; i++)
            dst[i] = ld16(p + 2 * i, big_endian);
        return 0;
    case TVPAL_I16:
        for (size_t i = 0; i < n; i++)
            dst[i] = (int16_t)ld16(p + 2 * i, big_endian);
        return 0;
    case TVPAL_F32:
    case TVPAL_F64:
        break;
    }
    for (size_t i = 0; i < n; i++) {
        double v;
        if (t == TVPAL_F32) {
            uint32_t u = ld32(p + 4 * i, big_endian);
            float f;
            memcpy(&f, &u, 4);
            v = f;
        } else {
            uint64_t u = (uint64_t)ld32(p + 8 * i + (big_endian ? 0 : 4),
                                        big_endian) << 32 |
                         ld32(p + 8 * i + (big_endian ? 4 : 0), big_endian);
            memcpy(&v, &u, 8);
        }
        if (!isfinite(v)) {
            if (nan_as) {
                v = *nan_as;
                nrep++;
            } else if (v != v) {
                dst[i] = NAN; /* missing */
                continue;
            } else {
                *bad = i;
                return TVPAL_E_NAN;
            }
        }
        if (fabs(v) > TVPAL_VALUE_MAX) {
            *bad = i;
            return TVPAL_E_RANGE;
        }
        dst[i] = (float)v;
    }
    if (replaced)
        *replaced += nrep;
    return 0;
}

size_t tvpal_missing_apply(float *v, size_t n, const double *values,
                           unsigned nvalues, const double *nan_as)
{
    const float to = nan_as ? (float)*nan_as : NAN;
    float m[16];
    unsigned k = nvalues < 16 ? nvalues : 16;
    for (unsigned i = 0; i < k; i++)
        m[i] = (float)values[i];
    size_t hits = 0;
    for (size_t i = 0; i < n; i++)
        for (unsigned j = 0; j < k; j++)
            if (v[i] == m[j]) {
                v[i] = to;
                hits++;
                break;
            }
    return hits;
}
