#include "tracer/lights.h"

#include <stdlib.h>
#include <string.h>

/* Largest guide table (cells); a power of two so that u * cells is exact. */
#define MAX_GUIDE (1u << 16)

/* Everything light_sample returns for one emissive triangle, in one record. */
typedef struct light_tri {
    vec3 p0, e1, e2;    /* vertex 0, edges 1 - 0 and 2 - 0 */
    vec3 n;             /* unit front normal */
    vec3 le;            /* L_e */
    float pdf_area;     /* selection probability / area */
    uint32_t tri;       /* mesh triangle */
} light_tri;

struct light_set {
    const emb_mesh *mesh;
    uint32_t n;
    light_tri *lt;      /* the emissive triangles */
    float *cdf;         /* n + 1 entries, cdf[n] = 1 */
    uint32_t nguide;    /* guide cells (a power of two) */
    uint32_t *guide;    /* nguide + 1 entries: the pick for u = g / nguide */
    float *pdf_area;    /* per mesh triangle: selection probability / area */
};

/* First index i in [lo, hi] whose cdf[i + 1] > u (hi when none). */
static inline uint32_t search(const float *cdf, uint32_t lo, uint32_t hi, float u)
{
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (cdf[mid + 1] > u) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

int light_build(const emb_mesh *m, light_set **out, ct_error *err)
{
    *out = NULL;
    light_set *l = calloc(1, sizeof *l);
    if (!l) return ct_fail(err, CT_ENOMEM, "out of memory");
    l->mesh = m;
    l->pdf_area = calloc(m->ntris ? m->ntris : 1, sizeof *l->pdf_area);
    if (!l->pdf_area) goto oom;
    for (uint32_t t = 0; t < m->ntris; t++) {
        vec3 le = m->mats[m->tri_mat[t]].emission;
        if (v3_luminance(le) > 0.0f && emb_tri_area(m, t) > 0.0f) l->n++;
    }
    l->nguide = 1;
    while (l->nguide < l->n && l->nguide < MAX_GUIDE) l->nguide *= 2;
    l->lt = malloc((l->n ? l->n : 1) * sizeof *l->lt);
    l->cdf = malloc(((size_t)l->n + 1) * sizeof *l->cdf);
    l->guide = malloc(((size_t)l->nguide + 1) * sizeof *l->guide);
    if (!l->lt || !l->cdf || !l->guide) goto oom;
    /* Cumulative power in double: thousands of small radiosity triangles
     * would lose precision summed in float. */
    double total = 0.0;
    uint32_t k = 0;
    l->cdf[0] = 0.0f;
    double *acc = malloc(((size_t)l->n + 1) * sizeof *acc);
    if (!acc) goto oom;
    acc[0] = 0.0;
    for (uint32_t t = 0; t < m->ntris; t++) {
        vec3 le = m->mats[m->tri_mat[t]].emission;
        float a = emb_tri_area(m, t);
        if (!(v3_luminance(le) > 0.0f && a > 0.0f)) continue;
        light_tri *r = &l->lt[k];
        const uint32_t *vi = m->tris + 3 * (size_t)t;
        r->tri = t;
        r->n = emb_tri_normal(m, t);
        r->p0 = m->pos[vi[0]];
        r->e1 = v3_sub(m->pos[vi[1]], m->pos[vi[0]]);
        r->e2 = v3_sub(m->pos[vi[2]], m->pos[vi[0]]);
        r->le = le;
        total += (double)a * v3_luminance(le);
        acc[++k] = total;
    }
    for (uint32_t i = 0; i < l->n; i++) {
        l->cdf[i + 1] = (float)(acc[i + 1] / total);
        uint32_t t = l->lt[i].tri;
        l->pdf_area[t] = (float)(v3_luminance(m->mats[m->tri_mat[t]].emission) / total);
        l->lt[i].pdf_area = l->pdf_area[t];
    }
    if (l->n) l->cdf[l->n] = 1.0f;
    free(acc);
    /* Guide table (Chen's cutpoint method): the pick for any u in cell g,
     * [g / G, (g + 1) / G), lies between the picks at the cell's two ends
     * (the search is monotone in u, and u * G is exact for G a power of two),
     * so light_sample searches only that range and returns exactly what a
     * search of the whole CDF would. */
    for (uint32_t g = 0; g <= l->nguide; g++)
        l->guide[g] = l->n ? search(l->cdf, 0, l->n - 1, (float)g / (float)l->nguide) : 0;
    *out = l;
    return CT_OK;
oom:
    light_free(l);
    return ct_fail(err, CT_ENOMEM, "out of memory for the light list");
}

void light_free(light_set *l)
{
    if (!l) return;
    free(l->lt);
    free(l->cdf);
    free(l->guide);
    free(l->pdf_area);
    free(l);
}

uint32_t light_count(const light_set *l) { return l->n; }

uint32_t light_pick(const light_set *l, float u0)
{
    if (l->n == 0) return 0;
    uint32_t g = (uint32_t)(u0 * (float)l->nguide);
    if (g >= l->nguide) g = l->nguide - 1;
    return search(l->cdf, l->guide[g], l->guide[g + 1], u0);
}

uint32_t light_pick_tri(const light_set *l, uint32_t i) { return i < l->n ? l->lt[i].tri : UINT32_MAX; }

bool light_sample(const light_set *l, float u0, float u1, float u2, light_point *out)
{
    if (l->n == 0) return false;
    const light_tri *r = &l->lt[light_pick(l, u0)];
    float su = sqrtf(u1);
    float b1 = 1.0f - su, b2 = u2 * su;   /* uniform by area */
    out->tri = r->tri;
    out->p = v3_add(r->p0, v3_add(v3_scale(r->e1, b1), v3_scale(r->e2, b2)));
    out->n = r->n;
    out->le = r->le;
    out->pdf_area = r->pdf_area;
    return true;
}

float light_pdf_area(const light_set *l, uint32_t tri)
{
    return tri < l->mesh->ntris ? l->pdf_area[tri] : 0.0f;
}
