/* disp_compositor.c: the display's multi-pass compositor
 * (disp_compositor.h). Over 600 lines on purpose: the passes share the GL
 * state they set up one after the other, which one file keeps in view. */
#include "display/disp_compositor.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/grow.h"
#include "display/disp_screen.h"
#include "display/gl_shaders.h"
#include "display/gl_target.h"

typedef struct mesh_prog {
    GLuint id;
    GLint u_mvp, u_texproj, u_rad_scale, u_color, u_tex[GL_ONE_PASS_MAX_TEX];
    GLint u_eye, u_transmission, u_ior, u_tri_base;
} mesh_prog;

struct disp_compositor {
    int width, height;
    gl_target hdr;       /* linear float image + depth (multisampled when samples > 1) */
    gl_target res;       /* hdr resolved to one sample a pixel (samples > 1 only) */
    int samples;
    gl_target ldr;       /* tone-mapped 8-bit image (headless "screen") */
    gl_target base;      /* radiosity + glass of base_cam, no corrections (made on first use) */
    bool base_ok;        /* base holds base_cam's view of scene base_scene */
    disp_screen *screen; /* the base's surfaces and the screen pass (one sample a pixel only) */
    bool base_gbuf;      /* the base holds its surfaces (else corrections go over the mesh) */
    disp_rect *within;   /* per drawn texture: its node's projected bounds */
    size_t within_cap;
    ct_camera base_cam, last_cam;
    uint64_t base_scene, last_scene;   /* disp_scene_serial; 0: none */
    mesh_prog mesh[GL_PASS_COUNT];   /* GL_PASS_ONE's slot unused: see one[] */
    mesh_prog one[GL_ONE_PASS_MAX_TEX];   /* one-pass programs for 1..4 textures */
    GLuint tonemap, points_world, flat_screen;
    GLint pw_mvp, pw_eye, pw_pull, pw_point, pw_color, fs_color;
    GLuint pw_vao, pw_vbo;
    uint32_t npoints;    /* sample points in pw_vbo */
    GLint tm_image, tm_exposure, tm_mode;
    GLuint empty_vao;
    /* draw segments, reused between frames */
    uint32_t *bounds;
    size_t bounds_cap;
    const disp_texture **seg_tex;   /* the textures of every segment, one run each */
    size_t seg_tex_cap;
    struct segment *segs;
    size_t segs_cap;
};

/* A run of triangles [b, e) covered by the same textures seg_tex[first ..
 * first + m); drawn untextured ones first, then textured ones nearest first. */
typedef struct segment {
    uint32_t b, e;
    uint32_t first, m;
    float key;   /* depth of the far end of the innermost texture's node */
    bounds3 box; /* world bounds of the innermost texture's node (textured ones) */
    bool glass;  /* inside a glass run: drawn by the glass passes */
} segment;

const char *disp_view_name(disp_view v)
{
    static const char *const names[] = {"full", "radiosity", "corrections", "assignment", "samples"};
    return (unsigned)v < DISP_VIEW_COUNT ? names[v] : "?";
}

static int build_mesh_prog(mesh_prog *p, int pass, int ntex, ct_error *err)
{
    char defs[64], name[32];
    snprintf(defs, sizeof defs, "#define PASS %d\n#define NTEX %d\n", pass, ntex);
    snprintf(name, sizeof name, "mesh-pass-%d-%d", pass, ntex);
    int rc = gl_program_build(name, gl_src_mesh_vs, gl_src_mesh_fs, defs, &p->id, err);
    if (rc) return rc;
    p->u_mvp = gl.GetUniformLocation(p->id, "u_mvp");
    p->u_texproj = gl.GetUniformLocation(p->id, "u_texproj");
    p->u_rad_scale = gl.GetUniformLocation(p->id, "u_rad_scale");
    p->u_color = gl.GetUniformLocation(p->id, "u_color");
    p->u_eye = gl.GetUniformLocation(p->id, "u_eye");
    p->u_transmission = gl.GetUniformLocation(p->id, "u_transmission");
    p->u_ior = gl.GetUniformLocation(p->id, "u_ior");
    p->u_tri_base = gl.GetUniformLocation(p->id, "u_tri_base");
    gl.UseProgram(p->id);
    for (int k = 0; k < GL_ONE_PASS_MAX_TEX; k++) {
        char u[16];
        snprintf(u, sizeof u, "u_tex%d", k);
        p->u_tex[k] = gl.GetUniformLocation(p->id, u);
        if (p->u_tex[k] >= 0) gl.Uniform1i(p->u_tex[k], k);
    }
    gl.UseProgram(0);
    return CT_OK;
}

int disp_compositor_new(int width, int height, unsigned float_format, int samples, disp_compositor **out,
                        ct_error *err)
{
    *out = NULL;
    if (!float_format) float_format = GL_RGBA32F;
    if (float_format != GL_RGBA32F && float_format != GL_RGBA16F)
        return ct_fail(err, CT_EINVAL, "float framebuffer format 0x%x is not RGBA32F or RGBA16F",
                       float_format);
    disp_compositor *c = calloc(1, sizeof *c);
    if (!c) return ct_fail(err, CT_ENOMEM, "out of memory for the compositor");
    c->width = width;
    c->height = height;
    c->samples = samples > 1 ? samples : 1;
    int rc = gl_target_init(&c->hdr, width, height, float_format, true, c->samples, err);
    if (!rc && c->samples > 1) rc = gl_target_init(&c->res, width, height, float_format, false, 1, err);
    if (!rc) rc = gl_target_init(&c->ldr, width, height, GL_RGBA8, false, 1, err);
    for (int p = 0; p < GL_PASS_COUNT && !rc; p++)
        if (p != GL_PASS_ONE) rc = build_mesh_prog(&c->mesh[p], p, 1, err);
    for (int k = 0; k < GL_ONE_PASS_MAX_TEX && !rc; k++)
        rc = build_mesh_prog(&c->one[k], GL_PASS_ONE, k + 1, err);
    if (!rc) rc = gl_program_build("tonemap", gl_src_screen_vs, gl_src_tonemap_fs, NULL, &c->tonemap, err);
    if (!rc)
        rc = gl_program_build("points-world", gl_src_points_world_vs, gl_src_points_fs, NULL, &c->points_world, err);
    if (!rc) rc = gl_program_build("flat-screen", gl_src_screen_vs, gl_src_points_fs, NULL, &c->flat_screen, err);
    if (!rc && c->samples == 1) rc = disp_screen_new(width, height, &c->screen, err);
    if (rc) {
        disp_compositor_free(c);
        return rc;
    }
    c->tm_image = gl.GetUniformLocation(c->tonemap, "u_image");
    c->tm_exposure = gl.GetUniformLocation(c->tonemap, "u_exposure");
    c->tm_mode = gl.GetUniformLocation(c->tonemap, "u_mode");
    c->pw_mvp = gl.GetUniformLocation(c->points_world, "u_mvp");
    c->pw_eye = gl.GetUniformLocation(c->points_world, "u_eye");
    c->pw_pull = gl.GetUniformLocation(c->points_world, "u_pull");
    c->pw_point = gl.GetUniformLocation(c->points_world, "u_point");
    c->pw_color = gl.GetUniformLocation(c->points_world, "u_color");
    c->fs_color = gl.GetUniformLocation(c->flat_screen, "u_color");
    gl.GenVertexArrays(1, &c->pw_vao);
    gl.GenBuffers(1, &c->pw_vbo);
    gl.BindVertexArray(c->pw_vao);
    gl.BindBuffer(GL_ARRAY_BUFFER, c->pw_vbo);
    gl.EnableVertexAttribArray(0);
    gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), (const void *)0);
    gl.BindVertexArray(0);
    gl.GenVertexArrays(1, &c->empty_vao);
    rc = gl_check("compositor set-up", err);
    if (rc) {
        disp_compositor_free(c);
        return rc;
    }
    *out = c;
    return CT_OK;
}

void disp_compositor_free(disp_compositor *c)
{
    if (!c) return;
    gl_target_free(&c->hdr);
    gl_target_free(&c->res);
    gl_target_free(&c->ldr);
    gl_target_free(&c->base);
    disp_screen_free(c->screen);
    free(c->within);
    for (int p = 0; p < GL_PASS_COUNT; p++)
        if (c->mesh[p].id) gl.DeleteProgram(c->mesh[p].id);
    for (int k = 0; k < GL_ONE_PASS_MAX_TEX; k++)
        if (c->one[k].id) gl.DeleteProgram(c->one[k].id);
    if (c->tonemap) gl.DeleteProgram(c->tonemap);
    if (c->points_world) gl.DeleteProgram(c->points_world);
    if (c->flat_screen) gl.DeleteProgram(c->flat_screen);
    if (c->pw_vao) gl.DeleteVertexArrays(1, &c->pw_vao);
    if (c->pw_vbo) gl.DeleteBuffers(1, &c->pw_vbo);
    if (c->empty_vao) gl.DeleteVertexArrays(1, &c->empty_vao);
    free(c->bounds);
    free(c->seg_tex);
    free(c->segs);
    free(c);
}

void disp_compositor_depth_range(const disp_scene *s, const ct_camera *cam, float *znear,
                                 float *zfar)
{
    bounds3 b = disp_scene_bounds(s);
    vec3 f;
    cam_axes(cam, NULL, NULL, &f);
    float dmax = 0.0f;
    for (int i = 0; i < 8; i++) {
        float d = v3_dot(v3_sub(b3_corner(b, i), cam->eye), f);
        if (d > dmax) dmax = d;
    }
    float diag = v3_len(b3_extent(b));
    *zfar = fmaxf(dmax * 1.01f + 1e-3f * diag, 1e-3f);
    /* Reversed float depth (zn / distance) resolves a float's 24 bits
     * relative to the distance whatever znear is, so the near plane can sit
     * where it clips nothing seen: at zfar / 10^3 a room inside a ground
     * plane 10^4 times its size was clipped away, and at a field of view
     * near 180 degrees so were the pixels looking sideways (a wall at 1 m
     * seen at 89.99 degrees off the axis is 0.2 mm ahead along it).
     * A 24-bit depth buffer resolves dz = z^2 / (znear 2^24) at distance z:
     * with znear = zfar / 10^4 that was 1.5 mm at 8 m in the office, and a
     * whiteboard 1 mm in front of its frame z-fought with it (the frame's
     * corrections showed through in black and white). zfar / 10^3 resolves
     * 0.15 mm there and clips only geometry nearer than a thousandth of the
     * scene's depth (2.5 cm in the office, 1.7 mm in the Cornell box). */
    *znear = gl.reversed_z ? fmaxf(*zfar * CT_NEAR_SHARE, 1e-12f) : fmaxf(*zfar * 1e-3f, 1e-6f);
}

/* "Nearer" and "as near" for the depth convention in use (gl_load.h). */
static GLenum depth_less(void) { return gl.reversed_z ? GL_GREATER : GL_LESS; }
static GLenum depth_lequal(void) { return gl.reversed_z ? GL_GEQUAL : GL_LEQUAL; }

static void set_texproj(const mesh_prog *p, const disp_texture *const *tex, int n)
{
    float m[GL_ONE_PASS_MAX_TEX][16];
    for (int k = 0; k < GL_ONE_PASS_MAX_TEX; k++) {
        mat4 x = k < n ? tex[k]->proj : m4_identity();
        memcpy(m[k], x.m, sizeof m[k]);
    }
    /* Row-major mat4: upload transposed (vecmath.h). */
    gl.UniformMatrix4fv(p->u_texproj, GL_ONE_PASS_MAX_TEX, GL_TRUE, &m[0][0]);
    for (int k = 0; k < n && k < GL_ONE_PASS_MAX_TEX; k++) {
        gl.ActiveTexture(GL_TEXTURE0 + (GLenum)k);
        gl.BindTexture(GL_TEXTURE_2D, tex[k]->gl_tex);
    }
    gl.ActiveTexture(GL_TEXTURE0);
}

static void use_mesh(const mesh_prog *p, const float *mvp, float rad_scale)
{
    gl.UseProgram(p->id);
    gl.UniformMatrix4fv(p->u_mvp, 1, GL_TRUE, mvp);
    if (p->u_rad_scale >= 0) gl.Uniform1f(p->u_rad_scale, rad_scale);
}

static bool drawable(const disp_texture *x, uint32_t ntris)
{
    return x->has_proj && x->tri_end > x->tri_begin && x->tri_end <= ntris;
}

/* Passes 2 and 3 (§4.3) for the given textures. */
static void correction_passes(disp_compositor *c, const disp_scene *s,
                              const disp_texture *const *tex, uint32_t n, const float *mvp,
                              bool all_positive, disp_render_stats *st)
{
    if (!n) return;
    gl.Enable(GL_BLEND);
    gl.BlendFunc(GL_ONE, GL_ONE);
    gl.DepthMask(GL_FALSE);
    gl.DepthFunc(depth_lequal());
    gl.BlendEquation(GL_FUNC_ADD);
    use_mesh(&c->mesh[GL_PASS_POS], mvp, 1.0f);
    for (uint32_t i = 0; i < n; i++) {
        set_texproj(&c->mesh[GL_PASS_POS], &tex[i], 1);
        disp_scene_draw(s, tex[i]->tri_begin, tex[i]->tri_end);
        st->draws++;
    }
    if (!all_positive) {
        gl.BlendEquation(GL_FUNC_REVERSE_SUBTRACT);
        use_mesh(&c->mesh[GL_PASS_NEG], mvp, 1.0f);
        for (uint32_t i = 0; i < n; i++) {
            if (!tex[i]->negative) continue;
            set_texproj(&c->mesh[GL_PASS_NEG], &tex[i], 1);
            disp_scene_draw(s, tex[i]->tri_begin, tex[i]->tri_end);
            st->draws++;
            st->pass3 = true;
        }
        gl.BlendEquation(GL_FUNC_ADD);
    }
    gl.Disable(GL_BLEND);
    gl.DepthMask(GL_TRUE);
    gl.DepthFunc(depth_less());
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

/* Whether sorted triangle t lies in one of the ng glass runs (in order). */
static bool in_glass(const disp_glass *g, uint32_t ng, uint32_t t)
{
    uint32_t lo = 0, hi = ng;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (g[mid].end <= t) lo = mid + 1;
        else hi = mid;
    }
    return lo < ng && g[lo].begin <= t;
}

static int by_draw_order(const void *pa, const void *pb)
{
    const segment *a = pa, *b = pb;
    if ((a->m == 0) != (b->m == 0)) return a->m == 0 ? -1 : 1;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return a->b < b->b ? -1 : a->b > b->b;
}

/* Cuts the mesh at every drawable texture's range ends into segments, each
 * with the textures covering all of it (untextured neighbours merged), in
 * drawing order: untextured segments first (cheap occluders), then textured
 * ones by the far depth of their innermost texture's node, nearest first.
 * The depth test runs before shading, so a fragment a nearer surface already
 * covers costs no texture lookups (on llvmpipe, which shades blocks of
 * pixels together, only when its whole block is hidden): drawn in mesh order, 32 % (cornell) to 47 % (table) of the
 * textured fragments of the benchmark scenes were hidden ones, 14 % and 42 %
 * in this order (the rest lie inside one part, e.g. its back faces). Every
 * view and pass 1 of the three-pass mode draw the same order, so they
 * resolve equal depths the same way. Returns the count in *nseg. */
static int build_segments(disp_compositor *c, const disp_scene *s, const disp_texture *const *tex,
                          uint32_t n, const ct_camera *cam, size_t *nseg, ct_error *err)
{
    uint32_t ntris = disp_scene_ntris(s), ng;
    const disp_glass *glass = disp_scene_glass(s, &ng);
    size_t ends = 2 * (size_t)n + 2 * (size_t)ng;
    int rc = ct_grow((void **)&c->bounds, &c->bounds_cap, ends + 2, sizeof *c->bounds, "draw segments", err);
    if (!rc) rc = ct_grow((void **)&c->segs, &c->segs_cap, ends + 1, sizeof *c->segs, "draw segments", err);
    if (rc) return rc;
    size_t nb = 0;
    c->bounds[nb++] = 0;
    c->bounds[nb++] = ntris;
    for (uint32_t i = 0; i < n; i++) {
        c->bounds[nb++] = tex[i]->tri_begin;
        c->bounds[nb++] = tex[i]->tri_end;
    }
    /* Glass runs are cut out: the glass passes draw them after the rest. */
    for (uint32_t i = 0; i < ng; i++) {
        c->bounds[nb++] = glass[i].begin;
        c->bounds[nb++] = glass[i].end;
    }
    qsort(c->bounds, nb, sizeof *c->bounds, cmp_u32);
    vec3 fwd;
    cam_axes(cam, NULL, NULL, &fwd);
    size_t ns = 0, used = 0;
    for (size_t k = 0; k + 1 < nb; k++) {
        uint32_t b = c->bounds[k], e = c->bounds[k + 1];
        if (b == e) continue;
        rc = ct_grow((void **)&c->seg_tex, &c->seg_tex_cap, used + n + 1, sizeof *c->seg_tex, "draw segments", err);
        if (rc) return rc;
        segment *g = &c->segs[ns++];
        g->first = (uint32_t)used;
        g->m = 0;
        const disp_texture *inner = NULL;
        for (uint32_t i = 0; i < n; i++)
            if (tex[i]->tri_begin <= b && e <= tex[i]->tri_end) {
                c->seg_tex[used + g->m++] = tex[i];
                if (!inner || tex[i]->tri_end - tex[i]->tri_begin < inner->tri_end - inner->tri_begin) inner = tex[i];
            }
        used += g->m;
        g->glass = in_glass(glass, ng, b);
        /* Merge following untextured segments into this one when it has none. */
        if (g->m == 0) {
            while (k + 2 < nb) {
                uint32_t b2 = c->bounds[k + 1], e2 = c->bounds[k + 2];
                bool covered = false;
                for (uint32_t i = 0; i < n && !covered && b2 < e2; i++)
                    covered = tex[i]->tri_begin <= b2 && e2 <= tex[i]->tri_end;
                if (covered || (b2 < e2 && in_glass(glass, ng, b2) != g->glass)) break;
                e = e2;
                k++;
            }
        }
        g->b = b;
        g->e = e;
        g->key = 0.0f;
        g->box = b3_empty();
        if (inner) {
            bounds3 nbx = disp_scene_node_bounds(s, inner->node);
            g->box = nbx;
            g->key = INFINITY;
            if (nbx.lo.x <= nbx.hi.x) {
                g->key = -INFINITY;
                for (int i = 0; i < 8; i++) g->key = fmaxf(g->key, v3_dot(v3_sub(b3_corner(nbx, i), cam->eye), fwd));
            }
        }
    }
    qsort(c->segs, ns, sizeof *c->segs, by_draw_order);
    *nseg = ns;
    return CT_OK;
}

/* One pass: each opaque segment is drawn once with the radiosity plus the
 * signed corrections of the (up to 4) textures covering it; untextured
 * segments with the plain radiosity program (no lookups). Glass segments
 * are left to the glass passes, and so are further textures on a segment
 * (rare: more than 4 stacked on one node): late_corrections. */
static void one_pass(disp_compositor *c, const disp_scene *s, size_t nseg, const float *mvp, float rad_scale,
                     disp_render_stats *st)
{
    for (size_t k = 0; k < nseg; k++) {
        const segment *g = &c->segs[k];
        if (g->glass) continue;
        const disp_texture **gt = c->seg_tex + g->first;
        uint32_t first = g->m < GL_ONE_PASS_MAX_TEX ? g->m : GL_ONE_PASS_MAX_TEX;
        const mesh_prog *p = first ? &c->one[first - 1] : &c->mesh[GL_PASS_RAD];
        use_mesh(p, mvp, rad_scale);
        if (first) set_texproj(p, gt, (int)first);
        disp_scene_draw(s, g->b, g->e);
        st->draws++;
    }
}

/* A pixel rectangle [x0, x1) x [y0, y1), GL's window coordinates (row 0 at
 * the bottom, as glScissor takes them). */
typedef struct px_rect {
    int x0, y0, x1, y1;
} px_rect;

static bool rect_empty(px_rect r) { return r.x0 >= r.x1 || r.y0 >= r.y1; }

static bool rects_meet(px_rect a, px_rect b) { return a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1; }

static px_rect rect_union(px_rect a, px_rect b)
{
    if (rect_empty(a)) return b;
    if (rect_empty(b)) return a;
    return (px_rect){a.x0 < b.x0 ? a.x0 : b.x0, a.y0 < b.y0 ? a.y0 : b.y0, a.x1 > b.x1 ? a.x1 : b.x1,
                     a.y1 > b.y1 ? a.y1 : b.y1};
}

static int clamp_px(float v, int n) { return v < 0.0f ? 0 : v > (float)n ? n : (int)v; }

/* The pixels b's projection may cover, a pixel wider each side (empty for
 * empty bounds; the whole target when b reaches behind the eye, where the
 * projection of its corners bounds nothing). With every corner in front,
 * the box projects into the hull of its projected corners. */
static px_rect screen_rect(const disp_compositor *c, const mat4 *mvp, bounds3 b)
{
    px_rect r = {c->width, c->height, 0, 0};
    if (b3_is_empty(b)) return r;
    float lx = INFINITY, ly = INFINITY, hx = -INFINITY, hy = -INFINITY;
    for (int i = 0; i < 8; i++) {
        vec4 q = m4_point4(mvp, b3_corner(b, i));
        if (!(q.w > 1e-6f)) return (px_rect){0, 0, c->width, c->height};
        float x = q.x / q.w, y = q.y / q.w;
        lx = fminf(lx, x); hx = fmaxf(hx, x);
        ly = fminf(ly, y); hy = fmaxf(hy, y);
    }
    float w = (float)c->width, h = (float)c->height;
    r.x0 = clamp_px(floorf((0.5f * lx + 0.5f) * w) - 1.0f, c->width);
    r.x1 = clamp_px(ceilf((0.5f * hx + 0.5f) * w) + 1.0f, c->width);
    r.y0 = clamp_px(floorf((0.5f * ly + 0.5f) * h) - 1.0f, c->height);
    r.y1 = clamp_px(ceilf((0.5f * hy + 0.5f) * h) + 1.0f, c->height);
    return r;
}

/* After one_pass: where glass lies in front, the corrections one_pass added
 * to the opaque surfaces seen through it are taken back (their samples hit
 * the glass, whose own corrections come later). The glass marks the
 * stencil where it passes the depth test; the textured opaque segments are
 * drawn again there with the plain radiosity program at equal depth, each
 * pixel once (the first segment to reach it, as one_pass's strict depth
 * test kept the first of equal depths). Costs a draw per glass run and one
 * per textured segment, with fragments only behind glass; no lookups in
 * the one pass itself. Both are kept to the glass's screen rectangle (the
 * scissor), and segments whose node lies wholly outside it are not drawn:
 * on a CPU rasteriser every triangle costs, drawn or not. */
static void uncorrect_behind_glass(disp_compositor *c, const disp_scene *s, size_t nseg, const mat4 *mvp4,
                                   float rad_scale, disp_render_stats *st)
{
    uint32_t ng;
    const disp_glass *glass = disp_scene_glass(s, &ng);
    const float *mvp = &mvp4->m[0][0];
    px_rect gr = {c->width, c->height, 0, 0};   /* empty: no glass in view */
    for (uint32_t i = 0; i < ng; i++) gr = rect_union(gr, screen_rect(c, mvp4, glass[i].bounds));
    if (rect_empty(gr)) return;
    gl.Enable(GL_SCISSOR_TEST);
    gl.Scissor(gr.x0, gr.y0, gr.x1 - gr.x0, gr.y1 - gr.y0);
    gl.Enable(GL_STENCIL_TEST);
    gl.StencilFunc(GL_ALWAYS, 1, 0xff);
    gl.StencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
    gl.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    gl.DepthMask(GL_FALSE);
    use_mesh(&c->mesh[GL_PASS_RAD], mvp, rad_scale);
    for (uint32_t i = 0; i < ng; i++) {
        disp_scene_draw(s, glass[i].begin, glass[i].end);
        st->draws++;
    }
    gl.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    gl.StencilFunc(GL_EQUAL, 1, 0xff);
    gl.StencilOp(GL_KEEP, GL_KEEP, GL_INCR);
    gl.DepthFunc(depth_lequal());
    for (size_t k = 0; k < nseg; k++) {
        const segment *g = &c->segs[k];
        if (g->glass || !g->m) continue;
        if (!rects_meet(screen_rect(c, mvp4, g->box), gr)) continue;
        disp_scene_draw(s, g->b, g->e);
        st->draws++;
    }
    gl.Disable(GL_STENCIL_TEST);
    gl.Disable(GL_SCISSOR_TEST);
    gl.DepthFunc(depth_less());
    gl.DepthMask(GL_TRUE);
}

/* After the glass passes of the one-pass mode: the corrections one_pass
 * left (glass segments', and a segment's fifth texture on), added signed
 * by the one-pass programs with the radiosity scaled to zero, up to 4
 * textures a draw (the float target holds negative sums, so the add and
 * reverse-subtract of passes 2/3 need not be split); the depth test keeps
 * them off what lies behind the nearest glass. With `all`, every
 * segment's corrections: the one-pass mode over a kept base. */
static void late_corrections(disp_compositor *c, const disp_scene *s, size_t nseg, const float *mvp, bool all,
                             disp_render_stats *st)
{
    bool any = false;
    for (size_t k = 0; k < nseg; k++) {
        const segment *g = &c->segs[k];
        const disp_texture **gt = c->seg_tex + g->first;
        for (uint32_t i = g->glass || all ? 0 : GL_ONE_PASS_MAX_TEX; i < g->m; i += GL_ONE_PASS_MAX_TEX) {
            if (!any) {
                gl.Enable(GL_BLEND);
                gl.BlendEquation(GL_FUNC_ADD);
                gl.BlendFunc(GL_ONE, GL_ONE);
                gl.DepthMask(GL_FALSE);
                gl.DepthFunc(depth_lequal());
                any = true;
            }
            uint32_t m = g->m - i < GL_ONE_PASS_MAX_TEX ? g->m - i : GL_ONE_PASS_MAX_TEX;
            const mesh_prog *p = &c->one[m - 1];
            use_mesh(p, mvp, 0.0f);
            set_texproj(p, gt + i, (int)m);
            disp_scene_draw(s, g->b, g->e);
            st->draws++;
        }
    }
    if (!any) return;
    gl.Disable(GL_BLEND);
    gl.DepthMask(GL_TRUE);
    gl.DepthFunc(depth_less());
}

/* The glass passes: every glass fragment in front of the opaque surfaces
 * multiplies what lies behind it by transmission * (1 - F) (with
 * `multiply`; a product is order-independent, so glass layers need no
 * sorting), then the glass's depth goes into the depth buffer, so that
 * corrections land on the nearest glass and not on what shows through it
 * (the samples there hit the glass). */
static void glass_passes(disp_compositor *c, const disp_scene *s, const float *mvp, const ct_camera *cam,
                         bool multiply, bool gbuf, disp_render_stats *st)
{
    uint32_t ng;
    const disp_glass *g = disp_scene_glass(s, &ng);
    if (!ng) return;
    /* The multiplying pass writes no surface: the position buffer keeps
     * what lies behind until the depth pass puts the glass there. */
    if (gbuf) gl.ColorMaski(1, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    if (multiply) {
        const mesh_prog *p = &c->mesh[GL_PASS_GLASS];
        use_mesh(p, mvp, 1.0f);
        gl.Uniform3f(p->u_eye, cam->eye.x, cam->eye.y, cam->eye.z);
        gl.DepthMask(GL_FALSE);
        gl.Enable(GL_BLEND);
        gl.BlendEquation(GL_FUNC_ADD);
        gl.BlendFunc(GL_ZERO, GL_SRC_COLOR);
        for (uint32_t i = 0; i < ng; i++) {
            gl.Uniform3f(p->u_transmission, g[i].transmission.x, g[i].transmission.y, g[i].transmission.z);
            gl.Uniform1f(p->u_ior, g[i].ior);
            disp_scene_draw(s, g[i].begin, g[i].end);
            st->draws++;
        }
        gl.Disable(GL_BLEND);
        gl.DepthMask(GL_TRUE);
    }
    gl.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    const mesh_prog *p = &c->mesh[gbuf ? GL_PASS_GBUF : GL_PASS_RAD];
    if (gbuf) gl.ColorMaski(1, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    use_mesh(p, mvp, 0.0f);
    for (uint32_t i = 0; i < ng; i++) {
        if (gbuf) gl.Uniform1i(p->u_tri_base, (GLint)g[i].begin);
        disp_scene_draw(s, g[i].begin, g[i].end);
        st->draws++;
    }
    gl.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
}

static vec3 id_colour(uint32_t id)
{
    uint32_t h = id * 2654435761u;
    h ^= h >> 15;
    h *= 2246822519u;
    h ^= h >> 13;
    return v3(0.25f + 0.75f * (float)(h & 255) / 255.0f, 0.25f + 0.75f * (float)((h >> 8) & 255) / 255.0f,
              0.25f + 0.75f * (float)((h >> 16) & 255) / 255.0f);
}

int disp_compositor_set_points(disp_compositor *c, const float *a, uint32_t na, const float *b,
                               uint32_t nb, ct_error *err)
{
    size_t n = (size_t)na + nb, bytes = 3 * sizeof(float);
    gl.BindBuffer(GL_ARRAY_BUFFER, c->pw_vbo);
    gl.BufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(n * bytes), NULL, GL_STREAM_DRAW);
    if (na) gl.BufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(na * bytes), a);
    if (nb) gl.BufferSubData(GL_ARRAY_BUFFER, (GLintptr)(na * bytes), (GLsizeiptr)(nb * bytes), b);
    gl.BindBuffer(GL_ARRAY_BUFFER, 0);
    c->npoints = (uint32_t)n;
    return gl_check("sample point upload", err);
}

/* The samples view (Fig. 7): the image dimmed, then every sample point as a
 * dot in DISP_SAMPLE_COLOR (scaled against the exposure, so it shows as
 * that colour), hidden behind nearer geometry by the depth test. */
static void draw_samples(disp_compositor *c, const ct_camera *cam, const mat4 *mvp, float exposure)
{
    gl.Disable(GL_DEPTH_TEST);
    gl.Enable(GL_BLEND);
    gl.BlendFunc(GL_ZERO, GL_CONSTANT_COLOR);
    gl.BlendColor(DISP_SAMPLE_DIM, DISP_SAMPLE_DIM, DISP_SAMPLE_DIM, 1.0f);
    gl.UseProgram(c->flat_screen);
    gl.Uniform3f(c->fs_color, 0, 0, 0);
    gl.BindVertexArray(c->empty_vao);
    gl.DrawArrays(GL_TRIANGLES, 0, 3);
    gl.Disable(GL_BLEND);
    gl.Enable(GL_DEPTH_TEST);
    if (!c->npoints) return;
    float k = exp2f(-exposure);
    gl.DepthFunc(depth_lequal());
    gl.DepthMask(GL_FALSE);
    gl.Enable(GL_PROGRAM_POINT_SIZE);
    gl.UseProgram(c->points_world);
    gl.UniformMatrix4fv(c->pw_mvp, 1, GL_TRUE, &mvp->m[0][0]);
    gl.Uniform3f(c->pw_eye, cam->eye.x, cam->eye.y, cam->eye.z);
    gl.Uniform1f(c->pw_pull, 0.998f);
    gl.Uniform1f(c->pw_point, c->width >= 512 ? 3.0f : 1.0f);
    gl.Uniform3f(c->pw_color, k * DISP_SAMPLE_COLOR_R, k * DISP_SAMPLE_COLOR_G, k * DISP_SAMPLE_COLOR_B);
    gl.BindVertexArray(c->pw_vao);
    gl.DrawArrays(GL_POINTS, 0, (GLsizei)c->npoints);
    gl.Disable(GL_PROGRAM_POINT_SIZE);
    gl.DepthMask(GL_TRUE);
    gl.DepthFunc(depth_less());
}

/* The state every frame's passes start from (whatever the last frame or
 * the tone mapping left). */
static void frame_state(void)
{
    gl.Enable(GL_DEPTH_TEST);
    gl.DepthFunc(depth_less());
    gl.DepthMask(GL_TRUE);
    gl.Disable(GL_BLEND);
    gl.Disable(GL_CULL_FACE);
    gl.Disable(GL_STENCIL_TEST);
    gl.Disable(GL_SCISSOR_TEST);
}

static void clear_target(const gl_target *t)
{
    gl_target_bind(t, 0, 0);
    gl.ClearColor(0, 0, 0, 1);
    gl.ClearDepth(gl.reversed_z ? 0.0 : 1.0);
    frame_state();
    gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
}

/* Pass 1 of the 3-pass mode: the opaque segments' radiosity, then the glass
 * (multiplied over what it covers, and its depth). With gbuf (the kept
 * base), every surface left in front also goes into the position buffer. */
static void radiosity_pass(disp_compositor *c, const disp_scene *s, size_t nseg, const float *mvp,
                           const ct_camera *cam, float rad_scale, bool gbuf, disp_render_stats *st)
{
    const mesh_prog *p = &c->mesh[gbuf ? GL_PASS_GBUF : GL_PASS_RAD];
    use_mesh(p, mvp, rad_scale);
    for (size_t k = 0; k < nseg; k++) {
        if (c->segs[k].glass) continue;
        if (gbuf) gl.Uniform1i(p->u_tri_base, (GLint)c->segs[k].b);
        disp_scene_draw(s, c->segs[k].b, c->segs[k].e);
        st->draws++;
    }
    glass_passes(c, s, mvp, cam, rad_scale > 0.0f, gbuf, st);
}

/* Plans the corrections over a kept base in screen space (disp_screen.h),
 * each texture within its node's projected bounds, and says whether to
 * draw them so: on a CPU rasteriser the screen pass costs per pixel it
 * covers (a fetch of the kept surface and a projection besides the
 * lookup: about 21-25 ns of CPU a pixel on llvmpipe), the mesh path per
 * textured triangle sent again (about 0.44 us) and per textured pixel
 * (about 16 ns). With the screen pass's pixels about 1.3 times the
 * textured ones, the screen pass wins once the textured triangles are
 * about 1/50 of its pixels: the radiosity meshes of table and office (70
 * and 60 thousand textured triangles against 1.3-1.4 million pixels at
 * 1024x1024), not the Cornell stand-in of 3,086 triangles, where it cost
 * 37.5 against 26.9 CPU ms a still frame (docs/display.md, "Still views"). */
static int plan_screen(disp_compositor *c, const disp_scene *s, const disp_texture *const *tex, uint32_t n,
                       size_t nseg, const mat4 *mvp, disp_kept_corr kept, bool *use, disp_render_stats *st,
                       ct_error *err)
{
    int rc = ct_grow((void **)&c->within, &c->within_cap, n, sizeof *c->within, "texture rectangles", err);
    if (rc) return rc;
    for (uint32_t i = 0; i < n; i++) {
        px_rect r = screen_rect(c, mvp, disp_scene_node_bounds(s, tex[i]->node));
        c->within[i] = (disp_rect){r.x0, r.y0, r.x1, r.y1};
    }
    uint64_t px = 0;
    if ((rc = disp_screen_plan(c->screen, tex, c->within, n, &px, err))) return rc;
    uint64_t tris = 0;
    for (size_t k = 0; k < nseg; k++)
        if (c->segs[k].m) tris += c->segs[k].e - c->segs[k].b;
    *use = kept == DISP_KEPT_SCREEN || (kept == DISP_KEPT_AUTO && 50 * tris >= px);
    if (*use) st->screen_px = px;
    return CT_OK;
}

/* Makes the kept base hold the radiosity and glass of cam (with gbuf also
 * the surface each pixel shows), drawing it when it holds another view.
 * Radiosity and glass do not change with the texels, and they are most of
 * a frame's cost on a CPU rasteriser; the frame then starts from a copy of
 * the base, and the corrections over the mesh go over it with the depth
 * the base left (so they land where pass 1's surfaces are, as in passes 2
 * and 3). */
static int base_ready(disp_compositor *c, const disp_scene *s, size_t nseg, const float *mvp,
                      const ct_camera *cam, bool gbuf, disp_render_stats *st, ct_error *err)
{
    uint64_t serial = disp_scene_serial(s);
    if (!c->base_ok || c->base_scene != serial || !cam_same(&c->base_cam, cam) || c->base_gbuf != gbuf) {
        if (!c->base.fbo) {
            int rc = gl_target_init(&c->base, c->width, c->height, c->hdr.format, true, c->samples, err);
            if (rc) return rc;
        }
        if (gbuf) {
            int rc = disp_screen_attach(c->screen, c->base.fbo, err);
            if (rc) return rc;
        }
        clear_target(&c->base);
        static const GLenum both[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
        gl.DrawBuffers(gbuf ? 2 : 1, both);
        if (gbuf) {
            static const GLfloat none[4] = {-1.0f, 0.0f, 0.0f, 0.0f};   /* triangle index -1: background */
            gl.ClearBufferfv(GL_COLOR, 1, none);
        }
        disp_scene_bind(s);
        radiosity_pass(c, s, nseg, mvp, cam, 1.0f, gbuf, st);
        if (gbuf) {
            /* Once per kept view: which triangles each tile shows. */
            int rc = disp_screen_index(c->screen, c->base.fbo, err);
            if (rc) return rc;
        }
        c->base_ok = true;
        c->base_gbuf = gbuf;
        c->base_cam = *cam;
        c->base_scene = serial;
    } else {
        st->base_reused = true;
    }
    return CT_OK;
}

int disp_compositor_render(disp_compositor *c, const disp_scene *s, const disp_textures *t,
                           const ct_camera *cam, const disp_render_opts *o,
                           disp_render_stats *stats, ct_error *err)
{
    disp_render_stats st = {0};
    if (o->passes != 1 && o->passes != 3)
        return ct_fail(err, CT_EINVAL, "passes must be 1 or 3, not %d", o->passes);
    float zn, zf;
    disp_compositor_depth_range(s, cam, &zn, &zf);
    mat4 proj = cam_proj(cam, c->width, c->height, zn, zf);
    if (gl.reversed_z) {
        /* depth = zn / distance: 1 at the near plane, 0 at infinity. */
        proj.m[2][0] = proj.m[2][1] = proj.m[2][2] = 0.0f;
        proj.m[2][3] = zn;
    }
    mat4 mvp = m4_mul(proj, cam_view(cam));

    /* The drawable textures, in table order; for corrections only those that
     * ever held a non-zero texel (an all-zero one changes no pixel, and on a
     * CPU rasteriser every lookup costs). */
    uint32_t ntex = t ? disp_textures_count(t) : 0, n = 0;
    int rc = CT_OK;
    const disp_texture **tex = malloc(((size_t)ntex + 1) * sizeof *tex);
    if (!tex) return ct_fail(err, CT_ENOMEM, "out of memory listing %u textures", ntex);
    for (uint32_t i = 0; i < ntex; i++) {
        const disp_texture *x = disp_textures_at(t, i);
        if (drawable(x, disp_scene_ntris(s)) && (x->nonzero || o->view == DISP_VIEW_ASSIGNMENT)) tex[n++] = x;
    }

    /* The second frame in a row of the same camera and scene starts from
     * the kept base: a still view under streamed texels redraws only its
     * corrections. The first draws everything at once (a moving camera
     * never draws a base it would not use). */
    uint64_t serial = disp_scene_serial(s);
    bool again = c->last_scene == serial && cam_same(&c->last_cam, cam);
    c->last_scene = serial;
    c->last_cam = *cam;
    bool reuse = again && !o->full_redraw && o->view == DISP_VIEW_FULL;
    if (!reuse) {
        clear_target(&c->hdr);
        disp_scene_bind(s);
    }

    bool corrections = o->view == DISP_VIEW_FULL || o->view == DISP_VIEW_CORRECTIONS ||
                       o->view == DISP_VIEW_SAMPLES;
    float rad_scale = o->view == DISP_VIEW_CORRECTIONS ? 0.0f : 1.0f;
    /* Every view draws the mesh in the same segment order, so the views
     * (and the two modes) differ only by what they add. */
    size_t nseg = 0;
    rc = build_segments(c, s, tex, n, cam, &nseg, err);
    if (!rc && reuse) {
        /* The base keeps its surfaces whenever the screen pass may be
         * used (triangle indices travel as floats: exact below 2^24);
         * each frame then takes the cheaper way. */
        bool gbuf = o->passes == 1 && o->kept != DISP_KEPT_MESH && c->screen && disp_scene_ntris(s) <= (1u << 24);
        bool screen = false;
        rc = base_ready(c, s, nseg, &mvp.m[0][0], cam, gbuf, &st, err);
        if (!rc && gbuf) rc = plan_screen(c, s, tex, n, nseg, &mvp, o->kept, &screen, &st, err);
        if (!rc) {
            /* The screen pass needs no depth: its surfaces come from the
             * position buffer (and on llvmpipe the depth and stencil are a
             * third of the copy's bytes). */
            gl_target_copy(&c->base, &c->hdr, !screen);
            frame_state();
            disp_scene_bind(s);
        }
        st.screen_pass = screen;
        if (!rc && screen) rc = disp_screen_draw(c->screen, tex, n, &st.draws, err);
        else if (!rc && o->passes == 1) late_corrections(c, s, nseg, &mvp.m[0][0], true, &st);
        else if (!rc) correction_passes(c, s, tex, n, &mvp.m[0][0], o->all_positive, &st);
    } else if (!rc && corrections && o->passes == 1) {
        one_pass(c, s, nseg, &mvp.m[0][0], rad_scale, &st);
        if (n) uncorrect_behind_glass(c, s, nseg, &mvp, rad_scale, &st);
        glass_passes(c, s, &mvp.m[0][0], cam, rad_scale > 0.0f, false, &st);
        late_corrections(c, s, nseg, &mvp.m[0][0], false, &st);
    } else if (!rc) {
        /* Pass 1 (glass after the opaque surfaces), then (with corrections)
         * passes 2 and 3. */
        radiosity_pass(c, s, nseg, &mvp.m[0][0], cam, rad_scale, false, &st);
        if (corrections) correction_passes(c, s, tex, n, &mvp.m[0][0], o->all_positive, &st);
    }
    if (!rc && o->view == DISP_VIEW_ASSIGNMENT && n) {
        /* Fig. 5: each textured node in its texture's colour over the radiosity. */
        gl.Enable(GL_BLEND);
        gl.BlendColor(0, 0, 0, 0.6f);
        gl.BlendFunc(GL_CONSTANT_ALPHA, GL_ONE_MINUS_CONSTANT_ALPHA);
        gl.DepthMask(GL_FALSE);
        gl.DepthFunc(depth_lequal());
        const mesh_prog *p = &c->mesh[GL_PASS_FLAT];
        use_mesh(p, &mvp.m[0][0], 1.0f);
        for (uint32_t i = 0; i < n; i++) {
            vec3 col = id_colour(tex[i]->id);
            gl.Uniform3f(p->u_color, col.x, col.y, col.z);
            disp_scene_draw(s, tex[i]->tri_begin, tex[i]->tri_end);
            st.draws++;
        }
        gl.Disable(GL_BLEND);
        gl.DepthMask(GL_TRUE);
        gl.DepthFunc(depth_less());
    }
    if (!rc && o->view == DISP_VIEW_SAMPLES) draw_samples(c, cam, &mvp, o->exposure);
    st.textures_drawn = corrections ? n : 0;
    free(tex);
    gl.BindVertexArray(0);
    gl.UseProgram(0);
    if (!rc && c->samples > 1) gl_target_resolve(&c->hdr, &c->res);
    if (stats) *stats = st;
    return rc ? rc : gl_check("frame rendering", err);
}

/* The single-sampled linear image of the last render. */
static const gl_target *shown(const disp_compositor *c) { return c->samples > 1 ? &c->res : &c->hdr; }

int disp_compositor_present(disp_compositor *c, const disp_render_opts *o, bool to_window, int win_w,
                            int win_h, ct_error *err)
{
    gl_target_bind(to_window ? NULL : &c->ldr, win_w, win_h);
    gl.Disable(GL_DEPTH_TEST);
    gl.Disable(GL_BLEND);
    if (to_window && (int64_t)win_w * c->height != (int64_t)win_h * c->width && win_w > 0 && win_h > 0) {
        /* A window of another shape than the image (a tiling window manager,
         * a user's resize) shows it whole at its own aspect ratio, black
         * bars beside it; it was stretched (600 x 200 squashed a square
         * view), and the master samples the image's size, not the window's. */
        double sc = fmin((double)win_w / c->width, (double)win_h / c->height);
        int vw = (int)fmax(1.0, round(c->width * sc)), vh = (int)fmax(1.0, round(c->height * sc));
        gl.ClearColor(0, 0, 0, 1);
        gl.Clear(GL_COLOR_BUFFER_BIT);
        gl.Viewport((win_w - vw) / 2, (win_h - vh) / 2, vw, vh);
    }
    gl.UseProgram(c->tonemap);
    gl.ActiveTexture(GL_TEXTURE0);
    gl.BindTexture(GL_TEXTURE_2D, shown(c)->color);
    gl.Uniform1i(c->tm_image, 0);
    gl.Uniform1f(c->tm_exposure, o->exposure);
    gl.Uniform1i(c->tm_mode, o->view == DISP_VIEW_CORRECTIONS ? 1 : 0);
    gl.BindVertexArray(c->empty_vao);
    gl.DrawArrays(GL_TRIANGLES, 0, 3);
    gl.BindVertexArray(0);
    gl.UseProgram(0);
    gl.Enable(GL_DEPTH_TEST);
    return gl_check("tone mapping", err);
}

/* GL reads rows bottom first; images keep row 0 at the top. In place (the
 * readers used to take a second, RGBA copy of the image: 16 MiB a frame at
 * 1024² for the linear one, and a zeroed image when that allocation failed). */
static void flip_rows(void *img, size_t row_bytes, int h)
{
    uint8_t *p = img, tmp[256];
    for (int y = 0; y < h / 2; y++) {
        uint8_t *a = p + (size_t)y * row_bytes, *b = p + (size_t)(h - 1 - y) * row_bytes;
        for (size_t o = 0; o < row_bytes; o += sizeof tmp) {
            size_t n = row_bytes - o < sizeof tmp ? row_bytes - o : sizeof tmp;
            memcpy(tmp, a + o, n);
            memcpy(a + o, b + o, n);
            memcpy(b + o, tmp, n);
        }
    }
}

void disp_compositor_read_linear(disp_compositor *c, float *rgb)
{
    gl_target_read_f32(shown(c), rgb);
    flip_rows(rgb, 3 * sizeof *rgb * (size_t)c->width, c->height);
}

void disp_compositor_read_display(disp_compositor *c, uint8_t *rgb)
{
    gl_target_read_u8(&c->ldr, 0, 0, rgb);
    flip_rows(rgb, 3 * (size_t)c->width, c->height);
}

void disp_compositor_read_window(int win_w, int win_h, uint8_t *rgb)
{
    gl_target_read_u8(NULL, win_w, win_h, rgb);
    flip_rows(rgb, 3 * (size_t)win_w, win_h);
}
