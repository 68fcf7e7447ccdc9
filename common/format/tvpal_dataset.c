/* tvpal_dataset.c: dataset directory access (see tvpal_dataset.h). */
#define _GNU_SOURCE
#include "tvpal_cli.h"
#include "tvpal_dataset.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static const char axis_name[3] = {'x', 'y', 'z'};

char *tvpal_shard_filename(const char *dir, uint32_t rank, unsigned axis)
{
    char *p;
    if (asprintf(&p, "%s/node-%u/axis-%c.tvps", dir, rank, axis_name[axis]) < 0)
        return NULL;
    return p;
}

int tvpal_shard_check_table(const char *path,
                            const struct tvpal_shard_header *h,
                            const struct tvpal_manifest *m,
                            struct tvpal_diag *diag)
{
    /* The shard's format without its missing values: 0, 1 or 4. */
    uint32_t shard = h->table_format >= TVPAL_TABLE_CHUNK
                         ? TVPAL_TABLE_CHUNK
                         : h->table_format & TVPAL_TABLE_U16;
    if (shard == m->table_format)
        return 0;
    return tvpal_diag_set(diag, TVPAL_E_MISMATCH,
                          "%s: header table_format %u (%s tables) does not "
                          "match the manifest's table = %s", path,
                          h->table_format,
                          shard == TVPAL_TABLE_CHUNK ? "per-chunk"
                          : shard ? "16-bit" : "float32",
                          tvpal_manifest_table_name(m->table_format));
}

int tvpal_dataset_check_dir(const char *dir, struct tvpal_diag *diag)
{
    struct stat st;
    if (stat(dir, &st) == 0 && !S_ISDIR(st.st_mode))
        return tvpal_diag_set(diag, TVPAL_E_OPEN, "%s: a file, not a dataset "
                              "directory (an input file? tvpal-info --inspect "
                              "%s describes it)", dir, dir);
    return 0;
}

/* Allocates a dataset for dir and loads dir/manifest.txt into it. */
static int open_manifest(struct tvpal_dataset **out, const char *dir,
                         struct tvpal_diag *diag)
{
    struct tvpal_diag d = {{0}};
    char *path = NULL;
    int rc;
    struct tvpal_dataset *ds = calloc(1, sizeof *ds);
    if (!ds || !(ds->dir = strdup(dir))) {
        free(ds);
        return TVPAL_E_NOMEM;
    }
    if ((rc = tvpal_dataset_check_dir(dir, diag)) < 0) {
        path = NULL;
    } else if (asprintf(&path, "%s/manifest.txt", dir) < 0) {
        path = NULL;
        rc = TVPAL_E_NOMEM;
    } else if ((rc = tvpal_manifest_load(path, &ds->m, &d)) < 0) {
        /* an open error names the file already; a parse error does not */
        if (!strncmp(d.msg, path, strlen(path)))
            tvpal_diag_set(diag, rc, "%s", d.msg);
        else
            tvpal_diag_set(diag, rc, "%s: %s", path, d.msg);
    }
    free(path);
    if (rc < 0) {
        tvpal_dataset_close(ds);
        return rc;
    }
    *out = ds;
    return 0;
}

int tvpal_dataset_has_axis(const struct tvpal_dataset *ds, unsigned axis)
{
    return axis < 3 && (ds->m.axes_mask & TVPAL_AXIS_BIT(axis)) != 0;
}

unsigned tvpal_dataset_default_axis(const struct tvpal_dataset *ds)
{
    unsigned a = 2;
    while (a > 0 && !tvpal_dataset_has_axis(ds, a))
        a--;
    return a;
}

/* Opens the shard at path into *out and checks its header against the
 * manifest m (FORMAT.md 8.3): dims, steps, window, nodes == nodes, rank,
 * axis, table.  node_msg: the mismatch named as a node's view ("this rank
 * is R of K") rather than the manifest's.  0 or the error, diag starting
 * with path. */
static int open_shard(struct tvpal_shard **out, const char *path,
                      const struct tvpal_manifest *m, uint32_t nodes,
                      uint32_t rank, unsigned axis, int node_msg,
                      struct tvpal_diag *diag)
{
    struct tvpal_diag d = {{0}};
    int rc = tvpal_shard_open(out, path, &d);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "%s: %s%s%s", path, tvpal_strerror(rc),
                              d.msg[0] ? ": " : "", d.msg);
    const struct tvpal_shard_header *h = tvpal_shard_hdr(*out);
    if (memcmp(h->dims, m->dims, sizeof h->dims) || h->steps != m->steps ||
        h->window != m->window || h->schedule != m->schedule ||
        h->nodes != nodes || h->rank != rank || h->axis != axis) {
        if (node_msg)
            return tvpal_diag_set(diag, TVPAL_E_MISMATCH,
                                  "%s: header says node %u of %u (axis %u); "
                                  "this rank is %u of %u", path, h->rank,
                                  h->nodes, h->axis, rank, nodes);
        return tvpal_diag_set(diag, TVPAL_E_MISMATCH,
                              "%s: header (dims %ux%ux%u, steps %u, window "
                              "%u, schedule %u, node %u of %u, axis %u) does "
                              "not match the manifest", path, h->dims[0],
                              h->dims[1], h->dims[2], h->steps, h->window,
                              h->schedule, h->rank, h->nodes, h->axis);
    }
    return tvpal_shard_check_table(path, h, m, diag);
}

int tvpal_dataset_open(struct tvpal_dataset **out, const char *dir,
                       struct tvpal_diag *diag)
{
    char *path = NULL;
    struct tvpal_dataset *ds;
    int rc = open_manifest(&ds, dir, diag);
    if (rc < 0)
        return rc;
    ds->nshards = ds->m.nodes;
    ds->first_rank = 0;
    for (unsigned a = 0; a < 3; a++) {
        if (!tvpal_dataset_has_axis(ds, a))
            continue;
        ds->shards[a] = calloc(ds->m.nodes, sizeof *ds->shards[a]);
        if (!ds->shards[a]) {
            rc = TVPAL_E_NOMEM;
            goto err;
        }
        for (uint32_t r = 0; r < ds->m.nodes; r++) {
            free(path);
            path = tvpal_shard_filename(dir, r, a);
            if (!path) {
                rc = TVPAL_E_NOMEM;
                goto err;
            }
            rc = open_shard(&ds->shards[a][r], path, &ds->m, ds->m.nodes, r,
                            a, 0, diag);
            if (rc < 0)
                goto err;
            ds->axis_bytes[a] += tvpal_shard_hdr(ds->shards[a][r])->file_bytes;
        }
    }
    free(path);
    *out = ds;
    return 0;
err:
    free(path);
    tvpal_dataset_close(ds);
    return rc;
}

void tvpal_dataset_close(struct tvpal_dataset *ds)
{
    if (!ds)
        return;
    for (unsigned a = 0; a < 3; a++) {
        if (ds->shards[a])
            for (uint32_t r = 0; r < ds->nshards; r++)
                tvpal_shard_close(ds->shards[a][r]);
        free(ds->shards[a]);
    }
    tvpal_manifest_clear(&ds->m);
    free(ds->dir);
    free(ds);
}

int tvpal_dataset_open_node(struct tvpal_dataset **out, const char *node_dir,
                            uint32_t rank, uint32_t nranks,
                            struct tvpal_diag *diag)
{
    char *path = NULL;
    struct tvpal_dataset *ds;
    int rc = open_manifest(&ds, node_dir, diag);
    if (rc < 0)
        return rc;
    if (ds->m.nodes != nranks) {
        rc = tvpal_diag_set(diag, TVPAL_E_MISMATCH,
                            "%s/manifest.txt: the dataset has %u node shards; "
                            "started with %u ranks (run mpirun -np %u)",
                            node_dir, ds->m.nodes, nranks, ds->m.nodes);
        goto err;
    }
    ds->nshards = 1;
    ds->first_rank = rank;
    for (unsigned a = 0; a < 3; a++) {
        if (!tvpal_dataset_has_axis(ds, a))
            continue;
        ds->shards[a] = calloc(1, sizeof *ds->shards[a]);
        if (!ds->shards[a]) {
            rc = TVPAL_E_NOMEM;
            goto err;
        }
        free(path);
        if (asprintf(&path, "%s/axis-%c.tvps", node_dir, axis_name[a]) < 0) {
            path = NULL;
            rc = TVPAL_E_NOMEM;
            goto err;
        }
        rc = open_shard(&ds->shards[a][0], path, &ds->m, nranks, rank, a, 1,
                        diag);
        if (rc < 0)
            goto err;
        ds->axis_bytes[a] = tvpal_shard_hdr(ds->shards[a][0])->file_bytes;
    }
    free(path);
    *out = ds;
    return 0;
err:
    free(path);
    tvpal_dataset_close(ds);
    return rc;
}

struct tvpal_volreader {
    struct tvpal_dataset *ds;
    unsigned axis;
    struct tvpal_slab **slabs;
};

int tvpal_volreader_create(struct tvpal_volreader **out,
                           struct tvpal_dataset *ds, unsigned axis,
                           struct tvpal_diag *diag)
{
    char axes[4];
    if (!tvpal_dataset_has_axis(ds, axis))
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "axis %c: dataset stores "
                              "axes %s only", axis < 3 ? axis_name[axis] : '?',
                              tvpal_axes_format(ds->m.axes_mask, axes));
    struct tvpal_volreader *r = calloc(1, sizeof *r);
    if (!r)
        return TVPAL_E_NOMEM;
    r->ds = ds;
    r->axis = axis;
    r->slabs = calloc(ds->m.nodes, sizeof *r->slabs);
    if (!r->slabs) {
        free(r);
        return TVPAL_E_NOMEM;
    }
    for (uint32_t k = 0; k < ds->m.nodes; k++) {
        int rc = tvpal_slab_create(&r->slabs[k], ds->shards[axis][k]);
        if (rc < 0) {
            tvpal_volreader_free(r);
            return rc;
        }
    }
    *out = r;
    return 0;
}

void tvpal_volreader_free(struct tvpal_volreader *r)
{
    if (!r)
        return;
    for (uint32_t k = 0; k < r->ds->m.nodes; k++)
        tvpal_slab_free(r->slabs[k]);
    free(r->slabs);
    free(r);
}

int tvpal_volreader_read(struct tvpal_volreader *r, uint32_t t, float *vol,
                         struct tvpal_diag *diag)
{
    for (uint32_t k = 0; k < r->ds->m.nodes; k++) {
        struct tvpal_diag d = {{0}};
        int rc = tvpal_slab_seek(r->slabs[k], t, &d);
        if (rc < 0)
            return tvpal_diag_set(diag, rc, "%s: %s",
                                  tvpal_shard_path(r->ds->shards[r->axis][k]),
                                  d.msg[0] ? d.msg : tvpal_strerror(rc));
        tvpal_slab_scatter(r->slabs[k], t, vol);
    }
    return 0;
}

uint64_t tvpal_volreader_bytes_read(const struct tvpal_volreader *r)
{
    uint64_t b = 0;
    for (uint32_t k = 0; k < r->ds->m.nodes; k++)
        b += tvpal_slab_bytes_read(r->slabs[k]);
    return b;
}
