/* Tests of path tracing's and drt's two models of the lamps' light through
 * glass (trc_glass_light; docs/tracer.md, Light sampling, "Light through
 * glass, refracted"): shadow rays that pass glass straight and attenuated,
 * and refracted paths only (drt with a mesh: refracted photons). Through a
 * pane the two differ only by the pane's sideways shift of a crossing ray,
 * computed here, which catches light counted twice or not at all; drt's
 * refracted photons bring what refracted path tracing does; through a ball
 * lens only the refracted paths and photons find the focus. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/radmesh.h"
#include "tests/support/testscenes.h"
#include "tracer/tracer.h"

#define CHECK(x) do { int rc_ = (x); cr_assert_eq(rc_, 0, "%s: %s", #x, err.msg); } while (0)

typedef enum glass_shape { NO_GLASS, PANE, BALL } glass_shape;

/* A dark diffuse floor at y = 0 (little interreflection with the glass)
 * and a square lamp of side `lamp` at height `lamp_y`; above the floor's
 * origin a 6 x 6 pane from y = 1 up by `thick`, or a glass ball of radius
 * 0.5 centred 0.75 above the floor (a ball lens of index 1.5 focuses 1.5
 * radii from its centre: on the floor). */
static ct_scene *glass_scene(glass_shape shape, float lamp, float lamp_y, float thick)
{
    ct_error err;
    ct_scene *s = scene_new("glass light");
    int floor_m = ts_diffuse(s, "floor", v3s(0.05f), v3s(0.0f), &err);
    int lamp_m = ts_diffuse(s, "lamp", v3s(0.0f), v3s(10.0f), &err);
    int gm = ts_glass(s, "glass", 1.5f, v3(1.0f, 0.5f, 1.0f), &err);
    cr_assert(floor_m >= 0 && lamp_m >= 0 && gm >= 0, "%s", err.msg);
    /* about [-2, 2]^2 in tiles of 0.125 (drt reads its caustic photons at a
     * mesh's vertices), shifted so that the origin, where the tests look, is
     * a tile's centre; the rest of the 20 x 20 floor in four quads */
    const float lo = -2.0f - 0.0625f, hi = lo + 4.0f;
    for (int i = 0; i < 32; i++)
        for (int j = 0; j < 32; j++)
            cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(lo + 0.125f * (float)i, 0, lo + 0.125f * (float)j),
                              v3(0, 0, 0.125f), v3(0.125f, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(-10, 0, -10), v3(0, 0, 20), v3(lo + 10, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(hi, 0, -10), v3(0, 0, 20), v3(10 - hi, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(lo, 0, -10), v3(0, 0, lo + 10), v3(4, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(lo, 0, hi), v3(0, 0, 10 - hi), v3(4, 0, 0), &err) >= 0);
    /* the lamp faces down */
    cr_assert(ts_quad(s, "lamp", (uint32_t)lamp_m, v3(-lamp / 2, lamp_y, -lamp / 2), v3(lamp, 0, 0), v3(0, 0, lamp),
                      &err) >= 0);
    if (shape == PANE)
        cr_assert(ts_box(s, "pane", (uint32_t)gm, v3(-3, 1, -3), v3(3, 1.0f + thick, 3), false, &err) >= 0);
    if (shape == BALL)
        cr_assert(ts_smooth_sphere(s, "ball", (uint32_t)gm, v3(0, 0.75f, 0), 0.5f, 96, 48, &err) >= 0);
    CHECK(scene_finalize(s, &err));
    return s;
}

/* The mean radiance the mode gives the floor over n samples: at its origin,
 * seen from beside it, or (wide) over the square [-0.9, 0.9]^2 around it,
 * seen from above (y = 0.9, under the pane); drt with a stand-in radiosity
 * mesh of the scene's own triangles (no indirect light: the floor is dark)
 * and a photon count of its own. */
static vec3 mode_floor_light(const ct_scene *s, trc_mode mode, trc_glass_light gl, bool wide, int n)
{
    ct_error err;
    trc_options o;
    trc_options_default(&o, mode);
    o.glass_light = gl;
    if (mode == TRC_MODE_PATH) o.depth = 8;
    o.caustic_photons = 300000;
    o.caustic_photons = 300000;
    ct_radmesh rad = {0};
    if (mode == TRC_MODE_DRT) CHECK(rmesh_from_scene(s, v3s(0.0f), &rad, &err));
    trc_tracer *t;
    CHECK(trc_new(s, mode == TRC_MODE_DRT ? &rad : NULL, &o, &t, &err));
    trc_view v;
    v.cam = wide ? cam_look_at(v3(0, 0.9f, 0), v3(0, 0, 0), v3(0, 0, 1), 90.0f)
                 : cam_look_at(v3(0.3f, 0.1f, -0.3f), v3(0, 0, 0), v3(0, 1, 0), 2.0f);
    v.width = v.height = 9;
    ct_request *req = calloc((size_t)n, sizeof *req);
    ct_sample *out = calloc((size_t)n, sizeof *out);
    cr_assert(req && out);
    for (int i = 0; i < n; i++) {
        req[i].id = (uint64_t)i;
        req[i].px = wide ? (float)(i % 9) + 0.5f : 4.5f;
        req[i].py = wide ? (float)(i / 9 % 9) + 0.5f : 4.5f;
    }
    trc_stats st = {0};
    trc_trace(t, &v, req, (size_t)n, out, &st);
    double sx = 0, sy = 0, sz = 0;
    for (int i = 0; i < n; i++) {
        cr_assert(out[i].flags & CT_SAMPLE_HIT);
        sx += out[i].l_hq.x, sy += out[i].l_hq.y, sz += out[i].l_hq.z;
    }
    free(req);
    free(out);
    trc_free(t);
    rmesh_free(&rad);
    return v3((float)(sx / n), (float)(sy / n), (float)(sz / n));
}

static vec3 floor_light(const ct_scene *s, trc_glass_light gl, int n)
{
    return mode_floor_light(s, TRC_MODE_PATH, gl, false, n);
}

/* The floor under a pane of thickness `thick`: refracted / straight. */
static double pane_ratio(float thick, int n)
{
    ct_scene *open = glass_scene(NO_GLASS, 4.0f, 5.0f, 0.0f), *pane = glass_scene(PANE, 4.0f, 5.0f, thick);
    vec3 o = floor_light(open, TRC_GLASS_STRAIGHT, 100000);
    vec3 st = floor_light(pane, TRC_GLASS_STRAIGHT, 100000);
    vec3 rf = floor_light(pane, TRC_GLASS_REFRACTED, n);
    printf("metric: floor under a pane %.2f thick: open %.4f, straight %.4f (green %.4f), refracted %.4f (green "
           "%.4f); refracted / straight %.4f, %.4f\n",
           (double)thick, o.x, st.x, st.y, rf.x, rf.y, rf.x / st.x, rf.y / st.y);
    cr_assert(o.x > 0.0f && st.x > 0.0f);
    /* the straight model's own check: two crossings near normal incidence,
     * (1 - F)^2 with F about 0.04 */
    cr_expect(st.x / o.x > 0.90 && st.x / o.x < 0.95, "straight: the pane passes %g of the light", st.x / o.x);
    /* the pane's colour is its transmission per crossing, in both models */
    cr_expect(fabs((rf.y / rf.x) / (st.y / st.x) - 1.0) < 0.02, "green / red: refracted %g, straight %g",
              rf.y / rf.x, st.y / st.x);
    scene_free(open);
    scene_free(pane);
    return rf.x / st.x;
}

/* A pane's parallel faces give back a crossing ray's direction but shift
 * it sideways, toward the normal: seen through the pane the lamp looks
 * larger by about twice the shift at its rim. Integrated over the lamp
 * (Fresnel per face, the pane's internal reflections), refracted paths
 * bring 1.004 times the straight model's light through a 0.02 thick pane
 * and 1.027 times through a 0.2 thick one. Light counted twice would be
 * about double; light not found at all, about the floor's interreflection
 * with the pane (under 1 %). */
Test(glass_light, refracted_paths_through_a_pane_bring_what_straight_shadow_rays_do)
{
    double thin = pane_ratio(0.02f, 1000000);
    cr_expect(fabs(thin - 1.004) < 0.01, "thin pane: refracted / straight %g, not 1.004", thin);
}

Test(glass_light, a_thick_pane_shows_the_lamp_larger_only_to_refracted_paths)
{
    double thick = pane_ratio(0.2f, 1000000);
    cr_expect(fabs(thick - 1.027) < 0.01, "thick pane: refracted / straight %g, not 1.027", thick);
}

/* A glass ball focuses a small, distant lamp onto the floor under it: the
 * refracted paths find a bright spot there (the ball gathers the light of
 * 0.79 square units into a spot blurred by its spherical aberration:
 * measured 66 times the open floor), the straight model only the ball's
 * attenuated shadow, (1 - F)^2 of the open floor at normal incidence. */
Test(glass_light, only_refracted_paths_find_a_ball_lens_focus)
{
    ct_scene *open = glass_scene(NO_GLASS, 1.0f, 10.0f, 0.0f), *ball = glass_scene(BALL, 1.0f, 10.0f, 0.0f);
    vec3 o = floor_light(open, TRC_GLASS_STRAIGHT, 2000);
    vec3 st = floor_light(ball, TRC_GLASS_STRAIGHT, 2000);
    vec3 rf = floor_light(ball, TRC_GLASS_REFRACTED, 20000);
    printf("metric: floor under a glass ball: open %.4f, straight %.4f, refracted %.4f (focus / open %.2f)\n", o.x,
           st.x, rf.x, rf.x / o.x);
    cr_assert(o.x > 0.0f);
    cr_expect(st.x / o.x > 0.88f && st.x / o.x < 0.97f, "the straight model's shadow passes %g of the light",
              st.x / o.x);
    cr_expect(rf.x > 30.0f * o.x, "the focus must be far brighter than the open floor (%g / %g)", rf.x, o.x);
    scene_free(open);
    scene_free(ball);
}

/* drt with a mesh, its shadow rays blocked by glass: the lamp's light
 * through a pane comes from refracted photons read at the floor's vertices,
 * and must be what refracted path tracing finds there, over a square of
 * the floor (one vertex's estimate holds a few hundred photons, 5-8 %
 * noise; the square's hundreds of vertices average it out); the straight
 * drt and path tracing agree too. Light counted twice (shadow rays and photons)
 * would be about double; photons not counted, none. */
Test(glass_light, drt_with_a_mesh_brings_a_pane_s_light_by_refracted_photons)
{
    ct_scene *pane = glass_scene(PANE, 4.0f, 5.0f, 0.2f);
    vec3 pr = mode_floor_light(pane, TRC_MODE_PATH, TRC_GLASS_REFRACTED, true, 400000);
    vec3 dr = mode_floor_light(pane, TRC_MODE_DRT, TRC_GLASS_REFRACTED, true, 8100);
    vec3 ps = mode_floor_light(pane, TRC_MODE_PATH, TRC_GLASS_STRAIGHT, true, 100000);
    vec3 ds = mode_floor_light(pane, TRC_MODE_DRT, TRC_GLASS_STRAIGHT, true, 8100);
    printf("metric: floor under a 0.2 thick pane: path refracted %.4f, drt refracted %.4f (%.4f); path straight %.4f, "
           "drt straight %.4f (%.4f)\n",
           pr.x, dr.x, dr.x / pr.x, ps.x, ds.x, ds.x / ps.x);
    cr_expect(fabs(dr.x / pr.x - 1.0) < 0.03, "drt refracted / path refracted %g", dr.x / pr.x);
    cr_expect(fabs((dr.y / dr.x) / (pr.y / pr.x) - 1.0) < 0.03, "the pane's colour: green / red %g against %g",
              dr.y / dr.x, pr.y / pr.x);
    cr_expect(fabs(ds.x / ps.x - 1.0) < 0.02, "drt straight / path straight %g", ds.x / ps.x);
    scene_free(pane);
}

/* The ball lens's focus: drt's refracted photons find it (blurred by the
 * density estimate's disc and the mesh's vertices, so far less than path
 * tracing's 66 times the open floor at a point); its straight model has a
 * shadow there, lit by the caustic ring the ball's sides reflect onto the
 * floor around its base, which the density estimate's disc (0.6 wide here:
 * the shadow holds too few photons for a smaller one) spreads into it:
 * measured 1.12 times the open floor, path tracing's straight 0.94. */
Test(glass_light, drt_with_a_mesh_finds_a_ball_lens_focus_by_refracted_photons)
{
    ct_scene *open = glass_scene(NO_GLASS, 1.0f, 10.0f, 0.0f), *ball = glass_scene(BALL, 1.0f, 10.0f, 0.0f);
    vec3 o = mode_floor_light(open, TRC_MODE_DRT, TRC_GLASS_STRAIGHT, false, 500);
    vec3 st = mode_floor_light(ball, TRC_MODE_DRT, TRC_GLASS_STRAIGHT, false, 500);
    vec3 rf = mode_floor_light(ball, TRC_MODE_DRT, TRC_GLASS_REFRACTED, false, 500);
    printf("metric: floor under a glass ball, drt with a mesh: open %.4f, straight %.4f, refracted %.4f (focus / open "
           "%.2f)\n",
           o.x, st.x, rf.x, rf.x / o.x);
    cr_assert(o.x > 0.0f);
    cr_expect(st.x / o.x > 0.85f && st.x / o.x < 1.3f, "drt's straight shadow: %g of the open floor", st.x / o.x);
    cr_expect(rf.x > 5.0f * o.x, "drt's refracted photons must find the focus (%g / %g)", rf.x, o.x);
    scene_free(open);
    scene_free(ball);
}

/* auto: the pane is flat glass, so its light takes the straight model (the
 * same images as straight, sample for sample); the ball bends light, so its
 * takes the refracted one (the same as refracted), in path tracing and drt. */
Test(glass_light, auto_is_straight_through_a_pane_and_refracted_through_a_ball)
{
    ct_scene *pane = glass_scene(PANE, 4.0f, 5.0f, 0.2f), *ball = glass_scene(BALL, 1.0f, 10.0f, 0.0f);
    trc_mode modes[2] = {TRC_MODE_PATH, TRC_MODE_DRT};
    for (int k = 0; k < 2; k++) {
        int n = modes[k] == TRC_MODE_PATH ? 4000 : 400;
        vec3 pa = mode_floor_light(pane, modes[k], TRC_GLASS_AUTO, true, n);
        vec3 ps = mode_floor_light(pane, modes[k], TRC_GLASS_STRAIGHT, true, n);
        vec3 ba = mode_floor_light(ball, modes[k], TRC_GLASS_AUTO, false, n);
        vec3 br = mode_floor_light(ball, modes[k], TRC_GLASS_REFRACTED, false, n);
        vec3 bs = mode_floor_light(ball, modes[k], TRC_GLASS_STRAIGHT, false, n);
        printf("metric: %s auto: under the pane %.5f (straight %.5f), under the ball %.5f (refracted %.5f, straight "
               "%.5f)\n",
               trc_mode_name(modes[k]), pa.x, ps.x, ba.x, br.x, bs.x);
        cr_expect(pa.x == ps.x && pa.y == ps.y && pa.z == ps.z, "%s: auto under the pane %g, straight %g",
                  trc_mode_name(modes[k]), pa.x, ps.x);
        cr_expect(ba.x == br.x && ba.y == br.y && ba.z == br.z, "%s: auto under the ball %g, refracted %g",
                  trc_mode_name(modes[k]), ba.x, br.x);
        cr_expect(ba.x > 3.0f * bs.x, "%s: auto must find the ball's focus (%g against straight %g)",
                  trc_mode_name(modes[k]), ba.x, bs.x);
    }
    scene_free(pane);
    scene_free(ball);
}

Test(glass_light, refracted_is_refused_by_reuse_diffuse)
{
    ct_error err;
    ct_scene *s = glass_scene(PANE, 1.0f, 5.0f, 0.2f);
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, v3s(0.0f), &rad, &err));
    trc_options o;
    trc_options_default(&o, TRC_MODE_REUSE);
    o.glass_light = TRC_GLASS_REFRACTED;
    trc_tracer *t = NULL;
    cr_assert_eq(trc_new(s, &rad, &o, &t, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "path tracing and drt only"), "%s", err.msg);
    rmesh_free(&rad);
    cr_assert_str_eq(trc_glass_light_name(TRC_GLASS_REFRACTED), "refracted");
    scene_free(s);
}
