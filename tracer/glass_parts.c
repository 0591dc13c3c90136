/* glass_parts.c: flat and bending glass parts (glass_parts.h). */
#include "tracer/glass_parts.h"

#include <math.h>
#include <stdlib.h>

#include "common/vecmath.h"

/* Two face normals count as one plane direction within about 0.8 degrees:
 * a tessellated flat face's triangles agree to float precision, the facets
 * of a sphere or a glass's wall differ by degrees. */
#define SAME_DIR 0.9999f
/* Plane directions kept per part, with their area; a part's glass beyond
 * them (a curved part's facets) counts only in its total. */
#define MAX_DIRS 64

typedef struct part_planes {
    vec3 n[MAX_DIRS];
    double area[MAX_DIRS];
    double total;
    int count;
} part_planes;

static void add_face(part_planes *p, vec3 n, double area)
{
    p->total += area;
    for (int i = 0; i < p->count; i++)
        if (v3_dot(p->n[i], n) > SAME_DIR) {
            p->area[i] += area;
            return;
        }
    if (p->count == MAX_DIRS) return;
    p->n[p->count] = n;
    p->area[p->count++] = area;
}

/* Flat (p holds some glass): a plane, or a pair of opposite planes, holding
 * GPARTS_FLAT_SHARE of the part's glass. Sliver triangles of a subdivided pane, whose rounded
 * corners tilt them by degrees, hold next to nothing of it. */
static bool flat(const part_planes *p)
{
    int a = 0;
    for (int i = 1; i < p->count; i++)
        if (p->area[i] > p->area[a]) a = i;
    double both = p->area[a];
    for (int i = 0; i < p->count; i++)
        if (v3_dot(p->n[i], p->n[a]) < -SAME_DIR) both += p->area[i];
    return both >= GPARTS_FLAT_SHARE * p->total;
}

int gparts_bending(const emb_mesh *m, uint8_t **out, ct_error *err)
{
    uint32_t nn = m->nnodes ? m->nnodes : 1;
    /* Planes only for the parts with glass (a scene may have millions of
     * parts and a few glasses): slot[node] indexes them, 0 = none. */
    uint32_t *slot = calloc(nn, sizeof *slot);
    uint8_t *bends = calloc(nn, 1);
    if (!slot || !bends) {
        free(slot);
        free(bends);
        return ct_fail(err, CT_ENOMEM, "out of memory for %u glass parts", nn);
    }
    uint32_t nglass = 0;
    for (uint32_t t = 0; t < m->ntris; t++) {
        uint32_t node = m->tri_node[t] < nn ? m->tri_node[t] : 0;
        if (m->mats[m->tri_mat[t]].dielectric && !slot[node]) slot[node] = ++nglass;
    }
    part_planes *pp = calloc(nglass ? nglass : 1, sizeof *pp);
    if (!pp) {
        free(slot);
        free(bends);
        return ct_fail(err, CT_ENOMEM, "out of memory for %u glass parts", nglass);
    }
    for (uint32_t t = 0; t < m->ntris; t++) {
        if (!m->mats[m->tri_mat[t]].dielectric) continue;
        const uint32_t *v = m->tris + 3 * (size_t)t;
        vec3 a = m->pos[v[0]];
        vec3 n = v3_cross(v3_sub(m->pos[v[1]], a), v3_sub(m->pos[v[2]], a));
        float len = v3_len(n);
        if (!(len > 0.0f) || !isfinite(len)) continue;
        uint32_t node = m->tri_node[t] < nn ? m->tri_node[t] : 0;
        add_face(&pp[slot[node] - 1], v3_scale(n, 1.0f / len), 0.5 * (double)len);
    }
    for (uint32_t i = 0; i < nn; i++) {
        const part_planes *p = slot[i] ? &pp[slot[i] - 1] : NULL;
        bends[i] = p && p->total > 0.0 && !flat(p);
    }
    free(pp);
    free(slot);
    *out = bends;
    return CT_OK;
}
