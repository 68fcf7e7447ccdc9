/* test-cli: the natural order of file names (numbers by value, the rest by
 * bytes) that tvpal-encode's --sort natural and its order warning use. */
#include "tvpal_cli.h"
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
    return tt_done("test-cli");
}
