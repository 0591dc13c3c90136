/* xport.h: byte transports for the display socket: UNIX (`unix:PATH`) and
 * TCP (`tcp:HOST:PORT`, IPv4 and IPv6, `tcp:[::1]:PORT`), behind one table of
 * functions (xport_ops) so callers never know which one they use. Sockets are
 * non-blocking, close-on-exec, and never raise SIGPIPE (MSG_NOSIGNAL). Also
 * the bounded send queue of encoded frames, written by offset with writev
 * (xport_queue_*; what goes into it and when is the callers' flow control,
 * docs/protocol.md). Errors name the address and the problem in one line. */
#ifndef CT_PROTO_XPORT_H
#define CT_PROTO_XPORT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <sys/uio.h>

#include "common/error.h"
#include "proto/wire.h"

#define XPORT_ADDR_LEN 300
#define XPORT_IOV_MAX  64     /* iovecs one xport_writev call passes on */

typedef enum xport_kind {
    XPORT_UNIX = 1,
    XPORT_TCP  = 2
} xport_kind;

/* A parsed address. */
typedef struct xport_addr {
    xport_kind kind;
    char path[108];            /* UNIX: socket path (sun_path size) */
    char host[256];            /* TCP: name or literal, without brackets; "" or "*" = any */
    char port[8];              /* TCP: decimal port */
    char text[XPORT_ADDR_LEN]; /* canonical "unix:PATH" / "tcp:HOST:PORT" */
} xport_addr;

/* What one transport implements (xport_unix.c, xport_tcp.c). */
typedef struct xport_ops {
    const char *scheme;     /* "unix" or "tcp" */
    bool needs_auth;        /* TCP: yes; UNIX: the socket file's mode protects it */
    /* Creates a listening socket; writes the bound address ("tcp:127.0.0.1:40123"). */
    int (*listen)(const xport_addr *a, int *fd, char *bound, size_t cap, ct_error *err);
    /* Connects within timeout_ms (< 0: no limit); the socket is non-blocking. */
    int (*connect)(const xport_addr *a, int timeout_ms, int *fd, ct_error *err);
    /* Names an accepted peer ("tcp:[::1]:5123", "unix:PATH (pid N)") and sets
     * its socket options (TCP_NODELAY). */
    void (*peer_name)(const xport_addr *listen_addr, int fd, char *out, size_t cap);
    /* Cleans up after a listener (UNIX: unlinks the socket file). */
    void (*unlisten)(const xport_addr *a);
} xport_ops;

extern const xport_ops xport_unix_ops;
extern const xport_ops xport_tcp_ops;

typedef struct xport_conn xport_conn;
typedef struct xport_listener xport_listener;

enum {
    XPORT_EOF        = 1,  /* xport_read: the peer closed the connection */
    XPORT_QUEUE_FULL = 1   /* xport_queue_push / chan_send: no room now, retry later */
};

/* Parses "unix:PATH" or "tcp:HOST:PORT" ("tcp:[v6]:PORT"); for_listen allows
 * port 0 and the host "*" (any address). */
int xport_parse(const char *spec, bool for_listen, xport_addr *a, ct_error *err);

/* The operations for an address kind. */
const xport_ops *xport_ops_for(xport_kind kind);

/* Listens on spec. */
int xport_listen(const char *spec, xport_listener **out, ct_error *err);
/* The address actually bound (port 0 resolved). */
const char *xport_listener_addr(const xport_listener *l);
/* Its file descriptor, for poll(). */
int xport_listener_fd(const xport_listener *l);
/* Accepts one pending connection; *out = NULL (and 0) when none is pending. */
int xport_accept(xport_listener *l, xport_conn **out, ct_error *err);
/* Closes the listener (and removes a UNIX socket file). */
void xport_listener_close(xport_listener *l);

/* Connects to spec within timeout_ms. */
int xport_connect(const char *spec, int timeout_ms, xport_conn **out, ct_error *err);
/* Reads up to cap bytes: 0 with *got = 0 when nothing is available now,
 * XPORT_EOF when the peer closed, negative on error. */
int xport_read(xport_conn *c, void *buf, size_t cap, size_t *got, ct_error *err);
/* Writes up to len bytes: 0 with *sent <= len (0 when the socket is full),
 * negative on error (a closed peer included). */
int xport_write(xport_conn *c, const void *buf, size_t len, size_t *sent, ct_error *err);
/* xport_write of n buffers in one call (at most XPORT_IOV_MAX). */
int xport_writev(xport_conn *c, const struct iovec *iov, int n, size_t *sent, ct_error *err);
/* Writes all len bytes, waiting for the socket as needed, within timeout_ms. */
int xport_write_all(xport_conn *c, const void *buf, size_t len, int timeout_ms, ct_error *err);
/* Waits until the socket is readable (POLLIN) / writable (POLLOUT) per events;
 * returns the ready events (0 on timeout) or a negative error. */
int xport_wait(xport_conn *c, short events, int timeout_ms, ct_error *err);
/* The peer's address. */
const char *xport_peer(const xport_conn *c);
/* The socket, for poll(). */
int xport_fd(const xport_conn *c);
/* The transport's operations (needs_auth, scheme). */
const xport_ops *xport_conn_ops(const xport_conn *c);
/* Caps every read and write call at max bytes (0 = no cap): exercises
 * partial I/O in tests and slow-link behaviour. */
void xport_set_io_limit(xport_conn *c, size_t max);
/* Closes the connection (NULL is fine). */
void xport_close(xport_conn *c);

/* --- the send queue ---------------------------------------------------------- */

/* Encoded frames in the order they are to be written, in a list of
 * segments that are appended to and written from by offset: nothing is
 * moved or copied after encoding, and a write takes several frames at once. */
typedef struct xport_queue xport_queue;

typedef struct xport_queue_stats {
    size_t bytes;          /* bytes queued and not yet written */
    uint64_t pushed;       /* frames accepted since creation */
    uint64_t written;      /* bytes written since creation */
} xport_queue_stats;

/* A queue holding at most max_bytes (one frame is always accepted when empty). */
int xport_queue_new(size_t max_bytes, xport_queue **out, ct_error *err);
/* Frees it. */
void xport_queue_free(xport_queue *q);
/* Encodes m at the tail: 0, XPORT_QUEUE_FULL (nothing queued, retry later),
 * or a negative error. */
int xport_queue_push(xport_queue *q, const wire_msg *m, ct_error *err);
/* The buffer whole frames are appended to by encoders that write in place
 * (wire_encode_patch); xport_queue_commit counts what was appended. Only
 * whole frames may be appended between the two calls; the bound is the
 * caller's to keep (xport_queue_get_stats). */
wire_buf *xport_queue_tail(xport_queue *q, ct_error *err);
void xport_queue_commit(xport_queue *q, uint64_t frames);
/* Up to max iovecs of the unwritten bytes, oldest first; returns their count. */
int xport_queue_iov(const xport_queue *q, struct iovec *iov, int max);
/* Marks n bytes (from the head) as written. */
void xport_queue_advance(xport_queue *q, size_t n);
/* Bytes left of a frame whose first bytes are written: 0 at a frame boundary. */
size_t xport_queue_partial(const xport_queue *q);
/* Whether anything is left to write. */
bool xport_queue_empty(const xport_queue *q);
/* Counters. */
xport_queue_stats xport_queue_get_stats(const xport_queue *q);

#endif
