/* xport_queue.c: the bounded send queue of one connection. Messages are
 * encoded when queued, except TEX_PATCH, which is kept as raw texels until it
 * reaches the head so that newer patches of the same texture area can be
 * merged into it (newest wins) instead of piling up when the peer falls
 * behind. Merging never crosses a barrier: any message other than TEX_PATCH,
 * STATS, SAMPLES, PING and PONG (a TEX_ALLOC/FREE/PROJECTION changes what texels mean,
 * a FRAME closes a lockstep frame). Policy: docs/protocol.md, "Send queue". */
#include "proto/xport.h"

#include <stdlib.h>
#include <string.h>

typedef struct qent {
    struct qent *prev, *next;
    bool patch;
    wire_buf bytes;          /* !patch: the encoded frame */
    uint32_t tex, x, y, w, h; /* patch: rectangle and texels (w*h*3 halves) */
    uint16_t *texels;
    size_t cost;
} qent;

struct xport_queue {
    qent *head, *tail;
    qent *barrier;           /* last barrier entry still queued (NULL: none) */
    size_t max_bytes, bytes, entries;
    wire_buf out;            /* frame being written */
    size_t out_off;
    uint64_t merged, pushed;
};

int xport_queue_new(size_t max_bytes, xport_queue **out, ct_error *err)
{
    xport_queue *q = calloc(1, sizeof *q);
    if (!q) return ct_fail(err, CT_ENOMEM, "send queue: out of memory");
    q->max_bytes = max_bytes;
    *out = q;
    return 0;
}

static void ent_free(qent *e)
{
    wire_buf_free(&e->bytes);
    free(e->texels);
    free(e);
}

static void unlink_ent(xport_queue *q, qent *e)
{
    if (e->prev) e->prev->next = e->next;
    else q->head = e->next;
    if (e->next) e->next->prev = e->prev;
    else q->tail = e->prev;
    if (q->barrier == e) q->barrier = NULL;
    q->bytes -= e->cost;
    q->entries--;
}

static void append(xport_queue *q, qent *e)
{
    e->prev = q->tail;
    e->next = NULL;
    if (q->tail) q->tail->next = e;
    else q->head = e;
    q->tail = e;
    q->bytes += e->cost;
    q->entries++;
}

void xport_queue_free(xport_queue *q)
{
    if (!q) return;
    for (qent *e = q->head, *n; e; e = n) {
        n = e->next;
        ent_free(e);
    }
    wire_buf_free(&q->out);
    free(q);
}

static bool is_barrier(unsigned type)
{
    return type != WIRE_TEX_PATCH && type != WIRE_STATS && type != WIRE_PING && type != WIRE_PONG &&
           type != WIRE_SAMPLES;
}

static size_t patch_cost(uint32_t w, uint32_t h)
{
    return (size_t)w * h * 6 + 32;
}

/* Copies texels of rectangle (sx, sy, sw, sh) into a (dx, dy, dw, dh) buffer. */
static void blit(uint16_t *dst, uint32_t dx, uint32_t dy, uint32_t dw, const uint16_t *src, uint32_t sx,
                 uint32_t sy, uint32_t sw, uint32_t sh)
{
    for (uint32_t r = 0; r < sh; r++)
        memcpy(dst + 3 * ((size_t)(sy + r - dy) * dw + (sx - dx)), src + 3 * (size_t)r * sw,
               (size_t)sw * 3 * sizeof *dst);
}

static bool overlaps(const qent *a, uint32_t x, uint32_t y, uint32_t w, uint32_t h)
{
    return x < a->x + a->w && a->x < x + w && y < a->y + a->h && a->y < y + h;
}

/* Whether a patch of the same texture queued after e overlaps e's area (then
 * e's texels may not move later in the queue, or older texels would win). */
static bool overlapped_later(const qent *e)
{
    for (const qent *o = e->next; o; o = o->next)
        if (o->patch && o->tex == e->tex && overlaps(o, e->x, e->y, e->w, e->h)) return true;
    return false;
}

static bool contains(const qent *o, uint32_t x, uint32_t y, uint32_t w, uint32_t h)
{
    return x >= o->x && y >= o->y && x + w <= o->x + o->w && y + h <= o->y + o->h;
}

/* Whether the union of two rectangles is exactly their bounding box (same
 * columns and touching or overlapping rows, or the transpose). */
static bool union_is_box(const qent *a, const qent *b)
{
    if (a->x == b->x && a->w == b->w) return a->y <= b->y + b->h && b->y <= a->y + a->h;
    if (a->y == b->y && a->h == b->h) return a->x <= b->x + b->w && b->x <= a->x + a->w;
    return false;
}

int xport_queue_push(xport_queue *q, const wire_msg *m, ct_error *err)
{
    if (m->type != WIRE_TEX_PATCH) {
        wire_buf b = {0};
        int rc = wire_encode(m, &b, err);
        if (rc) return rc;
        if (q->entries && q->bytes + b.len > q->max_bytes) {
            wire_buf_free(&b);
            return XPORT_QUEUE_FULL;
        }
        qent *e = calloc(1, sizeof *e);
        if (!e) {
            wire_buf_free(&b);
            return ct_fail(err, CT_ENOMEM, "send queue: out of memory");
        }
        e->bytes = b;
        e->cost = b.len;
        append(q, e);
        if (is_barrier(m->type)) q->barrier = e;
        q->pushed++;
        return 0;
    }

    const wire_tex_patch *p = &m->u.tex_patch;
    /* Check it will encode before taking it (a bad patch must fail here, not at the head). */
    if (p->w == 0 || p->h == 0 || (uint64_t)p->w * p->h > WIRE_PATCH_MAX_TEXELS || p->w > WIRE_TEX_MAX_DIM ||
        p->h > WIRE_TEX_MAX_DIM || p->x > WIRE_TEX_MAX_DIM - p->w || p->y > WIRE_TEX_MAX_DIM - p->h)
        return ct_fail(err, CT_EINVAL, "send queue: TEX_PATCH %ux%u at %u,%u out of range", p->w, p->h, p->x, p->y);

    /* 1. The newest queued patch of this texture (after the last barrier)
     *    that overlaps the new one takes its texels in place when it contains
     *    it: no new entry, no new memory. A newer overlapping patch that does
     *    not contain it stops the search (writing into an older one would
     *    let that newer one's older texels win). */
    for (qent *o = q->tail; o && o != q->barrier; o = o->prev) {
        if (!o->patch || o->tex != p->tex || !overlaps(o, p->x, p->y, p->w, p->h)) continue;
        if (contains(o, p->x, p->y, p->w, p->h)) {
            blit(o->texels, o->x, o->y, o->w, p->texels, p->x, p->y, p->w, p->h);
            q->merged++;
            q->pushed++;
            return 0;
        }
        break;
    }

    /* The new entry; it may grow by absorbing neighbours below. */
    qent *n = calloc(1, sizeof *n);
    size_t count = (size_t)p->w * p->h * 3;
    if (n) n->texels = malloc(count * sizeof *n->texels);
    if (!n || !n->texels) {
        free(n);
        return ct_fail(err, CT_ENOMEM, "send queue: out of memory for a %ux%u patch", p->w, p->h);
    }
    n->patch = true;
    n->tex = p->tex;
    n->x = p->x;
    n->y = p->y;
    n->w = p->w;
    n->h = p->h;
    memcpy(n->texels, p->texels, count * sizeof *n->texels);
    n->cost = patch_cost(n->w, n->h);

    /* 2. Queued patches inside the new one are dropped (the new texels win);
     *    those whose union with it is a rectangle, and whose area no later
     *    queued patch touches, are merged into it, their texels first, the
     *    new ones on top. Repeat until nothing changes. */
    uint64_t absorbed = 0;
    bool changed = true;
    while (changed) {
        changed = false;
        for (qent *o = q->tail, *prev; o && o != q->barrier; o = prev) {
            prev = o->prev;
            if (!o->patch || o->tex != n->tex) continue;
            if (contains(n, o->x, o->y, o->w, o->h)) {
                unlink_ent(q, o);
                ent_free(o);
                q->merged++;
                absorbed++;
                continue;
            }
            if (!union_is_box(o, n) || overlapped_later(o)) continue;
            uint32_t bx = o->x < n->x ? o->x : n->x, by = o->y < n->y ? o->y : n->y;
            uint32_t ex = o->x + o->w > n->x + n->w ? o->x + o->w : n->x + n->w;
            uint32_t ey = o->y + o->h > n->y + n->h ? o->y + o->h : n->y + n->h;
            uint32_t bw = ex - bx, bh = ey - by;
            if ((uint64_t)bw * bh > WIRE_PATCH_MAX_TEXELS) continue;
            uint16_t *t = malloc((size_t)bw * bh * 3 * sizeof *t);
            if (!t) continue; /* merging is an optimisation; keep both */
            blit(t, bx, by, bw, o->texels, o->x, o->y, o->w, o->h);
            blit(t, bx, by, bw, n->texels, n->x, n->y, n->w, n->h);
            free(n->texels);
            n->texels = t;
            n->x = bx;
            n->y = by;
            n->w = bw;
            n->h = bh;
            n->cost = patch_cost(bw, bh);
            unlink_ent(q, o);
            ent_free(o);
            q->merged++;
            absorbed++;
            changed = true;
            break;
        }
    }

    /* Refuse only when nothing was absorbed: absorbed texels live in n now.
     * Merging never grows the total (the union is the bounding box), so the
     * queue exceeds its bound by at most this one patch. */
    if (!absorbed && q->entries && q->bytes + n->cost > q->max_bytes) {
        ent_free(n);
        return XPORT_QUEUE_FULL;
    }
    append(q, n);
    q->pushed++;
    return 0;
}

int xport_queue_head(xport_queue *q, const uint8_t **data, size_t *len, ct_error *err)
{
    if (q->out_off == q->out.len) {
        q->out.len = 0;
        q->out_off = 0;
        qent *e = q->head;
        if (!e) {
            *data = NULL;
            *len = 0;
            return 0;
        }
        int rc = 0;
        if (e->patch) {
            wire_msg m;
            memset(&m, 0, sizeof m);
            m.type = WIRE_TEX_PATCH;
            m.u.tex_patch.tex = e->tex;
            m.u.tex_patch.x = e->x;
            m.u.tex_patch.y = e->y;
            m.u.tex_patch.w = e->w;
            m.u.tex_patch.h = e->h;
            m.u.tex_patch.texels = e->texels;
            rc = wire_encode(&m, &q->out, err);
        } else {
            rc = wire_buf_append(&q->out, e->bytes.data, e->bytes.len, err);
        }
        if (rc) return rc;
        unlink_ent(q, e);
        ent_free(e);
    }
    *data = q->out.data + q->out_off;
    *len = q->out.len - q->out_off;
    return 0;
}

void xport_queue_advance(xport_queue *q, size_t n)
{
    q->out_off += n;
    if (q->out_off > q->out.len) q->out_off = q->out.len;
}

bool xport_queue_empty(const xport_queue *q)
{
    return q->head == NULL && q->out_off == q->out.len;
}

xport_queue_stats xport_queue_get_stats(const xport_queue *q)
{
    xport_queue_stats s = {q->entries, q->bytes, q->merged, q->pushed};
    return s;
}
