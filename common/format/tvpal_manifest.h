/* tvpal_manifest.h: the dataset's human-readable manifest (manifest.txt).
 *
 * Lines of "key = value"; '#' starts a comment.  Keys that repeat (source)
 * keep their order.  Unknown keys are ignored on load, so later versions may
 * add keys; a missing required key is an error naming it.
 */
#ifndef TVPAL_MANIFEST_H
#define TVPAL_MANIFEST_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_error.h"
#include "tvpal_raw.h"

#define TVPAL_HIST_BINS 64
#define TVPAL_MISSING_VALUES_MAX 16
#define TVPAL_LEVELS_MAX 8
/* Axes stored, as a mask: bit a for axis a (FORMAT.md 4.1: 0 x, 1 y, 2 z). */
#define TVPAL_AXES_ALL 7u
#define TVPAL_AXIS_BIT(a) (1u << (a))

struct tvpal_manifest {
    uint32_t dims[3];
    enum tvpal_type type;
    int big_endian;
    uint32_t steps, window, nodes;
    uint32_t schedule;                    /* TVPAL_SCHEDULE_* (FORMAT.md 5):
                                           * key "schedule", absent = 0 */
    double value_min, value_max;          /* of the source, after NaN policy */
    uint64_t histogram[TVPAL_HIST_BINS];  /* linear bins over [min, max] */
    int has_nan_as;
    double nan_as;
    uint64_t nonfinite;                   /* values replaced by nan_as */
    uint64_t missing;                     /* missing source values (NaN,
                                           * CF fill/valid range,
                                           * missing_values), T*nx*ny*nz
                                           * at most; not in the range or
                                           * the histogram */
    double missing_values[TVPAL_MISSING_VALUES_MAX]; /* --missing V: source
                                           * values that mean missing,
                                           * compared as float32 */
    unsigned nmissing_values;
    int single_file;                      /* one input holding all steps */
    int series;                           /* self-describing files of one
                                           * or more steps each, in order
                                           * (source_layout = series) */
    char source_format[16];               /* "raw" (or "" = raw), "netcdf",
                                           * "vti": how to read the sources */
    char *source_var;                     /* owned; the variable read from
                                           * self-describing sources */
    double spacing[3];                    /* voxel size per axis; loaded
                                           * 1 1 1 when absent */
    double origin[3];                     /* the first voxel's position */
    double *times;                        /* owned; ntimes (0, or steps)
                                           * time values of the steps */
    uint32_t ntimes;
    char time_units[128];                 /* e.g. "hours since ...", or "" */
    char units[64];                       /* the values' units (the source
                                           * variable's units attribute,
                                           * or --units), or "" */
    uint64_t source_bytes;
    uint32_t table_format;                /* the key "table": 0 f32 (float32),
                                           * 1 u16 (16-bit scaled), 4 auto
                                           * (per chunk; TVPAL_TABLE_*) */
    uint32_t levels;                      /* coarser levels of detail in
                                           * level-1/ .. level-L/ (0: none;
                                           * at most TVPAL_LEVELS_MAX) */
    uint32_t axes_mask;                   /* axes whose shards exist
                                           * (manifest key axes):
                                           * TVPAL_AXIS_BIT(a) per axis,
                                           * 1..7; TVPAL_AXES_ALL when the
                                           * key is absent */
    char *encoder;                        /* owned strings (may be NULL) */
    char *options;
    size_t nsources;
    char **sources;                       /* owned, nsources entries */
};

/* The manifest's name of a table format 0, 1 or 4: "f32", "u16", "auto". */
const char *tvpal_manifest_table_name(uint32_t table_format);

/* Frees the owned strings and zeroes m. */
void tvpal_manifest_clear(struct tvpal_manifest *m);

/* Renders m as text into a malloc'ed string (*out owned by the caller).
 * format_version is the lowest that describes m (FORMAT.md 3.2): 4 with
 * the whole-window schedule, else 3 when m->axes_mask is not
 * TVPAL_AXES_ALL, else 2 with levels, else 1.
 * TVPAL_E_INVAL when m->axes_mask is not in 1..7, TVPAL_E_NOMEM. */
int tvpal_manifest_format(const struct tvpal_manifest *m, char **out);

/* Parses path into m, which must hold nothing owned (zeroed or cleared): it
 * is overwritten.  diag names the line or key at fault; on error m holds
 * nothing. */
int tvpal_manifest_load(const char *path, struct tvpal_manifest *m,
                        struct tvpal_diag *diag);

/* The rule the manifest reader applies to every number it reads back
 * (spacing, origin, times, value range, missing values): a finite value
 * that is 0 or normal.  A subnormal (1e-310) is written as "%.17g" and read
 * back with ERANGE, so a dataset holding one would not open: writers check
 * their numbers with this before any work.  1 or 0. */
int tvpal_manifest_number_ok(double v);

/* The grid and times a dataset would hold, checked by the reader's rule:
 * each spacing and origin tvpal_manifest_number_ok, a spacing also
 * non-zero (the reader wants > 0; a writer stores |spacing|), and each of
 * times[0..ntimes) (times may be NULL).  0, or TVPAL_E_RANGE with diag
 * naming the key, the axis or step, and the value ("spacing on axis z is
 * 1e-310: ..."). */
int tvpal_manifest_check_grid(const double spacing[3], const double origin[3],
                              const double *times, uint32_t ntimes,
                              struct tvpal_diag *diag);

/* Appends a copy of src to m->sources. */
int tvpal_manifest_add_source(struct tvpal_manifest *m, const char *src);

#endif
