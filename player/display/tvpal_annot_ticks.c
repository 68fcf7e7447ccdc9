/* tvpal_annot_ticks.c: the legend's round tick values and their labels
 * (see tvpal_annot.h); plain arithmetic, built with or without cairo. */
#include "tvpal_annot.h"

#include <math.h>
#include <stdio.h>

/* The round number (1, 2 or 5 times a power of ten) nearest to x > 0
 * (Heckbert, "Nice numbers for graph labels", Graphics Gems, 1990). */
static double nice_step(double x)
{
    const double e = floor(log10(x)), f = x / pow(10.0, e);
    const double nf = f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10;
    return nf * pow(10.0, e);
}

/* Multiples of step inside [vmin, vmax], at most max of them. */
static unsigned multiples(double vmin, double vmax, double step, unsigned max,
                          double *ticks)
{
    const double k0 = ceil(vmin / step);
    unsigned n = 0;
    for (double k = k0; n < max && k * step <= vmax; k++)
        ticks[n++] = k * step;
    return n;
}

unsigned tvpal_annot_ticks(double vmin, double vmax, unsigned want,
                           unsigned max, double *ticks, double *step)
{
    *step = 0;
    if (!isfinite(vmin) || !isfinite(vmax) || !(vmin < vmax) ||
        !isfinite(vmax - vmin) || max < 2 || want < 2)
        return 0;
    max = max > TVPAL_ANNOT_MAX_TICKS ? TVPAL_ANNOT_MAX_TICKS : max;
    double s = nice_step((vmax - vmin) / (want - 1));
    /* Too many for max: the next round step up, until they fit. */
    while ((vmax - vmin) / s + 1 > max)
        s = nice_step(s * 2.2);
    *step = s;
    return multiples(vmin, vmax, s, max, ticks);
}

void tvpal_annot_tick_label(double v, double step, char *buf, unsigned cap)
{
    if (!cap)
        return;
    /* Snap a value that is a tick up to rounding noise (0.30000000000004)
     * onto the tick; -0 prints as 0. */
    if (step > 0) {
        double k = nearbyint(v / step);
        if (fabs(v - k * step) < 1e-9 * step)
            v = k * step;
    }
    if (v == 0)
        v = 0;
    const double mag = fmax(fabs(v), step);
    if (step > 0 && mag < 1e6 && step >= 1e-4) {
        /* Fixed point with the decimals the step needs. */
        int dec = step >= 1 ? 0 : (int)ceil(-log10(step) - 1e-9);
        snprintf(buf, cap, "%.*f", dec, v);
    } else {
        /* Exponent form with the significant digits the step needs. */
        int sig = step > 0 ? (int)ceil(log10(mag / step) - 1e-9) + 1 : 6;
        sig = sig < 1 ? 1 : sig > 15 ? 15 : sig;
        snprintf(buf, cap, "%.*g", sig, v);
    }
}
