/* integrator.c: the three modes' estimators (integrator.h): path tracing,
 * distributed ray tracing and reuse-diffuse, over the direct light of
 * integ_light.c and the final gather of integ_gather.c. */
#include "tracer/integrator.h"

#include <string.h>

#include "tracer/integ_internal.h"

/* Bounces of the path-traced indirect light of drt without a radiosity mesh. */
#define DRT_INDIRECT_DEPTH 64
/* Russian roulette starts after this many bounces of a path. */
#define RR_START 3

typedef enum emis_mode { EMIS_FULL = 0, EMIS_NONE = 1, EMIS_MIS = 2 } emis_mode;

/* How emission found by a ray counts: fully (camera rays, delta bounces),
 * not at all, or MIS-weighted against light sampling. Light that a shading
 * point's shadow rays received through glass (straight, attenuated) must not
 * be counted again by its scattered rays passing the same glass: a ray that
 * is only refracted keeps FULL, and turns MIS into NONE (see after_delta). */
typedef struct emis_w {
    emis_mode mode;
    float pdf;    /* solid-angle pdf of the direction (EMIS_MIS) */
    int n;        /* rays of that strategy (EMIS_MIS) */
    vec3 from;        /* the shading point the ray left (EMIS_MIS: its light selection)... */
    uint32_t from_key;  /* ...and its light_key */
} emis_w;

/* The emission mode of a ray leaving a mirror or dielectric (of part node
 * `node`): reflections see lights fully; a refraction continues a straight
 * line that shadow rays already looked along, unless it started at the
 * camera or a reflection. Where the glass blocks shadow rays
 * (TRC_GLASS_REFRACTED; TRC_GLASS_AUTO's glass that bends light) no light
 * sample can make a path through it, so a refraction sees lights fully too. */
static inline emis_w after_delta(const integ_ctx *c, emis_w in, bool transmit, uint32_t node)
{
    emis_w out = {EMIS_FULL, 0.0f, 1, in.from, in.from_key};
    bool blocks = c->glass_bends && c->glass_bends[node];
    if (transmit && in.mode != EMIS_FULL && !blocks) out.mode = EMIS_NONE;
    return out;
}

bool integ_primary_start(integ_ctx *c, vec3 o, vec3 d, emb_hit *h)
{
    c->st->primary++;
    log_ray(c, o, d, INFINITY, 0);
    return emb_intersect_start(c->emb, o, d, 0.0f, INFINITY, h);
}

void integ_primary_finish(const integ_ctx *c, emb_hit *h, vec3 d, integ_surf *s)
{
    emb_hit_finish(h);
    integ_make_surf(c, h, d, s);
}

bool integ_primary(integ_ctx *c, vec3 o, vec3 d, integ_surf *s)
{
    emb_hit h;
    if (!integ_primary_start(c, o, d, &h)) return false;
    integ_primary_finish(c, &h, d, s);
    return true;
}

static bool trace_secondary(integ_ctx *c, vec3 o, vec3 d, integ_surf *s)
{
    emb_hit h;
    c->st->secondary++;
    log_ray(c, o, d, INFINITY, 0);
    if (!emb_intersect(c->emb, o, d, 0.0f, INFINITY, &h)) return false;
    integ_make_surf(c, &h, d, s);
    return true;
}

/* mirror_light with K / MIRROR_LIGHT_SHARE samples, rounded up. */
static vec3 mirror_light(integ_ctx *c, const integ_surf *s, const bsdf *b)
{
    return integ_mirror_light_n(c, s, b, (c->opt->shadow_rays + MIRROR_LIGHT_SHARE - 1) / MIRROR_LIGHT_SHARE);
}

/* Emission of s towards wo = -d, weighted as ew says. */
static vec3 emitted(const integ_ctx *c, const integ_surf *s, vec3 d, emis_w ew)
{
    float cos_front = -v3_dot(d, s->ng);
    if (cos_front <= 0.0f || v3_is_zero(s->m->emission) || ew.mode == EMIS_NONE) return v3s(0.0f);
    if (ew.mode == EMIS_FULL) return s->m->emission;
    /* The density the shadow rays of the point the ray left had. */
    light_sel sel;
    light_select_key(c->lights, ew.from_key, ew.from, &sel);
    float pl = light_pdf_area(c->lights, &sel, s->h.tri) * s->h.t * s->h.t / cos_front;
    return v3_scale(s->m->emission,
                    bsdf_power_heuristic((float)ew.n * ew.pdf, (float)c->opt->shadow_rays * pl));
}

/* Unbiased path tracing from o along d; first (if given) is the first hit. */
static vec3 path_li(integ_ctx *c, vec3 o, vec3 d, const integ_surf *first, bool count_first, int max_depth)
{
    vec3 L = v3s(0.0f), beta = v3s(1.0f);
    emis_w ew = {count_first ? EMIS_FULL : EMIS_NONE, 0.0f, 1, o, LIGHT_NO_KEY};
    integ_surf s;
    for (int depth = 0;; depth++) {
        if (depth == 0 && first) s = *first;
        else if (!trace_secondary(c, o, d, &s)) break;
        vec3 wo = v3_neg(d);
        L = v3_add(L, v3_mul(beta, emitted(c, &s, d, ew)));
        if (depth >= max_depth) break;
        bsdf b;
        surf_bsdf(&s, wo, &b);
        L = v3_add(L, v3_mul(beta, integ_direct_light(c, &s, &b, wo, DIRECT_ALL, 1)));
        float u0 = rnd(c), u1 = rnd(c), u2 = rnd(c);
        bsdf_sample bs;
        if (!bsdf_sample_all(&b, wo, u0, u1, u2, &bs)) break;
        beta = v3_mul(beta, bs.weight);
        if (bs.delta) {
            ew = after_delta(c, ew, bs.transmit, s.h.node);
        } else {
            ew.mode = EMIS_MIS;
            ew.pdf = bs.pdf;
            ew.n = 1;
            ew.from = s.p;
            ew.from_key = s.lkey;
        }
        if (depth >= RR_START) {
            float q = minf(0.95f, maxc(beta));
            if (!(rnd(c) < q)) break;
            beta = v3_scale(beta, 1.0f / q);
        }
        if (!(maxc(beta) > 0.0f)) break;
        o = emb_offset_ray(s.p, bs.transmit ? v3_neg(b.ng) : b.ng);
        d = bs.wi;
    }
    return L;
}

/* Below the fresnel_depth levels the weaker Fresnel branch of an event (weight
 * w < 1/2) is traced with probability min(1, w / FRESNEL_WEAK_P), its
 * radiance scaled by w / p: a ray about every fourth event of a thin
 * glass's 4 % reflections, each at a quarter of the weight picking by F
 * would give it (table, one sample a pixel at 512x512: the noise variance
 * 8.0e-4 -> 7.2e-4, rays +4 %; 0.1 gave 7.1e-4). */
#define FRESNEL_WEAK_P 0.25f

typedef vec3 (*radiance_fn)(integ_ctx *c, vec3 o, vec3 d, int depth, emis_w ew);

static vec3 drt_next(integ_ctx *c, vec3 o, vec3 d, int depth, emis_w ew);
static vec3 reuse_next(integ_ctx *c, vec3 o, vec3 d, int depth, emis_w ew);

/* Glossy rays at a hit on recursion level depth: B on the first
 * branch_depth levels, 1 below (so a sample's cost grows linearly with D,
 * not as B^D), none at the last level or without a glossy lobe. */
static int glossy_rays(const trc_options *opt, const bsdf *b, int depth)
{
    if (depth >= opt->depth || b->L.p_g <= 0.0f) return 0;
    return depth < opt->branch_depth ? opt->branch : 1;
}

/* The traced non-diffuse transport at s (drt, reuse-diffuse): nb glossy
 * rays MIS-weighted against light sampling, the mirror ray, and the Fresnel
 * reflection and refraction: both on the first fresnel_depth levels, below
 * the stronger always and the weaker by chance (unbiased). li continues a
 * ray. */
static vec3 scatter_specular(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 wo, int depth, emis_w ew,
                             int nb, radiance_fn li)
{
    vec3 L = v3s(0.0f);
    if (nb <= 0 && !(maxc(b->L.km) > 0.0f) && !b->L.dielectric) return L;
    emis_w refl = after_delta(c, ew, false, s->h.node), refr = after_delta(c, ew, true, s->h.node);
    vec3 up = emb_offset_ray(s->p, b->ng);
    for (int i = 0; i < nb; i++) {
        bsdf_sample bs;
        float u1 = rnd(c), u2 = rnd(c);
        if (!bsdf_sample_glossy(b, wo, u1, u2, &bs)) continue;
        emis_w mis = {EMIS_MIS, bs.pdf, nb, s->p, s->lkey};
        vec3 l = li(c, up, bs.wi, depth + 1, mis);
        L = v3_add(L, v3_scale(v3_mul(bs.weight, l), 1.0f / (float)nb));
    }
    if (maxc(b->L.km) > 0.0f) {
        vec3 wr = bsdf_reflect(wo, b->n);
        if (bsdf_same_side(b, wr)) L = v3_add(L, v3_mul(b->L.km, li(c, up, wr, depth + 1, refl)));
    }
    if (b->L.dielectric) {
        vec3 wr, wt;
        bool ok;
        float f = bsdf_dielectric(b, wo, &wr, &wt, &ok);
        float wrefl = f, wrefr = ok ? 1.0f - f : 0.0f;
        if (ok && depth >= c->opt->fresnel_depth) {
            /* The stronger branch always, with its Fresnel weight; the
             * weaker by chance (FRESNEL_WEAK_P; unbiased). Picking one of
             * the two by F instead dropped a glass's transmitted light
             * whenever the reflection won: the dark and bright specks of
             * single samples through glass. */
            float *weak = wrefl < wrefr ? &wrefl : &wrefr;
            float p = minf(1.0f, *weak / FRESNEL_WEAK_P);
            *weak = rnd(c) < p ? *weak / p : 0.0f;
        }
        if (wrefl > 0.0f) L = v3_add(L, v3_scale(li(c, up, wr, depth + 1, refl), wrefl));
        if (wrefr > 0.0f) {
            vec3 lt = li(c, emb_offset_ray(s->p, v3_neg(b->ng)), wt, depth + 1, refr);
            L = v3_add(L, v3_mul(lt, v3_scale(b->L.kt, wrefr * b->eta * b->eta)));
        }
    }
    return L;
}

/* Distributed ray tracing (Cook 1984) at recursion level depth. */
static vec3 drt_li(integ_ctx *c, vec3 o, vec3 d, const integ_surf *first, int depth, emis_w ew)
{
    integ_surf s;
    if (first) s = *first;
    else if (!trace_secondary(c, o, d, &s)) return v3s(0.0f);
    const trc_options *opt = c->opt;
    vec3 wo = v3_neg(d);
    vec3 L = emitted(c, &s, d, ew);
    bsdf b;
    surf_bsdf(&s, wo, &b);
    bool recurse = depth < opt->depth;
    int nb = glossy_rays(opt, &b, depth);
    L = v3_add(L, integ_direct_light(c, &s, &b, wo, DIRECT_GLOSSY_MIS, nb));
    if (b.L.p_d > 0.0f) {
        if (mlight_count(c->mirrors)) L = v3_add(L, mirror_light(c, &s, &b));
        if (c->rad && opt->indirect == TRC_INDIRECT_GATHER && ew.mode == EMIS_FULL) {
            /* The first diffuse hit of the path (the camera's, or seen in
             * mirrors and through glass: the hits whose emission counts
             * fully); behind a glossy bounce the mesh's value at the hit is
             * blurred by the lobe anyway. The caustic only here: the mesh's
             * value, read below and where the gather lands, holds what
             * mirrors and glass reflect already (spread as if diffuse,
             * docs/radiosity.md), the hit's own the gather cannot see. */
            L = v3_add(L, integ_final_gather(c, &s, &b));
            L = v3_add(L, integ_caustic(c, &s.h, d));
        } else if (c->rad) {
            /* The radiosity solution's indirect part at this very point. */
            vec3 ind = v3_sub(integ_vertex_lerp(c->rad->rad, &s.h), integ_vertex_lerp(c->rad->rad_direct, &s.h));
            L = v3_add(L, clamp0(ind));
        } else {
            bsdf_sample bs;
            float u1 = rnd(c), u2 = rnd(c);
            if (bsdf_sample_diffuse(&b, u1, u2, &bs)) {
                vec3 li = path_li(c, emb_offset_ray(s.p, b.ng), bs.wi, NULL, false, DRT_INDIRECT_DEPTH);
                L = v3_add(L, v3_mul(bs.weight, li));
            }
        }
    }
    if (recurse) L = v3_add(L, scatter_specular(c, &s, &b, wo, depth, ew, nb, drt_next));
    return L;
}

static vec3 drt_next(integ_ctx *c, vec3 o, vec3 d, int depth, emis_w ew)
{
    return drt_li(c, o, d, NULL, depth, ew);
}

/* reuse-diffuse (§4.1): the interpolated radiosity plus the traced glossy,
 * mirror and refractive transport. *base receives the radiosity part. */
static vec3 reuse_li(integ_ctx *c, vec3 o, vec3 d, const integ_surf *first, int depth, emis_w ew,
                     vec3 *base_out)
{
    integ_surf s;
    if (first) s = *first;
    else if (!trace_secondary(c, o, d, &s)) return v3s(0.0f);
    const trc_options *opt = c->opt;
    vec3 base = integ_vertex_lerp(c->rad->rad, &s.h);
    if (ew.mode != EMIS_FULL) {
        /* The radiosity includes the emitter's L_e; a glossy ray that found
         * it only carries its MIS share (light sampling has the rest). */
        vec3 le = emitted(c, &s, d, (emis_w){EMIS_FULL, 0.0f, 1, o, LIGHT_NO_KEY});
        vec3 keep = emitted(c, &s, d, ew);
        base = clamp0(v3_sub(base, v3_sub(le, keep)));
    }
    if (base_out) *base_out = base;
    /* A material with nothing but diffuse layers adds nothing here (most
     * hits of a scene): no frame, no light samples, no rays. */
    if (!s.bm->traced) return base;
    vec3 wo = v3_neg(d);
    bsdf b;
    surf_bsdf(&s, wo, &b);
    bool recurse = depth < opt->depth;
    int nb = glossy_rays(opt, &b, depth);
    vec3 extra = integ_direct_light(c, &s, &b, wo, DIRECT_GLOSSY_ONLY, nb);
    if (recurse) extra = v3_add(extra, scatter_specular(c, &s, &b, wo, depth, ew, nb, reuse_next));
    /* Every term of extra is >= 0; a NaN from a degenerate frame must not
     * break that guarantee, so it is dropped. */
    extra = clamp0(extra);
    if (!finite3(extra)) extra = v3s(0.0f);
    return v3_add(base, extra);
}

static vec3 reuse_next(integ_ctx *c, vec3 o, vec3 d, int depth, emis_w ew)
{
    return reuse_li(c, o, d, NULL, depth, ew, NULL);
}

vec3 integ_radiance(integ_ctx *c, vec3 o, vec3 d, const integ_surf *s, vec3 *base)
{
    emis_w full = {EMIS_FULL, 0.0f, 1, o, LIGHT_NO_KEY};
    switch (c->opt->mode) {
    case TRC_MODE_PATH: return path_li(c, o, d, s, true, c->opt->depth);
    case TRC_MODE_DRT: return drt_li(c, o, d, s, 0, full);
    case TRC_MODE_REUSE: return reuse_li(c, o, d, s, 0, full, base);
    }
    return v3s(0.0f);
}
