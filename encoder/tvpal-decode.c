/* tvpal-decode: reconstructs one timestep of a tvpal dataset (or of one of
 * its coarser levels) as raw little-endian float32 (x fastest), from any
 * axis the dataset stores.  A driver of libtvpal's reader (tvpal.h).
 *
 * The steps of main: parse and check the options, open the dataset, check
 * --step, --axis and --level against it, decode the step, write it
 * (atomically, or to stdout). */
#define _GNU_SOURCE
#include "tvpal.h"
#include "tvpal_cli.h"
#include "tvpal_format.h"   /* tvpal_store_f32le: the output's byte order */
#include "tvpal_fs.h"

#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define PROG "tvpal-decode"

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " OUTDIR --step T [--axis x|y|z] [--level K] -o FILE\n"
"Reconstruct timestep T (0-based) of the dataset OUTDIR as raw little-endian\n"
"float32, x fastest, decoded from the slices of one axis.\n"
"\n"
"  -t, --step T        timestep to decode, 0..steps-1 (required)\n"
"  -a, --axis A        axis whose slices are decoded: x, y or z, one the\n"
"                      dataset stores (default: z, else y, else x)\n"
"  -l, --level K       a coarser level of detail (tvpal-encode --levels):\n"
"                      its dims are ceil(dims / 2^K); default 0\n"
"  -o, --output FILE   output file, written atomically; '-' for stdout\n"
"  -h, --help          this help\n"
"  -V, --version       version\n"
"\n"
"Exit status: 0 success, 1 failure (I/O), 2 bad input, usage or corrupt data.\n");
}

struct options {
    const char *dir;      /* OUTDIR */
    const char *step_s;   /* --step as given: its range is the dataset's */
    const char *out;      /* -o FILE; "-" is stdout */
    int axis;             /* 0..2, or -1: the dataset's default */
    const char *level_s;  /* --level as given, or NULL */
};

static const struct option long_options[] = {
    {"step", required_argument, 0, 't'},
    {"axis", required_argument, 0, 'a'},
    {"level", required_argument, 0, 'l'},
    {"output", required_argument, 0, 'o'},
    {"help", no_argument, 0, 'h'},
    {"version", no_argument, 0, 'V'},
    {0, 0, 0, 0}};
static const char short_options[] = "t:a:l:o:hV";

/* Fills o from argv and checks that OUTDIR, --step and -o are there.
 * Returns -1 to go on, or the exit status when the program is done: --help,
 * --version or a usage error (message printed). */
static int parse_options(int argc, char **argv, struct options *o)
{
    int c;
    *o = (struct options){.axis = -1};
    while ((c = getopt_long(argc, argv, short_options, long_options, NULL)) != -1) {
        switch (c) {
        case 't': o->step_s = optarg; break;
        case 'a':
            if ((o->axis = tvpal_parse_axis(optarg)) < 0) {
                fprintf(stderr, PROG ": --axis \"%s\": expected x, y or z\n",
                        optarg);
                return TVPAL_EXIT_USAGE;
            }
            break;
        case 'l': o->level_s = optarg; break;
        case 'o': o->out = optarg; break;
        case 'h': usage(stdout); return TVPAL_EXIT_OK;
        case 'V': printf(PROG " " PACKAGE_VERSION "\n"); return TVPAL_EXIT_OK;
        default:
            fprintf(stderr, "Try '" PROG " --help'.\n");
            return TVPAL_EXIT_USAGE;
        }
    }
    if (optind != argc - 1 || !o->step_s || !o->out) {
        fprintf(stderr, PROG ": expected OUTDIR, --step T and -o FILE "
                "(try --help)\n");
        return TVPAL_EXIT_USAGE;
    }
    o->dir = argv[optind];
    return -1;
}

/* --step, --axis and --level against the dataset: the step t, the axis
 * as tvpal_reader_decode takes it (0: the default) and the level.
 * Returns 0 or TVPAL_EXIT_USAGE (printed). */
static int choose(const struct options *o, const struct tvpal_info *in,
                  uint32_t *t, unsigned *axis, uint32_t *level)
{
    char axes[4];
    if (tvpal_parse_u32(o->step_s, 0, in->steps - 1, t) < 0) {
        fprintf(stderr, PROG ": --step \"%s\": expected 0..%u for %s\n",
                o->step_s, in->steps - 1, o->dir);
        return TVPAL_EXIT_USAGE;
    }
    *level = 0;
    if (o->level_s && tvpal_parse_u32(o->level_s, 0, in->levels, level) < 0) {
        fprintf(stderr, PROG ": --level \"%s\": expected 0..%u for %s (%s)\n",
                o->level_s, in->levels, o->dir,
                in->levels ? "its coarser levels" : "it has no coarser levels");
        return TVPAL_EXIT_USAGE;
    }
    *axis = 0;
    if (o->axis < 0)
        return 0;
    if (!(in->axes & (1u << o->axis))) {
        fprintf(stderr, PROG ": --axis %c: %s stores axes %s only\n",
                "xyz"[o->axis], o->dir, tvpal_axes_format(in->axes, axes));
        return TVPAL_EXIT_USAGE;
    }
    *axis = 1u << o->axis;    /* TVPAL_AXIS_X, _Y, _Z */
    return 0;
}

/* A library error: the diag when the function filled it, else the code's
 * text (the library promises nothing about errno). */
static void print_lib_error(int rc, const struct tvpal_diag *diag)
{
    fprintf(stderr, PROG ": %s\n", diag->msg[0] ? diag->msg : tvpal_strerror(rc));
}

/* Writes the nvox little-endian floats at bytes to out ("-": stdout).
 * Returns 0 or TVPAL_EXIT_FAIL (printed). */
static int write_output(const char *out, const unsigned char *bytes, size_t nvox)
{
    if (!strcmp(out, "-")) {
        if (fwrite(bytes, 4, nvox, stdout) != nvox || fflush(stdout)) {
            fprintf(stderr, PROG ": stdout: write error\n");
            return TVPAL_EXIT_FAIL;
        }
        return 0;
    }
    struct tvpal_diag d = {{0}};
    int rc = tvpal_write_file_atomic(out, bytes, nvox * 4, &d);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", d.msg[0] ? d.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_FAIL;
    }
    return 0;
}

int main(int argc, char **argv)
{
    struct options o;
    int status = parse_options(argc, argv, &o);
    if (status >= 0)
        return status;
    struct tvpal_diag diag = {{0}};
    struct tvpal_reader *rd = NULL;
    /* Never over the dataset itself, a device node or a link. */
    if (strcmp(o.out, "-") && tvpal_path_inside(o.out, o.dir)) {
        fprintf(stderr, PROG ": %s: inside the dataset %s; write it "
                "elsewhere\n", o.out, o.dir);
        return TVPAL_EXIT_USAGE;
    }
    if (strcmp(o.out, "-") && tvpal_out_check(o.out, &diag) < 0) {
        fprintf(stderr, PROG ": %s\n", diag.msg);
        return TVPAL_EXIT_USAGE;
    }
    int rc = tvpal_reader_open(&rd, o.dir, &diag);
    if (rc < 0) {
        print_lib_error(rc, &diag);
        return rc == TVPAL_E_NOMEM ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE;
    }
    uint32_t t = 0, level = 0, d[3];
    unsigned axis = 0;
    float *vol = NULL;
    size_t nvox = 0;
    status = choose(&o, tvpal_reader_info(rd), &t, &axis, &level);
    if (status == 0) {
        tvpal_reader_level_dims(rd, level, d);
        nvox = (size_t)d[0] * d[1] * d[2];
        if (!(vol = malloc(nvox * sizeof *vol))) {
            fprintf(stderr, PROG ": out of memory\n");
            status = TVPAL_EXIT_FAIL;
        }
    }
    /* A failing device is a failure (1), corrupt data bad input (2). */
    if (status == 0 && (rc = tvpal_reader_decode(rd, t, axis, level, vol,
                                                 &diag)) < 0) {
        print_lib_error(rc, &diag);
        status = rc == TVPAL_E_READ || rc == TVPAL_E_NOMEM ? TVPAL_EXIT_FAIL
                                                          : TVPAL_EXIT_USAGE;
    }
    if (status == 0) {
        unsigned char *bytes = (unsigned char *)vol; /* convert in place */
        tvpal_store_f32le(vol, bytes, nvox);
        status = write_output(o.out, bytes, nvox);
    }
    tvpal_reader_close(rd);
    free(vol);
    return status;
}
