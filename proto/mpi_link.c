/* mpi_link.c: the MPI transport (mpi_link.h). Single-threaded use: the
 * pending-send list is process state, touched only by the thread that
 * called mpil_init (MPI_THREAD_FUNNELED). */
#include "proto/mpi_link.h"

#include <limits.h>
#include <signal.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "common/timer.h"

/* Turns a failed MPI call into a ct_error naming file:line, the call and
 * MPI's error string (IOR's MPI_CHECK), and returns from the function. */
#define MPI_CHECK(call, err)                                                         \
    do {                                                                             \
        int mpi_rc_ = (call);                                                        \
        if (mpi_rc_ != MPI_SUCCESS) return mpi_fail((err), mpi_rc_, #call, __FILE__, __LINE__); \
    } while (0)

static int mpi_fail(ct_error *err, int rc, const char *call, const char *file, int line)
{
    char msg[MPI_MAX_ERROR_STRING];
    int len = 0;
    if (MPI_Error_string(rc, msg, &len) != MPI_SUCCESS) snprintf(msg, sizeof msg, "MPI error %d", rc);
    const char *paren = strchr(call, '(');
    int name_len = paren ? (int)(paren - call) : (int)strlen(call);
    return ct_fail(err, CT_EIO, "%s:%d: %.*s failed: %s", file, line, name_len, call, msg);
}

typedef struct pending_send {
    MPI_Request req;
    wire_buf buf;
} pending_send;

/* A receive under way (mpil_poll_recv), in the order its message was matched. */
typedef struct pending_recv {
    MPI_Request req;
    mpil_info info;
    wire_buf buf;
    int done;
} pending_recv;

/* At most this many receives in flight: far above what the tracers' windows
 * can have outstanding, low enough to bound the memory a flood could take. */
#define MAX_RECVS 4096

static struct {
    int active;
    pending_send *sends;
    size_t n, cap;
    pending_recv *recvs;
    size_t nr, rcap;
    wire_buf spare;   /* the caller's last buffer, for the next receive */
} L;

static void finish_recvs(void);

int mpil_init(int *argc, char ***argv, int *rank, int *size, ct_error *err)
{
    int provided = 0;
    /* Open MPI's shared-memory transport reads large messages straight from
     * the sender's memory (CMA); when the sender dies mid-transfer the
     * receiver fails inside MPI and the master dies before it can tell the
     * display. Copying through the shared segment instead costs one memcpy
     * of messages under a megabyte. A value the user set wins. */
    setenv("OMPI_MCA_btl_vader_single_copy_mechanism", "none", 0);
    MPI_CHECK(MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided), err);
    L.active = 1;
    /* Errors come back to us (and are reported with file:line) rather than
     * aborting the job inside MPI with a less useful message. */
    MPI_CHECK(MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN), err);
    MPI_CHECK(MPI_Comm_rank(MPI_COMM_WORLD, rank), err);
    MPI_CHECK(MPI_Comm_size(MPI_COMM_WORLD, size), err);
    if (provided < MPI_THREAD_FUNNELED)
        return ct_fail(err, CT_ESYS, "MPI_Init_thread: the MPI library offers thread level %d, FUNNELED needed",
                       provided);
    return 0;
}

void mpil_host(char *out, size_t cap)
{
    char name[MPI_MAX_PROCESSOR_NAME];
    int len = 0;
    if (!L.active || MPI_Get_processor_name(name, &len) != MPI_SUCCESS) {
        snprintf(out, cap, "?");
        return;
    }
    snprintf(out, cap, "%.*s", len, name);
}

int mpil_finalize(ct_error *err)
{
    if (!L.active) return 0;
    int rc = mpil_drain(5.0, err);
    if (rc < 0) mpil_cancel_pending();
    finish_recvs();
    free(L.sends);
    L.sends = NULL;
    L.n = L.cap = 0;
    L.active = 0;
    MPI_CHECK(MPI_Finalize(), err);
    return rc;
}

void mpil_abort(int code)
{
    if (!L.active) return;
    /* MPI_Abort reports to mpirun through the local daemon. Once, on a
     * loaded machine, that report arrived garbled ("Data unpack would read
     * past end of buffer" in show_help) and the job stayed up 30 s with a
     * stopped tracer. If MPI_Abort has not ended this process after 3 s, the
     * default SIGALRM action does; mpirun then ends the job for a rank that
     * died by a signal (SIGTERM, then SIGKILL, to the others). */
    signal(SIGALRM, SIG_DFL);
    alarm(3);
    MPI_Abort(MPI_COMM_WORLD, code);
}

/* Room for one more entry of elem bytes in the list *p of *n entries. */
static int grow_list(void **p, size_t n, size_t *cap, size_t elem, const char *what, ct_error *err)
{
    if (n < *cap) return 0;
    size_t c = *cap ? 2 * *cap : 16;
    void *q = realloc(*p, c * elem);
    if (!q) return ct_fail(err, CT_ENOMEM, "MPI %s list: out of memory for %zu entries", what, c);
    *p = q;
    *cap = c;
    return 0;
}

static int check_len(size_t len, ct_error *err)
{
    if (len > MPIL_MAX_MESSAGE || len > INT_MAX)
        return ct_fail(err, CT_ERANGE, "MPI message of %zu bytes over the limit %zu", len, MPIL_MAX_MESSAGE);
    return 0;
}

int mpil_isend(int dest, int tag, wire_buf *buf, ct_error *err)
{
    if (check_len(buf->len, err) < 0) return CT_ERANGE;
    if (grow_list((void **)&L.sends, L.n, &L.cap, sizeof *L.sends, "send", err) < 0) return CT_ENOMEM;
    pending_send *s = &L.sends[L.n];
    s->buf = *buf;
    MPI_CHECK(MPI_Isend(s->buf.data, (int)s->buf.len, MPI_BYTE, dest, tag, MPI_COMM_WORLD, &s->req), err);
    memset(buf, 0, sizeof *buf);
    L.n++;
    return 0;
}

int mpil_progress(ct_error *err)
{
    size_t j = 0;
    for (size_t i = 0; i < L.n; i++) {
        int done = 0;
        MPI_CHECK(MPI_Test(&L.sends[i].req, &done, MPI_STATUS_IGNORE), err);
        if (done)
            wire_buf_free(&L.sends[i].buf);
        else
            L.sends[j++] = L.sends[i];
    }
    L.n = j;
    return (int)L.n;
}

int mpil_drain(double timeout_s, ct_error *err)
{
    double end = ct_now() + timeout_s;
    for (;;) {
        int left = mpil_progress(err);
        if (left <= 0) return left;
        if (ct_now() > end)
            return ct_fail(err, CT_EIO, "%d MPI sends still pending after %.1f s (a peer stopped receiving)",
                           left, timeout_s);
        ct_sleep_us(200);
    }
}

void mpil_cancel_pending(void)
{
    for (size_t i = 0; i < L.n; i++) {
        MPI_Cancel(&L.sends[i].req);
        MPI_Request_free(&L.sends[i].req);
        /* The buffer may still be read by MPI after a failed cancel: leak it
         * rather than free memory a transfer might touch. */
    }
    L.n = 0;
}

/* Fills info from the status of a probed message; returns 1 (a message). */
static int info_of(const MPI_Status *st, mpil_info *info, ct_error *err)
{
    int count = 0;
    MPI_CHECK(MPI_Get_count(st, MPI_BYTE, &count), err);
    info->source = st->MPI_SOURCE;
    info->tag = st->MPI_TAG;
    info->size = count < 0 ? 0 : (size_t)count;
    return 1;
}

/* Matches every message that arrived and starts its receive. */
static int start_recvs(int source, int tag, ct_error *err)
{
    while (L.nr < MAX_RECVS) {
        int flag = 0;
        MPI_Message msg;
        MPI_Status st;
        MPI_CHECK(MPI_Improbe(source == MPIL_ANY ? MPI_ANY_SOURCE : source, tag == MPIL_ANY ? MPI_ANY_TAG : tag,
                              MPI_COMM_WORLD, &flag, &msg, &st),
                  err);
        if (!flag) return 0;
        if (grow_list((void **)&L.recvs, L.nr, &L.rcap, sizeof *L.recvs, "receive", err) < 0) return CT_ENOMEM;
        pending_recv *r = &L.recvs[L.nr];
        memset(r, 0, sizeof *r);
        r->buf = L.spare;
        r->buf.len = 0;
        memset(&L.spare, 0, sizeof L.spare);
        if (info_of(&st, &r->info, err) < 0) return CT_EIO;
        /* A matched message must be received: one over the limit is taken
         * into a one-byte buffer (MPI reports the truncation) and refused. */
        int over = check_len(r->info.size, err) < 0;
        if (wire_buf_reserve(&r->buf, over || !r->info.size ? 1 : r->info.size, err) < 0) return CT_ENOMEM;
        MPI_CHECK(MPI_Imrecv(r->buf.data, over ? 0 : (int)r->info.size, MPI_BYTE, &msg, &r->req), err);
        L.nr++;
        if (over) return CT_ERANGE;
    }
    return 0;
}

int mpil_poll_recv(int source, int tag, mpil_info *info, wire_buf *out, ct_error *err)
{
    int rc = start_recvs(source, tag, err);
    if (rc < 0) return rc;
    for (size_t i = 0; i < L.nr; i++) {
        pending_recv *r = &L.recvs[i];
        if (!r->done) MPI_CHECK(MPI_Test(&r->req, &r->done, MPI_STATUS_IGNORE), err);
        if (!r->done) continue;
        /* The first completed message whose sender has no older one still
         * in flight: a sender's messages keep their order. */
        int older = 0;
        for (size_t j = 0; j < i && !older; j++) older = L.recvs[j].info.source == r->info.source;
        if (older) continue;
        *info = r->info;
        /* Buffers go round: the caller's last one takes the next message. */
        if (L.spare.data) wire_buf_free(out);
        else L.spare = *out;
        *out = r->buf;
        out->len = r->info.size;
        memmove(r, r + 1, (L.nr - i - 1) * sizeof *r);
        L.nr--;
        return 1;
    }
    return 0;
}

int mpil_recv_wait(int source, int tag, double timeout_s, mpil_info *info, wire_buf *out, ct_error *err)
{
    double end = ct_now() + timeout_s;
    for (;;) {
        int got = mpil_poll_recv(source, tag, info, out, err);
        if (got) return got;
        if (mpil_progress(err) < 0) return CT_EIO;
        if (ct_now() >= end) return 0;
        ct_sleep_us(200);
    }
}

/* At the end, receives still in flight (a tracer was sending when the loop
 * stopped) get the time the senders' own drain needs; what is left then
 * (a stopped sender) is left to MPI, its buffer still reachable from L. */
static void finish_recvs(void)
{
    double end = ct_now() + 2.0;
    while (L.nr && ct_now() < end) {
        size_t j = 0;
        for (size_t i = 0; i < L.nr; i++) {
            pending_recv *r = &L.recvs[i];
            if (!r->done && MPI_Test(&r->req, &r->done, MPI_STATUS_IGNORE) != MPI_SUCCESS) r->done = -1;
            if (r->done > 0) wire_buf_free(&r->buf);
            else L.recvs[j++] = *r;
        }
        L.nr = j;
        if (L.nr) ct_sleep_us(200);
    }
    wire_buf_free(&L.spare);
    for (size_t i = 0; i < L.nr; i++)
        if (L.recvs[i].done == 0) MPI_Request_free(&L.recvs[i].req);
    if (L.nr == 0) {
        free(L.recvs);
        L.recvs = NULL;
        L.rcap = 0;
    }
}

int mpil_bcast_u64(int root, uint64_t *v, ct_error *err)
{
    MPI_CHECK(MPI_Bcast(v, 1, MPI_UINT64_T, root, MPI_COMM_WORLD), err);
    return 0;
}

int mpil_bcast(int root, wire_buf *buf, ct_error *err)
{
    int rank = 0;
    MPI_CHECK(MPI_Comm_rank(MPI_COMM_WORLD, &rank), err);
    uint64_t len = rank == root ? buf->len : 0;
    if (mpil_bcast_u64(root, &len, err) < 0) return CT_EIO;
    if (rank != root) {
        if (len > (uint64_t)SIZE_MAX / 2)
            return ct_fail(err, CT_ERANGE, "broadcast of %llu bytes too large", (unsigned long long)len);
        buf->len = 0;
        if (wire_buf_reserve(buf, len ? (size_t)len : 1, err) < 0) return CT_ENOMEM;
        buf->len = (size_t)len;
    }
    /* MPI counts are ints: large payloads go in steps. */
    for (uint64_t off = 0; off < len; off += MPIL_BCAST_CHUNK) {
        size_t n = (size_t)(len - off < MPIL_BCAST_CHUNK ? len - off : MPIL_BCAST_CHUNK);
        MPI_CHECK(MPI_Bcast(buf->data + off, (int)n, MPI_BYTE, root, MPI_COMM_WORLD), err);
    }
    return 0;
}

/* Longest nap between two tests of a collective that waits on a rank. */
#define COLL_NAP_US 1000

int mpil_allreduce_max(int *v, ct_error *err)
{
    /* Non-blocking and tested with naps: the tracers wait here while the
     * master loads the scene and solves its radiosity (tens of seconds),
     * and the master while they build their scenes. MPI_Allreduce's wait
     * spins (yielding when oversubscribed): on a workstation running all
     * ranks the tracers took CPU from the master's solve (table, two
     * tracer ranks on two cores: 1.4-8.9 s of CPU each during a 17-26 s
     * start; 0.5-0.7 s, their own scene set-up, now). */
    int in = *v;
    MPI_Request req;
    MPI_CHECK(MPI_Iallreduce(&in, v, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD, &req), err);
    for (unsigned nap = 20;;) {
        int done = 0;
        MPI_CHECK(MPI_Test(&req, &done, MPI_STATUS_IGNORE), err);
        if (done) return 0;
        ct_nap(&nap, COLL_NAP_US);
    }
}
