/* tvpal_utf8.h: text from files made safe to draw.
 *
 * Labels come from the files users encode (a NetCDF units attribute, a
 * variable name, --units): bytes in whatever encoding the writer used.
 * Text renderers (cairo) refuse a string that is not valid UTF-8, so one
 * bad byte would fail every annotated frame.  These replace each byte that
 * does not begin a valid sequence with U+FFFD, as text viewers do. */
#ifndef TVPAL_UTF8_H
#define TVPAL_UTF8_H

#include <stddef.h>

/* Bytes of the first invalid sequence of the NUL-terminated s, or the
 * length of s when it is valid UTF-8 (RFC 3629: no overlong forms, no
 * surrogates, nothing above U+10FFFF). */
size_t tvpal_utf8_valid_prefix(const char *s);

/* Copies s into dst (cap bytes, cap >= 1; always NUL-terminated) with
 * every byte that does not begin a valid sequence replaced by U+FFFD (EF
 * BF BD), cut at a character's end where dst is too small.  Returns the
 * number of bytes replaced (0: dst holds s, cut or not). */
size_t tvpal_utf8_repair(char *dst, size_t cap, const char *s);

#endif
