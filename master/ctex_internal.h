/* ctex_internal.h: what the corrective-texture engine's files share
 * (ctex.c: options, events, lifecycle, queries, compositor; ctex_view.c:
 * the per-view assignment, projections, aging and memory; ctex_insert.c:
 * sample insertion and resolution changes). Not for other modules (the
 * engine's unit tests drive the resolution rule through it). */
#ifndef CT_MASTER_CTEX_INTERNAL_H
#define CT_MASTER_CTEX_INTERNAL_H

#include <math.h>

#include "master/ctex.h"
#include "master/ctex_hier.h"
#include "master/ctex_mem.h"
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
    int pend_w, pend_h;   /* a resolution change noted by a parallel insertion (0: none) */
} slot;

struct ctex {
    ctex_options o;
    ctex_hier h;
    ctex_mem *mem;         /* texel arrays given back, for the next ones */
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
    cam_rays rays;         /* cam's axes (r, u, f) and tan half-angles (tw, th) for W x H */
    float fpx;             /* focal length in pixels */
    float znear;
    uint32_t epoch;
    size_t bytes;
    ctex_stats st;
    uint64_t now_us;       /* stamped on texel changes (ctex_set_clock) */
    /* scratch of a parallel insertion (ctex_insert.c) */
    int32_t *par_own;      /* per sample: its texture, -1 */
    uint32_t *par_order;   /* sample indices grouped by texture */
    size_t par_cap;
    uint32_t *par_first, *par_count, *par_done;   /* per slot: group start, size, splatted */
    uint32_t *par_groups;  /* the slots with samples, in task order */
    uint64_t *par_keys;    /* sort keys of par_groups */
    uint32_t par_slots;
};

/* --- shared helpers ------------------------------------------------------------ */

/* Appends an event (NULL when out of memory: the event is lost, the next
 * full patch repairs contents). */
ctex_event *ctex_ev_push(ctex *c, ctex_event_kind kind, uint32_t tex);

/* ALLOC (with the texture's node, kind and size) and PROJECTION of slot id. */
void ctex_ev_alloc(ctex *c, uint32_t id);
void ctex_ev_proj(ctex *c, uint32_t id);
/* After slot id's resize from ow x oh: RESIZE when it was exact, else ALLOC. */
void ctex_ev_resized(ctex *c, uint32_t id, int ow, int oh);

/* Frees slot id's texels (FREE when the display has it). */
void ctex_destroy_slot(ctex *c, uint32_t id);

/* Evicts parked textures, least recently visible first, until `need` more
 * bytes fit under the cap; returns whether they fit. */
int ctex_make_room(ctex *c, size_t need);

/* §3.6: texture id's running mean of splat radii takes radius r; halves or
 * doubles the texture when the mean says so (with defer, a parallel
 * insertion: only notes it). ctex_insert.c. */
void ctex_adapt_resolution(ctex *c, uint32_t id, int r, int defer);

/* §3.5's BRDF term in texels of texture t: age_brdf x glossiness x the
 * change of the viewing direction (radians) x the texture's longer side.
 * Aging on a camera change (ctex_view.c) and a late sample's age
 * (ctex_insert.c) both use it. */
static inline float ctex_brdf_age(const ctex *c, const ctex_tex *t, float gloss, float ang)
{
    return c->o.age_brdf * gloss * ang * (float)(t->w > t->h ? t->w : t->h);
}

/* The leaf a hit belongs to: its part's leaf, or for a part split into
 * clusters the leaf of its triangle (or, when the triangle is unknown, the
 * cluster whose bounds are nearest to the hit point). -1 when none. */
static inline int32_t ctex_leaf_of_hit(const ctex *c, uint32_t node, uint32_t tri, vec3 p)
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

static inline int32_t ctex_owner_of(const ctex *c, uint32_t node, uint32_t tri, vec3 p)
{
    int32_t l = ctex_leaf_of_hit(c, node, tri, p);
    return l < 0 ? -1 : c->leaf_owner[l];
}

/* The image of world vector d at e (relative to the eye, depth z > 0) on
 * screen, times z / fpx (the perspective projection's derivative along d,
 * up to a factor that is the same for every d at e): its squared length. */
static inline float ctex_screen_len2(const ctex *c, vec3 e, float z, vec3 d)
{
    float dz = v3_dot(d, c->rays.f);
    float dx = z * v3_dot(d, c->rays.r) - v3_dot(e, c->rays.r) * dz;
    float dy = z * v3_dot(d, c->rays.u) - v3_dot(e, c->rays.u) * dz;
    return dx * dx + dy * dy;
}

/* ex of ctex_tex_splat_aniso for a sample at p on texture t, after
 * ctex_aniso_ex: sqrt(s_y / s_x) for a texel s_x by s_y pixels on screen
 * there. A camera-local texture lies in the current view's pixels (constant
 * texel size); an object-local one is seen through the perspective at p, so
 * a wall along the view shows its texels stretched towards the vanishing
 * point near the eye and squeezed far away. Compares squared ratios first:
 * most samples splat square rings and need no root. */
static inline float ctex_splat_ex_at(const ctex *c, const ctex_tex *t, vec3 p)
{
    float r4;   /* (s_y / s_x)^2 */
    if (t->kind == CTEX_PROJ_CAMERA) {
        float q = ((t->y1 - t->y0) * (float)t->w) / ((t->x1 - t->x0) * (float)t->h);
        r4 = q * q;
    } else {
        vec3 e = v3_sub(p, c->cam.eye);
        float z = v3_dot(e, c->rays.f);
        if (!(z > c->znear)) return 1.0f;
        float lx = ctex_screen_len2(c, e, z, v3_scale(t->t, 1.0f / (float)t->w));
        float ly = ctex_screen_len2(c, e, z, v3_scale(t->b, 1.0f / (float)t->h));
        r4 = ly / lx;
    }
    const float iso4 = CTEX_ANISO_ISO * CTEX_ANISO_ISO * CTEX_ANISO_ISO * CTEX_ANISO_ISO;
    if (r4 > iso4 && r4 < 1.0f / iso4) return 1.0f;
    return ctex_aniso_ex(sqrtf(sqrtf(r4)));
}

#endif
