/* wire_display.c: encode/decode of the display socket messages (frame header
 * and every body), byte buffers, and the checks shared by both directions:
 * one validate() is run by the encoder before writing and by the decoder
 * after parsing, so everything that can be sent decodes and vice versa.
 * Over 600 lines on purpose: every message's encoder, decoder and checks
 * side by side, which is what keeps the two directions in step. */
#include "proto/wire.h"

#include <lz4.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "proto/wire_io.h"

/* Fixed body sizes (docs/protocol.md); 0 = variable. */
#define SZ_AUTH        32u
#define SZ_SETTINGS    40u
#define SZ_SCENE_BEGIN 68u
#define SZ_SCENE_END   32u
#define SZ_CAMERA      44u
#define SZ_TEX_ALLOC   20u
#define SZ_TEX_PROJ    72u
#define SZ_TEX_FREE    4u
#define SZ_TEX_RESIZE  12u
#define SZ_FRAME       24u
#define SZ_STATS       56u
#define SZ_PING        8u
#define SZ_PONG        16u
#define SZ_SYNC        16u
#define SZ_ACK         8u
#define SZ_BYE         4u
#define SZ_CHUNK_HDR   8u
#define SZ_PATCH_HDR   36u
#define SZ_ERROR_HDR   6u
#define SZ_SAMPLES_HDR 16u
#define SZ_POINT       12u

/* --- buffers ---------------------------------------------------------------- */

int wire_buf_reserve(wire_buf *b, size_t extra, ct_error *err)
{
    if (extra > SIZE_MAX / 2 - b->len) return ct_fail(err, CT_ENOMEM, "wire buffer: size overflow");
    size_t need = b->len + extra;
    if (need <= b->cap) return 0;
    size_t cap = b->cap ? b->cap : 256;
    while (cap < need) cap *= 2;
    uint8_t *p = realloc(b->data, cap);
    if (!p) return ct_fail(err, CT_ENOMEM, "wire buffer: out of memory (%zu bytes)", cap);
    b->data = p;
    b->cap = cap;
    return 0;
}

int wire_buf_append(wire_buf *b, const void *data, size_t len, ct_error *err)
{
    int rc = wire_buf_reserve(b, len, err);
    if (rc) return rc;
    if (len) memcpy(b->data + b->len, data, len);
    b->len += len;
    return 0;
}

void wire_buf_consume(wire_buf *b, size_t n)
{
    if (n >= b->len) {
        b->len = 0;
        return;
    }
    memmove(b->data, b->data + n, b->len - n);
    b->len -= n;
}

void wire_buf_free(wire_buf *b)
{
    free(b->data);
    b->data = NULL;
    b->len = b->cap = 0;
}

void wire_scratch_free(wire_scratch *s)
{
    free(s->data);
    s->data = NULL;
    s->cap = 0;
}

static int scratch_get(wire_scratch *s, size_t n, ct_error *err)
{
    if (n <= s->cap) return 0;
    /* Scratch holds whole decompressed messages; n is already bounded by a
     * per-type maximum, so growing to exactly n is safe. */
    uint8_t *p = realloc(s->data, n);
    if (!p) return ct_fail(err, CT_ENOMEM, "wire: out of memory for %zu bytes of scratch", n);
    s->data = p;
    s->cap = n;
    return 0;
}

/* --- types ------------------------------------------------------------------ */

const char *wire_type_name(unsigned type)
{
    static const char *const names[WIRE_TYPE_COUNT] = {
        [WIRE_AUTH] = "AUTH", [WIRE_SETTINGS] = "SETTINGS", [WIRE_SCENE_BEGIN] = "SCENE_BEGIN",
        [WIRE_SCENE_CHUNK] = "SCENE_CHUNK", [WIRE_SCENE_END] = "SCENE_END", [WIRE_CAMERA] = "CAMERA",
        [WIRE_TEX_ALLOC] = "TEX_ALLOC", [WIRE_TEX_PROJECTION] = "TEX_PROJECTION",
        [WIRE_TEX_FREE] = "TEX_FREE", [WIRE_TEX_PATCH] = "TEX_PATCH", [WIRE_FRAME] = "FRAME",
        [WIRE_STATS] = "STATS", [WIRE_ERROR] = "ERROR", [WIRE_PING] = "PING", [WIRE_PONG] = "PONG",
        [WIRE_BYE] = "BYE", [WIRE_SAMPLES] = "SAMPLES", [WIRE_SYNC] = "SYNC", [WIRE_ACK] = "ACK",
        [WIRE_TEX_RESIZE] = "TEX_RESIZE",
    };
    if (type >= WIRE_TYPE_COUNT || !names[type]) return "?";
    return names[type];
}

/* Fixed size of a body, 0 for variable-size types and unknown types. */
static size_t fixed_size(unsigned type)
{
    switch (type) {
    case WIRE_AUTH: return SZ_AUTH;
    case WIRE_SETTINGS: return SZ_SETTINGS;
    case WIRE_SCENE_BEGIN: return SZ_SCENE_BEGIN;
    case WIRE_SCENE_END: return SZ_SCENE_END;
    case WIRE_CAMERA: return SZ_CAMERA;
    case WIRE_TEX_ALLOC: return SZ_TEX_ALLOC;
    case WIRE_TEX_PROJECTION: return SZ_TEX_PROJ;
    case WIRE_TEX_FREE: return SZ_TEX_FREE;
    case WIRE_TEX_RESIZE: return SZ_TEX_RESIZE;
    case WIRE_FRAME: return SZ_FRAME;
    case WIRE_STATS: return SZ_STATS;
    case WIRE_PING: return SZ_PING;
    case WIRE_PONG: return SZ_PONG;
    case WIRE_BYE: return SZ_BYE;
    case WIRE_SYNC: return SZ_SYNC;
    case WIRE_ACK: return SZ_ACK;
    default: return 0;
    }
}

size_t wire_max_body(unsigned type)
{
    switch (type) {
    case WIRE_SCENE_CHUNK: return SZ_CHUNK_HDR + LZ4_COMPRESSBOUND(WIRE_SCENE_CHUNK_RAW);
    case WIRE_TEX_PATCH: return SZ_PATCH_HDR + LZ4_COMPRESSBOUND(WIRE_PATCH_MAX_TEXELS * 6u);
    case WIRE_ERROR: return SZ_ERROR_HDR + WIRE_ERROR_TEXT_MAX;
    case WIRE_SAMPLES: return SZ_SAMPLES_HDR + (size_t)SZ_POINT * WIRE_SAMPLES_MAX_POINTS;
    default: return fixed_size(type);
    }
}

static bool printable(const char *s, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)s[i] < 0x20 || (unsigned char)s[i] > 0x7e) return false;
    return true;
}

void wire_make_error(wire_msg *m, uint32_t code, const char *text)
{
    memset(m, 0, sizeof *m);
    m->type = WIRE_ERROR;
    m->u.error.code = code;
    size_t n = text ? strlen(text) : 0;
    if (n > WIRE_ERROR_TEXT_MAX) n = WIRE_ERROR_TEXT_MAX;
    for (size_t i = 0; i < n; i++) {
        unsigned char c = (unsigned char)text[i];
        m->u.error.text[i] = (c < 0x20 || c > 0x7e) ? '?' : (char)c;
    }
    m->u.error.text[n] = '\0';
}

/* The checks every message passes on both sides. who: "peer X" text for errors. */
static int validate(const wire_msg *m, const char *who, ct_error *err)
{
    switch (m->type) {
    case WIRE_AUTH:
    case WIRE_SCENE_END:
    case WIRE_TEX_FREE:
    case WIRE_PING:
    case WIRE_PONG:
    case WIRE_SYNC:
    case WIRE_ACK:
        return 0;
    case WIRE_SETTINGS:
        if (m->u.settings.flags != 0)
            return ct_fail(err, CT_EPROTO, "%s: SETTINGS flags 0x%x unknown", who, m->u.settings.flags);
        if (m->u.settings.samples_per_frame > WIRE_SPF_MAX)
            return ct_fail(err, CT_EPROTO, "%s: SETTINGS samples per frame %u over the limit %u", who,
                           m->u.settings.samples_per_frame, WIRE_SPF_MAX);
        return 0;
    case WIRE_SCENE_BEGIN: {
        const wire_scene_begin *b = &m->u.scene_begin;
        if (b->flags & ~(uint32_t)WIRE_SCENE_CACHED)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_BEGIN flags 0x%x unknown", who, b->flags);
        if (b->nverts > WIRE_SCENE_MAX_VERTS || b->ntris > WIRE_SCENE_MAX_TRIS ||
            b->nnodes > WIRE_SCENE_MAX_NODES)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_BEGIN counts %u vertices, %u triangles, %u nodes over the limits",
                           who, b->nverts, b->ntris, b->nnodes);
        if (b->raw_size == 0 || b->raw_size > WIRE_SCENE_MAX_RAW)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_BEGIN payload size %llu out of range", who,
                           (unsigned long long)b->raw_size);
        if (!wire_scene_size_fits(b->raw_size, b->nverts, b->ntris, b->nnodes))
            return ct_fail(err, CT_EPROTO, "%s: SCENE_BEGIN payload size %llu does not match its counts", who,
                           (unsigned long long)b->raw_size);
        uint64_t want = (b->flags & WIRE_SCENE_CACHED)
                            ? 0
                            : (b->raw_size + WIRE_SCENE_CHUNK_RAW - 1) / WIRE_SCENE_CHUNK_RAW;
        if (b->nchunks != want)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_BEGIN announces %u chunks, expected %llu", who,
                           b->nchunks, (unsigned long long)want);
        return 0;
    }
    case WIRE_SCENE_CHUNK:
        if (m->u.scene_chunk.len == 0 || m->u.scene_chunk.len > WIRE_SCENE_CHUNK_RAW)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_CHUNK length %u out of range 1..%u", who,
                           m->u.scene_chunk.len, WIRE_SCENE_CHUNK_RAW);
        if (m->u.scene_chunk.index >= WIRE_SCENE_MAX_CHUNKS)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_CHUNK index %u over the limit", who,
                           m->u.scene_chunk.index);
        return 0;
    case WIRE_CAMERA: {
        const wire_camera *c = &m->u.camera;
        if (c->width == 0 || c->height == 0 || c->width > WIRE_IMAGE_MAX_DIM || c->height > WIRE_IMAGE_MAX_DIM)
            return ct_fail(err, CT_EPROTO, "%s: CAMERA image size %ux%u out of range", who, c->width, c->height);
        char why[96];
        if (!cam_valid(&c->cam, why, sizeof why)) return ct_fail(err, CT_EPROTO, "%s: CAMERA %s", who, why);
        return 0;
    }
    case WIRE_TEX_ALLOC: {
        const wire_tex_alloc *a = &m->u.tex_alloc;
        if (a->width == 0 || a->height == 0 || a->width > WIRE_TEX_MAX_DIM || a->height > WIRE_TEX_MAX_DIM)
            return ct_fail(err, CT_EPROTO, "%s: TEX_ALLOC size %ux%u out of range", who, a->width, a->height);
        if (a->proj != WIRE_PROJ_OBJECT_PARALLEL && a->proj != WIRE_PROJ_CAMERA_PERSPECTIVE)
            return ct_fail(err, CT_EPROTO, "%s: TEX_ALLOC projection kind %u unknown", who, a->proj);
        return 0;
    }
    case WIRE_TEX_RESIZE: {
        /* (whether it is an exact change of the texture's size, the
         * receiver checks: it knows the size) */
        const wire_tex_resize *r = &m->u.tex_resize;
        if (r->width == 0 || r->height == 0 || r->width > WIRE_TEX_MAX_DIM || r->height > WIRE_TEX_MAX_DIM)
            return ct_fail(err, CT_EPROTO, "%s: TEX_RESIZE size %ux%u out of range", who, r->width, r->height);
        return 0;
    }
    case WIRE_TEX_PROJECTION:
        for (int i = 0; i < 16; i++)
            if (!isfinite(m->u.tex_projection.world_to_tex.m[i / 4][i % 4]))
                return ct_fail(err, CT_EPROTO, "%s: TEX_PROJECTION has a non-finite value", who);
        return 0;
    case WIRE_TEX_PATCH: {
        const wire_tex_patch *p = &m->u.tex_patch;
        if (p->w == 0 || p->h == 0 || p->w > WIRE_TEX_MAX_DIM || p->h > WIRE_TEX_MAX_DIM ||
            (uint64_t)p->w * p->h > WIRE_PATCH_MAX_TEXELS)
            return ct_fail(err, CT_EPROTO, "%s: TEX_PATCH size %ux%u out of range", who, p->w, p->h);
        if (p->x > WIRE_TEX_MAX_DIM - p->w || p->y > WIRE_TEX_MAX_DIM - p->h)
            return ct_fail(err, CT_EPROTO, "%s: TEX_PATCH rectangle at %u,%u outside any texture", who, p->x, p->y);
        if (p->encoding != WIRE_PATCH_RAW && p->encoding != WIRE_PATCH_LZ4)
            return ct_fail(err, CT_EPROTO, "%s: TEX_PATCH encoding %u unknown", who, p->encoding);
        return 0;
    }
    case WIRE_FRAME:
        if (m->u.frame.flags & ~(uint32_t)WIRE_FLAG_ALL_POSITIVE)
            return ct_fail(err, CT_EPROTO, "%s: FRAME flags 0x%x unknown", who, m->u.frame.flags);
        return 0;
    case WIRE_STATS: {
        const wire_stats *s = &m->u.stats;
        if (s->flags & ~(uint32_t)WIRE_FLAG_ALL_POSITIVE)
            return ct_fail(err, CT_EPROTO, "%s: STATS flags 0x%x unknown", who, s->flags);
        if (!isfinite(s->samples_per_s) || !isfinite(s->coverage) || !isfinite(s->bytes_per_s) ||
            !isfinite(s->t_render) || !isfinite(s->t_sample) || !isfinite(s->t_texture))
            return ct_fail(err, CT_EPROTO, "%s: STATS has a non-finite value", who);
        return 0;
    }
    case WIRE_ERROR: {
        size_t n = strnlen(m->u.error.text, WIRE_ERROR_TEXT_MAX + 1);
        if (m->u.error.code < WIRE_ERR_PROTOCOL || m->u.error.code > WIRE_ERR_LIMIT)
            return ct_fail(err, CT_EPROTO, "%s: ERROR code %u unknown", who, m->u.error.code);
        if (n > WIRE_ERROR_TEXT_MAX || !printable(m->u.error.text, n))
            return ct_fail(err, CT_EPROTO, "%s: ERROR text is not printable ASCII of at most %u bytes", who,
                           WIRE_ERROR_TEXT_MAX);
        return 0;
    }
    case WIRE_BYE:
        if (m->u.bye.reason > WIRE_BYE_DONE)
            return ct_fail(err, CT_EPROTO, "%s: BYE reason %u unknown", who, m->u.bye.reason);
        return 0;
    case WIRE_SAMPLES: {
        const wire_samples *p = &m->u.samples;
        if (p->count > WIRE_SAMPLES_MAX_POINTS)
            return ct_fail(err, CT_EPROTO, "%s: SAMPLES count %u over the limit %u", who, p->count,
                           WIRE_SAMPLES_MAX_POINTS);
        for (size_t i = 0; i < 3 * (size_t)p->count; i++)
            if (!isfinite(p->xyz[i]))
                return ct_fail(err, CT_EPROTO, "%s: SAMPLES point %zu has a non-finite coordinate", who, i / 3);
        return 0;
    }
    default:
        return ct_fail(err, CT_EPROTO, "%s: message type %u unknown", who, m->type);
    }
}

/* --- encode ----------------------------------------------------------------- */

/* Appends header + LZ4 body for the two compressed types. hdr_len bytes of
 * fixed header fields are already in fixed[]. */
static int encode_compressed(unsigned type, const uint8_t *fixed, size_t hdr_len, const uint8_t *raw,
                             size_t raw_len, wire_buf *out, ct_error *err)
{
    size_t bound = (size_t)LZ4_compressBound((int)raw_len);
    int rc = wire_buf_reserve(out, WIRE_HEADER_SIZE + hdr_len + bound, err);
    if (rc) return rc;
    uint8_t *f = out->data + out->len;
    int clen = LZ4_compress_default((const char *)raw, (char *)f + WIRE_HEADER_SIZE + hdr_len, (int)raw_len,
                                    (int)bound);
    if (clen <= 0) return ct_fail(err, CT_ESYS, "wire: LZ4 compression of %zu bytes failed", raw_len);
    size_t body = hdr_len + (size_t)clen;
    if (body > wire_max_body(type))
        return ct_fail(err, CT_EINVAL, "wire: %s body of %zu bytes over the limit", wire_type_name(type), body);
    wio_put_u16(f, (uint16_t)type);
    wio_put_u16(f + 2, 0);
    wio_put_u32(f + 4, (uint32_t)body);
    memcpy(f + WIRE_HEADER_SIZE, fixed, hdr_len);
    out->len += WIRE_HEADER_SIZE + body;
    return 0;
}

int wire_encode(const wire_msg *m, wire_buf *out, ct_error *err)
{
    int rc = validate(m, "encode", err);
    if (rc) return rc;

    if (m->type == WIRE_SCENE_CHUNK) {
        uint8_t fixed[SZ_CHUNK_HDR];
        wio_put_u32(fixed, m->u.scene_chunk.index);
        wio_put_u32(fixed + 4, m->u.scene_chunk.len);
        return encode_compressed(WIRE_SCENE_CHUNK, fixed, sizeof fixed, m->u.scene_chunk.data,
                                 m->u.scene_chunk.len, out, err);
    }
    if (m->type == WIRE_TEX_PATCH) return wire_encode_patch(&m->u.tex_patch, NULL, NULL, out, NULL, err);

    size_t body = fixed_size(m->type);
    if (m->type == WIRE_ERROR) body = SZ_ERROR_HDR + strlen(m->u.error.text);
    if (m->type == WIRE_SAMPLES) body = SZ_SAMPLES_HDR + (size_t)SZ_POINT * m->u.samples.count;
    rc = wire_buf_reserve(out, WIRE_HEADER_SIZE + body, err);
    if (rc) return rc;
    wio_w w = {out->data + out->len};
    ww_u16(&w, m->type);
    ww_u16(&w, 0);
    ww_u32(&w, (uint32_t)body);
    switch (m->type) {
    case WIRE_AUTH: ww_bytes(&w, m->u.auth.mac, WIRE_MAC_SIZE); break;
    case WIRE_SETTINGS:
        ww_u32(&w, m->u.settings.samples_per_frame);
        ww_u32(&w, m->u.settings.flags);
        ww_bytes(&w, m->u.settings.cached_scene, WIRE_HASH_SIZE);
        break;
    case WIRE_SCENE_BEGIN: {
        const wire_scene_begin *b = &m->u.scene_begin;
        ww_bytes(&w, b->hash, WIRE_HASH_SIZE);
        ww_u64(&w, b->scene_hash);
        ww_u64(&w, b->raw_size);
        ww_u32(&w, b->nverts);
        ww_u32(&w, b->ntris);
        ww_u32(&w, b->nnodes);
        ww_u32(&w, b->nchunks);
        ww_u32(&w, b->flags);
        break;
    }
    case WIRE_SCENE_END: ww_bytes(&w, m->u.scene_end.hash, WIRE_HASH_SIZE); break;
    case WIRE_CAMERA:
        ww_u32(&w, m->u.camera.epoch);
        ww_u32(&w, m->u.camera.width);
        ww_u32(&w, m->u.camera.height);
        ww_camera(&w, &m->u.camera.cam);
        break;
    case WIRE_TEX_ALLOC:
        ww_u32(&w, m->u.tex_alloc.tex);
        ww_u32(&w, m->u.tex_alloc.node);
        ww_u32(&w, m->u.tex_alloc.width);
        ww_u32(&w, m->u.tex_alloc.height);
        ww_u32(&w, m->u.tex_alloc.proj);
        break;
    case WIRE_TEX_PROJECTION:
        ww_u32(&w, m->u.tex_projection.tex);
        ww_u32(&w, m->u.tex_projection.epoch);
        for (int i = 0; i < 16; i++) ww_f32(&w, m->u.tex_projection.world_to_tex.m[i / 4][i % 4]);
        break;
    case WIRE_TEX_FREE: ww_u32(&w, m->u.tex_free.tex); break;
    case WIRE_TEX_RESIZE:
        ww_u32(&w, m->u.tex_resize.tex);
        ww_u32(&w, m->u.tex_resize.width);
        ww_u32(&w, m->u.tex_resize.height);
        break;
    case WIRE_FRAME:
        ww_u64(&w, m->u.frame.frame);
        ww_u32(&w, m->u.frame.epoch);
        ww_u32(&w, m->u.frame.flags);
        ww_u32(&w, m->u.frame.samples);
        ww_u32(&w, m->u.frame.patches);
        break;
    case WIRE_STATS: {
        const wire_stats *s = &m->u.stats;
        ww_u32(&w, s->epoch);
        ww_u32(&w, s->flags);
        ww_u64(&w, s->samples_total);
        ww_f32(&w, s->samples_per_s);
        ww_u32(&w, s->queue_len);
        ww_f32(&w, s->coverage);
        ww_u32(&w, s->textures);
        ww_u64(&w, s->texel_bytes);
        ww_f32(&w, s->bytes_per_s);
        ww_f32(&w, s->t_render);
        ww_f32(&w, s->t_sample);
        ww_f32(&w, s->t_texture);
        break;
    }
    case WIRE_ERROR: {
        size_t n = strlen(m->u.error.text);
        ww_u32(&w, m->u.error.code);
        ww_u16(&w, (uint16_t)n);
        ww_bytes(&w, m->u.error.text, n);
        break;
    }
    case WIRE_PING: ww_u64(&w, m->u.ping.token); break;
    case WIRE_PONG:
        ww_u64(&w, m->u.ping.token);
        ww_u64(&w, m->u.ping.clock_us);
        break;
    case WIRE_BYE: ww_u32(&w, m->u.bye.reason); break;
    case WIRE_SYNC:
        ww_u64(&w, m->u.sync.seq);
        ww_u64(&w, m->u.sync.clock_us);
        break;
    case WIRE_ACK: ww_u64(&w, m->u.ack.seq); break;
    case WIRE_SAMPLES:
        ww_u32(&w, m->u.samples.epoch);
        ww_u32(&w, m->u.samples.count);
        ww_u64(&w, m->u.samples.dropped);
        for (size_t i = 0; i < 3 * (size_t)m->u.samples.count; i++) ww_f32(&w, m->u.samples.xyz[i]);
        break;
    default: break; /* validate() rejected unknown types */
    }
    out->len += WIRE_HEADER_SIZE + body;
    return 0;
}

/* Rows of a patch's own texels (wire_encode of a TEX_PATCH message). */
static void texel_rows(void *ctx, uint32_t row, uint8_t *dst)
{
    const wire_tex_patch *p = ctx;
    const uint16_t *src = p->texels + (size_t)row * p->w * 3;
    for (size_t i = 0; i < (size_t)p->w * 3; i++) wio_put_u16(dst + 2 * i, src[i]);
}

int wire_encode_patch(const wire_tex_patch *p, wire_patch_rows_fn rows, void *ctx, wire_buf *out,
                      wire_scratch *scratch, ct_error *err)
{
    wire_msg m = {.type = WIRE_TEX_PATCH};
    m.u.tex_patch = *p;
    int rc = validate(&m, "encode", err);
    if (rc) return rc;
    if (!rows) {
        rows = texel_rows;
        ctx = (void *)p;
    }
    uint8_t fixed[SZ_PATCH_HDR];
    wio_w w = {fixed};
    ww_u32(&w, p->tex);
    ww_u32(&w, p->x);
    ww_u32(&w, p->y);
    ww_u32(&w, p->w);
    ww_u32(&w, p->h);
    ww_u32(&w, p->encoding);
    ww_u32(&w, p->samples);
    ww_u64(&w, p->stamp_us);
    size_t row_bytes = (size_t)p->w * 6, raw = row_bytes * p->h;
    if (p->encoding == WIRE_PATCH_RAW) {
        size_t body = SZ_PATCH_HDR + raw;
        if ((rc = wire_buf_reserve(out, WIRE_HEADER_SIZE + body, err))) return rc;
        uint8_t *f = out->data + out->len;
        wio_put_u16(f, WIRE_TEX_PATCH);
        wio_put_u16(f + 2, 0);
        wio_put_u32(f + 4, (uint32_t)body);
        memcpy(f + WIRE_HEADER_SIZE, fixed, SZ_PATCH_HDR);
        uint8_t *d = f + WIRE_HEADER_SIZE + SZ_PATCH_HDR;
        for (uint32_t j = 0; j < p->h; j++) rows(ctx, j, d + j * row_bytes);
        out->len += WIRE_HEADER_SIZE + body;
        return 0;
    }
    wire_scratch local = {0};
    wire_scratch *sc = scratch ? scratch : &local;
    if ((rc = scratch_get(sc, raw, err)) == 0) {
        for (uint32_t j = 0; j < p->h; j++) rows(ctx, j, sc->data + j * row_bytes);
        rc = encode_compressed(WIRE_TEX_PATCH, fixed, sizeof fixed, sc->data, raw, out, err);
    }
    wire_scratch_free(&local);
    return rc;
}

/* --- decode ----------------------------------------------------------------- */

int wire_parse_header(const uint8_t hdr[WIRE_HEADER_SIZE], const char *peer, unsigned *type,
                      uint32_t *body_len, ct_error *err)
{
    unsigned t = wio_get_u16(hdr);
    unsigned flags = wio_get_u16(hdr + 2);
    uint32_t len = wio_get_u32(hdr + 4);
    size_t max = wire_max_body(t);
    if (max == 0) return ct_fail(err, CT_EPROTO, "%s: message type %u unknown", peer, t);
    if (flags != 0)
        return ct_fail(err, CT_EPROTO, "%s: %s header flags 0x%x unknown", peer, wire_type_name(t), flags);
    size_t fixed = fixed_size(t);
    if (fixed && len != fixed)
        return ct_fail(err, CT_EPROTO, "%s: %s body length %u, expected %zu", peer, wire_type_name(t), len, fixed);
    if (len > max)
        return ct_fail(err, CT_EPROTO, "%s: %s body length %u over the limit %zu", peer, wire_type_name(t), len,
                       max);
    *type = t;
    *body_len = len;
    return 0;
}

/* Decompresses exactly raw_len bytes into scratch. */
static int unpack(const uint8_t *src, size_t clen, size_t raw_len, const char *peer, const char *what,
                  wire_scratch *scratch, ct_error *err)
{
    int rc = scratch_get(scratch, raw_len, err);
    if (rc) return rc;
    int n = LZ4_decompress_safe((const char *)src, (char *)scratch->data, (int)clen, (int)raw_len);
    if (n < 0 || (size_t)n != raw_len)
        return ct_fail(err, CT_EPROTO, "%s: %s data does not decompress to %zu bytes", peer, what, raw_len);
    return 0;
}

int wire_decode_body(unsigned type, const uint8_t *body, size_t len, const char *peer, wire_msg *out,
                     wire_scratch *scratch, ct_error *err)
{
    memset(out, 0, sizeof *out);
    out->type = (uint16_t)type;
    size_t fixed = fixed_size(type);
    if (fixed && len != fixed)
        return ct_fail(err, CT_EPROTO, "%s: %s body length %zu, expected %zu", peer, wire_type_name(type), len,
                       fixed);
    if (len > wire_max_body(type))
        return ct_fail(err, CT_EPROTO, "%s: %s body length %zu over the limit %zu", peer, wire_type_name(type),
                       len, wire_max_body(type));
    wio_r r = {body, len, false};
    int rc;
    switch (type) {
    case WIRE_AUTH: wr_bytes(&r, out->u.auth.mac, WIRE_MAC_SIZE); break;
    case WIRE_SETTINGS:
        out->u.settings.samples_per_frame = wr_u32(&r);
        out->u.settings.flags = wr_u32(&r);
        wr_bytes(&r, out->u.settings.cached_scene, WIRE_HASH_SIZE);
        break;
    case WIRE_SCENE_BEGIN: {
        wire_scene_begin *b = &out->u.scene_begin;
        wr_bytes(&r, b->hash, WIRE_HASH_SIZE);
        b->scene_hash = wr_u64(&r);
        b->raw_size = wr_u64(&r);
        b->nverts = wr_u32(&r);
        b->ntris = wr_u32(&r);
        b->nnodes = wr_u32(&r);
        b->nchunks = wr_u32(&r);
        b->flags = wr_u32(&r);
        break;
    }
    case WIRE_SCENE_CHUNK: {
        wire_scene_chunk *c = &out->u.scene_chunk;
        c->index = wr_u32(&r);
        c->len = wr_u32(&r);
        if (r.bad)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_CHUNK body of %zu bytes is truncated", peer, len);
        if ((rc = validate(out, peer, err))) return rc;
        if ((rc = unpack(r.p, r.left, c->len, peer, "SCENE_CHUNK", scratch, err))) return rc;
        c->data = scratch->data;
        return 0;
    }
    case WIRE_SCENE_END: wr_bytes(&r, out->u.scene_end.hash, WIRE_HASH_SIZE); break;
    case WIRE_CAMERA:
        out->u.camera.epoch = wr_u32(&r);
        out->u.camera.width = wr_u32(&r);
        out->u.camera.height = wr_u32(&r);
        out->u.camera.cam = wr_camera(&r);
        break;
    case WIRE_TEX_ALLOC:
        out->u.tex_alloc.tex = wr_u32(&r);
        out->u.tex_alloc.node = wr_u32(&r);
        out->u.tex_alloc.width = wr_u32(&r);
        out->u.tex_alloc.height = wr_u32(&r);
        out->u.tex_alloc.proj = wr_u32(&r);
        break;
    case WIRE_TEX_PROJECTION:
        out->u.tex_projection.tex = wr_u32(&r);
        out->u.tex_projection.epoch = wr_u32(&r);
        for (int i = 0; i < 16; i++) out->u.tex_projection.world_to_tex.m[i / 4][i % 4] = wr_f32(&r);
        break;
    case WIRE_TEX_FREE: out->u.tex_free.tex = wr_u32(&r); break;
    case WIRE_TEX_RESIZE:
        out->u.tex_resize.tex = wr_u32(&r);
        out->u.tex_resize.width = wr_u32(&r);
        out->u.tex_resize.height = wr_u32(&r);
        break;
    case WIRE_TEX_PATCH: {
        wire_tex_patch *p = &out->u.tex_patch;
        p->tex = wr_u32(&r);
        p->x = wr_u32(&r);
        p->y = wr_u32(&r);
        p->w = wr_u32(&r);
        p->h = wr_u32(&r);
        p->encoding = wr_u32(&r);
        p->samples = wr_u32(&r);
        p->stamp_us = wr_u64(&r);
        if (r.bad) return ct_fail(err, CT_EPROTO, "%s: TEX_PATCH body of %zu bytes is truncated", peer, len);
        if ((rc = validate(out, peer, err))) return rc;
        size_t n = (size_t)p->w * p->h * 3;
        if (p->encoding == WIRE_PATCH_LZ4) {
            if ((rc = unpack(r.p, r.left, n * 2, peer, "TEX_PATCH", scratch, err))) return rc;
        } else {
            if (r.left != n * 2)
                return ct_fail(err, CT_EPROTO, "%s: raw TEX_PATCH of %ux%u texels has %zu data bytes, expected %zu",
                               peer, p->w, p->h, r.left, n * 2);
            if ((rc = scratch_get(scratch, n * 2, err))) return rc;
            memcpy(scratch->data, r.p, n * 2);
        }
        /* In place, little-endian to native: element i reads bytes 2i, 2i+1
         * before writing them (a no-op loop on little-endian hosts). */
        uint16_t *t = (uint16_t *)(void *)scratch->data;
        for (size_t i = 0; i < n; i++) t[i] = wio_get_u16(scratch->data + 2 * i);
        p->texels = t;
        return 0;
    }
    case WIRE_FRAME:
        out->u.frame.frame = wr_u64(&r);
        out->u.frame.epoch = wr_u32(&r);
        out->u.frame.flags = wr_u32(&r);
        out->u.frame.samples = wr_u32(&r);
        out->u.frame.patches = wr_u32(&r);
        break;
    case WIRE_STATS: {
        wire_stats *s = &out->u.stats;
        s->epoch = wr_u32(&r);
        s->flags = wr_u32(&r);
        s->samples_total = wr_u64(&r);
        s->samples_per_s = wr_f32(&r);
        s->queue_len = wr_u32(&r);
        s->coverage = wr_f32(&r);
        s->textures = wr_u32(&r);
        s->texel_bytes = wr_u64(&r);
        s->bytes_per_s = wr_f32(&r);
        s->t_render = wr_f32(&r);
        s->t_sample = wr_f32(&r);
        s->t_texture = wr_f32(&r);
        break;
    }
    case WIRE_ERROR: {
        out->u.error.code = wr_u32(&r);
        uint16_t n = wr_u16(&r);
        if (r.bad) return ct_fail(err, CT_EPROTO, "%s: ERROR body of %zu bytes is truncated", peer, len);
        if (n != r.left)
            return ct_fail(err, CT_EPROTO, "%s: ERROR text length %u does not match the body (%zu bytes left)",
                           peer, n, r.left);
        if (n > WIRE_ERROR_TEXT_MAX)
            return ct_fail(err, CT_EPROTO, "%s: ERROR text length %u over the limit %u", peer, n,
                           WIRE_ERROR_TEXT_MAX);
        wr_bytes(&r, out->u.error.text, n);
        out->u.error.text[n] = '\0';
        if (memchr(out->u.error.text, 0, n))
            return ct_fail(err, CT_EPROTO, "%s: ERROR text is not printable ASCII of at most %u bytes", peer,
                           WIRE_ERROR_TEXT_MAX);
        break;
    }
    case WIRE_PING: out->u.ping.token = wr_u64(&r); break;
    case WIRE_PONG:
        out->u.ping.token = wr_u64(&r);
        out->u.ping.clock_us = wr_u64(&r);
        break;
    case WIRE_BYE: out->u.bye.reason = wr_u32(&r); break;
    case WIRE_SYNC:
        out->u.sync.seq = wr_u64(&r);
        out->u.sync.clock_us = wr_u64(&r);
        break;
    case WIRE_ACK: out->u.ack.seq = wr_u64(&r); break;
    case WIRE_SAMPLES: {
        wire_samples *p = &out->u.samples;
        p->epoch = wr_u32(&r);
        p->count = wr_u32(&r);
        p->dropped = wr_u64(&r);
        if (r.bad) return ct_fail(err, CT_EPROTO, "%s: SAMPLES body of %zu bytes is truncated", peer, len);
        /* The count is checked against the body before anything is read or allocated. */
        if ((uint64_t)p->count * SZ_POINT != r.left)
            return ct_fail(err, CT_EPROTO, "%s: SAMPLES count %u does not match the body (%zu bytes of points)",
                           peer, p->count, r.left);
        size_t n = 3 * (size_t)p->count;
        if ((rc = scratch_get(scratch, n * sizeof(float) + 1, err))) return rc;
        float *f = (float *)(void *)scratch->data;
        for (size_t i = 0; i < n; i++) f[i] = wr_f32(&r);
        p->xyz = f;
        break;
    }
    default: return ct_fail(err, CT_EPROTO, "%s: message type %u unknown", peer, type);
    }
    if (r.bad) return ct_fail(err, CT_EPROTO, "%s: %s body of %zu bytes is truncated", peer, wire_type_name(type), len);
    if (r.left) return ct_fail(err, CT_EPROTO, "%s: %s body has %zu trailing bytes", peer, wire_type_name(type), r.left);
    return validate(out, peer, err);
}

int wire_decode(const uint8_t *buf, size_t len, const char *peer, wire_msg *out, wire_scratch *scratch,
                ct_error *err)
{
    if (len < WIRE_HEADER_SIZE)
        return ct_fail(err, CT_EPROTO, "%s: frame of %zu bytes is shorter than a header", peer, len);
    unsigned type;
    uint32_t body;
    int rc = wire_parse_header(buf, peer, &type, &body, err);
    if (rc) return rc;
    if (len - WIRE_HEADER_SIZE != body)
        return ct_fail(err, CT_EPROTO, "%s: %s frame has %zu body bytes, header says %u", peer,
                       wire_type_name(type), len - WIRE_HEADER_SIZE, body);
    return wire_decode_body(type, buf + WIRE_HEADER_SIZE, body, peer, out, scratch, err);
}
