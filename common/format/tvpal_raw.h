/* tvpal_raw.h: raw input volumes: element types, byte order, dims strings,
 * conversion to float32 with NaN/infinity policy. */
#ifndef TVPAL_RAW_H
#define TVPAL_RAW_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_error.h"

enum tvpal_type { TVPAL_F32, TVPAL_F64, TVPAL_U8, TVPAL_U16, TVPAL_I16 };

/* "f32" etc.; returns 0 or TVPAL_E_INVAL. */
int tvpal_type_parse(const char *s, enum tvpal_type *t);
const char *tvpal_type_name(enum tvpal_type t);
size_t tvpal_type_size(enum tvpal_type t);

/* "NXxNYxNZ" with each in 1..2^31-1 and the product times 8 bytes
 * representable; else TVPAL_E_INVAL (malformed or zero) or
 * TVPAL_E_OVERFLOW, with the reason in diag. */
int tvpal_dims_parse(const char *s, uint32_t dims[3], struct tvpal_diag *diag);

/* Largest magnitude accepted: leaves headroom so that DCT coefficients
 * (up to 4x a sample for N = 16) stay finite in float32. */
#define TVPAL_VALUE_MAX 1e37

/* Converts n elements of type t (byte order: big_endian) to float.  NaN and
 * +-inf become *nan_as when nan_as is non-NULL (their count is added to
 * *replaced when replaced is non-NULL); otherwise NaN stays NaN (a missing
 * value) and the first +-inf stops the conversion with TVPAL_E_NAN and its
 * element index in *bad.  |value| > TVPAL_VALUE_MAX gives TVPAL_E_RANGE
 * (index in *bad). */
int tvpal_raw_convert(const void *src, enum tvpal_type t, int big_endian,
                      size_t n, float *dst, const double *nan_as,
                      size_t *bad, size_t *replaced);

/* Missing values given by value (tvpal-encode --missing V): each of the n
 * floats equal to float32(values[k]) for some k < nvalues (at most 16)
 * becomes NaN (missing), or *nan_as when nan_as is non-NULL (--nan-as).
 * Returns how many did. */
size_t tvpal_missing_apply(float *v, size_t n, const double *values,
                           unsigned nvalues, const double *nan_as);

#endif
