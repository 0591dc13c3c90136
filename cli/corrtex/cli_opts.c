/* cli_opts.c: option-value parsing shared by the corrtex subcommands. */
#include <math.h>
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

int cli_float_opt(const char *component, const char *name, const char *s, double lo, double hi, float *out)
{
    char *end = NULL;
    double v = strtod(s, &end);
    if (end == s || *end || !isfinite(v) || v < lo || v > hi) {
        ct_log(CT_LOG_ERROR, component, "%s: '%s' is not a number in %g..%g", name, s, lo, hi);
        return -1;
    }
    *out = (float)v;
    return 0;
}
