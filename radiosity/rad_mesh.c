/* rad_mesh.c: meshes the leaves of the element hierarchy into a conforming
 * triangle mesh. Leaf corners are welded on their exact positions (midpoints
 * are bit-identical from both sides of a shared edge, rad_patch.c); a leaf
 * whose edges carry vertices of finer neighbours is anchored: triangulated as
 * a fan from its centre through every boundary vertex, so no T-vertex is left.
 * Vertex values are the mean of the leaves that share the vertex, within one
 * node and material and below the crease angle; elsewhere vertices are
 * duplicated so values stay separate. */
#include "radiosity/rad_internal.h"

#include <stdlib.h>
#include <string.h>

#include "common/rng.h"

typedef struct poshash {
    uint32_t *slot;   /* point index + 1, 0 = empty */
    uint32_t mask;
    vec3 *pts;
    uint32_t npts, cap;
} poshash;

static uint64_t pos_key(vec3 p, uint32_t k[3])
{
    float f[3] = {p.x, p.y, p.z};
    for (int i = 0; i < 3; i++) {
        if (f[i] == 0.0f) f[i] = 0.0f;   /* -0 and +0 are one point */
        memcpy(&k[i], &f[i], 4);
    }
    return ct_hash64(((uint64_t)k[0] << 32 | k[1]) ^ ct_hash64(k[2]));
}

static int same(vec3 a, const uint32_t k[3])
{
    uint32_t b[3];
    pos_key(a, b);
    return b[0] == k[0] && b[1] == k[1] && b[2] == k[2];
}

/* Index of p, or RAD_NONE when absent and !insert. */
static uint32_t ph_get(poshash *h, vec3 p, int insert)
{
    uint32_t k[3];
    uint64_t hv = pos_key(p, k);
    for (uint32_t i = (uint32_t)hv & h->mask;; i = (i + 1) & h->mask) {
        uint32_t s = h->slot[i];
        if (!s) {
            if (!insert || h->npts >= h->cap) return RAD_NONE;
            h->pts[h->npts] = p;
            h->slot[i] = ++h->npts;
            return h->npts - 1;
        }
        if (same(h->pts[s - 1], k)) return s - 1;
    }
}

typedef struct u32vec {
    uint32_t *v;
    size_t n, cap;
} u32vec;

static int push(u32vec *a, uint32_t x)
{
    if (a->n == a->cap) {
        size_t n = a->cap ? a->cap * 2 : 4096;
        uint32_t *q = realloc(a->v, n * sizeof *q);
        if (!q) return CT_ENOMEM;
        a->v = q;
        a->cap = n;
    }
    a->v[a->n++] = x;
    return 0;
}

/* --- points on input patch edges ------------------------------------------
 * Input meshes may have T-junctions of their own (a wall tessellated finer
 * than the ceiling it meets). Every mesh point lying on an input patch's
 * boundary edge is found through a hashed uniform grid and kept, sorted
 * along the edge; leaf edges on that boundary take their inner vertices from
 * there, so they are anchored to foreign vertices too. */

typedef struct pgrid {
    float h, inv_h;
    vec3 lo;
    uint32_t mask;
    uint32_t *start;   /* bucket -> first index in ids (size mask + 2) */
    uint32_t *ids;     /* point ids grouped by bucket */
} pgrid;

static void cell_of(const pgrid *g, vec3 p, int32_t q[3])
{
    q[0] = (int32_t)floorf((p.x - g->lo.x) * g->inv_h);
    q[1] = (int32_t)floorf((p.y - g->lo.y) * g->inv_h);
    q[2] = (int32_t)floorf((p.z - g->lo.z) * g->inv_h);
}

static uint32_t bucket_of(const pgrid *g, const int32_t q[3])
{
    uint64_t k = ((uint64_t)(uint32_t)q[0] * 0x9E3779B1u) ^ ((uint64_t)(uint32_t)q[1] * 0x85EBCA77u) ^
                 ((uint64_t)(uint32_t)q[2] * 0xC2B2AE3Du);
    return (uint32_t)ct_hash64(k) & g->mask;
}

static int pgrid_build(pgrid *g, const vec3 *pts, uint32_t n, float h)
{
    memset(g, 0, sizeof *g);
    g->h = h;
    g->inv_h = 1.0f / h;
    g->lo = v3s(0.0f);
    uint32_t cap = 1;
    while (cap < 2 * n + 2) cap <<= 1;
    g->mask = cap - 1;
    g->start = calloc((size_t)cap + 1, sizeof *g->start);
    g->ids = malloc(((size_t)n + 1) * sizeof *g->ids);
    uint32_t *b = malloc(((size_t)n + 1) * sizeof *b);
    if (!g->start || !g->ids || !b) {
        free(b);
        return CT_ENOMEM;
    }
    for (uint32_t i = 0; i < n; i++) {
        int32_t q[3];
        cell_of(g, pts[i], q);
        b[i] = bucket_of(g, q);
        g->start[b[i] + 1]++;
    }
    for (uint32_t i = 0; i < cap; i++) g->start[i + 1] += g->start[i];
    uint32_t *fill = malloc(((size_t)cap + 1) * sizeof *fill);
    if (!fill) {
        free(b);
        return CT_ENOMEM;
    }
    memcpy(fill, g->start, ((size_t)cap + 1) * sizeof *fill);
    for (uint32_t i = 0; i < n; i++) g->ids[fill[b[i]]++] = i;
    free(fill);
    free(b);
    return 0;
}

static void pgrid_free(pgrid *g)
{
    free(g->start);
    free(g->ids);
}

/* Points within this share of an edge's length or coordinates lie on it
 * (segment_points). */
#define SEG_TOL 4e-6f

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y;
}

/* The point grid's cell side: the median leaf's, so that a cell holds a
 * few points where the leaves are. By the mean, a 2 km ground plane of a
 * few large leaves beside a room of 26,000 small ones made 12 m cells, the
 * room's points shared a handful of them, and finding the points on its
 * edges took 7 s instead of 2. Never under the position tolerance of
 * segment_points, which looks one cell around. -1: out of memory. */
static float grid_cell(const rad_ctx *c, const u32vec *leaves)
{
    if (leaves->n == 0) return 1.0f;
    float *a = malloc(leaves->n * sizeof *a);
    if (!a) return -1.0f;
    float mag = 0.0f;
    for (size_t i = 0; i < leaves->n; i++) {
        const rad_elem *e = rad_el(c, leaves->v[i]);
        a[i] = e->area;
        mag = fmaxf(mag, v3_maxabs(e->c) + e->radius);
    }
    qsort(a, leaves->n, sizeof *a, cmp_float);
    float cell = sqrtf(a[leaves->n / 2]);
    free(a);
    float least = 4.0f * SEG_TOL * mag;   /* an edge is at most 2 sqrt(3) mag long */
    if (!(cell > least)) cell = least;
    return cell > 0.0f && isfinite(cell) ? cell : 1.0f;
}

typedef struct tpoint {
    float t;
    uint32_t id;
} tpoint;

static int cmp_tpoint(const void *a, const void *b)
{
    float x = ((const tpoint *)a)->t, y = ((const tpoint *)b)->t;
    return x < y ? -1 : x > y;
}

/* Appends to out the points strictly inside segment a-b (within a tolerance
 * of its length), sorted by their parameter t along it. stamp/mark dedupe
 * candidates seen through several cells. */
static int segment_points(const pgrid *g, const vec3 *pts, vec3 a, vec3 b, uint32_t *mark, uint32_t stamp,
                          tpoint **out, size_t *nout, size_t *capout)
{
    vec3 ab = v3_sub(b, a);
    float l2 = v3_len2(ab);
    if (!(l2 > 0.0f)) return 0;
    float len = sqrtf(l2);
    /* Rounding of coordinates, not of the edge, sets the tolerance. */
    float scale = fmaxf(v3_maxabs(a), v3_maxabs(b));
    float tol = SEG_TOL * fmaxf(scale, len);
    int steps = (int)ceilf(len * g->inv_h) + 1;
    if (steps > 1 << 20) steps = 1 << 20;
    size_t first = *nout;
    int32_t prev[3] = {INT32_MIN, INT32_MIN, INT32_MIN};
    for (int s = 0; s <= steps; s++) {
        vec3 p = v3_add(a, v3_scale(ab, (float)s / (float)steps));
        int32_t q[3];
        cell_of(g, p, q);
        if (q[0] == prev[0] && q[1] == prev[1] && q[2] == prev[2]) continue;
        memcpy(prev, q, sizeof prev);
        for (int dz = -1; dz <= 1; dz++)
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int32_t r[3] = {q[0] + dx, q[1] + dy, q[2] + dz};
                    uint32_t bk = bucket_of(g, r);
                    for (uint32_t k = g->start[bk]; k < g->start[bk + 1]; k++) {
                        uint32_t id = g->ids[k];
                        if (mark[id] == stamp) continue;
                        mark[id] = stamp;
                        vec3 d = v3_sub(pts[id], a);
                        float t = v3_dot(d, ab) / l2;
                        if (t * len <= tol || (1.0f - t) * len <= tol) continue;
                        vec3 off = v3_sub(d, v3_scale(ab, t));
                        if (v3_len2(off) > tol * tol) continue;
                        if (*nout == *capout) {
                            size_t nc = *capout ? *capout * 2 : 1024;
                            tpoint *x = realloc(*out, nc * sizeof *x);
                            if (!x) return CT_ENOMEM;
                            *out = x;
                            *capout = nc;
                        }
                        (*out)[*nout].t = t;
                        (*out)[*nout].id = id;
                        (*nout)++;
                    }
                }
    }
    if (*nout - first > 1) qsort(*out + first, *nout - first, sizeof **out, cmp_tpoint);
    return 0;
}

/* Parameter of p along a-b when p lies on that segment (inside tol), else -1. */
static float on_segment(vec3 a, vec3 b, vec3 p)
{
    vec3 ab = v3_sub(b, a), d = v3_sub(p, a);
    float l2 = v3_len2(ab);
    if (!(l2 > 0.0f)) return -1.0f;
    float t = v3_dot(d, ab) / l2;
    if (t < -1e-6f || t > 1.0f + 1e-6f) return -1.0f;
    float scale = fmaxf(v3_maxabs(a), v3_maxabs(b));
    float tol = 4e-6f * fmaxf(scale, sqrtf(l2));
    return v3_len2(v3_sub(d, v3_scale(ab, t))) <= tol * tol ? t : -1.0f;
}

/* The scene's shading normal at point q of patch pa: its triangle's (of a
 * quad, the one q lies in) vertex normals interpolated at q's barycentrics.
 * The tracer shades the radiosity mesh with these in drt, so they must be
 * the scene's, not the patches' averaged face normals: a faceted sphere
 * read smooth in drt and banded in path (6-14 % apart per region). The
 * patch normal stands in where the interpolation degenerates or faces the
 * patch's back. */
vec3 rad_shade_normal(const rad_ctx *c, const rad_patch *pa, vec3 q)
{
    const ct_scene *s = c->scene;
    int ntri = rad_el(c, pa->root)->nv == 4 ? 2 : 1;
    vec3 best = pa->n;
    float best_in = -INFINITY;
    for (int k = 0; k < ntri; k++) {
        const uint32_t *i = s->tris + 3 * ((size_t)pa->tri + (size_t)k);
        vec3 a = s->pos[i[0]], e1 = v3_sub(s->pos[i[1]], a), e2 = v3_sub(s->pos[i[2]], a), d = v3_sub(q, a);
        float d11 = v3_dot(e1, e1), d12 = v3_dot(e1, e2), d22 = v3_dot(e2, e2);
        float d1 = v3_dot(d, e1), d2 = v3_dot(d, e2), den = d11 * d22 - d12 * d12;
        if (!(den > 0.0f)) continue;
        float u = (d22 * d1 - d12 * d2) / den, v = (d11 * d2 - d12 * d1) / den, w = 1.0f - u - v;
        float in = fminf(w, fminf(u, v));
        if (!(in > best_in)) continue;
        /* (a corner rounded just outside takes its nearest inside weights) */
        u = fmaxf(u, 0.0f);
        v = fmaxf(v, 0.0f);
        w = fmaxf(w, 0.0f);
        vec3 n = v3_add(v3_add(v3_scale(s->nrm[i[0]], w), v3_scale(s->nrm[i[1]], u)), v3_scale(s->nrm[i[2]], v));
        float l2 = v3_len2(n);
        if (!(l2 > 1e-12f) || v3_dot(n, pa->n) <= 0.0f) continue;
        best_in = in;
        best = v3_scale(n, 1.0f / sqrtf(l2));
    }
    return best;
}

int rad_mesh_build(rad_ctx *c, ct_radmesh *out, ct_error *err)
{
    const ct_scene *s = c->scene;
    int rc = CT_OK;
    u32vec leaves = {0}, bnd = {0}, boff = {0}, stack = {0};
    poshash h = {0};
    pgrid grid = {0};
    tpoint *pe = NULL;
    size_t npe = 0, cappe = 0;
    uint32_t *pe_off = NULL, *mark = NULL;
    tpoint *tmp = NULL;
    size_t captmp = 0;
    uint32_t stamp = 4 * c->npatches;   /* stamps below are the patch edges' */
    uint32_t *cnt = NULL, *byp = NULL, *bvert = NULL;
    vec3 *vsum = NULL, *vdsum = NULL, *vnrm = NULL, *vpos = NULL;
    uint32_t *vcount = NULL, *vleaf = NULL;

    /* Leaves in patch order, depth first. */
    for (uint32_t p = 0; p < c->npatches && !rc; p++) {
        stack.n = 0;
        rc = push(&stack, c->patches[p].root);
        while (!rc && stack.n) {
            uint32_t e = stack.v[--stack.n];
            const rad_elem *el = rad_el(c, e);
            if (el->child == RAD_NONE) rc = push(&leaves, e);
            else for (int i = 3; i >= 0 && !rc; i--) rc = push(&stack, el->child + (uint32_t)i);
        }
    }
    if (rc) goto oom;

    uint32_t cap = 1;
    while (cap < leaves.n * 8 + 16) cap <<= 1;
    h.slot = calloc(cap, sizeof *h.slot);
    h.mask = cap - 1;
    h.cap = (uint32_t)(leaves.n * 4 + 4);
    h.pts = malloc((size_t)h.cap * sizeof *h.pts);
    if (!h.slot || !h.pts) goto oom;
    for (size_t i = 0; i < leaves.n; i++) {
        const rad_elem *e = rad_el(c, leaves.v[i]);
        for (int k = 0; k < e->nv; k++) ph_get(&h, e->p[k], 1);
    }

    /* Points on every input patch's boundary edges (grid cells about the
     * size of a leaf). */
    float cell = grid_cell(c, &leaves);
    if (cell < 0.0f) goto oom;
    if (pgrid_build(&grid, h.pts, h.npts, cell) != 0) goto oom;
    pe_off = malloc(((size_t)c->npatches * 4 + 1) * sizeof *pe_off);
    mark = malloc(((size_t)h.npts + 1) * sizeof *mark);
    if (!pe_off || !mark) goto oom;
    for (uint32_t i = 0; i < h.npts; i++) mark[i] = UINT32_MAX;
    for (uint32_t p = 0; p < c->npatches && !rc; p++) {
        const rad_elem *r = rad_el(c, c->patches[p].root);
        for (int k = 0; k < 4 && !rc; k++) {
            pe_off[4 * (size_t)p + (size_t)k] = (uint32_t)npe;
            if (k < r->nv)
                rc = segment_points(&grid, h.pts, r->p[k], r->p[(k + 1) % r->nv], mark, 4 * p + (uint32_t)k,
                                    &pe, &npe, &cappe);
        }
    }
    if (rc) goto oom;
    pe_off[4 * (size_t)c->npatches] = (uint32_t)npe;

    /* Boundary loop of every leaf: its corners, and the vertices inside its
     * edges: from the patch edge's list on the patch boundary, else the
     * finer neighbours' midpoints. */
    for (size_t i = 0; i < leaves.n && !rc; i++) {
        const rad_elem *e = rad_el(c, leaves.v[i]);
        const rad_elem *r = rad_el(c, c->patches[e->patch].root);
        rc = push(&boff, (uint32_t)bnd.n);
        for (int k = 0; k < e->nv && !rc; k++) {
            vec3 a = e->p[k], b = e->p[(k + 1) % e->nv];
            rc = push(&bnd, ph_get(&h, a, 0));
            int done = 0;
            for (int j = 0; j < r->nv && !rc && !done; j++) {
                vec3 pa = r->p[j], pb = r->p[(j + 1) % r->nv];
                float ta = on_segment(pa, pb, a), tb = on_segment(pa, pb, b);
                if (ta < 0.0f || tb < 0.0f) continue;
                done = 1;
                uint32_t lo = pe_off[4 * (size_t)e->patch + (size_t)j], hi = pe_off[4 * (size_t)e->patch + (size_t)j + 1];
                float t0 = fminf(ta, tb), t1 = fmaxf(ta, tb);
                /* Strictly between the leaf edge's ends, in a-to-b order. */
                float eps = 1e-6f;
                if (ta <= tb) {
                    for (uint32_t q = lo; q < hi && !rc; q++)
                        if (pe[q].t > t0 + eps && pe[q].t < t1 - eps) rc = push(&bnd, pe[q].id);
                } else {
                    for (uint32_t q = hi; q-- > lo && !rc;)
                        if (pe[q].t > t0 + eps && pe[q].t < t1 - eps) rc = push(&bnd, pe[q].id);
                }
            }
            if (!done && !rc) {
                /* Inside the patch: finer neighbours' midpoints, and any
                 * other geometry's vertex touching the edge (the corner of
                 * a box standing on a floor). */
                size_t n0 = 0;
                rc = segment_points(&grid, h.pts, a, b, mark, stamp++, &tmp, &n0, &captmp);
                for (size_t q = 0; q < n0 && !rc; q++) rc = push(&bnd, tmp[q].id);
            }
        }
    }
    if (!rc) rc = push(&boff, (uint32_t)bnd.n);
    if (rc) goto oom;

    /* Incidences grouped by point (counting sort of boundary slots). */
    cnt = calloc((size_t)h.npts + 1, sizeof *cnt);
    byp = malloc((bnd.n ? bnd.n : 1) * sizeof *byp);
    bvert = malloc((bnd.n ? bnd.n : 1) * sizeof *bvert);
    if (!cnt || !byp || !bvert) goto oom;
    for (size_t i = 0; i < bnd.n; i++) cnt[bnd.v[i] + 1]++;
    for (uint32_t i = 0; i < h.npts; i++) cnt[i + 1] += cnt[i];
    {
        uint32_t *fill = malloc(((size_t)h.npts + 1) * sizeof *fill);
        if (!fill) goto oom;
        memcpy(fill, cnt, ((size_t)h.npts + 1) * sizeof *fill);
        for (size_t i = 0; i < bnd.n; i++) byp[fill[bnd.v[i]]++] = (uint32_t)i;
        free(fill);
    }
    /* The leaf of each boundary slot. */
    uint32_t *slot_leaf = malloc((bnd.n ? bnd.n : 1) * sizeof *slot_leaf);
    if (!slot_leaf) goto oom;
    for (size_t i = 0; i < leaves.n; i++)
        for (uint32_t j = boff.v[i]; j < boff.v[i + 1]; j++) slot_leaf[j] = (uint32_t)i;

    /* The scene's shading normal at each boundary slot. */
    vec3 *snrm = malloc((bnd.n ? bnd.n : 1) * sizeof *snrm);
    if (!snrm) {
        free(slot_leaf);
        goto oom;
    }
    for (size_t i = 0; i < bnd.n; i++)
        snrm[i] = rad_shade_normal(c, &c->patches[rad_el(c, leaves.v[slot_leaf[i]])->patch], h.pts[bnd.v[i]]);

    /* Vertex groups: same node and material, face normals within the
     * crease and the same shading normal (a flat-shaded mesh keeps a vertex
     * per face: its radiosity and its shading are faceted, as in path). */
    float cos_crease = cosf((float)c->prm.crease_deg * CT_PI / 180.0f);
    const float cos_shade = 0.99996f;   /* 0.5 degrees: rounding of one interpolated normal */
    size_t vcap = bnd.n + leaves.n + 1;
    vsum = calloc(vcap, sizeof *vsum);
    vdsum = calloc(vcap, sizeof *vdsum);
    vnrm = calloc(vcap, sizeof *vnrm);
    vpos = calloc(vcap, sizeof *vpos);
    vcount = calloc(vcap, sizeof *vcount);
    vleaf = calloc(vcap, sizeof *vleaf);
    if (!vsum || !vdsum || !vnrm || !vpos || !vcount || !vleaf) {
        free(slot_leaf);
        free(snrm);
        goto oom;
    }
    uint32_t nv = 0;
    for (uint32_t p = 0; p < h.npts; p++) {
        uint32_t gfirst = nv;
        for (uint32_t k = cnt[p]; k < cnt[p + 1]; k++) {
            uint32_t slot = byp[k];
            const rad_elem *e = rad_el(c, leaves.v[slot_leaf[slot]]);
            const rad_patch *pa = &c->patches[e->patch];
            uint32_t g = RAD_NONE;
            for (uint32_t q = gfirst; q < nv && g == RAD_NONE; q++) {
                const rad_elem *f = rad_el(c, leaves.v[slot_leaf[vcount[q]]]);
                const rad_patch *pb = &c->patches[f->patch];
                if (pb->node == pa->node && pb->mat == pa->mat && v3_dot(pa->n, pb->n) >= cos_crease &&
                    v3_dot(snrm[slot], snrm[vcount[q]]) >= cos_shade)
                    g = q;
            }
            if (g == RAD_NONE) {
                g = nv++;
                vcount[g] = slot;   /* temporarily: the group's first slot */
                vpos[g] = h.pts[p];
            }
            bvert[slot] = g;
        }
        /* Normals per group and a leaf of each (vcount reused once the
         * groups are known). */
        for (uint32_t q = gfirst; q < nv; q++) vcount[q] = 0;
        for (uint32_t k = cnt[p]; k < cnt[p + 1]; k++) {
            uint32_t slot = byp[k], g = bvert[slot];
            if (vcount[g] == 0) vleaf[g] = leaves.v[slot_leaf[slot]];
            vnrm[g] = v3_add(vnrm[g], snrm[slot]);
            vcount[g]++;
        }
    }
    free(slot_leaf);
    free(snrm);
    /* Each vertex gathers with the normal it is shaded with, as the
     * tracers shade the same point: with one of its faces' planes instead,
     * the Cornell box's spheres were 20-46 % dark along their terminators
     * in 8 x 8-pixel blocks (docs/radiosity.md, "Curved surfaces"). */
    for (uint32_t g = 0; g < nv; g++) vnrm[g] = v3_norm(vnrm[g]);
    rc = rad_gather_points(c, vleaf, vpos, vnrm, nv, vsum, vdsum);
    if (!rc) rc = rad_contact_vertices(c, leaves.v, leaves.n, boff.v, bvert, nv, vpos, vsum, vdsum, &c->contact_vertices);
    if (rc) goto oom;

    /* Count triangles and centre vertices, then fill the mesh. */
    uint32_t ntris = 0, ncentres = 0;
    for (size_t i = 0; i < leaves.n; i++) {
        const rad_elem *e = rad_el(c, leaves.v[i]);
        uint32_t k = boff.v[i + 1] - boff.v[i];
        if (k == e->nv) ntris += e->nv == 4 ? 2 : 1;
        else { ntris += k; ncentres++; }
    }
    rc = rmesh_alloc(out, nv + ncentres, ntris, s->nnodes, err);
    if (rc) goto done;
    const float inv_pi = 1.0f / CT_PI;
    for (uint32_t g = 0; g < nv; g++) {
        /* (a room with walls at the range's edge: a corner rounded past it,
         * and the mesh's own loader refused it) */
        out->pos[g] = v3_clamp_range(vpos[g]);
        out->nrm[g] = vnrm[g];
        out->rad[g] = v3_scale(vsum[g], inv_pi);
        out->rad_direct[g] = v3_scale(vdsum[g], inv_pi);
    }
    uint32_t t = 0, vc = nv;
    for (size_t i = 0; i < leaves.n; i++) {
        const rad_elem *e = rad_el(c, leaves.v[i]);
        const rad_patch *pa = &c->patches[e->patch];
        uint32_t b0 = boff.v[i], k = boff.v[i + 1] - b0;
        uint32_t t_first = t;
        if (k == e->nv) {
            const uint32_t *v = bvert + b0;
            uint32_t tri[2][3] = {{v[0], v[1], v[2]}, {v[0], v[2], e->nv == 4 ? v[3] : 0}};
            for (int j = 0; j < (e->nv == 4 ? 2 : 1); j++, t++) memcpy(out->tris + 3 * (size_t)t, tri[j], sizeof tri[j]);
        } else {
            /* Anchor: a fan from the centre through every boundary vertex. */
            uint32_t ce = vc++;
            vec3 r = v3s(0.0f), rd = v3s(0.0f);
            for (uint32_t j = 0; j < k; j++) {
                r = v3_add(r, out->rad[bvert[b0 + j]]);
                rd = v3_add(rd, out->rad_direct[bvert[b0 + j]]);
            }
            out->pos[ce] = v3_clamp_range(e->c);
            out->nrm[ce] = rad_shade_normal(c, pa, e->c);
            out->rad[ce] = v3_scale(r, 1.0f / (float)k);
            out->rad_direct[ce] = v3_scale(rd, 1.0f / (float)k);
            for (uint32_t j = 0; j < k; j++, t++) {
                out->tris[3 * (size_t)t] = ce;
                out->tris[3 * (size_t)t + 1] = bvert[b0 + j];
                out->tris[3 * (size_t)t + 2] = bvert[b0 + (j + 1) % k];
            }
        }
        for (uint32_t j = t_first; j < t; j++) {
            out->tri_node[j] = pa->node;
            out->tri_mat[j] = pa->mat;
        }
    }
    for (uint32_t n = 0; n < s->nnodes; n++) {
        memcpy(out->nodes[n].name, s->nodes[n].name, sizeof out->nodes[n].name);
        out->nodes[n].parent = s->nodes[n].parent;
        out->nodes[n].node_end = s->nodes[n].node_end;
        out->nodes[n].material = s->nodes[n].material;
        out->nodes[n].bounds = s->nodes[n].bounds;
    }
    rc = rmesh_set_materials(out, s, err);
    if (rc) rmesh_free(out);
    goto done;
oom:
    rc = ct_fail(err, CT_ENOMEM, "radiosity: out of memory while meshing %zu leaves", leaves.n);
done:
    pgrid_free(&grid);
    free(pe);
    free(pe_off);
    free(mark);
    free(tmp);
    free(leaves.v);
    free(bnd.v);
    free(boff.v);
    free(stack.v);
    free(h.slot);
    free(h.pts);
    free(cnt);
    free(byp);
    free(bvert);
    free(vsum);
    free(vdsum);
    free(vleaf);
    free(vnrm);
    free(vpos);
    free(vcount);
    return rc;
}
