/* Harness: raw conversion and dims strings (tvpal_raw.c).
 *
 * Input byte 0 picks the case: bit 7 set, the rest of the input is a dims
 * string for tvpal_dims_parse; else bits 0-2 the type (mod 5), bit 3 big
 * endian, bit 4 a NaN replacement (0.5), bit 5 missing values applied
 * after conversion, and the rest of the input is the elements. */
#include "fuzz_util.h"
#include "tvpal_raw.h"

#include <stdlib.h>

static void convert(uint8_t mode, const uint8_t *p, size_t n)
{
    enum tvpal_type t = (enum tvpal_type)((mode & 7) % 5);
    size_t count = n / tvpal_type_size(t);
    float *dst = malloc(count * sizeof *dst + 1);
    if (!dst)
        abort();
    const double nan_as = 0.5, missing[2] = {0.0, 1.0};
    size_t bad = 0, replaced = 0;
    int rc = tvpal_raw_convert(p, t, (mode >> 3) & 1, count, dst,
                               (mode & 16) ? &nan_as : NULL, &bad,
                               &replaced);
    if (rc < 0 && bad >= count && count)
        abort();    /* the index of the bad element is one of them */
    if (rc == 0 && (mode & 32))
        (void)tvpal_missing_apply(dst, count, missing, 2,
                                  (mode & 16) ? &nan_as : NULL);
    free(dst);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0)
        return 0;
    if (data[0] & 128) {
        char *s = fuzz_strdup(data + 1, size - 1);
        uint32_t dims[3];
        struct tvpal_diag d;
        (void)tvpal_dims_parse(s, dims, &d);
        free(s);
    } else {
        convert(data[0], data + 1, size - 1);
    }
    return 0;
}
