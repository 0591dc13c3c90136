#!/usr/bin/env bash
# corrtex reference on a real radiosity mesh (--radmesh): drt and reuse-diffuse
# run on it (the per-sample non-negativity of reuse-diffuse corrections is a
# unit test; here the distance to the radiosity view is printed), a mesh of
# another scene is refused clearly, reuse-diffuse without a mesh too.
set -u
BIN=${CORRTEX_BIN:-bin}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
run() { echo "+ $*"; "$@"; }
run "$BIN/corrtex" radiosity scenes/cornell/cornell.json -o "$tmp/c.ctmesh" --max-triangles 20000 \
    --image "$tmp/rad.exr" --width 48 --height 48 --spp 4 --quiet >/dev/null || exit 1
run "$BIN/corrtex" reference scenes/cornell/cornell.json --radmesh "$tmp/c.ctmesh" --mode reuse-diffuse \
    --width 48 --height 48 --spp 4 -o "$tmp/reuse.exr" --quiet || exit 1
run "$BIN/corrtex" reference scenes/cornell/cornell.json --radmesh "$tmp/c.ctmesh" --mode drt \
    --width 48 --height 48 --spp 4 -o "$tmp/drt.exr" --quiet || exit 1
out=$("$BIN/corrtex" compare "$tmp/reuse.exr" "$tmp/rad.exr" --json) || exit 1
echo "metric: reuse-diffuse vs radiosity view: $out" | tr -d '\n\t'; echo
"$BIN/corrtex" reference scenes/table/table.json --radmesh "$tmp/c.ctmesh" --mode drt --width 8 --height 8 \
    --spp 1 -o "$tmp/x.exr" 2>"$tmp/err"; rc=$?
echo "+ reference table.json --radmesh cornell.ctmesh -> exit $rc: $(cat "$tmp/err")"
[[ $rc -eq 2 ]] || { echo "FAIL: a mesh of another scene must be refused with exit 2"; exit 1; }
grep -q "radiosity mesh" "$tmp/err" || { echo "FAIL: message must say what is wrong"; exit 1; }
"$BIN/corrtex" reference scenes/cornell/cornell.json --mode reuse-diffuse --width 8 --height 8 --spp 1 \
    -o "$tmp/y.exr" 2>"$tmp/err2"; rc=$?
echo "+ reference --mode reuse-diffuse without a mesh -> exit $rc: $(cat "$tmp/err2")"
[[ $rc -eq 2 ]] && grep -q -- "--radmesh" "$tmp/err2" || { echo "FAIL: reuse-diffuse without a mesh"; exit 1; }
