/* tvpal_in_vti_none.c: the vti backend of a build without its library:
 * every use is refused with the package to install. */
#include "tvpal_input_impl.h"

#define WHY "this tvpal was built without VTK ImageData support (install the Debian " \
            "packages libexpat1-dev and zlib1g-dev and reconfigure)"

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

const struct tvpal_input_backend tvpal_input_vti = {
    "vti", none_open, none_read, none_close, none_describe};

/* Without expat no .pvd is recognised: the vti backend above refuses its
 * files, naming the packages. */
int tvpal_input_vtk_collection(const char *path, char ***files,
                               double **times, int *n,
                               struct tvpal_diag *diag)
{
    (void)path;
    (void)diag;
    *files = NULL;
    *times = NULL;
    *n = 0;
    return 0;
}
