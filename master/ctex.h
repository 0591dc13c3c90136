/* ctex.h: the corrective textures of the master (§3.2-3.6): the texture
 * hierarchy (modeling hierarchy refined by a space-and-material BVH), the
 * per-view texture assignment with frustum culling, object-local parallel
 * and camera-local perspective projections as world -> texture matrices,
 * texels with signed RGB correction and validity, ring splatting, aging,
 * adaptive resolution under a memory cap, the event list for the display
 * (allocation, projection, patch, free) and a software compositor that draws
 * the same image as the display. docs/textures.md describes the algorithms.
 *
 * Texture coordinates: texel (i, j) of a w x h texture covers
 * [i/w, (i+1)/w) x [j/h, (j+1)/h); row j = 0 is stored first (GL uploads it
 * first, so it sits at t = 0). Lookups are bilinear with clamp-to-edge, like
 * GL_LINEAR + GL_CLAMP_TO_EDGE. A projection matrix M (row-major, column
 * vectors, common/vecmath.h) maps a world point p to q = M (p, 1) and the
 * texture position is (q.x / q.w, q.y / q.w); q.z is unused by the display. */
#ifndef CT_MASTER_CTEX_H
#define CT_MASTER_CTEX_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/image.h"
#include "common/optab.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/vecmath.h"
#include "common/records.h"

/* Every tunable of the texture engine; ctex_options_default() fills the
 * defaults, ctex_options_parse() sets one from a command-line flag. */
typedef struct ctex_options {
    float eps;            /* §3.3: parallax threshold Δr/d < eps, 0.3 */
    float max_proj;       /* §3.3: split nodes whose projected size exceeds this fraction of max(W,H); 0 = off */
    float flat_deg;       /* §3.2: normal spread under which a node is flat, 10 degrees */
    float flat_thickness; /* flat nodes must also be coplanar: extent along the normal / in-plane extent */
    float blend;          /* §3.4: validity band (texels) over which splat borders are blended; 0 = off */
    float mix;            /* weight of a new sample against the correction at its centre texel; 1 = off */
    float mix_radius;     /* ... when that correction's sample lies within this many texels (validity) */
    int splat_max;        /* largest splat radius (texels); 0 = no limit */
    int splat_aniso;      /* 1: rings measured on screen (ctex_tex_splat_aniso); 0: in texels */
    float splat_lo;       /* §3.6: mean splat radius under which the resolution doubles (texels) */
    float splat_hi;       /* §3.6: mean splat radius over which the resolution halves (texels) */
    int splat_window;     /* §3.6: samples in the running mean, and between two resolution changes */
    int tex_min;          /* §3.6: minimum texture size per axis, 4 */
    int tex_init;         /* size of a new texture along its longer axis */
    float tex_rate;       /* §3.6: maximum texels per screen pixel per axis, 2 */
    int tex_max;          /* absolute maximum size per axis */
    double mem_mb;        /* memory cap for all texels, MiB */
    float age_flow;       /* §3.5: weight of the texture-flow term (camera-local) */
    float age_brdf;       /* §3.5: weight of the BRDF term, texture sizes per radian at glossiness 1 */
    float late_deg;       /* glossy late samples whose view direction turned more (degrees x gloss) are dropped */
    float resample_age;   /* validity (texels) a resampled texel loses against fresh samples */
    float keep_deg;       /* camera-local textures keep their projector up to this view angle change; 0 = never */
    float proj_margin;    /* a camera-local texture made again on a move reaches past cut screen edges by this
                           * fraction of the screen; 0 = never */
    float bvh_mat_weight; /* BVH: cost factor for groups that mix materials */
    int cluster_tris;     /* parts with more triangles are split into clusters; 0 = never */
} ctex_options;

/* The defaults (the paper's values where it gives one). */
ctex_options ctex_options_default(void);

/* Sets the option named by a command-line flag ("--eps", ...) from value.
 * Returns 1 when the flag is a texture option, 0 when it is not, or a
 * negative CT_E* code for a bad value (err names the flag). */
int ctex_options_parse(ctex_options *o, const char *flag, const char *value, ct_error *err);

/* The option table (common/optab.h): one row per option with its default. */
const optab *ctex_options_table(size_t *n);

/* Prints one help line per option with its default. */
void ctex_options_help(FILE *f);

/* Projection kind of a texture (§3.2). */
typedef enum ctex_proj_kind {
    CTEX_PROJ_OBJECT = 1,   /* object-local parallel along the node's normal */
    CTEX_PROJ_CAMERA = 2    /* camera-local perspective from the eye */
} ctex_proj_kind;

/* What the display must do, in order (ctex_events). A texture id is reused
 * after its FREE. ALLOC of a live id is a resize. Texels are not events:
 * each texture marks the ones the display has not received
 * (ctex_visible_texture, master/ctex_dirty.h); every texel of an ALLOC'ed
 * texture is marked. RESIZE is an exact resize (wire_tex_resize_exact) of
 * a live texture from ow x oh: only the tiles computed from unsent texels
 * are marked, the display computes the rest from the texels it has; a
 * display that cannot (it got the texture at another size) needs the
 * texture as an ALLOC, all of it marked (master/dsync.c). */
typedef enum ctex_event_kind {
    CTEX_EV_ALLOC  = 1,   /* tex, node, kind, w, h */
    CTEX_EV_PROJ   = 2,   /* tex, matrix */
    CTEX_EV_FREE   = 4,   /* tex */
    CTEX_EV_RESIZE = 8    /* tex, node, kind, w, h, ow, oh */
} ctex_event_kind;

typedef struct ctex_event {
    ctex_event_kind kind;
    uint32_t tex;
    uint32_t node;        /* hierarchy node (ALLOC, RESIZE) */
    ctex_proj_kind proj;  /* ALLOC, RESIZE */
    int w, h;             /* ALLOC, RESIZE: the size */
    int ow, oh;           /* RESIZE: the size before */
    mat4 m;               /* PROJ: world -> texture */
} ctex_event;

/* Result of inserting one sample. */
typedef struct ctex_insert_info {
    vec3 correction;   /* ΔL read at the hit before the splat (bilinear, as displayed) */
    vec3 error;        /* E = l_hq - (l_base + ΔL), §3.7 (ΔL = 0 when dropped) */
    int32_t tex;       /* texture it went into, -1 when dropped */
    int radius;        /* splat radius r (texels); a late sample that wrote nothing: why (CTEX_LATE_*) */
} ctex_insert_info;

/* ctex_insert_info.radius of a late sample that wrote nothing
 * (ctex_insert_late_par): its viewing direction turned by more than
 * --late-deg times its glossiness, or its centre texel holds a fresher
 * sample; 0 when its hit has no texture now. */
#define CTEX_LATE_TURNED (-1)
#define CTEX_LATE_COVERED (-2)

/* A primary hit per pixel for the compositor: node = UINT32_MAX for a miss. */
typedef struct ctex_hit {
    uint32_t node;     /* scene part node id */
    uint32_t tri;      /* radiosity mesh triangle (UINT32_MAX: unknown) */
    vec3 p;            /* world hit point */
    vec3 l_base;       /* interactive value at the pixel */
} ctex_hit;

/* Counters for logs, CSV files and the display's STATS. */
typedef struct ctex_stats {
    uint32_t textures;        /* assigned (visible) textures */
    uint32_t parked;          /* textures kept for culled nodes */
    uint64_t texels;          /* texels of all live textures */
    size_t bytes;             /* their memory */
    double splat_radius_mean; /* mean of the visible textures' running means */
    uint64_t inserted;        /* samples splatted */
    uint64_t dropped;         /* samples with no texture (miss, culled, off the texture) */
    uint64_t resizes;         /* resolution changes */
    uint64_t evictions;       /* parked textures evicted for memory */
    uint64_t resampled;       /* camera changes that resampled a texture (reprojection, split, merge) */
    uint64_t kept;            /* camera changes that left a camera-local texture on its projector */
    uint32_t hier_nodes;      /* nodes of the texture hierarchy */
    uint32_t hier_leaves;     /* its leaves (mesh parts) */
} ctex_stats;

typedef struct ctex ctex;

/* --- lifecycle ------------------------------------------------------------ */

/* Builds the texture hierarchy over the radiosity mesh's node table and
 * triangles (mats: the scene's materials, indexed by the mesh's tri_mat, for
 * glossiness and material grouping). The mesh is not kept. */
int ctex_new(const ct_radmesh *mesh, const scene_material *mats, uint32_t nmats,
             const ctex_options *opt, ctex **out, ct_error *err);

/* Frees the engine and all textures (NULL is fine). */
void ctex_free(ctex *c);

/* --- per view ------------------------------------------------------------- */

/* Sets the camera for a width x height image: ages the surviving textures
 * (§3.5), reassigns textures (§3.3), updates camera-local projections and
 * resamples split or merged nodes' textures from the old ones. */
int ctex_set_camera(ctex *c, const ct_camera *cam, int width, int height, ct_error *err);

/* --- per sample ----------------------------------------------------------- */

/* Whether sample s's radiance does not depend on the view: the surface it
 * hit (its hierarchy leaf) has only diffuse materials. Such a sample, traced
 * for a view the camera has left, is still a right correction in the new
 * one: L_hq and L_base are both the same from any direction, and the splat
 * goes through the current view's texture of its world point. */
bool ctex_view_independent(const ctex *c, const ct_sample *s);

/* Inserts a sample (§3.4): maps its hit point into the texture of its node,
 * reads the displayed correction, computes the error and splats
 * l_hq - l_base. Returns 1 when splatted, 0 when dropped (info->tex = -1). */
int ctex_insert(ctex *c, const ct_sample *s, ctex_insert_info *info);

/* Inserts n samples (info[i] for s[i]) on the pool's threads: grouped by
 * texture, each texture's samples in their order by one thread, so that no
 * texel is shared; a resolution change (§3.6) a texture earns on the way is
 * made after all of them, in texture order, and at most one per texture and
 * call. The result does not depend on the number of threads (pool NULL: the
 * caller's alone); with n = 1 it is ctex_insert's. Returns how many were
 * splatted. */
size_t ctex_insert_par(ctex *c, ct_pool *pool, const ct_sample *s, size_t n, ctex_insert_info *info);

/* Late samples (traced for views the camera has left; the request queue
 * never hears of them) as ctex_insert_par, s[i] traced from eyes[i]: as if
 * it had gone in when traced and aged since by §3.5's BRDF term (the
 * glossiness of its surface x the change of the viewing direction at its
 * hit), so that it fills where its texture has nothing as fresh and never
 * covers a newer sample (ctex_tex_splat_late); one that needs no aging (a
 * diffuse surface, an unmoved eye) goes in as a new one. Those whose
 * viewing direction turned by more than late_deg x their glossiness, and
 * those that found their centre texel fresher, are not written (info tex
 * -1). Returns how many were. */
size_t ctex_insert_late_par(ctex *c, ct_pool *pool, const ct_sample *s, const vec3 *eyes, size_t n,
                            ctex_insert_info *info);

/* Refinement samples as ctex_refine, the pixel's sample count of s[i] in
 * n_px[i], grouped the same way. */
size_t ctex_refine_par(ctex *c, ct_pool *pool, const ct_sample *s, const uint16_t *n_px, size_t n,
                       ctex_insert_info *info);

/* A refinement sample (docs/sampling.md, "Refinement"), its pixel's n_px-th
 * (n_px >= 2): instead of a splat, the texels the display reads for its
 * pixel move towards its correction L_hq - L_base as a running mean in
 * which the first pass's value there counts as (2 - m) / m samples, m the
 * texture's mixing weight (docs/textures.md, "Mixing": the first pass's
 * mixed value is worth that many samples; 1 unmixed). info as ctex_insert
 * (E against what was displayed before). Returns 1 when written, 0 when
 * dropped. */
int ctex_refine(ctex *c, const ct_sample *s, uint16_t n_px, ctex_insert_info *info);

/* The correction the display shows at world point p on mesh triangle tri of
 * scene part `node` (tri = UINT32_MAX when unknown; only parts split into
 * clusters need it); zero when it has no texture. */
vec3 ctex_lookup(const ctex *c, uint32_t node, uint32_t tri, vec3 p);

/* --- display events -------------------------------------------------------- */

/* The clock (us) stamped on texel changes from now on (ctex_dirty.h). */
void ctex_set_clock(ctex *c, uint64_t now_us);

/* Marks every texel of every visible texture unsent (a new display). */
void ctex_dirty_all(ctex *c);

/* Texture ids are below ctex_slot_count; the texture of an id when the
 * display has it (live and visible: ALLOC'ed and not FREE'd), else NULL.
 * The display server reads and clears its unsent tiles (ctex_tex.d). */
uint32_t ctex_slot_count(const ctex *c);
struct ctex_tex *ctex_visible_texture(ctex *c, uint32_t id);

/* The pending events in order (valid until the next call that changes c). */
const ctex_event *ctex_events(const ctex *c, size_t *n);

/* Forgets the pending events (after the server has sent them). */
void ctex_events_clear(ctex *c);

/* Copies a rectangle of texture tex's corrections (RGB floats, rows top
 * first) into out (w*h*3 floats). */
int ctex_read_patch(const ctex *c, uint32_t tex, int x, int y, int w, int h, float *out,
                    ct_error *err);

/* The scene part nodes of a hierarchy node's leaves (a split part once per
 * cluster). */
const uint32_t *ctex_node_parts(const ctex *c, uint32_t hnode, uint32_t *n);

/* The texture hierarchy as a mesh node table in pre-order (modeling nodes
 * keep their names, BVH nodes are named "bvh:<id>", nodes inside a part
 * split into clusters "cluster:<id>"), for the display: the node of a
 * texture event is a hierarchy node, so the display server ships this table
 * as the SCENE's node table and writes ctex_hnode_of_tri as each triangle's
 * node; a texture then corrects the triangles of its node's subtree. out
 * holds ctex_get_stats(c).hier_nodes entries. */
void ctex_export_nodes(const ctex *c, rmesh_node *out);

/* The radiosity mesh as the display receives it (SCENE): mesh's vertices,
 * triangles and materials with the texture hierarchy as its node table
 * (ctex_export_nodes) and each triangle's hierarchy leaf as its node
 * (ctex_hnode_of_tri), so that a texture on hierarchy node h is drawn on
 * exactly the triangles of h's subtree: a cluster's texture on its cluster,
 * not on its whole part. mesh must be the mesh c was built from. out shares
 * mesh's other arrays and owns nodes and tri_node: release them with
 * ctex_display_mesh_free (not rmesh_free). */
int ctex_display_mesh(const ctex *c, const ct_radmesh *mesh, ct_radmesh *out, ct_error *err);

/* Frees what ctex_display_mesh allocated and zeroes out. */
void ctex_display_mesh_free(ct_radmesh *out);

/* The hierarchy node of scene part node `part` (its leaf, or the root of its
 * clusters), or UINT32_MAX when it has no triangles. */
uint32_t ctex_hnode_of_part(const ctex *c, uint32_t part);

/* The hierarchy leaf of mesh triangle tri (what the display server writes as
 * the triangle's node), or UINT32_MAX. */
uint32_t ctex_hnode_of_tri(const ctex *c, uint32_t tri);

/* --- queries ----------------------------------------------------------------- */

/* The texture id that corrects a hit on scene part `node` (triangle tri,
 * point p, as ctex_lookup) in the current view, or -1. */
int32_t ctex_owner(const ctex *c, uint32_t node, uint32_t tri, vec3 p);

/* Hierarchy node of texture tex, its size and projection; -1 when not live. */
int ctex_texture_info(const ctex *c, uint32_t tex, uint32_t *hnode, int *w, int *h,
                      ctex_proj_kind *kind, mat4 *m, float *vmax);

/* Texture tex's texels per screen pixel along each axis in the current view
 * (its size against its §3.6 bound, tex-rate texels a pixel): false when
 * that is not known (no view, not live, or a bound cut by --tex-max). */
bool ctex_texel_rate(const ctex *c, uint32_t tex, float *x, float *y);

/* The ex a sample at p on texture tex splats with (ctex_tex_splat_aniso;
 * docs/textures.md, "Anisotropic splats"): sqrt(s_y / s_x) for the texel at
 * p, s_x by s_y pixels in the current view, through ctex_aniso_ex (1: square
 * rings). 1 when tex is not live or p lies behind the eye. */
float ctex_splat_ex(const ctex *c, uint32_t tex, vec3 p);

/* Counters. */
ctex_stats ctex_get_stats(const ctex *c);

/* --- compositor ---------------------------------------------------------------- */

/* The image the display draws: per pixel l_base plus the bilinear correction
 * of the pixel's node at its hit point, averaged over the pixel's spp hits
 * (hits holds width x height x spp, a pixel's spp hits one after the other:
 * spp > 1 is a display drawing with multisampling). out must be width x
 * height. */
int ctex_composite(const ctex *c, const ctex_hit *hits, int spp, int width, int height, ct_image *out,
                   ct_error *err);

/* A distinct colour for texture tex (the paper's Fig. 5 debug view). */
vec3 ctex_debug_color(int32_t tex);

#endif
