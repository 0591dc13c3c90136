/* fuzz_scene.c: libFuzzer target for the SCENE payload parser (a payload that parses must re-serialize to the same bytes).
 * Build and run: make fuzz (FUZZ_SECONDS=20). The body lives in
 * tests/support/proto_fixtures.c so test_fuzz_replay runs it on the seeds and
 * on tests/fuzz/corpus/scene/ without libFuzzer. With FUZZ_WRITE_SEEDS=DIR the
 * binary writes its seed inputs into DIR and exits. */
#include "tests/fuzz/fuzz_proto_target.h"

FUZZ_PROTO_TARGET(scene)
