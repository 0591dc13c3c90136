/* rad_ff.c: form factors (Lambert's contour formula from points of the
 * smaller element to the other's polygon, averaged over a small quadrature,
 * turned by reciprocity), cluster factors by Monte Carlo over the cluster's
 * area, and visibility by jittered Embree rays weighted by the point kernel,
 * from an element or from a mesh vertex (rad_internal.h). (Over 600
 * lines: the factors, the cluster points and the link rays share the
 * strata, the random streams and the point pickers, which stay private to
 * this file.) */
#include "radiosity/rad_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"

/* ------------------------------------------------------------------------ */
/* Form factors                                                             */

/* The angle in [0, pi] between two vectors, from the length y > 0 of their
 * cross product and their dot product x: atan2(y, x) by the Cephes rational
 * approximation of atan on [0, tan(pi/8)] (within 5e-16 of libm's). The
 * point factor takes one per polygon edge, and libm's atan2 was 8 % of the
 * office building's solve; this one costs half of it. */
static inline double edge_angle(double y, double x)
{
    double ax = fabs(x);
    int steep = y > ax;
    double t = steep ? ax / y : y / ax, base = 0.0;
    if (t > 0.41421356237309503) {
        t = (t - 1.0) / (t + 1.0);
        base = 0.78539816339744831;
    }
    double z = t * t;
    double p = (((-8.750608600031904122785e-1 * z - 1.615753718733365076637e1) * z - 7.500855792314704667340e1) * z -
                1.228866684490136173410e2) * z - 6.485021904942025371773e1;
    double q = ((((z + 2.485846490142306297962e1) * z + 1.650270098316988542046e2) * z + 4.328810604912902668951e2) * z +
                4.853903996359136964868e2) * z + 1.945506571482613964425e2;
    double a = base + t + t * z * p / q;
    if (steep) a = 1.5707963267948966 - a;
    return x < 0.0 ? 3.141592653589793 - a : a;
}

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
        double gamma = edge_angle(lc, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
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

/* Side positions of a quad's 2 x 2 points: the receiver's spread points
 * (1/4, 3/4) and the Gauss-Legendre points of a factor's average
 * (1/2 -+ 1/(2 sqrt 3), exact for bicubics). */
static const float SPREAD_AT[2] = {0.25f, 0.75f};
static const float GAUSS_AT[2] = {0.21132487f, 0.78867513f};

/* An element's 2 x 2 points at side positions g (quads) or the 3-point
 * rule (4/6, 1/6, 1/6; triangles); returns their count. */
static int elem_points(const rad_elem *r, const float g[2], vec3 *x)
{
    if (r->nv == 4) {
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
 * a's centre, or over its Gauss points when a's radius exceeds GAUSS_FROM
 * times the distance d. The factor is curved over a, so one point is biased by
 * about (radius / d)^2, and always the same way for a small source beside a
 * large perpendicular receiver (a wall's element and a floor's): the centre
 * up to a fifth of d and the 1/4, 3/4 points beyond made the closed box's
 * walls exchange 0.2 % too much and created 0.23 % of its power at
 * --error 1e-4; Gauss points from a tenth of d 0.20 %, from a fortieth
 * 0.06 % (docs/radiosity.md, "Energy"). An element straddling
 * b's plane is clipped to the part in front of it first: its centre or
 * quadrature points alone would give all of it or nothing (a floor element
 * half under a box, seen from the box's side), which lost 16 % of the
 * floor's factor to a box standing on it. */
#define GAUSS_FROM 0.025f
static double ff_avg(const rad_ctx *c, const rad_elem *a, const rad_elem *b, float d)
{
    vec3 n = c->patches[a->patch].n, nb = c->patches[b->patch].n;
    float tol = fmaxf(1e-5f * a->radius, rad_pos_tol(b->c, b->radius + d));
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
    if (a->radius < GAUSS_FROM * d) return rad_ff_point_polygon(a->c, n, b->p, b->nv);
    vec3 x[4];
    int nq = elem_points(a, GAUSS_AT, x);
    double sum = 0.0;
    for (int k = 0; k < nq; k++) sum += rad_ff_point_polygon(x[k], n, b->p, b->nv);
    return sum / nq;
}

/* A curved receiver's corners whose factors with their shading normals
 * fall to this share of the largest straddle a terminator (rad_ff_elem). */
#define TERMINATOR_SHARE 0.1

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
void rad_ff_elem(const rad_ctx *c, const rad_elem *r, const rad_elem *s, double *F, double *dF)
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
    if (r->radius >= 0.2f * d) nx += elem_points(r, SPREAD_AT, x + nx);
    double lo = HUGE_VAL, hi = 0.0;
    for (int k = 0; k < nx; k++) {
        double f = rad_ff_point_polygon(x[k], n, s->p, s->nv);
        lo = fmin(lo, f);
        hi = fmax(hi, f);
    }
    *dF = hi - lo;
    const rad_patch *pr = &c->patches[r->patch];
    if (pr->curved) {
        /* The vertices gather with their shading normals (rad_mesh.c), and
         * on a curved surface those turn away from a source where the
         * plane still faces it: the light falls to zero along a line (a
         * terminator) that the plane's spread does not see, and the
         * Gouraud ramp between a lit and an unlit vertex overshot into the
         * dark side (the Cornell box's floor sphere 1.13 times path
         * tracing there in 4 x 4-pixel blocks at 64 x 64). Where the
         * corners' factors with their own shading normals fall to a tenth
         * of the largest or below, their spread is the receiver's: it
         * splits along the terminator (1.02-1.04). Taken everywhere on
         * curved patches it did as well there with four times the
         * triangles added (docs/radiosity.md, "Curved surfaces"). */
        double slo = HUGE_VAL, shi = 0.0;
        for (int k = 1; k <= r->nv; k++) {
            double f = rad_ff_point_polygon(x[k], rad_shade_normal(c, pr, x[k]), s->p, s->nv);
            slo = fmin(slo, f);
            shi = fmax(shi, f);
        }
        if (slo <= TERMINATOR_SHARE * shi) *dF = fmax(*dF, shi - slo);
    }
    if (s->area < r->area) *F = r->area > 0.0f ? ff_avg(c, s, r, d) * s->area / r->area : 0.0;
    else *F = ff_avg(c, r, s, d);
}

/* ------------------------------------------------------------------------ */
/* Visibility and cluster factors                                           */

int rad_src_has_emitter(const rad_ctx *c, uint32_t src)
{
    if (src & RAD_CLUSTER_BIT) return c->clusters[src & RAD_ID_MASK].has_emitter;
    return v3_maxc(c->patches[rad_el(c, src)->patch].E) > 0.0f;
}

/* The random stream of a link's rays, one per tag (TAG_*). Shared: the
 * stream of every link from this source. Links from one non-emitting source
 * share their jitter pattern, so neighbouring receivers see the same few
 * rays' bias instead of independent noise (blotches across a curved
 * surface or a shadow); the deciding rays turn it per receiver
 * (RAD_RAYS_TURNED, receiver_shift). Shadow rays to emitters stay independent, or penumbrae
 * would show as a few shifted hard shadows. */
/* A source's stable key: an element's (patch and child path), a cluster's
 * hashed index. */
static uint64_t src_key(const rad_ctx *c, uint32_t src)
{
    return (src & RAD_CLUSTER_BIT) ? ct_hash64(src) : rad_el(c, src)->key;
}

static ct_rng link_rng(const rad_ctx *c, const rad_elem *r, uint32_t src, int shared, uint64_t tag)
{
    return rng_make(c->prm.seed, shared ? 0x5eedu : r->key, src_key(c, src), tag);
}

/* The side m of the m x m strata for at least nrays rays: whole rows of
 * strata, as a partial last row leaves its stretch of the elements
 * unsampled. */
static int strata_side(int nrays)
{
    int m = 1;
    while (m * m < nrays) m++;
    return m;
}

/* Whether the segment x -> y leaves x's front (normal nx) and arrives at
 * y's front (normal ny); *cc receives cos_x cos_y and *d2 the squared
 * length, the parts of the point-to-point kernel. */
static int facing(vec3 x, vec3 nx, vec3 y, vec3 ny, double *cc, float *d2)
{
    vec3 w = v3_sub(y, x);
    *d2 = v3_len2(w);
    if (!(*d2 > 0.0f)) return 0;
    float inv = 1.0f / sqrtf(*d2);
    float cx = v3_dot(nx, w) * inv, cy = -v3_dot(ny, w) * inv;
    if (cx <= 0.0f || cy <= 0.0f) return 0;
    *cc = (double)cx * cy;
    return 1;
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

/* A shared stream puts its points on the source in the same places for
 * every receiver, so one unlucky point (1 mm under a lamp in a room
 * stretched four times, docs/radiosity.md "Shared rays") made every link
 * to the ceiling look part hidden and refined the whole room three times
 * over for one seed in four. Rays that ask for it (RAD_RAYS_TURNED: the
 * deciding rays, rad_link.c evaluate) turn the pattern on an element
 * source by an offset of the receiver's own (a Cranley-Patterson
 * rotation): the points stay stratified and paired as before, but no point
 * decides for all receivers. The value rays stay shared: turned too, neighbouring elements in a shadow drew
 * their own noise again, and the L room's box foot came out blotchier
 * (worst block over seeds 1-4 10.5 % on average against 8.7 %). A
 * cluster's points stay shared (cluster_segments): turned too, the office
 * building's drt image lost 0.1 dB against path tracing. */
static void receiver_shift(const rad_elem *r, float *du, float *dv)
{
    uint64_t h = ct_hash64(r->key ^ 0x7368696674ULL);
    *du = (float)(h & 0xffffffu) / 16777216.0f;
    *dv = (float)((h >> 24) & 0xffffffu) / 16777216.0f;
}

static float wrap01(float u)
{
    u -= floorf(u);
    return u < 1.0f ? u : 0.0f;
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
double rad_visibility(rad_ctx *c, const rad_elem *r, uint32_t src, int nrays, uint64_t tag, rad_rays rays,
                      int *nvalid)
{
    if (rad_src_has_emitter(c, src)) rays = RAD_RAYS_OWN;
    ct_rng g = link_rng(c, r, src, rays != RAD_RAYS_OWN, tag);
    float du = 0.0f, dv = 0.0f;
    if (rays == RAD_RAYS_TURNED) receiver_shift(r, &du, &dv);
    int m = strata_side(nrays);
    nrays = m * m;
    vec3 n = c->patches[r->patch].n;
    const rad_elem *se = rad_el(c, src);
    vec3 nsrc = c->patches[se->patch].n;
    uint16_t perm[1024];
    strata_perm(&g, perm, nrays);
    double sum = 0.0, sumv = 0.0;
    uint64_t traced = 0;
    for (int i = 0; i < nrays; i++) {
        float u, v, su, sv;
        stratum(&g, i, m, &u, &v);
        vec3 x = rad_elem_point(r, u, v);
        stratum(&g, perm[i], m, &su, &sv);
        su = wrap01(su + du);
        sv = wrap01(sv + dv);
        vec3 y = rad_elem_point(se, su, sv);
        double cc;
        float d2;
        if (!facing(x, n, y, nsrc, &cc, &d2)) continue;
        double kern = cc / d2;
        sum += kern;
        traced++;
        sumv += kern * rad_vis_transmit(c->vis, rad_lift(x, n), rad_lift(y, nsrc));
    }
    atomic_fetch_add(&c->rays, traced);
    *nvalid = (int)traced;
    return sum > 0.0 ? sumv / sum : -1.0;
}

/* The patch of cluster k whose stretch of the prefix sums pre (over the
 * patches in cluster order) holds the fraction u in [0, 1); NULL when the
 * cluster's stretch is empty. Since a cluster's patches are in BVH order,
 * stratified u spread the points over the cluster. */
static const rad_sgeo *cluster_pick(const rad_ctx *c, const double *pre, const rad_cluster *k, float u)
{
    double lo_a = pre[k->pbegin], hi_a = pre[k->pend];
    if (!(hi_a > lo_a)) return NULL;
    double a = lo_a + (double)(u < 0x1.fffffep-1f ? u : 0x1.fffffep-1f) * (hi_a - lo_a);
    uint32_t lo = k->pbegin, hi = k->pend - 1;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (pre[mid + 1] <= a) lo = mid + 1;
        else hi = mid;
    }
    return &c->sgeo[lo];
}

void rad_cluster_power(rad_ctx *c)
{
    for (uint32_t i = 0; i < c->npatches; i++) {
        const rad_patch *p = &c->patches[c->order[i]];
        double a = c->sarea[i + 1] - c->sarea[i];
        c->spow[i + 1] = c->spow[i] + a * v3_maxc(*rad_B(c, c->cur, p->root));
    }
}

/* Points drawn by power, not area: what a link carries comes from the
 * cluster's bright patches (a lamp, the walls it lights), and by area the
 * rays from a ground plane to a closed room went mostly to the room's dark
 * outside. A segment that meets the back of its patch, or leaves the back
 * of r, carries nothing and counts as blocked. */
int rad_cluster_hidden(rad_ctx *c, const rad_elem *r, uint32_t src, int nrays)
{
    const rad_cluster *k = &c->clusters[src & RAD_ID_MASK];
    ct_rng g = link_rng(c, r, src, 0, TAG_HIDDEN);
    int m = strata_side(nrays);
    nrays = m * m;
    vec3 n = c->patches[r->patch].n;
    uint16_t perm[1024];
    strata_perm(&g, perm, nrays);
    uint64_t traced = 0;
    int hidden = 1;
    for (int i = 0; i < nrays && hidden; i++) {
        float u, v;
        stratum(&g, i, m, &u, &v);
        vec3 x = rad_elem_point(r, u, v);
        float pu = ((float)perm[i] + rng_float(&g)) / (float)nrays;
        float su = rng_float(&g), sv = rng_float(&g);
        const rad_sgeo *q = cluster_pick(c, c->spow, k, pu);
        if (!q) break;
        vec3 y = poly_point(q->p, (int)q->nv, su, sv);
        double cc;
        float d2;
        if (!facing(x, n, y, q->n, &cc, &d2)) continue;
        traced++;
        hidden = !(rad_vis_transmit(c->vis, rad_lift(x, n), rad_lift(y, q->n)) > 0.0f);
    }
    atomic_fetch_add(&c->rays, traced);
    return hidden;
}

/* A point *y of cluster k for the fractions pu (which patch, by area) and
 * su, sv (where on it); returns its patch (normal, place in cluster order). */
static const rad_sgeo *cluster_point(const rad_ctx *c, const rad_cluster *k, float pu, float su, float sv, vec3 *y)
{
    const rad_sgeo *q = cluster_pick(c, c->sarea, k, pu);
    if (!q) q = &c->sgeo[k->pbegin];   /* (patches of no area: any point is as good) */
    *y = poly_point(q->p, (int)q->nv, su, sv);
    return q;
}

/* Whether y (in the plane of element e, patch normal n) lies inside e:
 * counter-clockwise around n, so left of every edge, up to rounding. */
static int elem_contains(const rad_elem *e, vec3 n, vec3 y)
{
    float tol = -1e-4f * e->radius * e->radius;
    for (int i = 0; i < e->nv; i++) {
        vec3 a = e->p[i], b = e->p[(i + 1) % e->nv];
        if (v3_dot(v3_cross(v3_sub(b, a), v3_sub(y, a)), n) < tol) return 0;
    }
    return 1;
}

/* The leaf of the published tree under element ei that holds point y of
 * its patch (normal n): the child that contains y at each level, the
 * nearest by centre where rounding leaves none. */
static uint32_t leaf_at(const rad_ctx *c, uint32_t ei, vec3 n, vec3 y)
{
    for (;;) {
        const rad_elem *e = rad_el(c, ei);
        if (e->child_pub == RAD_NONE) return ei;
        uint32_t next = RAD_NONE, near = e->child_pub;
        float nd = HUGE_VALF;
        for (uint32_t k = 0; k < 4 && next == RAD_NONE; k++) {
            const rad_elem *q = rad_el(c, e->child_pub + k);
            if (elem_contains(q, n, y)) next = e->child_pub + k;
            float d = v3_len2(v3_sub(q->c, y));
            if (d < nd) {
                nd = d;
                near = e->child_pub + k;
            }
        }
        ei = next != RAD_NONE ? next : near;
    }
}

/* Sums over at least nrays segments (a square number; returned) from
 * points stratified over r to points drawn by area over cluster k's
 * patches (cluster_point), stream g: *sum of their kernels cos_x+ cos_y+ /
 * (pi d^2), *sumv of those of the free ones, and with sumb the latter
 * weighted by the radiosity where each lands (the leaf there, the current
 * solution). Segments whose kernel is zero trace no ray. */
static int cluster_segments(rad_ctx *c, const rad_elem *r, const rad_cluster *k, ct_rng *g, int nrays,
                            double *sum, double *sumv, double *sumb)
{
    int m = strata_side(nrays);
    nrays = m * m;
    vec3 n = c->patches[r->patch].n;
    uint16_t perm[1024];
    strata_perm(g, perm, nrays);
    uint64_t traced = 0;
    *sum = *sumv = 0.0;
    if (sumb) *sumb = 0.0;
    for (int i = 0; i < nrays; i++) {
        float u, v;
        stratum(g, i, m, &u, &v);
        vec3 x = rad_elem_point(r, u, v);
        float pu = ((float)perm[i] + rng_float(g)) / (float)nrays;
        float su = rng_float(g), sv = rng_float(g);
        vec3 y;
        const rad_sgeo *q = cluster_point(c, k, pu, su, sv, &y);
        double cc;
        float d2;
        if (!facing(x, n, y, q->n, &cc, &d2)) continue;
        double kern = cc / (M_PI * d2);
        *sum += kern;
        traced++;
        double kv = kern * rad_vis_transmit(c->vis, rad_lift(x, n), rad_lift(y, q->n));
        *sumv += kv;
        if (sumb && kv > 0.0) {
            uint32_t root = c->patches[c->order[q - c->sgeo]].root;
            *sumb += kv * v3_avg(*rad_B(c, c->cur, leaf_at(c, root, q->n, y)));
        }
    }
    atomic_fetch_add(&c->rays, traced);
    return nrays;
}

/* A cluster seen from r, by Monte Carlo over its area: points x_i
 * stratified over r, y_i drawn by area over the cluster's patches
 * (cluster_pick), and
 *   F = A_k / n * sum cos_x+ cos_y+ / (pi d^2),   FV = the same over the free segments,
 * an unbiased estimate of r's average factor to the cluster, unoccluded
 * and visible. Patches turned away from x_i count zero, so no model of the
 * cluster's projected area is needed (the normal-sum model this replaced
 * overestimated clusters of mixed orientations by up to half), and the
 * points follow the area, not the patch count: with one patch per pick, a
 * cluster of a large floor and a finely tessellated sphere was tested
 * almost only towards the sphere, whose self-occlusion then cut the floor's
 * light from the link. */
void rad_cluster_factor(rad_ctx *c, const rad_elem *r, uint32_t src, double *F, double *FV)
{
    const rad_cluster *k = &c->clusters[src & RAD_ID_MASK];
    int emitting = k->has_emitter;
    int nrays = emitting ? c->prm.shadow_rays : c->prm.vis_rays;
    ct_rng g = link_rng(c, r, src, !emitting, TAG_DECIDE);
    double sum, sumv;
    int n = cluster_segments(c, r, k, &g, nrays, &sum, &sumv, NULL);
    *F = (double)k->area * sum / n;
    *FV = (double)k->area * sumv / n;
}

/* bk of r's link from non-emitting cluster src: the radiosity its free
 * segments land on over the cluster's mean as r sees it (rad_cluster_B).
 * The mean weighs the cluster's patches by area, openness and facing, not
 * by what r sees of them: in the office building the cluster links
 * brought 6 % less light than rays from their receivers saw, a third less
 * from clusters of over 512 patches, and all of the building was darker
 * than path tracing (docs/radiosity.md, "Cluster links"). The link's own
 * rays (evaluate's, the same stream), so that ff bk B = A_k / n sum kern
 * V B(y) over them, an unbiased estimate of what the link brings; a ratio
 * from other rays, a few of them, stands for the mean over what the rays
 * hit rather than over what their kernels weigh. Like the factor, the
 * points on the cluster are the same for all its receivers: neighbouring
 * elements agree, and the solution stays smooth (rays of each receiver's
 * own were tried: 37.98 dB against 38.11 in the office comparison). */
static float cluster_bk(rad_ctx *c, const rad_elem *r, uint32_t src)
{
    const rad_cluster *k = &c->clusters[src & RAD_ID_MASK];
    ct_rng g = link_rng(c, r, src, 1, TAG_DECIDE);
    double sum, sumv, sumb;
    cluster_segments(c, r, k, &g, c->prm.vis_rays, &sum, &sumv, &sumb);
    double mean = v3_avg(rad_cluster_B(k, c->cur, r->c));
    return sumv > 0.0 && mean > 0.0 ? (float)(sumb / (sumv * mean)) : 1.0f;
}

void rad_cluster_bk(rad_ctx *c, uint32_t pi)
{
    const rad_patch *p = &c->patches[pi];
    uint32_t stack[4 * RAD_MAX_DEPTH + 8];
    int sp = 0;
    stack[sp++] = p->root;
    while (sp) {
        const rad_elem *e = rad_el(c, stack[--sp]);
        if (e->child != RAD_NONE)
            for (uint32_t k = 0; k < 4; k++) stack[sp++] = e->child + k;
        for (uint32_t i = 0; i < e->nlinks; i++) {
            rad_link *l = &p->links[e->link_off + i];
            if ((l->src & RAD_CLUSTER_BIT) && l->ff > 0.0f && !c->clusters[l->src & RAD_ID_MASK].has_emitter)
                l->bk = cluster_bk(c, e, l->src);
        }
    }
}

/* Visible fraction of source src (element or cluster) seen from point x
 * (normal n, already lifted off its surface): rays to nrays points over the
 * source (an element's stratified, a cluster's drawn by area over its
 * patches), each weighted by its point-to-point kernel; -1 when no point is
 * in front of x. key seeds the jitter, so the result does not depend on
 * the thread that asks. */
float rad_point_visibility(const rad_ctx *c, vec3 x, vec3 n, uint32_t src, int nrays, uint64_t key)
{
    ct_rng g = rng_make(c->prm.seed, key, src_key(c, src), 0x7665727478ULL);
    int m = strata_side(nrays);
    const rad_cluster *k = (src & RAD_CLUSTER_BIT) ? &c->clusters[src & RAD_ID_MASK] : NULL;
    const rad_elem *se = k ? NULL : rad_el(c, src);
    double sum = 0.0, sumv = 0.0;
    for (int i = 0; i < m * m; i++) {
        float u, v;
        stratum(&g, i, m, &u, &v);
        vec3 y, ny;
        if (k) {
            ny = cluster_point(c, k, ((float)i + rng_float(&g)) / (float)(m * m), u, v, &y)->n;
        } else {
            y = rad_elem_point(se, u, v);
            ny = c->patches[se->patch].n;
        }
        double cc;
        float d2;
        if (!facing(x, n, y, ny, &cc, &d2)) continue;
        double kern = cc / d2;
        sum += kern;
        sumv += kern * rad_vis_transmit(c->vis, x, rad_lift(y, ny));
    }
    return sum > 0.0 ? (float)(sumv / sum) : -1.0f;
}
