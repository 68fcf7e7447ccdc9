/* tvpal_tf.c: transfer functions (see tvpal_tf.h). */
#include "tvpal_tf.h"
#include "tvpal_fs.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int add_point(struct tvpal_tf *tf, double v, const float c[4],
                     unsigned line, struct tvpal_diag *diag)
{
    if (tf->npoints >= TVPAL_TF_MAX_POINTS)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "line %u: more than %d points", line,
                              TVPAL_TF_MAX_POINTS);
    if (tf->npoints && v < tf->value[tf->npoints - 1])
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "line %u: value %g is below the previous "
                              "point's %g; expected non-decreasing values",
                              line, v, tf->value[tf->npoints - 1]);
    tf->value[tf->npoints] = v;
    memcpy(tf->rgba[tf->npoints], c, sizeof(float) * 4);
    tf->npoints++;
    return 0;
}

/* Checks that each of c's 4 components lies in [0, 1]; `what` prefixes
 * the component's name in the message ("" for a point, "nan " for the
 * NaN colour). */
static int check_unit_rgba(const float c[4], const char *what, unsigned line,
                           struct tvpal_diag *diag)
{
    for (int i = 0; i < 4; i++)
        if (!(c[i] >= 0.0f && c[i] <= 1.0f))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "line %u: %s%c = %g; expected 0..1", line,
                                  what, "rgba"[i], c[i]);
    return 0;
}

/* The text format's "nan r g b a" line s (after the keyword check). */
static int parse_nan_line(const char *s, unsigned line, struct tvpal_tf *tf,
                          struct tvpal_diag *diag)
{
    float c[4];
    char extra;
    if (sscanf(s, "%*s %f %f %f %f %c", &c[0], &c[1], &c[2], &c[3],
               &extra) != 4)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "line %u: expected \"nan r g b a\" (4 numbers "
                              "0..1), got \"%s\"", line, s);
    int rc = check_unit_rgba(c, "nan ", line, diag);
    if (rc < 0)
        return rc;
    memcpy(tf->nan_rgba, c, sizeof c);
    return 0;
}

int tvpal_tf_parse_text(const char *text, double vmin, double vmax,
                        struct tvpal_tf *tf, struct tvpal_diag *diag)
{
    memset(tf, 0, sizeof *tf);
    snprintf(tf->name, sizeof tf->name, "text");
    int normalized = -1; /* unknown until the domain line */
    unsigned line = 0;
    const char *p = text;
    while (*p) {
        const char *e = strchr(p, '\n');
        size_t n = e ? (size_t)(e - p) : strlen(p);
        char buf[512];
        line++;
        if (n >= sizeof buf)
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "line %u: too long",
                                  line);
        memcpy(buf, p, n);
        buf[n] = 0;
        p += n + (e ? 1 : 0);
        char *hash = strchr(buf, '#');
        if (hash)
            *hash = 0;
        char *s = buf;
        while (isspace((unsigned char)*s))
            s++;
        if (!*s)
            continue;
        char word[32];
        if (sscanf(s, "%31s", word) == 1 && !strcmp(word, "domain")) {
            char kind[32] = "";
            sscanf(s, "%*s %31s", kind);
            if (!strcmp(kind, "normalized"))
                normalized = 1;
            else if (!strcmp(kind, "data"))
                normalized = 0;
            else
                return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                      "line %u: domain \"%s\": expected "
                                      "normalized or data", line, kind);
            continue;
        }
        if (!strcmp(word, "name")) {
            char nm[64] = "";
            sscanf(s, "%*s %63s", nm);
            snprintf(tf->name, sizeof tf->name, "%s", nm);
            continue;
        }
        if (!strcmp(word, "nan")) {
            int rc = parse_nan_line(s, line, tf, diag);
            if (rc < 0)
                return rc;
            continue;
        }
        if (normalized < 0)
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "line %u: expected \"domain normalized\" or "
                                  "\"domain data\" before the points", line);
        double v;
        float c[4];
        char extra;
        int k = sscanf(s, "%lf %f %f %f %f %c", &v, &c[0], &c[1], &c[2],
                       &c[3], &extra);
        if (k != 5)
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "line %u: expected 5 numbers \"value r g b "
                                  "a\", got \"%s\"", line, s);
        int rc = check_unit_rgba(c, "", line, diag);
        if (rc < 0)
            return rc;
        if (!isfinite(v))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "line %u: value is not finite", line);
        if (normalized)
            v = vmin + v * (vmax - vmin);
        rc = add_point(tf, v, c, line, diag);
        if (rc < 0)
            return rc;
    }
    if (!tf->npoints)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "no points (expected lines \"value r g b a\")");
    return 0;
}

/* The value of "key" in json: the first occurrence of the quoted key
 * followed by ':' (a string that equals the key is skipped), past the
 * colon and blanks.  NULL when the key is absent. */
static const char *json_value(const char *json, const char *key)
{
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\"", key);
    for (const char *p = strstr(json, pat); p; p = strstr(p + 1, pat)) {
        const char *q = p + strlen(pat);
        while (isspace((unsigned char)*q))
            q++;
        if (*q != ':')
            continue;
        q++;
        while (isspace((unsigned char)*q))
            q++;
        return q;
    }
    return NULL;
}

/* Reads the numeric array value of "key" in json into out.  Returns 1
 * when read, 0 when the key is absent, -1 when the value is not an array
 * of at most cap finite numbers. */
static int json_array(const char *json, const char *key, double *out,
                      size_t cap, size_t *n)
{
    const char *p = json_value(json, key);
    *n = 0;
    if (!p)
        return 0;
    if (*p != '[')
        return -1;
    p++;
    for (;;) {
        while (isspace((unsigned char)*p) || *p == ',')
            p++;
        if (*p == ']')
            return 1;
        char *end;
        errno = 0;
        double v = strtod(p, &end);
        if (end == p || errno || !isfinite(v) || *n >= cap)
            return -1;
        out[(*n)++] = v;
        p = end;
    }
}

/* Reads the number value of "key" in json into out.  Returns 1 when read,
 * 0 when the key is absent, -1 when the value is not a finite number. */
static int json_number(const char *json, const char *key, double *out)
{
    const char *p = json_value(json, key);
    if (!p)
        return 0;
    char *end;
    errno = 0;
    double v = strtod(p, &end);
    if (end == p || errno || !isfinite(v))
        return -1;
    *out = v;
    return 1;
}

/* The preset's optional NaN colour: NanColor [r, g, b] and NanOpacity,
 * each in [0, 1]; the opacity is 1 when only the colour is given (as
 * vtkDiscretizableColorTransferFunction's NanOpacity defaults to 1).
 * Absent: tf->nan_rgba stays as it is (transparent). */
static int parse_paraview_nan(const char *json, struct tvpal_tf *tf,
                              struct tvpal_diag *diag)
{
    double rgb[3], op = 1.0;
    size_t n;
    int rc = json_array(json, "NanColor", rgb, 3, &n);
    if (rc < 0 || (rc > 0 && n != 3))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "NanColor: malformed; expected [r, g, b], 3 "
                              "numbers in 0..1");
    for (size_t i = 0; rc > 0 && i < 3; i++)
        if (!(rgb[i] >= 0 && rgb[i] <= 1))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "NanColor: %c = %g; expected [r, g, b], 3 "
                                  "numbers in 0..1", "rgb"[i], rgb[i]);
    int ro = json_number(json, "NanOpacity", &op);
    if (ro < 0)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "NanOpacity: malformed; "
                              "expected a number in 0..1");
    if (!(op >= 0 && op <= 1))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "NanOpacity: %g; "
                              "expected a number in 0..1", op);
    if (rc > 0)
        for (int i = 0; i < 3; i++)
            tf->nan_rgba[i] = (float)rgb[i];
    if (rc > 0 || ro > 0)
        tf->nan_rgba[3] = (float)op;
    return 0;
}

int tvpal_tf_parse_paraview(const char *json, double vmin, double vmax,
                            struct tvpal_tf *tf, struct tvpal_diag *diag)
{
    static double rgb[4 * TVPAL_TF_MAX_POINTS], op[4 * TVPAL_TF_MAX_POINTS];
    size_t nrgb, nop;
    memset(tf, 0, sizeof *tf);
    snprintf(tf->name, sizeof tf->name, "paraview");
    const char *nm = strstr(json, "\"Name\"");
    if (nm && (nm = strchr(nm + 6, '"'))) {
        const char *q = strchr(nm + 1, '"');
        if (q)
            snprintf(tf->name, sizeof tf->name, "%.*s",
                     (int)(q - nm - 1 < 63 ? q - nm - 1 : 63), nm + 1);
    }
    int r = json_array(json, "RGBPoints", rgb, sizeof rgb / sizeof *rgb, &nrgb);
    if (r <= 0 || nrgb < 4 || nrgb % 4)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "RGBPoints: %s; expected [x, r, g, b, ...] "
                              "with at least one point",
                              r == 0 ? "missing" : "malformed or too long");
    int ro = json_array(json, "Points", op, sizeof op / sizeof *op, &nop);
    if (ro < 0 || (ro > 0 && (nop < 4 || nop % 4)))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "Points: malformed; expected [x, opacity, "
                              "midpoint, sharpness, ...]");
    /* Rescale the preset's x domain onto [vmin, vmax]. */
    double x0 = rgb[0], x1 = rgb[nrgb - 4];
    for (size_t i = 4; i < nrgb; i += 4)
        if (rgb[i] < rgb[i - 4])
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "RGBPoints: x values must not decrease "
                                  "(point %zu)", i / 4);
    double span = x1 > x0 ? x1 - x0 : 1.0;
    for (size_t i = 0; i < nrgb; i += 4) {
        double x = rgb[i];
        float c[4] = {(float)rgb[i + 1], (float)rgb[i + 2], (float)rgb[i + 3],
                      1.0f};
        if (nop) {
            /* Opacity from the Points curve (linear; midpoint and
             * sharpness are not modelled), over the same preset domain. */
            double t = x, o = op[1];
            for (size_t k = 0; k + 4 < nop; k += 4)
                if (t >= op[k] && t <= op[k + 4]) {
                    double f = op[k + 4] > op[k] ? (t - op[k]) / (op[k + 4] - op[k]) : 0;
                    o = op[k + 1] + f * (op[k + 5] - op[k + 1]);
                    break;
                } else if (t > op[k + 4]) {
                    o = op[k + 5];
                }
            c[3] = (float)o;
        } else {
            c[3] = (float)((x - x0) / span); /* ramp: ParaView's default */
        }
        for (int k = 0; k < 4; k++)
            c[k] = c[k] < 0 ? 0 : c[k] > 1 ? 1 : c[k];
        int rc = add_point(tf, vmin + (x - x0) / span * (vmax - vmin), c,
                           (unsigned)(i / 4 + 1), diag);
        if (rc < 0)
            return rc;
    }
    return parse_paraview_nan(json, tf, diag);
}

int tvpal_tf_load(const char *path, double vmin, double vmax,
                  struct tvpal_tf *tf, struct tvpal_diag *diag)
{
    char *text = NULL;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_read_file(path, &text, NULL, &d);
    if (rc < 0) { /* d says "PATH: cause"; the caller names the file */
        const char *cause = strrchr(d.msg, ':');
        return tvpal_diag_set(diag, rc, "cannot read: %s",
                              cause ? cause + 2 : tvpal_strerror(rc));
    }
    const char *p = text;
    while (isspace((unsigned char)*p))
        p++;
    if (*p == '[' || *p == '{')
        rc = tvpal_tf_parse_paraview(text, vmin, vmax, tf, diag);
    else
        rc = tvpal_tf_parse_text(text, vmin, vmax, tf, diag);
    free(text);
    return rc;
}

void tvpal_tf_default(double vmin, double vmax, const uint64_t *hist,
                      unsigned nbins, struct tvpal_tf *tf)
{
    memset(tf, 0, sizeof *tf);
    snprintf(tf->name, sizeof tf->name, "default");
    if (!(vmax > vmin) || !nbins) {
        float c[4] = {1, 1, 1, 0.5f};
        add_point(tf, vmin, c, 0, NULL);
        return;
    }
    uint64_t total = 0, peak = 0;
    unsigned peak_bin = 0;
    for (unsigned i = 0; i < nbins; i++) {
        total += hist[i];
        if (hist[i] > peak) {
            peak = hist[i];
            peak_bin = i;
        }
    }
    /* One point per bin centre: opacity grows as the bin gets rarer
     * (-log of its share, normalized), zero for the background bin. */
    if (nbins > TVPAL_TF_MAX_POINTS)
        nbins = TVPAL_TF_MAX_POINTS;
    for (unsigned i = 0; i < nbins; i++) {
        double share = total ? (double)hist[i] / (double)total : 0.0;
        double rar = share > 0 ? -log(share) / log((double)total + 1.0) : 1.0;
        double x = (i + 0.5) / nbins;
        float c[4];
        c[0] = (float)(x < 0.5 ? 0.2 + 1.6 * x : 1.0);
        c[1] = (float)(x < 0.5 ? 0.3 + 1.4 * x : 2.0 * (1.0 - x));
        c[2] = (float)(x < 0.5 ? 1.0 : 2.0 * (1.0 - x) + 0.2);
        c[3] = (i == peak_bin) ? 0.0f : (float)(0.05 + 0.6 * rar * rar);
        for (int k = 0; k < 4; k++)
            c[k] = c[k] < 0 ? 0 : c[k] > 1 ? 1 : c[k];
        add_point(tf, vmin + x * (vmax - vmin), c, 0, NULL);
    }
}

void tvpal_tf_eval(const struct tvpal_tf *tf, double v, float rgba[4])
{
    const unsigned n = tf->npoints;
    if (v <= tf->value[0] || n == 1) {
        memcpy(rgba, tf->rgba[0], sizeof(float) * 4);
        return;
    }
    if (v >= tf->value[n - 1]) {
        memcpy(rgba, tf->rgba[n - 1], sizeof(float) * 4);
        return;
    }
    unsigned lo = 0, hi = n - 1; /* value[lo] <= v < value[hi] */
    while (hi - lo > 1) {
        unsigned mid = (lo + hi) / 2;
        if (tf->value[mid] <= v)
            lo = mid;
        else
            hi = mid;
    }
    double span = tf->value[hi] - tf->value[lo];
    float f = span > 0 ? (float)((v - tf->value[lo]) / span) : 1.0f;
    for (int k = 0; k < 4; k++)
        rgba[k] = tf->rgba[lo][k] + f * (tf->rgba[hi][k] - tf->rgba[lo][k]);
}
