/* rad_link.c: form factors (Lambert's contour formula from points of the
 * smaller element to the other's polygon, averaged over a small quadrature,
 * turned by reciprocity), cluster factors by Monte Carlo over the cluster's
 * area, visibility by jittered Embree rays weighted by the point kernel,
 * the per-patch link refinement with its error oracle (the links' error
 * over the receiver and from the source's radiosity, not their power), and
 * the final gather at the mesh's vertices. */
#include "tracer/rad_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"

/* ------------------------------------------------------------------------ */
/* Form factors                                                             */

double rad_ff_point_polygon(vec3 x, vec3 n, const vec3 *poly, int npoly)
{
    if (npoly < 3 || npoly > 8) return 0.0;
    /* Newell normal of the polygon: x must lie in front of it. */
    double nx = 0, ny = 0, nz = 0, cx = 0, cy = 0, cz = 0;
    for (int i = 0; i < npoly; i++) {
        vec3 a = poly[i], b = poly[(i + 1) % npoly];
        nx += ((double)a.y - b.y) * ((double)a.z + b.z);
        ny += ((double)a.z - b.z) * ((double)a.x + b.x);
        nz += ((double)a.x - b.x) * ((double)a.y + b.y);
        cx += a.x; cy += a.y; cz += a.z;
    }
    cx /= npoly; cy /= npoly; cz /= npoly;
    if (nx * (x.x - cx) + ny * (x.y - cy) + nz * (x.z - cz) <= 0.0) return 0.0;

    /* Clip the polygon to the receiver's upper half-space (Sutherland-Hodgman
     * against one plane), so only what the point can see counts. */
    double q[12][3];
    int nq = 0;
    for (int i = 0; i < npoly; i++) {
        vec3 a = poly[i], b = poly[(i + 1) % npoly];
        double da = (double)n.x * (a.x - x.x) + (double)n.y * (a.y - x.y) + (double)n.z * (a.z - x.z);
        double db = (double)n.x * (b.x - x.x) + (double)n.y * (b.y - x.y) + (double)n.z * (b.z - x.z);
        if (da >= 0.0) {
            q[nq][0] = a.x - (double)x.x; q[nq][1] = a.y - (double)x.y; q[nq][2] = a.z - (double)x.z;
            nq++;
        }
        if ((da >= 0.0) != (db >= 0.0)) {
            double t = da / (da - db);
            q[nq][0] = a.x + t * ((double)b.x - a.x) - x.x;
            q[nq][1] = a.y + t * ((double)b.y - a.y) - x.y;
            q[nq][2] = a.z + t * ((double)b.z - a.z) - x.z;
            nq++;
        }
    }
    if (nq < 3) return 0.0;
    double sum = 0.0;
    for (int i = 0; i < nq; i++) {
        const double *a = q[i], *b = q[(i + 1) % nq];
        double la = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        double lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        if (la < 1e-20 || lb < 1e-20) continue;
        double cr[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        double lc = sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
        if (lc < 1e-30) continue;
        double gamma = atan2(lc, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
        sum += gamma * (n.x * cr[0] + n.y * cr[1] + n.z * cr[2]) / lc;
    }
    return fabs(sum) / (2.0 * M_PI);
}

static vec3 poly_point(const vec3 *p, int np, float u, float v)
{
    if (np == 4) return v3_lerp(v3_lerp(p[0], p[1], u), v3_lerp(p[3], p[2], u), v);
    if (u + v > 1.0f) { u = 1.0f - u; v = 1.0f - v; }
    return v3_add(p[0], v3_add(v3_scale(v3_sub(p[1], p[0]), u), v3_scale(v3_sub(p[2], p[0]), v)));
}

double rad_ff_polygons(const vec3 *a, int na, const vec3 *b, int nb, int n)
{
    if (n < 1 || (na != 3 && na != 4)) return 0.0;
    vec3 nrm = v3_norm(v3_cross(v3_sub(a[1], a[0]), v3_sub(a[2], a[0])));
    double sum = 0.0;
    int cnt = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            float u = ((float)i + 0.5f) / (float)n, v = ((float)j + 0.5f) / (float)n;
            /* A triangle's folded square would sample the diagonal twice. */
            if (na == 3 && u + v > 1.0f) continue;
            sum += rad_ff_point_polygon(poly_point(a, na, u, v), nrm, b, nb);
            cnt++;
        }
    return cnt ? sum / cnt : 0.0;
}

/* The receiver's quadrature points: quads 2 x 2 points at 1/4 and 3/4 of
 * each side, triangles the 3-point rule (4/6, 1/6, 1/6); returns their
 * count. */
static int quad_points(const rad_elem *r, vec3 *x)
{
    if (r->nv == 4) {
        static const float g[2] = {0.25f, 0.75f};
        for (int i = 0; i < 2; i++)
            for (int j = 0; j < 2; j++) x[2 * i + j] = poly_point(r->p, 4, g[i], g[j]);
        return 4;
    }
    for (int k = 0; k < 3; k++)
        x[k] = v3_add(v3_scale(r->p[k], 4.0f / 6.0f),
                      v3_add(v3_scale(r->p[(k + 1) % 3], 1.0f / 6.0f), v3_scale(r->p[(k + 2) % 3], 1.0f / 6.0f)));
    return 3;
}

/* Point-to-polygon factor from element a to polygon b averaged over a: at
 * a's centre, or over its quadrature points when a is large compared with
 * the distance d (where the factor varies over a). An element straddling
 * b's plane is clipped to the part in front of it first: its centre or
 * quadrature points alone would give all of it or nothing (a floor element
 * half under a box, seen from the box's side), which lost 16 % of the
 * floor's factor to a box standing on it. */
static double ff_avg(const rad_ctx *c, const rad_elem *a, const rad_elem *b, float d)
{
    vec3 n = c->patches[a->patch].n, nb = c->patches[b->patch].n;
    float tol = fmaxf(1e-5f * a->radius, 0.05f * c->ray_eps);
    int front = 0, back = 0;
    float h[4];
    for (int i = 0; i < a->nv; i++) {
        h[i] = v3_dot(nb, v3_sub(a->p[i], b->c));
        front += h[i] > tol;
        back += h[i] < -tol;
    }
    if (front && back) {
        /* Clip a's polygon to b's front half-space (Sutherland-Hodgman),
         * then integrate over its fan of triangles, each at its centroid. */
        vec3 q[8];
        int nq = 0;
        for (int i = 0; i < a->nv; i++) {
            int j = (i + 1) % a->nv;
            if (h[i] >= 0.0f) q[nq++] = a->p[i];
            if ((h[i] >= 0.0f) != (h[j] >= 0.0f)) q[nq++] = v3_lerp(a->p[i], a->p[j], h[i] / (h[i] - h[j]));
        }
        double sum = 0.0;
        for (int k = 1; k + 1 < nq; k++) {
            float ta = 0.5f * v3_len(v3_cross(v3_sub(q[k], q[0]), v3_sub(q[k + 1], q[0])));
            vec3 g = v3_scale(v3_add(v3_add(q[0], q[k]), q[k + 1]), 1.0f / 3.0f);
            sum += ta * rad_ff_point_polygon(g, n, b->p, b->nv);
        }
        return a->area > 0.0f ? sum / a->area : 0.0;
    }
    if (a->radius < 0.2f * d) return rad_ff_point_polygon(a->c, n, b->p, b->nv);
    vec3 x[4];
    int nq = quad_points(a, x);
    double sum = 0.0;
    for (int k = 0; k < nq; k++) sum += rad_ff_point_polygon(x[k], n, b->p, b->nv);
    return sum / nq;
}

/* Unoccluded form factor F from element r to element s (r's average), and
 * dF, how much the point factor varies over r: the spread (largest minus
 * smallest) of the point-to-polygon factors at r's centre, its corners
 * (nudged inside: a corner on an edge shared with s lies in s's plane) and,
 * when r is large compared with the distance, its quadrature points. A link
 * gives its whole receiver one irradiance, so dF is what it cannot show:
 * the refinement splits receivers by it (refine_elem).
 *
 * F is integrated over the smaller of the two and turned by reciprocity,
 * F(r <- s) = A_s / A_r * F(s -> r). Averaged over a large receiver's few
 * points, a small source close to one of them came out orders of magnitude
 * too strong (a sphere's tiny pole triangle 3 mm above the floor was given
 * F = 0.11 to the whole 0.3 m^2 floor, 900 times what reciprocity allows),
 * and energy was created. */
static void ff_elem(const rad_ctx *c, const rad_elem *r, const rad_elem *s, double *F, double *dF)
{
    vec3 n = c->patches[r->patch].n;
    float d = v3_len(v3_sub(s->c, r->c));
    /* The corners are among the points: a source standing on a large
     * receiver (a box on a floor element) hides from the receiver's
     * centre and inner points, which all lie behind it. */
    vec3 x[9];
    int nx = 0;
    x[nx++] = r->c;
    for (int i = 0; i < r->nv; i++) x[nx++] = v3_lerp(r->p[i], r->c, 1e-3f);
    if (r->radius >= 0.2f * d) nx += quad_points(r, x + nx);
    double lo = HUGE_VAL, hi = 0.0;
    for (int k = 0; k < nx; k++) {
        double f = rad_ff_point_polygon(x[k], n, s->p, s->nv);
        lo = fmin(lo, f);
        hi = fmax(hi, f);
    }
    *dF = hi - lo;
    if (s->area < r->area) *F = r->area > 0.0f ? ff_avg(c, s, r, d) * s->area / r->area : 0.0;
    else *F = ff_avg(c, r, s, d);
}

/* ------------------------------------------------------------------------ */
/* Visibility and cluster factors                                           */

static int src_has_emitter(const rad_ctx *c, uint32_t src)
{
    if (src & RAD_CLUSTER_BIT) return c->clusters[src & RAD_ID_MASK].has_emitter;
    return v3_maxc(c->patches[rad_el(c, src)->patch].E) > 0.0f;
}

/* The random stream of a link's rays, one per tag (TAG_*). Shared: the
 * stream of every link from this source. Links from one non-emitting source
 * share their jitter pattern, so neighbouring receivers see the same few
 * rays' bias instead of independent noise (blotches across a curved
 * surface); shadow rays to emitters stay independent, or penumbrae would
 * show as a few shifted hard shadows. */
#define TAG_DECIDE 0x7669u   /* rays that decide whether a link is refined */
#define TAG_VALUE  0x7661u   /* rays of the factor a kept link carries */
#define TAG_RETEST 0x7265u   /* a second look before a link is dropped */
static ct_rng link_rng(const rad_ctx *c, const rad_elem *r, uint32_t src, int shared, uint64_t tag)
{
    uint64_t skey = (src & RAD_CLUSTER_BIT) ? ct_hash64(src) : rad_el(c, src)->key;
    return rng_make(c->prm.seed, shared ? 0x5eedu : r->key, skey, tag);
}

/* A random pairing of n strata (Fisher-Yates). */
static void strata_perm(ct_rng *g, uint16_t *perm, int n)
{
    for (int i = 0; i < n; i++) perm[i] = (uint16_t)i;
    for (int i = n - 1; i > 0; i--) {
        uint32_t j = rng_below(g, (uint32_t)i + 1);
        uint16_t t = perm[i];
        perm[i] = perm[j];
        perm[j] = t;
    }
}

/* Stratum i of an m x m grid, jittered. */
static void stratum(ct_rng *g, int i, int m, float *u, float *v)
{
    *u = ((float)(i % m) + rng_float(g)) / (float)m;
    *v = ((float)((i / m) % m) + rng_float(g)) / (float)m;
}

/* Visible fraction of source s seen from receiver r: jittered segments
 * between points stratified over both (the source strata paired with the
 * receiver's by a random permutation, so a penumbra's estimate varies less
 * from element to element), each weighted by its point-to-point kernel
 * cos_r+ cos_s+ / d^2. Unweighted, a segment to a point behind the
 * receiver's plane (or from one behind the source's) counted as blocked:
 * the form factor's clipping already leaves such points out, so a sphere
 * seeing half of a floor got half its light twice over. Returns -1 when no
 * segment's kernel is positive (the exchange is too slight for its rays to
 * find). */
static double visibility(rad_ctx *c, const rad_elem *r, uint32_t src, int nrays, uint64_t tag, int shared,
                         int *nvalid)
{
    int emitting = src_has_emitter(c, src);
    ct_rng g = link_rng(c, r, src, !emitting && shared, tag);
    int m = 1;
    while (m * m < nrays) m++;
    nrays = m * m;   /* whole rows of strata: a partial last row leaves its stretch of the elements unsampled */
    vec3 n = c->patches[r->patch].n;
    const rad_elem *se = rad_el(c, src);
    vec3 nsrc = c->patches[se->patch].n;
    vec3 nr = v3_scale(n, c->ray_eps), ns = v3_scale(nsrc, c->ray_eps);
    uint16_t perm[1024];
    strata_perm(&g, perm, nrays);
    double sum = 0.0, sumv = 0.0;
    uint64_t traced = 0;
    for (int i = 0; i < nrays; i++) {
        float u, v, su, sv;
        stratum(&g, i, m, &u, &v);
        vec3 x = rad_elem_point(r, u, v);
        stratum(&g, perm[i], m, &su, &sv);
        vec3 y = rad_elem_point(se, su, sv);
        vec3 w = v3_sub(y, x);
        float d2 = v3_len2(w);
        if (!(d2 > 0.0f)) continue;
        float inv = 1.0f / sqrtf(d2);
        float cx = v3_dot(n, w) * inv, cy = -v3_dot(nsrc, w) * inv;
        if (cx <= 0.0f || cy <= 0.0f) continue;
        double kern = (double)cx * cy / d2;
        sum += kern;
        traced++;
        sumv += kern * rad_vis_transmit(c->vis, v3_add(x, nr), v3_add(y, ns));
    }
    atomic_fetch_add(&c->rays, traced);
    *nvalid = (int)traced;
    return sum > 0.0 ? sumv / sum : -1.0;
}

/* The patch of cluster k whose stretch of the cluster's area holds the
 * fraction u in [0, 1): patches are drawn in proportion to their area, and
 * since a cluster's patches are in BVH order, stratified u spread the
 * points over the cluster. */
static const rad_sgeo *cluster_patch(const rad_ctx *c, const rad_cluster *k, float u)
{
    double lo_a = c->sarea[k->pbegin], hi_a = c->sarea[k->pend];
    double a = lo_a + (double)u * (hi_a - lo_a);
    uint32_t lo = k->pbegin, hi = k->pend - 1;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (c->sarea[mid + 1] <= a) lo = mid + 1;
        else hi = mid;
    }
    return &c->sgeo[lo];
}

/* A cluster seen from r, by Monte Carlo over its area: points x_i
 * stratified over r, y_i drawn by area over the cluster's patches
 * (cluster_patch), and
 *   F = A_k / n * sum cos_x+ cos_y+ / (pi d^2),   FV = the same over the free segments,
 * an unbiased estimate of r's average factor to the cluster, unoccluded
 * and visible. Patches turned away from x_i count zero, so no model of the
 * cluster's projected area is needed (the normal-sum model this replaced
 * overestimated clusters of mixed orientations by up to half), and the
 * points follow the area, not the patch count: with one patch per pick, a
 * cluster of a large floor and a finely tessellated sphere was tested
 * almost only towards the sphere, whose self-occlusion then cut the floor's
 * light from the link. Segments whose kernel is zero trace no ray. */
static void cluster_factor(rad_ctx *c, const rad_elem *r, uint32_t src, double *F, double *FV)
{
    const rad_cluster *k = &c->clusters[src & RAD_ID_MASK];
    int emitting = k->has_emitter;
    int nrays = emitting ? c->prm.shadow_rays : c->prm.vis_rays;
    ct_rng g = link_rng(c, r, src, !emitting, TAG_DECIDE);
    int m = 1;
    while (m * m < nrays) m++;
    nrays = m * m;   /* whole rows of strata: a partial last row leaves its stretch of the elements unsampled */
    vec3 n = c->patches[r->patch].n;
    vec3 nr = v3_scale(n, c->ray_eps);
    uint16_t perm[1024];
    strata_perm(&g, perm, nrays);
    double sum = 0.0, sumv = 0.0;
    uint64_t traced = 0;
    for (int i = 0; i < nrays; i++) {
        float u, v;
        stratum(&g, i, m, &u, &v);
        vec3 x = rad_elem_point(r, u, v);
        float pu = ((float)perm[i] + rng_float(&g)) / (float)nrays;
        const rad_sgeo *q = cluster_patch(c, k, pu < 0x1.fffffep-1f ? pu : 0x1.fffffep-1f);
        float su = rng_float(&g), sv = rng_float(&g);
        vec3 y = poly_point(q->p, (int)q->nv, su, sv);
        vec3 w = v3_sub(y, x);
        float d2 = v3_len2(w);
        if (!(d2 > 0.0f)) continue;
        float inv = 1.0f / sqrtf(d2);
        float cx = v3_dot(n, w) * inv, cy = -v3_dot(q->n, w) * inv;
        if (cx <= 0.0f || cy <= 0.0f) continue;
        double kern = (double)cx * cy / (M_PI * d2);
        sum += kern;
        traced++;
        sumv += kern * rad_vis_transmit(c->vis, v3_add(x, nr), v3_add(y, v3_scale(q->n, c->ray_eps)));
    }
    atomic_fetch_add(&c->rays, traced);
    *F = (double)k->area * sum / nrays;
    *FV = (double)k->area * sumv / nrays;
}

/* ------------------------------------------------------------------------ */
/* Error oracle and refinement                                              */

static vec3 src_B(const rad_ctx *c, uint32_t src)
{
    if (src & RAD_CLUSTER_BIT) return c->clusters[src & RAD_ID_MASK].B[c->cur];
    return *rad_B(c, c->cur, src);
}

/* All corners of s behind r's plane (or the reverse): nothing is exchanged. */
static int faces_away(const rad_ctx *c, const rad_elem *r, const rad_elem *s)
{
    vec3 nr = c->patches[r->patch].n, ns = c->patches[s->patch].n;
    /* Coplanar neighbours must come out "behind" despite float rounding,
     * which grows with the coordinates, not with the element. */
    float tol_r = fmaxf(1e-5f * r->radius, 0.05f * c->ray_eps);
    float tol_s = fmaxf(1e-5f * s->radius, 0.05f * c->ray_eps);
    int front = 0;
    for (int i = 0; i < s->nv && !front; i++) front = v3_dot(nr, v3_sub(s->p[i], r->c)) > tol_r;
    if (!front) return 1;
    front = 0;
    for (int i = 0; i < r->nv && !front; i++) front = v3_dot(ns, v3_sub(r->p[i], s->c)) > tol_s;
    return !front;
}

static int cluster_behind(const rad_ctx *c, const rad_elem *r, const rad_cluster *k)
{
    vec3 nr = c->patches[r->patch].n;
    float tol = fmaxf(1e-5f * r->radius, 0.05f * c->ray_eps);
    for (int i = 0; i < 8; i++)
        if (v3_dot(nr, v3_sub(b3_corner(k->b, i), r->c)) > tol) return 0;
    return 1;
}

#define ERR_DROP (-1.0)

/* A cluster whose bounding sphere nearly touches r: no estimate holds. */
static int too_close(const rad_elem *r, const rad_cluster *k)
{
    double d = v3_len(v3_sub(k->c, r->c)) - k->radius - r->radius;
    return d <= 0.5 * k->radius;
}

/* An upper estimate of the power B * F * A_r the link r <- src carries
 * (ERR_DROP: no exchange at all; HUGE_VAL: a cluster too close to
 * estimate), from the bounding geometry alone. */
static double link_power(const rad_ctx *c, const rad_elem *r, uint32_t src)
{
    double B = v3_maxc(src_B(c, src));
    if (src & RAD_CLUSTER_BIT) {
        const rad_cluster *k = &c->clusters[src & RAD_ID_MASK];
        if (cluster_behind(c, r, k)) return ERR_DROP;
        if (B <= 0.0) return 0.0;
        if (too_close(r, k)) return HUGE_VAL;
        double d = v3_len(v3_sub(k->c, r->c)) - k->radius - r->radius;
        double f = 0.25 * k->area / (M_PI * d * d);
        return B * fmin(f, 1.0) * r->area;
    }
    const rad_elem *s = rad_el(c, src);
    if (faces_away(c, r, s)) return ERR_DROP;
    if (B <= 0.0) return 0.0;
    vec3 w = v3_sub(s->c, r->c);
    float d = v3_len(w);
    if (d <= 0.0f) return HUGE_VAL;
    w = v3_scale(w, 1.0f / d);
    float cr = fminf(1.0f, fmaxf(0.0f, v3_dot(c->patches[r->patch].n, w) + s->radius / d));
    float cs = fminf(1.0f, fmaxf(0.0f, -v3_dot(c->patches[s->patch].n, w) + r->radius / d));
    double f = (double)s->area * cr * cs / (M_PI * (double)d * d + s->area);
    return B * f * r->area;
}

static int push_link(rad_tls *t, uint32_t e, const rad_link *l)
{
    if (t->nout == t->capout) {
        size_t n = t->capout ? t->capout * 2 : 1024;
        rad_out_link *q = realloc(t->out, n * sizeof *q);
        if (!q) return CT_ENOMEM;
        t->out = q;
        t->capout = n;
    }
    t->out[t->nout].e = e;
    t->out[t->nout].l = *l;
    t->nout++;
    return 0;
}

/* Whether r may be subdivided: depth, minimum area and the patch's share of
 * --max-triangles for this pass (rad_refine_patch). A per-patch quota, not
 * the shared running count: with the shared count, which patches got the
 * last of the budget depended on thread timing. A split the quota refuses
 * is counted as the patch's want, its claim on the next pass's budget. */
static int can_split_receiver(const rad_ctx *c, rad_tls *t, const rad_elem *r)
{
    if (!(r->depth < RAD_MAX_DEPTH && r->area * 0.25 >= c->min_area)) return 0;
    if (t->quota >= (int64_t)rad_split_tris(r)) return 1;
    t->want += rad_split_tris(r);
    return 0;
}

/* Rays of a second look at a link whose first rays were all blocked. */
#define RETEST_RAYS 256

/* Evaluates the link r <- src into l: its factor and its error per unit of
 * source radiosity, over the receiver (gr: the factor's spread over r,
 * A_r dF V / 2, the mean deviation from its mean of a factor varying
 * linearly over r) and from a partly visible source (gv: A_r F 2V(1 - V),
 * the mean deviation of a lit / shadowed pattern covering the fraction V
 * of r). *F receives the unoccluded factor for value(). Returns -1 when the
 * link carries nothing and can go (no unoccluded exchange, or every ray to
 * an element blocked).
 *
 * A cluster's link stays even at zero: its few rays do not prove that
 * nothing of a large cluster is visible, and a kept link is refined when
 * its source brightens. Its factor is final here: clusters are refined by
 * their power bound alone, never by these rays. An element's factor comes
 * from other rays (value): the rays that decide whether a link is refined
 * must not be the ones it keeps. Refining exactly the links whose rays saw
 * a partial shadow, and keeping the rest as their rays said (all blocked:
 * dropped; all free: fully visible), made the kept estimates biased,
 * towards zero where most of a source is hidden: 3-5 % of the indirect
 * light in the Cornell box was lost that way with 4 rays per link. */
static int evaluate(rad_ctx *c, const rad_elem *r, uint32_t src, double P, rad_link *l, double *F, int *nr)
{
    l->src = src;
    l->ff = l->gr = l->gv = 0.0f;
    l->vis = 1.0f;
    double V, dF = 0.0;
    *F = 0.0;
    *nr = 0;
    if (src & RAD_CLUSTER_BIT) {
        /* A cluster too close to estimate is only kept while it is dark, as
         * a placeholder of factor 0; it is refined as soon as it has light
         * to give. */
        if (too_close(r, &c->clusters[src & RAD_ID_MASK])) return 0;
        double FV;
        cluster_factor(c, r, src, F, &FV);
        l->ff = (float)FV;
        return 0;
    }
    ff_elem(c, r, rad_el(c, src), F, &dF);
    if (!(*F > 0.0)) return -1;
    int n = src_has_emitter(c, src) ? c->prm.shadow_rays : c->prm.vis_rays, nvalid;
    *nr = n;
    V = visibility(c, r, src, n, TAG_DECIDE, 1, &nvalid);
    if (V <= 0.0 && P > c->eps) {
        /* A link that may carry P is declared hidden only on enough
         * evidence: with n rays all blocked, a source visible to the
         * fraction V is missed with probability (1 - V)^n, so the expected
         * loss P V (1 - V)^n is at most P / (e n): n = P / (e eps) rays
         * keep it within the threshold. */
        double want = ceil(P / (M_E * c->eps));
        int n2 = want > RETEST_RAYS ? RETEST_RAYS : (int)want;
        if (n2 > n) {
            V = visibility(c, r, src, n2, TAG_RETEST, 0, &nvalid);
            *nr = n2;
        }
    }
    if (V < 0.0) {
        /* No ray found the exchange: its visibility counted as unknown
         * (half). */
        l->gr = (float)(0.5 * r->area * dF);
        l->gv = (float)(0.5 * r->area * *F);
        return 0;
    }
    l->gr = (float)(0.5 * r->area * dF * V);
    l->gv = (float)(r->area * *F * 2.0 * V * (1.0 - V));
    return 0;
}

/* The factor a kept element link carries: F times the visible fraction of
 * n rays independent of evaluate's (see there; as many as it traced); -1
 * when they are all blocked (the link carries nothing and goes). */
static int value(rad_ctx *c, const rad_elem *r, rad_link *l, double F, int n)
{
    int nvalid;
    double V = visibility(c, r, l->src, n, TAG_VALUE, n <= c->prm.shadow_rays, &nvalid);
    if (V == 0.0) return -1;
    l->vis = (float)(V < 0.0 ? 1.0 : V);
    l->ff = (float)(F * l->vis);
    return 0;
}

/* Spread (largest minus smallest) of the radiosity of s's children: what
 * a link that reads s's mean radiosity cannot show. 0 for a leaf. */
static double src_spread(const rad_ctx *c, const rad_elem *s)
{
    if (s->child_pub == RAD_NONE) return 0.0;
    double lo = HUGE_VAL, hi = 0.0;
    for (uint32_t i = 0; i < 4; i++) {
        double b = v3_maxc(*rad_B(c, c->cur, s->child_pub + i));
        lo = fmin(lo, b);
        hi = fmax(hi, b);
    }
    return hi - lo;
}

static int grow_cand(rad_tls *t, size_t need)
{
    if (need <= t->capwork) return 0;
    size_t n = t->capwork ? t->capwork : 256;
    while (n < need) n *= 2;
    rad_cand *q = realloc(t->work, n * sizeof *q);
    if (!q) return CT_ENOMEM;
    t->work = q;
    t->capwork = n;
    return 0;
}

static int add_cand(rad_tls *t, uint32_t src, const rad_link *old)
{
    if (grow_cand(t, t->nwork + 1)) return CT_ENOMEM;
    rad_cand *k = &t->work[t->nwork++];
    if (old) k->l = *old;
    else k->l.src = src;
    k->fresh = old == NULL;
    k->err = 0.0f;
    return 0;
}

/* Whether r may be split, without counting a refusal (can_split_receiver
 * counts it once a split is actually wanted). */
static int receiver_splittable(const rad_ctx *c, const rad_tls *t, const rad_elem *r)
{
    if (r->child != RAD_NONE) return 1;
    return r->depth < RAD_MAX_DEPTH && r->area * 0.25 >= c->min_area && t->quota >= (int64_t)rad_split_tris(r);
}

/* Replaces candidate i by the children of its source (appended). */
static int split_cand(rad_ctx *c, rad_tls *t, size_t i)
{
    uint32_t src = t->work[i].l.src;
    t->work[i] = t->work[--t->nwork];
    atomic_fetch_add(&c->refined, 1);
    if (src & RAD_CLUSTER_BIT) {
        const rad_cluster *q = &c->clusters[src & RAD_ID_MASK];
        for (int j = 0; j < 2; j++)
            if (add_cand(t, q->child[j], NULL)) return CT_ENOMEM;
        return 0;
    }
    uint32_t first = rad_el(c, src)->child_pub;
    for (uint32_t j = 0; j < 4; j++)
        if (add_cand(t, first + j, NULL)) return CT_ENOMEM;
    return 0;
}

/* A source is split for links that may carry more than this share of the
 * threshold (refine_elem). */
#define SOURCE_SHARE 0.1

/* Refines element ei's links: those it kept from the last pass and those
 * its parent passed down to it (work[in_b, in_e), new here), then its
 * children's, recursively.
 *
 * The oracle is each link's error, not its power. A link gives its
 * receiver one irradiance, so its error is the factor's variation over the
 * receiver (gr) and a shadow boundary crossing it (gv), times the source's
 * radiosity: such a link moves down to the receiver's children (the
 * receiver splits). A link also reads its source's mean radiosity; the
 * error of that, summed over every receiver the source serves, is up to
 * A_s dB / 2 (dB the spread of its children's radiosity), and it has one
 * sign for all receivers on one side of the source: an element source
 * whose A_s dB / 2 exceeds the threshold is split for every link that may
 * carry more than SOURCE_SHARE of the threshold. (Judged per link, A_r F
 * dB / 2, each of a thousand small receivers kept reading the mean of a
 * floor lit in its middle: the ceiling above the light was 15 % too dark,
 * its corners at the open side 25-35 % too bright, and a closed box lost up
 * to 0.8 % of the emitted power, more as the threshold was tightened.) A
 * cluster approximates its patches as a whole: while the link's power
 * bound exceeds the threshold, the larger of cluster and receiver splits (a
 * sphere of many small patches resting on a floor stays one cluster for
 * the floor's large elements, instead of hundreds of patch links on each
 * of them).
 *
 * The power oracle B * F * A_r this replaced split the larger side, which
 * let a large receiver keep a thousand links from ever smaller sources,
 * each under the threshold and all wrong in the same direction across the
 * receiver: the ceiling of the open Cornell box was 1.4-2 times too bright
 * at the open side, the indirect light 8-13 % low elsewhere, and tighter
 * thresholds only split the sources further. */
static int refine_elem(rad_ctx *c, rad_tls *t, uint32_t ei, size_t in_b, size_t in_e)
{
    if (atomic_load(&c->failed)) return CT_ENOMEM;
    const rad_patch *p = &c->patches[rad_el(c, ei)->patch];
    size_t base = t->nwork;
    {
        const rad_elem *e = rad_el(c, ei);
        for (uint32_t i = 0; i < e->nlinks; i++)
            if (add_cand(t, 0, &p->links[e->link_off + i])) return CT_ENOMEM;
    }
    for (size_t k = in_b; k < in_e; k++)
        if (add_cand(t, t->work[k].l.src, NULL)) return CT_ENOMEM;
    int r_split = receiver_splittable(c, t, rad_el(c, ei));
    size_t down = base;   /* work[base, down): links moving to the children */
    for (int again = 1; again;) {
        again = 0;
        for (size_t i = down; i < t->nwork;) {
            rad_elem *r = rad_el(c, ei);
            rad_cand *k = &t->work[i];
            uint32_t src = k->l.src;
            double P = 0.0;
            int move = 0;
            if ((!(src & RAD_CLUSTER_BIT) && rad_el(c, src)->patch == r->patch) ||
                (P = link_power(c, r, src)) == ERR_DROP) {
                t->work[i] = t->work[--t->nwork];
                continue;
            }
            if (src & RAD_CLUSTER_BIT) {
                if (P > c->eps) {
                    const rad_cluster *q = &c->clusters[src & RAD_ID_MASK];
                    if (!r_split || q->radius > r->radius) {
                        if (split_cand(c, t, i)) return CT_ENOMEM;
                        continue;
                    }
                    move = 1;
                } else if (k->fresh) {
                    double F;
                    int nr;
                    evaluate(c, r, src, P, &k->l, &F, &nr);
                    /* A lit cluster none of whose rays got through goes (its
                     * estimate is zero either way); a dark one stays, to be
                     * examined again once it has light to give. */
                    if (k->l.ff == 0.0f && P > 0.0) {
                        t->work[i] = t->work[--t->nwork];
                        continue;
                    }
                }
            } else {
                const rad_elem *s = rad_el(c, src);
                double F = 0.0;
                int nr = 0;
                if (k->fresh && evaluate(c, r, src, P, &k->l, &F, &nr) < 0) {
                    t->work[i] = t->work[--t->nwork];
                    continue;
                }
                if (s->child_pub != RAD_NONE && P > SOURCE_SHARE * c->eps && 0.5 * s->area * src_spread(c, s) > c->eps) {
                    if (split_cand(c, t, i)) return CT_ENOMEM;
                    continue;
                }
                double err = v3_maxc(src_B(c, src)) * ((double)k->l.gr + k->l.gv);
                move = err > c->eps && r_split;
                if (!move && k->fresh && value(c, r, &k->l, F, nr) < 0) {
                    t->work[i] = t->work[--t->nwork];
                    continue;
                }
            }
            k = &t->work[i];
            k->fresh = 0;
            if (move) {
                /* Gathered at the front of the list. */
                rad_cand tmp = t->work[down];
                t->work[down++] = *k;
                t->work[i] = tmp;
            }
            i++;
        }
        if (down > base && rad_el(c, ei)->child == RAD_NONE && !can_split_receiver(c, t, rad_el(c, ei))) {
            /* Refused by the triangle budget after all (counted as wanted):
             * the links are examined again as at a leaf. */
            r_split = 0;
            for (size_t i = base; i < down; i++) t->work[i].fresh = 1;
            down = base;
            again = 1;
        }
    }
    if (down > base) {
        if (rad_el(c, ei)->child == RAD_NONE) {
            t->quota -= rad_split_tris(rad_el(c, ei));
            if (rad_subdivide(c, ei) != 0) {
                atomic_store(&c->failed, 1);
                return CT_ENOMEM;
            }
        }
        atomic_fetch_add(&c->refined, down - base);
    }
    for (size_t i = down; i < t->nwork; i++)
        if (push_link(t, ei, &t->work[i].l)) return CT_ENOMEM;
    uint32_t ch = rad_el(c, ei)->child;
    if (ch != RAD_NONE) {
        t->nwork = down;   /* the links moving down stay, below the children's lists */
        for (uint32_t j = 0; j < 4; j++) {
            int rc = refine_elem(c, t, ch + j, base, down);
            if (rc) return rc;
        }
    }
    t->nwork = base;
    return 0;
}

static int grow_u32(uint32_t **p, size_t *cap, size_t need)
{
    if (need <= *cap) return 0;
    size_t n = *cap ? *cap : 256;
    while (n < need) n *= 2;
    uint32_t *q = realloc(*p, n * sizeof *q);
    if (!q) return CT_ENOMEM;
    *p = q;
    *cap = n;
    return 0;
}

/* Lists patch p's tree in DFS order into t->elems. */
static int list_tree(rad_ctx *c, rad_tls *t, uint32_t root)
{
    t->nelems = 0;
    size_t sp = 0;
    if (grow_u32(&t->stack, &t->capstack, 1)) return CT_ENOMEM;
    t->stack[sp++] = root;
    while (sp) {
        uint32_t e = t->stack[--sp];
        if (grow_u32(&t->elems, &t->capelems, t->nelems + 1)) return CT_ENOMEM;
        t->elems[t->nelems++] = e;
        uint32_t ch = rad_el(c, e)->child;
        if (ch != RAD_NONE) {
            if (grow_u32(&t->stack, &t->capstack, sp + 4)) return CT_ENOMEM;
            for (int i = 3; i >= 0; i--) t->stack[sp++] = ch + (uint32_t)i;
        }
    }
    return 0;
}

int rad_refine_patch(rad_ctx *c, rad_tls *t, uint32_t pi)
{
    rad_patch *p = &c->patches[pi];
    int rc = 0;
    t->nout = 0;
    /* The patch's share of the pass's triangle budget: by what it wanted
     * and was refused in the last pass, or by area when no patch was refused
     * (the first pass). A pure function of the state at the pass start, so
     * the mesh is the same for any thread count and timing; what a patch
     * leaves unused returns to the next pass's budget. */
    double share = c->want_total ? (double)p->want / (double)c->want_total
                   : c->total_area > 0.0 ? rad_el(c, p->root)->area / c->total_area : 0.0;
    t->quota = (int64_t)floor((double)c->pass_budget * share);
    t->want = 0;
    t->nwork = 0;
    if (c->pass == 0) {
        /* The first pass starts every patch with one link from the whole scene. */
        if (c->nclusters) {
            if (add_cand(t, RAD_CLUSTER_BIT, NULL)) return CT_ENOMEM;
            rc = refine_elem(c, t, p->root, 0, 1);
        }
    } else {
        rc = refine_elem(c, t, p->root, 0, 0);
    }
    if (rc) return rc;
    /* Counting sort of the new links by element (DFS order of the grown tree). */
    rc = list_tree(c, t, p->root);
    if (rc) return rc;
    for (size_t i = 0; i < t->nelems; i++) {
        rad_elem *e = rad_el(c, t->elems[i]);
        e->link_off = (uint32_t)i;   /* temporarily: the element's list index */
        e->nlinks = 0;
    }
    for (size_t i = 0; i < t->nout; i++) rad_el(c, t->out[i].e)->nlinks++;
    uint32_t off = 0;
    for (size_t i = 0; i < t->nelems; i++) {
        rad_elem *e = rad_el(c, t->elems[i]);
        e->link_off = off;
        off += e->nlinks;
        e->nlinks = 0;
    }
    rad_link *blk = NULL;
    if (t->nout) {
        if (rad_track(c, (int64_t)(t->nout * sizeof *blk)) != 0) {
            atomic_store(&c->failed, 1);
            return CT_ENOMEM;
        }
        blk = malloc(t->nout * sizeof *blk);
        if (!blk) return CT_ENOMEM;
    }
    for (size_t i = 0; i < t->nout; i++) {
        rad_elem *e = rad_el(c, t->out[i].e);
        blk[e->link_off + e->nlinks++] = t->out[i].l;
    }
    rad_track(c, -(int64_t)((size_t)p->nlinks * sizeof *blk));
    free(p->links);
    p->links = blk;
    p->nlinks = (uint32_t)t->nout;
    p->want = t->want;
    return 0;
}

void rad_tls_free(rad_tls *t)
{
    free(t->out);
    free(t->elems);
    free(t->stack);
    free(t->work);
    memset(t, 0, sizeof *t);
}

/* A point just inside leaf e near x, a hair in front of its plane: a mesh
 * vertex lies on the planes of the neighbours it shares an edge with, where
 * the point factor to them would be cut to nothing. */
static vec3 gather_point(const rad_ctx *c, const rad_elem *e, vec3 x, vec3 n)
{
    return v3_add(v3_lerp(x, e->c, 1e-3f), v3_scale(n, c->ray_eps));
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

/* Whether the final gather keeps link l (of element e) as it is: a cluster's
 * factor is all it knows, and a factor that hardly varies over its
 * receiver is its own value at every vertex too (most links: far or small
 * sources). */
static int gather_flat(const rad_elem *e, const rad_link *l)
{
    return (l->src & RAD_CLUSTER_BIT) || l->gr <= GATHER_FLAT * e->area * l->ff;
}

int rad_gather_prepare(const rad_ctx *c, rad_gather_prep *g)
{
    memset(g, 0, sizeof *g);
    size_t n = c->nelems;
    g->flat = calloc(n ? n : 1, sizeof *g->flat);
    g->flat_d = calloc(n ? n : 1, sizeof *g->flat_d);
    g->off = calloc(n + 1, sizeof *g->off);
    if (!g->flat || !g->flat_d || !g->off) return CT_ENOMEM;
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
                    if (!gather_flat(e, l)) {
                        if (sweep) g->idx[fill++] = e->link_off + i;
                        else g->off[ei + 1]++;
                    } else if (sweep) {
                        vec3 B = (l->src & RAD_CLUSTER_BIT) ? c->clusters[l->src & RAD_ID_MASK].B[c->cur]
                                                            : *rad_B(c, c->cur, l->src);
                        vec3 E = (l->src & RAD_CLUSTER_BIT) ? c->clusters[l->src & RAD_ID_MASK].E
                                                            : c->patches[rad_el(c, l->src)->patch].E;
                        g->flat[ei] = v3_madd(g->flat[ei], B, l->ff);
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
    free(g->off);
    free(g->idx);
    memset(g, 0, sizeof *g);
}

void rad_final_gather(const rad_ctx *c, const rad_gather_prep *g, uint32_t leaf, vec3 x, vec3 n, vec3 *H,
                      vec3 *Hd)
{
    vec3 h = v3s(0.0f), hd = v3s(0.0f);
    vec3 xp = gather_point(c, rad_el(c, leaf), x, n);
    for (uint32_t ei = leaf; ei != RAD_NONE; ei = rad_el(c, ei)->parent) {
        const rad_elem *e = rad_el(c, ei);
        const rad_patch *p = &c->patches[e->patch];
        h = v3_add(h, g->flat[ei]);
        hd = v3_add(hd, g->flat_d[ei]);
        for (uint32_t k = g->off[ei]; k < g->off[ei + 1]; k++) {
            const rad_link *l = &p->links[g->idx[k]];
            const rad_elem *s = rad_el(c, l->src);
            float f = gather_factor(c, xp, n, s) * l->vis;
            h = v3_madd(h, *rad_B(c, c->cur, l->src), f);
            hd = v3_madd(hd, c->patches[s->patch].E, f);
        }
    }
    *H = h;
    *Hd = hd;
}
