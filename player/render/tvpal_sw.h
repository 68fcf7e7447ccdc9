/* tvpal_sw.h: the CPU palette renderer by shear-warp factorization
 * (Lacroute & Levoy, SIGGRAPH 1994), for nodes without a GPU.
 *
 * Axis-aligned slices under an orthographic view make the factorization
 * exact: each slice is translated onto an intermediate image aligned with
 * the slices (the translation grows linearly with the slice's depth), and
 * one 2D affine warp maps that image to the output with bilinear filtering.
 * The intermediate image has K pixels per texel, a whole number: by default
 * ceil(output pixels per texel - 0.25), 1 to 4 (zoomed-in views stay
 * sharp), or forced to 1..8 (tvpal_sw_set_scale).  K whole makes the
 * bilinear weights of a slice row the same for every texel: K fixed phases.  Slices are composited front to back with the same
 * palette semantics as tvpal_render_ref (four nearest texels looked up in
 * the slice's palette, colours interpolated, premultiplied "over"); only
 * the resampling differs.
 *
 * Only what the frame needs is done.  Each slice is cut into square tiles.
 * Every frame a tile is visible iff it holds an index whose palette entry
 * is not fully transparent, and only runs of visible tiles are composited
 * (a transparent entry is all zero, so skipping adds exactly nothing).  The
 * set of indices a tile holds answers that for any palette; it is built
 * only when a frame needs it: after an upload (tvpal_sw_upload) a tile is
 * first probed at 16 texels, and one visible probe decides it with no set
 * (the index found decides it in later frames while it stays visible); a
 * tile with none gets its set built, kept until the next upload.
 *
 * Early termination with a bound.  A pixel of the intermediate image stops
 * accumulating once its remaining transmittance T = 1 - alpha is at most
 * 1/272 (alpha >= TVPAL_SW_ALPHA_STOP; 1 - alpha is exact in float above
 * 1/2).  Why that changes no 8-bit output pixel by more than one level.
 * Colours are premultiplied, c <= alpha <= 1 (what the player builds), so
 * all that lies behind the pixel adds T X, X a premultiplied colour in
 * [0, 1]: stopping lowers each channel and alpha by T X, in [0, T], and
 * over a background b the channel c + (1 - alpha) b moves by
 * T (X_c - X_alpha b), in [-T, T].  The warp's bilinear mixes are convex,
 * so they move by at most T too, and the over-compositing of cluster ranks
 * moves a pixel by at most the transmittance in front of the front-most
 * rank that stopped, again <= T.  Two values at most 1/255 apart round to
 * 8 bits (clamped, v * 255 + 0.5 truncated: any monotone rounding) at most
 * one level apart, as floor(u) - floor(w) < u - w + 1 <= 2.  So T could be
 * nearly 1/255; 1/272 leaves 1/255 - 1/272 = 2.45e-4 = 16 steps of 1/65535
 * for rounding: the warp's weights and the 8-bit conversion (about 1e-7
 * each); --exact's own blends behind the stop, which can gain at most half
 * an ulp (3e-8) each beyond what its alpha accounts for (one step per 500
 * slices); and a cluster's messages, 16-bit (tvpal_rle.c), whose rounding
 * adds up to two steps to the difference per message a pixel passes
 * through (one per binary-swap stage; 1/256 would leave one step, not
 * enough for two ranks).  The player rounds premultiplied RGBA to 8 bits
 * before it puts the background behind (tvpal_png_over8): on one node
 * colour and alpha move the same way, by 0 or 1 level each, and
 * c8 + (255 - a8) b moves by at most one level; in a cluster with a
 * background other than black a rank's remainder can darken a pixel while
 * raising its alpha, and the two roundings can add up to two levels (at
 * any threshold).  Float accumulation reaches alpha 1 itself only below a
 * transmittance of about 6e-8, ln(1 / 6e-8) = 16.6 optical depths into the
 * volume; 1/272 is reached at ln 272 = 5.6 (1/510, the earlier threshold,
 * at 6.2), so in a uniformly dense volume a pixel blends about a third of
 * the samples it would without stopping, 10% fewer than at 1/510.
 * tvpal_sw_set_exact(r, 1) stops only at alpha 1 (nothing behind can
 * show): the images of earlier builds.
 *
 * Opaque runs cost nothing: each row keeps a bitmap of its stopped pixels
 * (the job of Lacroute & Levoy's run links over opaque pixels of the
 * intermediate image), so a slice row finds its runs of live pixels by bit
 * scans, 64 pixels a word, jumps over each stopped run at once and
 * composites each live run with no test per pixel; a row whose pixels have
 * all stopped meets no further slice.  The maps change no bit
 * (tvpal_sw_set_runs(r, 0) tests each pixel instead, for tests).
 *
 * Cross frames (tvpal_frame.h: a single-copy dataset's z slices drawn
 * along x or y).  The renderer keeps, per view axis used, a transposed
 * copy of the held z slices' indices (one byte per voxel each, allocated
 * at the first such frame), in which slice s of the view's axis is rows
 * of texels, row b cut from z slice b; a row is cut again only when its
 * layer was uploaded since (tvpal_sw_upload), so steady playback cuts the
 * 1/N of the slices whose windows changed and crossing back to an axis
 * cuts only what changed meanwhile.  The four texels of a sample come from
 * two rows, each looked up in its own z slice's palette, then mixed as
 * always.  Empty space is skipped by tiles derived from the z slices'
 * tiles (a cross tile is visible when a z tile under it is), which is
 * conservative: transparent texels drawn add exactly zero, so the image is
 * that of a plain frame of the transposed slices, bit for bit.
 *
 * Rows of the intermediate image are shared among threads (OpenMP) in
 * bands of a few rows, each band composited by one thread through all
 * slices, a slice through every row of the band before the next (the rows
 * stay in L1, and a slice's palette and index rows are fetched once per
 * band rather than once per row): the image is the same for any thread
 * count and band.  An AVX2 inner loop is chosen
 * at run time where the CPU has AVX2 and FMA; it fuses each multiply with
 * its add, where the SSE2 loop rounds twice, so the two differ in the last
 * bits (and, with early termination, where a pixel's alpha ends next to
 * the stop, by one sample: less than 1/272).  Each loop's own operations
 * are fixed (the player library is built with -ffp-contract=off, so the
 * compiler fuses nothing else).  No allocation per frame once the largest image and the
 * slice set (tvpal_sw_set_slices) have been seen.
 */
#ifndef TVPAL_SW_H
#define TVPAL_SW_H

#include "tvpal_error.h"
#include "tvpal_frame.h"

struct tvpal_sw;

/* Owns *out on success; free with tvpal_sw_free. */
int tvpal_sw_create(struct tvpal_sw **out);
void tvpal_sw_free(struct tvpal_sw *r);   /* NULL is a no-op */

/* Options for tests and benchmarks: threads (0 = OpenMP's default),
 * skip (empty-space skipping and early termination; 1 by default),
 * simd (1: AVX2 and FMA where the CPU has them, the default; 0: SSE2
 * only). */
void tvpal_sw_options(struct tvpal_sw *r, int threads, int skip, int simd);

/* Alpha at which a pixel stops by default: remaining transmittance 1/272
 * (see above). */
#define TVPAL_SW_ALPHA_STOP (1.0f - 1.0f / 272.0f)

/* exact = 1: a pixel stops only at alpha 1 (the images of --exact); 0 (the
 * default): at TVPAL_SW_ALPHA_STOP.  Without skipping no pixel stops. */
void tvpal_sw_set_exact(struct tvpal_sw *r, int exact);

/* runs = 1 (the default): stopped pixels are skipped by runs through the
 * per-row maps; 0: each pixel is tested.  The same image either way. */
void tvpal_sw_set_runs(struct tvpal_sw *r, int runs);

/* Rows of the intermediate image composited together (1..32): each slice
 * goes through a band of rows before the next, so its palette and index
 * rows are fetched once per band.  By default a draw chooses from the L2
 * cache's size (sysconf) and the row length: 4 to 32 rows, the rows
 * taking at most a quarter of L2; 4 where L2 is unknown.  The same image
 * for any band (each pixel meets the same operations in the same order);
 * setting one is for tests and benchmarks.  TVPAL_E_INVAL outside 1..32.
 * tvpal_sw_band: the band of the last draw (0 before any). */
int tvpal_sw_set_band(struct tvpal_sw *r, unsigned rows);
unsigned tvpal_sw_band(const struct tvpal_sw *r);

/* Intermediate pixels per texel: 0 (the default) chooses K from the view
 * (1..4, see above); 1..8 forces it (speed against sharpness: the cost
 * grows as K^2).  TVPAL_E_INVAL for k > 8. */
int tvpal_sw_set_scale(struct tvpal_sw *r, unsigned k);

/* Prepares for `layers` slices of w x h indices (frame slices name their
 * layer, < layers).  Every layer starts as changed.  Allocates; 0 or
 * TVPAL_E_NOMEM / TVPAL_E_INVAL with diag set. */
int tvpal_sw_set_slices(struct tvpal_sw *r, uint32_t w, uint32_t h,
                        uint32_t layers, struct tvpal_diag *diag);

/* The indices of `layer` changed: its tile index sets are rebuilt from the
 * frame's idx pointer the next time it is drawn. */
void tvpal_sw_upload(struct tvpal_sw *r, uint32_t layer);

/* Renders the frame (slices in back-to-front order, as for the other
 * renderers) into width * height RGBA floats, row 0 at the bottom.  The
 * frame's slices must match the last tvpal_sw_set_slices and the view's
 * volume (TVPAL_E_INVAL otherwise); a layer may appear in several frame
 * slices, each with its own palette.  Palette entries are premultiplied;
 * alpha in [0, 1] is what the player builds, larger values are drawn as
 * given (the bound above then does not hold). */
int tvpal_sw_draw(struct tvpal_sw *r, const struct tvpal_frame *f,
                  float *rgba, struct tvpal_diag *diag);

/* Phase times of the last draw (ms): classification (tile index sets of
 * changed slices, visible tiles), compositing, warp. */
void tvpal_sw_times(const struct tvpal_sw *r, double *classify_ms,
                    double *composite_ms, double *warp_ms);

/* What decided the visible tiles of the last draw's slices whose index
 * sets were not current (see "lazily" in tvpal_sw.c): tiles proved
 * visible by the index an earlier probe found (their witness), by a
 * probe, and sets built.  For tests and reports. */
struct tvpal_sw_counts {
    unsigned long witnessed, probed, built;
};
void tvpal_sw_counts(const struct tvpal_sw *r, struct tvpal_sw_counts *c);

/* Intermediate pixels per texel (K) of the last draw, and the inner loops
 * used ("avx2": AVX2 with FMA for K = 1 and 2, SSE2 otherwise; "sse2";
 * "scalar"),
 * for reports. */
unsigned tvpal_sw_scale(const struct tvpal_sw *r);
const char *tvpal_sw_simd_name(const struct tvpal_sw *r);

/* r behind the renderer interface (name "cpu"; times: classify,
 * composite, warp).  r stays owned by the caller. */
void tvpal_sw_renderer(struct tvpal_sw *r, struct tvpal_renderer *out);

#endif
