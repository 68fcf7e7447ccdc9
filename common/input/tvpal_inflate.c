/* tvpal_inflate.c: zlib-format inflate by libdeflate or zlib (see
 * tvpal_inflate.h); the only file that includes libdeflate.h or zlib.h. */
#include "tvpal_inflate.h"

#include <stdint.h>

#ifdef HAVE_LIBDEFLATE
#include <libdeflate.h>
#include <pthread.h>
#include <stdio.h>
#else
#include <zlib.h>
#endif

#ifdef HAVE_LIBDEFLATE
/* One decompressor per thread (a few KB, allocated on the thread's first
 * call), freed by the key's destructor when the thread ends. */
static pthread_key_t dec_key;
static pthread_once_t dec_once = PTHREAD_ONCE_INIT;

static void dec_free(void *p)
{
    libdeflate_free_decompressor(p);
}

static void dec_key_make(void)
{
    pthread_key_create(&dec_key, dec_free);
}

static struct libdeflate_decompressor *decompressor(void)
{
    pthread_once(&dec_once, dec_key_make);
    struct libdeflate_decompressor *d = pthread_getspecific(dec_key);
    if (!d && (d = libdeflate_alloc_decompressor()))
        pthread_setspecific(dec_key, d);
    return d;
}

int tvpal_inflate(const void *src, size_t slen, void *dst, size_t cap,
                  size_t *got)
{
    struct libdeflate_decompressor *d = decompressor();
    *got = 0;
    if (!d)
        return TVPAL_INFLATE_NOMEM;
    switch (libdeflate_zlib_decompress(d, src, slen, dst, cap, got)) {
    case LIBDEFLATE_SUCCESS: return TVPAL_INFLATE_OK;
    case LIBDEFLATE_INSUFFICIENT_SPACE: return TVPAL_INFLATE_SPACE;
    default: return TVPAL_INFLATE_CORRUPT;
    }
}

const char *tvpal_inflate_library(void)
{
    return "libdeflate " LIBDEFLATE_VERSION_STRING;
}
#else
int tvpal_inflate(const void *src, size_t slen, void *dst, size_t cap,
                  size_t *got)
{
    z_stream z = {0};
    *got = 0;
    if (inflateInit(&z) != Z_OK)
        return TVPAL_INFLATE_NOMEM;
    const unsigned char *in = src;
    unsigned char *out = dst;
    /* z_stream counts in uInt: large buffers go in pieces. */
    size_t in_left = slen, out_left = cap;
    int status;
    for (;;) {
        if (!z.avail_in && in_left) {
            z.next_in = (unsigned char *)in;
            z.avail_in = in_left > UINT32_MAX ? UINT32_MAX : (uInt)in_left;
            in += z.avail_in;
            in_left -= z.avail_in;
        }
        if (!z.avail_out && out_left) {
            z.next_out = out;
            z.avail_out = out_left > UINT32_MAX ? UINT32_MAX : (uInt)out_left;
            out += z.avail_out;
            out_left -= z.avail_out;
        }
        int rc = inflate(&z, Z_NO_FLUSH);
        if (rc == Z_OK)
            continue;
        /* No progress: the room is used up, or the input ends early. */
        status = rc == Z_STREAM_END ? TVPAL_INFLATE_OK
                 : rc == Z_MEM_ERROR ? TVPAL_INFLATE_NOMEM
                 : rc == Z_BUF_ERROR && !z.avail_out && !out_left
                     ? TVPAL_INFLATE_SPACE
                     : TVPAL_INFLATE_CORRUPT;
        break;
    }
    *got = (size_t)z.total_out;
    inflateEnd(&z);
    return status;
}

const char *tvpal_inflate_library(void)
{
    return "zlib " ZLIB_VERSION;
}
#endif

const char *tvpal_inflate_why(int status)
{
    switch (status) {
    case TVPAL_INFLATE_OK: return "ok";
    case TVPAL_INFLATE_CORRUPT: return "corrupt or cut-off data";
    case TVPAL_INFLATE_SPACE: return "inflates to more than its size";
    default: return "out of memory";
    }
}
