/* embree_scene.h: the Embree 3 scene the tracer intersects, built from a
 * corrtex scene or from a radiosity mesh (the interactive solution that
 * tracer ranks must hit so L_base is interpolated on the very triangle GL
 * draws). One Embree geometry per mesh part node; geomID and primID map back
 * to the mesh triangle, its part node and its material. Embree device errors
 * are routed into ct_error. The scene is read-only after emb_new, so any
 * number of threads may query it at once. */
#ifndef CT_TRACER_EMBREE_SCENE_H
#define CT_TRACER_EMBREE_SCENE_H

#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "common/error.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/vecmath.h"

/* A read-only view of the triangles to intersect and their materials. The
 * arrays belong to the scene or radiosity mesh it was made from. */
typedef struct emb_mesh {
    uint32_t nverts;
    const vec3 *pos, *nrm;
    uint32_t ntris;
    const uint32_t *tris;      /* 3 vertex indices per triangle */
    const uint32_t *tri_node;  /* part node per triangle */
    const uint32_t *tri_mat;   /* material per triangle */
    uint32_t nnodes;
    uint32_t nmats;
    const scene_material *mats;
    bool vertex_reads;         /* hits read per-vertex values (a radiosity mesh) */
} emb_mesh;

/* The view of a scene's own triangles. */
emb_mesh emb_mesh_of_scene(const ct_scene *s);

/* The view of a radiosity mesh's triangles with the scene's materials. */
emb_mesh emb_mesh_of_radmesh(const ct_radmesh *m, const ct_scene *s);

/* What shading needs of one triangle, stored in Embree's (geomID, primID)
 * order at build: a hit reads this one record (128 bytes, two aligned cache
 * lines) instead of the order, node, material, index, position and normal
 * arrays (up to ten scattered cache misses per hit on a large mesh). The
 * first line holds what every hit needs; the second, the vertex normals and
 * indices, is loaded only for triangles with curved shading normals and on
 * meshes whose hits read per-vertex values: on office 60 % of the hits of
 * path tracing then touch one line instead of two. */
typedef struct emb_tri {
    vec3 a, e1, e2;     /* vertex 0 and the edges to vertices 1 and 2 */
    vec3 ng;            /* unit front (winding) normal */
    uint32_t tri;       /* mesh triangle */
    uint32_t node;      /* its part node */
    uint32_t mat;       /* its material */
    uint32_t flat;      /* 1: the shading normal is ng (no vertex normals, or
                         * all three within 1e-6 of ng) */
    /* second cache line */
    vec3 na, nb, nc;    /* vertex normals (unused when flat) */
    uint32_t v[3];      /* its vertex indices (per-vertex data: radiosity) */
    uint32_t pad[4];    /* to 128 bytes */
} emb_tri;

/* A ray hit mapped back to the mesh. */
typedef struct emb_hit {
    float t, u, v;      /* distance, Embree barycentrics */
    uint32_t tri;       /* mesh triangle */
    uint32_t node;      /* its part node */
    uint32_t mat;       /* its material */
    const emb_tri *rec; /* the triangle's record */
} emb_hit;

typedef struct emb_scene emb_scene;

/* Validates the mesh (indices, materials, finite positions) and builds the
 * Embree scene (high build quality, robust mode off). device_config is passed
 * to rtcNewDevice (NULL or "" for Embree's defaults). */
int emb_new(const emb_mesh *mesh, const char *device_config, emb_scene **out, ct_error *err);

/* Releases the Embree scene and device (NULL is fine). */
void emb_free(emb_scene *e);

/* The mesh the scene was built from. */
const emb_mesh *emb_get_mesh(const emb_scene *e);

/* Closest hit of the ray o + t d, t in (tnear, tfar); false on a miss. */
bool emb_intersect(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar, emb_hit *hit);

/* emb_intersect in two halves: _start finds the closest hit, sets t, u, v
 * and rec and starts loading the record (a cache miss on a large mesh);
 * emb_hit_finish reads tri, node and mat from it. Starting several rays
 * before finishing any overlaps their misses (the tracer's primary rays). */
bool emb_intersect_start(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar, emb_hit *hit);
static inline void emb_hit_finish(emb_hit *hit)
{
    hit->tri = hit->rec->tri;
    hit->node = hit->rec->node;
    hit->mat = hit->rec->mat;
}

/* True when anything blocks o + t d for t in (tnear, tfar). */
bool emb_occluded(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar);

/* Occlusion of n <= 8 rays o[i] + t d[i], t in (0, tfar[i]), into blocked[i]:
 * one rtcOccluded4/8 packet query for n > 1 (rays that share an origin, as
 * a shading point's shadow rays do, traverse the BVH together), the same
 * answers as emb_occluded ray by ray. */
void emb_occluded_batch(const emb_scene *e, int n, const vec3 *o, const vec3 *d, const float *tfar,
                        bool *blocked);

/* Raw rtcIntersect1 without mapping the hit back (benchmark baseline); returns
 * the hit distance or INFINITY. */
float emb_raw_intersect(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar);

/* Raw rtcOccluded1 (benchmark baseline). */
bool emb_raw_occluded(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar);

/* Unit shading normal of a hit: the vertex normals interpolated at its
 * barycentrics and normalized, or the face normal ng for a flat record
 * (emb_tri) and where the interpolation degenerates. Shading asks for it
 * only where a bsdf is set up. */
vec3 emb_shading_normal(const emb_hit *h);

/* Point of a hit at its barycentrics. */
static inline vec3 emb_hit_point(const emb_hit *h)
{
    const emb_tri *r = h->rec;
    return v3_add(r->a, v3_add(v3_scale(r->e1, h->u), v3_scale(r->e2, h->v)));
}

/* Offsets a point along n past the float error of the intersection (Waechter
 * & Binder, Ray Tracing Gems ch. 6): integer ULP steps far from the origin,
 * a small absolute step near it. Scale independent, so no scene-size epsilon. */
static inline vec3 emb_offset_ray(vec3 p, vec3 n)
{
    const float origin = 1.0f / 32.0f, float_scale = 1.0f / 65536.0f, int_scale = 256.0f;
    float pc[3] = {p.x, p.y, p.z}, nc[3] = {n.x, n.y, n.z}, out[3];
    for (int i = 0; i < 3; i++) {
        int32_t of = (int32_t)(int_scale * nc[i]), bits;
        memcpy(&bits, &pc[i], sizeof bits);
        bits += pc[i] < 0.0f ? -of : of;
        float moved;
        memcpy(&moved, &bits, sizeof moved);
        out[i] = fabsf(pc[i]) < origin ? pc[i] + float_scale * nc[i] : moved;
    }
    return v3(out[0], out[1], out[2]);
}

/* Geometric normal of mesh triangle t (unit; winding e1 x e2 = front side). */
vec3 emb_tri_normal(const emb_mesh *m, uint32_t t);

/* Area of mesh triangle t. */
float emb_tri_area(const emb_mesh *m, uint32_t t);

/* Point of triangle t at barycentrics (u, v), computed from the vertices. */
vec3 emb_tri_point(const emb_mesh *m, uint32_t t, float u, float v);

#endif
