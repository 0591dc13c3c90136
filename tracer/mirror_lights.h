/* mirror_lights.h: the planar mirrors of a mesh as virtual lights, so that
 * drt's shadow rays find the light a mirror reflects onto diffuse surfaces.
 *
 * drt takes diffuse light from two places: shadow rays to the lights, and
 * the radiosity solution (read at the hit or gathered). Neither has the
 * light that reaches a diffuse surface from a lamp by way of a mirror: a
 * shadow ray is blocked by the mirror, and the radiosity solution has no
 * specular transport. On `table` that light is most of what the floor under
 * the table receives (docs/tracer.md, "Indirect light"). A scattered ray
 * finds it only by hitting the lamp's mirror image, rarely and brightly (a
 * caustic: fireflies), so the gather leaves it out; here it is sampled the
 * way a real light is. A plane mirror maps the lamp to its mirror image
 * behind the plane; a point x in front of the mirror sees the image through
 * the mirror, so a point y on the lamp picked as for a shadow ray, mirrored
 * to y', gives the direction and distance of the path x -> mirror -> y (the
 * reflection keeps solid angle). The path counts when the mirror is really
 * there where x -> y' crosses the plane and nothing blocks either leg.
 *
 * A mirror here is the triangles of one part node and one material with a
 * mirror layer that lie in one plane; a node whose mirror triangles need
 * more than MLIGHT_NODE_PLANES planes (a tessellated sphere) has none: the
 * images of its small facets would cost work for little light. At most
 * MLIGHT_MAX mirrors, the largest by area. A shading point samples them
 * by the solid angle each fills (mlight_weight). */
#ifndef CT_TRACER_MIRROR_LIGHTS_H
#define CT_TRACER_MIRROR_LIGHTS_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "common/error.h"
#include "common/rng.h"
#include "common/vecmath.h"
#include "tracer/embree_scene.h"
#include "tracer/lights.h"

/* Most mirrors whose images are sampled. */
#define MLIGHT_MAX 32
/* Most planes the mirror triangles of one part node and material may span. */
#define MLIGHT_NODE_PLANES 8

/* One plane mirror. */
typedef struct mlight_plane {
    vec3 n;             /* unit normal (the first triangle's front side) */
    float d;            /* the plane: dot(n, p) = d */
    vec3 u, v;          /* unit axes in the plane */
    float u0, u1, v0, v1;   /* the mirror's bounds along them (a little grown) */
    uint32_t mat;       /* its material */
    vec3 rho;           /* its mirror reflectance */
    float area;
    vec3 c;             /* its centre (area-weighted) */
    float r2;           /* squared radius of a disc of its area */
    light_sel sel[2];   /* the lamp choice of points on its front (0) and back (1) side:
                         * the lamps its centre sees from that side */
} mlight_plane;

typedef struct mlight_set mlight_set;

/* Finds the mesh's plane mirrors and each one's lamp choice (copied: the
 * set does not keep lights). A mesh without any gives an empty set. */
int mlight_build(const emb_scene *e, const light_set *lights, mlight_set **out, ct_error *err);

/* Releases the set (NULL is fine). */
void mlight_free(mlight_set *s);

/* Number of mirrors. */
uint32_t mlight_count(const mlight_set *s);

/* Mirror i (i < mlight_count). */
const mlight_plane *mlight_get(const mlight_set *s, uint32_t i);

/* Whether material m can make a mirror: a mirror layer, not glass. */
static inline bool mlight_material(const scene_material *m)
{
    return (m->mirror.x > 0.0f || m->mirror.y > 0.0f || m->mirror.z > 0.0f) && !m->dielectric;
}

/* Signed distance of p from the mirror's plane. */
static inline float mlight_side(const mlight_plane *m, vec3 p) { return v3_dot(m->n, p) - m->d; }

/* The share of the mirror samples of a point x that mirror m gets (before
 * normalising over the mirrors): the solid angle the mirror fills seen from
 * x, area * cos / d^2 with d^2 kept at least r2 (the estimate of a disc:
 * finite next to the mirror, as light_select's is next to a lamp); 0 on
 * the plane. Cheap and positive wherever m could reflect light to x. */
static inline float mlight_weight(const mlight_plane *m, vec3 x)
{
    vec3 dv = v3_sub(x, m->c);
    float d2 = v3_len2(dv), cs = fabsf(v3_dot(dv, m->n));
    float q = d2 > m->r2 ? d2 : m->r2;
    return m->area * cs / (q * sqrtf(q));
}

/* Whether the point q of the plane lies within the mirror's bounds (a
 * quick test: the ray that follows decides). */
static inline bool mlight_in_bounds(const mlight_plane *m, vec3 q)
{
    float a = v3_dot(m->u, q), b = v3_dot(m->v, q);
    return a >= m->u0 && a <= m->u1 && b >= m->v0 && b <= m->v1;
}

/* Whether a surface of material mat with normal n (either side) is parallel
 * to mirror m and of its material: what being part of the mirror needs
 * besides lying in its plane. */
static inline bool mlight_same_kind(const mlight_plane *m, uint32_t mat, vec3 n)
{
    float c = v3_dot(n, m->n);
    return mat == m->mat && (c > 0.9999f || c < -0.9999f);
}

/* Whether a ray's hit h at distance near t_plane is the mirror itself
 * (its material, its plane) and not something in front of it. */
static inline bool mlight_is_mirror_hit(const mlight_plane *m, const emb_hit *h, float t_plane)
{
    return mlight_same_kind(m, h->mat, h->rec->ng) &&
           fabsf(h->t - t_plane) <= 1e-4f * (t_plane > 1.0f ? t_plane : 1.0f);
}

/* The mirror weights at x (mlight_weight) as a running sum in cdf
 * (MLIGHT_MAX entries); returns the total (0: no mirror can light x). */
float mlight_cdf(const mlight_set *s, vec3 x, float *cdf);

/* A lamp point seen in a mirror from x, before any ray is traced. */
typedef struct mlight_path {
    const mlight_plane *m;
    vec3 n_side;         /* the mirror's normal on x's side */
    light_point lp;      /* the lamp point (the real one) */
    vec3 wi;             /* unit direction from x to the lamp's image */
    float pdf;           /* solid-angle pdf of wi at x: mirror choice x lamp point */
    float tm;            /* distance from o along wi to the mirror's plane */
} mlight_path;

/* Picks a mirror by cdf/total (from mlight_cdf at x) with um and a lamp
 * point as that mirror's centre sees the lamps with u0..u2 (light_sample),
 * and mirrors it: false when the lamp is behind the mirror, faces away from
 * x's image of it, or the line from x (rays leave o, x pushed off its
 * surface) to the image crosses the plane outside the mirror's bounds. */
bool mlight_pick(const mlight_set *s, const light_set *lights, const float *cdf, float total, vec3 x, vec3 o,
                 float um, float u0, float u1, float u2, mlight_path *out);

/* The leg from the mirror to the lamp of path mp, whose first leg leaves o. */
typedef struct mlight_leg {
    vec3 o, d, target;   /* from a point off the mirror towards the lamp (unit d) */
    float dist;          /* to target */
} mlight_leg;

/* Traces the first leg of mp from o (one closest-hit ray, which must meet
 * the mirror itself before anything else) and fills the second; false when
 * something is in front of the mirror or no mirror is there. */
bool mlight_to_mirror(const emb_scene *e, const mlight_path *mp, vec3 o, mlight_leg *leg);

/* Irradiance at x (front normal n, rays from o) from the lamps seen in the
 * mirrors, by n random samples: the radiosity solver's source term
 * (rad_solve.c). Both legs by closest-hit rays, glass blocks. */
vec3 mlight_irradiance(const mlight_set *s, const emb_scene *e, const light_set *lights, vec3 x, vec3 nx, vec3 o,
                       int n, ct_rng *rng);

#endif
