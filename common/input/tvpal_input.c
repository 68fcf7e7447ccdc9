/* tvpal_input.c: format detection and series of files over the format
 * backends (see tvpal_input.h).  No format library here: each backend is
 * its own adapter file. */
#include "tvpal_input_impl.h"
#include "tvpal_fs.h"
#ifdef HAVE_INFLATE_ADAPTER
#include "tvpal_inflate.h"
#endif
#include "tvpal_manifest.h"
#include "tvpal_size.h"

#include <errno.h>
#include <sys/stat.h>
#include <unistd.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const format_names[] = {"auto", "raw", "netcdf", "vti",
                                            "vtk", "hdf5"};

const char *tvpal_input_format_name(enum tvpal_input_format f)
{
    return (unsigned)f < sizeof format_names / sizeof *format_names
               ? format_names[f] : "unknown";
}

int tvpal_input_format_parse(const char *s, enum tvpal_input_format *f)
{
    for (unsigned i = 0; i < sizeof format_names / sizeof *format_names; i++)
        if (!strcmp(s, format_names[i])) {
            *f = (enum tvpal_input_format)i;
            return 0;
        }
    return TVPAL_E_INVAL;
}

/* XML whose root element is a VTKFile of type ImageData, within the first
 * bytes (an XML declaration and comments may come first).  Text up to the
 * end of the root's tag, which the string functions check (head ends with
 * a NUL): appended raw data, NUL bytes included, may follow within the
 * first bytes, as in ParaView's own small files. */
/* A VTK XML file: a <VTKFile ...> tag in the text before any binary data.
 * Every VTK XML type goes to the vti reader, which reads ImageData and
 * refuses the others by name (better than "raw: give --dims"). */
static int looks_like_vtk_xml(const char *head)
{
    const char *root = strstr(head, "<VTKFile");
    return root && strchr(root, '>') != NULL;
}

/* The first cap - 1 bytes of path into head, NUL-terminated; *n read. */
static int read_head(const char *path, char *head, size_t cap, size_t *n,
                     struct tvpal_diag *diag)
{
    *n = 0;
    /* A regular file only: the libraries would block on a FIFO. */
    int fd = tvpal_open_regular(path, diag);
    if (fd < 0)
        return fd;
    ssize_t k;
    while ((k = read(fd, head + *n, cap - 1 - *n)) > 0 && *n + (size_t)k < cap - 1)
        *n += (size_t)k;
    if (k > 0)
        *n += (size_t)k;
    int err = k < 0 ? errno : 0;
    close(fd);
    if (err)
        return tvpal_diag_set(diag, TVPAL_E_READ, "%s: %s", path,
                              strerror(err));
    head[*n] = 0;
    return 0;
}

static int hdf5_signature(const char *head, size_t n)
{
    static const unsigned char sig[8] = {0x89, 'H', 'D', 'F',
                                         '\r', '\n', 0x1a, '\n'};
    return n >= 8 && !memcmp(head, sig, 8);
}

/* An HDF5 file is NetCDF-4 unless the variable is a dataset path inside a
 * group ("/grp/T") or the NetCDF reader refuses it as not NetCDF (no
 * netCDF metadata, or damaged).  A root-level path ("/T") of a NetCDF-4
 * file is its variable T, read by the NetCDF reader: the HDF5 path would
 * lose the CF coordinates (spacing, times) the NetCDF reader gives. */
int tvpal_input_detect(const char *path, const struct tvpal_input_opts *opts,
                       enum tvpal_input_format *f, struct tvpal_diag *diag)
{
    char head[1025];
    size_t n;
    int rc = read_head(path, head, sizeof head, &n, diag);
    if (rc < 0)
        return rc;
    const int dataset_path = opts && opts->var && opts->var[0] == '/' &&
                             !tvpal_input_root_var(opts->var);
    *f = TVPAL_IN_RAW;
    if (n >= 4 && !memcmp(head, "CDF", 3) &&
        (head[3] == 1 || head[3] == 2 || head[3] == 5))
        *f = TVPAL_IN_NETCDF;
    else if (hdf5_signature(head, n))
        *f = dataset_path || tvpal_input_netcdf_plain_hdf5(path)
                 ? TVPAL_IN_HDF5 : TVPAL_IN_NETCDF;
    else if (n >= 5 && looks_like_vtk_xml(head))
        *f = TVPAL_IN_VTI;
    else if (n >= 14 && !memcmp(head, "# vtk DataFile", 14))
        *f = TVPAL_IN_VTK;   /* legacy: any dataset; the reader names it */
    return 0;
}

static const struct tvpal_input_backend *backend_of(enum tvpal_input_format f)
{
    switch (f) {
    case TVPAL_IN_NETCDF: return &tvpal_input_netcdf;
    case TVPAL_IN_VTI: return &tvpal_input_vti;
    case TVPAL_IN_VTK: return &tvpal_input_vtk;
    case TVPAL_IN_HDF5: return &tvpal_input_hdf5;
    default: return NULL;
    }
}

struct tvpal_input {
    const struct tvpal_input_backend *be;
    enum tvpal_input_format fmt;   /* the format read (never AUTO) */
    int detected;              /* fmt came from files[0]'s bytes (AUTO) */
    struct tvpal_input_opts opts;
    struct tvpal_input_info info;
    char **files;              /* copies of the paths */
    char **listed_in;          /* [nfiles]: the .pvd of each file, or NULL */
    uint32_t *first;           /* [nfiles + 1]: first series step per file */
    int nfiles;
    double *times;             /* [steps] when info.has_times */
    struct tvpal_input_file *cur;  /* the open file, or NULL */
    int cur_i;
};

void tvpal_input_close(struct tvpal_input *in)
{
    if (!in)
        return;
    if (in->cur)
        in->be->close(in->cur);
    for (int i = 0; in->files && i < in->nfiles; i++)
        free(in->files[i]);
    for (int i = 0; in->listed_in && i < in->nfiles; i++)
        if (!i || in->listed_in[i] != in->listed_in[i - 1])
            free(in->listed_in[i]);
    free(in->files);
    free(in->listed_in);
    free(in->first);
    free(in->times);
    free(in);
}

/* Every file after the first must hold the same variable on the same grid
 * (its name, type, components and dims); only the number of steps may
 * differ. */
static int check_same_grid(const struct tvpal_input_info *a,
                           const struct tvpal_input_info *b,
                           const char *first, const char *path,
                           struct tvpal_diag *diag)
{
    if (memcmp(a->dims, b->dims, sizeof a->dims))
        return tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s: variable %s is "
                              "%ux%ux%u; %s has %ux%ux%u", path, b->var,
                              b->dims[0], b->dims[1], b->dims[2], first,
                              a->dims[0], a->dims[1], a->dims[2]);
    if (a->type != b->type)
        return tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s: variable %s is %s; "
                              "%s has %s", path, b->var, tvpal_type_name(b->type),
                              first, tvpal_type_name(a->type));
    if (a->components != b->components)
        return tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s: variable %s has "
                              "%u component%s; %s has %u", path, b->var,
                              b->components, b->components == 1 ? "" : "s",
                              first, a->components);
    if (a->has_times != b->has_times)
        return tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s: %s time values; %s "
                              "%s", path, b->has_times ? "has" : "has no",
                              first, a->has_times ? "has" : "has none");
    return 0;
}

static int file_of(const struct tvpal_input *in, uint32_t t);

/* A series found by its first file's bytes is of that format throughout:
 * a NetCDF file after a .vti was parsed as XML ("not well-formed").  Said
 * by name (a format given with --format is read as given). */
static int check_same_format(const struct tvpal_input *in, int i,
                             struct tvpal_diag *diag)
{
    enum tvpal_input_format f;
    if (!in->detected || i == 0 ||
        tvpal_input_detect(in->files[i], &in->opts, &f, NULL) < 0 ||
        f == in->fmt || f == TVPAL_IN_RAW)
        return 0;
    /* NetCDF-4 read as HDF5 (a dataset path) and the like are one file
     * format */
    if ((f == TVPAL_IN_NETCDF || f == TVPAL_IN_HDF5) &&
        (in->fmt == TVPAL_IN_NETCDF || in->fmt == TVPAL_IN_HDF5))
        return 0;
    return tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s: a %s file in a series "
                          "of %s files (%s is one): every file of a series "
                          "is of one format", in->files[i],
                          tvpal_input_format_name(f),
                          tvpal_input_format_name(in->fmt), in->files[0]);
}

/* What a file's grid must be for a dataset to hold it: points that can
 * be addressed, and spacing and origin by the manifest reader's rule
 * (tvpal_manifest_check_grid): a value a dataset could not read back is
 * refused here, naming the file and the variable, before any work. */
static int check_file_grid(const char *path,
                           const struct tvpal_input_info *info,
                           struct tvpal_diag *diag)
{
    size_t n;
    if (tvpal_points(info->dims, sizeof(double), &n) < 0)
        return tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "%s: variable %s: "
                              "%ux%ux%u points: more than can be addressed",
                              path, info->var, info->dims[0], info->dims[1],
                              info->dims[2]);
    struct tvpal_diag g;
    if (tvpal_manifest_check_grid(info->spacing, info->origin, NULL, 0, &g))
        return tvpal_diag_set(diag, TVPAL_E_RANGE, "%s: variable %s: %s",
                              path, info->var, g.msg);
    return 0;
}

/* Opens file i into in->cur (closing another). */
static int open_file(struct tvpal_input *in, int i, struct tvpal_input_info *info,
                     double **times, struct tvpal_diag *diag)
{
    if (in->cur && in->cur_i == i && !info)
        return 0;
    if (in->cur)
        in->be->close(in->cur);
    in->cur = NULL;
    struct tvpal_input_info scratch;
    double *t = NULL;
    if (!info)
        info = &scratch;
    if (!times)
        times = &t;
    /* What a file says nothing about: the unit grid, one component, no
     * times. */
    *info = (struct tvpal_input_info){.spacing = {1, 1, 1},
                                      .components = 1};
    *times = NULL;
    /* Every file of a series, and every file a collection names, as a file
     * given by itself: a regular file (a FIFO would block the format's
     * library for ever). */
    int rc = tvpal_open_regular(in->files[i], diag);
    if (rc >= 0) {
        close(rc);
        rc = check_same_format(in, i, diag);
    }
    if (rc >= 0) {
        rc = in->be->open(&in->cur, in->files[i], &in->opts, info, times,
                          diag);
    }
    if (rc == 0)
        rc = check_file_grid(in->files[i], info, diag);
    if (rc < 0 && in->cur) {
        in->be->close(in->cur);
        in->cur = NULL;
    }
    free(t);
    in->cur_i = i;
    if (rc < 0)
        in->cur = NULL;
    return rc;
}

static int append_times(struct tvpal_input *in, const double *t, uint32_t n)
{
    uint32_t have = in->info.steps;
    double *nt = realloc(in->times, sizeof *nt * ((size_t)have + n + 1));
    if (!nt)
        return TVPAL_E_NOMEM;
    in->times = nt;
    memcpy(nt + have, t, sizeof *nt * n);
    return 0;
}

/* Reads every file's description: steps per file, and that they agree. */
static int scan_files(struct tvpal_input *in, struct tvpal_diag *diag)
{
    for (int i = 0; i < in->nfiles; i++) {
        struct tvpal_input_info fi;
        double *times = NULL;
        int rc = open_file(in, i, &fi, &times, diag);
        if (rc == 0 && i == 0)
            in->info = fi, in->info.steps = 0;
        else if (rc == 0)
            rc = check_same_grid(&in->info, &fi, in->files[0], in->files[i],
                                 diag);
        if (rc == 0 && fi.has_times)
            rc = append_times(in, times, fi.steps);
        free(times);
        if (rc < 0 && in->listed_in && in->listed_in[i] && diag) {
            size_t k = strlen(diag->msg);
            snprintf(diag->msg + k, sizeof diag->msg - k, " (listed in %s)",
                     in->listed_in[i]);
        }
        if (rc < 0)
            return rc;
        if (fi.steps > UINT32_MAX - in->info.steps)
            return tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "too many steps");
        in->first[i] = in->info.steps;
        in->info.steps += fi.steps;
    }
    in->first[in->nfiles] = in->info.steps;
    return 0;
}

/* Puts the files of in (files[0..nfiles), .pvd collections expanded)
 * into in->files, in->listed_in and in->times.  A collection's times are
 * the series' times; plain files beside a collection would have none. */
static int expand_files(struct tvpal_input *in, char *const *files,
                        int nfiles, struct tvpal_diag *diag)
{
    int rc = 0, cap = 0, ncoll = 0, nplain = 0, ntimed = 0;
    for (int i = 0; rc == 0 && i < nfiles; i++) {
        char **cf = NULL;
        double *ct = NULL;
        int cn = 0;
        if (in->be == &tvpal_input_vti)
            rc = tvpal_input_vtk_collection(files[i], &cf, &ct, &cn, diag);
        char *owner = NULL;
        if (rc == 0 && cn > 0 && !(owner = strdup(files[i])))
            rc = TVPAL_E_NOMEM;
        int add = cn > 0 ? cn : 1;
        if (rc == 0 && in->nfiles + add > cap) {
            int nc = 2 * cap > in->nfiles + add ? 2 * cap : in->nfiles + add;
            char **f = realloc(in->files, sizeof *f * (size_t)nc);
            if (f)
                in->files = f;
            char **l = f ? realloc(in->listed_in, sizeof *l * (size_t)nc) : NULL;
            if (l)
                in->listed_in = l;
            double *t = l ? realloc(in->times, sizeof *t * (size_t)nc) : NULL;
            if (t)
                in->times = t;
            rc = t ? 0 : TVPAL_E_NOMEM;
            cap = t ? nc : cap;
        }
        for (int k = 0; rc == 0 && k < add; k++) {
            char *p = cn > 0 ? cf[k] : strdup(files[i]);
            if (cn > 0)
                cf[k] = NULL;
            if (!p) {
                rc = TVPAL_E_NOMEM;
                break;
            }
            in->files[in->nfiles] = p;
            in->listed_in[in->nfiles] = owner;
            in->times[in->nfiles] = ct ? ct[k] : 0;
            in->nfiles++;
        }
        if (rc < 0 && owner && (in->nfiles == 0 ||
                                in->listed_in[in->nfiles - 1] != owner))
            free(owner);
        for (int k = 0; k < cn; k++)
            free(cf[k]);
        free(cf);
        free(ct);
        ncoll += cn > 0;
        nplain += cn == 0;
        ntimed += cn > 0 && ct != NULL;
    }
    if (rc == 0 && ncoll && nplain)
        rc = tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s and %s: a .pvd "
                            "collection and plain files in one series (give "
                            "the collection or its files)", files[0],
                            files[nfiles - 1]);
    if (rc == 0 && ncoll && ntimed != ncoll)
        rc = tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s ... %s: some "
                            "collections have timesteps and some none",
                            files[0], files[nfiles - 1]);
    if (ncoll == 0 || ntimed != ncoll) {
        free(in->times);
        in->times = NULL;
    }
    return rc;
}

int tvpal_input_open(struct tvpal_input **out, enum tvpal_input_format fmt,
                     char *const *files, int nfiles,
                     const struct tvpal_input_opts *opts,
                     struct tvpal_diag *diag)
{
    if (nfiles < 1)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "no input files");
    int rc = 0;
    const int detected = fmt == TVPAL_IN_AUTO;
    if (fmt == TVPAL_IN_AUTO &&
        (rc = tvpal_input_detect(files[0], opts, &fmt, diag)) < 0)
        return rc;
    const struct tvpal_input_backend *be = backend_of(fmt);
    if (!be)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: a raw file (no "
                              "header tvpal reads): give --dims and --type",
                              files[0]);
    if (be->missing)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: %s", files[0],
                              be->missing);
    struct tvpal_input *in = calloc(1, sizeof *in);
    if (!in)
        return TVPAL_E_NOMEM;
    in->be = be;
    in->fmt = fmt;
    in->detected = detected;
    in->opts = opts ? *opts : (struct tvpal_input_opts){0};
    in->cur_i = -1;
    rc = expand_files(in, files, nfiles, diag);
    /* Collection times are the series' times, over any a file gives (a
     * .vti's FieldData TimeValue), as ParaView takes a .pvd's. */
    double *coll_times = in->times;
    in->times = NULL;
    if (rc == 0 && !(in->first = calloc((size_t)in->nfiles + 1,
                                        sizeof *in->first)))
        rc = TVPAL_E_NOMEM;
    if (rc == 0)
        rc = scan_files(in, diag);
    if (rc == 0 && coll_times) {
        if (in->info.steps != (uint32_t)in->nfiles)
            rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: its DataSets "
                                "hold %u steps in %d files (one each "
                                "expected)", files[0], in->info.steps,
                                in->nfiles);
        free(in->times);
        in->times = coll_times;
        coll_times = NULL;
        in->info.has_times = 1;
    }
    free(coll_times);
    for (uint32_t t = 0; rc == 0 && in->info.has_times && t < in->info.steps;
         t++)
        if (!tvpal_manifest_number_ok(in->times[t])) {
            /* a collection's timestep is the collection's; else the
             * file's time coordinate */
            const int i = file_of(in, t);
            const char *of = in->listed_in[i] ? in->listed_in[i]
                                              : in->files[i];
            rc = tvpal_diag_set(diag, TVPAL_E_RANGE, "%s: the time of step "
                                "%u (%s) is %.17g: a finite number, 0 or of "
                                "magnitude at least 2.2250738585072014e-308, "
                                "expected (a dataset could not hold it)", of,
                                t, in->files[i], in->times[t]);
        }
    /* The times must increase, as --times must: files given out of order,
     * or whose times repeat or overlap, would be encoded as a series that
     * runs backwards or stands still. */
    for (uint32_t t = 1; rc == 0 && in->info.has_times && t < in->info.steps;
         t++)
        if (!(in->times[t] > in->times[t - 1])) {
            const int i = file_of(in, t), h = file_of(in, t - 1);
            rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: the time of step "
                                "%u (%.17g, %s) is not after step %u's "
                                "(%.17g, %s): times must increase (files in "
                                "time order, none repeated)",
                                in->listed_in[i] ? in->listed_in[i]
                                                 : in->files[i],
                                t, in->times[t], in->files[i], t - 1,
                                in->times[t - 1], in->files[h]);
        }
    if (rc == 0 && in->info.steps == 0)
        rc = tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s has no "
                            "timesteps", files[0], in->info.var);
    if (rc < 0) {
        tvpal_input_close(in);
        return rc;
    }
    *out = in;
    return 0;
}

enum tvpal_input_format tvpal_input_format(const struct tvpal_input *in)
{
    return in->fmt;
}

const struct tvpal_input_info *tvpal_input_info(const struct tvpal_input *in)
{
    return &in->info;
}

/* The file holding series step t (binary search over first[]). */
static int file_of(const struct tvpal_input *in, uint32_t t)
{
    int lo = 0, hi = in->nfiles - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if (in->first[mid] <= t)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

const char *tvpal_input_file(const struct tvpal_input *in, uint32_t t,
                             uint32_t *index_in_file)
{
    int i = file_of(in, t);
    if (index_in_file)
        *index_in_file = t - in->first[i];
    return in->files[i];
}

int tvpal_input_read(struct tvpal_input *in, uint32_t t, float *dst,
                     struct tvpal_diag *diag)
{
    if (t >= in->info.steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u of %u", t,
                              in->info.steps);
    int i = file_of(in, t);
    int rc = open_file(in, i, NULL, NULL, diag);
    if (rc < 0)
        return rc;
    return in->be->read(in->cur, t - in->first[i], dst, diag);
}

int tvpal_input_read_box(struct tvpal_input *in, uint32_t t,
                         const uint32_t lo[3], const uint32_t n[3],
                         float *dst, struct tvpal_diag *diag)
{
    const struct tvpal_input_info *fi = &in->info;
    if (t >= fi->steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s: box "
                              "read of step %u of %u", in->files[0], fi->var,
                              t, fi->steps);
    const char *path = tvpal_input_file(in, t, NULL);
    for (int a = 0; a < 3; a++) {
        if (n[a] == 0)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s: "
                                  "step %u: empty box (size %u %u %u: 0 "
                                  "on axis %c)", path, fi->var, t, n[0],
                                  n[1], n[2], "xyz"[a]);
        if (lo[a] >= fi->dims[a] || n[a] > fi->dims[a] - lo[a])
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: variable %s: "
                                  "step %u: box at %u %u %u of size %u %u "
                                  "%u is outside the %ux%ux%u grid on axis "
                                  "%c", path, fi->var, t, lo[0], lo[1],
                                  lo[2], n[0], n[1], n[2], fi->dims[0],
                                  fi->dims[1], fi->dims[2], "xyz"[a]);
    }
    int i = file_of(in, t);
    int rc = open_file(in, i, NULL, NULL, diag);
    if (rc < 0)
        return rc;
    return in->be->read_box(in->cur, t - in->first[i], lo, n, dst, diag);
}

uint64_t tvpal_input_box_scratch(const struct tvpal_input *in,
                                 const uint32_t n[3])
{
    if (!in->cur || !n[0] || !n[1] || !n[2])
        return 0;
    return in->be->box_scratch(in->cur, n);
}

double tvpal_input_time(const struct tvpal_input *in, uint32_t t)
{
    return in->info.has_times && t < in->info.steps ? in->times[t] : (double)t;
}

int tvpal_input_describe(const char *path, enum tvpal_input_format fmt,
                         char **text, struct tvpal_diag *diag)
{
    int rc = 0;
    if (fmt == TVPAL_IN_AUTO &&
        (rc = tvpal_input_detect(path, NULL, &fmt, diag)) < 0)
        return rc;
    const struct tvpal_input_backend *be = backend_of(fmt);
    if (!be)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: a raw file: no "
                              "header says what it holds", path);
    if (be->missing)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: %s", path, be->missing);
    return be->describe(path, text, diag);
}

/* ------------------------------------------- helpers of the backends */

void tvpal_input_copy_str(char *dst, size_t cap, const char *src)
{
    size_t n = strlen(src);
    if (n >= cap)
        n = cap - 1;
    memcpy(dst, src, n);
    dst[n] = 0;
}


void tvpal_text_put(struct tvpal_text *b, const char *fmt, ...)
{
    if (b->full)
        return;
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(b->s + b->len, b->cap - b->len, fmt, ap);
        va_end(ap);
        if (n < 0) {
            b->full = 1;
            return;
        }
        if ((size_t)n < b->cap - b->len) {
            b->len += (size_t)n;
            return;
        }
        if (!b->grow) {
            b->full = 1;
            return;
        }
        size_t cap = b->cap * 2 + (size_t)n;
        char *s = realloc(b->s, cap);
        if (!s) {
            b->full = 1;
            return;
        }
        b->s = s, b->cap = cap;
    }
}

const char *tvpal_input_inflate_library(void)
{
#if defined(HAVE_INFLATE_ADAPTER) && defined(HAVE_HDF5)
    static char buf[96];
    snprintf(buf, sizeof buf, "%s (also HDF5 and NetCDF-4 chunks)",
             tvpal_inflate_library());
    return buf;
#elif defined(HAVE_INFLATE_ADAPTER)
    return tvpal_inflate_library();
#else
    return "none";
#endif
}

uint64_t tvpal_input_inflated_chunks(void)
{
    return tvpal_input_hdf5_inflated();
}

/* ------------------------------------------------- box reads of raw data */

int tvpal_input_pread(int fd, unsigned char *p, size_t len, uint64_t off,
                      const char *path, const char *what,
                      struct tvpal_diag *diag)
{
    while (len > 0) {
        size_t want = len < ((size_t)1 << 30) ? len : (size_t)1 << 30;
        ssize_t k = pread(fd, p, want, (off_t)off);
        if (k < 0 && errno == EINTR)
            continue;
        if (k < 0)
            return tvpal_diag_set(diag, TVPAL_E_READ, "%s: %s: read: %s",
                                  path, what, strerror(errno));
        if (k == 0) {
            /* The size was checked when the file was opened: it shrank
             * since (rewritten by a simulation, a copy in progress). */
            struct stat st;
            long long now = fstat(fd, &st) == 0 ? (long long)st.st_size : -1;
            return tvpal_diag_set(diag, TVPAL_E_TRUNC, "%s: %s: the file "
                                  "ends at byte %lld, before byte %llu: it "
                                  "shrank while being read (rewritten, or "
                                  "still being copied?)", path, what, now,
                                  (unsigned long long)(off + len));
        }
        p += k;
        len -= (size_t)k;
        off += (uint64_t)k;
    }
    return 0;
}

/* io->buf of at least len bytes (its contents not kept). */
static int io_room(struct tvpal_box_io *io, size_t len)
{
    if (io->cap >= len)
        return 0;
    free(io->buf);
    io->cap = 0;
    if (!(io->buf = malloc(len)))
        return TVPAL_E_NOMEM;
    io->cap = len;
    return 0;
}

/* count values contiguous at file offset off into d[0 .. count). */
static int read_dense(int fd, uint64_t off, size_t count, unsigned size,
                      float *d, tvpal_box_conv conv, const void *ctx,
                      struct tvpal_box_io *io, const char *path,
                      const char *what, struct tvpal_diag *diag)
{
    if (!conv)
        return tvpal_input_pread(fd, (unsigned char *)d, count * sizeof *d, off, path,
                         what, diag);
    const size_t per = TVPAL_BOX_IO_CAP / size;
    int rc = 0;
    for (size_t i = 0; rc == 0 && i < count; i += per) {
        size_t k = count - i < per ? count - i : per;
        rc = io_room(io, k * size);
        if (rc == 0)
            rc = tvpal_input_pread(fd, io->buf, k * size, off + (uint64_t)i * size,
                           path, what, diag);
        if (rc == 0)
            conv(io->buf, k, d + i, ctx);
    }
    return rc;
}

int tvpal_input_box_pread(int fd, uint64_t base, const uint32_t dims[3],
                          unsigned size, const uint32_t lo[3],
                          const uint32_t n[3], float *dst, size_t dy,
                          size_t dz, tvpal_box_conv conv, const void *ctx,
                          struct tvpal_box_io *io, const char *path,
                          const char *what, struct tvpal_diag *diag)
{
    const uint64_t nx = dims[0], ny = dims[1], ry = n[1];
    const uint64_t rb = (uint64_t)n[0] * size;
    const uint64_t nrows = ry * n[2];
    /* Rows per run contiguous in the file and in dst. */
    uint64_t per = 1;
    if (n[0] == dims[0] && dy == n[0]) {
        per = ry;
        if (n[1] == dims[1] && dz == (size_t)n[0] * n[1])
            per = nrows;
    }
#define ROW_OFF(r) (base + ((((uint64_t)lo[2] + (r) / ry) * ny + lo[1] +    \
                             (r) % ry) * nx + lo[0]) * size)
#define ROW_DST(r) (dst + (size_t)((r) % ry) * dy + (size_t)((r) / ry) * dz)
    int rc = 0;
    for (uint64_t r = 0; r < nrows && rc == 0;) {
        if (per > 1 || rb >= TVPAL_BOX_IO_CAP / 2) {
            rc = read_dense(fd, ROW_OFF(r), (size_t)(per * n[0]), size,
                            ROW_DST(r), conv, ctx, io, path, what, diag);
            r += per;
            continue;
        }
        /* A batch of short rows: one read of them and their gaps. */
        const uint64_t off = ROW_OFF(r);
        uint64_t end = off + rb, k = 1;
        while (r + k < nrows) {
            uint64_t o = ROW_OFF(r + k);
            if (o + rb - off > TVPAL_BOX_IO_CAP || o - end > TVPAL_BOX_GAP)
                break;
            end = o + rb;
            k++;
        }
        rc = io_room(io, (size_t)(end - off));
        if (rc == 0)
            rc = tvpal_input_pread(fd, io->buf, (size_t)(end - off), off, path, what,
                           diag);
        for (uint64_t j = 0; rc == 0 && j < k; j++) {
            const unsigned char *src = io->buf + (ROW_OFF(r + j) - off);
            if (conv)
                conv(src, n[0], ROW_DST(r + j), ctx);
            else
                memcpy(ROW_DST(r + j), src, (size_t)rb);
        }
        r += k;
    }
#undef ROW_OFF
#undef ROW_DST
    return rc;
}

uint64_t tvpal_input_box_pread_scratch(const uint32_t dims[3], unsigned size,
                                       const uint32_t n[3], int direct)
{
    const uint64_t rb = (uint64_t)n[0] * size;
    const uint64_t box = rb * n[1] * n[2];
    if (n[0] == dims[0] || rb >= TVPAL_BOX_IO_CAP / 2)
        return direct ? 0 : box < TVPAL_BOX_IO_CAP ? box : TVPAL_BOX_IO_CAP;
    uint64_t span = (((uint64_t)(n[2] - 1) * dims[1] + (n[1] - 1)) * dims[0] +
                     n[0]) * size;
    return span < TVPAL_BOX_IO_CAP ? span : TVPAL_BOX_IO_CAP;
}

/* ------------------------------------------------ boxes read in pieces */

void tvpal_box_split_init(struct tvpal_box_split *s, const uint32_t lo[3],
                          const uint32_t n[3], const uint32_t chunk[3],
                          uint64_t cap)
{
    memset(s, 0, sizeof *s);
    for (int a = 0; a < 3; a++) {
        s->lo[a] = s->at[a] = lo[a];
        s->n[a] = s->d[a] = n[a];
        s->chunk[a] = chunk[a] ? chunk[a] : 1;
    }
    const uint64_t n0 = n[0], n1 = n[1], n2 = n[2];
    if (cap < 1)
        cap = 1;
    if (n0 * n1 * n2 <= cap)
        return;
    /* Slabs of whole layers of chunks along z. */
    const uint64_t cz = s->chunk[2], cy = s->chunk[1], cx = s->chunk[0];
    uint64_t dz = cap / (n0 * n1) / cz * cz;
    s->split[2] = 1;
    s->d[2] = (uint32_t)(dz < cz ? cz : dz < n2 ? dz : (n2 + cz - 1) / cz * cz);
    const uint64_t hz = cz < n2 ? cz : n2;
    if (n0 * n1 * hz <= cap)
        return;
    /* One layer is too large: bands of chunk rows along y, a layer deep. */
    s->d[2] = (uint32_t)cz;
    s->split[1] = 1;
    uint64_t dy = cap / (n0 * hz) / cy * cy;
    s->d[1] = (uint32_t)(dy < cy ? cy : dy < n1 ? dy : (n1 + cy - 1) / cy * cy);
    const uint64_t hy = cy < n1 ? cy : n1;
    if (n0 * hy * hz <= cap)
        return;
    /* One band is too large: runs along x, a chunk high and deep. */
    s->d[1] = (uint32_t)cy;
    s->split[0] = 1;
    uint64_t dx = cap / (hy * hz) / cx * cx;
    s->d[0] = (uint32_t)(dx < cx ? cx : dx < n0 ? dx : (n0 + cx - 1) / cx * cx);
}

/* Where the piece of axis a that starts at `at` ends. */
static uint32_t split_end(const struct tvpal_box_split *s, int a, uint32_t at)
{
    uint64_t hi = (uint64_t)s->lo[a] + s->n[a];
    if (!s->split[a])
        return (uint32_t)hi;
    uint64_t e = (uint64_t)at / s->chunk[a] * s->chunk[a] + s->d[a];
    return (uint32_t)(e < hi ? e : hi);
}

int tvpal_box_split_next(struct tvpal_box_split *s, uint32_t plo[3],
                         uint32_t pn[3])
{
    if (s->done)
        return 0;
    uint32_t end[3];
    for (int a = 0; a < 3; a++) {
        end[a] = split_end(s, a, s->at[a]);
        plo[a] = s->at[a];
        pn[a] = end[a] - s->at[a];
    }
    for (int a = 0;; a++) {
        if (a == 3) {
            s->done = 1;
            break;
        }
        s->at[a] = end[a];
        if (s->at[a] < s->lo[a] + s->n[a])
            break;
        s->at[a] = s->lo[a];
    }
    return 1;
}

uint64_t tvpal_box_split_most(const struct tvpal_box_split *s)
{
    uint64_t v = 1;
    for (int a = 0; a < 3; a++)
        v *= s->d[a] < s->n[a] ? s->d[a] : s->n[a];
    return v;
}
