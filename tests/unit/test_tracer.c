/* (Over 600 lines: one module's tests, each with its own small scene.)
 * The tracer against analytic answers: white furnace, a plane under a
 * rectangular area light (point-to-rectangle form factor), a glass slab's
 * Fresnel energy balance, a mirror showing a known emitter; determinism
 * across batch orders and threads; reuse-diffuse corrections never negative. */
#include <criterion/criterion.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/radmesh.h"
#include "tests/support/testscenes.h"
#include "tracer/bsdf.h"
#include "tracer/embree_scene.h"
#include "tracer/tracer.h"

#define CHECK(x) do { int rc_ = (x); cr_assert_eq(rc_, 0, "%s: %s", #x, err.msg); } while (0)

static trc_tracer *make_tracer_ind(const ct_scene *s, const ct_radmesh *rad, trc_mode mode, int k, int b, int d,
                                   trc_indirect ind)
{
    trc_options o;
    trc_options_default(&o, mode);
    o.indirect = ind;
    if (k) o.shadow_rays = k;
    if (b) o.branch = b;
    if (d) o.depth = d;
    trc_tracer *t;
    ct_error err;
    int rc = trc_new(s, rad, &o, &t, &err);
    cr_assert_eq(rc, 0, "trc_new: %s", err.msg);
    return t;
}

/* A tracer with the default indirect light. */
static trc_tracer *make_tracer(const ct_scene *s, const ct_radmesh *rad, trc_mode mode, int k, int b, int d)
{
    trc_options o;
    trc_options_default(&o, mode);
    return make_tracer_ind(s, rad, mode, k, b, d, o.indirect);
}

/* Mean L_hq of n samples at image position (px, py) (request ids id0..) and,
 * if var is given, the variance of their red channel. */
static vec3 moments_at(const trc_tracer *t, const trc_view *v, float px, float py, int n, uint64_t id0,
                       ct_sample *last, double *var)
{
    ct_request *req = calloc((size_t)n, sizeof *req);
    ct_sample *out = calloc((size_t)n, sizeof *out);
    cr_assert(req && out);
    for (int i = 0; i < n; i++) {
        req[i].id = id0 + (uint64_t)i;
        req[i].px = px;
        req[i].py = py;
    }
    trc_stats st = {0};
    trc_trace(t, v, req, (size_t)n, out, &st);
    double sx = 0, sy = 0, sz = 0, sxx = 0;
    for (int i = 0; i < n; i++) {
        sx += out[i].l_hq.x;
        sy += out[i].l_hq.y;
        sz += out[i].l_hq.z;
        sxx += (double)out[i].l_hq.x * out[i].l_hq.x;
    }
    if (last) *last = out[n - 1];
    if (var) *var = sxx / n - (sx / n) * (sx / n);
    free(req);
    free(out);
    return v3((float)(sx / n), (float)(sy / n), (float)(sz / n));
}

/* Mean L_hq of n samples at image position (px, py) (request ids id0..). */
static vec3 mean_at(const trc_tracer *t, const trc_view *v, float px, float py, int n, uint64_t id0,
                    ct_sample *last)
{
    return moments_at(t, v, px, py, n, id0, last, NULL);
}

static trc_view view_of(vec3 eye, vec3 target, float fov, int w, int h)
{
    trc_view v;
    v.cam = cam_look_at(eye, target, v3(0, 1, 0), fov);
    v.width = w;
    v.height = h;
    return v;
}

/* --- white furnace ------------------------------------------------------- */

static void furnace(trc_mode mode)
{
    ct_error err;
    ct_scene *s = scene_new("furnace");
    cr_assert(s);
    int m = ts_diffuse(s, "white", v3s(0.5f), v3s(1.0f), &err);
    cr_assert(m >= 0);
    cr_assert(ts_sphere(s, "sphere", (uint32_t)m, v3(0, 0, 0), 1.0f, 24, 12, true, &err) >= 0);
    CHECK(scene_finalize(s, &err));
    trc_tracer *t = make_tracer(s, NULL, mode, 1, 1, 0);
    trc_view v = view_of(v3(0.1f, 0.2f, 0.0f), v3(0.5f, 0.3f, 1.0f), 90.0f, 8, 8);
    /* Analytic: L = L_e / (1 - rho) = 2 everywhere in a closed enclosure. */
    double sum = 0.0;
    int cells = 0;
    for (int y = 0; y < 8; y += 2)
        for (int x = 0; x < 8; x += 2) {
            vec3 l = mean_at(t, &v, x + 0.5f, y + 0.5f, 256, 1000u * (uint64_t)(y * 8 + x), NULL);
            cr_expect(fabsf(l.x - 2.0f) < 0.1f, "%s: pixel (%d,%d) L = %g, expected 2", trc_mode_name(mode),
                      x, y, (double)l.x);
            sum += l.x;
            cells++;
        }
    double mean = sum / cells;
    cr_expect(fabs(mean - 2.0) < 0.02, "%s furnace: mean L = %g, expected 2", trc_mode_name(mode), mean);
    trc_free(t);
    scene_free(s);
}

Test(tracer, white_furnace_path) { furnace(TRC_MODE_PATH); }
Test(tracer, white_furnace_drt_path_traced_indirect) { furnace(TRC_MODE_DRT); }

/* --- form factor ---------------------------------------------------------- */

/* A floor under one light 1 x 0.6 at height 1 (x in [-0.5, 0.5]) or, with
 * two_lights, also a second one 0.6 x 0.6 at height 1.5 over x in [1, 1.6]:
 * two emitters, so the spatial light selection picks between them. */
static ct_scene *plane_scene(bool two_lights)
{
    ct_error err;
    ct_scene *s = scene_new("plane");
    int floor_m = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3(10, 5, 2), &err);
    cr_assert(floor_m >= 0 && lamp >= 0);
    /* Floor y = 0 facing up; light 1 x 0.6 at height 1 facing down. */
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(-10, 0, -10), v3(0, 0, 20), v3(20, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "light", (uint32_t)lamp, v3(-0.5f, 1, -0.3f), v3(1, 0, 0), v3(0, 0, 0.6f), &err) >= 0);
    if (two_lights)
        cr_assert(ts_quad(s, "light2", (uint32_t)lamp, v3(1.0f, 1.5f, -0.3f), v3(0.6f, 0, 0), v3(0, 0, 0.6f),
                          &err) >= 0);
    CHECK(scene_finalize(s, &err));
    return s;
}

static void form_factor(trc_mode mode, bool with_rad, bool two_lights)
{
    ct_error err;
    ct_scene *s = plane_scene(two_lights);
    ct_radmesh rad;
    if (with_rad) CHECK(rmesh_from_scene(s, v3s(0.0f), &rad, &err));
    trc_tracer *t = make_tracer(s, with_rad ? &rad : NULL, mode, 4, 0, 0);
    trc_view v = view_of(v3(0, 0.6f, -2.5f), v3(0, 0, 0), 60.0f, 16, 16);
    static const float pix[][2] = {{8, 8}, {4, 12}, {12, 10}, {8, 15}, {2, 14}};
    for (size_t k = 0; k < sizeof pix / sizeof pix[0]; k++) {
        ct_sample last;
        vec3 l = mean_at(t, &v, pix[k][0], pix[k][1], 2000, 100000u * (k + 1), &last);
        cr_assert(last.flags & CT_SAMPLE_HIT);
        cr_assert(fabsf(last.hit.y) < 1e-4f, "must hit the floor");
        double f = ts_ff_rect(last.hit.x, last.hit.z, -0.5, 0.5, -0.3, 0.3, 1.0);
        if (two_lights) f += ts_ff_rect(last.hit.x, last.hit.z, 1.0, 1.6, -0.3, 0.3, 1.5);
        /* L = rho / pi * E = rho / pi * (L_e pi F) = rho L_e F. */
        double want = 0.5 * 10.0 * f;
        cr_expect(fabs(l.x - want) < 0.02 * want + 1e-5, "%s: at (%g, %g) L = %g, analytic %g (F = %g)",
                  trc_mode_name(mode), (double)last.hit.x, (double)last.hit.z, (double)l.x, want, f);
        cr_expect(fabs(l.z - want * 0.2) < 0.02 * want * 0.2 + 1e-5);
    }
    trc_free(t);
    if (with_rad) rmesh_free(&rad);
    scene_free(s);
}

Test(tracer, plane_under_area_light_path) { form_factor(TRC_MODE_PATH, false, false); }
Test(tracer, plane_under_area_light_drt) { form_factor(TRC_MODE_DRT, false, false); }
Test(tracer, plane_under_area_light_drt_radmesh) { form_factor(TRC_MODE_DRT, true, false); }
/* The K light samples of a point are stratified (a shifted Halton-like
 * set): with K = 4 the variance of direct light under two area lights is
 * under 0.22 of the one-sample variance (0.18 measured; independent samples
 * give a quarter: 0.24 measured with the same seeds). */
Test(tracer, light_samples_of_a_point_are_stratified)
{
    ct_scene *s = plane_scene(true);
    trc_view v = view_of(v3(0, 0.6f, -2.5f), v3(0, 0, 0), 60.0f, 16, 16);
    double var[2];
    vec3 mean[2];
    for (int i = 0; i < 2; i++) {
        trc_tracer *t = make_tracer(s, NULL, TRC_MODE_DRT, i ? 4 : 1, 0, 1);
        mean[i] = moments_at(t, &v, 8, 8, 4000, 777000u, NULL, &var[i]);
        trc_free(t);
    }
    printf("metric: direct light at one point, variance K=1 %.4g, K=4 %.4g (ratio %.3f; independent: 0.25)\n",
           var[0], var[1], var[1] / var[0]);
    cr_expect(fabsf(mean[0].x - mean[1].x) < 0.03f * mean[1].x, "means %g and %g", (double)mean[0].x,
              (double)mean[1].x);
    cr_expect(var[1] < 0.22 * var[0], "K=4 variance %g is not under 0.22 x the K=1 variance %g", var[1], var[0]);
    scene_free(s);
}

/* Two emitters: the spatial light selection (and, in path mode, its MIS
 * weights for light found by scattered rays) must stay unbiased. */
Test(tracer, plane_under_two_area_lights_path) { form_factor(TRC_MODE_PATH, false, true); }
Test(tracer, plane_under_two_area_lights_drt) { form_factor(TRC_MODE_DRT, false, true); }

/* --- glass slab ----------------------------------------------------------- */

/* A 0.1 thick glass slab at y in [-0.1, 0] seen at 45 degrees; emitters
 * (L_e = 1) below (transmitted light), above (reflected light) or both.
 * var, if given, receives the variance of one sample's red channel. */
static vec3 slab_moments(trc_mode mode, bool below, bool above, int n, int fresnel_depth, double *var)
{
    ct_error err;
    ct_scene *s = scene_new("slab");
    int gm = ts_glass(s, "glass", 1.5f, v3s(1.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3s(1.0f), &err);
    cr_assert(gm >= 0 && lamp >= 0);
    cr_assert(ts_box(s, "slab", (uint32_t)gm, v3(-50, -0.1f, -50), v3(50, 0, 50), false, &err) >= 0);
    if (below)
        cr_assert(ts_quad(s, "below", (uint32_t)lamp, v3(-100, -1, -100), v3(0, 0, 200), v3(200, 0, 0), &err) >= 0);
    if (above)
        cr_assert(ts_quad(s, "above", (uint32_t)lamp, v3(-100, 5, -100), v3(200, 0, 0), v3(0, 0, 200), &err) >= 0);
    CHECK(scene_finalize(s, &err));
    trc_options o;
    trc_options_default(&o, mode);
    o.shadow_rays = 1;
    o.fresnel_depth = fresnel_depth;
    trc_tracer *t;
    CHECK(trc_new(s, NULL, &o, &t, &err));
    trc_view v = view_of(v3(0, 1, -1), v3(0, 0, 0), 30.0f, 9, 9);
    vec3 l = moments_at(t, &v, 4.5f, 4.5f, n, 1, NULL, var);
    trc_free(t);
    scene_free(s);
    return l;
}

static vec3 slab(trc_mode mode, bool below, bool above, int n, int fresnel_depth)
{
    return slab_moments(mode, below, above, n, fresnel_depth, NULL);
}

Test(tracer, glass_slab_fresnel_energy_balance)
{
    float ct;
    double r = bsdf_fresnel(cosf(CT_PI / 4), 1.0f / 1.5f, &ct);
    double t_slab = (1 - r) / (1 + r), r_slab = 2 * r / (1 + r);
    /* drt splitting into both Fresnel branches on every level: deterministic
     * and exact. */
    vec3 lt = slab(TRC_MODE_DRT, true, false, 1, 5);
    vec3 lr = slab(TRC_MODE_DRT, false, true, 1, 5);
    vec3 lb = slab(TRC_MODE_DRT, true, true, 1, 5);
    cr_expect(fabs(lt.x - t_slab) < 1e-4, "drt: slab transmits %g, analytic %g", (double)lt.x, t_slab);
    cr_expect(fabs(lr.x - r_slab) < 1e-4, "drt: slab reflects %g, analytic %g", (double)lr.x, r_slab);
    cr_expect(fabs(lb.x - 1.0) < 1e-4, "drt: R + T = %g, not 1", (double)lb.x);
    /* drt with both branches on the first level only (the stronger below,
     * the weaker by chance) and path (one branch everywhere): unbiased on
     * average. */
    vec3 dt = slab(TRC_MODE_DRT, true, false, 20000, 1);
    cr_expect(fabs(dt.x - t_slab) < 0.01, "drt (Fresnel depth 1): slab transmits %g, analytic %g", (double)dt.x,
              t_slab);
    vec3 pt = slab(TRC_MODE_PATH, true, false, 20000, 1);
    vec3 pb = slab(TRC_MODE_PATH, true, true, 2000, 1);
    cr_expect(fabs(pt.x - t_slab) < 0.01, "path: slab transmits %g, analytic %g", (double)pt.x, t_slab);
    cr_expect(fabs(pb.x - 1.0) < 0.01, "path: R + T = %g, not 1", (double)pb.x);
}

/* Below the Fresnel levels (Fresnel depth 0: from the camera ray on) drt
 * traces the stronger Fresnel branch of every event and the weaker by
 * chance. Seen through the slab with the lamp below, every sample keeps the
 * transmitted light: picking one branch by F instead gave the reflection's
 * darkness to a fraction F of the samples, a variance of about
 * F (1 - F) T^2 (0.04 here), the specks of single samples through glass. */
Test(tracer, glass_keeps_the_transmitted_light_of_every_sample)
{
    float ct;
    double r = bsdf_fresnel(cosf(CT_PI / 4), 1.0f / 1.5f, &ct);
    double t_slab = (1 - r) / (1 + r), picked = r * (1 - r) * t_slab * t_slab;
    double var;
    vec3 lt = slab_moments(TRC_MODE_DRT, true, false, 20000, 0, &var);
    printf("metric: slab seen at 45 deg, Fresnel depth 0: mean %.4f (analytic %.4f), variance of a sample %.2e "
           "(one branch by F: about %.2e)\n",
           (double)lt.x, t_slab, var, picked);
    cr_expect(fabs(lt.x - t_slab) < 0.01, "drt (Fresnel depth 0): slab transmits %g, analytic %g", (double)lt.x,
              t_slab);
    cr_expect(var < 0.1 * picked, "variance of a sample %g, not under a tenth of one branch by F (%g)", var, picked);
}

/* --- mirror ---------------------------------------------------------------- */

Test(tracer, mirror_shows_known_emitter)
{
    ct_error err;
    ct_scene *s = scene_new("mirror");
    scene_material mm = scene_material_default("mirror");
    mm.mirror = v3s(0.8f);
    int mi = scene_add_material(s, &mm, &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3(3, 2, 1), &err);
    cr_assert(mi >= 0 && lamp >= 0);
    cr_assert(ts_quad(s, "mirror", (uint32_t)mi, v3(-5, 0, -5), v3(0, 0, 10), v3(10, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "lamp", (uint32_t)lamp, v3(-20, 2, -20), v3(40, 0, 0), v3(0, 0, 40), &err) >= 0);
    CHECK(scene_finalize(s, &err));
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, v3s(0.0f), &rad, &err));
    trc_view v = view_of(v3(0, 1, -3), v3(0, 0, 0), 40.0f, 8, 8);
    for (int mode = TRC_MODE_PATH; mode <= TRC_MODE_REUSE; mode++) {
        trc_tracer *t = make_tracer(s, mode == TRC_MODE_REUSE ? &rad : NULL, (trc_mode)mode, 0, 0, 0);
        ct_sample last;
        vec3 l = mean_at(t, &v, 4.5f, 5.5f, 16, 1, &last);
        cr_expect(fabsf(l.x - 2.4f) < 1e-4f && fabsf(l.y - 1.6f) < 1e-4f && fabsf(l.z - 0.8f) < 1e-4f,
                  "%s: mirror shows (%g %g %g), expected 0.8 * (3 2 1)", trc_mode_name((trc_mode)mode),
                  (double)l.x, (double)l.y, (double)l.z);
        cr_expect(last.node == 1, "hit node %u is not the mirror part", last.node);
        trc_free(t);
    }
    rmesh_free(&rad);
    scene_free(s);
}

/* --- drt takes its indirect diffuse light from the radiosity mesh ---------- */

Test(tracer, drt_indirect_diffuse_from_radiosity_mesh)
{
    ct_error err;
    ct_scene *s = scene_new("plane");
    int floor_m = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3(10, 5, 2), &err);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(-10, 0, -10), v3(0, 0, 20), v3(20, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "light", (uint32_t)lamp, v3(-0.5f, 1, -0.3f), v3(1, 0, 0), v3(0, 0, 0.6f), &err) >= 0);
    CHECK(scene_finalize(s, &err));
    /* Stand-in radiosity: rad = L_e + rho * A, rad_direct = L_e, so the
     * indirect part on the floor is rho * A = 0.5 * (0.2, 0.4, 0.6). */
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, v3(0.2f, 0.4f, 0.6f), &rad, &err));
    trc_tracer *t = make_tracer_ind(s, &rad, TRC_MODE_DRT, 4, 0, 0, TRC_INDIRECT_MESH);
    trc_view v = view_of(v3(0, 0.6f, -2.5f), v3(0, 0, 0), 60.0f, 16, 16);
    ct_sample last;
    vec3 l = mean_at(t, &v, 8, 8, 2000, 1, &last);
    double f = ts_ff_rect(last.hit.x, last.hit.z, -0.5, 0.5, -0.3, 0.3, 1.0);
    double want_x = 0.5 * 10.0 * f + 0.1, want_z = 0.5 * 2.0 * f + 0.3;
    cr_expect(fabs(l.x - want_x) < 0.02 * want_x, "L.x = %g, want direct + indirect %g", (double)l.x, want_x);
    cr_expect(fabs(l.z - want_z) < 0.02 * want_z, "L.z = %g, want %g", (double)l.z, want_z);
    cr_expect(last.flags & CT_SAMPLE_HAS_BASE);
    vec3 base = rmesh_eval(&rad, last.tri, last.u, last.v);
    cr_expect(memcmp(&base, &last.l_base, sizeof base) == 0, "l_base is not the Gouraud value at the hit");
    trc_free(t);
    rmesh_free(&rad);
    scene_free(s);
}

/* --- drt's final gather ----------------------------------------------------- */

/* Inside a closed box of one reflectance rho whose stand-in radiosity is
 * L_e + rho * A everywhere (the lamp reflects like the walls), every
 * gather ray sees rho * A once the lamp's emission is taken off, so the
 * gathered indirect light at any point is rho * (rho * A) for any number
 * of gather rays; the direct light is the shadow rays', as with the mesh's
 * indirect light (rho * A, read at the hit). The difference of the two modes
 * is therefore rho * A * (rho - 1), exactly, sample by sample up to the
 * direct light's noise, which both share (same seeds: the direct light is
 * drawn first). The gather reads the lamps' light from the mesh here
 * (--gather-direct mesh); the traced variant is tested below. */
Test(tracer, drt_final_gather_reads_the_mesh_where_its_rays_land)
{
    ct_error err;
    ct_scene *s = scene_new("gatherbox");
    int wall = ts_diffuse(s, "wall", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.5f), v3(8, 8, 8), &err);
    cr_assert(ts_box(s, "box", (uint32_t)wall, v3(0, 0, 0), v3(2, 2, 2), true, &err) >= 0);
    cr_assert(ts_quad(s, "lamp", (uint32_t)lamp, v3(0.8f, 1.999f, 0.8f), v3(0.4f, 0, 0), v3(0, 0, 0.4f), &err) >= 0);
    CHECK(scene_finalize(s, &err));
    const vec3 A = v3(0.2f, 0.4f, 0.6f);
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, A, &rad, &err));
    trc_view v = view_of(v3(1.0f, 1.2f, 0.3f), v3(1.0f, 0.2f, 1.8f), 70.0f, 16, 16);
    for (int g = 1; g <= 16; g *= 4) {
        trc_options o;
        trc_options_default(&o, TRC_MODE_DRT);
        o.shadow_rays = 4;
        o.gather_rays = g;
        o.indirect = TRC_INDIRECT_GATHER;
        o.gather_direct = TRC_GATHER_DIRECT_MESH;
        trc_tracer *tg;
        CHECK(trc_new(s, &rad, &o, &tg, &err));
        trc_tracer *tm = make_tracer_ind(s, &rad, TRC_MODE_DRT, 4, 0, 0, TRC_INDIRECT_MESH);
        for (int y = 2; y < 16; y += 6)
            for (int x = 2; x < 16; x += 6) {
                ct_sample sg, sm;
                vec3 lg = mean_at(tg, &v, x + 0.5f, y + 0.5f, 64, 7u, &sg);
                vec3 lm = mean_at(tm, &v, x + 0.5f, y + 0.5f, 64, 7u, &sm);
                cr_assert(sg.flags & CT_SAMPLE_HAS_BASE);
                cr_assert_eq(memcmp(&sg.l_base, &sm.l_base, sizeof sg.l_base), 0, "L_base depends on the gather");
                for (int k = 0; k < 3; k++) {
                    double a = v3_get(A, k), want = 0.5 * a * (0.5 - 1.0);
                    double got = (double)v3_get(lg, k) - v3_get(lm, k);
                    cr_expect(fabs(got - want) < 1e-4 + 1e-3 * fabs(want),
                              "G = %d, pixel (%d, %d), channel %d: gather - mesh = %g, want %g", g, x, y, k, got, want);
                }
            }
        trc_free(tg);
        trc_free(tm);
    }
    rmesh_free(&rad);
    scene_free(s);
}

/* The gather with the lamps' light traced where its rays land
 * (TRC_GATHER_DIRECT_TRACE, the default) over a mesh with no indirect light
 * (stand-in radiosity with ambient 0: every surface's radiosity is its
 * emission, its direct part too) brings exactly the light reflected once
 * between the lamp and the camera's hit: the same as path tracing with two
 * bounces (the hit's direct light, and the direct light at the second
 * vertex), in expectation. In a closed box (lamp at the top) with a
 * diffuse floor (rho 0.5), a point on the floor in the lamp's view and one
 * on a side wall; once with diffuse walls, once with glossy ones (Phong,
 * rho_s 0.3 over rho_d 0.3: the lamps' glossy reflection at the landing
 * counts too, which the radiosity solution leaves out). The gather that
 * reads the mesh has nothing to read there (its mean is the direct light
 * alone): the test tells the two apart. */
static void gather_vs_two_bounces(bool glossy_walls)
{
    ct_error err;
    ct_scene *s = scene_new("gatherbox");
    scene_material wm = scene_material_default("wall");
    wm.diffuse = v3s(glossy_walls ? 0.3f : 0.5f);
    if (glossy_walls) {
        wm.glossy = SCENE_GLOSSY_PHONG;
        wm.specular = v3s(0.3f);
        wm.phong_exp = 20.0f;
    }
    int wall = scene_add_material(s, &wm, &err);
    int floor_m = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.5f), v3(8, 8, 8), &err);
    cr_assert(wall >= 0 && floor_m >= 0 && lamp >= 0);
    cr_assert(ts_box(s, "box", (uint32_t)wall, v3(0, 0, 0), v3(2, 2, 2), true, &err) >= 0);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(0.001f, 0.001f, 0.001f), v3(0, 0, 1.998f),
                      v3(1.998f, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "lamp", (uint32_t)lamp, v3(0.8f, 1.999f, 0.8f), v3(0.4f, 0, 0), v3(0, 0, 0.4f), &err) >= 0);
    CHECK(scene_finalize(s, &err));
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, v3s(0.0f), &rad, &err));
    trc_options o;
    trc_options_default(&o, TRC_MODE_DRT);
    cr_assert_eq(o.gather_direct, TRC_GATHER_DIRECT_TRACE, "the traced lamps are the default");
    trc_tracer *tg, *tm, *tp;
    CHECK(trc_new(s, &rad, &o, &tg, &err));
    o.gather_direct = TRC_GATHER_DIRECT_MESH;
    CHECK(trc_new(s, &rad, &o, &tm, &err));
    trc_options_default(&o, TRC_MODE_PATH);
    o.depth = 2;
    CHECK(trc_new(s, NULL, &o, &tp, &err));
    /* Both points on the diffuse floor: drt's camera hit has no glossy lobe
     * to recurse through, so the two estimators count the same paths. */
    const vec3 eyes[2][2] = {{v3(1.0f, 1.5f, 0.2f), v3(1.0f, 0.0f, 1.2f)},
                             {v3(1.0f, 1.0f, 1.0f), v3(0.2f, 0.0f, 1.0f)}};
    const int n = 16384;
    for (int i = 0; i < 2; i++) {
        trc_view v = view_of(eyes[i][0], eyes[i][1], 20.0f, 3, 3);
        double vg, vp;
        vec3 g = moments_at(tg, &v, 1.5f, 1.5f, n, 11u, NULL, &vg);
        vec3 p = moments_at(tp, &v, 1.5f, 1.5f, n, 11u, NULL, &vp);
        vec3 m = mean_at(tm, &v, 1.5f, 1.5f, n, 11u, NULL);
        double sigma = sqrt((vg + vp) / n), d = v3_get(g, 0) - v3_get(p, 0);
        const char *what = i ? "floor by a wall" : "floor under the lamp";
        printf("metric: %s walls, %s: gather tracing the lamps %.5f, path (2 bounces) %.5f (sigma of the "
               "difference %.5f), gather reading the mesh %.5f\n",
               glossy_walls ? "glossy" : "diffuse", what, (double)v3_get(g, 0), (double)v3_get(p, 0), sigma,
               (double)v3_get(m, 0));
        cr_expect(fabs(d) < 4.0 * sigma + 1e-4, "%s: traced gather %g, path %g (sigma %g)", what,
                  (double)v3_get(g, 0), (double)v3_get(p, 0), sigma);
        cr_expect(v3_get(p, 0) - v3_get(m, 0) > 10.0 * sigma, "%s: the gather reading the mesh %g, path %g", what,
                  (double)v3_get(m, 0), (double)v3_get(p, 0));
    }
    trc_free(tg);
    trc_free(tm);
    trc_free(tp);
    rmesh_free(&rad);
    scene_free(s);
}

Test(tracer, drt_gather_traces_the_lamps_where_its_rays_land)
{
    gather_vs_two_bounces(false);
    gather_vs_two_bounces(true);
}

/* The radiosity solution has no specular transport (a mirror is black in
 * it), so the gather follows a mirror it hits and reads the mesh where the
 * reflected ray lands. A floor (rho 0.5) under a mirror ceiling of
 * reflectance R that fills its whole hemisphere, no light, a stand-in mesh
 * of radiance 0.5 A on the floor: every gather ray goes up, is reflected
 * down and reads 0.5 A, so the floor's indirect light is 0.5 * R * 0.5 A;
 * with the ceiling a black diffuse surface instead, nothing. */
/* (The scene of this test and the next: drt's mean radiance at the floor,
 * seen along look from between floor and ceiling.) */
static vec3 floor_under(const scene_material *ceiling, vec3 look, int spp, uint32_t seed)
{
    ct_error err;
    ct_scene *s = scene_new(ceiling->name);
    int floor_m = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), &err);
    int ceil_m = scene_add_material(s, ceiling, &err);
    cr_assert(floor_m >= 0 && ceil_m >= 0);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(-200, 0, -200), v3(0, 0, 400), v3(400, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "ceiling", (uint32_t)ceil_m, v3(-200, 1, -200), v3(400, 0, 0), v3(0, 0, 400), &err) >= 0);
    CHECK(scene_finalize(s, &err));
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, v3(0.2f, 0.4f, 0.6f), &rad, &err));
    trc_tracer *t = make_tracer_ind(s, &rad, TRC_MODE_DRT, 4, 0, 0, TRC_INDIRECT_GATHER);
    trc_view v = view_of(v3(0, 0.5f, 0), look, 40.0f, 9, 9);
    vec3 l = mean_at(t, &v, 4.5f, 4.5f, spp, seed, NULL);
    trc_free(t);
    rmesh_free(&rad);
    scene_free(s);
    return l;
}

static vec3 floor_under_ceiling(bool mirror)
{
    scene_material mm = scene_material_default("mirrorceiling");
    mm.diffuse = v3s(0.0f);
    if (mirror) mm.mirror = v3(0.8f, 0.6f, 0.4f);
    return floor_under(&mm, v3(0.3f, 0, 0.2f), 64, 3u);
}

Test(tracer, drt_final_gather_follows_mirrors)
{
    vec3 with = floor_under_ceiling(true), without = floor_under_ceiling(false);
    const float A[3] = {0.2f, 0.4f, 0.6f}, R[3] = {0.8f, 0.6f, 0.4f};
    for (int k = 0; k < 3; k++) {
        double want = 0.5 * R[k] * 0.5 * A[k];
        printf("metric: gather under a mirror, channel %d: %g (want %g), under a black ceiling %g\n", k,
               (double)v3_get(with, k), want, (double)v3_get(without, k));
        cr_expect(fabs(v3_get(with, k) - want) < 1e-4 + 1e-3 * want, "channel %d: %g, want %g", k,
                  (double)v3_get(with, k), want);
        cr_expect(fabs(v3_get(without, k)) < 1e-6, "black ceiling, channel %d: %g", k, (double)v3_get(without, k));
    }
}

/* The radiosity mesh holds the diffuse layer's light alone, so where a
 * gather ray lands on a glossy surface the gather traces its lobe on and
 * reads the mesh there. A floor (rho 0.5) under a ceiling with a sharp
 * normalized Phong lobe (rho_s R, exponent 1000) and diffuse D, no light,
 * a stand-in mesh of radiance rho_d A everywhere: a gather ray reads D A at
 * the ceiling plus what its lobe reflects of the floor, R (n+2)/(n+1)
 * cos(theta) 0.5 A (theta the ray's angle to the normal, whose mean over
 * cosine-weighted rays is 2/3). The diffuse layer makes the lobe traced by
 * chance (its share of the smooth reflectance), weighted up. */
static vec3 floor_under_glossy_ceiling(float diffuse)
{
    scene_material gm = scene_material_default("glossyceiling");
    gm.diffuse = v3s(diffuse);
    gm.glossy = SCENE_GLOSSY_PHONG;
    gm.specular = v3(0.8f, 0.6f, 0.4f);
    gm.phong_exp = 1000.0f;
    return floor_under(&gm, v3(0.3f, -1.0f, 0.2f), 8192, 7u);
}

Test(tracer, drt_final_gather_reads_the_room_in_glossy_surfaces)
{
    const float A[3] = {0.2f, 0.4f, 0.6f}, R[3] = {0.8f, 0.6f, 0.4f}, n = 1000.0f;
    const float D[2] = {0.0f, 0.3f};
    for (int j = 0; j < 2; j++) {
        vec3 l = floor_under_glossy_ceiling(D[j]);
        for (int k = 0; k < 3; k++) {
            double glossy = R[k] * (n + 2.0) / (n + 1.0) * (2.0 / 3.0) * 0.5 * A[k];
            double want = 0.5 * (D[j] * A[k] + glossy);
            printf("metric: gather under a glossy ceiling (diffuse %g), channel %d: %g (want %g, %g without the lobe)\n",
                   (double)D[j], k, (double)v3_get(l, k), want, 0.5 * D[j] * A[k]);
            cr_expect(fabs(v3_get(l, k) - want) < 0.02 * want, "diffuse %g, channel %d: %g, want %g", (double)D[j], k,
                      (double)v3_get(l, k), want);
        }
    }
}

/* A gather ray that meets glass takes what the glass passes and what its
 * face reflects. A floor (rho 0.5) under a glass ceiling (ior 1.5, clear)
 * with nothing above it, no light, a stand-in mesh of radiance 0.5 A on the
 * floor: what passes finds nothing, the reflection (followed with
 * probability F, weight 1) comes back down to the floor, so the floor's
 * indirect light is 0.5 * Fbar * 0.5 A, Fbar the cosine-weighted mean of
 * the face's Fresnel reflectance over the hemisphere (about 0.09). Before
 * tracer version 7 it was 0. */
Test(tracer, drt_final_gather_takes_the_reflection_of_glass)
{
    scene_material gm = scene_material_default("glassceiling");
    gm.diffuse = v3s(0.0f);
    gm.dielectric = 1;
    gm.ior = 1.5f;
    gm.transmission = v3s(1.0f);
    vec3 l = floor_under(&gm, v3(0.3f, -1.0f, 0.2f), 8192, 5u);
    /* Fbar = integral over theta of F(cos theta) 2 cos theta sin theta */
    double fbar = 0.0;
    const int n = 20000;
    for (int i = 0; i < n; i++) {
        const double half_pi = 1.57079632679489661923;
        double th = (i + 0.5) * half_pi / n, ct;
        float cos_t;
        ct = cos(th);
        fbar += rmesh_fresnel((float)ct, 1.0f / 1.5f, &cos_t) * 2.0 * ct * sin(th) * half_pi / n;
    }
    const float A[3] = {0.2f, 0.4f, 0.6f};
    for (int k = 0; k < 3; k++) {
        double want = 0.5 * fbar * 0.5 * A[k];
        printf("metric: gather under a glass ceiling, channel %d: %g (want %g, Fbar %.4f)\n", k,
               (double)v3_get(l, k), want, fbar);
        /* 32,768 gather rays, each reflected with p = Fbar: 1.7 % relative
         * deviation of the mean; the bound is four of them */
        cr_expect(fabs(v3_get(l, k) - want) < 0.07 * want, "channel %d: %g, want %g", k, (double)v3_get(l, k), want);
    }
}

/* A lamp seen in a plane mirror lights a diffuse floor (mirror_lights.h;
 * the scene: ts_mirror_lamp): drt's floor radiance must be rho * R * L_e *
 * F(image), the form factor to the lamp's image; the stand-in mesh (A = 0)
 * adds nothing else, with the gather reading the lamps' light from it
 * (--gather-direct mesh: traced, the lamps' light once reflected by the
 * walls would add to the analytic value, which leaves it out). Covered, or
 * with a diffuse ceiling: nothing. Split into three mirrors: the same. */
static void floor_under_mirror(trc_indirect ind, bool cover, bool diffuse_ceiling, bool split)
{
    ct_error err;
    ct_scene *s = ts_mirror_lamp(split, cover, diffuse_ceiling, &err);
    cr_assert(s, "%s", err.msg);
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, v3s(0.0f), &rad, &err));
    trc_options o;
    trc_options_default(&o, TRC_MODE_DRT);
    o.indirect = ind;
    o.gather_direct = TRC_GATHER_DIRECT_MESH;
    trc_tracer *t;
    CHECK(trc_new(s, &rad, &o, &t, &err));
    trc_view v = view_of(v3(-0.5f, 1.5f, -2.5f), v3(-0.5f, 0, 0), 40.0f, 16, 16);
    static const float pix[][2] = {{8, 8}, {3, 12}, {13, 10}, {8, 15}};
    for (size_t k = 0; k < sizeof pix / sizeof pix[0]; k++) {
        ct_sample last;
        vec3 l = mean_at(t, &v, pix[k][0], pix[k][1], split ? 4000 : 1000, 7000u * (k + 1), &last);
        cr_assert(fabsf(last.hit.y) < 1e-4f, "must hit the floor");
        vec3 want3 = ts_mirror_lamp_floor(last.hit.x, last.hit.z);
        for (int ch = 0; ch < 3; ch++) {
            double want = cover || diffuse_ceiling ? 0.0 : v3_get(want3, ch);
            double got = v3_get(l, ch);
            if (ch == 0)
                printf("metric: %s, lamp in a mirror%s%s%s, floor at (%.2f, %.2f): %g (analytic %g)\n",
                       trc_indirect_name(ind), cover ? ", covered" : "", diffuse_ceiling ? ", diffuse ceiling" : "",
                       split ? ", three mirrors" : "", (double)last.hit.x, (double)last.hit.z, got, want);
            cr_expect(fabs(got - want) < 0.02 * want + 1e-6, "%s at (%g, %g), channel %d: %g, analytic %g",
                      trc_indirect_name(ind), (double)last.hit.x, (double)last.hit.z, ch, got, want);
        }
    }
    trc_free(t);
    rmesh_free(&rad);
    scene_free(s);
}

Test(tracer, drt_samples_lamps_seen_in_a_plane_mirror)
{
    floor_under_mirror(TRC_INDIRECT_GATHER, false, false, false);
    floor_under_mirror(TRC_INDIRECT_MESH, false, false, false);
    floor_under_mirror(TRC_INDIRECT_GATHER, false, false, true);
}

Test(tracer, drt_mirrored_lamp_blocked_or_no_mirror)
{
    floor_under_mirror(TRC_INDIRECT_GATHER, true, false, false);
    floor_under_mirror(TRC_INDIRECT_GATHER, false, true, false);
}

Test(tracer, drt_indirect_options_parse_and_validate)
{
    ct_error err;
    cr_assert_str_eq(trc_indirect_name(TRC_INDIRECT_GATHER), "gather");
    ct_scene *s = scene_new("one");
    int m = ts_diffuse(s, "m", v3s(0.5f), v3s(1.0f), &err);
    cr_assert(ts_quad(s, "q", (uint32_t)m, v3(0, 0, 0), v3(1, 0, 0), v3(0, 0, 1), &err) >= 0);
    CHECK(scene_finalize(s, &err));
    trc_options o;
    trc_options_default(&o, TRC_MODE_DRT);
    o.gather_rays = 0;
    trc_tracer *t;
    cr_assert_eq(trc_new(s, NULL, &o, &t, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "gather rays 0"), "%s", err.msg);
    scene_free(s);
}

/* --- shadows of transparent objects ----------------------------------------- */

/* The floor under a small light at (light_x, 5, 0), lit through a glass
 * slab at y in [1, 1.2] or not. */
static vec3 under_slab(trc_mode mode, bool with_slab, float light_x)
{
    ct_error err;
    ct_scene *s = scene_new("shadow");
    int floor_m = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3s(100.0f), &err);
    int gm = ts_glass(s, "glass", 1.5f, v3(1.0f, 0.5f, 1.0f), &err);
    cr_assert(floor_m >= 0 && lamp >= 0 && gm >= 0);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(-10, 0, -10), v3(0, 0, 20), v3(20, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "light", (uint32_t)lamp, v3(light_x - 0.05f, 5, -0.05f), v3(0.1f, 0, 0), v3(0, 0, 0.1f),
                      &err) >= 0);
    if (with_slab)
        cr_assert(ts_box(s, "slab", (uint32_t)gm, v3(-3, 1, -3), v3(3, 1.2f, 3), false, &err) >= 0);
    CHECK(scene_finalize(s, &err));
    /* Direct light only: path stops after one bounce, drt takes a zero
     * indirect part from a stand-in radiosity mesh at the hit itself (the
     * floor and the glass would otherwise interreflect: a final gather
     * meets the floor's lit light again in the slab's reflection). */
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, v3s(0.0f), &rad, &err));
    trc_tracer *t = mode == TRC_MODE_DRT ? make_tracer_ind(s, &rad, mode, 4, 0, 1, TRC_INDIRECT_MESH)
                                         : make_tracer(s, NULL, mode, 4, 0, 1);
    trc_view v = view_of(v3(0, 0.5f, -1.0f), v3(0, 0, 0), 30.0f, 9, 9);
    vec3 l = mean_at(t, &v, 4.5f, 4.5f, 500, 1, NULL);
    trc_free(t);
    rmesh_free(&rad);
    scene_free(s);
    return l;
}

Test(tracer, glass_attenuates_shadow_rays_instead_of_blocking)
{
    for (int mode = TRC_MODE_PATH; mode <= TRC_MODE_DRT; mode++) {
        /* A small light high above: shadow rays cross the slab almost normally. */
        vec3 open = under_slab((trc_mode)mode, false, 0.0f), shaded = under_slab((trc_mode)mode, true, 0.0f);
        /* Two crossings at (nearly) normal incidence: (1 - F0)^2 * transmission. */
        double f0 = 0.04, want = (1 - f0) * (1 - f0);
        cr_assert(open.x > 0.0f);
        double rx = shaded.x / open.x, ry = shaded.y / open.y;
        cr_expect(fabs(rx - want) < 0.01, "%s: glass passes %g of the light, want %g", trc_mode_name((trc_mode)mode),
                  rx, want);
        cr_expect(fabs(ry - want * 0.25) < 0.01, "%s: green passes %g, want %g", trc_mode_name((trc_mode)mode), ry,
                  want * 0.25);
    }
}

/* Light crossing a pane at 60 degrees, beyond glass' critical angle of 41.8
 * degrees: the straight shadow ray stands for light refracted in and out at
 * that outside angle, so both crossings lose the Fresnel reflectance of 60
 * degrees and nothing is totally reflected. */
Test(tracer, glass_passes_oblique_shadow_rays)
{
    float lx = 5.0f * tanf(60.0f * 3.14159265f / 180.0f);
    float ct;
    double f = bsdf_fresnel(0.5f, 1.0f / 1.5f, &ct), want = (1 - f) * (1 - f);
    for (int mode = TRC_MODE_PATH; mode <= TRC_MODE_DRT; mode++) {
        vec3 open = under_slab((trc_mode)mode, false, lx), shaded = under_slab((trc_mode)mode, true, lx);
        cr_assert(open.x > 0.0f);
        double rx = shaded.x / open.x, ry = shaded.y / open.y;
        cr_expect(fabs(rx - want) < 0.01, "%s: glass passes %g of the light at 60 deg, want %g",
                  trc_mode_name((trc_mode)mode), rx, want);
        cr_expect(fabs(ry - want * 0.25) < 0.01, "%s: green passes %g at 60 deg, want %g",
                  trc_mode_name((trc_mode)mode), ry, want * 0.25);
    }
}

/* --- glass in the interactive solution ------------------------------------ */

/* A red wall (left of x = 0.2) 5 m ahead behind a 0.2 thick glass slab: the
 * samples whose primary hit is the glass take as L_base what the display's
 * see-through glass draws there: the wall's radiosity times transmission *
 * (1 - F) for each of the two crossings, F at the ray's angle; black where
 * the straight ray leaves the scene. The hit stays the glass's. */
Test(tracer, glass_l_base_shows_the_surface_behind)
{
    ct_error err;
    ct_scene *s = scene_new("pane");
    int red = ts_diffuse(s, "red", v3(0.8f, 0.2f, 0.1f), v3s(0.0f), &err);
    vec3 tint = v3(1.0f, 0.5f, 0.9f);
    int gm = ts_glass(s, "glass", 1.5f, tint, &err);
    cr_assert(red >= 0 && gm >= 0);
    cr_assert(ts_quad(s, "wall", (uint32_t)red, v3(-10, -10, -5), v3(10.2f, 0, 0), v3(0, 20, 0), &err) >= 0);
    int slab = ts_box(s, "slab", (uint32_t)gm, v3(-3, -3, -2.2f), v3(3, 3, -2), false, &err);
    cr_assert(slab >= 0);
    CHECK(scene_finalize(s, &err));
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, v3s(1.0f), &rad, &err));
    trc_tracer *t = make_tracer(s, &rad, TRC_MODE_REUSE, 0, 0, 0);
    trc_view v = view_of(v3(0, 0, 0), v3(0, 0, -1), 60.0f, 9, 9);
    const float px[3] = {4.5f, 0.5f, 8.5f}, py[3] = {4.5f, 0.5f, 4.5f};
    ct_request req[3];
    ct_sample out[3];
    memset(req, 0, sizeof req);
    for (int i = 0; i < 3; i++) {
        req[i].id = (uint64_t)i;
        req[i].px = px[i];
        req[i].py = py[i];
    }
    trc_stats st = {0};
    trc_trace_primary(t, &v, req, 3, out, &st);
    for (int i = 0; i < 3; i++) {
        cr_assert(out[i].flags & CT_SAMPLE_HIT);
        cr_expect_eq(out[i].node, (uint32_t)slab, "sample %d: the primary hit is the glass", i);
        vec3 d = v3_norm(out[i].hit);
        float ct;
        float f = bsdf_fresnel(fabsf(d.z), 1.0f / 1.5f, &ct);
        vec3 pass = v3_scale(tint, 1.0f - f);
        vec3 want = i == 2 ? v3s(0.0f) : v3_mul(v3_mul(pass, pass), v3(0.8f, 0.2f, 0.1f));
        printf("metric: glass pixel (%g, %g): cos %.3f, L_base %.4f %.4f %.4f, want %.4f %.4f %.4f\n",
               (double)px[i], (double)py[i], (double)fabsf(d.z), (double)out[i].l_base.x, (double)out[i].l_base.y,
               (double)out[i].l_base.z, (double)want.x, (double)want.y, (double)want.z);
        cr_expect(fabsf(out[i].l_base.x - want.x) < 1e-5f && fabsf(out[i].l_base.y - want.y) < 1e-5f &&
                      fabsf(out[i].l_base.z - want.z) < 1e-5f,
                  "sample %d: L_base %g %g %g, want %g %g %g", i, (double)out[i].l_base.x, (double)out[i].l_base.y,
                  (double)out[i].l_base.z, (double)want.x, (double)want.y, (double)want.z);
    }
    trc_free(t);
    rmesh_free(&rad);
    scene_free(s);
}
