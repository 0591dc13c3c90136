/* disp_client.c: the connection to the master and its thread (disp_client.h). */
#include "display/disp_client.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/log.h"
#include "common/timer.h"
#include "proto/auth.h"
#include "proto/chan.h"
#include "proto/wire.h"

#define COMP "corrtex-display"
#define MAX_OUT 64
/* PING: a few quickly for a first clock offset, then once a second. */
#define PING_FIRST_US 100000u
#define PING_EVERY_US 1000000u
#define PING_QUICK 4
#define READ_AFTER_SEND_FAILED_US 2000000u   /* see thread_main */
/* A master that makes no progress this long (disp_client_opts.silent_ms) is
 * taken for gone: one stopped in the middle of a message left a lockstep
 * display waiting for good (a working master answers a PING within its
 * loop's turn). Progress is a whole message, PONGs included, or
 * PROGRESS_BYTES more of one: a SCENE_CHUNK of up to 1 MiB over a slow link
 * still counts, a master that trickles a frame a byte a second (which kept
 * the display waiting when any byte counted) does not. */
#define MASTER_SILENT_MS 30000
#define PROGRESS_BYTES (64u << 10)   /* 64 KiB in 30 s: 17 kbit/s */

struct disp_client {
    chan *ch;
    char addr[XPORT_ADDR_LEN];
    disp_scene_cache *cache;
    disp_inbox *inbox;
    wire_scene_rx *rx;            /* thread only */
    pthread_t thread;
    bool started;
    atomic_bool stop;
    int wake[2];                  /* the render thread writes a byte to wake the thread */
    int silent_ms;                /* disp_client_opts.silent_ms */
    uint32_t epoch;               /* render thread only */
    uint64_t msgs_in;             /* thread only: messages decoded */
    bool frame_seen;              /* thread only: a FRAME arrived, frame_last is its number */
    uint64_t frame_last;
    /* A send that failed (thread only): the master may have closed after an
     * ERROR saying why, which is still to be read; ending at the failed send,
     * the display reported a bare lost connection. Sending stops, reading
     * goes on until the read side ends, or until read_until. */
    int send_rc;
    ct_error send_err;
    uint64_t read_until;
    bool lockstep;                /* every CAMERA asks for a frame */
    pthread_mutex_t mu;           /* guards what follows */
    wire_msg out[MAX_OUT];        /* CAMERA messages for the thread to send */
    int nout;
    int end_rc;                   /* 0 while the connection lives */
    ct_error end_err;
    bool ended;                   /* BYE received */
    bool have_offset;
    int64_t offset_us;
    uint64_t best_rtt_us;
};

static void *thread_main(void *arg);

int disp_client_connect(const disp_client_opts *o, disp_scene_cache *cache, disp_inbox *inbox,
                        disp_client **out, ct_error *err)
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
    c->wake[0] = c->wake[1] = -1;
    snprintf(c->addr, sizeof c->addr, "%s", o->addr);
    c->silent_ms = o->silent_ms > 0 ? o->silent_ms : MASTER_SILENT_MS;
    c->cache = cache;
    c->inbox = inbox;
    pthread_mutex_init(&c->mu, NULL);
    chan_config cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.role = AUTH_ROLE_DISPLAY;
    cfg.token = have ? &tok : NULL;
    cfg.require_auth = false;
    rc = chan_connect(o->addr, &cfg, o->connect_timeout_ms > 0 ? o->connect_timeout_ms : 10000, &c->ch, err);
    auth_token_wipe(&tok);
    if (rc) {
        disp_client_close(c);
        return rc;
    }
    wire_msg m;
    memset(&m, 0, sizeof m);
    m.type = WIRE_SETTINGS;
    m.u.settings.samples_per_frame = o->samples_per_frame;
    c->lockstep = o->samples_per_frame > 0;
    disp_scene_cache_select(cache, o->addr);
    (void)disp_scene_cache_hash(cache, m.u.settings.cached_scene);
    rc = chan_send(c->ch, &m, err);
    if (rc == XPORT_QUEUE_FULL) rc = ct_fail(err, CT_EIO, "%s: send queue full at start", c->addr);
    if (!rc) rc = chan_pump(c->ch, err);
    if (rc == CT_EIO) {
        /* A master that refuses us (ERROR BUSY: it serves another display)
         * says why and closes right after the handshake: the SETTINGS then
         * meet a closed socket, and "the peer closed the connection" hid
         * its reason, which is already read. */
        wire_msg e;
        ct_error e2;
        if (chan_recv_wait(c->ch, &e, 200, &e2) == WIRE_OK && e.type == WIRE_ERROR)
            rc = ct_fail(err, CT_EIO, "%s: master reports an error: %s", c->addr, e.u.error.text);
    }
    if (!rc && pipe2(c->wake, O_NONBLOCK | O_CLOEXEC) != 0)
        rc = ct_fail(err, CT_ESYS, "cannot make a pipe for the connection thread: %s", strerror(errno));
    if (!rc) {
        disp_inbox_connection(inbox);
        if (pthread_create(&c->thread, NULL, thread_main, c) != 0)
            rc = ct_fail(err, CT_ESYS, "cannot start the connection thread");
        else
            c->started = true;
    }
    if (rc) {
        disp_client_close(c);
        return rc;
    }
    ct_info(COMP, "connected to %s (%s)", chan_peer(c->ch), have ? "token" : "no token");
    *out = c;
    return CT_OK;
}

static void wake(disp_client *c)
{
    if (c->wake[1] >= 0) {
        ssize_t n = write(c->wake[1], "x", 1);
        (void)n;   /* a full pipe is awake already */
    }
}

void disp_client_close(disp_client *c)
{
    if (!c) return;
    if (c->started) {
        atomic_store(&c->stop, true);
        wake(c);
        pthread_join(c->thread, NULL);
    }
    if (c->ch) chan_free(c->ch);
    if (c->wake[0] >= 0) close(c->wake[0]);
    if (c->wake[1] >= 0) close(c->wake[1]);
    wire_scene_rx_free(c->rx);
    pthread_mutex_destroy(&c->mu);
    free(c);
}

int disp_client_send_camera(disp_client *c, const ct_camera *cam, int width, int height, ct_error *err)
{
    wire_msg m;
    memset(&m, 0, sizeof m);
    m.type = WIRE_CAMERA;
    m.u.camera.epoch = c->epoch + 1;
    m.u.camera.width = (uint32_t)width;
    m.u.camera.height = (uint32_t)height;
    m.u.camera.cam = *cam;
    int rc = CT_OK;
    pthread_mutex_lock(&c->mu);
    if (c->end_rc) {
        rc = c->end_rc;
        if (err) *err = c->end_err;
    } else if (!c->lockstep && c->nout > 0) {
        /* Free running only the newest view matters: it replaces an unsent
         * one (the master skips that epoch), so a display drawing hundreds
         * of frames a second never piles cameras up while the connection
         * thread or the master is slow. */
        c->out[c->nout - 1] = m;
    } else if (c->nout == MAX_OUT) {
        /* Lockstep has at most two frames asked for ahead: the thread is stuck. */
        rc = ct_fail(err, CT_EIO, "%s: the master does not read (%d cameras unsent)", c->addr, MAX_OUT);
    } else {
        c->out[c->nout++] = m;
    }
    pthread_mutex_unlock(&c->mu);
    if (rc) return rc;
    c->epoch++;
    disp_inbox_new_epoch(c->inbox, c->epoch);
    wake(c);
    return CT_OK;
}

uint32_t disp_client_epoch(const disp_client *c) { return c->epoch; }

int disp_client_status(disp_client *c, ct_error *err)
{
    pthread_mutex_lock(&c->mu);
    int rc = c->end_rc;
    if (rc && err) *err = c->end_err;
    pthread_mutex_unlock(&c->mu);
    return rc;
}

bool disp_client_ended(disp_client *c)
{
    pthread_mutex_lock(&c->mu);
    bool e = c->ended;
    pthread_mutex_unlock(&c->mu);
    return e;
}

bool disp_client_clock_offset(disp_client *c, int64_t *offset_us)
{
    pthread_mutex_lock(&c->mu);
    bool ok = c->have_offset;
    if (ok) *offset_us = c->offset_us;
    pthread_mutex_unlock(&c->mu);
    return ok;
}

/* --- the connection thread --------------------------------------------------- */

static int scene_done(disp_client *c, ct_error *err)
{
    const wire_scene_begin *b = wire_scene_rx_info(c->rx);
    ct_radmesh m;
    int rc;
    if (b->flags & WIRE_SCENE_CACHED) {
        const uint8_t *raw = NULL;
        uint64_t size = 0;
        if (!disp_scene_cache_get(c->cache, b->hash, &raw, &size))
            return ct_fail(err, CT_EPROTO, "%s: master says the scene is cached, but it is not", c->addr);
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
    disp_inbox_scene(c->inbox, &m);
    rmesh_free(&m);
    wire_scene_rx_free(c->rx);
    c->rx = NULL;
    return CT_OK;
}

static int send_now(disp_client *c, const wire_msg *m, ct_error *err)
{
    int rc = chan_send(c->ch, m, err);
    if (rc == XPORT_QUEUE_FULL) return ct_fail(err, CT_EIO, "%s: the master does not read (send queue full)", c->addr);
    return rc;
}

/* Sends m unless a send failed before; a failure is kept (send_rc), not
 * returned: the reading goes on (see struct disp_client). */
static void send_or_keep(disp_client *c, const wire_msg *m)
{
    if (c->send_rc) return;
    int rc = send_now(c, m, &c->send_err);
    if (rc) {
        c->send_rc = rc;
        c->read_until = ct_now_us() + READ_AFTER_SEND_FAILED_US;
    }
}

/* A PONG: the master's clock at the middle of the round trip. */
static void pong(disp_client *c, const wire_ping *p)
{
    uint64_t now = ct_now_us();
    if (p->token > now) return;   /* not one of ours */
    uint64_t rtt = now - p->token;
    /* In unsigned arithmetic: a master's clock_us may be anything, and a
     * signed difference of two far-apart values overflowed (undefined). */
    int64_t off = (int64_t)(p->clock_us - (p->token + rtt / 2));
    pthread_mutex_lock(&c->mu);
    if (!c->have_offset || rtt <= c->best_rtt_us) {
        c->have_offset = true;
        c->offset_us = off;
        c->best_rtt_us = rtt;
    }
    pthread_mutex_unlock(&c->mu);
}

static int apply(disp_client *c, const wire_msg *m, ct_error *err)
{
    disp_inbox *b = c->inbox;
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
        if (!c->rx) return ct_fail(err, CT_EPROTO, "%s: %s without SCENE_BEGIN", c->addr, wire_type_name(m->type));
        int rc = wire_scene_rx_feed(c->rx, m, err);
        if (rc < 0) return rc;
        return rc == 1 ? scene_done(c, err) : CT_OK;
    }
    case WIRE_CAMERA:
        disp_inbox_view(b, &m->u.camera.cam);
        return CT_OK;
    case WIRE_TEX_ALLOC: {
        const wire_tex_alloc *a = &m->u.tex_alloc;
        disp_proj_kind k = a->proj == WIRE_PROJ_CAMERA_PERSPECTIVE ? DISP_PROJ_CAMERA_PERSPECTIVE
                                                                   : DISP_PROJ_OBJECT_PARALLEL;
        return disp_inbox_tex_alloc(b, a->tex, a->node, (int)a->width, (int)a->height, k, err);
    }
    case WIRE_TEX_PROJECTION:
        return disp_inbox_tex_projection(b, m->u.tex_projection.tex, &m->u.tex_projection.world_to_tex, err);
    case WIRE_TEX_PATCH: {
        const wire_tex_patch *p = &m->u.tex_patch;
        return disp_inbox_tex_patch(b, p->tex, (int)p->x, (int)p->y, (int)p->w, (int)p->h, p->texels, p->stamp_us,
                                    p->samples, err);
    }
    case WIRE_TEX_FREE:
        return disp_inbox_tex_free(b, m->u.tex_free.tex, err);
    case WIRE_TEX_RESIZE:
        return disp_inbox_tex_resize(b, m->u.tex_resize.tex, (int)m->u.tex_resize.width,
                                     (int)m->u.tex_resize.height, err);
    case WIRE_FRAME:
        /* A frame number that does not grow would never count as ready
         * (disp_inbox_frame_ready): a lockstep display would wait for good. */
        if (c->frame_seen && m->u.frame.frame <= c->frame_last)
            return ct_fail(err, CT_EPROTO, "%s: FRAME %llu after FRAME %llu: frame numbers must increase", c->addr,
                           (unsigned long long)m->u.frame.frame, (unsigned long long)c->frame_last);
        c->frame_seen = true;
        c->frame_last = m->u.frame.frame;
        disp_inbox_frame_end(b, m->u.frame.frame, m->u.frame.epoch, m->u.frame.samples,
                             (m->u.frame.flags & WIRE_FLAG_ALL_POSITIVE) != 0);
        return CT_OK;
    case WIRE_SYNC: {
        /* Everything before it is in the inbox: the master may send more. */
        wire_msg a = {.type = WIRE_ACK};
        a.u.ack.seq = m->u.sync.seq;
        send_or_keep(c, &a);
        return CT_OK;
    }
    case WIRE_SAMPLES:
        /* Points of an older camera still land on surfaces: keep them all. */
        disp_inbox_points(b, m->u.samples.xyz, m->u.samples.count, m->u.samples.dropped);
        return CT_OK;
    case WIRE_STATS:
        disp_inbox_stats(b, m->u.stats.samples_total, (m->u.stats.flags & WIRE_FLAG_ALL_POSITIVE) != 0);
        return CT_OK;
    case WIRE_PING: {
        wire_msg p;
        memset(&p, 0, sizeof p);
        p.type = WIRE_PONG;
        p.u.ping.token = m->u.ping.token;
        p.u.ping.clock_us = ct_now_us();
        send_or_keep(c, &p);
        return CT_OK;
    }
    case WIRE_PONG:
        pong(c, &m->u.ping);
        return CT_OK;
    case WIRE_ERROR:
        return ct_fail(err, CT_EPROTO, "%s: master reports an error: %s", c->addr, m->u.error.text);
    case WIRE_BYE:
        pthread_mutex_lock(&c->mu);
        c->ended = true;
        pthread_mutex_unlock(&c->mu);
        return ct_fail(err, CT_EIO, "%s: the master ended the session (%s)", c->addr,
                       m->u.bye.reason == WIRE_BYE_SHUTDOWN ? "shutting down"
                       : m->u.bye.reason == WIRE_BYE_DONE   ? "run finished"
                                                             : "quit");
    default:
        return ct_fail(err, CT_EPROTO, "%s: unexpected %s message", c->addr, wire_type_name(m->type));
    }
}

/* Reads and applies every message that arrived; 0 or the error that ends
 * the connection (the master is told why when it is ours to tell). */
static int receive(disp_client *c, ct_error *err)
{
    /* The read buffer can hold hundreds of thousands of small messages, some
     * costly (a TEX_RESIZE of a large texture): a display asked to stop must
     * not work through them first. */
    while (!atomic_load(&c->stop)) {
        wire_msg m;
        int rc = chan_recv(c->ch, &m, err);
        if (rc == WIRE_NEED_MORE) return 0;
        if (rc < 0) {
            /* A frame the decoder refused: the master hears why (a lost
             * connection has nobody to tell). */
            if (rc != CT_EIO) chan_send_error(c->ch, WIRE_ERR_PROTOCOL, err->msg, 200);
            return rc;
        }
        c->msgs_in++;
        rc = apply(c, &m, err);
        if (!rc) continue;
        if ((m.type >= WIRE_TEX_ALLOC && m.type <= WIRE_TEX_PATCH) || m.type == WIRE_TEX_RESIZE) {
            /* Inbox errors do not know the peer: name it and the message. */
            char what[XPORT_ADDR_LEN + 32];
            snprintf(what, sizeof what, "%s: %s", c->addr, wire_type_name(m.type));
            ct_error_prefix(err, what);
        }
        /* A message that does not fit our state: tell the master why before
         * the connection is dropped (not after its own ERROR or BYE). */
        if (m.type != WIRE_ERROR && m.type != WIRE_BYE)
            chan_send_error(c->ch, rc == CT_ENOMEM || rc == CT_ESYS ? WIRE_ERR_INTERNAL : WIRE_ERR_PROTOCOL, err->msg,
                            200);
        return rc;
    }
    return 0;
}

/* Sends the cameras the render thread queued. */
static void send_queued(disp_client *c)
{
    wire_msg out[MAX_OUT];
    pthread_mutex_lock(&c->mu);
    int n = c->nout;
    memcpy(out, c->out, (size_t)n * sizeof *out);
    c->nout = 0;
    pthread_mutex_unlock(&c->mu);
    for (int i = 0; i < n; i++) send_or_keep(c, &out[i]);
}

static void *thread_main(void *arg)
{
    disp_client *c = arg;
    ct_error err;
    ct_error_clear(&err);
    uint64_t next_ping = ct_now_us(), heard = next_ping, heard_msgs = 0, heard_rx = 0;
    int pings = 0, rc = 0;
    bool more = false;   /* the last pump read bytes nobody has decoded yet */
    while (!atomic_load(&c->stop)) {
        uint64_t now = ct_now_us();
        int timeout = more ? 0 : c->send_rc ? 10 : next_ping > now ? (int)((next_ping - now) / 1000u) + 1 : 0;
        struct pollfd p[2] = {{chan_fd(c->ch), chan_events(c->ch), 0}, {c->wake[0], POLLIN, 0}};
        poll(p, 2, timeout);
        if (p[1].revents & POLLIN) {
            char buf[64];
            while (read(c->wake[0], buf, sizeof buf) > 0) {
            }
        }
        send_queued(c);
        now = ct_now_us();
        if (!c->send_rc && now >= next_ping) {
            wire_msg m = {.type = WIRE_PING};
            m.u.ping.token = now;
            send_or_keep(c, &m);
            next_ping = now + (++pings < PING_QUICK ? PING_FIRST_US : PING_EVERY_US);
        }
        if (c->send_rc && now > c->read_until) {
            rc = c->send_rc;
            err = c->send_err;
            break;
        }
        if ((rc = chan_pump(c->ch, &err))) break;
        uint64_t rx, tx;
        chan_byte_counts(c->ch, &rx, &tx);
        disp_inbox_bytes(c->inbox, rx);   /* before the messages it brought are visible */
        if ((rc = receive(c, &err))) break;
        /* ACKs go out at once; the same pump also reads, and what it read
         * must be decoded before the thread sleeps in poll, or a frame that
         * is complete in memory waits for the next ping. */
        if ((rc = chan_pump(c->ch, &err))) break;
        uint64_t rx2;
        chan_byte_counts(c->ch, &rx2, &tx);
        more = rx2 != rx;
        if (c->msgs_in != heard_msgs || rx2 - heard_rx >= PROGRESS_BYTES) {
            heard_msgs = c->msgs_in;
            heard_rx = rx2;
            heard = now;
        } else if (!c->send_rc && now - heard > 1000u * (uint64_t)c->silent_ms) {
            rc = ct_fail(&err, CT_EIO, "%s: the master completed no message for %.1f s, not even a PONG", c->addr,
                         c->silent_ms / 1000.0);
            break;
        }
    }
    if (rc) {
        pthread_mutex_lock(&c->mu);
        c->end_rc = rc;
        c->end_err = err;
        pthread_mutex_unlock(&c->mu);
    } else {
        /* Asked to stop: a BYE, briefly. */
        wire_msg m = {.type = WIRE_BYE};
        m.u.bye.reason = WIRE_BYE_QUIT;
        ct_error e;
        if (chan_send(c->ch, &m, &e) == 0) chan_flush(c->ch, 500, &e);
    }
    return NULL;
}
