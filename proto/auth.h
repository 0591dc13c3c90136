/* auth.h: the display socket handshake and authentication: the 64-byte HELLO
 * both sides send first (magic with "\r\n\x1a", protocol version, role, flags,
 * build id, nonce), checked before anything else, then, when the master asks
 * for it, an HMAC-SHA256 challenge-response over both HELLOs with a shared
 * token (mutual: each side proves the token to the other). A pure state
 * machine over bytes: it never touches a socket (chan.h drives it). Also the
 * token helpers (--token-file / CORRTEX_TOKEN). Spec: docs/protocol.md. */
#ifndef CT_PROTO_AUTH_H
#define CT_PROTO_AUTH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/error.h"
#include "proto/wire.h"

#define AUTH_MAGIC        "\x89" "CTX\r\n\x1a\n"  /* 8 bytes, PNG-style */
#define AUTH_MAGIC_SIZE   8u
#define AUTH_HELLO_SIZE   64u
#define AUTH_BUILD_ID_LEN 20u
#define AUTH_NONCE_SIZE   32u
#define AUTH_TOKEN_MIN    16u     /* bytes; shorter tokens are refused */
#define AUTH_TOKEN_MAX    1024u
#define AUTH_TOKEN_ENV    "CORRTEX_TOKEN"

/* The build id both sides must share; packagers may pass -DCT_BUILD_ID="...". */
#ifndef CT_BUILD_ID
#define CT_BUILD_ID "corrtex-proto-1"
#endif

/* Roles (u8 in HELLO). */
typedef enum auth_role {
    AUTH_ROLE_MASTER  = 1,  /* the server: rank 0 of the MPI job */
    AUTH_ROLE_DISPLAY = 2   /* the client: corrtex-display */
} auth_role;

/* HELLO flags. */
enum {
    AUTH_HELLO_REQUIRE_AUTH = 1u << 0  /* (master) the AUTH exchange follows */
};

/* A shared secret token. */
typedef struct auth_token {
    uint8_t bytes[AUTH_TOKEN_MAX];
    size_t len;
} auth_token;

/* Reads a token file: its bytes without trailing whitespace; refuses a file
 * that group or others may read, an empty or too short token. */
int auth_token_load(const char *path, auth_token *t, ct_error *err);

/* The token from path when not NULL, else from $CORRTEX_TOKEN; *have = false
 * when neither is given. */
int auth_token_get(const char *path, auth_token *t, bool *have, ct_error *err);

/* Overwrites the token's bytes. */
void auth_token_wipe(auth_token *t);

typedef struct auth_config {
    auth_role role;
    const auth_token *token;  /* NULL: none */
    bool require_auth;        /* master: demand AUTH; display: refuse a master that does not */
    const char *peer;         /* the peer's address, for errors */
    const char *build_id;     /* NULL: CT_BUILD_ID */
} auth_config;

typedef struct auth_hs auth_hs;

/* Starts a handshake; our HELLO is queued in the output at once. A master
 * with require_auth needs a token. */
int auth_hs_new(const auth_config *cfg, auth_hs **out, ct_error *err);

/* Frees it (wiping secrets). */
void auth_hs_free(auth_hs *hs);

/* Bytes to send to the peer; the caller removes what it wrote with
 * wire_buf_consume. After a failure it may hold an ERROR frame worth flushing. */
wire_buf *auth_hs_output(auth_hs *hs);

/* Consumes received bytes (*used of len; the rest, after completion, belong
 * to the message decoder). Returns 0 when the handshake is complete,
 * WIRE_NEED_MORE, or a negative error (sticky). */
int auth_hs_input(auth_hs *hs, const uint8_t *data, size_t len, size_t *used, ct_error *err);

/* Fills a 64-byte HELLO (for tests and tools). */
void auth_hello_encode(uint8_t out[AUTH_HELLO_SIZE], auth_role role, uint8_t flags, const char *build_id,
                       const uint8_t nonce[AUTH_NONCE_SIZE]);

/* HMAC-SHA256 proof of `prover` over both HELLOs with the token. */
void auth_mac(const auth_token *t, auth_role prover, const uint8_t master_hello[AUTH_HELLO_SIZE],
              const uint8_t display_hello[AUTH_HELLO_SIZE], uint8_t out[WIRE_MAC_SIZE]);

#endif
