/* tport_local.c: the in-process tracer port (tport_local.h). */
#include "tracer/tport_local.h"

#include <stdlib.h>
#include <string.h>

#include "tracer/screen_order.h"

typedef struct lport {
    tport base;
    const trc_tracer *t;
    ct_pool *pool;
    uint32_t epoch;      /* newest view */
    tport_fifo fifo;
    trc_stats st;
    so_buf keys;          /* a batch in screen order (screen_order.h) */
    uint32_t *perm;
    ct_request *req;
    ct_sample *out;
    size_t cap;
} lport;

/* Traces r[0..n) into s in screen order; as it came without the memory. */
static void trace_in_screen_order(lport *l, const trc_view *tv, const ct_request *r, uint32_t n, ct_sample *s)
{
    if (n > l->cap) {
        uint32_t *p = realloc(l->perm, (size_t)n * sizeof *p);
        if (p) l->perm = p;
        ct_request *q = p ? realloc(l->req, (size_t)n * sizeof *q) : NULL;
        if (q) l->req = q;
        ct_sample *o = q ? realloc(l->out, (size_t)n * sizeof *o) : NULL;
        if (o) l->out = o;
        if (o) l->cap = n;
    }
    if (n > l->cap || so_requests(&l->keys, r, n, l->perm) != CT_OK) {
        trc_trace_par(l->t, l->pool, tv, r, n, s, false, &l->st);
        return;
    }
    for (uint32_t i = 0; i < n; i++) l->req[i] = r[l->perm[i]];
    trc_trace_par(l->t, l->pool, tv, l->req, n, l->out, false, &l->st);
    for (uint32_t i = 0; i < n; i++) s[l->perm[i]] = l->out[i];
}

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
    ct_sample *s = NULL;
    uint32_t ns = 0;
    if (v->epoch > l->epoch) l->epoch = v->epoch;
    if (v->epoch == l->epoch && n > 0) {
        /* as a tracer rank: a batch of an older epoch is answered empty */
        if (!(s = malloc((size_t)n * sizeof *s)))
            return ct_fail(err, CT_ENOMEM, "local tracer port: out of memory for %u samples", n);
        trc_view tv = {.cam = v->cam, .width = (int)v->width, .height = (int)v->height};
        trace_in_screen_order(l, &tv, r, n, s);
        ns = n;
    }
    return tport_fifo_push(&l->fifo, lane, batch, s, ns, err);
}

static int lport_poll(tport *p, tport_reply *out, ct_error *err)
{
    (void)err;
    return tport_fifo_pop(&((lport *)p)->fifo, out);
}

static void lport_close(tport *p, double wait_s)
{
    (void)wait_s;
    lport *l = (lport *)p;
    tport_fifo_free(&l->fifo);
    so_free(&l->keys);
    free(l->perm);
    free(l->req);
    free(l->out);
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
