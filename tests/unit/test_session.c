/* The master's session and loop in one process (master/session.h,
 * master/drive.h) over the in-process tracer port (tracer/tport_local.h,
 * the real tracer) with a sink that records: the shown-node map is the
 * interactive image's item buffer; a live run (lockstep frames, two lanes,
 * two master threads) and an offline one (checkpoints, one lane, one
 * thread) of the same requests give the same textures; samples that hit
 * another node than the one shown get mismatch children. Cornell at 64x64
 * with the radiosity stand-in. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/pool.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "master/drive.h"
#include "master/session.h"
#include "master/sink.h"
#include "tracer/tport_local.h"
#include "tracer/tracer.h"

#define W 64
#define H 64
#define SCENE "scenes/cornell/cornell.json"

static ct_error err;
static ct_scene *scene;
static ct_radmesh mesh;
static trc_tracer *tracer;
static ct_camera cam;

static void setup(void)
{
    cr_assert_eq(scene_load(SCENE, &scene, &err), 0, "%s", err.msg);
    cr_assert_eq(rmesh_from_scene(scene, v3s(0.3f), &mesh, &err), 0, "%s", err.msg);
    trc_options to;
    trc_options_default(&to, TRC_MODE_DRT);
    to.shadow_rays = 1;
    to.branch = 1;
    to.depth = 2;
    cr_assert_eq(trc_new(scene, &mesh, &to, &tracer, &err), 0, "%s", err.msg);
    int ci = scene_find_camera(scene, "front");
    cr_assert_geq(ci, 0);
    cam = scene->cams[ci].cam;
}

static void teardown(void)
{
    trc_free(tracer);
    rmesh_free(&mesh);
    scene_free(scene);
}

TestSuite(session, .init = setup, .fini = teardown, .timeout = 120);

static sess *new_session(const ct_radmesh *m, int threads)
{
    rq_options ro;
    rq_options_default(&ro);
    ctex_options co = ctex_options_default();
    sess_config c = {m, scene->mats, scene->nmats, &ro, &co, 1, {threads}};
    sess *s = NULL;
    cr_assert_eq(sess_new(&c, &s, &err), 0, "%s", err.msg);
    cr_assert_eq(sess_threads(s), threads);
    return s;
}

/* The primary hit's part at every pixel centre, traced. */
static void traced_nodes(uint32_t *out)
{
    ct_request *req = calloc(W * H, sizeof *req);
    ct_sample *smp = calloc(W * H, sizeof *smp);
    for (int i = 0; i < W * H; i++)
        req[i] = (ct_request){.id = (uint64_t)i + 1, .px = (float)(i % W) + 0.5f, .py = (float)(i / W) + 0.5f};
    trc_view v = {cam, W, H};
    trc_trace_par(tracer, NULL, &v, req, W * H, smp, true, NULL);
    for (int i = 0; i < W * H; i++) out[i] = (smp[i].flags & CT_SAMPLE_HIT) ? smp[i].node : RQ_NODE_NONE;
    free(req);
    free(smp);
}

Test(session, shown_map_is_the_item_buffer)
{
    static uint32_t traced[W * H];
    traced_nodes(traced);
    for (int threads = 1; threads <= 3; threads++) {
        sess *s = new_session(&mesh, threads);
        cr_assert_null(sess_shown(s));
        cr_assert_eq(sess_set_view(s, &cam, W, H, &err), 1, "%s", err.msg);
        const uint32_t *shown = sess_shown(s);
        cr_assert_not_null(shown);
        int same = 0;
        for (int i = 0; i < W * H; i++) same += shown[i] == traced[i];
        /* only pixel centres on an edge between parts may differ */
        cr_assert_geq(same, W * H * 98 / 100, "%d threads: %d of %d pixels agree with the traced hits", threads, same,
                      W * H);
        sess_free(s);
    }
}
