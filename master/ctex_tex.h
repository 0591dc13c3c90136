/* ctex_tex.h: one corrective texture's texels and the operations on them:
 * ring splatting with validities (§3.4), v_max aging (§3.5), resolution
 * changes by box filter and bilinear interpolation (§3.6), bilinear lookup
 * and resampling from other textures through their projections. Used by the
 * engine in ctex.c; public so tests can drive a single texture. */
#ifndef CT_MASTER_CTEX_TEX_H
#define CT_MASTER_CTEX_TEX_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/half.h"
#include "common/vecmath.h"
#include "master/ctex.h"
#include "master/ctex_dirty.h"

/* One texel, 8 bytes: the signed RGB correction as IEEE half floats (the
 * values the display receives and draws, so the ΔL the master reads back is
 * the displayed one) and the validity in fixed point, q steps of
 * 1/CTEX_VQ texel above the texture's vbase (ctex_tex_v). Half the 16 bytes
 * of a float texel: splats are bound by memory traffic (docs/textures.md,
 * "Texel format"). */
typedef struct ctex_texel {
    uint16_t c[3];   /* correction R, G, B (binary16) */
    int16_t q;       /* validity: vbase + q / CTEX_VQ texels; CTEX_Q_EMPTY when empty */
} ctex_texel;

enum {
    CTEX_VQ = 8,                      /* validity steps per texel */
    CTEX_Q_EMPTY = INT16_MIN,         /* no correction: older than everything */
    CTEX_Q_OLDEST = INT16_MIN + 1,    /* older validities clamp to this one */
    CTEX_Q_REBASE = 4096,             /* vmax more than 512 texels above vbase: rebase */
    CTEX_DBL_SLACK_Q = 2              /* steps a doubling adds to every distance (ctex_tex.c) */
};

/* A texture with its projection. */
typedef struct ctex_tex {
    int w, h;
    int pitch;             /* texels from one row to the next (ctex_tex_pitch(w)) */
    ctex_texel *tx;        /* h rows of `pitch` texels, the first w of each used; row 0 first */
    float vmax;            /* §3.5: validity of a new sample's centre texel */
    float vbase;           /* validity of q = 0; follows vmax (ctex_tex_rebase) */
    ctex_proj_kind kind;
    mat4 m;                /* world -> texture */
    /* Unprojection of a texel centre to a world point (resampling): */
    vec3 o, t, b, n;       /* object-local: p = o + t*u + b*v (u, v in [0,1]) */
    ct_camera cam;         /* camera-local: the camera it was made for */
    int cam_w, cam_h;
    float x0, y0, x1, y1;  /* camera-local: the pixel rectangle mapped to [0,1]^2 */
    float ref_depth;       /* camera-local: depth of the plane used to unproject */
    /* §3.6 running mean of splat radii */
    float mean_r;
    double sum_r;          /* the clamped radii since the last change or aging (ctex_insert.c) */
    uint32_t n_sum;        /* how many */
    uint32_t since_resize;
    int last_resize;       /* +1 doubled, -1 halved, 0 none: hysteresis */
    uint8_t reversals;     /* changes that undid the one before (ctex_insert.c) */
    ctex_dirty d;          /* texels the display has not received (ctex_dirty.h) */
    struct ctex_mem *mem;  /* where its texel arrays come from and go back to (ctex_mem.h); NULL: the system */
} ctex_tex;

/* Row pitch of a texture w texels wide: w rounded up to whole 64-byte cache
 * lines (8 texels), plus one line when that is an even number of lines.
 * Texture widths are powers of two times the initial size, so rows of w
 * texels would lie a multiple of 4 KiB apart (16 KiB at w = 2048) and the
 * texels of a ring's column would all fall into the same few cache sets
 * (L1 and L2 index by the low address bits): a column of a large splat then
 * evicts itself before the next ring reuses its lines. An odd number of
 * lines per row spreads consecutive rows over all sets. */
static inline int ctex_tex_pitch(int w)
{
    int p = (w + 7) & ~7;
    if (!((p >> 3) & 1)) p += 8;
    return p;
}

/* Bytes of texel storage of a w x h texture (what the memory cap counts:
 * 8 bytes a texel, plus the row padding). */
static inline size_t ctex_tex_bytes(int w, int h)
{
    return (size_t)ctex_tex_pitch(w) * (size_t)h * sizeof(ctex_texel);
}

/* Texel (x, y). */
static inline ctex_texel *ctex_tex_at(const ctex_tex *t, int x, int y)
{
    return t->tx + (size_t)y * (size_t)t->pitch + (size_t)x;
}

/* Whether a texel holds a correction. */
static inline bool ctex_texel_valid(const ctex_texel *p)
{
    return p->q != CTEX_Q_EMPTY;
}

/* A texel's validity in texels (-INFINITY when empty). */
static inline float ctex_tex_v(const ctex_tex *t, const ctex_texel *p)
{
    return p->q == CTEX_Q_EMPTY ? -INFINITY : t->vbase + (float)p->q * (1.0f / (float)CTEX_VQ);
}

/* The fixed-point step of validity v (rounded; clamped to the oldest valid
 * step and the largest; -INFINITY gives CTEX_Q_EMPTY). */
static inline int16_t ctex_tex_q(const ctex_tex *t, float v)
{
    if (v == -INFINITY) return CTEX_Q_EMPTY;
    float q = rintf((v - t->vbase) * (float)CTEX_VQ);
    if (!(q > (float)CTEX_Q_OLDEST)) return CTEX_Q_OLDEST;   /* NaN too */
    if (q > (float)INT16_MAX) return INT16_MAX;
    return (int16_t)q;
}

/* A texel's correction. */
static inline vec3 ctex_texel_rgb(const ctex_texel *p)
{
    return v3(half_to_float(p->c[0]), half_to_float(p->c[1]), half_to_float(p->c[2]));
}

/* A texel's correction in f[0..2] (f[3]: junk), all four lanes converted
 * at once. */
static inline void ctex_texel_rgbx(const ctex_texel *p, float f[4])
{
    uint16_t h[4];
    memcpy(h, p, sizeof h);
    half4_to_float(h, f);
}

/* Sets a texel: correction c (each channel clamped to the half range), validity v. */
static inline void ctex_texel_set(const ctex_tex *t, ctex_texel *p, vec3 c, float v)
{
    p->c[0] = half_from_float(fminf(fmaxf(c.x, -HALF_MAX), HALF_MAX));
    p->c[1] = half_from_float(fminf(fmaxf(c.y, -HALF_MAX), HALF_MAX));
    p->c[2] = half_from_float(fminf(fmaxf(c.z, -HALF_MAX), HALF_MAX));
    p->q = ctex_tex_q(t, v);
}

/* Empties a texel. */
static inline void ctex_texel_clear(ctex_texel *p)
{
    *p = (ctex_texel){{0, 0, 0}, CTEX_Q_EMPTY};
}

/* Moves vbase to vmax, shifting every validity step (older ones clamp to
 * CTEX_Q_OLDEST); a no-op when vbase is vmax. Called where vmax rises past
 * the fixed-point window. */
void ctex_tex_rebase(ctex_tex *t);

/* Rebases when v_max has left the window [vbase, vbase + 512 texels] (aging
 * raised it, or a caller set it directly). */
static inline void ctex_tex_keep_base(ctex_tex *t)
{
    if (t->vmax - t->vbase > (float)(CTEX_Q_REBASE / CTEX_VQ) || t->vmax < t->vbase) ctex_tex_rebase(t);
}

/* Allocates w x h empty texels (validity -inf, correction 0), vmax = 0,
 * all unsent. */
int ctex_tex_init(ctex_tex *t, int w, int h, ct_error *err);

/* Frees the texels and the tile map. */
void ctex_tex_release(ctex_tex *t);

/* Splats value at texel (ci, cj) with the texture's v_max (§3.4): the centre
 * texel is always overwritten; ring k (Chebyshev distance k) overwrites texels
 * whose validity is below v_max - k, and blends texels within `blend` of it;
 * stops after the first ring that overwrote nothing, or after ring max_r
 * (0 = no limit). Returns the splat radius (last overwriting ring) and marks
 * the texels it visited unsent (ctex_dirty_mark). */
int ctex_tex_splat(ctex_tex *t, int ci, int cj, vec3 value, float blend, int max_r);

/* Moves the texels [x0, x1] x [y0, y1] (inclusive, inside the texture) by
 * w towards value (refinement: a further sample of a pixel, written where
 * the display reads that pixel: each texel a running mean in which its
 * value before counts as 1 / w - 1 samples; an empty texel takes value),
 * at least as valid as a new sample's centre, and marks them unsent,
 * counting one sample in texel row cy. No rings: the Voronoi cells around
 * keep their owners. In half precision a move under half a unit in the
 * last place rounds away: at --refine-max's 256th sample of a diffuse
 * pixel, a sample within about 13 % of the texel's value (its mean's
 * standard error is then a few per cent); its larger deviations still
 * move it. */
void ctex_tex_refine(ctex_tex *t, int x0, int y0, int x1, int y1, int cy, vec3 value, float w);

/* Anisotropic splats: ex in (CTEX_ANISO_ISO, 1 / CTEX_ANISO_ISO) splats
 * square rings; ex is clamped to [1 / CTEX_ANISO_MAX, CTEX_ANISO_MAX]. */
#define CTEX_ANISO_ISO 0.8f
#define CTEX_ANISO_MAX 4.0f

/* The ex ctex_tex_splat_aniso uses for ex: 1 near 1 (square rings) and for
 * anything but a positive finite number, else ex clamped. */
static inline float ctex_aniso_ex(float ex)
{
    if (!(ex > 0.0f && ex < INFINITY) || (ex > CTEX_ANISO_ISO && ex < 1.0f / CTEX_ANISO_ISO)) return 1.0f;
    return ex < 1.0f / CTEX_ANISO_MAX ? 1.0f / CTEX_ANISO_MAX : (ex > CTEX_ANISO_MAX ? CTEX_ANISO_MAX : ex);
}

/* Half-extents of ring k of an anisotropic splat (ex from ctex_aniso_ex):
 * round(k ex) x round(k / ex). */
static inline void ctex_aniso_ring(float ex, int k, int *xk, int *yk)
{
    *xk = (int)((float)k * ex + 0.5f);
    *yk = (int)((float)k / ex + 0.5f);
}

/* ctex_tex_splat with distances measured on screen rather than in texels
 * (docs/textures.md, "Anisotropic splats"): a texel offset (dx, dy) lies
 * max(|dx| / ex, |dy| * ex) rings out, where ex = sqrt(s_y / s_x) for a
 * texel s_x by s_y pixels on screen. Ring k then covers the texels of the
 * ctex_aniso_ring rectangle outside ring k - 1's, about as many as a square
 * ring of k holds; validities, radii and max_r count rings as before. ex
 * near 1 (ctex_aniso_ex) splats square rings (ctex_tex_splat). */
int ctex_tex_splat_aniso(ctex_tex *t, int ci, int cj, vec3 value, float blend, int max_r, float ex);

/* A late sample's splat (traced from an eye the camera has left,
 * ctex_insert_late_par): ctex_tex_splat_aniso as if the sample had gone in
 * when it was traced and aged since, its centre at v_max - age and ring k
 * at v_max - age - k; it takes the centre only where that texel is not
 * more valid, so it fills where the texture has nothing as fresh and never
 * covers a newer sample. -1 when it lost its centre (nothing written),
 * else the splat radius. age 0: ctex_tex_splat_aniso. */
int ctex_tex_splat_late(ctex_tex *t, int ci, int cj, vec3 value, float blend, int max_r, float ex, float age);

/* The value a sample of correction `value` landing on texel (ci, cj) splats
 * (docs/textures.md, "Mixing"): the texel's correction moved by the
 * fraction `mix` towards value when the texel holds one whose validity is
 * at most `radius` texels below v_max (its sample is that near and the
 * texture has not aged past it since); value itself otherwise, and always
 * for mix >= 1. Single samples are noisy estimates; mixing neighbours
 * averages the noise out where the correction is smooth. ctex_tex_mix_aged:
 * for a late sample aged by `age` texels (ctex_tex_splat_late), whose
 * validity is v_max - age: the texel's distance is measured from there. */
static inline vec3 ctex_tex_mix_aged(const ctex_tex *t, int ci, int cj, vec3 value, float mix, float radius,
                                     float age)
{
    if (!(mix < 1.0f)) return value;
    const ctex_texel *x = ctex_tex_at(t, ci, cj);
    if (!ctex_texel_valid(x) || !(t->vmax - age - ctex_tex_v(t, x) <= radius)) return value;
    float o[4];
    ctex_texel_rgbx(x, o);
    return v3(o[0] + mix * (value.x - o[0]), o[1] + mix * (value.y - o[1]), o[2] + mix * (value.z - o[2]));
}

static inline vec3 ctex_tex_mix(const ctex_tex *t, int ci, int cj, vec3 value, float mix, float radius)
{
    return ctex_tex_mix_aged(t, ci, cj, value, mix, radius, 0.0f);
}

/* Bilinear correction at texture position (u, v), clamp-to-edge (GL_LINEAR). */
static inline vec3 ctex_tex_sample(const ctex_tex *t, float u, float v)
{
    float x = u * (float)t->w - 0.5f, y = v * (float)t->h - 0.5f;
    float fx0 = floorf(x), fy0 = floorf(y);
    float fx = x - fx0, fy = y - fy0;
    int x0 = (int)fx0, y0 = (int)fy0, x1 = x0 + 1, y1 = y0 + 1;
    int wm = t->w - 1, hm = t->h - 1;
    x0 = x0 < 0 ? 0 : (x0 > wm ? wm : x0);
    x1 = x1 < 0 ? 0 : (x1 > wm ? wm : x1);
    y0 = y0 < 0 ? 0 : (y0 > hm ? hm : y0);
    y1 = y1 < 0 ? 0 : (y1 > hm ? hm : y1);
    float a[4], b[4], c[4], d[4];
    ctex_texel_rgbx(ctex_tex_at(t, x0, y0), a);
    ctex_texel_rgbx(ctex_tex_at(t, x1, y0), b);
    ctex_texel_rgbx(ctex_tex_at(t, x0, y1), c);
    ctex_texel_rgbx(ctex_tex_at(t, x1, y1), d);
    float wa = (1.0f - fx) * (1.0f - fy), wb = fx * (1.0f - fy), wc = (1.0f - fx) * fy, wd = fx * fy;
    return v3(wa * a[0] + wb * b[0] + wc * c[0] + wd * d[0],
              wa * a[1] + wb * b[1] + wc * c[1] + wd * d[1],
              wa * a[2] + wb * b[2] + wc * c[2] + wd * d[2]);
}

/* Texture position of world point p through the projection; false when p is
 * behind a camera-local projection's eye. */
static inline bool ctex_tex_project(const ctex_tex *t, vec3 p, float *u, float *v)
{
    vec4 q = m4_point4(&t->m, p);
    if (!(q.w > 0.0f)) return false;
    float iw = 1.0f / q.w;
    *u = q.x * iw;
    *v = q.y * iw;
    return true;
}

/* Whether texture position (u, v) lies on texture t, with half a texel of
 * slack at the borders (false for NaN). */
static inline bool ctex_tex_covers(const ctex_tex *t, float u, float v)
{
    float mu = 0.5f / (float)t->w, mv = 0.5f / (float)t->h;
    return u >= -mu && v >= -mv && u <= 1.0f + mu && v <= 1.0f + mv;
}

/* World point of texture position (u, v): on the node's mid-plane for an
 * object-local texture, on the plane at ref_depth for a camera-local one. */
vec3 ctex_tex_unproject(const ctex_tex *t, float u, float v);

/* §3.5: raises v_max by offset (texels). */
static inline void ctex_tex_age(ctex_tex *t, float offset)
{
    if (offset > 0.0f) t->vmax += offset;
    ctex_tex_keep_base(t);
}

/* §3.6: changes the resolution to nw x nh: box filter (area average of valid
 * texels) when shrinking, bilinear when growing; validities are rescaled to
 * the new texel size relative to v_max. An exact resize
 * (wire_tex_resize_exact: the display follows it) marks unsent the tiles whose texels were computed
 * from unsent ones (ctex_dirty_rescale), any other the whole texture. */
int ctex_tex_resize(ctex_tex *t, int nw, int nh, ct_error *err);

/* The same with an exact doubling's or halving's rows spread over pool's
 * threads (NULL: the caller's alone); the same texels either way. */
int ctex_tex_resize_on(ctex_tex *t, int nw, int nh, struct ct_pool *pool, ct_error *err);

/* Fills dst's texels from the sources: each texel centre is unprojected to a
 * world point, projected into every source, and takes the bilinear value of
 * the source whose nearest texel is most valid (relative to its v_max), with
 * that relative validity minus `penalty`. Texels no source covers stay
 * empty. dst's texels must be allocated; it becomes unsent. */
void ctex_tex_resample(ctex_tex *dst, const ctex_tex *const *src, int nsrc, float penalty);

/* Mean correction over the valid texels (tests, stats); 0 when none. */
vec3 ctex_tex_mean(const ctex_tex *t, uint32_t *nvalid);

#endif
