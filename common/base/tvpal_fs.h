/* tvpal_fs.h: file-system helpers for all-or-nothing outputs. */
#ifndef TVPAL_FS_H
#define TVPAL_FS_H

#include <stddef.h>
#include <stdio.h>

#include "tvpal_error.h"

/* mkdir -p (mode 0755).  0, TVPAL_E_INVAL (empty path), TVPAL_E_NOMEM or
 * TVPAL_E_WRITE; diag (optional, caller-owned) gets the cause, e.g.
 * "mkdir out/node-0: Permission denied". */
int tvpal_mkdirs(const char *path, struct tvpal_diag *diag);

/* Removes a directory tree (files, subdirectories).  Missing is fine. */
int tvpal_rmtree(const char *path);

/* Writes len bytes to path atomically: path.tmp, fsync, rename.  0,
 * TVPAL_E_NOMEM, TVPAL_E_OPEN (path.tmp cannot be created) or TVPAL_E_WRITE;
 * on failure path is unchanged and path.tmp removed, and diag (optional)
 * gets the cause, e.g. "write out/manifest.txt.tmp: No space left on
 * device". */
int tvpal_write_file_atomic(const char *path, const void *data, size_t len,
                            struct tvpal_diag *diag);

/* Inputs are regular files: a FIFO would block a reader forever and a
 * device such as /dev/zero feed it without end.  Opens path for reading
 * without blocking on a FIFO, and returns the descriptor (O_CLOEXEC,
 * blocking again) when it is a regular file; else TVPAL_E_OPEN, with
 * "PATH: not a regular file (a FIFO)" or the errno text in diag. */
int tvpal_open_regular(const char *path, struct tvpal_diag *diag);

/* Text inputs (manifests, transfer functions, --times lists, checkpoints)
 * are at most this large. */
#define TVPAL_TEXT_MAX ((size_t)64 << 20)

/* tvpal_open_regular as a stdio stream, refusing a file larger than
 * TVPAL_TEXT_MAX (TVPAL_E_RANGE).  NULL on failure (diag says why). */
FILE *tvpal_fopen_text(const char *path, int *rc, struct tvpal_diag *diag);

/* Reads a whole small file (regular, at most TVPAL_TEXT_MAX bytes) into a
 * malloc'ed, NUL-terminated buffer (*len: its bytes, when len is
 * non-NULL).  TVPAL_E_OPEN, TVPAL_E_RANGE (too large), TVPAL_E_READ or
 * TVPAL_E_NOMEM; diag (optional) gets "PATH: cause". */
int tvpal_read_file(const char *path, char **out, size_t *len,
                    struct tvpal_diag *diag);

/* fsync of a directory, so that renames in it are durable. */
int tvpal_fsync_dir(const char *path);

/* Does path exist (any type)? */
int tvpal_exists(const char *path);

#endif
