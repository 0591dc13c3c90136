/* lights.h: the area lights of a mesh (its emissive triangles) and how the
 * tracer samples them.
 *
 * Lights are grouped into emitters (the emissive triangles of one mesh part:
 * a ceiling panel, a bulb). A shading point x first picks an emitter, then
 * one of its triangles by power (area * luminance of L_e), then a point
 * uniformly by area on it. The emitter is picked from a mixture:
 *   - with probability 1 - LIGHT_DEFENSIVE among x's candidates, in
 *     proportion to their estimated contribution at x,
 *       power * cos_light / max(d^2, r^2) * (beta + (1 - beta) * V),
 *     cos_light and d taken to the emitter's centre (zero behind a flat
 *     emitter, which emits from its front side only), r its bounding radius,
 *     V the fraction of test rays that nothing but glass blocks between the
 *     emitter and points of the surfaces in x's grid cell that face the way
 *     x's surface faces, beta = LIGHT_VIS_FLOOR;
 *   - with probability LIGHT_DEFENSIVE among all emitters by power (every
 *     emitter keeps a positive density: the estimator stays unbiased).
 * The candidates of a (cell, side) are its LIGHT_CANDS strongest emitters by
 * that estimate at the cell centre, leaving out those under
 * LIGHT_CAND_MIN_SHARE of the sum over all emitters, made the first time the
 * cell and side is used (deterministically). So
 * p_A(y | x) = P(emitter | x) * lum(L_e(y)) / power(emitter). Without a
 * shading point (or with one emitter, or more than LIGHT_SEL_MAX) the
 * emitter is picked by power alone.
 *
 * The per-point choice costs a grid lookup (a cache miss) and the weighing
 * of the candidates at every shading point: about 13 % of path tracing's
 * time on a scene of two like panels over one room, where it lowered the
 * image error by about 1 %. So light_build first estimates what it can gain
 * (light_spatial_gain: over surface points, how much the power choice
 * raises the second moment of the emitter choice, 1 = nothing) and picks by
 * power alone below LIGHT_SPATIAL_MIN_GAIN (lights.c).
 *
 * This matters in scenes of many rooms: picking by power alone sends most
 * shadow rays of a point in one office to the lights of the others. */
#ifndef CT_TRACER_LIGHTS_H
#define CT_TRACER_LIGHTS_H

#include <stdbool.h>
#include <stdint.h>

#include "common/error.h"
#include "common/vecmath.h"
#include "tracer/embree_scene.h"

/* Most emitters the spatial selection handles; scenes with more pick by power. */
#define LIGHT_SEL_MAX 255
/* Emitters weighed at each shading point (a cell's strongest). */
#define LIGHT_CANDS 16
/* Emitters below this share of a cell's summed estimate are no candidates
 * (they keep the defensive share). */
#define LIGHT_CAND_MIN_SHARE 0.01f
/* Share of emitter picks by power among all emitters (the defensive part). */
#define LIGHT_DEFENSIVE 0.02f
/* beta: the visibility estimate's floor (see above). */
#define LIGHT_VIS_FLOOR 0.05f
/* Rays per (grid cell, emitter) of the visibility estimate. */
#define LIGHT_VIS_RAYS 8

typedef struct light_set light_set;

/* A sampled point on an area light. */
typedef struct light_point {
    vec3 p;          /* the point */
    vec3 n;          /* front normal of its triangle */
    vec3 le;         /* emitted radiance L_e */
    float pdf_area;  /* area-measure pdf of having picked p (for the selection used) */
    uint32_t tri;
} light_point;

/* The emitter probabilities at one shading point, made once and used by all
 * of its shadow rays and by the MIS weight of light found by its scattered
 * rays. */
typedef struct light_sel {
    uint32_t n;                     /* candidates; 0 = pick by power alone */
    float defensive;                /* share picked by power (1 when no candidate can light x) */
    uint8_t idx[LIGHT_CANDS];       /* the candidates' emitters */
    float cdf[LIGHT_CANDS + 1];     /* among the candidates, normalised */
} light_sel;

/* Collects the emissive triangles of the scene's mesh (zero lights is
 * valid). The set keeps e for its visibility estimates; e must outlive it. */
int light_build(const emb_scene *e, light_set **out, ct_error *err);

/* Releases the set (NULL is fine). */
void light_free(light_set *l);

/* Number of emissive triangles. */
uint32_t light_count(const light_set *l);

/* Number of emitters (emissive mesh parts). */
uint32_t light_emitters(const light_set *l);

/* Whether shading points pick emitters by their own weights (false: by
 * power alone, see above). */
bool light_is_spatial(const light_set *l);

/* The estimated gain of the per-point choice over the power choice (>= 1),
 * or 0 where it is not estimated: fewer than two emitters, or more than
 * LIGHT_SEL_MAX (both pick by power). */
double light_spatial_gain(const light_set *l);

/* Fills sel with the emitter probabilities at x on a surface with normal n
 * (the side of a wall matters). Thread-safe: a cell's visibility estimate is
 * a pure function of the cell and side, so threads that race to make it
 * compute the same values. */
void light_select(const light_set *l, vec3 x, vec3 n, light_sel *sel);

/* The visibility-grid key of x on a surface with normal n (LIGHT_NO_KEY
 * without a grid); starts loading the key's data, far away in memory for a
 * random point: call it as soon as a hit is known, select later. */
#define LIGHT_NO_KEY UINT32_MAX
uint32_t light_key(const light_set *l, vec3 x, vec3 n);

/* light_select with x's key from light_key (same n). */
void light_select_key(const light_set *l, uint32_t key, vec3 x, light_sel *sel);

/* sel for picking by power alone (no shading point). */
void light_select_power(light_sel *sel);

/* Picks a point on the lights from three uniform numbers; false when there
 * are no lights (or none can light x). */
bool light_sample(const light_set *l, const light_sel *sel, float u0, float u1, float u2, light_point *out);

/* Area-measure pdf of light_sample picking a point on triangle tri under sel
 * (0 for a triangle that does not emit). */
float light_pdf_area(const light_set *l, const light_sel *sel, uint32_t tri);

#endif
