/* ctex.c: the corrective-texture engine (ctex.h): options, per-view texture
 * assignment (§3.3) with projections (§3.2) and aging (§3.5), sample
 * insertion (§3.4) with adaptive resolution (§3.6) under a memory cap, the
 * display event list and the software compositor. */
#include "master/ctex.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "master/ctex_hier.h"
#include "master/ctex_tex.h"

typedef struct slot {
    ctex_tex t;
    int live;          /* holds texels */
    int active;        /* assigned in the current view (the display has it) */
    uint32_t hnode;
    uint32_t last_epoch;
    vec3 last_eye;     /* eye of the last view it was active in (§3.5) */
    int max_w, max_h;  /* §3.6 resolution bounds in the current view */
    /* Mixing weight of a new sample (docs/textures.md, "Mixing"): mirrors
     * and sharp lobes carry detail (reflected images) in their corrections,
     * diffuse surfaces mostly noise, so the glossier the less mixing. */
    float mix;
} slot;

struct ctex {
    ctex_options o;
    ctex_hier h;
    slot *slots;
    uint32_t nslots, cap_slots;
    int32_t *node_tex;     /* hierarchy node -> live slot, -1 */
    int32_t *leaf_owner;   /* leaf -> active slot, -1 */
    uint8_t *assigned;     /* hierarchy node -> assigned in the current view */
    char *names;           /* the mesh's node names (SCENE_NAME_LEN each) */
    uint32_t *list;        /* scratch: assigned nodes */
    uint32_t nlist;
    int32_t *srcs;         /* scratch: source slots */
    uint8_t *retire;       /* slot -> destroy at the end of set_camera */
    ctex_event *ev;
    size_t nev, cap_ev;
    int have_cam;
    ct_camera cam;
    int W, H;
    float tw, th, fpx;     /* tan half-angles and focal length in pixels */
    vec3 right, up, fwd;
    float znear;
    uint32_t epoch;
    size_t bytes;
    ctex_stats st;
    uint64_t now_us;       /* stamped on texel changes (ctex_set_clock) */
};

/* --- options ------------------------------------------------------------------ */

ctex_options ctex_options_default(void)
{
    ctex_options o;
    o.eps = 0.3f;            /* §3.3: ε = 0.3 (0.2-0.5 hardly visible) */
    o.max_proj = 0.5f;
    o.flat_deg = 10.0f;      /* §3.2: flat when normals deviate less than 10° */
    o.flat_thickness = 0.01f;
    o.blend = 1.0f;
    o.mix = 0.5f;            /* noise-aware splatting (docs/textures.md, "Mixing") */
    o.mix_radius = 16.0f;
    o.splat_max = 64;
    o.splat_aniso = 1;
    o.splat_lo = 1.0f;
    o.splat_hi = 5.0f;
    o.splat_window = 64;
    o.tex_min = 4;           /* §3.6: minimum 4x4 */
    o.tex_init = 16;
    o.tex_rate = 2.0f;       /* §3.6: at most twice the screen sampling rate */
    o.tex_max = 4096;
    o.mem_mb = 512.0;
    o.age_flow = 1.0f;
    o.age_brdf = 10.0f;
    o.resample_age = 1.0f;
    o.bvh_mat_weight = 1.0f;
    o.cluster_tris = 4096;
    return o;
}

typedef struct optdef {
    const char *flag;
    int type;      /* 0 float, 1 int, 2 double */
    size_t off;
    double lo, hi;
    const char *help;
} optdef;

#define OF(f) offsetof(ctex_options, f)
static const optdef OPTS[] = {
    {"--eps", 0, OF(eps), 0, 1e9, "parallax threshold Δr/d for one texture per node (§3.3)"},
    {"--max-proj", 0, OF(max_proj), 0, 1e9, "split nodes larger than this fraction of the screen; 0 = off (§3.3)"},
    {"--flat-deg", 0, OF(flat_deg), 0, 180, "normal spread (degrees) under which a node is flat: object-local (§3.2)"},
    {"--flat-thickness", 0, OF(flat_thickness), 0, 1e9, "flat nodes' extent along the normal / in-plane extent"},
    {"--blend", 0, OF(blend), 0, 1e6, "validity band (texels) blended at splat borders; 0 = off (§3.4)"},
    {"--mix", 0, OF(mix), 0.01, 1, "weight of a new sample against the correction it lands on (noise-aware splatting); 1 = off: each texel holds its nearest sample"},
    {"--mix-radius", 0, OF(mix_radius), 0, 1e6, "mix only with a correction whose sample lies within this many texels (validity below v_max)"},
    {"--splat-max", 1, OF(splat_max), 0, 65536, "largest splat radius (texels), bounds the cost of a sample in an empty region; 0 = none"},
    {"--splat-aniso", 1, OF(splat_aniso), 0, 1, "1: splat rings measured on screen (texels seen at a slant get elongated rings); 0: square rings in texels"},
    {"--splat-lo", 0, OF(splat_lo), 0, 1e6, "mean splat radius (texels) under which the resolution doubles (§3.6)"},
    {"--splat-hi", 0, OF(splat_hi), 0, 1e6, "mean splat radius (texels) over which the resolution halves (§3.6)"},
    {"--splat-window", 1, OF(splat_window), 1, 1e6, "samples in the running mean of splat radii (§3.6)"},
    {"--tex-min", 1, OF(tex_min), 1, 65536, "minimum texture size per axis (§3.6)"},
    {"--tex-init", 1, OF(tex_init), 1, 65536, "size of a new texture along its longer axis"},
    {"--tex-rate", 0, OF(tex_rate), 0.01, 64, "maximum texels per screen pixel per axis (§3.6)"},
    {"--tex-max", 1, OF(tex_max), 1, 65536, "maximum texture size per axis"},
    {"--tex-mem-mb", 2, OF(mem_mb), 1, 1e7, "memory cap for all texels, MiB (invisible textures evicted first)"},
    {"--age-flow", 0, OF(age_flow), 0, 1e9, "aging weight of camera-local texture flow (§3.5)"},
    {"--age-brdf", 0, OF(age_brdf), 0, 1e9, "aging weight of BRDF change: texture sizes per radian at glossiness 1 (§3.5)"},
    {"--resample-age", 0, OF(resample_age), 0, 1e9, "validity (texels) a resampled texel loses to fresh samples"},
    {"--bvh-mat-weight", 0, OF(bvh_mat_weight), 0, 1e9, "BVH cost factor for groups mixing materials (§3.3)"},
    {"--cluster-tris", 1, OF(cluster_tris), 0, 1e9, "parts with more triangles are split into clusters: one per face, curved ones into at most this many; 0 = never"},
};
#undef OF

int ctex_options_parse(ctex_options *o, const char *flag, const char *value, ct_error *err)
{
    for (size_t i = 0; i < sizeof OPTS / sizeof OPTS[0]; i++) {
        if (strcmp(flag, OPTS[i].flag) != 0) continue;
        if (!value) return ct_fail(err, CT_EINVAL, "%s needs a value", flag);
        char *end;
        errno = 0;
        double d = strtod(value, &end);
        if (errno || end == value || *end || !(d >= OPTS[i].lo && d <= OPTS[i].hi))
            return ct_fail(err, CT_EINVAL, "%s: '%s' is not a number in [%g, %g]", flag, value,
                           OPTS[i].lo, OPTS[i].hi);
        char *p = (char *)o + OPTS[i].off;
        if (OPTS[i].type == 0) *(float *)(void *)p = (float)d;
        else if (OPTS[i].type == 1) {
            if (d != (double)(int)d) return ct_fail(err, CT_EINVAL, "%s: '%s' is not an integer", flag, value);
            *(int *)(void *)p = (int)d;
        } else *(double *)(void *)p = d;
        return 1;
    }
    return 0;
}

void ctex_options_help(FILE *f)
{
    ctex_options d = ctex_options_default();
    for (size_t i = 0; i < sizeof OPTS / sizeof OPTS[0]; i++) {
        const char *p = (const char *)&d + OPTS[i].off;
        char val[32];
        if (OPTS[i].type == 0) snprintf(val, sizeof val, "%g", (double)*(const float *)(const void *)p);
        else if (OPTS[i].type == 1) snprintf(val, sizeof val, "%d", *(const int *)(const void *)p);
        else snprintf(val, sizeof val, "%g", *(const double *)(const void *)p);
        char flag[48];
        snprintf(flag, sizeof flag, "%s %s", OPTS[i].flag, OPTS[i].type == 1 ? "N" : "X");
        fprintf(f, "  %-30s %s (default %s)\n", flag, OPTS[i].help, val);
    }
}

/* --- events ------------------------------------------------------------------------ */

static ctex_event *push_event(ctex *c, ctex_event_kind kind, uint32_t tex)
{
    if (c->nev == c->cap_ev) {
        size_t nc = c->cap_ev ? 2 * c->cap_ev : 64;
        ctex_event *ne = realloc(c->ev, nc * sizeof *ne);
        if (!ne) return NULL;   /* the event is lost; the next full patch repairs contents */
        c->ev = ne;
        c->cap_ev = nc;
    }
    ctex_event *e = &c->ev[c->nev++];
    memset(e, 0, sizeof *e);
    e->kind = kind;
    e->tex = tex;
    return e;
}

static void ev_alloc(ctex *c, uint32_t id)
{
    slot *s = &c->slots[id];
    ctex_event *e = push_event(c, CTEX_EV_ALLOC, id);
    if (e) {
        e->node = s->hnode; e->proj = s->t.kind; e->w = s->t.w; e->h = s->t.h;
    }
}

static void ev_proj(ctex *c, uint32_t id)
{
    ctex_event *e = push_event(c, CTEX_EV_PROJ, id);
    if (e) e->m = c->slots[id].t.m;
}

void ctex_set_clock(ctex *c, uint64_t now_us)
{
    c->now_us = now_us;
}

void ctex_dirty_all(ctex *c)
{
    /* Stamps and counts start over: lag is measured for this display. */
    for (uint32_t i = 0; i < c->nslots; i++)
        if (c->slots[i].live && c->slots[i].active) {
            ctex_dirty_clear_all(&c->slots[i].t.d);
            ctex_dirty_mark_all(&c->slots[i].t.d);
        }
}

uint32_t ctex_slot_count(const ctex *c)
{
    return c->nslots;
}

ctex_tex *ctex_visible_texture(ctex *c, uint32_t id)
{
    if (id >= c->nslots || !c->slots[id].live || !c->slots[id].active) return NULL;
    return &c->slots[id].t;
}

const ctex_event *ctex_events(const ctex *c, size_t *n)
{
    *n = c->nev;
    return c->ev;
}

void ctex_events_clear(ctex *c)
{
    c->nev = 0;
}

/* The live texture tex when the patch rectangle lies inside it, else NULL
 * (err says why). */
static const ctex_tex *patch_texture(const ctex *c, uint32_t tex, int x, int y, int w, int h, ct_error *err)
{
    if (tex >= c->nslots || !c->slots[tex].live) {
        ct_fail(err, CT_ERANGE, "texture %u is not live", tex);
        return NULL;
    }
    const ctex_tex *t = &c->slots[tex].t;
    if (x < 0 || y < 0 || w < 0 || h < 0 || x + w > t->w || y + h > t->h) {
        ct_fail(err, CT_ERANGE, "patch %dx%d+%d+%d outside texture %u of %dx%d", w, h, x, y, tex, t->w, t->h);
        return NULL;
    }
    return t;
}

int ctex_read_patch(const ctex *c, uint32_t tex, int x, int y, int w, int h, float *out,
                    ct_error *err)
{
    const ctex_tex *t = patch_texture(c, tex, x, y, w, h, err);
    if (!t) return CT_ERANGE;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            vec3 v = ctex_texel_rgb(ctex_tex_at(t, x + i, y + j));
            float *o = out + 3 * ((size_t)j * (size_t)w + (size_t)i);
            o[0] = v.x; o[1] = v.y; o[2] = v.z;
        }
    return CT_OK;
}


const uint32_t *ctex_node_parts(const ctex *c, uint32_t hnode, uint32_t *n)
{
    if (hnode >= c->h.nnodes) {
        *n = 0;
        return NULL;
    }
    const ctex_hnode *hn = &c->h.nodes[hnode];
    *n = hn->leaf_end - hn->leaf_begin;
    return c->h.leaf_part + hn->leaf_begin;
}

void ctex_export_nodes(const ctex *c, rmesh_node *out)
{
    for (uint32_t i = 0; i < c->h.nnodes; i++) {
        const ctex_hnode *n = &c->h.nodes[i];
        rmesh_node *o = &out[i];
        memset(o, 0, sizeof *o);
        if (n->scene_node >= 0 && (uint32_t)n->scene_node < c->h.npart_map && c->names)
            snprintf(o->name, sizeof o->name, "%s", c->names + (size_t)n->scene_node * SCENE_NAME_LEN);
        else if (c->h.part_leaf[c->h.leaf_part[n->leaf_begin]] == -2 &&
                 c->h.leaf_part[n->leaf_begin] == c->h.leaf_part[n->leaf_end - 1])
            snprintf(o->name, sizeof o->name, "cluster:%u", i);   /* inside a split part */
        else
            snprintf(o->name, sizeof o->name, "bvh:%u", i);
        o->parent = n->parent;
        o->node_end = n->end;
        o->material = n->material;
        o->bounds = n->bounds;
    }
}

int ctex_display_mesh(const ctex *c, const ct_radmesh *mesh, ct_radmesh *out, ct_error *err)
{
    memset(out, 0, sizeof *out);
    if (mesh->ntris != c->h.ntris)
        return ct_fail(err, CT_EINVAL, "display mesh: %u triangles, the texture hierarchy has %u", mesh->ntris,
                       c->h.ntris);
    rmesh_node *nodes = malloc((c->h.nnodes ? c->h.nnodes : 1) * sizeof *nodes);
    uint32_t *tri_node = malloc((mesh->ntris ? mesh->ntris : 1) * sizeof *tri_node);
    if (!nodes || !tri_node) {
        free(nodes);
        free(tri_node);
        return ct_fail(err, CT_ENOMEM, "out of memory for the display's node table (%u nodes, %u triangles)",
                       c->h.nnodes, mesh->ntris);
    }
    ctex_export_nodes(c, nodes);
    /* (Every triangle lies in a leaf; the root only guards the range.) */
    for (uint32_t t = 0; t < mesh->ntris; t++) {
        uint32_t h = ctex_hnode_of_tri(c, t);
        tri_node[t] = h < c->h.nnodes ? h : 0;
    }
    *out = *mesh;
    out->nnodes = c->h.nnodes;
    out->nodes = nodes;
    out->tri_node = tri_node;
    return CT_OK;
}

void ctex_display_mesh_free(ct_radmesh *out)
{
    free(out->nodes);
    free(out->tri_node);
    memset(out, 0, sizeof *out);
}

uint32_t ctex_hnode_of_part(const ctex *c, uint32_t part)
{
    if (part >= c->h.npart_map || c->h.part_hnode[part] < 0) return UINT32_MAX;
    return (uint32_t)c->h.part_hnode[part];
}

uint32_t ctex_hnode_of_tri(const ctex *c, uint32_t tri)
{
    if (tri >= c->h.ntris) return UINT32_MAX;
    return c->h.leaf_node[c->h.tri_leaf[tri]];
}

/* --- lifecycle ------------------------------------------------------------------------ */

int ctex_new(const ct_radmesh *mesh, const scene_material *mats, uint32_t nmats,
             const ctex_options *opt, ctex **out, ct_error *err)
{
    *out = NULL;
    ctex *c = calloc(1, sizeof *c);
    if (!c) return ct_fail(err, CT_ENOMEM, "out of memory for the texture engine");
    c->o = opt ? *opt : ctex_options_default();
    if (c->o.tex_min > c->o.tex_max) c->o.tex_min = c->o.tex_max;
    if (c->o.tex_init < c->o.tex_min) c->o.tex_init = c->o.tex_min;
    int rc = ctex_hier_build(mesh, mats, nmats, c->o.flat_deg, c->o.flat_thickness, c->o.bvh_mat_weight,
                             (uint32_t)c->o.cluster_tris, &c->h, err);
    if (rc) {
        free(c);
        return rc;
    }
    uint32_t N = c->h.nnodes;
    c->node_tex = malloc(N * sizeof *c->node_tex);
    c->leaf_owner = malloc((c->h.nleaves ? c->h.nleaves : 1) * sizeof *c->leaf_owner);
    c->assigned = calloc(N, 1);
    c->list = malloc(N * sizeof *c->list);
    c->names = malloc((size_t)mesh->nnodes * SCENE_NAME_LEN);
    if (!c->node_tex || !c->leaf_owner || !c->assigned || !c->list || !c->names) {
        ctex_free(c);
        return ct_fail(err, CT_ENOMEM, "out of memory for the texture engine");
    }
    for (uint32_t i = 0; i < N; i++) c->node_tex[i] = -1;
    for (uint32_t i = 0; i < mesh->nnodes; i++)
        memcpy(c->names + (size_t)i * SCENE_NAME_LEN, mesh->nodes[i].name, SCENE_NAME_LEN);
    for (uint32_t i = 0; i < c->h.nleaves; i++) c->leaf_owner[i] = -1;
    bounds3 b = c->h.nodes[0].bounds;
    c->znear = 1e-4f * fmaxf(v3_len(b3_extent(b)), 1e-6f);
    c->st.hier_nodes = N;
    c->st.hier_leaves = c->h.nleaves;
    *out = c;
    return CT_OK;
}

void ctex_free(ctex *c)
{
    if (!c) return;
    for (uint32_t i = 0; i < c->nslots; i++) ctex_tex_release(&c->slots[i].t);
    free(c->slots);
    free(c->node_tex);
    free(c->leaf_owner);
    free(c->assigned);
    free(c->list);
    free(c->names);
    free(c->srcs);
    free(c->retire);
    free(c->ev);
    ctex_hier_free(&c->h);
    free(c);
}

/* --- geometry of a view ------------------------------------------------------------ */

/* Per node in the current view: visibility, parallax ratio, pixel rectangle. */
typedef struct nview {
    int visible;
    float zmin, zmax, zc;   /* depths of the bounds (and its centre) along the view */
    float ratio;            /* Δr / d */
    float x0, y0, x1, y1;   /* clipped pixel rectangle */
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
        X[i] = v3_dot(d, c->right); Y[i] = v3_dot(d, c->up); Z[i] = v3_dot(d, c->fwd);
        zmin = fminf(zmin, Z[i]); zmax = fmaxf(zmax, Z[i]);
    }
    (void)P;
    v->zmin = zmin; v->zmax = zmax;
    v->zc = v3_dot(v3_sub(b3_center(n->bounds), c->cam.eye), c->fwd);
    /* frustum culling: all corners outside one plane */
    int out_l = 1, out_r = 1, out_b = 1, out_t = 1;
    for (int i = 0; i < 8; i++) {
        if (X[i] >= -Z[i] * c->tw) out_l = 0;
        if (X[i] <= Z[i] * c->tw) out_r = 0;
        if (Y[i] >= -Z[i] * c->th) out_b = 0;
        if (Y[i] <= Z[i] * c->th) out_t = 0;
    }
    if (zmax < c->znear || out_l || out_r || out_b || out_t) return;
    /* the box clipped by the near plane, projected: its bounding rectangle */
    float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    float zn = c->znear;
#define ADDPT(xx, yy, zz) do { \
        float px_ = 0.5f * (float)c->W * (1.0f + (xx) / ((zz) * c->tw)); \
        float py_ = 0.5f * (float)c->H * (1.0f - (yy) / ((zz) * c->th)); \
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

/* Sets the texture's projection for the current view (§3.2) and returns the
 * pixel extent of its domain (for resolution bounds). */
static void make_projection(ctex *c, uint32_t hnode, ctex_tex *t, float *pxw, float *pxh)
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
    t->x0 = v.x0; t->y0 = v.y0; t->x1 = v.x1; t->y1 = v.y1;
    float zc = v.zc;
    float zlo = fmaxf(v.zmin, c->znear), zhi = fmaxf(v.zmax, zlo);
    t->ref_depth = zc < zlo ? zlo : (zc > zhi ? zhi : zc);
    float W = (float)c->W, H = (float)c->H;
    float dx = t->x1 - t->x0, dy = t->y1 - t->y0;
    /* rows in eye space (x_e, y_e, z_e, 1), camera looking down -z */
    mat4 e = m4_identity();
    float rx[4] = {0.5f * W / c->tw, 0.0f, -0.5f * W + t->x0, 0.0f};
    float ry[4] = {0.0f, -0.5f * H / c->th, -0.5f * H + t->y0, 0.0f};
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

static size_t mem_cap(const ctex *c) { return (size_t)(c->o.mem_mb * 1048576.0); }

static void destroy_slot(ctex *c, uint32_t id)
{
    slot *s = &c->slots[id];
    if (!s->live) return;
    if (s->active) push_event(c, CTEX_EV_FREE, id);
    c->bytes -= ctex_tex_bytes(s->t.w, s->t.h);
    ctex_tex_release(&s->t);
    if (c->node_tex[s->hnode] == (int32_t)id) c->node_tex[s->hnode] = -1;
    s->live = 0;
    s->active = 0;
}

/* Evicts parked textures, least recently visible first, until `need` more
 * bytes fit under the cap; returns whether they fit. */
static int make_room(ctex *c, size_t need)
{
    size_t cap = mem_cap(c);
    while (c->bytes + need > cap) {
        int32_t victim = -1;
        for (uint32_t i = 0; i < c->nslots; i++) {
            slot *s = &c->slots[i];
            if (!s->live || s->active || c->retire[i]) continue;
            if (victim < 0 || s->last_epoch < c->slots[victim].last_epoch) victim = (int32_t)i;
        }
        if (victim < 0) return 0;
        destroy_slot(c, (uint32_t)victim);
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
        /* BRDF change: glossiness x change of the viewing direction */
        float cosang = v3_dot(v3_norm(d0), v3_norm(d1));
        float ang = acosf(fmaxf(-1.0f, fminf(1.0f, cosang)));
        off += c->o.age_brdf * n->gloss * ang * (float)(s->t.w > s->t.h ? s->t.w : s->t.h);
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

/* Texels per screen pixel of a live texture: camera-local over the rectangle
 * it was made for, object-local at the current view. */
static float tex_rate_now(ctex *c, const slot *s)
{
    if (s->t.kind == CTEX_PROJ_CAMERA) return (float)s->t.w / fmaxf(s->t.x1 - s->t.x0, 1.0f);
    ctex_tex tmp = {0};
    float pxw, pxh;
    make_projection(c, s->hnode, &tmp, &pxw, &pxh);
    return (float)s->t.w / fmaxf(pxw, 1.0f);
}

static int same_camera(const ct_camera *a, const ct_camera *b)
{
    return a->eye.x == b->eye.x && a->eye.y == b->eye.y && a->eye.z == b->eye.z &&
           a->orient.w == b->orient.w && a->orient.x == b->orient.x && a->orient.y == b->orient.y &&
           a->orient.z == b->orient.z && a->fov_y == b->fov_y;
}

/* Recomputes the projection of a camera-local texture for the current view
 * and carries its contents over (reprojection through its mid-depth plane). */
static int reproject(ctex *c, uint32_t id, ct_error *err)
{
    slot *s = &c->slots[id];
    if (s->t.kind == CTEX_PROJ_CAMERA && s->t.cam_w == c->W && s->t.cam_h == c->H &&
        same_camera(&s->t.cam, &c->cam))
        return CT_OK;   /* same view: same projection */
    ctex_tex old = s->t;
    ctex_tex *t = &s->t;
    float pxw, pxh;
    make_projection(c, s->hnode, t, &pxw, &pxh);
    size_bounds(c, pxw, pxh, &s->max_w, &s->max_h);
    if (t->kind == CTEX_PROJ_OBJECT && old.kind == CTEX_PROJ_OBJECT) {
        /* glued to the object: nothing moves; only the bounds may shrink it */
        if (t->w > s->max_w || t->h > s->max_h) {
            int nw = t->w > s->max_w ? s->max_w : t->w, nh = t->h > s->max_h ? s->max_h : t->h;
            size_t ob = ctex_tex_bytes(t->w, t->h);
            int rc = ctex_tex_resize(t, nw, nh, err);
            if (rc) return rc;
            c->bytes = c->bytes - ob + ctex_tex_bytes(nw, nh);
            c->st.resizes++;
            if (s->active) ev_alloc(c, id);
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
    if (!make_room(c, ctex_tex_bytes(w, h))) aspect_size(c, pxw, pxh, (float)c->o.tex_min, s->max_w, s->max_h, &w, &h);
    t->tx = NULL;
    int rc = ctex_tex_init(t, w, h, err);
    if (rc) {
        t->tx = old.tx; t->w = old.w; t->h = old.h; t->pitch = old.pitch;
        c->bytes += ob;
        return rc;
    }
    t->vmax = old.vmax;
    t->mean_r = old.mean_r;
    t->since_resize = old.since_resize;
    const ctex_tex *src[1] = {&old};
    ctex_tex_resample(t, src, 1, 0.0f);
    free(old.tx);
    c->bytes += ctex_tex_bytes(w, h);
    if (s->active && (w != old.w || h != old.h)) ev_alloc(c, id);
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
    make_projection(c, n, &s->t, &pxw, &pxh);
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
    if (!make_room(c, ctex_tex_bytes(w, h))) aspect_size(c, pxw, pxh, (float)c->o.tex_min, s->max_w, s->max_h, &w, &h);
    s->t.d.clock = &c->now_us;
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
    }
    ev_alloc(c, (uint32_t)id);
    ev_proj(c, (uint32_t)id);
    return CT_OK;
}

int ctex_set_camera(ctex *c, const ct_camera *cam, int width, int height, ct_error *err)
{
    if (width < 1 || height < 1 || width > 65536 || height > 65536)
        return ct_fail(err, CT_EINVAL, "image size %dx%d out of range", width, height);
    if (!v3_finite(cam->eye) || !(cam->fov_y > 0.0f && cam->fov_y < CT_PI))
        return ct_fail(err, CT_EINVAL, "camera has a non-finite eye or a bad field of view");
    int had = c->have_cam;
    c->cam = *cam;
    c->W = width;
    c->H = height;
    c->th = tanf(0.5f * cam->fov_y);
    c->tw = c->th * (float)width / (float)height;
    c->fpx = 0.5f * (float)height / c->th;
    cam_axes(cam, &c->right, &c->up, &c->fwd);
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
            ctex_tex_age(&s->t, age_offset(c, s, s->last_eye));
            rc = reproject(c, i, err);
            if (rc) return rc;
            s->last_epoch = c->epoch;
            s->last_eye = c->cam.eye;
            if (s->t.kind == CTEX_PROJ_CAMERA) ev_proj(c, i);   /* object-local: unchanged */
            continue;
        }
        int related = 0;
        for (int32_t a = c->h.nodes[n].parent; a >= 0 && !related; a = c->h.nodes[a].parent)
            related = c->assigned[a];
        for (uint32_t d = n + 1; d < c->h.nodes[n].end && !related; d++) related = c->assigned[d];
        if (!related) {
            /* culled: park it, invisible to the display, evictable */
            push_event(c, CTEX_EV_FREE, i);
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
            ctex_tex_age(&s->t, age_offset(c, s, s->last_eye));
            rc = reproject(c, (uint32_t)id, err);
            if (rc) return rc;
            s->active = 1;
            s->last_epoch = c->epoch;
            s->last_eye = c->cam.eye;
            ctex_dirty_mark_all(&s->t.d);   /* the display gets it anew */
            ev_alloc(c, (uint32_t)id);
            ev_proj(c, (uint32_t)id);
            continue;
        }
        rc = create_texture(c, n, err);
        if (rc) return rc;
    }

    /* 4. retire the sources of splits and merges */
    for (uint32_t i = 0; i < c->nslots; i++)
        if (c->retire[i]) {
            c->retire[i] = 0;
            if (c->slots[i].live && !c->assigned[c->slots[i].hnode]) destroy_slot(c, i);
        }
    /* active textures whose node is no longer assigned and that were not
     * consumed (e.g. a related node was culled after all) */
    for (uint32_t i = 0; i < c->nslots; i++) {
        slot *s = &c->slots[i];
        if (s->live && s->active && !c->assigned[s->hnode]) destroy_slot(c, i);
    }

    /* 5. owners of the leaves */
    for (uint32_t l = 0; l < c->h.nleaves; l++) c->leaf_owner[l] = -1;
    for (uint32_t k = 0; k < c->nlist; k++) {
        uint32_t n = c->list[k];
        int32_t id = c->node_tex[n];
        for (uint32_t l = c->h.nodes[n].leaf_begin; l < c->h.nodes[n].leaf_end; l++) c->leaf_owner[l] = id;
    }
    /* 6. the memory cap */
    make_room(c, 0);
    return CT_OK;
}

/* --- samples ----------------------------------------------------------------------- */

/* The leaf a hit belongs to: its part's leaf, or for a part split into
 * clusters the leaf of its triangle (or, when the triangle is unknown, the
 * cluster whose bounds are nearest to the hit point). -1 when none. */
static int32_t leaf_of_hit(const ctex *c, uint32_t node, uint32_t tri, vec3 p)
{
    if (node >= c->h.npart_map) return -1;
    int32_t l = c->h.part_leaf[node];
    if (l != -2) return l;
    if (tri < c->h.ntris) {
        uint32_t tl = c->h.tri_leaf[tri];
        if (c->h.leaf_part[tl] == node) return (int32_t)tl;
    }
    const ctex_hnode *pn = &c->h.nodes[c->h.part_hnode[node]];
    int32_t best = -1;
    float bd = INFINITY;
    for (uint32_t k = pn->leaf_begin; k < pn->leaf_end; k++) {
        bounds3 b = c->h.nodes[c->h.leaf_node[k]].bounds;
        vec3 d = v3_max(v3_sub(b.lo, p), v3_max(v3_sub(p, b.hi), v3s(0.0f)));
        float d2 = v3_len2(d);
        if (d2 < bd) { bd = d2; best = (int32_t)k; }
    }
    return best;
}

static inline int32_t owner_of(const ctex *c, uint32_t node, uint32_t tri, vec3 p)
{
    int32_t l = leaf_of_hit(c, node, tri, p);
    return l < 0 ? -1 : c->leaf_owner[l];
}

/* §3.6: the running mean of splat radii decides halving or doubling. */
static void adapt_resolution(ctex *c, uint32_t id, int r)
{
    slot *s = &c->slots[id];
    ctex_tex *t = &s->t;
    uint32_t n = t->since_resize;
    uint32_t win = (uint32_t)c->o.splat_window;
    /* A sample flooding an empty region has a huge radius; clamping it keeps
     * single outliers from halving a texture that is dense elsewhere. */
    float rc = fminf((float)r, 2.0f * c->o.splat_hi);
    t->mean_r += (rc - t->mean_r) / (float)(n < win ? n + 1 : win);
    t->since_resize = n + 1;
    if (t->since_resize < win) return;
    /* hysteresis: reversing the last change needs four windows of evidence */
    int nw = t->w, nh = t->h;
    if (t->mean_r > c->o.splat_hi && (t->w > c->o.tex_min || t->h > c->o.tex_min)) {
        if (t->last_resize > 0 && t->since_resize < 4 * win) return;
        nw = (t->w + 1) / 2; nh = (t->h + 1) / 2;
        if (nw < c->o.tex_min) nw = t->w < c->o.tex_min ? t->w : c->o.tex_min;
        if (nh < c->o.tex_min) nh = t->h < c->o.tex_min ? t->h : c->o.tex_min;
    } else if (t->mean_r < c->o.splat_lo && (t->w < s->max_w || t->h < s->max_h)) {
        if (t->last_resize < 0 && t->since_resize < 4 * win) return;
        /* exact doublings only: an axis that would pass its bound stays */
        nw = 2 * t->w <= s->max_w ? 2 * t->w : t->w;
        nh = 2 * t->h <= s->max_h ? 2 * t->h : t->h;
        size_t grow = ctex_tex_bytes(nw, nh) - ctex_tex_bytes(t->w, t->h);
        if (!make_room(c, grow)) return;   /* the memory cap denies growth */
    } else {
        return;
    }
    if (nw == t->w && nh == t->h) return;
    size_t ob = ctex_tex_bytes(t->w, t->h);
    int dir = nw > t->w || nh > t->h ? 1 : -1;
    ct_debug("ctex", "texture %u: %dx%d -> %dx%d (mean splat radius %.2f over %u samples)", id, t->w, t->h, nw, nh,
             (double)t->mean_r, t->since_resize);
    if (ctex_tex_resize(t, nw, nh, NULL)) return;   /* out of memory: keep the old size */
    c->bytes = c->bytes - ob + ctex_tex_bytes(nw, nh);
    t->last_resize = dir;
    t->mean_r = 0.0f;
    t->since_resize = 0;
    c->st.resizes++;
    ev_alloc(c, id);
}

/* The image of world vector d at e (relative to the eye, depth z > 0) on
 * screen, times z / fpx (the perspective projection's derivative along d,
 * up to a factor that is the same for every d at e): its squared length. */
static inline float screen_len2(const ctex *c, vec3 e, float z, vec3 d)
{
    float dz = v3_dot(d, c->fwd);
    float dx = z * v3_dot(d, c->right) - v3_dot(e, c->right) * dz;
    float dy = z * v3_dot(d, c->up) - v3_dot(e, c->up) * dz;
    return dx * dx + dy * dy;
}

/* ex of ctex_tex_splat_aniso for a sample at p on texture t, after
 * ctex_aniso_ex: sqrt(s_y / s_x) for a texel s_x by s_y pixels on screen
 * there. A camera-local texture lies in the current view's pixels (constant
 * texel size); an object-local one is seen through the perspective at p, so
 * a wall along the view shows its texels stretched towards the vanishing
 * point near the eye and squeezed far away. Compares squared ratios first:
 * most samples splat square rings and need no root. */
static inline float splat_ex(const ctex *c, const ctex_tex *t, vec3 p)
{
    float r4;   /* (s_y / s_x)^2 */
    if (t->kind == CTEX_PROJ_CAMERA) {
        float q = ((t->y1 - t->y0) * (float)t->w) / ((t->x1 - t->x0) * (float)t->h);
        r4 = q * q;
    } else {
        vec3 e = v3_sub(p, c->cam.eye);
        float z = v3_dot(e, c->fwd);
        if (!(z > c->znear)) return 1.0f;
        float lx = screen_len2(c, e, z, v3_scale(t->t, 1.0f / (float)t->w));
        float ly = screen_len2(c, e, z, v3_scale(t->b, 1.0f / (float)t->h));
        r4 = ly / lx;
    }
    const float iso4 = CTEX_ANISO_ISO * CTEX_ANISO_ISO * CTEX_ANISO_ISO * CTEX_ANISO_ISO;
    if (r4 > iso4 && r4 < 1.0f / iso4) return 1.0f;
    return ctex_aniso_ex(sqrtf(sqrtf(r4)));
}

/* ex of a sample's splat as the prefetch stage found it, for the texture
 * (slot and size) it was computed on. */
typedef struct {
    int32_t id;
    int w, h;
    float ex;
} ex_hint;

/* ctex_insert, with ex taken from hint when it was computed on the same
 * texture at the same size (bit for bit what splat_ex gives here). */
/* The texture and texel of a sample, with what is displayed there now and
 * the error against it (§3.7); -1 when it has none (info says dropped). */
static int32_t locate(ctex *c, const ct_sample *s, ctex_insert_info *info, int *pci, int *pcj)
{
    info->tex = -1;
    info->radius = 0;
    info->correction = v3s(0.0f);
    info->error = v3_sub(s->l_hq, s->l_base);
    int32_t id = (s->flags & CT_SAMPLE_HIT) ? owner_of(c, s->node, s->tri, s->hit) : -1;
    float u, v;
    if (id < 0 || !v3_finite(s->l_hq) || !v3_finite(s->l_base) || !v3_finite(s->hit) ||
        !ctex_tex_project(&c->slots[id].t, s->hit, &u, &v)) {
        c->st.dropped++;
        return -1;
    }
    ctex_tex *t = &c->slots[id].t;
    float fx = u * (float)t->w, fy = v * (float)t->h;
    /* a hit more than a texel off the texture belongs to no texel */
    if (!(fx > -1.0f && fy > -1.0f && fx < (float)t->w + 1.0f && fy < (float)t->h + 1.0f)) {
        c->st.dropped++;
        return -1;
    }
    int ci = (int)fx, cj = (int)fy;
    if (fx < 0.0f) ci = 0;
    if (fy < 0.0f) cj = 0;
    if (ci >= t->w) ci = t->w - 1;
    if (cj >= t->h) cj = t->h - 1;
    vec3 corr = ctex_tex_sample(t, u, v);
    info->correction = corr;
    /* §3.7: E = L - (L' + ΔL) against what is displayed now */
    info->error = v3_sub(s->l_hq, v3_add(s->l_base, corr));
    info->tex = id;
    *pci = ci;
    *pcj = cj;
    return id;
}

static int insert_one(ctex *c, const ct_sample *s, ctex_insert_info *info, const ex_hint *hint)
{
    int ci, cj;
    int32_t id = locate(c, s, info, &ci, &cj);
    if (id < 0) return 0;
    ctex_tex *t = &c->slots[id].t;
    vec3 dl = ctex_tex_mix(t, ci, cj, v3_sub(s->l_hq, s->l_base), c->slots[id].mix, c->o.mix_radius);
    float ex = 1.0f;
    if (c->o.splat_aniso)
        ex = hint && hint->id == id && hint->w == t->w && hint->h == t->h ? hint->ex : splat_ex(c, t, s->hit);
    int r = ex == 1.0f ? ctex_tex_splat(t, ci, cj, dl, c->o.blend, c->o.splat_max)
                       : ctex_tex_splat_aniso(t, ci, cj, dl, c->o.blend, c->o.splat_max, ex);
    info->radius = r;
    c->st.inserted++;
    adapt_resolution(c, (uint32_t)id, r);
    return 1;
}

/* Texture position (in texels) of the point the ray through image position
 * (x, y) meets on texture t: a camera-local texture maps rays to positions,
 * an object-local one its plane through the hit p (normal t->n). */
static bool texel_of_ray(const ctex *c, const ctex_tex *t, vec3 p, float x, float y, float *tx, float *ty)
{
    vec3 d = cam_ray_dir(&c->cam, c->W, c->H, x, y);
    vec3 q = v3_add(c->cam.eye, d);
    if (t->kind == CTEX_PROJ_OBJECT) {
        float dn = v3_dot(d, t->n);
        if (!(fabsf(dn) > 1e-6f)) return false;
        q = v3_madd(c->cam.eye, d, v3_dot(v3_sub(p, c->cam.eye), t->n) / dn);
    }
    float u, v;
    if (!ctex_tex_project(t, q, &u, &v)) return false;
    *tx = u * (float)t->w;
    *ty = v * (float)t->h;
    return isfinite(*tx) && isfinite(*ty);
}

int ctex_refine(ctex *c, const ct_sample *s, vec3 dl, ctex_insert_info *info)
{
    int ci, cj;
    int32_t id = locate(c, s, info, &ci, &cj);
    if (id < 0 || !v3_finite(dl)) return 0;
    ctex_tex *t = &c->slots[id].t;
    /* The texels the display reads for this pixel: those whose centres lie
     * in the pixel's footprint on the texture (its corners' rays), within 4
     * texels of the hit's; at least the hit's own. */
    float fx = floorf(s->px), fy = floorf(s->py);
    float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    bool ok = c->have_cam;
    for (int k = 0; k < 4 && ok; k++) {
        float tx, ty;
        ok = texel_of_ray(c, t, s->hit, fx + (float)(k & 1), fy + (float)(k >> 1), &tx, &ty);
        if (!ok) break;
        x0 = fminf(x0, tx); x1 = fmaxf(x1, tx);
        y0 = fminf(y0, ty); y1 = fmaxf(y1, ty);
    }
    int a = ci, b = ci, e = cj, f = cj;
    if (ok) {
        a = (int)ceilf(x0 - 0.5f); b = (int)floorf(x1 - 0.5f);
        e = (int)ceilf(y0 - 0.5f); f = (int)floorf(y1 - 0.5f);
        a = a < ci - 4 ? ci - 4 : (a > ci ? ci : a);
        b = b > ci + 4 ? ci + 4 : (b < ci ? ci : b);
        e = e < cj - 4 ? cj - 4 : (e > cj ? cj : e);
        f = f > cj + 4 ? cj + 4 : (f < cj ? cj : f);
    }
    ctex_tex_refine(t, a < 0 ? 0 : a, e < 0 ? 0 : e, b >= t->w ? t->w - 1 : b, f >= t->h ? t->h - 1 : f, cj, dl);
    c->st.inserted++;
    return 1;
}

int ctex_insert(ctex *c, const ct_sample *s, ctex_insert_info *info)
{
    return insert_one(c, s, info, NULL);
}

/* Prefetches the texel rows a sample will read and splat first: the
 * rectangle of its splat's first two rings (anisotropic rings reach up to
 * 8 rows out, and a rectangle's rows are its cache misses), whose ex it
 * leaves in *hint so that the insertion need not compute it again. Always
 * inlined: a separate function whose only effect is __builtin_prefetch
 * counts as pure for GCC, which then drops the calls (their result is
 * unused) and with them the prefetches. */
static inline __attribute__((always_inline)) void prefetch_sample(const ctex *c, const ct_sample *s, ex_hint *hint)
{
    hint->id = -1;
    int32_t id = (s->flags & CT_SAMPLE_HIT) ? owner_of(c, s->node, s->tri, s->hit) : -1;
    float u, v;
    if (id < 0 || !ctex_tex_project(&c->slots[id].t, s->hit, &u, &v)) return;
    const ctex_tex *t = &c->slots[id].t;
    int ci = (int)(u * (float)t->w), cj = (int)(v * (float)t->h);
    if (ci < 0 || cj < 0 || ci >= t->w || cj >= t->h) return;
    int xk = 2, yk = 2;
    if (c->o.splat_aniso) {
        *hint = (ex_hint){id, t->w, t->h, splat_ex(c, t, s->hit)};
        if (hint->ex != 1.0f) ctex_aniso_ring(hint->ex, 2, &xk, &yk);
    }
    int y0 = cj - yk < 0 ? 0 : cj - yk, y1 = cj + yk >= t->h ? t->h - 1 : cj + yk;
    int x0 = ci - xk < 0 ? 0 : ci - xk, x1 = ci + xk >= t->w ? t->w - 1 : ci + xk;
    for (int j = y0; j <= y1; j++) {
        const ctex_texel *row = ctex_tex_at(t, 0, j);
        __builtin_prefetch(row + x0, 1, 1);
        __builtin_prefetch(row + x1, 1, 1);
    }
}

/* First prefetch stage: the triangle's leaf entry, which the texel address
 * depends on. */
static inline __attribute__((always_inline)) void prefetch_leaf(const ctex *c, const ct_sample *s)
{
    if (s->tri < c->h.ntris) __builtin_prefetch(&c->h.tri_leaf[s->tri], 0, 1);
}

size_t ctex_insert_batch(ctex *c, const ct_sample *s, size_t n, ctex_insert_info *info)
{
    /* two stages ahead: the leaf entries 8 samples ahead, the texel rows 4
     * ahead (their address needs the leaf); hides DRAM latency */
    enum { AHEAD = 4, AHEAD2 = 8 };
    ex_hint hint[2 * AHEAD];   /* sample i's in hint[i % (2 AHEAD)] */
    size_t done = 0;
    for (size_t i = 0; i < n && i < AHEAD2; i++) prefetch_leaf(c, &s[i]);
    for (size_t i = 0; i < n && i < AHEAD; i++) prefetch_sample(c, &s[i], &hint[i % (2 * AHEAD)]);
    for (size_t i = 0; i < n; i++) {
        if (i + AHEAD2 < n) prefetch_leaf(c, &s[i + AHEAD2]);
        if (i + AHEAD < n) prefetch_sample(c, &s[i + AHEAD], &hint[(i + AHEAD) % (2 * AHEAD)]);
        done += (size_t)insert_one(c, &s[i], &info[i], &hint[i % (2 * AHEAD)]);
    }
    return done;
}

vec3 ctex_lookup(const ctex *c, uint32_t node, uint32_t tri, vec3 p)
{
    int32_t id = owner_of(c, node, tri, p);
    float u, v;
    if (id < 0 || !ctex_tex_project(&c->slots[id].t, p, &u, &v)) return v3s(0.0f);
    return ctex_tex_sample(&c->slots[id].t, u, v);
}

/* --- queries ------------------------------------------------------------------------ */

int32_t ctex_owner(const ctex *c, uint32_t node, uint32_t tri, vec3 p)
{
    return owner_of(c, node, tri, p);
}

int ctex_texture_info(const ctex *c, uint32_t tex, uint32_t *hnode, int *w, int *h,
                      ctex_proj_kind *kind, mat4 *m, float *vmax)
{
    if (tex >= c->nslots || !c->slots[tex].live) return -1;
    const slot *s = &c->slots[tex];
    if (hnode) *hnode = s->hnode;
    if (w) *w = s->t.w;
    if (h) *h = s->t.h;
    if (kind) *kind = s->t.kind;
    if (m) *m = s->t.m;
    if (vmax) *vmax = s->t.vmax;
    return s->active ? 1 : 0;
}

float ctex_splat_ex(const ctex *c, uint32_t tex, vec3 p)
{
    if (tex >= c->nslots || !c->slots[tex].live || !c->have_cam) return 1.0f;
    return splat_ex(c, &c->slots[tex].t, p);
}

ctex_stats ctex_get_stats(const ctex *c)
{
    ctex_stats st = c->st;
    st.textures = 0;
    st.parked = 0;
    st.texels = 0;
    double rs = 0.0;
    for (uint32_t i = 0; i < c->nslots; i++) {
        const slot *s = &c->slots[i];
        if (!s->live) continue;
        st.texels += (uint64_t)s->t.w * (uint64_t)s->t.h;
        if (s->active) {
            st.textures++;
            rs += s->t.mean_r;
        } else {
            st.parked++;
        }
    }
    st.bytes = c->bytes;
    st.splat_radius_mean = st.textures ? rs / st.textures : 0.0;
    return st;
}

/* --- compositor ----------------------------------------------------------------------- */

int ctex_composite(const ctex *c, const ctex_hit *hits, int width, int height, ct_image *out,
                   ct_error *err)
{
    if (!out->px || out->width != width || out->height != height)
        return ct_fail(err, CT_EINVAL, "compositor output is not %dx%d", width, height);
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            const ctex_hit *h = &hits[(size_t)y * (size_t)width + (size_t)x];
            vec3 v = h->l_base;
            if (h->node != UINT32_MAX) v = v3_add(v, ctex_lookup(c, h->node, h->tri, h->p));
            img_set(out, x, y, v);
        }
    return CT_OK;
}

vec3 ctex_debug_color(int32_t tex)
{
    if (tex < 0) return v3s(0.0f);
    /* golden-ratio hues, full saturation */
    float hue = fmodf((float)tex * 0.618033988f, 1.0f) * 6.0f;
    float f = hue - floorf(hue);
    int i = (int)hue % 6;
    float q = 1.0f - f;
    switch (i) {
    case 0: return v3(1, f, 0);
    case 1: return v3(q, 1, 0);
    case 2: return v3(0, 1, f);
    case 3: return v3(0, q, 1);
    case 4: return v3(f, 0, 1);
    default: return v3(1, 0, q);
    }
}
