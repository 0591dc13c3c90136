#include "tests/support/fixtures.h"

#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Every string handed out is kept here and freed at exit, so LeakSanitizer
 * sees tests, not fixtures. Folders are removed at exit too. */
static char **g_strings;
static size_t g_nstrings;
static char **g_dirs;
static size_t g_ndirs;
static int g_registered;

static int rm_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
    (void)st; (void)flag; (void)ftw;
    return remove(path);
}

static void cleanup(void)
{
    for (size_t i = 0; i < g_ndirs; i++) nftw(g_dirs[i], rm_entry, 16, FTW_DEPTH | FTW_PHYS);
    for (size_t i = 0; i < g_nstrings; i++) free(g_strings[i]);
    free(g_strings);
    free(g_dirs);
    g_strings = g_dirs = NULL;
    g_nstrings = g_ndirs = 0;
}

static char *keep(char *s)
{
    if (!s) return NULL;
    if (!g_registered) { atexit(cleanup); g_registered = 1; }
    char **q = realloc(g_strings, (g_nstrings + 1) * sizeof *q);
    if (!q) { free(s); return NULL; }
    g_strings = q;
    g_strings[g_nstrings++] = s;
    return s;
}

const char *fx_tmpdir(void)
{
    char *t = keep(strdup("/tmp/corrtex-test-XXXXXX"));
    if (!t || !mkdtemp(t)) return NULL;
    char **q = realloc(g_dirs, (g_ndirs + 1) * sizeof *q);
    if (q) { g_dirs = q; g_dirs[g_ndirs++] = t; }
    return t;
}

const char *fx_path(const char *dir, const char *name)
{
    size_t n = strlen(dir) + strlen(name) + 2;
    char *p = keep(malloc(n));
    if (p) snprintf(p, n, "%s/%s", dir, name);
    return p;
}

const char *fx_write(const char *dir, const char *name, const char *text)
{
    const char *p = fx_path(dir, name);
    if (!p) return NULL;
    FILE *f = fopen(p, "wb");
    if (!f) return NULL;
    fputs(text, f);
    fclose(f);
    return p;
}

vec3 fx_rand_unit(ct_rng *r)
{
    for (;;) {
        /* One draw per statement: the order of a call's arguments is
         * unspecified (GCC and Clang differ), the test data must not be. */
        float x = 2 * rng_float(r) - 1, y = 2 * rng_float(r) - 1, z = 2 * rng_float(r) - 1;
        vec3 v = v3(x, y, z);
        float l = v3_len(v);
        if (l > 0.1f && l <= 1.0f) return v3_scale(v, 1.0f / l);
    }
}
