/* corrtex compare A.exr B.exr: image error metrics of A against reference B
 * (docs/images.md defines them), and with --regions the means of pixel
 * blocks, where a bias on small or dark regions shows that a whole-image
 * error hides under the reference's noise; with repeats of A or B (another
 * seed) each block's deviation in its own standard errors. Exit 0 ok, 1
 * when --max-rmse, --max-region-error or --max-region-sigma is exceeded, 2
 * on bad input or usage. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/corrtex/commands.h"
#include "common/image.h"
#include "common/log.h"
#include "common/metrics.h"
#include "common/optab.h"

#define COMPONENT "corrtex compare"

typedef struct compare_opts {
    bool json, table, ztable;
    double max_rmse;     /* < 0: no limit */
    double max_region;   /* < 0: no limit */
    double max_sigma;    /* < 0: no limit */
    int regions, margin;
    double flat_ratio, sigmas;
    const char *planes, *flat, *repeat_a, *repeat_b;
} compare_opts;

#define OF(f) offsetof(compare_opts, f)
static const optab OPTS[] = {
    {"json", 0, OPTAB_FLAG, OF(json), 0, 0, NULL, NULL,
     "print one JSON object {rmse, rel_mse, psnr, ssim, width, height} (psnr is null when the images are "
     "identical)", NULL},
    {"max-rmse", 0, OPTAB_DOUBLE, OF(max_rmse), 0, 1e300, NULL, "X", "exit 1 when rmse > X (default: no limit)", NULL},
    {"regions", 0, OPTAB_INT, OF(regions), 1, 65536, NULL, "S",
     "also compare the means of S x S pixel blocks: regions (blocks counted), region_worst (largest "
     "|mean(A) / mean(B) - 1|, at region_worst_at column row) and region_rms; a block counts where B's mean is "
     "positive and the masks below agree (default: off)", NULL},
    {"planes", 0, OPTAB_STRING, OF(planes), 0, 0, NULL, "P.exr",
     "count only blocks lying on one flat surface: one non-zero value of P at every pixel (corrtex radiosity "
     "--image-planes)", NULL},
    {"planes-margin", 0, OPTAB_INT, OF(margin), 0, 65536, "0", "M",
     "... and at every pixel within M pixels of the block: away from the surface's edges", NULL},
    {"flat", 0, OPTAB_STRING, OF(flat), 0, 0, NULL, "F.exr",
     "count only blocks where F's pixel means vary by at most (R - 1) x B's block mean (F the direct light: no "
     "shadow boundary inside)", NULL},
    {"flat-ratio", 0, OPTAB_DOUBLE, OF(flat_ratio), 1, 1e300, "1.25", "R", "R of --flat", NULL},
    {"max-region-error", 0, OPTAB_DOUBLE, OF(max_region), 0, 1e300, NULL, "X",
     "exit 1 when region_worst > X (default: no limit)", NULL},
    {"region-table", 0, OPTAB_FLAG, OF(table), 0, 0, NULL, NULL,
     "print the block ratios, row by row ('.' for a block not counted)", NULL},
    {"repeat-a", 0, OPTAB_STRING, OF(repeat_a), 0, 0, NULL, "A2.exr",
     "A rendered again with another seed: its difference to A gives the noise of A's block means", NULL},
    {"repeat-b", 0, OPTAB_STRING, OF(repeat_b), 0, 0, NULL, "B2.exr",
     "B rendered again with another seed, the same for B; with either: region_sigma_rms (the blocks' relative "
     "standard error: what region_rms reads without any bias), region_z_worst (the largest |ratio - 1| in a "
     "block's own standard errors, at region_z_worst_at) and region_beyond (blocks beyond --sigmas)", NULL},
    {"sigmas", 0, OPTAB_DOUBLE, OF(sigmas), 0, 1e300, "4", "S", "the bound of region_beyond, in standard errors",
     NULL},
    {"max-region-sigma", 0, OPTAB_DOUBLE, OF(max_sigma), 0, 1e300, NULL, "Z",
     "exit 1 when region_z_worst > Z (default: no limit)", NULL},
    {"z-table", 0, OPTAB_FLAG, OF(ztable), 0, 0, NULL, NULL,
     "print every block's z, (ratio - 1) in its standard errors, row by row", NULL},
};
#undef OF

static void usage(FILE *f)
{
    fprintf(f,
            "usage: corrtex compare A.exr B.exr [--json] [--max-rmse X]\n"
            "                       [--regions S [--planes P.exr [--planes-margin M]]\n"
            "                        [--flat F.exr [--flat-ratio R]]\n"
            "                        [--max-region-error X] [--region-table]\n"
            "                        [--repeat-a A2.exr] [--repeat-b B2.exr] [--sigmas S]\n"
            "                        [--max-region-sigma Z] [--z-table]]\n"
            "Compares image A against the reference B (same size, R G B channels).\n"
            "Metrics: rmse and rel_mse on linear RGB; psnr (dB) and ssim on sRGB values\n"
            "(exposure 0, clamped to [0,1]); see docs/images.md.\n\n"
            "options:\n");
    optab_usage(OPTS, OPTAB_COUNT(OPTS), NULL, f);
    fprintf(f, "  -h, --help                   this help\n"
               "exit status: 0 ok, 1 rmse above --max-rmse (or region_worst above\n"
               "--max-region-error, region_z_worst above --max-region-sigma), 2 bad\n"
               "input or usage\n");
}

/* Prints a double for JSON: 17 significant digits, null when not finite. */
static void json_num(const char *key, double v, int last)
{
    if (isfinite(v)) printf("\"%s\":%.17g%s", key, v, last ? "" : ",");
    else printf("\"%s\":null%s", key, last ? "" : ",");
}

static void print_table(const img_regions *reg, const float *v, const char *fmt)
{
    for (int y = 0; y < reg->ny; y++) {
        for (int x = 0; x < reg->nx; x++) {
            float q = v[y * reg->nx + x];
            if (isnan(q)) printf("     .");
            else printf(fmt, q);
        }
        printf("\n");
    }
}

static void print_text(const img_metrics *m, const img_regions *reg, int regions, const compare_opts *o, int w,
                       int h)
{
    printf("rmse %.6g\n", m->rmse);
    printf("rel_mse %.6g\n", m->rel_mse);
    printf("psnr %.4f dB\n", m->psnr);
    printf("ssim %.6f\n", m->ssim);
    printf("size %dx%d\n", w, h);
    if (regions) {
        printf("regions %d\n", reg->counted);
        printf("region_worst %.6g\n", reg->worst);
        printf("region_worst_at %d %d\n", reg->worst_x, reg->worst_y);
        printf("region_rms %.6g\n", reg->rms);
    }
    if (reg->z) {
        printf("region_sigma_rms %.6g\n", reg->sigma_rms);
        printf("region_z_worst %.4g\n", reg->z_worst);
        printf("region_z_worst_at %d %d\n", reg->z_worst_x, reg->z_worst_y);
        printf("region_beyond %d\n", reg->beyond);
    }
    if (o->table) print_table(reg, reg->ratio, " %5.3f");
    if (o->ztable && reg->z) print_table(reg, reg->z, " %5.1f");
}

int cmd_compare(int argc, char **argv)
{
    compare_opts o;
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), &o, &err);
    o.max_rmse = -1.0;
    o.max_region = -1.0;
    o.max_sigma = -1.0;
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
    if ((o.planes || o.flat || o.max_region >= 0.0 || o.table || o.margin || o.repeat_a || o.repeat_b) &&
        !o.regions) {
        ct_log(CT_LOG_ERROR, COMPONENT,
               "--planes, --flat, --max-region-error, --region-table and the repeats need --regions");
        return 2;
    }
    if ((o.max_sigma >= 0.0 || o.ztable || optab_given(&g, 1, argc, argv, "sigmas")) && !o.repeat_a &&
        !o.repeat_b) {
        ct_log(CT_LOG_ERROR, COMPONENT, "--sigmas, --max-region-sigma and --z-table need --repeat-a or --repeat-b");
        return 2;
    }
    /* a, b, the masks, then the repeats: read in order, freed together. */
    enum { NIMG = 6 };
    const char *paths[NIMG] = {pa, pb, o.planes, o.flat, o.repeat_a, o.repeat_b};
    ct_image img[NIMG];
    memset(img, 0, sizeof img);
    int rc = CT_OK;
    for (int i = 0; i < NIMG && !rc; i++)
        if (paths[i]) rc = img_read_exr(paths[i], &img[i], &err);
    img_metrics m;
    img_regions reg;
    memset(&reg, 0, sizeof reg);
    if (!rc) {
        rc = metrics_compare(&img[0], &img[1], &m, &err);
        if (rc) ct_error_prefix(&err, pa);
    }
    if (!rc && o.regions)
        rc = metrics_regions(&img[0], &img[1], o.planes ? &img[2] : NULL, o.margin, o.flat ? &img[3] : NULL,
                             o.flat_ratio, o.regions, &reg, &err);
    if (!rc && (o.repeat_a || o.repeat_b)) {
        rc = metrics_regions_noise(&img[0], o.repeat_a ? &img[4] : NULL, &img[1], o.repeat_b ? &img[5] : NULL,
                                   o.sigmas, &reg, &err);
        if (rc) ct_error_prefix(&err, o.repeat_a ? o.repeat_a : o.repeat_b);
    }
    int w = img[0].width, h = img[0].height;
    for (int i = 0; i < NIMG; i++) img_free(&img[i]);
    if (rc) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        metrics_regions_free(&reg);
        return 2;
    }
    if (o.json) {
        printf("{");
        json_num("rmse", m.rmse, 0);
        json_num("rel_mse", m.rel_mse, 0);
        json_num("psnr", m.psnr, 0);
        json_num("ssim", m.ssim, 0);
        if (o.regions) {
            printf("\"regions\":%d,", reg.counted);
            json_num("region_worst", reg.worst, 0);
            json_num("region_rms", reg.rms, 0);
        }
        if (reg.z) {
            json_num("region_sigma_rms", reg.sigma_rms, 0);
            json_num("region_z_worst", reg.z_worst, 0);
            printf("\"region_beyond\":%d,", reg.beyond);
        }
        printf("\"width\":%d,\"height\":%d}\n", w, h);
    } else {
        print_text(&m, &reg, o.regions, &o, w, h);
    }
    fflush(stdout);
    double z_worst = reg.z_worst;
    int zx = reg.z_worst_x, zy = reg.z_worst_y;
    metrics_regions_free(&reg);
    if (o.max_rmse >= 0.0 && m.rmse > o.max_rmse) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s: rmse %.6g exceeds --max-rmse %.6g", pa, m.rmse, o.max_rmse);
        return 1;
    }
    if (o.max_region >= 0.0 && reg.worst > o.max_region) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s: region mean off by %.4g (block %d %d) above --max-region-error %.6g",
               pa, reg.worst, reg.worst_x, reg.worst_y, o.max_region);
        return 1;
    }
    if (o.max_sigma >= 0.0 && z_worst > o.max_sigma) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s: a region mean off by %.3g of its standard errors (block %d %d) above "
               "--max-region-sigma %.6g", pa, z_worst, zx, zy, o.max_sigma);
        return 1;
    }
    return 0;
}
