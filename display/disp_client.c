#include "display/disp_client.h"

#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "proto/auth.h"
#include "proto/chan.h"
#include "proto/wire.h"

#define COMP "corrtex-display"

struct disp_client {
    chan *ch;
    char addr[XPORT_ADDR_LEN];
    disp_scene_cache *cache;
    wire_scene_rx *rx;
    bool have_scene;
    bool ended;               /* BYE received */
    uint32_t epoch;
    bool frame_seen;          /* a FRAME of the current epoch arrived... */
    uint64_t frame_last;      /* ...with this number */
    bool frame_taken_any;
    uint64_t frame_taken;     /* the last frame drawn */
    uint64_t bytes_seen;      /* received bytes already counted */
};

int disp_client_connect(const disp_client_opts *o, disp_scene_cache *cache, disp_client **out,
                        ct_error *err)
{
    *out = NULL;
    auth_token tok;
    bool have = false;
    int rc = auth_token_get(o->token_file, &tok, &have, err);
    if (rc) return rc;
    disp_client *c = calloc(1, sizeof *c);
    if (!c) {
        auth_token_wipe(&tok);
        return ct_fail(err, CT_ENOMEM, "out of memory for a connection");
    }
    snprintf(c->addr, sizeof c->addr, "%s", o->addr);
    c->cache = cache;
    chan_config cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.role = AUTH_ROLE_DISPLAY;
    cfg.token = have ? &tok : NULL;
    cfg.require_auth = false;
    rc = chan_connect(o->addr, &cfg, o->connect_timeout_ms > 0 ? o->connect_timeout_ms : 10000, &c->ch, err);
    auth_token_wipe(&tok);
    if (rc) {
        free(c);
        return rc;
    }
    wire_msg m;
    memset(&m, 0, sizeof m);
    m.type = WIRE_SETTINGS;
    m.u.settings.samples_per_frame = o->samples_per_frame;
    disp_scene_cache_select(cache, o->addr);
    (void)disp_scene_cache_hash(cache, m.u.settings.cached_scene);
    rc = chan_send(c->ch, &m, err);
    if (rc == XPORT_QUEUE_FULL) rc = ct_fail(err, CT_EIO, "%s: send queue full at start", c->addr);
    if (!rc) rc = chan_pump(c->ch, err);
    if (rc) {
        disp_client_close(c);
        return rc;
    }
    ct_info(COMP, "connected to %s (%s)", chan_peer(c->ch), have ? "token" : "no token");
    *out = c;
    return CT_OK;
}

void disp_client_close(disp_client *c)
{
    if (!c) return;
    if (c->ch) {
        wire_msg m;
        memset(&m, 0, sizeof m);
        m.type = WIRE_BYE;
        m.u.bye.reason = WIRE_BYE_QUIT;
        ct_error e;
        if (chan_send(c->ch, &m, &e) == 0) chan_flush(c->ch, 500, &e);
        chan_free(c->ch);
    }
    wire_scene_rx_free(c->rx);
    free(c);
}

static int send_msg(disp_client *c, const wire_msg *m, ct_error *err)
{
    int rc = chan_send(c->ch, m, err);
    if (rc == XPORT_QUEUE_FULL)
        return ct_fail(err, CT_EIO, "%s: the master does not read (send queue full)", c->addr);
    if (rc) return rc;
    return chan_pump(c->ch, err);
}

int disp_client_send_camera(disp_client *c, const ct_camera *cam, int width, int height,
                            ct_error *err)
{
    wire_msg m;
    memset(&m, 0, sizeof m);
    m.type = WIRE_CAMERA;
    m.u.camera.epoch = c->epoch + 1;
    m.u.camera.width = (uint32_t)width;
    m.u.camera.height = (uint32_t)height;
    m.u.camera.cam = *cam;
    int rc = send_msg(c, &m, err);
    if (rc) return rc;
    c->epoch++;
    c->frame_seen = false;
    return CT_OK;
}

uint32_t disp_client_epoch(const disp_client *c) { return c->epoch; }

static int scene_done(disp_client *c, disp_session *s, ct_error *err)
{
    const wire_scene_begin *b = wire_scene_rx_info(c->rx);
    ct_radmesh m;
    int rc;
    if (b->flags & WIRE_SCENE_CACHED) {
        const uint8_t *raw = NULL;
        uint64_t size = 0;
        if (!disp_scene_cache_get(c->cache, b->hash, &raw, &size))
            return ct_fail(err, CT_EPROTO, "%s: master says the scene is cached, but it is not",
                           c->addr);
        rc = wire_scene_parse(raw, (size_t)size, c->addr, &m, err);
        if (rc) return rc;
        ct_info(COMP, "scene from the cache: %u triangles, %u nodes", m.ntris, m.nnodes);
    } else {
        rc = wire_scene_rx_take(c->rx, &m, err);
        if (rc) return rc;
        uint64_t size = 0;
        const uint8_t *raw = wire_scene_rx_raw(c->rx, &size);
        if (raw && size) disp_scene_cache_put(c->cache, c->addr, b->hash, raw, size);
        ct_info(COMP, "scene received: %u triangles, %u nodes, %llu bytes", m.ntris, m.nnodes,
                (unsigned long long)size);
    }
    rc = disp_session_scene(s, &m, err);
    rmesh_free(&m);
    wire_scene_rx_free(c->rx);
    c->rx = NULL;
    if (!rc) c->have_scene = true;
    return rc;
}

static int apply(disp_client *c, disp_session *s, const wire_msg *m, ct_error *err)
{
    switch (m->type) {
    case WIRE_SCENE_BEGIN: {
        wire_scene_rx_free(c->rx);
        c->rx = NULL;
        int rc = wire_scene_rx_new(c->addr, &c->rx, err);
        if (rc) return rc;
    }   /* fall through: the receiver takes BEGIN too */
    /* FALLTHROUGH */
    case WIRE_SCENE_CHUNK:
    case WIRE_SCENE_END: {
        if (!c->rx)
            return ct_fail(err, CT_EPROTO, "%s: %s without SCENE_BEGIN", c->addr, wire_type_name(m->type));
        int rc = wire_scene_rx_feed(c->rx, m, err);
        if (rc < 0) return rc;
        return rc == 1 ? scene_done(c, s, err) : CT_OK;
    }
    case WIRE_TEX_ALLOC: {
        const wire_tex_alloc *a = &m->u.tex_alloc;
        disp_proj_kind k = a->proj == WIRE_PROJ_CAMERA_PERSPECTIVE ? DISP_PROJ_CAMERA_PERSPECTIVE
                                                                   : DISP_PROJ_OBJECT_PARALLEL;
        return disp_session_tex_alloc(s, a->tex, a->node, (int)a->width, (int)a->height, k, err);
    }
    case WIRE_TEX_PROJECTION:
        return disp_session_tex_projection(s, m->u.tex_projection.tex, &m->u.tex_projection.world_to_tex, err);
    case WIRE_TEX_PATCH: {
        const wire_tex_patch *p = &m->u.tex_patch;
        return disp_session_tex_patch(s, p->tex, (int)p->x, (int)p->y, (int)p->w, (int)p->h, p->texels, err);
    }
    case WIRE_TEX_FREE:
        return disp_session_tex_free(s, m->u.tex_free.tex, err);
    case WIRE_FRAME:
        disp_session_frame_end(s, (uint32_t)m->u.frame.frame, m->u.frame.samples,
                               (m->u.frame.flags & WIRE_FLAG_ALL_POSITIVE) != 0);
        if (m->u.frame.epoch == c->epoch) {
            c->frame_seen = true;
            c->frame_last = m->u.frame.frame;
        }
        return CT_OK;
    case WIRE_SAMPLES:
        /* Points of an older camera still land on surfaces: keep them all. */
        disp_session_sample_points(s, m->u.samples.xyz, m->u.samples.count, m->u.samples.dropped);
        return CT_OK;
    case WIRE_STATS:
        disp_session_stats(s, m->u.stats.samples_total, (m->u.stats.flags & WIRE_FLAG_ALL_POSITIVE) != 0);
        return CT_OK;
    case WIRE_PING: {
        wire_msg pong;
        memset(&pong, 0, sizeof pong);
        pong.type = WIRE_PONG;
        pong.u.ping.token = m->u.ping.token;
        return send_msg(c, &pong, err);
    }
    case WIRE_PONG:
        return CT_OK;
    case WIRE_ERROR:
        return ct_fail(err, CT_EPROTO, "%s: master reports an error: %s", c->addr, m->u.error.text);
    case WIRE_BYE:
        c->ended = true;
        return ct_fail(err, CT_EIO, "%s: the master ended the session (%s)", c->addr,
                       m->u.bye.reason == WIRE_BYE_SHUTDOWN ? "shutting down"
                       : m->u.bye.reason == WIRE_BYE_DONE   ? "run finished"
                                                             : "quit");
    default:
        return ct_fail(err, CT_EPROTO, "%s: unexpected %s message", c->addr, wire_type_name(m->type));
    }
}

int disp_client_service(disp_client *c, disp_session *s, int timeout_ms, ct_error *err)
{
    struct pollfd p = {chan_fd(c->ch), chan_events(c->ch), 0};
    if (timeout_ms > 0) poll(&p, 1, timeout_ms);
    int rc = chan_pump(c->ch, err);
    if (rc) return rc;
    for (;;) {
        wire_msg m;
        rc = chan_recv(c->ch, &m, err);
        if (rc == WIRE_NEED_MORE) break;
        if (rc < 0) break;
        rc = apply(c, s, &m, err);
        if (rc && m.type >= WIRE_TEX_ALLOC && m.type <= WIRE_TEX_PATCH) {
            /* Session errors do not know the peer: name it and the message. */
            char what[64];
            snprintf(what, sizeof what, "%s from %s", wire_type_name(m.type), c->addr);
            ct_error_prefix(err, what);
        }
        if (rc) {
            /* A message that does not fit our state: tell the master why
             * before the connection is dropped (not after its own ERROR/BYE). */
            if (m.type != WIRE_ERROR && m.type != WIRE_BYE)
                chan_send_error(c->ch, rc == CT_ENOMEM || rc == CT_ESYS ? WIRE_ERR_INTERNAL : WIRE_ERR_PROTOCOL,
                                err->msg, 200);
            break;
        }
    }
    uint64_t rx = 0, tx = 0;
    chan_byte_counts(c->ch, &rx, &tx);
    if (rx > c->bytes_seen) disp_session_add_bytes(s, rx - c->bytes_seen);
    c->bytes_seen = rx;
    return rc == WIRE_NEED_MORE ? CT_OK : rc;
}

bool disp_client_frame_ready(const disp_client *c, uint64_t *frame)
{
    if (!c->frame_seen) return false;
    if (c->frame_taken_any && c->frame_last <= c->frame_taken) return false;
    if (frame) *frame = c->frame_last;
    return true;
}

void disp_client_take_frame(disp_client *c)
{
    if (!c->frame_seen) return;
    c->frame_taken = c->frame_last;
    c->frame_taken_any = true;
}

bool disp_client_has_scene(const disp_client *c) { return c->have_scene; }

bool disp_client_ended(const disp_client *c) { return c->ended; }

const char *disp_client_addr(const disp_client *c) { return c->addr; }
