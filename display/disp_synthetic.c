#include "display/disp_synthetic.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct rect { float x0, y0, x1, y1; uint32_t node; } rect;

/* Projected bounding rectangle (NDC) of b; false when not in view. */
static bool project_bounds(const mat4 *pv, bounds3 b, rect *r)
{
    r->x0 = r->y0 = INFINITY;
    r->x1 = r->y1 = -INFINITY;
    for (int i = 0; i < 8; i++) {
        vec4 q = m4_point4(pv, b3_corner(b, i));
        if (q.w <= 1e-6f) return false;   /* straddles the eye plane: skip */
        float x = q.x / q.w, y = q.y / q.w;
        r->x0 = fminf(r->x0, x); r->x1 = fmaxf(r->x1, x);
        r->y0 = fminf(r->y0, y); r->y1 = fmaxf(r->y1, y);
    }
    r->x0 = fmaxf(r->x0, -1.0f); r->y0 = fmaxf(r->y0, -1.0f);
    r->x1 = fminf(r->x1, 1.0f);  r->y1 = fminf(r->y1, 1.0f);
    return r->x1 - r->x0 > 1e-3f && r->y1 - r->y0 > 1e-3f;
}

int disp_synthetic_textures(disp_session *s, const ct_radmesh *m, const ct_camera *cam, int width,
                            int height, uint32_t n, bool tiles, bool positive, uint32_t *made,
                            ct_error *err)
{
    *made = 0;
    if (!n) return CT_OK;
    mat4 pv = m4_mul(cam_proj(cam, width, height, 0.01f, 1000.0f), cam_view(cam));
    /* Part nodes (leaves with triangles) and their bounds from the mesh. */
    bounds3 *nb = malloc((size_t)m->nnodes * sizeof *nb);
    rect *vis = malloc((size_t)m->nnodes * sizeof *vis);
    if (!nb || !vis) {
        free(nb);
        free(vis);
        return ct_fail(err, CT_ENOMEM, "out of memory for synthetic textures");
    }
    for (uint32_t i = 0; i < m->nnodes; i++) nb[i] = b3_empty();
    for (uint32_t t = 0; t < m->ntris; t++)
        for (int k = 0; k < 3; k++)
            nb[m->tri_node[t]] = b3_add(nb[m->tri_node[t]], m->pos[m->tris[3 * t + (uint32_t)k]]);
    uint32_t nv = 0;
    for (uint32_t i = 0; i < m->nnodes; i++)
        if (!b3_is_empty(nb[i]) && project_bounds(&pv, nb[i], &vis[nv])) vis[nv++].node = i;
    int rc = CT_OK;
    if (nv) {
        /* Tiles per visible node: k x k with k*k*nv >= n. */
        uint32_t k = 1;
        while (tiles && k * k * nv < n) k++;
        uint32_t id = 1;
        float *buf = NULL;
        for (uint32_t v = 0; v < nv && id <= n && !rc; v++)
            for (uint32_t ty = 0; ty < k && id <= n && !rc; ty++)
                for (uint32_t tx = 0; tx < k && id <= n && !rc; tx++, id++) {
                    rect r = vis[v];
                    float w = (r.x1 - r.x0) / (float)k, h = (r.y1 - r.y0) / (float)k;
                    float a = r.x0 + w * (float)tx, c = r.y0 + h * (float)ty;
                    /* Resolution: about one texel per 2x2 pixels, 8..256. */
                    int tw = (int)fminf(256.0f, fmaxf(8.0f, 0.25f * w * (float)width));
                    int th = (int)fminf(256.0f, fmaxf(8.0f, 0.25f * h * (float)height));
                    mat4 sm = m4_identity();
                    sm.m[0][0] = 1.0f / w; sm.m[0][3] = -a / w;
                    sm.m[1][1] = 1.0f / h; sm.m[1][3] = -c / h;
                    mat4 proj;
                    for (int j = 0; j < 4; j++) {
                        proj.m[0][j] = sm.m[0][0] * pv.m[0][j] + sm.m[0][3] * pv.m[3][j];
                        proj.m[1][j] = sm.m[1][1] * pv.m[1][j] + sm.m[1][3] * pv.m[3][j];
                        proj.m[2][j] = 0.0f;
                        proj.m[3][j] = pv.m[3][j];
                    }
                    float *nbuf = realloc(buf, (size_t)tw * (size_t)th * 3 * sizeof *buf);
                    if (!nbuf) {
                        rc = ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d texture", tw, th);
                        break;
                    }
                    buf = nbuf;
                    for (int y = 0; y < th; y++)
                        for (int x = 0; x < tw; x++)
                            for (int ch = 0; ch < 3; ch++) {
                                float val = 0.15f * sinf(0.4f * (float)x + 0.3f * (float)y + 2.0f * (float)ch + (float)id);
                                buf[3 * ((size_t)y * (size_t)tw + (size_t)x) + (size_t)ch] = positive ? fabsf(val) : val;
                            }
                    rc = disp_session_tex_alloc(s, id, r.node, tw, th, DISP_PROJ_CAMERA_PERSPECTIVE, err);
                    if (!rc) rc = disp_session_tex_projection(s, id, &proj, err);
                    if (!rc) rc = disp_session_tex_patch_float(s, id, 0, 0, tw, th, buf, err);
                    if (!rc) (*made)++;
                }
        free(buf);
    }
    free(nb);
    free(vis);
    return rc;
}
