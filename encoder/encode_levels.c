/* encode_levels.c: tvpal-encode --levels L, the coarser levels of detail.
 *
 * Level k (1..L) is the 2x2x2 average of level k - 1 (level 0: the source
 * as encoded), each mean over the present voxels of its block (a block all
 * missing is missing: NaN), dims ceil(d / 2) per axis.  Its source is
 * written as raw float32 (NaN for missing), one file per step, to
 * OUTDIR.partial/level-k.src/, and encoded by a child tvpal-encode with the
 * same encoding options into OUTDIR.partial/level-k/, a complete dataset of
 * its own (FORMAT.md 3.3).  The child's own .partial and checkpoint make an
 * interrupted level resume; a level already complete is kept.  Level k's
 * source is removed once level k + 1 has been made from it.
 *
 * Its grid covers the same box as level 0: spacing s0 * d0 / dk per axis
 * and the first voxel's centre at the centre of the first block. */
#define _GNU_SOURCE
#include "encode.h"
#include "tvpal_fs.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <math.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

void level_dims(const uint32_t d0[3], unsigned k, uint32_t out[3])
{
    for (int a = 0; a < 3; a++) {
        uint32_t d = d0[a];
        for (unsigned i = 0; i < k; i++)
            d = (d + 1) / 2;
        out[a] = d;
    }
}

void level_grid(const double s0[3], const double o0[3], const uint32_t d0[3],
                const uint32_t dk[3], double sk[3], double ok[3])
{
    for (int i = 0; i < 3; i++) {
        sk[i] = s0[i] * d0[i] / dk[i];
        ok[i] = o0[i] + 0.5 * (sk[i] - s0[i]);
    }
}

/* Where a level's fine planes come from: level 0 through load_step (the
 * source, converted as encoded), a coarser one from its raw float32 files. */
struct plane_src {
    struct run *r;
    unsigned level;             /* of the planes read */
    uint32_t dims[3];
    char *dir;                  /* level >= 1: its .src directory */
    /* level 0: a slab of planes of step t read at once */
    float *slab;
    uint32_t slab_planes, slab_z0, slab_n;
    int64_t slab_t;
    struct encode_pass pass;
};

static char *step_file(const char *dir, uint32_t t)
{
    char *p;
    return asprintf(&p, "%s/step_%06u.f32", dir, t) < 0 ? NULL : p;
}

/* Plane z of step t into out (nx * ny floats). */
static void read_plane(struct plane_src *ps, uint32_t t, uint32_t z,
                       float *out)
{
    const size_t plane = (size_t)ps->dims[0] * ps->dims[1];
    if (ps->level == 0) {
        if (ps->slab_t != (int64_t)t || z < ps->slab_z0 ||
            z >= ps->slab_z0 + ps->slab_n) {
            struct run *r = ps->r;
            uint32_t n = ps->dims[2] - z < ps->slab_planes
                         ? ps->dims[2] - z : ps->slab_planes;
            ps->pass.box = (struct encode_box){{0, 0, z},
                                               {ps->dims[0], ps->dims[1], n}};
            ps->pass.stats = 0;
            const struct encode_pass *keep = r->pass;
            r->pass = &ps->pass;
            load_step(r, t, ps->slab);
            r->pass = keep;
            ps->slab_t = t;
            ps->slab_z0 = z;
            ps->slab_n = n;
        }
        memcpy(out, ps->slab + (size_t)(z - ps->slab_z0) * plane,
               plane * sizeof *out);
        return;
    }
    char *path = step_file(ps->dir, t);
    if (!path)
        die_fail("out of memory");
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        die_fail("%s: %s (rerun to resume)", path, strerror(errno));
    const size_t bytes = plane * sizeof *out;
    const off_t off = (off_t)z * (off_t)bytes;
    size_t got = 0;
    while (got < bytes) {
        ssize_t k = pread(fd, (char *)out + got, bytes - got, off + (off_t)got);
        if (k <= 0)
            die_fail("%s: %s (rerun to resume)", path,
                     k < 0 ? strerror(errno) : "shorter than expected");
        got += (size_t)k;
    }
    close(fd);
    free(path);
}

/* Adds fine plane p (nx x ny) into the block sums of a coarse plane. */
static void add_plane(const float *p, uint32_t nx, uint32_t ny, double *sum,
                      uint32_t *cnt)
{
    const uint32_t cx = (nx + 1) / 2;
    for (uint32_t y = 0; y < ny; y++)
        for (uint32_t x = 0; x < nx; x++) {
            float v = p[(size_t)y * nx + x];
            if (v != v)
                continue; /* missing: left out of the mean */
            size_t c = (size_t)(y / 2) * cx + x / 2;
            sum[c] += v;
            cnt[c]++;
        }
}

static int write_all(int fd, const void *buf, size_t n)
{
    const char *p = buf;
    while (n) {
        ssize_t k = write(fd, p, n);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return -1;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

/* Writes level k's source (every step) from ps into dir, each file
 * through a temporary renamed when complete, so a file that exists is
 * whole; steps already there are kept (a resumed run). */
static void make_level_source(struct plane_src *ps, const char *dir,
                              uint32_t T)
{
    const uint32_t nx = ps->dims[0], ny = ps->dims[1], nz = ps->dims[2];
    const uint32_t cx = (nx + 1) / 2, cy = (ny + 1) / 2, cz = (nz + 1) / 2;
    const size_t cplane = (size_t)cx * cy;
    float *fine = malloc((size_t)nx * ny * sizeof *fine);
    double *sum = malloc(cplane * sizeof *sum);
    uint32_t *cnt = malloc(cplane * sizeof *cnt);
    float *out = malloc(cplane * sizeof *out);
    if (!fine || !sum || !cnt || !out)
        die_fail("out of memory (a plane of level %u)", ps->level + 1);
    for (uint32_t t = 0; t < T; t++) {
        char *path = step_file(dir, t), *tmp = NULL;
        if (!path || asprintf(&tmp, "%s.tmp", path) < 0)
            die_fail("out of memory");
        if (tvpal_exists(path)) {
            free(path);
            free(tmp);
            continue;
        }
        int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
        if (fd < 0)
            die_fail("%s: %s", tmp, strerror(errno));
        for (uint32_t z = 0; z < cz; z++) {
            memset(sum, 0, cplane * sizeof *sum);
            memset(cnt, 0, cplane * sizeof *cnt);
            for (uint32_t dz = 0; dz < 2 && 2 * z + dz < nz; dz++) {
                read_plane(ps, t, 2 * z + dz, fine);
                add_plane(fine, nx, ny, sum, cnt);
            }
            for (size_t i = 0; i < cplane; i++)
                out[i] = cnt[i] ? (float)(sum[i] / cnt[i]) : NAN;
            if (write_all(fd, out, cplane * sizeof *out) < 0)
                die_fail("%s: %s (rerun to resume)", tmp, strerror(errno));
        }
        if (fsync(fd) < 0 || close(fd) < 0 || rename(tmp, path) < 0)
            die_fail("%s: %s (rerun to resume)", path, strerror(errno));
        free(path);
        free(tmp);
    }
    free(fine);
    free(sum);
    free(cnt);
    free(out);
}

/* This process's resident memory (bytes), from /proc/self/statm; 0 when
 * unknown. */
static uint64_t resident_bytes(void)
{
    unsigned long long size = 0, res = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (!f)
        return 0;
    if (fscanf(f, "%llu %llu", &size, &res) != 2)
        res = 0;
    fclose(f);
    return (uint64_t)res * (uint64_t)sysconf(_SC_PAGESIZE);
}

/* argv of the child encode of level k (malloc'ed strings; NULL-ended). */
struct argv_list {
    char **v;
    int n, cap;
};

static void arg_add(struct argv_list *a, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
static void arg_add(struct argv_list *a, const char *fmt, ...)
{
    if (a->n + 2 > a->cap) {
        a->cap = a->cap ? 2 * a->cap : 64;
        if (!(a->v = realloc(a->v, (size_t)a->cap * sizeof *a->v)))
            die_fail("out of memory");
    }
    va_list ap;
    va_start(ap, fmt);
    if (vasprintf(&a->v[a->n], fmt, ap) < 0)
        die_fail("out of memory");
    va_end(ap);
    a->v[++a->n] = NULL;
}

/* Runs the child encode of level k; ends the program when it fails. */
static void encode_level(struct run *r, unsigned k, const uint32_t dk[3],
                         const char *src, const char *out)
{
    const struct opts *o = &r->o;
    double s0[3], o0[3];
    grid_of(r, s0, o0);
    struct argv_list a = {0};
    arg_add(&a, "%s", PROG);
    arg_add(&a, "--dims");
    arg_add(&a, "%ux%ux%u", dk[0], dk[1], dk[2]);
    arg_add(&a, "--type");
    arg_add(&a, "f32");
    arg_add(&a, "--endian");
    arg_add(&a, "little");
    arg_add(&a, "--window");
    arg_add(&a, "%u", o->window);
    arg_add(&a, "--nodes");
    arg_add(&a, "%u", o->nodes);
    /* Every level stores level 0's axes (FORMAT.md 2.1). */
    char axes[4];
    arg_add(&a, "--axes");
    arg_add(&a, "%s", tvpal_axes_format(o->axes, axes));
    arg_add(&a, "-j");
    arg_add(&a, "%d", r->nthreads);
    /* The child's share of the limit: what this process does not hold. */
    uint64_t held = resident_bytes();
    if (held >= r->limit)
        die_fail("level %u: this process already holds %llu bytes of the "
                 "memory limit %llu", k, (unsigned long long)held,
                 (unsigned long long)r->limit);
    arg_add(&a, "--mem-limit");
    arg_add(&a, "%llu", (unsigned long long)(r->limit - held));
    arg_add(&a, "--checkpoint-every");
    arg_add(&a, "%u", o->checkpoint_every);
    arg_add(&a, "--table");
    arg_add(&a, "%s", tvpal_manifest_table_name((uint32_t)o->table_format));
    if (o->refine) {
        arg_add(&a, "--refine");
        arg_add(&a, "%u", o->refine);
    }
    if (o->naive)
        arg_add(&a, "--naive");
    if (o->klt) {
        arg_add(&a, "--transform");
        arg_add(&a, "klt");
    }
    if (o->alloc_mse) {
        arg_add(&a, "--alloc");
        arg_add(&a, "greedy-mse");
    }
    double sk[3], ok[3];
    level_grid(s0, o0, o->dims, dk, sk, ok);
    arg_add(&a, "--spacing");
    arg_add(&a, "%.17g,%.17g,%.17g", sk[0], sk[1], sk[2]);
    arg_add(&a, "--origin");
    arg_add(&a, "%.17g,%.17g,%.17g", ok[0], ok[1], ok[2]);
    if (r->times) {
        char *tf;
        if (asprintf(&tf, "%s/times.txt", src) < 0)
            die_fail("out of memory");
        FILE *f = fopen(tf, "w");
        if (!f)
            die_fail("%s: %s", tf, strerror(errno));
        for (uint32_t t = 0; t < r->T; t++)
            fprintf(f, "%.17g\n", r->times[t]);
        if (fclose(f) != 0)
            die_fail("%s: write failed", tf);
        arg_add(&a, "--times");
        arg_add(&a, "%s", tf);
        free(tf);
        if (r->time_units[0]) {
            arg_add(&a, "--time-units");
            arg_add(&a, "%s", r->time_units);
        }
    }
    if (r->units[0]) {
        arg_add(&a, "--units");
        arg_add(&a, "%s", r->units);
    }
    arg_add(&a, "-q");
    arg_add(&a, "-o");
    arg_add(&a, "%s", out);
    for (uint32_t t = 0; t < r->T; t++) {
        char *p = step_file(src, t);
        if (!p)
            die_fail("out of memory");
        arg_add(&a, "%s", p);
        free(p);
    }
    /* The child's summary line names its partial directory: this process
     * reports the levels instead (its errors still go to stderr). */
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    pid_t pid;
    int rc = posix_spawn(&pid, "/proc/self/exe", &fa, NULL, a.v, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0)
        die_fail("level %u: cannot start the encoder: %s", k, strerror(rc));
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
        ;
    for (int i = 0; i < a.n; i++)
        free(a.v[i]);
    free(a.v);
    if (WIFEXITED(status) && WEXITSTATUS(status) == 2)
        die_fail("level %u (%ux%ux%u): its encode refused the job (its "
                 "message is above); level 0 is kept in the partial output",
                 k, dk[0], dk[1], dk[2]);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        die_fail("level %u (%ux%ux%u): its encode failed (%s %d); rerun to "
                 "resume", k, dk[0], dk[1], dk[2],
                 WIFEXITED(status) ? "status" : "signal",
                 WIFEXITED(status) ? WEXITSTATUS(status) : WTERMSIG(status));
}

void encode_levels(struct run *r)
{
    const unsigned L = r->o.levels;
    /* Test hook: TVPAL_ENCODE_FAULT_LEVEL=k fails the run as level k's
     * encode would, once the levels before it are complete. */
    const char *fault = getenv("TVPAL_ENCODE_FAULT_LEVEL");
    const unsigned fault_k = fault ? (unsigned)atoi(fault) : 0;
    /* The ring is done with: its memory goes to the slabs read here. */
    release_ring(r);
    struct plane_src ps = {.r = r, .level = 0, .slab_t = -1};
    memcpy(ps.dims, r->o.dims, sizeof ps.dims);
    const uint64_t plane = (uint64_t)ps.dims[0] * ps.dims[1];
    uint64_t planes = r->plan.box_voxels_max / plane;
    ps.slab_planes = (uint32_t)(planes < 1 ? 1 : planes > ps.dims[2] ? ps.dims[2] : planes);
    if (!(ps.slab = malloc(ps.slab_planes * plane * sizeof(float))))
        die_fail("out of memory (%u planes of %llu voxels)", ps.slab_planes,
                 (unsigned long long)plane);
    char *prev_src = NULL;
    for (unsigned k = 1; k <= L; k++) {
        uint32_t dk[3];
        level_dims(r->o.dims, k, dk);
        char *src, *out;
        if (asprintf(&src, "%s/level-%u.src", r->partial, k) < 0 ||
            asprintf(&out, "%s/level-%u", r->partial, k) < 0)
            die_fail("out of memory");
        if (!tvpal_exists(out)) {
            if (k == fault_k)
                die_fail("level %u: failed as TVPAL_ENCODE_FAULT_LEVEL "
                         "asks (rerun to resume)", k);
            if (!r->o.quiet)
                msg("level %u of %u: %ux%ux%u", k, L, dk[0], dk[1], dk[2]);
            if (mkdir(src, 0755) < 0 && errno != EEXIST)
                die_fail("%s: %s", src, strerror(errno));
            make_level_source(&ps, src, r->T);
            if (k == 1) {
                /* The source is read no more: its buffers go before the
                 * child starts, so the child gets their share. */
                free(ps.slab);
                ps.slab = NULL;
                prefetch_stop(r->pf);
                r->pf = NULL;
                free(r->boxbuf);
                r->boxbuf = NULL;
            }
            encode_level(r, k, dk, src, out);
        }
        /* Level k's source made, level k - 1's is no longer needed. */
        if (prev_src)
            tvpal_rmtree(prev_src);
        free(prev_src);
        prev_src = src;
        free(out);
        ps.level = k;
        memcpy(ps.dims, dk, sizeof ps.dims);
        ps.dir = prev_src;
        free(ps.slab);
        ps.slab = NULL;
    }
    if (prev_src)
        tvpal_rmtree(prev_src);
    free(prev_src);
    free(ps.slab);
}
