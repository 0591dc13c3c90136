#include "display/disp_scene.h"

#include <stdlib.h>
#include <string.h>

#include "display/gl_load.h"

struct disp_scene {
    GLuint vao, vbo, ibo;
    uint32_t nverts, ntris, nnodes;
    uint32_t *node_first;   /* nnodes + 1: first sorted triangle of each node id */
    uint32_t *node_end;     /* subtree end node of each node */
    bounds3 *node_bounds;   /* world bounds of each node's subtree triangles */
    bounds3 bounds;
    disp_glass *glass;      /* runs of see-through triangles, in order */
    uint32_t nglass;
    uint64_t serial;        /* disp_scene_serial */
};

static int validate(const ct_radmesh *m, ct_error *err)
{
    if (m->nverts == 0 || m->ntris == 0 || m->nnodes == 0)
        return ct_fail(err, CT_EEMPTY, "mesh is empty (%u vertices, %u triangles, %u nodes)",
                       m->nverts, m->ntris, m->nnodes);
    for (size_t i = 0; i < 3 * (size_t)m->ntris; i++)
        if (m->tris[i] >= m->nverts)
            return ct_fail(err, CT_ERANGE, "mesh triangle %zu uses vertex %u of %u", i / 3,
                           m->tris[i], m->nverts);
    for (uint32_t t = 0; t < m->ntris; t++)
        if (m->tri_node[t] >= m->nnodes)
            return ct_fail(err, CT_ERANGE, "mesh triangle %u names node %u of %u", t,
                           m->tri_node[t], m->nnodes);
    for (uint32_t n = 0; n < m->nnodes; n++)
        if (m->nodes[n].node_end <= n || m->nodes[n].node_end > m->nnodes)
            return ct_fail(err, CT_ERANGE, "mesh node %u has subtree end %u (must be in %u..%u)",
                           n, m->nodes[n].node_end, n + 1, m->nnodes);
    for (uint32_t v = 0; v < m->nverts; v++)
        if (!v3_finite(m->pos[v]) || !v3_finite(m->rad[v]))
            return ct_fail(err, CT_ERANGE, "mesh vertex %u is not finite", v);
    return CT_OK;
}

/* The runs of see-through triangles of one material in the sorted order
 * (smat: each sorted triangle's material, idx its vertices). */
static int glass_runs(disp_scene *s, const ct_radmesh *m, const uint32_t *smat, const uint32_t *idx,
                      ct_error *err)
{
    uint32_t n = 0;
    for (uint32_t t = 0; t < m->ntris; t++)
        if (rmesh_is_glass(m, smat[t]) && (t == 0 || smat[t - 1] != smat[t])) n++;
    if (!n) return CT_OK;
    s->glass = malloc((size_t)n * sizeof *s->glass);
    if (!s->glass) return ct_fail(err, CT_ENOMEM, "out of memory for %u glass runs", n);
    for (uint32_t t = 0; t < m->ntris; t++) {
        if (!rmesh_is_glass(m, smat[t])) continue;
        if (t == 0 || smat[t - 1] != smat[t]) {
            const rmesh_material *x = &m->mats[smat[t]];
            s->glass[s->nglass++] = (disp_glass){t, t + 1, x->transmission, x->ior, b3_empty()};
        } else {
            s->glass[s->nglass - 1].end = t + 1;
        }
        disp_glass *g = &s->glass[s->nglass - 1];
        for (int k = 0; k < 3; k++) g->bounds = b3_add(g->bounds, m->pos[idx[3 * (size_t)t + (size_t)k]]);
    }
    return CT_OK;
}

int disp_scene_new(const ct_radmesh *m, disp_scene **out, ct_error *err)
{
    *out = NULL;
    int rc = validate(m, err);
    if (rc) return rc;
    /* GL contexts are made and used on one thread: no atomics needed. */
    static uint64_t serials;
    disp_scene *s = calloc(1, sizeof *s);
    if (s) s->serial = ++serials;
    float *verts = malloc((size_t)m->nverts * 6 * sizeof *verts);
    uint32_t *idx = malloc((size_t)m->ntris * 3 * sizeof *idx);
    if (s) {
        s->node_first = calloc((size_t)m->nnodes + 1, sizeof *s->node_first);
        s->node_end = malloc((size_t)m->nnodes * sizeof *s->node_end);
        s->node_bounds = malloc((size_t)m->nnodes * sizeof *s->node_bounds);
    }
    if (!s || !verts || !idx || !s->node_first || !s->node_end || !s->node_bounds) {
        free(verts);
        free(idx);
        disp_scene_free(s);
        return ct_fail(err, CT_ENOMEM, "out of memory uploading a mesh of %u triangles", m->ntris);
    }
    s->nverts = m->nverts;
    s->ntris = m->ntris;
    s->nnodes = m->nnodes;
    s->bounds = b3_empty();
    for (uint32_t v = 0; v < m->nverts; v++) {
        float *p = verts + 6 * (size_t)v;
        p[0] = m->pos[v].x; p[1] = m->pos[v].y; p[2] = m->pos[v].z;
        p[3] = m->rad[v].x; p[4] = m->rad[v].y; p[5] = m->rad[v].z;
        s->bounds = b3_add(s->bounds, m->pos[v]);
    }
    /* Counting sort of triangles by node id (stable): pre-order node ids make
     * every subtree one range. */
    for (uint32_t t = 0; t < m->ntris; t++) s->node_first[m->tri_node[t] + 1]++;
    for (uint32_t n = 0; n < m->nnodes; n++) s->node_first[n + 1] += s->node_first[n];
    uint32_t *fill = malloc((size_t)m->nnodes * sizeof *fill);
    if (!fill) {
        free(verts);
        free(idx);
        disp_scene_free(s);
        return ct_fail(err, CT_ENOMEM, "out of memory sorting %u triangles", m->ntris);
    }
    memcpy(fill, s->node_first, (size_t)m->nnodes * sizeof *fill);
    /* Each sorted triangle's material, for the glass runs. */
    uint32_t *smat = malloc((size_t)m->ntris * sizeof *smat);
    if (!smat) {
        free(fill);
        free(verts);
        free(idx);
        disp_scene_free(s);
        return ct_fail(err, CT_ENOMEM, "out of memory sorting %u triangles", m->ntris);
    }
    for (uint32_t t = 0; t < m->ntris; t++) {
        uint32_t at = fill[m->tri_node[t]]++;
        memcpy(idx + 3 * (size_t)at, m->tris + 3 * (size_t)t, 3 * sizeof *idx);
        smat[at] = m->tri_mat[t];
    }
    free(fill);
    rc = glass_runs(s, m, smat, idx, err);
    free(smat);
    if (rc) {
        free(verts);
        free(idx);
        disp_scene_free(s);
        return rc;
    }
    for (uint32_t n = 0; n < m->nnodes; n++) s->node_end[n] = m->nodes[n].node_end;
    /* Subtree bounds from the triangles themselves: a node's own triangles,
     * then each node's into its parent (pre-order: children after parents). */
    for (uint32_t n = 0; n < m->nnodes; n++) s->node_bounds[n] = b3_empty();
    for (uint32_t t = 0; t < m->ntris; t++) {
        bounds3 *b = &s->node_bounds[m->tri_node[t]];
        for (int k = 0; k < 3; k++) *b = b3_add(*b, m->pos[m->tris[3 * (size_t)t + (size_t)k]]);
    }
    for (uint32_t n = m->nnodes; n-- > 0;) {
        int32_t p = m->nodes[n].parent;
        if (p >= 0 && (uint32_t)p < n) {
            s->node_bounds[p] = b3_union(s->node_bounds[p], s->node_bounds[n]);
        }
    }

    gl.GenVertexArrays(1, &s->vao);
    gl.BindVertexArray(s->vao);
    gl.GenBuffers(1, &s->vbo);
    gl.BindBuffer(GL_ARRAY_BUFFER, s->vbo);
    gl.BufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)m->nverts * 6 * sizeof *verts), verts,
                  GL_STATIC_DRAW);
    gl.EnableVertexAttribArray(0);
    gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), (const void *)0);
    gl.EnableVertexAttribArray(1);
    gl.VertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float),
                           (const void *)(3 * sizeof(float)));
    gl.GenBuffers(1, &s->ibo);
    gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, s->ibo);
    gl.BufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)((size_t)m->ntris * 3 * sizeof *idx), idx,
                  GL_STATIC_DRAW);
    gl.BindVertexArray(0);
    free(verts);
    free(idx);
    rc = gl_check("mesh upload", err);
    if (rc) {
        disp_scene_free(s);
        return rc;
    }
    *out = s;
    return CT_OK;
}

void disp_scene_free(disp_scene *s)
{
    if (!s) return;
    if (s->vao) gl.DeleteVertexArrays(1, &s->vao);
    if (s->vbo) gl.DeleteBuffers(1, &s->vbo);
    if (s->ibo) gl.DeleteBuffers(1, &s->ibo);
    free(s->node_first);
    free(s->node_end);
    free(s->node_bounds);
    free(s->glass);
    free(s);
}

const disp_glass *disp_scene_glass(const disp_scene *s, uint32_t *n)
{
    *n = s->nglass;
    return s->glass;
}

uint32_t disp_scene_ntris(const disp_scene *s) { return s->ntris; }
uint64_t disp_scene_serial(const disp_scene *s) { return s->serial; }
bounds3 disp_scene_bounds(const disp_scene *s) { return s->bounds; }

bounds3 disp_scene_node_bounds(const disp_scene *s, uint32_t n)
{
    return n < s->nnodes ? s->node_bounds[n] : b3_empty();
}

int disp_scene_node_range(const disp_scene *s, uint32_t n, uint32_t *begin, uint32_t *end,
                          ct_error *err)
{
    if (n >= s->nnodes)
        return ct_fail(err, CT_ERANGE, "node %u out of range (mesh has %u nodes)", n, s->nnodes);
    *begin = s->node_first[n];
    *end = s->node_first[s->node_end[n]];
    return CT_OK;
}

void disp_scene_bind(const disp_scene *s)
{
    gl.BindVertexArray(s->vao);
}

void disp_scene_draw(const disp_scene *s, uint32_t begin, uint32_t end)
{
    if (end <= begin || end > s->ntris) return;
    gl.DrawElements(GL_TRIANGLES, (GLsizei)(3 * (end - begin)), GL_UNSIGNED_INT,
                    (const void *)(3 * (size_t)begin * sizeof(uint32_t)));
}
