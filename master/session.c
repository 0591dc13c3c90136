/* session.c: the master's engine (session.h). About 600 lines: the sorting
 * of a chunk (splats, refinement, late samples) and the side jobs that
 * overlap its reports with the texel writes share the chunk's buffers and
 * their ordering rules; split, each half would need the other's. */
#include "master/session.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "common/timer.h"
#include "master/shown.h"

#define COMPONENT "master"

/* One chunk's samples: those to splat, and the report of them to the queue
 * as a side job of the pool (report_task); its refinement samples, those of
 * them that move their pixel's texels and their pixels' sample counts
 * (refine_report), and its late samples (refine_write). */
typedef struct chunk {
    sess *s;
    ct_sample *splat;
    ctex_insert_info *info;
    uint32_t m;
    ct_sample *refine, *write;   /* write: the refinement samples that move their pixel's texels */
    ct_sample *late;             /* of an older view: diffuse, or traced from an eye of the last views */
    vec3 *late_eye;              /* the eye each late one was traced from */
    uint16_t *npx;               /* the writes' pixel sample counts */
    ctex_insert_info *winfo;     /* refinement writes and late splats */
    uint32_t nr, nw, nl;
    ct_error err;        /* the side job's own: the caller's may be in use */
} chunk;

enum { SESS_EYES = 16 };

struct sess {
    rq_options rq_opt;
    ctex_options ctex_opt;
    uint64_t seed;
    const ct_radmesh *mesh;
    ct_pool *pool;
    ctex *tex;
    rq_engine *rq;
    bool have_view;
    ct_camera cam;
    int w, h;
    uint32_t epoch;        /* internal: what the tracers see */
    uint32_t rq_epoch;     /* the request queue's own (it starts over with the image size) */
    uint32_t *shown;
    size_t shown_cap;
    shown_buf *sb;
    bool shown_ok;         /* the map is of the current view */
    bool lockstep;
    double shown_rest;     /* seconds (sess_options.shown_rest_ms) */
    double view_mem_mb;    /* sess_options.view_mem_mb; 0: no cap */
    double view_t;         /* when the current view was set */
    /* The eyes of the last views, by epoch (slot epoch % EYES): a sample
     * of a view the camera left goes in aged by how far its viewing
     * direction turned since (classify, ctex_insert_late_par). */
    vec3 eye[SESS_EYES];
    uint32_t eye_epoch[SESS_EYES];
    sess_counters n;
    /* Two chunks: the queue hears of one while the next is splatted, or
     * while the texels of the one before move (sess_insert). */
    chunk ch[2];
};

#define OF(f) offsetof(sess_options, f)
static const optab OPTS[] = {
    {"master-threads", 0, OPTAB_INT, OF(threads), 0, POOL_MAX_THREADS, "0", "N",
     "threads of the master inserting samples; 0: the cores it may use", NULL},
    {"shown-rest-ms", 0, OPTAB_DOUBLE, OF(shown_rest_ms), 0, 60000, "250", "X",
     "running free, the shown-node map of a view (§3.7's node check) is drawn once the camera rested this long "
     "(ms); 0: with every view", NULL},
    {"view-mem-mb", 0, OPTAB_DOUBLE, OF(view_mem_mb), 0, 1e9, "4096", "X",
     "memory cap for a view's per-pixel state (request queue, refinement records, shown-node map), MiB: a larger "
     "image is refused; 0: no cap", NULL},
};
#undef OF

const optab *sess_options_table(size_t *n)
{
    *n = OPTAB_COUNT(OPTS);
    return OPTS;
}

int sess_new(const sess_config *c, sess **out, ct_error *err)
{
    *out = NULL;
    sess *s = calloc(1, sizeof *s);
    if (!s) return ct_fail(err, CT_ENOMEM, "master: out of memory");
    if (c->rq) s->rq_opt = *c->rq;
    else rq_options_default(&s->rq_opt);
    s->ctex_opt = c->ctex ? *c->ctex : ctex_options_default();
    s->seed = c->seed;
    s->mesh = c->mesh;
    s->n.all_positive = true;
    s->shown_rest = c->opt.shown_rest_ms / 1000.0;
    s->view_mem_mb = c->opt.view_mem_mb;
    int threads = c->opt.threads > 0 ? c->opt.threads : pool_cpus();
    if (threads > POOL_MAX_THREADS) threads = POOL_MAX_THREADS;
    bool ok = true;
    for (int i = 0; i < 2; i++) {
        chunk *h = &s->ch[i];
        h->s = s;
        h->splat = malloc(SESS_CHUNK * sizeof *h->splat);
        h->info = malloc(SESS_CHUNK * sizeof *h->info);
        h->refine = malloc(SESS_CHUNK * sizeof *h->refine);
        h->write = malloc(SESS_CHUNK * sizeof *h->write);
        h->late = malloc(SESS_CHUNK * sizeof *h->late);
        h->late_eye = malloc(SESS_CHUNK * sizeof *h->late_eye);
        h->npx = malloc(SESS_CHUNK * sizeof *h->npx);
        h->winfo = malloc(SESS_CHUNK * sizeof *h->winfo);
        ok = ok && h->splat && h->info && h->refine && h->write && h->late && h->late_eye && h->npx && h->winfo;
    }
    int rc = ok ? CT_OK : ct_fail(err, CT_ENOMEM, "master: out of memory");
    if (!rc) rc = pool_new(threads, &s->pool, err);
    if (!rc) rc = ctex_new(c->mesh, c->mats, c->nmats, &s->ctex_opt, &s->tex, err);
    if (rc) {
        sess_free(s);
        return rc;
    }
    *out = s;
    return CT_OK;
}

void sess_free(sess *s)
{
    if (!s) return;
    rq_free(s->rq);
    ctex_free(s->tex);
    pool_free(s->pool);
    shown_buf_free(s->sb);
    free(s->shown);
    for (int i = 0; i < 2; i++) {
        chunk *c = &s->ch[i];
        free(c->splat);
        free(c->info);
        free(c->refine);
        free(c->write);
        free(c->late);
        free(c->late_eye);
        free(c->npx);
        free(c->winfo);
    }
    free(s);
}

int sess_threads(const sess *s)
{
    return pool_threads(s->pool);
}

bool sess_same_view(const sess *s, const ct_camera *cam, int width, int height)
{
    return s->have_view && width == s->w && height == s->h && memcmp(cam, &s->cam, sizeof *cam) == 0;
}

/* The shown-node map of the current view (s->cam, s->w, s->h). */
static int draw_shown(sess *s, ct_error *err)
{
    double t0 = ct_now();
    int rc = shown_render(s->mesh, &s->cam, s->w, s->h, s->pool, &s->sb, RQ_NODE_NONE, s->shown, err);
    if (rc) return rc;
    s->shown_ok = true;
    s->n.shown_maps++;
    ct_debug(COMPONENT, "shown-node map %dx%d: %.1f ms (%u triangles, %d threads)", s->w, s->h,
             1e3 * (ct_now() - t0), s->mesh->ntris, pool_threads(s->pool));
    return CT_OK;
}

/* A display (or a command line) may ask for any image up to the protocol's
 * 16384 x 16384, whose per-pixel state alone is some 32 GiB: refused before
 * anything is allocated, with the old view kept, rather than left to grow
 * until the host runs out of memory (the master goes on sampling a view
 * after its display left). */
static int view_fits(const sess *s, int width, int height, ct_error *err)
{
    uint64_t npx = (uint64_t)(width > 0 ? width : 0) * (uint64_t)(height > 0 ? height : 0);
    uint64_t q = rq_view_bytes(width, height, &s->rq_opt);
    uint64_t m = npx * sizeof *s->shown + shown_bytes(width, height, pool_threads(s->pool));
    double mib = (double)(q + m) / 1048576.0;
    if (!(s->view_mem_mb > 0.0) || mib <= s->view_mem_mb) return CT_OK;
    return ct_fail(err, CT_ENOMEM,
                   "a %dx%d view needs up to %.0f MiB (request queue and refinement %.0f, shown-node map %.0f), over "
                   "--view-mem-mb %g",
                   width, height, mib, (double)q / 1048576.0, (double)m / 1048576.0, s->view_mem_mb);
}

int sess_set_view(sess *s, const ct_camera *cam, int width, int height, ct_error *err)
{
    if (sess_same_view(s, cam, width, height)) return 0;
    double t0 = ct_now();
    int rc;
    if (!s->rq || width != s->w || height != s->h) {
        if ((rc = view_fits(s, width, height, err))) return rc;
        rq_free(s->rq);
        s->rq = NULL;
        s->have_view = false;   /* nothing is handed out until a camera is accepted */
        if ((rc = rq_new(&s->rq, width, height, cam, &s->rq_opt, s->seed, err))) return rc;
        s->rq_epoch = 0;
    } else {
        if ((rc = rq_set_camera(s->rq, cam, s->rq_epoch + 1, err))) return rc;
        s->rq_epoch++;
    }
    s->have_view = false;
    size_t npx = (size_t)width * (size_t)height;
    if (npx > s->shown_cap) {
        free(s->shown);
        s->shown = malloc(npx * sizeof *s->shown);
        s->shown_cap = s->shown ? npx : 0;
        if (!s->shown) return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d shown-node map", width, height);
    }
    ctex_set_clock(s->tex, ct_now_us());   /* stamps of the textures it makes */
    if ((rc = ctex_set_camera(s->tex, cam, width, height, err))) return rc;
    ctex_stats ts = ctex_get_stats(s->tex);
    ct_debug(COMPONENT, "view %dx%d: queue and textures %.1f ms (textures resampled %llu, kept on their projector %llu "
             "so far)", width, height, 1e3 * (ct_now() - t0), (unsigned long long)ts.resampled,
             (unsigned long long)ts.kept);
    s->cam = *cam;
    s->w = width;
    s->h = height;
    s->shown_ok = false;
    s->view_t = ct_now();
    if ((s->lockstep || !(s->shown_rest > 0.0)) && (rc = draw_shown(s, err))) return rc;
    s->have_view = true;
    s->epoch++;
    s->eye[s->epoch % SESS_EYES] = cam->eye;
    s->eye_epoch[s->epoch % SESS_EYES] = s->epoch;
    s->n.views++;
    s->n.t_view += ct_now() - t0;
    s->n.t_texture += ct_now() - t0;
    return 1;
}

void sess_set_lockstep(sess *s, bool on)
{
    s->lockstep = on;
}

bool sess_has_view(const sess *s)
{
    return s->have_view;
}

void sess_view(const sess *s, ct_camera *cam, int *width, int *height)
{
    if (cam) *cam = s->cam;
    if (width) *width = s->w;
    if (height) *height = s->h;
}

uint32_t sess_epoch(const sess *s)
{
    return s->epoch;
}

int sess_next(sess *s, ct_request *out, uint32_t n, ct_error *err)
{
    if (!s->have_view || n == 0) return 0;
    double t0 = ct_now();
    int k = rq_next_batch(s->rq, out, n > INT32_MAX ? INT32_MAX : (int)n, err);
    for (int i = 0; i < k; i++) out[i].epoch = s->epoch;
    s->n.t_next += ct_now() - t0;
    return k;
}

/* The node the interactive image shows where sample x lies, for §3.7's
 * check. The map holds pixel centres; a sample between four centres is
 * taken to show what any of them shows, since an edge between two parts
 * may pass anywhere between two centres: otherwise every sample beside a
 * silhouette would count as a disagreement about visibility. The sample's
 * own node when one of the four shows it, else the one at its pixel. */
static uint32_t shown_at(const sess *s, const ct_sample *x)
{
    if (!s->shown_ok) return RQ_NODE_UNKNOWN;
    float fx = floorf(x->px), fy = floorf(x->py);
    if (!(fx >= 0.0f && fy >= 0.0f && fx < (float)s->w && fy < (float)s->h)) return RQ_NODE_UNKNOWN;
    uint32_t hit = (x->flags & CT_SAMPLE_HIT) ? x->node : RQ_NODE_NONE;
    uint32_t own = s->shown[(size_t)fy * (size_t)s->w + (size_t)fx];
    if (own == hit) return hit;   /* most samples: one look */
    int x0 = (int)floorf(x->px - 0.5f), y0 = (int)floorf(x->py - 0.5f);
    for (int j = y0; j <= y0 + 1; j++)
        for (int i = x0; i <= x0 + 1; i++) {
            int ci = i < 0 ? 0 : i >= s->w ? s->w - 1 : i, cj = j < 0 ? 0 : j >= s->h ? s->h - 1 : j;
            if (s->shown[(size_t)cj * (size_t)s->w + (size_t)ci] == hit) return hit;
        }
    return own;
}

static inline __attribute__((always_inline)) void prefetch_shown(const sess *s, const ct_sample *x)
{
    float fx = floorf(x->px), fy = floorf(x->py);
    if (s->shown_ok && fx >= 0.0f && fy >= 0.0f && fx < (float)s->w && fy < (float)s->h)
        __builtin_prefetch(&s->shown[(size_t)fy * (size_t)s->w + (size_t)fx], 0, 1);
}

static void count(sess *s, const ct_sample *x, const ctex_insert_info *info)
{
    s->n.inserted++;
    if (info->tex < 0) s->n.no_texture++;
    vec3 c = info->correction, d = v3_sub(x->l_hq, x->l_base);
    if (c.x < 0 || c.y < 0 || c.z < 0 || d.x < 0 || d.y < 0 || d.z < 0) s->n.all_positive = false;
}

static void rejected(sess *s, const ct_sample *x, ct_error *err)
{
    ct_warn(COMPONENT, "sample %llu rejected by the request queue: %s", (unsigned long long)x->request_id, err->msg);
    ct_error_clear(err);
    s->n.rejected++;
}

/* The eye a sample of epoch `epoch` was traced from, if that view is one
 * of the last SESS_EYES. The radiance a surface sends toward the eye
 * depends on the eye's position, not on where the camera looks: a sample
 * from where the eye is now is exact (a camera that only turned), glossy
 * ones too; from elsewhere it is as stale as a texel aged since. */
static bool eye_of(const sess *s, uint32_t epoch, vec3 *eye)
{
    uint32_t k = epoch % SESS_EYES;
    if (s->eye_epoch[k] != epoch) return false;
    *eye = s->eye[k];
    return true;
}

/* Sorts a chunk (at most SESS_CHUNK samples) into c's samples to splat,
 * its refinement and its late ones (a view the camera left: those on
 * diffuse surfaces, and those traced from the eye of one of the last
 * views, which go in aged; the others are stale). Reads the queue (which
 * requests refine), so it runs before an earlier chunk's report starts. */
static void classify(sess *s, chunk *c, const ct_sample *smp, uint32_t n)
{
    uint32_t m = 0, nr = 0, nl = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (smp[i].epoch != s->epoch) {
            vec3 e = s->cam.eye;   /* a diffuse one's: it needs no aging */
            if (eye_of(s, smp[i].epoch, &e) || ctex_view_independent(s->tex, &smp[i])) {
                c->late_eye[nl] = e;
                c->late[nl++] = smp[i];
            } else {
                s->n.stale++;
            }
        } else if (rq_refines(s->rq, smp[i].request_id)) {
            c->refine[nr++] = smp[i];
        } else {
            c->splat[m++] = smp[i];
        }
    }
    c->m = m;
    c->nr = nr;
    c->nw = 0;
    c->nl = nl;
}

/* Reports a chunk's splatted samples to the queue, in their order, with the
 * errors their splats measured. Touches the queue, the counters and the
 * chunk, never the textures: it runs beside the next chunk's splats. */
static void report_task(void *ctx)
{
    chunk *c = ctx;
    sess *s = c->s;
    for (uint32_t j = 0; j < c->m; j++) {
        /* the map's line and the queue's records of a sample a few ahead
         * (samples land anywhere in megabytes: one cache miss each
         * otherwise) */
        if (j + 8 < c->m) {
            prefetch_shown(s, &c->splat[j + 8]);
            rq_report_prefetch(s->rq, &c->splat[j + 8]);
        }
        ct_sample *x = &c->splat[j];
        count(s, x, &c->info[j]);
        x->epoch = s->rq_epoch;
        if (rq_report(s->rq, x, c->info[j].error, shown_at(s, x), &c->err) < 0) rejected(s, x, &c->err);
    }
}

/* Reports a chunk's refinement samples to the queue, in their order, and
 * lists those the queue takes into their pixel's mean, with the pixel's
 * sample count then (a sample on another node than its pixel's first is
 * counted, not written: rq_refine.h). Touches the queue and the chunk,
 * never the textures: it runs beside the chunk before's texel writes. */
static void refine_report(chunk *c)
{
    sess *s = c->s;
    uint32_t kept = 0, nw = 0;
    for (uint32_t j = 0; j < c->nr; j++) {
        /* as report_task: refinement picks pixels all over the view */
        if (j + 8 < c->nr) {
            prefetch_shown(s, &c->refine[j + 8]);
            rq_report_prefetch(s->rq, &c->refine[j + 8]);
        }
        ct_sample *x = &c->refine[j];
        x->epoch = s->rq_epoch;
        int rc = rq_report(s->rq, x, v3s(0.0f), shown_at(s, x), &c->err);
        if (rc < 0) {
            rejected(s, x, &c->err);
            continue;
        }
        c->refine[kept++] = *x;
        if (rc & RQ_REPORT_REFINE) {
            c->write[nw] = *x;
            c->npx[nw++] = rq_pixel_samples(s->rq, x->px, x->py);
        }
    }
    c->nr = kept;
    c->nw = nw;
}

/* The texels of a chunk after its reports: the refinement writes, then the
 * late samples (splatted, never reported: their requests belong to a view
 * the queue has left). Touches the textures and the counters, never the
 * queue. */
static void refine_write(sess *s, chunk *c)
{
    ctex_refine_par(s->tex, s->pool, c->write, c->npx, c->nw, c->winfo);
    const ctex_insert_info unwritten = {.tex = -1};
    for (uint32_t j = 0, w = 0; j < c->nr; j++) {
        bool written = w < c->nw && c->write[w].request_id == c->refine[j].request_id;
        count(s, &c->refine[j], written ? &c->winfo[w++] : &unwritten);
    }
    if (c->nl) {
        ctex_insert_late_par(s->tex, s->pool, c->late, c->late_eye, c->nl, c->winfo);
        for (uint32_t j = 0; j < c->nl; j++) {
            if (c->winfo[j].tex < 0) {
                s->n.stale++;
                int why = c->winfo[j].radius;
                if (why == CTEX_LATE_TURNED) s->n.late_turned++;
                else if (why == CTEX_LATE_COVERED) s->n.late_covered++;
                else s->n.late_off++;
                continue;
            }
            count(s, &c->late[j], &c->winfo[j]);
            s->n.late++;
        }
    }
}

static void to_sink(const chunk *c, const sink *k)
{
    if (!k || !k->samples) return;
    if (c->m) k->samples(k->user, c->splat, c->m);
    if (c->nr) k->samples(k->user, c->refine, c->nr);
}

/* Requests popped ahead of a batch's reports (sess_insert_next), in one
 * portion per chunk of the batch. */
typedef struct next_job {
    sess *s;
    ct_request *out;
    uint32_t want;
    uint32_t parts;   /* portions: the batch's chunks */
    int got;          /* requests so far, or the queue's error */
    double dt;        /* seconds */
    ct_error err;
} next_job;

/* Portion i of the pops. */
static void pop_portion(next_job *j, uint32_t i)
{
    if (!j || j->got < 0) return;
    uint32_t a = (uint32_t)((uint64_t)j->want * i / j->parts), b = (uint32_t)((uint64_t)j->want * (i + 1) / j->parts);
    if (b <= a) return;
    double t0 = ct_now();
    ct_request *out = j->out + j->got;
    int k = rq_next_batch(j->s->rq, out, (int)(b - a), &j->err);
    if (k < 0) {
        j->got = k;
    } else {
        for (int q = 0; q < k; q++) out[q].epoch = j->s->epoch;
        j->got += k;
    }
    j->dt += ct_now() - t0;
}

/* What the side thread does beside a chunk's splats or the texel writes of
 * the chunk before: the report of the chunk before (if any), or the
 * refinement reports of the chunk (if any), then the next portion of the
 * pops (if any). */
typedef struct side_job {
    chunk *report;
    chunk *refine;
    next_job *ahead;
    uint32_t portion;
} side_job;

static void side_task(void *ctx)
{
    side_job *j = ctx;
    if (j->report) report_task(j->report);
    if (j->refine) refine_report(j->refine);
    pop_portion(j->ahead, j->portion);
}

/* Splats chunk c (classified) while the side job runs beside it (none
 * when it has nothing to do). */
static void splat_beside(sess *s, chunk *c, side_job *sj)
{
    bool side = sj->report || sj->refine || sj->ahead;
    if (side) pool_side(s->pool, side_task, sj);
    ctex_insert_par(s->tex, s->pool, c->splat, c->m, c->info);
    if (side) pool_side_wait(s->pool);
}

/* The chunks in order: each is classified and splatted, then reported
 * (its refinement samples after its splatted ones), then its texels move
 * (refinement writes, late samples). The queue's work and the textures'
 * overlap where they can: a chunk's report runs on another thread (a side
 * job of the pool) while the next chunk is splatted when it has no texels
 * to move after it; a chunk of refinement samples alone (a still view past
 * full coverage) is reported while the chunk before moves its texels; each
 * portion of the pops ahead follows on the side thread. The queue's
 * operations come in one fixed order (classify chunk c + 1, the reports,
 * pop portion c + 1), so do the textures' (the reports and the pops read no
 * texel, the texel work no queue state), and the result does not depend on
 * the threads. */
static void insert_chunks(sess *s, const ct_sample *smp, uint32_t n, const sink *k, next_job *ahead)
{
    uint32_t nchunks = (n + SESS_CHUNK - 1) / SESS_CHUNK;
    if (ahead) ahead->parts = nchunks;
    chunk *cur = &s->ch[0];
    classify(s, cur, smp, n < SESS_CHUNK ? n : SESS_CHUNK);
    side_job sj = {NULL, NULL, ahead, 0};
    splat_beside(s, cur, &sj);
    bool reported = false;   /* cur's reports ran beside the chunk before's texels */
    for (uint32_t c = 0; c < nchunks; c++) {
        chunk *nxt = cur == &s->ch[0] ? &s->ch[1] : &s->ch[0];
        uint32_t at = (c + 1) * SESS_CHUNK, nn = c + 1 < nchunks ? (n - at < SESS_CHUNK ? n - at : SESS_CHUNK) : 0;
        bool done = reported;
        reported = false;
        if (nn) classify(s, nxt, smp + at, nn);
        if (nn && cur->nr == 0 && cur->nl == 0) {
            /* nothing to write after its report: reported beside the next
             * chunk's splats */
            sj = (side_job){cur, NULL, ahead, c + 1};
            splat_beside(s, nxt, &sj);
            to_sink(cur, k);
            cur = nxt;
            continue;
        }
        if (!done) {
            report_task(cur);
            refine_report(cur);
        }
        if (nn && nxt->m == 0 && nxt->nl == 0) {
            /* refinement alone next: its reports beside these texels */
            sj = (side_job){NULL, nxt, ahead, c + 1};
            pool_side(s->pool, side_task, &sj);
            refine_write(s, cur);
            pool_side_wait(s->pool);
            reported = true;
            to_sink(cur, k);
        } else {
            refine_write(s, cur);
            to_sink(cur, k);
            if (nn) {
                sj = (side_job){NULL, NULL, ahead, c + 1};
                splat_beside(s, nxt, &sj);
            }
        }
        cur = nxt;
    }
}

int sess_insert_next(sess *s, const ct_sample *smp, uint32_t n, const sink *k, ct_request *out, uint32_t want,
                     int *got, ct_error *err)
{
    *got = 0;
    if (!s->have_view) {
        s->n.stale += n;
        return CT_OK;
    }
    double t0 = ct_now();
    if (!s->shown_ok && (s->lockstep || t0 - s->view_t >= s->shown_rest)) {
        int rc = draw_shown(s, err);
        if (rc) return rc;
    }
    ctex_set_clock(s->tex, ct_now_us());
    next_job ahead = {s, out, want, 1, 0, 0.0, {0}};
    if (n) insert_chunks(s, smp, n, k, want ? &ahead : NULL);
    else if (want) pop_portion(&ahead, 0);
    s->n.t_ahead += ahead.dt;
    s->n.t_texture += ct_now() - t0;
    if (ahead.got < 0) {
        *err = ahead.err;
        return ahead.got;
    }
    *got = ahead.got;
    return CT_OK;
}

int sess_insert(sess *s, const ct_sample *smp, uint32_t n, const sink *k, ct_error *err)
{
    int got;
    return sess_insert_next(s, smp, n, k, NULL, 0, &got, err);
}

ctex *sess_textures(sess *s)
{
    return s->tex;
}

void sess_queue_stats(const sess *s, rq_stats *st)
{
    if (s->rq) rq_stats_get(s->rq, st);
    else memset(st, 0, sizeof *st);
}

sess_counters sess_get_counters(const sess *s)
{
    return s->n;
}

const uint32_t *sess_shown(const sess *s)
{
    return s->have_view && s->shown_ok ? s->shown : NULL;
}
