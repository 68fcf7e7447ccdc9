/* tvpal_annot.c: annotations and the window HUD with cairo (see
 * tvpal_annot.h; the only file that includes cairo). */
#include "tvpal_annot.h"
#include "tvpal_utf8.h"

#include <cairo.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A rectangle of the overlay, top row first: [x0, x1) x [y0, y1). */
struct box {
    int x0, y0, x1, y1;
};

/* A W x H cairo ARGB32 image (premultiplied, top row first) to draw on. */
struct layer {
    unsigned char *px;
    cairo_surface_t *surf;
    cairo_t *cr;
    struct box dirty;           /* what the drawing since the last clear
                                 * touched */
};

struct tvpal_annot {
    unsigned W, H;
    int stride;                 /* bytes per layer row */
    double fs;                  /* font size, pixels */
    /* ov: the overlay blended into the frame; lg: the legend, kept from
     * frame to frame and drawn again only when what it shows changes
     * (its text is most of the drawing's cost). */
    struct layer ov, lg, *cur;  /* cur: the one drawn on */
    struct tvpal_annot_legend legend;
    int lg_valid;
    double lg_range[2];
    int lg_log;
    float lg_fg[3], lg_halo[3];
    char lg_title[160];
    float (*lg_rows)[4], (*rows)[4];  /* each bar row's colour: the cached
                                       * legend's, this frame's (H each) */
    struct box lg_box;          /* where lg holds the legend */
};

int tvpal_annot_available(void)
{
    return 1;
}

const char *tvpal_annot_describe(void)
{
    static char buf[48];
    snprintf(buf, sizeof buf, "cairo %s", cairo_version_string());
    return buf;
}

/* cairo's state as a diag: 0, or TVPAL_E_SYS naming what failed. */
static int cairo_check(cairo_status_t st, const char *what,
                       struct tvpal_diag *diag)
{
    if (st == CAIRO_STATUS_SUCCESS)
        return 0;
    return tvpal_diag_set(diag, st == CAIRO_STATUS_NO_MEMORY ? TVPAL_E_NOMEM
                                                             : TVPAL_E_SYS,
                          "annotations: %s: %s", what,
                          cairo_status_to_string(st));
}

static void layer_close(struct layer *l)
{
    if (l->cr)
        cairo_destroy(l->cr);
    if (l->surf)
        cairo_surface_destroy(l->surf);
    free(l->px);
    memset(l, 0, sizeof *l);
}

/* A cleared layer of a's size with a's font. */
static int layer_open(const struct tvpal_annot *a, struct layer *l,
                      struct tvpal_diag *diag)
{
    l->px = calloc((size_t)a->stride, a->H);
    if (!l->px)
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory");
    l->surf = cairo_image_surface_create_for_data(
        l->px, CAIRO_FORMAT_ARGB32, (int)a->W, (int)a->H, a->stride);
    l->cr = cairo_create(l->surf);
    int rc = cairo_check(cairo_status(l->cr), "cannot create a context",
                         diag);
    if (rc < 0)
        return rc;
    cairo_select_font_face(l->cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL,
                           CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(l->cr, a->fs);
    cairo_font_options_t *fo = cairo_font_options_create();
    cairo_font_options_set_antialias(fo, CAIRO_ANTIALIAS_GRAY);
    cairo_font_options_set_hint_metrics(fo, CAIRO_HINT_METRICS_OFF);
    cairo_set_font_options(l->cr, fo);
    cairo_font_options_destroy(fo);
    return cairo_check(cairo_status(l->cr), "cannot set the font", diag);
}

int tvpal_annot_create(struct tvpal_annot **out, unsigned width,
                       unsigned height, struct tvpal_diag *diag)
{
    *out = NULL;
    if (width < 1 || height < 1 || width > TVPAL_ANNOT_MAX_SIDE ||
        height > TVPAL_ANNOT_MAX_SIDE)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "annotations: image "
                              "size %ux%u: expected 1..%u each", width, height,
                              TVPAL_ANNOT_MAX_SIDE);
    struct tvpal_annot *a = calloc(1, sizeof *a);
    if (!a)
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory");
    a->W = width;
    a->H = height;
    a->stride = cairo_format_stride_for_width(CAIRO_FORMAT_ARGB32, (int)width);
    /* The font scales with the image: 8..16 pixels (14 at 512x512). */
    const double side = width < height ? width : height;
    a->fs = fmin(16.0, fmax(8.0, floor(side / 36.0)));
    a->cur = &a->ov;
    a->lg_rows = calloc(height, sizeof *a->lg_rows);
    a->rows = calloc(height, sizeof *a->rows);
    int rc = !a->lg_rows || !a->rows
                 ? tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory")
                 : layer_open(a, &a->ov, diag);
    if (rc == 0)
        rc = layer_open(a, &a->lg, diag);
    if (rc < 0) {
        tvpal_annot_free(a);
        return rc;
    }
    *out = a;
    return 0;
}

void tvpal_annot_free(struct tvpal_annot *a)
{
    if (!a)
        return;
    layer_close(&a->ov);
    layer_close(&a->lg);
    free(a->lg_rows);
    free(a->rows);
    free(a);
}

/* --------------------------------------------------- the dirty region */

static void dirty_add(struct tvpal_annot *a, double x0, double y0, double x1,
                      double y1)
{
    struct box b = {(int)floor(x0) - 1, (int)floor(y0) - 1,
                    (int)ceil(x1) + 1, (int)ceil(y1) + 1};
    b.x0 = b.x0 < 0 ? 0 : b.x0;
    b.y0 = b.y0 < 0 ? 0 : b.y0;
    b.x1 = b.x1 > (int)a->W ? (int)a->W : b.x1;
    b.y1 = b.y1 > (int)a->H ? (int)a->H : b.y1;
    if (b.x0 >= b.x1 || b.y0 >= b.y1)
        return;
    struct box *d = &a->cur->dirty;
    if (d->x0 >= d->x1) {
        *d = b;
        return;
    }
    d->x0 = b.x0 < d->x0 ? b.x0 : d->x0;
    d->y0 = b.y0 < d->y0 ? b.y0 : d->y0;
    d->x1 = b.x1 > d->x1 ? b.x1 : d->x1;
    d->y1 = b.y1 > d->y1 ? b.y1 : d->y1;
}

/* What cairo's stroke or fill of the current path will touch. */
static void dirty_stroke(struct tvpal_annot *a)
{
    double x0, y0, x1, y1;
    cairo_stroke_extents(a->cur->cr, &x0, &y0, &x1, &y1);
    dirty_add(a, x0, y0, x1, y1);
}

/* Blends the overlay's dirty region "over" the frame (premultiplied 8-bit
 * RGBA, row 0 at the bottom) and clears it for the next drawing. */
static void blend_and_clear(struct tvpal_annot *a, uint8_t *frame)
{
    struct layer *ov = &a->ov;
    const struct box d = ov->dirty;
    cairo_surface_flush(ov->surf);
    for (int y = d.y0; y < d.y1; y++) {
        uint32_t *src = (uint32_t *)(void *)(ov->px + (size_t)y * a->stride);
        uint8_t *dst = frame + 4 * ((size_t)(a->H - 1 - (unsigned)y) * a->W);
        for (int x = d.x0; x < d.x1; x++) {
            const uint32_t p = src[x];
            if (!p)
                continue;
            const unsigned al = p >> 24, keep = 255 - al;
            const unsigned s[4] = {(p >> 16) & 255, (p >> 8) & 255, p & 255,
                                   al};
            uint8_t *q = dst + 4 * (size_t)x;
            for (int c = 0; c < 4; c++)
                q[c] = (uint8_t)(s[c] + (q[c] * keep + 127) / 255);
        }
        memset(src + d.x0, 0, sizeof *src * (size_t)(d.x1 - d.x0));
    }
    cairo_surface_mark_dirty(ov->surf);
    ov->dirty = (struct box){0, 0, 0, 0};
}

/* Premultiplied ARGB32 s "over" d. */
static uint32_t over_argb(uint32_t s, uint32_t d)
{
    const unsigned keep = 255 - (s >> 24);
    uint32_t o = 0;
    for (int sh = 0; sh < 32; sh += 8)
        o |= (((s >> sh) & 255) + (((d >> sh) & 255) * keep + 127) / 255)
             << sh;
    return o;
}

/* Layer l's pixels in box b "over" the overlay's. */
static void over_overlay(struct tvpal_annot *a, const struct layer *l,
                         struct box b)
{
    struct layer *ov = &a->ov;
    cairo_surface_flush(ov->surf);
    for (int y = b.y0; y < b.y1; y++) {
        const uint32_t *s = (const uint32_t *)(const void *)(
            l->px + (size_t)y * a->stride);
        uint32_t *d = (uint32_t *)(void *)(ov->px + (size_t)y * a->stride);
        for (int x = b.x0; x < b.x1; x++)
            if (s[x])
                d[x] = over_argb(s[x], d[x]);
    }
    cairo_surface_mark_dirty(ov->surf);
    struct layer *was = a->cur;
    a->cur = ov;
    dirty_add(a, b.x0 + 1, b.y0 + 1, b.x1 - 1, b.y1 - 1);
    a->cur = was;
}

/* ------------------------------------------------------ text and lines */

/* s as cairo will draw it: itself when it is valid UTF-8, else a copy in
 * buf with U+FFFD for each invalid byte (cairo refuses such a string, and
 * would fail the frame for a label read from a file). */
#define TEXT_MAX 512
static const char *drawable(const char *s, char buf[TEXT_MAX])
{
    if (!s[tvpal_utf8_valid_prefix(s)])
        return s;
    tvpal_utf8_repair(buf, TEXT_MAX, s);
    return buf;
}

/* Text with its left baseline at (x, y), in fg over a halo: the glyphs
 * drawn in the halo colour one pixel off in eight directions, then in fg
 * (cairo's glyph cache makes this several times cheaper than stroking the
 * text's outline). */
static void text(struct tvpal_annot *a, double x, double y, const char *s,
                 const float fg[3], const float halo[3])
{
    static const signed char off[8][2] = {{-1, -1}, {0, -1}, {1, -1},
                                          {-1, 0}, {1, 0}, {-1, 1},
                                          {0, 1}, {1, 1}};
    cairo_t *cr = a->cur->cr;
    char buf[TEXT_MAX];
    s = drawable(s, buf);
    cairo_text_extents_t e;
    cairo_text_extents(cr, s, &e);
    dirty_add(a, x + e.x_bearing - 2, y + e.y_bearing - 2,
              x + e.x_bearing + e.width + 2, y + e.y_bearing + e.height + 2);
    cairo_set_source_rgb(cr, halo[0], halo[1], halo[2]);
    for (int i = 0; i < 8; i++) {
        cairo_move_to(cr, x + off[i][0], y + off[i][1]);
        cairo_show_text(cr, s);
    }
    cairo_set_source_rgb(cr, fg[0], fg[1], fg[2]);
    cairo_move_to(cr, x, y);
    cairo_show_text(cr, s);
    cairo_new_path(cr);
}

static double text_width(struct tvpal_annot *a, const char *s)
{
    char buf[TEXT_MAX];
    cairo_text_extents_t e;
    cairo_text_extents(a->cur->cr, drawable(s, buf), &e);
    return e.x_advance;
}

/* The ascent of the font: text of height fs sits this far above its
 * baseline. */
static double ascent(const struct tvpal_annot *a)
{
    return a->fs * 0.76;
}

/* A line from (x0, y0) to (x1, y1) in overlay coordinates. */
static void line(struct tvpal_annot *a, double x0, double y0, double x1,
                 double y1, double width, const float c[3])
{
    cairo_t *cr = a->cur->cr;
    cairo_new_path(cr);
    cairo_move_to(cr, x0, y0);
    cairo_line_to(cr, x1, y1);
    cairo_set_line_width(cr, width);
    cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
    cairo_set_source_rgb(cr, c[0], c[1], c[2]);
    dirty_stroke(a);
    cairo_stroke(cr);
}

/* ------------------------------------------------------------- legend */

static uint8_t to8(double c)
{
    c = c < 0 ? 0 : c > 1 ? 1 : c;
    return (uint8_t)(c * 255.0 + 0.5);
}

static uint32_t argb(double r, double g, double b)
{
    return 0xFF000000u | (uint32_t)to8(r) << 16 | (uint32_t)to8(g) << 8 |
           to8(b);
}

/* The bar's scale: value of row offset k (rows above the lowest tick's
 * row) is t0 + k * step / q, q rows per step; ticks at k = i * q. */
struct scale {
    double t0, step;
    long q, kmin, kmax;      /* the bar's rows: k in kmin..kmax */
};

static double scale_value(const struct scale *s, long k)
{
    return s->t0 + (double)k * s->step / (double)s->q;
}

/* The bar's coordinate of value v: v, or log10 v on a log bar. */
static double bar_coord(const struct tvpal_annot_frame *f, double v)
{
    return f->log_scale ? log10(v) : v;
}

/* The value at bar coordinate c (bar_coord's inverse). */
static double bar_value(const struct tvpal_annot_frame *f, double c)
{
    return f->log_scale ? pow(10.0, c) : c;
}

/* Tick coordinates over [lo, hi]: round numbers, and on a log bar whole
 * decades when at least two fit (1, 10, 100 rather than 10^0.2 steps). */
static unsigned bar_ticks(const struct tvpal_annot_frame *f, double lo,
                          double hi, double *ticks, double *step)
{
    unsigned n = tvpal_annot_ticks(lo, hi, 5, 8, ticks, step);
    if (!f->log_scale || *step >= 1 || floor(hi) - ceil(lo) < 1)
        return n;
    *step = 1;
    n = 0;
    for (double k = ceil(lo); k <= hi && n < 8; k++)
        ticks[n++] = k;
    return n;
}

/* A scale of about `rows` rows over the bar's coordinates of [vmin, vmax]
 * whose ticks fall on row centres; 0 ticks: -1. */
static int make_scale(const struct tvpal_annot_frame *f, double rows,
                      double *ticks, unsigned *nticks, struct scale *s)
{
    const double lo = bar_coord(f, f->vmin), hi = bar_coord(f, f->vmax);
    *nticks = bar_ticks(f, lo, hi, ticks, &s->step);
    if (*nticks == 0)
        return -1;
    const double span = hi - lo;
    s->t0 = ticks[0];
    s->q = lround(rows * s->step / span);
    s->q = s->q < 1 ? 1 : s->q;
    s->kmin = (long)ceil((lo - s->t0) / s->step * (double)s->q - 1e-9);
    s->kmax = (long)floor((hi - s->t0) / s->step * (double)s->q + 1e-9);
    return s->kmax >= s->kmin ? 0 : -1;
}

/* The bar's pixels, written straight into the layer: left half the
 * colour of its row (a->rows), right half that colour at its opacity
 * over a checkerboard. */
static void legend_bar(struct tvpal_annot *a, const struct tvpal_annot_legend *L)
{
    cairo_surface_flush(a->cur->surf);
    for (unsigned r = 0; r < L->h; r++) {
        const int y = (int)L->y0 + (int)r;
        if (y < 0 || y >= (int)a->H)
            continue;
        const float *c = a->rows[r];
        const double op = c[3] < 0 ? 0 : c[3] > 1 ? 1 : c[3];
        uint32_t *row = (uint32_t *)(void *)(a->cur->px + (size_t)y * a->stride);
        for (unsigned i = 0; i < L->w; i++) {
            const unsigned x = L->x0 + i;
            if (x >= a->W)
                continue;
            if (i < L->swatch_w) {
                row[x] = argb(c[0], c[1], c[2]);
                continue;
            }
            const double ck = ((x / 4 + (unsigned)y / 4) & 1) ? 0.75 : 0.45;
            row[x] = argb(c[0] * op + ck * (1 - op), c[1] * op + ck * (1 - op),
                          c[2] * op + ck * (1 - op));
        }
    }
    cairo_surface_mark_dirty(a->cur->surf);
    dirty_add(a, L->x0, L->y0, L->x0 + L->w, L->y0 + L->h);
}

/* Convex hull of the n <= 8 points p (x, y), counter-clockwise, into h
 * (monotone chain); its number of points (fewer than 3: no area). */
static unsigned hull8(double p[8][2], unsigned n, double h[16][2])
{
    for (unsigned i = 1; i < n; i++) /* sort by x, then y (8 points) */
        for (unsigned j = i; j > 0 && (p[j][0] < p[j - 1][0] ||
                                       (p[j][0] == p[j - 1][0] &&
                                        p[j][1] < p[j - 1][1])); j--) {
            double t0 = p[j][0], t1 = p[j][1];
            p[j][0] = p[j - 1][0], p[j][1] = p[j - 1][1];
            p[j - 1][0] = t0, p[j - 1][1] = t1;
        }
    unsigned k = 0;
#define CROSS(o, a, b) (((a)[0] - (o)[0]) * ((b)[1] - (o)[1]) -              \
                        ((a)[1] - (o)[1]) * ((b)[0] - (o)[0]))
    for (unsigned i = 0; i < n; i++) {
        while (k >= 2 && CROSS(h[k - 2], h[k - 1], p[i]) <= 0)
            k--;
        h[k][0] = p[i][0], h[k][1] = p[i][1], k++;
    }
    for (unsigned i = n - 1, t = k + 1; i-- > 0;) {
        while (k >= t && CROSS(h[k - 2], h[k - 1], p[i]) <= 0)
            k--;
        h[k][0] = p[i][0], h[k][1] = p[i][1], k++;
    }
    return k > 1 ? k - 1 : k;
}

/* Whether (x, y) is inside the counter-clockwise convex polygon h of n
 * points (n >= 3). */
static int in_hull(const double h[16][2], unsigned n, double x, double y)
{
    const double q[2] = {x, y};
    for (unsigned i = 0; i < n; i++)
        if (CROSS(h[i], h[(i + 1) % n], q) < 0)
            return 0;
    return 1;
#undef CROSS
}

/* How much of the rectangle [x0, x1) x [y0, y1) (row 0 at the top) the
 * volume's projection, the hull h of n points, covers: of 12 x 12 points
 * spread over it, those inside. */
static unsigned covered(const double h[16][2], unsigned n, double x0,
                        double y0, double x1, double y1)
{
    unsigned count = 0;
    for (unsigned i = 0; n >= 3 && i < 12; i++)
        for (unsigned j = 0; j < 12; j++)
            count += in_hull(h, n, x0 + (x1 - x0) * (j + 0.5) / 12,
                             y0 + (y1 - y0) * (i + 0.5) / 12);
    return count;
}

/* The legend's place for f: L's x0 and y0, its bar being L->w x L->h with
 * labels label_w wide to its right (tvpal_annot.h, enum
 * tvpal_annot_place). */
static void legend_place(const struct tvpal_annot *a,
                         const struct tvpal_annot_frame *f, double label_w,
                         struct tvpal_annot_legend *L)
{
    const double m = a->fs * 0.8, gap = a->fs * 0.4;
    const double width = L->w + 2 * gap + label_w;
    const double above = f->title && *f->title ? a->fs * 1.6 : 0;
    const double right = a->W - m - width, middle = (a->H - (double)L->h) / 2;
    const double xy[TVPAL_ANNOT_PLACES][2] = {
        [TVPAL_ANNOT_PLACE_RIGHT] = {right, middle},
        [TVPAL_ANNOT_PLACE_RIGHT_TOP] = {right, m + above},
        [TVPAL_ANNOT_PLACE_RIGHT_BOTTOM] = {right, a->H - m - (double)L->h},
        [TVPAL_ANNOT_PLACE_LEFT] = {m, middle}};
    unsigned pick = f->legend_place;
    if (pick == TVPAL_ANNOT_PLACE_AUTO || pick >= TVPAL_ANNOT_PLACES) {
        double p[8][2], h[16][2]; /* the box's corners, row 0 at the top */
        for (unsigned c = 0; c < 8; c++)
            p[c][0] = f->corner[c][0], p[c][1] = a->H - f->corner[c][1];
        const unsigned n = hull8(p, 8, h);
        unsigned least = ~0u;
        for (unsigned k = TVPAL_ANNOT_PLACE_RIGHT; k < TVPAL_ANNOT_PLACES;
             k++) {
            const unsigned c = covered(h, n, xy[k][0], xy[k][1] - above,
                                       xy[k][0] + width, xy[k][1] + L->h);
            if (c < least)
                least = c, pick = k;
        }
    }
    const double x0 = xy[pick][0], y0 = xy[pick][1];
    const double ymax = (double)a->H - L->h;
    L->x0 = x0 > 0 ? (unsigned)x0 : 0;
    L->y0 = y0 <= 0 ? 0 : y0 > ymax ? (unsigned)ymax : (unsigned)y0;
}

/* The legend's layout for f into L, and each bar row's colour into
 * a->rows (nothing drawn). */
static int legend_layout(struct tvpal_annot *a,
                         const struct tvpal_annot_frame *f,
                         struct tvpal_annot_legend *L, struct tvpal_diag *diag)
{
    double ticks[TVPAL_ANNOT_MAX_TICKS];
    struct scale s;
    if (make_scale(f, fmin(320.0, floor(a->H * 0.45)), ticks, &L->nticks,
                   &s) < 0)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "annotations: legend "
                              "range [%g, %g] has no ticks", f->vmin, f->vmax);
    double label_w = 0;
    for (unsigned i = 0; i < L->nticks; i++) {
        const double c = scale_value(&s, (long)i * s.q);
        L->tick_value[i] = bar_value(f, c);
        if (f->log_scale) /* as few digits as tell decades apart */
            snprintf(L->tick_label[i], sizeof L->tick_label[i], "%.3g",
                     L->tick_value[i]);
        else
            tvpal_annot_tick_label(c, s.step, L->tick_label[i],
                                   sizeof L->tick_label[i]);
        label_w = fmax(label_w, text_width(a, L->tick_label[i]));
    }
    L->w = 2 * (unsigned)lround(a->fs * 0.7);
    L->swatch_w = L->w / 2;
    L->h = (unsigned)(s.kmax - s.kmin + 1);
    L->h = L->h > a->H ? a->H : L->h;
    legend_place(a, f, label_w, L);
    L->swatch_x0 = L->x0;
    for (unsigned i = 0; i < L->nticks; i++)
        L->tick_row[i] = L->y0 + (unsigned)(s.kmax - (long)i * s.q);
    for (unsigned r = 0; r < L->h; r++)
        f->colour(f->colour_ctx, bar_value(f, scale_value(&s, s.kmax - (long)r)),
                  a->rows[r]);
    return 0;
}

/* Whether the legend held in a->lg shows f with layout L. */
static int legend_cached(const struct tvpal_annot *a,
                         const struct tvpal_annot_frame *f,
                         const struct tvpal_annot_legend *L)
{
    const char *title = f->title ? f->title : "";
    return a->lg_valid && a->lg_log == f->log_scale &&
           L->x0 == a->legend.x0 && L->y0 == a->legend.y0 &&
           a->lg_range[0] == f->vmin &&
           a->lg_range[1] == f->vmax && L->h == a->legend.h &&
           !memcmp(a->lg_fg, f->fg, sizeof a->lg_fg) &&
           !memcmp(a->lg_halo, f->halo, sizeof a->lg_halo) &&
           !strncmp(a->lg_title, title, sizeof a->lg_title) &&
           !memcmp(a->lg_rows, a->rows, L->h * sizeof *a->rows);
}

/* Draws the legend of layout L into a->lg and remembers what it shows. */
static void legend_render(struct tvpal_annot *a,
                          const struct tvpal_annot_frame *f,
                          const struct tvpal_annot_legend *L)
{
    struct layer *lg = &a->lg;
    const struct box old = a->lg_box;
    for (int y = old.y0; y < old.y1; y++)
        memset(lg->px + (size_t)y * a->stride + 4 * (size_t)old.x0, 0,
               4 * (size_t)(old.x1 - old.x0));
    cairo_surface_mark_dirty(lg->surf);
    a->cur = lg;
    lg->dirty = (struct box){0, 0, 0, 0};
    legend_bar(a, L);
    /* A frame just outside the bar, tick marks and labels beside it. */
    cairo_t *cr = lg->cr;
    cairo_new_path(cr);
    cairo_rectangle(cr, L->x0 - 0.5, L->y0 - 0.5, L->w + 1.0, L->h + 1.0);
    cairo_set_line_width(cr, 1.0);
    cairo_set_source_rgb(cr, f->fg[0], f->fg[1], f->fg[2]);
    dirty_stroke(a);
    cairo_stroke(cr);
    const double m = a->fs * 0.8, gap = a->fs * 0.4;
    const double xr = L->x0 + L->w + 0.5;
    for (unsigned i = 0; i < L->nticks; i++) {
        const double y = L->tick_row[i] + 0.5;
        line(a, xr, y, xr + gap, y, 1.0, f->fg);
        text(a, xr + 2 * gap, y + ascent(a) / 2, L->tick_label[i], f->fg,
             f->halo);
    }
    const char *title = f->title ? f->title : "";
    if (*title) {
        const double tx = fmin(L->x0, a->W - m - text_width(a, title));
        text(a, fmax(tx, m), L->y0 - a->fs * 0.6, title, f->fg, f->halo);
    }
    cairo_surface_flush(lg->surf);
    a->lg_box = lg->dirty;
    a->cur = &a->ov;
    a->lg_valid = 1;
    a->lg_log = f->log_scale;
    a->lg_range[0] = f->vmin;
    a->lg_range[1] = f->vmax;
    memcpy(a->lg_fg, f->fg, sizeof a->lg_fg);
    memcpy(a->lg_halo, f->halo, sizeof a->lg_halo);
    snprintf(a->lg_title, sizeof a->lg_title, "%s", title);
    memcpy(a->lg_rows, a->rows, L->h * sizeof *a->rows);
}

/* The legend onto the overlay: drawn again only when it changed. */
static int draw_legend(struct tvpal_annot *a, const struct tvpal_annot_frame *f,
                       struct tvpal_diag *diag)
{
    struct tvpal_annot_legend L = {0};
    int rc = legend_layout(a, f, &L, diag);
    if (rc < 0)
        return rc;
    if (!legend_cached(a, f, &L))
        legend_render(a, f, &L);
    L.shown = 1;
    a->legend = L;
    over_overlay(a, &a->lg, a->lg_box);
    return 0;
}

/* ------------------------------------------------- outline and triad */

static void draw_outline(struct tvpal_annot *a,
                         const struct tvpal_annot_frame *f)
{
    cairo_t *cr = a->cur->cr;
    cairo_new_path(cr);
    for (unsigned c = 0; c < 8; c++)
        for (unsigned bit = 1; bit < 8; bit <<= 1) {
            if (c & bit)
                continue;   /* each edge once, from its lower corner */
            const unsigned e = c | bit;
            cairo_move_to(cr, f->corner[c][0], a->H - f->corner[c][1]);
            cairo_line_to(cr, f->corner[e][0], a->H - f->corner[e][1]);
        }
    cairo_set_line_width(cr, 1.5);
    cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
    cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
    cairo_set_source_rgb(cr, f->fg[0], f->fg[1], f->fg[2]);
    dirty_stroke(a);
    cairo_stroke(cr);
}

static void draw_triad(struct tvpal_annot *a, const struct tvpal_annot_frame *f)
{
    static const float col[3][3] = {{0.95f, 0.25f, 0.2f},
                                    {0.3f, 0.85f, 0.3f},
                                    {0.35f, 0.55f, 1.0f}};
    static const char *const name[3] = {"x", "y", "z"};
    const double len = 2.5 * a->fs, m = a->fs * 0.8;
    const double ox = m + len + a->fs * 0.5, oy = a->H - m - len - a->fs * 0.5;
    for (int i = 0; i < 3; i++) {
        const double dx = f->axis_dir[i][0] * len, dy = -f->axis_dir[i][1] * len;
        line(a, ox, oy, ox + dx, oy + dy, 3.5, f->halo);
        line(a, ox, oy, ox + dx, oy + dy, 2.0, col[i]);
    }
    for (int i = 0; i < 3; i++) {
        const double dx = f->axis_dir[i][0], dy = -f->axis_dir[i][1];
        const double tx = ox + dx * (len + a->fs * 0.6) -
                          text_width(a, name[i]) / 2;
        const double ty = oy + dy * (len + a->fs * 0.6) + ascent(a) / 2;
        text(a, tx, ty, name[i], col[i], f->halo);
    }
}

/* -------------------------------------------------------------- entry */

int tvpal_annot_draw(struct tvpal_annot *a, const struct tvpal_annot_frame *f,
                     uint8_t *frame, struct tvpal_diag *diag)
{
    a->cur = &a->ov;
    a->legend.shown = 0;
    if (!f->what)
        return 0;
    double tk[TVPAL_ANNOT_MAX_TICKS], step;
    if ((f->what & TVPAL_ANNOT_LEGEND) &&
        (!f->colour || !tvpal_annot_ticks(f->vmin, f->vmax, 5, 8, tk, &step)))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "annotations: legend "
                              "range [%g, %g] or colours missing", f->vmin,
                              f->vmax);
    int rc = 0;
    /* Lines first: the legend and the text stay readable on top. */
    if (f->what & TVPAL_ANNOT_OUTLINE)
        draw_outline(a, f);
    if (f->what & TVPAL_ANNOT_TRIAD)
        draw_triad(a, f);
    if ((f->what & TVPAL_ANNOT_LEGEND) && (rc = draw_legend(a, f, diag)) < 0) {
        blend_and_clear(a, frame);
        return rc;
    }
    if ((f->what & TVPAL_ANNOT_TIME) && f->time_text && *f->time_text) {
        const double m = a->fs * 0.8;
        text(a, m, m + ascent(a), f->time_text, f->fg, f->halo);
    }
    rc = cairo_check(cairo_status(a->ov.cr), "drawing failed", diag);
    if (rc == 0)
        rc = cairo_check(cairo_status(a->lg.cr), "legend drawing failed",
                         diag);
    blend_and_clear(a, frame);
    return rc;
}

int tvpal_annot_hud(struct tvpal_annot *a, const char *const *lines,
                    unsigned nlines, const float fg[3], uint8_t *frame,
                    unsigned box[4], struct tvpal_diag *diag)
{
    a->cur = &a->ov;
    const double m = a->fs * 0.5, lh = a->fs * 1.3;
    double w = 0;
    for (unsigned i = 0; i < nlines; i++)
        w = fmax(w, text_width(a, lines[i]));
    const double bw = w + 2 * m, bh = nlines * lh + m;
    /* Top left, under the time's line: clear of the legend (right) and
     * the triad (bottom left). */
    const double x0 = m, y0 = 2 * m + a->fs * 1.6;
    cairo_t *cr = a->cur->cr;
    cairo_new_path(cr);
    cairo_rectangle(cr, x0, y0, bw, bh);
    cairo_set_source_rgba(cr, 0, 0, 0, 0.6);
    dirty_add(a, x0, y0, x0 + bw, y0 + bh);
    cairo_fill(cr);
    cairo_set_source_rgb(cr, fg[0], fg[1], fg[2]);
    for (unsigned i = 0; i < nlines; i++) {
        cairo_move_to(cr, x0 + m, y0 + m / 2 + (i + 1) * lh - (lh - ascent(a)));
        char buf[TEXT_MAX];
        cairo_show_text(cr, drawable(lines[i], buf));
    }
    if (box) {
        box[0] = (unsigned)x0;
        box[1] = (unsigned)y0;
        box[2] = (unsigned)ceil(bw);
        box[3] = (unsigned)ceil(bh);
    }
    int rc = cairo_check(cairo_status(cr), "HUD drawing failed", diag);
    blend_and_clear(a, frame);
    return rc;
}

void tvpal_annot_legend(const struct tvpal_annot *a,
                        struct tvpal_annot_legend *out)
{
    *out = a->legend;
}
