/* chan.h: one framed, authenticated connection of the display socket
 * protocol: a transport connection (xport.h), the handshake (auth.h), the
 * incremental decoder and the merging send queue (wire.h, xport.h) put
 * together. Everything is non-blocking: call chan_pump() when poll() reports
 * the descriptor ready (chan_events() says for what), or use the blocking
 * helpers. The master and the display use this and never see a socket. */
#ifndef CT_PROTO_CHAN_H
#define CT_PROTO_CHAN_H

#include <stdbool.h>
#include <stddef.h>

#include "common/error.h"
#include "proto/auth.h"
#include "proto/wire.h"
#include "proto/xport.h"

#define CHAN_DEFAULT_QUEUE_BYTES (64u << 20)  /* send queue bound */
#define CHAN_HANDSHAKE_TIMEOUT_MS 10000

typedef struct chan chan;

typedef struct chan_config {
    auth_role role;
    const auth_token *token;   /* NULL: none (then TCP fails the handshake) */
    bool require_auth;         /* display: refuse a master that does not authenticate, also on
                                * UNIX (always on TCP). A master authenticates whenever it has
                                * a token, and refuses TCP without one. */
    size_t queue_bytes;        /* 0: CHAN_DEFAULT_QUEUE_BYTES */
    int handshake_ms;          /* deadline of the handshake; 0: CHAN_HANDSHAKE_TIMEOUT_MS */
} chan_config;

/* Wraps a connected transport (ownership passes to the channel, also on
 * failure) and starts the handshake. */
int chan_new(xport_conn *conn, const chan_config *cfg, chan **out, ct_error *err);

/* Display side in one call: connects to spec ("unix:PATH", "tcp:HOST:PORT"),
 * starts the channel and completes the handshake, all within timeout_ms. */
int chan_connect(const char *spec, const chan_config *cfg, int timeout_ms, chan **out, ct_error *err);

/* Master side: accepts one pending connection from l and starts its
 * handshake (non-blocking); *out = NULL (and 0) when none is pending. */
int chan_accept(xport_listener *l, const chan_config *cfg, chan **out, ct_error *err);

/* Closes the connection and frees everything (NULL is fine). */
void chan_free(chan *c);

/* Reads what the socket has and writes what the queue holds, without
 * blocking; advances the handshake. 0, or a negative error (handshake
 * failure or timeout, a local failure). A lost connection is not reported
 * here but by chan_recv, after every message that arrived before it. */
int chan_pump(chan *c, ct_error *err);

/* Whether the handshake is complete (messages may flow). */
bool chan_ready(const chan *c);

/* The next received message: WIRE_OK, WIRE_NEED_MORE, or a negative error
 * (sticky; CT_EIO "closed" naming whether the peer left mid-message). A
 * received ERROR is returned as a message (the caller shows its text). */
int chan_recv(chan *c, wire_msg *out, ct_error *err);

/* Queues a message (allowed before the handshake ends: it is sent after it).
 * 0, XPORT_QUEUE_FULL, or a negative error. Call chan_pump to send. */
int chan_send(chan *c, const wire_msg *m, ct_error *err);

/* The send queue's tail for encoders that write whole frames in place
 * (wire_encode_patch), then chan_commit(frames). NULL, with err filled, when
 * the channel failed or its peer is gone. */
wire_buf *chan_tail(chan *c, ct_error *err);
void chan_commit(chan *c, uint64_t frames);

/* Sends an ERROR (best effort, within timeout_ms) before the caller closes:
 * 0 when it went out whole, -1 when not (the rest of a half-sent frame or
 * the ERROR itself did not fit the peer's socket in time; then nothing of
 * it was written inside a frame). */
int chan_send_error(chan *c, uint32_t code, const char *text, int timeout_ms);

/* poll() events the channel waits for: POLLIN, plus POLLOUT while bytes are queued. */
short chan_events(const chan *c);

/* The socket, for poll(). */
int chan_fd(const chan *c);

/* The peer's address, for messages. */
const char *chan_peer(const chan *c);

/* The send queue's counters. */
xport_queue_stats chan_queue_stats(const chan *c);

/* Total bytes received / sent on the connection. */
void chan_byte_counts(const chan *c, uint64_t *received, uint64_t *sent);

/* Blocking: pumps until the handshake completes (error after timeout_ms). */
int chan_handshake(chan *c, int timeout_ms, ct_error *err);

/* Blocking: pumps until the send queue is empty (error after timeout_ms). */
int chan_flush(chan *c, int timeout_ms, ct_error *err);

/* Blocking: waits up to timeout_ms for the next message; WIRE_OK,
 * WIRE_NEED_MORE on timeout, or a negative error. */
int chan_recv_wait(chan *c, wire_msg *out, int timeout_ms, ct_error *err);

/* The transport connection (for tests: xport_set_io_limit). */
xport_conn *chan_conn(chan *c);

#endif
