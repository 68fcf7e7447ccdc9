/* tvpal_in_vti_none.c: the vti backend of a build without its library:
 * every use is refused with the package to install. */
#include "tvpal_input_impl.h"

const struct tvpal_input_backend tvpal_input_vti = {
    .name = "vti",
    .missing = "this tvpal was built without VTK ImageData support (install the Debian "
               "packages libexpat1-dev and zlib1g-dev and reconfigure)"};

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
