/* tvpal_crc32c.c: table-driven CRC-32C, slicing by 8 (portable C, ~1 byte per
 * cycle).  Tables are built once, on first use, under pthread_once. */
#include "tvpal_crc32c.h"

#include <pthread.h>
#include <string.h>

static uint32_t crc_table[8][256];
static pthread_once_t crc_once = PTHREAD_ONCE_INIT;

static void crc_init(void)
{
    for (uint32_t i = 0; i < 256; i++) {
        uint32_t c = i;
        for (int k = 0; k < 8; k++)
            c = (c >> 1) ^ (0x82F63B78u & (0u - (c & 1u)));
        crc_table[0][i] = c;
    }
    for (uint32_t i = 0; i < 256; i++)
        for (int s = 1; s < 8; s++)
            crc_table[s][i] = (crc_table[s - 1][i] >> 8) ^
                              crc_table[0][crc_table[s - 1][i] & 0xFF];
}

/* ------------------------------------------------------------- combining */

/* CRC arithmetic over GF(2) modulo the reflected polynomial (zlib's
 * crc32_combine, after Mark Adler): a CRC is a polynomial, appending n
 * zero bytes multiplies the register by x^(8n), and the pre- and post-
 * conditioning cancel out between the two parts. */
#define CRC32C_POLY 0x82F63B78u

/* a * b modulo the polynomial (reflected: bit 31 is x^0). */
static uint32_t multmodp(uint32_t a, uint32_t b)
{
    uint32_t m = 1u << 31, p = 0;
    for (;;) {
        if (a & m) {
            p ^= b;
            if ((a & (m - 1)) == 0)
                break;
        }
        m >>= 1;
        b = b & 1 ? (b >> 1) ^ CRC32C_POLY : b >> 1;
    }
    return p;
}

static uint32_t x2n_table[32]; /* x^(2^k) modulo the polynomial */
static pthread_once_t x2n_once = PTHREAD_ONCE_INIT;

static void x2n_init(void)
{
    uint32_t p = 1u << 30; /* x^1 */
    x2n_table[0] = p;
    for (int k = 1; k < 32; k++)
        x2n_table[k] = p = multmodp(p, p);
}

/* x^(n * 2^k) modulo the polynomial. */
static uint32_t x2nmodp(uint64_t n, unsigned k)
{
    uint32_t p = 1u << 31; /* x^0 */
    while (n) {
        if (n & 1)
            p = multmodp(x2n_table[k & 31], p);
        n >>= 1;
        k++;
    }
    return p;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
/* SSE4.2 has a CRC-32C instruction.  It takes 3 cycles and issues every
 * cycle, so one dependent chain runs at a third of its rate: long inputs
 * go in blocks of three stripes of STRIPE bytes, each its own chain, and
 * the three registers are joined by shifting the first two over the
 * stripes after them (shift tables below).  A record is verified on the
 * stager thread, which shares the cores with the renderer: 32 MiB a frame
 * at 512^3, N = 4. */
#define STRIPE 8192

/* shift_tab[s][b][v]: the raw register v << 8 b (a byte of it) moved over
 * (s + 1) STRIPE zero bytes, modulo the polynomial: the shift is linear,
 * so a whole register moves by four lookups. */
static uint32_t shift_tab[2][4][256];
static pthread_once_t shift_once = PTHREAD_ONCE_INIT;

static void shift_init(void)
{
    pthread_once(&x2n_once, x2n_init);
    for (int s = 0; s < 2; s++) {
        const uint32_t xn = x2nmodp((uint64_t)(s + 1) * STRIPE, 3);
        for (int b = 0; b < 4; b++)
            for (uint32_t v = 0; v < 256; v++)
                shift_tab[s][b][v] = multmodp(xn, v << (8 * b));
    }
}

static inline uint32_t shift_over(int s, uint32_t r)
{
    return shift_tab[s][0][r & 255] ^ shift_tab[s][1][(r >> 8) & 255] ^
           shift_tab[s][2][(r >> 16) & 255] ^ shift_tab[s][3][r >> 24];
}

/* The CRC of p[0..len), copying it to dst on the way when dst is not
 * NULL (a constant in each caller below, so the stores disappear from
 * crc_hw): the copy then costs stores only, the bytes being in registers
 * already.  The stripes' stores bypass the caches (movnti): the copy is
 * the player's staged indices, read only from the next frame on, and
 * written with ordinary stores every line would first be read from memory
 * and then push the renderer's lines out (measured on the stager: 1656
 * samples of the fused loop with ordinary stores, 1424 with these, 1708
 * for a CRC pass and a memcpy). */
__attribute__((target("sse4.2"), always_inline)) static inline uint32_t
crc_hw_core(uint32_t crc, const unsigned char *p, size_t len,
            unsigned char *dst)
{
    uint64_t c = ~crc;
    while (len && ((uintptr_t)p & 7)) {
        if (dst)
            *dst++ = *p;
        c = __builtin_ia32_crc32qi((uint32_t)c, *p++);
        len--;
    }
    if (len >= 3 * STRIPE)
        pthread_once(&shift_once, shift_init);
    while (len >= 3 * STRIPE) {
        uint64_t c1 = 0, c2 = 0;
        for (size_t i = 0; i < STRIPE; i += 8) {
            uint64_t v0, v1, v2;
            memcpy(&v0, p + i, 8);
            memcpy(&v1, p + STRIPE + i, 8);
            memcpy(&v2, p + 2 * STRIPE + i, 8);
            if (dst) {
                __builtin_ia32_movnti64((long long *)(dst + i),
                                        (long long)v0);
                __builtin_ia32_movnti64((long long *)(dst + STRIPE + i),
                                        (long long)v1);
                __builtin_ia32_movnti64((long long *)(dst + 2 * STRIPE + i),
                                        (long long)v2);
            }
            c = __builtin_ia32_crc32di(c, v0);
            c1 = __builtin_ia32_crc32di(c1, v1);
            c2 = __builtin_ia32_crc32di(c2, v2);
        }
        c = shift_over(1, (uint32_t)c) ^ shift_over(0, (uint32_t)c1) ^
            (uint32_t)c2;
        p += 3 * STRIPE;
        if (dst) {
            __builtin_ia32_sfence(); /* ordered before any later store */
            dst += 3 * STRIPE;
        }
        len -= 3 * STRIPE;
    }
    while (len >= 8) {
        uint64_t v;
        memcpy(&v, p, 8);
        if (dst) {
            memcpy(dst, &v, 8);
            dst += 8;
        }
        c = __builtin_ia32_crc32di(c, v);
        p += 8;
        len -= 8;
    }
    while (len--) {
        if (dst)
            *dst++ = *p;
        c = __builtin_ia32_crc32qi((uint32_t)c, *p++);
    }
    return ~(uint32_t)c;
}

__attribute__((target("sse4.2"))) static uint32_t crc_hw(uint32_t crc,
                                                         const unsigned char *p,
                                                         size_t len)
{
    return crc_hw_core(crc, p, len, NULL);
}

__attribute__((target("sse4.2"))) static uint32_t
crc_hw_copy(uint32_t crc, unsigned char *dst, const unsigned char *p,
            size_t len)
{
    return crc_hw_core(crc, p, len, dst);
}

static int have_hw;
static void hw_init(void)
{
    __builtin_cpu_init();
    have_hw = __builtin_cpu_supports("sse4.2");
}
static pthread_once_t hw_once = PTHREAD_ONCE_INIT;
#endif

uint32_t tvpal_crc32c_sw(uint32_t crc, const void *data, size_t len);

uint32_t tvpal_crc32c(uint32_t crc, const void *data, size_t len)
{
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    pthread_once(&hw_once, hw_init);
    if (have_hw)
        return crc_hw(crc, data, len);
#endif
    return tvpal_crc32c_sw(crc, data, len);
}

uint32_t tvpal_crc32c_copy(uint32_t crc, void *dst, const void *src,
                           size_t len)
{
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    pthread_once(&hw_once, hw_init);
    if (have_hw)
        return crc_hw_copy(crc, dst, src, len);
#endif
    memcpy(dst, src, len);
    return tvpal_crc32c_sw(crc, dst, len);
}

uint32_t tvpal_crc32c_sw(uint32_t crc, const void *data, size_t len)
{
    const unsigned char *p = data;
    pthread_once(&crc_once, crc_init);
    crc = ~crc;
    while (len && ((uintptr_t)p & 7)) {
        crc = (crc >> 8) ^ crc_table[0][(crc ^ *p++) & 0xFF];
        len--;
    }
    while (len >= 8) {
        uint32_t lo, hi;
        memcpy(&lo, p, 4);
        memcpy(&hi, p + 4, 4);
#ifdef WORDS_BIGENDIAN
        lo = __builtin_bswap32(lo);
        hi = __builtin_bswap32(hi);
#endif
        lo ^= crc;
        crc = crc_table[7][lo & 0xFF] ^ crc_table[6][(lo >> 8) & 0xFF] ^
              crc_table[5][(lo >> 16) & 0xFF] ^ crc_table[4][lo >> 24] ^
              crc_table[3][hi & 0xFF] ^ crc_table[2][(hi >> 8) & 0xFF] ^
              crc_table[1][(hi >> 16) & 0xFF] ^ crc_table[0][hi >> 24];
        p += 8;
        len -= 8;
    }
    while (len--)
        crc = (crc >> 8) ^ crc_table[0][(crc ^ *p++) & 0xFF];
    return ~crc;
}

uint32_t tvpal_crc32c_combine(uint32_t crc1, uint32_t crc2, uint64_t len2)
{
    pthread_once(&x2n_once, x2n_init);
    return multmodp(x2nmodp(len2, 3), crc1) ^ crc2;
}
