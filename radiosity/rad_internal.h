/* rad_internal.h: the radiosity solver's private state, shared by the rad_*.c
 * files of tracer/ and by nothing else. Elements (patches and sub-patches)
 * live in fixed-size chunks so their addresses stay valid while worker
 * threads append children; links are flat (source, factor) pairs in one block
 * per input patch, rebuilt by the thread that owns the patch in each pass. */
#ifndef CT_RAD_INTERNAL_H
#define CT_RAD_INTERNAL_H

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

#include "common/scene.h"
#include "radiosity/radiosity.h"
#include "tracer/embree_scene.h"

#define RAD_NONE        UINT32_MAX
#define RAD_CLUSTER_BIT 0x80000000u   /* a source reference naming a cluster */
#define RAD_ID_MASK     0x3FFFFFFFu
#define RAD_CHUNK_SHIFT 14
#define RAD_CHUNK       (1u << RAD_CHUNK_SHIFT)
#define RAD_MAX_CHUNKS  (1u << 16)    /* 2^30 elements: ids fit RAD_ID_MASK */
#define RAD_MAX_DEPTH   14            /* subdivision levels below an input patch */

/* One link: the receiver gathers ff * B(src); ff is the form factor times
 * the fraction of visibility rays that were not blocked. gr and gv are its
 * error per unit of source radiosity (rad_link.c, evaluate), kept for the
 * oracle of the later passes. A cluster's link has no gv: in its place bk,
 * what the radiosity its rays saw is of the cluster's mean (rad_link_cluster_B). */
typedef struct rad_link {
    uint32_t src;
    float ff;
    float vis;           /* the visible fraction in ff */
    float gr;            /* a cluster's: its unoccluded factor (ff / vis, also where vis is 0) */
    union {
        float gv;        /* an element's */
        float bk;        /* a cluster's */
    };
} rad_link;

/* A patch or sub-patch: a triangle (nv = 3) or a quad (nv = 4) in world
 * space, counter-clockwise around the patch normal. */
typedef struct rad_elem {
    vec3 p[4];
    vec3 c;              /* centroid */
    float area, radius;  /* radius: largest corner distance from c */
    uint32_t patch;      /* input patch */
    uint32_t child;      /* first of 4 children, RAD_NONE for a leaf; owner thread only */
    uint32_t child_pub;  /* the same, as published between passes: what sources see */
    uint32_t parent;     /* RAD_NONE for a patch's root */
    uint32_t link_off, nlinks;  /* in the patch's link block */
    uint64_t key;        /* stable id from the patch and the child path (seeds rays) */
    vec3 Bd;             /* direct part: emission + one bounce of emitted light */
    vec3 Hm;             /* irradiance from lamps seen in plane mirrors (leaves; rad_mirror_leaf) */
    float hk, hkd;       /* a leaf's scale, minus 1, of what its ancestors' links bring it, and
                          * of their direct part (rad_leaf_scales; 0 until the last pass) */
    float exposed;       /* the part of its area not inside an object standing on it (rad_exposure) */
    uint8_t nv, depth;
    uint8_t hm_done;     /* Hm computed */
} rad_elem;

/* An input polygon: a scene triangle or a quad rebuilt from two triangles. */
typedef struct rad_patch {
    vec3 n;              /* unit normal of the front side */
    vec3 rho;            /* diffuse reflectance: what the solution shows */
    vec3 rho_t;          /* what it passes on: rho plus its glossy and mirror
                          * layers' reflectance, spread as if diffuse (rad_patch.c) */
    vec3 rho_ml;         /* the part of rho_t a plane mirror's lamp images pass on
                          * instead (rad_mirror.c): not applied to its direct light */
    vec3 E;              /* emitted radiosity: pi * L_e */
    uint32_t node, mat;
    uint32_t tri;        /* its first scene triangle (a quad's second follows it) */
    uint32_t root;       /* root element */
    rad_link *links;     /* this patch tree's links */
    uint32_t nlinks;
    uint64_t want;       /* triangles its last refinement wanted beyond its quota */
    float open;          /* the part of its hemisphere its links see (rad_solve.c, patch_openness) */
    float ior;           /* glass: its index of refraction (its links weighed by rad_pane_reflectance); 0 */
    uint8_t direct;      /* emits or sees an emitter: the first pass's lit area (rad_solve.c) */
    uint8_t curved;      /* its shading normals leave its plane by over a degree (rad_ff_elem) */
} rad_patch;

/* A source cluster: a node of a binary BVH over input patches. A child is a
 * cluster (RAD_CLUSTER_BIT | index) or, for a single patch, its root element. */
typedef struct rad_cluster {
    bounds3 b;
    vec3 c;
    float radius, area;
    vec3 N;              /* area-weighted sum of its patches' normals */
    uint32_t child[2];
    uint32_t pbegin, pend;  /* range in rad_ctx.order */
    int has_emitter;
    /* Its patches' radiosity as seen from each axis direction (+x, -x, +y,
     * -y, +z, -z), per buffer (see rad_cluster_B): sums of B weighted by
     * area x openness x the patch normal's component towards that
     * direction, and the sums of those weights. */
    vec3 NB[2][6];
    float W[2][6];
    vec3 E;              /* area-weighted emission */
} rad_cluster;

/* An input patch's corners and normal in one cache line, in cluster order:
 * what cluster visibility rays sample. */
typedef struct rad_sgeo {
    vec3 p[4];
    vec3 n;
    uint32_t nv;
} rad_sgeo;

typedef struct rad_vis rad_vis;

typedef struct rad_ctx {
    const ct_scene *scene;
    rad_params prm;
    double eps;          /* absolute link error threshold (power) */
    double reflected_mean; /* area-weighted mean reflected radiosity of the last pass (0 in the first) */
    double min_area;     /* absolute */
    double total_area, emitted;
    uint32_t contact_vertices; /* mesh vertices given the value at a contact line (rad_contact.c) */

    uint32_t npatches;
    rad_patch *patches;

    uint32_t nclusters;
    rad_cluster *clusters;
    uint32_t *order;     /* patch ids in cluster order */
    rad_sgeo *sgeo;      /* their geometry, same order */
    double *sarea;       /* prefix sums of their areas, same order (npatches + 1) */
    double *spow;        /* prefix sums of their power, area x brightest channel of
                          * B, same order, made at each refinement pass's start
                          * (rad_cluster_hidden) */

    rad_elem **chunks;
    vec3 **bchunks[2];   /* radiosity per element, double-buffered by iteration
                          * parity, apart from the elements so the gather's
                          * random reads stay in cache */
    uint32_t nelems;     /* allocated elements */
    pthread_mutex_t alloc_lock;

    int cur;             /* which B buffer holds the current solution */
    int pass;

    rad_vis *vis;
    struct ct_pool *pool; /* the solver's threads (prm.threads, the caller
                           * included; NULL: the caller alone) */

    /* Lamps seen in plane mirrors (rad_mirror.c): a tracer scene of the
     * scene's own triangles, its lamps and mirrors; all NULL without a
     * plane mirror or with mirror_samples 0. */
    struct emb_scene *memb;
    struct light_set *mlamps;
    struct mlight_set *mirrors;

    atomic_uint_fast64_t bytes;     /* tracked memory */
    atomic_uint_fast64_t peak;
    uint64_t cap_bytes;
    atomic_int over_cap;
    atomic_uint_fast64_t est_tris;  /* estimated output triangles */
    uint64_t pass_budget;           /* --max-triangles minus est_tris at the pass start */
    uint64_t want_total;            /* sum of the patches' want after the last pass (0 before the first) */
    atomic_uint_fast64_t rays;
    atomic_uint_fast64_t refined;   /* links refined in this pass */
    atomic_int failed;
} rad_ctx;

static inline rad_elem *rad_el(const rad_ctx *c, uint32_t i)
{
    return &c->chunks[i >> RAD_CHUNK_SHIFT][i & (RAD_CHUNK - 1)];
}

/* Cluster k's radiosity in buffer b as a receiver at point x sees it: the
 * mean of its patches' radiosity weighted by area x openness x how much of
 * each faces x. The facing term cos+(n . w) towards w = x - centre is taken
 * as sum_i |w_i| [n_i has w_i's sign] |n_i| (exact for axis-aligned
 * patches, a blend of the axis directions otherwise), so the six sums of
 * the cluster (NB, W) give it for any x. A plain mean counted the dark
 * undersides of furniture in what a ceiling sees of it and the lit tops in
 * what the floor sees: a closed box with 60 boxes in it absorbed 98.8 %
 * of the emitted power, 99.4 % with this (docs/radiosity.md, "Energy with
 * occlusion"). */
static inline vec3 rad_cluster_B(const rad_cluster *k, int b, vec3 x)
{
    vec3 w = v3_sub(x, k->c);
    float wc[3] = {w.x, w.y, w.z};
    vec3 num = v3s(0.0f);
    float den = 0.0f;
    for (int i = 0; i < 3; i++) {
        int d = 2 * i + (wc[i] < 0.0f);
        float a = wc[i] < 0.0f ? -wc[i] : wc[i];
        num = v3_madd(num, k->NB[b][d], a);
        den += a * k->W[b][d];
    }
    if (!(den > 0.0f)) {
        /* x at the centre, or nothing faces it: the mean over all sides. */
        num = v3s(0.0f);
        den = 0.0f;
        for (int d = 0; d < 6; d++) {
            num = v3_add(num, k->NB[b][d]);
            den += k->W[b][d];
        }
    }
    return den > 0.0f ? v3_scale(num, 1.0f / den) : v3s(0.0f);
}

/* The brightest of cluster k's six sides in buffer b (per channel): no
 * receiver sees more of it (rad_cluster_B blends the sides). */
static inline vec3 rad_cluster_B_max(const rad_cluster *k, int b)
{
    vec3 m = v3s(0.0f);
    for (int d = 0; d < 6; d++)
        if (k->W[b][d] > 0.0f) m = v3_max(m, v3_scale(k->NB[b][d], 1.0f / k->W[b][d]));
    return m;
}

/* What cluster link l brings its receiver from a point x of it, per unit
 * of ff, in buffer b: the cluster's mean as x sees it times the link's bk
 * (1 until the last pass sets it, rad_cluster_bk). Only clusters without
 * a lamp get a bk other than 1, so their emission (the direct part) needs
 * no scaling. */
static inline vec3 rad_link_cluster_B(const rad_ctx *c, const rad_link *l, int b, vec3 x)
{
    return v3_scale(rad_cluster_B(&c->clusters[l->src & RAD_ID_MASK], b, x), l->bk);
}

/* Below this exposure an element counts as covered: its radiosity is
 * passed on as it is (rad_src_B). */
#define RAD_EXPOSED_MIN 0.25f

/* What element e (patch emission E) passes on from the exposed part of
 * its area: its mean radiosity B counts the part hidden under objects that
 * stand on it (dark: nothing reaches it), and a link's visibility rays from
 * there are blocked as well; taking the mean for the exposed part lost
 * that part twice (docs/radiosity.md, "Covered parts"). The element
 * buffers hold this value; rad_mean_B gives the mean back. */
static inline vec3 rad_src_B(vec3 B, vec3 E, float exposed)
{
    if (!(exposed >= RAD_EXPOSED_MIN) || exposed >= 1.0f) return B;
    return v3_add(E, v3_scale(v3_sub(B, E), 1.0f / exposed));
}
static inline vec3 rad_true_B(vec3 Bs, vec3 E, float exposed)
{
    if (!(exposed >= RAD_EXPOSED_MIN) || exposed >= 1.0f) return Bs;
    return v3_add(E, v3_scale(v3_sub(Bs, E), exposed));
}

/* Radiosity of element i in buffer b (0 or 1). */
static inline vec3 *rad_B(const rad_ctx *c, int b, uint32_t i)
{
    return &c->bchunks[b][i >> RAD_CHUNK_SHIFT][i & (RAD_CHUNK - 1)];
}

/* Element i's mean radiosity in buffer b (the buffers hold what it passes
 * on, rad_src_B): what it shows, and what a gathering point whose own
 * factors and visibility leave its covered part out reads of it. */
static inline vec3 rad_mean_B(const rad_ctx *c, int b, uint32_t i)
{
    const rad_elem *e = rad_el(c, i);
    return rad_true_B(*rad_B(c, b, i), c->patches[e->patch].E, e->exposed);
}

/* The share of the light arriving at cos (to its normal) that a pane of
 * glass of index ior reflects, its two faces and their interreflections:
 * 2 F / (1 + F), F the Fresnel reflectance of one face. */
static inline float rad_pane_reflectance(float ior, float cos)
{
    float ct, f = rmesh_fresnel(fabsf(cos), 1.0f / ior, &ct);
    return 2.0f * f / (1.0f + f);
}

/* What element e's own links bring it from buffer b: the irradiance into
 * *H and, with direct, the sources' emission in it into *Hd (push_pull in
 * rad_solve.c, and a leaf's links in rad_gather.c). On glass, what it
 * reflects: each link's light times the pane's reflectance at the angle
 * from which the source's centre arrives (what passes through goes on by
 * the links' visibility, docs/radiosity.md "Glass"). */
static inline void rad_elem_links(const rad_ctx *c, const rad_elem *e, int b, bool direct, vec3 *H, vec3 *Hd)
{
    const rad_patch *p = &c->patches[e->patch];
    vec3 h = v3s(0.0f), hd = v3s(0.0f);
    for (uint32_t i = 0; i < e->nlinks; i++) {
        const rad_link *l = &p->links[e->link_off + i];
        uint32_t src = l->src;
        bool cl = (src & RAD_CLUSTER_BIT) != 0;
        float ff = l->ff;
        if (p->ior > 0.0f) {
            vec3 d = v3_sub(cl ? c->clusters[src & RAD_ID_MASK].c : rad_el(c, src)->c, e->c);
            float len = v3_len(d);
            ff *= rad_pane_reflectance(p->ior, len > 0.0f ? v3_dot(d, p->n) / len : 1.0f);
        }
        vec3 B;
        if (cl) {
            B = rad_link_cluster_B(c, l, b, e->c);
            if (direct) hd = v3_madd(hd, c->clusters[src & RAD_ID_MASK].E, ff);
        } else {
            B = *rad_B(c, b, src);
            if (direct) hd = v3_madd(hd, c->patches[rad_el(c, src)->patch].E, ff);
        }
        h = v3_madd(h, B, ff);
    }
    *H = h;
    *Hd = hd;
}

/* --- rad_patch.c ---------------------------------------------------------- */

/* Builds input patches (quads rebuilt from triangle pairs), their root
 * elements and the cluster BVH. */
int rad_build_patches(rad_ctx *c, ct_error *err);

/* Allocates n consecutive elements; returns the first or RAD_NONE (cap hit). */
uint32_t rad_alloc_elems(rad_ctx *c, uint32_t n);

/* Creates the 4 children of element e (owner thread); returns 0 or < 0. */
int rad_subdivide(rad_ctx *c, uint32_t e);

/* The exposed part of element e's area (rad_contact.c): the share of a few
 * stratified points on it that are not hidden inside an object standing on
 * its surface (1 before the visibility scene exists). */
float rad_exposure(const rad_ctx *c, const rad_elem *e);

/* Adds (or subtracts, negative) tracked bytes; returns -1 when over the cap. */
int rad_track(rad_ctx *c, int64_t delta);

/* Frees patches, clusters and elements. */
void rad_free_patches(rad_ctx *c);

/* A point on element e at (u, v) in [0,1]^2 (quads: bilinear; triangles:
 * folded square). */
vec3 rad_elem_point(const rad_elem *e, float u, float v);

/* --- rad_visibility.c ----------------------------------------------------- */

/* An Embree scene of all scene triangles for occlusion queries. */
int rad_vis_new(const ct_scene *s, int threads, rad_vis **out, ct_error *err);

/* Frees it (NULL is fine). */
void rad_vis_free(rad_vis *v);

/* The fraction of light that passes the segment a -> b (both lifted off
 * their surfaces, rad_lift): 0 when something opaque blocks it, else the product of the
 * glass crossings' transmission and Fresnel factors (1 without glass; 0
 * after RMESH_MAX_GLASS_CROSSINGS). */
float rad_vis_transmit(const rad_vis *v, vec3 a, vec3 b);

/* Whether the nearest opaque surface along the ray from o in direction d
 * (any length) is seen from behind its winding's side; false when the ray
 * hits nothing or a front face. */
bool rad_vis_hits_back(const rad_vis *v, vec3 o, vec3 d);

/* Bytes Embree uses for the scene. */
uint64_t rad_vis_bytes(const rad_vis *v);

/* --- rad_contact.c --------------------------------------------------------- */

/* Mesh vertices hidden inside an object that stands on their surface (a
 * floor's corner under a box): each takes the radiosity gathered where its
 * edge to the brightest corner of one of its elements leaves the object,
 * so that Gouraud shading does not smear its darkness over the element's
 * visible part. nl elements leaf[i], the vertex groups of each on its
 * boundary loop bvert[boff[i] .. boff[i+1]); nv vertex groups at pos with
 * radiosity B and direct part Bd, changed in place; *moved counts them. */
int rad_contact_vertices(const rad_ctx *c, const uint32_t *leaf, size_t nl, const uint32_t *boff,
                         const uint32_t *bvert, uint32_t nv, const vec3 *pos, vec3 *B, vec3 *Bd, uint32_t *moved);

/* --- rad_mirror.c --------------------------------------------------------- */

/* Finds the scene's plane mirrors and builds what sampling the lamps seen
 * in them needs (nothing when there are none or mirror_samples is 0), and
 * sets rho_ml of the patches that lie on one of those mirrors. */
int rad_mirror_new(rad_ctx *c, ct_error *err);

/* Frees it. */
void rad_mirror_free(rad_ctx *c);

/* The irradiance from lamps seen in plane mirrors on leaf e, averaged
 * over mirror_samples random points of it (deterministic per element). */
vec3 rad_mirror_leaf(const rad_ctx *c, const rad_elem *e);

/* The same at a mesh vertex x (normal n) of the final gather; key seeds it. */
vec3 rad_mirror_point(const rad_ctx *c, vec3 x, vec3 n, uint64_t key);

/* --- rad_ff.c -------------------------------------------------------------- */

/* Random stream tags of a link's rays (rad_visibility). */
#define TAG_DECIDE 0x7669u   /* rays that decide whether a link is refined */
#define TAG_VALUE  0x7661u   /* rays of the factor a kept link carries */
#define TAG_RETEST 0x7265u   /* a second look before a link is dropped */
#define TAG_HIDDEN 0x6869u   /* a cluster's look before its link is refined */

/* Whether source src (element or cluster) emits. */
int rad_src_has_emitter(const rad_ctx *c, uint32_t src);

/* Unoccluded factor F(r <- s) between two elements and its spread dF over
 * r, integrated over the smaller one and turned by reciprocity. */
void rad_ff_elem(const rad_ctx *c, const rad_elem *r, const rad_elem *s, double *F, double *dF);

/* Whose points a link's rays take on a non-emitting source (a lamp's
 * links always take their own, rad_ff.c link_rng): the link's own, the
 * source's shared with every receiver, or those turned by an offset of
 * the receiver's (receiver_shift). */
typedef enum { RAD_RAYS_OWN = 0, RAD_RAYS_SHARED, RAD_RAYS_TURNED } rad_rays;

/* Visible fraction of source src seen from receiver r by nrays jittered,
 * kernel-weighted segments (stream tag, points as rays says); *nvalid the
 * segments traced; -1 when none could be. */
double rad_visibility(rad_ctx *c, const rad_elem *r, uint32_t src, int nrays, uint64_t tag, rad_rays rays,
                      int *nvalid);

/* r's average factor to cluster src, unoccluded (*F) and visible (*FV), by
 * Monte Carlo over the cluster's area. */
void rad_cluster_factor(rad_ctx *c, const rad_elem *r, uint32_t src, double *F, double *FV);

/* Whether all of nrays segments from points stratified over r to points
 * of cluster src drawn by power (c->spow) are blocked or meet a patch's
 * back: 1 when none got through, 0 at the first that did. */
int rad_cluster_hidden(rad_ctx *c, const rad_elem *r, uint32_t src, int nrays);

/* Sets bk of patch p's links from non-emitting clusters from their own
 * rays again and the current solution; the others keep 1. */
void rad_cluster_bk(rad_ctx *c, uint32_t p);

/* Fills c->spow from the current solution (rad_cluster_hidden). */
void rad_cluster_power(rad_ctx *c);

/* Visible fraction of source src (element or cluster) seen from point x
 * with normal n, by nrays kernel-weighted rays seeded by key; -1 when no
 * part of the source is in front of x. */
float rad_point_visibility(const rad_ctx *c, vec3 x, vec3 n, uint32_t src, int nrays, uint64_t key);

/* --- rad_link.c ----------------------------------------------------------- */

/* Per-thread scratch of the refinement. */
typedef struct rad_out_link {
    uint32_t e;
    rad_link l;
} rad_out_link;

/* A link being refined: kept from the last pass, or new (fresh: to be
 * evaluated), with its error at the current radiosity. */
typedef struct rad_cand {
    rad_link l;
    float err;
    int fresh;
} rad_cand;

typedef struct rad_tls {
    rad_out_link *out;
    size_t nout, capout;
    uint32_t *elems;           /* the tree's elements, DFS order */
    size_t nelems, capelems;
    uint32_t *stack;
    size_t capstack;
    rad_cand *work;            /* candidate links, a stack of per-element lists */
    size_t nwork, capwork;
    int64_t quota;             /* triangles the patch being refined may still add */
    uint64_t want;             /* ...and those its quota refused */
} rad_tls;

/* A ray end point lifted off its surface at p (normal n) past the float
 * error of p, and the rounding a position test near centre c (radius r)
 * allows: both follow the coordinates' magnitude where they are taken, not
 * the scene's size. Up to solver version 18 both were shares of the scene's
 * bounding diagonal, which a large ground plane made centimetres: a closed
 * 2 m room on a 2 km plane saw its lamp through its own ceiling and leaked
 * light to the ground (docs/radiosity.md, "Scale"). */
static inline vec3 rad_lift(vec3 p, vec3 n) { return emb_offset_ray(p, n); }
static inline float rad_pos_tol(vec3 c, float r)
{
    float m = fmaxf(fmaxf(fabsf(c.x), fabsf(c.y)), fmaxf(fabsf(c.z), 1.0f / 32.0f));
    return 1e-6f * (m + r);
}

/* Estimated output triangles that splitting e adds (its 4 children replace
 * it; T-vertices of the neighbours included). */
static inline unsigned rad_split_tris(const rad_elem *e) { return e->nv == 4 ? 10u : 6u; }

/* Refines the links of every element of patch p's tree (the current pass's
 * B is the error oracle's estimate); the new links replace the old block. */
int rad_refine_patch(rad_ctx *c, rad_tls *t, uint32_t p);

/* Frees a thread's scratch. */
void rad_tls_free(rad_tls *t);

/* --- rad_mesh.c ----------------------------------------------------------- */

/* The scene's shading normal at point q of patch pa (its plane's where the
 * interpolation fails). */
vec3 rad_shade_normal(const rad_ctx *c, const rad_patch *pa, vec3 q);

/* Meshes the leaves into a conforming triangle mesh with per-vertex values. */
int rad_mesh_build(rad_ctx *c, ct_radmesh *out, ct_error *err);

/* --- rad_gather.c --------------------------------------------------------- */

/* What the final gather reads per element (by element id): the sums over
 * its links whose factor is the same at every vertex (clusters, and
 * factors flat over the element), and the others, to be taken at each
 * vertex, as indices into the patch's link block. */
typedef struct rad_gather_prep {
    vec3 *flat, *flat_d;     /* sum of ff * B and of ff * E of the flat links (B as seen_B) */
    vec3 *flat_p;            /* the same with the sources' means */
    uint32_t *off;           /* first entry of an element's other links in idx (nelems + 1) */
    uint32_t *idx;
    float *spread;           /* per element: its leaves' largest minus smallest radiosity (seen_B) */
} rad_gather_prep;

/* Fills g from the final links; CT_ENOMEM when out of memory. */
int rad_gather_prepare(const rad_ctx *c, rad_gather_prep *g);

/* Frees g's arrays. */
void rad_gather_prep_free(rad_gather_prep *g);

/* Sets hk and hkd of patch p's leaves: what their ancestors' links bring
 * them with each non-flat link shared out by the leaves' centres' factors,
 * against the ancestors' mean factors (rad_gather.c); CT_ENOMEM. */
int rad_leaf_scales(rad_ctx *c, uint32_t p);

/* A gathering thread's scratch: the partly hidden links of one vertex. */
typedef struct rad_partial {
    uint32_t src;
    float vis, f0;       /* the link's visibility, the unoccluded factor at the vertex */
    vec3 B, E;
    double s;            /* sampling weight */
} rad_partial;

typedef struct rad_gather_scratch {
    rad_partial *v;
    size_t n, cap;
} rad_gather_scratch;

void rad_gather_scratch_free(rad_gather_scratch *w);

/* The final gather at a mesh vertex x of leaf (normal n): the irradiance H
 * and its direct part Hd over the links of the leaf and its ancestors, each
 * element source's factor taken at x itself, and with --vertex-rays the
 * visibility of partly hidden sources seen from x itself. */
void rad_final_gather(const rad_ctx *c, const rad_gather_prep *g, rad_gather_scratch *w, uint32_t leaf, vec3 x,
                      vec3 n, vec3 *H, vec3 *Hd);

/* Radiosity B and its direct part Bd at the n points pos[g], each on leaf
 * leaf[g], facing nrm[g] (NULL: the leaves' planes' normals)
 * (rad_final_gather, plus lamps seen in mirrors), on c->prm.threads
 * threads. CT_OK or CT_ENOMEM. */
int rad_gather_points(const rad_ctx *c, const uint32_t *leaf, const vec3 *pos, const vec3 *nrm, uint32_t n, vec3 *B,
                      vec3 *Bd);

/* The final gather at the n leaves' centres, as the solve's values (B: E
 * plus what the leaf passes on, rho_t and rho_ml as push_pull; Bd: its
 * direct part; H: its irradiance), their gathered light scaled to what
 * their links bring over all of them; CT_OK or CT_ENOMEM. */
int rad_gather_leaves(const rad_ctx *c, const uint32_t *leaf, uint32_t n, vec3 *B, vec3 *Bd, vec3 *H);

#endif
