/* fuzz_util.h: helpers shared by the libFuzzer harnesses of tests/fuzz/.
 *
 * Each harness defines LLVMFuzzerTestOneInput; it is linked either with
 * libFuzzer (clang -fsanitize=fuzzer, --enable-fuzzers) or with replay.c
 * (any compiler), which feeds it the files of a corpus.  Helpers that touch
 * the file system use one private directory per process, made on first use
 * under $TMPDIR (or /tmp) and removed at exit. */
#ifndef TVPAL_FUZZ_UTIL_H
#define TVPAL_FUZZ_UTIL_H
#include <stddef.h>
#include <stdint.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The process's scratch directory (never NULL: aborts if it cannot be
 * made). */
const char *fuzz_dir(void);

/* Writes data[0..size) to fuzz_dir()/name (replacing it) and returns the
 * path, valid until the next call; aborts on an I/O error, which is the
 * harness's fault, not the input's. */
const char *fuzz_write(const char *name, const void *data, size_t size);

/* Removes fuzz_dir()/name recursively when it exists. */
void fuzz_remove(const char *name);

/* A malloc'ed NUL-terminated copy of data (aborts when out of memory). */
char *fuzz_strdup(const uint8_t *data, size_t size);

/* Re-seals the CRC-32Cs of a shard image the way a forger would
 * (FORMAT.md; tests/files/generate.sh): for each index entry whose record
 * lies in the buffer, the record's payload CRC (record header +24 and the
 * entry's +24) and record header CRC (+60); then the index CRC (header
 * +88, over [index_offset, size)) and the header CRC (+4092).  Offsets that
 * fall outside buf are skipped, so any bytes are accepted. */
void fuzz_seal_shard(uint8_t *buf, size_t size);

/* Re-seals one record at offset r of buf (its payload_bytes at +16 must
 * fit in buf): payload CRC (+24), header CRC (+60).  Returns 1 and the
 * payload CRC in *crc, or 0 (buf untouched) when it does not fit. */
int fuzz_seal_record(uint8_t *buf, size_t size, uint64_t r, uint32_t *crc);

/* Re-seals a 4096-byte shard header's own CRC (+4092) when size >= 4096. */
void fuzz_seal_header(uint8_t *buf, size_t size);

#endif
