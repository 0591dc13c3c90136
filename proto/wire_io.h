/* wire_io.h: little-endian field writers and a bounds-checked reader, shared
 * by the encoders and decoders in proto/ (internal to proto/). Floats travel
 * as their IEEE 754 bit pattern. A reader never reads past its end: a short
 * read sets `bad` and yields zeros, and the caller checks `bad` once. */
#ifndef CT_PROTO_WIRE_IO_H
#define CT_PROTO_WIRE_IO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "common/camera.h"
#include "common/vecmath.h"

static inline void wio_put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static inline void wio_put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static inline void wio_put_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static inline void wio_put_f32(uint8_t *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    wio_put_u32(p, u);
}
static inline uint16_t wio_get_u16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}
static inline uint32_t wio_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static inline uint64_t wio_get_u64(const uint8_t *p)
{
    return (uint64_t)wio_get_u32(p) | ((uint64_t)wio_get_u32(p + 4) << 32);
}
static inline float wio_get_f32(const uint8_t *p)
{
    uint32_t u = wio_get_u32(p);
    float f;
    memcpy(&f, &u, 4);
    return f;
}

/* A writer into memory the caller sized exactly (encoders compute sizes first). */
typedef struct wio_w {
    uint8_t *p;
} wio_w;

static inline void ww_u8(wio_w *w, uint8_t v) { *w->p++ = v; }
static inline void ww_u16(wio_w *w, uint16_t v) { wio_put_u16(w->p, v); w->p += 2; }
static inline void ww_u32(wio_w *w, uint32_t v) { wio_put_u32(w->p, v); w->p += 4; }
static inline void ww_i32(wio_w *w, int32_t v) { wio_put_u32(w->p, (uint32_t)v); w->p += 4; }
static inline void ww_u64(wio_w *w, uint64_t v) { wio_put_u64(w->p, v); w->p += 8; }
static inline void ww_f32(wio_w *w, float v) { wio_put_f32(w->p, v); w->p += 4; }
static inline void ww_bytes(wio_w *w, const void *d, size_t n)
{
    if (n) memcpy(w->p, d, n);
    w->p += n;
}
static inline void ww_vec3(wio_w *w, vec3 v) { ww_f32(w, v.x); ww_f32(w, v.y); ww_f32(w, v.z); }

/* A bounds-checked reader. */
typedef struct wio_r {
    const uint8_t *p;
    size_t left;
    bool bad;
} wio_r;

static inline const uint8_t *wr_take(wio_r *r, size_t n)
{
    if (r->bad || r->left < n) {
        r->bad = true;
        return NULL;
    }
    const uint8_t *q = r->p;
    r->p += n;
    r->left -= n;
    return q;
}
static inline uint8_t wr_u8(wio_r *r) { const uint8_t *q = wr_take(r, 1); return q ? q[0] : 0; }
static inline uint16_t wr_u16(wio_r *r) { const uint8_t *q = wr_take(r, 2); return q ? wio_get_u16(q) : 0; }
static inline uint32_t wr_u32(wio_r *r) { const uint8_t *q = wr_take(r, 4); return q ? wio_get_u32(q) : 0; }
static inline int32_t wr_i32(wio_r *r) { return (int32_t)wr_u32(r); }
static inline uint64_t wr_u64(wio_r *r) { const uint8_t *q = wr_take(r, 8); return q ? wio_get_u64(q) : 0; }
static inline float wr_f32(wio_r *r) { const uint8_t *q = wr_take(r, 4); return q ? wio_get_f32(q) : 0.0f; }
static inline void wr_bytes(wio_r *r, void *d, size_t n)
{
    const uint8_t *q = wr_take(r, n);
    if (q && n) memcpy(d, q, n);
    else if (n) memset(d, 0, n);
}
static inline vec3 wr_vec3(wio_r *r)
{
    vec3 v;
    v.x = wr_f32(r);
    v.y = wr_f32(r);
    v.z = wr_f32(r);
    return v;
}

/* A camera: eye, orientation quaternion (w, x, y, z), vertical fov; 32 bytes. */
static inline void ww_camera(wio_w *w, const ct_camera *c)
{
    ww_vec3(w, c->eye);
    ww_f32(w, c->orient.w);
    ww_f32(w, c->orient.x);
    ww_f32(w, c->orient.y);
    ww_f32(w, c->orient.z);
    ww_f32(w, c->fov_y);
}

static inline ct_camera wr_camera(wio_r *r)
{
    ct_camera c;
    c.eye = wr_vec3(r);
    c.orient.w = wr_f32(r);
    c.orient.x = wr_f32(r);
    c.orient.y = wr_f32(r);
    c.orient.z = wr_f32(r);
    c.fov_y = wr_f32(r);
    return c;
}

#endif
