#!/usr/bin/env bash
# What a new user gets with no optional flags (issue 27): a display given
# only --connect starts from the view the master suggests (the scene's first
# camera) and, headless without --frames, draws until a signal ends it in
# order (exit 0, frames.csv complete); a still view keeps refining past one
# sample per pixel (the master logs full coverage, then refinement, and the
# image ends closer to a converged reference of the same mode than one
# sample per pixel gets: drt with one shadow ray, so that noise is what one
# sample per pixel leaves); once the master is idle the display stops
# redrawing the unchanged view (--continuous draws anyway); corrtex-walk on a scene without a camera path
# walks the still view.
source "$(dirname "$0")/lib/mpi.sh"
source "$root/tests/e2e/lib/walk-san-env.bash"
need_programs "$corrtex"
# The Cornell box with its mirror and glass made glossy: refinement is for
# glossy noise, and a caustic through the glass (a rare path worth 80 times
# its pixel) in the few pixels refinement samples most would decide a PSNR
# over 4,096 pixels by itself.
scene="$tmp/glossy.json"
cat >"$scene" <<JSON
{
  "name": "cornell-glossy",
  "meshes": [ { "file": "$root/scenes/cornell/cornell.obj", "name": "box" } ],
  "materials": {
    "light": { "emission": [17, 12, 4] },
    "brushed_metal": { "diffuse": [0.04, 0.04, 0.04],
                       "ward": { "rho_s": [0.62, 0.6, 0.56], "alpha_x": 0.04, "alpha_y": 0.25, "tangent": [0.1, 1, 0.1] } },
    "mirror": { "diffuse": [0.1, 0.1, 0.1], "ward": { "rho_s": [0.6, 0.6, 0.6], "alpha_x": 0.15, "alpha_y": 0.15 } },
    "glass": { "diffuse": [0.2, 0.2, 0.2], "ward": { "rho_s": [0.5, 0.5, 0.5], "alpha_x": 0.1, "alpha_y": 0.1 } }
  },
  "cameras": [ { "name": "front", "eye": [278, 273, -800], "target": [278, 273, 0], "up": [0, 1, 0], "fov": 39.3 } ]
}
JSON
# One radiosity mesh for the job and the reference: drt takes its indirect light from it.
rad=("$corrtex" radiosity "$scene" --max-triangles 20000 -o "$tmp/cornell.ctmesh" --quiet)
log_cmd "${rad[@]}"
"${rad[@]}" || { fail "corrtex radiosity failed"; finish; }
ref=("$corrtex" reference "$scene" --camera front --width 64 --height 64 --spp 64 --mode drt --shadow-rays 1
  --threads 2 --radmesh "$tmp/cornell.ctmesh" -o "$tmp/ref.exr")
log_cmd "${ref[@]}"
"${ref[@]}" >"$tmp/ref.log" 2>&1 || { fail "corrtex reference failed"; cat "$tmp/ref.log"; finish; }

master_start job 2 "$scene" --mesh "$tmp/cornell.ctmesh" --listen "unix:$tmp/r.sock" --stats-s 0.25 --shadow-rays 1
master_wait_listen job || finish
# 1. Only --connect (and the headless size): no camera, no frames.
display_start plain --connect "$ADDR" "${HEADLESS[@]}" --out "$tmp/plain" --out-every 0.2 --no-images \
  --reference "$tmp/ref.exr"
for ((i = 0; i < 100; i++)); do grep -q '(refining:' "$tmp/job.log" && break; sleep 0.1; done
sleep 3
echo "+ kill -TERM <display>"
kill -TERM "$DISPLAY_PID"
wait "$DISPLAY_PID"; rc=$?
sed 's/^/  plain: /' "$tmp/plain.log" | tail -n 6
((rc == 0)) || fail "the display ended with status $rc after SIGTERM (want 0)"
csv="$tmp/plain/frames.csv"
rows=$(($(wc -l <"$csv" 2>/dev/null || echo 1) - 1))
((rows >= 5)) || fail "frames.csv has $rows rows after SIGTERM"
eye=$(awk -F, 'NR == 2 { printf "%.0f,%.0f,%.0f", $3, $4, $5 }' "$csv")
[[ $eye == 278,273,-800 ]] || fail "the display started at eye $eye, not the scene's first camera (278,273,-800)"
grep -q 'lag from insertion' "$tmp/plain.log" || fail "no lag line"
# 2. Refinement past full coverage, and the image still getting better.
grep -q 'view covered: every pixel sampled' "$tmp/job.log" || fail "the master never logged full coverage"
grep -q '(refining: ' "$tmp/job.log" || fail "no refinement after full coverage"
refined=$(awk -F, 'NR > 1 { p = $NF } END { print p }' "$csv")
master_term job
# The same view without refinement (one sample per pixel, the paper's end).
master_start once 2 "$scene" --mesh "$tmp/cornell.ctmesh" --listen "unix:$tmp/o.sock" --shadow-rays 1 --refine-error 0
master_wait_listen once || finish
display_run once --connect "$ADDR" "${HEADLESS[@]}" --seconds 2 --out "$tmp/once" --out-every 0.2 --no-images \
  --reference "$tmp/ref.exr"
once=$(awk -F, 'NR > 1 { p = $NF } END { print p }' "$tmp/once/frames.csv")
echo "metric: PSNR against the 64-spp reference: one sample per pixel $once dB, refined $refined dB"
awk -v a="$once" -v b="$refined" 'BEGIN { exit !(b > a + 0.5) }' ||
  fail "refinement did not bring the still view closer to the reference ($once -> $refined dB)"
# A master that went idle sends nothing new: the display stops redrawing
# the unchanged view (but for its captures), unless told --continuous.
idle=$(sed -n 's/^display: nothing new to draw for \([0-9.]*\) s.*/\1/p' "$tmp/once.log")
echo "metric: display idle (nothing new to draw) for ${idle:-0} s of 2 s once the master went idle"
awk -v t="${idle:-0}" 'BEGIN { exit !(t >= 0.5) }' || fail "the display kept redrawing an unchanged view"
display_run cont --connect "$ADDR" "${HEADLESS[@]}" --seconds 1 --continuous --out "$tmp/cont" --no-images
grep -q 'nothing new to draw' "$tmp/cont.log" && fail "--continuous skipped frames"
n_cont=$(($(wc -l <"$tmp/cont/frames.csv") - 1))
((n_cont >= 5)) || fail "--continuous drew $n_cont frames in 1 s"
master_term once
# 3. corrtex-walk on a scene without a camera path: the still view.
mkdir -p "$tmp/nopath"
cat >"$tmp/nopath/cornell.json" <<JSON
{
  "name": "cornell",
  "meshes": [ { "file": "$root/scenes/cornell/cornell.obj", "name": "box" } ],
  "materials": { "light": { "emission": [17, 12, 4] } },
  "cameras": [ { "name": "front", "eye": [278, 273, -800], "target": [278, 273, 0], "up": [0, 1, 0], "fov": 39.3 } ]
}
JSON
"$corrtex" info "$tmp/nopath/cornell.json" >/dev/null 2>"$tmp/info.err" ||
  { fail "the path-less scene copy does not load"; cat "$tmp/info.err"; finish; }
walk=("$root/scripts/corrtex-walk" "$tmp/nopath/cornell.json" --frames 3 --samples-per-frame 200 --width 64
  --height 64 --ranks 2 --listen "unix:$tmp/walk.sock" --out "$tmp/walk" --radiosity-cache "$tmp/walk.ctmesh"
  --radiosity-options "--max-triangles 20000" --display local --backend egl --timeout 120)
log_cmd "${walk[@]}"
(cd "$root" && env -u DISPLAY XDG_CACHE_HOME="$tmp/xdg" CORRTEX_BIN="$bin" "${walk[@]}") >"$tmp/walk.out" 2>&1; rc=$?
tail -n 5 "$tmp/walk.out" | sed 's/^/  walk: /'
((rc == 0)) || fail "corrtex-walk on a scene without a path: exit $rc"
rows=$(($(wc -l <"$tmp/walk/frames.csv" 2>/dev/null || echo 1) - 1))
((rows == 3)) || fail "the path-less walk drew $rows frames, want 3"
finish
