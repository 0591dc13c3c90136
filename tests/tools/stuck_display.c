/* stuck_display.c: displays that misbehave without breaking the protocol
 * (built with the unit tests; run by tests/e2e/render_stuck_display.sh).
 * Each connects and authenticates as corrtex-display does (proto/chan.h):
 *   stuck_display ADDR TOKEN_FILE|- burst N
 *     SETTINGS (free running) and N CAMERAs in one write, then reads as a
 *     display does for up to 20 s; prints "scene after N cameras" and exits
 *     0 once the scene has arrived, else 1.
 *   stuck_display ADDR TOKEN_FILE|- noread SECONDS
 *     SETTINGS and a CAMERA, then reads nothing for SECONDS.
 *   stuck_display ADDR TOKEN_FILE|- pingflood SECONDS
 *     SETTINGS and a CAMERA, then PINGs as fast as the socket takes them for
 *     SECONDS, reading nothing (the PONGs pile up at the master).
 *   stuck_display ADDR TOKEN_FILE|- silent SECONDS
 *     SETTINGS for lockstep frames and a CAMERA, then reads everything for
 *     SECONDS and sends nothing, not even a PING (a stopped process, or a
 *     host gone without closing its connections).
 * The last three then read what is left: "closed: <why>" (after "ERROR
 * <code>: <text>" when the master said why) and exit 0 when the master had
 * dropped the connection, "still connected" and exit 1 when not. Exit 2 on
 * bad usage or when it cannot connect. */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/camera.h"
#include "common/timer.h"
#include "tests/tools/tool_display.h"

static wire_msg camera_msg(uint32_t epoch)
{
    wire_msg m = {.type = WIRE_CAMERA};
    m.u.camera.epoch = epoch;
    m.u.camera.width = 64;
    m.u.camera.height = 64;
    m.u.camera.cam = cam_look_at(v3(278.0f, 273.0f, -800.0f), v3(278.0f, 273.0f, 0.0f), v3(0.0f, 1.0f, 0.0f), 39.3f);
    return m;
}

/* Reads for up to `seconds`: 0 when the master closed the connection. */
static int drain(chan *c, double seconds)
{
    double end = ct_now() + seconds;
    ct_error err;
    while (ct_now() < end) {
        wire_msg m;
        int rc = chan_recv_wait(c, &m, 200, &err);
        if (rc < 0) {
            printf("closed: %s\n", err.msg);
            return 0;
        }
        if (rc == WIRE_OK && m.type == WIRE_ERROR) printf("ERROR %u: %s\n", m.u.error.code, m.u.error.text);
    }
    printf("still connected\n");
    return 1;
}

static int burst(const char *addr, const char *token_file, long n)
{
    chan *c = tool_display_connect("stuck_display", addr, token_file, 0);
    if (!c) return 2;
    ct_error err;
    for (long i = 0; i < n; i++) {
        wire_msg m = camera_msg((uint32_t)i + 1);
        if (chan_send(c, &m, &err)) {
            fprintf(stderr, "stuck_display: %s\n", err.msg);
            return 2;
        }
    }
    if (chan_flush(c, 5000, &err)) {
        fprintf(stderr, "stuck_display: %s\n", err.msg);
        return 2;
    }
    double end = ct_now() + 20.0;
    while (ct_now() < end) {
        wire_msg m;
        int rc = chan_recv_wait(c, &m, 200, &err);
        if (rc < 0) {
            printf("closed: %s\n", err.msg);
            return 1;
        }
        if (rc != WIRE_OK) continue;
        if (m.type == WIRE_SCENE_END) {
            printf("scene after %ld cameras\n", n);
            chan_free(c);
            return 0;
        }
        if (m.type == WIRE_SYNC) {   /* as a display: acknowledge */
            wire_msg a = {.type = WIRE_ACK};
            a.u.ack.seq = m.u.sync.seq;
            chan_send(c, &a, &err);
        }
    }
    printf("no scene within 20 s\n");
    return 1;
}

/* Writes frame bytes straight to the socket, never reading: the chan
 * would read while it flushes. Returns false when the peer is gone. */
static bool write_raw(int fd, const wire_buf *b)
{
    size_t off = 0;
    while (off < b->len) {
        ssize_t k = write(fd, b->data + off, b->len - off);
        if (k > 0) {
            off += (size_t)k;
            continue;
        }
        if (k < 0 && errno == EINTR) continue;
        if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            struct pollfd p = {.fd = fd, .events = POLLOUT};
            if (poll(&p, 1, 200) <= 0) return true;   /* full: try again later */
            continue;
        }
        return false;
    }
    return true;
}

static int stuck(const char *addr, const char *token_file, const char *mode, double seconds)
{
    bool silent = !strcmp(mode, "silent");
    chan *c = tool_display_connect("stuck_display", addr, token_file, silent ? 500u : 0u);
    if (!c) return 2;
    ct_error err;
    wire_msg cm = camera_msg(1);
    if (chan_send(c, &cm, &err) || chan_flush(c, 5000, &err)) {
        fprintf(stderr, "stuck_display: %s\n", err.msg);
        return 2;
    }
    double end = ct_now() + seconds;
    if (silent) {
        int rc = drain(c, seconds);
        chan_free(c);
        return rc;
    }
    if (!strcmp(mode, "pingflood")) {
        wire_buf b = {0};
        for (uint64_t i = 0; i < 4096; i++) {
            wire_msg p = {.type = WIRE_PING};
            p.u.ping.token = i;
            if (wire_encode(&p, &b, &err)) {
                fprintf(stderr, "stuck_display: %s\n", err.msg);
                return 2;
            }
        }
        while (ct_now() < end && write_raw(chan_fd(c), &b)) {
        }
        wire_buf_free(&b);
    }
    while (ct_now() < end) usleep(50000);
    int rc = drain(c, 5.0);
    chan_free(c);
    return rc;
}

int main(int argc, char **argv)
{
    signal(SIGPIPE, SIG_IGN);   /* a dropped connection is what some modes wait for */
    if (argc == 5) {
        char *e;
        double v = strtod(argv[4], &e);
        if (!*e && v > 0 && v <= 3600) {
            if (!strcmp(argv[3], "burst") && v == (long)v) return burst(argv[1], argv[2], (long)v);
            if (!strcmp(argv[3], "noread") || !strcmp(argv[3], "pingflood") || !strcmp(argv[3], "silent"))
                return stuck(argv[1], argv[2], argv[3], v);
        }
    }
    fprintf(stderr, "usage: stuck_display ADDR TOKEN_FILE|- burst N | noread SECONDS | pingflood SECONDS | silent SECONDS\n");
    return 2;
}
