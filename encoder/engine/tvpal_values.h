/* tvpal_values.h: source values as the encoder takes them in: converted to
 * float32, checked, missing values marked, and counted into the source
 * statistics (range, replaced values, the fine histogram) that the
 * manifest and a resumed job's checkpoint need.
 *
 * A value is missing when it is NaN in the source, or equal to one of the
 * job's missing values; a missing value becomes NaN (or, with nan_as, that
 * value, counted as replaced).  Infinities and values beyond
 * TVPAL_VALUE_MAX are refused: the first one's index is reported.
 *
 * Library code: error convention of tvpal_error.h; nothing prints.
 */
#ifndef TVPAL_VALUES_H
#define TVPAL_VALUES_H

#include "tvpal_checkpoint.h"
#include "tvpal_format.h"
#include "tvpal_manifest.h"

#include <stddef.h>
#include <stdint.h>

/* What makes a value missing, and what it becomes. */
struct tvpal_values_rules {
    const double *missing;      /* nmissing values, or NULL */
    unsigned nmissing;
    const double *nan_as;       /* replacement of missing values, or NULL */
};

/* What converting a run of values found, merged over runs and threads
 * (tvpal_found_merge); starts as tvpal_found_empty. */
struct tvpal_found {
    uint64_t bad;            /* lowest volume index of a refused value */
    int rc;                  /* its code (TVPAL_E_NAN or _RANGE), or 0 */
    int read_err;            /* the caller's: errno of a failed read, -1 at
                              * end of file */
    size_t nrep;             /* values replaced by nan_as */
    size_t nmiss;            /* missing values (NaN after conversion) */
    double lo, hi;           /* range including the stats' so far */
};

/* No finding yet, over the range so far [lo, hi]. */
struct tvpal_found tvpal_found_empty(double lo, double hi);

/* f into all: the lowest index's refusal wins, the first read error,
 * counts and range add (in any order: the same result). */
void tvpal_found_merge(struct tvpal_found *all, const struct tvpal_found *f);

/* Converts n values at src (of type, in big-endian order when big_endian)
 * into dst, applying rules; vox0 is the volume index of the first (for
 * f->bad).  With fine (TVPAL_CHECKPOINT_BINS counters) non-NULL, the
 * values are counted: present ones into fine and f's range, missing ones
 * into f->nmiss, replaced ones into f->nrep.  A refused value sets f->bad
 * and f->rc and leaves dst and the counts of this run unspecified. */
void tvpal_values_convert(const struct tvpal_values_rules *rules,
                          const void *src, enum tvpal_type type,
                          int big_endian, size_t n, float *dst,
                          uint64_t vox0, uint64_t *fine,
                          struct tvpal_found *f);

/* Accounts a converted step (or box) of `voxels` values into st: the
 * threads' fine histograms fine[0 .. n-1] (tvpal_values_fold; n = 0: the
 * caller folds them later) and what they found, merged in all (range,
 * replaced and missing values). */
void tvpal_values_account(struct tvpal_checkpoint_stats *st,
                          uint64_t *const *fine, unsigned n,
                          const struct tvpal_found *all, uint64_t voxels);

/* Adds the threads' fine histograms fine[0 .. n-1] into st's and zeroes
 * them.  A caller whose steps are small folds them only when st's
 * histogram is needed (65536 classes per thread against a step's values). */
void tvpal_values_fold(struct tvpal_checkpoint_stats *st,
                       uint64_t *const *fine, unsigned n);

/* The value at the middle of a class of the fine histogram. */
float tvpal_values_bin_value(uint32_t b);

/* How the present values of st's fine histogram spread: the classes'
 * values at the 0.1 and 99.9 percentiles (*lo, *hi), the values beyond
 * +-1e30 (*huge: a fill value left in the data?) and those more than 100
 * times the percentile span outside it (*far); all 0 without values. */
void tvpal_values_spread(const struct tvpal_checkpoint_stats *st, double *lo,
                         double *hi, uint64_t *huge, uint64_t *far);

/* The manifest's histogram of st: its fine classes into TVPAL_HIST_BINS
 * equal bins over [st->vmin, st->vmax], added to hist. */
void tvpal_values_histogram(const struct tvpal_checkpoint_stats *st,
                            uint64_t hist[TVPAL_HIST_BINS]);

#endif
