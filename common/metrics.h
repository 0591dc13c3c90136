/* metrics.h: image error metrics between a test image and a reference.
 * RMSE and relative MSE on linear RGB; PSNR and SSIM on the tone-mapped
 * (exposure 0, sRGB-encoded, clamped to [0,1]) values that a viewer sees. */
#ifndef CT_METRICS_H
#define CT_METRICS_H

#include "common/error.h"
#include "common/image.h"

typedef struct img_metrics {
    double rmse;      /* sqrt(mean over pixels and channels of (a-b)^2), linear */
    double rel_mse;   /* mean of (a-b)^2 / (b^2 + 0.01), linear */
    double psnr;      /* dB, 10 log10(1 / MSE) on sRGB values in [0,1]; inf if equal */
    double ssim;      /* mean SSIM of sRGB luminance, 8x8 windows, stride 4 */
} img_metrics;

/* Compares a against reference ref; the sizes must match. */
int metrics_compare(const ct_image *a, const ct_image *ref, img_metrics *out, ct_error *err);

#endif
