/* tvpal_dataset.h: an encoded dataset directory as a whole (for the tools
 * that see all nodes' shards: decode, info, report).  A player rank opens
 * only its own node's shards with tvpal_shard.h. */
#ifndef TVPAL_DATASET_H
#define TVPAL_DATASET_H

#include <stdint.h>

#include "tvpal_error.h"
#include "tvpal_manifest.h"
#include "tvpal_shard.h"

struct tvpal_dataset {
    char *dir;
    struct tvpal_manifest m;          /* m.axes_mask: the axes stored */
    uint32_t nshards, first_rank;     /* shards held: ranks first_rank ..
                                         first_rank + nshards - 1 */
    struct tvpal_shard **shards[3];   /* [axis][i], nshards each; NULL for
                                         an axis the dataset does not store
                                         (tvpal_dataset_has_axis) */
    uint64_t axis_bytes[3];           /* bytes of the shards held, per axis
                                         (0 for an axis not stored) */
};

/* 1 when ds stores axis (0 x, 1 y, 2 z), i.e. shards[axis] is open; 0 for
 * an axis the manifest's axes key leaves out, or axis > 2. */
int tvpal_dataset_has_axis(const struct tvpal_dataset *ds, unsigned axis);

/* The first axis ds stores of the order z, y, x (z when it has it, the
 * axis tools decode by default). */
unsigned tvpal_dataset_default_axis(const struct tvpal_dataset *ds);

/* The manifest m's table (f32, u16 or auto) agrees with the table
 * encoding of the shard header h read from path (0, 1 or 4; formats 2, 3
 * and 5 are those with missing values), FORMAT.md 8.3.  0, or
 * TVPAL_E_MISMATCH with a message that starts with path. */
int tvpal_shard_check_table(const char *path,
                            const struct tvpal_shard_header *h,
                            const struct tvpal_manifest *m,
                            struct tvpal_diag *diag);

/* Path of node r's shard of an axis under dir (malloc'ed; caller frees). */
char *tvpal_shard_filename(const char *dir, uint32_t rank, unsigned axis);

/* Whether dir can be a dataset: 0 when it is a directory or absent (the
 * manifest's open then says so), else TVPAL_E_OPEN with "DIR: a file, not
 * a dataset directory" (an input file given where a dataset was
 * expected: tvpal-info --inspect describes those). */
int tvpal_dataset_check_dir(const char *dir, struct tvpal_diag *diag);

/* Opens dir/manifest.txt and every shard of the axes it stores, checking
 * that they agree (FORMAT.md 8.3).  On error, diag starts with the path of
 * the file at fault. */
int tvpal_dataset_open(struct tvpal_dataset **out, const char *dir,
                       struct tvpal_diag *diag);
void tvpal_dataset_close(struct tvpal_dataset *ds);  /* NULL is a no-op */

/* One node's part only: node_dir holds manifest.txt and axis-A.tvps of
 * node `rank` for each stored axis A (what a cluster rank has on its local
 * disk).  The
 * manifest's node count must equal nranks, and each shard's header must
 * say rank `rank` of nranks; diag names the file and the mismatch. */
int tvpal_dataset_open_node(struct tvpal_dataset **out, const char *node_dir,
                            uint32_t rank, uint32_t nranks,
                            struct tvpal_diag *diag);

/* Decoder of whole volumes along one axis: one slab per shard.  ds must
 * outlive the reader.  0; TVPAL_E_INVAL for an axis ds does not store or
 * axis > 2 (diag, optional, says which axes it stores: "axis x: dataset
 * stores axes z only"); TVPAL_E_NOMEM. */
struct tvpal_volreader;
int tvpal_volreader_create(struct tvpal_volreader **out,
                           struct tvpal_dataset *ds, unsigned axis,
                           struct tvpal_diag *diag);
void tvpal_volreader_free(struct tvpal_volreader *r);
/* Decodes timestep t into vol (nx*ny*nz floats, x fastest).  Sequential
 * calls read one record per shard; a jump reads at most N. */
int tvpal_volreader_read(struct tvpal_volreader *r, uint32_t t, float *vol,
                         struct tvpal_diag *diag);
uint64_t tvpal_volreader_bytes_read(const struct tvpal_volreader *r);

#endif
