/* tvpal_movie.c: movies through an ffmpeg process (see tvpal_movie.h).
 * The only file of the tree that runs ffmpeg. */
#define _GNU_SOURCE
#include "tvpal_movie.h"
#include "tvpal_fs.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

#define MOVIE_SIDE_MAX 16384
#define ERR_TAIL 160            /* bytes of ffmpeg's stderr in a message */

struct tvpal_movie {
    pid_t pid;                  /* ffmpeg, or 0 once waited for */
    int fd;                     /* the pipe to its stdin, or -1 */
    FILE *err;                  /* its stderr: an unlinked temporary */
    unsigned w, h, mw, mh;      /* frame size, movie frame size (even) */
    uint8_t *pad;               /* mw x mh frame, when it differs */
    uint64_t frames;
    int out;                    /* the temporary, open (ffmpeg writes it
                                 * as its fd 3), or -1 */
    char *path, *partial;       /* owned */
};

/* ffmpeg writes the temporary through the descriptor it inherits, not by
 * name: a link or FIFO put at the name after it was made redirects
 * nothing. */
#define CHILD_OUT "/proc/self/fd/3"

int tvpal_movie_kind(const char *path)
{
    const char *dot = path ? strrchr(path, '.') : NULL;
    if (!dot || strchr(dot, '/'))
        return TVPAL_MOVIE_NONE;
    if (!strcasecmp(dot, ".mp4"))
        return TVPAL_MOVIE_MP4;
    if (!strcasecmp(dot, ".webm"))
        return TVPAL_MOVIE_WEBM;
    return TVPAL_MOVIE_NONE;
}

const char *tvpal_movie_codec(int kind)
{
    return kind == TVPAL_MOVIE_MP4 ? "H.264" : kind == TVPAL_MOVIE_WEBM ? "VP9"
                                                                        : "";
}

void tvpal_movie_size(unsigned width, unsigned height, unsigned *mw,
                      unsigned *mh)
{
    *mw = width + (width & 1);
    *mh = height + (height & 1);
}

/* The temporary FILE.partial-XXXXXX.EXT, made with a unique name
 * (mkstemps: O_EXCL, so nothing planted at a predictable name is
 * followed) in the movie's directory (the rename stays within one file
 * system), with its extension (players and ffmpeg see the type).  Into
 * m->partial and m->out. */
static int make_partial(struct tvpal_movie *m, struct tvpal_diag *diag)
{
    const char *dot = strrchr(m->path, '.');
    if (asprintf(&m->partial, "%.*s.partial-XXXXXX%s",
                 (int)(dot - m->path), m->path, dot) < 0) {
        m->partial = NULL;
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory");
    }
    m->out = mkstemps(m->partial, (int)strlen(dot));
    if (m->out < 0)
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: cannot create a "
                              "temporary beside it: %s", m->path,
                              strerror(errno));
    mode_t um = umask(0);
    umask(um);
    if (fchmod(m->out, 0666 & ~um) < 0 ||
        fcntl(m->out, F_SETFD, FD_CLOEXEC) < 0) {
        int e = errno;
        unlink(m->partial);
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s", m->partial,
                              strerror(e));
    }
    return 0;
}

/* The end of ffmpeg's error output as one line (its last ERR_TAIL bytes,
 * newlines as " | "), or "no message". */
static void err_tail(struct tvpal_movie *m, char *out, size_t cap)
{
    char buf[ERR_TAIL + 1];
    size_t n = 0;
    long end = -1;
    if (m->err && fflush(m->err) == 0 && fseek(m->err, 0, SEEK_END) == 0)
        end = ftell(m->err);
    if (end > 0) {
        long from = end > ERR_TAIL ? end - ERR_TAIL : 0;
        if (fseek(m->err, from, SEEK_SET) == 0)
            n = fread(buf, 1, ERR_TAIL, m->err);
    }
    while (n > 0 && (buf[n - 1] == '\n' || buf[n - 1] == '\r' ||
                     buf[n - 1] == ' '))
        n--;
    buf[n] = 0;
    size_t o = 0;
    out[0] = 0;
    for (size_t i = 0; i < n && o + 4 < cap; i++) {
        if (buf[i] == '\n') {
            memcpy(out + o, " | ", 3);
            o += 3;
        } else if (buf[i] != '\r') {
            out[o++] = buf[i];
        }
    }
    out[o] = 0;
    if (!o)
        snprintf(out, cap, "no message");
}

/* Waits for ffmpeg: its exit status as a phrase in why; 0 when it
 * exited with status 0. */
static int reap(struct tvpal_movie *m, char *why, size_t cap)
{
    int st = 0;
    pid_t r;
    while ((r = waitpid(m->pid, &st, 0)) < 0 && errno == EINTR)
        ;
    m->pid = 0;
    if (r < 0) {
        snprintf(why, cap, "cannot wait for ffmpeg: %s", strerror(errno));
        return -1;
    }
    if (WIFEXITED(st)) {
        snprintf(why, cap, "ffmpeg exited with status %d", WEXITSTATUS(st));
        return WEXITSTATUS(st) ? -1 : 0;
    }
    snprintf(why, cap, "ffmpeg was killed by signal %d",
             WIFSIGNALED(st) ? WTERMSIG(st) : 0);
    return -1;
}

static void movie_free(struct tvpal_movie *m)
{
    if (m->fd >= 0)
        close(m->fd);
    if (m->err)
        fclose(m->err);
    if (m->out >= 0)
        close(m->out);
    free(m->pad);
    free(m->path);
    free(m->partial);
    free(m);
}

/* ffmpeg's command line: raw RGB frames on stdin, the codec of the kind,
 * yuv420p (what every player takes), no audio. */
static void build_argv(const struct tvpal_movie *m, int kind, char size[32],
                       char rate[32], const char *argv[40])
{
    snprintf(size, 32, "%ux%u", m->mw, m->mh);
    int n = 0;
    const char *head[] = {"ffmpeg", "-hide_banner", "-nostats", "-loglevel",
                          "error", "-y", "-f", "rawvideo", "-pix_fmt",
                          "rgb24", "-s", size, "-r", rate, "-i", "-", "-an"};
    for (size_t i = 0; i < sizeof head / sizeof *head; i++)
        argv[n++] = head[i];
    /* H.264 at CRF 18 is visually lossless for most content; VP9 in
     * constant quality mode (-b:v 0) at CRF 30, YouTube's choice for
     * 720p-1080p, at speed 4: on 48 turbulence frames of 512x512 1.8 times
     * as fast as the default speed for 0.3 dB less (41.7 dB against the
     * PNG frames; H.264: 42.9 dB). */
    const char *mp4[] = {"-c:v", "libx264", "-preset", "medium", "-crf", "18",
                         "-movflags", "+faststart", "-f", "mp4"};
    const char *webm[] = {"-c:v", "libvpx-vp9", "-crf", "30", "-b:v", "0",
                          "-row-mt", "1", "-deadline", "good", "-cpu-used",
                          "4", "-f", "webm"};
    const char **c = kind == TVPAL_MOVIE_MP4 ? mp4 : webm;
    const int nc = kind == TVPAL_MOVIE_MP4 ? 10 : 14;
    for (int i = 0; i < nc; i++)
        argv[n++] = c[i];
    argv[n++] = "-pix_fmt";
    argv[n++] = "yuv420p";
    argv[n++] = CHILD_OUT;
    argv[n] = NULL;
}

/* Whether PATH names an executable `name` (an empty entry is the current
 * directory, as for execvp).  Said before spawning: not every
 * posix_spawnp reports a failed exec (under valgrind the child exits 127
 * after the spawn succeeded), and a missing ffmpeg must stop the run
 * before any frame. */
static int on_path(const char *name)
{
    const char *path = getenv("PATH");
    char buf[4096];
    if (!path)
        path = "/usr/bin:/bin";
    for (const char *p = path;;) {
        size_t len = strcspn(p, ":");
        if (snprintf(buf, sizeof buf, "%.*s%s%s", (int)len, p, len ? "/" : "",
                     name) < (int)sizeof buf && access(buf, X_OK) == 0)
            return 1;
        if (!p[len])
            return 0;
        p += len + 1;
    }
}

/* Runs ffmpeg with stdin from the pipe's read end rfd, stdout to
 * /dev/null, stderr into m->err, SIGPIPE at its default. */
static int spawn(struct tvpal_movie *m, int rfd, char *const argv[],
                 struct tvpal_diag *diag)
{
    posix_spawn_file_actions_t fa;
    posix_spawnattr_t at;
    sigset_t def, none;
    sigemptyset(&def);
    sigaddset(&def, SIGPIPE);
    sigemptyset(&none);
    if (posix_spawn_file_actions_init(&fa) != 0)
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory");
    if (posix_spawnattr_init(&at) != 0) {
        posix_spawn_file_actions_destroy(&fa);
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory");
    }
    int rc = posix_spawn_file_actions_adddup2(&fa, rfd, 0);
    if (!rc)
        rc = posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    if (!rc)
        rc = posix_spawn_file_actions_adddup2(&fa, m->out, 3);
    if (!rc)
        rc = posix_spawn_file_actions_adddup2(&fa, fileno(m->err), 2);
    if (!rc)
        rc = posix_spawnattr_setflags(&at, POSIX_SPAWN_SETSIGDEF |
                                               POSIX_SPAWN_SETSIGMASK);
    if (!rc)
        rc = posix_spawnattr_setsigdefault(&at, &def);
    if (!rc)
        rc = posix_spawnattr_setsigmask(&at, &none);
    if (!rc)
        rc = on_path(argv[0]) ? posix_spawnp(&m->pid, argv[0], &fa, &at, argv,
                                             environ)
                              : ENOENT;
    posix_spawn_file_actions_destroy(&fa);
    posix_spawnattr_destroy(&at);
    if (rc == ENOENT)
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "ffmpeg not found on PATH "
                              "(a movie needs it: install the Debian package "
                              "ffmpeg)");
    if (rc) {
        m->pid = 0;
        return tvpal_diag_set(diag, TVPAL_E_SYS, "cannot run ffmpeg: %s",
                              strerror(rc));
    }
    return 0;
}

/* The movie's name may be replaced (absent, or a regular file: a link,
 * FIFO or device there is refused and left alone, as for every output,
 * tvpal_out_check) and the temporary can be made beside it: said now,
 * before any frame is drawn, rather than at the end. */
static int check_partial(struct tvpal_movie *m, struct tvpal_diag *diag)
{
    struct stat st;
    if (stat(m->path, &st) == 0 && S_ISDIR(st.st_mode))
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: is a directory (a "
                              "trailing / writes PNG frames into it)",
                              m->path);
    int rc = tvpal_out_check(m->path, diag);
    return rc < 0 ? rc : make_partial(m, diag);
}

int tvpal_movie_open(struct tvpal_movie **out, const char *path,
                     unsigned width, unsigned height, double fps,
                     struct tvpal_diag *diag)
{
    *out = NULL;
    const int kind = tvpal_movie_kind(path);
    if (kind == TVPAL_MOVIE_NONE || !width || !height ||
        width > MOVIE_SIDE_MAX || height > MOVIE_SIDE_MAX || !(fps > 0) ||
        fps > 1e6)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: not a movie of 1..%d "
                              "pixels a side at a positive frame rate "
                              "(.mp4 or .webm)", path ? path : "(null)",
                              MOVIE_SIDE_MAX);
    struct tvpal_movie *m = calloc(1, sizeof *m);
    if (!m)
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory");
    m->fd = m->out = -1;
    m->w = width;
    m->h = height;
    tvpal_movie_size(width, height, &m->mw, &m->mh);
    if (!(m->path = strdup(path)) || !(m->err = tmpfile()) ||
        ((m->mw != width || m->mh != height) &&
         !(m->pad = calloc((size_t)3 * m->mw * m->mh, 1)))) {
        movie_free(m);
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "out of memory");
    }
    int rc = check_partial(m, diag);
    int p[2] = {-1, -1};
    if (rc == 0 && pipe2(p, O_CLOEXEC) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_SYS, "pipe: %s", strerror(errno));
    if (rc == 0) {
        char size[32], rate[32];
        const char *argv[40];
        snprintf(rate, sizeof rate, "%.9g", fps);
        build_argv(m, kind, size, rate, argv);
        rc = spawn(m, p[0], (char *const *)argv, diag);
        close(p[0]);
        m->fd = p[1];
    }
    if (rc < 0) {
        if (m->out >= 0)
            unlink(m->partial);
        movie_free(m);
        return rc;
    }
    *out = m;
    return 0;
}

/* Writes n bytes to ffmpeg; 0, or the errno that stopped it (EPIPE: ffmpeg
 * closed its end). */
static int write_all(int fd, const uint8_t *p, size_t n)
{
    while (n > 0) {
        ssize_t k = write(fd, p, n);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return k < 0 ? errno : EIO;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

/* The frame as ffmpeg gets it: rgb itself, or padded to the even size
 * with copies of the last column and row. */
static const uint8_t *movie_frame(struct tvpal_movie *m, const uint8_t *rgb)
{
    if (!m->pad)
        return rgb;
    const size_t row = 3 * (size_t)m->w, mrow = 3 * (size_t)m->mw;
    for (unsigned y = 0; y < m->mh; y++) {
        const uint8_t *s = rgb + row * (y < m->h ? y : m->h - 1);
        uint8_t *d = m->pad + mrow * y;
        memcpy(d, s, row);
        if (m->mw != m->w)
            memcpy(d + row, s + row - 3, 3);
    }
    return m->pad;
}

int tvpal_movie_write(struct tvpal_movie *m, const uint8_t *rgb,
                      struct tvpal_diag *diag)
{
    if (m->fd < 0)
        return tvpal_diag_set(diag, TVPAL_E_WRITE, "%s: ffmpeg has stopped",
                              m->path);
    const uint8_t *f = movie_frame(m, rgb);
    int e = write_all(m->fd, f, (size_t)3 * m->mw * m->mh);
    if (!e) {
        m->frames++;
        return 0;
    }
    /* ffmpeg is gone or going: its status and last words say why. */
    close(m->fd);
    m->fd = -1;
    char why[96], tail[ERR_TAIL + 32];
    if (e == EPIPE)
        reap(m, why, sizeof why);
    else
        snprintf(why, sizeof why, "writing to ffmpeg: %s", strerror(e));
    err_tail(m, tail, sizeof tail);
    return tvpal_diag_set(diag, TVPAL_E_WRITE, "%s: ffmpeg stopped reading "
                          "at frame %llu (%s): %s", m->path,
                          (unsigned long long)m->frames + 1, why, tail);
}

uint64_t tvpal_movie_frames(const struct tvpal_movie *m)
{
    return m->frames;
}

/* What ffmpeg wrote, checked before it replaces anything: ffmpeg can
 * exit with status 0 after writes that failed (a full disk), leaving a
 * file without its index.  It must have said nothing at -loglevel error,
 * and ffprobe (Debian's ffmpeg package has it) must find every frame sent
 * in it: the packets are counted, not decoded. */
static int check_written(struct tvpal_movie *m, struct tvpal_diag *diag)
{
    char tail[ERR_TAIL + 32];
    long said = -1;
    if (m->err && fflush(m->err) == 0 && fseek(m->err, 0, SEEK_END) == 0)
        said = ftell(m->err);
    if (said > 0) {
        err_tail(m, tail, sizeof tail);
        return tvpal_diag_set(diag, TVPAL_E_WRITE, "%s: ffmpeg exited with "
                              "status 0 but reported errors: %s", m->path,
                              tail);
    }
    if (!on_path("ffprobe"))
        return 0;
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/fd/%d", (int)getpid(), m->out);
    const char *argv[] = {"ffprobe", "-v", "error", "-count_packets",
                          "-select_streams", "v:0", "-show_entries",
                          "stream=nb_read_packets", "-of", "csv=p=0", path,
                          NULL};
    int p[2];
    if (pipe2(p, O_CLOEXEC) < 0)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "pipe: %s", strerror(errno));
    posix_spawn_file_actions_t fa;
    pid_t pid = 0;
    int rc = posix_spawn_file_actions_init(&fa);
    if (!rc)
        rc = posix_spawn_file_actions_adddup2(&fa, p[1], 1);
    if (!rc)
        rc = posix_spawn_file_actions_adddup2(&fa, fileno(m->err), 2);
    if (!rc)
        rc = posix_spawnp(&pid, "ffprobe", &fa, NULL, (char *const *)argv,
                          environ);
    posix_spawn_file_actions_destroy(&fa);
    close(p[1]);
    char out[64] = "";
    size_t n = 0;
    ssize_t k;
    while (!rc && n < sizeof out - 1 &&
           ((k = read(p[0], out + n, sizeof out - 1 - n)) > 0 ||
            (k < 0 && errno == EINTR)))
        n += k > 0 ? (size_t)k : 0;
    while (n > 0 && (out[n - 1] == '\n' || out[n - 1] == '\r'))
        n--;
    out[n] = 0;
    close(p[0]);
    int st = 0;
    while (!rc && waitpid(pid, &st, 0) < 0 && errno == EINTR)
        ;
    if (rc)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "cannot run ffprobe: %s",
                              strerror(rc));
    char *end;
    unsigned long long got = strtoull(out, &end, 10);
    if (!WIFEXITED(st) || WEXITSTATUS(st) || end == out ||
        got != m->frames) {
        err_tail(m, tail, sizeof tail);
        return tvpal_diag_set(diag, TVPAL_E_WRITE, "%s: the movie ffmpeg "
                              "wrote holds %s of its %llu frames (disk "
                              "full?): %s", m->path, end == out ? "none" : out,
                              (unsigned long long)m->frames, tail);
    }
    return 0;
}

int tvpal_movie_close(struct tvpal_movie *m, struct tvpal_diag *diag)
{
    if (!m)
        return 0;
    if (m->fd < 0 || m->pid == 0) {   /* a write failed: said then */
        int rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "%s: ffmpeg has stopped",
                                m->path);
        tvpal_movie_abort(m);
        return rc;
    }
    close(m->fd);
    m->fd = -1;
    char why[96], tail[ERR_TAIL + 32];
    struct stat st;
    int rc = 0;
    if (reap(m, why, sizeof why) < 0) {
        err_tail(m, tail, sizeof tail);
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "%s: %s: %s", m->path, why,
                            tail);
    } else if (fstat(m->out, &st) < 0 || st.st_size == 0) {
        /* make_partial made it empty: ffmpeg wrote nothing there. */
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "%s: ffmpeg exited with "
                            "status 0 but wrote no movie", m->path);
    } else {
        rc = check_written(m, diag);
    }
    if (rc == 0 && fsync(m->out) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "%s: %s: %s", m->path,
                            m->partial, strerror(errno));
    /* The target checked again, just before: a link or FIFO put there
     * meanwhile is refused, and an older movie stays. */
    if (rc == 0 && (rc = tvpal_out_check(m->path, diag)) == 0 &&
        rename(m->partial, m->path) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_WRITE, "%s: cannot rename %s: %s",
                            m->path, m->partial, strerror(errno));
    if (rc < 0)
        unlink(m->partial);
    movie_free(m);
    return rc;
}

void tvpal_movie_abort(struct tvpal_movie *m)
{
    if (!m)
        return;
    if (m->fd >= 0) {
        close(m->fd);
        m->fd = -1;
    }
    if (m->pid > 0) {
        char why[96];
        kill(m->pid, SIGTERM);
        reap(m, why, sizeof why);
    }
    unlink(m->partial);
    movie_free(m);
}
