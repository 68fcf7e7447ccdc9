/* tvpal-report: accuracy and size of a tvpal dataset against its source.
 *
 * Per timestep and axis: RMSE, PSNR, max |error| and temporal flicker; per
 * axis and overall: the same plus compression ratio and bits per
 * voxel-timestep, always counting the decoder tables and every byte of the
 * shard files.  PSNR uses peak = max - min of the original over all
 * timesteps: PSNR = 10 log10(peak^2 / MSE).  Flicker at t >= 1 is
 * mean |(R[t] - R[t-1]) - (V[t] - V[t-1])| / peak: it exposes jumps at window
 * boundaries that a per-frame error hides.
 */
#define _GNU_SOURCE
#include "tvpal_cli.h"
#include "tvpal_dataset.h"
#include "tvpal_format.h"
#include "tvpal_raw.h"
#include "tvpal_schedule.h"

#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define PROG "tvpal-report"

static void usage(FILE *f)
{
    fprintf(f,
"Usage: " PROG " OUTDIR [--reference INPUT...] [--csv FILE] [--json FILE]\n"
"Compare the dataset OUTDIR with the original data, per timestep and overall:\n"
"PSNR (peak = max - min of the original over all timesteps), RMSE, max\n"
"absolute error, temporal flicker, compression ratio and bits per\n"
"voxel-timestep (decoder tables and all file overhead included), per axis.\n"
"\n"
"  -r, --reference     the remaining arguments are the original files (same\n"
"                      layout as at encoding); default: the manifest's sources\n"
"  -c, --csv FILE      per-timestep figures as CSV\n"
"  -j, --json FILE     everything as JSON\n"
"  -q, --quiet         only the closing summary line\n"
"  -h, --help          this help\n"
"  -V, --version       version\n"
"\n"
"The last line is a key=value summary: psnr (worst axis), psnr_x, psnr_y,\n"
"psnr_z, psnr_min (worst timestep and axis), rmse, max_abs_error and\n"
"flicker (worst axis), ratio (source bytes / mean bytes of one axis),\n"
"ratio_8bit, bpv (bits per voxel-timestep of one axis, everything counted),\n"
"index_bpv, table_bpv, disk_ratio (all three axes stored), steps, window.\n"
"Exit status: 0 success, 1 failure, 2 bad input.\n");
}

struct acc {
    double sse, maxabs, flick;     /* flick: sum of |.| over voxels */
};

static double psnr_of(double mse, double peak)
{
    if (mse <= 0)
        return INFINITY;
    if (peak <= 0)
        return -INFINITY;
    return 10.0 * log10(peak * peak / mse);
}

static void jstr(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            fprintf(f, "\\%c", c);
        else if (c < 0x20)
            fprintf(f, "\\u%04x", c);
        else
            fputc(c, f);
    }
    fputc('"', f);
}

/* JSON has no infinities: null stands for them. */
static void jnum(FILE *f, double v)
{
    if (isfinite(v))
        fprintf(f, "%.6g", v);
    else
        fputs("null", f);
}

static int read_ref(const struct tvpal_manifest *m, char **files, uint32_t t,
                    void *raw, float *dst, size_t nvox)
{
    size_t esz = tvpal_type_size(m->type), bytes = nvox * esz;
    const char *path = m->single_file ? files[0] : files[t];
    off_t off = m->single_file ? (off_t)t * (off_t)bytes : 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        fprintf(stderr, PROG ": %s: cannot open reference: %s\n", path,
                strerror(errno));
        return -1;
    }
    size_t got = 0;
    while (got < bytes) {
        ssize_t k = pread(fd, (char *)raw + got, bytes - got, off + (off_t)got);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0) {
            fprintf(stderr, PROG ": %s: timestep %u: %s\n", path, t,
                    k < 0 ? strerror(errno) : "file is shorter than expected");
            close(fd);
            return -1;
        }
        got += (size_t)k;
    }
    struct stat st;
    uint64_t want = m->single_file ? (uint64_t)bytes * m->steps : bytes;
    if (t == 0 || !m->single_file) {
        if (fstat(fd, &st) == 0 && (uint64_t)st.st_size != want) {
            fprintf(stderr, PROG ": %s: size is %lld bytes; expected %llu "
                    "(dims and type of the manifest)\n", path,
                    (long long)st.st_size, (unsigned long long)want);
            close(fd);
            return -1;
        }
    }
    close(fd);
    size_t bad;
    int rc = tvpal_raw_convert(raw, m->type, m->big_endian, nvox, dst,
                               m->has_nan_as ? &m->nan_as : NULL, &bad, NULL);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s: timestep %u: %s at element %zu\n", path,
                t, tvpal_strerror(rc), bad);
        return -1;
    }
    return 0;
}

/* Bytes of indices and tables of one axis, from the window schedule. */
static void payload_bytes(const struct tvpal_manifest *m, unsigned axis,
                          double *idx, double *tab)
{
    uint32_t n, w, h;
    tvpal_axis_geometry(m->dims, axis, &n, &w, &h);
    *idx = *tab = 0;
    for (uint32_t s = 0; s < n; s++)
        for (uint32_t t = 0; t < m->steps; t++)
            if (tvpal_schedule_starts(s, t, m->window)) {
                *idx += (double)w * h;
                *tab += 256.0 * (m->table_format == 1 ? 2 : 4) *
                        tvpal_schedule_len(s, t, m->window, m->steps);
            }
}

int main(int argc, char **argv)
{
    static const struct option lopts[] = {
        {"reference", no_argument, 0, 'r'},
        {"csv", required_argument, 0, 'c'},
        {"json", required_argument, 0, 'j'},
        {"quiet", no_argument, 0, 'q'},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0}};
    const char *csv_path = NULL, *json_path = NULL;
    int use_ref = 0, quiet = 0, c;
    while ((c = getopt_long(argc, argv, "rc:j:qhV", lopts, NULL)) != -1) {
        switch (c) {
        case 'r': use_ref = 1; break;
        case 'c': csv_path = optarg; break;
        case 'j': json_path = optarg; break;
        case 'q': quiet = 1; break;
        case 'h': usage(stdout); return 0;
        case 'V': printf(PROG " " PACKAGE_VERSION "\n"); return 0;
        default:
            fprintf(stderr, "Try '" PROG " --help'.\n");
            return TVPAL_EXIT_USAGE;
        }
    }
    if (optind >= argc) {
        fprintf(stderr, PROG ": expected OUTDIR (try --help)\n");
        return TVPAL_EXIT_USAGE;
    }
    const char *dir = argv[optind];
    struct tvpal_diag diag = {{0}};
    struct tvpal_dataset *ds = NULL;
    int rc = tvpal_dataset_open(&ds, dir, &diag);
    if (rc < 0) {
        fprintf(stderr, PROG ": %s\n", diag.msg[0] ? diag.msg : tvpal_strerror(rc));
        return TVPAL_EXIT_USAGE;
    }
    const struct tvpal_manifest *m = &ds->m;
    char **refs = m->sources;
    size_t nrefs = m->nsources;
    if (use_ref) {
        refs = argv + optind + 1;
        nrefs = (size_t)(argc - optind - 1);
    } else if (optind + 1 != argc) {
        fprintf(stderr, PROG ": unexpected argument \"%s\" (reference files "
                "follow --reference)\n", argv[optind + 1]);
        return TVPAL_EXIT_USAGE;
    }
    size_t want = m->single_file ? 1 : m->steps;
    if (nrefs != want) {
        fprintf(stderr, PROG ": %zu reference file%s; expected %zu (%s)\n",
                nrefs, nrefs == 1 ? "" : "s", want,
                m->single_file ? "one file holding every timestep"
                               : "one file per timestep");
        return TVPAL_EXIT_USAGE;
    }
    const uint32_t T = m->steps;
    const size_t nvox = (size_t)m->dims[0] * m->dims[1] * m->dims[2];
    /* Source size from dims, type and steps (not the manifest's
     * informational source_bytes, which could be stale or edited). */
    const uint64_t src_bytes = (uint64_t)nvox * T * tvpal_type_size(m->type);
    float *ref[2], *dec[3][2];
    void *raw = malloc(nvox * tvpal_type_size(m->type));
    struct tvpal_volreader *vr[3] = {0};
    struct acc *per = calloc((size_t)T * 3, sizeof *per);
    ref[0] = malloc(nvox * sizeof(float));
    ref[1] = malloc(nvox * sizeof(float));
    int ok = raw && per && ref[0] && ref[1];
    for (unsigned a = 0; a < 3 && ok; a++) {
        dec[a][0] = malloc(nvox * sizeof(float));
        dec[a][1] = malloc(nvox * sizeof(float));
        ok = dec[a][0] && dec[a][1] &&
             tvpal_volreader_create(&vr[a], ds, a) == 0;
    }
    if (!ok) {
        fprintf(stderr, PROG ": out of memory\n");
        return TVPAL_EXIT_FAIL;
    }

    double vmin = INFINITY, vmax = -INFINITY;
    for (uint32_t t = 0; t < T; t++) {
        float *R = ref[t & 1], *Rp = ref[(t & 1) ^ 1];
        if (read_ref(m, refs, t, raw, R, nvox) < 0)
            return TVPAL_EXIT_USAGE;
        for (size_t i = 0; i < nvox; i++) {
            vmin = R[i] < vmin ? R[i] : vmin;
            vmax = R[i] > vmax ? R[i] : vmax;
        }
        for (unsigned a = 0; a < 3; a++) {
            float *V = dec[a][t & 1], *Vp = dec[a][(t & 1) ^ 1];
            rc = tvpal_volreader_read(vr[a], t, V, &diag);
            if (rc < 0) {
                fprintf(stderr, PROG ": %s\n", diag.msg);
                return TVPAL_EXIT_USAGE;
            }
            struct acc *p = &per[(size_t)t * 3 + a];
            double sse = 0, mx = 0, fl = 0;
            for (size_t i = 0; i < nvox; i++) {
                double e = (double)V[i] - (double)R[i];
                sse += e * e;
                mx = fabs(e) > mx ? fabs(e) : mx;
            }
            if (t > 0)
                for (size_t i = 0; i < nvox; i++)
                    fl += fabs(((double)R[i] - Rp[i]) - ((double)V[i] - Vp[i]));
            p->sse = sse;
            p->maxabs = mx;
            p->flick = fl;
        }
    }
    const double peak = vmax - vmin;
    const double vts = (double)nvox * T;

    /* Per axis and overall. */
    double psnr_axis[3], rmse_axis[3], max_axis[3], flick_axis[3];
    double psnr_min = INFINITY, worst_rmse = 0, worst_max = 0, worst_flick = 0;
    uint32_t psnr_min_t = 0;
    unsigned psnr_min_a = 0;
    for (unsigned a = 0; a < 3; a++) {
        double sse = 0, mx = 0, fl = 0;
        for (uint32_t t = 0; t < T; t++) {
            const struct acc *p = &per[(size_t)t * 3 + a];
            sse += p->sse;
            mx = p->maxabs > mx ? p->maxabs : mx;
            fl += p->flick;
            double ps = psnr_of(p->sse / (double)nvox, peak);
            if (ps < psnr_min) {
                psnr_min = ps;
                psnr_min_t = t;
                psnr_min_a = a;
            }
        }
        rmse_axis[a] = sqrt(sse / vts);
        psnr_axis[a] = psnr_of(sse / vts, peak);
        max_axis[a] = mx;
        flick_axis[a] = T > 1 && peak > 0
                            ? fl / ((double)nvox * (T - 1)) / peak : 0.0;
        worst_rmse = rmse_axis[a] > worst_rmse ? rmse_axis[a] : worst_rmse;
        worst_max = mx > worst_max ? mx : worst_max;
        worst_flick = flick_axis[a] > worst_flick ? flick_axis[a] : worst_flick;
    }
    double psnr = fmin(psnr_axis[0], fmin(psnr_axis[1], psnr_axis[2]));
    double bytes_axis = (ds->axis_bytes[0] + ds->axis_bytes[1] +
                         ds->axis_bytes[2]) / 3.0;
    double idx_b[3], tab_b[3];
    for (unsigned a = 0; a < 3; a++)
        payload_bytes(m, a, &idx_b[a], &tab_b[a]);
    double idx_mean = (idx_b[0] + idx_b[1] + idx_b[2]) / 3.0;
    double tab_mean = (tab_b[0] + tab_b[1] + tab_b[2]) / 3.0;
    double ratio = (double)src_bytes / bytes_axis;

    if (!quiet) {
        printf("dataset %s: %ux%ux%u %s, %u steps, window %u, %u node%s\n",
               dir, m->dims[0], m->dims[1], m->dims[2],
               tvpal_type_name(m->type), T, m->window, m->nodes,
               m->nodes == 1 ? "" : "s");
        printf("peak (max - min of the original) = %.9g  [%.9g, %.9g]\n",
               peak, vmin, vmax);
        printf("%6s %9s %9s %9s %12s %10s\n", "step", "psnr_x", "psnr_y",
               "psnr_z", "max_abs_err", "flicker");
        for (uint32_t t = 0; t < T; t++) {
            double ps[3], mx = 0, fl = 0;
            for (unsigned a = 0; a < 3; a++) {
                const struct acc *p = &per[(size_t)t * 3 + a];
                ps[a] = psnr_of(p->sse / (double)nvox, peak);
                mx = p->maxabs > mx ? p->maxabs : mx;
                double f = t && peak > 0 ? p->flick / (double)nvox / peak : 0;
                fl = f > fl ? f : fl;
            }
            printf("%6u %9.3f %9.3f %9.3f %12.6g %10.3g\n", t, ps[0], ps[1],
                   ps[2], mx, fl);
        }
        printf("%4s %9s %12s %12s %10s %14s %8s %9s\n", "axis", "psnr",
               "rmse", "max_abs_err", "flicker", "bytes", "ratio", "bpv");
        for (unsigned a = 0; a < 3; a++)
            printf("%4c %9.3f %12.6g %12.6g %10.3g %14llu %8.3f %9.4f\n",
                   "xyz"[a], psnr_axis[a], rmse_axis[a], max_axis[a],
                   flick_axis[a], (unsigned long long)ds->axis_bytes[a],
                   (double)src_bytes / (double)ds->axis_bytes[a],
                   8.0 * (double)ds->axis_bytes[a] / vts);
        printf("bits per voxel-timestep (one axis): %.4f = indices %.4f + "
               "tables %.4f + headers/padding %.4f\n", 8 * bytes_axis / vts,
               8 * idx_mean / vts, 8 * tab_mean / vts,
               8 * (bytes_axis - idx_mean - tab_mean) / vts);
        printf("worst timestep: %u on axis %c (%.3f dB)\n", psnr_min_t,
               "xyz"[psnr_min_a], psnr_min);
    }
    if (csv_path) {
        FILE *f = fopen(csv_path, "w");
        if (!f) {
            fprintf(stderr, PROG ": %s: cannot write: %s\n", csv_path,
                    strerror(errno));
            return TVPAL_EXIT_FAIL;
        }
        fprintf(f, "step,axis,rmse,psnr,max_abs_error,flicker\n");
        for (uint32_t t = 0; t < T; t++)
            for (unsigned a = 0; a < 3; a++) {
                const struct acc *p = &per[(size_t)t * 3 + a];
                fprintf(f, "%u,%c,%.9g,%.6f,%.9g,%.9g\n", t, "xyz"[a],
                        sqrt(p->sse / (double)nvox),
                        psnr_of(p->sse / (double)nvox, peak), p->maxabs,
                        t && peak > 0 ? p->flick / (double)nvox / peak : 0.0);
            }
        if (fclose(f) != 0) {
            fprintf(stderr, PROG ": %s: write error\n", csv_path);
            return TVPAL_EXIT_FAIL;
        }
    }
    if (json_path) {
        FILE *f = fopen(json_path, "w");
        if (!f) {
            fprintf(stderr, PROG ": %s: cannot write: %s\n", json_path,
                    strerror(errno));
            return TVPAL_EXIT_FAIL;
        }
        fprintf(f, "{\n  \"dataset\": ");
        jstr(f, dir);
        fprintf(f, ",\n  \"dims\": [%u, %u, %u],\n"
                "  \"steps\": %u,\n  \"window\": %u,\n  \"nodes\": %u,\n"
                "  \"peak\": ", m->dims[0], m->dims[1], m->dims[2], T,
                m->window, m->nodes);
        jnum(f, peak);
        fprintf(f, ",\n  \"source_bytes\": %llu,\n  \"axes\": {",
                (unsigned long long)src_bytes);
        for (unsigned a = 0; a < 3; a++) {
            fprintf(f, "%s\n    \"%c\": {\"psnr\": ", a ? "," : "", "xyz"[a]);
            jnum(f, psnr_axis[a]);
            fprintf(f, ", \"rmse\": %.9g, \"max_abs_error\": %.9g, "
                    "\"flicker\": %.9g, \"bytes\": %llu, \"ratio\": %.6f, "
                    "\"bpv\": %.6f, \"index_bpv\": %.6f, \"table_bpv\": %.6f}",
                    rmse_axis[a], max_axis[a], flick_axis[a],
                    (unsigned long long)ds->axis_bytes[a],
                    (double)src_bytes / (double)ds->axis_bytes[a],
                    8.0 * (double)ds->axis_bytes[a] / vts, 8 * idx_b[a] / vts,
                    8 * tab_b[a] / vts);
        }
        fprintf(f, "\n  },\n  \"per_step\": [");
        for (uint32_t t = 0; t < T; t++) {
            fprintf(f, "%s\n    {\"step\": %u", t ? "," : "", t);
            for (unsigned a = 0; a < 3; a++) {
                const struct acc *p = &per[(size_t)t * 3 + a];
                fprintf(f, ", \"psnr_%c\": ", "xyz"[a]);
                jnum(f, psnr_of(p->sse / (double)nvox, peak));
                fprintf(f, ", \"max_abs_error_%c\": %.9g, \"flicker_%c\": %.9g",
                        "xyz"[a], p->maxabs, "xyz"[a],
                        t && peak > 0 ? p->flick / (double)nvox / peak : 0.0);
            }
            fputc('}', f);
        }
        fprintf(f, "\n  ],\n  \"summary\": {\"psnr\": ");
        jnum(f, psnr);
        fprintf(f, ", \"psnr_min\": ");
        jnum(f, psnr_min);
        fprintf(f, ", \"ratio\": %.6f, \"bpv\": %.6f}\n}\n", ratio,
                8 * bytes_axis / vts);
        if (fclose(f) != 0) {
            fprintf(stderr, PROG ": %s: write error\n", json_path);
            return TVPAL_EXIT_FAIL;
        }
    }
    printf("psnr=%.4f psnr_x=%.4f psnr_y=%.4f psnr_z=%.4f psnr_min=%.4f "
           "rmse=%.6g max_abs_error=%.6g flicker=%.6g ratio=%.4f "
           "ratio_8bit=%.4f bpv=%.4f index_bpv=%.4f table_bpv=%.4f "
           "disk_ratio=%.4f steps=%u window=%u\n",
           psnr, psnr_axis[0], psnr_axis[1], psnr_axis[2], psnr_min,
           worst_rmse, worst_max, worst_flick, ratio, vts / bytes_axis,
           8 * bytes_axis / vts, 8 * idx_mean / vts, 8 * tab_mean / vts,
           ratio / 3.0, T, m->window);

    for (unsigned a = 0; a < 3; a++) {
        tvpal_volreader_free(vr[a]);
        free(dec[a][0]);
        free(dec[a][1]);
    }
    free(ref[0]);
    free(ref[1]);
    free(raw);
    free(per);
    tvpal_dataset_close(ds);
    return 0;
}
