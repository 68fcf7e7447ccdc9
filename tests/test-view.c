/* test-view: named views (tvpal_view_orient): along an axis the rotation
 * has entries 0 and +-1 only, is proper (det +1) and looks along the named
 * direction with the chosen axis up and screen right = direction x up, so
 * the slice axis is the view's with |cos| exactly 1; iso is orthonormal,
 * looks along (-1,-1,-1) with up's projection up; the angles turn from the
 * named view (ay = 90 from +z is the -x view); bad names and up along the
 * view are refused; without a named view the rotation is Ry(ay) Rx(ax)
 * as before (within 1e-15). */
#include "tvpal_test.h"
#include "tvpal_view.h"

static double det3(double m[3][3])
{
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

static struct tvpal_view named(int name, int up, double ax, double ay)
{
    struct tvpal_view v = {.dims = {24, 20, 16}, .width = 64, .height = 48,
                           .ax_deg = ax, .ay_deg = ay, .zoom = 1,
                           .oriented = 1};
    REQUIRE(tvpal_view_orient(name, up, v.orient) == 0, "%d up %d", name, up);
    tvpal_view_setup(&v);
    return v;
}

static void axis_views(void)
{
    for (int n = 0; n < 6; n++)
        for (int up = 0; up < 3; up++) {
            double o[3][3];
            if (up == n / 2) {
                CHECK(tvpal_view_orient(n, up, o) == TVPAL_E_INVAL,
                      "%s up %c accepted", tvpal_view_name_str(n), "xyz"[up]);
                continue;
            }
            struct tvpal_view v = named(n, up, 0, 0);
            int exact = 1;
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                    exact &= v.rot[i][j] == 0 || fabs(v.rot[i][j]) == 1;
            CHECK(exact, "%s up %c: entries not 0/+-1", tvpal_view_name_str(n),
                  "xyz"[up]);
            CHECK(det3(v.rot) == 1, "%s: det %g", tvpal_view_name_str(n),
                  det3(v.rot));
            /* Looking along d: eye z (towards the viewer) is -d. */
            const double s = n % 2 ? -1 : 1;
            CHECK(v.rot[2][n / 2] == -s, "%s: eye z", tvpal_view_name_str(n));
            CHECK(v.rot[1][up] == 1, "%s: up %c", tvpal_view_name_str(n),
                  "xyz"[up]);
            CHECK(v.axis == (unsigned)(n / 2) && v.dcos == 1,
                  "%s: axis %u, cos %.17g", tvpal_view_name_str(n), v.axis,
                  v.dcos);
            CHECK(v.descending == (s > 0), "%s: slice order",
                  tvpal_view_name_str(n));
        }
    /* +x with z up: -y to the right; +z with y up: -x to the right. */
    struct tvpal_view v = named(TVPAL_VIEW_PX, 2, 0, 0);
    CHECK(v.rot[0][1] == -1, "+x: right is %g y", v.rot[0][1]);
    v = named(TVPAL_VIEW_PZ, 1, 0, 0);
    CHECK(v.rot[0][0] == -1, "+z: right is %g x", v.rot[0][0]);
    /* The angles turn from the named view: +z turned 90 degrees about the
     * screen's vertical looks along -x (up stays y). */
    v = named(TVPAL_VIEW_PZ, 1, 0, 90);
    CHECK(fabs(v.rot[2][0] - 1) < 1e-15 && fabs(v.rot[1][1] - 1) < 1e-15,
          "+z then ay 90: eye z %g %g %g", v.rot[2][0], v.rot[2][1],
          v.rot[2][2]);
}

static void iso_view(void)
{
    for (int up = 0; up < 3; up++) {
        struct tvpal_view v = named(TVPAL_VIEW_ISO, up, 0, 0);
        double e = 0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double d = 0;
                for (int k = 0; k < 3; k++)
                    d += v.rot[i][k] * v.rot[j][k];
                e = fmax(e, fabs(d - (i == j)));
            }
        CHECK(e < 1e-15 && fabs(det3(v.rot) - 1) < 1e-15,
              "iso up %c: not a rotation (%g)", "xyz"[up], e);
        for (int k = 0; k < 3; k++)
            CHECK(fabs(v.rot[2][k] - 1 / sqrt(3.0)) < 1e-15,
                  "iso: eye z %d = %g", k, v.rot[2][k]);
        /* up's projection: the up axis has the largest up component. */
        CHECK(fabs(v.rot[1][up] - sqrt(2.0 / 3)) < 1e-15, "iso up %c: %g",
              "xyz"[up], v.rot[1][up]);
    }
}

static void names_and_angles(void)
{
    static const char *const ok[] = {"+x", "-x", "+y", "-y", "+z", "-z", "iso"};
    for (int i = 0; i < 7; i++) {
        CHECK(tvpal_view_name_parse(ok[i]) == i, "%s", ok[i]);
        CHECK(!strcmp(tvpal_view_name_str(i), ok[i]), "%d", i);
    }
    static const char *const bad[] = {"x", "+X", "", "+x ", "isometric", "+w"};
    for (int i = 0; i < 6; i++)
        CHECK(tvpal_view_name_parse(bad[i]) == -1, "'%s' accepted", bad[i]);
    CHECK(tvpal_view_name_parse(NULL) == -1, "NULL");
    double o[3][3];
    CHECK(tvpal_view_orient(7, 0, o) < 0 && tvpal_view_orient(-1, 0, o) < 0 &&
          tvpal_view_orient(0, 3, o) < 0, "out of range accepted");
    CHECK(tvpal_view_default_up(TVPAL_VIEW_PZ) == 1 &&
          tvpal_view_default_up(TVPAL_VIEW_NX) == 2 &&
          tvpal_view_default_up(TVPAL_VIEW_PY) == 2 &&
          tvpal_view_default_up(TVPAL_VIEW_ISO) == 1, "default up");
    /* No named view: Ry(ay) Rx(ax), bit for bit. */
    struct tvpal_view v = {.dims = {8, 8, 8}, .width = 8, .height = 8,
                           .ax_deg = 20, .ay_deg = 30, .zoom = 1};
    tvpal_view_setup(&v);
    const double a = 20 * M_PI / 180, b = 30 * M_PI / 180;
    const double want[3][3] = {
        {cos(b), sin(b) * sin(a), sin(b) * cos(a)},
        {0, cos(a), -sin(a)},
        {-sin(b), cos(b) * sin(a), cos(b) * cos(a)}};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            CHECK(fabs(v.rot[i][j] - want[i][j]) < 1e-15, "rot[%d][%d]", i, j);
}

int main(void)
{
    axis_views();
    iso_view();
    names_and_angles();
    return tt_done("test-view");
}
