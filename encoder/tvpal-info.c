/* tvpal-info: prints what a tvpal dataset holds and, with --verify, checks
 * every record of every shard, naming each corrupt one.
 *
 * A thin program over libtvpal's reader (tvpal.h).  The steps of main:
 * parse the options, open the dataset's manifest and print it with the
 * axes it stores, then either verify every shard (--verify) or print its
 * bytes per stored axis; with --histogram, print only the manifest's value
 * histogram.  --inspect describes an input file (common/input). */
#define _GNU_SOURCE
#include "tvpal.h"
#include "tvpal_cli.h"
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
"bytes per stored axis and on disk, its chunks by decoder table format\n"
"(16-bit or float32) and the bytes of each coarser level; or, with\n"
"--inspect, what an input file holds.\n"
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

/* --verify's lines: "ok PATH: N records" per sound shard, "CORRUPT MSG"
 * per problem. */
static void print_check(void *ctx, const struct tvpal_check *c)
{
    (void)ctx;
    if (c->code == 0)
        printf("ok %s: %u records\n", c->path, c->records);
    else
        printf("CORRUPT %s\n", c->msg);
}

/* --verify: every shard and level (tvpal_reader_verify), then the
 * verdict.  Returns the exit status. */
static int print_verify(struct tvpal_reader *r, const char *dir)
{
    uint64_t bad = 0;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_reader_verify(r, print_check, NULL, &bad, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_FAIL;
    }
    printf("verify: %s (%llu problem%s)\n", bad ? "FAILED" : "ok",
           (unsigned long long)bad, bad == 1 ? "" : "s");
    if (bad)
        fprintf(stderr, PROG ": %s: %llu corrupt record%s or file%s\n", dir,
                (unsigned long long)bad, bad == 1 ? "" : "s",
                bad == 1 ? "" : "s");
    return bad ? TVPAL_EXIT_FAIL : TVPAL_EXIT_OK;
}

/* What each coarser level takes on disk (every file of DIR/level-k), in
 * bits per voxel-timestep of level 0 and as a share of the dataset's
 * disk_bytes.  Returns the exit status: a level that does not open is bad
 * input (2), as level 0 is. */
static int print_level_bytes(struct tvpal_reader *r, uint64_t disk,
                             double vts)
{
    const struct tvpal_info *in = tvpal_reader_info(r);
    for (uint32_t k = 1; k <= in->levels; k++) {
        struct tvpal_sizes z;
        struct tvpal_diag d = {{0}};
        int rc = tvpal_reader_sizes(r, k, &z, &d);
        if (rc < 0) {
            fprintf(stderr, PROG ": level %u: %s\n", k,
                    d.msg[0] ? d.msg : tvpal_strerror(rc));
            return rc == TVPAL_E_NOMEM ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE;
        }
        printf("level_%u_bytes = %llu  (%.4f bits per voxel-timestep of "
               "level 0, %.1f%% of disk_bytes)\n", k,
               (unsigned long long)z.disk_bytes,
               8.0 * (double)z.disk_bytes / vts,
               disk ? 100.0 * (double)z.disk_bytes / (double)disk : 0.0);
    }
    return TVPAL_EXIT_OK;
}

/* Without --verify: the sizes of level 0 (tvpal_reader_sizes opens every
 * shard's header and index): the bytes of each stored axis, then those of
 * every file of the dataset (what it takes on disk), then its chunks by
 * decoder table format.  Returns the exit status: a dataset that does not
 * open is bad input (2). */
static int print_axis_bytes(struct tvpal_reader *r)
{
    const struct tvpal_info *in = tvpal_reader_info(r);
    struct tvpal_sizes z;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_reader_sizes(r, 0, &z, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return rc == TVPAL_E_NOMEM ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE;
    }
    const double vts = (double)in->dims[0] * in->dims[1] * in->dims[2] *
                       in->steps;
    const double src = vts * in->source_value_bytes;
    uint64_t f32 = 0, u16 = 0;
    for (unsigned a = 0; a < 3; a++) {
        f32 += z.chunks_f32[a];
        u16 += z.chunks_u16[a];
        if (z.axis_bytes[a])
            printf("axis_%c_bytes = %llu  (%.4f bits per voxel-timestep, "
                   "axis_ratio %.3f)\n", "xyz"[a],
                   (unsigned long long)z.axis_bytes[a],
                   8.0 * (double)z.axis_bytes[a] / vts,
                   src / (double)z.axis_bytes[a]);
    }
    printf("disk_bytes = %llu  (%.4f bits per voxel-timestep, ratio %.3f: "
           "every file%s)\n", (unsigned long long)z.disk_bytes,
           8.0 * (double)z.disk_bytes / vts, src / (double)z.disk_bytes,
           in->levels ? ", levels included" : "");
    const uint64_t all = f32 + u16;
    printf("tables_u16 = %llu  (chunks with 16-bit decoder tables, all "
           "axes: %.1f%%)\n", (unsigned long long)u16,
           all ? 100.0 * (double)u16 / (double)all : 0.0);
    printf("tables_f32 = %llu  (chunks with float32 decoder tables)\n",
           (unsigned long long)f32);
    struct tvpal_coding c;
    rc = tvpal_reader_coding(r, 0, &c, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return rc == TVPAL_E_NOMEM ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE;
    }
    uint64_t n = 0, nc = 0, cb = 0, pb = 0;
    for (unsigned a = 0; a < 3; a++) {
        n += c.chunks[a];
        nc += c.chunks_coded[a];
        cb += c.coded_bytes[a];
        pb += c.coded_plain_bytes[a];
    }
    printf("chunks_coded = %llu  (zstd frames, FORMAT.md 6.11: %.1f%% of the "
           "chunks, %llu bytes for %llu inflated: %.1f%%)\n",
           (unsigned long long)nc, n ? 100.0 * (double)nc / (double)n : 0.0,
           (unsigned long long)cb, (unsigned long long)pb,
           pb ? 100.0 * (double)cb / (double)pb : 0.0);
    return print_level_bytes(r, z.disk_bytes, vts);
}

/* --histogram: the manifest's bins over [value_min, value_max], one line
 * each (bin, its value range, count, share of the counted values, a bar
 * scaled to the fullest bin), then a summary.  The counts are the
 * encoder's (approximate at bin edges: FORMAT.md 2.2). */
static void print_histogram(const char *dir, const struct tvpal_info *in)
{
    const unsigned bins = in->histogram_bins;
    const double lo = in->value_min, hi = in->value_max;
    const double w = (hi - lo) / bins;
    uint64_t total = 0, peak = 0;
    for (unsigned i = 0; i < bins; i++) {
        total += in->histogram[i];
        peak = in->histogram[i] > peak ? in->histogram[i] : peak;
    }
    printf("# histogram of %s: %u bins over [%.9g, %.9g] (the last includes "
           "its top)\n# bin lo hi count fraction bar\n", dir, bins, lo, hi);
    for (unsigned i = 0; i < bins; i++) {
        const uint64_t c = in->histogram[i];
        int bar = peak ? (int)(40.0 * (double)c / (double)peak + 0.5) : 0;
        bar = c && !bar ? 1 : bar;
        printf("%u %.9g %.9g %llu %.6f%s%.*s\n", i, lo + i * w,
               i + 1 == bins ? hi : lo + (i + 1) * w,
               (unsigned long long)c, total ? (double)c / (double)total : 0.0,
               bar ? " " : "", bar, "****************************************");
    }
    const double values = (double)in->dims[0] * in->dims[1] * in->dims[2] *
                          in->steps;
    printf("histogram: bins=%u count=%llu missing=%llu values=%.0f\n", bins,
           (unsigned long long)total, (unsigned long long)in->missing,
           values);
}

/* The manifest as it is on disk, and the axes it stores: the axes key is
 * absent for all three (FORMAT.md 2.2), so say them. */
static void print_manifest(const struct tvpal_info *in)
{
    fputs(in->manifest, stdout);
    char axes[4];   /* tvpal.h's axis bits are the manifest's */
    printf("stored_axes = %s\n", tvpal_axes_format(in->axes, axes));
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
    /* The manifest alone: --verify must name every damaged shard, and the
     * manifest is printed whatever the shards hold. */
    struct tvpal_reader *r = NULL;
    struct tvpal_diag d = {{0}};
    int rc = tvpal_reader_open_manifest(&r, o.dir, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return rc == TVPAL_E_NOMEM ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE;
    }
    const struct tvpal_info *in = tvpal_reader_info(r);
    status = TVPAL_EXIT_OK;
    if (o.histogram) {
        print_histogram(o.dir, in);
    } else {
        print_manifest(in);
        status = o.verify ? print_verify(r, o.dir) : print_axis_bytes(r);
    }
    tvpal_reader_close(r);
    return status;
}
