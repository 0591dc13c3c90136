/* See-through glass in the interactive solution: what the display draws
 * through glass (one and three passes) is, pixel by pixel, the L_base the
 * tracer gives the samples that hit the glass (the radiosity behind it times
 * transmission * (1 - F) per crossing, two glass objects stacked); and
 * corrections land on the nearest glass, never on what shows through it. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tests/support/disp_fixture.h"
#include "tests/support/testscenes.h"
#include "tracer/tracer.h"

#define W 64
#define H 48
/* GL against the tracer (linear radiance up to 0.8): the glass pass takes
 * its Fresnel angle from screen-space derivatives, the tracer from the face
 * normal; float differences only. */
#define TOL 2e-3

/* Node ids of the scene. */
typedef struct glass_nodes {
    int red, blue, slab, cube;
} glass_nodes;

/* Two walls (red left, blue right) 5 m in front of the camera, a glass slab
 * 3 m ahead covering the middle of the view, and a green-tinted glass cube
 * in front of part of it; stand-in radiosity: the walls' diffuse colour. */
static ct_scene *glass_scene(glass_nodes *nd, ct_radmesh *rad, ct_error *err)
{
    ct_scene *s = scene_new("glass");
    if (!s) return NULL;
    scene_material g = scene_material_default("glass");
    g.dielectric = 1;
    g.ior = 1.5f;
    g.transmission = v3(0.95f, 0.9f, 0.85f);
    scene_material tint = g;
    snprintf(tint.name, sizeof tint.name, "tint");
    tint.ior = 1.3f;
    tint.transmission = v3(0.5f, 1.0f, 0.6f);
    int red = ts_diffuse(s, "red", v3(0.8f, 0.2f, 0.1f), v3s(0.0f), err);
    int blue = ts_diffuse(s, "blue", v3(0.1f, 0.3f, 0.8f), v3s(0.0f), err);
    int gm = scene_add_material(s, &g, err), tm = scene_add_material(s, &tint, err);
    int rc = red < 0 || blue < 0 || gm < 0 || tm < 0;
    if (!rc) rc = (nd->red = ts_quad(s, "red_wall", (uint32_t)red, v3(-5, -5, -2), v3(5, 0, 0), v3(0, 10, 0), err)) < 0;
    if (!rc) rc = (nd->blue = ts_quad(s, "blue_wall", (uint32_t)blue, v3(0, -5, -2), v3(5, 0, 0), v3(0, 10, 0), err)) < 0;
    if (!rc) rc = (nd->slab = ts_box(s, "slab", (uint32_t)gm, v3(-1.5f, -1, -0.2f), v3(1.5f, 1, 0), false, err)) < 0;
    if (!rc) rc = (nd->cube = ts_box(s, "cube", (uint32_t)tm, v3(0.3f, -0.5f, 0.5f), v3(0.9f, 0.3f, 0.7f), false, err)) < 0;
    if (!rc) rc = scene_finalize(s, err);
    if (!rc) rc = rmesh_from_scene(s, v3s(1.0f), rad, err);
    if (rc) {
        scene_free(s);
        return NULL;
    }
    return s;
}

/* The node ids of glass_scene. */
static glass_nodes scene_nodes(void)
{
    glass_nodes nd;
    ct_radmesh rad;
    ct_error err;
    ct_scene *s = glass_scene(&nd, &rad, &err);
    cr_assert_not_null(s, "%s", err.msg);
    scene_free(s);
    rmesh_free(&rad);
    return nd;
}

/* Looks past the glass, down and to the left, so that the glass lies off
 * the image's centre on both axes (a mirrored screen rectangle of the
 * glass would then miss part of it). */
static ct_camera glass_camera(void) { return cam_look_at(v3(0, 0, 3), v3(-0.6f, -0.5f, -2), v3(0, 1, 0), 50.0f); }

/* The textures of a frame: a constant correction on the nodes given. */
typedef struct glass_setup {
    int ntex;
    uint32_t node[2];
    float value[2];
    mat4 proj[2];
} glass_setup;

/* Object-local parallel projection of x in [x0, x0 + sx], y in [y0, y0 + sy]. */
static mat4 xy_proj(float x0, float y0, float sx, float sy)
{
    mat4 m;
    memset(&m, 0, sizeof m);
    m.m[0][0] = 1.0f / sx;
    m.m[0][3] = -x0 / sx;
    m.m[1][1] = 1.0f / sy;
    m.m[1][3] = -y0 / sy;
    m.m[3][3] = 1.0f;
    return m;
}

static int setup(disp_session *s, void *ctx, ct_error *err)
{
    const glass_setup *f = ctx;
    glass_nodes nd;
    ct_radmesh m;
    ct_scene *sc = glass_scene(&nd, &m, err);
    if (!sc) return CT_EINVAL;
    scene_free(sc);
    int rc = disp_session_scene(s, &m, err);
    rmesh_free(&m);
    for (int i = 0; i < f->ntex && !rc; i++) {
        float rgb[4 * 4 * 3];
        for (int k = 0; k < 48; k++) rgb[k] = f->value[i];
        rc = disp_session_tex_alloc(s, (uint32_t)i + 1, f->node[i], 4, 4, DISP_PROJ_OBJECT_PARALLEL, err);
        if (!rc) rc = disp_session_tex_projection(s, (uint32_t)i + 1, &f->proj[i], err);
        if (!rc) rc = disp_session_tex_patch_float(s, (uint32_t)i + 1, 0, 0, 4, 4, rgb, err);
    }
    return rc;
}

/* The tracer's primary records at every pixel centre and at the 8
 * half-pixel neighbours; *usable: the pixel's 9 records agree (same node,
 * L_base within 0.01), so rasterisation rules cannot change its value. */
typedef struct base_image {
    ct_sample px[W * H];
    bool usable[W * H];
} base_image;

static void trace_bases(base_image *b)
{
    glass_nodes nd;
    ct_radmesh rad;
    ct_error err;
    ct_scene *s = glass_scene(&nd, &rad, &err);
    cr_assert_not_null(s, "%s", err.msg);
    trc_options o;
    trc_options_default(&o, TRC_MODE_REUSE);
    trc_tracer *t;
    cr_assert_eq(trc_new(s, &rad, &o, &t, &err), 0, "%s", err.msg);
    trc_view v = {glass_camera(), W, H};
    static ct_request req[9];
    ct_sample out[9];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            for (int k = 0; k < 9; k++) {
                memset(&req[k], 0, sizeof req[k]);
                req[k].id = (uint64_t)k;
                req[k].px = (float)x + 0.5f + 0.5f * (float)(k % 3 - 1);
                req[k].py = (float)y + 0.5f + 0.5f * (float)(k / 3 - 1);
            }
            trc_stats st = {0};
            trc_trace_primary(t, &v, req, 9, out, &st);
            size_t p = (size_t)y * W + (size_t)x;
            b->px[p] = out[4];
            bool ok = (out[4].flags & CT_SAMPLE_HIT) != 0;
            for (int k = 0; k < 9 && ok; k++) {
                vec3 d = v3_sub(out[k].l_base, out[4].l_base);
                ok = out[k].node == out[4].node && fmaxf(fabsf(d.x), fmaxf(fabsf(d.y), fabsf(d.z))) < 0.01f;
            }
            b->usable[p] = ok;
        }
    trc_free(t);
    rmesh_free(&rad);
    scene_free(s);
}

static bool glass_node(const glass_nodes *nd, uint32_t n) { return n == (uint32_t)nd->slab || n == (uint32_t)nd->cube; }

/* Renders with passes 1 and 3 and checks every usable pixel against
 * expect(pixel) (the L_base plus what corrections should add there). */
static void check_frames(const base_image *b, glass_setup *f, disp_view view, const char *what,
                         vec3 (*expect)(const base_image *, size_t, const glass_nodes *))
{
    glass_nodes nd = scene_nodes();
    ct_camera cam = glass_camera();
    /* frames 1: everything drawn at once; 3: the third frame of the same
     * camera, corrections over the kept base (1-pass: in screen space and
     * over the mesh) */
    for (int run = 0; run < 5; run++) {
        int passes = run % 2 ? 3 : 1, frames = run < 2 ? 1 : 3;
        disp_kept_corr kept = run == 2 ? DISP_KEPT_SCREEN : run == 4 ? DISP_KEPT_MESH : DISP_KEPT_AUTO;
        disp_render_opts o = {passes, view, 0.0f, false, false, kept};
        fx_frame fr;
        char msg[256];
        cr_assert_eq(fx_render_frames(GL_BACKEND_EGL, W, H, &cam, &o, frames, setup, f, &fr, msg, sizeof msg), 0,
                     "egl: %s", msg);
        double mx = 0.0;
        int used = 0, glass = 0, stacked = 0;
        for (size_t p = 0; p < (size_t)W * H; p++) {
            if (!b->usable[p]) continue;
            vec3 want = expect(b, p, &nd);
            const float *got = fr.linear + 3 * p;
            double d = fmax(fabs(got[0] - want.x), fmax(fabs(got[1] - want.y), fabs(got[2] - want.z)));
            if (d > mx) mx = d;
            used++;
            glass += glass_node(&nd, b->px[p].node);
            stacked += b->px[p].node == (uint32_t)nd.cube;
        }
        printf("metric: %s, %d-pass, frame %d%s: max |GL - expected| %.2e over %d pixels (%d through glass, %d "
               "through both), tolerance %.0e\n", what, passes, frames,
               run == 2 ? " (--kept-corrections screen)" : run == 4 ? " (--kept-corrections mesh)" : "", mx, used, glass, stacked, TOL);
        cr_expect_gt(glass, W * H / 4, "%s: only %d glass pixels comparable", what, glass);
        cr_expect_gt(stacked, 20, "%s: only %d pixels through both glasses", what, stacked);
        cr_expect_leq(mx, TOL, "%s, %d-pass, frame %d: max error %.3e", what, passes, frames, mx);
        fx_frame_free(&fr);
    }
}

static vec3 base_only(const base_image *b, size_t p, const glass_nodes *nd)
{
    (void)nd;
    return b->px[p].l_base;
}

Test(disp_glass, glass_shows_the_tracers_l_base)
{
    static base_image b;
    trace_bases(&b);
    glass_setup none = {0};
    check_frames(&b, &none, DISP_VIEW_RADIOSITY, "radiosity view", base_only);
    check_frames(&b, &none, DISP_VIEW_FULL, "full view, no textures", base_only);
}

/* +0.25 on the red wall, -0.125 on the slab: the slab's pixels (and the
 * cube's, which the slab's texture does not cover: it is not the slab's
 * node) get the slab's correction only where the slab is the nearest glass;
 * the wall's correction shows where the wall is seen directly, not through
 * glass. */
static vec3 corrected(const base_image *b, size_t p, const glass_nodes *nd)
{
    vec3 v = b->px[p].l_base;
    uint32_t n = b->px[p].node;
    if (n == (uint32_t)nd->red) v = v3_add(v, v3s(0.25f));
    if (n == (uint32_t)nd->slab) v = v3_add(v, v3s(-0.125f));
    return v;
}

Test(disp_glass, corrections_land_on_the_nearest_glass)
{
    static base_image b;
    trace_bases(&b);
    glass_nodes nd = scene_nodes();
    glass_setup f = {2, {(uint32_t)nd.red, (uint32_t)nd.slab}, {0.25f, -0.125f},
                     {xy_proj(-5, -5, 10, 10), xy_proj(-1.5f, -1, 3, 2)}};
    /* Some red-wall pixels are seen directly, some through the slab. */
    int direct = 0, behind = 0;
    for (size_t p = 0; p < (size_t)W * H; p++) {
        if (!b.usable[p]) continue;
        direct += b.px[p].node == (uint32_t)nd.red;
        behind += b.px[p].node == (uint32_t)nd.slab && b.px[p].l_base.x > b.px[p].l_base.z;
    }
    cr_assert(direct > 20 && behind > 20, "%d red pixels seen directly, %d through the slab", direct, behind);
    check_frames(&b, &f, DISP_VIEW_FULL, "corrections on the wall and the slab", corrected);
}
