#!/usr/bin/env bash
# --texel-fps: a display that shares its host with tracer ranks redraws a
# still view for new texels at most F times a second (docs/display.md,
# "Sharing a host with the tracers"). Two displays watch the same still view
# of the Cornell box for 4 s each while the master (2 tracer ranks) streams
# corrections: one with --texel-fps 2, which may draw the first frame, the
# last and one every half second (at most 2 x 4 + 3), and one without,
# which draws whenever texels arrive. Checks: the capped display stays
# within its bound and draws fewer frames than the other, and its last
# frame still carries the corrections (it differs from the radiosity view).
# A third display holds its redraws to 0.1 cores with --texel-cpu for 6 s
# (a 128x128 frame, its uploads and its frames.csv row cost 3-90 CPU ms, so
# it waits a few hundredths to most of a second between them; the first
# frame's shader compilation does not count, since it once held the view
# for 3 s under the sanitizers): at least 3 frames, their CPU time within
# 1.5 x the budget, and new texels held back for at least 0.3 s.
# While held, texels collect in the inbox and reach the screen with
# the next frame: the lag statistics count them all (they once counted only
# the texels of the last look at the inbox before a frame).
source "$(dirname "$0")/lib/mpi.sh"
need_programs "$corrtex"
cornell_args
CAM=(--camera 278,273,-800,278,273,0,39.3)
master_start job 3 "${CORNELL[@]}" --listen "unix:$tmp/r.sock" --stats-s 0.25 --shadow-rays 16 --branch 8
master_wait_listen job || finish
# The display prints "display: N frames in S s; ...".
frames_of() { sed -n 's/^display: \([0-9]*\) frames in .*/\1/p' "$tmp/$1.log"; }
display_run capped --connect "$ADDR" "${HEADLESS[@]}" --width 128 --height 128 "${CAM[@]}" --seconds 4 \
  --texel-fps 2 --out "$tmp/capped"
((DISPLAY_RC == 0)) || fail "capped display exit status $DISPLAY_RC"
display_run free --connect "$ADDR" "${HEADLESS[@]}" --width 128 --height 128 "${CAM[@]}" --seconds 4 \
  --out "$tmp/free"
((DISPLAY_RC == 0)) || fail "free display exit status $DISPLAY_RC"
display_run cpu --connect "$ADDR" "${HEADLESS[@]}" --width 128 --height 128 "${CAM[@]}" --seconds 6 \
  --texel-cpu 0.1 --out "$tmp/cpu" --no-images
((DISPLAY_RC == 0)) || fail "--texel-cpu display exit status $DISPLAY_RC"
display_run rad --connect "$ADDR" "${HEADLESS[@]}" --width 128 --height 128 "${CAM[@]}" --view radiosity \
  --frames 1 --out "$tmp/rad"
kill -TERM "$(rank_pid job 0)"
master_wait job 20 || fail "the job did not end"
((MASTER_RC == 0)) || fail "job exit status $MASTER_RC"
nc=$(frames_of capped) nf=$(frames_of free)
echo "metric: frames in 4 s of a still view while texels stream: $nc with --texel-fps 2, $nf without"
[[ -n $nc && -n $nf ]] || { fail "a display printed no frame count"; finish; }
((nc <= 11)) || fail "--texel-fps 2 drew $nc frames in 4 s (at most 11)"
((nc < nf)) || fail "--texel-fps 2 drew $nc frames, no fewer than the uncapped display's $nf"
ncpu=$(frames_of cpu)
# "display: N frames in S s; ... X CPU ms per frame; ..."
cpu_ms=$(sed -n 's/^display: .* \([0-9.]*\) CPU ms per frame.*/\1/p' "$tmp/cpu.log")
echo "metric: frames in 6 s with --texel-cpu 0.1: $ncpu, ${cpu_ms} CPU ms each"
[[ -n $ncpu && -n $cpu_ms ]] && ((ncpu >= 3)) &&
  awk -v n="$ncpu" -v c="$cpu_ms" 'BEGIN { exit !(n * c / 6000 <= 1.5 * 0.1) }' ||
  fail "--texel-cpu 0.1 drew $ncpu frames of ${cpu_ms:-?} CPU ms in 6 s (3 or more, within 0.15 cores)"
# Held back: after a frame of X CPU ms the display waits about 9 X ms
# (0.1 cores), while texels wait in its inbox. Frames of 3-5 ms (a still
# view whose textures no longer change size) make that 1-1.5 s in all, so
# the bound is a third of a second: without the budget it is 0.
held=$(sed -n 's/^display: new texels held back for \([0-9.]*\) s.*/\1/p' "$tmp/cpu.log")
echo "metric: --texel-cpu 0.1 held new texels back for ${held:-0} s of 6 s"
awk -v h="${held:-0}" 'BEGIN { exit !(h >= 0.3) }' ||
  fail "--texel-cpu 0.1 held new texels back for ${held:-0} s (at least 0.3 s)"
# Samples the lag statistics counted against those the master reported
# after its first STATS (which holds all the job inserted before the display
# came; it lands in the second or a later row, depending on how soon the
# display draws).
for d in capped cpu; do
  lagn=$(sed -n 's/^display: lag .* over \([0-9]*\) samples$/\1/p' "$tmp/$d.log")
  col=$(head -n 1 "$tmp/$d/frames.csv" | tr ',' '\n' | grep -n '^samples$' | cut -d: -f1)
  sum=$(awk -F, -v c="$col" 'NR > 1 && !seen && $c > 0 { seen = 1; next } seen { s += $c } END { print s + 0 }' \
    "$tmp/$d/frames.csv")
  echo "metric: $d display: lag counted for $lagn samples, the master reported $sum"
  [[ -n $lagn && -n $col ]] && awk -v a="$lagn" -v b="$sum" 'BEGIN { exit !(b > 0 && a >= 0.5 * b) }' ||
    fail "$d display: the lag counted $lagn of $sum samples"
done
last=$(ls "$tmp/capped"/frame_*.exr | tail -n 1)
d=$("$corrtex" compare "$last" "$tmp/rad/frame_00000.exr" | sed -n 's/^rmse //p')
echo "metric: the capped display's last frame: rmse $d against the radiosity view"
awk -v d="$d" 'BEGIN { exit !(d > 0.005) }' || fail "the capped display's last frame shows no corrections (rmse $d)"
# A bad value is refused with one line naming the option.
"$display" --texel-fps -1 --scene "${CORNELL[0]}" >"$tmp/bad.out" 2>&1
rc=$?
((rc == 2)) || fail "--texel-fps -1: exit status $rc, not 2"
grep -q -- "--texel-fps: '-1'" "$tmp/bad.out" || { fail "--texel-fps -1: no message naming it"; cat "$tmp/bad.out"; }
"$display" --texel-cpu 2000 --scene "${CORNELL[0]}" >"$tmp/bad.out" 2>&1
rc=$?
((rc == 2)) || fail "--texel-cpu 2000: exit status $rc, not 2"
grep -q -- "--texel-cpu: '2000'" "$tmp/bad.out" || { fail "--texel-cpu 2000: no message naming it"; cat "$tmp/bad.out"; }
finish
