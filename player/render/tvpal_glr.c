/* tvpal_glr.c: GL palette renderer (see tvpal_glr.h). */
#define GL_GLEXT_PROTOTYPES 1
#include "tvpal_glr.h"
#include "tvpal_clock.h"

#include <GL/gl.h>
#include <GL/glext.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *vs_src =
    "#version 330 core\n"
    "layout(location = 0) in vec2 pos;   // NDC\n"
    "layout(location = 1) in vec2 uv;    // slice coordinates in [0,1]\n"
    "layout(location = 2) in float layer;\n"
    "out vec2 v_uv;\n"
    "flat out int v_layer;\n"
    "void main() {\n"
    "    v_uv = uv;\n"
    "    v_layer = int(layer + 0.5);\n"
    "    gl_Position = vec4(pos, 0.0, 1.0);\n"
    "}\n";

/* Paletted-texture emulation: the four nearest texels (centres at
 * (i + 0.5) / size, clamped to the edge) are looked up in their palette
 * and the colours, not the indices, are interpolated.  One body, two
 * programs (compiled after "#define CROSS 0", "1" (y) or "2" (x): no
 * branch per fetch, which llvmpipe would run both ways):
 *  - plain: v_layer is the slice's layer; texel p is (p, v_layer), looked
 *    up in palette row v_layer.
 *  - cross: v_layer is the view-axis slice s (x or y) and size its
 *    w x nz; texel (a, b) is (a, s) of the z slice b in layer b - rows.x
 *    + rows.z (y slices), or (a, b - rows.x) of layer s of the transposed
 *    copy xt (x slices: texel (s, a) of z slice b, cut on the CPU, since
 *    a column of a z layer is a row apart per texel), looked up in z slice
 *    b's palette row; b clamps to the rows held [rows.x, rows.y], so taps
 *    never reach a row the frame does not hold. */
static const char *fs_version = "#version 330 core\n";
static const char *fs_src =
    "uniform usampler2DArray idx;\n"
    "#if CROSS == 2\n"
    "uniform usampler2DArray xt;         // x slices: [s] rows x ny\n"
    "#endif\n"
    "uniform sampler2D pal;              // 256 x layers, RGBA32F\n"
    "uniform ivec2 size;\n"
    "#if CROSS\n"
    "uniform ivec3 rows;                 // first, last row held; its layer\n"
    "#endif\n"
    "in vec2 v_uv;\n"
    "flat in int v_layer;\n"
    "out vec4 color;\n"
    "vec4 look(ivec2 p) {\n"
    "#if CROSS\n"
    "    p = clamp(p, ivec2(0, rows.x), ivec2(size.x - 1, rows.y));\n"
    "    int l = p.y - rows.x + rows.z;\n"
    "#if CROSS == 2\n"
    "    uint i = texelFetch(xt, ivec3(p.x, p.y - rows.x, v_layer), 0).r;\n"
    "#else\n"
    "    uint i = texelFetch(idx, ivec3(p.x, v_layer, l), 0).r;\n"
    "#endif\n"
    "    return texelFetch(pal, ivec2(int(i), l), 0);\n"
    "#else\n"
    "    p = clamp(p, ivec2(0), size - 1);\n"
    "    uint i = texelFetch(idx, ivec3(p, v_layer), 0).r;\n"
    "    return texelFetch(pal, ivec2(int(i), v_layer), 0);\n"
    "#endif\n"
    "}\n"
    "void main() {\n"
    "    vec2 t = v_uv * vec2(size) - 0.5;\n"
    "    vec2 t0 = floor(t);\n"
    "    vec2 f = t - t0;\n"
    "    ivec2 p = ivec2(t0);\n"
    "    vec4 a = mix(look(p), look(p + ivec2(1, 0)), f.x);\n"
    "    vec4 b = mix(look(p + ivec2(0, 1)), look(p + ivec2(1, 1)), f.x);\n"
    "    color = mix(a, b, f.y);\n"
    "}\n";

struct tvpal_glr {
    unsigned width, height;
    GLuint prog, prog_cross[2], vao, vbo, fbo, rbo, tex_idx, tex_pal, tex_xt;
    GLint u_size, u_size_cross[2], u_rows[2];   /* cross: [0] x, [1] y */
    uint32_t w, h, count;
    float *verts;            /* quad_cap * 6 * 5 */
    size_t quad_cap;
    float *pal;              /* count * 256 * 4 */
    uint64_t uploads;
    double t_upload, t_draw, t_read;
    /* The transposed copy of x slices (cross frames along x): xt on the
     * CPU, [s][k][a] = texel (s, a) of row k, ny x rows per slice, and in
     * tex_xt; row k was cut from layer xt_layer[k] at its generation
     * xt_gen[k] (0: nothing), compared with ugen (bumped per upload), so
     * only the rows whose window changed are cut and uploaded again. */
    uint32_t *ugen;          /* count */
    uint8_t *xt;
    size_t xt_cap;
    uint32_t *xt_gen, *xt_layer;
    uint32_t xt_rows, xt_rows_cap, xt_n, xt_w;
    uint32_t *xt_todo;
};

static int compile(GLenum type, GLsizei n, const char *const *src,
                   GLuint *out, struct tvpal_diag *diag)
{
    GLuint s = glCreateShader(type);
    glShaderSource(s, n, src, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[200];
        glGetShaderInfoLog(s, sizeof log, NULL, log);
        glDeleteShader(s);
        return tvpal_diag_set(diag, TVPAL_E_SYS, "shader: %s", log);
    }
    *out = s;
    return 0;
}

/* The program of fs_src compiled with CROSS = cross (0 plain, 1 y, 2 x
 * slices), its samplers bound to
 * units 0 (idx) and 1 (pal).  Once created, *out is the caller's to delete,
 * failed link or not. */
static int link_program(int cross, GLuint *out, struct tvpal_diag *diag)
{
    const char *fs[3] = {fs_version,
                         cross == 2 ? "#define CROSS 2\n"
                         : cross ? "#define CROSS 1\n" : "#define CROSS 0\n",
                         fs_src};
    GLuint vs = 0, f = 0;
    int rc = compile(GL_VERTEX_SHADER, 1, &vs_src, &vs, diag);
    if (rc < 0)
        return rc;
    rc = compile(GL_FRAGMENT_SHADER, 3, fs, &f, diag);
    if (rc < 0) {
        glDeleteShader(vs);
        return rc;
    }
    GLuint prog = *out = glCreateProgram();
    glAttachShader(prog, vs);
    glAttachShader(prog, f);
    glLinkProgram(prog);
    glDeleteShader(vs);
    glDeleteShader(f);
    GLint ok = 0;
    glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[200];
        glGetProgramInfoLog(prog, sizeof log, NULL, log);
        return tvpal_diag_set(diag, TVPAL_E_SYS, "shader link: %s", log);
    }
    glUseProgram(prog);
    glUniform1i(glGetUniformLocation(prog, "idx"), 0);
    glUniform1i(glGetUniformLocation(prog, "pal"), 1);
    if (cross == 2)
        glUniform1i(glGetUniformLocation(prog, "xt"), 2);
    return 0;
}

int tvpal_glr_create(struct tvpal_glr **out, unsigned width, unsigned height,
                     struct tvpal_diag *diag)
{
    return tvpal_glr_create_fb(out, width, height, 32, diag);
}

int tvpal_glr_create_fb(struct tvpal_glr **out, unsigned width,
                        unsigned height, unsigned fb_bits,
                        struct tvpal_diag *diag)
{
    const char *ver = (const char *)glGetString(GL_VERSION);
    int major = 0, minor = 0;
    if (!ver || sscanf(ver, "%d.%d", &major, &minor) != 2 ||
        major * 10 + minor < 33)
        return tvpal_diag_set(diag, TVPAL_E_SYS,
                              "OpenGL 3.3 is needed; the context offers %s",
                              ver ? ver : "none");
    struct tvpal_glr *r = calloc(1, sizeof *r);
    if (!r)
        return TVPAL_E_NOMEM;
    r->width = width;
    r->height = height;
    int rc = link_program(0, &r->prog, diag);
    if (rc < 0)
        goto err;
    for (int a = 0; a < 2; a++) {
        rc = link_program(a == 0 ? 2 : 1, &r->prog_cross[a], diag);
        if (rc < 0)
            goto err;
        r->u_size_cross[a] = glGetUniformLocation(r->prog_cross[a], "size");
        r->u_rows[a] = glGetUniformLocation(r->prog_cross[a], "rows");
    }
    r->u_size = glGetUniformLocation(r->prog, "size");

    glGenVertexArrays(1, &r->vao);
    glBindVertexArray(r->vao);
    glGenBuffers(1, &r->vbo);
    glBindBuffer(GL_ARRAY_BUFFER, r->vbo);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 5 * sizeof(float), (void *)0);
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, 5 * sizeof(float),
                          (void *)(2 * sizeof(float)));
    glVertexAttribPointer(2, 1, GL_FLOAT, GL_FALSE, 5 * sizeof(float),
                          (void *)(4 * sizeof(float)));
    glEnableVertexAttribArray(0);
    glEnableVertexAttribArray(1);
    glEnableVertexAttribArray(2);

    /* Float colour buffer: 8-bit accumulation over hundreds of slices
     * bands visibly. */
    glGenFramebuffers(1, &r->fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    glGenRenderbuffers(1, &r->rbo);
    glBindRenderbuffer(GL_RENDERBUFFER, r->rbo);
    glRenderbufferStorage(GL_RENDERBUFFER,
                          fb_bits == 8 ? GL_RGBA8 : fb_bits == 16 ? GL_RGBA16F
                                                                  : GL_RGBA32F,
                          (GLsizei)width, (GLsizei)height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0,
                              GL_RENDERBUFFER, r->rbo);
    GLenum st = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    if (st != GL_FRAMEBUFFER_COMPLETE) {
        rc = tvpal_diag_set(diag, TVPAL_E_SYS,
                            "a %ux%u float framebuffer is not available "
                            "(status 0x%x)", width, height, st);
        goto err;
    }
    glGenTextures(1, &r->tex_idx);
    glGenTextures(1, &r->tex_pal);
    glGenTextures(1, &r->tex_xt);
    glViewport(0, 0, (GLsizei)width, (GLsizei)height);
    glEnable(GL_BLEND);
    glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA); /* premultiplied "over" */
    glDisable(GL_DEPTH_TEST);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    if (glGetError() != GL_NO_ERROR) {
        rc = tvpal_diag_set(diag, TVPAL_E_SYS, "GL setup failed");
        goto err;
    }
    *out = r;
    return 0;
err:
    tvpal_glr_free(r);
    return rc;
}

void tvpal_glr_free(struct tvpal_glr *r)
{
    if (!r)
        return;
    if (r->tex_idx)
        glDeleteTextures(1, &r->tex_idx);
    if (r->tex_pal)
        glDeleteTextures(1, &r->tex_pal);
    if (r->tex_xt)
        glDeleteTextures(1, &r->tex_xt);
    free(r->ugen);
    free(r->xt);
    free(r->xt_gen);
    free(r->xt_layer);
    free(r->xt_todo);
    if (r->rbo)
        glDeleteRenderbuffers(1, &r->rbo);
    if (r->fbo)
        glDeleteFramebuffers(1, &r->fbo);
    if (r->vbo)
        glDeleteBuffers(1, &r->vbo);
    if (r->vao)
        glDeleteVertexArrays(1, &r->vao);
    if (r->prog)
        glDeleteProgram(r->prog);
    for (int a = 0; a < 2; a++)
        if (r->prog_cross[a])
            glDeleteProgram(r->prog_cross[a]);
    free(r->verts);
    free(r->pal);
    free(r);
}

/* Room in r->verts for n quads; grows only (a frame reuses it). */
static int reserve_quads(struct tvpal_glr *r, size_t n)
{
    if (n <= r->quad_cap)
        return 0;
    float *v = realloc(r->verts, sizeof(float) * 30 * n);
    if (!v)
        return TVPAL_E_NOMEM;
    r->verts = v;
    r->quad_cap = n;
    return 0;
}

int tvpal_glr_set_slices(struct tvpal_glr *r, uint32_t w, uint32_t h,
                         uint32_t count, struct tvpal_diag *diag)
{
    GLint maxl = 0, maxs = 0;
    glGetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &maxl);
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &maxs);
    if ((GLint)count > maxl || (GLint)w > maxs || (GLint)h > maxs)
        return tvpal_diag_set(diag, TVPAL_E_SYS,
                              "%u slices of %ux%u exceed the GL limits (%d "
                              "layers, %d texels)", count, w, h, maxl, maxs);
    float *p = realloc(r->pal, sizeof(float) * 1024 * count);
    if (p)
        r->pal = p;
    uint32_t *g = realloc(r->ugen, sizeof *g * (count ? count : 1));
    if (g)
        r->ugen = g;
    if (!p || !g || reserve_quads(r, count) < 0)
        return TVPAL_E_NOMEM;
    for (uint32_t i = 0; i < count; i++)
        r->ugen[i] = 1;
    r->xt_rows = 0;   /* the transposed copy is cut again */
    r->w = w;
    r->h = h;
    r->count = count;
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D_ARRAY, r->tex_idx);
    glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_R8UI, (GLsizei)w, (GLsizei)h,
                 (GLsizei)count, 0, GL_RED_INTEGER, GL_UNSIGNED_BYTE, NULL);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, r->tex_pal);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, 256, (GLsizei)count, 0, GL_RGBA,
                 GL_FLOAT, NULL);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    if (glGetError() != GL_NO_ERROR)
        return tvpal_diag_set(diag, TVPAL_E_SYS,
                              "cannot allocate textures for %u slices of "
                              "%ux%u", count, w, h);
    return 0;
}

void tvpal_glr_upload(struct tvpal_glr *r, uint32_t layer, const uint8_t *idx)
{
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D_ARRAY, r->tex_idx);
    glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, (GLint)layer, (GLsizei)r->w,
                    (GLsizei)r->h, 1, GL_RED_INTEGER, GL_UNSIGNED_BYTE, idx);
    r->uploads++;
    if (layer < r->count && ++r->ugen[layer] == 0)
        r->ugen[layer] = 1;   /* 0 means "nothing cut" */
}

/* Two triangles of the quad with eye-space corners c[0..3] ((0,0), (1,0),
 * (1,1), (0,1) in slice coordinates) and texture coordinates uv; the
 * last attribute is the layer (plain) or the slice (cross). */
static float *put_quad(float *q, const struct tvpal_view *v,
                       const double c[4][3], const float uv[4][2], float l)
{
    static const int tri[6] = {0, 1, 2, 0, 2, 3};
    for (int i = 0; i < 6; i++) {
        int ci = tri[i];
        *q++ = (float)(c[ci][0] / v->sx);
        *q++ = (float)(c[ci][1] / v->sy);
        *q++ = uv[ci][0];
        *q++ = uv[ci][1];
        *q++ = l;
    }
    return q;
}

/* Palettes of the plain frame's slices into their layers' rows, and its
 * quads back to front; returns the quad count. */
static uint32_t plain_quads(struct tvpal_glr *r, const struct tvpal_frame *f)
{
    const struct tvpal_view *v = f->view;
    static const float uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    float *q = r->verts;
    for (uint32_t k = 0; k < f->count; k++) {
        const struct tvpal_frame_slice *sl = &f->sl[k];
        memcpy(r->pal + (size_t)1024 * sl->layer, sl->palette,
               sizeof(float) * 1024);
        double c[4][3];
        for (int i = 0; i < 4; i++)
            tvpal_view_slice_corner(v, sl->slice, (unsigned)i, c[i]);
        q = put_quad(q, v, c, uv, (float)sl->layer);
    }
    return f->count;
}

/* A cross frame's z slices (their palettes into their layers' rows) and
 * quads: one per view-axis slice drawn, back to front, cut to the rows
 * held [z0, z1) (b from z0 / nz to z1 / nz of the slice).  The cut corners
 * are c0 (1 - t) + c3 t, exact at t = 0 and 1 and the same numbers for
 * two slabs meeting at a row, so rasterization's edge rule gives each
 * pixel at a slab boundary to one slab.  The layers must be consecutive
 * (layer of z slice b = layer of z0 + b - z0), which the shader assumes;
 * anything else, or a frame the textures do not fit, is refused. */
static int cross_quads(struct tvpal_glr *r, const struct tvpal_frame *f,
                       uint32_t *nquads, struct tvpal_diag *diag)
{
    const struct tvpal_view *v = f->view;
    *nquads = 0;
    if (v->axis > 1)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "a cross frame is drawn "
                              "along x or y; this view's axis is z");
    if (f->stride < 1)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "cross frame with "
                              "stride 0");
    if (!f->count)
        return 0;
    const uint32_t z0 = f->sl[0].slice, l0 = f->sl[0].layer;
    if (f->w != v->dims[0] || f->h != v->dims[1] || f->w != r->w ||
        f->h != r->h || z0 > v->dims[2] || f->count > v->dims[2] - z0 ||
        l0 > r->count || f->count > r->count - l0)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "cross frame of z slices "
                              "[%u, %u) of %ux%u in layers from %u; the "
                              "renderer holds %u layers of %ux%u", z0,
                              z0 + f->count, f->w, f->h, l0, r->count, r->w,
                              r->h);
    for (uint32_t k = 0; k < f->count; k++) {
        const struct tvpal_frame_slice *sl = &f->sl[k];
        if (sl->slice != z0 + k || sl->layer != l0 + k)
            return tvpal_diag_set(diag, TVPAL_E_INVAL, "cross frame: z "
                                  "slice %u in layer %u, expected z slice "
                                  "%u in layer %u", sl->slice, sl->layer,
                                  z0 + k, l0 + k);
        memcpy(r->pal + (size_t)1024 * sl->layer, sl->palette,
               sizeof(float) * 1024);
    }
    uint32_t w, h, n;
    tvpal_frame_cross_geometry(f, &w, &h, &n);
    if (reserve_quads(r, n) < 0)
        return TVPAL_E_NOMEM;
    uint32_t d0, d1;
    tvpal_frame_cross_draw_rows(f, &d0, &d1);
    if (d0 < z0 || d1 > z0 + f->count)
        return tvpal_diag_set(diag, TVPAL_E_INVAL, "cross frame: rows %u..%u "
                              "drawn, %u..%u held", d0, d1, z0, z0 + f->count);
    const double t0 = (double)d0 / h, t1 = (double)d1 / h;
    const float uv[4][2] = {{0, (float)t0}, {1, (float)t0}, {1, (float)t1},
                            {0, (float)t1}};
    float *q = r->verts;
    for (uint32_t i = 0; i < n; i++) {
        const uint32_t s = v->descending ? n - 1 - i : i;
        if (s % f->stride != f->phase)
            continue;
        double c[4][3], cut[4][3];
        for (int k = 0; k < 4; k++)
            tvpal_view_slice_corner(v, s, (unsigned)k, c[k]);
        for (int e = 0; e < 3; e++) {
            cut[0][e] = c[0][e] * (1 - t0) + c[3][e] * t0;
            cut[1][e] = c[1][e] * (1 - t0) + c[2][e] * t0;
            cut[2][e] = c[1][e] * (1 - t1) + c[2][e] * t1;
            cut[3][e] = c[0][e] * (1 - t1) + c[3][e] * t1;
        }
        q = put_quad(q, v, cut, uv, (float)s);
        ++*nquads;
    }
    return 0;
}

/* The transposed copy for a cross frame along x: (re)allocated when the
 * frame's rows or slices change shape, then the rows whose layer or
 * generation changed are cut on the CPU and uploaded, one
 * glTexSubImage3D per row (ny x 1 x nx texels, strided in xt): steady
 * playback uploads the 1/N of the rows whose windows changed. */
static int update_xt(struct tvpal_glr *r, const struct tvpal_frame *f,
                     struct tvpal_diag *diag)
{
    const uint32_t rows = f->count, nx = f->w, ny = f->h;
    glActiveTexture(GL_TEXTURE2);
    glBindTexture(GL_TEXTURE_2D_ARRAY, r->tex_xt);
    if (r->xt_rows != rows || r->xt_n != nx || r->xt_w != ny) {
        const size_t bytes = (size_t)nx * ny * rows;
        if (bytes > r->xt_cap) {
            uint8_t *b = realloc(r->xt, bytes);
            if (!b)
                return tvpal_diag_set(diag, TVPAL_E_NOMEM, "transposed x "
                                      "slices (%zu bytes)", bytes);
            r->xt = b;
            r->xt_cap = bytes;
        }
        if (rows > r->xt_rows_cap) {
            uint32_t *g = realloc(r->xt_gen, sizeof *g * rows);
            if (g)
                r->xt_gen = g;
            uint32_t *l = g ? realloc(r->xt_layer, sizeof *l * rows) : NULL;
            if (l)
                r->xt_layer = l;
            uint32_t *t = l ? realloc(r->xt_todo, sizeof *t * rows) : NULL;
            if (t)
                r->xt_todo = t;
            if (!t)
                return tvpal_diag_set(diag, TVPAL_E_NOMEM, "transposed x "
                                      "slices");
            r->xt_rows_cap = rows;
        }
        memset(r->xt_gen, 0, sizeof *r->xt_gen * rows);
        glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_R8UI, (GLsizei)ny,
                     (GLsizei)rows, (GLsizei)nx, 0, GL_RED_INTEGER,
                     GL_UNSIGNED_BYTE, NULL);
        glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        r->xt_rows = rows;
        r->xt_n = nx;
        r->xt_w = ny;
    }
    int ntodo = 0;
    for (uint32_t k = 0; k < rows; k++) {
        const uint32_t layer = f->sl[k].layer;
        if (r->xt_gen[k] != r->ugen[layer] || r->xt_layer[k] != layer)
            r->xt_todo[ntodo++] = k;
    }
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 2)
#endif
    for (int m = 0; m < ntodo; m++) {
        const uint32_t k = r->xt_todo[m];
        tvpal_frame_cut_row(r->xt, 0, rows, k, f->sl[k].idx, nx, ny);
    }
    glPixelStorei(GL_UNPACK_ROW_LENGTH, (GLint)ny);
    glPixelStorei(GL_UNPACK_IMAGE_HEIGHT, (GLint)rows);
    for (int m = 0; m < ntodo; m++) {
        const uint32_t k = r->xt_todo[m];
        glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, (GLint)k, 0, (GLsizei)ny, 1,
                        (GLsizei)nx, GL_RED_INTEGER, GL_UNSIGNED_BYTE,
                        r->xt + (size_t)k * ny);
        r->xt_layer[k] = f->sl[k].layer;
        r->xt_gen[k] = r->ugen[f->sl[k].layer];
    }
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    glPixelStorei(GL_UNPACK_IMAGE_HEIGHT, 0);
    if (glGetError() != GL_NO_ERROR)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "cannot upload the transposed "
                              "x slices (%ux%ux%u)", ny, rows, nx);
    return 0;
}

int tvpal_glr_draw(struct tvpal_glr *r, const struct tvpal_frame *f,
                   float *rgba, struct tvpal_diag *diag)
{
    double t0 = tvpal_now();
    uint32_t nq = 0;
    if (f->cross) {
        int rc = cross_quads(r, f, &nq, diag);
        if (rc == 0 && f->view->axis == 0 && f->count)
            rc = update_xt(r, f, diag);
        if (rc < 0)
            return rc;
    } else {
        nq = plain_quads(r, f);
    }
    /* Bind our program and textures every frame: a front end may have
     * used them (the window's composited-image texture, say). */
    if (f->cross) {
        uint32_t w, h, n;
        tvpal_frame_cross_geometry(f, &w, &h, &n);
        const GLint z0 = f->count ? (GLint)f->sl[0].slice : 0;
        const int a = f->view->axis == 0 ? 0 : 1;
        glUseProgram(r->prog_cross[a]);
        glUniform2i(r->u_size_cross[a], (GLint)w, (GLint)h);
        glUniform3i(r->u_rows[a], z0, z0 + (GLint)f->count - 1,
                    f->count ? (GLint)f->sl[0].layer : 0);
    } else {
        glUseProgram(r->prog);
        glUniform2i(r->u_size, (GLint)r->w, (GLint)r->h);
    }
    glBindVertexArray(r->vao);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D_ARRAY, r->tex_idx);
    glActiveTexture(GL_TEXTURE2);
    glBindTexture(GL_TEXTURE_2D_ARRAY, r->tex_xt);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, r->tex_pal);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, 256, (GLsizei)r->count, GL_RGBA,
                    GL_FLOAT, r->pal);
    glBindBuffer(GL_ARRAY_BUFFER, r->vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(sizeof(float) * 30 * nq),
                 r->verts, GL_STREAM_DRAW);
    double t1 = tvpal_now();
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    glClearColor(0, 0, 0, 0);
    glClear(GL_COLOR_BUFFER_BIT);
    glDrawArrays(GL_TRIANGLES, 0, (GLsizei)(6 * nq));
    glFinish();
    double t2 = tvpal_now();
    if (rgba) {
        glReadBuffer(GL_COLOR_ATTACHMENT0);
        glReadPixels(0, 0, (GLsizei)r->width, (GLsizei)r->height, GL_RGBA,
                     GL_FLOAT, rgba);
    }
    double t3 = tvpal_now();
    r->t_upload = (t1 - t0) * 1e3;
    r->t_draw = (t2 - t1) * 1e3;
    r->t_read = (t3 - t2) * 1e3;
    GLenum e = glGetError();
    if (e != GL_NO_ERROR)
        return tvpal_diag_set(diag, TVPAL_E_SYS, "GL error 0x%x while drawing",
                              e);
    return 0;
}

void tvpal_glr_blit(struct tvpal_glr *r, int x, int y)
{
    glBindFramebuffer(GL_READ_FRAMEBUFFER, r->fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    glBlitFramebuffer(0, 0, (GLint)r->width, (GLint)r->height, x, y,
                      x + (GLint)r->width, y + (GLint)r->height,
                      GL_COLOR_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
}

const char *tvpal_glr_gl_name(void)
{
    const char *s = (const char *)glGetString(GL_RENDERER);
    return s ? s : "unknown";
}

uint64_t tvpal_glr_uploads(const struct tvpal_glr *r)
{
    return r->uploads;
}

void tvpal_glr_times(const struct tvpal_glr *r, double *upload_ms,
                     double *draw_ms, double *readback_ms)
{
    *upload_ms = r->t_upload;
    *draw_ms = r->t_draw;
    *readback_ms = r->t_read;
}

/* ------------------------------------------------ the renderer interface */

static int gl_set(void *c, uint32_t w, uint32_t h, uint32_t n,
                  struct tvpal_diag *d)
{
    return tvpal_glr_set_slices(c, w, h, n, d);
}

static void gl_up(void *c, uint32_t layer, const uint8_t *idx)
{
    tvpal_glr_upload(c, layer, idx);
}

static int gl_draw(void *c, const struct tvpal_frame *f, float *rgba,
                   struct tvpal_diag *d)
{
    return tvpal_glr_draw(c, f, rgba, d);
}

static void gl_times(const void *c, struct tvpal_render_times *t)
{
    tvpal_glr_times(c, &t->upload_ms, &t->draw_ms, &t->readback_ms);
}

static void gl_describe(const void *c, char *buf, size_t cap)
{
    const char *name = tvpal_glr_gl_name();
    snprintf(buf, cap, "%s", name ? name : "GL");
}

void tvpal_glr_renderer(struct tvpal_glr *r, struct tvpal_renderer *out)
{
    *out = (struct tvpal_renderer){.name = "gl", .ctx = r,
                                   .set_slices = gl_set, .upload = gl_up,
                                   .draw = gl_draw, .times = gl_times,
                                   .describe = gl_describe};
}
