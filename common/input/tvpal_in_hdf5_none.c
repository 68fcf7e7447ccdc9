/* tvpal_in_hdf5_none.c: the hdf5 backend of a build without its library:
 * every use is refused with the package to install. */
#include "tvpal_input_impl.h"

const struct tvpal_input_backend tvpal_input_hdf5 = {
    .name = "hdf5",
    .missing = "this tvpal was built without HDF5 support (install the Debian "
               "package libhdf5-dev and reconfigure)"};
