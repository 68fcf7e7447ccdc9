/* test-annot: the annotations module (tvpal_annot, cairo) on frames it
 * checks pixel by pixel: the legend's rows beside its labels are the
 * transfer function at the labelled values (within one 8-bit level), also
 * when the legend kept from the frame before must be drawn again for a new
 * TF; its ticks are round numbers inside the range; the outline's lines meet at
 * the given corners; nothing is drawn where nothing was asked, and the
 * rest of the frame is left as it was; the HUD stays in its box; labels
 * that are not valid UTF-8 are drawn as their U+FFFD-repaired copies; bad
 * sizes and ranges are refused.  The tick arithmetic is checked in every
 * build; the drawing skips (77), saying so, without cairo. */
#include "tvpal_annot.h"
#include "tvpal_test.h"
#include "tvpal_tf.h"
#include "tvpal_utf8.h"

enum { WD = 320, HT = 240 };

static uint8_t frame[WD * HT * 4], before[WD * HT * 4];

/* Pixel (x, y), y from the top, of a frame whose row 0 is the bottom. */
static const uint8_t *px(const uint8_t *f, unsigned x, unsigned y)
{
    return f + 4 * ((size_t)(HT - 1 - y) * WD + x);
}

static void tf_colour(void *ctx, double v, float rgba[4])
{
    tvpal_tf_eval(ctx, v, rgba);
}

static void check_ticks(void)
{
    double t[TVPAL_ANNOT_MAX_TICKS], step;
    static const double r[][2] = {{0, 1}, {-3.7, 12.2}, {1e-7, 3e-7},
                                  {20, 50}, {-1e6, 1e6}, {0.001, 0.0013},
                                  {5, 5.0000001}};
    for (size_t i = 0; i < sizeof r / sizeof *r; i++) {
        unsigned n = tvpal_annot_ticks(r[i][0], r[i][1], 5, 8, t, &step);
        CHECK(n >= 2 && n <= 8, "[%g, %g]: %u ticks", r[i][0], r[i][1], n);
        double e = floor(log10(step)), m = step / pow(10, e);
        CHECK(fabs(m - 1) < 1e-9 || fabs(m - 2) < 1e-9 || fabs(m - 5) < 1e-9,
              "[%g, %g]: step %g is not 1, 2 or 5 x 10^k", r[i][0], r[i][1],
              step);
        for (unsigned k = 0; k < n; k++) {
            CHECK(t[k] >= r[i][0] && t[k] <= r[i][1], "tick %g outside", t[k]);
            CHECK(fabs(t[k] / step - nearbyint(t[k] / step)) < 1e-6,
                  "tick %g not a multiple of %g", t[k], step);
        }
    }
    CHECK(tvpal_annot_ticks(1, 1, 5, 8, t, &step) == 0, "empty range");
    CHECK(tvpal_annot_ticks(NAN, 1, 5, 8, t, &step) == 0, "NaN");
    CHECK(tvpal_annot_ticks(0, INFINITY, 5, 8, t, &step) == 0, "inf");
    char b[32];
    tvpal_annot_tick_label(0.30000000000000004, 0.1, b, sizeof b);
    CHECK(!strcmp(b, "0.3"), "label %s", b);
    tvpal_annot_tick_label(-0.0, 0.5, b, sizeof b);
    CHECK(!strcmp(b, "0.0"), "label %s", b);
    tvpal_annot_tick_label(40, 10, b, sizeof b);
    CHECK(!strcmp(b, "40"), "label %s", b);
    tvpal_annot_tick_label(1.5e6, 5e5, b, sizeof b);
    CHECK(!strcmp(b, "1.5e+06"), "label %s", b);
    tvpal_annot_tick_label(2e-7, 1e-7, b, sizeof b);
    CHECK(!strcmp(b, "2e-07"), "label %s", b);
}

/* The legend of tf over [lo, hi]: each tick row's swatch is TF(value). */
static void check_legend(struct tvpal_annot *a, const struct tvpal_tf *tf,
                         double lo, double hi)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_annot_frame f = {.what = TVPAL_ANNOT_LEGEND, .vmin = lo,
                                  .vmax = hi, .log_scale = tf->log_scale,
                                  .colour = tf_colour,
                                  .colour_ctx = (void *)tf, .title = "rho",
                                  .fg = {1, 1, 1}};
    memset(frame, 0, sizeof frame);
    REQUIRE(tvpal_annot_draw(a, &f, frame, &d) == 0, "%s", d.msg);
    struct tvpal_annot_legend L;
    tvpal_annot_legend(a, &L);
    CHECK(L.shown && L.nticks >= 2, "legend shown with %u ticks", L.nticks);
    CHECK(L.h >= HT / 3 && L.y0 + L.h <= HT && L.x0 + L.w <= WD,
          "bar %u,%u %ux%u", L.x0, L.y0, L.w, L.h);
    for (unsigned i = 0; i < L.nticks; i++) {
        float c[4];
        tvpal_tf_eval(tf, L.tick_value[i], c);
        CHECK(L.tick_value[i] >= lo && L.tick_value[i] <= hi, "tick %g",
              L.tick_value[i]);
        CHECK(i == 0 || L.tick_row[i] < L.tick_row[i - 1], "rows go up");
        for (unsigned x = L.swatch_x0; x < L.swatch_x0 + L.swatch_w; x++) {
            const uint8_t *p = px(frame, x, L.tick_row[i]);
            for (int k = 0; k < 3; k++)
                CHECK(fabs(p[k] - c[k] * 255.0) <= 1.0, "label %s (%g), "
                      "column %u, channel %d: %u, TF %.1f", L.tick_label[i],
                      L.tick_value[i], x, k, p[k], c[k] * 255.0);
            CHECK(p[3] == 255, "swatch opaque");
        }
    }
    /* Left of the bar, under the time's place and under the triad's: the
     * frame as it was (transparent). */
    CHECK(px(frame, 2, HT / 2)[3] == 0 && px(frame, 5, 5)[3] == 0 &&
          px(frame, 30, HT - 30)[3] == 0, "nothing drawn outside the legend");
}

/* The legend under tf's colours, over several ranges. */
static void check_legends(struct tvpal_annot *a)
{
    struct tvpal_tf tf;
    struct tvpal_diag d = {{0}};
    /* Steep in the middle, so that a label beside the wrong row shows. */
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 0 0 1 0.5\n0.45 0.1 0.2 0.9 0.5\n"
                                "0.55 1 0.8 0 0.5\n1 1 1 1 1\n", 20, 50,
                                &tf, &d) == 0, "%s", d.msg);
    check_legend(a, &tf, tf.value[0], tf.value[tf.npoints - 1]);
    check_legend(a, &tf, tf.value[0], tf.value[tf.npoints - 1]); /* kept */
    /* Another TF over the same range: the kept legend is drawn again. */
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 1 0 0 0\n1 0 0 1 1\n", 20, 50,
                                &tf, &d) == 0, "%s", d.msg);
    check_legend(a, &tf, 20, 50);
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 1 0 0 0\n1 0 0 1 1\n", -3.7e-5, 2.2e-4,
                                &tf, &d) == 0, "%s", d.msg);
    check_legend(a, &tf, tf.value[0], tf.value[tf.npoints - 1]);
    check_legend(a, &tf, -1e6, 3e6);
    /* A log-scale TF over six decades: a log bar, ticks at whole decades
     * (a linear bar would put 1..1e5 in its lowest rows), each row beside
     * a label the TF's colour at that value. */
    REQUIRE(tvpal_tf_parse_text("scale log\ndomain normalized\n0 0 0 1 0.5\n"
                                "0.5 1 1 1 0.5\n1 1 0 0 1\n", 1, 1e6,
                                &tf, &d) == 0, "%s", d.msg);
    check_legend(a, &tf, 1, 1e6);
    struct tvpal_annot_legend L;
    tvpal_annot_legend(a, &L);
    CHECK(L.nticks >= 4, "log legend: %u ticks", L.nticks);
    for (unsigned i = 0; i < L.nticks; i++) {
        const double e = log10(L.tick_value[i]);
        CHECK(fabs(e - nearbyint(e)) < 1e-9, "log tick %g is a power of ten",
              L.tick_value[i]);
    }
    /* Evenly spaced decades: rows between successive ticks agree. */
    for (unsigned i = 2; i < L.nticks; i++)
        CHECK(L.tick_row[i - 2] - L.tick_row[i - 1] ==
              L.tick_row[i - 1] - L.tick_row[i], "decades evenly spaced");
}

/* An outline's lines meet at the corners of a box (half extents 1, 0.8,
 * 0.6 turned 20 degrees about x, then 30 about y, 90 pixels per unit,
 * centred); just outside its silhouette's corners, nothing. */
static void check_outline(struct tvpal_annot *a)
{
    struct tvpal_annot_frame f = {.what = TVPAL_ANNOT_OUTLINE,
                                  .fg = {1, 1, 1}};
    const double ca = cos(20 * M_PI / 180), sa = sin(20 * M_PI / 180),
                 cb = cos(30 * M_PI / 180), sb = sin(30 * M_PI / 180);
    double ez[8], off[8][2];
    int near = 0, far = 0;
    for (int c = 0; c < 8; c++) {
        double x = c & 1 ? 1 : -1, y = c & 2 ? 0.8 : -0.8, z = c & 4 ? 0.6 : -0.6;
        double y1 = ca * y - sa * z, z1 = sa * y + ca * z;   /* Rx */
        double x2 = cb * x + sb * z1, z2 = -sb * x + cb * z1; /* Ry */
        off[c][0] = 90 * x2;
        off[c][1] = 90 * y1;
        ez[c] = z2;
        f.corner[c][0] = 160 + off[c][0];
        f.corner[c][1] = 120 + off[c][1];
        near = ez[c] > ez[near] ? c : near;
        far = ez[c] < ez[far] ? c : far;
    }
    struct tvpal_diag d = {{0}};
    memset(frame, 0, sizeof frame);
    REQUIRE(tvpal_annot_draw(a, &f, frame, &d) == 0, "%s", d.msg);
    for (int c = 0; c < 8; c++) {
        unsigned x = (unsigned)f.corner[c][0];
        unsigned y = HT - 1 - (unsigned)f.corner[c][1];
        CHECK(px(frame, x, y)[0] >= 128, "corner %d at (%u, %u): %u", c, x,
              y, px(frame, x, y)[0]);
        if (c == near || c == far)
            continue;   /* inside the silhouette */
        /* 4 pixels further from the centre: past the lines' ends. */
        double dx = off[c][0], dy = off[c][1], n = sqrt(dx * dx + dy * dy);
        unsigned ox = (unsigned)(f.corner[c][0] + 4 * dx / n);
        unsigned oy = HT - 1 - (unsigned)(f.corner[c][1] + 4 * dy / n);
        CHECK(px(frame, ox, oy)[3] == 0, "outside corner %d (%u, %u): %u", c,
              ox, oy, px(frame, ox, oy)[3]);
    }
    CHECK(px(frame, 10, 10)[3] == 0, "no legend, no time asked");
}

/* Nothing asked: the frame is untouched; the HUD stays in its box. */
static void check_untouched_and_hud(struct tvpal_annot *a)
{
    for (size_t i = 0; i < sizeof frame; i++)
        before[i] = (uint8_t)tt_rand64();
    memcpy(frame, before, sizeof frame);
    struct tvpal_annot_frame f = {0};
    struct tvpal_diag d = {{0}};
    CHECK(tvpal_annot_draw(a, &f, frame, &d) == 0, "%s", d.msg);
    CHECK(!memcmp(frame, before, sizeof frame), "what = 0 changed the frame");
    const char *lines[] = {"step 3/8", "TF warm", "12.5 fps"};
    static const float fg[3] = {1, 1, 1};
    unsigned box[4];
    CHECK(tvpal_annot_hud(a, lines, 3, fg, frame, box, &d) == 0, "%s", d.msg);
    CHECK(box[0] + box[2] <= WD && box[1] + box[3] <= HT && box[2] > 20 &&
          box[3] > 20, "HUD box %u,%u %ux%u", box[0], box[1], box[2], box[3]);
    size_t changed_in = 0, changed_out = 0;
    for (unsigned y = 0; y < HT; y++)
        for (unsigned x = 0; x < WD; x++) {
            int in = x >= box[0] && x < box[0] + box[2] && y >= box[1] &&
                     y < box[1] + box[3];
            int ch = memcmp(px(frame, x, y), px(before, x, y), 4) != 0;
            changed_in += in && ch;
            changed_out += !in && ch;
        }
    CHECK(changed_out == 0, "HUD changed %zu pixels outside its box",
          changed_out);
    CHECK(changed_in > (size_t)box[2] * box[3] / 2, "HUD box drawn (%zu)",
          changed_in);
}

/* Labels read from files that are not valid UTF-8 (a Latin-1 "\xb0C"
 * units attribute) are drawn, each invalid byte as U+FFFD, exactly as the
 * repaired string is: the frame never fails for a label. */
static void check_bad_utf8(struct tvpal_annot *a)
{
    static const char *bad[] = {"T [\xb0" "C]", "\xff\xfe", "a\xe2\x82",
                                "\xed\xa0\x80 surrogate",
                                "\xc0\xaf overlong"};
    static uint8_t want[WD * HT * 4];
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        char fixed[64];
        CHECK(tvpal_utf8_repair(fixed, sizeof fixed, bad[i]) > 0 &&
              !fixed[tvpal_utf8_valid_prefix(fixed)], "%zu repaired", i);
        struct tvpal_diag d = {{0}};
        struct tvpal_tf tf;
        REQUIRE(tvpal_tf_parse_text("domain normalized\n0 1 0 0 0\n1 0 0 1 "
                                    "1\n", 0, 1, &tf, &d) == 0, "%s", d.msg);
        struct tvpal_annot_frame f = {.what = TVPAL_ANNOT_LEGEND |
                                              TVPAL_ANNOT_TIME,
                                      .vmin = 0, .vmax = 1,
                                      .colour = tf_colour,
                                      .colour_ctx = &tf, .title = fixed,
                                      .time_text = fixed, .fg = {1, 1, 1}};
        memset(want, 0, sizeof want);
        CHECK(tvpal_annot_draw(a, &f, want, &d) == 0, "repaired: %s", d.msg);
        f.title = f.time_text = bad[i];
        memset(frame, 0, sizeof frame);
        CHECK(tvpal_annot_draw(a, &f, frame, &d) == 0, "label %zu not valid "
              "UTF-8: %s", i, d.msg);
        CHECK(!memcmp(frame, want, sizeof frame), "label %zu drawn as its "
              "repaired copy", i);
        const char *lines[] = {bad[i]};
        static const float fg[3] = {1, 1, 1};
        CHECK(tvpal_annot_hud(a, lines, 1, fg, frame, NULL, &d) == 0,
              "HUD line %zu: %s", i, d.msg);
    }
}

static void check_errors(struct tvpal_annot *a)
{
    struct tvpal_annot *b = NULL;
    struct tvpal_diag d = {{0}};
    CHECK(tvpal_annot_create(&b, 0, 10, &d) == TVPAL_E_INVAL && !b,
          "zero width refused");
    CHECK(tvpal_annot_create(&b, 10, TVPAL_ANNOT_MAX_SIDE + 1, &d) ==
              TVPAL_E_INVAL && strstr(d.msg, "expected"), "%s", d.msg);
    struct tvpal_annot_frame f = {.what = TVPAL_ANNOT_LEGEND, .vmin = 2,
                                  .vmax = 2, .colour = tf_colour};
    CHECK(tvpal_annot_draw(a, &f, frame, &d) == TVPAL_E_INVAL, "empty range");
    f.vmax = 3;
    f.colour = NULL;
    CHECK(tvpal_annot_draw(a, &f, frame, &d) == TVPAL_E_INVAL, "no colours");
    tvpal_annot_free(NULL);
}

/* The legend's places: each explicit one where it says, and AUTO off a
 * box that covers the right edge (the first place that covers least),
 * at the right (as before places existed) where nothing is in the way. */
static void check_places(struct tvpal_annot *a)
{
    struct tvpal_tf tf;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 1 0 0 0\n1 0 0 1 1\n",
                                0, 1, &tf, &d) == 0, "%s", d.msg);
    struct tvpal_annot_frame f = {.what = TVPAL_ANNOT_LEGEND, .vmin = 0,
                                  .vmax = 1, .colour = tf_colour,
                                  .colour_ctx = &tf, .title = "rho",
                                  .fg = {1, 1, 1}};
    struct tvpal_annot_legend L[TVPAL_ANNOT_PLACES];
    for (unsigned k = 0; k < TVPAL_ANNOT_PLACES; k++) {
        f.legend_place = k;
        REQUIRE(tvpal_annot_draw(a, &f, frame, &d) == 0, "%s", d.msg);
        tvpal_annot_legend(a, &L[k]);
    }
    const struct tvpal_annot_legend *r = &L[TVPAL_ANNOT_PLACE_RIGHT],
                                    *rt = &L[TVPAL_ANNOT_PLACE_RIGHT_TOP],
                                    *rb = &L[TVPAL_ANNOT_PLACE_RIGHT_BOTTOM],
                                    *l = &L[TVPAL_ANNOT_PLACE_LEFT];
    CHECK(r->x0 > WD / 2 && rt->x0 == r->x0 && rb->x0 == r->x0 &&
              l->x0 < WD / 4, "x: right %u, left %u", r->x0, l->x0);
    CHECK(rt->y0 < r->y0 && r->y0 < rb->y0 && l->y0 == r->y0 &&
              rb->y0 + rb->h <= HT && rt->y0 >= 16,
          "y: top %u, middle %u, bottom %u", rt->y0, r->y0, rb->y0);
    CHECK(L[TVPAL_ANNOT_PLACE_AUTO].x0 == r->x0 &&
              L[TVPAL_ANNOT_PLACE_AUTO].y0 == r->y0,
          "auto with nothing in the way: at the right");
    /* A box over the right half's lower part (pixel y up from the
     * bottom), which the middle place overlaps: auto goes to the right
     * top, which it leaves clear. */
    static const double box[4][2] = {{WD * 0.55, 0}, {WD, 0},
                                     {WD, HT * 0.45}, {WD * 0.55, HT * 0.45}};
    for (unsigned c = 0; c < 8; c++)
        f.corner[c][0] = box[c % 4][0], f.corner[c][1] = box[c % 4][1];
    f.legend_place = TVPAL_ANNOT_PLACE_AUTO;
    REQUIRE(tvpal_annot_draw(a, &f, frame, &d) == 0, "%s", d.msg);
    struct tvpal_annot_legend got;
    tvpal_annot_legend(a, &got);
    CHECK(got.x0 == rt->x0 && got.y0 == rt->y0, "auto beside a box over the "
          "right middle: at %u,%u, the right top %u,%u expected", got.x0,
          got.y0, rt->x0, rt->y0);
    /* A box over the whole right edge: the left. */
    static const double tall[4][2] = {{WD * 0.6, 0}, {WD, 0}, {WD, HT},
                                      {WD * 0.6, HT}};
    for (unsigned c = 0; c < 8; c++)
        f.corner[c][0] = tall[c % 4][0], f.corner[c][1] = tall[c % 4][1];
    REQUIRE(tvpal_annot_draw(a, &f, frame, &d) == 0, "%s", d.msg);
    tvpal_annot_legend(a, &got);
    CHECK(got.x0 == l->x0 && got.y0 == l->y0, "auto beside a box over the "
          "right edge: at %u,%u, the left %u,%u expected", got.x0, got.y0,
          l->x0, l->y0);
}

int main(void)
{
    check_ticks();
    if (!tvpal_annot_available()) {
        printf("test-annot: drawing skipped: %s\n", tvpal_annot_describe());
        return tt_failures ? tt_done("test-annot") : 77;
    }
    struct tvpal_annot *a;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_annot_create(&a, WD, HT, &d) == 0, "%s", d.msg);
    check_legends(a);
    check_places(a);
    check_outline(a);
    check_untouched_and_hud(a);
    check_bad_utf8(a);
    check_errors(a);
    tvpal_annot_free(a);
    return tt_done("test-annot");
}
