/* wire_decoder.c: the incremental decoder over one connection's receive
 * buffer. It holds at most one frame plus what the last read brought; a
 * header is checked (type, flags, per-type maximum) as soon as its 8 bytes
 * are there, so a hostile length never makes it allocate or wait for more
 * than that type's maximum. */
#include "proto/wire.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct wire_decoder {
    char peer[128];
    wire_buf in;
    size_t start;          /* first undecoded byte in `in` */
    wire_scratch scratch;
    int error;             /* sticky error code, 0 when healthy */
    ct_error last;         /* its message */
    size_t frame_size;     /* header + body of the frame being received, 0 = unknown */
};

int wire_decoder_new(const char *peer, wire_decoder **out, ct_error *err)
{
    wire_decoder *d = calloc(1, sizeof *d);
    if (!d) return ct_fail(err, CT_ENOMEM, "%s: out of memory for a decoder", peer);
    snprintf(d->peer, sizeof d->peer, "%s", peer ? peer : "peer");
    *out = d;
    return 0;
}

void wire_decoder_free(wire_decoder *d)
{
    if (!d) return;
    wire_buf_free(&d->in);
    wire_scratch_free(&d->scratch);
    free(d);
}

int wire_decoder_feed(wire_decoder *d, const void *data, size_t len, ct_error *err)
{
    if (d->error) {
        if (err) *err = d->last;
        return d->error;
    }
    /* Drop consumed bytes before growing, so the buffer stays one frame big. */
    if (d->start) {
        wire_buf_consume(&d->in, d->start);
        d->start = 0;
    }
    return wire_buf_append(&d->in, data, len, err);
}

static int fail(wire_decoder *d, int rc, ct_error *err)
{
    d->error = rc;
    if (err) d->last = *err;
    else ct_fail(&d->last, rc, "%s: decode failed", d->peer);
    return rc;
}

int wire_decoder_next(wire_decoder *d, wire_msg *out, ct_error *err)
{
    ct_error local;
    if (!err) err = &local;
    if (d->error) {
        *err = d->last;
        return d->error;
    }
    size_t avail = d->in.len - d->start;
    if (avail < WIRE_HEADER_SIZE) {
        d->frame_size = 0;
        return WIRE_NEED_MORE;
    }
    const uint8_t *p = d->in.data + d->start;
    unsigned type;
    uint32_t body;
    int rc = wire_parse_header(p, d->peer, &type, &body, err);
    if (rc) return fail(d, rc, err);
    d->frame_size = WIRE_HEADER_SIZE + (size_t)body;
    if (avail < d->frame_size) return WIRE_NEED_MORE;
    rc = wire_decode_body(type, p + WIRE_HEADER_SIZE, body, d->peer, out, &d->scratch, err);
    if (rc) return fail(d, rc, err);
    d->start += d->frame_size;
    d->frame_size = 0;
    if (d->start == d->in.len) {
        d->in.len = 0;
        d->start = 0;
    }
    return WIRE_OK;
}

size_t wire_decoder_pending(const wire_decoder *d)
{
    return d->in.len - d->start;
}

size_t wire_decoder_frame_size(const wire_decoder *d)
{
    return d->frame_size;
}
