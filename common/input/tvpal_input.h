/* tvpal_input.h: readers of self-describing simulation output (NetCDF,
 * HDF5, VTK ImageData, legacy VTK), one timestep at a time.
 *
 * A series is one or more files of one format holding one variable in
 * time order: a file may hold one timestep or several (a time dimension).
 * The variable's last three dimensions are z, y, x whatever their names;
 * tvpal_input_read gives a timestep as float32, x fastest, with missing
 * values (CF _FillValue, missing_value, outside valid_min/max/range) as NaN,
 * so the encoder's NaN policy (refuse, or --nan-as) applies to them.  A
 * reader holds at most one timestep's worth of scratch: memory does not
 * grow with the files.  tvpal_input_read_box reads a part of a timestep
 * (a slab of slices, one MPI rank's share) without a whole-step buffer,
 * with the scratch tvpal_input_box_scratch says.  Raw files are read by
 * the encoder itself (tvpal_raw.h); this interface is for the formats that
 * say what they hold.
 *
 * Each format is one backend file, the only one that includes its library
 * (LAYERS.md): tvpal_in_netcdf.c (libnetcdf), tvpal_in_hdf5.c (libhdf5),
 * tvpal_in_vti.c (expat, zlib: .vti, .pvti and .pvd collections),
 * tvpal_in_vtk.c (legacy .vtk, stdio).
 * A build without a library has its _none.c twin, which refuses the format
 * naming the Debian package to install.
 *
 * All functions return 0 or a negative TVPAL_E_* code and never print; the
 * diag (optional, caller-owned) names the file, the variable and what was
 * expected. */
#ifndef TVPAL_INPUT_H
#define TVPAL_INPUT_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_error.h"
#include "tvpal_raw.h"

enum tvpal_input_format {
    TVPAL_IN_AUTO,     /* from the file's own bytes (tvpal_input_detect) */
    TVPAL_IN_RAW,      /* no header: dims and type must be given */
    TVPAL_IN_NETCDF,   /* classic, 64-bit offset, CDF-5 and NetCDF-4 */
    TVPAL_IN_VTI,      /* VTK XML ImageData (.vti, .pvti), and .pvd
                        * collections of them */
    TVPAL_IN_VTK,      /* legacy VTK STRUCTURED_POINTS (.vtk) */
    TVPAL_IN_HDF5      /* HDF5 datasets by path (serial libhdf5) */
};

/* "auto", "raw", "netcdf", "vti", "vtk", "hdf5" <-> the enum; parse: 0 or
 * TVPAL_E_INVAL. */
const char *tvpal_input_format_name(enum tvpal_input_format f);
int tvpal_input_format_parse(const char *s, enum tvpal_input_format *f);

/* The format of path from its own bytes, never from its name: "CDF\1",
 * "CDF\2" and "CDF\5" are NetCDF; a file with HDF5's signature is NetCDF
 * (NetCDF-4 is HDF5) unless the NetCDF reader refuses it as not NetCDF
 * (TVPAL_E_FORMAT: a plain HDF5 file without netCDF's metadata, or a
 * damaged one), then hdf5; an XML file with a <VTKFile> root is vti (the
 * reader refuses VTK types other than ImageData, PImageData and Collection
 * by name); "# vtk DataFile" is legacy vtk; anything else is raw.
 * TVPAL_E_OPEN or TVPAL_E_READ when path cannot be read.
 *
 * With opts (may be NULL), one more rule: a file with HDF5's signature
 * whose opts->var starts with '/' (a dataset path) is hdf5, NetCDF-4 or not
 * (a variable in a group of a NetCDF-4 file).  --format hdf5
 * (TVPAL_IN_HDF5) reads any HDF5 file as HDF5.  tvpal_input_open with
 * TVPAL_IN_AUTO detects with its opts. */
struct tvpal_input_opts;
struct tvpal_pool;
int tvpal_input_detect(const char *path, const struct tvpal_input_opts *opts,
                       enum tvpal_input_format *f, struct tvpal_diag *diag);

/* Kept by tvpal_input_open as given: its strings must outlive the input
 * (a series reopens its files with them). */
struct tvpal_input_opts {
    const char *var;        /* variable (NetCDF), dataset path such as
                             * /group/dataset (HDF5) or point array (vti);
                             * NULL: the only candidate (HDF5: the only
                             * numeric dataset of rank 3 or 4), or vti's
                             * active Scalars */
    const char *time_dim;   /* NetCDF: the time dimension; NULL: the
                             * unlimited one, else the dimension a CF time
                             * coordinate (units "... since ...") names,
                             * else the first of a 4-D variable */
    int allow_external;     /* HDF5: read a dataset whose bytes live in
                             * other files (an external link on its
                             * path, external storage, a virtual
                             * dataset's sources); 0: refused, naming
                             * the file, since such a small file can
                             * read any file the user can */
    int magnitude;          /* VTK (vti, legacy vtk): a point array of
                             * several components (a vector, a tensor)
                             * is read as its Euclidean length at each
                             * point: the square root of the sum of the
                             * components' squares, in double, rounded to
                             * float32 once; 0: such an array is refused,
                             * naming it.  A scalar array (and a NetCDF or
                             * HDF5 variable) is read as it is.  At most
                             * TVPAL_INPUT_COMPONENTS_MAX components */
    struct tvpal_pool *pool;  /* the threads that inflate compressed
                             * blocks and chunks (VTK XML, HDF5 and
                             * NetCDF-4): borrowed, it must outlive the
                             * input, and only the thread that reads may
                             * drive it (tvpal_pool.h); NULL: the reading
                             * thread alone */
};

/* The longest variable name or dataset path read, with its NUL: NetCDF's
 * names (NC_MAX_NAME, 256) fit; a VTK array or HDF5 path beyond it is
 * refused by name.  A name cut short would name another variable (a
 * resume of another job, a report reading the wrong one). */
#define TVPAL_INPUT_VAR_MAX 512

/* The most components of a point array read with magnitude (a point's
 * stored bytes are held whole while its length is taken: 2 KiB at most). */
#define TVPAL_INPUT_COMPONENTS_MAX 256

/* What a series holds, from its files. */
struct tvpal_input_info {
    uint32_t dims[3];           /* x, y, z */
    uint32_t steps;             /* over all files */
    enum tvpal_type type;       /* the stored type (f32 after CF unpacking
                                 * of packed integers, f64 for doubles;
                                 * of each component where there are
                                 * several) */
    char var[TVPAL_INPUT_VAR_MAX];  /* the variable read, whole (a
                                 * longer name is refused, never cut) */
    uint32_t components;        /* of var at each point: 1, or (opts
                                 * magnitude) several, read as their
                                 * length; every file of a series alike */
    char units[64];             /* its units attribute, or "" */
    char dim_names[3][64];      /* x, y, z dimension names, or "" */
    double spacing[3], origin[3];  /* 1 and 0 where the file says nothing;
                                 * spacing < 0 for falling coordinates
                                 * (latitude north to south) */
    int nonuniform[3];          /* 1: the axis' coordinates are not evenly
                                 * spaced (spacing then 1, origin 0) */
    int has_times;              /* times from the files (tvpal_input_time) */
    char time_units[128];       /* e.g. "hours since 2005-08-28 00:00:00" */
    uint64_t missing_attrs;     /* 1: fill/missing/valid-range attributes
                                 * that reading turns into NaN */
};

struct tvpal_input;

/* Opens files[0..nfiles) as one series of format fmt (AUTO: detected
 * from files[0]; every file must be of that format).  A .pvd collection
 * (vti) stands for its DataSets' files, sorted by timestep, whose
 * timesteps are the times (has_times); several collections are strung
 * together; collections and plain files cannot be mixed.  Checks that every
 * file has the variable with the same spatial dims.  Owns *out on
 * success (tvpal_input_close).  Errors: TVPAL_E_OPEN, TVPAL_E_FORMAT (not
 * such a file, corrupt), TVPAL_E_INVAL (no such variable: the diag lists
 * the variables; fewer than 3 spatial dims; several steps per file wanted
 * and no time dimension), TVPAL_E_MISMATCH (dims differ between files),
 * TVPAL_E_SYS (format not built: the diag names the package). */
int tvpal_input_open(struct tvpal_input **out, enum tvpal_input_format fmt,
                     char *const *files, int nfiles,
                     const struct tvpal_input_opts *opts,
                     struct tvpal_diag *diag);
void tvpal_input_close(struct tvpal_input *in);   /* NULL is a no-op */

const struct tvpal_input_info *tvpal_input_info(const struct tvpal_input *in);

/* The format the series is read as (AUTO resolved). */
enum tvpal_input_format tvpal_input_format(const struct tvpal_input *in);

/* Timestep t (0-based over the series) into dst: dims[0] * dims[1] *
 * dims[2] floats, x fastest; missing values NaN.  Reads only that step
 * (hyperslab or array of one file). */
int tvpal_input_read(struct tvpal_input *in, uint32_t t, float *dst,
                     struct tvpal_diag *diag);

/* The box [lo, lo + n) of timestep t (x, y, z; 1 <= n[a] and lo[a] + n[a]
 * <= dims[a]) into dst: n[0] * n[1] * n[2] floats, x fastest, box-dense;
 * missing values NaN: exactly the values tvpal_input_read gives for those
 * voxels, bit for bit.  Reads only what the box needs where the format
 * allows (hyperslabs, the HDF5 chunks or VTK blocks that meet the box,
 * the box's rows of raw data in batches); the scratch it holds is
 * tvpal_input_box_scratch's.  Errors: TVPAL_E_INVAL (t past the steps, an
 * n[a] of 0, a box outside the grid: the diag names the file, the
 * variable, the step and the box), else those of tvpal_input_read. */
int tvpal_input_read_box(struct tvpal_input *in, uint32_t t,
                         const uint32_t lo[3], const uint32_t n[3],
                         float *dst, struct tvpal_diag *diag);

/* Bytes of scratch memory a box read of size n holds beyond dst (kept by
 * the reader between calls; and the format library's chunk cache where it
 * fills one), so that a caller can plan its memory: an upper bound, for
 * the file open now (the files of a series laid out alike).  0 for an
 * empty n.  By format:
 *   netcdf  float: none (classic), the library's chunk cache (NetCDF-4),
 *           or, deflated chunks being read directly, as hdf5 below; other
 *           types: pieces of at most 1 Mi values in the stored type (a
 *           layer, band or run of chunks where one is larger), and the
 *           cache;
 *   hdf5    float32: the library's chunk cache and one chunk, or (deflated
 *           chunks read directly) two compressed chunks per thread, two
 *           chunks of work per thread and the chunk tables; other types:
 *           pieces of at most 1 Mi doubles as above, the cache, a chunk
 *           and the library's 1 MiB conversion buffer;
 *   vti     raw appended: at most 4 MiB of rows (none for float32 in the
 *           host's byte order and boxes of whole x-rows; the rows with all
 *           their points' components for magnitude); zlib blocks: one
 *           compressed and one inflated block and the block table; base64:
 *           a 64 KiB piece; ascii: none (the text is parsed as it is
 *           read, through a 32 KiB window on the stack); .pvti: the most
 *           over its pieces; besides, while a call runs, the XML is read
 *           in pieces of 1 MiB (freed before it returns);
 *   vtk     binary: at most 4 MiB of rows (with all their points'
 *           components for magnitude); ascii: none (the values are
 *           parsed in order up to the box's last).
 * No format needs a whole timestep; a whole read of a vti array of several
 * components (magnitude) is such a box read of the whole grid. */
uint64_t tvpal_input_box_scratch(const struct tvpal_input *in,
                                 const uint32_t n[3]);

/* The time value of step t (has_times), else t. */
double tvpal_input_time(const struct tvpal_input *in, uint32_t t);

/* The file of step t and the step's index within it. */
const char *tvpal_input_file(const struct tvpal_input *in, uint32_t t,
                             uint32_t *index_in_file);

/* A listing of what path holds, for people (tvpal-info --inspect): the
 * format, then one line per variable with its dims, type and units.
 * *text is malloc'ed. */
int tvpal_input_describe(const char *path, enum tvpal_input_format fmt,
                         char **text, struct tvpal_diag *diag);

/* What inflates compressed input, for --version: "libdeflate 1.14 (also
 * HDF5 and NetCDF-4 chunks)", "zlib 1.2.13" or "none".  And how many
 * HDF5 or NetCDF-4 chunks libdeflate has inflated in this process (0
 * without it: the HDF5 library's own zlib filter does). */
const char *tvpal_input_inflate_library(void);
uint64_t tvpal_input_inflated_chunks(void);

#endif
