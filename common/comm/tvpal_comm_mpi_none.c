/* tvpal_comm_mpi_none.c: the MPI communicator of a build without MPI. */
#include "tvpal_comm.h"

int tvpal_comm_mpi_open(struct tvpal_comm *c, int *argc, char ***argv,
                        struct tvpal_diag *diag)
{
    (void)c, (void)argc, (void)argv;
    return tvpal_diag_set(diag, TVPAL_E_SYS, "this tvpal was built without "
                          "MPI (install the Debian package libopenmpi-dev "
                          "and rebuild)");
}

int tvpal_comm_mpi_built(void)
{
    return 0;
}
