/* Harness: the pure decoders of tvpal_format.c on one buffer, no I/O: a
 * 4096-byte shard header (tvpal_shard_header_decode), then one record
 * (tvpal_record_header_decode, tvpal_record_verify and
 * tvpal_record_verify_layout against that header,
 * tvpal_record_next_chunk and tvpal_chunk_table), then 64 bytes decoded as
 * a chunk header and 32 as an index entry.  The header's and the record's
 * CRC-32Cs are re-sealed first, as a forger would.  A record that verifies
 * and holds coded chunks (FORMAT.md 6.11) is inflated in place, from the
 * tail of its buffer, as the readers do (tvpal_record_inflate): what
 * inflates must verify as a plain record, and its tables are decoded
 * (a coded chunk's only once inflated). */
#include "fuzz_util.h"
#include "shard_walk.h"
#include "tvpal_chunkz.h"

#include <string.h>

/* The tail decoders, on the input's first bytes (any bytes accepted). */
static void decode_small(const uint8_t *data, size_t size)
{
    struct tvpal_diag d;
    if (size >= TVPAL_CHUNK_HEADER_BYTES) {
        struct tvpal_chunk_header ch;
        (void)tvpal_chunk_header_decode(data, &ch, &d);
    }
    if (size >= TVPAL_INDEX_ENTRY_BYTES) {
        struct tvpal_index_entry e;
        tvpal_index_entry_decode(data, &e);
    }
}

/* Inflates the verified record rec (bytes) of shard h in place when it has
 * coded chunks: at most 64 MiB inflated, the fuzzer's memory. */
static void inflate_record(const unsigned char *rec, uint64_t bytes,
                           const struct tvpal_shard_header *h,
                           const struct tvpal_record_header *rh)
{
    int coded = 0;
    uint64_t pos = 0;
    struct tvpal_chunk c;
    while (tvpal_record_next_chunk(rec, &pos, h->table_format, &c))
        coded |= (c.h.flags & TVPAL_CHUNK_ZSTD) != 0;
    if (!coded)
        return;
    struct tvpal_index_entry e = {
        .offset = TVPAL_SHARD_HEADER_BYTES, .bytes = bytes, .step = rh->step,
        .chunk_count = rh->chunk_count, .crc = rh->payload_crc, .coded = 1,
        .plain_bytes = tvpal_round_up(TVPAL_RECORD_HEADER_BYTES +
                                          rh->plain_bytes, TVPAL_ALIGN)};
    if (e.plain_bytes > ((uint64_t)64 << 20) || e.plain_bytes < bytes)
        return;
    struct tvpal_chunkz *z = NULL;
    unsigned char *buf = malloc(tvpal_record_buffer_bytes(&e));
    if (!buf || tvpal_chunkz_create(&z, tvpal_shard_max_chunk(h)) < 0)
        abort();
    memcpy(buf + tvpal_record_stored_at(&e), rec, bytes);
    struct tvpal_diag d;
    if (tvpal_record_inflate(z, buf, &e, rh->step, h, &d) == 0) {
        if (tvpal_record_verify(buf, e.plain_bytes, rh->step, h, &d) != 0)
            abort();
        walk_chunks(buf, h); /* the inflated tables, plain now */
    }
    tvpal_chunkz_free(z);
    free(buf);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    decode_small(data, size);
    if (size < TVPAL_SHARD_HEADER_BYTES)
        return 0;
    uint8_t *b = malloc(size);
    if (!b)
        abort();
    memcpy(b, data, size);
    fuzz_seal_header(b, size);
    uint32_t crc;
    (void)fuzz_seal_record(b, size, TVPAL_SHARD_HEADER_BYTES, &crc);
    struct tvpal_shard_header h;
    struct tvpal_record_header rh = {0};
    struct tvpal_diag d;
    const unsigned char *rec = b + TVPAL_SHARD_HEADER_BYTES;
    uint64_t bytes = size - TVPAL_SHARD_HEADER_BYTES;
    if (tvpal_shard_header_decode(b, &h, &d) == 0) {
        if (bytes >= TVPAL_RECORD_HEADER_BYTES)
            (void)tvpal_record_header_decode(rec, &rh, &d);
        int full = tvpal_record_verify(rec, bytes, rh.step, &h, &d);
        /* The layout check alone is what the streaming stager trusts
         * before it walks the chunks, summing the CRC as it goes: it
         * must accept whatever the full check accepts, and its walk must
         * be as safe. */
        int layout = tvpal_record_verify_layout(rec, bytes, rh.step, &h, &d);
        if (full == 0 && layout != 0)
            abort();
        if (layout == 0)
            walk_chunks(rec, &h);
        if (full == 0)
            inflate_record(rec, bytes, &h, &rh);
    }
    free(b);
    return 0;
}
