/* session.h: the master's engine as one object, the same in corrtex-render
 * and in corrtex converge: the request queue (sampler.h), the texture
 * hierarchy and corrective textures (ctex.h), the epochs of the current
 * view, its shown-node map (shown.h: which part the interactive image shows
 * at each pixel, so that §3.7's node-mismatch check runs wherever the
 * session runs) and the master's threads (common/pool.h).
 *
 * Samples go in through sess_insert in the order given, in chunks of
 * SESS_CHUNK: a chunk's samples are splatted on the threads, partitioned by
 * texture (ctex_insert_par), and then reported to the request queue one by
 * one in their order with the errors the splats measured; refinement
 * samples (docs/sampling.md) are not splatted: after the others they are
 * reported, and those the queue takes into their pixel's mean move its
 * texels (ctex_refine_par). So the textures and the queue depend on the order of the
 * samples and never on the number of threads: lockstep rounds, inserted in
 * request-id order, give the same frames for any number of tracer ranks and
 * master threads. A sample of an older view (the camera moved on while it
 * was traced) is *late*: the queue never hears of it, but where its surface
 * is diffuse (ctex_view_independent), or where the eye has not moved since
 * (a camera that only turned: the radiance toward the eye is the same), it
 * is still splatted into the current view's textures after the chunk's
 * others; elsewhere it is stale and dropped. A sink (sink.h) hears of every sample of the current view that
 * went in. Owns the sess_ prefix. */
#ifndef CT_MASTER_SESSION_H
#define CT_MASTER_SESSION_H

#include <stdbool.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/optab.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "common/records.h"
#include "common/scene.h"
#include "master/ctex.h"
#include "master/sampler.h"
#include "master/sink.h"

/* Samples splatted together (the unit of the deferred resolution changes,
 * ctex_insert_par): fixed, so that results do not depend on how samples
 * arrive. */
#define SESS_CHUNK 1024u

typedef struct sess_options {
    int threads;           /* master threads inserting samples; 0: the cores this process may use */
    double shown_rest_ms;  /* running free, a view's shown-node map is drawn once it is this old; 0: at once */
    double view_mem_mb;    /* a view whose per-pixel state may need more (MiB) is refused; 0: no cap */
} sess_options;

/* The option table (--master-threads, --shown-rest-ms, --view-mem-mb). */
const optab *sess_options_table(size_t *n);

typedef struct sess_config {
    const ct_radmesh *mesh;          /* the interactive solution (kept by the caller) */
    const scene_material *mats;      /* the scene's materials */
    uint32_t nmats;
    const rq_options *rq;
    const ctex_options *ctex;
    uint64_t seed;
    sess_options opt;
} sess_config;

/* Counters since the start. */
typedef struct sess_counters {
    uint64_t inserted;     /* samples inserted (splatted or not) */
    uint64_t no_texture;   /* ... of them without a texture (a miss, culled, off its texture) */
    uint64_t late;         /* samples of an older view splatted all the same (diffuse surfaces, the same eye, or aged; counted in inserted) */
    uint64_t stale;        /* samples of an older view, ignored (too old a view, or the three below) */
    uint64_t late_turned;  /* ... of them glossy, their viewing direction turned past --late-deg x glossiness */
    uint64_t late_covered; /* ... of them finding a fresher sample's texel at their centre */
    uint64_t late_off;     /* ... of them with no texture at their hit now (misses, parts this view does not texture) */
    uint64_t rejected;     /* samples the request queue refused (logged) */
    bool all_positive;     /* every correction so far was >= 0 (the display may skip pass 3) */
    double t_texture;      /* seconds in insertion and view changes */
    double t_next;         /* seconds in sess_next (the queue's pops, nothing beside them) */
    double t_ahead;        /* seconds of the pops inside sess_insert_next (on a side thread with 2+ threads; t_texture's wall includes what was not hidden) */
    uint64_t views;        /* views set (epochs) */
    double t_view;         /* seconds in setting them (queue, textures, and the map when drawn at once) */
    uint64_t shown_maps;   /* shown-node maps drawn */
} sess_counters;

typedef struct sess sess;

int sess_new(const sess_config *c, sess **out, ct_error *err);
void sess_free(sess *s);

/* The master's threads. */
int sess_threads(const sess *s);

/* Sets the view: 1 when it starts a new epoch (the request queue starts
 * over or reprojects, the textures are aged and reassigned, the shown-node
 * map is drawn or, running free with shown_rest_ms > 0, marked due), 0 when
 * it is the current view, negative for a camera or image the engines refuse
 * (then there is no view until the next one). */
int sess_set_view(sess *s, const ct_camera *cam, int width, int height, ct_error *err);

/* Lockstep (frames that must not depend on timing): every view's
 * shown-node map is drawn when the view is set. Running free (the default),
 * a moving camera's views do not wait for theirs: it is drawn when the first
 * samples go in after the view is shown_rest_ms old, and until then §3.7's
 * node check is skipped (it matters for the refinement of a view the camera
 * rests on; drawing the map costs tens of milliseconds per view at 1024^2,
 * docs/sampling.md). */
void sess_set_lockstep(sess *s, bool on);

bool sess_has_view(const sess *s);
bool sess_same_view(const sess *s, const ct_camera *cam, int width, int height);
void sess_view(const sess *s, ct_camera *cam, int *width, int *height);

/* The epoch of the current view: what requests carry to the tracers. */
uint32_t sess_epoch(const sess *s);

/* Pops up to n requests of the current view, stamped with its epoch;
 * fewer only when every pixel has been handed out (0 without a view). */
int sess_next(sess *s, ct_request *out, uint32_t n, ct_error *err);

/* Inserts n samples in this order (see above); samples of an older epoch
 * are splatted where they are view-independent, else counted and ignored.
 * sink (may be NULL) gets the inserted ones of the current epoch. */
int sess_insert(sess *s, const ct_sample *smp, uint32_t n, const sink *k, ct_error *err);

/* sess_insert, and the next batch: up to `want` requests of the current
 * view popped into out (as sess_next; *got how many) after the queue's
 * look at the first samples (which of them refine) and before any of them
 * is reported. So the next batch can go out without waiting for this
 * one's report, and on two or more threads the pops run beside the first
 * chunk's splats (a side job of the pool). The queue sees the same
 * operations in the same order for any number of threads; what it hands
 * out then does not know of these samples' children (one batch behind, as
 * a tracer with batches in flight sees it anyway). Negative (the queue's
 * error) when the pops failed; the samples went in all the same. */
int sess_insert_next(sess *s, const ct_sample *smp, uint32_t n, const sink *k, ct_request *out, uint32_t want,
                     int *got, ct_error *err);

/* The corrective textures (for a sink that sends or draws them). */
ctex *sess_textures(sess *s);

/* The request queue's counters (zero without a view). */
void sess_queue_stats(const sess *s, rq_stats *st);

sess_counters sess_get_counters(const sess *s);

/* The shown-node map of the current view (width x height, RQ_NODE_NONE for
 * background), NULL without a view or while it is not drawn yet. */
const uint32_t *sess_shown(const sess *s);

#endif
