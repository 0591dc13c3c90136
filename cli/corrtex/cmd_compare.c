/* corrtex compare A.exr B.exr: image error metrics of A against reference B
 * (docs/images.md defines them). Exit 0 ok, 1 when --max-rmse is exceeded,
 * 2 on bad input or usage. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/corrtex/commands.h"
#include "common/image.h"
#include "common/log.h"
#include "common/metrics.h"

#define COMPONENT "corrtex compare"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: corrtex compare A.exr B.exr [--json] [--max-rmse X]\n"
            "                       [--regions S [--planes P.exr [--planes-margin M]]\n"
            "                        [--flat F.exr [--flat-ratio R]]\n"
            "                        [--max-region-error X] [--region-table]]\n"
            "Compares image A against the reference B (same size, R G B channels).\n"
            "Metrics: rmse and rel_mse on linear RGB; psnr (dB) and ssim on sRGB values\n"
            "(exposure 0, clamped to [0,1]); see docs/images.md.\n\n"
            "options:\n"
            "  --json          print one JSON object {rmse, rel_mse, psnr, ssim, width, height}\n"
            "                  (psnr is null when the images are identical)   default: off\n"
            "  --max-rmse X    exit 1 when rmse > X (X >= 0)                  default: no limit\n"
            "  --regions S     also compare the means of S x S pixel blocks: regions (blocks\n"
            "                  counted), region_worst (largest |mean(A) / mean(B) - 1|, at\n"
            "                  region_worst_at column row) and region_rms; a block counts where\n"
            "                  B's mean is positive and the masks below agree    default: off\n"
            "  --planes P.exr  count only blocks lying on one flat surface: one non-zero value\n"
            "                  of P at every pixel (corrtex radiosity --image-planes)\n"
            "  --planes-margin M  ... and at every pixel within M pixels of the block: away\n"
            "                  from the surface's edges                          default: 0\n"
            "  --flat F.exr    count only blocks where F's pixel means vary by at most (R - 1)\n"
            "                  x B's block mean (F the direct light: no shadow boundary inside)\n"
            "  --flat-ratio R  R of --flat (R >= 1)                           default: 1.25\n"
            "  --max-region-error X  exit 1 when region_worst > X            default: no limit\n"
            "  --region-table  print the block ratios, row by row ('.' for a block not counted)\n"
            "  -h, --help      this help\n"
            "exit status: 0 ok, 1 rmse above --max-rmse (or region_worst above\n"
            "--max-region-error), 2 bad input or usage\n");
}

/* Parses a number in [lo, hi] into *v; logs and returns 1 when it is not one. */
static int number(const char *arg, const char *opt, double lo, double hi, double *v)
{
    char *end = NULL;
    *v = strtod(arg, &end);
    if (end == arg || *end || !isfinite(*v) || *v < lo || *v > hi) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s: '%s' is not a number in [%g, %g]", opt, arg, lo, hi);
        return 1;
    }
    return 0;
}

/* Prints a double for JSON: 17 significant digits, null when not finite. */
static void json_num(const char *key, double v, int last)
{
    if (isfinite(v)) printf("\"%s\":%.17g%s", key, v, last ? "" : ",");
    else printf("\"%s\":null%s", key, last ? "" : ",");
}

int cmd_compare(int argc, char **argv)
{
    static const struct option opts[] = {
        {"json", no_argument, NULL, 'j'},
        {"max-rmse", required_argument, NULL, 'm'},
        {"regions", required_argument, NULL, 'r'},
        {"planes", required_argument, NULL, 'p'},
        {"planes-margin", required_argument, NULL, 'g'},
        {"flat", required_argument, NULL, 'f'},
        {"flat-ratio", required_argument, NULL, 'F'},
        {"max-region-error", required_argument, NULL, 'M'},
        {"region-table", no_argument, NULL, 't'},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0}
    };
    int json = 0, have_max = 0, have_max_region = 0, regions = 0, table = 0, margin = 0;
    double max_rmse = 0.0, max_region = 0.0, flat_ratio = 1.25, v;
    const char *planes_path = NULL, *flat_path = NULL;
    optind = 1;
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        switch (c) {
        case 'j': json = 1; break;
        case 'm': {
            char *end = NULL;
            max_rmse = strtod(optarg, &end);
            if (end == optarg || *end || !isfinite(max_rmse) || max_rmse < 0.0) {
                ct_log(CT_LOG_ERROR, COMPONENT, "--max-rmse: '%s' is not a number >= 0", optarg);
                return 2;
            }
            have_max = 1;
            break;
        }
        case 'r':
            if (number(optarg, "--regions", 1.0, 65536.0, &v)) return 2;
            regions = (int)v;
            if (regions != v) {
                ct_log(CT_LOG_ERROR, COMPONENT, "--regions: '%s' is not a whole number", optarg);
                return 2;
            }
            break;
        case 'p': planes_path = optarg; break;
        case 'g':
            if (number(optarg, "--planes-margin", 0.0, 65536.0, &v)) return 2;
            margin = (int)v;
            break;
        case 'f': flat_path = optarg; break;
        case 'F':
            if (number(optarg, "--flat-ratio", 1.0, HUGE_VAL, &flat_ratio)) return 2;
            break;
        case 'M':
            if (number(optarg, "--max-region-error", 0.0, HUGE_VAL, &max_region)) return 2;
            have_max_region = 1;
            break;
        case 't': table = 1; break;
        case 'h': usage(stdout); return 0;
        default:
            ct_log(CT_LOG_ERROR, COMPONENT, "unknown or incomplete option '%s' (try --help)",
                   argv[optind - 1]);
            return 2;
        }
    }
    if (argc - optind != 2) {
        ct_log(CT_LOG_ERROR, COMPONENT, "expected two images A.exr B.exr, got %d (try --help)",
               argc - optind);
        return 2;
    }
    const char *pa = argv[optind], *pb = argv[optind + 1];
    if ((planes_path || flat_path || have_max_region || table || margin) && !regions) {
        ct_log(CT_LOG_ERROR, COMPONENT, "--planes, --flat, --max-region-error and --region-table need --regions");
        return 2;
    }
    /* a, b, then the masks: read in order, freed together. */
    const char *paths[4] = {pa, pb, planes_path, flat_path};
    ct_image img[4];
    memset(img, 0, sizeof img);
    ct_error err;
    int rc = CT_OK;
    for (int i = 0; i < 4 && !rc; i++)
        if (paths[i]) rc = img_read_exr(paths[i], &img[i], &err);
    img_metrics m;
    img_regions reg;
    memset(&reg, 0, sizeof reg);
    if (!rc) {
        rc = metrics_compare(&img[0], &img[1], &m, &err);
        if (rc) ct_error_prefix(&err, pa);
    }
    if (!rc && regions)
        rc = metrics_regions(&img[0], &img[1], planes_path ? &img[2] : NULL, margin, flat_path ? &img[3] : NULL,
                             flat_ratio, regions, &reg, &err);
    int w = img[0].width, h = img[0].height;
    for (int i = 0; i < 4; i++) img_free(&img[i]);
    if (rc) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        metrics_regions_free(&reg);
        return 2;
    }
    if (json) {
        printf("{");
        json_num("rmse", m.rmse, 0);
        json_num("rel_mse", m.rel_mse, 0);
        json_num("psnr", m.psnr, 0);
        json_num("ssim", m.ssim, 0);
        if (regions) {
            printf("\"regions\":%d,", reg.counted);
            json_num("region_worst", reg.worst, 0);
            json_num("region_rms", reg.rms, 0);
        }
        printf("\"width\":%d,\"height\":%d}\n", w, h);
    } else {
        printf("rmse %.6g\n", m.rmse);
        printf("rel_mse %.6g\n", m.rel_mse);
        printf("psnr %.4f dB\n", m.psnr);
        printf("ssim %.6f\n", m.ssim);
        printf("size %dx%d\n", w, h);
        if (regions) {
            printf("regions %d\n", reg.counted);
            printf("region_worst %.6g\n", reg.worst);
            printf("region_worst_at %d %d\n", reg.worst_x, reg.worst_y);
            printf("region_rms %.6g\n", reg.rms);
        }
        if (table)
            for (int y = 0; y < reg.ny; y++) {
                for (int x = 0; x < reg.nx; x++) {
                    float q = reg.ratio[y * reg.nx + x];
                    if (isnan(q)) printf("     .");
                    else printf(" %5.3f", q);
                }
                printf("\n");
            }
    }
    fflush(stdout);
    metrics_regions_free(&reg);
    if (have_max && m.rmse > max_rmse) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s: rmse %.6g exceeds --max-rmse %.6g", pa, m.rmse, max_rmse);
        return 1;
    }
    if (have_max_region && reg.worst > max_region) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s: region mean off by %.4g (block %d %d) above --max-region-error %.6g",
               pa, reg.worst, reg.worst_x, reg.worst_y, max_region);
        return 1;
    }
    return 0;
}
