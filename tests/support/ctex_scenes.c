/* ctex_scenes.c: scenes built in code for the corrective-texture tests
 * (ctex_scenes.h). */
#include "tests/support/ctex_scenes.h"

#include <criterion/criterion.h>
#include <stdio.h>
#include <string.h>


/* Adds the quad p[0..3] with normal n to the open part. */
void tcx_add_quad(ct_scene *s, const vec3 p[4], vec3 n)
{
    ct_error e;
    uint32_t idx[4];
    for (int i = 0; i < 4; i++) idx[i] = (uint32_t)scene_add_vertex(s, p[i], n, &e);
    cr_assert_eq(scene_add_polygon(s, idx, 4, &e), 0, "%s", e.msg);
}

void tcx_quad_part(ct_scene *s, const char *name, uint32_t mat, vec3 a, vec3 b, vec3 c, vec3 d)
{
    ct_error e;
    cr_assert_geq(scene_begin_node(s, name, SCENE_NODE_PART, mat, &e), 0, "%s", e.msg);
    vec3 p[4] = {a, b, c, d};
    tcx_add_quad(s, p, v3_norm(v3_cross(v3_sub(b, a), v3_sub(c, a))));
    cr_assert_eq(scene_end_node(s, &e), 0);
}

/* A scene with one grey material whose one part `part` is left open for
 * add_quad; one_part_end closes and finalizes it. */
ct_scene *tcx_one_part_begin(const char *name, const char *part)
{
    ct_error e;
    ct_scene *s = scene_new(name);
    cr_assert_not_null(s);
    scene_material w = scene_material_default("w");
    w.diffuse = v3s(0.5f);
    scene_add_material(s, &w, &e);
    cr_assert_geq(scene_begin_node(s, part, SCENE_NODE_PART, 0, &e), 0);
    return s;
}

void tcx_one_part_end(ct_scene *s)
{
    ct_error e;
    cr_assert_eq(scene_end_node(s, &e), 0);
    cr_assert_eq(scene_finalize(s, &e), 0, "%s", e.msg);
}

/* A closed box as one part (not flat). */
void tcx_box_part(ct_scene *s, const char *name, uint32_t mat, vec3 lo, vec3 hi)
{
    ct_error e;
    cr_assert_geq(scene_begin_node(s, name, SCENE_NODE_PART, mat, &e), 0, "%s", e.msg);
    const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int f = 0; f < 6; f++) {
        uint32_t idx[4];
        for (int k = 0; k < 4; k++) {
            bounds3 b = {lo, hi};
            idx[k] = (uint32_t)scene_add_vertex(s, b3_corner(b, faces[f][k]), v3(0, 1, 0), &e);
        }
        cr_assert_eq(scene_add_polygon(s, idx, 4, &e), 0);
    }
    cr_assert_eq(scene_end_node(s, &e), 0);
}

void tcx_build(tcx_scene *t)
{
    ct_error e;
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
    uint32_t mw = (uint32_t)scene_add_material(t->s, &dif, &e);
    uint32_t mr = (uint32_t)scene_add_material(t->s, &red, &e);
    uint32_t mg = (uint32_t)scene_add_material(t->s, &gl, &e);
    t->floor = (int)t->s->nnodes;
    tcx_quad_part(t->s, "floor", mw, v3(-10, 0, -10), v3(-10, 0, 10), v3(10, 0, 10), v3(10, 0, -10));
    for (int i = 0; i < 3; i++) {
        char name[16];
        snprintf(name, sizeof name, "g%d", i);
        cr_assert_geq(scene_begin_node(t->s, name, SCENE_NODE_GROUP, UINT32_MAX, &e), 0);
        float x = -4.0f + 4.0f * (float)i;
        t->box[i] = (int)t->s->nnodes;
        tcx_box_part(t->s, "box", mr, v3(x - 0.5f, 0, -0.5f), v3(x + 0.5f, 1, 0.5f));
        t->plate[i] = (int)t->s->nnodes;
        tcx_quad_part(t->s, "plate", mw, v3(x - 0.6f, 1.01f, -0.6f), v3(x - 0.6f, 1.01f, 0.6f),
                  v3(x + 0.6f, 1.01f, 0.6f), v3(x + 0.6f, 1.01f, -0.6f));
        cr_assert_eq(scene_end_node(t->s, &e), 0);
    }
    t->panel = (int)t->s->nnodes;
    tcx_quad_part(t->s, "panel", mg, v3(-3, 0.5f, -5), v3(-3, 3, -5), v3(3, 3, -5), v3(3, 0.5f, -5));
    t->behind = (int)t->s->nnodes;
    tcx_box_part(t->s, "behind", mr, v3(-1, 0, 30), v3(1, 2, 32));
    cr_assert_eq(scene_finalize(t->s, &e), 0, "%s", e.msg);
    cr_assert_eq(rmesh_from_scene(t->s, v3s(0.5f), &t->m, &e), 0);
}

void tcx_release(tcx_scene *t)
{
    rmesh_free(&t->m);
    scene_free(t->s);
}

ctex *tcx_engine(tcx_scene *t, ctex_options o)
{
    ct_error e;
    ctex *c = NULL;
    cr_assert_eq(ctex_new(&t->m, t->s->mats, t->s->nmats, &o, &c, &e), 0, "%s", e.msg);
    return c;
}

ct_camera tcx_front_cam(void)
{
    return cam_look_at(v3(0, 4, 14), v3(0, 0.5f, 0), v3(0, 1, 0), 50.0f);
}

/* The test scene with an engine of options o under the front camera at
 * w x h pixels. */
ctex *tcx_front_engine(tcx_scene *t, ctex_options o, int w, int h)
{
    ct_error e;
    tcx_build(t);
    ctex *c = tcx_engine(t, o);
    ct_camera cam = tcx_front_cam();
    cr_assert_eq(ctex_set_camera(c, &cam, w, h, &e), 0, "%s", e.msg);
    return c;
}

/* front_engine with leaf textures (eps = 0). */
ctex *tcx_leaf_engine(tcx_scene *t, int w, int h)
{
    ctex_options o = ctex_options_default();
    o.eps = 0.0f;
    return tcx_front_engine(t, o, w, h);
}

ct_sample tcx_sample(uint32_t node, vec3 hit, vec3 hq, vec3 base)
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
void tcx_fill_floor(ctex *c, uint32_t node, float val, float y)
{
    ctex_insert_info info;
    for (int i = 0; i < 40; i++)
        for (int j = 0; j < 40; j++) {
            vec3 p = v3(-9.75f + 0.5f * (float)i, y, -9.75f + 0.5f * (float)j);
            ct_sample s = tcx_sample(node, p, v3s(val), v3s(0.0f));
            ctex_insert(c, &s, &info);
        }
}

