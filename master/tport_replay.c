/* tport_replay.c: the replay port (tport_replay.h). The recording is sorted
 * by request id; a batch's answer is looked up when it is submitted and
 * waits for poll. */
#include "master/tport_replay.h"

#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

typedef struct rport {
    tport base;
    ct_sample *rec;      /* by request id */
    size_t nrec;
    bool dense;          /* ids rec[0].request_id + i: found by index */
    tport_fifo fifo;
} rport;

static int by_id(const void *a, const void *b)
{
    uint64_t x = ((const ct_sample *)a)->request_id, y = ((const ct_sample *)b)->request_id;
    return x < y ? -1 : x > y;
}

/* The master answers the replay port's requests as fast as it can, so the
 * lookup is part of what bench_master times: a recording answers every
 * request it made, its ids are consecutive, and an index replaces the
 * binary search (4-5 % of a replay's profile). */
static const ct_sample *find(const rport *r, uint64_t id)
{
    if (r->dense) {
        uint64_t i = id - r->rec[0].request_id;
        return id >= r->rec[0].request_id && i < r->nrec ? &r->rec[i] : NULL;
    }
    size_t lo = 0, hi = r->nrec;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (r->rec[mid].request_id < id) lo = mid + 1;
        else hi = mid;
    }
    return lo < r->nrec && r->rec[lo].request_id == id ? &r->rec[lo] : NULL;
}

static int rport_view(tport *p, const tport_view *v, ct_error *err)
{
    (void)p;
    (void)v;
    (void)err;
    return CT_OK;
}

static int rport_submit(tport *p, int lane, uint64_t batch, const tport_view *v, const ct_request *req, uint32_t n,
                        ct_error *err)
{
    rport *r = (rport *)p;
    ct_sample *s = n ? malloc((size_t)n * sizeof *s) : NULL;
    if (n && !s) return ct_fail(err, CT_ENOMEM, "replay port: out of memory for %u samples", n);
    for (uint32_t i = 0; i < n; i++) {
        const ct_sample *x = find(r, req[i].id);
        if (!x || x->px != req[i].px || x->py != req[i].py) {
            free(s);
            return ct_fail(err, CT_EPROTO,
                           "replay: request %llu at (%g, %g) is not in the recording (recorded with other options?)",
                           (unsigned long long)req[i].id, (double)req[i].px, (double)req[i].py);
        }
        s[i] = *x;
        s[i].epoch = v->epoch;
    }
    return tport_fifo_push(&r->fifo, lane, batch, s, n, err);
}

static int rport_poll(tport *p, tport_reply *out, ct_error *err)
{
    (void)err;
    return tport_fifo_pop(&((rport *)p)->fifo, out);
}

static void rport_close(tport *p, double wait_s)
{
    (void)wait_s;
    rport *r = (rport *)p;
    tport_fifo_free(&r->fifo);
    free(r->rec);
    free(r);
}

static const tport_ops RPORT_OPS = {rport_view, rport_submit, rport_poll, rport_close};

int tport_replay_new(const ct_sample *rec, size_t n, int lanes, tport **out, ct_error *err)
{
    *out = NULL;
    if (lanes < 1) return ct_fail(err, CT_EINVAL, "replay port: %d lanes", lanes);
    rport *r = calloc(1, sizeof *r);
    if (!r || !(r->rec = malloc((n ? n : 1) * sizeof *r->rec))) {
        free(r);
        return ct_fail(err, CT_ENOMEM, "replay port: out of memory for %zu samples", n);
    }
    memcpy(r->rec, rec, n * sizeof *rec);
    r->nrec = n;
    qsort(r->rec, n, sizeof *r->rec, by_id);
    r->dense = n > 0;
    for (size_t i = 1; r->dense && i < n; i++) r->dense = r->rec[i].request_id == r->rec[i - 1].request_id + 1;
    r->base.ops = &RPORT_OPS;
    r->base.lanes = lanes;
    *out = &r->base;
    return CT_OK;
}
