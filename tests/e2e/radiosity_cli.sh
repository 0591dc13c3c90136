#!/usr/bin/env bash
# corrtex radiosity end to end: solves the Cornell box at a coarse error,
# checks the stats it prints and the .ctmesh it writes, that the result does
# not depend on the thread count (byte-identical files), that --reuse keeps a
# fresh cache and recomputes a stale one, that an output which is not a
# .ctmesh is never replaced, and that bad input exits 2 with one
# error line and a blown memory cap exits 1 naming the cap.
# A room with walls at the coordinate range's edge gives a mesh a tracer takes.
set -u
BIN=${CORRTEX_BIN:-bin}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail=0
exec 3>&1   # commands are logged to the original stdout even when output is redirected
run() { echo "+ $*" >&3; "$@"; }
scene=scenes/cornell/cornell.json
[[ -f scenes/cornell/cornell.obj ]] || { echo "missing $scene meshes (run make scenes)"; exit 1; }

run "$BIN/corrtex" radiosity "$scene" -o "$tmp/a.ctmesh" --error 1e-4 --threads 1 >"$tmp/a.out" 2>"$tmp/a.err" \
  || { echo "FAIL: solve exited $?"; cat "$tmp/a.err"; exit 1; }
cat "$tmp/a.out"
for key in patches links iterations residual triangles seconds; do
  grep -q "^$key " "$tmp/a.out" || { echo "FAIL: stats lack '$key'"; fail=1; }
done
grep -q "^info radiosity: .*triangles.* s$" "$tmp/a.err" || { echo "FAIL: no final stats line on stderr"; fail=1; }
grep -q "^progress radiosity" "$tmp/a.err" || { echo "FAIL: no progress line"; fail=1; }
grep -q "not converged" "$tmp/a.err" && { echo "FAIL: the Cornell box converges, yet a warning says not"; fail=1; }
# Stopped before the tolerance (a closed white room at the defaults): a
# warning says the solution is darker than converged; it used to be silent.
run "$BIN/corrtex" radiosity "$scene" -o "$tmp/n.ctmesh" --error 1e-4 --max-iterations 1 >/dev/null 2>"$tmp/n.err" \
  || { echo "FAIL: the 1-iteration solve exited $?"; fail=1; }
grep -q "^warn radiosity: not converged: residual .* after 1 iterations is above --tolerance" "$tmp/n.err" \
  || { echo "FAIL: no 'not converged' warning"; cat "$tmp/n.err"; fail=1; }
tris=$(awk '$1 == "triangles" { print $2 }' "$tmp/a.out")
patches=$(awk '$1 == "patches" { print $2 }' "$tmp/a.out")
(( tris > 2 * patches )) || { echo "FAIL: $tris triangles for $patches patches: no refinement"; fail=1; }
# Header of the cache: magic, version 2, little-endian check.
head -c 10 "$tmp/a.ctmesh" | od -An -c | tr -s ' ' | grep -q 'C T M E S H \\r \\n 032 \\n' \
  || { echo "FAIL: bad magic"; od -An -c -N 16 "$tmp/a.ctmesh"; fail=1; }
[[ $(od -An -tu4 -j12 -N4 "$tmp/a.ctmesh" | tr -d ' ') == 2 ]] || { echo "FAIL: version is not 2"; fail=1; }
echo "metric: cornell_triangles=$tris"

run "$BIN/corrtex" radiosity "$scene" -o "$tmp/b.ctmesh" --error 1e-4 --threads 2 --quiet >/dev/null \
  || { echo "FAIL: 2-thread solve"; fail=1; }
cmp "$tmp/a.ctmesh" "$tmp/b.ctmesh" || { echo "FAIL: 1 and 2 threads give different meshes"; fail=1; }

# --image: the Gouraud view from a scene camera, PNG and EXR.
run "$BIN/corrtex" radiosity "$scene" -o "$tmp/a.ctmesh" --error 1e-4 --reuse --image "$tmp/v.png" --camera front \
  --width 64 --height 48 --spp 2 --quiet >/dev/null || { echo "FAIL: --image png"; fail=1; }
[[ $(head -c 8 "$tmp/v.png" | od -An -tx1 | tr -d ' ') == 89504e470d0a1a0a ]] || { echo "FAIL: not a PNG"; fail=1; }
run "$BIN/corrtex" radiosity "$scene" -o "$tmp/a.ctmesh" --error 1e-4 --reuse --image "$tmp/v.exr" --width 64 \
  --height 48 --quiet >/dev/null || { echo "FAIL: --image exr"; fail=1; }
run "$BIN/corrtex" compare "$tmp/v.exr" "$tmp/v.exr" --max-rmse 0 >/dev/null || { echo "FAIL: the EXR does not read back"; fail=1; }

run "$BIN/corrtex" radiosity "$scene" -o "$tmp/a.ctmesh" --error 1e-4 --reuse >"$tmp/r.out" 2>"$tmp/r.err" || fail=1
grep -q "^cached 1" "$tmp/r.out" || { echo "FAIL: --reuse did not keep a fresh cache"; cat "$tmp/r.err"; fail=1; }
run "$BIN/corrtex" radiosity "$scene" -o "$tmp/a.ctmesh" --error 2e-4 --reuse >"$tmp/r.out" 2>"$tmp/r.err" || fail=1
grep -q "^cached 1" "$tmp/r.out" && { echo "FAIL: --reuse kept a stale cache"; fail=1; }
grep -q "stale" "$tmp/r.err" || { echo "FAIL: no 'stale' reason logged"; cat "$tmp/r.err"; fail=1; }

# Bad input: exit 2, exactly one error line naming the problem.
printf 'v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n' > "$tmp/dark.obj"
printf '{"meshes":[{"file":"dark.obj"}]}' > "$tmp/dark.json"
check() { # expected-exit expected-substring args...
  local want=$1 msg=$2; shift 2
  "$BIN/corrtex" radiosity "$@" >"$tmp/o" 2>"$tmp/e"; rc=$?
  echo "+ $BIN/corrtex radiosity $*  -> exit $rc: $(grep '^error' "$tmp/e")"
  [[ $rc -eq $want ]] || { echo "FAIL: exit $rc, want $want"; fail=1; }
  [[ $(grep -c '^error ' "$tmp/e") -eq 1 ]] || { echo "FAIL: want exactly one error line"; cat "$tmp/e"; fail=1; }
  grep -q -- "$msg" "$tmp/e" || { echo "FAIL: message lacks '$msg'"; fail=1; }
}
check 2 "expected one scene file" -o "$tmp/x.ctmesh"
check 2 "missing.json" "$tmp/missing.json" -o "$tmp/x.ctmesh"
check 2 "no emitting surface" "$tmp/dark.json" -o "$tmp/x.ctmesh"
check 2 "\-\-error: 'abc'" "$scene" -o "$tmp/x.ctmesh" --error abc
check 2 "\-\-threads" "$scene" -o "$tmp/x.ctmesh" --threads 0
check 2 "unknown option '--bogus'" "$scene" -o "$tmp/x.ctmesh" --bogus
check 2 "\-\-mirror-samples: '-1'" "$scene" -o "$tmp/x.ctmesh" --mirror-samples -1
check 2 "\-\-mirror-samples: '4097'" "$scene" -o "$tmp/x.ctmesh" --mirror-samples 4097
check 2 "\-\-vertex-rays: '1025'" "$scene" -o "$tmp/x.ctmesh" --vertex-rays 1025
check 2 "\-\-gather-passes: '17'" "$scene" -o "$tmp/x.ctmesh" --gather-passes 17
check 2 "\-\-gather-passes: '-1'" "$scene" -o "$tmp/x.ctmesh" --gather-passes -1
check 2 "\-\-dim-floor: '1.5'" "$scene" -o "$tmp/x.ctmesh" --dim-floor 1.5
# An output file's folder is not made (docs/architecture.md, "Outputs"):
# refused before the scene is read, naming the missing folder.
check 2 "x.ctmesh: cannot create: its folder $tmp/no/such/dir does not exist" "$tmp/missing.json" \
  -o "$tmp/no/such/dir/x.ctmesh" --error 1e-2
check 2 "p.exr: cannot create: its folder $tmp/no/such/dir does not exist" "$scene" -o "$tmp/x.ctmesh" \
  --image-planes "$tmp/no/such/dir/p.exr" --error 1e-2
[[ ! -e $tmp/no ]] || { echo "FAIL: a folder was made for an output file"; fail=1; }
check 2 "no camera named 'nope'" "$scene" -o "$tmp/x.ctmesh" --image "$tmp/x.png" --camera nope
# An image name the format does not match (a .jpg got EXR bytes), refused before the solve.
check 2 "\-\-image $tmp/v.jpg: give a name ending in .exr (linear) or .png (sRGB)" "$scene" -o "$tmp/x.ctmesh" --image "$tmp/v.jpg"
check 2 "\-\-image-planes $tmp/p.png: give a name ending in .exr" "$scene" -o "$tmp/x.ctmesh" --image-planes "$tmp/p.png"
# An output that is not a .ctmesh (the scene itself, a document) is not
# replaced, with or without --reuse: it used to be, by a mesh.
cp "$scene" "$tmp/scene-copy.json"; cp scenes/cornell/cornell.obj scenes/cornell/cornell.mtl "$tmp/"
check 2 "scene-copy.json: exists and is not a corrtex mesh (.ctmesh): not replaced" "$tmp/scene-copy.json" \
  -o "$tmp/scene-copy.json" --error 1e-2
cmp -s "$scene" "$tmp/scene-copy.json" || { echo "FAIL: -o the scene file replaced it"; fail=1; }
echo "notes" >"$tmp/notes.txt"
check 2 "notes.txt: exists and is not a corrtex mesh" "$scene" -o "$tmp/notes.txt" --reuse --error 1e-2
[[ $(cat "$tmp/notes.txt") == notes ]] || { echo "FAIL: --reuse replaced a text file"; fail=1; }
: >"$tmp/empty.ctmesh"
run "$BIN/corrtex" radiosity "$scene" -o "$tmp/empty.ctmesh" --error 1e-2 --quiet >/dev/null ||
  { echo "FAIL: an empty output file was refused"; fail=1; }
check 1 "memory cap of 16 MB" "$scene" -o "$tmp/x.ctmesh" --error 1e-9 --min-area 1e-12 --memory-cap 16
[[ -e $tmp/x.ctmesh ]] && { echo "FAIL: a failed run left an output"; fail=1; }
# corrtex-render's solver options go through the same checks (a singleton
# MPI run: the options are refused before any rank work). Under the
# sanitizers Open MPI's own allocations live until exit: the suppressions
# and the slow unwinder of tests/e2e/lib/mpi.sh (without them LeakSanitizer
# aborted the run, exit 134, after the right message).
menv=(OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1)
if [[ -n ${ASAN_OPTIONS:-} ]]; then
  menv+=("LSAN_OPTIONS=${LSAN_OPTIONS:+$LSAN_OPTIONS:}suppressions=$(cd "$(dirname "$0")" && pwd)/lib/lsan-mpi.supp:print_suppressions=0"
    "ASAN_OPTIONS=$ASAN_OPTIONS:fast_unwind_on_malloc=0")
fi
env "${menv[@]}" timeout 60 "$BIN/corrtex-render" "$scene" --rad-dim-floor 2 >"$tmp/o" 2>"$tmp/e"; rc=$?
echo "+ $BIN/corrtex-render $scene --rad-dim-floor 2  -> exit $rc: $(grep '^error' "$tmp/e")"
[[ $rc -eq 2 ]] || { echo "FAIL: corrtex-render exit $rc, want 2"; fail=1; }
[[ $(grep -c '^error ' "$tmp/e") -eq 1 ]] || { echo "FAIL: corrtex-render: want exactly one error line"; cat "$tmp/e"; fail=1; }
grep -q -- "--rad-dim-floor: '2'" "$tmp/e" || { echo "FAIL: corrtex-render's message lacks the option"; fail=1; }

# A closed room with its walls at the coordinate range's edge (+-1e9, which
# the scene format allows): subdivided corners rounded a float step past it
# and the mesh's own loader refused the .ctmesh (corrtex-render failed to
# start). Now the mesh keeps to the range and a tracer takes it.
e=1e+09
{
  echo "usemtl wall"
  for f in "$e -$e -$e|$e $e -$e|-$e $e -$e|-$e -$e -$e" "-$e $e $e|$e $e $e|$e -$e $e|-$e -$e $e" \
           "-$e -$e -$e|-$e $e -$e|-$e $e $e|-$e -$e $e" "$e -$e $e|$e $e $e|$e $e -$e|$e -$e -$e" \
           "-$e -$e $e|$e -$e $e|$e -$e -$e|-$e -$e -$e" "-$e $e -$e|$e $e -$e|$e $e $e|-$e $e $e"; do
    IFS='|' read -r a b c d <<<"$f"; printf 'v %s\nv %s\nv %s\nv %s\n' "$a" "$b" "$c" "$d"
  done
  for i in 0 4 8 12 16 20; do echo "f $((i + 1)) $((i + 2)) $((i + 3)) $((i + 4))"; done
} >"$tmp/edge.obj"
cat >"$tmp/edge.json" <<'JSON'
{"meshes": [{"file": "edge.obj"}], "materials": {"wall": {"diffuse": [0.5, 0.5, 0.5]}},
 "cameras": [{"name": "c", "eye": [0, 0, -9e8], "target": [0, 0, 0]}],
 "lights": [{"type": "quad", "corner": [-1e8, 9.9e8, -1e8], "edge1": [0, 0, 2e8], "edge2": [2e8, 0, 0],
             "emission": [10, 10, 10]}]}
JSON
run "$BIN/corrtex" radiosity "$tmp/edge.json" -o "$tmp/edge.ctmesh" --max-triangles 20000 --quiet >/dev/null \
  || { echo "FAIL: the room at the range's edge did not solve"; fail=1; }
run "$BIN/corrtex" reference "$tmp/edge.json" --radmesh "$tmp/edge.ctmesh" --width 16 --height 16 --spp 1 --mode drt \
  --quiet -o "$tmp/edge.exr" >/dev/null 2>"$tmp/edge.err" \
  || { echo "FAIL: the room's mesh was refused: $(cat "$tmp/edge.err")"; fail=1; }
exit $fail
