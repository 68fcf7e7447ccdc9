/* test-tf: transfer functions: the text format (values normalized or in
 * data units), its errors (named by line and field), ParaView preset import
 * with its domain rescaled to the data, evaluation, the default from a
 * histogram, the NaN colour (text line, ParaView NanColor/NanOpacity,
 * defaults, errors), and palette construction (premultiplied,
 * opacity-corrected, NaN entries in the NaN colour, fully transparent slices
 * detected); log scales (geometric midpoints, log rescaling of presets,
 * values <= 0, errors), kept preset values, and colour interpolation in
 * Lab, Moreland's diverging Msh, HSV (plain and wrapped) and steps, checked
 * against the published formulas written out below, independently of
 * tvpal_tf.c (CIE 15:2004 Lab with the IEC 61966-2-1 sRGB matrix and the
 * D65 white 0.95047 1 1.08883; Moreland 2009, "Diverging Color Maps for
 * Scientific Visualization", section 5 and its pseudocode). */
#include "tvpal_frame.h"
#include "tvpal_test.h"
#include "tvpal_tf.h"

#include <string.h>

/* ---- reference colour formulas (published constants) ---- */

static double ref_lin(double c)
{
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

static double ref_gam(double c)
{
    return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1 / 2.4) - 0.055;
}

static const double ref_white[3] = {0.95047, 1.0, 1.08883};

static void ref_rgb2lab(const double rgb[3], double lab[3])
{
    static const double m[3][3] = {{0.4124564, 0.3575761, 0.1804375},
                                   {0.2126729, 0.7151522, 0.0721750},
                                   {0.0193339, 0.1191920, 0.9503041}};
    double f[3];
    for (int i = 0; i < 3; i++) {
        double t = (m[i][0] * ref_lin(rgb[0]) + m[i][1] * ref_lin(rgb[1]) +
                    m[i][2] * ref_lin(rgb[2])) / ref_white[i];
        f[i] = t > 216.0 / 24389 ? cbrt(t) : (24389.0 / 27 * t + 16) / 116;
    }
    lab[0] = 116 * f[1] - 16;
    lab[1] = 500 * (f[0] - f[1]);
    lab[2] = 200 * (f[1] - f[2]);
}

static void ref_lab2rgb(const double lab[3], double rgb[3])
{
    static const double m[3][3] = {{3.2404542, -1.5371385, -0.4985314},
                                   {-0.9692660, 1.8760108, 0.0415560},
                                   {0.0556434, -0.2040259, 1.0572252}};
    double fy = (lab[0] + 16) / 116, f[3] = {fy + lab[1] / 500, fy,
                                             fy - lab[2] / 200};
    double xyz[3];
    for (int i = 0; i < 3; i++)
        xyz[i] = ref_white[i] * (f[i] > 6.0 / 29 ? f[i] * f[i] * f[i]
                                 : (116 * f[i] - 16) * 27 / 24389);
    for (int i = 0; i < 3; i++)
        rgb[i] = ref_gam(m[i][0] * xyz[0] + m[i][1] * xyz[1] + m[i][2] * xyz[2]);
}

/* Moreland 2009: Msh and the diverging interpolation of two colours. */
static void ref_rgb2msh(const double rgb[3], double msh[3])
{
    double lab[3];
    ref_rgb2lab(rgb, lab);
    msh[0] = sqrt(lab[0] * lab[0] + lab[1] * lab[1] + lab[2] * lab[2]);
    msh[1] = acos(lab[0] / msh[0]);
    msh[2] = atan2(lab[2], lab[1]);
}

static double ref_adjust_hue(const double sat[3], double m_unsat)
{
    if (sat[0] >= m_unsat)
        return sat[2];
    double spin = sat[1] * sqrt(m_unsat * m_unsat - sat[0] * sat[0]) /
                  (sat[0] * sin(sat[1]));
    return sat[2] > -M_PI / 3 ? sat[2] + spin : sat[2] - spin;
}

static void ref_diverging(const double rgb1[3], const double rgb2[3],
                          double t, double out[3])
{
    double a[3], b[3];
    ref_rgb2msh(rgb1, a);
    ref_rgb2msh(rgb2, b);
    double dh = fabs(a[2] - b[2]);
    if (dh > M_PI)
        dh = 2 * M_PI - dh;
    if (a[1] > 0.05 && b[1] > 0.05 && dh > M_PI / 3) {
        double mid = fmax(fmax(a[0], b[0]), 88);
        if (t < 0.5) {
            b[0] = mid, b[1] = 0, b[2] = 0, t = 2 * t;
        } else {
            a[0] = mid, a[1] = 0, a[2] = 0, t = 2 * t - 1;
        }
    }
    if (a[1] < 0.05 && b[1] > 0.05)
        a[2] = ref_adjust_hue(b, a[0]);
    else if (b[1] < 0.05 && a[1] > 0.05)
        b[2] = ref_adjust_hue(a, b[0]);
    double m[3], lab[3];
    for (int i = 0; i < 3; i++)
        m[i] = (1 - t) * a[i] + t * b[i];
    lab[0] = m[0] * cos(m[1]);
    lab[1] = m[0] * sin(m[1]) * cos(m[2]);
    lab[2] = m[0] * sin(m[1]) * sin(m[2]);
    ref_lab2rgb(lab, out);
}

static int near3(const float c[4], const double want[3], double tol)
{
    return fabs(c[0] - want[0]) <= tol && fabs(c[1] - want[1]) <= tol &&
           fabs(c[2] - want[2]) <= tol;
}

/* A transfer function the parser must refuse: TVPAL_E_FORMAT with msg in
 * its message (src: text, or a preset's JSON; lo..hi: the range). */
struct bad_tf {
    const char *src, *msg;
    double lo, hi;
    int code;       /* 0: TVPAL_E_FORMAT */
};

static void check_refused(const struct bad_tf *b, size_t n, int preset,
                          const char *what)
{
    static struct tvpal_tf tf;
    for (size_t i = 0; i < n; i++) {
        struct tvpal_diag d = {{0}};
        int rc = preset ? tvpal_tf_parse_paraview(b[i].src, b[i].lo, b[i].hi,
                                                  &tf, &d)
                        : tvpal_tf_parse_text(b[i].src, b[i].lo, b[i].hi, &tf,
                                              &d);
        CHECK(rc == (b[i].code ? b[i].code : TVPAL_E_FORMAT) &&
              strstr(d.msg, b[i].msg),
              "%s %zu: got \"%s\", want \"%s\"", what, i, d.msg, b[i].msg);
    }
}
#define CHECK_REFUSED(table, preset, what) \
    check_refused(table, sizeof table / sizeof *table, preset, what)

/* Log scale: geometric midpoints, <= 0 below every point, presets rescaled
 * in log space, kept values, and the errors. */
static void test_log_scale(void)
{
    struct tvpal_tf tf;
    struct tvpal_diag d = {{0}};
    float c[4];
    CHECK(tvpal_tf_parse_text("scale log\ndomain data\n1 0 0 0 0\n"
                              "100 1 1 1 1\n", 0, 1, &tf, &d) == 0, "%s", d.msg);
    tvpal_tf_eval(&tf, 10, c);
    CHECK(fabs(c[0] - 0.5) < 1e-6 && fabs(c[3] - 0.5) < 1e-6,
          "log midpoint at the geometric mean: %g %g", c[0], c[3]);
    tvpal_tf_eval(&tf, 50.5, c);
    CHECK(fabs(c[3] - log10(50.5) / 2) < 1e-6, "log interp %g", c[3]);
    tvpal_tf_eval(&tf, 0, c);
    CHECK(c[0] == 0 && c[3] == 0, "0 with a log scale: the first point");
    tvpal_tf_eval(&tf, -3, c);
    CHECK(c[0] == 0 && c[3] == 0, "< 0 with a log scale: the first point");
    CHECK(fabs(tvpal_tf_domain_value(&tf, 0.5) - 10) < 1e-9,
          "domain middle %g", tvpal_tf_domain_value(&tf, 0.5));
    /* Normalized values are placed geometrically over the range. */
    CHECK(tvpal_tf_parse_text("domain normalized\n0 0 0 0 0\n0.5 1 0 0 1\n"
                              "1 1 1 1 1\nscale log\n", 1, 1e4, &tf, &d) == 0 &&
          fabs(tf.value[1] - 100) < 1e-9 && tf.value[2] == 1e4 &&
          fabs(tf.value[0] - 1) < 1e-12, "normalized log: %g %g %g",
          tf.value[0], tf.value[1], tf.value[2]);
    /* The same file without "scale log" is the linear one. */
    CHECK(tvpal_tf_parse_text("domain data\n1 0 0 0 0\n100 1 1 1 1\n", 0, 1,
                              &tf, &d) == 0, "%s", d.msg);
    tvpal_tf_eval(&tf, 10, c);
    CHECK(fabs(c[0] - 9.0 / 99) < 1e-6, "linear at 10: %g", c[0]);
    /* A preset: x 1, 10, 1000 rescaled onto 10..1e5 along log10. */
    const char *pv = "{\"UseLogScale\": 1, \"RGBPoints\": [1, 0, 0, 0, 10, "
                     "0.5, 0.5, 0.5, 1000, 1, 1, 1]}";
    CHECK(tvpal_tf_parse_paraview(pv, 10, 1e5, &tf, &d) == 0, "%s", d.msg);
    CHECK(tf.log_scale && fabs(tf.value[0] - 10) < 1e-9 &&
          fabs(tf.value[1] / pow(10, 1 + 4.0 / 3) - 1) < 1e-12 &&
          fabs(tf.value[2] / 1e5 - 1) < 1e-12, "log rescale: %g %g %g",
          tf.value[0], tf.value[1], tf.value[2]);
    tvpal_tf_eval(&tf, sqrt(tf.value[1] * tf.value[2]), c);
    CHECK(fabs(c[0] - 0.75) < 1e-6, "preset log midpoint %g", c[0]);
    /* The opacity ramp (no Points) runs along log10 too. */
    CHECK(fabs(tf.rgba[1][3] - 1.0 / 3) < 1e-6, "log ramp %g", tf.rgba[1][3]);
    /* A log opacity curve: halfway (in log10) between 10 and 100. */
    CHECK(tvpal_tf_parse_paraview("{\"UseLogScale\": 1, \"RGBPoints\": [1, 0, "
                                  "0, 0, 100, 1, 1, 1], \"Points\": [1, 0, 0.5, "
                                  "0, 10, 0, 0.5, 0, 100, 1, 0.5, 0]}", 1, 100,
                                  &tf, &d) == 0, "%s", d.msg);
    tvpal_tf_eval(&tf, sqrt(1000.0), c);
    CHECK(fabs(c[3] - 0.5) < 1e-6 && fabs(c[0] - 0.75) < 1e-6,
          "log opacity curve %g %g", c[3], c[0]);
    CHECK(tvpal_tf_parse_paraview("{\"UseLogScale\": true, \"RGBPoints\": [1, "
                                  "0, 0, 0, 100, 1, 1, 1], \"Points\": [1, 0, "
                                  "0.5, 0, 100, 1, 0.5, 0]}", NAN, NAN, &tf,
                                  &d) == 0 && tf.value[0] == 1 &&
          tf.value[1] == 100, "kept preset values: %s", d.msg);
    CHECK(tvpal_tf_parse_paraview("{\"UseLogScale\": 0, \"RGBPoints\": [-5, "
                                  "0, 0, 0, 5, 1, 1, 1]}", NAN, NAN, &tf, &d) == 0 &&
          tf.value[0] == -5 && !tf.log_scale, "kept, linear: %s", d.msg);
    static const struct bad_tf bad[] = {
        {"{\"UseLogScale\": 1, \"RGBPoints\": [0, 0, 0, 0, 1, 1, 1, 1]}",
         "UseLogScale: RGBPoints x = 0 (point 1); a log scale needs values > 0",
         1, 10},
        {"{\"UseLogScale\": 1, \"RGBPoints\": [1, 0, 0, 0, 2, 1, 1, 1], "
         "\"Points\": [-1, 0, 0.5, 0, 2, 1, 0.5, 0]}", "Points x = -1", 1, 10},
        {"{\"UseLogScale\": 1, \"RGBPoints\": [1, 0, 0, 0, 2, 1, 1, 1]}",
         "the value range 0..10 to rescale onto includes values <= 0", 0, 10,
         TVPAL_E_RANGE},
        {"{\"UseLogScale\": \"yes\", \"RGBPoints\": [1, 0, 0, 0]}",
         "UseLogScale: malformed", 1, 10},
    };
    CHECK_REFUSED(bad, 1, "bad log preset");
    static const struct bad_tf badt[] = {
        {"scale log\ndomain data\n0 0 0 0 0\n1 1 1 1 1\n",
         "point 1: value 0 with a log scale; expected values > 0", -1, 1},
        {"scale log\ndomain normalized\n0 0 0 0 0\n", "the value range -1..1 "
         "includes values <= 0", -1, 1, TVPAL_E_RANGE},
        {"scale logarithmic\n", "line 1: scale \"logarithmic\": expected "
         "linear or log", -1, 1},
    };
    CHECK_REFUSED(badt, 0, "bad log text");
    d.msg[0] = 0;
    CHECK(tvpal_tf_parse_text("domain normalized\n0 0 0 0 0\n", NAN, NAN, &tf,
                              &d) == TVPAL_E_FORMAT &&
          strstr(d.msg, "domain normalized: no value range"), "%s", d.msg);
}

/* Colour spaces against the reference formulas; opacity stays linear. */
static void test_color_spaces(void)
{
    struct tvpal_tf tf;
    struct tvpal_diag d = {{0}};
    float c[4];
    double want[3];
    /* ParaView's Cool to Warm: two points, ColorSpace Diverging.  Its
     * middle is the paper's white, (0.865, 0.865, 0.865). */
    const double cool[3] = {0.23137254902, 0.298039215686, 0.752941176471};
    const double warm[3] = {0.705882352941, 0.0156862745098, 0.149019607843};
    const char *ctw = "[{\"ColorSpace\" : \"Diverging\", \"Name\": \"Cool to "
                      "Warm\", \"RGBPoints\": [0, 0.23137254902, "
                      "0.298039215686, 0.752941176471, 1, 0.705882352941, "
                      "0.0156862745098, 0.149019607843]}]";
    CHECK(tvpal_tf_parse_paraview(ctw, 0, 1, &tf, &d) == 0 &&
          tf.space == TVPAL_TF_DIVERGING, "%s", d.msg);
    tvpal_tf_eval(&tf, 0.5, c);
    CHECK(near3(c, (const double[3]){0.865, 0.865, 0.865}, 1e-3),
          "Cool to Warm middle %g %g %g", c[0], c[1], c[2]);
    CHECK(fabs(c[3] - 0.5) < 1e-6, "diverging opacity linear: %g", c[3]);
    for (int i = 1; i < 16; i++) {
        double t = i / 16.0;
        tvpal_tf_eval(&tf, t, c);
        ref_diverging(cool, warm, t, want);
        CHECK(near3(c, want, 1e-3), "Cool to Warm at %g: %g %g %g, want %g %g "
              "%g", t, c[0], c[1], c[2], want[0], want[1], want[2]);
    }
    /* An unsaturated end: the saturated one's hue spun (no white). */
    const double grey[3] = {0.3, 0.3, 0.3};
    CHECK(tvpal_tf_parse_text("colorspace diverging\ndomain data\n"
                              "0 0.3 0.3 0.3 1\n1 0.705882352941 0.0156862745098 "
                              "0.149019607843 1\n", 0, 1, &tf, &d) == 0, "%s",
          d.msg);
    tvpal_tf_eval(&tf, 0.5, c);
    ref_diverging(grey, warm, 0.5, want);
    CHECK(near3(c, want, 1e-3), "grey to warm: %g %g %g, want %g %g %g", c[0],
          c[1], c[2], want[0], want[1], want[2]);
    /* Lab: the average of the ends' L*a*b*. */
    const double p[3] = {0.9, 0.2, 0.1}, q[3] = {0.1, 0.3, 0.8};
    CHECK(tvpal_tf_parse_text("colorspace lab\ndomain data\n0 0.9 0.2 0.1 0\n"
                              "10 0.1 0.3 0.8 1\n", 0, 1, &tf, &d) == 0, "%s",
          d.msg);
    for (int i = 1; i < 4; i++) {
        double lp[3], lq[3], l[3];
        ref_rgb2lab(p, lp);
        ref_rgb2lab(q, lq);
        for (int k = 0; k < 3; k++)
            l[k] = lp[k] + i / 4.0 * (lq[k] - lp[k]);
        ref_lab2rgb(l, want);
        tvpal_tf_eval(&tf, 2.5 * i, c);
        CHECK(near3(c, want, 1e-3), "Lab at %d/4: %g %g %g, want %g %g %g", i,
              c[0], c[1], c[2], want[0], want[1], want[2]);
        CHECK(fabs(c[3] - i / 4.0) < 1e-6, "Lab opacity %g", c[3]);
    }
    tvpal_tf_eval(&tf, 5, c);
    CHECK(fabs(c[0] - 0.5) > 0.02, "Lab differs from RGB (%g)", c[0]);
    CHECK(tvpal_tf_parse_paraview("{\"ColorSpace\": \"CIELAB\", \"RGBPoints\": "
                                  "[0, 1, 0, 0, 1, 0, 0, 1]}", 0, 1, &tf, &d) == 0 &&
          tf.space == TVPAL_TF_LAB, "CIELAB: %s", d.msg);
    /* HSV: red to blue through green; wrapped, through magenta. */
    CHECK(tvpal_tf_parse_paraview("{\"ColorSpace\": \"HSV\", \"RGBPoints\": "
                                  "[0, 1, 0, 0, 1, 0, 0, 1]}", 0, 1, &tf, &d) == 0,
          "%s", d.msg);
    tvpal_tf_eval(&tf, 0.5, c);
    CHECK(near3(c, (const double[3]){0, 1, 0}, 1e-6), "HSV middle %g %g %g",
          c[0], c[1], c[2]);
    tvpal_tf_eval(&tf, 0.25, c);
    CHECK(near3(c, (const double[3]){1, 1, 0}, 1e-6), "HSV quarter %g %g %g",
          c[0], c[1], c[2]);
    CHECK(tvpal_tf_parse_text("colorspace wrapped-hsv\ndomain data\n"
                              "0 1 0 0 1\n1 0 0 1 1\n", 0, 1, &tf, &d) == 0,
          "%s", d.msg);
    tvpal_tf_eval(&tf, 0.5, c);
    CHECK(near3(c, (const double[3]){1, 0, 1}, 1e-6), "wrapped HSV middle %g "
          "%g %g", c[0], c[1], c[2]);
    /* Step: the left point's colour over the interval; opacity linear. */
    CHECK(tvpal_tf_parse_text("colorspace step\ndomain data\n0 1 0 0 0\n"
                              "1 0 1 0 1\n2 0 0 1 1\n", 0, 1, &tf, &d) == 0,
          "%s", d.msg);
    tvpal_tf_eval(&tf, 0.99, c);
    CHECK(c[0] == 1 && c[1] == 0 && fabs(c[3] - 0.99) < 1e-6, "step %g %g",
          c[0], c[3]);
    tvpal_tf_eval(&tf, 1.0, c);
    CHECK(c[1] == 1 && c[0] == 0, "step at a point: its colour");
    /* Log scale and a colour space together: Lab at the geometric mean. */
    CHECK(tvpal_tf_parse_text("scale log\ncolorspace lab\ndomain data\n"
                              "1 0.9 0.2 0.1 0\n100 0.1 0.3 0.8 1\n", 0, 1, &tf,
                              &d) == 0, "%s", d.msg);
    tvpal_tf_eval(&tf, 10, c);
    {
        double lp[3], lq[3], l[3];
        ref_rgb2lab(p, lp);
        ref_rgb2lab(q, lq);
        for (int k = 0; k < 3; k++)
            l[k] = (lp[k] + lq[k]) / 2;
        ref_lab2rgb(l, want);
    }
    CHECK(near3(c, want, 1e-3) && fabs(c[3] - 0.5) < 1e-6, "log Lab middle");
    static const struct bad_tf bad[] = {
        {"{\"ColorSpace\": \"Lab/CIEDE2000\", \"RGBPoints\": [0, 0, 0, 0]}",
         "ColorSpace \"Lab/CIEDE2000\": expected \"RGB\", \"HSV\""},
        {"{\"ColorSpace\": 3, \"RGBPoints\": [0, 0, 0, 0]}",
         "ColorSpace \"(not a string)\""},
    };
    CHECK_REFUSED(bad, 1, "bad colour space");
    d.msg[0] = 0;
    CHECK(tvpal_tf_parse_text("colorspace cmyk\n", 0, 1, &tf, &d) ==
              TVPAL_E_FORMAT && strstr(d.msg, "line 1: colorspace \"cmyk\": "
                                       "expected rgb, hsv"), "%s", d.msg);
    CHECK(!strcmp(tvpal_tf_space_name(TVPAL_TF_DIVERGING), "Diverging"),
          "space name");
}

/* The largest difference between tf's tabulated colours and the exact
 * conversion (tab_cells 0), over 20001 values across its domain. */
static double tab_error(const struct tvpal_tf *tf)
{
    static struct tvpal_tf exact;
    exact = *tf;
    exact.tab_cells = 0;
    const double a = tf->key[0], b = tf->key[tf->npoints - 1];
    double worst = 0;
    for (int i = 0; i <= 20000; i++) {
        double k = a + (b - a) * i / 20000.0;
        double v = tf->log_scale ? pow(10.0, k) : k;
        float t[4], e[4];
        tvpal_tf_eval(tf, v, t);
        tvpal_tf_eval(&exact, v, e);
        for (int c = 0; c < 4; c++)
            worst = fmax(worst, fabs((double)t[c] - e[c]));
    }
    return worst;
}

/* Lab and diverging TFs are tabulated (a palette entry then costs what an
 * RGB one does) within an eighth of an 8-bit level of the exact colours
 * (1/2048; measured here over 20001 values, not only where
 * tvpal_tf_prepare checks): two-point maps (4096 cells an interval), and
 * 255 smooth points on a log scale, the densest, whose intervals get the
 * fewest cells (16).  255 random points turn too sharply for 16 cells and
 * keep the exact conversion. */
static void test_tabulated(void)
{
    static struct tvpal_tf tf;
    struct tvpal_diag d = {{0}};
    static const char *const spaces[] = {"diverging", "lab"};
    static char text[255 * 64 + 128];
    uint64_t rng = 42;
    for (int sp = 0; sp < 2; sp++) {
        for (int kind = 0; kind < 3; kind++) { /* 2 points, smooth, random */
            const unsigned n = kind ? 255 : 2;
            int at = snprintf(text, sizeof text, "colorspace %s\n%s"
                              "domain normalized\n", spaces[sp],
                              kind ? "scale log\n" : "");
            for (unsigned i = 0; i < n; i++) {
                const double f = (double)i / (n - 1);
                /* smooth: blue to yellow to red, sampled as presets are */
                double c[3] = {f < 0.5 ? 2 * f : 1, f < 0.5 ? 2 * f : 2 - 2 * f,
                               f < 0.5 ? 1 - 2 * f : 0};
                for (int k = 0; kind == 2 && k < 3; k++) {
                    rng = rng * 6364136223846793005ull + 1442695040888963407ull;
                    c[k] = (double)(rng >> 11) / 9007199254740992.0;
                }
                at += snprintf(text + at, sizeof text - at, "%.6f %.4f %.4f "
                               "%.4f 0.5\n", f, c[0], c[1], c[2]);
            }
            REQUIRE(tvpal_tf_parse_text(text, 1, 1000, &tf, &d) == 0, "%s",
                    d.msg);
            const double e = tab_error(&tf);
            printf("%s, %u %s points: %u cells an interval, largest "
                   "difference to the exact colour %.2e\n", spaces[sp], n,
                   kind == 2 ? "random" : "smooth", tf.tab_cells, e);
            if (kind == 2)
                CHECK(tf.tab_cells == 0 && e == 0, "%s, random points: "
                      "exact conversion kept", spaces[sp]);
            else
                CHECK(tf.tab_cells >= 16 && tf.tab_cells % 2 == 0,
                      "%s, %u points: tabulated (%u cells)", spaces[sp], n,
                      tf.tab_cells);
            CHECK(e <= 1.0 / 2048, "%s, %u points: table off by %g",
                  spaces[sp], n, e);
        }
    }
    /* RGB, HSV (kinks at the hue sextants) and Step: exact, no table. */
    static const char *const exact[] = {"rgb", "hsv", "wrapped-hsv", "step"};
    for (int i = 0; i < 4; i++) {
        snprintf(text, sizeof text, "colorspace %s\ndomain data\n0 0 0 1 1\n"
                 "1 1 1 0 1\n", exact[i]);
        CHECK(tvpal_tf_parse_text(text, 0, 1, &tf, &d) == 0 &&
              tf.tab_cells == 0, "%s: not tabulated", exact[i]);
    }
}

int main(void)
{
    struct tvpal_tf tf;
    struct tvpal_diag d = {{0}};
    float c[4];
    const char *t1 = "# comment\nname ramp\ndomain normalized\n"
                     "0   0 0 0 0\n0.5 1 0 0 0.5  # mid\n1   1 1 1 1\n";
    CHECK(tvpal_tf_parse_text(t1, 10, 20, &tf, &d) == 0, "%s", d.msg);
    CHECK(tf.npoints == 3 && tf.value[1] == 15 && !strcmp(tf.name, "ramp"),
          "normalized values mapped to [10,20]");
    tvpal_tf_eval(&tf, 12.5, c);
    CHECK(fabs(c[0] - 0.5) < 1e-6 && fabs(c[3] - 0.25) < 1e-6, "interp %g %g",
          c[0], c[3]);
    tvpal_tf_eval(&tf, -100, c);
    CHECK(c[3] == 0, "clamped below");
    tvpal_tf_eval(&tf, 100, c);
    CHECK(c[3] == 1, "clamped above");
    CHECK(tvpal_tf_parse_text("domain data\n5 1 1 1 1\n7 0 0 0 0\n", 0, 1,
                              &tf, &d) == 0 && tf.value[1] == 7, "data domain");
    /* The NaN colour: transparent unless a "nan r g b a" line says. */
    CHECK(tvpal_tf_parse_text(t1, 10, 20, &tf, &d) == 0 && tf.nan_rgba[0] == 0 &&
          tf.nan_rgba[1] == 0 && tf.nan_rgba[2] == 0 && tf.nan_rgba[3] == 0,
          "text without a nan line: transparent NaN colour");
    CHECK(tvpal_tf_parse_text("nan 1 0.5 0.25 0.75  # missing\ndomain data\n"
                              "0 0 0 0 0\n", 0, 1, &tf, &d) == 0, "%s", d.msg);
    CHECK(tf.nan_rgba[0] == 1.0f && tf.nan_rgba[1] == 0.5f &&
          tf.nan_rgba[2] == 0.25f && tf.nan_rgba[3] == 0.75f && tf.npoints == 1,
          "nan line: %g %g %g %g", tf.nan_rgba[0], tf.nan_rgba[1],
          tf.nan_rgba[2], tf.nan_rgba[3]);
    CHECK(tvpal_tf_parse_text("domain data\n0 0 0 0 0\nnan 0 1 0 1\n", 0, 1,
                              &tf, &d) == 0 && tf.nan_rgba[1] == 1.0f &&
          tf.nan_rgba[3] == 1.0f, "nan line after the points");
    static const struct bad_tf bad[] = {
        {"0 0 0 0 0\n", "line 1: expected \"domain"},
        {"domain weird\n", "line 1: domain \"weird\""},
        {"domain data\n1 0 0 0\n", "line 2: expected 5 numbers"},
        {"domain data\n1 0 0 0 0 9\n", "line 2: expected 5 numbers"},
        {"domain data\n1 0 2 0 0\n", "line 2: g = 2"},
        {"domain data\n1 0 0 0 0\n0 0 0 0 0\n", "line 3: value 0 is below"},
        {"domain data\n", "no points"},
        {"domain data\nnan 1 0 0\n0 0 0 0 0\n", "line 2: expected \"nan r g b a\""},
        {"domain data\nnan 1 0 0 1 1\n0 0 0 0 0\n", "line 2: expected \"nan r g b a\""},
        {"nan 1 0 0 1.5\ndomain data\n0 0 0 0 0\n", "line 1: nan a = 1.5; expected 0..1"},
        {"domain data\nnan -1 0 0 1\n0 0 0 0 0\n", "line 2: nan r = -1"},
        {"domain data\nnan 0 nan 0 1\n0 0 0 0 0\n", "line 2: nan g = nan"},
    };
    CHECK_REFUSED(bad, 0, "bad");
    const char *pv = "[{\"ColorSpace\": \"RGB\", \"Name\": \"Cool to Warm\", "
                     "\"RGBPoints\": [-1, 0.2, 0.3, 0.8, 0, 0.9, 0.9, 0.9, 1, "
                     "0.7, 0.0, 0.1], \"Points\": [-1, 0, 0.5, 0, 1, 1, 0.5, 0]}]";
    CHECK(tvpal_tf_parse_paraview(pv, 100, 200, &tf, &d) == 0, "%s", d.msg);
    CHECK(tf.npoints == 3 && tf.value[0] == 100 && tf.value[1] == 150 &&
          tf.value[2] == 200 && !strcmp(tf.name, "Cool to Warm"),
          "paraview domain rescaled");
    tvpal_tf_eval(&tf, 150, c);
    CHECK(fabs(c[3] - 0.5) < 1e-6 && fabs(c[0] - 0.9) < 1e-6, "paraview "
          "opacity %g", c[3]);
    CHECK(tf.nan_rgba[0] == 0 && tf.nan_rgba[1] == 0 && tf.nan_rgba[2] == 0 &&
          tf.nan_rgba[3] == 0, "preset without NanColor: transparent NaN");
    /* Opacity follows the Points curve between the colour points too. */
    CHECK(tvpal_tf_parse_paraview("{\"RGBPoints\": [0, 0, 0, 0, 1, 1, 1, 1], "
                                  "\"Points\": [0, 0, 0.5, 0, 0.5, 0, 0.5, 0, "
                                  "1, 1, 0.5, 0]}", 0, 10, &tf, &d) == 0 &&
          tf.nop == 3 && tf.op_value[1] == 5, "%s", d.msg);
    tvpal_tf_eval(&tf, 2.5, c);
    CHECK(c[3] == 0 && fabs(c[0] - 0.25) < 1e-6, "opacity curve at 2.5: %g",
          c[3]);
    tvpal_tf_eval(&tf, 7.5, c);
    CHECK(fabs(c[3] - 0.5) < 1e-6, "opacity curve at 7.5: %g", c[3]);
    tvpal_tf_eval(&tf, -1, c);
    CHECK(c[3] == 0 && c[0] == 0, "opacity curve below");
    d.msg[0] = 0;
    CHECK(tvpal_tf_parse_paraview("{\"RGBPoints\": [0, 0, 0, 0], \"Points\": "
                                  "[1, 0, 0.5, 0, 0, 1, 0.5, 0]}", 0, 1, &tf, &d)
              == TVPAL_E_FORMAT && strstr(d.msg, "Points: x values must not "
                                          "decrease (point 1)"), "%s", d.msg);
    /* NanColor and NanOpacity as ParaView writes them; NanOpacity defaults
     * to 1 with a NanColor. */
    const char *pvn = "[{\"Name\": \"n\", \"NanColor\": [1, 0.5, 0],\n"
                      "  \"NanOpacity\" : 0.25, \"RGBPoints\": [0, 0, 0, 0, 1, 1, 1, 1]}]";
    CHECK(tvpal_tf_parse_paraview(pvn, 0, 1, &tf, &d) == 0, "%s", d.msg);
    CHECK(tf.nan_rgba[0] == 1.0f && tf.nan_rgba[1] == 0.5f &&
          tf.nan_rgba[2] == 0.0f && tf.nan_rgba[3] == 0.25f,
          "NanColor/NanOpacity: %g %g %g %g", tf.nan_rgba[0], tf.nan_rgba[1],
          tf.nan_rgba[2], tf.nan_rgba[3]);
    CHECK(tvpal_tf_parse_paraview("{\"NanColor\": [0.5, 0.5, 1], \"RGBPoints\": "
                                  "[0, 0, 0, 0]}", 0, 1, &tf, &d) == 0 &&
          tf.nan_rgba[0] == 0.5f && tf.nan_rgba[2] == 1.0f &&
          tf.nan_rgba[3] == 1.0f, "NanColor alone: opacity %g", tf.nan_rgba[3]);
    CHECK(tvpal_tf_parse_paraview("{\"NanOpacity\": 0.5, \"RGBPoints\": "
                                  "[0, 0, 0, 0]}", 0, 1, &tf, &d) == 0 &&
          tf.nan_rgba[0] == 0 && tf.nan_rgba[3] == 0.5f,
          "NanOpacity alone: black, opacity %g", tf.nan_rgba[3]);
    /* A string equal to a key is not the key. */
    CHECK(tvpal_tf_parse_paraview("{\"Name\": \"NanColor\", \"RGBPoints\": "
                                  "[0, 0, 0, 0], \"NanColor\": [0, 1, 0]}", 0, 1,
                                  &tf, &d) == 0 && !strcmp(tf.name, "NanColor") &&
          tf.nan_rgba[1] == 1.0f && tf.nan_rgba[3] == 1.0f, "key vs string: %s",
          d.msg);
    static const struct bad_tf badpv[] = {
        {"{\"NanColor\": [1, 0], \"RGBPoints\": [0, 0, 0, 0]}",
         "NanColor: malformed; expected [r, g, b]"},
        {"{\"NanColor\": [1, 0, 0, 1], \"RGBPoints\": [0, 0, 0, 0]}",
         "NanColor: malformed; expected [r, g, b]"},
        {"{\"NanColor\": 1, \"RGBPoints\": [0, 0, 0, 0]}",
         "NanColor: malformed; expected [r, g, b]"},
        {"{\"NanColor\": [0, 2, 0], \"RGBPoints\": [0, 0, 0, 0]}",
         "NanColor: g = 2; expected [r, g, b], 3 numbers in 0..1"},
        {"{\"NanColor\": [0, 0, -0.5], \"RGBPoints\": [0, 0, 0, 0]}",
         "NanColor: b = -0.5"},
        {"{\"NanOpacity\": 1.5, \"RGBPoints\": [0, 0, 0, 0]}",
         "NanOpacity: 1.5; expected a number in 0..1"},
        {"{\"NanOpacity\": \"x\", \"RGBPoints\": [0, 0, 0, 0]}",
         "NanOpacity: malformed; expected a number in 0..1"},
    };
    CHECK_REFUSED(badpv, 1, "bad preset");
    CHECK(tvpal_tf_parse_paraview("{\"Name\": \"x\"}", 0, 1, &tf, &d) ==
              TVPAL_E_FORMAT && strstr(d.msg, "RGBPoints: missing"), "%s", d.msg);
    CHECK(tvpal_tf_parse_paraview("{\"RGBPoints\": [0, 1, 1]}", 0, 1, &tf, &d)
              == TVPAL_E_FORMAT, "short RGBPoints");
    uint64_t hist[64] = {0};
    hist[3] = 1000000;
    for (int i = 0; i < 64; i++)
        hist[i] += 10 + i;
    tvpal_tf_default(0, 64, hist, 64, &tf);
    tvpal_tf_eval(&tf, 3.5, c);
    CHECK(c[3] < 0.02, "background bin transparent (%g)", c[3]);
    tvpal_tf_eval(&tf, 50.5, c);
    CHECK(c[3] > 0.1, "rare values visible (%g)", c[3]);
    CHECK(tf.nan_rgba[0] == 0 && tf.nan_rgba[1] == 0 && tf.nan_rgba[2] == 0 &&
          tf.nan_rgba[3] == 0, "default TF: transparent NaN");

    /* Palettes. */
    float row[256], pal[1024];
    for (int i = 0; i < 256; i++)
        row[i] = (float)i / 255.0f;
    tvpal_tf_parse_text(t1, 0, 1, &tf, &d);
    CHECK(tvpal_palette_build(&tf, row, 1.0, 1.0, pal) == 0, "not clear");
    tvpal_tf_eval(&tf, row[200], c);
    CHECK(fabs(pal[4 * 200 + 3] - c[3]) < 1e-6 &&
          fabs(pal[4 * 200] - c[0] * c[3]) < 1e-6, "premultiplied");
    tvpal_palette_build(&tf, row, 2.0, 1.0, pal);
    CHECK(fabs(pal[4 * 200 + 3] - (1 - (1 - c[3]) * (1 - c[3]))) < 1e-6,
          "opacity correction for twice the distance");
    for (int i = 0; i < 256; i++)
        row[i] = -5.0f;
    CHECK(tvpal_palette_build(&tf, row, 1.0, 1.0, pal) == 1,
          "transparent slice detected");

    /* NaN (missing) entries: the NaN colour, scaled, corrected and
     * premultiplied; the finite entries bit for bit as without NaN. */
    float nrow[256], pal0[1024];
    for (int i = 0; i < 256; i++)
        row[i] = nrow[i] = (float)i / 255.0f;
    for (int i = 0; i < 256; i += 7)
        nrow[i] = NAN;
    nrow[255] = -NAN;
    const double expo = 1.7, scale = 0.8;
    tvpal_palette_build(&tf, row, expo, scale, pal0);
    CHECK(tvpal_palette_build(&tf, nrow, expo, scale, pal) == 0, "not clear");
    int same = 1, zero = 1;
    for (int i = 0; i < 256; i++) {
        if (isnan(nrow[i]))
            zero &= pal[4 * i] == 0 && pal[4 * i + 1] == 0 &&
                    pal[4 * i + 2] == 0 && pal[4 * i + 3] == 0;
        else
            same &= !memcmp(pal + 4 * i, pal0 + 4 * i, sizeof(float) * 4);
    }
    CHECK(same, "finite entries changed by NaN neighbours");
    CHECK(zero, "transparent NaN colour: exactly {0, 0, 0, 0}");
    const float nc[4] = {1.0f, 0.5f, 0.25f, 0.6f};
    memcpy(tf.nan_rgba, nc, sizeof nc);
    tvpal_palette_build(&tf, nrow, expo, scale, pal);
    const double na = 1 - pow(1 - nc[3] * scale, expo);
    int nan_ok = 1;
    same = 1;
    for (int i = 0; i < 256; i++) {
        const float *q = pal + 4 * i;
        if (isnan(nrow[i]))
            nan_ok &= fabs(q[3] - na) < 1e-6 && fabs(q[0] - nc[0] * na) < 1e-6 &&
                      fabs(q[1] - nc[1] * na) < 1e-6 &&
                      fabs(q[2] - nc[2] * na) < 1e-6;
        else
            same &= !memcmp(q, pal0 + 4 * i, sizeof(float) * 4);
    }
    CHECK(nan_ok, "NaN entry %g %g %g %g, want alpha %g", pal[0], pal[1], pal[2],
          pal[3], na);
    CHECK(same, "finite entries changed by a NaN colour");
    /* Opacity scale clamps the NaN colour's opacity like any other. */
    tvpal_palette_build(&tf, nrow, expo, 3.0, pal);
    CHECK(pal[3] == 1.0f && pal[0] == 1.0f && pal[1] == 0.5f, "clamped NaN "
          "opacity %g", pal[3]);
    /* All NaN: clear with the transparent colour, not with a visible one. */
    for (int i = 0; i < 256; i++)
        nrow[i] = NAN;
    CHECK(tvpal_palette_build(&tf, nrow, 1.0, 1.0, pal) == 0,
          "a visible NaN colour is not clear");
    memset(tf.nan_rgba, 0, sizeof tf.nan_rgba);
    memset(pal, 0xff, sizeof pal);
    CHECK(tvpal_palette_build(&tf, nrow, 1.0, 1.0, pal) == 1,
          "all NaN, transparent NaN colour: clear");
    zero = 1;
    for (int i = 0; i < 1024; i++)
        zero &= pal[i] == 0;
    CHECK(zero, "all NaN: every entry exactly 0");
    test_log_scale();
    test_color_spaces();
    test_tabulated();
    return tt_done("test-tf");
}
