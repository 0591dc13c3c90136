/* The built-in scenes (scenes/): each loads through scene_load, and what
 * comes out matches what its generator (scenes/gen/NAME.c) is designed to
 * write: the Cornell box's counts from its published geometry and sphere
 * tessellation, the table's and the office's counts from their design and
 * from the generator's own tally (NAME.counts, counted while writing, so it
 * is independent of assimp and the loader); materials by kind after the
 * JSON overrides; emitters; hierarchy; bounds; normals that agree with the
 * windings; and every camera and path sample is finite, inside the scene,
 * and looks at front faces that are not right in front of the lens.
 * Run from the repository root after `make` (which generates the meshes). */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "common/camera.h"
#include "common/campath.h"
#include "common/log.h"
#include "common/scene.h"

#define CORNELL "scenes/cornell/cornell.json"
#define TABLE "scenes/table/table.json"
#define OFFICE "scenes/office/office.json"

static void quiet(void) { ct_log_set_level(CT_LOG_ERROR); }
TestSuite(scenes, .init = quiet);

static ct_scene *load_ok(const char *path)
{
    ct_error err;
    ct_scene *s = NULL;
    int rc = scene_load(path, &s, &err);
    cr_assert_eq(rc, CT_OK, "loading %s failed (run make first): %s", path, err.msg);
    cr_assert_not_null(s);
    return s;
}

/* --- the generators' own tallies ------------------------------------------ */

typedef struct gen_counts { long files, objects, prims, quads, tris, ngons; } gen_counts;

static gen_counts read_counts(const char *path)
{
    gen_counts c = {-1, -1, -1, -1, -1, -1};
    FILE *f = fopen(path, "r");
    cr_assert_not_null(f, "%s missing (run make scenes)", path);
    char line[256], key[64];
    long v;
    while (fgets(line, sizeof line, f)) {
        if (line[0] == '#' || sscanf(line, "%63s %ld", key, &v) != 2) continue;
        if (!strcmp(key, "files")) c.files = v;
        else if (!strcmp(key, "objects")) c.objects = v;
        else if (!strcmp(key, "primitives")) c.prims = v;
        else if (!strcmp(key, "quads")) c.quads = v;
        else if (!strcmp(key, "triangles")) c.tris = v;
        else if (!strcmp(key, "ngons")) c.ngons = v;
    }
    fclose(f);
    cr_assert(c.files >= 0 && c.objects >= 0 && c.prims >= 0 && c.quads >= 0 && c.tris >= 0 &&
                  c.ngons >= 0, "%s incomplete", path);
    return c;
}

/* The loaded scene holds exactly what the generator wrote: every polygon
 * one primitive, quads as two triangles, one group per OBJ object, one
 * file node per mesh file. */
static void expect_matches_generator(const ct_scene *s, const char *counts_path)
{
    gen_counts c = read_counts(counts_path);
    cr_expect_eq(c.ngons, 0, "generators write triangles and quads only");
    cr_expect_eq(c.prims, c.quads + c.tris + c.ngons);
    cr_expect_eq((long)s->nprims, c.prims, "%s: primitives %u, generator wrote %ld", s->name,
                 s->nprims, c.prims);
    cr_expect_eq((long)s->nquads, c.quads, "%s: quads %u, generator wrote %ld", s->name, s->nquads,
                 c.quads);
    cr_expect_eq((long)s->ntris, c.tris + 2 * c.quads, "%s: triangles %u, expected %ld", s->name,
                 s->ntris, c.tris + 2 * c.quads);
    cr_expect_eq(s->dropped_degenerate, 0u, "%s: generators write no degenerate polygons", s->name);
    long files = 0, groups = 0;
    for (uint32_t n = 0; n < s->nnodes; n++) {
        files += s->nodes[n].kind == SCENE_NODE_FILE;
        groups += s->nodes[n].kind == SCENE_NODE_GROUP;
    }
    cr_expect_eq(files, c.files, "%s: %ld file nodes, generator wrote %ld files", s->name, files, c.files);
    cr_expect_eq(groups, c.objects, "%s: %ld groups, generator wrote %ld objects", s->name, groups,
                 c.objects);
}

/* --- materials by kind ------------------------------------------------------ */

typedef struct kinds { int diffuse, phong, ward, mirror, dielectric, emissive; } kinds;

static void count_kind(kinds *k, const scene_material *m)
{
    const char *kind = scene_material_kind(m);
    if (!strcmp(kind, "diffuse")) k->diffuse++;
    else if (!strcmp(kind, "phong")) k->phong++;
    else if (!strcmp(kind, "ward")) k->ward++;
    else if (!strcmp(kind, "mirror")) k->mirror++;
    else if (!strcmp(kind, "dielectric")) k->dielectric++;
    else if (!strcmp(kind, "emissive")) k->emissive++;
    else cr_assert_fail("unknown material kind %s", kind);
}

/* Kinds over all materials, and checks every material is used by some
 * triangle (the scenes define no spare ones). */
static kinds material_kinds(const ct_scene *s)
{
    kinds k = {0, 0, 0, 0, 0, 0};
    for (uint32_t i = 0; i < s->nmats; i++) {
        uint32_t t = 0;
        while (t < s->ntris && s->tri_mat[t] != i) t++;
        cr_expect_lt(t, s->ntris, "%s: material %s is not used", s->name, s->mats[i].name);
        count_kind(&k, &s->mats[i]);
    }
    return k;
}

static void expect_kinds(const ct_scene *s, kinds want)
{
    kinds k = material_kinds(s);
    cr_expect_eq(k.diffuse, want.diffuse, "%s: diffuse %d, want %d", s->name, k.diffuse, want.diffuse);
    cr_expect_eq(k.phong, want.phong, "%s: phong %d, want %d", s->name, k.phong, want.phong);
    cr_expect_eq(k.ward, want.ward, "%s: ward %d, want %d", s->name, k.ward, want.ward);
    cr_expect_eq(k.mirror, want.mirror, "%s: mirror %d, want %d", s->name, k.mirror, want.mirror);
    cr_expect_eq(k.dielectric, want.dielectric, "%s: dielectric %d, want %d", s->name, k.dielectric,
                 want.dielectric);
    cr_expect_eq(k.emissive, want.emissive, "%s: emissive %d, want %d", s->name, k.emissive,
                 want.emissive);
}

static const scene_material *mat(const ct_scene *s, const char *name)
{
    int i = scene_find_material(s, name);
    cr_assert_geq(i, 0, "%s: material %s missing", s->name, name);
    return &s->mats[i];
}

static const char *kind_of(const ct_scene *s, const char *name)
{
    return scene_material_kind(mat(s, name));
}

/* The first node of a kind with that name, or -1. */
static int find_node(const ct_scene *s, scene_node_kind kind, const char *name)
{
    for (uint32_t n = 0; n < s->nnodes; n++)
        if (s->nodes[n].kind == kind && !strcmp(s->nodes[n].name, name)) return (int)n;
    return -1;
}

/* The child of node p with that name, or -1. */
static int child_named(const ct_scene *s, int p, const char *name)
{
    cr_assert_geq(p, 0);
    uint32_t end = s->nodes[p].node_end;
    for (uint32_t c = scene_first_child(s, (uint32_t)p); c < end; c = scene_next_sibling(s, c))
        if (!strcmp(s->nodes[c].name, name)) return (int)c;
    return -1;
}

/* Kind of the only material under node n (all its parts share it). */
static const char *node_kind(const ct_scene *s, int n)
{
    cr_assert_geq(n, 0);
    const scene_node *g = &s->nodes[n];
    cr_assert_gt(g->tri_end, g->tri_begin, "node %s is empty", g->name);
    uint32_t m = s->tri_mat[g->tri_begin];
    for (uint32_t t = g->tri_begin; t < g->tri_end; t++)
        cr_assert_eq(s->tri_mat[t], m, "node %s mixes materials", g->name);
    return scene_material_kind(&s->mats[m]);
}

static bool inside(bounds3 outer, bounds3 b, float eps)
{
    return b.lo.x >= outer.lo.x - eps && b.lo.y >= outer.lo.y - eps && b.lo.z >= outer.lo.z - eps &&
           b.hi.x <= outer.hi.x + eps && b.hi.y <= outer.hi.y + eps && b.hi.z <= outer.hi.z + eps;
}

static void expect_bounds(const ct_scene *s, vec3 lo, vec3 hi, float eps)
{
    cr_expect(fabsf(s->bounds.lo.x - lo.x) <= eps && fabsf(s->bounds.lo.y - lo.y) <= eps &&
                  fabsf(s->bounds.lo.z - lo.z) <= eps && fabsf(s->bounds.hi.x - hi.x) <= eps &&
                  fabsf(s->bounds.hi.y - hi.y) <= eps && fabsf(s->bounds.hi.z - hi.z) <= eps,
              "%s: bounds [%g %g %g]..[%g %g %g], want [%g %g %g]..[%g %g %g]", s->name,
              (double)s->bounds.lo.x, (double)s->bounds.lo.y, (double)s->bounds.lo.z,
              (double)s->bounds.hi.x, (double)s->bounds.hi.y, (double)s->bounds.hi.z, (double)lo.x,
              (double)lo.y, (double)lo.z, (double)hi.x, (double)hi.y, (double)hi.z);
}

/* --- checks shared by all scenes ------------------------------------------ */

/* Hierarchy: root -> file -> group -> part, ranges nest, parts carry their
 * material, every node lies inside the scene bounds. */
static void check_hierarchy(const ct_scene *s)
{
    cr_assert_eq(s->nodes[0].kind, SCENE_NODE_ROOT);
    cr_expect_eq(s->nodes[0].node_end, s->nnodes);
    cr_expect_eq(s->nodes[0].tri_begin, 0u);
    cr_expect_eq(s->nodes[0].tri_end, s->ntris);
    float eps = 1e-4f * v3_maxc(b3_extent(s->bounds));
    for (uint32_t n = 1; n < s->nnodes; n++) {
        const scene_node *c = &s->nodes[n], *p = &s->nodes[c->parent];
        cr_assert_lt((uint32_t)c->parent, n);
        cr_expect_eq((int)c->kind, (int)p->kind + 1, "%s: node %s (kind %d) under kind %d", s->name,
                     c->name, c->kind, p->kind);
        cr_expect(p->tri_begin <= c->tri_begin && c->tri_end <= p->tri_end && c->node_end <= p->node_end);
        cr_expect_gt(c->tri_end, c->tri_begin, "%s: node %s is empty", s->name, c->name);
        cr_expect(inside(s->bounds, c->bounds, eps), "%s: node %s outside the scene bounds", s->name,
                  c->name);
        if (c->kind == SCENE_NODE_PART)
            for (uint32_t t = c->tri_begin; t < c->tri_end; t++) {
                cr_assert_eq(s->tri_node[t], n);
                cr_assert_eq(s->tri_mat[t], c->material);
            }
    }
}

/* Every vertex normal is a finite unit vector on the front side of its
 * triangle: the generators orient windings to agree with the normals. */
static void check_normals(const ct_scene *s)
{
    uint32_t bad = 0, first = UINT32_MAX;
    for (uint32_t t = 0; t < s->ntris; t++) {
        vec3 fn = scene_tri_normal(s, t);
        for (int k = 0; k < 3; k++) {
            vec3 n = s->nrm[s->tris[3 * t + k]];
            if (!v3_finite(n) || fabsf(v3_len(n) - 1.0f) > 1e-3f || v3_dot(n, fn) <= 0.0f) {
                if (!bad) first = t;
                bad++;
                break;
            }
        }
    }
    cr_expect_eq(bad, 0u, "%s: %u triangles whose normals disagree with their winding (first %u)",
                 s->name, bad, first);
}

/* Every light faces down into its room (the scenes' lights all hang from
 * ceilings or sit in lamp shades). */
static void check_emitters_face_down(const ct_scene *s)
{
    cr_assert_gt(s->nemitters, 0u);
    for (uint32_t i = 0; i < s->nemitters; i++) {
        vec3 n = scene_tri_normal(s, s->emitters[i]);
        cr_expect_lt(n.y, -0.9f, "%s: emitter triangle %u faces (%g %g %g)", s->name, s->emitters[i],
                     (double)n.x, (double)n.y, (double)n.z);
    }
}

/* Nearest hit of a ray (Moeller-Trumbore, both sides); -1 when none. */
static int64_t nearest_hit(const ct_scene *s, vec3 o, vec3 d, float *tmin)
{
    int64_t best = -1;
    double bt = INFINITY;
    for (uint32_t t = 0; t < s->ntris; t++) {
        vec3 a = s->pos[s->tris[3 * t]], b = s->pos[s->tris[3 * t + 1]], c = s->pos[s->tris[3 * t + 2]];
        double e1[3] = {b.x - a.x, b.y - a.y, b.z - a.z}, e2[3] = {c.x - a.x, c.y - a.y, c.z - a.z};
        double p[3] = {d.y * e2[2] - d.z * e2[1], d.z * e2[0] - d.x * e2[2], d.x * e2[1] - d.y * e2[0]};
        double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
        if (fabs(det) < 1e-18) continue;
        double inv = 1.0 / det, tv[3] = {o.x - a.x, o.y - a.y, o.z - a.z};
        double u = (tv[0] * p[0] + tv[1] * p[1] + tv[2] * p[2]) * inv;
        if (u < 0 || u > 1) continue;
        double q[3] = {tv[1] * e1[2] - tv[2] * e1[1], tv[2] * e1[0] - tv[0] * e1[2],
                       tv[0] * e1[1] - tv[1] * e1[0]};
        double v = (d.x * q[0] + d.y * q[1] + d.z * q[2]) * inv;
        if (v < 0 || u + v > 1) continue;
        double h = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) * inv;
        if (h > 0 && h < bt) {
            bt = h;
            best = t;
        }
    }
    *tmin = (float)bt;
    return best;
}

typedef struct view_rules {
    bounds3 eye_box;     /* where eyes may be */
    bool closed;         /* a room: every ray must hit something */
    float clearance;     /* nearest visible surface at least this far */
} view_rules;

/* A camera is finite, its eye inside the allowed box, and a 3 x 3 grid of
 * rays across its image sees front faces at least `clearance` away (so
 * the eye is not inside an object or pressed against one). */
static void check_view(const ct_scene *s, const ct_camera *c, const view_rules *r, const char *what)
{
    cr_assert(v3_finite(c->eye) && isfinite(c->orient.w) && isfinite(c->orient.x) &&
                  isfinite(c->orient.y) && isfinite(c->orient.z) && isfinite(c->fov_y),
              "%s: %s: non-finite camera", s->name, what);
    cr_assert(c->fov_y > 0.0f && c->fov_y < 3.1f, "%s: %s: fov %g", s->name, what, (double)c->fov_y);
    bounds3 e = {c->eye, c->eye};
    cr_expect(inside(r->eye_box, e, 0.0f), "%s: %s: eye (%g %g %g) outside the scene", s->name, what,
              (double)c->eye.x, (double)c->eye.y, (double)c->eye.z);
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++) {
            /* off-centre on purpose: hand-placed cameras often aim along
             * edges, where a ray grazes two faces */
            vec3 d = cam_ray_dir(c, 90, 90, 16.3f + 29.1f * i, 15.7f + 29.3f * j);
            float t;
            int64_t tri = nearest_hit(s, c->eye, d, &t);
            bool centre = i == 1 && j == 1;
            if (tri < 0) {
                cr_expect(!r->closed && !centre, "%s: %s: ray (%d,%d) sees nothing", s->name, what, i, j);
                continue;
            }
            vec3 n = scene_tri_normal(s, (uint32_t)tri);
            cr_expect_lt(v3_dot(n, d), 0.0f, "%s: %s: ray (%d,%d) sees the back of triangle %lld (%s)",
                         s->name, what, i, j, (long long)tri, s->nodes[s->nodes[s->tri_node[tri]].parent].name);
            cr_expect_geq(t, r->clearance, "%s: %s: ray (%d,%d) hits %s at %g, closer than %g", s->name,
                          what, i, j, s->nodes[s->nodes[s->tri_node[tri]].parent].name, (double)t,
                          (double)r->clearance);
        }
}

/* Named cameras and path samples all obey the view rules; every path lasts
 * about 10 s. */
static void check_cameras_and_paths(const ct_scene *s, const view_rules *r, int frames)
{
    cr_assert_geq(s->ncams, 2u, "%s: at least two named cameras", s->name);
    cr_assert_geq(s->npaths, 1u, "%s: at least one path", s->name);
    for (uint32_t i = 0; i < s->ncams; i++) check_view(s, &s->cams[i].cam, r, s->cams[i].name);
    for (uint32_t p = 0; p < s->npaths; p++) {
        const ct_campath *path = &s->paths[p];
        float dur = campath_duration(path);
        cr_expect(dur >= 8.0f && dur <= 12.0f, "%s: path %s lasts %g s", s->name, path->name, (double)dur);
        for (int k = 0; k < frames; k++) {
            ct_camera c = campath_frame(path, k, frames);
            char what[96];
            snprintf(what, sizeof what, "path %s frame %d/%d", path->name, k, frames);
            check_view(s, &c, r, what);
        }
    }
}

/* The scene at path: a well-formed hierarchy and consistent normals. */
static void check_structure(const char *path)
{
    ct_scene *s = load_ok(path);
    check_hierarchy(s);
    check_normals(s);
    scene_free(s);
}

/* The scene at path: its cameras and paths (frames samples each) obey r. */
static void check_views(const char *path, const view_rules *r, int frames)
{
    ct_scene *s = load_ok(path);
    check_cameras_and_paths(s, r, frames);
    scene_free(s);
}

/* --- Cornell box ------------------------------------------------------------ */

/* scenes/gen/cornell.c's design: 12 wall quads (floor, back, left, right
 * and a 3 x 3 ceiling without its centre), the light quad, two blocks of 5
 * quads, and two UV spheres of 20 stacks x 40 slices (pole bands are
 * triangles). */
#define C_STACKS 20
#define C_SLICES 40
#define C_SPHERE_PRIMS (C_STACKS * C_SLICES)
#define C_SPHERE_TRIS (2 * C_SLICES)

Test(scenes, cornell_counts)
{
    ct_scene *s = load_ok(CORNELL);
    cr_expect_str_eq(s->name, "cornell");
    long quads = 12 + 1 + 2 * 5 + 2 * (C_SPHERE_PRIMS - C_SPHERE_TRIS);
    long prims = 12 + 1 + 2 * 5 + 2 * C_SPHERE_PRIMS;
    cr_expect_eq((long)s->nprims, prims);
    cr_expect_eq((long)s->nquads, quads);
    cr_expect_eq((long)s->ntris, 2 * quads + 2 * C_SPHERE_TRIS);
    /* root, one file, 10 objects each with one material part */
    cr_expect_eq(s->nnodes, 1u + 1u + 10u + 10u);
    cr_expect_eq(s->nemitters, 2u);   /* the light quad */
    cr_expect_eq(s->ncams, 3u);
    cr_expect_eq(s->npaths, 2u);
    expect_kinds(s, (kinds){.diffuse = 3, .ward = 1, .mirror = 1, .dielectric = 1, .emissive = 1});
    expect_matches_generator(s, "scenes/cornell/cornell.counts");
    scene_free(s);
}

Test(scenes, cornell_published_geometry)
{
    ct_scene *s = load_ok(CORNELL);
    /* Cornell Box data: x 0..556, y 0..548.8, z 0..559.2 */
    expect_bounds(s, v3(0, 0, 0), v3(556.0f, 548.8f, 559.2f), 1e-3f);
    int light = find_node(s, SCENE_NODE_GROUP, "light");
    cr_assert_geq(light, 0);
    bounds3 lb = s->nodes[light].bounds;
    cr_expect(fabsf(lb.lo.x - 213.0f) < 1e-3f && fabsf(lb.hi.x - 343.0f) < 1e-3f &&
              fabsf(lb.lo.z - 227.0f) < 1e-3f && fabsf(lb.hi.z - 332.0f) < 1e-3f &&
              fabsf(lb.lo.y - 548.8f) < 1e-3f && fabsf(lb.hi.y - 548.8f) < 1e-3f);
    cr_expect_str_eq(node_kind(s, light), "emissive");
    /* the light fills the ceiling's opening: ceiling area + light area is
     * the published 556 x 559.2 */
    int ceil_n = find_node(s, SCENE_NODE_GROUP, "ceiling");
    double area = 0;
    for (uint32_t t = s->nodes[ceil_n].tri_begin; t < s->nodes[ceil_n].tri_end; t++)
        area += scene_tri_area(s, t);
    cr_expect(fabs(area + 130.0 * 105.0 - 556.0 * 559.2) < 1.0, "ceiling area %g", area);
    const scene_named_camera *front = &s->cams[0];
    cr_expect_str_eq(front->name, "front");
    cr_expect(front->cam.eye.x == 278.0f && front->cam.eye.y == 273.0f && front->cam.eye.z == -800.0f);
    cr_expect_float_eq(front->fov_deg, 39.3f, 1e-4f);
    check_emitters_face_down(s);
    scene_free(s);
}

Test(scenes, cornell_materials)
{
    ct_scene *s = load_ok(CORNELL);
    const scene_material *l = mat(s, "light");
    cr_expect(l->emission.x == 17.0f && l->emission.y == 12.0f && l->emission.z == 4.0f);
    const scene_material *g = mat(s, "glass");
    cr_expect(g->dielectric);
    cr_expect_float_eq(g->ior, 1.5f, 1e-6f);
    cr_expect_str_eq(kind_of(s, "mirror"), "mirror");
    const scene_material *w = mat(s, "brushed_metal");
    cr_expect_eq(w->glossy, SCENE_GLOSSY_WARD);
    cr_expect(w->ward_ax < w->ward_ay, "brushed: rougher across the grooves");
    cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, "tall_block")), "ward");
    cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, "glass_sphere")), "dielectric");
    cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, "mirror_sphere")), "mirror");
    cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, "left_wall")), "diffuse");
    cr_expect_gt(mat(s, "red")->diffuse.x, mat(s, "red")->diffuse.y);
    cr_expect_gt(mat(s, "green")->diffuse.y, mat(s, "green")->diffuse.x);
    scene_free(s);
}

Test(scenes, cornell_structure)
{
    check_structure(CORNELL);
}

Test(scenes, cornell_views)
{
    /* inside the box or in front of its open side */
    view_rules r = {{{1.0f, 1.0f, -2000.0f}, {555.0f, 547.8f, 558.0f}}, false, 40.0f};
    check_views(CORNELL, &r, 61);
}

/* --- table ------------------------------------------------------------------ */

Test(scenes, table_counts)
{
    ct_scene *s = load_ok(TABLE);
    cr_expect_str_eq(s->name, "table");
    expect_matches_generator(s, "scenes/table/table.counts");
    /* "thousands of primitives": at least the paper's smallest scene */
    cr_expect_geq(s->nprims, 3500u);
    /* 22 objects: floor, ceiling, walls, 2 lights, table, hourglass frame,
     * glass and sand, 2 wine glasses, plate, 2 vases, bowl, oranges, book
     * stack, mirror, 2 chairs, bookshelf and its books */
    gen_counts c = read_counts("scenes/table/table.counts");
    cr_expect_eq(c.objects, 22);
    cr_expect_eq(c.files, 1);
    cr_expect_eq(s->nemitters, 4u);   /* two light quads */
    cr_expect_eq(s->ncams, 3u);
    cr_expect_eq(s->npaths, 2u);
    /* diffuse: floor, ceiling, walls, fixture, walnut, cushion, sand, ceramic,
     * oranges, 6 book colours; Phong: oak, 2 vase glazes */
    expect_kinds(s, (kinds){.diffuse = 15, .phong = 3, .ward = 1, .mirror = 1, .dielectric = 1,
                            .emissive = 1});
    expect_bounds(s, v3(0, 0, 0), v3(5.0f, 2.8f, 4.5f), 1e-4f);
    scene_free(s);
}

Test(scenes, table_objects)
{
    ct_scene *s = load_ok(TABLE);
    static const char *const glass[] = {"hourglass_glass", "wine_glass_1", "wine_glass_2"};
    for (int i = 0; i < 3; i++)
        cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, glass[i])), "dielectric", "%s", glass[i]);
    cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, "metal_plate")), "ward");
    cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, "vase_tall")), "phong");
    cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, "vase_round")), "phong");
    cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, "bowl")), "diffuse");
    cr_expect_str_eq(node_kind(s, child_named(s, find_node(s, SCENE_NODE_GROUP, "wall_mirror"), "mirror")),
                     "mirror");
    /* everything on the table stands on its top (y = 0.76); glass 0.5 mm
     * above what it stands on, never in the plane of an opaque face */
    static const char *const on_table[] = {"hourglass_frame", "wine_glass_1", "wine_glass_2",
                                           "metal_plate", "vase_tall", "vase_round", "bowl", "book_stack"};
    for (int i = 0; i < 8; i++) {
        int n = find_node(s, SCENE_NODE_GROUP, on_table[i]);
        cr_assert_geq(n, 0, "%s", on_table[i]);
        float lift = strncmp(on_table[i], "wine_glass", 10) == 0 ? 0.0005f : 0.0f;
        cr_expect_float_eq(s->nodes[n].bounds.lo.y, 0.76f + lift, 1e-5f, "%s", on_table[i]);
    }
    /* the hourglass' glass between its walnut discs (0.76-0.78 and
     * 1.04-1.06), 0.5 mm off both, and its sand inside the glass */
    bounds3 g = s->nodes[find_node(s, SCENE_NODE_GROUP, "hourglass_glass")].bounds;
    cr_expect_float_eq(g.lo.y, 0.7805f, 1e-5f);
    cr_expect_float_eq(g.hi.y, 1.0395f, 1e-5f);
    bounds3 sand = s->nodes[find_node(s, SCENE_NODE_GROUP, "hourglass_sand")].bounds;
    cr_expect(inside(g, sand, 0.0f));
    check_emitters_face_down(s);
    scene_free(s);
}

Test(scenes, table_structure)
{
    check_structure(TABLE);
}

Test(scenes, table_views)
{
    view_rules r = {{{0.05f, 0.05f, 0.05f}, {4.95f, 2.75f, 4.45f}}, true, 0.15f};
    check_views(TABLE, &r, 41);
}

/* --- office ------------------------------------------------------------------ */

#define O_OFFICES 8

Test(scenes, office_counts)
{
    ct_scene *s = load_ok(OFFICE);
    cr_expect_str_eq(s->name, "office");
    expect_matches_generator(s, "scenes/office/office.counts");
    /* the paper's largest scene had almost 60,000 primitives */
    cr_expect(s->nprims >= 60000u && s->nprims <= 80000u, "office: %u primitives", s->nprims);
    /* lights: per office 2 ceiling panels and 2 desk-lamp bulbs, 8 corridor
     * panels; each a quad */
    cr_expect_eq(s->nemitters, 2u * (O_OFFICES * 4u + 8u));
    cr_expect_eq(s->ncams, 4u);
    cr_expect_eq(s->npaths, 2u);
    /* diffuse: 2 carpets, ceiling, 3 paints, housing, shelf wood, 3 fabrics,
     * paper, 8 book colours, terracotta, soil, leaf = 23; Phong: linoleum,
     * desk wood, 3 plastics, screen, whiteboard, 3 shades, 2 mugs = 12;
     * Ward: brushed metal, aluminium frames; 2 emissive: panels, bulbs */
    expect_kinds(s, (kinds){.diffuse = 23, .phong = 12, .ward = 2, .mirror = 1, .dielectric = 1,
                            .emissive = 2});
    expect_bounds(s, v3(0, 0, -6.2f), v3(24.0f, 3.0f, 6.2f), 1e-4f);
    scene_free(s);
}

Test(scenes, office_rooms)
{
    ct_scene *s = load_ok(OFFICE);
    cr_assert_str_eq(s->nodes[1].name, "corridor");
    /* nine room files, each office furnished alike */
    int files = 0;
    for (uint32_t n = s->nodes[0].node_end, c = scene_first_child(s, 0); c < n; c = scene_next_sibling(s, c)) {
        cr_assert_eq(s->nodes[c].kind, SCENE_NODE_FILE);
        files++;
        if (c == 1) continue;
        char want[32];
        snprintf(want, sizeof want, "office_%d", files - 1);
        cr_expect_str_eq(s->nodes[c].name, want);
        static const char *const furniture[] = {
            "desk_1", "desk_2", "desk_1_lamp", "desk_chair_1", "meeting_table", "meeting_table_chair_4",
            "bookshelf_1", "bookshelf_3_books", "plant", "mirror", "whiteboard", "partition_glass"};
        for (int f = 0; f < 12; f++)
            cr_expect_geq(child_named(s, (int)c, furniture[f]), 0, "%s has no %s", s->nodes[c].name,
                          furniture[f]);
        /* books: more than 100 on each of the three shelves (5 faces each) */
        for (int b = 1; b <= 3; b++) {
            char name[32];
            snprintf(name, sizeof name, "bookshelf_%d_books", b);
            int g = child_named(s, (int)c, name);
            cr_assert_geq(g, 0);
            uint32_t prims = s->tri_prim[s->nodes[g].tri_end - 1] - s->tri_prim[s->nodes[g].tri_begin] + 1;
            cr_expect_gt(prims / 5, 100u, "%s/%s: %u book faces", s->nodes[c].name, name, prims);
        }
    }
    cr_expect_eq(files, 1 + O_OFFICES);
    cr_expect_str_eq(node_kind(s, find_node(s, SCENE_NODE_GROUP, "partition_glass")), "dielectric");
    cr_expect_str_eq(node_kind(s, child_named(s, find_node(s, SCENE_NODE_GROUP, "end_mirror"), "mirror")),
                     "mirror");
    check_emitters_face_down(s);
    scene_free(s);
}

Test(scenes, office_structure)
{
    check_structure(OFFICE);
}

Test(scenes, office_views, .timeout = 120)
{
    view_rules r = {{{0.05f, 0.05f, -6.15f}, {23.95f, 2.95f, 6.15f}}, true, 0.25f};
    check_views(OFFICE, &r, 31);
}
