/* disp_rescale.c: exact resolution changes of the display's texel copies
 * (disp_rescale.h). Every product, sum and rounding below is the master's
 * (master/ctex_tex.c: double_rows, dbl_texel, halve_rows), in the same
 * order: tests/unit/test_disp_rescale.c holds them to the same bits. */
#include "display/disp_rescale.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/error.h"
#include "common/half.h"

/* Row j of src as floats (three a texel) and validity bytes: converted once
 * per row, four halves an instruction, instead of per read. */
static void row_in(const uint16_t *src, int w, int j, float *f, uint8_t *v)
{
    const uint16_t *p = src + 3 * (size_t)j * (size_t)w;
    const size_t n = 3 * (size_t)w;
    size_t k = 0;
    for (; k + 4 <= n; k += 4) half4_to_float(p + k, f + k);
    for (; k < n; k++) f[k] = half_to_float(p[k]);
    for (int i = 0; i < w; i++) v[i] = (p[3 * i] | p[3 * i + 1] | p[3 * i + 2]) != 0;
}

/* A new row from its floats and validity: empty texels +0, a valid one
 * whose halves are all +-0 stays valid as -0. */
static void row_out(const float *f, const uint8_t *v, int n, uint16_t *q, bool *neg, bool *nz)
{
    const size_t m = 3 * (size_t)n;
    size_t k = 0;
    for (; k + 4 <= m; k += 4) float4_to_half(f + k, q + k);
    for (; k < m; k++) q[k] = half_from_float(f[k]);
    /* (flags in locals: stores through *neg would alias q) */
    bool any_neg = false;
    unsigned mag = 0;
    for (int i = 0; i < n; i++, q += 3) {
        if (!v[i]) {
            q[0] = q[1] = q[2] = 0;
            continue;
        }
        unsigned a = q[0] & 0x7fffu, b = q[1] & 0x7fffu, c = q[2] & 0x7fffu;
        if (!(a | b | c)) {
            q[0] = 0x8000u; q[1] = q[2] = 0;
            continue;
        }
        mag |= a | b | c;
        any_neg |= (half_is_negative(q[0]) | half_is_negative(q[1]) | half_is_negative(q[2])) != 0;
    }
    *neg |= any_neg;
    *nz |= mag != 0;
}

static int factor_up(int n, int nn)
{
    return nn == 2 * n ? 2 : (nn == n ? 1 : 0);
}

static int factor_down(int n, int nn)
{
    return nn == (n + 1) / 2 ? 2 : (nn == n ? 1 : 0);
}

/* A new texel with some of its four sources empty: the weights over the
 * valid ones (ws[k] > 0), in order; empty when none is. */
static void doubled_partial(const float *const ps[4], const uint8_t ok[4], const float ws[4], float *c, uint8_t *vo)
{
    float sw = 0.0f, acc[3] = {0.0f, 0.0f, 0.0f};
    for (int k = 0; k < 4; k++)
        if (ok[k] && ws[k] > 0.0f) {
            sw += ws[k];
            for (int ch = 0; ch < 3; ch++) acc[ch] += ws[k] * ps[k][ch];
        }
    *vo = sw > 0.0f;
    float inv = *vo ? 1.0f / sw : 0.0f;
    for (int ch = 0; ch < 3; ch++) c[ch] = acc[ch] * inv;
}

/* Source rows, each converted once: row r in slot r % 3, so that a row
 * and its neighbours above and below never share a slot. */
typedef struct rows3 {
    float *f[3];
    uint8_t *v[3];
    int have[3];
} rows3;

static int row_at(rows3 *r, const uint16_t *src, int w, int j)
{
    int k = j % 3;
    if (r->have[k] != j) {
        row_in(src, w, j, r->f[k], r->v[k]);
        r->have[k] = j;
    }
    return k;
}

/* New texel (fx i + a, fy j + b): bilinear at the new centre from texel
 * (i, j), its neighbour towards that centre on each doubled axis (clamped
 * to the edge) and the diagonal; weights over the valid ones. A row is
 * first computed as if every texel were valid, in plain loops over floats
 * the compiler vectorizes (left and right neighbours apart, then
 * interleaved), then the texels next to empty ones are done again. */
static void doubled(const uint16_t *src, int w, int h, uint16_t *dst, int nw, int fx, int fy, float *buf,
                    uint8_t *vb, bool *neg, bool *nz)
{
    const float wx1 = fx == 2 ? 0.25f : 0.0f, wy1 = fy == 2 ? 0.25f : 0.0f;
    const float ws[4] = {(1.0f - wx1) * (1.0f - wy1), wx1 * (1.0f - wy1), (1.0f - wx1) * wy1, wx1 * wy1};
    const float w0 = ws[0], w1 = ws[1], w2 = ws[2], w3 = ws[3];
    const size_t n3 = 3 * (size_t)w;
    rows3 r = {{buf, buf + n3, buf + 2 * n3}, {vb, vb + w, vb + 2 * (size_t)w}, {-1, -1, -1}};
    float *fl = buf + 3 * n3, *fr = fl + n3, *fo = fr + n3;
    uint8_t *vo = vb + 3 * (size_t)w;
    for (int j = 0; j < h; j++) {
        int k0 = row_at(&r, src, w, j);
        const float *f0 = r.f[k0];
        const uint8_t *v0 = r.v[k0];
        for (int b = 0; b < fy; b++) {
            int jn = fy == 1 ? j : (b ? (j + 1 < h ? j + 1 : j) : (j > 0 ? j - 1 : 0));
            int k1 = row_at(&r, src, w, jn);
            const float *g1 = r.f[k1];
            const uint8_t *u1 = r.v[k1];
            if (fx == 2) {
                /* left neighbours (a = 0), the first texel its own */
                for (size_t k = 0; k < 3 && k < n3; k++) fl[k] = w0 * f0[k] + w1 * f0[k] + w2 * g1[k] + w3 * g1[k];
                for (size_t k = 3; k < n3; k++) fl[k] = w0 * f0[k] + w1 * f0[k - 3] + w2 * g1[k] + w3 * g1[k - 3];
                /* right neighbours (a = 1), the last texel its own */
                for (size_t k = 0; k + 3 < n3; k++) fr[k] = w0 * f0[k] + w1 * f0[k + 3] + w2 * g1[k] + w3 * g1[k + 3];
                for (size_t k = n3 - 3; k < n3; k++) fr[k] = w0 * f0[k] + w1 * f0[k] + w2 * g1[k] + w3 * g1[k];
                for (int i = 0; i < w; i++) {
                    memcpy(fo + 6 * i, fl + 3 * i, 3 * sizeof *fo);
                    memcpy(fo + 6 * i + 3, fr + 3 * i, 3 * sizeof *fo);
                }
            } else {
                for (size_t k = 0; k < n3; k++) fo[k] = w0 * f0[k] + w1 * f0[k] + w2 * g1[k] + w3 * g1[k];
            }
            memset(vo, 1, (size_t)nw);
            for (int i = 0; i < w; i++) {
                if (v0[i] & u1[i] & v0[i > 0 ? i - 1 : 0] & u1[i > 0 ? i - 1 : 0] & v0[i + 1 < w ? i + 1 : i] &
                    u1[i + 1 < w ? i + 1 : i])
                    continue;   /* the common case: every source valid */
                for (int a = 0; a < fx; a++) {
                    int in = fx == 1 ? i : (a ? (i + 1 < w ? i + 1 : i) : (i > 0 ? i - 1 : 0));
                    const uint8_t ok[4] = {v0[i], v0[in], u1[i], u1[in]};
                    if (ok[0] & ok[1] & ok[2] & ok[3]) continue;
                    const int o = fx * i + a;
                    const float *ps[4] = {f0 + 3 * i, f0 + 3 * in, g1 + 3 * i, g1 + 3 * in};
                    doubled_partial(ps, ok, ws, fo + 3 * o, vo + o);
                }
            }
            row_out(fo, vo, nw, dst + 3 * (size_t)(fy * j + b) * (size_t)nw, neg, nz);
        }
    }
}

/* New texel (i, j): the mean of the valid texels of its bx x by block. */
static void halved(const uint16_t *src, int w, int h, uint16_t *dst, int nw, int nh, int bx, int by, float *buf,
                   uint8_t *vb, bool *neg, bool *nz)
{
    float *f0 = buf, *f1 = f0 + 3 * (size_t)w, *fo = f1 + 3 * (size_t)w;
    uint8_t *v0 = vb, *v1 = v0 + w, *vo = v1 + w;
    for (int j = 0; j < nh; j++) {
        int y0 = by * j, rows = y0 + by > h ? h - y0 : by;
        row_in(src, w, y0, f0, v0);
        if (rows == 2) row_in(src, w, y0 + 1, f1, v1);
        for (int i = 0; i < nw; i++) {
            int x0 = bx * i, x1 = x0 + bx > w ? w : x0 + bx;
            float acc[3] = {0.0f, 0.0f, 0.0f};
            int n = 0;
            for (int y = 0; y < rows; y++) {
                const float *fr = y ? f1 : f0;
                const uint8_t *vr = y ? v1 : v0;
                for (int x = x0; x < x1; x++) {
                    if (!vr[x]) continue;
                    for (int ch = 0; ch < 3; ch++) acc[ch] += fr[3 * x + ch];
                    n++;
                }
            }
            vo[i] = n > 0;
            float inv = n ? 1.0f / (float)n : 0.0f;
            for (int ch = 0; ch < 3; ch++) fo[3 * i + ch] = fminf(fmaxf(acc[ch] * inv, -HALF_MAX), HALF_MAX);
        }
        row_out(fo, vo, nw, dst + 3 * (size_t)j * (size_t)nw, neg, nz);
    }
}

int disp_rescale(const uint16_t *src, int w, int h, uint16_t *dst, int nw, int nh, bool *negative, bool *nonzero)
{
    *negative = *nonzero = false;
    /* rows of floats and validity: three read, two of neighbours, one
     * written (twice as wide) */
    size_t wide = (size_t)(w > nw ? w : nw);
    float *buf = malloc(7 * 3 * wide * sizeof *buf);
    uint8_t *vb = malloc(4 * wide);
    if (!buf || !vb) {
        free(buf);
        free(vb);
        return CT_ENOMEM;
    }
    int fx = factor_up(w, nw), fy = factor_up(h, nh);
    if (fx && fy) doubled(src, w, h, dst, nw, fx, fy, buf, vb, negative, nonzero);
    else halved(src, w, h, dst, nw, nh, factor_down(w, nw), factor_down(h, nh), buf, vb, negative, nonzero);
    free(buf);
    free(vb);
    return CT_OK;
}
