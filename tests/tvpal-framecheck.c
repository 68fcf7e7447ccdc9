/* tvpal-framecheck DIR TF STEP WxH AX,AY R,G,B OUT.png: writes step STEP
 * of dataset DIR as tvpal-play drew its headless frames before it had
 * annotations: the cpu renderer through the player core (view of size
 * WxH turned AX about x then AY about y, zoom 1; TF a --tf file, or "-"
 * for the default from the histogram), the one-rank compositor's 8-bit
 * frame, written by tvpal_png_write8 over the background R,G,B.
 * tests/play-annot.sh compares `tvpal-play --annotate none` (and
 * --background) with it byte for byte: the frame path nothing was added
 * to.  Exit 0, or 99 on any error (with a message). */
#include "tvpal_comm.h"
#include "tvpal_composite.h"
#include "tvpal_player.h"
#include "tvpal_png.h"
#include "tvpal_sw.h"
#include "tvpal_test.h"

int main(int argc, char **argv)
{
    REQUIRE(argc == 8, "usage: tvpal-framecheck DIR TF STEP WxH AX,AY "
            "R,G,B OUT.png");
    unsigned t, W, H;
    double ax, ay;
    float bg[3];
    REQUIRE(sscanf(argv[3], "%u", &t) == 1 &&
            sscanf(argv[4], "%ux%u", &W, &H) == 2 &&
            sscanf(argv[5], "%lf,%lf", &ax, &ay) == 2 &&
            sscanf(argv[6], "%f,%f,%f", &bg[0], &bg[1], &bg[2]) == 3,
            "bad arguments");
    struct tvpal_diag d = {{0}};
    struct tvpal_player_opts po = {.incore = 1, .io = TVPAL_IO_PREAD};
    struct tvpal_player *pl;
    REQUIRE(tvpal_player_open(&pl, argv[1], &po, &d) == 0, "%s", d.msg);
    const struct tvpal_manifest *m = tvpal_player_manifest(pl);
    static struct tvpal_tf tf;
    if (!strcmp(argv[2], "-"))
        tvpal_tf_default(m->value_min, m->value_max, m->histogram,
                         TVPAL_HIST_BINS, &tf);
    else
        REQUIRE(tvpal_tf_load(argv[2], m->value_min, m->value_max, &tf,
                              &d) == 0, "%s", d.msg);
    tvpal_player_set_tf(pl, &tf, 1.0);
    struct tvpal_view v = {.width = W, .height = H, .ax_deg = ax,
                           .ay_deg = ay, .zoom = 1};
    memcpy(v.dims, m->dims, sizeof v.dims);
    tvpal_view_setup(&v);
    struct tvpal_sw *sw;
    struct tvpal_renderer r;
    REQUIRE(tvpal_sw_create(&sw) == 0, "out of memory");
    tvpal_sw_renderer(sw, &r);
    float *rgba = malloc(sizeof(float) * 4 * W * H);
    uint8_t *final = malloc(4 * (size_t)W * H), *rgb8 = malloc(3 * (size_t)W * H);
    struct tvpal_compositor *cx;
    REQUIRE(rgba && final && rgb8 &&
            tvpal_compositor_create(&cx, W, H, 1) == 0, "out of memory");
    struct tvpal_frame_stats st;
    REQUIRE(tvpal_player_frame(pl, &v, t, 1, &r, rgba, &st, &d) == 0, "%s",
            d.msg);
    struct tvpal_comm comm;
    tvpal_comm_self(&comm);
    struct tvpal_compose_stats cs;
    REQUIRE(tvpal_composite(cx, &comm, TVPAL_COMPOSE_BSWAP,
                            !tvpal_player_slabs_descending(pl, &v), rgba,
                            final, &cs) == 0, "compositing failed");
    REQUIRE(tvpal_png_write8(argv[7], final, W, H, bg, rgb8, &d) == 0, "%s",
            d.msg);
    tvpal_compositor_free(cx);
    tvpal_sw_free(sw);
    tvpal_player_close(pl);
    free(rgba);
    free(final);
    free(rgb8);
    return 0;
}
