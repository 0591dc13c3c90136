#!/usr/bin/env bash
# corrtex naive (the walkthrough benchmark's baselines) on cornell at 48x48:
# one frame and one frames.csv row per path frame, the samples column is K;
# radiosity alone (K = 0) and the point display are bit-identical for any
# thread count; K samples do change the radiosity image; the error columns
# against references exist; --hold keeps old samples (its frames differ from
# fresh ones); --path names the scene's path even beside a folder of that
# name; bad input gives one error line and exit 2, before the output folder
# is made.
source "$(dirname "$0")/lib/common.sh"
c=$corrtex
run() { echo "+ $*"; "$@"; }
[[ -x $c ]] || { echo "error: $c not built"; exit 1; }
scene="$root/scenes/cornell/cornell.json"; pathf="$root/scenes/cornell/walk.path"
[[ -f $scene ]] || { echo "error: $scene missing (make scenes)"; exit 1; }
w=48; n=3; k=300

run "$c" radiosity "$scene" -o "$tmp/c.ctmesh" --max-triangles 20000 --quiet >/dev/null || { echo "FAIL: radiosity"; exit 1; }
run "$c" reference "$scene" --path "$pathf" --frames $n --width $w --height $w --spp 4 --mode path --quiet -o "$tmp/ref" >/dev/null \
  || { echo "FAIL: references"; exit 1; }
common=("$scene" --mesh "$tmp/c.ctmesh" --path "$pathf" --frames $n --width $w --height $w -q)
run "$c" naive "${common[@]}" --samples-per-frame 0 --threads 1 -o "$tmp/rad1" || fail "K=0, 1 thread: exit $?"
run "$c" naive "${common[@]}" --samples-per-frame 0 --threads 2 -o "$tmp/rad2" || fail "K=0, 2 threads: exit $?"
run "$c" naive "${common[@]}" --samples-per-frame $k --threads 1 --reference "$tmp/ref" -o "$tmp/nv1" || fail "K=$k, 1 thread: exit $?"
run "$c" naive "${common[@]}" --samples-per-frame $k --threads 2 --reference "$tmp/ref" -o "$tmp/nv2" || fail "K=$k, 2 threads: exit $?"
run "$c" naive "${common[@]}" --samples-per-frame $k --hold --threads 2 -o "$tmp/hold" || fail "--hold: exit $?"

# --path by the scene's name, from a folder holding a walk/ of an earlier run:
# the name wins (it used to fail with "walk: is a folder"), the same frames
mkdir -p "$tmp/cwd/walk"
(cd "$tmp/cwd" && run "$c" naive "$scene" --mesh "$tmp/c.ctmesh" --path walk --frames $n --width $w --height $w -q \
  --samples-per-frame 0 --threads 1 -o "$tmp/byname") || fail "--path walk beside a walk/ folder: exit $?"
rmse() { "$c" compare "$1" "$2" --json | sed -nE 's/.*"rmse":([^,]+),.*/\1/p'; }
[[ $(rmse "$tmp/byname/frame_00001.exr" "$tmp/rad1/frame_00001.exr") == 0 ]] || fail "--path walk differs from the walk's file"

for ((f = 0; f < n; f++)); do
  fr=$(printf 'frame_%05d.exr' $f)
  for d in rad1 rad2 nv1 nv2 hold; do [[ -s $tmp/$d/$fr ]] || fail "missing $d/$fr"; done
  [[ $(rmse "$tmp/rad1/$fr" "$tmp/rad2/$fr") == 0 ]] || fail "radiosity alone differs between 1 and 2 threads at frame $f"
  [[ $(rmse "$tmp/nv1/$fr" "$tmp/nv2/$fr") == 0 ]] || fail "point display differs between 1 and 2 threads at frame $f"
  e=$(rmse "$tmp/nv1/$fr" "$tmp/rad1/$fr")
  echo "metric: frame $f rmse(point display, radiosity alone) = $e"
  awk -v e="$e" 'BEGIN { exit !(e > 0) }' || fail "K=$k samples left frame $f equal to radiosity alone"
done
e=$(rmse "$tmp/hold/frame_00002.exr" "$tmp/nv2/frame_00002.exr")
awk -v e="$e" 'BEGIN { exit !(e > 0) }' || fail "--hold gives the same frame 2 as fresh samples"
# frames.csv
for d in nv1 hold; do
  rows=$(($(wc -l <"$tmp/$d/frames.csv") - 1))
  ((rows == n)) || fail "$d/frames.csv: $rows rows, want $n"
  awk -F, -v k=$k 'NR > 1 && $3 != k { exit 1 }' "$tmp/$d/frames.csv" || fail "$d/frames.csv: samples column is not $k"
done
head -n1 "$tmp/nv1/frames.csv" | grep -q 'rmse,rel_mse,psnr_db,ssim' || fail "no error columns with --reference"
awk -F, 'NR > 1 { printf "metric: naive K=%s frame %s rmse %s psnr %s\n", $3, $1, $6, $8 }' "$tmp/nv1/frames.csv"

bad() {  # bad WANT ARGS...
  local want=$1; shift
  echo "+ $c naive $*"
  "$c" naive "$@" >"$tmp/out" 2>"$tmp/all"; local rc=$?
  grep -v '^progress ' "$tmp/all" >"$tmp/err"; sed 's/^/  stderr: /' "$tmp/err"
  ((rc == 2)) || fail "exit $rc, want 2: $*"
  [[ $(wc -l <"$tmp/err") -eq 1 ]] && grep -q '^error corrtex naive: ' "$tmp/err" || fail "want one error line: $*"
  grep -qF -- "$want" "$tmp/err" || fail "message lacks '$want': $*"
}
bad "--mesh" "$scene" --path "$pathf" -o "$tmp/x"
bad "path 'nope' is neither a path of" "$scene" --mesh "$tmp/c.ctmesh" --path nope -o "$tmp/x"
bad "--samples-per-frame 65 exceeds the 64 pixels of a frame" "$scene" --mesh "$tmp/c.ctmesh" --path "$pathf" --width 8 \
  --height 8 --samples-per-frame 65 -o "$tmp/x"
bad 'glass light "refracted" is for path tracing and drt only (mode reuse-diffuse)' "$scene" --mesh "$tmp/c.ctmesh" \
  --path "$pathf" --mode reuse-diffuse --glass-light refracted -o "$tmp/x"
# Every argument is checked before anything is made: K too large left the
# output folder behind, a missing reference frame (below) that folder with
# the frames before it written.
[[ ! -e $tmp/x ]] || fail "the run refusing K created its output folder $tmp/x"
bad "missing.ctmesh" "$scene" --mesh "$tmp/missing.ctmesh" --path "$pathf" -o "$tmp/x"
# the tracer's option table, shared with corrtex-render and reference (tracer/trc_cli.h)
bad "--indirect: 'photons' is not one of mesh|gather" "$scene" --mesh "$tmp/c.ctmesh" --path "$pathf" -o "$tmp/x" --indirect photons
bad "--reference: $tmp/none/frame_00000.exr: cannot open" "$scene" --mesh "$tmp/c.ctmesh" --path "$pathf" --width 8 \
  --height 8 --frames 1 --samples-per-frame 0 --reference "$tmp/none" -o "$tmp/x"
[[ ! -e $tmp/x ]] || fail "the run refusing --reference created its output folder $tmp/x"
echo notes >"$tmp/notes.txt"
bad "-o $tmp/notes.txt: not a folder" "$scene" --mesh "$tmp/c.ctmesh" --path "$pathf" --width 8 --height 8 --frames 1 \
  --samples-per-frame 0 -o "$tmp/notes.txt"
[[ $(cat "$tmp/notes.txt") == notes ]] || fail "-o a file changed it"
((fails == 0)) || { echo "$fails failure(s)"; exit 1; }
echo "ok: naive baselines"
