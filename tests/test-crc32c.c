/* test-crc32c: CRC-32C check value, incremental use, alignment and
 * combining; the CRC summed while copying (tvpal_crc32c_copy); every
 * implementation the CPU has against the table version, and the fastest
 * one really chosen where /proc/cpuinfo lists its features. */
#include "tvpal_crc32c.h"
#include "tvpal_test.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Does /proc/cpuinfo's first "flags" line list every one of names
 * (space-separated)?  -1: no /proc/cpuinfo (not Linux, or hidden). */
static int cpu_has(const char *names)
{
    FILE *f = fopen("/proc/cpuinfo", "r");
    if (!f)
        return -1;
    static char line[8192];
    int found = 0;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, "flags", 5)) {
            found = 1;
            break;
        }
    fclose(f);
    if (!found)
        return -1;
    char want[256];
    snprintf(want, sizeof want, "%s", names);
    for (char *w = strtok(want, " "); w; w = strtok(NULL, " ")) {
        char pat[64];
        snprintf(pat, sizeof pat, " %s", w);
        const char *at = line;
        int ok = 0;
        while ((at = strstr(at, pat))) {
            at += strlen(pat);
            if (*at == ' ' || *at == '\n' || *at == 0) {
                ok = 1;
                break;
            }
        }
        if (!ok)
            return 0;
    }
    return 1;
}

/* Each implementation up to the CPU's best against the table version:
 * lengths around the folding's 256-byte block and 16-byte lanes, every
 * start alignment within a cache line, start values other than 0, and a
 * CRC resumed mid-input from another implementation. */
static void test_impls(void)
{
    const enum tvpal_crc32c_impl best = tvpal_crc32c_impl();
    const int vp = cpu_has("avx512f avx512vl vpclmulqdq pclmulqdq sse4_2");
    const int sse = cpu_has("sse4_2");
    printf("crc32c: %s (cpuinfo: vpclmulqdq set %d, sse4.2 %d)\n",
           tvpal_crc32c_impl_name(best), vp, sse);
#if defined(__x86_64__)
    if (vp == 1)
        CHECK(best == TVPAL_CRC32C_VPCLMUL, "the CPU folds with VPCLMULQDQ, "
              "tvpal_crc32c uses %s", tvpal_crc32c_impl_name(best));
    else if (sse == 1)
        CHECK(best == TVPAL_CRC32C_SSE42, "the CPU has SSE4.2, tvpal_crc32c "
              "uses %s", tvpal_crc32c_impl_name(best));
#endif
    const size_t n = 70000;
    unsigned char *b = malloc(n + 64);
    REQUIRE(b != NULL, "malloc");
    for (size_t i = 0; i < n + 64; i++)
        b[i] = (unsigned char)tt_rand64();
    const size_t lens[] = {0, 1, 15, 16, 17, 255, 256, 257, 271, 272, 287,
                           511, 512, 513, 767, 1024, 4096 + 15, 65536 + 255,
                           n};
    for (int impl = TVPAL_CRC32C_TABLE; impl <= (int)best; impl++) {
        const char *name = tvpal_crc32c_impl_name(impl);
        for (size_t li = 0; li < sizeof lens / sizeof *lens; li++)
            for (size_t off = 0; off < 64; off += 1 + off / 4) {
                uint32_t init = (uint32_t)tt_rand64();
                uint32_t ref = tvpal_crc32c_sw(init, b + off, lens[li]);
                CHECK(tvpal_crc32c_with(impl, init, b + off, lens[li]) == ref,
                      "%s: length %zu offset %zu", name, lens[li], off);
            }
        for (int r = 0; r < 300; r++) {
            size_t len = (size_t)(tt_rand64() % 3000), off = tt_rand64() % 64;
            size_t cut = len ? (size_t)(tt_rand64() % len) : 0;
            uint32_t whole = tvpal_crc32c_sw(0, b + off, len);
            uint32_t c = tvpal_crc32c_with(impl, 0, b + off, cut);
            c = tvpal_crc32c_with(TVPAL_CRC32C_TABLE + (r % 3), c, b + off + cut,
                                  len - cut);
            CHECK(c == whole, "%s: length %zu offset %zu resumed at %zu", name,
                  len, off, cut);
        }
        memset(b, 0, n);
        CHECK(tvpal_crc32c_with(impl, 0, b, n) == tvpal_crc32c_sw(0, b, n),
              "%s: zeros", name);
        memset(b, 0xFF, n);
        CHECK(tvpal_crc32c_with(impl, ~0u, b, n) == tvpal_crc32c_sw(~0u, b, n),
              "%s: ones", name);
        for (size_t i = 0; i < n + 64; i++)
            b[i] = (unsigned char)tt_rand64();
    }
    free(b);
}

int main(void)
{
    const char *s = "123456789";
    CHECK(tvpal_crc32c(0, s, 9) == 0xE3069283u, "check value %08x",
          tvpal_crc32c(0, s, 9));
    CHECK(tvpal_crc32c(0, "", 0) == 0, "empty");
    /* RFC 3720 B.4: 32 bytes of zeros -> 0x8A9136AA, of 0xFF -> 0x62A8AB43 */
    unsigned char z[32] = {0}, f[32];
    memset(f, 0xFF, sizeof f);
    CHECK(tvpal_crc32c(0, z, 32) == 0x8A9136AAu, "zeros %08x",
          tvpal_crc32c(0, z, 32));
    CHECK(tvpal_crc32c(0, f, 32) == 0x62A8AB43u, "ones %08x",
          tvpal_crc32c(0, f, 32));
    unsigned char buf[1000 + 8];
    for (size_t i = 0; i < sizeof buf; i++)
        buf[i] = (unsigned char)tt_rand64();
    /* Every split point and start alignment gives the one-shot value. */
    for (size_t off = 0; off < 8; off++) {
        uint32_t whole = tvpal_crc32c(0, buf + off, 1000);
        for (size_t cut = 0; cut <= 1000; cut += 37) {
            uint32_t c = tvpal_crc32c(0, buf + off, cut);
            c = tvpal_crc32c(c, buf + off + cut, 1000 - cut);
            CHECK(c == whole, "off %zu cut %zu", off, cut);
        }
        /* Compare against a bitwise reference. */
        uint32_t ref = ~0u;
        for (size_t i = 0; i < 1000; i++) {
            ref ^= buf[off + i];
            for (int k = 0; k < 8; k++)
                ref = (ref >> 1) ^ (0x82F63B78u & (0u - (ref & 1u)));
        }
        CHECK(~ref == whole, "bitwise reference at offset %zu", off);
        CHECK(tvpal_crc32c_sw(0, buf + off, 1000) == whole,
              "table version = dispatched version at offset %zu", off);
    }
    /* Combining: CRC(A || B) from CRC(A), CRC(B) and |B|, at every split,
     * empty parts included. */
    for (size_t cut = 0; cut <= 1000; cut += 1 + cut / 3) {
        uint32_t a = tvpal_crc32c(0, buf, cut);
        uint32_t b = tvpal_crc32c(0, buf + cut, 1000 - cut);
        CHECK(tvpal_crc32c_combine(a, b, 1000 - cut) ==
                  tvpal_crc32c(0, buf, 1000), "combine at cut %zu", cut);
    }
    /* Three parts joined left to right, as records are from chunks. */
    uint32_t j = 0;
    for (size_t at = 0; at < 1000; at += 333) {
        size_t n = at + 333 > 1000 ? 1000 - at : 333;
        j = tvpal_crc32c_combine(j, tvpal_crc32c(0, buf + at, n), n);
    }
    CHECK(j == tvpal_crc32c(0, buf, 1000), "three parts joined");
    /* Long inputs through the dispatched version (folding where the CPU
     * has VPCLMULQDQ; test_impls checks each implementation) and the copy,
     * which goes through the SSE4.2 version's three interleaved stripes of
     * 8 KiB (block 24576 bytes): lengths around one and several blocks,
     * odd starts and an incremental call that starts mid-block against the
     * table version (without SSE4.2 all are the table version, and these
     * checks compare it with itself). */
    const size_t big = 5 * 24576 + 100;
    unsigned char *lb = malloc(big + 8);
    REQUIRE(lb != NULL, "malloc");
    for (size_t i = 0; i < big + 8; i++)
        lb[i] = (unsigned char)tt_rand64();
    const size_t lens[] = {24575, 24576, 24577, 24576 + 7, 2 * 24576,
                           3 * 24576 - 1, big};
    for (size_t li = 0; li < sizeof lens / sizeof *lens; li++)
        for (size_t off = 0; off < 8; off += 3) {
            uint32_t hw = tvpal_crc32c(0, lb + off, lens[li]);
            CHECK(hw == tvpal_crc32c_sw(0, lb + off, lens[li]),
                  "striped length %zu offset %zu", lens[li], off);
            uint32_t part = tvpal_crc32c(0, lb + off, 5000);
            CHECK(tvpal_crc32c(part, lb + off + 5000, lens[li] - 5000) == hw,
                  "striped length %zu offset %zu, resumed at 5000",
                  lens[li], off);
            /* Summed while copied: the same CRC, every byte copied, and
             * not one byte written around the destination (guards),
             * from any start and destination alignment, resumed. */
            for (size_t doff = 0; doff < 8; doff += 5) {
                unsigned char *dst = malloc(lens[li] + 16);
                REQUIRE(dst != NULL, "malloc");
                memset(dst, 0xA5, lens[li] + 16);
                uint32_t c = tvpal_crc32c_copy(0, dst + doff, lb + off, 777);
                c = tvpal_crc32c_copy(c, dst + doff + 777, lb + off + 777,
                                      lens[li] - 777);
                CHECK(c == hw, "copy: length %zu offsets %zu/%zu", lens[li],
                      off, doff);
                CHECK(!memcmp(dst + doff, lb + off, lens[li]),
                      "copy: bytes, length %zu offsets %zu/%zu", lens[li],
                      off, doff);
                int guard = 1;
                for (size_t g = 0; g < doff; g++)
                    guard &= dst[g] == 0xA5;
                for (size_t g = doff + lens[li]; g < lens[li] + 16; g++)
                    guard &= dst[g] == 0xA5;
                CHECK(guard, "copy: wrote outside, length %zu offsets %zu/%zu",
                      lens[li], off, doff);
                free(dst);
            }
        }
    memset(lb, 0, big);
    CHECK(tvpal_crc32c(0, lb, big) == tvpal_crc32c_sw(0, lb, big),
          "striped zeros");
    free(lb);
    test_impls();
    return tt_done("test-crc32c");
}
