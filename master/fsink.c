/* fsink.c: the files sink (fsink.h). */
#include "master/fsink.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/metrics.h"
#include "common/timer.h"

#define COMPONENT "corrtex converge"

struct fsink {
    fsink_config c;
    fs_atomic csv_at;
    FILE *csv;
    char csv_path[4096];
    const ctex_hit *hits;
    int spp;               /* hits per pixel */
    ct_image ref;          /* the phase's reference (px NULL when none) */
    metrics_ref *ref_prep; /* ref prepared for the phase's checkpoints */
    ct_image comp, hq, aux;
    uint8_t *covered;      /* pixel has a sample of the current phase */
    char phase[32], prefix[32];
    long done;             /* samples of the phase so far */
    double t0;
    double io;          /* seconds spent in earlier checkpoints (compositing, writing) */
};

int fsink_new(const fsink_config *c, fsink **out, ct_error *err)
{
    *out = NULL;
    fsink *k = calloc(1, sizeof *k);
    if (!k) return ct_fail(err, CT_ENOMEM, "out of memory");
    k->c = *c;
    k->t0 = ct_now();
    size_t npx = (size_t)c->width * (size_t)c->height;
    int rc = (k->covered = calloc(npx, 1)) ? CT_OK : ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d run",
                                                              c->width, c->height);
    if (!rc) rc = img_alloc(&k->comp, c->width, c->height, err);
    if (!rc) rc = img_alloc(&k->hq, c->width, c->height, err);
    if (!rc) rc = img_alloc(&k->aux, c->width, c->height, err);
    fs_join(c->out, "convergence.csv", k->csv_path, sizeof k->csv_path);
    if (!rc) rc = fs_atomic_open(&k->csv_at, k->csv_path, err);
    if (rc) {
        fsink_free(k);
        return rc;
    }
    k->csv = k->csv_at.f;
    fprintf(k->csv, "phase,samples,percent_pixels,coverage,rmse,psnr,ssim,textures,texels,"
                    "splat_radius_mean,rmse_vs_samples,psnr_vs_samples,seconds,sampling_seconds\n");
    *out = k;
    return CT_OK;
}

void fsink_free(fsink *k)
{
    if (!k) return;
    if (k->csv) fs_atomic_abort(&k->csv_at);
    metrics_ref_free(k->ref_prep);
    img_free(&k->ref);
    img_free(&k->comp);
    img_free(&k->hq);
    img_free(&k->aux);
    free(k->covered);
    free(k);
}

static void path_of(const fsink *k, const char *stem, const char *ext, char *out, size_t cap)
{
    char name[256];
    snprintf(name, sizeof name, "%s%s", stem, ext);
    fs_join(k->c.out, name, out, cap);
}

static int write_pair(fsink *k, const ct_image *img, const char *stem, ct_error *err)
{
    char path[4096];
    path_of(k, stem, ".exr", path, sizeof path);
    int rc = img_write_exr(path, img, IMG_HALF, err);
    if (rc) return rc;
    path_of(k, stem, ".png", path, sizeof path);
    return img_write_png(path, img, k->c.exposure, err);
}

int fsink_assignment(fsink *k, sess *s, const char *stem, ct_error *err)
{
    const ctex *c = sess_textures(s);
    for (int y = 0; y < k->c.height; y++)
        for (int x = 0; x < k->c.width; x++) {
            /* a pixel's first hit: the debug view needs no antialiasing */
            const ctex_hit *h = &k->hits[((size_t)y * (size_t)k->c.width + (size_t)x) * (size_t)k->spp];
            vec3 col = v3s(0.0f);
            if (h->node != UINT32_MAX) {
                float l = img_tonemap(v3_luminance(h->l_base), k->c.exposure);
                int32_t id = ctex_owner(c, h->node, h->tri, h->p);
                vec3 base = id >= 0 ? ctex_debug_color(id) : v3s(0.25f);
                col = v3_scale(base, 0.3f + 0.7f * l);
            }
            img_set(&k->aux, x, y, col);
        }
    char path[4096];
    path_of(k, stem, ".png", path, sizeof path);
    return img_write_png(path, &k->aux, 0.0f, err);
}

/* Fig. 7 right: the phase's samples in red over the dimmed corrected image. */
static int write_samples(fsink *k, const char *stem, ct_error *err)
{
    for (int y = 0; y < k->c.height; y++)
        for (int x = 0; x < k->c.width; x++) {
            size_t i = (size_t)y * (size_t)k->c.width + (size_t)x;
            float l = img_tonemap(v3_luminance(img_get(&k->comp, x, y)), k->c.exposure);
            img_set(&k->aux, x, y, k->covered[i] ? v3(1, 0, 0) : v3s(0.25f * l));
        }
    char path[4096];
    path_of(k, stem, ".png", path, sizeof path);
    return img_write_png(path, &k->aux, 0.0f, err);
}

/* RMSE (linear) and PSNR (sRGB) of the composite against the samples' own
 * high-quality values, over the pixels that have a sample. */
static void vs_samples(const fsink *k, double *rmse, double *psnr)
{
    double se = 0.0, se8 = 0.0;
    size_t n = 0;
    for (int y = 0; y < k->c.height; y++)
        for (int x = 0; x < k->c.width; x++) {
            if (!k->covered[(size_t)y * (size_t)k->c.width + (size_t)x]) continue;
            vec3 a = img_get(&k->comp, x, y), b = img_get(&k->hq, x, y);
            for (int j = 0; j < 3; j++) {
                double d = (double)v3_get(a, j) - (double)v3_get(b, j);
                double d8 = (double)img_tonemap(v3_get(a, j), 0.0f) - (double)img_tonemap(v3_get(b, j), 0.0f);
                se += d * d;
                se8 += d8 * d8;
            }
            n += 3;
        }
    *rmse = n ? sqrt(se / (double)n) : NAN;
    *psnr = n ? (se8 > 0.0 ? 10.0 * log10((double)n / se8) : INFINITY) : NAN;
}

static void csv_num(FILE *f, double v, int last)
{
    if (isfinite(v)) fprintf(f, "%.6g", v);
    else if (isinf(v)) fprintf(f, "inf");
    fputc(last ? '\n' : ',', f);
}

/* A checkpoint: composite, images, metrics, CSV row. */
static int checkpoint(fsink *k, sess *s, const char *phase, const char *stem, long samples, int sample_img,
                      ct_error *err)
{
    double reached = ct_now();
    const ctex *c = sess_textures(s);
    int rc = ctex_composite(c, k->hits, k->spp, k->c.width, k->c.height, &k->comp, err);
    if (rc || (rc = write_pair(k, &k->comp, stem, err))) return rc;
    if (sample_img) {
        char sstem[256];
        snprintf(sstem, sizeof sstem, "%ssamples_%ld", k->prefix, samples);
        if ((rc = write_samples(k, sstem, err))) return rc;
    }
    img_metrics m = {NAN, NAN, NAN, NAN};
    if (k->ref_prep && (rc = metrics_compare_ref(&k->comp, k->ref_prep, METRICS_SSIM, &m, err))) return rc;
    double vr, vp;
    vs_samples(k, &vr, &vp);
    ctex_stats st = ctex_get_stats(c);
    rq_stats qs;
    sess_queue_stats(s, &qs);
    double coverage = samples ? qs.coverage : 0.0;
    double pct = 100.0 * (double)samples / ((double)k->c.width * (double)k->c.height);
    fprintf(k->csv, "%s,%ld,", phase, samples);
    csv_num(k->csv, pct, 0);
    csv_num(k->csv, 100.0 * coverage, 0);
    csv_num(k->csv, m.rmse, 0);
    csv_num(k->csv, m.psnr, 0);
    csv_num(k->csv, m.ssim, 0);
    fprintf(k->csv, "%u,%llu,", st.textures, (unsigned long long)st.texels);
    csv_num(k->csv, st.splat_radius_mean, 0);
    csv_num(k->csv, vr, 0);
    csv_num(k->csv, vp, 0);
    csv_num(k->csv, ct_now() - k->t0, 0);
    csv_num(k->csv, reached - k->t0 - k->io, 1);
    ct_info(COMPONENT, "%s %ld samples (%.3f%% of pixels, coverage %.1f%%): rmse %.5g psnr %.2f dB, "
            "%u textures, %llu texels, splat radius %.2f, vs samples rmse %.5g",
            phase, samples, pct, 100.0 * coverage, m.rmse, m.psnr, st.textures, (unsigned long long)st.texels,
            st.splat_radius_mean, vr);
    if (m.rmse == m.rmse)
        printf("metric: %s_%ld_rmse=%.6g\nmetric: %s_%ld_psnr=%.4f\n", phase, samples, m.rmse, phase, samples, m.psnr);
    if (vr == vr) printf("metric: %s_%ld_vs_samples_rmse=%.6g\n", phase, samples, vr);
    k->io += ct_now() - reached;
    return CT_OK;
}

/* The samples of the phase: where they are, their high-quality values. */
static void on_samples(void *user, const ct_sample *s, uint32_t n)
{
    fsink *k = user;
    for (uint32_t i = 0; i < n; i++) {
        int x = (int)floorf(s[i].px), y = (int)floorf(s[i].py);
        if (x < 0 || y < 0 || x >= k->c.width || y >= k->c.height) continue;
        k->covered[(size_t)y * (size_t)k->c.width + (size_t)x] = 1;
        img_set(&k->hq, x, y, s[i].l_hq);
    }
}

static int on_frame(void *user, sess *s, const sink_frame *f, ct_error *err)
{
    fsink *k = user;
    k->done += f->samples;
    ctex_events_clear(sess_textures(s));   /* no display: the events go nowhere */
    char stem[256];
    snprintf(stem, sizeof stem, "%scorrected_%ld", k->prefix, k->done);
    return checkpoint(k, s, k->phase, stem, k->done, 1, err);
}

sink fsink_sink(fsink *k)
{
    return (sink){k, on_samples, on_frame};
}

int fsink_phase(fsink *k, const char *phase, const char *prefix, const ctex_hit *hits, int spp, const char *ref,
                ct_error *err)
{
    snprintf(k->phase, sizeof k->phase, "%s", phase);
    snprintf(k->prefix, sizeof k->prefix, "%s", prefix);
    k->hits = hits;
    k->spp = spp;
    k->done = 0;
    memset(k->covered, 0, (size_t)k->c.width * (size_t)k->c.height);
    metrics_ref_free(k->ref_prep);
    k->ref_prep = NULL;
    img_free(&k->ref);
    if (!ref) return CT_OK;
    int rc = img_read_exr(ref, &k->ref, err);
    if (rc) return rc;
    if (k->ref.width != k->c.width || k->ref.height != k->c.height)
        return ct_fail(err, CT_EINVAL, "%s is %dx%d, the run is %dx%d", ref, k->ref.width, k->ref.height, k->c.width,
                       k->c.height);
    if ((rc = metrics_ref_new(&k->ref, &k->ref_prep, err))) ct_error_prefix(err, ref);
    return rc;
}

int fsink_snapshot(fsink *k, sess *s, const char *name, ct_error *err)
{
    ctex_events_clear(sess_textures(s));
    return checkpoint(k, s, name, name, 0, 0, err);
}

int fsink_end_phase(fsink *k, ct_error *err)
{
    char path[4096], stem[64];
    snprintf(stem, sizeof stem, "%shq_samples", k->prefix);
    path_of(k, stem, ".exr", path, sizeof path);
    return img_write_exr(path, &k->hq, IMG_FLOAT, err);
}

int fsink_commit(fsink *k, const char **path, ct_error *err)
{
    int rc = fs_atomic_commit(&k->csv_at, err);
    k->csv = NULL;
    if (path) *path = k->csv_path;
    return rc;
}
