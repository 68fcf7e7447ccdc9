/* tvpal_test.h: minimal test harness for the C unit tests.
 * Exit status follows automake: 0 pass, 77 skip, 99 hard error, else fail.
 * CHECK records a failure and continues, so one run shows every problem. */
#ifndef TVPAL_TEST_H
#define TVPAL_TEST_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int tt_failures;
static unsigned long tt_checks;

#define CHECK(cond, ...)                                                      \
    do {                                                                      \
        tt_checks++;                                                          \
        if (!(cond)) {                                                        \
            tt_failures++;                                                    \
            fprintf(stderr, "%s:%d: CHECK(%s) failed: ", __FILE__, __LINE__,  \
                    #cond);                                                   \
            fprintf(stderr, __VA_ARGS__);                                     \
            fputc('\n', stderr);                                              \
        }                                                                     \
    } while (0)

#define REQUIRE(cond, ...)                                                    \
    do {                                                                      \
        if (!(cond)) {                                                        \
            fprintf(stderr, "%s:%d: REQUIRE(%s) failed: ", __FILE__,          \
                    __LINE__, #cond);                                         \
            fprintf(stderr, __VA_ARGS__);                                     \
            fputc('\n', stderr);                                              \
            exit(99);                                                         \
        }                                                                     \
    } while (0)

static inline int tt_done(const char *name)
{
    printf("%s: %lu checks, %d failed\n", name, tt_checks, tt_failures);
    return tt_failures ? 1 : 0;
}

/* Deterministic PRNG (xorshift64*) so every run tests the same inputs. */
static uint64_t tt_rng_state = 0x9E3779B97F4A7C15ull;
static inline uint64_t tt_rand64(void)
{
    uint64_t x = tt_rng_state;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    tt_rng_state = x;
    return x * 0x2545F4914F6CDD1Dull;
}
static inline double tt_uniform(void) /* [0, 1) */
{
    return (double)(tt_rand64() >> 11) * (1.0 / 9007199254740992.0);
}
static inline double tt_gauss(void)
{
    double u = tt_uniform(), v = tt_uniform();
    return sqrt(-2.0 * log(1.0 - u)) * cos(2.0 * M_PI * v);
}

/* n little-endian float32 values from path into v; 0 or -1. */
static inline int tt_load_f32(const char *path, float *v, size_t n)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return -1;
    unsigned char *b = malloc(n * 4);
    size_t got = b ? fread(b, 4, n, fp) : 0;
    int extra = fgetc(fp) != EOF;
    fclose(fp);
    for (size_t i = 0; i < got; i++) {
        uint32_t u = (uint32_t)b[4 * i] | (uint32_t)b[4 * i + 1] << 8 |
                     (uint32_t)b[4 * i + 2] << 16 | (uint32_t)b[4 * i + 3] << 24;
        memcpy(&v[i], &u, 4);
    }
    free(b);
    return got == n && !extra ? 0 : -1;
}

/* Bit for bit, except that any NaN equals any NaN. */
static inline size_t tt_count_diff(const float *a, const float *b, size_t n,
                         size_t *first)
{
    size_t bad = 0;
    for (size_t i = 0; i < n; i++)
        if (!(isnan(a[i]) && isnan(b[i])) && memcmp(&a[i], &b[i], 4)) {
            if (!bad)
                *first = i;
            bad++;
        }
    return bad;
}

#endif
