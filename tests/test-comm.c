/* test-comm: which communicator a process starts: the MPI launchers'
 * variables are recognised (Open MPI, PMIx, PMI, MVAPICH), TVPAL_COMM
 * overrides them, a process started by none gets the one-process
 * communicator, and closing it (twice, or a zeroed one) is safe.  A build
 * without MPI refuses MPI with a message that says what to install.  (The
 * MPI communicator itself runs under mpirun in tests/cluster.sh.) */
#include "tvpal_comm.h"
#include "tvpal_test.h"

#include <stdlib.h>
#include <string.h>

static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK",
                                   "PMI_SIZE", "PMI_RANK",
                                   "MV2_COMM_WORLD_SIZE", "TVPAL_COMM"};

static void clear_env(void)
{
    for (size_t i = 0; i < sizeof vars / sizeof *vars; i++)
        unsetenv(vars[i]);
}

int main(int argc, char **argv)
{
    const char *who;
    clear_env();
    CHECK(tvpal_comm_launched(&who) == 0 && who == NULL,
          "no launcher variable: not launched");
    for (size_t i = 0; i + 1 < sizeof vars / sizeof *vars; i++) {
        clear_env();
        setenv(vars[i], "2", 1);
        CHECK(tvpal_comm_launched(&who) == 1 && who && !strcmp(who, vars[i]),
              "%s: launched, named", vars[i]);
        setenv("TVPAL_COMM", "self", 1);
        CHECK(tvpal_comm_launched(NULL) == 0, "%s: TVPAL_COMM=self wins",
              vars[i]);
    }
    clear_env();
    setenv("TVPAL_COMM", "mpi", 1);
    CHECK(tvpal_comm_launched(&who) == 1 && !strcmp(who, "TVPAL_COMM"),
          "TVPAL_COMM=mpi forces MPI");

    clear_env();
    struct tvpal_comm c;
    struct tvpal_diag d = {{0}};
    CHECK(tvpal_comm_open(&c, TVPAL_COMM_AUTO, &argc, &argv, &d) == 0,
          "auto without a launcher: %s", d.msg);
    CHECK(c.size == 1 && c.rank == 0 && !strcmp(c.name, "self"),
          "one process: size %d rank %d %s", c.size, c.rank, c.name);
    double v[2] = {3, -1};
    CHECK(c.allmax(&c, v, 2) == 0 && v[0] == 3 && v[1] == -1, "allmax of one");
    tvpal_comm_close(&c);
    tvpal_comm_close(&c);
    struct tvpal_comm z;
    memset(&z, 0, sizeof z);
    tvpal_comm_close(&z);
    CHECK(c.size == 1, "closed self is still one process");
#ifndef HAVE_MPI
    d.msg[0] = 0;
    CHECK(tvpal_comm_open(&c, TVPAL_COMM_MPI, &argc, &argv, &d) == TVPAL_E_SYS,
          "MPI without MPI built");
    CHECK(strstr(d.msg, "libopenmpi-dev") != NULL, "names the package: %s",
          d.msg);
    CHECK(c.size == 1 && !strcmp(c.name, "self"), "left as one process");
#endif
    return tt_done("test-comm");
}
