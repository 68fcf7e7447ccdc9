/* Harness: a shard file (tvpal_shard_open on a temporary file, then every
 * record: tvpal_shard_read_record, tvpal_record_next_chunk,
 * tvpal_chunk_table, and a slab's seeks).  The input is re-sealed first
 * (fuzz_seal_shard) so that mutations get past the CRC-32Cs. */
#include "fuzz_util.h"
#include "shard_walk.h"

#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    uint8_t *b = malloc(size ? size : 1);
    if (!b)
        abort();
    memcpy(b, data, size);
    fuzz_seal_shard(b, size);
    const char *p = fuzz_write("shard.tvps", b, size);
    free(b);
    struct tvpal_shard *s;
    struct tvpal_diag d;
    if (tvpal_shard_open(&s, p, &d) == 0) {
        walk_shard(s);
        tvpal_shard_close(s);
    }
    return 0;
}
