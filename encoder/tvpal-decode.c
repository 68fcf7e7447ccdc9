/* tvpal-decode: reconstructs one timestep of a tvpal dataset as raw
 * little-endian float32 (x fastest), from any of the three axes. */
#define _GNU_SOURCE
#include "tvpal_cli.h"
#include "tvpal_dataset.h"
#include "tvpal_format.h"
#include "tvpal_fs.h"

#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define PROG "tvpal-decode"

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " OUTDIR --step T [--axis x|y|z] -o FILE\n"
"Reconstruct timestep T (0-based) of the dataset OUTDIR as raw little-endian\n"
"float32, x fastest, decoded from the slices of one axis.\n"
"\n"
"  -t, --step T        timestep to decode, 0..steps-1 (required)\n"
"  -a, --axis A        axis whose slices are decoded: x, y or z (default z)\n"
"  -o, --output FILE   output file, written atomically; '-' for stdout\n"
"  -h, --help          this help\n"
"  -V, --version       version\n"
"\n"
"Exit status: 0 success, 1 failure (I/O), 2 bad input, usage or corrupt data.\n");
}

int main(int argc, char **argv)
{
    static const struct option lopts[] = {
        {"step", required_argument, 0, 't'},
        {"axis", required_argument, 0, 'a'},
        {"output", required_argument, 0, 'o'},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0}};
    const char *step_s = NULL, *out = NULL;
    int axis = 2, c;
    while ((c = getopt_long(argc, argv, "t:a:o:hV", lopts, NULL)) != -1) {
        switch (c) {
        case 't': step_s = optarg; break;
        case 'a':
            if ((axis = tvpal_parse_axis(optarg)) < 0) {
                fprintf(stderr, PROG ": --axis \"%s\": expected x, y or z\n",
                        optarg);
                return TVPAL_EXIT_USAGE;
            }
            break;
        case 'o': out = optarg; break;
        case 'h': usage(stdout); return 0;
        case 'V': printf(PROG " " PACKAGE_VERSION "\n"); return 0;
        default:
            fprintf(stderr, "Try '" PROG " --help'.\n");
            return TVPAL_EXIT_USAGE;
        }
    }
    if (optind != argc - 1 || !step_s || !out) {
        fprintf(stderr, PROG ": expected OUTDIR, --step T and -o FILE "
                "(try --help)\n");
        return TVPAL_EXIT_USAGE;
    }
    const char *dir = argv[optind];
    struct tvpal_diag diag = {{0}};
    struct tvpal_dataset *ds = NULL;
    struct tvpal_volreader *vr = NULL;
    float *vol = NULL;
    int rc = tvpal_dataset_open(&ds, dir, &diag);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", diag.msg[0] ? diag.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_USAGE;
    }
    uint32_t t;
    if (tvpal_parse_u32(step_s, 0, ds->m.steps - 1, &t) < 0) {
        fprintf(stderr, PROG ": --step \"%s\": expected 0..%u for %s\n",
                step_s, ds->m.steps - 1, dir);
        tvpal_dataset_close(ds);
        return TVPAL_EXIT_USAGE;
    }
    size_t nvox = (size_t)ds->m.dims[0] * ds->m.dims[1] * ds->m.dims[2];
    int status = TVPAL_EXIT_OK;
    vol = malloc(nvox * sizeof *vol);
    if (!vol || tvpal_volreader_create(&vr, ds, (unsigned)axis) < 0) {
        fprintf(stderr, PROG ": out of memory\n");
        status = TVPAL_EXIT_FAIL;
        goto out;
    }
    rc = tvpal_volreader_read(vr, t, vol, &diag);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", diag.msg);
        /* A failing device is a failure (1); corrupt data is bad input. */
        status = rc == TVPAL_E_READ ? TVPAL_EXIT_FAIL : TVPAL_EXIT_USAGE;
        goto out;
    }
    unsigned char *bytes = (unsigned char *)vol; /* convert in place */
    tvpal_store_f32le(vol, bytes, nvox);
    if (!strcmp(out, "-")) {
        if (fwrite(bytes, 4, nvox, stdout) != nvox || fflush(stdout)) {
            fprintf(stderr, PROG ": stdout: write error\n");
            status = TVPAL_EXIT_FAIL;
        }
    } else if (tvpal_write_file_atomic(out, bytes, nvox * 4) < 0) {
        fprintf(stderr, PROG ": %s: cannot write: %s\n", out, strerror(errno));
        status = TVPAL_EXIT_FAIL;
    }
out:
    tvpal_volreader_free(vr);
    tvpal_dataset_close(ds);
    free(vol);
    return status;
}
