/* tvpal_comm.c: which communicator a process starts, and its end (see
 * tvpal_comm.h).  No MPI here: the MPI adapter is tvpal_comm_mpi.c. */
#include "tvpal_comm.h"

#include <stdlib.h>
#include <string.h>

/* Variables an MPI launcher sets in every process it starts. */
static const char *const launcher_vars[] = {
    "OMPI_COMM_WORLD_SIZE",   /* Open MPI mpirun / prterun */
    "PMIX_RANK",              /* PMIx: Open MPI 5, srun --mpi=pmix */
    "PMI_SIZE",               /* PMI-1/2: MPICH and Intel MPI Hydra, srun */
    "PMI_RANK",
    "MV2_COMM_WORLD_SIZE",    /* MVAPICH */
};

int tvpal_comm_launched(const char **launcher)
{
    const char *force = getenv("TVPAL_COMM");
    if (launcher)
        *launcher = NULL;
    if (force && !strcmp(force, "self"))
        return 0;
    if (force && !strcmp(force, "mpi")) {
        if (launcher)
            *launcher = "TVPAL_COMM";
        return 1;
    }
    for (size_t i = 0; i < sizeof launcher_vars / sizeof *launcher_vars; i++)
        if (getenv(launcher_vars[i])) {
            if (launcher)
                *launcher = launcher_vars[i];
            return 1;
        }
    return 0;
}

int tvpal_comm_open(struct tvpal_comm *c, enum tvpal_comm_kind kind,
                    int *argc, char ***argv, struct tvpal_diag *diag)
{
    if (kind == TVPAL_COMM_AUTO)
        kind = tvpal_comm_launched(NULL) ? TVPAL_COMM_MPI : TVPAL_COMM_SELF;
    if (kind == TVPAL_COMM_SELF) {
        tvpal_comm_self(c);
        return 0;
    }
    int rc = tvpal_comm_mpi_open(c, argc, argv, diag);
    if (rc < 0)
        tvpal_comm_self(c);   /* a later close or abort stays safe */
    return rc;
}

void tvpal_comm_close(struct tvpal_comm *c)
{
    if (c && c->finalize) {
        c->finalize(c);
        tvpal_comm_self(c);
    }
}
