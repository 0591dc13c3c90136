/* bench_master: the master's saturation. Samples recorded by a real run
 * (corrtex converge --record, proto/srec.h) are replayed into the master's
 * session (master/session.h) through the loop (master/drive.h) over the
 * replay port (master/tport_replay.h), which answers every request at once:
 * the master inserts as fast as it can. A display is connected and
 * consuming all the while: a child process that speaks the display protocol
 * (proto/chan.h) on a UNIX socket, copies every texture patch into its
 * textures as corrtex-display's inbox does before the GL upload, and
 * acknowledges every update (SYNC -> ACK), so texture updates go out paced
 * by it as in corrtex-render (master/dsink.h). The session is driven as the
 * recording run drove it (lockstep rounds of --batch, the same view and
 * options, --pop-ahead too), so it hands out the recorded requests.
 * Prints one markdown table row, with the loop's stages in wall seconds:
 * insertion (sess_insert_next, the pops ahead included where they were not
 * hidden), pops ahead (their own time, beside the splats with 2+ threads),
 * requests (sess_next), port (the rest of the loop: the replay port,
 * sorting rounds) and display (the server and the texture updates);
 * scripts/bench-master writes them into docs/benchmarks.md.
 *   bench_master SCENE --camera NAME --width W --height H --stand-in A
 *                --record FILE --master-threads N [--batch B] [--pop-ahead]
 *                [--header]
 * Exit 0, 1 when the run fails, 2 on bad usage. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/log.h"
#include "common/optab.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/timer.h"
#include "display/disp_rescale.h"
#include "master/drive.h"
#include "master/dsink.h"
#include "master/dsrv.h"
#include "master/session.h"
#include "master/tport_replay.h"
#include "proto/chan.h"
#include "proto/srec.h"
#include "proto/wire.h"

typedef struct opts {
    const char *camera, *record;
    int width, height, threads, batch;
    float stand_in, refine_error;
    double patch_share;
    bool header;
    bool pop_ahead;
} opts;

#define OF(f) offsetof(opts, f)
static const optab OPTS[] = {
    {"camera", 0, OPTAB_STRING, OF(camera), 0, 0, NULL, "NAME", "the recording run's camera", NULL},
    {"record", 0, OPTAB_STRING, OF(record), 0, 0, NULL, "FILE", "the recording (corrtex converge --record)", NULL},
    {"width", 0, OPTAB_INT, OF(width), 1, 16384, "1024", "W", "image width of the recording run", NULL},
    {"height", 0, OPTAB_INT, OF(height), 1, 16384, "1024", "H", "image height of the recording run", NULL},
    {"stand-in", 0, OPTAB_FLOAT, OF(stand_in), 0, 1e6, "0.3", "A", "the recording run's --stand-in", NULL},
    {"master-threads", 0, OPTAB_INT, OF(threads), 1, POOL_MAX_THREADS, "1", "N", "the master's threads", NULL},
    {"batch", 0, OPTAB_INT, OF(batch), 1, 65536, "256", "B", "the recording run's --batch (a round)", NULL},
    {"pop-ahead", 0, OPTAB_FLAG, OF(pop_ahead), 0, 0, NULL, NULL,
     "the recording run's --pop-ahead (each round popped ahead of the last one's reports)", NULL},
    {"refine-error", 0, OPTAB_FLOAT, OF(refine_error), 0, 1e6, "0", "E",
     "the recording run's --refine-error (refinement past full coverage recorded too)", NULL},
    {"patch-share", 0, OPTAB_DOUBLE, OF(patch_share), 0.0001, 1, "0.25", "X",
     "corrtex-render's --patch-share (the most of the master's time texture updates may take)", NULL},
    {"header", 0, OPTAB_FLAG, OF(header), 0, 0, NULL, NULL, "print the table header first", NULL},
};
#undef OF

/* --- the display: a child process ------------------------------------------- */

typedef struct tex {
    uint32_t w, h;
    uint16_t *texels;
} tex;

/* Connects, asks for free running, sends the view, then takes every
 * message until the master says BYE: textures kept as the display's inbox
 * keeps them, every SYNC acknowledged at once. Exit status 0 after BYE. */
static int consume(const char *addr, const ct_camera *cam, int w, int h)
{
    ct_error err;
    chan_config cfg = {.role = AUTH_ROLE_DISPLAY};
    chan *c = NULL;
    if (chan_connect(addr, &cfg, 10000, &c, &err)) {
        fprintf(stderr, "bench_master display: %s\n", err.msg);
        return 1;
    }
    wire_msg m = {.type = WIRE_SETTINGS};
    int rc = chan_send(c, &m, &err);
    m = (wire_msg){.type = WIRE_CAMERA};
    m.u.camera = (wire_camera){1, (uint32_t)w, (uint32_t)h, *cam};
    if (rc || chan_send(c, &m, &err) || chan_flush(c, 10000, &err)) {
        fprintf(stderr, "bench_master display: %s\n", err.msg);
        return 1;
    }
    tex *t = calloc(1u << 16, sizeof *t);
    int status = 1;
    bool ack_failed = false;
    char ack_msg[256] = "";
    for (;;) {
        rc = chan_recv_wait(c, &m, 60000, &err);
        if (rc < 0 || rc == WIRE_NEED_MORE) {
            fprintf(stderr, "bench_master display: %s%s%s\n", rc < 0 ? err.msg : "nothing for 60 s",
                    ack_failed ? "; an ACK failed before: " : "", ack_msg);
            break;
        }
        if (m.type == WIRE_BYE) {
            status = 0;
            break;
        }
        if (m.type == WIRE_ERROR) {
            fprintf(stderr, "bench_master display: the master says %s\n", m.u.error.text);
            break;
        }
        if (m.type == WIRE_TEX_ALLOC && m.u.tex_alloc.tex < (1u << 16)) {
            tex *x = &t[m.u.tex_alloc.tex];
            free(x->texels);
            x->w = m.u.tex_alloc.width;
            x->h = m.u.tex_alloc.height;
            x->texels = calloc((size_t)x->w * x->h * 3, sizeof *x->texels);
        } else if (m.type == WIRE_TEX_RESIZE && m.u.tex_resize.tex < (1u << 16)) {
            /* as a display does it: computed from the texels here */
            tex *x = &t[m.u.tex_resize.tex];
            int nw = (int)m.u.tex_resize.width, nh = (int)m.u.tex_resize.height;
            uint16_t *n = x->texels && wire_tex_resize_exact((int)x->w, (int)x->h, nw, nh)
                              ? malloc((size_t)nw * (size_t)nh * 3 * sizeof *n)
                              : NULL;
            if (!n) {
                fprintf(stderr, "bench_master display: a resize of texture %u it cannot follow\n",
                        m.u.tex_resize.tex);
                break;
            }
            bool neg, nz;
            if (disp_rescale(x->texels, (int)x->w, (int)x->h, n, nw, nh, &neg, &nz)) {
                fprintf(stderr, "bench_master display: out of memory\n");
                free(n);
                break;
            }
            free(x->texels);
            x->texels = n;
            x->w = (uint32_t)nw;
            x->h = (uint32_t)nh;
        } else if (m.type == WIRE_TEX_FREE && m.u.tex_free.tex < (1u << 16)) {
            free(t[m.u.tex_free.tex].texels);
            t[m.u.tex_free.tex].texels = NULL;
        } else if (m.type == WIRE_TEX_PATCH && m.u.tex_patch.tex < (1u << 16)) {
            const wire_tex_patch *p = &m.u.tex_patch;
            tex *x = &t[p->tex];
            if (!x->texels || p->x + p->w > x->w || p->y + p->h > x->h) continue;
            for (uint32_t j = 0; j < p->h; j++)
                memcpy(x->texels + 3 * ((size_t)(p->y + j) * x->w + p->x), p->texels + 3 * (size_t)j * p->w,
                       3 * sizeof *p->texels * p->w);
        } else if (m.type == WIRE_SYNC && !ack_failed) {
            /* The master sends its last SYNC, BYE and closes at once: an ACK
             * it no longer reads fails, but the BYE behind the SYNC is
             * already here to be read. */
            wire_msg a = {.type = WIRE_ACK};
            a.u.ack.seq = m.u.sync.seq;
            if (chan_send(c, &a, &err) || chan_flush(c, 10000, &err)) {
                ack_failed = true;
                snprintf(ack_msg, sizeof ack_msg, "%s", err.msg);
            }
        }
    }
    chan_free(c);
    return status;
}

/* --- the master ---------------------------------------------------------------- */

typedef struct bench {
    dsrv *ds;
    dsink *dk;
    sess *s;
    drv *d;
    int connected, have_view;
} bench;

static int events(bench *b, ct_error *err)
{
    dsrv_event ev;
    while (dsrv_next_event(b->ds, &ev)) {
        if (ev.kind == DSRV_EV_CONNECTED) {
            int rc = dsink_connected(b->dk, b->s, &ev.msg.u.settings, err);
            if (rc) return rc;
            b->connected = 1;
        } else if (ev.kind == DSRV_EV_MESSAGE && ev.msg.type == WIRE_CAMERA) {
            dsink_set_epoch(b->dk, ev.msg.u.camera.epoch);
            int rc = drv_set_view(b->d, &ev.msg.u.camera.cam, (int)ev.msg.u.camera.width,
                                  (int)ev.msg.u.camera.height, err);
            if (rc < 0) return rc;
            b->have_view = 1;
        } else if (ev.kind == DSRV_EV_MESSAGE && ev.msg.type == WIRE_ACK) {
            int rc = dsink_ack(b->dk, ev.msg.u.ack.seq, err);
            if (rc) return rc;
        } else if (ev.kind == DSRV_EV_DISCONNECTED) {
            return ct_fail(err, CT_EIO, "the display left: %s", ev.text);
        }
    }
    return 0;
}

static double cpu_s(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
           1e-6 * (double)ru.ru_stime.tv_usec;
}

int main(int argc, char **argv)
{
    signal(SIGPIPE, SIG_IGN);
    ct_log_set_level(CT_LOG_WARN);
    opts o;
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), &o, &err);
    optab_group g = {OPTS, OPTAB_COUNT(OPTS), &o};
    const char *pos[1];
    int npos = 0, rc = optab_parse(&g, 1, argc, argv, pos, 1, &npos, &err);
    if (rc == 1 || (rc == 0 && (!npos || !o.record))) {
        fprintf(rc == 1 ? stdout : stderr, "usage: bench_master SCENE --record FILE [options]\n");
        optab_usage(OPTS, OPTAB_COUNT(OPTS), NULL, rc == 1 ? stdout : stderr);
        return rc == 1 ? 0 : 2;
    }
    if (rc) {
        fprintf(stderr, "bench_master: %s\n", err.msg);
        return 2;
    }
    if (o.header) {
        printf("| master threads | samples | wall s | CPU s | samples/s | display updates | display MB | insertion s | "
               "pops ahead s | requests s | port s | display s |\n"
               "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
        fflush(stdout);
    }
    ct_scene *scene = NULL;
    ct_radmesh mesh = {0};
    ct_sample *rec = NULL;
    size_t nrec = 0;
    tport *port = NULL;
    bench b = {0};
    pid_t child = -1;
    char dir[] = "/tmp/bench-master-XXXXXX", addr[128];
    if (!mkdtemp(dir)) {
        perror("bench_master: mkdtemp");
        return 1;
    }
    snprintf(addr, sizeof addr, "unix:%s/s.sock", dir);
    rc = scene_load(pos[0], &scene, &err);
    int ci = rc ? -1 : o.camera ? scene_find_camera(scene, o.camera) : 0;
    if (!rc && ci < 0) rc = ct_fail(&err, CT_EINVAL, "%s has no camera '%s'", pos[0], o.camera);
    if (!rc) rc = rmesh_from_scene(scene, v3s(o.stand_in), &mesh, &err);
    if (!rc) rc = srec_read(o.record, &rec, &nrec, &err);
    dsrv_config dc = {.listen = addr, .handshake_timeout_ms = 10000, .queue_bytes = (size_t)64 << 20};
    if (!rc) rc = dsrv_new(&dc, &b.ds, &err);
    if (!rc) {
        fflush(stdout);
        child = fork();
        if (child == 0) _exit(consume(addr, &scene->cams[ci].cam, o.width, o.height));
        if (child < 0) rc = ct_fail(&err, CT_ESYS, "fork failed");
    }
    rq_options ro;
    rq_options_default(&ro);
    ro.refine_error = o.refine_error;   /* as corrtex converge recorded them */
    ctex_options co = ctex_options_default();
    sess_config sc = {&mesh, scene ? scene->mats : NULL, scene ? scene->nmats : 0, &ro, &co, 1, {o.threads, 0.0, 0.0}};
    if (!rc) rc = sess_new(&sc, &b.s, &err);
    if (!rc) rc = tport_replay_new(rec, nrec, 1, &port, &err);
    /* a generous send timeout: on a loaded machine the display child may
     * wait for a core */
    dsink_config kc = {b.ds, &mesh, scene, 120000, (size_t)64 << 20, -1, -1, 0.010, o.patch_share};
    if (!rc) rc = dsink_new(&kc, &b.dk, &err);
    drv_options dopt = {.window = 1, .batch_min = 1, .batch_max = 65536, .batch_ms = 20, .round = o.batch,
                        .pop_ahead = o.pop_ahead};
    sink k;
    if (!rc) {
        k = dsink_sink(b.dk);
        rc = drv_new(b.s, port, &k, &dopt, &b.d, &err);
    }
    /* the display connects and sends its view */
    double t_wait = ct_now();
    while (!rc && !(b.connected && b.have_view)) {
        if (ct_now() - t_wait > 30.0) rc = ct_fail(&err, CT_EIO, "the display did not connect");
        if (!rc) rc = dsrv_step(b.ds, 10, &err);
        if (!rc) rc = events(&b, &err);
    }
    double t0 = ct_now(), c0 = cpu_s();
    uint64_t bytes0 = b.ds ? dsrv_bytes_sent(b.ds) : 0;
    double t_tex0 = sess_get_counters(b.s).t_texture, t_next0 = sess_get_counters(b.s).t_next,
           t_ahead0 = sess_get_counters(b.s).t_ahead;
    if (!rc) {
        drv_set_lockstep(b.d, true);
        /* a recording past full coverage ends where it ends, not when the
         * queue runs dry (refinement would not) */
        drv_begin_frame(b.d, o.refine_error > 0.0f && nrec < UINT32_MAX ? (uint32_t)nrec : UINT32_MAX);
    }
    double t_disp = 0, t_drv = 0;   /* per-stage seconds (the session counts its own) */
    while (!rc && drv_in_frame(b.d)) {
        double a = ct_now();
        rc = dsrv_step(b.ds, 0, &err);
        if (!rc) rc = events(&b, &err);
        double m = ct_now();
        if (!rc) rc = drv_step(b.d, &err) < 0 ? CT_EIO : 0;
        double now = ct_now();
        t_drv += now - m;
        /* free-running updates paced as corrtex-render's (--patch-ms 10) and by the ACKs */
        if (!rc && dsink_update_due(b.dk, now)) rc = dsink_update(b.dk, b.s, &err);
        t_disp += ct_now() - now + (m - a);
    }
    double wall = ct_now() - t0, cpu = cpu_s() - c0;
    if (!rc) {
        uint64_t n = sess_get_counters(b.s).inserted;
        sess_counters cn = sess_get_counters(b.s);
        double t_ins = cn.t_texture - t_tex0, t_req = cn.t_next - t_next0;
        printf("| %d | %llu | %.3f | %.3f | %.0f | %llu | %.1f | %.3f | %.3f | %.3f | %.3f | %.3f |\n", sess_threads(b.s),
               (unsigned long long)n, wall, cpu, (double)n / wall, (unsigned long long)dsink_sync_stats(b.dk).updates,
               (double)(dsrv_bytes_sent(b.ds) - bytes0) / 1048576.0, t_ins, cn.t_ahead - t_ahead0, t_req,
               t_drv - t_ins - t_req, t_disp);
        if (n != nrec)
            fprintf(stderr, "bench_master: inserted %llu of the %zu recorded samples\n", (unsigned long long)n, nrec);
    }
    /* The display takes what is still queued before BYE (not timed). */
    double t_drain = ct_now();
    while (!rc && b.ds && dsrv_has_display(b.ds) && dsrv_queued(b.ds) > 0 && ct_now() - t_drain < 120.0) {
        rc = dsrv_step(b.ds, 10, &err);
        if (!rc) rc = events(&b, &err);
    }
    if (b.ds) dsrv_bye(b.ds, WIRE_BYE_DONE, 30000);
    if (child > 0) {
        int st = 0;
        waitpid(child, &st, 0);
        if (!rc && !(WIFEXITED(st) && WEXITSTATUS(st) == 0))
            rc = ct_fail(&err, CT_EIO, "the display failed (%s %d)", WIFEXITED(st) ? "exit status" : "signal",
                         WIFEXITED(st) ? WEXITSTATUS(st) : WTERMSIG(st));
    }
    if (rc) fprintf(stderr, "bench_master: %s\n", err.msg);
    drv_free(b.d);
    if (port) port->ops->close(port, 0);
    dsink_free(b.dk);
    dsrv_free(b.ds);
    sess_free(b.s);
    free(rec);
    rmesh_free(&mesh);
    scene_free(scene);
    char sock[160];
    snprintf(sock, sizeof sock, "%s/s.sock", dir);
    unlink(sock);
    rmdir(dir);
    return rc ? 1 : 0;
}
