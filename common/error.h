/* error.h: corrtex's error type. Functions that can fail return an int
 * (0 = ok, a negative CT_E* code otherwise) and fill a caller's ct_error with
 * one line naming the file or peer and the problem. Only main() prints it. */
#ifndef CT_ERROR_H
#define CT_ERROR_H

#include <stddef.h>

enum {
    CT_OK      = 0,
    CT_EIO     = -1,  /* file or socket I/O failed */
    CT_EPARSE  = -2,  /* malformed input (JSON, OBJ, EXR, message) */
    CT_EINVAL  = -3,  /* invalid argument or value */
    CT_ENOMEM  = -4,  /* allocation failed or a memory cap was hit */
    CT_ERANGE  = -5,  /* a value or index out of range */
    CT_EPROTO  = -6,  /* protocol violation by a peer */
    CT_EAUTH   = -7,  /* authentication failed */
    CT_ESYS    = -8,  /* a system or library call failed */
    CT_EEMPTY  = -9,  /* nothing to work on (empty scene, ...) */
    CT_ESTALE  = -10  /* cached data does not match its source */
};

#define CT_ERROR_LEN 256

typedef struct ct_error {
    char msg[CT_ERROR_LEN];
} ct_error;

/* Fills err (may be NULL) with a printf-style message and returns code. */
int ct_fail(ct_error *err, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Resets err to the empty message. */
void ct_error_clear(ct_error *err);

/* Prefixes err's message with "prefix: " (e.g. a file name), keeping it one line. */
void ct_error_prefix(ct_error *err, const char *prefix);

/* Short name of an error code ("io", "parse", ...). */
const char *ct_strerror(int code);

#endif
