/* tvpal-info: prints what a tvpal dataset holds and, with --verify, checks
 * every record of every shard, naming each corrupt one. */
#define _GNU_SOURCE
#include "tvpal_cli.h"
#include "tvpal_dataset.h"
#include "tvpal_format.h"
#include "tvpal_fs.h"

#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG "tvpal-info"

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " OUTDIR [--verify]\n"
"Print the manifest of the tvpal dataset OUTDIR and its bytes per axis.\n"
"\n"
"  -v, --verify   open every shard (header, index, size, agreement with the\n"
"                 manifest) and read every record (CRC-32C and layout); each\n"
"                 corrupt file or record is named\n"
"  -h, --help     this help\n"
"  -V, --version  version\n"
"\n"
"Exit status: 0 dataset valid; 1 --verify found corrupt, truncated or missing\n"
"shard files or records; 2 usage error, unreadable manifest, or (without\n"
"--verify) a dataset that cannot be opened.\n");
}

/* Verifies every shard file; returns the number of problems found. */
static unsigned verify(const char *dir, const struct tvpal_manifest *m)
{
    unsigned bad = 0;
    for (unsigned a = 0; a < 3; a++)
        for (uint32_t r = 0; r < m->nodes; r++) {
            char *path = tvpal_shard_filename(dir, r, a);
            struct tvpal_shard *s = NULL;
            struct tvpal_diag d = {{0}};
            if (!path)
                return bad + 1;
            int rc = tvpal_shard_open(&s, path, &d);
            if (rc < 0) {
                printf("CORRUPT %s: %s%s%s\n", path, tvpal_strerror(rc),
                       d.msg[0] ? ": " : "", d.msg);
                bad++;
                free(path);
                continue;
            }
            const struct tvpal_shard_header *h = tvpal_shard_hdr(s);
            if (memcmp(h->dims, m->dims, sizeof h->dims) ||
                h->steps != m->steps || h->window != m->window ||
                h->nodes != m->nodes || h->rank != r || h->axis != a) {
                printf("CORRUPT %s: header (dims %ux%ux%u, steps %u, window "
                       "%u, node %u of %u, axis %u) does not match the "
                       "manifest\n", path, h->dims[0], h->dims[1], h->dims[2],
                       h->steps, h->window, h->rank, h->nodes, h->axis);
                bad++;
                tvpal_shard_close(s);
                free(path);
                continue;
            }
            unsigned char *buf = malloc(tvpal_shard_max_record(s));
            unsigned shard_bad = 0;
            for (uint32_t t = 0; buf && t < h->steps; t++) {
                d.msg[0] = 0;
                rc = tvpal_shard_read_record(s, t, buf,
                                             tvpal_shard_max_record(s), &d);
                if (rc < 0) {
                    printf("CORRUPT %s: record %u (offset %llu): %s\n", path,
                           t,
                           (unsigned long long)tvpal_shard_entry(s, t)->offset,
                           d.msg[0] ? d.msg : tvpal_strerror(rc));
                    shard_bad++;
                }
            }
            if (!buf)
                shard_bad++;
            if (!shard_bad)
                printf("ok %s: %u records\n", path, h->steps);
            bad += shard_bad;
            free(buf);
            tvpal_shard_close(s);
            free(path);
        }
    return bad;
}

int main(int argc, char **argv)
{
    static const struct option lopts[] = {
        {"verify", no_argument, 0, 'v'},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0}};
    int do_verify = 0, c;
    while ((c = getopt_long(argc, argv, "vhV", lopts, NULL)) != -1) {
        switch (c) {
        case 'v': do_verify = 1; break;
        case 'h': usage(stdout); return 0;
        case 'V': printf(PROG " " PACKAGE_VERSION "\n"); return 0;
        default:
            fprintf(stderr, "Try '" PROG " --help'.\n");
            return TVPAL_EXIT_USAGE;
        }
    }
    if (optind != argc - 1) {
        fprintf(stderr, PROG ": expected one OUTDIR (try --help)\n");
        return TVPAL_EXIT_USAGE;
    }
    const char *dir = argv[optind];
    char *mpath, *text = NULL;
    struct tvpal_manifest m;
    struct tvpal_diag d = {{0}};
    if (asprintf(&mpath, "%s/manifest.txt", dir) < 0)
        return TVPAL_EXIT_FAIL;
    int rc = tvpal_manifest_load(mpath, &m, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s: %s%s%s\n", mpath, tvpal_strerror(rc),
                d.msg[0] ? ": " : "", d.msg);
        free(mpath);
        return TVPAL_EXIT_USAGE;
    }
    if (tvpal_read_file(mpath, &text, NULL) == 0) {
        fputs(text, stdout);
        free(text);
    }
    free(mpath);
    int status = TVPAL_EXIT_OK;
    if (do_verify) {
        unsigned bad = verify(dir, &m);
        printf("verify: %s (%u problem%s)\n", bad ? "FAILED" : "ok", bad,
               bad == 1 ? "" : "s");
        if (bad)
            fprintf(stderr, PROG ": %s: %u corrupt record%s or file%s\n",
                    dir, bad, bad == 1 ? "" : "s", bad == 1 ? "" : "s");
        status = bad ? TVPAL_EXIT_FAIL : TVPAL_EXIT_OK;
    } else {
        struct tvpal_dataset *ds = NULL;
        rc = tvpal_dataset_open(&ds, dir, &d);
        if (rc < 0) {
            fprintf(stderr, PROG ": %s\n", d.msg);
            tvpal_manifest_clear(&m);
            return TVPAL_EXIT_USAGE;
        }
        double vts = (double)m.dims[0] * m.dims[1] * m.dims[2] * m.steps;
        for (unsigned a = 0; a < 3; a++)
            printf("axis_%c_bytes = %llu  (%.4f bits per voxel-timestep, "
                   "ratio %.3f)\n", "xyz"[a],
                   (unsigned long long)ds->axis_bytes[a],
                   8.0 * (double)ds->axis_bytes[a] / vts,
                   vts * (double)tvpal_type_size(m.type) /
                       (double)ds->axis_bytes[a]);
        tvpal_dataset_close(ds);
    }
    tvpal_manifest_clear(&m);
    return status;
}
