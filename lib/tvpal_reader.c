/* tvpal_reader.c: the reader of tvpal.h over tvpal_dataset.h.
 *
 * Level 0 is opened and checked at tvpal_reader_open; a coarser level
 * (DIR/level-k, FORMAT.md 3.3) and an axis's decoder when first asked
 * for, then kept, so that sequential steps read one record per shard. */
#define _GNU_SOURCE
#include "tvpal.h"

#include "tvpal_dataset.h"
#include "tvpal_manifest.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Levels a reader keeps open: TVPAL_LEVELS_MAX of the manifest, and 0. */
#define LEVELS_CAP 16u

struct level {
    struct tvpal_dataset *ds;
    struct tvpal_volreader *vr[3];
};

struct tvpal_reader {
    char *dir;
    struct level lv[LEVELS_CAP + 1];
    struct tvpal_info info;
};

static void fill_info(struct tvpal_reader *r)
{
    const struct tvpal_manifest *m = &r->lv[0].ds->m;
    struct tvpal_info *in = &r->info;
    memcpy(in->dims, m->dims, sizeof in->dims);
    in->steps = m->steps;
    in->window = m->window;
    in->nodes = m->nodes;
    in->axes = m->axes_mask;
    in->levels = m->levels;
    memcpy(in->spacing, m->spacing, sizeof in->spacing);
    memcpy(in->origin, m->origin, sizeof in->origin);
    in->value_min = m->value_min;
    in->value_max = m->value_max;
    in->times = m->ntimes ? m->times : NULL;
    in->time_units = m->time_units;
    in->units = m->units;
    in->missing = m->missing;
    in->source_bytes = m->source_bytes;
}

int tvpal_reader_open(struct tvpal_reader **out, const char *dir,
                      struct tvpal_diag *diag)
{
    *out = NULL;
    if (!dir)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "no dataset directory");
    struct tvpal_reader *r = calloc(1, sizeof *r);
    if (!r || !(r->dir = strdup(dir))) {
        free(r);
        return TVPAL_E_NOMEM;
    }
    int rc = tvpal_dataset_check_dir(dir, diag);
    if (rc == 0)
        rc = tvpal_dataset_open(&r->lv[0].ds, dir, diag);
    if (rc == 0 && r->lv[0].ds->m.levels > LEVELS_CAP)
        rc = tvpal_diag_set(diag, TVPAL_E_MANIFEST, "%s: %u levels, at most "
                            "%u expected", dir, r->lv[0].ds->m.levels,
                            LEVELS_CAP);
    if (rc < 0) {
        tvpal_reader_close(r);
        return rc;
    }
    fill_info(r);
    *out = r;
    return 0;
}

void tvpal_reader_close(struct tvpal_reader *r)
{
    if (!r)
        return;
    for (unsigned k = 0; k <= LEVELS_CAP; k++) {
        for (unsigned a = 0; a < 3; a++)
            tvpal_volreader_free(r->lv[k].vr[a]);
        tvpal_dataset_close(r->lv[k].ds);
    }
    free(r->dir);
    free(r);
}

const struct tvpal_info *tvpal_reader_info(const struct tvpal_reader *r)
{
    return &r->info;
}

int tvpal_reader_level_dims(const struct tvpal_reader *r, uint32_t level,
                            uint32_t dims[3])
{
    if (level > r->info.levels)
        return TVPAL_E_INVAL;
    for (int a = 0; a < 3; a++) {
        uint32_t d = r->info.dims[a];
        for (uint32_t i = 0; i < level; i++)
            d = (d + 1) / 2;
        dims[a] = d;
    }
    return 0;
}

/* Level k's dataset, opened when first needed; it must be the level the
 * manifest of level 0 says (its dims and steps). */
static int open_level(struct tvpal_reader *r, uint32_t k,
                      struct tvpal_diag *diag)
{
    if (r->lv[k].ds)
        return 0;
    char *ld = NULL;
    if (asprintf(&ld, "%s/level-%u", r->dir, k) < 0)
        return TVPAL_E_NOMEM;
    int rc = tvpal_dataset_open(&r->lv[k].ds, ld, diag);
    uint32_t want[3];
    tvpal_reader_level_dims(r, k, want);
    if (rc == 0 && (memcmp(r->lv[k].ds->m.dims, want, sizeof want) ||
                    r->lv[k].ds->m.steps != r->info.steps))
        rc = tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s: not level %u of "
                            "%s (its dims or steps differ)", ld, k, r->dir);
    if (rc < 0) {
        tvpal_dataset_close(r->lv[k].ds);
        r->lv[k].ds = NULL;
    }
    free(ld);
    return rc;
}

int tvpal_reader_decode(struct tvpal_reader *r, uint32_t t, unsigned axis,
                        uint32_t level, float *dst, struct tvpal_diag *diag)
{
    if (t >= r->info.steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u: the dataset "
                              "has %u", t, r->info.steps);
    if (level > r->info.levels)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "level %u: the dataset "
                              "has levels 0..%u", level, r->info.levels);
    if (axis != 0 && axis != TVPAL_AXIS_X && axis != TVPAL_AXIS_Y &&
        axis != TVPAL_AXIS_Z)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "axis %u: TVPAL_AXIS_X, "
                              "_Y, _Z or 0 expected", axis);
    int rc = open_level(r, level, diag);
    if (rc < 0)
        return rc;
    struct level *lv = &r->lv[level];
    const unsigned a = axis == 0 ? tvpal_dataset_default_axis(lv->ds)
                       : axis == TVPAL_AXIS_X ? 0
                       : axis == TVPAL_AXIS_Y ? 1 : 2;
    if (!lv->vr[a] &&
        (rc = tvpal_volreader_create(&lv->vr[a], lv->ds, a, diag)) < 0)
        return rc;
    return tvpal_volreader_read(lv->vr[a], t, dst, diag);
}
