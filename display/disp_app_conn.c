/* disp_app_conn.c: the display program's connection to the master
 * (disp_app_internal.h): connecting and reconnecting with back-off, taking
 * what the connection thread received before each frame, sending the
 * camera, lockstep waits, and the lag of what was shown. */
#include "display/disp_app_internal.h"

#include <stdio.h>
#include <string.h>

#include "common/log.h"
#include "common/timer.h"

#define COMP "corrtex-display"

/* Reconnection back-off: 0.5 s doubling to 8 s. */
#define BACKOFF_FIRST 0.5
#define BACKOFF_MAX 8.0

int app_try_connect(app *a, ct_error *err)
{
    /* 3 s for connect + handshake: a master answers at once or not at all,
     * and a reconnecting display must not freeze for long. */
    disp_client_opts co = {a->o->connect, a->o->token_file, (uint32_t)a->o->samples_per_frame, 3000, 0};
    int rc = disp_client_connect(&co, a->cache, a->inbox, &a->client, err);
    if (rc) return rc;
    a->cam_sent = false;
    a->ever_connected = true;
    a->backoff = BACKOFF_FIRST;
    a->status[0] = '\0';
    return CT_OK;
}

/* The cause without the address in front (the transport names its peer,
 * and the line below names it already). */
static const char *without_addr(const char *msg, const char *addr)
{
    size_t n = strlen(addr);
    return strncmp(msg, addr, n) == 0 && msg[n] == ':' && msg[n + 1] == ' ' ? msg + n + 2 : msg;
}

/* The connection failed or was lost: with --reconnect schedule a retry and
 * keep showing the last image; else fail with DISP_EXIT_LOST. */
int app_connection_lost(app *a, ct_error *cause, double now, ct_error *err)
{
    disp_client_close(a->client);
    a->client = NULL;
    const char *why = without_addr(cause->msg, a->o->connect);
    snprintf(a->last_cause.msg, sizeof a->last_cause.msg, "%s", why);
    if (!a->o->reconnect) {
        ct_fail(err, CT_EIO, a->ever_connected ? "connection to %s lost: %s" : "cannot connect to %s: %s",
                a->o->connect, why);
        return DISP_EXIT_LOST;
    }
    if (a->backoff <= 0) a->backoff = BACKOFF_FIRST;
    a->retry_at = now + a->backoff;
    ct_warn(COMP, "%s %s: %s; retrying in %.1f s", a->ever_connected ? "connection lost to" : "cannot connect to",
            a->o->connect, why, a->backoff);
    snprintf(a->status, sizeof a->status, "CONNECTION LOST (%.60s), retrying", why);
    a->backoff = a->backoff * 2 > BACKOFF_MAX ? BACKOFF_MAX : a->backoff * 2;
    app_set_title(a, now, true);
    return CT_OK;
}

/* Checks the connection (its thread reads on its own) and reconnects when
 * due. Returns 0, 1 when the master ended the session, or DISP_EXIT_LOST
 * with err filled. */
static int service(app *a, ct_error *err)
{
    if (!a->o->connect) return CT_OK;
    double now = ct_now();
    ct_error e;
    ct_error_clear(&e);
    if (!a->client) {
        if (now < a->retry_at) return CT_OK;
        if (app_try_connect(a, &e)) return app_connection_lost(a, &e, now, err);
        ct_info(COMP, "reconnected to %s", a->o->connect);
        return CT_OK;
    }
    if (disp_client_status(a->client, &e)) {
        if (disp_client_ended(a->client)) {
            ct_info(COMP, "%s", e.msg);
            return 1;   /* orderly end */
        }
        return app_connection_lost(a, &e, now, err);
    }
    return CT_OK;
}

/* Moves what the connection thread received into the session: scene,
 * textures, changed texels (uploaded once each), points, statistics. */
static int take_inbox(app *a, ct_error *err)
{
    if (!a->inbox || a->hold_texels) return CT_OK;
    double t0 = ct_now();
    /* (an idle display takes its inbox every few ms: only takes that
     * upload something are timed on the GPU) */
    bool timed = a->gt && disp_inbox_pending(a->inbox);
    if (timed) disp_gpu_time_begin(a->gt, DISP_GT_TAKE);
    int rc = disp_inbox_apply(a->inbox, a->session, &a->took, err);
    if (timed) disp_gpu_time_end(a->gt);
    a->t_take += ct_now() - t0;
    a->uploads += a->took.uploads;
    a->uploaded += a->took.texels;
    return rc;
}

/* Takes the inbox even while texel redraws are held back: a frame drawn
 * for another reason (the camera moved) shows the newest texels. */
int app_take_inbox(app *a, ct_error *err)
{
    a->hold_texels = false;
    return take_inbox(a, err);
}

/* After a frame is presented: the lag of every sample its patches carried
 * (master clock of the patch's oldest change to now, on the master's clock). */
void app_count_lag(app *a)
{
    int64_t off;
    if (!a->lag || !a->client || !a->took.nstamps || !disp_client_clock_offset(a->client, &off)) return;
    /* (unsigned: the stamps and the offset come from the master and may be
     * anything; a signed overflow would be undefined) */
    uint64_t now = ct_now_us() + (uint64_t)off;
    for (uint32_t i = 0; i < a->took.nstamps; i++) {
        const disp_inbox_stamp *t = &a->took.stamps[i];
        disp_lag_add(a->lag, (double)(int64_t)(now - t->stamp_us) / 1000.0, t->samples);
    }
}


/* With --connect, before the camera of a frame is known: checks the
 * connection and takes what arrived. */
int app_connection_begin(app *a, ct_error *err)
{
    if (take_inbox(a, err)) return STEP_ERROR;
    int st = service(a, err);
    if (st == 0) return STEP_DRAW;
    /* What arrived before the connection ended (the thread has stopped:
     * nothing comes after this) is drawn too. */
    ct_error e;
    if (take_inbox(a, &e)) ct_warn(COMP, "%s", e.msg);
    return st == 1 ? STEP_END : STEP_LOST;
}

/* Then: sends the camera when it changed (cam NULL: the display has none
 * yet, it starts from the view the master suggests or an overview of the
 * scene once the scene is there), STEP_WAIT until there is a scene, and in
 * lockstep waits until the master's FRAME of the current epoch and all its
 * texels are in. With the next frame's camera known (next), lockstep asks
 * for that frame at once, before this one is drawn: the master computes it
 * while the display draws (the texels it sends wait in the inbox, which
 * this frame has already taken), so a frame costs the longer of the two,
 * not their sum. */
static int send_camera(app *a, const ct_camera *cam, ct_error *err)
{
    ct_error e;
    if (disp_client_send_camera(a->client, cam, a->o->width, a->o->height, &e))
        return app_connection_lost(a, &e, ct_now(), err) ? STEP_LOST : STEP_DRAW;
    a->cam_sent = true;
    a->last_cam = *cam;
    a->frame_taken = false;
    return STEP_DRAW;
}

int app_connection_step(app *a, const ct_camera *cam, const ct_camera *next, gl_input *in, double t_start,
                        ct_error *err)
{
    const disp_app_opts *o = a->o;
    int st;
    /* In lockstep every CAMERA asks for one frame, so a still camera sends
     * its (unchanged) camera again once the previous frame was drawn. */
    bool ask_frame = o->samples_per_frame > 0 && a->frame_taken;
    if (cam && a->client && (!a->cam_sent || ask_frame || !cam_same(cam, &a->last_cam)) &&
        send_camera(a, cam, err) == STEP_LOST)
        return STEP_LOST;
    if (!disp_session_scene_of(a->session)) {
        if (a->client) snprintf(a->status, sizeof a->status, "waiting for the scene from %s", o->connect);
        app_set_title(a, ct_now(), false);
        ct_sleep_us(5000);
        return STEP_WAIT;
    }
    if (!strncmp(a->status, "waiting", 7)) a->status[0] = '\0';
    /* Lockstep (docs/protocol.md): draw frame k only after FRAME k. */
    double w0 = ct_now(), take0 = a->t_take;
    while (a->client && o->samples_per_frame > 0 && !disp_inbox_frame_ready(a->inbox, NULL)) {
        st = service(a, err);
        if (st) return st == 1 ? STEP_END : STEP_LOST;
        if (!a->client) break;
        ct_sleep_us(1000);
        if (take_inbox(a, err)) return STEP_ERROR;
        gl_backend_poll(a->backend, in);
        if (!app_handle_keys(a, in)) return STEP_QUIT;
        if (o->max_seconds > 0 && ct_now() - t_start >= o->max_seconds) return STEP_QUIT;
        if (o->stop && *o->stop) return STEP_QUIT;   /* SIGINT, SIGTERM: a master that never sends FRAME */
    }
    a->t_wait += ct_now() - w0 - (a->t_take - take0);
    if (a->client) {
        disp_inbox_take_frame(a->inbox);
        a->frame_taken = true;
        if (o->samples_per_frame > 0 && next && send_camera(a, next, err) == STEP_LOST) return STEP_LOST;
    }
    return STEP_DRAW;
}
