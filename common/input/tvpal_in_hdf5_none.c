/* tvpal_in_hdf5_none.c: the hdf5 backend of a build without its library:
 * every use is refused with the package to install. */
#include "tvpal_input_impl.h"

const struct tvpal_input_backend tvpal_input_hdf5 = {
    .name = "hdf5",
    .missing = "this tvpal was built without HDF5 support (install the Debian "
               "package libhdf5-dev and reconfigure)"};

int tvpal_input_hdf5_direct_open(struct tvpal_h5direct **out,
                                 const char *path, const char *dataset,
                                 struct tvpal_pool *pool)
{
    (void)path, (void)dataset, (void)pool;
    *out = NULL;
    return 0;
}

int tvpal_input_hdf5_direct_read(struct tvpal_h5direct *d, uint32_t k,
                                 float *dst, struct tvpal_diag *diag)
{
    (void)d, (void)k, (void)dst, (void)diag;
    return 1;
}

int tvpal_input_hdf5_direct_read_box(struct tvpal_h5direct *d, uint32_t k,
                                     const uint32_t lo[3], const uint32_t n[3],
                                     float *dst, struct tvpal_diag *diag)
{
    (void)d, (void)k, (void)lo, (void)n, (void)dst, (void)diag;
    return 1;
}

uint64_t tvpal_input_hdf5_direct_scratch(const struct tvpal_h5direct *d)
{
    (void)d;
    return 0;
}

void tvpal_input_hdf5_direct_close(struct tvpal_h5direct *d)
{
    (void)d;
}

uint64_t tvpal_input_hdf5_inflated(void)
{
    return 0;
}
