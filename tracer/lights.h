/* lights.h: the area lights of a mesh (its emissive triangles) and how the
 * tracer samples them. Density: a triangle is picked with probability
 * proportional to its power (area * luminance of L_e; a CDF with a guide
 * table), then a point uniformly
 * by area on it, so the area-measure pdf is constant over all emitting
 * surface, weighted by brightness: p_A = lum(L_e) / sum_k(area_k lum(L_e,k)).
 * The integrator converts it to solid angle (p_A d^2 / cos_light). Emitters
 * emit from their front side only (the triangle winding's normal). */
#ifndef CT_TRACER_LIGHTS_H
#define CT_TRACER_LIGHTS_H

#include <stdbool.h>
#include <stdint.h>

#include "common/error.h"
#include "common/vecmath.h"
#include "tracer/embree_scene.h"

typedef struct light_set light_set;

/* A sampled point on an area light. */
typedef struct light_point {
    vec3 p;          /* the point */
    vec3 n;          /* front normal of its triangle */
    vec3 le;         /* emitted radiance L_e */
    float pdf_area;  /* area-measure pdf of having picked p */
    uint32_t tri;
} light_point;

/* Collects the emissive triangles of the mesh (zero lights is valid). */
int light_build(const emb_mesh *m, light_set **out, ct_error *err);

/* Releases the set (NULL is fine). */
void light_free(light_set *l);

/* Number of emissive triangles. */
uint32_t light_count(const light_set *l);

/* Index of the light triangle that u0 in [0, 1) picks (the first whose
 * cumulative power exceeds u0; a guide table makes it O(1) on average). */
uint32_t light_pick(const light_set *l, float u0);

/* Mesh triangle of light index i (UINT32_MAX when out of range). */
uint32_t light_pick_tri(const light_set *l, uint32_t i);

/* Picks a point on the lights from three uniform numbers; false when there
 * are no lights. */
bool light_sample(const light_set *l, float u0, float u1, float u2, light_point *out);

/* Area-measure pdf of light_sample picking a point on triangle tri (0 for a
 * triangle that does not emit). */
float light_pdf_area(const light_set *l, uint32_t tri);

#endif
