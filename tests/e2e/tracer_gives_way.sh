#!/usr/bin/env bash
# When a tracer rank gives a batch up for a newer view (docs/distributed.md,
# "Camera changes"), against a real rank over real MPI: tests/tools/
# tracer_script plays the master (rank 0) and checks that a batch goes on
# after a camera change until a batch of the newer view has come (before,
# the rank stopped or skipped it and then waited idle for the master: a
# camera moving faster than the master's round trip kept it idle half the
# time), and that once one has come, the batches of older views stop or go
# empty and the newer one is traced whole; and that the rank naps, not
# spins inside MPI, while a batch's transfer waits on a master that calls no
# MPI (its CPU time beside its tracing: a blocking receive spun a tracer's
# core on the master's time).
source "$(dirname "$0")/lib/mpi.sh"
script="$root/${CORRTEX_BUILD:-build/release}/tools/tracer_script"
need_programs "$script"

render=$script mpi_cmd 2 "$root/scenes/cornell/cornell.json" front
log_cmd env "${MPI_ENV[@]}" "${MPI_CMD[@]}"
env "${MPI_ENV[@]}" "${MPI_CMD[@]}" >"$tmp/script.log" 2>&1
rc=$?
grep -E '^(batch|tracer:|FAIL)' "$tmp/script.log" | sed 's/^/  /'
((rc == 0)) || { fail "tracer_script exited $rc"; tail -n 20 "$tmp/script.log" | sed 's/^/  log: /'; }
(($(grep -c '^batch ' "$tmp/script.log") == 5)) || fail "not every batch was answered"
finish
