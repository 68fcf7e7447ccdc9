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

/* The portable table-driven version (tvpal_crc32c uses the CPU's CRC-32C
 * instruction when it has one); for tests. */
uint32_t tvpal_crc32c_sw(uint32_t crc, const void *data, size_t len);

#endif
