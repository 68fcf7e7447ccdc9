/* tvpal_inflate.h: whole-buffer inflate of zlib-format data (RFC 1950),
 * the adapter of zlib and libdeflate (LAYERS.md).
 *
 * With libdeflate (Debian libdeflate-dev) the blocks of .vti files, and the
 * deflate chunks of HDF5 and NetCDF-4 files (read directly by
 * tvpal_in_hdf5.c), inflate two to three times faster than with zlib, to
 * the same bytes; without it zlib does.
 * Thread-safe: each thread keeps one libdeflate decompressor, freed when
 * the thread ends.
 */
#ifndef TVPAL_INFLATE_H
#define TVPAL_INFLATE_H

#include <stddef.h>

enum tvpal_inflate_status {
    TVPAL_INFLATE_OK = 0,
    TVPAL_INFLATE_CORRUPT,   /* not zlib data, a bad checksum, or cut off */
    TVPAL_INFLATE_SPACE,     /* inflates to more than the room given */
    TVPAL_INFLATE_NOMEM
};

/* Inflates src[0 .. slen) into dst[0 .. cap): *got is the size it
 * inflated to.  Returns a tvpal_inflate_status. */
int tvpal_inflate(const void *src, size_t slen, void *dst, size_t cap,
                  size_t *got);

/* Text of a status, for messages. */
const char *tvpal_inflate_why(int status);

/* "libdeflate 1.14" or "zlib 1.2.13": what inflates. */
const char *tvpal_inflate_library(void);

#endif
