/* sched.c: the master's scheduling loop (sched.h). One thread: each turn
 * polls the display socket (a short timeout only while nothing else is to
 * do), reads every sample batch that arrived (MPI_Iprobe), inserts samples,
 * hands out new batches, streams texture events and prints stats. */
#include "master/sched.h"

#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>

#include "common/half.h"
#include "common/log.h"
#include "common/timer.h"
#include "master/dsrv.h"
#include "master/dsync.h"
#include "proto/mpi_link.h"
#include "proto/wire.h"
#include "proto/wire_mpi.h"

#define COMPONENT "master"
#define MAX_FRAMES_QUEUED 64

void sched_options_default(sched_options *o)
{
    o->window = 3;
    o->batch_min = 16;
    o->batch_max = 4096;
    o->batch_ms = 20.0;
    o->round = 256;
    o->patch_ms = 10.0;
    o->stats_s = 1.0;
    o->handshake_ms = 5000;
    o->send_timeout_ms = 10000;
    o->tracer_timeout_s = 30.0;
    o->idle_ms = 2;
    o->queue_mb = 64;
    o->patch_encoding = -1;
    o->exit_when_display_leaves = false;
}

typedef struct opt_desc {
    const char *name, *help;
} opt_desc;

static const opt_desc OPTS[] = {
    {"window", "request batches in flight per tracer"},
    {"batch-min", "smallest free-running batch (requests)"},
    {"batch-max", "largest free-running batch (requests)"},
    {"batch-ms", "target tracing time of one free-running batch (ms)"},
    {"round", "lockstep: requests per round, inserted in id order"},
    {"patch-ms", "free-running: shortest interval of texture updates to the display (ms)"},
    {"stats-s", "interval of the stats line and STATS message (s)"},
    {"handshake-ms", "a connecting display must finish its handshake within this (ms)"},
    {"send-timeout-ms", "drop a display that does not read its full queue for this long (ms)"},
    {"tracer-timeout-s", "end the job when a tracer with work is silent this long (s)"},
    {"idle-ms", "socket poll timeout while idle (ms)"},
    {"queue-mb", "display send queue bound (MiB)"},
    {"patch-encoding", "texels to the display: raw, lz4 or auto (raw on UNIX, lz4 on TCP)"},
    {NULL, NULL}};

static int parse_num(const char *name, const char *v, double lo, double hi, double *out, ct_error *err)
{
    char *end;
    double x = strtod(v, &end);
    if (end == v || *end || !isfinite(x) || x < lo || x > hi)
        return ct_fail(err, CT_EINVAL, "--%s: '%s' is not a number in [%g, %g]", name, v, lo, hi);
    *out = x;
    return 0;
}

int sched_options_set(sched_options *o, const char *name, const char *value, ct_error *err)
{
    double x;
    if (strcmp(name, "patch-encoding") == 0) {
        if (!strcmp(value, "raw")) o->patch_encoding = WIRE_PATCH_RAW;
        else if (!strcmp(value, "lz4")) o->patch_encoding = WIRE_PATCH_LZ4;
        else if (!strcmp(value, "auto")) o->patch_encoding = -1;
        else return ct_fail(err, CT_EINVAL, "--patch-encoding: '%s' is not raw, lz4 or auto", value);
        return 1;
    }
#define NUM(n, lo, hi, field, type)                                               \
    if (strcmp(name, n) == 0) {                                               \
        if (parse_num(name, value, lo, hi, &x, err)) return CT_EINVAL;        \
        o->field = (type)x;                                                   \
        return 1;                                                             \
    }
    NUM("window", 1, 64, window, int)
    NUM("batch-min", 1, WIRE_MPI_MAX_BATCH, batch_min, int)
    NUM("batch-max", 1, WIRE_MPI_MAX_BATCH, batch_max, int)
    NUM("batch-ms", 0.1, 10000, batch_ms, double)
    NUM("round", 1, WIRE_MPI_MAX_BATCH, round, int)
    NUM("patch-ms", 0, 10000, patch_ms, double)
    NUM("stats-s", 0.05, 3600, stats_s, double)
    NUM("handshake-ms", 10, 600000, handshake_ms, int)
    NUM("send-timeout-ms", 10, 600000, send_timeout_ms, int)
    NUM("tracer-timeout-s", 0.1, 86400, tracer_timeout_s, double)
    NUM("idle-ms", 0, 1000, idle_ms, int)
    NUM("queue-mb", 1, 65536, queue_mb, size_t)
#undef NUM
    return 0;
}

void sched_options_usage(FILE *f)
{
    sched_options d;
    sched_options_default(&d);
    char v[32];
    for (const opt_desc *p = OPTS; p->name; p++) {
        if (!strcmp(p->name, "window")) snprintf(v, sizeof v, "%d", d.window);
        else if (!strcmp(p->name, "batch-min")) snprintf(v, sizeof v, "%d", d.batch_min);
        else if (!strcmp(p->name, "batch-max")) snprintf(v, sizeof v, "%d", d.batch_max);
        else if (!strcmp(p->name, "batch-ms")) snprintf(v, sizeof v, "%g", d.batch_ms);
        else if (!strcmp(p->name, "round")) snprintf(v, sizeof v, "%d", d.round);
        else if (!strcmp(p->name, "patch-ms")) snprintf(v, sizeof v, "%g", d.patch_ms);
        else if (!strcmp(p->name, "stats-s")) snprintf(v, sizeof v, "%g", d.stats_s);
        else if (!strcmp(p->name, "handshake-ms")) snprintf(v, sizeof v, "%d", d.handshake_ms);
        else if (!strcmp(p->name, "send-timeout-ms")) snprintf(v, sizeof v, "%d", d.send_timeout_ms);
        else if (!strcmp(p->name, "tracer-timeout-s")) snprintf(v, sizeof v, "%g", d.tracer_timeout_s);
        else if (!strcmp(p->name, "idle-ms")) snprintf(v, sizeof v, "%d", d.idle_ms);
        else if (!strcmp(p->name, "queue-mb")) snprintf(v, sizeof v, "%zu", d.queue_mb);
        else snprintf(v, sizeof v, "auto");
        char flag[40];
        snprintf(flag, sizeof flag, "%s %s", p->name, !strcmp(p->name, "patch-encoding") ? "E" : strchr(v, '.') ? "X" : "N");
        fprintf(f, "  --%-22s %s (default %s)\n", flag, p->help, v);
    }
}

/* ------------------------------------------------------------------------- */

typedef struct tracer {
    int inflight;               /* batches sent, not answered */
    double rate;                /* samples/s, smoothed (batch sizing) */
    double sent_at[64];         /* send times of the in-flight batches (FIFO) */
    unsigned char in_round[64]; /* whether each of them belongs to a lockstep round */
    int sent_head;
    uint64_t samples;           /* samples returned since the start */
    uint64_t samples_mark;      /* at the last stats line */
    double last_reply;
} tracer;

typedef struct frame_req {
    wire_camera cam;
} frame_req;

/* Everything the loop keeps between turns. */
typedef struct loop_state {
    const sched_config *c;
    dsrv *ds;
    dsync *sync;
    rq_engine *rq;
    ctex *tex;
    wire_scene_tx scene_tx;
    int have_scene_tx;
    tracer *tr;
    int T;
    /* the view */
    int have_cam;
    ct_camera cam;
    int w, h;
    uint32_t epoch;             /* internal epoch: what tracers see */
    uint32_t rq_epoch;          /* the request queue's own epoch */
    uint32_t disp_epoch;        /* the display's epoch number of the current camera */
    double view_t0;             /* when the current view was set */
    int view_covered;           /* its every pixel has been handed out (logged once) */
    double covered_logged;      /* when a coverage line was last logged at info level */
    uint64_t batch_id;
    int rr;                     /* free-running: the rank served first next time */
    /* lockstep */
    int lockstep;
    uint32_t K;
    frame_req frames[MAX_FRAMES_QUEUED];
    int fr_head, fr_n;
    int in_frame;
    int frame_orphan;           /* the frame in progress belongs to a display that left */
    uint32_t frame_left, frame_samples, frame_patches;
    uint64_t frame_no;
    int round_out;              /* batches of the current round not yet back */
    ct_sample *round_buf;
    uint32_t round_n, round_cap;
    int all_positive;
    /* buffers */
    ct_request *reqs;
    uint32_t reqs_cap;
    ct_sample *samples;
    uint32_t samples_cap;
    wire_buf mbuf, obuf;
    /* timing */
    double t_tex, t_sample_wait, t_render_wait, t_mark;
    double last_patch, last_stats;
    uint64_t bytes_mark;
    uint64_t stale, inserted, dropped_tex;
    uint64_t total_samples;
    /* SAMPLES: hit points inserted since the last send (droppable) */
    float *pts;                 /* 3 * WIRE_SAMPLES_MAX_POINTS floats once a display is there */
    uint32_t npts;
    uint64_t pts_dropped;       /* points not sent to the current display (back-pressure) */
    uint64_t pts_dropped_total; /* the same since the start (stats line) */
} loop_state;

static int grow(void **p, uint32_t *cap, uint32_t need, size_t elem, ct_error *err)
{
    if (need <= *cap) return 0;
    uint32_t n = *cap ? *cap : 256;
    while (n < need) n *= 2;
    void *q = realloc(*p, (size_t)n * elem);
    if (!q) return ct_fail(err, CT_ENOMEM, "master: out of memory for %u records", n);
    *p = q;
    *cap = n;
    return 0;
}

/* --- texture events -> display --------------------------------------------- */

static int send_msg(loop_state *s, const wire_msg *m, ct_error *err)
{
    return dsrv_send(s->ds, m, s->c->opt.send_timeout_ms, err);
}

/* Sends the hit points collected since the last call as one SAMPLES
 * message. They are only a debugging view (Fig. 7): when the display's send
 * queue already holds a quarter of its bound they are dropped and counted,
 * so they never block the loop or take room that texture updates need. */
static void flush_samples(loop_state *s)
{
    if (!s->npts || !dsrv_has_display(s->ds)) {
        s->npts = 0;
        return;
    }
    wire_msg m;
    memset(&m, 0, sizeof m);
    m.type = WIRE_SAMPLES;
    m.u.samples = (wire_samples){.epoch = s->disp_epoch, .count = s->npts, .dropped = s->pts_dropped, .xyz = s->pts};
    if (dsrv_try_send(s->ds, &m, (s->c->opt.queue_mb << 20) / 4) == DSRV_DROPPED) {
        s->pts_dropped += s->npts;
        s->pts_dropped_total += s->npts;
    }
    s->npts = 0;
}

/* Remembers the hit point of an inserted sample for the next SAMPLES. */
static void collect_point(loop_state *s, const ct_sample *x)
{
    if (!(x->flags & CT_SAMPLE_HIT) || !dsrv_has_display(s->ds)) return;
    if (!s->pts) {
        s->pts = malloc(3 * sizeof *s->pts * WIRE_SAMPLES_MAX_POINTS);
        if (!s->pts) return;   /* without memory the debugging view just shows nothing */
    }
    if (s->npts == WIRE_SAMPLES_MAX_POINTS) flush_samples(s);
    float *p = s->pts + 3 * (size_t)s->npts++;
    p[0] = x->hit.x;
    p[1] = x->hit.y;
    p[2] = x->hit.z;
}

/* Free running: one texture update when the display has acknowledged
 * enough of the last ones (dsync.h), after the sample points collected
 * since the last one. */
static int send_update(loop_state *s, ct_error *err)
{
    if (!dsync_can_send(s->sync)) return 0;
    flush_samples(s);
    double t0 = ct_now();
    int rc = dsync_update(s->sync, s->ds, s->tex, t0, ct_now_us(), err);
    s->t_tex += ct_now() - t0;
    return rc < 0 ? rc : 0;
}

/* The scene and every live texture, for a display that just connected. */
static int send_state(loop_state *s, const wire_settings *set, ct_error *err)
{
    int rc;
    char peer[CT_ERROR_LEN];
    snprintf(peer, sizeof peer, "%s", dsrv_peer(s->ds));   /* the display may leave meanwhile */
    if (!s->have_scene_tx) {
        /* The radiosity mesh with the texture hierarchy as its node table
         * (made once, content-hashed: a display keeps it cached). */
        ct_radmesh dm;
        if ((rc = ctex_display_mesh(s->tex, s->c->mesh, &dm, err))) return rc;
        rc = wire_scene_tx_init(&s->scene_tx, &dm, err);
        ctex_display_mesh_free(&dm);
        if (rc) return rc;
        s->have_scene_tx = 1;
    }
    /* First the view to start from, for a display without a camera of its
     * own: the current one, else the scene's first camera; it comes before
     * the scene so that the display has it when the scene is drawn. */
    wire_msg m = {.type = WIRE_CAMERA};
    if (s->have_cam || s->c->scene->ncams) {
        m.u.camera = s->have_cam ? (wire_camera){0, (uint32_t)s->w, (uint32_t)s->h, s->cam}
                                 : (wire_camera){0, 1024, 1024, s->c->scene->cams[0].cam};
        if ((rc = send_msg(s, &m, err))) return rc;
    }
    int cached = memcmp(set->cached_scene, s->scene_tx.hash, WIRE_HASH_SIZE) == 0;
    wire_scene_tx_begin(&s->scene_tx, cached, &m);
    if ((rc = send_msg(s, &m, err))) return rc;
    uint32_t nch = cached ? 0 : m.u.scene_begin.nchunks;
    for (uint32_t i = 0; i < nch && dsrv_has_display(s->ds); i++) {
        wire_scene_tx_chunk(&s->scene_tx, i, &m);
        if ((rc = send_msg(s, &m, err))) return rc;
    }
    wire_scene_tx_end(&s->scene_tx, &m);
    if ((rc = send_msg(s, &m, err))) return rc;
    uint32_t ntex = 0;
    if ((rc = dsync_send_state(s->sync, s->ds, s->tex, &ntex, err))) return rc;
    ct_info(COMPONENT, "sent the scene (%s) and %u textures to %s", cached ? "cached on the display" : "full",
            ntex, peer);
    return 0;
}

/* --- camera ------------------------------------------------------------------- */

static int same_view(const loop_state *s, const wire_camera *c)
{
    return s->have_cam && (int)c->width == s->w && (int)c->height == s->h &&
           memcmp(&c->cam, &s->cam, sizeof c->cam) == 0;
}

/* Applies a display camera: a new epoch when the view changed. */
static int apply_camera(loop_state *s, const wire_camera *c, ct_error *err)
{
    flush_samples(s);   /* the points so far belong to the previous epoch */
    s->disp_epoch = c->epoch;
    dsync_set_epoch(s->sync, c->epoch);
    if (same_view(s, c)) return 0;
    double t0 = ct_now();
    int rc;
    if (!s->rq || (int)c->width != s->w || (int)c->height != s->h) {
        rq_free(s->rq);
        s->rq = NULL;
        s->have_cam = 0;   /* nothing is handed out until a camera is accepted */
        if ((rc = rq_new(&s->rq, (int)c->width, (int)c->height, &c->cam, s->c->rq, s->c->seed, err))) return rc;
        s->rq_epoch = 0;
    } else {
        if ((rc = rq_set_camera(s->rq, &c->cam, s->rq_epoch + 1, err))) return rc;
        s->rq_epoch++;
    }
    s->cam = c->cam;
    s->w = (int)c->width;
    s->h = (int)c->height;
    s->have_cam = 1;
    s->epoch++;
    ctex_set_clock(s->tex, ct_now_us());   /* stamps of the textures it makes */
    s->view_t0 = t0;
    s->view_covered = 0;
    rc = ctex_set_camera(s->tex, &s->cam, s->w, s->h, err);
    s->t_tex += ct_now() - t0;
    if (rc) {
        s->have_cam = 0;
        return rc;
    }
    /* Tell every tracer: queued batches of older epochs are answered empty. */
    wire_mpi_camera mc = {.epoch = s->epoch, .width = (uint32_t)s->w, .height = (uint32_t)s->h, .cam = s->cam};
    for (int r = 1; r <= s->T; r++) {
        s->obuf.len = 0;
        if ((rc = wire_mpi_encode_camera(&mc, &s->obuf, err)) || (rc = mpil_isend(r, MPIL_TAG_CAMERA, &s->obuf, err)))
            return rc;
    }
    ct_debug(COMPONENT, "camera epoch %u (display epoch %u), %dx%d", s->epoch, c->epoch, s->w, s->h);
    return 0;
}

/* A display's camera: a camera the engines refuse (a bad field of view, an
 * image too large for memory) is the display's fault, not the job's: the
 * display is dropped with the reason and the master goes on. Only MPI
 * failures (CT_EIO) end the job. */
static int camera_or_drop(loop_state *s, const wire_camera *c, ct_error *err)
{
    int rc = apply_camera(s, c, err);
    if (rc == 0 || rc == CT_EIO) return rc;
    char why[CT_ERROR_LEN];
    snprintf(why, sizeof why, "camera refused: %s", err->msg);
    ct_warn(COMPONENT, "display %s: %s", dsrv_peer(s->ds), why);
    dsrv_drop(s->ds, rc == CT_ENOMEM ? WIRE_ERR_LIMIT : WIRE_ERR_PROTOCOL, why);
    ct_error_clear(err);
    s->fr_n = 0;
    return 0;
}

static int total_inflight(const loop_state *s);

/* --- tracers ------------------------------------------------------------------ */

static int send_batch(loop_state *s, int rank, const ct_request *reqs, uint32_t n, int round, ct_error *err)
{
    wire_mpi_requests h = {.batch = ++s->batch_id, .epoch = s->epoch, .width = (uint32_t)s->w,
                           .height = (uint32_t)s->h, .cam = s->cam};
    s->obuf.len = 0;
    int rc = wire_mpi_encode_requests(&h, reqs, n, &s->obuf, err);
    if (rc == 0) rc = mpil_isend(rank, MPIL_TAG_REQUESTS, &s->obuf, err);
    if (rc) return rc;
    tracer *t = &s->tr[rank - 1];
    t->sent_at[(t->sent_head + t->inflight) % 64] = ct_now();
    t->in_round[(t->sent_head + t->inflight) % 64] = (unsigned char)round;
    t->inflight++;
    return 0;
}

/* Pops up to n requests and stamps them with the internal epoch. */
static int next_requests(loop_state *s, uint32_t n, ct_error *err)
{
    int rc = grow((void **)&s->reqs, &s->reqs_cap, n, sizeof *s->reqs, err);
    if (rc) return rc;
    int k = rq_next_batch(s->rq, s->reqs, (int)n, err);
    if (k < 0) return k;
    for (int i = 0; i < k; i++) s->reqs[i].epoch = s->epoch;
    return k;
}

/* Inserts samples (already in the order that must be used; smp is
 * consumed: its current samples are moved together in place). They go to
 * the textures in runs of up to INSERT_RUN (ctex_insert_batch prefetches
 * the texels of the samples ahead), then to the request queue in the same
 * order; neither reads the other's state. */
enum { INSERT_RUN = 64 };

/* The request queue's part of an inserted sample, and the counters. */
static void count_sample(loop_state *s, const ct_sample *x, const ctex_insert_info *info)
{
    if (info->tex >= 0) s->inserted++;
    else s->dropped_tex++;
    if (info->correction.x < 0 || info->correction.y < 0 || info->correction.z < 0) s->all_positive = 0;
    vec3 d = v3_sub(x->l_hq, x->l_base);
    if (d.x < 0 || d.y < 0 || d.z < 0) s->all_positive = 0;
    collect_point(s, x);
    s->total_samples++;
    if (s->in_frame) s->frame_samples++;
}

static void rejected(const ct_sample *x, ct_error *err)
{
    ct_warn(COMPONENT, "sample %llu rejected by the request queue: %s", (unsigned long long)x->request_id, err->msg);
    ct_error_clear(err);
}

static int insert_samples(loop_state *s, ct_sample *smp, uint32_t n, ct_error *err)
{
    double t0 = ct_now();
    ctex_set_clock(s->tex, ct_now_us());
    ctex_insert_info info[INSERT_RUN];
    ct_sample refine[INSERT_RUN];
    for (uint32_t i0 = 0; i0 < n; i0 += INSERT_RUN) {
        uint32_t i1 = n - i0 < INSERT_RUN ? n : i0 + INSERT_RUN, m = 0, nr = 0;
        ct_sample *run = smp + i0;
        /* Refinement samples (past full coverage) are not splatted: their
         * pixel's mean goes into their texel once the queue has it. */
        for (uint32_t i = i0; i < i1; i++) {
            if (smp[i].epoch != s->epoch) continue;
            if (rq_refines(s->rq, smp[i].request_id)) refine[nr++] = smp[i];
            else run[m++] = smp[i];
        }
        s->stale += (i1 - i0) - m - nr;
        ctex_insert_par(s->tex, NULL, run, m, info);
        for (uint32_t j = 0; j < m; j++) {
            ct_sample *x = &run[j];
            count_sample(s, x, &info[j]);
            x->epoch = s->rq_epoch;
            if (rq_report(s->rq, x, info[j].error, RQ_NODE_UNKNOWN, err) < 0) rejected(x, err);
        }
        for (uint32_t j = 0; j < nr; j++) {
            ct_sample *x = &refine[j];
            x->epoch = s->rq_epoch;
            int rc = rq_report(s->rq, x, v3s(0.0f), RQ_NODE_UNKNOWN, err);
            if (rc < 0) {
                rejected(x, err);
                continue;
            }
            ctex_insert_info ri = {.tex = -1};
            if (rc & RQ_REPORT_REFINE) ctex_refine(s->tex, x, rq_pixel_mean(s->rq, x->px, x->py), &ri);
            count_sample(s, x, &ri);
        }
    }
    s->t_tex += ct_now() - t0;
    return 0;
}

static int by_id(const void *a, const void *b)
{
    uint64_t x = ((const ct_sample *)a)->request_id, y = ((const ct_sample *)b)->request_id;
    return x < y ? -1 : x > y;
}

/* Reads every sample batch that arrived; 1 when any did. */
static int receive_samples(loop_state *s, ct_error *err)
{
    int any = 0;
    mpil_info info;
    for (;;) {
        /* Never a blocking receive: a stopped tracer in the middle of a
         * large message would hold the loop, its watchdog included. */
        int got = mpil_poll_recv(MPIL_ANY, MPIL_ANY, &info, &s->mbuf, err);
        if (got < 0) return got;
        if (!got) break;
        int rc;
        char peer[32];
        snprintf(peer, sizeof peer, "tracer rank %d", info.source);
        if (info.tag != MPIL_TAG_SAMPLES || info.source < 1 || info.source > s->T)
            return ct_fail(err, CT_EPROTO, "%s: unexpected MPI message with tag %d", peer, info.tag);
        unsigned kind;
        uint32_t count;
        if ((rc = wire_mpi_peek(s->mbuf.data, s->mbuf.len, peer, &kind, &count, err))) return rc;
        if ((rc = grow((void **)&s->samples, &s->samples_cap, count ? count : 1, sizeof *s->samples, err))) return rc;
        wire_mpi_samples h;
        if ((rc = wire_mpi_decode_samples(s->mbuf.data, s->mbuf.len, peer, &h, s->samples, s->samples_cap, &count,
                                          err)))
            return rc;
        tracer *t = &s->tr[info.source - 1];
        double now = ct_now();
        /* A tracer answers its batches in order: the oldest one is this. */
        int was_round = t->inflight > 0 && t->in_round[t->sent_head];
        if (t->inflight > 0) {
            /* The batch was traced from when it was sent or when the
             * previous answer left the tracer, whichever is later. */
            double start = t->sent_at[t->sent_head];
            if (t->last_reply > start) start = t->last_reply;
            double dt = now - start;
            t->sent_head = (t->sent_head + 1) % 64;
            t->inflight--;
            if (count > 0 && dt > 1e-6) {
                double r = count / dt;
                t->rate = t->rate > 0 ? 0.7 * t->rate + 0.3 * r : r;
            }
        }
        t->last_reply = now;
        t->samples += count;
        any = 1;
        if (was_round) {
            if ((rc = grow((void **)&s->round_buf, &s->round_cap, s->round_n + count, sizeof *s->round_buf, err)))
                return rc;
            memcpy(s->round_buf + s->round_n, s->samples, count * sizeof *s->samples);
            s->round_n += count;
            if (--s->round_out == 0) {
                qsort(s->round_buf, s->round_n, sizeof *s->round_buf, by_id);
                if ((rc = insert_samples(s, s->round_buf, s->round_n, err))) return rc;
                s->round_n = 0;
            }
        } else if ((rc = insert_samples(s, s->samples, count, err))) {
            return rc;
        }
    }
    return any;
}

static uint32_t batch_size(const loop_state *s, const tracer *t)
{
    double b = t->rate > 0 ? t->rate * s->c->opt.batch_ms / 1000.0 : s->c->opt.batch_min;
    if (b < s->c->opt.batch_min) b = s->c->opt.batch_min;
    if (b > s->c->opt.batch_max) b = s->c->opt.batch_max;
    return (uint32_t)b;
}

/* Free-running: fill every tracer's window, one batch per tracer per pass
 * starting from a rotating rank, so that no tracer is starved when the
 * request queue runs short. 1 when work was handed out. */
static int feed_free(loop_state *s, ct_error *err)
{
    if (!s->have_cam) return 0;
    int any = 0;
    for (int pass = 0; pass < s->c->opt.window; pass++) {
        int gave = 0;
        for (int i = 0; i < s->T; i++) {
            int r = 1 + (s->rr + i) % s->T;
            tracer *t = &s->tr[r - 1];
            if (t->inflight >= s->c->opt.window) continue;
            int k = next_requests(s, batch_size(s, t), err);
            if (k < 0) return k;
            if (k == 0) return any;   /* every pixel of this view is handed out */
            int rc = send_batch(s, r, s->reqs, (uint32_t)k, 0, err);
            if (rc) return rc;
            any = gave = 1;
        }
        s->rr = (s->rr + 1) % s->T;
        if (!gave) break;
    }
    return any;
}

static int end_frame(loop_state *s, ct_error *err)
{
    flush_samples(s);
    double t0 = ct_now();
    int rc = dsync_flush_all(s->sync, s->ds, s->tex, &s->frame_patches, err);
    s->t_tex += ct_now() - t0;
    if (rc) return rc;
    s->in_frame = 0;
    rq_stats rs;
    rq_stats_get(s->rq, &rs);
    ct_debug(COMPONENT, "frame %llu: %u samples, %u patches; queue %llu, in flight %llu, coverage %.3f, stale %llu%s",
             (unsigned long long)s->frame_no, s->frame_samples, s->frame_patches, (unsigned long long)rs.queued,
             (unsigned long long)rs.in_flight, rs.coverage, (unsigned long long)s->stale,
             s->frame_orphan ? " (its display left)" : "");
    if (s->frame_orphan) {
        s->frame_orphan = 0;
        return 0;
    }
    wire_msg m = {.type = WIRE_FRAME};
    m.u.frame = (wire_frame){s->frame_no, s->disp_epoch, s->all_positive ? WIRE_FLAG_ALL_POSITIVE : 0u,
                             s->frame_samples, s->frame_patches};
    if ((rc = send_msg(s, &m, err))) return rc;
    s->frame_no++;
    return 0;
}

/* Lockstep: start frames and rounds. 1 when work was handed out. */
static int feed_lockstep(loop_state *s, ct_error *err)
{
    int rc;
    if (!s->in_frame) {
        if (!s->fr_n) return 0;
        /* Free-running batches still out (a free-running display was here
         * before) are taken in first, so a frame starts from a fixed state. */
        if (total_inflight(s) > 0) return 0;
        frame_req f = s->frames[s->fr_head];
        s->fr_head = (s->fr_head + 1) % MAX_FRAMES_QUEUED;
        s->fr_n--;
        if ((rc = camera_or_drop(s, &f.cam, err))) return rc;
        if (!s->have_cam || !same_view(s, &f.cam)) return 1;   /* refused */
        s->in_frame = 1;
        s->frame_left = s->K;
        s->frame_samples = 0;
    }
    if (s->round_out > 0) return 0;
    uint32_t n = s->frame_left < (uint32_t)s->c->opt.round ? s->frame_left : (uint32_t)s->c->opt.round;
    int k = n ? next_requests(s, n, err) : 0;
    if (k < 0) return k;
    if (k == 0) {
        if ((rc = end_frame(s, err))) return rc;
        return 1;
    }
    s->frame_left -= (uint32_t)k;
    /* One part per tracer; the split does not change the result. */
    uint32_t per = ((uint32_t)k + (uint32_t)s->T - 1) / (uint32_t)s->T;
    for (int r = 1; r <= s->T; r++) {
        uint32_t b = (uint32_t)(r - 1) * per;
        if (b >= (uint32_t)k) break;
        uint32_t e = b + per > (uint32_t)k ? (uint32_t)k : b + per;
        if ((rc = send_batch(s, r, s->reqs + b, e - b, 1, err))) return rc;
        s->round_out++;
    }
    return 1;
}

/* --- display events ------------------------------------------------------------ */

static int handle_display(loop_state *s, int *leave, ct_error *err)
{
    dsrv_event ev;
    int rc;
    /* Free-running: of the cameras that arrived since the last turn only the
     * newest matters (each change costs an assignment pass). */
    wire_camera latest;
    int have_latest = 0;
    while (dsrv_next_event(s->ds, &ev)) {
        switch (ev.kind) {
        case DSRV_EV_CONNECTED:
            /* A frame of the previous display still running ends with its
             * current round, without a FRAME: the new display did not ask
             * for it. */
            s->frame_left = 0;
            s->frame_orphan = s->in_frame;
            s->lockstep = ev.msg.u.settings.samples_per_frame > 0;
            s->K = ev.msg.u.settings.samples_per_frame;
            s->frame_no = 0;
            s->fr_n = 0;
            s->npts = 0;          /* points of an earlier display */
            s->pts_dropped = 0;
            if ((rc = send_state(s, &ev.msg.u.settings, err))) return rc;
            break;
        case DSRV_EV_MESSAGE:
            if (ev.msg.type == WIRE_ACK) {
                if (dsync_ack(s->sync, ev.msg.u.ack.seq, ct_now(), err)) {
                    dsrv_drop(s->ds, WIRE_ERR_PROTOCOL, err->msg);
                    ct_error_clear(err);
                }
                break;
            }
            if (ev.msg.type != WIRE_CAMERA) break;
            if (ev.msg.u.camera.width == 0 || ev.msg.u.camera.height == 0) {
                dsrv_drop(s->ds, WIRE_ERR_PROTOCOL, "CAMERA with an empty image size");
                break;
            }
            if (s->lockstep) {
                if (s->fr_n == MAX_FRAMES_QUEUED) {
                    dsrv_drop(s->ds, WIRE_ERR_LIMIT, "more than 64 lockstep frames requested ahead");
                    break;
                }
                s->frames[(s->fr_head + s->fr_n) % MAX_FRAMES_QUEUED].cam = ev.msg.u.camera;
                s->fr_n++;
            } else {
                latest = ev.msg.u.camera;
                have_latest = 1;
            }
            break;
        case DSRV_EV_DISCONNECTED:
            s->fr_n = 0;   /* frames asked for by a display that left */
            dsync_reset(s->sync);
            have_latest = 0;
            if (s->c->opt.exit_when_display_leaves) *leave = 1;
            break;
        }
    }
    if (have_latest && dsrv_has_display(s->ds) && !s->lockstep) return camera_or_drop(s, &latest, err);
    return 0;
}

/* --- stats ---------------------------------------------------------------------- */

static void stats(loop_state *s, double now)
{
    double dt = now - s->t_mark;
    if (dt <= 0) return;
    char per_rank[512];
    size_t off = 0;
    uint64_t sum = 0;
    per_rank[0] = 0;
    for (int r = 1; r <= s->T; r++) {
        tracer *t = &s->tr[r - 1];
        uint64_t d = t->samples - t->samples_mark;
        t->samples_mark = t->samples;
        sum += d;
        if (off < sizeof per_rank - 32)
            off += (size_t)snprintf(per_rank + off, sizeof per_rank - off, "%sr%d %.0f", r > 1 ? ", " : "", r, d / dt);
    }
    uint64_t bytes = dsrv_bytes_sent(s->ds);
    double bps = (double)(bytes - s->bytes_mark) / dt;
    s->bytes_mark = bytes;
    rq_stats rs = {0};
    if (s->rq) rq_stats_get(s->rq, &rs);
    ctex_stats ts = ctex_get_stats(s->tex);
    double ft = s->t_tex / dt, fs = s->t_sample_wait / dt, fr = s->t_render_wait / dt;
    double tot = ft + fs + fr;
    /* Fractions of the accounted time (texture work + waiting for samples +
     * waiting for the display); all zero when the master only idled. */
    double bt = tot > 1e-3 * dt ? ft / tot : 0, bs = tot > 1e-3 * dt ? fs / tot : 0,
           br = tot > 1e-3 * dt ? fr / tot : 0;
    char refining[96] = "";
    if (rs.refining)
        snprintf(refining, sizeof refining, " (refining: %llu more samples, largest pixel error %.2g)",
                 (unsigned long long)rs.refine_samples, (double)rs.refine_error);
    char dropped[64] = "";
    if (s->pts_dropped_total)
        snprintf(dropped, sizeof dropped, ", %llu sample points dropped",
                 (unsigned long long)s->pts_dropped_total);
    /* Idle intervals only at debug level: a waiting master would fill the log. */
    ct_log(sum || bps > 0 ? CT_LOG_INFO : CT_LOG_DEBUG, COMPONENT,
            "stats: %.0f samples/s (%s), total %llu (%llu without texture, %llu stale), queue %llu, coverage "
            "%.1f%%%s, textures %u (%.1f MiB), display %.1f KB/s, render:sample:texture %.0f:%.0f:%.0f, busy %.0f%%%s",
            sum / dt, per_rank, (unsigned long long)s->total_samples, (unsigned long long)s->dropped_tex,
            (unsigned long long)s->stale, (unsigned long long)rs.queued, 100.0 * rs.coverage, refining,
            ts.textures, ts.bytes / 1048576.0, bps / 1000.0, 100 * br, 100 * bs, 100 * bt, 100 * (tot > 1 ? 1 : tot),
            dropped);
    if (dsrv_has_display(s->ds)) {
        wire_msg m = {.type = WIRE_STATS};
        m.u.stats = (wire_stats){.epoch = s->disp_epoch,
                                 .flags = s->all_positive ? WIRE_FLAG_ALL_POSITIVE : 0u,
                                 .samples_total = s->total_samples,
                                 .samples_per_s = (float)(sum / dt),
                                 .queue_len = (uint32_t)(rs.queued > UINT32_MAX ? UINT32_MAX : rs.queued),
                                 .coverage = (float)rs.coverage,
                                 .textures = ts.textures,
                                 .texel_bytes = ts.bytes,
                                 .bytes_per_s = (float)bps,
                                 .t_render = (float)br,
                                 .t_sample = (float)bs,
                                 .t_texture = (float)bt};
        ct_error e;
        send_msg(s, &m, &e);
    }
    s->t_tex = s->t_sample_wait = s->t_render_wait = 0;
    s->t_mark = now;
}

/* --- the loop --------------------------------------------------------------------- */

static int total_inflight(const loop_state *s)
{
    int n = 0;
    for (int i = 0; i < s->T; i++) n += s->tr[i].inflight;
    return n;
}

static int check_tracers(loop_state *s, double now, ct_error *err)
{
    for (int r = 1; r <= s->T; r++) {
        tracer *t = &s->tr[r - 1];
        if (t->inflight > 0 && now - t->sent_at[t->sent_head] > s->c->opt.tracer_timeout_s)
            return ct_fail(err, CT_EIO, "tracer rank %d has not answered for %.0f s (%d batches outstanding)", r,
                           now - t->sent_at[t->sent_head], t->inflight);
    }
    return 0;
}

static void shutdown_tracers(loop_state *s, double wait_s)
{
    wire_mpi_control ctl = {.op = WIRE_MPI_OP_SHUTDOWN};
    ct_error e;
    for (int r = 1; r <= s->T; r++) {
        s->obuf.len = 0;
        if (wire_mpi_encode_control(&ctl, &s->obuf, &e) == 0) mpil_isend(r, MPIL_TAG_CONTROL, &s->obuf, &e);
    }
    if (mpil_drain(wait_s, &e) < 0) ct_warn(COMPONENT, "%s", e.msg);
}

int sched_run(const sched_config *c, ct_error *err)
{
    loop_state s;
    memset(&s, 0, sizeof s);
    s.c = c;
    s.T = c->ntracers;
    s.all_positive = 1;
    int rc = 0;
    s.tr = calloc((size_t)s.T, sizeof *s.tr);
    if (!s.tr) {
        rc = ct_fail(err, CT_ENOMEM, "master: out of memory");
        goto out;
    }
    if ((rc = ctex_new(c->mesh, c->scene->mats, c->scene->nmats, c->ctex, &s.tex, err))) goto out;
    dsrv_config dc = {.listen = c->listen, .token = c->token, .handshake_timeout_ms = c->opt.handshake_ms,
                      .queue_bytes = c->opt.queue_mb << 20};
    if ((rc = dsrv_new(&dc, &s.ds, err))) goto out;
    dsync_options so;
    dsync_options_default(&so, strncmp(dsrv_addr(s.ds), "tcp:", 4) == 0);
    if (c->opt.patch_encoding >= 0) so.encoding = (uint32_t)c->opt.patch_encoding;
    if ((rc = dsync_new(&so, &s.sync, err))) goto out;
    ct_info(COMPONENT, "listening on %s (%d tracer rank%s)", dsrv_addr(s.ds), s.T, s.T == 1 ? "" : "s");
    /* A line scripts can wait for. */
    fprintf(stdout, "corrtex-render: listening on %s\n", dsrv_addr(s.ds));
    fflush(stdout);

    double now = ct_now();
    s.t_mark = s.last_patch = s.last_stats = now;
    int leave = 0, busy = 1;
    while (!leave && !(c->stop && *c->stop)) {
        double t0 = ct_now();
        int inflight = total_inflight(&s);
        int timeout = busy ? 0 : (inflight ? 1 : c->opt.idle_ms);
        if ((rc = dsrv_step(s.ds, timeout, err))) break;
        double t1 = ct_now();
        /* Waiting time: for samples while batches are out, else for the
         * display (lockstep: it renders the previous frame meanwhile). */
        if (inflight) s.t_sample_wait += t1 - t0;
        else if (s.lockstep && dsrv_has_display(s.ds)) s.t_render_wait += t1 - t0;
        if ((rc = handle_display(&s, &leave, err))) break;
        int got = receive_samples(&s, err);
        if (got < 0) { rc = got; break; }
        if ((rc = mpil_progress(err)) < 0) break;
        rc = 0;
        int fed = s.lockstep ? feed_lockstep(&s, err) : feed_free(&s, err);
        if (fed < 0) { rc = fed; break; }
        busy = got || fed;
        now = ct_now();
        if (s.have_cam && !s.view_covered) {
            rq_stats rs;
            rq_stats_get(s.rq, &rs);
            if (rs.covered) {
                s.view_covered = 1;
                /* A moving camera covers small views every frame: one
                 * info line per stats interval, the rest at debug level. */
                int lvl = now - s.covered_logged >= c->opt.stats_s ? CT_LOG_INFO : CT_LOG_DEBUG;
                if (lvl == CT_LOG_INFO) s.covered_logged = now;
                ct_log(lvl, COMPONENT, "view covered: every pixel sampled %.2f s after the camera stopped (%llu samples)",
                        now - s.view_t0, (unsigned long long)s.total_samples);
            }
        }
        if (!s.lockstep && now - s.last_patch >= c->opt.patch_ms / 1000.0 && dsync_can_send(s.sync)) {
            if ((rc = send_update(&s, err))) break;
            s.last_patch = now;
        }
        if (now - s.last_stats >= c->opt.stats_s) {
            stats(&s, now);
            s.last_stats = now;
        }
        if ((rc = check_tracers(&s, now, err))) break;
    }
    if (rc) {
        char why[CT_ERROR_LEN];
        snprintf(why, sizeof why, "master failed: %s", err->msg);
        dsrv_drop(s.ds, WIRE_ERR_INTERNAL, why);
    } else if (c->stop && *c->stop == SIGTERM) {
        dsrv_drop(s.ds, WIRE_ERR_INTERNAL,
                  "the MPI job is ending: the master got SIGTERM (mpirun sends it when a rank dies or the job is "
                  "stopped)");
    } else if (s.ds) {
        dsrv_bye(s.ds, WIRE_BYE_SHUTDOWN, 2000);
    }
    if (c->stop && *c->stop) ct_info(COMPONENT, "signal %d: shutting down", *c->stop);
    /* The socket file goes first: nothing should connect to a job that ends. */
    dsrv_free(s.ds);
    s.ds = NULL;
out:
    /* Also after a failed start: the tracers wait for work or SHUTDOWN. */
    shutdown_tracers(&s, rc ? 0.5 : 3.0);
    dsrv_free(s.ds);
    rq_free(s.rq);
    ctex_free(s.tex);
    if (s.have_scene_tx) wire_scene_tx_free(&s.scene_tx);
    free(s.tr);
    free(s.reqs);
    free(s.samples);
    free(s.round_buf);
    dsync_free(s.sync);
    free(s.pts);
    wire_buf_free(&s.mbuf);
    wire_buf_free(&s.obuf);
    return rc;
}
