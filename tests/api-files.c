/* api-files: a user's program of libtvpal's encode from a source (tvpal.h
 * only, the shared library), for tests/api-files.sh: raw files of one step
 * each, read with pread (a concurrent source) or a box at a time (not),
 * encoded under a memory limit.
 *   api-files [--whole] [--type f32|f64|u8|u16|i16] [--big-endian]
 *             [--window N] [--axes MASK] [--mem-limit BYTES] [--levels L]
 *             [--threads J] [--checkpoint UNITS] [--plan] [--stop-after U]
 *             --dims NXxNYxNZ
 *             -o OUT FILE...
 * --plan prints tvpal_encoder_plan's figures as key=value and exits;
 * --stop-after U stops after unit U (TVPAL_SAVE_AND_STOP) and exits 3,
 * leaving OUT.partial for a rerun, which continues (the identity is the
 * files' names and sizes).  Built with -DAPI_FILES_MPI (tests/api-mpi.sh)
 * and run under mpirun, every rank reads the files and writes its node
 * shard of every axis (tvpal_encoder_set_mpi), as tvpal-encode --nodes
 * does. */
#define _GNU_SOURCE
#include "tvpal.h"
#ifdef API_FILES_MPI
#include "tvpal_mpi.h" /* and MPI's header */
#endif

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

struct files {
    char **paths;
    int n;
    uint32_t dims[3];
    size_t esize;
    uint64_t stop_after;
    uint64_t first_unit;
    int seen;
};

static int read_box(void *ctx, uint32_t t, const uint32_t lo[3],
                    const uint32_t n[3], void *dst, struct tvpal_diag *d)
{
    const struct files *f = ctx;
    int fd = open(f->paths[t], O_RDONLY);
    if (fd < 0)
        return tvpal_diag_set(d, TVPAL_E_OPEN, "%s: %s", f->paths[t],
                              strerror(errno));
    unsigned char *o = dst;
    /* Whole rows of a plane are one range; whole planes too. */
    const int rows_whole = n[0] == f->dims[0];
    const int planes_whole = rows_whole && n[1] == f->dims[1];
    const uint32_t ny = planes_whole ? 1 : n[1], nz = planes_whole ? 1 : n[2];
    const size_t row = (size_t)n[0] * f->esize *
                       (planes_whole ? (size_t)n[1] * n[2]
                        : rows_whole ? n[1] : 1);
    for (uint32_t z = 0; z < nz; z++)
        for (uint32_t y = 0; y < (rows_whole ? 1 : ny); y++, o += row) {
            const off_t at = (off_t)((lo[0] + (uint64_t)f->dims[0] *
                                                  (lo[1] + y + (uint64_t)
                                                   f->dims[1] * (lo[2] + z))) *
                                     f->esize);
            if (pread(fd, o, row, at) != (ssize_t)row) {
                close(fd);
                return tvpal_diag_set(d, TVPAL_E_READ, "%s: short read at "
                                      "byte %lld", f->paths[t],
                                      (long long)at);
            }
        }
    close(fd);
    return 0;
}

static int progress(void *ctx, const struct tvpal_progress *p)
{
    struct files *f = ctx;
    if (!f->seen++)
        f->first_unit = p->unit;
    return p->unit_end && f->stop_after && p->unit == f->stop_after
               ? TVPAL_SAVE_AND_STOP : TVPAL_GO_ON;
}

static int fail(const char *what, int rc, const struct tvpal_diag *d)
{
    fprintf(stderr, "api-files: %s: %s: %s\n", what, tvpal_strerror(rc),
            d->msg);
    return rc == TVPAL_E_CANCELED ? 3 : 1;
}

/* Encodes the files into out with the API; the program's exit status. */
static int encode_files(const char *out, struct files *f,
                        const struct tvpal_source *src, int plan_only,
                        double window, double axes, double limit,
                        double levels, double threads, double checkpoint)
{
    struct tvpal_encoder *e = NULL;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_encoder_open(&e, out, f->dims, (uint32_t)f->n, &d);
    if (rc < 0)
        return fail("open", rc, &d);
    const struct { enum tvpal_param p; double v; } set[] = {
        {TVPAL_PARAM_WINDOW, window}, {TVPAL_PARAM_AXES, axes},
        {TVPAL_PARAM_MEM_LIMIT, limit}, {TVPAL_PARAM_LEVELS, levels},
        {TVPAL_PARAM_THREADS, threads}, {TVPAL_PARAM_CHECKPOINT, checkpoint}};
    for (size_t k = 0; rc == 0 && k < sizeof set / sizeof *set; k++)
        rc = tvpal_encoder_set(e, set[k].p, set[k].v, &d);
    /* Its files in the manifest: tvpal-report reads them again. */
    const struct tvpal_provenance prov = {
        .encoder = "api-files", .format = "raw",
        .sources = (const char *const *)f->paths, .nsources = (uint32_t)f->n};
    if (rc == 0)
        rc = tvpal_encoder_set_provenance(e, &prov, &d);
#ifdef API_FILES_MPI
    int rank = 0, size = 1;
    uint32_t z0, nz;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    tvpal_slab(f->dims[2], (uint32_t)size, (uint32_t)rank, &z0, &nz);
    if (rc == 0)
        rc = tvpal_encoder_set_mpi(e, MPI_COMM_WORLD, z0, nz, &d);
#endif
    struct tvpal_plan p;
    if (rc == 0 && (rc = tvpal_encoder_plan(e, src, &p, &d)) == 0)
        printf("passes=%u passes_x=%u passes_y=%u passes_z=%u "
               "peak_bytes=%llu read_voxels=%llu levels_inline=%d "
               "ring_bytes=%llu\n",
               p.passes, p.passes_axis[0], p.passes_axis[1],
               p.passes_axis[2], (unsigned long long)p.peak_bytes,
               (unsigned long long)p.read_voxels, p.levels_inline,
               (unsigned long long)p.ring_bytes);
    if (rc < 0 || plan_only) {
        tvpal_encoder_abort(e);
        return rc < 0 ? fail("plan", rc, &d) : 0;
    }
    rc = tvpal_encoder_encode(e, src, &d);
    printf("first_unit=%llu\n", (unsigned long long)f->first_unit);
    if (rc < 0) {
        tvpal_encoder_abort(e);
        return fail("encode", rc, &d);
    }
    rc = tvpal_encoder_finish(e, &d);
    return rc < 0 ? fail("finish", rc, &d) : 0;
}

int main(int argc, char **argv)
{
    struct files f = {0};
    struct tvpal_source src = {.type = TVPAL_FLOAT32, .concurrent = 1,
                               .ctx = &f, .read = read_box,
                               .progress = progress};
    const char *out = NULL;
    double window = 4, axes = TVPAL_AXIS_Z, limit = 0, levels = 0, threads = 0,
           checkpoint = 1;
    int plan_only = 0, i = 1;
    for (; i < argc && argv[i][0] == '-'; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : "";
        if (!strcmp(a, "--whole"))
            src.concurrent = 0;
        else if (!strcmp(a, "--big-endian"))
            src.big_endian = 1;
        else if (!strcmp(a, "--plan"))
            plan_only = 1;
        else if (!strcmp(a, "--type") && ++i)
            src.type = !strcmp(v, "f64") ? TVPAL_FLOAT64
                       : !strcmp(v, "u8") ? TVPAL_UINT8
                       : !strcmp(v, "u16") ? TVPAL_UINT16
                       : !strcmp(v, "i16") ? TVPAL_INT16 : TVPAL_FLOAT32;
        else if (!strcmp(a, "--window") && ++i)
            window = atof(v);
        else if (!strcmp(a, "--axes") && ++i)
            axes = atof(v);
        else if (!strcmp(a, "--mem-limit") && ++i)
            limit = atof(v);
        else if (!strcmp(a, "--levels") && ++i)
            levels = atof(v);
        else if (!strcmp(a, "--threads") && ++i)
            threads = atof(v);
        else if (!strcmp(a, "--checkpoint") && ++i)
            checkpoint = atof(v);
        else if (!strcmp(a, "--stop-after") && ++i)
            f.stop_after = strtoull(v, NULL, 10);
        else if (!strcmp(a, "--dims") && ++i)
            sscanf(v, "%ux%ux%u", &f.dims[0], &f.dims[1], &f.dims[2]);
        else if (!strcmp(a, "-o") && ++i)
            out = v;
        else {
            fprintf(stderr, "api-files: unknown option %s\n", a);
            return 2;
        }
    }
    f.paths = argv + i;
    f.n = argc - i;
    f.esize = src.type == TVPAL_FLOAT64 ? 8 : src.type == TVPAL_UINT8 ? 1
              : src.type == TVPAL_FLOAT32 ? 4 : 2;
    if (!out || f.n < 1 || !f.dims[2]) {
        fprintf(stderr, "api-files: --dims, -o and files expected\n");
        return 2;
    }
    /* The identity: the files, in order, with their sizes. */
    size_t cap = 64;
    for (int k = 0; k < f.n; k++)
        cap += strlen(f.paths[k]) + 32;
    char *id = calloc(1, cap);
    for (int k = 0; id && k < f.n; k++) {
        struct stat st;
        long long size = stat(f.paths[k], &st) == 0 ? (long long)st.st_size
                                                    : -1;
        snprintf(id + strlen(id), cap - strlen(id), "%s %lld\n", f.paths[k],
                 size);
    }
    src.identity = id;
#ifdef API_FILES_MPI
    MPI_Init(&argc, &argv);
#endif
    int status = encode_files(out, &f, &src, plan_only, window, axes, limit,
                              levels, threads, checkpoint);
    free(id);
#ifdef API_FILES_MPI
    MPI_Finalize();
#endif
    return status;
}

