/* test-tf: transfer functions: the text format (values normalized or in
 * data units), its errors (named by line and field), ParaView preset import
 * with its domain rescaled to the data, evaluation, the default from a
 * histogram, the NaN colour (text line, ParaView NanColor/NanOpacity,
 * defaults, errors), and palette construction (premultiplied,
 * opacity-corrected, NaN entries in the NaN colour, fully transparent slices
 * detected). */
#include "tvpal_frame.h"
#include "tvpal_test.h"
#include "tvpal_tf.h"

#include <string.h>

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
    static const struct { const char *text, *msg; } bad[] = {
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
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        d.msg[0] = 0;
        CHECK(tvpal_tf_parse_text(bad[i].text, 0, 1, &tf, &d) == TVPAL_E_FORMAT &&
              strstr(d.msg, bad[i].msg), "bad %zu: got \"%s\", want \"%s\"", i,
              d.msg, bad[i].msg);
    }
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
    static const struct { const char *json, *msg; } badpv[] = {
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
    for (size_t i = 0; i < sizeof badpv / sizeof *badpv; i++) {
        d.msg[0] = 0;
        CHECK(tvpal_tf_parse_paraview(badpv[i].json, 0, 1, &tf, &d) ==
                  TVPAL_E_FORMAT && strstr(d.msg, badpv[i].msg),
              "bad preset %zu: got \"%s\", want \"%s\"", i, d.msg, badpv[i].msg);
    }
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
    return tt_done("test-tf");
}
