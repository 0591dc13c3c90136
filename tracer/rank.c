/* rank.c: a tracer rank's loop (rank.h). Every message that arrived has its
 * receive started at once and is taken when complete (so the master's sends
 * complete, and the rank never waits inside MPI for a transfer the master
 * has yet to progress), request batches wait in a FIFO, camera and control
 * messages act immediately; a batch is traced in slices with the same
 * intake between them (intake()), so that the previous batch's samples
 * leave and the next batch comes in while this one is traced (a large MPI
 * message moves only while both sides call MPI) and a batch of a newer
 * view, once it has come, takes over within a slice. */
#include "tracer/rank.h"

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "common/pool.h"
#include "common/timer.h"
#include "proto/mpi_link.h"
#include "proto/wire_mpi.h"
#include "tracer/screen_order.h"

#define COMPONENT "tracer"

/* Who sent what a tracer decodes, for its error lines. */
static const char PEER[] = "master (rank 0)";

/* A queued request batch with what its header says of it. */
typedef struct queued {
    wire_buf b;
    uint64_t batch;
    uint32_t epoch;
} queued;

typedef struct fifo {
    queued *items;
    size_t head, n, cap;
} fifo;

static int fifo_push(fifo *f, wire_buf *b, const wire_mpi_requests *h, ct_error *err)
{
    if (f->n == f->cap) {
        size_t cap = f->cap ? 2 * f->cap : 8;
        queued *p = malloc(cap * sizeof *p);
        if (!p) return ct_fail(err, CT_ENOMEM, "tracer: out of memory queueing request batches");
        for (size_t i = 0; i < f->n; i++) p[i] = f->items[(f->head + i) % f->cap];
        free(f->items);
        f->items = p;
        f->cap = cap;
        f->head = 0;
    }
    f->items[(f->head + f->n) % f->cap] = (queued){*b, h->batch, h->epoch};
    memset(b, 0, sizeof *b);
    f->n++;
    return 0;
}

static queued fifo_pop(fifo *f)
{
    queued q = f->items[f->head];
    f->head = (f->head + 1) % f->cap;
    f->n--;
    return q;
}

/* The epoch of the last batch queued (f->n > 0): the newest, as the master
 * sends epochs in order. */
static uint32_t fifo_newest(const fifo *f)
{
    return f->items[(f->head + f->n - 1) % f->cap].epoch;
}

static void fifo_free(fifo *f)
{
    while (f->n) {
        queued q = fifo_pop(f);
        wire_buf_free(&q.b);
    }
    free(f->items);
}

static uint64_t trace_threads(ct_pool *pool, const trank_config *c, const trc_view *v, const ct_request *req,
                              size_t n, ct_sample *out);

/* Requests traced between two looks at the master's messages: a few
 * milliseconds of work (a batch is up to 4096 requests, tens of ms). */
#define SLICE 256

/* Between two slices of a batch: 1 to go on, 0 when the batch is to stop,
 * negative on an MPI failure. */
typedef int (*slice_fn)(void *ctx, ct_error *err);

/* Traces req[0..n) in slices of SLICE, asking `between` after each; 1 when
 * done, 0 when stopped, negative on failure. *rays accumulates; *done is
 * the requests traced (out[0..*done)). */
static int trace_slices(ct_pool *pool, const trank_config *c, const trc_view *v, const ct_request *req, size_t n,
                        ct_sample *out, slice_fn between, void *ctx, uint64_t *rays, size_t *done, ct_error *err)
{
    *done = 0;
    for (size_t a = 0; a < n; a += SLICE) {
        size_t m = n - a < SLICE ? n - a : SLICE;
        *rays += trace_threads(pool, c, v, req + a, m, out + a);
        *done = a + m;
        if (a + m < n) {
            int go = between(ctx, err);
            if (go <= 0) return go;
        }
    }
    return 1;
}

/* Traces a batch in screen order (screen_order.h: table at 1024^2 traced
 * 5 % more samples a second this way) and answers in request order; a
 * batch stopped part way leaves its traced samples in out[0..*done), in the
 * order traced. Without memory for the permutation the batch goes as it
 * came. Returns as trace_slices. */
static int trace_batch(ct_pool *pool, const trank_config *c, so_batch *o, const trc_view *v,
                       const ct_request *req, size_t n, ct_sample *out, slice_fn between, void *ctx, uint64_t *rays,
                       size_t *done, ct_error *err)
{
    if (so_batch_order(o, req, n) != CT_OK)
        return trace_slices(pool, c, v, req, n, out, between, ctx, rays, done, err);
    int rc = trace_slices(pool, c, v, o->req, n, o->out, between, ctx, rays, done, err);
    if (rc > 0) so_batch_scatter(o, n, out);
    else if (rc == 0) memcpy(out, o->out, *done * sizeof *out);
    return rc;
}

/* Traces n requests on the pool (trc_trace_par); returns the rays. */
static uint64_t trace_threads(ct_pool *pool, const trank_config *c, const trc_view *v, const ct_request *req,
                              size_t n, ct_sample *out)
{
    trc_stats st = {0};
    trc_trace_par(c->tracer, pool, v, req, n, out, false, &st);
    return trc_stats_rays(&st);
}

/* Leaving in order: a large sample message completes only when the master
 * receives it, so the master takes (and drops) what is still on its way
 * until each tracer says BYE, which goes after the last samples. Left on a
 * signal (mpirun sends SIGTERM to every rank), the master's SHUTDOWN is
 * still to come: its messages are taken until then so its sends complete
 * too. Never blocks on a master that stopped: 3 s at most. */
static int farewell(const trank_config *c, int shutdown, wire_buf *msg, ct_error *err)
{
    wire_buf bye = {0};
    int rc = mpil_isend(0, MPIL_TAG_BYE, &bye, err);
    if (rc < 0) return rc;
    double end = ct_now() + 3.0;
    while (!shutdown) {
        mpil_info info;
        double left = end - ct_now();
        int got = left > 0 ? mpil_recv_wait(0, MPIL_ANY, left, &info, msg, err) : 0;
        if (got < 0) return got;
        if (!got) break;
        unsigned kind = 0;
        uint32_t count = 0;
        if (wire_mpi_peek(msg->data, msg->len, PEER, &kind, &count, err) < 0 || kind != WIRE_MPI_CONTROL) continue;
        wire_mpi_control ctl;
        if (wire_mpi_decode_control(msg->data, msg->len, PEER, &ctl, err) == 0 && ctl.op == WIRE_MPI_OP_SHUTDOWN)
            shutdown = 1;
    }
    if (!shutdown) ct_debug(COMPONENT, "rank %d: no SHUTDOWN from the master within 3 s of leaving", c->rank);
    return 0;
}

/* What the loop keeps between messages. */
typedef struct intake_state {
    const trank_config *c;
    fifo *q;
    wire_buf *msg;
    uint32_t epoch;        /* newest camera epoch heard of */
    uint32_t batch_epoch;  /* of the batch being traced */
    int shutdown;
} intake_state;

/* Takes every message whose transfer has completed (and starts the
 * receives of those that arrived since): request batches to the FIFO,
 * cameras and control at once; then progresses the sends (the samples on
 * their way to the master). Never waits in MPI: a blocking receive of a
 * large batch spun until the master, busy inserting or descheduled on a
 * shared host, progressed its send (9 % of a tracer rank's CPU in a table
 * walk at 1024x1024 on two cores, docs/distributed.md). */
static int intake(intake_state *in, ct_error *err)
{
    for (;;) {
        mpil_info info;
        int got = mpil_poll_recv(0, MPIL_ANY, &info, in->msg, err);
        if (got < 0) return got;
        if (!got) break;
        int rc;
        unsigned kind = 0;
        uint32_t count = 0;
        if ((rc = wire_mpi_peek(in->msg->data, in->msg->len, PEER, &kind, &count, err)) < 0) return rc;
        if (kind == WIRE_MPI_REQUESTS) {
            wire_mpi_requests h;
            if ((rc = wire_mpi_decode_requests_header(in->msg->data, in->msg->len, PEER, &h, err)) < 0) return rc;
            if ((rc = fifo_push(in->q, in->msg, &h, err)) < 0) return rc;
            /* a batch is made for a view its CAMERA announced; whichever came first */
            if (h.epoch > in->epoch) in->epoch = h.epoch;
        } else if (kind == WIRE_MPI_CAMERA) {
            wire_mpi_camera cam;
            if ((rc = wire_mpi_decode_camera(in->msg->data, in->msg->len, PEER, &cam, err)) < 0) return rc;
            if (cam.epoch > in->epoch) in->epoch = cam.epoch;
        } else if (kind == WIRE_MPI_CONTROL) {
            wire_mpi_control ctl;
            if ((rc = wire_mpi_decode_control(in->msg->data, in->msg->len, PEER, &ctl, err)) < 0) return rc;
            if (ctl.op == WIRE_MPI_OP_SHUTDOWN) in->shutdown = 1;
            /* CONFIG is not needed: every rank parses the same command line. */
        } else {
            return ct_fail(err, CT_EPROTO, "tracer %d: unexpected MPI message kind %u from the master", in->c->rank,
                           kind);
        }
    }
    return mpil_progress(err) < 0 ? CT_EIO : 0;
}

/* Whether a batch of `epoch` gives way: the camera moved on and a batch of
 * a newer view waits. Until that batch comes, the rank traces the old one
 * rather than wait: what it traces goes in as late samples (diffuse
 * surfaces, an unmoved eye) or aged, and a camera moving faster than the
 * master's round trip kept the rank idle half the time (docs/
 * distributed.md, "Camera changes"). */
static bool gives_way(const intake_state *in, uint32_t epoch)
{
    return epoch < in->epoch && in->q->n > 0 && fifo_newest(in->q) > epoch;
}

/* Between slices: the intake; the batch goes on unless it gives way or the
 * job ends. */
static int between_slices(void *ctx, ct_error *err)
{
    intake_state *in = ctx;
    int rc = intake(in, err);
    if (rc < 0) return rc;
    return !in->shutdown && !(in->c->stop && *in->c->stop) && !gives_way(in, in->batch_epoch);
}

/* With no batch queued: the intake until one is queued, the job ends or
 * 50 ms have passed, napping between looks from 20 us doubling up to
 * --idle-sleep-us (0: no naps), so that an idle rank leaves its core to the
 * ranks that work while a busy link stays fast. */
static int await_work(intake_state *in, ct_error *err)
{
    const trank_config *c = in->c;
    unsigned most = c->idle_sleep_us, nap = most < 20 ? most : 20;
    double end = ct_now() + 0.05;
    for (;;) {
        int rc = intake(in, err);
        if (rc < 0) return rc;
        if (in->q->n || in->shutdown || (c->stop && *c->stop) || ct_now() > end) return 0;
        ct_nap(&nap, most);
    }
}

int trank_run(const trank_config *c, trank_stats *st, ct_error *err)
{
    memset(st, 0, sizeof *st);
    fifo q = {0};
    wire_buf msg = {0}, reply = {0};
    ct_request *reqs = NULL;
    ct_sample *samples = NULL;
    so_batch order = {0};
    uint32_t cap = 0;
    ct_pool *pool = NULL;
    int rc = pool_new(c->threads < 1 ? 1 : c->threads, &pool, err);
    if (rc) return rc;
    intake_state in = {.c = c, .q = &q, .msg = &msg};

    while (!in.shutdown && !(c->stop && *c->stop)) {
        /* 1. read everything that arrived */
        if ((rc = intake(&in, err)) < 0) goto out;
        if (in.shutdown) break;

        /* 2. one batch */
        if (q.n == 0) {
            if ((rc = await_work(&in, err)) < 0) goto out;
            continue;
        }
        queued qb = fifo_pop(&q);
        wire_buf b = qb.b;
        unsigned kind = 0;
        uint32_t count = 0;
        wire_mpi_requests h;
        /* A batch that gives way is answered from what its header said. */
        bool skip = gives_way(&in, qb.epoch);
        rc = wire_mpi_peek(b.data, b.len, PEER, &kind, &count, err);
        if (rc == 0 && !skip && count > cap) {
            ct_request *r = realloc(reqs, count * sizeof *r);
            ct_sample *s = r ? realloc(samples, count * sizeof *s) : NULL;
            if (r) reqs = r;
            if (s) samples = s;
            if (!r || !s) rc = ct_fail(err, CT_ENOMEM, "tracer %d: out of memory for a batch of %u", c->rank, count);
            else cap = count;
        }
        if (rc == 0 && !skip) rc = wire_mpi_decode_requests(b.data, b.len, PEER, &h, reqs, cap, &count, err);
        wire_buf_free(&b);
        if (rc < 0) goto out;
        st->requests += count;
        wire_mpi_samples sh = {.batch = qb.batch, .rank = (uint32_t)c->rank};
        uint32_t nout = 0;
        if (skip) {
            st->gave_way++;   /* a newer view's batch waits behind it: answer empty */
        } else {
            trc_view v = {.cam = h.cam, .width = (int)h.width, .height = (int)h.height};
            double t0 = ct_now();
            in.batch_epoch = h.epoch;
            size_t done = 0;
            rc = trace_batch(pool, c, &order, &v, reqs, count, samples, between_slices, &in, &st->rays, &done, err);
            st->busy_s += ct_now() - t0;
            if (rc < 0) goto out;
            if (rc > 0) {
                st->samples += count;
                nout = count;
            } else {
                /* Stopped: a newer view's batch waits, or the job ends. What
                 * was traced goes back all the same: the master
                 * keeps them (late samples: as new ones on diffuse
                 * surfaces or from an unmoved eye, aged where glossy) unless
                 * too stale, and drops the others. A display
                 * moving its camera every frame changes the view faster than
                 * a batch takes: answered empty, nearly all tracing was lost
                 * (docs/distributed.md, "Camera changes"). The rest of the
                 * batch is not traced: the newer view's requests come first. */
                st->gave_way++;
                if (!in.shutdown && !(c->stop && *c->stop)) {
                    st->samples += done;
                    nout = (uint32_t)done;
                }
            }
            rc = 0;
        }
        st->batches++;
        reply.len = 0;
        if ((rc = wire_mpi_encode_samples(&sh, samples, nout, &reply, err)) < 0) goto out;
        if ((rc = mpil_isend(0, MPIL_TAG_SAMPLES, &reply, err)) < 0) goto out;
    }
    rc = farewell(c, in.shutdown, &msg, err);
out:
    pool_free(pool);
    fifo_free(&q);
    wire_buf_free(&msg);
    wire_buf_free(&reply);
    free(reqs);
    free(samples);
    so_batch_free(&order);
    if (rc == 0)
        ct_debug(COMPONENT,
                 "rank %d: %llu batches (%llu gave way to a newer view), %llu requests, %llu samples, %llu rays, "
                 "%.2f s tracing",
                 c->rank, (unsigned long long)st->batches, (unsigned long long)st->gave_way,
                 (unsigned long long)st->requests, (unsigned long long)st->samples, (unsigned long long)st->rays,
                 st->busy_s);
    return rc;
}
