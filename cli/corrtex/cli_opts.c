/* cli_opts.c: option-value parsing shared by the corrtex subcommands. */
#include <stdlib.h>

#include "cli/corrtex/commands.h"
#include "common/log.h"

int cli_int_opt(const char *component, const char *name, const char *s, long lo, long hi, int *out)
{
    char *end = NULL;
    long v = strtol(s, &end, 10);
    if (end == s || *end || v < lo || v > hi) {
        ct_log(CT_LOG_ERROR, component, "%s: '%s' is not an integer in %ld..%ld", name, s, lo, hi);
        return -1;
    }
    *out = (int)v;
    return 0;
}
