#include "common/metrics.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* SSIM constants for a dynamic range L = 1 (Wang et al. 2004):
 * C1 = (K1 L)^2, C2 = (K2 L)^2 with K1 = 0.01, K2 = 0.03. */
#define SSIM_C1 (0.01 * 0.01)
#define SSIM_C2 (0.03 * 0.03)
#define SSIM_WIN 8
#define SSIM_STRIDE 4
/* relMSE's guard against division by a zero reference. */
#define RELMSE_EPS 0.01

/* Origins of the windows along one axis of length n: 0, 4, 8, ... while the
 * window fits, plus one flush with the far edge when the stride leaves it
 * uncovered. A side shorter than the window gets one window of that side. */
static int window_origins(int n, int *org, int cap)
{
    if (n <= SSIM_WIN) { org[0] = 0; return 1; }
    int k = 0;
    for (int o = 0; o + SSIM_WIN <= n && k < cap; o += SSIM_STRIDE) org[k++] = o;
    if (org[k - 1] + SSIM_WIN < n && k < cap) org[k++] = n - SSIM_WIN;
    return k;
}

/* Mean SSIM of two luminance planes (w x h) over the windows above. */
static double ssim_planes(const float *ya, const float *yb, int w, int h, int *ox, int *oy)
{
    int nx = window_origins(w, ox, w / SSIM_STRIDE + 2);
    int ny = window_origins(h, oy, h / SSIM_STRIDE + 2);
    int ww = w < SSIM_WIN ? w : SSIM_WIN, wh = h < SSIM_WIN ? h : SSIM_WIN;
    double n = (double)ww * wh, sum = 0.0;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double ma = 0.0, mb = 0.0;
            for (int y = oy[j]; y < oy[j] + wh; y++)
                for (int x = ox[i]; x < ox[i] + ww; x++) {
                    ma += ya[(size_t)y * w + x];
                    mb += yb[(size_t)y * w + x];
                }
            ma /= n;
            mb /= n;
            /* Population (1/N) variances and covariance, two-pass. */
            double va = 0.0, vb = 0.0, cov = 0.0;
            for (int y = oy[j]; y < oy[j] + wh; y++)
                for (int x = ox[i]; x < ox[i] + ww; x++) {
                    double da = ya[(size_t)y * w + x] - ma, db = yb[(size_t)y * w + x] - mb;
                    va += da * da;
                    vb += db * db;
                    cov += da * db;
                }
            va /= n;
            vb /= n;
            cov /= n;
            sum += ((2.0 * ma * mb + SSIM_C1) * (2.0 * cov + SSIM_C2)) /
                   ((ma * ma + mb * mb + SSIM_C1) * (va + vb + SSIM_C2));
        }
    return sum / ((double)nx * ny);
}

/* Index of the first non-finite value of img, or -1. */
static long first_non_finite(const ct_image *img)
{
    size_t n = (size_t)img->width * (size_t)img->height * 3;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(img->px[i])) return (long)(i / 3);
    return -1;
}

struct metrics_ref {
    const ct_image *img;
    float *srgb;    /* tone-mapped R, G, B */
    float *luma;    /* Rec. 709 luma of srgb */
    float *rel_w;   /* 1 / (ref^2 + RELMSE_EPS) per channel */
};

void metrics_ref_free(metrics_ref *r)
{
    if (!r) return;
    free(r->srgb);
    free(r->luma);
    free(r->rel_w);
    free(r);
}

int metrics_ref_new(const ct_image *ref, metrics_ref **out, ct_error *err)
{
    *out = NULL;
    if (!ref || !ref->px || ref->width < 1 || ref->height < 1) return ct_fail(err, CT_EINVAL, "metrics: empty image");
    long bad = first_non_finite(ref);
    if (bad >= 0)
        return ct_fail(err, CT_EINVAL, "reference has a non-finite value at pixel (%ld, %ld)", bad % ref->width,
                       bad / ref->width);
    size_t npx = (size_t)ref->width * (size_t)ref->height;
    metrics_ref *r = calloc(1, sizeof *r);
    if (r) {
        r->img = ref;
        r->srgb = malloc(3 * npx * sizeof *r->srgb);
        r->luma = malloc(npx * sizeof *r->luma);
        r->rel_w = malloc(3 * npx * sizeof *r->rel_w);
    }
    if (!r || !r->srgb || !r->luma || !r->rel_w) {
        metrics_ref_free(r);
        return ct_fail(err, CT_ENOMEM, "metrics: out of memory for a %dx%d reference", ref->width, ref->height);
    }
    img_tonemap_n(ref->px, r->srgb, 3 * npx);
    for (size_t p = 0; p < npx; p++) {
        const float *s = r->srgb + 3 * p;
        r->luma[p] = v3_luminance(v3(s[0], s[1], s[2]));
        for (int c = 0; c < 3; c++) {
            double vb = ref->px[3 * p + c];
            r->rel_w[3 * p + c] = (float)(1.0 / (vb * vb + RELMSE_EPS));
        }
    }
    *out = r;
    return CT_OK;
}

/* Rows at a time, so the tone-mapped copy of a stays in cache. */
#define CMP_ROWS 16

int metrics_compare_ref(const ct_image *a, const metrics_ref *r, int what, img_metrics *out, ct_error *err)
{
    const ct_image *ref = r->img;
    if (!a || !a->px || a->width < 1 || a->height < 1) return ct_fail(err, CT_EINVAL, "metrics: empty image");
    if (a->width != ref->width || a->height != ref->height)
        return ct_fail(err, CT_EINVAL, "image sizes differ: %dx%d vs reference %dx%d", a->width,
                       a->height, ref->width, ref->height);
    /* A NaN would make every metric NaN and every threshold test pass. */
    long bad = first_non_finite(a);
    if (bad >= 0)
        return ct_fail(err, CT_EINVAL, "non-finite value at pixel (%ld, %ld)", bad % a->width,
                       bad / a->width);

    int w = a->width, h = a->height;
    size_t npx = (size_t)w * (size_t)h;
    size_t chunk = 3 * (size_t)w * CMP_ROWS;
    float *sa = malloc(chunk * sizeof *sa);
    float *ya = what & METRICS_SSIM ? malloc(npx * sizeof *ya) : NULL;
    int *ox = malloc(((size_t)w / SSIM_STRIDE + 2) * sizeof *ox);
    int *oy = malloc(((size_t)h / SSIM_STRIDE + 2) * sizeof *oy);
    if (!sa || !ox || !oy || (what & METRICS_SSIM && !ya)) {
        free(sa); free(ya); free(ox); free(oy);
        return ct_fail(err, CT_ENOMEM, "metrics: out of memory for %dx%d images", w, h);
    }
    double se = 0.0, rel = 0.0, se_srgb = 0.0;
    for (size_t i0 = 0; i0 < 3 * npx; i0 += chunk) {
        size_t n = 3 * npx - i0 < chunk ? 3 * npx - i0 : chunk;
        const float *pa = a->px + i0, *pb = ref->px + i0, *sb = r->srgb + i0, *wr = r->rel_w + i0;
        img_tonemap_n(pa, sa, n);
        for (size_t i = 0; i < n; i++) {
            double d = (double)pa[i] - pb[i], dd = d * d, ds = (double)sa[i] - sb[i];
            se += dd;
            rel += dd * wr[i];
            se_srgb += ds * ds;
        }
        if (ya)   /* Rec. 709 weights on the encoded values (luma). */
            for (size_t p = 0; p < n / 3; p++)
                ya[i0 / 3 + p] = v3_luminance(v3(sa[3 * p], sa[3 * p + 1], sa[3 * p + 2]));
    }
    double nv = 3.0 * (double)npx;
    double mse_srgb = se_srgb / nv;
    out->rmse = sqrt(se / nv);
    out->rel_mse = rel / nv;
    out->psnr = mse_srgb > 0.0 ? 10.0 * log10(1.0 / mse_srgb) : INFINITY;
    out->ssim = ya ? ssim_planes(ya, r->luma, w, h, ox, oy) : NAN;
    free(sa); free(ya); free(ox); free(oy);
    return CT_OK;
}

int metrics_compare(const ct_image *a, const ct_image *ref, img_metrics *out, ct_error *err)
{
    /* Sizes checked first: a mismatch must not tone-map the reference for nothing. */
    if (!a || !ref || !a->px || !ref->px || a->width < 1 || a->height < 1)
        return ct_fail(err, CT_EINVAL, "metrics: empty image");
    if (a->width != ref->width || a->height != ref->height)
        return ct_fail(err, CT_EINVAL, "image sizes differ: %dx%d vs reference %dx%d", a->width,
                       a->height, ref->width, ref->height);
    metrics_ref *r;
    int rc = metrics_ref_new(ref, &r, err);
    if (rc) return rc;
    rc = metrics_compare_ref(a, r, METRICS_SSIM, out, err);
    metrics_ref_free(r);
    return rc;
}

static double px_mean(const ct_image *img, int x, int y)
{
    vec3 v = img_get(img, x, y);
    return ((double)v.x + v.y + v.z) / 3.0;
}

/* Whether the block at (x0, y0) counts (metrics_regions); mean is the
 * reference's mean over it. */
static int block_counts(const ct_image *planes, int margin, const ct_image *flat, double flat_ratio, int x0, int y0,
                        int b, double mean)
{
    if (planes) {
        vec3 k = img_get(planes, x0, y0);
        if (k.x == 0.0f && k.y == 0.0f && k.z == 0.0f) return 0;
        int xa = x0 - margin > 0 ? x0 - margin : 0, ya = y0 - margin > 0 ? y0 - margin : 0;
        int xb = x0 + b + margin < planes->width ? x0 + b + margin : planes->width;
        int yb = y0 + b + margin < planes->height ? y0 + b + margin : planes->height;
        for (int y = ya; y < yb; y++)
            for (int x = xa; x < xb; x++) {
                vec3 q = img_get(planes, x, y);
                if (q.x != k.x || q.y != k.y || q.z != k.z) return 0;
            }
    }
    if (flat) {
        double lo = HUGE_VAL, hi = -HUGE_VAL;
        for (int y = y0; y < y0 + b; y++)
            for (int x = x0; x < x0 + b; x++) {
                double v = px_mean(flat, x, y);
                lo = fmin(lo, v);
                hi = fmax(hi, v);
            }
        if (hi - lo > (flat_ratio - 1.0) * mean) return 0;
    }
    return 1;
}

/* CT_OK when each of the n images given (NULL: none) has a's size. */
static int sizes_agree(const ct_image *a, const ct_image *const *all, int n, ct_error *err)
{
    for (int i = 0; i < n; i++)
        if (all[i] && (all[i]->width != a->width || all[i]->height != a->height))
            return ct_fail(err, CT_EINVAL, "image sizes differ: %dx%d vs %dx%d", a->width, a->height,
                           all[i]->width, all[i]->height);
    return CT_OK;
}

int metrics_regions(const ct_image *a, const ct_image *ref, const ct_image *planes, int margin, const ct_image *flat,
                    double flat_ratio, int block, img_regions *out, ct_error *err)
{
    memset(out, 0, sizeof *out);
    if (!a || !ref || !a->px || !ref->px || a->width < 1 || a->height < 1)
        return ct_fail(err, CT_EINVAL, "metrics: empty image");
    const ct_image *all[3] = {ref, planes, flat};
    int rc = sizes_agree(a, all, 3, err);
    if (rc) return rc;
    if (block < 1 || block > a->width || block > a->height)
        return ct_fail(err, CT_EINVAL, "region size %d outside [1, %d]", block,
                       a->width < a->height ? a->width : a->height);
    out->block = block;
    out->nx = a->width / block;
    out->ny = a->height / block;
    out->worst_x = out->worst_y = -1;
    out->ratio = malloc((size_t)out->nx * out->ny * sizeof *out->ratio);
    if (!out->ratio) return ct_fail(err, CT_ENOMEM, "metrics: out of memory for %d regions", out->nx * out->ny);
    double sq = 0.0;
    for (int by = 0; by < out->ny; by++)
        for (int bx = 0; bx < out->nx; bx++) {
            int x0 = bx * block, y0 = by * block;
            double sa = 0.0, sb = 0.0;
            for (int y = y0; y < y0 + block; y++)
                for (int x = x0; x < x0 + block; x++) {
                    sa += px_mean(a, x, y);
                    sb += px_mean(ref, x, y);
                }
            float *r = &out->ratio[by * out->nx + bx];
            *r = NAN;
            if (!(sb > 0.0) || !isfinite(sa) || !block_counts(planes, margin, flat, flat_ratio, x0, y0, block, sb / ((double)block * block))) continue;
            double q = sa / sb;
            *r = (float)q;
            out->counted++;
            sq += (q - 1.0) * (q - 1.0);
            if (fabs(q - 1.0) > out->worst || out->worst_x < 0) {
                out->worst = fabs(q - 1.0);
                out->worst_x = bx;
                out->worst_y = by;
            }
        }
    out->rms = out->counted ? sqrt(sq / out->counted) : 0.0;
    return CT_OK;
}

void metrics_regions_free(img_regions *r)
{
    free(r->ratio);
    free(r->z);
    r->ratio = NULL;
    r->z = NULL;
}

/* The variance of x's mean over the block at (x0, y0), side b, from the
 * pixel differences to x2 (NULL: 0); *mean gets x's mean. */
static double block_mean_var(const ct_image *x, const ct_image *x2, int x0, int y0, int b, double *mean)
{
    double s = 0.0, d2 = 0.0;
    for (int y = y0; y < y0 + b; y++)
        for (int xx = x0; xx < x0 + b; xx++) {
            double v = px_mean(x, xx, y);
            s += v;
            if (x2) {
                double d = v - px_mean(x2, xx, y);
                d2 += d * d;
            }
        }
    double n = (double)b * b;
    *mean = s / n;
    return d2 / (2.0 * n * n);
}

int metrics_regions_noise(const ct_image *a, const ct_image *a2, const ct_image *ref, const ct_image *ref2,
                          double sigmas, img_regions *r, ct_error *err)
{
    if (!a2 && !ref2) return ct_fail(err, CT_EINVAL, "metrics: no repeat to take the noise from");
    const ct_image *all[2] = {a2, ref2};
    int rc = sizes_agree(a, all, 2, err);
    if (rc) return rc;
    free(r->z);
    r->z = malloc((size_t)r->nx * r->ny * sizeof *r->z);
    if (!r->z) return ct_fail(err, CT_ENOMEM, "metrics: out of memory for %d regions", r->nx * r->ny);
    r->z_worst = 0.0;
    r->z_worst_x = r->z_worst_y = -1;
    r->beyond = 0;
    double s2 = 0.0;
    int n = 0;
    for (int by = 0; by < r->ny; by++)
        for (int bx = 0; bx < r->nx; bx++) {
            float *z = &r->z[by * r->nx + bx];
            *z = NAN;
            float q = r->ratio[by * r->nx + bx];
            if (isnan(q)) continue;
            int x0 = bx * r->block, y0 = by * r->block;
            double ma, mb;
            double va = block_mean_var(a, a2, x0, y0, r->block, &ma);
            double vb = block_mean_var(ref, ref2, x0, y0, r->block, &mb);
            /* (mb > 0: the block counts) */
            double rel = (ma > 0.0 ? va / (ma * ma) : 0.0) + vb / (mb * mb);
            if (!isfinite(rel)) continue;
            double sigma = sqrt(rel);
            s2 += rel;
            n++;
            if (!(sigma > 0.0)) continue;
            double zz = ((double)q - 1.0) / sigma;
            *z = (float)zz;
            if (fabs(zz) > sigmas) r->beyond++;
            if (fabs(zz) > r->z_worst || r->z_worst_x < 0) {
                r->z_worst = fabs(zz);
                r->z_worst_x = bx;
                r->z_worst_y = by;
            }
        }
    r->sigma_rms = n ? sqrt(s2 / n) : 0.0;
    return CT_OK;
}
