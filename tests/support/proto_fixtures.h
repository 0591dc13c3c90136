/* proto_fixtures.h: shared test data for the protocol tests and the fuzz
 * targets: one valid message of every display-socket type, a valid
 * radiosity mesh of a chosen size, and the fuzz target bodies (so the
 * libFuzzer harnesses and the corpus replay test run the same code). */
#ifndef CT_TESTS_PROTO_FIXTURES_H
#define CT_TESTS_PROTO_FIXTURES_H

#include <stddef.h>
#include <stdint.h>

#include "common/radmesh.h"
#include "proto/auth.h"
#include "proto/wire.h"

#define FX_NMSG 26

/* Fills out[] with FX_NMSG valid messages covering every type (patches and
 * chunks point to static storage); returns the count. */
size_t fx_messages(wire_msg *out);

/* A token holding the bytes of s (shorter than AUTH_TOKEN_MAX). */
auth_token fx_token(const char *s);

/* A valid mesh: a strip of nquads quads (2 triangles each) in 3 nodes. */
int fx_mesh(ct_radmesh *m, uint32_t nquads);

/* Fuzz bodies: each feeds arbitrary bytes to one decoder and returns 0. */
int fx_fuzz_wire(const uint8_t *data, size_t size);
int fx_fuzz_handshake(const uint8_t *data, size_t size);
int fx_fuzz_scene(const uint8_t *data, size_t size);
int fx_fuzz_mpi(const uint8_t *data, size_t size);

/* Writes seed inputs for a fuzz target ("wire", "handshake", "scene", "mpi")
 * through emit; returns the count. */
size_t fx_fuzz_seeds(const char *target, void (*emit)(const uint8_t *data, size_t size, void *ctx), void *ctx);

#endif
