/* tvpal_in_hdf5.c: the hdf5 backend of tvpal_input, on the serial HDF5 C
 * library (the only file of the library that includes hdf5.h, LAYERS.md).
 *
 * The dataset is opts->var, a path such as /group/dataset; without one,
 * the only numeric dataset of rank 3 or 4 in the file (every group
 * visited).
 * Rank 3 is one step (z, y, x, x fastest); rank 4 is (time, z, y, x), time
 * slowest.  Any integer or float type is read, converted by the library:
 * 32-bit floats straight into the caller's floats, the rest through double
 * scratch (exact for every integer up to 2^53, so that missing values
 * compare exactly) in pieces of at most TVPAL_BOX_PIECE values cut on the
 * chunks' edges (tvpal_box_split): no step of scratch.  A numeric
 * _FillValue or missing_value attribute makes the voxels of those values
 * NaN; a string units attribute is the units.  Chunked and compressed
 * (gzip) datasets are read by the library, one step's hyperslab per read;
 * a box read is the box's hyperslab (read_box).
 *
 * Deflated float32 chunks are read directly and inflated in parallel (see
 * "direct chunk reading" below), for this backend and for NetCDF-4
 * variables (tvpal_in_netcdf.c asks for it by file and dataset name).
 *
 * HDF5 prints its error stack by default: open and describe turn that off
 * for the process (H5Eset_auto2), and the innermost message of the stack
 * goes into the diag next to the file and the dataset. */
#include "tvpal_input_impl.h"
#include "tvpal_fs.h"

#include "tvpal_pool.h"
#include "tvpal_size.h"

#include <hdf5.h>
#include <stdatomic.h>

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define NO_ID ((hid_t)-1)
#define MAX_MISSING 64   /* _FillValue and missing_value's values */
#define MAX_RANK 32      /* H5S_MAX_RANK */

struct tvpal_input_file {
    hid_t file, dset, fspace, mspace;
    char *path;
    char var[TVPAL_INPUT_VAR_MAX];  /* the dataset's path, from the root */
    int rank;                  /* 3 or 4 */
    hsize_t dims[4];
    size_t nvox;
    uint32_t steps;
    int is_f32;                /* stored as 32-bit float: no scratch */
    uint32_t chunk[3];         /* x, y, z chunk sizes; 1 1 1 contiguous */
    uint64_t cache;            /* the library's chunk cache, bytes */
    uint64_t chunk_bytes;      /* one chunk as stored (0: contiguous) */
    double *scratch;           /* a piece as double (other types) */
    size_t scratch_cap;        /* in values */
    double miss[MAX_MISSING];  /* as the stored type holds them */
    int nmiss;
    int packed;                /* CF scale_factor / add_offset: values are
                                * stored * scale + offset (after the
                                * missing-value test, in stored units) */
    double scale, offset;
    struct tvpal_h5direct *direct; /* deflated float32: read directly */
};

/* ------------------------------------------------ direct chunk reading */

/* The library inflates a dataset's chunks one after the other with zlib.
 * For the common case -- float32 little-endian, chunked one step deep,
 * filtered by deflate alone or by shuffle then deflate -- a step is read
 * here instead: its compressed chunks are read as they are stored
 * (H5Dread_chunk, serial: the library is not thread-safe), then inflated
 * by tvpal_inflate (libdeflate where built with it: two to three times
 * faster) in parallel, unshuffled and copied into place.  A box read
 * (direct_read_box) reads the chunks that meet the box only, two per
 * thread at a time, and copies the parts inside the box.  Anything else
 * (other filters, an unallocated chunk, a skipped filter) is read through
 * the library as before; the bytes are the same either way. */
#ifdef HAVE_INFLATE_ADAPTER
#include "tvpal_inflate.h"
#endif

static atomic_ullong g_inflated;   /* chunks inflated here */

static void quiet(void);

struct tvpal_h5direct {
    hid_t file, dset;      /* file: NO_ID when the dataset is borrowed */
    int rank;              /* 3 or 4 (time slowest, chunked 1 deep) */
    hsize_t dims[4], chunk[4];
    int shuffle;
    size_t chunk_bytes, nchunks;       /* of one step */
    hsize_t *off;                      /* nchunks * rank chunk offsets */
    size_t *at, *len;                  /* compressed chunk c: raw + at[c] */
    unsigned char *raw;
    size_t raw_cap;
    unsigned char *work;               /* nthreads * 2 * chunk_bytes */
    int nthreads;                      /* the pool's, or 1 */
    struct tvpal_pool *pool;           /* borrowed (tvpal_input_opts) */
    /* box reads: a batch of chunks (offsets, compressed bytes) */
    hsize_t *boff;
    size_t *bat, *blen;
    unsigned char *braw;
    size_t braw_cap;
    char what[160];                    /* "FILE: DATASET", for messages */
};

void tvpal_input_hdf5_direct_close(struct tvpal_h5direct *d)
{
    if (!d)
        return;
    if (d->file != NO_ID) {
        H5Dclose(d->dset);
        H5Fclose(d->file);
    }
    free(d->off);
    free(d->at);
    free(d->len);
    free(d->raw);
    free(d->work);
    free(d->boff);
    free(d->bat);
    free(d->blen);
    free(d->braw);
    free(d);
}

/* Whether dset's layout, type and filters are the case handled here. */
static int direct_eligible(hid_t dset, struct tvpal_h5direct *d)
{
#if !defined(HAVE_INFLATE_ADAPTER) || defined(WORDS_BIGENDIAN)
    (void)dset, (void)d;
    return 0;
#else
    int ok = 0;
    hid_t type = H5Dget_type(dset), dcpl = H5Dget_create_plist(dset),
          space = H5Dget_space(dset);
    int rank = space >= 0 ? H5Sget_simple_extent_ndims(space) : -1;
    if (type >= 0 && dcpl >= 0 && (rank == 3 || rank == 4) &&
        H5Tequal(type, H5T_IEEE_F32LE) > 0 &&
        H5Pget_layout(dcpl) == H5D_CHUNKED &&
        H5Pget_chunk(dcpl, rank, d->chunk) == rank &&
        H5Sget_simple_extent_dims(space, d->dims, NULL) == rank &&
        (rank == 3 || d->chunk[0] == 1)) {
        int n = H5Pget_nfilters(dcpl);
        unsigned flags;
        size_t nc0 = 0, nc1 = 0; /* no cd_values wanted (in: room 0) */
        H5Z_filter_t f0 = n >= 1 ? H5Pget_filter2(dcpl, 0, &flags, &nc0, NULL,
                                                  0, NULL, NULL) : -1;
        H5Z_filter_t f1 = n == 2 ? H5Pget_filter2(dcpl, 1, &flags, &nc1, NULL,
                                                  0, NULL, NULL) : -1;
        d->shuffle = n == 2 && f0 == H5Z_FILTER_SHUFFLE;
        ok = (n == 1 && f0 == H5Z_FILTER_DEFLATE) ||
             (d->shuffle && f1 == H5Z_FILTER_DEFLATE);
        d->rank = rank;
    }
    if (type >= 0)
        H5Tclose(type);
    if (dcpl >= 0)
        H5Pclose(dcpl);
    if (space >= 0)
        H5Sclose(space);
    H5Eclear2(H5E_DEFAULT);
    return ok;
#endif
}

/* Chunk offsets of one step (time offset 0; set per read). */
static int direct_plan(struct tvpal_h5direct *d)
{
    const int s = d->rank - 3;   /* first spatial dim */
    size_t per[3], n = 1;
    for (int i = 0; i < 3; i++) {
        per[i] = (size_t)((d->dims[s + i] + d->chunk[s + i] - 1) /
                          d->chunk[s + i]);
        n *= per[i];
    }
    d->chunk_bytes = 4;
    for (int i = 0; i < d->rank; i++)
        d->chunk_bytes *= (size_t)d->chunk[i];
    d->nchunks = n;
    d->off = calloc(n * (size_t)d->rank, sizeof *d->off);
    d->at = malloc(n * sizeof *d->at);
    d->len = malloc(n * sizeof *d->len);
    d->nthreads = (int)tvpal_pool_threads(d->pool);
    d->work = malloc((size_t)d->nthreads * 2 * d->chunk_bytes);
    if (!d->off || !d->at || !d->len || !d->work)
        return TVPAL_E_NOMEM;
    for (size_t c = 0; c < n; c++) {
        hsize_t *o = d->off + c * (size_t)d->rank;
        o[s + 2] = (c % per[2]) * d->chunk[s + 2];
        o[s + 1] = (c / per[2] % per[1]) * d->chunk[s + 1];
        o[s] = (c / per[2] / per[1]) * d->chunk[s];
    }
    return 0;
}

/* A reader for dataset dset (borrowed: it must outlive the reader), or
 * *out NULL when the dataset is not the case handled here. */
static int direct_for(hid_t dset, const char *path, const char *name,
                      struct tvpal_pool *pool, struct tvpal_h5direct **out)
{
    *out = NULL;
    struct tvpal_h5direct *d = calloc(1, sizeof *d);
    if (!d)
        return TVPAL_E_NOMEM;
    d->file = NO_ID;
    d->pool = pool;
    d->dset = dset;
    snprintf(d->what, sizeof d->what, "%s: %s", path, name);
    if (!direct_eligible(dset, d)) {
        free(d);
        return 0;
    }
    int rc = direct_plan(d);
    if (rc < 0) {
        tvpal_input_hdf5_direct_close(d);
        return rc;
    }
    *out = d;
    return 0;
}

int tvpal_input_hdf5_direct_open(struct tvpal_h5direct **out,
                                 const char *path, const char *dataset,
                                 struct tvpal_pool *pool)
{
    *out = NULL;
    quiet();
    hid_t file = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    hid_t dset = file >= 0 ? H5Dopen2(file, dataset, H5P_DEFAULT) : NO_ID;
    H5Eclear2(H5E_DEFAULT);
    int rc = dset >= 0 ? direct_for(dset, path, dataset, pool, out) : 0;
    if (*out) {
        (*out)->file = file;
        return 0;
    }
    if (dset >= 0)
        H5Dclose(dset);
    if (file >= 0)
        H5Fclose(file);
    return rc;
}

/* Reads the compressed chunks of step k into d->raw.  1: a chunk is not
 * stored or a filter was skipped (read through the library instead). */
static int direct_fetch(struct tvpal_h5direct *d, uint32_t k)
{
    size_t total = 0;
    for (size_t c = 0; c < d->nchunks; c++) {
        hsize_t *o = d->off + c * (size_t)d->rank, sz = 0;
        if (d->rank == 4)
            o[0] = k;
        if (H5Dget_chunk_storage_size(d->dset, o, &sz) < 0 || sz == 0) {
            H5Eclear2(H5E_DEFAULT);
            return 1;
        }
        d->at[c] = total;
        d->len[c] = (size_t)sz;
        total += (size_t)sz;
    }
    if (total > d->raw_cap) {
        unsigned char *nb = realloc(d->raw, total);
        if (!nb)
            return TVPAL_E_NOMEM;
        d->raw = nb;
        d->raw_cap = total;
    }
    for (size_t c = 0; c < d->nchunks; c++) {
        uint32_t mask = 0;
        if (H5Dread_chunk(d->dset, H5P_DEFAULT, d->off + c * (size_t)d->rank,
                          &mask, d->raw + d->at[c]) < 0 || mask) {
            H5Eclear2(H5E_DEFAULT);
            return 1;
        }
    }
    return 0;
}

#ifdef HAVE_INFLATE_ADAPTER
/* Byte j of element i of a shuffled chunk is at j * n + i. */
static void unshuffle4(const unsigned char *in, size_t n, unsigned char *out)
{
    for (size_t i = 0; i < n; i++)
        for (size_t j = 0; j < 4; j++)
            out[4 * i + j] = in[j * n + i];
}

/* Chunk c (inflated in buf) into its place in dst, cut at the edges. */
static void direct_place(const struct tvpal_h5direct *d, size_t c,
                         const float *buf, float *dst)
{
    const int s = d->rank - 3;
    const hsize_t *o = d->off + c * (size_t)d->rank;
    const size_t nx = d->dims[s + 2], ny = d->dims[s + 1], nz = d->dims[s];
    const size_t cx = d->chunk[s + 2], cy = d->chunk[s + 1], cz = d->chunk[s];
    const size_t x0 = o[s + 2], y0 = o[s + 1], z0 = o[s];
    const size_t wx = nx - x0 < cx ? nx - x0 : cx;
    for (size_t z = 0; z < cz && z0 + z < nz; z++)
        for (size_t y = 0; y < cy && y0 + y < ny; y++)
            memcpy(dst + x0 + nx * (y0 + y + ny * (z0 + z)),
                   buf + cx * (y + cy * z), wx * sizeof *dst);
}
#endif

#ifdef HAVE_INFLATE_ADAPTER
/* Chunks inflated in parallel on the reader's pool (or its thread): chunk
 * i of the batch is src + at[i], len[i] bytes; each thread inflates into
 * its own part of d->work, and places the chunk into dst with place.  The
 * lowest chunk that does not inflate goes into bad (INT64_MAX: none), as a
 * serial loop would report it (tvpal_pool_lowest). */
static void direct_place_box(const struct tvpal_h5direct *d, const hsize_t *o,
                             const float *buf, const uint32_t lo[3],
                             const uint32_t n[3], float *dst);

struct chunk_job {
    struct tvpal_h5direct *d;
    const unsigned char *src;
    const size_t *at, *len;
    float *dst;
    const uint32_t *lo, *n;     /* box reads: the box */
    int64_t bad;                /* atomic minimum */
    void (*place)(const struct chunk_job *job, size_t i, const float *buf);
};

static void whole_chunk(const struct chunk_job *job, size_t i,
                        const float *buf)
{
    direct_place(job->d, i, buf, job->dst);
}

static void box_chunk(const struct chunk_job *job, size_t i, const float *buf)
{
    const struct tvpal_h5direct *d = job->d;
    direct_place_box(d, d->boff + i * (size_t)d->rank, buf, job->lo, job->n,
                     job->dst);
}

static void chunk_body(void *arg, size_t i, unsigned tid)
{
    struct chunk_job *job = arg;
    const struct tvpal_h5direct *d = job->d;
    unsigned char *a = d->work + (size_t)tid * 2 * d->chunk_bytes,
                  *b = a + d->chunk_bytes;
    size_t got;
    int z = tvpal_inflate(job->src + job->at[i], job->len[i], a,
                          d->chunk_bytes, &got);
    if (z != TVPAL_INFLATE_OK || got != d->chunk_bytes) {
        tvpal_pool_lowest(&job->bad, (int64_t)i);
        return;
    }
    if (d->shuffle)
        unshuffle4(a, d->chunk_bytes / 4, b);
    job->place(job, i, (const float *)(void *)(d->shuffle ? b : a));
}

#endif

int tvpal_input_hdf5_direct_read(struct tvpal_h5direct *d, uint32_t k,
                                 float *dst, struct tvpal_diag *diag)
{
#ifndef HAVE_INFLATE_ADAPTER
    (void)d, (void)k, (void)dst, (void)diag;
    return 1;
#else
    int rc = direct_fetch(d, k);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "%s: step %u: out of memory",
                              d->what, k);
    if (rc)
        return rc;
    struct chunk_job job = {.d = d, .src = d->raw, .at = d->at,
                            .len = d->len, .dst = dst, .bad = INT64_MAX,
                            .place = whole_chunk};
    tvpal_pool_for(d->pool, d->nchunks, chunk_body, &job);
    const int64_t bad = job.bad;
    if (bad != INT64_MAX)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: step %u: chunk %lld "
                              "of %zu does not inflate (corrupt file)",
                              d->what, k, (long long)bad + 1, d->nchunks);
    atomic_fetch_add(&g_inflated, d->nchunks);
    return 0;
#endif
}

#ifdef HAVE_INFLATE_ADAPTER
/* The part of chunk o (inflated in buf) inside the box [lo, lo + n) into
 * its place in the box-dense dst. */
static void direct_place_box(const struct tvpal_h5direct *d, const hsize_t *o,
                             const float *buf, const uint32_t lo[3],
                             const uint32_t n[3], float *dst)
{
    const int s = d->rank - 3;
    size_t c[3], o3[3], b[3], e[3];
    for (int a = 0; a < 3; a++) {
        c[a] = (size_t)d->chunk[s + 2 - a];
        o3[a] = (size_t)o[s + 2 - a];
        b[a] = o3[a] > lo[a] ? o3[a] : lo[a];
        e[a] = o3[a] + c[a] < (size_t)lo[a] + n[a] ? o3[a] + c[a]
                                                  : (size_t)lo[a] + n[a];
    }
    for (size_t z = b[2]; z < e[2]; z++)
        for (size_t y = b[1]; y < e[1]; y++)
            memcpy(dst + (b[0] - lo[0]) + n[0] * ((y - lo[1]) +
                                                  (size_t)n[1] * (z - lo[2])),
                   buf + (b[0] - o3[0]) + c[0] * ((y - o3[1]) +
                                                  c[1] * (z - o3[2])),
                   (e[0] - b[0]) * sizeof *dst);
}
#endif

/* Chunks of a box read handled at once: two per thread. */
static size_t direct_batch(const struct tvpal_h5direct *d)
{
    return 2 * (size_t)d->nthreads;
}

int tvpal_input_hdf5_direct_read_box(struct tvpal_h5direct *d, uint32_t k,
                                     const uint32_t lo[3], const uint32_t n[3],
                                     float *dst, struct tvpal_diag *diag)
{
#ifndef HAVE_INFLATE_ADAPTER
    (void)d, (void)k, (void)lo, (void)n, (void)dst, (void)diag;
    return 1;
#else
    const int s = d->rank - 3;
    size_t c0[3], per[3], all[3], total = 1;
    for (int a = 0; a < 3; a++) {
        const size_t c = (size_t)d->chunk[s + 2 - a];
        c0[a] = lo[a] / c;
        per[a] = ((size_t)lo[a] + n[a] - 1) / c - c0[a] + 1;
        all[a] = ((size_t)d->dims[s + 2 - a] + c - 1) / c;
        total *= per[a];
    }
    const size_t batch = direct_batch(d);
    if (!d->boff) {
        hsize_t *off = calloc(batch * (size_t)d->rank, sizeof *off);
        size_t *at = malloc(batch * sizeof *at), *len = malloc(batch * sizeof *len);
        if (!off || !at || !len) {
            free(off);
            free(at);
            free(len);
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "%s: step %u: out of "
                                  "memory", d->what, k);
        }
        d->boff = off, d->bat = at, d->blen = len;
    }
    for (size_t b0 = 0; b0 < total; b0 += batch) {
        const size_t nb = total - b0 < batch ? total - b0 : batch;
        size_t sum = 0;
        for (size_t j = 0; j < nb; j++) {
            const size_t i = b0 + j;
            const size_t cx = c0[0] + i % per[0],
                         cy = c0[1] + i / per[0] % per[1],
                         cz = c0[2] + i / per[0] / per[1];
            hsize_t *o = d->boff + j * (size_t)d->rank, sz = 0;
            if (d->rank == 4)
                o[0] = k;
            o[s + 2] = cx * d->chunk[s + 2];
            o[s + 1] = cy * d->chunk[s + 1];
            o[s] = cz * d->chunk[s];
            if (H5Dget_chunk_storage_size(d->dset, o, &sz) < 0 || sz == 0) {
                H5Eclear2(H5E_DEFAULT);
                return 1;
            }
            d->bat[j] = sum;
            d->blen[j] = (size_t)sz;
            sum += (size_t)sz;
        }
        if (sum > d->braw_cap) {
            free(d->braw);
            d->braw_cap = 0;
            if (!(d->braw = malloc(sum)))
                return tvpal_diag_set(diag, TVPAL_E_NOMEM, "%s: step %u: out "
                                      "of memory", d->what, k);
            d->braw_cap = sum;
        }
        for (size_t j = 0; j < nb; j++) {
            uint32_t mask = 0;
            if (H5Dread_chunk(d->dset, H5P_DEFAULT, d->boff + j * (size_t)d->rank,
                              &mask, d->braw + d->bat[j]) < 0 || mask) {
                H5Eclear2(H5E_DEFAULT);
                return 1;
            }
        }
        struct chunk_job job = {.d = d, .src = d->braw, .at = d->bat,
                                .len = d->blen, .dst = dst, .lo = lo,
                                .n = n, .bad = INT64_MAX,
                                .place = box_chunk};
        tvpal_pool_for(d->pool, nb, chunk_body, &job);
        const int64_t bad = job.bad;
        if (bad != INT64_MAX) {
            const hsize_t *o = d->boff + (size_t)bad * (size_t)d->rank;
            size_t c = ((size_t)(o[s] / d->chunk[s]) * all[1] +
                        (size_t)(o[s + 1] / d->chunk[s + 1])) * all[0] +
                       (size_t)(o[s + 2] / d->chunk[s + 2]);
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: step %u: chunk "
                                  "%zu of %zu does not inflate (corrupt "
                                  "file)", d->what, k, c + 1, d->nchunks);
        }
        atomic_fetch_add(&g_inflated, nb);
    }
    return 0;
#endif
}

uint64_t tvpal_input_hdf5_direct_scratch(const struct tvpal_h5direct *d)
{
    const uint64_t cb = d->chunk_bytes, batch = direct_batch(d);
    /* work, a batch of compressed chunks (deflate grows incompressible
     * data by a few bytes per 16 KiB), the chunk tables */
    return (uint64_t)d->nthreads * 2 * cb + batch * (cb + cb / 1024 + 64) +
           batch * ((uint64_t)d->rank * sizeof(hsize_t) + 2 * sizeof(size_t)) +
           (uint64_t)d->nchunks * ((uint64_t)d->rank * sizeof(hsize_t) +
                                   2 * sizeof(size_t));
}

uint64_t tvpal_input_hdf5_inflated(void)
{
    return atomic_load(&g_inflated);
}

/* ------------------------------------------------------- text appending */


/* ---------------------------------------------------------------- errors */

/* The library's automatic error printing off, in the calling thread (a
 * thread-safe libhdf5 keeps one error stack per thread: a step read by the
 * encoder's prefetch thread printed some 30 lines of HDF5-DIAG for a
 * missing filter).  Every entry point calls it; the diag says what
 * failed, from the stack (h5_fail). */
static void quiet(void)
{
    static __thread int done;
    if (!done) {
        H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
        done = 1;
    }
}

/* Keeps the description of the innermost frame (the last of a downward
 * walk): the cause ("file signature not found"), not the API call. */
static herr_t last_desc(unsigned n, const H5E_error2_t *e, void *data)
{
    (void)n;
    if (e->desc && e->desc[0])
        tvpal_input_copy_str(data, 96, e->desc);
    return 0;
}

/* The current error stack as one short text, then cleared. */
static const char *h5_msg(char *buf)
{
    buf[0] = 0;
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, last_desc, buf);
    H5Eclear2(H5E_DEFAULT);
    if (!buf[0])
        tvpal_input_copy_str(buf, 96, "HDF5 error");
    return buf;
}

/* "PATH: dataset VAR: WHAT (HDF5's cause)". */
static int h5_fail(struct tvpal_diag *diag, int code, const char *path,
                   const char *var, const char *what)
{
    char m[96];
    h5_msg(m);
    if (var)
        return tvpal_diag_set(diag, code, "%s: dataset %s: %s (%s)", path, var,
                              what, m);
    return tvpal_diag_set(diag, code, "%s: %s (%s)", path, what, m);
}

/* H5Fopen read-only; TVPAL_E_OPEN when the file system refuses the file,
 * TVPAL_E_FORMAT when its bytes are not HDF5. */
static int open_file(const char *path, hid_t *file, struct tvpal_diag *diag)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s", path,
                              strerror(errno));
    fclose(fp);
    quiet();
    *file = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (*file < 0)
        return h5_fail(diag, TVPAL_E_FORMAT, path, NULL,
                       "not an HDF5 file, or a damaged one");
    return 0;
}

/* ------------------------------------------------------ file inspection */

/* The dims of a dataset; rank < 0 on error. */
static int shape_of(hid_t dset, hsize_t *dims)
{
    hid_t s = H5Dget_space(dset);
    if (s < 0)
        return -1;
    int rank = H5Sget_simple_extent_ndims(s);
    if (rank > MAX_RANK ||
        (rank > 0 && H5Sget_simple_extent_dims(s, dims, NULL) < 0))
        rank = -1;
    H5Sclose(s);
    return rank;
}

static int is_numeric(hid_t type)
{
    H5T_class_t c = H5Tget_class(type);
    return c == H5T_INTEGER || c == H5T_FLOAT;
}

/* "float", "int16", ... for describe. */
static const char *type_name(hid_t t)
{
    static const char *const ints[2][4] = {
        {"uint8", "uint16", "uint32", "uint64"},
        {"int8", "int16", "int32", "int64"}};
    size_t size = H5Tget_size(t);
    int lg = size == 1 ? 0 : size == 2 ? 1 : size == 4 ? 2 : size == 8 ? 3 : -1;
    switch (H5Tget_class(t)) {
    case H5T_INTEGER:
        return lg < 0 ? "integer" : ints[H5Tget_sign(t) == H5T_SGN_2][lg];
    case H5T_FLOAT:
        return size == 4 ? "float" : size == 8 ? "double" : "float (other size)";
    case H5T_STRING: return "string";
    case H5T_COMPOUND: return "compound";
    case H5T_ENUM: return "enum";
    case H5T_ARRAY: return "array";
    case H5T_VLEN: return "vlen";
    case H5T_OPAQUE: return "opaque";
    case H5T_REFERENCE: return "reference";
    case H5T_BITFIELD: return "bitfield";
    default: return "unknown";
    }
}

/* The tvpal type of a stored numeric type: f32, f64, u8, i16 and u16 as
 * stored, f32 for the types tvpal has no name for. */
static enum tvpal_type stored_type(hid_t t)
{
    size_t size = H5Tget_size(t);
    if (H5Tget_class(t) == H5T_FLOAT)
        return size == 8 ? TVPAL_F64 : TVPAL_F32;
    int sgn = H5Tget_sign(t) == H5T_SGN_2;
    if (size == 1 && !sgn)
        return TVPAL_U8;
    if (size == 2)
        return sgn ? TVPAL_I16 : TVPAL_U16;
    return TVPAL_F32;
}

/* A numeric attribute of 1..max values, as double; 0 when absent. */
static int num_att(hid_t obj, const char *name, double *v, int max)
{
    if (H5Aexists(obj, name) <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return 0;
    }
    hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
    hid_t t = a >= 0 ? H5Aget_type(a) : NO_ID;
    hid_t s = a >= 0 ? H5Aget_space(a) : NO_ID;
    hssize_t n = s >= 0 ? H5Sget_simple_extent_npoints(s) : -1;
    int got = 0;
    if (t >= 0 && is_numeric(t) && n >= 1 && n <= max &&
        H5Aread(a, H5T_NATIVE_DOUBLE, v) >= 0)
        got = (int)n;
    if (s >= 0)
        H5Sclose(s);
    if (t >= 0)
        H5Tclose(t);
    if (a >= 0)
        H5Aclose(a);
    H5Eclear2(H5E_DEFAULT);
    return got;
}

/* The number of values of attribute name of obj; 0 when it has none. */
static long att_len(hid_t obj, const char *name)
{
    if (H5Aexists(obj, name) <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return 0;
    }
    hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
    hid_t s = a >= 0 ? H5Aget_space(a) : NO_ID;
    hssize_t n = s >= 0 ? H5Sget_simple_extent_npoints(s) : 0;
    if (s >= 0)
        H5Sclose(s);
    if (a >= 0)
        H5Aclose(a);
    H5Eclear2(H5E_DEFAULT);
    return n > 0 ? (long)n : 0;
}

/* A scalar string attribute (fixed or variable length) into buf; 1 when
 * found, else 0 and "". */
static int text_att(hid_t obj, const char *name, char *buf, size_t cap)
{
    buf[0] = 0;
    if (H5Aexists(obj, name) <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return 0;
    }
    hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
    hid_t t = a >= 0 ? H5Aget_type(a) : NO_ID;
    hid_t s = a >= 0 ? H5Aget_space(a) : NO_ID;
    hid_t mt = NO_ID;
    int got = 0;
    /* The memory type in the stored character set (h5py writes UTF-8, and
     * the library converts between no two sets: the read failed). */
    if (t >= 0 && s >= 0 && H5Tget_class(t) == H5T_STRING &&
        H5Sget_simple_extent_npoints(s) == 1 && (mt = H5Tcopy(H5T_C_S1)) >= 0 &&
        H5Tset_cset(mt, H5Tget_cset(t)) >= 0) {
        if (H5Tis_variable_str(t) > 0) {
            char *v = NULL;
            if (H5Tset_size(mt, H5T_VARIABLE) >= 0 && H5Aread(a, mt, &v) >= 0) {
                tvpal_input_copy_str(buf, cap, v ? v : "");
                got = 1;
            }
            H5free_memory(v);
        } else {
            /* One byte more than stored: a null-terminated memory string
             * of the stored size keeps room for its NUL and lost the last
             * character of a null- or space-padded one ("kg m-"). */
            size_t size = H5Tget_size(t);
            char *v = size ? malloc(size + 1) : NULL;
            if (v && H5Tset_size(mt, size + 1) >= 0 &&
                H5Aread(a, mt, v) >= 0) {
                v[size] = 0;
                tvpal_input_copy_str(buf, cap, v);
                got = 1;
            }
            free(v);
        }
    }
    if (mt >= 0)
        H5Tclose(mt);
    if (s >= 0)
        H5Sclose(s);
    if (t >= 0)
        H5Tclose(t);
    if (a >= 0)
        H5Aclose(a);
    H5Eclear2(H5E_DEFAULT);
    return got;
}

/* "(2, 3, 4)". */
static void put_shape(struct tvpal_text *b, const hsize_t *dims, int rank)
{
    tvpal_text_put(b, "(");
    for (int i = 0; i < rank; i++)
        tvpal_text_put(b, "%s%llu", i ? ", " : "", (unsigned long long)dims[i]);
    tvpal_text_put(b, ")");
}

/* Every dataset of the file, through its hard links (a dataset reached by
 * two hard links is seen twice; soft and external links are not
 * followed). */
struct walk {
    int ncand;            /* numeric datasets of rank 3 or 4 */
    char cand[128];       /* the last of them, from the root */
    int long_name;        /* a candidate's path did not fit cand */
    int all;              /* list every dataset, not the candidates only */
    int describe;         /* one line per dataset with type and units */
    struct tvpal_text *list;
    int nlisted;
};

static herr_t visit(hid_t g, const char *name, const H5L_info_t *li, void *data)
{
    struct walk *w = data;
    if (li->type != H5L_TYPE_HARD)
        return 0;
    hid_t o = H5Oopen(g, name, H5P_DEFAULT);
    if (o < 0) {
        H5Eclear2(H5E_DEFAULT);
        return 0;
    }
    hsize_t dims[MAX_RANK];
    int rank;
    if (H5Iget_type(o) == H5I_DATASET && (rank = shape_of(o, dims)) >= 0) {
        hid_t t = H5Dget_type(o);
        int cand = (rank == 3 || rank == 4) && t >= 0 && is_numeric(t);
        if (cand) {
            w->ncand++;
            int n = snprintf(w->cand, sizeof w->cand, "/%s", name);
            w->long_name = n < 0 || (size_t)n >= sizeof w->cand;
        }
        if (w->describe) {
            char units[256];
            text_att(o, "units", units, sizeof units);
            tvpal_text_put(w->list, "/%s ", name);
            put_shape(w->list, dims, rank);
            tvpal_text_put(w->list, " %s units=\"%s\"\n", t >= 0 ? type_name(t) : "?",
                units);
        } else if (cand || w->all) {
            tvpal_text_put(w->list, "%s/%s ", w->nlisted++ ? ", " : "", name);
            put_shape(w->list, dims, rank);
        }
        if (t >= 0)
            H5Tclose(t);
    }
    H5Oclose(o);
    H5Eclear2(H5E_DEFAULT);
    return 0;
}

/* Walks the file; 0 or TVPAL_E_FORMAT (its links cannot be read). */
static int walk(hid_t file, struct walk *w, const char *path,
                struct tvpal_diag *diag)
{
    if (H5Lvisit(file, H5_INDEX_NAME, H5_ITER_INC, visit, w) < 0)
        return h5_fail(diag, TVPAL_E_FORMAT, path, NULL,
                       "cannot list its groups");
    return 0;
}

/* "datasets: /a (2, 3, 4), ..." into out[cap]: the candidates, or every
 * dataset; "..." when the diag is short. */
static void list_datasets(char *out, size_t cap, hid_t file, int all)
{
    char tmp[512];
    struct tvpal_text b = {tmp, 0, sizeof tmp, 0, 0};
    struct walk w = {.all = all, .list = &b};
    tvpal_text_put(&b, "datasets: ");
    H5Lvisit(file, H5_INDEX_NAME, H5_ITER_INC, visit, &w);
    H5Eclear2(H5E_DEFAULT);
    if (!w.nlisted)
        tvpal_text_put(&b, "none");
    if (b.full || b.len >= cap)
        snprintf(tmp + (cap > 4 ? cap - 4 : 0), 4, "...");
    tvpal_input_copy_str(out, cap, tmp);
}

/* ------------------------------------------ files named inside the file */

/* The files an HDF5 file names are opened by the library, not by tvpal:
 * the targets of external links and a dataset's external storage.  Each
 * is checked as a top-level input is (tvpal_open_regular: a FIFO there
 * would block the library for ever), where the library looks for it: as
 * named (from the working directory) and beside the file that names it. */
struct named_file {
    const char *parent;         /* the file that names it */
    int allow;                  /* opts->allow_external */
    int external;               /* a link to another file was met */
    char bad[sizeof ((struct tvpal_diag *)0)->msg];  /* why it was refused */
};

/* 0, or -1 with c->bad set: name (as given, or beside c->parent) exists
 * and is not a regular file. */
static int check_named(struct named_file *c, const char *name)
{
    char beside[4096];
    const char *slash = strrchr(c->parent, '/');
    int k = name[0] == '/' || !slash ? -1
            : snprintf(beside, sizeof beside, "%.*s/%s",
                       (int)(slash - c->parent), c->parent, name);
    const char *cand[2] = {name, k > 0 && (size_t)k < sizeof beside ? beside
                                                                    : NULL};
    for (int i = 0; i < 2; i++) {
        struct stat st;
        if (!cand[i] || stat(cand[i], &st) < 0)
            continue;
        struct tvpal_diag d;
        int fd = tvpal_open_regular(cand[i], &d);
        if (fd < 0) {
            snprintf(c->bad, sizeof c->bad, "%s", d.msg);
            return -1;
        }
        close(fd);
    }
    return 0;
}

/* The library's callback before it follows an external link. */
static herr_t on_elink(const char *parent_file, const char *parent_group,
                       const char *child_file, const char *child_object,
                       unsigned *acc_flags, hid_t fapl, void *op)
{
    (void)parent_file, (void)parent_group, (void)child_object;
    (void)acc_flags, (void)fapl;
    struct named_file *c = op;
    if (!c->allow) {
        c->external = 1;
        snprintf(c->bad, sizeof c->bad, "%s", child_file);
        return -1;
    }
    return check_named(c, child_file) < 0 ? -1 : 0;
}

/* H5Oopen(file, path) with every external link on the path checked:
 * < 0 with c->bad set when one names a file that is not regular. */
static hid_t open_checked(hid_t file, const char *path, struct named_file *c)
{
    hid_t lapl = H5Pcreate(H5P_LINK_ACCESS);
    if (lapl < 0 || H5Pset_elink_cb(lapl, on_elink, c) < 0) {
        if (lapl >= 0)
            H5Pclose(lapl);
        return H5Oopen(file, path, H5P_DEFAULT);
    }
    hid_t o = H5Oopen(file, path, lapl);
    H5Pclose(lapl);
    return o;
}

/* A virtual dataset's source files (H5Pset_virtual): refused unless
 * allowed; each must then exist and be a regular file (a missing source
 * reads as fill values, silently). */
static int check_virtual_sources(const struct tvpal_input_file *f, hid_t dcpl,
                                 int allow, struct tvpal_diag *diag)
{
    size_t n = 0;
    if (H5Pget_layout(dcpl) != H5D_VIRTUAL ||
        H5Pget_virtual_count(dcpl, &n) < 0)
        return 0;
    struct named_file c = {.parent = f->path};
    for (size_t i = 0; i < n; i++) {
        char name[4096];
        if (H5Pget_virtual_filename(dcpl, i, name, sizeof name) < 0)
            continue;
        name[sizeof name - 1] = 0;
        if (!strcmp(name, "."))   /* the file itself */
            continue;
        if (!allow)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: dataset %s is "
                                  "virtual, its data in %s: not read "
                                  "unless --allow-external is given",
                                  f->path, f->var, name);
        char beside[4096];
        const char *slash = strrchr(f->path, '/');
        struct stat st;
        int k = name[0] == '/' || !slash ? -1
                : snprintf(beside, sizeof beside, "%.*s/%s",
                           (int)(slash - f->path), f->path, name);
        if (stat(name, &st) < 0 &&
            (k < 0 || (size_t)k >= sizeof beside || stat(beside, &st) < 0))
            return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: dataset %s: its "
                                  "virtual source %s is missing (it would "
                                  "read as fill values)", f->path, f->var,
                                  name);
        if (check_named(&c, name) < 0)
            return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: dataset %s: its "
                                  "virtual source: %s", f->path, f->var,
                                  c.bad);
    }
    return 0;
}

/* The dataset's external storage files (H5Pset_external) and virtual
 * sources: refused unless allowed, each checked when allowed. */
static int check_external_storage(const struct tvpal_input_file *f, int allow,
                                  struct tvpal_diag *diag)
{
    hid_t dcpl = H5Dget_create_plist(f->dset);
    int n = dcpl >= 0 ? H5Pget_external_count(dcpl) : 0;
    struct named_file c = {.parent = f->path};
    int rc = dcpl >= 0 ? check_virtual_sources(f, dcpl, allow, diag) : 0;
    for (int i = 0; i < n && rc == 0; i++) {
        char name[4096];
        off_t off;
        hsize_t size;
        if (H5Pget_external(dcpl, (unsigned)i, sizeof name, name, &off,
                            &size) < 0)
            continue;
        name[sizeof name - 1] = 0;
        if (!allow)
            rc = tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: dataset %s keeps "
                                "its data in %s (external storage): not read "
                                "unless --allow-external is given", f->path,
                                f->var, name);
        else if (check_named(&c, name) < 0)
            rc = tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: dataset %s: its "
                                "external storage: %s", f->path, f->var,
                                c.bad);
    }
    if (dcpl >= 0)
        H5Pclose(dcpl);
    H5Eclear2(H5E_DEFAULT);
    return rc;
}

/* The dataset to read: opts->var, or the only candidate.  Opens f->dset
 * and sets f->var. */
static int choose_dataset(struct tvpal_input_file *f,
                          const struct tvpal_input_opts *opts,
                          struct tvpal_diag *diag)
{
    /* the list gets what the diag has left after the rest of the message */
    char list[200];
    size_t other = strlen(f->path) + 60 + (opts->var ? strlen(opts->var) : 0);
    size_t room = sizeof diag->msg > other + 40 ? sizeof diag->msg - other : 40;
    if (room > sizeof list)
        room = sizeof list;
    if (opts->var) {
        int n = snprintf(f->var, sizeof f->var, "%s%s",
                         opts->var[0] == '/' ? "" : "/", opts->var);
        if (n < 0 || (size_t)n >= sizeof f->var)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: dataset path %s "
                                  "is too long (at most %zu characters)",
                                  f->path, opts->var, sizeof f->var - 2);
        struct named_file c = {.parent = f->path,
                               .allow = opts->allow_external};
        hid_t o = open_checked(f->file, f->var, &c);
        H5Eclear2(H5E_DEFAULT);
        if (o < 0 && c.external)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: %s crosses an "
                                  "external link to %s: not followed unless "
                                  "--allow-external is given", f->path,
                                  f->var, c.bad);
        if (o < 0 && c.bad[0])
            return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s: an external "
                                  "link to %s", f->path, f->var, c.bad);
        if (o >= 0 && H5Iget_type(o) == H5I_DATASET) {
            f->dset = o;
            return 0;
        }
        if (o >= 0) {
            H5Oclose(o);
            list_datasets(list, room, f->file, 1);
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: %s is not a "
                                  "dataset; %s", f->path, f->var, list);
        }
        list_datasets(list, room, f->file, 1);
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: no dataset %s; %s",
                              f->path, f->var, list);
    }
    struct walk w = {0};
    char tmp[8];
    struct tvpal_text b = {tmp, 0, sizeof tmp, 0, 0};
    w.list = &b;
    int rc = walk(f->file, &w, f->path, diag);
    if (rc < 0)
        return rc;
    if (w.ncand == 1 && !w.long_name) {
        tvpal_input_copy_str(f->var, sizeof f->var, w.cand);
        if ((f->dset = H5Dopen2(f->file, f->var, H5P_DEFAULT)) < 0)
            return h5_fail(diag, TVPAL_E_FORMAT, f->path, f->var,
                           "cannot open it");
        return 0;
    }
    if (w.ncand == 1)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: the dataset's path "
                              "is too long (at most %zu characters)", f->path,
                              sizeof f->var - 1);
    if (w.ncand == 0) {
        list_datasets(list, room, f->file, 1);
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: no numeric dataset "
                              "of rank 3 (z, y, x) or 4 (time, z, y, x); %s",
                              f->path, list);
    }
    list_datasets(list, room, f->file, 0);
    return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: %d datasets could be "
                          "read, give one (--var /group/dataset); %s", f->path,
                          w.ncand, list);
}

/* The dataset's shape, type and attributes into f and info. */
static int read_layout(struct tvpal_input_file *f,
                       struct tvpal_input_info *info, struct tvpal_diag *diag)
{
    hsize_t dims[MAX_RANK];
    int rank = shape_of(f->dset, dims);
    if (rank < 0)
        return h5_fail(diag, TVPAL_E_FORMAT, f->path, f->var,
                       "cannot read its dataspace");
    char shape[160];
    struct tvpal_text b = {shape, 0, sizeof shape, 0, 0};
    put_shape(&b, dims, rank);
    hid_t t = H5Dget_type(f->dset);
    if (t < 0)
        return h5_fail(diag, TVPAL_E_FORMAT, f->path, f->var,
                       "cannot read its type");
    int numeric = is_numeric(t);
    const char *tname = type_name(t);
    f->is_f32 = H5Tget_class(t) == H5T_FLOAT && H5Tget_size(t) == 4;
    info->type = numeric ? stored_type(t) : TVPAL_F32;
    H5Tclose(t);
    if (!numeric)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: dataset %s %s is of "
                              "type %s, not numbers", f->path, f->var, shape,
                              tname);
    if (rank != 3 && rank != 4)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: dataset %s %s has "
                              "rank %d; rank 3 (z, y, x) or 4 (time, z, y, "
                              "x) is read", f->path, f->var, shape, rank);
    f->rank = rank;
    memcpy(f->dims, dims, sizeof *dims * (size_t)rank);
    f->nvox = 1;
    for (int a = 0; a < 3; a++) {
        hsize_t len = dims[rank - 1 - a];
        if (len == 0)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: dataset %s %s is "
                                  "empty", f->path, f->var, shape);
        if (len > UINT32_MAX || f->nvox > SIZE_MAX / 8 / len)
            return tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "%s: dataset %s %s "
                                  "is too large", f->path, f->var, shape);
        f->nvox *= (size_t)len;
        info->dims[a] = (uint32_t)len;
    }
    if (rank == 4 && dims[0] > UINT32_MAX)
        return tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "%s: dataset %s %s has "
                              "too many steps", f->path, f->var, shape);
    f->steps = rank == 4 ? (uint32_t)dims[0] : 1;

    double v[MAX_MISSING];
    /* A missing_value list longer than is read would be ignored whole,
     * and its values taken as data: refused instead. */
    const long mlen = att_len(f->dset, "missing_value");
    if (mlen > MAX_MISSING - 1)
        return tvpal_diag_set(diag, TVPAL_E_RANGE, "%s: dataset %s: its "
                              "missing_value holds %ld values; at most %d are "
                              "read", f->path, f->var, mlen, MAX_MISSING - 1);
    int n = num_att(f->dset, "_FillValue", v, MAX_MISSING);
    n += num_att(f->dset, "missing_value", v + n, MAX_MISSING - n);
    for (int i = 0; i < n; i++)
        if (!isnan(v[i]))
            /* a float dataset holds the float the value rounds to */
            f->miss[f->nmiss++] = f->is_f32 && fabs(v[i]) <= 3.4e38
                                      ? (double)(float)v[i] : v[i];
    info->missing_attrs = n > 0;
    /* CF packing, as the NetCDF reader applies it: a packed int16 was
     * encoded as its raw counts (0..999 labelled K instead of 273..283). */
    double sc[1] = {1}, of[1] = {0};
    const int has_scale = num_att(f->dset, "scale_factor", sc, 1) == 1;
    const int has_offset = num_att(f->dset, "add_offset", of, 1) == 1;
    if ((has_scale || has_offset) && (sc[0] != 1 || of[0] != 0)) {
        if (!isfinite(sc[0]) || !isfinite(of[0]) || sc[0] == 0)
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: dataset %s: "
                                  "scale_factor %g, add_offset %g (finite, "
                                  "a non-zero scale expected)", f->path,
                                  f->var, sc[0], of[0]);
        f->packed = 1;
        f->scale = sc[0];
        f->offset = of[0];
        f->is_f32 = 0;   /* unpacked through doubles, not read directly */
        info->type = TVPAL_F32;
    }
    text_att(f->dset, "units", info->units, sizeof info->units);
    return 0;
}

static void h5_close(struct tvpal_input_file *f)
{
    if (!f)
        return;
    tvpal_input_hdf5_direct_close(f->direct);
    if (f->mspace >= 0)
        H5Sclose(f->mspace);
    if (f->fspace >= 0)
        H5Sclose(f->fspace);
    if (f->dset >= 0)
        H5Dclose(f->dset);
    if (f->file >= 0)
        H5Fclose(f->file);
    H5Eclear2(H5E_DEFAULT);
    free(f->scratch);
    free(f->path);
    free(f);
}

/* Chunk sizes (x, y, z), the bytes of a chunk and of the library's chunk
 * cache; 1 1 1 and 0 for contiguous data. */
/* The most bytes a chunk may take: the reader allocates a chunk (and the
 * library fills one) whatever the file holds, so a small file claiming
 * chunks larger than its data would have it allocate what it claims. */
static uint64_t chunk_bytes_max(const struct tvpal_input_file *f,
                                uint64_t elem)
{
    uint64_t step;
    if (tvpal_mul(f->nvox, elem, &step) < 0 || step > UINT64_MAX / 4)
        return UINT64_MAX;
    return step * 4 > ((uint64_t)16 << 20) ? step * 4 : (uint64_t)16 << 20;
}

static int read_chunking(struct tvpal_input_file *f, struct tvpal_diag *diag)
{
    f->chunk[0] = f->chunk[1] = f->chunk[2] = 1;
    hid_t dcpl = H5Dget_create_plist(f->dset);
    hsize_t c[4];
    int rc = 0;
    if (dcpl >= 0 && H5Pget_layout(dcpl) == H5D_CHUNKED &&
        H5Pget_chunk(dcpl, f->rank, c) == f->rank) {
        hid_t t = H5Dget_type(f->dset);
        const uint64_t elem = t >= 0 ? H5Tget_size(t) : 8;
        uint64_t cb = elem;
        for (int i = 0; i < f->rank && rc == 0; i++)
            if (tvpal_mul(cb, c[i], &cb) < 0)
                cb = UINT64_MAX;
        if (cb > chunk_bytes_max(f, elem))
            rc = tvpal_diag_set(diag, TVPAL_E_RANGE, "%s: dataset %s: chunks "
                                "of %llu bytes, more than 4 times a step of "
                                "its data (%llu values): refused", f->path,
                                f->var, (unsigned long long)cb,
                                (unsigned long long)f->nvox);
        f->chunk_bytes = (size_t)cb;
        for (int a = 0; a < 3; a++)
            f->chunk[a] = c[f->rank - 1 - a] <= UINT32_MAX
                              ? (uint32_t)c[f->rank - 1 - a] : UINT32_MAX;
        if (t >= 0)
            H5Tclose(t);
        hid_t dapl = H5Dget_access_plist(f->dset);
        size_t slots, bytes = 0;
        double w0;
        if (dapl >= 0 && H5Pget_chunk_cache(dapl, &slots, &bytes, &w0) >= 0)
            f->cache = bytes;
        if (dapl >= 0)
            H5Pclose(dapl);
    }
    if (dcpl >= 0)
        H5Pclose(dcpl);
    H5Eclear2(H5E_DEFAULT);
    return rc;
}

static int h5_open(struct tvpal_input_file **out, const char *path,
                   const struct tvpal_input_opts *opts,
                   struct tvpal_input_info *info, double **times,
                   struct tvpal_diag *diag)
{
    struct tvpal_input_file *f = calloc(1, sizeof *f);
    if (!f || !(f->path = strdup(path))) {
        free(f);
        return TVPAL_E_NOMEM;
    }
    f->file = f->dset = f->fspace = f->mspace = NO_ID;
    int rc = open_file(path, &f->file, diag);
    if (rc == 0)
        rc = choose_dataset(f, opts, diag);
    if (rc == 0)
        rc = check_external_storage(f, opts->allow_external, diag);
    if (rc == 0)
        rc = read_layout(f, info, diag);
    if (rc == 0) {
        hsize_t n = f->nvox;
        if ((f->fspace = H5Dget_space(f->dset)) < 0 ||
            (f->mspace = H5Screate_simple(1, &n, NULL)) < 0)
            rc = h5_fail(diag, TVPAL_E_FORMAT, path, f->var,
                         "cannot make its dataspaces");
    }
    if (rc == 0)
        rc = read_chunking(f, diag);
    if (rc == 0 && !f->packed)
        rc = direct_for(f->dset, path, f->var, opts->pool, &f->direct);
    if (rc < 0) {
        h5_close(f);
        return rc;
    }
    info->steps = f->steps;
    tvpal_input_copy_str(info->var, sizeof info->var, f->var);
    *out = f;
    return 0;
}

static inline int missing(const struct tvpal_input_file *f, double v)
{
    for (int i = 0; i < f->nmiss; i++)
        if (v == f->miss[i])
            return 1;
    return 0;
}

static int check_step(const struct tvpal_input_file *f, uint32_t k,
                      struct tvpal_diag *diag)
{
    if (k >= f->steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: dataset %s: step %u "
                              "of %u", f->path, f->var, k, f->steps);
    return 0;
}

/* The hyperslab of box [lo, lo + n) of step k into buf as mtype. */
static int h5_read_slab(struct tvpal_input_file *f, uint32_t k,
                        const uint32_t lo[3], const uint32_t n[3],
                        hid_t mtype, void *buf, struct tvpal_diag *diag)
{
    hsize_t start[4] = {0}, count[4] = {1, 1, 1, 1};
    const int s = f->rank - 3;
    if (f->rank == 4)
        start[0] = k;
    for (int a = 0; a < 3; a++) {
        start[s + 2 - a] = lo[a];
        count[s + 2 - a] = n[a];
    }
    hsize_t m = (hsize_t)n[0] * n[1] * n[2];
    hid_t ms = NO_ID;
    if (H5Sselect_hyperslab(f->fspace, H5S_SELECT_SET, start, NULL, count,
                            NULL) < 0 ||
        (ms = H5Screate_simple(1, &m, NULL)) < 0)
        return h5_fail(diag, TVPAL_E_READ, f->path, f->var,
                       "cannot select a box");
    herr_t st = H5Dread(f->dset, mtype, ms, f->fspace, H5P_DEFAULT, buf);
    H5Sclose(ms);
    if (st < 0) {
        char what[128];
        snprintf(what, sizeof what, "cannot read step %u (box at %u %u %u of "
                 "size %u %u %u)", k, lo[0], lo[1], lo[2], n[0], n[1], n[2]);
        return h5_fail(diag, TVPAL_E_READ, f->path, f->var, what);
    }
    return 0;
}

static int h5_read_box(struct tvpal_input_file *f, uint32_t k,
                       const uint32_t lo[3], const uint32_t n[3], float *dst,
                       struct tvpal_diag *diag)
{
    quiet();
    int rc = check_step(f, k, diag);
    if (rc < 0)
        return rc;
    const size_t nbox = (size_t)n[0] * n[1] * n[2];
    if (f->is_f32) {
        rc = f->direct ? tvpal_input_hdf5_direct_read_box(f->direct, k, lo, n,
                                                          dst, diag)
                       : 1;
        if (rc == 1)
            rc = h5_read_slab(f, k, lo, n, H5T_NATIVE_FLOAT, dst, diag);
        for (size_t i = 0; rc == 0 && f->nmiss && i < nbox; i++)
            if (missing(f, dst[i]))
                dst[i] = NAN;
        return rc;
    }
    struct tvpal_box_split sp;
    tvpal_box_split_init(&sp, lo, n, f->chunk, TVPAL_BOX_PIECE);
    const size_t need = (size_t)tvpal_box_split_most(&sp);
    if (need > f->scratch_cap) {
        free(f->scratch);
        f->scratch_cap = 0;
        if (!(f->scratch = malloc(need * sizeof *f->scratch)))
            return TVPAL_E_NOMEM;
        f->scratch_cap = need;
    }
    uint32_t plo[3], pn[3];
    while (tvpal_box_split_next(&sp, plo, pn)) {
        rc = h5_read_slab(f, k, plo, pn, H5T_NATIVE_DOUBLE, f->scratch, diag);
        if (rc < 0)
            return rc;
        const double *v = f->scratch;
        for (uint32_t z = 0; z < pn[2]; z++)
            for (uint32_t y = 0; y < pn[1]; y++) {
                float *row = dst + (plo[0] - lo[0]) +
                             ((size_t)(plo[2] - lo[2] + z) * n[1] +
                              (plo[1] - lo[1] + y)) * n[0];
                for (uint32_t x = 0; x < pn[0]; x++, v++)
                    row[x] = missing(f, *v) ? NAN
                             : f->packed ? (float)(*v * f->scale + f->offset)
                                         : (float)*v;
            }
    }
    return 0;
}

static uint64_t h5_box_scratch(const struct tvpal_input_file *f,
                               const uint32_t n[3])
{
    if (f->is_f32)
        return f->direct ? tvpal_input_hdf5_direct_scratch(f->direct)
                         : f->cache + f->chunk_bytes;
    struct tvpal_box_split sp;
    const uint32_t zero[3] = {0, 0, 0};
    tvpal_box_split_init(&sp, zero, n, f->chunk, TVPAL_BOX_PIECE);
    /* the pieces, the cache and a chunk, the library's conversion buffer
     * (1 MiB by default) */
    return tvpal_box_split_most(&sp) * sizeof(double) + f->cache +
           f->chunk_bytes + ((uint64_t)1 << 20);
}

static int h5_read(struct tvpal_input_file *f, uint32_t k, float *dst,
                   struct tvpal_diag *diag)
{
    quiet();
    int rc = check_step(f, k, diag);
    if (rc < 0)
        return rc;
    if (!f->is_f32) {
        const uint32_t zero[3] = {0, 0, 0};
        uint32_t dims[3];
        for (int a = 0; a < 3; a++)
            dims[a] = (uint32_t)f->dims[f->rank - 1 - a];
        return h5_read_box(f, k, zero, dims, dst, diag);
    }
    rc = f->direct ? tvpal_input_hdf5_direct_read(f->direct, k, dst, diag)
                   : 1;
    if (rc < 0)
        return rc;
    if (rc == 0)
        goto read;
    hsize_t start[4] = {0}, count[4];
    memcpy(count, f->dims, sizeof count);
    if (f->rank == 4)
        start[0] = k, count[0] = 1;
    if (H5Sselect_hyperslab(f->fspace, H5S_SELECT_SET, start, NULL, count,
                            NULL) < 0)
        return h5_fail(diag, TVPAL_E_READ, f->path, f->var,
                       "cannot select a step");
    if (H5Dread(f->dset, H5T_NATIVE_FLOAT, f->mspace, f->fspace, H5P_DEFAULT,
                dst) < 0) {
        char what[48];
        snprintf(what, sizeof what, "cannot read step %u", k);
        return h5_fail(diag, TVPAL_E_READ, f->path, f->var, what);
    }
read:
    if (f->nmiss)
        for (size_t i = 0; i < f->nvox; i++)
            if (missing(f, dst[i]))
                dst[i] = NAN;
    return 0;
}

static int h5_describe(const char *path, char **text, struct tvpal_diag *diag)
{
    quiet();
    hid_t file;
    *text = NULL;
    int rc = open_file(path, &file, diag);
    if (rc < 0)
        return rc;
    struct tvpal_text b = {malloc(256), 0, 256, 0, 1};
    if (!b.s) {
        H5Fclose(file);
        return TVPAL_E_NOMEM;
    }
    tvpal_text_put(&b, "hdf5\n");
    struct walk w = {.describe = 1, .list = &b};
    rc = walk(file, &w, path, diag);
    H5Fclose(file);
    H5Eclear2(H5E_DEFAULT);
    if (rc == 0 && b.full)
        rc = TVPAL_E_NOMEM;
    if (rc < 0) {
        free(b.s);
        return rc;
    }
    *text = b.s;
    return 0;
}

const struct tvpal_input_backend tvpal_input_hdf5 = {
    .name = "hdf5", .open = h5_open, .read = h5_read,
    .read_box = h5_read_box, .box_scratch = h5_box_scratch,
    .close = h5_close, .describe = h5_describe};
