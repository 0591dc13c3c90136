/* ctex_view.c: the corrective textures of one view (ctex_set_camera):
 * frustum culling and the §3.3 top-down assignment, object-local parallel
 * and camera-local perspective projections (§3.2), aging (§3.5),
 * reprojection and resampling of split or merged nodes, texture slots and
 * the memory cap. */
#include <stdlib.h>
#include <string.h>

#include "master/ctex_internal.h"

/* --- geometry of a view ------------------------------------------------------------ */

/* Per node in the current view: visibility, parallax ratio, pixel rectangle. */
typedef struct nview {
    int visible;
    float zmin, zmax, zc;   /* depths of the bounds (and its centre) along the view */
    float ratio;            /* Δr / d */
    float x0, y0, x1, y1;   /* clipped pixel rectangle */
    float ux0, uy0, ux1, uy1; /* the same before the screen's edges cut it */
} nview;

static void view_node(const ctex *c, const ctex_hnode *n, nview *v)
{
    memset(v, 0, sizeof *v);
    vec3 P[8];
    float X[8], Y[8], Z[8];
    float zmin = INFINITY, zmax = -INFINITY;
    for (int i = 0; i < 8; i++) {
        vec3 d = v3_sub(b3_corner(n->bounds, i), c->cam.eye);
        P[i] = d;
        X[i] = v3_dot(d, c->rays.r); Y[i] = v3_dot(d, c->rays.u); Z[i] = v3_dot(d, c->rays.f);
        zmin = fminf(zmin, Z[i]); zmax = fmaxf(zmax, Z[i]);
    }
    (void)P;
    v->zmin = zmin; v->zmax = zmax;
    v->zc = v3_dot(v3_sub(b3_center(n->bounds), c->cam.eye), c->rays.f);
    /* frustum culling: all corners outside one plane */
    int out_l = 1, out_r = 1, out_b = 1, out_t = 1;
    for (int i = 0; i < 8; i++) {
        if (X[i] >= -Z[i] * c->rays.tw) out_l = 0;
        if (X[i] <= Z[i] * c->rays.tw) out_r = 0;
        if (Y[i] >= -Z[i] * c->rays.th) out_b = 0;
        if (Y[i] <= Z[i] * c->rays.th) out_t = 0;
    }
    if (zmax < c->znear || out_l || out_r || out_b || out_t) return;
    /* the box clipped by the near plane, projected: its bounding rectangle */
    float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    float zn = c->znear;
#define ADDPT(xx, yy, zz) do { \
        float px_ = 0.5f * (float)c->W * (1.0f + (xx) / ((zz) * c->rays.tw)); \
        float py_ = 0.5f * (float)c->H * (1.0f - (yy) / ((zz) * c->rays.th)); \
        x0 = fminf(x0, px_); x1 = fmaxf(x1, px_); y0 = fminf(y0, py_); y1 = fmaxf(y1, py_); \
    } while (0)
    for (int i = 0; i < 8; i++)
        if (Z[i] >= zn) ADDPT(X[i], Y[i], Z[i]);
    for (int i = 0; i < 8; i++)
        for (int bit = 1; bit < 8; bit <<= 1) {
            int j = i | bit;
            if (j == i) continue;
            if ((Z[i] >= zn) == (Z[j] >= zn)) continue;
            float s = (zn - Z[i]) / (Z[j] - Z[i]);
            ADDPT(X[i] + s * (X[j] - X[i]), Y[i] + s * (Y[j] - Y[i]), zn);
        }
#undef ADDPT
    v->ux0 = x0; v->uy0 = y0; v->ux1 = x1; v->uy1 = y1;
    x0 = fmaxf(x0, 0.0f); y0 = fmaxf(y0, 0.0f);
    x1 = fminf(x1, (float)c->W); y1 = fminf(y1, (float)c->H);
    if (!(x1 > x0) || !(y1 > y0)) return;
    v->visible = 1;
    v->x0 = x0; v->y0 = y0; v->x1 = x1; v->y1 = y1;
    /* §3.3: parallax estimate Δr / d; d = nearest depth (infinite when the
     * node reaches the eye plane) */
    v->ratio = zmin > c->znear ? (zmax - zmin) / zmin : INFINITY;
}

/* §3.3 top-down assignment. */
static void visit(ctex *c, uint32_t n)
{
    const ctex_hnode *hn = &c->h.nodes[n];
    nview v;
    view_node(c, hn, &v);
    if (!v.visible) return;
    int leaf = hn->end == n + 1;
    float size = fmaxf(v.x1 - v.x0, v.y1 - v.y0);
    float limit = c->o.max_proj > 0.0f ? c->o.max_proj * (float)(c->W > c->H ? c->W : c->H) : INFINITY;
    if (leaf || (v.ratio < c->o.eps && size <= limit)) {
        c->assigned[n] = 1;
        c->list[c->nlist++] = n;
        return;
    }
    for (uint32_t ch = n + 1; ch < hn->end; ch = c->h.nodes[ch].end) visit(c, ch);
}

/* Widens a camera-local rectangle past the screen edges that cut the node,
 * by --projector-margin of the screen at most, and never by more than a
 * quarter of what shows along that axis: keep_projector wants half of a
 * texture's area in view, and this leaves 0.8 of each axis. */
static void widen(const ctex *c, nview *v)
{
    float share[2] = {v->x1 - v->x0, v->y1 - v->y0};
    float screen[2] = {(float)c->W, (float)c->H};
    float *lo[2] = {&v->x0, &v->y0}, *hi[2] = {&v->x1, &v->y1};
    const float ulo[2] = {v->ux0, v->uy0}, uhi[2] = {v->ux1, v->uy1};
    for (int a = 0; a < 2; a++) {
        int cut = (ulo[a] < *lo[a]) + (uhi[a] > *hi[a]);
        if (!cut) continue;
        float m = fminf(c->o.proj_margin * screen[a], 0.25f * share[a] / (float)cut);
        if (ulo[a] < *lo[a]) *lo[a] = fmaxf(ulo[a], *lo[a] - m);
        if (uhi[a] > *hi[a]) *hi[a] = fminf(uhi[a], *hi[a] + m);
    }
}

/* Sets the texture's projection for the current view (§3.2) and returns the
 * pixel extent of its domain (for resolution bounds). `margin`: a
 * camera-local domain reaches past the screen's edges where they cut the
 * node (widen), for a texture the camera's move made again: the next small
 * moves then find the node's new rectangle inside it and keep its
 * projector instead of resampling and re-sending it (docs/textures.md,
 * "Projections"). */
static void make_projection(ctex *c, uint32_t hnode, ctex_tex *t, bool margin, float *pxw, float *pxh)
{
    const ctex_hnode *n = &c->h.nodes[hnode];
    nview v;
    view_node(c, n, &v);
    if (n->flat) {
        /* object-local parallel projection along the normal */
        t->kind = CTEX_PROJ_OBJECT;
        t->o = n->o; t->t = n->t; t->b = n->b; t->n = n->normal;
        float lt2 = v3_len2(n->t), lb2 = v3_len2(n->b);
        vec3 a = v3_scale(n->t, 1.0f / lt2), b = v3_scale(n->b, 1.0f / lb2), nn = n->normal;
        mat4 m = m4_identity();
        m.m[0][0] = a.x; m.m[0][1] = a.y; m.m[0][2] = a.z; m.m[0][3] = -v3_dot(a, n->o);
        m.m[1][0] = b.x; m.m[1][1] = b.y; m.m[1][2] = b.z; m.m[1][3] = -v3_dot(b, n->o);
        m.m[2][0] = nn.x; m.m[2][1] = nn.y; m.m[2][2] = nn.z; m.m[2][3] = -v3_dot(nn, n->o);
        t->m = m;
        /* screen sampling rate at the node's nearest visible depth */
        float z = fmaxf(v.visible ? fmaxf(v.zmin, c->znear) : v.zc, c->znear);
        if (z < c->znear) z = c->znear;
        *pxw = sqrtf(lt2) * c->fpx / z;
        *pxh = sqrtf(lb2) * c->fpx / z;
        float cap = (float)(c->W > c->H ? c->W : c->H);
        if (*pxw > cap) *pxw = cap;
        if (*pxh > cap) *pxh = cap;
        return;
    }
    /* camera-local perspective: the bounding rectangle of the projected
     * bounding volume, a sheared frustum */
    t->kind = CTEX_PROJ_CAMERA;
    t->cam = c->cam;
    t->cam_w = c->W; t->cam_h = c->H;
    if (!v.visible) { v.x0 = 0; v.y0 = 0; v.x1 = (float)c->W; v.y1 = (float)c->H; }
    else if (margin && c->o.proj_margin > 0.0f) widen(c, &v);
    t->x0 = v.x0; t->y0 = v.y0; t->x1 = v.x1; t->y1 = v.y1;
    float zc = v.zc;
    float zlo = fmaxf(v.zmin, c->znear), zhi = fmaxf(v.zmax, zlo);
    t->ref_depth = zc < zlo ? zlo : (zc > zhi ? zhi : zc);
    float W = (float)c->W, H = (float)c->H;
    float dx = t->x1 - t->x0, dy = t->y1 - t->y0;
    /* rows in eye space (x_e, y_e, z_e, 1), camera looking down -z */
    mat4 e = m4_identity();
    float rx[4] = {0.5f * W / c->rays.tw, 0.0f, -0.5f * W + t->x0, 0.0f};
    float ry[4] = {0.0f, -0.5f * H / c->rays.th, -0.5f * H + t->y0, 0.0f};
    for (int k = 0; k < 4; k++) {
        e.m[0][k] = rx[k] / dx;
        e.m[1][k] = ry[k] / dy;
    }
    e.m[2][0] = 0; e.m[2][1] = 0; e.m[2][2] = 0; e.m[2][3] = 1;   /* keeps M invertible */
    e.m[3][0] = 0; e.m[3][1] = 0; e.m[3][2] = -1; e.m[3][3] = 0;  /* w = depth */
    mat4 view = cam_view(&c->cam);
    t->m = m4_mul(e, view);
    *pxw = dx;
    *pxh = dy;
}

static void size_bounds(const ctex *c, float pxw, float pxh, int *mw, int *mh)
{
    float r = c->o.tex_rate;   /* §3.6: up to twice the screen sampling rate */
    float fw = ceilf(pxw * r), fh = ceilf(pxh * r);
    int w = fw > (float)c->o.tex_max ? c->o.tex_max : (int)fw;
    int h = fh > (float)c->o.tex_max ? c->o.tex_max : (int)fh;
    if (w < c->o.tex_min) w = c->o.tex_min;
    if (h < c->o.tex_min) h = c->o.tex_min;
    *mw = w;
    *mh = h;
}

/* A size with the domain's aspect ratio whose longer axis is `longer`. */
static void aspect_size(const ctex *c, float pxw, float pxh, float longer, int mw, int mh, int *w, int *h)
{
    float a = pxw > 0.0f && pxh > 0.0f ? pxw / pxh : 1.0f;
    float fw = a >= 1.0f ? longer : longer * a, fh = a >= 1.0f ? longer / a : longer;
    int iw = (int)ceilf(fw), ih = (int)ceilf(fh);
    if (iw > mw) iw = mw;
    if (ih > mh) ih = mh;
    if (iw < c->o.tex_min) iw = c->o.tex_min;
    if (ih < c->o.tex_min) ih = c->o.tex_min;
    *w = iw;
    *h = ih;
}

void ctex_destroy_slot(ctex *c, uint32_t id)
{
    slot *s = &c->slots[id];
    if (!s->live) return;
    if (s->active) ctex_ev_push(c, CTEX_EV_FREE, id);
    c->bytes -= ctex_tex_bytes(s->t.w, s->t.h);
    ctex_tex_release(&s->t);
    if (c->node_tex[s->hnode] == (int32_t)id) c->node_tex[s->hnode] = -1;
    s->live = 0;
    s->active = 0;
}

/* Evicts parked textures, least recently visible first, until `need` more
 * bytes fit under the cap; returns whether they fit. */
int ctex_make_room(ctex *c, size_t need)
{
    size_t cap = (size_t)(c->o.mem_mb * 1048576.0);
    while (c->bytes + need > cap) {
        int32_t victim = -1;
        for (uint32_t i = 0; i < c->nslots; i++) {
            slot *s = &c->slots[i];
            if (!s->live || s->active || c->retire[i]) continue;
            if (victim < 0 || s->last_epoch < c->slots[victim].last_epoch) victim = (int32_t)i;
        }
        if (victim < 0) return 0;
        ctex_destroy_slot(c, (uint32_t)victim);
        c->st.evictions++;
    }
    return 1;
}

static int32_t new_slot(ctex *c, ct_error *err)
{
    for (uint32_t i = 0; i < c->nslots; i++)
        if (!c->slots[i].live) {
            memset(&c->slots[i], 0, sizeof c->slots[i]);
            return (int32_t)i;
        }
    if (c->nslots == c->cap_slots) {
        uint32_t nc = c->cap_slots ? 2 * c->cap_slots : 64;
        slot *ns = realloc(c->slots, nc * sizeof *ns);
        uint8_t *nr = realloc(c->retire, nc);
        int32_t *nsrc = realloc(c->srcs, nc * sizeof *nsrc);
        if (ns) c->slots = ns;
        if (nr) c->retire = nr;
        if (nsrc) c->srcs = nsrc;
        if (!ns || !nr || !nsrc) return ct_fail(err, CT_ENOMEM, "out of memory for texture slots");
        memset(c->slots + c->cap_slots, 0, (nc - c->cap_slots) * sizeof *ns);
        memset(c->retire + c->cap_slots, 0, nc - c->cap_slots);
        c->cap_slots = nc;
    }
    uint32_t id = c->nslots++;
    memset(&c->slots[id], 0, sizeof c->slots[id]);
    return (int32_t)id;
}

/* §3.5: v_max offset for a texture when the eye moves from e0 to the current one. */
static float age_offset(const ctex *c, const slot *s, vec3 e0)
{
    const ctex_hnode *n = &c->h.nodes[s->hnode];
    vec3 ctr = b3_center(n->bounds);
    vec3 d0 = v3_sub(ctr, e0), d1 = v3_sub(ctr, c->cam.eye);
    float off = 0.0f;
    if (n->gloss > 0.0f && v3_len2(d0) > 0.0f && v3_len2(d1) > 0.0f) {
        /* BRDF change: glossiness x change of the viewing direction
         * (v3_angle: acos of the dot product rounded every step under
         * 3.5e-4 radians, a millimetre seen from 3 m, to 0 or 3.5e-4) */
        float ang = v3_angle(d0, d1);
        off += ctex_brdf_age(c, &s->t, n->gloss, ang);
    }
    if (s->t.kind == CTEX_PROJ_CAMERA) {
        /* texture flow: (depth range / distance) x camera motion in pixels,
         * converted to texels */
        nview v;
        view_node(c, n, &v);
        float d = fmaxf(fabsf(v.zc), c->znear);
        float dr = fmaxf(v.zmax - v.zmin, 0.0f);
        float motion_px = c->fpx * v3_len(v3_sub(c->cam.eye, e0)) / d;
        float tex_per_px = (float)s->t.w / fmaxf(s->t.x1 - s->t.x0, 1.0f);
        off += c->o.age_flow * (dr / d) * motion_px * tex_per_px;
    }
    return off;
}

/* §3.5 aging on a camera change. The radii since the texture's last
 * resolution change were measured against samples of the views before;
 * the mean since the change that a resolution change needs (ctex_insert.c)
 * starts again from here. */
static void age(ctex *c, slot *s)
{
    ctex_tex_age(&s->t, age_offset(c, s, s->last_eye));
    s->t.sum_r = 0.0;
    s->t.n_sum = 0;
}

/* Texels per screen pixel of a live texture: camera-local over the rectangle
 * it was made for, object-local at the current view. */
static float tex_rate_now(ctex *c, const slot *s)
{
    if (s->t.kind == CTEX_PROJ_CAMERA) return (float)s->t.w / fmaxf(s->t.x1 - s->t.x0, 1.0f);
    ctex_tex tmp = {0};
    float pxw, pxh;
    make_projection(c, s->hnode, &tmp, false, &pxw, &pxh);
    return (float)s->t.w / fmaxf(pxw, 1.0f);
}

/* Whether every corner of bounds b projects into texture t: then so does
 * every surface point of its node, from any view. */
static bool corners_inside(const ctex_tex *t, bounds3 b)
{
    for (int i = 0; i < 8; i++) {
        float u, v;
        if (!ctex_tex_project(t, b3_corner(b, i), &u, &v) || !ctex_tex_covers(t, u, v)) return false;
    }
    return true;
}

/* Whether camera-local texture s may stay on the projector it was made for
 * in the current view. The projector is the camera of an earlier view: its
 * texels lie on the surface points that view's samples were splatted at,
 * which is exact for every point that view saw, where resampling through a
 * mid-depth plane (below) moves every point off that plane by the parallax;
 * so keeping it loses nothing while
 * - it still covers what the current view shows of the node: the node's
 *   whole bounding box projects into it (the node was on screen whole when
 *   it was made), or else the corners of the node's new rectangle, taken to
 *   the old texture as resampling would take them, fall within it;
 * - at least half of its area shows the node's part in the new view, and
 *   its texel density on screen stays within twice the §3.6 bound;
 * - the direction from which the node is seen turned by at most keep_deg
 *   (further, the old projector meets the node's surfaces at a slant the
 *   new view does not, and what it hid, the new view may show).
 * Camera changes then cost neither resampling nor re-sending the texture.
 * On success the size bounds are those of the new view. */
static bool keep_projector(ctex *c, slot *s)
{
    const ctex_tex *t = &s->t;
    if (!(c->o.keep_deg > 0.0f)) return false;
    const ctex_hnode *n = &c->h.nodes[s->hnode];
    vec3 ctr = b3_center(n->bounds), a = v3_sub(ctr, t->cam.eye), b = v3_sub(ctr, c->cam.eye);
    float la = v3_len(a), lb = v3_len(b);
    if (!(la > 0.0f && lb > 0.0f) || v3_dot(a, b) < la * lb * cosf(c->o.keep_deg * (CT_PI / 180.0f))) return false;
    ctex_tex nt = {0};
    float pxw, pxh;
    make_projection(c, s->hnode, &nt, false, &pxw, &pxh);
    if (nt.kind != CTEX_PROJ_CAMERA) return false;
    /* the new rectangle's corners in the old texture (the extent on screen,
     * and the coverage test of a node that was not on screen whole) */
    float u0 = INFINITY, v0 = INFINITY, u1 = -INFINITY, v1 = -INFINITY;
    for (int k = 0; k < 4; k++) {
        float u, v;
        if (!ctex_tex_project(t, ctex_tex_unproject(&nt, (float)(k & 1), (float)(k >> 1)), &u, &v)) return false;
        u0 = fminf(u0, u); u1 = fmaxf(u1, u);
        v0 = fminf(v0, v); v1 = fmaxf(v1, v);
    }
    if (!corners_inside(t, n->bounds) && !(ctex_tex_covers(t, u0, v0) && ctex_tex_covers(t, u1, v1))) return false;
    /* most of its texels still in view (else a smaller texture of the new
     * rectangle serves with fewer texels to keep and to send) */
    if ((fminf(u1, 1.0f) - fmaxf(u0, 0.0f)) * (fminf(v1, 1.0f) - fmaxf(v0, 0.0f)) < 0.5f) return false;
    /* the whole old domain in pixels of the new view */
    float fw = fmaxf(pxw, 1.0f) / fmaxf(u1 - u0, 1e-6f), fh = fmaxf(pxh, 1.0f) / fmaxf(v1 - v0, 1e-6f);
    if ((float)t->w > 2.0f * c->o.tex_rate * fw || (float)t->h > 2.0f * c->o.tex_rate * fh) return false;
    size_bounds(c, fw, fh, &s->max_w, &s->max_h);
    return true;
}

/* Gives a texture the projection of the current view: object-local ones
 * keep theirs (only the size bounds may shrink them); a camera-local one
 * keeps its projector while that serves (keep_projector), else gets the
 * current view's and its contents carried over (reprojection through its
 * mid-depth plane). *moved: whether the projection changed. */
static int reproject(ctex *c, uint32_t id, bool *moved, ct_error *err)
{
    slot *s = &c->slots[id];
    *moved = false;
    if (s->t.kind == CTEX_PROJ_CAMERA && s->t.cam_w == c->W && s->t.cam_h == c->H &&
        cam_same(&s->t.cam, &c->cam))
        return CT_OK;   /* same view: same projection */
    if (s->t.kind == CTEX_PROJ_CAMERA && keep_projector(c, s)) {
        c->st.kept++;
        return CT_OK;
    }
    ctex_tex old = s->t;
    ctex_tex *t = &s->t;
    float pxw, pxh;
    /* a camera-local texture the camera's move did not let keep its
     * projector: the camera is moving, so the new one gets a margin */
    make_projection(c, s->hnode, t, old.kind == CTEX_PROJ_CAMERA && c->o.keep_deg > 0.0f, &pxw, &pxh);
    size_bounds(c, pxw, pxh, &s->max_w, &s->max_h);
    if (t->kind == CTEX_PROJ_OBJECT && old.kind == CTEX_PROJ_OBJECT) {
        /* glued to the object: nothing moves; only the bounds may shrink it */
        if (t->w > s->max_w || t->h > s->max_h) {
            *moved = true;
            int nw = t->w > s->max_w ? s->max_w : t->w, nh = t->h > s->max_h ? s->max_h : t->h;
            const int ow = t->w, oh = t->h;
            size_t ob = ctex_tex_bytes(t->w, t->h);
            int rc = ctex_tex_resize(t, nw, nh, err);
            if (rc) return rc;
            c->bytes = c->bytes - ob + ctex_tex_bytes(nw, nh);
            c->st.resizes++;
            if (s->active) ctex_ev_resized(c, id, ow, oh);
        }
        return CT_OK;
    }
    /* keep the texel density; stay within the bounds */
    float rate = (float)old.w / fmaxf(old.x1 - old.x0, 1.0f);
    if (old.kind == CTEX_PROJ_OBJECT) rate = (float)old.w / fmaxf(pxw, 1.0f);
    int w, h;
    aspect_size(c, pxw, pxh, fmaxf(pxw, pxh) * rate, s->max_w, s->max_h, &w, &h);
    size_t ob = ctex_tex_bytes(old.w, old.h);
    c->bytes -= ob;
    if (!ctex_make_room(c, ctex_tex_bytes(w, h))) aspect_size(c, pxw, pxh, (float)c->o.tex_min, s->max_w, s->max_h, &w, &h);
    t->tx = NULL;
    int rc = ctex_tex_init(t, w, h, err);
    if (rc) {
        t->tx = old.tx; t->w = old.w; t->h = old.h; t->pitch = old.pitch;
        c->bytes += ob;
        return rc;
    }
    t->vmax = old.vmax;
    t->mean_r = old.mean_r;
    t->sum_r = old.sum_r;
    t->n_sum = old.n_sum;
    t->since_resize = old.since_resize;
    const ctex_tex *src[1] = {&old};
    ctex_tex_resample(t, src, 1, 0.0f);
    *moved = true;
    c->st.resampled++;
    ctex_mem_put(old.mem, old.tx, ctex_tex_bytes(old.w, old.h));
    c->bytes += ctex_tex_bytes(w, h);
    if (s->active && (w != old.w || h != old.h)) ctex_ev_alloc(c, id);
    return CT_OK;
}

/* A new texture for node n in the current view, resampled from the live
 * textures of its ancestors and descendants (split or merge). */
static int create_texture(ctex *c, uint32_t n, ct_error *err)
{
    int32_t id = new_slot(c, err);
    if (id < 0) return id;
    slot *s = &c->slots[id];
    s->hnode = n;
    s->mix = c->o.mix + (1.0f - c->o.mix) * c->h.nodes[n].gloss;
    float pxw, pxh;
    make_projection(c, n, &s->t, false, &pxw, &pxh);
    size_bounds(c, pxw, pxh, &s->max_w, &s->max_h);
    /* sources: ancestors and descendants with live textures */
    int ns = 0;
    for (int32_t a = c->h.nodes[n].parent; a >= 0; a = c->h.nodes[a].parent)
        if (c->node_tex[a] >= 0) c->srcs[ns++] = c->node_tex[a];
    for (uint32_t d = n + 1; d < c->h.nodes[n].end; d++)
        if (c->node_tex[d] >= 0) c->srcs[ns++] = c->node_tex[d];
    /* start at the sources' density, else coarse (§3.6) */
    float longer = (float)c->o.tex_init;
    float rate = 0.0f;
    for (int i = 0; i < ns; i++) rate = fmaxf(rate, tex_rate_now(c, &c->slots[c->srcs[i]]));
    if (rate > 0.0f) longer = fmaxf((float)c->o.tex_min, fmaxf(pxw, pxh) * rate);
    for (int i = 0; i < ns; i++) c->retire[c->srcs[i]] = 1;
    int w, h;
    aspect_size(c, pxw, pxh, longer, s->max_w, s->max_h, &w, &h);
    if (!ctex_make_room(c, ctex_tex_bytes(w, h))) aspect_size(c, pxw, pxh, (float)c->o.tex_min, s->max_w, s->max_h, &w, &h);
    s->t.d.clock = &c->now_us;
    s->t.mem = c->mem;
    int rc = ctex_tex_init(&s->t, w, h, err);
    if (rc) return rc;
    c->bytes += ctex_tex_bytes(w, h);
    s->live = 1;
    s->active = 1;
    s->last_epoch = c->epoch;
    s->last_eye = c->cam.eye;
    c->node_tex[n] = id;
    if (ns > 0) {
        /* more than 64 related textures is rare: the first 64 are used */
        const ctex_tex *src[64];
        int k = ns < 64 ? ns : 64;
        for (int i = 0; i < k; i++) src[i] = &c->slots[c->srcs[i]].t;
        ctex_tex_resample(&s->t, src, k, c->o.resample_age);
        c->st.resampled++;
    }
    ctex_ev_alloc(c, (uint32_t)id);
    ctex_ev_proj(c, (uint32_t)id);
    return CT_OK;
}

int ctex_set_camera(ctex *c, const ct_camera *cam, int width, int height, ct_error *err)
{
    if (width < 1 || height < 1 || width > 65536 || height > 65536)
        return ct_fail(err, CT_EINVAL, "image size %dx%d out of range", width, height);
    if (!v3_finite(cam->eye) || !cam_fov_valid(cam->fov_y))
        return ct_fail(err, CT_EINVAL, "camera has a non-finite eye or a bad field of view");
    int had = c->have_cam;
    c->cam = *cam;
    c->W = width;
    c->H = height;
    cam_rays_init(&c->rays, cam, width, height);
    c->fpx = 0.5f * (float)height / c->rays.th;
    c->have_cam = 1;
    c->epoch++;
    (void)had;

    /* 1. the new assignment */
    memset(c->assigned, 0, c->h.nnodes);
    c->nlist = 0;
    const ctex_hnode *root = &c->h.nodes[0];
    if (root->end == 1) visit(c, 0);
    else
        for (uint32_t ch = 1; ch < root->end; ch = c->h.nodes[ch].end) visit(c, ch);

    /* 2. old active textures: kept, parked (culled) or retired (split/merge) */
    int rc = CT_OK;
    for (uint32_t i = 0; i < c->nslots; i++) c->retire[i] = 0;
    for (uint32_t i = 0; i < c->nslots; i++) {
        slot *s = &c->slots[i];
        if (!s->live || !s->active) continue;
        uint32_t n = s->hnode;
        if (c->assigned[n]) {
            /* §3.5 aging, then the new projection (camera-local: reprojected) */
            age(c, s);
            bool moved;
            rc = reproject(c, i, &moved, err);
            if (rc) return rc;
            s->last_epoch = c->epoch;
            s->last_eye = c->cam.eye;
            if (moved && s->t.kind == CTEX_PROJ_CAMERA) ctex_ev_proj(c, i);   /* object-local: unchanged */
            continue;
        }
        int related = 0;
        for (int32_t a = c->h.nodes[n].parent; a >= 0 && !related; a = c->h.nodes[a].parent)
            related = c->assigned[a];
        for (uint32_t d = n + 1; d < c->h.nodes[n].end && !related; d++) related = c->assigned[d];
        if (!related) {
            /* culled: park it, invisible to the display, evictable */
            ctex_ev_push(c, CTEX_EV_FREE, i);
            s->active = 0;
        }
        /* else a source of the split/merge below, retired afterwards */
    }

    /* 3. new assignments: reuse a parked texture or create a resampled one */
    for (uint32_t k = 0; k < c->nlist; k++) {
        uint32_t n = c->list[k];
        int32_t id = c->node_tex[n];
        if (id >= 0 && c->slots[id].active) continue;   /* kept */
        if (id >= 0) {
            slot *s = &c->slots[id];
            age(c, s);
            bool moved;
            rc = reproject(c, (uint32_t)id, &moved, err);
            if (rc) return rc;
            s->active = 1;
            s->last_epoch = c->epoch;
            s->last_eye = c->cam.eye;
            ctex_dirty_mark_all(&s->t.d);   /* the display gets it anew */
            ctex_ev_alloc(c, (uint32_t)id);
            ctex_ev_proj(c, (uint32_t)id);
            continue;
        }
        rc = create_texture(c, n, err);
        if (rc) return rc;
    }

    /* 4. retire the sources of splits and merges */
    for (uint32_t i = 0; i < c->nslots; i++)
        if (c->retire[i]) {
            c->retire[i] = 0;
            if (c->slots[i].live && !c->assigned[c->slots[i].hnode]) ctex_destroy_slot(c, i);
        }
    /* active textures whose node is no longer assigned and that were not
     * consumed (e.g. a related node was culled after all) */
    for (uint32_t i = 0; i < c->nslots; i++) {
        slot *s = &c->slots[i];
        if (s->live && s->active && !c->assigned[s->hnode]) ctex_destroy_slot(c, i);
    }

    /* 5. owners of the leaves */
    for (uint32_t l = 0; l < c->h.nleaves; l++) c->leaf_owner[l] = -1;
    for (uint32_t k = 0; k < c->nlist; k++) {
        uint32_t n = c->list[k];
        int32_t id = c->node_tex[n];
        for (uint32_t l = c->h.nodes[n].leaf_begin; l < c->h.nodes[n].leaf_end; l++) c->leaf_owner[l] = id;
    }
    /* 6. the memory cap */
    ctex_make_room(c, 0);
    return CT_OK;
}

