/* encode_plan.h: how tvpal-encode fits a job into a memory limit.
 *
 * A slice-window needs only its own slice over N timesteps, so the volume
 * can be encoded in passes over boxes of it: each pass streams every
 * timestep of its box through a ring of N box-sized float volumes and
 * encodes the slices the box holds whole.  When the ring of the whole
 * volume fits the limit, one pass encodes every axis of the job (all three,
 * or the subset of --axes) from one read of each step (the fastest plan).  Otherwise each axis is encoded in passes
 * over slabs of its slices (a z slab is contiguous in an x-fastest file, a
 * y slab is nz runs of rows, an x slab touches every row), each reading
 * its box of every step once: the price of bounded memory is reading the
 * input once per pass.  The plan is made before any work starts, from the
 * sizes alone, and is the same for the same job and limit (a resumed job
 * must find the same passes).
 *
 * Pure functions; 0 or a negative TVPAL_E_* code (tvpal_error.h).
 */
#ifndef TVPAL_ENCODE_PLAN_H
#define TVPAL_ENCODE_PLAN_H

#include <stddef.h>
#include <stdint.h>

#include "tvpal_error.h"

/* A box of the volume: voxels lo[a] .. lo[a] + n[a] - 1 of each axis. */
struct encode_box {
    uint32_t lo[3], n[3];
};

static inline uint64_t encode_box_voxels(const struct encode_box *b)
{
    return (uint64_t)b->n[0] * b->n[1] * b->n[2];
}

struct encode_pass {
    struct encode_box box;
    unsigned axes;           /* bit a: slices s0[a] .. s1[a] - 1 of axis a
                              * are encoded in this pass */
    uint32_t s0[3], s1[3];
    int stats;               /* the box's values go into the statistics:
                              * the stats passes' boxes partition the
                              * process's part of the volume once */
};

/* What the plan is made from. */
struct encode_job {
    uint32_t dims[3];
    uint32_t N, T;
    uint32_t slab_lo[3], slab_n[3]; /* slices of each axis this process
                                     * encodes (all, or an MPI rank's) */
    unsigned axes;           /* the axes encoded: bit a for axis a (1..7);
                              * the others get no pass */
    int split;               /* 1: per-axis passes even when one fits (an
                              * MPI rank reads only its slabs) */
    uint64_t limit;          /* bytes */
    uint64_t fixed;          /* bytes that do not depend on the box:
                              * program, threads' workspaces, scratch */
    uint32_t box_bytes_per_voxel; /* ring and read buffers: 4 N, plus 4
                              * for a self-describing input's read-ahead */
    uint32_t group[3];       /* palette group size of each axis (0 or 1:
                              * none): a pass holds whole groups, cut only
                              * where the slab cuts them (FORMAT.md 5.1),
                              * so that the plan never changes the bytes */
};

struct encode_plan {
    struct encode_pass *pass;    /* npasses, owned: encode_plan_free */
    unsigned npasses;
    unsigned per_axis[3];        /* passes per axis (0: one pass for all,
                                  * or an axis not encoded) */
    uint64_t peak;               /* estimated bytes of the largest pass */
    uint64_t min_limit;          /* the smallest limit this job can have */
    uint64_t box_voxels_max;     /* largest box: the ring's size */
    uint64_t voxels_read;        /* voxels of a raw file read over all
                                  * passes and steps: each plane of a box
                                  * from its first voxel to its last (an
                                  * x slab's rows whole) */
};

/* Makes the plan of job j.  0; TVPAL_E_RANGE when even one slice per pass
 * does not fit the limit (p->min_limit says what would); TVPAL_E_NOMEM. */
int encode_plan_make(const struct encode_job *j, struct encode_plan *p);

void encode_plan_free(struct encode_plan *p);

/* One line for people: "1 pass (all axes from one ring)", "1 pass (axes z
 * from one ring)" or "12 passes (x 4, y 4, z 4)" into buf. */
void encode_plan_describe(const struct encode_plan *p, char *buf,
                          size_t cap);

/* The fingerprint text of a plan (a resumed job must have the same). */
void encode_plan_key(const struct encode_plan *p, char *buf, size_t cap);

/* "12G", "512M", "1.5GiB", "800000000": bytes (K, M, G, T are powers of
 * 1024, with or without "iB"/"B").  0 or TVPAL_E_INVAL. */
int encode_parse_size(const char *s, uint64_t *bytes);

/* The default limit: 3/4 of the smaller of physical memory and the
 * cgroup's memory.max (cgroup v2) or memory.limit_in_bytes (v1), divided
 * among `local_ranks` processes of one node.  *why describes it (static
 * text or buf). */
uint64_t encode_default_limit(unsigned local_ranks, char *why, size_t cap);

#endif
