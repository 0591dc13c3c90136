/* srec.h: recordings of sample records (corrtex converge --record FILE),
 * replayed into the master's session by the saturation benchmark
 * (master/tport_replay.h). The file is the 8 magic bytes "CTSREC1\n", then
 * blocks of a u32 little-endian length and one WIRE_MPI_SAMPLES message of
 * that length (proto/wire_mpi.h, docs/protocol.md), so every record is
 * checked as a tracer's batch would be. Owns the srec_ prefix. */
#ifndef CT_PROTO_SREC_H
#define CT_PROTO_SREC_H

#include <stddef.h>

#include "common/error.h"
#include "common/records.h"

/* Writes n samples to path (atomically), in blocks of at most
 * WIRE_MPI_MAX_BATCH. */
int srec_write(const char *path, const ct_sample *s, size_t n, ct_error *err);

/* Reads a recording: *s (malloc'd, caller frees) holds *n samples.
 * CT_EPARSE naming the file and offset for a broken one. */
int srec_read(const char *path, ct_sample **s, size_t *n, ct_error *err);

#endif
