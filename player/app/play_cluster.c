/* play_cluster.c: see play_cluster.h. */
#define _GNU_SOURCE
#include "play_cluster.h"
#include "tvpal_fs.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG "tvpal-play"

struct tvpal_comm play_comm;

void play_cluster_start(int *argc, char ***argv)
{
    struct tvpal_diag d = {{0}};
    if (tvpal_comm_open(&play_comm, TVPAL_COMM_AUTO, argc, argv, &d) < 0) {
        fprintf(stderr, PROG ": cannot initialize MPI: %s\n", d.msg);
        exit(1);
    }
}

void play_cluster_end(void)
{
    tvpal_comm_close(&play_comm);
}

int play_cluster_multi(void)
{
    return play_comm.size > 1;
}

int play_cluster_mpi(void)
{
    return play_comm.name && !strcmp(play_comm.name, "mpi");
}

void play_die(int code, const char *fmt, ...)
{
    if (play_comm.rank == 0) {
        va_list ap;
        va_start(ap, fmt);
        fputs(PROG ": ", stderr);
        vfprintf(stderr, fmt, ap);
        fputc('\n', stderr);
        va_end(ap);
    }
    play_cluster_end();
    exit(code);
}

void play_die_rank(int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    if (play_cluster_multi())
        fprintf(stderr, PROG ": rank %d: ", play_comm.rank);
    else
        fputs(PROG ": ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    if (play_cluster_multi())
        play_comm.abort(&play_comm, code);
    exit(code);
}

/* One rank's result of a step that may fail on some ranks only. */
struct rank_status {
    int rc;
    char msg[244];
};

void play_check_all(int rc, const char *msg, int code)
{
    struct rank_status mine = {.rc = rc}, *all = NULL;
    snprintf(mine.msg, sizeof mine.msg, "%s", msg);
    if (!play_cluster_multi()) {
        if (rc < 0)
            play_die(code, "%s", msg);
        return;
    }
    if (play_comm.rank == 0 &&
        !(all = calloc((size_t)play_comm.size, sizeof *all)))
        play_die_rank(1, "out of memory");
    if (play_comm.gather(&play_comm, &mine, sizeof mine, all) < 0)
        play_die_rank(1, "MPI gather failed");
    double bad = rc < 0;
    play_comm.allmax(&play_comm, &bad, 1);
    if (play_comm.rank == 0)
        for (int r = 0; r < play_comm.size; r++)
            if (all[r].rc < 0)
                fprintf(stderr, PROG ": rank %d: %s\n", r, all[r].msg);
    free(all);
    if (bad > 0) {
        play_cluster_end();
        exit(code);
    }
}

char *play_shard_dir(const char *dir, const char *pattern, int rank)
{
    return tvpal_node_dir(dir, pattern, (uint32_t)rank);
}
