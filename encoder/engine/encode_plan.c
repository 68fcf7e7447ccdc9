/* encode_plan.c: passes over boxes of the volume under a memory limit (see
 * encode_plan.h). */
#include "encode_plan.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <sys/resource.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Voxels of one slice of axis a. */
static uint64_t slice_voxels(const uint32_t dims[3], unsigned a)
{
    return (uint64_t)dims[(a + 1) % 3] * dims[(a + 2) % 3];
}

/* The slices a pass of axis a holds at the least: one, or a palette
 * group (within the axis). */
static uint64_t unit_slices(const struct encode_job *j, unsigned a)
{
    const uint32_t G = j->group[a] > 1 ? j->group[a] : 1;
    return G < j->dims[a] ? G : j->dims[a];
}

/* The palette groups the slab of axis a meets (1 slice each without). */
static uint32_t slab_groups(const struct encode_job *j, unsigned a)
{
    const uint32_t G = (uint32_t)unit_slices(j, a);
    return (j->slab_lo[a] + j->slab_n[a] - 1) / G - j->slab_lo[a] / G + 1;
}

/* stats: the pass's box goes into the statistics (its axis's slabs
 * partition the part once). */
static void add_pass(struct encode_plan *p, const struct encode_job *j,
                     unsigned axis, uint32_t s, uint32_t k, int stats)
{
    struct encode_pass *ps = &p->pass[p->npasses++];
    memset(ps, 0, sizeof *ps);
    memcpy(ps->box.n, j->dims, sizeof ps->box.n);
    ps->box.lo[axis] = s;
    ps->box.n[axis] = k;
    ps->axes = 1u << axis;
    ps->s0[axis] = s;
    ps->s1[axis] = s + k;
    ps->stats = stats;
}

int encode_plan_make(const struct encode_job *j, struct encode_plan *p)
{
    memset(p, 0, sizeof *p);
    const uint64_t bpv = j->box_bytes_per_voxel;
    const uint64_t nvox = (uint64_t)j->dims[0] * j->dims[1] * j->dims[2];
    /* The least a pass holds: one slice, or one palette group. */
    uint64_t most_slice = 0;
    for (unsigned a = 0; a < 3; a++)
        if ((j->axes & (1u << a)) && j->slab_n[a] &&
            unit_slices(j, a) * slice_voxels(j->dims, a) > most_slice)
            most_slice = unit_slices(j, a) * slice_voxels(j->dims, a);
    p->min_limit = j->fixed + most_slice * bpv;
    const int whole = j->slab_n[0] == j->dims[0] &&
                      j->slab_n[1] == j->dims[1] && j->slab_n[2] == j->dims[2];
    /* One pass when the whole ring fits (and the part is the whole). */
    if (!j->split && whole && j->fixed + nvox * bpv <= j->limit) {
        if (!(p->pass = calloc(1, sizeof *p->pass)))
            return TVPAL_E_NOMEM;
        struct encode_pass *ps = &p->pass[0];
        memcpy(ps->box.n, j->dims, sizeof ps->box.n);
        ps->axes = j->axes;
        for (unsigned a = 0; a < 3; a++)
            ps->s1[a] = j->dims[a];
        ps->stats = 1;
        p->npasses = 1;
        p->peak = j->fixed + nvox * bpv;
        p->box_voxels_max = nvox;
        p->voxels_read = nvox * j->T;
        return 0;
    }
    if (j->limit < p->min_limit)
        return TVPAL_E_RANGE;
    /* Groups per pass of each axis (the slab's groups: whole ones, and
     * the parts of those it cuts), then as equal passes as that allows. */
    uint32_t passes[3] = {0};
    uint64_t total = 0;
    for (unsigned a = 0; a < 3; a++) {
        if (!j->slab_n[a] || !(j->axes & (1u << a)))
            continue;
        const uint64_t G = unit_slices(j, a);
        uint64_t per = (j->limit - j->fixed) /
                       (G * slice_voxels(j->dims, a) * bpv);
        const uint32_t ng = slab_groups(j, a);
        if (per > ng)
            per = ng;
        passes[a] = (uint32_t)((ng + per - 1) / per);
        total += passes[a];
    }
    if (!(p->pass = calloc(total ? total : 1, sizeof *p->pass)))
        return TVPAL_E_NOMEM;
    /* z first, its slabs (contiguous in the file) taking the statistics;
     * without z, the first axis encoded of y, x takes them. */
    static const unsigned order[3] = {2, 1, 0};
    int stats_axis = -1;
    for (unsigned i = 0; i < 3; i++) {
        const unsigned a = order[i];
        const uint32_t n = j->slab_n[a], P = passes[a];
        p->per_axis[a] = P;
        if (P && stats_axis < 0)
            stats_axis = (int)a;
        const uint32_t G = (uint32_t)unit_slices(j, a), ng = slab_groups(j, a),
                       g0 = j->slab_lo[a] / G, lo = j->slab_lo[a],
                       hi = lo + n;
        for (uint32_t q = 0; q < P; q++) {
            /* Groups g0 + first .. g0 + first + count - 1, within the slab. */
            const uint32_t first = q * (ng / P) + (q < ng % P ? q : ng % P);
            const uint32_t count = ng / P + (q < ng % P);
            uint32_t s = (g0 + first) * G, e = (g0 + first + count) * G;
            s = s > lo ? s : lo;
            e = e < hi ? e : hi;
            add_pass(p, j, a, s, e - s, stats_axis == (int)a);
            const struct encode_box *b = &p->pass[p->npasses - 1].box;
            uint64_t v = encode_box_voxels(b);
            if (v > p->box_voxels_max)
                p->box_voxels_max = v;
            /* Read per plane: from the box's first voxel to its last. */
            p->voxels_read += (uint64_t)b->n[2] *
                              ((uint64_t)(b->n[1] - 1) * j->dims[0] + b->n[0]) *
                              j->T;
        }
    }
    p->peak = j->fixed + p->box_voxels_max * bpv;
    return 0;
}

void encode_plan_free(struct encode_plan *p)
{
    free(p->pass);
    p->pass = NULL;
    p->npasses = 0;
}

void encode_plan_describe(const struct encode_plan *p, char *buf, size_t cap)
{
    if (p->npasses == 1 && p->pass[0].axes == 7) {
        snprintf(buf, cap, "1 pass (all axes from one ring)");
        return;
    }
    if (p->npasses == 1 && p->per_axis[0] + p->per_axis[1] +
                               p->per_axis[2] == 0) {
        char names[4], *q = names;
        for (unsigned a = 0; a < 3; a++)
            if (p->pass[0].axes & (1u << a))
                *q++ = "xyz"[a];
        *q = 0;
        snprintf(buf, cap, "1 pass (axes %s from one ring)", names);
        return;
    }
    size_t n = (size_t)snprintf(buf, cap, "%u pass%s (", p->npasses,
                                p->npasses == 1 ? "" : "es");
    const char *sep = "";
    for (unsigned a = 0; a < 3 && n < cap; a++)
        if (p->per_axis[a]) {
            n += (size_t)snprintf(buf + n, cap - n, "%s%c %u", sep, "xyz"[a],
                                  p->per_axis[a]);
            sep = ", ";
        }
    if (n < cap)
        snprintf(buf + n, cap - n, ")");
}

void encode_plan_key(const struct encode_plan *p, char *buf, size_t cap)
{
    size_t n = (size_t)snprintf(buf, cap, "plan=%u", p->npasses);
    for (unsigned a = 0; a < 3 && n < cap; a++)
        n += (size_t)snprintf(buf + n, cap - n, ":%u", p->per_axis[a]);
}

int encode_parse_size(const char *s, uint64_t *bytes)
{
    char *end;
    if (!s || !isdigit((unsigned char)*s))
        return TVPAL_E_INVAL;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || !isfinite(v))
        return TVPAL_E_INVAL;
    double mul = 1;
    switch (toupper((unsigned char)*end)) {
    case 'K': mul = 1024.0; end++; break;
    case 'M': mul = 1024.0 * 1024; end++; break;
    case 'G': mul = 1024.0 * 1024 * 1024; end++; break;
    case 'T': mul = 1024.0 * 1024 * 1024 * 1024; end++; break;
    default: break;
    }
    if (mul > 1 && (!strcmp(end, "iB") || !strcmp(end, "B")))
        end += strlen(end);
    else if (mul == 1 && !strcmp(end, "B"))
        end++;
    if (*end || v * mul >= 18446744073709551615.0 || v * mul < 1)
        return TVPAL_E_INVAL;
    *bytes = (uint64_t)(v * mul);
    return 0;
}

/* A cgroup memory limit in bytes, or 0 when there is none ("max"). */
static uint64_t cgroup_limit(const char **which)
{
    static const char *const files[] = {
        "/sys/fs/cgroup/memory.max",                    /* v2 */
        "/sys/fs/cgroup/memory/memory.limit_in_bytes"}; /* v1 */
    for (unsigned i = 0; i < 2; i++) {
        FILE *f = fopen(files[i], "r");
        char line[64];
        if (!f)
            continue;
        int ok = fgets(line, sizeof line, f) != NULL;
        fclose(f);
        unsigned long long v;
        if (ok && sscanf(line, "%llu", &v) == 1 && v < (1ull << 60)) {
            *which = i == 0 ? "cgroup memory.max" : "cgroup memory limit";
            return v;
        }
    }
    return 0;
}

/* The address space this process may still take under its limit (ulimit
 * -v, RLIMIT_AS): the limit less what it holds now (the size in
 * /proc/self/statm: code, libraries, thread stacks); 0 when unlimited. */
static uint64_t address_space_left(void)
{
    struct rlimit rl;
    if (getrlimit(RLIMIT_AS, &rl) < 0 || rl.rlim_cur == RLIM_INFINITY)
        return 0;
    unsigned long long pages = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%llu", &pages) != 1)
            pages = 0;
        fclose(f);
    }
    const uint64_t held = (uint64_t)pages * (uint64_t)sysconf(_SC_PAGESIZE);
    return (uint64_t)rl.rlim_cur > held ? (uint64_t)rl.rlim_cur - held : 1;
}

uint64_t encode_default_limit(unsigned local_ranks, char *why, size_t cap)
{
    long pages = sysconf(_SC_PHYS_PAGES), psize = sysconf(_SC_PAGESIZE);
    uint64_t phys = pages > 0 && psize > 0 ? (uint64_t)pages * (uint64_t)psize
                                           : (uint64_t)4 << 30;
    const char *which = "physical memory";
    uint64_t cg = cgroup_limit(&which), base = phys;
    if (cg && cg < phys)
        base = cg;
    else
        which = "physical memory";
    if (local_ranks < 1)
        local_ranks = 1;
    uint64_t lim = base / 4 * 3 / local_ranks;
    if (local_ranks > 1)
        snprintf(why, cap, "3/4 of %s (%.1f GiB) shared by %u ranks", which,
                 (double)base / (1u << 30), local_ranks);
    else
        snprintf(why, cap, "3/4 of %s (%.1f GiB)", which,
                 (double)base / (1u << 30));
    /* A process's own address-space limit counts too (it was ignored: a
     * job under ulimit -v planned for the machine and ran out of memory
     * halfway). */
    const uint64_t as = address_space_left();
    if (as && as / 4 * 3 < lim) {
        lim = as / 4 * 3;
        snprintf(why, cap, "3/4 of the address space left under ulimit -v "
                 "(%.3f GiB)", (double)as / (1u << 30));
    }
    return lim;
}
