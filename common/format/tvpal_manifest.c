/* tvpal_manifest.c: manifest text format (see tvpal_manifest.h). */
#include "tvpal_manifest.h"
#include "tvpal_schedule.h"
#include "tvpal_cli.h"
#include "tvpal_format.h"
#include "tvpal_fs.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *tvpal_manifest_table_name(uint32_t table_format)
{
    return table_format == TVPAL_TABLE_U16     ? "u16"
           : table_format == TVPAL_TABLE_CHUNK ? "auto"
                                               : "f32";
}

void tvpal_manifest_clear(struct tvpal_manifest *m)
{
    free(m->encoder);
    free(m->options);
    free(m->source_var);
    free(m->times);
    for (size_t i = 0; i < m->nsources; i++)
        free(m->sources[i]);
    free(m->sources);
    memset(m, 0, sizeof *m);
}

int tvpal_manifest_add_source(struct tvpal_manifest *m, const char *src)
{
    char **s = realloc(m->sources, (m->nsources + 1) * sizeof *s);
    if (!s)
        return TVPAL_E_NOMEM;
    m->sources = s;
    if (!(s[m->nsources] = strdup(src)))
        return TVPAL_E_NOMEM;
    m->nsources++;
    return 0;
}

/* The lowest format_version that describes m (FORMAT.md 3.2, 10.3). */
static unsigned format_version_of(const struct tvpal_manifest *m)
{
    return m->schedule == TVPAL_SCHEDULE_JOINED ? 4
           : m->axes_mask != TVPAL_AXES_ALL    ? 3
           : m->levels                         ? 2
                                               : 1;
}

int tvpal_manifest_format(const struct tvpal_manifest *m, char **out)
{
    char *buf = NULL;
    size_t len = 0;
    char axes[4];
    if (m->axes_mask < 1 || m->axes_mask > TVPAL_AXES_ALL)
        return TVPAL_E_INVAL;
    FILE *f = open_memstream(&buf, &len);
    if (!f)
        return TVPAL_E_NOMEM;
    fprintf(f, "# tvpal dataset manifest (spec: common/format/FORMAT.md)\n");
    /* A version above 1 only where the dataset needs it (levels, a subset
     * of the axes), so that older readers still take every dataset they
     * can read and refuse the others. */
    fprintf(f, "format = tvpal-dataset\nformat_version = %u\n",
            format_version_of(m));
    fprintf(f, "encoder = %s\n", m->encoder ? m->encoder : "unknown");
    fprintf(f, "options = %s\n", m->options ? m->options : "");
    fprintf(f, "dims = %ux%ux%u\n", m->dims[0], m->dims[1], m->dims[2]);
    fprintf(f, "type = %s\n", tvpal_type_name(m->type));
    fprintf(f, "endian = %s\n", m->big_endian ? "big" : "little");
    fprintf(f, "steps = %u\nwindow = %u\nnodes = %u\n", m->steps, m->window,
            m->nodes);
    /* Absent means staggered (every dataset before the key). */
    if (m->schedule == TVPAL_SCHEDULE_JOINED)
        fprintf(f, "schedule = %s\n", tvpal_schedule_name(m->schedule));
    /* Absent means all three (datasets as before the key had a rule). */
    if (m->axes_mask != TVPAL_AXES_ALL)
        fprintf(f, "axes = %s\n", tvpal_axes_format(m->axes_mask, axes));
    fprintf(f, "table = %s\n", tvpal_manifest_table_name(m->table_format));
    if (m->levels)
        fprintf(f, "levels = %u\n", m->levels);
    fprintf(f, "value_min = %.9g\nvalue_max = %.9g\n", m->value_min,
            m->value_max);
    if (m->has_nan_as)
        fprintf(f, "nan_as = %.17g\n", m->nan_as);
    else
        fprintf(f, "nan_as = none\n");
    fprintf(f, "nonfinite_replaced = %llu\n",
            (unsigned long long)m->nonfinite);
    /* Missing values: absent when there are none and none were asked for
     * (manifests as before these keys). */
    if (m->nmissing_values) {
        fprintf(f, "missing_values =");
        for (unsigned i = 0; i < m->nmissing_values; i++)
            fprintf(f, " %.9g", m->missing_values[i]);
        fputc('\n', f);
    }
    if (m->missing || m->nmissing_values)
        fprintf(f, "missing = %llu\n", (unsigned long long)m->missing);
    fprintf(f, "histogram_bins = %d\nhistogram =", TVPAL_HIST_BINS);
    for (int i = 0; i < TVPAL_HIST_BINS; i++)
        fprintf(f, " %llu", (unsigned long long)m->histogram[i]);
    fprintf(f, "\nsource_bytes = %llu\n", (unsigned long long)m->source_bytes);
    fprintf(f, "source_layout = %s\n", m->single_file ? "single-file"
                                      : m->series ? "series" : "file-per-step");
    /* Raw sources say nothing more (manifests as before these keys). */
    if (m->source_format[0] && strcmp(m->source_format, "raw")) {
        fprintf(f, "source_format = %s\n", m->source_format);
        fprintf(f, "source_var = %s\n", m->source_var ? m->source_var : "");
    }
    if (m->units[0])
        fprintf(f, "units = %s\n", m->units);
    /* The physical grid, unless it is the default one (or unset: 0). */
    const double *sp = m->spacing, *o = m->origin;
    if ((sp[0] || sp[1] || sp[2]) && (sp[0] != 1 || sp[1] != 1 || sp[2] != 1))
        fprintf(f, "spacing = %.17g %.17g %.17g\n", sp[0], sp[1], sp[2]);
    if (o[0] || o[1] || o[2])
        fprintf(f, "origin = %.17g %.17g %.17g\n", o[0], o[1], o[2]);
    if (m->ntimes) {
        fprintf(f, "time_units = %s\ntimes =", m->time_units);
        for (uint32_t i = 0; i < m->ntimes; i++)
            fprintf(f, " %.17g", m->times[i]);
        fputc('\n', f);
    }
    for (size_t i = 0; i < m->nsources; i++)
        fprintf(f, "source = %s\n", m->sources[i]);
    if (fclose(f) != 0) {
        free(buf);
        return TVPAL_E_NOMEM;
    }
    *out = buf;
    return 0;
}

static char *trim(char *s)
{
    while (*s == ' ' || *s == '\t')
        s++;
    char *e = s + strlen(s);
    while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\n' ||
                     e[-1] == '\r'))
        *--e = 0;
    return s;
}

static int parse_u32(const char *v, uint32_t *out)
{
    char *end;
    errno = 0;
    unsigned long long x = strtoull(v, &end, 10);
    if (errno || *end || end == v || x > 0xFFFFFFFFull)
        return -1;
    *out = (uint32_t)x;
    return 0;
}

int tvpal_manifest_number_ok(double v)
{
    return isfinite(v) && (v == 0 || fabs(v) >= DBL_MIN);
}

int tvpal_manifest_check_grid(const double spacing[3], const double origin[3],
                              const double *times, uint32_t ntimes,
                              struct tvpal_diag *diag)
{
    static const char why[] = "a finite number, 0 or of magnitude at least "
                              "2.2250738585072014e-308, expected";
    for (int a = 0; a < 3; a++) {
        if (!tvpal_manifest_number_ok(spacing[a]) || spacing[a] == 0)
            return tvpal_diag_set(diag, TVPAL_E_RANGE, "spacing on axis %c "
                                  "is %.17g (a finite non-zero number of "
                                  "magnitude at least 2.2250738585072014e-308 "
                                  "expected)", "xyz"[a], spacing[a]);
        if (!tvpal_manifest_number_ok(origin[a]))
            return tvpal_diag_set(diag, TVPAL_E_RANGE, "origin on axis %c is "
                                  "%.17g (%s)", "xyz"[a], origin[a], why);
    }
    for (uint32_t t = 0; times && t < ntimes; t++)
        if (!tvpal_manifest_number_ok(times[t]))
            return tvpal_diag_set(diag, TVPAL_E_RANGE, "the time of step %u "
                                  "is %.17g (%s)", t, times[t], why);
    return 0;
}

/* A number as the manifest holds it (tvpal_manifest_number_ok): strtod
 * says ERANGE for what overflows and for subnormals. */
static int parse_dbl(const char *v, double *out)
{
    char *end;
    errno = 0;
    *out = strtod(v, &end);
    return (errno || *end || end == v || !tvpal_manifest_number_ok(*out))
               ? -1 : 0;
}

/* parse_dbl, and the value is finite (not nan or +-inf). */
static int parse_finite(const char *v, double *out)
{
    return parse_dbl(v, out) || !isfinite(*out) ? -1 : 0;
}

/* Three finite numbers "a b c"; spacing must also be > 0. */
static int parse_triple(const char *v, double out[3], int positive)
{
    char *end;
    const char *p = v;
    for (int i = 0; i < 3; i++) {
        errno = 0;
        out[i] = strtod(p, &end);
        if (end == p || errno || !tvpal_manifest_number_ok(out[i]) ||
            (positive && !(out[i] > 0)))
            return -1;
        p = end;
    }
    while (*p == ' ' || *p == '\t')
        p++;
    return *p ? -1 : 0;
}

/* "times = v v v ...": finite numbers, as many as the line holds (the
 * check against steps comes after every line is read). */
/* Decimal digits only (strtoull would take "-1" as 2^64-1). */
static int parse_u64(const char *v, uint64_t *out)
{
    char *end;
    errno = 0;
    if (*v < '0' || *v > '9')
        return -1;
    unsigned long long x = strtoull(v, &end, 10);
    if (errno || *end)
        return -1;
    *out = x;
    return 0;
}

/* Up to TVPAL_MISSING_VALUES_MAX finite numbers separated by spaces. */
static int parse_missing_values(struct tvpal_manifest *m, const char *v)
{
    m->nmissing_values = 0;
    for (const char *p = v;;) {
        while (*p == ' ' || *p == '\t')
            p++;
        if (!*p)
            return 0;
        char *end;
        errno = 0;
        double x = strtod(p, &end);
        if (end == p || errno || !tvpal_manifest_number_ok(x) ||
            m->nmissing_values == TVPAL_MISSING_VALUES_MAX)
            return -1;
        m->missing_values[m->nmissing_values++] = x;
        p = end;
    }
}

static int parse_times(struct tvpal_manifest *m, const char *v)
{
    free(m->times);
    m->times = NULL;
    m->ntimes = 0;
    size_t cap = 0;
    for (const char *p = v;;) {
        while (*p == ' ' || *p == '\t')
            p++;
        if (!*p)
            return 0;
        char *end;
        errno = 0;
        double t = strtod(p, &end);
        if (end == p || errno || !tvpal_manifest_number_ok(t) ||
            m->ntimes == UINT32_MAX)
            return -1;
        if (m->ntimes == cap) {
            cap = cap ? 2 * cap : 64;
            double *nt = realloc(m->times, cap * sizeof *nt);
            if (!nt)
                return -1;
            m->times = nt;
        }
        m->times[m->ntimes++] = t;
        p = end;
    }
}

enum { K_DIMS = 1, K_TYPE = 2, K_STEPS = 4, K_WINDOW = 8, K_NODES = 16,
       K_MIN = 32, K_MAX = 64, K_FORMAT = 128 };

/* Applies one "key = value" line to m, noting required keys in *seen and
 * the format_version in *version.  Unknown keys are ignored (FORMAT.md:
 * later versions may add keys).  0, TVPAL_E_VERSION or TVPAL_E_MANIFEST
 * naming the line. */
static int manifest_set(struct tvpal_manifest *m, const char *k, char *v,
                        unsigned lineno, unsigned *seen, uint32_t *version,
                        struct tvpal_diag *diag)
{
    int bad = 0;
    if (!strcmp(k, "format")) {
        bad = strcmp(v, "tvpal-dataset") != 0;
        *seen |= K_FORMAT;
    } else if (!strcmp(k, "format_version")) {
        if (parse_u32(v, version) || *version < 1 || *version > 4)
            return tvpal_diag_set(diag, TVPAL_E_VERSION,
                                  "line %u: format_version %s, expected 1 "
                                  "to 4", lineno, v);
    } else if (!strcmp(k, "schedule")) {
        const char *joined = tvpal_schedule_name(TVPAL_SCHEDULE_JOINED);
        bad = strcmp(v, joined) &&
              strcmp(v, tvpal_schedule_name(TVPAL_SCHEDULE_STAGGERED));
        m->schedule = !strcmp(v, joined) ? TVPAL_SCHEDULE_JOINED
                                         : TVPAL_SCHEDULE_STAGGERED;
    } else if (!strcmp(k, "axes")) {
        bad = tvpal_axes_parse(v, &m->axes_mask) < 0;
    } else if (!strcmp(k, "dims")) {
        bad = tvpal_dims_parse(v, m->dims, NULL) < 0;
        *seen |= K_DIMS;
    } else if (!strcmp(k, "type")) {
        bad = tvpal_type_parse(v, &m->type) < 0;
        *seen |= K_TYPE;
    } else if (!strcmp(k, "endian")) {
        bad = strcmp(v, "big") && strcmp(v, "little");
        m->big_endian = !strcmp(v, "big");
    } else if (!strcmp(k, "steps")) {
        bad = parse_u32(v, &m->steps) || !m->steps;
        *seen |= K_STEPS;
    } else if (!strcmp(k, "window")) {
        bad = parse_u32(v, &m->window) || m->window < 1 || m->window > 16;
        *seen |= K_WINDOW;
    } else if (!strcmp(k, "nodes")) {
        bad = parse_u32(v, &m->nodes) || !m->nodes;
        *seen |= K_NODES;
    } else if (!strcmp(k, "value_min")) {
        bad = parse_finite(v, &m->value_min);
        *seen |= K_MIN;
    } else if (!strcmp(k, "value_max")) {
        bad = parse_finite(v, &m->value_max);
        *seen |= K_MAX;
    } else if (!strcmp(k, "nan_as")) {
        m->has_nan_as = strcmp(v, "none") != 0;
        bad = m->has_nan_as && parse_dbl(v, &m->nan_as);
    } else if (!strcmp(k, "missing")) {
        bad = parse_u64(v, &m->missing);
    } else if (!strcmp(k, "missing_values")) {
        bad = parse_missing_values(m, v) < 0;
    } else if (!strcmp(k, "histogram")) {
        char *p = v;
        for (int i = 0; i < TVPAL_HIST_BINS && !bad; i++) {
            /* Decimal digits only: strtoull would take "-1" as 2^64-1. */
            while (*p == ' ' || *p == '\t')
                p++;
            char *end;
            errno = 0;
            m->histogram[i] = strtoull(p, &end, 10);
            bad = *p < '0' || *p > '9' || errno == ERANGE;
            p = end;
        }
    } else if (!strcmp(k, "levels")) {
        bad = parse_u32(v, &m->levels) || m->levels > TVPAL_LEVELS_MAX;
    } else if (!strcmp(k, "table")) {
        static const uint32_t formats[] = {TVPAL_TABLE_F32, TVPAL_TABLE_U16,
                                           TVPAL_TABLE_CHUNK};
        bad = 1;
        for (size_t i = 0; i < sizeof formats / sizeof *formats; i++)
            if (!strcmp(v, tvpal_manifest_table_name(formats[i]))) {
                m->table_format = formats[i];
                bad = 0;
            }
    } else if (!strcmp(k, "source_bytes")) {
        m->source_bytes = strtoull(v, NULL, 10);
    } else if (!strcmp(k, "source_layout")) {
        m->single_file = !strcmp(v, "single-file");
        m->series = !strcmp(v, "series");
    } else if (!strcmp(k, "source_format")) {
        bad = strlen(v) >= sizeof m->source_format;
        if (!bad)
            strcpy(m->source_format, v);
    } else if (!strcmp(k, "spacing")) {
        bad = parse_triple(v, m->spacing, 1) < 0;
    } else if (!strcmp(k, "origin")) {
        bad = parse_triple(v, m->origin, 0) < 0;
    } else if (!strcmp(k, "times")) {
        bad = parse_times(m, v) < 0;
    } else if (!strcmp(k, "units")) {
        bad = strlen(v) >= sizeof m->units;
        if (!bad)
            strcpy(m->units, v);
    } else if (!strcmp(k, "time_units")) {
        bad = strlen(v) >= sizeof m->time_units;
        if (!bad)
            strcpy(m->time_units, v);
    } else if (!strcmp(k, "source_var")) {
        free(m->source_var);
        bad = !(m->source_var = strdup(v));
    } else if (!strcmp(k, "encoder")) {
        free(m->encoder);
        bad = !(m->encoder = strdup(v));
    } else if (!strcmp(k, "options")) {
        free(m->options);
        bad = !(m->options = strdup(v));
    } else if (!strcmp(k, "source")) {
        bad = tvpal_manifest_add_source(m, v) < 0;
    }
    if (bad)
        return tvpal_diag_set(diag, TVPAL_E_MANIFEST,
                              "line %u: bad value for %s: \"%s\"", lineno, k,
                              v);
    return 0;
}

/* The rules between keys, once all lines are read: every required key
 * present, a subset of the axes only in format_version 3 or later,
 * value_min <= value_max, nodes within the dimensions, one source line
 * per step. */
static int manifest_check(const struct tvpal_manifest *m, unsigned seen,
                          uint32_t version, struct tvpal_diag *diag)
{
    static const struct { unsigned bit; const char *name; } req[] = {
        {K_FORMAT, "format"}, {K_DIMS, "dims"}, {K_TYPE, "type"},
        {K_STEPS, "steps"}, {K_WINDOW, "window"}, {K_NODES, "nodes"},
        {K_MIN, "value_min"}, {K_MAX, "value_max"}};
    for (size_t i = 0; i < sizeof req / sizeof *req; i++)
        if (!(seen & req[i].bit))
            return tvpal_diag_set(diag, TVPAL_E_MANIFEST,
                                  "required key \"%s\" is missing",
                                  req[i].name);
    /* A reader of version 1 or 2 would look for the absent axes' shards:
     * a writer must say 3 (FORMAT.md 3.2). */
    char axes[4];
    if (m->axes_mask != TVPAL_AXES_ALL && version < 3)
        return tvpal_diag_set(diag, TVPAL_E_MANIFEST,
                              "axes = %s (a subset of the axes) needs "
                              "format_version 3, not %u",
                              tvpal_axes_format(m->axes_mask, axes), version);
    /* Its windows are not the ones a reader of versions 1 to 3 knows. */
    if (m->schedule == TVPAL_SCHEDULE_JOINED && version < 4)
        return tvpal_diag_set(diag, TVPAL_E_MANIFEST,
                              "schedule = joined needs format_version 4, "
                              "not %u", version);
    if (m->value_min > m->value_max)
        return tvpal_diag_set(diag, TVPAL_E_MANIFEST,
                              "value_min %.9g exceeds value_max %.9g",
                              m->value_min, m->value_max);
    uint32_t mind = m->dims[0] < m->dims[1] ? m->dims[0] : m->dims[1];
    mind = m->dims[2] < mind ? m->dims[2] : mind;
    if (m->nodes > mind)
        return tvpal_diag_set(diag, TVPAL_E_MANIFEST,
                              "nodes = %u exceeds the smallest dimension %u",
                              m->nodes, mind);
    if (m->ntimes && m->ntimes != m->steps)
        return tvpal_diag_set(diag, TVPAL_E_MANIFEST,
                              "%u time values for %u steps", m->ntimes,
                              m->steps);
    if (!m->single_file && !m->series && m->nsources &&
        m->nsources != m->steps)
        return tvpal_diag_set(diag, TVPAL_E_MANIFEST,
                              "%zu source lines for %u steps", m->nsources,
                              m->steps);
    return 0;
}

int tvpal_manifest_load(const char *path, struct tvpal_manifest *m,
                        struct tvpal_diag *diag)
{
    memset(m, 0, sizeof *m);
    m->spacing[0] = m->spacing[1] = m->spacing[2] = 1;  /* absent: unit grid */
    m->axes_mask = TVPAL_AXES_ALL;                        /* absent: all */
    int rc = 0;
    FILE *f = tvpal_fopen_text(path, &rc, diag);
    if (!f)
        return rc;
    char *line = NULL;
    size_t cap = 0;
    unsigned lineno = 0, seen = 0;
    uint32_t version = 1; /* absent: version 1 */
    while (rc == 0 && getline(&line, &cap, f) > 0) {
        lineno++;
        char *s = trim(line);
        if (!*s || *s == '#')
            continue;
        char *eq = strchr(s, '=');
        if (!eq) {
            rc = tvpal_diag_set(diag, TVPAL_E_MANIFEST,
                                "line %u: expected \"key = value\"", lineno);
            break;
        }
        *eq = 0;
        rc = manifest_set(m, trim(s), trim(eq + 1), lineno, &seen, &version,
                          diag);
    }
    if (rc == 0)
        rc = manifest_check(m, seen, version, diag);
    free(line);
    fclose(f);
    if (rc < 0)
        tvpal_manifest_clear(m);
    return rc;
}
