/* optab.c: table-driven option parsing (optab.h). */
#include "common/optab.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

static void *field(void *base, const optab *r)
{
    return (char *)base + r->off;
}

/* Whole numbers: unsigned parsing when the range has no negatives, so a
 * 64-bit seed keeps every digit. */
static int whole(const optab *r, void *base, const char *v, ct_error *err)
{
    char *end = NULL;
    errno = 0;
    /* strtoull and strtoll skip leading blanks: "--frames ' 5'" is a quoting
     * slip, not a number */
    if (isspace((unsigned char)*v)) goto bad;
    if (r->lo >= 0) {
        unsigned long long u = strtoull(v, &end, 10);
        if (strchr(v, '-') || errno || end == v || *end || (double)u < r->lo || (double)u > r->hi) goto bad;
        if (r->type == OPTAB_U64) *(uint64_t *)field(base, r) = (uint64_t)u;
        else if (r->type == OPTAB_U32) *(uint32_t *)field(base, r) = (uint32_t)u;
        else if (r->type == OPTAB_SIZE) *(size_t *)field(base, r) = (size_t)u;
        else if (r->type == OPTAB_LONG) *(long *)field(base, r) = (long)u;
        else *(int *)field(base, r) = (int)u;
        return 1;
    }
    long long s = strtoll(v, &end, 10);
    if (errno || end == v || *end || (double)s < r->lo || (double)s > r->hi) goto bad;
    if (r->type == OPTAB_LONG) *(long *)field(base, r) = (long)s;
    else *(int *)field(base, r) = (int)s;
    return 1;
bad:;
    /* integers as integers: 2^64 - 1 printed as a double read 1.8446744073709552e+19 */
    char lo[32], hi[32];
    snprintf(lo, sizeof lo, "%.0f", r->lo);
    if (r->hi >= 18446744073709551615.0) snprintf(hi, sizeof hi, "18446744073709551615");
    else snprintf(hi, sizeof hi, "%.0f", r->hi);
    return ct_fail(err, CT_EINVAL, "--%s: '%s' is not an integer in [%s, %s]", r->name, v, lo, hi);
}

/* The k-th word of "a|b|c" and its length in *len, or NULL past the last. */
static const char *choice_word(const char *words, int k, size_t *len)
{
    const char *p = words;
    for (int i = 0; p && i < k; i++) {
        size_t w = strcspn(p, "|");
        p = p[w] ? p + w + 1 : NULL;
    }
    if (p) *len = strcspn(p, "|");
    return p;
}

/* The index of value among the words of "a|b|c", or -1. */
static int choice_index(const char *words, const char *value)
{
    size_t len = strlen(value), w;
    const char *p;
    for (int k = 0; (p = choice_word(words, k, &w)); k++)
        if (w == len && strncmp(p, value, len) == 0) return k;
    return -1;
}

static int set_row(const optab *r, void *base, const char *v, ct_error *err)
{
    if (r->type == OPTAB_FLAG) {
        *(bool *)field(base, r) = v ? (strcmp(v, "0") != 0 && strcmp(v, "off") != 0) : true;
        return 1;
    }
    if (!v) return ct_fail(err, CT_EINVAL, "option --%s needs a value (try --help)", r->name);
    switch (r->type) {
    case OPTAB_INT:
    case OPTAB_LONG:
    case OPTAB_U32:
    case OPTAB_U64:
    case OPTAB_SIZE:
        return whole(r, base, v, err);
    case OPTAB_FLOAT:
    case OPTAB_DOUBLE: {
        char *end = NULL;
        errno = 0;
        double x = strtod(v, &end);
        if (isspace((unsigned char)*v) || errno || end == v || *end || !isfinite(x) || !(x >= r->lo && x <= r->hi))
            return ct_fail(err, CT_EINVAL, "--%s: '%s' is not a number in [%g, %g]", r->name, v, r->lo, r->hi);
        if (r->type == OPTAB_FLOAT) *(float *)field(base, r) = (float)x;
        else *(double *)field(base, r) = x;
        return 1;
    }
    case OPTAB_CHOICE: {
        int k = r->arg ? choice_index(r->arg, v) : -1;
        if (k < 0) return ct_fail(err, CT_EINVAL, "--%s: '%s' is not one of %s", r->name, v, r->arg);
        *(int *)field(base, r) = r->codes ? r->codes[k] : k;
        return 1;
    }
    case OPTAB_STRING:
        /* Every string option names a file, folder, address, camera or list:
         * an empty one used to pass for none ("--token-file ''" served a
         * UNIX socket without a token) or fail late and unclearly
         * ("corrtex radiosity -o ''" solved, then ": cannot write"). */
        if (!*v)
            return ct_fail(err, CT_EINVAL, "--%s: the value is empty (give %s)", r->name, r->arg ? r->arg : "one");
        *(const char **)field(base, r) = v;
        return 1;
    default:
        return ct_fail(err, CT_EINVAL, "--%s: option of unknown type %d", r->name, (int)r->type);
    }
}

int optab_defaults(const optab *t, size_t n, void *base, ct_error *err)
{
    for (size_t i = 0; i < n; i++) {
        const optab *r = &t[i];
        if (!r->def) {
            switch (r->type) {
            case OPTAB_INT: case OPTAB_CHOICE: *(int *)field(base, r) = 0; break;
            case OPTAB_LONG: *(long *)field(base, r) = 0; break;
            case OPTAB_U32: *(uint32_t *)field(base, r) = 0; break;
            case OPTAB_U64: *(uint64_t *)field(base, r) = 0; break;
            case OPTAB_SIZE: *(size_t *)field(base, r) = 0; break;
            case OPTAB_FLOAT: *(float *)field(base, r) = 0.0f; break;
            case OPTAB_DOUBLE: *(double *)field(base, r) = 0.0; break;
            case OPTAB_FLAG: *(bool *)field(base, r) = false; break;
            case OPTAB_STRING: *(const char **)field(base, r) = NULL; break;
            }
            continue;
        }
        int rc = set_row(r, base, r->def, err);
        if (rc < 0) {
            ct_error_prefix(err, "default");
            return rc;
        }
    }
    return CT_OK;
}

const optab *optab_find(const optab *t, size_t n, const char *name)
{
    for (size_t i = 0; i < n; i++)
        if (strcmp(t[i].name, name) == 0) return &t[i];
    return NULL;
}

int optab_set(const optab *t, size_t n, void *base, const char *name, const char *value, ct_error *err)
{
    const optab *r = optab_find(t, n, name);
    if (!r) return 0;
    return set_row(r, base, value, err);
}

/* The value of row r's field in base, as text. */
static void field_text(const optab *r, const void *base, char *out, size_t cap)
{
    const void *f = (const char *)base + r->off;
    switch (r->type) {
    case OPTAB_INT: snprintf(out, cap, "%d", *(const int *)f); break;
    case OPTAB_LONG: snprintf(out, cap, "%ld", *(const long *)f); break;
    case OPTAB_U32: snprintf(out, cap, "%u", *(const uint32_t *)f); break;
    case OPTAB_U64: snprintf(out, cap, "%llu", (unsigned long long)*(const uint64_t *)f); break;
    case OPTAB_SIZE: snprintf(out, cap, "%zu", *(const size_t *)f); break;
    case OPTAB_FLOAT: snprintf(out, cap, "%g", (double)*(const float *)f); break;
    case OPTAB_DOUBLE: snprintf(out, cap, "%g", *(const double *)f); break;
    case OPTAB_FLAG: snprintf(out, cap, "%s", *(const bool *)f ? "on" : "off"); break;
    case OPTAB_STRING: snprintf(out, cap, "%s", *(const char *const *)f ? *(const char *const *)f : ""); break;
    case OPTAB_CHOICE: {
        /* The word whose code the field holds; none when it holds no word's. */
        int v = *(const int *)f;
        size_t w;
        const char *p;
        out[0] = 0;
        for (int k = 0; (p = choice_word(r->arg, k, &w)); k++)
            if ((r->codes ? r->codes[k] : k) == v) {
                snprintf(out, cap, "%.*s", (int)w, p);
                break;
            }
        break;
    }
    default: out[0] = 0; break;
    }
}

/* Whether row r's numeric field in base lies in its range (a value outside
 * it, such as 0 for "the mode's default", is no default to show). */
static bool in_range(const optab *r, const void *base)
{
    const void *f = (const char *)base + r->off;
    double v;
    switch (r->type) {
    case OPTAB_INT: v = *(const int *)f; break;
    case OPTAB_LONG: v = (double)*(const long *)f; break;
    case OPTAB_U32: v = *(const uint32_t *)f; break;
    case OPTAB_U64: v = (double)*(const uint64_t *)f; break;
    case OPTAB_SIZE: v = (double)*(const size_t *)f; break;
    case OPTAB_FLOAT: v = *(const float *)f; break;
    case OPTAB_DOUBLE: v = *(const double *)f; break;
    default: return true;
    }
    return v >= r->lo && v <= r->hi;
}

void optab_usage(const optab *t, size_t n, const void *defaults, FILE *f)
{
    for (size_t i = 0; i < n; i++) {
        const optab *r = &t[i];
        char flag[96];
        int k = r->short_name ? snprintf(flag, sizeof flag, "-%c, ", r->short_name) : 0;
        snprintf(flag + k, sizeof flag - (size_t)k, "--%s%s%s", r->name, r->type == OPTAB_FLAG ? "" : " ",
                 r->type == OPTAB_FLAG ? "" : r->arg ? r->arg : "X");
        fprintf(f, "  %-28s %s", flag, r->help);
        char dv[64] = "";
        if (r->type == OPTAB_FLAG && !defaults) snprintf(dv, sizeof dv, "%s", r->def && strcmp(r->def, "0") ? "on" : "off");
        else if (r->def) snprintf(dv, sizeof dv, "%s", r->def);
        else if (defaults && in_range(r, defaults)) field_text(r, defaults, dv, sizeof dv);
        if (dv[0]) fprintf(f, " (default %s)\n", dv);
        else fputc('\n', f);
    }
}

/* The row of argument a ("--name" or "-x") in the groups. */
static const optab *lookup(const optab_group *g, int ng, const char *a, int *gi)
{
    for (int k = 0; k < ng; k++)
        for (size_t i = 0; i < g[k].n; i++) {
            const optab *r = &g[k].rows[i];
            if ((a[1] == '-' && strcmp(a + 2, r->name) == 0) ||
                (a[1] != '-' && r->short_name && a[1] == r->short_name && a[2] == 0)) {
                *gi = k;
                return r;
            }
        }
    return NULL;
}

/* optab_parse's walk over argv; with `want`, nothing is set or collected
 * and *found says whether that row is among the options (optab_given). */
static int scan(const optab_group *g, int ng, int argc, char **argv, const char **pos, int maxpos, int *npos,
                const optab *want, bool *found, ct_error *err)
{
    *npos = 0;
    bool only_pos = false;   /* after "--" */
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!only_pos && strcmp(a, "--") == 0) {
            only_pos = true;
            continue;
        }
        if (!only_pos && (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0)) return 1;
        if (only_pos || a[0] != '-' || a[1] == 0) {
            if (want) continue;
            if (*npos >= maxpos) return ct_fail(err, CT_EINVAL, "unexpected argument '%s' (try --help)", a);
            /* positional arguments are files: '' named none */
            if (!*a) return ct_fail(err, CT_EINVAL, "an empty argument (try --help)");
            pos[(*npos)++] = a;
            continue;
        }
        /* --name=value as well as --name value */
        char name[80];
        const char *eq = a[1] == '-' ? strchr(a, '=') : NULL;
        if (eq && (size_t)(eq - a) < sizeof name) {
            memcpy(name, a, (size_t)(eq - a));
            name[eq - a] = '\0';
        } else {
            eq = NULL;
        }
        int k = 0;
        const optab *r = lookup(g, ng, eq ? name : a, &k);
        if (!r) return ct_fail(err, CT_EINVAL, "unknown option '%s' (try --help)", eq ? name : a);
        const char *v = NULL;
        if (r->type == OPTAB_FLAG && eq) return ct_fail(err, CT_EINVAL, "option %s takes no value", name);
        if (eq) {
            v = eq + 1;
        } else if (r->type != OPTAB_FLAG) {
            if (i + 1 >= argc) return ct_fail(err, CT_EINVAL, "option %s needs a value (try --help)", a);
            v = argv[++i];
        }
        if (want) {
            *found |= r == want;
            continue;
        }
        int rc = set_row(r, g[k].base, v, err);
        if (rc < 0) return rc;
    }
    return CT_OK;
}

int optab_parse(const optab_group *g, int ng, int argc, char **argv, const char **pos, int maxpos, int *npos,
                ct_error *err)
{
    return scan(g, ng, argc, argv, pos, maxpos, npos, NULL, NULL, err);
}

bool optab_given(const optab_group *g, int ng, int argc, char **argv, const char *name)
{
    const optab *want = NULL;
    for (int k = 0; k < ng && !want; k++) want = optab_find(g[k].rows, g[k].n, name);
    bool found = false;
    int npos;
    ct_error err;
    return want && scan(g, ng, argc, argv, NULL, 0, &npos, want, &found, &err) == CT_OK && found;
}
