/* integ_light.c: direct light for the integrators (integ_internal.h): the
 * lamps by K shadow rays tested in packets, the lamps seen in plane mirrors,
 * and shadow rays that pass glass attenuated. */
#include "tracer/integ_internal.h"

/* What one straight crossing of glass material m passes, d.ng = cosd
 * (rmesh_glass_pass: the display's see-through glass draws the same).
 * Evaluating the exit from the inside at the unrefracted angle instead would
 * make every crossing beyond asin(1 / ior), 41.8 deg for glass, a total
 * internal reflection that blocks the light. */
static inline vec3 glass_pass(const scene_material *m, float cosd)
{
    rmesh_material x = rmesh_material_of(m);
    return rmesh_glass_pass(&x, cosd);
}

/* Fraction of light reaching o from target along the straight line o + t d,
 * t in (0, dist), known to be blocked by something: 0 behind an opaque
 * surface; through dielectrics, their transmission colour times (1 -
 * Fresnel) per crossing (refraction of the shadow ray itself is ignored, so
 * glass casts a lighter, unfocused shadow as in the paper). At most
 * RMESH_MAX_GLASS_CROSSINGS crossings (a stack of glasses; also bounds the
 * work per shadow ray), then blocked. */
vec3 integ_through_glass(integ_ctx *c, vec3 o, vec3 d, float dist, vec3 target, bool *crossed)
{
    if (!c->has_dielectric) return v3s(0.0f);
    vec3 att = v3s(1.0f);
    for (int k = 0; k < RMESH_MAX_GLASS_CROSSINGS; k++) {
        emb_hit h;
        c->st->shadow++;
        log_ray(c, o, d, dist, 0);
        if (!emb_intersect(c->emb, o, d, 0.0f, dist, &h)) return att;
        const scene_material *m = &c->mesh->mats[h.mat];
        if (!m->dielectric || (c->glass_bends && c->glass_bends[h.node])) return v3s(0.0f);
        *crossed = true;
        vec3 ng = h.rec->ng;
        float cosd = v3_dot(d, ng);
        att = v3_mul(att, glass_pass(m, cosd));
        if (!(maxc(att) > 0.0f)) return v3s(0.0f);
        vec3 p = emb_hit_point(&h);
        o = emb_offset_ray(p, cosd < 0.0f ? v3_neg(ng) : ng);
        d = v3_sub(target, o);
        dist = v3_len(d);
        if (!(dist > 0.0f) || v3_dot(d, d) <= 0.0f) return att;
        d = v3_scale(d, 1.0f / dist);
    }
    return v3s(0.0f);
}

/* integ_base_through_glass; reflected: without the emission of the surface
 * found (for the final gather: the shadow rays of the point that gathers
 * bring that light). */
vec3 integ_through_glass_base(integ_ctx *c, const emb_hit *first, vec3 d, bool reflected)
{
    vec3 att = v3s(1.0f);
    emb_hit h = *first;
    for (int k = 0; k < RMESH_MAX_GLASS_CROSSINGS; k++) {
        const scene_material *m = &c->mesh->mats[h.mat];
        if (!m->dielectric) {
            vec3 l = integ_vertex_lerp(c->rad->rad, &h);
            if (reflected) l = clamp0(v3_sub(l, m->emission));
            return v3_mul(att, l);
        }
        vec3 ng = h.rec->ng;
        float cosd = v3_dot(d, ng);
        att = v3_mul(att, glass_pass(m, cosd));
        if (!(maxc(att) > 0.0f)) return v3s(0.0f);
        vec3 o = emb_offset_ray(emb_hit_point(&h), cosd < 0.0f ? v3_neg(ng) : ng);
        c->st->secondary++;
        log_ray(c, o, d, INFINITY, 0);
        if (!emb_intersect(c->emb, o, d, 0.0f, INFINITY, &h)) return v3s(0.0f);
    }
    return v3s(0.0f);
}

vec3 integ_base_through_glass(integ_ctx *c, const emb_hit *first, vec3 d)
{
    return integ_through_glass_base(c, first, d, false);
}

/* Light samples of one shading point whose shadow rays are tested together. */
#define SHADOW_BATCH 8

/* A light sample waiting for its shadow ray. */
typedef struct light_cand {
    vec3 f, fg;       /* the bsdf terms (see direct_light) */
    vec3 wi, le, target, d;
    float pl, pb, dist;
} light_cand;

/* Up to SHADOW_BATCH light samples of one shading point and their shadow
 * rays (all leave origin), between dl_prepare and dl_finish. */
typedef struct dl_batch {
    light_cand cand[SHADOW_BATCH];
    vec3 so[SHADOW_BATCH], sd[SHADOW_BATCH];
    float sfar[SHADOW_BATCH];
    bool blocked[SHADOW_BATCH];
    vec3 origin;
    int k;            /* the point's light samples in all (K) */
    int n;            /* shadow rays to test */
} dl_batch;

/* Draws kn light samples at s, evaluates the bsdf towards them and sets up
 * the shadow rays of those that can contribute (see direct_light). */
static void dl_prepare(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 wo, direct_mode mode, int nb,
                       int k0, int kn, const light_sel *sel, const float shift[3], dl_batch *q)
{
    q->n = 0;
    int k_rays = q->k;
    for (int k = 0; k < kn; k++) {
        /* The K light samples of a point are a randomly shifted Halton-like
         * set (k / K, radical inverses in bases 2 and 3): stratified over the
         * emitter choice and the light's area, each sample still uniform. */
        uint32_t i = (uint32_t)(k0 + k);
        float u0 = frac1((float)i / (float)k_rays + shift[0]);
        float u1 = frac1(radical_inverse(i, 2) + shift[1]);
        float u2 = frac1(radical_inverse(i, 3) + shift[2]);
        light_point lp;
        if (!light_sample(c->lights, sel, u0, u1, u2, &lp)) continue;
        if (lp.tri == s->h.tri) continue;
        vec3 wi = v3_sub(lp.p, s->p);
        float d2 = v3_len2(wi);
        if (!(d2 > 0.0f)) continue;
        wi = v3_scale(wi, 1.0f / sqrtf(d2));
        float cos_l = -v3_dot(wi, lp.n);
        if (cos_l <= 0.0f || !bsdf_same_side(b, wi)) continue;
        float pl = lp.pdf_area * d2 / cos_l;
        /* An infinite pdf (cos_l ~ 0) means a zero contribution, and would
         * turn into 0 * inf = NaN below. */
        if (!(pl > 0.0f && pl < INFINITY)) continue;
        light_cand *lc = &q->cand[q->n];
        lc->pb = 0.0f;
        lc->fg = v3s(0.0f);
        if (mode == DIRECT_ALL) {
            lc->f = bsdf_eval(b, wo, wi, &lc->pb);
        } else {
            lc->fg = bsdf_eval_glossy(b, wo, wi);
            lc->pb = nb > 0 ? bsdf_pdf_glossy(b, wo, wi) : 0.0f;
            lc->f = mode == DIRECT_GLOSSY_MIS ? v3_add(lc->fg, bsdf_eval_diffuse(b, wi)) : lc->fg;
        }
        if (v3_is_zero(lc->f)) continue;
        lc->target = emb_offset_ray(lp.p, lp.n);
        vec3 d = v3_sub(lc->target, q->origin);
        float dist = v3_len(d);
        if (!(dist > 0.0f)) continue;
        lc->d = v3_scale(d, 1.0f / dist);
        lc->dist = dist;
        lc->wi = wi;
        lc->le = lp.le;
        lc->pl = pl;
        q->so[q->n] = q->origin;
        q->sd[q->n] = lc->d;
        q->sfar[q->n] = dist;
        c->st->shadow++;
        log_ray(c, q->origin, lc->d, dist, 1);
        q->n++;
    }
}

/* Tests the batch's shadow rays (one packet query). */
static void dl_test(integ_ctx *c, dl_batch *q)
{
    emb_occluded_batch(c->emb, q->n, q->so, q->sd, q->sfar, q->blocked);
}

/* Adds the batch's contributions, in sample order, to *sum. */
static void dl_finish(integ_ctx *c, const bsdf *b, direct_mode mode, int nb, const dl_batch *q, vec3 *sum)
{
    int k_rays = q->k;
    for (int i = 0; i < q->n; i++) {
        const light_cand *lc = &q->cand[i];
        bool crossed = false;
        vec3 tr = q->blocked[i] ? integ_through_glass(c, q->origin, lc->d, lc->dist, lc->target, &crossed) : v3s(1.0f);
        if (v3_is_zero(tr)) continue;
        /* MIS against the scattered rays, except through glass: scattered
         * rays do not count lights seen through it (after_delta). */
        float w = crossed ? 1.0f : bsdf_power_heuristic((float)k_rays * lc->pl, (float)nb * lc->pb);
        vec3 f;
        if (mode == DIRECT_ALL) f = v3_scale(lc->f, w);
        else if (mode == DIRECT_GLOSSY_MIS) f = v3_add(v3_sub(lc->f, lc->fg), v3_scale(lc->fg, w));
        else f = v3_scale(lc->fg, w);
        float g = v3_dot(lc->wi, b->n) / (lc->pl * (float)k_rays);
        *sum = v3_add(*sum, v3_scale(v3_mul(v3_mul(f, lc->le), tr), g));
    }
}

/* True when direct_light has anything to do at s. */
static inline bool dl_active(const integ_ctx *c, const bsdf *b, direct_mode mode)
{
    if (light_count(c->lights) == 0) return false;
    return mode == DIRECT_GLOSSY_ONLY ? b->L.p_g > 0.0f : bsdf_has_smooth(b);
}

/* Direct light at s from K light samples (see direct_mode); nb and the
 * glossy/whole pdf give the competing strategy of the MIS weights. The K
 * samples go in batches: sample and evaluate up to SHADOW_BATCH lights
 * (drawing the random numbers in the same order as one at a time), test
 * their shadow rays with one packet query (they leave one point towards the
 * same lights: a coherent bundle), then add the contributions in sample
 * order. */
vec3 integ_direct_light_n(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 wo, direct_mode mode, int nb,
                          int k_rays)
{
    vec3 sum = v3s(0.0f);
    if (!dl_active(c, b, mode)) return sum;
    dl_batch q;
    q.origin = emb_offset_ray(s->p, b->ng);
    q.k = k_rays;
    /* The emitter probabilities at s, for all its light samples (lights.h). */
    light_sel sel;
    light_select_key(c->lights, s->lkey, s->p, &sel);
    float shift[3];
    for (int k = 0; k < 3; k++) shift[k] = rnd(c);   /* (an initializer list's order is unspecified) */
    for (int k0 = 0; k0 < k_rays; k0 += SHADOW_BATCH) {
        int kn = k_rays - k0 < SHADOW_BATCH ? k_rays - k0 : SHADOW_BATCH;
        dl_prepare(c, s, b, wo, mode, nb, k0, kn, &sel, shift, &q);
        dl_test(c, &q);
        dl_finish(c, b, mode, nb, &q, &sum);
    }
    return sum;
}

vec3 integ_direct_light(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 wo, direct_mode mode, int nb)
{
    return integ_direct_light_n(c, s, b, wo, mode, nb, c->opt->shadow_rays);
}

/* Light reaching the diffuse layer at s from the lamps by way of one plane
 * mirror (mirror_lights.h). Each of the K / MIRROR_LIGHT_SHARE samples picks
 * a mirror s lies in front of, in proportion to the solid angle it fills
 * (mlight_weight: every mirror that could reflect light to s keeps a
 * positive chance, so the sum stays unbiased, and a room's own mirror gets
 * most samples where a building has one per room), then a lamp point as
 * the mirror's centre sees the lamps, mirrored behind the plane. It counts
 * when the ray from s towards the image meets the mirror itself first and
 * nothing but glass blocks the leg from the mirror to the lamp. Weight 1:
 * no other part of drt brings this light to a diffuse layer (the mirror
 * blocks the shadow rays, the radiosity solution has no mirrors, the
 * gather leaves lamps seen in mirrors out). The glossy part is not taken:
 * glossy rays count lamps seen in mirrors fully. Glass on the leg to the
 * mirror blocks (a small loss of light, no double count). */
vec3 integ_mirror_light_n(integ_ctx *c, const integ_surf *s, const bsdf *b, int k_rays)
{
    float cdf[MLIGHT_MAX];
    float total = mlight_cdf(c->mirrors, s->p, cdf);
    if (!(total > 0.0f)) return v3s(0.0f);
    vec3 sum = v3s(0.0f), o = emb_offset_ray(s->p, b->ng);
    float shift[4];
    for (int k = 0; k < 4; k++) shift[k] = rnd(c);
    for (int k = 0; k < k_rays; k++) {
        /* Stratified as the real lamps' samples are (dl_prepare), the
         * mirror choice by a fourth shifted coordinate. */
        uint32_t j = (uint32_t)k;
        mlight_path mp;
        if (!mlight_pick(c->mirrors, c->lights, cdf, total, s->p, o, frac1((float)j / (float)k_rays + shift[3]),
                         frac1(radical_inverse(j, 5) + shift[0]), frac1(radical_inverse(j, 2) + shift[1]),
                         frac1(radical_inverse(j, 3) + shift[2]), &mp))
            continue;
        if (!bsdf_same_side(b, mp.wi)) continue;
        vec3 f = bsdf_eval_diffuse(b, mp.wi);
        if (v3_is_zero(f)) continue;
        mlight_leg leg;
        c->st->shadow++;
        log_ray(c, o, mp.wi, mp.tm, 1);
        if (!mlight_to_mirror(c->emb, &mp, o, &leg)) continue;
        c->st->shadow++;
        log_ray(c, leg.o, leg.d, leg.dist, 1);
        bool crossed = false;
        vec3 tr = emb_occluded(c->emb, leg.o, leg.d, 0.0f, leg.dist)
                      ? integ_through_glass(c, leg.o, leg.d, leg.dist, leg.target, &crossed)
                      : v3s(1.0f);
        if (v3_is_zero(tr)) continue;
        float g = v3_dot(mp.wi, b->n) / (mp.pdf * (float)k_rays);
        sum = v3_add(sum, v3_scale(v3_mul(v3_mul(v3_mul(f, mp.m->rho), mp.lp.le), tr), g));
    }
    return finite3(sum) ? sum : v3s(0.0f);
}
