/* Engine tests of the corrective textures (master/ctex.h): the texture
 * hierarchy, per-view assignment with frustum culling (§3.3), projections
 * (§3.2), aging (§3.5), resampling on split/merge, events and the
 * compositor, on small scenes built in code. */
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
#include "master/ctex_tex.h"
#include "master/ctex_hier.h"

static ct_error err;

/* Adds the quad p[0..3] with normal n to the open part. */
static void add_quad(ct_scene *s, const vec3 p[4], vec3 n)
{
    uint32_t idx[4];
    for (int i = 0; i < 4; i++) idx[i] = (uint32_t)scene_add_vertex(s, p[i], n, &err);
    cr_assert_eq(scene_add_polygon(s, idx, 4, &err), 0, "%s", err.msg);
}

static void quad_part(ct_scene *s, const char *name, uint32_t mat, vec3 a, vec3 b, vec3 c, vec3 d)
{
    cr_assert_geq(scene_begin_node(s, name, SCENE_NODE_PART, mat, &err), 0, "%s", err.msg);
    vec3 p[4] = {a, b, c, d};
    add_quad(s, p, v3_norm(v3_cross(v3_sub(b, a), v3_sub(c, a))));
    cr_assert_eq(scene_end_node(s, &err), 0);
}

/* A scene with one grey material whose one part `part` is left open for
 * add_quad; one_part_end closes and finalizes it. */
static ct_scene *one_part_begin(const char *name, const char *part)
{
    ct_scene *s = scene_new(name);
    cr_assert_not_null(s);
    scene_material w = scene_material_default("w");
    w.diffuse = v3s(0.5f);
    scene_add_material(s, &w, &err);
    cr_assert_geq(scene_begin_node(s, part, SCENE_NODE_PART, 0, &err), 0);
    return s;
}

static void one_part_end(ct_scene *s)
{
    cr_assert_eq(scene_end_node(s, &err), 0);
    cr_assert_eq(scene_finalize(s, &err), 0, "%s", err.msg);
}

/* A closed box as one part (not flat). */
static void box_part(ct_scene *s, const char *name, uint32_t mat, vec3 lo, vec3 hi)
{
    cr_assert_geq(scene_begin_node(s, name, SCENE_NODE_PART, mat, &err), 0, "%s", err.msg);
    static const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int f = 0; f < 6; f++) {
        uint32_t idx[4];
        for (int k = 0; k < 4; k++) {
            bounds3 b = {lo, hi};
            idx[k] = (uint32_t)scene_add_vertex(s, b3_corner(b, faces[f][k]), v3(0, 1, 0), &err);
        }
        cr_assert_eq(scene_add_polygon(s, idx, 4, &err), 0);
    }
    cr_assert_eq(scene_end_node(s, &err), 0);
}

/* Three groups of objects on a floor, spread along x:
 *   floor (flat, diffuse); group g<i> = box + flat top plate, i = 0..2;
 *   a glossy flat panel; a box far behind the default camera. */
typedef struct tscene {
    ct_scene *s;
    ct_radmesh m;
    int floor, panel, behind, box[3], plate[3];
} tscene;

static void build(tscene *t)
{
    memset(t, 0, sizeof *t);
    t->s = scene_new("test");
    cr_assert_not_null(t->s);
    scene_material dif = scene_material_default("white");
    dif.diffuse = v3(0.7f, 0.7f, 0.7f);
    scene_material red = scene_material_default("red");
    red.diffuse = v3(0.7f, 0.1f, 0.1f);
    scene_material gl = scene_material_default("glossy");
    gl.diffuse = v3(0.1f, 0.1f, 0.1f);
    gl.glossy = SCENE_GLOSSY_PHONG;
    gl.specular = v3(0.8f, 0.8f, 0.8f);
    gl.phong_exp = 200.0f;
    uint32_t mw = (uint32_t)scene_add_material(t->s, &dif, &err);
    uint32_t mr = (uint32_t)scene_add_material(t->s, &red, &err);
    uint32_t mg = (uint32_t)scene_add_material(t->s, &gl, &err);
    t->floor = (int)t->s->nnodes;
    quad_part(t->s, "floor", mw, v3(-10, 0, -10), v3(-10, 0, 10), v3(10, 0, 10), v3(10, 0, -10));
    for (int i = 0; i < 3; i++) {
        char name[16];
        snprintf(name, sizeof name, "g%d", i);
        cr_assert_geq(scene_begin_node(t->s, name, SCENE_NODE_GROUP, UINT32_MAX, &err), 0);
        float x = -4.0f + 4.0f * (float)i;
        t->box[i] = (int)t->s->nnodes;
        box_part(t->s, "box", mr, v3(x - 0.5f, 0, -0.5f), v3(x + 0.5f, 1, 0.5f));
        t->plate[i] = (int)t->s->nnodes;
        quad_part(t->s, "plate", mw, v3(x - 0.6f, 1.01f, -0.6f), v3(x - 0.6f, 1.01f, 0.6f),
                  v3(x + 0.6f, 1.01f, 0.6f), v3(x + 0.6f, 1.01f, -0.6f));
        cr_assert_eq(scene_end_node(t->s, &err), 0);
    }
    t->panel = (int)t->s->nnodes;
    quad_part(t->s, "panel", mg, v3(-3, 0.5f, -5), v3(-3, 3, -5), v3(3, 3, -5), v3(3, 0.5f, -5));
    t->behind = (int)t->s->nnodes;
    box_part(t->s, "behind", mr, v3(-1, 0, 30), v3(1, 2, 32));
    cr_assert_eq(scene_finalize(t->s, &err), 0, "%s", err.msg);
    cr_assert_eq(rmesh_from_scene(t->s, v3s(0.5f), &t->m, &err), 0);
}

static void release(tscene *t)
{
    rmesh_free(&t->m);
    scene_free(t->s);
}

static ctex *engine(tscene *t, ctex_options o)
{
    ctex *c = NULL;
    cr_assert_eq(ctex_new(&t->m, t->s->mats, t->s->nmats, &o, &c, &err), 0, "%s", err.msg);
    return c;
}

static ct_camera front_cam(void)
{
    return cam_look_at(v3(0, 4, 14), v3(0, 0.5f, 0), v3(0, 1, 0), 50.0f);
}

Test(ctex_engine, hierarchy_groups_parts)
{
    tscene t;
    build(&t);
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
    release(&t);
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
        quad_part(s, name, i % 2 ? mb : ma, v3(x, 0, 0), v3(x, 0, 1), v3(x + 1, 0, 1), v3(x + 1, 0, 0));
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

/* The test scene with an engine of options o under the front camera at
 * w x h pixels. */
static ctex *front_engine(tscene *t, ctex_options o, int w, int h)
{
    build(t);
    ctex *c = engine(t, o);
    ct_camera cam = front_cam();
    cr_assert_eq(ctex_set_camera(c, &cam, w, h, &err), 0, "%s", err.msg);
    return c;
}

/* front_engine with leaf textures (eps = 0). */
static ctex *leaf_engine(tscene *t, int w, int h)
{
    ctex_options o = ctex_options_default();
    o.eps = 0.0f;
    return front_engine(t, o, w, h);
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
    tscene t;
    ctex *c = leaf_engine(&t, 64, 64);
    int leaves;
    uint32_t covered;
    uint32_t n = count_textures(c, &leaves, &covered);
    cr_assert(leaves, "ε = 0: every texture on a single part");
    cr_assert_eq(n, 8, "all parts but the one behind the camera: %u", n);
    cr_assert_eq(ctex_owner(c, (uint32_t)t.behind, UINT32_MAX, v3s(0.0f)), -1, "frustum culling");
    cr_assert_geq(ctex_owner(c, (uint32_t)t.floor, UINT32_MAX, v3s(0.0f)), 0);
    ctex_free(c);
    release(&t);
}

Test(ctex_engine, eps_huge_gives_one_per_top_node)
{
    tscene t;
    build(&t);
    ctex_options o = ctex_options_default();
    o.eps = 1e9f;
    o.max_proj = 0.0f;
    ctex *c = engine(&t, o);
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
    release(&t);
}

Test(ctex_engine, default_eps_between)
{
    tscene t;
    ctex *c = front_engine(&t, ctex_options_default(), 128, 128);
    int leaves;
    uint32_t covered;
    uint32_t n = count_textures(c, &leaves, &covered);
    cr_assert_eq(covered, 8, "each visible part covered exactly once (%u)", covered);
    cr_assert(n >= 1 && n <= 8);
    ctex_free(c);
    release(&t);
}

Test(ctex_engine, frustum_culling_looking_away)
{
    tscene t;
    build(&t);
    ctex *c = engine(&t, ctex_options_default());
    ct_camera cam = cam_look_at(v3(0, 1, 20), v3(0, 1, 40), v3(0, 1, 0), 40.0f);
    cr_assert_eq(ctex_set_camera(c, &cam, 64, 64, &err), 0);
    cr_assert_geq(ctex_owner(c, (uint32_t)t.behind, UINT32_MAX, v3s(0.0f)), 0, "the box in front now has a texture");
    cr_assert_eq(ctex_owner(c, (uint32_t)t.panel, UINT32_MAX, v3s(0.0f)), -1);
    cr_assert_eq(ctex_owner(c, (uint32_t)t.box[1], UINT32_MAX, v3s(0.0f)), -1);
    ctex_free(c);
    release(&t);
}

Test(ctex_engine, camera_local_maps_bounding_rect_to_unit_square)
{
    tscene t;
    const int W = 96, H = 64;
    ctex *c = leaf_engine(&t, W, H);
    ct_camera cam = front_cam();
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
    release(&t);
}

Test(ctex_engine, object_local_projection_along_normal)
{
    tscene t;
    ctex *c = leaf_engine(&t, 64, 64);
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
    release(&t);
}

static ct_sample mk_sample(uint32_t node, vec3 hit, vec3 hq, vec3 base)
{
    ct_sample s;
    memset(&s, 0, sizeof s);
    s.flags = CT_SAMPLE_HIT | CT_SAMPLE_HAS_BASE;
    s.node = node;
    s.hit = hit;
    s.l_hq = hq;
    s.l_base = base;
    return s;
}

Test(ctex_engine, insert_reads_correction_and_error)
{
    tscene t;
    ctex *c = leaf_engine(&t, 64, 64);
    ctex_insert_info info;
    ct_sample s = mk_sample((uint32_t)t.floor, v3(1, 0, 2), v3(0.8f, 0.6f, 0.4f), v3(0.5f, 0.5f, 0.5f));
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
    s = mk_sample((uint32_t)t.behind, v3(0, 1, 30), v3s(1), v3s(0));
    cr_assert_eq(ctex_insert(c, &s, &info), 0);
    cr_assert_eq(info.tex, -1);
    /* a dropped sample's error is its whole ΔL (the request queue uses it) */
    cr_assert_float_eq(info.error.x, 1.0f, 1e-7);
    cr_assert_float_eq(info.correction.x, 0.0f, 1e-7);
    s = mk_sample(9999, v3(0, 0, 0), v3s(1), v3s(0));
    cr_assert_eq(ctex_insert(c, &s, &info), 0);
    ctex_stats st = ctex_get_stats(c);
    cr_assert_eq(st.inserted, 2);
    cr_assert_eq(st.dropped, 3);
    ctex_free(c);
    release(&t);
}

/* Pixels between the images of p and p + d under the front camera. */
static double px_dist(vec3 p, vec3 d, int w, int h)
{
    ct_camera cam = front_cam();
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
    tscene t;
    const int W = 256, H = 256;
    ctex *c = leaf_engine(&t, W, H);
    ctex_insert_info info;
    ct_sample s = mk_sample((uint32_t)t.floor, v3(1, 0, 6), v3s(1.0f), v3s(0.0f));
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
    ct_sample sp = mk_sample((uint32_t)t.panel, v3(0, 1, -5), v3s(1.0f), v3s(0.0f));
    cr_assert_eq(ctex_insert(c, &sp, &info), 1);
    float e = ctex_splat_ex(c, (uint32_t)info.tex, v3(0, 1, -5));
    cr_assert_eq(ctex_aniso_ex(e), 1.0f, "a facing panel splats square rings (ex %g)", (double)e);
    ctex_free(c);
    release(&t);
}

/* Fills node's texture with samples on a grid over the plate/floor region. */
static void fill_floor(ctex *c, uint32_t node, float val, float y)
{
    ctex_insert_info info;
    for (int i = 0; i < 40; i++)
        for (int j = 0; j < 40; j++) {
            vec3 p = v3(-9.75f + 0.5f * (float)i, y, -9.75f + 0.5f * (float)j);
            ct_sample s = mk_sample(node, p, v3s(val), v3s(0.0f));
            ctex_insert(c, &s, &info);
        }
}

Test(ctex_engine, diffuse_object_local_does_not_age)
{
    tscene t;
    ctex *c = leaf_engine(&t, 64, 64);
    fill_floor(c, (uint32_t)t.floor, 0.25f, 0.0f);
    int32_t id = ctex_owner(c, (uint32_t)t.floor, UINT32_MAX, v3s(0.0f));
    ct_sample sp = mk_sample((uint32_t)t.panel, v3(0, 1, -5), v3s(1.0f), v3s(0.0f));
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
    release(&t);
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
    tscene t;
    ctex_options o = ctex_options_default();
    o.eps = 0.0f;
    o.mix = mix;
    ctex *c = front_engine(&t, o, 64, 64);
    ct_rng r = rng_make(42, 0, 0, 0);
    ctex_insert_info info;
    for (int i = 0; i < n; i++) {
        float u = rng_float(&r), v = rng_float(&r), e = 0.6f * (rng_float(&r) - 0.5f);
        ct_sample s = mk_sample((uint32_t)t.floor, v3(-4.0f + 8.0f * u, 0.0f, -4.0f + 8.0f * v), v3s(0.5f + e),
                                v3s(0.0f));
        cr_assert_eq(ctex_insert(c, &s, &info), 1);
        s = mk_sample((uint32_t)t.panel, v3(-2.5f + 5.0f * u, 0.7f + 2.1f * v, -5.0f), v3s(0.5f + e), v3s(0.0f));
        cr_assert_eq(ctex_insert(c, &s, &info), 1);
    }
    *floor_dev = rms_dev(c, (uint32_t)t.floor, v3(-3.5f, 0.0f, -3.5f), v3(7.0f, 0, 0), v3(0, 0, 7.0f), 0.5f);
    *panel_dev = rms_dev(c, (uint32_t)t.panel, v3(-2.2f, 0.9f, -5.0f), v3(4.4f, 0, 0), v3(0, 1.7f, 0), 0.5f);
    ctex_free(c);
    release(&t);
}

/* Mixing averages the noise of neighbouring samples out on a diffuse
 * surface (the default mix 0.5), and much less on a glossy one, whose
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
    tscene t;
    build(&t);
    ctex_options o = ctex_options_default();
    ctex *c = engine(&t, o);
    /* far away: the group g1 (box + plate) shares one texture */
    ct_camera far = cam_look_at(v3(0, 30, 60), v3(0, 0.5f, 0), v3(0, 1, 0), 20.0f);
    cr_assert_eq(ctex_set_camera(c, &far, 64, 64, &err), 0);
    int32_t a = ctex_owner(c, (uint32_t)t.box[1], UINT32_MAX, v3s(0.0f)), b = ctex_owner(c, (uint32_t)t.plate[1], UINT32_MAX, v3s(0.0f));
    cr_assert_geq(a, 0);
    cr_assert_eq(a, b, "box and plate share a texture from far away");
    ctex_insert_info info;
    for (int i = 0; i < 200; i++) {
        float x = -0.6f + 1.2f * (float)(i % 20) / 19.0f, z = -0.6f + 1.2f * (float)(i / 20) / 9.0f;
        ct_sample s = mk_sample((uint32_t)t.plate[1], v3(x, 1.01f, z), v3s(0.75f), v3s(0.25f));
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
    release(&t);
}

Test(ctex_engine, events_alloc_proj_free_and_unsent_tiles)
{
    tscene t;
    ctex *c = leaf_engine(&t, 64, 64);
    ct_camera cam = front_cam();
    size_t n;
    const ctex_event *ev = ctex_events(c, &n);
    int alloc = 0, proj = 0;
    for (size_t i = 0; i < n; i++) {
        alloc += ev[i].kind == CTEX_EV_ALLOC;
        proj += ev[i].kind == CTEX_EV_PROJ;
        if (ev[i].kind == CTEX_EV_ALLOC) cr_assert(ev[i].w >= 4 && ev[i].h >= 4);
    }
    cr_assert_eq(alloc, 8);
    cr_assert_eq(proj, 8);
    ctex_events_clear(c);
    /* new textures are unsent as a whole; the display server sends them */
    for (uint32_t id = 0; id < ctex_slot_count(c); id++) {
        struct ctex_tex *vt = ctex_visible_texture(c, id);
        if (!vt) continue;
        int x0, y0, x1, y1;
        cr_assert(ctex_dirty_bounds(&vt->d, vt->w, vt->h, &x0, &y0, &x1, &y1));
        cr_assert(x0 == 0 && y0 == 0 && x1 == vt->w && y1 == vt->h, "texture %u wholly unsent", id);
        ctex_dirty_clear_all(&vt->d);
    }
    ctex_set_clock(c, 4242);
    ctex_insert_info info;
    ct_sample s = mk_sample((uint32_t)t.floor, v3(1, 0, 2), v3s(1.0f), v3s(0.5f));
    ctex_insert(c, &s, &info);
    ctex_insert(c, &s, &info);
    ctex_events(c, &n);
    cr_assert_eq(n, 0, "texels are not events");
    for (uint32_t id = 0; id < ctex_slot_count(c); id++) {
        struct ctex_tex *vt = ctex_visible_texture(c, id);
        if (!vt) continue;
        int x0, y0, x1, y1;
        bool any = ctex_dirty_bounds(&vt->d, vt->w, vt->h, &x0, &y0, &x1, &y1);
        cr_assert_eq(any, id == (uint32_t)info.tex, "only the sample's texture has unsent texels (%u)", id);
        if (!any) continue;
        /* the unsent tiles hold the splat, stamped with the clock, counting both samples */
        float u, v;
        cr_assert(ctex_tex_project(vt, s.hit, &u, &v));
        int ci = (int)(u * (float)vt->w), cj = (int)(v * (float)vt->h);
        cr_assert(ci >= x0 && ci < x1 && cj >= y0 && cj < y1);
        cr_assert_eq(vt->d.row_t[cj >> CTEX_TILE_SHIFT], 4242u);
        cr_assert_eq(vt->d.row_n[cj >> CTEX_TILE_SHIFT], 2u);
        float buf[3 * 64 * 64];
        cr_assert_eq(ctex_read_patch(c, id, x0, y0, x1 - x0, y1 - y0, buf, &err), 0);
        cr_assert_lt(ctex_read_patch(c, id, 0, 0, 9999, 1, buf, &err), 0);
    }
    cr_assert_eq(ctex_visible_texture(c, 9999), NULL);
    /* looking away frees (parks) the floor's texture for the display */
    ct_camera away = cam_look_at(v3(0, 1, 20), v3(0, 1, 40), v3(0, 1, 0), 30.0f);
    cr_assert_eq(ctex_set_camera(c, &away, 64, 64, &err), 0);
    ev = ctex_events(c, &n);
    int freed = 0;
    for (size_t i = 0; i < n; i++) freed += ev[i].kind == CTEX_EV_FREE && ev[i].tex == (uint32_t)info.tex;
    cr_assert_eq(freed, 1);
    cr_assert_eq(ctex_get_stats(c).parked, 8, "parked %u", ctex_get_stats(c).parked);
    /* coming back reuses the parked texture with its contents */
    ctex_events_clear(c);
    cr_assert_eq(ctex_set_camera(c, &cam, 64, 64, &err), 0);
    cr_assert_eq(ctex_owner(c, (uint32_t)t.floor, UINT32_MAX, v3s(0.0f)), info.tex);
    cr_assert_float_eq(ctex_lookup(c, (uint32_t)t.floor, UINT32_MAX, v3(1, 0, 2)).x, 0.5f, 1e-6);
    ctex_free(c);
    release(&t);
}

Test(ctex_engine, memory_cap_evicts_invisible_first)
{
    tscene t;
    ctex_options o = ctex_options_default();
    o.eps = 0.0f;
    o.mem_mb = 0.05;   /* ~3,300 texels */
    o.tex_init = 8;
    ctex *c = front_engine(&t, o, 256, 256);
    int32_t fl = ctex_owner(c, (uint32_t)t.floor, UINT32_MAX, v3s(0.0f));
    ct_camera away = cam_look_at(v3(0, 1, 20), v3(0, 1, 40), v3(0, 1, 0), 30.0f);
    cr_assert_eq(ctex_set_camera(c, &away, 256, 256, &err), 0);
    cr_assert_gt(ctex_get_stats(c).parked, 0);
    /* the visible box grows by dense samples until the cap bites */
    int32_t id = ctex_owner(c, (uint32_t)t.behind, UINT32_MAX, v3s(0.0f));
    cr_assert_geq(id, 0);
    ctex_insert_info info;
    for (int k = 0; k < 20000; k++) {
        float x = -1.0f + 2.0f * (float)(k % 141) / 140.0f, y = 2.0f * (float)((k / 141) % 141) / 140.0f;
        ct_sample s = mk_sample((uint32_t)t.behind, v3(x, y, 30), v3s((float)(k % 7)), v3s(0.0f));
        ctex_insert(c, &s, &info);
    }
    ctex_stats st = ctex_get_stats(c);
    cr_assert_leq(st.bytes, (size_t)(0.05 * 1048576.0), "bytes %zu over the cap", st.bytes);
    cr_assert_gt(st.evictions, 0, "parked textures were evicted");
    uint32_t hn;
    cr_assert_eq(ctex_texture_info(c, (uint32_t)id, &hn, NULL, NULL, NULL, NULL, NULL), 1, "visible texture kept");
    (void)fl;
    ctex_free(c);
    release(&t);
}

Test(ctex_engine, compositor_adds_bilinear_correction)
{
    tscene t;
    ctex *c = leaf_engine(&t, 8, 8);
    fill_floor(c, (uint32_t)t.floor, 0.25f, 0.0f);
    ctex_hit hits[64];
    for (int i = 0; i < 64; i++) {
        hits[i].node = i % 2 ? UINT32_MAX : (uint32_t)t.floor;
        hits[i].tri = UINT32_MAX;
        hits[i].p = v3(0.1f * (float)i - 3.0f, 0.0f, 1.0f);
        hits[i].l_base = v3s(0.1f);
    }
    /* (built by hand: the compositor only needs the pixel array) */
    ct_image img = {8, 8, calloc(8 * 8 * 3, sizeof(float))};
    cr_assert_eq(ctex_composite(c, hits, 8, 8, &img, &err), 0);
    for (int i = 0; i < 64; i++) {
        vec3 v = img_get(&img, i % 8, i / 8);
        float expect = i % 2 ? 0.1f : 0.35f;
        cr_assert_float_eq(v.x, expect, 1e-5, "pixel %d: %g", i, (double)v.x);
    }
    ct_image bad = {4, 4, calloc(4 * 4 * 3, sizeof(float))};
    cr_assert_lt(ctex_composite(c, hits, 8, 8, &bad, &err), 0);
    free(bad.px);
    free(img.px);
    ctex_free(c);
    release(&t);
}

Test(ctex_engine, options_parse_and_reject)
{
    ctex_options o = ctex_options_default();
    cr_assert_float_eq(o.eps, 0.3f, 1e-7);
    cr_assert_eq(ctex_options_parse(&o, "--eps", "0.5", &err), 1);
    cr_assert_float_eq(o.eps, 0.5f, 1e-7);
    cr_assert_eq(ctex_options_parse(&o, "--tex-min", "8", &err), 1);
    cr_assert_eq(o.tex_min, 8);
    cr_assert_eq(ctex_options_parse(&o, "--width", "8", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--eps", "abc", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--tex-min", "2.5", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--flat-deg", "-1", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--eps", NULL, &err), 0);
    /* mix 0 would freeze every texel at its first sample */
    cr_assert_lt(ctex_options_parse(&o, "--mix", "0", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--mix", "1.5", &err), 0);
    cr_assert_eq(ctex_options_parse(&o, "--mix", "1", &err), 1);
    cr_assert_float_eq(o.mix, 1.0f, 1e-7);
    /* --splat-aniso is a switch */
    cr_assert_eq(o.splat_aniso, 1);
    cr_assert_lt(ctex_options_parse(&o, "--splat-aniso", "2", &err), 0);
    cr_assert(strstr(err.msg, "--splat-aniso") != NULL, "the error names the option: %s", err.msg);
    cr_assert_lt(ctex_options_parse(&o, "--splat-aniso", "0.5", &err), 0);
    cr_assert_eq(ctex_options_parse(&o, "--splat-aniso", "0", &err), 1);
    cr_assert_eq(o.splat_aniso, 0);
}

Test(ctex_engine, bad_mesh_is_rejected)
{
    tscene t;
    build(&t);
    t.m.tri_node[0] = 12345;
    ctex *c = NULL;
    cr_assert_eq(ctex_new(&t.m, t.s->mats, t.s->nmats, NULL, &c, &err), CT_EPARSE);
    cr_assert_null(c);
    release(&t);
}

Test(ctex_engine, exported_node_table_for_the_display)
{
    tscene t;
    build(&t);
    ctex *c = engine(&t, ctex_options_default());
    uint32_t n = ctex_get_stats(c).hier_nodes;
    rmesh_node *nodes = calloc(n, sizeof *nodes);
    ctex_export_nodes(c, nodes);
    cr_assert_eq(nodes[0].parent, -1);
    cr_assert_eq(nodes[0].node_end, n);
    for (uint32_t i = 1; i < n; i++) {
        cr_assert(nodes[i].parent >= 0 && (uint32_t)nodes[i].parent < i, "pre-order parent of %u", i);
        cr_assert(nodes[i].node_end > i && nodes[i].node_end <= nodes[nodes[i].parent].node_end);
    }
    /* every part maps to a leaf whose exported name is the part's, and a
     * node's subtree holds exactly the parts ctex_node_parts lists */
    for (uint32_t p = 0; p < t.s->nnodes; p++) {
        uint32_t h = ctex_hnode_of_part(c, p);
        if (t.s->nodes[p].kind != SCENE_NODE_PART) {
            cr_assert_eq(h, UINT32_MAX);
            continue;
        }
        cr_assert_lt(h, n);
        cr_assert_eq(nodes[h].node_end, h + 1, "leaf");
        cr_assert_str_eq(nodes[h].name, t.s->nodes[p].name);
    }
    for (uint32_t h = 0; h < n; h++) {
        uint32_t np;
        const uint32_t *parts = ctex_node_parts(c, h, &np);
        uint32_t inside = 0;
        for (uint32_t p = 0; p < t.s->nnodes; p++) {
            uint32_t l = ctex_hnode_of_part(c, p);
            if (l != UINT32_MAX && l >= h && l < nodes[h].node_end) inside++;
        }
        cr_assert_eq(inside, np, "node %u", h);
        for (uint32_t k = 0; k < np; k++) {
            uint32_t l = ctex_hnode_of_part(c, parts[k]);
            cr_assert(l >= h && l < nodes[h].node_end);
        }
    }
    cr_assert_eq(ctex_hnode_of_part(c, 99999), UINT32_MAX);
    free(nodes);
    ctex_free(c);
    release(&t);
}

/* One part: a floor of n x n quads and a back wall of n x n quads meeting
 * at a corner (an L), one material. */
static ct_scene *l_scene(int n)
{
    ct_scene *s = one_part_begin("L", "L");
    for (int side = 0; side < 2; side++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                float x0 = -5.0f + 10.0f * (float)i / (float)n, x1 = -5.0f + 10.0f * (float)(i + 1) / (float)n;
                float a0 = 10.0f * (float)j / (float)n, a1 = 10.0f * (float)(j + 1) / (float)n;
                vec3 p[4];
                if (side == 0) { p[0] = v3(x0, 0, a0 - 10); p[1] = v3(x0, 0, a1 - 10); p[2] = v3(x1, 0, a1 - 10); p[3] = v3(x1, 0, a0 - 10); }
                else { p[0] = v3(x0, a0, -10); p[1] = v3(x1, a0, -10); p[2] = v3(x1, a1, -10); p[3] = v3(x0, a1, -10); }
                add_quad(s, p, side == 0 ? v3(0, 1, 0) : v3(0, 0, 1));
            }
    one_part_end(s);
    return s;
}

/* The engine over l_scene's mesh with clusters of at most 512 triangles and
 * a texture per visible leaf (ε = 0), the camera looking at the corner. */
static ctex *l_engine(const ct_scene *s, const ct_radmesh *m)
{
    ctex_options o = ctex_options_default();
    o.cluster_tris = 512;
    o.eps = 0.0f;
    ctex *c = NULL;
    cr_assert_eq(ctex_new(m, s->mats, s->nmats, &o, &c, &err), 0);
    ct_camera cam = cam_look_at(v3(0, 6, 12), v3(0, 2, -5), v3(0, 1, 0), 70.0f);
    cr_assert_eq(ctex_set_camera(c, &cam, 64, 64, &err), 0);
    return c;
}

Test(ctex_engine, large_parts_split_into_flat_clusters)
{
    ct_scene *s = l_scene(32);   /* 2 x 2048 triangles */
    ct_radmesh m;
    cr_assert_eq(rmesh_from_scene(s, v3s(0.5f), &m, &err), 0);
    ctex_hier h;
    cr_assert_eq(ctex_hier_build(&m, s->mats, s->nmats, 10.0f, 0.01f, 1.0f, 512, &h, &err), 0, "%s", err.msg);
    cr_assert_eq(h.nleaves, 2, "4096 triangles: split by normal into floor and wall, flat halves stay whole");
    uint32_t part = 1;
    cr_assert_eq(h.part_leaf[part], -2);
    for (uint32_t l = 0; l < h.nleaves; l++) {
        const ctex_hnode *n = &h.nodes[h.leaf_node[l]];
        cr_assert_eq(n->tri_end - n->tri_begin, 2048u);
        cr_assert(n->flat, "cluster %u is flat (the normal split separated floor and wall)", l);
        cr_assert_eq(h.leaf_part[l], part);
        for (uint32_t i = n->tri_begin; i < n->tri_end; i++) cr_assert_eq(h.tri_leaf[h.tris[i]], l);
    }
    /* the part's node has both, the first split is by normal: each half flat */
    const ctex_hnode *pn = &h.nodes[h.part_hnode[part]];
    cr_assert(!pn->flat);
    for (uint32_t c = h.part_hnode[part] + 1; c < pn->end; c = h.nodes[c].end) cr_assert(h.nodes[c].flat);
    ctex_hier_free(&h);

    /* through the engine: a sample goes into its triangle's cluster, the
     * lookup without a triangle finds the same texture by position */
    ctex *c = l_engine(s, &m);
    cr_assert_eq(ctex_get_stats(c).textures, 2, "one texture per visible cluster (ε = 0)");
    uint32_t tri = 100;   /* a floor triangle */
    const uint32_t *v = m.tris + 3 * tri;
    vec3 p = v3_scale(v3_add(m.pos[v[0]], v3_add(m.pos[v[1]], m.pos[v[2]])), 1.0f / 3.0f);
    ct_sample smp;
    memset(&smp, 0, sizeof smp);
    smp.flags = CT_SAMPLE_HIT;
    smp.node = part;
    smp.tri = tri;
    smp.hit = p;
    smp.l_hq = v3s(1.0f);
    ctex_insert_info info;
    cr_assert_eq(ctex_insert(c, &smp, &info), 1);
    cr_assert_eq(info.tex, ctex_owner(c, part, tri, p));
    cr_assert_eq(ctex_owner(c, part, UINT32_MAX, p), info.tex, "bounds fallback");
    cr_assert_float_eq(ctex_lookup(c, part, tri, p).x, 1.0f, 1e-6);
    uint32_t hl = ctex_hnode_of_tri(c, tri);
    uint32_t hn;
    cr_assert_eq(ctex_texture_info(c, (uint32_t)info.tex, &hn, NULL, NULL, NULL, NULL, NULL), 1);
    cr_assert_eq(hn, hl);
    rmesh_node *nodes = calloc(ctex_get_stats(c).hier_nodes, sizeof *nodes);
    ctex_export_nodes(c, nodes);
    cr_assert_str_eq(nodes[ctex_hnode_of_part(c, part)].name, "L");
    cr_assert(strncmp(nodes[hl].name, "cluster:", 8) == 0, "%s", nodes[hl].name);
    free(nodes);
    ctex_free(c);
    rmesh_free(&m);
    scene_free(s);
}

/* What the display draws a texture on (ctex_display_mesh): the node table is
 * the hierarchy and each triangle's node its leaf, so the subtree of a
 * texture's node holds exactly the triangles whose samples go into that
 * texture. A part split into clusters has one texture per cluster; drawn on
 * the whole part (the part's node table), a flat cluster's parallel
 * projection smeared its texels across the part's other faces as stripes. */
Test(ctex_engine, display_mesh_draws_each_texture_on_its_own_triangles)
{
    ct_scene *s = l_scene(32);   /* one part, floor + wall: two flat clusters */
    ct_radmesh m;
    cr_assert_eq(rmesh_from_scene(s, v3s(0.5f), &m, &err), 0);
    ctex *c = l_engine(s, &m);
    cr_assert_eq(ctex_get_stats(c).textures, 2);
    ct_radmesh d;
    cr_assert_eq(ctex_display_mesh(c, &m, &d, &err), 0, "%s", err.msg);
    cr_assert_eq(d.nnodes, ctex_get_stats(c).hier_nodes);
    cr_assert_eq(d.ntris, m.ntris);
    cr_assert(d.pos == m.pos && d.tris == m.tris && d.tri_mat == m.tri_mat, "geometry shared, not copied");
    for (uint32_t i = 1; i < d.nnodes; i++)
        cr_assert(d.nodes[i].parent >= 0 && (uint32_t)d.nodes[i].parent < i && d.nodes[i].node_end > i);
    uint32_t part = m.tri_node[0];
    int seen = 0;
    for (uint32_t tex = 0; tex < 16; tex++) {
        uint32_t hn;
        if (ctex_texture_info(c, tex, &hn, NULL, NULL, NULL, NULL, NULL) != 1) continue;
        seen++;
        uint32_t end = d.nodes[hn].node_end, drawn = 0;
        for (uint32_t t = 0; t < m.ntris; t++) {
            const uint32_t *v = m.tris + 3 * (size_t)t;
            vec3 p = v3_scale(v3_add(m.pos[v[0]], v3_add(m.pos[v[1]], m.pos[v[2]])), 1.0f / 3.0f);
            bool in_subtree = d.tri_node[t] >= hn && d.tri_node[t] < end;
            bool owned = ctex_owner(c, part, t, p) == (int32_t)tex;
            cr_assert_eq(in_subtree, owned, "texture %u, triangle %u: drawn %d, its samples go there %d", tex, t,
                         in_subtree, owned);
            drawn += in_subtree;
        }
        cr_assert_eq(drawn, 2048u, "texture %u is drawn on its cluster only", tex);
    }
    cr_assert_eq(seen, 2);
    ctex_display_mesh_free(&d);
    cr_assert_null(d.nodes);
    /* a mesh that is not the engine's */
    ct_radmesh other = m;
    other.ntris = m.ntris - 1;
    cr_assert_eq(ctex_display_mesh(c, &other, &d, &err), CT_EINVAL);
    ctex_free(c);
    rmesh_free(&m);
    scene_free(s);
}

/* Fills the box part's camera-local texture with samples whose value is
 * their x coordinate, on the faces seen from the front. */
static void fill_box(ctex *c, uint32_t node, float x0)
{
    ctex_insert_info info;
    for (int i = 0; i <= 40; i++)
        for (int j = 0; j <= 40; j++) {
            vec3 p = v3(x0 - 0.5f + (float)i / 40.0f, (float)j / 40.0f, 0.5f);   /* front face z = 0.5 */
            ct_sample s = mk_sample(node, p, v3s(p.x - x0 + 0.5f), v3s(0.0f));
            ctex_insert(c, &s, &info);
        }
}

Test(ctex_engine, camera_local_rotation_keeps_contents_and_does_not_age)
{
    tscene t;
    build(&t);
    ctex_options o = ctex_options_default();
    o.eps = 0.0f;
    ctex *c = engine(&t, o);
    ct_camera cam = cam_look_at(v3(0, 1.5f, 6), v3(0, 0.5f, 0), v3(0, 1, 0), 40.0f);
    cr_assert_eq(ctex_set_camera(c, &cam, 128, 128, &err), 0);
    uint32_t box = (uint32_t)t.box[1];
    int32_t id = ctex_owner(c, box, UINT32_MAX, v3(0, 0.5f, 0.5f));
    ctex_proj_kind kind;
    float v0;
    cr_assert_eq(ctex_texture_info(c, (uint32_t)id, NULL, NULL, NULL, &kind, NULL, &v0), 1);
    cr_assert_eq(kind, CTEX_PROJ_CAMERA);
    fill_box(c, box, 0.0f);
    vec3 pts[3] = {v3(-0.3f, 0.5f, 0.5f), v3(0.0f, 0.2f, 0.5f), v3(0.3f, 0.8f, 0.5f)};
    float before[3];
    for (int k = 0; k < 3; k++) before[k] = ctex_lookup(c, box, UINT32_MAX, pts[k]).x;
    /* turn the camera a little about its eye: the box moves on screen, the
     * reprojected texture stays on it */
    ct_camera turned = cam_look_at(cam.eye, v3(0.4f, 0.7f, 0), v3(0, 1, 0), 40.0f);
    cr_assert_eq(ctex_set_camera(c, &turned, 128, 128, &err), 0);
    cr_assert_eq(ctex_owner(c, box, UINT32_MAX, pts[0]), id);
    float v1;
    ctex_texture_info(c, (uint32_t)id, NULL, NULL, NULL, NULL, NULL, &v1);
    cr_assert_float_eq(v1, v0, 1e-6, "a rotation about the eye does not age (%g -> %g)", (double)v0, (double)v1);
    for (int k = 0; k < 3; k++) {
        float after = ctex_lookup(c, box, UINT32_MAX, pts[k]).x;
        cr_assert_float_eq(after, before[k], 0.06, "point %d: %g -> %g", k, (double)before[k], (double)after);
    }
    /* a translation ages a camera-local texture (texture flow, §3.5) */
    ct_camera moved = cam_look_at(v3(1.0f, 1.5f, 6), v3(0.4f, 0.7f, 0), v3(0, 1, 0), 40.0f);
    cr_assert_eq(ctex_set_camera(c, &moved, 128, 128, &err), 0);
    float v2;
    ctex_texture_info(c, (uint32_t)id, NULL, NULL, NULL, NULL, NULL, &v2);
    cr_assert_gt(v2, v1 + 0.01f, "moving the eye ages the camera-local texture (%g -> %g)", (double)v1, (double)v2);
    ctex_free(c);
    release(&t);
}

Test(ctex_engine, non_flat_large_parts_split_by_space)
{
    /* a corrugated sheet: strips tilted +-20 degrees, one part of 4096
     * triangles; the normal split gives two sets of parallel, not coplanar
     * strips, which split by space down to clusters of at most 512 */
    ct_scene *s = one_part_begin("corrugated", "sheet");
    const int nx = 64, nz = 32;
    for (int i = 0; i < nx; i++)
        for (int j = 0; j < nz; j++) {
            float x0 = (float)i * 0.2f, x1 = x0 + 0.2f, z0 = (float)j * 0.2f, z1 = z0 + 0.2f;
            float y0 = (i % 2) ? 0.0728f : 0.0f, y1 = (i % 2) ? 0.0f : 0.0728f;   /* tan(20°) * 0.2 */
            vec3 p[4] = {v3(x0, y0, z0), v3(x0, y0, z1), v3(x1, y1, z1), v3(x1, y1, z0)};
            add_quad(s, p, v3(0, 1, 0));
        }
    one_part_end(s);
    ct_radmesh m;
    cr_assert_eq(rmesh_from_scene(s, v3s(0.5f), &m, &err), 0);
    ctex_hier h;
    cr_assert_eq(ctex_hier_build(&m, s->mats, s->nmats, 10.0f, 0.01f, 1.0f, 512, &h, &err), 0, "%s", err.msg);
    cr_assert_geq(h.nleaves, 8u);
    uint32_t total = 0;
    for (uint32_t l = 0; l < h.nleaves; l++) {
        const ctex_hnode *n = &h.nodes[h.leaf_node[l]];
        cr_assert_leq(n->tri_end - n->tri_begin, 512u);
        total += n->tri_end - n->tri_begin;
        /* each cluster holds strips of one tilt only */
        cr_assert_lt(n->spread_deg, 1.0f, "cluster %u mixes tilts (spread %g)", l, (double)n->spread_deg);
    }
    cr_assert_eq(total, 4096u);
    ctex_hier_free(&h);
    rmesh_free(&m);
    scene_free(s);
}

/* One part shaped like a room: four walls of n x n quads facing inwards
 * (+x, -x, +z, -z), their vertices off their planes by up to 1e-4 (as a
 * radiosity mesh's subdivision leaves them, so the perpendicular normal
 * components are tiny and of either sign), and a door reveal: two small
 * quads facing +z 0.2 in front of the -z wall. */
static ct_scene *room_scene(int n)
{
    ct_scene *s = one_part_begin("room", "walls");
    for (int w = 0; w < 4; w++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                vec3 p[4];
                for (int c = 0; c < 4; c++) {
                    int ii = i + (c == 1 || c == 2), jj = j + (c >= 2);
                    float a = -5.0f + 10.0f * (float)ii / (float)n, y = 3.0f * (float)jj / (float)n;
                    float off = 1e-4f * (float)(((ii * 7 + jj * 13 + w) % 5) - 2) / 2.0f;
                    /* corners ordered so that each wall faces the room's inside */
                    switch (w) {
                    case 0: p[c] = v3(-5.0f + off, y, -a); break;   /* faces +x */
                    case 1: p[c] = v3(5.0f + off, y, a); break;     /* faces -x */
                    case 2: p[c] = v3(a, y, -5.0f + off); break;    /* faces +z */
                    default: p[c] = v3(-a, y, 5.0f + off); break;   /* faces -z */
                    }
                }
                vec3 nn = v3_norm(v3_cross(v3_sub(p[1], p[0]), v3_sub(p[2], p[0])));
                add_quad(s, p, nn);
            }
    for (int r = 0; r < 2; r++) {
        float x0 = (float)r * 2.0f, x1 = x0 + 0.5f;
        vec3 p[4] = {v3(x0, 0.0f, -4.8f), v3(x1, 0.0f, -4.8f), v3(x1, 2.0f, -4.8f), v3(x0, 2.0f, -4.8f)};
        add_quad(s, p, v3(0, 0, 1));
    }
    one_part_end(s);
    return s;
}

Test(ctex_engine, clusters_keep_each_face_whole)
{
    const int n = 16;   /* 512 triangles a wall */
    ct_scene *s = room_scene(n);
    ct_radmesh m;
    cr_assert_eq(rmesh_from_scene(s, v3s(0.5f), &m, &err), 0);
    ctex_hier h;
    cr_assert_eq(ctex_hier_build(&m, s->mats, s->nmats, 10.0f, 0.01f, 1.0f, 256, &h, &err), 0, "%s", err.msg);
    /* each leaf: one face (normal and plane), flat, never split whatever
     * the cluster size: the four walls and the two reveal quads in their
     * own plane */
    cr_assert_eq(h.nleaves, 5u, "four walls and the reveals: %u leaves", h.nleaves);
    uint32_t total = 0;
    for (uint32_t l = 0; l < h.nleaves; l++) {
        const ctex_hnode *nd = &h.nodes[h.leaf_node[l]];
        uint32_t cnt = nd->tri_end - nd->tri_begin;
        total += cnt;
        cr_assert(nd->flat, "cluster %u (%u triangles) is flat", l, cnt);
        cr_assert(cnt == 2u * n * n || cnt == 4u, "cluster %u has %u triangles: a whole wall or the reveals", l, cnt);
        vec3 n0 = v3s(0.0f);
        for (uint32_t i = nd->tri_begin; i < nd->tri_end; i++) {
            const uint32_t *v = m.tris + 3 * h.tris[i];
            vec3 nn = v3_norm(v3_cross(v3_sub(m.pos[v[1]], m.pos[v[0]]), v3_sub(m.pos[v[2]], m.pos[v[0]])));
            if (i == nd->tri_begin) n0 = nn;
            cr_assert_gt(v3_dot(nn, n0), 0.99f, "cluster %u mixes faces", l);
        }
    }
    cr_assert_eq(total, 4u * 2u * n * n + 4u);
    ctex_hier_free(&h);
    rmesh_free(&m);
    scene_free(s);
}

/* Every texel, size and projection of two engines' live textures agree. */
static void same_textures(ctex *a, ctex *b, const char *what)
{
    ctex_stats sa = ctex_get_stats(a), sb = ctex_get_stats(b);
    cr_assert_eq(sa.texels, sb.texels, "%s: texel counts differ", what);
    cr_assert_eq(sa.resizes, sb.resizes, "%s: resize counts differ", what);
    cr_assert_eq(sa.inserted, sb.inserted, "%s", what);
    cr_assert_eq(sa.dropped, sb.dropped, "%s", what);
    for (uint32_t tex = 0; tex < 64; tex++) {
        int wa, ha, wb, hb;
        int live = ctex_texture_info(a, tex, NULL, &wa, &ha, NULL, NULL, NULL);
        cr_assert_eq(ctex_texture_info(b, tex, NULL, &wb, &hb, NULL, NULL, NULL), live);
        if (live < 0) continue;
        cr_assert(wa == wb && ha == hb, "%s: texture %u is %dx%d and %dx%d", what, tex, wa, ha, wb, hb);
        float *pa = malloc((size_t)wa * (size_t)ha * 3 * sizeof *pa), *pb = malloc((size_t)wa * (size_t)ha * 3 * sizeof *pb);
        cr_assert_eq(ctex_read_patch(a, tex, 0, 0, wa, ha, pa, &err), 0);
        cr_assert_eq(ctex_read_patch(b, tex, 0, 0, wb, hb, pb, &err), 0);
        cr_assert_eq(memcmp(pa, pb, (size_t)wa * (size_t)ha * 3 * sizeof *pa), 0, "%s: texture %u differs", what, tex);
        free(pa);
        free(pb);
    }
}

/* Samples on the floor and, every fifth, on a plate: several textures. */
static ct_sample *scattered_samples(const tscene *t, int n)
{
    ct_sample *s = malloc((size_t)n * sizeof *s);
    ct_rng r = rng_make(77, 0, 0, 0);
    for (int i = 0; i < n; i++) {
        vec3 p = v3(-8.0f + 16.0f * rng_float(&r), 0.0f, -8.0f + 16.0f * rng_float(&r));
        uint32_t node = (uint32_t)t->floor;
        if (i % 5 == 0) {
            int g = (int)rng_below(&r, 3);
            p = v3(-4.0f + 4.0f * (float)g - 0.5f + rng_float(&r), 1.01f, -0.5f + rng_float(&r));
            node = (uint32_t)t->plate[g];
        }
        s[i] = mk_sample(node, p, v3(rng_float(&r), rng_float(&r), rng_float(&r)), v3s(0.3f));
    }
    return s;
}

/* ctex_insert_par one sample a call inserts exactly like ctex_insert: the
 * same infos and texels, through enough samples to make textures grow. */
Test(ctex_engine, parallel_insert_of_one_equals_single_inserts)
{
    tscene t;
    build(&t);
    ctex_options o = ctex_options_default();
    o.splat_window = 16;
    ctex *a = engine(&t, o), *b = engine(&t, o);
    ct_camera cam = front_cam();
    cr_assert_eq(ctex_set_camera(a, &cam, 96, 96, &err), 0);
    cr_assert_eq(ctex_set_camera(b, &cam, 96, 96, &err), 0);
    enum { N = 4096 };
    ct_sample *s = scattered_samples(&t, N);
    ctex_insert_info *ia = malloc(N * sizeof *ia), *ib = malloc(N * sizeof *ib);
    for (int i = 0; i < N; i++) ctex_insert_par(a, NULL, s + i, 1, ia + i);
    for (int i = 0; i < N; i++) ctex_insert(b, &s[i], &ib[i]);
    for (int i = 0; i < N; i++)
        cr_assert_eq(memcmp(&ia[i], &ib[i], sizeof ia[i]), 0, "sample %d: infos differ", i);
    cr_assert_gt(ctex_get_stats(a).resizes, 0, "the textures should have grown");
    same_textures(a, b, "one sample a call");
    free(s); free(ia); free(ib);
    ctex_free(a);
    ctex_free(b);
    release(&t);
}

/* Batches inserted on 1, 2 and 3 threads (textures partitioned over them)
 * give the same infos, texels, resizes and events. */
Test(ctex_engine, parallel_insert_independent_of_threads)
{
    tscene t;
    build(&t);
    ctex_options o = ctex_options_default();
    o.splat_window = 16;
    enum { N = 6000, B = 300 };
    ct_sample *s = scattered_samples(&t, N);
    ctex *ref = NULL;
    ctex_insert_info *iref = malloc(N * sizeof *iref), *ii = malloc(N * sizeof *ii);
    ct_camera cam = front_cam();
    for (int threads = 1; threads <= 3; threads++) {
        ct_pool *pool = NULL;
        cr_assert_eq(pool_new(threads, &pool, &err), 0, "%s", err.msg);
        ctex *c = engine(&t, o);
        cr_assert_eq(ctex_set_camera(c, &cam, 96, 96, &err), 0);
        size_t nev_total = 0;
        for (int i = 0; i < N; i += B) {
            ctex_stats before = ctex_get_stats(c);
            ctex_insert_par(c, pool, s + i, B, (threads == 1 ? iref : ii) + i);
            ctex_stats after = ctex_get_stats(c);
            cr_assert_leq(after.resizes - before.resizes, before.textures,
                          "a texture changed its resolution twice in one call");
            size_t nev;
            ctex_events(c, &nev);
            nev_total += nev;
            ctex_events_clear(c);
        }
        pool_free(pool);
        cr_assert_gt(ctex_get_stats(c).resizes, 0, "the textures should have grown");
        cr_assert_gt(nev_total, 0);
        if (threads == 1) {
            ref = c;
            continue;
        }
        for (int i = 0; i < N; i++) cr_assert_eq(memcmp(&ii[i], &iref[i], sizeof ii[i]), 0, "%d threads: sample %d", threads, i);
        same_textures(ref, c, "1 thread against more");
        ctex_free(c);
    }
    /* Without resolution changes a batch is exactly the samples one by one,
     * in order, whatever the split over threads. */
    o.splat_window = 1000000;
    ctex *one = engine(&t, o), *par = engine(&t, o);
    cr_assert_eq(ctex_set_camera(one, &cam, 96, 96, &err), 0);
    cr_assert_eq(ctex_set_camera(par, &cam, 96, 96, &err), 0);
    ct_pool *pool = NULL;
    cr_assert_eq(pool_new(2, &pool, &err), 0, "%s", err.msg);
    for (int i = 0; i < N; i += B) ctex_insert_par(par, pool, s + i, B, ii + i);
    for (int i = 0; i < N; i++) ctex_insert(one, &s[i], &iref[i]);
    for (int i = 0; i < N; i++) cr_assert_eq(memcmp(&ii[i], &iref[i], sizeof ii[i]), 0, "in order: sample %d", i);
    same_textures(one, par, "one by one against 2 threads");
    pool_free(pool);
    ctex_free(one);
    ctex_free(par);
    free(s); free(iref); free(ii);
    ctex_free(ref);
    release(&t);
}
