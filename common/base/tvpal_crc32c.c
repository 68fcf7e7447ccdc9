/* tvpal_crc32c.c: CRC-32C three ways, the fastest the CPU has chosen once:
 * folding with VPCLMULQDQ (AVX-512: 256 bytes a step, memory speed), the
 * SSE4.2 CRC instruction in three interleaved chains (8 bytes a cycle),
 * and a table-driven slicing by 8 (portable C, ~1 byte per cycle).
 * Tables and constants are built once, on first use, under pthread_once. */
#include "tvpal_crc32c.h"

#include <pthread.h>
#include <string.h>
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

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

/* ------------------------------------------------ VPCLMULQDQ folding */

/* Carry-less multiplication folds the input 16 bytes at a time: a lane X
 * (its first 8 bytes X0, the higher powers, and its next 8 X1) moved D
 * bytes further is X0 x^(8D + 64) + X1 x^(8D) modulo the polynomial, and
 * two multiplications by 32-bit constants give a 96-bit value with that
 * remainder, added (xor) into the lane D bytes on.  Reflected, a product
 * comes out one bit low, so the constant for a shift by n bits is
 * x^(n - 33) (fold_constants; checked against the published CRC-32C
 * constants for 64 bytes, 0x740eef02 and 0x9e4addf8).  Four 64-byte
 * registers of four lanes each take 256 bytes a step: two VPCLMULQDQ per
 * 64 bytes, so the loop runs at the memory's speed (a 34 MB record from
 * RAM: 2.2 ms with the CRC instruction, 1.2 ms folded).  At the end the
 * lanes fold into one, and the CRC instruction over its 16 bytes from a
 * zero register gives the CRC: the folded value has the input's
 * remainder.  The incoming CRC is added into the input's first 4 bytes,
 * as the register's start value is. */
#define FOLD_MIN 256 /* shorter inputs go to the CRC instruction */

struct fold_k {
    uint64_t k[2]; /* the constants for X0 and X1, by D bytes */
};
static struct fold_k fold_256, fold_64, fold_48, fold_32, fold_16;

static struct fold_k fold_constants(uint64_t bytes)
{
    return (struct fold_k){{x2nmodp(8 * bytes + 31, 0),
                            x2nmodp(8 * bytes - 33, 0)}};
}

/* Once, from hw_init. */
static void fold_init(void)
{
    pthread_once(&x2n_once, x2n_init);
    fold_256 = fold_constants(256);
    fold_64 = fold_constants(64);
    fold_48 = fold_constants(48);
    fold_32 = fold_constants(32);
    fold_16 = fold_constants(16);
}

#define FOLD_TARGET \
    __attribute__((target("avx512f,avx512vl,vpclmulqdq,pclmul,sse4.2")))

FOLD_TARGET static inline __m128i fold_k128(const struct fold_k *k)
{
    return _mm_set_epi64x((long long)k->k[1], (long long)k->k[0]);
}

/* x moved over its distance, plus d. */
FOLD_TARGET static inline __m512i fold512(__m512i x, __m512i k, __m512i d)
{
    return _mm512_ternarylogic_epi64(_mm512_clmulepi64_epi128(x, k, 0x00),
                                     _mm512_clmulepi64_epi128(x, k, 0x11), d,
                                     0x96); /* a ^ b ^ c */
}

FOLD_TARGET static inline __m128i fold128(__m128i x, __m128i k, __m128i d)
{
    return _mm_xor_si128(_mm_xor_si128(_mm_clmulepi64_si128(x, k, 0x00),
                                       _mm_clmulepi64_si128(x, k, 0x11)),
                         d);
}

/* The CRC of p[0..len), len >= FOLD_MIN. */
FOLD_TARGET static uint32_t crc_fold(uint32_t crc, const unsigned char *p,
                                     size_t len)
{
    __m512i k = _mm512_broadcast_i32x4(fold_k128(&fold_256));
    __m512i x0 = _mm512_loadu_si512(p), x1 = _mm512_loadu_si512(p + 64),
            x2 = _mm512_loadu_si512(p + 128), x3 = _mm512_loadu_si512(p + 192);
    x0 = _mm512_xor_si512(x0, _mm512_zextsi128_si512(
                                  _mm_cvtsi32_si128((int)~crc)));
    p += 256;
    len -= 256;
    for (; len >= 256; p += 256, len -= 256) {
        x0 = fold512(x0, k, _mm512_loadu_si512(p));
        x1 = fold512(x1, k, _mm512_loadu_si512(p + 64));
        x2 = fold512(x2, k, _mm512_loadu_si512(p + 128));
        x3 = fold512(x3, k, _mm512_loadu_si512(p + 192));
    }
    k = _mm512_broadcast_i32x4(fold_k128(&fold_64));
    x1 = fold512(x0, k, x1);
    x2 = fold512(x1, k, x2);
    x3 = fold512(x2, k, x3);
    /* x3's four lanes, 48, 32 and 16 bytes before its end, into the last */
    __m128i a = _mm512_extracti32x4_epi32(x3, 3);
    a = fold128(_mm512_extracti32x4_epi32(x3, 0), fold_k128(&fold_48), a);
    a = fold128(_mm512_extracti32x4_epi32(x3, 1), fold_k128(&fold_32), a);
    a = fold128(_mm512_extracti32x4_epi32(x3, 2), fold_k128(&fold_16), a);
    const __m128i k16 = fold_k128(&fold_16);
    for (; len >= 16; p += 16, len -= 16)
        a = fold128(a, k16, _mm_loadu_si128((const __m128i *)p));
    uint64_t c = _mm_crc32_u64(0, (uint64_t)_mm_cvtsi128_si64(a));
    c = _mm_crc32_u64(c, (uint64_t)_mm_extract_epi64(a, 1));
    while (len--)
        c = _mm_crc32_u8((uint32_t)c, *p++);
    return ~(uint32_t)c;
}

static enum tvpal_crc32c_impl best = TVPAL_CRC32C_TABLE;
static void hw_init(void)
{
    __builtin_cpu_init();
    if (__builtin_cpu_supports("sse4.2"))
        best = TVPAL_CRC32C_SSE42;
    if (best == TVPAL_CRC32C_SSE42 && __builtin_cpu_supports("avx512f") &&
        __builtin_cpu_supports("avx512vl") &&
        __builtin_cpu_supports("vpclmulqdq") &&
        __builtin_cpu_supports("pclmul")) {
        fold_init();
        best = TVPAL_CRC32C_VPCLMUL;
    }
}
static pthread_once_t hw_once = PTHREAD_ONCE_INIT;
#define HAVE_HW_CRC 1
#endif

enum tvpal_crc32c_impl tvpal_crc32c_impl(void)
{
#ifdef HAVE_HW_CRC
    pthread_once(&hw_once, hw_init);
    return best;
#else
    return TVPAL_CRC32C_TABLE;
#endif
}

const char *tvpal_crc32c_impl_name(enum tvpal_crc32c_impl impl)
{
    switch (impl) {
    case TVPAL_CRC32C_VPCLMUL: return "vpclmulqdq";
    case TVPAL_CRC32C_SSE42: return "sse4.2";
    default: return "table";
    }
}

uint32_t tvpal_crc32c_with(enum tvpal_crc32c_impl impl, uint32_t crc,
                           const void *data, size_t len)
{
    const enum tvpal_crc32c_impl have = tvpal_crc32c_impl();
    if (impl > have)
        impl = have;
#ifdef HAVE_HW_CRC
    if (impl == TVPAL_CRC32C_VPCLMUL && len >= FOLD_MIN)
        return crc_fold(crc, data, len);
    if (impl >= TVPAL_CRC32C_SSE42)
        return crc_hw(crc, data, len);
#endif
    return tvpal_crc32c_sw(crc, data, len);
}

uint32_t tvpal_crc32c(uint32_t crc, const void *data, size_t len)
{
    return tvpal_crc32c_with(TVPAL_CRC32C_VPCLMUL, crc, data, len);
}

uint32_t tvpal_crc32c_copy(uint32_t crc, void *dst, const void *src,
                           size_t len)
{
#ifdef HAVE_HW_CRC
    if (tvpal_crc32c_impl() >= TVPAL_CRC32C_SSE42)
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
