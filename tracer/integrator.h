/* integrator.h: the light transport of the three tracer modes (tracer.h):
 * path (NEE + MIS with the power heuristic), drt and reuse-diffuse, plus the
 * ray helpers they share (self-intersection offsets, shadow rays that pass
 * dielectrics attenuated by their transmission and Fresnel, ray counting).
 * Internal to tracer/: tracer.c owns the public API. No allocation per ray:
 * everything lives on the stack of the calling thread. The estimators are
 * in integrator.c, their direct light in integ_light.c and drt's final
 * gather in integ_gather.c (integ_internal.h joins them). */
#ifndef CT_TRACER_INTEGRATOR_H
#define CT_TRACER_INTEGRATOR_H

#include <stdbool.h>

#include "common/radmesh.h"
#include "common/rng.h"
#include "tracer/bsdf.h"
#include "tracer/embree_scene.h"
#include "tracer/lights.h"
#include "tracer/mirror_lights.h"
#include "tracer/tracer.h"

/* What one thread needs to trace one sample. */
typedef struct integ_ctx {
    const emb_scene *emb;
    const emb_mesh *mesh;
    const light_set *lights;
    const mlight_set *mirrors; /* plane mirrors as virtual lights (drt with a mesh); NULL: none */
    const vec3 *caustic;       /* per mesh vertex: reflective caustic irradiance (caustics.h); NULL: none */
    const bsdf_mat *bmats;     /* per material: its precomputed lobes */
    const ct_radmesh *rad;     /* NULL: no interactive solution */
    const trc_options *opt;
    bool has_dielectric;       /* shadow rays must look through glass (false: any glass blocks them) */
    const uint8_t *glass_bends; /* per part node: its glass blocks shadow rays (TRC_GLASS_AUTO, REFRACTED); NULL: none */
    ct_rng rng;
    trc_stats *st;
} integ_ctx;

/* A surface hit. */
typedef struct integ_surf {
    emb_hit h;
    vec3 p;            /* point on the triangle at (u, v) */
    vec3 ng;           /* front (winding) normal, unit */
    const scene_material *m;
    const bsdf_mat *bm;
    uint32_t lkey;     /* light_key at p, normal ng facing the ray */
} integ_surf;

/* Per-vertex values (radiosity) interpolated at a hit: rmesh_eval's
 * arithmetic exactly, with the vertex indices from the hit's record. */
static inline vec3 integ_vertex_lerp(const vec3 *val, const emb_hit *h)
{
    const uint32_t *i = h->rec->v;
    float u = h->u, v = h->v, w = 1.0f - u - v;
    vec3 a = val[i[0]], b = val[i[1]], c = val[i[2]];
    return v3(w * a.x + u * b.x + v * c.x, w * a.y + u * b.y + v * c.y, w * a.z + u * b.z + v * c.z);
}

/* Starts loading the per-vertex values integ_vertex_lerp will read at h (three
 * random reads into a large mesh's arrays). */
static inline void integ_vertex_prefetch(const vec3 *val, const emb_hit *h)
{
    const uint32_t *i = h->rec->v;
    __builtin_prefetch(&val[i[0]]);
    __builtin_prefetch(&val[i[1]]);
    __builtin_prefetch(&val[i[2]]);
}

/* Traces a primary ray (counted as primary); false on a miss. */
bool integ_primary(integ_ctx *c, vec3 o, vec3 d, integ_surf *s);

/* integ_primary in two halves (see emb_intersect_start): several primary
 * rays can be started before the first is finished. */
bool integ_primary_start(integ_ctx *c, vec3 o, vec3 d, emb_hit *h);
void integ_primary_finish(const integ_ctx *c, emb_hit *h, vec3 d, integ_surf *s);

/* L_base of a primary ray in direction d whose first hit is glass: what the
 * display's see-through glass shows (rmesh_material): the radiosity of the
 * first opaque surface along the straight ray (Gouraud, as integ_vertex_lerp)
 * times transmission * (1 - F) for every glass crossed before it; black when
 * the ray leaves the scene or crosses more than RMESH_MAX_GLASS_CROSSINGS
 * glass surfaces. Needs c->rad. */
vec3 integ_base_through_glass(integ_ctx *c, const emb_hit *first, vec3 d);

/* Radiance along the primary ray o + t d whose first hit is s (the mode in
 * c->opt). In reuse-diffuse mode *base receives the radiosity part (the
 * result is *base + a non-negative remainder); otherwise it is untouched. */
vec3 integ_radiance(integ_ctx *c, vec3 o, vec3 d, const integ_surf *s, vec3 *base);

#endif
