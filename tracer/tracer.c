#include "tracer/tracer.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "tracer/bsdf.h"
#include "tracer/caustics.h"
#include "tracer/glass_parts.h"
#include "tracer/embree_scene.h"
#include "tracer/integrator.h"
#include "tracer/lights.h"
#include "tracer/mirror_lights.h"

#if defined(__x86_64__) || defined(__SSE__)
#include <xmmintrin.h>
/* Flush-to-zero and denormals-are-zero while tracing: Embree runs much
 * slower on denormals (it warns about it), and setting them on every entry
 * keeps results identical whatever the calling thread's own mode is. */
static unsigned fpu_enter(void)
{
    unsigned old = _mm_getcsr();
    _mm_setcsr(old | 0x8040u);
    return old;
}
static void fpu_leave(unsigned old) { _mm_setcsr(old); }
#else
static unsigned fpu_enter(void) { return 0; }
static void fpu_leave(unsigned old) { (void)old; }
#endif

struct trc_tracer {
    trc_options opt;
    const ct_scene *scene;
    const ct_radmesh *rad;
    emb_scene *emb;
    light_set *lights;
    mlight_set *mirrors;
    bsdf_mat *bmats;     /* per scene material */
    bool has_dielectric;
    vec3 *caustic;       /* per mesh vertex: reflective caustic irradiance (drt with a mesh); NULL: none */
    uint8_t *glass_bends;   /* per part node: glass whose light refracted paths bring (NULL: none) */
    caus_stats caus;
};

void trc_options_default(trc_options *o, trc_mode mode)
{
    memset(o, 0, sizeof *o);
    o->mode = mode;
    o->seed = 1;
    if (mode == TRC_MODE_PATH) {
        o->shadow_rays = 1;
        o->branch = 1;
        o->branch_depth = 1;
        o->fresnel_depth = 1;
        o->depth = 64;
    } else {
        o->shadow_rays = 4;
        o->branch = 4;
        o->branch_depth = 1;
        /* A wine glass's bowl is a shell of four surfaces: with both
         * branches on its first three, a sample keeps the reflections and
         * the light through it that a chance pick of the weaker branch
         * leaves to other samples (table, every pixel once at 512x512,
         * seeds 1-6: +0.27 dB for 9-11 % more rays; glossy splitting on a
         * second level gave +0.29 dB for 31 %; docs/tracer.md). */
        o->fresnel_depth = 3;
        /* A ray through a wine glass crosses four surfaces before it
         * reaches the table behind, and its solid foot keeps rays inside
         * for several more; at 5 levels those ended black (table, every
         * pixel once at 1024x1024: +0.15 dB, rays +7 %; docs/tracer.md). */
        o->depth = 8;
    }
    o->indirect = TRC_INDIRECT_GATHER;
    o->gather_rays = 4;
    o->gather_direct = TRC_GATHER_DIRECT_TRACE;
    o->caustic_photons = mode == TRC_MODE_DRT ? TRC_CAUSTIC_PHOTONS : 0;
    /* The straight model is right for panes and wrong where glass bends
     * light (Cornell's sphere: 13 % blocks' rms against refracted path
     * tracing; docs/tracer.md, "Light through glass, refracted"). */
    o->glass_light = TRC_GLASS_AUTO;
}

const char *trc_mode_name(trc_mode m)
{
    switch (m) {
    case TRC_MODE_PATH: return "path";
    case TRC_MODE_DRT: return "drt";
    case TRC_MODE_REUSE: return "reuse-diffuse";
    }
    return "?";
}

const char *trc_indirect_name(trc_indirect i)
{
    switch (i) {
    case TRC_INDIRECT_MESH: return "mesh";
    case TRC_INDIRECT_GATHER: return "gather";
    }
    return "?";
}

const char *trc_gather_direct_name(trc_gather_direct g)
{
    switch (g) {
    case TRC_GATHER_DIRECT_MESH: return "mesh";
    case TRC_GATHER_DIRECT_TRACE: return "trace";
    }
    return "?";
}

const char *trc_glass_light_name(trc_glass_light g)
{
    switch (g) {
    case TRC_GLASS_STRAIGHT: return "straight";
    case TRC_GLASS_REFRACTED: return "refracted";
    case TRC_GLASS_AUTO: return "auto";
    }
    return "?";
}

int trc_options_check(const trc_options *o, ct_error *err)
{
    if (o->shadow_rays < 1 || o->shadow_rays > 4096)
        return ct_fail(err, CT_EINVAL, "shadow rays %d outside 1..4096", o->shadow_rays);
    if (o->branch < 1 || o->branch > 4096)
        return ct_fail(err, CT_EINVAL, "branch %d outside 1..4096", o->branch);
    if (o->branch_depth < 0 || o->branch_depth > 1024)
        return ct_fail(err, CT_EINVAL, "branch depth %d outside 0..1024", o->branch_depth);
    if (o->fresnel_depth < 0 || o->fresnel_depth > 1024)
        return ct_fail(err, CT_EINVAL, "Fresnel depth %d outside 0..1024", o->fresnel_depth);
    if (o->depth < 0 || o->depth > 1024)
        return ct_fail(err, CT_EINVAL, "depth %d outside 0..1024", o->depth);
    if (o->indirect != TRC_INDIRECT_MESH && o->indirect != TRC_INDIRECT_GATHER)
        return ct_fail(err, CT_EINVAL, "indirect light %d unknown", (int)o->indirect);
    if (o->gather_rays < 1 || o->gather_rays > 4096)
        return ct_fail(err, CT_EINVAL, "gather rays %d outside 1..4096", o->gather_rays);
    if (o->gather_direct != TRC_GATHER_DIRECT_MESH && o->gather_direct != TRC_GATHER_DIRECT_TRACE)
        return ct_fail(err, CT_EINVAL, "gather direct light %d unknown", (int)o->gather_direct);
    if (o->caustic_photons < 0 || o->caustic_photons > TRC_CAUSTIC_PHOTONS_MAX)
        return ct_fail(err, CT_EINVAL, "caustic photons %d outside 0..%d", o->caustic_photons,
                       TRC_CAUSTIC_PHOTONS_MAX);
    if (o->glass_light != TRC_GLASS_STRAIGHT && o->glass_light != TRC_GLASS_REFRACTED &&
        o->glass_light != TRC_GLASS_AUTO)
        return ct_fail(err, CT_EINVAL, "glass light %d unknown", (int)o->glass_light);
    /* reuse-diffuse's light is the radiosity solution's, which passes glass
     * straight: auto is straight there, refracted cannot be had. */
    if (o->glass_light == TRC_GLASS_REFRACTED && o->mode == TRC_MODE_REUSE)
        return ct_fail(err, CT_EINVAL, "glass light \"%s\" is for path tracing and drt only (mode %s)",
                       trc_glass_light_name(o->glass_light), trc_mode_name(o->mode));
    return CT_OK;
}

int trc_new(const ct_scene *scene, const ct_radmesh *rad, const trc_options *o, trc_tracer **out,
            ct_error *err)
{
    *out = NULL;
    if (o->mode == TRC_MODE_REUSE && !rad)
        return ct_fail(err, CT_EINVAL, "mode reuse-diffuse needs a radiosity mesh");
    int crc = trc_options_check(o, err);
    if (crc == CT_OK && rad) crc = rmesh_check_nodes(rad, scene, err);
    if (crc) return crc;
    trc_tracer *t = calloc(1, sizeof *t);
    if (!t) return ct_fail(err, CT_ENOMEM, "out of memory");
    t->opt = *o;
    t->opt.device_config = NULL;
    if (o->mode == TRC_MODE_REUSE) t->opt.glass_light = TRC_GLASS_STRAIGHT;
    t->scene = scene;
    t->rad = rad;
    emb_mesh mesh = rad ? emb_mesh_of_radmesh(rad, scene) : emb_mesh_of_scene(scene);
    int rc = emb_new(&mesh, o->device_config, &t->emb, err);
    if (rc) goto fail;
    rc = light_build(t->emb, &t->lights, err);
    if (rc) goto fail;
    if (t->opt.glass_light == TRC_GLASS_AUTO) {
        rc = gparts_bending(emb_get_mesh(t->emb), &t->glass_bends, err);
        if (rc) goto fail;
    } else if (t->opt.glass_light == TRC_GLASS_REFRACTED) {
        /* every part's glass blocks shadow rays and refracts photons */
        uint32_t nn = emb_get_mesh(t->emb)->nnodes;
        t->glass_bends = malloc(nn ? nn : 1);
        if (!t->glass_bends) {
            rc = ct_fail(err, CT_ENOMEM, "out of memory for %u glass parts", nn);
            goto fail;
        }
        memset(t->glass_bends, 1, nn ? nn : 1);
    }
    /* Only drt with a radiosity mesh samples mirrored lamps (integrator.c,
     * mirror_light): without a mesh its path-traced indirect light finds them. */
    if (rad && o->mode == TRC_MODE_DRT) {
        rc = mlight_build(t->emb, t->lights, &t->mirrors, err);
        if (rc) goto fail;
        rc = caus_build(t->emb, t->mirrors, (uint32_t)o->caustic_photons, o->seed, t->glass_bends, 0,
                        &t->caustic, &t->caus, err);
        if (rc) goto fail;
    }
    t->bmats = malloc((scene->nmats ? scene->nmats : 1) * sizeof *t->bmats);
    if (!t->bmats) {
        rc = ct_fail(err, CT_ENOMEM, "out of memory for %u materials", scene->nmats);
        goto fail;
    }
    for (uint32_t i = 0; i < scene->nmats; i++) {
        bsdf_mat_init(&t->bmats[i], &scene->mats[i]);
        if (scene->mats[i].dielectric) t->has_dielectric = true;
    }
    *out = t;
    return CT_OK;
fail:
    trc_free(t);
    return rc;
}

void trc_free(trc_tracer *t)
{
    if (!t) return;
    light_free(t->lights);
    mlight_free(t->mirrors);
    free(t->caustic);
    free(t->glass_bends);
    free(t->bmats);
    emb_free(t->emb);
    free(t);
}

void trc_light_choice(const trc_tracer *t, uint32_t *emitters, bool *spatial, double *gain)
{
    *emitters = light_emitters(t->lights);
    *spatial = light_is_spatial(t->lights);
    *gain = light_spatial_gain(t->lights);
}

void trc_caustic_stats(const trc_tracer *t, uint64_t *photons, uint64_t *landed, double *seconds)
{
    *photons = t->caus.photons;
    *landed = t->caus.deposits;
    *seconds = t->caus.seconds;
}

const trc_options *trc_get_options(const trc_tracer *t) { return &t->opt; }

static void init_ctx(const trc_tracer *t, integ_ctx *c, trc_stats *st)
{
    c->emb = t->emb;
    c->mesh = emb_get_mesh(t->emb);
    c->lights = t->lights;
    c->mirrors = t->mirrors;
    c->caustic = t->caustic;
    c->bmats = t->bmats;
    c->rad = t->rad;
    c->opt = &t->opt;
    /* refracted: every part's glass bends, so no shadow ray looks through
     * glass (not even the ray that would find it) */
    c->has_dielectric = t->has_dielectric && t->opt.glass_light != TRC_GLASS_REFRACTED;
    c->glass_bends = t->glass_bends;
    c->st = st;
}

/* The primary part of a record, first half: request fields and the primary
 * ray (its hit record's load started). */
static bool primary_start(integ_ctx *c, const trc_view *v, const cam_rays *vp, const ct_request *r,
                          ct_sample *out, emb_hit *h, vec3 *d)
{
    memset(out, 0, sizeof *out);
    out->request_id = r->id;
    out->epoch = r->epoch;
    out->px = r->px;
    out->py = r->py;
    out->node = UINT32_MAX;
    out->tri = UINT32_MAX;
    /* A position that is not a number has no ray: a miss, not an Embree query. */
    if (!isfinite(r->px) || !isfinite(r->py)) return false;
    *d = cam_rays_dir(vp, r->px, r->py);
    return integ_primary_start(c, v->cam.eye, *d, h);
}

/* Second half, for a hit: the surface, the hit fields and L_base. */
static void primary_finish(const trc_tracer *t, integ_ctx *c, emb_hit *h, vec3 d, ct_sample *out,
                           integ_surf *s)
{
    integ_primary_finish(c, h, d, s);
    out->flags |= CT_SAMPLE_HIT;
    if (!v3_is_zero(s->m->emission)) out->flags |= CT_SAMPLE_EMISSIVE;
    out->node = s->h.node;
    out->tri = s->h.tri;
    out->u = s->h.u;
    out->v = s->h.v;
    out->hit = s->p;
    if (t->rad) {
        /* Glass is see-through in the interactive solution: its L_base is
         * what the display draws there, the surfaces behind it. */
        out->l_base = s->m->dielectric ? integ_base_through_glass(c, &s->h, d) : integ_vertex_lerp(t->rad->rad, &s->h);
        out->flags |= CT_SAMPLE_HAS_BASE;
    }
}

/* Both halves: the primary part of a record: request fields, hit, L_base. */
static bool primary(const trc_tracer *t, integ_ctx *c, const trc_view *v, const cam_rays *vp,
                    const ct_request *r, ct_sample *out, integ_surf *s, vec3 *d)
{
    emb_hit h;
    if (!primary_start(c, v, vp, r, out, &h, d)) return false;
    primary_finish(t, c, &h, *d, out, s);
    return true;
}

/* Requests whose primary rays are traced back to back before any is shaded. */
#define PRIMARY_BATCH 16

void trc_trace(const trc_tracer *t, const trc_view *v, const ct_request *req, size_t n,
               ct_sample *out, trc_stats *st)
{
    integ_ctx c;
    init_ctx(t, &c, st);
    cam_rays vp;
    cam_rays_init(&vp, &v->cam, v->width, v->height);
    unsigned fpu = fpu_enter();
    /* First the primary rays of up to PRIMARY_BATCH requests, then their
     * hit records (whose loads the first loop started), then their shading:
     * independent Embree queries in a row overlap in the CPU (the next
     * traversal starts while the last one's loads are in flight), and so do
     * the cache misses on the hit triangles' records. A sample's value does
     * not depend on it: the primary hit is a function of the request alone
     * and the shading draws its random numbers after it. */
    integ_surf s[PRIMARY_BATCH];
    emb_hit h[PRIMARY_BATCH];
    vec3 d[PRIMARY_BATCH];
    bool hit[PRIMARY_BATCH];
    for (size_t i0 = 0; i0 < n; i0 += PRIMARY_BATCH) {
        size_t m = n - i0 < PRIMARY_BATCH ? n - i0 : PRIMARY_BATCH;
        for (size_t k = 0; k < m; k++) {
            st->samples++;
            hit[k] = primary_start(&c, v, &vp, &req[i0 + k], &out[i0 + k], &h[k], &d[k]);
        }
        /* The radiosity at the hits (L_base; drt also takes its direct
         * part for the indirect light) is three more random reads per
         * array: started together once the records are in. */
        if (t->rad)
            for (size_t k = 0; k < m; k++) {
                if (!hit[k]) continue;
                integ_vertex_prefetch(t->rad->rad, &h[k]);
                if (t->opt.mode == TRC_MODE_DRT) integ_vertex_prefetch(t->rad->rad_direct, &h[k]);
            }
        for (size_t k = 0; k < m; k++)
            if (hit[k]) primary_finish(t, &c, &h[k], d[k], &out[i0 + k], &s[k]);
        for (size_t k = 0; k < m; k++) {
            if (!hit[k]) continue;
            const ct_request *r = &req[i0 + k];
            c.rng = rng_make(t->opt.seed, r->id, r->epoch, TRC_DIM_TRACE);
            vec3 base = out[i0 + k].l_base;
            vec3 l = integ_radiance(&c, v->cam.eye, d[k], &s[k], &base);
            /* A NaN or infinity (a degenerate frame) would poison every
             * average it enters; such a sample counts as black. */
            if (!(isfinite(l.x) && isfinite(l.y) && isfinite(l.z))) l = v3s(0.0f);
            out[i0 + k].l_hq = l;
        }
    }
    fpu_leave(fpu);
}

void trc_trace_primary(const trc_tracer *t, const trc_view *v, const ct_request *req, size_t n,
                       ct_sample *out, trc_stats *st)
{
    integ_ctx c;
    init_ctx(t, &c, st);
    cam_rays vp;
    cam_rays_init(&vp, &v->cam, v->width, v->height);
    unsigned fpu = fpu_enter();
    for (size_t i = 0; i < n; i++) {
        integ_surf s;
        vec3 d;
        st->samples++;
        primary(t, &c, v, &vp, &req[i], &out[i], &s, &d);
    }
    fpu_leave(fpu);
}

static int by_seq(const void *a, const void *b)
{
    uint64_t x = ((const trc_ray *)a)->seq, y = ((const trc_ray *)b)->seq;
    return x < y ? -1 : x > y;
}

void trc_raylog_sort(trc_raylog *log)
{
    if (log->n > 1) qsort(log->rays, log->n, sizeof *log->rays, by_seq);
}

uint64_t trc_replay(const trc_tracer *t, const trc_raylog *log, int as_traced)
{
    uint64_t hits = 0;
    unsigned fpu = fpu_enter();
    for (size_t i = 0; i < log->n; i++) {
        const trc_ray *r = &log->rays[i];
        vec3 o = v3(r->o[0], r->o[1], r->o[2]), d = v3(r->d[0], r->d[1], r->d[2]);
        if (as_traced && r->shadow) hits += emb_raw_occluded(t->emb, o, d, r->tnear, r->tfar);
        else hits += emb_raw_intersect(t->emb, o, d, r->tnear, r->tfar) < INFINITY;
    }
    fpu_leave(fpu);
    return hits;
}

typedef struct par_trace {
    const trc_tracer *t;
    const trc_view *v;
    const ct_request *req;
    ct_sample *out;
    size_t n, per;
    bool primary;
    trc_stats st[POOL_MAX_THREADS];
} par_trace;

static void trace_part(void *ctx, int worker, size_t part)
{
    par_trace *j = ctx;
    size_t b = part * j->per, e = b + j->per < j->n ? b + j->per : j->n;
    trc_stats *st = &j->st[worker];
    if (j->primary) trc_trace_primary(j->t, j->v, j->req + b, e - b, j->out + b, st);
    else trc_trace(j->t, j->v, j->req + b, e - b, j->out + b, st);
}

void trc_trace_par(const trc_tracer *t, ct_pool *pool, const trc_view *v, const ct_request *req, size_t n,
                   ct_sample *out, bool primary, trc_stats *st)
{
    if (n == 0) return;
    int threads = pool_threads(pool);
    par_trace *j = calloc(1, sizeof *j);
    if (!j) {
        /* (a few KiB of counters: without them, on this thread alone) */
        trc_stats mine = {0};
        if (primary) trc_trace_primary(t, v, req, n, out, &mine);
        else trc_trace(t, v, req, n, out, &mine);
        if (st) {
            st->primary += mine.primary; st->secondary += mine.secondary;
            st->shadow += mine.shadow; st->samples += mine.samples;
        }
        return;
    }
    size_t parts = (size_t)threads * 4;
    j->t = t; j->v = v; j->req = req; j->out = out; j->n = n; j->primary = primary;
    j->per = (n + parts - 1) / parts;
    if (j->per < 8) j->per = 8;
    pool_run(pool, (n + j->per - 1) / j->per, trace_part, j);
    if (st)
        for (int i = 0; i < threads; i++) {
            st->primary += j->st[i].primary; st->secondary += j->st[i].secondary;
            st->shadow += j->st[i].shadow; st->samples += j->st[i].samples;
        }
    free(j);
}
