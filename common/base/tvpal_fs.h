/* tvpal_fs.h: file-system helpers for all-or-nothing outputs. */
#ifndef TVPAL_FS_H
#define TVPAL_FS_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "tvpal_error.h"

/* mkdir -p (mode 0755).  0, TVPAL_E_INVAL (empty path), TVPAL_E_NOMEM or
 * TVPAL_E_WRITE; diag (optional, caller-owned) gets the cause, e.g.
 * "mkdir out/node-0: Permission denied". */
int tvpal_mkdirs(const char *path, struct tvpal_diag *diag);

/* Removes a directory tree (files, subdirectories).  Missing is fine. */
int tvpal_rmtree(const char *path);

/* Every file a program writes goes through tvpal_out: a new file under a
 * unique name beside the target (mkstemp: created with O_EXCL, so a link
 * or file planted at a predictable name cannot redirect the write), made
 * complete (fsync) and then renamed over the target, so a reader never
 * sees a half-written file.  The target, when it exists, must be a
 * regular file: a device node, FIFO, directory or symbolic link there is
 * refused (TVPAL_E_EXIST) and left alone.  Not thread-safe per object. */
struct tvpal_out {
    int fd;          /* the temporary, open for writing */
    FILE *stream;    /* tvpal_out_stream's, or NULL */
    char *tmp;       /* owned: its name */
    char *path;      /* owned: the target */
};

/* Starts writing path.  0, TVPAL_E_EXIST (see above), TVPAL_E_OPEN (the
 * temporary cannot be created: e.g. no such directory) or TVPAL_E_NOMEM;
 * diag gets "PATH: cause".  On failure o holds nothing. */
int tvpal_out_open(struct tvpal_out *o, const char *path,
                   struct tvpal_diag *diag);

/* Whether path may be written by tvpal_out_open (absent, or a regular
 * file): 0 or TVPAL_E_EXIST / TVPAL_E_OPEN with the reason.  For checks
 * before long work; tvpal_out_open and _commit check again. */
int tvpal_out_check(const char *path, struct tvpal_diag *diag);

/* A stdio stream on the temporary (owned by o; do not fclose it). */
FILE *tvpal_out_stream(struct tvpal_out *o);

/* Writes n bytes to the temporary.  0 or TVPAL_E_WRITE (diag). */
int tvpal_out_write(struct tvpal_out *o, const void *data, size_t n,
                    struct tvpal_diag *diag);

/* Flushes, fsyncs, closes and renames the temporary over the target (the
 * target checked again).  0 or TVPAL_E_WRITE / TVPAL_E_EXIST; on failure
 * the temporary is removed and the target unchanged.  o holds nothing
 * after, whatever the result. */
int tvpal_out_commit(struct tvpal_out *o, struct tvpal_diag *diag);

/* Removes the temporary; o holds nothing after.  Safe on a zeroed o. */
void tvpal_out_abort(struct tvpal_out *o);

/* A file written as it goes rather than atomically (a log such as
 * timing.csv, flushed by the caller so a killed run keeps its rows):
 * created or truncated, but only when it is absent or a regular file; a
 * link, FIFO or device there is refused without opening it for writing
 * (O_NOFOLLOW, O_NONBLOCK).  NULL on failure, *rc and diag say why. */
FILE *tvpal_open_log(const char *path, int *rc, struct tvpal_diag *diag);

/* Whether path (existing or not) lies in directory dir or below it, after
 * resolving links of its directory: a program refuses to write inside
 * its own input.  1, 0, or 0 when either cannot be resolved. */
int tvpal_path_inside(const char *path, const char *dir);

/* Writes len bytes to path through tvpal_out (above).  0, TVPAL_E_NOMEM,
 * TVPAL_E_EXIST, TVPAL_E_OPEN or TVPAL_E_WRITE; on failure path is
 * unchanged and the temporary removed, and diag (optional) gets the
 * cause, e.g. "write out/manifest.txt: No space left on device". */
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

/* An exclusive lock on path for one job (flock, advisory: every tvpal
 * writer of that output takes it): the file is created when absent and
 * holds the holder's process id.  Taken without waiting: 0 with *fd
 * (keep it open; the lock goes with the process), or TVPAL_E_EXIST when
 * another process holds it (diag: "PATH: held by process PID"; "by
 * another process" where its id is not written), TVPAL_E_OPEN when it
 * cannot be made.  A lock file removed by its holder while this one
 * waited is taken again, so two processes never both hold path. */
int tvpal_lock_take(const char *path, int *fd, struct tvpal_diag *diag);

/* Removes path and releases the lock (fd from tvpal_lock_take; -1: a
 * no-op). */
void tvpal_lock_release(const char *path, int fd);

/* fsync of a directory, so that renames in it are durable. */
int tvpal_fsync_dir(const char *path);

/* Does path exist (any type)? */
int tvpal_exists(const char *path);

/* The bytes path takes as files: the sizes (st_size) of the regular files
 * under the directory path, in every subdirectory, added up (or path's
 * own size when it is a file); directories themselves are not counted,
 * links are followed, at most 16 directories deep.  What `du -b
 * --apparent-size` gives less its directory entries.  0 with *bytes set,
 * or TVPAL_E_OPEN (diag, optional, names the path that cannot be read) or
 * TVPAL_E_NOMEM; *bytes is left as it was on error. */
int tvpal_tree_bytes(const char *path, uint64_t *bytes,
                     struct tvpal_diag *diag);

/* Node r's directory of a dataset: DIR/node-r, or with a pattern (the
 * --shard-dir of tvpal-play and tvpal-encode: node-local disks) the
 * pattern with every %r replaced by r.  Malloc'ed; NULL when out of
 * memory. */
char *tvpal_node_dir(const char *dir, const char *pattern, uint32_t r);

#endif
