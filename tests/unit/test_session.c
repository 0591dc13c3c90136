/* The master's session and loop in one process (master/session.h,
 * master/drive.h) over the in-process tracer port (tracer/tport_local.h,
 * the real tracer) with a sink that records: the shown-node map is the
 * interactive image's item buffer; a live run (lockstep frames, two lanes,
 * two master threads) and an offline one (checkpoints, one lane, one
 * thread) of the same requests give the same textures; samples that hit
 * another node than the one shown get mismatch children; samples of views
 * the camera left go in late (diffuse, same eye, aged). Cornell at 64x64
 * with the radiosity stand-in. Over 600 lines: one module's tests, sharing
 * the scene, tracer and port set up once. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "common/pool.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/timer.h"
#include "master/drive.h"
#include "master/session.h"
#include "master/shown.h"
#include "master/sink.h"
#include "tracer/tport_local.h"
#include "tracer/tracer.h"

#define W 64
#define H 64
#define SCENE "scenes/cornell/cornell.json"

static ct_error err;
static ct_scene *scene;
static ct_radmesh mesh;
static trc_tracer *tracer;
static ct_camera cam;

static void setup(void)
{
    cr_assert_eq(scene_load(SCENE, &scene, &err), 0, "%s", err.msg);
    cr_assert_eq(rmesh_from_scene(scene, v3s(0.3f), &mesh, &err), 0, "%s", err.msg);
    trc_options to;
    trc_options_default(&to, TRC_MODE_DRT);
    to.shadow_rays = 1;
    to.branch = 1;
    to.depth = 2;
    cr_assert_eq(trc_new(scene, &mesh, &to, &tracer, &err), 0, "%s", err.msg);
    int ci = scene_find_camera(scene, "front");
    cr_assert_geq(ci, 0);
    cam = scene->cams[ci].cam;
}

static void teardown(void)
{
    trc_free(tracer);
    rmesh_free(&mesh);
    scene_free(scene);
}

TestSuite(session, .init = setup, .fini = teardown, .timeout = 120);

/* A session of mesh m with the default queue options and texture options
 * co. */
static sess *open_session_co(const ct_radmesh *m, sess_options so, ctex_options co)
{
    rq_options ro;
    rq_options_default(&ro);
    sess_config c = {m, scene->mats, scene->nmats, &ro, &co, 1, so};
    sess *s = NULL;
    cr_assert_eq(sess_new(&c, &s, &err), 0, "%s", err.msg);
    return s;
}

/* A session of mesh m with the default queue and texture options. */
static sess *open_session(const ct_radmesh *m, sess_options so)
{
    return open_session_co(m, so, ctex_options_default());
}

static sess *new_session(const ct_radmesh *m, int threads)
{
    sess *s = open_session(m, (sess_options){threads, 0.0, 0.0});
    cr_assert_eq(sess_threads(s), threads);
    return s;
}

/* The primary hit's part at every pixel centre, traced. */
static void traced_nodes(uint32_t *out)
{
    ct_request *req = calloc(W * H, sizeof *req);
    ct_sample *smp = calloc(W * H, sizeof *smp);
    for (int i = 0; i < W * H; i++)
        req[i] = (ct_request){.id = (uint64_t)i + 1, .px = (float)(i % W) + 0.5f, .py = (float)(i / W) + 0.5f};
    trc_view v = {cam, W, H};
    trc_trace_par(tracer, NULL, &v, req, W * H, smp, true, NULL);
    for (int i = 0; i < W * H; i++) out[i] = (smp[i].flags & CT_SAMPLE_HIT) ? smp[i].node : RQ_NODE_NONE;
    free(req);
    free(smp);
}

Test(session, shown_map_is_the_item_buffer)
{
    static uint32_t traced[W * H], first[W * H];
    traced_nodes(traced);
    /* 6 threads: more than the item buffer's planes (4) */
    static const int counts[] = {1, 2, 3, 6};
    for (size_t k = 0; k < sizeof counts / sizeof *counts; k++) {
        int threads = counts[k];
        sess *s = new_session(&mesh, threads);
        cr_assert_null(sess_shown(s));
        cr_assert_eq(sess_set_view(s, &cam, W, H, &err), 1, "%s", err.msg);
        const uint32_t *shown = sess_shown(s);
        cr_assert_not_null(shown);
        int same = 0;
        for (int i = 0; i < W * H; i++) same += shown[i] == traced[i];
        /* only pixel centres on an edge between parts may differ */
        cr_assert_geq(same, W * H * 98 / 100, "%d threads: %d of %d pixels agree with the traced hits", threads, same,
                      W * H);
        /* and the map does not depend on the threads */
        if (threads == 1) memcpy(first, shown, sizeof first);
        else cr_assert_arr_eq(shown, first, sizeof first, "%d threads drew another map than one", threads);
        sess_free(s);
    }
    cr_expect_eq(shown_bytes(W, H, 6), shown_bytes(W, H, 4), "the item buffer grows past 4 planes");
    cr_expect_gt(shown_bytes(W, H, 4), shown_bytes(W, H, 1));
}

/* Running free with a rest time, a new view's map waits until the view is
 * that old and samples go in; lockstep draws it with the view. */
Test(session, shown_map_waits_for_a_resting_camera)
{
    sess *s = open_session(&mesh, (sess_options){1, 60.0, 0.0});
    cr_assert_eq(sess_set_view(s, &cam, W, H, &err), 1, "%s", err.msg);
    cr_assert_null(sess_shown(s), "the map is drawn before the camera rested");
    cr_assert_eq(sess_insert(s, NULL, 0, NULL, &err), 0, "%s", err.msg);
    cr_assert_null(sess_shown(s), "samples 0 ms after the view drew the map");
    struct timespec ts = {0, 80 * 1000000L};
    nanosleep(&ts, NULL);
    cr_assert_eq(sess_insert(s, NULL, 0, NULL, &err), 0, "%s", err.msg);
    cr_assert_not_null(sess_shown(s), "the camera rested 80 ms, and no map");
    /* a moved camera: no map again; lockstep draws it at once */
    ct_camera moved = cam;
    moved.eye.x += 0.01f;
    cr_assert_eq(sess_set_view(s, &moved, W, H, &err), 1, "%s", err.msg);
    cr_assert_null(sess_shown(s));
    sess_set_lockstep(s, true);
    moved.eye.x += 0.01f;
    cr_assert_eq(sess_set_view(s, &moved, W, H, &err), 1, "%s", err.msg);
    cr_assert_not_null(sess_shown(s), "lockstep: the view came without its map");
    sess_free(s);
}

/* A view whose per-pixel state would take more than --view-mem-mb is
 * refused before anything is allocated, naming what it needs; the view
 * before it stays (same size, same camera). */
Test(session, view_over_the_memory_cap_refused)
{
    sess *s = open_session(&mesh, (sess_options){1, 0.0, 8.0});
    cr_assert_eq(sess_set_view(s, &cam, W, H, &err), 1, "%s", err.msg);
    rq_options ro;
    rq_options_default(&ro);
    uint64_t need = rq_view_bytes(1024, 1024, &ro);
    cr_assert_gt(need, 8u << 20, "a 1024x1024 queue is said to need only %llu bytes", (unsigned long long)need);
    cr_assert_gt(rq_view_bytes(2048, 2048, &ro), 3 * need, "the need does not grow with the pixels");
    ct_camera moved = cam;
    moved.eye.x += 0.01f;
    int rc = sess_set_view(s, &moved, 1024, 1024, &err);
    printf("metric: 1024x1024 under an 8 MiB cap: %s\n", err.msg);
    cr_assert_eq(rc, CT_ENOMEM, "a view over the cap was taken (%d)", rc);
    cr_expect(strstr(err.msg, "1024x1024") && strstr(err.msg, "--view-mem-mb 8"), "the refusal says little: %s",
              err.msg);
    cr_expect(sess_same_view(s, &cam, W, H), "the view before the refused one is gone");
    ct_request req[4];
    int n = sess_next(s, req, 4, &err);
    cr_expect_gt(n, 0, "no requests of the kept view (%d: %s)", n, err.msg);
    sess_free(s);
}

/* --- a sink that records ------------------------------------------------------ */

typedef struct recording {
    ct_sample *s;
    size_t n, cap;
    int frames;
    uint32_t frame_samples;
} recording;

static void rec_samples(void *user, const ct_sample *s, uint32_t n)
{
    recording *r = user;
    if (r->n + n > r->cap) {
        r->cap = (r->n + n) * 2;
        r->s = realloc(r->s, r->cap * sizeof *r->s);
        cr_assert(r->s);
    }
    memcpy(r->s + r->n, s, n * sizeof *s);
    r->n += n;
}

static int rec_frame(void *user, sess *s, const sink_frame *f, ct_error *e)
{
    (void)s;
    (void)e;
    recording *r = user;
    r->frames++;
    r->frame_samples += f->samples;
    return 0;
}

/* A session driven over the in-process port: `lanes` tracers, `threads`
 * master threads, rounds of 256; frames of k[i] samples. */
typedef struct run {
    sess *s;
    ct_pool *pool;
    tport *port;
    drv *d;
    recording rec;
} run;

/* The in-process port, but answers that are ready come back last lane
 * first (each lane's own in order), as MPI ranks may answer in any order. */
typedef struct rev_port {
    tport base;
    tport *inner;
    tport_fifo ready;
} rev_port;

static int rev_view(tport *p, const tport_view *v, ct_error *e)
{
    tport *in = ((rev_port *)p)->inner;
    return in->ops->view(in, v, e);
}

static int rev_submit(tport *p, int lane, uint64_t batch, const tport_view *v, const ct_request *r, uint32_t n,
                      ct_error *e)
{
    tport *in = ((rev_port *)p)->inner;
    return in->ops->submit(in, lane, batch, v, r, n, e);
}

static int rev_poll(tport *p, tport_reply *out, ct_error *e)
{
    rev_port *r = (rev_port *)p;
    if (!r->ready.n) {
        tport_reply got[64];
        int n = 0;
        while (n < 64 && r->inner->ops->poll(r->inner, &got[n], e) > 0) {
            ct_sample *copy = malloc((got[n].n ? got[n].n : 1) * sizeof *copy);
            memcpy(copy, got[n].samples, got[n].n * sizeof *copy);
            got[n].samples = copy;
            n++;
        }
        for (int lane = p->lanes - 1; lane >= 0; lane--)
            for (int i = 0; i < n; i++)
                if (got[i].lane == lane)
                    tport_fifo_push(&r->ready, lane, got[i].batch, (ct_sample *)got[i].samples, got[i].n, e);
    }
    return tport_fifo_pop(&r->ready, out);
}

static void rev_close(tport *p, double wait_s)
{
    rev_port *r = (rev_port *)p;
    r->inner->ops->close(r->inner, wait_s);
    tport_fifo_free(&r->ready);
    free(r);
}

static const tport_ops REV_OPS = {rev_view, rev_submit, rev_poll, rev_close};

static void start_rounds(run *r, const ct_radmesh *m, int lanes, int threads, int round, bool ahead)
{
    memset(r, 0, sizeof *r);
    r->s = new_session(m, threads);
    cr_assert_eq(pool_new(2, &r->pool, &err), 0, "%s", err.msg);
    cr_assert_eq(tport_local_new(tracer, r->pool, lanes, &r->port, &err), 0, "%s", err.msg);
    if (lanes > 1) {
        rev_port *rp = calloc(1, sizeof *rp);
        rp->base = (tport){&REV_OPS, lanes};
        rp->inner = r->port;
        r->port = &rp->base;
    }
    drv_options o = {.window = 3, .batch_min = 16, .batch_max = 4096, .batch_ms = 20, .round = round, .pop_ahead = ahead};
    sink k = {&r->rec, rec_samples, rec_frame};
    cr_assert_eq(drv_new(r->s, r->port, &k, &o, &r->d, &err), 0, "%s", err.msg);
    drv_set_lockstep(r->d, true);
    cr_assert_eq(drv_set_view(r->d, &cam, W, H, &err), 1, "%s", err.msg);
}

static void start(run *r, const ct_radmesh *m, int lanes, int threads)
{
    start_rounds(r, m, lanes, threads, 256, false);
}

static void frame(run *r, uint32_t k)
{
    drv_begin_frame(r->d, k);
    while (drv_in_frame(r->d)) cr_assert_geq(drv_step(r->d, &err), 0, "%s", err.msg);
}

static void stop(run *r)
{
    drv_free(r->d);
    r->port->ops->close(r->port, 0);
    pool_free(r->pool);
    sess_free(r->s);
    free(r->rec.s);
}

/* Every live texture of a and b: same node, size and texels. */
static void same_textures(sess *a, sess *b, const char *what)
{
    ctex *ta = sess_textures(a), *tb = sess_textures(b);
    ctex_stats sa = ctex_get_stats(ta), sb = ctex_get_stats(tb);
    cr_assert_eq(sa.textures, sb.textures, "%s: %u and %u textures", what, sa.textures, sb.textures);
    cr_assert_eq(sa.texels, sb.texels, "%s", what);
    cr_assert_eq(ctex_slot_count(ta), ctex_slot_count(tb), "%s", what);
    for (uint32_t id = 0; id < ctex_slot_count(ta); id++) {
        uint32_t na, nb;
        int wa, ha, wb, hb;
        int la = ctex_texture_info(ta, id, &na, &wa, &ha, NULL, NULL, NULL);
        cr_assert_eq(ctex_texture_info(tb, id, &nb, &wb, &hb, NULL, NULL, NULL), la, "%s: texture %u", what, id);
        if (la < 0) continue;
        cr_assert(na == nb && wa == wb && ha == hb, "%s: texture %u differs in node or size", what, id);
        size_t n = (size_t)wa * (size_t)ha * 3;
        float *pa = malloc(n * sizeof *pa), *pb = malloc(n * sizeof *pb);
        cr_assert_eq(ctex_read_patch(ta, id, 0, 0, wa, ha, pa, &err), 0);
        cr_assert_eq(ctex_read_patch(tb, id, 0, 0, wb, hb, pb, &err), 0);
        cr_assert_eq(memcmp(pa, pb, n * sizeof *pa), 0, "%s: texels of texture %u differ", what, id);
        free(pa);
        free(pb);
    }
}

/* A live run (lockstep frames as a display asks for them, 2 tracer lanes
 * answering last lane first, 2 master threads) and an offline one (converge's checkpoints at the same
 * counts, 1 lane, 1 thread) insert the same samples and end with the same
 * textures; so does a mix of the two. */
Test(session, live_and_offline_give_the_same_textures)
{
    static const uint32_t K[] = {700, 700, 700, 700};
    run live, off, mix;
    start(&live, &mesh, 2, 2);
    start(&off, &mesh, 1, 1);
    start(&mix, &mesh, 1, 2);
    for (int i = 0; i < 4; i++) {
        frame(&live, K[i]);
        frame(&off, K[i]);
        frame(&mix, K[i]);
        same_textures(live.s, off.s, "live against offline");
        same_textures(mix.s, off.s, "1 lane, 2 threads against offline");
    }
    cr_assert_eq(live.rec.frames, 4);
    cr_assert_eq(live.rec.frame_samples, 2800u, "frames of exactly K samples");
    cr_assert_eq(live.rec.n, off.rec.n);
    for (size_t i = 0; i < live.rec.n; i++)
        cr_assert_eq(live.rec.s[i].request_id, off.rec.s[i].request_id, "sample %zu went in out of turn", i);
    cr_assert_eq(memcmp(live.rec.s, off.rec.s, live.rec.n * sizeof *live.rec.s), 0, "the samples differ");
    rq_stats a, b;
    sess_queue_stats(live.s, &a);
    sess_queue_stats(off.s, &b);
    cr_assert_eq(a.queued, b.queued);
    cr_assert_eq(a.children, b.children);
    stop(&live);
    stop(&off);
    stop(&mix);
}

/* Rounds larger than a chunk (SESS_CHUNK): a chunk's report to the queue
 * runs beside the next chunk's splats on two or more threads, in order on
 * one; past full coverage a chunk of refinement samples alone is reported
 * beside the texel writes of the chunk before. The first pass, then
 * refinement (4096 pixels, then some 6,000 refinement samples), give the
 * same textures, queue and samples for 1, 2 and 3 master threads. */
Test(session, chunks_reported_beside_splats_same_for_any_threads)
{
    static const uint32_t K[] = {3500, 3500, 3000};
    run r[3];
    for (int t = 0; t < 3; t++) start_rounds(&r[t], &mesh, 1, t + 1, 3500, false);
    for (int i = 0; i < 3; i++) {
        for (int t = 0; t < 3; t++) frame(&r[t], K[i]);
        same_textures(r[1].s, r[0].s, "2 master threads against 1");
        same_textures(r[2].s, r[0].s, "3 master threads against 1");
    }
    rq_stats q[3];
    for (int t = 0; t < 3; t++) sess_queue_stats(r[t].s, &q[t]);
    cr_assert(q[0].covered, "the frames were to reach full coverage and refine");
    cr_assert_gt(sess_get_counters(r[0].s).inserted, (uint64_t)(W * H), "refinement samples went in");
    for (int t = 1; t < 3; t++) {
        cr_assert_eq(q[t].popped, q[0].popped);
        cr_assert_eq(q[t].children, q[0].children);
        cr_assert_eq(q[t].queued, q[0].queued);
        cr_assert_eq(q[t].mismatches, q[0].mismatches);
        cr_assert_eq(r[t].rec.n, r[0].rec.n);
        cr_assert_eq(memcmp(r[t].rec.s, r[0].rec.s, r[0].rec.n * sizeof *r[0].rec.s), 0,
                     "%d threads: the sink heard other samples", t + 1);
    }
    for (int t = 0; t < 3; t++) stop(&r[t]);
}

/* Lockstep rounds popped ahead of the last one's reports (--pop-ahead, as
 * a free-running master pops): frames of exactly K samples, nothing left in
 * flight after a frame, the same textures, queue and samples for 1, 2 and
 * 3 master threads and 1 or 2 lanes, and another order than the exact one
 * (the option does something). */
Test(session, pop_ahead_same_for_any_threads_and_lanes)
{
    static const uint32_t K[] = {3500, 3500, 3000};
    run r[4], exact;
    for (int t = 0; t < 3; t++) start_rounds(&r[t], &mesh, 1, t + 1, 3000, true);
    start_rounds(&r[3], &mesh, 2, 2, 3000, true);
    start_rounds(&exact, &mesh, 1, 1, 3000, false);
    for (int i = 0; i < 3; i++) {
        for (int t = 0; t < 4; t++) {
            frame(&r[t], K[i]);
            cr_assert_eq(drv_inflight(r[t].d), 0, "requests left in flight after a frame");
        }
        frame(&exact, K[i]);
        for (int t = 1; t < 4; t++) same_textures(r[t].s, r[0].s, "pop ahead: threads or lanes against 1 thread");
    }
    cr_assert_eq(r[0].rec.frames, 3);
    cr_assert_eq(r[0].rec.frame_samples, 10000u, "frames of exactly K samples");
    rq_stats q[4];
    for (int t = 0; t < 4; t++) sess_queue_stats(r[t].s, &q[t]);
    for (int t = 1; t < 4; t++) {
        cr_assert_eq(q[t].popped, q[0].popped);
        cr_assert_eq(q[t].children, q[0].children);
        cr_assert_eq(q[t].queued, q[0].queued);
        cr_assert_eq(r[t].rec.n, r[0].rec.n);
        cr_assert_eq(memcmp(r[t].rec.s, r[0].rec.s, r[0].rec.n * sizeof *r[0].rec.s), 0,
                     "run %d: the sink heard other samples", t);
    }
    cr_assert_eq(exact.rec.n, r[0].rec.n);
    size_t moved = 0;
    for (size_t i = 0; i < r[0].rec.n; i++)
        moved += exact.rec.s[i].px != r[0].rec.s[i].px || exact.rec.s[i].py != r[0].rec.s[i].py;
    cr_assert_gt(moved, 0u, "popping ahead handed out the same requests as the exact order");
    cr_assert_gt(sess_get_counters(r[0].s).t_ahead, 0.0, "no pops were made ahead");
    for (int t = 0; t < 4; t++) stop(&r[t]);
    stop(&exact);
}

/* Running free with --pop-ahead over two in-process tracers: every lane's
 * next batch goes out from inside the insertion of its answer, the view is
 * covered with every pixel handed out once, and a receive that must not
 * pop (a view change coming) hands nothing out. */
Test(session, pop_ahead_running_free)
{
    run r;
    start_rounds(&r, &mesh, 2, 2, 256, true);
    drv_set_lockstep(r.d, false);
    rq_stats q = {0};
    double end = ct_now() + 60.0;
    while (!q.covered && ct_now() < end) {
        cr_assert_geq(drv_step(r.d, &err), 0, "%s", err.msg);
        sess_queue_stats(r.s, &q);
    }
    cr_assert(q.covered, "the view was not covered within 60 s");
    cr_assert_eq(q.sampled_pixels, (uint64_t)(W * H));
    cr_assert_gt(sess_get_counters(r.s).t_ahead, 0.0, "no batch was popped ahead");
    /* what is still out comes back; without may_pop nothing new goes out */
    end = ct_now() + 30.0;
    while (drv_inflight(r.d) > 0 && ct_now() < end) cr_assert_geq(drv_receive(r.d, false, &err), 0, "%s", err.msg);
    cr_assert_eq(drv_inflight(r.d), 0, "drv_receive without may_pop handed out batches");
    stop(&r);
}

/* A tracer port that answers nothing: counts the batches handed to it for
 * the newest view and in all. */
typedef struct hold_port {
    tport base;
    uint32_t epoch, this_view, total;
} hold_port;

static int hold_view(tport *p, const tport_view *v, ct_error *e)
{
    (void)e;
    hold_port *h = (hold_port *)p;
    h->epoch = v->epoch;
    h->this_view = 0;
    return 0;
}

static int hold_submit(tport *p, int lane, uint64_t batch, const tport_view *v, const ct_request *r, uint32_t n,
                       ct_error *e)
{
    (void)lane, (void)batch, (void)r, (void)n, (void)e;
    hold_port *h = (hold_port *)p;
    cr_assert_eq(v->epoch, h->epoch, "a batch for another view than the newest");
    h->this_view++;
    h->total++;
    return 0;
}

static int hold_poll(tport *p, tport_reply *out, ct_error *e)
{
    (void)p, (void)out, (void)e;
    return 0;
}

static void hold_close(tport *p, double wait_s)
{
    (void)p, (void)wait_s;
}

/* Running free, a new view gets its window of batches at once although the
 * old view's are all still out (a tracer answers those as soon as a newer
 * batch comes; counted, they held the new view back until one was traced),
 * and the batches out stay within the 64 slots however many views pass. */
Test(session, a_new_view_gets_its_window_while_old_batches_are_out)
{
    static const tport_ops HOLD_OPS = {hold_view, hold_submit, hold_poll, hold_close};
    hold_port h = {.base = {&HOLD_OPS, 1}};
    sess *s = new_session(&mesh, 1);
    drv_options o = {.window = 3, .batch_min = 16, .batch_max = 4096, .batch_ms = 20, .round = 256};
    drv *d = NULL;
    cr_assert_eq(drv_new(s, &h.base, NULL, &o, &d, &err), 0, "%s", err.msg);
    ct_camera moved = cam;
    for (int v = 0; v < 40; v++) {
        moved.eye.x = cam.eye.x + (float)v;
        cr_assert_eq(drv_set_view(d, &moved, W, H, &err), 1, "%s", err.msg);
        for (int i = 0; i < 3; i++) cr_assert_geq(drv_step(d, &err), 0, "%s", err.msg);
        uint32_t want = v < 21 ? 3 : v == 21 ? 1 : 0;   /* 64 slots: 21 views of 3, then 1 */
        cr_assert_eq(h.this_view, want, "view %d: %u batches handed out, expected %u (%u out in all)", v,
                     h.this_view, want, h.total);
        cr_assert_eq(drv_inflight(d), (int)h.total);
    }
    cr_assert_eq(h.total, 64u);
    drv_free(d);
    sess_free(s);
}

/* The mesh without one part: the interactive image shows the wall behind
 * the tall block where the tracer hits the block. */
static uint32_t cut_part(const char *name, ct_radmesh *out)
{
    uint32_t group = UINT32_MAX, part = UINT32_MAX;
    for (uint32_t i = 0; i < mesh.nnodes; i++)
        if (strcmp(mesh.nodes[i].name, name) == 0) group = i;
    cr_assert_neq(group, UINT32_MAX, "cornell has no node '%s'", name);
    /* the group's part: the node whose triangles these are */
    for (uint32_t t = 0; t < mesh.ntris && part == UINT32_MAX; t++) {
        uint32_t n = mesh.tri_node[t];
        if (n == group || (n > group && n < mesh.nodes[group].node_end)) part = n;
    }
    cr_assert_neq(part, UINT32_MAX, "'%s' has no triangles", name);
    uint32_t keep = 0;
    for (uint32_t t = 0; t < mesh.ntris; t++) keep += mesh.tri_node[t] != part;
    cr_assert_lt(keep, mesh.ntris);
    *out = mesh;
    out->tris = malloc(3 * (size_t)keep * sizeof *out->tris);
    out->tri_node = malloc(keep * sizeof *out->tri_node);
    out->tri_mat = malloc(keep * sizeof *out->tri_mat);
    out->ntris = 0;
    for (uint32_t t = 0; t < mesh.ntris; t++) {
        if (mesh.tri_node[t] == part) continue;
        memcpy(out->tris + 3 * (size_t)out->ntris, mesh.tris + 3 * (size_t)t, 3 * sizeof *out->tris);
        out->tri_node[out->ntris] = mesh.tri_node[t];
        out->tri_mat[out->ntris++] = mesh.tri_mat[t];
    }
    return part;
}

Test(session, mismatch_children_where_another_node_is_shown)
{
    ct_radmesh cut;
    uint32_t part = cut_part("tall_block", &cut);
    static uint32_t traced[W * H];
    traced_nodes(traced);
    run whole, r;
    start(&whole, &mesh, 1, 2);
    start(&r, &cut, 1, 2);
    const uint32_t *shown = sess_shown(r.s);
    int region = 0;
    for (int i = 0; i < W * H; i++) region += traced[i] == part;
    cr_assert_gt(region, 50, "the tall block covers %d pixels", region);
    for (int i = 0; i < W * H; i++) cr_assert(traced[i] != part || shown[i] != part, "the cut mesh still shows it");
    /* a frame short enough that mismatch children are still waiting */
    frame(&whole, 400);
    frame(&r, 400);
    rq_stats ws, rs;
    sess_queue_stats(whole.s, &ws);
    sess_queue_stats(r.s, &rs);
    cr_assert_eq(ws.mismatches, 0, "the same mesh on both sides: %llu false mismatches",
                 (unsigned long long)ws.mismatches);
    cr_assert_gt(rs.mismatches, 10, "only %llu mismatches", (unsigned long long)rs.mismatches);
    /* The queue's mismatch children: parents on the block, priority prio-mismatch. */
    ct_request *q = malloc(W * H * sizeof *q);
    int n = sess_next(r.s, q, W * H, &err), children = 0;
    cr_assert_geq(n, 0);
    for (int i = 0; i < n; i++) {
        if (q[i].priority != 1e9f) continue;
        children++;
        const ct_sample *p = NULL;
        for (size_t j = 0; j < r.rec.n && !p; j++)
            if (r.rec.s[j].request_id == q[i].parent) p = &r.rec.s[j];
        cr_assert_not_null(p, "child %llu of an unknown sample", (unsigned long long)q[i].id);
        cr_assert(p->flags & CT_SAMPLE_HIT);
        cr_assert_eq(p->node, part, "a mismatch child of a sample on node %u, not on the block", p->node);
    }
    cr_assert_gt(children, 0, "no mismatch children queued");
    free(q);
    stop(&whole);
    stop(&r);
    free(cut.tris);
    free(cut.tri_node);
    free(cut.tri_mat);
}

/* A session (texture options co) on the camera and its first batch traced
 * into smp (W x H at most); *k the samples. */
static sess *first_batch_traced_co(ct_sample *smp, int *k, ctex_options co)
{
    sess *s = open_session_co(&mesh, (sess_options){1, 0.0, 0.0}, co);
    cr_assert_eq(sess_set_view(s, &cam, W, H, &err), 1, "%s", err.msg);
    static ct_request req[W * H];
    *k = sess_next(s, req, W * H, &err);
    cr_assert_gt(*k, 0, "%s", err.msg);
    trc_view v = {cam, W, H};
    trc_trace_par(tracer, NULL, &v, req, (size_t)*k, smp, true, NULL);
    return s;
}

static sess *first_batch_traced(ct_sample *smp, int *k)
{
    return first_batch_traced_co(smp, k, ctex_options_default());
}

/* The hits among k samples and those of them on diffuse surfaces; some
 * must be glossy. */
static void count_hits(sess *s, const ct_sample *smp, int k, uint32_t *hits, uint32_t *diffuse)
{
    *hits = *diffuse = 0;
    for (int i = 0; i < k; i++) {
        *hits += (smp[i].flags & CT_SAMPLE_HIT) != 0;
        *diffuse += ctex_view_independent(sess_textures(s), &smp[i]);
    }
    cr_assert(*diffuse < *hits, "%u of %u hits on diffuse surfaces: no glossy ones to test", *diffuse, *hits);
}

/* Samples traced for a view the camera has left: those on diffuse surfaces
 * are splatted into the new view's textures (late), the others (the
 * mirror and glass spheres with --late-deg 0, misses) are dropped (stale);
 * the request queue hears of none of them. */
Test(session, late_samples_on_diffuse_surfaces_go_in)
{
    static ct_sample smp[W * H];
    int k;
    ctex_options co = ctex_options_default();
    co.late_deg = 0.0f;   /* glossy ones from a moved eye: late_glossy_samples_go_in_aged_from_a_near_eye */
    sess *s = first_batch_traced_co(smp, &k, co);
    uint32_t diffuse = 0;
    for (int i = 0; i < k; i++) diffuse += ctex_view_independent(sess_textures(s), &smp[i]);
    cr_assert(diffuse > 0 && diffuse < (uint32_t)k, "%u of %d samples on diffuse surfaces", diffuse, k);
    /* the camera moves on before they come back */
    ct_camera moved = cam;
    moved.eye.x += 0.02f;
    cr_assert_eq(sess_set_view(s, &moved, W, H, &err), 1, "%s", err.msg);
    rq_stats before;
    sess_queue_stats(s, &before);
    cr_assert_eq(sess_insert(s, smp, (uint32_t)k, NULL, &err), 0, "%s", err.msg);
    sess_counters n = sess_get_counters(s);
    rq_stats after;
    sess_queue_stats(s, &after);
    cr_assert_eq(after.reported, before.reported, "the queue heard of samples of an older view");
    cr_assert_eq(n.late + n.stale, (uint64_t)k, "late %llu + stale %llu of %d", (unsigned long long)n.late,
                 (unsigned long long)n.stale, k);
    cr_assert_eq(n.inserted, n.late);
    /* every late one is on a diffuse surface, and most diffuse ones went in
     * (some may lie on a part the moved view does not texture) */
    cr_assert_leq(n.late, diffuse);
    cr_assert_geq(n.late, diffuse * 9 / 10, "%llu of %u diffuse samples went in", (unsigned long long)n.late, diffuse);
    /* and they are in the textures: the correction at a late sample's point */
    int checked = 0;
    for (int i = 0; i < k && checked < 20; i++) {
        if (!ctex_view_independent(sess_textures(s), &smp[i])) continue;
        vec3 c = ctex_lookup(sess_textures(s), smp[i].node, smp[i].tri, smp[i].hit);
        checked += c.x != 0.0f || c.y != 0.0f || c.z != 0.0f;
    }
    cr_assert_eq(checked, 20, "only %d of 20 late samples' points show a correction", checked);
    sess_free(s);
}

/* A camera that only turned: the eye is where it was, so the radiance each
 * sample carries toward it is unchanged, and the samples of the view it
 * left go in on glossy and mirror surfaces too (late, not aged); only
 * misses stay out. */
Test(session, late_samples_from_the_same_eye_go_in)
{
    static ct_sample smp[W * H];
    int k;
    sess *s = first_batch_traced(smp, &k);
    uint32_t hits, diffuse;
    count_hits(s, smp, k, &hits, &diffuse);
    /* turn by a degree about the vertical: same eye */
    ct_camera turned = cam;
    turned.orient = q_normalize(q_mul(q_axis_angle(v3(0, 1, 0), 0.0175f), cam.orient));
    cr_assert_eq(sess_set_view(s, &turned, W, H, &err), 1, "%s", err.msg);
    cr_assert_eq(sess_insert(s, smp, (uint32_t)k, NULL, &err), 0, "%s", err.msg);
    sess_counters n = sess_get_counters(s);
    cr_assert_eq(n.late + n.stale, (uint64_t)k);
    /* every hit but those on parts the turned view does not texture */
    cr_assert_gt(n.late, diffuse, "late %llu: no more than the %u diffuse", (unsigned long long)n.late, diffuse);
    cr_assert_geq(n.late, hits * 9 / 10, "%llu of %u hits went in", (unsigned long long)n.late, hits);
    /* every sample of the view just left is kept as late and none has
     * turned: the stale ones are those that wrote nothing, the misses among
     * them (a first batch covers no sample's centre) */
    cr_assert_eq(n.late_turned, 0u);
    cr_assert_eq(n.late_covered, 0u);
    cr_assert_eq(n.late_off, n.stale, "%llu of %llu stale off the textures", (unsigned long long)n.late_off,
                 (unsigned long long)n.stale);
    cr_assert_geq(n.late_off, (uint64_t)k - hits);
    sess_free(s);
}

/* Late samples traced from an eye the camera has left (master/ctex.h,
 * ctex_insert_late_par): glossy ones go in aged while their viewing
 * direction turned by at most --late-deg x their glossiness (here a step
 * of 5 mm in a scene 550 mm wide, seen from 800 mm: a third of a degree),
 * and are stale past it (a step of 400 mm: the spheres are seen some 20
 * degrees apart) or with --late-deg 0; diffuse ones go in either way. */
Test(session, late_glossy_samples_go_in_aged_from_a_near_eye)
{
    static ct_sample smp[W * H];
    static const struct {
        float step, late_deg;
        bool glossy_in;
    } cases[] = {{5.0f, 10.0f, true}, {400.0f, 10.0f, false}, {5.0f, 0.0f, false}};
    for (size_t c = 0; c < sizeof cases / sizeof *cases; c++) {
        ctex_options co = ctex_options_default();
        co.late_deg = cases[c].late_deg;
        int k;
        sess *s = first_batch_traced_co(smp, &k, co);
        uint32_t hits, diffuse;
        count_hits(s, smp, k, &hits, &diffuse);
        ct_camera moved = cam;
        moved.eye.x += cases[c].step;
        cr_assert_eq(sess_set_view(s, &moved, W, H, &err), 1, "%s", err.msg);
        cr_assert_eq(sess_insert(s, smp, (uint32_t)k, NULL, &err), 0, "%s", err.msg);
        sess_counters n = sess_get_counters(s);
        cr_assert_eq(n.late + n.stale, (uint64_t)k);
        cr_assert_eq(n.inserted, n.late);
        if (cases[c].glossy_in) {
            cr_assert_geq(n.late, hits * 9 / 10, "step %g: %llu of %u hits went in", (double)cases[c].step,
                          (unsigned long long)n.late, hits);
            cr_assert_eq(n.late_turned, 0u, "step %g: %llu turned", (double)cases[c].step,
                         (unsigned long long)n.late_turned);
        } else {
            cr_assert_leq(n.late, diffuse, "step %g, --late-deg %g: %llu late, %u diffuse", (double)cases[c].step,
                          (double)cases[c].late_deg, (unsigned long long)n.late, diffuse);
            /* (some diffuse parts leave the textures of a view 400 mm away) */
            cr_assert_geq(n.late, diffuse / 2, "step %g: %llu of %u diffuse went in", (double)cases[c].step,
                          (unsigned long long)n.late, diffuse);
            /* the glossy ones were dropped, most for their turn */
            printf("metric: step %g, --late-deg %g: %llu stale, %llu of them turned, %u glossy hits\n",
                   (double)cases[c].step, (double)cases[c].late_deg, (unsigned long long)n.stale,
                   (unsigned long long)n.late_turned, hits - diffuse);
            cr_assert_leq(n.late_turned, hits - diffuse);
            /* --late-deg 0: every glossy hit that has a texture turned; 400
             * mm away, those turned past 10 degrees x their glossiness */
            if (cases[c].late_deg == 0.0f) cr_assert_geq(n.late_turned, (hits - diffuse) * 9 / 10);
            else cr_assert_gt(n.late_turned, 0u);
        }
        cr_assert_eq(n.late_turned + n.late_covered + n.late_off, n.stale,
                     "a view just left: every stale one was kept as late");
        sess_free(s);
    }
}

/* Late samples that find a fresher sample at their centre texel write
 * nothing and are counted apart (late_covered) from those with no texture
 * at their hit (late_off) and those turned too far (late_turned): the
 * stats line tells which stale samples were lost and which were not needed. */
Test(session, late_samples_under_fresher_ones_are_counted_as_covered)
{
    static ct_sample old[W * H], fresh[W * H];
    static ct_request req[W * H];
    int k;
    sess *s = first_batch_traced(old, &k);
    ct_camera moved = cam;
    moved.eye.x += 5.0f;
    cr_assert_eq(sess_set_view(s, &moved, W, H, &err), 1, "%s", err.msg);
    /* the moved view's own samples first, over every pixel */
    int m = sess_next(s, req, W * H, &err);
    cr_assert_gt(m, 0, "%s", err.msg);
    trc_view v = {moved, W, H};
    trc_trace_par(tracer, NULL, &v, req, (size_t)m, fresh, true, NULL);
    cr_assert_eq(sess_insert(s, fresh, (uint32_t)m, NULL, &err), 0, "%s", err.msg);
    sess_counters n0 = sess_get_counters(s);
    cr_assert_eq(n0.stale, 0u);
    /* then the samples of the view left: glossy ones aged, under them */
    cr_assert_eq(sess_insert(s, old, (uint32_t)k, NULL, &err), 0, "%s", err.msg);
    sess_counters n = sess_get_counters(s);
    printf("metric: %d late samples: %llu in, %llu stale (%llu covered, %llu off, %llu turned)\n", k,
           (unsigned long long)n.late, (unsigned long long)n.stale, (unsigned long long)n.late_covered,
           (unsigned long long)n.late_off, (unsigned long long)n.late_turned);
    cr_assert_eq(n.late + n.stale, (uint64_t)k);
    cr_assert_eq(n.late_turned + n.late_covered + n.late_off, n.stale);
    cr_assert_gt(n.late_covered, 0u, "no late sample found a fresher one at its centre");
    cr_assert_eq(n.late_turned, 0u, "a 5 mm step turns nothing past 10 degrees");
    sess_free(s);
}
