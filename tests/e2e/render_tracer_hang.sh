#!/usr/bin/env bash
# A tracer that stops answering (SIGSTOP: alive for MPI, silent for us) must
# not hang the job: with --tracer-timeout-s 2 the master reports the rank,
# tells the display (ERROR) and aborts the job, which ends in a few seconds.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
master_start job 3 "${CORNELL[@]}" --listen "unix:$tmp/r.sock" --tracer-timeout-s 2
master_wait_listen job || finish
victim=$(rank_pid job 1)
[[ -n $victim ]] || { fail "tracer rank 1 not found"; finish; }
echo "+ kill -STOP $victim   (tracer rank 1)"
kill -STOP "$victim"
t0=$(date +%s.%N)
display_run display --connect "$ADDR" "${HEADLESS[@]}" --camera 278,273,-800,278,273,0,39.3 --samples-per-frame 1000 \
  --frames 1 --out "$tmp/out"
((DISPLAY_RC == 3)) || fail "display exit status $DISPLAY_RC, expected 3 (connection lost)"
grep -q 'tracer rank 1 has not answered' "$tmp/display.log" || fail "the display does not name the silent rank"
# Detection (2 s) is checked above through the display's message: the master
# has found the silent rank, told the display and aborted the job. A stopped
# process cannot take the SIGTERM of mpirun's teardown; on a loaded 2-core
# machine mpirun then took up to 17 s and sometimes more than 30 s to escalate.
# A hung tracer in real life is running (a loop, a stuck call) and does take
# SIGTERM, so resume the victim now; the job must then end promptly.
echo "+ kill -CONT $victim"
kill -CONT "$victim" 2>/dev/null
master_wait job 30 || fail "the job did not end within 30 s"
secs=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
echo "metric: job ended ${secs} s after the display asked for work (tracer timeout 2 s)"
((MASTER_RC != 0)) || fail "exit status 0 after a silent tracer"
master_log job | grep -v progress | tail -n 10
grep -q 'error corrtex-render: tracer rank 1 has not answered for' "$tmp/job.log" || fail "no error line on the master"
finish
