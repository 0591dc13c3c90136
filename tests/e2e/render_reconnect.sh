#!/usr/bin/env bash
# The display may leave (even killed with SIGKILL) and come back: the master
# keeps its state, and the new display receives the scene and every live
# texture. Job B: a display asks for lockstep frames of 256 samples at
# cornell's front camera, writes its first frame and is killed -9; a new
# display connects and asks for one more frame of 256 samples. Job A: one
# display asks for a single frame with as many samples as job B took in all
# (256 per frame B's master completed, counted in its log). Both frames must
# be equal bit for bit: the same samples in the same order (rounds of 256),
# and everything the first display had received was resent to the second.
# Job B then ends on SIGTERM to the master.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
CAM=(--camera 278,273,-800,278,273,0,39.3)

master_start jobB 3 "${CORNELL[@]}" --listen "unix:$tmp/b.sock" --verbose
master_wait_listen jobB || finish
display_start B1 --connect "$ADDR" "${HEADLESS[@]}" "${CAM[@]}" --samples-per-frame 256 --frames 2 --out "$tmp/B1"
for ((i = 0; i < 300; i++)); do [[ -s $tmp/B1/frame_00000.exr ]] && break; sleep 0.1; done
[[ -s $tmp/B1/frame_00000.exr ]] || fail "display B1 wrote no frame"
sleep 0.3
echo "+ kill -9 $DISPLAY_PID   (display B1)"
kill -9 "$DISPLAY_PID"; wait "$DISPLAY_PID" 2>/dev/null
for ((i = 0; i < 50; i++)); do grep -q 'left:' "$tmp/jobB.log" && break; sleep 0.1; done
grep -q 'left:' "$tmp/jobB.log" || fail "the master did not notice that display B1 left"

display_run B2 --connect "$ADDR" "${HEADLESS[@]}" "${CAM[@]}" --samples-per-frame 256 --frames 1 --out "$tmp/B2"
((DISPLAY_RC == 0)) || fail "display B2 exit status $DISPLAY_RC"
grep -q 'sent the scene (.*) and [1-9][0-9]* textures' "$tmp/jobB.log" || fail "B2 did not get the live textures"

m0=$(rank_pid jobB 0)
echo "+ kill -TERM $m0   (rank 0)"
kill -TERM "$m0"
master_wait jobB 20 || fail "job B did not end after SIGTERM to the master"
((MASTER_RC == 0)) || fail "job B exit status $MASTER_RC after SIGTERM to the master"
master_log jobB | grep -v -e progress -e 'debug ctex' | tail -n 16
[[ -e $tmp/b.sock ]] && fail "socket file left behind"

# Frames job B completed (B1 may have asked for more than one frame of the
# still view before it died; a frame in progress is completed anyway).
nb=$(grep -c 'debug master: frame [0-9]*: 256 samples' "$tmp/jobB.log")
((nb >= 2)) || fail "job B completed $nb frames, expected at least 2"
KA=$((256 * nb))
master_start jobA 3 "${CORNELL[@]}" --listen "unix:$tmp/a.sock" --exit-when-display-leaves
master_wait_listen jobA || finish
display_run A --connect "$ADDR" "${HEADLESS[@]}" "${CAM[@]}" --samples-per-frame $KA --frames 1 --out "$tmp/A"
((DISPLAY_RC == 0)) || fail "display A exit status $DISPLAY_RC"
master_wait jobA 20 || fail "job A did not end"
echo "metric: job B: $nb frames of 256 samples across the reconnect; job A: one frame of $KA samples"
if cmp -s "$tmp/A/frame_00000.exr" "$tmp/B2/frame_00000.exr"; then
  echo "metric: frame after reconnecting is bit-identical to the uninterrupted run"
else
  fail "the frame after reconnecting differs from the uninterrupted run"
  [[ -x $corrtex ]] && "$corrtex" compare "$tmp/B2/frame_00000.exr" "$tmp/A/frame_00000.exr"
fi
cmp -s "$tmp/B1/frame_00000.exr" "$tmp/B2/frame_00000.exr" && fail "the second frame equals the first (no new samples?)"
finish
