/* tvpal_in_vti.c: the VTK XML ImageData (.vti) backend of tvpal_input, and
 * the only file of the tree that includes expat (LAYERS.md).  It
 * also reads .pvti files (PImageData: the whole extent assembled from its
 * pieces, each a .vti read as below, one piece at a time) and parses .pvd
 * collections for tvpal_input.c (tvpal_input_vtk_collection).
 *
 * One file is one timestep.  The XML is parsed with expat up to the
 * <AppendedData> tag (what follows the '_' marker is not XML: raw bytes or
 * base64 text), the point array's data is found by the rules of the VTK
 * XML format and tvpal_inflate (zlib or libdeflate) inflates its blocks:
 *   ascii     numbers separated by white space in the DataArray's text;
 *   binary    base64 text in the DataArray;
 *   appended  at `offset` bytes (raw) or characters (base64) after '_'.
 * Binary data starts with a header of header_type (UInt32 or UInt64)
 * integers in the file's byte order: uncompressed, [nbytes]; compressed,
 * [nblocks, blocksize, lastblocksize, csize_1 .. csize_n] followed by the
 * blocks.  VTK base64-encodes an uncompressed header with its data as one
 * stream, a compressed header apart from its blocks; the decoder reads a
 * padded quad as the end of one stream and goes on with the next, which
 * reads both layouts (and a header written with its blocks).
 *
 * The reader never maps a file: a mapped file that shrinks under its reader
 * (a simulation rewriting its output, a copy in progress on a shared file
 * system) kills the process with SIGBUS at the first page past its new
 * end, where a read returns short and the reader says which file shrank.
 * Every byte comes by pread: the XML in pieces (load), array data straight
 * into its destination or through a window (struct src).  Every file is
 * opened as a regular file (tvpal_open_regular): a FIFO named in a .pvd or
 * a .pvti would block for ever.
 *
 * Nothing is kept between calls but the path and what open found: read opens
 * the file, parses it again and decodes into dst (float32 arrays in place;
 * other types through one step of scratch).  read_box parses it again as
 * well and reads the box's values only (decode_box): raw appended rows by
 * pread (tvpal_input_box_pread), the zlib blocks that meet the box one at
 * a time (raw: by pread), base64 decoded in order up to the box's end,
 * ascii parsed whole; its scratch (a batch of rows, one block) is kept
 * between calls.
 *
 * An array of several components per point (NumberOfComponents: a vector,
 * a tensor) is read, with tvpal_input_opts' magnitude, as each point's
 * length: its components' bytes are one value of that many bytes to the
 * code above, converted together (convert_points).  A whole read of such
 * an array is a box read of the whole grid (decode_box, its scratch), not
 * a step of stored values in memory.
 *
 * Errors are TVPAL_E_FORMAT for a file that is not a readable .vti, with
 * the path and the problem in the diag; TVPAL_E_INVAL for an array that
 * cannot be chosen or has several components without magnitude. */
#include "tvpal_fs.h"
#include "tvpal_inflate.h"
#include "tvpal_input_impl.h"
#include "tvpal_pool.h"
#include "tvpal_size.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <expat.h>

#define ZLIB_NAME "vtkZLibDataCompressor"

/* DataArray types: VTK's name, bytes per value, and the tvpal type that
 * info reports (the nearest float type where tvpal has no such integer). */
static const struct vti_type {
    const char *name;
    unsigned size;
    enum tvpal_type as;
} vti_types[] = {
    {"Float32", 4, TVPAL_F32}, {"Float64", 8, TVPAL_F64},
    {"Int8", 1, TVPAL_F32},    {"UInt8", 1, TVPAL_U8},
    {"Int16", 2, TVPAL_I16},   {"UInt16", 2, TVPAL_U16},
    {"Int32", 4, TVPAL_F64},   {"UInt32", 4, TVPAL_F64},
    {"Int64", 8, TVPAL_F64},   {"UInt64", 8, TVPAL_F64},
};
enum { T_F32, T_F64, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_I64, T_U64,
       T_COUNT };

enum { F_ASCII, F_BINARY, F_APPENDED, F_UNKNOWN };

struct vti_array {
    char *name;                 /* "" when the file gives none */
    char type[32];              /* as the file spells it */
    int t;                      /* T_*, or -1 for a type not read */
    long ncomp;
    int fmt;                    /* F_* */
    char fmt_name[32];
    int has_offset;
    uint64_t offset;
    size_t text_begin, text_end;   /* the element's data text in the
                                 * file: the first run of text directly
                                 * inside it that is not all white space
                                 * (VTK writes InformationKey elements
                                 * after the data, older writers before) */
    int has_text;
    size_t run_begin;           /* the run of text being parsed, */
    int in_run, run_data;       /* and whether it holds more than space */
    int cell;                   /* in CellData, not PointData */
    int field;                  /* in the ImageData's FieldData (ParaView's
                                 * TimeValue): never a variable */
};

/* Bytes per point of array a: its ncomp values (choose bounds ncomp). */
static unsigned point_size(const struct vti_array *a)
{
    return vti_types[a->t].size * (unsigned)a->ncomp;
}

/* A piece of a .pvti: its extent and its .vti (resolved). */
struct vti_piece {
    long long ext[6];
    char *source;
};

struct vti_doc {
    const char *path;
    int fd;                     /* the file, open; -1 when none */
    uint64_t size;              /* its bytes when it was opened */
    int big_endian, header64;
    char byte_order[32], header_type[32], compressor[64];
    int have_image, have_whole, have_direction;
    long long whole[6], extent[6];
    int have_extent;
    double origin[3], spacing[3], direction[9];
    int npieces;
    int parallel;               /* PImageData: pcs[] are its pieces */
    struct vti_piece *pcs;
    int npcs, pcap;
    char *scalars;              /* the PointData's Scalars, or NULL */
    char *vectors;              /* its Vectors, or NULL */
    struct vti_array *arrays;
    int narrays, cap;
    int have_appended, appended_base64;
    size_t appended_at;         /* first byte after '_'; 0 if none */
    /* parser state */
    XML_Parser xp;
    int depth, piece_depth, data_depth, cur;   /* cur: array open, or -1 */
    int in_cell, in_field, skip_piece;
    int rc;                     /* an error a handler met */
    struct tvpal_diag *diag;
    struct tvpal_pool *pool;    /* reads: the file's (tvpal_input_opts) */
};

struct tvpal_input_file {
    char *path;
    char var[TVPAL_INPUT_VAR_MAX];  /* the array open chose */
    uint32_t dims[3];
    int t;
    long ncomp;                 /* its components (several: magnitude) */
    struct tvpal_pool *pool;    /* borrowed (tvpal_input_opts), or NULL */
    /* .pvti: the whole extent, the pieces and one piece of scratch */
    long long whole[6];
    struct vti_piece *pcs;
    int npcs;
    float *scratch;
    /* box reads: what the files hold (the most over the pieces), and the
     * scratch kept between calls */
    int has_raw, has_b64;
    uint64_t blk_max, cmax_max, nb_max;
    struct tvpal_box_io io;     /* rows of raw data, pieces of base64 */
    unsigned char *blk, *cbuf;  /* one inflated, one compressed block */
    size_t blk_cap, cbuf_cap;
};

/* ---------------------------------------------------------- file access */

/* Opens path, a regular file, into d->fd and d->size. */
static int open_doc_file(struct vti_doc *d, const char *path,
                         struct tvpal_diag *diag)
{
    int fd = tvpal_open_regular(path, diag);
    if (fd < 0)
        return fd;
    struct stat st;
    if (fstat(fd, &st) < 0) {
        int e = errno;
        close(fd);
        return tvpal_diag_set(diag, TVPAL_E_READ, "%s: %s", path, strerror(e));
    }
    if (st.st_size == 0) {
        close(fd);
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: empty file, not a "
                              "VTK ImageData file", path);
    }
    d->fd = fd;
    d->size = (uint64_t)st.st_size;
    return 0;
}

/* len bytes of d's file at off into p: TVPAL_E_TRUNC, naming the file,
 * where it is shorter now than it was at open (tvpal_input_pread). */
static int doc_pread(const struct vti_doc *d, void *p, size_t len,
                     uint64_t off, const char *what)
{
    return tvpal_input_pread(d->fd, p, len, off, d->path, what, d->diag);
}

/* Bytes [off, end) of a file, read through a window: raw, or base64 text
 * decoded as it is read (src_read: white space is skipped, and a padded
 * quad ends one encoded stream with the next one following). */
#define SRC_WINDOW ((size_t)32 << 10)
struct src {
    const struct vti_doc *d;
    uint64_t off, end;          /* the bytes [off, end) are not yet read */
    unsigned char win[SRC_WINDOW];
    size_t wpos, wlen;          /* win[wpos, wlen): read, not yet taken */
    int b64;
    unsigned char pend[3];
    unsigned npend, ipend;
    int bad;                    /* a character that is not base64 */
    int err;                    /* a read failed (its diag said why): the
                                 * code; then s ends there */
};

static int src_range(struct src *s, const struct vti_doc *d, uint64_t off,
                     uint64_t end, int b64)
{
    s->d = d;
    s->off = off;
    s->end = end > d->size ? d->size : end;
    s->wpos = s->wlen = 0;
    s->b64 = b64;
    s->npend = s->ipend = 0;
    s->bad = s->err = 0;
    return 0;
}

/* The window refilled: 0 at the end of s or after a failed read. */
static int src_fill(struct src *s)
{
    if (s->err || s->off >= s->end)
        return 0;
    size_t k = s->end - s->off < SRC_WINDOW ? (size_t)(s->end - s->off)
                                            : SRC_WINDOW;
    int rc = doc_pread(s->d, s->win, k, s->off, "its data");
    if (rc < 0) {
        s->err = rc;
        return 0;
    }
    s->off += k;
    s->wpos = 0;
    s->wlen = k;
    return 1;
}

/* The next byte, or -1 at the end (or after a failed read: s->err). */
static inline int src_getc(struct src *s)
{
    if (s->wpos == s->wlen && !src_fill(s))
        return -1;
    return s->win[s->wpos++];
}

/* The file offset of the next byte of s (raw: of the next value). */
static uint64_t src_pos(const struct src *s)
{
    return s->off - (s->wlen - s->wpos);
}

/* Up to n raw bytes into out (NULL: skipped); how many there were.  What
 * the window does not hold goes straight into out. */
static size_t src_take(struct src *s, unsigned char *out, size_t n)
{
    size_t got = 0;
    while (got < n && !s->err) {
        if (s->wpos < s->wlen) {
            size_t k = s->wlen - s->wpos < n - got ? s->wlen - s->wpos
                                                   : n - got;
            if (out)
                memcpy(out + got, s->win + s->wpos, k);
            s->wpos += k;
            got += k;
            continue;
        }
        const uint64_t room = s->end - s->off;
        if (room == 0)
            break;
        if (n - got < SRC_WINDOW && out) {
            src_fill(s);
            continue;
        }
        size_t k = n - got < room ? n - got : (size_t)room;
        int rc = out ? doc_pread(s->d, out + got, k, s->off, "its data") : 0;
        if (rc < 0) {
            s->err = rc;
            break;
        }
        s->off += k;
        got += k;
    }
    return got;
}

/* ------------------------------------------------------------ XML parse */

static void doc_free(struct vti_doc *d)
{
    for (int i = 0; i < d->narrays; i++)
        free(d->arrays[i].name);
    free(d->arrays);
    for (int i = 0; i < d->npcs; i++)
        free(d->pcs[i].source);
    free(d->pcs);
    free(d->scalars);
    free(d->vectors);
    if (d->fd >= 0)
        close(d->fd);
    memset(d, 0, sizeof *d);
    d->fd = -1;
}

static const char *attr(const XML_Char **atts, const char *name)
{
    for (int i = 0; atts[i]; i += 2)
        if (!strcmp(atts[i], name))
            return atts[i + 1];
    return NULL;
}

/* Stops the parse with an error (the first one wins); returns the code. */
static int fail(struct vti_doc *d, int code, const char *fmt, const char *a,
                const char *b)
{
    if (d->rc == 0) {
        char what[512];
        snprintf(what, sizeof what, fmt, a, b ? b : "");
        d->rc = tvpal_diag_set(d->diag, code, "%s: line %lu: %s", d->path,
                               (unsigned long)XML_GetCurrentLineNumber(d->xp),
                               what);
    }
    XML_StopParser(d->xp, XML_FALSE);
    return code;
}

static int nomem(struct vti_doc *d)
{
    d->rc = TVPAL_E_NOMEM;
    XML_StopParser(d->xp, XML_FALSE);
    return TVPAL_E_NOMEM;
}

static int parse_ints(const char *s, long long *v, int n)
{
    for (int i = 0; i < n; i++) {
        char *e;
        errno = 0;
        v[i] = strtoll(s, &e, 10);
        if (e == s || errno)
            return -1;
        s = e;
    }
    while (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r')
        s++;
    return *s ? -1 : 0;
}

static int parse_doubles(const char *s, double *v, int n)
{
    for (int i = 0; i < n; i++) {
        char *e;
        v[i] = strtod(s, &e);
        if (e == s || !isfinite(v[i]))
            return -1;
        s = e;
    }
    while (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r')
        s++;
    return *s ? -1 : 0;
}

static void copy_attr(char *dst, size_t cap, const char *v)
{
    snprintf(dst, cap, "%s", v);
}

static int start_vtkfile(struct vti_doc *d, const XML_Char **atts)
{
    const char *v = attr(atts, "type");
    if (v && !strcmp(v, "Collection"))
        return fail(d, TVPAL_E_FORMAT, "a .pvd collection (VTKFile type "
                    "Collection) where an ImageData file was expected", NULL,
                    NULL);
    if (!v || (strcmp(v, "ImageData") && strcmp(v, "PImageData")))
        return fail(d, TVPAL_E_FORMAT, "VTKFile type is %s; only ImageData "
                    "(.vti), PImageData (.pvti) and Collection (.pvd) are "
                    "read", v ? v : "missing", NULL);
    d->parallel = !strcmp(v, "PImageData");
    v = attr(atts, "byte_order");
    copy_attr(d->byte_order, sizeof d->byte_order, v ? v : "LittleEndian");
    if (!strcmp(d->byte_order, "BigEndian"))
        d->big_endian = 1;
    else if (strcmp(d->byte_order, "LittleEndian"))
        return fail(d, TVPAL_E_FORMAT, "byte_order %s (LittleEndian or "
                    "BigEndian expected)", v, NULL);
    v = attr(atts, "header_type");
    copy_attr(d->header_type, sizeof d->header_type, v ? v : "UInt32");
    if (!strcmp(d->header_type, "UInt64"))
        d->header64 = 1;
    else if (strcmp(d->header_type, "UInt32"))
        return fail(d, TVPAL_E_FORMAT, "header_type %s (UInt32 or UInt64 "
                    "expected)", v, NULL);
    v = attr(atts, "compressor");
    copy_attr(d->compressor, sizeof d->compressor, v ? v : "");
    return 0;
}

static int start_image(struct vti_doc *d, const XML_Char **atts)
{
    const char *v;
    d->have_image = 1;
    if (!(v = attr(atts, "WholeExtent")) || parse_ints(v, d->whole, 6) < 0)
        return fail(d, TVPAL_E_FORMAT, "ImageData WholeExtent is %s (six "
                    "integers expected)", v ? v : "missing", NULL);
    d->have_whole = 1;
    if ((v = attr(atts, "Origin")) && parse_doubles(v, d->origin, 3) < 0)
        return fail(d, TVPAL_E_FORMAT, "ImageData Origin is %s (three "
                    "numbers expected)", v, NULL);
    if ((v = attr(atts, "Spacing")) && parse_doubles(v, d->spacing, 3) < 0)
        return fail(d, TVPAL_E_FORMAT, "ImageData Spacing is %s (three "
                    "numbers expected)", v, NULL);
    if ((v = attr(atts, "Direction"))) {
        if (parse_doubles(v, d->direction, 9) < 0)
            return fail(d, TVPAL_E_FORMAT, "ImageData Direction is %s (nine "
                        "numbers expected)", v, NULL);
        d->have_direction = 1;
    }
    return 0;
}

static int start_array(struct vti_doc *d, const XML_Char **atts)
{
    if (d->narrays == d->cap) {
        int cap = d->cap ? 2 * d->cap : 8;
        struct vti_array *a = realloc(d->arrays, sizeof *a * (size_t)cap);
        if (!a)
            return nomem(d);
        d->arrays = a;
        d->cap = cap;
    }
    struct vti_array *a = &d->arrays[d->narrays];
    memset(a, 0, sizeof *a);
    const char *v = attr(atts, "Name");
    if (!(a->name = strdup(v ? v : "")))
        return nomem(d);
    d->narrays++;
    a->cell = d->in_cell;
    a->field = d->in_field;
    v = attr(atts, "type");
    copy_attr(a->type, sizeof a->type, v ? v : "missing");
    a->t = -1;
    for (int i = 0; v && i < T_COUNT; i++)
        if (!strcmp(v, vti_types[i].name))
            a->t = i;
    a->ncomp = 1;
    if ((v = attr(atts, "NumberOfComponents"))) {
        char *e;
        a->ncomp = strtol(v, &e, 10);
        if (e == v || *e || a->ncomp < 1)
            return fail(d, TVPAL_E_FORMAT, "DataArray %s: NumberOfComponents "
                        "is %s", a->name, v);
    }
    v = attr(atts, "format");
    copy_attr(a->fmt_name, sizeof a->fmt_name, v ? v : "ascii");
    a->fmt = !strcmp(a->fmt_name, "ascii")      ? F_ASCII
             : !strcmp(a->fmt_name, "binary")   ? F_BINARY
             : !strcmp(a->fmt_name, "appended") ? F_APPENDED
                                                : F_UNKNOWN;
    if ((v = attr(atts, "offset"))) {
        char *e;
        errno = 0;
        unsigned long long o = strtoull(v, &e, 10);
        if (e == v || *e || errno || *v == '-')
            return fail(d, TVPAL_E_FORMAT, "DataArray %s: offset is %s",
                        a->name, v);
        a->offset = o;
        a->has_offset = 1;
    }
    d->cur = d->narrays - 1;
    return 0;
}

/* The Scalars and Vectors a PointData or PPointData names (the first). */
static int active_arrays(struct vti_doc *d, const XML_Char **atts)
{
    const char *s = attr(atts, "Scalars"), *v = attr(atts, "Vectors");
    if (d->in_cell)
        return 0;
    if (s && !d->scalars && !(d->scalars = strdup(s)))
        return nomem(d);
    if (v && !d->vectors && !(d->vectors = strdup(v)))
        return nomem(d);
    return 0;
}

/* A PImageData's children: PPointData/PCellData with their PDataArrays
 * (the arrays every piece has), and Piece Extent= Source=. */
static int start_parallel(struct vti_doc *d, int depth, const XML_Char *name,
                          const XML_Char **atts)
{
    if (!d->have_image)
        return 0;
    if (depth == 2 && !strcmp(name, "Piece")) {
        if (d->npcs == d->pcap) {
            int cap = d->pcap ? 2 * d->pcap : 8;
            struct vti_piece *p = realloc(d->pcs, sizeof *p * (size_t)cap);
            if (!p)
                return nomem(d);
            d->pcs = p;
            d->pcap = cap;
        }
        struct vti_piece *p = &d->pcs[d->npcs];
        const char *v = attr(atts, "Extent");
        if (!v || parse_ints(v, p->ext, 6) < 0)
            return fail(d, TVPAL_E_FORMAT, "Piece Extent is %s (six integers "
                        "expected)", v ? v : "missing", NULL);
        if (!(v = attr(atts, "Source")) || !*v)
            return fail(d, TVPAL_E_FORMAT, "Piece %s has no Source file",
                        attr(atts, "Extent"), NULL);
        if (!(p->source = strdup(v)))
            return nomem(d);
        d->npcs++;
        return 0;
    }
    if (depth == 2 && (!strcmp(name, "PPointData") ||
                       !strcmp(name, "PCellData"))) {
        d->in_cell = !strcmp(name, "PCellData");
        d->data_depth = depth;
        return active_arrays(d, atts);
    }
    if (d->data_depth && depth == d->data_depth + 1 &&
        !strcmp(name, "PDataArray"))
        return start_array(d, atts);
    return 0;
}

static int start(struct vti_doc *d, int depth, const XML_Char *name,
                 const XML_Char **atts)
{
    if (depth == 0) {
        if (strcmp(name, "VTKFile"))
            return fail(d, TVPAL_E_FORMAT, "the root element is <%s>, not "
                        "<VTKFile>", name, NULL);
        return start_vtkfile(d, atts);
    }
    if (depth == 1 && !strcmp(name, d->parallel ? "PImageData" : "ImageData"))
        return start_image(d, atts);
    if (d->parallel)
        return start_parallel(d, depth, name, atts);
    if (depth == 1 && !strcmp(name, "AppendedData")) {
        const char *v = attr(atts, "encoding");
        d->have_appended = 1;
        if (!v || !strcmp(v, "raw"))
            return 0;
        if (!strcmp(v, "base64")) {
            d->appended_base64 = 1;
            return 0;
        }
        return fail(d, TVPAL_E_FORMAT, "AppendedData encoding %s (raw or "
                    "base64 expected)", v, NULL);
    }
    if (depth == 2 && d->have_image && !strcmp(name, "Piece")) {
        /* The arrays of the first piece only: a second one is refused. */
        d->skip_piece = d->npieces++ > 0;
        d->piece_depth = depth;
        const char *v = attr(atts, "Extent");
        if (!d->skip_piece && v) {
            if (parse_ints(v, d->extent, 6) < 0)
                return fail(d, TVPAL_E_FORMAT, "Piece Extent is %s (six "
                            "integers expected)", v, NULL);
            d->have_extent = 1;
        }
        return 0;
    }
    if (depth == 2 && d->have_image && !strcmp(name, "FieldData")) {
        /* The dataset's own arrays (ParaView writes the time there as
         * TimeValue), read as DataArrays but never a variable. */
        d->in_cell = 0;
        d->in_field = 1;
        d->data_depth = depth;
        return 0;
    }
    if (d->piece_depth && depth == d->piece_depth + 1 && !d->skip_piece &&
        (!strcmp(name, "PointData") || !strcmp(name, "CellData"))) {
        d->in_field = 0;
        d->in_cell = !strcmp(name, "CellData");
        d->data_depth = depth;
        return active_arrays(d, atts);
    }
    if (d->data_depth && depth == d->data_depth + 1 &&
        !strcmp(name, "DataArray"))
        return start_array(d, atts);
    return 0;
}

/* The run of text of the open DataArray ends at the tag expat is at (a
 * child's, or the DataArray's end): the first run with more than white
 * space in it is the array's data text. */
static void end_run(struct vti_doc *d)
{
    struct vti_array *a = &d->arrays[d->cur];
    if (a->in_run && a->run_data && !a->has_text) {
        a->text_begin = a->run_begin;
        a->text_end = (size_t)XML_GetCurrentByteIndex(d->xp);
        a->has_text = 1;
    }
    a->in_run = 0;
}

static void XMLCALL on_start(void *ud, const XML_Char *name,
                             const XML_Char **atts)
{
    struct vti_doc *d = ud;
    int depth = d->depth++;
    /* An element inside the DataArray (InformationKey) ends a run. */
    if (d->cur >= 0 && depth == d->data_depth + 2)
        end_run(d);
    (void)start(d, depth, name, atts);
}

static void XMLCALL on_end(void *ud, const XML_Char *name)
{
    struct vti_doc *d = ud;
    int depth = --d->depth;
    if (d->cur >= 0 && d->data_depth && depth == d->data_depth + 1) {
        struct vti_array *a = &d->arrays[d->cur];
        end_run(d);
        if (!a->has_text) {   /* none but white space: no values */
            a->text_begin = a->text_end =
                (size_t)XML_GetCurrentByteIndex(d->xp);
            a->has_text = 1;
        }
        d->cur = -1;
    }
    if (depth == d->data_depth)
        d->data_depth = 0;
    if (depth == d->piece_depth)
        d->piece_depth = 0;
}

static void XMLCALL on_text(void *ud, const XML_Char *s, int len)
{
    struct vti_doc *d = ud;
    if (d->cur < 0 || d->depth != d->data_depth + 2)
        return;
    struct vti_array *a = &d->arrays[d->cur];
    if (!a->in_run) {
        a->run_begin = (size_t)XML_GetCurrentByteIndex(d->xp);
        a->in_run = 1;
        a->run_data = 0;
    }
    for (int i = 0; i < len && !a->run_data; i++)
        a->run_data = !(s[i] == ' ' || s[i] == '\t' || s[i] == '\n' ||
                        s[i] == '\r');
}

static const unsigned char *find(const unsigned char *p, size_t n,
                                 const char *s)
{
    size_t k = strlen(s);
    for (size_t i = 0; n >= k && i <= n - k; i++)
        if (p[i] == (unsigned char)s[0] && !memcmp(p + i, s, k))
            return p + i;
    return NULL;
}

/* Feeds buf[0..n) to expat in pieces (so that expat copies no more than a
 * piece of a large inline array); final: this is the last of the text. */
static int feed(struct vti_doc *d, const unsigned char *buf, size_t n,
                int final)
{
    const size_t piece = 1 << 20;
    do {
        size_t k = n < piece ? n : piece;
        int last = final && k == n;
        if (XML_Parse(d->xp, (const char *)buf, (int)k, last) !=
            XML_STATUS_OK) {
            if (d->rc)
                return d->rc;
            if (XML_GetErrorCode(d->xp) == XML_ERROR_NO_MEMORY)
                return TVPAL_E_NOMEM;
            return tvpal_diag_set(
                d->diag, TVPAL_E_FORMAT, "%s: XML error at line %lu: %s",
                d->path, (unsigned long)XML_GetCurrentLineNumber(d->xp),
                XML_ErrorString(XML_GetErrorCode(d->xp)));
        }
        buf += k;
        n -= k;
    } while (n > 0);
    return d->rc;
}

/* Pieces of the XML read and fed to expat at a time. */
#define XML_PIECE ((size_t)1 << 20)
/* The most bytes the <AppendedData ...> tag may take. */
#define TAG_MAX ((size_t)64 << 10)

/* The <AppendedData ...> tag at byte at (buf: TAG_MAX bytes of scratch):
 * fed to expat with the elements it leaves open closed after it, and
 * d->appended_at set to the first byte after the '_' marker that follows
 * it (white space between them skipped). */
static int appended_data(struct vti_doc *d, uint64_t at, unsigned char *buf)
{
    const size_t n = d->size - at < TAG_MAX ? (size_t)(d->size - at) : TAG_MAX;
    int rc = doc_pread(d, buf, n, at, "XML");
    if (rc < 0)
        return rc;
    const unsigned char *gt = memchr(buf, '>', n);
    if (!gt)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: the <AppendedData> "
                              "tag is not closed (truncated file?)", d->path);
    const int empty = gt[-1] == '/';
    static const char close_data[] = "</AppendedData>\n</VTKFile>\n";
    const char *rest = empty ? close_data + 16 : close_data;
    rc = feed(d, buf, (size_t)(gt + 1 - buf), 0);
    if (rc == 0)
        rc = feed(d, (const unsigned char *)rest, strlen(rest), 1);
    if (rc < 0 || empty)
        return rc;
    struct src s;
    src_range(&s, d, at + (uint64_t)(gt + 1 - buf), d->size, 0);
    int c;
    while ((c = src_getc(&s)) == ' ' || c == '\t' || c == '\n' || c == '\r')
        ;
    if (s.err)
        return s.err;
    if (c != '_')
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: AppendedData "
                              "has no '_' marker before its data", d->path);
    d->appended_at = src_pos(&s);
    return 0;
}

/* Opens path and parses its XML into *d (owned by the caller: doc_free,
 * also after an error). */
static int load(struct vti_doc *d, const char *path, struct tvpal_diag *diag)
{
    memset(d, 0, sizeof *d);
    d->fd = -1;
    d->path = path;
    d->diag = diag;
    d->cur = -1;
    d->spacing[0] = d->spacing[1] = d->spacing[2] = 1;
    int rc = open_doc_file(d, path, diag);
    if (rc < 0)
        return rc;
    unsigned char *buf = malloc(XML_PIECE > TAG_MAX ? XML_PIECE : TAG_MAX);
    if (!buf || !(d->xp = XML_ParserCreate(NULL))) {
        free(buf);
        return TVPAL_E_NOMEM;
    }
    XML_SetUserData(d->xp, d);
    XML_SetElementHandler(d->xp, on_start, on_end);
    XML_SetCharacterDataHandler(d->xp, on_text);

    /* As VTK does, the XML ends at <AppendedData ...>: the element is
     * closed for expat, and its data begins after the '_' marker.  The
     * last bytes of a piece, which may begin the tag, wait for the next. */
    static const char tag[] = "<AppendedData";
    const size_t keep = sizeof tag - 2;
    uint64_t pos = 0;   /* bytes fed */
    size_t have = 0;    /* buf[0, have): the bytes from pos on, read */
    for (;;) {
        size_t k = XML_PIECE - have;
        if (k > d->size - pos - have)
            k = (size_t)(d->size - pos - have);
        if (k && (rc = doc_pread(d, buf + have, k, pos + have, "XML")) < 0)
            break;
        have += k;
        const int eof = pos + have == d->size;
        const unsigned char *t = find(buf, have, tag);
        if (t) {
            rc = feed(d, buf, (size_t)(t - buf), 0);
            if (rc == 0)
                rc = appended_data(d, pos + (uint64_t)(t - buf), buf);
            break;
        }
        const size_t n = eof ? have : have - (have < keep ? have : keep);
        if ((rc = feed(d, buf, n, eof)) < 0 || eof)
            break;
        memmove(buf, buf + n, have - n);
        pos += n;
        have -= n;
    }
    free(buf);
    XML_ParserFree(d->xp);
    d->xp = NULL;
    if (rc == 0 && !d->have_whole)
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: no <%s> element "
                            "with a WholeExtent", path,
                            d->parallel ? "PImageData" : "ImageData");
    return rc;
}

/* ------------------------------------------------------ choosing a grid */

static int grid(const struct vti_doc *d, struct tvpal_input_info *info)
{
    for (int i = 0; i < 3; i++) {
        long long lo = d->whole[2 * i], hi = d->whole[2 * i + 1];
        if (hi < lo || hi - lo >= INT32_MAX)
            return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: WholeExtent "
                                  "%lld %lld on axis %c is empty or too "
                                  "large", d->path, lo, hi, "xyz"[i]);
        info->dims[i] = (uint32_t)(hi - lo + 1);
        if (!(d->spacing[i] > 0))
            return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: Spacing %g on "
                                  "axis %c (positive expected)", d->path,
                                  d->spacing[i], "xyz"[i]);
        info->spacing[i] = d->spacing[i];
        /* VTK places point (i, j, k) of the extent at Origin + i * Spacing:
         * the first point of the grid is at extent start. */
        info->origin[i] = d->origin[i] + (double)lo * d->spacing[i];
    }
    size_t n;
    if (tvpal_points(info->dims, sizeof(double), &n) < 0)
        return tvpal_diag_set(d->diag, TVPAL_E_OVERFLOW, "%s: WholeExtent of "
                              "%ux%ux%u points: more than can be addressed",
                              d->path, info->dims[0], info->dims[1],
                              info->dims[2]);
    if (d->have_direction)
        for (int i = 0; i < 9; i++)
            if (d->direction[i] != (i % 4 == 0 ? 1.0 : 0.0))
                return tvpal_diag_set(
                    d->diag, TVPAL_E_FORMAT, "%s: non-identity Direction is "
                    "not supported (%g %g %g %g %g %g %g %g %g)", d->path,
                    d->direction[0], d->direction[1], d->direction[2],
                    d->direction[3], d->direction[4], d->direction[5],
                    d->direction[6], d->direction[7], d->direction[8]);
    if (d->parallel)
        return d->npcs ? 0 : tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: no "
                                           "Piece in PImageData", d->path);
    if (d->npieces == 0)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: no Piece in "
                              "ImageData", d->path);
    if (d->npieces > 1)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: %d pieces: "
                              "several pieces are not supported", d->path,
                              d->npieces);
    if (!d->have_extent || memcmp(d->extent, d->whole, sizeof d->whole))
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: the Piece's Extent "
                              "is not the WholeExtent: several pieces are not "
                              "supported", d->path);
    return 0;
}

/* "a, b, c" of the point arrays into buf. */
/* A PointData array: what a variable is. */
static int is_point(const struct vti_array *a)
{
    return !a->cell && !a->field;
}

static void list_arrays(const struct vti_doc *d, char *buf, size_t cap)
{
    size_t n = 0;
    buf[0] = 0;
    for (int i = 0; i < d->narrays && n < cap; i++)
        if (is_point(&d->arrays[i])) {
            int k = snprintf(buf + n, cap - n, "%s%s", n ? ", " : "",
                             d->arrays[i].name);
            n += k > 0 ? (size_t)k : 0;
        }
    if (!buf[0])
        snprintf(buf, cap, "none");
}

/* The point array that opts (or the file: its active Scalars, else its
 * active Vectors, else its only point array) names, checked for reading:
 * one component, or with magnitude up to TVPAL_INPUT_COMPONENTS_MAX. */
static int choose(const struct vti_doc *d, const char *var, int magnitude,
                  int *out)
{
    char names[160];
    int pick = -1, npoint = 0;
    for (int i = 0; i < d->narrays; i++)
        npoint += is_point(&d->arrays[i]);
    list_arrays(d, names, sizeof names);
    const char *want = var ? var : d->scalars ? d->scalars : d->vectors;
    if (want) {
        for (int i = 0; i < d->narrays && pick < 0; i++)
            if (is_point(&d->arrays[i]) && !strcmp(d->arrays[i].name, want))
                pick = i;
        for (int i = 0; i < d->narrays && pick < 0; i++)
            if (d->arrays[i].cell && !strcmp(d->arrays[i].name, want))
                return tvpal_diag_set(d->diag, TVPAL_E_INVAL, "%s: %s is a "
                                      "cell array; tvpal reads point arrays "
                                      "(point arrays: %s)", d->path, want,
                                      names);
        if (pick < 0)
            return tvpal_diag_set(d->diag, var ? TVPAL_E_INVAL : TVPAL_E_FORMAT,
                                  "%s: no point array %s%s (point arrays: %s)",
                                  d->path, want, var ? ""
                                  : d->scalars ? " (the active Scalars)"
                                  : " (the active Vectors)", names);
    } else if (npoint == 1) {
        for (int i = 0; i < d->narrays; i++)
            if (is_point(&d->arrays[i]))
                pick = i;
    } else if (npoint == 0) {
        return tvpal_diag_set(d->diag, TVPAL_E_INVAL, "%s: no point arrays "
                              "(PointData DataArray) to read", d->path);
    } else {
        return tvpal_diag_set(d->diag, TVPAL_E_INVAL, "%s: %d point arrays "
                              "and no active Scalars: choose one (point "
                              "arrays: %s)", d->path, npoint, names);
    }
    const struct vti_array *a = &d->arrays[pick];
    if (strlen(a->name) >= sizeof ((struct tvpal_input_info *)0)->var)
        return tvpal_diag_set(d->diag, TVPAL_E_INVAL, "%s: array name %.40s... "
                              "is too long", d->path, a->name);
    if (a->ncomp != 1 && !magnitude)
        return tvpal_diag_set(d->diag, TVPAL_E_INVAL, "%s: array %s has %ld "
                              "components (NumberOfComponents); tvpal reads "
                              "one value per point: --magnitude encodes the "
                              "vector's length", d->path, a->name, a->ncomp);
    if (a->ncomp > TVPAL_INPUT_COMPONENTS_MAX)
        return tvpal_diag_set(d->diag, TVPAL_E_INVAL, "%s: array %s has %ld "
                              "components (NumberOfComponents); --magnitude "
                              "reads at most %d", d->path, a->name, a->ncomp,
                              TVPAL_INPUT_COMPONENTS_MAX);
    if (a->t < 0)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: array %s has type "
                              "%s (Float32/64, [U]Int8/16/32/64 are read)",
                              d->path, a->name, a->type);
    if (a->fmt == F_UNKNOWN)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: array %s has "
                              "format %s (ascii, binary or appended expected)",
                              d->path, a->name, a->fmt_name);
    if (a->fmt != F_ASCII && d->compressor[0] && strcmp(d->compressor, ZLIB_NAME))
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: compressor %s is not "
                              "supported yet (only " ZLIB_NAME " or none)",
                              d->path, d->compressor);
    if (a->fmt == F_APPENDED && (!d->have_appended || !d->appended_at))
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: array %s is "
                              "appended and the file has no AppendedData",
                              d->path, a->name);
    if (a->fmt == F_APPENDED && !a->has_offset)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: appended array %s "
                              "has no offset", d->path, a->name);
    *out = pick;
    return 0;
}

/* --------------------------------------------------------- byte sources */

static int b64_value(unsigned char c)
{
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    if (c == '=') return 64;
    if (c == ' ' || c == '\t' || c == '\n' || c == '\r') return -2;
    return -1;
}

/* Up to n bytes into out (NULL: skip them); returns how many there were. */
static size_t src_read(struct src *s, unsigned char *out, size_t n)
{
    if (!s->b64)
        return src_take(s, out, n);
    size_t got = 0;
    while (got < n) {
        if (s->ipend < s->npend) {
            unsigned char c = s->pend[s->ipend++];
            if (out)
                out[got] = c;
            got++;
            continue;
        }
        int v[4], k = 0, ch;
        while (k < 4 && (ch = src_getc(s)) >= 0) {
            int c = b64_value((unsigned char)ch);
            if (c == -2)
                continue;
            if (c == -1) {
                s->bad = 1;
                return got;
            }
            v[k++] = c;
        }
        if (k < 4)
            return got;
        unsigned nb = 3;
        if (v[0] == 64 || v[1] == 64 || (v[2] == 64 && v[3] != 64)) {
            s->bad = 1;
            return got;
        }
        if (v[2] == 64)
            nb = 1, v[2] = v[3] = 0;
        else if (v[3] == 64)
            nb = 2, v[3] = 0;
        uint32_t w = (uint32_t)v[0] << 18 | (uint32_t)v[1] << 12 |
                     (uint32_t)v[2] << 6 | (uint32_t)v[3];
        s->pend[0] = (unsigned char)(w >> 16);
        s->pend[1] = (unsigned char)(w >> 8);
        s->pend[2] = (unsigned char)w;
        s->npend = nb;
        s->ipend = 0;
    }
    return got;
}

/* The most bytes the rest of s can hold (base64: an upper bound). */
static size_t src_left(const struct src *s)
{
    uint64_t k = s->end - s->off + (s->wlen - s->wpos);
    if (s->b64)
        k = k / 4 * 3 + 3 + (s->npend - s->ipend);
    return k > SIZE_MAX ? SIZE_MAX : (size_t)k;
}

static uint64_t load_uint(const unsigned char *p, unsigned size, int be)
{
    uint64_t v = 0;
    for (unsigned i = 0; i < size; i++)
        v |= (uint64_t)p[be ? size - 1 - i : i] << (8 * i);
    return v;
}

/* ------------------------------------------------------------- decoding */

/* Converts n values of type t (byte order be) at src to float; src may be
 * dst itself for 4-byte types (each value is read before it is written). */
static void convert(const unsigned char *src, int t, int be, size_t n,
                    float *dst)
{
    unsigned sz = vti_types[t].size;
    const uint32_t one = 1;
    int host_be = *(const unsigned char *)&one == 0;
    if (t == T_F32 && be == host_be) {   /* already float32 as stored */
        if (src != (const unsigned char *)dst)
            memmove(dst, src, n * 4);
        return;
    }
    for (size_t i = 0; i < n; i++) {
        uint64_t u = load_uint(src + i * sz, sz, be);
        float f;
        double g;
        switch (t) {
        case T_F32: {
            uint32_t u32 = (uint32_t)u;
            memcpy(&f, &u32, 4);
            break;
        }
        case T_F64: memcpy(&g, &u, 8); f = (float)g; break;
        case T_I8: f = (float)(int8_t)(uint8_t)u; break;
        case T_U8: f = (float)(uint8_t)u; break;
        case T_I16: f = (float)(int16_t)(uint16_t)u; break;
        case T_U16: f = (float)(uint16_t)u; break;
        case T_I32: f = (float)(int32_t)(uint32_t)u; break;
        case T_U32: f = (float)(uint32_t)u; break;
        case T_I64: f = (float)(int64_t)u; break;
        default: f = (float)u; break;
        }
        dst[i] = f;
    }
}

/* The value of type t (byte order be) at src as a double: exact, but for
 * 64-bit integers beyond 2^53. */
static double value_f64(const unsigned char *src, int t, int be)
{
    const uint64_t u = load_uint(src, vti_types[t].size, be);
    switch (t) {
    case T_F32: {
        const uint32_t u32 = (uint32_t)u;
        float f;
        memcpy(&f, &u32, 4);
        return f;
    }
    case T_F64: {
        double g;
        memcpy(&g, &u, 8);
        return g;
    }
    case T_I8: return (int8_t)(uint8_t)u;
    case T_U8: return (uint8_t)u;
    case T_I16: return (int16_t)(uint16_t)u;
    case T_U16: return (uint16_t)u;
    case T_I32: return (int32_t)(uint32_t)u;
    case T_U32: return (uint32_t)u;
    case T_I64: return (double)(int64_t)u;
    default: return (double)u;
    }
}

/* n points of ncomp values of type t each at src into dst: convert's
 * values where ncomp is 1, else each point's length (tvpal_input_mag_add);
 * src is not dst then. */
static void convert_points(const unsigned char *src, int t, int be,
                           long ncomp, size_t n, float *dst)
{
    if (ncomp == 1) {
        convert(src, t, be, n, dst);
        return;
    }
    const unsigned sz = vti_types[t].size;
    for (size_t i = 0; i < n; i++) {
        double sum = 0;
        for (long c = 0; c < ncomp; c++, src += sz)
            sum = tvpal_input_mag_add(sum, value_f64(src, t, be));
        dst[i] = tvpal_input_mag_end(sum);
    }
}

/* The values of an ascii array in order: all are parsed (so that a box
 * read finds the errors a whole read does), those of the box [lo, lo + n)
 * of the pdims grid go into dst at x + y * dy + z * dz; of several
 * components per point (a->ncomp), each point's length. */
static int read_ascii(const struct vti_doc *d, const struct vti_array *a,
                      const uint32_t pdims[3], const uint32_t lo[3],
                      const uint32_t n[3], float *dst, size_t dy, size_t dz)
{
    struct src s;
    src_range(&s, d, a->text_begin, a->text_end, 0);
    int c = src_getc(&s);
    const size_t nx = pdims[0], ny = pdims[1], nc = (size_t)a->ncomp;
    const size_t npts = nx * ny * pdims[2], nrows = (size_t)n[1] * n[2];
    const size_t nvals = npts * nc;   /* choose and open bound it */
    size_t i = 0, r = 0, x = 0;
    size_t want = ((size_t)lo[2] * ny + lo[1]) * nx + lo[0];   /* a point */
    double sum = 0;
    for (;; i++) {
        while (c == ' ' || c == '\t' || c == '\n' || c == '\r')
            c = src_getc(&s);
        if (c < 0)
            break;
        char tok[64];
        size_t k = 0;
        while (c >= 0 && !(c == ' ' || c == '\t' || c == '\n' || c == '\r')
               && k < sizeof tok - 1) {
            tok[k++] = (char)c;
            c = src_getc(&s);
        }
        tok[k] = 0;
        if (i >= nvals)
            return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: ascii array %s "
                                  "has more than the %zu values of its extent",
                                  d->path, a->name, nvals);
        char *e;
        float f = 0;
        double v = 0;
        if (nc > 1)   /* a component, whole: float32 as stored */
            v = a->t == T_F32 ? (double)strtof(tok, &e) : strtod(tok, &e);
        else if (a->t == T_F32)
            f = strtof(tok, &e);
        else
            f = (float)strtod(tok, &e);
        if (e == tok || *e)
            return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: ascii array %s: "
                                  "value %zu is \"%.32s\", not a number",
                                  d->path, a->name, i + 1, tok);
        /* value i is component i % nc of point i / nc */
        if (r == nrows || (nc > 1 ? i / nc : i) != want)
            continue;
        if (nc > 1) {
            const size_t comp = i % nc;
            sum = tvpal_input_mag_add(comp ? sum : 0, v);
            if (comp + 1 < nc)
                continue;
            f = tvpal_input_mag_end(sum);
        }
        dst[(r % n[1]) * dy + (r / n[1]) * dz + x] = f;
        want++;
        if (++x < n[0])
            continue;
        x = 0;
        if (++r < nrows)
            want = (((size_t)lo[2] + r / n[1]) * ny + lo[1] + r % n[1]) * nx +
                   lo[0];
    }
    if (s.err)
        return s.err;
    if (i < nvals)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: ascii array %s has "
                              "%zu values; its extent needs %zu", d->path,
                              a->name, i, nvals);
    return 0;
}

static int truncated(const struct vti_doc *d, const struct vti_array *a,
                     const struct src *s, const char *what, uint64_t got,
                     uint64_t want)
{
    if (s->err)
        return s->err;
    if (s->bad)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: array %s: a "
                              "character that is not base64 in its %s",
                              d->path, a->name, what);
    return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: array %s: its %s ends "
                          "after %llu of %llu bytes (%s)", d->path, a->name,
                          what, (unsigned long long)got,
                          (unsigned long long)want,
                          a->fmt == F_BINARY || d->appended_base64
                              ? "truncated base64" : "past the end of the file");
}

/* The binary data of array a (binary or appended): checks its header
 * against nbytes, the size its extent needs, and decodes into out (NULL:
 * checks the header and the bounds only). */

/* A block that does not inflate to its size. */
static int block_error(const struct vti_doc *d, const struct vti_array *a,
                       uint64_t i, uint64_t nb, int z)
{
    if (z == TVPAL_INFLATE_NOMEM)
        return TVPAL_E_NOMEM;
    return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: array %s: zlib block "
                          "%llu of %llu does not inflate (%s)", d->path,
                          a->name, (unsigned long long)i + 1,
                          (unsigned long long)nb,
                          z != TVPAL_INFLATE_OK ? tvpal_inflate_why(z)
                                : "inflates to less than its size");
}

/* Block i: exactly `want` bytes from csize compressed ones; 0 or the
 * tvpal_inflate status (OK when it inflates to fewer bytes). */
static int inflate_block(const unsigned char *c, uint64_t csize,
                         unsigned char *out, uint64_t want, int *z)
{
    size_t got;
    *z = tvpal_inflate(c, (size_t)csize, out, (size_t)want, &got);
    return *z != TVPAL_INFLATE_OK || got != want;
}

/* Raw (not base64) compressed blocks lie one after the other in the file:
 * they are read in batches of about BLOCK_BATCH bytes (one block at
 * least) and each inflates on its own, so the threads of d->pool share a
 * batch (the encoder's other threads wait for the step meanwhile).  The
 * lowest failing block is reported, as a serial loop would. */
#define BLOCK_BATCH ((uint64_t)32 << 20)
struct blocks_job {
    const unsigned char *c;     /* the batch: blocks first .. */
    const uint64_t *csize, *at; /* at[i]: block i's offset in the blocks */
    uint64_t first, nb, bs, last;
    unsigned char *out;
    int64_t bad;                /* the lowest failing block (atomic
                                 * minimum); INT64_MAX: none */
};

static int block_inflate(const struct blocks_job *j, uint64_t i, int *z)
{
    uint64_t want = i + 1 == j->nb && j->last ? j->last : j->bs;
    return inflate_block(j->c + (j->at[i] - j->at[j->first]), j->csize[i],
                         j->out + i * j->bs, want, z);
}

static void block_body(void *arg, size_t i, unsigned tid)
{
    struct blocks_job *j = arg;
    (void)tid;
    int z;
    if (block_inflate(j, j->first + i, &z))
        tvpal_pool_lowest(&j->bad, (int64_t)(j->first + i));
}

static int inflate_raw_blocks(const struct vti_doc *d,
                              const struct vti_array *a, uint64_t foff,
                              const uint64_t *csize, uint64_t nb, uint64_t bs,
                              uint64_t last, unsigned char *out)
{
    uint64_t *at = malloc(sizeof *at * (size_t)(nb + 1));
    if (!at)
        return TVPAL_E_NOMEM;
    at[0] = 0;
    uint64_t most = 0;   /* the largest batch */
    for (uint64_t i = 0; i < nb; i++)
        at[i + 1] = at[i] + csize[i];
    for (uint64_t i = 0, j; i < nb; i = j) {
        for (j = i + 1; j < nb && at[j + 1] - at[i] <= BLOCK_BATCH; j++)
            ;
        most = at[j] - at[i] > most ? at[j] - at[i] : most;
    }
    unsigned char *c = malloc((size_t)most + 1);
    struct blocks_job job = {.c = c, .csize = csize, .at = at, .nb = nb,
                             .bs = bs, .last = last, .out = out,
                             .bad = INT64_MAX};
    int rc = c ? 0 : TVPAL_E_NOMEM;
    for (uint64_t i = 0, j; rc == 0 && i < nb; i = j) {
        for (j = i + 1; j < nb && at[j + 1] - at[i] <= BLOCK_BATCH; j++)
            ;
        rc = doc_pread(d, c, (size_t)(at[j] - at[i]), foff + at[i],
                       "its compressed blocks");
        job.first = i;
        if (rc == 0)
            tvpal_pool_for(d->pool, (size_t)(j - i), block_body, &job);
        if (rc == 0 && job.bad != INT64_MAX) {
            /* the lowest failing block's status: it fails the same way
             * again */
            int z;
            block_inflate(&job, (uint64_t)job.bad, &z);
            rc = block_error(d, a, (uint64_t)job.bad, nb, z);
        }
    }
    free(c);
    free(at);
    return rc;
}

/* Where the binary data of array a (binary or appended) starts. */
static int src_open(const struct vti_doc *d, const struct vti_array *a,
                    struct src *s)
{
    if (a->fmt == F_BINARY)
        return src_range(s, d, a->text_begin, a->text_end, 1);
    uint64_t room = d->size - d->appended_at;
    if (a->offset >= room)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: array %s: "
                              "appended offset %llu points past the end "
                              "of the file (%llu bytes of appended data)",
                              d->path, a->name, (unsigned long long)a->offset,
                              (unsigned long long)room);
    return src_range(s, d, d->appended_at + a->offset, d->size,
                     d->appended_base64);
}

/* The header of uncompressed data ([nbytes]) checked, s then at the
 * values, which must all be there. */
static int plain_header(const struct vti_doc *d, const struct vti_array *a,
                        struct src *s, uint64_t nbytes)
{
    const unsigned hs = d->header64 ? 8 : 4;
    unsigned char h[8];
    size_t got = src_read(s, h, hs);
    if (got < hs)
        return truncated(d, a, s, "header", got, hs);
    uint64_t len = load_uint(h, hs, d->big_endian);
    if (len != nbytes)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: array %s holds "
                              "%llu bytes; its extent needs %llu (%s)",
                              d->path, a->name, (unsigned long long)len,
                              (unsigned long long)nbytes,
                              vti_types[a->t].name);
    if (src_left(s) < nbytes)
        return truncated(d, a, s, "data", src_left(s), nbytes);
    return 0;
}

/* A compression header: nb blocks of bs bytes (the last of last bytes,
 * 0: bs), their compressed sizes (csize, malloc'ed), the largest cmax. */
struct blocks {
    uint64_t nb, bs, last, cmax;
    uint64_t *csize;
};

/* The compression header checked against nbytes and the bytes that
 * remain; s then at the first block.  b->csize is the caller's to free
 * (NULL after an error). */
static int blocks_header(const struct vti_doc *d, const struct vti_array *a,
                         struct src *s, uint64_t nbytes, struct blocks *b)
{
    const unsigned hs = d->header64 ? 8 : 4;
    unsigned char h[3 * 8];
    memset(b, 0, sizeof *b);
    size_t got = src_read(s, h, 3 * hs);
    if (got < 3 * hs)
        return truncated(d, a, s, "compression header", got, 3 * hs);
    const uint64_t nb = load_uint(h, hs, d->big_endian);
    const uint64_t bs = load_uint(h + hs, hs, d->big_endian);
    const uint64_t last = load_uint(h + 2 * hs, hs, d->big_endian);
    uint64_t total = 0;
    if (nb > 0 && bs > 0 && bs < (uint64_t)1 << 40 && last <= bs &&
        nb <= nbytes / bs + 1)
        total = last ? (nb - 1) * bs + last : nb * bs;
    if (total != nbytes || bs > ULONG_MAX)
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: array %s: %llu "
                              "compressed blocks of %llu bytes (last %llu) "
                              "do not make the %llu bytes its extent needs "
                              "(%s)", d->path, a->name, (unsigned long long)nb,
                              (unsigned long long)bs, (unsigned long long)last,
                              (unsigned long long)nbytes, vti_types[a->t].name);
    if (nb > src_left(s) / hs)
        return truncated(d, a, s, "compression header", src_left(s), nb * hs);
    uint64_t *csize = malloc(sizeof *csize * (size_t)nb);
    if (!csize)
        return TVPAL_E_NOMEM;
    int rc = 0;
    uint64_t sum = 0, cmax = 0;
    for (uint64_t i = 0; i < nb && rc == 0; i++) {
        got = src_read(s, h, hs);
        if (got < hs) {
            rc = truncated(d, a, s, "compression header", 3 * hs + i * hs + got,
                           (3 + nb) * hs);
            break;
        }
        csize[i] = load_uint(h, hs, d->big_endian);
        if (csize[i] > ULONG_MAX || csize[i] > src_left(s))
            rc = truncated(d, a, s, "compressed blocks", src_left(s),
                           csize[i]);
        sum += csize[i];
        cmax = csize[i] > cmax ? csize[i] : cmax;
    }
    if (rc == 0 && sum > src_left(s))
        rc = truncated(d, a, s, "compressed blocks", src_left(s), sum);
    if (rc < 0) {
        free(csize);
        return rc;
    }
    *b = (struct blocks){nb, bs, last, cmax, csize};
    return 0;
}

/* The binary data of array a (binary or appended): checks its header
 * against nbytes, the size its extent needs, and decodes into out (NULL:
 * checks the header and the bounds only). */
static int read_binary(const struct vti_doc *d, const struct vti_array *a,
                       uint64_t nbytes, unsigned char *out)
{
    struct src s;
    int rc = src_open(d, a, &s);
    if (rc < 0)
        return rc;
    if (!d->compressor[0]) {
        rc = plain_header(d, a, &s, nbytes);
        if (rc < 0 || !out)
            return rc;
        size_t got = src_read(&s, out, (size_t)nbytes);
        return got < nbytes ? truncated(d, a, &s, "data", got, nbytes) : 0;
    }
    struct blocks b;
    rc = blocks_header(d, a, &s, nbytes, &b);
    if (rc < 0)
        return rc;
    unsigned char *cbuf = NULL;
    if (out && s.b64 && !(cbuf = malloc((size_t)b.cmax + 1)))
        rc = TVPAL_E_NOMEM;
    if (rc == 0 && out && !s.b64)
        rc = inflate_raw_blocks(d, a, src_pos(&s), b.csize, b.nb, b.bs,
                                b.last, out);
    for (uint64_t i = 0; rc == 0 && out && s.b64 && i < b.nb; i++) {
        size_t got = src_read(&s, cbuf, (size_t)b.csize[i]);
        if (got < b.csize[i]) {
            rc = truncated(d, a, &s, "compressed blocks", got, b.csize[i]);
            break;
        }
        uint64_t want = i + 1 == b.nb && b.last ? b.last : b.bs;
        int z;
        if (inflate_block(cbuf, b.csize[i], out + i * b.bs, want, &z))
            rc = block_error(d, a, i, b.nb, z);
    }
    free(cbuf);
    free(b.csize);
    return rc;
}

/* ------------------------------------------------------------ box reads */

/* The box [lo, lo + n) of a grid of dims points of sz bytes (ncomp values
 * of type t each), row by row in the order of the array's bytes: row r (y
 * = r % n1, z = r / n1) of the box, pos bytes of it done; a point cut by
 * the end of a block waits in carry. */
struct box_cur {
    const uint32_t *dims, *lo, *n;
    unsigned sz;
    int t, be;
    long ncomp;
    float *dst;
    size_t dy, dz;
    uint64_t r, nrows, pos;
    unsigned char carry[8 * TVPAL_INPUT_COMPONENTS_MAX];
    unsigned ncarry;
};

/* The array byte the box wants next; UINT64_MAX when it has them all. */
static uint64_t cur_at(const struct box_cur *c)
{
    if (c->r >= c->nrows)
        return UINT64_MAX;
    const uint64_t y = c->r % c->n[1], z = c->r / c->n[1];
    return ((((uint64_t)c->lo[2] + z) * c->dims[1] + c->lo[1] + y) *
                c->dims[0] + c->lo[0]) * c->sz + c->pos;
}

/* Array bytes [at, at + len) in p: those of the box go into place.  The
 * caller feeds every byte from cur_at on. */
static void cur_feed(struct box_cur *c, const unsigned char *p, uint64_t at,
                     uint64_t len)
{
    const uint64_t rowb = (uint64_t)c->n[0] * c->sz;
    uint64_t want;
    while ((want = cur_at(c)) < at + len) {
        uint64_t k = rowb - c->pos < at + len - want ? rowb - c->pos
                                                     : at + len - want;
        const unsigned char *q = p + (want - at);
        float *row = c->dst + (size_t)(c->r % c->n[1]) * c->dy +
                     (size_t)(c->r / c->n[1]) * c->dz;
        size_t v = (size_t)(c->pos / c->sz);
        uint64_t left = k;
        if (c->ncarry) {
            unsigned take = c->sz - c->ncarry < left ? c->sz - c->ncarry
                                                     : (unsigned)left;
            memcpy(c->carry + c->ncarry, q, take);
            c->ncarry += take;
            q += take;
            left -= take;
            if (c->ncarry == c->sz) {
                convert_points(c->carry, c->t, c->be, c->ncomp, 1, row + v++);
                c->ncarry = 0;
            }
        }
        size_t whole = (size_t)(left / c->sz);
        convert_points(q, c->t, c->be, c->ncomp, whole, row + v);
        q += whole * c->sz;
        left -= whole * c->sz;
        if (left) {
            memcpy(c->carry, q, (size_t)left);
            c->ncarry = (unsigned)left;
        }
        c->pos += k;
        if (c->pos == rowb) {
            c->r++;
            c->pos = 0;
        }
    }
}

struct conv_ctx {
    int t, be;
    long ncomp;
};

static void conv_box(const unsigned char *src, size_t count, float *dst,
                     const void *ctx)
{
    const struct conv_ctx *c = ctx;
    convert_points(src, c->t, c->be, c->ncomp, count, dst);
}

static int host_big_endian(void)
{
    const uint32_t one = 1;
    return *(const unsigned char *)&one == 0;
}

static int grow(unsigned char **buf, size_t *cap, size_t len)
{
    if (*cap >= len)
        return 0;
    free(*buf);
    *cap = 0;
    if (!(*buf = malloc(len)))
        return TVPAL_E_NOMEM;
    *cap = len;
    return 0;
}

#define B64_PIECE ((size_t)64 << 10)

/* The box [lo, lo + n) of array a (a grid of pdims) into dst at x + y * dy
 * + z * dz: raw appended values by pread (their rows only), zlib blocks
 * that meet the box only (one block of scratch at a time), base64 decoded
 * in order up to the box's end, 64 KiB at a time, ascii parsed.  A point
 * of several components (its bytes together) is read whole and taken as
 * its length. */
static int decode_box(struct tvpal_input_file *f, const struct vti_doc *d,
                      const struct vti_array *a, const uint32_t pdims[3],
                      const uint32_t lo[3], const uint32_t n[3], float *dst,
                      size_t dy, size_t dz)
{
    if (a->fmt == F_ASCII)
        return read_ascii(d, a, pdims, lo, n, dst, dy, dz);
    const unsigned sz = point_size(a);
    const uint64_t nbytes = (uint64_t)pdims[0] * pdims[1] * pdims[2] * sz;
    char what[160];
    snprintf(what, sizeof what, "array %s", a->name);
    struct src s;
    int rc = src_open(d, a, &s);
    if (rc < 0)
        return rc;
    struct box_cur c = {pdims, lo, n, sz, a->t, d->big_endian, a->ncomp, dst,
                        dy, dz, 0, (uint64_t)n[1] * n[2], 0, {0}, 0};
    const int fd = d->fd;
    if (!d->compressor[0]) {
        rc = plain_header(d, a, &s, nbytes);
        if (rc == 0 && !s.b64) {
            const struct conv_ctx cc = {a->t, d->big_endian, a->ncomp};
            const int direct = a->t == T_F32 && a->ncomp == 1 &&
                               d->big_endian == host_big_endian();
            rc = tvpal_input_box_pread(fd, src_pos(&s), pdims, sz,
                                       lo, n, dst, dy, dz,
                                       direct ? NULL : conv_box, &cc, &f->io,
                                       d->path, what, d->diag);
        }
        uint64_t at = 0, want;
        while (rc == 0 && s.b64 && (want = cur_at(&c)) != UINT64_MAX) {
            size_t got;
            if (want > at && (got = src_read(&s, NULL, (size_t)(want - at))) <
                                 want - at) {
                rc = truncated(d, a, &s, "data", at + got, nbytes);
                break;
            }
            at = want;
            size_t k = nbytes - at < B64_PIECE ? (size_t)(nbytes - at)
                                               : B64_PIECE;
            if ((rc = grow(&f->io.buf, &f->io.cap, k)) < 0)
                break;
            if ((got = src_read(&s, f->io.buf, k)) < k) {
                rc = truncated(d, a, &s, "data", at + got, nbytes);
                break;
            }
            cur_feed(&c, f->io.buf, at, k);
            at += k;
        }
        return rc;
    }
    struct blocks b;
    rc = blocks_header(d, a, &s, nbytes, &b);
    if (rc == 0)
        rc = grow(&f->blk, &f->blk_cap, (size_t)b.bs);
    if (rc == 0)
        rc = grow(&f->cbuf, &f->cbuf_cap, (size_t)b.cmax + 1);
    uint64_t foff = src_pos(&s);   /* raw: block i's offset */
    for (uint64_t i = 0; rc == 0 && i < b.nb; i++) {
        const uint64_t b0 = i * b.bs;
        const uint64_t len = i + 1 == b.nb && b.last ? b.last : b.bs;
        const uint64_t want = cur_at(&c);
        if (want == UINT64_MAX)
            break;
        if (want >= b0 + len) {   /* a block outside the box */
            if (s.b64 && src_read(&s, NULL, (size_t)b.csize[i]) < b.csize[i])
                rc = truncated(d, a, &s, "compressed blocks", 0, b.csize[i]);
            foff += b.csize[i];
            continue;
        }
        if (s.b64) {
            size_t got = src_read(&s, f->cbuf, (size_t)b.csize[i]);
            if (got < b.csize[i])
                rc = truncated(d, a, &s, "compressed blocks", got, b.csize[i]);
        } else {
            rc = tvpal_input_pread(fd, f->cbuf, (size_t)b.csize[i], foff,
                                   d->path, what, d->diag);
        }
        foff += b.csize[i];
        int z;
        if (rc == 0 && inflate_block(f->cbuf, b.csize[i], f->blk, len, &z))
            rc = block_error(d, a, i, b.nb, z);
        if (rc == 0)
            cur_feed(&c, f->blk, b0, len);
    }
    free(b.csize);
    return rc;
}

/* Array a of the doc (a grid of dims) into dst.  One of several
 * components per point is read as a box of the whole grid (decode_box:
 * its scratch, not a step of stored values). */
static int decode(struct tvpal_input_file *f, const struct vti_doc *d,
                  const struct vti_array *a, const uint32_t dims[3],
                  float *dst)
{
    const size_t n = (size_t)dims[0] * dims[1] * dims[2];
    const uint32_t lo[3] = {0, 0, 0};
    if (a->fmt == F_ASCII || a->ncomp > 1)
        return decode_box(f, d, a, dims, lo, dims, dst, dims[0],
                          (size_t)dims[0] * dims[1]);
    unsigned sz = vti_types[a->t].size;
    unsigned char *raw = sz == sizeof *dst ? (unsigned char *)dst
                                           : malloc(n * sz);
    if (!raw)
        return TVPAL_E_NOMEM;
    int rc = read_binary(d, a, (uint64_t)n * sz, raw);
    if (rc == 0)
        convert(raw, a->t, d->big_endian, n, dst);
    if (raw != (unsigned char *)dst)
        free(raw);
    return rc;
}

/* What array a of d holds, for box_scratch (the most over the pieces). */
static void note_layout(struct tvpal_input_file *f, const struct vti_doc *d,
                        const struct vti_array *a, uint64_t nbytes)
{
    struct src s;
    if (a->fmt == F_ASCII || src_open(d, a, &s) < 0)
        return;
    if (!d->compressor[0]) {
        f->has_raw |= !s.b64;
        f->has_b64 |= s.b64;
        return;
    }
    struct blocks b;
    if (blocks_header(d, a, &s, nbytes, &b) < 0)
        return;
    free(b.csize);
    f->blk_max = b.bs > f->blk_max ? b.bs : f->blk_max;
    f->cmax_max = b.cmax + 1 > f->cmax_max ? b.cmax + 1 : f->cmax_max;
    f->nb_max = b.nb > f->nb_max ? b.nb : f->nb_max;
}

/* -------------------------------------------------------- .pvti pieces */

/* rel resolved against the directory of base (rel itself when absolute
 * or base has no directory); malloc'ed, or NULL. */
static char *beside(const char *base, const char *rel)
{
    const char *slash = strrchr(base, '/');
    size_t k = rel[0] == '/' || !slash ? 0 : (size_t)(slash - base) + 1;
    char *p = malloc(k + strlen(rel) + 1);
    if (p) {
        memcpy(p, base, k);
        strcpy(p + k, rel);
    }
    return p;
}

/* Appends " (what path)" to the diag: which .pvti or .pvd an error of one
 * of its files comes from. */
static void diag_note(struct tvpal_diag *diag, const char *what,
                      const char *path)
{
    if (!diag)
        return;
    size_t k = strlen(diag->msg);
    snprintf(diag->msg + k, sizeof diag->msg - k, " (%s %s)", what, path);
}

static long long ext_points(const long long *e)
{
    return (e[1] - e[0] + 1) * (e[3] - e[2] + 1) * (e[5] - e[4] + 1);
}

/* The points per axis of extent e, into dims (returned). */
static const uint32_t *piece_dims(const long long *e, uint32_t *dims)
{
    for (int a = 0; a < 3; a++)
        dims[a] = (uint32_t)(e[2 * a + 1] - e[2 * a] + 1);
    return dims;
}

/* Loads piece p of the .pvti ppath into *d and chooses array var in it:
 * one Piece of extent p->ext holding var as type t with ncomp components
 * (f's). */
static int piece_load(struct vti_doc *d, const struct tvpal_input_file *f,
                      const struct vti_piece *p, int *pick,
                      struct tvpal_diag *diag)
{
    const char *ppath = f->path, *var = f->var;
    const int t = f->t;
    int rc = load(d, p->source, diag);
    if (rc == 0 && d->parallel)
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: a piece that is a "
                            "PImageData itself", p->source);
    if (rc == 0 && d->npieces != 1)
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: %d Pieces (one "
                            "expected in a piece file)", p->source,
                            d->npieces);
    const long long *e = d->extent;
    if (rc == 0 && (!d->have_extent || memcmp(e, p->ext, sizeof d->extent)))
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: Piece Extent %lld %lld "
                            "%lld %lld %lld %lld; the .pvti says %lld %lld "
                            "%lld %lld %lld %lld", p->source, e[0], e[1], e[2],
                            e[3], e[4], e[5], p->ext[0], p->ext[1], p->ext[2],
                            p->ext[3], p->ext[4], p->ext[5]);
    /* any count of components here: it must be the .pvti's */
    if (rc == 0)
        rc = choose(d, var, 1, pick);
    if (rc == 0 && d->arrays[*pick].t != t)
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: array %s is %s; the "
                            ".pvti says %s", p->source, var,
                            d->arrays[*pick].type, vti_types[t].name);
    if (rc == 0 && d->arrays[*pick].ncomp != f->ncomp)
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: array %s has %ld "
                            "components; the .pvti says %ld", p->source, var,
                            d->arrays[*pick].ncomp, f->ncomp);
    if (rc == 0 && d->arrays[*pick].fmt != F_ASCII)
        rc = read_binary(d, &d->arrays[*pick],
                         (uint64_t)ext_points(p->ext) *
                             point_size(&d->arrays[*pick]), NULL);
    if (rc < 0)
        diag_note(diag, "a piece of", ppath);
    return rc;
}

static int cmp_ll(const void *a, const void *b)
{
    const long long x = *(const long long *)a, y = *(const long long *)b;
    return x < y ? -1 : x > y;
}

/* The index of x in the sorted v[0..n), where it is. */
static size_t index_of(const long long *v, size_t n, long long x)
{
    size_t lo = 0;
    while (n > 1) {
        size_t h = n / 2;
        if (v[lo + h] <= x)
            lo += h;
        n -= h;
    }
    return lo;
}

/* The most blocks the coverage check below marks (pieces times blocks):
 * a few thousand pieces on a regular decomposition take a millionth of
 * it. */
#define COVER_WORK ((uint64_t)1 << 32)

/* Whether the pieces of f (inside its whole extent) cover it.  The piece
 * boundaries cut each axis into at most 2 * npcs + 1 runs, and the grid of
 * these blocks, a byte per block, is marked piece by piece: memory and time
 * follow the pieces, not the points a file claims.  The first point in
 * none is named. */
static int pieces_cover(const struct tvpal_input_file *f, const char *path,
                        struct tvpal_diag *diag)
{
    const long long *w = f->whole;
    const size_t np = (size_t)f->npcs, cap = 2 * np + 2;
    long long *b[3] = {NULL, NULL, NULL};
    size_t nb[3] = {0, 0, 0};
    unsigned char *seen = NULL;
    int rc = 0;
    for (int a = 0; a < 3 && rc == 0; a++) {
        if (!(b[a] = malloc(sizeof *b[a] * cap))) {
            rc = TVPAL_E_NOMEM;
            break;
        }
        size_t k = 0;
        b[a][k++] = w[2 * a];
        b[a][k++] = w[2 * a + 1] + 1;
        for (size_t i = 0; i < np; i++) {
            b[a][k++] = f->pcs[i].ext[2 * a];
            b[a][k++] = f->pcs[i].ext[2 * a + 1] + 1;
        }
        qsort(b[a], k, sizeof *b[a], cmp_ll);
        nb[a] = 1;
        for (size_t i = 1; i < k; i++)
            if (b[a][i] != b[a][nb[a] - 1])
                b[a][nb[a]++] = b[a][i];
    }
    const size_t cx = nb[0] - 1, cy = nb[1] - 1, cz = nb[2] - 1;
    uint64_t cells = 0, work = 0;
    if (rc == 0 && (tvpal_mul3(cx, cy, cz, &cells) < 0 ||
                    tvpal_mul(cells, np, &work) < 0 || work > COVER_WORK))
        rc = tvpal_diag_set(diag, TVPAL_E_RANGE, "%s: %zu Pieces cut the "
                            "WholeExtent into %zux%zux%zu blocks: too many "
                            "to check that they cover it", path, np, cx, cy,
                            cz);
    if (rc == 0 && !(seen = calloc((size_t)cells, 1)))
        rc = TVPAL_E_NOMEM;
    for (size_t i = 0; rc == 0 && i < np; i++) {
        const long long *e = f->pcs[i].ext;
        size_t lo[3], hi[3];
        for (int a = 0; a < 3; a++) {
            lo[a] = index_of(b[a], nb[a], e[2 * a]);
            hi[a] = index_of(b[a], nb[a], e[2 * a + 1] + 1);
        }
        for (size_t z = lo[2]; z < hi[2]; z++)
            for (size_t y = lo[1]; y < hi[1]; y++)
                memset(seen + (z * cy + y) * cx + lo[0], 1, hi[0] - lo[0]);
    }
    size_t hole = 0;
    while (rc == 0 && hole < cells && seen[hole])
        hole++;
    if (rc == 0 && hole < cells)
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: the Pieces do not "
                            "cover the WholeExtent: point (%lld,%lld,%lld) "
                            "is in none", path, b[0][hole % cx],
                            b[1][hole / cx % cy], b[2][hole / cx / cy]);
    free(seen);
    for (int a = 0; a < 3; a++)
        free(b[a]);
    return rc;
}

/* The pieces of the .pvti d into f: resolved, inside the whole extent,
 * covering it (pieces_cover), each one readable. */
static int pieces_open(struct tvpal_input_file *f, struct vti_doc *d,
                       struct tvpal_diag *diag)
{
    if (!(f->pcs = calloc((size_t)d->npcs, sizeof *f->pcs)))
        return TVPAL_E_NOMEM;
    f->npcs = d->npcs;
    memcpy(f->whole, d->whole, sizeof f->whole);
    const long long *w = d->whole;
    long long most = 0;
    for (int i = 0; i < d->npcs; i++) {
        const long long *e = d->pcs[i].ext;
        memcpy(f->pcs[i].ext, e, sizeof f->pcs[i].ext);
        if (!(f->pcs[i].source = beside(d->path, d->pcs[i].source)))
            return TVPAL_E_NOMEM;
        for (int a = 0; a < 3; a++)
            if (e[2 * a] > e[2 * a + 1] || e[2 * a] < w[2 * a] ||
                e[2 * a + 1] > w[2 * a + 1])
                return tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: Piece %s: "
                                      "Extent %lld %lld %lld %lld %lld %lld is "
                                      "empty or outside the WholeExtent",
                                      d->path, d->pcs[i].source, e[0], e[1],
                                      e[2], e[3], e[4], e[5]);
        most = ext_points(e) > most ? ext_points(e) : most;
    }
    int rc = pieces_cover(f, d->path, diag);
    if (rc < 0)
        return rc;
    for (int i = 0; i < f->npcs; i++) {
        struct vti_doc pd;
        int pick = -1;
        rc = piece_load(&pd, f, &f->pcs[i], &pick, diag);
        if (rc == 0)
            note_layout(f, &pd, &pd.arrays[pick],
                        (uint64_t)ext_points(f->pcs[i].ext) *
                            point_size(&pd.arrays[pick]));
        doc_free(&pd);
        if (rc < 0)
            return rc;
    }
    if (!(f->scratch = malloc(sizeof *f->scratch * (size_t)most)))
        return TVPAL_E_NOMEM;
    return 0;
}

/* One step of a .pvti: each piece decoded into the scratch and copied into
 * its place; where pieces overlap (VTK's shared faces) the later one wins,
 * the values there being the same. */
static int pieces_read(struct tvpal_input_file *f, float *dst,
                       struct tvpal_diag *diag)
{
    const long long *w = f->whole;
    size_t nx = f->dims[0], ny = f->dims[1];
    for (int i = 0; i < f->npcs; i++) {
        struct vti_doc d;
        int pick = -1;
        const long long *e = f->pcs[i].ext;
        uint32_t pdims[3];
        int rc = piece_load(&d, f, &f->pcs[i], &pick, diag);
        d.pool = f->pool;
        if (rc == 0)
            rc = decode(f, &d, &d.arrays[pick], piece_dims(e, pdims),
                        f->scratch);
        doc_free(&d);
        if (rc < 0)
            return rc;
        size_t px = (size_t)(e[1] - e[0] + 1);
        const float *s = f->scratch;
        for (long long z = e[4]; z <= e[5]; z++)
            for (long long y = e[2]; y <= e[3]; y++, s += px)
                memcpy(dst + ((size_t)(z - w[4]) * ny + (size_t)(y - w[2])) *
                       nx + (size_t)(e[0] - w[0]), s, px * sizeof *s);
    }
    return 0;
}

/* The box [lo, lo + n) of a .pvti: the part of each piece that meets it,
 * one piece at a time, straight into its place (later pieces win where
 * they overlap, as in pieces_read). */
static int pieces_read_box(struct tvpal_input_file *f, const uint32_t lo[3],
                           const uint32_t n[3], float *dst,
                           struct tvpal_diag *diag)
{
    const long long *w = f->whole;
    for (int i = 0; i < f->npcs; i++) {
        const long long *e = f->pcs[i].ext;
        uint32_t pdims[3], plo[3], pn[3], b[3];
        int meets = 1;
        for (int a = 0; a < 3; a++) {
            long long p0 = e[2 * a] - w[2 * a], p1 = e[2 * a + 1] - w[2 * a] + 1;
            long long b0 = p0 > lo[a] ? p0 : lo[a];
            long long b1 = p1 < (long long)lo[a] + n[a] ? p1
                                                        : (long long)lo[a] + n[a];
            if (b0 >= b1) {
                meets = 0;
                break;
            }
            pdims[a] = (uint32_t)(p1 - p0);
            plo[a] = (uint32_t)(b0 - p0);
            pn[a] = (uint32_t)(b1 - b0);
            b[a] = (uint32_t)b0;
        }
        if (!meets)
            continue;
        struct vti_doc d;
        int pick = -1;
        int rc = piece_load(&d, f, &f->pcs[i], &pick, diag);
        d.pool = f->pool;
        float *at = dst + (b[0] - lo[0]) +
                    ((size_t)(b[2] - lo[2]) * n[1] + (b[1] - lo[1])) * n[0];
        if (rc == 0)
            rc = decode_box(f, &d, &d.arrays[pick], pdims, plo, pn, at, n[0],
                            (size_t)n[0] * n[1]);
        if (rc < 0)
            diag_note(diag, "a piece of", f->path);
        doc_free(&d);
        if (rc < 0)
            return rc;
    }
    return 0;
}

/* ------------------------------------------------------------- backend */

static void vti_close(struct tvpal_input_file *f)
{
    if (!f)
        return;
    for (int i = 0; i < f->npcs; i++)
        free(f->pcs[i].source);
    free(f->pcs);
    free(f->scratch);
    free(f->io.buf);
    free(f->blk);
    free(f->cbuf);
    free(f->path);
    free(f);
}

/* The time ParaView writes into a .vti: its FieldData's TimeValue, one
 * value of any type the reader knows, in any format; *t, and 1 where the
 * file has one, 0 where not; < 0 where it cannot be read (diag says). */
static int field_time(const struct vti_doc *d, double *t)
{
    const struct vti_array *a = NULL;
    for (int i = 0; i < d->narrays && !a; i++)
        if (d->arrays[i].field && !strcmp(d->arrays[i].name, "TimeValue"))
            a = &d->arrays[i];
    if (!a)
        return 0;
    if (a->t < 0 || a->ncomp != 1 || a->fmt == F_UNKNOWN ||
        (a->fmt == F_APPENDED && (!d->appended_at || !a->has_offset)))
        return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: FieldData "
                              "TimeValue: one value of a numeric type in "
                              "ascii, binary or appended format expected "
                              "(type %s, %ld components, format %s)",
                              d->path, a->type, a->ncomp, a->fmt_name);
    if (a->fmt == F_ASCII) {
        char text[128];
        const size_t n = a->text_end > a->text_begin
                             ? a->text_end - a->text_begin : 0;
        const size_t k = n < sizeof text - 1 ? n : sizeof text - 1;
        char *end;
        int rc = doc_pread(d, text, k, a->text_begin, "FieldData TimeValue");
        if (rc < 0)
            return rc;
        text[k] = 0;
        errno = 0;
        *t = strtod(text, &end);
        while (end != text && (*end == ' ' || *end == '\n' || *end == '\t' ||
                               *end == '\r'))
            end++;
        if (end == text || *end || errno)
            return tvpal_diag_set(d->diag, TVPAL_E_FORMAT, "%s: FieldData "
                                  "TimeValue is \"%.40s\": one number "
                                  "expected", d->path, text);
        return 1;
    }
    unsigned char raw[8];
    float f;
    const unsigned sz = vti_types[a->t].size;
    int rc = read_binary(d, a, sz, raw);
    if (rc < 0)
        return rc;
    if (a->t == T_F64) { /* whole: float32 would round the time */
        uint64_t u = load_uint(raw, 8, d->big_endian);
        memcpy(t, &u, sizeof *t);
    } else {
        convert(raw, a->t, d->big_endian, 1, &f);
        *t = f;
    }
    return 1;
}

static int vti_open(struct tvpal_input_file **out, const char *path,
                    const struct tvpal_input_opts *opts,
                    struct tvpal_input_info *info, double **times,
                    struct tvpal_diag *diag)
{
    struct vti_doc d;
    int pick = -1;
    int rc = load(&d, path, diag);
    if (rc == 0)
        rc = grid(&d, info);
    if (rc == 0)
        rc = choose(&d, opts->var, opts->magnitude, &pick);
    size_t n = 0;
    if (rc == 0 && tvpal_points(info->dims, point_size(&d.arrays[pick]),
                                &n) < 0)
        rc = tvpal_diag_set(diag, TVPAL_E_OVERFLOW, "%s: array %s: %ux%ux%u "
                            "points of %ld components: more than can be "
                            "addressed", path, d.arrays[pick].name,
                            info->dims[0], info->dims[1], info->dims[2],
                            d.arrays[pick].ncomp);
    if (rc == 0 && !d.parallel && d.arrays[pick].fmt != F_ASCII)
        rc = read_binary(&d, &d.arrays[pick],
                         (uint64_t)n * point_size(&d.arrays[pick]), NULL);
    double tv = 0;
    int has_tv = rc == 0 && !d.parallel ? field_time(&d, &tv) : 0;
    if (has_tv < 0)
        rc = has_tv;
    if (has_tv > 0 && times) {
        if (!(*times = malloc(sizeof **times)))
            rc = TVPAL_E_NOMEM;
        else
            **times = tv, info->has_times = 1;
    }
    struct tvpal_input_file *f = NULL;
    if (rc == 0 && (!(f = calloc(1, sizeof *f)) || !(f->path = strdup(path))))
        rc = TVPAL_E_NOMEM;
    if (rc == 0) {
        const struct vti_array *a = &d.arrays[pick];
        snprintf(info->var, sizeof info->var, "%s", a->name);
        info->type = vti_types[a->t].as;
        info->components = (uint32_t)a->ncomp;
        info->steps = 1;
        memcpy(f->var, info->var, sizeof f->var);
        memcpy(f->dims, info->dims, sizeof f->dims);
        f->t = a->t;
        f->ncomp = a->ncomp;
        f->pool = opts->pool;
        if (d.parallel)
            rc = pieces_open(f, &d, diag);
        else
            note_layout(f, &d, a, (uint64_t)n * point_size(a));
    }
    if (rc == 0) {
        *out = f;
        f = NULL;
    }
    vti_close(f);
    doc_free(&d);
    return rc;
}

/* This file again, checked against what open found (the array's type
 * and components too). */
static int reload(struct tvpal_input_file *f, struct vti_doc *d, int *pick,
                  struct tvpal_diag *diag)
{
    struct tvpal_input_info info = {0};
    int rc = load(d, f->path, diag);
    d->pool = f->pool;
    if (rc == 0)
        rc = grid(d, &info);
    if (rc == 0)
        rc = choose(d, f->var, 1, pick);   /* components compared below */
    if (rc == 0 && (memcmp(info.dims, f->dims, sizeof f->dims) ||
                    d->arrays[*pick].t != f->t ||
                    d->arrays[*pick].ncomp != f->ncomp))
        rc = tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s: changed since it was "
                            "opened (array %s)", f->path, f->var);
    return rc;
}

static int vti_read(struct tvpal_input_file *f, uint32_t k, float *dst,
                    struct tvpal_diag *diag)
{
    if (k != 0)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: step %u of a file "
                              "that holds one", f->path, k);
    if (f->npcs)
        return pieces_read(f, dst, diag);
    struct vti_doc d;
    int pick = -1;
    int rc = reload(f, &d, &pick, diag);
    if (rc == 0)
        rc = decode(f, &d, &d.arrays[pick], f->dims, dst);
    doc_free(&d);
    return rc;
}

static int vti_read_box(struct tvpal_input_file *f, uint32_t k,
                        const uint32_t lo[3], const uint32_t n[3], float *dst,
                        struct tvpal_diag *diag)
{
    if (k != 0)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "%s: step %u of a file "
                              "that holds one", f->path, k);
    if (f->npcs)
        return pieces_read_box(f, lo, n, dst, diag);
    struct vti_doc d;
    int pick = -1;
    int rc = reload(f, &d, &pick, diag);
    if (rc == 0)
        rc = decode_box(f, &d, &d.arrays[pick], f->dims, lo, n, dst, n[0],
                        (size_t)n[0] * n[1]);
    doc_free(&d);
    return rc;
}

static uint64_t vti_box_scratch(const struct tvpal_input_file *f,
                                const uint32_t n[3])
{
    const unsigned sz = vti_types[f->t].size * (unsigned)f->ncomp;
    uint64_t bytes = f->blk_max + f->cmax_max + f->nb_max * sizeof(uint64_t);
    if (f->has_b64)
        bytes += B64_PIECE;
    if (f->has_raw)
        bytes += tvpal_input_box_pread_scratch(
            f->dims, sz, n,
            f->t == T_F32 && f->ncomp == 1 && !host_big_endian());
    return bytes;
}

static int describe_file(const char *path, char **text,
                         struct tvpal_diag *diag);

/* -------------------------------------------------- .pvd collections */

struct pvd_set {
    double t;
    int has_t, order;
    char *part, *file;
};

struct pvd_doc {
    XML_Parser xp;
    const char *path;
    struct tvpal_diag *diag;
    int depth, is_coll, not_coll, in_coll, rc;
    struct pvd_set *sets;
    int n, cap;
};

static int pvd_fail(struct pvd_doc *p, const char *what, const char *a)
{
    if (p->rc == 0)
        p->rc = tvpal_diag_set(p->diag, TVPAL_E_FORMAT, "%s: line %lu: %s%s",
                               p->path,
                               (unsigned long)XML_GetCurrentLineNumber(p->xp),
                               what, a ? a : "");
    XML_StopParser(p->xp, XML_FALSE);
    return p->rc;
}

static void XMLCALL pvd_start(void *ud, const XML_Char *name,
                              const XML_Char **atts)
{
    struct pvd_doc *p = ud;
    int depth = p->depth++;
    if (p->rc || p->not_coll)
        return;
    if (depth == 0) {
        const char *t = attr(atts, "type");
        if (strcmp(name, "VTKFile") || !t || strcmp(t, "Collection")) {
            p->not_coll = 1;   /* not ours: stop reading at the root */
            XML_StopParser(p->xp, XML_FALSE);
        }
        p->is_coll = !p->not_coll;
        return;
    }
    if (depth == 1)
        p->in_coll = !strcmp(name, "Collection");
    if (depth != 2 || !p->in_coll || strcmp(name, "DataSet"))
        return;
    if (p->n == p->cap) {
        int cap = p->cap ? 2 * p->cap : 16;
        struct pvd_set *s = realloc(p->sets, sizeof *s * (size_t)cap);
        if (!s) {
            p->rc = TVPAL_E_NOMEM;
            XML_StopParser(p->xp, XML_FALSE);
            return;
        }
        p->sets = s;
        p->cap = cap;
    }
    struct pvd_set *s = &p->sets[p->n];
    memset(s, 0, sizeof *s);
    const char *f = attr(atts, "file"), *part = attr(atts, "part");
    const char *ts = attr(atts, "timestep");
    if (!f || !*f) {
        pvd_fail(p, "a DataSet without a file attribute", NULL);
        return;
    }
    if (ts) {
        char *e;
        s->t = strtod(ts, &e);
        while (*e == ' ' || *e == '\t' || *e == '\n' || *e == '\r')
            e++;
        if (e == ts || *e || !isfinite(s->t)) {
            pvd_fail(p, "DataSet timestep is not a number: ", ts);
            return;
        }
        s->has_t = 1;
    }
    s->order = p->n;
    if (!(s->file = strdup(f)) || !(s->part = strdup(part ? part : "0"))) {
        free(s->file);
        p->rc = TVPAL_E_NOMEM;
        XML_StopParser(p->xp, XML_FALSE);
        return;
    }
    p->n++;
}

static void XMLCALL pvd_end(void *ud, const XML_Char *name)
{
    struct pvd_doc *p = ud;
    (void)name;
    p->depth--;
}

/* By timestep, then document order (a stable sort, as VTK's reader
 * shows the steps in time order). */
static int pvd_cmp(const void *a, const void *b)
{
    const struct pvd_set *x = a, *y = b;
    if (x->t != y->t)
        return x->t < y->t ? -1 : 1;
    return x->order - y->order;
}

int tvpal_input_vtk_collection(const char *path, char ***files,
                               double **times, int *n,
                               struct tvpal_diag *diag)
{
    *files = NULL;
    *times = NULL;
    *n = 0;
    int fd = tvpal_open_regular(path, NULL);
    FILE *fp = fd >= 0 ? fdopen(fd, "rb") : NULL;
    if (!fp) {   /* not ours to say: the backend reports it */
        if (fd >= 0)
            close(fd);
        return 0;
    }
    struct pvd_doc p = {0};
    p.path = path;
    p.diag = diag;
    int rc = 0;
    if (!(p.xp = XML_ParserCreate(NULL))) {
        fclose(fp);
        return TVPAL_E_NOMEM;
    }
    XML_SetUserData(p.xp, &p);
    XML_SetElementHandler(p.xp, pvd_start, pvd_end);
    /* Small reads: a .vti stops at its root tag, in the first of them. */
    char buf[4096];
    for (;;) {
        size_t k = fread(buf, 1, sizeof buf, fp);
        int last = k < sizeof buf;
        if (XML_Parse(p.xp, buf, (int)k, last) != XML_STATUS_OK) {
            if (!p.is_coll || p.not_coll)
                break;   /* not a collection (or not XML): not ours */
            if (!p.rc && XML_GetErrorCode(p.xp) == XML_ERROR_NO_MEMORY)
                p.rc = TVPAL_E_NOMEM;
            if (!p.rc)
                p.rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: XML error "
                                      "at line %lu: %s", path, (unsigned long)
                                      XML_GetCurrentLineNumber(p.xp),
                                      XML_ErrorString(XML_GetErrorCode(p.xp)));
            break;
        }
        if (last)
            break;
    }
    fclose(fp);
    XML_ParserFree(p.xp);
    p.xp = NULL;
    rc = p.rc;
    if (rc == 0 && p.is_coll && p.n == 0)
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: a collection without "
                            "a DataSet", path);
    int timed = 0;
    for (int i = 0; i < p.n; i++)
        timed += p.sets[i].has_t;
    if (rc == 0 && p.n > 1 && timed < p.n)
        rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: %d of its %d DataSets "
                            "have no timestep", path, p.n - timed, p.n);
    if (rc == 0 && p.n > 1)
        qsort(p.sets, (size_t)p.n, sizeof *p.sets, pvd_cmp);
    for (int i = 1; rc == 0 && i < p.n; i++) {
        const struct pvd_set *a = &p.sets[i - 1], *b = &p.sets[i];
        if (a->t == b->t && strcmp(a->part, b->part))
            rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: timestep %g has "
                                "parts %s and %s: multi-part collections are "
                                "not supported", path, a->t, a->part, b->part);
        else if (a->t == b->t)
            rc = tvpal_diag_set(diag, TVPAL_E_FORMAT, "%s: two DataSets at "
                                "timestep %g (%s and %s)", path, a->t,
                                a->file, b->file);
    }
    char **fl = NULL;
    double *tl = NULL;
    if (rc == 0 && p.n > 0) {
        fl = calloc((size_t)p.n, sizeof *fl);
        tl = timed ? malloc(sizeof *tl * (size_t)p.n) : NULL;
        if (!fl || (timed && !tl))
            rc = TVPAL_E_NOMEM;
    }
    for (int i = 0; rc == 0 && i < p.n; i++) {
        if (!(fl[i] = beside(path, p.sets[i].file))) {
            rc = TVPAL_E_NOMEM;
            break;
        }
        if (tl)
            tl[i] = p.sets[i].t;
        /* As a file given by itself: regular (a FIFO would block the
         * reader for ever), readable. */
        struct tvpal_diag dd;
        int df = tvpal_open_regular(fl[i], &dd);
        if (df < 0)
            rc = tvpal_diag_set(diag, df, "%s: its DataSet %s", path, dd.msg);
        else
            close(df);
    }
    for (int i = 0; i < p.n; i++) {
        free(p.sets[i].file);
        free(p.sets[i].part);
    }
    free(p.sets);
    if (rc < 0 || !fl) {
        for (int i = 0; fl && i < p.n; i++)
            free(fl[i]);
        free(fl);
        free(tl);
        return rc;
    }
    *files = fl;
    *times = tl;
    *n = p.n;
    return 0;
}

/* ------------------------------------------------------------- describe */

/* A .pvd: its DataSets, then what the first one holds, read as an
 * ImageData file (a DataSet that is a collection itself, this one or
 * another, is refused by name, not followed: a .pvd that lists itself
 * recursed until the stack overflowed). */
static int describe_collection(const char *path, char **files, double *times,
                               int n, char **text, struct tvpal_diag *diag)
{
    char *first = NULL;
    int rc = describe_file(files[0], &first, diag);
    size_t cap = 256 + (first ? strlen(first) : 0);
    for (int i = 0; i < n; i++)
        cap += strlen(files[i]) + 48;
    char *t = rc == 0 ? malloc(cap) : NULL;
    if (rc == 0 && !t)
        rc = TVPAL_E_NOMEM;
    if (rc == 0) {
        size_t k = (size_t)snprintf(t, cap, "vti (VTK collection .pvd, %d "
                                    "DataSet%s, %s)\n", n, n == 1 ? "" : "s",
                                    times ? "by timestep" : "no timestep");
        for (int i = 0; i < n; i++)
            k += (size_t)snprintf(t + k, cap - k, "timestep %.17g %s\n",
                                  times ? times[i] : (double)i, files[i]);
        snprintf(t + k, cap - k, "first DataSet: %s", first);
        *text = t;
    } else {
        diag_note(diag, "listed in", path);
    }
    free(first);
    return rc;
}

static int vti_describe(const char *path, char **text, struct tvpal_diag *diag)
{
    *text = NULL;
    char **files = NULL;
    double *times = NULL;
    int nf = 0;
    int rc = tvpal_input_vtk_collection(path, &files, &times, &nf, diag);
    if (rc == 0 && nf > 0) {
        rc = describe_collection(path, files, times, nf, text, diag);
        for (int i = 0; i < nf; i++)
            free(files[i]);
        free(files);
        free(times);
        return rc;
    }
    if (rc < 0)
        return rc;
    return describe_file(path, text, diag);
}

/* What the .vti or .pvti path holds. */
static int describe_file(const char *path, char **text,
                         struct tvpal_diag *diag)
{
    struct vti_doc d;
    int rc = load(&d, path, diag);
    if (rc < 0) {
        doc_free(&d);
        return rc;
    }
    size_t cap = 1024;
    for (int i = 0; i < d.narrays; i++)
        cap += strlen(d.arrays[i].name) + sizeof d.arrays[i].type + 96;
    for (int i = 0; i < d.npcs; i++)
        cap += strlen(d.pcs[i].source) + 160;
    char *t = malloc(cap);
    if (!t) {
        doc_free(&d);
        return TVPAL_E_NOMEM;
    }
    size_t n = 0;
    const long long *w = d.whole;
    n += (size_t)snprintf(t + n, cap - n, "vti (VTK XML %s, %s, header "
                          "%s, %s)\nextent %lld %lld %lld %lld %lld %lld "
                          "(%lldx%lldx%lld) spacing %.9g %.9g %.9g origin %.9g "
                          "%.9g %.9g", d.parallel ? "PImageData" : "ImageData",
                          d.byte_order, d.header_type,
                          d.compressor[0] ? d.compressor : "none", w[0], w[1],
                          w[2], w[3], w[4], w[5], w[1] - w[0] + 1,
                          w[3] - w[2] + 1, w[5] - w[4] + 1, d.spacing[0],
                          d.spacing[1], d.spacing[2], d.origin[0], d.origin[1],
                          d.origin[2]);
    if (d.npieces > 1)
        n += (size_t)snprintf(t + n, cap - n, " pieces %d", d.npieces);
    if (d.have_direction)
        for (int i = 0; i < 9; i++)
            n += (size_t)snprintf(t + n, cap - n, "%s%.9g",
                                  i ? " " : " direction ", d.direction[i]);
    n += (size_t)snprintf(t + n, cap - n, "\n");
    for (int i = 0; i < d.npcs; i++) {
        const long long *e = d.pcs[i].ext;
        n += (size_t)snprintf(t + n, cap - n, "piece %s extent %lld %lld %lld "
                              "%lld %lld %lld\n", d.pcs[i].source, e[0], e[1],
                              e[2], e[3], e[4], e[5]);
    }
    for (int i = 0; i < d.narrays; i++) {
        const struct vti_array *a = &d.arrays[i];
        int active = !a->cell && d.scalars && !strcmp(d.scalars, a->name);
        int vectors = !a->cell && d.vectors && !strcmp(d.vectors, a->name);
        n += (size_t)snprintf(t + n, cap - n, "%s %s components=%ld%s%s%s\n",
                              a->name, a->type, a->ncomp,
                              active ? " [active scalars]" : "",
                              vectors ? " [active vectors]" : "",
                              a->cell ? " [cell data]" : "");
    }
    doc_free(&d);
    *text = t;
    return 0;
}

const struct tvpal_input_backend tvpal_input_vti = {
    .name = "vti", .open = vti_open, .read = vti_read,
    .read_box = vti_read_box, .box_scratch = vti_box_scratch,
    .close = vti_close, .describe = vti_describe};
