/* tport_mpi.c: the MPI tracer port (tport.h): encodes request batches and
 * camera changes for the tracer ranks (proto/wire_mpi.h) and takes their
 * sample batches with mpil_poll_recv, so that a tracer stopped in the
 * middle of a large message never holds the master. */
#include <stdio.h>
#include <stdlib.h>

#include "common/log.h"
#include "common/timer.h"
#include "proto/mpi_link.h"
#include "proto/tport.h"
#include "proto/wire_mpi.h"

typedef struct mport {
    tport base;
    wire_buf in, out;
    ct_sample *samples;
    uint32_t cap;
    double *left_at;    /* per lane: when it said BYE (0: still working) */
    int nleft;          /* lanes that said BYE */
} mport;

static int mport_view(tport *p, const tport_view *v, ct_error *err)
{
    mport *m = (mport *)p;
    wire_mpi_camera mc = {.epoch = v->epoch, .width = v->width, .height = v->height, .cam = v->cam};
    for (int r = 1; r <= p->lanes; r++) {
        m->out.len = 0;
        int rc = wire_mpi_encode_camera(&mc, &m->out, err);
        if (rc == 0) rc = mpil_isend(r, MPIL_TAG_CAMERA, &m->out, err);
        if (rc) return rc;
    }
    return mpil_progress(err) < 0 ? CT_EIO : CT_OK;
}

static int mport_submit(tport *p, int lane, uint64_t batch, const tport_view *v, const ct_request *r, uint32_t n,
                        ct_error *err)
{
    mport *m = (mport *)p;
    wire_mpi_requests h = {.batch = batch, .epoch = v->epoch, .width = v->width, .height = v->height, .cam = v->cam};
    m->out.len = 0;
    int rc = wire_mpi_encode_requests(&h, r, n, &m->out, err);
    if (rc == 0) rc = mpil_isend(lane + 1, MPIL_TAG_REQUESTS, &m->out, err);
    return rc;
}

static int mport_poll(tport *p, tport_reply *out, ct_error *err)
{
    mport *m = (mport *)p;
    if (mpil_progress(err) < 0) return CT_EIO;
    mpil_info info;
    /* Never a blocking receive: a stopped tracer in the middle of a large
     * message would hold the loop, its watchdog included. */
    int got = mpil_poll_recv(MPIL_ANY, MPIL_ANY, &info, &m->in, err);
    if (got < 0) return got;
    double now = ct_now();
    if (got && info.tag == MPIL_TAG_BYE && info.source >= 1 && info.source <= p->lanes) {
        /* A tracer left on a signal: mpirun signals every rank at once, so
         * a master whose own signal has not come within a second (its loop
         * stops before polling again) lost a tracer. */
        if (m->left_at[info.source - 1] == 0) {
            m->left_at[info.source - 1] = now;
            m->nleft++;
        }
        got = 0;
    }
    for (int i = 0; i < p->lanes && m->nleft; i++)
        if (m->left_at[i] > 0 && now - m->left_at[i] > 1.0)
            return ct_fail(err, CT_EIO, "tracer rank %d left the job (it got a signal)", i + 1);
    if (!got) return 0;
    char peer[32];
    snprintf(peer, sizeof peer, "tracer rank %d", info.source);
    if (info.tag != MPIL_TAG_SAMPLES || info.source < 1 || info.source > p->lanes)
        return ct_fail(err, CT_EPROTO, "%s: unexpected MPI message with tag %d", peer, info.tag);
    unsigned kind;
    uint32_t count;
    int rc = wire_mpi_peek(m->in.data, m->in.len, peer, &kind, &count, err);
    if (rc) return rc;
    if (count > m->cap || !m->samples) {
        uint32_t cap = count > 256 ? count : 256;
        ct_sample *s = realloc(m->samples, cap * sizeof *s);
        if (!s) return ct_fail(err, CT_ENOMEM, "master: out of memory for %u samples", cap);
        m->samples = s;
        m->cap = cap;
    }
    wire_mpi_samples h;
    if ((rc = wire_mpi_decode_samples(m->in.data, m->in.len, peer, &h, m->samples, m->cap, &count, err))) return rc;
    *out = (tport_reply){.lane = info.source - 1, .batch = h.batch, .samples = m->samples, .n = count};
    return 1;
}

/* Sends SHUTDOWN, then takes (and drops) what the tracers still send until
 * each has said BYE: a large sample message completes only when it is
 * received, and a tracer's MPI_Finalize waits for its sends (docs/protocol.md,
 * "Leaving in order"). A tracer that stopped or died gets wait_s. */
static void mport_close(tport *p, double wait_s)
{
    mport *m = (mport *)p;
    wire_mpi_control ctl = {.op = WIRE_MPI_OP_SHUTDOWN};
    ct_error e;
    for (int r = 1; r <= p->lanes; r++) {
        m->out.len = 0;
        if (wire_mpi_encode_control(&ctl, &m->out, &e) == 0) mpil_isend(r, MPIL_TAG_CONTROL, &m->out, &e);
    }
    double end = ct_now() + wait_s;
    int left = p->lanes - m->nleft;
    while (left > 0) {
        mpil_info info;
        double rest = end - ct_now();
        if (rest <= 0 || mpil_recv_wait(MPIL_ANY, MPIL_ANY, rest, &info, &m->in, &e) <= 0) break;
        if (info.tag == MPIL_TAG_BYE && info.source >= 1 && info.source <= p->lanes &&
            m->left_at[info.source - 1] == 0) {
            m->left_at[info.source - 1] = ct_now();
            left--;
        }
    }
    if (left > 0)
        ct_debug("master", "%d tracer rank%s did not say BYE within %.1f s", left, left == 1 ? "" : "s", wait_s);
    double rest = end - ct_now();
    if (mpil_drain(rest > 0.1 ? rest : 0.1, &e) < 0) ct_warn("master", "%s", e.msg);
    wire_buf_free(&m->in);
    wire_buf_free(&m->out);
    free(m->samples);
    free(m->left_at);
    free(m);
}

static const tport_ops MPORT_OPS = {mport_view, mport_submit, mport_poll, mport_close};

int tport_mpi_new(int ntracers, tport **out, ct_error *err)
{
    *out = NULL;
    if (ntracers < 1) return ct_fail(err, CT_EINVAL, "the MPI port needs at least one tracer rank");
    mport *m = calloc(1, sizeof *m);
    if (!m) return ct_fail(err, CT_ENOMEM, "master: out of memory");
    m->left_at = calloc((size_t)ntracers, sizeof *m->left_at);
    if (!m->left_at) {
        free(m);
        return ct_fail(err, CT_ENOMEM, "master: out of memory");
    }
    m->base.ops = &MPORT_OPS;
    m->base.lanes = ntracers;
    *out = &m->base;
    return CT_OK;
}
