/* The display's scene cache on disk: which payload a connection announces
 * (per master address, else the last one), least-recently-used pruning to a
 * byte bound, and what pruning must never touch. The round trip through a
 * real master is in test_disp_client.c. */
#include <criterion/criterion.h>

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "display/disp_cache.h"

#define PAYLOAD 10000u

typedef struct {
    uint8_t raw[PAYLOAD];
    uint8_t hash[WIRE_HASH_SIZE];
    char path[256];
} payload;

static char g_dir[64];

static void setup(void)
{
    snprintf(g_dir, sizeof g_dir, "/tmp/ctdisp-cache-XXXXXX");
    cr_assert(mkdtemp(g_dir));
}

static void teardown(void)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    cr_expect_eq(system(cmd), 0);
}

/* Distinct content per seed; path is where the cache keeps it. */
static void make_payload(payload *p, uint8_t seed)
{
    for (unsigned i = 0; i < PAYLOAD; i++) p->raw[i] = (uint8_t)(seed * 31u + i * 7u);
    wire_scene_hash(p->raw, PAYLOAD, p->hash);
    char hex[2 * WIRE_HASH_SIZE + 1];
    wire_hash_hex(p->hash, hex);
    snprintf(p->path, sizeof p->path, "%s/%s.ctscene", g_dir, hex);
}

static bool exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* File times come from a coarse kernel clock: steps of the tests that must
 * be ordered by time are this far apart. */
static void tick(void) { usleep(30000); }

/* What a new display process would announce when connecting to addr. */
static bool announced(const char *addr, uint64_t max, uint8_t hash[WIRE_HASH_SIZE])
{
    disp_scene_cache *c = NULL;
    ct_error err;
    cr_assert_eq(disp_scene_cache_new(g_dir, max, &c, &err), 0);
    disp_scene_cache_select(c, addr);
    bool have = disp_scene_cache_hash(c, hash);
    disp_scene_cache_free(c);
    return have;
}

/* A display process receiving p[i] from addr[i] in turn; spaced: one tick
 * between them, so that their file times are ordered. */
static void put_all(uint64_t max, const payload *p, const char *const *addr, int n, bool spaced)
{
    disp_scene_cache *c = NULL;
    ct_error err;
    cr_assert_eq(disp_scene_cache_new(g_dir, max, &c, &err), 0);
    for (int i = 0; i < n; i++) {
        disp_scene_cache_put(c, addr[i], p[i].hash, p[i].raw, PAYLOAD);
        if (spaced) tick();
    }
    disp_scene_cache_free(c);
}

TestSuite(disp_cache, .init = setup, .fini = teardown);

Test(disp_cache, each_master_address_gets_the_scene_it_sent_last)
{
    payload p[2];
    make_payload(&p[0], 1);
    make_payload(&p[1], 2);
    const payload a = p[0], b = p[1];
    uint8_t h[WIRE_HASH_SIZE];
    cr_expect_not(announced("unix:/run/a.sock", 0, h), "an empty cache announces nothing");
    const char *addr[2] = {"unix:/run/a.sock", "tcp:hostb:7000"};
    put_all(0, p, addr, 2, false);
    disp_scene_cache *c = NULL;
    ct_error err;

    cr_assert(announced("unix:/run/a.sock", 0, h));
    cr_expect_eq(memcmp(h, a.hash, WIRE_HASH_SIZE), 0, "master a sent scene a last");
    cr_assert(announced("tcp:hostb:7000", 0, h));
    cr_expect_eq(memcmp(h, b.hash, WIRE_HASH_SIZE), 0, "master b sent scene b last");
    cr_assert(announced("tcp:new-host:7000", 0, h));
    cr_expect_eq(memcmp(h, b.hash, WIRE_HASH_SIZE), 0, "an unknown master gets the last scene");

    /* The payload itself comes back from the file, only under its own hash. */
    cr_assert_eq(disp_scene_cache_new(g_dir, 0, &c, &err), 0);
    disp_scene_cache_select(c, "unix:/run/a.sock");
    const uint8_t *raw = NULL;
    uint64_t size = 0;
    cr_assert(disp_scene_cache_get(c, a.hash, &raw, &size));
    cr_expect_eq(size, PAYLOAD);
    cr_expect_eq(memcmp(raw, a.raw, PAYLOAD), 0);
    cr_expect_not(disp_scene_cache_get(c, b.hash, &raw, &size));
    disp_scene_cache_free(c);
}

Test(disp_cache, a_corrupt_payload_falls_back_to_the_last_scene)
{
    payload p[2];
    make_payload(&p[0], 1);
    make_payload(&p[1], 2);
    const char *addr[2] = {"unix:a", "unix:b"};
    put_all(0, p, addr, 2, false);
    const payload a = p[0], b = p[1];
    FILE *f = fopen(a.path, "r+b");
    cr_assert_not_null(f);
    fputc('x', f);
    fclose(f);
    uint8_t h[WIRE_HASH_SIZE];
    cr_assert(announced("unix:a", 0, h));
    cr_expect_eq(memcmp(h, b.hash, WIRE_HASH_SIZE), 0, "a corrupt payload must not be announced");
}

Test(disp_cache, least_recently_used_payloads_go_first)
{
    payload p[4];
    for (int i = 0; i < 4; i++) make_payload(&p[i], (uint8_t)(i + 1));
    const char *addr[4] = {"unix:0", "unix:1", "unix:2", "unix:3"};
    const uint64_t max = 2 * PAYLOAD + PAYLOAD / 2;   /* room for two */
    put_all(max, p, addr, 3, true);
    cr_expect_not(exists(p[0].path), "the oldest payload is removed");
    cr_expect(exists(p[1].path));
    cr_expect(exists(p[2].path));
    uint8_t h[WIRE_HASH_SIZE];
    cr_assert(announced(addr[0], max, h));
    cr_expect_eq(memcmp(h, p[2].hash, WIRE_HASH_SIZE), 0,
                 "the index of a removed payload is removed: its master gets the last scene");

    /* Using payload 1 makes it younger than payload 2, so 2 goes next. */
    tick();
    cr_assert(announced(addr[1], max, h));
    cr_expect_eq(memcmp(h, p[1].hash, WIRE_HASH_SIZE), 0);
    tick();
    put_all(max, &p[3], &addr[3], 1, false);
    cr_expect(exists(p[1].path), "a payload just used stays");
    cr_expect_not(exists(p[2].path), "the least recently used one goes");
    cr_expect(exists(p[3].path));
}

Test(disp_cache, the_scene_in_use_and_foreign_files_are_never_removed)
{
    payload a, b;
    make_payload(&a, 1);
    make_payload(&b, 2);
    char foreign[256], stale[256], fresh[256];
    snprintf(foreign, sizeof foreign, "%s/notes.ctscene", g_dir);
    snprintf(stale, sizeof stale, "%s.tmp.99999.0", a.path);
    snprintf(fresh, sizeof fresh, "%s.tmp.99999.1", a.path);
    const char *made[3] = {foreign, stale, fresh};
    for (int i = 0; i < 3; i++) {
        FILE *f = fopen(made[i], "wb");
        cr_assert_not_null(f);
        fputs("not a payload", f);
        fclose(f);
    }
    /* A temporary file from a display that died while writing, two hours ago. */
    struct timespec old[2] = {{time(NULL) - 7200, 0}, {time(NULL) - 7200, 0}};
    cr_assert_eq(utimensat(AT_FDCWD, stale, old, 0), 0);

    disp_scene_cache *c = NULL;
    ct_error err;
    cr_assert_eq(disp_scene_cache_new(g_dir, PAYLOAD / 2, &c, &err), 0);   /* smaller than one */
    disp_scene_cache_put(c, "unix:a", a.hash, a.raw, PAYLOAD);
    tick();
    disp_scene_cache_put(c, "unix:b", b.hash, b.raw, PAYLOAD);
    disp_scene_cache_free(c);
    cr_expect_not(exists(a.path));
    cr_expect(exists(b.path), "the payload in use stays even above the bound");
    cr_expect(exists(foreign), "a file that is not a payload stays");
    cr_expect_not(exists(stale), "a stale temporary file goes");
    cr_expect(exists(fresh), "a temporary file being written may stay");
}

Test(disp_cache, without_a_directory_the_scene_stays_in_memory)
{
    payload a;
    make_payload(&a, 1);
    disp_scene_cache *c = NULL;
    ct_error err;
    cr_assert_eq(disp_scene_cache_new(NULL, 1, &c, &err), 0);
    disp_scene_cache_select(c, "unix:a");
    disp_scene_cache_put(c, "unix:a", a.hash, a.raw, PAYLOAD);
    disp_scene_cache_select(c, "unix:b");
    uint8_t h[WIRE_HASH_SIZE];
    cr_assert(disp_scene_cache_hash(c, h));
    cr_expect_eq(memcmp(h, a.hash, WIRE_HASH_SIZE), 0);
    disp_scene_cache_free(c);
    cr_expect(!exists(a.path));
}

Test(disp_cache, an_unwritable_directory_only_warns)
{
    payload a;
    make_payload(&a, 1);
    char dir[128];
    snprintf(dir, sizeof dir, "%s/file", g_dir);
    FILE *f = fopen(dir, "wb");   /* a file where the directory should be */
    cr_assert_not_null(f);
    fclose(f);
    disp_scene_cache *c = NULL;
    ct_error err;
    cr_assert_eq(disp_scene_cache_new(dir, 0, &c, &err), 0);
    disp_scene_cache_select(c, "unix:a");
    disp_scene_cache_put(c, "unix:a", a.hash, a.raw, PAYLOAD);
    uint8_t h[WIRE_HASH_SIZE];
    cr_assert(disp_scene_cache_hash(c, h), "the scene is still kept in memory");
    cr_expect_eq(memcmp(h, a.hash, WIRE_HASH_SIZE), 0);
    disp_scene_cache_free(c);
}
