/* tvpal-heat: a small simulation that encodes its own output in situ
 * through libtvpal (tvpal.h), as a simulation code would.
 *
 * The heat equation u_t = k lap(u) on an NX x NY x NZ grid, explicit
 * Euler with a 7-point Laplacian, insulated faces, from three hot spots;
 * a moving heater keeps it changing.  Each output step is pushed to a
 * tvpal_encoder straight from the simulation's array (no file); with
 * --raw DIR it is also written as DIR/heat_tNNNN.f32, for comparing with
 * tvpal-encode.  Plain C: builds with
 *     cc tvpal-heat.c $(pkg-config --cflags --libs tvpal) -lm
 */
#include <tvpal.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void usage(FILE *f)
{
    fputs("Usage: tvpal-heat -o DIR [--dims NXxNYxNZ] [--steps T] "
          "[--window N] [--raw DIR]\n"
          "Runs a 3-D heat equation and encodes every step through "
          "libtvpal into the\ndataset DIR.\n\n"
          "  -o DIR             the dataset written (required)\n"
          "  --dims NXxNYxNZ    grid (default 48x40x32)\n"
          "  --steps T          output steps (default 24)\n"
          "  --window N         tvpal window (default 4)\n"
          "  --raw DIR          also write each step as raw float32 "
          "files in DIR\n"
          "  -h, --help         this help\n", f);
}

/* One explicit step of u_t = k lap(u) with insulated faces, plus a heater
 * that circles in z = nz / 2. */
static void step(const float *u, float *v, const unsigned d[3], double t)
{
    const size_t nx = d[0], ny = d[1], nz = d[2], sy = nx, sz = nx * ny;
    const float k = 0.15f;
    const double hx = nx * (0.5 + 0.3 * cos(t)), hy = ny * (0.5 + 0.3 * sin(t));
    for (size_t z = 0; z < nz; z++)
        for (size_t y = 0; y < ny; y++)
            for (size_t x = 0; x < nx; x++) {
                const size_t i = x + sy * y + sz * z;
                const float c = u[i];
                const float xm = x ? u[i - 1] : c, xp = x + 1 < nx ? u[i + 1] : c;
                const float ym = y ? u[i - sy] : c, yp = y + 1 < ny ? u[i + sy] : c;
                const float zm = z ? u[i - sz] : c, zp = z + 1 < nz ? u[i + sz] : c;
                float lap = xm + xp + ym + yp + zm + zp - 6 * c;
                double r2 = (x - hx) * (x - hx) + (y - hy) * (y - hy) +
                            (z - nz / 2.0) * (z - nz / 2.0);
                v[i] = c + k * lap + (float)(2.0 * exp(-r2 / 8.0));
            }
}

static void init(float *u, const unsigned d[3])
{
    const double spots[3][3] = {{0.25, 0.3, 0.3}, {0.7, 0.6, 0.5},
                                {0.4, 0.75, 0.7}};
    for (unsigned z = 0; z < d[2]; z++)
        for (unsigned y = 0; y < d[1]; y++)
            for (unsigned x = 0; x < d[0]; x++) {
                double s = 0;
                for (int k = 0; k < 3; k++) {
                    double dx = x - spots[k][0] * d[0],
                           dy = y - spots[k][1] * d[1],
                           dz = z - spots[k][2] * d[2];
                    s += 100 * exp(-(dx * dx + dy * dy + dz * dz) / 20.0);
                }
                u[x + (size_t)d[0] * (y + (size_t)d[1] * z)] = (float)s;
            }
}

static int write_raw(const char *dir, unsigned t, const float *u, size_t n)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/heat_t%04u.f32", dir, t);
    FILE *f = fopen(path, "wb");
    int ok = f && fwrite(u, sizeof *u, n, f) == n;
    if (f && fclose(f) != 0)
        ok = 0;
    if (!ok)
        fprintf(stderr, "tvpal-heat: %s: %s\n", path, strerror(errno));
    return ok ? 0 : -1;
}

/* Reports a libtvpal error and returns 1. */
static int fail(const char *what, int rc, const struct tvpal_diag *d)
{
    fprintf(stderr, "tvpal-heat: %s: %s%s%s%s\n", what, tvpal_strerror(rc),
            d->msg[0] ? " (" : "", d->msg, d->msg[0] ? ")" : "");
    return 1;
}

int main(int argc, char **argv)
{
    unsigned d[3] = {48, 40, 32}, T = 24, N = 4;
    const char *out = NULL, *raw = NULL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(a, "-o") && v) {
            out = v, i++;
        } else if (!strcmp(a, "--raw") && v) {
            raw = v, i++;
        } else if (!strcmp(a, "--dims") && v &&
                   sscanf(v, "%ux%ux%u", &d[0], &d[1], &d[2]) == 3 && d[0] &&
                   d[1] && d[2] && d[0] <= 4096 && d[1] <= 4096 &&
                   d[2] <= 4096) {
            i++;
        } else if (!strcmp(a, "--steps") && v && sscanf(v, "%u", &T) == 1 &&
                   T >= 1 && T <= 100000) {
            i++;
        } else if (!strcmp(a, "--window") && v && sscanf(v, "%u", &N) == 1) {
            i++;
        } else {
            fprintf(stderr, "tvpal-heat: bad argument %s\n", a);
            usage(stderr);
            return 2;
        }
    }
    if (!out) {
        usage(stderr);
        return 2;
    }
    const uint32_t dims[3] = {d[0], d[1], d[2]};
    const size_t n = (size_t)d[0] * d[1] * d[2];
    float *u = malloc(n * sizeof *u), *v = malloc(n * sizeof *v);
    double *times = malloc(T * sizeof *times);
    if (!u || !v || !times) {
        fputs("tvpal-heat: out of memory\n", stderr);
        return 1;
    }
    const unsigned sub = 4;           /* simulation steps per output step */
    const double dt = 0.05;
    for (unsigned t = 0; t < T; t++)
        times[t] = t * sub * dt;
    struct tvpal_encoder *enc = NULL;
    struct tvpal_diag dg = {{0}};
    int rc;
    const double spacing[3] = {0.5, 0.5, 0.5}, origin[3] = {0, 0, 0};
    if ((rc = tvpal_encoder_open(&enc, out, dims, T, &dg)) < 0)
        return fail(out, rc, &dg);
    if ((rc = tvpal_encoder_set(enc, TVPAL_PARAM_WINDOW, N, &dg)) < 0 ||
        (rc = tvpal_encoder_set_grid(enc, spacing, origin, &dg)) < 0 ||
        (rc = tvpal_encoder_set_times(enc, times, "seconds", &dg)) < 0 ||
        (rc = tvpal_encoder_set_units(enc, "K", &dg)) < 0) {
        tvpal_encoder_abort(enc);
        return fail(out, rc, &dg);
    }
    init(u, d);
    for (unsigned t = 0; t < T; t++) {
        if ((rc = tvpal_encoder_push(enc, u, TVPAL_FLOAT32, NULL, &dg)) < 0) {
            tvpal_encoder_abort(enc);
            return fail(out, rc, &dg);
        }
        if (raw && write_raw(raw, t, u, n) < 0) {
            tvpal_encoder_abort(enc);
            return 1;
        }
        for (unsigned s = 0; s < sub; s++) {
            step(u, v, d, (t * sub + s) * dt);
            float *w = u;
            u = v;
            v = w;
        }
    }
    if ((rc = tvpal_encoder_finish(enc, &dg)) < 0)
        return fail(out, rc, &dg);
    printf("tvpal-heat: %u steps of %ux%ux%u encoded into %s (libtvpal %s)\n",
           T, d[0], d[1], d[2], out, tvpal_version_string());
    free(u);
    free(v);
    free(times);
    return 0;
}
