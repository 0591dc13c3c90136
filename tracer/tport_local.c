/* tport_local.c: the in-process tracer port (tport_local.h). Replies wait
 * in a FIFO; the one poll returned last is freed by the next poll. */
#include "tracer/tport_local.h"

#include <stdlib.h>
#include <string.h>

typedef struct reply {
    int lane;
    uint64_t batch;
    ct_sample *s;
    uint32_t n;
} reply;

typedef struct lport {
    tport base;
    const trc_tracer *t;
    ct_pool *pool;
    uint32_t epoch;      /* newest view */
    reply *q;            /* FIFO */
    size_t head, n, cap;
    ct_sample *last;     /* the samples handed out by the last poll */
    trc_stats st;
} lport;

static int lport_view(tport *p, const tport_view *v, ct_error *err)
{
    (void)err;
    lport *l = (lport *)p;
    if (v->epoch > l->epoch) l->epoch = v->epoch;
    return CT_OK;
}

static int lport_submit(tport *p, int lane, uint64_t batch, const tport_view *v, const ct_request *r, uint32_t n,
                        ct_error *err)
{
    lport *l = (lport *)p;
    if (lane < 0 || lane >= p->lanes) return ct_fail(err, CT_EINVAL, "local tracer port: no lane %d", lane);
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 16;
        reply *q = malloc(cap * sizeof *q);
        if (!q) return ct_fail(err, CT_ENOMEM, "local tracer port: out of memory");
        for (size_t i = 0; i < l->n; i++) q[i] = l->q[(l->head + i) % l->cap];
        free(l->q);
        l->q = q;
        l->cap = cap;
        l->head = 0;
    }
    reply rp = {lane, batch, NULL, 0};
    if (v->epoch > l->epoch) l->epoch = v->epoch;
    if (v->epoch == l->epoch && n > 0) {
        /* as a tracer rank: a batch of an older epoch is answered empty */
        rp.s = malloc((size_t)n * sizeof *rp.s);
        if (!rp.s) return ct_fail(err, CT_ENOMEM, "local tracer port: out of memory for %u samples", n);
        trc_view tv = {.cam = v->cam, .width = (int)v->width, .height = (int)v->height};
        trc_trace_par(l->t, l->pool, &tv, r, n, rp.s, false, &l->st);
        rp.n = n;
    }
    l->q[(l->head + l->n) % l->cap] = rp;
    l->n++;
    return CT_OK;
}

static int lport_poll(tport *p, tport_reply *out, ct_error *err)
{
    (void)err;
    lport *l = (lport *)p;
    free(l->last);
    l->last = NULL;
    if (!l->n) return 0;
    reply rp = l->q[l->head];
    l->head = (l->head + 1) % l->cap;
    l->n--;
    l->last = rp.s;
    *out = (tport_reply){.lane = rp.lane, .batch = rp.batch, .samples = rp.s, .n = rp.n};
    return 1;
}

static void lport_close(tport *p, double wait_s)
{
    (void)wait_s;
    lport *l = (lport *)p;
    for (size_t i = 0; i < l->n; i++) free(l->q[(l->head + i) % l->cap].s);
    free(l->q);
    free(l->last);
    free(l);
}

static const tport_ops LPORT_OPS = {lport_view, lport_submit, lport_poll, lport_close};

int tport_local_new(const trc_tracer *t, ct_pool *pool, int lanes, tport **out, ct_error *err)
{
    *out = NULL;
    if (lanes < 1) return ct_fail(err, CT_EINVAL, "local tracer port: %d lanes", lanes);
    lport *l = calloc(1, sizeof *l);
    if (!l) return ct_fail(err, CT_ENOMEM, "local tracer port: out of memory");
    l->base.ops = &LPORT_OPS;
    l->base.lanes = lanes;
    l->t = t;
    l->pool = pool;
    *out = &l->base;
    return CT_OK;
}

trc_stats tport_local_stats(const tport *p)
{
    return ((const lport *)p)->st;
}
