/* lights.c: light sampling (lights.h). Over 600 lines on purpose: the
 * emitter records, the grid of candidates, their vectorized weighing and
 * the pdfs that MIS needs must agree exactly, so they stay in one file. */
#include "tracer/lights.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"
#include "tracer/bsdf.h"

/* Grid cells of the visibility estimate: about this many over the scene's
 * bounding box, and at most LIGHT_GRID_BYTES of candidate lists in all. */
#define LIGHT_GRID_CELLS 32768
#define LIGHT_GRID_BYTES (16u << 20)
/* Sides of a cell: the six axis directions a surface's normal is closest to. */
#define LIGHT_SIDES 6
/* The estimate's own seed: an importance function, independent of --seed. */
#define LIGHT_VIS_SEED 0x6c696768745f7631ULL

/* Surface points of the build-time test whether the per-point choice pays
 * (spatial_gain), and the gain it must reach. The choice costs about 13 % of
 * path tracing's time where it is cheapest (two emitters); the gain bounds
 * the variance it can save from above (area sampling and visibility add
 * noise of their own), so below 1.2 it cannot pay. */
#define LIGHT_GAIN_PROBES 512
#define LIGHT_SPATIAL_MIN_GAIN 1.2

/* Emitters weaker than this fraction of a cell's strongest get no test rays. */
#define LIGHT_VIS_SKIP 0.01f
/* Glass surfaces a test ray may cross (a stack of panes). */
#define LIGHT_GLASS_CROSSINGS 8

enum { CELL_EMPTY = 0, CELL_BUSY = 1, CELL_READY = 2 };

/* The emitters a (cell, side) weighs at each of its shading points: the
 * LIGHT_CANDS strongest by estimated contribution, with their test results. */
typedef struct key_cands {
    uint8_t n;
    uint8_t idx[LIGHT_CANDS];
    uint8_t vis[LIGHT_CANDS];   /* unblocked test rays of LIGHT_VIS_RAYS */
} key_cands;

/* One (cell, side) in the grid: its state and candidates in 32 bytes on one
 * cache line (each shading point reads a key at random: one miss, not two).
 * The visibility counts (0..LIGHT_VIS_RAYS) are packed two per byte. */
typedef struct grid_key {
    atomic_uchar state;         /* CELL_*: the rest is valid once READY */
    uint8_t n;
    uint8_t idx[LIGHT_CANDS];
    uint8_t vis2[LIGHT_CANDS / 2];
} __attribute__((aligned(32))) grid_key;
_Static_assert(sizeof(grid_key) == 32, "a grid key fills half a cache line");
_Static_assert(LIGHT_VIS_RAYS < 16, "visibility counts are packed in 4 bits");

typedef struct emitter {
    vec3 c;            /* centre of the bounding box */
    vec3 n;            /* common front normal when flat */
    float r2;          /* squared bounding radius (> 0) */
    float power;       /* sum of area * lum(L_e) */
    bool flat;         /* all triangles in one plane, facing one way */
    uint32_t first, count;   /* its lights: [first, first + count) */
} emitter;

/* Four floats or ints in one register (GCC and Clang vector extensions). */
typedef float v4f __attribute__((vector_size(16)));
typedef int32_t v4i __attribute__((vector_size(16)));

/* What light_select weighs of one emitter, in two vector registers: four
 * candidates' records load as eight vectors and transpose into columns with
 * eight shuffles (gathering the columns lane by lane took 36 inserts, the
 * better part of the weighing's time). */
typedef struct em_rec {
    v4f a;   /* centre x, y, z; squared bounding radius, negated when flat */
    v4f b;   /* front normal x, y, z (zero when not flat); power */
} em_rec;

struct light_set {
    const emb_scene *emb;
    const emb_mesh *mesh;
    uint32_t n;          /* emissive triangles, grouped by emitter */
    uint32_t *tri;
    vec3 *nrm;           /* their unit front normals */
    vec3 *geo;           /* per light: vertex 0, edge 1 - 0, edge 2 - 0, L_e (no index lookups) */
    float *cdf;          /* per light: cumulative power within its emitter, ends at 1 */
    float *pdf_in;       /* per mesh triangle: lum(L_e) / power of its emitter */
    uint32_t *tri_em;    /* per mesh triangle: its emitter, UINT32_MAX if not a light */
    uint32_t ne;
    emitter *em;
    em_rec *rec;         /* per emitter, for the per-point choice */
    float *em_cdf;       /* ne + 1 entries: emitters by power */
    /* The visibility grid (only with 2..LIGHT_SEL_MAX emitters). */
    bool spatial;
    double gain;                 /* spatial_gain; 0 where not estimated (see light_spatial_gain) */
    vec3 lo;
    float h;
    uint32_t nx, ny, nz;
    grid_key *keys;              /* per key (cell * 6 + side) */
};

/* Below this many entries a CDF is searched by counting instead of
 * bisecting: the count has no data-dependent branch, and a bisection's
 * branches (one per halving, taken at random) mispredicted about every
 * other time. */
#define CDF_SCAN_MAX 32

/* Number of a[0..n) <= u: for a non-decreasing a, the first index whose
 * entry exceeds u. */
static inline uint32_t count_le(const float *a, uint32_t n, float u)
{
    uint32_t c = 0;
    for (uint32_t i = 0; i < n; i++) c += a[i] <= u;
    return c;
}

static uint32_t emitter_of_cdf(const float *cdf, uint32_t n, float u)
{
    /* First index whose cdf[i + 1] > u (n - 1 when none). */
    if (n <= CDF_SCAN_MAX) return count_le(cdf + 1, n - 1, u);
    uint32_t lo = 0, hi = n - 1;
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (cdf[mid + 1] > u) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

/* Bounds, power and flatness of each emitter from its lights. */
static void describe_emitters(light_set *l)
{
    const emb_mesh *m = l->mesh;
    for (uint32_t e = 0; e < l->ne; e++) {
        emitter *em = &l->em[e];
        vec3 lo = v3s(INFINITY), hi = v3s(-INFINITY);
        double power = 0.0;
        for (uint32_t i = em->first; i < em->first + em->count; i++) {
            const uint32_t *vi = m->tris + 3 * (size_t)l->tri[i];
            for (int k = 0; k < 3; k++) {
                lo = v3_min(lo, m->pos[vi[k]]);
                hi = v3_max(hi, m->pos[vi[k]]);
            }
            power += (double)emb_tri_area(m, l->tri[i]) * v3_luminance(l->geo[4 * (size_t)i + 3]);
        }
        em->c = v3_scale(v3_add(lo, hi), 0.5f);
        vec3 half = v3_scale(v3_sub(hi, lo), 0.5f);
        em->r2 = bsdf_maxf(v3_len2(half), 1e-12f);
        em->power = (float)power;
        /* Flat: every vertex within a hair of the first light's plane and
         * every normal the same, so a point behind that plane gets nothing. */
        em->n = l->nrm[em->first];
        em->flat = true;
        float tol = 1e-4f * sqrtf(em->r2);
        for (uint32_t i = em->first; i < em->first + em->count && em->flat; i++) {
            if (v3_dot(l->nrm[i], em->n) < 0.9999f) em->flat = false;
            const uint32_t *vi = m->tris + 3 * (size_t)l->tri[i];
            for (int k = 0; k < 3; k++)
                if (fabsf(v3_dot(v3_sub(m->pos[vi[k]], em->c), em->n)) > tol) em->flat = false;
        }
    }
}

/* mask ? a : b per lane (mask lanes all ones or zero, as comparisons give). */
static inline v4f select4(v4i mask, v4f a, v4f b) { return (v4f)(((v4i)a & mask) | ((v4i)b & ~mask)); }

/* The rows r0..r3 (x, y, z, w each) as columns: col[0] the four x. */
static inline void transpose4(v4f r0, v4f r1, v4f r2, v4f r3, v4f col[4])
{
    v4f t0 = __builtin_shufflevector(r0, r1, 0, 4, 1, 5), t1 = __builtin_shufflevector(r2, r3, 0, 4, 1, 5);
    v4f t2 = __builtin_shufflevector(r0, r1, 2, 6, 3, 7), t3 = __builtin_shufflevector(r2, r3, 2, 6, 3, 7);
    col[0] = __builtin_shufflevector(t0, t1, 0, 1, 4, 5);
    col[1] = __builtin_shufflevector(t0, t1, 2, 3, 6, 7);
    col[2] = __builtin_shufflevector(t2, t3, 0, 1, 4, 5);
    col[3] = __builtin_shufflevector(t2, t3, 2, 3, 6, 7);
}

/* The emitters' weighing records (light_select). */
static int build_rec(light_set *l)
{
    l->rec = aligned_alloc(sizeof(em_rec), (l->ne ? l->ne : 1) * sizeof *l->rec);
    if (!l->rec) return CT_ENOMEM;
    for (uint32_t k = 0; k < l->ne; k++) {
        const emitter *em = &l->em[k];
        vec3 n = em->flat ? em->n : v3s(0.0f);
        l->rec[k].a = (v4f){em->c.x, em->c.y, em->c.z, em->flat ? -em->r2 : em->r2};
        l->rec[k].b = (v4f){n.x, n.y, n.z, em->power};
    }
    return CT_OK;
}

/* The cell grid over the mesh's bounding box. */
static int build_grid(light_set *l)
{
    const emb_mesh *m = l->mesh;
    vec3 lo = v3s(INFINITY), hi = v3s(-INFINITY);
    for (uint32_t i = 0; i < m->nverts; i++) {
        lo = v3_min(lo, m->pos[i]);
        hi = v3_max(hi, m->pos[i]);
    }
    vec3 ext = v3_sub(hi, lo);
    float big = fmaxf(ext.x, fmaxf(ext.y, ext.z));
    if (!(big > 0.0f) || !isfinite(big)) return CT_OK;   /* no extent: no grid, pick by power */
    uint32_t budget = LIGHT_GRID_BYTES / (LIGHT_SIDES * (uint32_t)sizeof(grid_key));
    if (budget > LIGHT_GRID_CELLS) budget = LIGHT_GRID_CELLS;
    /* Cubic cells; flat axes get one cell. */
    double vol = (double)fmaxf(ext.x, big * 1e-3f) * fmaxf(ext.y, big * 1e-3f) * fmaxf(ext.z, big * 1e-3f);
    float h = (float)cbrt(vol / budget);
    uint32_t n[3];
    float e3[3] = {ext.x, ext.y, ext.z};
    for (;;) {
        uint64_t cells = 1;
        for (int k = 0; k < 3; k++) {
            double c = ceil(e3[k] / h);
            n[k] = c < 1.0 ? 1u : c > 1024.0 ? 1024u : (uint32_t)c;
            cells *= n[k];
        }
        if (cells <= budget) break;
        h *= 1.1f;
    }
    l->lo = lo;
    l->h = h;
    l->nx = n[0], l->ny = n[1], l->nz = n[2];
    size_t keys = (size_t)n[0] * n[1] * n[2] * LIGHT_SIDES;
    l->keys = aligned_alloc(sizeof(grid_key), keys * sizeof *l->keys);
    if (!l->keys) return CT_ENOMEM;
    memset(l->keys, 0, keys * sizeof *l->keys);
    for (size_t i = 0; i < keys; i++) atomic_init(&l->keys[i].state, CELL_EMPTY);
    l->spatial = true;
    return CT_OK;
}

/* The weight light_select gives emitter k at x, without the visibility
 * factor (see lights.h). */
static float emitter_weight(const light_set *l, uint32_t k, vec3 x)
{
    const emitter *em = &l->em[k];
    vec3 dv = v3_sub(x, em->c);
    float m = bsdf_maxf(v3_len2(dv), em->r2);
    float w = em->power / m;
    if (em->flat) {
        float c = v3_dot(dv, em->n);
        w = c > 0.0f ? w * c / sqrtf(m) : 0.0f;
    }
    return isfinite(w) ? w : 0.0f;
}

/* What picking emitters per shading point could gain over picking them by
 * power. At LIGHT_GAIN_PROBES points spread by area over all surfaces: the
 * second moment of the one-sample estimate of the emitters' summed weights
 * (w_k, visibility left out) when emitter k is picked with its power share
 * P_k, relative to its value under the ideal choice w_k / W, that is
 * sum_k (w_k / W)^2 / P_k (1 where the weights follow the powers), averaged
 * over the points where any w_k > 0. A pure function of the mesh; 1 when no
 * point can be judged. */
static double spatial_gain(const light_set *l)
{
    const emb_mesh *m = l->mesh;
    double *acdf = malloc(((size_t)m->ntris + 1) * sizeof *acdf);
    if (!acdf) return INFINITY;   /* cannot judge: keep the per-point choice */
    acdf[0] = 0.0;
    for (uint32_t t = 0; t < m->ntris; t++)
        acdf[t + 1] = acdf[t] + (double)emb_tri_area(m, t);
    double area = acdf[m->ntris], total = 0.0, sum = 0.0;
    for (uint32_t k = 0; k < l->ne; k++) total += l->em[k].power;
    int used = 0;
    ct_rng r = rng_make(LIGHT_VIS_SEED, UINT64_MAX, 0, 0);
    for (int i = 0; i < LIGHT_GAIN_PROBES && area > 0.0 && total > 0.0; i++) {
        double u = rng_float(&r) * area;
        uint32_t lo = 0, hi = m->ntris - 1;   /* the triangle t with acdf[t] <= u < acdf[t + 1] */
        while (lo < hi) {
            uint32_t mid = (lo + hi) / 2;
            if (acdf[mid + 1] > u) hi = mid;
            else lo = mid + 1;
        }
        float u1 = rng_float(&r), u2 = rng_float(&r);
        vec3 x = emb_tri_point(m, lo, 1.0f - sqrtf(u1), u2 * sqrtf(u1));
        double w[LIGHT_SEL_MAX], W = 0.0;
        for (uint32_t k = 0; k < l->ne; k++) W += w[k] = emitter_weight(l, k, x);
        if (!(W > 0.0)) continue;
        double f = 0.0;
        for (uint32_t k = 0; k < l->ne; k++)
            if (w[k] > 0.0) f += (w[k] / W) * (w[k] / W) / (l->em[k].power / total);
        sum += f;
        used++;
    }
    free(acdf);
    return used ? sum / used : 1.0;
}

int light_build(const emb_scene *e, light_set **out, ct_error *err)
{
    *out = NULL;
    const emb_mesh *m = emb_get_mesh(e);
    light_set *l = calloc(1, sizeof *l);
    if (!l) return ct_fail(err, CT_ENOMEM, "out of memory");
    l->emb = e;
    l->mesh = m;
    size_t nt = m->ntris ? m->ntris : 1;
    l->pdf_in = calloc(nt, sizeof *l->pdf_in);
    l->tri_em = calloc(nt, sizeof *l->tri_em);
    uint32_t *node_em = malloc((m->nnodes ? m->nnodes : 1) * sizeof *node_em);
    uint32_t *fill = NULL;
    if (!l->pdf_in || !l->tri_em || !node_em) goto oom;
    /* Emitters: the emissive triangles of one part node, numbered in order
     * of first appearance (deterministic for a given mesh). tri_em is
     * UINT32_MAX for every triangle that is not a light. */
    for (uint32_t i = 0; i < m->nnodes; i++) node_em[i] = UINT32_MAX;
    for (uint32_t t = 0; t < m->ntris; t++) {
        l->tri_em[t] = UINT32_MAX;
        uint32_t node = m->tri_node[t];
        /* (node < nnodes: emb_new validated the mesh; belt and braces) */
        if (!(v3_luminance(m->mats[m->tri_mat[t]].emission) > 0.0f && emb_tri_area(m, t) > 0.0f) ||
            node >= m->nnodes)
            continue;
        l->n++;
        if (node_em[node] == UINT32_MAX) node_em[node] = l->ne++;
        l->tri_em[t] = node_em[node];
    }
    size_t nl = l->n ? l->n : 1;
    l->tri = malloc(nl * sizeof *l->tri);
    l->cdf = malloc(nl * sizeof *l->cdf);
    l->nrm = malloc(nl * sizeof *l->nrm);
    l->geo = malloc(nl * 4 * sizeof *l->geo);
    l->em = calloc(l->ne ? l->ne : 1, sizeof *l->em);
    l->em_cdf = malloc(((size_t)l->ne + 1) * sizeof *l->em_cdf);
    fill = calloc(l->ne ? l->ne : 1, sizeof *fill);
    if (!l->tri || !l->cdf || !l->nrm || !l->geo || !l->em || !l->em_cdf || !fill) goto oom;
    /* Lights grouped by emitter (a counting sort), mesh order within one. */
    for (uint32_t t = 0; t < m->ntris; t++)
        if (l->tri_em[t] != UINT32_MAX) l->em[l->tri_em[t]].count++;
    for (uint32_t k = 0, acc = 0; k < l->ne; k++) {
        l->em[k].first = acc;
        acc += l->em[k].count;
    }
    for (uint32_t t = 0; t < m->ntris; t++) {
        uint32_t k = l->tri_em[t];
        if (k == UINT32_MAX) continue;
        uint32_t i = l->em[k].first + fill[k]++;
        l->tri[i] = t;
        l->nrm[i] = emb_tri_normal(m, t);
        const uint32_t *vi = m->tris + 3 * (size_t)t;
        l->geo[4 * (size_t)i] = m->pos[vi[0]];
        l->geo[4 * (size_t)i + 1] = v3_sub(m->pos[vi[1]], m->pos[vi[0]]);
        l->geo[4 * (size_t)i + 2] = v3_sub(m->pos[vi[2]], m->pos[vi[0]]);
        l->geo[4 * (size_t)i + 3] = m->mats[m->tri_mat[t]].emission;
    }
    describe_emitters(l);
    /* Cumulative sums in double: thousands of small radiosity triangles
     * would lose precision summed in float. */
    double total = 0.0;
    for (uint32_t k = 0; k < l->ne; k++) total += l->em[k].power;
    double acc_e = 0.0;
    l->em_cdf[0] = 0.0f;
    for (uint32_t k = 0; k < l->ne; k++) {
        emitter *em = &l->em[k];
        acc_e += em->power;
        l->em_cdf[k + 1] = (float)(acc_e / total);
        double acc = 0.0;
        for (uint32_t i = em->first; i < em->first + em->count; i++) {
            uint32_t t = l->tri[i];
            float lum = v3_luminance(l->geo[4 * (size_t)i + 3]);
            acc += (double)emb_tri_area(m, t) * lum;
            l->cdf[i] = (float)(acc / em->power);
            l->pdf_in[t] = (float)(lum / em->power);
        }
        l->cdf[em->first + em->count - 1] = 1.0f;
    }
    if (l->ne) l->em_cdf[l->ne] = 1.0f;
    if (l->ne >= 2 && l->ne <= LIGHT_SEL_MAX) {
        l->gain = spatial_gain(l);
        /* The weighing records and the grid serve the per-point choice only. */
        if (!(l->gain < LIGHT_SPATIAL_MIN_GAIN) && (build_rec(l) != CT_OK || build_grid(l) != CT_OK)) goto oom;
    }
    free(node_em);
    free(fill);
    *out = l;
    return CT_OK;
oom:
    free(node_em);
    free(fill);
    light_free(l);
    return ct_fail(err, CT_ENOMEM, "out of memory for the light list");
}

void light_free(light_set *l)
{
    if (!l) return;
    free(l->tri);
    free(l->cdf);
    free(l->nrm);
    free(l->geo);
    free(l->pdf_in);
    free(l->tri_em);
    free(l->em);
    free(l->em_cdf);
    free(l->rec);
    free(l->keys);
    free(l);
}

uint32_t light_count(const light_set *l) { return l->n; }

uint32_t light_emitters(const light_set *l) { return l->ne; }

bool light_is_spatial(const light_set *l) { return l->spatial; }

double light_spatial_gain(const light_set *l) { return l->gain; }

/* The light of emitter em that v in [0, 1) picks by power (the emitter's
 * cdf has no leading 0). */
static uint32_t light_of_emitter(const light_set *l, const emitter *em, float v)
{
    if (em->count <= CDF_SCAN_MAX) return em->first + count_le(l->cdf + em->first, em->count - 1, v);
    uint32_t lo = em->first, hi = em->first + em->count - 1;
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (l->cdf[mid] > v) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

/* The point of light i at two uniform numbers, uniform by area. */
static vec3 light_point_at(const light_set *l, uint32_t i, float u1, float u2)
{
    float su = sqrtf(u1);
    float b1 = 1.0f - su, b2 = u2 * su;
    const vec3 *g = l->geo + 4 * (size_t)i;
    return v3_add(g[0], v3_add(v3_scale(g[1], b1), v3_scale(g[2], b2)));
}

/* A point on emitter k's lights, picked by power, from three numbers. */
static vec3 emitter_point(const light_set *l, uint32_t k, float u0, float u1, float u2)
{
    return light_point_at(l, light_of_emitter(l, &l->em[k], u0), u1, u2);
}

/* Whether light passes from p along d for dist: nothing blocks it but
 * dielectrics (shadow rays pass glass, attenuated; an estimate that counted
 * glass as a wall would starve the lights seen through a glass partition). */
static bool open_line(const light_set *l, vec3 p, vec3 d, float dist)
{
    if (!emb_occluded(l->emb, p, d, 0.0f, dist)) return true;
    float t0 = 0.0f;
    for (int k = 0; k < LIGHT_GLASS_CROSSINGS; k++) {
        emb_hit h;
        if (!emb_intersect(l->emb, p, d, t0, dist, &h)) return true;
        if (!l->mesh->mats[h.mat].dielectric) return false;
        /* Continue just past the glass surface (relative step: scale free). */
        t0 = h.t + fmaxf(h.t, 1.0f) * 1e-5f;
    }
    return false;
}

/* A point of a surface in the cell whose normal is closest to side's axis,
 * found by a ray from the cell's face on that side inwards (so a wall
 * through the cell is seen from the side its surface faces), pushed off the
 * surface; the cell volume's point p when no such surface is met. */
static vec3 probe_point(const light_set *l, vec3 base, int side, ct_rng *r)
{
    int axis = side / 2;
    float sign = side % 2 ? -1.0f : 1.0f;
    float c[3];
    for (int k = 0; k < 3; k++) c[k] = rng_float(r) * l->h;   /* (an initializer list's order is unspecified) */
    vec3 vol = v3_add(base, v3(c[0], c[1], c[2]));
    c[axis] = sign > 0.0f ? l->h : 0.0f;
    vec3 o = v3_add(base, v3(c[0], c[1], c[2]));
    float dd[3] = {0.0f, 0.0f, 0.0f};
    dd[axis] = -sign;
    vec3 d = v3(dd[0], dd[1], dd[2]);
    emb_hit h;
    if (!emb_intersect(l->emb, o, d, 0.0f, l->h, &h)) return vol;
    vec3 ng = emb_tri_normal(l->mesh, h.tri);
    if (-v3_dot(ng, d) <= 0.0f) return vol;   /* a back face: not this side's surface */
    vec3 q = v3_add(o, v3_scale(d, h.t));
    return v3_add(q, v3_scale(ng, 1e-4f * l->h));
}

/* The candidates of (cell, side) (ix, iy, iz, side): emitters scored by
 * their unblocked contribution at the cell centre times the visibility
 * factor of LIGHT_VIS_RAYS test rays between points of surfaces facing
 * `side` in the cell and the emitter; the best LIGHT_CANDS of those with at
 * least LIGHT_CAND_MIN_SHARE of the summed scores. Emitters under
 * LIGHT_VIS_SKIP of the strongest are left to the defensive picks (no rays).
 * A pure function of the key. */
static void estimate_key(const light_set *l, uint32_t key, uint32_t ix, uint32_t iy, uint32_t iz, int side,
                         key_cands *out)
{
    memset(out, 0, sizeof *out);   /* the grid key stores all LIGHT_CANDS slots */
    vec3 base = v3_add(l->lo, v3((float)ix * l->h, (float)iy * l->h, (float)iz * l->h));
    vec3 pts[LIGHT_VIS_RAYS];
    ct_rng r = rng_make(LIGHT_VIS_SEED, key, 0, 0);
    for (int j = 0; j < LIGHT_VIS_RAYS; j++) pts[j] = probe_point(l, base, side, &r);
    vec3 mid = v3_add(base, v3s(0.5f * l->h));
    float wmax = 0.0f, wk[LIGHT_SEL_MAX], score[LIGHT_SEL_MAX];
    uint8_t vis[LIGHT_SEL_MAX];
    for (uint32_t k = 0; k < l->ne; k++) {
        wk[k] = l->em[k].power / bsdf_maxf(v3_len2(v3_sub(mid, l->em[k].c)), l->em[k].r2);
        wmax = bsdf_maxf(wmax, wk[k]);
    }
    for (uint32_t k = 0; k < l->ne; k++) {
        const emitter *em = &l->em[k];
        score[k] = 0.0f;
        vis[k] = 0;
        if (!(wk[k] >= LIGHT_VIS_SKIP * wmax)) continue;
        ct_rng rk = rng_make(LIGHT_VIS_SEED, key, k + 1, 0);
        int open = 0;
        for (int j = 0; j < LIGHT_VIS_RAYS; j++) {
            vec3 p = pts[j];
            float u0 = rng_float(&rk), u1 = rng_float(&rk), u2 = rng_float(&rk);
            vec3 q = emitter_point(l, k, u0, u1, u2);
            if (em->flat && v3_dot(v3_sub(p, q), em->n) <= 0.0f) continue;   /* behind it */
            vec3 d = v3_sub(q, p);
            float dist = v3_len(d);
            if (!(dist > 0.0f)) continue;
            d = v3_scale(d, 1.0f / dist);
            /* Stop short of the emitter so its own surface does not count. */
            if (open_line(l, p, d, dist * (1.0f - 1e-4f))) open++;
        }
        vis[k] = (uint8_t)open;
        score[k] = wk[k] * (LIGHT_VIS_FLOOR + (1.0f - LIGHT_VIS_FLOOR) * (float)open / (float)LIGHT_VIS_RAYS);
    }
    /* Emitters under LIGHT_CAND_MIN_SHARE of the total are left to the
     * defensive picks: nearly all are lights of other rooms that no test
     * ray reached (only the floor beta keeps their score above 0), and
     * weighing them at every shading point cost more than they saved. */
    float total = 0.0f;
    for (uint32_t k = 0; k < l->ne; k++) total += score[k];
    for (uint32_t k = 0; k < l->ne; k++)
        if (score[k] < LIGHT_CAND_MIN_SHARE * total) score[k] = 0.0f;
    /* The best LIGHT_CANDS by score (ties: lower index), in that order. */
    out->n = 0;
    bool taken[LIGHT_SEL_MAX] = {false};
    while (out->n < LIGHT_CANDS) {
        int best = -1;
        for (uint32_t k = 0; k < l->ne; k++)
            if (!taken[k] && score[k] > 0.0f && (best < 0 || score[k] > score[best])) best = (int)k;
        if (best < 0) break;
        taken[best] = true;
        out->idx[out->n] = (uint8_t)best;
        out->vis[out->n] = vis[best];
        out->n++;
    }
}

void light_select_power(light_sel *sel) { sel->n = 0; }

/* The grid key (cell * 6 + side) of x on a surface with normal n. */
static uint32_t key_of(const light_set *l, vec3 x, vec3 n)
{
    float f[3] = {(x.x - l->lo.x) / l->h, (x.y - l->lo.y) / l->h, (x.z - l->lo.z) / l->h};
    uint32_t lim[3] = {l->nx, l->ny, l->nz}, idx[3];
    for (int k = 0; k < 3; k++) {
        float c = floorf(f[k]);
        idx[k] = !(c >= 0.0f) ? 0u : c >= (float)lim[k] ? lim[k] - 1 : (uint32_t)c;
    }
    /* The side: the axis direction closest to the normal (+x, -x, +y, ...). */
    float an[3] = {fabsf(n.x), fabsf(n.y), fabsf(n.z)}, nc[3] = {n.x, n.y, n.z};
    int axis = an[0] >= an[1] && an[0] >= an[2] ? 0 : an[1] >= an[2] ? 1 : 2;
    int side = 2 * axis + (nc[axis] < 0.0f);
    return ((idx[2] * l->ny + idx[1]) * l->nx + idx[0]) * LIGHT_SIDES + (uint32_t)side;
}

uint32_t light_key(const light_set *l, vec3 x, vec3 n)
{
    if (!l->spatial) return LIGHT_NO_KEY;
    uint32_t key = key_of(l, x, n);
    __builtin_prefetch(&l->keys[key]);
    return key;
}

void light_select(const light_set *l, vec3 x, vec3 n, light_sel *sel)
{
    light_select_key(l, light_key(l, x, n), x, sel);
}

void light_select_key(const light_set *l, uint32_t key, vec3 x, light_sel *sel)
{
    sel->n = 0;
    if (!l->spatial || key == LIGHT_NO_KEY) return;
    grid_key *gk = &l->keys[key];
    key_cands kc;
    if (atomic_load_explicit(&gk->state, memory_order_acquire) == CELL_READY) {
        kc.n = gk->n;
        memcpy(kc.idx, gk->idx, sizeof kc.idx);
        for (uint32_t j = 0; j < LIGHT_CANDS; j++) kc.vis[j] = (uint8_t)(gk->vis2[j / 2] >> (4 * (j % 2)) & 15u);
    } else {
        uint32_t cell = key / LIGHT_SIDES;
        estimate_key(l, key, cell % l->nx, cell / l->nx % l->ny, cell / l->nx / l->ny, (int)(key % LIGHT_SIDES), &kc);
        unsigned char expect = CELL_EMPTY;
        if (atomic_compare_exchange_strong_explicit(&gk->state, &expect, CELL_BUSY, memory_order_acq_rel,
                                                    memory_order_acquire)) {
            gk->n = kc.n;
            memcpy(gk->idx, kc.idx, sizeof kc.idx);
            for (int j = 0; j < LIGHT_CANDS; j += 2) gk->vis2[j / 2] = (uint8_t)(kc.vis[j] | kc.vis[j + 1] << 4);
            atomic_store_explicit(&gk->state, CELL_READY, memory_order_release);
        }
    }
    /* Every candidate's weight (see lights.h), four at a time: the same
     * operations in the same order as one candidate at a time. Lanes past
     * kc.n weigh emitter 0 (kc.idx is zero there) and are ignored. */
    float w[LIGHT_CANDS];
    const v4f zero = {0.0f, 0.0f, 0.0f, 0.0f};
    const v4i sign = {INT32_MIN, INT32_MIN, INT32_MIN, INT32_MIN};
    for (uint32_t j0 = 0; j0 < kc.n; j0 += 4) {
        const em_rec *e0 = &l->rec[kc.idx[j0]], *e1 = &l->rec[kc.idx[j0 + 1]];
        const em_rec *e2 = &l->rec[kc.idx[j0 + 2]], *e3 = &l->rec[kc.idx[j0 + 3]];
        v4f a[4], b[4];
        transpose4(e0->a, e1->a, e2->a, e3->a, a);
        transpose4(e0->b, e1->b, e2->b, e3->b, b);
        v4f cx = a[0], cy = a[1], cz = a[2], r2s = a[3], nx = b[0], ny = b[1], nz = b[2], pw = b[3];
        v4i flat = r2s < zero;
        v4f r2 = (v4f)((v4i)r2s & ~sign);
        v4f vis = {(float)kc.vis[j0], (float)kc.vis[j0 + 1], (float)kc.vis[j0 + 2], (float)kc.vis[j0 + 3]};
        v4f gv = LIGHT_VIS_FLOOR + (1.0f - LIGHT_VIS_FLOOR) * (vis / (float)LIGHT_VIS_RAYS);
        v4f dx = x.x - cx, dy = x.y - cy, dz = x.z - cz;
        v4f c = dx * nx + dy * ny + dz * nz;
        v4f d2 = dx * dx + dy * dy + dz * dz;
        v4f m = select4(d2 > r2, d2, r2);
        v4f wj = pw / m;
        v4f sq = {sqrtf(m[0]), sqrtf(m[1]), sqrtf(m[2]), sqrtf(m[3])};
        v4f wf = select4(c > zero, wj * c / sq, zero);
        v4f wv = select4(flat, wf, wj) * gv;
        memcpy(w + j0, &wv, sizeof wv);
    }
    float acc = 0.0f;
    sel->cdf[0] = 0.0f;
    for (uint32_t j = 0; j < kc.n; j++) {
        acc += isfinite(w[j]) ? w[j] : 0.0f;
        sel->idx[j] = kc.idx[j];
        sel->cdf[j + 1] = acc;
    }
    sel->n = kc.n;
    /* No candidate can light x (or there are none): every pick by power. */
    sel->defensive = acc > 0.0f ? LIGHT_DEFENSIVE : 1.0f;
    float inv = acc > 0.0f ? 1.0f / acc : 0.0f;
    for (uint32_t j = 1; j <= sel->n; j++) sel->cdf[j] *= inv;
    if (sel->n && acc > 0.0f) sel->cdf[sel->n] = 1.0f;
}

/* x clamped to [0, 1) (rescaled uniform numbers may round past the ends). */
static inline float unit(float x) { return x > 0.0f ? (x < 0x1.fffffep-1f ? x : 0x1.fffffep-1f) : 0.0f; }

/* Probability that sel picks emitter k; j is k's place among the
 * candidates when known, else LIGHT_CANDS (searched). */
static float emitter_prob(const light_set *l, const light_sel *sel, uint32_t k, uint32_t j)
{
    float pw = l->em_cdf[k + 1] - l->em_cdf[k];
    if (!sel->n) return pw;
    float p = sel->defensive * pw;
    if (j >= LIGHT_CANDS)
        for (j = 0; j < sel->n && sel->idx[j] != k; j++) continue;
    if (j < sel->n) p += (1.0f - sel->defensive) * (sel->cdf[j + 1] - sel->cdf[j]);
    return p;
}

bool light_sample(const light_set *l, const light_sel *sel, float u0, float u1, float u2, light_point *out)
{
    if (l->n == 0) return false;
    /* u0 picks the strategy, then (rescaled) the emitter, then (rescaled
     * again) its triangle. */
    const float *ec = l->em_cdf;
    uint32_t nc = l->ne;
    const uint8_t *map = NULL;
    if (sel->n && u0 >= sel->defensive) {
        u0 = (u0 - sel->defensive) / (1.0f - sel->defensive);
        ec = sel->cdf;
        nc = sel->n;
        map = sel->idx;
    } else if (sel->n) {
        u0 = u0 / sel->defensive;
    }
    u0 = unit(u0);
    uint32_t j = emitter_of_cdf(ec, nc, u0);
    float lo = ec[j], span = ec[j + 1] - lo;
    if (!(span > 0.0f)) return false;
    uint32_t k = map ? map[j] : j;
    float v = unit((u0 - lo) / span);
    uint32_t i = light_of_emitter(l, &l->em[k], v);
    out->tri = l->tri[i];
    out->p = light_point_at(l, i, u1, u2);
    out->n = l->nrm[i];
    out->le = l->geo[4 * (size_t)i + 3];
    out->pdf_area = emitter_prob(l, sel, k, map ? j : LIGHT_CANDS) * l->pdf_in[out->tri];
    return true;
}

float light_pdf_area(const light_set *l, const light_sel *sel, uint32_t tri)
{
    if (tri >= l->mesh->ntris || l->pdf_in[tri] <= 0.0f) return 0.0f;
    return emitter_prob(l, sel, l->tri_em[tri], LIGHT_CANDS) * l->pdf_in[tri];
}
