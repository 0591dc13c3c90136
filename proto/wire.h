/* wire.h: the display socket protocol's messages and their byte encoding
 * (docs/protocol.md is the specification): the frame header, one struct per
 * message, pure encode/decode functions, the incremental per-connection
 * decoder, half-float conversion and the SCENE payload (mesh + radiosity +
 * node table, LZ4 in chunks, BLAKE2b content hash). Every integer and float
 * is written little-endian field by field; no struct is ever copied onto the
 * wire. Every length is checked against the buffer and a per-type maximum
 * before use. The handshake (magic, version, build id, HMAC) is in auth.h. */
#ifndef CT_PROTO_WIRE_H
#define CT_PROTO_WIRE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/radmesh.h"
#include "common/vecmath.h"

#define WIRE_VERSION        5u          /* 2: SAMPLES; 3: the scene's material table; 4: raw or LZ4 patches
                                           with stamps, SYNC/ACK flow control, PONG clock, CAMERA from the master;
                                           5: TEX_RESIZE, valid zero texels sent as -0 */
#define WIRE_HEADER_SIZE    8u          /* u16 type, u16 flags (0), u32 body length */
#define WIRE_HASH_SIZE      32u         /* BLAKE2b-256 content hash of a SCENE payload */
#define WIRE_MAC_SIZE       32u         /* HMAC-SHA256 */

/* Limits (docs/protocol.md, "Limits"). */
#define WIRE_TEX_MAX_DIM        16384u          /* texture width/height */
#define WIRE_PATCH_MAX_TEXELS   (1u << 20)      /* w*h of one TEX_PATCH */
#define WIRE_IMAGE_MAX_DIM      16384u          /* CAMERA image width/height */
#define WIRE_ERROR_TEXT_MAX     200u            /* ERROR reason bytes */
#define WIRE_SCENE_CHUNK_RAW    (1u << 20)      /* uncompressed bytes per SCENE_CHUNK */
#define WIRE_SCENE_MAX_RAW      (1024ull << 20) /* whole uncompressed SCENE payload */
#define WIRE_SCENE_MAX_VERTS    (1u << 25)
#define WIRE_SCENE_MAX_TRIS     (1u << 25)
#define WIRE_SCENE_MAX_NODES    (1u << 20)
#define WIRE_SCENE_MAX_CHUNKS   1024u           /* = MAX_RAW / CHUNK_RAW */
#define WIRE_SAMPLES_MAX_POINTS 65536u          /* world points in one SAMPLES */
#define WIRE_SPF_MAX            (1u << 24)      /* SETTINGS samples per frame */

/* Message types (u16 on the wire; explicit values, never reuse one). */
typedef enum wire_type {
    WIRE_AUTH           = 1,   /* handshake: HMAC proof, both directions */
    WIRE_SETTINGS       = 2,   /* display -> master: lockstep K, cached scene */
    WIRE_SCENE_BEGIN    = 3,   /* master -> display */
    WIRE_SCENE_CHUNK    = 4,   /* master -> display */
    WIRE_SCENE_END      = 5,   /* master -> display */
    WIRE_CAMERA         = 6,   /* display -> master: its view; master -> display: a view to start from */
    WIRE_TEX_ALLOC      = 7,   /* master -> display */
    WIRE_TEX_PROJECTION = 8,   /* master -> display */
    WIRE_TEX_FREE       = 9,   /* master -> display */
    WIRE_TEX_PATCH      = 10,  /* master -> display */
    WIRE_FRAME          = 11,  /* master -> display */
    WIRE_STATS          = 12,  /* master -> display */
    WIRE_ERROR          = 13,  /* either direction, then the sender closes */
    WIRE_PING           = 14,  /* either direction */
    WIRE_PONG           = 15,  /* answer to PING */
    WIRE_BYE            = 16,  /* either direction: orderly close */
    WIRE_SAMPLES        = 17,  /* master -> display: hit points of inserted samples (droppable) */
    WIRE_SYNC           = 18,  /* master -> display: end of texture update n (free running) */
    WIRE_ACK            = 19,  /* display -> master: every update up to n is applied */
    WIRE_TEX_RESIZE     = 20,  /* master -> display: an exact resolution change the display derives */
    WIRE_TYPE_COUNT     = 21
} wire_type;

/* Texture projection kinds (§3.2), u32 on the wire. */
typedef enum wire_proj {
    WIRE_PROJ_OBJECT_PARALLEL    = 1,  /* object-local parallel along the node normal */
    WIRE_PROJ_CAMERA_PERSPECTIVE = 2   /* camera-local perspective from the eye */
} wire_proj;

/* ERROR codes, u32 on the wire. */
typedef enum wire_errcode {
    WIRE_ERR_PROTOCOL = 1,  /* malformed or unexpected message */
    WIRE_ERR_AUTH     = 2,  /* authentication failed */
    WIRE_ERR_VERSION  = 3,  /* version or build id mismatch */
    WIRE_ERR_BUSY     = 4,  /* the master already serves a display */
    WIRE_ERR_INTERNAL = 5,  /* the sender failed (out of memory, ...) */
    WIRE_ERR_LIMIT    = 6   /* a limit was exceeded (queue, sizes) */
} wire_errcode;

/* TEX_PATCH texel encodings, u32 on the wire. */
typedef enum wire_patch_enc {
    WIRE_PATCH_RAW = 0,  /* 6·w·h bytes of little-endian halves */
    WIRE_PATCH_LZ4 = 1   /* one LZ4 block that decompresses to those bytes */
} wire_patch_enc;

/* BYE reasons, u32 on the wire. */
typedef enum wire_bye_reason {
    WIRE_BYE_QUIT     = 0,  /* the user closed the display / ended the run */
    WIRE_BYE_SHUTDOWN = 1,  /* the master is shutting down */
    WIRE_BYE_DONE     = 2   /* a scripted run finished */
} wire_bye_reason;

/* FRAME / STATS flags. */
enum {
    WIRE_FLAG_ALL_POSITIVE = 1u << 0  /* every correction is >= 0: skip pass 3 (§4) */
};

/* SCENE_BEGIN flags. */
enum {
    WIRE_SCENE_CACHED = 1u << 0  /* the display has this hash cached: no chunks follow */
};

typedef struct wire_auth {
    uint8_t mac[WIRE_MAC_SIZE];
} wire_auth;

typedef struct wire_settings {
    uint32_t samples_per_frame;            /* lockstep K; 0 = free running */
    uint32_t flags;                        /* reserved, 0 */
    uint8_t cached_scene[WIRE_HASH_SIZE];  /* a scene the display has cached; zeros = none */
} wire_settings;

typedef struct wire_scene_begin {
    uint8_t hash[WIRE_HASH_SIZE];  /* BLAKE2b-256 of the uncompressed payload */
    uint64_t scene_hash;           /* ct_radmesh.scene_hash (informative) */
    uint64_t raw_size;             /* uncompressed payload bytes */
    uint32_t nverts, ntris, nnodes;
    uint32_t nchunks;              /* SCENE_CHUNKs that follow (0 when CACHED) */
    uint32_t flags;                /* WIRE_SCENE_* */
} wire_scene_begin;

typedef struct wire_scene_chunk {
    uint32_t index;         /* 0 .. nchunks-1, in order */
    uint32_t len;           /* uncompressed bytes in data */
    const uint8_t *data;    /* uncompressed payload bytes [index*CHUNK_RAW, +len) */
} wire_scene_chunk;

typedef struct wire_scene_end {
    uint8_t hash[WIRE_HASH_SIZE];  /* repeats SCENE_BEGIN's hash */
} wire_scene_end;

typedef struct wire_camera {
    uint32_t epoch;          /* increases by one per camera change */
    uint32_t width, height;  /* image size in pixels */
    ct_camera cam;
} wire_camera;

typedef struct wire_tex_alloc {
    uint32_t tex;            /* texture id (chosen by the master, unique while allocated) */
    uint32_t node;           /* radiosity mesh node the texture corrects */
    uint32_t width, height;  /* texels */
    uint32_t proj;           /* wire_proj */
} wire_tex_alloc;

typedef struct wire_tex_projection {
    uint32_t tex;
    uint32_t epoch;          /* camera epoch the projection belongs to */
    mat4 world_to_tex;       /* world -> texture [0,1]^2 (homogeneous, m[row][col]) */
} wire_tex_projection;

typedef struct wire_tex_free {
    uint32_t tex;
} wire_tex_free;

/* Each side kept, doubled or halved (odd sides round up), not both kept:
 * the display computes the new texels from its own (docs/protocol.md). */
typedef struct wire_tex_resize {
    uint32_t tex;
    uint32_t width, height;  /* the new size in texels */
} wire_tex_resize;

/* Whether w x h -> nw x nh is an exact resize, the sizes a TEX_RESIZE may
 * carry: each side kept or doubled (not both kept), else each kept or
 * halved (odd sides round up). The master's resolution changes of this
 * kind have fixed weights (master/ctex_tex.c), which the display computes
 * from its own texels (display/disp_rescale.c). */
static inline bool wire_tex_resize_exact(int w, int h, int nw, int nh)
{
    if (w < 1 || h < 1 || (nw == w && nh == h)) return false;
    bool up = (nw == 2 * w || nw == w) && (nh == 2 * h || nh == h);
    bool down = (nw == (w + 1) / 2 || nw == w) && (nh == (h + 1) / 2 || nh == h);
    return up || down;
}

typedef struct wire_tex_patch {
    uint32_t tex;
    uint32_t x, y, w, h;       /* texel rectangle, inside the texture */
    const uint16_t *texels;    /* w*h*3 IEEE half floats (RGB), rows top to bottom */
    uint32_t encoding;         /* wire_patch_enc the texels travel in */
    uint32_t samples;          /* samples inserted here since the last patch of these texels (lag weight) */
    uint64_t stamp_us;         /* master clock (us) of the oldest change in these texels not sent before */
} wire_tex_patch;

typedef struct wire_frame {
    uint64_t frame;     /* lockstep frame k: every patch of frame k was sent before */
    uint32_t epoch;     /* camera epoch of the frame */
    uint32_t flags;     /* WIRE_FLAG_* */
    uint32_t samples;   /* samples splatted in this frame */
    uint32_t patches;   /* TEX_PATCH messages of this frame */
} wire_frame;

typedef struct wire_stats {
    uint32_t epoch;
    uint32_t flags;             /* WIRE_FLAG_* */
    uint64_t samples_total;
    float samples_per_s;
    uint32_t queue_len;         /* requests waiting */
    float coverage;             /* fraction of screen pixels with a sample, 0..1 */
    uint32_t textures;          /* allocated correction textures */
    uint64_t texel_bytes;       /* texel memory of those textures */
    float bytes_per_s;          /* bytes sent to the display */
    float t_render, t_sample, t_texture;  /* time balance, fractions summing to <= 1 */
} wire_stats;

typedef struct wire_error_msg {
    uint32_t code;                          /* wire_errcode */
    char text[WIRE_ERROR_TEXT_MAX + 1];     /* printable ASCII, NUL-terminated */
} wire_error_msg;

typedef struct wire_ping {
    uint64_t token;     /* echoed by PONG */
    uint64_t clock_us;  /* PONG only: the answering side's clock when it answered (us) */
} wire_ping;

typedef struct wire_bye {
    uint32_t reason;  /* wire_bye_reason */
} wire_bye;

typedef struct wire_samples {
    uint32_t epoch;      /* the display's camera epoch the samples were traced for */
    uint32_t count;      /* points, <= WIRE_SAMPLES_MAX_POINTS */
    uint64_t dropped;    /* points the master dropped on this connection so far (back-pressure) */
    const float *xyz;    /* 3 * count floats: world hit points */
} wire_samples;

typedef struct wire_sync {
    uint64_t seq;        /* update number: 1, 2, ... per connection */
    uint64_t clock_us;   /* master clock when the update was made (us) */
} wire_sync;

typedef struct wire_ack {
    uint64_t seq;        /* the newest SYNC whose update the display has applied */
} wire_ack;

/* One decoded (or to-be-encoded) message. Pointers in a decoded message
 * point into the decoder's scratch memory and stay valid until its next call. */
typedef struct wire_msg {
    uint16_t type;  /* wire_type */
    union {
        wire_auth auth;
        wire_settings settings;
        wire_scene_begin scene_begin;
        wire_scene_chunk scene_chunk;
        wire_scene_end scene_end;
        wire_camera camera;
        wire_tex_alloc tex_alloc;
        wire_tex_projection tex_projection;
        wire_tex_free tex_free;
        wire_tex_resize tex_resize;
        wire_tex_patch tex_patch;
        wire_frame frame;
        wire_stats stats;
        wire_error_msg error;
        wire_ping ping;   /* PING and PONG */
        wire_bye bye;
        wire_samples samples;
        wire_sync sync;
        wire_ack ack;
    } u;
} wire_msg;

/* A growable byte buffer (encoder output, send queues). */
typedef struct wire_buf {
    uint8_t *data;
    size_t len, cap;
} wire_buf;

/* Scratch memory a decode may fill (decompressed patches and chunks). */
typedef struct wire_scratch {
    uint8_t *data;
    size_t cap;
} wire_scratch;

/* Status of the incremental decoder besides negative CT_E* errors. */
enum {
    WIRE_OK        = 0,  /* one message decoded */
    WIRE_NEED_MORE = 1   /* not a whole frame yet: feed more bytes */
};

/* --- buffers -------------------------------------------------------------- */

/* Makes room for extra more bytes. */
int wire_buf_reserve(wire_buf *b, size_t extra, ct_error *err);
/* Appends bytes. */
int wire_buf_append(wire_buf *b, const void *data, size_t len, ct_error *err);
/* Drops the first n bytes. */
void wire_buf_consume(wire_buf *b, size_t n);
/* Frees the memory and zeroes the buffer. */
void wire_buf_free(wire_buf *b);
/* Frees scratch memory. */
void wire_scratch_free(wire_scratch *s);

/* --- messages ------------------------------------------------------------- */

/* Name of a message type ("TEX_PATCH"), "?" when unknown. */
const char *wire_type_name(unsigned type);

/* Largest body a message of this type may have (0 for an unknown type). */
size_t wire_max_body(unsigned type);

/* Fills an ERROR message; text is cut to the maximum and non-printable bytes
 * become '?', so any reason string can be sent. */
void wire_make_error(wire_msg *m, uint32_t code, const char *text);

/* Appends the frame (header + body) of m to out. Fails (CT_EINVAL) on a
 * message the decoder would reject, so what is sent always decodes. */
int wire_encode(const wire_msg *m, wire_buf *out, ct_error *err);

/* Writes row j (0 .. h-1) of a patch's rectangle as 6·w little-endian bytes. */
typedef void (*wire_patch_rows_fn)(void *ctx, uint32_t row, uint8_t *dst);

/* Appends a TEX_PATCH frame whose texels come from rows() instead of
 * p->texels, in p->encoding: raw texels are written straight into out (one
 * copy from the caller's storage to the frame), LZ4 ones through scratch. */
int wire_encode_patch(const wire_tex_patch *p, wire_patch_rows_fn rows, void *ctx, wire_buf *out,
                      wire_scratch *scratch, ct_error *err);

/* Parses a frame header; checks the type, flags and the type's maximum body
 * length. peer names the sender in errors. */
int wire_parse_header(const uint8_t hdr[WIRE_HEADER_SIZE], const char *peer, unsigned *type,
                      uint32_t *body_len, ct_error *err);

/* Decodes one body of the given type (header already checked). Variable data
 * is decompressed into scratch. */
int wire_decode_body(unsigned type, const uint8_t *body, size_t len, const char *peer,
                     wire_msg *out, wire_scratch *scratch, ct_error *err);

/* Decodes exactly one whole frame from buf[0..len) (len must match the frame). */
int wire_decode(const uint8_t *buf, size_t len, const char *peer, wire_msg *out,
                wire_scratch *scratch, ct_error *err);

/* --- incremental decoder --------------------------------------------------- */

typedef struct wire_decoder wire_decoder;

/* A decoder for one connection; peer (e.g. "tcp:10.0.0.2:4000") names it in errors. */
int wire_decoder_new(const char *peer, wire_decoder **out, ct_error *err);
/* Frees the decoder (NULL is fine). */
void wire_decoder_free(wire_decoder *d);
/* Appends received bytes (copies them). */
int wire_decoder_feed(wire_decoder *d, const void *data, size_t len, ct_error *err);
/* WIRE_OK with *out filled, WIRE_NEED_MORE, or a negative error (sticky: every
 * later call answers the same error). */
int wire_decoder_next(wire_decoder *d, wire_msg *out, ct_error *err);
/* Bytes buffered but not yet decoded (a non-zero value at EOF = cut message). */
size_t wire_decoder_pending(const wire_decoder *d);
/* Bytes the frame being received needs in total (header + body), 0 when unknown. */
size_t wire_decoder_frame_size(const wire_decoder *d);

/* --- half floats ---------------------------------------------------------- */

/* IEEE 754 binary16 from a float (round to nearest even; overflow -> inf). */
uint16_t wire_half_from_float(float f);
/* Float from binary16 (exact). */
float wire_half_to_float(uint16_t h);

/* --- SCENE payload ---------------------------------------------------------- */

/* The whole uncompressed SCENE payload of a mesh, its hash and message headers.
 * The master builds it once and sends chunk messages from it. */
typedef struct wire_scene_tx {
    uint8_t *raw;
    uint64_t raw_size;
    uint8_t hash[WIRE_HASH_SIZE];
    wire_scene_begin begin;
} wire_scene_tx;

/* Serializes m (checking it the way a receiver will) and hashes it. */
int wire_scene_tx_init(wire_scene_tx *tx, const ct_radmesh *m, ct_error *err);
/* SCENE_BEGIN; cached=true (the display announced this hash) sends no chunks. */
void wire_scene_tx_begin(const wire_scene_tx *tx, bool cached, wire_msg *out);
/* SCENE_CHUNK number index (< begin.nchunks), pointing into tx. */
void wire_scene_tx_chunk(const wire_scene_tx *tx, uint32_t index, wire_msg *out);
/* SCENE_END. */
void wire_scene_tx_end(const wire_scene_tx *tx, wire_msg *out);
/* Frees the payload. */
void wire_scene_tx_free(wire_scene_tx *tx);

/* Reassembles a SCENE from its messages on the display side. */
typedef struct wire_scene_rx wire_scene_rx;

/* A receiver (peer names the master in errors). */
int wire_scene_rx_new(const char *peer, wire_scene_rx **out, ct_error *err);
/* Frees it. */
void wire_scene_rx_free(wire_scene_rx *rx);
/* Feeds SCENE_BEGIN / SCENE_CHUNK / SCENE_END in order. Returns 0 while more is
 * expected, 1 after a valid SCENE_END (the mesh is ready, or the cached hash
 * is to be loaded when begin.flags has WIRE_SCENE_CACHED), negative on error. */
int wire_scene_rx_feed(wire_scene_rx *rx, const wire_msg *m, ct_error *err);
/* After 1: the SCENE_BEGIN that started the scene (hash, counts, flags). */
const wire_scene_begin *wire_scene_rx_info(const wire_scene_rx *rx);
/* After 1 (not cached): moves the decoded mesh into *m (caller rmesh_free's it). */
int wire_scene_rx_take(wire_scene_rx *rx, ct_radmesh *m, ct_error *err);
/* The uncompressed payload after 1 (for a display-side cache file). */
const uint8_t *wire_scene_rx_raw(const wire_scene_rx *rx, uint64_t *size);

/* Parses a whole uncompressed payload (from the wire or a cache file) into a
 * mesh, checking every count, index and float. */
int wire_scene_parse(const uint8_t *raw, size_t size, const char *peer, ct_radmesh *m,
                     ct_error *err);
/* Bytes of the payload of a mesh with these counts. */
uint64_t wire_scene_payload_size(uint64_t nverts, uint64_t ntris, uint64_t nnodes, uint64_t nmats);
/* Whether a payload of raw_size bytes fits these counts with some number of
 * materials (at most RMESH_MAX_MATS): what SCENE_BEGIN, which does not
 * count the materials, can be checked against. */
bool wire_scene_size_fits(uint64_t raw_size, uint64_t nverts, uint64_t ntris, uint64_t nnodes);
/* Lower-case hex of a content hash (65 bytes with the NUL), e.g. for a cache file name. */
void wire_hash_hex(const uint8_t hash[WIRE_HASH_SIZE], char out[2 * WIRE_HASH_SIZE + 1]);
/* The content hash of a payload. */
void wire_scene_hash(const uint8_t *raw, size_t size, uint8_t out[WIRE_HASH_SIZE]);

#endif
