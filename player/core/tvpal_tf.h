/* tvpal_tf.h: transfer functions: data value -> colour and opacity.
 *
 * A transfer function maps through control points (value, r, g, b, a)
 * with r, g, b, a in [0, 1], interpolating between them (linearly in RGB
 * unless a log scale or colour space below says otherwise); values below
 * the first point take the first point's colour, above the last the
 * last's.  Opacity
 * a is per unit of reference slice spacing: the renderer corrects it for
 * the actual sampling distance.  Two sources:
 *   - the tvpal text format (samples/tf/README.md), with values in data
 *     units or normalized to the dataset's [min, max];
 *   - ParaView colour-map presets (JSON): RGBPoints and, when present, the
 *     opacity Points; their domain is rescaled onto the data range, as
 *     ParaView does when a preset is applied (or kept: see
 *     tvpal_tf_parse_paraview).
 * Two settings change how values between points are found, as in ParaView
 * (vtkColorTransferFunction, vtkPiecewiseFunction):
 *   - a log scale (UseLogScale, the text line "scale log"): colour and
 *     opacity are interpolated in log10(value), so the middle of two points
 *     is their geometric mean; every point's value must then be > 0, and a
 *     data value <= 0 takes the first point's colour and opacity (VTK's
 *     log10 of it lies below every point);
 *   - a colour space (ColorSpace, the text line "colorspace"): colours are
 *     interpolated in RGB, HSV, CIE-L*a*b* or Moreland's diverging Msh space
 *     (enum tvpal_tf_space); opacity is always interpolated linearly in the
 *     value (or its log10).
 * A missing value (a voxel that decodes to NaN) takes the TF's NaN colour
 * nan_rgba instead of a point's; every source defaults it to fully
 * transparent {0, 0, 0, 0}.
 * Functions return 0 or a negative TVPAL_E_* code with the reason (line,
 * field, expected) in diag.
 */
#ifndef TVPAL_TF_H
#define TVPAL_TF_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_error.h"

#define TVPAL_TF_MAX_POINTS 256
/* Cells of the colour table of a Lab or diverging TF over all its
 * intervals (tvpal_tf.tab), and the table's entries at most. */
#define TVPAL_TF_TAB_CELLS 4096
#define TVPAL_TF_TAB_MAX (TVPAL_TF_TAB_CELLS + TVPAL_TF_MAX_POINTS)

/* The space colours are interpolated in between two points (a preset's
 * ColorSpace), computed as VTK's vtkColorTransferFunction::GetTable does
 * with linear interpolation (midpoint 0.5, sharpness 0). */
enum tvpal_tf_space {
    TVPAL_TF_RGB = 0,   /* r, g, b linear: the default */
    TVPAL_TF_HSV,       /* hue, saturation, value linear; hue 0..1 without
                         * wrapping (ParaView's "HSV") */
    TVPAL_TF_HSV_WRAP,  /* HSV, hue the shorter way round the circle
                         * (ParaView's "Wrapped HSV", VTK's HSVWrap) */
    TVPAL_TF_LAB,       /* CIE-L*a*b* (D65), vtkMath::RGBToLab/LabToRGB */
    TVPAL_TF_DIVERGING, /* Moreland 2009: Msh, white inserted between two
                         * distinct saturated colours, hue spun towards
                         * an unsaturated end */
    TVPAL_TF_STEP       /* each interval in its left point's colour */
};

struct tvpal_tf {
    unsigned npoints;                       /* 1..TVPAL_TF_MAX_POINTS */
    double value[TVPAL_TF_MAX_POINTS];      /* non-decreasing, data units */
    float rgba[TVPAL_TF_MAX_POINTS][4];
    /* Colour and opacity of NaN (missing) values: straight, not
     * premultiplied, each in [0, 1], opacity per unit of reference slice
     * spacing like the points'.  {0, 0, 0, 0} (transparent) unless the
     * source sets it: the text format's "nan r g b a" line, a ParaView
     * preset's NanColor [r, g, b] and NanOpacity. */
    float nan_rgba[4];
    char name[64];
    /* A preset's opacity Points, when it has them: opacity then follows
     * this curve (nop points, op_value non-decreasing, data units like
     * value, op_a in [0, 1]) instead of the points' rgba[i][3] (which
     * hold its samples at the colour points).  nop 0: rgba[i][3]. */
    unsigned nop;
    double op_value[TVPAL_TF_MAX_POINTS];
    float op_a[TVPAL_TF_MAX_POINTS];
    int log_scale;                          /* 1: interpolate in log10(value);
                                             * every value > 0 */
    int space;                              /* enum tvpal_tf_space */
    /* Derived from the above by tvpal_tf_prepare (every parser and
     * tvpal_tf_default call it), so that tvpal_tf_eval does no conversion
     * of the points: key[i] is value[i] or log10(value[i]); seg[i] holds
     * interval i..i+1's end colours in the space (Lab, HSV with the wrap
     * applied, or Msh with the hue adjusted), [0] and [1], and when split[i]
     * (diverging: white inserted at the middle) [0]..[1] is the first half
     * and [2]..[3] the second; op_key[i] is op_value[i] or its log10. */
    double key[TVPAL_TF_MAX_POINTS];
    double op_key[TVPAL_TF_MAX_POINTS];
    double seg[TVPAL_TF_MAX_POINTS][4][3];
    unsigned char split[TVPAL_TF_MAX_POINTS];
    /* Lab and diverging colours, tabulated by tvpal_tf_prepare: interval
     * i's colour at s = j / tab_cells of the way (j = 0..tab_cells) is
     * tab[i * (tab_cells + 1) + j], and tvpal_tf_eval interpolates
     * linearly between neighbours, as ParaView's volume mappers sample the
     * colour function into a table.  The conversion from the space to RGB
     * (three pow, a cos and a sin) is then done once per entry, not per
     * palette entry per frame: a palette costs what an RGB one does.
     * tab_cells is even, so a diverging interval's white midpoint is an
     * entry, and at least 16.  The table is kept only when it is within
     * 1/2048 (an eighth of an 8-bit level) of the exact colour at the
     * middle of every cell, where linear interpolation errs most.  0: not
     * tabulated (RGB; HSV, whose hue sextants have kinks; Step; a Lab or
     * diverging TF that turns too sharply within a cell), and the exact
     * conversion per value (a test sets 0 to compare). */
    unsigned tab_cells;
    float tab[TVPAL_TF_TAB_MAX][3];
};

/* Parses the text format (samples/tf/README.md), with its "scale" and
 * "colorspace" lines; vmin/vmax give the range normalized values map onto
 * (linearly, or geometrically with "scale log": then vmin must be > 0).
 * vmin and vmax both NaN: no range (a file with "domain normalized" is
 * refused).  TVPAL_E_FORMAT for a malformed file, TVPAL_E_RANGE for a log
 * scale whose normalized values would map onto a range reaching 0. */
int tvpal_tf_parse_text(const char *text, double vmin, double vmax,
                        struct tvpal_tf *tf, struct tvpal_diag *diag);

/* Parses a ParaView preset (a JSON object or an array of them: the first
 * with RGBPoints is used).  NanColor [r, g, b] (0..1 each) sets the NaN
 * colour, NanOpacity (0..1) its opacity: 1 when only NanColor is given,
 * as in ParaView; black when only NanOpacity is.  ColorSpace: "RGB"
 * (default), "HSV", "Wrapped HSV", "Lab" or "CIELAB", "Diverging", "Step";
 * UseLogScale: 1 or true for a log scale.  Opacity follows the Points
 * curve (x, opacity, midpoint, sharpness, ...; midpoint and sharpness not
 * modelled: linear), or without it ramps from 0 to 1 over the RGBPoints
 * domain, as in ParaView.  The preset's RGBPoints x domain
 * is rescaled onto [vmin, vmax] as ParaView's RescaleTransferFunction does:
 * linearly, or with a log scale logarithmically (log10 x mapped linearly
 * onto [log10 vmin, log10 vmax]; vmin must then be > 0, else
 * TVPAL_E_RANGE).  vmin and vmax both NaN: the points keep the preset's
 * own x values.  TVPAL_E_FORMAT for a malformed preset. */
int tvpal_tf_parse_paraview(const char *json, double vmin, double vmax,
                            struct tvpal_tf *tf, struct tvpal_diag *diag);

/* Loads a file: ParaView JSON when it starts with '[' or '{', else text;
 * vmin and vmax as for the parsers (both NaN: keep the file's values). */
int tvpal_tf_load(const char *path, double vmin, double vmax,
                  struct tvpal_tf *tf, struct tvpal_diag *diag);

/* A default from the source histogram (TVPAL_HIST_BINS bins over
 * [vmin, vmax]): transparent in the most populated bin (the background),
 * opacity rising with value rarity, a blue-white-red colour ramp. */
void tvpal_tf_default(double vmin, double vmax, const uint64_t *hist,
                      unsigned nbins, struct tvpal_tf *tf);

/* Colour and opacity at a finite value v (straight, not premultiplied);
 * NaN is the caller's case (nan_rgba).  With a log scale a value <= 0
 * takes the first point's.  Allocates nothing and converts no point:
 * between two points it costs one log10 (log scale) and one conversion
 * from the colour space to RGB. */
void tvpal_tf_eval(const struct tvpal_tf *tf, double v, float rgba[4]);

/* Computes key, op_key, seg and split from the points, log_scale and
 * space: call after changing any of them.  TVPAL_E_FORMAT when log_scale
 * is set and a point's value is <= 0, or space is unknown. */
int tvpal_tf_prepare(struct tvpal_tf *tf, struct tvpal_diag *diag);

/* The value at fraction f (0..1) of the TF's domain [value[0],
 * value[npoints - 1]]: linear, or geometric with a log scale (a legend
 * places its colours and labels with it). */
double tvpal_tf_domain_value(const struct tvpal_tf *tf, double f);

/* "RGB", "HSV", "Wrapped HSV", "Lab", "Diverging" or "Step". */
const char *tvpal_tf_space_name(int space);

#endif
