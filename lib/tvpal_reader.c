/* tvpal_reader.c: the reader of tvpal.h over tvpal_dataset.h.
 *
 * The manifest is loaded at open, and level 0's shards opened and checked
 * (tvpal_reader_open) or left until a call needs them
 * (tvpal_reader_open_manifest); a coarser level (DIR/level-k, FORMAT.md
 * 3.3) and an axis's decoder when first asked for, then kept, so that
 * sequential steps read one record per shard.  tvpal_reader_verify opens
 * nothing it keeps: it walks the files the manifests name, one at a time,
 * so that one damaged file does not hide the others. */
#define _GNU_SOURCE
#include "tvpal.h"

#include "tvpal_dataset.h"
#include "tvpal_format.h"
#include "tvpal_fs.h"
#include "tvpal_manifest.h"
#include "tvpal_schedule.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Levels a reader keeps open: TVPAL_LEVELS_MAX of the manifest, and 0. */
#define LEVELS_CAP 16u

struct level {
    struct tvpal_dataset *ds;
    struct tvpal_volreader *vr[3];
};

struct tvpal_reader {
    char *dir;
    struct tvpal_manifest m;    /* DIR/manifest.txt, as info says */
    char *text;                 /* its text */
    struct level lv[LEVELS_CAP + 1];
    struct tvpal_info info;
};

/* The manifest's provenance and source into info (strings borrowed from
 * r->m; NULL ones become ""). */
static void fill_source_info(struct tvpal_reader *r)
{
    const struct tvpal_manifest *m = &r->m;
    struct tvpal_info *in = &r->info;
    in->encoder = m->encoder ? m->encoder : "";
    in->options = m->options ? m->options : "";
    in->manifest = r->text;
    in->source_format = m->source_format[0] ? m->source_format
                        : m->nsources ? "raw" : "";
    in->source_var = m->source_var ? m->source_var : "";
    in->source_type = tvpal_type_name(m->type);
    in->source_value_bytes = (uint32_t)tvpal_type_size(m->type);
    in->source_big_endian = m->big_endian;
    in->source_single_file = m->single_file;
    in->sources = (const char *const *)m->sources;
    in->nsources = (uint32_t)m->nsources;
}

static void fill_info(struct tvpal_reader *r)
{
    const struct tvpal_manifest *m = &r->m;
    struct tvpal_info *in = &r->info;
    memcpy(in->dims, m->dims, sizeof in->dims);
    in->steps = m->steps;
    in->window = m->window;
    in->schedule = m->schedule;
    for (unsigned a = 0; a < 3; a++)
        in->group[a] = r->lv[0].ds && tvpal_dataset_has_axis(r->lv[0].ds, a)
                           ? tvpal_shard_hdr(r->lv[0].ds->shards[a][0])->group
                           : 0;
    in->nodes = m->nodes;
    in->axes = m->axes_mask;
    in->levels = m->levels;
    memcpy(in->spacing, m->spacing, sizeof in->spacing);
    memcpy(in->origin, m->origin, sizeof in->origin);
    in->value_min = m->value_min;
    in->value_max = m->value_max;
    in->times = m->ntimes ? m->times : NULL;
    in->time_units = m->time_units;
    in->units = m->units;
    in->missing = m->missing;
    in->source_bytes = m->source_bytes;
    in->table = m->table_format;
    in->has_nan_as = m->has_nan_as;
    in->nan_as = m->nan_as;
    in->nonfinite = m->nonfinite;
    in->missing_values = m->nmissing_values ? m->missing_values : NULL;
    in->nmissing_values = m->nmissing_values;
    in->histogram = m->histogram;
    in->histogram_bins = TVPAL_HIST_BINS;
    fill_source_info(r);
}

/* Loads dir's manifest and its text into r.  diag names the file. */
static int load_manifest(struct tvpal_reader *r, struct tvpal_diag *diag)
{
    char *path = NULL;
    int rc = tvpal_dataset_check_dir(r->dir, diag);
    if (rc < 0)
        return rc;
    if (asprintf(&path, "%s/manifest.txt", r->dir) < 0)
        return TVPAL_E_NOMEM;
    rc = tvpal_manifest_load(path, &r->m, diag);
    if (rc < 0 && diag && strncmp(diag->msg, path, strlen(path))) {
        char cause[sizeof diag->msg];
        snprintf(cause, sizeof cause, "%s", diag->msg);
        tvpal_diag_set(diag, rc, "%s: %s%s%s", path, tvpal_strerror(rc),
                       cause[0] ? ": " : "", cause);
    }
    if (rc == 0 && r->m.levels > LEVELS_CAP)
        rc = tvpal_diag_set(diag, TVPAL_E_MANIFEST, "%s: %u levels, at most "
                            "%u expected", path, r->m.levels, LEVELS_CAP);
    /* Loaded and checked a moment ago: the text is what it says. */
    if (rc == 0)
        rc = tvpal_read_file(path, &r->text, NULL, diag);
    free(path);
    return rc;
}

/* Level 0's shards, opened when first needed (at open unless the reader
 * was opened on the manifest alone). */
static int open_level0(struct tvpal_reader *r, struct tvpal_diag *diag)
{
    if (r->lv[0].ds)
        return 0;
    return tvpal_dataset_open(&r->lv[0].ds, r->dir, diag);
}

/* Both opens: the manifest, then level 0's shards when `shards`. */
static int reader_open(struct tvpal_reader **out, const char *dir,
                       int shards, struct tvpal_diag *diag)
{
    *out = NULL;
    if (!dir)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "no dataset directory");
    struct tvpal_reader *r = calloc(1, sizeof *r);
    if (!r || !(r->dir = strdup(dir))) {
        free(r);
        return TVPAL_E_NOMEM;
    }
    int rc = load_manifest(r, diag);
    if (rc == 0 && shards)
        rc = open_level0(r, diag);
    if (rc < 0) {
        tvpal_reader_close(r);
        return rc;
    }
    fill_info(r);
    *out = r;
    return 0;
}

int tvpal_reader_open(struct tvpal_reader **out, const char *dir,
                      struct tvpal_diag *diag)
{
    return reader_open(out, dir, 1, diag);
}

int tvpal_reader_open_manifest(struct tvpal_reader **out, const char *dir,
                               struct tvpal_diag *diag)
{
    return reader_open(out, dir, 0, diag);
}

void tvpal_reader_close(struct tvpal_reader *r)
{
    if (!r)
        return;
    for (unsigned k = 0; k <= LEVELS_CAP; k++) {
        for (unsigned a = 0; a < 3; a++)
            tvpal_volreader_free(r->lv[k].vr[a]);
        tvpal_dataset_close(r->lv[k].ds);
    }
    tvpal_manifest_clear(&r->m);
    free(r->text);
    free(r->dir);
    free(r);
}

const struct tvpal_info *tvpal_reader_info(const struct tvpal_reader *r)
{
    return &r->info;
}

int tvpal_reader_level_dims(const struct tvpal_reader *r, uint32_t level,
                            uint32_t dims[3])
{
    if (level > r->info.levels)
        return TVPAL_E_INVAL;
    for (int a = 0; a < 3; a++) {
        uint32_t d = r->info.dims[a];
        for (uint32_t i = 0; i < level; i++)
            d = (d + 1) / 2;
        dims[a] = d;
    }
    return 0;
}

/* Level k's dataset, opened when first needed; it must be the level the
 * manifest of level 0 says (its dims and steps). */
static int open_level(struct tvpal_reader *r, uint32_t k,
                      struct tvpal_diag *diag)
{
    if (k == 0)
        return open_level0(r, diag);
    if (r->lv[k].ds)
        return 0;
    char *ld = NULL;
    if (asprintf(&ld, "%s/level-%u", r->dir, k) < 0)
        return TVPAL_E_NOMEM;
    int rc = tvpal_dataset_open(&r->lv[k].ds, ld, diag);
    uint32_t want[3];
    tvpal_reader_level_dims(r, k, want);
    if (rc == 0 && (memcmp(r->lv[k].ds->m.dims, want, sizeof want) ||
                    r->lv[k].ds->m.steps != r->info.steps))
        rc = tvpal_diag_set(diag, TVPAL_E_MISMATCH, "%s: not level %u of "
                            "%s (its dims or steps differ)", ld, k, r->dir);
    if (rc < 0) {
        tvpal_dataset_close(r->lv[k].ds);
        r->lv[k].ds = NULL;
    }
    free(ld);
    return rc;
}

int tvpal_reader_decode(struct tvpal_reader *r, uint32_t t, unsigned axis,
                        uint32_t level, float *dst, struct tvpal_diag *diag)
{
    if (t >= r->info.steps)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "step %u: the dataset "
                              "has %u", t, r->info.steps);
    if (level > r->info.levels)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "level %u: the dataset "
                              "has levels 0..%u", level, r->info.levels);
    if (axis != 0 && axis != TVPAL_AXIS_X && axis != TVPAL_AXIS_Y &&
        axis != TVPAL_AXIS_Z)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "axis %u: TVPAL_AXIS_X, "
                              "_Y, _Z or 0 expected", axis);
    int rc = open_level(r, level, diag);
    if (rc < 0)
        return rc;
    struct level *lv = &r->lv[level];
    const unsigned a = axis == 0 ? tvpal_dataset_default_axis(lv->ds)
                       : axis == TVPAL_AXIS_X ? 0
                       : axis == TVPAL_AXIS_Y ? 1 : 2;
    if (!lv->vr[a] &&
        (rc = tvpal_volreader_create(&lv->vr[a], lv->ds, a, diag)) < 0)
        return rc;
    return tvpal_volreader_read(lv->vr[a], t, dst, diag);
}

/* ------------------------------------------------------------------ sizes */

/* DIR, or DIR/level-k: level k's directory (malloc'ed; NULL: no memory). */
static char *level_dir(const struct tvpal_reader *r, uint32_t k)
{
    char *d = NULL;
    if (k == 0)
        return strdup(r->dir);
    return asprintf(&d, "%s/level-%u", r->dir, k) < 0 ? NULL : d;
}

/* The indices of axis a in a dataset ds: width * height bytes per
 * slice-window, one starting at step t of slice s as each shard's
 * schedule says (FORMAT.md 5; its palette groups, 5.1, set the phases). */
static uint64_t index_bytes(const struct tvpal_dataset *ds, unsigned a)
{
    uint64_t windows = 0;
    for (uint32_t k = 0; k < ds->nshards; k++) {
        const struct tvpal_shard_header *h = tvpal_shard_hdr(ds->shards[a][k]);
        const struct tvpal_schedule sc = tvpal_shard_schedule(h);
        for (uint32_t s = h->slice_begin; s < h->slice_begin + h->slice_count;
             s++)
            for (uint32_t t = 0; t < h->steps; t++)
                windows += (uint64_t)tvpal_schedule_starts(&sc, s, t);
    }
    const struct tvpal_shard_header *h0 = tvpal_shard_hdr(ds->shards[a][0]);
    return windows * h0->slice_w * h0->slice_h;
}

/* The table counts of axis a's shards (tvpal_shard_count_tables), summed
 * into *sum.  diag starts with the shard's path. */
static int count_axis(const struct tvpal_dataset *ds, unsigned a,
                      struct tvpal_table_count *sum, struct tvpal_diag *diag)
{
    memset(sum, 0, sizeof *sum);
    for (uint32_t k = 0; k < ds->nshards; k++) {
        struct tvpal_shard *sh = ds->shards[a][k];
        struct tvpal_table_count c;
        struct tvpal_diag d = {{0}};
        int rc = tvpal_shard_count_tables(sh, &c, &d);
        if (rc < 0)
            return tvpal_diag_set(diag, rc, "%s: %s", tvpal_shard_path(sh),
                                  d.msg[0] ? d.msg : tvpal_strerror(rc));
        for (unsigned u = 0; u < 2; u++) {
            sum->chunks[u] += c.chunks[u];
            sum->bytes[u] += c.bytes[u];
        }
        sum->coded_chunks += c.coded_chunks;
        sum->coded_bytes += c.coded_bytes;
        sum->coded_plain += c.coded_plain;
    }
    return 0;
}

/* Level `level`'s dataset, opened at its first use: 0, TVPAL_E_INVAL
 * (no such level) or open_level's error. */
static int level_dataset(struct tvpal_reader *r, uint32_t level,
                         const struct tvpal_dataset **ds,
                         struct tvpal_diag *diag)
{
    if (level > r->info.levels)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "level %u: the dataset "
                              "has levels 0..%u", level, r->info.levels);
    int rc = open_level(r, level, diag);
    if (rc == 0)
        *ds = r->lv[level].ds;
    return rc;
}

int tvpal_reader_coding(struct tvpal_reader *r, uint32_t level,
                        struct tvpal_coding *out, struct tvpal_diag *diag)
{
    const struct tvpal_dataset *ds = NULL;
    int rc = level_dataset(r, level, &ds, diag);
    if (rc < 0)
        return rc;
    struct tvpal_coding c;
    memset(&c, 0, sizeof c);
    for (unsigned a = 0; a < 3; a++) {
        struct tvpal_table_count n;
        if (!tvpal_dataset_has_axis(ds, a))
            continue;
        if ((rc = count_axis(ds, a, &n, diag)) < 0)
            return rc;
        c.chunks[a] = n.chunks[0] + n.chunks[1];
        c.chunks_coded[a] = n.coded_chunks;
        c.coded_bytes[a] = n.coded_bytes;
        c.coded_plain_bytes[a] = n.coded_plain;
    }
    *out = c;
    return 0;
}

int tvpal_reader_sizes(struct tvpal_reader *r, uint32_t level,
                       struct tvpal_sizes *out, struct tvpal_diag *diag)
{
    const struct tvpal_dataset *ds = NULL;
    int rc = level_dataset(r, level, &ds, diag);
    if (rc < 0)
        return rc;
    struct tvpal_sizes s;
    memset(&s, 0, sizeof s);
    for (unsigned a = 0; a < 3; a++) {
        struct tvpal_table_count n;
        if (!tvpal_dataset_has_axis(ds, a))
            continue;
        s.axis_bytes[a] = ds->axis_bytes[a];
        s.index_bytes[a] = index_bytes(ds, a);
        if ((rc = count_axis(ds, a, &n, diag)) < 0)
            return rc;
        s.table_bytes[a] = n.bytes[0] + n.bytes[1];
        s.chunks_f32[a] = n.chunks[0];
        s.chunks_u16[a] = n.chunks[1];
    }
    char *dir = level_dir(r, level);
    if (!dir)
        return TVPAL_E_NOMEM;
    rc = tvpal_tree_bytes(dir, &s.disk_bytes, diag);
    free(dir);
    if (rc == 0)
        *out = s;
    return rc;
}

/* ----------------------------------------------------------------- verify */

/* Where findings go: the caller's function, and their count. */
struct verdict {
    tvpal_check_fn fn;
    void *ctx;
    uint64_t problems;
};

/* One problem: msg (printf-style) with path, record and offset. */
__attribute__((format(printf, 6, 7)))
static void found(struct verdict *v, const char *path, int code,
                  int64_t record, uint64_t offset, const char *fmt, ...)
{
    char msg[sizeof ((struct tvpal_diag *)0)->msg + 512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    const struct tvpal_check c = {.path = path, .code = code,
                                  .record = record, .offset = offset,
                                  .msg = msg};
    v->problems++;
    if (v->fn)
        v->fn(v->ctx, &c);
}

/* Reads every record of the open shard s (path, header h), one problem
 * per bad record.  0 or TVPAL_E_NOMEM. */
static int verify_records(struct verdict *v, struct tvpal_shard *s,
                          const char *path, const struct tvpal_shard_header *h)
{
    const size_t cap = tvpal_shard_max_record(s);
    unsigned char *buf = malloc(cap ? cap : 1);
    if (!buf)
        return TVPAL_E_NOMEM;
    const uint64_t before = v->problems;
    for (uint32_t t = 0; t < h->steps; t++) {
        struct tvpal_diag d = {{0}};
        int rc = tvpal_shard_read_record(s, t, buf, cap, &d);
        if (rc < 0) {
            const uint64_t off = tvpal_shard_entry(s, t)->offset;
            found(v, path, rc, t, off, "%s: record %u (offset %llu): %s",
                  path, t, (unsigned long long)off,
                  d.msg[0] ? d.msg : tvpal_strerror(rc));
        }
    }
    free(buf);
    if (v->problems == before && v->fn) {
        const struct tvpal_check c = {.path = path, .record = -1,
                                      .records = h->steps};
        v->fn(v->ctx, &c);
    }
    return 0;
}

/* The shard of node k, axis a at path: it opens, its header agrees with
 * the manifest m, every record reads. */
static int verify_shard(struct verdict *v, const char *path,
                        const struct tvpal_manifest *m, uint32_t k,
                        unsigned a)
{
    struct tvpal_shard *s = NULL;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_shard_open(&s, path, &d);
    if (rc < 0) {
        found(v, path, rc, -1, 0, "%s: %s%s%s", path, tvpal_strerror(rc),
              d.msg[0] ? ": " : "", d.msg);
        return 0;
    }
    const struct tvpal_shard_header *h = tvpal_shard_hdr(s);
    if (memcmp(h->dims, m->dims, sizeof h->dims) || h->steps != m->steps ||
        h->window != m->window || h->schedule != m->schedule ||
        h->nodes != m->nodes || h->rank != k || h->axis != a)
        found(v, path, TVPAL_E_MISMATCH, -1, 0, "%s: header (dims %ux%ux%u, "
              "steps %u, window %u, schedule %u, node %u of %u, axis %u) "
              "does not match the manifest", path, h->dims[0], h->dims[1],
              h->dims[2], h->steps, h->window, h->schedule, h->rank,
              h->nodes, h->axis);
    else if ((rc = tvpal_shard_check_table(path, h, m, &d)) < 0)
        found(v, path, rc, -1, 0, "%s", d.msg);
    else
        rc = verify_records(v, s, path, h);
    tvpal_shard_close(s);
    return rc == TVPAL_E_NOMEM ? rc : 0;
}

/* Every shard of the axes m stores, in dir. */
static int verify_shards(struct verdict *v, const char *dir,
                         const struct tvpal_manifest *m)
{
    for (unsigned a = 0; a < 3; a++)
        for (uint32_t k = 0; (m->axes_mask & TVPAL_AXIS_BIT(a)) &&
                             k < m->nodes; k++) {
            char *path = tvpal_shard_filename(dir, k, a);
            int rc = path ? verify_shard(v, path, m, k, a) : TVPAL_E_NOMEM;
            free(path);
            if (rc < 0)
                return rc;
        }
    return 0;
}

/* Level k of r (FORMAT.md 2.1): a dataset of the same steps, with no
 * levels of its own, whose shards verify; a level named but missing is a
 * problem. */
static int verify_level(struct verdict *v, const struct tvpal_reader *r,
                        uint32_t k)
{
    char *ld = level_dir(r, k), *mp = NULL;
    if (!ld || asprintf(&mp, "%s/manifest.txt", ld) < 0) {
        free(ld);
        return TVPAL_E_NOMEM;
    }
    struct tvpal_manifest lm = {0};
    struct tvpal_diag d = {{0}};
    int rc = tvpal_manifest_load(mp, &lm, &d);
    if (rc < 0)
        found(v, ld, rc, -1, 0, "%s: level %u of the %u the manifest names: "
              "%s", ld, k, r->m.levels, d.msg);
    else if (lm.steps != r->m.steps || lm.levels)
        found(v, ld, TVPAL_E_MISMATCH, -1, 0, "%s: level %u has %u steps and "
              "%u levels of its own (%u and none expected)", ld, k, lm.steps,
              lm.levels, r->m.steps);
    else
        rc = verify_shards(v, ld, &lm);
    rc = rc == TVPAL_E_NOMEM ? rc : 0;
    tvpal_manifest_clear(&lm);
    free(mp);
    free(ld);
    return rc;
}

int tvpal_reader_verify(struct tvpal_reader *r, tvpal_check_fn fn, void *ctx,
                        uint64_t *problems, struct tvpal_diag *diag)
{
    struct verdict v = {.fn = fn, .ctx = ctx};
    int rc = verify_shards(&v, r->dir, &r->m);
    for (uint32_t k = 1; rc == 0 && k <= r->m.levels; k++)
        rc = verify_level(&v, r, k);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "%s: out of memory while verifying",
                              r->dir);
    if (problems)
        *problems = v.problems;
    return 0;
}
