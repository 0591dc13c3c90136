/* auth.c: HELLO checks, HMAC challenge-response and token files (auth.h). */
#include "proto/auth.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "proto/wire_io.h"

#define AUTH_LABEL "corrtex-auth-v1"

/* --- tokens ----------------------------------------------------------------- */

static int token_from_bytes(const uint8_t *b, size_t n, const char *src, auth_token *t, ct_error *err)
{
    while (n > 0 && isspace(b[n - 1])) n--;
    if (n == 0) return ct_fail(err, CT_EINVAL, "%s: the token is empty", src);
    if (n < AUTH_TOKEN_MIN)
        return ct_fail(err, CT_EINVAL, "%s: the token has %zu bytes, at least %u are needed", src, n, AUTH_TOKEN_MIN);
    if (n > AUTH_TOKEN_MAX)
        return ct_fail(err, CT_EINVAL, "%s: the token has more than %u bytes", src, AUTH_TOKEN_MAX);
    memcpy(t->bytes, b, n);
    t->len = n;
    return 0;
}

int auth_token_load(const char *path, auth_token *t, ct_error *err)
{
    memset(t, 0, sizeof *t);
    /* O_NONBLOCK: a FIFO would block the open; it is refused below. */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return ct_fail(err, CT_EIO, "%s: cannot open token file: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int e = errno;
        close(fd);
        return ct_fail(err, CT_EIO, "%s: cannot stat token file: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return ct_fail(err, CT_EINVAL, "%s: token file is not a regular file", path);
    }
    if (st.st_mode & 077) {
        close(fd);
        return ct_fail(err, CT_EINVAL, "%s: token file is accessible by group or others (mode %03o); chmod 600 it",
                       path, (unsigned)(st.st_mode & 0777));
    }
    uint8_t buf[AUTH_TOKEN_MAX + 64];
    size_t n = 0;
    for (;;) {
        ssize_t r = read(fd, buf + n, sizeof buf - n);
        if (r < 0 && errno == EINTR) continue;
        if (r < 0) {
            int e = errno;
            close(fd);
            sodium_memzero(buf, sizeof buf);
            return ct_fail(err, CT_EIO, "%s: cannot read token file: %s", path, strerror(e));
        }
        if (r == 0) break;
        n += (size_t)r;
        if (n == sizeof buf) break;
    }
    close(fd);
    int rc = token_from_bytes(buf, n, path, t, err);
    sodium_memzero(buf, sizeof buf);
    return rc;
}

int auth_token_get(const char *path, auth_token *t, bool *have, ct_error *err)
{
    *have = false;
    memset(t, 0, sizeof *t);
    if (path && *path) {
        int rc = auth_token_load(path, t, err);
        if (rc == 0) *have = true;
        return rc;
    }
    const char *env = getenv(AUTH_TOKEN_ENV);
    if (!env || !*env) return 0;
    int rc = token_from_bytes((const uint8_t *)env, strlen(env), "$" AUTH_TOKEN_ENV, t, err);
    if (rc == 0) *have = true;
    return rc;
}

void auth_token_wipe(auth_token *t)
{
    sodium_memzero(t, sizeof *t);
}

/* --- HELLO and MAC ---------------------------------------------------------- */

void auth_hello_encode(uint8_t out[AUTH_HELLO_SIZE], auth_role role, uint8_t flags, const char *build_id,
                       const uint8_t nonce[AUTH_NONCE_SIZE])
{
    memset(out, 0, AUTH_HELLO_SIZE);
    memcpy(out, AUTH_MAGIC, AUTH_MAGIC_SIZE);
    wio_put_u16(out + 8, WIRE_VERSION);
    out[10] = (uint8_t)role;
    out[11] = flags;
    size_t n = strnlen(build_id, AUTH_BUILD_ID_LEN);
    memcpy(out + 12, build_id, n);
    memcpy(out + 32, nonce, AUTH_NONCE_SIZE);
}

void auth_mac(const auth_token *t, auth_role prover, const uint8_t master_hello[AUTH_HELLO_SIZE],
              const uint8_t display_hello[AUTH_HELLO_SIZE], uint8_t out[WIRE_MAC_SIZE])
{
    crypto_auth_hmacsha256_state st;
    uint8_t role = (uint8_t)prover;
    crypto_auth_hmacsha256_init(&st, t->bytes, t->len);
    crypto_auth_hmacsha256_update(&st, (const uint8_t *)AUTH_LABEL, sizeof AUTH_LABEL - 1);
    crypto_auth_hmacsha256_update(&st, &role, 1);
    crypto_auth_hmacsha256_update(&st, master_hello, AUTH_HELLO_SIZE);
    crypto_auth_hmacsha256_update(&st, display_hello, AUTH_HELLO_SIZE);
    crypto_auth_hmacsha256_final(&st, out);
    sodium_memzero(&st, sizeof st);
}

/* --- the state machine ------------------------------------------------------ */

enum { HS_HELLO, HS_AUTH, HS_DONE, HS_FAILED };

struct auth_hs {
    auth_role role;
    auth_token token;
    bool have_token;
    bool require_auth;
    char peer[128];
    char build_id[AUTH_BUILD_ID_LEN + 1];
    uint8_t mine[AUTH_HELLO_SIZE];
    uint8_t theirs[AUTH_HELLO_SIZE];
    size_t got;                  /* bytes of the current unit (HELLO or frame) */
    uint8_t frame[WIRE_HEADER_SIZE + WIRE_ERROR_TEXT_MAX + 8];  /* AUTH or ERROR frame */
    size_t frame_need;           /* whole frame size once the header is known */
    int state;
    int error;
    ct_error last;
    wire_buf out;
};

static const char *role_name(unsigned r)
{
    return r == AUTH_ROLE_MASTER ? "master" : r == AUTH_ROLE_DISPLAY ? "display" : "unknown";
}

int auth_hs_new(const auth_config *cfg, auth_hs **out, ct_error *err)
{
    const char *peer = cfg->peer ? cfg->peer : "peer";
    if (cfg->role != AUTH_ROLE_MASTER && cfg->role != AUTH_ROLE_DISPLAY)
        return ct_fail(err, CT_EINVAL, "%s: handshake role %d unknown", peer, (int)cfg->role);
    if (cfg->role == AUTH_ROLE_MASTER && cfg->require_auth && !cfg->token)
        return ct_fail(err, CT_EINVAL, "%s: authentication is required but no token was given (--token-file or %s)",
                       peer, AUTH_TOKEN_ENV);
    if (sodium_init() < 0) return ct_fail(err, CT_ESYS, "%s: libsodium failed to initialise", peer);
    auth_hs *hs = calloc(1, sizeof *hs);
    if (!hs) return ct_fail(err, CT_ENOMEM, "%s: out of memory for a handshake", peer);
    hs->role = cfg->role;
    hs->require_auth = cfg->require_auth;
    if (cfg->token) {
        hs->token = *cfg->token;
        hs->have_token = true;
    }
    snprintf(hs->peer, sizeof hs->peer, "%s", peer);
    snprintf(hs->build_id, sizeof hs->build_id, "%s", cfg->build_id ? cfg->build_id : CT_BUILD_ID);
    uint8_t nonce[AUTH_NONCE_SIZE];
    randombytes_buf(nonce, sizeof nonce);
    uint8_t flags = (cfg->role == AUTH_ROLE_MASTER && cfg->require_auth) ? AUTH_HELLO_REQUIRE_AUTH : 0;
    auth_hello_encode(hs->mine, cfg->role, flags, hs->build_id, nonce);
    int rc = wire_buf_append(&hs->out, hs->mine, AUTH_HELLO_SIZE, err);
    if (rc) {
        free(hs);
        return rc;
    }
    *out = hs;
    return 0;
}

void auth_hs_free(auth_hs *hs)
{
    if (!hs) return;
    wire_buf_free(&hs->out);
    sodium_memzero(hs, sizeof *hs);
    free(hs);
}

wire_buf *auth_hs_output(auth_hs *hs)
{
    return &hs->out;
}

/* Records a failure; queues an ERROR frame for the peer when tell_code != 0. */
static int hs_fail(auth_hs *hs, int rc, uint32_t tell_code, const char *tell, ct_error *err)
{
    hs->state = HS_FAILED;
    hs->error = rc;
    if (err) hs->last = *err;
    if (tell_code) {
        wire_msg m;
        wire_make_error(&m, tell_code, tell);
        wire_encode(&m, &hs->out, NULL);
    }
    return rc;
}

/* Checks the complete peer HELLO; queues our AUTH when needed. */
static int check_hello(auth_hs *hs, ct_error *err)
{
    const uint8_t *h = hs->theirs;
    unsigned version = wio_get_u16(h + 8);
    unsigned role = h[10], flags = h[11];
    unsigned want_role = hs->role == AUTH_ROLE_MASTER ? AUTH_ROLE_DISPLAY : AUTH_ROLE_MASTER;
    char msg[CT_ERROR_LEN];
    if (version != WIRE_VERSION) {
        snprintf(msg, sizeof msg, "protocol version %u, expected %u", version, WIRE_VERSION);
        ct_fail(err, CT_EPROTO, "%s: %s", hs->peer, msg);
        return hs_fail(hs, CT_EPROTO, WIRE_ERR_VERSION, msg, err);
    }
    if (role != want_role) {
        snprintf(msg, sizeof msg, "peer has role %s (%u), expected %s", role_name(role), role, role_name(want_role));
        ct_fail(err, CT_EPROTO, "%s: %s", hs->peer, msg);
        return hs_fail(hs, CT_EPROTO, WIRE_ERR_PROTOCOL, msg, err);
    }
    if (flags & ~(unsigned)AUTH_HELLO_REQUIRE_AUTH || (role == AUTH_ROLE_DISPLAY && flags)) {
        snprintf(msg, sizeof msg, "HELLO flags 0x%02x unknown", flags);
        ct_fail(err, CT_EPROTO, "%s: %s", hs->peer, msg);
        return hs_fail(hs, CT_EPROTO, WIRE_ERR_PROTOCOL, msg, err);
    }
    char bid[AUTH_BUILD_ID_LEN + 1] = {0};
    memcpy(bid, h + 12, AUTH_BUILD_ID_LEN);
    size_t n = strlen(bid);
    bool ok = true;
    for (size_t i = 0; i < AUTH_BUILD_ID_LEN; i++)
        if (i < n ? (h[12 + i] < 0x20 || h[12 + i] > 0x7e) : h[12 + i] != 0) ok = false;
    if (!ok) {
        snprintf(msg, sizeof msg, "build id is not NUL-padded printable ASCII");
        ct_fail(err, CT_EPROTO, "%s: %s", hs->peer, msg);
        return hs_fail(hs, CT_EPROTO, WIRE_ERR_VERSION, msg, err);
    }
    if (strcmp(bid, hs->build_id) != 0) {
        snprintf(msg, sizeof msg, "build id '%s' differs from ours '%s'", bid, hs->build_id);
        ct_fail(err, CT_EPROTO, "%s: %s", hs->peer, msg);
        return hs_fail(hs, CT_EPROTO, WIRE_ERR_VERSION, msg, err);
    }
    const uint8_t *mh = hs->role == AUTH_ROLE_MASTER ? hs->mine : hs->theirs;
    bool auth = (mh[11] & AUTH_HELLO_REQUIRE_AUTH) != 0;
    if (hs->role == AUTH_ROLE_DISPLAY) {
        if (!auth && hs->require_auth) {
            ct_fail(err, CT_EAUTH, "%s: the master does not authenticate; refusing an unauthenticated connection",
                    hs->peer);
            return hs_fail(hs, CT_EAUTH, WIRE_ERR_AUTH, "display requires authentication", err);
        }
        if (auth && !hs->have_token) {
            ct_fail(err, CT_EAUTH, "%s: the master requires a token; give --token-file or set %s", hs->peer,
                    AUTH_TOKEN_ENV);
            return hs_fail(hs, CT_EAUTH, WIRE_ERR_AUTH, "display has no token", err);
        }
    }
    if (!auth) {
        hs->state = HS_DONE;
        return 0;
    }
    wire_msg m;
    memset(&m, 0, sizeof m);
    m.type = WIRE_AUTH;
    const uint8_t *dh = hs->role == AUTH_ROLE_MASTER ? hs->theirs : hs->mine;
    auth_mac(&hs->token, hs->role, mh, dh, m.u.auth.mac);
    int rc = wire_encode(&m, &hs->out, err);
    sodium_memzero(&m, sizeof m);
    if (rc) return hs_fail(hs, rc, 0, NULL, err);
    hs->state = HS_AUTH;
    hs->got = 0;
    hs->frame_need = 0;
    return WIRE_NEED_MORE;
}

/* Checks the complete AUTH (or ERROR) frame in hs->frame. */
static int check_auth(auth_hs *hs, ct_error *err)
{
    unsigned type = wio_get_u16(hs->frame);
    if (type == WIRE_ERROR) {
        wire_msg m;
        wire_scratch s = {0};
        int rc = wire_decode(hs->frame, hs->frame_need, hs->peer, &m, &s, err);
        wire_scratch_free(&s);
        if (rc) return hs_fail(hs, rc, 0, NULL, err);
        ct_fail(err, m.u.error.code == WIRE_ERR_AUTH ? CT_EAUTH : CT_EPROTO, "%s: peer refused the handshake: %s",
                hs->peer, m.u.error.text);
        return hs_fail(hs, m.u.error.code == WIRE_ERR_AUTH ? CT_EAUTH : CT_EPROTO, 0, NULL, err);
    }
    const uint8_t *mh = hs->role == AUTH_ROLE_MASTER ? hs->mine : hs->theirs;
    const uint8_t *dh = hs->role == AUTH_ROLE_MASTER ? hs->theirs : hs->mine;
    uint8_t want[WIRE_MAC_SIZE];
    auth_role prover = hs->role == AUTH_ROLE_MASTER ? AUTH_ROLE_DISPLAY : AUTH_ROLE_MASTER;
    auth_mac(&hs->token, prover, mh, dh, want);
    int bad = crypto_verify_32(want, hs->frame + WIRE_HEADER_SIZE);
    sodium_memzero(want, sizeof want);
    if (bad) {
        ct_fail(err, CT_EAUTH, "%s: authentication failed: the peer's proof does not match our token", hs->peer);
        return hs_fail(hs, CT_EAUTH, WIRE_ERR_AUTH, "authentication failed", err);
    }
    hs->state = HS_DONE;
    return 0;
}

int auth_hs_input(auth_hs *hs, const uint8_t *data, size_t len, size_t *used, ct_error *err)
{
    ct_error local;
    if (!err) err = &local;
    *used = 0;
    if (hs->state == HS_FAILED) {
        *err = hs->last;
        return hs->error;
    }
    if (hs->state == HS_DONE) return 0;
    size_t i = 0;
    while (i < len && hs->state == HS_HELLO) {
        uint8_t b = data[i++];
        /* The magic is checked byte by byte as it arrives: a stray HTTP client
         * or a wrong port fails at its first byte. */
        if (hs->got < AUTH_MAGIC_SIZE && b != (uint8_t)AUTH_MAGIC[hs->got]) {
            *used = i;
            ct_fail(err, CT_EPROTO, "%s: bad magic byte 0x%02x at offset %zu (not a corrtex peer?)", hs->peer, b,
                    hs->got);
            return hs_fail(hs, CT_EPROTO, WIRE_ERR_PROTOCOL, "bad magic", err);
        }
        hs->theirs[hs->got++] = b;
        if (hs->got == AUTH_HELLO_SIZE) {
            int rc = check_hello(hs, err);
            if (rc < 0) {
                *used = i;
                return rc;
            }
        }
    }
    while (i < len && hs->state == HS_AUTH) {
        hs->frame[hs->got++] = data[i++];
        if (hs->got == WIRE_HEADER_SIZE) {
            unsigned type;
            uint32_t body;
            int rc = wire_parse_header(hs->frame, hs->peer, &type, &body, err);
            if (rc) {
                *used = i;
                return hs_fail(hs, rc, WIRE_ERR_PROTOCOL, "bad frame during the handshake", err);
            }
            if (type != WIRE_AUTH && type != WIRE_ERROR) {
                *used = i;
                ct_fail(err, CT_EPROTO, "%s: expected AUTH during the handshake, got %s", hs->peer, wire_type_name(type));
                return hs_fail(hs, CT_EPROTO, WIRE_ERR_PROTOCOL, "expected AUTH", err);
            }
            hs->frame_need = WIRE_HEADER_SIZE + body; /* <= sizeof frame: AUTH 32, ERROR <= 206 */
        }
        if (hs->frame_need && hs->got == hs->frame_need) {
            int rc = check_auth(hs, err);
            *used = i;
            return rc;
        }
    }
    *used = i;
    if (hs->state == HS_DONE) return 0;
    return WIRE_NEED_MORE;
}
