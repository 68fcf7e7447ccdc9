/* tvpal_annot_none.c: annotations in a build without cairo: nothing can
 * be drawn, and create says which Debian package to install (see
 * tvpal_annot.h). */
#include "tvpal_annot.h"

#define TVPAL_ANNOT_WHY "built without cairo (install libcairo2-dev and " \
                        "fonts-dejavu-core and reconfigure)"

int tvpal_annot_available(void)
{
    return 0;
}

const char *tvpal_annot_describe(void)
{
    return TVPAL_ANNOT_WHY;
}

int tvpal_annot_create(struct tvpal_annot **out, unsigned width,
                       unsigned height, struct tvpal_diag *diag)
{
    *out = NULL;
    return tvpal_diag_set(diag, TVPAL_E_SYS, "annotations: " TVPAL_ANNOT_WHY);
}

void tvpal_annot_free(struct tvpal_annot *a) {}

int tvpal_annot_draw(struct tvpal_annot *a, const struct tvpal_annot_frame *f,
                     uint8_t *frame, struct tvpal_diag *diag)
{
    return tvpal_diag_set(diag, TVPAL_E_SYS, "annotations: " TVPAL_ANNOT_WHY);
}

int tvpal_annot_hud(struct tvpal_annot *a, const char *const *lines,
                    unsigned nlines, const float fg[3], uint8_t *frame,
                    unsigned box[4], struct tvpal_diag *diag)
{
    return tvpal_diag_set(diag, TVPAL_E_SYS, "annotations: " TVPAL_ANNOT_WHY);
}

void tvpal_annot_legend(const struct tvpal_annot *a,
                        struct tvpal_annot_legend *out)
{
    *out = (struct tvpal_annot_legend){0};
}
