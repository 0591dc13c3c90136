/* tracer_script.c: a scripted master (rank 0) against a real tracer rank
 * (rank 1 runs trank_run, tracer/rank.h, with the Cornell box's tracer), run
 * by tests/e2e/tracer_gives_way.sh under mpirun:
 *   mpirun -np 2 tracer_script SCENE.json CAMERA
 * It checks when a rank gives a batch up for a newer view
 * (docs/distributed.md, "Camera changes"):
 * 1. CAMERA 1, a batch of 4096 requests for view 1, CAMERA 2 and nothing
 *    more: the rank traces the whole batch (no batch of view 2 waits, and
 *    idling would throw the time away);
 * 2. two batches of 4096 for view 2, CAMERA 3, a batch of 64 for view 3:
 *    the first of view 2 stops part way (or goes empty), the second goes
 *    empty, the one of view 3 is traced whole;
 * 3. a batch of 4096 for view 3, then the master calls no MPI for 1.5 s:
 *    a large message moves only while both sides call MPI, and the rank
 *    must nap, not spin inside MPI, while the master does not (a blocking
 *    receive spun a tracer's core on the master's time: 9 % of its CPU in a
 *    walk on two cores). The rank counts its CPU time beside its tracing.
 * Prints "batch B: N of M samples" for each answer; exits 0 when the rank
 * behaved so, 1 naming what it did not, 2 on bad usage or a failed set-up. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/radmesh.h"
#include "common/scene.h"
#include "common/timer.h"
#include "proto/mpi_link.h"
#include "proto/wire_mpi.h"
#include "tracer/rank.h"
#include "tracer/tracer.h"

#define W 64
#define H 64
#define PEER "tracer (rank 1)"

static ct_camera g_cam;

static int say(const char *what, const ct_error *err)
{
    fprintf(stderr, "tracer_script: %s: %s\n", what, err->msg);
    return 2;
}

static int send_camera(uint32_t epoch, ct_error *err)
{
    wire_mpi_camera c = {epoch, W, H, g_cam};
    wire_buf b = {0};
    int rc = wire_mpi_encode_camera(&c, &b, err);
    if (rc == 0) rc = mpil_isend(1, MPIL_TAG_CAMERA, &b, err);
    wire_buf_free(&b);
    return rc;
}

static int send_batch(uint64_t batch, uint32_t epoch, uint32_t n, ct_error *err)
{
    ct_request *r = calloc(n, sizeof *r);
    if (!r) return ct_fail(err, CT_ENOMEM, "out of memory");
    for (uint32_t i = 0; i < n; i++) {
        uint32_t p = (i * 2654435761u) % (W * H);   /* pixels spread over the image */
        r[i] = (ct_request){.id = batch * 100000 + i + 1, .epoch = epoch, .px = (float)(p % W) + 0.5f,
                            .py = (float)(p / W) + 0.5f, .radius = 1.0f, .priority = 1.0f};
    }
    wire_mpi_requests h = {batch, epoch, W, H, g_cam};
    wire_buf b = {0};
    int rc = wire_mpi_encode_requests(&h, r, n, &b, err);
    if (rc == 0) rc = mpil_isend(1, MPIL_TAG_REQUESTS, &b, err);
    wire_buf_free(&b);
    free(r);
    return rc;
}

/* The next answer: its batch id and sample count. */
static int answer(uint64_t *batch, uint32_t *n, ct_error *err)
{
    wire_buf b = {0};
    mpil_info info;
    int got = mpil_recv_wait(1, MPIL_TAG_SAMPLES, 60.0, &info, &b, err);
    if (got == 0) got = ct_fail(err, CT_EIO, "no answer within 60 s");
    int rc = got < 0 ? got : 0;
    unsigned kind = 0;
    if (rc == 0) rc = wire_mpi_peek(b.data, b.len, PEER, &kind, n, err);
    ct_sample *s = rc == 0 ? calloc(*n ? *n : 1, sizeof *s) : NULL;
    wire_mpi_samples h;
    if (rc == 0 && !s) rc = ct_fail(err, CT_ENOMEM, "out of memory");
    if (rc == 0) rc = wire_mpi_decode_samples(b.data, b.len, PEER, &h, s, *n, n, err);
    if (rc == 0) *batch = h.batch;
    free(s);
    wire_buf_free(&b);
    return rc;
}

/* Answers of batches first..first+k-1, in order, into n[]. */
static int answers(uint64_t first, int k, uint32_t *n, const uint32_t *asked, ct_error *err)
{
    for (int i = 0; i < k; i++) {
        uint64_t b = 0;
        int rc = answer(&b, &n[i], err);
        if (rc) return rc;
        if (b != first + (uint64_t)i)
            return ct_fail(err, CT_EPROTO, "answer of batch %llu where %llu was due", (unsigned long long)b,
                           (unsigned long long)(first + (uint64_t)i));
        printf("batch %llu: %u of %u samples\n", (unsigned long long)b, n[i], asked[i]);
    }
    return 0;
}

static int master(ct_error *err)
{
    int bad = 0, rc;
    uint32_t n[3];
    /* 1: the camera moved on, but nothing newer came: traced whole. */
    static const uint32_t ask1[1] = {4096};
    if ((rc = send_camera(1, err)) || (rc = send_batch(1, 1, ask1[0], err)) || (rc = send_camera(2, err)) ||
        (rc = answers(1, 1, n, ask1, err)))
        return rc;
    if (n[0] != ask1[0]) {
        printf("FAIL: the rank gave batch 1 up (%u of %u) though no batch of a newer view came\n", n[0], ask1[0]);
        bad = 1;
    }
    /* 2: a batch of view 3 waits behind two of view 2. */
    static const uint32_t ask2[3] = {4096, 4096, 64};
    if ((rc = send_batch(2, 2, ask2[0], err)) || (rc = send_batch(3, 2, ask2[1], err)) ||
        (rc = send_camera(3, err)) || (rc = send_batch(4, 3, ask2[2], err)) || (rc = answers(2, 3, n, ask2, err)))
        return rc;
    if (n[0] == ask2[0]) {
        printf("FAIL: batch 2 was traced whole (%u) though a batch of a newer view waited\n", n[0]);
        bad = 1;
    }
    if (n[1] != 0) {
        printf("FAIL: batch 3 answered %u samples though a batch of a newer view waited behind it\n", n[1]);
        bad = 1;
    }
    if (n[2] != ask2[2]) {
        printf("FAIL: batch 4, of the newest view, answered %u of %u\n", n[2], ask2[2]);
        bad = 1;
    }
    /* 3: the batch's transfer waits on the master; the rank naps meanwhile. */
    static const uint32_t ask3[1] = {4096};
    if ((rc = send_batch(5, 3, ask3[0], err))) return rc;
    ct_sleep_us(1500000);
    if ((rc = answers(5, 1, n, ask3, err))) return rc;
    if (n[0] != ask3[0]) {
        printf("FAIL: batch 5 answered %u of %u\n", n[0], ask3[0]);
        bad = 1;
    }
    /* leave in order: SHUTDOWN, then the rank's BYE */
    wire_mpi_control c = {.op = WIRE_MPI_OP_SHUTDOWN};
    wire_buf b = {0};
    if ((rc = wire_mpi_encode_control(&c, &b, err)) == 0) rc = mpil_isend(1, MPIL_TAG_CONTROL, &b, err);
    wire_buf_free(&b);
    mpil_info info;
    int got = rc ? rc : mpil_recv_wait(1, MPIL_TAG_BYE, 10.0, &info, &b, err);
    wire_buf_free(&b);
    if (got < 0) return got;
    if (got == 0) return ct_fail(err, CT_EIO, "no BYE from the tracer within 10 s of SHUTDOWN");
    if ((rc = mpil_drain(10.0, err))) return rc;
    return bad;
}

static int tracer(const ct_scene *scene, ct_error *err)
{
    ct_radmesh mesh;
    int rc = rmesh_from_scene(scene, v3s(0.3f), &mesh, err);
    if (rc) return rc;
    trc_options to;
    trc_options_default(&to, TRC_MODE_DRT);
    /* Costly samples (some 50 ms a batch here): a batch of view 2 must not
     * be done before the master, busy on a loaded host, sends view 3's. */
    to.shadow_rays = 16;
    trc_tracer *t = NULL;
    rc = trc_new(scene, &mesh, &to, &t, err);
    if (rc == 0) {
        trank_config tc = {.tracer = t, .rank = 1, .threads = 1, .idle_sleep_us = 200};
        trank_stats st;
        double cpu0 = ct_process_cpu();
        rc = trank_run(&tc, &st, err);
        double cpu = ct_process_cpu() - cpu0;
        printf("tracer: %.2f s of CPU, %.2f s of it tracing\n", cpu, st.busy_s);
        /* Napping through the master's 1.5 s costs a few ms; spinning in
         * MPI costs about all of it. */
        if (rc == 0 && cpu - st.busy_s > 0.75) {
            printf("FAIL: the rank used %.2f s of CPU beside its tracing: it waited inside MPI for the master\n",
                   cpu - st.busy_s);
            rc = 1;
        }
    }
    trc_free(t);
    rmesh_free(&mesh);
    return rc;
}

int main(int argc, char **argv)
{
    ct_error err = {0};
    int rank = 0, size = 0;
    if (mpil_init(&argc, &argv, &rank, &size, &err)) return say("MPI", &err);
    int rc = 0;
    ct_scene *scene = NULL;
    if (argc != 3 || size != 2) {
        if (rank == 0) fprintf(stderr, "usage: mpirun -np 2 tracer_script SCENE.json CAMERA\n");
        rc = 2;
    } else if (scene_load(argv[1], &scene, &err)) {
        rc = say(argv[1], &err);
    } else {
        int ci = scene_find_camera(scene, argv[2]);
        if (ci < 0) {
            fprintf(stderr, "tracer_script: %s: no camera '%s'\n", argv[1], argv[2]);
            rc = 2;
        } else {
            g_cam = scene->cams[ci].cam;
            rc = rank == 0 ? master(&err) : tracer(scene, &err);
            if (rc < 0) rc = say(rank == 0 ? "master" : "tracer", &err);
        }
    }
    scene_free(scene);
    if (rc == 2) mpil_abort(2);
    ct_error e;
    mpil_finalize(&e);
    return rc;
}
