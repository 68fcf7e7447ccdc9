/* tvpal_tf.c: transfer functions (see tvpal_tf.h). */
#include "tvpal_tf.h"
#include "tvpal_fs.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* ------------------------------------------------------- colour spaces
 *
 * The conversions and the diverging interpolation follow VTK:
 * vtkMath.cxx (RGBToXYZ, XYZToLab, LabToXYZ, XYZToRGB with its clipping,
 * RGBToHSV, HSVToRGB) and vtkColorTransferFunction.cxx (GetTable's linear
 * case for each ColorSpace, vtkColorTransferFunctionInterpolateDiverging,
 * ...AdjustHue, ...AngleDiff), which implement Moreland, "Diverging Color
 * Maps for Scientific Visualization" (ISVC 2009).  Same constants (sRGB
 * matrix to 4 digits, D65 white 0.9505 1 1.089), so colours match
 * ParaView's. */

#define TF_PI 3.14159265358979323846

static double srgb_to_linear(double c)
{
    return c > 0.04045 ? pow((c + 0.055) / 1.055, 2.4) : c / 12.92;
}

static double linear_to_srgb(double c)
{
    return c > 0.0031308 ? 1.055 * pow(c, 1 / 2.4) - 0.055 : 12.92 * c;
}

static double lab_f(double t)
{
    return t > 0.008856 ? cbrt(t) : 7.787 * t + 16.0 / 116.0;
}

static double lab_finv(double t)
{
    double t3 = t * t * t;
    return t3 > 0.008856 ? t3 : (t - 16.0 / 116.0) / 7.787;
}

static void rgb_to_lab(const double rgb[3], double lab[3])
{
    double r = srgb_to_linear(rgb[0]), g = srgb_to_linear(rgb[1]),
           b = srgb_to_linear(rgb[2]);
    double x = lab_f((r * 0.4124 + g * 0.3576 + b * 0.1805) / 0.9505);
    double y = lab_f(r * 0.2126 + g * 0.7152 + b * 0.0722);
    double z = lab_f((r * 0.0193 + g * 0.1192 + b * 0.9505) / 1.089);
    lab[0] = 116 * y - 16;
    lab[1] = 500 * (x - y);
    lab[2] = 200 * (y - z);
}

/* Out-of-gamut results are clipped as VTK does: scaled down by the
 * largest component above 1, negatives to 0. */
static void lab_to_rgb(const double lab[3], double rgb[3])
{
    double fy = (lab[0] + 16) / 116;
    double x = 0.9505 * lab_finv(lab[1] / 500 + fy);
    double y = lab_finv(fy);
    double z = 1.089 * lab_finv(fy - lab[2] / 200);
    rgb[0] = linear_to_srgb(x * 3.2406 + y * -1.5372 + z * -0.4986);
    rgb[1] = linear_to_srgb(x * -0.9689 + y * 1.8758 + z * 0.0415);
    rgb[2] = linear_to_srgb(x * 0.0557 + y * -0.2040 + z * 1.0570);
    double m = fmax(rgb[0], fmax(rgb[1], rgb[2]));
    for (int k = 0; k < 3; k++)
        rgb[k] = fmax(m > 1 ? rgb[k] / m : rgb[k], 0.0);
}

/* Hue, saturation, value, each 0..1 (hue 0 red). */
static void rgb_to_hsv(const double rgb[3], double hsv[3])
{
    double mx = fmax(rgb[0], fmax(rgb[1], rgb[2]));
    double mn = fmin(rgb[0], fmin(rgb[1], rgb[2]));
    double h = 0, s = mx > 0 ? (mx - mn) / mx : 0;
    if (s > 0) {
        if (rgb[0] == mx)
            h = (rgb[1] - rgb[2]) / (mx - mn) / 6;
        else if (rgb[1] == mx)
            h = 1.0 / 3 + (rgb[2] - rgb[0]) / (mx - mn) / 6;
        else
            h = 2.0 / 3 + (rgb[0] - rgb[1]) / (mx - mn) / 6;
        if (h < 0)
            h += 1;
    }
    hsv[0] = h;
    hsv[1] = s;
    hsv[2] = mx;
}

static void hsv_to_rgb(const double hsv[3], double rgb[3])
{
    const double h = hsv[0], s = hsv[1], v = hsv[2];
    double r, g, b;
    if (h > 1.0 / 6 && h <= 1.0 / 3) {
        r = (1.0 / 3 - h) * 6, g = 1, b = 0;
    } else if (h > 1.0 / 3 && h <= 0.5) {
        r = 0, g = 1, b = (h - 1.0 / 3) * 6;
    } else if (h > 0.5 && h <= 2.0 / 3) {
        r = 0, g = (2.0 / 3 - h) * 6, b = 1;
    } else if (h > 2.0 / 3 && h <= 5.0 / 6) {
        r = (h - 2.0 / 3) * 6, g = 0, b = 1;
    } else if (h > 5.0 / 6 && h <= 1) {
        r = 1, g = 0, b = (1 - h) * 6;
    } else {
        r = 1, g = h * 6, b = 0;
    }
    rgb[0] = (s * r + 1 - s) * v;
    rgb[1] = (s * g + 1 - s) * v;
    rgb[2] = (s * b + 1 - s) * v;
}

/* Msh: the polar form of Lab (magnitude, saturation angle, hue angle). */
static void lab_to_msh(const double lab[3], double msh[3])
{
    msh[0] = sqrt(lab[0] * lab[0] + lab[1] * lab[1] + lab[2] * lab[2]);
    msh[1] = msh[0] > 0.001 ? acos(lab[0] / msh[0]) : 0;
    msh[2] = msh[1] > 0.001 ? atan2(lab[2], lab[1]) : 0;
}

static void msh_to_lab(const double msh[3], double lab[3])
{
    lab[0] = msh[0] * cos(msh[1]);
    lab[1] = msh[0] * sin(msh[1]) * cos(msh[2]);
    lab[2] = msh[0] * sin(msh[1]) * sin(msh[2]);
}

/* The smaller angle between two hues. */
static double angle_diff(double a1, double a2)
{
    double d = fabs(a1 - a2);
    while (d >= 2 * TF_PI)
        d -= 2 * TF_PI;
    return d > TF_PI ? 2 * TF_PI - d : d;
}

/* A hue for an unsaturated end of magnitude unsat_m next to the saturated
 * colour msh: spun so that the perceived change stays about constant
 * (Moreland 2009, section 5), away from 0 except for purples. */
static double adjust_hue(const double msh[3], double unsat_m)
{
    if (msh[0] >= unsat_m - 0.1)
        return msh[2];
    double spin = msh[1] * sqrt(unsat_m * unsat_m - msh[0] * msh[0]) /
                  (msh[0] * sin(msh[1]));
    return msh[2] > -0.3 * TF_PI ? msh[2] + spin : msh[2] - spin;
}

/* Interval ends a, b (Msh): the hue of an unsaturated end is adjusted. */
static void diverging_pair(const double a[3], const double b[3], double out[2][3])
{
    memcpy(out[0], a, sizeof out[0]);
    memcpy(out[1], b, sizeof out[1]);
    if (a[1] < 0.05 && b[1] > 0.05)
        out[0][2] = adjust_hue(b, a[0]);
    else if (b[1] < 0.05 && a[1] > 0.05)
        out[1][2] = adjust_hue(a, b[0]);
}

/* seg[0..3] and split of one diverging interval from its RGB ends.  Two
 * distinct saturated ends get white (magnitude at least 88) in between:
 * the first half runs to it, the second from it. */
static int diverging_interval(const double rgb1[3], const double rgb2[3],
                              double seg[4][3])
{
    double lab[3], m1[3], m2[3];
    rgb_to_lab(rgb1, lab);
    lab_to_msh(lab, m1);
    rgb_to_lab(rgb2, lab);
    lab_to_msh(lab, m2);
    if (m1[1] > 0.05 && m2[1] > 0.05 && angle_diff(m1[2], m2[2]) > 0.33 * TF_PI) {
        double white[3] = {fmax(88.0, fmax(m1[0], m2[0])), 0, 0};
        diverging_pair(m1, white, seg);
        diverging_pair(white, m2, seg + 2);
        return 1;
    }
    diverging_pair(m1, m2, seg);
    return 0;
}

/* The colour at fraction s of interval i in tf's space (not RGB). */
static void space_color(const struct tvpal_tf *tf, unsigned i, double s,
                        double rgb[3])
{
    const double (*e)[3] = tf->seg[i];
    if (tf->space == TVPAL_TF_DIVERGING && tf->split[i]) {
        if (s < 0.5) {
            s = 2 * s;
        } else {
            e += 2;
            s = 2 * s - 1;
        }
    }
    double c[3];
    for (int k = 0; k < 3; k++)
        c[k] = (1 - s) * e[0][k] + s * e[1][k];
    switch (tf->space) {
    case TVPAL_TF_HSV:
    case TVPAL_TF_HSV_WRAP:
        if (c[0] < 0)
            c[0] += 1;
        hsv_to_rgb(c, rgb);
        break;
    case TVPAL_TF_LAB:
        lab_to_rgb(c, rgb);
        break;
    case TVPAL_TF_DIVERGING: {
        double lab[3];
        msh_to_lab(c, lab);
        lab_to_rgb(lab, rgb);
        break;
    }
    default: /* step */
        for (int k = 0; k < 3; k++)
            rgb[k] = tf->rgba[i][k];
    }
}

/* seg[i] for one interval of an HSV, Lab or diverging TF. */
static void prepare_interval(struct tvpal_tf *tf, unsigned i)
{
    double a[3], b[3];
    for (int k = 0; k < 3; k++) {
        a[k] = tf->rgba[i][k];
        b[k] = tf->rgba[i + 1][k];
    }
    double (*e)[3] = tf->seg[i];
    tf->split[i] = 0;
    switch (tf->space) {
    case TVPAL_TF_HSV:
    case TVPAL_TF_HSV_WRAP:
        rgb_to_hsv(a, e[0]);
        rgb_to_hsv(b, e[1]);
        /* HSVWrap: the hue goes the shorter way, below 0 if need be. */
        if (tf->space == TVPAL_TF_HSV_WRAP && fabs(e[0][0] - e[1][0]) > 0.5)
            e[e[0][0] > e[1][0] ? 0 : 1][0] -= 1;
        break;
    case TVPAL_TF_LAB:
        rgb_to_lab(a, e[0]);
        rgb_to_lab(b, e[1]);
        break;
    case TVPAL_TF_DIVERGING:
        tf->split[i] = (unsigned char)diverging_interval(a, b, e);
        break;
    }
}

static void tab_color(const struct tvpal_tf *tf, unsigned i, double s,
                      float rgb[3]);

/* Whether the table stays within TAB_TOL of the exact colours at the
 * middle of every cell (where linear interpolation errs most): a TF whose
 * colours turn sharply within a cell (random neighbours, gamut clipping)
 * keeps the exact conversion. */
#define TAB_TOL (1.0 / 2048)   /* an eighth of an 8-bit level */
static int table_holds(const struct tvpal_tf *tf)
{
    const unsigned cells = tf->tab_cells;
    for (unsigned i = 0; i + 1 < tf->npoints; i++)
        for (unsigned j = 0; j < cells; j++) {
            const double s = (j + 0.5) / cells;
            double exact[3];
            float t[3];
            space_color(tf, i, s, exact);
            tab_color(tf, i, s, t);
            for (int c = 0; c < 3; c++) {
                double e = exact[c] < 0 ? 0 : exact[c] > 1 ? 1 : exact[c];
                if (fabs(t[c] - e) > TAB_TOL)
                    return 0;
            }
        }
    return 1;
}

/* tf->tab for a Lab or diverging TF of two or more points (see
 * tvpal_tf.h) when it holds, else tab_cells 0. */
static void tabulate(struct tvpal_tf *tf)
{
    tf->tab_cells = 0;
    if ((tf->space != TVPAL_TF_LAB && tf->space != TVPAL_TF_DIVERGING) ||
        tf->npoints < 2)
        return;
    unsigned cells = (TVPAL_TF_TAB_CELLS / (tf->npoints - 1)) & ~1u;
    cells = cells < 16 ? 16 : cells;
    for (unsigned i = 0; i + 1 < tf->npoints; i++)
        for (unsigned j = 0; j <= cells; j++) {
            double rgb[3];
            space_color(tf, i, (double)j / cells, rgb);
            float *e = tf->tab[i * (cells + 1) + j];
            for (int c = 0; c < 3; c++)
                e[c] = (float)(rgb[c] < 0 ? 0 : rgb[c] > 1 ? 1 : rgb[c]);
        }
    tf->tab_cells = cells;
    if (!table_holds(tf))
        tf->tab_cells = 0;
}

/* Colour at s (0..1) of interval i from the table. */
static void tab_color(const struct tvpal_tf *tf, unsigned i, double s,
                      float rgb[3])
{
    const unsigned cells = tf->tab_cells;
    const double x = s * cells;
    unsigned j = (unsigned)x;
    j = j >= cells ? cells - 1 : j;
    const float t = (float)(x - j);
    const float *a = tf->tab[i * (cells + 1) + j], *b = a + 3;
    for (int c = 0; c < 3; c++)
        rgb[c] = a[c] + t * (b[c] - a[c]);
}

static const char *const space_names[] = {"RGB", "HSV", "Wrapped HSV", "Lab",
                                          "Diverging", "Step"};

const char *tvpal_tf_space_name(int space)
{
    return space >= 0 && space <= TVPAL_TF_STEP ? space_names[space] : "?";
}

int tvpal_tf_prepare(struct tvpal_tf *tf, struct tvpal_diag *diag)
{
    if (tf->space < TVPAL_TF_RGB || tf->space > TVPAL_TF_STEP)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "colour space %d: "
                              "expected 0..%d", tf->space, TVPAL_TF_STEP);
    for (unsigned i = 0; i < tf->npoints; i++) {
        if (tf->log_scale && !(tf->value[i] > 0))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "point %u: value %g with a log scale; "
                                  "expected values > 0", i + 1, tf->value[i]);
        tf->key[i] = tf->log_scale ? log10(tf->value[i]) : tf->value[i];
    }
    for (unsigned i = 0; i < tf->nop; i++) {
        if (tf->log_scale && !(tf->op_value[i] > 0))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "opacity point %u: value %g with a log "
                                  "scale; expected values > 0", i + 1,
                                  tf->op_value[i]);
        tf->op_key[i] = tf->log_scale ? log10(tf->op_value[i]) : tf->op_value[i];
    }
    for (unsigned i = 0; i + 1 < tf->npoints && tf->space != TVPAL_TF_RGB; i++)
        prepare_interval(tf, i);
    tabulate(tf);
    return 0;
}

double tvpal_tf_domain_value(const struct tvpal_tf *tf, double f)
{
    const double a = tf->value[0], b = tf->value[tf->npoints - 1];
    if (tf->log_scale && a > 0 && b > 0)
        return pow(10.0, log10(a) + f * (log10(b) - log10(a)));
    return a + f * (b - a);
}

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

/* Reads "[value] r g b a" from the numbers at num of line s (the value
 * into *v when v is not NULL), r, g, b, a each in [0, 1]; `form` is the
 * expected line and `what` prefixes a component's name in messages. */
static int scan_rgba(const char *s, const char *num, double *v, float c[4],
                     const char *form, const char *what, unsigned line,
                     struct tvpal_diag *diag)
{
    char extra;
    int k = v ? sscanf(num, "%lf %f %f %f %f %c", v, &c[0], &c[1], &c[2],
                       &c[3], &extra)
              : sscanf(num, "%f %f %f %f %c", &c[0], &c[1], &c[2], &c[3],
                       &extra);
    if (k != (v ? 5 : 4))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "line %u: expected %s, "
                              "got \"%s\"", line, form, s);
    return check_unit_rgba(c, what, line, diag);
}

/* The text format's "nan r g b a" line s (after the keyword check). */
static int parse_nan_line(const char *s, unsigned line, struct tvpal_tf *tf,
                          struct tvpal_diag *diag)
{
    float c[4];
    const char *num = s + strcspn(s, " \t");
    int rc = scan_rgba(s, num, NULL, c, "\"nan r g b a\" (4 numbers 0..1)",
                       "nan ", line, diag);
    if (rc < 0)
        return rc;
    memcpy(tf->nan_rgba, c, sizeof c);
    return 0;
}

/* A colour space by name, case-insensitive: ParaView's ColorSpace names
 * and the text format's ("wrapped-hsv"); -1 when unknown. */
static int space_from_name(const char *name)
{
    static const struct { const char *name; int space; } names[] = {
        {"rgb", TVPAL_TF_RGB}, {"hsv", TVPAL_TF_HSV},
        {"wrapped hsv", TVPAL_TF_HSV_WRAP}, {"wrapped-hsv", TVPAL_TF_HSV_WRAP},
        {"lab", TVPAL_TF_LAB}, {"cielab", TVPAL_TF_LAB},
        {"diverging", TVPAL_TF_DIVERGING}, {"step", TVPAL_TF_STEP}};
    for (size_t i = 0; i < sizeof names / sizeof *names; i++)
        if (!strcasecmp(name, names[i].name))
            return names[i].space;
    return -1;
}

/* Maps normalized point values (fractions of [vmin, vmax]) onto the range:
 * linearly, or with a log scale geometrically (vmin^(1-v) vmax^v), as a
 * preset's domain is rescaled. */
static int place_normalized(struct tvpal_tf *tf, double vmin, double vmax,
                            struct tvpal_diag *diag)
{
    if (isnan(vmin) || isnan(vmax))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "domain normalized: no "
                              "value range to map onto (the file's own "
                              "values are kept: use \"domain data\")");
    if (tf->log_scale && !(vmin > 0 && vmax > 0))
        return tvpal_diag_set(diag, TVPAL_E_RANGE, "scale log: the value "
                              "range %g..%g includes values <= 0; a log "
                              "scale needs a range above 0", vmin, vmax);
    for (unsigned i = 0; i < tf->npoints; i++) {
        const double v = tf->value[i];
        tf->value[i] = tf->log_scale
            ? pow(10.0, log10(vmin) + v * (log10(vmax) - log10(vmin)))
            : vmin + v * (vmax - vmin);
    }
    return 0;
}

/* The text format's keyword lines: domain, name, nan, scale, colorspace.
 * Returns 1 when s was one (applied), 0 when it is not, or an error. */
static int parse_keyword(const char *word, const char *s, unsigned line,
                         struct tvpal_tf *tf, int *normalized,
                         struct tvpal_diag *diag)
{
    char arg[64] = "";
    sscanf(s, "%*s %63[^\n]", arg);
    for (size_t n = strlen(arg); n && isspace((unsigned char)arg[n - 1]);)
        arg[--n] = 0;
    if (!strcmp(word, "domain")) {
        if (strcmp(arg, "normalized") && strcmp(arg, "data"))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "line %u: domain "
                                  "\"%s\": expected normalized or data", line,
                                  arg);
        *normalized = !strcmp(arg, "normalized");
    } else if (!strcmp(word, "name")) {
        char nm[64] = "";
        sscanf(s, "%*s %63s", nm);
        snprintf(tf->name, sizeof tf->name, "%s", nm);
    } else if (!strcmp(word, "nan")) {
        int rc = parse_nan_line(s, line, tf, diag);
        return rc < 0 ? rc : 1;
    } else if (!strcmp(word, "scale")) {
        if (strcmp(arg, "linear") && strcmp(arg, "log"))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "line %u: scale "
                                  "\"%s\": expected linear or log", line, arg);
        tf->log_scale = !strcmp(arg, "log");
    } else if (!strcmp(word, "colorspace")) {
        if ((tf->space = space_from_name(arg)) < 0)
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "line %u: colorspace "
                                  "\"%s\": expected rgb, hsv, wrapped-hsv, "
                                  "lab, diverging or step", line, arg);
    } else {
        return 0;
    }
    return 1;
}

/* One "value r g b a" line s; the value is kept as written (normalized
 * values are placed once the whole file is read). */
static int parse_point(const char *s, unsigned line, struct tvpal_tf *tf,
                       struct tvpal_diag *diag)
{
    double v;
    float c[4];
    int rc = scan_rgba(s, s, &v, c, "5 numbers \"value r g b a\"", "", line,
                       diag);
    if (rc < 0)
        return rc;
    if (!isfinite(v))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "line %u: value is not finite", line);
    return add_point(tf, v, c, line, diag);
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
        char word[32];
        if (!*s || sscanf(s, "%31s", word) != 1)
            continue;
        int rc = parse_keyword(word, s, line, tf, &normalized, diag);
        if (rc > 0)
            continue;
        if (rc == 0 && normalized < 0)
            rc = tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                "line %u: expected \"domain normalized\" or "
                                "\"domain data\" before the points", line);
        if (rc == 0)
            rc = parse_point(s, line, tf, diag);
        if (rc < 0)
            return rc;
    }
    if (!tf->npoints)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                              "no points (expected lines \"value r g b a\")");
    int rc = normalized ? place_normalized(tf, vmin, vmax, diag) : 0;
    return rc < 0 ? rc : tvpal_tf_prepare(tf, diag);
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

/* Reads the string value of "key" in json into out (cap bytes).  Returns
 * 1 when read, 0 when the key is absent, -1 when the value is not a string
 * that fits. */
static int json_string(const char *json, const char *key, char *out,
                       size_t cap)
{
    const char *p = json_value(json, key);
    if (!p)
        return 0;
    const char *q = *p == '"' ? strchr(p + 1, '"') : NULL;
    if (!q || (size_t)(q - p - 1) >= cap)
        return -1;
    memcpy(out, p + 1, (size_t)(q - p - 1));
    out[q - p - 1] = 0;
    return 1;
}

/* The preset's ColorSpace and UseLogScale (1, 0, true or false). */
static int parse_paraview_scale(const char *json, struct tvpal_tf *tf,
                                struct tvpal_diag *diag)
{
    char name[32];
    int r = json_string(json, "ColorSpace", name, sizeof name);
    if (r < 0 || (r > 0 && (tf->space = space_from_name(name)) < 0))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "ColorSpace \"%s\": "
                              "expected \"RGB\", \"HSV\", \"Wrapped HSV\", "
                              "\"Lab\", \"CIELAB\", \"Diverging\" or "
                              "\"Step\"", r < 0 ? "(not a string)" : name);
    const char *p = json_value(json, "UseLogScale");
    double v = 0;
    if (p && !strncmp(p, "true", 4))
        v = 1;
    else if (p && strncmp(p, "false", 5) && json_number(json, "UseLogScale", &v) < 0)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "UseLogScale: malformed; "
                              "expected 0, 1, true or false");
    tf->log_scale = v != 0;
    return 0;
}

/* Where x lies on the TF's axis: x itself, or log10(x) with a log scale. */
static double axis_key(const struct tvpal_tf *tf, double x)
{
    return tf->log_scale ? log10(x) : x;
}

/* Checks what a log scale needs of the preset: x values (RGBPoints and
 * opacity Points) above 0 and, unless the values are kept, a target range
 * above 0. */
static int check_log_preset(const struct tvpal_tf *tf, const double *rgb,
                            size_t nrgb, const double *op, size_t nop,
                            double vmin, double vmax, struct tvpal_diag *diag)
{
    if (!tf->log_scale)
        return 0;
    for (size_t i = 0; i < nrgb; i += 4)
        if (!(rgb[i] > 0))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "UseLogScale: "
                                  "RGBPoints x = %g (point %zu); a log scale "
                                  "needs values > 0", rgb[i], i / 4 + 1);
    for (size_t i = 0; i < nop; i += 4)
        if (!(op[i] > 0))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "UseLogScale: Points "
                                  "x = %g (point %zu); a log scale needs "
                                  "values > 0", op[i], i / 4 + 1);
    if (!isnan(vmin) && !(vmin > 0 && vmax > 0))
        return tvpal_diag_set(diag, TVPAL_E_RANGE, "UseLogScale: the value "
                              "range %g..%g to rescale onto includes values "
                              "<= 0; a log scale needs a range above 0",
                              vmin, vmax);
    return 0;
}

/* Opacity at preset x t from the Points curve (linear in the axis key;
 * midpoint and sharpness are not modelled). */
static double preset_opacity(const struct tvpal_tf *tf, const double *op,
                             size_t nop, double t)
{
    double o = op[1];
    const double kt = axis_key(tf, t);
    for (size_t k = 0; k + 4 < nop; k += 4)
        if (t >= op[k] && t <= op[k + 4]) {
            double k0 = axis_key(tf, op[k]), k1 = axis_key(tf, op[k + 4]);
            double f = k1 > k0 ? (kt - k0) / (k1 - k0) : 0;
            return op[k + 1] + f * (op[k + 5] - op[k + 1]);
        } else if (t > op[k + 4]) {
            o = op[k + 5];
        }
    return o;
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
    for (size_t i = 4; i < nrgb; i += 4)
        if (rgb[i] < rgb[i - 4])
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "RGBPoints: x values must not decrease "
                                  "(point %zu)", i / 4);
    for (size_t i = 4; i < nop; i += 4)
        if (op[i] < op[i - 4])
            return tvpal_diag_set(diag, TVPAL_E_FORMAT,
                                  "Points: x values must not decrease "
                                  "(point %zu)", i / 4);
    int rc = parse_paraview_scale(json, tf, diag);
    if (rc == 0)
        rc = check_log_preset(tf, rgb, nrgb, op, nop, vmin, vmax, diag);
    if (rc < 0)
        return rc;
    /* Rescale the preset's x domain onto [vmin, vmax] along the axis
     * (ParaView's RescaleTransferFunction), unless its values are kept. */
    const int keep = isnan(vmin) || isnan(vmax);
    const double k0 = axis_key(tf, rgb[0]), k1 = axis_key(tf, rgb[nrgb - 4]);
    const double lo = keep ? 0 : axis_key(tf, vmin);
    const double hi = keep ? 0 : axis_key(tf, vmax);
    double span = k1 > k0 ? k1 - k0 : 1.0;
    /* The opacity curve, placed as the colour points are. */
    for (size_t i = 0; i < nop; i += 4, tf->nop++) {
        double v = lo + (axis_key(tf, op[i]) - k0) / span * (hi - lo);
        tf->op_value[tf->nop] = keep ? op[i] : tf->log_scale ? pow(10.0, v) : v;
        tf->op_a[tf->nop] = (float)(op[i + 1] < 0 ? 0 : op[i + 1] > 1 ? 1
                                                                : op[i + 1]);
    }
    for (size_t i = 0; i < nrgb; i += 4) {
        double x = rgb[i], k = axis_key(tf, x);
        float c[4] = {(float)rgb[i + 1], (float)rgb[i + 2], (float)rgb[i + 3],
                      1.0f};
        /* Opacity from the Points curve, over the same preset domain;
         * without it a ramp, ParaView's default. */
        c[3] = (float)(nop ? preset_opacity(tf, op, nop, x) : (k - k0) / span);
        for (int j = 0; j < 4; j++)
            c[j] = c[j] < 0 ? 0 : c[j] > 1 ? 1 : c[j];
        double v = lo + (k - k0) / span * (hi - lo);
        if (tf->log_scale)
            v = pow(10.0, v);
        rc = add_point(tf, keep ? x : v, c, (unsigned)(i / 4 + 1), diag);
        if (rc < 0)
            return rc;
    }
    rc = parse_paraview_nan(json, tf, diag);
    return rc < 0 ? rc : tvpal_tf_prepare(tf, diag);
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
        tvpal_tf_prepare(tf, NULL);
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
    tvpal_tf_prepare(tf, NULL); /* linear RGB: cannot fail */
}

/* Interval lo..lo+1 of keys holding k (key[0] < k < key[n-1]). */
static unsigned find_interval(const double *key, unsigned n, double k)
{
    unsigned lo = 0, hi = n - 1; /* key[lo] <= k < key[hi] */
    while (hi - lo > 1) {
        unsigned mid = (lo + hi) / 2;
        if (key[mid] <= k)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

/* Opacity at axis position k from the opacity curve (tf->nop > 0). */
static float curve_opacity(const struct tvpal_tf *tf, double k)
{
    const unsigned n = tf->nop;
    if (k <= tf->op_key[0] || n == 1)
        return tf->op_a[0];
    if (k >= tf->op_key[n - 1])
        return tf->op_a[n - 1];
    const unsigned lo = find_interval(tf->op_key, n, k);
    const double span = tf->op_key[lo + 1] - tf->op_key[lo];
    const float f = span > 0 ? (float)((k - tf->op_key[lo]) / span) : 1.0f;
    return tf->op_a[lo] + f * (tf->op_a[lo + 1] - tf->op_a[lo]);
}

/* Colour and (the points') opacity at axis position k: below the first
 * point its, above the last its, between two interpolated in the space. */
static void points_rgba(const struct tvpal_tf *tf, const double *key,
                        double k, float rgba[4])
{
    const unsigned n = tf->npoints;
    if (k <= key[0] || n == 1) {
        memcpy(rgba, tf->rgba[0], sizeof(float) * 4);
        return;
    }
    if (k >= key[n - 1]) {
        memcpy(rgba, tf->rgba[n - 1], sizeof(float) * 4);
        return;
    }
    const unsigned lo = find_interval(key, n, k), hi = lo + 1;
    double span = key[hi] - key[lo];
    float f = span > 0 ? (float)((k - key[lo]) / span) : 1.0f;
    int ncol = 4;
    if (tf->tab_cells) {
        tab_color(tf, lo, span > 0 ? (k - key[lo]) / span : 1.0, rgba);
        ncol = 1; /* opacity only, below */
    } else if (tf->space != TVPAL_TF_RGB) {
        double rgb[3];
        space_color(tf, lo, span > 0 ? (k - key[lo]) / span : 1.0, rgb);
        for (int c = 0; c < 3; c++)
            rgba[c] = (float)(rgb[c] < 0 ? 0 : rgb[c] > 1 ? 1 : rgb[c]);
        ncol = 1; /* opacity only, below */
    }
    for (int c = 4 - ncol; c < 4; c++)
        rgba[c] = tf->rgba[lo][c] + f * (tf->rgba[hi][c] - tf->rgba[lo][c]);
}

void tvpal_tf_eval(const struct tvpal_tf *tf, double v, float rgba[4])
{
    /* Linear RGB reads the values themselves: the same arithmetic as
     * before key existed (frames stay byte-identical). */
    const double *key = tf->log_scale || tf->space ? tf->key : tf->value;
    double k = v;
    if (tf->log_scale)
        k = v > 0 ? log10(v) : -HUGE_VAL; /* <= 0: below every point */
    points_rgba(tf, key, k, rgba);
    if (tf->nop)
        rgba[3] = curve_opacity(tf, tf->log_scale ? k : v);
}
