/* rad_solve.c: the hierarchical radiosity driver: refinement passes (links
 * refined by the B*F*A oracle against the current solution), Jacobi
 * gather/push-pull iterations until the residual is under the tolerance,
 * each a loop over input patches on one thread pool (common/pool.h), the
 * memory cap, and the stats. (About 700 lines on purpose: the passes,
 * the iterations and the jobs they hand the pool share one worker state
 * and one order of steps, which one file keeps in view.) */
#include "radiosity/rad_internal.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/fsutil.h"
#include "common/log.h"
#include "common/pool.h"
#include "common/rng.h"
#include "common/timer.h"

/* Bump when a change alters solutions, so old caches become stale. */
#define RAD_SOLVER_VERSION 27u   /* 2: --max-triangles shared out per patch and pass; 3: the error
                                 * oracle, unbiased factors and visibility, the final gather;
                                 * 4: lamps seen in plane mirrors; 5: light passes glass;
                                 * 6: clusters weigh their patches by openness; 7: cluster links
                                 * whose rays were all blocked stay (refined later); 8: a
                                 * cluster's radiosity as seen from the receiver's side; 9: contact
                                 * regions refined further, vertices look at their own visibility
                                 * of partly hidden sources; 10: element links whose value rays
                                 * were all blocked stay when their deciding rays were not;
                                 * 11: dim receivers refined further (--dim-floor); 12: vertices
                                 * hidden under objects take the value at the contact line; 13: factors
                                 * averaged over Gauss points from a tenth of the distance; 14: a
                                 * leaf's inherited light taken at its centre (rad_leaf_scales);
                                 * 15: Gauss points from a fortieth of the distance; 16: vertices
                                 * look at element links whose rays were all blocked; 17: glossy
                                 * and mirror layers pass their light on (rho_t); 18: the mesh
                                 * carries the scene's shading normals (rad_mesh.c); 19: the
                                 * triangle budget shared by area, count and refused wants;
                                 * 20: cluster links looked at before they are refined, the
                                 * first pass's lit area, segment ends traced from both
                                 * sides, value rays that miss take a 256-ray look; 21: a
                                 * cluster link scales the cluster's mean by the radiosity
                                 * its rays saw (bk); 22: deciding rays turned per receiver;
                                 * 23: near sources seen by their parts in the final gather,
                                 * the final gather at the leaves (--gather-passes); 24: the
                                 * leaves' steps keep the links' total light, vertices
                                 * gather with their shading normals; 25: sources pass on
                                 * their exposed part's radiosity (rad_src_B); 26: receivers
                                 * on curved patches split along their shading terminator;
                                 * 27: glass passes on what its faces reflect */

void rad_params_default(rad_params *p)
{
    memset(p, 0, sizeof *p);
    p->error = 1e-5;
    p->dim_floor = 0.1;
    p->min_area = 2e-7;
    p->max_triangles = 2000000;
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    p->threads = n > 0 ? (int)(n < 64 ? n : 64) : 1;
    p->memory_cap_mb = 4096;
    p->vis_rays = 4;
    p->shadow_rays = 16;
    p->vertex_rays = 8;
    /* Off: two steps take the Cornell box's contacts most of the way to
     * the truth but cost 1.4-2 times the solve, and where no curved object
     * stands on a surface they change nothing measurable (docs/radiosity.md,
     * "The final gather at the leaves"). */
    p->gather_passes = 0;
    p->tolerance = 1e-3;
    p->max_iterations = 100;
    p->max_passes = 8;
    p->crease_deg = 30.0;
    p->seed = 1;
    p->mirror_samples = 32;
}

int rad_params_check(const rad_params *p, ct_error *err)
{
    if (!(p->error > 0.0 && p->error < 1.0))
        return ct_fail(err, CT_EINVAL, "--error %g outside (0, 1)", p->error);
    if (!(p->dim_floor >= 0.0 && p->dim_floor <= 1.0))
        return ct_fail(err, CT_EINVAL, "--dim-floor %g outside [0, 1]", p->dim_floor);
    if (!(p->min_area > 0.0 && p->min_area < 1.0))
        return ct_fail(err, CT_EINVAL, "--min-area %g outside (0, 1)", p->min_area);
    if (p->max_triangles < 1) return ct_fail(err, CT_EINVAL, "--max-triangles must be at least 1");
    if (p->threads < 1 || p->threads > 256)
        return ct_fail(err, CT_EINVAL, "--threads %d outside [1, 256]", p->threads);
    if (p->memory_cap_mb < 16) return ct_fail(err, CT_EINVAL, "--memory-cap %u MB is below 16", p->memory_cap_mb);
    if (p->vis_rays < 1 || p->vis_rays > 1024)
        return ct_fail(err, CT_EINVAL, "--vis-rays %d outside [1, 1024]", p->vis_rays);
    if (p->shadow_rays < 1 || p->shadow_rays > 1024)
        return ct_fail(err, CT_EINVAL, "--shadow-rays %d outside [1, 1024]", p->shadow_rays);
    if (p->vertex_rays < 0 || p->vertex_rays > 1024)
        return ct_fail(err, CT_EINVAL, "--vertex-rays %d outside [0, 1024]", p->vertex_rays);
    if (p->gather_passes < 0 || p->gather_passes > 16)
        return ct_fail(err, CT_EINVAL, "--gather-passes %d outside [0, 16]", p->gather_passes);
    if (!(p->tolerance > 0.0 && p->tolerance < 1.0))
        return ct_fail(err, CT_EINVAL, "--tolerance %g outside (0, 1)", p->tolerance);
    if (p->max_iterations < 1) return ct_fail(err, CT_EINVAL, "--max-iterations must be at least 1");
    if (p->max_passes < 1) return ct_fail(err, CT_EINVAL, "--max-passes must be at least 1");
    if (p->mirror_samples < 0 || p->mirror_samples > 4096)
        return ct_fail(err, CT_EINVAL, "--mirror-samples %d outside [0, 4096]", p->mirror_samples);
    if (!(p->crease_deg >= 0.0 && p->crease_deg <= 180.0))
        return ct_fail(err, CT_EINVAL, "--crease-angle %g outside [0, 180]", p->crease_deg);
    return CT_OK;
}

static uint64_t mix(uint64_t h, uint64_t v) { return ct_hash64(h ^ (v + 0x9e3779b97f4a7c15ULL + (h << 6))); }

static uint64_t mix_f(uint64_t h, double d)
{
    uint64_t b;
    memcpy(&b, &d, sizeof b);
    return mix(h, b);
}

static uint64_t mix_bytes(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    uint64_t f = 1469598103934665603ULL;   /* FNV-1a, then mixed */
    for (size_t i = 0; i < n; i++) f = (f ^ p[i]) * 1099511628211ULL;
    return mix(h, f);
}

uint64_t rad_solution_hash(const ct_scene *s, const rad_params *p)
{
    uint64_t h = mix(0x63746d657368ULL, RAD_SOLVER_VERSION);
    if (s->source_hash) {
        h = mix(h, s->source_hash);
    } else {
        /* A scene built in code: its geometry and materials are its content. */
        h = mix_bytes(h, s->pos, (size_t)s->nverts * sizeof *s->pos);
        h = mix_bytes(h, s->nrm, (size_t)s->nverts * sizeof *s->nrm);
        h = mix_bytes(h, s->tris, (size_t)s->ntris * 3 * sizeof *s->tris);
        h = mix_bytes(h, s->tri_mat, (size_t)s->ntris * sizeof *s->tri_mat);
        h = mix_bytes(h, s->tri_node, (size_t)s->ntris * sizeof *s->tri_node);
        h = mix_bytes(h, s->tri_prim, (size_t)s->ntris * sizeof *s->tri_prim);
        for (uint32_t i = 0; i < s->nmats; i++) {
            h = mix_bytes(h, &s->mats[i].diffuse, sizeof(vec3));
            h = mix_bytes(h, &s->mats[i].emission, sizeof(vec3));
            h = mix_bytes(h, &s->mats[i].mirror, sizeof(vec3));
        }
        for (uint32_t i = 0; i < s->nnodes; i++) h = mix_bytes(h, s->nodes[i].name, strlen(s->nodes[i].name));
    }
    h = mix_f(h, p->error);
    h = mix_f(h, p->dim_floor);
    h = mix_f(h, p->min_area);
    h = mix(h, p->max_triangles);
    h = mix(h, (uint64_t)p->vis_rays);
    h = mix(h, (uint64_t)p->shadow_rays);
    h = mix(h, (uint64_t)p->vertex_rays);
    h = mix(h, (uint64_t)p->gather_passes);
    h = mix_f(h, p->tolerance);
    h = mix(h, (uint64_t)p->max_iterations);
    h = mix(h, (uint64_t)p->max_passes);
    h = mix_f(h, p->crease_deg);
    h = mix(h, p->seed);
    h = mix(h, (uint64_t)p->mirror_samples);
    return h ? h : 1;
}

int rad_cache_default(const ct_scene *s, const rad_params *p, int make, char *out, size_t cap, ct_error *err)
{
    char dir[4096];
    int rc = fs_user_cache_dir(dir, sizeof dir, make, err);
    if (rc) return rc;
    int n = snprintf(out, cap, "%s/%016" PRIx64 ".ctmesh", dir, rad_solution_hash(s, p));
    if (n < 0 || (size_t)n >= cap) return ct_fail(err, CT_EINVAL, "%s: the cache file's path is too long", dir);
    return CT_OK;
}

int rad_cached_solve(const ct_scene *s, const rad_params *p, const char *cache_path,
                     rad_progress_fn progress, void *user, ct_radmesh *out, rad_stats *st,
                     int *from_cache, ct_error *why, ct_error *err)
{
    ct_error load_err;
    *from_cache = 0;
    if (why) ct_error_clear(why);
    uint64_t h = rad_solution_hash(s, p);
    if (rmesh_load(cache_path, h, out, &load_err) == CT_OK) {
        *from_cache = 1;
        if (st) memset(st, 0, sizeof *st);
        if (st) {
            st->triangles = out->ntris;
            st->vertices = out->nverts;
        }
        return CT_OK;
    }
    if (why) {
        /* A first run has no cache: say so plainly, not as a failed open. */
        if (access(cache_path, F_OK) != 0 && errno == ENOENT)
            ct_fail(why, CT_OK, "no cached solution at %s yet", cache_path);
        else
            *why = load_err;
    }
    int rc = rad_solve(s, p, progress, user, out, st, err);
    if (rc) return rc;
    rc = rmesh_save(out, cache_path, err);
    if (rc) rmesh_free(out);
    return rc;
}

/* ------------------------------------------------------------------------ */
/* Worker threads over input patches                                        */

/* Publishing a patch's tree (what sources see of it next pass) also makes
 * its openness from the links just refined (patch_openness). */
typedef enum { JOB_REFINE, JOB_GATHER, JOB_PUBLISH, JOB_LEAF_SCALES, JOB_DIRECT, JOB_CLUSTER_BK } job_kind;

typedef struct worker {
    rad_ctx *c;
    job_kind kind;
    rad_tls tls;
    double residual;
    double max_reflected;   /* largest reflected radiosity (B - E) of a leaf */
    double absorbed;
    int final;
    int rc;
    rad_progress_fn progress;
    void *user;
} worker;

/* Gather over e's links and push-pull below it; returns e's area-weighted
 * radiosity for the next buffer. */
static vec3 push_pull(worker *w, uint32_t ei, vec3 Hdown, vec3 Hddown, vec3 *Bd_out)
{
    rad_ctx *c = w->c;
    rad_elem *e = rad_el(c, ei);
    const rad_patch *p = &c->patches[e->patch];
    int cur = c->cur, nxt = 1 - cur;
    vec3 H, Hd;
    /* The direct part needs no iteration (only the final gather computes
     * it: it reads the elements, which is slower), except on plane mirrors,
     * which pass on the rest (rho_ml). */
    bool direct = w->final || v3_maxc(p->rho_ml) > 0.0f;
    rad_elem_links(c, e, cur, direct, &H, &Hd);
    /* A leaf's inherited light as its own centre sees it (rad_leaf_scales). */
    if (e->child == RAD_NONE) {
        Hdown = v3_scale(Hdown, 1.0f + e->hk);
        Hddown = v3_scale(Hddown, 1.0f + e->hkd);
    }
    vec3 Ht = v3_add(Hdown, H), Hdt = v3_add(Hddown, Hd);
    vec3 B, Bd;
    if (e->child == RAD_NONE) {
        if (c->mirrors) {
            /* The lamps seen in mirrors: a fixed source term, sampled once
             * per leaf (rad_mirror.c), direct light. */
            if (!e->hm_done) {
                e->Hm = rad_mirror_leaf(c, e);
                e->hm_done = 1;
            }
            Ht = v3_add(Ht, e->Hm);
            Hdt = v3_add(Hdt, e->Hm);
        }
        /* What the element passes on (rho_t); a plane mirror's lamp
         * images pass its direct light on (rho_ml). */
        vec3 refl = v3_max(v3_sub(v3_mul(p->rho_t, Ht), v3_mul(p->rho_ml, Hdt)), v3s(0.0f));
        B = v3_add(p->E, refl);
        Bd = v3_add(p->E, v3_mul(p->rho, Hdt));
        vec3 old = *rad_B(c, cur, ei);
        double r = v3_maxabs(v3_sub(rad_src_B(B, p->E, e->exposed), old));
        if (r > w->residual) w->residual = r;
        double rmax = v3_maxc(refl);
        if (rmax > w->max_reflected) w->max_reflected = rmax;
        /* (Glass passes on what its links bring, attenuated:
         * rad_vis_transmit. What a plane mirror's images pass on is not
         * absorbed either.) */
        if (w->final && !c->scene->mats[p->mat].dielectric)
            w->absorbed += (double)v3_avg(v3_mul(v3_sub(v3s(1.0f), p->rho_t), Ht)) * e->area;
    } else {
        B = Bd = v3s(0.0f);
        for (uint32_t i = 0; i < 4; i++) {
            uint32_t ci = e->child + i;
            vec3 cbd;
            vec3 cb = push_pull(w, ci, Ht, Hdt, &cbd);
            float a = rad_el(c, ci)->area;
            B = v3_madd(B, cb, a);
            Bd = v3_madd(Bd, cbd, a);
        }
        float inv = e->area > 0.0f ? 1.0f / e->area : 0.0f;
        B = v3_scale(B, inv);
        Bd = v3_scale(Bd, inv);
    }
    *rad_B(c, nxt, ei) = rad_src_B(B, p->E, e->exposed);
    e->Bd = Bd;
    *Bd_out = Bd;
    return B;
}

/* The sum of the factors of e's links and its ancestors' (sumf: its
 * parent's), area-weighted over its leaves. */
static double subtree_factor(const rad_ctx *c, uint32_t ei, double sumf)
{
    const rad_elem *e = rad_el(c, ei);
    const rad_patch *p = &c->patches[e->patch];
    for (uint32_t i = 0; i < e->nlinks; i++) sumf += p->links[e->link_off + i].ff;
    if (e->child == RAD_NONE) return sumf * e->area;
    double s = 0.0;
    for (uint32_t k = 0; k < 4; k++) s += subtree_factor(c, e->child + k, sumf);
    return s;
}

/* Patch p's openness: the mean over it of the summed factors of the links
 * it gathers through, about 1 where its hemisphere is open and 0 where it
 * is covered (a ceiling under a lamp's housing, a wall behind a shelf). */
static void patch_openness(rad_ctx *c, uint32_t pi)
{
    rad_patch *p = &c->patches[pi];
    const rad_elem *r = rad_el(c, p->root);
    double f = r->area > 0.0f ? subtree_factor(c, p->root, 0.0) / r->area : 1.0;
    p->open = (float)fmin(1.0, fmax(0.0, f));
}

static void publish_tree(rad_ctx *c, uint32_t root)
{
    uint32_t stack[4 * RAD_MAX_DEPTH + 8];
    int sp = 0;
    stack[sp++] = root;
    while (sp) {
        rad_elem *e = rad_el(c, stack[--sp]);
        e->child_pub = e->child;
        if (e->child != RAD_NONE)
            for (uint32_t i = 0; i < 4; i++) stack[sp++] = e->child + i;
    }
}

/* The lit area and the area-weighted mean reflected radiosity over it
 * (brightest channel), from the last pass's solution: what --min-area is a
 * share of, and what a dim receiver is measured against (refine_elem,
 * --dim-floor). A patch counts as lit when it emits or reflects more than a
 * millionth of the radiosity its light meets on average (the power-weighted
 * mean, which dark area cannot dilute). Over all the area, a 2 km ground
 * plane no light reached made a closed room's smallest element 0.8 m^2 and
 * every wall "bright" (docs/radiosity.md, "Scale"). */
#define LIT_SHARE 1e-6
static double reflected(const rad_ctx *c, const rad_patch *pa)
{
    vec3 b = rad_mean_B(c, c->cur, pa->root);
    return v3_maxc(v3_max(v3_sub(b, pa->E), v3s(0.0f)));
}

/* The first pass has no solution to measure: its lit area is that of the
 * patches that emit or see an emitter (JOB_DIRECT: rays drawn by the
 * emitters' power, as rad_cluster_hidden draws them). With all the area,
 * a closed room beside a 2 km ground plane could not split its walls in
 * the first pass; the cluster links it then split instead stayed split,
 * and the room ended with 4.2 million links against 0.75 million alone
 * (26 s against 7 s; docs/radiosity.md, "Scale"). */
static double direct_area(const rad_ctx *c)
{
    double area = 0.0;
    for (uint32_t p = 0; p < c->npatches; p++)
        if (c->patches[p].direct) area += rad_el(c, c->patches[p].root)->area;
    return area > 0.0 ? area : c->total_area;
}

static void lit_stats(const rad_ctx *c, double *lit_area, double *mean)
{
    double s1 = 0.0, s2 = 0.0;
    for (uint32_t p = 0; p < c->npatches; p++) {
        double a = rad_el(c, c->patches[p].root)->area, b = reflected(c, &c->patches[p]);
        s1 += a * b;
        s2 += a * b * b;
    }
    double cut = s1 > 0.0 ? LIT_SHARE * s2 / s1 : 0.0, area = 0.0, sum = 0.0;
    for (uint32_t p = 0; p < c->npatches; p++) {
        const rad_patch *pa = &c->patches[p];
        double a = rad_el(c, pa->root)->area, b = reflected(c, pa);
        if (!(b > cut) && !(v3_maxc(pa->E) > 0.0f)) continue;
        area += a;
        sum += a * b;
    }
    /* Nothing reflects (black materials only): no lit area to speak of,
     * and the oracle would refine receivers whose light nobody sees. */
    *lit_area = s1 > 0.0 && area > 0.0 ? area : c->total_area;
    *mean = area > 0.0 ? sum / area : 0.0;
}

/* Patches per pool task: enough to keep the hand-out counter cold, few
 * enough that the last tasks of a pass balance. */
#define JOB_BATCH 16u

typedef struct job {
    rad_ctx *c;
    worker *ws;   /* one per pool worker */
} job;

static void job_task(void *ctx, int wi, size_t task)
{
    const job *j = ctx;
    worker *w = &j->ws[wi];
    rad_ctx *c = j->c;
    uint32_t b = (uint32_t)task * JOB_BATCH;
    if (atomic_load(&c->failed)) return;
    uint32_t e = b + JOB_BATCH < c->npatches ? b + JOB_BATCH : c->npatches;
    for (uint32_t p = b; p < e; p++) {
        if (w->kind == JOB_REFINE) {
            int rc = rad_refine_patch(c, &w->tls, p);
            if (rc) {
                w->rc = rc;
                atomic_store(&c->failed, 1);
                return;
            }
        } else if (w->kind == JOB_GATHER) {
            vec3 bd;
            push_pull(w, c->patches[p].root, v3s(0.0f), v3s(0.0f), &bd);
        } else if (w->kind == JOB_DIRECT) {
            rad_patch *pa = &c->patches[p];
            pa->direct = v3_maxc(pa->E) > 0.0f ||
                         (c->nclusters &&
                          !rad_cluster_hidden(c, rad_el(c, pa->root), RAD_CLUSTER_BIT, c->prm.shadow_rays));
        } else if (w->kind == JOB_CLUSTER_BK) {
            rad_cluster_bk(c, p);
        } else if (w->kind == JOB_LEAF_SCALES) {
            if (rad_leaf_scales(c, p)) {
                w->rc = CT_ENOMEM;
                atomic_store(&c->failed, 1);
                return;
            }
        } else {
            publish_tree(c, c->patches[p].root);
            patch_openness(c, p);
        }
    }
    /* Progress from the calling thread only: the callback is not
     * thread-safe. */
    if (wi == 0 && w->progress && w->kind == JOB_REFINE) {
        char msg[96];
        snprintf(msg, sizeof msg, "pass %d: refining links (%u/%u patches)", c->pass + 1, e, c->npatches);
        w->progress(w->user, (double)e / c->npatches, msg);
    }
}

/* One pass of `kind` over every patch on the solver's pool; ws holds one
 * worker state per pool thread (its scratch kept across passes). */
static int run_job(rad_ctx *c, worker *ws, int n, job_kind kind, int final)
{
    for (int i = 0; i < n; i++) {
        ws[i].kind = kind;
        ws[i].residual = 0.0;
        ws[i].max_reflected = 0.0;
        ws[i].absorbed = 0.0;
        ws[i].final = final;
        ws[i].rc = 0;
    }
    job j = {c, ws};
    pool_run(c->pool, (c->npatches + JOB_BATCH - 1) / JOB_BATCH, job_task, &j);
    for (int i = 0; i < n; i++)
        if (ws[i].rc) return ws[i].rc;
    return atomic_load(&c->failed) ? CT_ENOMEM : 0;
}

/* Cluster radiosity for the next buffer (rad_cluster_B): clusters are
 * numbered in pre-order, so children come after parents and a reverse
 * sweep sees them first. Each patch weighs by its area times its openness
 * (a covered patch, nothing sees it, counts for nothing) times its normal's
 * component towards each of the six axis directions. */
static void update_clusters(rad_ctx *c)
{
    int nxt = 1 - c->cur;
    for (uint32_t i = c->nclusters; i-- > 0;) {
        rad_cluster *k = &c->clusters[i];
        vec3 NB[6];
        float W[6];
        for (int d = 0; d < 6; d++) {
            NB[d] = v3s(0.0f);
            W[d] = 0.0f;
        }
        for (int j = 0; j < 2; j++) {
            uint32_t ch = k->child[j];
            if (ch & RAD_CLUSTER_BIT) {
                const rad_cluster *q = &c->clusters[ch & RAD_ID_MASK];
                for (int d = 0; d < 6; d++) {
                    NB[d] = v3_add(NB[d], q->NB[nxt][d]);
                    W[d] += q->W[nxt][d];
                }
            } else {
                const rad_elem *e = rad_el(c, ch);
                const rad_patch *p = &c->patches[e->patch];
                float a = e->area * p->open;
                float nc[3] = {p->n.x, p->n.y, p->n.z};
                vec3 b = *rad_B(c, nxt, ch);
                for (int d = 0; d < 6; d++) {
                    float f = (d & 1) ? -nc[d / 2] : nc[d / 2];
                    if (!(f > 0.0f)) continue;
                    NB[d] = v3_madd(NB[d], b, a * f);
                    W[d] += a * f;
                }
            }
        }
        memcpy(k->NB[nxt], NB, sizeof NB);
        memcpy(k->W[nxt], W, sizeof W);
    }
}

/* Gathers and pushes/pulls until the largest change, relative to the
 * brightest reflected radiosity, is under tol, or max_it times; *residual
 * receives the last change. tp: the pass's start (debug lines). */
static int iterate(rad_ctx *c, worker *ws, int max_it, double tol, double tp, rad_stats *st, double *residual)
{
    const rad_params *prm = &c->prm;
    for (int it = 0; it < max_it; it++) {
        int rc = run_job(c, ws, prm->threads, JOB_GATHER, 0);
        if (rc) return rc;
        update_clusters(c);
        c->cur = 1 - c->cur;
        st->iterations++;
        double res = 0.0, scale = 0.0;
        for (int i = 0; i < prm->threads; i++) {
            res = fmax(res, ws[i].residual);
            scale = fmax(scale, ws[i].max_reflected);
        }
        /* Relative to the brightest reflected light: emitters are orders
         * of magnitude brighter and would hide a slow convergence. */
        *residual = res = scale > 0.0 ? res / scale : 0.0;
        if (ws[0].progress) {
            char msg[128];
            snprintf(msg, sizeof msg, "pass %d: iteration %d, residual %.2e, %u elements", c->pass + 1, it + 1, res,
                     c->nelems);
            ws[0].progress(ws[0].user, res > 0.0 ? fmax(0.0, fmin(1.0, log(res) / log(prm->tolerance))) : 1.0, msg);
        }
        ct_debug("radiosity", "pass %d iteration %d: residual %.3e (%.2f s into the pass)", c->pass + 1, it + 1, res,
                 ct_now() - tp);
        if (res < tol) break;
    }
    return 0;
}

/* Pulls the leaves' radiosity (buffer b) up to every element of e's tree. */
static vec3 pull_tree(rad_ctx *c, int b, uint32_t ei, vec3 *Bd)
{
    rad_elem *e = rad_el(c, ei);
    const rad_patch *pa = &c->patches[e->patch];
    if (e->child == RAD_NONE) {
        *Bd = e->Bd;
        return rad_mean_B(c, b, ei);
    }
    vec3 B = v3s(0.0f), D = v3s(0.0f);
    for (uint32_t k = 0; k < 4; k++) {
        vec3 cd;
        vec3 cb = pull_tree(c, b, e->child + k, &cd);
        float a = rad_el(c, e->child + k)->area;
        B = v3_madd(B, cb, a);
        D = v3_madd(D, cd, a);
    }
    float inv = e->area > 0.0f ? 1.0f / e->area : 0.0f;
    B = v3_scale(B, inv);
    e->Bd = *Bd = v3_scale(D, inv);
    *rad_B(c, b, ei) = rad_src_B(B, pa->E, e->exposed);
    return B;
}

/* One step of the final gather at every leaf's centre (rad_gather_leaves)
 * into the next buffer, pulled up the trees and into the clusters; the
 * power the leaves absorb then into *absorbed. The links' values of a leaf
 * are what its links bring with their receivers' visibility: a leaf that
 * inherits a link from an ancestor partly hidden from the source takes the
 * ancestor's visible share, where its own may be none (the floor under the
 * Cornell box's sphere: its links brought 0.131 where rays from its
 * vertices saw 0.104, docs/radiosity.md). The mesh's vertices look at their
 * own visibility in the final gather, but they gathered from those leaves,
 * and the floor and the sphere lit each other up. Each step here gives
 * the leaves what their own centres see, as the vertices will. */
static int regather_leaves(rad_ctx *c, double *absorbed)
{
    uint32_t nl = 0, cap = c->nelems ? c->nelems : 1;
    uint32_t *leaf = malloc(cap * sizeof *leaf);
    vec3 *B = malloc(cap * sizeof *B), *Bd = malloc(cap * sizeof *Bd), *H = malloc(cap * sizeof *H);
    int rc = leaf && B && Bd && H ? CT_OK : CT_ENOMEM;
    for (uint32_t p = 0; p < c->npatches && !rc; p++) {
        uint32_t stack[4 * RAD_MAX_DEPTH + 8];
        int sp = 0;
        stack[sp++] = c->patches[p].root;
        while (sp) {
            uint32_t ei = stack[--sp];
            const rad_elem *e = rad_el(c, ei);
            if (e->child == RAD_NONE) leaf[nl++] = ei;
            else for (uint32_t k = 0; k < 4; k++) stack[sp++] = e->child + k;
        }
    }
    if (!rc) rc = rad_gather_leaves(c, leaf, nl, B, Bd, H);
    if (!rc) {
        int nxt = 1 - c->cur;
        double ab = 0.0;
        for (uint32_t i = 0; i < nl; i++) {
            rad_elem *e = rad_el(c, leaf[i]);
            const rad_patch *p = &c->patches[e->patch];
            *rad_B(c, nxt, leaf[i]) = rad_src_B(B[i], p->E, e->exposed);
            e->Bd = Bd[i];
            if (!c->scene->mats[p->mat].dielectric)
                ab += (double)v3_avg(v3_mul(v3_sub(v3s(1.0f), p->rho_t), H[i])) * e->area;
        }
        for (uint32_t p = 0; p < c->npatches; p++) {
            vec3 d;
            pull_tree(c, nxt, c->patches[p].root, &d);
        }
        update_clusters(c);
        c->cur = nxt;
        *absorbed = ab;
    }
    free(leaf);
    free(B);
    free(Bd);
    free(H);
    return rc;
}

static int cap_error(rad_ctx *c, ct_error *err)
{
    return ct_fail(err, CT_ENOMEM,
                   "radiosity: memory cap of %u MB reached (%u elements); raise --memory-cap, "
                   "--error or --min-area", c->prm.memory_cap_mb, c->nelems);
}

int rad_solve(const ct_scene *s, const rad_params *prm, rad_progress_fn progress, void *user,
              ct_radmesh *out, rad_stats *st, ct_error *err)
{
    double t0 = ct_now();
    memset(out, 0, sizeof *out);
    rad_stats dummy;
    if (!st) st = &dummy;
    memset(st, 0, sizeof *st);
    int rc = rad_params_check(prm, err);
    if (rc) return rc;
    if (s->ntris == 0) return ct_fail(err, CT_EEMPTY, "radiosity: scene '%s' has no triangles", s->name);

    rad_ctx *c = calloc(1, sizeof *c);
    if (!c) return ct_fail(err, CT_ENOMEM, "radiosity: out of memory");
    c->scene = s;
    c->prm = *prm;
    c->cap_bytes = (uint64_t)prm->memory_cap_mb << 20;
    pthread_mutex_init(&c->alloc_lock, NULL);
    worker *ws = calloc((size_t)prm->threads, sizeof *ws);
    if (!ws) {
        rc = ct_fail(err, CT_ENOMEM, "radiosity: out of memory");
        goto done;
    }
    /* Without worker threads the caller solves alone (pool NULL). */
    if (prm->threads > 1 && pool_new(prm->threads, &c->pool, err) != CT_OK) {
        ct_warn("radiosity", "%s: solving on one thread", err->msg);
        c->pool = NULL;
    }
    for (int i = 0; i < prm->threads; i++) {
        ws[i].c = c;
        ws[i].progress = progress;
        ws[i].user = user;
    }

    rc = rad_build_patches(c, err);
    if (rc) goto done;
    if (c->emitted <= 0.0) {
        rc = ct_fail(err, CT_EEMPTY, "radiosity: scene '%s' has no emitting surface", s->name);
        goto done;
    }
    c->eps = prm->error * c->emitted;
    if (progress) progress(user, 0.0, "building the visibility scene");
    rc = rad_vis_new(s, prm->threads, &c->vis, err);
    if (rc) goto done;
    rad_track(c, (int64_t)rad_vis_bytes(c->vis));
    for (uint32_t i = 0; i < c->npatches; i++) {
        rad_elem *r = rad_el(c, c->patches[i].root);
        r->exposed = rad_exposure(c, r);
    }
    rc = rad_mirror_new(c, err);
    if (rc) goto done;
    if (atomic_load(&c->over_cap)) {
        rc = cap_error(c, err);
        goto done;
    }
    /* Clusters start from their patches' emission. */
    c->cur = 1;
    update_clusters(c);
    c->cur = 0;
    rad_cluster_power(c);
    run_job(c, ws, prm->threads, JOB_DIRECT, 0);   /* (traces only: cannot fail) */
    c->min_area = prm->min_area * direct_area(c);

    double residual = 1.0;
    for (c->pass = 0; c->pass < prm->max_passes; c->pass++) {
        atomic_store(&c->refined, 0);
        double tp = ct_now();
        uint64_t est = atomic_load(&c->est_tris);
        c->pass_budget = prm->max_triangles > est ? prm->max_triangles - est : 0;
        if (c->pass > 0) {
            double lit;
            lit_stats(c, &lit, &c->reflected_mean);
            c->min_area = prm->min_area * lit;
            rad_cluster_power(c);
        }
        rc = run_job(c, ws, prm->threads, JOB_REFINE, 0);
        if (rc || atomic_load(&c->over_cap)) {
            rc = rc == CT_ENOMEM || atomic_load(&c->over_cap) ? cap_error(c, err)
                                                             : ct_fail(err, rc, "radiosity: refinement failed");
            goto done;
        }
        run_job(c, ws, prm->threads, JOB_PUBLISH, 0);
        st->passes = c->pass + 1;
        uint64_t refined = atomic_load(&c->refined);
        uint64_t nlinks = 0;
        for (uint32_t i = 0; i < c->npatches; i++) nlinks += c->patches[i].nlinks;
        /* Converged when (almost) no link changed: a pass that refines under
         * 0.1 % of the links changes the solution by far less than the
         * links' own error. Not while the quotas refused splits that the
         * budget still has room for: the next pass gives them their share. */
        c->want_total = 0;   /* the next pass's shares (rad_refine_patch) */
        for (uint32_t i = 0; i < c->npatches; i++) c->want_total += c->patches[i].want;
        int room = c->want_total > 0 && atomic_load(&c->est_tris) < prm->max_triangles;
        int last = (c->pass > 0 && refined * 1000 <= nlinks && !room) || c->pass + 1 == prm->max_passes;
        /* Intermediate passes only need the oracle's B roughly right: a few
         * iterations; the last pass converges to the tolerance. Before it
         * does, its cluster links take bk (rad_cluster_bk) from a solution
         * roughly converged on the final links, and the leaves' inherited
         * light is shared out with it. bk is set here only: taken when a
         * link was made, from the solution of an earlier pass (the lamps
         * alone in the first, patches not yet weighed by openness), it
         * brought the office building's cluster links 5 % more light than
         * their rays saw at the end, and the brighter light refined it to
         * 50 million links (docs/radiosity.md, "Cluster links"). */
        int rough = prm->max_iterations < 6 ? prm->max_iterations : 6;
        rc = iterate(c, ws, rough, 10.0 * prm->tolerance, tp, st, &residual);
        if (rc) goto done;
        if (last) {
            double ts = ct_now();
            run_job(c, ws, prm->threads, JOB_CLUSTER_BK, 0);   /* (traces only: cannot fail) */
            if ((rc = run_job(c, ws, prm->threads, JOB_LEAF_SCALES, 0)) != 0) {
                rc = ct_fail(err, rc, "radiosity: out of memory while sharing out the links' light");
                goto done;
            }
            ct_debug("radiosity", "pass %d: cluster links' bk and inherited links shared out in %.2f s", c->pass + 1,
                     ct_now() - ts);
            rc = iterate(c, ws, prm->max_iterations, prm->tolerance, tp, st, &residual);
            if (rc) goto done;
        }
        ct_debug("radiosity", "pass %d: %llu links refined, %u elements, %.2f s", c->pass + 1,
                 (unsigned long long)refined, c->nelems, ct_now() - tp);
        /* A scene that reflects nearly all its light (a closed white room)
         * converges slowly: stopped here it is darker than its solution
         * (20 % in a box of albedo 1 at the defaults), which no figure said. */
        if (last && !(residual < prm->tolerance))
            ct_warn("radiosity", "not converged: residual %.2e after %d iterations is above --tolerance %.0e; "
                    "the solution is darker than converged (raise --max-iterations)", residual,
                    prm->max_iterations, prm->tolerance);
        if (last) break;
    }
    /* One more gather at the converged values for the absorbed power. */
    run_job(c, ws, prm->threads, JOB_GATHER, 1);
    for (int i = 0; i < prm->threads; i++) st->absorbed += ws[i].absorbed;
    c->cur = 1 - c->cur;

    /* The leaves' values again, from the final gather (docs/radiosity.md,
     * "The final gather at the leaves"). */
    for (int k = 0; k < prm->gather_passes; k++) {
        if (progress) progress(user, 1.0, "final gather at the leaves");
        double tg = ct_now();
        rc = regather_leaves(c, &st->absorbed);
        if (rc) {
            rc = ct_fail(err, rc, "radiosity: out of memory in the final gather at the leaves");
            goto done;
        }
        ct_debug("radiosity", "final gather at the leaves %d/%d: %.2f s", k + 1, prm->gather_passes, ct_now() - tg);
    }
    if (progress) progress(user, 1.0, "meshing");
    double tm = ct_now();
    rc = rad_mesh_build(c, out, err);
    if (rc) goto done;
    ct_debug("radiosity", "meshing: %u triangles, %u vertices, %.2f s", out->ntris, out->nverts, ct_now() - tm);
    out->scene_hash = rad_solution_hash(s, prm);

    st->patches = c->npatches;
    st->clusters = c->nclusters;
    uint64_t ncl = 0, nzero = 0;
    for (uint32_t i = 0; i < c->npatches; i++) {
        st->links += c->patches[i].nlinks;
        for (uint32_t k = 0; k < c->patches[i].nlinks; k++) {
            ncl += (c->patches[i].links[k].src & RAD_CLUSTER_BIT) != 0;
            nzero += c->patches[i].links[k].ff == 0.0f;
        }
    }
    ct_debug("radiosity", "links: %llu from clusters, %llu of factor 0", (unsigned long long)ncl,
             (unsigned long long)nzero);
    st->elements = 0;
    st->leaves = 0;
    for (uint32_t i = 0; i < c->npatches; i++) {
        uint32_t stack[4 * RAD_MAX_DEPTH + 8];
        int sp = 0;
        stack[sp++] = c->patches[i].root;
        while (sp) {
            const rad_elem *e = rad_el(c, stack[--sp]);
            st->elements++;
            if (e->child == RAD_NONE) st->leaves++;
            else for (uint32_t k = 0; k < 4; k++) stack[sp++] = e->child + k;
        }
    }
    st->rays = atomic_load(&c->rays);
    st->residual = residual;
    st->triangles = out->ntris;
    st->vertices = out->nverts;
    st->contact_vertices = c->contact_vertices;
    st->emitted = c->emitted;
    st->peak_bytes = atomic_load(&c->peak);
    rc = CT_OK;
done:
    if (ws)
        for (int i = 0; i < prm->threads; i++) rad_tls_free(&ws[i].tls);
    free(ws);
    pool_free(c->pool);
    rad_vis_free(c->vis);
    rad_mirror_free(c);
    rad_free_patches(c);
    pthread_mutex_destroy(&c->alloc_lock);
    free(c);
    st->seconds = ct_now() - t0;
    if (rc) rmesh_free(out);
    return rc;
}
