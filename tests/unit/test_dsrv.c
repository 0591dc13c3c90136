/* test_dsrv.c: the master's display server (master/dsrv.h) with real
 * sockets: the UNIX socket's mode, TCP refused without a token, a legitimate
 * display's SETTINGS and CAMERA as events, PING answered, a second display
 * refused with ERROR BUSY, and hostile peers (garbage, an oversized length,
 * a wrong token, a silent peer) dropped while the legitimate display goes on
 * undisturbed, and idle connections that cannot take the handshake slots
 * from a display, nor a flood of HELLOs in every try; a burst of CAMERAs
 * right after SETTINGS keeps every event; a display's silence is measured;
 * PINGs of a display that reads nothing do not fill the send queue; CAMERA
 * epochs that do not increase (by one in lockstep) drop the display. The
 * server runs in its own thread, as in the master's loop. Over 600 lines:
 * every case shares the threaded server and display helpers above. */
#include <arpa/inet.h>
#include <criterion/criterion.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common/timer.h"
#include "master/dsrv.h"
#include "proto/chan.h"
#include "proto/xport.h"

typedef struct server {
    dsrv *s;
    pthread_t th;
    pthread_mutex_t mu;
    volatile int stop;
    volatile int hold;   /* events stay queued in the server (dsrv_view_pending) */
    dsrv_event ev[64];
    int nev;
} server;

static void *serve(void *arg)
{
    server *sv = arg;
    while (!sv->stop) {
        ct_error err;
        pthread_mutex_lock(&sv->mu);
        dsrv_step(sv->s, sv->hold ? 0 : 5, &err);
        dsrv_event e;
        while (!sv->hold && dsrv_next_event(sv->s, &e))
            if (sv->nev < 64) sv->ev[sv->nev++] = e;
        pthread_mutex_unlock(&sv->mu);
        if (sv->hold) usleep(1000);
    }
    return NULL;
}

static void start_queue(server *sv, const char *listen, const auth_token *tok, int handshake_ms, size_t queue_bytes)
{
    memset(sv, 0, sizeof *sv);
    dsrv_config c = {.listen = listen, .token = tok, .handshake_timeout_ms = handshake_ms, .queue_bytes = queue_bytes};
    ct_error err = {{0}};
    cr_assert_eq(dsrv_new(&c, &sv->s, &err), 0, "%s", err.msg);
    pthread_mutex_init(&sv->mu, NULL);
    cr_assert_eq(pthread_create(&sv->th, NULL, serve, sv), 0);
}

static void start(server *sv, const char *listen, const auth_token *tok, int handshake_ms)
{
    start_queue(sv, listen, tok, handshake_ms, 0);
}

static void stop(server *sv)
{
    sv->stop = 1;
    pthread_join(sv->th, NULL);
    dsrv_free(sv->s);
    pthread_mutex_destroy(&sv->mu);
}

/* Waits up to 3 s for the n-th event (0-based) and returns its kind. */
static int wait_event(server *sv, int n, dsrv_event *out)
{
    double end = ct_now() + 3.0;
    while (ct_now() < end) {
        pthread_mutex_lock(&sv->mu);
        int have = sv->nev > n;
        if (have && out) *out = sv->ev[n];
        pthread_mutex_unlock(&sv->mu);
        if (have) return (int)out->kind;
        usleep(2000);
    }
    return 0;
}

static void sock_spec(char *out, size_t cap, const char *tag)
{
    snprintf(out, cap, "unix:/tmp/ct-dsrv-%s-%d.sock", tag, (int)getpid());
}

static chan *display(const char *spec, const auth_token *tok, uint32_t k)
{
    chan_config cc = {.role = AUTH_ROLE_DISPLAY, .token = tok};
    chan *c = NULL;
    ct_error err = {{0}};
    cr_assert_eq(chan_connect(spec, &cc, 3000, &c, &err), 0, "%s", err.msg);
    wire_msg m = {.type = WIRE_SETTINGS};
    m.u.settings.samples_per_frame = k;
    cr_assert_eq(chan_send(c, &m, &err), 0, "%s", err.msg);
    cr_assert_eq(chan_flush(c, 2000, &err), 0, "%s", err.msg);
    return c;
}

static void send_camera(chan *c, uint32_t epoch)
{
    wire_msg m = {.type = WIRE_CAMERA};
    m.u.camera.epoch = epoch;
    m.u.camera.width = 64;
    m.u.camera.height = 48;
    m.u.camera.cam = cam_look_at(v3(0, 0, 5), v3(0, 0, 0), v3(0, 1, 0), 45.0f);
    ct_error err = {{0}};
    cr_assert_eq(chan_send(c, &m, &err), 0, "%s", err.msg);
    cr_assert_eq(chan_flush(c, 2000, &err), 0, "%s", err.msg);
}

/* A PING must come back as PONG with the same token: the display is served. */
static void ping_pong(chan *c, uint64_t token)
{
    wire_msg m = {.type = WIRE_PING};
    m.u.ping.token = token;
    ct_error err = {{0}};
    cr_assert_eq(chan_send(c, &m, &err), 0, "%s", err.msg);
    cr_assert_eq(chan_flush(c, 2000, &err), 0, "%s", err.msg);
    wire_msg r;
    cr_assert_eq(chan_recv_wait(c, &r, 3000, &err), WIRE_OK, "%s", err.msg);
    cr_assert_eq(r.type, WIRE_PONG, "got %s", wire_type_name(r.type));
    cr_assert_eq(r.u.ping.token, token);
}

/* Reads from a raw connection until EOF (1) or 3 s pass (0). */
static int closed_by_peer(xport_conn *x)
{
    double end = ct_now() + 3.0;
    uint8_t buf[4096];
    while (ct_now() < end) {
        size_t got = 0;
        ct_error err;
        int rc = xport_read(x, buf, sizeof buf, &got, &err);
        if (rc == XPORT_EOF || rc < 0) return 1;
        if (got == 0) xport_wait(x, POLLIN, 50, &err);
    }
    return 0;
}

static void token(auth_token *t, char fill)
{
    memset(t, 0, sizeof *t);
    memset(t->bytes, fill, 32);
    t->len = 32;
}

/* A server on a fresh socket (tag names it, spec receives it) and one
 * display asking for k samples per frame, after the server has reported the
 * connection (*e). */
static chan *connected_display(server *sv, char *spec, size_t cap, const char *tag, uint32_t k, dsrv_event *e)
{
    sock_spec(spec, cap, tag);
    start(sv, spec, NULL, 2000);
    chan *d = display(spec, NULL, k);
    cr_assert_eq(wait_event(sv, 0, e), DSRV_EV_CONNECTED);
    return d;
}

/* What may change the view is pending while a camera is queued, not while
 * only acknowledgements are (the master pops a tracer's next batch ahead
 * only then: master/drive.h). */
Test(dsrv, view_pending_for_a_camera_not_for_an_ack)
{
    char spec[128];
    server sv;
    dsrv_event e;
    chan *d = connected_display(&sv, spec, sizeof spec, "pending", 0, &e);
    sv.hold = 1;
    wire_msg m = {.type = WIRE_ACK};
    m.u.ack.seq = 0;
    ct_error err = {{0}};
    cr_assert_eq(chan_send(d, &m, &err), 0, "%s", err.msg);
    ping_pong(d, 7);   /* answered after the ACK was taken */
    pthread_mutex_lock(&sv.mu);
    bool pending = dsrv_view_pending(sv.s);
    pthread_mutex_unlock(&sv.mu);
    cr_assert_not(pending, "an ACK alone counted as a view change");
    send_camera(d, 1);
    double end = ct_now() + 3.0;
    while (!pending && ct_now() < end) {
        pthread_mutex_lock(&sv.mu);
        pending = dsrv_view_pending(sv.s);
        pthread_mutex_unlock(&sv.mu);
        usleep(1000);
    }
    cr_assert(pending, "a queued CAMERA is not pending");
    sv.hold = 0;
    cr_assert_eq(wait_event(&sv, 2, &e), DSRV_EV_MESSAGE);
    cr_assert_eq(e.msg.type, WIRE_CAMERA, "got %s", wire_type_name(e.msg.type));
    pthread_mutex_lock(&sv.mu);
    cr_assert_not(dsrv_view_pending(sv.s));
    pthread_mutex_unlock(&sv.mu);
    chan_free(d);
    stop(&sv);
}

Test(dsrv, unix_socket_mode_and_default_address)
{
    char spec[128];
    sock_spec(spec, sizeof spec, "mode");
    server sv;
    start(&sv, spec, NULL, 1000);
    struct stat st;
    cr_assert_eq(stat(spec + 5, &st), 0);
    cr_assert_eq(st.st_mode & 0777, 0600, "mode %o", st.st_mode & 0777);
    stop(&sv);
    cr_assert_neq(access(spec + 5, F_OK), 0, "the socket file is removed");
    char def[300];
    dsrv_default_listen(def, sizeof def);
    cr_assert(strncmp(def, "unix:", 5) == 0 && strstr(def, "corrtex-"), "%s", def);
}

Test(dsrv, tcp_needs_a_token)
{
    dsrv_config c = {.listen = "tcp:127.0.0.1:0", .token = NULL, .handshake_timeout_ms = 1000};
    dsrv *s = NULL;
    ct_error err = {{0}};
    cr_assert_eq(dsrv_new(&c, &s, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "TCP needs a token"), "%s", err.msg);
}

/* A UNIX address the socket cannot take is refused by the check the
 * master runs before its solve and the tracers' start: a folder that does
 * not exist, a path that is a file. */
Test(dsrv, unix_addresses_checked_before_the_job)
{
    ct_error err = {{0}};
    dsrv_config c = {.listen = "unix:/nonexistent-dir/x.sock"};
    cr_assert_eq(dsrv_check_config(&c, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "cannot create the socket in /nonexistent-dir"), "%s", err.msg);
    char path[] = "/tmp/ct-dsrv-file-XXXXXX";
    int fd = mkstemp(path);
    cr_assert_geq(fd, 0);
    close(fd);
    char spec[128];
    snprintf(spec, sizeof spec, "unix:%s", path);
    c.listen = spec;
    cr_assert_eq(dsrv_check_config(&c, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "exists and is not a socket"), "%s", err.msg);
    unlink(path);
    c.listen = spec;   /* gone: fine */
    cr_assert_eq(dsrv_check_config(&c, &err), 0, "%s", err.msg);
}

Test(dsrv, display_events_ping_and_busy)
{
    char spec[128];
    server sv;
    dsrv_event e;
    chan *d = connected_display(&sv, spec, sizeof spec, "busy", 7, &e);
    cr_assert_eq(e.msg.u.settings.samples_per_frame, 7u);
    send_camera(d, 1);
    cr_assert_eq(wait_event(&sv, 1, &e), DSRV_EV_MESSAGE);
    cr_assert_eq(e.msg.type, WIRE_CAMERA);
    cr_assert_eq(e.msg.u.camera.width, 64u);
    ping_pong(d, 42);

    /* A second display is told why it is refused. */
    chan_config cc = {.role = AUTH_ROLE_DISPLAY};
    chan *d2 = NULL;
    ct_error err = {{0}};
    cr_assert_eq(chan_connect(spec, &cc, 3000, &d2, &err), 0, "%s", err.msg);
    wire_msg r;
    cr_assert_eq(chan_recv_wait(d2, &r, 3000, &err), WIRE_OK, "%s", err.msg);
    cr_assert_eq(r.type, WIRE_ERROR);
    cr_assert_eq(r.u.error.code, (uint32_t)WIRE_ERR_BUSY);
    cr_assert(strstr(r.u.error.text, "already serves a display"), "%s", r.u.error.text);
    chan_free(d2);
    ping_pong(d, 43);

    /* The display leaves; the next one is served. */
    chan_free(d);
    cr_assert_eq(wait_event(&sv, 2, &e), DSRV_EV_DISCONNECTED);
    chan *d3 = display(spec, NULL, 0);
    cr_assert_eq(wait_event(&sv, 3, &e), DSRV_EV_CONNECTED);
    ping_pong(d3, 44);
    chan_free(d3);
    stop(&sv);
}

/* dsrv_silent_s: seconds since the display's last byte, as the master's
 * calls see them (a display PINGs once a second; the master drops one
 * silent for --send-timeout-ms, master/dsink.c). */
static double silent_s(server *sv)
{
    pthread_mutex_lock(&sv->mu);
    double s = dsrv_silent_s(sv->s, ct_now());
    pthread_mutex_unlock(&sv->mu);
    return s;
}

Test(dsrv, silence_is_measured_from_the_last_byte)
{
    char spec[128];
    server sv;
    dsrv_event e;
    chan *d = connected_display(&sv, spec, sizeof spec, "silent", 5, &e);
    cr_expect_lt(silent_s(&sv), 0.5);
    double t0 = ct_now(), s = 0.0;
    while (ct_now() - t0 < 1.5) {
        s = silent_s(&sv);
        usleep(100000);
    }
    cr_expect_geq(s, 1.2, "silent for %.2f s after 1.5 s without a byte", s);
    ping_pong(d, 5);
    cr_expect_lt(silent_s(&sv), 0.3, "a PING did not end the silence");

    /* A master that did not look for over a second cannot tell: it starts
     * counting again. */
    usleep(1300000);
    cr_expect_lt(silent_s(&sv), 0.1);
    chan_free(d);
    cr_assert_eq(wait_event(&sv, 1, &e), DSRV_EV_DISCONNECTED);
    cr_expect_eq(silent_s(&sv), 0.0, "no display, no silence");
    stop(&sv);
}

Test(dsrv, hostile_peers_next_to_a_display)
{
    char spec[128];
    sock_spec(spec, sizeof spec, "hostile");
    auth_token good, bad;
    token(&good, 'g');
    token(&bad, 'b');
    server sv;
    start(&sv, spec, &good, 400);
    chan *d = display(spec, &good, 0);
    dsrv_event e;
    cr_assert_eq(wait_event(&sv, 0, &e), DSRV_EV_CONNECTED);
    ct_error err = {{0}};

    /* Garbage instead of a HELLO. */
    xport_conn *g = NULL;
    cr_assert_eq(xport_connect(spec, 1000, &g, &err), 0, "%s", err.msg);
    const char junk[] = "GET / HTTP/1.1\r\nHost: x\r\n\r\n";
    cr_assert_eq(xport_write_all(g, junk, sizeof junk - 1, 1000, &err), 0);
    cr_assert(closed_by_peer(g), "garbage peer not dropped");
    xport_close(g);
    ping_pong(d, 1);

    /* A wrong token. */
    chan_config cc = {.role = AUTH_ROLE_DISPLAY, .token = &bad};
    chan *w = NULL;
    int rc = chan_connect(spec, &cc, 3000, &w, &err);
    cr_assert_lt(rc, 0, "a wrong token was accepted");
    ping_pong(d, 2);

    /* A silent peer (or a very slow writer): dropped at the deadline. */
    xport_conn *q = NULL;
    cr_assert_eq(xport_connect(spec, 1000, &q, &err), 0, "%s", err.msg);
    double t0 = ct_now();
    cr_assert(closed_by_peer(q), "silent peer not dropped");
    cr_assert_lt(ct_now() - t0, 2.5);
    xport_close(q);
    ping_pong(d, 3);

    /* An oversized length: a HELLO dribbled byte by byte, then a frame
     * header announcing 2 GiB. The handshake fails first (the master wants
     * AUTH); either way the peer is dropped without reading 2 GiB. */
    xport_conn *o = NULL;
    cr_assert_eq(xport_connect(spec, 1000, &o, &err), 0, "%s", err.msg);
    uint8_t hello[AUTH_HELLO_SIZE], nonce[AUTH_NONCE_SIZE] = {1};
    auth_hello_encode(hello, AUTH_ROLE_DISPLAY, 0, CT_BUILD_ID, nonce);
    for (size_t i = 0; i < sizeof hello; i++) {
        cr_assert_eq(xport_write_all(o, hello + i, 1, 1000, &err), 0);
        usleep(1000);
    }
    uint8_t huge[8] = {WIRE_CAMERA, 0, 0, 0, 0xff, 0xff, 0xff, 0x7f};
    xport_write_all(o, huge, sizeof huge, 1000, &err);
    cr_assert(closed_by_peer(o), "oversized peer not dropped");
    xport_close(o);
    ping_pong(d, 4);

    /* The display never noticed: its camera still arrives as the next event. */
    send_camera(d, 1);
    int n = 1;
    for (; n < 64; n++) {
        int k = wait_event(&sv, n, &e);
        cr_assert_neq(k, 0, "no camera event");
        if (k == DSRV_EV_MESSAGE) break;
        cr_assert_neq(k, DSRV_EV_DISCONNECTED, "the display was disconnected: %s", e.text);
    }
    cr_assert_eq(e.msg.type, WIRE_CAMERA);
    chan_free(d);
    stop(&sv);
}

/* Sends CAMERAs with the given epochs; returns how many came out as
 * events before the display was dropped (n when it was not), with the
 * ERROR the display was told in *text. */
static int cameras_until_dropped(uint32_t k, const char *tag, const uint32_t *epochs, int n, char *text, size_t cap)
{
    char spec[128];
    server sv;
    dsrv_event e;
    chan *d = connected_display(&sv, spec, sizeof spec, tag, k, &e);
    for (int i = 0; i < n; i++) send_camera(d, epochs[i]);
    int taken = 0;
    text[0] = 0;
    for (int i = 1; i <= n; i++) {
        int kind = wait_event(&sv, i, &e);
        cr_assert_neq(kind, 0, "%s: no event %d", tag, i);
        if (kind == DSRV_EV_DISCONNECTED) {
            wire_msg r;
            ct_error err = {{0}};
            cr_assert_eq(chan_recv_wait(d, &r, 3000, &err), WIRE_OK, "%s: %s", tag, err.msg);
            cr_assert_eq(r.type, WIRE_ERROR, "%s: got %s", tag, wire_type_name(r.type));
            cr_assert_eq(r.u.error.code, (uint32_t)WIRE_ERR_PROTOCOL);
            snprintf(text, cap, "%s", r.u.error.text);
            cr_assert_str_eq(e.text, text);
            break;
        }
        cr_assert_eq(e.msg.type, WIRE_CAMERA);
        cr_assert_eq(e.msg.u.camera.epoch, epochs[i - 1]);
        taken++;
    }
    chan_free(d);
    stop(&sv);
    return taken;
}

Test(dsrv, camera_epochs_must_increase)
{
    char text[CT_ERROR_LEN];
    /* Free running: skips are fine (a replaced camera), and so is the wrap. */
    const uint32_t skips[] = {0xfffffffdu, 0xffffffffu, 2, 5, 6};
    cr_assert_eq(cameras_until_dropped(0, "ep-skip", skips, 5, text, sizeof text), 5, "dropped: %s", text);
    const uint32_t again[] = {1, 2, 2};
    cr_assert_eq(cameras_until_dropped(0, "ep-again", again, 3, text, sizeof text), 2);
    cr_assert(strstr(text, "CAMERA epoch 2 after epoch 2: epochs must increase"), "%s", text);
    const uint32_t back[] = {7, 3};
    cr_assert_eq(cameras_until_dropped(0, "ep-back", back, 2, text, sizeof text), 1);
    cr_assert(strstr(text, "CAMERA epoch 3 after epoch 7"), "%s", text);
    /* Lockstep: every camera asks for a frame, so none may be skipped. */
    const uint32_t step[] = {4, 5, 6};
    cr_assert_eq(cameras_until_dropped(2, "ep-lock", step, 3, text, sizeof text), 3, "dropped: %s", text);
    const uint32_t skip[] = {1, 2, 4};
    cr_assert_eq(cameras_until_dropped(2, "ep-lskip", skip, 3, text, sizeof text), 2);
    cr_assert(strstr(text, "CAMERA epoch 4 after epoch 2: epochs must increase by one in lockstep"), "%s", text);
}

Test(dsrv, oversized_frame_from_an_authenticated_display)
{
    char spec[128];
    server sv;
    dsrv_event e;
    chan *d = connected_display(&sv, spec, sizeof spec, "oversize", 0, &e);
    uint8_t huge[8] = {WIRE_CAMERA, 0, 0, 0, 0xff, 0xff, 0xff, 0x7f};
    ct_error err = {{0}};
    cr_assert_eq(xport_write_all(chan_conn(d), huge, sizeof huge, 1000, &err), 0);
    cr_assert_eq(wait_event(&sv, 1, &e), DSRV_EV_DISCONNECTED);
    cr_assert(strstr(e.text, "body length 2147483647"), "%s", e.text);
    chan_free(d);
    stop(&sv);
}

/* SAMPLES are droppable: dsrv_try_send queues them only while the display's
 * send queue holds at most the given bytes, never blocks, and the messages it
 * did queue arrive intact, in order with the others. */
Test(dsrv, droppable_samples_under_back_pressure)
{
    char spec[128];
    server sv;
    dsrv_event e;
    chan *d = connected_display(&sv, spec, sizeof spec, "drop", 0, &e);
    /* From here on one thread drives both sides. */
    sv.stop = 1;
    pthread_join(sv.th, NULL);
    static float pts[3 * WIRE_SAMPLES_MAX_POINTS];
    for (size_t i = 0; i < sizeof pts / sizeof pts[0]; i++) pts[i] = (float)i;
    wire_msg m = {.type = WIRE_SAMPLES};
    m.u.samples = (wire_samples){.epoch = 3, .count = WIRE_SAMPLES_MAX_POINTS, .xyz = pts};
    size_t limit = 1u << 20;   /* one message of 786 KB fits under it, two do not */
    double t0 = ct_now();
    cr_expect_eq(dsrv_try_send(sv.s, &m, limit), 0);
    m.u.samples.dropped = 1;
    cr_expect_eq(dsrv_try_send(sv.s, &m, limit), 0);
    cr_expect_eq(dsrv_try_send(sv.s, &m, limit), DSRV_DROPPED, "a third SAMPLES was queued");
    cr_expect_lt(ct_now() - t0, 0.5, "dsrv_try_send blocked");
    wire_msg f = {.type = WIRE_TEX_FREE};
    f.u.tex_free.tex = 9;
    ct_error err = {{0}};
    cr_assert_eq(dsrv_send(sv.s, &f, 2000, &err), 0);
    cr_assert(dsrv_has_display(sv.s));
    /* Both queued SAMPLES and the TEX_FREE arrive, in order. */
    int got = 0;
    double end = ct_now() + 5.0;
    while (got < 3 && ct_now() < end) {
        dsrv_step(sv.s, 1, &err);
        cr_assert_eq(chan_pump(d, &err), 0, "%s", err.msg);
        wire_msg r;
        int rc;
        while ((rc = chan_recv(d, &r, &err)) == WIRE_OK) {
            if (got < 2) {
                cr_assert_eq(r.type, WIRE_SAMPLES, "message %d is %s", got, wire_type_name(r.type));
                cr_expect_eq(r.u.samples.count, WIRE_SAMPLES_MAX_POINTS);
                cr_expect_eq(r.u.samples.dropped, (uint64_t)got);
                cr_expect(memcmp(r.u.samples.xyz, pts, sizeof pts) == 0, "points differ");
            } else {
                cr_assert_eq(r.type, WIRE_TEX_FREE);
            }
            got++;
        }
        cr_assert_eq(rc, WIRE_NEED_MORE, "%s", err.msg);
    }
    cr_expect_eq(got, 3, "%d messages arrived", got);
    chan_free(d);
    dsrv_free(sv.s);
    pthread_mutex_destroy(&sv.mu);
}

/* SETTINGS and 100 CAMERAs in one write, while the master takes no events:
 * the server stops reading the display before its event ring (64) is
 * full, so the display's CONNECTED and every CAMERA arrive, in order (the
 * ring used to drop its oldest event: the CONNECTED, and the display never
 * got the scene). */
Test(dsrv, a_burst_after_settings_keeps_every_event)
{
    char spec[128];
    server sv;
    sock_spec(spec, sizeof spec, "burst");
    start(&sv, spec, NULL, 2000);
    sv.hold = 1;
    chan_config cc = {.role = AUTH_ROLE_DISPLAY};
    chan *d = NULL;
    ct_error err = {{0}};
    cr_assert_eq(chan_connect(spec, &cc, 3000, &d, &err), 0, "%s", err.msg);
    wire_msg m = {.type = WIRE_SETTINGS};
    cr_assert_eq(chan_send(d, &m, &err), 0);
    for (uint32_t i = 1; i <= 100; i++) {
        wire_msg c = {.type = WIRE_CAMERA};
        c.u.camera = (wire_camera){i, 64, 48, cam_look_at(v3(0, 0, 5), v3(0, 0, 0), v3(0, 1, 0), 45.0f)};
        cr_assert_eq(chan_send(d, &c, &err), 0);
    }
    cr_assert_eq(chan_flush(d, 2000, &err), 0, "%s", err.msg);
    usleep(300000);   /* the held server reads what it may */
    sv.stop = 1;
    pthread_join(sv.th, NULL);
    int connected = 0, cameras = 0;
    double end = ct_now() + 3.0;
    while (cameras < 100 && ct_now() < end) {
        dsrv_step(sv.s, 5, &err);
        dsrv_event e;
        while (dsrv_next_event(sv.s, &e)) {
            if (e.kind == DSRV_EV_CONNECTED) {
                cr_assert_eq(cameras, 0, "CONNECTED after a CAMERA");
                connected++;
                continue;
            }
            cr_assert_eq(e.kind, DSRV_EV_MESSAGE);
            cr_assert_eq(e.msg.type, WIRE_CAMERA);
            cr_assert_eq(e.msg.u.camera.epoch, (uint32_t)cameras + 1, "camera %u after %d", e.msg.u.camera.epoch,
                         cameras);
            cameras++;
        }
    }
    cr_expect_eq(connected, 1, "the display's CONNECTED event was lost");
    cr_expect_eq(cameras, 100, "%d of 100 cameras arrived", cameras);
    chan_free(d);
    dsrv_free(sv.s);
    pthread_mutex_destroy(&sv.mu);
}

/* A display that sends PINGs and reads nothing: the server answers none
 * behind a quarter of its queue's bound, so the queue does not fill and a
 * control message after them is queued at once (the PONGs used to fill it,
 * and the next STATS waited --send-timeout-ms for room, the master's whole
 * loop with it). */
Test(dsrv, pings_of_a_display_that_reads_nothing_do_not_fill_the_queue)
{
    char spec[128];
    server sv;
    sock_spec(spec, sizeof spec, "pings");
    const size_t bound = 64u << 10;
    start_queue(&sv, spec, NULL, 2000, bound);
    chan *d = display(spec, NULL, 0);
    dsrv_event e;
    cr_assert_eq(wait_event(&sv, 0, &e), DSRV_EV_CONNECTED);
    sv.stop = 1;
    pthread_join(sv.th, NULL);
    /* 20,000 PINGs (320 KB; their PONGs would be 480 KB), written raw:
     * the chan would read while it flushes */
    wire_buf b = {0};
    ct_error err = {{0}};
    for (uint64_t i = 0; i < 20000; i++) {
        wire_msg p = {.type = WIRE_PING};
        p.u.ping.token = i;
        cr_assert_eq(wire_encode(&p, &b, &err), 0);
    }
    size_t off = 0, most = 0;
    double end = ct_now() + 10.0;
    while (off < b.len && ct_now() < end) {
        ssize_t k = write(chan_fd(d), b.data + off, b.len - off);
        if (k > 0) off += (size_t)k;
        dsrv_step(sv.s, 1, &err);
        dsrv_event ev;
        while (dsrv_next_event(sv.s, &ev)) {
        }
        size_t q = dsrv_queued(sv.s);
        if (q > most) most = q;
    }
    cr_assert_eq(off, b.len, "the server stopped reading the PINGs");
    for (int i = 0; i < 50; i++) dsrv_step(sv.s, 1, &err);
    cr_expect_leq(most, bound / 4 + 24, "%zu bytes queued (bound %zu)", most, bound);
    wire_msg f = {.type = WIRE_TEX_FREE};
    double t0 = ct_now();
    cr_assert_eq(dsrv_send(sv.s, &f, 2000, &err), 0);
    cr_expect_lt(ct_now() - t0, 0.1, "a control message waited %.2f s for room", ct_now() - t0);
    cr_expect(dsrv_has_display(sv.s));
    wire_buf_free(&b);
    chan_free(d);
    dsrv_free(sv.s);
    pthread_mutex_destroy(&sv.mu);
}

/* A server on a free TCP port of 127.0.0.1 with token tok; returns the port. */
static int start_tcp(server *sv, const auth_token *tok)
{
    start(sv, "tcp:127.0.0.1:0", tok, 5000);
    return atoi(strrchr(dsrv_addr(sv->s), ':') + 1);
}

/* An idle TCP connection from source address 127.0.0.<host> to port. */
static int idle_peer(int host, int port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    cr_assert_geq(fd, 0);
    struct sockaddr_in a = {.sin_family = AF_INET};
    a.sin_addr.s_addr = htonl(0x7f000000u | (uint32_t)host);
    cr_assert_eq(bind(fd, (struct sockaddr *)&a, sizeof a), 0, "bind 127.0.0.%d: %s", host, strerror(errno));
    a.sin_addr.s_addr = htonl(0x7f000001u);
    a.sin_port = htons((uint16_t)port);
    cr_assert_eq(connect(fd, (struct sockaddr *)&a, sizeof a), 0, "%s", strerror(errno));
    return fd;
}

/* Whether the server closed fd within ms (its HELLO is read and skipped). */
static int dropped_within(int fd, int ms)
{
    double end = ct_now() + ms / 1000.0;
    char buf[256];
    while (ct_now() < end) {
        struct pollfd p = {.fd = fd, .events = POLLIN};
        if (poll(&p, 1, 20) > 0 && read(fd, buf, sizeof buf) <= 0) return 1;
    }
    return 0;
}

/* Idle connections used to hold every handshake slot (16, each for the
 * handshake timeout) and a client re-opening them locked displays out. Now
 * one address holds at most 4, a newcomer from it replaces its oldest idle
 * one, a full table gives way to the newcomer the same way, and an
 * authenticated display always gets in. */
Test(dsrv, idle_handshakes_never_lock_a_display_out)
{
    auth_token tok;
    token(&tok, 't');
    server sv;
    int port = start_tcp(&sv, &tok);
    const char *addr = dsrv_addr(sv.s);
    int idle[4][DSRV_MAX_PENDING_PER_PEER];
    for (int h = 0; h < 4; h++)
        for (int k = 0; k < DSRV_MAX_PENDING_PER_PEER; k++) {
            idle[h][k] = idle_peer(2 + h, port);
            usleep(5000);   /* distinct ages */
        }
    cr_assert(!dropped_within(idle[0][0], 200), "a connection within the bounds was dropped");

    /* A fifth from 127.0.0.2 takes the place of that address's oldest. */
    int fifth = idle_peer(2, port);
    cr_assert(dropped_within(idle[0][0], 1000), "the oldest of 127.0.0.2 was kept");
    cr_assert(!dropped_within(idle[1][0], 200), "another address's connection was dropped");

    /* The table is full of idle connections: a display still gets in. */
    chan *d = display(addr, &tok, 0);
    dsrv_event e;
    cr_assert_eq(wait_event(&sv, 0, &e), DSRV_EV_CONNECTED, "the display was locked out");
    ping_pong(d, 7);
    cr_assert(dropped_within(idle[0][1], 1000), "the oldest idle connection was kept for the display");
    cr_assert(!dropped_within(idle[1][0], 200), "a younger idle connection was dropped");
    chan_free(d);
    close(fifth);
    for (int h = 0; h < 4; h++)
        for (int k = 0; k < DSRV_MAX_PENDING_PER_PEER; k++) close(idle[h][k]);
    stop(&sv);
}

/* The HELLO a display with token tok sends first: captured from a chan
 * connected to a plain listening socket. */
static size_t display_hello(const auth_token *tok, uint8_t *out, size_t cap)
{
    int ls = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET};
    a.sin_addr.s_addr = htonl(0x7f000001u);
    socklen_t al = sizeof a;
    cr_assert_eq(bind(ls, (struct sockaddr *)&a, sizeof a), 0);
    cr_assert_eq(listen(ls, 1), 0);
    cr_assert_eq(getsockname(ls, (struct sockaddr *)&a, &al), 0);
    char spec[64];
    snprintf(spec, sizeof spec, "tcp:127.0.0.1:%d", ntohs(a.sin_port));
    xport_conn *x = NULL;
    ct_error err = {{0}};
    cr_assert_eq(xport_connect(spec, 2000, &x, &err), 0, "%s", err.msg);
    chan_config cc = {.role = AUTH_ROLE_DISPLAY, .token = tok};
    chan *c = NULL;
    cr_assert_eq(chan_new(x, &cc, &c, &err), 0, "%s", err.msg);
    chan_pump(c, &err);
    int fd = accept(ls, NULL, NULL);
    cr_assert_geq(fd, 0);
    struct pollfd p = {.fd = fd, .events = POLLIN};
    cr_assert_gt(poll(&p, 1, 2000), 0, "no HELLO");
    ssize_t n = read(fd, out, cap);
    cr_assert_gt(n, 0);
    close(fd);
    close(ls);
    chan_free(c);
    return (size_t)n;
}

/* Connections that send a display's HELLO and then wait look like displays
 * waiting for their AUTH's round trip. The server used to replace the
 * oldest of them, so a flood that came after the real display always took
 * its place before its AUTH arrived; now it replaces one at random, and the
 * display gets in within a few tries (in each try below 20 newcomers arrive
 * during its round trip: the oldest rule dropped it in every try, at random
 * it stays with a chance of (15/16)^20 = 0.27 a try). */
Test(dsrv, a_hello_flood_does_not_always_take_the_display_s_place, .timeout = 60)
{
    auth_token tok;
    token(&tok, 'h');
    uint8_t hello[256];
    size_t nh = display_hello(&tok, hello, sizeof hello);
    server sv;
    int port = start_tcp(&sv, &tok);
    const char *addr = dsrv_addr(sv.s);
    int served = 0, tries = 30;
    for (int t = 0; t < tries; t++) {
        int fds[36], nf = 0;
        for (int h = 0; h < 4; h++)
            for (int k = 0; k < DSRV_MAX_PENDING_PER_PEER; k++) {
                fds[nf] = idle_peer(2 + h, port);
                cr_assert_eq(write(fds[nf], hello, nh), (ssize_t)nh);
                nf++;
            }
        usleep(20000);
        /* The display: its HELLO, then (its round trip) the flood, then the rest. */
        xport_conn *x = NULL;
        ct_error err = {{0}};
        cr_assert_eq(xport_connect(addr, 2000, &x, &err), 0, "%s", err.msg);
        chan_config cc = {.role = AUTH_ROLE_DISPLAY, .token = &tok};
        chan *d = NULL;
        cr_assert_eq(chan_new(x, &cc, &d, &err), 0, "%s", err.msg);
        chan_pump(d, &err);
        usleep(20000);
        for (int h = 0; h < 5; h++)
            for (int k = 0; k < DSRV_MAX_PENDING_PER_PEER; k++) {
                fds[nf] = idle_peer(6 + h, port);
                if (write(fds[nf], hello, nh) != (ssize_t)nh) {
                }
                nf++;
                usleep(1000);
            }
        usleep(20000);
        if (chan_handshake(d, 2000, &err) == 0) {
            wire_msg m = {.type = WIRE_SETTINGS};
            if (chan_send(d, &m, &err) == 0 && chan_flush(d, 2000, &err) == 0) {
                dsrv_event e;
                if (wait_event(&sv, 2 * served, &e) == DSRV_EV_CONNECTED) served++;
            }
        }
        chan_free(d);
        for (int i = 0; i < nf; i++) close(fds[i]);
        if (served) {
            dsrv_event e;
            cr_assert_eq(wait_event(&sv, 2 * served - 1, &e), DSRV_EV_DISCONNECTED);
        }
        if (served >= 2) break;
        usleep(50000);
    }
    cr_expect_geq(served, 1, "the display was never served in %d tries under the flood", tries);
    stop(&sv);
}

/* A display whose HELLO has arrived but not yet been read is not idle:
 * several newcomers accepted in one step ahead of the pumping used to find
 * it unread (nothing received), take it for the oldest idle connection of
 * its address and drop it (a slot-holding client next to a display on a
 * loaded host: tests/e2e/render_slot_holders.sh failed so under the
 * sanitizers). The server is held between steps while the connections
 * queue, so that one step accepts them all. */
Test(dsrv, a_hello_waiting_unread_is_not_taken_for_an_idle_connection)
{
    auth_token tok;
    token(&tok, 't');
    uint8_t hello[256];
    size_t nh = display_hello(&tok, hello, sizeof hello);
    server sv;
    int port = start_tcp(&sv, &tok);
    pthread_mutex_lock(&sv.mu);
    int disp = idle_peer(3, port);
    cr_assert_eq(write(disp, hello, nh), (ssize_t)nh);
    int idle[DSRV_MAX_PENDING_PER_PEER];
    for (int k = 0; k < DSRV_MAX_PENDING_PER_PEER; k++) idle[k] = idle_peer(3, port);
    usleep(50000);   /* the HELLO is in the server's socket buffer */
    pthread_mutex_unlock(&sv.mu);
    cr_assert(dropped_within(idle[0], 1000), "the oldest idle connection was kept");
    cr_assert(!dropped_within(disp, 300), "the connection whose HELLO waited unread was dropped");
    for (int k = 1; k < DSRV_MAX_PENDING_PER_PEER; k++)
        cr_assert(!dropped_within(idle[k], 100), "idle connection %d was dropped too", k);
    close(disp);
    for (int k = 0; k < DSRV_MAX_PENDING_PER_PEER; k++) close(idle[k]);
    stop(&sv);
}
