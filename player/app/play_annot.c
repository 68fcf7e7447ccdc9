/* play_annot.c: see play_annot.h. */
#include "play_annot.h"
#include "tvpal_utf8.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

unsigned play_annot_bits(int level)
{
    switch (level) {
    case PLAY_ANNOT_MINIMAL:
        return TVPAL_ANNOT_LEGEND | TVPAL_ANNOT_TIME;
    case PLAY_ANNOT_FULL:
        return TVPAL_ANNOT_LEGEND | TVPAL_ANNOT_TIME | TVPAL_ANNOT_OUTLINE |
               TVPAL_ANNOT_TRIAD;
    default:
        return 0;
    }
}

/* Text dark on a light background, light on a dark one; the halo is the
 * background itself. */
static void text_colours(struct play_annot *pa, const float bg[3])
{
    const double lum = 0.2126 * bg[0] + 0.7152 * bg[1] + 0.0722 * bg[2];
    const float c = lum > 0.5 ? 0.0f : 1.0f;
    for (int i = 0; i < 3; i++) {
        pa->fg[i] = c;
        pa->halo[i] = bg[i];
    }
}

int play_annot_open(struct play_annot *pa, const struct play_opts *o,
                    int want_hud, unsigned width, unsigned height,
                    struct tvpal_diag *diag)
{
    memset(pa, 0, sizeof *pa);
    pa->what = play_annot_bits(o->annotate);
    pa->place = o->legend_place;
    text_colours(pa, o->background);
    if (!pa->what && !want_hud)
        return 0;
    return tvpal_annot_create(&pa->a, width, height, diag);
}

void play_annot_close(struct play_annot *pa)
{
    tvpal_annot_free(pa->a);
    pa->a = NULL;
}

/* The legend's colours: the TF's, its opacity times the opacity scale. */
static void tf_colour(void *ctx, double value, float rgba[4])
{
    const struct play_annot *pa = ctx;
    tvpal_tf_eval(pa->tf, value, rgba);
    rgba[3] = (float)(rgba[3] * pa->opacity);
}

/* The legend's range: the TF's points, else the data's, else a little
 * around the one value there is (constant data: a relative width, as
 * c +- 0.5 is c itself for |c| beyond 2^53).  0, or -1 when there is no
 * finite range at all (the legend is then left out). */
static int legend_range(const struct play_session *s, double *lo,
                        double *hi)
{
    const struct tvpal_tf *tf = s->tf;
    *lo = tf->value[0];
    *hi = tf->value[tf->npoints - 1];
    if (!(*lo < *hi)) {
        *lo = s->m->value_min;
        *hi = s->m->value_max;
    }
    if (!(*lo < *hi)) {
        const double c = isfinite(*lo) ? *lo : 0, h = fmax(0.5, fabs(c) * 1e-6);
        *lo = c - h;
        *hi = c + h;
    }
    return isfinite(*lo) && isfinite(*hi) && *lo < *hi ? 0 : -1;
}

void play_annot_box_corners(const struct tvpal_view *v, double corner[8][2])
{
    for (unsigned c = 0; c < 8; c++) {
        const double p[3] = {(c & 1) ? v->half[0] : -v->half[0],
                             (c & 2) ? v->half[1] : -v->half[1],
                             (c & 4) ? v->half[2] : -v->half[2]};
        double e[2];
        for (int i = 0; i < 2; i++)
            e[i] = v->rot[i][0] * p[0] + v->rot[i][1] * p[1] +
                   v->rot[i][2] * p[2];
        tvpal_view_eye_to_pixel(v, e[0], e[1], &corner[c][0], &corner[c][1]);
    }
}

/* Labels that are not valid UTF-8 are drawn with U+FFFD for the bytes
 * that are not (tvpal_annot): said once per run, naming the key. */
static void warn_text(struct play_annot *pa, const struct tvpal_manifest *m)
{
    const char *keys[3] = {"units", "time_units", "source_var"};
    const char *vals[3] = {m->units, m->time_units,
                           m->source_var ? m->source_var : ""};
    for (int i = 0; i < 3 && !pa->warned_text; i++)
        if (vals[i][tvpal_utf8_valid_prefix(vals[i])]) {
            fprintf(stderr, PLAY_PROG ": warning: the manifest's %s is not valid "
                    "UTF-8 (a byte 0x%02x): drawn with U+FFFD for its "
                    "invalid bytes\n", keys[i], (unsigned char)
                    vals[i][tvpal_utf8_valid_prefix(vals[i])]);
            pa->warned_text = 1;
        }
}

int play_annot_frame(struct play_annot *pa, const struct play_session *s,
                     const struct tvpal_view *v, uint32_t t, uint8_t *frame,
                     struct tvpal_diag *diag)
{
    if (!pa->a || !pa->what)
        return 0;
    const struct tvpal_manifest *m = s->m;
    struct tvpal_annot_frame f = {.what = pa->what, .colour = tf_colour,
                                  .colour_ctx = pa, .title = pa->title,
                                  .legend_place = pa->place,
                                  .time_text = pa->time};
    memcpy(f.fg, pa->fg, sizeof f.fg);
    memcpy(f.halo, pa->halo, sizeof f.halo);
    pa->tf = s->tf;
    pa->opacity = s->tf_opacity;
    if (legend_range(s, &f.vmin, &f.vmax) < 0)
        f.what &= ~TVPAL_ANNOT_LEGEND;
    /* A log-scale TF gets a log bar (its points are > 0; a range from the
     * data may reach 0, and is then shown linearly). */
    f.log_scale = s->tf->log_scale && f.vmin > 0;
    /* The variable and its units as the manifest has them ("T [K]"); no
     * units are guessed where it has none. */
    const char *var = m->source_var ? m->source_var : "";
    if (m->units[0])
        snprintf(pa->title, sizeof pa->title, "%s%s[%s]", var, *var ? " " : "",
                 m->units);
    else
        snprintf(pa->title, sizeof pa->title, "%s", var);
    if (m->ntimes && t < m->ntimes)
        snprintf(pa->time, sizeof pa->time, "t = %g%s%s", m->times[t],
                 m->time_units[0] ? " " : "", m->time_units);
    else
        snprintf(pa->time, sizeof pa->time, "step %u", t);
    warn_text(pa, m);
    play_annot_box_corners(v, f.corner);
    for (int i = 0; i < 3; i++) {
        f.axis_dir[i][0] = v->rot[0][i];
        f.axis_dir[i][1] = v->rot[1][i];
    }
    return tvpal_annot_draw(pa->a, &f, frame, diag);
}
