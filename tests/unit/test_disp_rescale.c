/* The display's exact resizes (display/disp_rescale.h) against the
 * master's (master/ctex_tex.c): from the texels as TEX_PATCH carries them
 * (a valid zero as -0, an empty texel as +0), every new texel the display
 * computes has the master's validity and value, through chains of
 * doublings and halvings, odd sides and empty texels among valid ones; and
 * the master's tile marks after an exact resize (ctex_dirty_rescale) cover
 * every new texel computed from a marked one. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"
#include "display/disp_rescale.h"
#include "master/ctex_tex.h"
#include "proto/wire.h"

/* Random texels: a fifth empty, a tenth valid zeros (one channel or all),
 * the rest signed values over many magnitudes. */
static void fill(ctex_tex *t, uint64_t seed)
{
    ct_rng r = rng_make(seed, 1, 2, 3);
    t->vmax = 1.75f;
    for (int j = 0; j < t->h; j++)
        for (int i = 0; i < t->w; i++) {
            ctex_texel *p = ctex_tex_at(t, i, j);
            float u = rng_float(&r);
            if (u < 0.2f) {
                ctex_texel_clear(p);
                continue;
            }
            /* magnitudes 2^-12 .. 2^12 apart, so that sums round and their
             * order shows */
            vec3 c = v3((rng_float(&r) - 0.4f) * exp2f(24.0f * rng_float(&r) - 12.0f),
                        (rng_float(&r) - 0.5f) * exp2f(24.0f * rng_float(&r) - 12.0f),
                        rng_float(&r) * exp2f(24.0f * rng_float(&r) - 12.0f));
            if (u < 0.25f) c = v3(0.0f, 0.0f, 0.0f);
            else if (u < 0.3f) c.y = 0.0f;
            ctex_texel_set(t, p, c, t->vmax - 3.0f * rng_float(&r));
        }
}

/* The texels as TEX_PATCH sends them (master/dsync.c). */
static uint16_t *wire_copy(const ctex_tex *t)
{
    uint16_t *d = malloc((size_t)t->w * (size_t)t->h * 3 * sizeof *d);
    for (int j = 0; j < t->h; j++)
        for (int i = 0; i < t->w; i++) {
            const ctex_texel *p = ctex_tex_at(t, i, j);
            uint16_t *q = d + 3 * ((size_t)j * (size_t)t->w + (size_t)i);
            memcpy(q, p->c, 6);
            if (!ctex_texel_valid(p)) q[0] = q[1] = q[2] = 0;
            else if (!(q[0] | q[1] | q[2])) q[0] = 0x8000u;
        }
    return d;
}

/* The display's copy holds the master's texels: the same validity, the
 * same values (a zero's sign aside). */
static void expect_same(const ctex_tex *t, const uint16_t *d, const char *what)
{
    for (int j = 0; j < t->h; j++)
        for (int i = 0; i < t->w; i++) {
            const ctex_texel *p = ctex_tex_at(t, i, j);
            const uint16_t *q = d + 3 * ((size_t)j * (size_t)t->w + (size_t)i);
            bool dv = (q[0] | q[1] | q[2]) != 0;
            cr_assert_eq(dv, ctex_texel_valid(p), "%s: texel (%d, %d) of %dx%d: validity %d at the display", what,
                         i, j, t->w, t->h, dv);
            for (int k = 0; k < 3; k++) {
                uint16_t a = p->c[k], b = q[k];
                if (!(a & 0x7fffu) && !(b & 0x7fffu)) continue;
                cr_assert_eq(a, b, "%s: texel (%d, %d) of %dx%d channel %d: master 0x%04x, display 0x%04x", what, i,
                             j, t->w, t->h, k, a, b);
            }
        }
}

static void resize_both(ctex_tex *t, uint16_t **d, int nw, int nh, const char *what)
{
    cr_assert(wire_tex_resize_exact(t->w, t->h, nw, nh), "%s: %dx%d -> %dx%d", what, t->w, t->h, nw, nh);
    uint16_t *n = malloc((size_t)nw * (size_t)nh * 3 * sizeof *n);
    bool neg, nz;
    cr_assert_eq(disp_rescale(*d, t->w, t->h, n, nw, nh, &neg, &nz), 0);
    free(*d);
    *d = n;
    cr_assert_eq(ctex_tex_resize(t, nw, nh, NULL), 0);
    expect_same(t, *d, what);
}

Test(disp_rescale, chains_of_exact_resizes_match_the_master)
{
    const int sizes[][2] = {{1, 1}, {1, 5}, {2, 3}, {3, 3}, {7, 4}, {16, 16}, {33, 17}, {64, 9}, {257, 190}};
    /* per step: x and y each doubled (2), kept (1) or halved (-2) */
    const int steps[][2] = {{2, 2}, {2, 1}, {1, 2}, {-2, -2}, {-2, 1}, {2, 2}, {1, -2}, {2, 2}, {-2, -2}};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        ctex_tex t = {0};
        cr_assert_eq(ctex_tex_init(&t, sizes[s][0], sizes[s][1], NULL), 0);
        fill(&t, 100 + s);
        uint16_t *d = wire_copy(&t);
        for (size_t k = 0; k < sizeof steps / sizeof steps[0]; k++) {
            int nw = steps[k][0] > 0 ? t.w * steps[k][0] : (t.w + 1) / 2;
            int nh = steps[k][1] > 0 ? t.h * steps[k][1] : (t.h + 1) / 2;
            if (nw == t.w && nh == t.h) continue;   /* a 1-texel side halved */
            char what[64];
            snprintf(what, sizeof what, "size %zu step %zu", s, k);
            resize_both(&t, &d, nw, nh, what);
        }
        free(d);
        ctex_tex_release(&t);
    }
}

Test(disp_rescale, only_exact_changes)
{
    cr_assert(wire_tex_resize_exact(4, 4, 8, 4));
    cr_assert(wire_tex_resize_exact(5, 3, 3, 2));
    cr_assert(wire_tex_resize_exact(1, 4, 1, 2));
    cr_assert_not(wire_tex_resize_exact(4, 4, 4, 4));
    cr_assert_not(wire_tex_resize_exact(4, 4, 8, 2));   /* one axis up, one down */
    cr_assert_not(wire_tex_resize_exact(4, 4, 6, 4));
    cr_assert_not(wire_tex_resize_exact(5, 4, 2, 4));
    /* against the rule spelled out: the new sides as factors of the old */
    for (int w = 1; w < 20; w++)
        for (int nw = 1; nw < 42; nw++)
            for (int h = 1; h < 6; h++)
                for (int nh = 1; nh < 12; nh++) {
                    bool want = false;
                    for (int fx = 1; fx <= 2; fx++)
                        for (int fy = 1; fy <= 2; fy++) {
                            want |= (fx > 1 || fy > 1) && nw == fx * w && nh == fy * h;
                            want |= (fx > 1 || fy > 1) && nw == (w + fx - 1) / fx && nh == (h + fy - 1) / fy &&
                                    (nw != w || nh != h);
                        }
                    cr_assert_eq(wire_tex_resize_exact(w, h, nw, nh), want, "%dx%d -> %dx%d", w, h, nw, nh);
                }
}

/* Which old texels new texel (x, y) is computed from: the master's rule
 * (ctex_tex.c, double_rows / halve_rows). */
static bool reads_marked(const ctex_tex *o, const ctex_dirty *od, int x, int y, int nw, int nh)
{
    int xs[2], ys[2], nx = 1, ny = 1;
    if (nw > o->w) {
        xs[0] = x / 2;
        xs[1] = x % 2 ? (x / 2 + 1 < o->w ? x / 2 + 1 : x / 2) : (x / 2 > 0 ? x / 2 - 1 : 0);
        nx = 2;
    } else if (nw < o->w) {
        xs[0] = 2 * x;
        xs[1] = 2 * x + 1 < o->w ? 2 * x + 1 : 2 * x;
        nx = 2;
    } else {
        xs[0] = x;
    }
    if (nh > o->h) {
        ys[0] = y / 2;
        ys[1] = y % 2 ? (y / 2 + 1 < o->h ? y / 2 + 1 : y / 2) : (y / 2 > 0 ? y / 2 - 1 : 0);
        ny = 2;
    } else if (nh < o->h) {
        ys[0] = 2 * y;
        ys[1] = 2 * y + 1 < o->h ? 2 * y + 1 : 2 * y;
        ny = 2;
    } else {
        ys[0] = y;
    }
    for (int a = 0; a < nx; a++)
        for (int b = 0; b < ny; b++) {
            int tx = xs[a] >> CTEX_TILE_SHIFT, ty = ys[b] >> CTEX_TILE_SHIFT;
            if (od->bits[(size_t)ty * (size_t)od->words + (size_t)(tx >> 6)] >> (tx & 63) & 1) return true;
        }
    return false;
}

static bool marked(const ctex_dirty *d, int x, int y)
{
    int tx = x >> CTEX_TILE_SHIFT, ty = y >> CTEX_TILE_SHIFT;
    return d->bits[(size_t)ty * (size_t)d->words + (size_t)(tx >> 6)] >> (tx & 63) & 1;
}

Test(disp_rescale, marks_follow_an_exact_resize)
{
    const int sizes[][2] = {{9, 9}, {40, 13}, {300, 70}};
    const int steps[][2] = {{2, 2}, {2, 1}, {1, 2}, {-2, -2}, {-2, 1}, {1, -2}};
    uint64_t clock = 1000;
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++)
        for (size_t k = 0; k < sizeof steps / sizeof steps[0]; k++) {
            ctex_tex t = {0};
            cr_assert_eq(ctex_tex_init(&t, sizes[s][0], sizes[s][1], NULL), 0);
            t.d.clock = &clock;
            ctex_dirty_clear_all(&t.d);
            ct_rng r = rng_make(7 + s, k, 0, 0);
            uint32_t samples = 0;
            for (int n = 0; n < 5; n++) {
                int x = (int)(rng_float(&r) * (float)t.w), y = (int)(rng_float(&r) * (float)t.h);
                int x1 = x + 3 < t.w ? x + 3 : t.w, y1 = y + 2 < t.h ? y + 2 : t.h;
                clock += 10;
                ctex_dirty_mark(&t.d, x, y, x1, y1, y);
                samples++;
            }
            uint64_t oldest = UINT64_MAX;
            for (int ty = 0; ty < t.d.th; ty++)
                if (t.d.row_t[ty] && t.d.row_t[ty] < oldest) oldest = t.d.row_t[ty];
            ctex_tex old = t;   /* its size and, below, its marks */
            ctex_dirty od = t.d;
            od.bits = malloc((size_t)od.th * (size_t)od.words * sizeof *od.bits);
            memcpy(od.bits, t.d.bits, (size_t)od.th * (size_t)od.words * sizeof *od.bits);
            int nw = steps[k][0] > 0 ? t.w * steps[k][0] : (t.w + 1) / 2;
            int nh = steps[k][1] > 0 ? t.h * steps[k][1] : (t.h + 1) / 2;
            cr_assert_eq(ctex_tex_resize(&t, nw, nh, NULL), 0);
            int nmarked = 0;
            for (int y = 0; y < nh; y++)
                for (int x = 0; x < nw; x++) {
                    bool m = marked(&t.d, x, y);
                    nmarked += m;
                    if (reads_marked(&old, &od, x, y, nw, nh))
                        cr_assert(m, "%dx%d -> %dx%d: texel (%d, %d) reads a marked texel, its tile is not marked",
                                  old.w, old.h, nw, nh, x, y);
                }
            /* (five marks cover most of a small texture) */
            if (nw * nh >= 4096)
                cr_assert_lt(nmarked, nw * nh / 4, "%dx%d -> %dx%d: %d of %d texels marked", old.w, old.h, nw, nh,
                         nmarked, nw * nh);
            uint32_t got = 0;
            uint64_t first = UINT64_MAX;
            for (int ty = 0; ty < t.d.th; ty++) {
                got += t.d.row_n[ty];
                if (t.d.row_t[ty] && t.d.row_t[ty] < first) first = t.d.row_t[ty];
                if (t.d.row_t[ty]) cr_assert(ctex_dirty_row(&t.d, ty), "row %d stamped but not marked", ty);
            }
            cr_assert_eq(got, samples, "the sample counts carry over");
            cr_assert_eq(first, oldest, "the oldest stamp carries over");
            free(od.bits);
            ctex_tex_release(&t);
        }
}
