/* tvpal_utf8.c: see tvpal_utf8.h. */
#include "tvpal_utf8.h"

#include <string.h>

/* The length of the valid sequence at p (1..4), or 0 when p[0] does not
 * begin one.  The ranges of RFC 3629, section 4. */
static size_t seq_len(const unsigned char *p)
{
    const unsigned c = p[0];
    if (c < 0x80)
        return 1;
    unsigned lo = 0x80, hi = 0xBF;
    size_t n;
    if (c >= 0xC2 && c <= 0xDF)
        n = 2;
    else if (c >= 0xE0 && c <= 0xEF) {
        n = 3;
        if (c == 0xE0)
            lo = 0xA0;          /* no overlong forms */
        else if (c == 0xED)
            hi = 0x9F;          /* no surrogates */
    } else if (c >= 0xF0 && c <= 0xF4) {
        n = 4;
        if (c == 0xF0)
            lo = 0x90;
        else if (c == 0xF4)
            hi = 0x8F;          /* nothing above U+10FFFF */
    } else {
        return 0;
    }
    if (p[1] < lo || p[1] > hi)
        return 0;
    for (size_t i = 2; i < n; i++)
        if (p[i] < 0x80 || p[i] > 0xBF)
            return 0;
    return n;
}

size_t tvpal_utf8_valid_prefix(const char *s)
{
    const unsigned char *p = (const unsigned char *)s;
    size_t i = 0, k;
    while (p[i] && (k = seq_len(p + i)) > 0)
        i += k;
    return i;
}

size_t tvpal_utf8_repair(char *dst, size_t cap, const char *s)
{
    static const char fffd[] = "\xEF\xBF\xBD";
    const unsigned char *p = (const unsigned char *)s;
    size_t out = 0, bad = 0;
    while (*p) {
        size_t k = seq_len(p);
        const char *from = k ? (const char *)p : fffd;
        size_t len = k ? k : 3;
        if (out + len >= cap)
            break;
        memcpy(dst + out, from, len);
        out += len;
        bad += k == 0;
        p += k ? k : 1;
    }
    dst[out] = 0;
    return bad;
}
