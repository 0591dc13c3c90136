/* dsink.c: the display sink (dsink.h). */
#include "master/dsink.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "common/timer.h"

#define COMPONENT "master"

struct dsink {
    dsink_config c;
    dsync *sync;
    wire_scene_tx scene_tx;
    bool have_scene_tx;
    uint32_t disp_epoch;        /* the display's epoch number of the current camera */
    uint64_t frame_no;
    bool orphan;                /* the frame in progress belongs to a display that left */
    uint32_t frame_patches;
    double t_encode;
    /* SAMPLES: hit points inserted since the last send (droppable) */
    float *pts;                 /* 3 * WIRE_SAMPLES_MAX_POINTS floats once a display is there */
    uint32_t npts;
    uint64_t pts_dropped;       /* points not sent to the current display */
    uint64_t pts_dropped_total; /* the same since the start (stats line) */
};

int dsink_new(const dsink_config *c, dsink **out, ct_error *err)
{
    *out = NULL;
    dsink *k = calloc(1, sizeof *k);
    if (!k) return ct_fail(err, CT_ENOMEM, "master: out of memory");
    k->c = *c;
    dsync_options so;
    dsync_options_default(&so, strncmp(dsrv_addr(c->ds), "tcp:", 4) == 0);
    if (c->patch_encoding >= 0) so.encoding = (uint32_t)c->patch_encoding;
    if (c->display_texels >= 0) so.screen_rate = c->display_texels == 1;
    so.interval_s = c->patch_s;
    so.send_timeout_ms = c->send_timeout_ms;
    so.share = c->patch_share;
    int rc = dsync_new(&so, &k->sync, err);
    if (rc) {
        free(k);
        return rc;
    }
    *out = k;
    return CT_OK;
}

void dsink_free(dsink *k)
{
    if (!k) return;
    if (k->have_scene_tx) wire_scene_tx_free(&k->scene_tx);
    dsync_free(k->sync);
    free(k->pts);
    free(k);
}

static int send_msg(dsink *k, const wire_msg *m, ct_error *err)
{
    return dsrv_send(k->c.ds, m, k->c.send_timeout_ms, err);
}

/* Sends the hit points collected since the last call as one SAMPLES
 * message. They are only a debugging view (Fig. 7): when the display's send
 * queue already holds a quarter of its bound they are dropped and counted,
 * so they never block the loop or take room that texture updates need. */
static void flush_points(dsink *k)
{
    if (!k->npts || !dsrv_has_display(k->c.ds)) {
        k->npts = 0;
        return;
    }
    wire_msg m;
    memset(&m, 0, sizeof m);
    m.type = WIRE_SAMPLES;
    m.u.samples = (wire_samples){.epoch = k->disp_epoch, .count = k->npts, .dropped = k->pts_dropped, .xyz = k->pts};
    if (dsrv_try_send(k->c.ds, &m, k->c.queue_bytes / 4) == DSRV_DROPPED) {
        k->pts_dropped += k->npts;
        k->pts_dropped_total += k->npts;
    }
    k->npts = 0;
}

/* Remembers the hit points of inserted samples for the next SAMPLES. */
static void on_samples(void *user, const ct_sample *s, uint32_t n)
{
    dsink *k = user;
    if (!dsrv_has_display(k->c.ds)) return;
    if (!k->pts && !(k->pts = malloc(3 * sizeof *k->pts * WIRE_SAMPLES_MAX_POINTS)))
        return;   /* without memory the debugging view just shows nothing */
    for (uint32_t i = 0; i < n; i++) {
        if (!(s[i].flags & CT_SAMPLE_HIT)) continue;
        if (k->npts == WIRE_SAMPLES_MAX_POINTS) flush_points(k);
        float *p = k->pts + 3 * (size_t)k->npts++;
        p[0] = s[i].hit.x;
        p[1] = s[i].hit.y;
        p[2] = s[i].hit.z;
    }
}

/* The end of a lockstep frame: its points, every unsent tile, FRAME. */
static int on_frame(void *user, sess *s, const sink_frame *f, ct_error *err)
{
    dsink *k = user;
    flush_points(k);
    double t0 = ct_now();
    k->frame_patches = 0;
    int rc = dsync_flush_all(k->sync, k->c.ds, sess_textures(s), &k->frame_patches, err);
    k->t_encode += ct_now() - t0;
    if (rc) return rc;
    rq_stats rs;
    sess_queue_stats(s, &rs);
    sess_counters n = sess_get_counters(s);
    ct_debug(COMPONENT, "frame %llu: %u samples, %u patches; queue %llu, in flight %llu, coverage %.3f, stale %llu%s",
             (unsigned long long)k->frame_no, f->samples, k->frame_patches, (unsigned long long)rs.queued,
             (unsigned long long)rs.in_flight, rs.coverage, (unsigned long long)n.stale,
             k->orphan ? " (its display left)" : "");
    if (k->orphan) {
        k->orphan = false;
        return 0;
    }
    wire_msg m = {.type = WIRE_FRAME};
    m.u.frame = (wire_frame){k->frame_no, k->disp_epoch, n.all_positive ? WIRE_FLAG_ALL_POSITIVE : 0u, f->samples,
                             k->frame_patches};
    if ((rc = send_msg(k, &m, err))) return rc;
    k->frame_no++;
    return 0;
}

sink dsink_sink(dsink *k)
{
    return (sink){k, on_samples, on_frame};
}

int dsink_connected(dsink *k, sess *s, const wire_settings *set, ct_error *err)
{
    int rc;
    k->frame_no = 0;
    k->npts = 0;          /* points of an earlier display */
    k->pts_dropped = 0;
    char peer[CT_ERROR_LEN];
    snprintf(peer, sizeof peer, "%s", dsrv_peer(k->c.ds));   /* the display may leave meanwhile */
    if (!k->have_scene_tx) {
        /* The radiosity mesh with the texture hierarchy as its node table
         * (made once, content-hashed: a display keeps it cached). */
        ct_radmesh dm;
        if ((rc = ctex_display_mesh(sess_textures(s), k->c.mesh, &dm, err))) return rc;
        rc = wire_scene_tx_init(&k->scene_tx, &dm, err);
        ctex_display_mesh_free(&dm);
        if (rc) return rc;
        k->have_scene_tx = true;
    }
    /* First the view to start from, for a display without a camera of its
     * own: the current one, else the scene's first camera; it comes before
     * the scene so that the display has it when the scene is drawn. */
    wire_msg m = {.type = WIRE_CAMERA};
    if (sess_has_view(s) || k->c.scene->ncams) {
        if (sess_has_view(s)) {
            int w, h;
            sess_view(s, &m.u.camera.cam, &w, &h);
            m.u.camera.width = (uint32_t)w;
            m.u.camera.height = (uint32_t)h;
        } else {
            m.u.camera = (wire_camera){0, 1024, 1024, k->c.scene->cams[0].cam};
        }
        if ((rc = send_msg(k, &m, err))) return rc;
    }
    int cached = memcmp(set->cached_scene, k->scene_tx.hash, WIRE_HASH_SIZE) == 0;
    wire_scene_tx_begin(&k->scene_tx, cached, &m);
    if ((rc = send_msg(k, &m, err))) return rc;
    uint32_t nch = cached ? 0 : m.u.scene_begin.nchunks;
    for (uint32_t i = 0; i < nch && dsrv_has_display(k->c.ds); i++) {
        wire_scene_tx_chunk(&k->scene_tx, i, &m);
        if ((rc = send_msg(k, &m, err))) return rc;
    }
    wire_scene_tx_end(&k->scene_tx, &m);
    if ((rc = send_msg(k, &m, err))) return rc;
    uint32_t ntex = 0;
    if ((rc = dsync_send_state(k->sync, k->c.ds, sess_textures(s), &ntex, err))) return rc;
    ct_info(COMPONENT, "sent the scene (%s) and %u textures to %s", cached ? "cached on the display" : "full", ntex,
            peer);
    return 0;
}

void dsink_disconnected(dsink *k)
{
    dsync_stats st = dsync_get_stats(k->sync);
    ct_info(COMPONENT, "texels to displays so far: %llu patches, %.1f MB; %llu exact resizes the display computed "
            "(%.1f million texels, only their changed tiles sent), %llu sent whole (the display had them as 2 x 2 "
            "means)",
            (unsigned long long)st.patches, (double)st.texel_bytes / 1e6, (unsigned long long)st.resized,
            (double)st.resized_texels / 1e6, (unsigned long long)st.resized_whole);
    dsync_reset(k->sync);
}

void dsink_set_epoch(dsink *k, uint32_t display_epoch)
{
    flush_points(k);
    k->disp_epoch = display_epoch;
    dsync_set_epoch(k->sync, display_epoch);
}

int dsink_ack(dsink *k, uint64_t seq, ct_error *err)
{
    return dsync_ack(k->sync, seq, ct_now(), err);
}

void dsink_drop_stalled(dsink *k, double now)
{
    if (!dsrv_has_display(k->c.ds)) return;
    double stalled = dsync_stalled_s(k->sync, k->c.ds, now);
    if (stalled * 1000.0 <= (double)k->c.send_timeout_ms) return;
    /* Stopped, hung, or reading nothing: the slot is free for another. */
    char why[CT_ERROR_LEN];
    snprintf(why, sizeof why, "the display took nothing and acknowledged nothing for %.1f s (--send-timeout-ms)",
             stalled);
    dsrv_drop(k->c.ds, WIRE_ERR_LIMIT, why);
}

#define SILENT_MIN_MS 3000.0

void dsink_drop_silent(dsink *k, double now)
{
    double silent = dsrv_silent_s(k->c.ds, now);
    /* Never under 3 s: a display PINGs once a second, and a short
     * --send-timeout-ms (meant for stalls) would drop it between two. */
    if (silent * 1000.0 <= fmax((double)k->c.send_timeout_ms, SILENT_MIN_MS)) return;
    /* A stopped process or a host gone without a word (no FIN on TCP): the
     * socket takes what is sent for a long while yet, so nothing else
     * notices, and the slot would stay taken. */
    char why[CT_ERROR_LEN];
    snprintf(why, sizeof why, "the display sent nothing, not even its PING a second, for %.1f s (--send-timeout-ms, at least 3 s)",
             silent);
    dsrv_drop(k->c.ds, WIRE_ERR_LIMIT, why);
}

bool dsink_update_due(const dsink *k, double now)
{
    return dsync_due(k->sync, now);
}

int dsink_update(dsink *k, sess *s, ct_error *err)
{
    if (!dsync_can_send(k->sync)) return 0;
    flush_points(k);
    double t0 = ct_now();
    int rc = dsync_update(k->sync, k->c.ds, sess_textures(s), t0, ct_now_us(), err);
    k->t_encode += ct_now() - t0;
    return rc < 0 ? rc : 0;
}

void dsink_orphan_frame(dsink *k)
{
    k->orphan = true;
}

void dsink_stats(dsink *k, const wire_stats *st)
{
    if (!dsrv_has_display(k->c.ds)) return;
    wire_msg m = {.type = WIRE_STATS};
    m.u.stats = *st;
    m.u.stats.epoch = k->disp_epoch;
    ct_error e;
    send_msg(k, &m, &e);
}

uint64_t dsink_points_dropped(const dsink *k)
{
    return k->pts_dropped_total;
}

double dsink_take_encode_s(dsink *k)
{
    double t = k->t_encode;
    k->t_encode = 0;
    return t;
}

dsync_stats dsink_sync_stats(const dsink *k)
{
    return dsync_get_stats(k->sync);
}
