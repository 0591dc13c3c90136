/* caustics.c: photons from the lamps through mirror and glass reflections,
 * gathered at a radiosity mesh's vertices (caustics.h). */
#include "tracer/caustics.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/grow.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "common/rng.h"
#include "common/timer.h"
#include "tracer/bsdf.h"

/* Reflections and glass crossings a photon is followed through. */
#define CAUS_MAX_EVENTS 16
/* Mirror and glass parts photons are aimed at (the largest ones). */
#define CAUS_MAX_TARGETS 64
/* Share of the photons aimed at them; the rest leave the lamp by the
 * cosine (every direction keeps a positive density). */
#define CAUS_AIMED 0.9f
/* Photons a task shoots, and vertices a task estimates: the work is cut
 * into the same pieces for any thread count, so the deposits come out in
 * photon order and the result does not depend on it. */
#define CAUS_PHOTON_TASK 8192u
#define CAUS_VERTEX_TASK 1024u

typedef struct deposit {
    vec3 p, n;   /* where it landed, the surface's front normal */
    vec3 pow;    /* its power */
} deposit;

/* A mirror or glass part's bounding sphere. */
typedef struct target {
    vec3 c;
    float r;
    uint32_t node;
} target;

typedef struct shooter {
    const emb_scene *e;
    const emb_mesh *m;
    const mlight_set *mirrors;
    double *cdf;        /* over the emissive triangles, by luminance x area */
    uint32_t *etri;     /* their mesh triangles */
    uint32_t nemit;
    double total;       /* sum of luminance x area */
    target tg[CAUS_MAX_TARGETS];
    uint32_t ntg;
    deposit *dep;       /* every task's deposits, in photon order */
    size_t ndep;
    const uint8_t *refract;   /* per part node: its glass refracts photons and blocks shadow rays; NULL: none */
} shooter;

static vec3 tri_corner(const emb_mesh *m, uint32_t t, int k) { return m->pos[m->tris[3 * t + (uint32_t)k]]; }

static int collect_emitters(shooter *s, ct_error *err)
{
    const emb_mesh *m = s->m;
    s->cdf = malloc(((size_t)m->ntris + 1) * sizeof *s->cdf);
    s->etri = malloc(((size_t)m->ntris + 1) * sizeof *s->etri);
    if (!s->cdf || !s->etri) return ct_fail(err, CT_ENOMEM, "caustics: out of memory for %u triangles", m->ntris);
    double sum = 0.0;
    for (uint32_t t = 0; t < m->ntris; t++) {
        float lum = v3_luminance(m->mats[m->tri_mat[t]].emission);
        if (!(lum > 0.0f)) continue;
        vec3 a = tri_corner(m, t, 0);
        float area = 0.5f * v3_len(v3_cross(v3_sub(tri_corner(m, t, 1), a), v3_sub(tri_corner(m, t, 2), a)));
        if (!(area > 0.0f)) continue;
        sum += (double)lum * (double)area;
        s->etri[s->nemit] = t;
        s->cdf[s->nemit++] = sum;
    }
    s->total = sum;
    return CT_OK;
}

/* Whether a point x of material mat and normal ng lies on one of the plane
 * mirrors whose lamp images drt samples (mirror_lights.h). */
static bool on_sampled_mirror(const mlight_set *ms, uint32_t mat, vec3 ng, vec3 x)
{
    for (uint32_t i = 0; ms && i < mlight_count(ms); i++) {
        const mlight_plane *p = mlight_get(ms, i);
        float scale = fmaxf(1.0f, fabsf(p->d));
        if (mlight_same_kind(p, mat, ng) && fabsf(mlight_side(p, x)) <= 1e-4f * scale && mlight_in_bounds(p, x))
            return true;
    }
    return false;
}

static bool specular(const scene_material *m) { return m->dielectric || mlight_material(m); }

/* The parts photons are aimed at: each part node's mirror and glass
 * triangles (those of sampled plane mirrors left out: one reflection there
 * is no caustic), as a sphere around their bounding box; the
 * CAUS_MAX_TARGETS largest. */
static int collect_targets(shooter *s, ct_error *err)
{
    const emb_mesh *m = s->m;
    uint32_t nn = m->nnodes ? m->nnodes : 1;
    vec3 *lo = malloc(nn * sizeof *lo), *hi = malloc(nn * sizeof *hi);
    if (!lo || !hi) {
        free(lo);
        free(hi);
        return ct_fail(err, CT_ENOMEM, "caustics: out of memory for %u parts", nn);
    }
    for (uint32_t i = 0; i < nn; i++) lo[i] = v3s(INFINITY), hi[i] = v3s(-INFINITY);
    for (uint32_t t = 0; t < m->ntris; t++) {
        uint32_t mat = m->tri_mat[t], node = m->tri_node[t] < nn ? m->tri_node[t] : 0;
        if (!specular(&m->mats[mat])) continue;
        vec3 a = tri_corner(m, t, 0), b = tri_corner(m, t, 1), c = tri_corner(m, t, 2);
        vec3 ng = v3_norm(v3_cross(v3_sub(b, a), v3_sub(c, a)));
        vec3 mid = v3_scale(v3_add(a, v3_add(b, c)), 1.0f / 3.0f);
        if (!m->mats[mat].dielectric && on_sampled_mirror(s->mirrors, mat, ng, mid)) continue;
        for (int k = 0; k < 3; k++) {
            lo[node] = v3_min(lo[node], tri_corner(m, t, k));
            hi[node] = v3_max(hi[node], tri_corner(m, t, k));
        }
    }
    for (uint32_t i = 0; i < nn; i++) {
        if (!(lo[i].x <= hi[i].x)) continue;
        target g = {v3_scale(v3_add(lo[i], hi[i]), 0.5f), 0.5f * v3_len(v3_sub(hi[i], lo[i])) * 1.001f, i};
        if (!(g.r > 0.0f)) continue;
        uint32_t at = s->ntg < CAUS_MAX_TARGETS ? s->ntg++ : CAUS_MAX_TARGETS;
        if (at == CAUS_MAX_TARGETS) {   /* full: replace the smallest if this is larger */
            uint32_t sm = 0;
            for (uint32_t k = 1; k < s->ntg; k++)
                if (s->tg[k].r < s->tg[sm].r) sm = k;
            if (s->tg[sm].r >= g.r) continue;
            at = sm;
        }
        s->tg[at] = g;
    }
    free(lo);
    free(hi);
    return CT_OK;
}

/* The cone of directions from p to a target: cos of its half angle (-1:
 * p inside, every direction) and its solid angle. */
static void cone_of(const target *g, vec3 p, vec3 *axis, float *cos_a, float *omega)
{
    vec3 dv = v3_sub(g->c, p);
    float d = v3_len(dv);
    if (d <= g->r) {
        *axis = v3(0.0f, 1.0f, 0.0f);
        *cos_a = -1.0f;
        *omega = 4.0f * (float)M_PI;
        return;
    }
    *axis = v3_scale(dv, 1.0f / d);
    float s = g->r / d;
    *cos_a = sqrtf(fmaxf(0.0f, 1.0f - s * s));
    *omega = 2.0f * (float)M_PI * (1.0f - *cos_a);
}

/* A cosine-weighted direction about n. */
static vec3 cosine_dir(vec3 n, float r1, float r2)
{
    float ct = sqrtf(1.0f - r1), st = sqrtf(r1), ph = 2.0f * (float)M_PI * r2;
    vec3 tx = fabsf(n.x) > 0.5f ? v3(0.0f, 1.0f, 0.0f) : v3(1.0f, 0.0f, 0.0f);
    vec3 bx = v3_norm(v3_cross(n, tx)), by = v3_cross(n, bx);
    return v3_add(v3_scale(n, ct), v3_add(v3_scale(bx, st * cosf(ph)), v3_scale(by, st * sinf(ph))));
}

/* A direction from the lamp point p (front ng): with probability
 * CAUS_AIMED uniform in the cone of a target picked by the solid angle it
 * fills over the lamp's front, else by the cosine; *pdf the mixture's
 * solid-angle density of the direction chosen (0: none to be had). */
static vec3 leave_lamp(const shooter *s, ct_rng *r, vec3 p, vec3 ng, float *pdf)
{
    float w[CAUS_MAX_TARGETS], om[CAUS_MAX_TARGETS], ca[CAUS_MAX_TARGETS], wsum = 0.0f;
    vec3 ax[CAUS_MAX_TARGETS];
    for (uint32_t j = 0; j < s->ntg; j++) {
        cone_of(&s->tg[j], p, &ax[j], &ca[j], &om[j]);
        /* facing: the lamp emits from its front only */
        float f = ca[j] < 0.0f ? 1.0f : v3_dot(ax[j], ng) + sqrtf(fmaxf(0.0f, 1.0f - ca[j] * ca[j]));
        w[j] = f > 0.0f ? (ca[j] < 0.0f ? 2.0f * (float)M_PI : om[j]) : 0.0f;
        wsum += w[j];
    }
    float q = wsum > 0.0f ? CAUS_AIMED : 0.0f;
    vec3 d;
    if (rng_float(r) < q) {
        float u = rng_float(r) * wsum, acc = 0.0f;
        uint32_t j = 0;
        for (; j + 1 < s->ntg; j++) {
            acc += w[j];
            if (u < acc) break;
        }
        if (ca[j] < 0.0f) {
            d = cosine_dir(ng, rng_float(r), rng_float(r));   /* inside the target: its whole front */
        } else {
            float ct = 1.0f - rng_float(r) * (1.0f - ca[j]), st = sqrtf(fmaxf(0.0f, 1.0f - ct * ct));
            float ph = 2.0f * (float)M_PI * rng_float(r);
            vec3 tx = fabsf(ax[j].x) > 0.5f ? v3(0.0f, 1.0f, 0.0f) : v3(1.0f, 0.0f, 0.0f);
            vec3 bx = v3_norm(v3_cross(ax[j], tx)), by = v3_cross(ax[j], bx);
            d = v3_add(v3_scale(ax[j], ct), v3_add(v3_scale(bx, st * cosf(ph)), v3_scale(by, st * sinf(ph))));
        }
    } else {
        d = cosine_dir(ng, rng_float(r), rng_float(r));
    }
    float cosl = v3_dot(d, ng), pc = fmaxf(cosl, 0.0f) / (float)M_PI;
    float p_d = (1.0f - q) * pc;
    for (uint32_t j = 0; q > 0.0f && j < s->ntg; j++) {
        if (!(w[j] > 0.0f)) continue;
        if (ca[j] < 0.0f) p_d += q * (w[j] / wsum) * pc;
        else if (v3_dot(d, ax[j]) >= ca[j]) p_d += q * (w[j] / wsum) / om[j];
    }
    *pdf = p_d;
    return d;
}

/* One task's deposits. */
typedef struct deposits {
    deposit *dep;
    size_t n, cap;
} deposits;

static int keep(deposits *ds, vec3 p, vec3 n, vec3 pow, ct_error *err)
{
    int rc = ct_grow((void **)&ds->dep, &ds->cap, ds->n + 1, sizeof *ds->dep, "caustic photons", err);
    if (rc) return rc;
    ds->dep[ds->n++] = (deposit){p, n, pow};
    return CT_OK;
}

/* One photon: a lamp point by luminance x area, a cosine direction about
 * its front, then the reflections and glass crossings until it lands on an
 * opaque surface. The crossings pass it straight, or refract it where the
 * glass blocks the shadow rays (s->refract): a photon carries power, so a
 * refraction changes its direction, not its power. */
static int shoot(const shooter *s, deposits *out, ct_rng *r, float unit_n, ct_error *err)
{
    const emb_mesh *m = s->m;
    double u = rng_double(r) * s->total;
    uint32_t lo = 0, hi = s->nemit - 1;
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (s->cdf[mid] < u) lo = mid + 1;
        else hi = mid;
    }
    uint32_t t = s->etri[lo];
    const scene_material *em = &m->mats[m->tri_mat[t]];
    vec3 a = tri_corner(m, t, 0), e1 = v3_sub(tri_corner(m, t, 1), a), e2 = v3_sub(tri_corner(m, t, 2), a);
    vec3 ng = v3_norm(v3_cross(e1, e2));
    float su = sqrtf(rng_float(r)), u2 = rng_float(r);
    vec3 p = v3_add(a, v3_add(v3_scale(e1, su * (1.0f - u2)), v3_scale(e2, su * u2)));
    /* Power: L_e cos over the densities of the point (lum / total by area)
     * and of the direction; unit_n carries total / N. */
    float pdf;
    vec3 d = leave_lamp(s, r, p, ng, &pdf);
    float cosl = v3_dot(d, ng);
    if (!(cosl > 0.0f) || !(pdf > 0.0f)) return CT_OK;
    vec3 pow = v3_scale(em->emission, unit_n * cosl / (v3_luminance(em->emission) * pdf));
    vec3 o = emb_offset_ray(p, ng);
    int reflections = 0;
    bool refracted = false;   /* crossed glass that blocks the shadow rays */
    bool first_on_image_mirror = false;
    for (int k = 0; k < CAUS_MAX_EVENTS; k++) {
        emb_hit h;
        if (!emb_intersect(s->e, o, d, 0.0f, INFINITY, &h)) return CT_OK;
        const scene_material *hm = &m->mats[h.mat];
        vec3 x = emb_hit_point(&h), n = h.rec->ng;
        float cosd = v3_dot(d, n);
        vec3 side = cosd < 0.0f ? n : v3_neg(n);   /* the side the photon came from */
        if (hm->dielectric) {
            rmesh_material g = rmesh_material_of(hm);
            /* Straight crossings are symmetric (rmesh_glass_pass: F on the
             * air side); a refraction from inside has its own eta, and total
             * internal reflection beyond the critical angle. */
            bool bends = s->refract && s->refract[h.node < m->nnodes ? h.node : 0];
            float eta = bends && cosd > 0.0f ? g.ior : 1.0f / g.ior, ct;
            if (rng_float(r) < rmesh_fresnel(fabsf(cosd), eta, &ct)) {
                reflections++;
                d = bsdf_reflect(v3_neg(d), side);
                o = emb_offset_ray(x, side);
            } else {
                pow = v3_mul(pow, hm->transmission);
                o = emb_offset_ray(x, v3_neg(side));
                if (bends) {
                    /* t = eta d + (eta cos_i - cos_t) n, n against d */
                    d = v3_norm(v3_add(v3_scale(d, eta), v3_scale(side, eta * fabsf(cosd) - ct)));
                    refracted = true;
                }
            }
            continue;
        }
        bool counts = refracted || reflections > 1 || (reflections == 1 && !first_on_image_mirror);
        if (counts && cosd < 0.0f && v3_maxc(hm->diffuse) > 0.0f) {
            int rc = keep(out, x, n, pow, err);
            if (rc) return rc;
        }
        float pm = mlight_material(hm) ? v3_maxc(hm->mirror) : 0.0f;
        if (!(pm > 0.0f) || rng_float(r) >= fminf(pm, 1.0f)) return CT_OK;
        pow = v3_scale(v3_mul(pow, hm->mirror), 1.0f / fminf(pm, 1.0f));
        if (reflections == 0) first_on_image_mirror = on_sampled_mirror(s->mirrors, h.mat, h.rec->ng, x);
        reflections++;
        d = bsdf_reflect(v3_neg(d), side);
        o = emb_offset_ray(x, side);
    }
    return CT_OK;
}

/* --- the density estimate --------------------------------------------------- */

typedef struct grid {
    float cell;
    vec3 lo;
    uint32_t nx, ny, nz;
    uint32_t *start;   /* nx*ny*nz + 1 offsets into idx */
    uint32_t *idx;     /* deposits by cell */
} grid;

static uint32_t cell_of(const grid *g, float v, float lo, uint32_t n)
{
    float c = (v - lo) / g->cell;
    if (!(c > 0.0f)) return 0;
    uint32_t i = (uint32_t)c;
    return i >= n ? n - 1 : i;
}

static int grid_build(grid *g, const deposit *dep, size_t n, vec3 lo, vec3 hi, float cell, ct_error *err)
{
    g->cell = cell;
    g->lo = lo;
    vec3 ext = v3_sub(hi, lo);
    /* At most about 2^24 cells: a coarser grid only costs more photons a look. */
    for (;;) {
        double nx = floor(ext.x / g->cell) + 1, ny = floor(ext.y / g->cell) + 1, nz = floor(ext.z / g->cell) + 1;
        if (nx * ny * nz <= (double)(1u << 24)) {
            g->nx = (uint32_t)nx, g->ny = (uint32_t)ny, g->nz = (uint32_t)nz;
            break;
        }
        g->cell *= 2.0f;
    }
    size_t nc = (size_t)g->nx * g->ny * g->nz;
    g->start = calloc(nc + 1, sizeof *g->start);
    g->idx = malloc((n ? n : 1) * sizeof *g->idx);
    uint32_t *key = malloc((n ? n : 1) * sizeof *key);
    if (!g->start || !g->idx || !key) {
        free(key);
        return ct_fail(err, CT_ENOMEM, "caustics: out of memory for a grid of %zu cells", nc);
    }
    for (size_t i = 0; i < n; i++) {
        vec3 p = dep[i].p;
        key[i] = (cell_of(g, p.z, lo.z, g->nz) * g->ny + cell_of(g, p.y, lo.y, g->ny)) * g->nx +
                 cell_of(g, p.x, lo.x, g->nx);
        g->start[key[i] + 1]++;
    }
    for (size_t c = 0; c < nc; c++) g->start[c + 1] += g->start[c];
    uint32_t *fill = malloc((nc ? nc : 1) * sizeof *fill);
    if (!fill) {
        free(key);
        return ct_fail(err, CT_ENOMEM, "caustics: out of memory for a grid of %zu cells", nc);
    }
    memcpy(fill, g->start, nc * sizeof *fill);
    for (size_t i = 0; i < n; i++) g->idx[fill[key[i]]++] = (uint32_t)i;
    free(fill);
    free(key);
    return CT_OK;
}

/* Power of the deposits within r of p whose surface faces as n does. */
static vec3 gather(const grid *g, const deposit *dep, vec3 p, vec3 n, float r, uint32_t *count)
{
    vec3 sum = v3s(0.0f);
    uint32_t x0 = cell_of(g, p.x - r, g->lo.x, g->nx), x1 = cell_of(g, p.x + r, g->lo.x, g->nx);
    uint32_t y0 = cell_of(g, p.y - r, g->lo.y, g->ny), y1 = cell_of(g, p.y + r, g->lo.y, g->ny);
    uint32_t z0 = cell_of(g, p.z - r, g->lo.z, g->nz), z1 = cell_of(g, p.z + r, g->lo.z, g->nz);
    float r2 = r * r;
    *count = 0;
    for (uint32_t z = z0; z <= z1; z++)
        for (uint32_t y = y0; y <= y1; y++) {
            size_t row = ((size_t)z * g->ny + y) * g->nx;
            for (uint32_t i = g->start[row + x0]; i < g->start[row + x1 + 1]; i++) {
                const deposit *q = &dep[g->idx[i]];
                if (v3_len2(v3_sub(q->p, p)) > r2 || v3_dot(q->n, n) < 0.7f) continue;
                sum = v3_add(sum, q->pow);
                (*count)++;
            }
        }
    return sum;
}

/* The radii a vertex's estimate chooses among: rmax, rmax/2, rmax/4, rmax/8. */
enum { CAUS_RINGS = 4 };

typedef struct estimate_job {
    const shooter *s;
    const grid *g;
    float r[CAUS_RINGS];
    const uint8_t *read;   /* per vertex: a corner of a diffuse triangle */
    vec3 *e;
} estimate_job;

/* Vertices [task * CAUS_VERTEX_TASK, ...): the smallest radius that holds
 * CAUS_KNN photons (a sharper caustic at the same noise), else rmax. */
static void estimate_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    const estimate_job *j = ctx;
    const emb_mesh *m = j->s->m;
    size_t i0 = task * CAUS_VERTEX_TASK, i1 = i0 + CAUS_VERTEX_TASK;
    if (i1 > m->nverts) i1 = m->nverts;
    for (size_t i = i0; i < i1; i++) {
        if (!j->read[i]) continue;
        vec3 n = m->nrm[i];
        float ln = v3_len(n);
        if (!(ln > 0.0f)) continue;
        n = v3_scale(n, 1.0f / ln);
        /* From the smallest radius out: where photons are dense (a focus,
         * where the estimate's cost is) the first look is the small one. */
        uint32_t cnt = 0;
        vec3 sum = v3s(0.0f);
        int k = CAUS_RINGS - 1;
        for (; k >= 0; k--) {
            sum = gather(j->g, j->s->dep, m->pos[i], n, j->r[k], &cnt);
            if (cnt >= CAUS_KNN) break;
        }
        if (k < 0) k = 0;
        if (cnt) j->e[i] = v3_scale(sum, 1.0f / ((float)M_PI * j->r[k] * j->r[k]));
    }
}

static int estimate(const shooter *s, ct_pool *pool, vec3 **out, ct_error *err)
{
    const emb_mesh *m = s->m;
    vec3 lo = v3s(INFINITY), hi = v3s(-INFINITY);
    for (uint32_t i = 0; i < m->nverts; i++) {
        lo = v3_min(lo, m->pos[i]);
        hi = v3_max(hi, m->pos[i]);
    }
    float rmax = CAUS_RADIUS_SHARE * v3_len(v3_sub(hi, lo));
    if (!(rmax > 0.0f)) return CT_OK;
    grid g = {0};
    /* cells of twice the smallest radius (table, one thread: 1.15 s; half
     * the largest 1.24 s; the smallest radius 1.36 s, its 10 million cells
     * 71 MB more at the peak) */
    int rc = grid_build(&g, s->dep, s->ndep, lo, hi, rmax / 4.0f, err);
    vec3 *e = rc ? NULL : calloc(m->nverts ? m->nverts : 1, sizeof *e);
    /* drt reads the estimate only at diffuse hits (integrator.c): the
     * vertices of glass and of pure mirrors need none, and glass standing
     * in its own focus made most of the estimate's work (table: the
     * glasses' vertices looking at the deposits under them, facing away). */
    uint8_t *read = rc ? NULL : calloc(m->nverts ? m->nverts : 1, 1);
    if (!rc && (!e || !read)) rc = ct_fail(err, CT_ENOMEM, "caustics: out of memory for %u vertices", m->nverts);
    for (uint32_t t = 0; !rc && t < m->ntris; t++) {
        const scene_material *mt = &m->mats[m->tri_mat[t]];
        if (mt->dielectric || !(v3_maxc(mt->diffuse) > 0.0f)) continue;
        for (int k = 0; k < 3; k++) read[m->tris[3 * t + (uint32_t)k]] = 1;
    }
    if (!rc) {
        estimate_job j = {.s = s, .g = &g, .read = read, .e = e};
        for (int k = 0; k < CAUS_RINGS; k++) j.r[k] = k ? j.r[k - 1] / 2.0f : rmax;
        pool_run(pool, (m->nverts + CAUS_VERTEX_TASK - 1) / CAUS_VERTEX_TASK, estimate_task, &j);
    }
    free(read);
    free(g.start);
    free(g.idx);
    if (rc) {
        free(e);
        return rc;
    }
    *out = e;
    return CT_OK;
}

typedef struct shoot_job {
    const shooter *s;
    uint32_t photons;
    uint64_t seed;
    float unit_n;
    deposits *tasks;   /* per task */
    int *rc;
    ct_error *err;
} shoot_job;

static void shoot_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    shoot_job *j = ctx;
    uint32_t i0 = (uint32_t)task * CAUS_PHOTON_TASK;
    uint32_t i1 = j->photons - i0 < CAUS_PHOTON_TASK ? j->photons : i0 + CAUS_PHOTON_TASK;
    for (uint32_t i = i0; i < i1 && !j->rc[task]; i++) {
        ct_rng r = rng_make(j->seed, 0xCA05u, i, 0);
        j->rc[task] = shoot(j->s, &j->tasks[task], &r, j->unit_n, &j->err[task]);
    }
}

/* Shoots the photons in tasks and joins their deposits in photon order. */
static int shoot_all(shooter *s, ct_pool *pool, uint32_t photons, uint64_t seed, ct_error *err)
{
    size_t nt = (photons + (size_t)CAUS_PHOTON_TASK - 1) / CAUS_PHOTON_TASK;
    shoot_job j = {.s = s, .photons = photons, .seed = seed, .unit_n = (float)(s->total / (double)photons),
                   .tasks = calloc(nt, sizeof *j.tasks), .rc = calloc(nt, sizeof *j.rc),
                   .err = calloc(nt, sizeof *j.err)};
    int rc = CT_OK;
    if (!j.tasks || !j.rc || !j.err) rc = ct_fail(err, CT_ENOMEM, "caustics: out of memory for %zu tasks", nt);
    if (!rc) pool_run(pool, nt, shoot_task, &j);
    size_t total = 0;
    for (size_t t = 0; !rc && t < nt; t++) {
        if (j.rc[t]) {
            rc = j.rc[t];
            *err = j.err[t];
        }
        total += j.tasks[t].n;
    }
    if (!rc && total) {
        s->dep = malloc(total * sizeof *s->dep);
        if (!s->dep) rc = ct_fail(err, CT_ENOMEM, "caustics: out of memory for %zu photons", total);
        for (size_t t = 0; !rc && t < nt; t++) {
            if (j.tasks[t].n) memcpy(s->dep + s->ndep, j.tasks[t].dep, j.tasks[t].n * sizeof *s->dep);
            s->ndep += j.tasks[t].n;
        }
    }
    for (size_t t = 0; j.tasks && t < nt; t++) free(j.tasks[t].dep);
    free(j.tasks);
    free(j.rc);
    free(j.err);
    return rc;
}

int caus_build(const emb_scene *e, const mlight_set *mirrors, uint32_t photons, uint64_t seed,
               const uint8_t *refract_nodes, int threads, vec3 **out, caus_stats *st, ct_error *err)
{
    *out = NULL;
    memset(st, 0, sizeof *st);
    const emb_mesh *m = emb_get_mesh(e);
    if (!photons || !m->vertex_reads) return CT_OK;
    bool any = false;
    for (uint32_t i = 0; i < m->nmats; i++) any = any || specular(&m->mats[i]);
    if (!any) return CT_OK;
    double t0 = ct_now();
    shooter s = {.e = e, .m = m, .mirrors = mirrors, .refract = refract_nodes};
    ct_pool *pool = NULL;
    int rc = collect_emitters(&s, err);
    if (!rc) rc = collect_targets(&s, err);
    if (!rc && s.nemit && s.ntg) {
        if (threads <= 0) threads = pool_cpus();
        if (threads > POOL_MAX_THREADS) threads = POOL_MAX_THREADS;
        if (threads > 1) rc = pool_new(threads, &pool, err);
        if (!rc) rc = shoot_all(&s, pool, photons, seed, err);
        st->photons = photons;
        st->deposits = s.ndep;
        if (!rc && s.ndep) rc = estimate(&s, pool, out, err);
    }
    pool_free(pool);
    free(s.cdf);
    free(s.etri);
    free(s.dep);
    st->seconds = ct_now() - t0;
    return rc;
}
