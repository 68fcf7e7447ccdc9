/* tvpal_in_netcdf.c: the netcdf backend of tvpal_input, on libnetcdf (the
 * only file of the tree that includes netcdf.h, LAYERS.md).  Classic,
 * 64-bit offset, CDF-5 and NetCDF-4/HDF5 files all go through nc_open; the
 * variables of the root group are read.  An HDF5 file without netCDF's
 * metadata is refused as not NetCDF (TVPAL_E_FORMAT): tvpal_in_hdf5.c
 * reads it.
 *
 * A variable's last three dims are z, y, x.  Its time dim is, in order:
 * opts->time_dim; the unlimited dim; a dim whose coordinate variable has CF
 * time units ("<unit> since <date>"); the first dim of a variable of 4
 * (or more) dims.  A 3-D variable is one step, unless one of its dims is
 * time by those rules (the file's unlimited dim, or the first dim of its
 * 4-D variables): it then has 2 spatial dims and is refused.  Dims other
 * than time, z, y and x must have length 1.
 *
 * Missing values follow CF (section 2.5.1 and 8.1): a stored value equal to
 * _FillValue or to one of missing_value's values, or outside valid_min /
 * valid_max / valid_range, becomes NaN; those tests are made on the stored
 * (packed) value.  Then scale_factor and add_offset unpack it, in double.
 * One exception, as netCDF-Java does it: a valid_* attribute of a packed
 * variable whose type is that of scale_factor/add_offset (not the stored
 * type) is in unpacked units and is tested after unpacking.
 *
 * read() reads one step's hyperslab (nc_get_vara) into the caller's floats
 * (float variables; NetCDF-4 deflated chunks directly, as the HDF5 backend
 * reads them); other types go through scratch in the stored type, in
 * pieces of at most TVPAL_BOX_PIECE values cut on the chunks' edges
 * (tvpal_box_split), so no type needs a step of scratch.  read_box reads
 * the box's hyperslab (time index first where the variable has time) the
 * same way, with the same missing values and unpacking. */
#include "tvpal_input_impl.h"
#include "tvpal_fs.h"

#include <netcdf.h>

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define MAX_DIMS 8       /* dims of one variable (time, extras, z, y, x) */
#define MAX_MISSING 64   /* _FillValue and missing_value's values */
#define MAX_TIME_DIMS 32 /* dims of a file that look like time */

struct tvpal_input_file {
    int ncid, varid;
    char *path;
    char var[NC_MAX_NAME + 1];
    nc_type xtype;
    int ndims, tpos;           /* tpos: index of the time dim, or -1 */
    size_t steps;
    size_t count[MAX_DIMS];    /* one step: 1 on time and extra dims */
    size_t nvox;
    size_t tsize;              /* bytes of a stored value */
    uint32_t chunk[3];         /* x, y, z chunk sizes; 1 1 1 contiguous */
    uint64_t cache;            /* the library's chunk cache (NetCDF-4) */
    void *scratch;             /* a piece, stored type (not float) */
    size_t scratch_cap;
    double miss[MAX_MISSING];  /* in the stored type's values */
    int nmiss;
    int has_min, has_max, valid_unpacked;
    double vmin, vmax;
    int packed;
    double scale, offset;
    int cook;                  /* any of the above: per-voxel work */
    struct tvpal_h5direct *direct; /* NetCDF-4 deflated float: its chunks
                                    * read by the HDF5 backend directly */
};

/* ---------------------------------------------------------------- errors */

static int code_of(int status, int code)
{
    return status == NC_ENOMEM ? TVPAL_E_NOMEM : code;
}

static int ncdf_fail(struct tvpal_diag *diag, int status, int code,
                   const char *path, const char *var)
{
    if (var)
        return tvpal_diag_set(diag, code_of(status, code), "%s: variable %s: "
                              "%s", path, var, nc_strerror(status));
    return tvpal_diag_set(diag, code_of(status, code), "%s: %s", path,
                          nc_strerror(status));
}

/* nc_open's failure: errno values (positive) are the file system's, the
 * rest mean the bytes are not a readable NetCDF file. */
static int open_fail(struct tvpal_diag *diag, int status, const char *path)
{
    return ncdf_fail(diag, status, status > 0 ? TVPAL_E_OPEN : TVPAL_E_FORMAT,
                   path, NULL);
}

/* ------------------------------------------- classic header, bounded */

/* libnetcdf sizes its allocations for a classic (CDF-1, -2, -5) file by
 * the counts of its header before it reads what they count: a forged
 * count makes nc_open allocate gigabytes.  Before the library sees such a
 * file, its header is walked here, without allocating, and every count is
 * checked against the bytes that remain (a valid header holds each item
 * it counts); the library still parses and checks everything else. */
struct cdf_walk {
    const unsigned char *p;
    size_t n, at;            /* bytes read from the file; position */
    int v5;                  /* CDF-5: 8-byte counts */
    int bad;                 /* a count exceeds the file */
    int cut;                 /* the header runs past the bytes read */
};

static uint64_t cdf_get(struct cdf_walk *w, unsigned bytes)
{
    if (w->bad || w->cut || w->n - w->at < bytes) {
        w->cut = 1;
        return 0;
    }
    uint64_t v = 0;
    for (unsigned i = 0; i < bytes; i++)
        v = v << 8 | w->p[w->at + i];
    w->at += bytes;
    return v;
}

/* A count of items of at least `each` bytes: must fit in the file. */
static uint64_t cdf_count(struct cdf_walk *w, uint64_t each, uint64_t fsize)
{
    uint64_t c = cdf_get(w, w->v5 ? 8 : 4);
    if (!w->cut && c > (fsize - w->at) / each)
        w->bad = 1;
    return w->bad || w->cut ? 0 : c;
}

static void cdf_skip(struct cdf_walk *w, uint64_t bytes)
{
    if (w->bad || w->cut || w->n - w->at < bytes)
        w->cut = 1;
    else
        w->at += (size_t)bytes;
}

static void cdf_name(struct cdf_walk *w, uint64_t fsize)
{
    uint64_t len = cdf_count(w, 1, fsize);
    cdf_skip(w, (len + 3) & ~(uint64_t)3);
}

static unsigned cdf_type_size(uint64_t t)
{
    static const unsigned size[12] = {0, 1, 1, 2, 4, 4, 8, 1, 2, 4, 8, 8};
    return t < 12 ? size[t] : 1;   /* an unknown type: the library says */
}

static void cdf_atts(struct cdf_walk *w, uint64_t fsize)
{
    uint64_t tag = cdf_get(w, 4);
    uint64_t n = cdf_count(w, 12, fsize); /* name, type, count */
    for (uint64_t i = 0; tag && i < n && !w->bad && !w->cut; i++) {
        cdf_name(w, fsize);
        unsigned sz = cdf_type_size(cdf_get(w, 4));
        uint64_t k = cdf_count(w, sz, fsize);
        cdf_skip(w, (k * sz + 3) & ~(uint64_t)3);
    }
}

/* 1 when the classic header in p[0 .. n) (of a file of fsize bytes) holds
 * a count larger than the file could; -1 when the header runs past the n
 * bytes read before showing one (more bytes are needed); else 0. */
static int cdf_header_forged(const unsigned char *p, size_t n, uint64_t fsize)
{
    if (n < 8 || memcmp(p, "CDF", 3) || (p[3] != 1 && p[3] != 2 && p[3] != 5))
        return 0;
    struct cdf_walk w = {p, n, 4, p[3] == 5, 0, 0};
    cdf_get(&w, w.v5 ? 8 : 4);                   /* numrecs */
    uint64_t tag = cdf_get(&w, 4);
    uint64_t ndims = cdf_count(&w, 8, fsize);    /* name, length */
    for (uint64_t i = 0; tag && i < ndims && !w.bad && !w.cut; i++) {
        cdf_name(&w, fsize);
        cdf_get(&w, w.v5 ? 8 : 4);
    }
    cdf_atts(&w, fsize);                          /* global */
    tag = cdf_get(&w, 4);
    uint64_t nvars = cdf_count(&w, 24, fsize);
    for (uint64_t i = 0; tag && i < nvars && !w.bad && !w.cut; i++) {
        cdf_name(&w, fsize);
        uint64_t nd = cdf_count(&w, w.v5 ? 8 : 4, fsize);
        cdf_skip(&w, nd * (w.v5 ? 8 : 4));
        cdf_atts(&w, fsize);
        cdf_get(&w, 4);                          /* type */
        cdf_get(&w, w.v5 ? 8 : 4);               /* vsize */
        cdf_get(&w, p[3] == 1 ? 4 : 8);          /* begin */
    }
    return w.bad ? 1 : w.cut ? -1 : 0;
}

/* Refuses a classic file whose header counts more than the file holds,
 * before nc_open allocates for it.  0 or TVPAL_E_FORMAT. */
static int check_classic_header(const char *path, struct tvpal_diag *diag)
{
    int fd = tvpal_open_regular(path, NULL);
    if (fd < 0)
        return 0; /* nc_open says why */
    /* The header only: 64 KiB, doubled while the walk needs more, up to
     * 16 MiB (a header beyond that is left to the library). */
    struct stat st;
    unsigned char *buf = NULL;
    size_t n = 0, want = (size_t)64 << 10;
    int forged = 0;
    const uint64_t size = fstat(fd, &st) == 0 ? (uint64_t)st.st_size : 0;
    while (size >= 8) {
        if (want > size)
            want = (size_t)size;
        unsigned char *nb = realloc(buf, want);
        if (!nb)
            break;
        buf = nb;
        ssize_t k;
        while (n < want && (k = pread(fd, buf + n, want - n, (off_t)n)) > 0)
            n += (size_t)k;
        forged = cdf_header_forged(buf, n, size);
        if (forged >= 0 || n < want || n == size || want >= ((size_t)16 << 20))
            break;
        want *= 2;
    }
    close(fd);
    free(buf);
    if (forged > 0)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: a NetCDF header "
                              "that counts more items than the file's %lld "
                              "bytes can hold (damaged or forged)", path,
                              (long long)size);
    return 0;
}

/* A file of NetCDF-4 format without netCDF's metadata is plain HDF5:
 * libnetcdf would read it (root group only, phony dims) but it is not
 * NetCDF, and TVPAL_E_FORMAT sends it to the hdf5 reader
 * (tvpal_input_detect).  netCDF writes _NCProperties (4.4.1 on) and marks
 * its variables with dimension scales, which its _IsNetcdf4 reports. */
static int plain_hdf5_fail(int ncid, const char *path, struct tvpal_diag *diag)
{
    int fmt, is_nc4 = 1;
    if (nc_inq_format(ncid, &fmt) != NC_NOERR || fmt != NC_FORMAT_NETCDF4 ||
        nc_inq_att(ncid, NC_GLOBAL, "_NCProperties", NULL, NULL) == NC_NOERR ||
        nc_get_att_int(ncid, NC_GLOBAL, "_IsNetcdf4", &is_nc4) != NC_NOERR ||
        is_nc4)
        return 0;
    nc_close(ncid);
    return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: an HDF5 file without "
                          "netCDF metadata, not NetCDF-4 (--format hdf5 "
                          "reads it)", path);
}

int tvpal_input_netcdf_plain_hdf5(const char *path)
{
    int ncid;
    if (nc_open(path, NC_NOWRITE, &ncid) != NC_NOERR)
        return 1;
    if (plain_hdf5_fail(ncid, path, NULL) < 0)
        return 1;   /* it closed ncid */
    nc_close(ncid);
    return 0;
}

/* ------------------------------------------------------- text appending */

/* src into dst[cap], cut short where it does not fit. */

/* ------------------------------------------------------ file inspection */

/* A text attribute (NC_CHAR, or a NetCDF-4 string) into buf; 1 when found
 * and text, 0 otherwise. */
static int text_att(int ncid, int varid, const char *name, char *buf,
                    size_t cap)
{
    nc_type t;
    size_t len;
    buf[0] = 0;
    if (nc_inq_att(ncid, varid, name, &t, &len) != NC_NOERR)
        return 0;
    if (t == NC_CHAR) {
        char *tmp = malloc(len + 1);
        if (!tmp || nc_get_att_text(ncid, varid, name, tmp) != NC_NOERR) {
            free(tmp);
            return 0;
        }
        tmp[len] = 0;
        snprintf(buf, cap, "%s", tmp);
        free(tmp);
        return 1;
    }
    if (t == NC_STRING && len >= 1) {
        char **v = calloc(len, sizeof *v);
        if (!v || nc_get_att_string(ncid, varid, name, v) != NC_NOERR) {
            free(v);
            return 0;
        }
        snprintf(buf, cap, "%s", v[0] ? v[0] : "");
        nc_free_string(len, v);
        free(v);
        return 1;
    }
    return 0;
}

static int is_numeric(nc_type t)
{
    switch (t) {
    case NC_BYTE: case NC_UBYTE: case NC_SHORT: case NC_USHORT:
    case NC_INT: case NC_UINT: case NC_INT64: case NC_UINT64:
    case NC_FLOAT: case NC_DOUBLE:
        return 1;
    default:
        return 0;
    }
}

/* A coordinate variable: 1-D, named as its dim. */
static int is_coord_var(int ncid, int varid)
{
    char name[NC_MAX_NAME + 1], dname[NC_MAX_NAME + 1];
    int nd, dimid;
    if (nc_inq_varndims(ncid, varid, &nd) != NC_NOERR || nd != 1 ||
        nc_inq_varname(ncid, varid, name) != NC_NOERR ||
        nc_inq_vardimid(ncid, varid, &dimid) != NC_NOERR ||
        nc_inq_dimname(ncid, dimid, dname) != NC_NOERR)
        return 0;
    return !strcmp(name, dname);
}

/* The numeric coordinate variable of dimid, or -1. */
static int coord_var_of(int ncid, int dimid)
{
    char dname[NC_MAX_NAME + 1];
    int varid, nd, d;
    nc_type t;
    if (nc_inq_dimname(ncid, dimid, dname) != NC_NOERR ||
        nc_inq_varid(ncid, dname, &varid) != NC_NOERR ||
        nc_inq_varndims(ncid, varid, &nd) != NC_NOERR || nd != 1 ||
        nc_inq_vardimid(ncid, varid, &d) != NC_NOERR || d != dimid ||
        nc_inq_vartype(ncid, varid, &t) != NC_NOERR || !is_numeric(t))
        return -1;
    return varid;
}

/* CF time units: "<unit> since <date>". */
static int cf_time_units(int ncid, int varid)
{
    char u[256];
    return text_att(ncid, varid, "units", u, sizeof u) && strstr(u, " since ");
}

static int dim_is_cf_time(int ncid, int dimid)
{
    int v = coord_var_of(ncid, dimid);
    return v >= 0 && cf_time_units(ncid, v);
}

static int is_unlimited(int ncid, int dimid)
{
    int n, ids[NC_MAX_DIMS];
    if (nc_inq_unlimdims(ncid, &n, NULL) != NC_NOERR || n < 1 ||
        n > NC_MAX_DIMS || nc_inq_unlimdims(ncid, &n, ids) != NC_NOERR)
        return 0;
    for (int i = 0; i < n; i++)
        if (ids[i] == dimid)
            return 1;
    return 0;
}

/* The dims of the file that are time for choosing a variable: the named
 * one, the unlimited ones, those with a CF time coordinate and the first
 * dim of every variable of 4 or more dims. */
static int file_time_dims(int ncid, const char *time_dim, int *ids)
{
    int n = 0, nv, d;
    if (time_dim && nc_inq_dimid(ncid, time_dim, &d) == NC_NOERR)
        ids[n++] = d;
    int nu, u[NC_MAX_DIMS];
    if (nc_inq_unlimdims(ncid, &nu, NULL) == NC_NOERR && nu <= NC_MAX_DIMS &&
        nc_inq_unlimdims(ncid, &nu, u) == NC_NOERR)
        for (int i = 0; i < nu && n < MAX_TIME_DIMS; i++)
            ids[n++] = u[i];
    if (nc_inq_nvars(ncid, &nv) != NC_NOERR)
        return n;
    for (int v = 0; v < nv && n < MAX_TIME_DIMS; v++) {
        int nd, dims[NC_MAX_VAR_DIMS];
        if (nc_inq_varndims(ncid, v, &nd) != NC_NOERR || nd > NC_MAX_VAR_DIMS ||
            nc_inq_vardimid(ncid, v, dims) != NC_NOERR)
            continue;
        if (is_coord_var(ncid, v) && cf_time_units(ncid, v))
            ids[n++] = dims[0];
        else if (nd >= 4)
            ids[n++] = dims[0];
    }
    return n;
}

/* A variable with at least 3 dims that are not time, numeric, and not a
 * coordinate variable. */
static int is_candidate(int ncid, int varid, const int *tdims, int ntd)
{
    int nd, dims[NC_MAX_VAR_DIMS], spatial = 0;
    nc_type t;
    if (nc_inq_varndims(ncid, varid, &nd) != NC_NOERR || nd < 3 ||
        nd > NC_MAX_VAR_DIMS || nc_inq_vardimid(ncid, varid, dims) != NC_NOERR ||
        nc_inq_vartype(ncid, varid, &t) != NC_NOERR || !is_numeric(t) ||
        is_coord_var(ncid, varid))
        return 0;
    for (int i = 0; i < nd; i++) {
        int time = 0;
        for (int j = 0; j < ntd; j++)
            time |= dims[i] == tdims[j];
        spatial += !time;
    }
    return spatial >= 3;
}

/* "NAME(dim1,dim2,...)". */
static void put_var_dims(struct tvpal_text *b, int ncid, int varid)
{
    char name[NC_MAX_NAME + 1], dname[NC_MAX_NAME + 1];
    int nd, dims[NC_MAX_VAR_DIMS];
    if (nc_inq_varname(ncid, varid, name) != NC_NOERR ||
        nc_inq_varndims(ncid, varid, &nd) != NC_NOERR || nd > NC_MAX_VAR_DIMS ||
        nc_inq_vardimid(ncid, varid, dims) != NC_NOERR)
        return;
    tvpal_text_put(b, "%s(", name);
    for (int i = 0; i < nd; i++)
        if (nc_inq_dimname(ncid, dims[i], dname) == NC_NOERR)
            tvpal_text_put(b, "%s%s", i ? "," : "", dname);
    tvpal_text_put(b, ")");
}

/* "variables: T(frtime,level,lat,lon), Z(...)": the candidates, or every
 * variable but the coordinate variables; "..." when the diag is short. */
static void list_vars(char *out, size_t cap, int ncid, int candidates,
                      const int *tdims, int ntd)
{
    char tmp[512];
    struct tvpal_text b = {tmp, 0, sizeof tmp, 0, 0};
    int nv, k = 0;
    tvpal_text_put(&b, "variables: ");
    if (nc_inq_nvars(ncid, &nv) == NC_NOERR)
        for (int v = 0; v < nv; v++) {
            if (candidates ? !is_candidate(ncid, v, tdims, ntd)
                           : is_coord_var(ncid, v))
                continue;
            if (k++)
                tvpal_text_put(&b, ", ");
            put_var_dims(&b, ncid, v);
        }
    if (!k)
        tvpal_text_put(&b, "none");
    if (b.full || b.len >= cap)
        snprintf(tmp + (cap > 4 ? cap - 4 : 0), 4, "...");
    tvpal_input_copy_str(out, cap, tmp);
}

/* The variable to read: opts->var, or the only candidate. */
static int choose_var(int ncid, const char *path,
                      const struct tvpal_input_opts *opts, int *varid,
                      struct tvpal_diag *diag)
{
    int tdims[MAX_TIME_DIMS], ntd = file_time_dims(ncid, opts->time_dim, tdims);
    /* the list gets what the diag has left after the rest of the message */
    char list[200];
    size_t other = strlen(path) + 50 + (opts->var ? strlen(opts->var) : 0);
    size_t room = sizeof diag->msg > other + 40 ? sizeof diag->msg - other : 40;
    if (room > sizeof list)
        room = sizeof list;
    if (opts->var) {
        /* "/T": the root group's T, as an HDF5 path names it */
        const char *root = tvpal_input_root_var(opts->var);
        const char *name = root ? root : opts->var;
        if (nc_inq_varid(ncid, name, varid) == NC_NOERR)
            return 0;
        list_vars(list, room, ncid, 0, tdims, ntd);
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: no variable %s; %s",
                              path, opts->var, list);
    }
    int nv, found = 0;
    int rc = nc_inq_nvars(ncid, &nv);
    if (rc != NC_NOERR)
        return ncdf_fail(diag, rc, TVPAL_E_FORMAT, path, NULL);
    for (int v = 0; v < nv; v++)
        if (is_candidate(ncid, v, tdims, ntd))
            *varid = v, found++;
    if (found == 1)
        return 0;
    if (found == 0) {
        list_vars(list, room, ncid, 0, tdims, ntd);
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: no variable with 3 "
                              "spatial dims (z, y, x); %s", path, list);
    }
    list_vars(list, room, ncid, 1, tdims, ntd);
    return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: %d variables could be "
                          "read, give one (--var); %s", path, found, list);
}

/* The position of the variable's time dim among its dims, or -1 (one
 * step); see the top of the file for the order of the rules.  In a
 * variable of 4 or more dims the time dim is looked for before the last
 * three (z, y, x); a named one there, or a time dim of a 3-D variable, is
 * refused by the caller (fewer than 3 spatial dims). */
static int find_time_dim(int ncid, const char *path, const char *vd,
                         const int *dims, int nd,
                         const struct tvpal_input_opts *opts, int *tpos,
                         struct tvpal_diag *diag)
{
    char dname[NC_MAX_NAME + 1];
    *tpos = -1;
    if (opts->time_dim) {
        for (int i = 0; i < nd; i++)
            if (nc_inq_dimname(ncid, dims[i], dname) == NC_NOERR &&
                !strcmp(dname, opts->time_dim))
                *tpos = i;
        if (*tpos < 0)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: time dim %s is "
                                  "not a dim of %s", path, opts->time_dim, vd);
        return 0;
    }
    if (nd == 3) {
        /* one step, unless one of its dims is time elsewhere in the file
         * (Psl(frtime,lat,lon) next to T(frtime,level,lat,lon)): then it
         * has 2 spatial dims, refused by the caller */
        int tdims[MAX_TIME_DIMS], ntd = file_time_dims(ncid, NULL, tdims);
        for (int i = 0; i < nd && *tpos < 0; i++)
            for (int j = 0; j < ntd; j++)
                if (dims[i] == tdims[j])
                    *tpos = i;
        return 0;
    }
    for (int i = 0; i < nd - 3 && *tpos < 0; i++)
        if (is_unlimited(ncid, dims[i]))
            *tpos = i;
    for (int i = 0; i < nd - 3 && *tpos < 0; i++)
        if (dim_is_cf_time(ncid, dims[i]))
            *tpos = i;
    if (*tpos < 0)
        *tpos = 0;
    return 0;
}

/* Reads n values of an attribute as double; 0 when absent. */
static int num_att(int ncid, int varid, const char *name, double *v, int max,
                   nc_type *type)
{
    size_t len;
    if (nc_inq_att(ncid, varid, name, type, &len) != NC_NOERR ||
        !is_numeric(*type) || len < 1 || len > (size_t)max)
        return 0;
    if (nc_get_att_double(ncid, varid, name, v) != NC_NOERR)
        return 0;
    return (int)len;
}

/* An attribute value as the stored type holds it: a double missing_value
 * on a float variable compares as the float it rounds to. */
static double as_stored(nc_type t, double v)
{
    if (t == NC_FLOAT && fabs(v) <= FLT_MAX)
        return (double)(float)v;
    return v;
}

/* CF attributes: missing values, valid range, packing.  Returns whether
 * any of the missing/valid attributes exists. */
static int read_cf_atts(struct tvpal_input_file *f)
{
    int ncid = f->ncid, varid = f->varid, any = 0;
    nc_type t, pack_type = NC_NAT;
    double v[MAX_MISSING];
    int n;

    if ((n = num_att(ncid, varid, "scale_factor", v, 1, &t)) == 1)
        f->scale = v[0], f->packed = 1, pack_type = t;
    if ((n = num_att(ncid, varid, "add_offset", v, 1, &t)) == 1)
        f->offset = v[0], f->packed = 1, pack_type = t;
    if (f->packed && f->xtype == NC_FLOAT && f->scale == 1 && f->offset == 0)
        f->packed = 0;   /* identity: nothing to do */

    if ((n = num_att(ncid, varid, "_FillValue", v, 1, &t)) == 1)
        f->miss[f->nmiss++] = as_stored(f->xtype, v[0]), any = 1;
    if ((n = num_att(ncid, varid, "missing_value", v, MAX_MISSING - 1, &t)))
        for (int i = 0; i < n; i++)
            f->miss[f->nmiss++] = as_stored(f->xtype, v[i]), any = 1;

    nc_type vt = NC_NAT;
    if (num_att(ncid, varid, "valid_range", v, 2, &t) == 2) {
        f->vmin = v[0], f->vmax = v[1], f->has_min = f->has_max = 1, vt = t;
    } else {
        if (num_att(ncid, varid, "valid_min", v, 1, &t) == 1)
            f->vmin = v[0], f->has_min = 1, vt = t;
        if (num_att(ncid, varid, "valid_max", v, 1, &t) == 1)
            f->vmax = v[0], f->has_max = 1, vt = t;
    }
    if (f->has_min || f->has_max) {
        any = 1;
        f->valid_unpacked = f->packed && vt == pack_type && vt != f->xtype;
        if (!f->valid_unpacked) {
            f->vmin = as_stored(f->xtype, f->vmin);
            f->vmax = as_stored(f->xtype, f->vmax);
        }
    }
    f->cook = any || f->packed;
    return any;
}

/* One stored value, as double, to the float the caller gets. */
static inline float cook(const struct tvpal_input_file *f, double v)
{
    if (isnan(v))
        return NAN;
    for (int i = 0; i < f->nmiss; i++)
        if (v == f->miss[i])
            return NAN;
    if (!f->valid_unpacked &&
        ((f->has_min && v < f->vmin) || (f->has_max && v > f->vmax)))
        return NAN;
    if (f->packed)
        v = v * f->scale + f->offset;
    if (f->valid_unpacked &&
        ((f->has_min && v < f->vmin) || (f->has_max && v > f->vmax)))
        return NAN;
    return (float)v;
}

/* An axis' coordinate variable into spacing, origin and nonuniform. */
static int read_axis(struct tvpal_input_file *f, int dimid, size_t len,
                     double *spacing, double *origin, int *nonuniform,
                     struct tvpal_diag *diag)
{
    *spacing = 1, *origin = 0, *nonuniform = 0;
    int cv = coord_var_of(f->ncid, dimid);
    if (cv < 0 || len < 1)
        return 0;
    double *c = malloc(sizeof *c * len);
    if (!c)
        return TVPAL_E_NOMEM;
    int st = nc_get_var_double(f->ncid, cv, c);
    if (st != NC_NOERR) {
        free(c);
        char name[NC_MAX_NAME + 1] = "?";
        nc_inq_varname(f->ncid, cv, name);
        return ncdf_fail(diag, st, TVPAL_E_READ, f->path, name);
    }
    *origin = c[0];
    if (len > 1) {
        /* Even at the coordinate's own precision: values stored as float32
         * (or rounded to it) are each off by up to half a float32 ulp, so
         * an axis in steps of 0.1 up to 20 differs from its mean step by
         * some 1e-6 of a value: 1e-6 of the step alone called it uneven,
         * and its spacing fell back to 1. */
        nc_type ct = NC_DOUBLE;
        nc_inq_vartype(f->ncid, cv, &ct);
        const double eps = ct == NC_DOUBLE || ct == NC_INT64 ||
                                   ct == NC_UINT64
                               ? 0x1p-52 : ct == NC_FLOAT ? 0x1p-24 : 0;
        double cmax = 0;
        for (size_t i = 0; i < len; i++)
            cmax = fabs(c[i]) > cmax ? fabs(c[i]) : cmax;
        double step = (c[len - 1] - c[0]) / (double)(len - 1);
        const double tol = fmax(1e-6 * fabs(step), 4 * eps * cmax);
        int even = step != 0 && isfinite(step);
        for (size_t i = 1; even && i < len; i++)
            even = fabs((c[i] - c[i - 1]) - step) <= tol;
        if (even)
            *spacing = step;
        else
            *nonuniform = 1, *origin = 0;
    }
    free(c);
    return 0;
}

/* Time values of the time dim: its coordinate variable, else (WRF: no
 * coordinate variables; the Times char array is not parsed) the only 1-D
 * numeric variable on it with CF time units, such as WRF's XTIME.  None:
 * has_times stays 0. */
static int read_times(struct tvpal_input_file *f, int tdim,
                      struct tvpal_input_info *info, double **times,
                      struct tvpal_diag *diag)
{
    int tv = coord_var_of(f->ncid, tdim);
    if (tv < 0) {
        int nv, found = 0;
        if (nc_inq_nvars(f->ncid, &nv) != NC_NOERR)
            return 0;
        for (int v = 0; v < nv; v++) {
            int nd, d;
            nc_type t;
            if (nc_inq_varndims(f->ncid, v, &nd) == NC_NOERR && nd == 1 &&
                nc_inq_vardimid(f->ncid, v, &d) == NC_NOERR && d == tdim &&
                nc_inq_vartype(f->ncid, v, &t) == NC_NOERR && is_numeric(t) &&
                cf_time_units(f->ncid, v))
                tv = v, found++;
        }
        if (found != 1)
            return 0;
    }
    double *t = malloc(sizeof *t * (f->steps ? f->steps : 1));
    if (!t)
        return TVPAL_E_NOMEM;
    int st = f->steps ? nc_get_var_double(f->ncid, tv, t) : NC_NOERR;
    if (st != NC_NOERR) {
        free(t);
        char name[NC_MAX_NAME + 1] = "?";
        nc_inq_varname(f->ncid, tv, name);
        return ncdf_fail(diag, st, TVPAL_E_READ, f->path, name);
    }
    text_att(f->ncid, tv, "units", info->time_units, sizeof info->time_units);
    info->has_times = 1;
    *times = t;
    return 0;
}

/* The variable's grid: time dim, z, y, x, the extra dims of length 1. */
static int read_grid(struct tvpal_input_file *f,
                     const struct tvpal_input_opts *opts,
                     struct tvpal_input_info *info, int *tdim,
                     struct tvpal_diag *diag)
{
    int dims[NC_MAX_VAR_DIMS], nd, st;
    char vd[200];
    struct tvpal_text b = {vd, 0, sizeof vd, 0, 0};
    put_var_dims(&b, f->ncid, f->varid);
    if ((st = nc_inq_varndims(f->ncid, f->varid, &nd)) != NC_NOERR ||
        (nd <= NC_MAX_VAR_DIMS &&
         (st = nc_inq_vardimid(f->ncid, f->varid, dims)) != NC_NOERR) ||
        (st = nc_inq_vartype(f->ncid, f->varid, &f->xtype)) != NC_NOERR)
        return ncdf_fail(diag, st, TVPAL_E_FORMAT, f->path, f->var);
    if (!is_numeric(f->xtype))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s is not "
                              "numeric", f->path, vd);
    if (nd < 3)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s has %d "
                              "dims; 3 spatial ones (z, y, x) are needed",
                              f->path, vd, nd);
    if (nd > MAX_DIMS)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s has %d "
                              "dims; at most %d are read", f->path, vd, nd,
                              MAX_DIMS);
    int rc = find_time_dim(f->ncid, f->path, vd, dims, nd, opts, &f->tpos,
                           diag);
    if (rc < 0)
        return rc;
    f->ndims = nd;
    if (f->tpos >= nd - 3) {
        char dname[NC_MAX_NAME + 1] = "?";
        nc_inq_dimname(f->ncid, dims[f->tpos], dname);
        if (nd == 3)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s: "
                                  "with time dim %s it has fewer than 3 "
                                  "spatial dims (z, y, x)", f->path, vd, dname);
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s: time dim "
                              "%s is one of its last three dims, which are z, "
                              "y, x", f->path, vd, dname);
    }
    f->nvox = 1;
    for (int i = 0; i < nd; i++) {
        size_t len;
        char dname[NC_MAX_NAME + 1];
        if ((st = nc_inq_dim(f->ncid, dims[i], dname, &len)) != NC_NOERR)
            return ncdf_fail(diag, st, TVPAL_E_FORMAT, f->path, f->var);
        if (i == f->tpos) {
            f->steps = len;
            f->count[i] = 1;
            continue;
        }
        if (i < nd - 3 && len != 1)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s: dim "
                                  "%s (length %zu) is neither its time dim "
                                  "nor z, y, x%s", f->path, vd, dname, len,
                                  f->tpos < 0 ? "; give the time dim" : "");
        f->count[i] = len;
        if (i < nd - 3)
            continue;
        int axis = nd - 1 - i;
        if (len == 0)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s: dim "
                                  "%s has length 0", f->path, vd, dname);
        if (len > UINT32_MAX || f->nvox > SIZE_MAX / 8 / len)
            return tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "%s: variable %s "
                                  "is too large", f->path, vd);
        f->nvox *= len;
        info->dims[axis] = (uint32_t)len;
        tvpal_input_copy_str(info->dim_names[axis], sizeof info->dim_names[axis], dname);
        rc = read_axis(f, dims[i], len, &info->spacing[axis],
                       &info->origin[axis], &info->nonuniform[axis], diag);
        if (rc < 0)
            return rc;
    }
    if (f->tpos < 0)
        f->steps = 1;
    if (f->steps > UINT32_MAX)
        return tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "%s: variable %s has "
                              "too many steps", f->path, vd);
    *tdim = f->tpos >= 0 ? dims[f->tpos] : -1;
    return 0;
}

static enum tvpal_type stored_type(const struct tvpal_input_file *f)
{
    if (f->packed)
        return TVPAL_F32;
    switch (f->xtype) {
    case NC_DOUBLE: return TVPAL_F64;
    case NC_UBYTE: return TVPAL_U8;
    case NC_SHORT: return TVPAL_I16;
    case NC_USHORT: return TVPAL_U16;
    /* float, and the types tvpal has no name for (byte, 32- and 64-bit
     * integers): read as float32 like the rest */
    default: return TVPAL_F32;
    }
}

static void ncdf_close(struct tvpal_input_file *f)
{
    if (!f)
        return;
    tvpal_input_hdf5_direct_close(f->direct);
    nc_close(f->ncid);
    free(f->scratch);
    free(f->path);
    free(f);
}

/* A NetCDF-4 float variable of the root group, time first (or no time):
 * the HDF5 dataset of the same name, whose deflated chunks the HDF5
 * backend can read faster than libnetcdf does (f->direct stays NULL when
 * it cannot). */
static int direct_open(struct tvpal_input_file *f, struct tvpal_pool *pool)
{
    int fmt;
    char name[NC_MAX_NAME + 2];
    if (nc_inq_format(f->ncid, &fmt) != NC_NOERR ||
        (fmt != NC_FORMAT_NETCDF4 && fmt != NC_FORMAT_NETCDF4_CLASSIC) ||
        !((f->ndims == 4 && f->tpos == 0) || (f->ndims == 3 && f->tpos < 0)))
        return 0;
    snprintf(name, sizeof name, "/%s", f->var);
    return tvpal_input_hdf5_direct_open(&f->direct, f->path, name, pool);
}

/* Chunk sizes (x, y, z) of a chunked NetCDF-4 variable and the size of
 * the library's chunk cache for it; 1 1 1 and 0 for contiguous data. */
static void read_chunking(struct tvpal_input_file *f)
{
    int storage = NC_CONTIGUOUS;
    size_t cs[NC_MAX_VAR_DIMS], cache = 0, nelems;
    float preempt;
    f->chunk[0] = f->chunk[1] = f->chunk[2] = 1;
    if (f->ndims > NC_MAX_VAR_DIMS ||
        nc_inq_var_chunking(f->ncid, f->varid, &storage, cs) != NC_NOERR ||
        storage != NC_CHUNKED)
        return;
    for (int a = 0; a < 3; a++)
        f->chunk[a] = cs[f->ndims - 1 - a] > 0 && cs[f->ndims - 1 - a] <= UINT32_MAX
                          ? (uint32_t)cs[f->ndims - 1 - a] : 1;
    if (nc_get_var_chunk_cache(f->ncid, f->varid, &cache, &nelems,
                               &preempt) == NC_NOERR)
        f->cache = cache;
}

static int ncdf_open(struct tvpal_input_file **out, const char *path,
                        const struct tvpal_input_opts *opts,
                        struct tvpal_input_info *info, double **times,
                        struct tvpal_diag *diag)
{
    struct tvpal_input_file *f = calloc(1, sizeof *f);
    if (!f || !(f->path = strdup(path))) {
        free(f);
        return TVPAL_E_NOMEM;
    }
    f->scale = 1;
    int rc = check_classic_header(path, diag);
    if (rc < 0) {
        free(f->path);
        free(f);
        return rc;
    }
    int st = nc_open(path, NC_NOWRITE, &f->ncid);
    rc = st != NC_NOERR ? open_fail(diag, st, path)
                        : plain_hdf5_fail(f->ncid, path, diag);
    if (rc < 0) {
        free(f->path);
        free(f);
        return rc;
    }
    int tdim = -1;
    rc = choose_var(f->ncid, path, opts, &f->varid, diag);
    if (rc == 0 && (st = nc_inq_varname(f->ncid, f->varid, f->var)) != NC_NOERR)
        rc = ncdf_fail(diag, st, TVPAL_E_FORMAT, path, NULL);
    if (rc == 0)
        rc = read_grid(f, opts, info, &tdim, diag);
    /* A missing_value list longer than is read would be ignored whole,
     * and its values taken as data: refused instead. */
    nc_type mt;
    size_t mlen;
    if (rc == 0 && nc_inq_att(f->ncid, f->varid, "missing_value", &mt,
                              &mlen) == NC_NOERR && mlen > MAX_MISSING - 1)
        rc = tvpal_diag_set(diag, TVPAL_E_RANGE, "%s: variable %s: its "
                            "missing_value holds %zu values; at most %d are "
                            "read", path, f->var, mlen, MAX_MISSING - 1);
    if (rc == 0) {
        info->missing_attrs = (uint64_t)read_cf_atts(f);
        info->type = stored_type(f);
        info->steps = (uint32_t)f->steps;
        tvpal_input_copy_str(info->var, sizeof info->var, f->var);
        text_att(f->ncid, f->varid, "units", info->units, sizeof info->units);
        if (f->xtype == NC_FLOAT)
            rc = direct_open(f, opts->pool);
        if ((st = nc_inq_type(f->ncid, f->xtype, NULL, &f->tsize)) != NC_NOERR)
            rc = ncdf_fail(diag, st, TVPAL_E_FORMAT, path, f->var);
        read_chunking(f);
    }
    if (rc == 0 && tdim >= 0)
        rc = read_times(f, tdim, info, times, diag);
    if (rc < 0) {
        ncdf_close(f);
        return rc;
    }
    *out = f;
    return 0;
}

/* The hyperslab of box [lo, lo + n) of step k into buf (the stored type,
 * or float for float variables). */
static int ncdf_vara(const struct tvpal_input_file *f, uint32_t k,
                     const uint32_t lo[3], const uint32_t n[3], void *buf)
{
    size_t start[MAX_DIMS] = {0}, count[MAX_DIMS];
    memcpy(count, f->count, sizeof count);
    if (f->tpos >= 0)
        start[f->tpos] = k;
    for (int a = 0; a < 3; a++) {
        start[f->ndims - 1 - a] = lo[a];
        count[f->ndims - 1 - a] = n[a];
    }
    return f->xtype == NC_FLOAT
               ? nc_get_vara_float(f->ncid, f->varid, start, count, buf)
               : nc_get_vara(f->ncid, f->varid, start, count, buf);
}

/* A piece pn of stored values (scratch) into its place d of a box of
 * rows n0 and slices n0 * n1 of dst. */
#define NCDF_COOK(T)                                                         \
    do {                                                                     \
        const T *s = f->scratch;                                             \
        for (uint32_t z = 0; z < pn[2]; z++)                                 \
            for (uint32_t y = 0; y < pn[1]; y++) {                           \
                float *row = d + ((size_t)z * n[1] + y) * n[0];              \
                for (uint32_t x = 0; x < pn[0]; x++)                         \
                    row[x] = cook(f, (double)*s++);                          \
            }                                                                \
    } while (0)

static int check_step(const struct tvpal_input_file *f, uint32_t k,
                      struct tvpal_diag *diag)
{
    if (k >= f->steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s: step %u "
                              "of %zu", f->path, f->var, k, f->steps);
    return 0;
}

static int ncdf_read_box(struct tvpal_input_file *f, uint32_t k,
                         const uint32_t lo[3], const uint32_t n[3],
                         float *dst, struct tvpal_diag *diag)
{
    int st, rc = check_step(f, k, diag);
    if (rc < 0)
        return rc;
    const size_t nbox = (size_t)n[0] * n[1] * n[2];
    if (f->xtype == NC_FLOAT) {
        rc = f->direct ? tvpal_input_hdf5_direct_read_box(f->direct, k, lo, n,
                                                          dst, diag)
                       : 1;
        if (rc < 0)
            return rc;
        if (rc == 1 && (st = ncdf_vara(f, k, lo, n, dst)) != NC_NOERR)
            return ncdf_fail(diag, st, TVPAL_E_READ, f->path, f->var);
        if (f->cook)
            for (size_t i = 0; i < nbox; i++)
                dst[i] = cook(f, dst[i]);
        return 0;
    }
    struct tvpal_box_split sp;
    tvpal_box_split_init(&sp, lo, n, f->chunk, TVPAL_BOX_PIECE);
    const size_t need = (size_t)tvpal_box_split_most(&sp) * f->tsize;
    if (need > f->scratch_cap) {
        free(f->scratch);
        f->scratch_cap = 0;
        if (!(f->scratch = malloc(need)))
            return TVPAL_E_NOMEM;
        f->scratch_cap = need;
    }
    uint32_t plo[3], pn[3];
    while (tvpal_box_split_next(&sp, plo, pn)) {
        if ((st = ncdf_vara(f, k, plo, pn, f->scratch)) != NC_NOERR)
            return ncdf_fail(diag, st, TVPAL_E_READ, f->path, f->var);
        float *d = dst + (plo[0] - lo[0]) +
                   ((size_t)(plo[2] - lo[2]) * n[1] + (plo[1] - lo[1])) * n[0];
        switch (f->xtype) {
        case NC_BYTE: NCDF_COOK(signed char); break;
        case NC_UBYTE: NCDF_COOK(unsigned char); break;
        case NC_SHORT: NCDF_COOK(short); break;
        case NC_USHORT: NCDF_COOK(unsigned short); break;
        case NC_INT: NCDF_COOK(int); break;
        case NC_UINT: NCDF_COOK(unsigned int); break;
        case NC_INT64: NCDF_COOK(long long); break;
        case NC_UINT64: NCDF_COOK(unsigned long long); break;
        default: NCDF_COOK(double); break;   /* NC_DOUBLE */
        }
    }
    return 0;
}

static void grid_of(const struct tvpal_input_file *f, uint32_t dims[3])
{
    for (int a = 0; a < 3; a++)
        dims[a] = (uint32_t)f->count[f->ndims - 1 - a];
}

static int ncdf_read(struct tvpal_input_file *f, uint32_t k, float *dst,
                        struct tvpal_diag *diag)
{
    int st, rc = check_step(f, k, diag);
    if (rc < 0)
        return rc;
    const uint32_t zero[3] = {0, 0, 0};
    uint32_t dims[3];
    grid_of(f, dims);
    if (f->xtype != NC_FLOAT)
        return ncdf_read_box(f, k, zero, dims, dst, diag);
    rc = f->direct ? tvpal_input_hdf5_direct_read(f->direct, k, dst, diag) : 1;
    if (rc < 0)
        return rc;
    if (rc == 1 && (st = ncdf_vara(f, k, zero, dims, dst)) != NC_NOERR)
        return ncdf_fail(diag, st, TVPAL_E_READ, f->path, f->var);
    if (f->cook)
        for (size_t i = 0; i < f->nvox; i++)
            dst[i] = cook(f, dst[i]);
    return 0;
}

static uint64_t ncdf_box_scratch(const struct tvpal_input_file *f,
                                 const uint32_t n[3])
{
    if (f->xtype == NC_FLOAT)
        return f->direct ? tvpal_input_hdf5_direct_scratch(f->direct)
                         : f->cache;
    struct tvpal_box_split sp;
    const uint32_t zero[3] = {0, 0, 0};
    tvpal_box_split_init(&sp, zero, n, f->chunk, TVPAL_BOX_PIECE);
    return tvpal_box_split_most(&sp) * f->tsize + f->cache;
}

static const char *format_name(int fmt)
{
    switch (fmt) {
    case NC_FORMAT_CLASSIC: return "classic";
    case NC_FORMAT_64BIT_OFFSET: return "64-bit offset";
    case NC_FORMAT_CDF5: return "cdf5";
    case NC_FORMAT_NETCDF4: return "netcdf-4";
    case NC_FORMAT_NETCDF4_CLASSIC: return "netcdf-4";
    default: return "unknown";
    }
}

static int ncdf_describe(const char *path, char **text, struct tvpal_diag *diag)
{
    int ncid, fmt, nv, st;
    *text = NULL;
    int rc = check_classic_header(path, diag);
    if (rc < 0)
        return rc;
    if ((st = nc_open(path, NC_NOWRITE, &ncid)) != NC_NOERR)
        return open_fail(diag, st, path);
    rc = plain_hdf5_fail(ncid, path, diag);
    if (rc < 0)
        return rc;
    if ((st = nc_inq_format(ncid, &fmt)) != NC_NOERR ||
        (st = nc_inq_nvars(ncid, &nv)) != NC_NOERR) {
        nc_close(ncid);
        return ncdf_fail(diag, st, TVPAL_E_FORMAT, path, NULL);
    }
    struct tvpal_text b = {malloc(256), 0, 256, 0, 1};
    if (!b.s) {
        nc_close(ncid);
        return TVPAL_E_NOMEM;
    }
    tvpal_text_put(&b, "netcdf %s\n", format_name(fmt));
    for (int v = 0; v < nv; v++) {
        char name[NC_MAX_NAME + 1], dname[NC_MAX_NAME + 1], tname[NC_MAX_NAME + 1];
        char units[256];
        int nd, dims[NC_MAX_VAR_DIMS];
        nc_type t;
        if ((st = nc_inq_var(ncid, v, name, &t, &nd, NULL, NULL)) != NC_NOERR ||
            nd > NC_MAX_VAR_DIMS ||
            (st = nc_inq_vardimid(ncid, v, dims)) != NC_NOERR ||
            (st = nc_inq_type(ncid, t, tname, NULL)) != NC_NOERR) {
            nc_close(ncid);
            free(b.s);
            return ncdf_fail(diag, st, TVPAL_E_FORMAT, path, NULL);
        }
        tvpal_text_put(&b, "%s(", name);
        for (int i = 0; i < nd; i++) {
            size_t len = 0;
            nc_inq_dim(ncid, dims[i], dname, &len);
            tvpal_text_put(&b, "%s%s=%zu", i ? ", " : "", dname, len);
        }
        text_att(ncid, v, "units", units, sizeof units);
        tvpal_text_put(&b, ") %s units=\"%s\"%s\n", tname, units,
            is_coord_var(ncid, v) ? " coordinate" : "");
    }
    nc_close(ncid);
    if (b.full) {
        free(b.s);
        return TVPAL_E_NOMEM;
    }
    *text = b.s;
    return 0;
}

const struct tvpal_input_backend tvpal_input_netcdf = {
    .name = "netcdf", .open = ncdf_open, .read = ncdf_read,
    .read_box = ncdf_read_box, .box_scratch = ncdf_box_scratch,
    .close = ncdf_close, .describe = ncdf_describe};
