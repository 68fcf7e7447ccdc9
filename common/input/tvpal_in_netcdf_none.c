/* tvpal_in_netcdf_none.c: the netcdf backend of a build without its library:
 * every use is refused with the package to install. */
#include "tvpal_input_impl.h"

const struct tvpal_input_backend tvpal_input_netcdf = {
    .name = "netcdf",
    .missing = "this tvpal was built without NetCDF support (install the Debian "
               "package libnetcdf-dev and reconfigure)"};

int tvpal_input_netcdf_plain_hdf5(const char *path)
{
    (void)path;
    return 0;
}
