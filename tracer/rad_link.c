/* rad_link.c: form factors (Lambert's contour formula from points of the
 * receiver to the source polygon, averaged over a small quadrature), the
 * B*F*A error oracle of Hanrahan-Salzman-Aupperle, visibility by jittered
 * Embree rays, and the per-patch link refinement. */
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

/* Unoccluded form factor from element r to element s: the point-to-polygon
 * factor at r's centre, or averaged over a quadrature (quads: 2 x 2 Gauss-like
 * points; triangles: the 3-point rule) when r is large compared with the
 * distance, where the factor varies over r. */
static double ff_elem(const rad_ctx *c, const rad_elem *r, const rad_elem *s)
{
    vec3 n = c->patches[r->patch].n;
    float d = v3_len(v3_sub(s->c, r->c));
    if (r->radius < 0.2f * d) return rad_ff_point_polygon(r->c, n, s->p, s->nv);
    double sum = 0.0;
    if (r->nv == 4) {
        static const float g[2] = {0.25f, 0.75f};
        for (int i = 0; i < 2; i++)
            for (int j = 0; j < 2; j++)
                sum += rad_ff_point_polygon(poly_point(r->p, 4, g[i], g[j]), n, s->p, s->nv);
        return sum * 0.25;
    }
    for (int k = 0; k < 3; k++) {
        vec3 x = v3_add(v3_scale(r->p[k], 4.0f / 6.0f),
                        v3_add(v3_scale(r->p[(k + 1) % 3], 1.0f / 6.0f), v3_scale(r->p[(k + 2) % 3], 1.0f / 6.0f)));
        sum += rad_ff_point_polygon(x, n, s->p, s->nv);
    }
    return sum / 3.0;
}

/* A cluster seen from r: its projected area towards r is that of its
 * area-weighted normal N (exact for a planar cluster) plus a quarter of the
 * area N does not account for (the mean projected area of randomly oriented
 * one-sided surfaces); the cosine at r is averaged over the box's centre and
 * corners. */
static double ff_cluster(const rad_ctx *c, const rad_elem *r, const rad_cluster *k)
{
    vec3 n = c->patches[r->patch].n;
    vec3 w = v3_sub(k->c, r->c);
    float d2 = v3_len2(w);
    if (d2 <= 0.0f) return 0.0;
    float d = sqrtf(d2);
    double cs = fmax(0.0, v3_dot(n, w) / d);
    for (int i = 0; i < 8; i++) {
        vec3 q = v3_norm(v3_sub(b3_corner(k->b, i), r->c));
        cs += fmax(0.0, v3_dot(n, q));
    }
    cs /= 9.0;
    double nlen = v3_len(k->N);
    double proj = fmax(0.0, -v3_dot(k->N, w) / d) + 0.25 * fmax(0.0, k->area - nlen);
    double f = proj * cs / (M_PI * d2);
    return f < 1.0 ? f : 1.0;
}

/* ------------------------------------------------------------------------ */
/* Visibility                                                               */

static int src_has_emitter(const rad_ctx *c, uint32_t src)
{
    if (src & RAD_CLUSTER_BIT) return c->clusters[src & RAD_ID_MASK].has_emitter;
    return v3_maxc(c->patches[rad_el(c, src)->patch].E) > 0.0f;
}

/* Fraction of jittered segments between r and the source that are free:
 * receiver and source points both stratified, the source strata paired with
 * the receiver's by a random permutation (so a penumbra's estimate varies
 * less from element to element). For a cluster the end
 * point is on a random patch of it that faces the receiver point: the
 * cluster's projected area already accounts for the patches turned away, so
 * their (self-occluded) rays must not count twice. */
static float visibility(rad_ctx *c, const rad_elem *r, uint32_t src)
{
    int emitting = src_has_emitter(c, src);
    int nrays = emitting ? c->prm.shadow_rays : c->prm.vis_rays;
    uint64_t skey = (src & RAD_CLUSTER_BIT) ? ct_hash64(src) : rad_el(c, src)->key;
    /* Links from one non-emitting source share their jitter pattern, so
     * neighbouring receivers see the same few rays' bias instead of
     * independent noise (blotches across a curved surface); shadow rays to
     * emitters stay independent, or penumbrae would show as a few shifted
     * hard shadows. */
    ct_rng g = rng_make(c->prm.seed, emitting ? r->key : 0x5eedu, skey, 0x7669u);
    int m = 1;
    while (m * m < nrays) m++;
    vec3 nr = v3_scale(c->patches[r->patch].n, c->ray_eps);
    const rad_elem *se = (src & RAD_CLUSTER_BIT) ? NULL : rad_el(c, src);
    vec3 ns_eps = se ? v3_scale(c->patches[se->patch].n, c->ray_eps) : v3s(0.0f);
    int free_ = 0, counted = 0;
    uint16_t perm[1024];
    for (int i = 0; i < nrays; i++) perm[i] = (uint16_t)i;
    for (int i = nrays - 1; i > 0; i--) {
        uint32_t j = rng_below(&g, (uint32_t)i + 1);
        uint16_t t = perm[i];
        perm[i] = perm[j];
        perm[j] = t;
    }
    for (int i = 0; i < nrays; i++) {
        float u = ((float)(i % m) + rng_float(&g)) / (float)m;
        float v = ((float)((i / m) % m) + rng_float(&g)) / (float)m;
        vec3 a = v3_add(rad_elem_point(r, u, v), nr);
        int found = 0;
        vec3 b = a;
        if (src & RAD_CLUSTER_BIT) {
            const rad_cluster *k = &c->clusters[src & RAD_ID_MASK];
            for (int tries = 0; tries < 8 && !found; tries++) {
                const rad_sgeo *q = &c->sgeo[k->pbegin + rng_below(&g, k->pend - k->pbegin)];
                float su = rng_float(&g), sv = rng_float(&g);
                if (q->nv == 4) {
                    b = v3_lerp(v3_lerp(q->p[0], q->p[1], su), v3_lerp(q->p[3], q->p[2], su), sv);
                } else {
                    if (su + sv > 1.0f) { su = 1.0f - su; sv = 1.0f - sv; }
                    b = v3_add(q->p[0], v3_add(v3_scale(v3_sub(q->p[1], q->p[0]), su),
                                               v3_scale(v3_sub(q->p[2], q->p[0]), sv)));
                }
                found = v3_dot(q->n, v3_sub(a, b)) > 0.0f;
                b = v3_add(b, v3_scale(q->n, c->ray_eps));
            }
        } else {
            float su = ((float)(perm[i] % m) + rng_float(&g)) / (float)m;
            float sv = ((float)((perm[i] / m) % m) + rng_float(&g)) / (float)m;
            b = v3_add(rad_elem_point(se, su, sv), ns_eps);
            found = 1;
        }
        if (!found) continue;
        counted++;
        if (!rad_vis_occluded(c->vis, a, b)) free_++;
    }
    atomic_fetch_add(&c->rays, (uint64_t)counted);
    return counted ? (float)free_ / (float)counted : 0.0f;
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

/* Estimated power error B * F * A_r of the link r <- src (ERR_DROP: no
 * exchange at all; HUGE_VAL: too close to estimate). */
static double link_error(const rad_ctx *c, const rad_elem *r, uint32_t src)
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

static int push_link(rad_tls *t, uint32_t e, uint32_t src, float ff)
{
    if (t->nout == t->capout) {
        size_t n = t->capout ? t->capout * 2 : 1024;
        rad_out_link *q = realloc(t->out, n * sizeof *q);
        if (!q) return CT_ENOMEM;
        t->out = q;
        t->capout = n;
    }
    t->out[t->nout].e = e;
    t->out[t->nout].l.src = src;
    t->out[t->nout].l.ff = ff;
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

/* Unoccluded factor times visibility of a link; -1 when the link carries
 * nothing and can go (no unoccluded exchange, or every ray blocked). */
static float evaluate(rad_ctx *c, const rad_elem *r, uint32_t src, int *uniform)
{
    *uniform = 0;
    if (src & RAD_CLUSTER_BIT) {
        const rad_cluster *k = &c->clusters[src & RAD_ID_MASK];
        /* A cluster too close to estimate is only kept while it is dark, as
         * a placeholder of factor 0; it is refined as soon as it has light
         * to give. */
        if (too_close(r, k)) return 0.0f;
    }
    double f = (src & RAD_CLUSTER_BIT) ? ff_cluster(c, r, &c->clusters[src & RAD_ID_MASK])
                                       : ff_elem(c, r, rad_el(c, src));
    if (f <= 0.0) return -1.0f;
    float v = visibility(c, r, src);
    *uniform = v == 0.0f || v == 1.0f;
    return v > 0.0f ? (float)f * v : -1.0f;
}

/* Links whose rays all agreed (fully visible or fully hidden) carry less
 * error than the unoccluded estimate says: the shadow boundary, where
 * refinement pays, is elsewhere. */
#define UNIFORM_FACTOR 0.25

/* Refines one link r <- src; keeps it (with its factor, computed when
 * ff_old < 0) or replaces it by links of children. */
static int refine(rad_ctx *c, rad_tls *t, uint32_t ri, uint32_t src_flags, float ff_old)
{
    if (atomic_load(&c->failed)) return CT_ENOMEM;
    uint32_t src = src_flags & ~RAD_UNIFORM_BIT;
    int uniform = (src_flags & RAD_UNIFORM_BIT) != 0;
    rad_elem *r = rad_el(c, ri);
    if (!(src & RAD_CLUSTER_BIT) && rad_el(c, src)->patch == r->patch) return 0;
    double err = link_error(c, r, src);
    if (err == ERR_DROP) return 0;
    float ff = ff_old;
    if (ff >= 0.0f && uniform) err *= UNIFORM_FACTOR;
    int evaluated = 0;
    if (ff < 0.0f && err > c->eps && err * UNIFORM_FACTOR <= c->eps) {
        ff = evaluate(c, r, src, &uniform);
        evaluated = 1;
        if (uniform) err *= UNIFORM_FACTOR;
    }
    if (err > c->eps) {
        if (src & RAD_CLUSTER_BIT) {
            const rad_cluster *k = &c->clusters[src & RAD_ID_MASK];
            atomic_fetch_add(&c->refined, 1);
            for (int i = 0; i < 2; i++) {
                int rc = refine(c, t, ri, k->child[i], -1.0f);
                if (rc) return rc;
            }
            return 0;
        }
        const rad_elem *s = rad_el(c, src);
        int s_can = s->child_pub != RAD_NONE;
        /* The larger side splits; the receiver's split is asked for (and,
         * when its quota refuses, counted as wanted) only when it is the
         * one that should split. */
        int prefer_src = s_can && s->area > r->area;
        int r_can = !prefer_src && can_split_receiver(c, t, r);
        int split_src = s_can && (prefer_src || !r_can);
        if (split_src) {
            atomic_fetch_add(&c->refined, 1);
            for (uint32_t i = 0; i < 4; i++) {
                int rc = refine(c, t, ri, s->child_pub + i, -1.0f);
                if (rc) return rc;
            }
            return 0;
        }
        if (r_can) {
            t->quota -= rad_split_tris(r);
            if (rad_subdivide(c, ri) != 0) {
                atomic_store(&c->failed, 1);
                return CT_ENOMEM;
            }
            atomic_fetch_add(&c->refined, 1);
            uint32_t first = rad_el(c, ri)->child;
            for (uint32_t i = 0; i < 4; i++) {
                int rc = refine(c, t, first + i, src, -1.0f);
                if (rc) return rc;
            }
            return 0;
        }
    }
    if (ff < 0.0f && !evaluated) ff = evaluate(c, r, src, &uniform);
    /* A link that carries nothing (hidden from every ray, or no exchange)
     * goes; placeholders of factor 0 stay to be re-examined when their
     * source brightens. */
    if (ff < 0.0f) return 0;
    return push_link(t, ri, src | (uniform ? RAD_UNIFORM_BIT : 0u), ff);
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
    int rc = list_tree(c, t, p->root);
    if (rc) return rc;
    size_t n0 = t->nelems;
    if (grow_u32(&t->old, &t->capold, 2 * n0)) return CT_ENOMEM;
    for (size_t i = 0; i < n0; i++) {
        rad_elem *e = rad_el(c, t->elems[i]);
        t->old[2 * i] = e->link_off;
        t->old[2 * i + 1] = e->nlinks;
    }
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
    if (c->pass == 0) {
        /* The first pass starts every patch with one link from the whole scene. */
        uint32_t top = c->nclusters ? RAD_CLUSTER_BIT : RAD_NONE;
        if (top != RAD_NONE) rc = refine(c, t, p->root, top, -1.0f);
    } else {
        for (size_t i = 0; i < n0 && !rc; i++) {
            uint32_t off = t->old[2 * i], nl = t->old[2 * i + 1];
            for (uint32_t k = 0; k < nl && !rc; k++) {
                const rad_link *l = &p->links[off + k];
                rc = refine(c, t, t->elems[i], l->src, l->ff);
            }
        }
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
    free(t->old);
    free(t->stack);
    memset(t, 0, sizeof *t);
}
