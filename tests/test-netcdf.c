/* test-netcdf: the NetCDF reader on fixtures ncgen makes from CDL text at
 * test time (classic, 64-bit offset, NetCDF-4 chunked and deflated): dims,
 * steps, values, CF missing values and packing, coordinates, time values,
 * the errors, describe, series of files; and the files of ../shared/data
 * when present.  Skipped (77) without NetCDF support or ncgen. */
#include "config.h"

#include "tvpal_input_impl.h"
#include "tvpal_test.h"
#include "tt_box.h"

#include <stdarg.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#ifndef HAVE_NETCDF
int main(void)
{
    printf("test-netcdf: built without NetCDF (libnetcdf-dev): skipped\n");
    return 77;
}
#else

static char work[1024];

static const char *wpath(const char *name)
{
    static char p[4][1200];
    static int i;
    i = (i + 1) % 4;
    snprintf(p[i], sizeof p[i], "%s/%s", work, name);
    return p[i];
}

/* Writes NAME.cdl from fmt and makes NAME.nc with ncgen -k KIND. */
static void gen(const char *name, const char *kind, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void gen(const char *name, const char *kind, const char *fmt, ...)
{
    char cdl[64], nc[64], cmd[3000];
    snprintf(cdl, sizeof cdl, "%s.cdl", name);
    snprintf(nc, sizeof nc, "%s.nc", name);
    FILE *fp = fopen(wpath(cdl), "w");
    REQUIRE(fp, "cannot write %s", wpath(cdl));
    va_list ap;
    va_start(ap, fmt);
    vfprintf(fp, fmt, ap);
    va_end(ap);
    REQUIRE(fclose(fp) == 0, "write %s", wpath(cdl));
    snprintf(cmd, sizeof cmd, "ncgen -k %s -o '%s' '%s'", kind, wpath(nc),
             wpath(cdl));
    REQUIRE(system(cmd) == 0, "%s failed", cmd);
}

/* Value i of step k in the fixtures (exact in float and in decimal). */
static float val(int k, int i)
{
    return (float)(k * 100 + 0.5 * i + 0.25);
}

/* "v, v, ..." of steps k0..k0+nk of n values each into s[SERIES_CAP], the
 * text fill in place of value fill_i of step fill_k (-1: none). */

#define SERIES_CAP 4096
static char *series_text(char *s, int k0, int nk, int n, int fill_k,
                         int fill_i, const char *fill)
{
    size_t len = 0, cap = SERIES_CAP;
    for (int k = k0; k < k0 + nk; k++)
        for (int i = 0; i < n; i++) {
            int last = k == k0 + nk - 1 && i == n - 1;
            if (k == fill_k && i == fill_i)
                len += (size_t)snprintf(s + len, cap - len, "%s%s", fill,
                                        last ? "" : ", ");
            else
                len += (size_t)snprintf(s + len, cap - len, "%.9g%s",
                                        val(k, i), last ? "" : ", ");
        }
    return s;
}

static struct tvpal_input *open1(const char *file, const char *var,
                                 const char *time_dim, int *rc,
                                 struct tvpal_diag *g)
{
    struct tvpal_input *in = NULL;
    char *files[1] = {(char *)file};
    struct tvpal_input_opts o = {.var = var, .time_dim = time_dim};
    g->msg[0] = 0;
    *rc = tvpal_input_open(&in, TVPAL_IN_AUTO, files, 1, &o, g);
    return *rc == 0 ? in : NULL;
}

static int same_float(float a, float b)
{
    return (isnan(a) && isnan(b)) || a == b;
}

/* Classic file: unlimited time with CF coordinate, uniform and not
 * uniform axes, _FillValue, a 3-D variable on time (2 spatial dims) and
 * a 2-D one. */
static void test_classic(void)
{
    char t[SERIES_CAP], p[SERIES_CAP];
    gen("a", "nc3",
        "netcdf a {\n"
        "dimensions:\n time = UNLIMITED ;\n z = 2 ;\n y = 3 ;\n x = 4 ;\n"
        "variables:\n"
        " double time(time) ;\n  time:units = \"hours since 2005-08-28 00:00:00\" ;\n"
        " float z(z) ;\n float y(y) ;\n double x(x) ;\n"
        " float T(time, z, y, x) ;\n  T:units = \"K\" ;\n  T:_FillValue = -999.f ;\n"
        " float Psurf(time, y, x) ;\n"
        " float Flat(y, x) ;\n"
        "data:\n"
        " time = 0, 6, 30 ;\n z = 100, 300 ;\n y = 0, 1, 5 ;\n x = 0.5, 1, 1.5, 2 ;\n"
        " T = %s ;\n Psurf = %s ;\n"
        " Flat = 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12 ;\n}\n",
        series_text(t, 0, 3, 24, 1, 5, "-999"),
        series_text(p, 0, 3, 12, -1, -1, ""));

    struct tvpal_diag g;
    int rc;
    struct tvpal_input *in = open1(wpath("a.nc"), NULL, NULL, &rc, &g);
    REQUIRE(in, "open a.nc: %d %s", rc, g.msg);
    const struct tvpal_input_info *fi = tvpal_input_info(in);
    CHECK(fi->dims[0] == 4 && fi->dims[1] == 3 && fi->dims[2] == 2, "dims %ux%ux%u",
          fi->dims[0], fi->dims[1], fi->dims[2]);
    CHECK(fi->steps == 3, "steps %u", fi->steps);
    CHECK(!strcmp(fi->var, "T"), "var %s (the only candidate)", fi->var);
    CHECK(fi->type == TVPAL_F32, "type");
    CHECK(!strcmp(fi->units, "K"), "units %s", fi->units);
    CHECK(!strcmp(fi->dim_names[0], "x") && !strcmp(fi->dim_names[1], "y") &&
          !strcmp(fi->dim_names[2], "z"), "dim names");
    CHECK(fi->missing_attrs == 1, "missing_attrs");
    CHECK(!fi->nonuniform[0] && fi->spacing[0] == 0.5 && fi->origin[0] == 0.5,
          "x uniform: %g %g", fi->spacing[0], fi->origin[0]);
    CHECK(fi->nonuniform[1] && fi->spacing[1] == 1 && fi->origin[1] == 0,
          "y not uniform");
    CHECK(!fi->nonuniform[2] && fi->spacing[2] == 200 && fi->origin[2] == 100,
          "z uniform: %g %g", fi->spacing[2], fi->origin[2]);
    CHECK(fi->has_times && !strcmp(fi->time_units, "hours since 2005-08-28 00:00:00"),
          "time units %s", fi->time_units);
    CHECK(tvpal_input_time(in, 0) == 0 && tvpal_input_time(in, 1) == 6 &&
          tvpal_input_time(in, 2) == 30, "times");
    float buf[24];
    for (uint32_t k = 0; k < 3; k++) {
        REQUIRE(tvpal_input_read(in, k, buf, &g) == 0, "read %u: %s", k, g.msg);
        int bad = 0;
        for (int i = 0; i < 24; i++) {
            float want = (k == 1 && i == 5) ? NAN : val((int)k, i);
            bad += !same_float(buf[i], want);
        }
        CHECK(!bad, "step %u: %d values differ", k, bad);
    }
    CHECK(tvpal_input_read(in, 3, buf, &g) == TVPAL_E_INVAL, "step past the end");
    tt_check_boxes(in, "a.nc T");
    const uint32_t slice[3] = {4, 3, 1};
    CHECK(tvpal_input_box_scratch(in, slice) == 0, "classic float: a box "
          "needs no scratch (%llu)",
          (unsigned long long)tvpal_input_box_scratch(in, slice));
    tvpal_input_close(in);

    /* Errors: an unknown variable lists them; fewer than 3 spatial dims. */
    CHECK(!open1(wpath("a.nc"), "nope", NULL, &rc, &g) && rc == TVPAL_E_INVAL &&
          strstr(g.msg, "nope") && strstr(g.msg, "T(time,z,y,x)") &&
          strstr(g.msg, "Psurf(time,y,x)") && strstr(g.msg, "Flat(y,x)"),
          "unknown var: %d %s", rc, g.msg);
    CHECK(!open1(wpath("a.nc"), "Flat", NULL, &rc, &g) && rc == TVPAL_E_INVAL &&
          strstr(g.msg, "Flat(y,x)") && strstr(g.msg, "2 dims"),
          "2-D var: %d %s", rc, g.msg);
    CHECK(!open1(wpath("a.nc"), "Psurf", NULL, &rc, &g) && rc == TVPAL_E_INVAL &&
          strstr(g.msg, "fewer than 3 spatial"), "time + 2-D: %d %s", rc, g.msg);
    CHECK(!open1(wpath("a.nc"), "T", "level", &rc, &g) && rc == TVPAL_E_INVAL &&
          strstr(g.msg, "level"), "bad time dim: %d %s", rc, g.msg);
    CHECK(!open1(wpath("a.nc"), "T", "x", &rc, &g) && rc == TVPAL_E_INVAL,
          "time dim among z, y, x: %d %s", rc, g.msg);
    in = open1(wpath("a.nc"), "T", "time", &rc, &g);
    CHECK(in && tvpal_input_info(in)->steps == 3, "--time-dim time: %s", g.msg);
    tvpal_input_close(in);

    char *text = NULL;
    CHECK(tvpal_input_describe(wpath("a.nc"), TVPAL_IN_AUTO, &text, &g) == 0,
          "describe: %s", g.msg);
    CHECK(text && !strncmp(text, "netcdf classic\n", 15), "describe format: %s", text);
    CHECK(text && strstr(text, "T(time=3, z=2, y=3, x=4) float units=\"K\"\n"),
          "describe T: %s", text);
    CHECK(text && strstr(text, "Psurf(") && strstr(text, "Flat(y=3, x=4) float") &&
          strstr(text, "time(time=3) double units=\"hours since") &&
          strstr(text, "x(x=4) double units=\"\" coordinate"),
          "describe all: %s", text);
    free(text);
}

/* 64-bit offset, 3-D variables (one step each): valid_range and a
 * missing_value vector on a float, a packed short with a fill value, a
 * packed short whose valid_min is in unpacked units. */
static void test_64bit(void)
{
    gen("b", "nc6",
        "netcdf b {\n"
        "dimensions:\n z = 2 ;\n y = 2 ;\n x = 3 ;\n"
        "variables:\n"
        " float A(z, y, x) ;\n  A:valid_range = 0.f, 10.f ;\n"
        "  A:missing_value = 7.f, 8.f ;\n"
        " short P(z, y, x) ;\n  P:scale_factor = 0.5 ;\n  P:add_offset = 100. ;\n"
        "  P:_FillValue = -32767s ;\n  P:units = \"m\" ;\n"
        " short Q(z, y, x) ;\n  Q:scale_factor = 0.25f ;\n  Q:add_offset = 10.f ;\n"
        "  Q:valid_min = 10.f ;\n"
        "data:\n"
        " A = -1, 0, 5, 10, 10.5, 3, 7, 8, 7.5, 1e30, 2.25, 9.75 ;\n"
        " P = 0, 1, -3, 200, -32767, 32000, -32000, 7, 9, 11, 13, 15 ;\n"
        " Q = -4, -1, 0, 1, 2, 400, 5, 6, 7, 8, 9, 10 ;\n"
        "}\n");
    struct tvpal_diag g;
    int rc;
    float buf[12];
    CHECK(!open1(wpath("b.nc"), NULL, NULL, &rc, &g) && rc == TVPAL_E_INVAL &&
          strstr(g.msg, "variables: A(z,y,x), P(z,y,x), Q(z,y,x)"),
          "several candidates: %d %s", rc, g.msg);

    struct tvpal_input *in = open1(wpath("b.nc"), "A", NULL, &rc, &g);
    REQUIRE(in, "open A: %s", g.msg);
    const struct tvpal_input_info *fi = tvpal_input_info(in);
    CHECK(fi->steps == 1 && fi->dims[0] == 3 && fi->dims[1] == 2 && fi->dims[2] == 2,
          "3-D var: one step, dims");
    CHECK(fi->missing_attrs == 1 && !fi->has_times && fi->type == TVPAL_F32, "A info");
    CHECK(tvpal_input_read(in, 0, buf, &g) == 0, "read A: %s", g.msg);
    static const float wa[12] = {NAN, 0, 5, 10, NAN, 3, NAN, NAN, 7.5f, NAN,
                                 2.25f, 9.75f};
    for (int i = 0; i < 12; i++)
        CHECK(same_float(buf[i], wa[i]), "A[%d] = %g, want %g", i, buf[i], wa[i]);
    tt_check_boxes(in, "b.nc A");
    tvpal_input_close(in);

    in = open1(wpath("b.nc"), "P", NULL, &rc, &g);
    REQUIRE(in, "open P: %s", g.msg);
    fi = tvpal_input_info(in);
    CHECK(fi->type == TVPAL_F32 && fi->missing_attrs == 1 && !strcmp(fi->units, "m"),
          "P: packed is f32");
    CHECK(tvpal_input_read(in, 0, buf, &g) == 0, "read P: %s", g.msg);
    static const short sp[12] = {0, 1, -3, 200, -32767, 32000, -32000, 7, 9, 11,
                                 13, 15};
    for (int i = 0; i < 12; i++) {
        float want = sp[i] == -32767 ? NAN : (float)(sp[i] * 0.5 + 100.0);
        CHECK(same_float(buf[i], want), "P[%d] = %g, want %g", i, buf[i], want);
    }
    tt_check_boxes(in, "b.nc P");
    tvpal_input_close(in);

    /* valid_min of the unpacked type (float, like scale_factor): applies to
     * unpacked values: -4 -> 9, -1 -> 9.75 are out. */
    in = open1(wpath("b.nc"), "Q", NULL, &rc, &g);
    REQUIRE(in, "open Q: %s", g.msg);
    CHECK(tvpal_input_read(in, 0, buf, &g) == 0, "read Q: %s", g.msg);
    static const short sq[12] = {-4, -1, 0, 1, 2, 400, 5, 6, 7, 8, 9, 10};
    for (int i = 0; i < 12; i++) {
        float want = sq[i] < 0 ? NAN : (float)(sq[i] * (double)0.25f + 10.0);
        CHECK(same_float(buf[i], want), "Q[%d] = %g, want %g", i, buf[i], want);
    }
    tt_check_boxes(in, "b.nc Q");
    tvpal_input_close(in);

    char *text = NULL;
    CHECK(tvpal_input_describe(wpath("b.nc"), TVPAL_IN_NETCDF, &text, &g) == 0 &&
          !strncmp(text, "netcdf 64-bit offset\n", 21) &&
          strstr(text, "A(z=2, y=2, x=3) float") && strstr(text, "P(z=2, y=2, x=3) short units=\"m\"") &&
          strstr(text, "Q("), "describe b: %s", text ? text : g.msg);
    free(text);

    /* CDF-5: the unsigned types */
    gen("d", "nc5",
        "netcdf d {\n"
        "dimensions:\n z = 2 ;\n y = 2 ;\n x = 3 ;\n"
        "variables:\n ubyte B(z, y, x) ;\n ushort U(z, y, x) ;\n"
        "  U:_FillValue = 65535US ;\n"
        "data:\n"
        " B = 0, 1, 2, 3, 4, 5, 250, 251, 252, 253, 254, 255 ;\n"
        " U = 0, 1, 2, 3, 4, 5, 60000, 65534, 65535, 9, 10, 11 ;\n"
        "}\n");
    in = open1(wpath("d.nc"), "B", NULL, &rc, &g);
    REQUIRE(in, "open B: %s", g.msg);
    CHECK(tvpal_input_info(in)->type == TVPAL_U8 &&
          !tvpal_input_info(in)->missing_attrs, "B: u8, no missing attrs");
    CHECK(tvpal_input_read(in, 0, buf, &g) == 0 && buf[0] == 0 && buf[6] == 250 &&
          buf[11] == 255, "read B");
    tt_check_boxes(in, "d.nc B");
    tvpal_input_close(in);
    in = open1(wpath("d.nc"), "U", NULL, &rc, &g);
    REQUIRE(in, "open U: %s", g.msg);
    CHECK(tvpal_input_info(in)->type == TVPAL_U16 &&
          tvpal_input_info(in)->missing_attrs, "U: u16, missing attrs");
    CHECK(tvpal_input_read(in, 0, buf, &g) == 0 && buf[6] == 60000 &&
          buf[7] == 65534 && isnan(buf[8]) && buf[11] == 11, "read U");
    tt_check_boxes(in, "d.nc U");
    tvpal_input_close(in);
    CHECK(tvpal_input_describe(wpath("d.nc"), TVPAL_IN_AUTO, &text, &g) == 0 &&
          !strncmp(text, "netcdf cdf5\n", 12) && strstr(text, "B(z=2, y=2, x=3) ubyte") &&
          strstr(text, "U(z=2, y=2, x=3) ushort"), "describe d: %s", text ? text : g.msg);
    free(text);
}

/* NetCDF-4: a chunked and deflated variable whose time dim is neither
 * unlimited nor a coordinate (the first of 4 dims); extra dims. */
static void test_netcdf4(void)
{
    char v[SERIES_CAP], w[SERIES_CAP], x[SERIES_CAP], cmd[1200];
    gen("c", "nc4",
        "netcdf c {\n"
        "dimensions:\n step = 3 ;\n one = 1 ;\n two = 2 ;\n lev = 2 ;\n"
        " lat = 3 ;\n lon = 5 ;\n"
        "variables:\n"
        " float V(step, lev, lat, lon) ;\n  V:_ChunkSizes = 1, 2, 3, 5 ;\n"
        "  V:_DeflateLevel = 4 ;\n  V:units = \"m s-1\" ;\n"
        " double W(step, one, lev, lat, lon) ;\n"
        " float E(step, two, lev, lat, lon) ;\n"
        " float S(step, lev, lat, lon) ;\n  S:_ChunkSizes = 1, 1, 2, 3 ;\n"
        "  S:_DeflateLevel = 1 ;\n  S:_Shuffle = \"true\" ;\n"
        " int lev(lev) ;\n"
        "data:\n"
        " V = %s ;\n W = %s ;\n S = %s ;\n lev = 10, 20 ;\n}\n",
        series_text(v, 0, 3, 30, 2, 29, "1e30"),
        series_text(w, 0, 3, 30, -1, -1, ""),
        series_text(x, 0, 3, 30, -1, -1, ""));
    snprintf(cmd, sizeof cmd, "ncdump -hs '%s' | grep -q 'V:_DeflateLevel = 4'",
             wpath("c.nc"));
    CHECK(system(cmd) == 0, "c.nc has a deflated V");

    struct tvpal_diag g;
    int rc;
    float buf[30];
    const uint64_t chunks0 = tvpal_input_inflated_chunks();
    struct tvpal_input *in = open1(wpath("c.nc"), "V", NULL, &rc, &g);
    REQUIRE(in, "open V: %s", g.msg);
    const struct tvpal_input_info *fi = tvpal_input_info(in);
    CHECK(fi->dims[0] == 5 && fi->dims[1] == 3 && fi->dims[2] == 2 && fi->steps == 3,
          "V dims %ux%ux%u steps %u", fi->dims[0], fi->dims[1], fi->dims[2], fi->steps);
    CHECK(!fi->has_times && !fi->missing_attrs, "V: no times, no missing attrs");
    CHECK(fi->spacing[2] == 10 && fi->origin[2] == 10 && !fi->nonuniform[2] &&
          fi->spacing[0] == 1 && fi->origin[0] == 0, "lev spacing");
    for (uint32_t k = 0; k < 3; k++) {
        REQUIRE(tvpal_input_read(in, k, buf, &g) == 0, "read V %u: %s", k, g.msg);
        int bad = 0;
        for (int i = 0; i < 30; i++)
            bad += buf[i] != (k == 2 && i == 29 ? 1e30f : val((int)k, i));
        CHECK(!bad, "V step %u: %d differ", k, bad);
    }
    tvpal_input_close(in);
    /* Deflated float chunks are read directly (tvpal_in_hdf5.c) and
     * inflated by tvpal_inflate, not by the library: one per step. */
#ifdef HAVE_HDF5
    CHECK(tvpal_input_inflated_chunks() == chunks0 + 3,
          "V: 3 chunks inflated directly (%llu)",
          (unsigned long long)(tvpal_input_inflated_chunks() - chunks0));
#endif
    /* Shuffled, 2 x 2 x 2 chunks per step cut at the edges. */
    in = open1(wpath("c.nc"), "S", NULL, &rc, &g);
    REQUIRE(in, "open S: %s", g.msg);
    for (uint32_t k = 0; k < 3; k++) {
        REQUIRE(tvpal_input_read(in, k, buf, &g) == 0, "read S %u: %s", k, g.msg);
        int bad = 0;
        for (int i = 0; i < 30; i++)
            bad += buf[i] != val((int)k, i);
        CHECK(!bad, "S step %u (shuffled, edge chunks): %d differ", k, bad);
    }
    tvpal_input_close(in);
#ifdef HAVE_HDF5
    CHECK(tvpal_input_inflated_chunks() == chunks0 + 3 + 3 * 8,
          "S: 8 chunks a step inflated directly (%llu in all)",
          (unsigned long long)(tvpal_input_inflated_chunks() - chunks0));
#endif

    in = open1(wpath("c.nc"), "W", NULL, &rc, &g);
    REQUIRE(in, "open W (an extra dim of length 1): %s", g.msg);
    fi = tvpal_input_info(in);
    CHECK(fi->steps == 3 && fi->type == TVPAL_F64 && fi->dims[2] == 2, "W info");
    CHECK(tvpal_input_read(in, 1, buf, &g) == 0 && buf[0] == val(1, 0) &&
          buf[29] == val(1, 29), "read W");
    tt_check_boxes(in, "c.nc W");
    tvpal_input_close(in);

    /* Box reads of the deflated V and S (read directly, where built so):
     * a voxel's box inflates the one chunk it is in. */
    static const char *const vs[] = {"V", "S"};
    for (int i = 0; i < 2; i++) {
        in = open1(wpath("c.nc"), vs[i], NULL, &rc, &g);
        REQUIRE(in, "open %s: %s", vs[i], g.msg);
        char name[16];
        snprintf(name, sizeof name, "c.nc %s", vs[i]);
        tt_check_boxes(in, name);
        const uint32_t lo[3] = {4, 2, 1}, one[3] = {1, 1, 1};
        const uint64_t c1 = tvpal_input_inflated_chunks();
        CHECK(tvpal_input_read_box(in, 1, lo, one, buf, &g) == 0 &&
              buf[0] == val(1, 29), "%s: a voxel's box: %s", vs[i], g.msg);
#ifdef HAVE_HDF5
        CHECK(tvpal_input_inflated_chunks() - c1 == 1, "%s: a voxel's box "
              "inflates one chunk (%llu)", vs[i],
              (unsigned long long)(tvpal_input_inflated_chunks() - c1));
#else
        (void)c1;
#endif
        tvpal_input_close(in);
    }
    CHECK(!open1(wpath("c.nc"), "E", NULL, &rc, &g) && rc == TVPAL_E_INVAL &&
          strstr(g.msg, "two"), "extra dim of length 2: %d %s", rc, g.msg);

    char *text = NULL;
    CHECK(tvpal_input_describe(wpath("c.nc"), TVPAL_IN_AUTO, &text, &g) == 0 &&
          !strncmp(text, "netcdf netcdf-4\n", 16) &&
          strstr(text, "V(step=3, lev=2, lat=3, lon=5) float units=\"m s-1\"") &&
          strstr(text, "W(") && strstr(text, "E(") &&
          strstr(text, "lev(lev=2) int units=\"\" coordinate"),
          "describe c: %s", text ? text : g.msg);
    free(text);
}

/* A series: two files of two steps each; a file with other dims. */
static void test_series(void)
{
    static const char *hdr =
        "dimensions:\n time = UNLIMITED ;\n z = 2 ;\n y = 2 ;\n x = %d ;\n"
        "variables:\n float time(time) ;\n  time:units = \"days since 2000-01-01\" ;\n"
        " float T(time, z, y, x) ;\n";
    char h[512], text[SERIES_CAP];
    snprintf(h, sizeof h, hdr, 3);
    gen("s1", "nc3", "netcdf s1 {\n%sdata:\n time = 0, 1 ;\n T = %s ;\n}\n", h,
        series_text(text, 0, 2, 12, -1, -1, ""));
    gen("s2", "nc4", "netcdf s2 {\n%sdata:\n time = 2, 3 ;\n T = %s ;\n}\n", h,
        series_text(text, 2, 2, 12, -1, -1, ""));
    snprintf(h, sizeof h, hdr, 4);
    gen("s3", "nc3", "netcdf s3 {\n%sdata:\n time = 4, 5 ;\n T = %s ;\n}\n", h,
        series_text(text, 4, 2, 16, -1, -1, ""));

    struct tvpal_diag g = {{0}};
    struct tvpal_input *in = NULL;
    char *files[3] = {(char *)wpath("s1.nc"), (char *)wpath("s2.nc"),
                      (char *)wpath("s3.nc")};
    int rc = tvpal_input_open(&in, TVPAL_IN_AUTO, files, 2, NULL, &g);
    REQUIRE(rc == 0, "series: %d %s", rc, g.msg);
    CHECK(tvpal_input_info(in)->steps == 4, "4 steps");
    float buf[12];
    for (uint32_t t = 0; t < 4; t++) {
        uint32_t k;
        const char *file = tvpal_input_file(in, t, &k);
        CHECK(file && !strcmp(file, files[t / 2]) && k == t % 2, "file of step %u", t);
        CHECK(tvpal_input_time(in, t) == t, "time of %u", t);
        REQUIRE(tvpal_input_read(in, t, buf, &g) == 0, "read %u: %s", t, g.msg);
        int bad = 0;
        for (int i = 0; i < 12; i++)
            bad += buf[i] != val((int)t, i);
        CHECK(!bad, "series step %u: %d differ", t, bad);
    }
    /* back to the first file */
    CHECK(tvpal_input_read(in, 0, buf, &g) == 0 && buf[3] == val(0, 3), "reread 0");
    tt_check_boxes(in, "series s1.nc s2.nc");
    tvpal_input_close(in);

    in = NULL;
    rc = tvpal_input_open(&in, TVPAL_IN_AUTO, files, 3, NULL, &g);
    CHECK(rc == TVPAL_E_MISMATCH && !in && strstr(g.msg, "s3.nc"),
          "other dims: %d %s", rc, g.msg);
}

static void test_not_netcdf(void)
{
    FILE *fp = fopen(wpath("not.nc"), "w");
    REQUIRE(fp, "write not.nc");
    fputs("this is not a NetCDF file\n", fp);
    fclose(fp);
    struct tvpal_diag g;
    struct tvpal_input_file *f = NULL;
    struct tvpal_input_info fi = {.spacing = {1, 1, 1}};
    const struct tvpal_input_opts none = {0};
    double *times = NULL;
    int rc = tvpal_input_netcdf.open(&f, wpath("not.nc"), &none, &fi, &times, &g);
    CHECK(rc == TVPAL_E_FORMAT && !f && strstr(g.msg, "not.nc"),
          "not netcdf: %d %s", rc, g.msg);
    char *files[1] = {(char *)wpath("not.nc")};
    struct tvpal_input *in = NULL;
    rc = tvpal_input_open(&in, TVPAL_IN_NETCDF, files, 1, NULL, &g);
    CHECK(rc == TVPAL_E_FORMAT && !in, "series of a non-netcdf: %d %s", rc, g.msg);
    char *text = NULL;
    CHECK(tvpal_input_describe(wpath("not.nc"), TVPAL_IN_NETCDF, &text, &g) ==
          TVPAL_E_FORMAT && !text, "describe not netcdf");
    rc = tvpal_input_netcdf.open(&f, wpath("absent.nc"), &none, &fi, &times, &g);
    CHECK(rc == TVPAL_E_OPEN && strstr(g.msg, "absent.nc"), "absent: %d %s", rc, g.msg);
}

/* The real files of ../shared/data/netcdf, where present. */
static int test_shared(void)
{
    const char *sh = getenv("TVPAL_SHARED");
    const char *src = getenv("TVPAL_SRCDIR");
    char dir[1024];
    if (sh)
        snprintf(dir, sizeof dir, "%s/data/netcdf", sh);
    else
        snprintf(dir, sizeof dir, "%s/../shared/data/netcdf", src ? src : ".");
    char contour[1100], merc[1100];
    snprintf(contour, sizeof contour, "%s/contour.cdf", dir);
    snprintf(merc, sizeof merc, "%s/mercator_sample.nc", dir);
    if (access(contour, R_OK) || access(merc, R_OK)) {
        printf("test-netcdf: no %s: the real files are not tested\n", dir);
        return 0;
    }
    struct tvpal_diag g;
    int rc;
    CHECK(!open1(contour, NULL, NULL, &rc, &g) && rc == TVPAL_E_INVAL &&
          strstr(g.msg, "T(frtime,level,lat,lon)") &&
          strstr(g.msg, "Z(frtime,level,lat,lon)"), "contour, no var: %s", g.msg);
    struct tvpal_input *in = open1(contour, "T", NULL, &rc, &g);
    REQUIRE(in, "contour T: %s", g.msg);
    const struct tvpal_input_info *fi = tvpal_input_info(in);
    CHECK(fi->dims[0] == 36 && fi->dims[1] == 33 && fi->dims[2] == 10 &&
          fi->steps == 7, "contour T %ux%ux%u x %u", fi->dims[0], fi->dims[1],
          fi->dims[2], fi->steps);
    CHECK(fi->missing_attrs && fi->nonuniform[2] && !strcmp(fi->dim_names[2], "level"),
          "contour: missing attrs, non-uniform levels");
    CHECK(fi->has_times && tvpal_input_time(in, 1) == 6 &&
          tvpal_input_time(in, 6) == 48 && !strcmp(fi->time_units, "hours"),
          "contour times (%s)", fi->time_units);
    float *buf = malloc(sizeof *buf * 49 * 48 * 14);   /* the largest */
    REQUIRE(buf, "malloc");
    size_t out = 0, nan = 0;
    for (uint32_t t = 0; t < 7; t++) {
        REQUIRE(tvpal_input_read(in, t, buf, &g) == 0, "contour read %u: %s", t, g.msg);
        for (size_t i = 0; i < 36 * 33 * 10; i++)
            nan += isnan(buf[i]), out += !isnan(buf[i]) && (buf[i] < 0 || buf[i] > 400);
    }
    CHECK(out == 0, "contour: %zu values outside valid_range", out);
    printf("test-netcdf: contour T: %zu missing voxels\n", nan);
    tt_check_boxes_n(in, 8, "contour T");
    tvpal_input_close(in);

    in = open1(merc, "T", NULL, &rc, &g);
    REQUIRE(in, "mercator T: %s", g.msg);
    fi = tvpal_input_info(in);
    CHECK(fi->dims[0] == 48 && fi->dims[1] == 48 && fi->dims[2] == 14 &&
          fi->steps == 4, "mercator T %ux%ux%u x %u", fi->dims[0], fi->dims[1],
          fi->dims[2], fi->steps);
    CHECK(fi->has_times && strstr(fi->time_units, "minutes since"),
          "mercator times from XTIME (%s)", fi->time_units);
    REQUIRE(tvpal_input_read(in, 3, buf, &g) == 0, "mercator read: %s", g.msg);
    tt_check_boxes_n(in, 8, "mercator T");
    tvpal_input_close(in);
    in = open1(merc, "U", NULL, &rc, &g);
    REQUIRE(in, "mercator U: %s", g.msg);
    fi = tvpal_input_info(in);
    CHECK(fi->dims[0] == 49 && fi->dims[1] == 48 && fi->dims[2] == 14 &&
          !strcmp(fi->dim_names[0], "west_east_stag"), "U on its staggered x");
    REQUIRE(tvpal_input_read(in, 0, buf, &g) == 0, "mercator U read: %s", g.msg);
    tt_check_boxes_n(in, 8, "mercator U");
    tvpal_input_close(in);
    CHECK(!open1(merc, "nope", NULL, &rc, &g) && rc == TVPAL_E_INVAL &&
          strstr(g.msg, "Times(Time,DateStrLen)"), "mercator unknown var: %s", g.msg);
    char *text = NULL;
    CHECK(tvpal_input_describe(merc, TVPAL_IN_AUTO, &text, &g) == 0 &&
          !strncmp(text, "netcdf netcdf-4\n", 16) &&
          strstr(text, "QVAPOR(Time=4, bottom_top=14, south_north=48, west_east=48) "
                 "float units=\"kg kg-1\""), "describe mercator");
    free(text);
    free(buf);
    return 1;
}

int main(void)
{
    if (system("ncgen -version >/dev/null 2>&1 || command -v ncgen >/dev/null 2>&1")) {
        printf("test-netcdf: no ncgen (Debian netcdf-bin): skipped\n");
        return 77;
    }
    const char *b = getenv("TVPAL_BUILDDIR");
    snprintf(work, sizeof work, "%s/tests/work/test-netcdf", b ? b : ".");
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s'", work, work);
    REQUIRE(system(cmd) == 0, "%s", cmd);

    test_classic();
    test_64bit();
    test_netcdf4();
    test_series();
    test_not_netcdf();
    test_shared();
    int rc = tt_done("test-netcdf");
    if (rc == 0) {
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", work);
        if (system(cmd) != 0)
            fprintf(stderr, "could not remove %s\n", work);
    }
    return rc;
}
#endif
