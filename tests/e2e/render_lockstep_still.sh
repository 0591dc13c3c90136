#!/usr/bin/env bash
# Lockstep with a camera that does not move: every CAMERA asks for one frame,
# so the display re-sends its unchanged camera after each drawn frame. With
# K samples a frame, 4 frames of a still camera must all arrive (no wait for a
# camera change), and the error against a high-quality reference of that view
# must not grow as the corrections accumulate. The job and the reference run
# in the reuse-diffuse mode (§4.1: the diffuse part from the radiosity, only
# specular and glossy transport traced): single drt samples carry Monte Carlo
# penumbra noise that, on the Cornell box's accurate radiosity, can make more
# corrections measure worse at 64x64; reuse-diffuse corrections (the mirror,
# the glass) converge to the reference, so frame 3 must beat frame 0 by
# half a dB. K = 100 at 64x64: 100 -> 400 samples gain about 1.1 dB (1.0-1.1
# with a 16, 64 or 256-spp reference and --mix 0.3, 0.5 or 1; the run is
# deterministic). With 300 a frame the gain was 0.1-0.3 dB and one sample
# of a caustic through the glass sphere (5.4 where the 256-spp reference has
# 0.07, splatted over 3x3 pixels) landed in frame 1 and cost 0.6 dB: a
# single outlier, which a still view keeps until better samples cover it.
source "$(dirname "$0")/lib/mpi.sh"
need_programs "$corrtex"
cornell_args
sock="$tmp/still.sock"
K=100
cam=278,273,-800,278,273,0,39.3

master_start master 2 "${CORNELL[@]}" --listen "unix:$sock" --exit-when-display-leaves --mode reuse-diffuse
master_wait_listen master || finish

# The reference on the job's own radiosity mesh (written before it listens).
ref=("$corrtex" reference "${CORNELL[0]}" --camera front --width 64 --height 64 --spp 64 --mode reuse-diffuse
  --radmesh "$tmp/cornell.ctmesh" --threads 2 -o "$tmp/ref/frame_00000.exr")
mkdir -p "$tmp/ref"
log_cmd "${ref[@]}"
"${ref[@]}" >"$tmp/ref.log" 2>&1 || { fail "corrtex reference failed"; cat "$tmp/ref.log"; finish; }
for k in 1 2 3; do cp "$tmp/ref/frame_00000.exr" "$tmp/ref/frame_0000$k.exr"; done

display_run display --connect "$ADDR" "${HEADLESS[@]}" --samples-per-frame $K --camera "$cam" --frames 4 \
  --seconds 60 --out "$tmp/out" --reference "$tmp/ref"
((DISPLAY_RC == 0)) || fail "display exit status $DISPLAY_RC"
master_wait master 20 || fail "the job did not end after the display left"
n=$(ls "$tmp/out"/frame_0000?.exr 2>/dev/null | wc -l)
((n == 4)) || fail "$n frames written, expected 4 (a still camera must still get lockstep frames)"
[[ -f $tmp/out/frames.csv ]] || { fail "no frames.csv"; finish; }
col() { head -n 1 "$1" | tr ',' '\n' | grep -n -x "$2" | cut -d: -f1; }
val() { awk -F, -v c="$(col "$1" "$3")" -v r=$(($2 + 2)) 'NR == r { print $c }' "$1"; }
p0=$(val "$tmp/out/frames.csv" 0 psnr_db); p3=$(val "$tmp/out/frames.csv" 3 psnr_db)
echo "metric: still camera, lockstep K=$K: PSNR frame 0 $p0 dB, frame 3 $p3 dB"
awk -v a="$p0" -v b="$p3" 'BEGIN { exit !(b > a + 0.5) }' || fail "PSNR did not rise by 0.5 dB from frame 0 to frame 3"
finish
