/* tvpal_input_impl.h: what a format backend of tvpal_input provides (for
 * tvpal_input.c and the backend files only).
 *
 * A backend opens one file at a time: tvpal_input.c strings the files of a
 * series together, checks that they agree and maps a series step to (file,
 * step in file). */
#ifndef TVPAL_INPUT_IMPL_H
#define TVPAL_INPUT_IMPL_H

#include "tvpal_input.h"

#include <math.h>
#include <string.h>

struct tvpal_input_file;   /* a backend's open file */

struct tvpal_input_backend {
    const char *name;      /* "netcdf", "vti", "vtk", "hdf5" */
    /* Opens path; fills info (steps: the steps in this file; times of
     * those steps into *times, malloc'ed, when info->has_times).  opts is
     * never NULL; info arrives zeroed but for spacing 1 1 1 and
     * components 1, and *times NULL (tvpal_input.c sets these defaults
     * once for every backend). */
    int (*open)(struct tvpal_input_file **out, const char *path,
                const struct tvpal_input_opts *opts,
                struct tvpal_input_info *info, double **times,
                struct tvpal_diag *diag);
    /* Step k of the file into dst (float32, x fastest, missing NaN). */
    int (*read)(struct tvpal_input_file *f, uint32_t k, float *dst,
                struct tvpal_diag *diag);
    /* The box [lo, lo + n) of step k into dst (box-dense, as read gives
     * those voxels); tvpal_input.c has checked k, lo and n against the
     * series' grid. */
    int (*read_box)(struct tvpal_input_file *f, uint32_t k,
                    const uint32_t lo[3], const uint32_t n[3], float *dst,
                    struct tvpal_diag *diag);
    /* What read_box holds for a box of size n (tvpal_input_box_scratch). */
    uint64_t (*box_scratch)(const struct tvpal_input_file *f,
                            const uint32_t n[3]);
    void (*close)(struct tvpal_input_file *f);
    int (*describe)(const char *path, char **text, struct tvpal_diag *diag);
    /* Non-NULL in a build without the format's library (the _none.c
     * twins): why it is refused and what to install; the functions above
     * are then NULL and never called. */
    const char *missing;
};

/* In a build with libnetcdf: whether path (an HDF5 file) lacks netCDF's
 * metadata, so it is plain HDF5 rather than NetCDF-4; 1 too when libnetcdf
 * cannot open it at all (a damaged file: the hdf5 reader says what is
 * wrong).  Without libnetcdf: 0 (NetCDF, which that build refuses). */
int tvpal_input_netcdf_plain_hdf5(const char *path);

extern const struct tvpal_input_backend tvpal_input_netcdf;
extern const struct tvpal_input_backend tvpal_input_vti;
extern const struct tvpal_input_backend tvpal_input_vtk;

/* A ParaView collection (.pvd: <VTKFile type="Collection">, parsed with
 * expat in tvpal_in_vti.c).  path not a collection (another root, another
 * VTKFile type, not XML): 0 with *files NULL and *n 0.  A collection: its
 * DataSets' files (relative paths resolved against path's directory),
 * sorted by timestep as VTK's reader does (a stable sort: document order
 * where the file is in order already), into *files (*n malloc'ed strings
 * in a malloc'ed array) and their timesteps into *times (malloc'ed; NULL
 * when the one DataSet of the file has no timestep).  Every file must be
 * readable.  Errors: TVPAL_E_FORMAT (XML error, no DataSet, a DataSet
 * without file or timestep, several parts or DataSets at one timestep),
 * TVPAL_E_OPEN (a DataSet's file: the diag names it and path). */
int tvpal_input_vtk_collection(const char *path, char ***files,
                               double **times, int *n,
                               struct tvpal_diag *diag);
extern const struct tvpal_input_backend tvpal_input_hdf5;

/* Direct chunk reading (tvpal_in_hdf5.c): a float32 dataset chunked one
 * step deep and compressed by deflate (with or without shuffle) is read
 * chunk by chunk as stored and inflated by tvpal_inflate, in parallel on
 * pool (tvpal_input_opts.pool; NULL: on the calling thread).
 * open: *out NULL (and 0) when path's dataset is not such a dataset, or
 * without HDF5.  read: step k (rank 4; rank 3: the one step) into dst;
 * 0, 1 when this step must be read through the library after all (a chunk
 * not stored), or TVPAL_E_FORMAT (a chunk that does not inflate) /
 * TVPAL_E_NOMEM with "FILE: DATASET: step K: ..." in diag.  inflated:
 * chunks inflated so in this process. */
struct tvpal_h5direct;
int tvpal_input_hdf5_direct_open(struct tvpal_h5direct **out,
                                 const char *path, const char *dataset,
                                 struct tvpal_pool *pool);
int tvpal_input_hdf5_direct_read(struct tvpal_h5direct *d, uint32_t k,
                                 float *dst, struct tvpal_diag *diag);
void tvpal_input_hdf5_direct_close(struct tvpal_h5direct *d);
/* The box [lo, lo + n) (x, y, z) of step k into dst (box-dense): only the
 * chunks that meet the box, in batches of two per thread.  0, 1 (read
 * through the library after all) or an error, as direct_read.  scratch:
 * the bytes it holds (tvpal_input_box_scratch). */
int tvpal_input_hdf5_direct_read_box(struct tvpal_h5direct *d, uint32_t k,
                                     const uint32_t lo[3], const uint32_t n[3],
                                     float *dst, struct tvpal_diag *diag);
uint64_t tvpal_input_hdf5_direct_scratch(const struct tvpal_h5direct *d);
uint64_t tvpal_input_hdf5_inflated(void);

/* Helpers the backends share (tvpal_input.c). */

/* Box reads of raw arrays (x fastest, dims[0] x dims[1] x dims[2] values
 * of `size` bytes at byte base of fd): the box [lo, lo + n) goes into dst,
 * value (x, y, z) of the box at dst[x + y * dy + z * dz].  Runs that are
 * contiguous in the file and in dst (whole x-rows) are one pread each,
 * straight into dst when conv is NULL (float32 as the host stores it);
 * shorter rows are read in batches of at most TVPAL_BOX_IO_CAP bytes
 * (the rows and the gaps between them, gaps up to TVPAL_BOX_GAP bytes)
 * and picked out.  conv(src, count, dst, ctx) turns count stored values
 * into floats.  io is the scratch, kept by the caller between calls
 * (free(io->buf)).  Errors: TVPAL_E_READ (the file system's), TVPAL_E_FORMAT
 * (the file ends within the values), TVPAL_E_NOMEM; the diag says
 * "PATH: WHAT: ...". */
#define TVPAL_BOX_IO_CAP ((size_t)4 << 20)
#define TVPAL_BOX_GAP ((size_t)64 << 10)
struct tvpal_box_io {
    unsigned char *buf;
    size_t cap;
};
typedef void (*tvpal_box_conv)(const unsigned char *src, size_t count,
                               float *dst, const void *ctx);
int tvpal_input_box_pread(int fd, uint64_t base, const uint32_t dims[3],
                          unsigned size, const uint32_t lo[3],
                          const uint32_t n[3], float *dst, size_t dy,
                          size_t dz, tvpal_box_conv conv, const void *ctx,
                          struct tvpal_box_io *io, const char *path,
                          const char *what, struct tvpal_diag *diag);
/* len bytes at offset off of fd into p (the errors as above). */
int tvpal_input_pread(int fd, unsigned char *p, size_t len, uint64_t off,
                      const char *path, const char *what,
                      struct tvpal_diag *diag);
/* The most io->buf grows to for such a read of a box of size n. */
uint64_t tvpal_input_box_pread_scratch(const uint32_t dims[3], unsigned size,
                                       const uint32_t n[3], int direct);

/* The pieces a box is read in where a backend reads through scratch (the
 * stored type, converted after): all of it when it has at most cap values;
 * else slabs of z-slices, then (a slab of one layer of chunks being too
 * large) bands of y-rows, then runs of x, each cut on multiples of chunk[]
 * (1 1 1 for contiguous data), so that each chunk of a chunked variable
 * is in one piece and inflated once.  A piece holds at most
 * tvpal_box_split_most values: cap, or one chunk's extent clipped to the
 * box where that is more.  next: 1 and the piece's lo and n, or 0 when
 * done. */
struct tvpal_box_split {
    uint32_t lo[3], n[3], chunk[3], d[3], at[3];
    int split[3], done;
};
void tvpal_box_split_init(struct tvpal_box_split *s, const uint32_t lo[3],
                          const uint32_t n[3], const uint32_t chunk[3],
                          uint64_t cap);
int tvpal_box_split_next(struct tvpal_box_split *s, uint32_t plo[3],
                         uint32_t pn[3]);
uint64_t tvpal_box_split_most(const struct tvpal_box_split *s);
#define TVPAL_BOX_PIECE ((uint64_t)1 << 20)   /* values per piece */

/* The length of a point of several components (tvpal_input_opts
 * magnitude), taken a component at a time in the stored order:
 *     double sum = 0;
 *     for each component v (its exact value as a double):
 *         sum = tvpal_input_mag_add(sum, v);
 *     value = tvpal_input_mag_end(sum);
 * Each square is rounded to double before it is added (no fused
 * multiply-add, which GCC makes on aarch64 and with -mfma: the volatile
 * keeps the two roundings), so that x*x + y*y + z*z summed left to right
 * in float64 by anyone (numpy) gives the same bits; the root is rounded to
 * float32 once.  A NaN component gives NaN, an infinite one infinity. */
static inline double tvpal_input_mag_add(double sum, double v)
{
    volatile double sq = v * v;
    return sum + sq;
}

static inline float tvpal_input_mag_end(double sum)
{
    return (float)sqrt(sum);
}

/* The variable a --var of the form "/NAME" (a dataset path at the root,
 * no group) names: NAME, a NetCDF-4 file's root variable; NULL for any
 * other var (a plain name, or a path inside a group: "/grp/NAME"). */
static inline const char *tvpal_input_root_var(const char *var)
{
    return var && var[0] == '/' && !strchr(var + 1, '/') ? var + 1 : NULL;
}

/* src into dst (cap bytes), cut to fit, always terminated. */
void tvpal_input_copy_str(char *dst, size_t cap, const char *src);

/* Text built by pieces: s of cap bytes (len used).  With grow, s is
 * malloc'ed and grows; without, a full buffer sets full and drops the
 * rest (as it does when growing fails). */
struct tvpal_text {
    char *s;
    size_t len, cap;
    int full;   /* fixed-size buffer ran out (growable: malloc failed) */
    int grow;
};
void tvpal_text_put(struct tvpal_text *b, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

#endif
