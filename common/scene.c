#include "common/scene.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Scene size limits: far beyond the paper's scenes, low enough that a hostile
 * file cannot make us allocate without bound. */
#define SCENE_MAX_VERTS (1u << 27)
#define SCENE_MAX_TRIS  (1u << 27)
#define SCENE_MAX_NODES (1u << 24)
#define SCENE_MAX_MATS  (1u << 16)

static int grow(void **p, uint32_t *cap, uint32_t need, size_t elem, uint32_t max, ct_error *err,
                const char *what)
{
    if (need <= *cap) return CT_OK;
    if (need > max) return ct_fail(err, CT_ENOMEM, "too many %s (limit %u)", what, max);
    uint32_t n = *cap ? *cap : 64;
    while (n < need) n = n > max / 2 ? max : n * 2;
    void *q = realloc(*p, (size_t)n * elem);
    if (!q) return ct_fail(err, CT_ENOMEM, "out of memory for %u %s", n, what);
    *p = q;
    *cap = n;
    return CT_OK;
}

const char *scene_material_kind(const scene_material *m)
{
    if (v3_maxc(m->emission) > 0.0f) return "emissive";
    if (m->dielectric) return "dielectric";
    if (v3_maxc(m->mirror) > 0.0f) return "mirror";
    if (m->glossy == SCENE_GLOSSY_WARD && v3_maxc(m->specular) > 0.0f) return "ward";
    if (m->glossy == SCENE_GLOSSY_PHONG && v3_maxc(m->specular) > 0.0f) return "phong";
    return "diffuse";
}

scene_material scene_material_default(const char *name)
{
    scene_material m;
    memset(&m, 0, sizeof m);
    snprintf(m.name, sizeof m.name, "%s", name ? name : "");
    m.ior = 1.0f;
    m.ward_tangent = v3(1, 0, 0);
    return m;
}

float scene_material_glossiness(const scene_material *m)
{
    /* Share of non-diffuse reflection, weighted by how sharp it is: a mirror
     * or glass changes fully with the view, a wide lobe only partly. */
    float spec = 0.0f, sharp = 0.0f;
    if (m->dielectric || v3_maxc(m->mirror) > 0.0f) return 1.0f;
    if (m->glossy == SCENE_GLOSSY_PHONG) {
        spec = v3_maxc(m->specular);
        sharp = m->phong_exp / (m->phong_exp + 10.0f);
    } else if (m->glossy == SCENE_GLOSSY_WARD) {
        spec = v3_maxc(m->specular);
        float a = 0.5f * (m->ward_ax + m->ward_ay);
        sharp = 1.0f / (1.0f + 10.0f * a);
    }
    float total = spec + v3_maxc(m->diffuse);
    if (total <= 0.0f) return 0.0f;
    return fminf(1.0f, sharp * spec / total);
}

ct_scene *scene_new(const char *name)
{
    ct_scene *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    snprintf(s->name, sizeof s->name, "%s", name ? name : "scene");
    s->bounds = b3_empty();
    s->open_depth = 0;
    if (scene_begin_node(s, s->name, SCENE_NODE_ROOT, UINT32_MAX, NULL) < 0) {
        scene_free(s);
        return NULL;
    }
    return s;
}

void scene_free(ct_scene *s)
{
    if (!s) return;
    free(s->pos);
    free(s->nrm);
    free(s->tris);
    free(s->tri_node);
    free(s->tri_mat);
    free(s->tri_prim);
    free(s->nodes);
    free(s->mats);
    free(s->cams);
    for (uint32_t i = 0; i < s->npaths; i++) campath_free(&s->paths[i]);
    free(s->paths);
    free(s->emitters);
    free(s);
}

int scene_add_material(ct_scene *s, const scene_material *m, ct_error *err)
{
    int rc = grow((void **)&s->mats, &s->cap_mats, s->nmats + 1, sizeof *s->mats, SCENE_MAX_MATS,
                  err, "materials");
    if (rc) return rc;
    s->mats[s->nmats] = *m;
    return (int)s->nmats++;
}

int scene_find_material(const ct_scene *s, const char *name)
{
    for (uint32_t i = 0; i < s->nmats; i++)
        if (strcmp(s->mats[i].name, name) == 0) return (int)i;
    return -1;
}

int scene_begin_node(ct_scene *s, const char *name, scene_node_kind kind, uint32_t material,
                     ct_error *err)
{
    if (s->open_depth >= (int)(sizeof s->open_stack / sizeof s->open_stack[0]))
        return ct_fail(err, CT_ERANGE, "node hierarchy deeper than %d levels",
                       (int)(sizeof s->open_stack / sizeof s->open_stack[0]));
    if (kind == SCENE_NODE_ROOT && s->nnodes != 0)
        return ct_fail(err, CT_EINVAL, "a scene has one root node");
    if (kind != SCENE_NODE_ROOT && s->open_depth == 0)
        return ct_fail(err, CT_EINVAL, "node '%s' has no open parent", name);
    if (s->open_depth > 0 && s->nodes[s->open_stack[s->open_depth - 1]].kind == SCENE_NODE_PART)
        return ct_fail(err, CT_EINVAL, "node '%s': a mesh part cannot have children", name);
    if (kind == SCENE_NODE_PART && material >= s->nmats)
        return ct_fail(err, CT_ERANGE, "node '%s': material %u out of range", name, material);
    int rc = grow((void **)&s->nodes, &s->cap_nodes, s->nnodes + 1, sizeof *s->nodes,
                  SCENE_MAX_NODES, err, "nodes");
    if (rc) return rc;
    scene_node *n = &s->nodes[s->nnodes];
    memset(n, 0, sizeof *n);
    snprintf(n->name, sizeof n->name, "%s", name ? name : "");
    n->kind = kind;
    n->parent = s->open_depth ? s->open_stack[s->open_depth - 1] : -1;
    n->tri_begin = n->tri_end = s->ntris;
    n->node_end = s->nnodes + 1;
    n->material = kind == SCENE_NODE_PART ? material : UINT32_MAX;
    n->bounds = b3_empty();
    s->open_stack[s->open_depth++] = (int32_t)s->nnodes;
    return (int)s->nnodes++;
}

int scene_end_node(ct_scene *s, ct_error *err)
{
    if (s->open_depth <= 0) return ct_fail(err, CT_EINVAL, "no open node to close");
    uint32_t id = (uint32_t)s->open_stack[--s->open_depth];
    scene_node *n = &s->nodes[id];
    n->node_end = s->nnodes;
    n->tri_end = s->ntris;
    bounds3 b = b3_empty();
    if (n->kind == SCENE_NODE_PART) {
        for (uint32_t t = n->tri_begin; t < n->tri_end; t++)
            for (int k = 0; k < 3; k++) b = b3_add(b, s->pos[s->tris[3 * t + k]]);
    } else {
        for (uint32_t c = id + 1; c < n->node_end; c = s->nodes[c].node_end)
            b = b3_union(b, s->nodes[c].bounds);
    }
    n->bounds = b;
    return CT_OK;
}

int64_t scene_add_vertex(ct_scene *s, vec3 pos, vec3 nrm, ct_error *err)
{
    if (!v3_in_range(pos))
        return ct_fail(err, CT_ERANGE, "vertex (%g, %g, %g) not finite or outside the coordinate range +-%g",
                       (double)pos.x, (double)pos.y, (double)pos.z, (double)CT_COORD_MAX);
    uint32_t cap = s->cap_verts;
    int rc = grow((void **)&s->pos, &cap, s->nverts + 1, sizeof *s->pos, SCENE_MAX_VERTS, err,
                  "vertices");
    if (rc) return rc;
    if (cap != s->cap_verts) {
        void *q = realloc(s->nrm, (size_t)cap * sizeof *s->nrm);
        if (!q) return ct_fail(err, CT_ENOMEM, "out of memory for %u vertices", cap);
        s->nrm = q;
        s->cap_verts = cap;
    }
    s->pos[s->nverts] = pos;
    s->nrm[s->nverts] = nrm;
    return (int64_t)s->nverts++;
}

static int add_triangle(ct_scene *s, uint32_t a, uint32_t b, uint32_t c, uint32_t part,
                        uint32_t prim, ct_error *err)
{
    vec3 e1 = v3_sub(s->pos[b], s->pos[a]), e2 = v3_sub(s->pos[c], s->pos[a]);
    vec3 n = v3_cross(e1, e2);
    float l2 = v3_len2(n);
    float scale = fmaxf(v3_len2(e1), v3_len2(e2));
    /* Zero or sliver area relative to the edge lengths: no surface to hit. */
    if (!(l2 > 1e-14f * scale * scale) || !isfinite(l2)) {
        s->dropped_degenerate++;
        return 0;
    }
    uint32_t cap = s->cap_tris;
    int rc = grow((void **)&s->tri_node, &cap, s->ntris + 1, sizeof(uint32_t), SCENE_MAX_TRIS,
                  err, "triangles");
    if (rc) return rc;
    if (cap != s->cap_tris) {
        void *t1 = realloc(s->tris, (size_t)cap * 3 * sizeof(uint32_t));
        if (t1) s->tris = t1;
        void *t2 = realloc(s->tri_mat, (size_t)cap * sizeof(uint32_t));
        if (t2) s->tri_mat = t2;
        void *t3 = realloc(s->tri_prim, (size_t)cap * sizeof(uint32_t));
        if (t3) s->tri_prim = t3;
        if (!t1 || !t2 || !t3) return ct_fail(err, CT_ENOMEM, "out of memory for %u triangles", cap);
        s->cap_tris = cap;
    }
    uint32_t t = s->ntris++;
    s->tris[3 * t] = a;
    s->tris[3 * t + 1] = b;
    s->tris[3 * t + 2] = c;
    s->tri_node[t] = part;
    s->tri_mat[t] = s->nodes[part].material;
    s->tri_prim[t] = prim;
    return 1;
}

vec3 scene_polygon_normal(const ct_scene *s, const uint32_t *idx, int n)
{
    vec3 nn = v3s(0);
    for (int i = 0; i < n; i++) {
        vec3 a = s->pos[idx[i]], b = s->pos[idx[(i + 1) % n]];
        nn.x += (a.y - b.y) * (a.z + b.z);
        nn.y += (a.z - b.z) * (a.x + b.x);
        nn.z += (a.x - b.x) * (a.y + b.y);
    }
    return v3_norm(nn);
}

/* Concave polygons are cut into ears (triangles whose corner turns the
 * polygon's way and holds no other vertex) rather than fanned: a fan of a
 * ring-shaped n-gon covered its hole. Not aiProcess_Triangulate: it would
 * forget which triangles form one input polygon (tri_prim, which radiosity
 * patches and the primitive counts read), and lights' quads never pass
 * through assimp. The ear test scans the remaining vertices, O(n^2) per
 * polygon at worst; larger concave polygons are refused. */
#define SCENE_MAX_EAR_VERTS 1024

/* Twice the signed area of the projected triangle (a, b, c). */
static double turn(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* The polygon's vertices in the plane of its normal n, counter-clockwise
 * seen from n's side (uv, 2n values); whether every corner turns that way
 * (within a relative tolerance, so a slightly bent convex quad stays a fan). */
static bool project_polygon(const ct_scene *s, const uint32_t *idx, int n, vec3 nrm, double *uv)
{
    int k = fabsf(nrm.x) > fabsf(nrm.y) ? (fabsf(nrm.x) > fabsf(nrm.z) ? 0 : 2) : (fabsf(nrm.y) > fabsf(nrm.z) ? 1 : 2);
    float sign = v3_get(nrm, k) < 0.0f ? -1.0f : 1.0f;
    for (int i = 0; i < n; i++) {
        vec3 p = s->pos[idx[i]];
        uv[2 * i] = v3_get(p, (k + 1) % 3);
        uv[2 * i + 1] = sign * v3_get(p, (k + 2) % 3);
    }
    bool convex = true;
    for (int i = 0; i < n && convex; i++) {
        const double *a = uv + 2 * ((i + n - 1) % n), *b = uv + 2 * i, *c = uv + 2 * ((i + 1) % n);
        double ab = hypot(b[0] - a[0], b[1] - a[1]), bc = hypot(c[0] - b[0], c[1] - b[1]);
        convex = turn(a, b, c) >= -1e-6 * ab * bc;
    }
    return convex;
}

static bool same_point(const double *a, const double *b) { return a[0] == b[0] && a[1] == b[1]; }

/* Whether corner i (between prev a and next c) of the remaining ring is an
 * ear. Vertices at the same place as a corner (the two sides of a bridge
 * into a hole) do not block it. */
static bool is_ear(const double *uv, const int *next, int a, int i, int c)
{
    const double *pa = uv + 2 * a, *pb = uv + 2 * i, *pc = uv + 2 * c;
    if (!(turn(pa, pb, pc) > 0.0)) return false;
    for (int j = next[c]; j != a; j = next[j]) {
        const double *q = uv + 2 * j;
        if (same_point(q, pa) || same_point(q, pb) || same_point(q, pc)) continue;
        if (turn(pa, pb, q) >= 0.0 && turn(pb, pc, q) >= 0.0 && turn(pc, pa, q) >= 0.0) return false;
    }
    return true;
}

static int ear_clip(ct_scene *s, const uint32_t *idx, int n, const double *uv, uint32_t part, int *added,
                    ct_error *err)
{
    int *next = malloc((size_t)n * 2 * sizeof *next);
    if (!next) return ct_fail(err, CT_ENOMEM, "out of memory for a polygon of %d vertices", n);
    int *prev = next + n;
    for (int i = 0; i < n; i++) {
        next[i] = (i + 1) % n;
        prev[i] = (i + n - 1) % n;
    }
    int m = n, i = 0, misses = 0, rc = 0;
    while (m > 3 && rc >= 0) {
        int a = prev[i], c = next[i];
        if (!is_ear(uv, next, a, i, c)) {
            i = c;
            /* A full round without an ear: the polygon crosses itself. */
            if (++misses > m) break;
            continue;
        }
        rc = add_triangle(s, idx[a], idx[i], idx[c], part, s->nprims, err);
        *added += rc > 0;
        next[a] = c;
        prev[c] = a;
        m--;
        misses = 0;
        i = a;
    }
    /* The last triangle, or a fan of what a self-crossing polygon left. */
    for (int b = next[i]; rc >= 0 && next[b] != i; b = next[b]) {
        rc = add_triangle(s, idx[i], idx[b], idx[next[b]], part, s->nprims, err);
        *added += rc > 0;
    }
    free(next);
    return rc < 0 ? rc : 0;
}

int scene_add_polygon(ct_scene *s, const uint32_t *idx, int n, ct_error *err)
{
    if (s->open_depth <= 0 || s->nodes[s->open_stack[s->open_depth - 1]].kind != SCENE_NODE_PART)
        return ct_fail(err, CT_EINVAL, "polygon outside a mesh part");
    if (n < 3) return ct_fail(err, CT_EINVAL, "polygon with %d vertices", n);
    for (int i = 0; i < n; i++)
        if (idx[i] >= s->nverts)
            return ct_fail(err, CT_ERANGE, "vertex index %u out of range (%u vertices)", idx[i],
                           s->nverts);
    uint32_t part = (uint32_t)s->open_stack[s->open_depth - 1];
    int added = 0;
    double small[2 * 64], *uv = n <= 64 ? small : malloc((size_t)n * 2 * sizeof *uv);
    if (!uv) return ct_fail(err, CT_ENOMEM, "out of memory for a polygon of %d vertices", n);
    bool convex = n == 3 || project_polygon(s, idx, n, scene_polygon_normal(s, idx, n), uv);
    int rc = 0;
    if (convex) {
        for (int i = 1; i + 1 < n && rc >= 0; i++) {
            rc = add_triangle(s, idx[0], idx[i], idx[i + 1], part, s->nprims, err);
            added += rc > 0;
        }
    } else if (n > SCENE_MAX_EAR_VERTS) {
        rc = ct_fail(err, CT_ERANGE, "concave polygon of %d vertices (at most %d are triangulated)", n,
                     SCENE_MAX_EAR_VERTS);
    } else {
        rc = ear_clip(s, idx, n, uv, part, &added, err);
    }
    if (uv != small) free(uv);
    if (rc < 0) return rc;
    if (added > 0) {
        s->nprims++;
        if (n == 4) s->nquads++;
    }
    return CT_OK;
}

int scene_add_camera(ct_scene *s, const char *name, vec3 eye, vec3 target, vec3 up,
                     float fov_deg, ct_error *err)
{
    if (!v3_finite(eye) || !v3_finite(target) || !v3_finite(up) || !isfinite(fov_deg))
        return ct_fail(err, CT_EINVAL, "camera '%s': non-finite value", name);
    if (!v3_in_range(eye) || !v3_in_range(target))
        return ct_fail(err, CT_ERANGE, "camera '%s': eye or target outside the coordinate range +-%g", name,
                       (double)CT_COORD_MAX);
    if (v3_len2(v3_sub(target, eye)) <= 0.0f)
        return ct_fail(err, CT_EINVAL, "camera '%s': eye and target coincide", name);
    if (!cam_fov_deg_valid(fov_deg))
        return ct_fail(err, CT_EINVAL, "camera '%s': fov %.7g outside [%g, %g] degrees", name, (double)fov_deg,
                       (double)CT_FOV_DEG_MIN, (double)CT_FOV_DEG_MAX);
    if (scene_find_camera(s, name) >= 0)
        return ct_fail(err, CT_EINVAL, "camera '%s' defined twice", name);
    void *q = realloc(s->cams, (size_t)(s->ncams + 1) * sizeof *s->cams);
    if (!q) return ct_fail(err, CT_ENOMEM, "out of memory");
    s->cams = q;
    scene_named_camera *c = &s->cams[s->ncams++];
    memset(c, 0, sizeof *c);
    snprintf(c->name, sizeof c->name, "%s", name);
    c->cam = cam_look_at(eye, target, up, fov_deg);
    c->target = target;
    c->up = up;
    c->fov_deg = fov_deg;
    return CT_OK;
}

int scene_add_path(ct_scene *s, ct_campath *p, ct_error *err)
{
    if (scene_find_path(s, p->name) >= 0)
        return ct_fail(err, CT_EINVAL, "camera path '%s' defined twice", p->name);
    void *q = realloc(s->paths, (size_t)(s->npaths + 1) * sizeof *s->paths);
    if (!q) return ct_fail(err, CT_ENOMEM, "out of memory");
    s->paths = q;
    s->paths[s->npaths++] = *p;
    memset(p, 0, sizeof *p);
    return CT_OK;
}

int scene_finalize(ct_scene *s, ct_error *err)
{
    while (s->open_depth > 0) {
        int rc = scene_end_node(s, err);
        if (rc) return rc;
    }
    if (s->ntris == 0) return ct_fail(err, CT_EEMPTY, "scene has no triangles");
    s->bounds = s->nodes[0].bounds;
    free(s->emitters);
    s->emitters = NULL;
    s->nemitters = 0;
    uint32_t n = 0;
    for (uint32_t t = 0; t < s->ntris; t++)
        if (v3_maxc(s->mats[s->tri_mat[t]].emission) > 0.0f) n++;
    if (n) {
        s->emitters = malloc((size_t)n * sizeof *s->emitters);
        if (!s->emitters) return ct_fail(err, CT_ENOMEM, "out of memory");
        for (uint32_t t = 0; t < s->ntris; t++)
            if (v3_maxc(s->mats[s->tri_mat[t]].emission) > 0.0f) s->emitters[s->nemitters++] = t;
    }
    return CT_OK;
}

int scene_find_camera(const ct_scene *s, const char *name)
{
    for (uint32_t i = 0; i < s->ncams; i++)
        if (strcmp(s->cams[i].name, name) == 0) return (int)i;
    return -1;
}

int scene_find_path(const ct_scene *s, const char *name)
{
    for (uint32_t i = 0; i < s->npaths; i++)
        if (strcmp(s->paths[i].name, name) == 0) return (int)i;
    return -1;
}

const ct_campath *scene_path_or_file(const ct_scene *s, const char *scene_file, const char *name, ct_campath *own,
                                     ct_error *err)
{
    int pi = scene_find_path(s, name);
    if (pi >= 0) return &s->paths[pi];
    int rc = campath_load(name, own, err);
    if (!rc) return own;
    ct_error why = *err;
    ct_fail(err, rc, "path '%s' is neither a path of %s nor a readable path file (%s)", name, scene_file, why.msg);
    return NULL;
}

vec3 scene_tri_normal(const ct_scene *s, uint32_t t)
{
    const uint32_t *i = s->tris + 3 * (size_t)t;
    return v3_norm(v3_cross(v3_sub(s->pos[i[1]], s->pos[i[0]]), v3_sub(s->pos[i[2]], s->pos[i[0]])));
}

float scene_tri_area(const ct_scene *s, uint32_t t)
{
    const uint32_t *i = s->tris + 3 * (size_t)t;
    return 0.5f * v3_len(v3_cross(v3_sub(s->pos[i[1]], s->pos[i[0]]), v3_sub(s->pos[i[2]], s->pos[i[0]])));
}

uint32_t scene_first_child(const ct_scene *s, uint32_t n)
{
    return n + 1 < s->nodes[n].node_end ? n + 1 : s->nodes[n].node_end;
}

uint32_t scene_next_sibling(const ct_scene *s, uint32_t c)
{
    return s->nodes[c].node_end;
}
