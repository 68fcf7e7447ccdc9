/* play_cli.c: tvpal-play's command line: one table of options, the parser
 * it drives, and play_options_check, which holds every rule between
 * options (see play.h). */
#include "play.h"
#include "play_cluster.h"
#include "tvpal_annot.h"
#include "play_progress.h"
#include "tvpal_cli.h"
#include "tvpal_comm.h"
#include "tvpal_crc32c.h"
#include "tvpal_movie.h"
#include "tvpal_view.h"

#include <getopt.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG PLAY_PROG

/* Bounds of the numeric options (also in --help and tvpal-play.1). */
#define PLAY_SIZE_MAX 16384   /* --size, each side */
#define PLAY_DEG_MAX 360.0    /* --rotate, --spin: |degrees| */

/* --help, first part: what the player does, view and frame options. */
static void usage_view(FILE *f)
{
    fprintf(f,
"Usage: " PROG " OUTDIR [options]\n"
"Play the tvpal dataset OUTDIR: every frame decodes the slices of the axis\n"
"most orthogonal to the view by a per-frame palette, TF(decoder[t][i])\n"
"(interpolation after the lookup), and blends them in depth order in\n"
"float, with the cpu shear-warp renderer or the GLSL palette shader (see\n"
"--renderer).  Headless: with -o DIR, writes DIR/tNNNN.png (NNNN: the\n"
"timestep) and a per-frame timing CSV, with -o FILE.mp4 or FILE.webm a\n"
"movie; in a window: interactive.\n"
"\n"
"View and frames:\n"
"      --headless           render off-screen to PNG files (default when\n"
"                           there is no display)\n"
"  -w, --window             interactive window (default with a display)\n"
"  -s, --steps A:B|T        timesteps A..B inclusive, 0-based (default all);\n"
"                           B < A plays backward; T alone: the one step T\n"
"  -S, --size WxH           image size, each 1..16384 (default 512x512)\n"
"  -r, --rotate AX,AY       degrees about x, then about y, each -360..360\n"
"                           (default 20,30)\n"
"      --view V             a named view instead of --rotate: +x, -x, +y, -y,\n"
"                           +z, -z (looking along that axis, as ParaView's\n"
"                           \"set view direction to +X\": +x looks from the\n"
"                           -x side) or iso (from the +x+y+z corner); exactly\n"
"                           axis-aligned images\n"
"      --up A               x, y or z: the axis pointing up on the screen in\n"
"                           a named view (default as ParaView: y for +z, -z\n"
"                           and iso, z for the x and y views); in the window\n"
"                           also for the view keys\n"
"      --slice-axis A       auto, x, y or z: the slices that draw the volume\n"
"                           (default auto: the axis that faces the view in\n"
"                           voxel units, or larger slices where a volume is\n"
"                           flat and seen obliquely)\n"
"  -z, --zoom Z             zoom factor, 0.001..1000 (default 1)\n"
"  -t, --tf FILE            transfer function (samples/tf/README.md: tvpal\n"
"                           text format or ParaView preset JSON); default:\n"
"                           one from the data's histogram.  Repeat to give\n"
"                           several (the window cycles through them)\n"
"      --tf-range R         what the --tf files' values are placed on: data\n"
"                           (default: a preset's domain and normalized values\n"
"                           rescaled onto the data range, as ParaView does),\n"
"                           MIN:MAX (onto MIN..MAX instead: absolute values,\n"
"                           e.g. 20:50 for 20..50 m/s) or preset (each file's\n"
"                           own values, unrescaled; text files need \"domain\n"
"                           data\").  Log-scale TFs need a range above 0\n"
"      --nan-color SPEC     colour of missing values (voxels that decode to\n"
"                           NaN) for every transfer function: none\n"
"                           (transparent) or R,G,B[,A], each 0..1, A default\n"
"                           1; default: the TF file's (transparent unless it\n"
"                           says)\n"
"      --opacity S          opacity scale, 0..1000 (default 1)\n"
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
"      --level N            draw from level of detail N (0: the finest;\n"
"                           tvpal-encode --levels); default: the finest\n"
"                           whose voxels are at least half a pixel, and\n"
"                           in a window coarser while dragging, scrubbing or\n"
"                           playing faster than --budget-ms allows\n"
"      --budget-ms MS       window: the frame time to keep to while the view\n"
"                           moves, 1..100000 (default 66, about 15 fps)\n"
"      --progressive on|off never wait for the disk: a jump, or reads\n"
"                           behind the clock, draw a coarser level at once\n"
"                           while the full level's records load off the\n"
"                           frame's thread, then the full level (default: on\n"
"                           in the window, off headless: every frame at its\n"
"                           full level, for exact frames and movies)\n"
"      --exact              cpu renderer: blend every sample until a pixel is\n"
"                           fully opaque (default: a pixel stops once its\n"
"                           remaining transmittance is at most 1/272, which\n"
"                           changes no 8-bit pixel by more than one level)\n"
"      --scale-z F          stretch z by F, 0.001..1000 (vertical\n"
"                           exaggeration; default 1: the dataset's spacing,\n"
"                           its physical shape)\n"
"      --spin DEG           turn the view DEG degrees about y per frame,\n"
"                           -360..360\n"
"                           (a camera path; with three copies crossing axes\n"
"                           loads records, with one copy nothing)\n"
"Annotations (drawn into the final image: PNG frames, movies and the window\n"
"alike, on rank 0 after compositing; need cairo):\n"
"      --annotate A         none, minimal (a colour legend of the transfer\n"
"                           function with value labels and the variable's\n"
"                           name, and the time, or the step where the dataset\n"
"                           has no times) or full (default: minimal, the\n"
"                           volume's outline and an x, y, z triad); none\n"
"                           without cairo\n"
"      --legend P           where the legend goes: auto (default: of right,\n"
"                           right-top, right-bottom and left, the first that\n"
"                           covers the least of the volume), right,\n"
"                           right-top, right-bottom or left\n"
"      --background C       the colour behind the volume: black (default),\n"
"                           white, gray, darkgray or R,G,B, each 0..1\n");
}

/* --help, second part: data, output, cluster, window keys, exit status. */
static void usage_data_output(FILE *f)
{
    fprintf(f,
"Data:\n"
"  -m, --mode M             incore (records in RAM) or stream (default: from\n"
"                           disk, O_DIRECT, prefetching)\n"
"      --io B               auto (default: io_uring, else pread, with a\n"
"                           warning), uring (io_uring or fail) or pread\n"
"      --prefetch P         timesteps read ahead when streaming, 0..64\n"
"                           (default 4); above 0 a stager thread also\n"
"                           prepares the next step while one is drawn\n"
"      --read-ahead MIB     streaming: a step's records are read in turn,\n"
"                           each checked while the next is read, as many\n"
"                           at once as fit in MIB, 1..65536 (default 32)\n"
"      --direct             O_DIRECT or fail (default: O_DIRECT where the\n"
"                           file system takes it, else a warning)\n"
"      --no-direct          stream through the page cache\n"
"      --mem MIB            in-core: keep at most MIB (1..16777216) of\n"
"                           records in RAM\n"
"                           (axes beyond it are dropped or streamed); also\n"
"                           reports how many timesteps fit in MIB\n"
"      --from-z             draw every view from the z slices, as for a\n"
"                           single-copy dataset (tvpal-encode --axes z),\n"
"                           even where x and y are stored (comparisons)\n"
"Benchmarking (headless):\n"
"      --repeat K           draw every frame K times, 1..100000 (times the\n"
"                           draw alone)\n"
"      --tf-cycle           use the next --tf every frame\n"
"      --jumps K            every K-th frame jumps to a random timestep of\n"
"                           A..B, K in 1..1000000 (CSV column jump = 1);\n"
"                           playback goes on from there (after B: A)\n"
"      --jump-span S        such a jump lands within S steps of the frame's\n"
"                           step, 1..1000000 (the slider's neighbourhood)\n"
"      --loop K             play A..B K times over, 1..100000 (frames of a\n"
"                           step again overwrite its PNG)\n"
"Output:\n"
"  -o, --output DIR         write PNG frames here (created)\n"
"  -o, --output FILE.mp4    write a movie instead: .mp4 (H.264) or .webm\n"
"                           (VP9), yuv420p, through ffmpeg (Debian: ffmpeg;\n"
"                           needed on PATH); written as FILE.partial.mp4\n"
"                           and renamed when complete; an odd width or\n"
"                           height gets one more column or row (a copy of\n"
"                           the last: yuv420p needs even sizes)\n"
"      --fps F              frames per second, 0.1..1000: the movie's\n"
"                           (default 24); headless without a movie, and\n"
"                           with --progressive on, the clock frames keep\n"
"                           to (a playback); in the window the playing\n"
"                           rate (default: as fast as drawn)\n"
"      --csv FILE           per-frame timings (default DIR/timing.csv with\n"
"                           -o DIR, none with a movie; in the window: frame,\n"
"                           step, level, interacting, frame_ms)\n"
"      --progress S         headless, when stderr is not a terminal: a\n"
"                           progress line every S seconds, 0..86400\n"
"                           (default 10; 0: every frame); on a terminal a\n"
"                           progress bar with ETA; none with --quiet\n"
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
"      --autoplay K         window: play K frames (1..100000000) from A,\n"
"                           then exit\n"
"      --screenshot FILE    window: save the last frame shown as PNG\n"
"      --shot-dir DIR       window: where S saves tvpal-shot-NNNN.png\n"
"                           (created; default: the current directory)\n"
"      --no-hud             window: start with the HUD hidden (H shows it)\n"
"  -q, --quiet              only the closing summary line\n"
"  -h, --help               this help\n"
"  -V, --version            version\n"
"\n"
"Window keys: space play/pause, Right/Left (or . ,) step, Home/End first/\n"
"last, B reverse direction, T next transfer function, R reload it from its\n"
"file, Up/Down opacity, ] / [ stretch or shrink z, M in-core/out-of-core,\n"
"+/- or wheel zoom, 1 2 3 4 5 6 the views +x -x +y -y +z -z and 0 iso\n"
"(as --view, with --up), H show/hide the HUD, S screenshot\n"
"(tvpal-shot-NNNN.png in --shot-dir; what the window shows, HUD included),\n"
"Q or Esc quit.  Mouse: drag the image to rotate, drag or click the slider\n"
"to scrub.  While dragging or scrubbing every other slice is drawn; the\n"
"full image follows when idle.  The HUD (top left, shown at start unless\n"
"--no-hud; needs cairo) and the title show timestep and time, fps,\n"
"renderer, level of detail and transfer function.\n"
"\n"
"A record that fails to load is reported (file, record); the affected\n"
"slices keep their last good data and playback continues, unless --strict.\n"
"Exit status: 0 success; 1 failure (GL context, writing output) or load\n"
"errors during playback; 2 bad input or usage, a dataset that cannot be\n"
"opened, or (with --strict) the first load error.\n");
}

static void usage(FILE *f)
{
    usage_view(f);
    usage_data_output(f);
}

/* ---------------------------------------------------------- the table */

/* How an option's argument is taken.  Numbers are checked against
 * [lo, hi]; a refused argument is reported as
 * `--NAME "ARG": expected EXPECT` (exit 2). */
enum opt_kind {
    OPT_SET,      /* no argument: int field = lo */
    OPT_U32,      /* uint32_t field in [lo, hi] */
    OPT_DOUBLE,   /* finite double field in [lo, hi] */
    OPT_TEXT,     /* const char * field = the argument */
    OPT_FN        /* fn(o, arg): 0 or -1 */
};

struct opt_def {
    const char *name;
    int key;                   /* getopt's value: the short letter or > 255 */
    enum opt_kind kind;
    size_t off;                /* field of struct play_opts */
    double lo, hi;
    int (*fn)(struct play_opts *o, const char *arg);
    const char *expect;
};

#define F(field) offsetof(struct play_opts, field)

/* --size WxH: each 1..PLAY_SIZE_MAX. */
static int set_size(struct play_opts *o, const char *arg)
{
    uint32_t wh[2];
    if (tvpal_parse_u32_pair(arg, 'x', 1, PLAY_SIZE_MAX, wh) < 0)
        return -1;
    o->width = wh[0];
    o->height = wh[1];
    return 0;
}

/* --rotate AX,AY: each a finite number of degrees in
 * [-PLAY_DEG_MAX, PLAY_DEG_MAX]. */
static int set_rotate(struct play_opts *o, const char *arg)
{
    char ax[64];
    const char *comma = strchr(arg, ',');
    double a, b;
    if (!comma || (size_t)(comma - arg) >= sizeof ax)
        return -1;
    memcpy(ax, arg, (size_t)(comma - arg));
    ax[comma - arg] = 0;
    if (tvpal_parse_double_in(ax, -PLAY_DEG_MAX, PLAY_DEG_MAX, &a) < 0 ||
        tvpal_parse_double_in(comma + 1, -PLAY_DEG_MAX, PLAY_DEG_MAX, &b) < 0)
        return -1;
    o->ax = a;
    o->ay = b;
    o->rotate_given = 1;
    return 0;
}

static int set_view(struct play_opts *o, const char *arg)
{
    o->view = tvpal_view_name_parse(arg);
    return o->view < 0 ? -1 : 0;
}

static int set_up(struct play_opts *o, const char *arg)
{
    if (strlen(arg) != 1 || !strchr("xyz", arg[0]))
        return -1;
    o->up = arg[0] - 'x';
    return 0;
}

static int set_legend(struct play_opts *o, const char *arg)
{
    static const char *const names[TVPAL_ANNOT_PLACES] = {
        "auto", "right", "right-top", "right-bottom", "left"};
    for (unsigned k = 0; k < TVPAL_ANNOT_PLACES; k++)
        if (!strcmp(arg, names[k])) {
            o->legend_place = k;
            return 0;
        }
    return -1;
}

static int set_slice_axis(struct play_opts *o, const char *arg)
{
    if (!strcmp(arg, "auto"))
        o->slice_axis = 0;
    else if (strlen(arg) == 1 && strchr("xyz", arg[0]))
        o->slice_axis = 1 + (unsigned)(arg[0] - 'x');
    else
        return -1;
    return 0;
}

static int set_fps(struct play_opts *o, const char *arg)
{
    o->fps_given = 1;
    return tvpal_parse_double_in(arg, 0.1, 1000, &o->fps);
}

static int set_tf(struct play_opts *o, const char *arg)
{
    if (o->ntf == PLAY_MAX_TF)
        play_die(2, "--tf: at most %d transfer functions", PLAY_MAX_TF);
    o->tf_files[o->ntf++] = arg;
    return 0;
}

/* The transfer-function options' keys (apart: the main list grows
 * elsewhere). */
enum { K_TF_RANGE = 512 };

/* --tf-range data | preset | MIN:MAX (finite, MIN < MAX). */
static int set_tf_range(struct play_opts *o, const char *arg)
{
    const char *colon = strchr(arg, ':');
    char lo[64];
    if (!strcmp(arg, "data") || !strcmp(arg, "preset")) {
        o->tf_range = !strcmp(arg, "data") ? PLAY_TF_DATA : PLAY_TF_PRESET;
        return 0;
    }
    if (!colon || (size_t)(colon - arg) >= sizeof lo)
        return -1;
    memcpy(lo, arg, (size_t)(colon - arg));
    lo[colon - arg] = 0;
    if (tvpal_parse_double_in(lo, -HUGE_VAL, HUGE_VAL, &o->tf_lo) < 0 ||
        tvpal_parse_double_in(colon + 1, -HUGE_VAL, HUGE_VAL, &o->tf_hi) < 0 ||
        !(o->tf_lo < o->tf_hi))
        return -1;
    o->tf_range = PLAY_TF_MINMAX;
    return 0;
}

/* A colour "R,G,B" or, with max 4, "R,G,B,A": each in [0, 1], into c
 * (entries not given are left as they are).  0 or -1. */
static int parse_colour(const char *arg, unsigned max, float *c)
{
    unsigned n = 0;
    for (const char *p = arg;;) {
        char num[64];
        size_t len = strcspn(p, ",");
        double v;
        if (n == max || len >= sizeof num)
            return -1;
        memcpy(num, p, len);
        num[len] = 0;
        if (tvpal_parse_double(num, &v) < 0 || !(v >= 0 && v <= 1))
            return -1;
        c[n++] = (float)v;
        if (!p[len])
            break;
        p += len + 1;
    }
    return n < 3 ? -1 : 0;
}

/* --nan-color none | R,G,B[,A]: each in [0, 1], A 1 when left out. */
static int set_nan_color(struct play_opts *o, const char *arg)
{
    float c[4] = {0, 0, 0, 1};
    o->nan_given = 1;
    if (!strcmp(arg, "none")) {
        memset(o->nan_rgba, 0, sizeof o->nan_rgba);
        return 0;
    }
    if (parse_colour(arg, 4, c) < 0)
        return -1;
    memcpy(o->nan_rgba, c, sizeof c);
    return 0;
}

/* --background NAME | R,G,B (each 0..1). */
static int set_background(struct play_opts *o, const char *arg)
{
    static const struct {
        const char *name;
        float rgb[3];
    } named[] = {{"black", {0, 0, 0}}, {"white", {1, 1, 1}},
                 {"gray", {0.5f, 0.5f, 0.5f}}, {"grey", {0.5f, 0.5f, 0.5f}},
                 {"darkgray", {0.2f, 0.2f, 0.2f}},
                 {"darkgrey", {0.2f, 0.2f, 0.2f}}};
    for (size_t i = 0; i < sizeof named / sizeof *named; i++)
        if (!strcmp(arg, named[i].name)) {
            memcpy(o->background, named[i].rgb, sizeof o->background);
            return 0;
        }
    float c[3];
    if (parse_colour(arg, 3, c) < 0)
        return -1;
    memcpy(o->background, c, sizeof c);
    return 0;
}

/* --annotate none | minimal | full. */
static int set_annotate(struct play_opts *o, const char *arg)
{
    static const char *const names[] = {"none", "minimal", "full"};
    for (int i = 0; i < 3; i++)
        if (!strcmp(arg, names[i])) {
            o->annotate = PLAY_ANNOT_NONE + i;
            return 0;
        }
    return -1;
}

static int set_renderer(struct play_opts *o, const char *arg)
{
    static const char *const names[] = {"gl", "cpu", "ref", "none"};
    static const int kinds[] = {PLAY_REND_GL, PLAY_REND_CPU, PLAY_REND_REF,
                                PLAY_REND_NONE};
    for (int i = 0; i < 4; i++)
        if (!strcmp(arg, names[i])) {
            o->renderer = kinds[i];
            return 0;
        }
    return -1;
}

static int set_fb(struct play_opts *o, const char *arg)
{
    o->fb_given = 1;
    return tvpal_parse_u32(arg, 8, 32, &o->fb_bits) == 0 &&
                   (o->fb_bits == 8 || o->fb_bits == 16 || o->fb_bits == 32)
               ? 0 : -1;
}

static int set_progressive(struct play_opts *o, const char *arg)
{
    if (!strcmp(arg, "on") || !strcmp(arg, "off")) {
        o->progressive = !strcmp(arg, "on");
        return 0;
    }
    return -1;
}

static int set_level(struct play_opts *o, const char *arg)
{
    o->level_given = 1;
    return tvpal_parse_u32(arg, 0, TVPAL_LEVELS_MAX, &o->level);
}

static int set_cpu_scale(struct play_opts *o, const char *arg)
{
    o->scale_given = 1;
    if (!strcmp(arg, "auto"))
        return 0;
    return tvpal_parse_u32(arg, 1, 8, &o->cpu_scale);
}

static int set_mode(struct play_opts *o, const char *arg)
{
    if (!strcmp(arg, "incore"))
        o->po.incore = 1;
    else if (strcmp(arg, "stream"))
        return -1;
    return 0;
}

static int set_io(struct play_opts *o, const char *arg)
{
    if (!strcmp(arg, "pread"))
        o->po.io = TVPAL_IO_PREAD;
    else if (!strcmp(arg, "uring"))
        o->po.io_strict = 1;
    else if (strcmp(arg, "auto"))
        return -1;
    return 0;
}

static int set_prefetch(struct play_opts *o, const char *arg)
{
    return tvpal_parse_u32(arg, 0, 64, &o->po.prefetch);
}

static int set_composite(struct play_opts *o, const char *arg)
{
    if (!strcmp(arg, "gather"))
        o->ckind = TVPAL_COMPOSE_GATHER;
    else if (strcmp(arg, "bswap"))
        return -1;
    return 0;
}

enum { K_HEADLESS = 256, K_SPIN, K_SHARD_DIR, K_COMPOSITE, K_FB, K_CPU_SCALE,
       K_REPEAT, K_TF_CYCLE, K_JUMPS, K_LOOP, K_AUTOPLAY, K_SCREENSHOT, K_OPACITY,
       K_RENDERER, K_IO, K_PREFETCH, K_NO_DIRECT, K_DIRECT, K_MEM, K_CSV, K_STRICT,
       K_REF_PSNR, K_SCALE_Z, K_NAN_COLOR, K_EXACT, K_LEVEL, K_BUDGET,
       K_FROM_Z, K_ANNOTATE, K_BACKGROUND, K_SHOT_DIR, K_NO_HUD,
       K_READ_AHEAD, K_PROGRESSIVE, K_JUMP_SPAN };
/* Views, movies and progress (apart: the list above grows elsewhere). */
enum { K_VIEW = 384, K_UP, K_FPS, K_PROGRESS, K_SLICE_AXIS, K_LEGEND };

/* Grouped as --help groups them. */
static const struct opt_def opt_table[] = {
    /* view and frames */
    {"headless", K_HEADLESS, OPT_SET, F(window), 0, 0, NULL, NULL},
    {"window", 'w', OPT_SET, F(window), 1, 0, NULL, NULL},
    {"steps", 's', OPT_TEXT, F(steps), 0, 0, NULL, NULL},
    {"size", 'S', OPT_FN, 0, 0, 0, set_size, "WxH, each 1..16384"},
    {"rotate", 'r', OPT_FN, 0, 0, 0, set_rotate,
     "AX,AY in degrees, each -360..360"},
    {"view", K_VIEW, OPT_FN, 0, 0, 0, set_view,
     "+x, -x, +y, -y, +z, -z or iso"},
    {"up", K_UP, OPT_FN, 0, 0, 0, set_up, "x, y or z"},
    {"slice-axis", K_SLICE_AXIS, OPT_FN, 0, 0, 0, set_slice_axis,
     "auto, x, y or z"},
    {"zoom", 'z', OPT_DOUBLE, F(zoom), 0.001, 1000, NULL,
     "a number in 0.001..1000"},
    {"tf", 't', OPT_FN, 0, 0, 0, set_tf, NULL},
    {"tf-range", K_TF_RANGE, OPT_FN, 0, 0, 0, set_tf_range,
     "MIN:MAX (finite numbers, MIN < MAX), data or preset"},
    {"nan-color", K_NAN_COLOR, OPT_FN, 0, 0, 0, set_nan_color,
     "none or R,G,B[,A], each 0..1"},
    {"opacity", K_OPACITY, OPT_DOUBLE, F(opacity), 0, 1000, NULL,
     "a number in 0..1000"},
    {"renderer", K_RENDERER, OPT_FN, 0, 0, 0, set_renderer,
     "gl, cpu, ref or none"},
    {"fb", K_FB, OPT_FN, 0, 0, 0, set_fb, "8, 16 or 32"},
    {"cpu-scale", K_CPU_SCALE, OPT_FN, 0, 0, 0, set_cpu_scale,
     "auto or 1..8"},
    {"exact", K_EXACT, OPT_SET, F(exact), 1, 0, NULL, NULL},
    {"level", K_LEVEL, OPT_FN, 0, 0, 0, set_level, "0..8"},
    {"progressive", K_PROGRESSIVE, OPT_FN, 0, 0, 0, set_progressive,
     "on or off"},
    {"budget-ms", K_BUDGET, OPT_U32, F(budget_ms), 1, 100000, NULL,
     "1..100000"},
    {"spin", K_SPIN, OPT_DOUBLE, F(spin), -PLAY_DEG_MAX, PLAY_DEG_MAX, NULL,
     "degrees in -360..360"},
    {"scale-z", K_SCALE_Z, OPT_DOUBLE, F(scale_z), 0.001, 1000, NULL,
     "a factor in 0.001..1000"},
    {"annotate", K_ANNOTATE, OPT_FN, 0, 0, 0, set_annotate,
     "none, minimal or full"},
    {"legend", K_LEGEND, OPT_FN, 0, 0, 0, set_legend,
     "auto, right, right-top, right-bottom or left"},
    {"background", K_BACKGROUND, OPT_FN, 0, 0, 0, set_background,
     "black, white, gray, darkgray or R,G,B, each 0..1"},
    /* data */
    {"mode", 'm', OPT_FN, 0, 0, 0, set_mode, "incore or stream"},
    {"io", K_IO, OPT_FN, 0, 0, 0, set_io, "auto, uring or pread"},
    {"direct", K_DIRECT, OPT_SET, F(want_direct), 1, 0, NULL, NULL},
    {"prefetch", K_PREFETCH, OPT_FN, 0, 0, 0, set_prefetch, "0..64"},
    {"read-ahead", K_READ_AHEAD, OPT_U32, F(read_ahead_mib), 1, 65536, NULL,
     "MiB in 1..65536"},
    {"no-direct", K_NO_DIRECT, OPT_SET, F(no_direct), 1, 0, NULL, NULL},
    {"mem", K_MEM, OPT_U32, F(mem_mib), 1, 16777216, NULL,
     "MiB in 1..16777216"},
    {"from-z", K_FROM_Z, OPT_SET, F(from_z), 1, 0, NULL, NULL},
    /* benchmarking */
    {"repeat", K_REPEAT, OPT_U32, F(repeat), 1, 100000, NULL, "1..100000"},
    {"tf-cycle", K_TF_CYCLE, OPT_SET, F(tf_cycle), 1, 0, NULL, NULL},
    {"jumps", K_JUMPS, OPT_U32, F(jumps), 1, 1000000, NULL, "1..1000000"},
    {"jump-span", K_JUMP_SPAN, OPT_U32, F(jump_span), 1, 1000000, NULL,
     "1..1000000"},
    {"loop", K_LOOP, OPT_U32, F(loops), 1, 100000, NULL, "1..100000"},
    /* output */
    {"output", 'o', OPT_TEXT, F(outdir), 0, 0, NULL, NULL},
    {"fps", K_FPS, OPT_FN, 0, 0, 0, set_fps, "frames per second in 0.1..1000"},
    {"csv", K_CSV, OPT_TEXT, F(csv_path), 0, 0, NULL, NULL},
    {"progress", K_PROGRESS, OPT_DOUBLE, F(progress_s), 0, 86400, NULL,
     "seconds in 0..86400"},
    {"strict", K_STRICT, OPT_SET, F(strict), 1, 0, NULL, NULL},
    {"ref-psnr", K_REF_PSNR, OPT_SET, F(ref_psnr), 1, 0, NULL, NULL},
    /* cluster and window */
    {"shard-dir", K_SHARD_DIR, OPT_TEXT, F(shard_pat), 0, 0, NULL, NULL},
    {"composite", K_COMPOSITE, OPT_FN, 0, 0, 0, set_composite,
     "bswap or gather"},
    {"autoplay", K_AUTOPLAY, OPT_U32, F(autoplay), 1, 100000000, NULL,
     "a frame count in 1..100000000"},
    {"screenshot", K_SCREENSHOT, OPT_TEXT, F(shot), 0, 0, NULL, NULL},
    {"shot-dir", K_SHOT_DIR, OPT_TEXT, F(shot_dir), 0, 0, NULL, NULL},
    {"no-hud", K_NO_HUD, OPT_SET, F(no_hud), 1, 0, NULL, NULL},
    {"quiet", 'q', OPT_SET, F(quiet), 1, 0, NULL, NULL},
};
#define NOPTS (sizeof opt_table / sizeof *opt_table)

/* Options that take no argument (getopt's has_arg). */
static int takes_arg(const struct opt_def *d)
{
    return d->kind != OPT_SET;
}

static void defaults(struct play_opts *o)
{
    *o = (struct play_opts){
        .width = 512, .height = 512, .ax = 20, .ay = 30, .zoom = 1,
        .scale_z = 1,
        .opacity = 1, .renderer = PLAY_REND_AUTO, .renderer_why = "",
        .fb_bits = 32, .window = -1, .repeat = 1, .loops = 1, .budget_ms = 66,
        .annotate = PLAY_ANNOT_AUTO,
        .view = -1, .up = -1, .fps = 24, .progressive = -1,
        .progress_s = PLAY_PROGRESS_EVERY_S,
        .po = {.incore = 0, .io = TVPAL_IO_URING, .prefetch = 4, .direct = 1},
        .ckind = TVPAL_COMPOSE_BSWAP};
}

/* Applies table entry d to its argument; 0 or -1. */
static int apply(struct play_opts *o, const struct opt_def *d,
                 const char *arg)
{
    char *base = (char *)o;
    switch (d->kind) {
    case OPT_SET:
        *(int *)(void *)(base + d->off) = (int)d->lo;
        return 0;
    case OPT_U32:
        return tvpal_parse_u32(arg, (uint32_t)d->lo, (uint32_t)d->hi,
                               (uint32_t *)(void *)(base + d->off));
    case OPT_DOUBLE:
        return tvpal_parse_double_in(arg, d->lo, d->hi,
                                     (double *)(void *)(base + d->off));
    case OPT_TEXT:
        *(const char **)(void *)(base + d->off) = arg;
        return 0;
    case OPT_FN:
        return d->fn(o, arg);
    }
    return -1;
}

static void print_version(void)
{
    printf(PROG " " PACKAGE_VERSION " (window: %s, gl: %s, mpi: %s, "
           "uring: %s, annotations: %s, crc32c: %s)\n",
#ifdef TVPAL_HAVE_WINDOW
           "yes",
#else
           "no",
#endif
#ifdef TVPAL_HAVE_GL
           "yes",
#else
           "no",
#endif
           tvpal_comm_mpi_built() ? "yes" : "no",
#ifdef HAVE_LIBURING
           "yes",
#else
           "no",
#endif
           tvpal_annot_available() ? "yes" : "no",
           tvpal_crc32c_impl_name(tvpal_crc32c_impl()));
}

int play_options_parse(struct play_opts *o, int argc, char **argv)
{
    struct option lopts[NOPTS + 3];
    for (size_t i = 0; i < NOPTS; i++)
        lopts[i] = (struct option){opt_table[i].name,
                                   takes_arg(&opt_table[i]) ? required_argument
                                                            : no_argument,
                                   NULL, opt_table[i].key};
    lopts[NOPTS] = (struct option){"help", no_argument, NULL, 'h'};
    lopts[NOPTS + 1] = (struct option){"version", no_argument, NULL, 'V'};
    lopts[NOPTS + 2] = (struct option){NULL, 0, NULL, 0};
    defaults(o);
    int c;
    while ((c = getopt_long(argc, argv, "s:S:r:z:t:m:o:wqhV", lopts, NULL)) != -1) {
        if (c == 'h') {
            usage(stdout);
            return 1;
        }
        if (c == 'V') {
            print_version();
            return 1;
        }
        const struct opt_def *d = NULL;
        for (size_t i = 0; i < NOPTS && !d; i++)
            if (opt_table[i].key == c)
                d = &opt_table[i];
        if (!d) {
            fprintf(stderr, "Try '" PROG " --help'.\n");
            play_cluster_end();
            exit(2);
        }
        if (apply(o, d, optarg) < 0)
            play_die(2, "--%s \"%s\": expected %s", d->name, optarg,
                     d->expect);
    }
    if (optind != argc - 1)
        play_die(2, "expected one OUTDIR (try --help)");
    o->dir = argv[optind];
    o->po.mem_budget = (uint64_t)o->mem_mib << 20;
    o->po.read_ahead = (uint64_t)o->read_ahead_mib << 20;
    o->po.z_only = o->from_z;
    if (o->no_direct && o->want_direct)
        play_die(2, "--direct and --no-direct: choose one");
    o->po.direct = !o->no_direct;
    o->po.direct_strict = o->want_direct;
    return 0;
}

/* ---------------------------------------------------------- the rules */

/* Options that belong to one renderer choose it, or are refused with
 * another. */
static void check_renderer_options(struct play_opts *o)
{
    if (o->fb_given && o->renderer == PLAY_REND_AUTO) {
        o->renderer = PLAY_REND_GL;
        o->renderer_why = "; --fb asks for a GL framebuffer";
    }
    if (o->fb_given && o->renderer != PLAY_REND_GL)
        play_die(2, "--fb: the GL framebuffer's depth; only with --renderer "
                 "gl (the cpu renderer accumulates in float)");
    if (o->scale_given && o->renderer == PLAY_REND_AUTO) {
        o->renderer = PLAY_REND_CPU;
        o->renderer_why = "; --cpu-scale asks for it";
    }
    if (o->scale_given && o->renderer != PLAY_REND_CPU)
        play_die(2, "--cpu-scale: the shear-warp intermediate image's "
                 "resolution; only with --renderer cpu");
}

/* --annotate: full by default where cairo is built in; minimal and full
 * refused without it (naming the package), none always possible. */
static void check_annotate(struct play_opts *o)
{
    if (o->annotate == PLAY_ANNOT_AUTO)
        o->annotate = tvpal_annot_available() ? PLAY_ANNOT_FULL
                                              : PLAY_ANNOT_NONE;
    else if (o->annotate != PLAY_ANNOT_NONE && !tvpal_annot_available())
        play_die(2, "--annotate %s: %s; --annotate none draws none",
                 o->annotate == PLAY_ANNOT_FULL ? "full" : "minimal",
                 tvpal_annot_describe());
}

/* --view and --rotate, --up with the view. */
static void check_view_options(const struct play_opts *o)
{
    if (o->view >= 0 && o->rotate_given)
        play_die(2, "--view and --rotate: choose one (--view %s is a "
                 "rotation of its own)", tvpal_view_name_str(o->view));
    double orient[3][3];
    if (o->view >= 0 && o->up >= 0 &&
        tvpal_view_orient(o->view, o->up, orient) < 0)
        play_die(2, "--up %c: the view %s looks along %c; choose another "
                 "axis", "xyz"[o->up], tvpal_view_name_str(o->view),
                 "xyz"[o->up]);
    if (o->up >= 0 && o->view < 0 && !o->window)
        play_die(2, "--up: the up axis of a named view; give --view (or, "
                 "in the window, press a view key)");
}

/* -o FILE.mp4|.webm: a movie, headless. */
static void check_movie_options(struct play_opts *o)
{
    o->movie = o->outdir ? tvpal_movie_kind(o->outdir) : TVPAL_MOVIE_NONE;
    if (o->movie && o->window > 0)
        play_die(2, "-o %s: movies are written headless (--headless)",
                 o->outdir);
}

void play_options_check(struct play_opts *o, int nranks)
{
    check_renderer_options(o);
    check_annotate(o);
    check_movie_options(o);
    if (o->window < 0)
        o->window = getenv("DISPLAY") && *getenv("DISPLAY") && !o->outdir;
    /* The window shows what is there now; written frames wait for the
     * full level unless asked. */
    if (o->progressive < 0)
        o->progressive = o->window ? 1 : 0;
    check_view_options(o);
    if (o->window) {
        if (o->ref_psnr)
            play_die(2, "--ref-psnr: headless only");
        if (o->renderer == PLAY_REND_REF || o->renderer == PLAY_REND_NONE)
            play_die(2, "--renderer %s: headless only (the window renders "
                     "with gl or cpu)",
                     o->renderer == PLAY_REND_REF ? "ref" : "none");
        return; /* the window's GL decides an automatic choice */
    }
    if (o->autoplay || o->shot || o->shot_dir || o->no_hud)
        play_die(2, "--autoplay, --screenshot, --shot-dir and --no-hud need "
                 "the window (--window)");
    /* Headless GL is OSMesa, a software rasterizer: the CPU renderer is
     * the faster one there. */
    if (o->renderer == PLAY_REND_AUTO) {
        o->renderer = PLAY_REND_CPU;
        o->renderer_why = "; default: headless GL is OSMesa, which draws on "
                          "the CPU";
    }
    if (o->ref_psnr && (nranks > 1 || o->renderer == PLAY_REND_NONE ||
                        o->renderer == PLAY_REND_REF))
        play_die(2, "--ref-psnr: one rank, with the cpu or gl renderer");
}

void play_tf_apply_options(const struct play_opts *o, struct tvpal_tf *tf)
{
    if (o->nan_given)
        memcpy(tf->nan_rgba, o->nan_rgba, sizeof tf->nan_rgba);
}

int play_tf_load(const struct play_opts *o, const struct tvpal_manifest *m,
                 unsigned i, struct tvpal_tf *tf, struct tvpal_diag *d)
{
    double lo = m->value_min, hi = m->value_max;
    if (o->tf_range == PLAY_TF_MINMAX) {
        lo = o->tf_lo;
        hi = o->tf_hi;
    } else if (o->tf_range == PLAY_TF_PRESET) {
        lo = hi = NAN; /* tvpal_tf_load: keep the file's values */
    }
    int rc = tvpal_tf_load(o->tf_files[i], lo, hi, tf, d);
    if (rc == TVPAL_E_RANGE && o->tf_range == PLAY_TF_DATA) {
        size_t n = strlen(d->msg);
        snprintf(d->msg + n, sizeof d->msg - n, " (give one with --tf-range "
                 "MIN:MAX, MIN > 0)");
    }
    if (rc == 0)
        play_tf_apply_options(o, tf);
    return rc;
}

void play_view_spacing(const struct tvpal_manifest *m, double scale_z,
                       double spacing[3])
{
    for (int i = 0; i < 3; i++)
        spacing[i] = m->spacing[i] > 0 ? m->spacing[i] : 1.0;
    spacing[2] *= scale_z > 0 ? scale_z : 1.0;
    /* The unit grid stays the view's isotropic case (same bits as before
     * spacing existed). */
    if (spacing[0] == 1 && spacing[1] == 1 && spacing[2] == 1)
        spacing[0] = spacing[1] = spacing[2] = 0;
}

void play_view_named(struct tvpal_view *v, int view, int up)
{
    if (view < 0)
        return;
    if (up < 0 || tvpal_view_orient(view, up, v->orient) < 0)
        tvpal_view_orient(view, tvpal_view_default_up(view), v->orient);
    v->oriented = 1;
    v->ax_deg = v->ay_deg = 0;
}
