/* test-cli: the natural order of file names (numbers by value, the rest by
 * bytes) that tvpal-encode's --sort natural and its order warning use; the
 * option parsers' number pairs (WxH, A:B) and ranged doubles; error details
 * (tvpal_diag) long enough for three paths, cut visibly beyond. */
#include "tvpal_cli.h"
#include "tvpal_error.h"
#include "tvpal_test.h"

#include <string.h>

static int sign(int v)
{
    return (v > 0) - (v < 0);
}

int main(void)
{
    static const struct { const char *a, *b; int want; } cases[] = {
        {"density_2", "density_10", -1}, {"density_10", "density_2", 1},
        {"density_1", "density_1", 0},   {"a1b2", "a1b10", -1},
        {"t009.f32", "t010.f32", -1},    {"t9.f32", "t010.f32", -1},
        {"run2/x_1", "run10/x_1", -1},   {"abc", "abd", -1},
        {"abc", "ab", 1},                {"", "a", -1},
        {"x_99999999999999999999", "x_100000000000000000000", -1},
        {"file.nc", "file1.nc", -1},     {"a_0", "a_00", 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        int got = sign(tvpal_natural_cmp(cases[i].a, cases[i].b));
        CHECK(got == cases[i].want, "\"%s\" vs \"%s\": %d, expected %d",
              cases[i].a, cases[i].b, got, cases[i].want);
    }
    /* Pairs: each part a whole number in range, nothing else. */
    static const struct { const char *s; int ok; uint32_t a, b; } pairs[] = {
        {"3x4", 1, 3, 4},          {"16384x1", 1, 16384, 1},
        {"4294967297x1", 0, 0, 0}, {"1x4294967296", 0, 0, 0},
        {"18446744073709551617x1", 0, 0, 0},
        {"-1x2", 0, 0, 0},         {"+1x2", 0, 0, 0},
        {"1x-2", 0, 0, 0},         {"1x2x", 0, 0, 0},
        {"1x2 ", 0, 0, 0},         {" 1x2", 0, 0, 0},
        {"x2", 0, 0, 0},           {"1x", 0, 0, 0},
        {"12", 0, 0, 0},           {"", 0, 0, 0},
        {"0x1", 0, 0, 0},          {"16385x1", 0, 0, 0},
        {"1x2x3", 0, 0, 0},
    };
    for (size_t i = 0; i < sizeof pairs / sizeof *pairs; i++) {
        uint32_t v[2] = {7, 7};
        int rc = tvpal_parse_u32_pair(pairs[i].s, 'x', 1, 16384, v);
        if (pairs[i].ok)
            CHECK(rc == 0 && v[0] == pairs[i].a && v[1] == pairs[i].b,
                  "pair \"%s\": rc %d, %ux%u", pairs[i].s, rc, v[0], v[1]);
        else
            CHECK(rc < 0 && v[0] == 7 && v[1] == 7,
                  "pair \"%s\" taken: %ux%u", pairs[i].s, v[0], v[1]);
    }
    double d = 5;
    CHECK(tvpal_parse_double_in("1e-20", 0.001, 1000, &d) < 0 && d == 5,
          "1e-20 taken as %g", d);
    CHECK(tvpal_parse_double_in("nan", -1, 1, &d) < 0, "nan taken");
    CHECK(tvpal_parse_double_in("inf", -1, 1e308, &d) < 0, "inf taken");
    CHECK(tvpal_parse_double_in("1e999", -1, 1e308, &d) < 0, "1e999 taken");
    CHECK(tvpal_parse_double_in("-360", -360, 360, &d) == 0 && d == -360,
          "-360 refused");
    /* Lists of doubles: exactly n parts, each a whole finite number. */
    static const struct { const char *s; int ok; } lists[] = {
        {"1,2.5,-3", 1}, {"1e300,0,0", 1}, {"1,2", 0}, {"1,2,3,", 0},
        {"1,2,3,4", 0}, {"1,,3", 0}, {",1,2", 0}, {"1,2,3x", 0},
        {"1,2,1e999", 0}, {"nan,1,2", 0}, {"1,inf,2", 0}, {"", 0},
    };
    for (size_t i = 0; i < sizeof lists / sizeof *lists; i++) {
        double v3[3];
        int rc = tvpal_parse_doubles(lists[i].s, ',', 3, v3);
        CHECK((rc == 0) == lists[i].ok, "list \"%s\": rc %d", lists[i].s, rc);
    }
    /* Error details: three paths of 300 characters fit whole (a message
     * naming a file, its collection and the file before it); a longer
     * detail is cut and says so. */
    static char path[301], big[3 * TVPAL_DIAG_MAX];
    memset(path, 'p', 300);
    struct tvpal_diag dg;
    CHECK(tvpal_diag_set(&dg, TVPAL_E_FORMAT, "%s: step 2 (%s) after (%s)",
                         path, path, path) == TVPAL_E_FORMAT &&
              strlen(dg.msg) == 3 * 300 + 20,
          "three paths: %zu characters kept", strlen(dg.msg));
    memset(big, 'b', sizeof big - 1);
    tvpal_diag_set(&dg, TVPAL_E_FORMAT, "%s", big);
    CHECK(strlen(dg.msg) == TVPAL_DIAG_MAX - 1 &&
              !strcmp(dg.msg + TVPAL_DIAG_MAX - 4, "..."),
          "a cut detail does not end in ...");
    char small[8];
    tvpal_diag_copy(small, sizeof small, "1234567");
    CHECK(!strcmp(small, "1234567"), "copy that fits: \"%s\"", small);
    tvpal_diag_copy(small, sizeof small, "12345678");
    CHECK(!strcmp(small, "1234..."), "cut copy: \"%s\"", small);
    CHECK(tvpal_diag_set(NULL, TVPAL_E_READ, "x") == TVPAL_E_READ,
          "no diag: the code");
    return tt_done("test-cli");
}
