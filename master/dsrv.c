/* dsrv.c: the display server (dsrv.h). Connections go through three stages:
 * pending (handshake: HELLO, AUTH), waiting for SETTINGS, active (the one
 * display). Everything is non-blocking and driven by one poll() per step, so
 * a peer that stalls or misbehaves costs the others nothing. About 600
 * lines: the stages share the connection table and the event queue, and
 * each stage's checks of a hostile peer read best beside the stage. */
#include "master/dsrv.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common/fsutil.h"
#include "common/log.h"
#include "common/rng.h"
#include "common/timer.h"
#include "proto/chan.h"
#include "proto/xport.h"

#define COMPONENT "display-server"
#define MAX_EVENTS 64

typedef struct pconn {
    chan *c;
    double deadline;     /* handshake + SETTINGS must be done by then (also its age) */
    int ready_logged;
    char host[XPORT_ADDR_LEN];   /* peer address without the port: the per-peer bound's key */
} pconn;

struct dsrv {
    dsrv_config cfg;
    xport_listener *l;
    char addr[XPORT_ADDR_LEN];
    pconn pend[DSRV_MAX_PENDING];
    int npend;
    chan *disp;          /* the active display */
    char disp_peer[XPORT_ADDR_LEN];
    bool disp_lockstep;     /* the display asked for frames (SETTINGS K > 0) */
    bool cam_seen;          /* the display has sent a CAMERA: cam_epoch is its epoch */
    uint32_t cam_epoch;
    uint64_t sent_closed;   /* bytes sent on connections already closed */
    double t_io;            /* CPU seconds in the display's reads and writes */
    dsrv_event ev[MAX_EVENTS];
    int ev_head, ev_n;
    uint64_t rx_mark;       /* the display's received byte count when it last grew... */
    double rx_time;         /* ...at this time (dsrv_silent_s) */
    double rx_checked;      /* the last dsrv_silent_s */
    uint64_t evicted;       /* handshakes dropped for newcomers, not yet logged */
    ct_rng rng;             /* eviction_victim's choice */
    double evict_logged;    /* when they were last logged */
};

void dsrv_default_listen(char *out, size_t cap)
{
    const char *dir = getenv("XDG_RUNTIME_DIR");
    if (!dir || !*dir) dir = "/tmp";
    snprintf(out, cap, "unix:%s/corrtex-%ld.sock", dir, (long)getpid());
}

static int check_config(const dsrv_config *cfg, xport_addr *a, ct_error *err)
{
    int rc = xport_parse(cfg->listen, true, a, err);
    if (rc) return rc;
    if (a->kind == XPORT_TCP && !cfg->token)
        return ct_fail(err, CT_EINVAL,
                       "%s: TCP needs a token (--token-file FILE or %s): without one anyone who reaches the port "
                       "could drive the master",
                       cfg->listen, AUTH_TOKEN_ENV);
    if (a->kind == XPORT_UNIX) {
        /* Checked before the solve and the tracers' start, so that a typo
         * ends the job with one line instead of an abort after both. */
        struct stat st;
        if (lstat(a->path, &st) == 0 && !S_ISSOCK(st.st_mode))
            return ct_fail(err, CT_EINVAL, "%s: %s exists and is not a socket", cfg->listen, a->path);
        char dir[sizeof a->path];
        fs_dirname(a->path, dir, sizeof dir);
        if (access(dir, W_OK | X_OK) != 0)
            return ct_fail(err, CT_EINVAL, "%s: cannot create the socket in %s (%s)", cfg->listen, dir,
                           strerror(errno));
    }
    return 0;
}

int dsrv_check_config(const dsrv_config *cfg, ct_error *err)
{
    xport_addr a;
    return check_config(cfg, &a, err);
}

int dsrv_new(const dsrv_config *cfg, dsrv **out, ct_error *err)
{
    xport_addr a;
    int rc = check_config(cfg, &a, err);
    if (rc) return rc;
    dsrv *s = calloc(1, sizeof *s);
    if (!s) return ct_fail(err, CT_ENOMEM, "display server: out of memory");
    s->cfg = *cfg;
    /* (an attacker should not know the order of the draws) */
    s->rng = rng_make(ct_now_us(), (uint64_t)getpid(), (uint64_t)(uintptr_t)s, 0x657669637473ULL);
    if (a.kind == XPORT_UNIX) {
        /* The socket file is created with this mode: only our user may connect. */
        mode_t old = umask(0077);
        rc = xport_listen(cfg->listen, &s->l, err);
        umask(old);
        if (rc == 0 && chmod(a.path, 0600) != 0)
            rc = ct_fail(err, CT_ESYS, "%s: cannot set mode 0600 on the socket file", a.path);
    } else {
        rc = xport_listen(cfg->listen, &s->l, err);
    }
    if (rc) {
        if (s->l) xport_listener_close(s->l);
        free(s);
        return rc;
    }
    snprintf(s->addr, sizeof s->addr, "%s", xport_listener_addr(s->l));
    *out = s;
    return 0;
}

static void add_event(dsrv *s, dsrv_event_kind kind, const wire_msg *m, const char *text)
{
    if (s->ev_n == MAX_EVENTS) {
        /* (service_display stops reading before this.) Never a connection's
         * start or end: the oldest message goes, else the oldest event. */
        int drop = 0;
        for (int k = 0; k < s->ev_n; k++)
            if (s->ev[(s->ev_head + k) % MAX_EVENTS].kind == DSRV_EV_MESSAGE) {
                drop = k;
                break;
            }
        for (int k = drop; k > 0; k--)
            s->ev[(s->ev_head + k) % MAX_EVENTS] = s->ev[(s->ev_head + k - 1) % MAX_EVENTS];
        s->ev_head = (s->ev_head + 1) % MAX_EVENTS;
        s->ev_n--;
    }
    dsrv_event *e = &s->ev[(s->ev_head + s->ev_n) % MAX_EVENTS];
    memset(e, 0, sizeof *e);
    e->kind = kind;
    if (m) e->msg = *m;
    if (text) snprintf(e->text, sizeof e->text, "%s", text);
    s->ev_n++;
}

static void count_closed(dsrv *s, chan *c)
{
    uint64_t rx, tx;
    chan_byte_counts(c, &rx, &tx);
    s->sent_closed += tx;
}

static void close_pending(dsrv *s, int i)
{
    count_closed(s, s->pend[i].c);
    chan_free(s->pend[i].c);
    s->pend[i] = s->pend[--s->npend];
}

static void close_display(dsrv *s, const char *why)
{
    if (!s->disp) return;
    count_closed(s, s->disp);
    chan_free(s->disp);
    s->disp = NULL;
    add_event(s, DSRV_EV_DISCONNECTED, NULL, why);
    s->disp_peer[0] = 0;
}

void dsrv_free(dsrv *s)
{
    if (!s) return;
    while (s->npend) close_pending(s, s->npend - 1);
    if (s->disp) chan_free(s->disp);
    xport_listener_close(s->l);
    free(s);
}

const char *dsrv_addr(const dsrv *s)
{
    return s->addr;
}

double dsrv_silent_s(dsrv *s, double now)
{
    if (!s->disp) return 0.0;
    uint64_t rx, tx;
    chan_byte_counts(s->disp, &rx, &tx);
    /* A master that did not look for a while (a long view change) cannot
     * tell whether the display was silent meanwhile; and while the server
     * holds back reading it (the master has its events to take) its bytes
     * wait unread, not unsent. */
    bool gap = now - s->rx_checked > 1.0;
    s->rx_checked = now;
    if (rx != s->rx_mark || gap || s->ev_n >= MAX_EVENTS - 1) {
        s->rx_mark = rx;
        s->rx_time = now;
    }
    return now - s->rx_time;
}

bool dsrv_has_display(const dsrv *s)
{
    return s->disp != NULL;
}

const char *dsrv_peer(const dsrv *s)
{
    return s->disp ? s->disp_peer : "";
}

double dsrv_io_seconds(const dsrv *s)
{
    return s->t_io;
}

uint64_t dsrv_bytes_sent(const dsrv *s)
{
    uint64_t total = s->sent_closed, rx, tx;
    for (int i = 0; i < s->npend; i++) {
        chan_byte_counts(s->pend[i].c, &rx, &tx);
        total += tx;
    }
    if (s->disp) {
        chan_byte_counts(s->disp, &rx, &tx);
        total += tx;
    }
    return total;
}

/* "tcp:[::1]:5123" -> "tcp:[::1]"; a UNIX peer ("unix:PATH (pid N)") is its
 * own key. */
static void peer_host(const char *peer, char *out, size_t cap)
{
    const char *colon = strrchr(peer, ':');
    int n = strncmp(peer, "tcp:", 4) == 0 && colon > peer + 3 ? (int)(colon - peer) : (int)strlen(peer);
    snprintf(out, cap, "%.*s", n, peer);
}

/* Whether bytes wait unread on fd: a peer that has sent its HELLO is not
 * idle even before the server has pumped it (several newcomers accepted
 * in one step, ahead of the pumping, used to find a slow display's HELLO
 * unread and take it for an idle connection). */
static bool has_input(int fd)
{
    int n = 0;
    return ioctl(fd, FIONREAD, &n) == 0 && n > 0;
}

/* The pending connection a newcomer from host may replace (any host when
 * NULL): the oldest of those that sent nothing yet; else one chosen at
 * random of those that have not authenticated; -1 when every one has
 * authenticated. Not the oldest there: a flood of connections that each
 * send a HELLO looks like displays waiting for their AUTH's round trip,
 * and the oldest was then always the real display (the flood came after
 * it), however it retried; at random it gets in within a few tries unless
 * the flood turns the table over many times in one round trip. */
static int eviction_victim(dsrv *s, const char *host)
{
    int best = -1, nbusy = 0;
    int busy[DSRV_MAX_PENDING];
    for (int i = 0; i < s->npend; i++) {
        const pconn *p = &s->pend[i];
        if (chan_ready(p->c) || (host && strcmp(p->host, host) != 0)) continue;
        uint64_t rx, tx;
        chan_byte_counts(p->c, &rx, &tx);
        if (rx > 0 || has_input(chan_fd(p->c))) {
            if (nbusy < DSRV_MAX_PENDING) busy[nbusy++] = i;
            continue;
        }
        if (best < 0 || p->deadline < s->pend[best].deadline) best = i;
    }
    if (best >= 0 || nbusy == 0) return best;
    return busy[rng_below(&s->rng, (uint32_t)nbusy)];
}

/* Makes room for a newcomer from host; 0, or -1 when it must be refused. */
static int make_room(dsrv *s, const char *host)
{
    int same = 0;
    for (int i = 0; i < s->npend; i++) same += strcmp(s->pend[i].host, host) == 0;
    if (same < DSRV_MAX_PENDING_PER_PEER && s->npend < DSRV_MAX_PENDING) return 0;
    int v = eviction_victim(s, same >= DSRV_MAX_PENDING_PER_PEER ? host : NULL);
    if (v < 0) return -1;
    ct_debug(COMPONENT, "%s: dropped to make room for a newer connection", chan_peer(s->pend[v].c));
    close_pending(s, v);
    s->evicted++;
    return 0;
}

static void accept_all(dsrv *s)
{
    for (;;) {
        xport_conn *conn = NULL;
        ct_error e;
        if (xport_accept(s->l, &conn, &e) != 0) {
            ct_warn(COMPONENT, "%s", e.msg);
            return;
        }
        if (!conn) return;
        char host[XPORT_ADDR_LEN];
        peer_host(xport_peer(conn), host, sizeof host);
        if (make_room(s, host) != 0) {
            ct_warn(COMPONENT, "%s: dropped: every connection it could replace (%d in handshake, %d per address) "
                    "has authenticated and waits for SETTINGS", xport_peer(conn), DSRV_MAX_PENDING,
                    DSRV_MAX_PENDING_PER_PEER);
            xport_close(conn);
            continue;
        }
        chan_config cc = {.role = AUTH_ROLE_MASTER,
                          .token = s->cfg.token,
                          .require_auth = s->cfg.token != NULL,
                          .queue_bytes = s->cfg.queue_bytes,
                          .handshake_ms = s->cfg.handshake_timeout_ms};
        chan *c = NULL;
        if (chan_new(conn, &cc, &c, &e) != 0) {
            ct_warn(COMPONENT, "dropped a connection: %s", e.msg);
            continue;
        }
        ct_debug(COMPONENT, "%s: connected, handshake started", chan_peer(c));
        pconn *p = &s->pend[s->npend++];
        *p = (pconn){c, ct_now() + s->cfg.handshake_timeout_ms / 1000.0, 0, ""};
        snprintf(p->host, sizeof p->host, "%s", host);
    }
}

/* One line a second at most: a client that keeps re-opening connections
 * would otherwise fill the log. */
static void log_evictions(dsrv *s)
{
    if (!s->evicted) return;
    double now = ct_now();
    if (now - s->evict_logged < 1.0) return;
    ct_warn(COMPONENT, "dropped %llu connection%s that had not authenticated, to make room for newer ones (at most "
            "%d in handshake, %d per address)", (unsigned long long)s->evicted, s->evicted == 1 ? "" : "s",
            DSRV_MAX_PENDING, DSRV_MAX_PENDING_PER_PEER);
    s->evicted = 0;
    s->evict_logged = now;
}

/* Advances pending connection i; 1 when it was closed or promoted. */
static int service_pending(dsrv *s, int i)
{
    pconn *p = &s->pend[i];
    ct_error e;
    if (chan_pump(p->c, &e) != 0) {
        ct_warn(COMPONENT, "dropped a peer: %s", e.msg);
        close_pending(s, i);
        return 1;
    }
    if (chan_ready(p->c)) {
        if (s->disp) {
            char why[CT_ERROR_LEN];
            snprintf(why, sizeof why, "the master already serves a display (%s); one display at a time",
                     s->disp_peer);
            ct_warn(COMPONENT, "refused %s: %s", chan_peer(p->c), why);
            chan_send_error(p->c, WIRE_ERR_BUSY, why, 200);
            close_pending(s, i);
            return 1;
        }
        wire_msg m;
        int rc = chan_recv(p->c, &m, &e);
        if (rc == WIRE_OK) {
            if (m.type != WIRE_SETTINGS) {
                char why[CT_ERROR_LEN];
                snprintf(why, sizeof why, "expected SETTINGS after the handshake, got %s", wire_type_name(m.type));
                ct_warn(COMPONENT, "dropped %s: %s", chan_peer(p->c), why);
                chan_send_error(p->c, WIRE_ERR_PROTOCOL, why, 200);
                close_pending(s, i);
                return 1;
            }
            s->disp = p->c;
            snprintf(s->disp_peer, sizeof s->disp_peer, "%s", chan_peer(p->c));
            s->disp_lockstep = m.u.settings.samples_per_frame > 0;
            s->cam_seen = false;
            s->rx_checked = s->rx_time = ct_now();
            s->rx_mark = 0;
            s->pend[i] = s->pend[--s->npend];
            ct_info(COMPONENT, "display %s connected (%s)", s->disp_peer,
                    m.u.settings.samples_per_frame ? "lockstep" : "free-running");
            add_event(s, DSRV_EV_CONNECTED, &m, NULL);
            return 1;
        }
        if (rc < 0) {
            ct_warn(COMPONENT, "dropped a peer: %s", e.msg);
            close_pending(s, i);
            return 1;
        }
    }
    if (ct_now() > p->deadline) {
        char why[CT_ERROR_LEN];
        snprintf(why, sizeof why, "handshake not completed within %d ms", s->cfg.handshake_timeout_ms);
        ct_warn(COMPONENT, "dropped %s: %s", chan_peer(p->c), why);
        chan_send_error(p->c, WIRE_ERR_PROTOCOL, why, 50);
        close_pending(s, i);
        return 1;
    }
    return 0;
}

/* Epochs label what the master sends back (SAMPLES, FRAME, projections),
 * so a display that reuses or reorders them would read old work as new:
 * each CAMERA must be after the last (by one in lockstep, where every
 * camera asks for a frame; free running a camera replaced before sending
 * skips one). "After" in serial-number arithmetic, so a display running
 * past 2^32 cameras wraps rather than ends. */
static bool camera_in_order(dsrv *s, uint32_t epoch, char *why, size_t cap)
{
    if (s->cam_seen) {
        uint32_t step = epoch - s->cam_epoch;
        bool ok = s->disp_lockstep ? step == 1 : step != 0 && step < 0x80000000u;
        if (!ok) {
            snprintf(why, cap, "CAMERA epoch %u after epoch %u: epochs must increase%s", epoch, s->cam_epoch,
                     s->disp_lockstep ? " by one in lockstep" : "");
            return false;
        }
    }
    s->cam_seen = true;
    s->cam_epoch = epoch;
    return true;
}

static void service_display(dsrv *s)
{
    ct_error e;
    if (chan_pump(s->disp, &e) != 0) {
        ct_warn(COMPONENT, "display dropped: %s", e.msg);
        close_display(s, e.msg);
        return;
    }
    for (;;) {
        /* A display that sends faster than the master takes its events
         * waits in its socket: its CAMERAs and ACKs are not dropped, nor
         * the CONNECTED event a burst right after SETTINGS would push out
         * (one event is kept free for a DISCONNECTED). */
        if (s->ev_n >= MAX_EVENTS - 1) return;
        wire_msg m;
        int rc = chan_recv(s->disp, &m, &e);
        if (rc == WIRE_NEED_MORE) return;
        if (rc < 0) {
            if (rc == CT_EIO) {
                ct_info(COMPONENT, "display left: %s", e.msg);
            } else {
                /* A message the decoder refused (a CAMERA out of range, say):
                 * the display hears why. */
                ct_warn(COMPONENT, "dropped display %s: %s", s->disp_peer, e.msg);
                chan_send_error(s->disp, WIRE_ERR_PROTOCOL, e.msg, 200);
            }
            close_display(s, e.msg);
            return;
        }
        switch (m.type) {
        case WIRE_CAMERA: {
            char why[CT_ERROR_LEN];
            if (!camera_in_order(s, m.u.camera.epoch, why, sizeof why)) {
                dsrv_drop(s, WIRE_ERR_PROTOCOL, why);
                return;
            }
            add_event(s, DSRV_EV_MESSAGE, &m, NULL);
            break;
        }
        case WIRE_ACK:
            add_event(s, DSRV_EV_MESSAGE, &m, NULL);
            break;
        case WIRE_PING: {
            /* With our clock: the display estimates its offset (lag stats).
             * Not behind a quarter of the queue's bound: a PONG queued behind
             * megabytes tells the display no round trip worth having, and a
             * display that pings without reading would fill the queue until
             * the next control message waits for room, stalling the loop. */
            size_t bound = s->cfg.queue_bytes ? s->cfg.queue_bytes : CHAN_DEFAULT_QUEUE_BYTES;
            if (chan_queue_stats(s->disp).bytes > bound / 4) break;
            wire_msg pong = m;
            pong.type = WIRE_PONG;
            pong.u.ping.clock_us = ct_now_us();
            if (chan_send(s->disp, &pong, &e) < 0) {
                close_display(s, e.msg);
                return;
            }
            break;
        }
        case WIRE_PONG:
            break;
        case WIRE_BYE: {
            char why[64];
            snprintf(why, sizeof why, "the display said BYE (reason %u)", m.u.bye.reason);
            ct_info(COMPONENT, "display %s left: %s", s->disp_peer, why);
            close_display(s, why);
            return;
        }
        case WIRE_ERROR: {
            char why[CT_ERROR_LEN];
            snprintf(why, sizeof why, "the display reported an error: %s", m.u.error.text);
            ct_warn(COMPONENT, "display %s: %s", s->disp_peer, why);
            close_display(s, why);
            return;
        }
        default: {
            char why[CT_ERROR_LEN];
            snprintf(why, sizeof why, "unexpected %s message from a display", wire_type_name(m.type));
            dsrv_drop(s, WIRE_ERR_PROTOCOL, why);
            return;
        }
        }
    }
}

int dsrv_step(dsrv *s, int timeout_ms, ct_error *err)
{
    (void)err;
    struct pollfd fds[DSRV_MAX_PENDING + 2];
    int n = 0;
    fds[n++] = (struct pollfd){.fd = xport_listener_fd(s->l), .events = POLLIN};
    for (int i = 0; i < s->npend; i++) fds[n++] = (struct pollfd){.fd = chan_fd(s->pend[i].c), .events = chan_events(s->pend[i].c)};
    int di = s->disp ? n : -1;
    if (s->disp) fds[n++] = (struct pollfd){.fd = chan_fd(s->disp), .events = chan_events(s->disp)};
    /* Pending handshakes have deadlines: do not sleep past them by much. */
    if (s->npend && (timeout_ms < 0 || timeout_ms > 100)) timeout_ms = 100;
    int r = poll(fds, (nfds_t)n, timeout_ms);
    if (r < 0) return 0;   /* EINTR (a signal): the caller checks its flags */
    if (fds[0].revents & POLLIN) accept_all(s);
    log_evictions(s);
    for (int i = 0; i < s->npend;)
        if (!service_pending(s, i)) i++;
    if (s->disp) {
        /* Timed (a system call each way) only when the socket had bytes to
         * move: the master steps thousands of times a second, mostly idle.
         * (di < 0: the display was promoted from a handshake just now.) */
        bool timed = di >= 0 && fds[di].revents;
        double t0 = timed ? ct_thread_cpu() : 0.0;
        service_display(s);
        if (timed) s->t_io += ct_thread_cpu() - t0;
    }
    return 0;
}

int dsrv_next_event(dsrv *s, dsrv_event *ev)
{
    if (!s->ev_n) return 0;
    *ev = s->ev[s->ev_head];
    s->ev_head = (s->ev_head + 1) % MAX_EVENTS;
    s->ev_n--;
    return 1;
}

bool dsrv_view_pending(const dsrv *s)
{
    for (int i = 0; i < s->ev_n; i++) {
        const dsrv_event *e = &s->ev[(s->ev_head + i) % MAX_EVENTS];
        if (!(e->kind == DSRV_EV_MESSAGE && e->msg.type == WIRE_ACK)) return true;
    }
    return false;
}

int dsrv_send(dsrv *s, const wire_msg *m, int timeout_ms, ct_error *err)
{
    if (!s->disp) return 0;
    ct_error e;
    double end = ct_now() + timeout_ms / 1000.0;
    for (;;) {
        int rc = chan_send(s->disp, m, &e);
        if (rc == 0) return 0;
        if (rc < 0) {
            ct_info(COMPONENT, "display %s lost: %s", s->disp_peer, e.msg);
            close_display(s, e.msg);
            return 0;
        }
        /* Queue full: write until there is room (patches are merged in the
         * queue, so this only happens when the display stops reading). */
        if (chan_pump(s->disp, &e) != 0) {
            close_display(s, e.msg);
            return 0;
        }
        if (ct_now() > end) {
            char why[CT_ERROR_LEN];
            snprintf(why, sizeof why, "the display read nothing for %d ms with a full send queue", timeout_ms);
            ct_warn(COMPONENT, "dropped display %s: %s", s->disp_peer, why);
            chan_send_error(s->disp, WIRE_ERR_LIMIT, why, 100);
            close_display(s, why);
            return 0;
        }
        struct pollfd p = {.fd = chan_fd(s->disp), .events = POLLOUT};
        poll(&p, 1, 10);
    }
    (void)err;
}

wire_buf *dsrv_tail(dsrv *s)
{
    if (!s->disp) return NULL;
    ct_error e;
    wire_buf *b = chan_tail(s->disp, &e);
    if (!b) {
        ct_info(COMPONENT, "display %s lost: %s", s->disp_peer, e.msg);
        close_display(s, e.msg);
    }
    return b;
}

void dsrv_commit(dsrv *s, uint64_t frames)
{
    if (s->disp) chan_commit(s->disp, frames);
}

size_t dsrv_queued(const dsrv *s)
{
    return s->disp ? chan_queue_stats(s->disp).bytes : 0;
}

uint64_t dsrv_written(const dsrv *s)
{
    return s->disp ? chan_queue_stats(s->disp).written : 0;
}

int dsrv_try_send(dsrv *s, const wire_msg *m, size_t max_queued)
{
    if (!s->disp) return 0;
    if (chan_queue_stats(s->disp).bytes > max_queued) return DSRV_DROPPED;
    ct_error e;
    int rc = chan_send(s->disp, m, &e);
    if (rc == XPORT_QUEUE_FULL) return DSRV_DROPPED;
    if (rc < 0) {
        ct_info(COMPONENT, "display %s lost: %s", s->disp_peer, e.msg);
        close_display(s, e.msg);
    }
    return 0;
}

bool dsrv_drop(dsrv *s, uint32_t code, const char *text)
{
    if (!s->disp) return false;
    ct_log(code == WIRE_ERR_INTERNAL ? CT_LOG_INFO : CT_LOG_WARN, COMPONENT, "dropped display %s: %s", s->disp_peer,
           text);
    bool told = chan_send_error(s->disp, code, text, 500) == 0;
    close_display(s, text);
    return told;
}

void dsrv_bye(dsrv *s, uint32_t reason, int timeout_ms)
{
    if (!s->disp) return;
    wire_msg m = {.type = WIRE_BYE};
    m.u.bye.reason = reason;
    ct_error e;
    if (chan_send(s->disp, &m, &e) == 0) chan_flush(s->disp, timeout_ms, &e);
    close_display(s, "the master said BYE");
}
