/* test-raw: dims parsing (valid, zero, overflow, malformed), types, and
 * conversion of every type and byte order with the NaN policy. */
#include "tvpal_raw.h"
#include "tvpal_test.h"

#include <string.h>

int main(void)
{
    uint32_t d[3];
    struct tvpal_diag g;
    CHECK(tvpal_dims_parse("64x48x1", d, &g) == 0 && d[0] == 64 && d[1] == 48
          && d[2] == 1, "valid");
    CHECK(tvpal_dims_parse("1X2X3", d, &g) == 0, "upper-case X");
    static const char *bad[] = {"", "64", "64x64", "64x64x", "x64x64",
                                "64x64x64x", "64x-1x3", "64 x64x64", "axbxc",
                                "64x64x64 "};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++)
        CHECK(tvpal_dims_parse(bad[i], d, &g) == TVPAL_E_INVAL,
              "malformed \"%s\"", bad[i]);
    CHECK(tvpal_dims_parse("0x4x4", d, &g) == TVPAL_E_INVAL &&
          strstr(g.msg, "at least 1"), "zero: %s", g.msg);
    CHECK(tvpal_dims_parse("4294967296x1x1", d, &g) == TVPAL_E_OVERFLOW,
          "component overflow");
    CHECK(tvpal_dims_parse("2000000000x2000000000x2000000000", d, &g) ==
          TVPAL_E_OVERFLOW, "product overflow");

    enum tvpal_type t;
    static const char *names[] = {"f32", "f64", "u8", "u16", "i16"};
    static const size_t sizes[] = {4, 8, 1, 2, 2};
    for (int i = 0; i < 5; i++) {
        CHECK(tvpal_type_parse(names[i], &t) == 0 &&
              !strcmp(tvpal_type_name(t), names[i]) &&
              tvpal_type_size(t) == sizes[i], "type %s", names[i]);
    }
    CHECK(tvpal_type_parse("float", &t) == TVPAL_E_INVAL, "bad type");

    float out[4];
    size_t badi = 0, rep = 0;
    const unsigned char u16le[] = {0x34, 0x12, 0xFF, 0xFF};
    const unsigned char u16be[] = {0x12, 0x34, 0xFF, 0xFF};
    CHECK(tvpal_raw_convert(u16le, TVPAL_U16, 0, 2, out, NULL, &badi, NULL) == 0
          && out[0] == 0x1234 && out[1] == 65535, "u16 le");
    CHECK(tvpal_raw_convert(u16be, TVPAL_U16, 1, 2, out, NULL, &badi, NULL) == 0
          && out[0] == 0x1234, "u16 be");
    CHECK(tvpal_raw_convert(u16le, TVPAL_I16, 0, 2, out, NULL, &badi, NULL) == 0
          && out[0] == 0x1234 && out[1] == -1, "i16 le");
    CHECK(tvpal_raw_convert(u16be, TVPAL_U8, 0, 4, out, NULL, &badi, NULL) == 0
          && out[0] == 0x12 && out[3] == 255, "u8");
    const unsigned char f32be[] = {0x3F, 0xC0, 0, 0, 0xC1, 0x20, 0, 0};
    CHECK(tvpal_raw_convert(f32be, TVPAL_F32, 1, 2, out, NULL, &badi, NULL) == 0
          && out[0] == 1.5f && out[1] == -10.0f, "f32 be");
    const unsigned char f64le[] = {0, 0, 0, 0, 0, 0, 0xF8, 0x3F};
    CHECK(tvpal_raw_convert(f64le, TVPAL_F64, 0, 1, out, NULL, &badi, NULL) == 0
          && out[0] == 1.5f, "f64 le");
    const unsigned char f64be[] = {0x3F, 0xF8, 0, 0, 0, 0, 0, 0};
    CHECK(tvpal_raw_convert(f64be, TVPAL_F64, 1, 1, out, NULL, &badi, NULL) == 0
          && out[0] == 1.5f, "f64 be");
    float in[4] = {1.0f, NAN, 2.0f, INFINITY};
    CHECK(tvpal_raw_convert(in, TVPAL_F32, 0, 4, out, NULL, &badi, NULL) ==
              TVPAL_E_NAN && badi == 3, "infinity found at 3 (got %zu)", badi);
    CHECK(isnan(out[1]) && out[2] == 2.0f, "NaN kept as missing");
    const unsigned char f64nan[] = {0, 0, 0, 0, 0, 0, 0xF8, 0x7F};
    CHECK(tvpal_raw_convert(f64nan, TVPAL_F64, 0, 1, out, NULL, &badi, NULL) ==
              0 && isnan(out[0]), "f64 NaN kept");
    float mv[5] = {1e35f, 3.0f, -999.0f, 0.1f, 1e35f};
    const double vals[2] = {1e35, -999};
    CHECK(tvpal_missing_apply(mv, 5, vals, 2, NULL) == 3 && isnan(mv[0]) &&
              isnan(mv[2]) && isnan(mv[4]) && mv[1] == 3.0f && mv[3] == 0.1f,
          "--missing values compared as float32");
    float mr[3] = {-999.0f, 1.0f, -999.0f};
    const double repl2 = 5;
    CHECK(tvpal_missing_apply(mr, 3, vals, 2, &repl2) == 2 && mr[0] == 5.0f &&
              mr[1] == 1.0f && mr[2] == 5.0f, "--missing with --nan-as");
    double repl = -7;
    CHECK(tvpal_raw_convert(in, TVPAL_F32, 0, 4, out, &repl, &badi, &rep) == 0
          && out[1] == -7.0f && out[3] == -7.0f && rep == 2, "nan-as");
    double big = 1e300;
    CHECK(tvpal_raw_convert(&big, TVPAL_F64, 0, 1, out, NULL, &badi, NULL) ==
          TVPAL_E_RANGE, "beyond float range");
    return tt_done("test-raw");
}
