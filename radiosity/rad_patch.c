/* rad_patch.c: input patches from the scene's triangles (quads rebuilt from
 * the two triangles of one input polygon), element storage and 4-way
 * subdivision, and the source-cluster BVH over the input patches. */
#include "radiosity/rad_internal.h"

#include <stdlib.h>
#include <string.h>

#include "common/rng.h"

int rad_track(rad_ctx *c, int64_t delta)
{
    uint64_t now = atomic_fetch_add(&c->bytes, (uint64_t)delta) + (uint64_t)delta;
    uint64_t peak = atomic_load(&c->peak);
    while (now > peak && !atomic_compare_exchange_weak(&c->peak, &peak, now)) {
    }
    if (delta > 0 && c->cap_bytes && now > c->cap_bytes) {
        atomic_store(&c->over_cap, 1);
        return -1;
    }
    return 0;
}

uint32_t rad_alloc_elems(rad_ctx *c, uint32_t n)
{
    pthread_mutex_lock(&c->alloc_lock);
    uint32_t first = c->nelems;
    /* Keep a group inside one chunk so children are addressable as a run. */
    uint32_t room = RAD_CHUNK - (first & (RAD_CHUNK - 1));
    if (room < n) first += room;
    uint32_t last = first + n - 1;
    uint32_t ch = last >> RAD_CHUNK_SHIFT;
    if (ch >= RAD_MAX_CHUNKS) {
        pthread_mutex_unlock(&c->alloc_lock);
        return RAD_NONE;
    }
    if (!c->chunks[ch]) {
        if (rad_track(c, (int64_t)RAD_CHUNK * (int64_t)(sizeof(rad_elem) + 2 * sizeof(vec3))) != 0) {
            pthread_mutex_unlock(&c->alloc_lock);
            return RAD_NONE;
        }
        c->chunks[ch] = calloc(RAD_CHUNK, sizeof(rad_elem));
        c->bchunks[0][ch] = calloc(RAD_CHUNK, sizeof(vec3));
        c->bchunks[1][ch] = calloc(RAD_CHUNK, sizeof(vec3));
        if (!c->chunks[ch] || !c->bchunks[0][ch] || !c->bchunks[1][ch]) {
            pthread_mutex_unlock(&c->alloc_lock);
            return RAD_NONE;
        }
    }
    c->nelems = last + 1;
    pthread_mutex_unlock(&c->alloc_lock);
    return first;
}

static float tri_area(vec3 a, vec3 b, vec3 c)
{
    return 0.5f * v3_len(v3_cross(v3_sub(b, a), v3_sub(c, a)));
}

/* Area, centroid and radius of an element from its corners. */
static void elem_geometry(rad_elem *e)
{
    if (e->nv == 3) {
        e->area = tri_area(e->p[0], e->p[1], e->p[2]);
        e->c = v3_scale(v3_add(v3_add(e->p[0], e->p[1]), e->p[2]), 1.0f / 3.0f);
    } else {
        float a1 = tri_area(e->p[0], e->p[1], e->p[2]);
        float a2 = tri_area(e->p[0], e->p[2], e->p[3]);
        vec3 c1 = v3_scale(v3_add(v3_add(e->p[0], e->p[1]), e->p[2]), 1.0f / 3.0f);
        vec3 c2 = v3_scale(v3_add(v3_add(e->p[0], e->p[2]), e->p[3]), 1.0f / 3.0f);
        e->area = a1 + a2;
        e->c = e->area > 0.0f ? v3_scale(v3_add(v3_scale(c1, a1), v3_scale(c2, a2)), 1.0f / e->area)
                              : c1;
    }
    float r = 0.0f;
    for (int i = 0; i < e->nv; i++) r = fmaxf(r, v3_len(v3_sub(e->p[i], e->c)));
    e->radius = r;
}

vec3 rad_elem_point(const rad_elem *e, float u, float v)
{
    if (e->nv == 4) {
        vec3 a = v3_lerp(e->p[0], e->p[1], u), b = v3_lerp(e->p[3], e->p[2], u);
        return v3_lerp(a, b, v);
    }
    if (u + v > 1.0f) { u = 1.0f - u; v = 1.0f - v; }
    return v3_add(e->p[0], v3_add(v3_scale(v3_sub(e->p[1], e->p[0]), u),
                                  v3_scale(v3_sub(e->p[2], e->p[0]), v)));
}

/* Midpoints are computed the same way from both sides of a shared edge
 * ((a + b) * 0.5 is symmetric in IEEE arithmetic), so neighbouring patches
 * produce bit-identical vertices: rad_mesh.c welds on exact positions. */
static vec3 mid(vec3 a, vec3 b) { return v3_scale(v3_add(a, b), 0.5f); }

int rad_subdivide(rad_ctx *c, uint32_t ei)
{
    rad_elem *e = rad_el(c, ei);
    if (e->child != RAD_NONE) return 0;
    uint32_t first = rad_alloc_elems(c, 4);
    if (first == RAD_NONE) return CT_ENOMEM;
    e = rad_el(c, ei);
    vec3 q[4][4];
    if (e->nv == 4) {
        vec3 m01 = mid(e->p[0], e->p[1]), m12 = mid(e->p[1], e->p[2]);
        vec3 m23 = mid(e->p[2], e->p[3]), m30 = mid(e->p[3], e->p[0]);
        vec3 ce = v3_scale(v3_add(v3_add(e->p[0], e->p[2]), v3_add(e->p[1], e->p[3])), 0.25f);
        vec3 a[4][4] = {{e->p[0], m01, ce, m30}, {m01, e->p[1], m12, ce},
                        {ce, m12, e->p[2], m23}, {m30, ce, m23, e->p[3]}};
        memcpy(q, a, sizeof q);
    } else {
        vec3 m01 = mid(e->p[0], e->p[1]), m12 = mid(e->p[1], e->p[2]), m20 = mid(e->p[2], e->p[0]);
        vec3 a[4][4] = {{e->p[0], m01, m20, m20}, {m01, e->p[1], m12, m12},
                        {m20, m12, e->p[2], e->p[2]}, {m12, m20, m01, m01}};
        memcpy(q, a, sizeof q);
    }
    for (uint32_t i = 0; i < 4; i++) {
        rad_elem *k = rad_el(c, first + i);
        memset(k, 0, sizeof *k);
        memcpy(k->p, q[i], sizeof k->p);
        k->nv = e->nv;
        k->depth = (uint8_t)(e->depth + 1);
        k->patch = e->patch;
        k->child = k->child_pub = RAD_NONE;
        k->parent = ei;
        k->key = ct_hash64(e->key * 4u + i + 1u);
        *rad_B(c, 0, first + i) = *rad_B(c, 0, ei);
        *rad_B(c, 1, first + i) = *rad_B(c, 1, ei);
        k->Bd = e->Bd;
        elem_geometry(k);
        k->exposed = rad_exposure(c, k);
    }
    /* The children's 4 x 9 points tell the parent's exposure better than
     * its own 9. */
    e->exposed = 0.25f * (rad_el(c, first)->exposed + rad_el(c, first + 1)->exposed +
                          rad_el(c, first + 2)->exposed + rad_el(c, first + 3)->exposed);
    /* Publish the children only after they are complete. */
    e->child = first;
    atomic_fetch_add(&c->est_tris, rad_split_tris(e));
    return 0;
}

/* Is the quad a-b-c-d (two fan triangles a-b-c, a-c-d) planar and convex
 * enough to be one patch? */
static int good_quad(vec3 a, vec3 b, vec3 c, vec3 d)
{
    vec3 n1 = v3_norm(v3_cross(v3_sub(b, a), v3_sub(c, a)));
    vec3 n2 = v3_norm(v3_cross(v3_sub(c, a), v3_sub(d, a)));
    if (v3_dot(n1, n2) < 0.9995f) return 0;
    vec3 p[4] = {a, b, c, d};
    for (int i = 0; i < 4; i++) {
        vec3 e1 = v3_sub(p[(i + 1) & 3], p[i]), e2 = v3_sub(p[(i + 2) & 3], p[(i + 1) & 3]);
        if (v3_dot(v3_cross(e1, e2), n1) <= 0.0f) return 0;
    }
    return 1;
}

static const rad_ctx *g_sort_ctx;
static int g_sort_axis;

static float patch_centroid_axis(const rad_ctx *c, uint32_t p, int axis)
{
    return v3_get(rad_el(c, c->patches[p].root)->c, axis);
}

static int cmp_axis(const void *a, const void *b)
{
    float x = patch_centroid_axis(g_sort_ctx, *(const uint32_t *)a, g_sort_axis);
    float y = patch_centroid_axis(g_sort_ctx, *(const uint32_t *)b, g_sort_axis);
    if (x < y) return -1;
    if (x > y) return 1;
    uint32_t i = *(const uint32_t *)a, j = *(const uint32_t *)b;
    return i < j ? -1 : i > j;
}

/* Builds the cluster over order[b, e) and returns its reference. */
static uint32_t build_cluster(rad_ctx *c, uint32_t b, uint32_t e)
{
    if (e - b == 1) return c->patches[c->order[b]].root;
    uint32_t id = c->nclusters++;
    rad_cluster *k = &c->clusters[id];
    memset(k, 0, sizeof *k);
    k->pbegin = b;
    k->pend = e;
    bounds3 cb = b3_empty(), bb = b3_empty();
    float area = 0.0f;
    vec3 E = v3s(0.0f);
    for (uint32_t i = b; i < e; i++) {
        const rad_patch *p = &c->patches[c->order[i]];
        const rad_elem *r = rad_el(c, p->root);
        cb = b3_add(cb, r->c);
        for (int j = 0; j < r->nv; j++) bb = b3_add(bb, r->p[j]);
        area += r->area;
        k->N = v3_madd(k->N, p->n, r->area);
        E = v3_madd(E, p->E, r->area);
        if (v3_maxc(p->E) > 0.0f) k->has_emitter = 1;
    }
    k->b = bb;
    k->c = b3_center(bb);
    k->radius = 0.5f * v3_len(b3_extent(bb));
    k->area = area;
    k->E = area > 0.0f ? v3_scale(E, 1.0f / area) : v3s(0.0f);
    vec3 ext = b3_extent(cb);
    g_sort_ctx = c;
    g_sort_axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    qsort(c->order + b, e - b, sizeof *c->order, cmp_axis);
    uint32_t m = b + (e - b) / 2;
    uint32_t l = build_cluster(c, b, m);
    uint32_t r = build_cluster(c, m, e);
    c->clusters[id].child[0] = l;
    c->clusters[id].child[1] = r;
    return id | RAD_CLUSTER_BIT;
}

int rad_build_patches(rad_ctx *c, ct_error *err)
{
    const ct_scene *s = c->scene;
    c->patches = calloc(s->ntris ? s->ntris : 1, sizeof *c->patches);
    c->chunks = calloc(RAD_MAX_CHUNKS, sizeof *c->chunks);
    c->bchunks[0] = calloc(RAD_MAX_CHUNKS, sizeof *c->bchunks[0]);
    c->bchunks[1] = calloc(RAD_MAX_CHUNKS, sizeof *c->bchunks[1]);
    if (!c->patches || !c->chunks || !c->bchunks[0] || !c->bchunks[1]) return ct_fail(err, CT_ENOMEM, "radiosity: out of memory for %u patches", s->ntris);
    rad_track(c, (int64_t)s->ntris * (int64_t)sizeof *c->patches);
    c->total_area = 0.0;
    c->emitted = 0.0;
    for (uint32_t t = 0; t < s->ntris;) {
        const uint32_t *i0 = s->tris + 3 * (size_t)t;
        vec3 v[4] = {s->pos[i0[0]], s->pos[i0[1]], s->pos[i0[2]], s->pos[i0[2]]};
        int nv = 3, used = 1;
        if (t + 1 < s->ntris && s->tri_prim[t + 1] == s->tri_prim[t]) {
            const uint32_t *i1 = i0 + 3;
            /* scene_add_polygon fans a quad as (0,1,2), (0,2,3). */
            if (i1[0] == i0[0] && i1[1] == i0[2] &&
                (t + 2 >= s->ntris || s->tri_prim[t + 2] != s->tri_prim[t]) &&
                good_quad(v[0], v[1], v[2], s->pos[i1[2]])) {
                v[3] = s->pos[i1[2]];
                nv = 4;
                used = 2;
            }
        }
        vec3 fn = v3_norm(v3_cross(v3_sub(v[1], v[0]), v3_sub(v[2], v[0])));
        vec3 vn = v3s(0.0f);
        for (int k = 0; k < used; k++)
            for (int j = 0; j < 3; j++) vn = v3_add(vn, s->nrm[s->tris[3 * (size_t)(t + (uint32_t)k) + (uint32_t)j]]);
        /* The front side is the winding's, unless the shading normals all
         * say otherwise (then the corners are reversed to stay CCW). */
        if (v3_dot(fn, vn) < 0.0f) {
            fn = v3_neg(fn);
            vec3 tmp = v[1];
            v[1] = v[nv - 1];
            v[nv - 1] = tmp;
            if (nv == 3) v[3] = v[2];
        }
        uint32_t pi = c->npatches++;
        rad_patch *p = &c->patches[pi];
        const scene_material *m = &s->mats[s->tri_mat[t]];
        p->n = fn;
        /* Reflectance below 1 so the iteration converges (and energy is
         * never created). The solution shows the diffuse layer alone, but
         * passes on what the glossy and mirror layers reflect too, spread
         * as if diffuse: without it a glossy table top and a wall mirror
         * absorbed their light, and every surface lit by way of them was
         * 2-5 % dark (docs/radiosity.md, Materials). Glass passes light
         * through its links' visibility instead. */
        p->rho = v3_min(v3_max(m->diffuse, v3s(0.0f)), v3s(0.99f));
        vec3 spec = v3s(0.0f);
        if (!m->dielectric) {
            if (m->glossy != SCENE_GLOSSY_NONE) spec = v3_max(m->specular, v3s(0.0f));
            spec = v3_add(spec, v3_max(m->mirror, v3s(0.0f)));
        }
        p->rho_t = v3_min(v3_add(p->rho, spec), v3s(0.99f));
        /* Glass passes on what its faces reflect, each link's light weighed
         * by the pane's reflectance at its angle (rad_elem_links): before,
         * that light was lost, about 2.5 % of the office building's power
         * (docs/radiosity.md, "Glass"). Its own diffuse layer is left to
         * the corrections, as the display leaves it. */
        p->ior = m->dielectric && m->ior > 0.0f ? m->ior : 0.0f;
        if (p->ior > 0.0f) p->rho_t = v3s(0.99f);
        p->rho_ml = v3s(0.0f);
        p->E = v3_scale(v3_max(m->emission, v3s(0.0f)), CT_PI);
        p->node = s->tri_node[t];
        p->mat = s->tri_mat[t];
        p->tri = t;
        p->open = 1.0f;
        p->curved = 0;
        for (int k = 0; k < used; k++)
            for (int j = 0; j < 3; j++) {
                vec3 sn = s->nrm[s->tris[3 * (size_t)(t + (uint32_t)k) + (uint32_t)j]];
                float l2 = v3_len2(sn);
                if (l2 > 0.0f && v3_dot(sn, fn) < 0.99985f * sqrtf(l2)) p->curved = 1;
            }
        uint32_t ei = rad_alloc_elems(c, 1);
        if (ei == RAD_NONE) return ct_fail(err, CT_ENOMEM, "radiosity: memory cap reached while creating patches");
        rad_elem *e = rad_el(c, ei);
        memset(e, 0, sizeof *e);
        memcpy(e->p, v, sizeof e->p);
        e->nv = (uint8_t)nv;
        e->patch = pi;
        e->child = e->child_pub = RAD_NONE;
        e->parent = RAD_NONE;
        e->key = ct_hash64((uint64_t)pi + 0x51ed27ULL);
        e->Bd = p->E;
        *rad_B(c, 0, ei) = *rad_B(c, 1, ei) = p->E;
        e->exposed = 1.0f;   /* (rad_solve measures it once the visibility scene exists) */
        elem_geometry(e);
        p->root = ei;
        c->total_area += e->area;
        c->emitted += (double)v3_avg(p->E) * e->area;
        atomic_fetch_add(&c->est_tris, nv == 4 ? 2u : 1u);
        t += (uint32_t)used;
    }
    c->order = malloc((size_t)c->npatches * sizeof *c->order);
    c->clusters = calloc(c->npatches ? c->npatches : 1, sizeof *c->clusters);
    if (!c->order || !c->clusters) return ct_fail(err, CT_ENOMEM, "radiosity: out of memory for clusters");
    rad_track(c, (int64_t)c->npatches * (int64_t)(sizeof *c->order + sizeof *c->clusters));
    for (uint32_t i = 0; i < c->npatches; i++) c->order[i] = i;
    c->nclusters = 0;
    if (c->npatches > 1) build_cluster(c, 0, c->npatches);
    c->sgeo = aligned_alloc(64, ((size_t)c->npatches * sizeof *c->sgeo + 63) / 64 * 64);
    if (!c->sgeo) return ct_fail(err, CT_ENOMEM, "radiosity: out of memory for clusters");
    c->sarea = malloc(((size_t)c->npatches + 1) * sizeof *c->sarea);
    c->spow = malloc(((size_t)c->npatches + 1) * sizeof *c->spow);
    if (!c->sarea || !c->spow) return ct_fail(err, CT_ENOMEM, "radiosity: out of memory for clusters");
    rad_track(c, (int64_t)c->npatches * (int64_t)(sizeof *c->sgeo + sizeof *c->sarea + sizeof *c->spow));
    c->sarea[0] = c->spow[0] = 0.0;
    for (uint32_t i = 0; i < c->npatches; i++) {
        const rad_patch *p = &c->patches[c->order[i]];
        const rad_elem *e = rad_el(c, p->root);
        memcpy(c->sgeo[i].p, e->p, sizeof e->p);
        c->sgeo[i].n = p->n;
        c->sgeo[i].nv = e->nv;
        c->sarea[i + 1] = c->sarea[i] + e->area;
    }
    return CT_OK;
}

void rad_free_patches(rad_ctx *c)
{
    if (c->patches)
        for (uint32_t i = 0; i < c->npatches; i++) free(c->patches[i].links);
    free(c->patches);
    free(c->clusters);
    free(c->order);
    free(c->sgeo);
    free(c->sarea);
    free(c->spow);
    c->sgeo = NULL;
    c->sarea = NULL;
    c->spow = NULL;
    for (uint32_t i = 0; i < RAD_MAX_CHUNKS; i++) {
        if (c->chunks) free(c->chunks[i]);
        if (c->bchunks[0]) free(c->bchunks[0][i]);
        if (c->bchunks[1]) free(c->bchunks[1][i]);
    }
    free(c->chunks);
    free(c->bchunks[0]);
    free(c->bchunks[1]);
    c->bchunks[0] = c->bchunks[1] = NULL;
    c->patches = NULL;
    c->clusters = NULL;
    c->order = NULL;
    c->chunks = NULL;
}
