/* tvpal_crc32c.h: CRC-32C (Castagnoli), the checksum of every tvpal record.
 *
 * Same polynomial as iSCSI/ext4/btrfs (reflected 0x82F63B78); the check value
 * of "123456789" is 0xE3069283.  Incremental: crc = tvpal_crc32c(crc, p, n)
 * starting from crc = 0.
 */
#ifndef TVPAL_CRC32C_H
#define TVPAL_CRC32C_H

#include <stddef.h>
#include <stdint.h>

uint32_t tvpal_crc32c(uint32_t crc, const void *data, size_t len);

/* tvpal_crc32c(crc, src, len), copying src to dst (len bytes, not
 * overlapping) in the same pass: one read of src instead of two where the
 * bytes are both checked and kept (the player's stager). */
uint32_t tvpal_crc32c_copy(uint32_t crc, void *dst, const void *src,
                           size_t len);

/* The CRC of A followed by B from crc1 = CRC(A), crc2 = CRC(B) and B's
 * length: lets chunks written in any order, by any thread, be checksummed
 * where they are made and joined in file order afterwards (O(log len2)). */
uint32_t tvpal_crc32c_combine(uint32_t crc1, uint32_t crc2, uint64_t len2);

/* The portable table-driven version (tvpal_crc32c uses the fastest
 * implementation the CPU has, below); for tests. */
uint32_t tvpal_crc32c_sw(uint32_t crc, const void *data, size_t len);

/* The implementations, slowest first: tables (any CPU), the SSE4.2 CRC
 * instruction, folding with VPCLMULQDQ (AVX-512; inputs of 256 bytes and
 * more, shorter ones by the instruction). */
enum tvpal_crc32c_impl {
    TVPAL_CRC32C_TABLE,
    TVPAL_CRC32C_SSE42,
    TVPAL_CRC32C_VPCLMUL
};

/* The fastest this CPU has: the one tvpal_crc32c uses. */
enum tvpal_crc32c_impl tvpal_crc32c_impl(void);

/* "table", "sse4.2" or "vpclmulqdq". */
const char *tvpal_crc32c_impl_name(enum tvpal_crc32c_impl impl);

/* tvpal_crc32c by impl, or by the fastest this CPU has when it lacks impl:
 * for tests and benchmarks that compare them. */
uint32_t tvpal_crc32c_with(enum tvpal_crc32c_impl impl, uint32_t crc,
                           const void *data, size_t len);

#endif
