/* Plane mirrors as virtual lights (tracer/mirror_lights.h): which mirror
 * triangles make a mirror (one plane of one part and material), that a
 * curved mirror makes none, the bounds and the lamp choice of each side. */
#include <criterion/criterion.h>
#include <math.h>

#include "tests/support/testscenes.h"
#include "tracer/embree_scene.h"
#include "tracer/lights.h"
#include "tracer/mirror_lights.h"

#define CHECK(x) do { int rc_ = (x); cr_assert_eq(rc_, 0, "%s: %s", #x, err.msg); } while (0)

static int mirror_material(ct_scene *s, ct_error *err)
{
    scene_material mm = scene_material_default("mirror");
    mm.diffuse = v3s(0.0f);
    mm.mirror = v3(0.9f, 0.8f, 0.7f);
    return scene_add_material(s, &mm, err);
}

typedef struct built {
    ct_scene *s;
    emb_scene *e;
    light_set *l;
    mlight_set *m;
} built;

static void build(built *b)
{
    ct_error err;
    CHECK(scene_finalize(b->s, &err));
    emb_mesh mesh = emb_mesh_of_scene(b->s);
    CHECK(emb_new(&mesh, NULL, &b->e, &err));
    CHECK(light_build(b->e, &b->l, &err));
    CHECK(mlight_build(b->e, b->l, &b->m, &err));
}

static void release(built *b)
{
    mlight_free(b->m);
    light_free(b->l);
    emb_free(b->e);
    scene_free(b->s);
}

Test(mirror_lights, quads_boxes_and_spheres)
{
    ct_error err;
    built b = {scene_new("mirrors"), NULL, NULL, NULL};
    int mi = mirror_material(b.s, &err);
    int wall = ts_diffuse(b.s, "wall", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(b.s, "lamp", v3s(0.0f), v3s(5.0f), &err);
    cr_assert(mi >= 0 && wall >= 0 && lamp >= 0);
    /* A wall mirror 2 x 1 in the plane z = 4 facing -z (front e1 x e2 =
     * (0,1,0) x (1,0,0) = (0,0,-1)), a mirror box (six planes), a mirror
     * sphere of 16 x 8 facets (curved: none), a diffuse wall (none) and a
     * lamp facing down at y = 3. */
    cr_assert(ts_quad(b.s, "wall_mirror", (uint32_t)mi, v3(1, 1, 4), v3(0, 1, 0), v3(2, 0, 0), &err) >= 0);
    cr_assert(ts_box(b.s, "mirror_box", (uint32_t)mi, v3(-3, 0, 0), v3(-2.5f, 0.5f, 0.5f), false, &err) >= 0);
    cr_assert(ts_sphere(b.s, "ball", (uint32_t)mi, v3(5, 1, 1), 0.5f, 16, 8, false, &err) >= 0);
    cr_assert(ts_quad(b.s, "wall", (uint32_t)wall, v3(-10, 0, 6), v3(0, 5, 0), v3(20, 0, 0), &err) >= 0);
    cr_assert(ts_quad(b.s, "lamp", (uint32_t)lamp, v3(0, 3, 1), v3(1, 0, 0), v3(0, 0, 1), &err) >= 0);
    build(&b);
    cr_assert_eq(mlight_count(b.m), 7, "1 wall mirror + 6 box faces, no sphere facet: %u", mlight_count(b.m));
    /* The largest first: the wall mirror (2 m^2; box faces 0.25 m^2). */
    const mlight_plane *w = mlight_get(b.m, 0);
    cr_assert_float_eq(w->area, 2.0f, 1e-5f);
    cr_assert(fabsf(w->n.z + 1.0f) < 1e-6f && fabsf(w->d + 4.0f) < 1e-5f, "plane n (%g %g %g) d %g", (double)w->n.x,
              (double)w->n.y, (double)w->n.z, (double)w->d);
    cr_assert(fabsf(w->rho.x - 0.9f) < 1e-7f && fabsf(w->rho.z - 0.7f) < 1e-7f);
    cr_assert(mlight_in_bounds(w, v3(2.0f, 1.5f, 4.0f)), "the mirror's middle");
    cr_assert(mlight_in_bounds(w, v3(1.0f, 1.0f, 4.0f)), "a corner");
    cr_assert(!mlight_in_bounds(w, v3(0.98f, 1.5f, 4.0f)), "beside it");
    cr_assert(!mlight_in_bounds(w, v3(2.0f, 2.02f, 4.0f)), "above it");
    cr_assert(mlight_side(w, v3(0, 0, 0)) > 0.0f, "the room is in front of the mirror");
    for (uint32_t i = 1; i < mlight_count(b.m); i++)
        cr_assert_float_eq(mlight_get(b.m, i)->area, 0.25f, 1e-5f);
    release(&b);
}

/* A quad as polygon of the open part (no normals: flat). */
static void quad_in_part(ct_scene *s, vec3 c, vec3 e1, vec3 e2)
{
    ct_error err;
    vec3 p[4] = {c, v3_add(c, e1), v3_add(v3_add(c, e1), e2), v3_add(c, e2)};
    uint32_t idx[4];
    for (int k = 0; k < 4; k++) {
        int64_t v = scene_add_vertex(s, p[k], v3s(0.0f), &err);
        cr_assert(v >= 0, "%s", err.msg);
        idx[k] = (uint32_t)v;
    }
    CHECK(scene_add_polygon(s, idx, 4, &err));
}

/* Two coplanar quads of one part are one mirror (its area their sum, its
 * bounds both); the same quads as two parts are two mirrors; a part whose
 * mirror triangles span more than MLIGHT_NODE_PLANES planes (a staircase of
 * nine steps) has none. */
Test(mirror_lights, one_plane_of_one_part_is_one_mirror)
{
    ct_error err;
    for (int parts = 1; parts <= 2; parts++) {
        built b = {scene_new("split"), NULL, NULL, NULL};
        int mi = mirror_material(b.s, &err);
        cr_assert(mi >= 0);
        cr_assert(scene_begin_node(b.s, "m", SCENE_NODE_PART, (uint32_t)mi, &err) >= 0);
        quad_in_part(b.s, v3(0, 0, 0), v3(0, 1, 0), v3(1, 0, 0));
        if (parts == 2) {
            CHECK(scene_end_node(b.s, &err));
            cr_assert(scene_begin_node(b.s, "m2", SCENE_NODE_PART, (uint32_t)mi, &err) >= 0);
        }
        quad_in_part(b.s, v3(3, 0, 0), v3(0, 1, 0), v3(1, 0, 0));
        CHECK(scene_end_node(b.s, &err));
        build(&b);
        cr_assert_eq(mlight_count(b.m), (uint32_t)parts, "%d parts: %u mirrors", parts, mlight_count(b.m));
        if (parts == 1) {
            const mlight_plane *m = mlight_get(b.m, 0);
            cr_assert_float_eq(m->area, 2.0f, 1e-5f);
            cr_assert(mlight_in_bounds(m, v3(0.5f, 0.5f, 0)) && mlight_in_bounds(m, v3(3.5f, 0.5f, 0)));
        }
        release(&b);
    }
    built b = {scene_new("steps"), NULL, NULL, NULL};
    int mi = mirror_material(b.s, &err);
    cr_assert(mi >= 0);
    cr_assert(scene_begin_node(b.s, "steps", SCENE_NODE_PART, (uint32_t)mi, &err) >= 0);
    for (int k = 0; k <= MLIGHT_NODE_PLANES; k++)
        quad_in_part(b.s, v3(0, 0.1f * (float)k, (float)k), v3(0, 0, 1), v3(1, 0, 0));
    CHECK(scene_end_node(b.s, &err));
    build(&b);
    cr_assert_eq(mlight_count(b.m), 0, "%d planes: %u mirrors", MLIGHT_NODE_PLANES + 1, mlight_count(b.m));
    release(&b);
}
