/* tvpal-playcheck DIR: checks of the player core on an encoded dataset,
 * with the GL renderer (OSMesa) and the CPU reference:
 *  - GL frames match the reference within tolerance on all three axes;
 *  - a jump to t renders the same image as playing 0..t, and backward
 *    playback the same as forward;
 *  - in-core, io_uring (O_DIRECT) and pread give identical images;
 *  - a transfer-function change uploads no slice texture; a forward step
 *    uploads only the slices whose window starts there (about 1/N);
 *  - playback round a loop (tvpal_player_loop): the stager prepares the
 *    loop's first step after its last, and a read-ahead goes round it,
 *    so the frames there read nothing and draw what playing draws;
 *  - the meter (tvpal_player_meter) counts the bytes read and the time
 *    the disk was busy, and coded records inflated.
 * Exit 0 pass, 1 fail, 99 setup error. */
#include "tvpal_clock.h"
#include "tvpal_glr.h"
#include "tvpal_osmesa.h"
#include "tvpal_player.h"
#include "tvpal_render_ref.h"
#include "tvpal_test.h"
#include "tvpal_schedule.h"
#include "tvpal_shard.h"
#include "tvpal_stream.h"

#include <stdio.h>
#include <string.h>
#include <time.h>

#define W 128
#define H 112

static struct tvpal_glr *glr;

/* The palette group size of axis a's shards (node 0's; 1: none). */
static uint32_t axis_group(const char *dir, unsigned a)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/node-0/axis-%c.tvps", dir, "xyz"[a]);
    struct tvpal_shard *sh = NULL;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_shard_open(&sh, path, &d) == 0, "%s: %s", path, d.msg);
    const uint32_t G = tvpal_shard_hdr(sh)->group;
    tvpal_shard_close(sh);
    return G;
}

static struct tvpal_player *open_player(const char *dir, int incore,
                                        enum tvpal_io_kind io, int direct)
{
    struct tvpal_player_opts o = {.incore = incore, .io = io, .prefetch = 3,
                                  .direct = direct};
    struct tvpal_player *p;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_player_open(&p, dir, &o, &d) == 0, "%s", d.msg);
    return p;
}

static struct tvpal_view view(const struct tvpal_manifest *m, double ax,
                              double ay)
{
    struct tvpal_view v = {.width = W, .height = H, .ax_deg = ax,
                           .ay_deg = ay, .zoom = 1.2};
    memcpy(v.dims, m->dims, sizeof v.dims);
    tvpal_view_setup(&v);
    return v;
}

/* Playback round the loop lo..Tm-1 (tvpal_player_loop), frames against
 * seq (playing 0..Tm-1), both backends:
 *  - steady: after the frame at its last step, the stager prepares its
 *    first (ready within 5 s; without the loop no job makes it, and it is
 *    refused at once), whose frame installs what was staged;
 *  - a read-ahead (keep_ahead) kept from three steps before its end goes
 *    round it: its first steps are kept, and the frames up to lo + 2
 *    read nothing.
 * lo > N - 1 needs windows begun before lo, which the read-ahead reads
 * first when it comes round. */
static void check_loop(const char *dir, const struct tvpal_view *v,
                       struct tvpal_renderer *r, float (*seq)[W * H * 4],
                       uint32_t Tm, uint32_t lo)
{
    static float img[W * H * 4];
    struct tvpal_frame_stats st;
    struct tvpal_diag d = {{0}};
    const uint32_t hi = Tm - 1;
    for (int pass = 0; pass < 4; pass++) {
        const int looped = pass < 2;
        struct tvpal_player *j = open_player(dir, 0, pass % 2 ? TVPAL_IO_PREAD
                                                              : TVPAL_IO_URING, 1);
        REQUIRE(!looped || tvpal_player_loop(j, lo, hi) == 0, "loop");
        REQUIRE(tvpal_player_frame(j, v, hi - 1, 1, r, img, &st, &d) == 0 &&
                    tvpal_player_frame(j, v, hi, 1, r, img, &st, &d) == 0,
                "%s", d.msg);
        const double w0 = tvpal_now();
        const int ready = tvpal_player_ready(j, v, lo, 5000);
        CHECK(ready == looped && (looped || tvpal_now() - w0 < 1.0),
              "loop %u..%u (%s): step %u after %u %s", lo, hi,
              looped ? "set" : "none", lo, hi,
              ready ? "prepared" : "not prepared");
        REQUIRE(tvpal_player_frame(j, v, lo, 1, r, img, &st, &d) == 0, "%s",
                d.msg);
        CHECK(!memcmp(img, seq[lo], sizeof img) && (st.staged > 0) == looped,
              "loop %u..%u: step %u after %u: %u records staged, image %s",
              lo, hi, lo, hi, st.staged,
              memcmp(img, seq[lo], sizeof img) ? "differs" : "the same");
        tvpal_player_close(j);
    }
    for (int pass = 0; pass < 2; pass++) {
        struct tvpal_player_opts o = {.io = pass ? TVPAL_IO_PREAD : TVPAL_IO_URING,
                                      .prefetch = 1, .direct = 1,
                                      .keep_ahead = (uint64_t)1 << 30};
        struct tvpal_player *k;
        REQUIRE(tvpal_player_open(&k, dir, &o, &d) == 0, "%s", d.msg);
        REQUIRE(tvpal_player_loop(k, lo, hi) == 0 &&
                tvpal_player_loop(k, lo, Tm + 5) == TVPAL_E_INVAL, "loop");
        const uint32_t t0 = hi - 3;
        REQUIRE(tvpal_player_frame(k, v, t0, 1, r, img, &st, &d) == 0, "%s",
                d.msg);
        CHECK(tvpal_player_keep(k, v, t0, 1, &d) == 1, "keep from %u", t0);
        const double k0 = tvpal_now();
        while (tvpal_player_busy(k, v) && tvpal_now() - k0 < 10)
            nanosleep(&(struct timespec){0, 2000000}, NULL);
        int near = 0;
        (void)tvpal_player_kept(k, v, lo + 1, &near);
        CHECK(near, "loop %u..%u: step %u not among those kept from %u", lo,
              hi, lo + 1, t0);
        uint64_t read = 0;
        uint32_t t = t0;
        for (int f = 0; f < 6; f++) {
            t = t == hi ? lo : t + 1;
            REQUIRE(tvpal_player_frame(k, v, t, 1, r, img, &st, &d) == 0, "%s",
                    d.msg);
            read += f > 0 ? st.bytes_read : 0; /* t0 + 1: staged before */
            CHECK(!memcmp(img, seq[t], sizeof img), "loop %u..%u read ahead: "
                  "step %u differs", lo, hi, t);
        }
        CHECK(read == 0, "%s: loop %u..%u: the 5 frames from %u on, round "
              "to %u, after the read-ahead read %llu bytes",
              pass ? "pread" : "uring", lo, hi, t0 + 2, t,
              (unsigned long long)read);
        tvpal_player_close(k);
    }
}

/* A read-ahead (keep_ahead: 24 steps or a few more) round a loop
 * lo..Tm-1 longer than its record buffers, over plain records (coded
 * ones keep to the buffers already touched), a keep after each frame (as
 * play_prog_keep asks) waited for, two rounds:
 *  - every frame draws what playing draws;
 *  - a frame at a step ready before it (its records in), not staged,
 *    reads nothing;
 *  - the second round reads only the records the buffers could not keep:
 *    a buffer is reused for the record shown again last (next_use), so
 *    of the B buffers read into, all but those a step shows, stages and
 *    reads ahead (N + N + P + the reach, and N more for the windows a
 *    step round the loop needs) keep records from the first round. */
static void check_cache(const char *dir, const struct tvpal_view *v,
                        struct tvpal_renderer *r, float (*seq)[W * H * 4],
                        uint32_t Tm, uint32_t lo, uint32_t N)
{
    static float img[W * H * 4];
    struct tvpal_frame_stats st;
    struct tvpal_diag d = {{0}};
    const uint32_t hi = Tm - 1, L = hi - lo + 1, P = 1;
    struct tvpal_player *k = NULL;
    unsigned around = 0;
    uint64_t stored = 0, plain = 0;
    {
        struct tvpal_player *q = open_player(dir, 0, TVPAL_IO_PREAD, 1);
        REQUIRE(tvpal_player_frame(q, v, lo, 1, r, img, &st, &d) == 0, "%s",
                d.msg);
        tvpal_player_step_bytes(q, v, &stored, &plain);
        tvpal_player_close(q);
    }
    for (uint64_t m = 1; m < 800 && around < 24; m++) {
        struct tvpal_player_opts o = {.io = TVPAL_IO_URING, .prefetch = P,
                                      .direct = 1,
                                      .keep_ahead = stored / 4 * m};
        tvpal_player_close(k);
        REQUIRE(tvpal_player_open(&k, dir, &o, &d) == 0 &&
                    tvpal_player_loop(k, lo, hi) == 0 &&
                    tvpal_player_open_axis(k, v->axis, &d) == 0,
                "%s", d.msg);
        around = tvpal_player_kept(k, v, lo, NULL);
    }
    REQUIRE(around >= 24 && around < L / 2, "loop %u..%u: read-ahead of %u "
            "steps", lo, hi, around);
    uint64_t round_bytes[2] = {0, 0}, ready_read = 0;
    unsigned buffers = 0;
    for (int round = 0; round < 2; round++) {
        struct tvpal_stream_meter m0, m1;
        tvpal_player_meter(k, v, &m0);
        for (uint32_t t = lo; t <= hi; t++) {
            const int ready = tvpal_player_ready(k, v, t, 0);
            REQUIRE(tvpal_player_frame(k, v, t, 1, r, img, &st, &d) == 0,
                    "%s", d.msg);
            CHECK(!memcmp(img, seq[t], sizeof img), "cache, round %d: step "
                  "%u differs", round + 1, t);
            /* (a step staged reports what the stager read for it) */
            ready_read += ready && !st.staged ? st.bytes_needed : 0;
            CHECK(tvpal_player_keep(k, v, t, 1, &d) >= 0, "%s", d.msg);
            const double k0 = tvpal_now();
            while (tvpal_player_busy(k, v) && tvpal_now() - k0 < 10)
                nanosleep(&(struct timespec){0, 2000000}, NULL);
        }
        tvpal_player_meter(k, v, &m1);
        round_bytes[round] = m1.read_bytes - m0.read_bytes;
        struct tvpal_io_path path;
        tvpal_player_io_path(k, &path);
        buffers = path.buffers;
    }
    /* The buffers that keep records of the first round, of L. */
    const unsigned busy = 3 * N + P + around;
    const unsigned keep = buffers > busy ? buffers - busy : 0;
    const double bound = (double)(L - (keep < L ? keep : L)) / L;
    const double got = (double)round_bytes[1] / (double)round_bytes[0];
    CHECK(ready_read == 0 && keep > 0 && got <= bound,
          "loop %u..%u, read-ahead %u, %u buffers: frames at ready steps "
          "read %llu bytes; round 2 read %.3f of round 1's bytes, more than "
          "%.3f", lo, hi, around, buffers, (unsigned long long)ready_read,
          got, bound);
    printf("cache: loop %u..%u, read-ahead %u steps, %u buffers; round 2 "
           "read %.3f of round 1's bytes (bound %.3f)\n", lo, hi, around,
           buffers, got, bound);
    tvpal_player_close(k);
}

/* The meter of player p, which has played view v's axis: bytes read with
 * a busy time, coded records counted as inflated; a step's records from
 * scratch hold at least a byte per voxel once inflated, and take fewer
 * stored where they are coded. */
static void check_meter(struct tvpal_player *p, const struct tvpal_view *v,
                        const struct tvpal_manifest *m)
{
    struct tvpal_stream_meter me;
    uint64_t stored = 0, plain = 0;
    tvpal_player_meter(p, v, &me);
    tvpal_player_step_bytes(p, v, &stored, &plain);
    const uint64_t voxels = (uint64_t)m->dims[0] * m->dims[1] * m->dims[2];
    CHECK(me.read_bytes > 0 && me.read_s > 0, "meter: %llu bytes in %.6f s",
          (unsigned long long)me.read_bytes, me.read_s);
    CHECK(plain >= voxels && stored > 0 && stored <= plain,
          "step bytes: %llu stored, %llu plain, %llu voxels",
          (unsigned long long)stored, (unsigned long long)plain,
          (unsigned long long)voxels);
    CHECK((stored < plain) == (me.inflated_bytes > 0 && me.inflate_s > 0),
          "meter: %llu bytes inflated in %.6f s (step: %llu stored, %llu "
          "plain)", (unsigned long long)me.inflated_bytes, me.inflate_s,
          (unsigned long long)stored, (unsigned long long)plain);
}

/* GL frames of player p against the CPU reference, in four views that
 * cover the three axes, at a few steps: within 2e-3 but for 1 in 50
 * values. */
static void check_gl_ref(struct tvpal_player *p, const struct tvpal_manifest *m,
                         struct tvpal_renderer *rgl, struct tvpal_renderer *rref)
{
    static float a[W * H * 4], b[W * H * 4];
    static const double views[][2] = {{10, 20}, {85, 10}, {5, 95}, {-30, 200}};
    struct tvpal_frame_stats st;
    struct tvpal_diag d = {{0}};
    const uint32_t T = m->steps;
    unsigned axes = 0;
    for (size_t vi = 0; vi < 4; vi++) {
        struct tvpal_view v = view(m, views[vi][0], views[vi][1]);
        axes |= 1u << v.axis;
        for (uint32_t t = 0; t < T; t += (T > 3 ? T / 3 : 1)) {
            REQUIRE(tvpal_player_frame(p, &v, t, 1, rgl, a, &st, &d) == 0, "%s", d.msg);
            REQUIRE(tvpal_player_frame(p, &v, t, 1, rref, b, &st, &d) == 0, "%s", d.msg);
            size_t over = 0;
            double mx = 0, energy = 0;
            for (size_t i = 0; i < (size_t)W * H * 4; i++) {
                double e = fabs(a[i] - b[i]);
                over += e > 2e-3;
                mx = e > mx ? e : mx;
                energy += b[i];
            }
            CHECK(energy > 1, "view %zu t %u: empty frame", vi, t);
            CHECK(over <= W * H / 50, "view %zu axis %c t %u: %zu values "
                  "differ > 2e-3 (max %g)", vi, "xyz"[v.axis], t, over, mx);
        }
    }
    CHECK(axes == 7, "views cover the three axes (%u)", axes);
}

int main(int argc, char **argv)
{
    const int cache_only = argc == 3 && !strcmp(argv[1], "--cache");
    REQUIRE(argc == 2 || cache_only, "usage: tvpal-playcheck [--cache] DIR");
    const char *dir = argv[argc - 1];
    struct tvpal_osmesa *ctx;
    struct tvpal_diag d = {{0}};
    REQUIRE(tvpal_osmesa_create(&ctx, &d) == 0, "%s", d.msg);
    REQUIRE(tvpal_glr_create(&glr, W, H, &d) == 0, "%s", d.msg);
    struct tvpal_ref *ref;
    REQUIRE(tvpal_ref_create(&ref, (size_t)W * H) == 0, "out of memory");
    static float a[W * H * 4], b[W * H * 4];
    struct tvpal_renderer rgl, rref;
    tvpal_glr_renderer(glr, &rgl);
    tvpal_ref_renderer(ref, &rref);
    struct tvpal_player *p = open_player(dir, 0, TVPAL_IO_URING, 1);
    const struct tvpal_manifest *m = tvpal_player_manifest(p);
    const uint32_t T = m->steps, N = m->window;
    struct tvpal_frame_stats st;

    /* GL vs reference, three axes. */
    if (!cache_only)
        check_gl_ref(p, m, &rgl, &rref);

    /* Jumps and backward playback equal forward playback. */
    struct tvpal_view v = view(m, 25, 35);
    static float seq[64][W * H * 4];
    uint32_t Tm = T < 64 ? T : 64;
    struct tvpal_player *q = open_player(dir, 0, TVPAL_IO_URING, 1);
    for (uint32_t t = 0; t < Tm; t++) {
        REQUIRE(tvpal_player_frame(q, &v, t, 1, &rgl, seq[t], &st, &d) == 0, "%s", d.msg);
        if (t > 0 && !cache_only) {
            /* Only slices whose window starts at t change. */
            uint32_t n = v.axis == 0 ? m->dims[0] : v.axis == 1 ? m->dims[1] : m->dims[2];
            uint32_t starting = 0;
            const struct tvpal_schedule sc = tvpal_schedule_of(
                N, m->steps, m->schedule, axis_group(dir, v.axis));
            for (uint32_t s = 0; s < n; s++)
                starting += tvpal_schedule_starts(&sc, s, t);
            CHECK(st.uploads <= starting, "step %u: %u uploads, %u windows "
                  "start", t, st.uploads, starting);
        }
    }
    tvpal_player_close(q);
    if (cache_only) {
        /* A series longer than a small read-ahead's buffers, so that
         * some are reused each round. */
        REQUIRE(Tm >= 6 * N + 40, "--cache: %u steps, too few for N = %u",
                Tm, N);
        check_cache(dir, &v, &rgl, seq, Tm, 0, N);
        check_cache(dir, &v, &rgl, seq, Tm, N + 1, N);
        tvpal_player_close(p);
        tvpal_glr_free(glr);
        tvpal_osmesa_free(ctx);
        tvpal_ref_free(ref);
        return tt_done("tvpal-playcheck --cache");
    }
    for (int i = 0; i < 12; i++) {
        uint32_t t = (uint32_t)(tt_rand64() % Tm);
        struct tvpal_player *j = open_player(dir, 0, i % 2 ? TVPAL_IO_PREAD
                                                           : TVPAL_IO_URING, 1);
        REQUIRE(tvpal_player_frame(j, &v, t, 1, &rgl, a, &st, &d) == 0, "%s", d.msg);
        CHECK(!memcmp(a, seq[t], sizeof a), "jump to %u differs from playing "
              "to it", t);
        tvpal_player_close(j);
    }
    /* A jump prepared off the frame's thread (tvpal_player_prepare): the
     * slabs keep the step they show until the frame at the target, which
     * installs the staged records (ready said it would read nothing; its
     * bytes_read are the stager's), and draws what playing to it draws; a
     * second prepare while one runs replaces it. */
    for (int i = 0; i < 8 && Tm > 2; i++) {
        const uint32_t from = (uint32_t)(tt_rand64() % Tm);
        const uint32_t t = (from + 2 + (uint32_t)(tt_rand64() % (Tm - 2))) % Tm;
        const uint32_t other = (t + 1) % Tm;
        struct tvpal_player *j = open_player(dir, 0, i % 2 ? TVPAL_IO_PREAD
                                                           : TVPAL_IO_URING, 1);
        REQUIRE(tvpal_player_frame(j, &v, from, 1, &rgl, a, &st, &d) == 0, "%s", d.msg);
        CHECK(tvpal_player_prepare(j, &v, i % 3 ? t : other, 1, i % 2, &d) == 0 &&
                  tvpal_player_prepare(j, &v, t, 1, i % 2, &d) == 0, "prepare %u: %s",
              t, d.msg);
        /* The timed wait: a job for t is waited for (up to 5 s here);
         * a step no job makes is refused at once, however long the
         * caller would wait. */
        const int ready = tvpal_player_ready(j, &v, t, 5000);
        const double w0 = tvpal_now();
        (void)tvpal_player_ready(j, &v, other, 2000);
        const double waited = tvpal_now() - w0;
        /* The step after t may be ready too (a seek there reads
         * nothing where t's prefetch, or from's, read its records), but
         * is answered at once either way. */
        CHECK(ready && waited < 1.0, "prepared step %u not ready within 5 s "
              "(or %u refused after %.3f s)", t, other, waited);
        REQUIRE(tvpal_player_frame(j, &v, t, 1, &rgl, a, &st, &d) == 0, "%s", d.msg);
        CHECK(st.staged > 0 && !memcmp(a, seq[t], sizeof a),
              "prepared jump %u -> %u: %u records installed as staged, "
              "image %s", from, t, st.staged,
              memcmp(a, seq[t], sizeof a) ? "differs" : "the same");
        REQUIRE(tvpal_player_frame(j, &v, (t + 1) % Tm, 1, &rgl, a, &st, &d) == 0,
                "%s", d.msg);
        CHECK(!memcmp(a, seq[(t + 1) % Tm], sizeof a), "the step after a "
              "prepared jump to %u differs", t);
        tvpal_player_close(j);
    }
    /* A read-ahead (keep_ahead, TVPAL_STREAM_KEEP_AHEAD): once the
     * stager has kept the steps after t (tvpal_player_keep, waited for
     * with tvpal_player_busy), playing on from t reads nothing, and draws
     * what playing from 0 draws (but for t + 1, staged by t's frame
     * before the keep); a keep of the step asked for already is not set
     * to run again. */
    for (int pass = 0; pass < 2 && Tm > 3; pass++) {
        struct tvpal_player_opts o = {.io = pass ? TVPAL_IO_PREAD : TVPAL_IO_URING,
                                      .prefetch = 1, .direct = 1,
                                      .keep_ahead = (uint64_t)1 << 30};
        struct tvpal_player *k;
        REQUIRE(tvpal_player_open(&k, dir, &o, &d) == 0, "%s", d.msg);
        const uint32_t t0 = (uint32_t)(tt_rand64() % (Tm - 3));
        REQUIRE(tvpal_player_frame(k, &v, t0, 1, &rgl, a, &st, &d) == 0, "%s", d.msg);
        const unsigned ahead = tvpal_player_kept(k, &v, t0, NULL);
        const int kr = tvpal_player_keep(k, &v, t0, 1, &d);
        const double k0 = tvpal_now();
        while (tvpal_player_busy(k, &v) && tvpal_now() - k0 < 10)
            nanosleep(&(struct timespec){0, 2000000}, NULL);
        CHECK(ahead >= Tm - 1 - t0 && kr == 1 && !tvpal_player_busy(k, &v) &&
                  tvpal_player_keep(k, &v, t0, 1, &d) == 0,
              "keep ahead of %u: %u steps, set %d, busy %d", t0, ahead, kr,
              tvpal_player_busy(k, &v));
        uint64_t read = 0;
        for (uint32_t t = t0 + 1; t < Tm; t++) {
            REQUIRE(tvpal_player_frame(k, &v, t, 1, &rgl, a, &st, &d) == 0, "%s", d.msg);
            /* (t0 + 1 was staged, its prefetch read, before the keep) */
            read += t > t0 + 1 ? st.bytes_read : 0;
            CHECK(!memcmp(a, seq[t], sizeof a), "read ahead: step %u differs", t);
        }
        CHECK(read == 0, "%s: steps %u..%u after the read-ahead read %llu bytes",
              pass ? "pread" : "uring", t0 + 2, Tm - 1, (unsigned long long)read);
        tvpal_player_close(k);
    }
    if (Tm > 4) {
        check_loop(dir, &v, &rgl, seq, Tm, 0);
        if (Tm > N + 5)
            check_loop(dir, &v, &rgl, seq, Tm, N + 1);
    }
    check_meter(p, &v, m);
    for (uint32_t t = Tm; t-- > 0;) {
        REQUIRE(tvpal_player_frame(p, &v, t, -1, &rgl, a, &st, &d) == 0, "%s", d.msg);
        CHECK(!memcmp(a, seq[t], sizeof a), "backward step %u differs", t);
    }
    /* In-core, pread and page-cache streaming give the same images. */
    struct tvpal_player *ic = open_player(dir, 1, TVPAL_IO_URING, 1);
    struct tvpal_player *pr = open_player(dir, 0, TVPAL_IO_PREAD, 0);
    for (uint32_t t = 0; t < Tm; t++) {
        REQUIRE(tvpal_player_frame(ic, &v, t, 1, &rgl, a, &st, &d) == 0, "%s", d.msg);
        CHECK(!memcmp(a, seq[t], sizeof a), "in-core step %u differs", t);
        REQUIRE(tvpal_player_frame(pr, &v, t, 1, &rgl, a, &st, &d) == 0, "%s", d.msg);
        CHECK(!memcmp(a, seq[t], sizeof a), "pread step %u differs", t);
    }
    /* A TF change uploads no slice texture (both TFs keep every slice
     * visible, so no slice becomes visible for the first time). */
    uint32_t t = Tm / 2;
    struct tvpal_tf tf;
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 0 0 1 0.02\n1 1 0 0 0.4\n",
                                m->value_min, m->value_max, &tf, &d) == 0, "%s", d.msg);
    tvpal_player_set_tf(ic, &tf, 1.0);
    REQUIRE(tvpal_player_frame(ic, &v, t, 1, &rgl, a, &st, &d) == 0, "%s", d.msg);
    CHECK(st.skipped == 0, "all slices visible");
    REQUIRE(tvpal_tf_parse_text("domain normalized\n0 0 1 0 0.05\n1 1 1 1 0.2\n",
                                m->value_min, m->value_max, &tf, &d) == 0, "%s", d.msg);
    tvpal_player_set_tf(ic, &tf, 1.0);
    uint64_t before = tvpal_glr_uploads(glr);
    REQUIRE(tvpal_player_frame(ic, &v, t, 1, &rgl, b, &st, &d) == 0, "%s", d.msg);
    CHECK(tvpal_glr_uploads(glr) == before && st.uploads == 0,
          "TF change uploaded %u slices", st.uploads);
    CHECK(memcmp(a, b, sizeof a) != 0, "TF change changed the image");
    tvpal_player_close(ic);
    tvpal_player_close(pr);
    tvpal_player_close(p);
    tvpal_glr_free(glr);
    tvpal_osmesa_free(ctx);
    tvpal_ref_free(ref);
    return tt_done("tvpal-playcheck");
}
