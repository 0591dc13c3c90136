#include "common/radmesh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int rmesh_alloc(ct_radmesh *m, uint32_t nverts, uint32_t ntris, uint32_t nnodes, ct_error *err)
{
    memset(m, 0, sizeof *m);
    m->nverts = nverts;
    m->ntris = ntris;
    m->nnodes = nnodes;
    m->pos = calloc(nverts ? nverts : 1, sizeof *m->pos);
    m->nrm = calloc(nverts ? nverts : 1, sizeof *m->nrm);
    m->rad = calloc(nverts ? nverts : 1, sizeof *m->rad);
    m->rad_direct = calloc(nverts ? nverts : 1, sizeof *m->rad_direct);
    m->tris = calloc(ntris ? (size_t)ntris * 3 : 1, sizeof *m->tris);
    m->tri_node = calloc(ntris ? ntris : 1, sizeof *m->tri_node);
    m->tri_mat = calloc(ntris ? ntris : 1, sizeof *m->tri_mat);
    m->nodes = calloc(nnodes ? nnodes : 1, sizeof *m->nodes);
    if (!m->pos || !m->nrm || !m->rad || !m->rad_direct || !m->tris || !m->tri_node ||
        !m->tri_mat || !m->nodes) {
        rmesh_free(m);
        return ct_fail(err, CT_ENOMEM, "out of memory for a mesh of %u vertices, %u triangles",
                       nverts, ntris);
    }
    return CT_OK;
}

void rmesh_free(ct_radmesh *m)
{
    free(m->pos);
    free(m->nrm);
    free(m->rad);
    free(m->rad_direct);
    free(m->tris);
    free(m->tri_node);
    free(m->tri_mat);
    free(m->nodes);
    free(m->mats);
    memset(m, 0, sizeof *m);
}

float rmesh_fresnel(float cos_i, float eta, float *cos_t)
{
    float c2 = 1.0f - cos_i * cos_i;
    float sin2_t = eta * eta * (c2 > 0.0f ? c2 : 0.0f);
    if (sin2_t >= 1.0f) {
        *cos_t = 0.0f;
        return 1.0f;
    }
    float ct = sqrtf(1.0f - sin2_t);
    float rs = (eta * cos_i - ct) / (eta * cos_i + ct);
    float rp = (cos_i - eta * ct) / (cos_i + eta * ct);
    *cos_t = ct;
    return 0.5f * (rs * rs + rp * rp);
}

int rmesh_set_materials(ct_radmesh *m, const ct_scene *s, ct_error *err)
{
    if (s->nmats > RMESH_MAX_MATS)
        return ct_fail(err, CT_ERANGE, "%u materials, a mesh carries at most %u", s->nmats, RMESH_MAX_MATS);
    rmesh_material *t = calloc(s->nmats ? s->nmats : 1, sizeof *t);
    if (!t) return ct_fail(err, CT_ENOMEM, "out of memory for %u materials", s->nmats);
    for (uint32_t i = 0; i < s->nmats; i++) t[i] = rmesh_material_of(&s->mats[i]);
    free(m->mats);
    m->mats = t;
    m->nmats = s->nmats;
    return CT_OK;
}

int rmesh_check_nodes(const ct_radmesh *m, const ct_scene *s, ct_error *err)
{
    if (m->nnodes != s->nnodes)
        return ct_fail(err, CT_ESTALE, "radiosity mesh has %u nodes, the scene %u", m->nnodes, s->nnodes);
    for (uint32_t n = 0; n < m->nnodes; n++)
        if (strcmp(m->nodes[n].name, s->nodes[n].name) != 0 || m->nodes[n].material != s->nodes[n].material)
            return ct_fail(err, CT_ESTALE, "radiosity mesh node %u ('%s') does not match the scene's ('%s')", n,
                           m->nodes[n].name, s->nodes[n].name);
    return CT_OK;
}

int rmesh_from_scene(const ct_scene *s, vec3 ambient, ct_radmesh *m, ct_error *err)
{
    /* Vertices are duplicated per triangle so each triangle can carry its own
     * material's constant value without bleeding across parts. */
    int rc = rmesh_alloc(m, s->ntris * 3, s->ntris, s->nnodes, err);
    if (rc) return rc;
    for (uint32_t t = 0; t < s->ntris; t++) {
        const scene_material *mat = &s->mats[s->tri_mat[t]];
        vec3 c = v3_add(mat->emission, v3_mul(mat->diffuse, ambient));
        for (int k = 0; k < 3; k++) {
            uint32_t src = s->tris[3 * t + k], dst = 3 * t + (uint32_t)k;
            m->pos[dst] = s->pos[src];
            m->nrm[dst] = s->nrm[src];
            m->rad[dst] = c;
            m->rad_direct[dst] = mat->emission;
            m->tris[dst] = dst;
        }
        m->tri_node[t] = s->tri_node[t];
        m->tri_mat[t] = s->tri_mat[t];
    }
    for (uint32_t n = 0; n < s->nnodes; n++) {
        snprintf(m->nodes[n].name, sizeof m->nodes[n].name, "%s", s->nodes[n].name);
        m->nodes[n].parent = s->nodes[n].parent;
        m->nodes[n].node_end = s->nodes[n].node_end;
        m->nodes[n].material = s->nodes[n].material;
        m->nodes[n].bounds = s->nodes[n].bounds;
    }
    m->scene_hash = s->source_hash;
    rc = rmesh_set_materials(m, s, err);
    if (rc) rmesh_free(m);
    return rc;
}
