/* xport_addr.c: parsing of transport addresses ("unix:PATH", "tcp:HOST:PORT",
 * "tcp:[v6]:PORT") with one-line errors that quote the address. */
#include "proto/xport.h"

#include <stdio.h>
#include <string.h>

static int parse_port(const char *spec, const char *p, bool for_listen, xport_addr *a, ct_error *err)
{
    size_t n = strlen(p);
    if (n == 0) return ct_fail(err, CT_EINVAL, "address '%s': missing port (expected tcp:HOST:PORT)", spec);
    if (n > 5) return ct_fail(err, CT_EINVAL, "address '%s': port '%s' out of range 1..65535", spec, p);
    unsigned v = 0;
    for (size_t i = 0; i < n; i++) {
        if (p[i] < '0' || p[i] > '9')
            return ct_fail(err, CT_EINVAL, "address '%s': port '%s' is not a number", spec, p);
        v = v * 10 + (unsigned)(p[i] - '0');
    }
    if (v > 65535 || (v == 0 && !for_listen))
        return ct_fail(err, CT_EINVAL, "address '%s': port %u out of range 1..65535", spec, v);
    snprintf(a->port, sizeof a->port, "%u", v);
    return 0;
}

int xport_parse(const char *spec, bool for_listen, xport_addr *a, ct_error *err)
{
    memset(a, 0, sizeof *a);
    if (!spec || !*spec)
        return ct_fail(err, CT_EINVAL, "address is empty (expected unix:PATH or tcp:HOST:PORT)");
    if (strlen(spec) >= XPORT_ADDR_LEN - 4)
        return ct_fail(err, CT_EINVAL, "address of %zu bytes is too long", strlen(spec));
    if (strncmp(spec, "unix:", 5) == 0) {
        const char *path = spec + 5;
        size_t n = strlen(path);
        if (n == 0) return ct_fail(err, CT_EINVAL, "address '%s': missing socket path (expected unix:PATH)", spec);
        if (n >= sizeof a->path)
            return ct_fail(err, CT_EINVAL, "address '%s': socket path is %zu bytes, the limit is %zu", spec, n,
                           sizeof a->path - 1);
        a->kind = XPORT_UNIX;
        memcpy(a->path, path, n + 1);
        snprintf(a->text, sizeof a->text, "unix:%s", a->path);
        return 0;
    }
    if (strncmp(spec, "tcp:", 4) == 0) {
        const char *h = spec + 4;
        const char *port;
        size_t hlen;
        if (*h == '[') {
            const char *close = strchr(h, ']');
            if (!close) return ct_fail(err, CT_EINVAL, "address '%s': missing ']' after the IPv6 address", spec);
            if (close[1] != ':')
                return ct_fail(err, CT_EINVAL, "address '%s': expected ':PORT' after ']'", spec);
            h++;
            hlen = (size_t)(close - h);
            port = close + 2;
            if (hlen == 0) return ct_fail(err, CT_EINVAL, "address '%s': empty IPv6 address", spec);
        } else {
            const char *colon = strrchr(h, ':');
            if (!colon) return ct_fail(err, CT_EINVAL, "address '%s': missing port (expected tcp:HOST:PORT)", spec);
            hlen = (size_t)(colon - h);
            port = colon + 1;
            if (memchr(h, ':', hlen))
                return ct_fail(err, CT_EINVAL, "address '%s': an IPv6 address needs brackets (tcp:[::1]:PORT)", spec);
            if (hlen == 0) return ct_fail(err, CT_EINVAL, "address '%s': missing host (expected tcp:HOST:PORT)", spec);
        }
        if (hlen >= sizeof a->host) return ct_fail(err, CT_EINVAL, "address '%s': host name too long", spec);
        memcpy(a->host, h, hlen);
        a->host[hlen] = '\0';
        if (strcmp(a->host, "*") == 0 && !for_listen)
            return ct_fail(err, CT_EINVAL, "address '%s': '*' (any address) is only for listening", spec);
        int rc = parse_port(spec, port, for_listen, a, err);
        if (rc) return rc;
        a->kind = XPORT_TCP;
        if (strchr(a->host, ':'))
            snprintf(a->text, sizeof a->text, "tcp:[%s]:%s", a->host, a->port);
        else
            snprintf(a->text, sizeof a->text, "tcp:%s:%s", a->host, a->port);
        return 0;
    }
    return ct_fail(err, CT_EINVAL, "address '%s': unknown scheme (expected unix:PATH or tcp:HOST:PORT)", spec);
}

const xport_ops *xport_ops_for(xport_kind kind)
{
    return kind == XPORT_UNIX ? &xport_unix_ops : kind == XPORT_TCP ? &xport_tcp_ops : NULL;
}
