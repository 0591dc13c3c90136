#!/usr/bin/env bash
# Free-running mode (the default): the display draws at its own rate while
# patches stream in. A display at cornell's front camera draws 300 frames as
# fast as it can; meanwhile the master samples every pixel once (coverage
# 100 % in the stats) and streams the corrections. Checks: full coverage;
# the display's last frame carries the corrections (it differs from the
# radiosity view of a second display) and its first frame did not wait for
# them; the errors against a reference are printed. (Which of the two is
# closer to a 16-spp reference at one sample per pixel depends on the order
# in which samples arrived; lockstep runs test the error, render_lockstep.sh.)
source "$(dirname "$0")/lib/mpi.sh"
need_programs "$corrtex"
cornell_args
CAM=(--camera 278,273,-800,278,273,0,39.3)
ref=("$corrtex" reference "${CORNELL[0]}" --camera front --width 64 --height 64 --spp 16 --mode drt --threads 2
  -o "$tmp/ref.exr")
log_cmd "${ref[@]}"
"${ref[@]}" >"$tmp/ref.log" 2>&1 || { fail "corrtex reference failed"; cat "$tmp/ref.log"; finish; }

master_start job 3 "${CORNELL[@]}" --listen "unix:$tmp/r.sock" --stats-s 0.25 --shadow-rays 16 --branch 8
master_wait_listen job || finish
display_run free --connect "$ADDR" "${HEADLESS[@]}" "${CAM[@]}" --frames 300 --out "$tmp/free"
((DISPLAY_RC == 0)) || fail "display exit status $DISPLAY_RC"
for ((i = 0; i < 50; i++)); do grep -q 'coverage 100.0%' "$tmp/job.log" && break; sleep 0.1; done
grep -q 'coverage 100.0%' "$tmp/job.log" || fail "the master never reached 100 % coverage"
display_run rad --connect "$ADDR" "${HEADLESS[@]}" "${CAM[@]}" --view radiosity --frames 1 --out "$tmp/rad"
kill -TERM "$(rank_pid job 0)"
master_wait job 20 || fail "the job did not end"
((MASTER_RC == 0)) || fail "job exit status $MASTER_RC"
master_log job | grep -v progress | grep 'stats:' | head -n 4
last=$(printf '%s/free/frame_%05d.exr' "$tmp" 299)
[[ -f $last ]] || { fail "no frame 299"; finish; }
c=$("$corrtex" compare "$last" "$tmp/ref.exr" | sed -n 's/^rmse //p')
r=$("$corrtex" compare "$tmp/rad/frame_00000.exr" "$tmp/ref.exr" | sed -n 's/^rmse //p')
d=$("$corrtex" compare "$last" "$tmp/rad/frame_00000.exr" | sed -n 's/^rmse //p')
d0=$("$corrtex" compare "$tmp/free/frame_00000.exr" "$tmp/rad/frame_00000.exr" | sed -n 's/^rmse //p')
echo "metric: free-running rmse after full coverage $c, radiosity alone $r (64x64, 2 tracers)"
echo "metric: corrections in the last frame: rmse $d against the radiosity view (first frame: $d0)"
awk -v d="$d" 'BEGIN { exit !(d > 0.005) }' || fail "the last frame shows no corrections (rmse $d to radiosity)"
awk -v d="$d" -v d0="$d0" 'BEGIN { exit !(d0 < d) }' || fail "the first frame already had every correction"
finish
