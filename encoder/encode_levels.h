/* encode_levels.h: tvpal-encode --levels L (encode_levels.c): the coarser
 * levels of detail, each through a libtvpal encoder in this process.
 * Above encode_source.h (a level's steps from the source read again) and
 * encode_output.h; program code.
 */
#ifndef TVPAL_ENCODE_LEVELS_H
#define TVPAL_ENCODE_LEVELS_H

#include "encode.h"
#include "tvpal_levels.h"

/* After level 0 is finished in OUTDIR.partial: levels 1..L into
 * OUTDIR.partial/level-k/ (encode_levels.c says how): those made beside
 * level 0 (r->lvs) finished, or made now from the source read again. */
void encode_levels(struct run *r);
/* Removes OUTDIR.partial/level-k (and its partial output) for every k
 * beyond --levels: an earlier run of the job (the same level 0) that
 * asked for more left them. */
void remove_levels_beyond(const struct run *r);
/* The levels' encoders (the levels not yet complete), their steps made
 * from whole source steps given to levels_step (inline_steps: level 0's
 * single pass) or from the source read again (vol0 NULL); levels_close
 * finishes them and frees ls (ending the program on failure); levels_free
 * aborts them (a level's partial output goes) and frees ls. */
struct levels;
struct levels *levels_open(struct run *r, int inline_steps);
void levels_step(struct run *r, struct levels *ls, uint32_t t,
                 const float *vol0);
void levels_close(struct run *r, struct levels *ls);
void levels_free(struct levels *ls);

#endif
