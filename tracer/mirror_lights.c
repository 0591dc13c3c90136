/* mirror_lights.c: plane mirrors as virtual lights (mirror_lights.h). */
#include "tracer/mirror_lights.h"

#include <stdlib.h>
#include <string.h>

struct mlight_set {
    uint32_t n;
    mlight_plane m[MLIGHT_MAX];
};

/* A mirror plane while it is collected. */
typedef struct plane_acc {
    mlight_plane p;
    vec3 csum;          /* area-weighted sum of triangle centres */
    uint32_t order;     /* creation order (ties of area) */
} plane_acc;

typedef struct mtri {
    uint32_t node, mat, t;
} mtri;

static int cmp_mtri(const void *a, const void *b)
{
    const mtri *x = a, *y = b;
    if (x->node != y->node) return x->node < y->node ? -1 : 1;
    if (x->mat != y->mat) return x->mat < y->mat ? -1 : 1;
    return x->t < y->t ? -1 : x->t > y->t;
}

static int cmp_area(const void *a, const void *b)
{
    const plane_acc *x = a, *y = b;
    if (x->p.area != y->p.area) return x->p.area > y->p.area ? -1 : 1;
    return x->order < y->order ? -1 : x->order > y->order;
}

/* Whether triangle t lies in plane p (normal either way). */
static bool in_plane(const emb_mesh *m, uint32_t t, vec3 nt, const mlight_plane *p)
{
    float c = v3_dot(nt, p->n);
    if (!(c > 1.0f - 1e-5f || c < -(1.0f - 1e-5f))) return false;
    float tol = 1e-4f * (1.0f + fabsf(p->d));
    for (int k = 0; k < 3; k++)
        if (fabsf(mlight_side(p, m->pos[m->tris[3 * (size_t)t + k]])) > tol) return false;
    return true;
}

static void plane_start(const emb_mesh *m, uint32_t t, vec3 nt, uint32_t order, plane_acc *a)
{
    memset(a, 0, sizeof *a);
    a->order = order;
    mlight_plane *p = &a->p;
    p->n = nt;
    p->d = v3_dot(nt, m->pos[m->tris[3 * (size_t)t]]);
    /* An axis away from n: the one of n's smallest component. */
    vec3 ax = fabsf(nt.x) <= fabsf(nt.y) && fabsf(nt.x) <= fabsf(nt.z) ? v3(1, 0, 0)
              : fabsf(nt.y) <= fabsf(nt.z)                          ? v3(0, 1, 0)
                                                                    : v3(0, 0, 1);
    p->u = v3_norm(v3_cross(nt, ax));
    p->v = v3_cross(nt, p->u);
    p->u0 = p->v0 = INFINITY;
    p->u1 = p->v1 = -INFINITY;
    p->mat = m->tri_mat[t];
    p->rho = m->mats[p->mat].mirror;
}

static void plane_add(const emb_mesh *m, uint32_t t, plane_acc *a)
{
    mlight_plane *p = &a->p;
    vec3 c = v3s(0.0f);
    for (int k = 0; k < 3; k++) {
        vec3 q = m->pos[m->tris[3 * (size_t)t + k]];
        float x = v3_dot(p->u, q), y = v3_dot(p->v, q);
        p->u0 = fminf(p->u0, x);
        p->u1 = fmaxf(p->u1, x);
        p->v0 = fminf(p->v0, y);
        p->v1 = fmaxf(p->v1, y);
        c = v3_add(c, q);
    }
    float area = emb_tri_area(m, t);
    p->area += area;
    a->csum = v3_add(a->csum, v3_scale(c, area / 3.0f));
}

/* The planes of the mirror triangles tris[0..n) of one node and material
 * appended to out (capacity enough for MLIGHT_NODE_PLANES more); none when
 * they span more planes than that. */
static uint32_t node_planes(const emb_mesh *m, const mtri *tris, size_t n, plane_acc *out, uint32_t order0)
{
    uint32_t np = 0;
    for (size_t i = 0; i < n; i++) {
        uint32_t t = tris[i].t;
        vec3 nt = emb_tri_normal(m, t);
        uint32_t k = 0;
        while (k < np && !in_plane(m, t, nt, &out[k].p)) k++;
        if (k == np) {
            if (np == MLIGHT_NODE_PLANES) return 0;
            plane_start(m, t, nt, order0 + np, &out[np]);
            np++;
        }
        plane_add(m, t, &out[k]);
    }
    return np;
}

static bool mirror_tri(const emb_mesh *m, uint32_t t)
{
    return mlight_material(&m->mats[m->tri_mat[t]]) && emb_tri_area(m, t) > 0.0f;
}

int mlight_build(const emb_scene *e, const light_set *lights, mlight_set **out, ct_error *err)
{
    *out = NULL;
    const emb_mesh *m = emb_get_mesh(e);
    mlight_set *s = calloc(1, sizeof *s);
    size_t nt = 0;
    for (uint32_t t = 0; t < m->ntris; t++) {
        if (mirror_tri(m, t)) nt++;
    }
    mtri *tris = malloc((nt ? nt : 1) * sizeof *tris);
    plane_acc *acc = NULL;
    size_t nacc = 0, cap = 0;
    if (!s || !tris) goto oom;
    nt = 0;
    for (uint32_t t = 0; t < m->ntris; t++) {
        if (mirror_tri(m, t)) tris[nt++] = (mtri){m->tri_node[t], m->tri_mat[t], t};
    }
    qsort(tris, nt, sizeof *tris, cmp_mtri);
    for (size_t i = 0; i < nt;) {
        size_t j = i;
        while (j < nt && tris[j].node == tris[i].node && tris[j].mat == tris[i].mat) j++;
        if (nacc + MLIGHT_NODE_PLANES > cap) {
            cap = 2 * cap + MLIGHT_NODE_PLANES;
            plane_acc *grown = realloc(acc, cap * sizeof *acc);
            if (!grown) goto oom;
            acc = grown;
        }
        nacc += node_planes(m, tris + i, j - i, acc + nacc, (uint32_t)nacc);
        i = j;
    }
    if (nacc > 1) qsort(acc, nacc, sizeof *acc, cmp_area);
    s->n = nacc < MLIGHT_MAX ? (uint32_t)nacc : MLIGHT_MAX;
    for (uint32_t i = 0; i < s->n; i++) {
        mlight_plane *p = &s->m[i];
        *p = acc[i].p;
        /* Grown so that a crossing on the mirror's edge is not lost to
         * rounding (the ray decides). */
        float g = 1e-4f * (1.0f + fmaxf(p->u1 - p->u0, p->v1 - p->v0) + fabsf(p->d));
        p->u0 -= g, p->v0 -= g, p->u1 += g, p->v1 += g;
        p->c = v3_scale(acc[i].csum, 1.0f / p->area);
        p->r2 = p->area / 3.14159265f;
        light_select(lights, p->c, p->n, &p->sel[0]);
        light_select(lights, p->c, v3_neg(p->n), &p->sel[1]);
    }
    free(tris);
    free(acc);
    *out = s;
    return CT_OK;
oom:
    free(tris);
    free(acc);
    free(s);
    return ct_fail(err, CT_ENOMEM, "out of memory for the mirror list");
}

void mlight_free(mlight_set *s) { free(s); }

uint32_t mlight_count(const mlight_set *s) { return s ? s->n : 0; }

const mlight_plane *mlight_get(const mlight_set *s, uint32_t i) { return &s->m[i]; }

float mlight_cdf(const mlight_set *s, vec3 x, float *cdf)
{
    float total = 0.0f;
    for (uint32_t i = 0; i < s->n; i++) {
        total += mlight_weight(&s->m[i], x);
        cdf[i] = total;
    }
    return total > 0.0f && total < INFINITY ? total : 0.0f;
}

bool mlight_pick(const mlight_set *s, const light_set *lights, const float *cdf, float total, vec3 x, vec3 o,
                 float um, float u0, float u1, float u2, mlight_path *out)
{
    float t = um * total;
    uint32_t i = 0;
    while (i + 1 < s->n && !(t < cdf[i])) i++;
    const mlight_plane *m = &s->m[i];
    float pm = (cdf[i] - (i ? cdf[i - 1] : 0.0f)) / total;
    if (!(pm > 0.0f)) return false;
    float sx = mlight_side(m, x);
    int side = sx > 0.0f ? 0 : 1;
    light_point lp;
    if (!light_sample(lights, &m->sel[side], u0, u1, u2, &lp)) return false;
    float sy = mlight_side(m, lp.p);
    if (!(sy * sx > 0.0f)) return false;   /* a lamp behind the mirror */
    vec3 img = v3_sub(lp.p, v3_scale(m->n, 2.0f * sy));
    vec3 img_n = v3_sub(lp.n, v3_scale(m->n, 2.0f * v3_dot(lp.n, m->n)));
    vec3 wi = v3_sub(img, x);
    float d2 = v3_len2(wi);
    if (!(d2 > 0.0f)) return false;
    wi = v3_scale(wi, 1.0f / sqrtf(d2));
    float cos_l = -v3_dot(wi, img_n);
    if (!(cos_l > 0.0f)) return false;
    float pdf = pm * lp.pdf_area * d2 / cos_l;
    if (!(pdf > 0.0f && pdf < INFINITY)) return false;
    float tm = -mlight_side(m, o) / v3_dot(m->n, wi);
    if (!(tm > 0.0f && tm < INFINITY) || !mlight_in_bounds(m, v3_madd(o, wi, tm))) return false;
    out->m = m;
    out->n_side = side == 0 ? m->n : v3_neg(m->n);
    out->lp = lp;
    out->wi = wi;
    out->pdf = pdf;
    out->tm = tm;
    return true;
}

bool mlight_to_mirror(const emb_scene *e, const mlight_path *mp, vec3 o, mlight_leg *leg)
{
    emb_hit h;
    if (!emb_intersect(e, o, mp->wi, 0.0f, mp->tm * (1.0f + 2e-4f) + 2e-4f, &h) || !mlight_is_mirror_hit(mp->m, &h, mp->tm))
        return false;
    leg->o = emb_offset_ray(emb_hit_point(&h), mp->n_side);
    leg->target = emb_offset_ray(mp->lp.p, mp->lp.n);
    vec3 d = v3_sub(leg->target, leg->o);
    leg->dist = v3_len(d);
    if (!(leg->dist > 0.0f)) return false;
    leg->d = v3_scale(d, 1.0f / leg->dist);
    return true;
}

vec3 mlight_irradiance(const mlight_set *s, const emb_scene *e, const light_set *lights, vec3 x, vec3 nx, vec3 o,
                       int n, ct_rng *rng)
{
    float cdf[MLIGHT_MAX];
    float total = mlight_cdf(s, x, cdf);
    vec3 sum = v3s(0.0f);
    if (!(total > 0.0f) || n <= 0) return sum;
    for (int k = 0; k < n; k++) {
        float u[4];
        for (int j = 0; j < 4; j++) u[j] = rng_float(rng);   /* (an initializer list's order is unspecified) */
        mlight_path mp;
        if (!mlight_pick(s, lights, cdf, total, x, o, u[0], u[1], u[2], u[3], &mp)) continue;
        float cos_x = v3_dot(mp.wi, nx);
        if (!(cos_x > 0.0f)) continue;
        mlight_leg leg;
        if (!mlight_to_mirror(e, &mp, o, &leg) || emb_occluded(e, leg.o, leg.d, 0.0f, leg.dist)) continue;
        sum = v3_add(sum, v3_scale(v3_mul(mp.m->rho, mp.lp.le), cos_x / mp.pdf));
    }
    sum = v3_scale(sum, 1.0f / (float)n);
    return v3_finite(sum) ? sum : v3s(0.0f);
}
