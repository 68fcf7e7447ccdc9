/* tvpal_encoder_impl.h: the encoder of tvpal.h inside libtvpal, shared by
 * its two drivers: pushes from memory (tvpal_encoder.c) and a pulled
 * source read in passes (tvpal_encoder_source.c).  Private to the library:
 * not installed.
 *
 * Library code: error convention of tvpal_error.h; nothing prints.
 */
#ifndef TVPAL_ENCODER_IMPL_H
#define TVPAL_ENCODER_IMPL_H

#include "tvpal.h"

#include "encode_plan.h"
#include "tvpal_checkpoint.h"
#include "tvpal_engine.h"
#include "tvpal_manifest.h"
#include "tvpal_values.h"

#include <stdint.h>

#define MISSING_MAX 16u
#define LIB_NAME "libtvpal " PACKAGE_VERSION

enum state { OPENED, STARTED, FAILED };

/* The rounds in which the ranks of a collective agree, in order (a round's
 * number travels in its votes, a check that every rank is in the same):
 * START: nobody has refused (a wrong slab), then rank 0 prepares the
 * output; SETUP: every rank has its engine, and the step its checkpoint
 * resumes from (tvpal_encoder_resume: each rank from its own, the caller
 * from the earliest of them); WRITERS: every rank has its shard writers,
 * resumed or new; STATS: every
 * rank has pushed every step, the statistics summed and the manifest sent
 * from rank 0; LEVEL0 (a pulled encode): every rank has finished its
 * shards of level 0, then rank 0 writes its manifest (and with levels the
 * marker that keeps it); PLACE: every rank has finished its shards, then
 * rank 0
 * writes the manifest, verifies and renames.  A round that decides a
 * failure is the last: every rank knows it and none joins another. */
enum round { R_START = 1, R_SETUP, R_WRITERS, R_STATS, R_LEVEL0, R_PLACE,
             R_DONE };

/* What a rank sends rank 0 in a round, and the verdict rank 0 sends back;
 * the statistics ride along (summed by rank 0; used in R_STATS). */
struct vote {
    int32_t round, code;
    uint64_t done;           /* SETUP: the steps its checkpoint has done */
    uint32_t levels;         /* START: its TVPAL_PARAM_LEVELS, which every
                              * rank must share */
    int32_t kept;            /* SETUP: level 0 is an earlier encode's,
                              * kept (every rank must agree) */
    double vmin, vmax;
    uint64_t nonfinite, missing, counted;
    char msg[TVPAL_DIAG_MAX];
};
struct verdict {
    int32_t code;
    uint64_t done;           /* SETUP: the earliest step a rank resumes
                              * from: the caller's first push */
    uint32_t text_len;       /* R_STATS: the manifest's bytes that follow */
    uint32_t groups[3];      /* START: the palette groups rank 0 measured
                              * (TVPAL_GROUP_AUTO) */
    double vmin, vmax;
    uint64_t nonfinite, missing, counted;
    char msg[TVPAL_DIAG_MAX];
};
/* The fine histogram goes to rank 0 in pieces of this many bins, so that
 * rank 0 holds size * HIST_PIECE counters at a time, not size whole
 * histograms. */
#define HIST_PIECE 2048u

struct tvpal_encoder {
    char *dir, *partial, *lock_path;
    int lock_fd;
    struct tvpal_engine_params ep;
    unsigned threads;
    uint64_t mem_limit;
    int force, has_nan_as;
    double nan_as;
    double spacing[3], origin[3];
    double *times;
    char time_units[128], units[64];
    double missing[MISSING_MAX];
    unsigned nmissing;
    enum state state;
    enum tvpal_type type;            /* of the first push */
    uint32_t pushed, encoded;        /* steps in, steps' windows coded */
    uint32_t next_in;                /* the caller's next step: below
                                      * pushed after a resume where another
                                      * rank resumed from an earlier step
                                      * (those pushes are passed over) */
    struct tvpal_engine *eng;
    struct tvpal_pool *pool;
    struct encode_pass pass;         /* the whole volume, every axis */
    struct tvpal_checkpoint_stats st;
    uint64_t **fine;                 /* per thread */
    struct tvpal_found *found;       /* per thread */
    void **rows;                     /* per thread: a row of 8-byte values
                                      * (strided pushes) */
    /* The ranks: a caller's collective, or this process alone. */
    struct tvpal_collective coll;
    uint32_t slab_z0, slab_n;        /* the planes this rank pushes */
    enum round round;                /* the next round to join */
    int decided;                     /* a round decided a failure */
    int own_rc;                      /* this rank's failure (a wrong slab,
                                      * a failed push), which it tells the
                                      * others in the next round */
    char own_msg[TVPAL_DIAG_MAX];
    int made_partial;                /* rank 0 created DIR.partial */
    struct vote *votes;              /* rank 0: size of them */
    /* Checkpoints (tvpal_checkpoint.h) in this rank's directory: after
     * every ckpt_every steps encoded; a resumed job converts steps below
     * recount_to again without counting them (they are in st). */
    uint32_t ckpt_every;
    double tick_seconds;             /* TVPAL_PARAM_PROGRESS */
    int index_level;                 /* TVPAL_PARAM_INDEX_LEVEL, 0: unset
                                      * (ep.index_level: 0 with
                                      * TVPAL_CODING_NONE) */
    int resuming;
    uint64_t done_local;             /* SETUP: what this rank's checkpoint
                                      * has done */
    uint32_t recount_to;
    char *ckdir, *fp;
    struct tvpal_checkpoint_progress ckp;
    /* Levels of detail 1 .. levels: each a libtvpal encoder of its own
     * into DIR.partial/level-k, fed the block means of the step before it
     * (lvol[k], ldims[k]); lnext[k]: the first step it takes (a resumed
     * level may be ahead of level 0: its checkpoint is saved first). */
    uint32_t levels;
    struct tvpal_encoder *lv[TVPAL_LEVELS_MAX + 1];
    float *lvol[TVPAL_LEVELS_MAX + 1];
    uint32_t ldims[TVPAL_LEVELS_MAX + 1][3];
    uint32_t lnext[TVPAL_LEVELS_MAX + 1];
    uint64_t *pieces;                /* rank 0: size * HIST_PIECE */
    /* Levels of a collective ("levels of a collective" below): this
     * rank's part of each step's level 1 (xbuf, xbytes), rank 0's of
     * every rank (xall); xsent: the steps sent so far.  xbytes is 0 in
     * one process. */
    unsigned char *xbuf, *xall;
    size_t xbytes;
    uint32_t xsent;
    int xfailed;                     /* rank 0: a rank's step was not
                                      * taken (its failure is the job's,
                                      * not the levels' it starved) */
    /* A pulled encode (tvpal_encoder_encode; NULL for pushes): the
     * caller's source and the state of its passes
     * (tvpal_encoder_source.c). */
    const struct tvpal_source *src;  /* the caller's: only during
                                      * tvpal_encoder_encode (NULL after) */
    struct pull *pull;
    int src_big_endian;              /* the source's byte order, for the
                                      * manifest written at finish */
    int keep_partial;                /* release leaves DIR.partial (a
                                      * pulled encode that may continue) */
    int keep_identity;               /* a pulled encode with an identity:
                                      * a failure that may pass keeps
                                      * DIR.partial */
    int decided_code;                /* the failure a round decided */
    /* A pulled encode with levels finishes level 0 before it makes or
     * finishes the levels (tvpal_enc_finish_level0): the manifest's text,
     * kept for the PLACE round of finish. */
    int level0_finished;
    char *text;
    char *shard_pat;                 /* tvpal_encoder_set_shard_dir's, or
                                      * NULL: DIR.partial/node-R */
    int had_partial;                 /* rank 0: DIR.partial was there when
                                      * the encode began */
    /* tvpal_encoder_set_provenance's, owned; encoder "" and no format
     * when not set. */
    char prov_encoder[128], prov_format[16];
    char *prov_var;
    char **prov_sources;
    uint32_t prov_nsources;
    int prov_single_file, prov_series;
};

/* The first push's setup, or a pulled encode's (e->src set): every rank's
 * engine, threads and workspaces, its shard writers (resumed from its
 * checkpoint where there is one of this job) and rank 0's levels, after
 * rounds in which every rank agrees.  0 or the first failure, every
 * rank's. */
int tvpal_enc_start(struct tvpal_encoder *e, enum tvpal_type type,
                    struct tvpal_diag *diag);

/* Step t of level 1, made already in e->lvol[1], to every level's encoder
 * (each next level the block means of the one before). */
int tvpal_enc_push_levels(struct tvpal_encoder *e, uint32_t t,
                          struct tvpal_diag *diag);

/* Opens level k's encoder (level 0's parameters and grid) into
 * e->lv[k]; resumed from its checkpoint when resume (*next: the first step
 * it takes; at least `at_least`, else TVPAL_E_MISMATCH). */
int tvpal_enc_open_level(struct tvpal_encoder *e, uint32_t k, int resume,
                         uint64_t at_least, struct tvpal_diag *diag);

/* The checkpoint of what is encoded (unit: e->encoded, or a pulled
 * encode's units) in this rank's directory. */
int tvpal_enc_save_checkpoint(struct tvpal_encoder *e, uint64_t unit,
                              struct tvpal_diag *diag);

/* Level 0 finished, on every rank, before the levels: the statistics
 * summed (STATS round), every value missing refused, this rank's shards
 * and node manifests finished and its checkpoint removed, and rank 0's
 * DIR.partial/manifest.txt written; the text is kept in e->text for
 * tvpal_encoder_finish, which then only places the dataset.  0, or the
 * first failure (every rank's when the round decided it). */
int tvpal_enc_finish_level0(struct tvpal_encoder *e, struct tvpal_diag *diag);

/* Level k's encoder finished (DIR.partial/level-k complete) and released;
 * 0 where there is none.  diag says "level k: ...". */
int tvpal_enc_finish_level(struct tvpal_encoder *e, uint32_t k,
                           struct tvpal_diag *diag);

/* This rank's node k's directory while the job runs (malloc'ed; NULL out
 * of memory): DIR.partial/node-k, or the shard directory's. */
char *tvpal_enc_node_dir(const struct tvpal_encoder *e, uint32_t k);

/* Whether a pulled encode that failed with code may be continued by the
 * next (stopped, a read, a write, the system, memory): DIR.partial is
 * kept for it. */
int tvpal_enc_failure_may_pass(int code);

/* The library's type of a public scalar type. */
enum tvpal_type tvpal_enc_scalar_type(enum tvpal_scalar s);

/* A pulled encode (tvpal_encoder_source.c), in tvpal_enc_start's setup:
 * source_plan makes the plan for nthreads threads (*ring_voxels: its
 * largest box, the ring's), source_ready (after the engine has started)
 * the reading workspaces, the fingerprint and, with a source identity,
 * the checkpoint's unit in e->done_local; source_levels_inline says
 * whether the levels are made beside level 0 (opened at the start).
 * source_free releases it all (NULL-safe). */
int tvpal_enc_source_plan(struct tvpal_encoder *e, unsigned nthreads,
                          uint64_t *ring_voxels, struct tvpal_diag *diag);
int tvpal_enc_source_ready(struct tvpal_encoder *e, struct tvpal_diag *diag);
int tvpal_enc_source_levels_inline(const struct tvpal_encoder *e);
/* With TVPAL_GROUP_AUTO, " groups=GX,GY,GZ" (the sizes measured) after
 * the options line at opts (cap bytes): a checkpoint's fingerprint names
 * them, so that a resume never mixes two choices. */
void tvpal_enc_groups_said(const struct tvpal_engine_params *p, char *opts,
                           size_t cap);
/* TVPAL_GROUP_AUTO (rank 0, before setup): each axis' palette group size
 * measured on the source (tvpal_groupauto.h) into G (1 for an axis not
 * stored).  0, or the source's code or TVPAL_E_NOMEM with diag set. */
int tvpal_enc_source_groups(struct tvpal_encoder *e, uint32_t G[3],
                            struct tvpal_diag *diag);
/* The partial output of this rank (its writers, DIR.partial or its node
 * directory, the statistics) forgotten: the encode starts at unit 0, and
 * its first progress call says it started over. */
int tvpal_enc_source_start_over(struct tvpal_encoder *e,
                                struct tvpal_diag *diag);
void tvpal_enc_source_free(struct tvpal_encoder *e);

#endif
