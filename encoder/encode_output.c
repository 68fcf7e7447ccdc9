/* encode_output.c: what tvpal-encode says of its output (encode_output.h). */
#define _GNU_SOURCE
#include "encode_output.h"
#include "tvpal_clock.h"
#include "tvpal_cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The physical grid: --spacing/--origin, else what a self-describing input
 * says (the size of a falling coordinate's step; an axis not evenly spaced
 * counts 1, origin 0), else the unit grid. */
void grid_of(const struct run *r, double spacing[3], double origin[3])
{
    const struct opts *o = &r->o;
    const struct tvpal_input_info *in = r->in ? tvpal_input_info(r->in) : NULL;
    for (int i = 0; i < 3; i++) {
        int known = in && !in->nonuniform[i] && in->spacing[i] != 0;
        spacing[i] = o->have_spacing ? o->spacing[i]
                     : known ? fabs(in->spacing[i]) : 1.0;
        origin[i] = o->have_origin ? o->origin[i]
                    : in && !in->nonuniform[i] ? in->origin[i] : 0.0;
    }
}

void warn_dropped(uint64_t dropped)
{
    if (dropped)
        msg("warning: %llu present value%s coded as missing: slice-windows "
            "with more than 128 patterns of missing timesteps (a smaller "
            "--window avoids it)", (unsigned long long)dropped,
            dropped == 1 ? "" : "s");
}

void warn_spread(double vmin, double vmax, double plo, double phi,
                 uint64_t huge, uint64_t far, uint64_t total)
{
    const double span = phi - plo, range = vmax - vmin;
    if (huge)
        msg("warning: %llu value%s beyond +-1e30 (the range is %g .. %g): a "
            "fill value? It sets the quantizers' and the colours' range "
            "(--missing V marks a value as missing)",
            (unsigned long long)huge, huge == 1 ? "" : "s", vmin, vmax);
    else if (range > 1000 * span && far)
        msg("warning: %llu value%s (%.3g%%) lie far outside the bulk of the "
            "data (0.1..99.9 percentiles %.4g .. %.4g, range %g .. %g): they "
            "set the quantizers' and the colours' range; missing values? "
            "(--missing V marks a value as missing)",
            (unsigned long long)far, far == 1 ? "" : "s",
            100.0 * (double)far / (double)total, plo, phi, vmin, vmax);
}

/* Progress: `last` forces the closing line.  Work done counts the
 * slice-windows encoded; reading counts as time, so the rate and ETA are
 * of the whole job. */
void report_progress(struct run *r, int last)
{
    struct progress *p = &r->prog;
    double now = tvpal_now();
    if (p->quiet || (!last && now - p->last < p->interval))
        return;
    p->last = now;
    char line[256];
    const uint64_t done = p->work;
    const double el = now - p->t0;
    const double mine = (double)(done - p->work_at_start);
    /* Source voxel-steps: the work counts each once per axis encoded. */
    const double rate = mine / tvpal_axes_count(r->o.axes) /
                        (el > 0 ? el : 1e-9) / 1e6;
    const double eta = mine > 0 ? el / mine * (double)(p->total - done) : -1;
    /* Steps over all passes ("pass-steps" when there are several). */
    tvpal_progress_format(line, sizeof line, last ? p->units : p->unit,
                          p->units, r->passes > 1 ? "pass-steps"
                                                        : "steps",
                          rate, "Mvox-steps/s", eta, p->tty ? 30 : 0);
    if (p->tty)
        fprintf(stderr, "\r%s\033[K%s", line, last ? "\n" : "");
    else
        fprintf(stderr, PROG ": %s\n", line);
}

