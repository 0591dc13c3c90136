/* records.h: the in-memory records that travel between master and tracers:
 * a sample request and the sample record a tracer returns. Their wire
 * encodings (explicit little-endian, field by field) are in proto/; these
 * structs are never memcpy'd onto a wire. */
#ifndef CT_COMMON_RECORDS_H
#define CT_COMMON_RECORDS_H

#include <stdint.h>

#include "common/vecmath.h"

/* A request for one high-quality sample at a sub-pixel image position. */
typedef struct ct_request {
    uint64_t id;        /* unique per run, increasing in creation order */
    uint64_t parent;    /* id of the request whose sample spawned it, 0 = none */
    uint32_t epoch;     /* camera epoch it was made for */
    float px, py;       /* image position in pixels (camera.h convention) */
    float radius;       /* domain radius s in pixels (§3.7) */
    float priority;     /* larger = sooner */
} ct_request;

/* Flags of a sample record. */
enum {
    CT_SAMPLE_HIT      = 1u << 0,  /* the primary ray hit geometry */
    CT_SAMPLE_EMISSIVE = 1u << 1,  /* the hit surface is an emitter */
    CT_SAMPLE_HAS_BASE = 1u << 2   /* l_base was interpolated on a radiosity mesh */
};

/* The result of tracing one request. */
typedef struct ct_sample {
    uint64_t request_id;
    uint32_t epoch;
    uint32_t flags;     /* CT_SAMPLE_* */
    float px, py;       /* the request's image position */
    uint32_t node;      /* hit part node (scene / radiosity mesh node id) */
    uint32_t tri;       /* hit triangle of the mesh that was intersected */
    float u, v;         /* Embree barycentrics on that triangle */
    vec3 hit;           /* world hit point */
    vec3 l_hq;          /* high-quality radiance */
    vec3 l_base;        /* interactive (Gouraud radiosity) radiance at the hit */
} ct_sample;

#endif
