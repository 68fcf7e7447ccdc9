/* encode_output.c: what tvpal-encode writes (encode_output.h). */
#define _GNU_SOURCE
#include "encode_output.h"
#include "tvpal_clock.h"
#include "tvpal_cli.h"
#include "tvpal_fs.h"
#include "tvpal_output.h"
#include "tvpal_values.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The engine's view of the job (tvpal_engine.h): every node's shards, or
 * under MPI this rank's node's, and how the source came. */
struct tvpal_engine_params run_engine_params(const struct run *r)
{
    const struct opts *o = &r->o;
    return (struct tvpal_engine_params){
        .dims = {o->dims[0], o->dims[1], o->dims[2]}, .steps = r->T,
        .window = o->window, .axes = o->axes, .nodes = o->nodes,
        .node_first = r->mpi ? r->node : 0,
        .node_count = r->mpi ? 1 : o->nodes,
        .table_format = (uint32_t)o->table_format, .refine = o->refine,
        .naive = o->naive, .klt = o->klt, .alloc_mse = o->alloc_mse};
}

struct tvpal_engine_source run_engine_source(const struct run *r)
{
    const struct opts *o = &r->o;
    return (struct tvpal_engine_source){
        .type = o->type, .big_endian = o->big_endian,
        .steps_single = o->steps_single ? r->T : 0,
        .nan_as = o->has_nan_as ? &o->nan_as : NULL,
        .missing = o->missing, .nmissing = o->nmissing};
}

/* Node k's directory while the job runs: OUTDIR.partial/node-k, or with
 * --shard-dir the pattern's directory plus ".partial".  Malloc'ed. */
char *node_partial(const struct run *r, uint32_t k)
{
    char *d = tvpal_node_dir(r->partial, r->o.shard_pat, k), *p = NULL;
    if (!d || !r->o.shard_pat)
        return d;
    int n = asprintf(&p, "%s.partial", d);
    free(d);
    return n < 0 ? NULL : p;
}

/* The file of shard j in its node's directory (malloc'ed). */
char *shard_path(const struct run *r, const struct tvpal_engine_shard *j)
{
    char *nd = node_partial(r, j->rank), *p = NULL;
    int n = nd ? asprintf(&p, "%s/axis-%c.tvps", nd, "xyz"[j->axis]) : -1;
    free(nd);
    return n < 0 ? NULL : p;
}

/* The physical grid: --spacing/--origin, else what a self-describing input
 * says (the size of a falling coordinate's step; an axis not evenly spaced
 * counts 1, origin 0), else the unit grid. */
void grid_of(const struct run *r, double spacing[3], double origin[3])
{
    const struct opts *o = &r->o;
    const struct tvpal_input_info *in = r->in ? tvpal_input_info(r->in) : NULL;
    for (int i = 0; i < 3; i++) {
        int known = in && !in->nonuniform[i] && in->spacing[i] != 0;
        spacing[i] = o->have_spacing ? o->spacing[i]
                     : known ? fabs(in->spacing[i]) : 1.0;
        origin[i] = o->have_origin ? o->origin[i]
                    : in && !in->nonuniform[i] ? in->origin[i] : 0.0;
    }
}

static void build_manifest(const struct run *r, struct tvpal_manifest *m)
{
    const struct opts *o = &r->o;
    const struct tvpal_engine_params p = run_engine_params(r);
    const struct tvpal_engine_source src = run_engine_source(r);
    if (tvpal_engine_manifest(&p, &src, &r->st, r->times, r->time_units,
                              r->units, PROG " " PACKAGE_VERSION, m) < 0)
        die_fail("out of memory");
    m->single_file = o->steps_single != 0;
    m->levels = o->levels;
    grid_of(r, m->spacing, m->origin);
    if (r->in) {
        /* One file of all steps, one file per step, or files of several
         * steps each (series). */
        m->single_file = o->ninputs == 1 && r->T > 1;
        m->series = o->ninputs > 1 && (uint32_t)o->ninputs != r->T;
        snprintf(m->source_format, sizeof m->source_format, "%s",
                 tvpal_input_format_name(o->format));
        /* What was encoded: a vector's length says so (tvpal-report reads
         * "NAME (magnitude)" back as NAME with --magnitude). */
        const struct tvpal_input_info *in = tvpal_input_info(r->in);
        if (asprintf(&m->source_var, "%s%s", in->var,
                     in->components > 1 ? " (magnitude)" : "") < 0) {
            m->source_var = NULL;
            die_fail("out of memory");
        }
    }
    for (int i = 0; i < o->ninputs; i++)
        if (tvpal_manifest_add_source(m, o->inputs[i]) < 0)
            die_fail("out of memory");
}

/* Finishes this process's shards with the source range (9.1). */
void finish_shards(struct run *r)
{
    struct tvpal_diag d = {{0}};
    for (uint32_t q = 0; q < r->nshard; q++) {
        tvpal_shardw_set_range(r->sj[q].w, r->st.vmin, r->st.vmax);
        int rc = tvpal_shardw_finish(r->sj[q].w, &d);
        r->sj[q].w = NULL;
        if (rc < 0) {
            char *path = shard_path(r, &r->sj[q]), where[512];
            snprintf(where, sizeof where, "%s", path ? path : "shard");
            free(path);
            die_fail("%s: cannot finish: %s", where, lib_error(rc, &d));
        }
    }
}

/* The manifest's text (malloc'ed). */
char *manifest_text(const struct run *r)
{
    struct tvpal_manifest m;
    char *text = NULL;
    build_manifest(r, &m);
    if (tvpal_manifest_format(&m, &text) < 0)
        die_fail("out of memory");
    tvpal_manifest_clear(&m);
    return text;
}

void write_manifest(const char *dir, const char *text)
{
    struct tvpal_diag d = {{0}};
    char *path = NULL;
    int rc = asprintf(&path, "%s/manifest.txt", dir) < 0
                 ? TVPAL_E_NOMEM
                 : tvpal_write_file_atomic(path, text, strlen(text), &d);
    if (rc < 0)
        die_fail("%s: cannot write manifest: %s", dir, lib_error(rc, &d));
    free(path);
}

/* Renames OUTDIR.partial to OUTDIR (tvpal_output_place: with --force an
 * existing OUTDIR is replaced, and stays as it was if that fails); says
 * what went wrong in err and returns -1. */
int place_output(const struct run *r, char *err, size_t cap)
{
    struct tvpal_diag d = {{0}};
    if (tvpal_output_place(r->partial, r->o.outdir, &d) < 0) {
        snprintf(err, cap, "%s", d.msg[0] ? d.msg : "out of memory");
        return -1;
    }
    return 0;
}

/* Every value missing leaves nothing to encode or draw; present values
 * coded as missing (more missing-value patterns in a slice-window than the
 * code has indices for) are reported. */
int all_missing(const struct run *r, char *why, size_t cap)
{
    snprintf(why, cap, "%s: every value is missing (NaN%s); expected some "
             "present values", r->o.inputs[0],
             r->o.nmissing ? " or a --missing value" : "");
    return !(r->st.vmin <= r->st.vmax);
}

uint64_t dropped_values(const struct run *r)
{
    return tvpal_engine_dropped(r->eng);
}

void warn_dropped(uint64_t dropped)
{
    if (dropped)
        msg("warning: %llu present value%s coded as missing: slice-windows "
            "with more than 128 patterns of missing timesteps (a smaller "
            "--window avoids it)", (unsigned long long)dropped,
            dropped == 1 ? "" : "s");
}

/* A few voxels far from all the others (a fill value such as 1e35 left in
 * the data) set the value range, so the quantizers and the default transfer
 * function spend it on them and the report's PSNR, relative to that range,
 * looks excellent.  Warns, naming how many, when the range is more than
 * 1000 times the 0.1..99.9 percentile range or a value is beyond +-1e30
 * (from the source histogram's 65536 classes). */
void warn_dominating_values(const struct run *r)
{
    double plo, phi;
    uint64_t huge, far, total = 0;
    tvpal_values_spread(&r->st, &plo, &phi, &huge, &far);
    for (uint32_t b = 0; b < TVPAL_CHECKPOINT_BINS; b++)
        total += r->st.fine[b];
    warn_spread(r->st.vmin, r->st.vmax, plo, phi, huge, far, total);
}

void warn_spread(double vmin, double vmax, double plo, double phi,
                 uint64_t huge, uint64_t far, uint64_t total)
{
    const double span = phi - plo, range = vmax - vmin;
    if (huge)
        msg("warning: %llu value%s beyond +-1e30 (the range is %g .. %g): a "
            "fill value? It sets the quantizers' and the colours' range "
            "(--missing V marks a value as missing)",
            (unsigned long long)huge, huge == 1 ? "" : "s", vmin, vmax);
    else if (range > 1000 * span && far)
        msg("warning: %llu value%s (%.3g%%) lie far outside the bulk of the "
            "data (0.1..99.9 percentiles %.4g .. %.4g, range %g .. %g): they "
            "set the quantizers' and the colours' range; missing values? "
            "(--missing V marks a value as missing)",
            (unsigned long long)far, far == 1 ? "" : "s",
            100.0 * (double)far / (double)total, plo, phi, vmin, vmax);
}

/* Progress: `last` forces the closing line.  Work done counts the
 * slice-windows encoded; reading counts as time, so the rate and ETA are
 * of the whole job. */
void report_progress(struct run *r, int last)
{
    struct progress *p = &r->prog;
    double now = tvpal_now();
    if (p->quiet || (!last && now - p->last < p->interval))
        return;
    p->last = now;
    char line[256];
    const uint64_t done = __atomic_load_n(&p->work, __ATOMIC_RELAXED);
    const double el = now - p->t0;
    const double mine = (double)(done - p->work_at_start);
    /* Source voxel-steps: the work counts each once per axis encoded. */
    const double rate = mine / tvpal_axes_count(r->o.axes) /
                        (el > 0 ? el : 1e-9) / 1e6;
    const double eta = mine > 0 ? el / mine * (double)(p->total - done) : -1;
    /* Steps over all passes ("pass-steps" when there are several). */
    tvpal_progress_format(line, sizeof line, last ? p->units : p->unit,
                          p->units, r->plan.npasses > 1 ? "pass-steps"
                                                        : "steps",
                          rate, "Mvox-steps/s", eta, p->tty ? 30 : 0);
    if (p->tty)
        fprintf(stderr, "\r%s\033[K%s", line, last ? "\n" : "");
    else
        fprintf(stderr, PROG ": %s\n", line);
}

void tick_progress(void *run)
{
    report_progress(run, 0);
}

void release_ring(struct run *r)
{
    tvpal_engine_release_ring(r->eng);
}
