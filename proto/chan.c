/* chan.c: a framed, authenticated connection (chan.h). Application messages
 * queued before the handshake completes stay in the queue until it has: no
 * byte of them reaches an unauthenticated peer. */
#include "proto/chan.h"

#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define READ_CHUNK      65536u
#define READ_BACKLOG    (8u << 20)   /* stop reading while this much is undecoded */

struct chan {
    xport_conn *conn;
    auth_hs *hs;             /* NULL once the handshake is done */
    wire_decoder *dec;
    xport_queue *q;
    bool ready;
    int error;               /* sticky error (handshake, decode, local) */
    ct_error last;
    bool closed;             /* the connection is gone (EOF, read or write failure) */
    bool rd_closed;          /* reading ended: nothing more will arrive */
    ct_error closed_why;
    long long t_start;
    int handshake_ms;
    uint64_t rx, tx;
    uint8_t rbuf[READ_CHUNK];
};

static long long now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (long long)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

int chan_new(xport_conn *conn, const chan_config *cfg, chan **out, ct_error *err)
{
    const char *peer = xport_peer(conn);
    chan *c = calloc(1, sizeof *c);
    if (!c) {
        xport_close(conn);
        return ct_fail(err, CT_ENOMEM, "%s: out of memory for a channel", peer);
    }
    c->conn = conn;
    c->t_start = now_ms();
    c->handshake_ms = cfg->handshake_ms > 0 ? cfg->handshake_ms : CHAN_HANDSHAKE_TIMEOUT_MS;
    auth_config ac = {
        .role = cfg->role,
        .token = cfg->token,
        /* A master with a token always demands it; TCP always needs one. */
        .require_auth = cfg->require_auth || xport_conn_ops(conn)->needs_auth ||
                        (cfg->role == AUTH_ROLE_MASTER && cfg->token),
        .peer = peer,
        .build_id = NULL,
    };
    int rc;
    if (cfg->role == AUTH_ROLE_MASTER && ac.require_auth && !cfg->token)
        rc = ct_fail(err, CT_EAUTH, "%s: %s connections require a token (--token-file or %s)", peer,
                     xport_conn_ops(conn)->scheme, AUTH_TOKEN_ENV);
    else if ((rc = auth_hs_new(&ac, &c->hs, err)) == 0 && (rc = wire_decoder_new(peer, &c->dec, err)) == 0)
        rc = xport_queue_new(cfg->queue_bytes ? cfg->queue_bytes : CHAN_DEFAULT_QUEUE_BYTES, &c->q, err);
    if (rc) {
        chan_free(c);
        return rc;
    }
    *out = c;
    return 0;
}

void chan_free(chan *c)
{
    if (!c) return;
    auth_hs_free(c->hs);
    wire_decoder_free(c->dec);
    xport_queue_free(c->q);
    xport_close(c->conn);
    free(c);
}

static int fail(chan *c, int rc, ct_error *err)
{
    c->error = rc;
    if (err) c->last = *err;
    return rc;
}

/* A write failure marks the connection closed, but reading goes on: what the
 * peer sent before it left is still delivered. */
static void mark_closed(chan *c, const ct_error *why, bool reading)
{
    if (reading) c->rd_closed = true;
    if (!c->closed || reading) c->closed_why = *why;
    c->closed = true;
}

/* Writes as much of data as the socket takes; false when it failed. */
static bool write_some(chan *c, const uint8_t *data, size_t len, size_t *sent)
{
    ct_error e;
    *sent = 0;
    if (xport_write(c->conn, data, len, sent, &e) != 0) {
        mark_closed(c, &e, false);
        return false;
    }
    c->tx += *sent;
    return true;
}

static int pump_write(chan *c, ct_error *err)
{
    if (c->closed) return 0;
    if (c->hs) {
        wire_buf *o = auth_hs_output(c->hs);
        size_t sent;
        if (o->len && write_some(c, o->data, o->len, &sent)) wire_buf_consume(o, sent);
        return 0;
    }
    (void)err;
    for (;;) {
        struct iovec iov[XPORT_IOV_MAX];
        int n = xport_queue_iov(c->q, iov, XPORT_IOV_MAX);
        if (!n) return 0;
        size_t want = 0, sent;
        for (int i = 0; i < n; i++) want += iov[i].iov_len;
        ct_error e;
        if (xport_writev(c->conn, iov, n, &sent, &e) != 0) {
            mark_closed(c, &e, false);
            return 0;
        }
        c->tx += sent;
        xport_queue_advance(c->q, sent);
        if (sent < want) return 0;
    }
}

/* Feeds received bytes to the handshake, then the rest to the decoder. */
static int take_bytes(chan *c, const uint8_t *d, size_t n, ct_error *err)
{
    if (c->hs) {
        size_t used;
        int rc = auth_hs_input(c->hs, d, n, &used, err);
        if (rc < 0) {
            /* Best effort, briefly: let the peer read why (the hs queued an ERROR). */
            wire_buf *o = auth_hs_output(c->hs);
            if (o->len && !c->closed && xport_write_all(c->conn, o->data, o->len, 200, NULL) == 0)
                wire_buf_consume(o, o->len);
            return fail(c, rc, err);
        }
        if (rc == WIRE_NEED_MORE) return 0;
        /* Done: flush the rest of our handshake bytes (e.g. our AUTH) before any message. */
        wire_buf *o = auth_hs_output(c->hs);
        if (o->len && !c->closed) {
            ct_error e;
            if (xport_write_all(c->conn, o->data, o->len, 2000, &e) != 0) mark_closed(c, &e, false);
            else c->tx += o->len;
        }
        auth_hs_free(c->hs);
        c->hs = NULL;
        c->ready = true;
        d += used;
        n -= used;
    }
    if (n) {
        int rc = wire_decoder_feed(c->dec, d, n, err);
        if (rc) return fail(c, rc, err);
    }
    return 0;
}

static int pump_read(chan *c, ct_error *err)
{
    for (int i = 0; i < 16 && !c->rd_closed; i++) {
        if (!c->hs && wire_decoder_pending(c->dec) >= READ_BACKLOG) return 0; /* let the caller catch up */
        size_t got;
        ct_error e;
        int rc = xport_read(c->conn, c->rbuf, sizeof c->rbuf, &got, &e);
        if (rc == XPORT_EOF) {
            ct_fail(&e, CT_EIO, "%s: the peer closed the connection", xport_peer(c->conn));
            mark_closed(c, &e, true);
            break;
        }
        if (rc < 0) {
            mark_closed(c, &e, true);
            break;
        }
        if (got == 0) break;
        c->rx += got;
        rc = take_bytes(c, c->rbuf, got, err);
        if (rc) return rc;
    }
    if (c->hs && c->rd_closed) {
        ct_fail(err, CT_EIO, "%s: connection closed during the handshake (%s)", xport_peer(c->conn),
                c->closed_why.msg);
        return fail(c, CT_EIO, err);
    }
    return 0;
}

int chan_pump(chan *c, ct_error *err)
{
    ct_error local;
    if (!err) err = &local;
    if (c->error) {
        *err = c->last;
        return c->error;
    }
    int rc = pump_write(c, err);
    if (rc) return rc;
    rc = pump_read(c, err);
    if (rc) return rc;
    rc = pump_write(c, err); /* the handshake may have finished: send queued messages */
    if (rc) return rc;
    if (c->hs && now_ms() - c->t_start > c->handshake_ms) {
        ct_fail(err, CT_EPROTO, "%s: handshake not completed within %d ms", xport_peer(c->conn), c->handshake_ms);
        return fail(c, CT_EPROTO, err);
    }
    return 0;
}

bool chan_ready(const chan *c)
{
    return c->ready && !c->error;
}

int chan_recv(chan *c, wire_msg *out, ct_error *err)
{
    ct_error local;
    if (!err) err = &local;
    if (c->error) {
        *err = c->last;
        return c->error;
    }
    if (!c->ready) return WIRE_NEED_MORE;
    int rc = wire_decoder_next(c->dec, out, err);
    if (rc < 0) return fail(c, rc, err);
    if (rc == WIRE_OK) return WIRE_OK;
    if (c->rd_closed) {
        size_t pend = wire_decoder_pending(c->dec);
        if (pend)
            ct_fail(err, CT_EIO, "%s: connection closed in the middle of a message (%zu of %zu bytes received)",
                    xport_peer(c->conn), pend, wire_decoder_frame_size(c->dec));
        else
            *err = c->closed_why;
        return fail(c, CT_EIO, err);
    }
    return WIRE_NEED_MORE;
}

int chan_send(chan *c, const wire_msg *m, ct_error *err)
{
    if (c->error) {
        if (err) *err = c->last;
        return c->error;
    }
    if (c->closed) {
        if (err) *err = c->closed_why;
        return CT_EIO;
    }
    return xport_queue_push(c->q, m, err);
}

wire_buf *chan_tail(chan *c, ct_error *err)
{
    if (c->error || c->closed) {
        if (err) *err = c->error ? c->last : c->closed_why;
        return NULL;
    }
    return xport_queue_tail(c->q, err);
}

void chan_commit(chan *c, uint64_t frames)
{
    xport_queue_commit(c->q, frames);
}

int chan_send_error(chan *c, uint32_t code, const char *text, int timeout_ms)
{
    wire_msg m;
    wire_buf b = {0};
    wire_make_error(&m, code, text);
    if (c->closed || wire_encode(&m, &b, NULL) != 0) {
        wire_buf_free(&b);
        return -1;
    }
    /* Written directly, after the rest of a frame that is half sent, so
     * framing stays intact and the ERROR comes early; when that rest does
     * not go out in time, the ERROR would land inside the frame: not sent. */
    int rc = 0;
    if (c->ready) {
        size_t left = xport_queue_partial(c->q);
        struct iovec iov[1];
        if (left) {
            rc = xport_queue_iov(c->q, iov, 1) == 1 && iov[0].iov_len >= left &&
                         xport_write_all(c->conn, iov[0].iov_base, left, timeout_ms, NULL) == 0
                     ? 0
                     : -1;
            if (!rc) xport_queue_advance(c->q, left);
        }
    } else if (c->hs) {
        wire_buf *o = auth_hs_output(c->hs);
        if (o->len) {
            rc = xport_write_all(c->conn, o->data, o->len, timeout_ms, NULL) == 0 ? 0 : -1;
            if (!rc) wire_buf_consume(o, o->len);
        }
    }
    if (!rc) rc = xport_write_all(c->conn, b.data, b.len, timeout_ms, NULL) == 0 ? 0 : -1;
    wire_buf_free(&b);
    return rc;
}

short chan_events(const chan *c)
{
    short ev = POLLIN;
    bool pending = c->hs ? auth_hs_output(c->hs)->len > 0 : (c->ready && !xport_queue_empty(c->q));
    if (pending && !c->closed) ev |= POLLOUT;
    return ev;
}

int chan_fd(const chan *c)
{
    return xport_fd(c->conn);
}

const char *chan_peer(const chan *c)
{
    return xport_peer(c->conn);
}

xport_queue_stats chan_queue_stats(const chan *c)
{
    return xport_queue_get_stats(c->q);
}

void chan_byte_counts(const chan *c, uint64_t *received, uint64_t *sent)
{
    *received = c->rx;
    *sent = c->tx;
}

xport_conn *chan_conn(chan *c)
{
    return c->conn;
}

/* Waits for the socket per chan_events until the deadline; false on timeout. */
static int wait_ready(chan *c, long long deadline, ct_error *err)
{
    long long left = deadline < 0 ? -1 : deadline - now_ms();
    if (deadline >= 0 && left <= 0) return 0;
    return xport_wait(c->conn, chan_events(c), (int)left, err);
}

int chan_handshake(chan *c, int timeout_ms, ct_error *err)
{
    long long deadline = timeout_ms < 0 ? -1 : now_ms() + timeout_ms;
    for (;;) {
        int rc = chan_pump(c, err);
        if (rc) return rc;
        if (c->ready) return 0;
        rc = wait_ready(c, deadline, err);
        if (rc < 0) return rc;
        if (rc == 0)
            return ct_fail(err, CT_EIO, "%s: handshake timed out after %d ms", xport_peer(c->conn), timeout_ms);
    }
}

int chan_flush(chan *c, int timeout_ms, ct_error *err)
{
    long long deadline = timeout_ms < 0 ? -1 : now_ms() + timeout_ms;
    for (;;) {
        int rc = chan_pump(c, err);
        if (rc) return rc;
        if (c->ready && xport_queue_empty(c->q)) return 0;
        if (c->closed) {
            if (err) *err = c->closed_why;
            return CT_EIO;
        }
        rc = wait_ready(c, deadline, err);
        if (rc < 0) return rc;
        if (rc == 0)
            return ct_fail(err, CT_EIO, "%s: send timed out after %d ms", xport_peer(c->conn), timeout_ms);
    }
}

int chan_recv_wait(chan *c, wire_msg *out, int timeout_ms, ct_error *err)
{
    long long deadline = timeout_ms < 0 ? -1 : now_ms() + timeout_ms;
    for (;;) {
        int rc = chan_recv(c, out, err);
        if (rc != WIRE_NEED_MORE) return rc;
        rc = chan_pump(c, err);
        if (rc) return rc;
        rc = chan_recv(c, out, err);
        if (rc != WIRE_NEED_MORE) return rc;
        rc = wait_ready(c, deadline, err);
        if (rc < 0) return rc;
        if (rc == 0) return WIRE_NEED_MORE;
    }
}

int chan_connect(const char *spec, const chan_config *cfg, int timeout_ms, chan **out, ct_error *err)
{
    long long deadline = timeout_ms < 0 ? -1 : now_ms() + timeout_ms;
    xport_conn *conn;
    int rc = xport_connect(spec, timeout_ms, &conn, err);
    if (rc) return rc;
    chan *c;
    rc = chan_new(conn, cfg, &c, err);
    if (rc) return rc;
    int left = deadline < 0 ? -1 : (int)(deadline - now_ms());
    if (deadline >= 0 && left < 1) left = 1;
    rc = chan_handshake(c, left, err);
    if (rc) {
        chan_free(c);
        return rc;
    }
    *out = c;
    return 0;
}

int chan_accept(xport_listener *l, const chan_config *cfg, chan **out, ct_error *err)
{
    *out = NULL;
    xport_conn *conn;
    int rc = xport_accept(l, &conn, err);
    if (rc || !conn) return rc;
    return chan_new(conn, cfg, out, err);
}
