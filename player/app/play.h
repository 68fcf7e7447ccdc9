/* play.h: the parts of tvpal-play and what they share: the options
 * (play_cli.c), the session every front end plays (tvpal-play.c opens it),
 * the headless loop (play_headless.c) and the window loop (play_window.c).
 * Renderers are chosen in play_renderer.c, per-frame figures described in
 * play_timing.c, the cluster glue is play_cluster.c. */
#ifndef PLAY_H
#define PLAY_H

#include <stdint.h>

#include "tvpal_composite.h"
#include "tvpal_player.h"
#include "tvpal_tf.h"

#define PLAY_PROG "tvpal-play"
#define PLAY_MAX_TF 16

/* --renderer */
enum play_renderer_kind {
    PLAY_REND_AUTO, PLAY_REND_GL, PLAY_REND_CPU, PLAY_REND_REF, PLAY_REND_NONE
};

/* --tf-range: what a --tf file's values are placed on. */
enum play_tf_range {
    PLAY_TF_DATA,       /* the data range (the default, as ParaView) */
    PLAY_TF_MINMAX,     /* MIN:MAX */
    PLAY_TF_PRESET      /* the file's own values */
};

/* --annotate: what the final frame shows (play_annot.h); AUTO is full
 * where cairo is built in, else none. */
enum play_annot_level {
    PLAY_ANNOT_AUTO = -1, PLAY_ANNOT_NONE, PLAY_ANNOT_MINIMAL, PLAY_ANNOT_FULL
};

/* Everything the command line says, after play_options_check. */
struct play_opts {
    const char *dir;                    /* OUTDIR */
    const char *steps;                  /* --steps T or A:B, checked once
                                         * open */
    unsigned width, height;             /* --size */
    double ax, ay, zoom, opacity, spin;
    int rotate_given;                   /* --rotate */
    int view, up;                       /* --view (tvpal_view_name), --up
                                         * (0..2); -1 when not given */
    unsigned slice_axis;                /* --slice-axis: 0 auto, 1..3 x..z
                                         * (tvpal_view's force_axis) */
    unsigned legend_place;              /* --legend: enum tvpal_annot_place */
    double scale_z;                     /* vertical exaggeration (z) */
    const char *tf_files[PLAY_MAX_TF];  /* --tf, in order */
    unsigned ntf;
    int tf_range;                       /* enum play_tf_range: --tf-range */
    double tf_lo, tf_hi;                /* its MIN:MAX, MIN < MAX */
    int nan_given;                      /* --nan-color: */
    float nan_rgba[4];                  /* straight RGBA, each in [0, 1] */
    int renderer;                       /* enum play_renderer_kind */
    const char *renderer_why;           /* why a default or implied choice */
    uint32_t fb_bits, cpu_scale;        /* cpu_scale 0: auto */
    int fb_given, scale_given;
    int exact;                          /* --exact: no bounded termination */
    int from_z;                         /* --from-z: cross frames always */
    uint32_t level;                     /* --level N (with level_given) */
    int level_given;
    uint32_t budget_ms;                 /* --budget-ms: window frame budget */
    int progressive;                    /* --progressive: 1 on, 0 off (-1
                                         * until checked: on in the window) */
    int window;                         /* -1 until checked: from $DISPLAY */
    struct tvpal_player_opts po;        /* data mode, I/O, prefetch */
    uint32_t mem_mib;
    uint32_t read_ahead_mib;            /* --read-ahead (0: the default) */
    uint32_t repeat, jumps, autoplay;
    uint32_t loops;                     /* --loop: A..B played K times */
    uint32_t jump_span;                 /* --jump-span: jumps within it of
                                         * the step (0: anywhere) */
    int tf_cycle, ref_psnr, strict, quiet, no_direct, want_direct;
    const char *outdir, *csv_path, *shot, *shard_pat;
    int annotate;                       /* enum play_annot_level */
    float background[3];                /* --background: RGB, each 0..1 */
    const char *shot_dir;               /* --shot-dir: the S key's PNGs */
    int no_hud;                         /* --no-hud: the HUD starts hidden */
    int movie;                          /* -o FILE.mp4|.webm: its
                                         * tvpal_movie_kind, else 0 (-o DIR) */
    double fps;                         /* --fps: the movie's frame rate */
    int fps_given;
    double progress_s;                  /* --progress: seconds between
                                         * lines when stderr is no terminal */
    enum tvpal_compose_kind ckind;
};

/* Parses argv into o (defaults first).  --help and --version print and
 * return 1 (exit 0); usage errors end the job with exit 2.  Returns 0 to
 * go on. */
int play_options_parse(struct play_opts *o, int argc, char **argv);
/* The rules between options: renderer implications (--fb: gl, --cpu-scale:
 * cpu, default cpu headless), what needs or refuses the window, --ref-psnr
 * on one rank.  Ends the job with exit 2 on a conflict. */
void play_options_check(struct play_opts *o, int nranks);

/* What the options change in a loaded transfer function: --nan-color
 * replaces its NaN colour.  Applied to every --tf file (also when reloaded)
 * and to the default. */
void play_tf_apply_options(const struct play_opts *o, struct tvpal_tf *tf);
/* Loads --tf file i onto the range --tf-range says (the data range of m,
 * MIN:MAX, or the file's own values) and applies the options to it.
 * Returns 0 or the tvpal_tf_load error, with the reason in d. */
int play_tf_load(const struct play_opts *o, const struct tvpal_manifest *m,
                 unsigned i, struct tvpal_tf *tf, struct tvpal_diag *d);

/* The view's voxel spacing: the dataset's, z times scale_z. */
void play_view_spacing(const struct tvpal_manifest *m, double scale_z,
                       double spacing[3]);

/* The named view `view` (a tvpal_view_name; < 0: none, v keeps its
 * angles) with axis `up` pointing up (< 0, or up along the view: the
 * view's default), in v before tvpal_view_setup: its orientation, angles
 * 0. */
void play_view_named(struct tvpal_view *v, int view, int up);

/* The dataset being played and what every front end needs of it. */
struct play_session {
    struct play_opts *o;
    struct tvpal_player *pl;            /* owned; a loop may replace it */
    const struct tvpal_manifest *m;
    uint32_t a, b;                      /* first and last step */
    struct tvpal_tf tfs[PLAY_MAX_TF + 1]; /* --tf files, then the default */
    unsigned ntf;                       /* --tf count (tfs[ntf]: default) */
    /* Levels of detail (tvpal-encode --levels): lvl[0] is pl, level k's
     * player is opened on its first use (play_levels.c); every level gets
     * the same TF, opacity and slice reduction. */
    unsigned nlevels;                   /* 1 + the manifest's levels */
    int loop_set;                       /* play_levels_loop: the steps */
    uint32_t loop_first, loop_last;     /* playback goes round */
    struct tvpal_player *lvl[TVPAL_LEVELS_MAX + 1];
    const struct tvpal_tf *tf;
    double tf_opacity;
    unsigned reduce;
};

/* play_levels.c.  After s->pl and s->m are open. */
void play_levels_init(struct play_session *s);
/* Output pixels per voxel of level 0 under the set-up view v. */
double play_level0_pixels_per_voxel(const struct tvpal_view *v);
/* The level a still frame of view v0 (level 0's, set up) draws from: the
 * finest whose voxels are at least half an output pixel wide, so 1024^3
 * seen whole into 512x512 draws from the 512^3 level. */
unsigned play_level_auto(const struct play_session *s,
                         const struct tvpal_view *v0);
/* Level k's player (the coarsest there is when k is beyond it), opened on
 * first use from OUTDIR/level-k (under MPI its node-r: the encoder's
 * layout); ends the job when it cannot be opened or does not match. */
struct tvpal_player *play_level_player(struct play_session *s, unsigned k);
/* View v0 of level 0 for level k (its player open): the same box, angles,
 * image and opacity, level k's dims and voxel size. */
void play_level_view(const struct play_session *s, unsigned k,
                     const struct tvpal_view *v0, struct tvpal_view *vk);
/* --progressive: the memory the levels' records may take: --mem, else a
 * quarter of the machine's.  Level k > 0 keeps its records within 1/2^k
 * of it (play_level_player), and level 0 reads ahead within a quarter of
 * it once reads fall behind the clock (play_prog_keep). */
uint64_t play_levels_memory(const struct play_opts *o);
/* --progressive: levels 1.. opened now, each with the axis of view v0
 * (level 0's) loaded (in RAM within --mem, play_level_player), so that
 * no jump waits for them; ends the job on an error. */
void play_levels_preload(struct play_session *s, const struct tvpal_view *v0);
/* Where the coarser levels' records are, for the start line: "level 1 in
 * RAM (3.2 MiB), level 2 streamed (6 steps each way kept)" into buf. */
void play_levels_describe(const struct play_session *s,
                          const struct tvpal_view *v0, char *buf, size_t n);
/* Playback goes round the steps first..last (tvpal_player_loop), on
 * every level's player, open now or later (both within the series). */
void play_levels_loop(struct play_session *s, uint32_t first, uint32_t last);
void play_set_tf(struct play_session *s, const struct tvpal_tf *tf,
                 double opacity);
void play_set_reduce(struct play_session *s, unsigned reduce);
uint64_t play_levels_incore_bytes(const struct play_session *s);
/* Closes levels 1.. (level 0 is s->pl, the loops close it). */
void play_levels_close(struct play_session *s);

/* The loops.  Each returns the exit status (0, or 1 after load errors)
 * and closes s->pl. */
int play_run_headless(struct play_session *s);
int play_run_window(struct play_session *s);

#endif
