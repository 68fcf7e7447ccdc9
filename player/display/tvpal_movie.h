/* tvpal_movie.h: movies (H.264 .mp4, VP9 .webm) written by an ffmpeg
 * process that reads raw RGB frames on a pipe.  tvpal_movie.c is the only
 * file that runs ffmpeg (LAYERS.md).
 *
 * ffmpeg is found on PATH when the movie is opened (Debian package ffmpeg,
 * a run-time dependency).  The movie is written to a temporary with a
 * unique name in the same directory, FILE.partial-XXXXXX.EXT (made with
 * O_EXCL; ffmpeg writes it through the descriptor it inherits, so nothing
 * planted at a name is followed), and renamed to FILE only when ffmpeg has
 * read every frame, exited with status 0 without reporting an error, and
 * ffprobe finds every frame in what it wrote (ffmpeg may exit 0 after
 * failed writes on a full disk): a failed or interrupted run never leaves
 * a FILE that looks complete, nor replaces an older one.  FILE must be
 * absent or a regular file (tvpal_out_check): a link, FIFO or device there
 * is refused and left alone.
 *
 * The caller ignores SIGPIPE (signal(SIGPIPE, SIG_IGN)): when ffmpeg dies,
 * a frame write then fails with EPIPE and is reported, instead of the
 * signal ending the program. */
#ifndef TVPAL_MOVIE_H
#define TVPAL_MOVIE_H

#include <stdint.h>

#include "tvpal_error.h"

enum tvpal_movie_kind {
    TVPAL_MOVIE_NONE,   /* not a movie name */
    TVPAL_MOVIE_MP4,    /* .mp4: H.264 (libx264), yuv420p */
    TVPAL_MOVIE_WEBM    /* .webm: VP9 (libvpx-vp9), yuv420p */
};

/* The kind of movie path names by its extension (.mp4, .webm, any case),
 * or TVPAL_MOVIE_NONE (also for "x.mp4/": a trailing / names a
 * directory). */
int tvpal_movie_kind(const char *path);

/* The codec's name for messages ("H.264", "VP9"; "" for NONE). */
const char *tvpal_movie_codec(int kind);

/* yuv420p stores colour at half resolution, so both sides of a movie
 * frame are even: an odd width or height gets one more column or row, a
 * copy of the last one (nothing visible is added). */
void tvpal_movie_size(unsigned width, unsigned height, unsigned *mw,
                      unsigned *mh);

struct tvpal_movie;

/* Starts ffmpeg writing path (tvpal_movie_kind(path) != NONE) from frames
 * of width x height pixels (each 1..16384) at fps frames per second (> 0).
 * Allocates all it needs now (nothing per frame).  0, or:
 * TVPAL_E_OPEN when ffmpeg is not on PATH, path is a directory or the
 * temporary cannot be created (no such directory, not writable),
 * TVPAL_E_INVAL for a
 * bad argument, TVPAL_E_NOMEM, TVPAL_E_SYS (pipe, spawn); diag (may be
 * NULL) says which. */
int tvpal_movie_open(struct tvpal_movie **out, const char *path,
                     unsigned width, unsigned height, double fps,
                     struct tvpal_diag *diag);

/* Sends one frame: width x height 8-bit RGB, top row first (3 * width
 * bytes a row).  0, or TVPAL_E_WRITE when ffmpeg stopped reading (it
 * died or failed: diag has its exit status and the end of its error
 * output); then the movie can only be aborted. */
int tvpal_movie_write(struct tvpal_movie *m, const uint8_t *rgb,
                      struct tvpal_diag *diag);

/* Frames sent so far. */
uint64_t tvpal_movie_frames(const struct tvpal_movie *m);

/* Ends the stream, waits for ffmpeg and, when it succeeded, renames the
 * temporary to the movie's path.  0, or TVPAL_E_WRITE (ffmpeg failed:
 * diag has its status and the end of its error output; the temporary is
 * removed).  Frees m in every case (NULL: 0). */
int tvpal_movie_close(struct tvpal_movie *m, struct tvpal_diag *diag);

/* Stops ffmpeg (SIGTERM), waits for it, removes the temporary and frees
 * m.  For error paths; NULL is a no-op. */
void tvpal_movie_abort(struct tvpal_movie *m);

#endif
