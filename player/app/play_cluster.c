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
    char msg[TVPAL_DIAG_MAX];
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

/* ---------------------------------------------------------- ghost rows */

enum { GHOST_HEAD = 16, GHOST_ROW = 256 * 4 };

static unsigned char *ghost_sbuf, *ghost_rbuf;
static size_t ghost_cap;

static void put_u32(unsigned char *b, uint32_t v)
{
    memcpy(b, &v, 4);
}

static uint32_t get_u32(const unsigned char *b)
{
    uint32_t v;
    memcpy(&v, b, 4);
    return v;
}

/* One side: mine out to peer, theirs in. */
static int ghost_swap(int peer, const struct tvpal_ghost_row *mine,
                      struct tvpal_ghost_row *theirs, size_t idx_bytes,
                      struct tvpal_diag *diag)
{
    const int has = mine->slice != UINT32_MAX;
    const int with_idx = has && mine->send_idx;
    put_u32(ghost_sbuf, mine->slice);
    put_u32(ghost_sbuf + 4, mine->gen);
    put_u32(ghost_sbuf + 8, (uint32_t)with_idx);
    put_u32(ghost_sbuf + 12, 0);
    size_t n = GHOST_HEAD;
    if (has) {
        memcpy(ghost_sbuf + n, mine->row, GHOST_ROW);
        n += GHOST_ROW;
    }
    if (with_idx) {
        memcpy(ghost_sbuf + n, mine->idx, idx_bytes);
        n += idx_bytes;
    }
    size_t got = 0;
    int rc = play_comm.sendrecv(&play_comm, peer, ghost_sbuf, n, ghost_rbuf,
                                ghost_cap, &got);
    if (rc < 0)
        return tvpal_diag_set(diag, rc, "ghost rows: exchange with rank %d "
                              "failed", peer);
    if (got < GHOST_HEAD)
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "ghost rows: %zu bytes "
                              "from rank %d", got, peer);
    uint32_t slice = get_u32(ghost_rbuf), gen = get_u32(ghost_rbuf + 4);
    uint32_t idx_in = get_u32(ghost_rbuf + 8);
    if (slice == UINT32_MAX)
        return 0;
    if (got != GHOST_HEAD + GHOST_ROW + (idx_in ? idx_bytes : 0))
        return tvpal_diag_set(diag, TVPAL_E_FORMAT, "ghost rows: %zu bytes "
                              "from rank %d for slice %u", got, peer, slice);
    memcpy(theirs->row, ghost_rbuf + GHOST_HEAD, GHOST_ROW);
    if (idx_in)
        memcpy(theirs->idx, ghost_rbuf + GHOST_HEAD + GHOST_ROW, idx_bytes);
    theirs->slice = slice;
    theirs->gen = gen;
    return 0;
}

int play_ghost_exchange(void *ctx, const struct tvpal_ghost_row mine[2],
                        struct tvpal_ghost_row theirs[2], size_t idx_bytes,
                        struct tvpal_diag *diag)
{
    (void)ctx;
    const size_t need = GHOST_HEAD + GHOST_ROW + idx_bytes;
    if (need > ghost_cap) {   /* grows once per dataset size, then stays */
        unsigned char *s = realloc(ghost_sbuf, need), *r;
        if (s)
            ghost_sbuf = s;
        r = s ? realloc(ghost_rbuf, need) : NULL;
        if (r)
            ghost_rbuf = r;
        if (!s || !r)
            return tvpal_diag_set(diag, TVPAL_E_NOMEM, "ghost row buffers");
        ghost_cap = need;
    }
    const int rank = play_comm.rank, size = play_comm.size;
    for (int phase = 0; phase < 2; phase++) {
        const int up = (rank % 2 == 0) == (phase == 0);  /* talk to r + 1 */
        const int peer = up ? rank + 1 : rank - 1;
        if (peer < 0 || peer >= size)
            continue;
        int rc = ghost_swap(peer, &mine[up], &theirs[up], idx_bytes, diag);
        if (rc < 0)
            return rc;
    }
    return 0;
}
