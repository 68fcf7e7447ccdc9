/* tvpal_output.c: a dataset's output directory (tvpal_output.h). */
#define _GNU_SOURCE
#include "tvpal_output.h"
#include "tvpal_fs.h"
#include "tvpal_manifest.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int tvpal_output_check(const char *dir, int force, const char *how,
                       struct tvpal_diag *diag)
{
    if (!tvpal_exists(dir))
        return 0;
    if (!force)
        return tvpal_diag_set(diag, TVPAL_E_EXIST, "%s: output already "
                              "exists (%s replace it)", dir, how);
    char *mp = NULL;
    struct tvpal_manifest old;
    if (asprintf(&mp, "%s/manifest.txt", dir) < 0)
        return TVPAL_E_NOMEM;
    int rc = tvpal_manifest_load(mp, &old, NULL);
    free(mp);
    if (rc < 0)
        return tvpal_diag_set(diag, TVPAL_E_EXIST, "%s: exists and is not a "
                              "tvpal dataset (no valid manifest.txt); "
                              "refusing to replace it", dir);
    tvpal_manifest_clear(&old);
    return 0;
}

/* The directory holding path's entry, made durable. */
static void sync_parent(const char *path)
{
    char *parent = strdup(path), *slash = parent ? strrchr(parent, '/')
                                                 : NULL;
    if (slash)
        *slash = 0;
    tvpal_fsync_dir(slash ? (slash == parent ? "/" : parent) : ".");
    free(parent);
}

int tvpal_output_place(const char *partial, const char *dir,
                       struct tvpal_diag *diag)
{
    if (!tvpal_exists(dir)) {
        if (rename(partial, dir) < 0)
            return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot rename %s "
                                  "into place: %s", dir, partial,
                                  strerror(errno));
        sync_parent(dir);
        return 0;
    }
    char *old = NULL;
    if (asprintf(&old, "%s.old", dir) < 0)
        return TVPAL_E_NOMEM;
    tvpal_rmtree(old);
    int rc = 0;
    if (rename(dir, old) < 0) {
        rc = tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot replace: %s", dir,
                            strerror(errno));
    } else if (rename(partial, dir) < 0) {
        const int e = errno;
        rename(old, dir); /* the old dataset back where it was */
        rc = tvpal_diag_set(diag, TVPAL_E_SYS, "%s: cannot replace (left as "
                            "it was): %s", dir, strerror(e));
    } else {
        sync_parent(dir);
        tvpal_rmtree(old);
    }
    free(old);
    return rc;
}
