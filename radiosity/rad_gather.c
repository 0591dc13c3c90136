/* rad_gather.c: the final gather at the mesh's vertices: what each
 * element's links bring, summed once for the links whose factor is flat over
 * it, the others' factors taken at every vertex, and the visibility of
 * partly hidden sources looked at from the vertex itself; and the same
 * sharing of non-flat links at the leaves' centres for the solve's last
 * pass (rad_leaf_scales), and the same gather at the leaves after the
 * solve (rad_gather_leaves) (rad_internal.h). (Over 600 lines: the
 * gather's parts -- flat sums, near sources by their parts, a vertex's own
 * visibility, the leaves' shares and values -- read one set of links the
 * same way, which one file keeps in view.) */
#include "radiosity/rad_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/pool.h"
#include "common/rng.h"

/* A point just inside leaf e near x, a hair in front of its plane: a mesh
 * vertex lies on the planes of the neighbours it shares an edge with, where
 * the point factor to them would be cut to nothing. */
static vec3 gather_point(const rad_elem *e, vec3 x, vec3 n)
{
    return rad_lift(v3_lerp(x, e->c, 1e-3f), n);
}

/* Unoccluded factor from point x (normal n) to element s: the point-to-
 * point kernel towards s's centre when s is small seen from x (its error
 * is of the order (radius / d)^2, under 1 % here), else Lambert's contour
 * integral, ten times as costly. */
static float gather_factor(const rad_ctx *c, vec3 x, vec3 n, const rad_elem *s)
{
    vec3 w = v3_sub(s->c, x);
    float d2 = v3_len2(w);
    if (s->radius * s->radius < 0.01f * d2) {
        vec3 ns = c->patches[s->patch].n;
        float cx = v3_dot(n, w), cs = -v3_dot(ns, w);
        if (cx <= 0.0f || cs <= 0.0f) return 0.0f;
        return s->area * cx * cs / (CT_PI * d2 * d2);
    }
    return (float)rad_ff_point_polygon(x, n, s->p, s->nv);
}

/* Relative spread of a link's factor over its receiver below which the
 * final gather keeps the link's own factor. */
#define GATHER_FLAT 0.01f

/* Whether link l's factor hardly varies over its receiver e: its own value
 * at every point of e too (most links: far or small sources). */
static int factor_flat(const rad_elem *e, const rad_link *l)
{
    return l->gr <= GATHER_FLAT * e->area * l->ff;
}

/* Whether the final gather keeps link l (of element e) as it is: a cluster's
 * factor is all it knows, and a flat factor is its own value at every
 * vertex -- unless the source is partly hidden and the gather looks at the
 * vertex's own visibility (rad_final_gather). */
static int gather_flat(const rad_ctx *c, const rad_elem *e, const rad_link *l)
{
    if (c->prm.vertex_rays > 0 && l->vis < 1.0f) return 0;
    return (l->src & RAD_CLUSTER_BIT) || factor_flat(e, l);
}

/* A source element is seen as one value from x while it is small there
 * (radius^2 under SEEN_SMALL d^2, gather_factor's own test: its factor is
 * then even over it) or its leaves' radiosity spreads by at most
 * SEEN_SPREAD of its mean. */
#define SEEN_SMALL 0.01f
#define SEEN_SPREAD 0.05f

static int seen_whole(const rad_ctx *c, const rad_gather_prep *g, vec3 x, uint32_t si, vec3 B)
{
    const rad_elem *s = rad_el(c, si);
    return s->child == RAD_NONE || s->radius * s->radius < SEEN_SMALL * v3_len2(v3_sub(s->c, x)) ||
           g->spread[si] <= SEEN_SPREAD * v3_maxc(B);
}

static void seen_descend(const rad_ctx *c, const rad_gather_prep *g, vec3 x, vec3 n, uint32_t si, double *fs,
                         vec3 *fb)
{
    vec3 B = rad_mean_B(c, c->cur, si);
    if (seen_whole(c, g, x, si, B)) {
        float f = gather_factor(c, x, n, rad_el(c, si));
        *fs += f;
        *fb = v3_madd(*fb, B, f);
        return;
    }
    for (uint32_t k = 0; k < 4; k++) seen_descend(c, g, x, n, rad_el(c, si)->child + k, fs, fb);
}

/* Source element si's radiosity as the point x (normal n) sees it. A link
 * holds a source as coarse as its error allowed, and gathers the source's
 * mean; but a near source's parts weigh by their own factors. Under the
 * Cornell box's sphere, the floor around the contact is dark and the lit
 * floor beyond it bright: the sphere's lowest vertices took the mean of
 * floor elements reaching out into the light and gathered twice what their
 * rays saw there (0.173 against 0.083, docs/radiosity.md "Where a curved
 * object touches a surface"). So where the source is large seen from x and
 * its leaves differ, its children's values are weighed by their factors at
 * x, down to where that no longer matters; the link's factor and
 * visibility stay its own. */
static vec3 seen_B(const rad_ctx *c, const rad_gather_prep *g, vec3 x, vec3 n, uint32_t si)
{
    vec3 B = rad_mean_B(c, c->cur, si);
    if (seen_whole(c, g, x, si, B)) return B;
    double fs = 0.0;
    vec3 fb = v3s(0.0f);
    seen_descend(c, g, x, n, si, &fs, &fb);
    return fs > 0.0 ? v3_scale(fb, (float)(1.0 / fs)) : B;
}

/* The spread of element ei's leaves' radiosity (brightest channel) into
 * spread[ei]; returns their smallest and largest in *lo, *hi. */
static void leaf_spread(const rad_ctx *c, float *spread, uint32_t ei, float *lo, float *hi)
{
    const rad_elem *e = rad_el(c, ei);
    if (e->child == RAD_NONE) {
        *lo = *hi = v3_maxc(rad_mean_B(c, c->cur, ei));
        spread[ei] = 0.0f;
        return;
    }
    float a = INFINITY, b = -INFINITY;
    for (uint32_t k = 0; k < 4; k++) {
        float l, h;
        leaf_spread(c, spread, e->child + k, &l, &h);
        a = fminf(a, l);
        b = fmaxf(b, h);
    }
    spread[ei] = b - a;
    *lo = a;
    *hi = b;
}

int rad_gather_prepare(const rad_ctx *c, rad_gather_prep *g)
{
    memset(g, 0, sizeof *g);
    size_t n = c->nelems;
    g->flat = calloc(n ? n : 1, sizeof *g->flat);
    g->flat_d = calloc(n ? n : 1, sizeof *g->flat_d);
    g->flat_p = calloc(n ? n : 1, sizeof *g->flat_p);
    g->off = calloc(n + 1, sizeof *g->off);
    g->spread = calloc(n ? n : 1, sizeof *g->spread);
    if (!g->flat || !g->flat_d || !g->flat_p || !g->off || !g->spread) return CT_ENOMEM;
    for (uint32_t pi = 0; pi < c->npatches; pi++) {
        float lo, hi;
        leaf_spread(c, g->spread, c->patches[pi].root, &lo, &hi);
    }
    /* Two sweeps over every element: count the links taken per vertex
     * (into off[e + 1]), then sum the flat ones and list the others. */
    for (int sweep = 0; sweep < 2; sweep++) {
        if (sweep == 1) {
            for (size_t e = 0; e < n; e++) g->off[e + 1] += g->off[e];
            g->idx = malloc((g->off[n] ? g->off[n] : 1) * sizeof *g->idx);
            if (!g->idx) return CT_ENOMEM;
        }
        for (uint32_t pi = 0; pi < c->npatches; pi++) {
            const rad_patch *p = &c->patches[pi];
            uint32_t stack[4 * RAD_MAX_DEPTH + 8];
            int sp = 0;
            stack[sp++] = p->root;
            while (sp) {
                uint32_t ei = stack[--sp];
                const rad_elem *e = rad_el(c, ei);
                uint32_t fill = sweep ? g->off[ei] : 0;
                for (uint32_t i = 0; i < e->nlinks; i++) {
                    const rad_link *l = &p->links[e->link_off + i];
                    if (!gather_flat(c, e, l)) {
                        if (sweep) g->idx[fill++] = e->link_off + i;
                        else g->off[ei + 1]++;
                    } else if (sweep) {
                        /* A flat link's factor is the same at every vertex,
                         * and so, near enough, is how its source looks:
                         * seen from the receiver's centre. */
                        vec3 B = (l->src & RAD_CLUSTER_BIT) ? rad_link_cluster_B(c, l, c->cur, e->c)
                                                            : seen_B(c, g, rad_lift(e->c, p->n), p->n, l->src);
                        vec3 E = (l->src & RAD_CLUSTER_BIT) ? c->clusters[l->src & RAD_ID_MASK].E
                                                            : c->patches[rad_el(c, l->src)->patch].E;
                        vec3 Bp = (l->src & RAD_CLUSTER_BIT) ? B : rad_mean_B(c, c->cur, l->src);
                        g->flat[ei] = v3_madd(g->flat[ei], B, l->ff);
                        g->flat_p[ei] = v3_madd(g->flat_p[ei], Bp, l->ff);
                        g->flat_d[ei] = v3_madd(g->flat_d[ei], E, l->ff);
                    }
                }
                if (e->child != RAD_NONE)
                    for (uint32_t k = 0; k < 4; k++) stack[sp++] = e->child + k;
            }
        }
    }
    return CT_OK;
}

void rad_gather_prep_free(rad_gather_prep *g)
{
    free(g->flat);
    free(g->flat_d);
    free(g->flat_p);
    free(g->off);
    free(g->idx);
    free(g->spread);
    memset(g, 0, sizeof *g);
}

/* A vertex's seed: its position's bits (the vertex is gathered once per
 * leaf around it, and each must see the same rays). */
static uint64_t vertex_key(vec3 x)
{
    uint32_t kx, ky, kz;
    memcpy(&kx, &x.x, 4);
    memcpy(&ky, &x.y, 4);
    memcpy(&kz, &x.z, 4);
    return ((uint64_t)kx << 32 | ky) ^ ((uint64_t)kz * 0x9e3779b97f4a7c15ULL);
}

/* Share of a vertex's irradiance above which a partly hidden link's
 * expected change is traced with all of --vertex-rays, and how many single
 * rays sample the rest (rad_final_gather). */
#define GATHER_VIS_SHARE 0.01
/* The single rays of the rest: as many as bring their estimate's noise
 * (about S / sqrt(m) for a spread S) to GATHER_SMALL_NOISE of the vertex's
 * irradiance, at least --vertex-rays and at most GATHER_SMALL_MAX times it. */
#define GATHER_SMALL_NOISE 0.02
#define GATHER_SMALL_MAX 32

static int scratch_push(rad_gather_scratch *w, const rad_link *l, float f0, vec3 B, vec3 E)
{
    if (w->n == w->cap) {
        size_t cap = w->cap ? 2 * w->cap : 256;
        rad_partial *q = realloc(w->v, cap * sizeof *q);
        if (!q) return -1;
        w->v = q;
        w->cap = cap;
    }
    rad_partial *e = &w->v[w->n++];
    e->src = l->src;
    e->vis = l->vis;
    e->f0 = f0;
    e->B = B;
    e->E = E;
    return 0;
}

void rad_gather_scratch_free(rad_gather_scratch *w)
{
    free(w->v);
    memset(w, 0, sizeof *w);
}

/* The changes of a vertex's partly hidden links (w, gathered at xp with
 * normal n) when it looks at their visibility itself, added to *h and *hd.
 *
 * A link's visibility is its receiver's average: across a shadow
 * boundary (a box's shadow on the floor, lit or indirect) every vertex
 * of the receiver got the same share, and the boundary was as coarse as
 * the elements that the power threshold leaves there, which is coarse
 * wherever the light is dim. So the vertex looks at its own visibility
 * of every partly hidden link, as an unbiased estimate of the sum of
 * their changes f0 B (v - V): a link whose expected change (the mean
 * deviation 2 V (1 - V) of a lit / shadowed pattern covering V of the
 * receiver) exceeds GATHER_VIS_SHARE of the vertex's irradiance is
 * traced with --vertex-rays rays; the others -- thousands of small
 * sources in a dim corner, none of which matters alone but all of
 * which err the same way -- are sampled with single rays, drawn in
 * proportion to f0 B sqrt(V (1 - V)) (the spread of one ray's outcome)
 * at evenly spaced points of their running sum, as many as bring the
 * estimate's noise (their spread S over the square root of the count) to
 * GATHER_SMALL_NOISE of the vertex's irradiance. Tracing every link
 * took the office building's meshing from 36 to 76 s. */
static void look_at_partial_links(const rad_ctx *c, rad_gather_scratch *w, vec3 xp, vec3 n, uint64_t key, vec3 *h,
                                   vec3 *hd)
{
    double ref = v3_maxc(*h), S = 0.0;
    for (size_t i = 0; i < w->n; i++) {
        rad_partial *e = &w->v[i];
        double b = v3_maxc(e->B) * e->f0;
        if (b * 2.0 * e->vis * (1.0 - e->vis) > GATHER_VIS_SHARE * ref) {
            float v = rad_point_visibility(c, xp, n, e->src, c->prm.vertex_rays, key);
            if (v >= 0.0f) {
                float df = e->f0 * (v - e->vis);
                *h = v3_madd(*h, e->B, df);
                *hd = v3_madd(*hd, e->E, df);
            }
            e->s = 0.0;
        } else {
            /* A link kept though all its rays were blocked (V = 0) may
             * still be partly visible from here: a receiver in the
             * shadow of a box that sees past it. With V = 0 it had no
             * spread and was never looked at, and the floor 30-40 cm
             * behind the L room's box stayed 1.5-6 % dark; its weight
             * is the spread of the rule of succession's 1 / (n + 2) for
             * n = --vis-rays blocked rays (a lamp's links had more, so
             * theirs is drawn more often than it needs, which costs rays,
             * not accuracy). Each draw is weighted by its odds, so the
             * estimate of the vertex's own visibility stays unbiased.
             * Element links only: the office building keeps millions of
             * cluster links whose rays all met walls, and looking at those
             * too took its solve from 50 to 66 s for nothing the L room
             * showed. */
            int hidden = e->vis <= 0.0f && !(e->src & RAD_CLUSTER_BIT);
            double v = hidden ? 1.0 / (c->prm.vis_rays + 2) : e->vis;
            e->s = b * sqrt(v * (1.0 - v));
            S += e->s;
        }
    }
    if (S > 0.0) {
        double want = ref > 0.0 ? S / (GATHER_SMALL_NOISE * ref) : INFINITY;
        double lo = c->prm.vertex_rays, hi = (double)GATHER_SMALL_MAX * c->prm.vertex_rays;
        int m = (int)ceil(fmin(fmax(want * want, lo), hi));
        ct_rng rg = rng_make(c->prm.seed, key, 0x736d616c6cULL, 0);
        double step = S / m, at = rng_float(&rg) * step, run = 0.0;
        size_t i = 0;
        for (int j = 0; j < m; j++, at += step) {
            while (i + 1 < w->n && run + w->v[i].s <= at) run += w->v[i++].s;
            rad_partial *e = &w->v[i];
            if (e->s <= 0.0) continue;
            float v = rad_point_visibility(c, xp, n, e->src, 1, key + (uint64_t)j);
            if (v < 0.0f) continue;
            /* Drawn with probability m s / S per sample. */
            float df = (float)(e->f0 * (v - e->vis) * S / (m * e->s));
            *h = v3_madd(*h, e->B, df);
            *hd = v3_madd(*hd, e->E, df);
        }
    }
}

/* The final gather reads every non-flat link's source element and its
 * radiosity, scattered over the element chunks: a miss on each link made a
 * quarter of its time (perf, the Cornell box). So an element's first
 * GATHER_AHEAD links' sources are asked for before its loop, and each
 * later one GATHER_AHEAD links early. */
#define GATHER_AHEAD 4

static inline void gather_ahead(const rad_ctx *c, const rad_gather_prep *g, const rad_patch *p, uint32_t k)
{
    uint32_t src = p->links[g->idx[k]].src;
    if (src & RAD_CLUSTER_BIT) return;
    const char *e = (const char *)rad_el(c, src);
    __builtin_prefetch(e);
    __builtin_prefetch(e + 64);
    __builtin_prefetch(rad_B(c, c->cur, src));
}

/* rad_final_gather; with Hl and Hdl, also what the same point factors
 * bring with the links' own visibility and their sources' means
 * (gather_leaf). */
static void final_gather(const rad_ctx *c, const rad_gather_prep *g, rad_gather_scratch *w, uint32_t leaf, vec3 x,
                         vec3 n, vec3 *H, vec3 *Hd, vec3 *Hl, vec3 *Hdl)
{
    vec3 h = v3s(0.0f), hd = v3s(0.0f), hl = v3s(0.0f);
    vec3 xp = gather_point(rad_el(c, leaf), x, n);
    int look = c->prm.vertex_rays > 0;
    w->n = 0;
    for (uint32_t ei = leaf; ei != RAD_NONE; ei = rad_el(c, ei)->parent) {
        const rad_elem *e = rad_el(c, ei);
        const rad_patch *p = &c->patches[e->patch];
        h = v3_add(h, g->flat[ei]);
        hd = v3_add(hd, g->flat_d[ei]);
        if (Hl) hl = v3_add(hl, g->flat_p[ei]);
        uint32_t end = g->off[ei + 1];
        for (uint32_t k = g->off[ei]; k < end && k < g->off[ei] + GATHER_AHEAD; k++) gather_ahead(c, g, p, k);
        for (uint32_t k = g->off[ei]; k < end; k++) {
            if (k + GATHER_AHEAD < end) gather_ahead(c, g, p, k + GATHER_AHEAD);
            const rad_link *l = &p->links[g->idx[k]];
            float f0, f;
            vec3 B, E;
            if (l->src & RAD_CLUSTER_BIT) {
                /* Non-flat only when partly hidden: its factor stays the
                 * receiver's average, its visibility becomes the vertex's. */
                const rad_cluster *q = &c->clusters[l->src & RAD_ID_MASK];
                f0 = l->gr;
                f = l->ff;
                B = rad_link_cluster_B(c, l, c->cur, xp);
                E = q->E;
            } else {
                const rad_elem *s = rad_el(c, l->src);
                f0 = gather_factor(c, xp, n, s);
                f = f0 * l->vis;
                B = seen_B(c, g, xp, n, l->src);
                E = c->patches[s->patch].E;
                if (Hl) hl = v3_madd(hl, rad_mean_B(c, c->cur, l->src), f);
            }
            h = v3_madd(h, B, f);
            hd = v3_madd(hd, E, f);
            /* A cluster's value is the same either way. */
            if (Hl && (l->src & RAD_CLUSTER_BIT)) hl = v3_madd(hl, B, f);
            /* Out of memory: this vertex keeps its elements' visibility. */
            if (look && l->vis < 1.0f && f0 > 0.0f && v3_maxc(B) > 0.0f && scratch_push(w, l, f0, B, E)) look = 0;
        }
    }
    if (Hl) {
        *Hl = hl;
        *Hdl = hd;
    }
    if (look && w->n > 0) look_at_partial_links(c, w, xp, n, vertex_key(x), &h, &hd);
    /* A sampled change may overshoot where the vertex is nearly dark. */
    *H = v3_max(h, v3s(0.0f));
    *Hd = v3_max(hd, v3s(0.0f));
}

void rad_final_gather(const rad_ctx *c, const rad_gather_prep *g, rad_gather_scratch *w, uint32_t leaf, vec3 x,
                      vec3 n, vec3 *H, vec3 *Hd)
{
    final_gather(c, g, w, leaf, x, n, H, Hd, NULL, NULL);
}

/* The leaves of one patch tree and what their ancestors' links bring them
 * (rad_leaf_scales): per leaf, the sum of b ff over every inherited link
 * (tot) and how much the non-flat ones change it with each one's factor
 * taken at the leaf's centre (shift); the same with the sources' emission
 * for the direct part (the d fields). */
typedef struct leaf_acc {
    uint32_t *id;
    double *tot, *shift, *totd, *shiftd;
    float *f;          /* scratch: one link's centre factors over a range of leaves */
    uint32_t n;
} leaf_acc;

/* Walks element ei's subtree, appending its leaves to a, and shares each of
 * ei's non-flat links among them by their centres' factors, scaled so that
 * their area-weighted mean is the link's own (its power is kept). */
static void leaf_walk(rad_ctx *c, const rad_patch *p, leaf_acc *a, uint32_t ei)
{
    const rad_elem *e = rad_el(c, ei);
    uint32_t lo = a->n;
    if (e->child == RAD_NONE) {
        a->id[a->n++] = ei;
        return;   /* a leaf's own links reach it as they are */
    }
    for (uint32_t k = 0; k < 4; k++) leaf_walk(c, p, a, e->child + k);
    uint32_t hi = a->n;
    for (uint32_t i = 0; i < e->nlinks; i++) {
        const rad_link *l = &p->links[e->link_off + i];
        int cl = (l->src & RAD_CLUSTER_BIT) != 0;
        double b = v3_avg(cl ? rad_link_cluster_B(c, l, c->cur, e->c) : *rad_B(c, c->cur, l->src));
        double ee = cl ? v3_avg(c->clusters[l->src & RAD_ID_MASK].E) : v3_avg(c->patches[rad_el(c, l->src)->patch].E);
        /* Not gather_flat: no vertex rays look at a partly hidden source
         * here, a cluster has no polygon to take a factor to, and a hidden
         * link brings nothing to share. */
        int flat = cl || !(l->vis > 0.0f) || factor_flat(e, l);
        double sum = 0.0;
        if (!flat) {
            const rad_elem *s = rad_el(c, l->src);
            for (uint32_t j = lo; j < hi; j++) {
                const rad_elem *lf = rad_el(c, a->id[j]);
                a->f[j] = gather_factor(c, rad_lift(lf->c, p->n), p->n, s);
                sum += (double)lf->area * a->f[j];
            }
        }
        double k = sum > 0.0 ? (double)e->area * l->ff / sum : 0.0;
        for (uint32_t j = lo; j < hi; j++) {
            a->tot[j] += b * l->ff;
            a->totd[j] += ee * l->ff;
            if (flat || !(sum > 0.0)) continue;
            a->shift[j] += b * (a->f[j] * k - l->ff);
            a->shiftd[j] += ee * (a->f[j] * k - l->ff);
        }
    }
}

/* A link held at a coarse receiver reaches every leaf below it with the
 * receiver's mean factor. Where the receiver split for one link whose
 * factor varies over it (the adjacent wall near an edge), its hundreds of
 * other links stayed, each under the threshold and all erring the same
 * way: near the edge the adjacent wall covers more of the hemisphere and
 * every other source's factor is smaller, in the interior larger. In the
 * closed room a leaf's factors summed to 1.39 within 1 cm of an edge and
 * 0.94 beyond 30 cm, and the elements' indirect light ended 7 % dark in the
 * interiors (docs/radiosity.md, "Light moved towards the surfaces'
 * edges"). The final gather takes such links' factors at each vertex; this
 * shares each non-flat inherited link among the leaves below its receiver
 * by their centres' factors (its power kept: a centre's factor is not its
 * leaf's mean, and the closed box gained 0.3 % of its power at --error
 * 1e-4 without that), once, for the last pass's iterations. */
int rad_leaf_scales(rad_ctx *c, uint32_t pi)
{
    const rad_patch *p = &c->patches[pi];
    uint32_t nl = 0;
    {
        uint32_t stack[4 * RAD_MAX_DEPTH + 8];
        int sp = 0;
        stack[sp++] = p->root;
        while (sp) {
            const rad_elem *e = rad_el(c, stack[--sp]);
            if (e->child == RAD_NONE) nl++;
            else for (uint32_t k = 0; k < 4; k++) stack[sp++] = e->child + k;
        }
    }
    leaf_acc a = {0};
    a.id = malloc(nl * sizeof *a.id);
    a.f = malloc(nl * sizeof *a.f);
    a.tot = calloc(4 * (size_t)nl, sizeof *a.tot);
    if (!a.id || !a.f || !a.tot) {
        free(a.id);
        free(a.f);
        free(a.tot);
        return CT_ENOMEM;
    }
    a.shift = a.tot + nl;
    a.totd = a.shift + nl;
    a.shiftd = a.totd + nl;
    leaf_walk(c, p, &a, p->root);
    for (uint32_t j = 0; j < a.n; j++) {
        rad_elem *lf = rad_el(c, a.id[j]);
        lf->hk = a.tot[j] > 0.0 ? (float)(a.shift[j] / a.tot[j]) : 0.0f;
        lf->hkd = a.totd[j] > 0.0 ? (float)(a.shiftd[j] / a.totd[j]) : 0.0f;
    }
    free(a.id);
    free(a.f);
    free(a.tot);
    return CT_OK;
}

/* The final gather at points (rad_gather_points), in runs of GATHER_RUN
 * points per pool task, a scratch per worker. */
#define GATHER_RUN 256

/* What leaf li's links bring it, as push_pull gathers it (rad_solve.c):
 * its own links, and its ancestors' scaled by its share (hk, hkd). */
static void leaf_links(const rad_ctx *c, uint32_t li, vec3 *H, vec3 *Hd)
{
    const rad_elem *lf = rad_el(c, li);
    vec3 h, hd, hi = v3s(0.0f), hdi = v3s(0.0f);
    rad_elem_links(c, lf, c->cur, true, &h, &hd);
    for (uint32_t ei = lf->parent; ei != RAD_NONE; ei = rad_el(c, ei)->parent) {
        vec3 a, ad;
        rad_elem_links(c, rad_el(c, ei), c->cur, true, &a, &ad);
        hi = v3_add(hi, a);
        hdi = v3_add(hdi, ad);
    }
    *H = v3_add(h, v3_scale(hi, 1.0f + lf->hk));
    *Hd = v3_add(hd, v3_scale(hdi, 1.0f + lf->hkd));
}

/* Per channel: the links' value a scaled by the point's change num / den;
 * the point's own value where the links' visibility brought nothing. */
static vec3 rescale(vec3 a, vec3 num, vec3 den)
{
    float av[3] = {a.x, a.y, a.z}, nv[3] = {num.x, num.y, num.z}, dv[3] = {den.x, den.y, den.z}, o[3];
    for (int i = 0; i < 3; i++) o[i] = dv[i] > 0.0f ? av[i] * (nv[i] / dv[i]) : nv[i];
    return v3(o[0], o[1], o[2]);
}

/* A leaf's irradiance and its direct part from the final gather at its
 * centre, as a change of what its links bring (rad_solve.c,
 * regather_leaves): the links' values times what the centre's own
 * visibility and its near sources' parts (seen_B) make of the same point
 * factors. The point factors themselves stay out: a leaf's centre is not
 * its mean, and where a leaf is large beside a lamp (office's desks under
 * their desk lamps) the centre's value tripled the desks' power. */
static void gather_leaf(const rad_ctx *c, const rad_gather_prep *g, rad_gather_scratch *w, uint32_t li, vec3 *H,
                        vec3 *Hd, vec3 *a, vec3 *ad)
{
    const rad_elem *lf = rad_el(c, li);
    vec3 num, numd, den, dend;
    final_gather(c, g, w, li, lf->c, c->patches[lf->patch].n, &num, &numd, &den, &dend);
    leaf_links(c, li, a, ad);
    *H = rescale(*a, num, den);
    *Hd = rescale(*ad, numd, dend);
}

typedef struct gather_job {
    const rad_ctx *c;
    const rad_gather_prep *prep;
    rad_gather_scratch *w;   /* one per worker */
    const uint32_t *leaf;
    const vec3 *pos;         /* NULL: at the leaves' centres, as the solve's values */
    const vec3 *nrm;         /* at points: their normals (NULL: their leaves' planes') */
    vec3 *B, *Bd;            /* at points: B and Bd; at leaves: the gathered H and Hd */
    vec3 *L, *Ld;            /* at leaves: what their links bring (H, Hd) */
    uint32_t n;
} gather_job;

static void gather_task(void *ctx, int worker, size_t task)
{
    const gather_job *j = ctx;
    uint32_t b = (uint32_t)task * GATHER_RUN, e = b + GATHER_RUN < j->n ? b + GATHER_RUN : j->n;
    for (uint32_t g = b; g < e; g++) {
        if (!j->pos) {
            gather_leaf(j->c, j->prep, &j->w[worker], j->leaf[g], &j->B[g], &j->Bd[g], &j->L[g], &j->Ld[g]);
            continue;
        }
        const rad_elem *lf = rad_el(j->c, j->leaf[g]);
        const rad_patch *p = &j->c->patches[lf->patch];
        vec3 H, Hd;
        vec3 n = j->nrm ? j->nrm[g] : p->n;
        rad_final_gather(j->c, j->prep, &j->w[worker], j->leaf[g], j->pos[g], n, &H, &Hd);
        if (j->c->mirrors) {
            vec3 hm = rad_mirror_point(j->c, j->pos[g], n, g);
            H = v3_add(H, hm);
            Hd = v3_add(Hd, hm);
        }
        j->B[g] = v3_add(p->E, v3_mul(p->rho, H));
        j->Bd[g] = v3_add(p->E, v3_mul(p->rho, Hd));
    }
}

static int gather_run(const rad_ctx *c, const uint32_t *leaf, const vec3 *pos, const vec3 *nrm, uint32_t n,
                      vec3 *B, vec3 *Bd, vec3 *L, vec3 *Ld)
{
    /* On the solver's pool (rad_solve.c), the caller alone without one. */
    int nth = pool_threads(c->pool);
    rad_gather_prep prep;
    rad_gather_scratch *w = calloc((size_t)nth, sizeof *w);
    int rc = w ? rad_gather_prepare(c, &prep) : CT_ENOMEM;
    if (!rc) {
        gather_job j = {c, &prep, w, leaf, pos, nrm, B, Bd, L, Ld, n};
        pool_run(c->pool, ((size_t)n + GATHER_RUN - 1) / GATHER_RUN, gather_task, &j);
    }
    if (w) {
        for (int i = 0; i < nth; i++) rad_gather_scratch_free(&w[i]);
        rad_gather_prep_free(&prep);
    }
    free(w);
    return rc ? CT_ENOMEM : CT_OK;
}

int rad_gather_points(const rad_ctx *c, const uint32_t *leaf, const vec3 *pos, const vec3 *nrm, uint32_t n, vec3 *B,
                      vec3 *Bd)
{
    return gather_run(c, leaf, pos, nrm, n, B, Bd, NULL, NULL);
}

static void acc3(double s[3], vec3 v, float a)
{
    s[0] += (double)v.x * a;
    s[1] += (double)v.y * a;
    s[2] += (double)v.z * a;
}

/* Per channel, o * want / have (o where have is 0). */
static vec3 scale3(vec3 o, const double want[3], const double have[3])
{
    float v[3] = {o.x, o.y, o.z};
    for (int i = 0; i < 3; i++)
        if (have[i] > 0.0) v[i] = (float)(v[i] * (want[i] / have[i]));
    return v3(v[0], v[1], v[2]);
}

/* The leaves' gathers move light between them; how much light there is
 * stays the links'. Their ratios are point values at the leaves' centres,
 * and over the box with boxes they drifted from the links' total by
 * +0.6 to +0.8 % (seeds 1-3, tests/unit/test_radiosity.c), while the
 * links' transport keeps that box's power within 0.8 %. So the scene's
 * gathered light (per channel, and its direct part apart) is scaled back
 * to what the links bring to the same leaves. Per patch instead, the
 * Cornell box's sphere (a patch per triangle) kept its lowest triangles'
 * excess, and its 8-px blocks' rms error went back from 5.7 to 9.9 %. */
int rad_gather_leaves(const rad_ctx *c, const uint32_t *leaf, uint32_t n, vec3 *B, vec3 *Bd, vec3 *H)
{
    vec3 *L = malloc((n ? n : 1) * sizeof *L), *Ld = malloc((n ? n : 1) * sizeof *Ld);
    /* The gathered irradiance into H, its direct part into Bd until the
     * values replace it below. */
    int rc = L && Ld ? gather_run(c, leaf, NULL, NULL, n, H, Bd, L, Ld) : CT_ENOMEM;
    double links[3] = {0}, got[3] = {0}, linksd[3] = {0}, gotd[3] = {0};
    for (uint32_t g = 0; g < n && !rc; g++) {
        float a = rad_el(c, leaf[g])->area;
        acc3(links, L[g], a);
        acc3(got, H[g], a);
        acc3(linksd, Ld[g], a);
        acc3(gotd, Bd[g], a);
    }
    for (uint32_t g = 0; g < n && !rc; g++) {
        const rad_elem *lf = rad_el(c, leaf[g]);
        const rad_patch *p = &c->patches[lf->patch];
        vec3 h = scale3(H[g], links, got), hd = scale3(Bd[g], linksd, gotd);
        /* A leaf's value as push_pull makes it (rad_solve.c): what it
         * passes on, with the lamps its mirrors show sampled once. */
        if (c->mirrors) {
            h = v3_add(h, lf->Hm);
            hd = v3_add(hd, lf->Hm);
        }
        vec3 refl = v3_max(v3_sub(v3_mul(p->rho_t, h), v3_mul(p->rho_ml, hd)), v3s(0.0f));
        B[g] = v3_add(p->E, refl);
        Bd[g] = v3_add(p->E, v3_mul(p->rho, hd));
        H[g] = h;
    }
    free(L);
    free(Ld);
    return rc;
}
