/* tool_display.h: the start every display stand-in of tests/tools shares
 * (raw_camera, camera_flood): connect and authenticate as corrtex-display
 * does (proto/chan.h), then SETTINGS. Header-only: each tool is one C file
 * built alone. */
#ifndef CT_TESTS_TOOLS_TOOL_DISPLAY_H
#define CT_TESTS_TOOLS_TOOL_DISPLAY_H

#include <stdio.h>
#include <string.h>

#include "proto/auth.h"
#include "proto/chan.h"
#include "proto/wire.h"

/* A display connection to addr (token_file "-": none) that has sent
 * SETTINGS with samples_per_frame (0: free running); NULL, with one line
 * "NAME: why" on stderr, when it cannot. */
static inline chan *tool_display_connect(const char *name, const char *addr, const char *token_file,
                                         uint32_t samples_per_frame)
{
    auth_token tok;
    bool have = strcmp(token_file, "-") != 0;
    ct_error err;
    chan *c = NULL;
    if (have && auth_token_load(token_file, &tok, &err)) {
        fprintf(stderr, "%s: %s\n", name, err.msg);
        return NULL;
    }
    chan_config cfg = {.role = AUTH_ROLE_DISPLAY, .token = have ? &tok : NULL};
    if (chan_connect(addr, &cfg, 5000, &c, &err)) {
        fprintf(stderr, "%s: %s\n", name, err.msg);
        return NULL;
    }
    wire_msg m = {.type = WIRE_SETTINGS};
    m.u.settings.samples_per_frame = samples_per_frame;
    if (chan_send(c, &m, &err) || chan_flush(c, 5000, &err)) {
        fprintf(stderr, "%s: settings: %s\n", name, err.msg);
        chan_free(c);
        return NULL;
    }
    return c;
}

#endif
