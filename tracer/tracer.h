/* tracer.h: the high-quality sample client (§4.1): a tracer over an Embree
 * scene built from a corrtex scene or its radiosity mesh, with three modes
 *   path           unbiased path tracing, next-event estimation + MIS (ground truth)
 *   drt            distributed ray tracing (Cook 1984): K shadow rays, B rays at
 *                  glossy surfaces (on the first branch-depth levels, then 1), one
 *                  per mirror and per Fresnel branch, to depth D; indirect
 *                  diffuse from the radiosity mesh (--indirect: read at the hit,
 *                  total - direct, or a final gather of it over G rays), or
 *                  path-traced when no mesh is given
 *   reuse-diffuse  the diffuse part is the interpolated radiosity; only glossy,
 *                  mirror and refractive transport is traced (corrections >= 0)
 * The per-sample API traces a batch of requests and returns sample records.
 * A sample's randomness is rng_make(seed, request id, epoch, TRC_DIM_*), so a
 * request gives the same record on any rank, thread or batch order. A tracer
 * is read-only after trc_new: threads share it, each with its own trc_stats. */
#ifndef CT_TRACER_TRACER_H
#define CT_TRACER_TRACER_H

#include <stddef.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/records.h"

typedef enum trc_mode {
    TRC_MODE_PATH  = 0,
    TRC_MODE_DRT   = 1,
    TRC_MODE_REUSE = 2
} trc_mode;

/* Where drt takes its indirect diffuse light from, when it has a radiosity
 * mesh (docs/tracer.md, "Indirect light"). */
typedef enum trc_indirect {
    TRC_INDIRECT_MESH   = 0,   /* the mesh at the hit: its total minus its direct part */
    TRC_INDIRECT_GATHER = 1    /* a final gather: G cosine rays read the mesh where they land */
} trc_indirect;

/* What a final-gather ray counts of the lamps' direct light where it lands
 * (docs/tracer.md, "Indirect light"). */
typedef enum trc_gather_direct {
    TRC_GATHER_DIRECT_MESH  = 0,   /* the mesh's value there, direct part included */
    TRC_GATHER_DIRECT_TRACE = 1    /* the mesh's indirect part plus one traced lamp sample */
} trc_gather_direct;

/* How path tracing and drt find the lamps' light through glass (docs/tracer.md,
 * Light sampling, "Light through glass, refracted"). */
typedef enum trc_glass_light {
    TRC_GLASS_STRAIGHT  = 0,   /* shadow rays pass glass, attenuated (the paper's; the radiosity solution's) */
    TRC_GLASS_REFRACTED = 1,   /* glass blocks shadow rays: refracted paths (drt with a mesh: photons) bring that light */
    TRC_GLASS_AUTO      = 2    /* straight through flat glass (panes, sheets), refracted through glass that bends
                                * light (spheres, lenses, drinking glasses): tracer/glass_parts.h */
} trc_glass_light;

/* Random stream dimensions (the third id of rng_make). */
enum {
    TRC_DIM_TRACE = 0,   /* everything the integrator draws */
    TRC_DIM_PIXEL = 1    /* the reference renderer's sub-pixel jitter */
};

/* Changes whenever an image a mode gives changes (not its speed), so that
 * references cached by scripts (named after `corrtex reference --help`,
 * which prints it) are rendered again: 1: drt's final gather follows
 * mirrors; 2: drt samples lamps seen in plane mirrors; 3: the gather traces
 * the lamps' light where its rays land (TRC_GATHER_DIRECT_TRACE); 4: by
 * the landing surface's glossy lobe too; 5: both Fresnel branches on the
 * first three levels (fresnel_depth); 6: a glossy layer where a gather
 * ray lands reflects the room's light too (integ_gather.c); 7: a gather ray
 * that meets glass takes its face's reflection too; 8: drt with a mesh
 * adds the lamps' reflective caustics (caustics.h); 9: path tracing and drt
 * refract the lamps' light through glass that bends it by default
 * (TRC_GLASS_AUTO). */
#define TRC_VERSION 9

/* drt's default photons for the reflective caustics (caustics.h). */
#define TRC_CAUSTIC_PHOTONS 1000000
#define TRC_CAUSTIC_PHOTONS_MAX 100000000

typedef struct trc_options {
    trc_mode mode;
    int shadow_rays;     /* K: light samples per shading point */
    int branch;          /* B: rays per glossy lobe (drt, reuse-diffuse) */
    int branch_depth;    /* levels that split into B glossy rays; 1 below */
    int fresnel_depth;   /* levels that trace both Fresnel branches; below, the weaker by chance */
    int depth;           /* D: bounces (drt, reuse-diffuse: recursion; path: maximum length) */
    trc_indirect indirect;   /* drt with a mesh: its indirect light */
    int gather_rays;     /* G: rays of TRC_INDIRECT_GATHER per shading point */
    trc_gather_direct gather_direct;   /* TRC_INDIRECT_GATHER: the lamps' light where a ray lands */
    int caustic_photons; /* drt with a mesh: photons of the lamps' reflective caustics (0: none) */
    trc_glass_light glass_light;   /* light through glass (default auto; reuse-diffuse: auto is straight, refracted refused) */
    uint64_t seed;
    const char *device_config;   /* rtcNewDevice config, NULL for defaults */
} trc_options;

/* Defaults of a mode: path K=1, D=64 (Russian roulette from bounce 3);
 * drt and reuse-diffuse K=4, B=4, D=8, glossy splitting on the first level
 * only, both Fresnel branches on the first three;
 * drt's indirect light by final gather, G=4, the lamps traced where its
 * rays land, and its reflective caustics from DRT_CAUSTIC_PHOTONS photons.
 * Seed 1. */
void trc_options_default(trc_options *o, trc_mode mode);

/* "path", "drt", "reuse-diffuse". */
const char *trc_mode_name(trc_mode m);

/* "mesh", "gather". */
const char *trc_indirect_name(trc_indirect i);

/* "mesh", "trace". */
const char *trc_gather_direct_name(trc_gather_direct g);

/* "straight", "refracted", "auto". */
const char *trc_glass_light_name(trc_glass_light g);

/* A recorded ray (benchmark replay of the very rays a run traced). */
typedef struct trc_ray {
    float o[3], d[3];
    float tnear, tfar;
    uint32_t shadow;     /* 1: traced with rtcOccluded1 */
    uint64_t seq;        /* position in the thread's ray stream */
} trc_ray;

/* A bounded per-thread ray log: a uniform random subset (reservoir
 * sampling) of all rays the thread traced, so a capped log still represents
 * the whole image; trc_raylog_sort restores the traced order for replay. */
typedef struct trc_raylog {
    trc_ray *rays;
    size_t n, cap;
    uint64_t seen;       /* rays offered to the log */
    uint64_t state;      /* the reservoir's own random state */
} trc_raylog;

/* Sorts a log's rays back into the order they were traced. */
void trc_raylog_sort(trc_raylog *log);

/* Per-thread counters (and optional ray log). */
typedef struct trc_stats {
    uint64_t primary, secondary, shadow;   /* rays by kind */
    uint64_t samples;
    trc_raylog *log;                      /* NULL: no recording */
} trc_stats;

/* Total rays of a stats record. */
static inline uint64_t trc_stats_rays(const trc_stats *s) { return s->primary + s->secondary + s->shadow; }

/* The view requests refer to: camera and image size (camera.h positions). */
typedef struct trc_view {
    ct_camera cam;
    int width, height;
} trc_view;

typedef struct trc_tracer trc_tracer;

/* Whether o's values and their combination are valid (ranges; the refracted
 * glass light only for path tracing and drt): what trc_new refuses, for programs
 * that check their options before loading a scene. */
int trc_options_check(const trc_options *o, ct_error *err);

/* A tracer over the scene, intersecting rad's triangles when rad is given
 * (then samples carry L_base), else the scene's. reuse-diffuse needs rad.
 * scene and rad must outlive the tracer. */
int trc_new(const ct_scene *scene, const ct_radmesh *rad, const trc_options *o, trc_tracer **out,
            ct_error *err);

/* Releases the tracer (NULL is fine). */
void trc_free(trc_tracer *t);

/* The options it was made with. */
const trc_options *trc_get_options(const trc_tracer *t);

/* How the tracer picks lights, for logs: its emitters, whether each shading
 * point weighs them itself, and the estimated gain of doing so (lights.h). */
void trc_light_choice(const trc_tracer *t, uint32_t *emitters, bool *spatial, double *gain);

/* The reflective caustics' photons (caustics.h): shot, landed after a
 * reflection, and the seconds their shooting and estimate took at
 * trc_new; all 0 where there are none (no mesh, not drt, no mirror or
 * glass, or --caustic-photons 0). */
void trc_caustic_stats(const trc_tracer *t, uint64_t *photons, uint64_t *landed, double *seconds);

/* Traces n requests into n sample records (full L_hq). */
void trc_trace(const trc_tracer *t, const trc_view *v, const ct_request *req, size_t n,
               ct_sample *out, trc_stats *st);

/* Primary hits only: the records without L_hq (zero), with L_base. */
void trc_trace_primary(const trc_tracer *t, const trc_view *v, const ct_request *req, size_t n,
                       ct_sample *out, trc_stats *st);

/* trc_trace (with `primary`: trc_trace_primary) of n requests on the pool's
 * threads, a few parts per thread so that harder parts balance; the records
 * do not depend on the split (each sample's randomness is its own). st (may
 * be NULL) gets the rays of every part added. */
void trc_trace_par(const trc_tracer *t, ct_pool *pool, const trc_view *v, const ct_request *req, size_t n,
                   ct_sample *out, bool primary, trc_stats *st);

/* Replays logged rays with raw Embree queries: every ray with rtcIntersect1
 * (as_traced 0) or shadow rays with rtcOccluded1 (as_traced 1). Returns the
 * number of hits (so the work cannot be optimized away). */
uint64_t trc_replay(const trc_tracer *t, const trc_raylog *log, int as_traced);

#endif
