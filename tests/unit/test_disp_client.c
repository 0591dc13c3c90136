/* The display's socket client against a master peer speaking the real
 * protocol over a UNIX socket (a child process using proto/'s channel): the
 * scene, texture allocation / projection / patches and FRAME arrive through
 * the connection thread and the inbox and render exactly like the same
 * events applied directly; lockstep frames; a lost connection and an
 * orderly BYE are reported as such; a master that stalls or trickles a
 * message, or repeats a FRAME number, is given up with the reason. */
#include <criterion/criterion.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/timer.h"
#include "display/disp_client.h"
#include "display/disp_inbox.h"
#include "proto/chan.h"
#include "proto/wire.h"
#include "tests/support/disp_fixture.h"
#include "tests/support/disp_master.h"

#define W 64
#define H 48

/* Renders the session's state (display bytes). */
static void render(disp_session *s, uint8_t *out)
{
    ct_error err;
    cr_assert_eq(fx_render_session(s, W, H, out, &err), 0, "%s", err.msg);
}

/* The same state applied directly. */
static void render_direct(uint8_t *out)
{
    ct_error err;
    disp_session *s = NULL;
    cr_assert_eq(disp_session_new(&s, &err), 0);
    ct_radmesh mesh;
    fx_box_nodes nd;
    cr_assert_eq(fx_box_mesh(4, &mesh, &nd, &err), 0);
    cr_assert_eq(disp_session_scene(s, &mesh, &err), 0, "%s", err.msg);
    mat4 p = fxm_wall_proj();
    cr_assert_eq(disp_session_tex_alloc(s, 5, nd.back, 8, 6, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    cr_assert_eq(disp_session_tex_projection(s, 5, &p, &err), 0);
    cr_assert_eq(disp_session_tex_patch_float(s, 5, 0, 0, 8, 6, fxm_tex_rgb(), &err), 0);
    render(s, out);
    rmesh_free(&mesh);
    disp_session_free(s);
}

/* Takes what the connection thread received, up to ms milliseconds, until
 * done() or the connection ends; the connection's status. */
static int pump(disp_client *c, disp_inbox *in, disp_session *s, int ms, bool (*done)(disp_inbox *), ct_error *err)
{
    int rc = 0;
    for (int i = 0; i < ms / 5; i++) {
        disp_inbox_took took;
        cr_assert_eq(disp_inbox_apply(in, s, &took, err), 0, "%s", err->msg);
        if (done && done(in)) {
            /* what arrived between the apply and the look (the FRAME's
             * counts) goes into the session too */
            cr_assert_eq(disp_inbox_apply(in, s, &took, err), 0, "%s", err->msg);
            break;
        }
        if ((rc = disp_client_status(c, err))) {
            cr_assert_eq(disp_inbox_apply(in, s, &took, err), 0, "%s", err->msg);
            break;
        }
        usleep(5000);
    }
    return rc;
}

static bool frame_ready(disp_inbox *in) { return disp_inbox_frame_ready(in, NULL); }

static disp_inbox *new_inbox(void)
{
    ct_error err;
    disp_inbox *in = NULL;
    cr_assert_eq(disp_inbox_new(DISP_TEX_MAX_SIZE, &in, &err), 0);
    return in;
}

static void run_display(fxm_peer *p, uint32_t k, int expect_end_rc, bool expect_ended,
                        const char *token_file)
{
    ct_error err;
    gl_backend *b = NULL;
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, W, H, NULL, false, &b, &err), 0, "%s", err.msg);
    disp_session *s = NULL;
    cr_assert_eq(disp_session_new(&s, &err), 0);
    disp_scene_cache *cache = NULL;
    cr_assert_eq(disp_scene_cache_new(NULL, 0, &cache, &err), 0);
    disp_inbox *in = new_inbox();
    disp_client *c = NULL;
    disp_client_opts o = {p->addr, token_file, k, 5000, 0};
    cr_assert_eq(disp_client_connect(&o, cache, in, &c, &err), 0, "%s", err.msg);
    ct_camera cam = fx_box_camera();
    cr_assert_eq(disp_client_send_camera(c, &cam, W, H, &err), 0, "%s", err.msg);
    cr_assert_eq(disp_client_epoch(c), 1u);
    /* Nothing is taken before the FRAME is in: the two patches of one tile
     * row then go up as one upload (taken between them, the tile went up
     * twice, under load now and then). */
    for (int i = 0; i < 1000 && !disp_inbox_get_state(in).frame_seen && !disp_client_status(c, &err); i++)
        usleep(5000);
    int rc = pump(c, in, s, 5000, frame_ready, &err);
    uint64_t frame = 99;
    cr_assert(disp_inbox_frame_ready(in, &frame), "no FRAME (rc %d: %s)", rc, err.msg);
    cr_expect_eq(frame, 0u);
    disp_inbox_take_frame(in);
    cr_expect_not(disp_inbox_frame_ready(in, NULL), "a frame is taken once");
    cr_expect(disp_inbox_get_state(in).have_scene);
    disp_counters cnt = disp_session_counters(s);
    cr_expect_eq(cnt.samples, 123u);
    cr_expect_eq(cnt.texels, 48u, "texels uploaded %llu", (unsigned long long)cnt.texels);
    cr_expect_eq(cnt.patches, 1u, "two patches of one tile row are one upload (uploads %llu)",
                 (unsigned long long)cnt.patches);
    cr_expect_gt(cnt.bytes, 1000u);
    cr_expect_eq(disp_textures_count(disp_session_textures(s)), 1u);
    uint8_t got[W * H * 3], want[W * H * 3];
    render(s, got);
    render_direct(want);
    int dmax = 0;
    for (size_t i = 0; i < sizeof got; i++) {
        int d = abs((int)got[i] - (int)want[i]);
        if (d > dmax) dmax = d;
    }
    printf("metric: image from the socket vs direct events: max %d/255\n", dmax);
    cr_expect_eq(dmax, 0);
    /* What happens next: the master closes, says BYE, or stays. */
    rc = expect_end_rc ? pump(c, in, s, 2500, NULL, &err) : disp_client_status(c, &err);
    cr_expect_eq(rc, expect_end_rc, "end: rc %d (%s)", rc, err.msg);
    if (expect_end_rc) printf("end of session reported as: %s\n", err.msg);
    cr_expect_eq(disp_client_ended(c), expect_ended);
    disp_client_close(c);
    disp_inbox_release_gl(in);
    disp_inbox_free(in);
    disp_scene_cache_free(cache);
    disp_session_free(s);
    gl_backend_close(b);
}

Test(disp_client, events_render_like_direct_calls_then_lost_connection)
{
        fxm_peer p = {0};
    cr_assert_eq(fxm_start(&p, FXM_END_CLOSE, 0, W, H), 0, "%s", p.msg);
    run_display(&p, 0, CT_EIO, false, NULL);
    cr_expect_eq(fxm_stop(&p), 0, "master child failed");
}

Test(disp_client, lockstep_settings_and_bye)
{
        fxm_peer p = {0};
    cr_assert_eq(fxm_start(&p, FXM_END_BYE, 500, W, H), 0, "%s", p.msg);
    run_display(&p, 500, CT_EIO, true, NULL);
    cr_expect_eq(fxm_stop(&p), 0, "master child failed");
}

Test(disp_client, display_says_bye)
{
        fxm_peer p = {0};
    cr_assert_eq(fxm_start(&p, FXM_END_STAY, 0, W, H), 0, "%s", p.msg);
    run_display(&p, 0, 0, false, NULL);
    cr_expect_eq(fxm_stop(&p), 0, "master child failed (did it get BYE?)");
}

Test(disp_client, no_master_is_an_error)
{
    ct_error err;
    disp_client *c = NULL;
    disp_client_opts o = {"unix:/nonexistent-dir/sock", NULL, 0, 1000, 0};
    disp_inbox *in = new_inbox();
    int rc = disp_client_connect(&o, NULL, in, &c, &err);
    disp_inbox_free(in);
    cr_expect_lt(rc, 0);
    cr_expect(strstr(err.msg, "nonexistent-dir") != NULL, "message: %s", err.msg);
    printf("no master: %s\n", err.msg);
}

static const char *const TOKEN = "a-test-token-of-sufficient-length";

static void write_token(char *path, size_t cap, const char *text)
{
    snprintf(path, cap, "/tmp/ctdisp-token-XXXXXX");
    int fd = mkstemp(path);
    cr_assert_geq(fd, 0);
    cr_assert_eq(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
}

Test(disp_client, tcp_with_token)
{
    fxm_peer p = {0};
    p.token = TOKEN;
    cr_assert_eq(fxm_start(&p, FXM_END_CLOSE, 0, W, H), 0, "%s", p.msg);
    char tf[64];
    write_token(tf, sizeof tf, TOKEN);
    printf("master at %s\n", p.addr);
    run_display(&p, 0, CT_EIO, false, tf);
    cr_expect_eq(fxm_stop(&p), 0, "master child failed");
    unlink(tf);
}

Test(disp_client, tcp_with_a_wrong_token_fails)
{
    fxm_peer p = {0};
    p.token = TOKEN;
    cr_assert_eq(fxm_start(&p, FXM_END_CLOSE, 0, W, H), 0, "%s", p.msg);
    char tf[64];
    write_token(tf, sizeof tf, "another-token-of-sufficient-length");
    ct_error err;
    disp_client *c = NULL;
    disp_client_opts o = {p.addr, tf, 0, 5000, 0};
    disp_inbox *in = new_inbox();
    int rc = disp_client_connect(&o, NULL, in, &c, &err);
    disp_inbox_free(in);
    printf("wrong token: %s\n", err.msg);
    cr_expect_lt(rc, 0);
    cr_expect_null(c);
    cr_expect_neq(fxm_stop(&p), 0, "the master must refuse the display");
    unlink(tf);
}

/* Runs one session against a master that stays until BYE; returns the bytes received. */
static uint64_t session_bytes(disp_scene_cache *cache)
{
    fxm_peer p = {0};
    cr_assert_eq(fxm_start(&p, FXM_END_STAY, 0, W, H), 0, "%s", p.msg);
    ct_error err;
    disp_session *s = NULL;
    cr_assert_eq(disp_session_new(&s, &err), 0);
    disp_inbox *in = new_inbox();
    disp_client *c = NULL;
    disp_client_opts o = {p.addr, NULL, 0, 5000, 0};
    cr_assert_eq(disp_client_connect(&o, cache, in, &c, &err), 0, "%s", err.msg);
    ct_camera cam = fx_box_camera();
    cr_assert_eq(disp_client_send_camera(c, &cam, W, H, &err), 0);
    cr_assert_eq(pump(c, in, s, 5000, frame_ready, &err), 0, "%s", err.msg);
    cr_assert(disp_inbox_get_state(in).have_scene);
    cr_expect_eq(disp_textures_count(disp_session_textures(s)), 1u);
    uint8_t img[W * H * 3], want[W * H * 3];
    render(s, img);
    render_direct(want);
    cr_expect_eq(memcmp(img, want, sizeof img), 0, "the cached scene renders the same");
    uint64_t bytes = disp_session_counters(s).bytes;
    disp_client_close(c);
    disp_inbox_release_gl(in);
    disp_inbox_free(in);
    disp_session_free(s);
    cr_expect_eq(fxm_stop(&p), 0);
    return bytes;
}

Test(disp_client, scene_cache_on_disk)
{
    ct_error err;
    gl_backend *b = NULL;
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, W, H, NULL, false, &b, &err), 0, "%s", err.msg);
    char dir[64];
    snprintf(dir, sizeof dir, "/tmp/ctdisp-cache-XXXXXX");
    cr_assert(mkdtemp(dir));
    disp_scene_cache *cache = NULL;
    cr_assert_eq(disp_scene_cache_new(dir, 0, &cache, &err), 0);
    uint64_t first = session_bytes(cache);
    disp_scene_cache_free(cache);
    /* A new display process: the cache comes from the directory. */
    cr_assert_eq(disp_scene_cache_new(dir, 0, &cache, &err), 0);
    uint64_t second = session_bytes(cache);
    disp_scene_cache_free(cache);
    printf("metric: bytes received: %llu with the scene, %llu with it cached\n",
           (unsigned long long)first, (unsigned long long)second);
    cr_expect_lt(second + 1000, first, "the cached scene was sent again");
    /* A corrupted cache file is ignored (the scene is sent again). */
    char cmd[256];
    snprintf(cmd, sizeof cmd, "for f in %s/*.ctscene; do printf 'x' >> \"$f\"; done", dir);
    cr_assert_eq(system(cmd), 0);
    cr_assert_eq(disp_scene_cache_new(dir, 0, &cache, &err), 0);
    uint64_t third = session_bytes(cache);
    disp_scene_cache_free(cache);
    cr_expect_gt(third, second + 1000, "a corrupt cache must not be announced");
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    cr_expect_eq(system(cmd), 0);
    gl_backend_close(b);
}

/* A GL context, a master child ending as asked, a session and a connected
 * free-running client that has sent the box camera. */
typedef struct rig {
    gl_backend *b;
    fxm_peer p;
    disp_session *s;
    disp_inbox *in;
    disp_client *c;
} rig;

static void rig_open(rig *r, fxm_end end)
{
    ct_error err;
    memset(r, 0, sizeof *r);
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, W, H, NULL, false, &r->b, &err), 0, "%s", err.msg);
    cr_assert_eq(fxm_start(&r->p, end, 0, W, H), 0, "%s", r->p.msg);
    cr_assert_eq(disp_session_new(&r->s, &err), 0);
    r->in = new_inbox();
    disp_client_opts o = {r->p.addr, NULL, 0, 5000, 0};
    cr_assert_eq(disp_client_connect(&o, NULL, r->in, &r->c, &err), 0, "%s", err.msg);
    ct_camera cam = fx_box_camera();
    cr_assert_eq(disp_client_send_camera(r->c, &cam, W, H, &err), 0);
}

/* Closes everything; the master child's exit status. */
static int rig_close(rig *r)
{
    disp_client_close(r->c);
    disp_inbox_release_gl(r->in);
    disp_inbox_free(r->in);
    int st = fxm_stop(&r->p);
    disp_session_free(r->s);
    gl_backend_close(r->b);
    return st;
}

/* A display against a master child ending as `end`, sending one camera:
 * how its connection ended (its status and message, printed as WHAT), or
 * 0 when it had not within 5 s. */
static int ended_by(fxm_end end, int silent_ms, const char *what, ct_error *err)
{
    ct_error_clear(err);
    fxm_peer p;
    memset(&p, 0, sizeof p);
    cr_assert_eq(fxm_start(&p, end, 0, W, H), 0, "%s", p.msg);
    disp_inbox *in = new_inbox();
    disp_client *c = NULL;
    disp_client_opts o = {p.addr, NULL, 0, 5000, silent_ms};
    cr_assert_eq(disp_client_connect(&o, NULL, in, &c, err), 0, "%s", err->msg);
    ct_camera cam = fx_box_camera();
    cr_assert_eq(disp_client_send_camera(c, &cam, W, H, err), 0);
    double t0 = ct_now();
    int rc = 0;
    while (!(rc = disp_client_status(c, err)) && ct_now() - t0 < 5.0) usleep(10000);
    printf("%s: %s after %.1f s\n", what, err->msg, ct_now() - t0);
    disp_client_close(c);
    disp_inbox_free(in);
    cr_expect_eq(fxm_stop(&p), 0);
    return rc;
}

/* A master that stops in the middle of a message, PONGs and all: the
 * display gives up after silent_ms with a line that says so (a lockstep
 * display used to wait for good). */
Test(disp_client, a_master_that_stalls_mid_message_is_given_up)
{
    ct_error err;
    cr_expect_eq(ended_by(FXM_END_STALL, 1000, "stalled master", &err), CT_EIO);
    cr_expect(strstr(err.msg, "the master completed no message for 1.0 s, not even a PONG") != NULL, "%s",
              err.msg);
}

/* A master that trickles a message, a byte every 50 ms: bytes arrive, no
 * message completes, and the display gives up as for silence (bytes used to
 * count, and a byte a second kept it waiting for good). */
Test(disp_client, a_master_that_trickles_a_message_is_given_up)
{
    ct_error err;
    cr_expect_eq(ended_by(FXM_END_TRICKLE, 1000, "trickling master", &err), CT_EIO);
    cr_expect(strstr(err.msg, "the master completed no message for 1.0 s, not even a PONG") != NULL, "%s",
              err.msg);
}

/* A master that queues minutes of work (1,000 resizes, to 4096x4096 and
 * back, 20 bytes each): the display, asked to stop, stops within about one
 * resize (its connection thread used to work through every message it had
 * read before it looked; a resize takes up to a second under the
 * sanitizers, hence the bound of 10 s against minutes). */
Test(disp_client, a_display_asked_to_stop_does_not_finish_a_backlog_first, .timeout = 30)
{
    fxm_peer p;
    memset(&p, 0, sizeof p);
    cr_assert_eq(fxm_start(&p, FXM_END_RESIZES, 0, W, H), 0, "%s", p.msg);
    disp_inbox *in = new_inbox();
    disp_client *c = NULL;
    ct_error err;
    disp_client_opts o = {p.addr, NULL, 0, 5000, 0};
    cr_assert_eq(disp_client_connect(&o, NULL, in, &c, &err), 0, "%s", err.msg);
    ct_camera cam = fx_box_camera();
    cr_assert_eq(disp_client_send_camera(c, &cam, W, H, &err), 0);
    usleep(1500000);   /* the resizes arrive and the first ones are computed */
    cr_assert_eq(disp_client_status(c, &err), 0, "the connection ended: %s", err.msg);
    double t0 = ct_now();
    disp_client_close(c);
    double took = ct_now() - t0;
    printf("closing with a backlog of resizes took %.2f s\n", took);
    cr_expect_lt(took, 10.0, "closing took %.2f s", took);
    disp_inbox_free(in);
    cr_expect_eq(fxm_stop(&p), 0);
}

/* A FRAME number that does not grow would never make a frame ready: the
 * display names the problem and ends (it used to wait for good). */
Test(disp_client, a_frame_number_that_does_not_grow_ends_the_connection)
{
    ct_error err;
    cr_expect_eq(ended_by(FXM_END_FRAME_AGAIN, 0, "frame again", &err), CT_EPROTO, "%s", err.msg);
    cr_expect(strstr(err.msg, ": FRAME 5 after FRAME 5: frame numbers must increase") != NULL, "%s", err.msg);
}

/* A master that stops reading and then sends SYNC, ERROR and closes (as
 * corrtex-render does on SIGTERM): the display's PINGs and its ACK fail
 * before the ERROR is read, and it still reports the master's words (it
 * used to end at the failed send with a bare lost connection). */
Test(disp_client, the_masters_last_words_are_read_after_a_failed_send)
{
    ct_error err;
    cr_expect_eq(ended_by(FXM_END_DEAF, 0, "deaf master", &err), CT_EPROTO, "%s", err.msg);
    cr_expect(strstr(err.msg, "master reports an error: " FXM_DEAF_TEXT) != NULL, "%s", err.msg);
}

Test(disp_client, a_message_that_does_not_fit_is_answered_with_error)
{
    ct_error err;
    rig r;
    rig_open(&r, FXM_END_BAD);
    int rc = pump(r.c, r.in, r.s, 5000, NULL, &err);
    printf("bad patch: %s\n", err.msg);
    cr_expect_eq(rc, CT_EPROTO);
    cr_expect(strstr(err.msg, "unknown texture 77") != NULL, "%s", err.msg);
    cr_expect_eq(rig_close(&r), 0, "the master did not get a PROTOCOL error naming texture 77");
}

/* Lockstep rounds: each frame asked for arrives as soon as its bytes do.
 * The connection thread once left a frame it had read but not decoded in
 * memory until its next ping (up to a second) whenever the last bytes came
 * with the read that sends ACKs. */
Test(disp_client, lockstep_rounds_do_not_wait_for_the_ping)
{
    ct_error err;
    rig r;
    rig_open(&r, FXM_END_ROUNDS);
    disp_client *c = r.c;
    disp_inbox *in = r.in;
    disp_session *s = r.s;
    ct_camera cam = fx_box_camera();
    cr_assert_eq(pump(c, in, s, 5000, frame_ready, &err), 0, "%s", err.msg);
    disp_inbox_take_frame(in);
    usleep(500000);   /* past the quick pings of the first 400 ms: the next is a second away */
    double worst = 0, sum = 0;
    for (int k = 1; k <= FXM_ROUNDS; k++) {
        double t0 = ct_now();
        cr_assert_eq(disp_client_send_camera(c, &cam, W, H, &err), 0);
        /* Poll finely: the round trip is what is measured, not our sleep. */
        disp_inbox_took took;
        uint64_t frame = 0;
        for (;;) {
            cr_assert_eq(disp_inbox_apply(in, s, &took, &err), 0, "%s", err.msg);
            if (disp_inbox_frame_ready(in, &frame) || ct_now() - t0 > 5.0) break;
            cr_assert_eq(disp_client_status(c, &err), 0, "%s", err.msg);
            usleep(500);
        }
        cr_assert(disp_inbox_frame_ready(in, &frame), "round %d: no frame", k);
        cr_expect_eq(frame, (uint64_t)k);
        double dt = ct_now() - t0;
        sum += dt;
        if (dt > worst) worst = dt;
        disp_inbox_take_frame(in);
    }
    printf("metric: lockstep round trip with 6 MiB in 1024 patches: mean %.1f ms, worst %.1f ms (%d rounds)\n",
           1000 * sum / FXM_ROUNDS, 1000 * worst, FXM_ROUNDS);
    /* A ping period is a second; a healthy round is milliseconds even
     * under the sanitizers. */
    cr_expect_lt(worst, 0.5, "a frame waited %.0f ms after its bytes were read", 1000 * worst);
    cr_expect_eq(rig_close(&r), 0, "master child failed");
}

/* Free running, cameras drawn faster than they can be sent replace the
 * unsent one: no error however many, and the newest one arrives. */
Test(disp_client, free_running_cameras_never_pile_up)
{
    ct_error err;
    fxm_peer p = {0};
    cr_assert_eq(fxm_start(&p, FXM_END_CAMERAS, 0, W, H), 0, "%s", p.msg);
    disp_inbox *in = new_inbox();
    disp_client *c = NULL;
    disp_client_opts o = {p.addr, NULL, 0, 5000, 0};
    cr_assert_eq(disp_client_connect(&o, NULL, in, &c, &err), 0, "%s", err.msg);
    ct_camera cam = fx_box_camera();
    for (int i = 0; i < 5000; i++) {
        cam.eye.x = i == 4999 ? FXM_LAST_X : (float)i * 1e-4f;
        cr_assert_eq(disp_client_send_camera(c, &cam, W, H, &err), 0, "camera %d: %s", i, err.msg);
    }
    cr_expect_eq(disp_client_epoch(c), 5000u);
    usleep(200000);
    cr_expect_eq(disp_client_status(c, &err), 0, "%s", err.msg);
    disp_client_close(c);   /* BYE */
    disp_inbox_free(in);
    int st = fxm_stop(&p);
    cr_expect_eq(st, 0, "the master did not get the newest camera last (or epochs went back): %d", st);
}
