/* test-vti: the VTK ImageData reader on the fixtures of tests/make-vti.py
 * (every encoding, both header types, both byte orders, the types, grids,
 * array choice, describe, each bad file with its code and a diag naming it;
 * compressed blocks inflated on the reading thread and on a pool; arrays
 * of several components read as their length with magnitude) and on
 * the real viscous-fingers .vti series of ../shared/data, which
 * must equal the raw steps bit for bit. */
#include "tvpal_input.h"
#include "tvpal_pool.h"
#include "tvpal_test.h"
#include "tt_box.h"

#include <glob.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#if !defined(HAVE_EXPAT) || !defined(HAVE_ZLIB)
int main(void)
{
    printf("test-vti: built without expat or zlib (libexpat1-dev, "
           "zlib1g-dev): skipped\n");
    return 77;
}
#else

#define NX 5
#define NY 4
#define NZ 3
#define N (NX * NY * NZ)

static char work[4096];

static const char *fixture(const char *name, const char *ext)
{
    static char path[2][4200];
    static int k;
    k ^= 1;
    snprintf(path[k], sizeof path[k], "%s/%s%s", work, name, ext);
    return path[k];
}

/* Reads fixture name (var: opts.var, g_magnitude: opts.magnitude) and
 * compares with name.f32 (or expect's .f32); returns the info through *out
 * when non-NULL.  Once inflating on the reading thread, once on a pool of
 * 3 threads. */
static struct tvpal_pool *g_pool;
static int g_magnitude;

static void check_good_on(const char *name, const char *var,
                          const char *expect, enum tvpal_type type,
                          struct tvpal_input_info *out,
                          struct tvpal_pool *pool)
{
    char *files[1] = {(char *)fixture(name, ".vti")};
    struct tvpal_input_opts opts = {.var = var, .pool = pool,
                                    .magnitude = g_magnitude};
    struct tvpal_input *in = NULL;
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_open(&in, TVPAL_IN_AUTO, files, 1, &opts, &g);
    CHECK(rc == 0, "%s: open: %s (%s)", name, tvpal_strerror(rc), g.msg);
    if (rc < 0)
        return;
    const struct tvpal_input_info *info = tvpal_input_info(in);
    CHECK(info->dims[0] == NX && info->dims[1] == NY && info->dims[2] == NZ,
          "%s: dims %ux%ux%u", name, info->dims[0], info->dims[1],
          info->dims[2]);
    CHECK(info->steps == 1 && !info->has_times, "%s: steps %u", name,
          info->steps);
    CHECK(info->type == type, "%s: type %s, expected %s", name,
          tvpal_type_name(info->type), tvpal_type_name(type));
    float got[N], want[N];
    for (int i = 0; i < N; i++)
        got[i] = -12345.f;
    rc = tvpal_input_read(in, 0, got, &g);
    CHECK(rc == 0, "%s: read: %s (%s)", name, tvpal_strerror(rc), g.msg);
    REQUIRE(tt_load_f32(fixture(expect ? expect : name, ".f32"), want, N) == 0,
            "%s.f32", expect ? expect : name);
    size_t first = 0, bad = tt_count_diff(got, want, N, &first);
    CHECK(rc < 0 || bad == 0, "%s: %zu values differ, first at %zu: %.9g, "
          "expected %.9g", name, bad, first, got[first], want[first]);
    rc = tvpal_input_read(in, 1, got, &g);
    CHECK(rc == TVPAL_E_INVAL, "%s: step 1 of 1 is refused (%d)", name, rc);
    tt_check_boxes(in, name);
    if (out)
        *out = *info;
    tvpal_input_close(in);
}

static void check_good(const char *name, const char *var, const char *expect,
                       enum tvpal_type type, struct tvpal_input_info *out)
{
    check_good_on(name, var, expect, type, out, NULL);
    check_good_on(name, var, expect, type, out, g_pool);
}

/* Opening (and, if that passes, reading) fixture name must fail with code,
 * with a diag naming the file and holding what. */
static void check_bad_on(const char *name, enum tvpal_input_format fmt,
                         const char *var, int code, const char *what,
                         struct tvpal_pool *pool)
{
    char *files[1] = {(char *)fixture(name, ".vti")};
    struct tvpal_input_opts opts = {.var = var, .pool = pool,
                                    .magnitude = g_magnitude};
    struct tvpal_input *in = NULL;
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_open(&in, fmt, files, 1, &opts, &g);
    if (rc == 0) {
        float v[N];
        rc = tvpal_input_read(in, 0, v, &g);
        tvpal_input_close(in);
    }
    CHECK(rc == code, "%s: %s (%d), expected %s (%d): %s", name,
          tvpal_strerror(rc), rc, tvpal_strerror(code), code, g.msg);
    CHECK(strstr(g.msg, files[0]) != NULL, "%s: the diag names the file: %s",
          name, g.msg);
    CHECK(strstr(g.msg, what) != NULL, "%s: the diag says \"%s\": %s", name,
          what, g.msg);
    printf("  %s: %s\n", name, g.msg);
}

/* check_bad_on, on the reading thread and on a pool: with blocks inflated
 * in any order, the lowest failing one is reported. */
static void check_bad(const char *name, enum tvpal_input_format fmt,
                      const char *var, int code, const char *what)
{
    check_bad_on(name, fmt, var, code, what, NULL);
    check_bad_on(name, fmt, var, code, what, g_pool);
}

static void fixtures(void)
{
    static const char *const f32[] = {
        "ascii", "ascii-infokey", "binary", "binary64", "binary-zlib",
        "binary-zlib64", "binary-zlib-joint", "appended-raw",
        "appended-raw64", "appended-zlib", "appended-zlib64", "appended-b64",
        "appended-b64-64", "appended-b64-zlib", "appended-b64-zlib64",
        "bigendian-raw", "bigendian-zlib64", "bigendian-binary"};
    for (size_t i = 0; i < sizeof f32 / sizeof *f32; i++)
        check_good(f32[i], NULL, NULL, TVPAL_F32, NULL);
    static const struct {
        const char *name;
        enum tvpal_type type;
    } typed[] = {{"float64", TVPAL_F64}, {"float64-be", TVPAL_F64},
                 {"float64-ascii", TVPAL_F64}, {"int16", TVPAL_I16},
                 {"int16-be", TVPAL_I16}, {"uint16", TVPAL_U16},
                 {"uint8", TVPAL_U8}, {"int8", TVPAL_F32},
                 {"int32", TVPAL_F64}, {"uint32", TVPAL_F64}};
    for (size_t i = 0; i < sizeof typed / sizeof *typed; i++)
        check_good(typed[i].name, NULL, NULL, typed[i].type, NULL);

    struct tvpal_input_info info;
    memset(&info, 0, sizeof info);
    check_good("grid", NULL, NULL, TVPAL_F32, &info);
    CHECK(info.spacing[0] == 0.5 && info.spacing[1] == 2 &&
          info.spacing[2] == 4, "grid: spacing %g %g %g", info.spacing[0],
          info.spacing[1], info.spacing[2]);
    CHECK(info.origin[0] == 1 && info.origin[1] == 2 && info.origin[2] == 3,
          "grid: origin %g %g %g", info.origin[0], info.origin[1],
          info.origin[2]);
    CHECK(!info.nonuniform[0] && !info.nonuniform[1] && !info.nonuniform[2] &&
          !info.missing_attrs, "grid: uniform, no missing attributes");
    CHECK(!strcmp(info.var, "v"), "grid: var %s", info.var);
    /* Extent 2..6, -1..2, 10..12: the first point is at Origin + start *
     * Spacing. */
    memset(&info, 0, sizeof info);
    check_good("extent", NULL, NULL, TVPAL_F32, &info);
    CHECK(info.origin[0] == 2 && info.origin[1] == 0 && info.origin[2] == 43,
          "extent: origin %g %g %g, expected 2 0 43", info.origin[0],
          info.origin[1], info.origin[2]);
    memset(&info, 0, sizeof info);
    check_good("appended-raw", NULL, NULL, TVPAL_F32, &info);
    CHECK(info.spacing[0] == 1 && info.spacing[1] == 1 && info.spacing[2] == 1 &&
          info.origin[0] == 0 && info.origin[1] == 0 && info.origin[2] == 0,
          "appended-raw: spacing 1, origin 0");

    /* The active Scalars (b), then a by name. */
    memset(&info, 0, sizeof info);
    check_good("two-arrays", NULL, NULL, TVPAL_F32, &info);
    CHECK(!strcmp(info.var, "b"), "two-arrays: var %s, expected b", info.var);
    memset(&info, 0, sizeof info);
    check_good("two-arrays", "a", "two-arrays-a", TVPAL_F32, &info);
    CHECK(!strcmp(info.var, "a"), "two-arrays --var a: var %s", info.var);
    check_good("no-scalars", "b", "two-arrays", TVPAL_F32, NULL);

    /* describe */
    char *text = NULL;
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_describe(fixture("two-arrays", ".vti"),
                                  TVPAL_IN_AUTO, &text, &g);
    static const char want[] =
        "vti (VTK XML ImageData, LittleEndian, header UInt32, none)\n"
        "extent 0 4 0 3 0 2 (5x4x3) spacing 1 1 1 origin 0 0 0\n"
        "a Float32 components=1\n"
        "b Float32 components=1 [active scalars]\n"
        "c Float32 components=1 [cell data]\n";
    CHECK(rc == 0 && text && !strcmp(text, want), "describe two-arrays: "
          "%d\n%s", rc, text ? text : g.msg);
    free(text);
    text = NULL;
    rc = tvpal_input_describe(fixture("bigendian-zlib64", ".vti"),
                              TVPAL_IN_VTI, &text, &g);
    CHECK(rc == 0 && text && !strncmp(text, "vti (VTK XML ImageData, "
          "BigEndian, header UInt64, vtkZLibDataCompressor)\n", 73),
          "describe bigendian-zlib64: %d\n%s", rc, text ? text : g.msg);
    free(text);
    text = NULL;
    rc = tvpal_input_describe(fixture("grid", ".vti"), TVPAL_IN_VTI, &text,
                              &g);
    CHECK(rc == 0 && text && strstr(text, "spacing 0.5 2 4 origin 1 2 3\n"),
          "describe grid: %d\n%s", rc, text ? text : g.msg);
    free(text);
    text = NULL;
    rc = tvpal_input_describe(fixture("bad-xml", ".vti"), TVPAL_IN_VTI, &text,
                              &g);
    CHECK(rc == TVPAL_E_FORMAT && !text, "describe bad-xml: %d", rc);

    enum tvpal_input_format f = TVPAL_IN_RAW;
    CHECK(tvpal_input_detect(fixture("appended-zlib", ".vti"), NULL, &f, &g) == 0 &&
          f == TVPAL_IN_VTI, "appended-zlib detected as vti");

    puts("bad files:");
    check_bad("bad-xml", TVPAL_IN_AUTO, NULL, TVPAL_E_FORMAT,
              "XML error at line 10: mismatched tag");
    check_bad("bad-zlib", TVPAL_IN_AUTO, NULL, TVPAL_E_FORMAT,
              "zlib block 2 of 4");
    check_bad("bad-offset", TVPAL_IN_AUTO, NULL, TVPAL_E_FORMAT,
              "offset 100000 points past the end");
    check_bad("bad-truncated", TVPAL_IN_AUTO, NULL, TVPAL_E_FORMAT,
              "past the end of the file");
    check_bad("bad-base64", TVPAL_IN_AUTO, NULL, TVPAL_E_FORMAT,
              "truncated base64");
    check_bad("bad-direction", TVPAL_IN_AUTO, NULL, TVPAL_E_FORMAT,
              "non-identity Direction is not supported");
    check_bad("bad-components", TVPAL_IN_AUTO, NULL, TVPAL_E_INVAL,
              "array v has 2 components (NumberOfComponents); tvpal reads "
              "one value per point: --magnitude encodes the vector's length");
    check_bad("vec-raw", TVPAL_IN_AUTO, NULL, TVPAL_E_INVAL,
              "array vel has 3 components");
    check_bad("bad-size", TVPAL_IN_AUTO, NULL, TVPAL_E_FORMAT,
              "holds 236 bytes; its extent needs 240");
    check_bad("bad-pieces", TVPAL_IN_AUTO, NULL, TVPAL_E_FORMAT,
              "several pieces are not supported");
    check_bad("bad-lz4", TVPAL_IN_AUTO, NULL, TVPAL_E_FORMAT,
              "compressor vtkLZ4DataCompressor is not supported yet");
    check_bad("bad-polydata", TVPAL_IN_VTI, NULL, TVPAL_E_FORMAT,
              "only ImageData");
    check_bad("two-arrays", TVPAL_IN_AUTO, "zzz", TVPAL_E_INVAL,
              "no point array zzz (point arrays: a, b)");
    check_bad("two-arrays", TVPAL_IN_AUTO, "c", TVPAL_E_INVAL,
              "c is a cell array");
    check_bad("no-scalars", TVPAL_IN_AUTO, NULL, TVPAL_E_INVAL,
              "2 point arrays and no active Scalars");

    /* A series of two files that disagree on the type. */
    char *two[2] = {(char *)fixture("appended-zlib", ".vti"),
                    (char *)fixture("float64", ".vti")};
    struct tvpal_input *in = NULL;
    rc = tvpal_input_open(&in, TVPAL_IN_AUTO, two, 2, NULL, &g);
    CHECK(rc == TVPAL_E_MISMATCH, "f32 then f64 files: %d (%s)", rc, g.msg);
    tvpal_input_close(in);
}

/* Arrays of several components with magnitude: each point's length, as
 * make-vti.py computes it, whole and in boxes, in every encoding; a scalar
 * array as it is; more components than are read refused. */
static void vectors(void)
{
    static const struct {
        const char *name;
        enum tvpal_type type;
        uint32_t ncomp;
    } vec[] = {{"vec-ascii", TVPAL_F32, 3}, {"vec-binary", TVPAL_F32, 3},
               {"vec-binary-zlib64", TVPAL_F32, 3}, {"vec-raw", TVPAL_F32, 3},
               {"vec-zlib", TVPAL_F32, 3}, {"vec-b64", TVPAL_F32, 3},
               {"vec-b64-zlib", TVPAL_F32, 3},
               {"vec-be-float64", TVPAL_F64, 2},
               {"vec-float64-ascii", TVPAL_F64, 3},
               {"vec-int16", TVPAL_I16, 3}, {"vec-uint8-4", TVPAL_U8, 4},
               {"vec-int32-9", TVPAL_F64, 9}};
    g_magnitude = 1;
    for (size_t i = 0; i < sizeof vec / sizeof *vec; i++) {
        struct tvpal_input_info info;
        memset(&info, 0, sizeof info);
        check_good(vec[i].name, NULL, NULL, vec[i].type, &info);
        CHECK(info.components == vec[i].ncomp && !strcmp(info.var, "vel"),
              "%s: %u components of %s, expected %u of vel", vec[i].name,
              info.components, info.var, vec[i].ncomp);
    }
    struct tvpal_input_info info;
    memset(&info, 0, sizeof info);
    check_good("appended-zlib", NULL, NULL, TVPAL_F32, &info);
    CHECK(info.components == 1, "a scalar array with magnitude: %u "
          "components", info.components);
    check_good("two-arrays", "a", "two-arrays-a", TVPAL_F32, NULL);
    check_bad("bad-ncomp", TVPAL_IN_AUTO, NULL, TVPAL_E_INVAL,
              "array vel has 257 components (NumberOfComponents); "
              "--magnitude reads at most 256");
    /* A series of a vector and a scalar array of one name is refused. */
    char *two[2] = {(char *)fixture("vec-zlib", ".vti"),
                    (char *)fixture("appended-zlib", ".vti")};
    struct tvpal_input_opts opts = {.var = "vel", .magnitude = 1};
    struct tvpal_input *in = NULL;
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_open(&in, TVPAL_IN_AUTO, two, 2, &opts, &g);
    CHECK(rc == TVPAL_E_INVAL && strstr(g.msg, "no point array vel"),
          "vector then scalar files: %d (%s)", rc, g.msg);
    tvpal_input_close(in);
    g_magnitude = 0;
}

/* Box reads of the larger grids of make-vti.py --big (written into
 * work/big by main): every box equals the whole read's; the scratch of a
 * slice stays far below a step. */
static void big(void)
{
    static const char *const names[] = {"big-raw", "big-zlib",
                                        "big-zlib64-be", "big-binary-zlib",
                                        "big-b64", "big-int16",
                                        "big-vec-raw", "big-vec-zlib",
                                        "big-vec-b64-f64"};
    for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
        char path[4400];
        snprintf(path, sizeof path, "%s/big/%s.vti", work, names[i]);
        char *files[1] = {path};
        struct tvpal_input *in = NULL;
        struct tvpal_diag g = {{0}};
        const struct tvpal_input_opts opts = {
            .magnitude = !strncmp(names[i], "big-vec", 7)};
        int rc = tvpal_input_open(&in, TVPAL_IN_AUTO, files, 1, &opts, &g);
        CHECK(rc == 0, "%s: open: %s", names[i], g.msg);
        if (rc < 0)
            continue;
        tt_check_boxes_n(in, 6, names[i]);
        /* zlib: a block or two; raw float32 z-slices: none */
        tt_check_box_scratch(in, strstr(names[i], "zlib") ? 4 : 1, names[i]);
        if (!strcmp(names[i], "big-raw")) {
            const uint32_t *d = tvpal_input_info(in)->dims;
            const uint32_t zs[3] = {d[0], d[1], 3}, xs[3] = {2, d[1], d[2]};
            CHECK(tvpal_input_box_scratch(in, zs) == 0, "big-raw: z-slab "
                  "boxes read straight into dst");
            CHECK(tvpal_input_box_scratch(in, xs) == ((size_t)4 << 20),
                  "big-raw: an x-slab batches rows in 4 MiB (%llu)",
                  (unsigned long long)tvpal_input_box_scratch(in, xs));
        }
        tvpal_input_close(in);
    }
}

/* The real series: 20 .vti files of run01; steps 1, 2, 10 and 20 equal the
 * raw files. */
static int realdata(void)
{
    const char *shared = getenv("TVPAL_SHARED");
    const char *src = getenv("TVPAL_SRCDIR");
    char base[4096], pat[4200];
    if (shared)
        snprintf(base, sizeof base, "%s/data", shared);
    else
        snprintf(base, sizeof base, "%s/../shared/data", src ? src : ".");
    snprintf(pat, sizeof pat, "%s/viscous-fingers-run01-vti/*.vti", base);
    glob_t gl;
    if (glob(pat, 0, NULL, &gl) != 0 || gl.gl_pathc == 0) {
        printf("no %s: the real-data part is skipped\n", pat);
        return 0;
    }
    int ran = 0;
    CHECK(gl.gl_pathc == 20, "%zu files in %s", gl.gl_pathc, pat);
    struct tvpal_input *in = NULL;
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_open(&in, TVPAL_IN_AUTO, gl.gl_pathv,
                              (int)gl.gl_pathc, NULL, &g);
    CHECK(rc == 0, "open the real series: %s (%s)", tvpal_strerror(rc), g.msg);
    if (rc == 0) {
        const struct tvpal_input_info *info = tvpal_input_info(in);
        CHECK(info->steps == gl.gl_pathc && info->dims[0] == 64 &&
              info->dims[1] == 64 && info->dims[2] == 64 &&
              info->type == TVPAL_F32 && !strcmp(info->var, "ImageFile"),
              "real series: %u steps, %ux%ux%u %s %s", info->steps,
              info->dims[0], info->dims[1], info->dims[2],
              tvpal_type_name(info->type), info->var);
        size_t n = (size_t)64 * 64 * 64;
        float *got = malloc(n * 4), *want = malloc(n * 4);
        REQUIRE(got && want, "memory");
        static const unsigned steps[] = {1, 2, 10, 20};
        for (size_t i = 0; i < sizeof steps / sizeof *steps; i++) {
            unsigned s = steps[i];
            if (s > info->steps)
                continue;
            char raw[4300];
            snprintf(raw, sizeof raw, "%s/viscous-fingers-run01/"
                     "density_t%03u.f32", base, s);
            if (tt_load_f32(raw, want, n) < 0) {
                printf("no %s: that step is not compared\n", raw);
                continue;
            }
            rc = tvpal_input_read(in, s - 1, got, &g);
            CHECK(rc == 0, "read step %u: %s", s, g.msg);
            size_t first = 0, bad = tt_count_diff(got, want, n, &first);
            CHECK(rc < 0 || bad == 0, "step %u: %zu values differ from %s, "
                  "first at %zu", s, bad, raw, first);
            ran++;
        }
        free(got);
        free(want);
        tt_check_boxes_n(in, 4, "real series");
        tt_check_box_scratch(in, 4, "real series");
    }
    tvpal_input_close(in);
    globfree(&gl);
    CHECK(ran > 0, "no raw step to compare the .vti steps with");
    printf("real data: %d steps of the .vti series equal the raw files\n", ran);
    return ran;
}

int main(void)
{
    const char *build = getenv("TVPAL_BUILDDIR");
    const char *src = getenv("TVPAL_SRCDIR");
    const char *py = getenv("PYTHON");
    if (!py)
        py = access("/usr/bin/python3", X_OK) == 0 ? "/usr/bin/python3"
                                                  : "python3";
    char cmd[12000];
    snprintf(cmd, sizeof cmd, "command -v '%s' > /dev/null 2>&1", py);
    if (system(cmd) != 0) {
        printf("test-vti: no python3 to write the fixtures: skipped\n");
        return 77;
    }
    snprintf(work, sizeof work, "%s/tests/work/test-vti", build ? build : ".");
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s' && '%s' "
             "'%s/tests/make-vti.py' '%s'", work, work, py, src ? src : ".",
             work);
    REQUIRE(system(cmd) == 0, "%s", cmd);
    snprintf(cmd, sizeof cmd, "'%s' '%s/tests/make-vti.py' --big '%s/big'",
             py, src ? src : ".", work);
    REQUIRE(system(cmd) == 0, "%s", cmd);
    REQUIRE(tvpal_pool_create(&g_pool, 3) == 0, "pool");
    fixtures();
    vectors();
    big();
    realdata();
    int rc = tt_done("test-vti");
    if (rc == 0) {
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", work);
        if (system(cmd) != 0)
            fprintf(stderr, "could not remove %s\n", work);
    }
    return rc;
}

#endif
