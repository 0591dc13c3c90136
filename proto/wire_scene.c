/* wire_scene.c: the SCENE payload: the interactive solution (radiosity mesh
 * with per-vertex radiance and the node table) serialized little-endian,
 * hashed with BLAKE2b-256 (the display's cache key), cut into chunks of
 * WIRE_SCENE_CHUNK_RAW bytes that travel LZ4-compressed in SCENE_CHUNK
 * messages, and reassembled and checked on the display side. */
#include "proto/wire.h"

#include <math.h>
#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto/wire_io.h"

#define PAYLOAD_HDR 24u   /* nverts, ntris, nnodes, nmats, scene_hash */
#define NODE_SIZE   100u  /* name[64], parent, node_end, material, bounds (6 f32) */
#define MAT_SIZE    16u   /* transmission (3 f32), ior */

uint64_t wire_scene_payload_size(uint64_t nv, uint64_t nt, uint64_t nn, uint64_t nm)
{
    return PAYLOAD_HDR + 48 * nv + 20 * nt + NODE_SIZE * nn + MAT_SIZE * nm;
}

bool wire_scene_size_fits(uint64_t raw_size, uint64_t nv, uint64_t nt, uint64_t nn)
{
    uint64_t base = wire_scene_payload_size(nv, nt, nn, 0);
    return raw_size >= base && (raw_size - base) % MAT_SIZE == 0 && (raw_size - base) / MAT_SIZE <= RMESH_MAX_MATS;
}

void wire_scene_hash(const uint8_t *raw, size_t size, uint8_t out[WIRE_HASH_SIZE])
{
    crypto_generichash(out, WIRE_HASH_SIZE, raw, size, NULL, 0);
}

void wire_hash_hex(const uint8_t hash[WIRE_HASH_SIZE], char out[2 * WIRE_HASH_SIZE + 1])
{
    static const char digits[] = "0123456789abcdef";
    for (unsigned i = 0; i < WIRE_HASH_SIZE; i++) {
        out[2 * i] = digits[hash[i] >> 4];
        out[2 * i + 1] = digits[hash[i] & 15];
    }
    out[2 * WIRE_HASH_SIZE] = '\0';
}

static bool vec_ok(vec3 v)
{
    return isfinite(v.x) && isfinite(v.y) && isfinite(v.z);
}

/* Checks a payload and, when m is not NULL, fills the mesh. */
static int parse_payload(const uint8_t *raw, size_t size, const char *peer, ct_radmesh *m, ct_error *err)
{
    wio_r r = {raw, size, false};
    uint32_t nv = wr_u32(&r), nt = wr_u32(&r), nn = wr_u32(&r), nm = wr_u32(&r);
    uint64_t scene_hash = wr_u64(&r);
    if (r.bad) return ct_fail(err, CT_EPROTO, "%s: scene payload of %zu bytes is truncated", peer, size);
    if (nv > WIRE_SCENE_MAX_VERTS || nt > WIRE_SCENE_MAX_TRIS || nn > WIRE_SCENE_MAX_NODES || nm > RMESH_MAX_MATS)
        return ct_fail(err, CT_EPROTO, "%s: scene counts %u vertices, %u triangles, %u nodes, %u materials over the limits",
                       peer, nv, nt, nn, nm);
    if (wire_scene_payload_size(nv, nt, nn, nm) != size)
        return ct_fail(err, CT_EPROTO, "%s: scene payload is %zu bytes, its counts need %llu", peer, size,
                       (unsigned long long)wire_scene_payload_size(nv, nt, nn, nm));
    /* Nothing to draw or to correct: no master sends that (its scenes have
     * triangles), and the display must not start a run on it. */
    if (nv == 0 || nt == 0 || nn == 0)
        return ct_fail(err, CT_EPROTO, "%s: scene is empty (%u vertices, %u triangles, %u nodes)", peer, nv, nt, nn);
    if (m) {
        int rc = rmesh_alloc(m, nv, nt, nn, err);
        if (rc) return rc;
        m->scene_hash = scene_hash;
    }
    static const char *const vnames[4] = {"position", "normal", "radiance", "direct radiance"};
    for (int a = 0; a < 4; a++) {
        vec3 *dst = !m ? NULL : a == 0 ? m->pos : a == 1 ? m->nrm : a == 2 ? m->rad : m->rad_direct;
        for (uint32_t i = 0; i < nv; i++) {
            vec3 v = wr_vec3(&r);
            if (!vec_ok(v)) {
                if (m) rmesh_free(m);
                return ct_fail(err, CT_EPROTO, "%s: scene vertex %u has a non-finite %s", peer, i, vnames[a]);
            }
            if (dst) dst[i] = v;
        }
    }
    for (uint32_t i = 0; i < 3 * nt; i++) {
        uint32_t v = wr_u32(&r);
        if (v >= nv) {
            if (m) rmesh_free(m);
            return ct_fail(err, CT_EPROTO, "%s: scene triangle %u uses vertex %u of %u", peer, i / 3, v, nv);
        }
        if (m) m->tris[i] = v;
    }
    for (uint32_t i = 0; i < nt; i++) {
        uint32_t n = wr_u32(&r);
        if (n >= nn) {
            if (m) rmesh_free(m);
            return ct_fail(err, CT_EPROTO, "%s: scene triangle %u belongs to node %u of %u", peer, i, n, nn);
        }
        if (m) m->tri_node[i] = n;
    }
    for (uint32_t i = 0; i < nt; i++) {
        uint32_t mat = wr_u32(&r);
        if (m) m->tri_mat[i] = mat;
    }
    /* node_end of each node, to check nesting (preorder: a child ends
     * inside its parent). Read in place from the payload. */
    const uint8_t *node_base = r.p;
    for (uint32_t i = 0; i < nn; i++) {
        char name[SCENE_NAME_LEN];
        wr_bytes(&r, name, SCENE_NAME_LEN);
        int32_t parent = wr_i32(&r);
        uint32_t end = wr_u32(&r), mat = wr_u32(&r);
        bounds3 b;
        b.lo = wr_vec3(&r);
        b.hi = wr_vec3(&r);
        const char *why = NULL;
        size_t len = strnlen(name, SCENE_NAME_LEN);
        if (len == SCENE_NAME_LEN) why = "a name without a terminating NUL";
        for (size_t k = len; !why && k < SCENE_NAME_LEN; k++)
            if (name[k]) why = "bytes after its name's NUL";
        if (!why && (parent < -1 || parent >= (int32_t)i)) why = "a parent out of order";
        if (!why && (end <= i || end > nn)) why = "an end index out of range";
        if (!why && parent >= 0 && end > wio_get_u32(node_base + (size_t)parent * NODE_SIZE + 68))
            why = "an end past its parent's";
        if (!why && (isnan(b.lo.x) || isnan(b.lo.y) || isnan(b.lo.z) || isnan(b.hi.x) || isnan(b.hi.y) ||
                     isnan(b.hi.z)))
            why = "NaN bounds";
        if (why) {
            if (m) rmesh_free(m);
            return ct_fail(err, CT_EPROTO, "%s: scene node %u has %s", peer, i, why);
        }
        if (m) {
            rmesh_node *n = &m->nodes[i];
            memcpy(n->name, name, SCENE_NAME_LEN);
            n->parent = parent;
            n->node_end = end;
            n->material = mat;
            n->bounds = b;
        }
    }
    if (m) {
        m->mats = calloc(nm ? nm : 1, sizeof *m->mats);
        if (!m->mats) {
            rmesh_free(m);
            return ct_fail(err, CT_ENOMEM, "%s: out of memory for %u materials", peer, nm);
        }
        m->nmats = nm;
    }
    for (uint32_t i = 0; i < nm; i++) {
        rmesh_material x;
        x.transmission = wr_vec3(&r);
        x.ior = wr_f32(&r);
        if (!rmesh_material_ok(&x)) {
            if (m) rmesh_free(m);
            return ct_fail(err, CT_EPROTO, "%s: scene material %u has a transmission or index of refraction out of range",
                           peer, i);
        }
        if (m) m->mats[i] = x;
    }
    /* The size check above makes these unreachable; kept as a backstop. */
    if (r.bad || r.left) {
        if (m) rmesh_free(m);
        return ct_fail(err, CT_EPROTO, "%s: scene payload size mismatch", peer);
    }
    return 0;
}

int wire_scene_parse(const uint8_t *raw, size_t size, const char *peer, ct_radmesh *m, ct_error *err)
{
    memset(m, 0, sizeof *m);
    return parse_payload(raw, size, peer, m, err);
}

/* --- sender ----------------------------------------------------------------- */

int wire_scene_tx_init(wire_scene_tx *tx, const ct_radmesh *m, ct_error *err)
{
    memset(tx, 0, sizeof *tx);
    if (m->nverts > WIRE_SCENE_MAX_VERTS || m->ntris > WIRE_SCENE_MAX_TRIS || m->nnodes > WIRE_SCENE_MAX_NODES ||
        m->nmats > RMESH_MAX_MATS)
        return ct_fail(err, CT_ERANGE, "scene: %u vertices, %u triangles, %u nodes, %u materials exceed the protocol limits",
                       m->nverts, m->ntris, m->nnodes, m->nmats);
    uint64_t size = wire_scene_payload_size(m->nverts, m->ntris, m->nnodes, m->nmats);
    if (size > WIRE_SCENE_MAX_RAW)
        return ct_fail(err, CT_ERANGE, "scene: payload of %llu bytes exceeds the protocol limit",
                       (unsigned long long)size);
    uint8_t *raw = malloc(size);
    if (!raw) return ct_fail(err, CT_ENOMEM, "scene: out of memory for a %llu-byte payload", (unsigned long long)size);
    wio_w w = {raw};
    ww_u32(&w, m->nverts);
    ww_u32(&w, m->ntris);
    ww_u32(&w, m->nnodes);
    ww_u32(&w, m->nmats);
    ww_u64(&w, m->scene_hash);
    const vec3 *arrays[4] = {m->pos, m->nrm, m->rad, m->rad_direct};
    for (int a = 0; a < 4; a++)
        for (uint32_t i = 0; i < m->nverts; i++) ww_vec3(&w, arrays[a][i]);
    for (uint32_t i = 0; i < 3 * m->ntris; i++) ww_u32(&w, m->tris[i]);
    for (uint32_t i = 0; i < m->ntris; i++) ww_u32(&w, m->tri_node[i]);
    for (uint32_t i = 0; i < m->ntris; i++) ww_u32(&w, m->tri_mat[i]);
    for (uint32_t i = 0; i < m->nnodes; i++) {
        const rmesh_node *n = &m->nodes[i];
        uint8_t name[SCENE_NAME_LEN] = {0};
        memcpy(name, n->name, strnlen(n->name, SCENE_NAME_LEN - 1)); /* always NUL-terminated */
        ww_bytes(&w, name, SCENE_NAME_LEN);
        ww_i32(&w, n->parent);
        ww_u32(&w, n->node_end);
        ww_u32(&w, n->material);
        ww_vec3(&w, n->bounds.lo);
        ww_vec3(&w, n->bounds.hi);
    }
    for (uint32_t i = 0; i < m->nmats; i++) {
        ww_vec3(&w, m->mats[i].transmission);
        ww_f32(&w, m->mats[i].ior);
    }
    ct_error why;
    int rc = parse_payload(raw, size, "scene", NULL, &why);
    if (rc) {
        free(raw);
        return ct_fail(err, CT_EINVAL, "%s (the mesh cannot be sent)", why.msg);
    }
    tx->raw = raw;
    tx->raw_size = size;
    wire_scene_hash(raw, size, tx->hash);
    wire_scene_begin *b = &tx->begin;
    memcpy(b->hash, tx->hash, WIRE_HASH_SIZE);
    b->scene_hash = m->scene_hash;
    b->raw_size = size;
    b->nverts = m->nverts;
    b->ntris = m->ntris;
    b->nnodes = m->nnodes;
    b->nchunks = (uint32_t)((size + WIRE_SCENE_CHUNK_RAW - 1) / WIRE_SCENE_CHUNK_RAW);
    b->flags = 0;
    return 0;
}

void wire_scene_tx_begin(const wire_scene_tx *tx, bool cached, wire_msg *out)
{
    memset(out, 0, sizeof *out);
    out->type = WIRE_SCENE_BEGIN;
    out->u.scene_begin = tx->begin;
    if (cached) {
        out->u.scene_begin.flags |= WIRE_SCENE_CACHED;
        out->u.scene_begin.nchunks = 0;
    }
}

void wire_scene_tx_chunk(const wire_scene_tx *tx, uint32_t index, wire_msg *out)
{
    memset(out, 0, sizeof *out);
    out->type = WIRE_SCENE_CHUNK;
    uint64_t off = (uint64_t)index * WIRE_SCENE_CHUNK_RAW;
    uint64_t left = off < tx->raw_size ? tx->raw_size - off : 0;
    out->u.scene_chunk.index = index;
    out->u.scene_chunk.len = (uint32_t)(left < WIRE_SCENE_CHUNK_RAW ? left : WIRE_SCENE_CHUNK_RAW);
    out->u.scene_chunk.data = tx->raw + (left ? off : 0);
}

void wire_scene_tx_end(const wire_scene_tx *tx, wire_msg *out)
{
    memset(out, 0, sizeof *out);
    out->type = WIRE_SCENE_END;
    memcpy(out->u.scene_end.hash, tx->hash, WIRE_HASH_SIZE);
}

void wire_scene_tx_free(wire_scene_tx *tx)
{
    free(tx->raw);
    memset(tx, 0, sizeof *tx);
}

/* --- receiver --------------------------------------------------------------- */

enum { RX_IDLE, RX_CHUNKS, RX_DONE };

struct wire_scene_rx {
    char peer[128];
    int state;
    wire_scene_begin begin;
    uint8_t *raw;
    uint32_t next;       /* next expected chunk index */
    ct_radmesh mesh;
    bool have_mesh;
};

int wire_scene_rx_new(const char *peer, wire_scene_rx **out, ct_error *err)
{
    wire_scene_rx *rx = calloc(1, sizeof *rx);
    if (!rx) return ct_fail(err, CT_ENOMEM, "%s: out of memory for a scene receiver", peer);
    snprintf(rx->peer, sizeof rx->peer, "%s", peer ? peer : "peer");
    *out = rx;
    return 0;
}

static void rx_reset(wire_scene_rx *rx)
{
    free(rx->raw);
    rx->raw = NULL;
    if (rx->have_mesh) rmesh_free(&rx->mesh);
    rx->have_mesh = false;
    rx->state = RX_IDLE;
    rx->next = 0;
}

void wire_scene_rx_free(wire_scene_rx *rx)
{
    if (!rx) return;
    rx_reset(rx);
    free(rx);
}

int wire_scene_rx_feed(wire_scene_rx *rx, const wire_msg *m, ct_error *err)
{
    const char *peer = rx->peer;
    switch (m->type) {
    case WIRE_SCENE_BEGIN: {
        if (rx->state == RX_CHUNKS)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_BEGIN before the previous scene ended", peer);
        rx_reset(rx);
        const wire_scene_begin *b = &m->u.scene_begin;
        if (!wire_scene_size_fits(b->raw_size, b->nverts, b->ntris, b->nnodes))
            return ct_fail(err, CT_EPROTO, "%s: SCENE_BEGIN payload size %llu does not match its counts", peer,
                           (unsigned long long)b->raw_size);
        rx->begin = *b;
        if (!(b->flags & WIRE_SCENE_CACHED)) {
            rx->raw = malloc(b->raw_size);
            if (!rx->raw)
                return ct_fail(err, CT_ENOMEM, "%s: out of memory for a %llu-byte scene", peer,
                               (unsigned long long)b->raw_size);
        }
        rx->state = RX_CHUNKS;
        return 0;
    }
    case WIRE_SCENE_CHUNK: {
        const wire_scene_chunk *c = &m->u.scene_chunk;
        if (rx->state != RX_CHUNKS) return ct_fail(err, CT_EPROTO, "%s: SCENE_CHUNK outside a scene", peer);
        if (c->index != rx->next || c->index >= rx->begin.nchunks)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_CHUNK %u out of order (expected %u of %u)", peer, c->index,
                           rx->next, rx->begin.nchunks);
        uint64_t off = (uint64_t)c->index * WIRE_SCENE_CHUNK_RAW;
        uint64_t left = rx->begin.raw_size - off;
        uint32_t want = (uint32_t)(left < WIRE_SCENE_CHUNK_RAW ? left : WIRE_SCENE_CHUNK_RAW);
        if (c->len != want)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_CHUNK %u has %u bytes, expected %u", peer, c->index, c->len,
                           want);
        memcpy(rx->raw + off, c->data, c->len);
        rx->next++;
        return 0;
    }
    case WIRE_SCENE_END: {
        if (rx->state != RX_CHUNKS) return ct_fail(err, CT_EPROTO, "%s: SCENE_END outside a scene", peer);
        if (rx->next != rx->begin.nchunks)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_END after %u of %u chunks", peer, rx->next, rx->begin.nchunks);
        if (memcmp(m->u.scene_end.hash, rx->begin.hash, WIRE_HASH_SIZE) != 0)
            return ct_fail(err, CT_EPROTO, "%s: SCENE_END hash differs from SCENE_BEGIN's", peer);
        if (!(rx->begin.flags & WIRE_SCENE_CACHED)) {
            uint8_t h[WIRE_HASH_SIZE];
            wire_scene_hash(rx->raw, rx->begin.raw_size, h);
            if (memcmp(h, rx->begin.hash, WIRE_HASH_SIZE) != 0)
                return ct_fail(err, CT_EPROTO, "%s: scene payload does not match its content hash", peer);
            int rc = wire_scene_parse(rx->raw, rx->begin.raw_size, peer, &rx->mesh, err);
            if (rc) return rc;
            rx->have_mesh = true;
        }
        rx->state = RX_DONE;
        return 1;
    }
    default:
        return ct_fail(err, CT_EPROTO, "%s: %s is not part of a scene", peer, wire_type_name(m->type));
    }
}

const wire_scene_begin *wire_scene_rx_info(const wire_scene_rx *rx)
{
    return &rx->begin;
}

int wire_scene_rx_take(wire_scene_rx *rx, ct_radmesh *m, ct_error *err)
{
    if (rx->state != RX_DONE || !rx->have_mesh)
        return ct_fail(err, CT_EINVAL, "%s: no received scene mesh to take", rx->peer);
    *m = rx->mesh;
    memset(&rx->mesh, 0, sizeof rx->mesh);
    rx->have_mesh = false;
    return 0;
}

const uint8_t *wire_scene_rx_raw(const wire_scene_rx *rx, uint64_t *size)
{
    if (rx->state != RX_DONE || !rx->raw) {
        *size = 0;
        return NULL;
    }
    *size = rx->begin.raw_size;
    return rx->raw;
}
