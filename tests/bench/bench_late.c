/* bench_late: are glossy samples traced from an eye the camera has left
 * worth putting in (master/ctex.h, ctex_insert_late_par)? A walk's batch in
 * flight, in one process over the real tracer: a session on the scene's
 * camera A takes a quarter of the view's pixels, traced and inserted; the
 * next 4,096 requests are traced from A while the eye steps sideways by d
 * to B; then they go in three ways: dropped when glossy (--late-deg 0, the
 * rule before), late (aged by §3.5's BRDF term, the option's value), or
 * popped again and traced fresh from B (what a tracer would have traced had
 * the camera not moved while it worked). Each is compared with a reference
 * of B (the mean of --ref-spp samples a pixel) on the pixels whose surface
 * is glossy: RMSE, and the RMS of the mean error over 4 x 4 blocks of the
 * view (a bias measure: a block's mean averages the samples' noise away).
 * Prints a markdown table, one row per step.
 *   bench_late SCENE CAMERA MESH|- [--late-deg X] [--unit U] [--size N]
 *              [--ref-spp N] [--steps "0.005 0.02 ..."]
 * MESH: a .ctmesh of the scene's radiosity solution, or - for the stand-in
 * (ambient 0.3); --unit: scene units per metre (cornell: 1000). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/camera.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "master/ctex.h"
#include "master/session.h"
#include "tracer/tracer.h"

enum { MAX_STEPS = 16, BLOCKS = 4, IN_FLIGHT = 4096 };

typedef struct bench {
    ct_scene *scene;
    ct_radmesh mesh;
    trc_tracer *tr;
    int w, h;
    float late_deg;
} bench;

static void usage(FILE *f)
{
    fprintf(f, "usage: bench_late SCENE CAMERA MESH|- [--late-deg X] [--unit U] [--size N] [--ref-spp N] "
               "[--steps \"D ...\"]\n");
}

static void trace(const bench *b, ct_camera cam, const ct_request *rq, size_t n, ct_sample *out, bool primary)
{
    trc_view v = {cam, b->w, b->h};
    trc_trace_par(b->tr, NULL, &v, rq, n, out, primary, NULL);
}

/* The batch in flight: 0 dropped, 1 late, 2 traced fresh from B. */
static sess *run(const bench *b, ct_camera A, ct_camera B, int how, ct_error *err)
{
    size_t n = (size_t)b->w * (size_t)b->h;
    rq_options ro;
    rq_options_default(&ro);
    ctex_options co = ctex_options_default();
    co.late_deg = how == 0 ? 0.0f : b->late_deg;
    sess_config c = {&b->mesh, b->scene->mats, b->scene->nmats, &ro, &co, 1, (sess_options){1, 0.0, 0.0}};
    sess *s = NULL;
    ct_request *rq = malloc(n * sizeof *rq);
    ct_sample *sm = malloc(n * sizeof *sm);
    int rc = !rq || !sm ? ct_fail(err, CT_ENOMEM, "out of memory") : sess_new(&c, &s, err);
    if (!rc && (rc = sess_set_view(s, &A, b->w, b->h, err)) > 0) rc = 0;
    int got = rc ? 0 : sess_next(s, rq, (uint32_t)(n / 4), err);
    if (!rc && got < 0) rc = got;
    if (!rc) {
        trace(b, A, rq, (size_t)got, sm, false);
        rc = sess_insert(s, sm, (uint32_t)got, NULL, err);
    }
    if (!rc && (got = sess_next(s, rq, IN_FLIGHT, err)) < 0) rc = got;
    if (!rc && how < 2) trace(b, A, rq, (size_t)got, sm, false);
    if (!rc && (rc = sess_set_view(s, &B, b->w, b->h, err)) > 0) rc = 0;
    if (!rc && how == 2) {
        if ((got = sess_next(s, rq, (uint32_t)got, err)) < 0) rc = got;
        else trace(b, B, rq, (size_t)got, sm, false);
    }
    if (!rc) rc = sess_insert(s, sm, (uint32_t)got, NULL, err);
    free(rq);
    free(sm);
    if (rc) {
        sess_free(s);
        return NULL;
    }
    return s;
}

int main(int argc, char **argv)
{
    bench b = {.w = 128, .h = 128, .late_deg = -1.0f};
    double unit = 1.0;
    int ref_spp = 32;
    float steps[MAX_STEPS] = {0.005f, 0.02f, 0.05f, 0.1f, 0.2f};
    int nsteps = 5;
    const char *pos[3];
    int npos = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        char *end = NULL;
        if (strcmp(a, "--help") == 0) { usage(stdout); return 0; }
        if (strncmp(a, "--", 2) != 0) {
            if (npos == 3) { usage(stderr); return 2; }
            pos[npos++] = a;
            continue;
        }
        if (!v) { usage(stderr); return 2; }
        i++;
        if (strcmp(a, "--late-deg") == 0) b.late_deg = strtof(v, &end);
        else if (strcmp(a, "--unit") == 0) unit = strtod(v, &end);
        else if (strcmp(a, "--size") == 0) b.w = b.h = (int)strtol(v, &end, 10);
        else if (strcmp(a, "--ref-spp") == 0) ref_spp = (int)strtol(v, &end, 10);
        else if (strcmp(a, "--steps") == 0) {
            nsteps = 0;
            const char *p = v;
            while (*p && nsteps < MAX_STEPS) {
                steps[nsteps++] = strtof(p, &end);
                if (end == p || !(steps[nsteps - 1] > 0.0f)) { end = (char *)p; break; }
                p = end;
                while (*p == ' ') p++;
            }
            if (*p) { fprintf(stderr, "error bench_late: --steps takes positive numbers, not '%s'\n", v); return 2; }
            continue;
        } else { usage(stderr); return 2; }
        if (!end || *end || end == v) { fprintf(stderr, "error bench_late: %s takes a number, not '%s'\n", a, v); return 2; }
    }
    if (npos != 3) { usage(stderr); return 2; }
    if (b.w < 16 || b.w > 4096 || ref_spp < 1 || !(unit > 0.0)) {
        fprintf(stderr, "error bench_late: --size takes 16-4096, --ref-spp and --unit positive values\n");
        return 2;
    }
    if (b.late_deg != -1.0f && !(b.late_deg >= 0.0f && b.late_deg <= 180.0f)) {
        fprintf(stderr, "error bench_late: --late-deg takes 0-180 degrees\n");
        return 2;
    }
    ct_error err;
    if (scene_load(pos[0], &b.scene, &err)) { fprintf(stderr, "error bench_late: %s\n", err.msg); return 1; }
    if (b.late_deg < 0.0f) b.late_deg = ctex_options_default().late_deg;
    int rc = strcmp(pos[2], "-") ? rmesh_load(pos[2], 0, &b.mesh, &err)
                                 : rmesh_from_scene(b.scene, v3s(0.3f), &b.mesh, &err);
    trc_options to;
    trc_options_default(&to, TRC_MODE_DRT);
    if (!rc) rc = trc_new(b.scene, &b.mesh, &to, &b.tr, &err);
    int ci = rc ? -1 : scene_find_camera(b.scene, pos[1]);
    if (!rc && ci < 0) rc = ct_fail(&err, CT_EINVAL, "%s: no camera '%s'", pos[0], pos[1]);
    if (rc) { fprintf(stderr, "error bench_late: %s\n", err.msg); return 1; }
    ct_camera A = b.scene->cams[ci].cam;
    vec3 right;
    cam_axes(&A, &right, NULL, NULL);
    size_t n = (size_t)b.w * (size_t)b.h;
    ct_sample *hit = calloc(n, sizeof *hit), *tmp = calloc(n, sizeof *tmp);
    ct_request *req = calloc(n, sizeof *req);
    vec3 *ref = calloc(n, sizeof *ref);
    if (!hit || !tmp || !req || !ref) { fprintf(stderr, "error bench_late: out of memory\n"); return 1; }
    printf("| step m | glossy pixels | RMSE dropped | RMSE late | RMSE fresh | block bias dropped | block bias late | "
           "block bias fresh | late in | of them glossy |\n");
    printf("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    for (int k = 0; k < nsteps; k++) {
        ct_camera B = A;
        B.eye = v3_madd(A.eye, right, (float)((double)steps[k] * unit));
        memset(ref, 0, n * sizeof *ref);
        for (int p = 0; p <= ref_spp; p++) {
            for (size_t i = 0; i < n; i++)
                req[i] = (ct_request){.id = (uint64_t)(p + 1) * 100000000ull + i + 1, .px = (float)(i % (size_t)b.w) + 0.5f,
                                      .py = (float)(i / (size_t)b.w) + 0.5f};
            trace(&b, B, req, n, p == ref_spp ? hit : tmp, p == ref_spp);
            if (p < ref_spp)
                for (size_t i = 0; i < n; i++) ref[i] = v3_add(ref[i], v3_scale(tmp[i].l_hq, 1.0f / (float)ref_spp));
        }
        sess *s[3];
        for (int h = 0; h < 3; h++)
            if (!(s[h] = run(&b, A, B, h, &err))) { fprintf(stderr, "error bench_late: %s\n", err.msg); return 1; }
        double se[3] = {0};
        vec3 bm[3][BLOCKS * BLOCKS];
        size_t bn[BLOCKS * BLOCKS] = {0}, ng = 0;
        memset(bm, 0, sizeof bm);
        for (size_t i = 0; i < n; i++) {
            if (!(hit[i].flags & CT_SAMPLE_HIT) || ctex_view_independent(sess_textures(s[0]), &hit[i])) continue;
            size_t blk = (i % (size_t)b.w) * BLOCKS / (size_t)b.w + BLOCKS * ((i / (size_t)b.w) * BLOCKS / (size_t)b.h);
            ng++;
            bn[blk]++;
            for (int h = 0; h < 3; h++) {
                vec3 c = ctex_lookup(sess_textures(s[h]), hit[i].node, hit[i].tri, hit[i].hit);
                vec3 d = v3_sub(v3_add(hit[i].l_base, c), ref[i]);
                se[h] += v3_dot(d, d);
                bm[h][blk] = v3_add(bm[h][blk], d);
            }
        }
        double bias[3] = {0};
        for (int h = 0; h < 3; h++)
            for (int q = 0; q < BLOCKS * BLOCKS; q++)
                if (bn[q]) {
                    vec3 m = v3_scale(bm[h][q], 1.0f / (float)bn[q]);
                    bias[h] += (double)bn[q] * v3_dot(m, m);
                }
        sess_counters c0 = sess_get_counters(s[0]), c1 = sess_get_counters(s[1]);
        double g = ng ? (double)ng : 1.0;
        printf("| %g | %zu | %.4f | %.4f | %.4f | %.4f | %.4f | %.4f | %llu | %llu |\n", (double)steps[k], ng,
               sqrt(se[0] / g), sqrt(se[1] / g), sqrt(se[2] / g), sqrt(bias[0] / g), sqrt(bias[1] / g),
               sqrt(bias[2] / g), (unsigned long long)c1.late, (unsigned long long)(c1.late - c0.late));
        fflush(stdout);
        for (int h = 0; h < 3; h++) sess_free(s[h]);
    }
    free(hit);
    free(tmp);
    free(req);
    free(ref);
    trc_free(b.tr);
    rmesh_free(&b.mesh);
    scene_free(b.scene);
    return 0;
}
