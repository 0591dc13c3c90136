/* corrtex converge: the master engine (request queue + corrective textures)
 * and the tracer library in one process, for a still camera: traces samples
 * chosen by the adaptive queue (§3.7), splats them (§3.4) and writes, at
 * each checkpoint, the corrected image the display would draw (software
 * compositor), the sample positions (Fig. 7 right), the texture assignment
 * (Fig. 5) and a row of convergence.csv. --move-to moves the camera without
 * updates and traces more samples (Fig. 7). Exit 0 ok, 2 bad input or usage. */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "cli/corrtex/commands.h"
#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/metrics.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/timer.h"
#include "master/ctex.h"
#include "master/sampler.h"
#include "tracer/radiosity.h"
#include "tracer/tracer.h"

#define COMPONENT "corrtex converge"
#define MAX_CHECKPOINTS 64
#define CK_ALL (-1L)   /* "all": until every pixel has been sampled */

static void usage(FILE *f)
{
    fprintf(f,
            "usage: corrtex converge SCENE --samples N[,N2,...] --out DIR [options]\n"
            "Runs the master (request queue + corrective textures) and the tracer in one\n"
            "process for a still camera and writes, at each checkpoint N (total samples;\n"
            "'all' = until every pixel is sampled): corrected_N.exr/.png (the image the\n"
            "display draws), samples_N.png (sample positions), assignment.png (textures,\n"
            "Fig. 5), hq_samples.exr (each sampled pixel's high-quality value) and a row of\n"
            "convergence.csv. radiosity.exr/.png is the interactive solution alone.\n\n"
            "options:\n"
            "  --camera NAME          scene camera                       default: the first\n"
            "  --samples LIST         checkpoints, increasing (required)\n"
            "  --mode M               drt | reuse-diffuse | path         default: drt\n"
            "  --width W --height H   image size                         default: 512 x 512\n"
            "  --reference REF.exr    reference for RMSE/PSNR/SSIM       default: none\n"
            "  --out DIR              output folder (required)\n"
            "  --move-to NAME         then move to this camera without updates (moved.exr) ...\n"
            "  --samples-after LIST   ... and trace these many more samples (after_*.png)\n"
            "  --reference-after REF  reference for the moved camera     default: none\n"
            "  --mesh FILE.ctmesh     radiosity cache: loaded when it holds this scene's solution,\n"
            "                         else solved (default parameters) and written there\n"
            "                                                            default: solve, no cache\n"
            "  --stand-in A           interactive solution: the constant stand-in (emission +\n"
            "                         diffuse x A per material) instead of radiosity (tests)\n"
            "                                                            default: off\n"
            "  --batch B              requests per batch                 default: 256\n"
            "  --threads T            tracing threads                    default: 2\n"
            "  --seed S               seed of the queue and the tracer   default: 1\n"
            "  --shadow-rays K --branch B --depth D   tracer options     default: the mode's\n"
            "  --exposure E           PNG exposure (stops)               default: 0\n"
            "  --time-insert          replay all samples into a fresh engine and print the\n"
            "                         insertion rate (one thread, CPU time)  default: off\n"
            "  --insert-runs N        replays for --time-insert; the median is reported\n"
            "                                                            default: 1\n"
            "  --quiet, --verbose\n"
            "request queue options (docs/sampling.md; here --refine-error defaults to 0:\n"
            "the figures count samples up to one per pixel):\n");
    rq_options_usage(f);
    fprintf(f, "corrective texture options (docs/textures.md):\n");
    ctex_options_help(f);
    fprintf(f, "exit status: 0 ok, 2 bad input or usage\n");
}

/* --- checkpoints --------------------------------------------------------------- */

static int parse_list(const char *s, long *out, int *n, const char *flag, ct_error *err)
{
    *n = 0;
    const char *p = s;
    long prev = 0;
    while (*p) {
        if (*n >= MAX_CHECKPOINTS) return ct_fail(err, CT_EINVAL, "%s: more than %d checkpoints", flag, MAX_CHECKPOINTS);
        long v;
        if (strncmp(p, "all", 3) == 0 && (p[3] == ',' || p[3] == 0)) {
            v = CK_ALL;
            p += 3;
        } else {
            char *end;
            errno = 0;
            v = strtol(p, &end, 10);
            if (errno || end == p || v < 0 || (*end && *end != ','))
                return ct_fail(err, CT_EINVAL, "%s: '%s' is not a list of sample counts", flag, s);
            p = end;
        }
        if (*n > 0 && (prev == CK_ALL || (v != CK_ALL && v <= prev)))
            return ct_fail(err, CT_EINVAL, "%s: checkpoints must increase ('%s')", flag, s);
        out[(*n)++] = v;
        prev = v;
        if (*p == ',') p++;
    }
    if (*n == 0) return ct_fail(err, CT_EINVAL, "%s: empty list", flag);
    return CT_OK;
}

/* --- threaded tracing -------------------------------------------------------------- */

typedef struct trace_job {
    const trc_tracer *t;
    const trc_view *v;
    const ct_request *req;
    ct_sample *out;
    size_t n;
    int primary;
    trc_stats st;
} trace_job;

static void *trace_worker(void *arg)
{
    trace_job *j = arg;
    if (j->primary) trc_trace_primary(j->t, j->v, j->req, j->n, j->out, &j->st);
    else trc_trace(j->t, j->v, j->req, j->n, j->out, &j->st);
    return NULL;
}

/* Traces n requests on up to `threads` threads (results in request order). */
static void trace_par(const trc_tracer *t, const trc_view *v, const ct_request *req, size_t n,
                      ct_sample *out, int primary, int threads, trc_stats *total)
{
    trace_job jobs[64];
    pthread_t th[64];
    if (threads > 64) threads = 64;
    if ((size_t)threads > n) threads = n ? (int)n : 1;
    size_t per = (n + (size_t)threads - 1) / (size_t)threads;
    int started = 0;
    for (int i = 0; i < threads; i++) {
        size_t a = (size_t)i * per, b = a + per > n ? n : a + per;
        jobs[i] = (trace_job){t, v, req + a, out + a, b > a ? b - a : 0, primary, {0}};
        if (i == 0) continue;
        if (pthread_create(&th[i], NULL, trace_worker, &jobs[i]) == 0) started |= 1 << (i & 31);
        else trace_worker(&jobs[i]);   /* no thread: do it here */
    }
    trace_worker(&jobs[0]);
    for (int i = 1; i < threads; i++)
        if (started & (1 << (i & 31))) pthread_join(th[i], NULL);
    for (int i = 0; i < threads; i++) {
        total->primary += jobs[i].st.primary;
        total->secondary += jobs[i].st.secondary;
        total->shadow += jobs[i].st.shadow;
        total->samples += jobs[i].st.samples;
    }
}

/* Primary hits at every pixel centre: what the display shows. */
static int primary_hits(const trc_tracer *t, const trc_view *v, uint32_t epoch, int threads,
                        ctex_hit *hits, uint32_t *shown, ct_error *err)
{
    size_t n = (size_t)v->width * (size_t)v->height;
    ct_request *req = calloc(n, sizeof *req);
    ct_sample *s = calloc(n, sizeof *s);
    if (!req || !s) {
        free(req); free(s);
        return ct_fail(err, CT_ENOMEM, "out of memory for %zu primary hits", n);
    }
    for (size_t i = 0; i < n; i++) {
        req[i].id = i + 1;
        req[i].epoch = epoch;
        req[i].px = (float)(i % (size_t)v->width) + 0.5f;
        req[i].py = (float)(i / (size_t)v->width) + 0.5f;
    }
    trc_stats st = {0};
    trace_par(t, v, req, n, s, 1, threads, &st);
    for (size_t i = 0; i < n; i++) {
        int hit = (s[i].flags & CT_SAMPLE_HIT) != 0;
        hits[i].node = hit ? s[i].node : UINT32_MAX;
        hits[i].tri = hit ? s[i].tri : UINT32_MAX;
        hits[i].p = s[i].hit;
        hits[i].l_base = hit ? s[i].l_base : v3s(0.0f);
        shown[i] = hit ? s[i].node : RQ_NODE_NONE;
    }
    free(req);
    free(s);
    return CT_OK;
}

/* --- outputs ------------------------------------------------------------------------- */

typedef struct run_state {
    const char *out;
    float exposure;
    int W, H;
    FILE *csv;
    fs_atomic csv_at;
    ct_image ref;          /* current reference (px NULL when none) */
    ct_image comp, hq, aux;
    uint8_t *covered;      /* pixel has a sample in the current phase */
    uint8_t *marked;       /* pixel has a sample of the current phase (sample image) */
    double t0;
} run_state;

static int write_pair(run_state *rs, const ct_image *img, const char *stem, int exr, ct_error *err)
{
    char path[4096], name[256];
    int rc = CT_OK;
    if (exr) {
        snprintf(name, sizeof name, "%s.exr", stem);
        fs_join(rs->out, name, path, sizeof path);
        rc = img_write_exr(path, img, IMG_HALF, err);
        if (rc) return rc;
    }
    snprintf(name, sizeof name, "%s.png", stem);
    fs_join(rs->out, name, path, sizeof path);
    return img_write_png(path, img, rs->exposure, err);
}

/* Fig. 5: each pixel in its texture's colour, shaded by the interactive image. */
static int write_assignment(run_state *rs, const ctex *c, const ctex_hit *hits, const char *stem,
                            ct_error *err)
{
    for (int y = 0; y < rs->H; y++)
        for (int x = 0; x < rs->W; x++) {
            const ctex_hit *h = &hits[(size_t)y * (size_t)rs->W + (size_t)x];
            vec3 col = v3s(0.0f);
            if (h->node != UINT32_MAX) {
                float l = img_tonemap(v3_luminance(h->l_base), rs->exposure);
                int32_t id = ctex_owner(c, h->node, h->tri, h->p);
                vec3 base = id >= 0 ? ctex_debug_color(id) : v3s(0.25f);
                col = v3_scale(base, 0.3f + 0.7f * l);
            }
            img_set(&rs->aux, x, y, col);
        }
    char path[4096], name[256];
    snprintf(name, sizeof name, "%s.png", stem);
    fs_join(rs->out, name, path, sizeof path);
    return img_write_png(path, &rs->aux, 0.0f, err);
}

/* Fig. 7 right: the phase's samples in red over the dimmed corrected image. */
static int write_samples(run_state *rs, const char *stem, ct_error *err)
{
    for (int y = 0; y < rs->H; y++)
        for (int x = 0; x < rs->W; x++) {
            size_t i = (size_t)y * (size_t)rs->W + (size_t)x;
            float l = img_tonemap(v3_luminance(img_get(&rs->comp, x, y)), rs->exposure);
            img_set(&rs->aux, x, y, rs->marked[i] ? v3(1, 0, 0) : v3s(0.25f * l));
        }
    char path[4096], name[256];
    snprintf(name, sizeof name, "%s.png", stem);
    fs_join(rs->out, name, path, sizeof path);
    return img_write_png(path, &rs->aux, 0.0f, err);
}

/* RMSE (linear) and PSNR (sRGB) of the composite against the samples' own
 * high-quality values, over the pixels that have a sample. */
static void vs_samples(const run_state *rs, double *rmse, double *psnr)
{
    double se = 0.0, se8 = 0.0;
    size_t n = 0;
    for (int y = 0; y < rs->H; y++)
        for (int x = 0; x < rs->W; x++) {
            if (!rs->covered[(size_t)y * (size_t)rs->W + (size_t)x]) continue;
            vec3 a = img_get(&rs->comp, x, y), b = img_get(&rs->hq, x, y);
            for (int k = 0; k < 3; k++) {
                double d = (double)v3_get(a, k) - (double)v3_get(b, k);
                double d8 = (double)img_tonemap(v3_get(a, k), 0.0f) - (double)img_tonemap(v3_get(b, k), 0.0f);
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
static int checkpoint(run_state *rs, const ctex *c, const ctex_hit *hits, const char *phase,
                      const char *prefix, long samples, double coverage, int sample_img, ct_error *err)
{
    int rc = ctex_composite(c, hits, rs->W, rs->H, &rs->comp, err);
    if (rc) return rc;
    char stem[256];
    if (strcmp(phase, "radiosity") == 0 || strcmp(phase, "moved") == 0) snprintf(stem, sizeof stem, "%s", phase);
    else snprintf(stem, sizeof stem, "%scorrected_%ld", prefix, samples);
    rc = write_pair(rs, &rs->comp, stem, 1, err);
    if (rc) return rc;
    if (sample_img) {
        snprintf(stem, sizeof stem, "%ssamples_%ld", prefix, samples);
        rc = write_samples(rs, stem, err);
        if (rc) return rc;
    }
    img_metrics m = {NAN, NAN, NAN, NAN};
    if (rs->ref.px) {
        rc = metrics_compare(&rs->comp, &rs->ref, &m, err);
        if (rc) return rc;
    }
    double vr, vp;
    vs_samples(rs, &vr, &vp);
    ctex_stats st = ctex_get_stats(c);
    double pct = 100.0 * (double)samples / ((double)rs->W * (double)rs->H);
    fprintf(rs->csv, "%s,%ld,", phase, samples);
    csv_num(rs->csv, pct, 0);
    csv_num(rs->csv, 100.0 * coverage, 0);
    csv_num(rs->csv, m.rmse, 0);
    csv_num(rs->csv, m.psnr, 0);
    csv_num(rs->csv, m.ssim, 0);
    fprintf(rs->csv, "%u,%llu,", st.textures, (unsigned long long)st.texels);
    csv_num(rs->csv, st.splat_radius_mean, 0);
    csv_num(rs->csv, vr, 0);
    csv_num(rs->csv, vp, 0);
    csv_num(rs->csv, ct_now() - rs->t0, 1);
    ct_info(COMPONENT, "%s %ld samples (%.3f%% of pixels, coverage %.1f%%): rmse %.5g psnr %.2f dB, "
            "%u textures, %llu texels, splat radius %.2f, vs samples rmse %.5g",
            phase, samples, pct, 100.0 * coverage, m.rmse, m.psnr, st.textures,
            (unsigned long long)st.texels, st.splat_radius_mean, vr);
    if (m.rmse == m.rmse) printf("metric: %s_%ld_rmse=%.6g\nmetric: %s_%ld_psnr=%.4f\n", phase, samples, m.rmse, phase, samples, m.psnr);
    if (vr == vr) printf("metric: %s_%ld_vs_samples_rmse=%.6g\n", phase, samples, vr);
    return CT_OK;
}

/* --- the sampling loop ------------------------------------------------------------------ */

typedef struct recorder {
    ct_sample *s;
    size_t n, cap;
    size_t phase_start;   /* index of the first sample after --move-to */
} recorder;

static int record(recorder *r, const ct_sample *s, size_t n, ct_error *err)
{
    if (r->n + n > r->cap) {
        size_t nc = r->cap ? 2 * r->cap : 65536;
        while (nc < r->n + n) nc *= 2;
        ct_sample *ns = realloc(r->s, nc * sizeof *ns);
        if (!ns) return ct_fail(err, CT_ENOMEM, "out of memory recording %zu samples", nc);
        r->s = ns;
        r->cap = nc;
    }
    memcpy(r->s + r->n, s, n * sizeof *s);
    r->n += n;
    return CT_OK;
}

typedef struct phase_ctx {
    run_state *rs;
    ctex *c;
    rq_engine *q;
    const trc_tracer *t;
    trc_view view;
    const ctex_hit *hits;
    const uint32_t *shown;
    int batch, threads;
    recorder *rec;
    ct_request *req;
    ct_sample *smp;
    ctex_insert_info *info;
    trc_stats st;
} phase_ctx;

static int run_phase(phase_ctx *p, const long *ck, int nck, const char *phase, const char *prefix,
                     ct_error *err)
{
    run_state *rs = p->rs;
    long done = 0;
    size_t npx = (size_t)rs->W * (size_t)rs->H;
    memset(rs->covered, 0, npx);
    memset(rs->marked, 0, npx);
    for (int k = 0; k < nck; k++) {
        long target = ck[k];
        for (;;) {
            long want = p->batch;
            if (target != CK_ALL && target - done < want) want = target - done;
            if (want <= 0) break;
            int n = rq_next_batch(p->q, p->req, (int)want, err);
            if (n < 0) return n;
            if (n == 0) break;   /* every pixel handed out */
            trace_par(p->t, &p->view, p->req, (size_t)n, p->smp, 0, p->threads, &p->st);
            ctex_insert_par(p->c, NULL, p->smp, (size_t)n, p->info);
            for (int i = 0; i < n; i++) {
                const ct_sample *s = &p->smp[i];
                int x = (int)floorf(s->px), y = (int)floorf(s->py);
                uint32_t shown = RQ_NODE_UNKNOWN;
                if (x >= 0 && y >= 0 && x < rs->W && y < rs->H) {
                    size_t pi = (size_t)y * (size_t)rs->W + (size_t)x;
                    shown = p->shown[pi];
                    rs->covered[pi] = 1;
                    rs->marked[pi] = 1;
                    img_set(&rs->hq, x, y, s->l_hq);
                }
                int rc = rq_report(p->q, s, p->info[i].error, shown, err);
                if (rc < 0) return rc;
            }
            ctex_events_clear(p->c);   /* no display: the events go nowhere */
            if (p->rec) {
                int rc = record(p->rec, p->smp, (size_t)n, err);
                if (rc) return rc;
            }
            done += n;
            if (n < want) break;
        }
        rq_stats qs;
        rq_stats_get(p->q, &qs);
        int rc = checkpoint(rs, p->c, p->hits, phase, prefix, done, qs.coverage, 1, err);
        if (rc) return rc;
        if (target != CK_ALL && done < target)
            ct_warn(COMPONENT, "every pixel was sampled after %ld of %ld samples", done, target);
    }
    /* the high-quality values of this phase's samples */
    char name[256], path[4096];
    snprintf(name, sizeof name, "%shq_samples.exr", prefix);
    fs_join(rs->out, name, path, sizeof path);
    return img_write_exr(path, &rs->hq, IMG_FLOAT, err);
}

/* One replay of the recorded samples into a fresh engine on this thread;
 * *cpu is the thread's CPU time spent in the insertions and flushes. */
static int replay_once(const ct_radmesh *mesh, const ct_scene *s, const ctex_options *co,
                       const recorder *rec, const ct_camera *cam, const ct_camera *cam2, int W, int H,
                       ctex_insert_info *info, int batch, double *cpu, double *sys, ctex_stats *st,
                       ct_error *err)
{
    ctex *c = NULL;
    int rc = ctex_new(mesh, s->mats, s->nmats, co, &c, err);
    if (rc) return rc;
    rc = ctex_set_camera(c, cam, W, H, err);
    *cpu = 0.0;
    struct rusage ru0, ru1;
    getrusage(RUSAGE_THREAD, &ru0);
    struct timespec a, b;
    for (size_t i = 0; !rc && i < rec->n;) {
        if (cam2 && i == rec->phase_start) {
            rc = ctex_set_camera(c, cam2, W, H, err);
            if (rc) break;
        }
        size_t end = i + (size_t)batch;
        if (cam2 && i < rec->phase_start && end > rec->phase_start) end = rec->phase_start;
        if (end > rec->n) end = rec->n;
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &a);
        ctex_insert_par(c, NULL, rec->s + i, end - i, info);
        ctex_events_clear(c);
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &b);
        *cpu += (double)(b.tv_sec - a.tv_sec) + 1e-9 * (double)(b.tv_nsec - a.tv_nsec);
        i = end;
    }
    if (!rc) *st = ctex_get_stats(c);
    getrusage(RUSAGE_THREAD, &ru1);
    *sys = (double)(ru1.ru_stime.tv_sec - ru0.ru_stime.tv_sec) +
           1e-6 * (double)(ru1.ru_stime.tv_usec - ru0.ru_stime.tv_usec);
    ctex_free(c);
    return rc;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Replays the recorded samples `runs` times, each into a fresh engine on
 * this thread, and reports insertions per CPU second of the median run
 * (lookup, error, splat, resolution, dirty rectangles). */
static int time_insert(const ct_radmesh *mesh, const ct_scene *s, const ctex_options *co,
                       const recorder *rec, const ct_camera *cam, const ct_camera *cam2, int W, int H,
                       int batch, int runs, ct_error *err)
{
    ctex_insert_info *info = malloc((size_t)batch * sizeof *info);
    double *cpus = malloc((size_t)runs * sizeof *cpus), *sys = malloc((size_t)runs * sizeof *sys);
    int rc = info && cpus && sys ? CT_OK : ct_fail(err, CT_ENOMEM, "out of memory");
    ctex_stats st = {0};
    for (int k = 0; !rc && k < runs; k++)
        rc = replay_once(mesh, s, co, rec, cam, cam2, W, H, info, batch, &cpus[k], &sys[k], &st, err);
    for (int k = 0; !rc && k < runs; k++)
        ct_debug(COMPONENT, "insertion run %d: %.3f s CPU (%.3f s of it in the kernel: page faults), %.3f M/s",
                 k + 1, cpus[k], sys[k], (double)rec->n / cpus[k] / 1e6);
    if (!rc) {
        qsort(cpus, (size_t)runs, sizeof *cpus, cmp_double);
        double cpu = cpus[runs / 2];
        double rate = cpu > 0.0 ? (double)rec->n / cpu : 0.0;
        ct_info(COMPONENT, "insertion: %zu samples in %.3f s CPU (median of %d): %.3f M/s (%u textures, "
                "%llu texels, %llu resizes)", rec->n, cpu, runs, rate / 1e6, st.textures,
                (unsigned long long)st.texels, (unsigned long long)st.resizes);
        printf("metric: insert_samples=%zu\nmetric: insert_cpu_s=%.6f\nmetric: insert_rate=%.1f\n"
               "metric: insert_textures=%u\nmetric: insert_texels=%llu\nmetric: insert_resizes=%llu\n"
               "metric: insert_runs=%d\n",
               rec->n, cpu, rate, st.textures, (unsigned long long)st.texels,
               (unsigned long long)st.resizes, runs);
    }
    free(sys);
    free(cpus);
    free(info);
    return rc;
}

/* --- main ------------------------------------------------------------------------------ */

static int parse_int(const char *flag, const char *v, int lo, int hi, int *out, ct_error *err)
{
    char *end;
    errno = 0;
    long x = v ? strtol(v, &end, 10) : 0;
    if (!v || errno || end == v || *end || x < lo || x > hi)
        return ct_fail(err, CT_EINVAL, "%s: '%s' is not an integer in [%d, %d]", flag, v ? v : "", lo, hi);
    *out = (int)x;
    return CT_OK;
}

static void rad_progress(void *user, double fraction, const char *what)
{
    (void)user;
    ct_progress("radiosity", fraction, fraction >= 1.0, "%s", what);
}

/* The interactive solution: the constant stand-in when asked for (tests,
 * throughput), else hierarchical radiosity with default parameters, loaded
 * from or written to the cache file when one is given (stale caches are
 * recomputed). */
static int load_mesh(const ct_scene *s, float stand_in, const char *cache, ct_radmesh *m, ct_error *err)
{
    if (stand_in >= 0.0f) {
        ct_info(COMPONENT, "interactive solution: the constant stand-in (ambient %g)", (double)stand_in);
        return rmesh_from_scene(s, v3s(stand_in), m, err);
    }
    rad_params p;
    rad_params_default(&p);
    rad_stats st;
    int from_cache = 0, rc;
    ct_error why;
    double t0 = ct_now();
    if (cache)
        rc = rad_cached_solve(s, &p, cache, rad_progress, NULL, m, &st, &from_cache, &why, err);
    else
        rc = rad_solve(s, &p, rad_progress, NULL, m, &st, err);
    if (rc) return rc;
    if (from_cache)
        ct_info(COMPONENT, "interactive solution: %s (%u triangles, cached)", cache, m->ntris);
    else if (cache)
        ct_info(COMPONENT, "interactive solution: radiosity, %u triangles in %.1f s, written to %s (%s)",
                m->ntris, ct_now() - t0, cache, why.msg);
    else
        ct_info(COMPONENT, "interactive solution: radiosity, %u triangles in %.1f s", m->ntris, ct_now() - t0);
    return CT_OK;
}

int cmd_converge(int argc, char **argv)
{
    ct_error err = {{0}};
    const char *scene_path = NULL, *cam_name = NULL, *move_name = NULL, *out = NULL, *mesh_path = NULL;
    const char *ref_path = NULL, *ref2_path = NULL, *samples_arg = NULL, *after_arg = NULL;
    int W = 512, H = 512, batch = 256, threads = 2, time_ins = 0, ins_runs = 1;
    int shadow = -1, branch = -1, depth = -1;
    long seed = 1;
    float exposure = 0.0f, stand_in = -1.0f;
    trc_mode mode = TRC_MODE_DRT;
    ctex_options co = ctex_options_default();
    rq_options ro;
    rq_options_default(&ro);
    /* The paper's figures count samples up to one per pixel: no refinement
     * past it unless asked (--refine-error). */
    ro.refine_error = 0.0f;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        int rc = CT_OK, used = 1;
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) { usage(stdout); return 0; }
        else if (strcmp(a, "--quiet") == 0) { ct_log_set_level(CT_LOG_WARN); used = 0; }
        else if (strcmp(a, "--verbose") == 0) { ct_log_set_level(CT_LOG_DEBUG); used = 0; }
        else if (strcmp(a, "--time-insert") == 0) { time_ins = 1; used = 0; }
        else if (strcmp(a, "--camera") == 0) cam_name = v;
        else if (strcmp(a, "--samples") == 0) samples_arg = v;
        else if (strcmp(a, "--samples-after") == 0) after_arg = v;
        else if (strcmp(a, "--move-to") == 0) move_name = v;
        else if (strcmp(a, "--out") == 0) out = v;
        else if (strcmp(a, "--reference") == 0) ref_path = v;
        else if (strcmp(a, "--reference-after") == 0) ref2_path = v;
        else if (strcmp(a, "--mode") == 0) rc = v ? trc_mode_parse(v, &mode, &err) : ct_fail(&err, CT_EINVAL, "--mode needs a value");
        else if (strcmp(a, "--width") == 0) rc = parse_int(a, v, 1, 16384, &W, &err);
        else if (strcmp(a, "--height") == 0) rc = parse_int(a, v, 1, 16384, &H, &err);
        else if (strcmp(a, "--insert-runs") == 0) rc = parse_int(a, v, 1, 1000, &ins_runs, &err);
        else if (strcmp(a, "--batch") == 0) rc = parse_int(a, v, 1, 1 << 20, &batch, &err);
        else if (strcmp(a, "--threads") == 0) rc = parse_int(a, v, 1, 64, &threads, &err);
        else if (strcmp(a, "--shadow-rays") == 0) rc = parse_int(a, v, 1, 1 << 16, &shadow, &err);
        else if (strcmp(a, "--branch") == 0) rc = parse_int(a, v, 1, 1 << 16, &branch, &err);
        else if (strcmp(a, "--depth") == 0) rc = parse_int(a, v, 0, 1 << 10, &depth, &err);
        else if (strcmp(a, "--seed") == 0) {
            int s32;
            rc = parse_int(a, v, 0, 2147483647, &s32, &err);
            seed = s32;
        } else if (strcmp(a, "--exposure") == 0) {
            char *end;
            exposure = v ? strtof(v, &end) : 0.0f;
            if (!v || end == v || *end || !isfinite(exposure)) rc = ct_fail(&err, CT_EINVAL, "--exposure: '%s' is not a number", v ? v : "");
        } else if (strcmp(a, "--mesh") == 0) {
            mesh_path = v;
            if (!v) rc = ct_fail(&err, CT_EINVAL, "--mesh needs a file name");
        } else if (strcmp(a, "--stand-in") == 0) {
            char *end;
            stand_in = v ? strtof(v, &end) : -1.0f;
            if (!v || end == v || *end || !(stand_in >= 0.0f && stand_in <= 1e6f))
                rc = ct_fail(&err, CT_EINVAL, "--stand-in: '%s' is not a number >= 0", v ? v : "");
        } else if (a[0] == '-' && a[1] == '-') {
            rc = ctex_options_parse(&co, a, v, &err);
            if (rc == 0) {
                rc = v ? rq_options_set(&ro, a + 2, v, &err) : ct_fail(&err, CT_EINVAL, "unknown option '%s' (try --help)", a);
            } else if (rc == 1) rc = CT_OK;
        } else if (!scene_path) {
            scene_path = a;
            used = 0;
        } else {
            rc = ct_fail(&err, CT_EINVAL, "unexpected argument '%s' (try --help)", a);
        }
        if (rc) {
            ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
            return 2;
        }
        if (used) {
            if (!v) {
                ct_log(CT_LOG_ERROR, COMPONENT, "%s needs a value (try --help)", a);
                return 2;
            }
            i++;
        }
    }
    long ck[MAX_CHECKPOINTS], ck2[MAX_CHECKPOINTS];
    int nck = 0, nck2 = 0;
    if (!scene_path || !samples_arg || !out) {
        ct_log(CT_LOG_ERROR, COMPONENT, "need SCENE, --samples and --out (try --help)");
        return 2;
    }
    if (parse_list(samples_arg, ck, &nck, "--samples", &err) ||
        (after_arg && parse_list(after_arg, ck2, &nck2, "--samples-after", &err)) ||
        rq_options_check(&ro, &err)) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return 2;
    }
    if (!!move_name != !!after_arg) {
        ct_log(CT_LOG_ERROR, COMPONENT, "--move-to and --samples-after go together");
        return 2;
    }

    ct_scene *scene = NULL;
    ct_radmesh mesh = {0};
    trc_tracer *tr = NULL;
    ctex *c = NULL;
    rq_engine *q = NULL;
    ctex_hit *hits = NULL;
    uint32_t *shown = NULL;
    recorder rec = {0};
    run_state rs = {0};
    phase_ctx pc = {0};
    int status = 2, rc;
    rs.out = out;
    rs.exposure = exposure;
    rs.W = W;
    rs.H = H;
    rs.t0 = ct_now();

    if ((rc = scene_load(scene_path, &scene, &err))) goto fail;
    if (scene->ncams == 0 && !cam_name) { rc = ct_fail(&err, CT_EINVAL, "%s has no camera", scene_path); goto fail; }
    int ci = cam_name ? scene_find_camera(scene, cam_name) : 0;
    if (ci < 0) { rc = ct_fail(&err, CT_EINVAL, "%s has no camera '%s'", scene_path, cam_name); goto fail; }
    int ci2 = -1;
    if (move_name) {
        ci2 = scene_find_camera(scene, move_name);
        if (ci2 < 0) { rc = ct_fail(&err, CT_EINVAL, "%s has no camera '%s'", scene_path, move_name); goto fail; }
    }
    ct_camera cam = scene->cams[ci].cam, cam2 = ci2 >= 0 ? scene->cams[ci2].cam : cam;
    if ((rc = fs_mkdirs(out, &err))) goto fail;
    if (mesh_path && stand_in >= 0.0f) {
        rc = ct_fail(&err, CT_EINVAL, "give --mesh or --stand-in, not both");
        goto fail;
    }
    if ((rc = load_mesh(scene, stand_in, mesh_path, &mesh, &err))) goto fail;
    trc_options to;
    trc_options_default(&to, mode);
    to.seed = (uint64_t)seed;
    if (shadow > 0) to.shadow_rays = shadow;
    if (branch > 0) to.branch = branch;
    if (depth >= 0) to.depth = depth;
    if ((rc = trc_new(scene, &mesh, &to, &tr, &err))) goto fail;
    if ((rc = ctex_new(&mesh, scene->mats, scene->nmats, &co, &c, &err))) goto fail;
    {
        ctex_stats st = ctex_get_stats(c);
        ct_info(COMPONENT, "texture hierarchy: %u nodes, %u leaves", st.hier_nodes, st.hier_leaves);
    }
    size_t npx = (size_t)W * (size_t)H;
    hits = malloc(npx * sizeof *hits);
    shown = malloc(npx * sizeof *shown);
    rs.covered = malloc(npx);
    rs.marked = malloc(npx);
    pc.req = malloc((size_t)batch * sizeof *pc.req);
    pc.smp = malloc((size_t)batch * sizeof *pc.smp);
    pc.info = malloc((size_t)batch * sizeof *pc.info);
    if (!hits || !shown || !rs.covered || !rs.marked || !pc.req || !pc.smp || !pc.info) {
        rc = ct_fail(&err, CT_ENOMEM, "out of memory for a %dx%d run", W, H);
        goto fail;
    }
    if ((rc = img_alloc(&rs.comp, W, H, &err)) || (rc = img_alloc(&rs.hq, W, H, &err)) ||
        (rc = img_alloc(&rs.aux, W, H, &err)))
        goto fail;
    if (ref_path) {
        if ((rc = img_read_exr(ref_path, &rs.ref, &err))) goto fail;
        if (rs.ref.width != W || rs.ref.height != H) {
            rc = ct_fail(&err, CT_EINVAL, "%s is %dx%d, the run is %dx%d", ref_path, rs.ref.width, rs.ref.height, W, H);
            goto fail;
        }
    }
    char csv_path[4096];
    fs_join(out, "convergence.csv", csv_path, sizeof csv_path);
    if ((rc = fs_atomic_open(&rs.csv_at, csv_path, &err))) goto fail;
    rs.csv = rs.csv_at.f;
    fprintf(rs.csv, "phase,samples,percent_pixels,coverage,rmse,psnr,ssim,textures,texels,"
                    "splat_radius_mean,rmse_vs_samples,psnr_vs_samples,seconds\n");

    /* phase 1: the still camera */
    pc.view.cam = cam;
    pc.view.width = W;
    pc.view.height = H;
    if ((rc = primary_hits(tr, &pc.view, 0, threads, hits, shown, &err))) goto fail_csv;
    if ((rc = ctex_set_camera(c, &cam, W, H, &err))) goto fail_csv;
    if ((rc = rq_new(&q, W, H, &cam, &ro, (uint64_t)seed, &err))) goto fail_csv;
    pc.rs = &rs; pc.c = c; pc.q = q; pc.t = tr; pc.hits = hits; pc.shown = shown;
    pc.batch = batch; pc.threads = threads; pc.rec = time_ins ? &rec : NULL;
    memset(rs.covered, 0, npx);
    memset(rs.marked, 0, npx);
    if ((rc = checkpoint(&rs, c, hits, "radiosity", "", 0, 0.0, 0, &err))) goto fail_csv;
    if ((rc = write_assignment(&rs, c, hits, "assignment", &err))) goto fail_csv;
    if ((rc = run_phase(&pc, ck, nck, "still", "", &err))) goto fail_csv;

    /* phase 2: moved without updates, then more samples (Fig. 7) */
    if (ci2 >= 0) {
        rec.phase_start = rec.n;
        img_free(&rs.ref);
        if (ref2_path) {
            if ((rc = img_read_exr(ref2_path, &rs.ref, &err))) goto fail_csv;
            if (rs.ref.width != W || rs.ref.height != H) {
                rc = ct_fail(&err, CT_EINVAL, "%s is %dx%d, the run is %dx%d", ref2_path, rs.ref.width, rs.ref.height, W, H);
                goto fail_csv;
            }
        }
        pc.view.cam = cam2;
        double tc = ct_now();
        if ((rc = ctex_set_camera(c, &cam2, W, H, &err))) goto fail_csv;
        {
            ctex_stats cs = ctex_get_stats(c);
            ct_info(COMPONENT, "camera change without updates: %.1f ms (aging, reassignment, reprojection); "
                    "%u textures, %u parked, %llu texels", 1e3 * (ct_now() - tc), cs.textures, cs.parked,
                    (unsigned long long)cs.texels);
        }
        if ((rc = primary_hits(tr, &pc.view, 1, threads, hits, shown, &err))) goto fail_csv;
        if ((rc = rq_set_camera(q, &cam2, 1, &err))) goto fail_csv;
        memset(rs.covered, 0, npx);
        memset(rs.marked, 0, npx);
        if ((rc = checkpoint(&rs, c, hits, "moved", "", 0, 0.0, 0, &err))) goto fail_csv;
        if ((rc = write_assignment(&rs, c, hits, "after_assignment", &err))) goto fail_csv;
        if ((rc = run_phase(&pc, ck2, nck2, "after", "after_", &err))) goto fail_csv;
    }
    if ((rc = fs_atomic_commit(&rs.csv_at, &err))) goto fail;
    rs.csv = NULL;
    ct_info(COMPONENT, "traced %llu samples (%llu rays) in %.1f s; wrote %s",
            (unsigned long long)pc.st.samples, (unsigned long long)trc_stats_rays(&pc.st), ct_now() - rs.t0, csv_path);
    if (time_ins && (rc = time_insert(&mesh, scene, &co, &rec, &cam, ci2 >= 0 ? &cam2 : NULL, W, H, batch, ins_runs, &err)))
        goto fail;
    status = 0;
    goto done;
fail_csv:
    fs_atomic_abort(&rs.csv_at);
    rs.csv = NULL;
fail:
    ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
    status = 2;
done:
    free(pc.req); free(pc.smp); free(pc.info);
    free(rs.covered); free(rs.marked);
    img_free(&rs.comp); img_free(&rs.hq); img_free(&rs.aux); img_free(&rs.ref);
    free(hits); free(shown); free(rec.s);
    rq_free(q);
    ctex_free(c);
    trc_free(tr);
    rmesh_free(&mesh);
    scene_free(scene);
    return status;
}
