/* test-vtk: the .pvd collections, .pvti pieces and legacy .vtk
 * STRUCTURED_POINTS readers on the fixtures of tests/make-vtk.py: exact
 * values, dims, spacing and origin, the times of a .pvd (sorted by
 * timestep), array choice, describe, detection, vectors read as their
 * length (magnitude: VECTORS, SCALARS of 3, FIELD arrays, .pvti pieces),
 * and each bad file with its code and a diag naming it. */
#include "tvpal_input.h"
#include "tvpal_test.h"
#include "tt_box.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define NX 5
#define NY 4
#define NZ 3
#define N (NX * NY * NZ)

static char work[4096];
static int g_magnitude;   /* opts.magnitude of check_good and check_bad */

static const char *fixture(const char *name)
{
    static char path[2][4200];
    static int k;
    k ^= 1;
    snprintf(path[k], sizeof path[k], "%s/%s", work, name);
    return path[k];
}

/* Opens fixture name (var: opts.var) as a series; each step s must equal
 * expect[s] (a .f32 fixture); checks dims and type, returns the info. */
static void check_good(const char *name, const char *var,
                       const char *const *expect, unsigned steps,
                       enum tvpal_type type, struct tvpal_input_info *out)
{
    char *files[1] = {(char *)fixture(name)};
    struct tvpal_input_opts opts = {.var = var, .magnitude = g_magnitude};
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
    CHECK(info->steps == steps, "%s: steps %u, expected %u", name,
          info->steps, steps);
    CHECK(info->type == type, "%s: type %s, expected %s", name,
          tvpal_type_name(info->type), tvpal_type_name(type));
    for (unsigned s = 0; s < steps && s < info->steps; s++) {
        float got[N], want[N];
        for (int i = 0; i < N; i++)
            got[i] = -12345.f;
        rc = tvpal_input_read(in, s, got, &g);
        CHECK(rc == 0, "%s: read %u: %s (%s)", name, s, tvpal_strerror(rc),
              g.msg);
        REQUIRE(tt_load_f32(fixture(expect[s]), want, N) == 0, "%s", expect[s]);
        size_t first = 0, bad = tt_count_diff(got, want, N, &first);
        CHECK(rc < 0 || bad == 0, "%s step %u: %zu values differ, first at "
              "%zu: %.9g, expected %.9g", name, s, bad, first, got[first],
              want[first]);
    }
    tt_check_boxes(in, name);
    if (out)
        *out = *info;
    for (unsigned s = 0; s < info->steps; s++) {
        uint32_t k = 99;
        const char *f = tvpal_input_file(in, s, &k);
        if (steps > 1)
            printf("  %s step %u: %s (time %g)\n", name, s, f,
                   tvpal_input_time(in, s));
        CHECK(k == 0, "%s: step %u is step %u of its file", name, s, k);
    }
    tvpal_input_close(in);
}

/* Opening (and, if that passes, reading) fixture name must fail with code,
 * with a diag naming the file (and also, when non-NULL, also) and holding
 * what. */
static void check_bad(const char *name, const char *var, int code,
                      const char *what, const char *also)
{
    char *files[1] = {(char *)fixture(name)};
    struct tvpal_input_opts opts = {.var = var, .magnitude = g_magnitude};
    struct tvpal_input *in = NULL;
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_open(&in, TVPAL_IN_AUTO, files, 1, &opts, &g);
    if (rc == 0) {
        float v[N];
        rc = tvpal_input_read(in, 0, v, &g);
        tvpal_input_close(in);
    }
    CHECK(rc == code, "%s: %s (%d), expected %s (%d): %s", name,
          tvpal_strerror(rc), rc, tvpal_strerror(code), code, g.msg);
    CHECK(strstr(g.msg, files[0]) != NULL, "%s: the diag names the file: %s",
          name, g.msg);
    CHECK(!also || strstr(g.msg, also), "%s: the diag names %s: %s", name,
          also ? also : "", g.msg);
    CHECK(strstr(g.msg, what) != NULL, "%s: the diag says \"%s\": %s", name,
          what, g.msg);
    printf("  %s: %s\n", name, g.msg);
}

static void grid_is(const char *name, const struct tvpal_input_info *info,
                    double sx, double sy, double sz, double ox, double oy,
                    double oz)
{
    CHECK(info->spacing[0] == sx && info->spacing[1] == sy &&
          info->spacing[2] == sz, "%s: spacing %g %g %g", name,
          info->spacing[0], info->spacing[1], info->spacing[2]);
    CHECK(info->origin[0] == ox && info->origin[1] == oy &&
          info->origin[2] == oz, "%s: origin %g %g %g", name,
          info->origin[0], info->origin[1], info->origin[2]);
}

static void describe_has(const char *name, const char *want)
{
    char *text = NULL;
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_describe(fixture(name), TVPAL_IN_AUTO, &text, &g);
    CHECK(rc == 0 && text && strstr(text, want), "describe %s: %d, no "
          "\"%s\" in:\n%s", name, rc, want, text ? text : g.msg);
    free(text);
}

static void pvd(void)
{
    static const char *const steps[] = {"series-1.f32", "series-2.f32",
                                        "series-3.f32"};
    static const double want_t[] = {0.5, 1.0, 2.5};
    struct tvpal_input_info info;
    const char *const names[] = {"series.pvd", "unsorted.pvd"};
    for (int k = 0; k < 2; k++) {
        memset(&info, 0, sizeof info);
        check_good(names[k], NULL, steps, 3, TVPAL_F32, &info);
        CHECK(info.has_times, "%s: has times", names[k]);
        grid_is(names[k], &info, 0.5, 2, 4, 1, 2, 3);
        char *files[1] = {(char *)fixture(names[k])};
        struct tvpal_input *in = NULL;
        struct tvpal_diag g = {{0}};
        if (tvpal_input_open(&in, TVPAL_IN_VTI, files, 1, NULL, &g) == 0) {
            for (uint32_t s = 0; s < 3; s++) {
                CHECK(tvpal_input_time(in, s) == want_t[s], "%s: time %u is "
                      "%g, expected %g", names[k], s, tvpal_input_time(in, s),
                      want_t[s]);
                char suffix[32];
                snprintf(suffix, sizeof suffix, "/series/step-%u.vti", s);
                const char *f = tvpal_input_file(in, s, NULL);
                CHECK(strlen(f) > strlen(suffix) &&
                      !strcmp(f + strlen(f) - strlen(suffix), suffix) &&
                      !strncmp(f, work, strlen(work)), "%s: step %u is %s",
                      names[k], s, f);
            }
        } else {
            CHECK(0, "%s: open as vti: %s", names[k], g.msg);
        }
        tvpal_input_close(in);
    }
    /* Two collections strung together: six steps, their times in order;
     * two whose times repeat (the same steps twice) are refused, as
     * --times refuses them. */
    FILE *lp = fopen(fixture("later.pvd"), "wb");
    REQUIRE(lp && fputs("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" "
                        "version=\"0.1\"><Collection>\n"
                        "<DataSet timestep=\"3\" file=\"series/step-0.vti\"/>\n"
                        "<DataSet timestep=\"4\" file=\"series/step-1.vti\"/>\n"
                        "<DataSet timestep=\"5\" file=\"series/step-2.vti\"/>\n"
                        "</Collection></VTKFile>\n", lp) >= 0 &&
            fclose(lp) == 0, "later.pvd");
    char *two[2] = {(char *)fixture("series.pvd"),
                    (char *)fixture("later.pvd")};
    struct tvpal_input *in = NULL;
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_open(&in, TVPAL_IN_AUTO, two, 2, NULL, &g);
    CHECK(rc == 0 && tvpal_input_info(in)->steps == 6 &&
          tvpal_input_time(in, 3) == 3, "two collections: %d (%s)", rc,
          g.msg);
    tvpal_input_close(in);
    in = NULL;
    char *again[2] = {(char *)fixture("series.pvd"),
                      (char *)fixture("unsorted.pvd")};
    rc = tvpal_input_open(&in, TVPAL_IN_AUTO, again, 2, NULL, &g);
    CHECK(rc == TVPAL_E_FORMAT && strstr(g.msg, "unsorted.pvd: the time of "
                                         "step 3 (0.5") &&
          strstr(g.msg, "is not after step 2's (2.5"),
          "two collections of the same times: %d (%s)", rc, g.msg);
    tvpal_input_close(in);
    in = NULL;
    char *mixed[2] = {(char *)fixture("series.pvd"),
                      (char *)fixture("series/step-0.vti")};
    rc = tvpal_input_open(&in, TVPAL_IN_AUTO, mixed, 2, NULL, &g);
    CHECK(rc == TVPAL_E_MISMATCH && strstr(g.msg, "collection and plain"),
          "collection and a plain file: %d (%s)", rc, g.msg);
    tvpal_input_close(in);
    describe_has("series.pvd", "vti (VTK collection .pvd, 3 DataSets, by "
                 "timestep)\ntimestep 0.5 ");
    describe_has("series.pvd", "\nfirst DataSet: vti (VTK XML ImageData");
    enum tvpal_input_format f = TVPAL_IN_RAW;
    CHECK(tvpal_input_detect(fixture("series.pvd"), NULL, &f, &g) == 0 &&
          f == TVPAL_IN_VTI, "series.pvd detected as vti");

    check_bad("bad-missing.pvd", NULL, TVPAL_E_OPEN, "No such file",
              "series/no-such-step.vti");
    check_bad("bad-parts.pvd", NULL, TVPAL_E_FORMAT,
              "multi-part collections are not supported", NULL);
}

static void pvti(void)
{
    static const char *const v[] = {"pieces.f32"}, *const w[] = {"pieces-w.f32"};
    struct tvpal_input_info info;
    memset(&info, 0, sizeof info);
    check_good("pieces.pvti", NULL, v, 1, TVPAL_F32, &info);
    grid_is("pieces.pvti", &info, 0.5, 2, 4, 1, 2, 3);
    CHECK(!strcmp(info.var, "v") && !info.has_times, "pieces.pvti: var %s",
          info.var);
    check_good("pieces.pvti", "w", w, 1, TVPAL_F32, NULL);
    describe_has("pieces.pvti", "vti (VTK XML PImageData, LittleEndian");
    describe_has("pieces.pvti", "(5x4x3) spacing 0.5 2 4 origin 1 2 3");
    describe_has("pieces.pvti", "\npiece pieces/p3.vti extent 2 4 1 3 0 2\n");
    describe_has("pieces.pvti", "\nv Float32 components=1 [active scalars]\n");
    check_bad("bad-piece.pvti", NULL, TVPAL_E_OPEN, "No such file",
              "pieces/no-such-piece.vti");
    check_bad("bad-hole.pvti", NULL, TVPAL_E_FORMAT,
              "do not cover the WholeExtent", NULL);
    check_bad("pieces.pvti", "zzz", TVPAL_E_INVAL, "no point array zzz", NULL);
}

static void legacy(void)
{
    static const char *const af[] = {"ascii-float.f32"},
                             *const bf[] = {"binary-float.f32"},
                             *const bs[] = {"binary-short.f32"},
                             *const ta[] = {"two-scalars.f32"},
                             *const tb[] = {"two-scalars-b.f32"};
    struct tvpal_input_info info;
    memset(&info, 0, sizeof info);
    check_good("ascii-float.vtk", NULL, af, 1, TVPAL_F32, &info);
    grid_is("ascii-float.vtk", &info, 0.5, 2, 4, 1, 2, 3);
    CHECK(!strcmp(info.var, "v") && !info.has_times, "ascii-float: var %s",
          info.var);
    memset(&info, 0, sizeof info);
    check_good("binary-float.vtk", NULL, bf, 1, TVPAL_F32, &info);
    grid_is("binary-float.vtk", &info, 1, 1, 1, 0, 0, 0);
    check_good("binary-short.vtk", NULL, bs, 1, TVPAL_I16, NULL);
    memset(&info, 0, sizeof info);
    check_good("two-scalars.vtk", NULL, ta, 1, TVPAL_F32, &info);
    CHECK(!strcmp(info.var, "a"), "two-scalars: default %s, expected a (the "
          "first SCALARS)", info.var);
    check_good("two-scalars.vtk", "b", tb, 1, TVPAL_F64, NULL);
    describe_has("two-scalars.vtk", "vtk (legacy VTK 3.0, BINARY big-endian, "
                 "STRUCTURED_POINTS): tvpal tests/make-vtk.py fixture\n"
                 "extent 0 4 0 3 0 2 (5x4x3) spacing 1 1 1 origin 0 0 0\n"
                 "a float components=1 [active scalars]\n"
                 "vel float components=3 VECTORS\n"
                 "b double components=1\n"
                 "c float components=1 [cell data]\n");
    enum tvpal_input_format f = TVPAL_IN_RAW;
    struct tvpal_diag g = {{0}};
    CHECK(tvpal_input_detect(fixture("ascii-float.vtk"), NULL, &f, &g) == 0 &&
          f == TVPAL_IN_VTK, "ascii-float.vtk detected as vtk");
    CHECK(tvpal_input_format_parse("vtk", &f) == 0 && f == TVPAL_IN_VTK &&
          !strcmp(tvpal_input_format_name(TVPAL_IN_VTK), "vtk"),
          "format name vtk");
    check_bad("bad-dims.vtk", NULL, TVPAL_E_FORMAT,
              "POINT_DATA 60; DIMENSIONS 5 4 4 make 80", NULL);
    check_bad("bad-count.vtk", NULL, TVPAL_E_FORMAT,
              "ends after 55 of 60 values", NULL);
    check_bad("bad-truncated.vtk", NULL, TVPAL_E_FORMAT,
              "ends before its 240 bytes", NULL);
    check_bad("bad-polydata.vtk", NULL, TVPAL_E_FORMAT,
              "DATASET POLYDATA: only STRUCTURED_POINTS", NULL);
    check_bad("two-scalars.vtk", "zzz", TVPAL_E_INVAL,
              "no point array zzz (point arrays: a, vel (VECTORS), b)", NULL);
    check_bad("two-scalars.vtk", "c", TVPAL_E_INVAL, "c is cell SCALARS",
              NULL);
    check_bad("two-scalars.vtk", "vel", TVPAL_E_INVAL, "VECTORS vel has 3 "
              "components; tvpal reads one value per point: --magnitude "
              "encodes the vector's length", NULL);
    check_bad("vectors-ascii.vtk", NULL, TVPAL_E_INVAL, "VECTORS vel has 3 "
              "components", NULL);
    check_bad("scalars3.vtk", NULL, TVPAL_E_INVAL, "SCALARS v3 has 3 "
              "components", NULL);
    check_bad("field.vtk", "grad", TVPAL_E_INVAL, "FIELD grad has 2 "
              "components", NULL);
    /* A FIELD array of POINT_DATA is a point array; one of CELL_DATA not;
     * the dataset's own FIELD (two-scalars' TIME) is no array at all. */
    static const char *const fp[] = {"field-p.f32"};
    check_good("field.vtk", "p", fp, 1, TVPAL_F64, NULL);
    check_good("field-ascii.vtk", "p", fp, 1, TVPAL_F64, NULL);
    check_bad("field.vtk", "cf", TVPAL_E_INVAL, "cf is cell FIELD", NULL);
    check_bad("two-scalars.vtk", "TIME", TVPAL_E_INVAL, "no point array "
              "TIME", NULL);
    describe_has("field.vtk", "\np double components=1 FIELD\n"
                 "grad float components=2 FIELD\n");
}

/* Vectors with magnitude: each point's length as make-vtk.py computes it,
 * whole and in boxes; the default array of a file without SCALARS is its
 * first VECTORS; a scalar array is read as it is. */
static void legacy_vectors(void)
{
    static const char *const vel[] = {"two-scalars-vel.f32"},
                             *const va[] = {"vectors-ascii.f32"},
                             *const s3[] = {"scalars3.f32"},
                             *const fg[] = {"field.f32"},
                             *const ta[] = {"two-scalars.f32"};
    struct tvpal_input_info info;
    g_magnitude = 1;
    memset(&info, 0, sizeof info);
    check_good("two-scalars.vtk", "vel", vel, 1, TVPAL_F32, &info);
    CHECK(info.components == 3 && !strcmp(info.var, "vel"), "two-scalars "
          "vel: %u components of %s", info.components, info.var);
    memset(&info, 0, sizeof info);
    check_good("vectors-ascii.vtk", NULL, va, 1, TVPAL_F32, &info);
    CHECK(!strcmp(info.var, "vel"), "vectors-ascii: default %s, expected "
          "vel (the first VECTORS)", info.var);
    check_good("scalars3.vtk", NULL, s3, 1, TVPAL_I16, NULL);
    check_good("field.vtk", "grad", fg, 1, TVPAL_F32, NULL);
    check_good("field-ascii.vtk", "grad", fg, 1, TVPAL_F32, NULL);
    memset(&info, 0, sizeof info);
    check_good("two-scalars.vtk", NULL, ta, 1, TVPAL_F32, &info);
    CHECK(info.components == 1 && !strcmp(info.var, "a"), "two-scalars "
          "with magnitude: %u components of %s", info.components, info.var);
    g_magnitude = 0;
}

/* A .pvti of vectors: the pieces' lengths in place; a piece of other
 * components than the .pvti says is refused naming both. */
static void pvti_vectors(void)
{
    static const char *const v[] = {"vectors.f32"};
    struct tvpal_input_info info;
    g_magnitude = 1;
    memset(&info, 0, sizeof info);
    check_good("vectors.pvti", NULL, v, 1, TVPAL_F32, &info);
    CHECK(info.components == 3 && !strcmp(info.var, "vel"), "vectors.pvti: "
          "%u components of %s (the active Vectors)", info.components,
          info.var);
    check_bad("bad-vectors.pvti", NULL, TVPAL_E_FORMAT,
              "vec-bad.vti: array vel has 2 components; the .pvti says 3",
              "bad-vectors.pvti");
    g_magnitude = 0;
    check_bad("vectors.pvti", NULL, TVPAL_E_INVAL, "array vel has 3 "
              "components (NumberOfComponents); tvpal reads one value per "
              "point: --magnitude", NULL);
    describe_has("vectors.pvti", "\nvel Float32 components=3 [active "
                 "vectors]\n");
}

/* A legacy BINARY file of nx x ny x nz points of ncomp big-endian values
 * of type (float or short) at path: rows past the 4 MiB a batch of box
 * reads holds. */
static void write_big_vtk(const char *path, const char *type, uint32_t nx,
                          uint32_t ny, uint32_t nz, unsigned ncomp)
{
    FILE *fp = fopen(path, "wb");
    REQUIRE(fp, "write %s", path);
    const size_t n = (size_t)nx * ny * nz;
    fprintf(fp, "# vtk DataFile Version 3.0\ntvpal test-vtk big\nBINARY\n"
            "DATASET STRUCTURED_POINTS\nDIMENSIONS %u %u %u\nSPACING 1 1 1"
            "\nORIGIN 0 0 0\nPOINT_DATA %zu\nSCALARS v %s %u\n"
            "LOOKUP_TABLE default\n", nx, ny, nz, n, type, ncomp);
    const int is_short = !strcmp(type, "short");
    for (size_t i = 0; i < n * ncomp; i++) {
        unsigned char b[4];
        if (is_short) {
            uint16_t u = (uint16_t)(int16_t)((int)(i * 7919 % 60001) - 30000);
            b[0] = (unsigned char)(u >> 8), b[1] = (unsigned char)u;
            fwrite(b, 1, 2, fp);
        } else {
            float f = (float)((double)(i * 7919 % 10007) * 0.01 - 50.0);
            uint32_t u;
            memcpy(&u, &f, 4);
            b[0] = (unsigned char)(u >> 24), b[1] = (unsigned char)(u >> 16);
            b[2] = (unsigned char)(u >> 8), b[3] = (unsigned char)u;
            fwrite(b, 1, 4, fp);
        }
    }
    fputc('\n', fp);
    REQUIRE(fclose(fp) == 0, "write %s", path);
}

/* Box reads of large legacy BINARY files against their whole reads. */
static void legacy_big(void)
{
    static const struct {
        const char *name, *type;
        uint32_t nx, ny, nz, ncomp;
    } big[] = {{"big-float.vtk", "float", 200, 100, 60, 1},
               {"big-short.vtk", "short", 150, 90, 50, 1},
               {"big-vec.vtk", "float", 120, 100, 60, 3}};
    for (size_t i = 0; i < sizeof big / sizeof *big; i++) {
        char *files[1] = {(char *)fixture(big[i].name)};
        write_big_vtk(files[0], big[i].type, big[i].nx, big[i].ny, big[i].nz,
                      big[i].ncomp);
        struct tvpal_input *in = NULL;
        struct tvpal_diag g = {{0}};
        const struct tvpal_input_opts opts = {.magnitude = big[i].ncomp > 1};
        int rc = tvpal_input_open(&in, TVPAL_IN_AUTO, files, 1, &opts, &g);
        CHECK(rc == 0, "%s: open: %s", big[i].name, g.msg);
        if (rc < 0)
            continue;
        tt_check_boxes_n(in, 6, big[i].name);
        tt_check_box_scratch(in, 1, big[i].name);
        tvpal_input_close(in);
    }
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
        printf("test-vtk: no python3 to write the fixtures: skipped\n");
        return 77;
    }
    snprintf(work, sizeof work, "%s/tests/work/test-vtk", build ? build : ".");
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s' && '%s' "
             "'%s/tests/make-vtk.py' '%s'", work, work, py, src ? src : ".",
             work);
    REQUIRE(system(cmd) == 0, "%s", cmd);
    legacy();   /* no library needed */
    legacy_vectors();
    legacy_big();
#if defined(HAVE_EXPAT) && defined(HAVE_ZLIB)
    pvd();
    pvti();
    pvti_vectors();
#else
    printf("built without expat or zlib: .pvd and .pvti not tested\n");
#endif
    int rc = tt_done("test-vtk");
    if (rc == 0) {
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", work);
        if (system(cmd) != 0)
            fprintf(stderr, "could not remove %s\n", work);
    }
    return rc;
}
