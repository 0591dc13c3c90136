/* wire_mpi.c: encode/decode of the master <-> tracer MPI messages
 * (wire_mpi.h). As on the display socket, one check() per message kind runs
 * before encoding and after decoding. */
#include "proto/wire_mpi.h"

#include <math.h>
#include <string.h>

#include "proto/wire_io.h"

#define REQ_HDR  52u  /* batch u64, epoch, width, height, camera (32) */
#define SMP_HDR  16u  /* batch u64, rank, reserved */
#define CAM_BODY 44u
#define CTL_BODY 24u

static const char *kind_name(unsigned k)
{
    switch (k) {
    case WIRE_MPI_REQUESTS: return "REQUESTS";
    case WIRE_MPI_SAMPLES: return "SAMPLES";
    case WIRE_MPI_CAMERA: return "CAMERA";
    case WIRE_MPI_CONTROL: return "CONTROL";
    default: return "?";
    }
}

size_t wire_mpi_requests_size(uint32_t count)
{
    return WIRE_MPI_HEADER_SIZE + REQ_HDR + (size_t)count * WIRE_MPI_REQUEST_SIZE;
}

size_t wire_mpi_samples_size(uint32_t count)
{
    return WIRE_MPI_HEADER_SIZE + SMP_HDR + (size_t)count * WIRE_MPI_SAMPLE_SIZE;
}

static size_t size_of(unsigned kind, uint32_t count)
{
    switch (kind) {
    case WIRE_MPI_REQUESTS: return wire_mpi_requests_size(count);
    case WIRE_MPI_SAMPLES: return wire_mpi_samples_size(count);
    case WIRE_MPI_CAMERA: return WIRE_MPI_HEADER_SIZE + CAM_BODY;
    case WIRE_MPI_CONTROL: return WIRE_MPI_HEADER_SIZE + CTL_BODY;
    default: return 0;
    }
}

int wire_mpi_peek(const uint8_t *buf, size_t len, const char *peer, unsigned *kind, uint32_t *count, ct_error *err)
{
    if (len < WIRE_MPI_HEADER_SIZE)
        return ct_fail(err, CT_EPROTO, "%s: MPI message of %zu bytes is shorter than its header", peer, len);
    unsigned k = wio_get_u16(buf), v = wio_get_u16(buf + 2);
    uint32_t n = wio_get_u32(buf + 4);
    if (k < WIRE_MPI_REQUESTS || k > WIRE_MPI_CONTROL)
        return ct_fail(err, CT_EPROTO, "%s: MPI message kind %u unknown", peer, k);
    if (v != WIRE_MPI_VERSION)
        return ct_fail(err, CT_EPROTO, "%s: MPI message version %u, expected %u", peer, v, WIRE_MPI_VERSION);
    bool batch = k == WIRE_MPI_REQUESTS || k == WIRE_MPI_SAMPLES;
    if (batch ? n > WIRE_MPI_MAX_BATCH : n != 0)
        return ct_fail(err, CT_EPROTO, "%s: MPI %s count %u out of range", peer, kind_name(k), n);
    size_t want = size_of(k, n);
    if (len != want)
        return ct_fail(err, CT_EPROTO, "%s: MPI %s of %u records is %zu bytes, expected %zu", peer, kind_name(k), n,
                       len, want);
    *kind = k;
    *count = n;
    return 0;
}

static bool cam_ok(uint32_t w, uint32_t h, const ct_camera *c)
{
    return w >= 1 && h >= 1 && w <= WIRE_IMAGE_MAX_DIM && h <= WIRE_IMAGE_MAX_DIM && cam_valid(c, NULL, 0);
}

static int check_request(const ct_request *q, const char *who, uint32_t i, ct_error *err)
{
    if (!isfinite(q->px) || !isfinite(q->py) || !isfinite(q->priority) || !isfinite(q->radius) || q->radius < 0.0f)
        return ct_fail(err, CT_EPROTO, "%s: MPI request %u has a non-finite or negative value", who, i);
    return 0;
}

static int check_sample(const ct_sample *s, const char *who, uint32_t i, ct_error *err)
{
    if (s->flags & ~(uint32_t)(CT_SAMPLE_HIT | CT_SAMPLE_EMISSIVE | CT_SAMPLE_HAS_BASE))
        return ct_fail(err, CT_EPROTO, "%s: MPI sample %u flags 0x%x unknown", who, i, s->flags);
    if (!isfinite(s->px) || !isfinite(s->py) || !isfinite(s->u) || !isfinite(s->v) || !v3_finite(s->hit) ||
        !v3_finite(s->l_hq) || !v3_finite(s->l_base))
        return ct_fail(err, CT_EPROTO, "%s: MPI sample %u has a non-finite value", who, i);
    return 0;
}

static int check_control(const wire_mpi_control *c, const char *who, ct_error *err)
{
    if (c->op != WIRE_MPI_OP_SHUTDOWN && c->op != WIRE_MPI_OP_CONFIG)
        return ct_fail(err, CT_EPROTO, "%s: MPI CONTROL op %u unknown", who, c->op);
    if (c->op == WIRE_MPI_OP_CONFIG) {
        if (c->mode != WIRE_MPI_MODE_FULL && c->mode != WIRE_MPI_MODE_REUSE_DIFFUSE)
            return ct_fail(err, CT_EPROTO, "%s: MPI CONTROL mode %u unknown", who, c->mode);
        if (c->shadow_rays < 1 || c->shadow_rays > 4096 || c->max_depth < 1 || c->max_depth > 64)
            return ct_fail(err, CT_EPROTO, "%s: MPI CONTROL shadow rays %u or depth %u out of range", who,
                           c->shadow_rays, c->max_depth);
    }
    return 0;
}

static uint8_t *start(wire_buf *out, unsigned kind, uint32_t count, ct_error *err)
{
    size_t n = size_of(kind, count);
    if (wire_buf_reserve(out, n, err)) return NULL;
    uint8_t *p = out->data + out->len;
    wio_put_u16(p, (uint16_t)kind);
    wio_put_u16(p + 2, WIRE_MPI_VERSION);
    wio_put_u32(p + 4, count);
    out->len += n;
    return p + WIRE_MPI_HEADER_SIZE;
}

int wire_mpi_encode_requests(const wire_mpi_requests *h, const ct_request *reqs, uint32_t count, wire_buf *out,
                             ct_error *err)
{
    if (count > WIRE_MPI_MAX_BATCH)
        return ct_fail(err, CT_EINVAL, "MPI requests: batch of %u over the limit %u", count, WIRE_MPI_MAX_BATCH);
    if (!cam_ok(h->width, h->height, &h->cam)) return ct_fail(err, CT_EINVAL, "MPI requests: invalid camera");
    for (uint32_t i = 0; i < count; i++) {
        int rc = check_request(&reqs[i], "encode", i, err);
        if (rc) return rc;
    }
    uint8_t *p = start(out, WIRE_MPI_REQUESTS, count, err);
    if (!p) return CT_ENOMEM;
    wio_w w = {p};
    ww_u64(&w, h->batch);
    ww_u32(&w, h->epoch);
    ww_u32(&w, h->width);
    ww_u32(&w, h->height);
    ww_camera(&w, &h->cam);
    for (uint32_t i = 0; i < count; i++) {
        const ct_request *q = &reqs[i];
        ww_u64(&w, q->id);
        ww_u64(&w, q->parent);
        ww_u32(&w, q->epoch);
        ww_f32(&w, q->px);
        ww_f32(&w, q->py);
        ww_f32(&w, q->radius);
        ww_f32(&w, q->priority);
    }
    return 0;
}

/* The header of a REQUESTS message (peeked: kind and exact size checked);
 * *n its record count, r left at the first record. */
static int requests_header(const uint8_t *buf, size_t len, const char *peer, wire_mpi_requests *h, uint32_t *n,
                           wio_r *r, ct_error *err)
{
    unsigned kind;
    int rc = wire_mpi_peek(buf, len, peer, &kind, n, err);
    if (rc) return rc;
    if (kind != WIRE_MPI_REQUESTS)
        return ct_fail(err, CT_EPROTO, "%s: expected an MPI REQUESTS message, got %s", peer, kind_name(kind));
    *r = (wio_r){buf + WIRE_MPI_HEADER_SIZE, len - WIRE_MPI_HEADER_SIZE, false};
    h->batch = wr_u64(r);
    h->epoch = wr_u32(r);
    h->width = wr_u32(r);
    h->height = wr_u32(r);
    h->cam = wr_camera(r);
    if (r->bad || !cam_ok(h->width, h->height, &h->cam))
        return ct_fail(err, CT_EPROTO, "%s: MPI REQUESTS has an invalid camera", peer);
    return 0;
}

int wire_mpi_decode_requests_header(const uint8_t *buf, size_t len, const char *peer, wire_mpi_requests *h,
                                    ct_error *err)
{
    uint32_t n;
    wio_r r;
    return requests_header(buf, len, peer, h, &n, &r, err);
}

int wire_mpi_decode_requests(const uint8_t *buf, size_t len, const char *peer, wire_mpi_requests *h,
                             ct_request *reqs, uint32_t cap, uint32_t *count, ct_error *err)
{
    uint32_t n;
    wio_r r;
    int rc = requests_header(buf, len, peer, h, &n, &r, err);
    if (rc) return rc;
    if (n > cap) return ct_fail(err, CT_EPROTO, "%s: MPI REQUESTS of %u records, room for %u", peer, n, cap);
    for (uint32_t i = 0; i < n; i++) {
        ct_request *q = &reqs[i];
        q->id = wr_u64(&r);
        q->parent = wr_u64(&r);
        q->epoch = wr_u32(&r);
        q->px = wr_f32(&r);
        q->py = wr_f32(&r);
        q->radius = wr_f32(&r);
        q->priority = wr_f32(&r);
        if ((rc = check_request(q, peer, i, err))) return rc;
    }
    *count = n;
    return r.bad || r.left ? ct_fail(err, CT_EPROTO, "%s: MPI REQUESTS size mismatch", peer) : 0;
}

int wire_mpi_encode_samples(const wire_mpi_samples *h, const ct_sample *s, uint32_t count, wire_buf *out,
                            ct_error *err)
{
    if (count > WIRE_MPI_MAX_BATCH)
        return ct_fail(err, CT_EINVAL, "MPI samples: batch of %u over the limit %u", count, WIRE_MPI_MAX_BATCH);
    for (uint32_t i = 0; i < count; i++) {
        int rc = check_sample(&s[i], "encode", i, err);
        if (rc) return rc;
    }
    uint8_t *p = start(out, WIRE_MPI_SAMPLES, count, err);
    if (!p) return CT_ENOMEM;
    wio_w w = {p};
    ww_u64(&w, h->batch);
    ww_u32(&w, h->rank);
    ww_u32(&w, 0);
    for (uint32_t i = 0; i < count; i++) {
        const ct_sample *x = &s[i];
        ww_u64(&w, x->request_id);
        ww_u32(&w, x->epoch);
        ww_u32(&w, x->flags);
        ww_f32(&w, x->px);
        ww_f32(&w, x->py);
        ww_u32(&w, x->node);
        ww_u32(&w, x->tri);
        ww_f32(&w, x->u);
        ww_f32(&w, x->v);
        ww_vec3(&w, x->hit);
        ww_vec3(&w, x->l_hq);
        ww_vec3(&w, x->l_base);
    }
    return 0;
}

int wire_mpi_decode_samples(const uint8_t *buf, size_t len, const char *peer, wire_mpi_samples *h, ct_sample *s,
                            uint32_t cap, uint32_t *count, ct_error *err)
{
    unsigned kind;
    uint32_t n;
    int rc = wire_mpi_peek(buf, len, peer, &kind, &n, err);
    if (rc) return rc;
    if (kind != WIRE_MPI_SAMPLES)
        return ct_fail(err, CT_EPROTO, "%s: expected an MPI SAMPLES message, got %s", peer, kind_name(kind));
    if (n > cap) return ct_fail(err, CT_EPROTO, "%s: MPI SAMPLES of %u records, room for %u", peer, n, cap);
    wio_r r = {buf + WIRE_MPI_HEADER_SIZE, len - WIRE_MPI_HEADER_SIZE, false};
    h->batch = wr_u64(&r);
    h->rank = wr_u32(&r);
    uint32_t reserved = wr_u32(&r);
    if (reserved) return ct_fail(err, CT_EPROTO, "%s: MPI SAMPLES reserved field is %u, not 0", peer, reserved);
    for (uint32_t i = 0; i < n; i++) {
        ct_sample *x = &s[i];
        x->request_id = wr_u64(&r);
        x->epoch = wr_u32(&r);
        x->flags = wr_u32(&r);
        x->px = wr_f32(&r);
        x->py = wr_f32(&r);
        x->node = wr_u32(&r);
        x->tri = wr_u32(&r);
        x->u = wr_f32(&r);
        x->v = wr_f32(&r);
        x->hit = wr_vec3(&r);
        x->l_hq = wr_vec3(&r);
        x->l_base = wr_vec3(&r);
        if ((rc = check_sample(x, peer, i, err))) return rc;
    }
    *count = n;
    return r.bad || r.left ? ct_fail(err, CT_EPROTO, "%s: MPI SAMPLES size mismatch", peer) : 0;
}

int wire_mpi_encode_camera(const wire_mpi_camera *c, wire_buf *out, ct_error *err)
{
    if (!cam_ok(c->width, c->height, &c->cam)) return ct_fail(err, CT_EINVAL, "MPI camera: invalid camera");
    uint8_t *p = start(out, WIRE_MPI_CAMERA, 0, err);
    if (!p) return CT_ENOMEM;
    wio_w w = {p};
    ww_u32(&w, c->epoch);
    ww_u32(&w, c->width);
    ww_u32(&w, c->height);
    ww_camera(&w, &c->cam);
    return 0;
}

int wire_mpi_decode_camera(const uint8_t *buf, size_t len, const char *peer, wire_mpi_camera *c, ct_error *err)
{
    unsigned kind;
    uint32_t n;
    int rc = wire_mpi_peek(buf, len, peer, &kind, &n, err);
    if (rc) return rc;
    if (kind != WIRE_MPI_CAMERA)
        return ct_fail(err, CT_EPROTO, "%s: expected an MPI CAMERA message, got %s", peer, kind_name(kind));
    wio_r r = {buf + WIRE_MPI_HEADER_SIZE, len - WIRE_MPI_HEADER_SIZE, false};
    c->epoch = wr_u32(&r);
    c->width = wr_u32(&r);
    c->height = wr_u32(&r);
    c->cam = wr_camera(&r);
    if (!cam_ok(c->width, c->height, &c->cam))
        return ct_fail(err, CT_EPROTO, "%s: MPI CAMERA has an invalid camera", peer);
    return 0;
}

int wire_mpi_encode_control(const wire_mpi_control *c, wire_buf *out, ct_error *err)
{
    int rc = check_control(c, "encode", err);
    if (rc) return rc;
    uint8_t *p = start(out, WIRE_MPI_CONTROL, 0, err);
    if (!p) return CT_ENOMEM;
    wio_w w = {p};
    ww_u32(&w, c->op);
    ww_u32(&w, c->mode);
    ww_u64(&w, c->seed);
    ww_u32(&w, c->shadow_rays);
    ww_u32(&w, c->max_depth);
    return 0;
}

int wire_mpi_decode_control(const uint8_t *buf, size_t len, const char *peer, wire_mpi_control *c, ct_error *err)
{
    unsigned kind;
    uint32_t n;
    int rc = wire_mpi_peek(buf, len, peer, &kind, &n, err);
    if (rc) return rc;
    if (kind != WIRE_MPI_CONTROL)
        return ct_fail(err, CT_EPROTO, "%s: expected an MPI CONTROL message, got %s", peer, kind_name(kind));
    wio_r r = {buf + WIRE_MPI_HEADER_SIZE, len - WIRE_MPI_HEADER_SIZE, false};
    c->op = wr_u32(&r);
    c->mode = wr_u32(&r);
    c->seed = wr_u64(&r);
    c->shadow_rays = wr_u32(&r);
    c->max_depth = wr_u32(&r);
    return check_control(c, peer, err);
}
