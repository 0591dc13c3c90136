/* Unit tests of common/metrics.c against values computed by hand on tiny
 * images (the arithmetic is in the comments). */
#include <criterion/criterion.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "common/metrics.h"
#include "common/rng.h"

static ct_image make(int w, int h, float r, float g, float b)
{
    ct_image img;
    ct_error err;
    cr_assert_eq(img_alloc(&img, w, h, &err), 0, "%s", err.msg);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) img_set(&img, x, y, v3(r, g, b));
    return img;
}

static img_metrics compare_ok(const ct_image *a, const ct_image *b)
{
    img_metrics m;
    ct_error err;
    cr_assert_eq(metrics_compare(a, b, &m, &err), 0, "%s", err.msg);
    return m;
}

Test(metrics, rmse_relmse_psnr_two_pixels)
{
    /* a = [(1,1,1), (0,0,0)], ref = black: three of six values differ by 1.
     * MSE = 3/6 = 0.5, RMSE = sqrt(0.5) = 0.7071068.
     * relMSE = (3 * 1 / (0 + 0.01)) / 6 = 50.
     * sRGB values are the same (0 and 1), so PSNR = 10 log10(1 / 0.5) = 3.0103 dB. */
    ct_image a = make(2, 1, 0, 0, 0), ref = make(2, 1, 0, 0, 0);
    img_set(&a, 0, 0, v3(1, 1, 1));
    img_metrics m = compare_ok(&a, &ref);
    cr_assert_float_eq(m.rmse, 0.70710678, 1e-7);
    cr_assert_float_eq(m.rel_mse, 50.0, 1e-9);
    cr_assert_float_eq(m.psnr, 3.0102999566, 1e-6);
    img_free(&a);
    img_free(&ref);
}

Test(metrics, grey_levels)
{
    /* a = 0.5 grey, ref = 0.25 grey (linear).
     * RMSE = 0.25; relMSE = 0.0625 / (0.0625 + 0.01) = 0.862069.
     * sRGB(0.5) = 0.735357, sRGB(0.25) = 0.537099: MSE = 0.198258^2 = 0.039306,
     * PSNR = 10 log10(1 / 0.039306) = 14.05537 dB.
     * Flat windows have zero variance and covariance, so SSIM reduces to the
     * luminance term (2 mu_a mu_b + C1) / (mu_a^2 + mu_b^2 + C1) = 0.952604. */
    ct_image a = make(12, 9, 0.5f, 0.5f, 0.5f), ref = make(12, 9, 0.25f, 0.25f, 0.25f);
    img_metrics m = compare_ok(&a, &ref);
    cr_assert_float_eq(m.rmse, 0.25, 1e-9);
    cr_assert_float_eq(m.rel_mse, 0.86206897, 1e-7);
    cr_assert_float_eq(m.psnr, 14.0553745, 1e-4);
    cr_assert_float_eq(m.ssim, 0.9526044, 1e-5);
    /* Swapping the roles changes relMSE (it divides by the reference). */
    img_metrics r = compare_ok(&ref, &a);
    cr_assert_float_eq(r.rmse, 0.25, 1e-9);
    cr_assert_float_eq(r.rel_mse, 0.0625 / (0.25 + 0.01), 1e-7);
    img_free(&a);
    img_free(&ref);
}

Test(metrics, per_channel_and_clamping)
{
    /* Only green differs, by 2 (linear), in one of 4 pixels: MSE = 4 / 12,
     * RMSE = 0.5773503. Green 3.0 vs 1.0 both tone-map to 1.0, so PSNR is
     * infinite and SSIM is 1: they only see displayable values. */
    ct_image a = make(2, 2, 0.2f, 1.0f, 0.1f), ref = make(2, 2, 0.2f, 1.0f, 0.1f);
    img_set(&a, 1, 1, v3(0.2f, 3.0f, 0.1f));
    img_metrics m = compare_ok(&a, &ref);
    cr_assert_float_eq(m.rmse, sqrt(4.0 / 12.0), 1e-7);
    cr_assert_float_eq(m.rel_mse, (4.0 / 1.01) / 12.0, 1e-7);
    cr_assert(isinf(m.psnr) && m.psnr > 0);
    cr_assert_float_eq(m.ssim, 1.0, 1e-12);
    img_free(&a);
    img_free(&ref);
}

Test(metrics, identical_images)
{
    ct_image a = make(37, 21, 0, 0, 0);
    ct_rng r = rng_make(1, 2, 3, 4);
    for (size_t i = 0; i < 37 * 21 * 3; i++) a.px[i] = 2.0f * rng_float(&r);
    img_metrics m = compare_ok(&a, &a);
    cr_assert_eq(m.rmse, 0.0);
    cr_assert_eq(m.rel_mse, 0.0);
    cr_assert(isinf(m.psnr));
    cr_assert_float_eq(m.ssim, 1.0, 1e-12);
    img_free(&a);
}

Test(metrics, ssim_drops_with_noise)
{
    /* A smooth gradient with increasing amounts of noise: SSIM < 1 and
     * decreasing, PSNR decreasing, RMSE increasing. */
    int w = 64, h = 48;
    ct_image ref = make(w, h, 0, 0, 0), a = make(w, h, 0, 0, 0);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float v = 0.05f + 0.8f * (float)(x + y) / (float)(w + h);
            img_set(&ref, x, y, v3(v, 0.5f * v, 0.25f + 0.5f * v));
        }
    double prev_ssim = 1.0, prev_psnr = INFINITY, prev_rmse = 0.0;
    const float sigmas[] = {0.01f, 0.03f, 0.1f, 0.3f};
    for (int k = 0; k < 4; k++) {
        ct_rng r = rng_make(7, (uint64_t)k, 0, 0);
        for (size_t i = 0; i < (size_t)w * h * 3; i++)
            a.px[i] = ref.px[i] + sigmas[k] * (2.0f * rng_float(&r) - 1.0f);
        img_metrics m = compare_ok(&a, &ref);
        cr_assert_lt(m.ssim, prev_ssim, "sigma %g: ssim %g not below %g", (double)sigmas[k], m.ssim, prev_ssim);
        cr_assert_lt(m.psnr, prev_psnr);
        cr_assert_gt(m.rmse, prev_rmse);
        /* Uniform noise in [-s, s] has RMS s / sqrt(3). */
        cr_assert_float_eq(m.rmse, sigmas[k] / sqrt(3.0), 0.05 * sigmas[k]);
        prev_ssim = m.ssim; prev_psnr = m.psnr; prev_rmse = m.rmse;
    }
    cr_assert_lt(prev_ssim, 0.8);
    cr_assert_gt(prev_ssim, -1.0);
    img_free(&a);
    img_free(&ref);
}

Test(metrics, ssim_checkerboard_vs_inverse)
{
    /* 8x8: one window. Checkerboard of 0/1 against its inverse: both means
     * 0.5, variances 0.25, covariance -0.25.
     * SSIM = (2*0.25 + C1)(-0.5 + C2) / ((0.5 + C1)(0.5 + C2))
     *      = -0.4991 / 0.5009 = -0.9964064. */
    ct_image a = make(8, 8, 0, 0, 0), b = make(8, 8, 0, 0, 0);
    for (int y = 0; y < 8; y++)
        for (int x = 0; x < 8; x++) {
            float v = (float)((x + y) % 2);
            img_set(&a, x, y, v3s(v));
            img_set(&b, x, y, v3s(1.0f - v));
        }
    img_metrics m = compare_ok(&a, &b);
    cr_assert_float_eq(m.ssim, -0.4991 / 0.5009, 1e-5);
    cr_assert_float_eq(m.rmse, 1.0, 1e-12);
    cr_assert_float_eq(m.psnr, 0.0, 1e-12);
    img_free(&a);
    img_free(&b);
}

Test(metrics, ssim_covers_edges_and_tiny_images)
{
    /* 13 x 9: windows at x = 0, 4 and 5 (flush right), y = 0 and 1. A change in
     * the last column and last row must lower SSIM. */
    ct_image a = make(13, 9, 0.3f, 0.3f, 0.3f), b = make(13, 9, 0.3f, 0.3f, 0.3f);
    img_set(&a, 12, 8, v3s(0.9f));
    img_metrics m = compare_ok(&a, &b);
    cr_assert_lt(m.ssim, 0.999);
    /* Images smaller than a window: one window of the whole image. */
    ct_image c = make(3, 2, 0.5f, 0.5f, 0.5f), d = make(3, 2, 0.25f, 0.25f, 0.25f);
    m = compare_ok(&c, &d);
    cr_assert_float_eq(m.ssim, 0.9526044, 1e-5);
    ct_image e = make(1, 1, 0.5f, 0.5f, 0.5f);
    m = compare_ok(&e, &e);
    cr_assert_float_eq(m.ssim, 1.0, 1e-12);
    img_free(&a); img_free(&b); img_free(&c); img_free(&d); img_free(&e);
}

Test(metrics, size_mismatch_is_an_error)
{
    ct_image a = make(4, 3, 0, 0, 0), b = make(3, 4, 0, 0, 0);
    img_metrics m;
    ct_error err;
    cr_assert_eq(metrics_compare(&a, &b, &m, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "4x3") != NULL && strstr(err.msg, "3x4") != NULL, "%s", err.msg);
    img_free(&a);
    img_free(&b);
}

Test(metrics, non_finite_is_an_error)
{
    ct_image a = make(4, 3, 0, 0, 0), b = make(4, 3, 0, 0, 0);
    img_metrics m;
    ct_error err;
    img_set(&a, 2, 1, v3(0, NAN, 0));
    cr_assert_eq(metrics_compare(&a, &b, &m, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "(2, 1)") != NULL, "%s", err.msg);
    img_set(&a, 2, 1, v3(0, 0, 0));
    img_set(&b, 3, 2, v3(INFINITY, 0, 0));
    cr_assert_eq(metrics_compare(&a, &b, &m, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "reference") != NULL && strstr(err.msg, "(3, 2)") != NULL, "%s", err.msg);
    img_free(&a);
    img_free(&b);
}

Test(metrics, prepared_reference_gives_the_same_metrics)
{
    /* Noise over a gradient: the prepared reference's metrics equal
     * metrics_compare's, for several images against one reference; without
     * SSIM the rest is unchanged and ssim is NaN. */
    int w = 70, h = 41;   /* rows not a multiple of the comparison's row chunk */
    ct_image ref = make(w, h, 0, 0, 0), a = make(w, h, 0, 0, 0);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float v = 0.002f + 1.2f * (float)(x * y) / (float)(w * h);
            img_set(&ref, x, y, v3(v, 0.5f * v, 0.25f + 0.5f * v));
        }
    metrics_ref *r;
    ct_error err;
    cr_assert_eq(metrics_ref_new(&ref, &r, &err), 0, "%s", err.msg);
    for (int k = 0; k < 3; k++) {
        ct_rng g = rng_make(11, (uint64_t)k, 0, 0);
        for (size_t i = 0; i < (size_t)w * h * 3; i++) a.px[i] = ref.px[i] + 0.05f * (float)k * (rng_float(&g) - 0.4f);
        img_metrics m = compare_ok(&a, &ref), p, q;
        cr_assert_eq(metrics_compare_ref(&a, r, METRICS_SSIM, &p, &err), 0, "%s", err.msg);
        cr_assert_eq(metrics_compare_ref(&a, r, METRICS_NO_SSIM, &q, &err), 0, "%s", err.msg);
        cr_assert_float_eq(p.rmse, m.rmse, 1e-12);
        cr_assert_float_eq(p.rel_mse, m.rel_mse, 1e-9 * m.rel_mse + 1e-15);
        if (k) cr_assert_float_eq(p.psnr, m.psnr, 1e-9);
        else cr_assert(isinf(p.psnr) && isinf(m.psnr));
        cr_assert_float_eq(p.ssim, m.ssim, 1e-12);
        cr_assert_eq(q.rmse, p.rmse);
        cr_assert_eq(q.psnr, p.psnr);
        cr_assert(isnan(q.ssim));
    }
    ct_image small = make(w - 1, h, 0, 0, 0);
    img_metrics m;
    cr_assert_eq(metrics_compare_ref(&small, r, METRICS_NO_SSIM, &m, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "sizes differ") != NULL, "%s", err.msg);
    img_set(&a, 1, 2, v3(NAN, 0, 0));
    cr_assert_eq(metrics_compare_ref(&a, r, METRICS_NO_SSIM, &m, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "(1, 2)") != NULL, "%s", err.msg);
    metrics_ref_free(r);
    img_set(&ref, 3, 4, v3(0, INFINITY, 0));
    cr_assert_eq(metrics_ref_new(&ref, &r, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "reference") != NULL && strstr(err.msg, "(3, 4)") != NULL, "%s", err.msg);
    img_free(&small);
    img_free(&a);
    img_free(&ref);
}

static img_regions regions_ok(const ct_image *a, const ct_image *ref, const ct_image *planes, const ct_image *flat,
                              double flat_ratio, int block)
{
    img_regions r;
    ct_error err;
    cr_assert_eq(metrics_regions(a, ref, planes, 0, flat, flat_ratio, block, &r, &err), 0, "%s", err.msg);
    return r;
}

Test(metrics, region_means_and_worst_block)
{
    /* 10 x 6 pixels in 4 x 4 blocks: 2 x 1 full blocks, the rest left out.
     * The reference is grey 1 (mean of RGB); a is 1.0 in block (0, 0) and
     * 1.5 on one pixel of block (1, 0) (mean (15 + 1.5) / 16 = 1.03125):
     * worst 0.03125 at (1, 0), rms sqrt((0 + 0.03125^2) / 2). */
    ct_image a = make(10, 6, 1, 1, 1), ref = make(10, 6, 0.5f, 1.0f, 1.5f);
    img_set(&a, 5, 2, v3(1.5f, 1.5f, 1.5f));
    img_set(&a, 9, 5, v3(100, 100, 100));   /* in no full block */
    img_regions r = regions_ok(&a, &ref, NULL, NULL, 1.25, 4);
    cr_assert_eq(r.nx, 2);
    cr_assert_eq(r.ny, 1);
    cr_assert_eq(r.counted, 2);
    cr_assert_float_eq(r.ratio[0], 1.0f, 1e-6f);
    cr_assert_float_eq(r.ratio[1], 1.03125f, 1e-6f);
    cr_assert_float_eq(r.worst, 0.03125, 1e-9);
    cr_assert_eq(r.worst_x, 1);
    cr_assert_eq(r.worst_y, 0);
    cr_assert_float_eq(r.rms, sqrt(0.03125 * 0.03125 / 2.0), 1e-9);
    metrics_regions_free(&r);
    img_free(&a);
    img_free(&ref);
}

Test(metrics, region_masks_planes_flat_and_dark_reference)
{
    /* Four 2 x 2 blocks of a 4 x 4 image. Block (0, 0): on one plane, flat:
     * counts. Block (1, 0): two plane values: out. Block (0, 1): flat varies
     * by 0.3 against a reference mean of 1 (over 0.25): out. Block (1, 1):
     * reference black: out. */
    ct_image a = make(4, 4, 2, 2, 2), ref = make(4, 4, 1, 1, 1), planes = make(4, 4, 7, 3, 1),
             flat = make(4, 4, 0.5f, 0.5f, 0.5f);
    img_set(&planes, 3, 1, v3(7, 3, 2));
    img_set(&flat, 1, 3, v3(0.8f, 0.8f, 0.8f));
    for (int y = 2; y < 4; y++)
        for (int x = 2; x < 4; x++) img_set(&ref, x, y, v3s(0.0f));
    img_regions r = regions_ok(&a, &ref, &planes, &flat, 1.25, 2);
    cr_assert_eq(r.counted, 1);
    cr_assert_float_eq(r.ratio[0], 2.0f, 1e-6f);
    for (int i = 1; i < 4; i++) cr_assert(isnan(r.ratio[i]), "block %d should not count", i);
    cr_assert_float_eq(r.worst, 1.0, 1e-9);
    metrics_regions_free(&r);
    /* A looser flat ratio lets block (0, 1) count; a zero plane value never counts. */
    img_set(&planes, 0, 0, v3s(0.0f));
    r = regions_ok(&a, &ref, &planes, &flat, 1.35, 2);
    cr_assert_eq(r.counted, 1);
    cr_assert(isnan(r.ratio[0]));
    cr_assert_float_eq(r.ratio[2], 2.0f, 1e-6f);
    metrics_regions_free(&r);
    /* Block (0, 1) covers x 0-1, y 2-3; a margin of 1 adds x 2 and y 1: a
     * pixel of another plane at (2, 1) keeps it out. */
    img_set(&planes, 2, 1, v3(7, 3, 2));
    ct_error err;
    cr_assert_eq(metrics_regions(&a, &ref, &planes, 1, &flat, 1.35, 2, &r, &err), 0, "%s", err.msg);
    cr_assert_eq(r.counted, 0, "a plane edge one pixel from block (0, 1) must keep it out");
    metrics_regions_free(&r);
    img_free(&a);
    img_free(&ref);
    img_free(&planes);
    img_free(&flat);
}

Test(metrics, region_size_and_mask_size_errors)
{
    ct_image a = make(4, 4, 1, 1, 1), ref = make(4, 4, 1, 1, 1), small = make(3, 4, 1, 1, 1);
    img_regions r;
    ct_error err;
    cr_assert_eq(metrics_regions(&a, &ref, NULL, 0, NULL, 1.25, 5, &r, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "region size 5"), "%s", err.msg);
    cr_assert_eq(metrics_regions(&a, &ref, &small, 0, NULL, 1.25, 2, &r, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "sizes differ"), "%s", err.msg);
    img_free(&a);
    img_free(&ref);
    img_free(&small);
}

/* A grey image of 1 plus independent Gaussian noise of deviation sd per
 * pixel and channel (Box-Muller), seeded. */
static ct_image noisy(int w, int h, double sd, uint64_t seed)
{
    ct_image img = make(w, h, 1, 1, 1);
    ct_rng r = rng_make(seed, 7, 0, 0);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float c[3];
            for (int k = 0; k < 3; k++) {
                double u1 = 1.0 - rng_float(&r), u2 = rng_float(&r);
                c[k] = (float)(1.0 + sd * sqrt(-2.0 * log(u1)) * cos(2.0 * CT_PI * u2));
            }
            img_set(&img, x, y, v3(c[0], c[1], c[2]));
        }
    return img;
}

Test(metrics, region_noise_from_repeats_gives_each_block_its_standard_error)
{
    /* 256 x 256 in 8 x 8 blocks: 1024 blocks of 64 pixels. Pixel noise sd
     * 0.3 per channel is sd / sqrt(3) on a pixel's mean of R, G, B, so a
     * block mean of one image has the relative standard error 0.3 /
     * sqrt(3 * 64), and a ratio of two such sqrt(2) times that: 0.0306.
     * Four independent images (a, its repeat, ref, its repeat) must give
     * that as sigma_rms and z about N(0, 1): rms near 1, hardly a block
     * beyond 4 (expected 0.06 of 1024). Then one block of a 20 % brighter:
     * z about 6.5 there, the worst. */
    ct_error err;
    const double sd = 0.3, want = sd / sqrt(3.0 * 64.0) * sqrt(2.0);
    ct_image a = noisy(256, 256, sd, 1), a2 = noisy(256, 256, sd, 2);
    ct_image ref = noisy(256, 256, sd, 3), ref2 = noisy(256, 256, sd, 4);
    img_regions r = regions_ok(&a, &ref, NULL, NULL, 1.25, 8);
    cr_assert_eq(metrics_regions_noise(&a, &a2, &ref, &ref2, 4.0, &r, &err), 0, "%s", err.msg);
    double zz = 0.0;
    for (int i = 0; i < r.nx * r.ny; i++) zz += (double)r.z[i] * r.z[i];
    double zrms = sqrt(zz / (r.nx * r.ny));
    printf("metric: noise from repeats: sigma_rms %.5f (want %.5f), z rms %.3f, |z| > 4: %d, worst %.2f\n",
           r.sigma_rms, want, zrms, r.beyond, r.z_worst);
    cr_expect(fabs(r.sigma_rms / want - 1.0) < 0.05, "sigma_rms %g, want %g", r.sigma_rms, want);
    cr_expect(zrms > 0.9 && zrms < 1.1, "z rms %g", zrms);
    cr_expect_leq(r.beyond, 2);
    metrics_regions_free(&r);

    for (int y = 80; y < 88; y++)
        for (int x = 40; x < 48; x++) img_set(&a, x, y, v3_scale(img_get(&a, x, y), 1.2f));
    r = regions_ok(&a, &ref, NULL, NULL, 1.25, 8);
    cr_assert_eq(metrics_regions_noise(&a, &a2, &ref, &ref2, 4.0, &r, &err), 0, "%s", err.msg);
    printf("metric: a block 20 %% over: z %.2f at %d %d\n", r.z_worst, r.z_worst_x, r.z_worst_y);
    cr_expect_eq(r.z_worst_x, 5);
    cr_expect_eq(r.z_worst_y, 10);
    cr_expect_gt(r.z_worst, 4.0);
    metrics_regions_free(&r);

    /* Only the reference's repeat: a taken as exact, sigma 1 / sqrt(2) of
     * the pair's. */
    r = regions_ok(&a, &ref, NULL, NULL, 1.25, 8);
    cr_assert_eq(metrics_regions_noise(&a, NULL, &ref, &ref2, 4.0, &r, &err), 0, "%s", err.msg);
    cr_expect(fabs(r.sigma_rms / (want / sqrt(2.0)) - 1.0) < 0.05, "sigma_rms %g with the reference's only",
              r.sigma_rms);
    cr_assert_eq(metrics_regions_noise(&a, NULL, &ref, NULL, 4.0, &r, &err), CT_EINVAL);
    ct_image small = make(8, 8, 1, 1, 1);
    cr_assert_eq(metrics_regions_noise(&a, &small, &ref, NULL, 4.0, &r, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "sizes differ"), "%s", err.msg);
    metrics_regions_free(&r);
    img_free(&small);
    img_free(&a);
    img_free(&a2);
    img_free(&ref);
    img_free(&ref2);
}
