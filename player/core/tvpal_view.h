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
 * Slices of the axis most orthogonal to the view are drawn back to front;
 * the TF opacity is per unit of the smallest voxel spacing, corrected for
 * the distance a ray travels between two slices:
 * alpha' = 1 - (1 - alpha)^(gap / |cos theta|), gap = the slice spacing
 * over the smallest spacing (1 on an isotropic grid), or over opacity_unit
 * where that is set.
 */
#ifndef TVPAL_VIEW_H
#define TVPAL_VIEW_H

#include <stdint.h>

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
