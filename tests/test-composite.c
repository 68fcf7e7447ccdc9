/* test-composite: the compositing codec without MPI: run-length encoding of
 * a region (transparent runs skipped, 16-bit values) decodes to the image
 * within 1/65535; blending "over" in front of and behind matches the direct
 * formula; the 8-bit output of a one-rank composite rounds like the PNG
 * writer (SSE2 and scalar paths agree, clamping out-of-range values). */
#include "tvpal_comm.h"
#include "tvpal_composite.h"
#include "tvpal_rle.h"
#include "tvpal_test.h"

#include <string.h>

#define W 37
#define H 23

int main(void)
{
    static float img[W * H * 4], back[W * H * 4], ref[W * H * 4];
    static unsigned char buf[1 << 20];
    for (int i = 0; i < W * H; i++) {
        int clear = (i / 5) % 3 == 0; /* runs of transparent pixels */
        float a = clear ? 0.0f : (float)(0.05 + 0.9 * tt_uniform());
        for (int c = 0; c < 3; c++)
            img[4 * i + c] = clear ? 0.0f : a * (float)tt_uniform();
        img[4 * i + 3] = a;
        float b = (float)(0.1 + 0.8 * tt_uniform());
        for (int c = 0; c < 3; c++)
            back[4 * i + c] = b * (float)tt_uniform();
        back[4 * i + 3] = b;
    }
    /* Rows 5..17 of img, received in front of back. */
    size_t n = tvpal_rle_encode(img, W, 5, 17, buf);
    CHECK(n <= tvpal_rle_bound(W, 12), "bound");
    uint32_t spans;
    memcpy(&spans, buf, 4);
    size_t active = 0;
    for (int i = 5 * W; i < 17 * W; i++)
        active += img[4 * i + 3] != 0.0f;
    CHECK(n == 4 + 8 * (size_t)spans + active * 8, "size: %zu bytes for %zu "
          "active pixels in %u spans", n, active, spans);
    memcpy(ref, back, sizeof ref);
    uint64_t px = tvpal_rle_blend(ref, W, 5, 17, buf, n, 1);
    CHECK(px == active, "blended %llu of %zu", (unsigned long long)px, active);
    double err = 0;
    for (int i = 0; i < W * H; i++)
        for (int c = 0; c < 4; c++) {
            float want = back[4 * i + c];
            if (i >= 5 * W && i < 17 * W)
                want = img[4 * i + c] + (1.0f - img[4 * i + 3]) * back[4 * i + c];
            err = fmax(err, fabs(ref[4 * i + c] - want));
        }
    CHECK(err <= 1.0 / 65535, "front blend error %g", err);
    memcpy(ref, back, sizeof ref);
    tvpal_rle_blend(ref, W, 5, 17, buf, n, 0);
    err = 0;
    for (int i = 5 * W; i < 17 * W; i++)
        for (int c = 0; c < 4; c++) {
            float want = back[4 * i + c] + (1.0f - back[4 * i + 3]) * img[4 * i + c];
            err = fmax(err, fabs(ref[4 * i + c] - want));
        }
    CHECK(err <= 1.0 / 65535, "behind blend error %g", err);
    /* A malformed span count must not write out of bounds. */
    unsigned char bad[16] = {0};
    uint32_t big[3] = {1, (uint32_t)(W * H), 5};
    memcpy(bad, big, 12);
    CHECK(tvpal_rle_blend(ref, W, 0, 1, bad, sizeof bad, 1) == 0, "overrun");

    /* One-rank composite: 8-bit output, PNG-writer rounding. */
    struct tvpal_comm self;
    tvpal_comm_self(&self);
    struct tvpal_compositor *cx;
    REQUIRE(tvpal_compositor_create(&cx, W, H, 1) == 0, "create");
    static const float special[] = {-1.0f, 0.0f, 0.5f / 255, 0.5f / 255 - 1e-6f,
                                    1.0f, 1.5f, 254.5f / 255, 0.999f};
    for (int i = 0; i < W * H * 4; i++)
        img[i] = i < 8 ? special[i] : (float)tt_uniform();
    static uint8_t out8[W * H * 4];
    struct tvpal_compose_stats st;
    REQUIRE(tvpal_composite(cx, &self, TVPAL_COMPOSE_BSWAP, 0, img, out8, &st) == 0,
            "composite");
    int bad8 = 0;
    for (int i = 0; i < W * H * 4; i++) {
        float v = img[i] < 0 ? 0 : img[i] > 1 ? 1 : img[i];
        bad8 += out8[i] != (uint8_t)(v * 255.0f + 0.5f);
    }
    CHECK(bad8 == 0, "%d values rounded differently", bad8);
    tvpal_compositor_free(cx);
    return tt_done("test-composite");
}
