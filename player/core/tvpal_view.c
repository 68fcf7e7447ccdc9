/* tvpal_view.c: view geometry (see tvpal_view.h). */
#include "tvpal_view.h"

#include <math.h>
#include <string.h>

/* An angle in degrees fit for cos and sin: NaN and infinities are 0; a
 * huge one is reduced modulo 360 first (d * pi would overflow); ordinary
 * ones are kept as they are (the same bits as before). */
static double safe_deg(double d)
{
    if (!isfinite(d))
        return 0;
    return fabs(d) > 1e9 ? fmod(d, 360.0) : d;
}

/* The zoom the view uses: NaN and <= 0 are 1, the rest clamped to
 * [TVPAL_VIEW_ZOOM_MIN, TVPAL_VIEW_ZOOM_MAX] (eye extents stay finite and
 * non-zero). */
static double safe_zoom(double z)
{
    if (!(z > 0))
        return 1.0;
    return z < TVPAL_VIEW_ZOOM_MIN ? TVPAL_VIEW_ZOOM_MIN
         : z > TVPAL_VIEW_ZOOM_MAX ? TVPAL_VIEW_ZOOM_MAX : z;
}

/* Spacing usable as given: all three finite and > 0. */
static int spacing_valid(const double sp[3])
{
    for (int i = 0; i < 3; i++)
        if (!(isfinite(sp[i]) && sp[i] > 0))
            return 0;
    return 1;
}

static const char *const view_names[TVPAL_VIEW_NAMES] = {
    "+x", "-x", "+y", "-y", "+z", "-z", "iso"};

int tvpal_view_name_parse(const char *s)
{
    for (int i = 0; s && i < TVPAL_VIEW_NAMES; i++)
        if (!strcmp(s, view_names[i]))
            return i;
    return -1;
}

const char *tvpal_view_name_str(int name)
{
    return name >= 0 && name < TVPAL_VIEW_NAMES ? view_names[name] : "?";
}

int tvpal_view_default_up(int name)
{
    return name == TVPAL_VIEW_PZ || name == TVPAL_VIEW_NZ ||
                   name == TVPAL_VIEW_ISO ? 1 : 2;
}

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

int tvpal_view_orient(int name, int up, double orient[3][3])
{
    if (name < 0 || name >= TVPAL_VIEW_NAMES || up < 0 || up > 2 ||
        (name != TVPAL_VIEW_ISO && name / 2 == up))
        return TVPAL_E_INVAL;
    double d[3] = {0, 0, 0}, u[3] = {0, 0, 0}, r[3];
    u[up] = 1;
    if (name == TVPAL_VIEW_ISO) {
        /* u minus its part along d, normalized: up's projection. */
        const double k = -1 / sqrt(3.0);
        d[0] = d[1] = d[2] = k;
        for (int i = 0; i < 3; i++)
            u[i] -= k * d[i];
        double n = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        for (int i = 0; i < 3; i++)
            u[i] /= n;
    } else {
        d[name / 2] = name % 2 ? -1 : 1;   /* exact: 0 and +-1 */
    }
    cross(d, u, r);   /* screen right = view direction x up */
    for (int i = 0; i < 3; i++) {
        orient[0][i] = r[i];
        orient[1][i] = u[i];
        orient[2][i] = -d[i];   /* eye z points towards the viewer */
    }
    return 0;
}

/* The slice axis of view direction d (object space) on a grid of dims
 * voxels of size sp (physical units; object units are proportional)
 * (tvpal_view.h): slices crossed per unit length along d, |d[i]| / sp[i];
 * the most, or within TVPAL_VIEW_AXIS_BAND of it an axis with at least
 * twice the voxels a slice.  On an isotropic grid (sp all 1) the first
 * rule is the largest |d[i]|, the first of equals, as it always was. */
static unsigned slice_axis(const uint32_t dims[3], const double sp[3],
                           const double d[3])
{
    double cross[3], area[3];
    unsigned ax = 0;
    for (unsigned i = 0; i < 3; i++) {
        cross[i] = fabs(d[i]) / sp[i];
        area[i] = (double)(dims[(i + 1) % 3] ? dims[(i + 1) % 3] : 1) *
                  (dims[(i + 2) % 3] ? dims[(i + 2) % 3] : 1);
        if (cross[i] > cross[ax])
            ax = i;
    }
    unsigned best = ax;
    for (unsigned i = 0; i < 3; i++)
        if (cross[i] >= TVPAL_VIEW_AXIS_BAND * cross[ax] &&
            area[i] >= 2 * area[ax] && area[i] > area[best])
            best = i;
    return best;
}

void tvpal_view_setup(struct tvpal_view *v)
{
    const double a = safe_deg(v->ax_deg) * M_PI / 180.0,
                 b = safe_deg(v->ay_deg) * M_PI / 180.0;
    const double ca = cos(a), sa = sin(a), cb = cos(b), sb = sin(b);
    /* R = Ry(b) Rx(a) */
    const double rx[3][3] = {{1, 0, 0}, {0, ca, -sa}, {0, sa, ca}};
    const double ry[3][3] = {{cb, 0, sb}, {0, 1, 0}, {-sb, 0, cb}};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int k = 0; k < 3; k++)
                s += ry[i][k] * rx[k][j];
            v->rot[i][j] = s;
        }
    /* A named view's orientation comes first (on the right); without
     * one the angles' matrix is used as it is (the same bits as before
     * named views existed). */
    if (v->oriented) {
        double t[3][3];
        memcpy(t, v->rot, sizeof t);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                v->rot[i][j] = t[i][0] * v->orient[0][j] +
                               t[i][1] * v->orient[1][j] +
                               t[i][2] * v->orient[2][j];
    }
    /* Physical extents; on an isotropic grid the same numbers (and bits)
     * as the voxel counts.  Spacing that is not valid counts as isotropic
     * (all three set to 0, so every user of the view agrees). */
    if (!spacing_valid(v->spacing))
        v->spacing[0] = v->spacing[1] = v->spacing[2] = 0;
    const int iso = v->spacing[0] == 0 && v->spacing[1] == 0 &&
                    v->spacing[2] == 0;
    double ext[3], sp[3], emax = 0, smin = 0;
    for (int i = 0; i < 3; i++) {
        sp[i] = iso ? 1.0 : v->spacing[i];
        ext[i] = (double)v->dims[i] * sp[i];
        emax = ext[i] > emax ? ext[i] : emax;
        smin = i == 0 || sp[i] < smin ? sp[i] : smin;
    }
    for (int i = 0; i < 3; i++)
        v->half[i] = emax > 0 ? ext[i] / emax : 1.0;   /* no voxels: 1 */
    /* View direction in object space: R^T (0, 0, -1). */
    double d[3] = {-v->rot[2][0], -v->rot[2][1], -v->rot[2][2]};
    const unsigned ax = v->force_axis >= 1 && v->force_axis <= 3
                            ? v->force_axis - 1
                            : slice_axis(v->dims, sp, d);
    v->axis = ax;
    v->dcos = fabs(d[ax]);
    v->gap = iso ? 1.0 : v->spacing[ax] / smin;
    if (v->opacity_unit > 0 && isfinite(v->opacity_unit))
        v->gap = (iso ? 1.0 : v->spacing[ax]) / v->opacity_unit;
    /* Farther slices first: larger coordinate along d is farther. */
    v->descending = d[ax] > 0;
    double zoom = safe_zoom(v->zoom);
    double aspect = v->width && v->height
                        ? (double)v->width / (double)v->height : 1.0;
    /* The box's bounding sphere (radius |half|) fits the shorter side. */
    double r = sqrt(v->half[0] * v->half[0] + v->half[1] * v->half[1] +
                    v->half[2] * v->half[2]);
    v->sx = r / zoom * (aspect > 1 ? aspect : 1.0);
    v->sy = r / zoom / (aspect < 1 ? aspect : 1.0);
}

void tvpal_view_slice_corner(const struct tvpal_view *v, uint32_t s,
                             unsigned c, double eye[3])
{
    double p[3];
    const unsigned ax = v->axis;
    const unsigned ua = ax == 0 ? 1 : 0, ub = ax == 2 ? 1 : 2;
    p[ax] = ((s + 0.5) / v->dims[ax] * 2.0 - 1.0) * v->half[ax];
    p[ua] = (c == 1 || c == 2) ? v->half[ua] : -v->half[ua];
    p[ub] = (c >= 2) ? v->half[ub] : -v->half[ub];
    for (int i = 0; i < 3; i++)
        eye[i] = v->rot[i][0] * p[0] + v->rot[i][1] * p[1] +
                 v->rot[i][2] * p[2];
}

void tvpal_view_eye_to_pixel(const struct tvpal_view *v, double ex, double ey,
                             double *px, double *py)
{
    *px = (ex / v->sx + 1.0) * 0.5 * v->width;
    *py = (ey / v->sy + 1.0) * 0.5 * v->height;
}

void tvpal_view_pixel_to_eye(const struct tvpal_view *v, double px, double py,
                             double *ex, double *ey)
{
    *ex = (px / v->width * 2.0 - 1.0) * v->sx;
    *ey = (py / v->height * 2.0 - 1.0) * v->sy;
}
