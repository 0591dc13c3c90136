/* fuzz_mpi.c: libFuzzer target for the MPI message decoders (whatever decodes must re-encode to the same bytes).
 * Build and run: make fuzz (FUZZ_SECONDS=20). The body lives in
 * tests/support/proto_fixtures.c so test_fuzz_replay runs it on the seeds and
 * on tests/fuzz/corpus/mpi/ without libFuzzer. With FUZZ_WRITE_SEEDS=DIR the
 * binary writes its seed inputs into DIR and exits. */
#include "tests/fuzz/fuzz_proto_target.h"

FUZZ_PROTO_TARGET(mpi)
