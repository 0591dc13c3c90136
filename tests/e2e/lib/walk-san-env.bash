# Sourced by tests that start scripts/corrtex-walk ($root set). Sanitizer
# builds: the MPI job that corrtex-walk starts gets the same settings as the
# tests that run mpirun directly (lib/mpi.sh): Open MPI's own until-exit
# allocations suppressed, found by the slow unwinder. Only the MPI job: the
# display (llvmpipe) would crawl with the slow unwinder.
if [[ -n ${ASAN_OPTIONS:-} ]]; then
  export CORRTEX_WALK_MPI_ENV="LSAN_OPTIONS=${LSAN_OPTIONS:+$LSAN_OPTIONS:}suppressions=$root/tests/e2e/lib/lsan-mpi.supp:print_suppressions=0 ASAN_OPTIONS=$ASAN_OPTIONS:fast_unwind_on_malloc=0"
fi
