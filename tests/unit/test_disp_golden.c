/* Golden images of the radiosity pass: the box mesh drawn by OSMesa and by
 * EGL agrees with a software Gouraud rasterisation at pixel centres, and the
 * two backends agree with each other; a surface 1 mm in front of another
 * (a whiteboard on its frame) does not z-fight with it across a deep scene;
 * multisampling averages the edges toward the pixel's mean. */
#include <criterion/criterion.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tests/support/disp_fixture.h"
#include "tests/support/testscenes.h"
#include "display/gl_load.h"

#define W 96
#define H 72
/* Tolerance against the software rasteriser (linear radiance, values in
 * 0.05..0.95): float interpolation differences only. */
#define TOL_REF 2e-3
/* Between the two headless backends. */
#define TOL_BACKENDS 1e-4

static int setup_box(disp_session *s, void *ctx, ct_error *err)
{
    (void)ctx;
    ct_radmesh m;
    int rc = fx_box_mesh(4, &m, NULL, err);
    if (rc) return rc;
    rc = disp_session_scene(s, &m, err);
    rmesh_free(&m);
    return rc;
}

static void compare_ref(const fx_frame *f, const fx_ref *ref, const char *name)
{
    size_t used = 0, bg = 0;
    double mx = 0, sum = 0;
    for (size_t p = 0; p < (size_t)W * H; p++) {
        if (!ref->smooth[p]) continue;
        if (ref->node[p] < 0) {
            bg++;
            for (int k = 0; k < 3; k++) cr_expect_eq(f->linear[3 * p + (size_t)k], 0.0f, "%s background pixel %zu", name, p);
            continue;
        }
        used++;
        for (int k = 0; k < 3; k++) {
            double d = fabs((double)f->linear[3 * p + (size_t)k] - ref->rgb[3 * p + (size_t)k]);
            sum += d;
            if (d > mx) mx = d;
        }
    }
    printf("metric: %s vs software Gouraud: max |diff| %.2e, mean %.2e over %zu interior pixels "
           "(+%zu background), tolerance %.0e\n", name, mx, used ? sum / (3.0 * (double)used) : 0.0,
           used, bg, TOL_REF);
    cr_expect_gt(used, (size_t)W * H / 2, "%s: only %zu pixels comparable", name, used);
    cr_expect_leq(mx, TOL_REF, "%s: max error %.3e over tolerance", name, mx);
}

Test(disp_golden, backends_match_software_gouraud)
{
    ct_radmesh m;
    ct_camera cam;
    fx_ref ref;
    ct_error err;
    cr_assert_eq(fx_box_reference(W, H, &m, NULL, &cam, &ref, &err), 0, "%s", err.msg);
    disp_render_opts o = {3, DISP_VIEW_RADIOSITY, 0.0f, false, false, DISP_KEPT_AUTO};
    fx_frame osm, egl;
    char msg[256];
    cr_assert_eq(fx_render(GL_BACKEND_OSMESA, W, H, &cam, &o, setup_box, NULL, &osm, msg, sizeof msg), 0,
                 "osmesa: %s", msg);
    cr_assert_eq(fx_render(GL_BACKEND_EGL, W, H, &cam, &o, setup_box, NULL, &egl, msg, sizeof msg), 0,
                 "egl: %s", msg);
    compare_ref(&osm, &ref, "osmesa");
    compare_ref(&egl, &ref, "egl");
    double mx, mean;
    fx_diff(osm.linear, egl.linear, (size_t)W * H * 3, &mx, &mean);
    printf("metric: osmesa vs egl: max |diff| %.2e, mean %.2e over all pixels, tolerance %.0e\n", mx,
           mean, TOL_BACKENDS);
    cr_expect_leq(mx, TOL_BACKENDS);
    int dmax = 0;
    for (size_t i = 0; i < (size_t)W * H * 3; i++) {
        int d = abs((int)osm.display[i] - (int)egl.display[i]);
        if (d > dmax) dmax = d;
    }
    cr_expect_leq(dmax, 1, "tone-mapped images differ by %d/255", dmax);
    fx_frame_free(&osm);
    fx_frame_free(&egl);
    fx_ref_free(&ref);
    rmesh_free(&m);
}

Test(disp_golden, rejects_bad_mesh)
{
    /* A triangle naming a vertex that does not exist must fail cleanly. */
    ct_radmesh m;
    ct_error err;
    cr_assert_eq(fx_box_mesh(1, &m, NULL, &err), 0, "%s", err.msg);
    m.tris[5] = m.nverts + 7;
    gl_backend *b = NULL;
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, 16, 16, NULL, false, &b, &err), 0, "%s", err.msg);
    disp_session *s = NULL;
    cr_assert_eq(disp_session_new(&s, &err), 0);
    cr_expect_eq(disp_session_scene(s, &m, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "vertex") != NULL, "message: %s", err.msg);
    m.tris[5] = 0;
    m.tri_node[0] = m.nnodes;
    cr_expect_eq(disp_session_scene(s, &m, &err), CT_ERANGE);
    cr_expect_eq(disp_session_tex_alloc(s, 1, 0, 4, 4, DISP_PROJ_OBJECT_PARALLEL, &err), CT_EPROTO);
    disp_session_free(s);
    gl_backend_close(b);
    rmesh_free(&m);
}

/* Gives session s the scene sc (freed) with the stand-in radiosity of
 * ambient 1 (white diffuse = 1); rc is the building's status so far. */
static int show_scene(disp_session *s, ct_scene *sc, int rc, ct_error *err)
{
    if (!rc) rc = scene_finalize(sc, err);
    ct_radmesh m;
    if (!rc) rc = rmesh_from_scene(sc, v3s(1.0f), &m, err);
    scene_free(sc);
    if (rc) return rc;
    rc = disp_session_scene(s, &m, err);
    rmesh_free(&m);
    return rc;
}

/* A 25 m deep scene (a floor strip sets the far plane), a black panel
 * `dist` metres ahead and a white one 1 mm in front of it, added after it so
 * that depth ties would go to the black one. */
typedef struct layers {
    float dist;
    bool reversed;   /* the depth convention the child must be using */
} layers;

static int setup_layers(disp_session *s, void *ctx, ct_error *err)
{
    const layers *l = ctx;
    if (gl.reversed_z != l->reversed)
        return ct_fail(err, CT_ESYS, "%s", l->reversed ? "no clip control: no reversed depth" : "reversed depth is on");
    ct_scene *sc = scene_new("layers");
    int dark = ts_diffuse(sc, "frame", v3s(0.0f), v3s(0.0f), err);
    int white = ts_diffuse(sc, "board", v3s(1.0f), v3s(0.0f), err);
    int rc = dark < 0 || white < 0 ? CT_EINVAL : CT_OK;
    float z = -l->dist;
    if (!rc && ts_quad(sc, "floor", (uint32_t)dark, v3(-1, -5, 0), v3(0, 0, -25), v3(2, 0, 0), err) < 0) rc = CT_EINVAL;
    if (!rc && ts_quad(sc, "frame", (uint32_t)dark, v3(-4, -4, z), v3(8, 0, 0), v3(0, 8, 0), err) < 0) rc = CT_EINVAL;
    if (!rc && ts_quad(sc, "board", (uint32_t)white, v3(-4, -4, z + 0.001f), v3(8, 0, 0), v3(0, 8, 0), err) < 0)
        rc = CT_EINVAL;
    return show_scene(s, sc, rc, err);
}

/* Board pixels (of the middle 16 x 16) that show the frame behind. */
static void layered(layers l)
{
    ct_camera cam = cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), 10.0f);
    fx_frame f;
    char msg[256];
    if (!l.reversed) setenv("CORRTEX_GL_REVERSED_Z", "0", 1);
    for (int passes = 1; passes <= 3; passes += 2) {
        disp_render_opts o = {passes, passes == 1 ? DISP_VIEW_FULL : DISP_VIEW_RADIOSITY, 0.0f, false, false, DISP_KEPT_AUTO};
        int rc = fx_render(GL_BACKEND_EGL, 32, 32, &cam, &o, setup_layers, &l, &f, msg, sizeof msg);
        if (rc && strstr(msg, "no clip control")) {
            unsetenv("CORRTEX_GL_REVERSED_Z");
            cr_skip_test("the GL context has no clip control");
        }
        cr_assert_eq(rc, 0, "egl: %s", msg);
        /* The 8 m wide panels fill the 10 degree view up to 45 m away. */
        int dark = 0;
        for (int y = 8; y < 24; y++)
            for (int x = 8; x < 24; x++)
                if (f.linear[3 * ((size_t)y * 32 + (size_t)x)] < 0.99f) dark++;
        printf("metric: %s depth, %d-pass, panels at %g m: %d of 256 board pixels show the frame 1 mm behind\n",
               l.reversed ? "reversed" : "classic", passes, (double)l.dist, dark);
        cr_expect_eq(dark, 0, "%d-pass: %d board pixels z-fight with the frame behind", passes, dark);
        fx_frame_free(&f);
    }
    unsetenv("CORRTEX_GL_REVERSED_Z");
}

/* Reversed float depth: 1 mm apart at 20 m of a 25 m deep scene. */
Test(disp_golden, one_millimetre_apart_at_twenty_metres) { layered((layers){20.0f, true}); }

/* The classic 24-bit fallback: 1 mm apart at 8 m (the office's whiteboard). */
Test(disp_golden, one_millimetre_apart_at_eight_metres_classic_depth) { layered((layers){8.0f, false}); }

/* Near geometry the near plane must not clip: a white panel 0.5 m ahead in
 * a scene 20 km deep (a ground plane around a room), and a closed white box
 * seen from inside at a 179.9 degree field of view (pixels looking nearly
 * sideways are a fraction of a millimetre ahead along the axis). With the
 * near plane at a thousandth of the scene's depth the first was black and
 * the second black at its edges. */
typedef struct near_case {
    bool box;   /* the box (else the panel in the deep scene) */
} near_case;

static int setup_near(disp_session *s, void *ctx, ct_error *err)
{
    const near_case *nc = ctx;
    if (!gl.reversed_z) return ct_fail(err, CT_ESYS, "no clip control: no reversed depth");
    ct_scene *sc = scene_new("near");
    int dark = ts_diffuse(sc, "ground", v3s(0.0f), v3s(0.0f), err);
    int white = ts_diffuse(sc, "white", v3s(1.0f), v3s(0.0f), err);
    int rc = dark < 0 || white < 0 ? CT_EINVAL : CT_OK;
    if (!rc && !nc->box) {
        if (ts_quad(sc, "ground", (uint32_t)dark, v3(-2e4f, -2e4f, -2e4f), v3(4e4f, 0, 0), v3(0, 4e4f, 0), err) < 0 ||
            ts_quad(sc, "panel", (uint32_t)white, v3(-0.2f, -0.2f, -0.5f), v3(0.4f, 0, 0), v3(0, 0.4f, 0), err) < 0)
            rc = CT_EINVAL;
    } else if (!rc) {
        /* Six faces of [-1, 1]^3 around the eye. */
        for (int a = 0; a < 3 && !rc; a++)
            for (int side = -1; side <= 1 && !rc; side += 2) {
                float c[3] = {-1, -1, -1}, e1[3] = {0, 0, 0}, e2[3] = {0, 0, 0};
                c[a] = (float)side;
                e1[(a + 1) % 3] = 2.0f;
                e2[(a + 2) % 3] = 2.0f;
                if (ts_quad(sc, "wall", (uint32_t)white, v3(c[0], c[1], c[2]), v3(e1[0], e1[1], e1[2]),
                            v3(e2[0], e2[1], e2[2]), err) < 0)
                    rc = CT_EINVAL;
            }
    }
    return show_scene(s, sc, rc, err);
}

static void near_geometry(near_case nc, float fov_deg)
{
    ct_camera cam = cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), fov_deg);
    fx_frame f;
    char msg[256];
    disp_render_opts o = {1, DISP_VIEW_RADIOSITY, 0.0f, false, false, DISP_KEPT_AUTO};
    int rc = fx_render(GL_BACKEND_EGL, 32, 32, &cam, &o, setup_near, &nc, &f, msg, sizeof msg);
    if (rc && strstr(msg, "no clip control")) cr_skip_test("the GL context has no clip control");
    cr_assert_eq(rc, 0, "egl: %s", msg);
    int black = 0;
    for (int p = 0; p < 32 * 32; p++)
        if (f.linear[3 * (size_t)p] < 0.99f) black++;
    printf("metric: %s, fov %g: %d of 1024 pixels clipped (not white)\n", nc.box ? "box from inside" : "panel in a deep scene",
           (double)fov_deg, black);
    cr_expect_eq(black, 0, "%d of 1024 pixels clipped by the near plane", black);
    fx_frame_free(&f);
}

Test(disp_golden, a_panel_half_a_metre_ahead_in_a_scene_twenty_km_deep) { near_geometry((near_case){false}, 40.0f); }

Test(disp_golden, a_box_seen_from_inside_at_a_179_degree_field_of_view) { near_geometry((near_case){true}, 179.9f); }

/* Multisampling (--msaa): with 4 samples a pixel the interior pixels keep
 * the single-sample values (the varyings are centroid-sampled, so a covered
 * pixel is shaded at its centre), and the pixels on the box's edges come
 * closer to the pixel's true mean, a 4x4-supersampled software
 * rasterisation box-filtered to the image, than the single-sample image
 * does: the error the edges of a centre-sampled image carry against a
 * reference that averages the whole pixel. */
Test(disp_golden, multisampling_averages_the_edges)
{
    ct_radmesh m;
    ct_camera cam;
    fx_ref ref;
    ct_error err;
    cr_assert_eq(fx_box_reference(W, H, &m, NULL, &cam, &ref, &err), 0, "%s", err.msg);
    enum { S = 4 };
    fx_ref fine;
    cr_assert_eq(fx_rasterise(&m, &cam, W * S, H * S, &fine), 0);
    disp_render_opts o = {1, DISP_VIEW_RADIOSITY, 0.0f, false, false, DISP_KEPT_AUTO};
    fx_frame one, ms;
    char msg[256];
    cr_assert_eq(fx_render_ms(GL_BACKEND_EGL, W, H, &cam, &o, 1, 1, setup_box, NULL, &one, msg, sizeof msg), 0,
                 "egl: %s", msg);
    cr_assert_eq(fx_render_ms(GL_BACKEND_EGL, W, H, &cam, &o, 4, 1, setup_box, NULL, &ms, msg, sizeof msg), 0,
                 "egl, 4 samples: %s", msg);
    double e_one = 0, e_ms = 0;
    size_t edges = 0, inner = 0, same = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t p = (size_t)y * W + (size_t)x;
            if (ref.smooth[p]) {
                /* the box's triangles have colours of their own: a pixel
                 * across two of them is averaged too, one inside one is not */
                inner++;
                double d = 0;
                for (int k = 0; k < 3; k++)
                    d = fmax(d, fabs((double)one.linear[3 * p + (size_t)k] - ms.linear[3 * p + (size_t)k]));
                same += d < 1e-5;
                continue;
            }
            edges++;
            for (int k = 0; k < 3; k++) {
                double mean = 0;
                for (int j = 0; j < S; j++)
                    for (int i = 0; i < S; i++)
                        mean += fine.rgb[3 * ((size_t)(S * y + j) * (size_t)(W * S) + (size_t)(S * x + i)) + (size_t)k];
                mean /= S * S;
                e_one += fabs((double)one.linear[3 * p + (size_t)k] - mean);
                e_ms += fabs((double)ms.linear[3 * p + (size_t)k] - mean);
            }
        }
    e_one /= 3.0 * (double)edges;
    e_ms /= 3.0 * (double)edges;
    printf("metric: %zu edge pixels, mean |diff| to the 16-sample mean: 1 sample %.4f, 4 samples %.4f (must be "
           "under half)\n", edges, e_one, e_ms);
    printf("metric: %zu of %zu pixels inside one part unchanged by multisampling (must be at least 3/4)\n", same,
           inner);
    cr_expect_gt(edges, (size_t)100, "only %zu edge pixels", edges);
    cr_expect_geq(4 * same, 3 * inner, "%zu of %zu inner pixels unchanged", same, inner);
    cr_expect_lt(e_ms, 0.5 * e_one, "4 samples %.4f against 1 sample %.4f", e_ms, e_one);
    fx_frame_free(&one);
    fx_frame_free(&ms);
    fx_ref_free(&fine);
    fx_ref_free(&ref);
    rmesh_free(&m);
}
