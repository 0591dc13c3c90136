/* rad_gather.c: the final gather at the mesh's vertices: what each
 * element's links bring, summed once for the links whose factor is flat over
 * it, the others' factors taken at every vertex (rad_internal.h). */
#include "tracer/rad_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"

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
                        vec3 B = (l->src & RAD_CLUSTER_BIT)
                                     ? rad_cluster_B(&c->clusters[l->src & RAD_ID_MASK], c->cur, e->c)
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
