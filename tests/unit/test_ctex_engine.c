/* Engine tests of the corrective textures (master/ctex.h): the texture
 * hierarchy, per-view assignment with frustum culling (§3.3), projections
 * (§3.2), insertion, aging (§3.5), mixing and resampling on split/merge, on
 * small scenes built in code (tests/support/ctex_scenes.h). Over 600
 * lines: one module's tests over the scenes those share. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/half.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "common/rng.h"
#include "common/scene.h"
#include "master/ctex.h"
#include "master/ctex_hier.h"
#include "master/ctex_internal.h"   /* the resolution rule, driven directly */
#include "master/ctex_tex.h"
#include "tests/support/ctex_scenes.h"

static ct_error err;

Test(ctex_engine, hierarchy_groups_parts)
{
    tcx_scene t;
    tcx_build(&t);
    ctex_hier h;
    cr_assert_eq(ctex_hier_build(&t.m, t.s->mats, t.s->nmats, 10.0f, 0.01f, 1.0f, 0, &h, &err), 0, "%s", err.msg);
    /* leaves = parts: floor, 3 x (box, plate), panel, behind */
    cr_assert_eq(h.nleaves, 9);
    uint32_t ntri = 0;
    for (uint32_t l = 0; l < h.nleaves; l++) {
        const ctex_hnode *n = &h.nodes[h.leaf_node[l]];
        cr_assert_eq(n->end, h.leaf_node[l] + 1, "leaf has no children");
        ntri += n->tri_end - n->tri_begin;
        for (uint32_t i = n->tri_begin; i < n->tri_end; i++) cr_assert_eq(t.m.tri_node[h.tris[i]], h.leaf_part[l]);
    }
    cr_assert_eq(ntri, t.m.ntris);
    /* the root has 5 children items (floor, g0..g2, panel, behind = 6): a BVH
     * refines it into a binary tree; every inner node's ranges nest */
    for (uint32_t i = 0; i < h.nnodes; i++) {
        const ctex_hnode *n = &h.nodes[i];
        if (n->parent >= 0) {
            const ctex_hnode *p = &h.nodes[n->parent];
            cr_assert(n->leaf_begin >= p->leaf_begin && n->leaf_end <= p->leaf_end);
            cr_assert(i > (uint32_t)n->parent && n->end <= p->end);
        }
        int nch = 0;
        for (uint32_t c = i + 1; c < n->end; c = h.nodes[c].end) nch++;
        if (n->scene_node < 0) cr_assert_eq(nch, 2, "BVH nodes are binary");
    }
    /* flatness: floor, plates and panel are flat, boxes are not */
    cr_assert(h.nodes[h.leaf_node[h.part_leaf[t.floor]]].flat);
    cr_assert(h.nodes[h.leaf_node[h.part_leaf[t.plate[1]]]].flat);
    cr_assert(h.nodes[h.leaf_node[h.part_leaf[t.panel]]].flat);
    cr_assert(!h.nodes[h.leaf_node[h.part_leaf[t.box[0]]]].flat);
    cr_assert_gt(h.nodes[h.leaf_node[h.part_leaf[t.panel]]].gloss, 0.5f);
    cr_assert_eq(h.nodes[h.leaf_node[h.part_leaf[t.floor]]].gloss, 0.0f);
    /* a group of a box and its plate is not flat (two normals, not coplanar) */
    cr_assert(!h.nodes[0].flat);
    ctex_hier_free(&h);
    tcx_release(&t);
}

Test(ctex_engine, bvh_groups_by_material)
{
    /* Four coplanar tiles in a row with alternating materials A B A B: with a
     * strong material weight the BVH pairs same-material tiles. */
    ct_scene *s = scene_new("tiles");
    scene_material a = scene_material_default("a"), b = scene_material_default("b");
    a.diffuse = v3s(0.5f);
    b.diffuse = v3s(0.2f);
    b.glossy = SCENE_GLOSSY_PHONG; b.specular = v3s(0.5f); b.phong_exp = 50;
    uint32_t ma = (uint32_t)scene_add_material(s, &a, &err), mb = (uint32_t)scene_add_material(s, &b, &err);
    for (int i = 0; i < 4; i++) {
        char name[8];
        snprintf(name, sizeof name, "t%d", i);
        float x = (float)i * 1.1f;
        tcx_quad_part(s, name, i % 2 ? mb : ma, v3(x, 0, 0), v3(x, 0, 1), v3(x + 1, 0, 1), v3(x + 1, 0, 0));
    }
    cr_assert_eq(scene_finalize(s, &err), 0);
    ct_radmesh m;
    cr_assert_eq(rmesh_from_scene(s, v3s(0.5f), &m, &err), 0);
    ctex_hier h;
    cr_assert_eq(ctex_hier_build(&m, s->mats, s->nmats, 10.0f, 0.01f, 100.0f, 0, &h, &err), 0);
    /* the root's two BVH children each hold one material */
    int groups = 0;
    for (uint32_t c = 1; c < h.nodes[0].end; c = h.nodes[c].end) {
        cr_assert_neq(h.nodes[c].material, UINT32_MAX, "child %u mixes materials", c);
        groups++;
    }
    cr_assert_eq(groups, 2);
    ctex_hier_free(&h);
    /* with no material weight, space wins: neighbours are paired */
    cr_assert_eq(ctex_hier_build(&m, s->mats, s->nmats, 10.0f, 0.01f, 0.0f, 0, &h, &err), 0);
    for (uint32_t c = 1; c < h.nodes[0].end; c = h.nodes[c].end) cr_assert_eq(h.nodes[c].material, UINT32_MAX);
    ctex_hier_free(&h);
    rmesh_free(&m);
    scene_free(s);
}

/* Number of active textures and whether every one sits on a leaf. */
static uint32_t count_textures(ctex *c, int *all_leaves, uint32_t *parts_covered)
{
    ctex_stats st = ctex_get_stats(c);
    *all_leaves = 1;
    *parts_covered = 0;
    for (uint32_t id = 0; id < 4096; id++) {
        uint32_t hn;
        if (ctex_texture_info(c, id, &hn, NULL, NULL, NULL, NULL, NULL) != 1) continue;
        uint32_t np;
        ctex_node_parts(c, hn, &np);
        if (np != 1) *all_leaves = 0;
        *parts_covered += np;
    }
    return st.textures;
}

Test(ctex_engine, eps_zero_gives_leaf_textures)
{
    tcx_scene t;
    ctex *c = tcx_leaf_engine(&t, 64, 64);
    int leaves;
    uint32_t covered;
    uint32_t n = count_textures(c, &leaves, &covered);
    cr_assert(leaves, "ε = 0: every texture on a single part");
    cr_assert_eq(n, 8, "all parts but the one behind the camera: %u", n);
    cr_assert_eq(ctex_owner(c, (uint32_t)t.behind, UINT32_MAX, v3s(0.0f)), -1, "frustum culling");
    cr_assert_geq(ctex_owner(c, (uint32_t)t.floor, UINT32_MAX, v3s(0.0f)), 0);
    ctex_free(c);
    tcx_release(&t);
}

Test(ctex_engine, eps_huge_gives_one_per_top_node)
{
    tcx_scene t;
    tcx_build(&t);
    ctex_options o = ctex_options_default();
    o.eps = 1e9f;
    o.max_proj = 0.0f;
    ctex *c = tcx_engine(&t, o);
    /* from far away and above, nothing reaches the eye plane */
    ct_camera cam = cam_look_at(v3(0, 60, 60), v3(0, 0, 0), v3(0, 1, 0), 60.0f);
    cr_assert_eq(ctex_set_camera(c, &cam, 64, 64, &err), 0);
    int leaves;
    uint32_t covered;
    uint32_t n = count_textures(c, &leaves, &covered);
    /* the top nodes are the root's two BVH children */
    uint32_t top = 0;
    ctex_hier h;
    cr_assert_eq(ctex_hier_build(&t.m, t.s->mats, t.s->nmats, 10.0f, 0.01f, 1.0f, 0, &h, &err), 0);
    for (uint32_t ch = 1; ch < h.nodes[0].end; ch = h.nodes[ch].end) top++;
    ctex_hier_free(&h);
    cr_assert_eq(n, top, "%u textures, %u top nodes", n, top);
    cr_assert_eq(covered, 9, "all parts are covered");
    /* with a camera close to the objects the parallax test splits even
     * ε = 1e9 nodes that reach the eye plane: every part still textured once */
    ctex_free(c);
    tcx_release(&t);
}

Test(ctex_engine, default_eps_between)
{
    tcx_scene t;
    ctex *c = tcx_front_engine(&t, ctex_options_default(), 128, 128);
    int leaves;
    uint32_t covered;
    uint32_t n = count_textures(c, &leaves, &covered);
    cr_assert_eq(covered, 8, "each visible part covered exactly once (%u)", covered);
    cr_assert(n >= 1 && n <= 8);
    ctex_free(c);
    tcx_release(&t);
}

Test(ctex_engine, frustum_culling_looking_away)
{
    tcx_scene t;
    tcx_build(&t);
    ctex *c = tcx_engine(&t, ctex_options_default());
    ct_camera cam = cam_look_at(v3(0, 1, 20), v3(0, 1, 40), v3(0, 1, 0), 40.0f);
    cr_assert_eq(ctex_set_camera(c, &cam, 64, 64, &err), 0);
    cr_assert_geq(ctex_owner(c, (uint32_t)t.behind, UINT32_MAX, v3s(0.0f)), 0, "the box in front now has a texture");
    cr_assert_eq(ctex_owner(c, (uint32_t)t.panel, UINT32_MAX, v3s(0.0f)), -1);
    cr_assert_eq(ctex_owner(c, (uint32_t)t.box[1], UINT32_MAX, v3s(0.0f)), -1);
    ctex_free(c);
    tcx_release(&t);
}

Test(ctex_engine, camera_local_maps_bounding_rect_to_unit_square)
{
    tcx_scene t;
    const int W = 96, H = 64;
    ctex *c = tcx_leaf_engine(&t, W, H);
    ct_camera cam = tcx_front_cam();
    int32_t id = ctex_owner(c, (uint32_t)t.box[1], UINT32_MAX, v3s(0.0f));
    cr_assert_geq(id, 0);
    ctex_proj_kind kind;
    mat4 m;
    cr_assert_eq(ctex_texture_info(c, (uint32_t)id, NULL, NULL, NULL, &kind, &m, NULL), 1);
    cr_assert_eq(kind, CTEX_PROJ_CAMERA);
    bounds3 b = t.s->nodes[t.box[1]].bounds;
    float umin = INFINITY, umax = -INFINITY, vmin = INFINITY, vmax = -INFINITY;
    for (int i = 0; i < 8; i++) {
        vec3 p = b3_corner(b, i);
        vec4 q = m4_point4(&m, p);
        cr_assert_gt(q.w, 0.0f);
        float u = q.x / q.w, v = q.y / q.w;
        umin = fminf(umin, u); umax = fmaxf(umax, u); vmin = fminf(vmin, v); vmax = fmaxf(vmax, v);
        /* the texture position is an affine map of the pixel position */
        float px, py;
        cr_assert(cam_project(&cam, W, H, p, &px, &py, NULL));
        (void)px; (void)py;
    }
    cr_assert_float_eq(umin, 0.0f, 1e-4);
    cr_assert_float_eq(umax, 1.0f, 1e-4);
    cr_assert_float_eq(vmin, 0.0f, 1e-4);
    cr_assert_float_eq(vmax, 1.0f, 1e-4);
    /* v grows downwards like image rows: the top of the box has the smaller v */
    vec4 top = m4_point4(&m, v3(0, 1, 0.5f)), bot = m4_point4(&m, v3(0, 0, 0.5f));
    cr_assert_lt(top.y / top.w, bot.y / bot.w);
    ctex_free(c);
    tcx_release(&t);
}

Test(ctex_engine, object_local_projection_along_normal)
{
    tcx_scene t;
    ctex *c = tcx_leaf_engine(&t, 64, 64);
    int32_t id = ctex_owner(c, (uint32_t)t.plate[0], UINT32_MAX, v3s(0.0f));
    ctex_proj_kind kind;
    mat4 m;
    cr_assert_eq(ctex_texture_info(c, (uint32_t)id, NULL, NULL, NULL, &kind, &m, NULL), 1);
    cr_assert_eq(kind, CTEX_PROJ_OBJECT);
    /* the plate's corners map onto the unit square's corners, w = 1, and a
     * point moved along the normal keeps its texture position */
    float umin = INFINITY, umax = -INFINITY;
    for (uint32_t tt = t.s->nodes[t.plate[0]].tri_begin; tt < t.s->nodes[t.plate[0]].tri_end; tt++)
        for (int k = 0; k < 3; k++) {
            vec4 q = m4_point4(&m, t.s->pos[t.s->tris[3 * tt + k]]);
            cr_assert_float_eq(q.w, 1.0f, 1e-6);
            cr_assert(q.x > -1e-4f && q.x < 1.0001f && q.y > -1e-4f && q.y < 1.0001f);
            umin = fminf(umin, q.x); umax = fmaxf(umax, q.x);
        }
    cr_assert_float_eq(umin, 0.0f, 1e-4);
    cr_assert_float_eq(umax, 1.0f, 1e-4);
    vec4 a = m4_point4(&m, v3(-4.2f, 1.01f, 0.1f)), b = m4_point4(&m, v3(-4.2f, 3.0f, 0.1f));
    cr_assert_float_eq(a.x, b.x, 1e-5);
    cr_assert_float_eq(a.y, b.y, 1e-5);
    ctex_free(c);
    tcx_release(&t);
}


Test(ctex_engine, insert_reads_correction_and_error)
{
    tcx_scene t;
    ctex *c = tcx_leaf_engine(&t, 64, 64);
    ctex_insert_info info;
    ct_sample s = tcx_sample((uint32_t)t.floor, v3(1, 0, 2), v3(0.8f, 0.6f, 0.4f), v3(0.5f, 0.5f, 0.5f));
    cr_assert_eq(ctex_insert(c, &s, &info), 1);
    cr_assert_float_eq(info.correction.x, 0.0f, 1e-7, "empty texture: no correction yet");
    cr_assert_float_eq(info.error.x, 0.3f, 1e-6);
    cr_assert_float_eq(info.error.z, -0.1f, 1e-6);
    /* texels hold halves, as the display does */
    const float h3 = half_to_float(half_from_float(0.8f - 0.5f)), h1 = half_to_float(half_from_float(0.4f - 0.5f));
    vec3 l = ctex_lookup(c, (uint32_t)t.floor, UINT32_MAX, v3(1, 0, 2));
    cr_assert_float_eq(l.x, h3, 1e-6, "the first sample floods its texture");
    cr_assert_float_eq(l.z, h1, 1e-6);
    /* the same sample again: the error is now only the half rounding */
    cr_assert_eq(ctex_insert(c, &s, &info), 1);
    cr_assert_float_eq(info.error.x, 0.8f - (0.5f + h3), 1e-6);
    cr_assert_lt(fabsf(info.error.x), 0.3f * 0x1p-11f);
    /* a miss and a culled node are dropped */
    s.flags = 0;
    cr_assert_eq(ctex_insert(c, &s, &info), 0);
    s = tcx_sample((uint32_t)t.behind, v3(0, 1, 30), v3s(1), v3s(0));
    cr_assert_eq(ctex_insert(c, &s, &info), 0);
    cr_assert_eq(info.tex, -1);
    /* a dropped sample's error is its whole ΔL (the request queue uses it) */
    cr_assert_float_eq(info.error.x, 1.0f, 1e-7);
    cr_assert_float_eq(info.correction.x, 0.0f, 1e-7);
    s = tcx_sample(9999, v3(0, 0, 0), v3s(1), v3s(0));
    cr_assert_eq(ctex_insert(c, &s, &info), 0);
    ctex_stats st = ctex_get_stats(c);
    cr_assert_eq(st.inserted, 2);
    cr_assert_eq(st.dropped, 3);
    ctex_free(c);
    tcx_release(&t);
}

/* Pixels between the images of p and p + d under the front camera. */
static double px_dist(vec3 p, vec3 d, int w, int h)
{
    ct_camera cam = tcx_front_cam();
    float ax, ay, bx, by, z;
    cr_assert(cam_project(&cam, w, h, p, &ax, &ay, &z));
    cr_assert(cam_project(&cam, w, h, v3_add(p, d), &bx, &by, &z));
    return hypot((double)bx - ax, (double)by - ay);
}

/* The floor seen at a slant (about 16 degrees): its texels look far wider
 * than deep, so splat rings reach further in depth (ex away from 1), by the
 * ratio of the texel's sides on screen, here measured by projecting a texel's
 * two edges (finite differences, independent of the engine's derivative).
 * A camera-local texture's texels are (x1 - x0) / w by (y1 - y0) / h pixels. */
Test(ctex_engine, splat_ex_follows_the_texels_on_screen)
{
    tcx_scene t;
    const int W = 256, H = 256;
    ctex *c = tcx_leaf_engine(&t, W, H);
    ctex_insert_info info;
    ct_sample s = tcx_sample((uint32_t)t.floor, v3(1, 0, 6), v3s(1.0f), v3s(0.0f));
    cr_assert_eq(ctex_insert(c, &s, &info), 1);
    int tw, th;
    ctex_proj_kind kind;
    mat4 m;
    ctex_texture_info(c, (uint32_t)info.tex, NULL, &tw, &th, &kind, &m, NULL);
    cr_assert_eq(kind, CTEX_PROJ_OBJECT);
    /* world -> texture rows u = a.p + .., v = b.p + ..: a texel's edges are
     * a / |a|^2 / w and b / |b|^2 / h */
    vec3 a = v3(m.m[0][0], m.m[0][1], m.m[0][2]), b = v3(m.m[1][0], m.m[1][1], m.m[1][2]);
    vec3 eu = v3_scale(a, 1.0f / (v3_len2(a) * (float)tw)), ev = v3_scale(b, 1.0f / (v3_len2(b) * (float)th));
    const float pts[][3] = {{1, 0, 6}, {-3, 0, 2}, {4, 0, -6}, {0, 0, 11.5f}};
    for (size_t i = 0; i < sizeof pts / sizeof pts[0]; i++) {
        vec3 p = v3(pts[i][0], pts[i][1], pts[i][2]);
        const double f = 1e-3;
        double sx = px_dist(p, v3_scale(eu, (float)f), W, H) / f, sy = px_dist(p, v3_scale(ev, (float)f), W, H) / f;
        double want = ctex_aniso_ex((float)sqrt(sy / sx)), got = ctex_splat_ex(c, (uint32_t)info.tex, p);
        cr_assert(fabs(got / want - 1.0) < 0.01, "at (%g,%g,%g): ex %g, projected texel %g x %g px: %g", (double)p.x,
                  (double)p.y, (double)p.z, got, sx, sy, want);
        /* the floor's depth axis is squeezed, rings stretch along it;
         * except right below the eye (the last point), where the texels
         * look nearly square */
        int depth_is_u = fabsf(a.z) > fabsf(a.x);
        if (i < 3) cr_assert(depth_is_u ? got > 1.0 / CTEX_ANISO_ISO : got < CTEX_ANISO_ISO, "ex %g: rings should stretch in depth", got);
    }
    cr_assert_eq(ctex_splat_ex(c, 9999, v3s(0.0f)), 1.0f, "not a texture");
    /* the glossy panel faces the camera: camera-local or not, near 1 */
    ct_sample sp = tcx_sample((uint32_t)t.panel, v3(0, 1, -5), v3s(1.0f), v3s(0.0f));
    cr_assert_eq(ctex_insert(c, &sp, &info), 1);
    float e = ctex_splat_ex(c, (uint32_t)info.tex, v3(0, 1, -5));
    cr_assert_eq(ctex_aniso_ex(e), 1.0f, "a facing panel splats square rings (ex %g)", (double)e);
    ctex_free(c);
    tcx_release(&t);
}

Test(ctex_engine, diffuse_object_local_does_not_age)
{
    tcx_scene t;
    ctex *c = tcx_leaf_engine(&t, 64, 64);
    tcx_fill_floor(c, (uint32_t)t.floor, 0.25f, 0.0f);
    int32_t id = ctex_owner(c, (uint32_t)t.floor, UINT32_MAX, v3s(0.0f));
    ct_sample sp = tcx_sample((uint32_t)t.panel, v3(0, 1, -5), v3s(1.0f), v3s(0.0f));
    ctex_insert_info info;
    cr_assert_eq(ctex_insert(c, &sp, &info), 1);
    int32_t pid = info.tex;
    float v0, pv0;
    ctex_texture_info(c, (uint32_t)id, NULL, NULL, NULL, NULL, NULL, &v0);
    ctex_texture_info(c, (uint32_t)pid, NULL, NULL, NULL, NULL, NULL, &pv0);
    vec3 before = ctex_lookup(c, (uint32_t)t.floor, UINT32_MAX, v3(2, 0, 3));
    /* move and turn the camera */
    ct_camera cam2 = cam_look_at(v3(6, 5, 10), v3(-1, 0, 0), v3(0, 1, 0), 50.0f);
    cr_assert_eq(ctex_set_camera(c, &cam2, 64, 64, &err), 0);
    cr_assert_eq(ctex_owner(c, (uint32_t)t.floor, UINT32_MAX, v3s(0.0f)), id, "the floor keeps its texture");
    float v1, pv1;
    ctex_texture_info(c, (uint32_t)id, NULL, NULL, NULL, NULL, NULL, &v1);
    ctex_texture_info(c, (uint32_t)pid, NULL, NULL, NULL, NULL, NULL, &pv1);
    cr_assert_eq(v1, v0, "a diffuse object-local texture never ages");
    cr_assert_gt(pv1, pv0 + 1.0f, "a glossy one ages (%g -> %g)", (double)pv0, (double)pv1);
    vec3 after = ctex_lookup(c, (uint32_t)t.floor, UINT32_MAX, v3(2, 0, 3));
    cr_assert_eq(after.x, before.x, "and keeps its contents");
    ctex_free(c);
    tcx_release(&t);
}

/* RMS deviation from `mean` of node's correction at a 24 x 24 grid of
 * points o + a du + b dv, a and b in (0, 1). */
static double rms_dev(ctex *c, uint32_t node, vec3 o, vec3 du, vec3 dv, float mean)
{
    double se = 0.0;
    for (int i = 0; i < 24; i++)
        for (int j = 0; j < 24; j++) {
            float a = ((float)i + 0.5f) / 24.0f, b = ((float)j + 0.5f) / 24.0f;
            vec3 l = ctex_lookup(c, node, UINT32_MAX, v3_add(o, v3_add(v3_scale(du, a), v3_scale(dv, b))));
            se += ((double)l.x - mean) * ((double)l.x - mean);
        }
    return sqrt(se / (24.0 * 24.0));
}

/* Inserts n samples of correction 0.5 + uniform noise in [-0.3, 0.3] at
 * random points of the floor square [-4, 4]^2 and of the glossy panel, and
 * returns the RMS deviation of the floor's and the panel's corrections. */
static void noisy_field(float mix, int n, double *floor_dev, double *panel_dev)
{
    tcx_scene t;
    ctex_options o = ctex_options_default();
    o.eps = 0.0f;
    o.mix = mix;
    ctex *c = tcx_front_engine(&t, o, 64, 64);
    ct_rng r = rng_make(42, 0, 0, 0);
    ctex_insert_info info;
    for (int i = 0; i < n; i++) {
        float u = rng_float(&r), v = rng_float(&r), e = 0.6f * (rng_float(&r) - 0.5f);
        ct_sample s = tcx_sample((uint32_t)t.floor, v3(-4.0f + 8.0f * u, 0.0f, -4.0f + 8.0f * v), v3s(0.5f + e),
                                v3s(0.0f));
        cr_assert_eq(ctex_insert(c, &s, &info), 1);
        s = tcx_sample((uint32_t)t.panel, v3(-2.5f + 5.0f * u, 0.7f + 2.1f * v, -5.0f), v3s(0.5f + e), v3s(0.0f));
        cr_assert_eq(ctex_insert(c, &s, &info), 1);
    }
    *floor_dev = rms_dev(c, (uint32_t)t.floor, v3(-3.5f, 0.0f, -3.5f), v3(7.0f, 0, 0), v3(0, 0, 7.0f), 0.5f);
    *panel_dev = rms_dev(c, (uint32_t)t.panel, v3(-2.2f, 0.9f, -5.0f), v3(4.4f, 0, 0), v3(0, 1.7f, 0), 0.5f);
    ctex_free(c);
    tcx_release(&t);
}

/* Mixing averages the noise of neighbouring samples out on a diffuse
 * surface (the default mix, 0.3), and much less on a glossy one, whose
 * corrections carry detail. Mix 1 keeps each sample's own value: the
 * noise of single samples, 0.6 / sqrt(12) = 0.17 at a texel, somewhat less
 * after bilinear lookups and box-filtered halvings (0.10 here). */
Test(ctex_engine, mixing_averages_noise_on_diffuse_surfaces)
{
    double f1, p1, f5, p5;
    noisy_field(1.0f, 400, &f1, &p1);
    noisy_field(ctex_options_default().mix, 400, &f5, &p5);
    cr_log_info("rms deviation: floor %.4f -> %.4f, glossy panel %.4f -> %.4f", f1, f5, p1, p5);
    cr_assert_gt(f1, 0.08, "unmixed: single samples' noise (%.4f)", f1);
    cr_assert_lt(f5, 0.75 * f1, "mixed floor: %.4f against %.4f unmixed", f5, f1);
    cr_assert_gt(p5 / p1, f5 / f1 + 0.15, "the glossy panel mixes less (%.4f / %.4f against %.4f / %.4f)", p5, p1,
                 f5, f1);
}

Test(ctex_engine, split_and_merge_resample_contents)
{
    tcx_scene t;
    tcx_build(&t);
    ctex_options o = ctex_options_default();
    ctex *c = tcx_engine(&t, o);
    /* far away: the group g1 (box + plate) shares one texture */
    ct_camera far = cam_look_at(v3(0, 30, 60), v3(0, 0.5f, 0), v3(0, 1, 0), 20.0f);
    cr_assert_eq(ctex_set_camera(c, &far, 64, 64, &err), 0);
    int32_t a = ctex_owner(c, (uint32_t)t.box[1], UINT32_MAX, v3s(0.0f)), b = ctex_owner(c, (uint32_t)t.plate[1], UINT32_MAX, v3s(0.0f));
    cr_assert_geq(a, 0);
    cr_assert_eq(a, b, "box and plate share a texture from far away");
    ctex_insert_info info;
    for (int i = 0; i < 200; i++) {
        float x = -0.6f + 1.2f * (float)(i % 20) / 19.0f, z = -0.6f + 1.2f * (float)(i / 20) / 9.0f;
        ct_sample s = tcx_sample((uint32_t)t.plate[1], v3(x, 1.01f, z), v3s(0.75f), v3s(0.25f));
        ctex_insert(c, &s, &info);
    }
    vec3 l0 = ctex_lookup(c, (uint32_t)t.plate[1], UINT32_MAX, v3(0.1f, 1.01f, 0.1f));
    cr_assert_float_eq(l0.x, 0.5f, 1e-5);
    /* close up: the group splits; the plate's new texture is resampled */
    ct_camera near = cam_look_at(v3(0, 2.2f, 2.2f), v3(0, 0.8f, 0), v3(0, 1, 0), 60.0f);
    cr_assert_eq(ctex_set_camera(c, &near, 64, 64, &err), 0);
    int32_t a2 = ctex_owner(c, (uint32_t)t.box[1], UINT32_MAX, v3s(0.0f)), b2 = ctex_owner(c, (uint32_t)t.plate[1], UINT32_MAX, v3s(0.0f));
    cr_assert_geq(a2, 0);
    cr_assert_geq(b2, 0);
    cr_assert_neq(a2, b2, "split into box and plate");
    vec3 l1 = ctex_lookup(c, (uint32_t)t.plate[1], UINT32_MAX, v3(0.1f, 1.01f, 0.1f));
    cr_assert_float_eq(l1.x, 0.5f, 1e-4, "split texture resampled from the old one (%g)", (double)l1.x);
    /* back far away: merged again, still carrying the correction */
    cr_assert_eq(ctex_set_camera(c, &far, 64, 64, &err), 0);
    cr_assert_eq(ctex_owner(c, (uint32_t)t.box[1], UINT32_MAX, v3s(0.0f)), ctex_owner(c, (uint32_t)t.plate[1], UINT32_MAX, v3s(0.0f)));
    vec3 l2 = ctex_lookup(c, (uint32_t)t.plate[1], UINT32_MAX, v3(0.1f, 1.01f, 0.1f));
    cr_assert_float_eq(l2.x, 0.5f, 1e-3, "merged texture resampled (%g)", (double)l2.x);
    ctex_free(c);
    tcx_release(&t);
}


/* Whether events hold a PROJ of texture id. */
static bool has_proj_event(const ctex *c, int32_t id)
{
    size_t n;
    const ctex_event *ev = ctex_events(c, &n);
    for (size_t i = 0; i < n; i++)
        if (ev[i].kind == CTEX_EV_PROJ && ev[i].tex == (uint32_t)id) return true;
    return false;
}

/* A camera-local texture keeps the projector it was made for when the
 * camera moves a little (same matrix, no PROJ event, the correction at a
 * surface point exactly as before, refinement writes where its pixel's ray
 * meets the surface), and gets the new view's when the view of its node
 * turned by more than --keep-projector-deg, or always with 0. */
Test(ctex_engine, camera_local_keeps_its_projector_on_small_moves)
{
    for (int pass = 0; pass < 2; pass++) {
        tcx_scene t;
        ctex_options o = ctex_options_default();
        o.eps = 0.0f;
        o.mix = 1.0f;   /* plain Voronoi cells: the refinement's arithmetic below */
        if (pass == 1) o.keep_deg = 0.0f;
        const int W = 96, H = 64;
        ctex *c = tcx_front_engine(&t, o, W, H);
        uint32_t box = (uint32_t)t.box[1];
        int32_t id = ctex_owner(c, box, UINT32_MAX, v3s(0.0f));
        cr_assert_geq(id, 0);
        ctex_proj_kind kind;
        mat4 m0, m1;
        cr_assert_eq(ctex_texture_info(c, (uint32_t)id, NULL, NULL, NULL, &kind, &m0, NULL), 1);
        cr_assert_eq(kind, CTEX_PROJ_CAMERA);
        vec3 p = v3(0.1f, 0.6f, 0.5f);   /* on the box's front face */
        ct_sample s = tcx_sample(box, p, v3s(1.0f), v3s(0.0f));
        ctex_insert_info info;
        cr_assert_eq(ctex_insert(c, &s, &info), 1);
        vec3 before = ctex_lookup(c, box, UINT32_MAX, p);
        cr_assert_gt(before.x, 0.5f);
        ctex_events_clear(c);
        ctex_stats st0 = ctex_get_stats(c);
        ct_camera small = cam_look_at(v3(0.3f, 4.1f, 13.8f), v3(0, 0.5f, 0), v3(0, 1, 0), 50.0f);
        cr_assert_eq(ctex_set_camera(c, &small, W, H, &err), 0, "%s", err.msg);
        cr_assert_eq(ctex_owner(c, box, UINT32_MAX, v3s(0.0f)), id);
        cr_assert_eq(ctex_texture_info(c, (uint32_t)id, NULL, NULL, NULL, NULL, &m1, NULL), 1);
        ctex_stats st1 = ctex_get_stats(c);
        vec3 after = ctex_lookup(c, box, UINT32_MAX, p);
        if (pass == 0) {
            cr_assert_eq(memcmp(&m0, &m1, sizeof m0), 0, "the projector changed on a small move");
            cr_assert_not(has_proj_event(c, id), "a PROJ event for a kept projector");
            cr_assert_gt(st1.kept, st0.kept);
            cr_assert_eq(after.x, before.x, "the correction moved: %g -> %g", (double)before.x, (double)after.x);
            /* refinement: the pixel whose ray meets p writes p's texels */
            float px, py;
            cr_assert(cam_project(&small, W, H, p, &px, &py, NULL));
            ct_sample r = tcx_sample(box, p, v3s(0.0f), v3s(0.0f));
            r.px = px;
            r.py = py;
            r.l_hq = v3s(-0.25f);   /* its correction: -0.25 */
            ctex_tex *tx = ctex_visible_texture(c, (uint32_t)id);
            float u, v;
            cr_assert(tx && ctex_tex_project(tx, p, &u, &v));
            const ctex_texel *at = ctex_tex_at(tx, (int)(u * (float)tx->w), (int)(v * (float)tx->h));
            size_t ntx = (size_t)tx->w * (size_t)tx->h;
            float *old = malloc(ntx * sizeof *old);
            for (int y = 0; y < tx->h; y++)
                for (int x = 0; x < tx->w; x++) old[(size_t)y * tx->w + x] = ctex_texel_rgb(ctex_tex_at(tx, x, y)).x;
            /* the pixel's second sample: a running mean in which the first
             * pass's value counts as (2 - m) / m = 1 sample here (mix 1) */
            float c1 = ctex_texel_rgb(at).x;
            cr_assert_eq(ctex_refine(c, &r, 2, &info), 1);
            float c2 = ctex_texel_rgb(at).x;
            cr_assert_float_eq(c2, 0.5f * (c1 - 0.25f), 0.01f, "refinement wrote elsewhere: %g -> %g at p's texel",
                               (double)c1, (double)c2);
            cr_assert_eq(ctex_refine(c, &r, 3, &info), 1);
            float c3 = ctex_texel_rgb(at).x;
            cr_assert_float_eq(c3, c2 + (-0.25f - c2) / 3.0f, 0.01f, "third: %g -> %g", (double)c2, (double)c3);
            /* and only there: one pixel covers about a texel of this texture */
            int written = 0;
            for (int y = 0; y < tx->h; y++)
                for (int x = 0; x < tx->w; x++) written += ctex_texel_rgb(ctex_tex_at(tx, x, y)).x != old[(size_t)y * tx->w + x];
            free(old);
            cr_assert_geq(written, 1);
            cr_assert_leq(written, 4, "one pixel's refinement wrote %d texels of a %dx%d texture", written, tx->w, tx->h);
            /* a turn of more than 20 degrees around the node: the new view's projector */
            ct_camera side = cam_look_at(v3(9.0f, 4.0f, 9.0f), v3(0, 0.5f, 0), v3(0, 1, 0), 50.0f);
            ctex_events_clear(c);
            cr_assert_eq(ctex_set_camera(c, &side, W, H, &err), 0, "%s", err.msg);
            int32_t id2 = ctex_owner(c, box, UINT32_MAX, v3s(0.0f));
            cr_assert_geq(id2, 0);
            mat4 m2;
            cr_assert_eq(ctex_texture_info(c, (uint32_t)id2, NULL, NULL, NULL, NULL, &m2, NULL), 1);
            cr_assert_neq(memcmp(&m1, &m2, sizeof m1), 0, "the projector was kept through a 40 degree turn");
            cr_assert(has_proj_event(c, id2));
        } else {
            cr_assert_neq(memcmp(&m0, &m1, sizeof m0), 0, "--keep-projector-deg 0 kept the projector");
            cr_assert(has_proj_event(c, id));
            cr_assert_eq(st1.kept, st0.kept);
            cr_assert_gt(st1.resampled, st0.resampled);
        }
        ctex_free(c);
        tcx_release(&t);
    }
}

/* A camera-local texture that a turn made again reaches past the screen
 * edge that cuts its node (--projector-margin), so that the next small
 * turns keep its projector and its texels; with no margin every turn that
 * shows more of the node resamples it. */
Test(ctex_engine, a_texture_a_turn_made_again_reaches_past_the_screen_edge)
{
    uint64_t resampled[2];
    for (int pass = 0; pass < 2; pass++) {
        tcx_scene t;
        ctex_options o = ctex_options_default();
        o.eps = 0.0f;
        if (pass == 1) o.proj_margin = 0.0f;
        const int W = 384, H = 256;
        tcx_build(&t);
        ctex *c = tcx_engine(&t, o);
        uint32_t box = (uint32_t)t.box[0];
        /* box 0 cut by the screen's left edge */
        float tx = 5.2f;
        ct_camera cam = cam_look_at(v3(0, 4, 14), v3(tx, 0.5f, 0), v3(0, 1, 0), 50.0f);
        cr_assert_eq(ctex_set_camera(c, &cam, W, H, &err), 0, "%s", err.msg);
        int32_t id = ctex_owner(c, box, UINT32_MAX, v3s(0.0f));
        cr_assert_geq(id, 0);
        ctex_tex *tex = ctex_visible_texture(c, (uint32_t)id);
        cr_assert(tex && tex->kind == CTEX_PROJ_CAMERA);
        cr_assert_eq(tex->x0, 0.0f, "box 0 is not cut by the left edge (x0 %g)", (double)tex->x0);
        cr_assert_gt(tex->x1, 4.0f, "box 0 is off the screen");
        ctex_stats st0 = ctex_get_stats(c);
        int reached = 0;
        /* turn left in steps of about 0.16 degrees, each showing more of it */
        for (int k = 0; k < 12; k++) {
            tx -= 0.04f;
            cam = cam_look_at(v3(0, 4, 14), v3(tx, 0.5f, 0), v3(0, 1, 0), 50.0f);
            cr_assert_eq(ctex_set_camera(c, &cam, W, H, &err), 0, "%s", err.msg);
            cr_assert_eq(ctex_owner(c, box, UINT32_MAX, v3s(0.0f)), id);
            tex = ctex_visible_texture(c, (uint32_t)id);
            reached += tex->x0 < 0.0f;
            /* a quarter more than shows at most: most of it stays in view */
            cr_assert_geq(tex->x1 - fmaxf(tex->x0, 0.0f), 0.79f * (tex->x1 - tex->x0), "margin %g of %g px",
                          (double)-tex->x0, (double)(tex->x1 - tex->x0));
            if (pass == 1) cr_assert_geq(tex->x0, 0.0f, "--projector-margin 0 reached past the edge");
        }
        ctex_stats st1 = ctex_get_stats(c);
        resampled[pass] = st1.resampled - st0.resampled;
        if (pass == 0) cr_assert_gt(reached, 0, "no remade texture reached past the screen's edge");
        cr_assert_eq(st1.resampled + st1.kept - st0.resampled - st0.kept >= 12, true);
        ctex_free(c);
        tcx_release(&t);
    }
    cr_log_info("12 small turns resampled box 0's texture %llu times with the margin, %llu without",
                (unsigned long long)resampled[0], (unsigned long long)resampled[1]);
    cr_assert_geq(resampled[1], 10, "without a margin only %llu of 12 turns resampled", (unsigned long long)resampled[1]);
    cr_assert_leq(resampled[0], 4, "with the margin %llu of 12 turns resampled", (unsigned long long)resampled[0]);
}

static int tex_width(const ctex *c, uint32_t id)
{
    int w, h;
    cr_assert_geq(ctex_texture_info(c, id, NULL, &w, &h, NULL, NULL, NULL), 0);
    return w;
}

/* Feeds radius r to texture id until its width changes, at most max
 * times; how many it took (max: no change). */
static int radii_until_change(ctex *c, uint32_t id, int r, int max)
{
    const int w = tex_width(c, id);
    int n = 0;
    while (n < max && tex_width(c, id) == w) {
        ctex_adapt_resolution(c, id, r, 0);
        n++;
    }
    return n;
}

/* An engine whose resolution rule is driven by hand (ctex_internal.h):
 * a window of 16 and one floor sample, whose texture is id, w0 texels
 * wide; with `doubled`, radii of 0 have doubled it once. */
typedef struct rtex {
    tcx_scene t;
    ctex_options o;
    ctex *c;
    uint32_t id;
    int w0;
} rtex;

static void rtex_open(rtex *r, bool doubled)
{
    r->o = ctex_options_default();
    r->o.splat_window = 16;
    r->c = tcx_front_engine(&r->t, r->o, 96, 96);
    ct_sample s = tcx_sample((uint32_t)r->t.floor, v3(0.5f, 0.0f, 0.5f), v3s(0.5f), v3s(0.3f));
    ctex_insert_info info;
    cr_assert_eq(ctex_insert(r->c, &s, &info), 1);
    r->id = (uint32_t)info.tex;
    r->w0 = tex_width(r->c, r->id);
    if (!doubled) return;
    radii_until_change(r->c, r->id, 0, 64);
    cr_assert_eq(tex_width(r->c, r->id), 2 * r->w0, "the texture did not double");
}

static void rtex_close(rtex *r)
{
    ctex_free(r->c);
    tcx_release(&r->t);
}

/* Feeds n radii of the pattern lo (the first n_lo of every 64) and hi (the
 * rest); asserts the width stays; returns the running mean's extreme
 * (the largest with want_peak, else the smallest) after the first 64. */
static float pattern_keeps_size(ctex *c, uint32_t id, int n, int n_lo, int lo, int hi, bool want_peak)
{
    const int w = tex_width(c, id);
    float ext = want_peak ? -1e9f : 1e9f;
    for (int k = 0; k < n; k++) {
        ctex_adapt_resolution(c, id, k % 64 < n_lo ? lo : hi, 0);
        cr_assert_eq(tex_width(c, id), w, "the size changed after %d radii of mean %.3f", k + 1,
                     (double)(n_lo * lo + (64 - n_lo) * hi) / 64.0);
        const float mr = c->slots[id].t.mean_r;
        if (k >= 64) ext = want_peak ? fmaxf(ext, mr) : fminf(ext, mr);
    }
    return ext;
}

/* A doubled texture whose radii run under --splat-hi on the whole but
 * over it for a window now and then (samples landing in a sparse part for a
 * while: office at 1024x1024 halved its floor and walls from 2048 to 1024
 * and doubled them again, up to three times in one first pass): the
 * running mean crosses the threshold, the mean since the doubling does not,
 * so the texture keeps its size. A steady over-threshold run still halves
 * it (resolution_reversals_back_off). */
Test(ctex_engine, resolution_reversal_needs_the_mean_since_the_change)
{
    rtex r;
    rtex_open(&r, true);
    /* 40 radii of 3, then 24 of 8: mean 4.875 under --splat-hi 5; the
     * 16-sample running mean passes 5 in every run of 8s */
    cr_assert_float_eq(r.o.splat_hi, 5.0f, 0.0f);
    float peak = pattern_keeps_size(r.c, r.id, 64 * 200, 40, 3, 8, true);
    cr_assert_gt(peak, r.o.splat_hi, "the running mean never passed --splat-hi (%.2f): the test tests nothing",
                 (double)peak);
    rtex_close(&r);
}

/* The same for a change in the direction of the last one, or the first:
 * radii whose running mean dips under --splat-lo now and then but whose
 * mean since the texture's last change stays over it (office's floor and
 * walls doubled early that way, then halved again, docs/textures.md
 * "Resolution") leave the size alone; a steady run of radii under it still
 * doubles the texture. */
Test(ctex_engine, resolution_change_needs_the_mean_since_the_last)
{
    rtex r;
    rtex_open(&r, false);
    cr_assert_float_eq(r.o.splat_lo, 1.0f, 0.0f);
    /* 40 radii of 2, then 24 of 0: mean 1.25; the 16-sample running mean
     * falls to 0.4 in every run of 0s */
    float low = pattern_keeps_size(r.c, r.id, 64 * 200, 40, 2, 0, false);
    cr_assert_lt(low, r.o.splat_lo, "the running mean never fell under --splat-lo (%.2f): the test tests nothing",
                 (double)low);
    int n = radii_until_change(r.c, r.id, 0, 20000);
    cr_log_info("doubled after %d radii of 0", n);
    cr_assert_eq(tex_width(r.c, r.id), 2 * r.w0, "radii of 0 never doubled it");
    rtex_close(&r);
}

/* The mean since the change starts again at a camera change: the radii
 * measured in the views before tell nothing of this one's density. A
 * doubled texture that took 4,000 radii of 1 (no change) and then sees a
 * camera change, a window of radii of 4 and then radii of 10 halves within
 * a few windows, where the mean since its doubling would have stayed under
 * --splat-hi for 4,000 more. */
Test(ctex_engine, resolution_reversal_counts_from_the_last_camera_change)
{
    rtex r;
    rtex_open(&r, true);
    pattern_keeps_size(r.c, r.id, 4000, 64, 1, 1, true);
    ct_camera cam = cam_look_at(v3(0.5f, 4, 14), v3(0, 0.5f, 0), v3(0, 1, 0), 50.0f);
    cr_assert_eq(ctex_set_camera(r.c, &cam, 96, 96, &err), 0, "%s", err.msg);
    cr_assert_eq(ctex_owner(r.c, (uint32_t)r.t.floor, UINT32_MAX, v3s(0.0f)), (int32_t)r.id, "the floor keeps its texture");
    cr_assert_eq(tex_width(r.c, r.id), 2 * r.w0, "the camera change resized the texture");
    /* a window of 4s (under --splat-hi: no change), so that the mean since
     * the camera change, not the running mean alone, decides below */
    pattern_keeps_size(r.c, r.id, 16, 64, 4, 4, true);
    int n = radii_until_change(r.c, r.id, 10, 4000);
    cr_log_info("halved after %d radii of 10 since the camera change", n);
    cr_assert_eq(tex_width(r.c, r.id), r.w0, "no halving after %d radii of 10", n);
    cr_assert_leq(n, 4 * 16, "halved only after %d radii of 10", n);
    rtex_close(&r);
}

/* A texture whose splat radii change with its size (a dense part on
 * screen and a sparse one: under --splat-lo at one size, over --splat-hi at
 * twice it) halved and doubled again every four windows; each reversal now
 * doubles the samples the next one needs. Driven through the resolution
 * rule itself (ctex_internal.h): radius 0 while the texture is small, 10
 * (the clamp, 2 --splat-hi) once it is large. */
Test(ctex_engine, resolution_reversals_back_off)
{
    rtex r;
    rtex_open(&r, false);
    /* samples until each change: small -> radius 0 (doubles), large -> 10 (halves) */
    int gaps[10];
    for (int k = 0; k < 10; k++) {
        gaps[k] = radii_until_change(r.c, r.id, tex_width(r.c, r.id) > r.w0 ? 10 : 0, 1 << 20);
        cr_assert_lt(gaps[k], 1 << 20, "change %d never came", k);
    }
    cr_log_info("samples before each change: %d %d %d %d %d %d %d %d %d %d", gaps[0], gaps[1], gaps[2], gaps[3],
                gaps[4], gaps[5], gaps[6], gaps[7], gaps[8], gaps[9]);
    /* the first change (nothing before it to reverse) takes one window (the
     * inserted sample was its first); reversal k (from 1) takes 4 windows
     * << (k - 1), up to << 8 */
    cr_assert_eq(gaps[0], 16 - 1);
    for (int k = 1; k < 10; k++) {
        int want = (4 * 16) << (k - 1 < 8 ? k - 1 : 8);
        cr_assert_eq(gaps[k], want, "reversal %d after %d samples, expected %d", k, gaps[k], want);
    }
    rtex_close(&r);
}

/* Refinement past full coverage (docs/sampling.md): a pixel's further
 * samples move its texels as a running mean in which the first pass's
 * (mixed) value counts as (2 - m) / m samples, m the mixing weight (a
 * diffuse node: the --mix option), so the value goes from the first pass's
 * towards the mean of the pixel's samples, never back to one sample's
 * noise. */
Test(ctex_engine, refinement_keeps_the_first_pass_value_as_a_prior)
{
    tcx_scene t;
    ctex_options o = ctex_options_default();
    o.eps = 0.0f;
    const int W = 96, H = 64;
    ctex *c = tcx_front_engine(&t, o, W, H);
    uint32_t box = (uint32_t)t.box[1];
    int32_t id = ctex_owner(c, box, UINT32_MAX, v3s(0.0f));
    cr_assert_geq(id, 0);
    vec3 p = v3(0.1f, 0.6f, 0.5f);   /* on the box's front face */
    ct_sample s = tcx_sample(box, p, v3s(1.0f), v3s(0.0f));
    ctex_insert_info info;
    cr_assert_eq(ctex_insert(c, &s, &info), 1);
    ctex_tex *tx = ctex_visible_texture(c, (uint32_t)id);
    float u, v;
    cr_assert(tx && ctex_tex_project(tx, p, &u, &v));
    const ctex_texel *at = ctex_tex_at(tx, (int)(u * (float)tx->w), (int)(v * (float)tx->h));
    const float t0 = ctex_texel_rgb(at).x;
    cr_assert_float_eq(t0, 1.0f, 0.01f);
    ct_camera cam = tcx_front_cam();
    float px, py;
    cr_assert(cam_project(&cam, W, H, p, &px, &py, NULL));
    ct_sample r = tcx_sample(box, p, v3s(-0.25f), v3s(0.0f));
    r.px = px;
    r.py = py;
    const float prior = (2.0f - o.mix) / o.mix;   /* the box is diffuse: m = --mix */
    for (uint16_t n = 2; n <= 60; n++) {
        cr_assert_eq(ctex_refine(c, &r, n, &info), 1);
        float want = (prior * t0 + (float)(n - 1) * -0.25f) / (prior + (float)(n - 1));
        float got = ctex_texel_rgb(at).x;
        cr_assert_float_eq(got, want, 0.005f + 0.002f * fabsf(want), "sample %u: %g, want %g", n, (double)got,
                           (double)want);
    }
    cr_assert_lt(fabsf(ctex_texel_rgb(at).x + 0.25f), 0.15f, "60 samples of -0.25 outweigh the prior");
    ctex_free(c);
    tcx_release(&t);
}
