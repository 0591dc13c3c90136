/* fuzz_proto_target.h: the libFuzzer entry points shared by the proto fuzz
 * targets. FUZZ_PROTO_TARGET(name) defines LLVMFuzzerInitialize (with
 * FUZZ_WRITE_SEEDS=DIR it writes the target's generated seeds there and exits)
 * and LLVMFuzzerTestOneInput (fx_fuzz_<name> from tests/support/proto_fixtures). */
#ifndef CT_FUZZ_PROTO_TARGET_H
#define CT_FUZZ_PROTO_TARGET_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "tests/support/proto_fixtures.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerInitialize(int *argc, char ***argv);

static void fuzz_write_seed(const uint8_t *data, size_t size, void *ctx)
{
    int *n = ctx;
    char path[4096];
    snprintf(path, sizeof path, "%s/seed-%03d", getenv("FUZZ_WRITE_SEEDS"), (*n)++);
    FILE *f = fopen(path, "wb");
    if (!f) return;
    fwrite(data, 1, size, f);
    fclose(f);
}

#define FUZZ_PROTO_TARGET(name)                                   \
    int LLVMFuzzerInitialize(int *argc, char ***argv)             \
    {                                                             \
        (void)argc;                                               \
        (void)argv;                                               \
        if (getenv("FUZZ_WRITE_SEEDS")) {                         \
            int n = 0;                                            \
            fx_fuzz_seeds(#name, fuzz_write_seed, &n);            \
            exit(0);                                              \
        }                                                         \
        return 0;                                                 \
    }                                                             \
    int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)  \
    {                                                             \
        return fx_fuzz_##name(data, size);                        \
    }

#endif
