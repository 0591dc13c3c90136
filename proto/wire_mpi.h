/* wire_mpi.h: the MPI message layouts between the master (rank 0) and the
 * tracer ranks: request batches (camera + epoch header and ct_request
 * records), sample batches (ct_sample records), camera changes and control
 * (shutdown, seed and mode). Encoded like the display protocol: explicit
 * little-endian, field by field, every count checked against the buffer and
 * a maximum; MPI delimits messages, so a buffer must be exactly one message.
 * The MPI transport is proto/mpi_link.h. Spec:
 * docs/protocol.md, "MPI messages". */
#ifndef CT_PROTO_WIRE_MPI_H
#define CT_PROTO_WIRE_MPI_H

#include <stddef.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/records.h"
#include "proto/wire.h"

#define WIRE_MPI_VERSION      1u
#define WIRE_MPI_HEADER_SIZE  8u      /* u16 kind, u16 version, u32 count */
#define WIRE_MPI_MAX_BATCH    65536u  /* records per batch */
#define WIRE_MPI_REQUEST_SIZE 36u     /* bytes per ct_request record */
#define WIRE_MPI_SAMPLE_SIZE  76u     /* bytes per ct_sample record */

/* Message kinds (u16; explicit values). */
typedef enum wire_mpi_kind {
    WIRE_MPI_REQUESTS = 1,  /* master -> tracer */
    WIRE_MPI_SAMPLES  = 2,  /* tracer -> master */
    WIRE_MPI_CAMERA   = 3,  /* master -> tracers */
    WIRE_MPI_CONTROL  = 4   /* master -> tracers */
} wire_mpi_kind;

/* CONTROL operations (u32). */
typedef enum wire_mpi_op {
    WIRE_MPI_OP_SHUTDOWN = 1,  /* finish the current batch and exit */
    WIRE_MPI_OP_CONFIG   = 2   /* set seed, mode and sampling parameters */
} wire_mpi_op;

/* Tracer modes (u32). */
typedef enum wire_mpi_mode {
    WIRE_MPI_MODE_FULL          = 0,  /* full distributed ray tracing */
    WIRE_MPI_MODE_REUSE_DIFFUSE = 1   /* diffuse part from the radiosity solution (§4) */
} wire_mpi_mode;

/* Header of a request batch: the camera the requests were made for. */
typedef struct wire_mpi_requests {
    uint64_t batch;          /* batch id, echoed by the sample batch */
    uint32_t epoch;
    uint32_t width, height;  /* image size of the camera */
    ct_camera cam;
} wire_mpi_requests;

/* Header of a sample batch. */
typedef struct wire_mpi_samples {
    uint64_t batch;          /* the request batch it answers */
    uint32_t rank;           /* the tracer that computed it */
} wire_mpi_samples;

/* A camera change. */
typedef struct wire_mpi_camera {
    uint32_t epoch;
    uint32_t width, height;
    ct_camera cam;
} wire_mpi_camera;

/* Control. */
typedef struct wire_mpi_control {
    uint32_t op;            /* wire_mpi_op */
    uint32_t mode;          /* wire_mpi_mode (CONFIG) */
    uint64_t seed;          /* base seed of the random streams (CONFIG) */
    uint32_t shadow_rays;   /* shadow rays per light sample, >= 1 (CONFIG) */
    uint32_t max_depth;     /* path depth limit, >= 1 (CONFIG) */
} wire_mpi_control;

/* Kind and record count of a message, checking its header and exact size. */
int wire_mpi_peek(const uint8_t *buf, size_t len, const char *peer, unsigned *kind, uint32_t *count,
                  ct_error *err);

/* Encoded size of a request / sample batch of count records. */
size_t wire_mpi_requests_size(uint32_t count);
size_t wire_mpi_samples_size(uint32_t count);

/* Appends a request batch (count <= WIRE_MPI_MAX_BATCH). */
int wire_mpi_encode_requests(const wire_mpi_requests *h, const ct_request *reqs, uint32_t count, wire_buf *out,
                             ct_error *err);
/* Decodes the header of a request batch only (its size checked). */
int wire_mpi_decode_requests_header(const uint8_t *buf, size_t len, const char *peer, wire_mpi_requests *h,
                                    ct_error *err);
/* Decodes a request batch into reqs (capacity cap records); *count set. */
int wire_mpi_decode_requests(const uint8_t *buf, size_t len, const char *peer, wire_mpi_requests *h,
                             ct_request *reqs, uint32_t cap, uint32_t *count, ct_error *err);

/* Appends a sample batch. */
int wire_mpi_encode_samples(const wire_mpi_samples *h, const ct_sample *s, uint32_t count, wire_buf *out,
                            ct_error *err);
/* Decodes a sample batch into s (capacity cap records); *count set. */
int wire_mpi_decode_samples(const uint8_t *buf, size_t len, const char *peer, wire_mpi_samples *h, ct_sample *s,
                            uint32_t cap, uint32_t *count, ct_error *err);

/* Appends / decodes a camera change. */
int wire_mpi_encode_camera(const wire_mpi_camera *c, wire_buf *out, ct_error *err);
int wire_mpi_decode_camera(const uint8_t *buf, size_t len, const char *peer, wire_mpi_camera *c, ct_error *err);

/* Appends / decodes a control message. */
int wire_mpi_encode_control(const wire_mpi_control *c, wire_buf *out, ct_error *err);
int wire_mpi_decode_control(const uint8_t *buf, size_t len, const char *peer, wire_mpi_control *c, ct_error *err);

#endif
