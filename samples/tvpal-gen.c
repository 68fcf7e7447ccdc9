/* tvpal-gen: deterministic analytic time-varying fields as raw float32
 * (little-endian, x fastest), one file per timestep, any size.  Used by the
 * tests, the demo and the benchmarks.  Output depends only on the options
 * (field, dims, steps, seed), never on the machine or the thread count.
 *
 * The steps of main: parse and check the options, create the output
 * directory, then per timestep compute the field (gen_step) and write it,
 * to its own file or appended to the --single file. */
#define _GNU_SOURCE
#include "tvpal_cli.h"
#include "tvpal_format.h"
#include "tvpal_fs.h"
#include "tvpal_raw.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG "tvpal-gen"

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " --field NAME --dims NXxNYxNZ --steps T -o DIR [options]\n"
"Write a deterministic analytic time-varying field as raw little-endian\n"
"float32 volumes (x fastest): DIR/NAME_t0000.f32, DIR/NAME_t0001.f32, ...\n"
"\n"
"Fields:\n"
"  blobs       smooth: Gaussian blobs moving on circular paths\n"
"  turbulence  turbulent-looking: sum of advected value-noise octaves\n"
"  front       a sharp moving front (shock-like) with a wrinkled surface\n"
"  constant    the same value everywhere, every step (see --value)\n"
"\n"
"Options:\n"
"  -f, --field NAME     field to write (required)\n"
"  -d, --dims NXxNYxNZ  volume size (required)\n"
"  -s, --steps T        number of timesteps (required)\n"
"  -o, --output DIR     output directory, created if missing (required)\n"
"      --single FILE    write all timesteps into one file instead\n"
"      --prefix NAME    file name prefix (default: the field name)\n"
"      --seed S         seed for blob paths and noise (default 1)\n"
"      --value V        value of the constant field (default 1.5)\n"
"  -h, --help           this help\n"
"  -V, --version        version\n");
}

enum field { BLOBS, TURB, FRONT, CONST };

/* What a timestep's values depend on. */
struct gen {
    enum field field;
    uint32_t dims[3], steps, seed;
    double value;                 /* of the constant field */
};

/* ------------------------------------------------------------------------
 * The fields
 */

/* Integer hash (lowbias32, Chris Wellons) for lattice noise. */
static uint32_t hash32(uint32_t x)
{
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

static double lattice(uint32_t seed, int i, int j, int k)
{
    uint32_t h = hash32((uint32_t)i * 73856093u ^ hash32((uint32_t)j * 19349663u ^
                        hash32((uint32_t)k * 83492791u ^ seed)));
    return (double)h / 4294967295.0 * 2.0 - 1.0;
}

static double smooth(double t)
{
    return t * t * t * (t * (t * 6 - 15) + 10);
}

/* Trilinear value noise with quintic fade, in [-1, 1]. */
static double vnoise(uint32_t seed, double x, double y, double z)
{
    double fx = floor(x), fy = floor(y), fz = floor(z);
    int i = (int)fx, j = (int)fy, k = (int)fz;
    double u = smooth(x - fx), v = smooth(y - fy), w = smooth(z - fz);
    double c[2][2][2];
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++)
            for (int d = 0; d < 2; d++)
                c[a][b][d] = lattice(seed, i + a, j + b, k + d);
    double x00 = c[0][0][0] + u * (c[1][0][0] - c[0][0][0]);
    double x10 = c[0][1][0] + u * (c[1][1][0] - c[0][1][0]);
    double x01 = c[0][0][1] + u * (c[1][0][1] - c[0][0][1]);
    double x11 = c[0][1][1] + u * (c[1][1][1] - c[0][1][1]);
    double y0 = x00 + v * (x10 - x00), y1 = x01 + v * (x11 - x01);
    return y0 + w * (y1 - y0);
}

#define NBLOBS 6

static void gen_constant(const struct gen *g, float *out)
{
    size_t n = (size_t)g->dims[0] * g->dims[1] * g->dims[2];
    for (size_t i = 0; i < n; i++)
        out[i] = (float)g->value;
}

/* Blob b at time tt: its amplitude, and its separable factors
 * exp(-|p-c|^2/s^2) = ex(x) ey(y) ez(z) along each axis (nx, ny, nz
 * entries at ex, ey, ez). */
static double blob_tables(const struct gen *g, int b, double tt, double *ex,
                          double *ey, double *ez)
{
    const uint32_t nx = g->dims[0], ny = g->dims[1], nz = g->dims[2];
    uint32_t h = hash32(g->seed * 1000u + (uint32_t)b);
    double ph = (h & 0xFFFF) / 65536.0 * 2 * M_PI;
    double sp = 0.02 + 0.03 * ((h >> 16) & 0xFF) / 255.0;
    double rad = 0.15 + 0.2 * ((h >> 24) & 0xFF) / 255.0;
    double cx = 0.5 + rad * cos(ph + sp * tt);
    double cy = 0.5 + rad * sin(ph + sp * tt);
    double cz = 0.5 + 0.3 * sin(0.7 * ph + 0.5 * sp * tt);
    double s = 0.08 + 0.06 * (b % 3) / 2.0;
    for (uint32_t i = 0; i < nx; i++) {
        double d = (i + 0.5) / nx - cx;
        ex[i] = exp(-d * d / (s * s));
    }
    for (uint32_t i = 0; i < ny; i++) {
        double d = (i + 0.5) / ny - cy;
        ey[i] = exp(-d * d / (s * s));
    }
    for (uint32_t i = 0; i < nz; i++) {
        double d = (i + 0.5) / nz - cz;
        ez[i] = exp(-d * d / (s * s));
    }
    return 0.6 + 0.4 * ((b * 37) % 7) / 6.0;
}

/* Gaussian blobs on circular paths.  Separable: per-blob 1D tables make
 * this cheap for large volumes. */
static void gen_blobs(const struct gen *g, uint32_t t, float *out)
{
    const uint32_t nx = g->dims[0], ny = g->dims[1], nz = g->dims[2];
    double *ex = malloc(sizeof(double) * NBLOBS * (nx + ny + nz));
    if (!ex)
        abort();
    double *ey = ex + NBLOBS * nx, *ez = ey + NBLOBS * ny;
    double amp[NBLOBS];
    for (int b = 0; b < NBLOBS; b++)
        amp[b] = blob_tables(g, b, (double)t, ex + b * nx, ey + b * ny,
                             ez + b * nz);
#ifdef _OPENMP
#pragma omp parallel for schedule(static)
#endif
    for (uint32_t z = 0; z < nz; z++)
        for (uint32_t y = 0; y < ny; y++) {
            float *row = out + (size_t)nx * (y + (size_t)ny * z);
            for (uint32_t x = 0; x < nx; x++) {
                double v = 0;
                for (int b = 0; b < NBLOBS; b++)
                    v += amp[b] * ex[b * nx + x] * ey[b * ny + y] *
                         ez[b * nz + z];
                row[x] = (float)v;
            }
        }
    free(ex);
}

/* Turbulence at cell centre (px, py, pz) and time tt: octave o is advected
 * with its own velocity, so the scales move relative to each other. */
static double turbulence_at(const struct gen *g, double px, double py,
                            double pz, double tt)
{
    double v = 0, amp = 1.0, f = 4.0;
    for (int o = 0; o < 5; o++) {
        double vx = 0.010 * (o + 1), vy = 0.006 * (2 - o), vz = 0.004;
        v += amp * vnoise(g->seed + (uint32_t)o, f * (px - vx * tt),
                          f * (py - vy * tt), f * (pz - vz * tt) + 0.05 * o * tt);
        amp *= 0.55;
        f *= 2.0;
    }
    return v;
}

/* The front at (px, py, pz) and time tt: a tanh step about one voxel wide,
 * wrinkled and sweeping along x every 40 steps, over faint noise. */
static double front_at(const struct gen *g, double px, double py, double pz,
                       double tt)
{
    double wr = 0.04 * vnoise(g->seed, 6 * py, 6 * pz, 0.0);
    double pos = 0.1 + 0.8 * fmod(tt / 40.0, 1.0);
    double width = 0.5 / g->dims[0]; /* about one voxel */
    double d = (px + wr - pos) / width;
    return 1.0 + 2.0 * 0.5 * (1.0 - tanh(d)) +
           0.05 * vnoise(g->seed + 7, 10 * px, 10 * py, 10 * pz + 0.1 * tt);
}

/* The fields evaluated voxel by voxel (turbulence, front). */
static void gen_pointwise(const struct gen *g, uint32_t t, float *out)
{
    const uint32_t nx = g->dims[0], ny = g->dims[1], nz = g->dims[2];
    const double tt = (double)t;
#ifdef _OPENMP
#pragma omp parallel for schedule(static)
#endif
    for (uint32_t z = 0; z < nz; z++)
        for (uint32_t y = 0; y < ny; y++) {
            float *row = out + (size_t)nx * (y + (size_t)ny * z);
            double pz = (z + 0.5) / nz, py = (y + 0.5) / ny;
            for (uint32_t x = 0; x < nx; x++) {
                double px = (x + 0.5) / nx;
                double v = g->field == TURB ? turbulence_at(g, px, py, pz, tt)
                                            : front_at(g, px, py, pz, tt);
                row[x] = (float)v;
            }
        }
}

/* Timestep t of the field into out (nx*ny*nz floats, x fastest).
 * Coordinates are cell centres in [0, 1]. */
static void gen_step(const struct gen *g, uint32_t t, float *out)
{
    switch (g->field) {
    case CONST: gen_constant(g, out); break;
    case BLOBS: gen_blobs(g, t, out); break;
    case TURB:
    case FRONT: gen_pointwise(g, t, out); break;
    }
}

/* ------------------------------------------------------------------------
 * Options
 */

struct options {
    struct gen g;
    const char *field, *dir, *single, *prefix;
    int have_dims;
    int nextra;                   /* arguments that are not options */
};

static const struct option long_options[] = {
    {"field", required_argument, 0, 'f'},
    {"dims", required_argument, 0, 'd'},
    {"steps", required_argument, 0, 's'},
    {"output", required_argument, 0, 'o'},
    {"single", required_argument, 0, 'S'},
    {"prefix", required_argument, 0, 'p'},
    {"seed", required_argument, 0, 'r'},
    {"value", required_argument, 0, 'v'},
    {"help", no_argument, 0, 'h'},
    {"version", no_argument, 0, 'V'},
    {0, 0, 0, 0}};
static const char short_options[] = "f:d:s:o:hV";

/* Fills o from argv; numbers are checked as they come.  Returns -1 to go
 * on, or the exit status when the program is done: --help, --version or a
 * usage error (message printed). */
static int parse_options(int argc, char **argv, struct options *o)
{
    int c;
    struct tvpal_diag diag;
    *o = (struct options){.g = {.seed = 1, .value = 1.5}};
    while ((c = getopt_long(argc, argv, short_options, long_options, NULL)) != -1) {
        switch (c) {
        case 'f': o->field = optarg; break;
        case 'd':
            if (tvpal_dims_parse(optarg, o->g.dims, &diag) < 0) {
                fprintf(stderr, PROG ": --dims: %s\n", diag.msg);
                return TVPAL_EXIT_USAGE;
            }
            o->have_dims = 1;
            break;
        case 's':
            if (tvpal_parse_u32(optarg, 1, 1000000, &o->g.steps) < 0) {
                fprintf(stderr, PROG ": --steps \"%s\": expected 1..1000000\n",
                        optarg);
                return TVPAL_EXIT_USAGE;
            }
            break;
        case 'o': o->dir = optarg; break;
        case 'S': o->single = optarg; break;
        case 'p': o->prefix = optarg; break;
        case 'r':
            if (tvpal_parse_u32(optarg, 0, UINT32_MAX, &o->g.seed) < 0) {
                fprintf(stderr, PROG ": --seed \"%s\": expected a whole "
                        "number\n", optarg);
                return TVPAL_EXIT_USAGE;
            }
            break;
        case 'v':
            if (tvpal_parse_double(optarg, &o->g.value) < 0) {
                fprintf(stderr, PROG ": --value \"%s\": expected a finite "
                        "number\n", optarg);
                return TVPAL_EXIT_USAGE;
            }
            break;
        case 'h': usage(stdout); return TVPAL_EXIT_OK;
        case 'V': printf(PROG " " PACKAGE_VERSION "\n"); return TVPAL_EXIT_OK;
        default:
            fprintf(stderr, "Try '" PROG " --help'.\n");
            return TVPAL_EXIT_USAGE;
        }
    }
    o->nextra = argc - optind;
    return -1;
}

/* The required options are there and not empty, nothing else is; the field
 * is known (sets o->g.field); the prefix defaults to the field's name.
 * Returns 0 or TVPAL_EXIT_USAGE (printed). */
static int validate_options(struct options *o)
{
    if (!o->field || !o->have_dims || !o->g.steps || (!o->dir && !o->single) ||
        (o->dir && !*o->dir) || (o->single && !*o->single) || o->nextra) {
        fprintf(stderr, PROG ": --field, --dims, --steps and -o DIR (or "
                "--single FILE) are required (try --help)\n");
        return TVPAL_EXIT_USAGE;
    }
    static const struct { const char *name; enum field field; } fields[] = {
        {"blobs", BLOBS}, {"turbulence", TURB}, {"front", FRONT},
        {"constant", CONST}};
    size_t i = 0;
    while (i < sizeof fields / sizeof fields[0] && strcmp(o->field, fields[i].name))
        i++;
    if (i == sizeof fields / sizeof fields[0]) {
        fprintf(stderr, PROG ": --field \"%s\": expected blobs, turbulence, "
                "front or constant\n", o->field);
        return TVPAL_EXIT_USAGE;
    }
    o->g.field = fields[i].field;
    if (!o->prefix)
        o->prefix = o->field;
    return 0;
}

/* ------------------------------------------------------------------------
 * Output
 */

/* Digits of the step number in file names: at least 4, more when needed, so
 * that file names sort in time order (the encoder takes its inputs in
 * argument order). */
static int step_digits(uint32_t steps)
{
    int digits = 4;
    for (uint32_t m = 10000; m <= steps - 1 && digits < 10; m *= 10)
        digits++;
    return digits;
}

/* Every timestep into one file, written as FILE.tmp and renamed when
 * complete.  vol is scratch for nvox floats.  Returns 0 or TVPAL_EXIT_FAIL
 * (printed). */
static int write_single(const struct options *o, float *vol, size_t nvox)
{
    struct tvpal_diag d = {{0}};
    struct tvpal_out out;
    int rc = tvpal_out_open(&out, o->single, &d);
    for (uint32_t t = 0; rc == 0 && t < o->g.steps; t++) {
        gen_step(&o->g, t, vol);
        tvpal_store_f32le(vol, (unsigned char *)vol, nvox);
        rc = tvpal_out_write(&out, vol, nvox * 4, &d);
    }
    /* Renamed into place only when every byte reached the file. */
    if (rc == 0)
        rc = tvpal_out_commit(&out, &d);
    else
        tvpal_out_abort(&out);
    if (rc < 0)
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
    return rc < 0 ? TVPAL_EXIT_FAIL : 0;
}

/* Creates -o DIR when given, even with --single (which is what is written
 * then).  Returns 0 or TVPAL_EXIT_FAIL (printed). */
static int make_output_dir(const struct options *o)
{
    if (!o->dir)
        return 0;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_mkdirs(o->dir, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s: cannot create: %s\n", o->dir,
                d.msg[0] ? d.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_FAIL;
    }
    return 0;
}

/* One file per timestep, DIR/PREFIX_tNNNN.f32, each written atomically.
 * vol is scratch for nvox floats.  Returns 0 or TVPAL_EXIT_FAIL (printed). */
static int write_per_step(const struct options *o, float *vol, size_t nvox)
{
    const int digits = step_digits(o->g.steps);
    for (uint32_t t = 0; t < o->g.steps; t++) {
        gen_step(&o->g, t, vol);
        tvpal_store_f32le(vol, (unsigned char *)vol, nvox);
        char *path;
        if (asprintf(&path, "%s/%s_t%0*u.f32", o->dir, o->prefix, digits, t) < 0) {
            fprintf(stderr, PROG ": out of memory\n");
            return TVPAL_EXIT_FAIL;
        }
        struct tvpal_diag d = {{0}};
        int rc = tvpal_write_file_atomic(path, vol, nvox * 4, &d);
        if (rc < 0)
            fprintf(stderr, PROG ": %s: cannot write: %s\n", path,
                    d.msg[0] ? d.msg : tvpal_strerror(rc));
        free(path);
        if (rc < 0)
            return TVPAL_EXIT_FAIL;
    }
    return 0;
}

int main(int argc, char **argv)
{
    struct options o;
    int status = parse_options(argc, argv, &o);
    if (status >= 0)
        return status;
    if ((status = validate_options(&o)) != 0 || (status = make_output_dir(&o)) != 0)
        return status;
    size_t nvox = (size_t)o.g.dims[0] * o.g.dims[1] * o.g.dims[2];
    float *vol = malloc(nvox * sizeof *vol);
    if (!vol) {
        fprintf(stderr, PROG ": out of memory for %zu voxels\n", nvox);
        return TVPAL_EXIT_FAIL;
    }
    status = o.single ? write_single(&o, vol, nvox) : write_per_step(&o, vol, nvox);
    free(vol);
    return status;
}
