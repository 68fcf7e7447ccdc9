/* tt_box.h: box reads (tvpal_input_read_box) checked against the same box
 * cut from tvpal_input_read, bit for bit (NaN included), for the input
 * tests: the whole grid, every corner voxel, one random voxel, one slice of
 * x, of y and of z (first, last and a random one), an x-row, a z-column
 * and random boxes; and the refused boxes (empty, outside the grid, a step
 * past the end) with the diag that names them. */
#ifndef TT_BOX_H
#define TT_BOX_H

#include "tvpal_input.h"
#include "tvpal_test.h"

static inline uint32_t tt_bits(float v)
{
    uint32_t u;
    memcpy(&u, &v, 4);
    return u;
}

/* One box of step t against full (the step read whole). */
static inline void tt_box_one(struct tvpal_input *in, uint32_t t,
                              const float *full, uint32_t x0, uint32_t y0,
                              uint32_t z0, uint32_t nx, uint32_t ny,
                              uint32_t nz, const char *name)
{
    const uint32_t *dims = tvpal_input_info(in)->dims;
    const uint32_t lo[3] = {x0, y0, z0}, n[3] = {nx, ny, nz};
    const size_t nb = (size_t)nx * ny * nz;
    float *got = malloc((nb + 1) * sizeof *got);
    REQUIRE(got, "memory for a box of %zu", nb);
    const uint32_t guard = 0x7fbadbadu;
    for (size_t i = 0; i <= nb; i++)
        memcpy(&got[i], &guard, 4);
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_read_box(in, t, lo, n, got, &g);
    CHECK(rc == 0, "%s: step %u: box %u %u %u + %u %u %u: %s (%s)", name, t,
          x0, y0, z0, nx, ny, nz, tvpal_strerror(rc), g.msg);
    size_t bad = 0, first = 0;
    for (uint32_t z = 0; rc == 0 && z < nz; z++)
        for (uint32_t y = 0; y < ny; y++)
            for (uint32_t x = 0; x < nx; x++) {
                size_t i = ((size_t)z * ny + y) * nx + x;
                size_t j = ((size_t)(z0 + z) * dims[1] + (y0 + y)) * dims[0] +
                           (x0 + x);
                if (tt_bits(got[i]) != tt_bits(full[j]) && !bad++)
                    first = i;
            }
    CHECK(bad == 0, "%s: step %u: box %u %u %u + %u %u %u: %zu values "
          "differ from the whole read, first at %zu: %.9g, expected %.9g",
          name, t, x0, y0, z0, nx, ny, nz, bad, first, got[first],
          full[((size_t)(z0 + first / nx / ny) * dims[1] +
                (y0 + first / nx % ny)) * dims[0] + x0 + first % nx]);
    CHECK(tt_bits(got[nb]) == guard, "%s: box %u %u %u + %u %u %u: written "
          "past its end", name, x0, y0, z0, nx, ny, nz);
    free(got);
}

static inline uint32_t tt_below(uint32_t n)
{
    return (uint32_t)(tt_rand64() % n);
}

/* The boxes of one step; nrandom random ones. */
static inline void tt_boxes_of_step(struct tvpal_input *in, uint32_t t,
                                    const float *full, int nrandom,
                                    const char *name)
{
    const uint32_t X = tvpal_input_info(in)->dims[0],
                   Y = tvpal_input_info(in)->dims[1],
                   Z = tvpal_input_info(in)->dims[2];
    tt_box_one(in, t, full, 0, 0, 0, X, Y, Z, name);
    for (int c = 0; c < 8; c++)
        tt_box_one(in, t, full, c & 1 ? X - 1 : 0, c & 2 ? Y - 1 : 0,
                   c & 4 ? Z - 1 : 0, 1, 1, 1, name);
    tt_box_one(in, t, full, tt_below(X), tt_below(Y), tt_below(Z), 1, 1, 1,
               name);
    const uint32_t xs[3] = {0, X - 1, tt_below(X)}, ys[3] = {0, Y - 1,
                                                             tt_below(Y)},
                   zs[3] = {0, Z - 1, tt_below(Z)};
    for (int k = 0; k < 3; k++) {
        tt_box_one(in, t, full, xs[k], 0, 0, 1, Y, Z, name);
        tt_box_one(in, t, full, 0, ys[k], 0, X, 1, Z, name);
        tt_box_one(in, t, full, 0, 0, zs[k], X, Y, 1, name);
    }
    tt_box_one(in, t, full, 0, tt_below(Y), tt_below(Z), X, 1, 1, name);
    tt_box_one(in, t, full, tt_below(X), tt_below(Y), 0, 1, 1, Z, name);
    /* a slab of z-slices and a band of y-rows, as the encoder's passes */
    uint32_t z0 = tt_below(Z), y0 = tt_below(Y);
    tt_box_one(in, t, full, 0, 0, z0, X, Y, 1 + tt_below(Z - z0), name);
    tt_box_one(in, t, full, 0, y0, 0, X, 1 + tt_below(Y - y0), Z, name);
    for (int k = 0; k < nrandom; k++) {
        uint32_t a = tt_below(X), b = tt_below(Y), c = tt_below(Z);
        tt_box_one(in, t, full, a, b, c, 1 + tt_below(X - a),
                   1 + tt_below(Y - b), 1 + tt_below(Z - c), name);
    }
}

/* The refused boxes: TVPAL_E_INVAL and a diag naming the variable, the
 * step and the problem. */
static inline void tt_box_errors(struct tvpal_input *in, const char *name)
{
    const struct tvpal_input_info *info = tvpal_input_info(in);
    const uint32_t *d = info->dims;
    float v[4];
    static const struct {
        uint32_t lo[3], n[3];
        int beyond;      /* the step past the end */
        const char *what;
    } bad[] = {
        {{0, 0, 0}, {0, 1, 1}, 0, "empty box"},
        {{0, 0, 0}, {1, 0, 1}, 0, "empty box"},
        {{0, 0, 0}, {1, 1, 0}, 0, "empty box"},
        {{UINT32_MAX, 0, 0}, {1, 1, 1}, 0, "outside"},
        {{0, 0, 0}, {1, 1, UINT32_MAX}, 0, "outside"},
        {{0, 0, 0}, {1, 1, 1}, 1, "step"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        struct tvpal_diag g = {{0}};
        int rc = tvpal_input_read_box(in, bad[i].beyond ? info->steps : 0,
                                      bad[i].lo, bad[i].n, v, &g);
        CHECK(rc == TVPAL_E_INVAL && strstr(g.msg, info->var) &&
              strstr(g.msg, "step") && strstr(g.msg, bad[i].what),
              "%s: bad box %zu: %s (%d), %s", name, i, tvpal_strerror(rc), rc,
              g.msg);
    }
    /* one past the grid on each axis */
    for (int a = 0; a < 3; a++) {
        uint32_t lo[3] = {0, 0, 0}, n[3] = {1, 1, 1};
        lo[a] = d[a] - 1;
        n[a] = 2;
        struct tvpal_diag g = {{0}};
        int rc = tvpal_input_read_box(in, 0, lo, n, v, &g);
        char axis[16];
        snprintf(axis, sizeof axis, "on axis %c", "xyz"[a]);
        CHECK(rc == TVPAL_E_INVAL && strstr(g.msg, axis) &&
              strstr(g.msg, tvpal_input_file(in, 0, NULL)),
              "%s: box one past axis %c: %d %s", name, "xyz"[a], rc, g.msg);
    }
}

/* Every step (at most the first, middle and last of a long series) box by
 * box against the whole read; then the refused boxes. */
static inline void tt_check_boxes_n(struct tvpal_input *in, int nrandom,
                                    const char *name)
{
    const struct tvpal_input_info *info = tvpal_input_info(in);
    const size_t n = (size_t)info->dims[0] * info->dims[1] * info->dims[2];
    float *full = malloc(n * sizeof *full);
    REQUIRE(full, "memory for a step of %zu", n);
    const uint32_t last = info->steps - 1;
    const uint32_t steps[3] = {0, last / 2, last};
    for (int k = 0; k < 3; k++) {
        if (k && steps[k] == steps[k - 1])
            continue;
        struct tvpal_diag g = {{0}};
        int rc = tvpal_input_read(in, steps[k], full, &g);
        CHECK(rc == 0, "%s: read step %u: %s", name, steps[k], g.msg);
        if (rc == 0)
            tt_boxes_of_step(in, steps[k], full, nrandom, name);
    }
    free(full);
    tt_box_errors(in, name);
}

static inline void tt_check_boxes(struct tvpal_input *in, const char *name)
{
    tt_check_boxes_n(in, 24, name);
}

/* Scratch of a box of one z-slice, and of one x-slice, against a step of
 * float (a float per component: the rows of a vector hold them all): at
 * most a step / min_ratio. */
static inline void tt_check_box_scratch(struct tvpal_input *in,
                                        uint64_t min_ratio, const char *name)
{
    const uint32_t *d = tvpal_input_info(in)->dims;
    const uint64_t step = (uint64_t)d[0] * d[1] * d[2] * 4 *
                          tvpal_input_info(in)->components;
    const uint32_t zs[3] = {d[0], d[1], 1}, xs[3] = {1, d[1], d[2]};
    uint64_t sz = tvpal_input_box_scratch(in, zs),
             sx = tvpal_input_box_scratch(in, xs);
    CHECK(sz * min_ratio <= step, "%s: scratch of a z-slice box %llu bytes; a "
          "step is %llu", name, (unsigned long long)sz,
          (unsigned long long)step);
    CHECK(sx <= step, "%s: scratch of an x-slice box %llu bytes; a step is "
          "%llu", name, (unsigned long long)sx, (unsigned long long)step);
    const uint32_t none[3] = {0, 1, 1};
    CHECK(tvpal_input_box_scratch(in, none) == 0, "%s: scratch of an empty "
          "box", name);
    printf("%s: box scratch: z-slice %llu bytes, x-slice %llu, a step %llu\n",
           name, (unsigned long long)sz, (unsigned long long)sx,
           (unsigned long long)step);
}

#endif
