#!/usr/bin/env bash
# The samples view (paper Fig. 7) with real sample points: corrtex-render
# under mpirun -np 2 (a master, one tracer) on cornell, a headless display in
# lockstep (K samples per frame) with --view samples, its camera far enough
# back that the box fills only the middle of the 64x64 image. The master
# sends the hit points of the samples it inserted (SAMPLES); the display
# draws them as dots in the sample colour. Checks: the frames show many such
# dots; every dot lies on geometry (a radiosity-only frame of the same
# camera, drawn from the scene without a master, is the mask; one pixel
# of slack at silhouettes), none on the background; the master logged no
# dropped points; a full-view frame of the same run has no such dots.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
K=600
CAM=(--camera 278,273,-2000,278,273,0,39.3)

check="$tmp/samples_check"
cc_cmd=("${CC:-cc}" -O1 -o "$check" "$root/tests/e2e/lib/samples_check.c" -lpng)
log_cmd "${cc_cmd[@]}"
"${cc_cmd[@]}" || { fail "cannot build the pixel checker"; finish; }

master_start master 2 "${CORNELL[@]}" --listen "unix:$tmp/render.sock" --stats-s 0.2
master_wait_listen master || finish
display_run samples --connect "$ADDR" "${HEADLESS[@]}" --samples-per-frame $K --frames 3 "${CAM[@]}" \
  --view samples --sample-frames 3 --out "$tmp/samples"
((DISPLAY_RC == 0)) || fail "samples-view display exit status $DISPLAY_RC"
display_run full --connect "$ADDR" "${HEADLESS[@]}" --samples-per-frame $K --frames 1 "${CAM[@]}" --out "$tmp/full"
((DISPLAY_RC == 0)) || fail "full-view display exit status $DISPLAY_RC"
echo "+ kill -TERM <rank 0>"
kill -TERM "$(rank_pid master 0)"
master_wait master 20 || fail "the job did not end"
master_log master | grep -v -e progress | tail -n 8
grep -q 'sample points dropped' "$tmp/master.log" && fail "the master dropped sample points with an idle queue"

# The mask: the scene drawn alone with the same camera and a stand-in radiosity
# (ambient light on every material, so no surface is black, unlike the unlit
# outsides of the box in the real solution).
display_run mask --scene "${CORNELL[0]}" "${HEADLESS[@]}" --view radiosity "${CAM[@]}" --out "$tmp/mask"
((DISPLAY_RC == 0)) || fail "mask display exit status $DISPLAY_RC"

for k in 0 2; do
  f=$(printf 'frame_%05d.png' $k)
  log_cmd "$check" "$tmp/samples/$f" "$tmp/mask/frame_00000.png"
  out=$("$check" "$tmp/samples/$f" "$tmp/mask/frame_00000.png") || { fail "checker failed on $f"; continue; }
  echo "$out" | grep '^metric:' | sed "s/^metric:/metric: frame $k:/"
  read -r _ dots on_geo on_bg geo total <<<"$(echo "$out" | grep '^counts')"
  ((geo > total / 8 && geo < total * 3 / 4)) || fail "frame $k: geometry covers $geo of $total pixels; the camera should show background around the box"
  ((dots >= 100)) || fail "frame $k: only $dots sample-coloured pixels (K=$K per frame)"
  ((on_bg == 0)) || fail "frame $k: $on_bg sample-coloured pixels on the background"
done
# Frame 2 shows the points of frames 0..2 (--sample-frames 3): more than frame 0.
d0=$("$check" "$tmp/samples/frame_00000.png" "$tmp/mask/frame_00000.png" | awk '/^counts/ { print $2 }')
d2=$("$check" "$tmp/samples/frame_00002.png" "$tmp/mask/frame_00000.png" | awk '/^counts/ { print $2 }')
((d2 > d0)) || fail "frame 2 shows $d2 dots, frame 0 $d0: points of earlier frames are not kept"
read -r _ dots _ <<<"$("$check" "$tmp/full/frame_00000.png" "$tmp/mask/frame_00000.png" | grep '^counts')"
((dots == 0)) || fail "the full view has $dots sample-coloured pixels"
finish
