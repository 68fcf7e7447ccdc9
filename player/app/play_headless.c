/* play_headless.c: the headless loop of tvpal-play: renders a range of
 * timesteps off-screen, composites the ranks' images (sort-last), and on
 * rank 0 writes PNG frames or a movie, the timing CSV, the progress and
 * the summary line. */
#define _GNU_SOURCE
#include "play.h"
#include "play_annot.h"
#include "play_cluster.h"
#include "play_progress.h"
#include "play_progressive.h"
#include "play_renderer.h"
#include "play_timing.h"
#include "tvpal_clock.h"
#include "tvpal_fs.h"
#include "tvpal_movie.h"
#include "tvpal_png.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG PLAY_PROG

/* Everything one headless run holds; sized once, nothing per frame. */
struct headless {
    struct play_session *s;
    const struct play_opts *o;
    struct play_renderer pr;
    struct tvpal_ref *ref;          /* --ref-psnr: the reference renderer */
    struct tvpal_renderer rref;
    float *ref_rgba;
    float *rgba;                    /* this rank's image */
    uint8_t *final, *rgb8;          /* composited frame (rank 0), PNG rows */
    struct tvpal_compositor *cx;
    struct play_annot pa;           /* rank 0 with frames to write */
    struct play_rank_rec *recs;     /* rank 0: one per rank */
    const char *outdir, *csv_path;  /* rank 0 only */
    const char *movie_path;         /* rank 0, -o FILE.mp4|.webm */
    struct tvpal_movie *movie;      /* its ffmpeg, while open */
    char *csv_default;
    FILE *csv;
    struct play_progress progress;
    int quiet, digits;
    struct tvpal_view v;            /* level 0's view */
    unsigned level;                 /* this frame's level of detail, */
    unsigned full;                  /* its view's own (--progressive) */
    struct tvpal_player *lpl;       /* its player (s->lvl[level]) */
    struct tvpal_view vl;           /* and v for it */
    int dir_step;
    uint32_t nsteps;                /* A..B */
    uint32_t nframes;               /* those --loop times */
    uint32_t cur;                   /* the step of the last frame */
    /* --progressive: which level each frame draws (play_progressive.h);
     * a clock with --fps. */
    int progressive;
    struct play_prog prog;
    double stage_ms;                /* the last frame's stager time, */
    uint64_t bytes_needed;          /* and its own records' bytes */
    struct tvpal_diag prog_diag;    /* prog.load_rc's */
    unsigned errors;
    char last_err[TVPAL_DIAG_MAX];
    struct play_totals tot;
    uint64_t rng;
};

static void setup_renderers(struct headless *h)
{
    const struct play_opts *o = h->o;
    struct tvpal_diag d = {{0}};
    int rc = play_renderer_open(&h->pr, o->renderer, o->width, o->height,
                                o->fb_bits, o->cpu_scale, o->exact, 1, &d);
    play_check_all(rc, d.msg, 1);
    if (o->ref_psnr) {
        if (tvpal_ref_create(&h->ref, (size_t)o->width * o->height) < 0 ||
            !(h->ref_rgba = malloc(sizeof(float) * 4 * o->width * o->height)))
            play_die(1, "out of memory");
        tvpal_ref_renderer(h->ref, &h->rref);
    }
}

static void setup_buffers(struct headless *h)
{
    const unsigned W = h->o->width, H = h->o->height;
    h->rgba = malloc(sizeof(float) * 4 * W * H);
    /* The frame as rank 0 gets it from the compositor: premultiplied
     * 8-bit RGBA (with one rank, just this rank's image rounded). */
    h->final = malloc(4 * (size_t)W * H);
    h->rgb8 = malloc(3 * (size_t)W * H);
    if (!h->rgba || !h->rgb8 || !h->final ||
        tvpal_compositor_create(&h->cx, W, H, play_comm.size) < 0)
        play_die_rank(1, "out of memory");
    if (play_comm.rank == 0 &&
        !(h->recs = calloc((size_t)play_comm.size, sizeof *h->recs)))
        play_die_rank(1, "out of memory");
}

/* The movie being written, for play_die's exit: a run that stops leaves
 * no movie and no temporary. */
static struct tvpal_movie *open_movie;

static void abort_movie(void)
{
    tvpal_movie_abort(open_movie);
    open_movie = NULL;
}

/* -o FILE.mp4|.webm: rank 0 starts ffmpeg now, so that a missing one or
 * an unwritable place is said before any frame is drawn (every rank
 * stops then). */
static void open_movie_output(struct headless *h)
{
    const struct play_opts *o = h->o;
    struct tvpal_diag d = {{0}};
    char msg[TVPAL_DIAG_MAX + 512] = "";
    int rc = 0;
    /* A dead ffmpeg makes a write fail with EPIPE, reported, instead of
     * SIGPIPE ending the run without a word. */
    signal(SIGPIPE, SIG_IGN);
    if (h->movie_path &&
        (rc = tvpal_movie_open(&h->movie, h->movie_path, o->width, o->height,
                               o->fps, &d)) < 0)
        snprintf(msg, sizeof msg, "-o %s: %s", h->movie_path, d.msg);
    play_check_all(rc, msg, 2);
    if (!h->movie)
        return;
    if (!open_movie)
        atexit(abort_movie);
    open_movie = h->movie;
    unsigned mw, mh;
    tvpal_movie_size(o->width, o->height, &mw, &mh);
    if ((mw != o->width || mh != o->height) && !h->quiet)
        fprintf(stderr, PROG ": %s: frames of %ux%u padded to %ux%u (the "
                "movie's yuv420p needs even sizes; the added column or row "
                "repeats the last)\n", h->movie_path, o->width, o->height,
                mw, mh);
}

/* Rank 0, with a movie: the final frame as the PNG frame shows it (the
 * same RGB rows), sent to ffmpeg. */
static void write_movie_frame(struct headless *h)
{
    struct tvpal_diag d = {{0}};
    tvpal_png_rgb8(h->final, h->o->width, h->o->height, h->o->background,
                   h->rgb8);
    if (tvpal_movie_write(h->movie, h->rgb8, &d) < 0) {
        abort_movie();   /* the job may end without exit handlers */
        play_die_rank(1, "%s", d.msg);
    }
}

/* Rank 0 writes frames or a movie, CSV and the summary.  A movie gets a
 * CSV only with --csv (there is no directory for the default). */
static void setup_outputs(struct headless *h)
{
    h->outdir = h->o->movie ? NULL : h->o->outdir;
    h->movie_path = h->o->movie ? h->o->outdir : NULL;
    h->csv_path = h->o->csv_path;
    h->quiet = h->o->quiet;
    if (play_comm.rank != 0) {
        h->outdir = h->csv_path = h->movie_path = NULL;
        h->quiet = 1;
    }
    /* Drawing and timing without writing is a benchmark's run; anyone
     * else has forgotten -o. */
    if (play_comm.rank == 0 && !h->o->outdir && !h->csv_path && !h->quiet &&
        h->o->renderer != PLAY_REND_NONE)
        fprintf(stderr, PROG ": warning: no -o or --csv given: frames are "
                "rendered and timed but not written (-o DIR for PNG frames, "
                "-o FILE.mp4 for a movie)\n");
    if (h->o->movie)
        open_movie_output(h);
    if (h->outdir) {
        struct tvpal_diag d = {{0}};
        if (tvpal_mkdirs(h->outdir, &d) < 0)
            play_die(2, "%s: cannot create: %s", h->outdir, d.msg);
        if (!h->csv_path &&
            asprintf(&h->csv_default, "%s/timing.csv", h->outdir) >= 0)
            h->csv_path = h->csv_default;
    }
    if (h->outdir || h->movie_path) {   /* annotations: what is written */
        struct tvpal_diag d = {{0}};
        if (play_annot_open(&h->pa, h->o, 0, h->o->width, h->o->height,
                            &d) < 0)
            play_die(1, "%s", d.msg);
    }
    if (h->csv_path) {
        struct tvpal_diag d = {{0}};
        int rc;
        if (!(h->csv = tvpal_open_log(h->csv_path, &rc, &d)))
            play_die(2, "cannot write %s", d.msg);
        play_timing_csv_header(h->csv);
    }
    h->digits = 4;
    for (uint32_t x = 10000; x <= h->s->m->steps - 1 && h->digits < 10; x *= 10)
        h->digits++;
}

static void setup_view(struct headless *h)
{
    const struct play_opts *o = h->o;
    h->v = (struct tvpal_view){.width = o->width, .height = o->height,
                               .ax_deg = o->ax, .ay_deg = o->ay,
                               .zoom = o->zoom,
                               .force_axis = o->slice_axis};
    memcpy(h->v.dims, h->s->m->dims, sizeof h->v.dims);
    play_view_spacing(h->s->m, o->scale_z, h->v.spacing);
    play_view_named(&h->v, o->view, o->up);
    tvpal_view_setup(&h->v);
    h->dir_step = h->s->b >= h->s->a ? 1 : -1;
    h->nsteps = (h->s->b >= h->s->a ? h->s->b - h->s->a
                                    : h->s->a - h->s->b) + 1;
    const uint64_t nf = (uint64_t)h->nsteps * o->loops;
    if (nf > UINT32_MAX)
        play_die(2, "--loop %u: %llu frames; at most %u", o->loops,
                 (unsigned long long)nf, UINT32_MAX);
    h->nframes = (uint32_t)nf;
    h->rng = 0x9E3779B97F4A7C15ull;
    /* One process: a cluster's frames exchange ghost rows at the frame. */
    h->progressive = o->progressive > 0 && !play_cluster_multi();
    play_prog_init(&h->prog, o->fps_given ? 1000.0 / o->fps : 0,
                   o->budget_ms, h->s->a, h->s->b, !o->fps_given);
    /* The reads ahead go round --steps A:B as playback does (--loop K,
     * K > 1), and the record buffers keep what the next round shows
     * again; played once, nothing is read or kept for a round after. */
    if (o->loops > 1)
        play_levels_loop(h->s, h->s->a, h->s->b);
}

/* The level of detail of a frame of view h->v (--level, else the finest
 * whose voxels cover about a pixel), its player and view. */
static void choose_level(struct headless *h)
{
    h->level = h->o->level_given ? h->o->level
                                 : play_level_auto(h->s, &h->v);
    h->lpl = play_level_player(h->s, h->level);
    play_level_view(h->s, h->level, &h->v, &h->vl);
}

/* --progressive: the level of the frame at step t (play_prog_frame),
 * its player and view.  Returns the milliseconds since the jump or stall
 * when this frame is the full level's return, else 0. */
static double progressive_level(struct headless *h, uint32_t t, int jump)
{
    choose_level(h);
    const unsigned full = h->level;
    double refined;
    int k = play_prog_frame(&h->prog, h->s, &h->v, full, t, h->dir_step,
                            jump, &refined, &h->prog_diag);
    if ((unsigned)k != full) {
        h->level = (unsigned)k;
        h->lpl = play_level_player(h->s, h->level);
        play_level_view(h->s, h->level, &h->v, &h->vl);
    }
    h->full = full;
    return refined;
}

/* The first frame's axis, opened now: a refused I/O path ends the run
 * before any frame, and the start line says what the reads really do. */
static void open_first_axis(struct headless *h)
{
    struct tvpal_diag d = {{0}};
    if (h->progressive)
        play_levels_preload(h->s, &h->v);
    choose_level(h);
    if (tvpal_player_open_axis(h->lpl, h->vl.axis, &d) < 0)
        play_die(1, "%s: %s", h->o->dir, d.msg[0] ? d.msg : "cannot open");
}

static void print_start_line(const struct headless *h)
{
    const struct tvpal_manifest *m = h->s->m;
    char desc[160];
    struct tvpal_io_path ip;
    tvpal_player_io_path(h->lpl, &ip);
    /* A fallback is said even with -q: it changes what is measured. */
    if (ip.why[0])
        fprintf(stderr, PROG ": warning: %s\n", ip.why);
    if (h->quiet)
        return;
    char lv[96] = "";
    if (h->s->nlevels > 1)
        snprintf(lv, sizeof lv, ", level %u of 0..%u (%ux%ux%u%s)", h->level,
                 h->s->nlevels - 1, h->vl.dims[0], h->vl.dims[1],
                 h->vl.dims[2], h->o->level_given ? ", --level" : "");
    /* Without fixed buffers every read pins its pages: said, not warned
     * of (RLIMIT_MEMLOCK refuses them to most users). */
    char fx[240] = "";
    if (!h->o->po.incore)
        snprintf(fx, sizeof fx, ", fixed buffers %s%s%s%s", ip.fixed,
                 ip.fixed_why[0] ? " (" : "", ip.fixed_why,
                 ip.fixed_why[0] ? ")" : "");
    /* The data axis' palette groups, where it has them. */
    char gr[48] = "";
    const int da = tvpal_player_data_axis(h->s->pl, h->vl.axis);
    const uint32_t G = da < 0 ? 0 : tvpal_player_group(h->s->pl, (unsigned)da);
    if (G > 1)
        snprintf(gr, sizeof gr, ", palette groups of %u", G);
    fprintf(stderr, PROG ": %s: %ux%ux%u, %u steps, window %u %s%s%s; axis "
            "%c, data %s (%s, O_DIRECT %s%s), renderer %s (%s%s)\n",
            h->o->dir, m->dims[0], m->dims[1], m->dims[2], m->steps,
            m->window, tvpal_schedule_name(m->schedule), gr, lv,
            "xyz"[h->vl.axis], h->o->po.incore ? "in-core" : "streamed",
            ip.io, ip.direct, fx, h->pr.r.name,
            play_renderer_describe(&h->pr, desc, sizeof desc),
            h->o->renderer_why);
    if (h->progressive && h->s->nlevels > 1) {
        char lv2[320];
        play_levels_describe(h->s, &h->v, lv2, sizeof lv2);
        fprintf(stderr, PROG ": --progressive: %s\n", lv2);
    }
}

/* Timestep of frame i: the next of A..B after the previous frame's (from
 * A again past B); every --jumps K-th frame a reproducible random one of
 * A..B (xorshift), from which playback goes on, as after a click on the
 * slider: so the frames that are not jumps are steady ones. */
static uint32_t frame_step(struct headless *h, uint32_t i, int *jump)
{
    const uint32_t a = h->s->a, b = h->s->b;
    const uint32_t lo = a < b ? a : b, n = h->nsteps;
    *jump = 0;
    if (h->o->jumps && i > 0 && i % h->o->jumps == 0) {
        h->rng ^= h->rng << 13;
        h->rng ^= h->rng >> 7;
        h->rng ^= h->rng << 17;
        *jump = 1;
        const uint32_t span = h->o->jump_span;
        if (span && n > 1) {
            /* Within span of the step, either way (the other way where
             * one runs out of the range), never the step itself. */
            uint32_t d = 1 + (uint32_t)((h->rng >> 1) %
                                        (span < n - 1 ? span : n - 1));
            const uint32_t off = h->cur - lo;
            int up_ok = off + d < n, down_ok = off >= d;
            if (!up_ok && !down_ok) {   /* to the farther end */
                up_ok = n - 1 - off >= off;
                d = up_ok ? n - 1 - off : off;
            }
            const int up = up_ok && (!down_ok || (h->rng & 1));
            h->cur = up ? h->cur + d : h->cur - d;
        } else {
            h->cur = lo + (uint32_t)(h->rng % n);
        }
    } else if (i == 0) {
        h->cur = a;
    } else {
        h->cur = play_prog_next(&h->prog, h->cur, h->dir_step, h->s->m->steps);
    }
    return h->cur;
}

/* PSNR of this rank's float image against the reference renderer's
 * drawing of the same frame.  Drawn after the timings: switching renderers
 * makes the next frame upload every slice again, so the timings of a
 * --ref-psnr run are not representative. */
static double reference_psnr(struct headless *h, uint32_t t)
{
    struct tvpal_frame_stats st;
    struct tvpal_diag d = {{0}};
    if (tvpal_player_frame(h->lpl, &h->vl, t, h->dir_step, &h->rref,
                           h->ref_rgba, &st, &d) < 0 && !st.rendered)
        play_die(2, "step %u: reference: %s", t, d.msg);
    const double *ref = tvpal_ref_image(h->ref);
    const size_t np = (size_t)4 * h->o->width * h->o->height;
    double e = 0;
    for (size_t q = 0; q < np; q++)
        e += ((double)h->rgba[q] - ref[q]) * ((double)h->rgba[q] - ref[q]);
    e /= (double)np;
    return e > 0 ? 10 * log10(1.0 / e) : INFINITY;
}

/* Whether a load error rc (of a frame that was drawn) stops the run:
 * with --strict, and out of memory or a system error. */
static int fatal_load(const struct headless *h, int rc)
{
    return h->o->strict || rc == TVPAL_E_SYS || rc == TVPAL_E_NOMEM;
}

/* Draws frame t (--repeat times), composites it and measures this rank's
 * part; row gets the player's statistics. */
static void draw_frame(struct headless *h, uint32_t t, struct play_rank_rec *me,
                       struct play_row *row)
{
    struct tvpal_frame_stats st;
    struct tvpal_diag d = {{0}};
    double f0 = tvpal_now();
    int rc = tvpal_player_frame(h->lpl, &h->vl, t, h->dir_step, &h->pr.r,
                                h->rgba, &st, &d);
    for (uint32_t k = 1; k < h->o->repeat && rc >= 0; k++)
        rc = tvpal_player_frame(h->lpl, &h->vl, t, h->dir_step, &h->pr.r,
                                h->rgba, &st, &d);
    if (!st.rendered && rc < 0 && !play_cluster_multi())
        play_die(2, "step %u: %s", t, d.msg);
    h->stage_ms = st.stage_ms;
    h->bytes_needed = st.bytes_needed;
    struct tvpal_render_times rt = {.draw_ms = st.draw_ms};
    if (h->pr.r.times)
        h->pr.r.times(h->pr.r.ctx, &rt);
    /* Sort-last compositing of the ranks' images (rank 0 gets it). */
    struct tvpal_compose_stats cs;
    double c0 = tvpal_now();
    if (tvpal_composite(h->cx, &play_comm, h->o->ckind,
                        !tvpal_player_slabs_descending(h->lpl, &h->vl),
                        h->rgba, h->final, &cs) < 0)
        play_die_rank(1, "compositing failed at step %u", t);
    double comp_ms = (tvpal_now() - c0) * 1e3;
    *me = (struct play_rank_rec){
        .io = st.io_ms, .stream = st.stream_ms,
        .up = st.upload_ms + rt.upload_ms, .draw = rt.draw_ms,
        .read = rt.readback_ms, .enc = cs.encode_ms, .exch = cs.exchange_ms,
        .blend = cs.blend_ms, .comp = comp_ms, .gath = cs.gather_ms,
        .total = (tvpal_now() - f0) * 1e3, .classify = rt.classify_ms,
        .accum = rt.composite_ms, .warp = rt.warp_ms,
        .bytes_read = st.bytes_read, .bytes_needed = st.bytes_needed,
        .bytes_sent = cs.bytes_sent,
        .gather_bytes = cs.gather_bytes, .pixels = cs.pixels_blended,
        .rc = rc, .fatal = rc < 0 && (!st.rendered || fatal_load(h, rc))};
    tvpal_diag_copy(me->msg, sizeof me->msg, rc < 0 ? d.msg : "");
    *row = (struct play_row){.step = t, .axis = "xyz"[st.axis],
                             .drawn = st.drawn, .skipped = st.skipped,
                             .uploads = st.uploads, .stride = st.stride,
                             .staged = st.staged, .level = h->level,
                             .axis_switch_ms = st.axis_switch_ms,
                             .ranks = play_comm.size, .psnr = NAN,
                             .time = h->s->m->ntimes ? h->s->m->times[t]
                                                     : (double)t};
}

/* Rank 0 reports each rank's new load error once (a bad record is retried
 * every frame that needs it); every rank learns whether to stop. */
static void settle_errors(struct headless *h, uint32_t t,
                          const struct play_rank_rec *me, struct play_row *row)
{
    row->agg = *me;
    if (play_cluster_multi()) {
        if (play_comm.gather(&play_comm, me, sizeof *me, h->recs) < 0)
            play_die_rank(1, "MPI gather failed");
        if (play_comm.rank == 0)
            play_timing_aggregate(h->recs, play_comm.size, &row->agg);
    }
    int stop = 0;
    if (play_comm.rank == 0) {
        const char *keep = h->o->strict ? "" : " (keeping the last good data)";
        if (row->agg.rc < 0)
            play_progress_end(&h->progress);   /* messages on a clean line */
        for (int r = 0; r < play_comm.size; r++) {
            const struct play_rank_rec *q = play_cluster_multi() ? &h->recs[r] : me;
            if (q->rc >= 0 || !strcmp(q->msg, h->last_err))
                continue;
            h->errors++;
            snprintf(h->last_err, sizeof h->last_err, "%s", q->msg);
            if (play_cluster_multi())
                fprintf(stderr, PROG ": rank %d: step %u: %s%s\n", r, t,
                        q->msg, keep);
            else
                fprintf(stderr, PROG ": step %u: %s%s\n", t, q->msg, keep);
        }
        stop = row->agg.fatal;
    }
    play_comm.bcast(&play_comm, &stop, sizeof stop, 0);
    if (stop)
        play_die(row->agg.rc == TVPAL_E_SYS || row->agg.rc == TVPAL_E_NOMEM
                     ? 1 : 2, "stopped at step %u", t);
}

/* Rank 0: the annotations (--annotate) drawn into the final frame, which
 * every output writes from (after this). */
static void annotate_frame(struct headless *h, uint32_t t)
{
    struct tvpal_diag d = {{0}};
    if (play_annot_frame(&h->pa, h->s, &h->v, t, h->final, &d) < 0)
        play_die(1, "step %u: %s", t, d.msg);
}

/* Rank 0: the frame's PNG and CSV row. */
static void write_frame(struct headless *h, const struct play_row *row)
{
    if (h->movie)
        write_movie_frame(h);
    if (h->outdir) {
        char *path;
        struct tvpal_diag d = {{0}};
        if (asprintf(&path, "%s/t%0*u.png", h->outdir, h->digits, row->step) < 0)
            play_die(1, "out of memory");
        if (tvpal_png_write8(path, h->final, h->o->width, h->o->height,
                             h->o->background, h->rgb8, &d) < 0)
            play_die(1, "%s: cannot write: %s", path, d.msg);
        free(path);
    }
    if (h->csv) { /* flushed per frame: a killed run keeps its rows */
        play_timing_csv_row(h->csv, row);
        fflush(h->csv);
    }
}

static void play_frames(struct headless *h)
{
    const struct play_opts *o = h->o;
    for (uint32_t i = 0; i < h->nframes; i++) {
        int jump;
        uint32_t t = frame_step(h, i, &jump);
        if (o->spin != 0 && i > 0) {
            h->v.ay_deg += o->spin;
            tvpal_view_setup(&h->v);
        }
        if (o->tf_cycle && o->ntf > 1)
            play_set_tf(h->s, &h->s->tfs[i % o->ntf], o->opacity);
        struct play_rank_rec me;
        struct play_row row;
        double refined = 0;
        if (h->progressive)
            refined = progressive_level(h, t, jump);
        else
            choose_level(h);
        draw_frame(h, t, &me, &row);
        if (h->progressive && h->prog.load_rc < 0 && me.rc >= 0) {
            /* The prepared step's install failed on a record: this
             * frame's load error, as if the frame had read it. */
            me.rc = h->prog.load_rc;
            me.fatal = fatal_load(h, me.rc);
            tvpal_diag_copy(me.msg, sizeof me.msg, h->prog_diag.msg);
        }
        row.jump = jump;
        row.full_ms = refined > 0 ? refined + me.total : 0;
        if (h->progressive) {
            play_prog_measured(&h->prog, me.io, h->stage_ms, me.total,
                               h->bytes_needed, h->level, h->full);
            play_prog_keep(&h->prog, h->s, &h->v, h->full, t, h->dir_step);
        }
        if (o->ref_psnr)
            row.psnr = reference_psnr(h, t);
        settle_errors(h, t, &me, &row);
        if (play_comm.rank != 0)
            continue;
        play_timing_add(&h->tot, &row);
        annotate_frame(h, t);
        write_frame(h, &row);
        play_progress_update(&h->progress, i + 1);
        /* --fps keeps the clock of a playback; a movie's frames are
         * written as fast as drawn unless they are the ones shown. */
        if (o->fps_given && (h->progressive || !o->movie))
            play_prog_pace(&h->prog);
    }
    play_progress_end(&h->progress);
}

/* Rank 0: ffmpeg finishes the movie; it is renamed into place. */
static void close_movie(struct headless *h)
{
    struct tvpal_diag d = {{0}};
    open_movie = NULL;
    int rc = tvpal_movie_close(h->movie, &d);
    h->movie = NULL;
    if (rc < 0)
        play_die_rank(1, "%s", d.msg);
}

static void print_summary(struct headless *h, double elapsed)
{
    if (h->csv && fclose(h->csv) != 0)
        play_die(1, "%s: write error", h->csv_path);
    h->csv = NULL;
    if (h->movie) {
        close_movie(h);
        if (!h->quiet)
            fprintf(stderr, PROG ": %u frames in %s (%s, %g fps)\n",
                    h->nframes, h->movie_path,
                    tvpal_movie_codec(h->o->movie), h->o->fps);
    }
    if (!h->quiet && h->outdir)
        fprintf(stderr, PROG ": %u frames in %s/\n", h->nframes, h->outdir);
    play_timing_summary(stdout, &h->tot,
                        h->nframes / (elapsed > 0 ? elapsed : 1e-9));
    struct tvpal_io_path ip;
    /* The I/O path of the level drawn last; counts over every level. */
    tvpal_player_io_path(h->lpl, &ip);
    uint64_t submits = 0;
    for (unsigned k = 0; k < h->s->nlevels; k++)
        if (h->s->lvl[k])
            submits += tvpal_player_io_submits(h->s->lvl[k]);
    printf(" incore_mib=%.1f mode=%s io=%s direct=%s fixed=%s fixed_reads=%llu "
           "buffers=%u io_submits=%llu renderer=%s errors=%u\n",
           play_levels_incore_bytes(h->s) / 1048576.0,
           tvpal_player_io_name(h->lpl), ip.io, ip.direct, ip.fixed,
           (unsigned long long)ip.fixed_reads, ip.buffers,
           (unsigned long long)submits,
           h->pr.r.name, h->errors);
    if (h->progressive)
        printf("progressive: below_full=%u jumps=%u late=%u\n",
               h->prog.below, h->prog.jumps, h->prog.stalls);
    if (h->o->ref_psnr)
        printf("psnr_ref=%.3f\n", play_timing_mean_psnr(&h->tot));
}

static void teardown(struct headless *h)
{
    if (h->csv)
        fclose(h->csv);
    play_renderer_close(&h->pr);
    tvpal_ref_free(h->ref);
    play_levels_close(h->s);
    tvpal_player_close(h->s->pl);
    h->s->pl = NULL;
    tvpal_compositor_free(h->cx);
    play_annot_close(&h->pa);
    free(h->final);
    free(h->recs);
    free(h->rgba);
    free(h->rgb8);
    free(h->ref_rgba);
    free(h->csv_default);
}

int play_run_headless(struct play_session *s)
{
    struct headless h = {.s = s, .o = s->o};
    setup_renderers(&h);
    setup_buffers(&h);
    setup_outputs(&h);
    setup_view(&h);
    open_first_axis(&h);
    print_start_line(&h);
    if (play_comm.rank == 0)
        play_progress_start(&h.progress, stderr, h.quiet, s->o->progress_s,
                            h.nframes);
    const double t_start = tvpal_now();
    play_prog_clock_start(&h.prog);
    play_frames(&h);
    if (play_comm.rank == 0)
        print_summary(&h, tvpal_now() - t_start);
    unsigned errors = h.errors;
    teardown(&h);
    return errors ? 1 : 0;
}
