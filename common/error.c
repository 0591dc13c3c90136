#include "common/error.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

int ct_fail(ct_error *err, int code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
        /* One line only: a message that embeds a newline from a peer or a
         * library would break the log format. */
        for (char *p = err->msg; *p; p++)
            if (*p == '\n' || *p == '\r') *p = ' ';
    }
    return code;
}

void ct_error_clear(ct_error *err)
{
    if (err) err->msg[0] = '\0';
}

void ct_error_prefix(ct_error *err, const char *prefix)
{
    if (!err || !prefix) return;
    char tmp[CT_ERROR_LEN];
    snprintf(tmp, sizeof tmp, "%s: %s", prefix, err->msg);
    memcpy(err->msg, tmp, sizeof tmp);
}

const char *ct_strerror(int code)
{
    switch (code) {
    case CT_OK: return "ok";
    case CT_EIO: return "io";
    case CT_EPARSE: return "parse";
    case CT_EINVAL: return "invalid";
    case CT_ENOMEM: return "memory";
    case CT_ERANGE: return "range";
    case CT_EPROTO: return "protocol";
    case CT_EAUTH: return "auth";
    case CT_ESYS: return "system";
    case CT_EEMPTY: return "empty";
    case CT_ESTALE: return "stale";
    default: return "unknown";
    }
}
