/* tvpal_in_hdf5_none.c: the hdf5 backend of a build without its library:
 * every use is refused with the package to install. */
#include "tvpal_input_impl.h"

#define WHY "this tvpal was built without HDF5 support (install the Debian " \
            "package libhdf5-dev and reconfigure)"

static int none_open(struct tvpal_input_file **out, const char *path,
                     const struct tvpal_input_opts *opts,
                     struct tvpal_input_info *info, double **times,
                     struct tvpal_diag *diag)
{
    return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: " WHY, path);
}

static int none_read(struct tvpal_input_file *f, uint32_t k, float *dst,
                     struct tvpal_diag *diag)
{
    return tvpal_diag_set(diag, TVPAL_E_SYS, WHY);
}

static void none_close(struct tvpal_input_file *f)
{
}

static int none_describe(const char *path, char **text,
                         struct tvpal_diag *diag)
{
    return tvpal_diag_set(diag, TVPAL_E_SYS, "%s: " WHY, path);
}

const struct tvpal_input_backend tvpal_input_hdf5 = {
    "hdf5", none_open, none_read, none_close, none_describe};
