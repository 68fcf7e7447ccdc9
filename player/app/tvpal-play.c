/* tvpal-play: plays a tvpal dataset through the per-frame palette renderer.
 * This front end is headless: it renders a range of timesteps with OSMesa
 * and writes PNG frames and a per-frame timing CSV. */
#define _GNU_SOURCE
#include "tvpal_cli.h"
#include "tvpal_clock.h"
#include "tvpal_comm.h"
#include "tvpal_composite.h"
#include "tvpal_fs.h"
#include "tvpal_glr.h"
#include "tvpal_osmesa.h"
#include "tvpal_player.h"
#include "tvpal_png.h"
#include "tvpal_render_ref.h"
#include "tvpal_sw.h"
#include "tvpal_win.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define PROG "tvpal-play"

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " OUTDIR [options]\n"
"Play the tvpal dataset OUTDIR: every frame decodes the slices of the axis\n"
"most orthogonal to the view by a per-frame palette, TF(decoder[t][i]),\n"
"emulated in a GLSL fragment shader (interpolation after the lookup), and\n"
"blends them back to front in a float framebuffer.  Headless (OSMesa):\n"
"with -o DIR, writes DIR/tNNNN.png (NNNN: the timestep) and a per-frame\n"
"timing CSV.\n"
"\n"
"View and frames:\n"
"      --headless           render off-screen to PNG files (default when\n"
"                           there is no display)\n"
"  -w, --window             interactive window (default with a display)\n"
"  -s, --steps A:B          timesteps A..B inclusive, 0-based (default all);\n"
"                           B < A plays backward\n"
"  -S, --size WxH           image size (default 512x512)\n"
"  -r, --rotate AX,AY       degrees about x, then about y (default 20,30)\n"
"  -z, --zoom Z             zoom factor (default 1)\n"
"  -t, --tf FILE            transfer function (samples/tf/README.md: tvpal\n"
"                           text format or ParaView preset JSON); default:\n"
"                           one from the data's histogram.  Repeat to give\n"
"                           several (the window cycles through them)\n"
"      --opacity S          opacity scale (default 1)\n"
"      --renderer R         cpu (shear-warp on the CPU), gl (GLSL palette\n"
"                           shader), ref (CPU reference, slow) or none (read\n"
"                           and decode only: I/O benchmarks).  Default: cpu\n"
"                           headless (OSMesa draws on the CPU) and in a window\n"
"                           whose GL is a software rasterizer (llvmpipe),\n"
"                           gl in a window on a GPU\n"
"      --fb BITS            GL colour buffer: 32 (float, default), 16 (half)\n"
"                           or 8 (shows the banding of 8-bit blending);\n"
"                           implies --renderer gl\n"
"      --cpu-scale K        cpu renderer: intermediate pixels per texel, auto\n"
"                           (default: 1 to 4, as many as the view shows) or\n"
"                           1..8 (sharper at close zoom; cost grows as K^2);\n"
"                           implies --renderer cpu\n"
"      --spin DEG           turn the view DEG degrees about y per frame\n"
"                           (a camera path; crossing axes loads records)\n"
"Data:\n"
"  -m, --mode M             incore (records in RAM) or stream (default: from\n"
"                           disk, O_DIRECT, prefetching)\n"
"      --io B               uring (default; pread when unavailable) or pread\n"
"      --prefetch P         timesteps read ahead when streaming (default 4)\n"
"      --no-direct          stream through the page cache\n"
"      --mem MIB            in-core: keep at most MIB of records in RAM\n"
"                           (axes beyond it are dropped or streamed); also\n"
"                           reports how many timesteps fit in MIB\n"
"Benchmarking (headless):\n"
"      --repeat K           draw every frame K times (times the draw alone)\n"
"      --tf-cycle           use the next --tf every frame\n"
"      --jumps K            every K-th frame jumps to a random timestep\n"
"                           (CSV column jump = 1)\n"
"Output:\n"
"  -o, --output DIR         write PNG frames here (created)\n"
"      --csv FILE           per-frame timings (default DIR/timing.csv)\n"
"      --strict             stop at the first read or checksum error\n"
"      --ref-psnr           also draw every frame with the reference renderer\n"
"                           and report the image's PSNR against it (CSV\n"
"                           column psnr_ref, summary line psnr_ref=; one\n"
"                           rank; timings are then not representative)\n"
"Cluster (mpirun -np K tvpal-play ..., one rank per node shard):\n"
"      --shard-dir PATTERN  where rank r finds its shard: %%r is replaced by\n"
"                           the rank (default OUTDIR/node-%%r)\n"
"      --composite S        bswap (binary swap, default) or gather (all\n"
"                           images to rank 0: the baseline)\n"
"      --autoplay K         window: play K frames from A, then exit\n"
"      --screenshot FILE    window: save the last frame shown as PNG\n"
"  -q, --quiet              only the closing summary line\n"
"  -h, --help               this help\n"
"  -V, --version            version\n"
"\n"
"Window keys: space play/pause, Right/Left (or . ,) step, Home/End first/\n"
"last, B reverse direction, T next transfer function, R reload it from its\n"
"file, Up/Down opacity, M in-core/out-of-core, +/- or wheel zoom, S\n"
"screenshot (tvpal-shot-NNNN.png), Q or Esc quit.  Mouse: drag the image to\n"
"rotate, drag or click the slider to scrub.  While dragging or scrubbing\n"
"every other slice is drawn; the full image follows when idle.  The title\n"
"shows timestep, fps, data mode, axis and transfer function.\n"
"\n"
"A record that fails to load is reported (file, record); the affected\n"
"slices keep their last good data and playback continues, unless --strict.\n"
"Exit status: 0 success; 1 failure (GL context, writing output) or load\n"
"errors during playback; 2 bad input or usage, a dataset that cannot be\n"
"opened, or (with --strict) the first load error.\n");
}

/* Under MPI only rank 0 reports what every rank finds alike (options,
 * dataset-wide errors); a failure of one rank is reported by that rank and
 * ends the whole job (die_rank), so no rank waits forever. */
static int g_env_rank;            /* from the launcher's environment */
static struct tvpal_comm g_comm;  /* valid once g_have_comm */
static int g_have_comm;

static void die(int code, const char *fmt, ...)
    __attribute__((format(printf, 2, 3), noreturn));
static void die(int code, const char *fmt, ...)
{
    if (g_env_rank == 0) {
        va_list ap;
        va_start(ap, fmt);
        fputs(PROG ": ", stderr);
        vfprintf(stderr, fmt, ap);
        fputc('\n', stderr);
        va_end(ap);
    }
#ifdef HAVE_MPI
    if (g_have_comm && g_comm.size > 1)
        tvpal_comm_mpi_finalize(&g_comm);
#endif
    exit(code);
}

static void die_rank(int code, const char *fmt, ...)
    __attribute__((format(printf, 2, 3), noreturn));
static void die_rank(int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    if (g_have_comm && g_comm.size > 1)
        fprintf(stderr, PROG ": rank %d: ", g_comm.rank);
    else
        fputs(PROG ": ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    if (g_have_comm && g_comm.size > 1)
        g_comm.abort(&g_comm, code);
    exit(code);
}

/* Every rank's result of a step that may fail on some ranks only: rank 0
 * prints the failures (naming the ranks); all ranks exit when any failed. */
struct rank_status {
    int rc;
    char msg[244];
};

static void check_all(int rc, const char *msg, int code)
{
    struct rank_status mine = {.rc = rc}, *all = NULL;
    snprintf(mine.msg, sizeof mine.msg, "%s", msg);
    if (g_comm.size == 1) {
        if (rc < 0)
            die(code, "%s", msg);
        return;
    }
    if (g_comm.rank == 0 &&
        !(all = calloc((size_t)g_comm.size, sizeof *all)))
        die_rank(1, "out of memory");
    if (g_comm.gather(&g_comm, &mine, sizeof mine, all) < 0)
        die_rank(1, "MPI gather failed");
    double bad = rc < 0;
    g_comm.allmax(&g_comm, &bad, 1);
    if (g_comm.rank == 0)
        for (int r = 0; r < g_comm.size; r++)
            if (all[r].rc < 0)
                fprintf(stderr, PROG ": rank %d: %s\n", r, all[r].msg);
    free(all);
    if (bad > 0) {
#ifdef HAVE_MPI
        tvpal_comm_mpi_finalize(&g_comm);
#endif
        exit(code);
    }
}

/* Renderer adapters. */
static int gl_set(void *c, uint32_t w, uint32_t h, uint32_t n,
                  struct tvpal_diag *d)
{
    return tvpal_glr_set_slices(c, w, h, n, d);
}
static void gl_up(void *c, uint32_t layer, const uint8_t *idx)
{
    tvpal_glr_upload(c, layer, idx);
}
static int gl_draw(void *c, const struct tvpal_frame *f, float *rgba,
                   struct tvpal_diag *d)
{
    return tvpal_glr_draw(c, f, rgba, d);
}

static int sw_set(void *c, uint32_t w, uint32_t h, uint32_t n,
                  struct tvpal_diag *d)
{
    return tvpal_sw_set_slices(c, w, h, n, d);
}
static void sw_up(void *c, uint32_t layer, const uint8_t *idx)
{
    (void)idx; /* read from the frame when drawn */
    tvpal_sw_upload(c, layer);
}
static int sw_draw(void *c, const struct tvpal_frame *f, float *rgba,
                   struct tvpal_diag *d)
{
    return tvpal_sw_draw(c, f, rgba, d);
}

static double *ref_buf;
static int none_draw(void *c, const struct tvpal_frame *f, float *rgba,
                     struct tvpal_diag *d)
{
    memset(rgba, 0, sizeof(float) * 4 * f->view->width * f->view->height);
    return 0;
}
static int ref_set(void *c, uint32_t w, uint32_t h, uint32_t n,
                   struct tvpal_diag *d)
{
    return 0;
}
static void ref_up(void *c, uint32_t layer, const uint8_t *idx)
{
}
static int ref_draw(void *c, const struct tvpal_frame *f, float *rgba,
                    struct tvpal_diag *d)
{
    size_t n = (size_t)f->view->width * f->view->height * 4;
    tvpal_render_ref(f, ref_buf);
    for (size_t i = 0; i < n; i++)
        rgba[i] = (float)ref_buf[i];
    return 0;
}


/* One rank's figures for one frame (gathered on rank 0). */
struct frame_rec {
    double io, up, draw, read, enc, exch, blend, comp, gath, total;
    double classify, accum, warp;   /* CPU renderer phases (0 otherwise) */
    uint64_t bytes_read, bytes_sent, bytes_sent_total, gather_bytes, pixels;
    int rc, fatal;
    char msg[200];
};

/* Slowest rank per phase; bytes sent max and total; pixels max. */
static void aggregate(const struct frame_rec *r, int n, struct frame_rec *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 0; i < n; i++) {
        const struct frame_rec *q = &r[i];
        o->io = fmax(o->io, q->io);
        o->up = fmax(o->up, q->up);
        o->draw = fmax(o->draw, q->draw);
        o->read = fmax(o->read, q->read);
        o->enc = fmax(o->enc, q->enc);
        o->exch = fmax(o->exch, q->exch);
        o->blend = fmax(o->blend, q->blend);
        o->comp = fmax(o->comp, q->comp);
        o->gath = fmax(o->gath, q->gath);
        o->total = fmax(o->total, q->total);
        o->classify = fmax(o->classify, q->classify);
        o->accum = fmax(o->accum, q->accum);
        o->warp = fmax(o->warp, q->warp);
        o->bytes_read += q->bytes_read;
        o->bytes_sent = q->bytes_sent > o->bytes_sent ? q->bytes_sent : o->bytes_sent;
        o->bytes_sent_total += q->bytes_sent;
        o->gather_bytes += q->gather_bytes;
        o->pixels = q->pixels > o->pixels ? q->pixels : o->pixels;
        if (q->rc < 0 && o->rc >= 0)
            o->rc = q->rc;
        o->fatal |= q->fatal;
    }
}

/* ------------------------------------------------------------ renderers */

enum { REND_AUTO, REND_GL, REND_CPU, REND_REF, REND_NONE };

/* GL renderer names of Mesa's software rasterizers: on these the CPU
 * shear-warp renderer is the faster one. */
static int gl_is_software(const char *name)
{
    return !name || strstr(name, "llvmpipe") || strstr(name, "softpipe") ||
           strstr(name, "swrast") || strstr(name, "Software") ||
           strstr(name, "software");
}

static struct tvpal_sw *sw_new(void)
{
    struct tvpal_sw *sw;
    if (tvpal_sw_create(&sw) < 0)
        die_rank(1, "out of memory");
    return sw;
}

static const char *sw_desc(const struct tvpal_sw *sw)
{
    static char b[64];
    int nt = 1;
#ifdef _OPENMP
    nt = omp_get_max_threads();
#endif
    snprintf(b, sizeof b, "shear-warp, %s, %d thread%s", tvpal_sw_simd_name(sw),
             nt, nt == 1 ? "" : "s");
    return b;
}

/* ------------------------------------------------------------ window mode */

struct win_args {
    const char *dir;
    struct tvpal_player_opts po;
    struct tvpal_tf *tfs;
    const char **tf_files;
    unsigned ntf;
    unsigned width, height;
    double ax, ay, zoom, opacity;
    uint32_t a, b, autoplay;
    const char *shot;
    int quiet;
    int renderer;     /* REND_AUTO, REND_GL or REND_CPU */
    unsigned fb_bits, cpu_scale;
};

static int save_shot(const char *path, const uint8_t *rgb, unsigned w,
                     unsigned h, float *scratch, uint8_t *rgb8)
{
    /* tvpal_png_write takes premultiplied floats bottom-up: convert. */
    for (unsigned y = 0; y < h; y++)
        for (unsigned x = 0; x < w; x++) {
            const uint8_t *s = rgb + 3 * ((size_t)(h - 1 - y) * w + x);
            float *d = scratch + 4 * ((size_t)y * w + x);
            for (int c = 0; c < 3; c++)
                d[c] = s[c] / 255.0f;
            d[3] = 1.0f;
        }
    static const float bg[3] = {0, 0, 0};
    return tvpal_png_write(path, scratch, w, h, bg, rgb8);
}

/* What rank 0's window tells every rank before each frame (cluster mode:
 * user input reaches all ranks; all stay on the same timestep). */
struct win_cmd {
    int quit, render, reduce, toggle_mode, reload_tf;
    uint32_t t, tfi, width, height;
    int dir;
    double ax, ay, zoom, opacity;
};

static int run_window(struct tvpal_player *pl, const struct win_args *wa)
{
    struct tvpal_diag d = {{0}};
    const int leader = g_comm.rank == 0, multi = g_comm.size > 1;
    struct tvpal_win *win = NULL;
    struct tvpal_osmesa *octx = NULL;
    unsigned W = wa->width, H = wa->height;
    /* Rank 0 opens the window; the other ranks render off-screen. */
    int rc = leader ? tvpal_win_open(&win, W, H, PROG, &d) : 0;
    check_all(rc, d.msg, 1);
    /* The renderer: the leader's choice (its window's GL decides the
     * default) holds on every rank. */
    int use_cpu = wa->renderer == REND_CPU;
    char why[160] = "";
    if (leader && wa->renderer == REND_AUTO) {
        const char *gname = tvpal_glr_gl_name();
        use_cpu = gl_is_software(gname);
        snprintf(why, sizeof why, "default: the window's GL is %s%s",
                 gname ? gname : "unknown",
                 use_cpu ? ", which draws on the CPU" : "");
    }
    if (multi)
        g_comm.bcast(&g_comm, &use_cpu, sizeof use_cpu, 0);
    rc = !leader && !use_cpu ? tvpal_osmesa_create(&octx, &d) : 0;
    check_all(rc, rc < 0 ? d.msg : "", 1);
    struct tvpal_glr *glr = NULL;
    struct tvpal_sw *sw = NULL;
    struct tvpal_renderer rend;
    if (use_cpu) {
        sw = sw_new();
        tvpal_sw_set_scale(sw, wa->cpu_scale);
        rend = (struct tvpal_renderer){sw, NULL, sw_set, sw_up, sw_draw};
    } else {
        rc = tvpal_glr_create_fb(&glr, W, H, wa->fb_bits, &d);
        check_all(rc, d.msg, 1);
        rend = (struct tvpal_renderer){glr, NULL, gl_set, gl_up, gl_draw};
    }
    if (leader && !wa->quiet)
        fprintf(stderr, PROG ": renderer %s (%s%s%s)\n", use_cpu ? "cpu" : "gl",
                use_cpu ? sw_desc(sw) : tvpal_glr_gl_name(), *why ? "; " : "", why);
    /* The CPU image reaches the window as the compositor's 8-bit frame
     * (with one rank: this rank's image rounded), like a cluster's. */
    const int via_final = multi || use_cpu;
    const struct tvpal_manifest *m = tvpal_player_manifest(pl);
    const uint32_t T = m->steps;
    uint8_t *rgb = malloc(3 * (size_t)W * H), *rgb8 = malloc(3 * (size_t)W * H);
    float *scratch = malloc(sizeof(float) * 4 * W * H);
    float *img = via_final ? malloc(sizeof(float) * 4 * W * H) : NULL;
    uint8_t *final = via_final ? malloc(4 * (size_t)W * H) : NULL;
    struct tvpal_compositor *cx = NULL;
    if (!rgb || !rgb8 || !scratch || (via_final && (!img || !final ||
        tvpal_compositor_create(&cx, W, H, g_comm.size) < 0)))
        die_rank(1, "out of memory");
    struct tvpal_player_opts po = wa->po;
    double ax = wa->ax, ay = wa->ay, zoom = wa->zoom, opacity = wa->opacity;
    unsigned tfi = 0, ntf_all = wa->ntf + 1, shots = 0;
    uint32_t t = wa->a;
    int dir = wa->b >= wa->a ? 1 : -1;
    int playing = wa->autoplay > 0, redraw = 1, reduced = 0, status = 0;
    uint32_t frames = 0;
    double fps = 0, last = tvpal_now();
    char last_err[sizeof d.msg] = "";
    for (;;) {
        struct win_cmd cmd = {0};
        if (leader) {
            struct tvpal_input in;
            tvpal_win_poll(win, !playing && !redraw && !multi, &in);
            if (tvpal_win_should_close(win))
                cmd.quit = 1;
            for (int i = 0; i < in.nkeys; i++) {
                switch (in.keys[i]) {
                case TVPAL_KEY_PLAY: playing = !playing; break;
                case TVPAL_KEY_NEXT: t = t + 1 < T ? t + 1 : t; playing = 0; dir = 1; break;
                case TVPAL_KEY_PREV: t = t > 0 ? t - 1 : 0; playing = 0; dir = -1; break;
                case TVPAL_KEY_FIRST: t = 0; break;
                case TVPAL_KEY_LAST: t = T - 1; break;
                case TVPAL_KEY_REVERSE: dir = -dir; break;
                case TVPAL_KEY_TF_NEXT: tfi = (tfi + 1) % ntf_all; break;
                case TVPAL_KEY_TF_RELOAD: cmd.reload_tf = 1; break;
                case TVPAL_KEY_OPACITY_UP: opacity *= 1.25; break;
                case TVPAL_KEY_OPACITY_DOWN: opacity *= 0.8; break;
                case TVPAL_KEY_MODE: cmd.toggle_mode = 1; break;
                case TVPAL_KEY_ZOOM_IN: zoom *= 1.15; break;
                case TVPAL_KEY_ZOOM_OUT: zoom /= 1.15; break;
                case TVPAL_KEY_SHOT: {
                    char name[64];
                    snprintf(name, sizeof name, "tvpal-shot-%04u.png", shots++);
                    tvpal_win_read(win, rgb);
                    if (save_shot(name, rgb, W, H, scratch, rgb8) == 0 && !wa->quiet)
                        fprintf(stderr, PROG ": saved %s\n", name);
                    break;
                }
                case TVPAL_KEY_QUIT: cmd.quit = 1; break;
                }
                redraw = 1;
            }
            if (in.dragging) {
                ay += in.drag_dx * 0.4;
                ax += in.drag_dy * 0.4;
                redraw = 1;
            }
            if (in.scroll != 0) {
                zoom *= pow(1.1, in.scroll);
                redraw = 1;
            }
            if (in.scrubbing) {
                t = (uint32_t)floor(in.scrub_pos * (T - 1) + 0.5);
                playing = 0;
                redraw = 1;
            }
            if (in.resized && in.width && in.height &&
                (in.width != W || in.height != H)) {
                cmd.width = in.width;
                cmd.height = in.height;
                redraw = 1;
            }
            /* Reduced quality while the user interacts; refine when idle. */
            int interacting = in.dragging || in.scrubbing;
            if (!interacting && reduced)
                redraw = 1;
            if (playing && !redraw) {
                int64_t nt = (int64_t)t + dir;
                if (nt < 0 || nt >= T)
                    nt = dir > 0 ? 0 : T - 1; /* loop */
                t = (uint32_t)nt;
            }
            cmd.render = redraw || playing;
            cmd.reduce = interacting ? 2 : 1;
            cmd.t = t;
            cmd.dir = dir;
            cmd.tfi = tfi;
            cmd.ax = ax;
            cmd.ay = ay;
            cmd.zoom = zoom;
            cmd.opacity = opacity;
        }
        if (multi && g_comm.bcast(&g_comm, &cmd, sizeof cmd, 0) < 0)
            die_rank(1, "MPI broadcast failed");
        if (cmd.quit)
            break;
        if (cmd.reload_tf && cmd.tfi < wa->ntf) {
            struct tvpal_tf nt;
            if (tvpal_tf_load(wa->tf_files[cmd.tfi], m->value_min,
                              m->value_max, &nt, &d) < 0) {
                if (leader)
                    fprintf(stderr, PROG ": %s: %s (keeping the old one)\n",
                            wa->tf_files[cmd.tfi], d.msg);
            } else {
                wa->tfs[cmd.tfi] = nt;
            }
        }
        if (cmd.toggle_mode) {
            /* Reopen with the other data mode; the pause is the cost of
             * loading (in-core) or of nothing (stream). */
            struct tvpal_player *np;
            po.incore = !po.incore;
            double s0 = tvpal_now();
            rc = tvpal_player_open(&np, multi ? tvpal_player_dir(pl) : wa->dir,
                                   &po, &d);
            check_all(rc, d.msg, 1);
            tvpal_player_close(pl);
            pl = np;
            m = tvpal_player_manifest(pl);
            if (leader && !wa->quiet)
                fprintf(stderr, PROG ": data now %s (%.0f ms)\n",
                        po.incore ? "in-core" : "streamed",
                        (tvpal_now() - s0) * 1e3);
        }
        if (cmd.width && cmd.height) {
            W = cmd.width;
            H = cmd.height;
            if (glr) {
                tvpal_glr_free(glr);
                rc = tvpal_glr_create_fb(&glr, W, H, wa->fb_bits, &d);
                check_all(rc, d.msg, 1);
                rend = (struct tvpal_renderer){glr, NULL, gl_set, gl_up, gl_draw};
            }
            free(rgb);
            free(rgb8);
            free(scratch);
            free(img);
            free(final);
            tvpal_compositor_free(cx);
            cx = NULL;
            rgb = malloc(3 * (size_t)W * H);
            rgb8 = malloc(3 * (size_t)W * H);
            scratch = malloc(sizeof(float) * 4 * W * H);
            img = via_final ? malloc(sizeof(float) * 4 * W * H) : NULL;
            final = via_final ? malloc(4 * (size_t)W * H) : NULL;
            if (!rgb || !rgb8 || !scratch || (via_final && (!img || !final ||
                tvpal_compositor_create(&cx, W, H, g_comm.size) < 0)))
                die_rank(1, "out of memory");
        }
        if (!cmd.render)
            continue;
        tvpal_player_set_tf(pl, &wa->tfs[cmd.tfi], cmd.opacity);
        tvpal_player_set_reduce(pl, (unsigned)cmd.reduce);
        reduced = cmd.reduce > 1;
        struct tvpal_view v = {.width = W, .height = H, .ax_deg = cmd.ax,
                               .ay_deg = cmd.ay, .zoom = cmd.zoom};
        memcpy(v.dims, m->dims, sizeof v.dims);
        tvpal_view_setup(&v);
        struct tvpal_frame_stats st;
        d.msg[0] = 0;
        rc = tvpal_player_frame(pl, &v, cmd.t, cmd.dir, &rend, img, &st, &d);
        if (rc < 0 && strcmp(d.msg, last_err)) {
            snprintf(last_err, sizeof last_err, "%s", d.msg);
            if (multi)
                fprintf(stderr, PROG ": rank %d: step %u: %s (keeping the last "
                        "good data)\n", g_comm.rank, cmd.t, d.msg);
            else
                fprintf(stderr, PROG ": step %u: %s (keeping the last good "
                        "data)\n", cmd.t, d.msg);
            status = 1;
            if (!st.rendered)
                die_rank(2, "cannot render step %u", cmd.t);
        }
        if (via_final) {
            struct tvpal_compose_stats cs;
            if (tvpal_composite(cx, &g_comm, TVPAL_COMPOSE_BSWAP, !v.descending,
                                img, final, &cs) < 0)
                die_rank(1, "compositing failed at step %u", cmd.t);
        }
        redraw = 0;
        frames++;
        if (!leader)
            continue;
        if (via_final)
            tvpal_win_show(win, final, W, H);
        else
            tvpal_glr_blit(glr, 0, TVPAL_SLIDER_HEIGHT);
        if (wa->shot)
            tvpal_win_read(win, rgb);
        tvpal_win_present(win, T > 1 ? (double)cmd.t / (T - 1) : 0.0);
        double now = tvpal_now();
        double inst = now > last ? 1.0 / (now - last) : 0;
        fps = frames > 1 ? 0.8 * fps + 0.2 * inst : inst;
        last = now;
        char title[256];
        snprintf(title, sizeof title, PROG " - t=%u/%u - %.1f fps - %s%s - "
                 "axis %c - %s - %s%s%s", cmd.t, T - 1, fps,
                 tvpal_player_io_name(pl), po.incore ? "" : " stream",
                 "xyz"[v.axis], use_cpu ? "cpu" : "gl", wa->tfs[cmd.tfi].name,
                 reduced ? " - preview" : "",
                 multi ? " - cluster" : "");
        tvpal_win_title(win, title);
        if (wa->autoplay && frames >= wa->autoplay) {
            /* Tell everyone to stop at the next round. */
            playing = 0;
            redraw = 0;
            struct win_cmd q = {.quit = 1};
            if (multi)
                g_comm.bcast(&g_comm, &q, sizeof q, 0);
            break;
        }
        if (playing && wa->autoplay) {
            int64_t nt = (int64_t)t + dir;
            if (nt < 0 || nt >= T) {
                struct win_cmd q = {.quit = 1};
                if (multi)
                    g_comm.bcast(&g_comm, &q, sizeof q, 0);
                break;
            }
            t = (uint32_t)nt;
            redraw = 1;
        }
    }
    if (leader && wa->shot && save_shot(wa->shot, rgb, W, H, scratch, rgb8) < 0)
        die(1, "%s: cannot write", wa->shot);
    if (leader)
        printf("frames=%u last_step=%u fps=%.3f mode=%s ranks=%d renderer=%s\n",
               frames, t, fps, tvpal_player_io_name(pl), g_comm.size,
               use_cpu ? "cpu" : "gl");
    tvpal_glr_free(glr);
    tvpal_sw_free(sw);
    tvpal_win_close(win);
    tvpal_osmesa_free(octx);
    tvpal_player_close(pl);
    tvpal_compositor_free(cx);
    free(rgb);
    free(rgb8);
    free(scratch);
    free(img);
    free(final);
#ifdef HAVE_MPI
    if (multi)
        tvpal_comm_mpi_finalize(&g_comm);
#endif
    return status;
}

int main(int argc, char **argv)
{
    static const struct option lopts[] = {
        {"headless", no_argument, 0, 'H'},
        {"window", no_argument, 0, 'w'},
        {"spin", required_argument, 0, 'Y'},
        {"shard-dir", required_argument, 0, 'G'},
        {"composite", required_argument, 0, 'Q'},
        {"fb", required_argument, 0, 'F'},
        {"cpu-scale", required_argument, 0, 'k'},
        {"repeat", required_argument, 0, 'K'},
        {"tf-cycle", no_argument, 0, 'T'},
        {"jumps", required_argument, 0, 'J'},
        {"autoplay", required_argument, 0, 'A'},
        {"screenshot", required_argument, 0, 'C'},
        {"steps", required_argument, 0, 's'},
        {"size", required_argument, 0, 'S'},
        {"rotate", required_argument, 0, 'r'},
        {"zoom", required_argument, 0, 'z'},
        {"tf", required_argument, 0, 't'},
        {"opacity", required_argument, 0, 'O'},
        {"renderer", required_argument, 0, 'R'},
        {"mode", required_argument, 0, 'm'},
        {"io", required_argument, 0, 'I'},
        {"prefetch", required_argument, 0, 'P'},
        {"no-direct", no_argument, 0, 'D'},
        {"mem", required_argument, 0, 'M'},
        {"output", required_argument, 0, 'o'},
        {"csv", required_argument, 0, 'c'},
        {"strict", no_argument, 0, 'x'},
        {"ref-psnr", no_argument, 0, 'e'},
        {"quiet", no_argument, 0, 'q'},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0}};
    const char *steps_s = NULL, *tf_path = NULL, *outdir = NULL,
               *csv_path = NULL;
    const char *env_rank = getenv("OMPI_COMM_WORLD_RANK");
    g_env_rank = env_rank ? atoi(env_rank) : 0;
    unsigned width = 512, height = 512;
    double ax = 20, ay = 30, zoom = 1, opacity = 1;
    int renderer = REND_AUTO, strict = 0, quiet = 0, c;
    uint32_t mem_mib = 0;
    struct tvpal_player_opts po = {.incore = 0, .io = TVPAL_IO_URING,
                                   .prefetch = 4, .direct = 1};
    int mode_window = -1; /* -1: decide from the display */
    double spin = 0;
    const char *shard_pat = NULL;
    enum tvpal_compose_kind ckind = TVPAL_COMPOSE_BSWAP;
    uint32_t fb_bits = 32, cpu_scale = 0;
    int fb_given = 0, scale_given = 0;
    uint32_t repeat = 1, jumps = 0;
    int tf_cycle = 0, ref_psnr = 0;
    uint32_t autoplay = 0;
    const char *shot = NULL;
    const char *tf_files[16];
    unsigned ntf = 0;
    while ((c = getopt_long(argc, argv, "s:S:r:z:t:m:o:wqhV", lopts, NULL)) != -1) {
        switch (c) {
        case 'H': mode_window = 0; break;
        case 'w': mode_window = 1; break;
        case 'A':
            if (tvpal_parse_u32(optarg, 1, UINT32_MAX, &autoplay) < 0)
                die(2, "--autoplay \"%s\": expected a frame count >= 1", optarg);
            break;
        case 'C': shot = optarg; break;
        case 'Y':
            if (tvpal_parse_double(optarg, &spin) < 0)
                die(2, "--spin \"%s\": expected degrees", optarg);
            break;
        case 'K':
            if (tvpal_parse_u32(optarg, 1, 100000, &repeat) < 0)
                die(2, "--repeat \"%s\": expected 1..100000", optarg);
            break;
        case 'T': tf_cycle = 1; break;
        case 'G': shard_pat = optarg; break;
        case 'Q':
            if (!strcmp(optarg, "gather"))
                ckind = TVPAL_COMPOSE_GATHER;
            else if (strcmp(optarg, "bswap"))
                die(2, "--composite \"%s\": expected bswap or gather", optarg);
            break;
        case 'F':
            fb_given = 1;
            if (tvpal_parse_u32(optarg, 8, 32, &fb_bits) < 0 ||
                (fb_bits != 8 && fb_bits != 16 && fb_bits != 32))
                die(2, "--fb \"%s\": expected 8, 16 or 32", optarg);
            break;
        case 'k':
            scale_given = 1;
            if (strcmp(optarg, "auto") && tvpal_parse_u32(optarg, 1, 8, &cpu_scale) < 0)
                die(2, "--cpu-scale \"%s\": expected auto or 1..8", optarg);
            break;
        case 'J':
            if (tvpal_parse_u32(optarg, 1, UINT32_MAX, &jumps) < 0)
                die(2, "--jumps \"%s\": expected K >= 1", optarg);
            break;
        case 's': steps_s = optarg; break;
        case 'S':
            if (sscanf(optarg, "%ux%u", &width, &height) != 2 || !width ||
                !height || width > 16384 || height > 16384)
                die(2, "--size \"%s\": expected WxH, each 1..16384", optarg);
            break;
        case 'r':
            if (sscanf(optarg, "%lf,%lf", &ax, &ay) != 2 || !isfinite(ax) ||
                !isfinite(ay))
                die(2, "--rotate \"%s\": expected AX,AY in degrees", optarg);
            break;
        case 'z':
            if (tvpal_parse_double(optarg, &zoom) < 0 || zoom <= 0)
                die(2, "--zoom \"%s\": expected a number > 0", optarg);
            break;
        case 't':
            if (ntf == 16)
                die(2, "--tf: at most 16 transfer functions");
            tf_files[ntf++] = tf_path = optarg;
            break;
        case 'O':
            if (tvpal_parse_double(optarg, &opacity) < 0 || opacity < 0)
                die(2, "--opacity \"%s\": expected a number >= 0", optarg);
            break;
        case 'R':
            if (!strcmp(optarg, "ref"))
                renderer = REND_REF;
            else if (!strcmp(optarg, "cpu"))
                renderer = REND_CPU;
            else if (!strcmp(optarg, "none"))
                renderer = REND_NONE;
            else if (!strcmp(optarg, "gl"))
                renderer = REND_GL;
            else
                die(2, "--renderer \"%s\": expected gl, cpu, ref or none",
                    optarg);
            break;
        case 'm':
            if (!strcmp(optarg, "incore"))
                po.incore = 1;
            else if (strcmp(optarg, "stream"))
                die(2, "--mode \"%s\": expected incore or stream", optarg);
            break;
        case 'I':
            if (!strcmp(optarg, "pread"))
                po.io = TVPAL_IO_PREAD;
            else if (strcmp(optarg, "uring"))
                die(2, "--io \"%s\": expected uring or pread", optarg);
            break;
        case 'P':
            if (tvpal_parse_u32(optarg, 0, 64, &po.prefetch) < 0)
                die(2, "--prefetch \"%s\": expected 0..64", optarg);
            break;
        case 'D': po.direct = 0; break;
        case 'M':
            if (tvpal_parse_u32(optarg, 1, UINT32_MAX, &mem_mib) < 0)
                die(2, "--mem \"%s\": expected MiB >= 1", optarg);
            break;
        case 'o': outdir = optarg; break;
        case 'c': csv_path = optarg; break;
        case 'x': strict = 1; break;
        case 'e': ref_psnr = 1; break;
        case 'q': quiet = 1; break;
        case 'h': usage(stdout); return 0;
        case 'V':
            printf(PROG " " PACKAGE_VERSION " (window: %s, gl: %s)\n",
#ifdef TVPAL_HAVE_WINDOW
                   "yes",
#else
                   "no",
#endif
#ifdef TVPAL_HAVE_GL
                   "yes");
#else
                   "no");
#endif
            return 0;
        default:
            fprintf(stderr, "Try '" PROG " --help'.\n");
            return 2;
        }
    }
    if (optind != argc - 1)
        die(2, "expected one OUTDIR (try --help)");
    const char *dir = argv[optind];

    struct tvpal_diag d = {{0}};
    struct tvpal_player *pl = NULL;
    po.mem_budget = (uint64_t)mem_mib << 20;
    int cluster = 0;
#ifdef HAVE_MPI
    if (getenv("OMPI_COMM_WORLD_SIZE")) { /* started by mpirun */
        if (tvpal_comm_mpi_init(&argc, &argv) < 0 || tvpal_comm_mpi(&g_comm) < 0)
            die_rank(1, "cannot initialize MPI");
        cluster = 1;
    } else
#endif
        tvpal_comm_self(&g_comm);
    g_have_comm = 1;
    char *node_dir = NULL;
    if (cluster) {
        /* Rank r reads only its own shard: OUTDIR/node-r by default. */
        const char *pat = shard_pat ? shard_pat : NULL;
        char rs[16];
        snprintf(rs, sizeof rs, "%d", g_comm.rank);
        if (!pat) {
            if (asprintf(&node_dir, "%s/node-%s", dir, rs) < 0)
                die_rank(1, "out of memory");
        } else {
            size_t cap = strlen(pat) * 4 + 32, o = 0;
            node_dir = malloc(cap);
            if (!node_dir)
                die_rank(1, "out of memory");
            for (const char *q = pat; *q && o + 16 < cap; q++) {
                if (q[0] == '%' && q[1] == 'r') {
                    o += (size_t)snprintf(node_dir + o, cap - o, "%s", rs);
                    q++;
                } else {
                    node_dir[o++] = *q;
                }
            }
            node_dir[o] = 0;
        }
        po.rank = (uint32_t)g_comm.rank;
        po.nranks = (uint32_t)g_comm.size;
    }
    int orc = tvpal_player_open(&pl, cluster ? node_dir : dir, &po, &d);
    check_all(orc, d.msg, 2);
    const struct tvpal_manifest *m = tvpal_player_manifest(pl);
    uint32_t a = 0, b = m->steps - 1;
    if (steps_s) {
        if (sscanf(steps_s, "%u:%u", &a, &b) != 2 || a >= m->steps ||
            b >= m->steps)
            die(2, "--steps \"%s\": expected A:B within 0..%u", steps_s,
                m->steps - 1);
    }
    /* Transfer functions: every --tf file (checked now), then the default. */
    static struct tvpal_tf tfs[17];
    for (unsigned i = 0; i < ntf; i++) {
        char em[300] = "";
        int trc = tvpal_tf_load(tf_files[i], m->value_min, m->value_max,
                                &tfs[i], &d);
        if (trc < 0)
            snprintf(em, sizeof em, "%s: %s", tf_files[i], d.msg);
        check_all(trc, em, 2);
    }
    tvpal_tf_default(m->value_min, m->value_max, m->histogram,
                     TVPAL_HIST_BINS, &tfs[ntf]);
    tvpal_player_set_tf(pl, &tfs[0], opacity);
    (void)tf_path;
    if (mem_mib && g_comm.rank == 0) {
        double per_step = (double)tvpal_player_axis_bytes(pl) / m->steps;
        double fit = (double)mem_mib * 1048576.0 / per_step;
        printf("memory: %u MiB holds %.0f timesteps of one axis (%.2f MiB per "
               "timestep; %u in the dataset%s)\n", mem_mib, floor(fit),
               per_step / 1048576.0, m->steps,
               fit >= m->steps ? ": in-core fits" : ": stream from disk");
    }

    /* Options that belong to one renderer choose it, or are refused with
     * the other. */
    const char *why = "";
    if (fb_given && renderer == REND_AUTO) {
        renderer = REND_GL;
        why = "; --fb asks for a GL framebuffer";
    }
    if (fb_given && renderer != REND_GL)
        die(2, "--fb: the GL framebuffer's depth; only with --renderer gl "
            "(the cpu renderer accumulates in float)");
    if (scale_given && renderer == REND_AUTO) {
        renderer = REND_CPU;
        why = "; --cpu-scale asks for it";
    }
    if (scale_given && renderer != REND_CPU)
        die(2, "--cpu-scale: the shear-warp intermediate image's resolution; "
            "only with --renderer cpu");
    if (mode_window < 0)
        mode_window = getenv("DISPLAY") && *getenv("DISPLAY") && !outdir;
    if (mode_window && ref_psnr)
        die(2, "--ref-psnr: headless only");
    if (mode_window && (renderer == REND_REF || renderer == REND_NONE))
        die(2, "--renderer %s: headless only (the window renders with gl or "
            "cpu)", renderer == REND_REF ? "ref" : "none");
    if (mode_window) {
        struct win_args wa = {
            .dir = dir, .po = po, .tfs = tfs, .tf_files = tf_files, .ntf = ntf,
            .width = width, .height = height, .ax = ax, .ay = ay,
            .zoom = zoom, .opacity = opacity, .a = a, .b = b,
            .autoplay = autoplay, .shot = shot, .quiet = quiet,
            .renderer = renderer, .fb_bits = fb_bits, .cpu_scale = cpu_scale};
        return run_window(pl, &wa);
    }
    if (autoplay || shot)
        die(2, "--autoplay and --screenshot need the window (--window)");

    /* Renderer. */
    struct tvpal_renderer rend;
    struct tvpal_osmesa *ctx = NULL;
    struct tvpal_glr *glr = NULL;
    struct tvpal_sw *sw = NULL;
    /* Headless GL is OSMesa, a software rasterizer: the CPU renderer is
     * the faster one there. */
    if (renderer == REND_AUTO) {
        renderer = REND_CPU;
        why = "; default: headless GL is OSMesa, which draws on the CPU";
    }
    const int no_render = renderer == REND_NONE, use_cpu = renderer == REND_CPU,
              use_ref = renderer == REND_REF;
    if (no_render) {
        rend = (struct tvpal_renderer){NULL, NULL, ref_set, ref_up, none_draw};
    } else if (use_cpu) {
        sw = sw_new();
        tvpal_sw_set_scale(sw, cpu_scale);
        rend = (struct tvpal_renderer){sw, NULL, sw_set, sw_up, sw_draw};
    } else if (use_ref) {
        ref_buf = malloc(sizeof(double) * 4 * width * height);
        if (!ref_buf)
            die(1, "out of memory");
        rend = (struct tvpal_renderer){NULL, NULL, ref_set, ref_up, ref_draw};
    } else {
        int grc = tvpal_osmesa_create(&ctx, &d);
        if (grc == 0)
            grc = tvpal_glr_create_fb(&glr, width, height, fb_bits, &d);
        check_all(grc, d.msg, 1);
        rend = (struct tvpal_renderer){glr, NULL, gl_set, gl_up, gl_draw};
    }
    /* --ref-psnr: the reference renderer draws every frame again. */
    struct tvpal_renderer rend_ref = {NULL, NULL, ref_set, ref_up, ref_draw};
    float *ref_rgba = NULL;
    if (ref_psnr) {
        if (g_comm.size > 1 || no_render || use_ref)
            die(2, "--ref-psnr: one rank, with the cpu or gl renderer");
        if (!ref_buf && !(ref_buf = malloc(sizeof(double) * 4 * width * height)))
            die(1, "out of memory");
        if (!(ref_rgba = malloc(sizeof(float) * 4 * width * height)))
            die(1, "out of memory");
    }
    float *rgba = malloc(sizeof(float) * 4 * width * height);
    /* The frame as rank 0 gets it from the compositor: premultiplied
     * 8-bit RGBA (with one rank, just this rank's image rounded). */
    uint8_t *final = malloc(4 * (size_t)width * height);
    uint8_t *rgb8 = malloc(3 * (size_t)width * height);
    struct tvpal_compositor *cx = NULL;
    if (!rgba || !rgb8 || !final ||
        tvpal_compositor_create(&cx, width, height, g_comm.size) < 0)
        die_rank(1, "out of memory");
    struct frame_rec *recs = NULL;
    if (g_comm.rank == 0 &&
        !(recs = calloc((size_t)g_comm.size, sizeof *recs)))
        die_rank(1, "out of memory");
    if (g_comm.rank != 0) {
        outdir = NULL; /* rank 0 writes frames, CSV and the summary */
        csv_path = NULL;
        quiet = 1;
    }
    FILE *csv = NULL;
    char *csv_default = NULL;
    if (outdir) {
        if (tvpal_mkdirs(outdir) < 0)
            die(2, "%s: cannot create: %s", outdir, strerror(errno));
        if (!csv_path && asprintf(&csv_default, "%s/timing.csv", outdir) >= 0)
            csv_path = csv_default;
    }
    if (csv_path) {
        if (!(csv = fopen(csv_path, "w")))
            die(2, "%s: cannot write: %s", csv_path, strerror(errno));
        fprintf(csv, "step,axis,io_ms,upload_ms,draw_ms,readback_ms,total_ms,"
                "bytes_read,slices_drawn,slices_skipped,slice_uploads,"
                "axis_switch_ms,jump,stride,encode_ms,exchange_ms,blend_ms,"
                "composite_ms,gather_ms,bytes_sent_max,bytes_sent_total,"
                "gather_bytes_total,pixels_blended_max,ranks,"
                "sw_classify_ms,sw_composite_ms,sw_warp_ms,psnr_ref\n");
    }
    int digits = 4;
    for (uint32_t x = 10000; x <= m->steps - 1 && digits < 10; x *= 10)
        digits++;

    struct tvpal_view v = {.width = width, .height = height, .ax_deg = ax,
                           .ay_deg = ay, .zoom = zoom};
    memcpy(v.dims, m->dims, sizeof v.dims);
    tvpal_view_setup(&v);
    const int dir_step = b >= a ? 1 : -1;
    const uint32_t nframes = (b >= a ? b - a : a - b) + 1;
    double sum_io = 0, sum_up = 0, sum_draw = 0, sum_read = 0, sum_comp = 0;
    double sum_psnr = 0;
    uint64_t sum_bytes = 0;
    unsigned errors = 0;
    char last_err[sizeof d.msg] = "";
    const double t_start = tvpal_now();
    if (!quiet)
        fprintf(stderr, PROG ": %s: %ux%ux%u, %u steps, window %u; axis %c, "
                "data %s, renderer %s (%s%s)\n", dir, m->dims[0], m->dims[1],
                m->dims[2], m->steps, m->window, "xyz"[v.axis],
                po.incore ? "in-core" : "streamed",
                no_render ? "none" : use_cpu ? "cpu" : use_ref ? "ref" : "gl",
                no_render ? "read and decode only" : use_cpu ? sw_desc(sw)
                : use_ref ? "double-precision reference" : tvpal_glr_gl_name(),
                why);
    uint64_t rng = 0x9E3779B97F4A7C15ull;
    for (uint32_t i = 0; i < nframes; i++) {
        uint32_t t = a + (uint32_t)((int)i * dir_step);
        int jump = 0;
        if (jumps && i > 0 && i % jumps == 0) {
            /* xorshift: a reproducible random timestep */
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            t = (uint32_t)(rng % m->steps);
            jump = 1;
        }
        if (spin != 0 && i > 0) {
            v.ay_deg += spin;
            tvpal_view_setup(&v);
        }
        if (tf_cycle && ntf > 1)
            tvpal_player_set_tf(pl, &tfs[i % ntf], opacity);
        struct tvpal_frame_stats st;
        d.msg[0] = 0;
        double f0 = tvpal_now();
        int rc = tvpal_player_frame(pl, &v, t, dir_step, &rend, rgba, &st, &d);
        for (uint32_t k = 1; k < repeat && rc >= 0; k++)
            rc = tvpal_player_frame(pl, &v, t, dir_step, &rend, rgba, &st, &d);
        if (!st.rendered && rc < 0 && g_comm.size == 1)
            die(2, "step %u: %s", t, d.msg);
        double up = 0, dr = st.draw_ms, rb = 0;
        if (glr)
            tvpal_glr_times(glr, &up, &dr, &rb);
        double swc = 0, swa = 0, sww = 0;
        if (sw)
            tvpal_sw_times(sw, &swc, &swa, &sww);
        /* Sort-last compositing of the ranks' images (rank 0 gets it). */
        struct tvpal_compose_stats cs;
        double c0 = tvpal_now();
        if (tvpal_composite(cx, &g_comm, ckind, !v.descending, rgba, final,
                            &cs) < 0)
            die_rank(1, "compositing failed at step %u", t);
        double comp_ms = (tvpal_now() - c0) * 1e3;
        double total = (tvpal_now() - f0) * 1e3;
        double psnr = 0;
        if (ref_psnr) {
            /* The same frame by the reference renderer (after the timings:
             * switching renderers makes the next frame upload every slice
             * again, so timings of a --ref-psnr run are not representative). */
            struct tvpal_frame_stats st2;
            if (tvpal_player_frame(pl, &v, t, dir_step, &rend_ref, ref_rgba,
                                   &st2, &d) < 0 && !st2.rendered)
                die(2, "step %u: reference: %s", t, d.msg);
            double e = 0;
            const size_t np = (size_t)4 * width * height;
            for (size_t q = 0; q < np; q++)
                e += ((double)rgba[q] - ref_buf[q]) * ((double)rgba[q] - ref_buf[q]);
            e /= (double)np;
            psnr = e > 0 ? 10 * log10(1.0 / e) : INFINITY;
            sum_psnr += psnr;
        }
        /* Per-rank figures to rank 0: the CSV shows the slowest rank per
         * phase (as the paper did), bytes and pixels per rank. */
        struct frame_rec me = {
            .io = st.io_ms, .up = st.upload_ms + up, .draw = dr, .read = rb,
            .enc = cs.encode_ms, .exch = cs.exchange_ms, .blend = cs.blend_ms,
            .comp = comp_ms, .gath = cs.gather_ms, .total = total,
            .classify = swc, .accum = swa, .warp = sww,
            .bytes_read = st.bytes_read, .bytes_sent = cs.bytes_sent,
            .gather_bytes = cs.gather_bytes, .pixels = cs.pixels_blended,
            .rc = rc, .fatal = rc < 0 && (strict || !st.rendered ||
                                          rc == TVPAL_E_SYS ||
                                          rc == TVPAL_E_NOMEM)};
        snprintf(me.msg, sizeof me.msg, "%s", rc < 0 ? d.msg : "");
        struct frame_rec agg = me;
        if (g_comm.size > 1) {
            if (g_comm.gather(&g_comm, &me, sizeof me, recs) < 0)
                die_rank(1, "MPI gather failed");
            if (g_comm.rank == 0)
                aggregate(recs, g_comm.size, &agg);
        }
        int stop = 0;
        if (g_comm.rank == 0) {
            for (int r = 0; r < g_comm.size; r++) {
                const struct frame_rec *q = g_comm.size > 1 ? &recs[r] : &me;
                if (q->rc >= 0 || !strcmp(q->msg, last_err))
                    continue;
                /* A bad record is retried every frame that needs it; it is
                 * reported (and counted) once. */
                errors++;
                snprintf(last_err, sizeof last_err, "%s", q->msg);
                if (g_comm.size > 1)
                    fprintf(stderr, PROG ": rank %d: step %u: %s%s\n", r, t,
                            q->msg, strict ? "" : " (keeping the last good data)");
                else
                    fprintf(stderr, PROG ": step %u: %s%s\n", t, q->msg,
                            strict ? "" : " (keeping the last good data)");
            }
            stop = agg.fatal;
        }
        g_comm.bcast(&g_comm, &stop, sizeof stop, 0);
        if (stop)
            die(agg.rc == TVPAL_E_SYS || agg.rc == TVPAL_E_NOMEM ? 1 : 2,
                "stopped at step %u", t);
        if (g_comm.rank != 0)
            continue;
        sum_io += agg.io;
        sum_up += agg.up;
        sum_draw += agg.draw;
        sum_read += agg.read;
        sum_comp += agg.comp;
        sum_bytes += agg.bytes_read;
        if (outdir) {
            char *path;
            if (asprintf(&path, "%s/t%0*u.png", outdir, digits, t) < 0)
                die(1, "out of memory");
            static const float bg[3] = {0, 0, 0};
            if (tvpal_png_write8(path, final, width, height, bg, rgb8) < 0)
                die(1, "%s: cannot write: %s", path, strerror(errno));
            free(path);
        }
        if (csv)
            fprintf(csv, "%u,%c,%.3f,%.3f,%.3f,%.3f,%.3f,%llu,%u,%u,%u,%.3f,"
                    "%d,%u,%.3f,%.3f,%.3f,%.3f,%.3f,%llu,%llu,%llu,%llu,%d,"
                    "%.3f,%.3f,%.3f,%.3f\n",
                    t, "xyz"[st.axis], agg.io, agg.up, agg.draw, agg.read,
                    agg.total, (unsigned long long)agg.bytes_read, st.drawn,
                    st.skipped, st.uploads, st.axis_switch_ms, jump, st.stride,
                    agg.enc, agg.exch, agg.blend, agg.comp, agg.gath,
                    (unsigned long long)agg.bytes_sent,
                    (unsigned long long)agg.bytes_sent_total,
                    (unsigned long long)agg.gather_bytes,
                    (unsigned long long)agg.pixels, g_comm.size,
                    agg.classify, agg.accum, agg.warp, ref_psnr ? psnr : NAN);
    }
    double el = tvpal_now() - t_start;
    if (g_comm.rank != 0) {
        tvpal_glr_free(glr);
        tvpal_osmesa_free(ctx);
        tvpal_player_close(pl);
        tvpal_compositor_free(cx);
#ifdef HAVE_MPI
        if (cluster)
            tvpal_comm_mpi_finalize(&g_comm);
#endif
        return 0;
    }
    if (csv && fclose(csv) != 0)
        die(1, "%s: write error", csv_path);
    if (!quiet && outdir)
        fprintf(stderr, PROG ": %u frames in %s/\n", nframes, outdir);
    printf("fps=%.3f frames=%u io_ms=%.3f upload_ms=%.3f draw_ms=%.3f "
           "readback_ms=%.3f composite_ms=%.3f ranks=%d bytes_read=%llu "
           "incore_mib=%.1f mode=%s renderer=%s errors=%u\n",
           nframes / (el > 0 ? el : 1e-9), nframes, sum_io / nframes,
           sum_up / nframes, sum_draw / nframes, sum_read / nframes,
           sum_comp / nframes, g_comm.size, (unsigned long long)sum_bytes,
           tvpal_player_incore_bytes(pl) / 1048576.0, tvpal_player_io_name(pl),
           no_render ? "none" : use_cpu ? "cpu" : use_ref ? "ref" : "gl", errors);
    if (ref_psnr)
        printf("psnr_ref=%.3f\n", sum_psnr / nframes);
    tvpal_glr_free(glr);
    tvpal_osmesa_free(ctx);
    tvpal_player_close(pl);
    tvpal_compositor_free(cx);
    tvpal_sw_free(sw);
    free(final);
    free(recs);
    free(node_dir);
    free(rgba);
    free(rgb8);
    free(ref_buf);
    free(ref_rgba);
#ifdef HAVE_MPI
    if (cluster)
        tvpal_comm_mpi_finalize(&g_comm);
#endif
    free(csv_default);
    return errors ? 1 : 0;
}
