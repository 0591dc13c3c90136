#include "common/metrics.h"

#include <math.h>
#include <stdlib.h>

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

int metrics_compare(const ct_image *a, const ct_image *ref, img_metrics *out, ct_error *err)
{
    if (!a || !ref || !a->px || !ref->px || a->width < 1 || a->height < 1)
        return ct_fail(err, CT_EINVAL, "metrics: empty image");
    if (a->width != ref->width || a->height != ref->height)
        return ct_fail(err, CT_EINVAL, "image sizes differ: %dx%d vs reference %dx%d", a->width,
                       a->height, ref->width, ref->height);
    /* A NaN would make every metric NaN and every threshold test pass. */
    long bad = first_non_finite(a);
    if (bad >= 0)
        return ct_fail(err, CT_EINVAL, "non-finite value at pixel (%ld, %ld)", bad % a->width,
                       bad / a->width);
    bad = first_non_finite(ref);
    if (bad >= 0)
        return ct_fail(err, CT_EINVAL, "reference has a non-finite value at pixel (%ld, %ld)",
                       bad % ref->width, bad / ref->width);

    int w = a->width, h = a->height;
    size_t npx = (size_t)w * (size_t)h;
    float *ya = malloc(npx * sizeof *ya), *yb = malloc(npx * sizeof *yb);
    int *ox = malloc(((size_t)w / SSIM_STRIDE + 2) * sizeof *ox);
    int *oy = malloc(((size_t)h / SSIM_STRIDE + 2) * sizeof *oy);
    if (!ya || !yb || !ox || !oy) {
        free(ya); free(yb); free(ox); free(oy);
        return ct_fail(err, CT_ENOMEM, "metrics: out of memory for %dx%d images", w, h);
    }
    double se = 0.0, rel = 0.0, se_srgb = 0.0;
    for (size_t p = 0; p < npx; p++) {
        float sa[3], sb[3];
        for (int c = 0; c < 3; c++) {
            double va = a->px[3 * p + c], vb = ref->px[3 * p + c], d = va - vb;
            se += d * d;
            rel += d * d / (vb * vb + RELMSE_EPS);
            sa[c] = img_tonemap(a->px[3 * p + c], 0.0f);
            sb[c] = img_tonemap(ref->px[3 * p + c], 0.0f);
            double ds = (double)sa[c] - sb[c];
            se_srgb += ds * ds;
        }
        /* Rec. 709 weights on the encoded values (luma). */
        ya[p] = v3_luminance(v3(sa[0], sa[1], sa[2]));
        yb[p] = v3_luminance(v3(sb[0], sb[1], sb[2]));
    }
    double nv = 3.0 * (double)npx;
    double mse_srgb = se_srgb / nv;
    out->rmse = sqrt(se / nv);
    out->rel_mse = rel / nv;
    out->psnr = mse_srgb > 0.0 ? 10.0 * log10(1.0 / mse_srgb) : INFINITY;
    out->ssim = ssim_planes(ya, yb, w, h, ox, oy);
    free(ya); free(yb); free(ox); free(oy);
    return CT_OK;
}
