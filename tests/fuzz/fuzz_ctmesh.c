/* fuzz_ctmesh.c: libFuzzer target for the .ctmesh decoder (common/radmesh_io.c):
 * no input may crash it, and an input it accepts must encode back to exactly
 * the same bytes. Build and run: make fuzz (FUZZ_SECONDS=20). With
 * FUZZ_WRITE_SEEDS=DIR the binary writes valid seed files into DIR and exits. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/radmesh.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerInitialize(int *argc, char ***argv);

/* A small valid mesh: n triangles in a strip, two nodes. */
static void seed_mesh(ct_radmesh *m, uint32_t n)
{
    rmesh_alloc(m, n + 2, n, 2, NULL);
    for (uint32_t i = 0; i < n + 2; i++) {
        m->pos[i] = v3((float)(i / 2), (float)(i % 2), 0.0f);
        m->nrm[i] = v3(0, 0, 1);
        m->rad[i] = v3(0.5f * (float)i, 1.0f, 2.0f);
        m->rad_direct[i] = v3(0.25f * (float)i, 0.5f, 1.0f);
    }
    for (uint32_t t = 0; t < n; t++) {
        m->tris[3 * t] = t;
        m->tris[3 * t + 1] = t + 1;
        m->tris[3 * t + 2] = t + 2;
        m->tri_node[t] = 1;
        m->tri_mat[t] = 0;
    }
    snprintf(m->nodes[0].name, sizeof m->nodes[0].name, "root");
    m->nodes[0].parent = -1;
    m->nodes[0].node_end = 2;
    m->nodes[0].material = UINT32_MAX;
    snprintf(m->nodes[1].name, sizeof m->nodes[1].name, "part");
    m->nodes[1].parent = 0;
    m->nodes[1].node_end = 2;
    m->nodes[1].material = 0;
    m->scene_hash = 0x1234u + n;
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    const char *dir = getenv("FUZZ_WRITE_SEEDS");
    if (!dir) return 0;
    for (uint32_t n = 1; n <= 4; n++) {
        ct_radmesh m;
        seed_mesh(&m, n);
        unsigned char *buf;
        size_t len;
        if (rmesh_encode(&m, &buf, &len, NULL) == 0) {
            char path[4096];
            snprintf(path, sizeof path, "%s/seed-%u", dir, n);
            FILE *f = fopen(path, "wb");
            if (f) {
                fwrite(buf, 1, len, f);
                fclose(f);
            }
            free(buf);
        }
        rmesh_free(&m);
    }
    exit(0);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ct_radmesh m;
    ct_error err;
    if (rmesh_decode(data, size, "fuzz", 0, &m, &err) != 0) return 0;
    unsigned char *buf;
    size_t len;
    if (rmesh_encode(&m, &buf, &len, &err) != 0) __builtin_trap();
    if (len != size || memcmp(buf, data, size) != 0) __builtin_trap();
    free(buf);
    rmesh_free(&m);
    return 0;
}
