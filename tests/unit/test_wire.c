/* (Over 600 lines: the tables of broken byte strings of every message.)
 * test_wire.c: the display-socket messages, the incremental decoder, the
 * SCENE payload, the handshake/HMAC state machine, half floats, the MPI
 * layouts and token files: round trips (encode -> decode -> encode gives the
 * same bytes) and tables of broken byte strings with the exact error each
 * must produce. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "proto/auth.h"
#include "proto/wire.h"
#include "proto/wire_io.h"
#include "proto/wire_mpi.h"
#include "tests/support/proto_fixtures.h"

/* --- round trips ----------------------------------------------------------- */

static void encode_ok(const wire_msg *m, wire_buf *b)
{
    ct_error err = {{0}};
    int rc = wire_encode(m, b, &err);
    cr_assert_eq(rc, 0, "encode %s: %s", wire_type_name(m->type), err.msg);
}

Test(wire, round_trip_every_message)
{
    wire_msg msgs[FX_NMSG];
    size_t n = fx_messages(msgs);
    bool seen[WIRE_TYPE_COUNT] = {false};
    for (size_t i = 0; i < n; i++) {
        wire_buf a = {0}, b = {0};
        wire_scratch s = {0};
        encode_ok(&msgs[i], &a);
        wire_msg d;
        ct_error err = {{0}};
        int rc = wire_decode(a.data, a.len, "peer", &d, &s, &err);
        cr_assert_eq(rc, 0, "decode %s: %s", wire_type_name(msgs[i].type), err.msg);
        cr_assert_eq(d.type, msgs[i].type);
        encode_ok(&d, &b);
        cr_assert_eq(a.len, b.len, "%s: %zu vs %zu bytes", wire_type_name(d.type), a.len, b.len);
        cr_assert(memcmp(a.data, b.data, a.len) == 0, "%s: re-encoded bytes differ", wire_type_name(d.type));
        /* Header fields as specified. */
        cr_assert_eq(wio_get_u16(a.data), msgs[i].type);
        cr_assert_eq(wio_get_u16(a.data + 2), 0);
        cr_assert_eq(wio_get_u32(a.data + 4), a.len - WIRE_HEADER_SIZE);
        seen[d.type] = true;
        wire_buf_free(&a);
        wire_buf_free(&b);
        wire_scratch_free(&s);
    }
    for (unsigned t = 1; t < WIRE_TYPE_COUNT; t++) cr_assert(seen[t], "no round trip for %s", wire_type_name(t));
}

Test(wire, decoded_fields_match)
{
    wire_msg msgs[FX_NMSG];
    size_t n = fx_messages(msgs);
    for (size_t i = 0; i < n; i++) {
        wire_buf a = {0};
        wire_scratch s = {0};
        encode_ok(&msgs[i], &a);
        wire_msg d;
        cr_assert_eq(wire_decode(a.data, a.len, "peer", &d, &s, NULL), 0);
        const wire_msg *m = &msgs[i];
        switch (m->type) {
        case WIRE_TEX_PATCH: {
            const wire_tex_patch *p = &m->u.tex_patch, *q = &d.u.tex_patch;
            cr_assert(p->tex == q->tex && p->x == q->x && p->y == q->y && p->w == q->w && p->h == q->h);
            cr_assert(memcmp(p->texels, q->texels, (size_t)p->w * p->h * 6) == 0, "patch texels differ");
            break;
        }
        case WIRE_SCENE_CHUNK:
            cr_assert_eq(d.u.scene_chunk.len, m->u.scene_chunk.len);
            cr_assert(memcmp(d.u.scene_chunk.data, m->u.scene_chunk.data, m->u.scene_chunk.len) == 0);
            break;
        case WIRE_CAMERA:
            cr_assert(memcmp(&d.u.camera.cam, &m->u.camera.cam, sizeof(ct_camera)) == 0);
            cr_assert_eq(d.u.camera.epoch, 17);
            cr_assert_eq(d.u.camera.width, 640);
            break;
        case WIRE_TEX_PROJECTION:
            cr_assert(memcmp(&d.u.tex_projection.world_to_tex, &m->u.tex_projection.world_to_tex, sizeof(mat4)) == 0);
            break;
        case WIRE_STATS:
            cr_assert_eq(d.u.stats.samples_per_s, m->u.stats.samples_per_s);
            cr_assert_eq(d.u.stats.texel_bytes, m->u.stats.texel_bytes);
            cr_assert_eq(d.u.stats.t_texture, m->u.stats.t_texture);
            break;
        case WIRE_ERROR: cr_assert_str_eq(d.u.error.text, m->u.error.text); break;
        case WIRE_FRAME: cr_assert_eq(d.u.frame.frame, 123456789012ull); break;
        case WIRE_SAMPLES:
            cr_assert_eq(d.u.samples.epoch, m->u.samples.epoch);
            cr_assert_eq(d.u.samples.count, m->u.samples.count);
            cr_assert_eq(d.u.samples.dropped, m->u.samples.dropped);
            cr_assert(memcmp(d.u.samples.xyz, m->u.samples.xyz, 12 * (size_t)m->u.samples.count) == 0,
                      "sample points differ");
            break;
        default: break;
        }
        wire_buf_free(&a);
        wire_scratch_free(&s);
    }
}

Test(wire, explicit_little_endian_layout)
{
    /* A CAMERA body byte by byte as docs/protocol.md specifies it. */
    wire_msg m;
    memset(&m, 0, sizeof m);
    m.type = WIRE_CAMERA;
    m.u.camera.epoch = 0x01020304;
    m.u.camera.width = 640;
    m.u.camera.height = 480;
    m.u.camera.cam.eye = v3(1.0f, -2.0f, 0.5f);
    m.u.camera.cam.orient = (quat){1, 0, 0, 0};
    m.u.camera.cam.fov_y = 1.0f;
    wire_buf b = {0};
    encode_ok(&m, &b);
    static const uint8_t want[] = {
        6, 0, 0, 0, 44, 0, 0, 0,                         /* header: CAMERA, flags 0, 44 bytes */
        4, 3, 2, 1, 0x80, 2, 0, 0, 0xe0, 1, 0, 0,        /* epoch, 640, 480 */
        0, 0, 0x80, 0x3f, 0, 0, 0, 0xc0, 0, 0, 0, 0x3f,  /* eye 1, -2, 0.5 */
        0, 0, 0x80, 0x3f, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, /* orient w x y z */
        0, 0, 0x80, 0x3f,                                /* fov_y */
    };
    cr_assert_eq(b.len, sizeof want);
    cr_assert(memcmp(b.data, want, sizeof want) == 0, "CAMERA bytes differ from the specification");
    wire_buf_free(&b);
}

Test(wire, samples_layout)
{
    /* A SAMPLES body with two points, byte by byte as docs/protocol.md says. */
    const float pts[6] = {1.0f, -2.0f, 0.5f, 0.0f, 1.0f, 2.0f};
    wire_msg m;
    memset(&m, 0, sizeof m);
    m.type = WIRE_SAMPLES;
    m.u.samples = (wire_samples){.epoch = 0x01020304, .count = 2, .dropped = 0x0000000500000007ull, .xyz = pts};
    wire_buf b = {0};
    encode_ok(&m, &b);
    static const uint8_t want[] = {
        17, 0, 0, 0, 40, 0, 0, 0,                        /* header: SAMPLES, flags 0, 16 + 2 * 12 bytes */
        4, 3, 2, 1, 2, 0, 0, 0,                          /* epoch, count */
        7, 0, 0, 0, 5, 0, 0, 0,                          /* dropped (u64) */
        0, 0, 0x80, 0x3f, 0, 0, 0, 0xc0, 0, 0, 0, 0x3f,  /* point 0: 1, -2, 0.5 */
        0, 0, 0, 0, 0, 0, 0x80, 0x3f, 0, 0, 0, 0x40,     /* point 1: 0, 1, 2 */
    };
    cr_assert_eq(b.len, sizeof want);
    cr_assert(memcmp(b.data, want, sizeof want) == 0, "SAMPLES bytes differ from the specification");
    cr_assert_eq(wire_max_body(WIRE_SAMPLES), 16 + 12 * (size_t)WIRE_SAMPLES_MAX_POINTS);
    wire_buf_free(&b);
}

Test(wire, invalid_messages_do_not_encode)
{
    wire_msg m;
    wire_buf b = {0};
    ct_error err;
    memset(&m, 0, sizeof m);
    m.type = WIRE_TEX_ALLOC;
    m.u.tex_alloc = (wire_tex_alloc){.tex = 1, .node = 1, .width = 16, .height = 16, .proj = 9};
    cr_assert_eq(wire_encode(&m, &b, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "encode: TEX_ALLOC projection kind 9 unknown");
    m.type = 77;
    cr_assert_eq(wire_encode(&m, &b, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "encode: message type 77 unknown");
    uint16_t t[3] = {0};
    memset(&m, 0, sizeof m);
    m.type = WIRE_TEX_PATCH;
    m.u.tex_patch = (wire_tex_patch){.tex = 1, .x = 0, .y = 0, .w = 2048, .h = 1024, .texels = t};
    cr_assert_eq(wire_encode(&m, &b, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "encode: TEX_PATCH size 2048x1024 out of range");
    static float pts[3 * 4];
    memset(&m, 0, sizeof m);
    m.type = WIRE_SAMPLES;
    m.u.samples = (wire_samples){.count = WIRE_SAMPLES_MAX_POINTS + 1, .xyz = pts};
    cr_assert_eq(wire_encode(&m, &b, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "encode: SAMPLES count 65537 over the limit 65536");
    pts[7] = INFINITY;
    m.u.samples.count = 4;
    cr_assert_eq(wire_encode(&m, &b, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "encode: SAMPLES point 2 has a non-finite coordinate");
    cr_assert_eq(b.len, 0, "a failed encode appended bytes");
    wire_buf_free(&b);
}

Test(wire, error_text_is_sanitised)
{
    wire_msg m;
    wire_make_error(&m, WIRE_ERR_INTERNAL, "line1\nline2\x01\xff end");
    cr_assert_str_eq(m.u.error.text, "line1?line2?? end");
    char longtext[400];
    memset(longtext, 'x', sizeof longtext - 1);
    longtext[sizeof longtext - 1] = '\0';
    wire_make_error(&m, WIRE_ERR_INTERNAL, longtext);
    cr_assert_eq(strlen(m.u.error.text), WIRE_ERROR_TEXT_MAX);
    wire_buf b = {0};
    encode_ok(&m, &b);
    wire_buf_free(&b);
}

/* --- the incremental decoder ------------------------------------------------ */

/* All fixture frames back to back. */
static void stream(wire_buf *b, size_t *nmsg)
{
    wire_msg msgs[FX_NMSG];
    *nmsg = fx_messages(msgs);
    for (size_t i = 0; i < *nmsg; i++) encode_ok(&msgs[i], b);
}

static void decode_in_steps(size_t step)
{
    wire_buf all = {0};
    size_t nmsg;
    stream(&all, &nmsg);
    wire_decoder *d;
    cr_assert_eq(wire_decoder_new("peer", &d, NULL), 0);
    size_t got = 0, off = 0;
    wire_buf again = {0};
    while (off < all.len) {
        size_t n = all.len - off < step ? all.len - off : step;
        cr_assert_eq(wire_decoder_feed(d, all.data + off, n, NULL), 0);
        off += n;
        wire_msg m;
        int rc;
        ct_error err = {{0}};
        while ((rc = wire_decoder_next(d, &m, &err)) == WIRE_OK) {
            encode_ok(&m, &again);
            got++;
        }
        cr_assert_eq(rc, WIRE_NEED_MORE, "step %zu: %s", step, err.msg);
    }
    cr_assert_eq(got, nmsg, "step %zu: %zu of %zu messages", step, got, nmsg);
    cr_assert_eq(wire_decoder_pending(d), 0);
    cr_assert_eq(again.len, all.len);
    cr_assert(memcmp(again.data, all.data, all.len) == 0, "step %zu: re-encoded stream differs", step);
    wire_decoder_free(d);
    wire_buf_free(&all);
    wire_buf_free(&again);
}

Test(decoder, one_byte_at_a_time) { decode_in_steps(1); }
Test(decoder, odd_chunks) { decode_in_steps(7); decode_in_steps(1000); }
Test(decoder, all_at_once) { decode_in_steps(1u << 30); }

Test(decoder, need_more_until_last_byte)
{
    wire_msg msgs[FX_NMSG];
    fx_messages(msgs);
    wire_buf b = {0};
    encode_ok(&msgs[11], &b); /* TEX_PATCH */
    wire_decoder *d;
    wire_decoder_new("peer", &d, NULL);
    wire_msg m;
    for (size_t i = 0; i + 1 < b.len; i++) {
        wire_decoder_feed(d, b.data + i, 1, NULL);
        cr_assert_eq(wire_decoder_next(d, &m, NULL), WIRE_NEED_MORE, "byte %zu", i);
        if (i + 1 >= WIRE_HEADER_SIZE) cr_assert_eq(wire_decoder_frame_size(d), b.len);
    }
    wire_decoder_feed(d, b.data + b.len - 1, 1, NULL);
    cr_assert_eq(wire_decoder_next(d, &m, NULL), WIRE_OK);
    cr_assert_eq(m.type, WIRE_TEX_PATCH);
    cr_assert_eq(wire_decoder_next(d, &m, NULL), WIRE_NEED_MORE);
    wire_decoder_free(d);
    wire_buf_free(&b);
}

Test(decoder, errors_are_sticky_and_early)
{
    wire_decoder *d;
    wire_decoder_new("tcp:10.0.0.2:4000", &d, NULL);
    /* A header announcing 4 GiB fails as soon as the header is complete. */
    uint8_t hdr[8] = {10, 0, 0, 0, 0xff, 0xff, 0xff, 0xff};
    wire_decoder_feed(d, hdr, 8, NULL);
    wire_msg m;
    ct_error err;
    char want[200];
    snprintf(want, sizeof want, "tcp:10.0.0.2:4000: TEX_PATCH body length 4294967295 over the limit %zu",
             wire_max_body(WIRE_TEX_PATCH));
    cr_assert_eq(wire_decoder_next(d, &m, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, want);
    memset(&err, 0, sizeof err);
    cr_assert_eq(wire_decoder_next(d, &m, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, want);
    cr_assert_eq(wire_decoder_feed(d, hdr, 8, &err), CT_EPROTO);
    wire_decoder_free(d);
}

/* --- broken frames ---------------------------------------------------------- */

typedef struct broken {
    const char *name;
    uint8_t bytes[96];
    size_t len;
    int code;
    const char *msg;     /* exact, with "peer" as the peer name; NULL = see dyn */
} broken;

#define H(t, f, l) (uint8_t)(t), (uint8_t)((t) >> 8), (uint8_t)(f), (uint8_t)((f) >> 8), \
    (uint8_t)(l), (uint8_t)((l) >> 8), (uint8_t)((l) >> 16), (uint8_t)((l) >> 24)
#define F32(b0, b1, b2, b3) b0, b1, b2, b3
#define ONE  F32(0, 0, 0x80, 0x3f)
#define U32(v) (uint8_t)(v), (uint8_t)((v) >> 8), (uint8_t)((v) >> 16), (uint8_t)((v) >> 24)
/* A TEX_PATCH header: texture, rectangle, encoding; samples 0, stamp 0. */
#define PH(t, x, y, w, h, e) U32(t), U32(x), U32(y), U32(w), U32(h), U32(e), U32(0), U32(0), U32(0)
#define NAN32 F32(0, 0, 0xc0, 0x7f)

static const broken broken_frames[] = {
    {"unknown type", {H(99, 0, 0)}, 8, CT_EPROTO, "peer: message type 99 unknown"},
    {"type zero", {H(0, 0, 4), 1, 2, 3, 4}, 12, CT_EPROTO, "peer: message type 0 unknown"},
    {"header flags", {H(WIRE_PING, 1, 8), 0, 0, 0, 0, 0, 0, 0, 0}, 16, CT_EPROTO, "peer: PING header flags 0x1 unknown"},
    {"fixed length too short", {H(WIRE_PING, 0, 7), 0, 0, 0, 0, 0, 0, 0}, 15, CT_EPROTO,
     "peer: PING body length 7, expected 8"},
    {"fixed length too long", {H(WIRE_BYE, 0, 5), 0, 0, 0, 0, 0}, 13, CT_EPROTO, "peer: BYE body length 5, expected 4"},
    {"oversized ERROR", {H(WIRE_ERROR, 0, 1000)}, 8, CT_EPROTO, "peer: ERROR body length 1000 over the limit 206"},
    {"truncated body", {H(WIRE_PING, 0, 8), 1, 2, 3, 4}, 12, CT_EPROTO, "peer: PING frame has 4 body bytes, header says 8"},
    {"trailing bytes", {H(WIRE_BYE, 0, 4), 0, 0, 0, 0, 9}, 13, CT_EPROTO, "peer: BYE frame has 5 body bytes, header says 4"},
    {"short header", {6, 0, 0}, 3, CT_EPROTO, "peer: frame of 3 bytes is shorter than a header"},
    {"patch header truncated", {H(WIRE_TEX_PATCH, 0, 10), 1, 0, 0, 0, 2, 0, 0, 0, 3, 0}, 18, CT_EPROTO,
     "peer: TEX_PATCH body of 10 bytes is truncated"},
    {"patch of width 0", {H(WIRE_TEX_PATCH, 0, 37), PH(1, 0, 0, 0, 1, 0), 0}, 45, CT_EPROTO,
     "peer: TEX_PATCH size 0x1 out of range"},
    {"patch outside any texture", {H(WIRE_TEX_PATCH, 0, 37), PH(1, 0x3fff, 0, 2, 1, 0), 0}, 45, CT_EPROTO,
     "peer: TEX_PATCH rectangle at 16383,0 outside any texture"},
    {"patch encoding unknown", {H(WIRE_TEX_PATCH, 0, 42), PH(1, 0, 0, 1, 1, 2), 0, 0, 0, 0, 0, 0}, 50, CT_EPROTO,
     "peer: TEX_PATCH encoding 2 unknown"},
    {"patch garbage LZ4", {H(WIRE_TEX_PATCH, 0, 40), PH(1, 0, 0, 1, 1, 1), 0xff, 0xff, 0xff, 0xff}, 48, CT_EPROTO,
     "peer: TEX_PATCH data does not decompress to 6 bytes"},
    /* LZ4 block "4 literals ABCD" is valid but 4 bytes, not the 6 of a 1x1 patch. */
    {"patch wrong raw size", {H(WIRE_TEX_PATCH, 0, 41), PH(1, 0, 0, 1, 1, 1), 0x40, 'A', 'B', 'C', 'D'}, 49, CT_EPROTO,
     "peer: TEX_PATCH data does not decompress to 6 bytes"},
    {"raw patch too short", {H(WIRE_TEX_PATCH, 0, 40), PH(1, 0, 0, 1, 1, 0), 1, 2, 3, 4}, 48, CT_EPROTO,
     "peer: raw TEX_PATCH of 1x1 texels has 4 data bytes, expected 6"},
    {"SYNC of the wrong size", {H(WIRE_SYNC, 0, 8), 1, 0, 0, 0, 0, 0, 0, 0}, 16, CT_EPROTO,
     "peer: SYNC body length 8, expected 16"},
    {"PONG without its clock", {H(WIRE_PONG, 0, 8), 1, 0, 0, 0, 0, 0, 0, 0}, 16, CT_EPROTO,
     "peer: PONG body length 8, expected 16"},
    {"chunk of length 0", {H(WIRE_SCENE_CHUNK, 0, 9), 0, 0, 0, 0, 0, 0, 0, 0, 0x00}, 17, CT_EPROTO,
     "peer: SCENE_CHUNK length 0 out of range 1..1048576"},
    {"chunk length over the limit", {H(WIRE_SCENE_CHUNK, 0, 9), 0, 0, 0, 0, 1, 0, 0x10, 0, 0x00}, 17, CT_EPROTO,
     "peer: SCENE_CHUNK length 1048577 out of range 1..1048576"},
    {"ERROR text length mismatch", {H(WIRE_ERROR, 0, 9), 1, 0, 0, 0, 5, 0, 'a', 'b', 'c'}, 17, CT_EPROTO,
     "peer: ERROR text length 5 does not match the body (3 bytes left)"},
    {"ERROR with a newline", {H(WIRE_ERROR, 0, 9), 1, 0, 0, 0, 3, 0, 'a', '\n', 'c'}, 17, CT_EPROTO,
     "peer: ERROR text is not printable ASCII of at most 200 bytes"},
    {"ERROR with a NUL", {H(WIRE_ERROR, 0, 9), 1, 0, 0, 0, 3, 0, 'a', 0, 'c'}, 17, CT_EPROTO,
     "peer: ERROR text is not printable ASCII of at most 200 bytes"},
    {"ERROR code unknown", {H(WIRE_ERROR, 0, 7), 99, 0, 0, 0, 1, 0, 'a'}, 15, CT_EPROTO, "peer: ERROR code 99 unknown"},
    {"BYE reason unknown", {H(WIRE_BYE, 0, 4), 7, 0, 0, 0}, 12, CT_EPROTO, "peer: BYE reason 7 unknown"},
    {"TEX_ALLOC projection unknown", {H(WIRE_TEX_ALLOC, 0, 20), 1, 0, 0, 0, 2, 0, 0, 0, 16, 0, 0, 0, 16, 0, 0, 0, 3, 0, 0, 0},
     28, CT_EPROTO, "peer: TEX_ALLOC projection kind 3 unknown"},
    {"TEX_ALLOC of size 0", {H(WIRE_TEX_ALLOC, 0, 20), 1, 0, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 16, 0, 0, 0, 1, 0, 0, 0},
     28, CT_EPROTO, "peer: TEX_ALLOC size 0x16 out of range"},
    {"TEX_RESIZE past the limit", {H(WIRE_TEX_RESIZE, 0, 12), U32(1), U32(16385), U32(16)}, 20, CT_EPROTO,
     "peer: TEX_RESIZE size 16385x16 out of range"},
    {"TEX_RESIZE of height 0", {H(WIRE_TEX_RESIZE, 0, 12), U32(1), U32(16), U32(0)}, 20, CT_EPROTO,
     "peer: TEX_RESIZE size 16x0 out of range"},
    {"TEX_RESIZE too long", {H(WIRE_TEX_RESIZE, 0, 16), U32(1), U32(16), U32(16), U32(0)}, 24, CT_EPROTO,
     "peer: TEX_RESIZE body length 16, expected 12"},
    {"CAMERA NaN", {H(WIRE_CAMERA, 0, 44), 1, 0, 0, 0, 64, 0, 0, 0, 64, 0, 0, 0, NAN32, ONE, ONE, ONE, ONE, ONE, ONE,
                    ONE}, 52, CT_EPROTO, "peer: CAMERA has a non-finite value"},
    {"CAMERA fov", {H(WIRE_CAMERA, 0, 44), 1, 0, 0, 0, 64, 0, 0, 0, 64, 0, 0, 0, ONE, ONE, ONE, ONE, ONE, ONE, ONE,
                    F32(0, 0, 0x80, 0xbf)}, 52, CT_EPROTO,
     "peer: CAMERA field of view -1 out of range [0.0001, 3.14159) radians"},
    /* An eye far outside the scene range made a tracer abort inside Embree. */
    {"CAMERA eye far away", {H(WIRE_CAMERA, 0, 44), 1, 0, 0, 0, 64, 0, 0, 0, 64, 0, 0, 0, ONE, ONE,
                             F32(0x23, 0xc7, 0x0a, 0xdf), ONE, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, ONE}, 52,
     CT_EPROTO, "peer: CAMERA eye coordinate -1e+19 outside +-1e+09"},
    {"CAMERA zero orientation", {H(WIRE_CAMERA, 0, 44), 1, 0, 0, 0, 64, 0, 0, 0, 64, 0, 0, 0, ONE, ONE, ONE,
                                 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, ONE}, 52, CT_EPROTO,
     "peer: CAMERA orientation is not a unit quaternion (norm^2 0)"},
    {"CAMERA image size", {H(WIRE_CAMERA, 0, 44), 1, 0, 0, 0, 0, 0, 0, 0, 64, 0, 0, 0, ONE, ONE, ONE, ONE, ONE, ONE, ONE,
                           ONE}, 52, CT_EPROTO, "peer: CAMERA image size 0x64 out of range"},
    {"SETTINGS flags", {H(WIRE_SETTINGS, 0, 40), 0, 0, 0, 0, 4, 0, 0, 0}, 48, CT_EPROTO, "peer: SETTINGS flags 0x4 unknown"},
    {"FRAME flags", {H(WIRE_FRAME, 0, 24), 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 0}, 32, CT_EPROTO,
     "peer: FRAME flags 0x2 unknown"},
    {"STATS NaN", {H(WIRE_STATS, 0, 56), 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, NAN32}, 64, CT_EPROTO,
     "peer: STATS has a non-finite value"},
    {"SCENE_BEGIN wrong chunk count", {H(WIRE_SCENE_BEGIN, 0, 68), [8 + 40] = 72, [8 + 48] = 1, [8 + 60] = 5}, 76,
     CT_EPROTO, "peer: SCENE_BEGIN announces 5 chunks, expected 1"},
    {"SCENE_BEGIN size not matching counts", {H(WIRE_SCENE_BEGIN, 0, 68), [8 + 40] = 73, [8 + 48] = 1, [8 + 60] = 1},
     76, CT_EPROTO, "peer: SCENE_BEGIN payload size 73 does not match its counts"},
    {"SAMPLES header truncated", {H(WIRE_SAMPLES, 0, 10), 1, 0, 0, 0, 2, 0, 0, 0, 0, 0}, 18, CT_EPROTO,
     "peer: SAMPLES body of 10 bytes is truncated"},
    {"SAMPLES count not matching the body", {H(WIRE_SAMPLES, 0, 28), 1, 0, 0, 0, 2, 0, 0, 0, [8 + 16] = 0}, 36,
     CT_EPROTO, "peer: SAMPLES count 2 does not match the body (12 bytes of points)"},
    {"SAMPLES count over the limit", {H(WIRE_SAMPLES, 0, 16), 0, 0, 0, 0, 1, 0, 1, 0, [8 + 15] = 0}, 24, CT_EPROTO,
     "peer: SAMPLES count 65537 does not match the body (0 bytes of points)"},
    {"SAMPLES point NaN", {H(WIRE_SAMPLES, 0, 40), 1, 0, 0, 0, 2, 0, 0, 0, [8 + 16] = ONE, ONE, ONE, ONE, NAN32, ONE},
     48, CT_EPROTO, "peer: SAMPLES point 1 has a non-finite coordinate"},
    {"oversized SAMPLES", {H(WIRE_SAMPLES, 0, 786449)}, 8, CT_EPROTO,
     "peer: SAMPLES body length 786449 over the limit 786448"},
    {"TEX_PROJECTION infinity", {H(WIRE_TEX_PROJECTION, 0, 72), [8 + 8] = 0, [8 + 10] = 0x80, [8 + 11] = 0x7f}, 80,
     CT_EPROTO, "peer: TEX_PROJECTION has a non-finite value"},
};

Test(broken, frames_give_their_exact_error)
{
    for (size_t i = 0; i < sizeof broken_frames / sizeof broken_frames[0]; i++) {
        const broken *b = &broken_frames[i];
        wire_msg m;
        wire_scratch s = {0};
        ct_error err = {{0}};
        int rc = wire_decode(b->bytes, b->len, "peer", &m, &s, &err);
        cr_expect_eq(rc, b->code, "%s: code %d, expected %d (%s)", b->name, rc, b->code, err.msg);
        cr_expect_str_eq(err.msg, b->msg, "%s", b->name);
        wire_scratch_free(&s);
        /* The incremental decoder gives the same answer (or NEED_MORE for a cut frame). */
        wire_decoder *d;
        wire_decoder_new("peer", &d, NULL);
        wire_decoder_feed(d, b->bytes, b->len, NULL);
        memset(&err, 0, sizeof err);
        rc = wire_decoder_next(d, &m, &err);
        if (strstr(b->name, "truncated body") || strstr(b->name, "short header"))
            cr_expect_eq(rc, WIRE_NEED_MORE, "%s", b->name);
        else if (strstr(b->name, "trailing bytes"))
            cr_expect_eq(rc, WIRE_OK, "%s: the extra byte starts the next frame", b->name);
        else {
            cr_expect_eq(rc, b->code, "%s (incremental)", b->name);
            cr_expect_str_eq(err.msg, b->msg, "%s (incremental)", b->name);
        }
        wire_decoder_free(d);
    }
}

/* --- half floats ------------------------------------------------------------- */

Test(half, known_values)
{
    cr_assert_eq(wire_half_from_float(0.0f), 0x0000);
    cr_assert_eq(wire_half_from_float(-0.0f), 0x8000);
    cr_assert_eq(wire_half_from_float(1.0f), 0x3c00);
    cr_assert_eq(wire_half_from_float(-2.0f), 0xc000);
    cr_assert_eq(wire_half_from_float(65504.0f), 0x7bff);
    cr_assert_eq(wire_half_from_float(65520.0f), 0x7c00); /* rounds to infinity */
    cr_assert_eq(wire_half_from_float(1e9f), 0x7c00);
    cr_assert_eq(wire_half_from_float(0x1p-24f), 0x0001); /* smallest subnormal */
    cr_assert_eq(wire_half_from_float(0x1p-26f), 0x0000);
    cr_assert_eq(wire_half_from_float(0.1f), 0x2e66);
    cr_assert_eq(wire_half_from_float(1.0f + 0x1p-11f), 0x3c00);  /* tie -> even */
    cr_assert_eq(wire_half_from_float(1.0f + 0x1p-10f + 0x1p-11f), 0x3c02);
    cr_assert(isnan(wire_half_to_float(wire_half_from_float(NAN))));
    cr_assert_eq(wire_half_to_float(0x3555), 0.333251953125f);
}

Test(half, every_half_round_trips)
{
    for (uint32_t h = 0; h < 65536; h++) {
        float f = wire_half_to_float((uint16_t)h);
        if (isnan(f)) continue;
        cr_assert_eq(wire_half_from_float(f), h, "half 0x%04x -> %g -> 0x%04x", h, (double)f,
                     wire_half_from_float(f));
    }
}

/* --- SCENE --------------------------------------------------------------------- */

static void send_scene(const ct_radmesh *m, wire_scene_rx *rx, bool cached, int *last_rc)
{
    wire_scene_tx tx;
    ct_error err = {{0}};
    cr_assert_eq(wire_scene_tx_init(&tx, m, &err), 0, "%s", err.msg);
    wire_msg msgs[3];
    wire_scene_tx_begin(&tx, cached, &msgs[0]);
    uint32_t nchunks = msgs[0].u.scene_begin.nchunks;
    wire_buf b = {0};
    wire_scratch s = {0};
    for (uint32_t i = 0; i < nchunks + 2; i++) {
        wire_msg out, in;
        if (i == 0) out = msgs[0];
        else if (i <= nchunks) wire_scene_tx_chunk(&tx, i - 1, &out);
        else wire_scene_tx_end(&tx, &out);
        b.len = 0;
        encode_ok(&out, &b);
        cr_assert_eq(wire_decode(b.data, b.len, "master", &in, &s, &err), 0, "%s", err.msg);
        *last_rc = wire_scene_rx_feed(rx, &in, &err);
        cr_assert_geq(*last_rc, 0, "%s", err.msg);
    }
    wire_buf_free(&b);
    wire_scratch_free(&s);
    wire_scene_tx_free(&tx);
}

static void assert_same_mesh(const ct_radmesh *a, const ct_radmesh *b)
{
    cr_assert_eq(a->nverts, b->nverts);
    cr_assert_eq(a->ntris, b->ntris);
    cr_assert_eq(a->nnodes, b->nnodes);
    cr_assert_eq(a->scene_hash, b->scene_hash);
    cr_assert(memcmp(a->pos, b->pos, a->nverts * sizeof(vec3)) == 0);
    cr_assert(memcmp(a->nrm, b->nrm, a->nverts * sizeof(vec3)) == 0);
    cr_assert(memcmp(a->rad, b->rad, a->nverts * sizeof(vec3)) == 0);
    cr_assert(memcmp(a->rad_direct, b->rad_direct, a->nverts * sizeof(vec3)) == 0);
    cr_assert(memcmp(a->tris, b->tris, a->ntris * 3 * sizeof(uint32_t)) == 0);
    cr_assert(memcmp(a->tri_node, b->tri_node, a->ntris * sizeof(uint32_t)) == 0);
    cr_assert(memcmp(a->tri_mat, b->tri_mat, a->ntris * sizeof(uint32_t)) == 0);
    for (uint32_t i = 0; i < a->nnodes; i++) {
        cr_assert_str_eq(a->nodes[i].name, b->nodes[i].name);
        cr_assert_eq(a->nodes[i].parent, b->nodes[i].parent);
        cr_assert_eq(a->nodes[i].node_end, b->nodes[i].node_end);
        cr_assert_eq(a->nodes[i].material, b->nodes[i].material);
        cr_assert(memcmp(&a->nodes[i].bounds, &b->nodes[i].bounds, sizeof(bounds3)) == 0);
    }
}

Test(scene, small_and_multi_chunk_round_trip)
{
    uint32_t sizes[2] = {4, 40000}; /* the second is 5.4 MB: 6 chunks */
    for (int k = 0; k < 2; k++) {
        ct_radmesh m, r;
        cr_assert_eq(fx_mesh(&m, sizes[k]), 0);
        wire_scene_rx *rx;
        wire_scene_rx_new("master", &rx, NULL);
        int rc = 0;
        send_scene(&m, rx, false, &rc);
        cr_assert_eq(rc, 1, "SCENE_END did not complete the scene");
        if (k == 1) cr_assert_geq(wire_scene_rx_info(rx)->nchunks, 3);
        cr_assert_eq(wire_scene_rx_take(rx, &r, NULL), 0);
        assert_same_mesh(&m, &r);
        /* The cached payload reproduces the hash. */
        uint64_t size;
        const uint8_t *raw = wire_scene_rx_raw(rx, &size);
        uint8_t h[WIRE_HASH_SIZE];
        wire_scene_hash(raw, size, h);
        cr_assert(memcmp(h, wire_scene_rx_info(rx)->hash, WIRE_HASH_SIZE) == 0);
        /* A second scene on the same receiver, announced as cached. */
        send_scene(&m, rx, true, &rc);
        cr_assert_eq(rc, 1);
        cr_assert(wire_scene_rx_info(rx)->flags & WIRE_SCENE_CACHED);
        cr_assert_eq(wire_scene_rx_take(rx, &r, NULL) < 0, true, "a cached scene has no mesh to take");
        wire_scene_rx_free(rx);
        rmesh_free(&m);
        rmesh_free(&r);
    }
}

Test(scene, hash_depends_on_content)
{
    ct_radmesh m;
    fx_mesh(&m, 5);
    wire_scene_tx a, b;
    wire_scene_tx_init(&a, &m, NULL);
    m.rad[3].y += 0.5f;
    wire_scene_tx_init(&b, &m, NULL);
    cr_assert(memcmp(a.hash, b.hash, WIRE_HASH_SIZE) != 0);
    /* BLAKE2b-256 of the empty string, as a check of the hash and its hex form. */
    uint8_t h[WIRE_HASH_SIZE];
    char hex[2 * WIRE_HASH_SIZE + 1];
    wire_scene_hash((const uint8_t *)"", 0, h);
    wire_hash_hex(h, hex);
    cr_assert_str_eq(hex, "0e5751c026e543b2e8ab2eb06099daa1d1e5df47778f7787faab45cdf12fe3a8");
    wire_scene_tx_free(&a);
    wire_scene_tx_free(&b);
    rmesh_free(&m);
}

/* An empty scene (a well-formed header and nothing else, or vertices with
 * no triangles) is refused with the peer's name, not left to the display's
 * mesh check to report without it. */
Test(scene, empty_payload_refused)
{
    uint8_t raw[24 + 4 * 12 * 2] = {0};
    ct_radmesh r;
    ct_error err = {{0}};
    cr_assert_eq(wire_scene_parse(raw, 24, "master", &r, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "master: scene is empty (0 vertices, 0 triangles, 0 nodes)");
    raw[0] = 2;   /* two vertices, all zero, no triangles */
    cr_assert_eq(wire_scene_parse(raw, sizeof raw, "master", &r, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "master: scene is empty (2 vertices, 0 triangles, 0 nodes)");
}

/* Breaks the payload of a 4-quad mesh with f and expects the parse error. */
static void broken_payload(void (*f)(uint8_t *raw), const char *want)
{
    ct_radmesh m, r;
    fx_mesh(&m, 4);
    wire_scene_tx tx;
    cr_assert_eq(wire_scene_tx_init(&tx, &m, NULL), 0);
    f(tx.raw);
    ct_error err = {{0}};
    cr_expect_eq(wire_scene_parse(tx.raw, tx.raw_size, "master", &r, &err), CT_EPROTO, "%s", want);
    cr_expect_str_eq(err.msg, want);
    wire_scene_tx_free(&tx);
    rmesh_free(&m);
}

/* 4 quads: 10 vertices, 8 triangles, 3 nodes, 4 materials. Offsets per
 * docs/protocol.md. */
#define OFF_TRIS  (24 + 48 * 10)
#define OFF_TNODE (OFF_TRIS + 12 * 8)
#define OFF_NODES (OFF_TNODE + 8 * 8)
#define OFF_MATS  (OFF_NODES + 100 * 3)
static void bad_index(uint8_t *raw) { wio_put_u32(raw + OFF_TRIS + 4 * 5, 10); }
static void bad_node(uint8_t *raw) { wio_put_u32(raw + OFF_TNODE + 4 * 2, 3); }
static void nan_pos(uint8_t *raw) { wio_put_u32(raw + 24 + 12 * 2 + 4, 0x7fc00000u); }
static void bad_parent(uint8_t *raw) { wio_put_u32(raw + OFF_NODES + 100 * 1 + 64, 1); }
static void bad_end(uint8_t *raw) { wio_put_u32(raw + OFF_NODES + 100 * 2 + 68, 4); }
static void unterminated(uint8_t *raw) { memset(raw + OFF_NODES + 100, 'x', 64); }
static void mat_count(uint8_t *raw) { raw[12] = 3; }
static void bright_glass(uint8_t *raw) { wio_put_f32(raw + OFF_MATS + 16 * 2 + 4, 1.5f); }
static void nan_ior(uint8_t *raw) { wio_put_u32(raw + OFF_MATS + 16 * 1 + 12, 0x7fc00000u); }
static void negative_ior(uint8_t *raw) { wio_put_f32(raw + OFF_MATS + 16 * 3 + 12, -1.0f); }
static void counts(uint8_t *raw) { wio_put_u32(raw, 11); }

Test(scene, broken_payloads)
{
    broken_payload(bad_index, "master: scene triangle 1 uses vertex 10 of 10");
    broken_payload(bad_node, "master: scene triangle 2 belongs to node 3 of 3");
    broken_payload(nan_pos, "master: scene vertex 2 has a non-finite position");
    broken_payload(bad_parent, "master: scene node 1 has a parent out of order");
    broken_payload(bad_end, "master: scene node 2 has an end index out of range");
    broken_payload(unterminated, "master: scene node 1 has a name without a terminating NUL");
    broken_payload(mat_count, "master: scene payload is 1028 bytes, its counts need 1012");
    broken_payload(bright_glass, "master: scene material 2 has a transmission or index of refraction out of range");
    broken_payload(nan_ior, "master: scene material 1 has a transmission or index of refraction out of range");
    broken_payload(negative_ior, "master: scene material 3 has a transmission or index of refraction out of range");
    broken_payload(counts, "master: scene payload is 1028 bytes, its counts need 1076");
}

Test(scene, broken_sequences)
{
    ct_radmesh m;
    fx_mesh(&m, 40000);
    wire_scene_tx tx;
    wire_scene_tx_init(&tx, &m, NULL);
    wire_scene_rx *rx;
    wire_scene_rx_new("master", &rx, NULL);
    wire_msg b, c, e;
    ct_error err;
    wire_scene_tx_begin(&tx, false, &b);
    wire_scene_tx_end(&tx, &e);

    cr_assert_eq(wire_scene_rx_feed(rx, &e, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "master: SCENE_END outside a scene");
    cr_assert_eq(wire_scene_rx_feed(rx, &b, &err), 0);
    wire_scene_tx_chunk(&tx, 1, &c);
    cr_assert_eq(wire_scene_rx_feed(rx, &c, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "master: SCENE_CHUNK 1 out of order (expected 0 of 6)");
    wire_scene_tx_chunk(&tx, 0, &c);
    cr_assert_eq(wire_scene_rx_feed(rx, &c, &err), 0);
    cr_assert_eq(wire_scene_rx_feed(rx, &e, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "master: SCENE_END after 1 of 6 chunks");
    cr_assert_eq(wire_scene_rx_feed(rx, &b, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "master: SCENE_BEGIN before the previous scene ended");

    /* A chunk whose bytes were altered: caught by the content hash. */
    wire_scene_rx_free(rx);
    wire_scene_rx_new("master", &rx, NULL);
    cr_assert_eq(wire_scene_rx_feed(rx, &b, &err), 0);
    for (uint32_t i = 0; i < b.u.scene_begin.nchunks; i++) {
        wire_scene_tx_chunk(&tx, i, &c);
        if (i == 2) tx.raw[(size_t)2 * WIRE_SCENE_CHUNK_RAW + 100] ^= 1;
        cr_assert_eq(wire_scene_rx_feed(rx, &c, &err), 0, "%s", err.msg);
    }
    cr_assert_eq(wire_scene_rx_feed(rx, &e, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "master: scene payload does not match its content hash");
    wire_msg ping = {.type = WIRE_PING};
    cr_assert_eq(wire_scene_rx_feed(rx, &ping, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "master: PING is not part of a scene");
    wire_scene_rx_free(rx);
    wire_scene_tx_free(&tx);
    rmesh_free(&m);
}

/* --- handshake ----------------------------------------------------------------- */

/* Moves one side's output into the other's input; returns the input status. */
static int shuttle(auth_hs *from, auth_hs *to, ct_error *err)
{
    wire_buf *o = auth_hs_output(from);
    size_t used = 0;
    int rc = o->len ? auth_hs_input(to, o->data, o->len, &used, err) : WIRE_NEED_MORE;
    wire_buf_consume(o, used);
    return rc;
}

static void run_pair(const auth_config *mc, const auth_config *dc, int *mrc, int *drc, ct_error *merr,
                     ct_error *derr)
{
    auth_hs *m, *d;
    cr_assert_eq(auth_hs_new(mc, &m, merr), 0, "%s", merr->msg);
    cr_assert_eq(auth_hs_new(dc, &d, derr), 0, "%s", derr->msg);
    *mrc = *drc = WIRE_NEED_MORE;
    for (int i = 0; i < 8 && (*mrc == WIRE_NEED_MORE || *drc == WIRE_NEED_MORE); i++) {
        if (*drc == WIRE_NEED_MORE) *drc = shuttle(m, d, derr);
        if (*mrc == WIRE_NEED_MORE) *mrc = shuttle(d, m, merr);
    }
    auth_hs_free(m);
    auth_hs_free(d);
}

Test(handshake, mutual_hmac_and_plain)
{
    auth_token t = fx_token("correct horse battery staple");
    auth_config mc = {.role = AUTH_ROLE_MASTER, .token = &t, .require_auth = true, .peer = "display"};
    auth_config dc = {.role = AUTH_ROLE_DISPLAY, .token = &t, .require_auth = true, .peer = "master"};
    int mrc, drc;
    ct_error me = {{0}}, de = {{0}};
    run_pair(&mc, &dc, &mrc, &drc, &me, &de);
    cr_assert_eq(mrc, 0, "master: %s", me.msg);
    cr_assert_eq(drc, 0, "display: %s", de.msg);

    /* No token on either side: HELLO only (a UNIX socket). */
    auth_config mc2 = {.role = AUTH_ROLE_MASTER, .peer = "display"};
    auth_config dc2 = {.role = AUTH_ROLE_DISPLAY, .peer = "master"};
    run_pair(&mc2, &dc2, &mrc, &drc, &me, &de);
    cr_assert_eq(mrc, 0, "%s", me.msg);
    cr_assert_eq(drc, 0, "%s", de.msg);
}

Test(handshake, wrong_token_fails_on_both_sides)
{
    auth_token a = fx_token("correct horse battery staple"), b = fx_token("incorrect horse battery staple");
    auth_config mc = {.role = AUTH_ROLE_MASTER, .token = &a, .require_auth = true, .peer = "display"};
    auth_config dc = {.role = AUTH_ROLE_DISPLAY, .token = &b, .require_auth = true, .peer = "master"};
    int mrc, drc;
    ct_error me = {{0}}, de = {{0}};
    run_pair(&mc, &dc, &mrc, &drc, &me, &de);
    cr_assert_eq(mrc, CT_EAUTH);
    cr_assert_str_eq(me.msg, "display: authentication failed: the peer's proof does not match our token");
    cr_assert_eq(drc, CT_EAUTH);
    cr_assert_str_eq(de.msg, "master: authentication failed: the peer's proof does not match our token");
}

Test(handshake, policy_errors)
{
    auth_token t = fx_token("correct horse battery staple");
    int mrc, drc;
    ct_error me = {{0}}, de = {{0}};
    /* The display insists (TCP) but the master does not authenticate. */
    auth_config mc = {.role = AUTH_ROLE_MASTER, .peer = "display"};
    auth_config dc = {.role = AUTH_ROLE_DISPLAY, .token = &t, .require_auth = true, .peer = "master"};
    run_pair(&mc, &dc, &mrc, &drc, &me, &de);
    cr_assert_eq(drc, CT_EAUTH);
    cr_assert_str_eq(de.msg, "master: the master does not authenticate; refusing an unauthenticated connection");
    /* The master requires a token the display does not have. */
    auth_config mc2 = {.role = AUTH_ROLE_MASTER, .token = &t, .require_auth = true, .peer = "display"};
    auth_config dc2 = {.role = AUTH_ROLE_DISPLAY, .peer = "master"};
    run_pair(&mc2, &dc2, &mrc, &drc, &me, &de);
    cr_assert_eq(drc, CT_EAUTH);
    cr_assert_str_eq(de.msg, "master: the master requires a token; give --token-file or set CORRTEX_TOKEN");
    /* ...and the master then reads the display's ERROR instead of an AUTH. */
    cr_assert_eq(mrc, CT_EAUTH);
    cr_assert_str_eq(me.msg, "display: peer refused the handshake: display has no token");
    /* A master that requires auth without a token cannot start. */
    auth_hs *hs;
    auth_config bad = {.role = AUTH_ROLE_MASTER, .require_auth = true, .peer = "display"};
    cr_assert_eq(auth_hs_new(&bad, &hs, &me), CT_EINVAL);
    cr_assert_str_eq(me.msg,
                     "display: authentication is required but no token was given (--token-file or CORRTEX_TOKEN)");
}

typedef struct broken_hs {
    const char *name;
    auth_role role;     /* the side under test */
    bool token;         /* it has (and, as master, requires) a token */
    uint8_t bytes[128];
    size_t len;
    int code;
    const char *msg;
} broken_hs;

#define MAGIC 0x89, 'C', 'T', 'X', '\r', '\n', 0x1a, '\n'
#define BID 'c', 'o', 'r', 'r', 't', 'e', 'x', '-', 'p', 'r', 'o', 't', 'o', '-', '1', 0, 0, 0, 0, 0
#define NONCE [32] = 0
static const broken_hs broken_handshakes[] = {
    {"HTTP request", AUTH_ROLE_MASTER, false, "GET / HTTP/1.1\r\n", 16, CT_EPROTO,
     "peer: bad magic byte 0x47 at offset 0 (not a corrtex peer?)"},
    {"magic without \\x1a", AUTH_ROLE_MASTER, false, {0x89, 'C', 'T', 'X', '\r', '\n', '\n'}, 7, CT_EPROTO,
     "peer: bad magic byte 0x0a at offset 6 (not a corrtex peer?)"},
    {"wrong version (an older peer)", AUTH_ROLE_MASTER, false, {MAGIC, 4, 0, 2, 0, BID}, 64, CT_EPROTO, "peer: protocol version 4, expected 5"},
    {"wrong role", AUTH_ROLE_MASTER, false, {MAGIC, WIRE_VERSION, 0, 1, 0, BID}, 64, CT_EPROTO,
     "peer: peer has role master (1), expected display"},
    {"unknown role", AUTH_ROLE_DISPLAY, false, {MAGIC, WIRE_VERSION, 0, 9, 0, BID}, 64, CT_EPROTO,
     "peer: peer has role unknown (9), expected master"},
    {"unknown flags", AUTH_ROLE_DISPLAY, false, {MAGIC, WIRE_VERSION, 0, 1, 0x80, BID}, 64, CT_EPROTO,
     "peer: HELLO flags 0x80 unknown"},
    {"display sets a flag", AUTH_ROLE_MASTER, false, {MAGIC, WIRE_VERSION, 0, 2, 1, BID}, 64, CT_EPROTO,
     "peer: HELLO flags 0x01 unknown"},
    {"other build", AUTH_ROLE_MASTER, false, {MAGIC, WIRE_VERSION, 0, 2, 0, 'c', 'o', 'r', 'r', 't', 'e', 'x', '-', '0'}, 64,
     CT_EPROTO, "peer: build id 'corrtex-0' differs from ours 'corrtex-proto-1'"},
    {"build id garbage", AUTH_ROLE_MASTER, false, {MAGIC, WIRE_VERSION, 0, 2, 0, 'a', 0, 'b'}, 64, CT_EPROTO,
     "peer: build id is not NUL-padded printable ASCII"},
    {"bad HMAC", AUTH_ROLE_MASTER, true, {MAGIC, WIRE_VERSION, 0, 2, 0, BID, [64] = H(WIRE_AUTH, 0, 32)}, 104, CT_EAUTH,
     "peer: authentication failed: the peer's proof does not match our token"},
    {"PING instead of AUTH", AUTH_ROLE_MASTER, true, {MAGIC, WIRE_VERSION, 0, 2, 0, BID, [64] = H(WIRE_PING, 0, 8)}, 72,
     CT_EPROTO, "peer: expected AUTH during the handshake, got PING"},
    {"short AUTH", AUTH_ROLE_MASTER, true, {MAGIC, WIRE_VERSION, 0, 2, 0, BID, [64] = H(WIRE_AUTH, 0, 31)}, 72, CT_EPROTO,
     "peer: AUTH body length 31, expected 32"},
    {"garbage frame", AUTH_ROLE_MASTER, true, {MAGIC, WIRE_VERSION, 0, 2, 0, BID, [64] = H(500, 0, 0)}, 72, CT_EPROTO,
     "peer: message type 500 unknown"},
};

Test(broken, handshakes_give_their_exact_error)
{
    auth_token t = fx_token("correct horse battery staple");
    for (size_t i = 0; i < sizeof broken_handshakes / sizeof broken_handshakes[0]; i++) {
        const broken_hs *b = &broken_handshakes[i];
        auth_config cfg = {.role = b->role, .token = b->token ? &t : NULL, .require_auth = b->token, .peer = "peer"};
        auth_hs *hs;
        cr_assert_eq(auth_hs_new(&cfg, &hs, NULL), 0);
        /* Byte by byte: the error must come at the same point either way. */
        int rc = WIRE_NEED_MORE;
        ct_error err = {{0}};
        for (size_t k = 0; k < b->len && rc == WIRE_NEED_MORE; k++) {
            size_t used;
            rc = auth_hs_input(hs, b->bytes + k, 1, &used, &err);
        }
        cr_expect_eq(rc, b->code, "%s: code %d (%s)", b->name, rc, err.msg);
        cr_expect_str_eq(err.msg, b->msg, "%s", b->name);
        /* A failed handshake tells the peer why (an ERROR frame after our HELLO). */
        wire_buf *o = auth_hs_output(hs);
        cr_expect_gt(o->len, AUTH_HELLO_SIZE, "%s: no ERROR queued for the peer", b->name);
        auth_hs_free(hs);
    }
}

/* --- MPI ------------------------------------------------------------------------ */

static void collect(const uint8_t *d, size_t n, void *ctx)
{
    wire_buf *all = ctx;
    uint32_t len = (uint32_t)n;
    wire_buf_append(all, &len, 4, NULL);
    wire_buf_append(all, d, n, NULL);
}

Test(mpi, round_trip_every_kind)
{
    wire_buf seeds = {0};
    cr_assert_eq(fx_fuzz_seeds("mpi", collect, &seeds), 4);
    size_t off = 0;
    unsigned kinds_seen = 0;
    while (off < seeds.len) {
        uint32_t n;
        memcpy(&n, seeds.data + off, 4);
        const uint8_t *msg = seeds.data + off + 4;
        off += 4 + n;
        unsigned kind;
        uint32_t count;
        ct_error err = {{0}};
        cr_assert_eq(wire_mpi_peek(msg, n, "rank 1", &kind, &count, &err), 0, "%s", err.msg);
        kinds_seen |= 1u << kind;
        wire_buf again = {0};
        if (kind == WIRE_MPI_REQUESTS) {
            ct_request r[8];
            wire_mpi_requests h;
            cr_assert_eq(wire_mpi_decode_requests(msg, n, "rank 1", &h, r, 8, &count, &err), 0, "%s", err.msg);
            cr_assert_eq(count, 3);
            cr_assert_eq(r[0].id, 1);
            cr_assert_eq(r[0].py, 20.25f);
            cr_assert_eq(h.width, 64);
            wire_mpi_encode_requests(&h, r, count, &again, NULL);
        } else if (kind == WIRE_MPI_SAMPLES) {
            ct_sample s[8];
            wire_mpi_samples h;
            cr_assert_eq(wire_mpi_decode_samples(msg, n, "rank 1", &h, s, 8, &count, &err), 0, "%s", err.msg);
            cr_assert_eq(count, 2);
            cr_assert_eq(s[0].l_hq.z, 0.125f);
            cr_assert_eq(s[0].tri, 99);
            cr_assert_eq(h.rank, 2);
            wire_mpi_encode_samples(&h, s, count, &again, NULL);
        } else if (kind == WIRE_MPI_CAMERA) {
            wire_mpi_camera c;
            cr_assert_eq(wire_mpi_decode_camera(msg, n, "rank 1", &c, &err), 0, "%s", err.msg);
            cr_assert_eq(c.epoch, 5);
            wire_mpi_encode_camera(&c, &again, NULL);
        } else {
            wire_mpi_control c;
            cr_assert_eq(wire_mpi_decode_control(msg, n, "rank 1", &c, &err), 0, "%s", err.msg);
            cr_assert_eq(c.seed, 77);
            cr_assert_eq(c.mode, WIRE_MPI_MODE_REUSE_DIFFUSE);
            wire_mpi_encode_control(&c, &again, NULL);
        }
        cr_assert_eq(again.len, n);
        cr_assert(memcmp(again.data, msg, n) == 0, "MPI kind %u re-encodes differently", kind);
        wire_buf_free(&again);
    }
    cr_assert_eq(kinds_seen, 0x1e);
    wire_buf_free(&seeds);
}

Test(mpi, broken_messages)
{
    ct_request r[4];
    wire_mpi_requests h;
    wire_mpi_control c;
    uint32_t n;
    ct_error err;
    uint8_t b[64] = {1, 0, 1, 0, 2, 0, 0, 0};
    cr_assert_eq(wire_mpi_decode_requests(b, 3, "rank 2", &h, r, 4, &n, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI message of 3 bytes is shorter than its header");
    cr_assert_eq(wire_mpi_decode_requests(b, 64, "rank 2", &h, r, 4, &n, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI REQUESTS of 2 records is 64 bytes, expected 132");
    uint8_t big[8] = {1, 0, 1, 0, 0, 0, 2, 0};
    cr_assert_eq(wire_mpi_decode_requests(big, 8, "rank 2", &h, r, 4, &n, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI REQUESTS count 131072 out of range");
    uint8_t kind[8] = {9, 0, 1, 0, 0, 0, 0, 0};
    cr_assert_eq(wire_mpi_decode_control(kind, 8, "rank 2", &c, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI message kind 9 unknown");
    uint8_t ver[8] = {4, 0, 7, 0, 0, 0, 0, 0};
    cr_assert_eq(wire_mpi_decode_control(ver, 8, "rank 2", &c, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI message version 7, expected 1");
    uint8_t ctl[32] = {4, 0, 1, 0, 0, 0, 0, 0, 3, 0, 0, 0};
    cr_assert_eq(wire_mpi_decode_control(ctl, 32, "rank 2", &c, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI CONTROL op 3 unknown");
    cr_assert_eq(wire_mpi_decode_requests(ctl, 32, "rank 2", &h, r, 4, &n, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: expected an MPI REQUESTS message, got CONTROL");
    /* The header alone (a tracer queues batches by it) is checked the same way. */
    cr_assert_eq(wire_mpi_decode_requests_header(b, 64, "rank 2", &h, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI REQUESTS of 2 records is 64 bytes, expected 132");
    cr_assert_eq(wire_mpi_decode_requests_header(ctl, 32, "rank 2", &h, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: expected an MPI REQUESTS message, got CONTROL");
    /* A request batch larger than the caller's array. */
    wire_buf seeds = {0};
    fx_fuzz_seeds("mpi", collect, &seeds);
    uint32_t len;
    memcpy(&len, seeds.data, 4);
    cr_assert_eq(wire_mpi_decode_requests(seeds.data + 4, len, "rank 2", &h, r, 2, &n, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI REQUESTS of 3 records, room for 2");
    cr_assert_eq(wire_mpi_decode_requests_header(seeds.data + 4, len, "rank 2", &h, &err), 0, "%s", err.msg);
    /* an image width of 0 (header offset 8 + batch 8 + epoch 4) */
    uint32_t width;
    memcpy(&width, seeds.data + 4 + 8 + 12, 4);
    wio_put_u32(seeds.data + 4 + 8 + 12, 0);
    cr_assert_eq(wire_mpi_decode_requests_header(seeds.data + 4, len, "rank 2", &h, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI REQUESTS has an invalid camera");
    memcpy(seeds.data + 4 + 8 + 12, &width, 4);
    /* A NaN position in request 1 (record offset 8 + 52 + 36 + 20). */
    wio_put_u32(seeds.data + 4 + 8 + 52 + 36 + 20, 0x7fc00000u);
    cr_assert_eq(wire_mpi_decode_requests(seeds.data + 4, len, "rank 2", &h, r, 4, &n, &err), CT_EPROTO);
    cr_assert_str_eq(err.msg, "rank 2: MPI request 1 has a non-finite or negative value");
    wire_buf_free(&seeds);
}

/* --- tokens ---------------------------------------------------------------------- */

static void write_file(const char *path, const char *text, mode_t mode)
{
    FILE *f = fopen(path, "w");
    cr_assert(f);
    fputs(text, f);
    fclose(f);
    chmod(path, mode);
}

Test(token, files_and_environment)
{
    char dir[] = "/tmp/ct-token-XXXXXX";
    cr_assert(mkdtemp(dir));
    char path[256];
    snprintf(path, sizeof path, "%s/token", dir);
    auth_token t;
    ct_error err;
    bool have;

    write_file(path, "0123456789abcdef0123\n", 0600);
    cr_assert_eq(auth_token_load(path, &t, &err), 0, "%s", err.msg);
    cr_assert_eq(t.len, 20, "trailing newline not stripped");

    write_file(path, "0123456789abcdef0123\n", 0644);
    char want[400];
    cr_assert_eq(auth_token_load(path, &t, &err), CT_EINVAL);
    snprintf(want, sizeof want, "%s: token file is accessible by group or others (mode 644); chmod 600 it", path);
    cr_assert_str_eq(err.msg, want);

    write_file(path, "short\n", 0600);
    cr_assert_eq(auth_token_load(path, &t, &err), CT_EINVAL);
    snprintf(want, sizeof want, "%s: the token has 5 bytes, at least 16 are needed", path);
    cr_assert_str_eq(err.msg, want);

    write_file(path, " \n\n", 0600);
    cr_assert_eq(auth_token_load(path, &t, &err), CT_EINVAL);
    snprintf(want, sizeof want, "%s: the token is empty", path);
    cr_assert_str_eq(err.msg, want);

    snprintf(path, sizeof path, "%s/missing", dir);
    cr_assert_eq(auth_token_load(path, &t, &err), CT_EIO);
    snprintf(want, sizeof want, "%s: cannot open token file: No such file or directory", path);
    cr_assert_str_eq(err.msg, want);

    unsetenv("CORRTEX_TOKEN");
    cr_assert_eq(auth_token_get(NULL, &t, &have, &err), 0);
    cr_assert(!have);
    setenv("CORRTEX_TOKEN", "an-environment-token", 1);
    cr_assert_eq(auth_token_get(NULL, &t, &have, &err), 0);
    cr_assert(have);
    cr_assert_eq(t.len, 20);
    setenv("CORRTEX_TOKEN", "tiny", 1);
    cr_assert_eq(auth_token_get(NULL, &t, &have, &err), CT_EINVAL);
    cr_assert_str_eq(err.msg, "$CORRTEX_TOKEN: the token has 4 bytes, at least 16 are needed");
    unsetenv("CORRTEX_TOKEN");
    snprintf(path, sizeof path, "%s/token", dir);
    unlink(path);
    rmdir(dir);
}
