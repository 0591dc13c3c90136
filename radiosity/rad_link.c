/* rad_link.c: the per-patch link refinement with its error oracle (the
 * links' error over the receiver and from the source's radiosity, not their
 * power), over the factors and visibility of rad_ff.c. (Just over 600
 * lines: the oracle's rules -- thresholds, shares, looks before a split --
 * and the one loop that applies them read best side by side.) */
#include "radiosity/rad_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"

/* ------------------------------------------------------------------------ */
/* Error oracle and refinement                                              */

/* An upper estimate of the radiosity any receiver gathers from src, for
 * the refinement's bounds: a cluster's brightest side (what it shows a
 * receiver is a blend of its sides, rad_cluster_B). Bounding by the side
 * the receiver sees refined less towards dark sides, and a closed box with
 * boxes in it lost 0.5 % of its power more. */
static vec3 src_B(const rad_ctx *c, uint32_t src)
{
    if (src & RAD_CLUSTER_BIT) return rad_cluster_B_max(&c->clusters[src & RAD_ID_MASK], c->cur);
    return *rad_B(c, c->cur, src);
}

/* All corners of s behind r's plane (or the reverse): nothing is exchanged. */
static int faces_away(const rad_ctx *c, const rad_elem *r, const rad_elem *s)
{
    vec3 nr = c->patches[r->patch].n, ns = c->patches[s->patch].n;
    /* Coplanar neighbours must come out "behind" despite float rounding,
     * which grows with the coordinates, not with the element. */
    float tol_r = fmaxf(1e-5f * r->radius, rad_pos_tol(r->c, r->radius + s->radius));
    float tol_s = fmaxf(1e-5f * s->radius, rad_pos_tol(s->c, r->radius + s->radius));
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
    float tol = fmaxf(1e-5f * r->radius, rad_pos_tol(r->c, r->radius + k->radius));
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
 * their power bound and a look for being hidden (cluster_hidden), never by
 * these rays. An element's factor comes
 * from other rays (value): the rays that decide whether a link is refined
 * must not be the ones it keeps. Refining exactly the links whose rays saw
 * a partial shadow, and keeping the rest as their rays said (all blocked:
 * dropped; all free: fully visible), made the kept estimates biased,
 * towards zero where most of a source is hidden: 3-5 % of the indirect
 * light in the Cornell box was lost that way with 4 rays per link. */
static int evaluate(rad_ctx *c, const rad_elem *r, uint32_t src, double P, rad_link *l, double *F, int *nr)
{
    l->src = src;
    l->ff = l->gr = 0.0f;
    if (src & RAD_CLUSTER_BIT) l->bk = 1.0f;   /* (set after the last refinement: rad_cluster_bk) */
    else l->gv = 0.0f;
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
        rad_cluster_factor(c, r, src, F, &FV);
        l->ff = (float)FV;
        /* Kept for the final gather, which looks at a vertex's own
         * visibility of a partly hidden cluster (rad_gather.c). */
        l->gr = (float)*F;
        l->vis = *F > 0.0 ? (float)(FV / *F) : 1.0f;
        return 0;
    }
    rad_ff_elem(c, r, rad_el(c, src), F, &dF);
    if (!(*F > 0.0)) return -1;
    int n = rad_src_has_emitter(c, src) ? c->prm.shadow_rays : c->prm.vis_rays, nvalid;
    *nr = n;
    /* Turned per receiver: a point shared by all would decide for all
     * (rad_ff.c, receiver_shift). */
    V = rad_visibility(c, r, src, n, TAG_DECIDE, RAD_RAYS_TURNED, &nvalid);
    if (V <= 0.0 && P > c->eps) {
        /* A link that may carry P is declared hidden only on enough
         * evidence: with n rays all blocked, a source visible to the
         * fraction V is missed with probability (1 - V)^n, so the expected
         * loss P V (1 - V)^n is at most P / (e n): n = P / (e eps) rays
         * keep it within the threshold. */
        double want = ceil(P / (M_E * c->eps));
        int n2 = want > RETEST_RAYS ? RETEST_RAYS : (int)want;
        if (n2 > n) {
            V = rad_visibility(c, r, src, n2, TAG_RETEST, RAD_RAYS_OWN, &nvalid);
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
 * when these rays and evaluate's were all blocked (the link carries
 * nothing and goes). A link whose deciding rays saw some of the source
 * stays even when these all came back blocked, with factor 0: dropping it
 * was a selection on rays that a later refinement discards (the cluster
 * links in refine_elem), which took 0.2 % of the emitted power out of the
 * closed box with boxes in it (solver version 9; docs/radiosity.md,
 * "Energy with occlusion"). The final gather's vertices keep its 0: their
 * own rays go to links in proportion to V (1 - V). */
static int value(rad_ctx *c, const rad_elem *r, rad_link *l, double F, int n)
{
    int nvalid;
    double V = rad_visibility(c, r, l->src, n, TAG_VALUE, n <= c->prm.shadow_rays ? RAD_RAYS_SHARED : RAD_RAYS_OWN,
                              &nvalid);
    /* None of these rays found the exchange (their points were all turned
     * away from each other): a closer look with RETEST_RAYS of its own
     * (evaluate's estimate would be the deciding rays' again, a selection:
     * see above); what even that misses is counted as unknown, half
     * visible. Taken as fully visible, grazing links carried their whole
     * unoccluded factor: ground reaching under a closed room got light from
     * inside it, a fortieth of the room's own (docs/radiosity.md, "Scale"). */
    if (V < 0.0) V = rad_visibility(c, r, l->src, RETEST_RAYS, TAG_RETEST, RAD_RAYS_OWN, &nvalid);
    if (V < 0.0) V = 0.5;
    if (V == 0.0 && l->gr == 0.0f && l->gv == 0.0f) return -1;
    l->vis = (float)V;
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

/* Whether r may be split (1), is refused by the quota alone (-1: a split
 * it then wants is counted, refine_elem), or is too small or too deep (0). */
static int receiver_splittable(const rad_ctx *c, const rad_tls *t, const rad_elem *r)
{
    if (r->child != RAD_NONE) return 1;
    if (!(r->depth < RAD_MAX_DEPTH && r->area * 0.25 >= c->min_area)) return 0;
    return t->quota >= (int64_t)rad_split_tris(r) ? 1 : -1;
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

/* A link whose source is partly hidden and closer to the receiver than
 * CONTACT_GAP of the receiver's radii is refined down to CONTACT_SHARE of
 * the threshold (refine_elem). Where a box stands on a floor, the floor
 * beside it and the box's foot exchange much of their light over a short
 * distance, past the box's edge, and factor and shadow vary across an
 * element faster than anywhere else: at the plain threshold the Cornell
 * box's short box face was 4-6 % too bright at its foot. Only partly
 * hidden links: every link near a room's corners too (nothing hidden
 * there) cost the office building a third more triangles, and in the
 * closed box the finer corner elements added 0.03 % to the power its walls
 * absorb, past the 0.2 % its test allows (docs/radiosity.md, "Contact
 * regions"). */
#define CONTACT_GAP   2.0
#define CONTACT_SHARE 0.1

/* Whether a cluster link whose bound P is over the threshold is hidden
 * from r: before r is split for it, a look with as many rays as evaluate's
 * retest of an element link (n = P / (e eps), so that a cluster visible to
 * the fraction V is missed with an expected loss P V (1 - V)^n <= eps),
 * drawn by the cluster's power. A hidden link is kept unrefined, as one
 * under the threshold. The bound ignores occlusion: without the look, a
 * 2 km ground plane under a closed lit room was split into 600,000
 * elements for light that never reaches it (33 s against 7 s for the room
 * alone; docs/radiosity.md, "Scale"). Not before the cluster is split (a
 * receiver smaller than it): that costs links, not triangles, and the
 * cluster links the look kept coarse there carried less light than their
 * children would (coarse clusters err dark, docs/radiosity.md "Office"):
 * the office building's indirect light fell 0.5-1 %. A cluster too close
 * to bound (P infinite) is refined as before. */
static int cluster_hidden(rad_ctx *c, const rad_elem *r, uint32_t src, double P)
{
    if (!isfinite(P)) return 0;
    double want = ceil(P / (M_E * c->eps));
    int n = want > RETEST_RAYS ? RETEST_RAYS : (int)want;
    if (n < c->prm.vis_rays) n = c->prm.vis_rays;
    return rad_cluster_hidden(c, r, src, n);
}

/* The share of the threshold a receiver's links get: its reflected
 * radiosity over the scene's mean, between prm.dim_floor and 1. The
 * threshold is a share of all the emitted power, so a receiver lit a
 * tenth as much as the mean would be refined only for errors ten times
 * larger relative to its own light, and a relative error is what the eye
 * sees. In the L room the arm lit only around the corner kept elements so
 * coarse that its end wall was 10-11 % too bright along its edges, which
 * shrank only with the threshold everywhere (7 % at a fifth of it, 4.8 % at
 * a twentieth: 23 MB of mesh, 428 s); a floor of 0.1 takes it to 4 % for
 * a third more triangles in the office building (docs/radiosity.md,
 * "Dim receivers"). The first pass has no solution to compare with. */
static double dim_share(const rad_ctx *c, uint32_t ei)
{
    if (c->prm.dim_floor <= 0.0 || !(c->reflected_mean > 0.0)) return 1.0;
    const rad_elem *r = rad_el(c, ei);
    /* (its own mean, not what it passes on from its exposed part: a floor
     * element reaching under a box is dim for what it shows) */
    vec3 b = rad_mean_B(c, c->cur, ei);
    double share = v3_maxc(v3_max(v3_sub(b, c->patches[r->patch].E), v3s(0.0f))) / c->reflected_mean;
    return share < c->prm.dim_floor ? c->prm.dim_floor : share > 1.0 ? 1.0 : share;
}

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
    /* A receiver the quota refuses still counts the split its links want:
     * that is its claim on the next pass's budget. Uncounted (solver
     * version 18), a patch whose area share of the first pass's budget was
     * under one split never claimed any and stayed one element: hundreds
     * of refinements a pass in the Cornell box, about 10,000 in the office
     * building, and a closed room beside a 2 km ground plane kept its walls
     * whole (docs/radiosity.md, "Scale"). */
    int r_split = receiver_splittable(c, t, rad_el(c, ei));
    const int starved = r_split < 0;
    int wanted = 0;
    if (starved) r_split = 0;
    const double dim = dim_share(c, ei);   /* the receiver's B does not change while it is refined */
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
                const rad_cluster *q = &c->clusters[src & RAD_ID_MASK];
                int refine = P > c->eps;
                if (refine && r_split && q->radius <= r->radius && cluster_hidden(c, r, src, P)) refine = 0;
                if (refine) {
                    wanted |= q->radius <= r->radius;
                    if (!r_split || q->radius > r->radius) {
                        if (split_cand(c, t, i)) return CT_ENOMEM;
                        continue;
                    }
                    move = 1;
                } else if (k->fresh) {
                    double F;
                    int nr;
                    /* A cluster none of whose rays got through stays, with
                     * factor 0: a later pass splits it when its light grows
                     * past the threshold, and its children are estimated
                     * afresh. Dropping it for a zero estimate kept exactly
                     * the links whose rays happened to get through and lost
                     * the rest, a selection on rays that refinement later
                     * discards: (solver version 6) it took 1.3 % of the
                     * emitted power out of the office building and 0.1-0.3 %
                     * out of a closed box with boxes in it, more with fewer
                     * rays per link (docs/radiosity.md, "Energy with
                     * occlusion"). */
                    evaluate(c, r, src, P, &k->l, &F, &nr);
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
                double gap = v3_len(v3_sub(s->c, r->c)) - s->radius - r->radius;
                double lim = gap < CONTACT_GAP * r->radius && k->l.gv > 0.0f ? CONTACT_SHARE * c->eps : c->eps;
                lim *= dim;
                move = err > lim && r_split;
                wanted |= err > lim;
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
    if (starved && wanted) t->want += rad_split_tris(rad_el(c, ei));
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
    /* The patch's share of the pass's triangle budget: half by its area,
     * half in equal parts, and when patches were refused in the last pass,
     * half of that and half by what each wanted. A pure function of the
     * state at the pass start, so the mesh is the same for any thread count
     * and timing; what a patch leaves unused returns to the next pass's
     * budget. By area alone, a small patch beside a large one got less than
     * one split (docs/radiosity.md, "Scale"); by want alone, every
     * patch not refused last pass got nothing. */
    double share = 0.5 / (double)c->npatches;
    if (c->total_area > 0.0) share += 0.5 * rad_el(c, p->root)->area / c->total_area;
    if (c->want_total) share = 0.5 * share + 0.5 * (double)p->want / (double)c->want_total;
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
