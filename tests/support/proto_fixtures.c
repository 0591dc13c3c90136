/* proto_fixtures.c: see proto_fixtures.h. */
#include "tests/support/proto_fixtures.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto/auth.h"
#include "proto/wire_mpi.h"

static uint16_t fx_texels[3 * 37 * 11];
static uint8_t fx_chunk[5000];
static float fx_points[3 * 5];

size_t fx_messages(wire_msg *out)
{
    for (size_t i = 0; i < sizeof fx_texels / sizeof fx_texels[0]; i++)
        fx_texels[i] = wire_half_from_float((float)((int)(i % 97) - 48) * 0.03125f);
    for (size_t i = 0; i < sizeof fx_chunk; i++) fx_chunk[i] = (uint8_t)((i * 7) ^ (i >> 5));
    size_t n = 0;
    memset(out, 0, FX_NMSG * sizeof *out);
    wire_msg *m;

    m = &out[n++];
    m->type = WIRE_AUTH;
    for (int i = 0; i < 32; i++) m->u.auth.mac[i] = (uint8_t)(i * 13 + 1);

    m = &out[n++];
    m->type = WIRE_SETTINGS;
    m->u.settings.samples_per_frame = 4096;
    for (int i = 0; i < 32; i++) m->u.settings.cached_scene[i] = (uint8_t)(0xa0 + i);

    m = &out[n++];
    m->type = WIRE_SCENE_BEGIN;
    m->u.scene_begin.nverts = 30000;
    m->u.scene_begin.ntris = 20000;
    m->u.scene_begin.nnodes = 12;
    m->u.scene_begin.raw_size = wire_scene_payload_size(30000, 20000, 12, 0);
    m->u.scene_begin.nchunks = (uint32_t)((m->u.scene_begin.raw_size + WIRE_SCENE_CHUNK_RAW - 1) / WIRE_SCENE_CHUNK_RAW);
    m->u.scene_begin.scene_hash = 0x0123456789abcdefull;
    for (int i = 0; i < 32; i++) m->u.scene_begin.hash[i] = (uint8_t)(255 - i);

    m = &out[n++];
    m->type = WIRE_SCENE_BEGIN;
    m->u.scene_begin.nverts = 3;
    m->u.scene_begin.ntris = 1;
    m->u.scene_begin.nnodes = 1;
    m->u.scene_begin.raw_size = wire_scene_payload_size(3, 1, 1, 0);
    m->u.scene_begin.flags = WIRE_SCENE_CACHED;

    m = &out[n++];
    m->type = WIRE_SCENE_CHUNK;
    m->u.scene_chunk.index = 3;
    m->u.scene_chunk.len = sizeof fx_chunk;
    m->u.scene_chunk.data = fx_chunk;

    m = &out[n++];
    m->type = WIRE_SCENE_END;
    for (int i = 0; i < 32; i++) m->u.scene_end.hash[i] = (uint8_t)(i * 3);

    m = &out[n++];
    m->type = WIRE_CAMERA;
    m->u.camera.epoch = 17;
    m->u.camera.width = 640;
    m->u.camera.height = 480;
    m->u.camera.cam = cam_look_at(v3(1.5f, 2.0f, -3.25f), v3(0, 1, 0), v3(0, 1, 0), 55.0f);

    m = &out[n++];
    m->type = WIRE_TEX_ALLOC;
    m->u.tex_alloc = (wire_tex_alloc){.tex = 42, .node = 7, .width = 256, .height = 128,
                                      .proj = WIRE_PROJ_OBJECT_PARALLEL};

    m = &out[n++];
    m->type = WIRE_TEX_ALLOC;
    m->u.tex_alloc = (wire_tex_alloc){.tex = 43, .node = 9, .width = 64, .height = 64,
                                      .proj = WIRE_PROJ_CAMERA_PERSPECTIVE};

    m = &out[n++];
    m->type = WIRE_TEX_PROJECTION;
    m->u.tex_projection.tex = 42;
    m->u.tex_projection.epoch = 17;
    for (int i = 0; i < 16; i++) m->u.tex_projection.world_to_tex.m[i / 4][i % 4] = (float)i * 0.25f - 1.0f;

    m = &out[n++];
    m->type = WIRE_TEX_FREE;
    m->u.tex_free.tex = 43;

    m = &out[n++];
    m->type = WIRE_TEX_PATCH;
    m->u.tex_patch = (wire_tex_patch){.tex = 42, .x = 5, .y = 9, .w = 37, .h = 11, .texels = fx_texels,
                                      .encoding = WIRE_PATCH_LZ4, .samples = 77, .stamp_us = 0x123456789abcull};

    m = &out[n++];
    m->type = WIRE_TEX_PATCH;
    m->u.tex_patch = (wire_tex_patch){.tex = 42, .x = 0, .y = 8, .w = 16, .h = 8, .texels = fx_texels,
                                      .encoding = WIRE_PATCH_RAW, .samples = 0, .stamp_us = 1};

    m = &out[n++];
    m->type = WIRE_FRAME;
    m->u.frame = (wire_frame){.frame = 123456789012ull, .epoch = 17, .flags = WIRE_FLAG_ALL_POSITIVE,
                              .samples = 4096, .patches = 33};

    m = &out[n++];
    m->type = WIRE_STATS;
    m->u.stats = (wire_stats){.epoch = 17, .flags = 0, .samples_total = 1u << 30, .samples_per_s = 250000.5f,
                              .queue_len = 777, .coverage = 0.625f, .textures = 31, .texel_bytes = 12345678,
                              .bytes_per_s = 3.5e6f, .t_render = 0.25f, .t_sample = 0.5f, .t_texture = 0.125f};

    m = &out[n++];
    wire_make_error(m, WIRE_ERR_BUSY, "another display is connected");

    m = &out[n++];
    wire_make_error(m, WIRE_ERR_PROTOCOL, "");

    m = &out[n++];
    m->type = WIRE_PING;
    m->u.ping.token = 0xfeedfacecafebeefull;

    m = &out[n++];
    m->type = WIRE_PONG;
    m->u.ping.token = 1;
    m->u.ping.clock_us = 0xabcdef0123ull;

    m = &out[n++];
    m->type = WIRE_SYNC;
    m->u.sync = (wire_sync){.seq = 12, .clock_us = 987654321};

    m = &out[n++];
    m->type = WIRE_ACK;
    m->u.ack.seq = 11;

    m = &out[n++];
    m->type = WIRE_BYE;
    m->u.bye.reason = WIRE_BYE_DONE;

    m = &out[n++];
    m->type = WIRE_BYE;
    m->u.bye.reason = WIRE_BYE_QUIT;

    for (size_t i = 0; i < sizeof fx_points / sizeof fx_points[0]; i++)
        fx_points[i] = (float)((int)i - 7) * 13.375f + (i % 3 == 2 ? -1e-3f : 0.0f);
    m = &out[n++];
    m->type = WIRE_SAMPLES;
    m->u.samples = (wire_samples){.epoch = 17, .count = 5, .dropped = 0x100000001ull, .xyz = fx_points};

    m = &out[n++];
    m->type = WIRE_SAMPLES;   /* no points: only the drop count */
    m->u.samples = (wire_samples){.epoch = 18, .count = 0, .dropped = 3, .xyz = fx_points};

    m = &out[n++];
    m->type = WIRE_TEX_RESIZE;
    m->u.tex_resize = (wire_tex_resize){.tex = 42, .width = 512, .height = 128};
    return n;
}

auth_token fx_token(const char *s)
{
    auth_token t;
    memset(&t, 0, sizeof t);
    t.len = strlen(s);
    memcpy(t.bytes, s, t.len);
    return t;
}

int fx_mesh(ct_radmesh *m, uint32_t nquads)
{
    int rc = rmesh_alloc(m, 2 * (nquads + 1), 2 * nquads, 3, NULL);
    if (rc) return rc;
    for (uint32_t i = 0; i <= nquads; i++) {
        for (uint32_t k = 0; k < 2; k++) {
            uint32_t v = 2 * i + k;
            m->pos[v] = v3((float)i, (float)k, 0.5f * sinf((float)i));
            m->nrm[v] = v3(0, 0, 1);
            m->rad[v] = v3(0.1f * (float)(i % 7), 0.2f, (float)k);
            m->rad_direct[v] = v3(0.05f * (float)(i % 3), 0.0f, 0.5f);
        }
    }
    for (uint32_t q = 0; q < nquads; q++) {
        uint32_t a = 2 * q, b = a + 1, c = a + 2, d = a + 3;
        uint32_t t = 2 * q;
        m->tris[3 * t + 0] = a, m->tris[3 * t + 1] = c, m->tris[3 * t + 2] = b;
        m->tris[3 * t + 3] = b, m->tris[3 * t + 4] = c, m->tris[3 * t + 5] = d;
        m->tri_node[t] = m->tri_node[t + 1] = q < nquads / 2 ? 1 : 2;
        m->tri_mat[t] = m->tri_mat[t + 1] = q % 4;
    }
    /* root(0) with two parts (1, 2) */
    snprintf(m->nodes[0].name, SCENE_NAME_LEN, "root");
    m->nodes[0].parent = -1;
    m->nodes[0].node_end = 3;
    m->nodes[0].material = UINT32_MAX;
    m->nodes[0].bounds = (bounds3){v3(0, 0, -1), v3((float)nquads, 1, 1)};
    for (int n = 1; n < 3; n++) {
        snprintf(m->nodes[n].name, SCENE_NAME_LEN, "part-%d", n);
        m->nodes[n].parent = 0;
        m->nodes[n].node_end = (uint32_t)n + 1;
        m->nodes[n].material = (uint32_t)n;
        m->nodes[n].bounds = b3_empty();
    }
    /* materials 0..3, the third one glass */
    m->mats = calloc(4, sizeof *m->mats);
    if (!m->mats) {
        rmesh_free(m);
        return CT_ENOMEM;
    }
    m->nmats = 4;
    m->mats[2] = (rmesh_material){v3(0.9f, 0.8f, 0.7f), 1.5f};
    m->scene_hash = 0x5eed5eed5eed5eedull;
    return 0;
}

/* --- fuzz bodies -------------------------------------------------------------- */

int fx_fuzz_wire(const uint8_t *data, size_t size)
{
    /* The first byte picks a feeding pattern (chunk size), the rest is the stream. */
    if (size < 1) return 0;
    size_t step = (size_t)(data[0] % 16) + 1;
    data++;
    size--;
    wire_decoder *d;
    if (wire_decoder_new("fuzz", &d, NULL)) return 0;
    wire_buf again = {0};
    for (size_t off = 0; off < size; off += step) {
        size_t n = size - off < step ? size - off : step;
        if (wire_decoder_feed(d, data + off, n, NULL)) break;
        wire_msg m;
        int rc;
        while ((rc = wire_decoder_next(d, &m, NULL)) == WIRE_OK) {
            /* Whatever decodes must re-encode and decode to the same bytes. */
            again.len = 0;
            if (wire_encode(&m, &again, NULL) != 0) __builtin_trap();
            wire_msg m2;
            wire_scratch s = {0};
            if (wire_decode(again.data, again.len, "fuzz", &m2, &s, NULL) != 0) __builtin_trap();
            wire_scratch_free(&s);
        }
        if (rc < 0) break;
    }
    wire_buf_free(&again);
    wire_decoder_free(d);
    return 0;
}

int fx_fuzz_handshake(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    auth_token tok;
    memset(&tok, 0, sizeof tok);
    memcpy(tok.bytes, "fuzz-token-0123456789", 21);
    tok.len = 21;
    auth_config cfg = {.role = (data[0] & 1) ? AUTH_ROLE_MASTER : AUTH_ROLE_DISPLAY,
                       .token = (data[0] & 2) ? &tok : NULL,
                       .require_auth = (data[0] & 2) != 0,
                       .peer = "fuzz"};
    auth_hs *hs;
    if (auth_hs_new(&cfg, &hs, NULL)) return 0;
    size_t step = (size_t)((data[0] >> 2) % 8) + 1;
    for (size_t off = 1; off < size; off += step) {
        size_t n = size - off < step ? size - off : step, used;
        int rc = auth_hs_input(hs, data + off, n, &used, NULL);
        if (used > n) __builtin_trap();
        if (rc != WIRE_NEED_MORE) break;
    }
    auth_hs_free(hs);
    return 0;
}

int fx_fuzz_scene(const uint8_t *data, size_t size)
{
    ct_radmesh m;
    if (wire_scene_parse(data, size, "fuzz", &m, NULL) == 0) {
        /* A payload that parses re-serializes to the same bytes. */
        wire_scene_tx tx;
        if (wire_scene_tx_init(&tx, &m, NULL) != 0) __builtin_trap();
        if (tx.raw_size != size || memcmp(tx.raw, data, size) != 0) __builtin_trap();
        wire_scene_tx_free(&tx);
        rmesh_free(&m);
    }
    return 0;
}

int fx_fuzz_mpi(const uint8_t *data, size_t size)
{
    static ct_request reqs[64];
    static ct_sample smp[64];
    wire_mpi_requests rh;
    wire_mpi_samples sh;
    wire_mpi_camera c;
    wire_mpi_control ctl;
    uint32_t n;
    wire_buf b = {0};
    if (wire_mpi_decode_requests(data, size, "fuzz", &rh, reqs, 64, &n, NULL) == 0) {
        if (wire_mpi_encode_requests(&rh, reqs, n, &b, NULL) || b.len != size || memcmp(b.data, data, size))
            __builtin_trap();
    }
    b.len = 0;
    if (wire_mpi_decode_samples(data, size, "fuzz", &sh, smp, 64, &n, NULL) == 0) {
        if (wire_mpi_encode_samples(&sh, smp, n, &b, NULL) || b.len != size || memcmp(b.data, data, size))
            __builtin_trap();
    }
    b.len = 0;
    if (wire_mpi_decode_camera(data, size, "fuzz", &c, NULL) == 0) {
        if (wire_mpi_encode_camera(&c, &b, NULL) || b.len != size || memcmp(b.data, data, size)) __builtin_trap();
    }
    b.len = 0;
    if (wire_mpi_decode_control(data, size, "fuzz", &ctl, NULL) == 0) {
        if (wire_mpi_encode_control(&ctl, &b, NULL) || b.len != size || memcmp(b.data, data, size)) __builtin_trap();
    }
    wire_buf_free(&b);
    return 0;
}

/* --- seeds ----------------------------------------------------------------- */

size_t fx_fuzz_seeds(const char *target, void (*emit)(const uint8_t *data, size_t size, void *ctx), void *ctx)
{
    size_t count = 0;
    wire_buf b = {0};
    if (strcmp(target, "wire") == 0) {
        wire_msg msgs[FX_NMSG];
        size_t n = fx_messages(msgs);
        for (size_t i = 0; i < n; i++) {
            b.len = 0;
            uint8_t step = (uint8_t)(i % 16);
            wire_buf_append(&b, &step, 1, NULL);
            if (wire_encode(&msgs[i], &b, NULL) == 0) {
                emit(b.data, b.len, ctx);
                count++;
            }
        }
    } else if (strcmp(target, "handshake") == 0) {
        uint8_t nonce[AUTH_NONCE_SIZE] = {1, 2, 3};
        for (uint8_t mode = 0; mode < 4; mode++) {
            uint8_t hello[AUTH_HELLO_SIZE];
            auth_role peer_role = (mode & 1) ? AUTH_ROLE_DISPLAY : AUTH_ROLE_MASTER;
            auth_hello_encode(hello, peer_role, peer_role == AUTH_ROLE_MASTER && (mode & 2) ? 1 : 0, CT_BUILD_ID,
                              nonce);
            b.len = 0;
            uint8_t first = mode;
            wire_buf_append(&b, &first, 1, NULL);
            wire_buf_append(&b, hello, sizeof hello, NULL);
            wire_msg m;
            memset(&m, 0, sizeof m);
            m.type = WIRE_AUTH;
            wire_encode(&m, &b, NULL);
            emit(b.data, b.len, ctx);
            count++;
        }
    } else if (strcmp(target, "scene") == 0) {
        ct_radmesh m;
        uint32_t sizes[3] = {1, 3, 10};
        for (int i = 0; i < 3; i++) {
            if (fx_mesh(&m, sizes[i])) continue;
            wire_scene_tx tx;
            if (wire_scene_tx_init(&tx, &m, NULL) == 0) {
                emit(tx.raw, tx.raw_size, ctx);
                count++;
                wire_scene_tx_free(&tx);
            }
            rmesh_free(&m);
        }
    } else if (strcmp(target, "mpi") == 0) {
        ct_request r[3] = {{1, 0, 4, 10.5f, 20.25f, 2.0f, 1.0f}, {2, 1, 4, 0, 0, 0, 0}, {3, 1, 4, 5, 6, 7, 8}};
        ct_sample s[2];
        memset(s, 0, sizeof s);
        s[0] = (ct_sample){.request_id = 1, .epoch = 4, .flags = CT_SAMPLE_HIT | CT_SAMPLE_HAS_BASE, .px = 10.5f,
                           .py = 20.25f, .node = 3, .tri = 99, .u = 0.25f, .v = 0.5f, .hit = {1, 2, 3},
                           .l_hq = {0.5f, 0.25f, 0.125f}, .l_base = {0.4f, 0.2f, 0.1f}};
        wire_mpi_requests rh = {.batch = 9, .epoch = 4, .width = 64, .height = 48,
                                .cam = cam_look_at(v3(0, 0, 5), v3(0, 0, 0), v3(0, 1, 0), 45.0f)};
        wire_mpi_samples sh = {.batch = 9, .rank = 2};
        wire_mpi_camera c = {.epoch = 5, .width = 64, .height = 48, .cam = rh.cam};
        wire_mpi_control ctl = {.op = WIRE_MPI_OP_CONFIG, .mode = WIRE_MPI_MODE_REUSE_DIFFUSE, .seed = 77,
                                .shadow_rays = 4, .max_depth = 5};
        b.len = 0;
        if (!wire_mpi_encode_requests(&rh, r, 3, &b, NULL)) emit(b.data, b.len, ctx), count++;
        b.len = 0;
        if (!wire_mpi_encode_samples(&sh, s, 2, &b, NULL)) emit(b.data, b.len, ctx), count++;
        b.len = 0;
        if (!wire_mpi_encode_camera(&c, &b, NULL)) emit(b.data, b.len, ctx), count++;
        b.len = 0;
        if (!wire_mpi_encode_control(&ctl, &b, NULL)) emit(b.data, b.len, ctx), count++;
    }
    wire_buf_free(&b);
    return count;
}
