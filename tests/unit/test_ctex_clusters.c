/* Large parts split into clusters (master/ctex_hier.c): flat faces stay
 * whole, curved parts split by space, each texture is drawn on its own
 * triangles; camera-local textures keep their contents when the camera
 * turns. */
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
#include "master/ctex_tex.h"
#include "tests/support/ctex_scenes.h"

static ct_error err;

static ct_scene *l_scene(int n)
{
    ct_scene *s = tcx_one_part_begin("L", "L");
    for (int side = 0; side < 2; side++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                float x0 = -5.0f + 10.0f * (float)i / (float)n, x1 = -5.0f + 10.0f * (float)(i + 1) / (float)n;
                float a0 = 10.0f * (float)j / (float)n, a1 = 10.0f * (float)(j + 1) / (float)n;
                vec3 p[4];
                if (side == 0) { p[0] = v3(x0, 0, a0 - 10); p[1] = v3(x0, 0, a1 - 10); p[2] = v3(x1, 0, a1 - 10); p[3] = v3(x1, 0, a0 - 10); }
                else { p[0] = v3(x0, a0, -10); p[1] = v3(x1, a0, -10); p[2] = v3(x1, a1, -10); p[3] = v3(x0, a1, -10); }
                tcx_add_quad(s, p, side == 0 ? v3(0, 1, 0) : v3(0, 0, 1));
            }
    tcx_one_part_end(s);
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

Test(ctex_clusters, large_parts_split_into_flat_clusters)
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
Test(ctex_clusters, display_mesh_draws_each_texture_on_its_own_triangles)
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
            ct_sample s = tcx_sample(node, p, v3s(p.x - x0 + 0.5f), v3s(0.0f));
            ctex_insert(c, &s, &info);
        }
}

Test(ctex_clusters, camera_local_rotation_keeps_contents_and_does_not_age)
{
    tcx_scene t;
    tcx_build(&t);
    ctex_options o = ctex_options_default();
    o.eps = 0.0f;
    ctex *c = tcx_engine(&t, o);
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
    tcx_release(&t);
}

Test(ctex_clusters, non_flat_large_parts_split_by_space)
{
    /* a corrugated sheet: strips tilted +-20 degrees, one part of 4096
     * triangles; the normal split gives two sets of parallel, not coplanar
     * strips, which split by space down to clusters of at most 512 */
    ct_scene *s = tcx_one_part_begin("corrugated", "sheet");
    const int nx = 64, nz = 32;
    for (int i = 0; i < nx; i++)
        for (int j = 0; j < nz; j++) {
            float x0 = (float)i * 0.2f, x1 = x0 + 0.2f, z0 = (float)j * 0.2f, z1 = z0 + 0.2f;
            float y0 = (i % 2) ? 0.0728f : 0.0f, y1 = (i % 2) ? 0.0f : 0.0728f;   /* tan(20°) * 0.2 */
            vec3 p[4] = {v3(x0, y0, z0), v3(x0, y0, z1), v3(x1, y1, z1), v3(x1, y1, z0)};
            tcx_add_quad(s, p, v3(0, 1, 0));
        }
    tcx_one_part_end(s);
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
    ct_scene *s = tcx_one_part_begin("room", "walls");
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
                tcx_add_quad(s, p, nn);
            }
    for (int r = 0; r < 2; r++) {
        float x0 = (float)r * 2.0f, x1 = x0 + 0.5f;
        vec3 p[4] = {v3(x0, 0.0f, -4.8f), v3(x1, 0.0f, -4.8f), v3(x1, 2.0f, -4.8f), v3(x0, 2.0f, -4.8f)};
        tcx_add_quad(s, p, v3(0, 0, 1));
    }
    tcx_one_part_end(s);
    return s;
}

Test(ctex_clusters, clusters_keep_each_face_whole)
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
