/* xport_conn.c: the transport-independent part of connections and
 * listeners: non-blocking reads and writes on the socket (MSG_NOSIGNAL, so a
 * vanished peer is an error and never a SIGPIPE), waiting, and the dispatch
 * to the transport table (xport_ops). */
#include "proto/xport.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

struct xport_conn {
    const xport_ops *ops;
    int fd;
    size_t io_limit;
    char peer[XPORT_ADDR_LEN + 32];
};

struct xport_listener {
    const xport_ops *ops;
    xport_addr addr;
    int fd;
    char bound[XPORT_ADDR_LEN];
};

static int conn_new(const xport_ops *ops, int fd, const char *peer, xport_conn **out, ct_error *err)
{
    xport_conn *c = calloc(1, sizeof *c);
    if (!c) {
        close(fd);
        return ct_fail(err, CT_ENOMEM, "%s: out of memory for a connection", peer);
    }
    c->ops = ops;
    c->fd = fd;
    snprintf(c->peer, sizeof c->peer, "%s", peer);
    *out = c;
    return 0;
}

int xport_listen(const char *spec, xport_listener **out, ct_error *err)
{
    xport_addr a;
    int rc = xport_parse(spec, true, &a, err);
    if (rc) return rc;
    xport_listener *l = calloc(1, sizeof *l);
    if (!l) return ct_fail(err, CT_ENOMEM, "%s: out of memory for a listener", a.text);
    l->ops = xport_ops_for(a.kind);
    l->addr = a;
    rc = l->ops->listen(&a, &l->fd, l->bound, sizeof l->bound, err);
    if (rc) {
        free(l);
        return rc;
    }
    *out = l;
    return 0;
}

const char *xport_listener_addr(const xport_listener *l)
{
    return l->bound;
}

int xport_listener_fd(const xport_listener *l)
{
    return l->fd;
}

int xport_accept(xport_listener *l, xport_conn **out, ct_error *err)
{
    *out = NULL;
    for (;;) {
        int fd = accept4(l->fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd >= 0) {
            char peer[XPORT_ADDR_LEN + 32];
            l->ops->peer_name(&l->addr, fd, peer, sizeof peer);
            return conn_new(l->ops, fd, peer, out, err);
        }
        if (errno == EINTR) continue;
        /* A client that gave up before we accepted it is not our error. */
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ECONNABORTED || errno == EPROTO) return 0;
        return ct_fail(err, CT_EIO, "%s: accept: %s", l->bound, strerror(errno));
    }
}

void xport_listener_close(xport_listener *l)
{
    if (!l) return;
    close(l->fd);
    l->ops->unlisten(&l->addr);
    free(l);
}

int xport_connect(const char *spec, int timeout_ms, xport_conn **out, ct_error *err)
{
    xport_addr a;
    int rc = xport_parse(spec, false, &a, err);
    if (rc) return rc;
    const xport_ops *ops = xport_ops_for(a.kind);
    int fd;
    rc = ops->connect(&a, timeout_ms, &fd, err);
    if (rc) return rc;
    return conn_new(ops, fd, a.text, out, err);
}

int xport_read(xport_conn *c, void *buf, size_t cap, size_t *got, ct_error *err)
{
    *got = 0;
    if (c->io_limit && cap > c->io_limit) cap = c->io_limit;
    for (;;) {
        ssize_t n = recv(c->fd, buf, cap, 0);
        if (n > 0) {
            *got = (size_t)n;
            return 0;
        }
        if (n == 0) return cap ? XPORT_EOF : 0;
        if (errno == EINTR) continue;
        if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
        if (errno == ECONNRESET) return ct_fail(err, CT_EIO, "%s: connection reset by the peer", c->peer);
        return ct_fail(err, CT_EIO, "%s: read: %s", c->peer, strerror(errno));
    }
}

int xport_write(xport_conn *c, const void *buf, size_t len, size_t *sent, ct_error *err)
{
    *sent = 0;
    if (c->io_limit && len > c->io_limit) len = c->io_limit;
    while (len) {
        ssize_t n = send(c->fd, buf, len, MSG_NOSIGNAL);
        if (n > 0) {
            *sent = (size_t)n;
            return 0;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return 0;
        if (n < 0 && (errno == EPIPE || errno == ECONNRESET))
            return ct_fail(err, CT_EIO, "%s: the peer closed the connection", c->peer);
        return ct_fail(err, CT_EIO, "%s: write: %s", c->peer, strerror(n < 0 ? errno : EIO));
    }
    return 0;
}

int xport_writev(xport_conn *c, const struct iovec *iov, int n, size_t *sent, ct_error *err)
{
    *sent = 0;
    struct iovec cut[XPORT_IOV_MAX];
    if (n > XPORT_IOV_MAX) n = XPORT_IOV_MAX;
    size_t total = 0;
    int k = 0;
    /* The test cap (xport_set_io_limit) applies to the whole call. */
    for (; k < n; k++) {
        size_t len = iov[k].iov_len;
        if (c->io_limit && total + len > c->io_limit) len = c->io_limit - total;
        cut[k] = (struct iovec){iov[k].iov_base, len};
        total += len;
        if (c->io_limit && total >= c->io_limit) {
            k++;
            break;
        }
    }
    if (!total) return 0;
    struct msghdr mh = {.msg_iov = cut, .msg_iovlen = (size_t)k};
    for (;;) {
        ssize_t r = sendmsg(c->fd, &mh, MSG_NOSIGNAL);
        if (r > 0) {
            *sent = (size_t)r;
            return 0;
        }
        if (r < 0 && errno == EINTR) continue;
        if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return 0;
        if (r < 0 && (errno == EPIPE || errno == ECONNRESET))
            return ct_fail(err, CT_EIO, "%s: the peer closed the connection", c->peer);
        return ct_fail(err, CT_EIO, "%s: write: %s", c->peer, strerror(r < 0 ? errno : EIO));
    }
}

static long long now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (long long)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

int xport_wait(xport_conn *c, short events, int timeout_ms, ct_error *err)
{
    struct pollfd p = {c->fd, events, 0};
    long long deadline = timeout_ms < 0 ? 0 : now_ms() + timeout_ms;
    for (;;) {
        int left = timeout_ms < 0 ? -1 : (int)(deadline - now_ms());
        if (timeout_ms >= 0 && left < 0) left = 0;
        int r = poll(&p, 1, left);
        if (r > 0) return p.revents & (events | POLLHUP | POLLERR);
        if (r == 0) return 0;
        if (errno != EINTR) return ct_fail(err, CT_ESYS, "%s: poll: %s", c->peer, strerror(errno));
    }
}

int xport_write_all(xport_conn *c, const void *buf, size_t len, int timeout_ms, ct_error *err)
{
    const uint8_t *p = buf;
    long long deadline = timeout_ms < 0 ? 0 : now_ms() + timeout_ms;
    while (len) {
        size_t sent;
        int rc = xport_write(c, p, len, &sent, err);
        if (rc) return rc;
        p += sent;
        len -= sent;
        if (!len) break;
        if (sent == 0) {
            int left = timeout_ms < 0 ? -1 : (int)(deadline - now_ms());
            if (timeout_ms >= 0 && left <= 0)
                return ct_fail(err, CT_EIO, "%s: write timed out with %zu bytes unsent", c->peer, len);
            rc = xport_wait(c, POLLOUT, left, err);
            if (rc < 0) return rc;
        }
    }
    return 0;
}

const char *xport_peer(const xport_conn *c)
{
    return c->peer;
}

int xport_fd(const xport_conn *c)
{
    return c->fd;
}

const xport_ops *xport_conn_ops(const xport_conn *c)
{
    return c->ops;
}

void xport_set_io_limit(xport_conn *c, size_t max)
{
    c->io_limit = max;
}

void xport_close(xport_conn *c)
{
    if (!c) return;
    close(c->fd);
    free(c);
}
