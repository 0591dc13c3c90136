/* xport_queue.c: the send queue of one connection (xport.h). Frames are
 * encoded straight into the tail segment and written from the head segment
 * by offset, several at a time (writev): after encoding, a frame's bytes are
 * never moved. A segment is closed once it holds SEG_TARGET bytes, so a
 * frame never spans two segments (xport_queue_partial reads the length of
 * the frame being written from its own header). What is queued, and when,
 * is the callers' flow control: the master's texture updates are paced by
 * the display's acknowledgements (docs/protocol.md, "Flow control"). */
#include "proto/xport.h"

#include <stdlib.h>
#include <string.h>

#include "proto/wire_io.h"

/* Segment size: large enough that a writev of a few segments fills a
 * socket buffer, small enough that an emptied one is cheap to keep. */
#define SEG_TARGET (256u << 10)
#define SPARES     4

typedef struct seg {
    struct seg *next;
    wire_buf b;
    size_t off;              /* bytes of b already written */
} seg;

struct xport_queue {
    seg *head, *tail;
    seg *spare[SPARES];      /* emptied segments kept for reuse */
    int nspare;
    size_t max_bytes, bytes;
    size_t tail_seen;        /* tail->b.len already counted in bytes */
    size_t frame_left;       /* unwritten bytes of a frame whose first bytes are written */
    uint64_t pushed, written;
};

int xport_queue_new(size_t max_bytes, xport_queue **out, ct_error *err)
{
    xport_queue *q = calloc(1, sizeof *q);
    if (!q) return ct_fail(err, CT_ENOMEM, "send queue: out of memory");
    q->max_bytes = max_bytes;
    *out = q;
    return 0;
}

static void seg_free(seg *s)
{
    wire_buf_free(&s->b);
    free(s);
}

void xport_queue_free(xport_queue *q)
{
    if (!q) return;
    for (seg *s = q->head, *n; s; s = n) {
        n = s->next;
        seg_free(s);
    }
    for (int i = 0; i < q->nspare; i++) seg_free(q->spare[i]);
    free(q);
}

/* The segment frames are appended to: the tail, or a new one when the tail
 * is full (or there is none). */
static seg *open_tail(xport_queue *q, ct_error *err)
{
    if (q->tail && q->tail->b.len < SEG_TARGET) return q->tail;
    seg *s = q->nspare ? q->spare[--q->nspare] : calloc(1, sizeof *s);
    if (!s) {
        ct_fail(err, CT_ENOMEM, "send queue: out of memory");
        return NULL;
    }
    s->next = NULL;
    s->b.len = 0;
    s->off = 0;
    if (q->tail) q->tail->next = s;
    else q->head = s;
    q->tail = s;
    q->tail_seen = 0;
    return s;
}

int xport_queue_push(xport_queue *q, const wire_msg *m, ct_error *err)
{
    seg *s = open_tail(q, err);
    if (!s) return CT_ENOMEM;
    size_t before = s->b.len;
    int rc = wire_encode(m, &s->b, err);
    if (rc) return rc;
    size_t n = s->b.len - before;
    if (q->bytes && q->bytes + n > q->max_bytes) {
        s->b.len = before;   /* nothing of it is queued */
        return XPORT_QUEUE_FULL;
    }
    q->bytes += n;
    q->tail_seen = s->b.len;
    q->pushed++;
    return 0;
}

wire_buf *xport_queue_tail(xport_queue *q, ct_error *err)
{
    seg *s = open_tail(q, err);
    return s ? &s->b : NULL;
}

void xport_queue_commit(xport_queue *q, uint64_t frames)
{
    if (!q->tail) return;
    q->bytes += q->tail->b.len - q->tail_seen;
    q->tail_seen = q->tail->b.len;
    q->pushed += frames;
}

int xport_queue_iov(const xport_queue *q, struct iovec *iov, int max)
{
    int n = 0;
    for (const seg *s = q->head; s && n < max; s = s->next) {
        size_t len = (s == q->tail ? q->tail_seen : s->b.len) - s->off;
        if (len) iov[n++] = (struct iovec){s->b.data + s->off, len};
    }
    return n;
}

/* Drops the emptied head segment, keeping a few for reuse. */
static void pop_head(xport_queue *q)
{
    seg *s = q->head;
    q->head = s->next;
    if (!q->head) q->tail = NULL;
    if (q->nspare < SPARES && s->b.cap <= 4 * SEG_TARGET) q->spare[q->nspare++] = s;
    else seg_free(s);
}

void xport_queue_advance(xport_queue *q, size_t n)
{
    if (n > q->bytes) n = q->bytes;
    q->bytes -= n;
    q->written += n;
    while (n) {
        seg *s = q->head;
        if (!q->frame_left) q->frame_left = WIRE_HEADER_SIZE + wio_get_u32(s->b.data + s->off + 4);
        size_t take = n < q->frame_left ? n : q->frame_left;
        s->off += take;
        q->frame_left -= take;
        n -= take;
        if (s->off == s->b.len && s != q->tail) pop_head(q);
    }
    /* An emptied tail starts over rather than growing. */
    if (q->head && q->head == q->tail && q->head->off == q->tail_seen && q->tail_seen == q->head->b.len) {
        q->head->b.len = q->head->off = 0;
        q->tail_seen = 0;
    }
}

size_t xport_queue_partial(const xport_queue *q)
{
    return q->frame_left;
}

bool xport_queue_empty(const xport_queue *q)
{
    return q->bytes == 0;
}

xport_queue_stats xport_queue_get_stats(const xport_queue *q)
{
    xport_queue_stats s = {q->bytes, q->pushed, q->written};
    return s;
}
