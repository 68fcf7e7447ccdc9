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
 * and, as an MPI program whose grid is decomposed along z (each rank owns
 * a slab of planes, tvpal_slab, with one halo plane either side, and
 * encodes its slab: tvpal_mpi.h), with
 *     cc -DTVPAL_HEAT_MPI tvpal-heat.c \
 *        $(pkg-config --cflags --libs ompi-c tvpal) -lm
 * Every rank count computes the same values, bit for bit.
 */
#ifdef TVPAL_HEAT_MPI
#include <tvpal_mpi.h>
#else
#include <tvpal.h>
#endif

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* This process's part of the grid: planes z0 .. z0 + nz - 1 of the global
 * d[2], stored with a halo plane below and above (planes 0 and nz + 1 of
 * the local array). */
struct part {
    unsigned d[3];
    uint32_t z0, nz;
    int rank, size;
};

static size_t plane_of(const struct part *p)
{
    return (size_t)p->d[0] * p->d[1];
}

static void usage(FILE *f)
{
    fputs("Usage: [mpirun -np K] tvpal-heat -o DIR [--dims NXxNYxNZ] "
          "[--steps T]\n                  [--window N] [--levels L] "
          "[--raw DIR] [--bad-value R]\n                  [--resume]\n"
          "Runs a 3-D heat equation and encodes every step through "
          "libtvpal into the\ndataset DIR.\n\n"
          "  -o DIR             the dataset written (required)\n"
          "  --dims NXxNYxNZ    grid (default 48x40x32)\n"
          "  --steps T          output steps (default 24)\n"
          "  --window N         tvpal window (default 4)\n"
          "  --levels L         also L coarser levels of detail\n"
          "  --raw DIR          also write each step as raw float32 "
          "files in DIR\n"
          "  --resume           continue an interrupted encode of DIR from "
          "its checkpoint\n"
          "                     (the simulation runs from its start and "
          "pushes only the\n"
          "                     steps the encode still needs)\n"
          "  --bad-value R      rank R's step T/2 holds an infinity: its push "
          "fails,\n"
          "                     and every rank's encode with it\n"
          "  -h, --help         this help\n", f);
}

/* The halo planes from the neighbouring ranks; at the grid's faces a
 * copy of the face plane (insulated: the Laplacian sees no gradient). */
static void exchange_halos(float *u, const struct part *p)
{
    const size_t pl = plane_of(p);
    float *lo = u, *first = u + pl, *last = u + pl * p->nz,
          *hi = u + pl * (p->nz + 1);
#ifdef TVPAL_HEAT_MPI
    const int below = p->rank > 0 ? p->rank - 1 : MPI_PROC_NULL,
              above = p->rank + 1 < p->size ? p->rank + 1 : MPI_PROC_NULL;
    MPI_Sendrecv(last, (int)pl, MPI_FLOAT, above, 0, lo, (int)pl, MPI_FLOAT,
                 below, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    MPI_Sendrecv(first, (int)pl, MPI_FLOAT, below, 1, hi, (int)pl, MPI_FLOAT,
                 above, 1, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
#endif
    if (p->z0 == 0)
        memcpy(lo, first, pl * sizeof *u);
    if (p->z0 + p->nz == p->d[2])
        memcpy(hi, last, pl * sizeof *u);
}

/* One explicit step of u_t = k lap(u) with insulated faces, plus a heater
 * that circles in z = nz / 2, on this part's planes (halos current). */
static void step(const float *u, float *v, const struct part *p, double t)
{
    const size_t nx = p->d[0], ny = p->d[1], sy = nx, sz = nx * ny;
    const float k = 0.15f;
    const double hx = nx * (0.5 + 0.3 * cos(t)), hy = ny * (0.5 + 0.3 * sin(t));
    for (size_t lz = 1; lz <= p->nz; lz++) {
        const double z = (double)(p->z0 + lz - 1);
        for (size_t y = 0; y < ny; y++)
            for (size_t x = 0; x < nx; x++) {
                const size_t i = x + sy * y + sz * lz;
                const float c = u[i];
                const float xm = x ? u[i - 1] : c, xp = x + 1 < nx ? u[i + 1] : c;
                const float ym = y ? u[i - sy] : c, yp = y + 1 < ny ? u[i + sy] : c;
                const float zm = u[i - sz], zp = u[i + sz];
                float lap = xm + xp + ym + yp + zm + zp - 6 * c;
                double r2 = (x - hx) * (x - hx) + (y - hy) * (y - hy) +
                            (z - p->d[2] / 2.0) * (z - p->d[2] / 2.0);
                v[i] = c + k * lap + (float)(2.0 * exp(-r2 / 8.0));
            }
    }
}

static void init(float *u, const struct part *p)
{
    const double spots[3][3] = {{0.25, 0.3, 0.3}, {0.7, 0.6, 0.5},
                                {0.4, 0.75, 0.7}};
    const unsigned *d = p->d;
    for (unsigned lz = 1; lz <= p->nz; lz++)
        for (unsigned y = 0; y < d[1]; y++)
            for (unsigned x = 0; x < d[0]; x++) {
                const unsigned z = p->z0 + lz - 1;
                double s = 0;
                for (int k = 0; k < 3; k++) {
                    double dx = x - spots[k][0] * d[0],
                           dy = y - spots[k][1] * d[1],
                           dz = z - spots[k][2] * d[2];
                    s += 100 * exp(-(dx * dx + dy * dy + dz * dz) / 20.0);
                }
                u[x + (size_t)d[0] * (y + (size_t)d[1] * lz)] = (float)s;
            }
}

/* This part's planes of step t into DIR/heat_tNNNN.f32, at their place in
 * the file (every rank writes its own planes). */
static int write_raw(const char *dir, unsigned t, const float *slab,
                     const struct part *p)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/heat_t%04u.f32", dir, t);
    const size_t bytes = plane_of(p) * p->nz * sizeof *slab;
    const off_t at = (off_t)(plane_of(p) * p->z0 * sizeof *slab);
    int fd = open(path, O_WRONLY | O_CREAT, 0644);
    int ok = fd >= 0 && pwrite(fd, slab, bytes, at) == (ssize_t)bytes;
    if (fd >= 0 && close(fd) != 0)
        ok = 0;
    if (!ok)
        fprintf(stderr, "tvpal-heat: %s: %s\n", path, strerror(errno));
    return ok ? 0 : -1;
}

static int g_rank, g_size = 1;

/* Reports a libtvpal error and returns 1. */
static int fail(const char *what, int rc, const struct tvpal_diag *d)
{
    if (g_size > 1)
        fprintf(stderr, "tvpal-heat[rank %d]: ", g_rank);
    else
        fputs("tvpal-heat: ", stderr);
    fprintf(stderr, "%s: %s%s%s%s\n", what, tvpal_strerror(rc),
            d->msg[0] ? " (" : "", d->msg, d->msg[0] ? ")" : "");
    return 1;
}

/* The command line. */
struct heat_opts {
    unsigned d[3], T, N, L;
    int bad_rank, resume;
    const char *out, *raw;
};

/* Parses argv into o: -1 to run, or the exit status (0: --help). */
static int parse_args(int argc, char **argv, struct heat_opts *o)
{
    *o = (struct heat_opts){{48, 40, 32}, 24, 4, 0, -1, 0, NULL, NULL};
    unsigned *d = o->d;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            if (g_rank == 0)
                usage(stdout);
            return 0;
        } else if (!strcmp(a, "-o") && v) {
            o->out = v, i++;
        } else if (!strcmp(a, "--resume")) {
            o->resume = 1;
        } else if (!strcmp(a, "--raw") && v) {
            o->raw = v, i++;
        } else if (!strcmp(a, "--dims") && v &&
                   sscanf(v, "%ux%ux%u", &d[0], &d[1], &d[2]) == 3 && d[0] &&
                   d[1] && d[2] && d[0] <= 4096 && d[1] <= 4096 &&
                   d[2] <= 4096) {
            i++;
        } else if (!strcmp(a, "--steps") && v &&
                   sscanf(v, "%u", &o->T) == 1 && o->T >= 1 &&
                   o->T <= 100000) {
            i++;
        } else if (!strcmp(a, "--window") && v &&
                   sscanf(v, "%u", &o->N) == 1) {
            i++;
        } else if (!strcmp(a, "--levels") && v &&
                   sscanf(v, "%u", &o->L) == 1) {
            i++;
        } else if (!strcmp(a, "--bad-value") && v &&
                   sscanf(v, "%d", &o->bad_rank) == 1) {
            i++;
        } else {
            if (g_rank == 0) {
                fprintf(stderr, "tvpal-heat: bad argument %s\n", a);
                usage(stderr);
            }
            return 2;
        }
    }
    if (!o->out) {
        if (g_rank == 0)
            usage(stderr);
        return 2;
    }
    return -1;
}

/* The encoder of the run, set up (under MPI with this part's slab), and
 * with --resume the first step it needs in *next: 0, or 1 (reported). */
static int open_encoder(const struct heat_opts *o, const struct part *p,
                        const double *times, struct tvpal_encoder **out,
                        uint32_t *next)
{
    struct tvpal_encoder *enc = NULL;
    struct tvpal_diag dg = {{0}};
    const uint32_t dims[3] = {o->d[0], o->d[1], o->d[2]};
    const double spacing[3] = {0.5, 0.5, 0.5}, origin[3] = {0, 0, 0};
    int rc = tvpal_encoder_open(&enc, o->out, dims, o->T, &dg);
    if (rc < 0)
        return fail(o->out, rc, &dg);
    if ((rc = tvpal_encoder_set(enc, TVPAL_PARAM_WINDOW, o->N, &dg)) < 0 ||
        (rc = tvpal_encoder_set(enc, TVPAL_PARAM_LEVELS, o->L, &dg)) < 0 ||
        (rc = tvpal_encoder_set_grid(enc, spacing, origin, &dg)) < 0 ||
        (rc = tvpal_encoder_set_times(enc, times, "seconds", &dg)) < 0 ||
        (rc = tvpal_encoder_set_units(enc, "K", &dg)) < 0)
        goto refused;
#ifdef TVPAL_HEAT_MPI
    if ((rc = tvpal_encoder_set_mpi(enc, MPI_COMM_WORLD, p->z0, p->nz,
                                    &dg)) < 0)
        goto refused;
#else
    (void)p;
#endif
    *next = 0;
    if (o->resume) {
        if ((rc = tvpal_encoder_resume(enc, TVPAL_FLOAT32, next, &dg)) < 0)
            goto refused;
        if (g_rank == 0)
            printf("tvpal-heat: resumed %s at step %u of %u\n", o->out,
                   *next, o->T);
    }
    *out = enc;
    return 0;
refused:
    tvpal_encoder_abort(enc);
    return fail(o->out, rc, &dg);
}

/* The simulation: T output steps of `sub` steps each, every output step
 * from `next` on pushed to enc (and with --raw dumped).  Finishes enc
 * (collective); 0 or 1. */
static int simulate(const struct heat_opts *o, const struct part *p,
                    struct tvpal_encoder *enc, uint32_t next, float *u,
                    float *v, unsigned sub, double dt)
{
    const size_t pl = plane_of(p), n = pl * p->nz;
    struct tvpal_diag dg = {{0}};
    int rc, failed = 0;
    init(u, p);
    for (unsigned t = 0; t < o->T; t++) {
        float *slab = u + pl; /* past the lower halo */
        const float keep = slab[0];
        if (g_rank == o->bad_rank && t == o->T / 2)
            slab[0] = INFINITY; /* a bad output value on one rank, not fed
                                 * back into the simulation (--bad-value) */
        if (!failed && t >= next &&
            (rc = tvpal_encoder_push(enc, slab, TVPAL_FLOAT32, n, NULL,
                                     &dg)) < 0)
            /* The output fails; the simulation goes on (its neighbours
             * wait for its halos) and keeps the encoder: the finish of
             * every rank, collective, fails with this rank's message. */
            failed = fail(o->out, rc, &dg);
        slab[0] = keep;
        if (o->raw && write_raw(o->raw, t, slab, p) < 0)
            failed = 1;
        for (unsigned s = 0; s < sub; s++) {
            exchange_halos(u, p);
            step(u, v, p, (t * sub + s) * dt);
            float *w = u;
            u = v;
            v = w;
        }
    }
    if ((rc = tvpal_encoder_finish(enc, &dg)) < 0)
        return failed ? 1 : fail(o->out, rc, &dg);
    return failed;
}

/* The simulation and its encode; 0, 1 (failed) or 2 (usage). */
static int run(int argc, char **argv)
{
    struct heat_opts o;
    int rc = parse_args(argc, argv, &o);
    if (rc >= 0)
        return rc;
    struct part p = {{o.d[0], o.d[1], o.d[2]}, 0, o.d[2], g_rank, g_size};
    tvpal_slab(o.d[2], (uint32_t)g_size, (uint32_t)g_rank, &p.z0, &p.nz);
    if (p.nz == 0) {
        if (g_rank == 0)
            fprintf(stderr, "tvpal-heat: %d ranks for %u planes: at most one "
                    "rank per plane\n", g_size, o.d[2]);
        return 2;
    }
    const size_t pl = plane_of(&p);
    float *u = calloc(pl * (p.nz + 2), sizeof *u),
          *v = calloc(pl * (p.nz + 2), sizeof *v);
    double *times = malloc(o.T * sizeof *times);
    const unsigned sub = 4;           /* simulation steps per output step */
    const double dt = 0.05;
    struct tvpal_encoder *enc = NULL;
    uint32_t next = 0;
    if (!u || !v || !times) {
        fputs("tvpal-heat: out of memory\n", stderr);
        rc = 1;
    } else {
        for (unsigned t = 0; t < o.T; t++)
            times[t] = t * sub * dt;
        rc = open_encoder(&o, &p, times, &enc, &next);
    }
    if (rc == 0)
        rc = simulate(&o, &p, enc, next, u, v, sub, dt);
    if (rc == 0 && g_rank == 0)
        printf("tvpal-heat: %u steps of %ux%ux%u encoded into %s on %d "
               "rank%s (libtvpal %s)\n", o.T, o.d[0], o.d[1], o.d[2], o.out,
               g_size, g_size > 1 ? "s" : "", tvpal_version_string());
    free(u);
    free(v);
    free(times);
    return rc;
}

int main(int argc, char **argv)
{
#ifdef TVPAL_HEAT_MPI
    MPI_Init(&argc, &argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &g_size);
#endif
    int rc = run(argc, argv);
#ifdef TVPAL_HEAT_MPI
    MPI_Finalize();
#endif
    return rc;
}
