/* integ_gather.c: drt's final gather of the radiosity solution at the
 * first diffuse hit (integ_internal.h; docs/tracer.md, "Indirect light"). */
#include "tracer/integ_internal.h"

/* Mirrors (and glass faces' reflections) a gather ray follows (their light
 * is not in the radiosity solution, which has no specular transport)
 * before it reads the mesh. */
#define GATHER_MIRROR_BOUNCES 4

/* The direct light leaving the surface at h towards -d, traced: one lamp
 * sample (chosen as the point's own shadow rays choose) and its shadow ray
 * (glass attenuates), reflected by the diffuse and the glossy lobe, and
 * where the scene has mirrors, one in MIRROR_LIGHT_SHARE landings a lamp
 * sample by way of a mirror onto the diffuse layer, weighted up by as much.
 * What the radiosity solution's direct part counts (rad_direct: the lamps
 * on the diffuse layer, and the lamps seen in plane mirrors), and the
 * lamps' glossy reflection, which the solution leaves out: light a glossy
 * desk or table top throws onto the walls (office at 64 spp: +0.5 dB, its
 * 16x16-block rms error 10.0 -> 9.1 %; table +0.1 dB). Weight 1: no other
 * part of drt brings the lamps' light by a glossy bounce to a diffuse
 * surface. */
static vec3 gather_direct(integ_ctx *c, const integ_surf *s, const bsdf *b, vec3 d)
{
    if (!bsdf_has_smooth(b)) return v3s(0.0f);
    vec3 l = v3s(0.0f);
    if (mlight_count(c->mirrors) && rnd(c) * (float)MIRROR_LIGHT_SHARE < 1.0f)
        l = v3_scale(integ_mirror_light_n(c, s, b, 1), (float)MIRROR_LIGHT_SHARE);
    /* One sample of the whole non-delta bsdf, no competing strategy (nb 0:
     * MIS weight 1). */
    vec3 lamp = integ_direct_light_n(c, s, b, v3_neg(d), DIRECT_ALL, 0, 1);
    return finite3(lamp) ? v3_add(l, lamp) : l;
}

/* The room's light that a glossy layer at the landing reflects towards the
 * gathering point: one ray from its lobe, reading the mesh's radiance where
 * it lands less the emission there (the lamps' glossy reflection is
 * gather_direct's). The mesh holds the diffuse layer's light alone, so
 * without it the floor under a brushed metal sphere, lit mostly by the
 * lit floor around it by way of the sphere's underside, was half as bright
 * as path tracing shows it (docs/tracer.md, "Indirect light"). */
static vec3 gather_glossy(integ_ctx *c, const bsdf *b, const integ_surf *s, vec3 d)
{
    /* Traced by chance, in proportion to the glossy layer's share of the
     * smooth reflectance, and weighted up by as much: a floor of diffuse
     * 0.55 and glossy 0.12 (office's linoleum) takes a ray in one landing
     * of six, a brushed metal one at every landing. Always tracing it cost
     * office 8 % and table 10 % of drt's samples/s. */
    float q = b->L.p_g / (b->L.p_d + b->L.p_g);
    if (!(q > 0.0f) || (q < 1.0f && rnd(c) >= q)) return v3s(0.0f);
    bsdf_sample bs;
    if (!bsdf_sample_glossy(b, v3_neg(d), rnd(c), rnd(c), &bs)) return v3s(0.0f);
    bs.weight = v3_scale(bs.weight, 1.0f / q);
    vec3 o = emb_offset_ray(s->p, b->ng);
    emb_hit h;
    c->st->secondary++;
    log_ray(c, o, bs.wi, INFINITY, 0);
    if (!emb_intersect(c->emb, o, bs.wi, 0.0f, INFINITY, &h)) return v3s(0.0f);
    const scene_material *hm = &c->mesh->mats[h.mat];
    if (hm->dielectric || v3_dot(bs.wi, h.rec->ng) >= 0.0f) return v3s(0.0f);
    vec3 l = v3_mul(bs.weight, clamp0(v3_sub(integ_vertex_lerp(c->rad->rad, &h), hm->emission)));
    return finite3(l) ? l : v3s(0.0f);
}

/* What a final-gather ray from a diffuse point finds at h, coming along d:
 * the mesh's radiance there less the emission the point's shadow rays
 * already brought (through glass as the display shows it, and what the
 * glass's face reflects; behind a surface's back nothing: radiosity's
 * surfaces are one-sided), plus what a
 * mirror there reflects: the radiosity solution has a mirror as black, so
 * the ray is reflected on (at most GATHER_MIRROR_BOUNCES times) and reads
 * the mesh where it lands. Emission seen in a mirror is left out as well:
 * a light reached that way by a cosine-sampled ray is a caustic, rare and
 * bright, which in one-sample images is fireflies (the corrections of the
 * Cornell box's floor under its mirror sphere; on `table` at 256x256 a
 * one-sample image lost 1.8 dB with it, 16 samples 1.0 dB, and only from
 * about 64 samples on did it gain); that light comes from the lamps'
 * images in plane mirrors and the photons' caustic estimate (caustics.h),
 * at the gathering point itself. What a mirror shows of the lit room is
 * kept. With TRC_GATHER_DIRECT_TRACE the direct part of that radiance
 * is traced instead of read (gather_direct): the mesh blurs its shadows
 * over the elements they cross, and a gather next to a contact reads them
 * at close range (docs/tracer.md, "Indirect light"). */
/* Reflects *d off the surface at *h whose normal n faces the incoming
 * side and traces on into *h; false when the ray leaves the scene. */
static bool reflect_on(integ_ctx *c, emb_hit *h, vec3 *d, vec3 n)
{
    *d = bsdf_reflect(v3_neg(*d), n);
    vec3 o = emb_offset_ray(emb_hit_point(h), n);
    c->st->secondary++;
    log_ray(c, o, *d, INFINITY, 0);
    return emb_intersect(c->emb, o, *d, 0.0f, INFINITY, h);
}

static vec3 gather_hit(integ_ctx *c, emb_hit h, vec3 d)
{
    vec3 sum = v3s(0.0f), att = v3s(1.0f);
    for (int k = 0;; k++) {
        const scene_material *hm = &c->mesh->mats[h.mat];
        vec3 ng = h.rec->ng;
        float cosd = v3_dot(d, ng);
        if (hm->dielectric) {
            /* What the glass passes, and what its face reflects (F of the
             * light, more at a slant), followed as a mirror's with
             * probability F and weight 1, so that the extra ray costs what
             * it brings: without it a room beside a glass partition lost
             * that share of the light from the partition's side. */
            sum = v3_add(sum, v3_mul(att, integ_through_glass_base(c, &h, d, true)));
            rmesh_material x = rmesh_material_of(hm);
            float cos_t;
            if (k == GATHER_MIRROR_BOUNCES || rnd(c) >= rmesh_fresnel(fabsf(cosd), 1.0f / x.ior, &cos_t)) return sum;
            if (!reflect_on(c, &h, &d, cosd < 0.0f ? ng : v3_neg(ng))) return sum;
            continue;
        }
        if (cosd >= 0.0f) return sum;
        vec3 l;
        bool glossy = hm->glossy != SCENE_GLOSSY_NONE && maxc(hm->specular) > 0.0f;
        integ_surf s;
        bsdf b;
        if (glossy || c->opt->gather_direct == TRC_GATHER_DIRECT_TRACE) {
            integ_make_surf(c, &h, d, &s);
            surf_bsdf(&s, v3_neg(d), &b);
        }
        if (c->opt->gather_direct == TRC_GATHER_DIRECT_TRACE) {
            l = clamp0(v3_sub(integ_vertex_lerp(c->rad->rad, &h), integ_vertex_lerp(c->rad->rad_direct, &h)));
            l = v3_add(l, gather_direct(c, &s, &b, d));
        } else {
            l = clamp0(v3_sub(integ_vertex_lerp(c->rad->rad, &h), hm->emission));
        }
        if (glossy) l = v3_add(l, gather_glossy(c, &b, &s, d));
        sum = v3_add(sum, v3_mul(att, l));
        if (!(maxc(hm->mirror) > 0.0f) || k == GATHER_MIRROR_BOUNCES) return sum;
        att = v3_mul(att, hm->mirror);
        if (!reflect_on(c, &h, &d, ng)) return sum;
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
vec3 integ_final_gather(integ_ctx *c, const integ_surf *s, const bsdf *b)
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
