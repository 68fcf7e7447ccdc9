/* tvpal_osmesa.c: headless GL context (see tvpal_osmesa.h). */
#define GL_GLEXT_PROTOTYPES 1
#include "tvpal_osmesa.h"

#include <GL/osmesa.h>
#include <stdlib.h>
#include <string.h>

struct tvpal_osmesa {
    OSMesaContext ctx;
    unsigned char buf[16 * 16 * 4];
};

int tvpal_osmesa_create(struct tvpal_osmesa **out, struct tvpal_diag *diag)
{
    static const int attribs[] = {
        OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 0,
        OSMESA_STENCIL_BITS, 0, OSMESA_ACCUM_BITS, 0,
        OSMESA_PROFILE, OSMESA_CORE_PROFILE,
        OSMESA_CONTEXT_MAJOR_VERSION, 3, OSMESA_CONTEXT_MINOR_VERSION, 3, 0};
    struct tvpal_osmesa *c = calloc(1, sizeof *c);
    if (!c)
        return TVPAL_E_NOMEM;
    c->ctx = OSMesaCreateContextAttribs(attribs, NULL);
    if (!c->ctx) {
        free(c);
        return tvpal_diag_set(diag, TVPAL_E_SYS,
                              "OSMesa could not create an OpenGL 3.3 core "
                              "context");
    }
    if (!OSMesaMakeCurrent(c->ctx, c->buf, GL_UNSIGNED_BYTE, 16, 16)) {
        OSMesaDestroyContext(c->ctx);
        free(c);
        return tvpal_diag_set(diag, TVPAL_E_SYS,
                              "OSMesaMakeCurrent failed");
    }
    *out = c;
    return 0;
}

void tvpal_osmesa_free(struct tvpal_osmesa *c)
{
    if (!c)
        return;
    OSMesaDestroyContext(c->ctx);
    free(c);
}
