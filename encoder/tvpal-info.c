/* tvpal-info: prints what a tvpal dataset holds and, with --verify, checks
 * every record of every shard, naming each corrupt one.
 *
 * The steps of main: parse the options, load the manifest and print it
 * with the axes it stores, then either verify every shard (--verify) or
 * open the dataset and print its bytes per stored axis; with --histogram,
 * load the manifest and print only its value histogram. */
#define _GNU_SOURCE
#include "tvpal_cli.h"
#include "tvpal_dataset.h"
#include "tvpal_format.h"
#include "tvpal_fs.h"
#include "tvpal_input.h"

#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG "tvpal-info"

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " OUTDIR [--verify]\n"
"       " PROG " OUTDIR --histogram\n"
"       " PROG " --inspect FILE\n"
"Print the manifest of the tvpal dataset OUTDIR, the axes it stores, its\n"
"bytes per stored axis and on disk, and its chunks by decoder table format\n"
"(16-bit or float32); or, with --inspect, what an input file holds.\n"
"\n"
"  -v, --verify     open every shard of the stored axes (header, index,\n"
"                   size, agreement with the manifest) and read every record\n"
"                   (CRC-32C and layout), of level 0 and of every level\n"
"                   the manifest names; each corrupt file or record is\n"
"                   named\n"
"  -H, --histogram  print only the dataset's value histogram (from the\n"
"                   manifest): one line per bin, \"BIN LO HI COUNT FRACTION\n"
"                   BAR\", then a summary line (count, missing, values)\n"
"  -i, --inspect    FILE is an input for tvpal-encode: print its format and\n"
"                   its variables with their dims, type and units (NetCDF,\n"
"                   VTK ImageData)\n"
"  -h, --help       this help\n"
"  -V, --version    version\n"
"\n"
"Exit status: 0 dataset valid; 1 --verify found corrupt, truncated or missing\n"
"shard files or records; 2 usage error, unreadable manifest, or (without\n"
"--verify) a dataset that cannot be opened.\n");
}

struct options {
    const char *dir;   /* OUTDIR, or the FILE of --inspect */
    int verify, inspect, histogram;
};

static const struct option long_options[] = {
    {"verify", no_argument, 0, 'v'},
    {"inspect", no_argument, 0, 'i'},
    {"histogram", no_argument, 0, 'H'},
    {"help", no_argument, 0, 'h'},
    {"version", no_argument, 0, 'V'},
    {0, 0, 0, 0}};
static const char short_options[] = "viHhV";

/* Fills o from argv and checks that exactly one OUTDIR is given.  Returns -1
 * to go on, or the exit status when the program is done: --help, --version
 * or a usage error (message printed). */
static int parse_options(int argc, char **argv, struct options *o)
{
    int c;
    *o = (struct options){0};
    while ((c = getopt_long(argc, argv, short_options, long_options, NULL)) != -1) {
        switch (c) {
        case 'v': o->verify = 1; break;
        case 'i': o->inspect = 1; break;
        case 'H': o->histogram = 1; break;
        case 'h': usage(stdout); return TVPAL_EXIT_OK;
        case 'V': printf(PROG " " PACKAGE_VERSION "\n"); return TVPAL_EXIT_OK;
        default:
            fprintf(stderr, "Try '" PROG " --help'.\n");
            return TVPAL_EXIT_USAGE;
        }
    }
    if (optind != argc - 1) {
        fprintf(stderr, PROG ": expected one %s (try --help)\n",
                o->inspect ? "FILE" : "OUTDIR");
        return TVPAL_EXIT_USAGE;
    }
    if (o->inspect + o->verify + o->histogram > 1) {
        fprintf(stderr, PROG ": --inspect, --verify and --histogram: one at "
                "a time\n");
        return TVPAL_EXIT_USAGE;
    }
    o->dir = argv[optind];
    return -1;
}

/* Reads every record of the open shard s (path, header h); prints one line
 * per bad record and returns their number (1 when out of memory). */
static unsigned verify_records(struct tvpal_shard *s, const char *path,
                               const struct tvpal_shard_header *h)
{
    const size_t cap = tvpal_shard_max_record(s);
    unsigned char *buf = malloc(cap);
    if (!buf)
        return 1;
    unsigned bad = 0;
    for (uint32_t t = 0; t < h->steps; t++) {
        struct tvpal_diag d = {{0}};
        int rc = tvpal_shard_read_record(s, t, buf, cap, &d);
        if (rc < 0) {
            printf("CORRUPT %s: record %u (offset %llu): %s\n", path, t,
                   (unsigned long long)tvpal_shard_entry(s, t)->offset,
                   d.msg[0] ? d.msg : tvpal_strerror(rc));
            bad++;
        }
    }
    free(buf);
    return bad;
}

/* Verifies the shard of node r, axis a at path: it opens, its header
 * agrees with the manifest m, every record reads.  Prints "ok ..." or one
 * "CORRUPT ..." line per problem and returns the number of problems. */
static unsigned verify_shard(const char *path, const struct tvpal_manifest *m,
                             uint32_t r, unsigned a)
{
    struct tvpal_shard *s = NULL;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_shard_open(&s, path, &d);
    if (rc < 0) {
        printf("CORRUPT %s: %s%s%s\n", path, tvpal_strerror(rc),
               d.msg[0] ? ": " : "", d.msg);
        return 1;
    }
    const struct tvpal_shard_header *h = tvpal_shard_hdr(s);
    unsigned bad;
    if (memcmp(h->dims, m->dims, sizeof h->dims) || h->steps != m->steps ||
        h->window != m->window || h->nodes != m->nodes || h->rank != r ||
        h->axis != a) {
        printf("CORRUPT %s: header (dims %ux%ux%u, steps %u, window "
               "%u, node %u of %u, axis %u) does not match the "
               "manifest\n", path, h->dims[0], h->dims[1], h->dims[2],
               h->steps, h->window, h->rank, h->nodes, h->axis);
        bad = 1;
    } else if (tvpal_shard_check_table(path, h, m, &d) < 0) {
        printf("CORRUPT %s\n", d.msg);
        bad = 1;
    } else {
        bad = verify_records(s, path, h);
        if (!bad)
            printf("ok %s: %u records\n", path, h->steps);
    }
    tvpal_shard_close(s);
    return bad;
}

/* Verifies every shard file of the stored axes; returns the number of
 * problems found. */
static unsigned verify(const char *dir, const struct tvpal_manifest *m)
{
    unsigned bad = 0;
    for (unsigned a = 0; a < 3; a++)
        for (uint32_t r = 0; (m->axes_mask & TVPAL_AXIS_BIT(a)) &&
                             r < m->nodes; r++) {
            char *path = tvpal_shard_filename(dir, r, a);
            if (!path)
                return bad + 1;
            bad += verify_shard(path, m, r, a);
            free(path);
        }
    return bad;
}

/* Verifies the coarser levels the manifest m of dir names (level-1 ..
 * level-L, FORMAT.md 2.1): each is a dataset of the same steps whose
 * shards verify; a level named but missing is a problem. */
static unsigned verify_levels(const char *dir, const struct tvpal_manifest *m)
{
    unsigned bad = 0;
    for (uint32_t k = 1; k <= m->levels; k++) {
        char *ld = NULL, *mp = NULL;
        if (asprintf(&ld, "%s/level-%u", dir, k) < 0 ||
            asprintf(&mp, "%s/manifest.txt", ld) < 0) {
            free(ld);
            return bad + 1;
        }
        struct tvpal_manifest lm = {0};
        struct tvpal_diag d = {{0}};
        if (tvpal_manifest_load(mp, &lm, &d) < 0) {
            printf("CORRUPT %s: level %u of the %u the manifest names: %s\n",
                   ld, k, m->levels, d.msg);
            bad++;
        } else if (lm.steps != m->steps || lm.levels) {
            printf("CORRUPT %s: level %u has %u steps and %u levels of its "
                   "own (%u and none expected)\n", ld, k, lm.steps,
                   lm.levels, m->steps);
            bad++;
        } else {
            bad += verify(ld, &lm);
        }
        tvpal_manifest_clear(&lm);
        free(mp);
        free(ld);
    }
    return bad;
}

/* --verify: every shard, then the verdict.  Returns the exit status. */
static int print_verify(const char *dir, const struct tvpal_manifest *m)
{
    unsigned bad = verify(dir, m) + verify_levels(dir, m);
    printf("verify: %s (%u problem%s)\n", bad ? "FAILED" : "ok", bad,
           bad == 1 ? "" : "s");
    if (bad)
        fprintf(stderr, PROG ": %s: %u corrupt record%s or file%s\n",
                dir, bad, bad == 1 ? "" : "s", bad == 1 ? "" : "s");
    return bad ? TVPAL_EXIT_FAIL : TVPAL_EXIT_OK;
}

/* Without --verify: opens the dataset (every shard's header and index) and
 * prints the bytes of each stored axis, then those of every file of the
 * dataset (what it takes on disk), then its chunks by decoder table
 * format (with --table auto, from every chunk header).  Returns the exit
 * status. */
static int print_axis_bytes(const char *dir, const struct tvpal_manifest *m)
{
    struct tvpal_dataset *ds = NULL;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_dataset_open(&ds, dir, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_USAGE;
    }
    double vts = (double)m->dims[0] * m->dims[1] * m->dims[2] * m->steps;
    double src = vts * (double)tvpal_type_size(m->type);
    for (unsigned a = 0; a < 3; a++)
        if (tvpal_dataset_has_axis(ds, a))
            printf("axis_%c_bytes = %llu  (%.4f bits per voxel-timestep, "
                   "axis_ratio %.3f)\n", "xyz"[a],
                   (unsigned long long)ds->axis_bytes[a],
                   8.0 * (double)ds->axis_bytes[a] / vts,
                   src / (double)ds->axis_bytes[a]);
    uint64_t n[2] = {0, 0};
    for (unsigned a = 0; a < 3; a++)
        for (uint32_t k = 0; tvpal_dataset_has_axis(ds, a) && k < ds->nshards;
             k++) {
            struct tvpal_table_count c;
            rc = tvpal_shard_count_tables(ds->shards[a][k], &c, &d);
            if (rc < 0) {
                fprintf(stderr, PROG ": %s: %s\n",
                        tvpal_shard_path(ds->shards[a][k]),
                        d.msg[0] ? d.msg : tvpal_strerror(rc));
                tvpal_dataset_close(ds);
                return TVPAL_EXIT_FAIL;
            }
            n[0] += c.chunks[0];
            n[1] += c.chunks[1];
        }
    tvpal_dataset_close(ds);
    uint64_t disk = 0;
    rc = tvpal_tree_bytes(dir, &disk, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_USAGE;
    }
    printf("disk_bytes = %llu  (%.4f bits per voxel-timestep, ratio %.3f: "
           "every file%s)\n", (unsigned long long)disk, 8.0 * (double)disk / vts,
           src / (double)disk, m->levels ? ", levels included" : "");
    const uint64_t all = n[0] + n[1];
    printf("tables_u16 = %llu  (chunks with 16-bit decoder tables, all "
           "axes: %.1f%%)\n", (unsigned long long)n[1],
           all ? 100.0 * (double)n[1] / (double)all : 0.0);
    printf("tables_f32 = %llu  (chunks with float32 decoder tables)\n",
           (unsigned long long)n[0]);
    return TVPAL_EXIT_OK;
}

/* --histogram: the manifest's TVPAL_HIST_BINS bins over [value_min,
 * value_max], one line each (bin, its value range, count, share of the
 * counted values, a bar scaled to the fullest bin), then a summary.  The
 * counts are the encoder's (approximate at bin edges: FORMAT.md 2.2). */
static void print_histogram(const char *dir, const struct tvpal_manifest *m)
{
    const double lo = m->value_min, hi = m->value_max;
    const double w = (hi - lo) / TVPAL_HIST_BINS;
    uint64_t total = 0, peak = 0;
    for (unsigned i = 0; i < TVPAL_HIST_BINS; i++) {
        total += m->histogram[i];
        peak = m->histogram[i] > peak ? m->histogram[i] : peak;
    }
    printf("# histogram of %s: %d bins over [%.9g, %.9g] (the last includes "
           "its top)\n# bin lo hi count fraction bar\n", dir,
           TVPAL_HIST_BINS, lo, hi);
    for (unsigned i = 0; i < TVPAL_HIST_BINS; i++) {
        const uint64_t c = m->histogram[i];
        int bar = peak ? (int)(40.0 * (double)c / (double)peak + 0.5) : 0;
        bar = c && !bar ? 1 : bar;
        printf("%u %.9g %.9g %llu %.6f%s%.*s\n", i, lo + i * w,
               i + 1 == TVPAL_HIST_BINS ? hi : lo + (i + 1) * w,
               (unsigned long long)c, total ? (double)c / (double)total : 0.0,
               bar ? " " : "", bar, "****************************************");
    }
    const double values = (double)m->dims[0] * m->dims[1] * m->dims[2] *
                          m->steps;
    printf("histogram: bins=%d count=%llu missing=%llu values=%.0f\n",
           TVPAL_HIST_BINS, (unsigned long long)total,
           (unsigned long long)m->missing, values);
}

/* Loads dir/manifest.txt into m and prints the file as it is (unless
 * quiet).  Returns 0 or the exit status (printed). */
static int load_and_print_manifest(const char *dir, struct tvpal_manifest *m,
                                   int quiet)
{
    char *mpath, *text = NULL;
    struct tvpal_diag d = {{0}};
    if (asprintf(&mpath, "%s/manifest.txt", dir) < 0)
        return TVPAL_EXIT_FAIL;
    int rc = tvpal_dataset_check_dir(dir, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg);
        free(mpath);
        return TVPAL_EXIT_USAGE;
    }
    rc = tvpal_manifest_load(mpath, m, &d);
    if (rc < 0 && !strncmp(d.msg, mpath, strlen(mpath))) {
        fprintf(stderr, PROG ": %s\n", d.msg);   /* it names the file */
        free(mpath);
        return TVPAL_EXIT_USAGE;
    }
    if (rc < 0) {
        fprintf(stderr, PROG ": %s: %s%s%s\n", mpath, tvpal_strerror(rc),
                d.msg[0] ? ": " : "", d.msg);
        free(mpath);
        return TVPAL_EXIT_USAGE;
    }
    /* Loaded and checked a moment ago: a failure to read it again only
     * leaves out the text. */
    if (quiet) {
        free(mpath);
        return 0;
    }
    if (tvpal_read_file(mpath, &text, NULL, NULL) == 0) {
        fputs(text, stdout);
        free(text);
    }
    /* The axes key is absent for all three (FORMAT.md 2.2): say it. */
    char axes[4];
    printf("stored_axes = %s\n", tvpal_axes_format(m->axes_mask, axes));
    free(mpath);
    return 0;
}

/* --inspect: what an input file holds (tvpal_input_describe). */
static int inspect(const char *path)
{
    struct tvpal_diag d = {{0}};
    enum tvpal_input_format f;
    char *text = NULL;
    int rc = tvpal_input_detect(path, NULL, &f, &d);
    if (rc == 0 && f == TVPAL_IN_RAW) {
        printf("%s: raw (no header: tvpal-encode needs --dims and --type)\n",
               path);
        return TVPAL_EXIT_OK;
    }
    if (rc == 0)
        rc = tvpal_input_describe(path, f, &text, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_USAGE;
    }
    printf("%s: %s", path, text);
    free(text);
    return TVPAL_EXIT_OK;
}

int main(int argc, char **argv)
{
    struct options o;
    int status = parse_options(argc, argv, &o);
    if (status >= 0)
        return status;
    if (o.inspect)
        return inspect(o.dir);
    struct tvpal_manifest m;
    status = load_and_print_manifest(o.dir, &m, o.histogram);
    if (status != 0)
        return status;
    if (o.histogram)
        print_histogram(o.dir, &m);
    else
        status = o.verify ? print_verify(o.dir, &m)
                          : print_axis_bytes(o.dir, &m);
    tvpal_manifest_clear(&m);
    return status;
}
