/* play_renderer.c: see play_renderer.h. */
#include "play_renderer.h"
#include "play.h"

#include <string.h>

int play_gl_is_software(const char *name)
{
    return !name || strstr(name, "llvmpipe") || strstr(name, "softpipe") ||
           strstr(name, "swrast") || strstr(name, "Software") ||
           strstr(name, "software");
}

static int open_gl(struct play_renderer *pr, unsigned width, unsigned height,
                   int need_context, struct tvpal_diag *diag)
{
    int rc = need_context ? tvpal_osmesa_create(&pr->osmesa, diag) : 0;
    if (rc == 0)
        rc = tvpal_glr_create_fb(&pr->glr, width, height, pr->fb_bits, diag);
    if (rc == 0)
        tvpal_glr_renderer(pr->glr, &pr->r);
    return rc;
}

int play_renderer_open(struct play_renderer *pr, int kind, unsigned width,
                       unsigned height, unsigned fb_bits, unsigned cpu_scale,
                       int exact, int need_context, struct tvpal_diag *diag)
{
    memset(pr, 0, sizeof *pr);
    pr->fb_bits = fb_bits;
    switch (kind) {
    case PLAY_REND_NONE:
        tvpal_renderer_none(&pr->r);
        return 0;
    case PLAY_REND_CPU:
        if (tvpal_sw_create(&pr->sw) < 0)
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory");
        tvpal_sw_set_scale(pr->sw, cpu_scale);
        tvpal_sw_set_exact(pr->sw, exact);
        tvpal_sw_renderer(pr->sw, &pr->r);
        return 0;
    case PLAY_REND_REF:
        if (tvpal_ref_create(&pr->ref, (size_t)width * height) < 0)
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory");
        tvpal_ref_renderer(pr->ref, &pr->r);
        return 0;
    default:
        return open_gl(pr, width, height, need_context, diag);
    }
}

int play_renderer_resize(struct play_renderer *pr, unsigned width,
                         unsigned height, struct tvpal_diag *diag)
{
    if (!pr->glr)
        return 0; /* cpu draws any size it is given */
    tvpal_glr_free(pr->glr);
    pr->glr = NULL;
    int rc = tvpal_glr_create_fb(&pr->glr, width, height, pr->fb_bits, diag);
    if (rc == 0)
        tvpal_glr_renderer(pr->glr, &pr->r);
    return rc;
}

void play_renderer_close(struct play_renderer *pr)
{
    tvpal_glr_free(pr->glr);
    tvpal_osmesa_free(pr->osmesa);
    tvpal_sw_free(pr->sw);
    tvpal_ref_free(pr->ref);
    memset(pr, 0, sizeof *pr);
}

const char *play_renderer_describe(const struct play_renderer *pr,
                                   char *buf, size_t cap)
{
    if (pr->r.describe)
        pr->r.describe(pr->r.ctx, buf, cap);
    else if (cap)
        buf[0] = 0;
    return buf;
}
