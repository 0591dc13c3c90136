/* camera_flood.c: a display that moves its camera faster than any screen
 * refreshes (built with the unit tests; run by tests/e2e/render_camera_rate.sh
 * and scripts/bench-walk --camera-hz). A display sends a CAMERA each frame
 * it draws while the view moves, and a GPU display without vsync draws
 * hundreds of frames a second; every new view costs the master a change of
 * its queue and textures (docs/distributed.md, "Camera changes"). This one
 * connects and authenticates as corrtex-display does (proto/chan.h), runs
 * free (SETTINGS with no samples per frame), sends CAMERA messages at RATE a
 * second for SECONDS, each a little turned from the last (the view swinging
 * by up to 2 degrees a second about the direction from EYE to TARGET; the
 * eye fixed, or with EYE_SWING > 0 swinging sideways by up to that many
 * scene units, as a walker sways; with ALT_WIDTH every other camera is
 * ALT_WIDTH wide, a new image size each time), and takes in what the
 * master sends as a display does, acknowledging every texture update
 * (SYNC) at once:
 *   camera_flood ADDR TOKEN_FILE|- WIDTH HEIGHT RATE SECONDS EX EY EZ TX TY TZ [FOV_DEG [EYE_SWING [ALT_WIDTH]]]
 * prints "cameras N updates U bytes B" and exits 0; 1 when the master
 * closes the connection or answers with ERROR (printed), 2 on bad usage or
 * when it cannot connect. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/camera.h"
#include "common/timer.h"
#include "tests/tools/tool_display.h"

static int fail(const char *what, const ct_error *err)
{
    fprintf(stderr, "camera_flood: %s: %s\n", what, err->msg);
    return 1;
}

static bool number(const char *s, double lo, double hi, double *out)
{
    char *end;
    double v = strtod(s, &end);
    if (end == s || *end || !(v >= lo && v <= hi)) return false;
    *out = v;
    return true;
}

int main(int argc, char **argv)
{
    double v[10] = {0};
    double fov = 50.0, swing = 0.0, alt = 0.0;
    bool ok = argc >= 13 && argc <= 16;
    static const double lo[10] = {1, 1, 0.1, 0.1, -1e6, -1e6, -1e6, -1e6, -1e6, -1e6};
    static const double hi[10] = {16384, 16384, 100000, 3600, 1e6, 1e6, 1e6, 1e6, 1e6, 1e6};
    for (int i = 0; ok && i < 10; i++) ok = number(argv[3 + i], lo[i], hi[i], &v[i]);
    if (ok && argc >= 14) ok = number(argv[13], 1, 170, &fov);
    if (ok && argc >= 15) ok = number(argv[14], 0, 1e6, &swing);
    if (ok && argc == 16) ok = number(argv[15], 1, 16384, &alt);
    if (!ok) {
        fprintf(stderr, "usage: camera_flood ADDR TOKEN_FILE|- WIDTH HEIGHT RATE SECONDS EX EY EZ TX TY TZ [FOV_DEG "
                        "[EYE_SWING [ALT_WIDTH]]]\n");
        return 2;
    }
    chan *c = tool_display_connect("camera_flood", argv[1], argv[2], 0);
    if (!c) return 2;
    ct_error err;
    wire_msg m;

    vec3 eye = v3((float)v[4], (float)v[5], (float)v[6]), target = v3((float)v[7], (float)v[8], (float)v[9]);
    vec3 d = v3_sub(target, eye);
    float dist = v3_len(d), yaw0 = atan2f(d.x, -d.z), pitch = asinf(d.y / (dist > 0 ? dist : 1.0f));
    double t0 = ct_now(), period = 1.0 / v[2], next = t0;
    uint64_t cameras = 0, updates = 0, bytes = 0;
    uint32_t epoch = 0;
    while (ct_now() - t0 < v[3]) {
        double now = ct_now();
        if (now >= next) {
            /* a swing of +-2 degrees a second: every camera differs; the
             * eye sideways (perpendicular to the view, level) a quarter
             * turn out of phase */
            float ph = (float)(6.2832 * (now - t0));
            float yaw = yaw0 + 0.0349f * sinf(ph);
            vec3 dir = v3(sinf(yaw) * cosf(pitch), sinf(pitch), -cosf(yaw) * cosf(pitch));
            vec3 at = v3_add(eye, v3_scale(v3(cosf(yaw0), 0.0f, sinf(yaw0)), (float)swing * cosf(ph)));
            m = (wire_msg){.type = WIRE_CAMERA};
            epoch++;
            uint32_t w = alt > 0 && (epoch & 1) ? (uint32_t)alt : (uint32_t)v[0];
            m.u.camera = (wire_camera){.epoch = epoch, .width = w, .height = (uint32_t)v[1],
                                       .cam = cam_look_at(at, v3_add(at, dir), v3(0, 1, 0), (float)fov)};
            int q = chan_send(c, &m, &err);
            if (q < 0) return fail("camera", &err);
            if (q == 0) cameras++;   /* else the queue is full: the master is not reading */
            if (chan_pump(c, &err)) return fail("sending", &err);
            next += period;
            if (next < now) next = now;   /* behind: no burst to catch up */
        }
        /* take in what arrived until the next camera is due */
        int wait_ms = (int)((next - ct_now()) * 1000.0);
        int rc = chan_recv_wait(c, &m, wait_ms < 0 ? 0 : wait_ms, &err);
        if (rc < 0) {
            printf("closed: %s\n", err.msg);
            chan_free(c);
            return 1;
        }
        for (; rc == WIRE_OK; rc = chan_recv(c, &m, &err)) {
            if (m.type == WIRE_ERROR) {
                printf("ERROR %u: %s\n", m.u.error.code, m.u.error.text);
                chan_free(c);
                return 1;
            }
            if (m.type == WIRE_TEX_PATCH) bytes += (uint64_t)m.u.tex_patch.w * m.u.tex_patch.h * 6u;
            if (m.type == WIRE_SYNC) {
                updates++;
                wire_msg a = {.type = WIRE_ACK};
                a.u.ack.seq = m.u.sync.seq;
                if (chan_send(c, &a, &err) < 0 || chan_pump(c, &err)) return fail("ack", &err);
            }
        }
        if (rc < 0) {
            printf("closed: %s\n", err.msg);
            chan_free(c);
            return 1;
        }
    }
    printf("cameras %llu updates %llu bytes %llu\n", (unsigned long long)cameras, (unsigned long long)updates,
           (unsigned long long)bytes);
    chan_free(c);
    return 0;
}
