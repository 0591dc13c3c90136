#!/usr/bin/env bash
# corrtex info on good and broken scenes: exit 0 / 2, and for each broken one
# exactly one error line on stderr that names the offending file.
set -u
BIN=${CORRTEX_BIN:-bin}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail=0
run() { echo "+ $*"; "$@"; }

run "$BIN/corrtex" info tests/data/scenes/mini.json --json >"$tmp/out.json" 2>"$tmp/err" || { echo "mini failed"; cat "$tmp/err"; exit 1; }
for key in nodes primitives triangles materials emitters cameras paths bounds; do
  grep -q "\"$key\"" "$tmp/out.json" || { echo "missing key $key in --json output"; fail=1; }
done

printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > "$tmp/ok.obj"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n' > "$tmp/range.obj"
printf 'v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n' > "$tmp/nan.obj"
printf 'v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n' > "$tmp/degen.obj"
printf '{"meshes":[{"file":"ok.obj"}],\n "oops" }\n' > "$tmp/syntax.json"
printf '{"meshes":[{"file":"range.obj"}]}' > "$tmp/range.json"
printf '{"meshes":[{"file":"nan.obj"}]}' > "$tmp/nan.json"
printf '{"meshes":[{"file":"degen.obj"}]}' > "$tmp/degen.json"
printf '{"meshes":[{"file":"ok.obj"}],"materials":{"m":{"shiny":1}}}' > "$tmp/key.json"
printf '{}' > "$tmp/empty.json"
# Trailing garbage, and a key given twice (the first used to win silently).
printf '{"meshes":[{"file":"ok.obj"}]}\n} x\n' > "$tmp/trailing.json"
printf '{"meshes":[{"file":"ok.obj"}],"materials":{"m":{"diffuse":[1,0,0],"diffuse":[0,0,1]}}}' > "$tmp/dupkey.json"
printf '{"meshes":[{"file":"ok.obj"}],\n "meshes":[]}' > "$tmp/dupmesh.json"
# Coordinates beyond the range rays can take (a camera at -1e30 aborted the
# tracer inside Embree; a light edge of 1e30 rendered black).
printf '{"meshes":[{"file":"ok.obj"}],"cameras":[{"name":"c","eye":[0,1,-1e30],"target":[0,0,0]}]}' > "$tmp/far_cam.json"
printf '{"meshes":[{"file":"ok.obj"}],"lights":[{"type":"quad","corner":[0,2,0],"edge1":[1e30,0,0],"edge2":[0,0,1],"emission":[1,1,1]}]}' > "$tmp/far_light.json"

check() { # file expected-substring
  local f=$1 want=$2
  "$BIN/corrtex" info "$f" >"$tmp/o" 2>"$tmp/e"; rc=$?
  echo "+ $BIN/corrtex info $f  -> exit $rc: $(cat "$tmp/e")"
  [[ $rc -eq 2 ]] || { echo "FAIL: $f: exit $rc, want 2"; fail=1; }
  [[ $(grep -c '^error ' "$tmp/e") -eq 1 ]] || { echo "FAIL: $f: want exactly one error line"; fail=1; }
  grep -q -- "$want" "$tmp/e" || { echo "FAIL: $f: message lacks '$want'"; fail=1; }
}
check "$tmp/missing.json" "missing.json"
check "$tmp/syntax.json" "syntax.json:2:"
check "$tmp/range.json" "range.obj"
check "$tmp/nan.json" "nan.obj"
check "$tmp/degen.json" "no triangles"
check "$tmp/key.json" "unknown key 'shiny'"
check "$tmp/empty.json" "empty.json"
check "$tmp/trailing.json" "trailing.json:2:1: trailing characters after the JSON value"
check "$tmp/dupkey.json" "dupkey.json: duplicate key 'diffuse' in 'm'"
check "$tmp/dupmesh.json" "dupmesh.json: duplicate key 'meshes' at the top level"
# A mesh file without triangles next to others: loaded, with a warning naming it.
printf 'v 0 0 0\nv 1 0 0\nl 1 2\n' > "$tmp/lines.obj"
printf '{"meshes":[{"file":"ok.obj"},{"file":"lines.obj"}]}' > "$tmp/lines.json"
"$BIN/corrtex" info "$tmp/lines.json" >"$tmp/o" 2>"$tmp/e"; rc=$?
echo "+ $BIN/corrtex info $tmp/lines.json  -> exit $rc: $(cat "$tmp/e")"
[[ $rc -eq 0 ]] || { echo "FAIL: lines.json: exit $rc, want 0"; fail=1; }
grep -q '^warn scene: .*lines.obj: no triangles' "$tmp/e" || { echo "FAIL: no warning naming lines.obj"; fail=1; }
check "$tmp/far_cam.json" "far_cam.json: camera 'c': eye or target outside the coordinate range"
check "$tmp/far_light.json" "far_light.json: lights\[0\]: corner 1 at (1e+30, 2, 0) is outside the coordinate range"
for cmd in "reference --width 8 --height 8 --spp 1 --mode path -o $tmp/far.exr" "radiosity -o $tmp/far.ctmesh --image $tmp/far.png"; do
  "$BIN/corrtex" ${cmd%% *} "$tmp/far_cam.json" ${cmd#* } >"$tmp/o" 2>"$tmp/e"; rc=$?
  echo "+ $BIN/corrtex ${cmd%% *} $tmp/far_cam.json ${cmd#* } -> exit $rc: $(cat "$tmp/e")"
  [[ $rc -eq 2 && $(grep -c '^error ' "$tmp/e") -eq 1 ]] || { echo "FAIL: corrtex ${cmd%% *}: want exit 2 and one error line"; fail=1; }
done
"$BIN/corrtex" info >/dev/null 2>&1; [[ $? -eq 2 ]] || { echo "FAIL: no argument must exit 2"; fail=1; }
"$BIN/corrtex" info --bogus x >/dev/null 2>&1; [[ $? -eq 2 ]] || { echo "FAIL: unknown option must exit 2"; fail=1; }
"$BIN/corrtex" frobnicate >/dev/null 2>&1; [[ $? -eq 2 ]] || { echo "FAIL: unknown command must exit 2"; fail=1; }
exit $fail
