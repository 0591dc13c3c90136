/* bench_rq: requests handled per second by the master's sample acquisition
 * (master/sampler.h) on one core: pop (rq_next_batch, with mask discards)
 * and report (rq_report: norm, significance, children with mask/threshold
 * checks), in lockstep batches, with synthetic samples. Prints one markdown
 * table row per scenario; scripts/bench-master writes them into
 * docs/benchmarks.md.
 *   bench_rq [--width W] [--height H] [--batch N] [--seed S] [--header]
 *            [--scenario disc|zero|moving] [--repeat R]
 * Times are medians of R runs (default 5), each with a fresh engine; the
 * rate uses the thread's CPU time. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "common/log.h"
#include "common/timer.h"
#include "master/sampler.h"

typedef struct scene {
    int w, h;
    int ndisc;
    float dx[8], dy[8], dr[8];
} scene;

/* Synthetic error field: a few bright discs (|E| = 1) on a dim background
 * (|E| = 0.02), or zero everywhere. */
static vec3 field(const scene *sc, float px, float py)
{
    for (int i = 0; i < sc->ndisc; i++) {
        float x = px - sc->dx[i], y = py - sc->dy[i];
        if (x * x + y * y < sc->dr[i] * sc->dr[i]) return v3(1.0f, 0.6f, 0.3f);
    }
    return sc->ndisc ? v3(0.02f, 0.01f, 0.0f) : v3s(0.0f);
}

static void usage(FILE *f)
{
    fprintf(f, "usage: bench_rq [--width W] [--height H] [--batch N] [--seed S] [--header]\n"
               "                [--scenario disc|zero|moving] [--repeat R]\n"
               "defaults: 1024 1024 256 1 disc 5; times are medians of R runs\n");
}

/* CPU time of this thread: on a shared machine it measures the work, not
 * the waiting for a core. */
static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* One run to the end of the scenario: returns 0 and fills *wall, *cpu, *st. */
static int run_once(const scene *sc, int w, int h, int bs, unsigned long long seed, int moving,
                    double *wall, double *cpu, rq_stats *st)
{
    ct_camera cam = cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), 60.0f);
    rq_engine *e = NULL;
    ct_error err;
    if (rq_new(&e, w, h, &cam, NULL, seed, &err) != 0) {
        ct_log(CT_LOG_ERROR, "bench_rq", "%s", err.msg);
        return 1;
    }
    ct_request *req = malloc((size_t)bs * sizeof *req);
    int rc = 1;
    if (!req) goto done;
    /* The moving scenario: a new camera every 4,000 samples (§5: 1,000-4,000
     * samples per frame), panning slowly, for as many samples as pixels. */
    const uint64_t frame = 4000, budget = (uint64_t)w * (uint64_t)h;
    uint32_t epoch = 0;
    uint64_t since = 0, handled = 0;
    ct_sample s;
    memset(&s, 0, sizeof s);
    s.flags = CT_SAMPLE_HIT;
    s.node = 1;
    double t0 = ct_now(), c0 = cpu_now();
    for (;;) {
        int k = rq_next_batch(e, req, bs, &err);
        if (k < 0) {
            ct_log(CT_LOG_ERROR, "bench_rq", "%s", err.msg);
            goto done;
        }
        if (k == 0) break;
        for (int i = 0; i < k; i++) {
            /* as the master's session reports: the records of a sample a few ahead asked for */
            if (i + 8 < k) {
                ct_sample ahead = {.request_id = req[i + 8].id, .px = req[i + 8].px, .py = req[i + 8].py};
                rq_report_prefetch(e, &ahead);
            }
            s.request_id = req[i].id;
            s.epoch = req[i].epoch;
            s.px = req[i].px;
            s.py = req[i].py;
            /* A world point on the plane z = -10 (cheap stand-in for a hit). */
            s.hit = v3((req[i].px / (float)w - 0.5f) * 11.5f, (0.5f - req[i].py / (float)h) * 11.5f, -10.0f);
            if (rq_report(e, &s, field(sc, req[i].px, req[i].py), 1, &err) < 0) {
                ct_log(CT_LOG_ERROR, "bench_rq", "%s", err.msg);
                goto done;
            }
        }
        handled += (uint64_t)k;
        if (moving) {
            since += (uint64_t)k;
            if (handled >= budget) break;
            if (since >= frame) {
                since = 0;
                ct_camera c2 = cam_look_at(v3(0.002f * (float)(epoch + 1), 0, 0),
                                           v3(0.002f * (float)(epoch + 1), 0, -1), v3(0, 1, 0), 60.0f);
                if (rq_set_camera(e, &c2, ++epoch, &err) != 0) {
                    ct_log(CT_LOG_ERROR, "bench_rq", "%s", err.msg);
                    goto done;
                }
            }
        }
    }
    *cpu = cpu_now() - c0;
    *wall = ct_now() - t0;
    rq_stats_get(e, st);
    rc = 0;
done:
    free(req);
    rq_free(e);
    return rc;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int main(int argc, char **argv)
{
    int w = 1024, h = 1024, bs = 256, header = 0, repeat = 5;
    unsigned long long seed = 1;
    const char *scen = "disc";
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "--header") == 0) { header = 1; continue; }
        if (strcmp(a, "--help") == 0) { usage(stdout); return 0; }
        if (!v) { usage(stderr); return 2; }
        if (strcmp(a, "--width") == 0) w = atoi(v);
        else if (strcmp(a, "--height") == 0) h = atoi(v);
        else if (strcmp(a, "--batch") == 0) bs = atoi(v);
        else if (strcmp(a, "--seed") == 0) seed = strtoull(v, NULL, 10);
        else if (strcmp(a, "--scenario") == 0) scen = v;
        else if (strcmp(a, "--repeat") == 0) repeat = atoi(v);
        else { usage(stderr); return 2; }
        i++;
    }
    int moving = strcmp(scen, "moving") == 0;
    if (w <= 0 || h <= 0 || bs <= 0 || bs > 1 << 20 || repeat < 1 || repeat > 64 ||
        (strcmp(scen, "disc") != 0 && strcmp(scen, "zero") != 0 && !moving)) {
        usage(stderr);
        return 2;
    }
    if (header) {
        printf("| scenario | image | batch | requests handed out | discarded by mask | children queued "
               "| discarded by threshold | peak queue | allocations | CPU s | wall s | M requests/s (CPU) |\n"
               "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
        return 0;
    }
    scene sc = {w, h, 0, {0}, {0}, {0}};
    if (strcmp(scen, "zero") != 0) {
        /* Five discs covering about 9 % of the image. */
        const float fx[5] = {0.3f, 0.7f, 0.5f, 0.15f, 0.8f}, fy[5] = {0.3f, 0.25f, 0.6f, 0.8f, 0.75f};
        const float fr[5] = {0.1f, 0.06f, 0.08f, 0.05f, 0.07f};
        sc.ndisc = 5;
        for (int i = 0; i < 5; i++) {
            sc.dx[i] = fx[i] * (float)w;
            sc.dy[i] = fy[i] * (float)h;
            sc.dr[i] = fr[i] * (float)(w < h ? w : h);
        }
    }
    double walls[64], cpus[64];
    rq_stats st, st0;
    memset(&st0, 0, sizeof st0);
    for (int r = 0; r < repeat; r++) {
        if (run_once(&sc, w, h, bs, seed, moving, &walls[r], &cpus[r], &st) != 0) return 1;
        /* Every run of the same scenario must do exactly the same work. */
        if (r == 0) st0 = st;
        else if (st.popped != st0.popped || st.children != st0.children ||
                 st.discarded_mask != st0.discarded_mask) {
            ct_log(CT_LOG_ERROR, "bench_rq", "run %d differs from run 0: not deterministic", r);
            return 1;
        }
    }
    qsort(walls, (size_t)repeat, sizeof walls[0], cmp_double);
    qsort(cpus, (size_t)repeat, sizeof cpus[0], cmp_double);
    double wall = walls[repeat / 2], cpu = cpus[repeat / 2];
    char scen_desc[96];
    if (moving) snprintf(scen_desc, sizeof scen_desc, "moving (%u camera changes)", st.epoch);
    else snprintf(scen_desc, sizeof scen_desc, "%s, still camera until the queue is idle%s", scen,
                  st.popped > st.total_pixels ? " (refined past full coverage)" : "");
    printf("| %s | %dx%d | %d | %llu | %llu | %llu | %llu | %llu | %llu | %.3f | %.3f | %.2f |\n", scen_desc, w, h,
           bs, (unsigned long long)st.popped, (unsigned long long)st.discarded_mask,
           (unsigned long long)st.children, (unsigned long long)st.discarded_threshold,
           (unsigned long long)st.peak_queued, (unsigned long long)st.allocations, cpu, wall,
           (double)st.popped / cpu * 1e-6);
    return 0;
}
