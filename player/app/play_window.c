/* play_window.c: the interactive window of tvpal-play.  Rank 0 owns the
 * window and its input; before each frame it tells every rank what to do
 * (a win_cmd), so that under MPI all ranks stay on the same timestep and
 * view, and the frame reaches the window through the compositor. */
#define _GNU_SOURCE
#include "play.h"
#include "play_annot.h"
#include "play_cluster.h"
#include "play_progressive.h"
#include "play_renderer.h"
#include "tvpal_clock.h"
#include "tvpal_fs.h"
#include "tvpal_png.h"
#include "tvpal_win.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG PLAY_PROG

/* What rank 0's window tells every rank before each frame. */
struct win_cmd {
    int quit, render, reduce, toggle_mode, reload_tf, interacting, playing;
    uint32_t t, tfi, width, height, level;
    int dir;
    int view;                       /* named view (-1: none; up: --up) */
    double ax, ay, zoom, opacity, scale_z;
};

struct win_state {
    struct play_session *s;
    const struct play_opts *o;
    int leader, multi;
    struct tvpal_win *win;          /* rank 0 */
    struct play_renderer pr;
    int use_cpu;
    unsigned W, H;
    /* The annotations and the HUD (rank 0; pa.a NULL without cairo). */
    struct play_annot pa;
    int hud;                        /* the HUD is shown (H) */
    int flat_bg;                    /* --background is not black */
    uint8_t *rgb, *rgb8, *final;    /* window pixels, PNG rows, composite */
    uint8_t *show;                  /* final over the background, + HUD */
    float *scratch, *img;
    struct tvpal_compositor *cx;
    struct tvpal_player_opts po;
    /* The view and playback state rank 0 steers. */
    double ax, ay, zoom, opacity, scale_z;
    int view;                       /* the named view the angles turn */
    unsigned tfi, shots;
    /* S saves the frame drawn after the keys pressed before it: the keys
     * of a poll are taken up to S, the shot after the next frame is shown,
     * and the keys after S (held) in the next round. */
    int shot_pending;
    int held[16], nheld;
    uint32_t t;
    int dir, playing, redraw, reduced, status;
    uint32_t frames;
    double fps, last;
    char last_err[TVPAL_DIAG_MAX];
    /* Levels of detail: rank 0's running mean of each level's frame time
     * (ms; 0 until drawn), the level of the last frame and whether it was
     * coarser than a still frame's. */
    double level_ms[TVPAL_LEVELS_MAX + 1];
    unsigned level;
    int coarse;
    /* --progressive (one process, on by default): the level each frame
     * draws so that none waits for the disk (play_progressive.h); the
     * step of the last frame drawn (prog_t, with prog_drawn). */
    int progressive;
    struct play_prog prog;
    uint32_t prog_t;
    int prog_drawn;
    unsigned full;                  /* the last frame's full level */
    FILE *csv;                      /* --csv: a line per frame (rank 0) */
};

/* Whether the frame reaches the window as the compositor's 8-bit frame
 * (with one rank: this rank's image rounded), as a cluster's and the cpu
 * renderer's do, rather than by a blit of the GL renderer's framebuffer:
 * also whenever something is drawn into it (annotations, HUD) or under it
 * (a background other than black).  The same on every rank. */
static int via_final(const struct win_state *w)
{
    return w->multi || w->use_cpu || w->pa.what || w->hud || w->flat_bg;
}

static void free_buffers(struct win_state *w)
{
    free(w->rgb);
    free(w->rgb8);
    free(w->scratch);
    free(w->img);
    free(w->final);
    free(w->show);
    tvpal_compositor_free(w->cx);
    w->rgb = w->rgb8 = w->final = w->show = NULL;
    w->scratch = w->img = NULL;
    w->cx = NULL;
}

/* Buffers for W x H (again after a resize); the 8-bit path's too, since
 * the HUD key may switch to it at any time. */
static void alloc_buffers(struct win_state *w)
{
    const size_t n = (size_t)w->W * w->H;
    w->rgb = malloc(3 * n);
    w->rgb8 = malloc(3 * n);
    w->scratch = malloc(sizeof(float) * 4 * n);
    w->img = malloc(sizeof(float) * 4 * n);
    w->final = malloc(4 * n);
    w->show = malloc(4 * n);
    if (!w->rgb || !w->rgb8 || !w->scratch || !w->img || !w->final ||
        !w->show ||
        tvpal_compositor_create(&w->cx, w->W, w->H, play_comm.size) < 0)
        play_die_rank(1, "out of memory");
}

/* Rank 0: annotations and HUD for W x H (again after a resize).  The HUD
 * needs cairo; without it the window has the title only. */
static void open_annot(struct win_state *w)
{
    struct tvpal_diag d = {{0}};
    int was = w->pa.a != NULL, hud = w->hud;
    play_annot_close(&w->pa);
    if (!w->leader)
        return;
    if (play_annot_open(&w->pa, w->o, tvpal_annot_available(), w->W, w->H,
                        &d) < 0)
        play_die(1, "%s", d.msg);
    w->hud = was ? hud : w->pa.a && !w->o->no_hud;
}

/* The window on rank 0, and the renderer: the leader's choice (its
 * window's GL decides the default) holds on every rank. */
static void open_window(struct win_state *w)
{
    struct tvpal_diag d = {{0}};
    int rc = w->leader ? tvpal_win_open(&w->win, w->W, w->H, PROG, &d) : 0;
    play_check_all(rc, d.msg, 1);
    w->use_cpu = w->o->renderer == PLAY_REND_CPU;
    char why[160] = "";
    if (w->leader && w->o->renderer == PLAY_REND_AUTO) {
        const char *gname = tvpal_glr_gl_name();
        w->use_cpu = play_gl_is_software(gname);
        snprintf(why, sizeof why, "default: the window's GL is %s%s",
                 gname ? gname : "unknown",
                 w->use_cpu ? ", which draws on the CPU" : "");
    }
    if (w->multi)
        play_comm.bcast(&play_comm, &w->use_cpu, sizeof w->use_cpu, 0);
    /* Ranks other than 0 draw GL off-screen, in their own context. */
    rc = play_renderer_open(&w->pr, w->use_cpu ? PLAY_REND_CPU : PLAY_REND_GL,
                            w->W, w->H, w->o->fb_bits, w->o->cpu_scale,
                            w->o->exact, !w->leader, &d);
    play_check_all(rc, rc < 0 ? d.msg : "", 1);
    if (w->leader && !w->o->quiet) {
        char desc[160];
        fprintf(stderr, PROG ": renderer %s (%s%s%s)\n", w->pr.r.name,
                play_renderer_describe(&w->pr, desc, sizeof desc),
                *why ? "; " : "", why);
    }
    const float *bg = w->o->background;
    w->flat_bg = bg[0] != 0 || bg[1] != 0 || bg[2] != 0;
    open_annot(w);   /* rank 0; via_final() holds on every rank when multi */
    alloc_buffers(w);
}

/* tvpal_png_write takes premultiplied floats bottom-up: convert the
 * window's top-down RGB. */
static int save_shot(struct win_state *w, const char *path)
{
    const unsigned W = w->W, H = w->H;
    for (unsigned y = 0; y < H; y++)
        for (unsigned x = 0; x < W; x++) {
            const uint8_t *s = w->rgb + 3 * ((size_t)(H - 1 - y) * W + x);
            float *d = w->scratch + 4 * ((size_t)y * W + x);
            for (int c = 0; c < 3; c++)
                d[c] = s[c] / 255.0f;
            d[3] = 1.0f;
        }
    static const float bg[3] = {0, 0, 0};
    struct tvpal_diag d = {{0}};
    int rc = tvpal_png_write(path, w->scratch, W, H, bg, w->rgb8, &d);
    if (rc < 0)
        fprintf(stderr, PROG ": %s\n", d.msg);
    return rc;
}

/* Rank 0: S's screenshot of the frame just shown (read into w->rgb
 * before its buffers were swapped), as tvpal-shot-NNNN.png in
 * --shot-dir. */
static void save_key_shot(struct win_state *w)
{
    char *name;
    w->shot_pending = 0;
    if (asprintf(&name, "%s/tvpal-shot-%04u.png",
                 w->o->shot_dir ? w->o->shot_dir : ".", w->shots++) < 0)
        play_die(1, "out of memory");
    if (save_shot(w, name) == 0 && !w->o->quiet)
        fprintf(stderr, PROG ": saved %s\n", name);
    free(name);
}

/* One key pressed on rank 0. */
static void handle_key(struct win_state *w, int key, struct win_cmd *cmd)
{
    const uint32_t T = w->s->m->steps;
    switch (key) {
    case TVPAL_KEY_PLAY: w->playing = !w->playing; break;
    case TVPAL_KEY_NEXT:
        w->t = w->t + 1 < T ? w->t + 1 : w->t;
        w->playing = 0;
        w->dir = 1;
        break;
    case TVPAL_KEY_PREV:
        w->t = w->t > 0 ? w->t - 1 : 0;
        w->playing = 0;
        w->dir = -1;
        break;
    case TVPAL_KEY_FIRST: w->t = 0; break;
    case TVPAL_KEY_LAST: w->t = T - 1; break;
    case TVPAL_KEY_REVERSE: w->dir = -w->dir; break;
    case TVPAL_KEY_TF_NEXT: w->tfi = (w->tfi + 1) % (w->s->ntf + 1); break;
    case TVPAL_KEY_TF_RELOAD: cmd->reload_tf = 1; break;
    case TVPAL_KEY_OPACITY_UP: w->opacity *= 1.25; break;
    case TVPAL_KEY_OPACITY_DOWN: w->opacity *= 0.8; break;
    case TVPAL_KEY_MODE: cmd->toggle_mode = 1; break;
    case TVPAL_KEY_ZOOM_IN: w->zoom *= 1.15; break;
    case TVPAL_KEY_ZOOM_OUT: w->zoom /= 1.15; break;
    case TVPAL_KEY_SCALE_Z_UP: w->scale_z = fmin(w->scale_z * 1.25, 1000); break;
    case TVPAL_KEY_SCALE_Z_DOWN: w->scale_z = fmax(w->scale_z * 0.8, 1e-3); break;
    case TVPAL_KEY_SHOT: w->shot_pending = 1; break;
    case TVPAL_KEY_HUD: w->hud = w->pa.a && !w->hud; break;
    case TVPAL_KEY_QUIT: cmd->quit = 1; break;
    default:
        /* A named view: its orientation, the angles (drag) from 0. */
        if (key >= TVPAL_KEY_VIEW && key < TVPAL_KEY_VIEW + TVPAL_KEY_VIEWS) {
            w->view = key - TVPAL_KEY_VIEW;
            w->ax = w->ay = 0;
        }
        break;
    }
    w->redraw = 1;
}

/* The view of level 0 that cmd describes. */
static void cmd_view(const struct win_state *w, const struct win_cmd *cmd,
                     struct tvpal_view *v)
{
    *v = (struct tvpal_view){.width = w->W, .height = w->H, .zoom = cmd->zoom,
                             .force_axis = w->o->slice_axis};
    play_view_named(v, cmd->view, w->o->up);
    v->ax_deg = cmd->ax;
    v->ay_deg = cmd->ay;
    memcpy(v->dims, w->s->m->dims, sizeof v->dims);
    play_view_spacing(w->s->m, cmd->scale_z, v->spacing);
    tvpal_view_setup(v);
}

/* Rank 0: the level of detail of the frame.  --level forces one; a still
 * frame draws from the finest whose voxels are at least half a pixel;
 * while the view moves (drag, scrub, play) the first level from there
 * whose frames keep to --budget-ms, as last measured (a level not yet
 * drawn is tried), down to the coarsest. */
static void choose_level(struct win_state *w, struct win_cmd *cmd, int moving)
{
    const struct play_session *s = w->s;
    if (w->o->level_given) {
        cmd->level = w->o->level;
        return;
    }
    cmd->ax = w->ax;
    cmd->ay = w->ay;
    cmd->view = w->view;
    cmd->zoom = w->zoom;
    cmd->scale_z = w->scale_z;
    struct tvpal_view v;
    cmd_view(w, cmd, &v);
    unsigned k = play_level_auto(s, &v);
    if (moving)
        while (k + 1 < s->nlevels && w->level_ms[k] > w->o->budget_ms)
            k++;
    cmd->level = k;
}

/* Rank 0: the keys held from the last round, then this poll's, in the
 * order pressed, up to the first S (whose shot needs the frame they make);
 * the rest are held for the next round. */
static void take_keys(struct win_state *w, const struct tvpal_input *in,
                      struct win_cmd *cmd)
{
    int keys[32], n = 0, i = 0;
    for (int k = 0; k < w->nheld; k++)
        keys[n++] = w->held[k];
    for (int k = 0; k < in->nkeys; k++)
        keys[n++] = in->keys[k];
    w->nheld = 0;
    while (i < n && !w->shot_pending)
        handle_key(w, keys[i++], cmd);
    for (; i < n && w->nheld < (int)(sizeof w->held / sizeof w->held[0]); i++)
        w->held[w->nheld++] = keys[i];
}

/* Rank 0: this frame's input, and the command for every rank. */
static void read_input(struct win_state *w, struct win_cmd *cmd)
{
    const uint32_t T = w->s->m->steps;
    struct tvpal_input in;
    tvpal_win_poll(w->win, !w->playing && !w->redraw && !w->multi &&
                   !w->nheld, &in);
    if (tvpal_win_should_close(w->win))
        cmd->quit = 1;
    take_keys(w, &in, cmd);
    if (in.dragging) {
        w->ay += in.drag_dx * 0.4;
        w->ax += in.drag_dy * 0.4;
        w->redraw = 1;
    }
    if (in.scroll != 0) {
        w->zoom *= pow(1.1, in.scroll);
        w->redraw = 1;
    }
    if (in.scrubbing) {
        w->t = (uint32_t)floor(in.scrub_pos * (T - 1) + 0.5);
        w->playing = 0;
        w->redraw = 1;
    }
    if (in.resized && in.width && in.height &&
        (in.width != w->W || in.height != w->H)) {
        cmd->width = in.width;
        cmd->height = in.height;
        w->redraw = 1;
    }
    /* Reduced quality while the user interacts (and coarser levels while
     * playing); refine when idle, not while playing, where the next step
     * is drawn anyway. */
    int interacting = in.dragging || in.scrubbing;
    if (!interacting && !w->playing && (w->reduced || w->coarse))
        w->redraw = 1;
    if (w->playing && !w->redraw) {
        int64_t nt = (int64_t)w->t + w->dir;
        if (nt < 0 || nt >= T)
            nt = w->dir > 0 ? 0 : T - 1; /* loop */
        w->t = (uint32_t)nt;
    }
    cmd->render = w->redraw || w->playing;
    cmd->playing = w->playing;
    cmd->interacting = interacting;
    choose_level(w, cmd, interacting || w->playing);
    /* Without coarser levels, every other slice while interacting. */
    cmd->reduce = interacting && w->s->nlevels == 1 ? 2 : 1;
    cmd->t = w->t;
    cmd->dir = w->dir;
    cmd->tfi = w->tfi;
    cmd->ax = w->ax;
    cmd->ay = w->ay;
    cmd->view = w->view;
    cmd->zoom = w->zoom;
    cmd->opacity = w->opacity;
    cmd->scale_z = w->scale_z;
}

static void reload_tf(struct win_state *w, uint32_t tfi)
{
    struct play_session *s = w->s;
    struct tvpal_tf nt;
    struct tvpal_diag d = {{0}};
    if (play_tf_load(w->o, s->m, tfi, &nt, &d) < 0) {
        if (w->leader)
            fprintf(stderr, PROG ": %s: %s (keeping the old one)\n",
                    w->o->tf_files[tfi], d.msg);
    } else {
        s->tfs[tfi] = nt;
    }
}

/* --progressive: the coarser levels loaded before they are needed (at
 * the start, and after the data mode changed). */
static void preload_levels(struct win_state *w)
{
    if (!w->progressive)
        return;
    struct win_cmd c0 = {.ax = w->ax, .ay = w->ay, .view = w->view,
                         .zoom = w->zoom, .scale_z = w->scale_z};
    struct tvpal_view v0;
    cmd_view(w, &c0, &v0);
    play_levels_preload(w->s, &v0);
    w->prog.active = 0;  /* what it prepared went with the players */
    w->prog_drawn = 0;
}

/* Reopens the dataset in the other data mode; the pause is the cost of
 * loading (in-core) or of nothing (stream). */
static void toggle_mode(struct win_state *w)
{
    struct play_session *s = w->s;
    struct tvpal_player *np;
    struct tvpal_diag d = {{0}};
    w->po.incore = !w->po.incore;
    double s0 = tvpal_now();
    int rc = tvpal_player_open(&np, w->multi ? tvpal_player_dir(s->pl)
                                             : w->o->dir, &w->po, &d);
    play_check_all(rc, d.msg, 1);
    play_levels_close(s);   /* reopened in the new mode when drawn */
    tvpal_player_close(s->pl);
    s->pl = np;
    s->lvl[0] = np;
    s->o->po.incore = w->po.incore;
    s->m = tvpal_player_manifest(np);
    preload_levels(w);
    if (w->leader && !w->o->quiet)
        fprintf(stderr, PROG ": data now %s (%.0f ms)\n",
                w->po.incore ? "in-core" : "streamed",
                (tvpal_now() - s0) * 1e3);
}

static void resize(struct win_state *w, unsigned width, unsigned height)
{
    struct tvpal_diag d = {{0}};
    w->W = width;
    w->H = height;
    int rc = play_renderer_resize(&w->pr, width, height, &d);
    play_check_all(rc, d.msg, 1);
    free_buffers(w);
    alloc_buffers(w);
    open_annot(w);
}

/* A load error at step t, said once (a bad record is retried every frame
 * that needs it); the slices keep their last good data, the exit status
 * becomes 1. */
static void say_load_error(struct win_state *w, uint32_t t, const char *msg)
{
    w->status = 1;
    if (!strcmp(msg, w->last_err))
        return;
    snprintf(w->last_err, sizeof w->last_err, "%s", msg);
    if (w->multi)
        fprintf(stderr, PROG ": rank %d: step %u: %s (keeping the last good "
                "data)\n", play_comm.rank, t, msg);
    else
        fprintf(stderr, PROG ": step %u: %s (keeping the last good data)\n",
                t, msg);
}

/* --progressive: the level the frame draws (its view's own, cmd->level,
 * unless its records are late: play_prog_frame), and *refined the
 * milliseconds since the jump when it is the full level's return.  A
 * step other than the one playback came to is a jump; a paused view is
 * still (the refinement prepares the step shown). */
static unsigned progressive_level(struct win_state *w,
                                  const struct win_cmd *cmd,
                                  const struct tvpal_view *v0,
                                  double *refined)
{
    w->full = cmd->level;
    if (!w->progressive)
        return cmd->level;
    const int dir = cmd->playing ? cmd->dir : 0;
    const uint32_t T = w->s->m->steps;
    const int jump = !w->prog_drawn || (cmd->t != w->prog_t &&
        cmd->t != play_prog_next(&w->prog, w->prog_t, cmd->dir, T));
    struct tvpal_diag d = {{0}};
    int k = play_prog_frame(&w->prog, w->s, v0, cmd->level, cmd->t, dir,
                            jump, refined, &d);
    w->prog_t = cmd->t;
    w->prog_drawn = 1;
    if (w->prog.load_rc < 0) /* a prepared step's record: as a frame's */
        say_load_error(w, cmd->t, d.msg);
    return (unsigned)k;
}

/* Every rank: draws the command's frame (and composites it). */
static void render(struct win_state *w, const struct win_cmd *cmd,
                   struct tvpal_view *v)
{
    struct play_session *s = w->s;
    play_set_tf(s, &s->tfs[cmd->tfi], cmd->opacity);
    play_set_reduce(s, (unsigned)cmd->reduce);
    w->reduced = cmd->reduce > 1;
    struct tvpal_view v0;
    cmd_view(w, cmd, &v0);
    double refined = 0;
    const unsigned lv = progressive_level(w, cmd, &v0, &refined);
    struct tvpal_player *pl = play_level_player(s, lv);
    play_level_view(s, lv, &v0, v);
    w->coarse = lv > w->full ||
                (!w->o->level_given && lv > play_level_auto(s, &v0));
    struct tvpal_frame_stats st;
    struct tvpal_diag d = {{0}};
    double f0 = tvpal_now();
    const int flat = via_final(w);
    int rc = tvpal_player_frame(pl, v, cmd->t, cmd->dir, &w->pr.r,
                                flat ? w->img : NULL, &st, &d);
    if (rc < 0) {
        say_load_error(w, cmd->t, d.msg);
        if (!st.rendered)
            play_die_rank(2, "cannot render step %u", cmd->t);
    }
    if (flat) {
        struct tvpal_compose_stats cs;
        if (tvpal_composite(w->cx, &play_comm, TVPAL_COMPOSE_BSWAP,
                            !tvpal_player_slabs_descending(pl, v), w->img,
                            w->final, &cs) < 0)
            play_die_rank(1, "compositing failed at step %u", cmd->t);
    }
    double ms = (tvpal_now() - f0) * 1e3;
    double *m = &w->level_ms[lv];
    *m = *m > 0 ? 0.7 * *m + 0.3 * ms : ms;
    w->level = lv;
    if (w->progressive) {
        play_prog_measured(&w->prog, st.io_ms, st.stage_ms, ms,
                           st.bytes_needed, lv, w->full);
        play_prog_keep(&w->prog, s, &v0, w->full, cmd->t,
                       cmd->playing ? cmd->dir : 0);
    }
    if (w->csv) {
        fprintf(w->csv, "%u,%u,%u,%d,%.3f,%.3f\n", w->frames, cmd->t, lv,
                cmd->interacting, ms, refined > 0 ? refined + ms : 0);
        fflush(w->csv);
    }
    w->redraw = 0;
    w->frames++;
}

/* Rank 0: the HUD's lines (step and time, TF, renderer, fps, level of
 * detail) over the frame in w->show. */
static void draw_hud(struct win_state *w, const struct win_cmd *cmd,
                     const struct tvpal_view *v, const char *when)
{
    char l[5][96];
    const struct play_session *s = w->s;
    snprintf(l[0], sizeof l[0], "step %u/%u%s", cmd->t, s->m->steps - 1, when);
    snprintf(l[1], sizeof l[1], "TF %s", s->tfs[cmd->tfi].name);
    snprintf(l[2], sizeof l[2], "renderer %s%s", w->pr.r.name,
             w->multi ? ", cluster" : "");
    snprintf(l[3], sizeof l[3], "%.1f fps", w->fps);
    snprintf(l[4], sizeof l[4], "level %u/%u (%ux%ux%u)%s", w->level,
             s->nlevels - 1, v->dims[0], v->dims[1], v->dims[2],
             w->level > w->full ? " refining"
             : w->reduced || w->coarse ? " preview" : "");
    const char *const lines[5] = {l[0], l[1], l[2], l[3], l[4]};
    static const float fg[3] = {1, 1, 1};
    struct tvpal_diag d = {{0}};
    if (tvpal_annot_hud(w->pa.a, lines, 5, fg, w->show, NULL, &d) < 0)
        play_die(1, "%s", d.msg);
}

/* Rank 0: the 8-bit frame into the window: annotated, over the
 * background, with the HUD on top (on a copy: the HUD is the window's,
 * not the frame's). */
static void show_final(struct win_state *w, const struct win_cmd *cmd,
                       const struct tvpal_view *v, const char *when)
{
    struct tvpal_view v0;
    struct tvpal_diag d = {{0}};
    cmd_view(w, cmd, &v0);
    if (play_annot_frame(&w->pa, w->s, &v0, cmd->t, w->final, &d) < 0)
        play_die(1, "step %u: %s", cmd->t, d.msg);
    const uint8_t *img = w->final;
    if (w->hud || w->flat_bg) {
        const float *bg = w->o->background;
        const size_t n = (size_t)w->W * w->H;
        for (size_t i = 0; i < n; i++) {
            const uint8_t *p = w->final + 4 * i;
            uint8_t *q = w->show + 4 * i;
            for (int c = 0; c < 3; c++)
                q[c] = tvpal_png_over8(p[c], p[3], bg[c]);
            q[3] = 255;
        }
        if (w->hud)
            draw_hud(w, cmd, v, when);
        img = w->show;
    }
    tvpal_win_show(w->win, img, w->W, w->H);
}

/* Rank 0: shows the frame, the slider and the title. */
static void present(struct win_state *w, const struct win_cmd *cmd,
                    const struct tvpal_view *v)
{
    const uint32_t T = w->s->m->steps;
    double now = tvpal_now();
    double inst = now > w->last ? 1.0 / (now - w->last) : 0;
    w->fps = w->frames > 1 ? 0.8 * w->fps + 0.2 * inst : inst;
    w->last = now;
    const struct tvpal_manifest *m = w->s->m;
    char when[96] = "";
    if (m->ntimes)
        snprintf(when, sizeof when, " (%g%s%.40s)", m->times[cmd->t],
                 m->time_units[0] ? " " : "", m->time_units);
    if (via_final(w))
        show_final(w, cmd, v, when);
    else
        tvpal_glr_blit(w->pr.glr, 0, TVPAL_SLIDER_HEIGHT);
    if (w->o->shot || w->shot_pending)
        tvpal_win_read(w->win, w->rgb);   /* the back buffer, before swap */
    tvpal_win_present(w->win, T > 1 ? (double)cmd->t / (T - 1) : 0.0);
    if (w->shot_pending)
        save_key_shot(w);
    char lv[64] = "";
    if (w->s->nlevels > 1)
        snprintf(lv, sizeof lv, " - level %u/%u (%ux%ux%u)", w->level,
                 w->s->nlevels - 1, v->dims[0], v->dims[1], v->dims[2]);
    char title[384];
    snprintf(title, sizeof title, PROG " - t=%u/%u%s - %.1f fps - %s%s - "
             "axis %c%s - %s - %s%s%s", cmd->t, T - 1, when, w->fps,
             tvpal_player_io_name(w->s->pl), w->po.incore ? "" : " stream",
             "xyz"[v->axis], lv, w->pr.r.name, w->s->tfs[cmd->tfi].name,
             w->reduced || w->coarse ? " - preview" : "",
             w->multi ? " - cluster" : "");
    tvpal_win_title(w->win, title);
}

/* Rank 0, --autoplay: whether the run is over; then every rank is told
 * to stop at its next round. */
static int autoplay_over(struct win_state *w)
{
    const uint32_t T = w->s->m->steps;
    int over = 0;
    if (w->o->autoplay && w->frames >= w->o->autoplay) {
        w->playing = 0;
        w->redraw = 0;
        over = 1;
    } else if (w->playing && w->o->autoplay) {
        int64_t nt = (int64_t)w->t + w->dir;
        if (nt < 0 || nt >= T) {
            over = 1;
        } else {
            w->t = (uint32_t)nt;
            w->redraw = 1;
        }
    }
    if (over && w->multi) {
        struct win_cmd q = {.quit = 1};
        play_comm.bcast(&play_comm, &q, sizeof q, 0);
    }
    return over;
}

static void event_loop(struct win_state *w)
{
    for (;;) {
        struct win_cmd cmd = {0};
        struct tvpal_view v;
        if (w->leader)
            read_input(w, &cmd);
        if (w->multi && play_comm.bcast(&play_comm, &cmd, sizeof cmd, 0) < 0)
            play_die_rank(1, "MPI broadcast failed");
        if (cmd.quit)
            break;
        if (cmd.reload_tf && cmd.tfi < w->s->ntf)
            reload_tf(w, cmd.tfi);
        if (cmd.toggle_mode)
            toggle_mode(w);
        if (cmd.width && cmd.height)
            resize(w, cmd.width, cmd.height);
        if (!cmd.render)
            continue;
        render(w, &cmd, &v);
        if (!w->leader)
            continue;
        present(w, &cmd, &v);
        if (autoplay_over(w))
            break;
        if (w->playing)
            play_prog_pace(&w->prog);   /* --fps */
    }
}

int play_run_window(struct play_session *s)
{
    struct win_state w = {
        .s = s, .o = s->o, .leader = play_comm.rank == 0,
        .multi = play_cluster_multi(), .W = s->o->width, .H = s->o->height,
        .po = s->o->po, .ax = s->o->view >= 0 ? 0 : s->o->ax,
        .ay = s->o->view >= 0 ? 0 : s->o->ay, .view = s->o->view,
        .zoom = s->o->zoom,
        .opacity = s->o->opacity, .scale_z = s->o->scale_z, .t = s->a, .dir = s->b >= s->a ? 1 : -1,
        .playing = s->o->autoplay > 0, .redraw = 1, .last = tvpal_now()};
    open_window(&w);
    /* The clock (--fps) paces playing with or without --progressive. */
    play_prog_init(&w.prog, s->o->fps_given ? 1000.0 / s->o->fps : 0,
                   s->o->budget_ms, 0, s->m->steps - 1, 0);
    play_levels_loop(s, 0, s->m->steps - 1); /* playing goes round them */
    w.progressive = s->o->progressive > 0 && !w.multi && s->nlevels > 1;
    preload_levels(&w);
    if (w.leader && s->o->shot_dir) {
        struct tvpal_diag d = {{0}};
        if (tvpal_mkdirs(s->o->shot_dir, &d) < 0)
            play_die(2, "--shot-dir %s: cannot create: %s", s->o->shot_dir,
                     d.msg);
    }
    if (w.leader && s->o->csv_path) {
        struct tvpal_diag d = {{0}};
        int rc;
        if (!(w.csv = tvpal_open_log(s->o->csv_path, &rc, &d)))
            play_die(2, "cannot write %s", d.msg);
        fprintf(w.csv, "frame,step,level,interacting,frame_ms,full_ms\n");
    }
    event_loop(&w);
    if (w.csv && fclose(w.csv) != 0)
        play_die(1, "%s: write error", s->o->csv_path);
    if (w.leader && w.o->shot && save_shot(&w, w.o->shot) < 0)
        play_die(1, "%s: cannot write", w.o->shot);
    if (w.leader)
        printf("frames=%u last_step=%u fps=%.3f mode=%s ranks=%d renderer=%s\n",
               w.frames, w.t, w.fps, tvpal_player_io_name(s->pl),
               play_comm.size, w.pr.r.name);
    play_renderer_close(&w.pr);
    play_annot_close(&w.pa);
    tvpal_win_close(w.win);
    play_levels_close(s);
    tvpal_player_close(s->pl);
    s->pl = NULL;
    free_buffers(&w);
    return w.status;
}
