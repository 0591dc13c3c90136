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

/* A reference prepared once for comparing many images with it (a
 * display's frames, a run's checkpoints): its checks, tone mapping and
 * luminance are done in metrics_ref_new, so a comparison tone-maps one
 * image, not two. It keeps a pointer to ref: ref must outlive it. */
typedef struct metrics_ref metrics_ref;

int metrics_ref_new(const ct_image *ref, metrics_ref **out, ct_error *err);
void metrics_ref_free(metrics_ref *r);

/* What metrics_compare_ref computes: SSIM costs as much as the rest. */
enum { METRICS_NO_SSIM = 0, METRICS_SSIM = 1 };

/* metrics_compare against a prepared reference; with METRICS_NO_SSIM,
 * out->ssim is NaN. */
int metrics_compare_ref(const ct_image *a, const metrics_ref *ref, int what, img_metrics *out, ct_error *err);

/* Region means: a bias that the whole image's error hides under noise
 * shows in the means of blocks, whose noise falls with their pixel count.
 * A block (block x block pixels; partial blocks at the right and bottom
 * are left out) counts when the reference's mean (of R, G, B) is positive
 * and, when given, every pixel of planes within margin pixels of it carries
 * one and the same non-zero value (one flat surface, away from its edges:
 * rad_render_view's RAD_VIEW_PLANES) and flat's
 * pixel means vary over it by at most (flat_ratio - 1) times the
 * reference's mean (flat the direct light: no shadow boundary inside). */
typedef struct img_regions {
    int block;          /* block side in pixels */
    int nx, ny;         /* blocks per row, rows */
    int counted;        /* blocks that count */
    double worst;       /* largest |mean(a) / mean(ref) - 1| of a counted block */
    int worst_x, worst_y;
    double rms;         /* root mean square of mean(a) / mean(ref) - 1 over them */
    float *ratio;       /* nx * ny block ratios mean(a) / mean(ref), NaN where a block
                         * does not count (free with metrics_regions_free) */
    /* metrics_regions_noise's (NULL / 0 without it) */
    float *z;           /* nx * ny: (ratio - 1) over its standard error */
    double z_worst;     /* largest |z| */
    int z_worst_x, z_worst_y;
    double sigma_rms;   /* rms of the blocks' relative standard errors */
    int beyond;         /* blocks with |z| above the bound given */
} img_regions;

/* Block means of a against ref (same sizes; planes and flat may be NULL;
 * margin >= 0). */
int metrics_regions(const ct_image *a, const ct_image *ref, const ct_image *planes, int margin, const ct_image *flat,
                    double flat_ratio, int block, img_regions *out, ct_error *err);

/* Frees out->ratio (and out->z). */
void metrics_regions_free(img_regions *r);

/* The blocks' noise, from repeats: a2, the render of a with another seed,
 * ref2 that of ref (either may be NULL, not both; same sizes). Two
 * independent renders differ per pixel by their noise alone, so the mean
 * over a block of the squared differences, halved, is the pixel variance,
 * and over the pixel count the variance of the block's mean (pixels
 * independent, as a tracer's are). Per counted block of r: sigma = the
 * relative standard error of its ratio, sqrt(var_a / mean_a^2 + var_ref /
 * mean_ref^2), and z = (ratio - 1) / sigma: how many of its own standard
 * errors a block is off. Fills r->z (NaN where a block does not count or
 * sigma is 0), r->z_worst (largest |z|, at z_worst_x, z_worst_y),
 * r->sigma_rms (the rms of sigma: what region_rms would read with no bias
 * at all) and r->beyond (blocks with |z| > sigmas). */
int metrics_regions_noise(const ct_image *a, const ct_image *a2, const ct_image *ref, const ct_image *ref2,
                          double sigmas, img_regions *r, ct_error *err);

#endif
