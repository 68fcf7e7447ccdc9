/* tvpal_view.h: view geometry shared by every renderer (GL-free).
 *
 * Object space: the volume is the box centred at the origin whose sides are
 * proportional to its physical extents dims[i] * spacing[i], the longest
 * one spanning [-1, 1]; voxel (i, j, k) has its centre at
 * ((i + 0.5) / nx - 0.5) * 2 half[0], ... (half[i]: the half extent).
 * The view rotates the volume by ax degrees about x, then ay about y, and
 * projects orthographically along -z onto [-1, 1]^2 / zoom, widened for
 * the image aspect ratio.  Rays go along -z in eye space.
 *
 * A named view (tvpal_view_orient) puts the volume in its orientation
 * first: then the rotation is Ry(ay) Rx(ax) O, and with ax = ay = 0
 * exactly O, whose entries are 0 and +-1 for the views along an axis.
 *
 * Slices of the axis most orthogonal to the view are drawn back to front.
 * That axis is chosen as shear-warp chooses it, in voxel units: the one
 * along which a ray crosses the most slices per unit length (the view
 * direction's component over the voxel size), so that consecutive slices
 * shift by at most about a voxel; where another axis comes within
 * TVPAL_VIEW_AXIS_BAND of it and has at least twice as many voxels a slice
 * (a volume flat along it, seen obliquely), that one: few large slices
 * draw a thin volume as a continuous sheet, where many thin ones break
 * into stripes at their edges.  force_axis overrides the choice.
 * the TF opacity is per unit of the smallest voxel spacing, corrected for
 * the distance a ray travels between two slices:
 * alpha' = 1 - (1 - alpha)^(gap / |cos theta|), gap = the slice spacing
 * over the smallest spacing (1 on an isotropic grid), or over opacity_unit
 * where that is set.
 */
#ifndef TVPAL_VIEW_H
#define TVPAL_VIEW_H

#include <stdint.h>

#include "tvpal_error.h"

struct tvpal_view {
    uint32_t dims[3];
    double spacing[3];           /* voxel size per axis (physical units, any
                                  * scale); 0 in all three: 1 1 1 */
    double opacity_unit;         /* the length the TF's opacity is per; 0
                                  * (the default): the smallest spacing.  A
                                  * coarser level of detail keeps its finest
                                  * level's, so it looks as opaque */
    unsigned width, height;      /* image size in pixels */
    double ax_deg, ay_deg, zoom;
    int oriented;                /* 1: orient applies (a named view) */
    double orient[3][3];         /* object -> the named view's eye frame */
    unsigned force_axis;         /* 0: the slice axis chosen by the view
                                  * (above); 1, 2, 3: x, y or z always */
    /* derived by tvpal_view_setup */
    double rot[3][3];            /* object -> eye */
    double half[3];              /* half extents of the box per axis */
    double sx, sy;               /* eye units per NDC unit in x and y */
    unsigned axis;               /* slice axis */
    int descending;              /* draw slices from high to low index */
    double dcos;                 /* |view direction . axis| */
    double gap;                  /* slice spacing / smallest spacing (or
                                  * opacity_unit) */
};

/* Named views, as ParaView's camera buttons ("Set view direction to
 * +X"): TVPAL_VIEW_PX looks along +x (from the -x side), TVPAL_VIEW_NX
 * along -x, and so on; TVPAL_VIEW_ISO looks along (-1, -1, -1), from the
 * +x+y+z corner (ParaView's isometric view). */
enum tvpal_view_name {
    TVPAL_VIEW_PX, TVPAL_VIEW_NX, TVPAL_VIEW_PY, TVPAL_VIEW_NY,
    TVPAL_VIEW_PZ, TVPAL_VIEW_NZ, TVPAL_VIEW_ISO, TVPAL_VIEW_NAMES
};

/* "+x", "-x", "+y", "-y", "+z", "-z" or "iso" -> its tvpal_view_name, or
 * -1; and back. */
int tvpal_view_name_parse(const char *s);
const char *tvpal_view_name_str(int name);

/* The axis (0 x, 1 y, 2 z) a named view shows pointing up by default, as
 * ParaView: y for the z views and iso, z for the x and y views. */
int tvpal_view_default_up(int name);

/* The orientation of named view `name` with axis `up` (0..2) pointing up
 * on the screen (for iso: up's projection): rows are the object-space
 * directions of the screen's right, its up and the way towards the
 * viewer.  0, or TVPAL_E_INVAL when up is the view's own axis (or name or
 * up is out of range); orient is then unchanged. */
int tvpal_view_orient(int name, int up, double orient[3][3]);

/* How close (a ratio of slices crossed per unit length, 0..1) another axis
 * must come to the shear-warp axis for its larger slices to be chosen. */
#define TVPAL_VIEW_AXIS_BAND 0.85

/* Zoom range the view honours (tvpal_view_setup clamps to it). */
#define TVPAL_VIEW_ZOOM_MIN 1e-6
#define TVPAL_VIEW_ZOOM_MAX 1e6

/* Fills the derived fields; the derived fields are finite for any input.
 * Meant for: zoom > 0, spacing all 0 (isotropic) or all finite and > 0,
 * width, height and dims >= 1.  Otherwise, safely: a NaN or infinite
 * angle is 0 (a huge one is taken modulo 360), a NaN or non-positive zoom
 * is 1 and the rest is clamped to [TVPAL_VIEW_ZOOM_MIN,
 * TVPAL_VIEW_ZOOM_MAX], invalid spacing is reset to isotropic (0 0 0), a
 * zero width or height gives aspect 1. */
void tvpal_view_setup(struct tvpal_view *v);

/* Object-space corner c (0..3: (0,0), (1,0), (1,1), (0,1) in slice (a, b)
 * coordinates) of slice s of the view's axis, and its eye-space position. */
void tvpal_view_slice_corner(const struct tvpal_view *v, uint32_t s,
                             unsigned c, double eye[3]);

/* Eye-space (x, y) -> pixel coordinates (continuous; pixel centres at
 * integer + 0.5), and back. */
void tvpal_view_eye_to_pixel(const struct tvpal_view *v, double ex, double ey,
                             double *px, double *py);
void tvpal_view_pixel_to_eye(const struct tvpal_view *v, double px, double py,
                             double *ex, double *ey);

/* Opacity correction exponent gap / |cos theta| for the view. */
static inline double tvpal_view_opacity_exponent(const struct tvpal_view *v)
{
    return v->gap / v->dcos;
}

#endif
