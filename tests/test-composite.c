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

/* tvpal_rle_blend of msg[0, bytes) copied into a buffer of exactly bytes
 * (so that ASan sees any read past its end) into rows [y0, y1) of img.
 * Returns its return code; *px gets the pixels blended. */
static int blend_exact(float *img, unsigned y0, unsigned y1,
                       const unsigned char *msg, size_t bytes, uint64_t *px)
{
    unsigned char *copy = malloc(bytes ? bytes : 1);
    REQUIRE(copy, "malloc");
    memcpy(copy, msg, bytes);
    *px = 0;
    int rc = tvpal_rle_blend(img, W, y0, y1, copy, bytes, 1, px);
    free(copy);
    return rc;
}

/* A message of spans (start, length) pairs, with 8 bytes of pixel data per
 * pixel the spans claim plus `extra` bytes (negative: fewer); returns its
 * bytes. */
static size_t forge(unsigned char *buf, const uint32_t *spans, uint32_t ns,
                    long extra)
{
    size_t px = 0;
    memcpy(buf, &ns, 4);
    for (uint32_t k = 0; k < ns; k++) {
        memcpy(buf + 4 + 8 * (size_t)k, spans + 2 * k, 8);
        px += spans[2 * k + 1];
    }
    size_t n = 4 + 8 * (size_t)ns + (size_t)((long)(8 * px) + extra);
    memset(buf + 4 + 8 * (size_t)ns, 0x40, n - 4 - 8 * (size_t)ns);
    return n;
}

/* Malformed messages are refused (TVPAL_E_FORMAT) before anything is read
 * past their end or blended; a well-formed one still blends. */
static void test_malformed(const float *img)
{
    static unsigned char msg[1 << 16];
    static float a[W * H * 4], b[W * H * 4];
    uint64_t px;
    memcpy(a, img, sizeof a);
    memcpy(b, img, sizeof b);
    const uint32_t row = W;                  /* pixels of one row */
    const uint32_t ok2[] = {1, 3, 10, 2};
    size_t n = forge(msg, ok2, 2, 0);
    CHECK(blend_exact(a, 0, 1, msg, n, &px) == 0 && px == 5,
          "well-formed: %llu pixels", (unsigned long long)px);
    memcpy(a, img, sizeof a);
    struct { const char *what; uint32_t spans[4]; uint32_t ns; long extra;
             size_t cut; } bad[] = {
        {"pixel data one pixel short", {1, 3, 10, 2}, 2, -8, 0},
        {"pixel data one byte short", {1, 3, 10, 2}, 2, -1, 0},
        {"trailing bytes", {1, 3, 10, 2}, 2, 8, 0},
        {"run past the rows", {row - 2, 3}, 1, 0, 0},
        {"run of more pixels than the image", {0, W * H + 1}, 1, 0, 0},
        {"start past the rows", {row + 5, 1}, 1, 0, 0},
        {"start near 2^32", {0xFFFFFFF0u, 0x20}, 1, 0, 0},
        {"empty span", {1, 0}, 1, 0, 0},
        {"overlapping spans", {1, 3, 2, 2}, 2, 0, 0},
        {"descending spans", {10, 2, 1, 3}, 2, 0, 0},
        {"span headers cut", {1, 3, 10, 2}, 2, 0, 4 + 8 + 4},
        {"count only, spans missing", {1, 3, 10, 2}, 2, 0, 4},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        n = forge(msg, bad[i].spans, bad[i].ns, bad[i].extra);
        if (bad[i].cut)
            n = bad[i].cut;
        int rc = blend_exact(a, 0, 1, msg, n, &px);
        CHECK(rc == TVPAL_E_FORMAT && px == 0, "%s: rc %d, %llu pixels",
              bad[i].what, rc, (unsigned long long)px);
    }
    /* Shorter than the count, and a count claiming 2^32-1 spans. */
    CHECK(blend_exact(a, 0, 1, msg, 2, &px) == TVPAL_E_FORMAT, "2 bytes");
    CHECK(blend_exact(a, 0, 1, msg, 0, &px) == TVPAL_E_FORMAT, "0 bytes");
    uint32_t huge = 0xFFFFFFFFu;
    memcpy(msg, &huge, 4);
    CHECK(blend_exact(a, 0, 1, msg, 12, &px) == TVPAL_E_FORMAT, "2^32-1 spans");
    CHECK(!memcmp(a, b, sizeof a), "a refused message changed the image");
}

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
    uint64_t px = 0;
    CHECK(tvpal_rle_blend(ref, W, 5, 17, buf, n, 1, &px) == 0, "blend");
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
    CHECK(tvpal_rle_blend(ref, W, 5, 17, buf, n, 0, &px) == 0, "blend behind");
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
    px = 0;
    CHECK(tvpal_rle_blend(ref, W, 0, 1, bad, sizeof bad, 1, &px) ==
          TVPAL_E_FORMAT && px == 0, "overrun");
    test_malformed(back);

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
