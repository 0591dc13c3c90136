#!/usr/bin/env bash
# The display's radiosity viewer on a real .ctmesh: corrtex-display --mesh
# (OSMesa and EGL) against the software Gouraud view of the same mesh from
# corrtex radiosity --image. Both draw rmesh_eval at the primary hit, so they
# agree to float precision when the software view samples pixel centres
# (--spp 1), as GL rasterisation does.
set -u
BIN=${CORRTEX_BIN:-bin}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
run() { echo "+ $*"; "$@"; }
W=96; H=96
# cornell's front camera: eye (278,273,-800), target (278,273,0), fov 39.3
run "$BIN/corrtex" radiosity scenes/cornell/cornell.json -o "$tmp/c.ctmesh" --max-triangles 20000 \
    --image "$tmp/soft.exr" --camera front --width $W --height $H --spp 1 --quiet || exit 1
for be in osmesa egl; do
  run "$BIN/corrtex-display" --mesh "$tmp/c.ctmesh" --backend $be --width $W --height $H \
      --camera 278,273,-800,278,273,0,39.3 --frames 1 --out "$tmp/$be" --quiet || exit 1
  out=$("$BIN/corrtex" compare "$tmp/$be/frame_00000.exr" "$tmp/soft.exr" --json) || exit 1
  rmse=$(sed -n 's/.*"rmse":[[:space:]]*\([0-9.e+-]*\).*/\1/p' <<<"$out" | head -n1)
  echo "metric: display --mesh ($be) vs software Gouraud view: rmse=$rmse (limit 1e-4)"
  awk -v r="$rmse" 'BEGIN{exit !(r < 1e-4)}' || { echo "FAIL: $be differs from the software view"; exit 1; }
done
# a broken mesh file: one error line, exit 2
head -c 100 "$tmp/c.ctmesh" > "$tmp/broken.ctmesh"
"$BIN/corrtex-display" --mesh "$tmp/broken.ctmesh" --backend osmesa --width 8 --height 8 --frames 1 2>"$tmp/err"; rc=$?
echo "+ corrtex-display --mesh broken.ctmesh -> exit $rc: $(cat "$tmp/err")"
[[ $rc -eq 2 ]] || { echo "FAIL: want exit 2"; exit 1; }
grep -q "broken.ctmesh" "$tmp/err" || { echo "FAIL: error must name the file"; exit 1; }
# Multisampling: against the pixel means (64 jittered samples a pixel of the
# software view), --msaa 4 must remove most of the error a centre-sampled
# image has along the edges; more samples than the context allows are cut,
# with a warning.
run "$BIN/corrtex" radiosity scenes/cornell/cornell.json -o "$tmp/c.ctmesh" --max-triangles 20000 \
    --image "$tmp/soft64.exr" --camera front --width $W --height $H --spp 64 --quiet || exit 1
declare -A err=()
for ms in 1 4; do
  run "$BIN/corrtex-display" --mesh "$tmp/c.ctmesh" --backend egl --width $W --height $H \
      --camera 278,273,-800,278,273,0,39.3 --frames 1 --msaa $ms --out "$tmp/ms$ms" --quiet || exit 1
  out=$("$BIN/corrtex" compare "$tmp/ms$ms/frame_00000.exr" "$tmp/soft64.exr" --json) || exit 1
  err[$ms]=$(sed -n 's/.*"rmse":[[:space:]]*\([0-9.e+-]*\).*/\1/p' <<<"$out" | head -n1)
done
echo "metric: display vs the 64-sample pixel means: rmse ${err[1]} with 1 sample, ${err[4]} with --msaa 4 (must be under 0.6 x)"
awk -v a="${err[4]}" -v b="${err[1]}" 'BEGIN{exit !(a < 0.6 * b)}' || { echo "FAIL: --msaa 4 does not average the edges"; exit 1; }
"$BIN/corrtex-display" --mesh "$tmp/c.ctmesh" --backend egl --width 8 --height 8 --frames 1 --msaa 64 \
    --out "$tmp/ms64" 2>"$tmp/err"; rc=$?
echo "+ corrtex-display --msaa 64 -> exit $rc: $(grep msaa "$tmp/err")"
[[ $rc -eq 0 ]] && grep -q "allows" "$tmp/err" || { echo "FAIL: --msaa 64 must be cut with a warning"; exit 1; }
echo "PASS"
