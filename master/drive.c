/* drive.c: the master's sample loop (drive.h). */
#include "master/drive.h"

#include <stdlib.h>
#include <string.h>

#include "common/timer.h"
#include "proto/wire_mpi.h"

#define MAX_WINDOW 64

typedef struct lane {
    drv_lane pub;
    double sent_at[MAX_WINDOW];           /* send times of the batches in flight (FIFO) */
    unsigned char in_round[MAX_WINDOW];   /* whether each of them belongs to a lockstep round */
    uint32_t epoch[MAX_WINDOW];           /* the view each of them was made for */
    int head;
    double last_reply;
} lane;

struct drv {
    sess *s;
    tport *p;
    sink k;
    drv_options o;
    lane *lanes;
    int rr;                /* free running: the lane served first by the next call */
    uint64_t batch_id;
    bool lockstep;
    bool in_frame;
    uint32_t frame_left, frame_samples;
    int round_out;         /* batches of the current round not yet back */
    ct_sample *round_buf;
    uint32_t round_n, round_cap;
    ct_request *reqs;
    uint32_t reqs_cap;
    double view_at;        /* when the current view was taken */
    double view_gap;       /* running mean of the time between views (0: one view so far) */
};

#define OF(f) offsetof(drv_options, f)
static const optab OPTS[] = {
    {"window", 0, OPTAB_INT, OF(window), 1, MAX_WINDOW, "3", "N",
     "request batches of the current view in flight per tracer", NULL},
    {"batch-min", 0, OPTAB_INT, OF(batch_min), 1, WIRE_MPI_MAX_BATCH, "16", "N",
     "smallest free-running batch (requests)", NULL},
    {"batch-max", 0, OPTAB_INT, OF(batch_max), 1, WIRE_MPI_MAX_BATCH, "4096", "N",
     "largest free-running batch (requests)", NULL},
    {"batch-ms", 0, OPTAB_DOUBLE, OF(batch_ms), 0.1, 10000, "20", "X",
     "target tracing time of one free-running batch (ms)", NULL},
    {"round", 0, OPTAB_INT, OF(round), 1, WIRE_MPI_MAX_BATCH, "256", "N",
     "lockstep: requests per round, inserted in id order", NULL},
    {"pop-ahead", 0, OPTAB_FLAG, OF(pop_ahead), 0, 0, NULL, NULL,
     "pop a tracer's next batch (lockstep: the next round) ahead of the reports of the one going in, beside its "
     "splats: more samples a second from a master that many tracers saturate, less adaptive sampling",
     NULL},
};
#undef OF

const optab *drv_options_table(size_t *n)
{
    *n = OPTAB_COUNT(OPTS);
    return OPTS;
}

static int grow(void **p, uint32_t *cap, uint32_t need, size_t elem, ct_error *err)
{
    if (need <= *cap) return 0;
    uint32_t n = *cap ? *cap : 256;
    while (n < need) n *= 2;
    void *q = realloc(*p, (size_t)n * elem);
    if (!q) return ct_fail(err, CT_ENOMEM, "master: out of memory for %u records", n);
    *p = q;
    *cap = n;
    return 0;
}

int drv_new(sess *s, tport *p, const sink *k, const drv_options *o, drv **out, ct_error *err)
{
    *out = NULL;
    if (o->batch_min > o->batch_max)
        return ct_fail(err, CT_EINVAL, "--batch-min %d is larger than --batch-max %d", o->batch_min, o->batch_max);
    drv *d = calloc(1, sizeof *d);
    if (!d || !(d->lanes = calloc((size_t)p->lanes, sizeof *d->lanes))) {
        free(d);
        return ct_fail(err, CT_ENOMEM, "master: out of memory");
    }
    d->s = s;
    d->p = p;
    if (k) d->k = *k;
    d->o = *o;
    if (d->o.window > MAX_WINDOW) d->o.window = MAX_WINDOW;
    *out = d;
    return CT_OK;
}

void drv_free(drv *d)
{
    if (!d) return;
    free(d->lanes);
    free(d->round_buf);
    free(d->reqs);
    free(d);
}

int drv_set_view(drv *d, const ct_camera *cam, int width, int height, ct_error *err)
{
    int rc = sess_set_view(d->s, cam, width, height, err);
    if (rc <= 0) return rc;
    double now = ct_now();
    if (d->view_at > 0) {
        double gap = now - d->view_at;
        d->view_gap = d->view_gap > 0 ? 0.7 * d->view_gap + 0.3 * gap : gap;
    }
    d->view_at = now;
    /* Every lane hears of it: once a batch of this view follows them, its
     * batches of older views are answered at once (tracer/rank.h). */
    tport_view v = {sess_epoch(d->s), (uint32_t)width, (uint32_t)height, *cam};
    if (d->p->ops->view(d->p, &v, err)) return CT_EIO;
    return 1;
}

void drv_begin_frame(drv *d, uint32_t k)
{
    drv_set_lockstep(d, true);
    d->in_frame = true;
    d->frame_left = k;
    d->frame_samples = 0;
}

void drv_cut_frame(drv *d)
{
    d->frame_left = 0;
}

bool drv_in_frame(const drv *d)
{
    return d->in_frame;
}

void drv_set_lockstep(drv *d, bool on)
{
    d->lockstep = on;
    sess_set_lockstep(d->s, on);
}

int drv_inflight(const drv *d)
{
    int n = 0;
    for (int i = 0; i < d->p->lanes; i++) n += d->lanes[i].pub.inflight;
    return n;
}

const drv_lane *drv_lane_get(const drv *d, int i)
{
    return &d->lanes[i].pub;
}

int drv_check(const drv *d, double now, double timeout_s, ct_error *err)
{
    for (int i = 0; i < d->p->lanes; i++) {
        const lane *l = &d->lanes[i];
        if (l->pub.inflight > 0 && now - l->sent_at[l->head] > timeout_s)
            return ct_fail(err, CT_EIO, "tracer rank %d has not answered for %.0f s (%d batches outstanding)", i + 1,
                           now - l->sent_at[l->head], l->pub.inflight);
    }
    return 0;
}

/* Inserts samples, counting those of the frame in progress, and pops up
 * to `want` requests ahead of their reports into d->reqs (*got). */
static int insert_next(drv *d, const ct_sample *smp, uint32_t n, uint32_t want, int *got, ct_error *err)
{
    *got = 0;
    int rc = grow((void **)&d->reqs, &d->reqs_cap, want, sizeof *d->reqs, err);
    if (rc) return rc;
    sess_counters before = sess_get_counters(d->s);
    rc = sess_insert_next(d->s, smp, n, &d->k, d->reqs, want, got, err);
    if (d->in_frame) d->frame_samples += (uint32_t)(sess_get_counters(d->s).inserted - before.inserted);
    return rc;
}

static int submit(drv *d, int i, const ct_request *reqs, uint32_t n, int round, ct_error *err);
static int submit_round(drv *d, uint32_t k, ct_error *err);
static uint32_t batch_size(const drv *d, const lane *l);
static bool lane_open(const drv *d, const lane *l);

static int by_id(const void *a, const void *b)
{
    uint64_t x = ((const ct_sample *)a)->request_id, y = ((const ct_sample *)b)->request_id;
    return x < y ? -1 : x > y;
}

static bool sorted_by_id(const ct_sample *s, uint32_t n)
{
    for (uint32_t i = 1; i < n; i++)
        if (s[i].request_id < s[i - 1].request_id) return false;
    return true;
}

/* Takes every answered batch; 1 when any was. With pop_ahead: running
 * free, a lane's next batch is popped ahead and sent when `may_pop` (not
 * before a view change); a lockstep round's successor regardless of it
 * (frames must not depend on when a round came back). */
static int receive(drv *d, bool may_pop, ct_error *err)
{
    int any = 0;
    tport_reply r;
    int got = 0;
    /* Only the batches out now: those sent here (popped ahead) wait for
     * the next call, so that a port answering at once cannot keep the
     * caller (its display, its events) waiting for a whole frame. */
    int budget = drv_inflight(d);
    if (budget < 1) budget = 1;
    while (budget-- > 0 && (got = d->p->ops->poll(d->p, &r, err)) > 0) {
        lane *l = &d->lanes[r.lane];
        double now = ct_now();
        /* A lane answers its batches in order: the oldest one is this. */
        int was_round = l->pub.inflight > 0 && l->in_round[l->head];
        if (l->pub.inflight > 0) {
            /* The batch was traced from when it was sent or when the
             * previous answer left the tracer, whichever is later. */
            double start = l->sent_at[l->head];
            if (l->last_reply > start) start = l->last_reply;
            double dt = now - start;
            l->head = (l->head + 1) % MAX_WINDOW;
            l->pub.inflight--;
            if (r.n > 0 && dt > 1e-6) {
                double rate = r.n / dt;
                l->pub.rate = l->pub.rate > 0 ? 0.7 * l->pub.rate + 0.3 * rate : rate;
            }
        }
        l->last_reply = now;
        l->pub.samples += r.n;
        any = 1;
        int rc;
        if (was_round) {
            if ((rc = grow((void **)&d->round_buf, &d->round_cap, d->round_n + r.n, sizeof *d->round_buf, err)))
                return rc;
            memcpy(d->round_buf + d->round_n, r.samples, r.n * sizeof *r.samples);
            d->round_n += r.n;
            if (--d->round_out == 0) {
                /* one lane's answer, or lanes that answered in order, come sorted */
                if (!sorted_by_id(d->round_buf, d->round_n))
                    qsort(d->round_buf, d->round_n, sizeof *d->round_buf, by_id);
                /* with pop_ahead, the frame's next round is popped ahead
                 * of this one's reports and goes out at once */
                uint32_t want = 0;
                if (d->o.pop_ahead && d->in_frame)
                    want = d->frame_left < (uint32_t)d->o.round ? d->frame_left : (uint32_t)d->o.round;
                int k;
                rc = insert_next(d, d->round_buf, d->round_n, want, &k, err);
                d->round_n = 0;
                if (rc) return rc;
                if (k > 0 && (rc = submit_round(d, (uint32_t)k, err))) return rc;
            }
        } else {
            /* with pop_ahead, the lane's next batch is popped ahead of
             * this one's reports and goes back to it at once */
            uint32_t want = 0;
            if (d->o.pop_ahead && may_pop && !d->lockstep && sess_has_view(d->s) && lane_open(d, l))
                want = batch_size(d, l);
            int k;
            if ((rc = insert_next(d, r.samples, r.n, want, &k, err))) return rc;
            if (k > 0 && (rc = submit(d, r.lane, d->reqs, (uint32_t)k, 0, err))) return rc;
        }
    }
    return got < 0 ? got : any;
}

/* Whether lane l may take one more free-running batch: --window batches of
 * the current view at most. Batches of views left do not count: the tracer
 * answers them (empty, or what it traced of them) as soon as a newer batch
 * has come, and until then it traces them rather than wait (tracer/rank.h).
 * Counted against the window, they held the new view's first batch back
 * until the tracer had finished one of them. The slot ring bounds the
 * total. */
static bool lane_open(const drv *d, const lane *l)
{
    if (l->pub.inflight >= MAX_WINDOW) return false;
    uint32_t now = sess_epoch(d->s);
    int current = 0;
    for (int j = 0; j < l->pub.inflight; j++) current += l->epoch[(l->head + j) % MAX_WINDOW] == now;
    return current < d->o.window;
}

static int submit(drv *d, int i, const ct_request *reqs, uint32_t n, int round, ct_error *err)
{
    lane *l = &d->lanes[i];
    /* Free running, lane_open keeps a lane within its slots; a lockstep
     * round goes out when nothing is (master/sched.c). A caller that broke
     * that would overwrite the oldest batch's slot: refuse. */
    if (l->pub.inflight >= MAX_WINDOW)
        return ct_fail(err, CT_EINVAL, "master: tracer %d already has %d batches out", i + 1, MAX_WINDOW);
    ct_camera cam;
    int w, h;
    sess_view(d->s, &cam, &w, &h);
    tport_view v = {sess_epoch(d->s), (uint32_t)w, (uint32_t)h, cam};
    int rc = d->p->ops->submit(d->p, i, ++d->batch_id, &v, reqs, n, err);
    if (rc) return rc;
    int slot = (l->head + l->pub.inflight) % MAX_WINDOW;
    l->sent_at[slot] = ct_now();
    l->in_round[slot] = (unsigned char)round;
    l->epoch[slot] = v.epoch;
    l->pub.inflight++;
    return 0;
}

static int next(drv *d, uint32_t n, ct_error *err)
{
    int rc = grow((void **)&d->reqs, &d->reqs_cap, n, sizeof *d->reqs, err);
    return rc ? rc : sess_next(d->s, d->reqs, n, err);
}

/* A lane's next free-running batch: --batch-ms of its tracing, and no more
 * than a window's share of how long views last. A view that lasts less
 * than the window's tracing leaves most of its batches to be answered
 * (nearly) empty: the master popped, encoded and sent them for nothing, at
 * 200 views a second most of its work (docs/distributed.md, "Camera
 * changes"). How long the view lasts: the running mean of the intervals
 * between views, or how long this one has lasted where longer (a camera
 * that stopped). */
static uint32_t batch_size(const drv *d, const lane *l)
{
    double ms = d->o.batch_ms;
    if (d->view_gap > 0) {
        double life = ct_now() - d->view_at;
        if (life < d->view_gap) life = d->view_gap;
        double share = 1000.0 * life / d->o.window;
        if (share < ms) ms = share;
    }
    double b = l->pub.rate > 0 ? l->pub.rate * ms / 1000.0 : d->o.batch_min;
    if (b < d->o.batch_min) b = d->o.batch_min;
    if (b > d->o.batch_max) b = d->o.batch_max;
    return (uint32_t)b;
}

/* Free running: fill every lane's window, one batch per lane per pass,
 * each call starting from the next lane: when the queue runs short (every
 * pixel handed out, refinement asking for a few pixels at a time), the
 * lane served first gets what there is, and that must not always be the
 * same lane. */
static int feed_free(drv *d, ct_error *err)
{
    if (!sess_has_view(d->s)) return 0;
    int any = 0, T = d->p->lanes, first = d->rr;
    d->rr = (d->rr + 1) % T;
    for (int pass = 0; pass < d->o.window; pass++) {
        int gave = 0;
        for (int j = 0; j < T; j++) {
            int i = (first + pass + j) % T;
            lane *l = &d->lanes[i];
            if (!lane_open(d, l)) continue;
            int k = next(d, batch_size(d, l), err);
            if (k < 0) return k;
            if (k == 0) return any;   /* every pixel of this view is handed out */
            int rc = submit(d, i, d->reqs, (uint32_t)k, 0, err);
            if (rc) return rc;
            any = gave = 1;
        }
        if (!gave) break;
    }
    return any;
}

/* Lockstep: the next round of the frame, or its end. */
static int feed_frame(drv *d, ct_error *err)
{
    if (!d->in_frame || d->round_out > 0) return 0;
    uint32_t n = d->frame_left < (uint32_t)d->o.round ? d->frame_left : (uint32_t)d->o.round;
    int k = n ? next(d, n, err) : 0;
    if (k < 0) return k;
    if (k == 0) {
        d->in_frame = false;
        sink_frame f = {d->frame_samples, d->frame_left > 0};
        int rc = d->k.frame ? d->k.frame(d->k.user, d->s, &f, err) : 0;
        return rc ? rc : 1;
    }
    int rc = submit_round(d, (uint32_t)k, err);
    return rc ? rc : 1;
}

/* Sends the k requests in d->reqs as the frame's next round. */
static int submit_round(drv *d, uint32_t k, ct_error *err)
{
    if (d->frame_left != UINT32_MAX) d->frame_left -= k;
    /* One part per lane; the split does not change the result. */
    uint32_t T = (uint32_t)d->p->lanes, per = (k + T - 1) / T;
    for (uint32_t i = 0; i < T; i++) {
        uint32_t b = i * per;
        if (b >= k) break;
        uint32_t e = b + per > k ? k : b + per;
        int rc = submit(d, (int)i, d->reqs + b, e - b, 1, err);
        if (rc) return rc;
        d->round_out++;
    }
    return 0;
}

int drv_receive(drv *d, bool may_pop, ct_error *err)
{
    return receive(d, may_pop, err);
}

int drv_step(drv *d, ct_error *err)
{
    int got = receive(d, true, err);
    if (got < 0) return got;
    int fed = d->lockstep ? feed_frame(d, err) : feed_free(d, err);
    if (fed < 0) return fed;
    return got || fed;
}
