#include "tracer/integrator.h"

#include <math.h>
#include <string.h>

#include "tracer/bsdf.h"

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

typedef enum direct_mode {
    DIRECT_ALL,         /* path: f_d + f_g, MIS against the whole bsdf's sampling */
    DIRECT_GLOSSY_MIS,  /* drt: f_d with weight 1, f_g MIS against the B glossy rays */
    DIRECT_GLOSSY_ONLY  /* reuse-diffuse: f_g only (diffuse comes from radiosity) */
} direct_mode;

/* The emission mode of a ray leaving a mirror or dielectric: reflections see
 * lights fully; a refraction continues a straight line that shadow rays
 * already looked along, unless it started at the camera or a reflection. */
static inline emis_w after_delta(emis_w in, bool transmit)
{
    emis_w out = {EMIS_FULL, 0.0f, 1, in.from, in.from_key};
    if (transmit && in.mode != EMIS_FULL) out.mode = EMIS_NONE;
    return out;
}


static inline float rnd(integ_ctx *c) { return rng_float(&c->rng); }

static inline bool finite3(vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

static inline vec3 clamp0(vec3 a) { return v3(bsdf_maxf(a.x, 0.0f), bsdf_maxf(a.y, 0.0f), bsdf_maxf(a.z, 0.0f)); }

/* v3_maxc and fminf, inlined with the same results (bsdf_maxf). */
static inline float maxc(vec3 a) { return bsdf_maxf(a.x, bsdf_maxf(a.y, a.z)); }
static inline float minf(float x, float y) { return x < y || y != y ? x : y; }

static inline void log_ray(integ_ctx *c, vec3 o, vec3 d, float tfar, uint32_t shadow)
{
    trc_raylog *l = c->st->log;
    if (!l || !l->cap) return;
    uint64_t seq = l->seen++;
    size_t slot;
    if (l->n < l->cap) {
        slot = l->n++;
    } else {
        /* Reservoir sampling: keep ray seq with probability cap / (seq + 1). */
        l->state = ct_hash64(l->state + 0x9e3779b97f4a7c15ULL);
        uint64_t k = l->state % (seq + 1);
        if (k >= l->cap) return;
        slot = (size_t)k;
    }
    trc_ray *r = &l->rays[slot];
    r->seq = seq;
    r->o[0] = o.x; r->o[1] = o.y; r->o[2] = o.z;
    r->d[0] = d.x; r->d[1] = d.y; r->d[2] = d.z;
    r->tnear = 0.0f;
    r->tfar = tfar;
    r->shadow = shadow;
}

static void make_surf(const integ_ctx *c, const emb_hit *h, vec3 d, integ_surf *s)
{
    s->h = *h;
    /* The shading normal waits for bsdf setup (surf_bsdf): reuse-diffuse
     * needs none at most hits. */
    s->p = emb_hit_point(h);
    s->ng = h->rec->ng;
    s->m = &c->mesh->mats[h->mat];
    s->bm = &c->bmats[h->mat];
    /* Most hits select lights after their bsdf setup: start the load now
     * (with the normal facing the ray: the bsdf's b.ng). */
    s->lkey = light_key(c->lights, s->p, v3_dot(d, s->ng) <= 0.0f ? s->ng : v3_neg(s->ng));
}

/* The bsdf at s seen from wo (with its shading normal). */
static inline void surf_bsdf(const integ_surf *s, vec3 wo, bsdf *b)
{
    bsdf_setup(b, s->bm, emb_shading_normal(&s->h), s->ng, wo);
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
    make_surf(c, h, d, s);
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
    make_surf(c, &h, d, s);
    return true;
}

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
static vec3 through_glass(integ_ctx *c, vec3 o, vec3 d, float dist, vec3 target, bool *crossed)
{
    if (!c->has_dielectric) return v3s(0.0f);
    vec3 att = v3s(1.0f);
    for (int k = 0; k < RMESH_MAX_GLASS_CROSSINGS; k++) {
        emb_hit h;
        c->st->shadow++;
        log_ray(c, o, d, dist, 0);
        if (!emb_intersect(c->emb, o, d, 0.0f, dist, &h)) return att;
        const scene_material *m = &c->mesh->mats[h.mat];
        if (!m->dielectric) return v3s(0.0f);
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
static vec3 through_glass_base(integ_ctx *c, const emb_hit *first, vec3 d, bool reflected)
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
    return through_glass_base(c, first, d, false);
}

/* x - floor(x) for x in [0, 2), kept below 1 (float rounding). */
static inline float frac1(float x)
{
    float f = x >= 1.0f ? x - 1.0f : x;
    return f < 0x1.fffffep-1f ? f : 0x1.fffffep-1f;
}

/* The radical inverse of i in base b (2 or 3): the i-th Halton coordinate. */
static inline float radical_inverse(uint32_t i, uint32_t base)
{
    float inv = 1.0f / (float)base, f = inv, r = 0.0f;
    while (i) {
        r += f * (float)(i % base);
        i /= base;
        f *= inv;
    }
    return r;
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
    int n;            /* shadow rays to test */
} dl_batch;

/* Draws kn light samples at s, evaluates the bsdf towards them and sets up
 * the shadow rays of those that can contribute (see direct_light). */
static void dl_prepare(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 wo, direct_mode mode, int nb,
                       int k0, int kn, const light_sel *sel, const float shift[3], dl_batch *q)
{
    q->n = 0;
    int k_rays = c->opt->shadow_rays;
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
    int k_rays = c->opt->shadow_rays;
    for (int i = 0; i < q->n; i++) {
        const light_cand *lc = &q->cand[i];
        bool crossed = false;
        vec3 tr = q->blocked[i] ? through_glass(c, q->origin, lc->d, lc->dist, lc->target, &crossed) : v3s(1.0f);
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
static vec3 direct_light(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 wo, direct_mode mode,
                         int nb)
{
    int k_rays = c->opt->shadow_rays;
    vec3 sum = v3s(0.0f);
    if (!dl_active(c, b, mode)) return sum;
    dl_batch q;
    q.origin = emb_offset_ray(s->p, b->ng);
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

/* Lamp samples by way of the mirrors per shading point: one per this many
 * shadow rays (K), rounded up. The mirrored light is smooth: on `table` at
 * 256x256 (docs/tracer.md) 4 samples instead of 1 cost 14 % more time per
 * sample and raise the PSNR at 1 and 16 spp by only 0.1 and 0.02 dB. */
#define MIRROR_LIGHT_SHARE 4

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
static vec3 mirror_light_n(integ_ctx *c, const integ_surf *s, const bsdf *b, int k_rays)
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
                      ? through_glass(c, leg.o, leg.d, leg.dist, leg.target, &crossed)
                      : v3s(1.0f);
        if (v3_is_zero(tr)) continue;
        float g = v3_dot(mp.wi, b->n) / (mp.pdf * (float)k_rays);
        sum = v3_add(sum, v3_scale(v3_mul(v3_mul(v3_mul(f, mp.m->rho), mp.lp.le), tr), g));
    }
    return finite3(sum) ? sum : v3s(0.0f);
}

/* mirror_light with K / MIRROR_LIGHT_SHARE samples, rounded up. */
static vec3 mirror_light(integ_ctx *c, const integ_surf *s, const bsdf *b)
{
    return mirror_light_n(c, s, b, (c->opt->shadow_rays + MIRROR_LIGHT_SHARE - 1) / MIRROR_LIGHT_SHARE);
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
        L = v3_add(L, v3_mul(beta, direct_light(c, &s, &b, wo, DIRECT_ALL, 1)));
        float u0 = rnd(c), u1 = rnd(c), u2 = rnd(c);
        bsdf_sample bs;
        if (!bsdf_sample_all(&b, wo, u0, u1, u2, &bs)) break;
        beta = v3_mul(beta, bs.weight);
        if (bs.delta) {
            ew = after_delta(ew, bs.transmit);
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
 * reflection and refraction: both on the first branch_depth levels, below
 * one of them chosen with probability F (unbiased). li continues a ray. */
static vec3 scatter_specular(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 wo, int depth, emis_w ew,
                             int nb, radiance_fn li)
{
    vec3 L = v3s(0.0f);
    if (nb <= 0 && !(maxc(b->L.km) > 0.0f) && !b->L.dielectric) return L;
    emis_w refl = after_delta(ew, false), refr = after_delta(ew, true);
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
        float wrefl = f, wrefr = 1.0f - f;
        if (ok && depth >= c->opt->branch_depth) {
            /* One branch, picked by Fresnel: the weights F/F and (1-F)/(1-F). */
            if (rnd(c) < f) wrefr = 0.0f, wrefl = 1.0f;
            else wrefl = 0.0f, wrefr = 1.0f;
        }
        if (wrefl > 0.0f) L = v3_add(L, v3_scale(li(c, up, wr, depth + 1, refl), wrefl));
        if (ok && wrefr > 0.0f) {
            vec3 lt = li(c, emb_offset_ray(s->p, v3_neg(b->ng)), wt, depth + 1, refr);
            L = v3_add(L, v3_mul(lt, v3_scale(b->L.kt, wrefr * b->eta * b->eta)));
        }
    }
    return L;
}

/* Mirrors a gather ray follows (their light is not in the radiosity
 * solution, which has no specular transport) before it reads the mesh. */
#define GATHER_MIRROR_BOUNCES 4

/* The direct light leaving the diffuse layer of the surface at h towards
 * -d, as the radiosity solution's direct part counts it (rad_direct: the
 * lamps, and the lamps seen in plane mirrors), traced: one lamp sample
 * (chosen as the point's own shadow rays choose) and its shadow ray (glass
 * attenuates), and where the scene has mirrors, one in MIRROR_LIGHT_SHARE
 * landings a lamp sample by way of a mirror, weighted up by as much. */
static vec3 gather_direct(integ_ctx *c, const emb_hit *h, vec3 d)
{
    integ_surf s;
    make_surf(c, h, d, &s);
    bsdf b;
    surf_bsdf(&s, v3_neg(d), &b);
    if (!(b.L.p_d > 0.0f)) return v3s(0.0f);
    vec3 l = v3s(0.0f);
    if (mlight_count(c->mirrors) && rnd(c) * (float)MIRROR_LIGHT_SHARE < 1.0f)
        l = v3_scale(mirror_light_n(c, &s, &b, 1), (float)MIRROR_LIGHT_SHARE);
    if (light_count(c->lights) == 0) return l;
    light_sel sel;
    light_select_key(c->lights, s.lkey, s.p, &sel);
    float u0 = rnd(c), u1 = rnd(c), u2 = rnd(c);
    light_point lp;
    if (!light_sample(c->lights, &sel, u0, u1, u2, &lp) || lp.tri == h->tri) return l;
    vec3 wi = v3_sub(lp.p, s.p);
    float d2 = v3_len2(wi);
    if (!(d2 > 0.0f)) return l;
    wi = v3_scale(wi, 1.0f / sqrtf(d2));
    float cos_l = -v3_dot(wi, lp.n);
    if (cos_l <= 0.0f || !bsdf_same_side(&b, wi)) return l;
    float pl = lp.pdf_area * d2 / cos_l;
    if (!(pl > 0.0f && pl < INFINITY)) return l;
    vec3 f = bsdf_eval_diffuse(&b, wi);
    if (v3_is_zero(f)) return l;
    vec3 o = emb_offset_ray(s.p, b.ng), target = emb_offset_ray(lp.p, lp.n);
    vec3 sd = v3_sub(target, o);
    float dist = v3_len(sd);
    if (!(dist > 0.0f)) return l;
    sd = v3_scale(sd, 1.0f / dist);
    c->st->shadow++;
    log_ray(c, o, sd, dist, 1);
    bool crossed = false;
    vec3 tr = emb_occluded(c->emb, o, sd, 0.0f, dist) ? through_glass(c, o, sd, dist, target, &crossed) : v3s(1.0f);
    vec3 lamp = v3_scale(v3_mul(v3_mul(f, lp.le), tr), v3_dot(wi, b.n) / pl);
    return finite3(lamp) ? v3_add(l, lamp) : l;
}

/* What a final-gather ray from a diffuse point finds at h, coming along d:
 * the mesh's radiance there less the emission the point's shadow rays
 * already brought (through glass as the display shows it; behind a
 * surface's back nothing: radiosity's surfaces are one-sided), plus what a
 * mirror there reflects: the radiosity solution has a mirror as black, so
 * the ray is reflected on (at most GATHER_MIRROR_BOUNCES times) and reads
 * the mesh where it lands. Emission seen in a mirror is left out as well:
 * a light reached that way by a cosine-sampled ray is a caustic, rare and
 * bright, which in one-sample images is fireflies (the corrections of the
 * Cornell box's floor under its mirror sphere; on `table` at 256x256 a
 * one-sample image lost 1.8 dB with it, 16 samples 1.0 dB, and only from
 * about 64 samples on did it gain). What a mirror shows of the lit room
 * is kept. With TRC_GATHER_DIRECT_TRACE the direct part of that radiance
 * is traced instead of read (gather_direct): the mesh blurs its shadows
 * over the elements they cross, and a gather next to a contact reads them
 * at close range (docs/tracer.md, "Indirect light"). */
static vec3 gather_hit(integ_ctx *c, emb_hit h, vec3 d)
{
    vec3 sum = v3s(0.0f), att = v3s(1.0f);
    for (int k = 0;; k++) {
        const scene_material *hm = &c->mesh->mats[h.mat];
        vec3 ng = h.rec->ng;
        float cosd = v3_dot(d, ng);
        if (hm->dielectric) return v3_add(sum, v3_mul(att, through_glass_base(c, &h, d, true)));
        if (cosd >= 0.0f) return sum;
        vec3 l;
        if (c->opt->gather_direct == TRC_GATHER_DIRECT_TRACE) {
            l = clamp0(v3_sub(integ_vertex_lerp(c->rad->rad, &h), integ_vertex_lerp(c->rad->rad_direct, &h)));
            l = v3_add(l, gather_direct(c, &h, d));
        } else {
            l = clamp0(v3_sub(integ_vertex_lerp(c->rad->rad, &h), hm->emission));
        }
        sum = v3_add(sum, v3_mul(att, l));
        if (!(maxc(hm->mirror) > 0.0f) || k == GATHER_MIRROR_BOUNCES) return sum;
        att = v3_mul(att, hm->mirror);
        d = bsdf_reflect(v3_neg(d), ng);
        vec3 o = emb_offset_ray(emb_hit_point(&h), ng);
        c->st->secondary++;
        log_ray(c, o, d, INFINITY, 0);
        if (!emb_intersect(c->emb, o, d, 0.0f, INFINITY, &h)) return sum;
    }
}

/* drt's indirect diffuse light at s by a final gather from the radiosity
 * solution: G cosine-weighted rays (stratified, one random shift per
 * point) read the mesh's radiance where they land, less the emission the K
 * shadow rays already brought (seen through glass as the display shows it,
 * behind a surface's back nothing: radiosity's surfaces are one-sided).
 * Read at s itself, the mesh's own error and its Gouraud interpolation
 * are the image's floor; gathered, they are averaged over the hemisphere
 * one bounce away (docs/tracer.md, "Indirect light"). */
static vec3 final_gather(integ_ctx *c, const integ_surf *s, const bsdf *b)
{
    int n = c->opt->gather_rays;
    float su = rnd(c), sv = rnd(c);
    vec3 o = emb_offset_ray(s->p, b->ng), sum = v3s(0.0f);
    for (int i = 0; i < n; i++) {
        /* (i / n, radical inverse of i in base 2), shifted: stratified in
         * the first number for any n, each ray still uniform. */
        float u1 = frac1((float)i / (float)n + su);
        float u2 = frac1(radical_inverse((uint32_t)i, 2) + sv);
        bsdf_sample bs;
        if (!bsdf_sample_diffuse(b, u1, u2, &bs)) continue;
        emb_hit h;
        c->st->secondary++;
        log_ray(c, o, bs.wi, INFINITY, 0);
        if (!emb_intersect(c->emb, o, bs.wi, 0.0f, INFINITY, &h)) continue;
        sum = v3_add(sum, v3_mul(bs.weight, gather_hit(c, h, bs.wi)));
    }
    sum = v3_scale(sum, 1.0f / (float)n);
    return finite3(sum) ? sum : v3s(0.0f);
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
    L = v3_add(L, direct_light(c, &s, &b, wo, DIRECT_GLOSSY_MIS, nb));
    if (b.L.p_d > 0.0f) {
        if (mlight_count(c->mirrors)) L = v3_add(L, mirror_light(c, &s, &b));
        if (c->rad && opt->indirect == TRC_INDIRECT_GATHER && ew.mode == EMIS_FULL) {
            /* The first diffuse hit of the path (the camera's, or seen in
             * mirrors and through glass: the hits whose emission counts
             * fully); behind a glossy bounce the mesh's value at the hit is
             * blurred by the lobe anyway. */
            L = v3_add(L, final_gather(c, &s, &b));
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
    vec3 extra = direct_light(c, &s, &b, wo, DIRECT_GLOSSY_ONLY, nb);
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
