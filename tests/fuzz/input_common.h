/* input_common.h: the body of the input-reader harnesses (vti, vtk,
 * netcdf, hdf5): the input is written to a temporary file named name and
 * read as format fmt: tvpal_input_detect, tvpal_input_open (VTK: also with
 * magnitude, arrays of several components read as their length), the grid
 * and times it reports (check_grid), the first steps and a box of each
 * (when a step is at most 2^20 voxels), tvpal_input_describe. */
#ifndef TVPAL_FUZZ_INPUT_COMMON_H
#define TVPAL_FUZZ_INPUT_COMMON_H
#include "fuzz_util.h"
#include "tvpal_input.h"
#include "tvpal_manifest.h"
#include "tvpal_size.h"

#include <stdlib.h>
#include <string.h>

static void read_steps(struct tvpal_input *in)
{
    const struct tvpal_input_info *info = tvpal_input_info(in);
    uint64_t n = (uint64_t)info->dims[0] * info->dims[1] * info->dims[2];
    if (n == 0 || n > (1u << 20))
        return;
    float *v = malloc((size_t)n * sizeof *v);
    if (!v)
        abort();
    struct tvpal_diag d;
    const uint32_t lo[3] = {info->dims[0] / 4, info->dims[1] / 4,
                            info->dims[2] / 4};
    const uint32_t bn[3] = {(info->dims[0] + 1) / 2, (info->dims[1] + 1) / 2,
                            (info->dims[2] + 1) / 2};
    for (uint32_t t = 0; t < info->steps && t < 3; t++) {
        (void)tvpal_input_read(in, t, v, &d);
        (void)tvpal_input_read_box(in, t, lo, bn, v, &d);
        (void)tvpal_input_time(in, t);
    }
    free(v);
}

/* What a reader accepts, a dataset must be able to hold: points that can
 * be addressed, and a grid and times by the manifest reader's rule
 * (tvpal_manifest_check_grid).  A reader that lets through what the
 * encoder would write and then fail to read back aborts here. */
static void check_grid(struct tvpal_input *in)
{
    const struct tvpal_input_info *info = tvpal_input_info(in);
    size_t n;
    if (tvpal_points(info->dims, sizeof(double), &n) < 0)
        abort();
    if (tvpal_manifest_check_grid(info->spacing, info->origin, NULL, 0,
                                  NULL) < 0)
        abort();
    for (uint32_t t = 0; info->has_times && t < info->steps && t < 65536;
         t++)
        if (!tvpal_manifest_number_ok(tvpal_input_time(in, t)))
            abort();
}

/* Opens files[0..nfiles) as format fmt, checks its grid and reads its
 * first steps. */
static void open_and_read(char **files, int nfiles,
                          enum tvpal_input_format fmt)
{
    struct tvpal_diag d;
    struct tvpal_input *in;
    const struct tvpal_input_opts mag = {.magnitude = 1};
    const int vtk = fmt == TVPAL_IN_VTI || fmt == TVPAL_IN_VTK;
    for (int k = 0; k < 1 + vtk; k++)
        if (tvpal_input_open(&in, fmt, files, nfiles, k ? &mag : NULL,
                             &d) == 0) {
            check_grid(in);
            read_steps(in);
            tvpal_input_close(in);
        }
}

static int fuzz_input(const uint8_t *data, size_t size,
                      enum tvpal_input_format fmt, const char *name)
{
    char *path = strdup(fuzz_write(name, data, size));
    if (!path)
        abort();
    struct tvpal_diag d;
    enum tvpal_input_format f;
    (void)tvpal_input_detect(path, NULL, &f, &d);
    open_and_read(&path, 1, fmt);
    char *text = NULL;
    if (tvpal_input_describe(path, fmt, &text, &d) == 0)
        free(text);
    free(path);
    return 0;
}
#endif
