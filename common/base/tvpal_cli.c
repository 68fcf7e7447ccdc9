/* tvpal_cli.c: program helpers (see tvpal_cli.h). */
#include "tvpal_cli.h"
#include "tvpal_error.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int tvpal_parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out)
{
    char *end;
    if (!s || *s < '0' || *s > '9')
        return -1;
    errno = 0;
    unsigned long long v = strtoull(s, &end, 10);
    if (errno || *end || v < lo || v > hi)
        return -1;
    *out = (uint32_t)v;
    return 0;
}

int tvpal_parse_double(const char *s, double *out)
{
    char *end;
    if (!s || !*s)
        return -1;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || *end || !isfinite(v))
        return -1;
    *out = v;
    return 0;
}

int tvpal_parse_double_in(const char *s, double lo, double hi, double *out)
{
    double v;
    if (tvpal_parse_double(s, &v) < 0 || !(v >= lo && v <= hi))
        return -1;
    *out = v;
    return 0;
}

int tvpal_parse_doubles(const char *s, char sep, unsigned n, double *out)
{
    for (unsigned i = 0; s && i < n; i++) {
        char part[64];
        const char *next = strchr(s, sep);
        size_t len = next ? (size_t)(next - s) : strlen(s);
        if (len >= sizeof part || (i + 1 < n) != (next != NULL))
            return -1;
        memcpy(part, s, len);
        part[len] = 0;
        if (tvpal_parse_double(part, &out[i]) < 0)
            return -1;
        s = next ? next + 1 : NULL;
    }
    return n ? 0 : -1;
}

int tvpal_parse_u32_pair(const char *s, char sep, uint32_t lo, uint32_t hi,
                         uint32_t out[2])
{
    char first[32];
    const char *mid = s ? strchr(s, sep) : NULL;
    uint32_t v[2];
    if (!mid || (size_t)(mid - s) >= sizeof first)
        return -1;
    memcpy(first, s, (size_t)(mid - s));
    first[mid - s] = 0;
    if (tvpal_parse_u32(first, lo, hi, &v[0]) < 0 ||
        tvpal_parse_u32(mid + 1, lo, hi, &v[1]) < 0)
        return -1;
    out[0] = v[0];
    out[1] = v[1];
    return 0;
}

int tvpal_parse_axis(const char *s)
{
    if (s && s[0] && !s[1] && s[0] >= 'x' && s[0] <= 'z')
        return s[0] - 'x';
    return -1;
}

void tvpal_progress_format(char *buf, size_t cap, uint64_t done,
                           uint64_t total, const char *unit, double rate,
                           const char *rate_unit, double eta_s, int width)
{
    char bar[128] = "";
    double frac = total ? (double)done / (double)total : 1.0;
    if (width > 0) {
        if (width > 100)
            width = 100;
        int fill = (int)(frac * width + 0.5);
        bar[0] = '[';
        for (int i = 0; i < width; i++)
            bar[1 + i] = i < fill ? '#' : '.';
        bar[1 + width] = ']';
        bar[2 + width] = ' ';
        bar[3 + width] = 0;
    }
    char eta[32];
    if (!(eta_s >= 0) || eta_s > 1e7)
        snprintf(eta, sizeof eta, "--");
    else if (eta_s >= 3600)
        snprintf(eta, sizeof eta, "%dh%02dm", (int)(eta_s / 3600),
                 (int)fmod(eta_s / 60, 60));
    else if (eta_s >= 60)
        snprintf(eta, sizeof eta, "%dm%02ds", (int)(eta_s / 60),
                 (int)fmod(eta_s, 60));
    else
        snprintf(eta, sizeof eta, "%.0fs", eta_s);
    snprintf(buf, cap, "%s%3.0f%%  %llu/%llu %s  %.1f %s  ETA %s", bar,
             100.0 * frac, (unsigned long long)done,
             (unsigned long long)total, unit, rate, rate_unit, eta);
}

int tvpal_natural_cmp(const char *a, const char *b)
{
    while (*a && *b) {
        if (isdigit((unsigned char)*a) && isdigit((unsigned char)*b)) {
            const char *ea = a, *eb = b;
            while (*a == '0')
                a++;
            while (*b == '0')
                b++;
            for (ea = a; isdigit((unsigned char)*ea); ea++)
                ;
            for (eb = b; isdigit((unsigned char)*eb); eb++)
                ;
            /* Without leading zeros, the longer run is the larger number;
             * runs of one length compare digit by digit. */
            if (ea - a != eb - b)
                return ea - a < eb - b ? -1 : 1;
            int c = strncmp(a, b, (size_t)(ea - a));
            if (c)
                return c;
            a = ea;
            b = eb;
            continue;
        }
        if (*a != *b)
            return (unsigned char)*a < (unsigned char)*b ? -1 : 1;
        a++;
        b++;
    }
    return (unsigned char)*a - (unsigned char)*b;
}

int tvpal_axes_parse(const char *s, uint32_t *mask)
{
    uint32_t got = 0;
    for (; *s; s++) {
        if (*s == ' ' || *s == '\t')
            continue;
        const char *c = strchr("xyz", *s);
        if (!c || !*c || (got & (1u << (c - "xyz"))))
            return TVPAL_E_INVAL;
        got |= (1u << (c - "xyz"));
    }
    if (!got)
        return TVPAL_E_INVAL;
    *mask = got;
    return 0;
}

char *tvpal_axes_format(uint32_t mask, char buf[4])
{
    char *p = buf;
    for (unsigned a = 0; a < 3 && mask >= 1 && mask <= 7u; a++)
        if (mask & (1u << a))
            *p++ = "xyz"[a];
    *p = 0;
    return buf;
}

unsigned tvpal_axes_count(uint32_t mask)
{
    return (mask & 1) + (mask >> 1 & 1) + (mask >> 2 & 1);
}
