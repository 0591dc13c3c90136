#include "display/disp_cache.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "common/fsutil.h"
#include "common/log.h"

#define COMP "corrtex-display"
#define HEX_LEN (2 * WIRE_HASH_SIZE)
#define SUFFIX ".ctscene"
/* A temporary file this old is left over from a display that died while
 * writing; younger ones may belong to a display writing right now. */
#define STALE_TEMP_S 3600

struct disp_scene_cache {
    uint8_t *raw;
    uint64_t size;
    uint8_t hash[WIRE_HASH_SIZE];
    char dir[2048];    /* "" = memory only */
    uint64_t max_bytes;
};

int disp_scene_cache_new(const char *dir, uint64_t max_bytes, disp_scene_cache **out,
                         ct_error *err)
{
    disp_scene_cache *c = calloc(1, sizeof *c);
    *out = c;
    if (!c) return ct_fail(err, CT_ENOMEM, "out of memory for the scene cache");
    if (dir) snprintf(c->dir, sizeof c->dir, "%s", dir);
    c->max_bytes = max_bytes;
    return CT_OK;
}

void disp_scene_cache_free(disp_scene_cache *c)
{
    if (!c) return;
    free(c->raw);
    free(c);
}

bool disp_scene_cache_hash(const disp_scene_cache *c, uint8_t hash[WIRE_HASH_SIZE])
{
    if (!c || !c->raw) return false;
    memcpy(hash, c->hash, WIRE_HASH_SIZE);
    return true;
}

bool disp_scene_cache_get(const disp_scene_cache *c, const uint8_t hash[WIRE_HASH_SIZE],
                          const uint8_t **raw, uint64_t *size)
{
    if (!c || !c->raw || memcmp(c->hash, hash, WIRE_HASH_SIZE) != 0) return false;
    *raw = c->raw;
    *size = c->size;
    return true;
}

static bool is_hex(const char *s, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!((s[i] >= '0' && s[i] <= '9') || (s[i] >= 'a' && s[i] <= 'f'))) return false;
    return true;
}

/* "<64 lowercase hex>.ctscene": only such files are ever deleted as payloads. */
static bool is_payload_name(const char *name)
{
    return strlen(name) == HEX_LEN + strlen(SUFFIX) && is_hex(name, HEX_LEN) &&
           !strcmp(name + HEX_LEN, SUFFIX);
}

/* "addr-<16 hex>.last" */
static bool is_index_name(const char *name)
{
    return strlen(name) == 5 + 16 + 5 && !strncmp(name, "addr-", 5) && is_hex(name + 5, 16) &&
           !strcmp(name + 21, ".last");
}

static void index_name(const char *addr, char out[32])
{
    uint8_t h[WIRE_HASH_SIZE];
    char hex[HEX_LEN + 1];
    wire_scene_hash((const uint8_t *)addr, strlen(addr), h);
    wire_hash_hex(h, hex);
    snprintf(out, 32, "addr-%.16s.last", hex);
}

static void payload_path(const disp_scene_cache *c, const char *hex, char *out, size_t cap)
{
    char name[HEX_LEN + sizeof SUFFIX];
    snprintf(name, sizeof name, "%.*s%s", HEX_LEN, hex, SUFFIX);
    fs_join(c->dir, name, out, cap);
}

/* The hash an index file names, or false when it is missing or malformed. */
static bool read_index(const disp_scene_cache *c, const char *name, char hex[HEX_LEN + 1])
{
    char path[4096], *text = NULL;
    size_t len = 0;
    ct_error e;
    fs_join(c->dir, name, path, sizeof path);
    if (fs_read_all(path, HEX_LEN + 8, &text, &len, &e)) return false;
    bool ok = len >= HEX_LEN && is_hex(text, HEX_LEN);
    if (ok) snprintf(hex, HEX_LEN + 1, "%.*s", HEX_LEN, text);
    free(text);
    return ok;
}

/* Marks a payload as just used: pruning goes by modification time. */
static void touch(const char *path)
{
    (void)utimensat(AT_FDCWD, path, NULL, 0);
}

/* Loads the payload named hex; false (logged) when it is unreadable or does
 * not match its hash. */
static bool load(disp_scene_cache *c, const char *hex)
{
    char path[4096], *raw = NULL;
    size_t size = 0;
    ct_error e;
    payload_path(c, hex, path, sizeof path);
    if (fs_read_all(path, (size_t)WIRE_SCENE_MAX_RAW, &raw, &size, &e)) {
        ct_warn(COMP, "scene cache: %s", e.msg);
        return false;
    }
    uint8_t h[WIRE_HASH_SIZE];
    char got[HEX_LEN + 1];
    wire_scene_hash((const uint8_t *)raw, size, h);
    wire_hash_hex(h, got);
    if (strcmp(got, hex) != 0) {
        ct_warn(COMP, "scene cache: %s does not match its hash; ignored", path);
        free(raw);
        return false;
    }
    free(c->raw);
    c->raw = (uint8_t *)raw;
    c->size = size;
    memcpy(c->hash, h, WIRE_HASH_SIZE);
    touch(path);
    /* Only offered: the master sends its scene in full when it has another. */
    ct_info(COMP, "scene cache: offering %s (%zu bytes) to the master", path, size);
    return true;
}

void disp_scene_cache_select(disp_scene_cache *c, const char *addr)
{
    if (!c || !c->dir[0]) return;
    char name[32], hex[HEX_LEN + 1], cur[HEX_LEN + 1] = "";
    if (c->raw) wire_hash_hex(c->hash, cur);
    index_name(addr, name);
    const char *tries[2] = {name, "last"};
    for (int i = 0; i < 2; i++) {
        if (!read_index(c, tries[i], hex)) continue;
        if (!strcmp(hex, cur)) {
            char path[4096];
            payload_path(c, hex, path, sizeof path);
            touch(path);
            return;
        }
        if (load(c, hex)) return;
    }
}

typedef struct {
    char name[HEX_LEN + sizeof SUFFIX];
    struct timespec mtime;
    uint64_t size;
} cache_file;

static int newest_first(const void *a, const void *b)
{
    const cache_file *x = a, *y = b;
    if (x->mtime.tv_sec != y->mtime.tv_sec) return x->mtime.tv_sec < y->mtime.tv_sec ? 1 : -1;
    if (x->mtime.tv_nsec != y->mtime.tv_nsec) return x->mtime.tv_nsec < y->mtime.tv_nsec ? 1 : -1;
    return strcmp(x->name, y->name);
}

static void remove_file(const disp_scene_cache *c, const char *name)
{
    char path[4096];
    fs_join(c->dir, name, path, sizeof path);
    if (unlink(path) != 0 && errno != ENOENT)
        ct_warn(COMP, "scene cache: cannot remove %s: %s", path, strerror(errno));
    else
        ct_debug(COMP, "scene cache: removed %s", path);
}

/* Deletes the least recently used payloads beyond max_bytes (never the one in
 * memory), then index files naming a payload that is gone and temporary files
 * left by a display that died while writing. */
static void prune(disp_scene_cache *c)
{
    DIR *d = opendir(c->dir);
    if (!d) return;
    cache_file *files = NULL;
    size_t n = 0, cap = 0;
    time_t now = time(NULL);
    char cur[HEX_LEN + 1] = "";
    if (c->raw) wire_hash_hex(c->hash, cur);
    struct dirent *de;
    while ((de = readdir(d)) != NULL) {
        const char *name = de->d_name;
        char path[4096];
        struct stat st;
        fs_join(c->dir, name, path, sizeof path);
        if (strstr(name, ".tmp.") && (is_hex(name, HEX_LEN) || !strncmp(name, "addr-", 5) ||
                                      !strncmp(name, "last.", 5))) {
            if (stat(path, &st) == 0 && now - st.st_mtime > STALE_TEMP_S) remove_file(c, name);
            continue;
        }
        if (!is_payload_name(name) || stat(path, &st) != 0 || !S_ISREG(st.st_mode)) continue;
        if (n == cap) {
            size_t ncap = cap ? 2 * cap : 64;
            cache_file *g = realloc(files, ncap * sizeof *g);
            if (!g) break;   /* pruning less this time is harmless */
            files = g;
            cap = ncap;
        }
        snprintf(files[n].name, sizeof files[n].name, "%s", name);
        files[n].mtime = st.st_mtim;
        files[n].size = (uint64_t)st.st_size;
        n++;
    }
    closedir(d);
    if (c->max_bytes && n) {
        qsort(files, n, sizeof *files, newest_first);
        uint64_t kept = c->raw ? c->size : 0;
        for (size_t i = 0; i < n; i++) {
            if (!strncmp(files[i].name, cur, HEX_LEN) && cur[0]) continue;
            if (kept + files[i].size <= c->max_bytes) kept += files[i].size;
            else remove_file(c, files[i].name);
        }
    }
    free(files);
    d = opendir(c->dir);
    if (!d) return;
    while ((de = readdir(d)) != NULL) {
        char hex[HEX_LEN + 1], path[4096];
        struct stat st;
        if (!is_index_name(de->d_name) && strcmp(de->d_name, "last") != 0) continue;
        bool gone = !read_index(c, de->d_name, hex);
        if (!gone) {
            payload_path(c, hex, path, sizeof path);
            gone = stat(path, &st) != 0;
        }
        if (gone) remove_file(c, de->d_name);
    }
    closedir(d);
}

void disp_scene_cache_put(disp_scene_cache *c, const char *addr,
                          const uint8_t hash[WIRE_HASH_SIZE], const uint8_t *raw, uint64_t size)
{
    if (!c) return;
    uint8_t *copy = malloc(size ? (size_t)size : 1);
    if (!copy) return;   /* the next connection just gets the scene again */
    memcpy(copy, raw, (size_t)size);
    free(c->raw);
    c->raw = copy;
    c->size = size;
    memcpy(c->hash, hash, WIRE_HASH_SIZE);
    if (!c->dir[0]) return;

    char hex[HEX_LEN + 1], line[HEX_LEN + 2], name[32], path[4096];
    ct_error e;
    wire_hash_hex(hash, hex);
    snprintf(line, sizeof line, "%s\n", hex);
    int rc = fs_mkdirs(c->dir, &e);
    if (!rc) {
        payload_path(c, hex, path, sizeof path);
        rc = fs_write_atomic(path, raw, (size_t)size, &e);
    }
    if (!rc) {
        index_name(addr, name);
        fs_join(c->dir, name, path, sizeof path);
        rc = fs_write_atomic(path, line, HEX_LEN + 1, &e);
    }
    if (!rc) {
        fs_join(c->dir, "last", path, sizeof path);
        rc = fs_write_atomic(path, line, HEX_LEN + 1, &e);
    }
    if (rc) ct_warn(COMP, "scene cache: %s", e.msg);
    prune(c);
}
