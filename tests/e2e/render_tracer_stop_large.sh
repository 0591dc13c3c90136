#!/usr/bin/env bash
# A tracer that stops (SIGSTOP) in the middle of sending a large sample
# batch (4096 samples, about 300 KB: MPI moves the rest of it only when the
# sender makes progress): tests/e2e/lib/stop_after_send.c stops rank 1 right
# after it starts its second such message. The master used to match the
# message and block in its receive for good (the watchdog never ran, the
# display got nothing); now its receives are polled, and after
# --tracer-timeout-s it names the rank to the display and ends the job, as
# render_tracer_hang.sh checks for a tracer stopped while idle.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
command -v mpicc >/dev/null || skip "mpicc not found (install libopenmpi-dev)"
shim="$tmp/stop_after_send.so"
log_cmd mpicc -shared -fPIC -O1 -o "$shim" "$root/tests/e2e/lib/stop_after_send.c"
mpicc -shared -fPIC -O1 -o "$shim" "$root/tests/e2e/lib/stop_after_send.c" || { fail "cannot build the shim"; finish; }
cornell_args
MPIRUN_EXTRA="-x LD_PRELOAD=$shim -x CORRTEX_STOP_RANK=1 -x CORRTEX_STOP_AFTER=2" \
  master_start job 2 "${CORNELL[@]}" --listen "unix:$tmp/r.sock" --tracer-timeout-s 2 \
  --batch-min 4096 --batch-max 4096
master_wait_listen job || finish
victim=$(rank_pid job 1)
[[ -n $victim ]] || { fail "tracer rank 1 not found"; finish; }
t0=$(date +%s.%N)
display_run display --connect "$ADDR" --backend egl --width 256 --height 256 --quiet \
  --camera 278,273,-800,278,273,0,39.3 --seconds 20
secs=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
((DISPLAY_RC == 3)) || fail "display exit status $DISPLAY_RC, expected 3 (connection lost; 124: the master hangs)"
grep -q 'tracer rank 1 has not answered' "$tmp/display.log" || fail "the display does not name the silent rank"
echo "metric: the display heard of the stopped tracer ${secs} s after it connected (tracer timeout 2 s)"
# As in render_tracer_hang.sh: a stopped process cannot take mpirun's SIGTERM.
echo "+ kill -CONT $victim"
kill -CONT "$victim" 2>/dev/null
master_wait job 30 || fail "the job did not end within 30 s"
((MASTER_RC != 0)) || fail "exit status 0 after a silent tracer"
master_log job | grep -v -e progress -e stats | tail -n 8
grep -q 'error corrtex-render: tracer rank 1 has not answered for' "$tmp/job.log" || fail "no error line on the master"
finish
