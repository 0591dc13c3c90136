/* mesh_precheck.c: a PLY header's counts against the file's size
 * (mesh_precheck.h). */
#include "common/mesh_precheck.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define HEADER_MAX (64u << 10)   /* a longer header is left to assimp */

/* Bytes of a binary PLY scalar type; 0 when unknown. */
static unsigned type_size(const char *t)
{
    static const struct { const char *name; unsigned size; } types[] = {
        {"char", 1},  {"uchar", 1},  {"int8", 1},  {"uint8", 1},   {"short", 2},   {"ushort", 2},  {"int16", 2},
        {"uint16", 2}, {"int", 4},   {"uint", 4},  {"int32", 4},   {"uint32", 4},  {"float", 4},   {"float32", 4},
        {"double", 8}, {"float64", 8},
    };
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
        if (!strcmp(t, types[i].name)) return types[i].size;
    return 0;
}

typedef struct element {
    char name[64];
    unsigned long long count;
    unsigned long long per;   /* least bytes one of them takes */
} element;

/* What the elements promise, checked against the data's bytes. */
static int check(const char *path, const element *e, int n, unsigned long long avail, ct_error *err)
{
    unsigned long long need = 0;
    for (int i = 0; i < n; i++) {
        unsigned long long per = e[i].per ? e[i].per : 1, bytes;
        if (__builtin_mul_overflow(e[i].count, per, &bytes) || __builtin_add_overflow(need, bytes, &need))
            need = UINT64_MAX;
        if (need > avail)
            return ct_fail(err, CT_EPARSE,
                           "%s: the PLY header promises %llu %s%s (at least %llu bytes) but the file has %llu bytes "
                           "after its header",
                           path, e[i].count, e[i].name, i ? " after the elements before" : "", need, avail);
    }
    return CT_OK;
}

int mesh_precheck(FILE *f, const char *path, size_t size, ct_error *err)
{
    char *h = malloc(HEADER_MAX + 1);
    if (!h) return ct_fail(err, CT_ENOMEM, "%s: out of memory", path);
    size_t got = fread(h, 1, HEADER_MAX, f);
    h[got] = '\0';
    int rc = CT_OK;
    if (got < 4 || memcmp(h, "ply", 3) || (h[3] != '\n' && h[3] != '\r')) goto done;
    bool ascii = strstr(h, "\nformat ascii") != NULL;
    element e[64];
    int n = 0;
    char *line = h, *end;
    for (; (end = strchr(line, '\n')); line = end + 1) {
        *end = '\0';
        char w1[32] = "", w2[64] = "", w3[64] = "";
        int k = sscanf(line, "%31s %63s %63s", w1, w2, w3);
        if (k >= 1 && !strcmp(w1, "end_header")) {
            size_t header = (size_t)(end + 1 - h);
            rc = check(path, e, n, size > header ? (unsigned long long)(size - header) : 0, err);
            goto done;
        }
        if (k == 3 && !strcmp(w1, "element")) {
            if (n == 64) goto done;   /* unusual: left to assimp */
            char *tail;
            unsigned long long c = strtoull(w3, &tail, 10);
            if (*tail || w3[0] == '-') goto done;
            snprintf(e[n].name, sizeof e[n].name, "%s", w2);
            e[n].count = c;
            e[n].per = 0;
            n++;
        } else if (k >= 2 && !strcmp(w1, "property") && n > 0) {
            /* a list: at least its count; a scalar: its size (ASCII: a
             * digit and a separator either way) */
            unsigned s = type_size(w2);
            if (!strcmp(w2, "list")) s = type_size(w3);
            e[n - 1].per += ascii ? 2 : (s ? s : 1);
        }
    }
done:
    free(h);
    return rc;
}
