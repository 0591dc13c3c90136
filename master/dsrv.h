/* dsrv.h: the master's display server: listens on a UNIX socket (default,
 * mode 0600) or TCP (token required), runs every connection's handshake in
 * parallel without blocking, serves one display at a time and refuses a
 * second one with an ERROR saying why, drops misbehaving peers (garbage,
 * oversized lengths, wrong token, handshake timeout) with a log line while
 * the active display goes on undisturbed, and turns the active display's
 * messages into events for the scheduling loop. Owns the dsrv_ prefix. */
#ifndef CT_MASTER_DSRV_H
#define CT_MASTER_DSRV_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/error.h"
#include "proto/auth.h"
#include "proto/wire.h"

/* Connections in handshake at once, and of those from one peer address (a
 * TCP host, a local process). A newcomer beyond either bound takes the place
 * of the oldest connection there that has not authenticated (one that has
 * sent nothing first), so idle connections cannot lock a display out; only
 * when all of them have authenticated is the newcomer refused. */
#define DSRV_MAX_PENDING 16
#define DSRV_MAX_PENDING_PER_PEER 4

typedef struct dsrv dsrv;

typedef struct dsrv_config {
    const char *listen;          /* "unix:PATH" or "tcp:HOST:PORT" */
    const auth_token *token;     /* NULL: none (then TCP is refused at start) */
    int handshake_timeout_ms;    /* a peer must finish HELLO/AUTH/SETTINGS within this */
    size_t queue_bytes;          /* send queue bound of the display connection */
} dsrv_config;

typedef enum dsrv_event_kind {
    DSRV_EV_CONNECTED = 1,     /* a display finished its handshake and sent SETTINGS */
    DSRV_EV_MESSAGE = 2,       /* a message from the display (CAMERA, ...) */
    DSRV_EV_DISCONNECTED = 3   /* the display left (reason in text) */
} dsrv_event_kind;

typedef struct dsrv_event {
    dsrv_event_kind kind;
    wire_msg msg;                /* CONNECTED: the SETTINGS; MESSAGE: the message */
    char text[CT_ERROR_LEN];     /* DISCONNECTED: why */
} dsrv_event;

/* The default listen address: unix:$XDG_RUNTIME_DIR/corrtex-<pid>.sock, or
 * /tmp when XDG_RUNTIME_DIR is not set. */
void dsrv_default_listen(char *out, size_t cap);

/* Fails as dsrv_new would on the configuration alone (an address that does
 * not parse, TCP without a token): a program checks it before expensive
 * work (corrtex-render: before the radiosity solve). */
int dsrv_check_config(const dsrv_config *cfg, ct_error *err);

/* Starts listening (a UNIX socket file gets mode 0600). TCP without a token
 * fails: the socket would be open to anyone who can reach the port. */
int dsrv_new(const dsrv_config *cfg, dsrv **out, ct_error *err);

/* Closes every connection and the listener (removing a UNIX socket file). */
void dsrv_free(dsrv *s);

/* The address actually bound ("tcp:127.0.0.1:40123"). */
const char *dsrv_addr(const dsrv *s);

/* Waits up to timeout_ms for socket activity, then accepts, advances
 * handshakes, reads and writes. Events are queued for dsrv_next_event. */
int dsrv_step(dsrv *s, int timeout_ms, ct_error *err);

/* The next event (1), or 0 when none is queued. */
int dsrv_next_event(dsrv *s, dsrv_event *ev);

/* Whether an event other than an ACK is queued (a camera, settings, a
 * display that came or went): what may change the view when taken. */
bool dsrv_view_pending(const dsrv *s);

/* Whether a display is connected (after its SETTINGS). */
bool dsrv_has_display(const dsrv *s);

/* Seconds (ct_now's clock) since the display's last received byte, as far
 * as the caller's calls can tell: a display sends a PING a second, so a
 * long silence is a stopped process or a vanished host (0 without one). */
double dsrv_silent_s(dsrv *s, double now);

/* The display's address (for logs), "" when none. */
const char *dsrv_peer(const dsrv *s);

/* Queues a message to the display (nothing when none is connected). When the
 * send queue is full it writes (blocking up to timeout_ms) until there is
 * room; a display that does not read for that long is dropped. */
int dsrv_send(dsrv *s, const wire_msg *m, int timeout_ms, ct_error *err);

/* dsrv_try_send: the message was not queued. */
#define DSRV_DROPPED 1

/* Queues a droppable message (SAMPLES) without ever blocking: only when the
 * display's send queue holds at most max_queued bytes and has room, so it
 * never delays texture updates. 0 when queued (or no display is
 * connected), DSRV_DROPPED when not. */
int dsrv_try_send(dsrv *s, const wire_msg *m, size_t max_queued);

/* The display's send queue tail for frames encoded in place (chan_tail),
 * then dsrv_commit(frames). NULL when no display is connected (or it just
 * failed: it is dropped). */
wire_buf *dsrv_tail(dsrv *s);
void dsrv_commit(dsrv *s, uint64_t frames);

/* Bytes queued to the display and not yet written (0 without a display). */
size_t dsrv_queued(const dsrv *s);
/* Bytes written to the display's socket since it connected (0: none). */
uint64_t dsrv_written(const dsrv *s);

/* Bytes sent to displays since the start. */
uint64_t dsrv_bytes_sent(const dsrv *s);

/* CPU seconds dsrv_step spent in the display's socket reads and writes
 * since the start (not in waiting for it). */
double dsrv_io_seconds(const dsrv *s);

/* Drops the display after a best-effort ERROR (code, text), with a log
 * line naming it and the text (a warning; information for
 * WIRE_ERR_INTERNAL, the master's own end, which its caller explains); true
 * when the ERROR went out whole (chan_send_error), false when not or when
 * no display was there. */
bool dsrv_drop(dsrv *s, uint32_t code, const char *text);

/* Sends BYE (reason) to the display and flushes within timeout_ms. */
void dsrv_bye(dsrv *s, uint32_t reason, int timeout_ms);

#endif
