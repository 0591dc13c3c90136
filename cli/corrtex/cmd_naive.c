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
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/corrtex/commands.h"
#include "common/campath.h"
#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/metrics.h"
#include "common/optab.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "common/rng.h"
#include "common/scene.h"
#include "common/timer.h"
#include "tracer/tracer.h"
#include "tracer/trc_cli.h"

#define COMPONENT "corrtex naive"
#define MAX_THREADS POOL_MAX_THREADS
/* rng_make dimension of the pixel choice (the tracer uses 0 and 1). */
#define DIM_PICK 7

typedef struct naive_opts {
    const char *scene, *mesh, *path, *out, *ref;
    int frames, spp_frame, width, height, threads;
    bool hold, no_png, quiet;
    float exposure;
    trc_cli cli;       /* the tracer's options as given */
    uint64_t seed;
    trc_options trc;
} naive_opts;

#define OF(f) offsetof(naive_opts, f)
static const optab OPTS[] = {
    {"mesh", 0, OPTAB_STRING, OF(mesh), 0, 0, NULL, "FILE", "the radiosity cache (.ctmesh) the display draws (required)",
     NULL},
    {"path", 0, OPTAB_STRING, OF(path), 0, 0, NULL, "P", "camera path: a path name of the scene, or a file (required)",
     NULL},
    {"frames", 0, OPTAB_INT, OF(frames), 1, 100000, "100", "N", "frames spread evenly over the path", NULL},
    /* §5: 1,000 to 4,000 samples per frame */
    {"samples-per-frame", 0, OPTAB_INT, OF(spp_frame), 0, 1 << 24, "1000", "K", "high-quality samples per frame", NULL},
    {"hold", 0, OPTAB_FLAG, OF(hold), 0, 0, NULL, NULL, "keep older samples in their pixels (stale)", NULL},
    /* §5: 1024x1024 display */
    {"width", 0, OPTAB_INT, OF(width), 1, 16384, "1024", "W", "image width", NULL},
    {"height", 0, OPTAB_INT, OF(height), 1, 16384, "1024", "H", "image height", NULL},
    {"seed", 0, OPTAB_U64, OF(seed), 0, 1.8446744073709552e19, "1", "S", "random seed (pixel choice and tracing)", NULL},
    {"threads", 0, OPTAB_INT, OF(threads), 1, MAX_THREADS, "1", "T", "worker threads", NULL},
    {"reference", 0, OPTAB_STRING, OF(ref), 0, 0, NULL, "DIR", "per-frame RMSE/PSNR/SSIM against DIR/frame_NNNNN.exr",
     NULL},
    {"exposure", 0, OPTAB_FLOAT, OF(exposure), -30, 30, "0", "E", "stops for the PNG frames", NULL},
    {"no-png", 0, OPTAB_FLAG, OF(no_png), 0, 0, NULL, NULL, "EXR frames only", NULL},
    {"output", 'o', OPTAB_STRING, OF(out), 0, 0, NULL, "DIR", "output folder (required)", NULL},
    {"quiet", 'q', OPTAB_FLAG, OF(quiet), 0, 0, NULL, NULL, "errors only", NULL},
};
#undef OF

static void usage(FILE *f)
{
    fprintf(f,
            "usage: corrtex naive SCENE.json --mesh FILE.ctmesh --path P -o DIR [options]\n"
            "Baselines for the walkthrough benchmark, without corrective textures:\n"
            "  --samples-per-frame 0   radiosity alone (Gouraud radiosity at each pixel's hit)\n"
            "  --samples-per-frame K   radiosity plus K high-quality samples per frame, each\n"
            "                          filling only its own pixel (point display, no reprojection)\n"
            "Writes DIR/frame_NNNNN.exr (and .png) per frame and DIR/frames.csv.\n\n"
            "options:\n");
    optab_usage(OPTS, OPTAB_COUNT(OPTS), NULL, f);
    size_t n;
    const optab *t = trc_cli_table(&n);
    optab_usage(t, n, NULL, f);
    fprintf(f, "  -h, --help                   this help\n"
               "The last line on stdout is 'stats: key=value ...' (frames, samples, seconds,\n"
               "samples_per_s, base_s, sample_s, and mean_rmse, mean_psnr with --reference).\n"
               "exit status: 0 ok, 1 runtime failure, 2 bad input or usage\n");
}

/* ---- the run ------------------------------------------------------------ */

/* Requests traced at once: bands of image rows, chunks of picked pixels. */
#define CHUNK 65536

typedef struct naive_run {
    const naive_opts *o;
    const trc_tracer *trc;
    ct_pool *pool;
    trc_view view;
    uint32_t frame;
    ct_image img;           /* the frame being built */
    uint32_t *perm;         /* a permutation of the pixels: sampling order */
    size_t npx, cursor;     /* next unsampled position in perm (--hold) */
    const uint32_t *picks;  /* this frame's K pixels */
    size_t npicks;
    float *held;            /* --hold: last sample value per pixel */
    uint8_t *held_mask;
    ct_request *req;        /* CHUNK of each */
    ct_sample *smp;
} naive_run;

/* A request at pixel p's centre. */
static ct_request pixel_request(const naive_run *r, uint32_t p)
{
    uint32_t w = (uint32_t)r->o->width;
    return (ct_request){.id = (uint64_t)r->frame * r->npx + p + 1, .epoch = r->frame,
                        .px = (float)(p % w) + 0.5f, .py = (float)(p / w) + 0.5f, .radius = 0.5f};
}

/* Radiosity alone: L_base at every pixel centre. */
static void base_pass(naive_run *r)
{
    for (size_t a = 0; a < r->npx; a += CHUNK) {
        size_t n = r->npx - a < CHUNK ? r->npx - a : CHUNK;
        for (size_t i = 0; i < n; i++) r->req[i] = pixel_request(r, (uint32_t)(a + i));
        trc_trace_par(r->trc, r->pool, &r->view, r->req, n, r->smp, true, NULL);
        for (size_t i = 0; i < n; i++) memcpy(r->img.px + 3 * (a + i), &r->smp[i].l_base, 3 * sizeof(float));
    }
}

/* K high-quality samples, each at its pixel's centre, written to that pixel. */
static void sample_pass(naive_run *r)
{
    for (size_t a = 0; a < r->npicks; a += CHUNK) {
        size_t n = r->npicks - a < CHUNK ? r->npicks - a : CHUNK;
        for (size_t i = 0; i < n; i++) r->req[i] = pixel_request(r, r->picks[a + i]);
        trc_trace_par(r->trc, r->pool, &r->view, r->req, n, r->smp, false, NULL);
        for (size_t i = 0; i < n; i++) {
            uint32_t p = r->picks[a + i];
            memcpy(r->img.px + 3 * (size_t)p, &r->smp[i].l_hq, 3 * sizeof(float));
            if (r->held) {
                memcpy(r->held + 3 * (size_t)p, &r->smp[i].l_hq, 3 * sizeof(float));
                r->held_mask[p] = 1;
            }
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
    char *csv = NULL;
    size_t csv_len = 0, csv_cap = 0;
    int have_path = 0;
    r.req = malloc(CHUNK * sizeof *r.req);
    r.smp = malloc(CHUNK * sizeof *r.smp);
    int rc = r.req && r.smp ? CT_OK : ct_fail(err, CT_ENOMEM, "out of memory");
    if (!rc) rc = pool_new(o->threads, &r.pool, err);
    if (!rc) rc = scene_load(o->scene, &scene, err);
    if (!rc) rc = rmesh_load(o->mesh, 0, &mesh, err);
    if (!rc) {
        /* (a copy of the scene's path: path is freed as a loaded one is) */
        ct_campath own = {0};
        const ct_campath *p = scene_path_or_file(scene, o->scene, o->path, &own, err);
        if (!p) rc = CT_EINVAL;
        else if (p == &own) path = own;
        else rc = campath_from_keys(p->keys, p->nkeys, p->up, o->path, &path, err);
        have_path = !rc;
    }
    if (!rc && (rc = trc_new(scene, &mesh, &o->trc, &trc, err)) == CT_ESTALE) ct_error_prefix(err, o->mesh);
    if (!rc) rc = img_alloc(&r.img, o->width, o->height, err);
    r.o = o;
    r.trc = trc;
    r.npx = (size_t)o->width * (size_t)o->height;
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
    /* The output folder last, once every input has been read and checked. */
    if (!rc) rc = fs_mkdirs(o->out, err);
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
        base_pass(&r);
        if (r.held)
            for (size_t p = 0; p < r.npx; p++)
                if (r.held_mask[p]) memcpy(r.img.px + 3 * p, r.held + 3 * p, 3 * sizeof(float));
        double t1 = ct_now();
        if (o->spp_frame > 0) {
            choose_pixels(&r, (size_t)o->spp_frame);
            sample_pass(&r);
            samples += r.npicks;
        }
        double t2 = ct_now();
        base_s += t1 - t0;
        sample_s += t2 - t1;
        char name[64], file[4096];
        snprintf(name, sizeof name, "frame_%05d.exr", k);
        fs_join(o->out, name, file, sizeof file);
        rc = img_write_exr(file, &r.img, IMG_HALF, err);
        if (!rc && !o->no_png) {
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
    free(r.req);
    free(r.smp);
    pool_free(r.pool);
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

/* Bad arguments found before anything is made (the output folder used to
 * be created first, and a reference frame found missing after the frames
 * before it were written). */
static int check_args(const naive_opts *o, ct_error *err)
{
    size_t npx = (size_t)o->width * (size_t)o->height;
    if ((size_t)o->spp_frame > npx)
        return ct_fail(err, CT_EINVAL, "--samples-per-frame %d exceeds the %zu pixels of a frame", o->spp_frame,
                       npx);
    int rc = trc_cli_check(&o->cli, err);
    if (rc == 0) rc = fs_folder_check("-o", o->out, err);
    if (rc) return rc;
    for (int k = 0; o->ref && k < o->frames; k++) {
        char name[64], file[4096];
        snprintf(name, sizeof name, "frame_%05d.exr", k);
        fs_join(o->ref, name, file, sizeof file);
        FILE *f;
        size_t size;
        if ((rc = fs_open_regular(file, &f, &size, err))) {
            ct_error_prefix(err, "--reference");
            return rc;
        }
        fclose(f);
    }
    return CT_OK;
}

int cmd_naive(int argc, char **argv)
{
    naive_opts o;
    memset(&o, 0, sizeof o);
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), &o, &err);
    size_t ntr;
    const optab *ttr = trc_cli_table(&ntr);
    optab_defaults(ttr, ntr, &o.cli, &err);
    optab_group g[2] = {{OPTS, OPTAB_COUNT(OPTS), &o}, {ttr, ntr, &o.cli}};
    const char *pos[1];
    int npos = 0;
    int rc = optab_parse(g, 2, argc, argv, pos, 1, &npos, &err);
    if (rc == 1) {
        usage(stdout);
        return 0;
    }
    if (o.quiet) ct_log_set_level(CT_LOG_ERROR);
    if (rc) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return 2;
    }
    trc_cli_apply(&o.cli, &o.trc);
    o.trc.seed = o.seed;
    if (npos != 1) {
        ct_log(CT_LOG_ERROR, COMPONENT, "expected one scene file, got %d (try --help)", npos);
        return 2;
    }
    o.scene = pos[0];
    const char *missing = !o.mesh ? "--mesh FILE.ctmesh" : !o.path ? "--path P" : !o.out ? "-o DIR" : NULL;
    if (missing) {
        ct_log(CT_LOG_ERROR, COMPONENT, "missing %s (try --help)", missing);
        return 2;
    }
    if (check_args(&o, &err)) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return 2;
    }
    rc = run(&o, &err);
    if (rc) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return (rc == CT_ENOMEM || rc == CT_ESYS) ? 1 : 2;
    }
    return 0;
}
