/* sched.c: the master of corrtex-render (sched.h). One thread talks to the
 * socket and to MPI (the session's own threads only insert): each turn polls
 * the display socket (a short timeout only while nothing else is to do),
 * turns display events into views and frame requests, runs the loop
 * (drive.h), sends texture updates and prints stats. */
#include "master/sched.h"

#include <signal.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "common/timer.h"
#include "master/dsink.h"
#include "master/dsrv.h"
#include "proto/wire.h"

#define COMPONENT "master"
#define MAX_FRAMES_QUEUED 64
#define MAX_VIEW_WAIT_S 1.0   /* the longest a camera change's cost holds the next (take_view) */

static const int PATCH_ENC[] = {WIRE_PATCH_RAW, WIRE_PATCH_LZ4, -1};
static const int DISPLAY_TEXELS[] = {0, 1, -1};

#define OF(f) offsetof(sched_options, f)
static const optab OPTS[] = {
    {"patch-ms", 0, OPTAB_DOUBLE, OF(patch_ms), 0, 10000, "10", "X",
     "free-running: shortest interval of texture updates to the display (ms)", NULL},
    {"patch-share", 0, OPTAB_DOUBLE, OF(patch_share), 0.0001, 1, "0.25", "X",
     "free-running: the most of the master's time texture updates may take; the next waits until then (1: every "
     "--patch-ms)", NULL},
    {"stats-s", 0, OPTAB_DOUBLE, OF(stats_s), 0.05, 3600, "1", "X", "interval of the stats line and STATS message (s)",
     NULL},
    {"handshake-ms", 0, OPTAB_INT, OF(handshake_ms), 10, 600000, "5000", "N",
     "a connecting display must finish its handshake within this (ms)", NULL},
    {"send-timeout-ms", 0, OPTAB_INT, OF(send_timeout_ms), 10, 600000, "10000", "N",
     "drop a display that does not read its full queue for this long (ms)", NULL},
    {"tracer-timeout-s", 0, OPTAB_DOUBLE, OF(tracer_timeout_s), 0.1, 86400, "30", "X",
     "end the job when a tracer with work is silent this long (s)", NULL},
    {"idle-ms", 0, OPTAB_INT, OF(idle_ms), 0, 1000, "2", "N", "socket poll timeout while idle (ms)", NULL},
    {"queue-mb", 0, OPTAB_SIZE, OF(queue_mb), 1, 65536, "64", "N", "display send queue bound (MiB)", NULL},
    {"patch-encoding", 0, OPTAB_CHOICE, OF(patch_encoding), 0, 0, "auto", "raw|lz4|auto",
     "texels to the display: raw, lz4 or auto (raw on UNIX, lz4 on TCP)", PATCH_ENC},
    {"display-texels", 0, OPTAB_CHOICE, OF(display_texels), 0, 0, "auto", "all|screen|auto",
     "texels to the display: all, at most one a screen pixel (denser textures as means of 2x2), or auto (screen on "
     "TCP, all on UNIX)", DISPLAY_TEXELS},
    {"view-ms", 0, OPTAB_DOUBLE, OF(view_ms), 0, 10000, "50", "X",
     "free-running: shortest interval between two camera changes (ms); a newer camera waits until then", NULL},
    {"view-share", 0, OPTAB_DOUBLE, OF(view_share), 0.0001, 1, "0.25", "X",
     "free-running: the most of the master's time camera changes may take; a newer camera waits until then (1: "
     "every camera at once)", NULL},
    {"exit-when-display-leaves", 0, OPTAB_FLAG, OF(exit_when_display_leaves), 0, 0, NULL, NULL,
     "end the job when the display disconnects (batch runs)", NULL},
};
#undef OF

const optab *sched_options_table(size_t *n)
{
    *n = OPTAB_COUNT(OPTS);
    return OPTS;
}

/* Everything the loop keeps between turns. */
typedef struct loop {
    const sched_config *c;
    dsrv *ds;
    dsink *dk;
    sess *s;
    drv *d;
    bool lockstep;
    uint32_t K;
    wire_camera frames[MAX_FRAMES_QUEUED];   /* lockstep frame requests */
    int fr_head, fr_n;
    wire_camera next_view;   /* free running: the newest camera, waiting for view_ready */
    bool view_waits;
    double view_ready;       /* when the next camera change may start */
    double view_t0;
    bool view_covered;
    double covered_logged;   /* when a coverage line was last logged at info level */
    double t_tex, t_sample_wait, t_render_wait, t_mark, last_stats, tex_mark;
    uint64_t bytes_mark;
    uint64_t *lane_mark;
} loop;

/* A display's camera (a new epoch when the view changed). A camera the
 * engines refuse (a bad field of view, an image too large for memory) is
 * the display's fault, not the job's: the display is dropped with the
 * reason and the master goes on. Only MPI failures (CT_EIO) end the job. */
static int camera_or_drop(loop *l, const wire_camera *c, ct_error *err)
{
    dsink_set_epoch(l->dk, c->epoch);
    double t0 = ct_now();
    int rc = drv_set_view(l->d, &c->cam, (int)c->width, (int)c->height, err);
    if (rc == 1) {
        l->view_t0 = t0;
        l->view_covered = false;
        ct_debug(COMPONENT, "camera epoch %u (display epoch %u), %ux%u", sess_epoch(l->s), c->epoch, c->width,
                 c->height);
    }
    if (rc >= 0 || rc == CT_EIO) return rc < 0 ? rc : 0;
    char why[CT_ERROR_LEN];
    snprintf(why, sizeof why, "camera refused: %s", err->msg);
    dsrv_drop(l->ds, rc == CT_ENOMEM ? WIRE_ERR_LIMIT : WIRE_ERR_PROTOCOL, why);
    ct_error_clear(err);
    l->fr_n = 0;
    return 0;
}

/* Lockstep: starts the next requested frame once the loop is idle (batches
 * of a free-running display before are taken in first, so a frame starts
 * from a fixed state). 1 when one started or a request was refused. */
static int start_frame(loop *l, ct_error *err)
{
    if (!l->lockstep || drv_in_frame(l->d) || !l->fr_n || drv_inflight(l->d) > 0) return 0;
    wire_camera f = l->frames[l->fr_head];
    l->fr_head = (l->fr_head + 1) % MAX_FRAMES_QUEUED;
    l->fr_n--;
    int rc = camera_or_drop(l, &f, err);
    if (rc) return rc;
    if (sess_same_view(l->s, &f.cam, (int)f.width, (int)f.height)) drv_begin_frame(l->d, l->K);
    return 1;
}

/* Free running: the newest camera that arrived, at most every --view-ms
 * and once camera changes have had no more than their share of the
 * master's time. A display moving its camera sends one a frame (60-144 a
 * second, hundreds without vsync); each change costs the master its queue,
 * the textures' assignment and reprojection, and stops the tracers'
 * batches: taken one by one at 60 a second, nearly every traced sample was
 * stale (docs/distributed.md, "Camera changes"). So the next change waits
 * view_ms after this one started, and t (1 - share) / share after a change
 * that took t (a second at most); the cameras that arrive meanwhile
 * replace each other, and the newest is taken when the time is up. */
static int take_view(loop *l, ct_error *err)
{
    if (!l->view_waits || l->lockstep || !dsrv_has_display(l->ds)) {
        l->view_waits = false;
        return 0;
    }
    double t0 = ct_now();
    if (t0 < l->view_ready) return 0;
    l->view_waits = false;
    int rc = camera_or_drop(l, &l->next_view, err);
    double t1 = ct_now(), share = l->c->opt.view_share;
    /* A rare costly change (a new image size of many megapixels) holds the
     * camera for a second at most: the user is still moving it. */
    double wait = (t1 - t0) * (1.0 - share) / share;
    double by_cost = t1 + (wait < MAX_VIEW_WAIT_S ? wait : MAX_VIEW_WAIT_S);
    double by_interval = t0 + l->c->opt.view_ms / 1000.0;
    l->view_ready = by_cost > by_interval ? by_cost : by_interval;
    return rc;
}

static int handle_display(loop *l, int *leave, ct_error *err)
{
    dsrv_event ev;
    int rc;
    while (dsrv_next_event(l->ds, &ev)) {
        switch (ev.kind) {
        case DSRV_EV_CONNECTED:
            /* A frame of the previous display still running ends with its
             * current round, without a FRAME: the new display did not ask
             * for it. */
            if (drv_in_frame(l->d)) {
                drv_cut_frame(l->d);
                dsink_orphan_frame(l->dk);
            }
            l->lockstep = ev.msg.u.settings.samples_per_frame > 0;
            l->view_waits = false;
            l->view_ready = 0.0;   /* a new display's first camera goes in at once */
            l->K = ev.msg.u.settings.samples_per_frame;
            drv_set_lockstep(l->d, l->lockstep);
            l->fr_n = 0;
            if ((rc = dsink_connected(l->dk, l->s, &ev.msg.u.settings, err))) return rc;
            break;
        case DSRV_EV_MESSAGE:
            if (!dsrv_has_display(l->ds)) break;   /* the rest of a display dropped above */
            if (ev.msg.type == WIRE_ACK) {
                if (dsink_ack(l->dk, ev.msg.u.ack.seq, err)) {
                    dsrv_drop(l->ds, WIRE_ERR_PROTOCOL, err->msg);
                    ct_error_clear(err);
                }
                break;
            }
            if (ev.msg.type != WIRE_CAMERA) break;
            if (ev.msg.u.camera.width == 0 || ev.msg.u.camera.height == 0) {
                dsrv_drop(l->ds, WIRE_ERR_PROTOCOL, "CAMERA with an empty image size");
                break;
            }
            if (l->lockstep) {
                if (l->fr_n == MAX_FRAMES_QUEUED) {
                    dsrv_drop(l->ds, WIRE_ERR_LIMIT, "more than 64 lockstep frames requested ahead");
                    break;
                }
                l->frames[(l->fr_head + l->fr_n) % MAX_FRAMES_QUEUED] = ev.msg.u.camera;
                l->fr_n++;
            } else {
                l->next_view = ev.msg.u.camera;
                l->view_waits = true;
            }
            break;
        case DSRV_EV_DISCONNECTED:
            l->fr_n = 0;   /* frames asked for by a display that left */
            dsink_disconnected(l->dk);
            l->view_waits = false;
            if (l->c->opt.exit_when_display_leaves) *leave = 1;
            break;
        }
    }
    return take_view(l, err);
}

static void stats(loop *l, double now)
{
    double dt = now - l->t_mark;
    if (dt <= 0) return;
    char per_rank[512];
    size_t off = 0;
    uint64_t sum = 0;
    per_rank[0] = 0;
    for (int i = 0; i < l->c->port->lanes; i++) {
        const drv_lane *ln = drv_lane_get(l->d, i);
        uint64_t d = ln->samples - l->lane_mark[i];
        l->lane_mark[i] = ln->samples;
        sum += d;
        if (off < sizeof per_rank - 32)
            off += (size_t)snprintf(per_rank + off, sizeof per_rank - off, "%sr%d %.0f", i ? ", " : "", i + 1, d / dt);
    }
    uint64_t bytes = dsrv_bytes_sent(l->ds);
    double bps = (double)(bytes - l->bytes_mark) / dt;
    l->bytes_mark = bytes;
    rq_stats rs;
    sess_queue_stats(l->s, &rs);
    ctex_stats ts = ctex_get_stats(sess_textures(l->s));
    sess_counters n = sess_get_counters(l->s);
    l->t_tex += n.t_texture - l->tex_mark + dsink_take_encode_s(l->dk);
    l->tex_mark = n.t_texture;
    double ft = l->t_tex / dt, fs = l->t_sample_wait / dt, fr = l->t_render_wait / dt;
    double tot = ft + fs + fr;
    /* Fractions of the accounted time (texture work + waiting for samples +
     * waiting for the display); all zero when the master only idled. */
    double bt = tot > 1e-3 * dt ? ft / tot : 0, bs = tot > 1e-3 * dt ? fs / tot : 0,
           br = tot > 1e-3 * dt ? fr / tot : 0;
    char refining[96] = "", dropped[64] = "";
    if (rs.refining)
        snprintf(refining, sizeof refining, " (refining: %llu more samples, largest pixel error %.2g)",
                 (unsigned long long)rs.refine_samples, (double)rs.refine_error);
    if (dsink_points_dropped(l->dk))
        snprintf(dropped, sizeof dropped, ", %llu sample points dropped",
                 (unsigned long long)dsink_points_dropped(l->dk));
    /* Idle intervals only at debug level: a waiting master would fill the log. */
    ct_log(sum || bps > 0 ? CT_LOG_INFO : CT_LOG_DEBUG, COMPONENT,
           "stats: %.0f samples/s (%s), total %llu (%llu without texture, %llu late), %llu stale, %llu of them turned "
           "past --late-deg, %llu under fresher texels, %llu off the textures, queue %llu, "
           "coverage %.1f%%%s, textures %u (%.1f MiB), display %.1f KB/s, render:sample:texture %.0f:%.0f:%.0f, busy "
           "%.0f%%, %d master thread%s, %llu node mismatches, views %llu (%.1f ms in all, %llu shown-node maps)%s",
           sum / dt, per_rank, (unsigned long long)n.inserted, (unsigned long long)n.no_texture,
           (unsigned long long)n.late, (unsigned long long)n.stale, (unsigned long long)n.late_turned,
           (unsigned long long)n.late_covered, (unsigned long long)n.late_off,
           (unsigned long long)rs.queued,
           100.0 * rs.coverage, refining, ts.textures, ts.bytes / 1048576.0, bps / 1000.0, 100 * br, 100 * bs, 100 * bt, 100 * (tot > 1 ? 1 : tot),
           sess_threads(l->s), sess_threads(l->s) == 1 ? "" : "s", (unsigned long long)rs.mismatches,
           (unsigned long long)n.views, 1e3 * n.t_view, (unsigned long long)n.shown_maps, dropped);
    wire_stats st = {.flags = n.all_positive ? WIRE_FLAG_ALL_POSITIVE : 0u,
                     .samples_total = n.inserted,
                     .samples_per_s = (float)(sum / dt),
                     .queue_len = (uint32_t)(rs.queued > UINT32_MAX ? UINT32_MAX : rs.queued),
                     .coverage = (float)rs.coverage,
                     .textures = ts.textures,
                     .texel_bytes = ts.bytes,
                     .bytes_per_s = (float)bps,
                     .t_render = (float)br,
                     .t_sample = (float)bs,
                     .t_texture = (float)bt};
    dsink_stats(l->dk, &st);
    l->t_tex = l->t_sample_wait = l->t_render_wait = 0;
    l->t_mark = now;
}

/* One turn of the loop; *busy says whether it did work. */
static int turn(loop *l, int *busy, int *leave, ct_error *err)
{
    const sched_options *o = &l->c->opt;
    double t0 = ct_now();
    int inflight = drv_inflight(l->d);
    int rc = dsrv_step(l->ds, *busy ? 0 : (inflight ? 1 : o->idle_ms), err);
    if (rc) return rc;
    double t1 = ct_now();
    /* Waiting time: for samples while batches are out, else for the
     * display (lockstep: it renders the previous frame meanwhile). */
    if (inflight) l->t_sample_wait += t1 - t0;
    else if (l->lockstep && dsrv_has_display(l->ds)) l->t_render_wait += t1 - t0;
    /* Samples that arrived go in before a camera that came with them
     * changes the view: they belong to the view they were traced for. */
    bool view_next = (dsrv_view_pending(l->ds) || l->view_waits) && (l->lockstep || t1 >= l->view_ready);
    int early = drv_receive(l->d, !view_next, err);
    if (early < 0) return early;
    if ((rc = handle_display(l, leave, err))) return rc;
    int got = drv_step(l->d, err);
    if (got >= 0) got |= early;
    if (got < 0) return got;
    int started = start_frame(l, err);
    if (started < 0) return started;
    int fed = started ? drv_step(l->d, err) : 0;
    if (fed < 0) return fed;
    *busy = got || started || fed;
    double now = ct_now();
    if (sess_has_view(l->s) && !l->view_covered) {
        rq_stats rs;
        sess_queue_stats(l->s, &rs);
        if (rs.covered) {
            l->view_covered = true;
            /* A moving camera covers small views every frame: one info
             * line per stats interval, the rest at debug level. */
            int lvl = now - l->covered_logged >= o->stats_s ? CT_LOG_INFO : CT_LOG_DEBUG;
            if (lvl == CT_LOG_INFO) l->covered_logged = now;
            ct_log(lvl, COMPONENT, "view covered: every pixel sampled %.2f s after the camera stopped (%llu samples)",
                   now - l->view_t0, (unsigned long long)sess_get_counters(l->s).inserted);
        }
    }
    if (!l->lockstep) dsink_drop_stalled(l->dk, now);
    dsink_drop_silent(l->dk, now);
    if (!l->lockstep && dsink_update_due(l->dk, now) && (rc = dsink_update(l->dk, l->s, err))) return rc;
    if (now - l->last_stats >= o->stats_s) {
        stats(l, now);
        l->last_stats = now;
    }
    return drv_check(l->d, now, o->tracer_timeout_s, err);
}

int sched_run(const sched_config *c, ct_error *err)
{
    loop l;
    memset(&l, 0, sizeof l);
    l.c = c;
    sess_config sc = {c->mesh, c->scene->mats, c->scene->nmats, c->rq, c->ctex, c->seed, c->session};
    dsrv_config dc = {.listen = c->listen, .token = c->token, .handshake_timeout_ms = c->opt.handshake_ms,
                      .queue_bytes = c->opt.queue_mb << 20};
    int rc = (l.lane_mark = calloc((size_t)c->port->lanes, sizeof *l.lane_mark)) ? CT_OK
                                                                                 : ct_fail(err, CT_ENOMEM, "master: out of memory");
    if (!rc) rc = sess_new(&sc, &l.s, err);
    if (!rc) rc = dsrv_new(&dc, &l.ds, err);
    if (!rc) {
        dsink_config kc = {l.ds, c->mesh, c->scene, c->opt.send_timeout_ms, c->opt.queue_mb << 20,
                           c->opt.patch_encoding, c->opt.display_texels, c->opt.patch_ms / 1000.0,
                           c->opt.patch_share};
        rc = dsink_new(&kc, &l.dk, err);
    }
    if (!rc) {
        sink k = dsink_sink(l.dk);
        rc = drv_new(l.s, c->port, &k, &c->drive, &l.d, err);
    }
    if (rc) goto out;
    ct_info(COMPONENT, "listening on %s (%d tracer rank%s, %d master thread%s)", dsrv_addr(l.ds), c->port->lanes,
            c->port->lanes == 1 ? "" : "s", sess_threads(l.s), sess_threads(l.s) == 1 ? "" : "s");
    /* A line scripts can wait for. */
    fprintf(stdout, "corrtex-render: listening on %s\n", dsrv_addr(l.ds));
    fflush(stdout);
    l.t_mark = l.last_stats = ct_now();
    int leave = 0, busy = 1;
    while (!leave && !(c->stop && *c->stop) && !(rc = turn(&l, &busy, &leave, err))) {
    }
    if (rc) {
        char why[CT_ERROR_LEN];
        snprintf(why, sizeof why, "master failed: %s", err->msg);
        dsrv_drop(l.ds, WIRE_ERR_INTERNAL, why);
    } else if (c->stop && *c->stop == SIGTERM) {
        bool had = dsrv_has_display(l.ds);
        bool told = dsrv_drop(l.ds, WIRE_ERR_INTERNAL,
                              "the MPI job is ending: the master got SIGTERM (mpirun sends it when a rank dies or "
                              "the job is stopped)");
        /* (a display whose queue stays full for half a second is not told:
         * the tests read which) */
        if (had)
            ct_info(COMPONENT, "%s",
                    told ? "told the display the job is ending"
                         : "could not tell the display the job is ending: its socket stayed full for 0.5 s");
    } else {
        dsrv_bye(l.ds, WIRE_BYE_SHUTDOWN, 2000);
    }
    if (c->stop && *c->stop) ct_info(COMPONENT, "signal %d: shutting down", *c->stop);
out:
    /* The socket file goes first: nothing should connect to a job that
     * ends. Then the tracers, also after a failed start: they wait for
     * work or SHUTDOWN. */
    dsrv_free(l.ds);
    c->port->ops->close(c->port, rc ? 0.5 : 3.0);
    drv_free(l.d);
    dsink_free(l.dk);
    sess_free(l.s);
    free(l.lane_mark);
    return rc;
}
