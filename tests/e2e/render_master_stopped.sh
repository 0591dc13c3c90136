#!/usr/bin/env bash
# A master that stops (SIGSTOP to rank 0) under a lockstep display: the
# display waits for its next FRAME, and SIGTERM still ends it within a
# second or two, with status 0 and the frames it drew written (frames.csv
# closed, not lost). Its wait for a FRAME used to look at --seconds and the
# keys only: a stopped or misbehaving master kept it until the socket closed.
# Then the master continues (SIGCONT) and SIGTERM ends the job in order.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
master_start job 2 "${CORNELL[@]}" --listen "unix:$tmp/m.sock"
master_wait_listen job || finish
display_start display --connect "$ADDR" "${HEADLESS[@]}" --camera 278,273,-800,278,273,0,39.3 \
  --samples-per-frame 200 --frames 100000 --out "$tmp/out" --no-images
# a few frames drawn: frames.csv is written as the run goes
for ((i = 0; i < 300; i++)); do (($(wc -l <"$tmp/out/frames.csv" 2>/dev/null || echo 0) > 3)) && break; sleep 0.1; done
(($(wc -l <"$tmp/out/frames.csv" 2>/dev/null || echo 0) > 3)) || { fail "the display drew no frames"; finish; }
rank0=$(rank_pid job 0)
[[ -n $rank0 ]] || { fail "rank 0 not found"; finish; }
echo "+ kill -STOP $rank0   (rank 0)"
kill -STOP "$rank0"
sleep 1
rows=$(wc -l <"$tmp/out/frames.csv")
echo "+ kill -TERM <display>"
t0=$EPOCHREALTIME
kill -TERM "$DISPLAY_PID"
display_gone
dt=$(awk -v a="$t0" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f", b - a }')
echo "metric: a lockstep display under a stopped master ended $dt s after SIGTERM (exit $DISPLAY_RC)"
sed 's/^/  display: /' "$tmp/display.log" | tail -n 4
((DISPLAY_RC == 0)) || fail "display exit status $DISPLAY_RC after SIGTERM, want 0"
awk -v t="$dt" 'BEGIN { exit !(t < 3) }' || fail "the display took $dt s to end after SIGTERM"
((rows > 3)) && (($(wc -l <"$tmp/out/frames.csv") >= rows)) || fail "frames.csv lost rows ($rows before)"
echo "+ kill -CONT $rank0"
kill -CONT "$rank0"
master_term job
finish
