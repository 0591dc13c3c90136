/* radiosity.h: the interactive solution (§4.1): hierarchical radiosity after
 * Hanrahan, Salzman and Aupperle 1991 with source-side clusters, Embree
 * visibility, and its conforming Gouraud mesh (common/radmesh.h). Owns the
 * rad_ prefix; the pieces live in rad_patch.c (input patches, element and
 * cluster hierarchies), rad_visibility.c (Embree occlusion), rad_ff.c (form
 * factors, link visibility), rad_link.c (error oracle, link refinement),
 * rad_solve.c (gather, push-pull, passes, threads), rad_gather.c (the final
 * gather at the mesh's vertices), rad_mesh.c (conforming meshing),
 * rad_mirror.c (lamps seen in plane mirrors) and rad_view.c (a Gouraud image
 * of the mesh). docs/radiosity.md
 * describes the method, its parameters and how non-diffuse materials are
 * treated. */
#ifndef CT_RADIOSITY_H
#define CT_RADIOSITY_H

#include <stddef.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/image.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/vecmath.h"

/* Solver parameters; every field is a `corrtex radiosity` option. */
typedef struct rad_params {
    double error;           /* link error threshold, fraction of the total emitted power */
    double dim_floor;       /* a receiver dimmer than the mean reflected radiosity takes the threshold times its
                             * share of that mean, down to this factor (0: every receiver the same threshold) */
    double min_area;        /* smallest element area, fraction of the lit surface area (docs/radiosity.md, "Scale") */
    uint32_t max_triangles; /* stop subdividing near this many output triangles */
    int threads;            /* worker threads (pthreads) */
    uint32_t memory_cap_mb; /* fail when the solver's memory would exceed this */
    int vis_rays;           /* visibility rays per link from a non-emitting source */
    int shadow_rays;        /* visibility rays per link from a source containing emitters */
    int vertex_rays;        /* final gather: rays from a vertex to a partly hidden source (0: the link's own visibility) */
    int gather_passes;      /* after the solve, steps of the final gather at every leaf (0: the links' values) */
    double tolerance;       /* residual (relative to the brightest reflected light) to stop iterating */
    int max_iterations;     /* gather/push-pull iterations per refinement pass at most */
    int max_passes;         /* refinement passes at most */
    double crease_deg;      /* vertex values are averaged only below this normal angle */
    uint64_t seed;          /* visibility ray seed */
    int mirror_samples;     /* lamp samples by way of plane mirrors per leaf and vertex (0: none) */
} rad_params;

/* What a solve did, for the final stats line and the tests. */
typedef struct rad_stats {
    uint32_t patches;       /* input patches (triangles and rebuilt quads) */
    uint32_t clusters;      /* source clusters above them */
    uint64_t elements;      /* patches and sub-patches */
    uint64_t leaves;        /* elements without children */
    uint64_t links;         /* links of the final solution */
    uint64_t rays;          /* visibility rays traced */
    int passes;             /* refinement passes */
    int iterations;         /* gather/push-pull iterations, all passes */
    double residual;        /* last residual, relative to the brightest reflected light */
    uint32_t triangles;     /* output mesh */
    uint32_t vertices;
    uint32_t contact_vertices; /* vertices hidden under an object on their surface, given the
                                * radiosity at its contact line (docs/radiosity.md) */
    uint64_t peak_bytes;    /* the solver's own peak (elements, links, Embree) */
    double emitted;         /* total emitted power (mean of RGB, scene units) */
    double absorbed;        /* total absorbed power at convergence (same units) */
    double seconds;
} rad_stats;

/* Progress callback: fraction in [0, 1] of the current stage, a short text. */
typedef void (*rad_progress_fn)(void *user, double fraction, const char *what);

/* The defaults printed by `corrtex radiosity --help`. */
void rad_params_default(rad_params *p);

/* Checks every parameter's range; fills err naming the bad one. */
int rad_params_check(const rad_params *p, ct_error *err);

/* Hash of the scene (its file contents' hash, or its geometry and materials
 * when it was built in code) and the parameters that change the result: the
 * .ctmesh cache key (threads and the memory cap do not change it). */
uint64_t rad_solution_hash(const ct_scene *s, const rad_params *p);

/* The default cache file of this scene's solution for these parameters:
 * HASH.ctmesh (rad_solution_hash, 16 hex digits) in the user's cache folder
 * (fs_user_cache_dir; with make, the folder is made when missing).
 * corrtex-render without --mesh or --rad-cache and corrtex radiosity without
 * -o both use it, so either finds what the other solved. */
int rad_cache_default(const ct_scene *s, const rad_params *p, int make, char *out, size_t cap, ct_error *err);

/* Solves the scene and meshes the solution into out (which the caller frees
 * with rmesh_free). progress may be NULL. Fails with CT_ENOMEM when the memory
 * cap is hit, CT_EEMPTY when the scene emits no light. */
int rad_solve(const ct_scene *s, const rad_params *p, rad_progress_fn progress, void *user,
              ct_radmesh *out, rad_stats *st, ct_error *err);

/* The solution through its cache: loads cache_path when it holds this
 * scene's solution for these parameters (rad_solution_hash), otherwise
 * solves and writes the cache atomically. *from_cache tells which happened;
 * a missing, stale or unreadable cache is recomputed (its reason is in
 * *why when why is not NULL, "" when it was used). */
int rad_cached_solve(const ct_scene *s, const rad_params *p, const char *cache_path,
                     rad_progress_fn progress, void *user, ct_radmesh *out, rad_stats *st,
                     int *from_cache, ct_error *why, ct_error *err);

/* What rad_render_view shows. */
enum {
    RAD_VIEW_TOTAL = 0,   /* the Gouraud radiance, as the display */
    RAD_VIEW_DIRECT = 1,  /* its direct part (rad_direct) */
    RAD_VIEW_PLANES = 2   /* per pixel, the plane all its samples hit (part node + 1, quantized
                           * normal, offset), 0 where they hit more than one plane or nothing:
                           * which regions of an image lie on one flat surface (corrtex compare
                           * --regions) */
};

/* Renders the mesh as the display shows it (Gouraud radiance at the primary
 * hit, rmesh_eval), its direct part or its planes (which: RAD_VIEW_*) from
 * cam into img (sized by the caller), spp jittered samples per pixel, black
 * where nothing is hit (rad_view.c). */
int rad_render_view(const ct_radmesh *m, const ct_camera *cam, int spp, int which, int threads,
                    ct_image *img, ct_error *err);

/* Unoccluded form factor from a differential area at x (unit normal n) to a
 * planar polygon (Lambert's contour formula), clipped to n's hemisphere;
 * 0 when x lies behind the polygon (its front is counter-clockwise). */
double rad_ff_point_polygon(vec3 x, vec3 n, const vec3 *poly, int npoly);

/* Area-to-area form factor F(a -> b) of two planar convex polygons,
 * averaging the point-to-polygon factor over an n x n grid on a. */
double rad_ff_polygons(const vec3 *a, int na, const vec3 *b, int nb, int n);

#endif
