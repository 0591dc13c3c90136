/* corrtex compare A.exr B.exr: image error metrics of A against reference B
 * (docs/images.md defines them). Exit 0 ok, 1 when --max-rmse is exceeded,
 * 2 on bad input or usage. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "cli/corrtex/commands.h"
#include "common/image.h"
#include "common/log.h"
#include "common/metrics.h"
#include "common/optab.h"

#define COMPONENT "corrtex compare"

typedef struct compare_opts {
    bool json;
    double max_rmse;   /* < 0: no limit */
} compare_opts;

#define OF(f) offsetof(compare_opts, f)
static const optab OPTS[] = {
    {"json", 0, OPTAB_FLAG, OF(json), 0, 0, NULL, NULL,
     "print one JSON object {rmse, rel_mse, psnr, ssim, width, height} (psnr is null when the images are "
     "identical)", NULL},
    {"max-rmse", 0, OPTAB_DOUBLE, OF(max_rmse), 0, 1e300, NULL, "X", "exit 1 when rmse > X (default: no limit)", NULL},
};
#undef OF

static void usage(FILE *f)
{
    fprintf(f,
            "usage: corrtex compare A.exr B.exr [--json] [--max-rmse X]\n"
            "Compares image A against the reference B (same size, R G B channels).\n"
            "Metrics: rmse and rel_mse on linear RGB; psnr (dB) and ssim on sRGB values\n"
            "(exposure 0, clamped to [0,1]); see docs/images.md.\n\n"
            "options:\n");
    optab_usage(OPTS, OPTAB_COUNT(OPTS), NULL, f);
    fprintf(f, "  -h, --help                   this help\n"
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
    compare_opts o;
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), &o, &err);
    o.max_rmse = -1.0;
    optab_group g = {OPTS, OPTAB_COUNT(OPTS), &o};
    const char *pos[2];
    int npos = 0, prc = optab_parse(&g, 1, argc, argv, pos, 2, &npos, &err);
    if (prc == 1) {
        usage(stdout);
        return 0;
    }
    if (prc) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return 2;
    }
    if (npos != 2) {
        ct_log(CT_LOG_ERROR, COMPONENT, "expected two images A.exr B.exr, got %d (try --help)", npos);
        return 2;
    }
    const char *pa = pos[0], *pb = pos[1];
    ct_image a, b;
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
    if (o.json) {
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
    if (o.max_rmse >= 0.0 && m.rmse > o.max_rmse) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s: rmse %.6g exceeds --max-rmse %.6g", pa, m.rmse, o.max_rmse);
        return 1;
    }
    return 0;
}
