/* corrtex compare A.exr B.exr: image error metrics of A against reference B
 * (docs/images.md defines them). Exit 0 ok, 1 when --max-rmse is exceeded,
 * 2 on bad input or usage. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "cli/corrtex/commands.h"
#include "common/image.h"
#include "common/log.h"
#include "common/metrics.h"

#define COMPONENT "corrtex compare"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: corrtex compare A.exr B.exr [--json] [--max-rmse X]\n"
            "Compares image A against the reference B (same size, R G B channels).\n"
            "Metrics: rmse and rel_mse on linear RGB; psnr (dB) and ssim on sRGB values\n"
            "(exposure 0, clamped to [0,1]); see docs/images.md.\n\n"
            "options:\n"
            "  --json          print one JSON object {rmse, rel_mse, psnr, ssim, width, height}\n"
            "                  (psnr is null when the images are identical)   default: off\n"
            "  --max-rmse X    exit 1 when rmse > X (X >= 0)                  default: no limit\n"
            "  -h, --help      this help\n"
            "exit status: 0 ok, 1 rmse above --max-rmse, 2 bad input or usage\n");
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
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0}
    };
    int json = 0, have_max = 0;
    double max_rmse = 0.0;
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
    ct_image a, b;
    ct_error err;
    if (img_read_exr(pa, &a, &err)) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return 2;
    }
    if (img_read_exr(pb, &b, &err)) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        img_free(&a);
        return 2;
    }
    img_metrics m;
    int rc = metrics_compare(&a, &b, &m, &err);
    int w = a.width, h = a.height;
    img_free(&a);
    img_free(&b);
    if (rc) {
        ct_error_prefix(&err, pa);
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return 2;
    }
    if (json) {
        printf("{");
        json_num("rmse", m.rmse, 0);
        json_num("rel_mse", m.rel_mse, 0);
        json_num("psnr", m.psnr, 0);
        json_num("ssim", m.ssim, 0);
        printf("\"width\":%d,\"height\":%d}\n", w, h);
    } else {
        printf("rmse %.6g\n", m.rmse);
        printf("rel_mse %.6g\n", m.rel_mse);
        printf("psnr %.4f dB\n", m.psnr);
        printf("ssim %.6f\n", m.ssim);
        printf("size %dx%d\n", w, h);
    }
    fflush(stdout);
    if (have_max && m.rmse > max_rmse) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s: rmse %.6g exceeds --max-rmse %.6g", pa, m.rmse, max_rmse);
        return 1;
    }
    return 0;
}
