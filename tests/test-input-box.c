/* test-input-box: the helpers of the input backends' box reads
 * (tvpal_input_impl.h), apart from any format.  tvpal_box_split: its
 * pieces cover a box exactly once, each within the scratch it promises,
 * and never cut a chunk (so that a chunk is inflated once).
 * tvpal_input_box_pread: boxes of a raw file larger than a batch, read
 * straight (float32) and converted (big-endian int16), into dense and
 * strided destinations, equal to the values in memory; thin x-slabs go in
 * batches of rows, z-slabs straight into dst; a file that ends early is
 * TVPAL_E_FORMAT and a bad descriptor TVPAL_E_READ, with the diag. */
#include "tvpal_input_impl.h"
#include "tvpal_test.h"

#include <fcntl.h>
#include <unistd.h>

/* ------------------------------------------------------- tvpal_box_split */

static void split_case(const uint32_t lo[3], const uint32_t n[3],
                       const uint32_t chunk[3], uint64_t cap)
{
    const size_t nb = (size_t)n[0] * n[1] * n[2];
    int *piece = malloc(nb * sizeof *piece);
    REQUIRE(piece, "memory");
    for (size_t i = 0; i < nb; i++)
        piece[i] = -1;
    struct tvpal_box_split s;
    tvpal_box_split_init(&s, lo, n, chunk, cap);
    const uint64_t most = tvpal_box_split_most(&s);
    uint64_t clip = 1;
    for (int a = 0; a < 3; a++)
        clip *= chunk[a] < n[a] ? chunk[a] : n[a];
    CHECK(most <= (cap > clip ? cap : clip), "box %u %u %u chunk %u %u %u cap "
          "%llu: pieces of %llu values", n[0], n[1], n[2], chunk[0], chunk[1],
          chunk[2], (unsigned long long)cap, (unsigned long long)most);
    CHECK(nb > cap || most == nb, "a box within cap is one piece");
    uint32_t plo[3], pn[3];
    int np = 0, twice = 0, outside = 0, big = 0;
    while (tvpal_box_split_next(&s, plo, pn)) {
        for (int a = 0; a < 3; a++)
            outside += pn[a] == 0 || plo[a] < lo[a] ||
                       plo[a] + pn[a] > lo[a] + n[a];
        if (outside)
            break;
        big += (uint64_t)pn[0] * pn[1] * pn[2] > most;
        for (uint32_t z = 0; z < pn[2]; z++)
            for (uint32_t y = 0; y < pn[1]; y++)
                for (uint32_t x = 0; x < pn[0]; x++) {
                    size_t i = ((size_t)(plo[2] - lo[2] + z) * n[1] +
                                (plo[1] - lo[1] + y)) * n[0] +
                               (plo[0] - lo[0] + x);
                    twice += piece[i] >= 0;
                    piece[i] = np;
                }
        np++;
    }
    size_t missed = 0, cut = 0;
    for (uint32_t z = 0; !outside && z < n[2]; z++)
        for (uint32_t y = 0; y < n[1]; y++)
            for (uint32_t x = 0; x < n[0]; x++) {
                size_t i = ((size_t)z * n[1] + y) * n[0] + x;
                missed += piece[i] < 0;
                /* the box's first voxel of this voxel's chunk */
                uint32_t c[3] = {x, y, z};
                for (int a = 0; a < 3; a++) {
                    uint32_t g = (lo[a] + c[a]) / chunk[a] * chunk[a];
                    c[a] = g > lo[a] ? g - lo[a] : 0;
                }
                cut += piece[i] != piece[((size_t)c[2] * n[1] + c[1]) * n[0] +
                                         c[0]];
            }
    CHECK(!outside && !twice && !missed && !big && !cut, "box %u %u %u + %u "
          "%u %u chunk %u %u %u cap %llu: %d pieces, outside %d, twice %d, "
          "missed %zu, too big %d, chunks cut %zu", lo[0], lo[1], lo[2], n[0],
          n[1], n[2], chunk[0], chunk[1], chunk[2], (unsigned long long)cap,
          np, outside, twice, missed, big, cut);
    free(piece);
}

static void test_split(void)
{
    /* the three levels: slabs of z, bands of y, runs of x */
    split_case((uint32_t[]){0, 0, 0}, (uint32_t[]){10, 10, 10},
               (uint32_t[]){1, 1, 1}, 1000);
    split_case((uint32_t[]){3, 5, 7}, (uint32_t[]){10, 10, 10},
               (uint32_t[]){4, 4, 4}, 250);
    split_case((uint32_t[]){3, 5, 7}, (uint32_t[]){40, 30, 20},
               (uint32_t[]){8, 8, 8}, 100);
    split_case((uint32_t[]){1, 0, 2}, (uint32_t[]){64, 64, 9},
               (uint32_t[]){64, 64, 4}, 1);
    split_case((uint32_t[]){0, 0, 0}, (uint32_t[]){1, 1, 1},
               (uint32_t[]){1, 1, 1}, 1);
    for (int k = 0; k < 300; k++) {
        uint32_t lo[3], n[3], c[3];
        for (int a = 0; a < 3; a++) {
            lo[a] = (uint32_t)(tt_rand64() % 50);
            n[a] = 1 + (uint32_t)(tt_rand64() % 40);
            c[a] = 1 + (uint32_t)(tt_rand64() % 12);
        }
        static const uint64_t caps[] = {1, 5, 64, 300, 2000, 20000, 100000};
        split_case(lo, n, c, caps[tt_rand64() % 7]);
    }
    /* a box of the cap's size and one value more */
    split_case((uint32_t[]){0, 0, 0}, (uint32_t[]){1024, 1024, 1},
               (uint32_t[]){1, 1, 1}, TVPAL_BOX_PIECE);
    split_case((uint32_t[]){0, 0, 0}, (uint32_t[]){1024, 1024, 2},
               (uint32_t[]){1, 1, 1}, TVPAL_BOX_PIECE);
}

/* ------------------------------------------------- tvpal_input_box_pread */

#define HDR 123   /* bytes before the values, as a header would be */

static void conv_i16be(const unsigned char *src, size_t count, float *dst,
                       const void *ctx)
{
    (void)ctx;
    for (size_t i = 0; i < count; i++)
        dst[i] = (float)(int16_t)(uint16_t)(src[2 * i] << 8 | src[2 * i + 1]);
}

static float value(size_t i, int is_i16)
{
    return is_i16 ? (float)((int)(i * 7919 % 60001) - 30000)
                  : (float)((double)(i * 7919 % 10007) * 0.01 - 50.0);
}

/* Box lo + n of the file (dims, float32 or int16) into a dst with rows of
 * dy and slices of dz (padding checked untouched). */
static void pread_case(int fd, const uint32_t dims[3], int is_i16,
                       const uint32_t lo[3], const uint32_t n[3], size_t pad,
                       struct tvpal_box_io *io)
{
    const size_t dy = n[0] + pad, dz = dy * n[1] + pad;
    const size_t len = dz * n[2];
    float *dst = malloc(len * sizeof *dst);
    REQUIRE(dst, "memory");
    for (size_t i = 0; i < len; i++)
        dst[i] = -12345.f;
    struct tvpal_diag g = {{0}};
    int rc = tvpal_input_box_pread(fd, HDR, dims, is_i16 ? 2 : 4, lo, n, dst,
                                   dy, dz, is_i16 ? conv_i16be : NULL, NULL,
                                   io, "file", "values", &g);
    CHECK(rc == 0, "box pread: %d %s", rc, g.msg);
    size_t bad = 0, touched = 0;
    for (size_t z = 0; z < n[2]; z++)
        for (size_t y = 0; y < dy; y++)
            for (size_t x = 0; x < (y < n[1] ? dy : 0); x++) {
                float got = dst[z * dz + y * dy + x];
                if (x >= n[0]) {
                    touched += got != -12345.f;
                    continue;
                }
                size_t i = ((lo[2] + z) * dims[1] + lo[1] + y) * dims[0] +
                           lo[0] + x;
                bad += got != value(i, is_i16);
            }
    CHECK(bad == 0 && touched == 0, "%s box %u %u %u + %u %u %u pad %zu: %zu "
          "values differ, %zu of the padding written", is_i16 ? "int16" :
          "float", lo[0], lo[1], lo[2], n[0], n[1], n[2], pad, bad, touched);
    free(dst);
}

static void test_pread(const char *dir)
{
    const uint32_t dims[3] = {300, 200, 30};   /* 7.2 MB of float32 */
    const size_t n = (size_t)dims[0] * dims[1] * dims[2];
    for (int is_i16 = 0; is_i16 < 2; is_i16++) {
        char path[1200];
        snprintf(path, sizeof path, "%s/%s.raw", dir, is_i16 ? "i16" : "f32");
        FILE *fp = fopen(path, "wb");
        REQUIRE(fp, "write %s", path);
        for (int i = 0; i < HDR; i++)
            fputc('#', fp);
        for (size_t i = 0; i < n; i++) {
            float v = value(i, is_i16);
            if (is_i16) {
                uint16_t u = (uint16_t)(int16_t)v;
                fputc(u >> 8, fp);
                fputc(u & 255, fp);
            } else {
                fwrite(&v, 4, 1, fp);   /* the host's float32 */
            }
        }
        REQUIRE(fclose(fp) == 0, "write %s", path);
        int fd = open(path, O_RDONLY);
        REQUIRE(fd >= 0, "open %s", path);
        struct tvpal_box_io io = {0};

        /* whole z-slices of float32 go straight into dst */
        pread_case(fd, dims, is_i16, (uint32_t[]){0, 0, 3},
                   (uint32_t[]){300, 200, 5}, 0, &io);
        CHECK(is_i16 || io.cap == 0, "a z-slab of float32 needs no scratch "
              "(%zu)", io.cap);
        /* a thin x-slab: rows in batches of up to 4 MiB, not row by row */
        pread_case(fd, dims, is_i16, (uint32_t[]){7, 0, 0},
                   (uint32_t[]){1, 200, 30}, 0, &io);
        CHECK(io.cap > ((size_t)1 << 20) && io.cap <= TVPAL_BOX_IO_CAP,
              "an x-slab is read in batches: scratch %zu", io.cap);
        pread_case(fd, dims, is_i16, (uint32_t[]){299, 0, 0},
                   (uint32_t[]){1, 200, 30}, 3, &io);
        pread_case(fd, dims, is_i16, (uint32_t[]){0, 0, 0},
                   (uint32_t[]){300, 200, 30}, 0, &io);
        pread_case(fd, dims, is_i16, (uint32_t[]){0, 0, 0},
                   (uint32_t[]){300, 200, 30}, 2, &io);
        pread_case(fd, dims, is_i16, (uint32_t[]){0, 199, 29},
                   (uint32_t[]){300, 1, 1}, 0, &io);
        CHECK(io.cap <= TVPAL_BOX_IO_CAP, "scratch %zu", io.cap);
        for (int k = 0; k < 20; k++) {
            uint32_t lo[3], bn[3];
            for (int a = 0; a < 3; a++) {
                lo[a] = (uint32_t)(tt_rand64() % dims[a]);
                bn[a] = 1 + (uint32_t)(tt_rand64() % (dims[a] - lo[a]));
            }
            pread_case(fd, dims, is_i16, lo, bn, (size_t)(tt_rand64() % 3),
                       &io);
        }
        CHECK(io.cap <= TVPAL_BOX_IO_CAP, "scratch %zu", io.cap);
        CHECK(tvpal_input_box_pread_scratch(dims, 4, (uint32_t[]){300, 200, 1},
                                            1) == 0 &&
              tvpal_input_box_pread_scratch(dims, 4, (uint32_t[]){1, 200, 30},
                                            1) == TVPAL_BOX_IO_CAP &&
              tvpal_input_box_pread_scratch(dims, 2, (uint32_t[]){3, 2, 1},
                                            0) == (300 + 3) * 2,
              "pread scratch bounds");

        /* the file ends within the values; a descriptor that is not open */
        const uint32_t dims2[3] = {300, 200, 31};
        float v[300];
        struct tvpal_diag g = {{0}};
        int rc = tvpal_input_box_pread(fd, HDR, dims2, is_i16 ? 2 : 4,
                                       (uint32_t[]){0, 5, 30},
                                       (uint32_t[]){300, 1, 1}, v, 300, 300,
                                       is_i16 ? conv_i16be : NULL, NULL, &io,
                                       "file", "values", &g);
        /* every caller checked the size at open: the file shrank since */
        CHECK(rc == TVPAL_E_TRUNC && strstr(g.msg, "file: values: the file "
                                            "ends at byte") &&
              strstr(g.msg, "shrank while being read"), "short file: %d %s",
              rc, g.msg);
        close(fd);
        rc = tvpal_input_box_pread(fd, HDR, dims, is_i16 ? 2 : 4,
                                   (uint32_t[]){0, 0, 0},
                                   (uint32_t[]){300, 1, 1}, v, 300, 300,
                                   is_i16 ? conv_i16be : NULL, NULL, &io,
                                   "file", "values", &g);
        CHECK(rc == TVPAL_E_READ && strstr(g.msg, "file: values: read: "),
              "closed fd: %d %s", rc, g.msg);
        free(io.buf);
        unlink(path);
    }
}

int main(void)
{
    const char *b = getenv("TVPAL_BUILDDIR");
    char dir[1024], cmd[2200];
    snprintf(dir, sizeof dir, "%s/tests/work/test-input-box", b ? b : ".");
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s'", dir, dir);
    REQUIRE(system(cmd) == 0, "%s", cmd);
    test_split();
    test_pread(dir);
    int rc = tt_done("test-input-box");
    if (rc == 0) {
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
        if (system(cmd) != 0)
            fprintf(stderr, "could not remove %s\n", dir);
    }
    return rc;
}
