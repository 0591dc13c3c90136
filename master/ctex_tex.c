/* ctex_tex.c: texel storage, ring splatting, resizing and resampling of one
 * corrective texture (see ctex_tex.h and docs/textures.md). */
#include "master/ctex_tex.h"

#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

/* Four floats: a texel (r, g, b, v) in one SSE register (GCC/Clang vector
 * extensions, portable C): the same IEEE single-precision operations as
 * scalar code, so the results are bit-identical. */
typedef float v4f __attribute__((vector_size(16)));
typedef int32_t v4i __attribute__((vector_size(16)));

/* Texel storage. Samples land anywhere in 5-15 million texels (tens of MiB),
 * so with 4 KiB pages nearly every splat misses the TLB as well as the
 * caches; arrays of 2 MiB and more are aligned to 2 MiB and advised as huge
 * pages (transparent huge pages in "madvise" mode), which removes most page
 * walks. The size is not rounded up: the tail past the last whole 2 MiB stays
 * in small pages, so the memory cap's count (ctex_tex_bytes: 16 bytes a
 * texel of the padded rows) stays true. Freed with free(). */
static ctex_texel *alloc_texels(size_t n)
{
    enum { HUGE = 2u << 20 };
    size_t bytes = n * sizeof(ctex_texel);
    if (bytes < HUGE) return malloc(bytes);
    void *p = NULL;
    if (posix_memalign(&p, HUGE, bytes)) return NULL;
#ifdef MADV_HUGEPAGE
    (void)madvise(p, bytes, MADV_HUGEPAGE);   /* a hint: failure only costs speed */
#endif
    return p;
}

static void clear_texels(ctex_texel *tx, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        tx[i].r = tx[i].g = tx[i].b = 0.0f;
        tx[i].v = -INFINITY;
    }
}

int ctex_tex_init(ctex_tex *t, int w, int h, ct_error *err)
{
    if (w < 1 || h < 1 || w > 65536 || h > 65536)
        return ct_fail(err, CT_EINVAL, "texture size %dx%d out of range", w, h);
    const int pitch = ctex_tex_pitch(w);
    ctex_texel *tx = alloc_texels((size_t)pitch * (size_t)h);
    if (!tx) return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d texture", w, h);
    clear_texels(tx, (size_t)pitch * (size_t)h);
    free(t->tx);
    t->tx = tx;
    t->w = w;
    t->h = h;
    t->pitch = pitch;
    t->vmax = 0.0f;   /* §3.4: the first samples start at validity 0 */
    t->mean_r = 0.0f;
    t->since_resize = 0;
    t->last_resize = 0;
    t->dx0 = 0; t->dy0 = 0; t->dx1 = w; t->dy1 = h;
    return CT_OK;
}

void ctex_tex_release(ctex_tex *t)
{
    free(t->tx);
    t->tx = NULL;
    t->w = t->h = t->pitch = 0;
}

/* Writes value into texel x with margin m = v_new - v_old; blend: band. */
static inline int put(ctex_texel *x, float vn, vec3 val, float blend)
{
    float m = vn - x->v;
    if (m > 0.0f) {
        if (m >= blend) {
            /* one 16-byte store */
            *x = (ctex_texel){val.x, val.y, val.z, vn};
            return 1;
        } else {
            /* §3.4: blend new and old by their validities at splat borders */
            float w = 0.5f + 0.5f * m / blend;
            x->r += w * (val.x - x->r); x->g += w * (val.y - x->g); x->b += w * (val.z - x->b);
        }
        x->v = vn;
        return 1;
    }
    if (m > -blend) {
        float w = 0.5f + 0.5f * m / blend;
        x->r += w * (val.x - x->r); x->g += w * (val.y - x->g); x->b += w * (val.z - x->b);
    }
    return 0;
}

int ctex_tex_splat(ctex_tex *t, int ci, int cj, vec3 val, float blend, int max_r)
{
    const int W = t->w, H = t->h;
    const size_t P = (size_t)t->pitch;
    ctex_texel *T = t->tx;
    const float vmax = t->vmax;
    if (blend < 0.0f) blend = 0.0f;
    /* The centre texel always takes the newest sample. */
    ctex_texel *c = T + (size_t)cj * P + (size_t)ci;
    c->r = val.x; c->g = val.y; c->b = val.z;
    c->v = vmax > c->v ? vmax : c->v;
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
        const float vn = vmax - 1.0f;
        ctex_texel *a = c - P, *b = c + P;
        int changed = put(a - 1, vn, val, blend) | put(a, vn, val, blend) | put(a + 1, vn, val, blend);
        changed |= put(b - 1, vn, val, blend) | put(b, vn, val, blend) | put(b + 1, vn, val, blend);
        changed |= put(c - 1, vn, val, blend) | put(c + 1, vn, val, blend);
        if (!changed) goto dirty;
        r = 1;
        k = 2;
    }
    for (; k <= kmax; k++) {
        const float vn = vmax - (float)k;   /* §3.4: validity v_max - d */
        int changed = 0;
        int xa = ci - k < 0 ? 0 : ci - k, xb = ci + k > W - 1 ? W - 1 : ci + k;
        /* top and bottom rows of the ring */
        if (cj - k >= 0) {
            ctex_texel *row = T + (size_t)(cj - k) * P;
            for (int x = xa; x <= xb; x++) changed |= put(row + x, vn, val, blend);
        }
        if (cj + k <= H - 1) {
            ctex_texel *row = T + (size_t)(cj + k) * P;
            for (int x = xa; x <= xb; x++) changed |= put(row + x, vn, val, blend);
        }
        /* left and right columns without the corners */
        int ya = cj - k + 1 < 0 ? 0 : cj - k + 1, yb = cj + k - 1 > H - 1 ? H - 1 : cj + k - 1;
        if (ci - k >= 0)
            for (int y = ya; y <= yb; y++) changed |= put(T + (size_t)y * P + (size_t)(ci - k), vn, val, blend);
        if (ci + k <= W - 1)
            for (int y = ya; y <= yb; y++) changed |= put(T + (size_t)y * P + (size_t)(ci + k), vn, val, blend);
        if (!changed) break;
        r = k;
    }
dirty:;
    /* Dirty: everything up to the ring that stopped the splat (it may have
     * been blended). */
    int e = k > kmax ? kmax : k;
    int x0 = ci - e < 0 ? 0 : ci - e, x1 = ci + e + 1 > W ? W : ci + e + 1;
    int y0 = cj - e < 0 ? 0 : cj - e, y1 = cj + e + 1 > H ? H : cj + e + 1;
    if (t->dx0 >= t->dx1 || t->dy0 >= t->dy1) {
        t->dx0 = x0; t->dx1 = x1; t->dy0 = y0; t->dy1 = y1;
    } else {
        if (x0 < t->dx0) t->dx0 = x0;
        if (x1 > t->dx1) t->dx1 = x1;
        if (y0 < t->dy0) t->dy0 = y0;
        if (y1 > t->dy1) t->dy1 = y1;
    }
    return r;
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
            if (p->v == -INFINITY || w <= 0.0f) continue;
            acc = v3_add(acc, v3(p->r * w, p->g * w, p->b * w));
            sw += w;
        }
    }
    if (sw <= 0.0f) return false;
    *out = v3_scale(acc, 1.0f / sw);
    return true;
}

/* Exact doubling along each axis with factor fx, fy in {1, 2} (not both 1):
 * a doubled axis gives new texel 2i+a weights 3/4 for old texel i and 1/4
 * for its neighbour towards the new centre (bilinear at the new centres,
 * clamp to edge); a kept axis weight 1. Weights are renormalized over valid
 * texels; the validity is texel i's with distances scaled by the factor.
 * The same values as the generic path, without its per-texel searches. */
typedef struct dbl_ctx {
    float vmax, vs;
    float ws[4];                  /* weights of texel i, its x neighbour, its y neighbour, the diagonal */
    v4f w0, w1, w2, w3, vm, vsv;  /* the same, four lanes each */
} dbl_ctx;

/* All four covering texels valid (the common case): the weights sum to 1.
 * Four channels at a time, the same products and sums in the same order as
 * the scalar code (so the same bits); the validity lane is texel i's,
 * rescaled. */
static inline void dbl_valid(const dbl_ctx *d, v4f p0, v4f p1, v4f p2, v4f p3, ctex_texel *q)
{
    const v4i rgb = {-1, -1, -1, 0};
    v4f c = d->w0 * p0 + d->w1 * p1 + d->w2 * p2 + d->w3 * p3;
    v4f v = d->vm + (p0 - d->vm) * d->vsv;
    v4i out = ((v4i)c & rgb) | ((v4i)v & ~rgb);
    memcpy(q, &out, sizeof out);
}

/* One new texel from old texel p0, its x neighbour p1, y neighbour p2 and
 * diagonal p3 (the same texel where an axis is kept or clamped). */
static inline void dbl_texel(const dbl_ctx *d, const ctex_texel *const ps[4], ctex_texel *q)
{
    if (ps[0]->v != -INFINITY && ps[1]->v != -INFINITY && ps[2]->v != -INFINITY && ps[3]->v != -INFINITY) {
        v4f p0, p1, p2, p3;
        memcpy(&p0, ps[0], sizeof p0); memcpy(&p1, ps[1], sizeof p1);
        memcpy(&p2, ps[2], sizeof p2); memcpy(&p3, ps[3], sizeof p3);
        dbl_valid(d, p0, p1, p2, p3, q);
        return;
    }
    const float *ws = d->ws;
    float sw = 0.0f, cr = 0.0f, cg = 0.0f, cb = 0.0f;
    for (int k = 0; k < 4; k++)
        if (ps[k]->v != -INFINITY && ws[k] > 0.0f) {
            sw += ws[k]; cr += ws[k] * ps[k]->r; cg += ws[k] * ps[k]->g; cb += ws[k] * ps[k]->b;
        }
    if (!(sw > 0.0f)) {
        q->r = q->g = q->b = 0.0f;
        q->v = -INFINITY;
        return;
    }
    float inv = 1.0f / sw;
    q->r = cr * inv; q->g = cg * inv; q->b = cb * inv;
    /* an empty covering texel next to valid ones: one texel off */
    float v = ps[0]->v == -INFINITY ? d->vmax - 1.0f : ps[0]->v;
    q->v = d->vmax + (v - d->vmax) * d->vs;
}

static void double_exact(const ctex_tex *t, ctex_texel *nt, int npitch, int fx, int fy)
{
    const int w = t->w, h = t->h;
    dbl_ctx d;
    d.vmax = t->vmax;
    d.vs = (float)(fx > fy ? fx : fy);
    const float wx1 = fx == 2 ? 0.25f : 0.0f, wy1 = fy == 2 ? 0.25f : 0.0f;
    d.ws[0] = (1.0f - wx1) * (1.0f - wy1); d.ws[1] = wx1 * (1.0f - wy1);
    d.ws[2] = (1.0f - wx1) * wy1; d.ws[3] = wx1 * wy1;
    d.w0 = (v4f){d.ws[0], d.ws[0], d.ws[0], d.ws[0]}; d.w1 = (v4f){d.ws[1], d.ws[1], d.ws[1], d.ws[1]};
    d.w2 = (v4f){d.ws[2], d.ws[2], d.ws[2], d.ws[2]}; d.w3 = (v4f){d.ws[3], d.ws[3], d.ws[3], d.ws[3]};
    d.vm = (v4f){d.vmax, d.vmax, d.vmax, d.vmax}; d.vsv = (v4f){d.vs, d.vs, d.vs, d.vs};
    for (int j = 0; j < h; j++) {
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
                    if (A[0].v != -INFINITY && A[1].v != -INFINITY && A[2].v != -INFINITY &&
                        B[0].v != -INFINITY && B[1].v != -INFINITY && B[2].v != -INFINITY) {
                        v4f a0, a1, a2, b0, b1, b2;
                        memcpy(&a0, A, sizeof a0); memcpy(&a1, A + 1, sizeof a1); memcpy(&a2, A + 2, sizeof a2);
                        memcpy(&b0, B, sizeof b0); memcpy(&b1, B + 1, sizeof b1); memcpy(&b2, B + 2, sizeof b2);
                        dbl_valid(&d, a1, a0, b1, b0, o + 2 * i);
                        dbl_valid(&d, a1, a2, b1, b2, o + 2 * i + 1);
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

/* Exact halving with block sizes bx, by in {1, 2} (odd sizes: the last block
 * is one texel wide): the mean of each block's valid texels, the best
 * validity, distances scaled down. */
static void halve_exact(const ctex_tex *t, ctex_texel *nt, int npitch, int nw, int nh, int bx, int by)
{
    const int w = t->w, h = t->h;
    const float vmax = t->vmax, vs = 1.0f / (float)(bx > by ? bx : by);
    for (int j = 0; j < nh; j++) {
        int y0 = by * j, y1 = y0 + by > h ? h : y0 + by;
        ctex_texel *o = nt + (size_t)j * (size_t)npitch;
        for (int i = 0; i < nw; i++) {
            int x0 = bx * i, x1 = x0 + bx > w ? w : x0 + bx;
            float cr = 0.0f, cg = 0.0f, cb = 0.0f, best = -INFINITY;
            int n = 0;
            for (int y = y0; y < y1; y++)
                for (int x = x0; x < x1; x++) {
                    const ctex_texel *p = ctex_tex_at(t, x, y);
                    if (p->v == -INFINITY) continue;
                    cr += p->r; cg += p->g; cb += p->b;
                    if (p->v > best) best = p->v;
                    n++;
                }
            ctex_texel *q = o + i;
            if (!n) {
                q->r = q->g = q->b = 0.0f;
                q->v = -INFINITY;
                continue;
            }
            float inv = 1.0f / (float)n;
            q->r = cr * inv; q->g = cg * inv; q->b = cb * inv;
            q->v = vmax + (best - vmax) * vs;
        }
    }
}

int ctex_tex_resize(ctex_tex *t, int nw, int nh, ct_error *err)
{
    if (nw < 1 || nh < 1 || nw > 65536 || nh > 65536)
        return ct_fail(err, CT_EINVAL, "texture size %dx%d out of range", nw, nh);
    if (nw == t->w && nh == t->h) return CT_OK;
    const int npitch = ctex_tex_pitch(nw);
    ctex_texel *nt = alloc_texels((size_t)npitch * (size_t)nh);
    if (!nt) return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d texture", nw, nh);
    {
        int fx = nw == 2 * t->w ? 2 : (nw == t->w ? 1 : 0), fy = nh == 2 * t->h ? 2 : (nh == t->h ? 1 : 0);
        if (fx && fy) {
            double_exact(t, nt, npitch, fx, fy);
            goto done;
        }
        int bx = nw == (t->w + 1) / 2 ? 2 : (nw == t->w ? 1 : 0), by = nh == (t->h + 1) / 2 ? 2 : (nh == t->h ? 1 : 0);
        if (bx && by) {
            halve_exact(t, nt, npitch, nw, nh, bx, by);
            goto done;
        }
    }
    const float sx = (float)t->w / (float)nw, sy = (float)t->h / (float)nh;
    /* Validities are distances in texels: rescale them relative to v_max. */
    const float vs = 1.0f / fmaxf(sx, sy);
    const bool shrink = nw <= t->w && nh <= t->h;
    for (int j = 0; j < nh; j++) {
        for (int i = 0; i < nw; i++) {
            ctex_texel *o = nt + (size_t)j * (size_t)npitch + (size_t)i;
            o->r = o->g = o->b = 0.0f;
            o->v = -INFINITY;
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
                        if (p->v == -INFINITY) continue;
                        double w = (double)wx * (double)wy;
                        acc[0] += w * p->r; acc[1] += w * p->g; acc[2] += w * p->b;
                        sw += w;
                        if (p->v > best) best = p->v;
                    }
                }
                if (sw > 0.0) {
                    o->r = (float)(acc[0] / sw); o->g = (float)(acc[1] / sw); o->b = (float)(acc[2] / sw);
                    o->v = t->vmax + (best - t->vmax) * vs;
                }
            } else {
                /* §3.6: bilinear refinement (texel centres, clamp to edge). */
                float x = ((float)i + 0.5f) * sx - 0.5f, y = ((float)j + 0.5f) * sy - 0.5f;
                vec3 val;
                if (sample_valid(t, x, y, &val)) {
                    const ctex_texel *p = nearest(t, ((float)i + 0.5f) / (float)nw, ((float)j + 0.5f) / (float)nh);
                    float best = p->v;
                    if (best == -INFINITY) {
                        /* next to the valid region: take the neighbours' best */
                        best = t->vmax - 1.0f;
                    }
                    o->r = val.x; o->g = val.y; o->b = val.z;
                    o->v = t->vmax + (best - t->vmax) * vs;
                }
            }
        }
    }
done:
    free(t->tx);
    t->tx = nt;
    t->w = nw;
    t->h = nh;
    t->pitch = npitch;
    t->dx0 = 0; t->dy0 = 0; t->dx1 = nw; t->dy1 = nh;
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
    for (int j = 0; j < dst->h; j++) {
        vec3 row = v3_madd(x0, xv, ((float)j + 0.5f) * ih);
        for (int i = 0; i < dst->w; i++) {
            ctex_texel *o = ctex_tex_at(dst, i, j);
            o->r = o->g = o->b = 0.0f;
            o->v = -INFINITY;
            vec3 p = v3_madd(row, xu, ((float)i + 0.5f) * iw);
            float best = -INFINITY;
            for (int s = 0; s < nsrc; s++) {
                const ctex_tex *st = src[s];
                float u, v;
                if (!ctex_tex_project(st, p, &u, &v)) continue;
                /* half a texel of slack at the borders */
                float mu = 0.5f / (float)st->w, mv = 0.5f / (float)st->h;
                if (u < -mu || u > 1.0f + mu || v < -mv || v > 1.0f + mv) continue;
                const ctex_texel *n = nearest(st, u, v);
                if (n->v == -INFINITY) continue;
                float rel = n->v - st->vmax;
                if (rel <= best) continue;
                vec3 val;
                if (!sample_valid(st, u * (float)st->w - 0.5f, v * (float)st->h - 0.5f, &val)) continue;
                best = rel;
                o->r = val.x; o->g = val.y; o->b = val.z;
            }
            if (best > -INFINITY) o->v = dst->vmax + best - penalty;
        }
    }
    dst->dx0 = 0; dst->dy0 = 0; dst->dx1 = dst->w; dst->dy1 = dst->h;
}

vec3 ctex_tex_mean(const ctex_tex *t, uint32_t *nvalid)
{
    double acc[3] = {0, 0, 0};
    uint32_t n = 0;
    for (int y = 0; y < t->h; y++)
        for (int x = 0; x < t->w; x++) {
            const ctex_texel *p = ctex_tex_at(t, x, y);
            if (p->v == -INFINITY) continue;
            acc[0] += p->r; acc[1] += p->g; acc[2] += p->b;
            n++;
        }
    if (nvalid) *nvalid = n;
    if (!n) return v3s(0.0f);
    return v3((float)(acc[0] / n), (float)(acc[1] / n), (float)(acc[2] / n));
}
