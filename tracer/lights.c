#include "tracer/lights.h"

#include <stdlib.h>
#include <string.h>

struct light_set {
    const emb_mesh *mesh;
    uint32_t n;
    uint32_t *tri;      /* emissive triangles */
    vec3 *nrm;          /* their unit front normals */
    vec3 *geo;          /* per light: vertex 0, edge 1 - 0, edge 2 - 0, L_e (no index lookups) */
    float *cdf;         /* n + 1 entries, cdf[n] = 1 */
    float *pdf_area;    /* per mesh triangle: selection probability / area */
};

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
    l->tri = malloc((l->n ? l->n : 1) * sizeof *l->tri);
    l->cdf = malloc(((size_t)l->n + 1) * sizeof *l->cdf);
    l->nrm = malloc((l->n ? l->n : 1) * sizeof *l->nrm);
    l->geo = malloc((l->n ? l->n : 1) * 4 * sizeof *l->geo);
    if (!l->tri || !l->cdf || !l->nrm || !l->geo) goto oom;
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
        l->tri[k] = t;
        l->nrm[k] = emb_tri_normal(m, t);
        const uint32_t *vi = m->tris + 3 * (size_t)t;
        l->geo[4 * k] = m->pos[vi[0]];
        l->geo[4 * k + 1] = v3_sub(m->pos[vi[1]], m->pos[vi[0]]);
        l->geo[4 * k + 2] = v3_sub(m->pos[vi[2]], m->pos[vi[0]]);
        l->geo[4 * k + 3] = le;
        total += (double)a * v3_luminance(le);
        acc[++k] = total;
    }
    for (uint32_t i = 0; i < l->n; i++) {
        l->cdf[i + 1] = (float)(acc[i + 1] / total);
        uint32_t t = l->tri[i];
        l->pdf_area[t] = (float)(v3_luminance(m->mats[m->tri_mat[t]].emission) / total);
    }
    if (l->n) l->cdf[l->n] = 1.0f;
    free(acc);
    *out = l;
    return CT_OK;
oom:
    light_free(l);
    return ct_fail(err, CT_ENOMEM, "out of memory for the light list");
}

void light_free(light_set *l)
{
    if (!l) return;
    free(l->tri);
    free(l->cdf);
    free(l->nrm);
    free(l->geo);
    free(l->pdf_area);
    free(l);
}

uint32_t light_count(const light_set *l) { return l->n; }

bool light_sample(const light_set *l, float u0, float u1, float u2, light_point *out)
{
    if (l->n == 0) return false;
    /* First index whose cdf[i + 1] > u0. */
    uint32_t lo = 0, hi = l->n - 1;
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (l->cdf[mid + 1] > u0) hi = mid;
        else lo = mid + 1;
    }
    uint32_t t = l->tri[lo];
    float su = sqrtf(u1);
    float b1 = 1.0f - su, b2 = u2 * su;   /* uniform by area */
    const vec3 *g = l->geo + 4 * (size_t)lo;
    out->tri = t;
    out->p = v3_add(g[0], v3_add(v3_scale(g[1], b1), v3_scale(g[2], b2)));
    out->n = l->nrm[lo];
    out->le = g[3];
    out->pdf_area = l->pdf_area[t];
    return true;
}

float light_pdf_area(const light_set *l, uint32_t tri)
{
    return tri < l->mesh->ntris ? l->pdf_area[tri] : 0.0f;
}
