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
