/* tvpal_output.h: the rules for a dataset's output directory, shared by
 * every writer (tvpal-encode, libtvpal's encoder).
 *
 * A dataset is written under DIR.partial and renamed to DIR only when it
 * is complete and verified; what DIR held before is replaced only when the
 * caller says so (force) and only when it is a tvpal dataset, and it stays
 * as it was if the rename fails.
 *
 * Library code: error convention of tvpal_error.h; nothing here prints.
 */
#ifndef TVPAL_OUTPUT_H
#define TVPAL_OUTPUT_H

#include "tvpal_error.h"

/* Whether dir may receive a dataset: absent, or with force a tvpal
 * dataset (a valid manifest.txt).  0, or TVPAL_E_EXIST with diag "DIR:
 * output already exists (HOW replaces it)" (how: the caller's way to
 * force, e.g. "use --force to") or "DIR: exists and is not a tvpal
 * dataset ...", or TVPAL_E_NOMEM. */
int tvpal_output_check(const char *dir, int force, const char *how,
                       struct tvpal_diag *diag);

/* Renames partial to dir; an existing dir goes to dir.old first (an older
 * dir.old removed) and is removed after, and comes back if the rename
 * fails.  The parent's entry is made durable (fsync).  0, or TVPAL_E_SYS
 * (diag names the path and the cause) or TVPAL_E_NOMEM. */
int tvpal_output_place(const char *partial, const char *dir,
                       struct tvpal_diag *diag);

#endif
