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
    so_batch order;       /* a batch in screen order (screen_order.h) */
} lport;

/* Traces r[0..n) into s in screen order; as it came without the memory. */
static void trace_in_screen_order(lport *l, const trc_view *tv, const ct_request *r, uint32_t n, ct_sample *s)
{
    if (so_batch_order(&l->order, r, n) != CT_OK) {
        trc_trace_par(l->t, l->pool, tv, r, n, s, false, &l->st);
        return;
    }
    trc_trace_par(l->t, l->pool, tv, l->order.req, n, l->order.out, false, &l->st);
    so_batch_scatter(&l->order, n, s);
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
        /* drv submits for the current view only, so this does not happen
         * through it; a batch of a view left is answered empty, as a rank
         * does once a newer batch is queued behind it */
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
    so_batch_free(&l->order);
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
