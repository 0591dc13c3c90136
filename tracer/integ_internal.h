/* integ_internal.h: what the integrator's files share: integrator.c (the
 * three modes' estimators, surfaces), integ_light.c (direct light from the
 * lamps and their images in plane mirrors, shadow rays through glass) and
 * integ_gather.c (drt's final gather of the radiosity solution). Small
 * inline helpers, and the functions one file gives the others; prefix
 * integ_. Internal to those three files. */
#ifndef CT_TRACER_INTEG_INTERNAL_H
#define CT_TRACER_INTEG_INTERNAL_H

#include <math.h>

#include "tracer/bsdf.h"
#include "tracer/integrator.h"

/* Which lobes a point's light samples evaluate, per mode. */
typedef enum direct_mode {
    DIRECT_ALL,         /* path: f_d + f_g, MIS against the whole bsdf's sampling */
    DIRECT_GLOSSY_MIS,  /* drt: f_d with weight 1, f_g MIS against the B glossy rays */
    DIRECT_GLOSSY_ONLY  /* reuse-diffuse: f_g only (diffuse comes from radiosity) */
} direct_mode;

/* Lamp samples by way of the mirrors per shading point: one per this many
 * shadow rays (K), rounded up. The mirrored light is smooth: on `table` at
 * 256x256 (docs/tracer.md) 4 samples instead of 1 cost 14 % more time per
 * sample and raise the PSNR at 1 and 16 spp by only 0.1 and 0.02 dB. */
#define MIRROR_LIGHT_SHARE 4

static inline float rnd(integ_ctx *c) { return rng_float(&c->rng); }

static inline bool finite3(vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

static inline vec3 clamp0(vec3 a) { return v3(bsdf_maxf(a.x, 0.0f), bsdf_maxf(a.y, 0.0f), bsdf_maxf(a.z, 0.0f)); }

/* v3_maxc and fminf, inlined with the same results (bsdf_maxf). */
static inline float maxc(vec3 a) { return bsdf_maxf(a.x, bsdf_maxf(a.y, a.z)); }
static inline float minf(float x, float y) { return x < y || y != y ? x : y; }

/* The lamps' reflective caustic (caustics.h) that the diffuse layer at h
 * sends back along a ray that arrived along d: rho_d / pi times the
 * irradiance interpolated as the mesh's values are; on the front side
 * only, as the mesh's values hold. */
static inline vec3 integ_caustic(const integ_ctx *c, const emb_hit *h, vec3 d)
{
    if (!c->caustic || v3_dot(d, h->rec->ng) >= 0.0f) return v3s(0.0f);
    vec3 e = integ_vertex_lerp(c->caustic, h);
    return v3_mul(v3_scale(c->bmats[h->mat].kd, (float)(1.0 / M_PI)), e);
}

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

/* A surface hit: its point, normals, material and light key. */
static inline void integ_make_surf(const integ_ctx *c, const emb_hit *h, vec3 d, integ_surf *s)
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

/* integ_light.c ------------------------------------------------------------ */

/* Fraction of light reaching o from target along the straight ray o + t d,
 * t in (0, dist), known to be blocked: 0 behind an opaque surface, glass
 * attenuates (*crossed set when it did). */
vec3 integ_through_glass(integ_ctx *c, vec3 o, vec3 d, float dist, vec3 target, bool *crossed);

/* integ_base_through_glass; reflected: without the emission of the surface
 * found (for the final gather). */
vec3 integ_through_glass_base(integ_ctx *c, const emb_hit *first, vec3 d, bool reflected);

/* Direct light at s from the K light samples (see direct_mode); nb glossy
 * rays compete in the MIS weights. */
vec3 integ_direct_light(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 wo, direct_mode mode, int nb);

/* The same from k_rays light samples. */
vec3 integ_direct_light_n(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 wo, direct_mode mode, int nb,
                          int k_rays);

/* Light reaching the diffuse layer at s from the lamps by way of one plane
 * mirror, from k_rays samples. */
vec3 integ_mirror_light_n(integ_ctx *c, const integ_surf *s, const bsdf *b, int k_rays);

/* integ_gather.c ----------------------------------------------------------- */

/* drt's indirect diffuse light at s by a final gather of the radiosity
 * solution (c->opt->gather_rays rays). */
vec3 integ_final_gather(integ_ctx *c, const integ_surf *s, const bsdf *b);

#endif
