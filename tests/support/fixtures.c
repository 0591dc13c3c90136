#include "tests/support/fixtures.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *fx_tmpdir(void)
{
    char *t = strdup("/tmp/corrtex-test-XXXXXX");
    if (!t || !mkdtemp(t)) return NULL;
    return t;
}

const char *fx_write(const char *dir, const char *name, const char *text)
{
    size_t n = strlen(dir) + strlen(name) + 2;
    char *p = malloc(n);
    if (!p) return NULL;
    snprintf(p, n, "%s/%s", dir, name);
    FILE *f = fopen(p, "wb");
    if (!f) { free(p); return NULL; }
    fputs(text, f);
    fclose(f);
    return p;
}
