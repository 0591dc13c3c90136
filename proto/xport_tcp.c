/* xport_tcp.c: the TCP transport, IPv4 and IPv6 through getaddrinfo. Nagle is
 * off (TCP_NODELAY) because camera messages are small and latency-bound. */
#include "proto/xport.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

static void name_of(const struct sockaddr *sa, char *out, size_t cap)
{
    char host[INET6_ADDRSTRLEN] = "?";
    unsigned port = 0;
    if (sa->sa_family == AF_INET) {
        const struct sockaddr_in *s = (const struct sockaddr_in *)(const void *)sa;
        inet_ntop(AF_INET, &s->sin_addr, host, sizeof host);
        port = ntohs(s->sin_port);
        snprintf(out, cap, "tcp:%s:%u", host, port);
    } else if (sa->sa_family == AF_INET6) {
        const struct sockaddr_in6 *s = (const struct sockaddr_in6 *)(const void *)sa;
        port = ntohs(s->sin6_port);
        if (IN6_IS_ADDR_V4MAPPED(&s->sin6_addr)) { /* an IPv4 peer on a dual-stack socket */
            inet_ntop(AF_INET, s->sin6_addr.s6_addr + 12, host, sizeof host);
            snprintf(out, cap, "tcp:%s:%u", host, port);
        } else {
            inet_ntop(AF_INET6, &s->sin6_addr, host, sizeof host);
            snprintf(out, cap, "tcp:[%s]:%u", host, port);
        }
    } else {
        snprintf(out, cap, "tcp:?");
    }
}

static int resolve(const xport_addr *a, bool passive, struct addrinfo **res, ct_error *err)
{
    struct addrinfo hints;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICSERV | (passive ? AI_PASSIVE : 0);
    const char *host = (passive && strcmp(a->host, "*") == 0) ? NULL : a->host;
    int rc = getaddrinfo(host, a->port, &hints, res);
    if (rc != 0)
        return ct_fail(err, CT_EIO, "%s: cannot resolve host '%s': %s", a->text, a->host, gai_strerror(rc));
    return 0;
}

/* Creates, binds and listens one socket; 0 or an errno. dual: an IPv6
 * socket that also accepts IPv4 (IPV6_V6ONLY off). */
static int try_listen(const struct addrinfo *ai, bool dual, int *out)
{
    int fd = socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, ai->ai_protocol);
    if (fd < 0) return errno;
    int one = 1, zero = 0;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (dual) setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &zero, sizeof zero);
    if (bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || listen(fd, 16) != 0) {
        int e = errno;
        close(fd);
        return e;
    }
    *out = fd;
    return 0;
}

static int tcp_listen(const xport_addr *a, int *out, char *bound, size_t cap, ct_error *err)
{
    struct addrinfo *res;
    int rc = resolve(a, true, &res, err);
    if (rc) return rc;
    /* For "*" try IPv6 first, dual-stack, so IPv4 and IPv6 displays both
     * reach one socket; then (or otherwise) the addresses in resolver order. */
    bool any = strcmp(a->host, "*") == 0;
    int last = EADDRNOTAVAIL, fd = -1;
    for (int pass = any ? 0 : 1; pass < 2 && fd < 0; pass++) {
        for (struct addrinfo *ai = res; ai && fd < 0; ai = ai->ai_next) {
            if (pass == 0 && ai->ai_family != AF_INET6) continue;
            int e = try_listen(ai, pass == 0, &fd);
            if (e) last = e;
        }
    }
    freeaddrinfo(res);
    if (fd < 0) return ct_fail(err, CT_EIO, "%s: cannot listen: %s", a->text, strerror(last));
    struct sockaddr_storage ss;
    socklen_t sl = sizeof ss;
    if (getsockname(fd, (struct sockaddr *)&ss, &sl) == 0)
        name_of((struct sockaddr *)&ss, bound, cap);
    else
        snprintf(bound, cap, "%s", a->text);
    *out = fd;
    return 0;
}

/* One non-blocking connect attempt within timeout_ms. Returns 0 or an errno. */
static int try_connect(const struct addrinfo *ai, int timeout_ms, int *out)
{
    int fd = socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, ai->ai_protocol);
    if (fd < 0) return errno;
    if (connect(fd, ai->ai_addr, ai->ai_addrlen) != 0) {
        if (errno != EINPROGRESS) {
            int e = errno;
            close(fd);
            return e;
        }
        struct pollfd p = {fd, POLLOUT, 0};
        int r;
        do r = poll(&p, 1, timeout_ms);
        while (r < 0 && errno == EINTR);
        if (r == 0) {
            close(fd);
            return ETIMEDOUT;
        }
        int soerr = 0;
        socklen_t sl = sizeof soerr;
        if (r < 0 || getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &sl) != 0 || soerr) {
            int e = r < 0 ? errno : soerr ? soerr : errno;
            close(fd);
            return e;
        }
    }
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    *out = fd;
    return 0;
}

static int tcp_connect(const xport_addr *a, int timeout_ms, int *out, ct_error *err)
{
    struct addrinfo *res;
    int rc = resolve(a, false, &res, err);
    if (rc) return rc;
    int e = EADDRNOTAVAIL;
    for (struct addrinfo *ai = res; ai; ai = ai->ai_next) {
        e = try_connect(ai, timeout_ms, out);
        if (e == 0) {
            freeaddrinfo(res);
            return 0;
        }
    }
    freeaddrinfo(res);
    return ct_fail(err, CT_EIO, "%s: connect: %s", a->text, strerror(e));
}

static void tcp_peer_name(const xport_addr *listen_addr, int fd, char *out, size_t cap)
{
    struct sockaddr_storage ss;
    socklen_t sl = sizeof ss;
    if (getpeername(fd, (struct sockaddr *)&ss, &sl) == 0)
        name_of((struct sockaddr *)&ss, out, cap);
    else
        snprintf(out, cap, "%s (peer)", listen_addr->text);
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
}

static void tcp_unlisten(const xport_addr *a)
{
    (void)a;
}

const xport_ops xport_tcp_ops = {
    .scheme = "tcp",
    .needs_auth = true,
    .listen = tcp_listen,
    .connect = tcp_connect,
    .peer_name = tcp_peer_name,
    .unlisten = tcp_unlisten,
};
