/* test_fuzz_replay.c: runs the fuzz target bodies without libFuzzer: on their
 * generated seeds, on deterministic mutations of them (bit flips, cuts,
 * inserted and overwritten bytes), and on every regression input under
 * tests/fuzz/corpus/<target>/. A target traps (fails the test) when a
 * decoder misbehaves; the sanitizer build catches memory errors. */
#include <criterion/criterion.h>
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"
#include "proto/wire.h"
#include "tests/support/proto_fixtures.h"

typedef int (*body_fn)(const uint8_t *data, size_t size);

typedef struct seeds {
    wire_buf all;    /* u32 length + bytes, repeated */
    size_t count;
} seeds;

static void collect(const uint8_t *d, size_t n, void *ctx)
{
    seeds *s = ctx;
    uint32_t len = (uint32_t)n;
    wire_buf_append(&s->all, &len, 4, NULL);
    wire_buf_append(&s->all, d, n, NULL);
    s->count++;
}

static size_t mutate(ct_rng *r, const uint8_t *in, size_t n, uint8_t *out, size_t cap)
{
    size_t len = n < cap ? n : cap;
    memcpy(out, in, len);
    int ops = 1 + (int)(rng_u32(r) % 4);
    for (int k = 0; k < ops; k++) {
        uint32_t op = rng_u32(r) % 5, at = len ? rng_u32(r) % (uint32_t)len : 0;
        switch (op) {
        case 0: if (len) out[at] ^= (uint8_t)(1u << (rng_u32(r) % 8)); break;
        case 1: if (len) out[at] = (uint8_t)rng_u32(r); break;
        case 2: len = at; break; /* cut */
        case 3: /* insert a byte */
            if (len < cap) {
                memmove(out + at + 1, out + at, len - at);
                out[at] = (uint8_t)rng_u32(r);
                len++;
            }
            break;
        case 4: /* an interesting value in a 32-bit field */
            if (len >= 4) {
                static const uint32_t vals[] = {0, 1, 0x7fffffff, 0xffffffff, 0x10000, 65535, 0x7fc00000};
                uint32_t v = vals[rng_u32(r) % 7];
                size_t p = at > len - 4 ? len - 4 : at;
                for (int i = 0; i < 4; i++) out[p + (size_t)i] = (uint8_t)(v >> (8 * i));
            }
            break;
        }
    }
    return len;
}

static void replay(const char *target, body_fn body, int mutations)
{
    seeds s = {{0}, 0};
    fx_fuzz_seeds(target, collect, &s);
    cr_assert_gt(s.count, 0, "%s: no seeds", target);
    static uint8_t buf[1 << 16];
    ct_rng r = rng_make(2026, 5, 0, 0);
    size_t off = 0;
    size_t lens[64], offs[64], n = 0;
    while (off < s.all.len && n < 64) {
        uint32_t len;
        memcpy(&len, s.all.data + off, 4);
        offs[n] = off + 4;
        lens[n++] = len;
        body(s.all.data + off + 4, len);
        off += 4 + len;
    }
    for (int i = 0; i < mutations; i++) {
        size_t k = rng_u32(&r) % n;
        size_t len = mutate(&r, s.all.data + offs[k], lens[k], buf, sizeof buf - 1);
        body(buf, len);
    }
    /* Regression inputs kept in the source tree. */
    char dir[256];
    snprintf(dir, sizeof dir, "tests/fuzz/corpus/%s", target);
    DIR *d = opendir(dir);
    int files = 0;
    if (d) {
        struct dirent *e;
        while ((e = readdir(d))) {
            if (e->d_name[0] == '.') continue;
            char path[600];
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            FILE *f = fopen(path, "rb");
            if (!f) continue;
            size_t len = fread(buf, 1, sizeof buf, f);
            fclose(f);
            body(buf, len);
            files++;
        }
        closedir(d);
    }
    cr_log_info("%s: %zu seeds, %d mutations, %d corpus files", target, n, mutations, files);
    wire_buf_free(&s.all);
}

Test(fuzz_replay, wire) { replay("wire", fx_fuzz_wire, 20000); }
Test(fuzz_replay, handshake) { replay("handshake", fx_fuzz_handshake, 5000); }
Test(fuzz_replay, scene) { replay("scene", fx_fuzz_scene, 20000); }
Test(fuzz_replay, mpi) { replay("mpi", fx_fuzz_mpi, 20000); }
