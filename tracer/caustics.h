/* caustics.h: the lamps' reflective caustics on a radiosity mesh: light
 * from a lamp by way of mirrors and glass faces onto a diffuse surface,
 * which neither drt's shadow rays nor its final gather find (the gather
 * leaves a lamp seen in a mirror out: rare and bright, fireflies). Photons
 * are shot from the lamps, followed through their mirror and glass
 * reflections (glass passes the rest straight on, as the tracer's shadow
 * rays see it, or refracts it where glass blocks them), and where one lands
 * on a diffuse surface after at least one reflection or such a refraction
 * its power is kept; a density estimate at every mesh vertex
 * turns them into irradiance, which drt reads as it reads the mesh
 * (docs/tracer.md, "Reflective caustics"). One reflection by a plane
 * mirror is left out where drt samples the lamps' images in it
 * (mirror_lights.h). Owns the caus_ prefix. */
#ifndef CT_TRACER_CAUSTICS_H
#define CT_TRACER_CAUSTICS_H

#include <stdint.h>

#include "common/error.h"
#include "common/vecmath.h"
#include "tracer/embree_scene.h"
#include "tracer/mirror_lights.h"

/* Photons a density estimate at a vertex wants within its radius; it takes
 * the smallest of the radii (an eighth, a quarter, a half and all of
 * CAUS_RADIUS_SHARE of the scene's diagonal) that holds them, else the
 * largest. */
#define CAUS_KNN 128
#define CAUS_RADIUS_SHARE 0.02f

typedef struct caus_stats {
    uint64_t photons;    /* shot */
    uint64_t deposits;   /* landed on a diffuse surface after a reflection or a refraction */
    double seconds;
} caus_stats;

/* The caustic irradiance at each vertex of e's mesh (a radiosity mesh:
 * per-vertex reads), from `photons` photons of seed `seed`; mirrors may be
 * NULL. refract_nodes (per part node; NULL: none): that part's glass
 * refracts the photons, and every photon that crossed it counts (the shadow
 * rays do not pass it: TRC_GLASS_REFRACTED, TRC_GLASS_AUTO); other glass
 * passes them straight, and there only reflections make a caustic. *out
 * is NULL (and CT_OK) when the scene has no lamp, no mirror or glass, or no
 * photon landed; else an array of the mesh's nverts for the caller to free.
 * Runs on `threads` threads (0: the cores this process may use, as
 * Embree's build does). Deterministic for a seed, whatever the threads. */
int caus_build(const emb_scene *e, const mlight_set *mirrors, uint32_t photons, uint64_t seed,
               const uint8_t *refract_nodes, int threads, vec3 **out, caus_stats *st, ct_error *err);

#endif
