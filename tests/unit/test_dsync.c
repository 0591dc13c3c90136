/* test_dsync.c: texture updates to a display (master/dsync.h) over a real
 * display server and socket: the display ends with exactly the master's
 * texels; no more than `window` updates go out unacknowledged however many
 * samples are inserted meanwhile; texels changed several times between two
 * updates go out once (newest wins); an update holds about its budget and
 * the next one resumes where it stopped; lockstep sends everything at once;
 * an ACK of an update never sent is a protocol error; free-running updates
 * keep to their interval and their share of the master's time. */
#include <criterion/criterion.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/half.h"
#include "common/radmesh.h"
#include "common/rng.h"
#include "common/timer.h"
#include "display/disp_rescale.h"
#include "master/ctex_tex.h"
#include "master/dsrv.h"
#include "master/dsync.h"
#include "proto/chan.h"
#include "proto/wire.h"
#include "tests/support/testscenes.h"

/* The display's copy: per texture id its size and halves. */
#define MAXTEX 256
typedef struct copy {
    int w[MAXTEX], h[MAXTEX];
    uint16_t *tx[MAXTEX];
    uint64_t last_sync, patches, texel_bytes;
    uint64_t resizes, resized_bytes;   /* TEX_RESIZEs followed; their textures' texel bytes */
} copy;

typedef struct rig {
    ct_scene *scene;
    ct_radmesh mesh;
    ctex *tex;
    dsrv *ds;
    dsync *sync;
    chan *disp;
    copy cp;
    char spec[128];
    uint64_t next_id;
} rig;

typedef struct conn_arg {
    const char *spec;
    chan *c;
    int rc;
} conn_arg;

static void *connect_display(void *arg)
{
    conn_arg *a = arg;
    chan_config cc = {.role = AUTH_ROLE_DISPLAY};
    ct_error err;
    a->rc = chan_connect(a->spec, &cc, 3000, &a->c, &err);
    if (!a->rc) {
        wire_msg m = {.type = WIRE_SETTINGS};
        a->rc = chan_send(a->c, &m, &err);
        if (!a->rc) a->rc = chan_flush(a->c, 2000, &err);
    }
    return NULL;
}

static void setup(rig *r, const dsync_options *o)
{
    memset(r, 0, sizeof *r);
    ct_error err;
    r->scene = ts_room(&err);
    cr_assert_not_null(r->scene, "%s", err.msg);
    cr_assert_eq(rmesh_from_scene(r->scene, v3s(0.5f), &r->mesh, &err), 0, "%s", err.msg);
    ctex_options co = ctex_options_default();
    cr_assert_eq(ctex_new(&r->mesh, r->scene->mats, r->scene->nmats, &co, &r->tex, &err), 0, "%s", err.msg);
    cr_assert_eq(ctex_set_camera(r->tex, &r->scene->cams[0].cam, 128, 96, &err), 0, "%s", err.msg);
    snprintf(r->spec, sizeof r->spec, "unix:/tmp/ct-dsync-%d.sock", (int)getpid());
    dsrv_config dc = {.listen = r->spec, .handshake_timeout_ms = 3000};
    cr_assert_eq(dsrv_new(&dc, &r->ds, &err), 0, "%s", err.msg);
    cr_assert_eq(dsync_new(o, &r->sync, &err), 0, "%s", err.msg);
    /* The display connects on a thread while the server steps here. */
    conn_arg a = {r->spec, NULL, -1};
    pthread_t th;
    cr_assert_eq(pthread_create(&th, NULL, connect_display, &a), 0);
    bool connected = false;
    for (int i = 0; i < 3000 && !connected; i++) {
        dsrv_step(r->ds, 1, &err);
        dsrv_event ev;
        while (dsrv_next_event(r->ds, &ev)) connected |= ev.kind == DSRV_EV_CONNECTED;
    }
    pthread_join(th, NULL);
    cr_assert(connected && a.rc == 0, "display did not connect");
    r->disp = a.c;
    uint32_t ntex = 0;
    cr_assert_eq(dsync_send_state(r->sync, r->ds, r->tex, &ntex, &err), 0, "%s", err.msg);
    cr_assert_gt(ntex, 3);
    r->next_id = 1;
}

static void teardown(rig *r)
{
    for (int i = 0; i < MAXTEX; i++) free(r->cp.tx[i]);
    chan_free(r->disp);
    dsync_free(r->sync);
    dsrv_free(r->ds);
    ctex_free(r->tex);
    rmesh_free(&r->mesh);
    scene_free(r->scene);
}

/* Moves bytes both ways and applies what the display got; with ack, SYNCs
 * are acknowledged (as the display's connection thread does). Returns the
 * ACKs delivered to dsync. */
static int pump(rig *r, bool ack, int rounds)
{
    ct_error err;
    int acks = 0;
    for (int i = 0; i < rounds; i++) {
        dsrv_step(r->ds, 0, &err);
        chan_pump(r->disp, &err);
        wire_msg m;
        while (chan_recv(r->disp, &m, &err) == WIRE_OK) {
            copy *c = &r->cp;
            if (m.type == WIRE_TEX_ALLOC) {
                uint32_t id = m.u.tex_alloc.tex;
                cr_assert_lt(id, MAXTEX);
                free(c->tx[id]);
                c->w[id] = (int)m.u.tex_alloc.width;
                c->h[id] = (int)m.u.tex_alloc.height;
                c->tx[id] = calloc((size_t)c->w[id] * (size_t)c->h[id] * 3, sizeof(uint16_t));
            } else if (m.type == WIRE_TEX_RESIZE) {
                /* as the display does: the new texels from the ones here */
                uint32_t id = m.u.tex_resize.tex;
                int nw = (int)m.u.tex_resize.width, nh = (int)m.u.tex_resize.height;
                cr_assert_lt(id, MAXTEX);
                cr_assert_not_null(c->tx[id], "resize of unallocated texture %u", id);
                cr_assert(wire_tex_resize_exact(c->w[id], c->h[id], nw, nh), "texture %u: %dx%d -> %dx%d", id, c->w[id],
                          c->h[id], nw, nh);
                uint16_t *n = malloc((size_t)nw * (size_t)nh * 3 * sizeof *n);
                bool neg, nz;
                cr_assert_eq(disp_rescale(c->tx[id], c->w[id], c->h[id], n, nw, nh, &neg, &nz), 0);
                free(c->tx[id]);
                c->tx[id] = n;
                c->w[id] = nw;
                c->h[id] = nh;
                c->resizes++;
                c->resized_bytes += (uint64_t)nw * (uint64_t)nh * 6;
            } else if (m.type == WIRE_TEX_FREE) {
                free(c->tx[m.u.tex_free.tex]);
                c->tx[m.u.tex_free.tex] = NULL;
            } else if (m.type == WIRE_TEX_PATCH) {
                const wire_tex_patch *p = &m.u.tex_patch;
                cr_assert_not_null(c->tx[p->tex], "patch of unallocated texture %u", p->tex);
                cr_assert_leq(p->x + p->w, (uint32_t)c->w[p->tex]);
                cr_assert_leq(p->y + p->h, (uint32_t)c->h[p->tex]);
                for (uint32_t y = 0; y < p->h; y++)
                    memcpy(c->tx[p->tex] + 3 * ((size_t)(p->y + y) * (size_t)c->w[p->tex] + p->x),
                           p->texels + 3 * (size_t)y * p->w, (size_t)p->w * 6);
                c->patches++;
                c->texel_bytes += (uint64_t)p->w * p->h * 6;
            } else if (m.type == WIRE_SYNC) {
                c->last_sync = m.u.sync.seq;
                if (ack) {
                    wire_msg a = {.type = WIRE_ACK};
                    a.u.ack.seq = m.u.sync.seq;
                    chan_send(r->disp, &a, &err);
                }
            }
        }
        chan_pump(r->disp, &err);
        dsrv_step(r->ds, 0, &err);
        dsrv_event ev;
        while (dsrv_next_event(r->ds, &ev))
            if (ev.kind == DSRV_EV_MESSAGE && ev.msg.type == WIRE_ACK) {
                cr_assert_eq(dsync_ack(r->sync, ev.msg.u.ack.seq, ct_now(), &err), 0, "%s", err.msg);
                acks++;
            }
    }
    return acks;
}

/* n samples at random points of the view: they land on the room's surfaces. */
static void insert(rig *r, int n, uint64_t seed)
{
    ct_rng g = rng_make(seed, 0, 0, 0);
    const ct_camera *cam = &r->scene->cams[0].cam;
    for (int i = 0; i < n; i++) {
        float px = rng_float(&g) * 128.0f, py = rng_float(&g) * 96.0f;
        vec3 d = cam_ray_dir(cam, 128, 96, px, py);
        /* the room's walls: the first plane the ray meets */
        float t = 1e30f;
        float planes[6][2] = {{0, -2}, {0, 2}, {1, 0}, {1, 3}, {2, -2}, {2, 2}};
        for (int k = 0; k < 6; k++) {
            float o = (&cam->eye.x)[(int)planes[k][0]], dd = (&d.x)[(int)planes[k][0]];
            float tt = (planes[k][1] - o) / dd;
            if (tt > 1e-3f && tt < t) t = tt;
        }
        ct_sample s;
        memset(&s, 0, sizeof s);
        s.request_id = r->next_id++;
        s.flags = CT_SAMPLE_HIT;
        s.px = px;
        s.py = py;
        s.hit = v3_madd(cam->eye, d, t * 0.999f);
        s.node = 0;
        s.tri = UINT32_MAX;
        s.l_base = v3s(0.5f);
        s.l_hq = v3(0.5f + rng_float(&g), 0.5f, 0.5f - rng_float(&g));
        /* the part under the hit: try every node, as the tracer would know it */
        ctex_insert_info info;
        for (uint32_t nd = 0; nd < r->scene->nnodes; nd++) {
            s.node = nd;
            if (ctex_owner(r->tex, nd, UINT32_MAX, s.hit) >= 0) {
                ctex_insert(r->tex, &s, &info);
                break;
            }
        }
    }
}

/* The mean of master texels (2x, 2y) .. (2x + 1, 2y + 1) as the display
 * gets it (dsync.c: per channel in float, one rounding to half). */
static void mean_of_four(const ctex_tex *t, int x, int y, uint16_t out[3])
{
    float f[4][4], m[4] = {0};
    half4_to_float(ctex_tex_at(t, 2 * x, 2 * y)->c, f[0]);
    half4_to_float(ctex_tex_at(t, 2 * x + 1, 2 * y)->c, f[1]);
    half4_to_float(ctex_tex_at(t, 2 * x, 2 * y + 1)->c, f[2]);
    half4_to_float(ctex_tex_at(t, 2 * x + 1, 2 * y + 1)->c, f[3]);
    for (int c = 0; c < 3; c++) m[c] = 0.25f * ((f[0][c] + f[1][c]) + (f[2][c] + f[3][c]));
    uint16_t h[4];
    float4_to_half(m, h);
    memcpy(out, h, 3 * sizeof *out);
}

/* Every visible texture's texels, as halves, equal the display's copy: the
 * master's own, or (a texture denser than the screen, sent at half size)
 * the means of 2 x 2 of them. Returns how many went at half size. */
static int expect_same(rig *r)
{
    int checked = 0, halved = 0;
    for (uint32_t id = 0; id < ctex_slot_count(r->tex); id++) {
        ctex_tex *t = ctex_visible_texture(r->tex, id);
        if (!t) continue;
        cr_assert_lt(id, MAXTEX);
        cr_assert_not_null(r->cp.tx[id], "texture %u never allocated on the display", id);
        bool half = r->cp.w[id] != t->w;
        if (half) {
            halved++;
            cr_assert(t->w % 2 == 0 && t->h % 2 == 0, "texture %u of %dx%d sent halved", id, t->w, t->h);
            cr_assert_eq(r->cp.w[id], t->w / 2);
            cr_assert_eq(r->cp.h[id], t->h / 2);
            float rx, ry;
            cr_assert(ctex_texel_rate(r->tex, id, &rx, &ry) && rx > 1.0f && ry > 1.0f,
                      "texture %u sent halved at %g x %g texels a pixel", id, rx, ry);
        } else {
            cr_assert_eq(r->cp.h[id], t->h);
        }
        for (int y = 0; y < r->cp.h[id]; y++)
            for (int x = 0; x < r->cp.w[id]; x++) {
                const uint16_t *got = r->cp.tx[id] + 3 * ((size_t)y * (size_t)r->cp.w[id] + (size_t)x);
                uint16_t want[3];
                if (half) {
                    mean_of_four(t, x, y, want);
                    cr_assert_eq(memcmp(got, want, 6), 0, "texture %u texel %d,%d differs", id, x, y);
                    continue;
                }
                /* whole: the validity the display reads from the bits
                 * (a valid zero is -0), the values (a zero's sign aside) */
                const ctex_texel *p = ctex_tex_at(t, x, y);
                cr_assert_eq((got[0] | got[1] | got[2]) != 0, ctex_texel_valid(p),
                             "texture %u texel %d,%d: validity differs", id, x, y);
                for (int k = 0; k < 3; k++)
                    if ((got[k] | p->c[k]) & 0x7fffu)
                        cr_assert_eq(got[k], p->c[k], "texture %u texel %d,%d channel %d: 0x%04x, master 0x%04x", id,
                                     x, y, k, got[k], p->c[k]);
            }
        checked++;
    }
    cr_assert_gt(checked, 3);
    return halved;
}

/* Updates until nothing is unsent and every update is acknowledged. */
static void settle(rig *r)
{
    ct_error err;
    for (int i = 0; i < 2000; i++) {
        int sent = dsync_update(r->sync, r->ds, r->tex, ct_now(), ct_now_us(), &err);
        cr_assert_geq(sent, 0, "%s", err.msg);
        pump(r, true, 3);
        dsync_stats st = dsync_get_stats(r->sync);
        bool dirty = false;
        for (uint32_t id = 0; id < ctex_slot_count(r->tex); id++) {
            ctex_tex *t = ctex_visible_texture(r->tex, id);
            if (t && t->d.any) dirty = true;
        }
        if (!dirty && st.acked == st.updates && !sent) return;
    }
    cr_assert_fail("updates never settled");
}

Test(dsync, the_display_ends_with_the_masters_texels_and_the_window_holds)
{
    dsync_options o;
    dsync_options_default(&o, false);
    rig r;
    setup(&r, &o);
    ct_error err;
    settle(&r);
    expect_same(&r);
    /* No ACKs now: after `window` updates nothing more goes out, however
     * many samples come in. */
    uint64_t before = dsync_get_stats(r.sync).updates;
    for (int round = 0; round < 20; round++) {
        insert(&r, 200, 100 + (uint64_t)round);
        cr_assert_geq(dsync_update(r.sync, r.ds, r.tex, ct_now(), ct_now_us(), &err), 0);
        pump(&r, false, 2);
    }
    dsync_stats st = dsync_get_stats(r.sync);
    cr_assert_eq(st.updates - before, (uint64_t)o.window, "%llu updates without an ACK",
                 (unsigned long long)(st.updates - before));
    cr_assert_not(dsync_can_send(r.sync));
    /* The display acknowledges what it has: the newest texels follow. */
    wire_msg a = {.type = WIRE_ACK};
    a.u.ack.seq = r.cp.last_sync;
    chan_send(r.disp, &a, &err);
    pump(&r, true, 5);
    settle(&r);
    expect_same(&r);
    /* The textures doubled on the way: the display computed their texels
     * (TEX_RESIZE) and still holds exactly the master's. */
    printf("metric: %llu exact resizes followed by the display (%llu texel bytes it computed), %llu texel bytes "
           "sent\n", (unsigned long long)r.cp.resizes, (unsigned long long)r.cp.resized_bytes,
           (unsigned long long)r.cp.texel_bytes);
    cr_assert_gt(r.cp.resizes, 0, "no exact resize reached the display");
    teardown(&r);
}

Test(dsync, texels_changed_between_updates_go_out_once)
{
    dsync_options o;
    dsync_options_default(&o, false);
    rig r;
    setup(&r, &o);
    settle(&r);
    ct_error err;
    /* First the textures find their resolution (a resize sends a texture
     * whole, which would hide what is measured below). */
    for (int i = 0; i < 30; i++) insert(&r, 300, 5);
    settle(&r);
    /* The same 300 points, 30 times over, between two updates: every
     * change lands on the same tiles. */
    uint64_t b0 = r.cp.texel_bytes;
    for (int i = 0; i < 30; i++) insert(&r, 300, 5);
    settle(&r);
    uint64_t once = r.cp.texel_bytes - b0;
    expect_same(&r);
    /* The same again, with an update after each round. */
    uint64_t b1 = r.cp.texel_bytes;
    for (int i = 0; i < 30; i++) {
        insert(&r, 300, 5);
        settle(&r);
    }
    uint64_t each = r.cp.texel_bytes - b1;
    printf("metric: texel bytes for 30 rounds of the same 300 samples: %llu in one update, %llu in 30\n",
           (unsigned long long)once, (unsigned long long)each);
    cr_assert_gt(once, 0u);
    cr_assert_gt(each, 20 * once, "newest wins: one update sends the texels once");
    (void)err;
    teardown(&r);
}

Test(dsync, an_update_holds_its_budget_and_the_next_resumes)
{
    dsync_options o;
    dsync_options_default(&o, false);
    o.min_bytes = o.max_bytes = 4096;   /* a few tile runs an update */
    rig r;
    setup(&r, &o);
    ct_error err;
    insert(&r, 3000, 77);   /* textures grow past their first coarse size */
    int updates = 0;
    uint64_t prev = 0;
    for (int i = 0; i < 5000; i++) {
        int sent = dsync_update(r.sync, r.ds, r.tex, ct_now(), ct_now_us(), &err);
        cr_assert_geq(sent, 0);
        if (sent) {
            updates++;
            uint64_t now = dsync_get_stats(r.sync).texel_bytes;
            /* a budget, plus the run that crossed it (at most a tile row of
             * the widest texture) */
            cr_assert_leq(now - prev, 4096u + 8u * 6u * 2048u, "update of %llu bytes", (unsigned long long)(now - prev));
            prev = now;
        }
        pump(&r, true, 2);
        bool dirty = false;
        for (uint32_t id = 0; id < ctex_slot_count(r.tex); id++) {
            ctex_tex *t = ctex_visible_texture(r.tex, id);
            if (t && t->d.any) dirty = true;
        }
        dsync_stats st = dsync_get_stats(r.sync);
        if (!dirty && st.acked == st.updates) break;
    }
    printf("metric: the state in %d updates of 4 KiB\n", updates);
    cr_assert_gt(updates, 10);
    expect_same(&r);
    teardown(&r);
}

Test(dsync, lockstep_sends_everything_at_once_and_bad_acks_are_refused)
{
    dsync_options o;
    dsync_options_default(&o, true);
    cr_assert_eq(o.encoding, WIRE_PATCH_LZ4, "TCP: LZ4");
    dsync_options_default(&o, false);
    cr_assert_eq(o.encoding, WIRE_PATCH_RAW, "UNIX: raw");
    o.encoding = WIRE_PATCH_LZ4;
    rig r;
    setup(&r, &o);
    ct_error err;
    insert(&r, 500, 9);
    uint32_t patches = 0;
    cr_assert_eq(dsync_flush_all(r.sync, r.ds, r.tex, &patches, &err), 0, "%s", err.msg);
    cr_assert_gt(patches, 0);
    pump(&r, true, 200);
    cr_assert_eq(r.cp.last_sync, 0u, "lockstep sends no SYNC (FRAME ends it)");
    expect_same(&r);
    cr_assert_eq(dsync_ack(r.sync, 5, ct_now(), &err), CT_EPROTO);
    cr_assert(strstr(err.msg, "ACK of update 5"), "%s", err.msg);
    teardown(&r);
}

/* Textures denser than the screen go to the display as the means of 2 x 2
 * texels (screen_rate, the default on TCP; docs/protocol.md): a quarter
 * of the bytes for them; without it (the default on a UNIX socket)
 * every texel goes as it is. Both end equal to what the master holds
 * (expect_same). */
Test(dsync, dense_textures_go_at_the_screens_rate)
{
    uint64_t bytes[2];
    int halved[2];
    for (int k = 0; k < 2; k++) {
        dsync_options o;
        dsync_options_default(&o, k == 0);
        o.encoding = WIRE_PATCH_RAW;   /* the rig's display copies raw texels */
        cr_assert_eq(o.screen_rate, k == 0, "the default by transport");
        rig r;
        setup(&r, &o);
        /* dense enough that textures double past one texel a pixel */
        for (int i = 0; i < 40; i++) {
            insert(&r, 500, 900 + (uint64_t)i);
            settle(&r);
        }
        halved[k] = expect_same(&r);
        bytes[k] = r.cp.texel_bytes;
        teardown(&r);
    }
    printf("metric: texel bytes to the display for the same samples: %llu at the screen's rate (%d textures "
           "halved), %llu as the master keeps them\n",
           (unsigned long long)bytes[0], halved[0], (unsigned long long)bytes[1]);
    cr_assert_gt(halved[0], 0, "no texture went at half size");
    cr_assert_eq(halved[1], 0, "without screen_rate %d textures were halved", halved[1]);
    cr_expect_lt(bytes[0], bytes[1], "halving sent no fewer bytes");
}

/* Free running, an update is due once the interval has passed and once the
 * updates have had at most their share of the time: one that cost t (the
 * CPU time of its encoding, and of the display's socket reads and writes
 * since the one before) holds the next until t / share after it started.
 * Checked against bounds of that cost (the socket's time as dsrv counts
 * it, the wall time around the calls), so no sleep is needed. */
Test(dsync, updates_keep_to_their_interval_and_share)
{
    dsync_options o;
    dsync_options_default(&o, false);
    cr_assert(o.interval_s > 0.0 && o.share > 0.0 && o.share < 1.0, "defaults: an interval and a share");
    o.interval_s = 0.0;
    o.share = 0.5;
    rig r;
    setup(&r, &o);
    ct_error err;
    cr_assert(dsync_due(r.sync, ct_now()), "a new display's first update goes at once");
    insert(&r, 2000, 31);
    double t0 = ct_now();
    cr_assert_eq(dsync_update(r.sync, r.ds, r.tex, t0, ct_now_us(), &err), 1, "%s", err.msg);
    double t1 = ct_now();
    /* the first update's cost is its encoding's CPU time, at most t1 - t0 */
    cr_assert_not(dsync_due(r.sync, t0), "due at its own start");
    cr_assert(dsync_due(r.sync, t0 + (t1 - t0) / o.share + 1e-9), "not due after the bound");
    /* The socket's work counts with the next update. */
    double io0 = dsrv_io_seconds(r.ds);
    pump(&r, true, 20);
    insert(&r, 5, 32);   /* a small update: most of its cost is the socket's */
    double io1 = dsrv_io_seconds(r.ds);
    cr_assert_gt(io1, io0, "the display's socket work is timed");
    /* The second update starts past the first one's bound: the pump and the
     * insertion may take less than that (the first encoding is slow under
     * the sanitizers). Its cost is bounded by the wall time around it. */
    double a = ct_now(), t2 = fmax(a, t0 + (t1 - t0) / o.share + 1e-9);
    cr_assert(dsync_due(r.sync, t2));
    cr_assert_eq(dsync_update(r.sync, r.ds, r.tex, t2, ct_now_us(), &err), 1, "%s", err.msg);
    double b = ct_now(), io2 = dsrv_io_seconds(r.ds);
    printf("metric: second update: encoding at most %.0f us, socket %.0f us before it\n", 1e6 * (b - a),
           1e6 * (io1 - io0));
    cr_assert_not(dsync_due(r.sync, t2 + 0.999 * (io1 - io0) / o.share), "the socket's time was not counted");
    cr_assert(dsync_due(r.sync, t2 + (b - a + io2 - io0) / o.share + 1e-9), "not due after the bound");
    /* The smallest share holds the next update a second at most. */
    pump(&r, true, 20);
    dsync_free(r.sync);
    o.share = 1e-9;
    cr_assert_eq(dsync_new(&o, &r.sync, &err), 0, "%s", err.msg);
    uint32_t ntex;
    cr_assert_eq(dsync_send_state(r.sync, r.ds, r.tex, &ntex, &err), 0, "%s", err.msg);
    double t5 = ct_now();
    cr_assert_eq(dsync_update(r.sync, r.ds, r.tex, t5, ct_now_us(), &err), 1, "%s", err.msg);
    cr_assert_not(dsync_due(r.sync, t5 + 0.99));
    cr_assert(dsync_due(r.sync, t5 + 1.0), "held past a second");
    pump(&r, true, 20);
    /* Share 1 and an interval: the interval alone paces (the window allows
     * two updates in flight). */
    dsync_free(r.sync);
    o.share = 1.0;
    o.interval_s = 3600.0;
    cr_assert_eq(dsync_new(&o, &r.sync, &err), 0, "%s", err.msg);
    cr_assert_eq(dsync_send_state(r.sync, r.ds, r.tex, &ntex, &err), 0, "%s", err.msg);
    double t4 = ct_now();
    cr_assert_eq(dsync_update(r.sync, r.ds, r.tex, t4, ct_now_us(), &err), 1, "%s", err.msg);
    cr_assert_not(dsync_due(r.sync, t4 + 3599.0));
    cr_assert(dsync_due(r.sync, t4 + 3600.0));
    teardown(&r);
}

Test(dsync, pacing_out_of_range_is_refused)
{
    const double bad[][2] = {{0.01, 0.0}, {0.01, 1.5}, {0.01, -0.25}, {-1.0, 0.25}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        dsync_options o;
        dsync_options_default(&o, false);
        o.interval_s = bad[i][0];
        o.share = bad[i][1];
        dsync *d = (dsync *)1;
        ct_error err;
        cr_assert_eq(dsync_new(&o, &d, &err), CT_EINVAL, "interval %g share %g", bad[i][0], bad[i][1]);
        cr_assert_null(d);
        cr_assert(strstr(err.msg, "pacing"), "%s", err.msg);
    }
}
