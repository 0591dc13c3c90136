/* Texel-level tests of the corrective textures (master/ctex_tex.h):
 * the discrete Voronoi property of ring splatting (§3.4, Fig. 3), aging
 * (§3.5) and resolution changes (§3.6). Over 600 lines: one module's
 * tests, most of them exhaustive checks against a brute-force reference. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/pool.h"
#include "common/rng.h"
#include "master/ctex_tex.h"

/* Texel (x, y) of t (rows are ctex_tex_pitch(w) texels apart). */
/* The texels [x0, x1) x [y0, y1) of a splat are marked unsent, by whole
 * tiles (ctex_dirty.h): the marked box is that rectangle widened to tile
 * borders, clipped to the texture. */
static void expect_unsent(const ctex_tex *t, int x0, int y0, int x1, int y1)
{
    int bx0, by0, bx1, by1;
    cr_assert(ctex_dirty_bounds(&t->d, t->w, t->h, &bx0, &by0, &bx1, &by1), "nothing marked");
    int ex1 = (x1 + CTEX_TILE - 1) / CTEX_TILE * CTEX_TILE, ey1 = (y1 + CTEX_TILE - 1) / CTEX_TILE * CTEX_TILE;
    cr_assert_eq(bx0, x0 / CTEX_TILE * CTEX_TILE);
    cr_assert_eq(by0, y0 / CTEX_TILE * CTEX_TILE);
    cr_assert_eq(bx1, ex1 > t->w ? t->w : ex1);
    cr_assert_eq(by1, ey1 > t->h ? t->h : ey1);
}

static ctex_texel *at(const ctex_tex *t, int x, int y)
{
    return ctex_tex_at(t, x, y);
}

/* The correction (red, green, blue) and the validity of texel (x, y). */
static float R(const ctex_tex *t, int x, int y) { return ctex_texel_rgb(at(t, x, y)).x; }
static float G(const ctex_tex *t, int x, int y) { return ctex_texel_rgb(at(t, x, y)).y; }
static float B(const ctex_tex *t, int x, int y) { return ctex_texel_rgb(at(t, x, y)).z; }
static float V(const ctex_tex *t, int x, int y) { return ctex_tex_v(t, at(t, x, y)); }
/* What a doubling adds to every distance, in texels. */
#define SLACK ((float)CTEX_DBL_SLACK_Q / (float)CTEX_VQ)

/* Sets texel (x, y): red only (green, blue 0), validity v. */
static void set_rv(ctex_tex *t, int x, int y, float r, float v)
{
    ctex_texel_set(t, at(t, x, y), v3(r, 0.0f, 0.0f), v);
}

/* Copies src's texels into dst (same size). */
static void copy_texels(ctex_tex *dst, const ctex_tex *src)
{
    memcpy(dst->tx, src->tx, (size_t)src->pitch * (size_t)src->h * sizeof *src->tx);
}

static int cheb(int ax, int ay, int bx, int by)
{
    int dx = abs(ax - bx), dy = abs(ay - by);
    return dx > dy ? dx : dy;
}

/* A random texel of a W x H texture not used before; marks it used. */
static void free_texel(ct_rng *r, uint8_t *used, int W, int H, int *x, int *y)
{
    do {
        *x = (int)rng_below(r, (uint32_t)W);
        *y = (int)rng_below(r, (uint32_t)H);
    } while (used[*y * W + *x]);
    used[*y * W + *x] = 1;
}

/* Splats n samples at distinct random texels (value = index) with blending
 * off and checks that every texel holds its nearest sample in the
 * Chebyshev metric, ties going to the earliest sample. */
static void voronoi_case(int W, int H, int n, uint64_t seed)
{
    ctex_tex t = {0};
    ct_error err;
    cr_assert_eq(ctex_tex_init(&t, W, H, &err), 0);
    int *sx = malloc((size_t)n * sizeof *sx), *sy = malloc((size_t)n * sizeof *sy);
    uint8_t *used = calloc((size_t)W * (size_t)H, 1);
    ct_rng r = rng_make(seed, 1, 2, 3);
    for (int k = 0; k < n; k++) {
        free_texel(&r, used, W, H, &sx[k], &sy[k]);
        ctex_tex_splat(&t, sx[k], sy[k], v3((float)k, (float)-k, 0.5f), 0.0f, 0);
    }
    int ties = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            int best = -1, bd = 1 << 30, nbest = 0;
            for (int k = 0; k < n; k++) {
                int d = cheb(x, y, sx[k], sy[k]);
                if (d < bd) { bd = d; best = k; nbest = 1; }
                else if (d == bd) nbest++;
            }
            ties += nbest > 1;
            /* (sample indices are integers below 2048: exact halves) */
            cr_assert_eq(R(&t, x, y), (float)best, "texel (%d,%d) holds sample %g, nearest is %d (d=%d)", x, y,
                         (double)R(&t, x, y), best, bd);
            cr_assert_eq(G(&t, x, y), (float)-best);
            cr_assert_eq(V(&t, x, y), -(float)bd, "texel (%d,%d) validity %g, expected %d", x, y,
                         (double)V(&t, x, y), -bd);
        }
    cr_assert_gt(ties, 0, "the case should contain ties to exercise the tie rule");
    free(sx); free(sy); free(used);
    ctex_tex_release(&t);
}

Test(ctex_tex, voronoi_20_samples) { voronoi_case(64, 48, 20, 7); }
Test(ctex_tex, voronoi_100_samples) { voronoi_case(64, 48, 100, 11); }
Test(ctex_tex, voronoi_dense) { voronoi_case(33, 17, 300, 3); }

/* The ring of texel offset (dx, dy) in an anisotropic splat (ex from
 * ctex_aniso_ex): the first k whose ctex_aniso_ring rectangle holds it. */
static int aniso_ring_of(float ex, int dx, int dy)
{
    dx = abs(dx);
    dy = abs(dy);
    for (int k = 0;; k++) {
        int xk, yk;
        ctex_aniso_ring(ex, k, &xk, &yk);
        if (dx <= xk && dy <= yk) return k;
    }
}

/* voronoi_case for ctex_tex_splat_aniso: every texel holds its nearest
 * sample in the screen metric of the rings, ties to the earliest. */
static void aniso_voronoi_case(int W, int H, int n, float ex, uint64_t seed)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, W, H, NULL), 0);
    int *sx = malloc((size_t)n * sizeof *sx), *sy = malloc((size_t)n * sizeof *sy);
    uint8_t *used = calloc((size_t)W * (size_t)H, 1);
    ct_rng r = rng_make(seed, 4, 5, 6);
    float e = ctex_aniso_ex(ex);
    cr_assert_neq(e, 1.0f, "ex %g should splat anisotropic rings", (double)ex);
    for (int k = 0; k < n; k++) {
        free_texel(&r, used, W, H, &sx[k], &sy[k]);
        ctex_tex_splat_aniso(&t, sx[k], sy[k], v3((float)k, 0.0f, 0.0f), 0.0f, 0, ex);
    }
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            int best = -1, bd = 1 << 30;
            for (int k = 0; k < n; k++) {
                int d = aniso_ring_of(e, x - sx[k], y - sy[k]);
                if (d < bd) { bd = d; best = k; }
            }
            int got = (int)R(&t, x, y);
            int dg = aniso_ring_of(e, x - sx[got], y - sy[got]);
            cr_assert_eq(V(&t, x, y), -(float)dg, "validity is the held sample's ring");
            cr_assert_eq(got, best, "ex %g: texel (%d,%d) holds sample %d at (%d,%d), ring %d; nearest is %d at (%d,%d), ring %d",
                         (double)ex, x, y, got, sx[got], sy[got], dg, best, sx[best], sy[best], bd);
        }
    free(sx); free(sy); free(used);
    ctex_tex_release(&t);
}

/* Texels seen 4 times wider than high on screen (ex = 0.5) take rings half
 * as wide and twice as high, and so on; near the texture's borders rings
 * wholly outside along one axis still grow along the other. */
Test(ctex_tex, anisotropic_voronoi)
{
    const float exs[] = {0.5f, 0.7f, 1.6f, 3.0f, 0.25f, 100.0f};
    for (size_t i = 0; i < sizeof exs / sizeof exs[0]; i++) {
        aniso_voronoi_case(64, 48, 40, exs[i], 20 + i);
        aniso_voronoi_case(64, 48, 300, exs[i], 40 + i);
        aniso_voronoi_case(9, 70, 12, exs[i], 30 + i);
        aniso_voronoi_case(70, 5, 25, exs[i], 50 + i);
    }
}

/* A lone sample in an empty texture: ring k of ex = 0.5 reaches k / 2
 * texels across and 2 k along; the dirty rectangle is the texture. */
Test(ctex_tex, anisotropic_ring_shape)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 32, 32, NULL), 0);
    ctex_dirty_clear_all(&t.d);
    int r = ctex_tex_splat_aniso(&t, 16, 16, v3(1.0f, 0.0f, 0.0f), 0.0f, 0, 0.5f);
    cr_assert_eq(r, 31, "the splat reaches the far border (16 texels across at ring 31: round(15.5))");
    cr_assert_eq(V(&t, 16, 16 + 8), -4.0f);   /* 8 texels along: ring 4 */
    cr_assert_eq(V(&t, 16 + 8, 16), -15.0f);  /* 8 texels across: ring 15 (round(7.5)) */
    cr_assert_eq(V(&t, 16 + 1, 16), -1.0f);   /* round(0.5) = 1 */
    expect_unsent(&t, 0, 0, 32, 32);
    ctex_tex_release(&t);
}

/* ex near 1, or no number, splats square rings, bit for bit. */
Test(ctex_tex, nearly_isotropic_splats_square_rings)
{
    const float exs[] = {1.0f, 0.85f, 1.2f, NAN, INFINITY, 0.0f, -2.0f};
    for (size_t i = 0; i < sizeof exs / sizeof exs[0]; i++) {
        ctex_tex a = {0}, b = {0};
        cr_assert_eq(ctex_tex_init(&a, 33, 17, NULL), 0);
        cr_assert_eq(ctex_tex_init(&b, 33, 17, NULL), 0);
        ct_rng r = rng_make(7, i, 0, 0);
        for (int n = 0; n < 60; n++) {
            int x = (int)rng_below(&r, 33), y = (int)rng_below(&r, 17);
            vec3 v = v3(rng_float(&r), 0.0f, 0.0f);
            cr_assert_eq(ctex_tex_splat_aniso(&a, x, y, v, 1.0f, 0, exs[i]), ctex_tex_splat(&b, x, y, v, 1.0f, 0));
        }
        cr_assert_eq(memcmp(a.tx, b.tx, (size_t)a.pitch * 17 * sizeof *a.tx), 0, "ex %g", (double)exs[i]);
        ctex_tex_release(&a);
        ctex_tex_release(&b);
    }
}

Test(ctex_tex, splat_radius_and_dirty_rect)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 32, 32, NULL), 0);
    ctex_dirty_clear_all(&t.d);
    int r = ctex_tex_splat(&t, 5, 5, v3(1, 1, 1), 0.0f, 0);
    cr_assert_eq(r, 26, "first sample floods the texture: radius %d", r);
    expect_unsent(&t, 0, 0, 32, 32);
    ctex_dirty_clear_all(&t.d);
    /* a second sample 8 texels away: its radius is the farthest texel it
     * takes over (strictly closer to it than to the first) */
    r = ctex_tex_splat(&t, 13, 5, v3(2, 2, 2), 0.0f, 0);
    int expect = 0;
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 32; x++)
            if (cheb(x, y, 13, 5) < cheb(x, y, 5, 5) && cheb(x, y, 13, 5) > expect) expect = cheb(x, y, 13, 5);
    cr_assert_eq(r, expect, "radius %d, expected %d", r, expect);
    int e = r + 1;
    expect_unsent(&t, 13 - e < 0 ? 0 : 13 - e, 5 - e < 0 ? 0 : 5 - e, 13 + e + 1 > 32 ? 32 : 13 + e + 1,
                  5 + e + 1 > 32 ? 32 : 5 + e + 1);
    cr_assert_eq(R(&t, 9, 5), 1.0f, "equidistant texel stays with the older sample");
    cr_assert_eq(R(&t, 10, 5), 2.0f);
    ctex_tex_release(&t);
}

Test(ctex_tex, blending_is_between_neighbours)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 32, 8, NULL), 0);
    ctex_tex_splat(&t, 4, 4, v3(0, 0, 0), 1.0f, 0);
    ctex_tex_splat(&t, 12, 4, v3(1, 1, 1), 1.0f, 0);
    /* the tie at x = 8 is blended half-half, interior texels are not */
    cr_assert_float_eq(R(&t, 8, 4), 0.5f, 1e-6);
    cr_assert_eq(R(&t, 6, 4), 0.0f);
    cr_assert_eq(R(&t, 10, 4), 1.0f);
    for (int i = 0; i < 32 * 8; i++) cr_assert(R(&t, i % 32, i / 32) >= 0.0f && R(&t, i % 32, i / 32) <= 1.0f);
    ctex_tex_release(&t);
}

Test(ctex_tex, newer_sample_wins_after_aging)
{
    const int W = 48, H = 16;
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, W, H, NULL), 0);
    ctex_tex_splat(&t, 10, 8, v3(1, 0, 0), 0.0f, 0);
    ctex_tex_splat(&t, 40, 8, v3(3, 0, 0), 0.0f, 0);
    const float age = 5.0f;
    ctex_tex_age(&t, age);
    cr_assert_eq(t.vmax, age);
    ctex_tex_splat(&t, 25, 8, v3(2, 0, 0), 0.0f, 0);
    int won = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float old_v = -(float)(cheb(x, y, 10, 8) < cheb(x, y, 40, 8) ? cheb(x, y, 10, 8) : cheb(x, y, 40, 8));
            float old_val = cheb(x, y, 10, 8) <= cheb(x, y, 40, 8) ? 1.0f : 3.0f;
            float new_v = age - (float)cheb(x, y, 25, 8);
            float expect = new_v > old_v ? 2.0f : old_val;
            won += new_v > old_v;
            cr_assert_eq(R(&t, x, y), expect, "texel (%d,%d)", x, y);
        }
    /* the aged sample conquers more than its distance-only share (texels
     * strictly closer to it than to 10 or 40: |x-25| < 7.5) */
    cr_assert_gt(won, 15 * H, "new sample owns %d texels", won);
    ctex_tex_release(&t);
}

/* A late sample aged by `age` texels (ctex_tex_splat_late) splats as if it
 * had gone in `age` texels of aging ago: it takes the texels whose
 * validity is below v_max - age - k (empty ones, and those far from every
 * fresher sample), never a fresh sample's own; on a centre texel fresher
 * than it, it writes nothing. Age 0 is a new sample's splat. */
Test(ctex_tex, late_sample_fills_gaps_never_covers_fresher)
{
    const int W = 48, H = 16;
    ctex_tex t = {0}, u = {0};
    cr_assert_eq(ctex_tex_init(&t, W, H, NULL), 0);
    cr_assert_eq(ctex_tex_init(&u, W, H, NULL), 0);
    ctex_tex_splat(&t, 10, 8, v3(1, 0, 0), 0.0f, 0);
    const float age = 6.0f;
    int r = ctex_tex_splat_late(&t, 30, 8, v3(2, 0, 0), 0.0f, 0, 1.0f, age);
    cr_assert_geq(r, 0, "the late sample lost its centre");
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            /* the fresh sample's validity -d0, the late one's -age - d1 */
            float v0 = -(float)cheb(x, y, 10, 8), v1 = -age - (float)cheb(x, y, 30, 8);
            cr_assert_eq(R(&t, x, y), (v1 > v0 || (x == 30 && y == 8)) ? 2.0f : 1.0f, "texel (%d,%d)", x, y);
        }
    /* it keeps fewer texels than a new sample at 30 would (their tie would
     * be at 20): the fresh one's share grew by age / 2 texels */
    cr_assert_eq(R(&t, 24, 8), 2.0f);
    cr_assert_eq(R(&t, 23, 8), 1.0f, "texel 23: 7 + 6 of age from the late sample, 13 from the fresh one (a tie)");
    /* on the fresh sample's own texel it writes nothing */
    cr_assert_eq(ctex_tex_splat_late(&t, 11, 8, v3(5, 0, 0), 0.0f, 0, 1.0f, age), -1);
    cr_assert_eq(R(&t, 11, 8), 1.0f);
    cr_assert_eq(R(&t, 10, 8), 1.0f);
    /* age 0: the same as a new sample's splat, texel for texel */
    ctex_tex_splat(&u, 10, 8, v3(1, 0, 0), 0.0f, 0);
    ctex_tex_splat(&u, 30, 8, v3(2, 0, 0), 0.0f, 0);
    ctex_tex w = {0};
    cr_assert_eq(ctex_tex_init(&w, W, H, NULL), 0);
    ctex_tex_splat(&w, 10, 8, v3(1, 0, 0), 0.0f, 0);
    ctex_tex_splat_late(&w, 30, 8, v3(2, 0, 0), 0.0f, 0, 1.0f, 0.0f);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            cr_assert_eq(R(&w, x, y), R(&u, x, y), "texel (%d,%d)", x, y);
            cr_assert_eq(V(&w, x, y), V(&u, x, y), "texel (%d,%d)", x, y);
        }
    ctex_tex_release(&t);
    ctex_tex_release(&u);
    ctex_tex_release(&w);
}

/* A late sample mixes (ctex_tex_mix_aged) only with a texel about as old as
 * it: the radius counts from its own validity, v_max - age. */
Test(ctex_tex, late_sample_mixes_from_its_own_validity)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 48, 8, NULL), 0);
    ctex_tex_splat(&t, 4, 4, v3(1.0f, 1.0f, 1.0f), 0.0f, 0);   /* floods the texture */
    vec3 b = v3(3.0f, 3.0f, 3.0f);
    /* 30 texels from the sample: too far for a new one at radius 16, near
     * enough for one aged by 20 */
    cr_assert_eq(ctex_tex_mix(&t, 34, 4, b, 0.5f, 16.0f).x, 3.0f);
    cr_assert_float_eq(ctex_tex_mix_aged(&t, 34, 4, b, 0.5f, 16.0f, 20.0f).x, 2.0f, 1e-6);
    cr_assert_eq(ctex_tex_mix_aged(&t, 44, 4, b, 0.5f, 16.0f, 20.0f).x, 3.0f, "40 texels: 20 past its validity");
    ctex_tex_release(&t);
}

/* Noise-aware splatting: a sample moves the correction it lands on by
 * `mix` towards its own value, but only a fresh correction of a sample
 * within `radius` texels (validity), never an empty texel, and not at all
 * for mix 1. */
Test(ctex_tex, mix_only_with_near_fresh_corrections)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 48, 8, NULL), 0);
    vec3 b = v3(3.0f, 2.0f, 1.0f);
    vec3 v = ctex_tex_mix(&t, 4, 4, b, 0.5f, 16.0f);
    cr_assert(v.x == b.x && v.y == b.y && v.z == b.z, "an empty texel gives the sample's own value");
    ctex_tex_splat(&t, 4, 4, v3(1.0f, 1.0f, 1.0f), 0.0f, 0);   /* floods the texture */
    v = ctex_tex_mix(&t, 4, 4, b, 0.5f, 16.0f);
    cr_assert_float_eq(v.x, 2.0f, 1e-6, "halfway between 1 and 3: %g", (double)v.x);
    cr_assert_float_eq(v.y, 1.5f, 1e-6);
    cr_assert_float_eq(v.z, 1.0f, 1e-6);
    v = ctex_tex_mix(&t, 20, 4, b, 0.25f, 16.0f);
    cr_assert_float_eq(v.x, 1.5f, 1e-6, "16 texels from the sample: mixed by 1/4");
    v = ctex_tex_mix(&t, 21, 4, b, 0.25f, 16.0f);
    cr_assert_eq(v.x, b.x, "17 texels from the sample: too far to mix");
    v = ctex_tex_mix(&t, 4, 4, b, 1.0f, 16.0f);
    cr_assert_eq(v.x, b.x, "mix 1: off");
    /* aging past the radius makes the correction stale */
    ctex_tex_age(&t, 12.0f);
    v = ctex_tex_mix(&t, 8, 4, b, 0.5f, 16.0f);
    cr_assert_float_eq(v.x, 2.0f, 1e-6, "4 texels + 12 of aging: still mixed");
    v = ctex_tex_mix(&t, 9, 4, b, 0.5f, 16.0f);
    cr_assert_eq(v.x, b.x, "5 texels + 12 of aging: stale");
    ctex_tex_release(&t);
}

static void fill_random(ctex_tex *t, uint64_t seed)
{
    ct_rng r = rng_make(seed, 0, 0, 0);
    for (int i = 0; i < t->w * t->h; i++) {
        /* one draw per statement (argument order is unspecified) */
        float red = rng_float(&r) * 2.0f - 1.0f;
        float green = rng_float(&r);
        float blue = -rng_float(&r);
        float v = -rng_float(&r) * 3.0f;
        ctex_texel_set(t, at(t, i % t->w, i / t->w), v3(red, green, blue), v);
    }
}

Test(ctex_tex, double_then_halve_keeps_mean)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 16, 12, NULL), 0);
    fill_random(&t, 5);
    vec3 m0 = ctex_tex_mean(&t, NULL);
    cr_assert_eq(ctex_tex_resize(&t, 32, 24, NULL), 0);
    vec3 m1 = ctex_tex_mean(&t, NULL);
    cr_assert_eq(ctex_tex_resize(&t, 16, 12, NULL), 0);
    vec3 m2 = ctex_tex_mean(&t, NULL);
    /* texels are halves: each new texel rounds to 2^-11 relative (values
     * within [-1, 1]: at most 2.5e-4), the means of hundreds of them far less */
    cr_assert_float_eq(m1.x, m0.x, 1e-4);
    cr_assert_float_eq(m1.y, m0.y, 1e-4);
    cr_assert_float_eq(m2.x, m0.x, 1e-4);
    cr_assert_float_eq(m2.y, m0.y, 1e-4);
    cr_assert_float_eq(m2.z, m0.z, 1e-4);
    /* halving an odd size keeps the mean too (area-weighted box) */
    cr_assert_eq(ctex_tex_resize(&t, 7, 5, NULL), 0);
    vec3 m3 = ctex_tex_mean(&t, NULL);
    cr_assert_float_eq(m3.x, m0.x, 2e-4);
    ctex_tex_release(&t);
}

Test(ctex_tex, halving_averages_boxes_and_rescales_validity)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 4, 2, NULL), 0);
    float vals[8] = {1, 3, 5, 7, 2, 4, 6, 8};
    for (int i = 0; i < 8; i++) set_rv(&t, i % 4, i / 4, vals[i], -4.0f);
    ctex_texel_clear(at(&t, 2, 0));   /* an empty texel does not count */
    cr_assert_eq(ctex_tex_resize(&t, 2, 1, NULL), 0);
    cr_assert_float_eq(R(&t, 0, 0), 2.5f, 1e-6);
    /* 7: the half nearest to 21/3 */
    cr_assert_eq(R(&t, 1, 0), half_to_float(half_from_float((7.0f + 6.0f + 8.0f) / 3.0f)));
    cr_assert_float_eq(V(&t, 0, 0), -2.0f, 1e-6, "distances halve with the texel size");
    ctex_tex_release(&t);
}

Test(ctex_tex, empty_texture_stays_empty_on_resize)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 8, 8, NULL), 0);
    cr_assert_eq(ctex_tex_resize(&t, 16, 16, NULL), 0);
    uint32_t nv;
    ctex_tex_mean(&t, &nv);
    cr_assert_eq(nv, 0);
    cr_assert_eq(ctex_tex_resize(&t, 4, 4, NULL), 0);
    ctex_tex_mean(&t, &nv);
    cr_assert_eq(nv, 0);
    ct_error err;
    cr_assert_eq(ctex_tex_resize(&t, 0, 4, &err), CT_EINVAL);
    ctex_tex_release(&t);
}

Test(ctex_tex, doubling_is_bilinear_at_new_centres)
{
    ctex_tex t = {0}, old = {0};
    cr_assert_eq(ctex_tex_init(&t, 9, 6, NULL), 0);
    cr_assert_eq(ctex_tex_init(&old, 9, 6, NULL), 0);
    fill_random(&t, 9);
    copy_texels(&old, &t);
    cr_assert_eq(ctex_tex_resize(&t, 18, 12, NULL), 0);
    for (int j = 0; j < 12; j++)
        for (int i = 0; i < 18; i++) {
            vec3 e = ctex_tex_sample(&old, ((float)i + 0.5f) / 18.0f, ((float)j + 0.5f) / 12.0f);
            /* the bilinear value rounded to a half (values within [-1, 1]) */
            cr_assert_float_eq(R(&t, i, j), e.x, 2.5e-4, "texel (%d,%d)", i, j);
            cr_assert_float_eq(G(&t, i, j), e.y, 2.5e-4);
            cr_assert_float_eq(B(&t, i, j), e.z, 2.5e-4);
            /* validity: the covering old texel's, distances doubled, plus
             * the doubling's slack */
            cr_assert_float_eq(V(&t, i, j), 2.0f * V(&old, i / 2, j / 2) - SLACK, 1e-5);
        }
    ctex_tex_release(&t);
    ctex_tex_release(&old);
}

Test(ctex_tex, splat_max_bounds_the_radius)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 64, 64, NULL), 0);
    ctex_dirty_clear_all(&t.d);
    int r = ctex_tex_splat(&t, 30, 20, v3(1, 1, 1), 1.0f, 5);
    cr_assert_eq(r, 5);
    for (int y = 0; y < 64; y++)
        for (int x = 0; x < 64; x++) {
            int inside = cheb(x, y, 30, 20) <= 5;
            cr_assert_eq(ctex_texel_valid(at(&t, x, y)), inside, "texel (%d,%d)", x, y);
        }
    expect_unsent(&t, 25, 15, 36, 26);
    ctex_tex_release(&t);
}

Test(ctex_tex, doubling_one_axis_and_odd_halving)
{
    ctex_tex t = {0}, old = {0};
    cr_assert_eq(ctex_tex_init(&t, 7, 5, NULL), 0);
    cr_assert_eq(ctex_tex_init(&old, 7, 5, NULL), 0);
    fill_random(&t, 13);
    copy_texels(&old, &t);
    cr_assert_eq(ctex_tex_resize(&t, 14, 5, NULL), 0);
    for (int j = 0; j < 5; j++)
        for (int i = 0; i < 14; i++) {
            vec3 e = ctex_tex_sample(&old, ((float)i + 0.5f) / 14.0f, ((float)j + 0.5f) / 5.0f);
            cr_assert_float_eq(R(&t, i, j), e.x, 2.5e-4, "texel (%d,%d)", i, j);
        }
    /* halving 7x5 -> 4x3: 2x2 blocks, the last column and row one texel wide */
    cr_assert_eq(ctex_tex_resize(&old, 4, 3, NULL), 0);
    ctex_tex ref = {0};
    cr_assert_eq(ctex_tex_init(&ref, 7, 5, NULL), 0);
    fill_random(&ref, 13);
    float e = (R(&ref, 6, 0) + R(&ref, 6, 1)) / 2.0f;   /* block (3, 0): column 6, rows 0-1 */
    cr_assert_eq(R(&old, 3, 0), half_to_float(half_from_float(e)));
    float e2 = R(&ref, 6, 4);                           /* block (3, 2): texel (6, 4) alone */
    cr_assert_eq(R(&old, 3, 2), e2);
    ctex_tex_release(&t);
    ctex_tex_release(&old);
    ctex_tex_release(&ref);
}

/* Doubling with empty texels scattered inside (the per-texel fallback next
 * to the four-channel path): each new texel is the bilinear weight (3/4,
 * 1/4 per axis, clamped) renormalized over the valid old texels, empty when
 * none is valid; its validity is the covering old texel's (or v_max - 1 when
 * that one is empty) with distances doubled, plus the slack. */
Test(ctex_tex, doubling_with_empty_texels)
{
    const int W = 11, H = 7;
    ctex_tex t = {0}, old = {0};
    cr_assert_eq(ctex_tex_init(&t, W, H, NULL), 0);
    cr_assert_eq(ctex_tex_init(&old, W, H, NULL), 0);
    fill_random(&t, 21);
    ct_rng r = rng_make(22, 0, 0, 0);
    for (int i = 0; i < W * H; i++)
        if (rng_float(&r) < 0.3f) {
            ctex_texel_clear(at(&t, i % W, i / W));
        }
    t.vmax = 1.5f;
    copy_texels(&old, &t);
    cr_assert_eq(ctex_tex_resize(&t, 2 * W, 2 * H, NULL), 0);
    int empty = 0, partial = 0;
    for (int j = 0; j < 2 * H; j++)
        for (int i = 0; i < 2 * W; i++) {
            int ox = i / 2, oy = j / 2;
            int nx = i % 2 ? (ox + 1 < W ? ox + 1 : ox) : (ox > 0 ? ox - 1 : 0);
            int ny = j % 2 ? (oy + 1 < H ? oy + 1 : oy) : (oy > 0 ? oy - 1 : 0);
            const ctex_texel *ps[4] = {at(&old, ox, oy), at(&old, nx, oy), at(&old, ox, ny), at(&old, nx, ny)};
            const float ws[4] = {0.5625f, 0.1875f, 0.1875f, 0.0625f};
            float sw = 0.0f, cr = 0.0f;
            int nvalid = 0;
            for (int k = 0; k < 4; k++)
                if (ctex_texel_valid(ps[k])) { sw += ws[k]; cr += ws[k] * ctex_texel_rgb(ps[k]).x; nvalid++; }
            const ctex_texel *q = at(&t, i, j);
            if (nvalid == 0) {
                cr_assert(!ctex_texel_valid(q), "texel (%d,%d) should stay empty", i, j);
                empty++;
                continue;
            }
            partial += nvalid < 4;
            cr_assert_float_eq(R(&t, i, j), cr / sw, 2.5e-4, "texel (%d,%d): %g, expected %g", i, j,
                               (double)R(&t, i, j), (double)(cr / sw));
            float v = ctex_texel_valid(ps[0]) ? V(&old, ox, oy) : t.vmax - 1.0f;
            /* validities are steps of 1/8 texel */
            cr_assert_float_eq(V(&t, i, j), t.vmax + (v - t.vmax) * 2.0f - SLACK, 0.0625f, "texel (%d,%d) validity", i,
                               j);
        }
    cr_assert_gt(partial, 0, "the case should have texels next to empty ones");
    cr_assert_gt(empty + partial, 0);
    ctex_tex_release(&t);
    ctex_tex_release(&old);
}

/* A doubling's distances are what the old texels claimed, scaled, plus a
 * slack: a sample that lands among the texels a doubling made of an older
 * sample's centre takes its ring 2, which the doubling put at that older
 * sample's distance 2. Without the slack the ring tied with them
 * everywhere, took nothing, and the splat stopped at ring 1: the older,
 * interpolated values stayed around every fresh sample. */
Test(ctex_tex, fresh_sample_spreads_through_doubled_texels)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 4, 4, NULL), 0);
    ctex_tex_splat(&t, 1, 1, v3(1, 1, 1), 1.0f, 0);   /* one sample covers the texture */
    cr_assert_eq(ctex_tex_resize(&t, 8, 8, NULL), 0);
    cr_assert_eq(V(&t, 2, 2), -SLACK, "a child of the old centre");
    cr_assert_eq(V(&t, 0, 4), -2.0f - SLACK, "a child of the old ring 1");
    /* the fresh sample in a child of the old centre */
    int r = ctex_tex_splat(&t, 2, 2, v3(3, 3, 3), 1.0f, 0);
    cr_assert_eq(r, 2, "splat radius %d, expected 2", r);
    for (int y = 0; y <= 4; y++)
        for (int x = 0; x <= 4; x++) {
            if (cheb(x, y, 2, 2) != 2) continue;
            cr_assert_eq(V(&t, x, y), -2.0f, "ring 2 texel (%d,%d): validity %g", x, y, (double)V(&t, x, y));
            cr_assert_gt(R(&t, x, y), 2.0f, "ring 2 texel (%d,%d) nearer the fresh sample's value: %g", x, y,
                         (double)R(&t, x, y));
        }
    cr_assert_eq(V(&t, 5, 5), -2.0f - SLACK, "ring 3 is nearer the older sample");
    ctex_tex_release(&t);
}

/* A texture large enough for the huge-page allocation (2 MiB and more)
 * splats, doubles and halves like a small one. */
Test(ctex_tex, large_texture_splats_and_resizes)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 600, 400, NULL), 0);   /* 3.7 MiB */
    ctex_tex_splat(&t, 100, 100, v3(1, 0, 0), 0.0f, 0);
    ctex_tex_splat(&t, 500, 300, v3(2, 0, 0), 0.0f, 0);
    cr_assert_eq(R(&t, 100, 100), 1.0f);
    cr_assert_eq(R(&t, 599, 399), 2.0f);
    cr_assert_eq(R(&t, 0, 0), 1.0f);
    cr_assert_eq(V(&t, 0, 0), -100.0f);
    vec3 m0 = ctex_tex_mean(&t, NULL);
    cr_assert_eq(ctex_tex_resize(&t, 1200, 800, NULL), 0);   /* 14.6 MiB */
    cr_assert_eq(V(&t, 0, 0), -200.0f - SLACK, "distances double (plus the slack)");
    cr_assert_eq(ctex_tex_resize(&t, 600, 400, NULL), 0);
    vec3 m2 = ctex_tex_mean(&t, NULL);
    cr_assert_float_eq(m2.x, m0.x, 1e-4);
    ctex_tex_release(&t);
}

/* Row pitch: whole 64-byte lines, an odd number of them, never less than w. */
Test(ctex_tex, row_pitch_is_an_odd_number_of_cache_lines)
{
    const int ws[] = {1, 3, 4, 5, 8, 16, 17, 100, 256, 1024, 2048, 4096};
    for (size_t i = 0; i < sizeof ws / sizeof ws[0]; i++) {
        int p = ctex_tex_pitch(ws[i]);
        cr_assert_geq(p, ws[i]);
        cr_assert_lt(p, ws[i] + 16, "w %d: pitch %d", ws[i], p);
        cr_assert_eq(p % 8, 0, "w %d: pitch %d is not whole lines", ws[i], p);
        cr_assert_eq((p / 8) % 2, 1, "w %d: pitch %d is an even number of lines", ws[i], p);
    }
    cr_assert_eq(sizeof(ctex_texel), 8, "eight texels a cache line");
    cr_assert_eq(ctex_tex_pitch(2048), 2056);
    cr_assert_eq(ctex_tex_bytes(2048, 10), (size_t)2056 * 10 * 8);
}

/* §3.4 written as plainly as possible, as the reference for the engine's
 * splat (ring 1 unclipped inside the texture, the rest ring by ring), in the
 * texel format (halves, validity steps of 1/CTEX_VQ texel): the centre takes
 * the value; ring k = 1, 2, ... (clipped, up to max_r) updates each texel by
 * its margin m = (v_max - k) - v: overwritten when m > 0 (blended when
 * m < blend, unless the texel was empty), blended when -blend < m <= 0; the
 * splat stops after the first ring without an overwritten texel. */
static int ref_splat(ctex_tex *t, int ci, int cj, vec3 val, float blend, int max_r)
{
    ctex_texel h;
    ctex_texel_set(t, &h, val, 0.0f);
    const vec3 hv = ctex_texel_rgb(&h);   /* the value as the texels hold it */
    const int qmax = ctex_tex_q(t, t->vmax);
    ctex_texel *c = at(t, ci, cj);
    int cq = c->q > qmax ? c->q : qmax;
    *c = h;
    c->q = (int16_t)cq;
    int r = 0;
    for (int k = 1; max_r <= 0 || k <= max_r; k++) {
        int inside = 0, changed = 0;
        const int vn = qmax - CTEX_VQ * k < CTEX_Q_OLDEST ? CTEX_Q_OLDEST : qmax - CTEX_VQ * k;
        for (int y = cj - k; y <= cj + k; y++)
            for (int x = ci - k; x <= ci + k; x++) {
                if (cheb(x, y, ci, cj) != k || x < 0 || y < 0 || x >= t->w || y >= t->h) continue;
                inside = 1;
                ctex_texel *p = at(t, x, y);
                float m = (float)(vn - p->q) / (float)CTEX_VQ;
                if (m > 0.0f && (m >= blend || !ctex_texel_valid(p))) {
                    memcpy(p->c, h.c, sizeof h.c);
                } else if (m > -blend) {
                    float w = 0.5f + 0.5f * m / blend;
                    vec3 o = ctex_texel_rgb(p);
                    p->c[0] = half_from_float(o.x + w * (hv.x - o.x));
                    p->c[1] = half_from_float(o.y + w * (hv.y - o.y));
                    p->c[2] = half_from_float(o.z + w * (hv.z - o.z));
                }
                if (m > 0.0f) {
                    p->q = (int16_t)vn;
                    changed = 1;
                }
            }
        if (!inside || !changed) break;
        r = k;
    }
    return r;
}

/* Random textures (random values, validities and empty texels, an aged
 * v_max so margins are fractional), random splats anywhere (borders and
 * corners included), blending on and off, with and without --splat-max:
 * the engine's splat and the reference give the same radius and the same
 * bits in every texel. */
Test(ctex_tex, splat_equals_plain_ring_reference)
{
    const int sizes[][2] = {{1, 1}, {2, 3}, {5, 4}, {33, 17}, {64, 48}};
    ct_rng r = rng_make(31, 0, 0, 0);
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        const int W = sizes[s][0], H = sizes[s][1];
        ctex_tex a = {0}, b = {0};
        cr_assert_eq(ctex_tex_init(&a, W, H, NULL), 0);
        cr_assert_eq(ctex_tex_init(&b, W, H, NULL), 0);
        fill_random(&a, 40 + s);
        for (int i = 0; i < W * H; i++)
            if (rng_float(&r) < 0.2f) ctex_texel_clear(at(&a, i % W, i / W));
        a.vmax = 0.75f;
        copy_texels(&b, &a);
        b.vmax = a.vmax;
        for (int n = 0; n < 300; n++) {
            int x = (int)rng_below(&r, (uint32_t)W), y = (int)rng_below(&r, (uint32_t)H);
            vec3 val = v3(rng_float(&r), -rng_float(&r), 2.0f * rng_float(&r));
            float blend = n % 3 == 0 ? 0.0f : (n % 3 == 1 ? 1.0f : 2.5f);
            int max_r = n % 4 == 0 ? 3 : 0;
            int ra = ctex_tex_splat(&a, x, y, val, blend, max_r);
            int rb = ref_splat(&b, x, y, val, blend, max_r);
            cr_assert_eq(ra, rb, "%dx%d splat %d at (%d,%d): radius %d, reference %d", W, H, n, x, y, ra, rb);
            if (n % 50 == 49) ctex_tex_age(&a, 0.4f), ctex_tex_age(&b, 0.4f);
        }
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++)
                cr_assert_eq(memcmp(at(&a, x, y), at(&b, x, y), sizeof(ctex_texel)), 0, "%dx%d: texel (%d,%d) differs",
                             W, H, x, y);
        ctex_tex_release(&a);
        ctex_tex_release(&b);
    }
}

/* §3.5 over a long walkthrough: v_max keeps rising, validities are steps
 * above a base that follows it. Within the window every validity keeps its
 * value across a rebase; far older ones clamp to the oldest step and still
 * lose to any new sample. */
Test(ctex_tex, validity_survives_rebasing)
{
    const int W = 40, H = 9;
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, W, H, NULL), 0);
    ctex_tex_splat(&t, 5, 4, v3(1, 0, 0), 0.0f, 0);
    ctex_tex_age(&t, 300.0f);
    ctex_tex_splat(&t, 30, 4, v3(2, 0, 0), 0.0f, 0);
    ctex_tex_age(&t, 300.25f);   /* past the window: a rebase */
    cr_assert_gt(t.vbase, 0.0f, "vbase follows v_max");
    cr_assert_eq(t.vmax, 600.25f);
    for (int x = 0; x < W; x++) {
        /* texels the second sample took: 300 - d; the rest kept 0 - d */
        int d2 = abs(x - 30), d1 = abs(x - 5);
        float expect = 300.0f - (float)d2 > -(float)d1 ? 300.0f - (float)d2 : -(float)d1;
        cr_assert_eq(V(&t, x, 4), expect, "x %d: validity %g, expected %g", x, (double)V(&t, x, 4), (double)expect);
    }
    /* a huge age: everything older than the window clamps... */
    ctex_tex_age(&t, 100000.0f);
    float oldest = V(&t, 0, 0);
    for (int x = 0; x < W; x++) cr_assert_eq(V(&t, x, 4), oldest, "x %d", x);
    cr_assert_lt(oldest, t.vmax - 4000.0f);
    /* ...and a new sample takes the texture again, nearest first */
    ctex_tex_splat(&t, 20, 4, v3(3, 0, 0), 0.0f, 0);
    for (int x = 0; x < W; x++) {
        cr_assert_eq(R(&t, x, 4), 3.0f, "x %d", x);
        cr_assert_eq(V(&t, x, 4), t.vmax - (float)abs(x - 20));
    }
    ctex_tex_release(&t);
}

/* Corrections beyond the half range are clamped to it, never infinite (the
 * display would draw inf, and the bilinear lookup would give NaN). */
Test(ctex_tex, huge_corrections_clamp_to_the_half_range)
{
    ctex_tex t = {0};
    cr_assert_eq(ctex_tex_init(&t, 4, 4, NULL), 0);
    ctex_tex_splat(&t, 1, 1, v3(1e9f, -1e9f, 70000.0f), 1.0f, 0);
    cr_assert_eq(R(&t, 1, 1), HALF_MAX);
    cr_assert_eq(G(&t, 1, 1), -HALF_MAX);
    cr_assert_eq(B(&t, 3, 3), HALF_MAX);
    vec3 s = ctex_tex_sample(&t, 0.4f, 0.6f);
    cr_assert(isfinite(s.x) && isfinite(s.y) && isfinite(s.z));
    ctex_tex_release(&t);
}

/* An exact doubling or halving split over a pool's threads by row bands
 * (ctex_tex_resize_on) writes the very texels of the serial pass: textures
 * large enough to be split (several bands), with empty texels among valid
 * ones and odd sizes (halving's last block one texel wide). */
Test(ctex_tex, resize_on_a_pool_matches_serial)
{
    ct_pool *pool = NULL;
    cr_assert_eq(pool_new(3, &pool, NULL), 0);
    const int sizes[3][2] = {{301, 263}, {256, 300}, {517, 129}};
    for (int s = 0; s < 3; s++) {
        const int W = sizes[s][0], H = sizes[s][1];
        for (int grow = 0; grow < 2; grow++) {
            ctex_tex a = {0}, b = {0};
            cr_assert_eq(ctex_tex_init(&a, W, H, NULL), 0);
            cr_assert_eq(ctex_tex_init(&b, W, H, NULL), 0);
            cr_assert_geq(H * a.pitch, 1 << 16, "too small to be split (RESIZE_PAR_TEXELS, ctex_tex.c)");
            fill_random(&a, 40 + (uint64_t)s);
            ct_rng r = rng_make(50 + (uint64_t)s, 0, 0, 0);
            for (int i = 0; i < W * H; i++)
                if (rng_float(&r) < 0.2f) ctex_texel_clear(at(&a, i % W, i / W));
            a.vmax = b.vmax = 2.25f;
            copy_texels(&b, &a);
            const int nw = grow ? 2 * W : (W + 1) / 2, nh = grow ? 2 * H : (H + 1) / 2;
            cr_assert_eq(ctex_tex_resize(&a, nw, nh, NULL), 0);
            cr_assert_eq(ctex_tex_resize_on(&b, nw, nh, pool, NULL), 0);
            for (int j = 0; j < nh; j++)
                cr_assert_eq(memcmp(at(&a, 0, j), at(&b, 0, j), (size_t)nw * sizeof(ctex_texel)), 0,
                             "%dx%d %s: row %d differs", W, H, grow ? "doubled" : "halved", j);
            ctex_tex_release(&a);
            ctex_tex_release(&b);
        }
    }
    pool_free(pool);
}
