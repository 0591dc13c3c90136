/* ctex_insert.c: sample insertion (§3.4) with the §3.6 resolution changes
 * it triggers, one sample at a time (ctex_insert) or partitioned by texture
 * over the thread pool (ctex_insert_par), and the refinement writes. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "master/ctex_internal.h"

/* --- samples ----------------------------------------------------------------------- */

/* A texture whose density is uneven (a dense part on screen, a sparse
 * one) can have a mean splat radius over --splat-hi at one size and under
 * --splat-lo at half of it: it halved and doubled again every few windows
 * (table at 1024x1024: its largest texture 60 times in one first pass,
 * each a pass over 2 million texels). Each reversal doubles the evidence
 * the next one needs, up to 2^MAX_REVERSALS times. */
#define MAX_REVERSALS 8

/* Resizes slot id to nw x nh (after the memory cap allowed growth), its
 * rows on pool's threads (NULL: the caller's). */
static void resize(ctex *c, uint32_t id, int nw, int nh, ct_pool *pool)
{
    ctex_tex *t = &c->slots[id].t;
    size_t ob = ctex_tex_bytes(t->w, t->h);
    const int ow = t->w, oh = t->h;
    int dir = nw > t->w || nh > t->h ? 1 : -1;
    ct_debug("ctex", "texture %u: %dx%d -> %dx%d (mean splat radius %.2f over %u samples)", id, t->w, t->h, nw, nh,
             (double)t->mean_r, t->since_resize);
    if (ctex_tex_resize_on(t, nw, nh, pool, NULL)) return;   /* out of memory: keep the old size */
    c->bytes = c->bytes - ob + ctex_tex_bytes(nw, nh);
    if (dir == -t->last_resize && t->reversals < MAX_REVERSALS) t->reversals++;
    t->last_resize = dir;
    t->mean_r = 0.0f;
    t->sum_r = 0.0;
    t->n_sum = 0;
    t->since_resize = 0;
    c->st.resizes++;
    ctex_ev_resized(c, id, ow, oh);
}

/* The mean of t's radii since its last change or aging; the running mean
 * for the first window after it. Only when the running mean passes a
 * threshold: a division per sample otherwise, in the insertion loop. */
static inline float since_mean(const ctex_tex *t, uint32_t win)
{
    return t->n_sum >= win ? (float)(t->sum_r / (double)t->n_sum) : t->mean_r;
}

/* §3.6: the running mean of splat radii, and the mean since the last
 * change, decide halving or doubling (docs/textures.md). With
 * `defer` (a parallel insertion) the change is only noted, once per call,
 * and made after every texture's samples (apply_resizes): growth takes
 * memory that other textures compete for. */
void ctex_adapt_resolution(ctex *c, uint32_t id, int r, int defer)
{
    slot *s = &c->slots[id];
    ctex_tex *t = &s->t;
    uint32_t n = t->since_resize;
    uint32_t win = (uint32_t)c->o.splat_window;
    /* A sample flooding an empty region has a huge radius; clamping it keeps
     * single outliers from halving a texture that is dense elsewhere. */
    float rc = fminf((float)r, 2.0f * c->o.splat_hi);
    t->mean_r += (rc - t->mean_r) / (float)(n < win ? n + 1 : win);
    t->sum_r += rc;
    t->n_sum++;
    t->since_resize = n + 1;
    if (t->since_resize < win || s->pend_w) return;
    /* Every change needs the mean of every radius since the last change
     * past the threshold as well as the running mean (since the last aging,
     * if later: the views before saw other densities; the running mean alone
     * for the first window after it): the running mean's window swings by
     * a texel where the queue moves between dense and sparse parts of a
     * texture. Reversing the last change also needs four windows of
     * evidence, twice as many after each reversal. */
    const uint32_t rev = (4u * win) << t->reversals;
    int nw = t->w, nh = t->h;
    if (t->mean_r > c->o.splat_hi && (t->w > c->o.tex_min || t->h > c->o.tex_min)) {
        if (!(since_mean(t, win) > c->o.splat_hi)) return;
        if (t->last_resize > 0 && t->since_resize < rev) return;
        nw = (t->w + 1) / 2; nh = (t->h + 1) / 2;
        if (nw < c->o.tex_min) nw = t->w < c->o.tex_min ? t->w : c->o.tex_min;
        if (nh < c->o.tex_min) nh = t->h < c->o.tex_min ? t->h : c->o.tex_min;
    } else if (t->mean_r < c->o.splat_lo && (t->w < s->max_w || t->h < s->max_h)) {
        if (!(since_mean(t, win) < c->o.splat_lo)) return;
        if (t->last_resize < 0 && t->since_resize < rev) return;
        /* exact doublings only: an axis that would pass its bound stays */
        nw = 2 * t->w <= s->max_w ? 2 * t->w : t->w;
        nh = 2 * t->h <= s->max_h ? 2 * t->h : t->h;
        if (!defer && !ctex_make_room(c, ctex_tex_bytes(nw, nh) - ctex_tex_bytes(t->w, t->h)))
            return;   /* the memory cap denies growth */
    } else {
        return;
    }
    if (nw == t->w && nh == t->h) return;
    if (defer) {
        s->pend_w = nw;
        s->pend_h = nh;
        return;
    }
    resize(c, id, nw, nh, NULL);
}

/* The resolution changes noted by a parallel insertion, in slot order. */
static void apply_resizes(ctex *c, ct_pool *pool)
{
    for (uint32_t id = 0; id < c->nslots; id++) {
        slot *s = &c->slots[id];
        int nw = s->pend_w, nh = s->pend_h;
        if (!nw) continue;
        s->pend_w = s->pend_h = 0;
        const ctex_tex *t = &s->t;
        if (!s->live || (nw == t->w && nh == t->h)) continue;
        if ((nw > t->w || nh > t->h) && !ctex_make_room(c, ctex_tex_bytes(nw, nh) - ctex_tex_bytes(t->w, t->h)))
            continue;   /* the memory cap denies growth */
        resize(c, id, nw, nh, pool);
    }
}

/* ex of a sample's splat as the prefetch stage found it, for the texture
 * (slot and size) it was computed on. */
typedef struct {
    int32_t id;
    int w, h;
    float ex;
} ex_hint;

/* The texture a sample goes to (-1: none), and info as for a dropped one. */
static int32_t owner(const ctex *c, const ct_sample *s, ctex_insert_info *info)
{
    info->tex = -1;
    info->radius = 0;
    info->correction = v3s(0.0f);
    info->error = v3_sub(s->l_hq, s->l_base);
    if (!(s->flags & CT_SAMPLE_HIT) || !v3_finite(s->l_hq) || !v3_finite(s->l_base) || !v3_finite(s->hit))
        return -1;
    return ctex_owner_of(c, s->node, s->tri, s->hit);
}

/* The texel of a sample on texture id, with what is displayed there now and
 * the error against it (§3.7); -1 when it lies off the texture. */
static int32_t locate_at(ctex *c, const ct_sample *s, int32_t id, ctex_insert_info *info, int *pci, int *pcj)
{
    float u, v;
    if (!ctex_tex_project(&c->slots[id].t, s->hit, &u, &v)) return -1;
    ctex_tex *t = &c->slots[id].t;
    float fx = u * (float)t->w, fy = v * (float)t->h;
    /* a hit more than a texel off the texture belongs to no texel */
    if (!(fx > -1.0f && fy > -1.0f && fx < (float)t->w + 1.0f && fy < (float)t->h + 1.0f)) return -1;
    int ci = (int)fx, cj = (int)fy;
    if (fx < 0.0f) ci = 0;
    if (fy < 0.0f) cj = 0;
    if (ci >= t->w) ci = t->w - 1;
    if (cj >= t->h) cj = t->h - 1;
    vec3 corr = ctex_tex_sample(t, u, v);
    info->correction = corr;
    /* §3.7: E = L - (L' + ΔL) against what is displayed now */
    info->error = v3_sub(s->l_hq, v3_add(s->l_base, corr));
    info->tex = id;
    *pci = ci;
    *pcj = cj;
    return id;
}

/* The ex of sample s's splat on texture t (slot id): from hint when that
 * was computed on the same texture at the same size (bit for bit what
 * ctex_splat_ex_at gives here); 1 (square rings) without --splat-aniso. */
static float splat_ex(const ctex *c, const ctex_tex *t, int32_t id, const ct_sample *s, const ex_hint *hint)
{
    if (!c->o.splat_aniso) return 1.0f;
    return hint && hint->id == id && hint->w == t->w && hint->h == t->h ? hint->ex : ctex_splat_ex_at(c, t, s->hit);
}

/* Splats sample s into texture id (its owner); 1 when splatted, 0 when it
 * lies off the texture (ex: splat_ex). */
static int insert_at(ctex *c, const ct_sample *s, int32_t id, ctex_insert_info *info, const ex_hint *hint, int defer)
{
    int ci, cj;
    if (locate_at(c, s, id, info, &ci, &cj) < 0) return 0;
    ctex_tex *t = &c->slots[id].t;
    vec3 dl = ctex_tex_mix(t, ci, cj, v3_sub(s->l_hq, s->l_base), c->slots[id].mix, c->o.mix_radius);
    float ex = splat_ex(c, t, id, s, hint);
    int r = ex == 1.0f ? ctex_tex_splat(t, ci, cj, dl, c->o.blend, c->o.splat_max)
                       : ctex_tex_splat_aniso(t, ci, cj, dl, c->o.blend, c->o.splat_max, ex);
    info->radius = r;
    ctex_adapt_resolution(c, (uint32_t)id, r, defer);
    return 1;
}

/* §3.5's BRDF term for late sample s on texture id, traced from eye e0:
 * its surface's glossiness x the change of the viewing direction at its
 * hit, in texels of the texture as age() measures a camera change
 * (ctex_view.c). 0 for a diffuse surface or an unmoved eye; INFINITY past
 * --late-deg (the sample is dropped). */
static float late_age(const ctex *c, const ct_sample *s, int32_t id, vec3 e0)
{
    vec3 e1 = c->cam.eye;
    if (!c->have_cam || (e0.x == e1.x && e0.y == e1.y && e0.z == e1.z)) return 0.0f;
    int32_t l = ctex_leaf_of_hit(c, s->node, s->tri, s->hit);
    float gloss = l >= 0 ? c->h.nodes[c->h.leaf_node[l]].gloss : 1.0f;
    if (!(gloss > 0.0f)) return 0.0f;
    vec3 d0 = v3_sub(s->hit, e0), d1 = v3_sub(s->hit, e1);
    if (!(v3_len2(d0) > 0.0f && v3_len2(d1) > 0.0f)) return INFINITY;
    float ang = v3_angle(d0, d1);
    if (!(gloss * ang <= c->o.late_deg * (float)(M_PI / 180.0))) return INFINITY;
    return ctex_brdf_age(c, &c->slots[id].t, gloss, ang);
}

/* Splats late sample s, traced from eye e0, into texture id (its owner): as
 * insert_at while its age is 0; else aged (ctex_tex_splat_late), mixed
 * with a texel only as old as it (ctex_tex_mix_aged), and with no say in
 * the resolution (its radius measures the gaps between fresher samples,
 * not the density). 1 when it wrote texels. */
static int late_at(ctex *c, const ct_sample *s, int32_t id, vec3 e0, ctex_insert_info *info, const ex_hint *hint,
                   int defer)
{
    float age = late_age(c, s, id, e0);
    if (age == 0.0f) return insert_at(c, s, id, info, hint, defer);
    int ci, cj;
    if (!(age < INFINITY)) {
        info->radius = CTEX_LATE_TURNED;
        return 0;
    }
    if (locate_at(c, s, id, info, &ci, &cj) < 0) return 0;
    ctex_tex *t = &c->slots[id].t;
    float ex = splat_ex(c, t, id, s, hint);
    vec3 dl = ctex_tex_mix_aged(t, ci, cj, v3_sub(s->l_hq, s->l_base), c->slots[id].mix, c->o.mix_radius, age);
    int r = ctex_tex_splat_late(t, ci, cj, dl, c->o.blend, c->o.splat_max, ex, age);
    if (r < 0) {
        info->tex = -1;
        info->radius = CTEX_LATE_COVERED;
        return 0;
    }
    info->radius = r;
    return 1;
}

/* Texture position (in texels) of the point the ray through image position
 * (x, y) meets on texture t: a camera-local texture projected from the
 * current eye maps rays to positions; one that kept the projector of an
 * earlier view (ctex_view.c) takes the ray's point at the hit p's depth;
 * an object-local one its plane through p (normal t->n). */
static bool texel_of_ray(const ctex *c, const ctex_tex *t, vec3 p, float x, float y, float *tx, float *ty)
{
    vec3 d = cam_rays_dir(&c->rays, x, y);
    vec3 q = v3_add(c->cam.eye, d);
    if (t->kind == CTEX_PROJ_CAMERA && !v3_is_zero(v3_sub(t->cam.eye, c->cam.eye))) {
        float dz = v3_dot(d, c->rays.f);
        if (!(dz > 1e-6f)) return false;
        q = v3_madd(c->cam.eye, d, v3_dot(v3_sub(p, c->cam.eye), c->rays.f) / dz);
    } else if (t->kind == CTEX_PROJ_OBJECT) {
        float dn = v3_dot(d, t->n);
        if (!(fabsf(dn) > 1e-6f)) return false;
        q = v3_madd(c->cam.eye, d, v3_dot(v3_sub(p, c->cam.eye), t->n) / dn);
    }
    float u, v;
    if (!ctex_tex_project(t, q, &u, &v)) return false;
    *tx = u * (float)t->w;
    *ty = v * (float)t->h;
    return isfinite(*tx) && isfinite(*ty);
}

/* Writes refinement sample s, its pixel's n_px-th, on texture id. */
static int refine_at(ctex *c, const ct_sample *s, int32_t id, uint16_t n_px, ctex_insert_info *info)
{
    int ci, cj;
    vec3 dl = v3_sub(s->l_hq, s->l_base);
    if (locate_at(c, s, id, info, &ci, &cj) < 0 || !v3_finite(dl)) return 0;
    ctex_tex *t = &c->slots[id].t;
    /* The texels the display reads for this pixel: those whose centres lie
     * in the pixel's footprint on the texture (its corners' rays), within 4
     * texels of the hit's; at least the hit's own. */
    float fx = floorf(s->px), fy = floorf(s->py);
    float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    bool ok = c->have_cam;
    for (int k = 0; k < 4 && ok; k++) {
        float tx, ty;
        ok = texel_of_ray(c, t, s->hit, fx + (float)(k & 1), fy + (float)(k >> 1), &tx, &ty);
        if (!ok) break;
        x0 = fminf(x0, tx); x1 = fmaxf(x1, tx);
        y0 = fminf(y0, ty); y1 = fmaxf(y1, ty);
    }
    int a = ci, b = ci, e = cj, f = cj;
    if (ok) {
        a = (int)ceilf(x0 - 0.5f); b = (int)floorf(x1 - 0.5f);
        e = (int)ceilf(y0 - 0.5f); f = (int)floorf(y1 - 0.5f);
        a = a < ci - 4 ? ci - 4 : (a > ci ? ci : a);
        b = b > ci + 4 ? ci + 4 : (b < ci ? ci : b);
        e = e < cj - 4 ? cj - 4 : (e > cj ? cj : e);
        f = f > cj + 4 ? cj + 4 : (f < cj ? cj : f);
    }
    /* The first pass's value is the prior: with mixing weight m it is a
     * running average of about (2 - m) / m samples (docs/textures.md,
     * "Mixing"), less noisy than the pixel's first few samples, which it
     * replaced when the pixel's plain mean was written here (a still
     * view's PSNR then fell for a while after full coverage); the pixel's
     * samples outweigh it as they come. */
    float m = c->slots[id].mix;
    float prior = m > 0.0f ? (2.0f - m) / m : 1.0f;
    float w = 1.0f / (prior + (float)(n_px < 2 ? 2 : n_px) - 1.0f);
    ctex_tex_refine(t, a < 0 ? 0 : a, e < 0 ? 0 : e, b >= t->w ? t->w - 1 : b, f >= t->h ? t->h - 1 : f, cj, dl, w);
    return 1;
}

int ctex_refine(ctex *c, const ct_sample *s, uint16_t n_px, ctex_insert_info *info)
{
    int32_t id = owner(c, s, info);
    int ok = id >= 0 && refine_at(c, s, id, n_px, info);
    if (ok) c->st.inserted++;
    else c->st.dropped++;
    return ok;
}

int ctex_insert(ctex *c, const ct_sample *s, ctex_insert_info *info)
{
    int32_t id = owner(c, s, info);
    int ok = id >= 0 && insert_at(c, s, id, info, NULL, 0);
    if (ok) c->st.inserted++;
    else c->st.dropped++;
    return ok;
}

/* Prefetches the texel rows a sample will read and splat first: the
 * rectangle of its splat's first two rings (anisotropic rings reach up to
 * 8 rows out, and a rectangle's rows are its cache misses), whose ex it
 * leaves in *hint so that the insertion need not compute it again. Always
 * inlined: a separate function whose only effect is __builtin_prefetch
 * counts as pure for GCC, which then drops the calls (their result is
 * unused) and with them the prefetches. */
static inline __attribute__((always_inline)) void prefetch_sample(const ctex *c, const ct_sample *s, int32_t id,
                                                                  ex_hint *hint)
{
    hint->id = -1;
    float u, v;
    if (id < 0 || !ctex_tex_project(&c->slots[id].t, s->hit, &u, &v)) return;
    const ctex_tex *t = &c->slots[id].t;
    int ci = (int)(u * (float)t->w), cj = (int)(v * (float)t->h);
    if (ci < 0 || cj < 0 || ci >= t->w || cj >= t->h) return;
    int xk = 2, yk = 2;
    if (c->o.splat_aniso) {
        *hint = (ex_hint){id, t->w, t->h, ctex_splat_ex_at(c, t, s->hit)};
        if (hint->ex != 1.0f) ctex_aniso_ring(hint->ex, 2, &xk, &yk);
    }
    int y0 = cj - yk < 0 ? 0 : cj - yk, y1 = cj + yk >= t->h ? t->h - 1 : cj + yk;
    int x0 = ci - xk < 0 ? 0 : ci - xk, x1 = ci + xk >= t->w ? t->w - 1 : ci + xk;
    for (int j = y0; j <= y1; j++) {
        const ctex_texel *row = ctex_tex_at(t, 0, j);
        __builtin_prefetch(row + x0, 1, 1);
        __builtin_prefetch(row + x1, 1, 1);
    }
}

/* --- parallel insertion -------------------------------------------------------- */

enum { OWNER_TASK = 512 };   /* samples per task of the first pass */
enum { PAR_MIN_SAMPLES = 1024 };   /* fewer samples are splatted by the calling thread alone */

typedef struct par_job {
    ctex *c;
    const ct_sample *s;
    const uint16_t *n_px;      /* refinement: the samples' pixel counts; NULL: splats */
    const vec3 *eyes;          /* late samples: the eyes they were traced from; NULL: new ones */
    ctex_insert_info *info;
    size_t n;
} par_job;

/* First pass: each sample's texture (ctex_owner_of reads only the view's
 * assignment, which no insertion changes). */
static void owner_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    par_job *j = ctx;
    size_t a = task * OWNER_TASK, e = a + OWNER_TASK < j->n ? a + OWNER_TASK : j->n;
    for (size_t i = a; i < e; i++) {
        /* the leaf entry the owner depends on, a few samples ahead */
        if (i + 8 < e && j->s[i + 8].tri < j->c->h.ntris) __builtin_prefetch(&j->c->h.tri_leaf[j->s[i + 8].tri], 0, 1);
        j->c->par_own[i] = owner(j->c, &j->s[i], &j->info[i]);
    }
}

/* Second pass: one texture's samples, in their order, by one thread; the
 * texel rows of the samples four ahead are prefetched (the loop is bound by
 * memory latency). */
static void group_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    enum { AHEAD = 4 };
    par_job *j = ctx;
    ctex *c = j->c;
    uint32_t id = c->par_groups[task];
    const uint32_t *ix = c->par_order + c->par_first[id];
    uint32_t n = c->par_count[id], done = 0;
    ex_hint hint[2 * AHEAD];   /* sample k's in hint[k % (2 AHEAD)] */
    for (uint32_t k = 0; k < n && k < AHEAD; k++) prefetch_sample(c, &j->s[ix[k]], (int32_t)id, &hint[k % (2 * AHEAD)]);
    for (uint32_t k = 0; k < n; k++) {
        uint32_t i = ix[k];
        if (k + AHEAD < n) prefetch_sample(c, &j->s[ix[k + AHEAD]], (int32_t)id, &hint[(k + AHEAD) % (2 * AHEAD)]);
        if (j->n_px) done += (uint32_t)refine_at(c, &j->s[i], (int32_t)id, j->n_px[i], &j->info[i]);
        else if (j->eyes)
            done += (uint32_t)late_at(c, &j->s[i], (int32_t)id, j->eyes[i], &j->info[i], &hint[k % (2 * AHEAD)], 1);
        else done += (uint32_t)insert_at(c, &j->s[i], (int32_t)id, &j->info[i], &hint[k % (2 * AHEAD)], 1);
    }
    c->par_done[id] = done;
}

/* Grows the per-call scratch to n samples and the slots. */
static int par_scratch(ctex *c, size_t n)
{
    if (n > c->par_cap) {
        size_t cap = n < 1024 ? 1024 : n;
        int32_t *own = realloc(c->par_own, cap * sizeof *own);
        if (own) c->par_own = own;
        uint32_t *ord = realloc(c->par_order, cap * sizeof *ord);
        if (ord) c->par_order = ord;
        if (!own || !ord) return CT_ENOMEM;
        c->par_cap = cap;
    }
    if (c->nslots > c->par_slots) {
        uint32_t ns = c->cap_slots;
        uint32_t *f = realloc(c->par_first, ns * sizeof *f);
        if (f) c->par_first = f;
        uint32_t *k = realloc(c->par_count, ns * sizeof *k);
        if (k) c->par_count = k;
        uint32_t *g = realloc(c->par_groups, ns * sizeof *g);
        if (g) c->par_groups = g;
        uint32_t *d = realloc(c->par_done, ns * sizeof *d);
        if (d) c->par_done = d;
        uint64_t *y = realloc(c->par_keys, ns * sizeof *y);
        if (y) c->par_keys = y;
        if (!f || !k || !g || !d || !y) return CT_ENOMEM;
        c->par_slots = ns;
    }
    return CT_OK;
}

static int by_key(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static size_t run_par(ctex *c, ct_pool *pool, const ct_sample *s, const uint16_t *n_px, const vec3 *eyes, size_t n,
                      ctex_insert_info *info)
{
    if (n == 0) return 0;
    if (par_scratch(c, n)) {
        /* without scratch memory: one sample at a time (resolution changes
         * then come at once, as with ctex_insert) */
        size_t done = 0;
        for (size_t i = 0; i < n; i++) {
            int ok;
            if (n_px) ok = ctex_refine(c, &s[i], n_px[i], &info[i]);
            else if (!eyes) ok = ctex_insert(c, &s[i], &info[i]);
            else {
                int32_t id = owner(c, &s[i], &info[i]);
                ok = id >= 0 && late_at(c, &s[i], id, eyes[i], &info[i], NULL, 0);
                if (ok) c->st.inserted++;
                else c->st.dropped++;
            }
            done += (size_t)ok;
        }
        return done;
    }
    par_job j = {c, s, n_px, eyes, info, n};
    pool_run(pool, (n + OWNER_TASK - 1) / OWNER_TASK, owner_task, &j);
    /* group the samples by texture (a counting sort keeps their order) */
    memset(c->par_count, 0, c->nslots * sizeof *c->par_count);
    size_t dropped = 0;
    for (size_t i = 0; i < n; i++) {
        if (c->par_own[i] >= 0) c->par_count[c->par_own[i]]++;
        else dropped++;
    }
    uint32_t ngroups = 0, at = 0;
    for (uint32_t id = 0; id < c->nslots; id++) {
        c->par_first[id] = at;
        at += c->par_count[id];
        if (c->par_count[id]) c->par_groups[ngroups++] = id;
    }
    for (size_t i = 0; i < n; i++)
        if (c->par_own[i] >= 0) c->par_order[c->par_first[c->par_own[i]]++] = (uint32_t)i;
    for (uint32_t id = 0; id < c->nslots; id++) c->par_first[id] -= c->par_count[id];
    if (pool_threads(pool) > 1 && ngroups > 1) {
        /* larger groups first, so that the longest tasks start early */
        for (uint32_t g = 0; g < ngroups; g++)
            c->par_keys[g] = (uint64_t)(UINT32_MAX - c->par_count[c->par_groups[g]]) << 32 | c->par_groups[g];
        qsort(c->par_keys, ngroups, sizeof *c->par_keys, by_key);
        for (uint32_t g = 0; g < ngroups; g++) c->par_groups[g] = (uint32_t)c->par_keys[g];
    }
    /* Waking the other threads costs more than they give on a few hundred
     * samples (rounds of 256 ran slower on two threads than on one, office
     * at 1024^2: docs/benchmarks.md "Master: saturation"); the result is
     * the same either way. */
    pool_run(n >= PAR_MIN_SAMPLES ? pool : NULL, ngroups, group_task, &j);
    size_t done = 0;
    for (uint32_t g = 0; g < ngroups; g++) {
        uint32_t id = c->par_groups[g];
        done += c->par_done[id];
        dropped += c->par_count[id] - c->par_done[id];
    }
    c->st.inserted += done;
    c->st.dropped += dropped;
    if (!n_px) apply_resizes(c, pool);
    return done;
}

size_t ctex_insert_par(ctex *c, ct_pool *pool, const ct_sample *s, size_t n, ctex_insert_info *info)
{
    return run_par(c, pool, s, NULL, NULL, n, info);
}

size_t ctex_insert_late_par(ctex *c, ct_pool *pool, const ct_sample *s, const vec3 *eyes, size_t n,
                            ctex_insert_info *info)
{
    return run_par(c, pool, s, NULL, eyes, n, info);
}

size_t ctex_refine_par(ctex *c, ct_pool *pool, const ct_sample *s, const uint16_t *n_px, size_t n,
                       ctex_insert_info *info)
{
    return run_par(c, pool, s, n_px, NULL, n, info);
}
