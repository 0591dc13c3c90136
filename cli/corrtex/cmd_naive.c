/* corrtex naive SCENE --mesh FILE.ctmesh --path P --frames N -o DIR: the
 * walkthrough benchmark's baselines, without corrective textures.
 *   K = 0   radiosity alone: every pixel shows the Gouraud-interpolated
 *           radiosity at its primary hit (L_base, exactly what GL draws).
 *   K > 0   the naive point display (render-cache style, no reprojection):
 *           the radiosity image, and each of K high-quality samples per
 *           frame fills only its own pixel (no splatting, no textures, no
 *           error-driven placement: K distinct random pixels per frame).
 *           With --hold, older samples stay in the pixels they were taken in
 *           (stale when the camera moves, as a point display that does not
 *           reproject), and new samples go to pixels not sampled yet.
 * Frames follow the path like `corrtex-display --frames N` and
 * `corrtex reference --frames N` (frame k at path time k/(N-1) of the
 * duration), so DIR/frame_NNNNN.exr compares with a reference folder; with
 * --reference DIR the error per frame goes into DIR/frames.csv. */
#include <getopt.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli/corrtex/commands.h"
#include "common/campath.h"
#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/metrics.h"
#include "common/radmesh.h"
#include "common/rng.h"
#include "common/scene.h"
#include "common/timer.h"
#include "tracer/tracer.h"

#define COMPONENT "corrtex naive"
#define MAX_THREADS 64
/* rng_make dimension of the pixel choice (the tracer uses 0 and 1). */
#define DIM_PICK 7

typedef struct naive_opts {
    const char *scene, *mesh, *path, *out, *ref;
    int frames, spp_frame, width, height, threads;
    int hold, png;
    float exposure;
    trc_options trc;
} naive_opts;

static void usage(FILE *f)
{
    fprintf(f,
            "usage: corrtex naive SCENE.json --mesh FILE.ctmesh --path P -o DIR [options]\n"
            "Baselines for the walkthrough benchmark, without corrective textures:\n"
            "  --samples-per-frame 0   radiosity alone (Gouraud radiosity at each pixel's hit)\n"
            "  --samples-per-frame K   radiosity plus K high-quality samples per frame, each\n"
            "                          filling only its own pixel (point display, no reprojection)\n"
            "Writes DIR/frame_NNNNN.exr (and .png) per frame and DIR/frames.csv.\n\n"
            "options:\n"
            "  --mesh FILE            the radiosity cache (.ctmesh) the display draws   required\n"
            "  --path P               camera path: a file, or a path name of the scene  required\n"
            "  --frames N             frames spread evenly over the path (1..100000)    default: 100\n"
            "  --samples-per-frame K  high-quality samples per frame (0..16777216)      default: 1000\n"
            "  --hold                 keep older samples in their pixels (stale)       default: off\n"
            "  --width W, --height H  image size                                       default: 1024x1024\n"
            "  --mode M               drt | path | reuse-diffuse                       default: drt\n"
            "  --shadow-rays K        light samples per shading point                  default: mode's\n"
            "  --branch B             rays per glossy lobe (drt, reuse-diffuse)        default: mode's\n"
            "  --depth D              recursion depth                                  default: mode's\n"
            "  --seed S               random seed (pixel choice and tracing)           default: 1\n"
            "  --threads T            worker threads (1..64)                           default: 1\n"
            "  --reference DIR        per-frame RMSE/PSNR/SSIM against DIR/frame_NNNNN.exr\n"
            "  --exposure E           stops for the PNG frames                         default: 0\n"
            "  --no-png               EXR frames only                                  default: both\n"
            "  -o, --output DIR       output folder                                    required\n"
            "  -q, --quiet            errors only\n"
            "  -h, --help             this help\n"
            "The last line on stdout is 'stats: key=value ...' (frames, samples, seconds,\n"
            "samples_per_s, base_s, sample_s, and mean_rmse, mean_psnr with --reference).\n"
            "exit status: 0 ok, 1 runtime failure, 2 bad input or usage\n");
}

/* ---- a parallel loop over [0, n) in chunks ------------------------------ */

typedef struct pjob pjob;
typedef void (*pjob_fn)(pjob *j, int tid, size_t begin, size_t end);

struct pjob {
    pjob_fn fn;
    size_t n, chunk;
    atomic_size_t next;
    void *user;
    trc_stats st[MAX_THREADS];
    ct_request *req[MAX_THREADS];
    ct_sample *smp[MAX_THREADS];
};

typedef struct pworker {
    pjob *j;
    int tid;
    pthread_t th;
} pworker;

static void *pjob_worker(void *arg)
{
    pworker *w = arg;
    pjob *j = w->j;
    for (;;) {
        size_t b = atomic_fetch_add(&j->next, j->chunk);
        if (b >= j->n) break;
        size_t e = b + j->chunk < j->n ? b + j->chunk : j->n;
        j->fn(j, w->tid, b, e);
    }
    return NULL;
}

/* Runs fn over [0, n) on `threads` threads (the caller's thread included). */
static int pjob_run(pjob *j, int threads, size_t n, size_t chunk, pjob_fn fn, ct_error *err)
{
    j->fn = fn;
    j->n = n;
    j->chunk = chunk ? chunk : 1;
    atomic_store(&j->next, 0);
    pworker w[MAX_THREADS];
    int started = 0, rc = CT_OK;
    for (int i = 1; i < threads; i++) {
        w[i].j = j;
        w[i].tid = i;
        if (pthread_create(&w[i].th, NULL, pjob_worker, &w[i])) {
            rc = ct_fail(err, CT_ESYS, "cannot start worker thread %d of %d", i + 1, threads);
            break;
        }
        started = i;
    }
    w[0].j = j;
    w[0].tid = 0;
    pjob_worker(&w[0]);
    for (int i = 1; i <= started; i++) pthread_join(w[i].th, NULL);
    return rc;
}

/* ---- the run ------------------------------------------------------------ */

typedef struct naive_run {
    const naive_opts *o;
    const trc_tracer *trc;
    trc_view view;
    uint32_t frame;
    ct_image img;           /* the frame being built */
    uint32_t *perm;         /* a permutation of the pixels: sampling order */
    size_t npx, cursor;     /* next unsampled position in perm (--hold) */
    const uint32_t *picks;  /* this frame's K pixels */
    size_t npicks;
    float *held;            /* --hold: last sample value per pixel */
    uint8_t *held_mask;
} naive_run;

/* Radiosity alone: L_base at every pixel centre, one image row per item. */
static void base_rows(pjob *j, int tid, size_t begin, size_t end)
{
    naive_run *r = j->user;
    int w = r->o->width;
    for (size_t y = begin; y < end; y++) {
        for (int x = 0; x < w; x++) {
            ct_request *q = &j->req[tid][x];
            memset(q, 0, sizeof *q);
            q->id = ((uint64_t)r->frame * r->npx + y * (uint64_t)w + (uint64_t)x) + 1;
            q->epoch = r->frame;
            q->px = (float)x + 0.5f;
            q->py = (float)y + 0.5f;
            q->radius = 0.5f;
        }
        trc_trace_primary(r->trc, &r->view, j->req[tid], (size_t)w, j->smp[tid], &j->st[tid]);
        for (int x = 0; x < w; x++) img_set(&r->img, x, (int)y, j->smp[tid][x].l_base);
    }
}

/* K high-quality samples, each at its pixel's centre, written to that pixel. */
static void sample_picks(pjob *j, int tid, size_t begin, size_t end)
{
    naive_run *r = j->user;
    int w = r->o->width;
    size_t n = end - begin;
    for (size_t i = 0; i < n; i++) {
        uint32_t p = r->picks[begin + i];
        ct_request *q = &j->req[tid][i];
        memset(q, 0, sizeof *q);
        q->id = ((uint64_t)r->frame * r->npx + p) + 1;
        q->epoch = r->frame;
        q->px = (float)(p % (uint32_t)w) + 0.5f;
        q->py = (float)(p / (uint32_t)w) + 0.5f;
        q->radius = 0.5f;
    }
    trc_trace(r->trc, &r->view, j->req[tid], n, j->smp[tid], &j->st[tid]);
    for (size_t i = 0; i < n; i++) {
        uint32_t p = r->picks[begin + i];
        vec3 l = j->smp[tid][i].l_hq;
        img_set(&r->img, (int)(p % (uint32_t)w), (int)(p / (uint32_t)w), l);
        if (r->held) {
            r->held[3 * (size_t)p] = l.x;
            r->held[3 * (size_t)p + 1] = l.y;
            r->held[3 * (size_t)p + 2] = l.z;
            r->held_mask[p] = 1;
        }
    }
}

/* Chooses this frame's K pixels by a partial Fisher-Yates shuffle of perm:
 * distinct pixels, uniformly random; --hold continues where the last frame
 * stopped, so pixels not sampled yet come first. */
static void choose_pixels(naive_run *r, size_t k)
{
    ct_rng g = rng_make(r->o->trc.seed, r->frame, 0, DIM_PICK);
    if (!r->o->hold || r->cursor + k > r->npx) r->cursor = 0;
    for (size_t i = r->cursor; i < r->cursor + k; i++) {
        size_t left = r->npx - i;
        size_t jx = i + (left > UINT32_MAX ? (size_t)rng_u32(&g) % left : rng_below(&g, (uint32_t)left));
        uint32_t t = r->perm[i];
        r->perm[i] = r->perm[jx];
        r->perm[jx] = t;
    }
    r->picks = r->perm + r->cursor;
    r->npicks = k;
    r->cursor += k;
}

static int write_csv(const char *dir, const char *rows, int has_ref, ct_error *err)
{
    char path[4096];
    fs_join(dir, "frames.csv", path, sizeof path);
    fs_atomic a;
    int rc = fs_atomic_open(&a, path, err);
    if (rc) return rc;
    fprintf(a.f, "frame,time_s,samples,base_ms,sample_ms%s\n", has_ref ? ",rmse,rel_mse,psnr_db,ssim" : "");
    fputs(rows, a.f);
    return fs_atomic_commit(&a, err);
}

static int run(const naive_opts *o, ct_error *err)
{
    ct_scene *scene = NULL;
    ct_radmesh mesh;
    memset(&mesh, 0, sizeof mesh);
    ct_campath path;
    memset(&path, 0, sizeof path);
    trc_tracer *trc = NULL;
    naive_run r;
    memset(&r, 0, sizeof r);
    pjob *job = calloc(1, sizeof *job);
    char *csv = NULL;
    size_t csv_len = 0, csv_cap = 0;
    int have_path = 0;
    int rc = job ? CT_OK : ct_fail(err, CT_ENOMEM, "out of memory");
    if (!rc) rc = scene_load(o->scene, &scene, err);
    if (!rc) rc = rmesh_load(o->mesh, 0, &mesh, err);
    if (!rc) {
        struct stat st;
        if (stat(o->path, &st) == 0) {
            rc = campath_load(o->path, &path, err);
            have_path = !rc;
        } else {
            int pi = scene_find_path(scene, o->path);
            if (pi < 0)
                rc = ct_fail(err, CT_EINVAL, "--path %s: neither a file nor a path of %s", o->path, o->scene);
            else
                rc = campath_from_keys(scene->paths[pi].keys, scene->paths[pi].nkeys, scene->paths[pi].up,
                                       o->path, &path, err);
            have_path = !rc;
        }
    }
    if (!rc) rc = trc_new(scene, &mesh, &o->trc, &trc, err);
    if (!rc) rc = fs_mkdirs(o->out, err);
    if (!rc) rc = img_alloc(&r.img, o->width, o->height, err);
    r.o = o;
    r.trc = trc;
    r.npx = (size_t)o->width * (size_t)o->height;
    if (!rc && (size_t)o->spp_frame > r.npx)
        rc = ct_fail(err, CT_EINVAL, "--samples-per-frame %d exceeds the %zu pixels of a frame", o->spp_frame,
                     r.npx);
    if (!rc && o->spp_frame > 0) {
        r.perm = malloc(r.npx * sizeof *r.perm);
        if (!r.perm) rc = ct_fail(err, CT_ENOMEM, "out of memory for %zu pixels", r.npx);
        else
            for (size_t i = 0; i < r.npx; i++) r.perm[i] = (uint32_t)i;
        if (!rc && o->hold) {
            r.held = malloc(r.npx * 3 * sizeof *r.held);
            r.held_mask = calloc(r.npx, 1);
            if (!r.held || !r.held_mask) rc = ct_fail(err, CT_ENOMEM, "out of memory for --hold");
        }
    }
    /* Per-thread buffers: a row for the radiosity pass, a chunk of samples. */
    size_t chunk = 256, per = (size_t)o->width > chunk ? (size_t)o->width : chunk;
    for (int t = 0; !rc && t < o->threads; t++) {
        job->req[t] = malloc(per * sizeof(ct_request));
        job->smp[t] = malloc(per * sizeof(ct_sample));
        if (!job->req[t] || !job->smp[t]) rc = ct_fail(err, CT_ENOMEM, "out of memory for thread buffers");
    }
    job->user = &r;
    r.view.width = o->width;
    r.view.height = o->height;
    double base_s = 0, sample_s = 0, sum_rmse = 0, sum_psnr = 0, t_all = ct_now();
    uint64_t samples = 0;
    int nref = 0;
    float dur = have_path ? campath_duration(&path) : 0.0f;
    for (int k = 0; !rc && k < o->frames; k++) {
        r.frame = (uint32_t)k;
        r.view.cam = campath_frame(&path, k, o->frames);
        double t0 = ct_now();
        rc = pjob_run(job, o->threads, (size_t)o->height, 4, base_rows, err);
        if (rc) break;
        if (r.held)
            for (size_t p = 0; p < r.npx; p++)
                if (r.held_mask[p]) memcpy(r.img.px + 3 * p, r.held + 3 * p, 3 * sizeof(float));
        double t1 = ct_now();
        if (o->spp_frame > 0) {
            choose_pixels(&r, (size_t)o->spp_frame);
            rc = pjob_run(job, o->threads, r.npicks, chunk, sample_picks, err);
            if (rc) break;
            samples += r.npicks;
        }
        double t2 = ct_now();
        base_s += t1 - t0;
        sample_s += t2 - t1;
        char name[64], file[4096];
        snprintf(name, sizeof name, "frame_%05d.exr", k);
        fs_join(o->out, name, file, sizeof file);
        rc = img_write_exr(file, &r.img, IMG_HALF, err);
        if (!rc && o->png) {
            snprintf(name, sizeof name, "frame_%05d.png", k);
            fs_join(o->out, name, file, sizeof file);
            rc = img_write_png(file, &r.img, o->exposure, err);
        }
        if (rc) break;
        char row[512];
        double ftime = o->frames > 1 ? (double)dur * k / (double)(o->frames - 1) : 0.0;
        int n = snprintf(row, sizeof row, "%d,%.6f,%zu,%.3f,%.3f", k, ftime, o->spp_frame > 0 ? r.npicks : 0,
                         1000.0 * (t1 - t0), 1000.0 * (t2 - t1));
        if (o->ref) {
            snprintf(name, sizeof name, "frame_%05d.exr", k);
            fs_join(o->ref, name, file, sizeof file);
            ct_image ref = {0, 0, NULL};
            rc = img_read_exr(file, &ref, err);
            img_metrics m;
            if (!rc) {
                rc = metrics_compare(&r.img, &ref, &m, err);
                if (rc) ct_error_prefix(err, file);
            }
            img_free(&ref);
            if (rc) break;
            double psnr = isinf(m.psnr) ? 999.0 : m.psnr;
            snprintf(row + n, sizeof row - (size_t)n, ",%.6g,%.6g,%.4f,%.6f", m.rmse, m.rel_mse, psnr, m.ssim);
            sum_rmse += m.rmse;
            sum_psnr += psnr;
            nref++;
        }
        size_t len = strlen(row);
        if (csv_len + len + 2 > csv_cap) {
            size_t cap = csv_cap ? 2 * csv_cap : 8192;
            while (cap < csv_len + len + 2) cap *= 2;
            char *p = realloc(csv, cap);
            if (!p) {
                rc = ct_fail(err, CT_ENOMEM, "out of memory for frames.csv");
                break;
            }
            csv = p;
            csv_cap = cap;
        }
        memcpy(csv + csv_len, row, len);
        csv_len += len;
        csv[csv_len++] = '\n';
        csv[csv_len] = '\0';
        ct_progress(COMPONENT, (double)(k + 1) / o->frames, 0, "frame %d/%d", k + 1, o->frames);
    }
    if (!rc) {
        ct_progress(COMPONENT, 1.0, 1, "frame %d/%d", o->frames, o->frames);
        rc = write_csv(o->out, csv ? csv : "", o->ref != NULL, err);
    }
    if (!rc) {
        double all = ct_now() - t_all;
        printf("stats: frames=%d samples=%llu seconds=%.3f samples_per_s=%.1f base_s=%.3f sample_s=%.3f", o->frames,
               (unsigned long long)samples, all, sample_s > 0 ? (double)samples / sample_s : 0.0, base_s, sample_s);
        if (nref) printf(" mean_rmse=%.6g mean_psnr=%.4f", sum_rmse / nref, sum_psnr / nref);
        printf("\n");
        fflush(stdout);
    }
    free(csv);
    for (int t = 0; job && t < o->threads; t++) {
        free(job->req[t]);
        free(job->smp[t]);
    }
    free(job);
    free(r.perm);
    free(r.held);
    free(r.held_mask);
    img_free(&r.img);
    trc_free(trc);
    if (have_path) campath_free(&path);
    rmesh_free(&mesh);
    if (scene) scene_free(scene);
    return rc;
}

/* An int option within [lo, hi]; logs and returns -1 when bad. */
static int int_opt(const char *name, const char *s, long lo, long hi, int *out)
{
    return cli_int_opt(COMPONENT, name, s, lo, hi, out);
}

int cmd_naive(int argc, char **argv)
{
    enum { O_MESH = 256, O_PATH, O_FRAMES, O_SPF, O_HOLD, O_W, O_H, O_MODE, O_K, O_B, O_D, O_SEED, O_THREADS,
           O_REF, O_EXP, O_NOPNG };
    static const struct option opts[] = {
        {"mesh", required_argument, NULL, O_MESH},       {"path", required_argument, NULL, O_PATH},
        {"frames", required_argument, NULL, O_FRAMES},   {"samples-per-frame", required_argument, NULL, O_SPF},
        {"hold", no_argument, NULL, O_HOLD},             {"width", required_argument, NULL, O_W},
        {"height", required_argument, NULL, O_H},        {"mode", required_argument, NULL, O_MODE},
        {"shadow-rays", required_argument, NULL, O_K},   {"branch", required_argument, NULL, O_B},
        {"depth", required_argument, NULL, O_D},         {"seed", required_argument, NULL, O_SEED},
        {"threads", required_argument, NULL, O_THREADS}, {"reference", required_argument, NULL, O_REF},
        {"exposure", required_argument, NULL, O_EXP},    {"no-png", no_argument, NULL, O_NOPNG},
        {"output", required_argument, NULL, 'o'},        {"quiet", no_argument, NULL, 'q'},
        {"help", no_argument, NULL, 'h'},                {NULL, 0, NULL, 0}};
    naive_opts o;
    memset(&o, 0, sizeof o);
    o.frames = 100;
    o.spp_frame = 1000;   /* §5: 1,000 to 4,000 samples per frame */
    o.width = o.height = 1024;   /* §5: 1024x1024 display */
    o.threads = 1;
    o.png = 1;
    trc_options_default(&o.trc, TRC_MODE_DRT);
    int k = -1, b = -1, d = -1;
    long long seed = -1;
    ct_error err;
    optind = 1;
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, "o:qh", opts, NULL)) != -1) {
        switch (c) {
        case O_MESH: o.mesh = optarg; break;
        case O_PATH: o.path = optarg; break;
        case O_FRAMES: if (int_opt("--frames", optarg, 1, 100000, &o.frames)) return 2; break;
        case O_SPF: if (int_opt("--samples-per-frame", optarg, 0, 1 << 24, &o.spp_frame)) return 2; break;
        case O_HOLD: o.hold = 1; break;
        case O_W: if (int_opt("--width", optarg, 1, 16384, &o.width)) return 2; break;
        case O_H: if (int_opt("--height", optarg, 1, 16384, &o.height)) return 2; break;
        case O_MODE: {
            trc_mode m;
            if (trc_mode_parse(optarg, &m, &err)) {
                ct_log(CT_LOG_ERROR, COMPONENT, "--mode: %s", err.msg);
                return 2;
            }
            trc_options_default(&o.trc, m);
            break;
        }
        case O_K: if (int_opt("--shadow-rays", optarg, 1, 1024, &k)) return 2; break;
        case O_B: if (int_opt("--branch", optarg, 1, 1024, &b)) return 2; break;
        case O_D: if (int_opt("--depth", optarg, 0, 1024, &d)) return 2; break;
        case O_SEED: {
            char *end = NULL;
            seed = strtoll(optarg, &end, 10);
            if (end == optarg || *end || seed < 0) {
                ct_log(CT_LOG_ERROR, COMPONENT, "--seed: '%s' is not an integer >= 0", optarg);
                return 2;
            }
            break;
        }
        case O_THREADS: if (int_opt("--threads", optarg, 1, MAX_THREADS, &o.threads)) return 2; break;
        case O_REF: o.ref = optarg; break;
        case O_EXP: if (cli_float_opt(COMPONENT, "--exposure", optarg, -30, 30, &o.exposure)) return 2; break;
        case O_NOPNG: o.png = 0; break;
        case 'o': o.out = optarg; break;
        case 'q': ct_log_set_level(CT_LOG_ERROR); break;
        case 'h': usage(stdout); return 0;
        default:
            ct_log(CT_LOG_ERROR, COMPONENT, "unknown or incomplete option '%s' (try --help)", argv[optind - 1]);
            return 2;
        }
    }
    if (k > 0) o.trc.shadow_rays = k;
    if (b > 0) o.trc.branch = b;
    if (d >= 0) o.trc.depth = d;
    if (seed >= 0) o.trc.seed = (uint64_t)seed;
    if (argc - optind != 1) {
        ct_log(CT_LOG_ERROR, COMPONENT, "expected one scene file, got %d (try --help)", argc - optind);
        return 2;
    }
    o.scene = argv[optind];
    const char *missing = !o.mesh ? "--mesh FILE.ctmesh" : !o.path ? "--path P" : !o.out ? "-o DIR" : NULL;
    if (missing) {
        ct_log(CT_LOG_ERROR, COMPONENT, "missing %s (try --help)", missing);
        return 2;
    }
    int rc = run(&o, &err);
    if (rc) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return (rc == CT_ENOMEM || rc == CT_ESYS) ? 1 : 2;
    }
    return 0;
}
