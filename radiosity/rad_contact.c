/* rad_contact.c: mesh vertices hidden under geometry that stands on their
 * surface (rad_contact_vertices in rad_internal.h; docs/radiosity.md,
 * "Contact lines"). The quadtree of a floor does not know where a box
 * stands on it: an element straddles the box's edge with some corners
 * outside and some under the box, where the final gather finds no light.
 * Gouraud shading then smears that dark over the visible part of the
 * element: along the L room's box a band up to an element (2 cm) wide, up
 * to 60 % too dark at the box's edge. A hidden corner is given the
 * radiosity gathered where its edge to a lit corner of the same element
 * comes out from under the box (the contact line), which is what the
 * visible part lies next to. The same test of a point tells an element's
 * exposure (rad_exposure): what its links pass on comes from that part. */
#include "radiosity/rad_internal.h"

#include <math.h>
#include <stdlib.h>

/* A vertex is looked at when it is darker than this share of the
 * brightest corner of one of its elements: inside an element a hidden
 * corner stands out, a lit one does not. */
#define CONTACT_DARK 0.25f

/* Rays that must all meet a surface from behind (4 x 4 strata of the
 * cosine-weighted hemisphere, at their centres). */
#define CONTACT_RAYS_SIDE 4

/* Bisection steps from a hidden corner to the contact line along its edge:
 * the line is placed within 2^-12 of the edge's length. */
#define CONTACT_STEPS 12

/* Whether x on a surface of unit normal n is hidden: every ray over its
 * hemisphere meets a surface from behind, i.e. x lies inside a closed
 * object standing on its surface. A lit or shadowed point sees a front
 * face or open space along its first ray or soon after. */
static bool hidden(const rad_ctx *c, vec3 x, vec3 n)
{
    vec3 t, b;
    v3_basis(n, &t, &b);
    vec3 o = rad_lift(x, n);
    const int m = CONTACT_RAYS_SIDE;
    for (int i = 0; i < m * m; i++) {
        float u = ((float)(i % m) + 0.5f) / (float)m, v = ((float)(i / m) + 0.5f) / (float)m;
        float r = sqrtf(u), phi = 2.0f * CT_PI * v;
        vec3 d = v3_add(v3_add(v3_scale(t, r * cosf(phi)), v3_scale(b, r * sinf(phi))), v3_scale(n, sqrtf(1.0f - u)));
        if (!rad_vis_hits_back(c->vis, o, d)) return false;
    }
    return true;
}

/* 3 x 3 points: a quarter-covered element is told from an open one. */
#define EXPOSURE_SIDE 3

float rad_exposure(const rad_ctx *c, const rad_elem *e)
{
    if (!c->vis) return 1.0f;
    vec3 n = c->patches[e->patch].n;
    int open = 0;
    for (int i = 0; i < EXPOSURE_SIDE * EXPOSURE_SIDE; i++) {
        float u = ((float)(i % EXPOSURE_SIDE) + 0.5f) / EXPOSURE_SIDE;
        float v = ((float)(i / EXPOSURE_SIDE) + 0.5f) / EXPOSURE_SIDE;
        /* (a triangle's points fold over its diagonal: still inside) */
        open += !hidden(c, rad_elem_point(e, u, v), n);
    }
    return (float)open / (float)(EXPOSURE_SIDE * EXPOSURE_SIDE);
}

int rad_contact_vertices(const rad_ctx *c, const uint32_t *leaf, size_t nl, const uint32_t *boff,
                         const uint32_t *bvert, uint32_t nv, const vec3 *pos, vec3 *B, vec3 *Bd, uint32_t *moved)
{
    *moved = 0;
    /* Per vertex: the element (index into leaf) and corner it is darkest
     * against, the brightest such corner of all its elements (an element
     * wholly under the object has only dark corners to offer). */
    uint32_t *cl = malloc((nv ? nv : 1) * sizeof *cl);
    uint32_t *cu = malloc((nv ? nv : 1) * sizeof *cu);
    float *cmx = malloc((nv ? nv : 1) * sizeof *cmx);   /* that corner's luminance */
    uint32_t *rleaf = NULL, *rv = NULL;
    vec3 *rpos = NULL, *rB = NULL, *rBd = NULL;
    int rc = CT_ENOMEM;
    if (!cl || !cu || !cmx) goto done;
    for (uint32_t g = 0; g < nv; g++) cl[g] = RAD_NONE;
    uint32_t ncand = 0;
    for (size_t i = 0; i < nl; i++) {
        uint32_t b0 = boff[i], b1 = boff[i + 1], ub = RAD_NONE;
        float mx = 0.0f;
        for (uint32_t k = b0; k < b1; k++) {
            float y = v3_luminance(B[bvert[k]]);
            if (y > mx) {
                mx = y;
                ub = bvert[k];
            }
        }
        if (ub == RAD_NONE) continue;
        for (uint32_t k = b0; k < b1; k++) {
            uint32_t g = bvert[k];
            if (!(v3_luminance(B[g]) < CONTACT_DARK * mx)) continue;
            if (cl[g] == RAD_NONE) ncand++;
            else if (mx <= cmx[g]) continue;
            cl[g] = (uint32_t)i;
            cu[g] = ub;
            cmx[g] = mx;
        }
    }
    rleaf = malloc((ncand ? ncand : 1) * sizeof *rleaf);
    rv = malloc((ncand ? ncand : 1) * sizeof *rv);
    rpos = malloc((ncand ? ncand : 1) * sizeof *rpos);
    if (!rleaf || !rv || !rpos) goto done;
    uint32_t nr = 0;
    for (uint32_t g = 0; g < nv; g++) {
        if (cl[g] == RAD_NONE) continue;
        uint32_t e = leaf[cl[g]];
        vec3 n = c->patches[rad_el(c, e)->patch].n;
        vec3 x = pos[g], u = pos[cu[g]];
        if (!hidden(c, x, n) || hidden(c, u, n)) continue;
        /* The edge x -> u leaves the object between lo (hidden) and hi. */
        float lo = 0.0f, hi = 1.0f;
        for (int s = 0; s < CONTACT_STEPS; s++) {
            float mid = 0.5f * (lo + hi);
            if (hidden(c, v3_lerp(x, u, mid), n)) lo = mid;
            else hi = mid;
        }
        rleaf[nr] = e;
        rv[nr] = g;
        rpos[nr] = v3_lerp(x, u, hi);
        nr++;
    }
    rc = CT_OK;
    if (nr) {
        rB = malloc(nr * sizeof *rB);
        rBd = malloc(nr * sizeof *rBd);
        rc = rB && rBd ? rad_gather_points(c, rleaf, rpos, NULL, nr, rB, rBd) : CT_ENOMEM;
        for (uint32_t i = 0; i < nr && !rc; i++) {
            B[rv[i]] = rB[i];
            Bd[rv[i]] = rBd[i];
        }
        if (!rc) *moved = nr;
    }
done:
    free(cl);
    free(cu);
    free(cmx);
    free(rleaf);
    free(rv);
    free(rpos);
    free(rB);
    free(rBd);
    return rc;
}
