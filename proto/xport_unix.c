/* xport_unix.c: the UNIX-domain stream socket transport. The socket file is
 * created with mode 0600 (only the owner may connect), which is why
 * authentication is optional here; a stale socket file left by a dead master
 * is replaced, a live one is not. */
#include "proto/xport.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

static void fill(const xport_addr *a, struct sockaddr_un *sa)
{
    memset(sa, 0, sizeof *sa);
    sa->sun_family = AF_UNIX;
    memcpy(sa->sun_path, a->path, strlen(a->path) + 1); /* length checked by xport_parse */
}

/* True when something accepts connections on the socket file. */
static bool alive(const struct sockaddr_un *sa)
{
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return true; /* be conservative: do not remove it */
    int rc = connect(fd, (const struct sockaddr *)sa, sizeof *sa);
    int e = errno;
    close(fd);
    return rc == 0 || e != ECONNREFUSED;
}

static int unix_listen(const xport_addr *a, int *out, char *bound, size_t cap, ct_error *err)
{
    struct sockaddr_un sa;
    fill(a, &sa);
    struct stat st;
    if (lstat(a->path, &st) == 0) {
        if (!S_ISSOCK(st.st_mode))
            return ct_fail(err, CT_EIO, "%s: path exists and is not a socket", a->text);
        if (alive(&sa)) return ct_fail(err, CT_EIO, "%s: another process is listening there", a->text);
        unlink(a->path); /* stale socket of a dead process */
    }
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) return ct_fail(err, CT_ESYS, "%s: socket: %s", a->text, strerror(errno));
    if (bind(fd, (struct sockaddr *)&sa, sizeof sa) != 0) {
        int e = errno;
        close(fd);
        return ct_fail(err, CT_EIO, "%s: bind: %s", a->text, strerror(e));
    }
    /* Before listen() nobody can connect, so tightening the mode here leaves no window. */
    if (chmod(a->path, 0600) != 0 || listen(fd, 16) != 0) {
        int e = errno;
        close(fd);
        unlink(a->path);
        return ct_fail(err, CT_EIO, "%s: listen: %s", a->text, strerror(e));
    }
    snprintf(bound, cap, "%s", a->text);
    *out = fd;
    return 0;
}

static int unix_connect(const xport_addr *a, int timeout_ms, int *out, ct_error *err)
{
    struct sockaddr_un sa;
    fill(a, &sa);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) return ct_fail(err, CT_ESYS, "%s: socket: %s", a->text, strerror(errno));
    if (connect(fd, (struct sockaddr *)&sa, sizeof sa) != 0) {
        if (errno != EAGAIN && errno != EINPROGRESS) {
            int e = errno;
            close(fd);
            return ct_fail(err, CT_EIO, "%s: connect: %s", a->text, strerror(e));
        }
        /* A full backlog: wait for the listener to accept. */
        struct pollfd p = {fd, POLLOUT, 0};
        int r;
        do r = poll(&p, 1, timeout_ms);
        while (r < 0 && errno == EINTR);
        int soerr = 0;
        socklen_t sl = sizeof soerr;
        if (r <= 0 || getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &sl) != 0 || soerr) {
            close(fd);
            return ct_fail(err, CT_EIO, "%s: connect: %s", a->text, r == 0 ? "timed out" : strerror(soerr ? soerr : errno));
        }
    }
    *out = fd;
    return 0;
}

static void unix_peer_name(const xport_addr *listen_addr, int fd, char *out, size_t cap)
{
    struct ucred cr;
    socklen_t len = sizeof cr;
    if (getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cr, &len) == 0)
        snprintf(out, cap, "%s (pid %ld)", listen_addr->text, (long)cr.pid);
    else
        snprintf(out, cap, "%s", listen_addr->text);
}

static void unix_unlisten(const xport_addr *a)
{
    unlink(a->path);
}

const xport_ops xport_unix_ops = {
    .scheme = "unix",
    .needs_auth = false,
    .listen = unix_listen,
    .connect = unix_connect,
    .peer_name = unix_peer_name,
    .unlisten = unix_unlisten,
};
