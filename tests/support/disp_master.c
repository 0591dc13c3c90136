#include "tests/support/disp_master.h"

#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/timer.h"
#include "proto/chan.h"
#include "proto/wire.h"
#include "tests/support/disp_fixture.h"


static float tex_rgb[8 * 6 * 3];

const float *fxm_tex_rgb(void)
{
    for (int i = 0; i < 8 * 6 * 3; i++) tex_rgb[i] = (float)((i * 29) % 64 - 32) / 128.0f;
    return tex_rgb;
}

mat4 fxm_wall_proj(void)
{
    mat4 m;
    memset(&m, 0, sizeof m);
    m.m[0][0] = 0.5f; m.m[0][3] = 0.5f;
    m.m[1][1] = 0.5f; m.m[1][3] = 0.5f;
    m.m[3][3] = 1.0f;
    return m;
}

static int send_all(chan *c, const wire_msg *m)
{
    ct_error err;
    if (chan_send(c, m, &err) != 0) return -1;
    return chan_flush(c, 5000, &err);
}

/* The next message other than PING (answered with PONG, as a master does:
 * the display pings from the start to learn the master's clock). */
static int recv_wait(chan *c, wire_msg *m, int timeout_ms, ct_error *err)
{
    double end = ct_now() + timeout_ms / 1000.0;
    for (;;) {
        int left = (int)((end - ct_now()) * 1000.0);
        int rc = chan_recv_wait(c, m, left > 0 ? left : 0, err);
        if (rc != WIRE_OK || m->type != WIRE_PING) return rc;
        wire_msg pong = *m;
        pong.type = WIRE_PONG;
        pong.u.ping.clock_us = ct_now_us();
        if (chan_send(c, &pong, err) != 0) return CT_EIO;
    }
}

/* The master: accepts one display, checks SETTINGS and CAMERA, sends the box
 * scene, one texture in two patches and FRAME 0 for the display's epoch. */
static int master(xport_listener *l, fxm_end end, uint32_t want_k, int w, int h, const char *token)
{
    ct_error err;
    chan_config cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.role = AUTH_ROLE_MASTER;
    auth_token tok;
    if (token) {
        memset(&tok, 0, sizeof tok);
        tok.len = strlen(token);
        memcpy(tok.bytes, token, tok.len);
        cfg.token = &tok;
        cfg.require_auth = true;
    }
    chan *c = NULL;
    struct pollfd p = {xport_listener_fd(l), POLLIN, 0};
    for (int i = 0; i < 100 && !c; i++) {
        poll(&p, 1, 100);
        if (chan_accept(l, &cfg, &c, &err)) return 10;
    }
    /* Nobody else may connect: removing the socket file makes a display's
     * reconnection fail at once. */
    xport_listener_close(l);
    if (!c || chan_handshake(c, 5000, &err)) return 11;
    wire_msg m;
    if (recv_wait(c, &m, 5000, &err) != WIRE_OK || m.type != WIRE_SETTINGS) return 12;
    if (m.u.settings.samples_per_frame != want_k) return 13;
    uint8_t cached[WIRE_HASH_SIZE];
    memcpy(cached, m.u.settings.cached_scene, WIRE_HASH_SIZE);
    if (recv_wait(c, &m, 5000, &err) != WIRE_OK || m.type != WIRE_CAMERA) return 14;
    uint32_t epoch = m.u.camera.epoch;
    float first_x = m.u.camera.cam.eye.x;
    if (m.u.camera.width != (uint32_t)w || m.u.camera.height != (uint32_t)h) return 15;
    ct_radmesh mesh;
    fx_box_nodes nd;
    if (fx_box_mesh(4, &mesh, &nd, &err)) return 16;
    wire_scene_tx tx;
    if (wire_scene_tx_init(&tx, &mesh, &err)) return 17;
    /* A display that announces this scene's hash gets it as CACHED. */
    bool is_cached = memcmp(cached, tx.hash, WIRE_HASH_SIZE) == 0;
    wire_scene_tx_begin(&tx, is_cached, &m);
    if (send_all(c, &m)) return 18;
    for (uint32_t i = 0; !is_cached && i < tx.begin.nchunks; i++) {
        wire_scene_tx_chunk(&tx, i, &m);
        if (send_all(c, &m)) return 19;
    }
    wire_scene_tx_end(&tx, &m);
    if (send_all(c, &m)) return 20;
    wire_scene_tx_free(&tx);
    memset(&m, 0, sizeof m);
    m.type = WIRE_TEX_ALLOC;
    m.u.tex_alloc = (wire_tex_alloc){5, nd.back, 8, 6, WIRE_PROJ_OBJECT_PARALLEL};
    if (send_all(c, &m)) return 21;
    m.type = WIRE_TEX_PROJECTION;
    m.u.tex_projection.tex = 5;
    m.u.tex_projection.epoch = epoch;
    m.u.tex_projection.world_to_tex = fxm_wall_proj();
    if (send_all(c, &m)) return 22;
    uint16_t half[8 * 6 * 3];
    for (int i = 0; i < 8 * 6 * 3; i++) half[i] = wire_half_from_float(fxm_tex_rgb()[i]);
    m.type = WIRE_TEX_PATCH;
    m.u.tex_patch = (wire_tex_patch){.tex = 5, .x = 0, .y = 0, .w = 8, .h = 3, .texels = half};
    if (send_all(c, &m)) return 23;
    m.u.tex_patch = (wire_tex_patch){.tex = 5, .x = 0, .y = 3, .w = 8, .h = 3, .texels = half + 8 * 3 * 3};
    if (send_all(c, &m)) return 24;
    memset(&m, 0, sizeof m);
    m.type = WIRE_FRAME;
    m.u.frame = (wire_frame){0, epoch, 0, 123, 2};
    if (send_all(c, &m)) return 25;
    rmesh_free(&mesh);
    if (end == FXM_END_BYE) {
        m.type = WIRE_BYE;
        m.u.bye.reason = WIRE_BYE_DONE;
        send_all(c, &m);
    } else if (end == FXM_END_STALL) {
        wire_buf b = {0};
        memset(&m, 0, sizeof m);
        m.type = WIRE_TEX_PATCH;
        m.u.tex_patch = (wire_tex_patch){.tex = 5, .x = 0, .y = 0, .w = 8, .h = 3, .texels = half};
        if (wire_encode(&m, &b, &err) || write(chan_fd(c), b.data, 10) != 10) return 60;
        wire_buf_free(&b);
        usleep(5000000);
        chan_free(c);
        return 0;
    } else if (end == FXM_END_TRICKLE) {
        wire_buf b = {0};
        memset(&m, 0, sizeof m);
        m.type = WIRE_TEX_PATCH;
        m.u.tex_patch = (wire_tex_patch){.tex = 5, .x = 0, .y = 0, .w = 8, .h = 3, .texels = half};
        if (wire_encode(&m, &b, &err)) return 80;
        for (size_t i = 0; i < b.len && i < 100; i++) {
            if (send(chan_fd(c), b.data + i, 1, MSG_NOSIGNAL) != 1) break;   /* the display hung up */
            usleep(50000);
        }
        wire_buf_free(&b);
        chan_free(c);
        return 0;
    } else if (end == FXM_END_RESIZES) {
        memset(&m, 0, sizeof m);
        m.type = WIRE_TEX_ALLOC;
        m.u.tex_alloc = (wire_tex_alloc){7, nd.back, 2048, 2048, WIRE_PROJ_OBJECT_PARALLEL};
        if (chan_send(c, &m, &err)) return 100;
        for (int i = 0; i < 1000; i++) {
            memset(&m, 0, sizeof m);
            m.type = WIRE_TEX_RESIZE;
            m.u.tex_resize = (wire_tex_resize){7, i & 1 ? 2048u : 4096u, i & 1 ? 2048u : 4096u};
            if (chan_send(c, &m, &err)) return 101;
        }
        if (chan_flush(c, 5000, &err)) return 102;
        for (int i = 0; i < 100; i++) {
            int rc = recv_wait(c, &m, 100, &err);
            if (rc < 0 || (rc == WIRE_OK && (m.type == WIRE_BYE || m.type == WIRE_ERROR))) break;
        }
    } else if (end == FXM_END_FRAME_AGAIN) {
        for (int i = 0; i < 2; i++) {
            memset(&m, 0, sizeof m);
            m.type = WIRE_FRAME;
            m.u.frame = (wire_frame){5, epoch, 0, 123, 0};
            if (send_all(c, &m)) return 90;
        }
        for (int i = 0; i < 50; i++) {
            int rc = recv_wait(c, &m, 100, &err);
            if (rc < 0 || (rc == WIRE_OK && (m.type == WIRE_BYE || m.type == WIRE_ERROR))) break;
        }
    } else if (end == FXM_END_DEAF) {
        /* As a master that is going away: the display's PINGs fail (EPIPE)
         * before the ERROR saying why comes, and so does the ACK of the
         * SYNC just before it. */
        if (shutdown(chan_fd(c), SHUT_RD)) return 70;
        usleep(500000);
        /* Both queued before one flush: the chan reads its own end of
         * file (the shut read side) in the flush and sends nothing after. */
        memset(&m, 0, sizeof m);
        m.type = WIRE_SYNC;
        m.u.sync.seq = 1;
        if (chan_send(c, &m, &err)) return 72;
        memset(&m, 0, sizeof m);
        m.type = WIRE_ERROR;
        m.u.error.code = WIRE_ERR_INTERNAL;
        snprintf(m.u.error.text, sizeof m.u.error.text, "%s", FXM_DEAF_TEXT);
        if (send_all(c, &m)) return 71;
        chan_free(c);
        return 0;
    } else if (end == FXM_END_BAD) {
        memset(&m, 0, sizeof m);
        m.type = WIRE_TEX_PATCH;
        m.u.tex_patch = (wire_tex_patch){.tex = 77, .x = 0, .y = 0, .w = 1, .h = 1, .texels = half};
        if (send_all(c, &m)) return 30;
        int got = 31;
        for (int i = 0; i < 50 && got == 31; i++) {
            int rc = recv_wait(c, &m, 100, &err);
            if (rc < 0) break;
            if (rc == WIRE_OK && m.type == WIRE_ERROR)
                got = m.u.error.code == WIRE_ERR_PROTOCOL && strstr(m.u.error.text, "77") ? 0 : 32;
        }
        chan_free(c);
        return got;
    } else if (end == FXM_END_ROUNDS) {
        enum { S = 1024 };
        uint16_t *big = calloc(32 * 32 * 3, sizeof *big);
        if (!big) return 40;
        memset(&m, 0, sizeof m);
        m.type = WIRE_TEX_ALLOC;
        m.u.tex_alloc = (wire_tex_alloc){6, nd.back, S, S, WIRE_PROJ_OBJECT_PARALLEL};
        if (send_all(c, &m)) return 41;
        for (uint32_t k = 1; k <= FXM_ROUNDS; k++) {
            if (recv_wait(c, &m, 5000, &err) != WIRE_OK || m.type != WIRE_CAMERA) return 42;
            epoch = m.u.camera.epoch;
            for (size_t i = 0; i < 32 * 32 * 3; i++) big[i] = wire_half_from_float((float)((i + k) % 7) / 16.0f);
            /* Many tiles, as a master sends them: reads end mid-message. */
            for (int py = 0; py < S; py += 32)
                for (int px = 0; px < S; px += 32) {
                    memset(&m, 0, sizeof m);
                    m.type = WIRE_TEX_PATCH;
                    m.u.tex_patch = (wire_tex_patch){.tex = 6, .x = (uint32_t)px, .y = (uint32_t)py, .w = 32,
                                                     .h = 32, .texels = big};
                    if (chan_send(c, &m, &err)) return 43;
                }
            memset(&m, 0, sizeof m);
            m.type = WIRE_FRAME;
            m.u.frame = (wire_frame){k, epoch, 0, 123, 2};
            if (send_all(c, &m)) return 44;
        }
        free(big);
        for (int i = 0; i < 50; i++) {
            int rc = recv_wait(c, &m, 100, &err);
            if (rc < 0 || (rc == WIRE_OK && m.type == WIRE_BYE)) break;
        }
    } else if (end == FXM_END_CAMERAS) {
        /* Cameras drawn before the connection was up arrive as the first. */
        float last_x = first_x;
        uint32_t last_epoch = epoch;
        for (double until = ct_now() + 5.0; ct_now() < until;) {
            int rc = recv_wait(c, &m, 100, &err);
            if (rc < 0) return 50;
            if (rc != WIRE_OK) continue;
            if (m.type == WIRE_BYE) break;
            if (m.type != WIRE_CAMERA) continue;
            if (m.u.camera.epoch <= last_epoch) return 51;   /* epochs only grow */
            last_epoch = m.u.camera.epoch;
            last_x = m.u.camera.cam.eye.x;
        }
        chan_free(c);
        return last_x == FXM_LAST_X ? 0 : 52;
    } else if (end == FXM_END_STAY) {
        /* Wait for the display's BYE. */
        for (int i = 0; i < 50; i++) {
            int rc = recv_wait(c, &m, 100, &err);
            if (rc < 0 || (rc == WIRE_OK && m.type == WIRE_BYE)) break;
        }
    }
    chan_free(c);
    return 0;
}

int fxm_start(fxm_peer *p, fxm_end end, uint32_t k, int w, int h)
{
    ct_error err;
    p->msg[0] = '\0';
    snprintf(p->dir, sizeof p->dir, "/tmp/ctdisp-XXXXXX");
    if (!mkdtemp(p->dir)) {
        snprintf(p->msg, sizeof p->msg, "mkdtemp failed");
        return -1;
    }
    snprintf(p->addr, sizeof p->addr, p->token ? "tcp:127.0.0.1:0" : "unix:%s/sock", p->dir);
    p->l = NULL;
    if (xport_listen(p->addr, &p->l, &err)) {
        snprintf(p->msg, sizeof p->msg, "%s", err.msg);
        return -1;
    }
    if (p->token) snprintf(p->addr, sizeof p->addr, "%s", xport_listener_addr(p->l));
    fflush(NULL);
    p->pid = fork();
    if (p->pid < 0) {
        snprintf(p->msg, sizeof p->msg, "fork failed");
        return -1;
    }
    if (p->pid == 0) _exit(master(p->l, end, k, w, h, p->token));
    return 0;
}

int fxm_stop(fxm_peer *p)
{
    int st = 0;
    waitpid(p->pid, &st, 0);
    xport_listener_close(p->l);
    char path[160];
    snprintf(path, sizeof path, "%s/sock", p->dir);
    unlink(path);
    rmdir(p->dir);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 100;
}
