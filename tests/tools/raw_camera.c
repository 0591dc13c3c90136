/* raw_camera.c: a hostile display for the end-to-end tests (built with the
 * unit tests, run by tests/e2e/render_hostile_camera.sh). It connects and
 * authenticates as corrtex-display does (proto/chan.h), sends SETTINGS
 * (lockstep, 100 samples a frame) and then one CAMERA frame written byte by
 * byte with the floats of the command line, which wire_encode would refuse
 * to send, and reports what the master answers:
 *   raw_camera ADDR TOKEN_FILE|- EX EY EZ QW QX QY QZ FOV_RADIANS [WIDTH HEIGHT]
 * (the image 16 x 16 unless WIDTH and HEIGHT say otherwise)
 * prints "ERROR <code>: <text>", "FRAME" (the master traced the camera) or
 * "closed: <why>"; exit status 0 after an ERROR, 1 after a FRAME or a
 * closed connection, 2 on bad usage or when it cannot connect. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto/xport.h"
#include "tests/tools/tool_display.h"

static void put_f32(uint8_t *p, float f)
{
    uint32_t v;
    memcpy(&v, &f, 4);
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}

int main(int argc, char **argv)
{
    if (argc != 11 && argc != 13) {
        fprintf(stderr, "usage: raw_camera ADDR TOKEN_FILE|- EX EY EZ QW QX QY QZ FOV_RADIANS [WIDTH HEIGHT]\n");
        return 2;
    }
    uint32_t width = argc == 13 ? (uint32_t)strtoul(argv[11], NULL, 10) : 16;
    uint32_t height = argc == 13 ? (uint32_t)strtoul(argv[12], NULL, 10) : 16;
    float f[8];
    for (int i = 0; i < 8; i++) f[i] = strtof(argv[3 + i], NULL);
    chan *c = tool_display_connect("raw_camera", argv[1], argv[2], 100);
    if (!c) return 2;
    ct_error err;
    wire_msg m;
    /* A valid CAMERA from the encoder, then its camera bytes replaced: eye at
     * body offset 12, orientation at 24, fov at 40 (docs/protocol.md). */
    m = (wire_msg){.type = WIRE_CAMERA};
    m.u.camera = (wire_camera){.epoch = 1, .width = width, .height = height,
                               .cam = {.eye = v3s(0), .orient = {1, 0, 0, 0}, .fov_y = 1.0f}};
    wire_buf b = {0};
    if (wire_encode(&m, &b, &err)) {
        fprintf(stderr, "raw_camera: %s\n", err.msg);
        return 2;
    }
    for (int i = 0; i < 8; i++) put_f32(b.data + WIRE_HEADER_SIZE + 12 + 4 * i, f[i]);
    if (xport_write_all(chan_conn(c), b.data, b.len, 5000, &err)) {
        fprintf(stderr, "raw_camera: %s\n", err.msg);
        return 2;
    }
    wire_buf_free(&b);
    for (;;) {
        int rc = chan_recv_wait(c, &m, 30000, &err);
        if (rc < 0 || rc == WIRE_NEED_MORE) {
            printf("closed: %s\n", rc < 0 ? err.msg : "no answer within 30 s");
            chan_free(c);
            return 1;
        }
        if (m.type == WIRE_ERROR) {
            printf("ERROR %u: %s\n", m.u.error.code, m.u.error.text);
            chan_free(c);
            return 0;
        }
        if (m.type == WIRE_FRAME) {
            printf("FRAME\n");
            chan_free(c);
            return 1;
        }
    }
}
