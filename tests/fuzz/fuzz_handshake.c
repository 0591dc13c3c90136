/* fuzz_handshake.c: libFuzzer target for the handshake state machine (HELLO, AUTH/ERROR frame) as master or display, with or without a token.
 * Build and run: make fuzz (FUZZ_SECONDS=20). The body lives in
 * tests/support/proto_fixtures.c so test_fuzz_replay runs it on the seeds and
 * on tests/fuzz/corpus/handshake/ without libFuzzer. With FUZZ_WRITE_SEEDS=DIR the
 * binary writes its seed inputs into DIR and exits. */
#include "tests/fuzz/fuzz_proto_target.h"

FUZZ_PROTO_TARGET(handshake)
