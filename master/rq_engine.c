/* rq_engine.c: the adaptive sample acquisition of §3.7 (see sampler.h and
 * docs/sampling.md). Everything per request works on preallocated arrays:
 * the 4-ary heap (rq_heap.c), the pixel bitmask (rq_mask.c), a ring of the
 * in-flight requests indexed by id, and a min-heap of the n_sig most
 * significant samples; buffers only grow (doubling) and every growth is
 * counted in rq_stats.allocations. Over 600 lines on purpose: the pops,
 * the reports and the camera changes all work on the same in-flight ring,
 * mask, significant set and refinement records, whose invariants are read
 * together; split, each part would need the engine's private struct. */
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"
#include "master/rq_heap.h"
#include "master/rq_mask.h"
#include "master/rq_refine.h"
#include "master/sampler.h"

/* Random stream selectors; every stream is a pure function of the seed, an
 * id and its selector, so batches are reproducible: the grid and the global
 * requests use rng_make(seed, epoch, selector, round), the children a PCG
 * state hashed from (seed, selector, parent id). */
#define STREAM_SEED   0x53454544u
#define STREAM_CHILD  0x4348494cu
#define STREAM_GLOBAL 0x474c4f42u
#define STREAM_REFINE 0x52454649u

/* A handed-out request, kept until its sample is reported. */
typedef struct flight {
    float px, py, radius;
    uint16_t outstanding;
    uint16_t kind;       /* RQ_KIND_* */
} flight;

/* A significant sample: its error, request, world point and domain. */
typedef struct sigsample {
    float err;
    float radius;
    uint64_t id;
    vec3 hit;
} sigsample;

struct rq_engine {
    int w, h;
    ct_camera cam;
    rq_options o;
    uint64_t seed;
    uint32_t epoch;
    uint32_t seq;            /* push sequence within the epoch (tie-break) */
    uint64_t next_id;        /* next request id; ids start at 1 */
    rq_heap heap;
    rq_mask mask;
    uint64_t switch_count;   /* sampled pixels at which the list takes over */
    int list_mode;
    uint64_t global_round;
    float child_scale;       /* 1 / sqrt(N) */
    uint64_t child_salt;     /* hash of the seed for the children's streams */
    int child_k;             /* children sit in a k x k subdivision, k = ceil(sqrt(N)) */
    flight *fl;              /* ring indexed by id & (fl_cap - 1) */
    size_t fl_cap;           /* power of two */
    uint64_t fl_lo;          /* ids below are reported or stale */
    uint64_t fl_out;         /* outstanding this epoch */
    uint64_t fl_refine;      /* of them refinement requests */
    sigsample *sig;          /* min-heap: least significant at [0] */
    int n_sig;
    rq_refine ref;           /* past full coverage (px NULL: refinement off) */
    uint64_t grows;          /* allocations of this file's buffers */
    rq_stats st;
};

float rq_error_norm(vec3 E, rq_norm norm)
{
    vec3 a = v3(fabsf(E.x), fabsf(E.y), fabsf(E.z));
    switch (norm) {
    case RQ_NORM_LUM: return v3_luminance(a);
    case RQ_NORM_AVG: return v3_avg(a);
    default: {
        /* Plain compares: fmaxf is a library call at -O2 (NaN handling). */
        float m = a.x > a.y ? a.x : a.y;
        return m > a.z ? m : a.z;
    }
    }
}

/* Pixel index of an image position, or -1 outside the image. */
static inline int64_t pixel_of(const rq_engine *e, float px, float py)
{
    /* Compare as floats first: a reprojected point near the eye plane can be
     * far outside the int range. NaN fails every comparison. */
    if (!(px >= 0.0f && py >= 0.0f && px < (float)e->w && py < (float)e->h)) return -1;
    int x = (int)px, y = (int)py;
    if (x >= e->w || y >= e->h) return -1;
    return (int64_t)y * e->w + x;
}

/* Queues a request at (px, py); discards it (counted) when it is outside the
 * image, its pixel is sampled already, or the queue is full. */
static inline bool enqueue(rq_engine *e, float px, float py, float radius, float prio,
                           uint64_t parent, uint32_t kind, uint64_t *outside)
{
    int64_t p = pixel_of(e, px, py);
    if (p < 0) {
        if (outside) (*outside)++;
        return false;
    }
    if (rq_mask_test(&e->mask, (uint32_t)p)) {
        e->st.discarded_mask++;
        return false;
    }
    rq_item it;
    it.key = rq_key(prio, e->seq);
    if (e->seq < UINT32_MAX) e->seq++;
    it.parent = parent;
    it.px = px;
    it.py = py;
    it.radius = radius;
    it.kind = kind;
    it.tag = (uint32_t)p;
    if (rq_heap_push(&e->heap, &it) != 0) {
        e->st.discarded_full++;
        return false;
    }
    if (e->heap.n > e->st.peak_queued) e->st.peak_queued = e->heap.n;
    return true;
}

/* The initial jittered grid: cells of about seed_spacing pixels, one request
 * per cell at a random position inside it, radius = the cell spacing (§3.7:
 * "the domain radius of these requests is given by their average distance"),
 * queued in a shuffled order so that any prefix is spread over the image. */
static int queue_seeds(rq_engine *e, ct_error *err)
{
    int nx = (int)lroundf((float)e->w / e->o.seed_spacing);
    int ny = (int)lroundf((float)e->h / e->o.seed_spacing);
    if (nx < 1) nx = 1;
    if (ny < 1) ny = 1;
    float cw = (float)e->w / (float)nx, ch = (float)e->h / (float)ny;
    float radius = sqrtf(cw * ch);
    uint32_t n = (uint32_t)nx * (uint32_t)ny;
    uint32_t *order = malloc(n * sizeof *order);
    if (!order) return ct_fail(err, CT_ENOMEM, "sampler: cannot allocate %u initial requests", n);
    e->grows++;
    ct_rng r = rng_make(e->seed, e->epoch, STREAM_SEED, 0);
    for (uint32_t i = 0; i < n; i++) order[i] = i;
    for (uint32_t i = n; i > 1; i--) {
        uint32_t j = rng_below(&r, i);
        uint32_t t = order[i - 1];
        order[i - 1] = order[j];
        order[j] = t;
    }
    for (uint32_t i = 0; i < n; i++) {
        uint32_t cx = order[i] % (uint32_t)nx, cy = order[i] / (uint32_t)nx;
        float px = ((float)cx + rng_float(&r)) * cw;
        float py = ((float)cy + rng_float(&r)) * ch;
        /* Rounding can put a position on the far border: pull it inside. */
        if (px >= (float)e->w) px = nextafterf((float)e->w, 0.0f);
        if (py >= (float)e->h) py = nextafterf((float)e->h, 0.0f);
        if (enqueue(e, px, py, radius, e->o.prio_seed, 0, RQ_KIND_SEED, NULL)) e->st.seeds++;
    }
    free(order);
    return 0;
}

/* The queue ran dry: random global requests over the unsampled pixels
 * (§3.7), radius = their average spacing over the unsampled area. Returns how
 * many were queued. */
static int queue_globals(rq_engine *e)
{
    uint64_t total = (uint64_t)e->w * (uint64_t)e->h;
    uint64_t unsampled = total - e->mask.count;
    if (unsampled == 0) return 0;
    float radius = sqrtf((float)unsampled / (float)e->o.global_batch);
    if (radius > e->o.seed_spacing) radius = e->o.seed_spacing;
    if (radius < 1.0f) radius = 1.0f;
    ct_rng r = rng_make(e->seed, e->epoch, STREAM_GLOBAL, e->global_round++);
    int added = 0;
    for (int i = 0; i < e->o.global_batch; i++) {
        for (int t = 0; t < e->o.global_tries; t++) {
            float px = rng_float(&r) * (float)e->w;
            float py = rng_float(&r) * (float)e->h;
            int64_t p = pixel_of(e, px, py);
            if (p < 0 || rq_mask_test(&e->mask, (uint32_t)p)) continue;
            if (enqueue(e, px, py, radius, e->o.prio_seed, 0, RQ_KIND_GLOBAL, NULL)) {
                added++;
                e->st.global++;
            }
            break;
        }
    }
    return added;
}

static int enter_list_mode(rq_engine *e, ct_error *err)
{
    int rc = rq_mask_build_list(&e->mask, e->seed, e->epoch, err);
    if (rc) return rc;
    e->list_mode = 1;
    return 0;
}

/* Makes room in the in-flight ring for `more` new ids. */
static int reserve_flights(rq_engine *e, uint64_t more, ct_error *err)
{
    uint64_t need = e->next_id - e->fl_lo + more;
    if (need <= e->fl_cap) return 0;
    size_t ncap = e->fl_cap ? e->fl_cap : 1024;
    while (ncap < need) ncap *= 2;
    flight *nf = malloc(ncap * sizeof *nf);
    if (!nf) return ct_fail(err, CT_ENOMEM, "sampler: cannot track %zu requests in flight", ncap);
    e->grows++;
    for (uint64_t id = e->fl_lo; id < e->next_id; id++)
        nf[id & (ncap - 1)] = e->fl[id & (e->fl_cap - 1)];
    free(e->fl);
    e->fl = nf;
    e->fl_cap = ncap;
    return 0;
}

static inline void emit(rq_engine *e, const rq_item *it, ct_request *r)
{
    uint64_t id = e->next_id++;
    flight *f = &e->fl[id & (e->fl_cap - 1)];
    f->px = it->px;
    f->py = it->py;
    f->radius = it->radius;
    f->outstanding = 1;
    f->kind = (uint16_t)it->kind;
    e->fl_out++;
    e->fl_refine += it->kind == RQ_KIND_REFINE;
    r->id = id;
    r->parent = it->parent;
    r->epoch = e->epoch;
    r->px = it->px;
    r->py = it->py;
    r->radius = it->radius;
    r->priority = rq_key_priority(it->key);
    e->st.popped++;
}

int rq_next_batch(rq_engine *e, ct_request *out, int n, ct_error *err)
{
    if (n <= 0) return 0;
    int rc = reserve_flights(e, (uint64_t)n, err);
    if (rc) return rc;
    int k = 0;
    while (k < n) {
        rq_item it;
        if (e->heap.n) {
            /* The pixel was checked when queued and travels as the tag: a
             * request for a pixel handed out since is dropped unread. */
            if (rq_mask_test_set(&e->mask, rq_heap_top_tag(&e->heap))) {
                rq_heap_drop(&e->heap);
                e->st.discarded_mask++;
                continue;
            }
            rq_heap_pop(&e->heap, &it);
            emit(e, &it, &out[k++]);
        } else if (e->list_mode) {
            uint32_t p;
            if (!rq_mask_list_next(&e->mask, &p)) {
                /* Every pixel handed out: refine, or this view is done. */
                if (!e->ref.px) break;
                if (!e->ref.active && (rc = rq_refine_start(&e->ref, err))) return k ? k : rc;
                float prio;
                if (!rq_refine_next(&e->ref, &p, &prio)) break;
                /* A new position in the pixel for each of its samples: a
                 * pure function of (seed, epoch, pixel, sample count). */
                ct_rng r = rng_make(e->seed, e->epoch, STREAM_REFINE, (uint64_t)p << 16 | e->ref.px[p].n);
                it.key = rq_key(prio, 0);
                it.parent = 0;
                it.px = (float)(p % (uint32_t)e->w) + rng_float(&r);
                it.py = (float)(p / (uint32_t)e->w) + rng_float(&r);
                it.radius = 0.5f;
                it.kind = RQ_KIND_REFINE;
                emit(e, &it, &out[k++]);
                continue;
            }
            it.key = rq_key(e->o.prio_seed, 0);
            it.parent = 0;
            it.px = (float)(p % (uint32_t)e->w) + 0.5f;
            it.py = (float)(p / (uint32_t)e->w) + 0.5f;
            it.radius = 1.0f;   /* one pixel apart: the domain is the pixel */
            it.kind = RQ_KIND_LIST;
            e->st.from_list++;
            emit(e, &it, &out[k++]);
        } else {
            if (queue_globals(e) > 0) continue;
            /* Random positions keep missing the last free pixels. */
            rc = enter_list_mode(e, err);
            if (rc) return k ? k : rc;
            continue;
        }
        if (!e->list_mode && e->mask.count >= e->switch_count) {
            rc = enter_list_mode(e, err);
            if (rc) return k ? k : rc;
        }
    }
    return k;
}

/* Significance order: larger |E| first, then the older request. */
static inline bool less_significant(const sigsample *a, const sigsample *b)
{
    return a->err < b->err || (a->err == b->err && a->id > b->id);
}

static void sig_insert(rq_engine *e, const sigsample *s)
{
    sigsample *h = e->sig;
    int n = e->n_sig;
    if (n < e->o.n_sig) {
        int i = e->n_sig++;
        while (i > 0) {
            int p = (i - 1) / 2;
            if (!less_significant(s, &h[p])) break;
            h[i] = h[p];
            i = p;
        }
        h[i] = *s;
        return;
    }
    if (n == 0 || !less_significant(&h[0], s)) return;
    int i = 0;
    for (;;) {
        int c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && less_significant(&h[c + 1], &h[c])) c++;
        if (!less_significant(&h[c], s)) break;
        h[i] = h[c];
        i = c;
    }
    h[i] = *s;
}

/* N children covering the parent's domain (the s x s square around it) more
 * densely: a k x k subdivision (k = ceil(sqrt(N))), N of its cells, one child
 * at a random position in each, radius s_c = s / sqrt(N), priority |E| * s_c
 * (§3.7); children of a node mismatch get prio_mismatch and skip the threshold. */
static void make_children(rq_engine *e, uint64_t pid, const flight *f, float err, bool mismatch)
{
    const int nchild = e->o.children;
    float s = f->radius;
    float sc = s * e->child_scale;
    if (sc < e->o.min_radius) {
        e->st.leaves++;
        return;
    }
    float prio = mismatch ? e->o.prio_mismatch : err * sc;
    if (!mismatch && !(prio >= e->o.min_priority)) {
        e->st.discarded_threshold += (uint64_t)nchild;
        return;
    }
    const int k = e->child_k;
    const float cell = s / (float)k;
    const float ox = f->px - 0.5f * s, oy = f->py - 0.5f * s;
    /* The children's stream is a pure function of (seed, parent id); ids are
     * unique over the run, so that is all it needs. One hash instead of
     * rng_make's four: this runs once per sample. */
    ct_rng r;
    r.state = ct_hash64(e->child_salt ^ pid);
    r.inc = 0x5851f42d4c957f2dULL;
    uint8_t cells[64];
    int ncell = k * k;
    for (int i = 0; i < ncell; i++) cells[i] = (uint8_t)i;
    if (nchild < ncell) {
        /* Partial Fisher-Yates: a random choice of N distinct cells. */
        for (int i = 0; i < nchild; i++) {
            int j = i + (int)rng_below(&r, (uint32_t)(ncell - i));
            uint8_t t = cells[i];
            cells[i] = cells[j];
            cells[j] = t;
        }
    }
    uint32_t kind = mismatch ? RQ_KIND_MISMATCH : RQ_KIND_CHILD;
    for (int i = 0; i < nchild; i++) {
        int cx = cells[i] % k, cy = cells[i] / k;
        /* One 32-bit draw: 16 bits of jitter per axis (1/65536 of a cell). */
        uint32_t j = rng_u32(&r);
        float px = ox + ((float)cx + (float)(j & 0xffffu) * 0x1p-16f) * cell;
        float py = oy + ((float)cy + (float)(j >> 16) * 0x1p-16f) * cell;
        if (enqueue(e, px, py, sc, prio, pid, kind, &e->st.discarded_outside)) e->st.children++;
    }
}

void rq_report_prefetch(const rq_engine *e, const ct_sample *s)
{
    uint64_t id = s->request_id;
    if (id >= e->fl_lo && id < e->next_id) __builtin_prefetch(&e->fl[id & (e->fl_cap - 1)], 1, 1);
    if (e->ref.px) {
        int64_t p = pixel_of(e, s->px, s->py);
        if (p >= 0 && (size_t)p < e->ref.npx) {
            __builtin_prefetch(&e->ref.px[p], 1, 1);
            /* its four neighbours: a refined pixel's priority reads their
             * records (rq_refine.c); the left or right one lies on the next
             * cache line, the others rows away */
            if (e->ref.active) {
                size_t w = (size_t)e->ref.w, q = (size_t)p;
                if (q >= 1) __builtin_prefetch(&e->ref.px[q - 1], 0, 3);
                if (q + 1 < e->ref.npx) __builtin_prefetch(&e->ref.px[q + 1], 0, 3);
                if (q >= w) __builtin_prefetch(&e->ref.px[q - w], 0, 3);
                if (q + w < e->ref.npx) __builtin_prefetch(&e->ref.px[q + w], 0, 3);
            }
        }
    }
}

int rq_report(rq_engine *e, const ct_sample *s, vec3 E, uint32_t shown_node, ct_error *err)
{
    if (s->epoch < e->epoch) {
        e->st.stale++;
        return RQ_REPORT_STALE;
    }
    if (s->epoch > e->epoch)
        return ct_fail(err, CT_EPROTO, "sampler: sample of request %llu has epoch %u, current is %u",
                       (unsigned long long)s->request_id, s->epoch, e->epoch);
    uint64_t id = s->request_id;
    if (id < e->fl_lo || id >= e->next_id || !e->fl[id & (e->fl_cap - 1)].outstanding)
        return ct_fail(err, CT_EPROTO, "sampler: sample for request %llu, which is not outstanding",
                       (unsigned long long)id);
    if (!v3_finite(E))
        return ct_fail(err, CT_EINVAL, "sampler: sample of request %llu has a non-finite error",
                       (unsigned long long)id);
    flight *f = &e->fl[id & (e->fl_cap - 1)];
    flight req = *f;
    f->outstanding = 0;
    e->fl_out--;
    e->fl_refine -= req.kind == RQ_KIND_REFINE;
    while (e->fl_lo < e->next_id && !e->fl[e->fl_lo & (e->fl_cap - 1)].outstanding) e->fl_lo++;
    e->st.reported++;

    float en = rq_error_norm(E, e->o.norm);
    bool hit = (s->flags & CT_SAMPLE_HIT) != 0;
    bool refine = req.kind == RQ_KIND_REFINE;
    int in_mean = 0;
    if (e->ref.px && hit && v3_finite(s->l_hq) && v3_finite(s->l_base)) {
        int64_t p = pixel_of(e, req.px, req.py);
        in_mean = p >= 0 ? rq_refine_add(&e->ref, (uint32_t)p, s->node, v3_sub(s->l_hq, s->l_base),
                                                 v3_luminance(s->l_base), en, err) : 0;
        if (in_mean < 0) return in_mean;
    }
    if (refine) {
        /* The sample goes into its pixel's texels (not one on another
         * node than the pixel's: those texels are not its node's); no
         * children (the pixel is the domain), and the significant samples
         * are the view's first ones. */
        if (!hit && e->ref.px) {
            int64_t p = pixel_of(e, req.px, req.py);
            int rc = p >= 0 ? rq_refine_miss(&e->ref, (uint32_t)p, err) : 0;
            if (rc < 0) return rc;
        }
        return in_mean ? RQ_REPORT_REFINE : 0;
    }
    uint32_t hq_node = hit ? s->node : RQ_NODE_NONE;
    bool mismatch = shown_node != RQ_NODE_UNKNOWN && shown_node != hq_node;
    int flags = 0;
    if (mismatch) {
        e->st.mismatches++;
        flags |= RQ_REPORT_MISMATCH;
    }
    if (hit && e->o.n_sig > 0 && v3_finite(s->hit)) {
        sigsample ss = {en, req.radius, id, s->hit};
        sig_insert(e, &ss);
    }
    make_children(e, id, &req, en, mismatch);
    return flags;
}

static int cmp_sig_desc(const void *a, const void *b)
{
    const sigsample *x = a, *y = b;
    if (less_significant(y, x)) return -1;
    if (less_significant(x, y)) return 1;
    return 0;
}

static bool camera_ok(const ct_camera *c)
{
    return v3_finite(c->eye) && isfinite(c->orient.w) && isfinite(c->orient.x) &&
           isfinite(c->orient.y) && isfinite(c->orient.z) &&
           (c->orient.w * c->orient.w + c->orient.x * c->orient.x + c->orient.y * c->orient.y +
            c->orient.z * c->orient.z) > 1e-12f &&
           cam_fov_valid(c->fov_y);
}

int rq_set_camera(rq_engine *e, const ct_camera *cam, uint32_t epoch, ct_error *err)
{
    if (epoch <= e->epoch)
        return ct_fail(err, CT_EINVAL, "sampler: camera epoch %u is not newer than the current %u",
                       epoch, e->epoch);
    if (!camera_ok(cam))
        return ct_fail(err, CT_EINVAL, "sampler: camera of epoch %u is not valid", epoch);
    /* Older requests point at positions of the old image: drop them all. */
    rq_heap_clear(&e->heap);
    rq_mask_clear(&e->mask);
    rq_refine_epoch(&e->ref);
    e->list_mode = 0;
    e->fl_lo = e->next_id;
    e->fl_out = 0;
    e->fl_refine = 0;
    e->seq = 0;
    e->global_round = 0;
    e->epoch = epoch;
    e->cam = *cam;
    /* Most significant first, so that FIFO among equal priorities keeps it. */
    if (e->n_sig > 1) qsort(e->sig, (size_t)e->n_sig, sizeof *e->sig, cmp_sig_desc);
    for (int i = 0; i < e->n_sig; i++) {
        const sigsample *s = &e->sig[i];
        float px, py;
        if (cam_project(&e->cam, e->w, e->h, s->hit, &px, &py, NULL) && pixel_of(e, px, py) >= 0) {
            if (enqueue(e, px, py, s->radius, e->o.prio_reproject, s->id, RQ_KIND_REPROJECT, NULL))
                e->st.reprojected++;
        } else {
            e->st.reproject_dropped++;
        }
    }
    e->n_sig = 0;
    if (e->o.reseed) return queue_seeds(e, err);
    return 0;
}

uint64_t rq_view_bytes(int width, int height, const rq_options *o)
{
    uint64_t npx = (uint64_t)(width > 0 ? width : 0) * (uint64_t)(height > 0 ? height : 0);
    uint64_t maxq = o->max_queue > 0 ? (uint64_t)o->max_queue : npx;
    /* payload and free list at the cap; bucket entries up to twice theirs */
    uint64_t b = maxq * (sizeof(rq_payload) + sizeof(uint32_t) + 2 * sizeof(rq_hent));
    b += (npx + 63) / 64 * sizeof(uint64_t);
    if (o->refine_error > 0.0f) b += npx * (sizeof(rq_pixel) + 2 * sizeof(rq_hent));
    return b;
}

int rq_new(rq_engine **out, int width, int height, const ct_camera *cam, const rq_options *opt,
           uint64_t seed, ct_error *err)
{
    *out = NULL;
    rq_options o;
    if (opt) o = *opt;
    else rq_options_default(&o);
    int rc = rq_options_check(&o, err);
    if (rc) return rc;
    if (width <= 0 || height <= 0 || (uint64_t)width * (uint64_t)height > (1ull << 31))
        return ct_fail(err, CT_EINVAL, "sampler: bad image size %dx%d", width, height);
    if (!camera_ok(cam)) return ct_fail(err, CT_EINVAL, "sampler: initial camera is not valid");
    rq_engine *e = calloc(1, sizeof *e);
    if (!e) return ct_fail(err, CT_ENOMEM, "sampler: cannot allocate the engine");
    e->w = width;
    e->h = height;
    e->cam = *cam;
    e->o = o;
    e->seed = seed;
    e->next_id = 1;
    e->fl_lo = 1;
    e->grows = 1;
    e->child_scale = 1.0f / sqrtf((float)o.children);
    e->child_salt = ct_hash64(seed ^ ((uint64_t)STREAM_CHILD << 32));
    e->child_k = (int)ceil(sqrt((double)o.children) - 1e-9);
    uint64_t total = (uint64_t)width * (uint64_t)height;
    e->switch_count = (uint64_t)ceil((double)o.coverage_switch * (double)total);
    size_t maxq = o.max_queue > 0 ? (size_t)o.max_queue : (size_t)total;
    size_t initq = total / 16 < maxq ? (size_t)(total / 16) : maxq;
    if ((rc = rq_heap_init(&e->heap, initq, maxq, err)) != 0 ||
        (rc = rq_mask_init(&e->mask, width, height, err)) != 0 ||
        (rc = reserve_flights(e, 1024, err)) != 0) {
        rq_free(e);
        return rc;
    }
    if (o.refine_error > 0.0f &&
        (rc = rq_refine_init(&e->ref, width, height, o.refine_error, (uint16_t)o.refine_max, err)) != 0) {
        rq_free(e);
        return rc;
    }
    if (o.n_sig > 0) {
        e->sig = malloc((size_t)o.n_sig * sizeof *e->sig);
        if (!e->sig) {
            rq_free(e);
            return ct_fail(err, CT_ENOMEM, "sampler: cannot allocate %d significant samples", o.n_sig);
        }
        e->grows++;
    }
    if ((rc = queue_seeds(e, err)) != 0) {
        rq_free(e);
        return rc;
    }
    *out = e;
    return 0;
}

void rq_free(rq_engine *e)
{
    if (!e) return;
    rq_heap_free(&e->heap);
    rq_mask_free(&e->mask);
    rq_refine_free(&e->ref);
    free(e->fl);
    free(e->sig);
    free(e);
}

void rq_stats_get(const rq_engine *e, rq_stats *st)
{
    *st = e->st;
    st->allocations = e->grows + e->heap.grows + e->mask.grows;
    st->queued = e->heap.n;
    st->in_flight = e->fl_out;
    st->epoch = e->epoch;
    st->list_mode = e->list_mode;
    st->sampled_pixels = e->mask.count;
    st->total_pixels = (uint64_t)e->w * (uint64_t)e->h;
    st->covered = st->sampled_pixels == st->total_pixels && e->fl_out == e->fl_refine;
    st->coverage = (double)st->sampled_pixels / (double)st->total_pixels;
    st->refining = e->ref.active;
    st->refine_samples = e->ref.samples;
    st->refine_error = e->ref.active ? e->ref.top : 0.0f;
}

bool rq_refines(const rq_engine *e, uint64_t id)
{
    if (id < e->fl_lo || id >= e->next_id) return false;
    const flight *f = &e->fl[id & (e->fl_cap - 1)];
    return f->outstanding && f->kind == RQ_KIND_REFINE;
}

vec3 rq_pixel_mean(const rq_engine *e, float px, float py)
{
    int64_t p = pixel_of(e, px, py);
    return p < 0 ? v3s(0.0f) : rq_refine_mean(&e->ref, (uint32_t)p);
}

uint16_t rq_pixel_samples(const rq_engine *e, float px, float py)
{
    int64_t p = pixel_of(e, px, py);
    return p < 0 ? 0 : rq_refine_samples(&e->ref, (uint32_t)p);
}
