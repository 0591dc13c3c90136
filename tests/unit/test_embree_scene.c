/* The Embree scene: geomID/primID map back to triangle, part node and
 * material, for a scene and for a radiosity mesh whose triangles are not
 * grouped by node; bad meshes and device configs give one-line errors. */
#include <criterion/criterion.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/radmesh.h"
#include "tests/support/testscenes.h"
#include "tracer/embree_scene.h"

/* Three unit quads side by side at z = 0 (x in [0,1], [2,3], [4,5]),
 * each its own part with its own material. */
static ct_scene *three_quads(void)
{
    ct_error err;
    ct_scene *s = scene_new("three");
    cr_assert(s);
    for (int i = 0; i < 3; i++) {
        char name[16];
        snprintf(name, sizeof name, "m%d", i);
        int m = ts_diffuse(s, name, v3s(0.1f * (float)(i + 1)), v3s(0.0f), &err);
        cr_assert(m >= 0);
        cr_assert(ts_quad(s, name, (uint32_t)m, v3(2.0f * (float)i, 0, 0), v3(1, 0, 0), v3(0, 1, 0), &err) >= 0);
    }
    cr_assert_eq(scene_finalize(s, &err), 0, "%s", err.msg);
    return s;
}

static void check_hits(const emb_scene *e, const emb_mesh *m)
{
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 2; k++) {
            /* Lower-right / upper-left halves of quad i. */
            vec3 o = v3(2.0f * (float)i + (k ? 0.2f : 0.8f), k ? 0.8f : 0.2f, -1.0f);
            emb_hit h;
            cr_assert(emb_intersect(e, o, v3(0, 0, 1), 0.0f, 10.0f, &h));
            cr_expect(fabsf(h.t - 1.0f) < 1e-5f);
            cr_expect_eq(h.node, m->tri_node[h.tri]);
            cr_expect_eq(h.mat, m->tri_mat[h.tri]);
            cr_expect_eq(h.mat, (uint32_t)i, "quad %d: material %u", i, h.mat);
            vec3 p = emb_tri_point(m, h.tri, h.u, h.v);
            cr_expect(fabsf(p.x - o.x) < 1e-5f && fabsf(p.y - o.y) < 1e-5f && fabsf(p.z) < 1e-5f,
                      "barycentrics do not give the hit point");
            cr_expect(emb_occluded(e, o, v3(0, 0, 1), 0.0f, 10.0f));
            cr_expect(!emb_occluded(e, o, v3(0, 0, 1), 0.0f, 0.5f));
        }
    emb_hit h;
    cr_expect(!emb_intersect(e, v3(1.5f, 0.5f, -1), v3(0, 0, 1), 0.0f, 10.0f, &h), "gap between quads hit");
}

Test(embree_scene, scene_hits_map_to_node_triangle_material)
{
    ct_scene *s = three_quads();
    emb_mesh m = emb_mesh_of_scene(s);
    emb_scene *e;
    ct_error err;
    cr_assert_eq(emb_new(&m, NULL, &e, &err), 0, "%s", err.msg);
    check_hits(e, emb_get_mesh(e));
    emb_free(e);
    scene_free(s);
}

Test(embree_scene, radmesh_with_interleaved_nodes)
{
    ct_scene *s = three_quads();
    ct_radmesh r;
    ct_error err;
    cr_assert_eq(rmesh_from_scene(s, v3s(0.0f), &r, &err), 0);
    /* Reverse the triangle order, so nodes appear out of order. */
    for (uint32_t a = 0, b = r.ntris - 1; a < b; a++, b--) {
        uint32_t t3[3];
        memcpy(t3, r.tris + 3 * a, sizeof t3);
        memcpy(r.tris + 3 * a, r.tris + 3 * b, sizeof t3);
        memcpy(r.tris + 3 * b, t3, sizeof t3);
        uint32_t x = r.tri_node[a]; r.tri_node[a] = r.tri_node[b]; r.tri_node[b] = x;
        x = r.tri_mat[a]; r.tri_mat[a] = r.tri_mat[b]; r.tri_mat[b] = x;
    }
    emb_mesh m = emb_mesh_of_radmesh(&r, s);
    emb_scene *e;
    cr_assert_eq(emb_new(&m, "", &e, &err), 0, "%s", err.msg);
    check_hits(e, emb_get_mesh(e));
    emb_free(e);
    rmesh_free(&r);
    scene_free(s);
}

Test(embree_scene, bad_meshes_and_device_config)
{
    ct_scene *s = three_quads();
    emb_scene *e = NULL;
    ct_error err;
    emb_mesh m = emb_mesh_of_scene(s);
    uint32_t *tris = malloc(3 * sizeof(uint32_t) * s->ntris);
    memcpy(tris, s->tris, 3 * sizeof(uint32_t) * s->ntris);
    tris[4] = 99;
    m.tris = tris;
    cr_expect_eq(emb_new(&m, NULL, &e, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "vertex index 99") != NULL, "%s", err.msg);
    cr_expect(e == NULL);
    m = emb_mesh_of_scene(s);
    m.nmats = 1;
    cr_expect_eq(emb_new(&m, NULL, &e, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "material") != NULL, "%s", err.msg);
    m = emb_mesh_of_scene(s);
    cr_expect_eq(emb_new(&m, "threads=abc", &e, &err), CT_ESYS);
    cr_expect(strstr(err.msg, "embree") != NULL && strchr(err.msg, '\n') == NULL, "%s", err.msg);
    free(tris);
    scene_free(s);
}

/* Shading normals: a triangle whose vertex normals agree with its face normal
 * takes the face normal; tilted or flipped vertex normals are interpolated
 * (their record's second cache line is read), with the mesh's per-vertex
 * reads on or off. */
Test(embree_scene, shading_normals_flat_and_curved)
{
    const float c = 0.6f, z = 0.8f;
    vec3 pos[9], nrm[9];
    uint32_t tris[9], node[3] = {0, 1, 2}, mat[3] = {0, 0, 0};
    for (int t = 0; t < 3; t++) {
        pos[3 * t] = v3(2.0f * (float)t, 0, 0);
        pos[3 * t + 1] = v3(2.0f * (float)t + 1.0f, 0, 0);
        pos[3 * t + 2] = v3(2.0f * (float)t, 1, 0);
        for (int k = 0; k < 3; k++) tris[3 * t + k] = (uint32_t)(3 * t + k);
    }
    /* triangle 0 flat (+z, the winding's normal); 1 with vertex 0 tilted
     * towards +x; 2 flipped against its winding */
    for (int k = 0; k < 3; k++) nrm[k] = v3(0, 0, 1);
    nrm[3] = v3(c, 0, z); nrm[4] = v3(0, 0, 1); nrm[5] = v3(0, 0, 1);
    for (int k = 6; k < 9; k++) nrm[k] = v3(0, 0, -1);
    scene_material mats[1];
    memset(mats, 0, sizeof mats);
    emb_mesh m = {.nverts = 9, .pos = pos, .nrm = nrm, .ntris = 3, .tris = tris, .tri_node = node,
                  .tri_mat = mat, .nnodes = 3, .nmats = 1, .mats = mats};
    for (int reads = 0; reads < 2; reads++) {
        m.vertex_reads = reads;
        emb_scene *e;
        ct_error err;
        cr_assert_eq(emb_new(&m, NULL, &e, &err), 0, "%s", err.msg);
        for (int t = 0; t < 3; t++) {
            vec3 o = v3(2.0f * (float)t + 0.25f, 0.25f, 1.0f);
            emb_hit h;
            cr_assert(emb_intersect(e, o, v3(0, 0, -1), 0.0f, 10.0f, &h));
            cr_assert_eq(h.tri, (uint32_t)t);
            vec3 n = emb_shading_normal(&h);
            float w = 1.0f - h.u - h.v;
            vec3 want = v3_norm(v3_add(v3_add(v3_scale(nrm[3 * t], w), v3_scale(nrm[3 * t + 1], h.u)),
                                       v3_scale(nrm[3 * t + 2], h.v)));
            cr_expect(fabsf(n.x - want.x) < 1e-6f && fabsf(n.y - want.y) < 1e-6f && fabsf(n.z - want.z) < 1e-6f,
                      "triangle %d (vertex reads %d): shading normal (%g %g %g), want (%g %g %g)", t, reads,
                      (double)n.x, (double)n.y, (double)n.z, (double)want.x, (double)want.y, (double)want.z);
        }
        /* the tilted triangle really bends the normal (0.25 of vertex 0's tilt
         * would not pass for the face normal) */
        emb_hit h;
        cr_assert(emb_intersect(e, v3(2.25f, 0.25f, 1.0f), v3(0, 0, -1), 0.0f, 10.0f, &h));
        cr_expect_gt(emb_shading_normal(&h).x, 0.1f);
        emb_free(e);
    }
}
