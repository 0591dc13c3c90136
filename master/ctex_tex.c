/* ctex_tex.c: texel storage, ring splatting, resizing and resampling of one
 * corrective texture (see ctex_tex.h and docs/textures.md). Over 600 lines
 * on purpose: the splat kernels, resize and resample share the texel layout
 * and its inline helpers, and the hot loops are tuned together (docs/
 * textures.md, "Insertion speed"); split, they would need a second header of
 * internals for no reader's gain. */
#include "master/ctex_tex.h"

#include "common/pool.h"
#include "master/ctex_mem.h"
#include "proto/wire.h"

#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

/* Four floats: a texel's correction (r, g, b, junk) in one SSE register
 * (GCC/Clang vector extensions, portable C): the same IEEE single-precision
 * operations as scalar code, so the results are bit-identical. */
typedef float v4f __attribute__((vector_size(16)));

static inline v4f texel4(const ctex_texel *p)
{
    v4f f;
    float a[4];
    ctex_texel_rgbx(p, a);
    memcpy(&f, a, sizeof f);
    return f;
}

/* Texel storage: ctex_mem.h (huge pages, the pool of given-back arrays). */
static ctex_texel *alloc_texels(const ctex_tex *t, size_t n)
{
    return ctex_mem_get(t->mem, n * sizeof(ctex_texel));
}

/* Gives t's texel array back (its size from t->w, t->h). */
static void free_texels(const ctex_tex *t, ctex_texel *tx)
{
    ctex_mem_put(t->mem, tx, ctex_tex_bytes(t->w, t->h));
}

static void clear_texels(ctex_texel *tx, size_t n)
{
    for (size_t i = 0; i < n; i++) ctex_texel_clear(&tx[i]);
}

int ctex_tex_init(ctex_tex *t, int w, int h, ct_error *err)
{
    if (w < 1 || h < 1 || w > 65536 || h > 65536)
        return ct_fail(err, CT_EINVAL, "texture size %dx%d out of range", w, h);
    const int pitch = ctex_tex_pitch(w);
    ctex_texel *tx = alloc_texels(t, (size_t)pitch * (size_t)h);
    if (!tx) return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d texture", w, h);
    if (ctex_dirty_reset(&t->d, w, h, err)) {
        ctex_mem_put(t->mem, tx, ctex_tex_bytes(w, h));
        return CT_ENOMEM;
    }
    clear_texels(tx, (size_t)pitch * (size_t)h);
    if (t->tx) free_texels(t, t->tx);
    t->tx = tx;
    t->w = w;
    t->h = h;
    t->pitch = pitch;
    t->vmax = 0.0f;   /* §3.4: the first samples start at validity 0 */
    t->vbase = 0.0f;
    t->mean_r = 0.0f;
    t->sum_r = 0.0;
    t->n_sum = 0;
    t->since_resize = 0;
    t->last_resize = 0;
    t->reversals = 0;
    return CT_OK;
}

void ctex_tex_release(ctex_tex *t)
{
    if (t->tx) free_texels(t, t->tx);
    t->tx = NULL;
    t->w = t->h = t->pitch = 0;
    ctex_dirty_free(&t->d);
}

void ctex_tex_rebase(ctex_tex *t)
{
    /* whole steps only, so every validity keeps its exact value or clamps */
    float sh = rintf((t->vmax - t->vbase) * (float)CTEX_VQ);
    if (sh == 0.0f || !isfinite(sh)) return;
    t->vbase += sh / (float)CTEX_VQ;
    /* a shift past the whole range clamps every validity alike */
    int32_t d = (int32_t)fmaxf(fminf(sh, 131072.0f), -131072.0f);
    for (int y = 0; y < t->h; y++) {
        ctex_texel *row = ctex_tex_at(t, 0, y);
        for (int x = 0; x < t->w; x++) {
            if (row[x].q == CTEX_Q_EMPTY) continue;
            int32_t q = (int32_t)row[x].q - d;
            row[x].q = (int16_t)(q < CTEX_Q_OLDEST ? CTEX_Q_OLDEST : (q > INT16_MAX ? INT16_MAX : q));
        }
    }
}

/* A splat's value: as halves (one 8-byte store a texel) and as the floats
 * those halves hold (blending). */
typedef struct splat_val {
    uint64_t rgb;     /* the texel's bytes with q = 0 */
    v4f f4;           /* its value as stored (halves), 0 */
    float blend;      /* band (texels) */
} splat_val;

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "store() builds a texel as a little-endian 64-bit word (q in the top 16 bits)"
#endif

/* Texel x := the bytes rgb with validity step q, as one 8-byte store. */
static inline void store(ctex_texel *x, uint64_t rgb, int32_t q)
{
    uint64_t w = rgb | (uint64_t)(uint16_t)(int16_t)q << 48;
    memcpy(x, &w, sizeof w);
}

/* Prefetches the top and bottom rows of ring k (for writing): each row
 * of a ring is a new row of the texture, a cache miss the hardware
 * prefetchers cannot foresee; issued a ring ahead, the misses of a large
 * splat overlap. Always inlined (see prefetch_sample in ctex.c). */
static inline __attribute__((always_inline)) void prefetch_ring(const ctex_tex *t, int ci, int cj, int k)
{
    int xa = ci - k < 0 ? 0 : ci - k, xb = ci + k > t->w - 1 ? t->w - 1 : ci + k;
    for (int y = cj - k; y <= cj + k; y += 2 * k) {
        if (y < 0 || y >= t->h) continue;
        const ctex_texel *row = ctex_tex_at(t, 0, y);
        for (int x = xa; x < xb; x += 8) __builtin_prefetch(row + x, 1, 1);
        __builtin_prefetch(row + xb, 1, 1);
    }
}

/* §3.4: blends value into texel x by margin m (texels) in (-blend, blend).
 * The three channels in one conversion each way (the fourth lane carries q
 * and is not stored): since the doubling's slack, validities differ by
 * fractions of a texel and most splats blend a ring of texels (blending
 * was a third of the insertion's time; one conversion instead of three
 * each way took table 1024²'s from 0.78-0.80 to 0.72-0.75 CPU s). The same
 * operations per channel, so the same values. */
static void blend_into(ctex_texel *x, float m, const splat_val *sv)
{
    const float w = 0.5f + 0.5f * m / sv->blend;
    const v4f o = texel4(x), wv = {w, w, w, w};
    const v4f r = o + wv * (sv->f4 - o);
    float f[4];
    memcpy(f, &r, sizeof f);
    uint16_t h[4];
    float4_to_half(f, h);
    memcpy(x->c, h, sizeof x->c);
}

/* Writes the value into texel x at validity step vn: replaced when vn is
 * more valid by the blend band or more (or x is empty), blended within the
 * band (validity max(old, new)). Returns whether x's validity rose. */
static inline int put(ctex_texel *x, int32_t vn, const splat_val *sv)
{
    int32_t m = vn - (int32_t)x->q;
    if (m > 0) {
        float mf = (float)m * (1.0f / (float)CTEX_VQ);
        if (mf >= sv->blend || x->q == CTEX_Q_EMPTY) {
            store(x, sv->rgb, vn);
            return 1;
        }
        blend_into(x, mf, sv);
        x->q = (int16_t)vn;
        return 1;
    }
    float mf = (float)m * (1.0f / (float)CTEX_VQ);
    if (mf > -sv->blend) blend_into(x, mf, sv);
    return 0;
}

/* A splat's start: sv from the value, the centre texel written at the step
 * of v_max - age, which it returns. A new sample (age 0) always takes its
 * centre; an aged one (a late sample, ctex_tex_splat_late) only where the
 * centre is not more valid, else nothing is written and it returns
 * SPLAT_LOST. */
#define SPLAT_LOST INT32_MIN
static inline __attribute__((always_inline)) int32_t splat_centre(ctex_tex *t, int ci, int cj, vec3 val, float blend,
                                                                  float age, splat_val *sv)
{
    ctex_tex_keep_base(t);
    const int32_t qmax = ctex_tex_q(t, t->vmax - age);
    ctex_texel *c = ctex_tex_at(t, ci, cj);
    if (age > 0.0f && c->q > qmax) return SPLAT_LOST;
    ctex_texel h;
    ctex_texel_set(t, &h, val, 0.0f);
    h.q = 0;
    memcpy(&sv->rgb, &h, sizeof sv->rgb);
    sv->f4 = texel4(&h);   /* q = 0: the fourth lane is 0 */
    sv->blend = blend < 0.0f ? 0.0f : blend;
    store(c, sv->rgb, c->q > qmax ? c->q : qmax);
    return qmax;
}

/* Marks the texels within ex, ey of (ci, cj) unsent. */
static inline void grow_dirty(ctex_tex *t, int ci, int cj, int ex, int ey)
{
    int x0 = ci - ex < 0 ? 0 : ci - ex, x1 = ci + ex + 1 > t->w ? t->w : ci + ex + 1;
    int y0 = cj - ey < 0 ? 0 : cj - ey, y1 = cj + ey + 1 > t->h ? t->h : cj + ey + 1;
    ctex_dirty_mark(&t->d, x0, y0, x1, y1, cj);
}

void ctex_tex_refine(ctex_tex *t, int x0, int y0, int x1, int y1, int cy, vec3 value, float w)
{
    ctex_tex_keep_base(t);
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++) {
            ctex_texel *p = ctex_tex_at(t, x, y);
            float v = ctex_tex_v(t, p);
            vec3 to = value;
            if (ctex_texel_valid(p)) {
                float o[4];
                ctex_texel_rgbx(p, o);
                to = v3(o[0] + w * (value.x - o[0]), o[1] + w * (value.y - o[1]), o[2] + w * (value.z - o[2]));
            }
            ctex_texel_set(t, p, to, v > t->vmax ? v : t->vmax);
        }
    ctex_dirty_mark(&t->d, x0, y0, x1 + 1, y1 + 1, cy);
}

/* ctex_tex_splat with the centre at v_max - age (0: a new sample); -1 when
 * an aged splat lost its centre (nothing written). */
static inline __attribute__((always_inline)) int splat_iso(ctex_tex *t, int ci, int cj, vec3 val, float blend,
                                                           int max_r, float age)
{
    const int W = t->w, H = t->h;
    const size_t P = (size_t)t->pitch;
    ctex_texel *T = t->tx;
    splat_val sv;
    /* validity steps: v_max's, and ring k's v_max - k (§3.4) */
    const int32_t qmax = splat_centre(t, ci, cj, val, blend, age, &sv);
    if (qmax == SPLAT_LOST) return -1;
    ctex_texel *c = T + (size_t)cj * P + (size_t)ci;
    int r = 0, k = 1;
    /* The largest ring that still has a texel inside the texture. */
    int kmax = ci;
    if (W - 1 - ci > kmax) kmax = W - 1 - ci;
    if (cj > kmax) kmax = cj;
    if (H - 1 - cj > kmax) kmax = H - 1 - cj;
    if (max_r > 0 && max_r < kmax) kmax = max_r;
    if (kmax >= 1 && ci >= 1 && cj >= 1 && ci < W - 1 && cj < H - 1) {
        /* Ring 1 inside the texture (most samples stop after it): its eight
         * texels in the ring loop's order, without the clipping. */
        const int32_t vn = qmax - CTEX_VQ < CTEX_Q_OLDEST ? CTEX_Q_OLDEST : qmax - CTEX_VQ;
        ctex_texel *a = c - P, *b = c + P;
        int changed = put(a - 1, vn, &sv) | put(a, vn, &sv) | put(a + 1, vn, &sv);
        changed |= put(b - 1, vn, &sv) | put(b, vn, &sv) | put(b + 1, vn, &sv);
        changed |= put(c - 1, vn, &sv) | put(c + 1, vn, &sv);
        if (!changed) goto dirty;
        r = 1;
        k = 2;
    }
    if (k <= kmax) prefetch_ring(t, ci, cj, k);
    for (; k <= kmax; k++) {
        if (k < kmax) prefetch_ring(t, ci, cj, k + 1);
        /* §3.4: validity v_max - d (older ones clamp to the oldest step) */
        const int32_t vq = qmax - CTEX_VQ * k;
        const int32_t vn = vq < CTEX_Q_OLDEST ? CTEX_Q_OLDEST : vq;
        int changed = 0;
        int xa = ci - k < 0 ? 0 : ci - k, xb = ci + k > W - 1 ? W - 1 : ci + k;
        /* top and bottom rows of the ring */
        if (cj - k >= 0) {
            ctex_texel *row = T + (size_t)(cj - k) * P;
            for (int x = xa; x <= xb; x++) changed |= put(row + x, vn, &sv);
        }
        if (cj + k <= H - 1) {
            ctex_texel *row = T + (size_t)(cj + k) * P;
            for (int x = xa; x <= xb; x++) changed |= put(row + x, vn, &sv);
        }
        /* left and right columns without the corners */
        int ya = cj - k + 1 < 0 ? 0 : cj - k + 1, yb = cj + k - 1 > H - 1 ? H - 1 : cj + k - 1;
        if (ci - k >= 0)
            for (int y = ya; y <= yb; y++) changed |= put(T + (size_t)y * P + (size_t)(ci - k), vn, &sv);
        if (ci + k <= W - 1)
            for (int y = ya; y <= yb; y++) changed |= put(T + (size_t)y * P + (size_t)(ci + k), vn, &sv);
        if (!changed) break;
        r = k;
    }
dirty:;
    /* Dirty: everything up to the ring that stopped the splat (it may have
     * been blended). */
    int e = k > kmax ? kmax : k;
    grow_dirty(t, ci, cj, e, e);
    return r;
}

int ctex_tex_splat(ctex_tex *t, int ci, int cj, vec3 val, float blend, int max_r)
{
    return splat_iso(t, ci, cj, val, blend, max_r, 0.0f);
}

/* Prefetches the rows ring k adds above and below ring k - 1's rectangle
 * (py rows either side of cj), for writing: prefetch_ring's counterpart. */
static inline __attribute__((always_inline)) void prefetch_bands(const ctex_tex *t, int ci, int cj, float ex, int k,
                                                                 int py)
{
    int xk, yk;
    ctex_aniso_ring(ex, k, &xk, &yk);
    int xa = ci - xk < 0 ? 0 : ci - xk, xb = ci + xk > t->w - 1 ? t->w - 1 : ci + xk;
    for (int d = py + 1; d <= yk; d++)
        for (int y = cj - d; y <= cj + d; y += 2 * d) {
            if (y < 0 || y >= t->h) continue;
            const ctex_texel *row = ctex_tex_at(t, 0, y);
            for (int x = xa; x < xb; x += 8) __builtin_prefetch(row + x, 1, 1);
            __builtin_prefetch(row + xb, 1, 1);
        }
}

/* ctex_tex_splat_aniso with the centre at v_max - age, as splat_iso. */
static inline __attribute__((always_inline)) int splat_aniso(ctex_tex *t, int ci, int cj, vec3 val, float blend,
                                                             int max_r, float ex, float age)
{
    ex = ctex_aniso_ex(ex);
    if (ex == 1.0f) return splat_iso(t, ci, cj, val, blend, max_r, age);
    /* locals: the texel stores could alias t's fields */
    const int W = t->w, H = t->h;
    const size_t P = (size_t)t->pitch;
    ctex_texel *const T = t->tx;
    splat_val sv;
    const int32_t qmax = splat_centre(t, ci, cj, val, blend, age, &sv);
    if (qmax == SPLAT_LOST) return -1;
    /* Ring k: the texels of its rectangle outside ring k - 1's; one of the
     * two extents grows by at least one texel a ring (ex ey = 1). */
    const int reachx = ci > W - 1 - ci ? ci : W - 1 - ci;
    const int reachy = cj > H - 1 - cj ? cj : H - 1 - cj;
    int px = 0, py = 0, r = 0;   /* the last visited ring's half-extents */
    for (int k = 1; (max_r <= 0 || k <= max_r) && (px < reachx || py < reachy); k++) {
        int xk, yk;
        ctex_aniso_ring(ex, k, &xk, &yk);
        /* Ring k + 1's new rows, while ring k is written; not from ring 1,
         * after which most samples stop (ctex_tex_splat does the same). */
        if (k > 1 && (max_r <= 0 || k < max_r)) prefetch_bands(t, ci, cj, ex, k + 1, yk);
        const int32_t vq = qmax - CTEX_VQ * k;
        const int32_t vn = vq < CTEX_Q_OLDEST ? CTEX_Q_OLDEST : vq;
        /* The rectangle clipped to the texture, row by row (ascending
         * addresses): whole rows above and below ring k - 1's rows, the
         * left and right strips beside them. */
        const int xa = ci - xk < 0 ? 0 : ci - xk, xb = ci + xk > W - 1 ? W - 1 : ci + xk;
        const int ya = cj - yk < 0 ? 0 : cj - yk, yb = cj + yk > H - 1 ? H - 1 : cj + yk;
        const int lb = ci - px - 1 < xb ? ci - px - 1 : xb;   /* left strip [xa, lb] */
        const int ra = ci + px + 1 > xa ? ci + px + 1 : xa;   /* right strip [ra, xb] */
        const int strips = (lb >= xa ? lb - xa + 1 : 0) + (xb >= ra ? xb - ra + 1 : 0);
        int changed = 0, inside = 0;
        for (int y = ya; y <= yb; y++) {
            ctex_texel *row = T + (size_t)y * P;
            if (y < cj - py || y > cj + py) {
                for (int x = xa; x <= xb; x++) changed |= put(row + x, vn, &sv);
                inside += xb - xa + 1;
            } else {
                for (int x = xa; x <= lb; x++) changed |= put(row + x, vn, &sv);
                for (int x = ra; x <= xb; x++) changed |= put(row + x, vn, &sv);
                inside += strips;
            }
        }
        int full = xk > px && yk > py;
        px = xk;
        py = yk;
        /* A ring wholly outside the texture stops nothing: a later one may
         * grow along the axis that still has texels. */
        if (!inside) continue;
        /* Only a ring around the whole last rectangle stops the splat: one
         * that grew along one axis leaves the texels past the other
         * rectangle's sides, where a later ring may still win (the
         * Voronoi property, tested). */
        if (!changed) {
            if (full) break;
            continue;
        }
        r = k;
        if (k == 1 && (max_r <= 0 || max_r > 1)) prefetch_bands(t, ci, cj, ex, 2, yk);
    }
    /* Dirty: everything up to the ring that stopped the splat (it may have
     * been blended). */
    grow_dirty(t, ci, cj, px, py);
    return r;
}

int ctex_tex_splat_aniso(ctex_tex *t, int ci, int cj, vec3 val, float blend, int max_r, float ex)
{
    return splat_aniso(t, ci, cj, val, blend, max_r, ex, 0.0f);
}

int ctex_tex_splat_late(ctex_tex *t, int ci, int cj, vec3 val, float blend, int max_r, float ex, float age)
{
    return splat_aniso(t, ci, cj, val, blend, max_r, ex, age > 0.0f ? age : 0.0f);
}

vec3 ctex_tex_unproject(const ctex_tex *t, float u, float v)
{
    if (t->kind == CTEX_PROJ_OBJECT)
        return v3_add(t->o, v3_add(v3_scale(t->t, u), v3_scale(t->b, v)));
    float px = t->x0 + u * (t->x1 - t->x0), py = t->y0 + v * (t->y1 - t->y0);
    vec3 d = cam_ray_dir(&t->cam, t->cam_w, t->cam_h, px, py);
    vec3 f;
    cam_axes(&t->cam, NULL, NULL, &f);
    float c = v3_dot(d, f);
    if (c < 1e-6f) c = 1e-6f;
    return v3_madd(t->cam.eye, d, t->ref_depth / c);
}

/* Nearest texel of position (u, v), clamped. */
static inline const ctex_texel *nearest(const ctex_tex *t, float u, float v)
{
    int i = (int)floorf(u * (float)t->w), j = (int)floorf(v * (float)t->h);
    i = i < 0 ? 0 : (i >= t->w ? t->w - 1 : i);
    j = j < 0 ? 0 : (j >= t->h ? t->h - 1 : j);
    return ctex_tex_at(t, i, j);
}

/* Bilinear over valid texels only (weights renormalized); false if none. */
static bool sample_valid(const ctex_tex *t, float x, float y, vec3 *out)
{
    float fx0 = floorf(x), fy0 = floorf(y);
    float fx = x - fx0, fy = y - fy0;
    int xs[2] = {(int)fx0, (int)fx0 + 1}, ys[2] = {(int)fy0, (int)fy0 + 1};
    float wx[2] = {1.0f - fx, fx}, wy[2] = {1.0f - fy, fy};
    float sw = 0.0f;
    vec3 acc = v3s(0.0f);
    for (int b = 0; b < 2; b++) {
        int yy = ys[b] < 0 ? 0 : (ys[b] >= t->h ? t->h - 1 : ys[b]);
        for (int a = 0; a < 2; a++) {
            int xx = xs[a] < 0 ? 0 : (xs[a] >= t->w ? t->w - 1 : xs[a]);
            const ctex_texel *p = ctex_tex_at(t, xx, yy);
            float w = wx[a] * wy[b];
            if (!ctex_texel_valid(p) || w <= 0.0f) continue;
            acc = v3_add(acc, v3_scale(ctex_texel_rgb(p), w));
            sw += w;
        }
    }
    if (sw <= 0.0f) return false;
    *out = v3_scale(acc, 1.0f / sw);
    return true;
}

/* CTEX_DBL_SLACK_Q, the distance (in steps of 1/CTEX_VQ texel) a doubling
 * adds to every texel's scaled distance. An old texel's distance was
 * measured from its centre, but its sample lay anywhere in it: twice the
 * old distance is what the new texels can claim at best, not what they
 * have. Claimed exactly, it ties with a fresh sample's even rings, which
 * put() does not take (a ring must beat a texel's validity), so the fresh
 * sample's splat stopped there and the older, interpolated values stayed
 * around it. On table at
 * 1024x1024, every pixel sampled once (corrtex converge), 432 of 992
 * 32-pixel blocks of the corrected image were more than 2 % off drt's
 * converged image, 26 with a quarter texel; PSNR against a path-traced
 * reference 33.5 -> 33.8 dB. The price: splats cover whole Voronoi cells,
 * insertion runs at about 0.4 of its rate before (docs/textures.md,
 * "Resolution"). */

/* Exact doubling along each axis with factor fx, fy in {1, 2} (not both 1):
 * a doubled axis gives new texel 2i+a weights 3/4 for old texel i and 1/4
 * for its neighbour towards the new centre (bilinear at the new centres,
 * clamp to edge); a kept axis weight 1. Weights are renormalized over valid
 * texels; the validity is texel i's with distances scaled by the factor and
 * CTEX_DBL_SLACK_Q added. The same values as the generic path, without its
 * per-texel searches. */
typedef struct dbl_ctx {
    float qm, vs;                 /* v_max in validity steps above vbase; the distance scale */
    float ws[4];                  /* weights of texel i, its x neighbour, its y neighbour, the diagonal */
    v4f w0, w1, w2, w3;           /* the same, four lanes each */
} dbl_ctx;

/* Validity step q with its distance to v_max scaled (clamped like ctex_tex_q). */
static inline int16_t dbl_q(const dbl_ctx *d, float q)
{
    float n = rintf(d->qm + (q - d->qm) * d->vs) - (float)CTEX_DBL_SLACK_Q;
    if (!(n > (float)CTEX_Q_OLDEST)) return CTEX_Q_OLDEST;
    return n > (float)INT16_MAX ? INT16_MAX : (int16_t)n;
}

/* All four covering texels valid (the common case): the weights sum to 1.
 * Four channels at a time, the same products and sums in the same order as
 * the scalar code (so the same bits); the validity is texel i's, rescaled. */
static inline void dbl_valid(const dbl_ctx *d, v4f p0, v4f p1, v4f p2, v4f p3, float q0, ctex_texel *q)
{
    v4f c = d->w0 * p0 + d->w1 * p1 + d->w2 * p2 + d->w3 * p3;
    float f[4];
    memcpy(f, &c, sizeof f);
    uint16_t h[4];
    float4_to_half(f, h);
    h[3] = (uint16_t)dbl_q(d, q0);
    memcpy(q, h, sizeof h);   /* one 8-byte store into the fresh array */
}

/* One new texel from old texel p0, its x neighbour p1, y neighbour p2 and
 * diagonal p3 (the same texel where an axis is kept or clamped). */
static inline void dbl_texel(const dbl_ctx *d, const ctex_texel *const ps[4], ctex_texel *q)
{
    if (ctex_texel_valid(ps[0]) && ctex_texel_valid(ps[1]) && ctex_texel_valid(ps[2]) &&
        ctex_texel_valid(ps[3])) {
        dbl_valid(d, texel4(ps[0]), texel4(ps[1]), texel4(ps[2]), texel4(ps[3]), ps[0]->q, q);
        return;
    }
    const float *ws = d->ws;
    float sw = 0.0f, cr = 0.0f, cg = 0.0f, cb = 0.0f;
    for (int k = 0; k < 4; k++)
        if (ctex_texel_valid(ps[k]) && ws[k] > 0.0f) {
            vec3 v = ctex_texel_rgb(ps[k]);
            sw += ws[k]; cr += ws[k] * v.x; cg += ws[k] * v.y; cb += ws[k] * v.z;
        }
    if (!(sw > 0.0f)) {
        ctex_texel_clear(q);
        return;
    }
    float inv = 1.0f / sw;
    q->c[0] = half_from_float(cr * inv); q->c[1] = half_from_float(cg * inv); q->c[2] = half_from_float(cb * inv);
    /* an empty covering texel next to valid ones: one texel off */
    q->q = dbl_q(d, ctex_texel_valid(ps[0]) ? (float)ps[0]->q : d->qm - (float)CTEX_VQ);
}

static dbl_ctx dbl_init(const ctex_tex *t, int fx, int fy)
{
    dbl_ctx d;
    d.qm = (t->vmax - t->vbase) * (float)CTEX_VQ;
    d.vs = (float)(fx > fy ? fx : fy);
    const float wx1 = fx == 2 ? 0.25f : 0.0f, wy1 = fy == 2 ? 0.25f : 0.0f;
    d.ws[0] = (1.0f - wx1) * (1.0f - wy1); d.ws[1] = wx1 * (1.0f - wy1);
    d.ws[2] = (1.0f - wx1) * wy1; d.ws[3] = wx1 * wy1;
    d.w0 = (v4f){d.ws[0], d.ws[0], d.ws[0], d.ws[0]}; d.w1 = (v4f){d.ws[1], d.ws[1], d.ws[1], d.ws[1]};
    d.w2 = (v4f){d.ws[2], d.ws[2], d.ws[2], d.ws[2]}; d.w3 = (v4f){d.ws[3], d.ws[3], d.ws[3], d.ws[3]};
    return d;
}

/* Old rows [j0, j1) of an exact doubling (fx, fy in {1, 2}) into nt. */
static void double_rows(const ctex_tex *t, const dbl_ctx *dp, ctex_texel *nt, int npitch, int fx, int fy, int j0,
                        int j1)
{
    const int w = t->w, h = t->h;
    const dbl_ctx d = *dp;
    for (int j = j0; j < j1; j++) {
        for (int b = 0; b < fy; b++) {
            int jn = fy == 1 ? j : (b ? (j + 1 < h ? j + 1 : j) : (j > 0 ? j - 1 : 0));
            const ctex_texel *r0 = ctex_tex_at(t, 0, j), *r1 = ctex_tex_at(t, 0, jn);
            ctex_texel *o = nt + (size_t)(fy * j + b) * (size_t)npitch;
            int i = 0;
            if (fx == 2 && w >= 3) {
                /* first column clamped, then the interior two new texels
                 * at a time from a 3 x 2 window of old texels */
                for (int a = 0; a < 2; a++) {
                    const ctex_texel *ps[4] = {r0, r0 + a, r1, r1 + a};
                    dbl_texel(&d, ps, o + a);
                }
                for (i = 1; i < w - 1; i++) {
                    const ctex_texel *A = r0 + i - 1, *B = r1 + i - 1;
                    if (ctex_texel_valid(A) && ctex_texel_valid(A + 1) && ctex_texel_valid(A + 2) &&
                        ctex_texel_valid(B) && ctex_texel_valid(B + 1) && ctex_texel_valid(B + 2)) {
                        v4f a0 = texel4(A), a1 = texel4(A + 1), a2 = texel4(A + 2);
                        v4f b0 = texel4(B), b1 = texel4(B + 1), b2 = texel4(B + 2);
                        dbl_valid(&d, a1, a0, b1, b0, A[1].q, o + 2 * i);
                        dbl_valid(&d, a1, a2, b1, b2, A[1].q, o + 2 * i + 1);
                        continue;
                    }
                    const ctex_texel *p0[4] = {A + 1, A, B + 1, B}, *p1[4] = {A + 1, A + 2, B + 1, B + 2};
                    dbl_texel(&d, p0, o + 2 * i);
                    dbl_texel(&d, p1, o + 2 * i + 1);
                }
            }
            for (; i < w; i++) {
                for (int a = 0; a < fx; a++) {
                    int in = fx == 1 ? i : (a ? (i + 1 < w ? i + 1 : i) : (i > 0 ? i - 1 : 0));
                    const ctex_texel *ps[4] = {r0 + i, r0 + in, r1 + i, r1 + in};
                    dbl_texel(&d, ps, o + fx * i + a);
                }
            }
        }
    }
}

/* New rows [j0, j1) of an exact halving with block sizes bx, by in {1, 2}
 * (odd sizes: the last block is one texel wide): the mean of each block's
 * valid texels, the best validity, distances scaled down. */
static void halve_rows(const ctex_tex *t, ctex_texel *nt, int npitch, int nw, int bx, int by, int j0, int j1)
{
    const int w = t->w, h = t->h;
    const float vmax = t->vmax, vs = 1.0f / (float)(bx > by ? bx : by);
    /* (nt shares t's vbase: ctex_tex_resize) */
    for (int j = j0; j < j1; j++) {
        int y0 = by * j, y1 = y0 + by > h ? h : y0 + by;
        ctex_texel *o = nt + (size_t)j * (size_t)npitch;
        for (int i = 0; i < nw; i++) {
            int x0 = bx * i, x1 = x0 + bx > w ? w : x0 + bx;
            float cr = 0.0f, cg = 0.0f, cb = 0.0f, best = -INFINITY;
            int n = 0;
            for (int y = y0; y < y1; y++)
                for (int x = x0; x < x1; x++) {
                    const ctex_texel *p = ctex_tex_at(t, x, y);
                    if (!ctex_texel_valid(p)) continue;
                    vec3 v = ctex_texel_rgb(p);
                    cr += v.x; cg += v.y; cb += v.z;
                    float pv = ctex_tex_v(t, p);
                    if (pv > best) best = pv;
                    n++;
                }
            ctex_texel *q = o + i;
            if (!n) {
                ctex_texel_clear(q);
                continue;
            }
            float inv = 1.0f / (float)n;
            ctex_texel_set(t, q, v3(cr * inv, cg * inv, cb * inv), vmax + (best - vmax) * vs);
        }
    }
}

/* An exact resize's rows in bands, one task each (the pool's threads write
 * disjoint rows of the new array from the old one: the same texels for any
 * thread count). A resize of a large texture is a pass over millions of
 * texels, most of them fresh pages the kernel zeroes on first touch, and
 * the parallel insertion's threads would otherwise wait for it. */
enum { RESIZE_BAND = 32 };   /* rows a task */
#define RESIZE_PAR_TEXELS ((size_t)1 << 16)   /* old texels from which a resize is split */

typedef struct resize_job {
    const ctex_tex *t;
    ctex_texel *nt;
    int npitch, rows, f1, f2;   /* f1, f2: fx, fy (doubling) or bx, by (halving); rows: of the pass */
    int nw;                     /* halving: the new width */
    const dbl_ctx *d;           /* doubling; NULL: halving */
} resize_job;

static void resize_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    const resize_job *r = ctx;
    int j0 = (int)task * RESIZE_BAND, j1 = j0 + RESIZE_BAND < r->rows ? j0 + RESIZE_BAND : r->rows;
    if (r->d)
        double_rows(r->t, r->d, r->nt, r->npitch, r->f1, r->f2, j0, j1);
    else
        halve_rows(r->t, r->nt, r->npitch, r->nw, r->f1, r->f2, j0, j1);
}

static void resize_run(ct_pool *pool, resize_job *r)
{
    size_t tasks = (size_t)(r->rows + RESIZE_BAND - 1) / RESIZE_BAND;
    /* a small texture: not worth waking the workers */
    if ((size_t)r->t->h * (size_t)r->t->pitch < RESIZE_PAR_TEXELS) pool = NULL;
    pool_run(pool, tasks, resize_task, r);
}

int ctex_tex_resize(ctex_tex *t, int nw, int nh, ct_error *err)
{
    return ctex_tex_resize_on(t, nw, nh, NULL, err);
}

int ctex_tex_resize_on(ctex_tex *t, int nw, int nh, ct_pool *pool, ct_error *err)
{
    if (nw < 1 || nh < 1 || nw > 65536 || nh > 65536)
        return ct_fail(err, CT_EINVAL, "texture size %dx%d out of range", nw, nh);
    if (nw == t->w && nh == t->h) return CT_OK;
    const int npitch = ctex_tex_pitch(nw);
    ctex_texel *nt = alloc_texels(t, (size_t)npitch * (size_t)nh);
    if (!nt) return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d texture", nw, nh);
    if (wire_tex_resize_exact(t->w, t->h, nw, nh) ? ctex_dirty_rescale(&t->d, t->w, t->h, nw, nh, err)
                                                  : ctex_dirty_reset(&t->d, nw, nh, err)) {
        ctex_mem_put(t->mem, nt, ctex_tex_bytes(nw, nh));
        return CT_ENOMEM;
    }
    {
        int fx = nw == 2 * t->w ? 2 : (nw == t->w ? 1 : 0), fy = nh == 2 * t->h ? 2 : (nh == t->h ? 1 : 0);
        if (fx && fy) {
            const dbl_ctx d = dbl_init(t, fx, fy);
            resize_job r = {t, nt, npitch, t->h, fx, fy, nw, &d};
            resize_run(pool, &r);
            goto done;
        }
        int bx = nw == (t->w + 1) / 2 ? 2 : (nw == t->w ? 1 : 0), by = nh == (t->h + 1) / 2 ? 2 : (nh == t->h ? 1 : 0);
        if (bx && by) {
            resize_job r = {t, nt, npitch, nh, bx, by, nw, NULL};
            resize_run(pool, &r);
            goto done;
        }
    }
    const float sx = (float)t->w / (float)nw, sy = (float)t->h / (float)nh;
    /* Validities are distances in texels: rescale them relative to v_max. */
    const float vs = 1.0f / fmaxf(sx, sy);
    const float slack = (float)CTEX_DBL_SLACK_Q / (float)CTEX_VQ;   /* what a doubling adds (dbl_q) */
    const bool shrink = nw <= t->w && nh <= t->h;
    for (int j = 0; j < nh; j++) {
        for (int i = 0; i < nw; i++) {
            ctex_texel *o = nt + (size_t)j * (size_t)npitch + (size_t)i;
            ctex_texel_clear(o);
            if (shrink) {
                /* §3.6: box filter, area-weighted over the old texels the new
                 * one covers; empty texels do not count. */
                float ax = (float)i * sx, bx = (float)(i + 1) * sx;
                float ay = (float)j * sy, by = (float)(j + 1) * sy;
                int ix0 = (int)floorf(ax), ix1 = (int)ceilf(bx), iy0 = (int)floorf(ay), iy1 = (int)ceilf(by);
                if (ix1 > t->w) ix1 = t->w;
                if (iy1 > t->h) iy1 = t->h;
                double acc[3] = {0, 0, 0}, sw = 0;
                float best = -INFINITY;
                for (int y = iy0; y < iy1; y++) {
                    float wy = fminf(by, (float)(y + 1)) - fmaxf(ay, (float)y);
                    if (wy <= 0.0f) continue;
                    for (int x = ix0; x < ix1; x++) {
                        float wx = fminf(bx, (float)(x + 1)) - fmaxf(ax, (float)x);
                        if (wx <= 0.0f) continue;
                        const ctex_texel *p = ctex_tex_at(t, x, y);
                        if (!ctex_texel_valid(p)) continue;
                        double w = (double)wx * (double)wy;
                        vec3 v = ctex_texel_rgb(p);
                        acc[0] += w * v.x; acc[1] += w * v.y; acc[2] += w * v.z;
                        sw += w;
                        float pv = ctex_tex_v(t, p);
                        if (pv > best) best = pv;
                    }
                }
                if (sw > 0.0)
                    ctex_texel_set(t, o, v3((float)(acc[0] / sw), (float)(acc[1] / sw), (float)(acc[2] / sw)),
                                   t->vmax + (best - t->vmax) * vs);
            } else {
                /* §3.6: bilinear refinement (texel centres, clamp to edge). */
                float x = ((float)i + 0.5f) * sx - 0.5f, y = ((float)j + 0.5f) * sy - 0.5f;
                vec3 val;
                if (sample_valid(t, x, y, &val)) {
                    const ctex_texel *p = nearest(t, ((float)i + 0.5f) / (float)nw, ((float)j + 0.5f) / (float)nh);
                    float best = ctex_tex_v(t, p);
                    if (best == -INFINITY) {
                        /* next to the valid region: take the neighbours' best */
                        best = t->vmax - 1.0f;
                    }
                    ctex_texel_set(t, o, val, t->vmax + (best - t->vmax) * vs - slack);
                }
            }
        }
    }
done:
    free_texels(t, t->tx);
    t->tx = nt;
    t->w = nw;
    t->h = nh;
    t->pitch = npitch;
    return CT_OK;
}

void ctex_tex_resample(ctex_tex *dst, const ctex_tex *const *src, int nsrc, float penalty)
{
    /* The unprojection is affine in (u, v) for both kinds (object-local: the
     * frame; camera-local: eye + depth * (forward + right sx + up sy) with
     * sx, sy affine in the pixel position), so three calls give it all. */
    vec3 x0 = ctex_tex_unproject(dst, 0.0f, 0.0f);
    vec3 xu = v3_sub(ctex_tex_unproject(dst, 1.0f, 0.0f), x0);
    vec3 xv = v3_sub(ctex_tex_unproject(dst, 0.0f, 1.0f), x0);
    const float iw = 1.0f / (float)dst->w, ih = 1.0f / (float)dst->h;
    dst->vbase = dst->vmax;   /* every texel is written below */
    for (int j = 0; j < dst->h; j++) {
        vec3 row = v3_madd(x0, xv, ((float)j + 0.5f) * ih);
        for (int i = 0; i < dst->w; i++) {
            ctex_texel *o = ctex_tex_at(dst, i, j);
            vec3 out = v3s(0.0f);
            vec3 p = v3_madd(row, xu, ((float)i + 0.5f) * iw);
            float best = -INFINITY;
            for (int s = 0; s < nsrc; s++) {
                const ctex_tex *st = src[s];
                float u, v;
                if (!ctex_tex_project(st, p, &u, &v) || !ctex_tex_covers(st, u, v)) continue;
                const ctex_texel *n = nearest(st, u, v);
                if (!ctex_texel_valid(n)) continue;
                float rel = ctex_tex_v(st, n) - st->vmax;
                if (rel <= best) continue;
                vec3 val;
                if (!sample_valid(st, u * (float)st->w - 0.5f, v * (float)st->h - 0.5f, &val)) continue;
                best = rel;
                out = val;
            }
            if (best > -INFINITY)
                ctex_texel_set(dst, o, out, dst->vmax + best - penalty);
            else
                ctex_texel_clear(o);
        }
    }
    ctex_dirty_mark_all(&dst->d);
}

vec3 ctex_tex_mean(const ctex_tex *t, uint32_t *nvalid)
{
    double acc[3] = {0, 0, 0};
    uint32_t n = 0;
    for (int y = 0; y < t->h; y++)
        for (int x = 0; x < t->w; x++) {
            const ctex_texel *p = ctex_tex_at(t, x, y);
            if (!ctex_texel_valid(p)) continue;
            vec3 v = ctex_texel_rgb(p);
            acc[0] += v.x; acc[1] += v.y; acc[2] += v.z;
            n++;
        }
    if (nvalid) *nvalid = n;
    if (!n) return v3s(0.0f);
    return v3((float)(acc[0] / n), (float)(acc[1] / n), (float)(acc[2] / n));
}
