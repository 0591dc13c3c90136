/* corrtex converge: the master's session (master/session.h) and the real
 * tracer in one process, for a still camera: the loop (master/drive.h)
 * over the in-process tracer port (tracer/tport_local.h) traces the samples
 * the adaptive queue chooses (§3.7), the session splats them (§3.4), and at
 * each checkpoint (a lockstep frame of the loop) the files sink
 * (master/fsink.h) writes the corrected image the display would draw
 * (software compositor), the sample positions (Fig. 7 right), the texture
 * assignment (Fig. 5) and a row of convergence.csv. --move-to moves the
 * camera without updates and traces more samples (Fig. 7). --record FILE
 * keeps every sample for the saturation benchmark. Exit 0 ok, 2 bad input
 * or usage. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "cli/corrtex/commands.h"
#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/optab.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/timer.h"
#include "master/ctex.h"
#include "master/drive.h"
#include "master/fsink.h"
#include "master/sampler.h"
#include "master/session.h"
#include "proto/srec.h"
#include "radiosity/radiosity.h"
#include "tracer/tport_local.h"
#include "tracer/tracer.h"
#include "tracer/trc_cli.h"

#define COMPONENT "corrtex converge"
#define MAX_CHECKPOINTS 64
#define CK_ALL (-1L)   /* "all": until every pixel has been sampled */

typedef struct conv_opts {
    const char *camera, *samples, *samples_after, *move_to, *out, *reference, *reference_after, *mesh, *record;
    int width, height, batch, threads, insert_runs, aa;
    trc_cli trc;   /* the tracer's options */
    uint64_t seed;
    float exposure, stand_in;
    bool time_insert, quiet, verbose, pop_ahead;
} conv_opts;

#define OF(f) offsetof(conv_opts, f)
static const optab OPTS[] = {
    {"camera", 0, OPTAB_STRING, OF(camera), 0, 0, NULL, "NAME", "scene camera (default: the first)", NULL},
    {"samples", 0, OPTAB_STRING, OF(samples), 0, 0, NULL, "LIST", "checkpoints, increasing (required)", NULL},
    {"width", 0, OPTAB_INT, OF(width), 1, 16384, "512", "W", "image width", NULL},
    {"height", 0, OPTAB_INT, OF(height), 1, 16384, "512", "H", "image height", NULL},
    {"reference", 0, OPTAB_STRING, OF(reference), 0, 0, NULL, "REF.exr", "reference for RMSE/PSNR/SSIM", NULL},
    {"out", 'o', OPTAB_STRING, OF(out), 0, 0, NULL, "DIR", "output folder (required)", NULL},
    {"move-to", 0, OPTAB_STRING, OF(move_to), 0, 0, NULL, "NAME",
     "then move to this camera without updates (moved.exr) ...", NULL},
    {"samples-after", 0, OPTAB_STRING, OF(samples_after), 0, 0, NULL, "LIST",
     "... and trace these many more samples (after_*.png)", NULL},
    {"reference-after", 0, OPTAB_STRING, OF(reference_after), 0, 0, NULL, "REF", "reference for the moved camera (with --move-to)",
     NULL},
    {"mesh", 0, OPTAB_STRING, OF(mesh), 0, 0, NULL, "FILE.ctmesh",
     "radiosity cache: loaded when it holds this scene's solution at the default parameters, else solved (default "
     "parameters) and written there, with a warning when it held another scene's or other parameters' solution; a file "
     "that is not a .ctmesh is refused (default: solve, no cache)", NULL},
    {"stand-in", 0, OPTAB_FLOAT, OF(stand_in), 0, 1e6, NULL, "A",
     "interactive solution: the constant stand-in (emission + diffuse x A per material) instead of radiosity "
     "(tests)", NULL},
    {"aa", 0, OPTAB_INT, OF(aa), 1, 4, "2", "N",
     "the compositor's primary hits per pixel side (N x N, averaged): the display's multisampling; 1: the pixel "
     "centre only", NULL},
    {"batch", 0, OPTAB_INT, OF(batch), 1, 65536, "256", "B", "requests per batch (a lockstep round)", NULL},
    {"pop-ahead", 0, OPTAB_FLAG, OF(pop_ahead), 0, 0, NULL, NULL,
     "pop each batch's successor ahead of its reports (corrtex-render --pop-ahead; docs/sampling.md)", NULL},
    {"threads", 0, OPTAB_INT, OF(threads), 1, POOL_MAX_THREADS, "2", "T", "tracing threads", NULL},
    {"seed", 0, OPTAB_U64, OF(seed), 0, 1.8446744073709552e19, "1", "S", "seed of the queue and the tracer", NULL},
    {"exposure", 0, OPTAB_FLOAT, OF(exposure), -30, 30, "0", "E", "PNG exposure (stops)", NULL},
    {"record", 0, OPTAB_STRING, OF(record), 0, 0, NULL, "FILE",
     "write every sample to FILE (proto/srec.h), for scripts/bench-master --part saturation", NULL},
    {"time-insert", 0, OPTAB_FLAG, OF(time_insert), 0, 0, NULL, NULL,
     "replay all samples into a fresh engine and print the insertion rate (one thread, CPU time)", NULL},
    {"insert-runs", 0, OPTAB_INT, OF(insert_runs), 1, 1000, "1", "N", "replays for --time-insert; the median is reported",
     NULL},
    {"quiet", 'q', OPTAB_FLAG, OF(quiet), 0, 0, NULL, NULL, "warnings and errors only", NULL},
    {"verbose", 0, OPTAB_FLAG, OF(verbose), 0, 0, NULL, NULL, "debug lines too", NULL},
};
#undef OF

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
            "options:\n");
    optab_usage(OPTS, OPTAB_COUNT(OPTS), NULL, f);
    size_t n;
    const optab *t = trc_cli_table(&n);
    fprintf(f, "tracer options (docs/tracer.md):\n");
    optab_usage(t, n, NULL, f);
    t = sess_options_table(&n);
    optab_usage(t, n, NULL, f);
    fprintf(f, "request queue options (docs/sampling.md; here --refine-error defaults to 0:\n"
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

/* Primary hits at aa x aa stratified points of every pixel (its centre for
 * aa = 1), pixel by pixel: what the display shows, for the compositor. The
 * reference images average over the whole pixel, so a compositor that took
 * the centre alone would count the edges' aliasing as error. */
static int primary_hits(const trc_tracer *t, ct_pool *pool, const ct_camera *cam, int w, int h, int aa,
                        uint32_t epoch, ctex_hit *hits, ct_error *err)
{
    size_t spp = (size_t)aa * (size_t)aa, n = (size_t)w * (size_t)h * spp;
    /* in chunks: the records of all aa x aa hits of a large view would not fit */
    size_t chunk = n < ((size_t)1 << 20) ? n : ((size_t)1 << 20);
    ct_request *req = calloc(chunk, sizeof *req);
    ct_sample *s = calloc(chunk, sizeof *s);
    if (!req || !s) {
        free(req);
        free(s);
        return ct_fail(err, CT_ENOMEM, "out of memory for %zu primary hits", chunk);
    }
    trc_view v = {*cam, w, h};
    for (size_t b = 0; b < n; b += chunk) {
        size_t m = n - b < chunk ? n - b : chunk;
        for (size_t j = 0; j < m; j++) {
            size_t i = b + j, pix = i / spp, sub = i % spp;
            req[j].id = i + 1;
            req[j].epoch = epoch;
            req[j].px = (float)(pix % (size_t)w) + ((float)(sub % (size_t)aa) + 0.5f) / (float)aa;
            req[j].py = (float)(pix / (size_t)w) + ((float)(sub / (size_t)aa) + 0.5f) / (float)aa;
        }
        trc_trace_par(t, pool, &v, req, m, s, true, NULL);
        for (size_t j = 0; j < m; j++) {
            ctex_hit *o = &hits[b + j];
            int hit = (s[j].flags & CT_SAMPLE_HIT) != 0;
            o->node = hit ? s[j].node : UINT32_MAX;
            o->tri = hit ? s[j].tri : UINT32_MAX;
            o->p = s[j].hit;
            o->l_base = hit ? s[j].l_base : v3s(0.0f);
        }
    }
    free(req);
    free(s);
    return CT_OK;
}

/* --- recording ------------------------------------------------------------------- */

typedef struct recorder {
    ct_sample *s;
    size_t n, cap;
    size_t phase_start;   /* index of the first sample after --move-to */
    int failed;           /* out of memory: the recording is incomplete */
    sink next;            /* the files sink */
} recorder;

/* Keeps the inserted samples, then passes them on to the files sink. */
static void rec_samples(void *user, const ct_sample *s, uint32_t n)
{
    recorder *r = user;
    if (!r->failed && r->n + n > r->cap) {
        size_t nc = r->cap ? 2 * r->cap : 65536;
        while (nc < r->n + n) nc *= 2;
        ct_sample *ns = realloc(r->s, nc * sizeof *ns);
        if (ns) {
            r->s = ns;
            r->cap = nc;
        } else {
            r->failed = 1;
        }
    }
    if (!r->failed) {
        memcpy(r->s + r->n, s, n * sizeof *s);
        r->n += n;
    }
    r->next.samples(r->next.user, s, n);
}

static int rec_frame(void *user, sess *s, const sink_frame *f, ct_error *err)
{
    recorder *r = user;
    return r->next.frame(r->next.user, s, f, err);
}

/* --- the phases ---------------------------------------------------------------------- */

typedef struct run {
    const conv_opts *o;
    const trc_tracer *t;
    ct_pool *pool;
    sess *s;
    drv *d;
    fsink *fk;
    ctex_hit *hits;
} run;

/* A view and its checkpoints: snapshot without new samples (snap, "radiosity"
 * or "moved"), the assignment, then one lockstep frame per checkpoint. */
static int phase(run *r, const ct_camera *cam, uint32_t epoch, const char *name, const char *prefix, const char *snap,
                 const char *ref, const long *ck, int nck, ct_error *err)
{
    int W = r->o->width, H = r->o->height, rc;
    if ((rc = primary_hits(r->t, r->pool, cam, W, H, r->o->aa, epoch, r->hits, err))) return rc;
    double tc = ct_now();
    if ((rc = drv_set_view(r->d, cam, W, H, err)) < 0) return rc;
    if (epoch > 0) {
        ctex_stats cs = ctex_get_stats(sess_textures(r->s));
        ct_info(COMPONENT, "camera change without updates: %.1f ms (aging, reassignment, reprojection, shown-node map); "
                "%u textures, %u parked, %llu texels", 1e3 * (ct_now() - tc), cs.textures, cs.parked,
                (unsigned long long)cs.texels);
    }
    char stem[64];
    snprintf(stem, sizeof stem, "%sassignment", prefix);
    if ((rc = fsink_phase(r->fk, name, prefix, r->hits, r->o->aa * r->o->aa, ref, err)) ||
        (rc = fsink_snapshot(r->fk, r->s, snap, err)) ||
        (rc = fsink_assignment(r->fk, r->s, stem, err)))
        return rc;
    uint64_t first = sess_get_counters(r->s).inserted;
    for (int k = 0; k < nck; k++) {
        long done = (long)(sess_get_counters(r->s).inserted - first);
        drv_begin_frame(r->d, ck[k] == CK_ALL ? UINT32_MAX : (uint32_t)(ck[k] - done));
        while (drv_in_frame(r->d))
            if ((rc = drv_step(r->d, err)) < 0) return rc;
        done = (long)(sess_get_counters(r->s).inserted - first);
        if (ck[k] != CK_ALL && done < ck[k])
            ct_warn(COMPONENT, "every pixel was sampled after %ld of %ld samples", done, ck[k]);
    }
    return fsink_end_phase(r->fk, err);
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

static void rad_progress(void *user, double fraction, const char *what)
{
    (void)user;
    ct_progress("radiosity", fraction, fraction >= 1.0, "%s", what);
}

/* The interactive solution: the constant stand-in when asked for (tests,
 * throughput), else hierarchical radiosity with default parameters, loaded
 * from or written to the cache file when one is given (stale caches are
 * recomputed). A cache file whose node table is not this scene's is solved
 * over with a warning naming it (corrtex-render --mesh and reference
 * --radmesh, whose file is an input, refuse it by the same check). */
static int load_mesh(const ct_scene *s, float stand_in, const char *cache, ct_radmesh *m, ct_error *err)
{
    if (stand_in >= 0.0f) {
        ct_info(COMPONENT, "interactive solution: the constant stand-in (ambient %g)", (double)stand_in);
        return rmesh_from_scene(s, v3s(stand_in), m, err);
    }
    rad_params p;
    rad_params_default(&p);
    rad_stats st;
    int from_cache = 0;
    ct_error why;
    double t0 = ct_now();
    /* The cache is read once: why it cannot serve (missing, stale, another
     * scene's) is known from that read. */
    if (cache && rmesh_load(cache, 0, m, &why) == CT_OK) {
        uint64_t want = rad_solution_hash(s, &p);
        /* A node table that is not this scene's: another scene's cache, or
         * this one's from before its meshes changed (which a refusal would
         * make the user delete by hand). A cache either way, solved over,
         * but said aloud: it used to be an info line. */
        if (rmesh_check_nodes(m, s, &why))
            ct_warn(COMPONENT, "%s: the radiosity mesh of another scene, or of this one before its meshes changed (%s): "
                    "solving over it (the file is replaced)", cache, why.msg);
        else if (m->scene_hash == want)
            from_cache = 1;
        else {
            /* This scene's, but not the defaults' (corrtex radiosity with
             * options) or an older solver's: replaced, said aloud. */
            ct_fail(&why, CT_ESTALE,
                    "%s: solved with other parameters or another solver version (solution hash %016llx, expected "
                    "%016llx for the defaults)",
                    cache, (unsigned long long)m->scene_hash, (unsigned long long)want);
            ct_warn(COMPONENT, "%s: solving at the defaults over it (the file is replaced)", why.msg);
        }
        if (!from_cache) rmesh_free(m);
    }
    if (!from_cache) {
        int rc = rad_solve(s, &p, rad_progress, NULL, m, &st, err);
        if (rc == 0 && cache && (rc = rmesh_save(m, cache, err))) rmesh_free(m);
        if (rc) return rc;
    }
    if (from_cache)
        ct_info(COMPONENT, "interactive solution: %s (%u triangles, cached)", cache, m->ntris);
    else if (cache)
        ct_info(COMPONENT, "interactive solution: radiosity, %u triangles in %.1f s, written to %s (%s)",
                m->ntris, ct_now() - t0, cache, why.msg);
    else
        ct_info(COMPONENT, "interactive solution: radiosity, %u triangles in %.1f s", m->ntris, ct_now() - t0);
    return CT_OK;
}

/* A reference of the run's size, read before any work (in its phase it was
 * found after --out was made; --reference-after, after phase 1 wrote there). */
static int check_reference(const char *ref, int width, int height, ct_error *err)
{
    ct_image img = {0};
    int rc = img_read_exr(ref, &img, err);
    if (!rc && (img.width != width || img.height != height))
        rc = ct_fail(err, CT_EINVAL, "%s is %dx%d, the run is %dx%d", ref, img.width, img.height, width, height);
    img_free(&img);
    return rc;
}

int cmd_converge(int argc, char **argv)
{
    ct_error err = {{0}};
    conv_opts o;
    memset(&o, 0, sizeof o);
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), &o, &err);
    o.stand_in = -1.0f;
    ctex_options co = ctex_options_default();
    rq_options ro;
    rq_options_default(&ro);
    /* The paper's figures count samples up to one per pixel: no refinement
     * past it unless asked (--refine-error). */
    ro.refine_error = 0.0f;
    sess_options so;
    drv_options dopt;
    size_t nrq, nct, nss, ndr, ntr;
    const optab *trq = rq_options_table(&nrq), *tct = ctex_options_table(&nct), *tss = sess_options_table(&nss),
                *tdr = drv_options_table(&ndr), *ttr = trc_cli_table(&ntr);
    optab_defaults(tss, nss, &so, &err);
    optab_defaults(tdr, ndr, &dopt, &err);
    optab_defaults(ttr, ntr, &o.trc, &err);
    optab_group g[] = {{OPTS, OPTAB_COUNT(OPTS), &o}, {ttr, ntr, &o.trc}, {tss, nss, &so}, {trq, nrq, &ro},
                       {tct, nct, &co}};
    const char *pos[1];
    int npos = 0;
    int prc = optab_parse(g, 5, argc, argv, pos, 1, &npos, &err);
    if (prc == 1) {
        usage(stdout);
        return 0;
    }
    if (o.quiet) ct_log_set_level(CT_LOG_WARN);
    if (o.verbose) ct_log_set_level(CT_LOG_DEBUG);
    if (prc) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return 2;
    }
    long ck[MAX_CHECKPOINTS], ck2[MAX_CHECKPOINTS];
    int nck = 0, nck2 = 0;
    if (!npos || !o.samples || !o.out) {
        ct_log(CT_LOG_ERROR, COMPONENT, "need SCENE, --samples and --out (try --help)");
        return 2;
    }
    if (parse_list(o.samples, ck, &nck, "--samples", &err) ||
        (o.samples_after && parse_list(o.samples_after, ck2, &nck2, "--samples-after", &err)) ||
        rq_options_check(&ro, &err) || trc_cli_check(&o.trc, &err)) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return 2;
    }
    if (!!o.move_to != !!o.samples_after || (o.reference_after && !o.move_to)) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", o.move_to || !o.reference_after ? "--move-to and --samples-after go together"
               : "--reference-after needs --move-to: it is the moved camera's reference");
        return 2;
    }
    /* (before the scene is read and --out made: found after both, it left
     * an empty output folder behind) */
    if (o.mesh && o.stand_in >= 0.0f) {
        ct_log(CT_LOG_ERROR, COMPONENT, "give --mesh or --stand-in, not both");
        return 2;
    }
    /* --record is written at the end of the run: one that cannot be (its
     * folder missing) is found now. */
    if (o.record && fs_output_check(o.record, &err)) {
        ct_log(CT_LOG_ERROR, COMPONENT, "--record %s", err.msg);
        return 2;
    }
    /* (an --out that is a file was found after the solve, when convergence.csv
     * could not be made in it) */
    if (fs_folder_check("--out", o.out, &err) ||
        (o.reference && check_reference(o.reference, o.width, o.height, &err)) ||
        (o.reference_after && check_reference(o.reference_after, o.width, o.height, &err))) {
        ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
        return 2;
    }
    const char *scene_path = pos[0];
    ct_scene *scene = NULL;
    ct_radmesh mesh = {0};
    trc_tracer *tr = NULL;
    ct_pool *pool = NULL;
    tport *port = NULL;
    recorder rec = {0};
    run r = {.o = &o};
    int status = 2, rc;
    double t0 = ct_now();

    if ((rc = scene_load(scene_path, &scene, &err))) goto fail;
    if (scene->ncams == 0 && !o.camera) { rc = ct_fail(&err, CT_EINVAL, "%s has no camera", scene_path); goto fail; }
    int ci = o.camera ? scene_find_camera(scene, o.camera) : 0;
    if (ci < 0) { rc = ct_fail(&err, CT_EINVAL, "%s has no camera '%s'", scene_path, o.camera); goto fail; }
    int ci2 = -1;
    if (o.move_to && (ci2 = scene_find_camera(scene, o.move_to)) < 0) {
        rc = ct_fail(&err, CT_EINVAL, "%s has no camera '%s'", scene_path, o.move_to);
        goto fail;
    }
    ct_camera cam = scene->cams[ci].cam, cam2 = ci2 >= 0 ? scene->cams[ci2].cam : cam;
    /* (before a solve that would end in a refusal) */
    if (o.mesh && (rc = rmesh_output_check(o.mesh, &err))) goto fail;
    if ((rc = load_mesh(scene, o.stand_in, o.mesh, &mesh, &err))) goto fail;
    trc_options to;
    trc_cli_apply(&o.trc, &to);
    to.seed = o.seed;
    if ((rc = trc_new(scene, &mesh, &to, &tr, &err)) || (rc = pool_new(o.threads, &pool, &err)) ||
        (rc = tport_local_new(tr, pool, 1, &port, &err)))
        goto fail;
    sess_config sc = {&mesh, scene->mats, scene->nmats, &ro, &co, o.seed, so};
    if ((rc = sess_new(&sc, &r.s, &err))) goto fail;
    {
        ctex_stats st = ctex_get_stats(sess_textures(r.s));
        ct_info(COMPONENT, "texture hierarchy: %u nodes, %u leaves", st.hier_nodes, st.hier_leaves);
    }
    /* The output folder last, once every input has been read and checked. */
    if ((rc = fs_mkdirs(o.out, &err))) goto fail;
    fsink_config fc = {o.out, o.exposure, o.width, o.height};
    if ((rc = fsink_new(&fc, &r.fk, &err))) goto fail;
    rec.next = fsink_sink(r.fk);
    sink k = o.time_insert || o.record ? (sink){&rec, rec_samples, rec_frame} : rec.next;
    dopt.round = o.batch;
    dopt.pop_ahead = o.pop_ahead;
    if ((rc = drv_new(r.s, port, &k, &dopt, &r.d, &err))) goto fail;
    drv_set_lockstep(r.d, true);
    r.t = tr;
    r.pool = pool;
    if (!(r.hits = malloc((size_t)o.width * (size_t)o.height * (size_t)o.aa * (size_t)o.aa * sizeof *r.hits))) {
        rc = ct_fail(&err, CT_ENOMEM, "out of memory for a %dx%d run", o.width, o.height);
        goto fail;
    }
    /* phase 1: the still camera; phase 2: moved without updates, then more samples (Fig. 7) */
    if ((rc = phase(&r, &cam, 0, "still", "", "radiosity", o.reference, ck, nck, &err))) goto fail;
    rec.phase_start = rec.n;
    if (ci2 >= 0 && (rc = phase(&r, &cam2, 1, "after", "after_", "moved", o.reference_after, ck2, nck2, &err)))
        goto fail;
    const char *csv_path = NULL;
    if ((rc = fsink_commit(r.fk, &csv_path, &err))) goto fail;
    trc_stats ts = tport_local_stats(port);
    ct_info(COMPONENT, "traced %llu samples (%llu rays) in %.1f s; wrote %s", (unsigned long long)ts.samples,
            (unsigned long long)trc_stats_rays(&ts), ct_now() - t0, csv_path);
    if ((o.record || o.time_insert) && rec.failed) {
        rc = ct_fail(&err, CT_ENOMEM, "out of memory recording the samples");
        goto fail;
    }
    if (o.record && (rc = srec_write(o.record, rec.s, rec.n, &err))) goto fail;
    if (o.record) ct_info(COMPONENT, "recorded %zu samples in %s", rec.n, o.record);
    if (o.time_insert && (rc = time_insert(&mesh, scene, &co, &rec, &cam, ci2 >= 0 ? &cam2 : NULL, o.width, o.height,
                                           o.batch, o.insert_runs, &err)))
        goto fail;
    status = 0;
    goto done;
fail:
    ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
    status = 2;
done:
    drv_free(r.d);
    fsink_free(r.fk);
    sess_free(r.s);
    if (port) port->ops->close(port, 0);
    pool_free(pool);
    free(r.hits);
    free(rec.s);
    trc_free(tr);
    rmesh_free(&mesh);
    scene_free(scene);
    return status;
}
