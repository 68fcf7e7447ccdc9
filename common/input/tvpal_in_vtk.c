/* tvpal_in_vtk.c: the legacy VTK (.vtk) backend of tvpal_input, for
 * DATASET STRUCTURED_POINTS, on stdio alone (a text header and raw or
 * ASCII numbers: no library reads it short of VTK itself).
 *
 * The layout, as VTK's vtkDataReader reads it: "# vtk DataFile Version
 * x.y", a title line, ASCII or BINARY, DATASET STRUCTURED_POINTS, then
 * white-space separated keywords (case-insensitive): DIMENSIONS nx ny nz,
 * SPACING (or ASPECT_RATIO) and ORIGIN, POINT_DATA n / CELL_DATA n, and
 * their attributes: SCALARS name type [ncomp] followed by LOOKUP_TABLE
 * name, then the values; VECTORS, NORMALS (3 components), TENSORS (9),
 * TEXTURE_COORDINATES name dim type; FIELD name n, then n arrays "name
 * ncomp ntuples type" with their values, each maybe followed by its
 * METADATA (where VTK's writer puts every point array but the active
 * attributes).  BINARY values are big-endian and start after the newline
 * that ends the line before them.  Every attribute is skipped by its size
 * while the header is scanned, so that every point array of the file can
 * be chosen (--var; default the first point SCALARS, VTK's active
 * scalars, else the first point VECTORS); one of several components per
 * point is read as its length (magnitude, tvpal_input_opts), else refused
 * naming it.  COLOR_SCALARS, LOOKUP_TABLE, METADATA and the dataset's own
 * FIELD are never variables.
 *
 * open scans the whole header (ASCII: the numbers too, to find the arrays
 * after the first); read seeks to the chosen array and converts one step
 * through a fixed buffer.  read_box: BINARY preads the box's rows
 * (tvpal_input_box_pread: whole runs, or batches of short rows, at most 4
 * MiB of scratch kept between calls; a point's components are one value
 * of their bytes there); ASCII parses the values in order up to the box's
 * last one, converting those in the box (no scratch).  Errors are
 * TVPAL_E_FORMAT for a file that is not a readable STRUCTURED_POINTS file,
 * with the path, the line and the problem in the diag; TVPAL_E_INVAL for
 * an array that cannot be chosen. */
#include "tvpal_input_impl.h"
#include "tvpal_fs.h"
#include "tvpal_size.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

/* The legacy type names, bytes per value and the tvpal type info says. */
static const struct vtk_type {
    const char *name;
    unsigned size;
    int is_signed, is_float;
    enum tvpal_type as;
} vtk_types[] = {
    {"float", 4, 1, 1, TVPAL_F32},         {"double", 8, 1, 1, TVPAL_F64},
    {"unsigned_char", 1, 0, 0, TVPAL_U8},  {"char", 1, 1, 0, TVPAL_F32},
    {"short", 2, 1, 0, TVPAL_I16},         {"unsigned_short", 2, 0, 0, TVPAL_U16},
    {"int", 4, 1, 0, TVPAL_F64},           {"unsigned_int", 4, 0, 0, TVPAL_F64},
    {"long", 8, 1, 0, TVPAL_F64},          {"unsigned_long", 8, 0, 0, TVPAL_F64},
    {"vtkIdType", 4, 1, 0, TVPAL_F64},
};
#define NTYPES (int)(sizeof vtk_types / sizeof *vtk_types)

struct vtk_array {
    char kind[24];              /* SCALARS, VECTORS, ..., FIELD (an array
                                 * of a POINT_DATA or CELL_DATA FIELD) */
    char name[128];
    char type[64];
    int t;                      /* vtk_types index, or -1 */
    long ncomp;
    int cell;
    long long offset;           /* first byte of the values */
};

struct vtk_hdr {
    const char *path;
    struct tvpal_diag *diag;
    FILE *fp;
    long long size;             /* of the file */
    unsigned long line;
    char version[32], title[160];
    int binary;
    uint32_t dims[3];
    int have_dims;
    double spacing[3], origin[3];
    struct vtk_array *arrays;
    int n, cap;
};

struct tvpal_input_file {
    char *path;
    char var[TVPAL_INPUT_VAR_MAX];
    char kind[24];              /* the array's kind, for messages */
    uint32_t dims[3];
    int t, binary;
    long ncomp;                 /* components per point (several:
                                 * magnitude) */
    long long offset;
    struct tvpal_box_io io;     /* box reads of BINARY values */
};

static int bad(struct vtk_hdr *h, int code, const char *fmt, const char *a,
               const char *b)
{
    char what[512];
    snprintf(what, sizeof what, fmt, a, b ? b : "");
    return tvpal_diag_set(h->diag, code, "%s: line %lu: %s", h->path, h->line,
                          what);
}

/* The next white-space separated word into buf; -1 at the end. */
static int word(struct vtk_hdr *h, char *buf, size_t cap)
{
    int c;
    while ((c = getc(h->fp)) != EOF && (c == ' ' || c == '\t' || c == '\n' ||
                                        c == '\r'))
        h->line += c == '\n';
    if (c == EOF)
        return -1;
    size_t k = 0;
    do {
        if (k + 1 < cap)
            buf[k++] = (char)c;
    } while ((c = getc(h->fp)) != EOF && !(c == ' ' || c == '\t' ||
                                           c == '\n' || c == '\r'));
    if (c != EOF)
        ungetc(c, h->fp);
    buf[k] = 0;
    return 0;
}

/* The rest of the line, its newline included (the one before binary
 * values). */
static void end_line(struct vtk_hdr *h)
{
    int c;
    while ((c = getc(h->fp)) != EOF && c != '\n')
        ;
    h->line += c == '\n';
}

static int want_word(struct vtk_hdr *h, char *buf, size_t cap,
                     const char *what)
{
    if (word(h, buf, cap) < 0)
        return bad(h, TVPAL_E_FORMAT, "the file ends where %s was expected",
                   what, NULL);
    return 0;
}

static int want_long(struct vtk_hdr *h, long long *v, const char *what)
{
    char w[64], *e;
    int rc = want_word(h, w, sizeof w, what);
    if (rc < 0)
        return rc;
    errno = 0;
    *v = strtoll(w, &e, 10);
    if (e == w || *e || errno || *v < 0)
        return bad(h, TVPAL_E_FORMAT, "%s is \"%s\" (a count expected)", what,
                   w);
    return 0;
}

static int want_doubles(struct vtk_hdr *h, double *v, const char *what)
{
    for (int i = 0; i < 3; i++) {
        char w[64], *e;
        int rc = want_word(h, w, sizeof w, what);
        if (rc < 0)
            return rc;
        v[i] = strtod(w, &e);
        if (e == w || *e || !isfinite(v[i]))
            return bad(h, TVPAL_E_FORMAT, "%s: \"%s\" is not a number", what, w);
    }
    return 0;
}

static int type_of(const char *name)
{
    for (int i = 0; i < NTYPES; i++)
        if (!strcasecmp(name, vtk_types[i].name))
            return i;
    return -1;
}

/* Skips count values of type t (ASCII: count words; BINARY: their bytes,
 * which must be in the file). */
static int skip_values(struct vtk_hdr *h, const char *what, uint64_t count,
                       int t)
{
    if (h->binary) {
        if (t < 0)
            return bad(h, TVPAL_E_FORMAT, "%s: type not read, its size "
                       "unknown", what, NULL);
        long long here = ftello(h->fp);
        uint64_t bytes = count * vtk_types[t].size;
        if (here < 0 || bytes > (uint64_t)(h->size - here)) {
            char n[64];
            snprintf(n, sizeof n, "%llu", (unsigned long long)bytes);
            return bad(h, TVPAL_E_FORMAT, "%s: the file ends before its %s "
                       "bytes", what, n);
        }
        return fseeko(h->fp, here + (long long)bytes, SEEK_SET) < 0
                   ? bad(h, TVPAL_E_READ, "%s: seek failed", what, NULL) : 0;
    }
    char w[64];
    for (uint64_t i = 0; i < count; i++)
        if (word(h, w, sizeof w) < 0) {
            char n[80];
            snprintf(n, sizeof n, "%llu of %llu values",
                     (unsigned long long)i, (unsigned long long)count);
            return bad(h, TVPAL_E_FORMAT, "%s: the file ends after %s", what,
                       n);
        }
    return 0;
}

static struct vtk_array *add_array(struct vtk_hdr *h)
{
    if (h->n == h->cap) {
        int cap = h->cap ? 2 * h->cap : 8;
        struct vtk_array *a = realloc(h->arrays, sizeof *a * (size_t)cap);
        if (!a)
            return NULL;
        h->arrays = a;
        h->cap = cap;
    }
    struct vtk_array *a = &h->arrays[h->n++];
    memset(a, 0, sizeof *a);
    return a;
}

/* A new array of h, filled: its kind (upper case), name, type and
 * components, in section `cell`, its values starting here; NULL out of
 * memory. */
static struct vtk_array *record_array(struct vtk_hdr *h, const char *kind,
                                      const char *name, const char *type,
                                      long ncomp, int cell)
{
    struct vtk_array *a = add_array(h);
    if (!a)
        return NULL;
    snprintf(a->kind, sizeof a->kind, "%s", kind);
    for (char *c = a->kind; *c; c++)
        *c = (char)(*c >= 'a' && *c <= 'z' ? *c - 32 : *c);
    snprintf(a->name, sizeof a->name, "%s", name);
    snprintf(a->type, sizeof a->type, "%s", type);
    a->t = type_of(type);
    a->ncomp = ncomp;
    a->cell = cell;
    a->offset = ftello(h->fp);
    return a;
}

/* METADATA: its lines up to an empty one (VTK 9's component names and
 * information keys), skipped. */
static int skip_metadata(struct vtk_hdr *h)
{
    char line[512];
    end_line(h);
    while (fgets(line, sizeof line, h->fp)) {
        h->line++;
        if (line[strspn(line, " \t\r")] == '\n')
            break;
    }
    return 0;
}

/* FIELD name n, then its n arrays: those of count tuples in a section
 * (cell >= 0) are the section's arrays, the rest skipped. */
static int field_arrays(struct vtk_hdr *h, uint64_t count, int cell)
{
    char name[128], type[64];
    long long na;
    int rc;
    if ((rc = want_word(h, name, sizeof name, "FIELD's name")) < 0 ||
        (rc = want_long(h, &na, "FIELD's array count")) < 0)
        return rc;
    for (long long i = 0; i < na; i++) {
        long long nc, nt;
        if ((rc = want_word(h, name, sizeof name, "a FIELD array")) < 0)
            return rc;
        if (!strcasecmp(name, "NULL_ARRAY"))
            continue;
        if (!strcasecmp(name, "METADATA")) {
            /* the array before's (its COMPONENT_NAMES, as VTK 9 writes
             * them): not an array */
            if ((rc = skip_metadata(h)) < 0)
                return rc;
            i--;
            continue;
        }
        if ((rc = want_long(h, &nc, "the FIELD array's components")) < 0 ||
            (rc = want_long(h, &nt, "the FIELD array's tuples")) < 0 ||
            (rc = want_word(h, type, sizeof type, "its type")) < 0)
            return rc;
        if (h->binary)
            end_line(h);
        if (cell >= 0 && (uint64_t)nt == count && nc > 0 &&
            !record_array(h, "FIELD", name, type, (long)nc, cell))
            return TVPAL_E_NOMEM;
        if ((rc = skip_values(h, name, (uint64_t)nc * (uint64_t)nt,
                              type_of(type))) < 0)
            return rc;
    }
    return 0;
}

/* LOOKUP_TABLE name size or COLOR_SCALARS name n (n values per tuple of
 * count): skipped. */
static int skip_colours(struct vtk_hdr *h, const char *kw, uint64_t count)
{
    char name[128];
    long long n;
    const int table = !strcasecmp(kw, "LOOKUP_TABLE");
    int rc;
    if ((rc = want_word(h, name, sizeof name, table ? "the table's name"
                                                 : "COLOR_SCALARS' name")) < 0 ||
        (rc = want_long(h, &n, table ? "LOOKUP_TABLE's size"
                                     : "COLOR_SCALARS' value count")) < 0)
        return rc;
    if (h->binary)
        end_line(h);
    return skip_values(h, name, (uint64_t)n * (table ? 4 : count),
                       h->binary ? type_of("unsigned_char") : 0);
}

/* What follows SCALARS name type: [ncomp] LOOKUP_TABLE name (VTK requires
 * the table); *ncomp gets the count (1 where none is given). */
static int scalars_tail(struct vtk_hdr *h, const char *name, long *ncomp)
{
    char w[64];
    int rc;
    *ncomp = 1;
    if ((rc = want_word(h, w, sizeof w, "LOOKUP_TABLE")) < 0)
        return rc;
    if (strcasecmp(w, "LOOKUP_TABLE")) {
        char *e;
        *ncomp = strtol(w, &e, 10);
        if (e == w || *e || *ncomp < 1)
            return bad(h, TVPAL_E_FORMAT, "SCALARS %s: \"%s\" is neither a "
                       "component count nor LOOKUP_TABLE", name, w);
        if ((rc = want_word(h, w, sizeof w, "LOOKUP_TABLE")) < 0)
            return rc;
    }
    if (strcasecmp(w, "LOOKUP_TABLE"))
        return bad(h, TVPAL_E_FORMAT, "SCALARS %s: LOOKUP_TABLE expected, "
                   "not \"%s\"", name, w);
    return want_word(h, w, sizeof w, "the lookup table's name");
}

/* SCALARS, VECTORS, NORMALS, TENSORS or TEXTURE_COORDINATES (keyword kw)
 * of count tuples: an array of the section. */
static int data_attribute(struct vtk_hdr *h, const char *kw, uint64_t count,
                          int cell)
{
    char name[128], type[64];
    long long dim = 0;
    long ncomp = !strcasecmp(kw, "TENSORS") ? 9 : 3;
    int rc;
    if ((rc = want_word(h, name, sizeof name, "the attribute's name")) < 0)
        return rc;
    if (!strcasecmp(kw, "TEXTURE_COORDINATES") &&
        (rc = want_long(h, &dim, "the coordinates' dimension")) < 0)
        return rc;
    if ((rc = want_word(h, type, sizeof type, "the attribute's type")) < 0)
        return rc;
    if (dim)
        ncomp = (long)dim;
    if (!strcasecmp(kw, "SCALARS") && (rc = scalars_tail(h, name, &ncomp)) < 0)
        return rc;
    if (h->binary)
        end_line(h);
    const struct vtk_array *a = record_array(h, kw, name, type, ncomp, cell);
    if (!a)
        return TVPAL_E_NOMEM;
    return skip_values(h, name, count * (uint64_t)ncomp, a->t);
}

/* One attribute of a POINT_DATA (cell 0) or CELL_DATA (cell 1) section of
 * count tuples, its keyword kw read; cell -1: the dataset's own FIELD or
 * METADATA before them (never a variable).  The arrays of a section's
 * FIELD with count tuples are arrays of the section, as VTK's writer puts
 * every point array but the active attributes there. */
static int attribute(struct vtk_hdr *h, const char *kw, uint64_t count,
                     int cell)
{
    if (!strcasecmp(kw, "METADATA"))
        return skip_metadata(h);
    if (!strcasecmp(kw, "FIELD"))
        return field_arrays(h, count, cell);
    if (!strcasecmp(kw, "LOOKUP_TABLE") || !strcasecmp(kw, "COLOR_SCALARS"))
        return skip_colours(h, kw, count);
    if (!strcasecmp(kw, "SCALARS") || !strcasecmp(kw, "VECTORS") ||
        !strcasecmp(kw, "NORMALS") || !strcasecmp(kw, "TENSORS") ||
        !strcasecmp(kw, "TEXTURE_COORDINATES"))
        return data_attribute(h, kw, count, cell);
    return bad(h, TVPAL_E_FORMAT, "unknown keyword \"%s\" in the %s", kw,
               cell ? "CELL_DATA" : "POINT_DATA");
}

static void hdr_free(struct vtk_hdr *h)
{
    if (h->fp)
        fclose(h->fp);
    free(h->arrays);
    memset(h, 0, sizeof *h);
}

/* Reads the header of path and finds its arrays into *h (hdr_free, also
 * after an error). */
/* Opens path (a regular file: a FIFO would block) into h->fp, h->size. */
static int open_file(struct vtk_hdr *h, const char *path,
                     struct tvpal_diag *diag)
{
    int fd = tvpal_open_regular(path, diag);
    if (fd < 0)
        return fd;
    if (!(h->fp = fdopen(fd, "rb"))) {
        close(fd);
        return tvpal_diag_set(diag, TVPAL_E_NOMEM, "%s: %s", path,
                              strerror(errno));
    }
    struct stat st;
    if (fstat(fileno(h->fp), &st) < 0)
        return tvpal_diag_set(diag, TVPAL_E_READ, "%s: %s", path,
                              strerror(errno));
    h->size = (long long)st.st_size;
    return 0;
}

/* The lines before the dataset's keywords: the version, the title, ASCII
 * or BINARY, DATASET STRUCTURED_POINTS. */
static int read_preamble(struct vtk_hdr *h)
{
    char line[512], w[128];
    h->line = 1;
    if (!fgets(line, sizeof line, h->fp) ||
        strncmp(line, "# vtk DataFile Version", 22))
        return bad(h, TVPAL_E_FORMAT, "not a legacy VTK file (no \"# vtk "
                   "DataFile Version\" line)", NULL, NULL);
    sscanf(line + 22, "%31s", h->version);
    if (!strchr(line, '\n'))
        end_line(h);
    h->line++;
    if (!fgets(line, sizeof line, h->fp))
        return bad(h, TVPAL_E_FORMAT, "the file ends before its title", NULL,
                   NULL);
    int whole = strchr(line, '\n') != NULL;
    line[strcspn(line, "\r\n")] = 0;
    snprintf(h->title, sizeof h->title, "%.159s", line);
    if (!whole)
        end_line(h);
    h->line++;
    int rc = want_word(h, w, sizeof w, "ASCII or BINARY");
    if (rc < 0)
        return rc;
    if (!strcasecmp(w, "BINARY"))
        h->binary = 1;
    else if (strcasecmp(w, "ASCII"))
        return bad(h, TVPAL_E_FORMAT, "\"%s\" where ASCII or BINARY was "
                   "expected", w, NULL);
    if ((rc = want_word(h, w, sizeof w, "DATASET")) < 0)
        return rc;
    if (strcasecmp(w, "DATASET"))
        return bad(h, TVPAL_E_FORMAT, "\"%s\" where DATASET was expected", w,
                   NULL);
    if ((rc = want_word(h, w, sizeof w, "the dataset type")) < 0)
        return rc;
    if (strcasecmp(w, "STRUCTURED_POINTS"))
        return bad(h, TVPAL_E_FORMAT, "DATASET %s: only STRUCTURED_POINTS "
                   "(image data) is read from legacy VTK files", w, NULL);
    return 0;
}

/* DIMENSIONS NX NY NZ: each 1..INT32_MAX, their product addressable. */
static int read_dims(struct vtk_hdr *h)
{
    long long v[3];
    int rc = 0;
    for (int i = 0; i < 3 && rc == 0; i++)
        rc = want_long(h, &v[i], "DIMENSIONS");
    if (rc < 0)
        return rc;
    for (int i = 0; i < 3; i++) {
        if (v[i] < 1 || v[i] > INT32_MAX)
            return bad(h, TVPAL_E_FORMAT, "DIMENSIONS: an axis of size 0 or "
                       "too large", NULL, NULL);
        h->dims[i] = (uint32_t)v[i];
    }
    size_t points;
    if (tvpal_points(h->dims, sizeof(double), &points) < 0)
        return bad(h, TVPAL_E_OVERFLOW, "DIMENSIONS: more points than can be "
                   "addressed", NULL, NULL);
    h->have_dims = 1;
    return 0;
}

static int scan(struct vtk_hdr *h, const char *path, struct tvpal_diag *diag)
{
    memset(h, 0, sizeof *h);
    h->path = path;
    h->diag = diag;
    h->spacing[0] = h->spacing[1] = h->spacing[2] = 1;
    int rc = open_file(h, path, diag);
    if (rc == 0)
        rc = read_preamble(h);
    if (rc < 0)
        return rc;
    char w[128];
    uint64_t count = 0;
    int section = -1;   /* -1 none yet, 0 POINT_DATA, 1 CELL_DATA */
    while ((rc = word(h, w, sizeof w)) == 0) {
        long long v[3];
        if (!strcasecmp(w, "DIMENSIONS")) {
            if ((rc = read_dims(h)) < 0)
                return rc;
        } else if (!strcasecmp(w, "SPACING") || !strcasecmp(w, "ASPECT_RATIO")) {
            if ((rc = want_doubles(h, h->spacing, w)) < 0)
                return rc;
        } else if (!strcasecmp(w, "ORIGIN")) {
            if ((rc = want_doubles(h, h->origin, "ORIGIN")) < 0)
                return rc;
        } else if (!strcasecmp(w, "POINT_DATA") || !strcasecmp(w, "CELL_DATA")) {
            int cell = !strcasecmp(w, "CELL_DATA");
            if ((rc = want_long(h, &v[0], w)) < 0)
                return rc;
            if (!h->have_dims)
                return bad(h, TVPAL_E_FORMAT, "%s before DIMENSIONS", w, NULL);
            uint64_t np = (uint64_t)h->dims[0] * h->dims[1] * h->dims[2], nc = 1;
            for (int i = 0; i < 3; i++)
                nc *= h->dims[i] > 1 ? h->dims[i] - 1 : 1;
            if ((uint64_t)v[0] != (cell ? nc : np)) {
                char m[120];
                snprintf(m, sizeof m, "%lld; DIMENSIONS %u %u %u make %llu",
                         v[0], h->dims[0], h->dims[1], h->dims[2],
                         (unsigned long long)(cell ? nc : np));
                return bad(h, TVPAL_E_FORMAT, "%s %s", w, m);
            }
            count = (uint64_t)v[0];
            section = cell;
        } else if (section < 0 && !strcasecmp(w, "FIELD")) {
            if ((rc = attribute(h, w, 1, -1)) < 0)   /* the dataset's field */
                return rc;
        } else if (section < 0 && !strcasecmp(w, "METADATA")) {
            if ((rc = attribute(h, w, 1, -1)) < 0)
                return rc;
        } else if (section < 0) {
            return bad(h, TVPAL_E_FORMAT, "unknown keyword \"%s\" in the "
                       "STRUCTURED_POINTS header", w, NULL);
        } else if ((rc = attribute(h, w, count, section)) < 0) {
            return rc;
        }
    }
    if (ferror(h->fp))
        return tvpal_diag_set(diag, TVPAL_E_READ, "%s: read error", path);
    if (!h->have_dims)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: no DIMENSIONS",
                              path);
    for (int i = 0; i < 3; i++)
        if (!(h->spacing[i] > 0))
            return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: SPACING %g on "
                                  "axis %c (positive expected)", path,
                                  h->spacing[i], "xyz"[i]);
    return 0;
}

/* "a, vel (VECTORS), b" of the point arrays into names (cap bytes). */
static void list_points(const struct vtk_hdr *h, char *names, size_t cap)
{
    size_t k = 0;
    names[0] = 0;
    for (int i = 0; i < h->n && k < cap; i++) {
        const struct vtk_array *a = &h->arrays[i];
        if (a->cell)
            continue;
        const int scalars = !strcmp(a->kind, "SCALARS");
        int m = snprintf(names + k, cap - k, "%s%s%s%s%s", k ? ", " : "",
                         a->name, scalars ? "" : " (", scalars ? "" : a->kind,
                         scalars ? "" : ")");
        k += m > 0 ? (size_t)m : 0;
    }
    if (!names[0])
        snprintf(names, cap, "none");
}

/* The first point array named var of kind (NULL: any kind), or -1. */
static int find_point(const struct vtk_hdr *h, const char *var,
                      const char *kind)
{
    for (int i = 0; i < h->n; i++) {
        const struct vtk_array *a = &h->arrays[i];
        if (!a->cell && (!var || !strcmp(a->name, var)) &&
            (!kind || !strcmp(a->kind, kind)))
            return i;
    }
    return -1;
}

/* The point array var (NULL: the first point SCALARS, VTK's active
 * scalars, or where there are none the first point VECTORS), checked for
 * reading: a SCALARS of that name before any other array (VECTORS,
 * NORMALS, TENSORS, TEXTURE_COORDINATES, a FIELD array); one component, or
 * with magnitude up to TVPAL_INPUT_COMPONENTS_MAX. */
static int choose(const struct vtk_hdr *h, const char *var, int magnitude,
                  int *out)
{
    char names[160];
    list_points(h, names, sizeof names);
    int pick = find_point(h, var, "SCALARS");
    if (pick < 0)
        pick = find_point(h, var, var ? NULL : "VECTORS");
    if (pick < 0 && var)
        for (int i = 0; i < h->n; i++)
            if (!strcmp(h->arrays[i].name, var))
                return tvpal_diag_set(h->diag, TVPAL_E_INVAL, "%s: %s is "
                                      "cell %s; tvpal reads point arrays "
                                      "(point arrays: %s)", h->path, var,
                                      h->arrays[i].kind, names);
    if (pick < 0)
        return tvpal_diag_set(h->diag, TVPAL_E_INVAL, var ? "%s: no point "
                              "array %s (point arrays: %s)" : "%s: no point "
                              "SCALARS or VECTORS to read%s (point arrays: "
                              "%s; --var chooses one)", h->path,
                              var ? var : "", names);
    const struct vtk_array *a = &h->arrays[pick];
    if (a->ncomp < 1)
        return tvpal_diag_set(h->diag, TVPAL_E_FORMAT, "%s: %s %s has %ld "
                              "components", h->path, a->kind, a->name,
                              a->ncomp);
    if (a->ncomp > 1 && !magnitude)
        return tvpal_diag_set(h->diag, TVPAL_E_INVAL, "%s: %s %s has %ld "
                              "components; tvpal reads one value per point: "
                              "--magnitude encodes the vector's length",
                              h->path, a->kind, a->name, a->ncomp);
    if (a->ncomp > TVPAL_INPUT_COMPONENTS_MAX)
        return tvpal_diag_set(h->diag, TVPAL_E_INVAL, "%s: %s %s has %ld "
                              "components; --magnitude reads at most %d",
                              h->path, a->kind, a->name, a->ncomp,
                              TVPAL_INPUT_COMPONENTS_MAX);
    if (a->t < 0)
        return tvpal_diag_set(h->diag, TVPAL_E_FORMAT, "%s: %s %s has "
                              "type %s (float, double, [unsigned_]char, "
                              "short, int, long are read)", h->path, a->kind,
                              a->name, a->type);
    size_t n;
    if (tvpal_points(h->dims, (uint64_t)vtk_types[a->t].size *
                                  (uint64_t)a->ncomp, &n) < 0)
        return tvpal_diag_set(h->diag, TVPAL_E_OVERFLOW, "%s: %s %s: %ux%ux%u "
                              "points of %ld components: more than can be "
                              "addressed", h->path, a->kind, a->name,
                              h->dims[0], h->dims[1], h->dims[2], a->ncomp);
    *out = pick;
    return 0;
}

/* ------------------------------------------------------------- backend */

static int vtk_open(struct tvpal_input_file **out, const char *path,
                    const struct tvpal_input_opts *opts,
                    struct tvpal_input_info *info, double **times,
                    struct tvpal_diag *diag)
{
    struct vtk_hdr h;
    int pick = -1;
    int rc = scan(&h, path, diag);
    if (rc == 0)
        rc = choose(&h, opts->var, opts->magnitude, &pick);
    if (rc == 0 && strlen(h.arrays[pick].name) >= sizeof info->var)
        rc = tvpal_diag_set(diag, TVPAL_E_RANGE, "%s: array name of %zu "
                            "characters (at most %zu are read)", path,
                            strlen(h.arrays[pick].name), sizeof info->var - 1);
    struct tvpal_input_file *f = NULL;
    if (rc == 0 && (!(f = calloc(1, sizeof *f)) || !(f->path = strdup(path))))
        rc = TVPAL_E_NOMEM;
    if (rc == 0) {
        const struct vtk_array *a = &h.arrays[pick];
        memcpy(info->dims, h.dims, sizeof info->dims);
        memcpy(info->spacing, h.spacing, sizeof info->spacing);
        memcpy(info->origin, h.origin, sizeof info->origin);
        snprintf(info->var, sizeof info->var, "%s", a->name);
        info->type = vtk_types[a->t].as;
        info->components = (uint32_t)a->ncomp;
        info->steps = 1;
        memcpy(f->var, info->var, sizeof f->var);
        memcpy(f->kind, a->kind, sizeof f->kind);
        memcpy(f->dims, h.dims, sizeof f->dims);
        f->t = a->t;
        f->ncomp = a->ncomp;
        f->binary = h.binary;
        f->offset = a->offset;
        *out = f;
        f = NULL;
    }
    if (f)
        free(f->path);
    free(f);
    hdr_free(&h);
    return rc;
}

/* The value of type t, big-endian, at src as a double: exact, but for
 * 64-bit integers beyond 2^53. */
static double value_be(const unsigned char *src, int t)
{
    const struct vtk_type *ty = &vtk_types[t];
    uint64_t u = 0;
    for (unsigned b = 0; b < ty->size; b++)
        u = u << 8 | src[b];
    if (ty->is_float && ty->size == 4) {
        const uint32_t u32 = (uint32_t)u;
        float f;
        memcpy(&f, &u32, 4);
        return f;
    }
    if (ty->is_float) {
        double g;
        memcpy(&g, &u, 8);
        return g;
    }
    if (ty->is_signed) {   /* sign-extend from size bytes */
        const unsigned sh = 64 - 8 * ty->size;
        return (double)((int64_t)(u << sh) >> sh);
    }
    return (double)u;
}

/* n values of type t, big-endian, at src into dst. */
static void convert_be(const unsigned char *src, int t, size_t n, float *dst)
{
    const struct vtk_type *ty = &vtk_types[t];
    for (size_t i = 0; i < n; i++, src += ty->size) {
        uint64_t u = 0;
        for (unsigned b = 0; b < ty->size; b++)
            u = u << 8 | src[b];
        float f;
        if (ty->is_float && ty->size == 4) {
            uint32_t u32 = (uint32_t)u;
            memcpy(&f, &u32, 4);
        } else if (ty->is_float) {
            double g;
            memcpy(&g, &u, 8);
            f = (float)g;
        } else if (ty->is_signed) {   /* sign-extend from size bytes */
            unsigned sh = 64 - 8 * ty->size;
            f = (float)((int64_t)(u << sh) >> sh);
        } else {
            f = (float)u;
        }
        dst[i] = f;
    }
}

/* n points of ncomp values of type t each, big-endian, at src into dst:
 * convert_be's values where ncomp is 1, else each point's length
 * (tvpal_input_mag_add). */
static void convert_points(const unsigned char *src, int t, long ncomp,
                           size_t n, float *dst)
{
    if (ncomp == 1) {
        convert_be(src, t, n, dst);
        return;
    }
    const unsigned sz = vtk_types[t].size;
    for (size_t i = 0; i < n; i++) {
        double sum = 0;
        for (long c = 0; c < ncomp; c++, src += sz)
            sum = tvpal_input_mag_add(sum, value_be(src, t));
        dst[i] = tvpal_input_mag_end(sum);
    }
}

/* The next ASCII value of f's array (a word of h) into *v: float32 values
 * as strtof reads them, the others as strtod; i is its index, for the
 * message.  0, or TVPAL_E_FORMAT (the file ends: total values expected;
 * not a number). */
static int ascii_value(const struct tvpal_input_file *f, struct vtk_hdr *h,
                       size_t i, size_t total, double *v)
{
    char w[64], *e;
    if (word(h, w, sizeof w) < 0)
        return tvpal_diag_set(h->diag, TVPAL_E_FORMAT, "%s: %s %s: the "
                              "file ends after %zu of %zu values", f->path,
                              f->kind, f->var, i, total);
    *v = vtk_types[f->t].size == 4 && vtk_types[f->t].is_float
             ? (double)strtof(w, &e) : strtod(w, &e);
    if (e == w || *e)
        return tvpal_diag_set(h->diag, TVPAL_E_FORMAT, "%s: %s %s: value "
                              "%zu is \"%.32s\", not a number", f->path,
                              f->kind, f->var, i + 1, w);
    return 0;
}

/* The next ASCII point of f's array into *out: its value (float32 as
 * read: a double of float32's value or strtod's rounded once), or the
 * length of its f->ncomp components; *i counts the values read. */
static int ascii_point(const struct tvpal_input_file *f, struct vtk_hdr *h,
                       size_t *i, size_t total, float *out)
{
    double sum = 0, v = 0;
    for (long c = 0; c < f->ncomp; c++) {
        int rc = ascii_value(f, h, (*i)++, total, &v);
        if (rc < 0)
            return rc;
        if (f->ncomp > 1)
            sum = tvpal_input_mag_add(sum, v);
    }
    *out = f->ncomp > 1 ? tvpal_input_mag_end(sum) : (float)v;
    return 0;
}

static int vtk_read(struct tvpal_input_file *f, uint32_t k, float *dst,
                    struct tvpal_diag *diag)
{
    if (k != 0)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: step %u of a file "
                              "that holds one", f->path, k);
    FILE *fp = fopen(f->path, "rb");
    if (!fp)
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s", f->path,
                              strerror(errno));
    size_t n = (size_t)f->dims[0] * f->dims[1] * f->dims[2];
    int rc = 0;
    if (fseeko(fp, f->offset, SEEK_SET) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_READ, "%s: seek: %s", f->path,
                            strerror(errno));
    if (rc == 0 && f->binary) {
        /* whole points: at most 2 KiB each (choose), 32 a buffer */
        unsigned char buf[1 << 16];
        const size_t psz = vtk_types[f->t].size * (size_t)f->ncomp;
        const size_t per = sizeof buf / psz;
        for (size_t i = 0; rc == 0 && i < n; i += per) {
            size_t want = n - i < per ? n - i : per;
            if (fread(buf, psz, want, fp) != want)
                rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: %s %s: "
                                    "the file ends within its values "
                                    "(changed since it was opened?)",
                                    f->path, f->kind, f->var);
            else
                convert_points(buf, f->t, f->ncomp, want, dst + i);
        }
    }
    struct vtk_hdr h = {.path = f->path, .diag = diag, .fp = fp, .line = 0};
    const size_t total = n * (size_t)f->ncomp;
    for (size_t p = 0, i = 0; rc == 0 && !f->binary && p < n; p++)
        rc = ascii_point(f, &h, &i, total, dst + p);
    fclose(fp);
    return rc;
}

static void conv_box(const unsigned char *src, size_t count, float *dst,
                     const void *ctx)
{
    const struct tvpal_input_file *f = ctx;
    convert_points(src, f->t, f->ncomp, count, dst);
}

static int vtk_read_box(struct tvpal_input_file *f, uint32_t k,
                        const uint32_t lo[3], const uint32_t n[3], float *dst,
                        struct tvpal_diag *diag)
{
    if (k != 0)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: step %u of a file "
                              "that holds one", f->path, k);
    char what[160];
    snprintf(what, sizeof what, "%s %.130s", f->kind, f->var);
    if (f->binary) {
        int fd = open(f->path, O_RDONLY);
        if (fd < 0)
            return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s", f->path,
                                  strerror(errno));
        /* a point's components together, as one value of their bytes */
        int rc = tvpal_input_box_pread(fd, (uint64_t)f->offset, f->dims,
                                       vtk_types[f->t].size *
                                           (unsigned)f->ncomp,
                                       lo, n, dst, n[0], (size_t)n[0] * n[1],
                                       conv_box, f, &f->io, f->path, what,
                                       diag);
        close(fd);
        return rc;
    }
    FILE *fp = fopen(f->path, "rb");
    if (!fp)
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: %s", f->path,
                              strerror(errno));
    int rc = 0;
    if (fseeko(fp, f->offset, SEEK_SET) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_READ, "%s: seek: %s", f->path,
                            strerror(errno));
    /* The points in file order up to the box's last: row r of the box
     * (y = r % n1, z = r / n1) starts at point `want`; the values of the
     * points before it are read as words only. */
    const size_t nx = f->dims[0], ny = f->dims[1];
    const size_t nrows = (size_t)n[1] * n[2];
    const size_t total = nx * ny * f->dims[2] * (size_t)f->ncomp;
    struct vtk_hdr h = {.path = f->path, .diag = diag, .fp = fp, .line = 0};
    size_t r = 0, x = 0, i = 0, p = 0;   /* i: values read, p: points */
    size_t want = ((size_t)lo[2] * ny + lo[1]) * nx + lo[0];
    for (; rc == 0 && r < nrows; p++) {
        if (p < want) {
            char w[64];
            for (long c = 0; c < f->ncomp; c++, i++)
                if (word(&h, w, sizeof w) < 0) {
                    rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: %s %s: "
                                        "the file ends after %zu of %zu "
                                        "values", f->path, f->kind, f->var,
                                        i, total);
                    break;
                }
            continue;
        }
        if ((rc = ascii_point(f, &h, &i, total, &dst[r * n[0] + x])) < 0)
            break;
        if (++x < n[0]) {
            want++;
            continue;
        }
        x = 0;
        if (++r < nrows)
            want = (((size_t)lo[2] + r / n[1]) * ny + lo[1] + r % n[1]) * nx +
                   lo[0];
    }
    fclose(fp);
    return rc;
}

static uint64_t vtk_box_scratch(const struct tvpal_input_file *f,
                                const uint32_t n[3])
{
    const unsigned psz = vtk_types[f->t].size * (unsigned)f->ncomp;
    return f->binary ? tvpal_input_box_pread_scratch(f->dims, psz, n, 0) : 0;
}

static void vtk_close(struct tvpal_input_file *f)
{
    if (f) {
        free(f->path);
        free(f->io.buf);
    }
    free(f);
}

static int vtk_describe(const char *path, char **text, struct tvpal_diag *diag)
{
    struct vtk_hdr h;
    *text = NULL;
    int rc = scan(&h, path, diag);
    size_t cap = 1024;
    for (int i = 0; i < h.n; i++)
        cap += sizeof h.arrays[i] + 64;
    char *t = rc == 0 ? malloc(cap) : NULL;
    if (rc == 0 && !t)
        rc = TVPAL_E_NOMEM;
    if (rc < 0) {
        hdr_free(&h);
        return rc;
    }
    int active = -1;
    for (int i = 0; i < h.n && active < 0; i++)
        if (!h.arrays[i].cell && !strcmp(h.arrays[i].kind, "SCALARS"))
            active = i;
    size_t n = (size_t)snprintf(t, cap, "vtk (legacy VTK %s, %s, "
                                "STRUCTURED_POINTS): %s\nextent 0 %u 0 %u 0 %u "
                                "(%ux%ux%u) spacing %.9g %.9g %.9g origin %.9g "
                                "%.9g %.9g\n", h.version, h.binary ? "BINARY "
                                "big-endian" : "ASCII", h.title, h.dims[0] - 1,
                                h.dims[1] - 1, h.dims[2] - 1, h.dims[0],
                                h.dims[1], h.dims[2], h.spacing[0], h.spacing[1],
                                h.spacing[2], h.origin[0], h.origin[1],
                                h.origin[2]);
    for (int i = 0; i < h.n; i++) {
        const struct vtk_array *a = &h.arrays[i];
        n += (size_t)snprintf(t + n, cap - n, "%s %s components=%ld%s%s%s\n",
                              a->name, a->type, a->ncomp,
                              strcmp(a->kind, "SCALARS") ? " " : "",
                              strcmp(a->kind, "SCALARS") ? a->kind : "",
                              i == active ? " [active scalars]"
                              : a->cell ? " [cell data]" : "");
    }
    hdr_free(&h);
    *text = t;
    return 0;
}

const struct tvpal_input_backend tvpal_input_vtk = {
    .name = "vtk", .open = vtk_open, .read = vtk_read,
    .read_box = vtk_read_box, .box_scratch = vtk_box_scratch,
    .close = vtk_close, .describe = vtk_describe};
