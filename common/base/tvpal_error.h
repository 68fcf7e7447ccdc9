/* tvpal_error.h: the one error convention of libtvpal.
 *
 * Every fallible library function returns int: 0 on success or a negative
 * TVPAL_E_* code.  Library code never prints, never exits and does not
 * report errors through errno (its value after a call is unspecified); the
 * programs turn codes into messages with tvpal_strerror().  Where a
 * code alone cannot say what was wrong (which header field, which record),
 * functions take an optional struct tvpal_diag into which they write a short
 * detail; the caller owns it and may pass NULL.
 *
 * Installed beside tvpal.h: the codes, tvpal_strerror and struct
 * tvpal_diag are part of the public API; tvpal_diag_set and
 * tvpal_diag_copy are the library's own (not exported).
 */
#ifndef TVPAL_ERROR_H
#define TVPAL_ERROR_H

#include <stddef.h>

/* Marks the functions of the public API (tvpal.h), the only symbols
 * libtvpal exports; installed with tvpal.h. */
#ifndef TVPAL_API
#define TVPAL_API __attribute__((visibility("default")))
#endif

/* X(name, value, message) */
#define TVPAL_ERROR_MAP(X)                                                    \
    X(OK,        0,   "success")                                              \
    X(NOMEM,    -1,   "out of memory")                                        \
    X(INVAL,    -2,   "invalid argument")                                     \
    X(OPEN,     -3,   "cannot open file")                                     \
    X(READ,     -4,   "read error")                                           \
    X(WRITE,    -5,   "write error")                                          \
    X(TRUNC,    -6,   "file is truncated")                                    \
    X(MAGIC,    -7,   "not a tvpal file (bad magic number)")                  \
    X(VERSION,  -8,   "unsupported format version")                           \
    X(CHECKSUM, -9,   "checksum mismatch (corrupt data)")                     \
    X(FORMAT,   -10,  "malformed file (field out of range)")                  \
    X(SIZE,     -11,  "file size does not match dims and type")               \
    X(NAN,      -12,  "infinite value in input")                              \
    X(RANGE,    -13,  "value out of supported range")                         \
    X(OVERFLOW, -14,  "size overflows")                                       \
    X(EXIST,    -15,  "output already exists")                                \
    X(MANIFEST, -16,  "malformed manifest")                                   \
    X(MISMATCH, -17,  "files of one dataset disagree")                        \
    X(SYS,      -18,  "system call failed")                                   \
    X(CANCELED, -19,  "stopped by the caller")

enum tvpal_error {
#define TVPAL_X_ENUM(name, value, msg) TVPAL_E_##name = value,
    TVPAL_ERROR_MAP(TVPAL_X_ENUM)
#undef TVPAL_X_ENUM
};

/* Static message for a code; never NULL (unknown codes get a generic text). */
TVPAL_API const char *tvpal_strerror(int code);

/* Optional detail for an error: caller-owned, filled with snprintf.  Room
 * for a message that names three long paths (a file, the collection that
 * listed it, the file before it); a longer one is cut and ends in "...". */
enum { TVPAL_DIAG_MAX = 1024 };
struct tvpal_diag {
    char msg[TVPAL_DIAG_MAX];
};

/* Writes printf-style detail into diag when diag is non-NULL.  Returns code,
 * so that `return tvpal_diag_set(d, TVPAL_E_FORMAT, "...")` reads naturally.
 * Exported since libtvpal 0.3.0: a source's read (tvpal.h) reports with it. */
TVPAL_API int tvpal_diag_set(struct tvpal_diag *diag, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Copies src into dst[cap] (cap >= 4), cut to end in "..." when it does not
 * fit: for a detail kept in a smaller record (a per-frame status). */
void tvpal_diag_copy(char *dst, size_t cap, const char *src);

#endif
