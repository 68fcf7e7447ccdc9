/* tf_common.h: what the two transfer-function harnesses do with a parser
 * (tf_text.c, tf_paraview.c): parse the input onto a range reaching below
 * 0, onto one above 0 (where a log scale can take it) and with the file's
 * own values (NaN range), then evaluate across and beyond each TF's domain,
 * at 0 and below; every colour and opacity must be a number in [0, 1]
 * (to float rounding). */
#ifndef TF_COMMON_H
#define TF_COMMON_H

#include "tvpal_tf.h"

#include <math.h>
#include <stdlib.h>

typedef int (*fuzz_tf_parser)(const char *src, double vmin, double vmax,
                              struct tvpal_tf *tf, struct tvpal_diag *diag);

static void fuzz_tf(const char *s, fuzz_tf_parser parse)
{
    static const double ranges[3][2] = {{-1.0, 2.0}, {0.5, 1e3}, {NAN, NAN}};
    struct tvpal_tf *tf = malloc(sizeof *tf);
    if (!tf)
        abort();
    for (int r = 0; r < 3; r++) {
        struct tvpal_diag d;
        if (parse(s, ranges[r][0], ranges[r][1], tf, &d) != 0)
            continue;
        for (int i = -4; i <= 20; i++) {
            float rgba[4];
            tvpal_tf_eval(tf, i <= 0 ? 0.5 * i
                              : tvpal_tf_domain_value(tf, (i - 2) / 16.0), rgba);
            for (int k = 0; k < 4; k++)
                if (!(rgba[k] >= -1e-6f && rgba[k] <= 1 + 1e-6f))
                    abort();
        }
    }
    free(tf);
}

#endif
