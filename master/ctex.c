/* ctex.c: the corrective-texture engine (ctex.h): its options, the display
 * event list, texel readback and the texture hierarchy as the display's node
 * table, lifecycle, queries and the software compositor. The per-view work
 * is in ctex_view.c, sample insertion in ctex_insert.c. */
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "common/optab.h"
#include "master/ctex_internal.h"
#include "proto/wire.h"

#define OF(f) offsetof(ctex_options, f)
static const optab OPTS[] = {
    /* §3.3: ε = 0.3 (0.2-0.5 hardly visible) */
    {"eps", 0, OPTAB_FLOAT, OF(eps), 0, 1e9, "0.3", "X", "parallax threshold Δr/d for one texture per node (§3.3)", NULL},
    {"max-proj", 0, OPTAB_FLOAT, OF(max_proj), 0, 1e9, "0.5", "X",
     "split nodes larger than this fraction of the screen; 0 = off (§3.3)", NULL},
    /* §3.2: flat when normals deviate less than 10° */
    {"flat-deg", 0, OPTAB_FLOAT, OF(flat_deg), 0, 180, "10", "X",
     "normal spread (degrees) under which a node is flat: object-local (§3.2)", NULL},
    {"flat-thickness", 0, OPTAB_FLOAT, OF(flat_thickness), 0, 1e9, "0.01", "X",
     "flat nodes' extent along the normal / in-plane extent", NULL},
    {"blend", 0, OPTAB_FLOAT, OF(blend), 0, 1e6, "1", "X",
     "validity band (texels) blended at splat borders; 0 = off (§3.4)", NULL},
    /* noise-aware splatting (docs/textures.md, "Mixing") */
    {"mix", 0, OPTAB_FLOAT, OF(mix), 0.01, 1, "0.3", "X",
     "weight of a new sample against the correction it lands on (noise-aware splatting); 1 = off: each texel "
     "holds its nearest sample", NULL},
    {"mix-radius", 0, OPTAB_FLOAT, OF(mix_radius), 0, 1e6, "16", "X",
     "mix only with a correction whose sample lies within this many texels (validity below v_max)", NULL},
    {"splat-max", 0, OPTAB_INT, OF(splat_max), 0, 65536, "64", "N",
     "largest splat radius (texels), bounds the cost of a sample in an empty region; 0 = none", NULL},
    {"splat-aniso", 0, OPTAB_INT, OF(splat_aniso), 0, 1, "1", "N",
     "1: splat rings measured on screen (texels seen at a slant get elongated rings); 0: square rings in texels",
     NULL},
    {"splat-lo", 0, OPTAB_FLOAT, OF(splat_lo), 0, 1e6, "1", "X",
     "mean splat radius (texels) under which the resolution doubles (§3.6)", NULL},
    {"splat-hi", 0, OPTAB_FLOAT, OF(splat_hi), 0, 1e6, "5", "X",
     "mean splat radius (texels) over which the resolution halves (§3.6)", NULL},
    {"splat-window", 0, OPTAB_INT, OF(splat_window), 1, 1e6, "64", "N", "samples in the running mean of splat radii (§3.6)",
     NULL},
    /* §3.6: minimum 4x4 */
    {"tex-min", 0, OPTAB_INT, OF(tex_min), 1, 65536, "4", "N", "minimum texture size per axis (§3.6)", NULL},
    {"tex-init", 0, OPTAB_INT, OF(tex_init), 1, 65536, "16", "N", "size of a new texture along its longer axis", NULL},
    /* §3.6: at most twice the screen sampling rate */
    {"tex-rate", 0, OPTAB_FLOAT, OF(tex_rate), 0.01, 64, "2", "X", "maximum texels per screen pixel per axis (§3.6)",
     NULL},
    {"tex-max", 0, OPTAB_INT, OF(tex_max), 1, 65536, "4096", "N", "maximum texture size per axis", NULL},
    {"tex-mem-mb", 0, OPTAB_DOUBLE, OF(mem_mb), 1, 1e7, "512", "X",
     "memory cap for all texels, MiB (invisible textures evicted first)", NULL},
    {"age-flow", 0, OPTAB_FLOAT, OF(age_flow), 0, 1e9, "1", "X", "aging weight of camera-local texture flow (§3.5)",
     NULL},
    {"age-brdf", 0, OPTAB_FLOAT, OF(age_brdf), 0, 1e9, "10", "X",
     "aging weight of BRDF change: texture sizes per radian at glossiness 1 (§3.5)", NULL},
    {"late-deg", 0, OPTAB_FLOAT, OF(late_deg), 0, 180, "10", "X",
     "a glossy sample traced from an eye the camera has left goes in aged by §3.5's BRDF term while its viewing "
     "direction turned by at most this many degrees times its glossiness, else it is dropped; 0 = only from "
     "the eye's position now", NULL},
    {"resample-age", 0, OPTAB_FLOAT, OF(resample_age), 0, 1e9, "1", "X",
     "validity (texels) a resampled texel loses to fresh samples", NULL},
    {"keep-projector-deg", 0, OPTAB_FLOAT, OF(keep_deg), 0, 90, "20", "X",
     "a camera-local texture keeps the projector it was made for (no resampling, nothing re-sent) while it covers "
     "the node's new view and the view direction to the node turned by at most this many degrees; 0 = resample on "
     "every camera change", NULL},
    {"projector-margin", 0, OPTAB_FLOAT, OF(proj_margin), 0, 1, "0.125", "X",
     "a camera-local texture made again because the camera moved reaches past the screen edges that cut its node "
     "by up to this fraction of the screen (at most a quarter of what shows), so that the next small moves keep "
     "its projector; 0 = the screen's edges", NULL},
    {"bvh-mat-weight", 0, OPTAB_FLOAT, OF(bvh_mat_weight), 0, 1e9, "1", "X",
     "BVH cost factor for groups mixing materials (§3.3)", NULL},
    {"cluster-tris", 0, OPTAB_INT, OF(cluster_tris), 0, 1e9, "4096", "N",
     "parts with more triangles are split into clusters: one per face, curved ones into at most this many; 0 = "
     "never", NULL},
};
#undef OF

const optab *ctex_options_table(size_t *n)
{
    *n = OPTAB_COUNT(OPTS);
    return OPTS;
}

ctex_options ctex_options_default(void)
{
    ctex_options o;
    memset(&o, 0, sizeof o);
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), &o, &err);   /* the table's defaults parse (test_ctex_engine) */
    return o;
}

int ctex_options_parse(ctex_options *o, const char *flag, const char *value, ct_error *err)
{
    if (strncmp(flag, "--", 2) != 0) return 0;
    return optab_set(OPTS, OPTAB_COUNT(OPTS), o, flag + 2, value, err);
}

void ctex_options_help(FILE *f)
{
    optab_usage(OPTS, OPTAB_COUNT(OPTS), NULL, f);
}

/* --- events ------------------------------------------------------------------------ */

ctex_event *ctex_ev_push(ctex *c, ctex_event_kind kind, uint32_t tex)
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

/* ALLOC or RESIZE of slot id with its node, kind and size. */
static ctex_event *ev_texture(ctex *c, ctex_event_kind kind, uint32_t id)
{
    const slot *s = &c->slots[id];
    ctex_event *e = ctex_ev_push(c, kind, id);
    if (e) {
        e->node = s->hnode; e->proj = s->t.kind; e->w = s->t.w; e->h = s->t.h;
    }
    return e;
}

void ctex_ev_alloc(ctex *c, uint32_t id)
{
    ev_texture(c, CTEX_EV_ALLOC, id);
}

void ctex_ev_resized(ctex *c, uint32_t id, int ow, int oh)
{
    const slot *s = &c->slots[id];
    bool exact = wire_tex_resize_exact(ow, oh, s->t.w, s->t.h);
    ctex_event *e = ev_texture(c, exact ? CTEX_EV_RESIZE : CTEX_EV_ALLOC, id);
    if (e && exact) e->ow = ow, e->oh = oh;
}

void ctex_ev_proj(ctex *c, uint32_t id)
{
    ctex_event *e = ctex_ev_push(c, CTEX_EV_PROJ, id);
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
    /* an eighth of the memory cap kept for reuse: one or two of the
     * largest textures' worth */
    c->mem = ctex_mem_new((size_t)(c->o.mem_mb * 1048576.0 / 8.0));
    if (!c->node_tex || !c->leaf_owner || !c->assigned || !c->list || !c->names || !c->mem) {
        ctex_free(c);
        return ct_fail(err, CT_ENOMEM, "out of memory for the texture engine");
    }
    for (uint32_t i = 0; i < N; i++) c->node_tex[i] = -1;
    for (uint32_t i = 0; i < mesh->nnodes; i++)
        memcpy(c->names + (size_t)i * SCENE_NAME_LEN, mesh->nodes[i].name, SCENE_NAME_LEN);
    for (uint32_t i = 0; i < c->h.nleaves; i++) c->leaf_owner[i] = -1;
    bounds3 b = c->h.nodes[0].bounds;
    /* The display's near plane (CT_NEAR_SHARE): at 10^-4 of the diagonal a
     * part within 28 cm of the eye in a room on a 2 km ground got no
     * texture. */
    c->znear = CT_NEAR_SHARE * fmaxf(v3_len(b3_extent(b)), 1e-6f);
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
    free(c->par_own);
    free(c->par_order);
    free(c->par_first);
    free(c->par_count);
    free(c->par_done);
    free(c->par_groups);
    free(c->par_keys);
    ctex_hier_free(&c->h);
    ctex_mem_free(c->mem);
    free(c);
}

vec3 ctex_lookup(const ctex *c, uint32_t node, uint32_t tri, vec3 p)
{
    int32_t id = ctex_owner_of(c, node, tri, p);
    float u, v;
    if (id < 0 || !ctex_tex_project(&c->slots[id].t, p, &u, &v)) return v3s(0.0f);
    return ctex_tex_sample(&c->slots[id].t, u, v);
}

/* --- queries ------------------------------------------------------------------------ */

int32_t ctex_owner(const ctex *c, uint32_t node, uint32_t tri, vec3 p)
{
    return ctex_owner_of(c, node, tri, p);
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

bool ctex_texel_rate(const ctex *c, uint32_t tex, float *x, float *y)
{
    if (tex >= c->nslots || !c->slots[tex].live || !c->have_cam) return false;
    const slot *s = &c->slots[tex];
    if (s->max_w <= 0 || s->max_h <= 0 || s->max_w >= c->o.tex_max || s->max_h >= c->o.tex_max) return false;
    *x = (float)s->t.w * c->o.tex_rate / (float)s->max_w;
    *y = (float)s->t.h * c->o.tex_rate / (float)s->max_h;
    return true;
}

float ctex_splat_ex(const ctex *c, uint32_t tex, vec3 p)
{
    if (tex >= c->nslots || !c->slots[tex].live || !c->have_cam) return 1.0f;
    return ctex_splat_ex_at(c, &c->slots[tex].t, p);
}

bool ctex_view_independent(const ctex *c, const ct_sample *s)
{
    if (!(s->flags & CT_SAMPLE_HIT)) return false;
    int32_t l = ctex_leaf_of_hit(c, s->node, s->tri, s->hit);
    return l >= 0 && c->h.nodes[c->h.leaf_node[l]].gloss == 0.0f;
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

int ctex_composite(const ctex *c, const ctex_hit *hits, int spp, int width, int height, ct_image *out,
                   ct_error *err)
{
    if (!out->px || out->width != width || out->height != height)
        return ct_fail(err, CT_EINVAL, "compositor output is not %dx%d", width, height);
    if (spp < 1) return ct_fail(err, CT_EINVAL, "compositor: %d hits per pixel", spp);
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            const ctex_hit *h = &hits[((size_t)y * (size_t)width + (size_t)x) * (size_t)spp];
            vec3 v = v3s(0.0f);
            for (int k = 0; k < spp; k++) {
                v = v3_add(v, h[k].l_base);
                if (h[k].node != UINT32_MAX) v = v3_add(v, ctex_lookup(c, h[k].node, h[k].tri, h[k].p));
            }
            img_set(out, x, y, v3_scale(v, 1.0f / (float)spp));
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
