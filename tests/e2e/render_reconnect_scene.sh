#!/usr/bin/env bash
# A display that reconnects (--reconnect, no --camera) to a master of another
# scene starts at that scene's view: it kept the old scene's camera (the
# Cornell box's eye at z = -800 mm, far outside the mini scene: a black
# window) and its speed, and the new master then took that view as its own.
# Job C serves the Cornell box; the display draws a few frames; job C ends
# on SIGTERM to rank 0; job M serves tests/data/scenes/mini.json on the same
# socket; the display's last frames must be at mini's first camera.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
sock="unix:$tmp/s.sock"

master_start jobC 2 "${CORNELL[@]}" --listen "$sock"
master_wait_listen jobC || finish
display_start D --connect "$sock" "${HEADLESS[@]}" --reconnect --seconds 40 --out "$tmp/D" --no-images --out-every 0.2
for ((i = 0; i < 300; i++)); do (($(wc -l <"$tmp/D/frames.csv" 2>/dev/null || echo 0) >= 3)) && break; sleep 0.1; done
master_term jobC
master_start jobM 2 "$root/tests/data/scenes/mini.json" --rad-cache "$tmp/mini.ctmesh" --rad-max-triangles 20000 \
  --listen "$sock"
master_wait_listen jobM || finish
# (the display's back-off is at most 8 s; frames.csv is written as it goes)
for ((i = 0; i < 300; i++)); do
  [[ $(tail -n 1 "$tmp/D/frames.csv" | cut -d, -f3-5) == 0,1,4 ]] && break
  sleep 0.1
done
sleep 0.5
echo "+ kill -TERM $DISPLAY_PID   (display)"
kill -TERM "$DISPLAY_PID"; wait "$DISPLAY_PID"; rc=$?
sed 's/^/  D: /' "$tmp/D.log" | tail -n 8
((rc == 0)) || fail "display exit status $rc"
master_term jobM
# frames.csv: frame,time_s,eye_x,eye_y,eye_z,...: the first rows at the Cornell
# box's front camera, the last at mini's front camera (0, 1, 4).
first=$(awk -F, 'NR == 2 { print $3, $4, $5 }' "$tmp/D/frames.csv")
final=$(awk -F, 'END { print $3, $4, $5 }' "$tmp/D/frames.csv")
echo "metric: eye in the first frame ($first), in the last ($final)"
awk -v e="$first" 'BEGIN { split(e, v, " "); exit !(v[1] == 278 && v[2] == 273 && v[3] == -800) }' \
  || fail "the first frames are not at the Cornell box's camera: $first"
awk -v e="$final" 'BEGIN { split(e, v, " "); exit !(v[1] == 0 && v[2] == 1 && v[3] == 4) }' \
  || fail "after reconnecting to the mini scene the eye is $final, not its camera 0 1 4"
finish
