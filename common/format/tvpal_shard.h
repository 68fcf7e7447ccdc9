/* tvpal_shard.h: reading and writing shard files (format: common/format/FORMAT.md).
 *
 * Writer: records are appended in step order, the index and the final header
 * are written by tvpal_shardw_finish; until then the header is zeros, so an
 * unfinished file is never mistaken for a valid one.  A writer can resume a
 * partial file: its first `steps_done` records are re-verified, the index is
 * rebuilt from them, and anything after them is cut off.
 *
 * Reader: tvpal_shard_open validates the header, the file size (truncation)
 * and the index; tvpal_shard_read_record reads one record with pread and
 * verifies it (CRC-32C, step, chunk layout).
 */
#ifndef TVPAL_SHARD_H
#define TVPAL_SHARD_H

#include <stdint.h>

#include "tvpal_error.h"
#include "tvpal_format.h"

/* ---- writer ---- */
struct tvpal_shardw;

/* Creates (truncates) path for a shard described by h (index fields are
 * filled in by finish).  *out owned by the caller: finish or free it. */
int tvpal_shardw_create(struct tvpal_shardw **out, const char *path,
                        const struct tvpal_shard_header *h);

/* Reopens a partial shard written by the same encoding and keeps its first
 * steps_done records (verified); diag names the first bad one. */
int tvpal_shardw_resume(struct tvpal_shardw **out, const char *path,
                        const struct tvpal_shard_header *h,
                        uint32_t steps_done, struct tvpal_diag *diag);

/* Records the source value range in the header written by finish. */
void tvpal_shardw_set_range(struct tvpal_shardw *w, double lo, double hi);

/* Size the file has after the records appended so far. */
uint64_t tvpal_shardw_size(const struct tvpal_shardw *w);

/* Appends the sealed record for the next step (buf of `bytes`, a multiple of
 * TVPAL_ALIGN, from tvpal_record_seal).  0, TVPAL_E_INVAL (all steps already
 * written, or bytes not aligned) or TVPAL_E_WRITE; diag (optional) gets the
 * cause, e.g. "write at byte 8192: No space left on device". */
int tvpal_shardw_append(struct tvpal_shardw *w, const unsigned char *buf,
                        uint64_t bytes, struct tvpal_diag *diag);

/* Writes index and header (a placed writer: also every record header,
 * after checking that every record's payload was added in full, else
 * TVPAL_E_INVAL naming the record; a per-chunk shard is packed first,
 * reading every chunk back, TVPAL_E_CHECKSUM when a record's bytes are no
 * longer what was written), fsyncs and closes; frees w whatever the
 * result.
 * When a chunk appended (or kept by resume) has TVPAL_CHUNK_MISSING, the
 * header's table_format gets TVPAL_TABLE_MISSING (FORMAT.md 6.7).
 * 0, TVPAL_E_INVAL (not every step appended), TVPAL_E_NOMEM or
 * TVPAL_E_WRITE, with the cause in diag (optional). */
int tvpal_shardw_finish(struct tvpal_shardw *w, struct tvpal_diag *diag);

/* ---- placed writing ----
 * A shard's layout follows from its header alone (FORMAT.md 6.3: which
 * slices start at each step, every chunk's size), so a chunk can be
 * written straight to its final place, in any order and by any thread: the
 * encoder writes each slice-window as soon as it is coded, in passes over
 * parts of a slab, and never holds a whole record.  Each record's payload
 * CRC is joined from its chunks' CRCs in slice order (tvpal_shardw_extend);
 * the record headers, the index and the header are written by
 * tvpal_shardw_finish, so until then the file is invalid (zero headers).
 * A writer is placed or appending, never both. */

/* Creates (truncates) path sized to all its records, for placed writing. */
int tvpal_shardw_create_placed(struct tvpal_shardw **out, const char *path,
                               const struct tvpal_shard_header *h,
                               struct tvpal_diag *diag);

/* Reopens a placed shard of the same header for a resumed job: the file
 * must have exactly the size create_placed gave it (else TVPAL_E_TRUNC or
 * TVPAL_E_MISMATCH).  Every record's progress starts at nothing: the
 * caller restores it (tvpal_shardw_set_progress) from its checkpoint. */
int tvpal_shardw_reopen_placed(struct tvpal_shardw **out, const char *path,
                               const struct tvpal_shard_header *h,
                               struct tvpal_diag *diag);

/* Writes the chunk of slice s in record t (bytes = tvpal_chunk_bytes of
 * its window with the shard's table_format; a chunk of k slices of a
 * palette group, FORMAT.md 6.5, takes the k rooms of its slices, zeros
 * after it, and finish packs the shard) at its place and sets *crc to
 * the chunk's CRC-32C.  In a per-chunk shard (table_format 4) that is the
 * room of a float32 chunk: a 16-bit chunk (TVPAL_CHUNK_U16) comes first,
 * followed by zeros, and finish packs it (FORMAT.md 9.1).  Safe to call
 * from several threads at once for different chunks.  0, TVPAL_E_INVAL (s
 * has no window starting at t, or not in the slab; a size other than its
 * chunk's; chunk flags the shard's format does not take) or TVPAL_E_WRITE
 * with the cause in diag. */
int tvpal_shardw_put_chunk(struct tvpal_shardw *w, uint32_t t, uint32_t s,
                           const unsigned char *chunk, uint64_t bytes,
                           uint32_t *crc, struct tvpal_diag *diag);

/* Coded chunks (FORMAT.md 6.11): with on, put_chunk also takes a coded
 * chunk (TVPAL_CHUNK_ZSTD, tvpal_chunkz_code) in its room, followed by
 * zeros, and finish packs the shard; the shard is format_version 2 when
 * one was put.  Set it before the first put, and again on a writer
 * reopened to resume a job that set it.  Off at creation. */
void tvpal_shardw_set_coding(struct tvpal_shardw *w, int on);

/* Adds the chunk of slice s, holding `slices` slices (1 without palette
 * groups), written with CRC crc, to record t's payload CRC.  Chunks must
 * be added in ascending slice order: TVPAL_E_INVAL for any other than the
 * next one of the record.  Not thread-safe. */
int tvpal_shardw_extend(struct tvpal_shardw *w, uint32_t t, uint32_t s,
                        uint32_t slices, uint32_t crc);

/* A record's progress (bytes of payload added, their CRC) and whether a
 * chunk had missing entries: what a checkpoint keeps to resume.
 * set_progress reads the `filled` bytes back and checks their CRC: 0,
 * TVPAL_E_INVAL (more than the record's payload), TVPAL_E_READ,
 * TVPAL_E_TRUNC, TVPAL_E_NOMEM or TVPAL_E_CHECKSUM (the bytes are not the
 * ones the checkpoint saw written), named in diag. */
void tvpal_shardw_progress(const struct tvpal_shardw *w, uint32_t t,
                           uint64_t *filled, uint32_t *crc);
int tvpal_shardw_set_progress(struct tvpal_shardw *w, uint32_t t,
                              uint64_t filled, uint32_t crc,
                              struct tvpal_diag *diag);
int tvpal_shardw_missing(const struct tvpal_shardw *w);
void tvpal_shardw_set_missing(struct tvpal_shardw *w, int missing);

/* Closes without finishing (the file stays invalid); NULL is a no-op. */
void tvpal_shardw_free(struct tvpal_shardw *w);

/* Completes a record whose chunks occupy buf[64 .. 64 + payload_bytes):
 * writes the record header (with the payload CRC), zero-pads to the next
 * TVPAL_ALIGN boundary and returns the record's total bytes.  buf must have
 * room for tvpal_round_up(64 + payload_bytes, TVPAL_ALIGN). */
uint64_t tvpal_record_seal(unsigned char *buf, uint32_t step, uint32_t axis,
                           uint32_t chunk_count, uint64_t payload_bytes);

/* ---- reader ---- */
struct tvpal_shard;

int tvpal_shard_open(struct tvpal_shard **out, const char *path,
                     struct tvpal_diag *diag);
void tvpal_shard_close(struct tvpal_shard *s);   /* NULL is a no-op */

const struct tvpal_shard_header *tvpal_shard_hdr(const struct tvpal_shard *s);
const struct tvpal_index_entry *tvpal_shard_entry(const struct tvpal_shard *s,
                                                  uint32_t step);
const char *tvpal_shard_path(const struct tvpal_shard *s);
int tvpal_shard_fd(const struct tvpal_shard *s);
/* Largest record of the shard once inflated (FORMAT.md 6.11; buffer size
 * for read_record). */
uint64_t tvpal_shard_max_record(const struct tvpal_shard *s);
/* 1 when some record has coded chunks (its index entry says so; FORMAT.md
 * 6.9, 6.11): a shard of format_version 2, or 3 with coded chunks. */
int tvpal_shard_coded(const struct tvpal_shard *s);
/* Bytes every record of the shard takes in RAM, inflated (the sum of
 * tvpal_record_buffer_bytes: an in-core reader's memory); the records'
 * region of the file (index_offset - 4096) when nothing is coded. */
uint64_t tvpal_shard_ram_bytes(const struct tvpal_shard *s);

/* Reads and verifies record `step` into buf (capacity cap, at least the
 * entry's plain_bytes), inflated (tvpal_record_inflate) when it has coded
 * chunks: buf then holds the plain record.  One thread at a time per
 * shard (the inflater is the shard's). */
int tvpal_shard_read_record(struct tvpal_shard *s, uint32_t step,
                            unsigned char *buf, uint64_t cap,
                            struct tvpal_diag *diag);

/* The shard's chunks by the format of their decoder table, [0] float32
 * and [1] 16-bit (FORMAT.md 6.7), and the bytes of those tables. */
struct tvpal_table_count {
    uint64_t chunks[2];
    uint64_t bytes[2];        /* the tables' bytes, plain */
    /* Of them, the coded chunks (FORMAT.md 6.11) and what they take in
     * the file (headers, frames, padding). */
    uint64_t coded_chunks;
    uint64_t coded_bytes;
    uint64_t coded_plain;     /* the same chunks' bytes inflated */
};

/* Counts what tables the chunks of s have.  For table_format 0..3 of
 * format_version 1 from the header alone; for a per-chunk shard (4, 5) or
 * one with coded chunks from every chunk header (a
 * 64-byte read each, walked from the start of each record; the records'
 * CRCs are not checked, tvpal_shard_read_record does that); the walk is
 * done once per open shard, later calls give its result.  0,
 * TVPAL_E_READ, or TVPAL_E_FORMAT naming the record and slice whose chunk
 * header is not where the layout puts it. */
int tvpal_shard_count_tables(struct tvpal_shard *s,
                             struct tvpal_table_count *out,
                             struct tvpal_diag *diag);

/* ---- decoding state of one slab ---- */
/* Holds, for every slice of a shard, the window (decoder table + indices)
 * holding the current timestep.  Moving to timestep t loads only the records
 * of the windows that change: one record during forward or backward playback,
 * at most N after a jump. */
struct tvpal_slab;

/* sh is borrowed and must outlive the slab. */
int tvpal_slab_create(struct tvpal_slab **out, struct tvpal_shard *sh);
void tvpal_slab_free(struct tvpal_slab *slab);   /* NULL is a no-op */

/* Steps of the records needed to hold timestep t (ascending, at most N),
 * given what is loaded now; writes them to steps and returns the count. */
unsigned tvpal_slab_needed(const struct tvpal_slab *slab, uint32_t t,
                           uint32_t steps[TVPAL_SCHEDULE_RECORDS_MAX]);

/* Installs, from a verified record (read by any I/O backend), the chunks of
 * the slices whose window holding timestep t starts at that record's step.
 * Other chunks are skipped: record 0, say, also holds the short first
 * windows of slices that need a later record at t. */
void tvpal_slab_apply(struct tvpal_slab *slab, const unsigned char *rec,
                      uint32_t t);

/* Staging: the same as apply, but into spare buffers, leaving what the
 * slab shows untouched until tvpal_slab_install swaps the staged windows in
 * (pointer swaps, no copy).  So a window can be prepared while the current
 * one is drawn, on another thread, as long as only one thread calls into
 * the slab at a time and nothing reads the slab during install.  Spare
 * buffers come from a pool that install refills with the windows it
 * replaces, so in steady playback the slab holds about 1/N more than its
 * windows.  tvpal_slab_needed still answers for what is installed.
 * stage: 0 or TVPAL_E_NOMEM (the chunks staged so far stay staged). */
int tvpal_slab_stage(struct tvpal_slab *slab, const unsigned char *rec,
                     uint32_t t);

/* tvpal_slab_stage for a record whose layout is verified
 * (tvpal_record_verify_layout) but not yet its payload CRC: the CRC is
 * summed chunk by chunk, each chunk just before it is staged, so the
 * record is read from memory once instead of twice.  0; TVPAL_E_CHECKSUM
 * when the CRC does not match, and then nothing of rec stays staged (its
 * slices show what they showed before); TVPAL_E_NOMEM (as
 * tvpal_slab_stage). */
int tvpal_slab_stage_verify(struct tvpal_slab *slab, const unsigned char *rec,
                            uint32_t t);
void tvpal_slab_install(struct tvpal_slab *slab);
/* Drops what is staged (the buffers go back to the pool). */
void tvpal_slab_unstage(struct tvpal_slab *slab);

/* Borrowing (off at creation): with on, tvpal_slab_apply and the staging
 * calls no longer copy a record's indices into the slab but point the
 * slices at them, inside rec: no copy, and for stage_verify a read of
 * the indices instead of a read and a write.  The caller then keeps
 * every such record unchanged and allocated while a slice shows or has
 * staged a window from it (tvpal_slab_borrows), or copies those windows
 * in first (tvpal_slab_detach).  The window of a slice starts at the step
 * of the record that holds it, so "record step" names it.  Switching off
 * detaches nothing. */
void tvpal_slab_borrow(struct tvpal_slab *slab, int on);
/* Whether a slice shows or has staged indices borrowed from the record of
 * `step` (UINT32_MAX: from any record). */
int tvpal_slab_borrows(const struct tvpal_slab *slab, uint32_t step);
/* Copies the indices borrowed from the record of `step` (UINT32_MAX: all)
 * into the slab's own buffers: the record may then change.  What the
 * slab shows stays the same, generations included. */
void tvpal_slab_detach(struct tvpal_slab *slab, uint32_t step);
/* Copies in the borrowed windows shown that do not hold t: those of
 * slices whose record for t failed, which keep an older window. */
void tvpal_slab_detach_stale(struct tvpal_slab *slab, uint32_t t);

/* needed + read (pread) + apply. */
int tvpal_slab_seek(struct tvpal_slab *slab, uint32_t t,
                    struct tvpal_diag *diag);

/* After a seek to t: the indices of local slice k (w*h bytes) and the 256
 * decoded values of its palette at time t.  When the slice's window does not
 * hold t (a record failed to load), the row nearest t of the window it
 * holds is returned: the last good data stays on screen.  NULL when the
 * slice never got a window. */
const uint8_t *tvpal_slab_indices(const struct tvpal_slab *slab, uint32_t k);
const float *tvpal_slab_row(const struct tvpal_slab *slab, uint32_t k,
                            uint32_t t);

/* Incremented each time slice k gets a new window (its indices change):
 * renderers upload a slice's texture only when this moves. */
uint32_t tvpal_slab_generation(const struct tvpal_slab *slab, uint32_t k);

/* The shard a slab decodes. */
struct tvpal_shard *tvpal_slab_shard(const struct tvpal_slab *slab);

/* Writes the slab's decoded voxels at time t (after a seek to t) into vol, a
 * full nx*ny*nz volume, x fastest. */
void tvpal_slab_scatter(const struct tvpal_slab *slab, uint32_t t,
                        float *vol);

/* Bytes and records read by tvpal_slab_seek so far. */
uint64_t tvpal_slab_bytes_read(const struct tvpal_slab *slab);

#endif
