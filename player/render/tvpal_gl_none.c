/* tvpal_gl_none.c: the GL renderer and OSMesa context of a build without
 * OSMesa: creating either fails and says why (the cpu renderer needs
 * neither); nothing else is reachable. */
#include "tvpal_glr.h"
#include "tvpal_osmesa.h"

#define WHY "built without OSMesa (install libosmesa6-dev and reconfigure); " \
            "use --renderer cpu"

int tvpal_osmesa_create(struct tvpal_osmesa **out, struct tvpal_diag *diag)
{
    (void)out;
    return tvpal_diag_set(diag, TVPAL_E_SYS, "no GL renderer: " WHY);
}

void tvpal_osmesa_free(struct tvpal_osmesa *c) { (void)c; }

int tvpal_glr_create_fb(struct tvpal_glr **out, unsigned width,
                        unsigned height, unsigned fb_bits,
                        struct tvpal_diag *diag)
{
    (void)out, (void)width, (void)height, (void)fb_bits;
    return tvpal_diag_set(diag, TVPAL_E_SYS, "no GL renderer: " WHY);
}

int tvpal_glr_create(struct tvpal_glr **out, unsigned width, unsigned height,
                     struct tvpal_diag *diag)
{
    return tvpal_glr_create_fb(out, width, height, 32, diag);
}

void tvpal_glr_free(struct tvpal_glr *r) { (void)r; }

int tvpal_glr_set_slices(struct tvpal_glr *r, uint32_t w, uint32_t h,
                         uint32_t count, struct tvpal_diag *diag)
{
    (void)r, (void)w, (void)h, (void)count;
    return tvpal_diag_set(diag, TVPAL_E_SYS, "no GL renderer: " WHY);
}

void tvpal_glr_upload(struct tvpal_glr *r, uint32_t layer, const uint8_t *idx)
{
    (void)r, (void)layer, (void)idx;
}

int tvpal_glr_draw(struct tvpal_glr *r, const struct tvpal_frame *f,
                   float *rgba, struct tvpal_diag *diag)
{
    (void)r, (void)f, (void)rgba;
    return tvpal_diag_set(diag, TVPAL_E_SYS, "no GL renderer: " WHY);
}

void tvpal_glr_blit(struct tvpal_glr *r, int x, int y) { (void)r, (void)x, (void)y; }

const char *tvpal_glr_gl_name(void) { return NULL; }

uint64_t tvpal_glr_uploads(const struct tvpal_glr *r)
{
    (void)r;
    return 0;
}

void tvpal_glr_times(const struct tvpal_glr *r, double *upload_ms,
                     double *draw_ms, double *readback_ms)
{
    (void)r;
    *upload_ms = *draw_ms = *readback_ms = 0;
}

/* Never reached with a renderer: tvpal_glr_create fails in this build. */
void tvpal_glr_renderer(struct tvpal_glr *r, struct tvpal_renderer *out)
{
    (void)r;
    *out = (struct tvpal_renderer){.name = "gl"};
}
