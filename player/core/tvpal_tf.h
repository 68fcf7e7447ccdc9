/* tvpal_tf.h: transfer functions: data value -> colour and opacity.
 *
 * A transfer function is a piecewise-linear map through control points
 * (value, r, g, b, a) with r, g, b, a in [0, 1]; values below the first
 * point take the first point's colour, above the last the last's.  Opacity
 * a is per unit of reference slice spacing: the renderer corrects it for
 * the actual sampling distance.  Two sources:
 *   - the tvpal text format (samples/tf/README.md), with values in data
 *     units or normalized to the dataset's [min, max];
 *   - ParaView colour-map presets (JSON): RGBPoints and, when present, the
 *     opacity Points; their domain is rescaled onto the data range, as
 *     ParaView does when a preset is applied.
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
};

/* Parses the text format; vmin/vmax give the data range for normalized
 * values.  name labels messages. */
int tvpal_tf_parse_text(const char *text, double vmin, double vmax,
                        struct tvpal_tf *tf, struct tvpal_diag *diag);

/* Parses a ParaView preset (a JSON object or an array of them: the first
 * with RGBPoints is used).  NanColor [r, g, b] (0..1 each) sets the NaN
 * colour, NanOpacity (0..1) its opacity: 1 when only NanColor is given,
 * as in ParaView; black when only NanOpacity is. */
int tvpal_tf_parse_paraview(const char *json, double vmin, double vmax,
                            struct tvpal_tf *tf, struct tvpal_diag *diag);

/* Loads a file: ParaView JSON when it starts with '[' or '{', else text. */
int tvpal_tf_load(const char *path, double vmin, double vmax,
                  struct tvpal_tf *tf, struct tvpal_diag *diag);

/* A default from the source histogram (TVPAL_HIST_BINS bins over
 * [vmin, vmax]): transparent in the most populated bin (the background),
 * opacity rising with value rarity, a blue-white-red colour ramp. */
void tvpal_tf_default(double vmin, double vmax, const uint64_t *hist,
                      unsigned nbins, struct tvpal_tf *tf);

/* Colour and opacity at a finite value v (straight, not premultiplied);
 * NaN is the caller's case (nan_rgba). */
void tvpal_tf_eval(const struct tvpal_tf *tf, double v, float rgba[4]);

#endif
