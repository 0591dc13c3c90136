/* fuzz_scene.c: libFuzzer target for the SCENE payload parser (a payload that parses must re-serialize to the same bytes).
 * Build and run: make fuzz (FUZZ_SECONDS=20). The body lives in
 * tests/support/proto_fixtures.c so test_fuzz_replay runs it on the seeds and
 * on tests/fuzz/corpus/scene/ without libFuzzer. With FUZZ_WRITE_SEEDS=DIR the
 * binary writes its seed inputs into DIR and exits. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "tests/support/proto_fixtures.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerInitialize(int *argc, char ***argv);

static void write_seed(const uint8_t *data, size_t size, void *ctx)
{
    int *n = ctx;
    char path[4096];
    snprintf(path, sizeof path, "%s/seed-%03d", getenv("FUZZ_WRITE_SEEDS"), (*n)++);
    FILE *f = fopen(path, "wb");
    if (!f) return;
    fwrite(data, 1, size, f);
    fclose(f);
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    if (getenv("FUZZ_WRITE_SEEDS")) {
        int n = 0;
        fx_fuzz_seeds("scene", write_seed, &n);
        exit(0);
    }
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fx_fuzz_scene(data, size);
}
