/* tvpal_osmesa.h: a headless OpenGL 3.3 core context (OSMesa). */
#ifndef TVPAL_OSMESA_H
#define TVPAL_OSMESA_H

#include "tvpal_error.h"

struct tvpal_osmesa;

/* Creates a context (with a small default framebuffer: rendering goes to
 * the renderer's own FBO) and makes it current. */
int tvpal_osmesa_create(struct tvpal_osmesa **out, struct tvpal_diag *diag);
void tvpal_osmesa_free(struct tvpal_osmesa *c);  /* NULL is a no-op */

#endif
