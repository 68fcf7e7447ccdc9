/* test-utf8: tvpal_utf8_valid_prefix and tvpal_utf8_repair on the
 * awkward cases of RFC 3629 (overlong forms, surrogates, code points past
 * U+10FFFF, sequences cut short, lone continuation bytes) and on a
 * destination too small for the repaired text, which is cut at a
 * character's end. */
#include "tvpal_test.h"
#include "tvpal_utf8.h"

#include <string.h>

static void repair(const char *in, const char *want, size_t bad)
{
    char out[64];
    size_t n = tvpal_utf8_repair(out, sizeof out, in);
    CHECK(n == bad && !strcmp(out, want), "repair of \"%s\": %zu replaced, "
          "\"%s\"", in, n, out);
    CHECK(!out[tvpal_utf8_valid_prefix(out)], "repaired \"%s\" is valid", in);
}

int main(void)
{
    /* valid: ASCII, 2-, 3- and 4-byte forms at the edges of their ranges */
    static const char *good[] = {"", "K", "m s-1", "\xc2\xb0" "C",
                                 "\xdf\xbf", "\xe0\xa0\x80", "\xed\x9f\xbf",
                                 "\xee\x80\x80", "\xef\xbf\xbd",
                                 "\xf0\x90\x80\x80", "\xf4\x8f\xbf\xbf"};
    for (size_t i = 0; i < sizeof good / sizeof *good; i++) {
        CHECK(tvpal_utf8_valid_prefix(good[i]) == strlen(good[i]),
              "valid %zu", i);
        repair(good[i], good[i], 0);
    }
    /* invalid: where the first bad byte is, and the repair */
    CHECK(tvpal_utf8_valid_prefix("ab\xff" "cd") == 2, "0xff at 2");
    CHECK(tvpal_utf8_valid_prefix("\xc0\xaf") == 0, "overlong 2-byte");
    CHECK(tvpal_utf8_valid_prefix("\xe0\x80\xaf") == 0, "overlong 3-byte");
    CHECK(tvpal_utf8_valid_prefix("x\xed\xa0\x80") == 1, "surrogate");
    CHECK(tvpal_utf8_valid_prefix("\xf4\x90\x80\x80") == 0, "past U+10FFFF");
    CHECK(tvpal_utf8_valid_prefix("\xf5\x80\x80\x80") == 0, "0xf5");
    CHECK(tvpal_utf8_valid_prefix("a\xe2\x82") == 1, "cut short");
    repair("K\xff", "K\xef\xbf\xbd", 1);
    repair("\xb0" "C", "\xef\xbf\xbd" "C", 1);               /* Latin-1 */
    repair("a\xe2\x82", "a\xef\xbf\xbd\xef\xbf\xbd", 2);     /* cut short */
    repair("\xc0\xaf", "\xef\xbf\xbd\xef\xbf\xbd", 2);
    repair("\xed\xa0\x80", "\xef\xbf\xbd\xef\xbf\xbd\xef\xbf\xbd", 3);
    /* too small: cut at a character's end, never inside U+FFFD */
    char out[5];
    size_t n = tvpal_utf8_repair(out, sizeof out, "ab\xff\xff");
    CHECK(!strcmp(out, "ab") && n == 0, "cut before U+FFFD: \"%s\" %zu", out,
          n);
    n = tvpal_utf8_repair(out, sizeof out, "a\xc2\xb0\xc2\xb0");
    CHECK(!strcmp(out, "a\xc2\xb0") && n == 0, "cut at a character: %zu", n);
    n = tvpal_utf8_repair(out, 1, "abc");
    CHECK(out[0] == 0 && n == 0, "cap 1");
    return tt_done("test-utf8");
}
