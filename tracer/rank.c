/* rank.c: a tracer rank's loop (rank.h). Every received message is read at
 * once (so the master's sends complete), request batches wait in a FIFO,
 * camera and control messages act immediately. */
#include "tracer/rank.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "common/timer.h"
#include "proto/mpi_link.h"
#include "proto/wire_mpi.h"

#define COMPONENT "tracer"

typedef struct fifo {
    wire_buf *items;
    size_t head, n, cap;
} fifo;

static int fifo_push(fifo *f, wire_buf *b, ct_error *err)
{
    if (f->n == f->cap) {
        size_t cap = f->cap ? 2 * f->cap : 8;
        wire_buf *p = malloc(cap * sizeof *p);
        if (!p) return ct_fail(err, CT_ENOMEM, "tracer: out of memory queueing request batches");
        for (size_t i = 0; i < f->n; i++) p[i] = f->items[(f->head + i) % f->cap];
        free(f->items);
        f->items = p;
        f->cap = cap;
        f->head = 0;
    }
    f->items[(f->head + f->n) % f->cap] = *b;
    memset(b, 0, sizeof *b);
    f->n++;
    return 0;
}

static wire_buf fifo_pop(fifo *f)
{
    wire_buf b = f->items[f->head];
    f->head = (f->head + 1) % f->cap;
    f->n--;
    return b;
}

static void fifo_free(fifo *f)
{
    while (f->n) {
        wire_buf b = fifo_pop(f);
        wire_buf_free(&b);
    }
    free(f->items);
}

typedef struct work {
    const trc_tracer *t;
    const trc_view *v;
    const ct_request *req;
    ct_sample *out;
    size_t n;
    trc_stats st;
} work;

static void *trace_part(void *arg)
{
    work *w = arg;
    if (w->n) trc_trace(w->t, w->v, w->req, w->n, w->out, &w->st);
    return NULL;
}

/* Traces n requests on up to `threads` threads; the records do not depend on
 * the split (each sample's randomness is its own, tracer.h). */
static void trace_batch(const trank_config *c, const trc_view *v, const ct_request *req, size_t n,
                        ct_sample *out)
{
    int nt = c->threads < 1 ? 1 : c->threads;
    if ((size_t)nt > n) nt = n ? (int)n : 1;
    work w[64];
    if (nt > 64) nt = 64;
    pthread_t th[64];
    int started[64] = {0};
    size_t per = (n + (size_t)nt - 1) / (size_t)nt;
    for (int i = 0; i < nt; i++) {
        size_t b = (size_t)i * per, e = b + per > n ? n : b + per;
        w[i] = (work){c->tracer, v, req + b, out + b, b < e ? e - b : 0, {0}};
        if (i > 0) started[i] = pthread_create(&th[i], NULL, trace_part, &w[i]) == 0;
    }
    trace_part(&w[0]);
    for (int i = 1; i < nt; i++) {
        if (started[i]) pthread_join(th[i], NULL);
        else trace_part(&w[i]);   /* no thread: do the part here */
    }
}

int trank_run(const trank_config *c, trank_stats *st, ct_error *err)
{
    memset(st, 0, sizeof *st);
    fifo q = {0};
    wire_buf msg = {0}, reply = {0};
    ct_request *reqs = NULL;
    ct_sample *samples = NULL;
    uint32_t cap = 0;
    uint32_t epoch = 0;
    char peer[32];
    snprintf(peer, sizeof peer, "master (rank 0)");
    int rc = 0, shutdown = 0;

    while (!shutdown && !(c->stop && *c->stop)) {
        /* 1. read everything that arrived */
        mpil_info info;
        for (;;) {
            int got = mpil_probe(0, MPIL_ANY, &info, err);
            if (got < 0) { rc = got; goto out; }
            if (!got) break;
            if ((rc = mpil_recv(&info, &msg, err)) < 0) goto out;
            unsigned kind = 0;
            uint32_t count = 0;
            if ((rc = wire_mpi_peek(msg.data, msg.len, peer, &kind, &count, err)) < 0) goto out;
            if (kind == WIRE_MPI_REQUESTS) {
                if ((rc = fifo_push(&q, &msg, err)) < 0) goto out;
            } else if (kind == WIRE_MPI_CAMERA) {
                wire_mpi_camera cam;
                if ((rc = wire_mpi_decode_camera(msg.data, msg.len, peer, &cam, err)) < 0) goto out;
                if (cam.epoch > epoch) epoch = cam.epoch;
            } else if (kind == WIRE_MPI_CONTROL) {
                wire_mpi_control ctl;
                if ((rc = wire_mpi_decode_control(msg.data, msg.len, peer, &ctl, err)) < 0) goto out;
                if (ctl.op == WIRE_MPI_OP_SHUTDOWN) shutdown = 1;
                /* CONFIG is not needed: every rank parses the same command line. */
            } else {
                rc = ct_fail(err, CT_EPROTO, "tracer %d: unexpected MPI message kind %u from the master", c->rank,
                             kind);
                goto out;
            }
        }
        if (shutdown) break;
        if ((rc = mpil_progress(err)) < 0) goto out;

        /* 2. one batch */
        if (q.n == 0) {
            int got = mpil_wait(0, MPIL_ANY, c->idle_sleep_us, 0.05, &info, err);
            if (got < 0) { rc = got; goto out; }
            continue;
        }
        wire_buf b = fifo_pop(&q);
        unsigned kind = 0;
        uint32_t count = 0;
        rc = wire_mpi_peek(b.data, b.len, peer, &kind, &count, err);
        if (rc == 0 && count > cap) {
            ct_request *r = realloc(reqs, count * sizeof *r);
            ct_sample *s = r ? realloc(samples, count * sizeof *s) : NULL;
            if (r) reqs = r;
            if (s) samples = s;
            if (!r || !s) rc = ct_fail(err, CT_ENOMEM, "tracer %d: out of memory for a batch of %u", c->rank, count);
            else cap = count;
        }
        wire_mpi_requests h;
        if (rc == 0) rc = wire_mpi_decode_requests(b.data, b.len, peer, &h, reqs, cap, &count, err);
        wire_buf_free(&b);
        if (rc < 0) goto out;
        if (h.epoch > epoch) epoch = h.epoch;
        wire_mpi_samples sh = {.batch = h.batch, .rank = (uint32_t)c->rank};
        uint32_t nout = 0;
        if (h.epoch < epoch) {
            st->stale_batches++;   /* the camera moved on: answer empty */
        } else {
            trc_view v = {.cam = h.cam, .width = (int)h.width, .height = (int)h.height};
            double t0 = ct_now();
            trace_batch(c, &v, reqs, count, samples);
            st->busy_s += ct_now() - t0;
            st->samples += count;
            nout = count;
        }
        st->batches++;
        reply.len = 0;
        if ((rc = wire_mpi_encode_samples(&sh, samples, nout, &reply, err)) < 0) goto out;
        if ((rc = mpil_isend(0, MPIL_TAG_SAMPLES, &reply, err)) < 0) goto out;
    }
out:
    fifo_free(&q);
    wire_buf_free(&msg);
    wire_buf_free(&reply);
    free(reqs);
    free(samples);
    if (rc == 0) ct_debug(COMPONENT, "rank %d: %llu batches (%llu stale), %llu samples, %.2f s tracing", c->rank,
                          (unsigned long long)st->batches, (unsigned long long)st->stale_batches,
                          (unsigned long long)st->samples, st->busy_s);
    return rc;
}
