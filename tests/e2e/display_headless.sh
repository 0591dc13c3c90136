#!/usr/bin/env bash
# corrtex-display without a master: scripted path on a small scene with
# synthetic corrections, headless under OSMesa and EGL and in a GLFW window
# under Xvfb; frames and frames.csv written; the backends and 1-pass vs
# 3-pass agree (RMSE through --reference); a path of the scene taken by
# name; --hold at a real-time path's end; bad input (references of another
# frame count too, options another one makes meaningless) exits 2 with one
# line, and --out is made only once the input is known good.
set -u
BIN=${CORRTEX_BIN:-bin}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail=0
run() { echo "+ $*"; "$@"; }
# bad WANT ARGS...: exit 2 and one error line that mentions WANT.
bad() {
  local want=$1; shift
  timeout 20 "$BIN/corrtex-display" "$@" >"$tmp/o" 2>"$tmp/e"; rc=$?
  echo "+ $BIN/corrtex-display $*  -> exit $rc: $(cat "$tmp/e")"
  [[ $rc -eq 2 ]] || { echo "FAIL: exit $rc, want 2"; fail=1; }
  [[ $(grep -c "^error" "$tmp/e") -eq 1 ]] || { echo "FAIL: want exactly one error line"; fail=1; }
  grep -q -- "$want" "$tmp/e" || { echo "FAIL: error does not mention '$want'"; fail=1; }
}
SCENE=tests/data/scenes/mini.json
PATHF=tests/data/scenes/mini.path
COMMON=(--scene "$SCENE" --path "$PATHF" --frames 4 --width 64 --height 48 --synthetic 6 --quiet)

run "$BIN/corrtex-display" --backend osmesa "${COMMON[@]}" --out "$tmp/osm" >"$tmp/osm.log" || { echo "FAIL: osmesa run"; exit 1; }
# GPU timers: off by default on a software rasteriser, on when asked, and the
# frames the same either way
grep -q "GPU time per frame" "$tmp/osm.log" && { echo "FAIL: --gpu-times auto timed a software rasteriser"; fail=1; }
run "$BIN/corrtex-display" --backend osmesa "${COMMON[@]}" --gpu-times on --out "$tmp/osmgt" >"$tmp/osmgt.log" ||
  { echo "FAIL: osmesa run with --gpu-times on"; fail=1; }
gl=$(grep "GPU time per frame" "$tmp/osmgt.log")
echo "  $gl"
[[ $gl =~ ([0-9.]+)\ ms\ drawing ]] && awk -v d="${BASH_REMATCH[1]}" 'BEGIN { exit !(d > 0) }' ||
  { echo "FAIL: --gpu-times on printed no drawing time"; fail=1; }
for k in 0 1 2 3; do
  f=$(printf 'frame_%05d.exr' "$k")
  cmp -s "$tmp/osm/$f" "$tmp/osmgt/$f" || { echo "FAIL: $f differs with --gpu-times on"; fail=1; }
done
for k in 0 1 2 3; do
  for ext in exr png; do
    f=$(printf '%s/osm/frame_%05d.%s' "$tmp" "$k" "$ext")
    [[ -s $f ]] || { echo "FAIL: missing $f"; fail=1; }
  done
done
lines=$(wc -l <"$tmp/osm/frames.csv")
[[ $lines -eq 5 ]] || { echo "FAIL: frames.csv has $lines lines, want 5"; fail=1; }
head -n 1 "$tmp/osm/frames.csv" | grep -q '^frame,time_s,eye_x' || { echo "FAIL: frames.csv header"; fail=1; }
ls "$tmp/osm" | grep -q '\.tmp' && { echo "FAIL: temporary files left"; fail=1; }

# EGL with OSMesa's frames as the reference: the same pixels, up to the half
# float rounding of the reference EXR (relative 2^-11; the light is bright).
run "$BIN/corrtex-display" --backend egl "${COMMON[@]}" --out "$tmp/egl" --reference "$tmp/osm" || { echo "FAIL: egl run"; exit 1; }
max_rmse() { awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "rmse") c = i; next }
                      c && $c > m { m = $c } END { printf "%.3g", c ? m + 0 : 1 }' "$1"; }
r=$(max_rmse "$tmp/egl/frames.csv")
echo "metric: egl vs osmesa frames: max RMSE $r (tolerance 1e-3)"
awk -v r="$r" 'BEGIN { exit !(r <= 1e-3) }' || { echo "FAIL: egl differs from osmesa"; fail=1; }

# EGL through an EGL device (EGL_EXT_platform_device; here Mesa's software
# device) rather than the surfaceless platform: the path a GPU server
# without X takes (docs/display.md, "Backends"); the same frames.
CORRTEX_EGL_DEVICE=0 "$BIN/corrtex-display" --backend egl "${COMMON[@]}" --out "$tmp/egldev" --reference "$tmp/osm" \
  >"$tmp/egldev.log" 2>&1; rc=$?
if grep -q "lists 0 devices" "$tmp/egldev.log"; then
  echo "skip: EGL lists no devices here"
elif [[ $rc -ne 0 ]]; then
  cat "$tmp/egldev.log"; echo "FAIL: egl device run"; fail=1
else
  r=$(max_rmse "$tmp/egldev/frames.csv")
  echo "metric: egl device 0 vs osmesa frames: max RMSE $r (tolerance 1e-3)"
  awk -v r="$r" 'BEGIN { exit !(r <= 1e-3) }' || { echo "FAIL: egl device differs from osmesa"; fail=1; }
fi
# A device EGL does not list, and a malformed index: one error line each.
CORRTEX_EGL_DEVICE=15 "$BIN/corrtex-display" --backend egl "${COMMON[@]}" --out "$tmp/egl15" >"$tmp/o" 2>"$tmp/e"; rc=$?
echo "+ CORRTEX_EGL_DEVICE=15 corrtex-display --backend egl  -> exit $rc: $(cat "$tmp/e")"
[[ $rc -ne 0 && $(grep -c "^error" "$tmp/e") -eq 1 ]] && grep -q "CORRTEX_EGL_DEVICE=15, but EGL lists" "$tmp/e" ||
  { echo "FAIL: want one error line naming the device count"; fail=1; }
CORRTEX_EGL_DEVICE=gpu0 bad "CORRTEX_EGL_DEVICE='gpu0' is not a device index" --backend egl "${COMMON[@]}" --out "$tmp/eglbad"

# Three passes against one pass.
run "$BIN/corrtex-display" --backend egl "${COMMON[@]}" --passes 3 --out "$tmp/p3" --reference "$tmp/osm" || { echo "FAIL: 3-pass run"; exit 1; }
r=$(max_rmse "$tmp/p3/frames.csv")
echo "metric: 3-pass vs 1-pass frames: max RMSE $r (tolerance 1e-3)"
awk -v r="$r" 'BEGIN { exit !(r <= 1e-3) }' || { echo "FAIL: 3-pass differs from 1-pass"; fail=1; }

# The corrections change the image (the comparison above is not vacuous).
run "$BIN/corrtex-display" --backend egl "${COMMON[@]}" --synthetic 0 --out "$tmp/rad" --reference "$tmp/osm" || { echo "FAIL: radiosity run"; exit 1; }
r=$(max_rmse "$tmp/rad/frames.csv")
echo "metric: radiosity alone vs corrected frames: max RMSE $r (must exceed 5e-3)"
awk -v r="$r" 'BEGIN { exit !(r > 5e-3) }' || { echo "FAIL: synthetic corrections had no effect"; fail=1; }

# The window backend under Xvfb writes the same frames.
if command -v xvfb-run >/dev/null; then
  run xvfb-run -a "$BIN/corrtex-display" --backend glfw --no-vsync "${COMMON[@]}" --out "$tmp/win" --reference "$tmp/osm" || { echo "FAIL: glfw run"; exit 1; }
  r=$(max_rmse "$tmp/win/frames.csv")
  echo "metric: glfw window vs osmesa frames: max RMSE $r (tolerance 1e-3)"
  awk -v r="$r" 'BEGIN { exit !(r <= 1e-3) }' || { echo "FAIL: glfw differs"; fail=1; }
else
  echo "skip: xvfb-run not installed"
fi

# A path of the scene by name (mini's "inline" is defined by keys in the
# scene file), as corrtex reference takes it: it was opened as a file
# ("inline: cannot open"). The same frames as the path written out by
# corrtex info --path, which is how a display with --connect gets it.
"$BIN/corrtex" info "$SCENE" --path inline >"$tmp/inline.path" || { echo "FAIL: corrtex info --path inline"; fail=1; }
SMALL=(--scene "$SCENE" --frames 3 --width 32 --height 24 --quiet)
run "$BIN/corrtex-display" --backend osmesa "${SMALL[@]}" --path inline --out "$tmp/byname" ||
  { echo "FAIL: --scene with --path NAME"; fail=1; }
run "$BIN/corrtex-display" --backend osmesa "${SMALL[@]}" --path "$tmp/inline.path" --out "$tmp/byfile" ||
  { echo "FAIL: --scene with the written-out path"; fail=1; }
cams() { cut -d, -f1-10 "$1/frames.csv" 2>/dev/null; }
[[ $(cams "$tmp/byname" | wc -l) -eq 4 ]] && cmp -s <(cams "$tmp/byname") <(cams "$tmp/byfile") ||
  { echo "FAIL: the path by name and written out give other cameras:"; diff <(cams "$tmp/byname") <(cams "$tmp/byfile"); fail=1; }
for k in 0 1 2; do
  f=$(printf 'frame_%05d.exr' "$k")
  cmp -s "$tmp/byname/$f" "$tmp/byfile/$f" || { echo "FAIL: $f differs between the path by name and its file"; fail=1; }
done
bad "path 'nope' is neither a path of $SCENE nor a readable path file" --backend osmesa --scene "$SCENE" --path nope
# without --scene a name is no file: the line says how to get the file
bad "--path inline: no such path file (a scene's path name needs --scene" --backend osmesa \
  --mesh "$tmp/none.ctmesh" --path inline

# A folder of references is checked against --frames before the first
# frame: too few used to end the run at the first missing one (exit 1),
# and those of another frame count were compared with other cameras.
bad "--reference $tmp/osm: frame_00004.exr missing: 4 reference frames there, --frames 6 needs 6" \
  --backend osmesa --scene "$SCENE" --path "$PATHF" --frames 6 --width 64 --height 48 --out "$tmp/refn" \
  --reference "$tmp/osm"
bad "--reference $tmp/osm: 4 reference frames there, made for --frames 4, not 3" \
  --backend osmesa --scene "$SCENE" --path "$PATHF" --frames 3 --width 64 --height 48 --out "$tmp/refn" \
  --reference "$tmp/osm"
ls "$tmp/refn" 2>/dev/null | grep -q frame_ && { echo "FAIL: frames drawn before the references were refused"; fail=1; }

# Bad input: exit 2 and one error line naming the problem.
bad "nope.json" --backend osmesa --scene "$tmp/nope.json"
bad "--passes" --backend osmesa --scene "$SCENE" --passes 2
bad "unknown option" --backend osmesa --scene "$SCENE" --bogus
bad "backend" --backend vulkan --scene "$SCENE"
bad "--kept-corrections" --backend osmesa --scene "$SCENE" --kept-corrections both
bad "--gpu-times" --backend osmesa --scene "$SCENE" --gpu-times sometimes
bad "--msaa" --backend osmesa --scene "$SCENE" --msaa 65
bad "--msaa" --backend osmesa --scene "$SCENE" --msaa -1
bad "--msaa" --backend osmesa --scene "$SCENE" --msaa four
bad "exactly one" --backend osmesa
printf '0 0 0 1 0 0 0\n0 1 1 1 0 0 0\n' >"$tmp/bad.path"
bad "bad.path" --backend osmesa --scene "$SCENE" --path "$tmp/bad.path"
bad "no camera named" --backend osmesa --scene "$SCENE" --camera-name nope
# Only a scene file names cameras: with --mesh or --connect the option was
# dropped without a word.
bad "--camera-name needs --scene: a .ctmesh names no cameras" --backend osmesa --mesh "$tmp/none.ctmesh" \
  --camera-name front
bad "--camera-name needs --scene: the scene a master sends" --backend osmesa --connect "unix:$tmp/none.sock" \
  --camera-name front
# The options of a connection without one: dropped without a word before
# (a --token-file meant for a master looked taken).
bad "--token-file needs --connect: --scene has no master" --backend osmesa --scene "$SCENE" \
  --token-file "$tmp/token"
bad "--reconnect needs --connect: --mesh has no master" --backend osmesa --mesh "$tmp/none.ctmesh" --reconnect
bad "--samples-per-frame needs --connect" --backend osmesa --scene "$SCENE" --samples-per-frame 100
bad "--cache needs --connect" --backend osmesa --scene "$SCENE" --cache "$tmp/cache"
bad "--no-cache needs --connect" --backend osmesa --scene "$SCENE" --no-cache
bad "--cache-max-mb needs --connect" --backend osmesa --scene "$SCENE" --cache-max-mb 5
# Options that shape what another one makes, given without it: dropped
# without a word before, also at their default values (0.3, 0).
bad "--ambient is the stand-in radiosity of --scene: not with --mesh" --backend osmesa --mesh "$tmp/none.ctmesh" \
  --ambient 0.5
bad "--ambient is the stand-in radiosity of --scene: not with --mesh" --backend osmesa --mesh "$tmp/none.ctmesh" \
  --ambient 0.3
bad "--ambient is the stand-in radiosity of --scene: not with --connect" --backend osmesa \
  --connect "unix:$tmp/none.sock" --ambient 1
bad "--synthetic-tiles needs --synthetic N (N > 0)" --backend osmesa --scene "$SCENE" --synthetic-tiles
bad "--synthetic-tiles needs --synthetic N (N > 0)" --backend osmesa --scene "$SCENE" --synthetic 0 --synthetic-tiles
bad "--synthetic-positive needs --synthetic N (N > 0)" --backend osmesa --scene "$SCENE" --synthetic-positive
bad "--hold needs --path" --backend osmesa --scene "$SCENE" --hold 5
bad "--hold needs --path" --backend osmesa --mesh "$tmp/none.ctmesh" --hold 0
# --frames N steps the path: no real time to stay in (dropped without a
# word before, also --hold 0).
bad "--hold needs --path in real time, not --frames 3: it keeps a real-time path's last camera" --backend osmesa \
  --scene "$SCENE" --path "$PATHF" --frames 3 --hold 2
bad "--hold needs --path in real time, not --frames 1" --backend osmesa --mesh "$tmp/none.ctmesh" --path "$PATHF" \
  --frames 1 --hold 0
# A master sends its own textures: --synthetic N made none with --connect.
bad "--synthetic 5 makes corrective textures without a master: not with --connect" --backend osmesa \
  --connect "unix:$tmp/none.sock" --synthetic 5
# ... and taken where they belong.
run "$BIN/corrtex-display" --backend osmesa "${SMALL[@]}" --path inline --ambient 0.5 --synthetic 3 --synthetic-tiles \
  --synthetic-positive --out "$tmp/shaped" || { echo "FAIL: --ambient and --synthetic-tiles with --scene"; fail=1; }
# --hold with a real-time path (--frames 0): the 1 s path, then 0.5 s at its
# last camera.
run "$BIN/corrtex-display" --backend osmesa --scene "$SCENE" --width 32 --height 24 --quiet --path inline \
  --hold 0.5 --out "$tmp/held" --no-images || { echo "FAIL: --hold with a real-time path"; fail=1; }
held=$(tail -n 1 "$tmp/held/frames.csv" 2>/dev/null | awk -F, '{ print $2, $NF }')
echo "  last frame: path time, wall seconds: $held"
awk -v t="${held% *}" -v w="${held#* }" 'BEGIN { exit !(t == 1 && w >= 1.5) }' ||
  { echo "FAIL: --hold 0.5: the last frame is not at the path's end 0.5 s after it"; fail=1; }
# Found before the first frame, as bad input: an address no transport
# takes was a lost connection (exit 3), an --out that is a file and a
# missing --reference failures (exit 1) after the first frame.
bad "--connect address 'foo:bar': unknown scheme" --backend osmesa --connect foo:bar
bad "port 99999 out of range" --backend osmesa --connect tcp:localhost:99999
echo notes >"$tmp/notes.txt"
bad "--out $tmp/notes.txt: not a folder" --backend osmesa --scene "$SCENE" --frames 1 --out "$tmp/notes.txt"
bad "--reference $tmp/nope: No such file" --backend osmesa --scene "$SCENE" --frames 1 --out "$tmp/refout" \
  --reference "$tmp/nope"
# --out is made once every input is known good: a bad scene, mesh or
# reference image left the folder behind (made before any of them was read).
bad "nope.json" --backend osmesa --scene "$tmp/nope.json" --frames 1 --out "$tmp/made/scene"
bad "none.ctmesh" --backend osmesa --mesh "$tmp/none.ctmesh" --frames 1 --out "$tmp/made/mesh"
bad "reference: $tmp/notes.txt" --backend osmesa --scene "$SCENE" --frames 1 --out "$tmp/made/ref" \
  --reference "$tmp/notes.txt"
[[ ! -e $tmp/made ]] || { echo "FAIL: --out made before the input was refused: $(cd "$tmp" && find made)"; fail=1; }
bad "--sample-frames" --backend osmesa --scene "$SCENE" --sample-frames 0
bad "--sample-max" --backend osmesa --scene "$SCENE" --sample-max abc
bad "--cache-max-mb" --backend osmesa --scene "$SCENE" --cache-max-mb -5
# The protocol's bound on K: above it the display connected and then failed
# to encode its SETTINGS (exit 3, "cannot connect").
bad "--samples-per-frame: '16777217' is not an integer in \[0, 16777216\]" --backend osmesa \
  --connect "unix:$tmp/none.sock" --samples-per-frame 16777217
bad "--camera: '0,1,nan,0,0,0'" --backend osmesa --scene "$SCENE" --camera 0,1,nan,0,0,0
bad "a scene camera by name: --camera-name with --scene" --backend osmesa --connect "unix:$tmp/none.sock" \
  --camera front
bad "--camera: 'inf,1,4,0,0,0'" --backend osmesa --scene "$SCENE" --camera inf,1,4,0,0,0
bad "must be finite and within +-1e+09" --backend osmesa --scene "$SCENE" --camera 0,1,-1e19,0,0,0
# The field of view's range is the scenes' and paths' (it was (1, 179) here alone).
bad "the field of view 179.995 is outside \[0.01, 179.99\] degrees" --backend osmesa --scene "$SCENE" \
  --camera 0,1,4,0,1,0,179.995
# A bad token file is bad input (exit 2), not a lost connection (exit 3);
# a FIFO as token file used to block the display for good.
printf 'short\n' >"$tmp/short.token"; chmod 600 "$tmp/short.token"
bad "short.token: the token has 5 bytes" --backend osmesa --connect "unix:$tmp/none.sock" --token-file "$tmp/short.token"
mkfifo "$tmp/fifo.token"
bad "fifo.token: token file is not a regular file" --backend osmesa --connect "unix:$tmp/none.sock" \
  --token-file "$tmp/fifo.token"
# No master at the address and no --reconnect: exit 3, one error line.
"$BIN/corrtex-display" --backend osmesa --connect "unix:$tmp/none.sock" --width 32 --height 32 --out "$tmp/nomaster" \
  >"$tmp/o" 2>"$tmp/e"; rc=$?
echo "+ $BIN/corrtex-display --backend osmesa --connect unix:$tmp/none.sock --out $tmp/nomaster -> exit $rc: $(cat "$tmp/e")"
[[ $rc -eq 3 ]] || { echo "FAIL: exit $rc, want 3"; fail=1; }
[[ ! -e $tmp/nomaster ]] || { echo "FAIL: --out made without a master"; fail=1; }
[[ $(grep -c "^error" "$tmp/e") -eq 1 ]] && grep -q "none.sock" "$tmp/e" || { echo "FAIL: want one error line naming the socket"; fail=1; }
grep -q "none.sock: .*none.sock" "$tmp/e" && { echo "FAIL: the address is named twice"; fail=1; }
# With --reconnect, a run that ends before any connection got through is
# not a success (it used to exit 0): exit 3, the address and the last reason.
"$BIN/corrtex-display" --backend osmesa --connect "unix:$tmp/none.sock" --reconnect --seconds 1.5 --width 32 --height 32 \
  >"$tmp/o" 2>"$tmp/e"; rc=$?
echo "+ $BIN/corrtex-display --backend osmesa --connect unix:$tmp/none.sock --reconnect --seconds 1.5 -> exit $rc: $(grep '^error' "$tmp/e")"
[[ $rc -eq 3 ]] || { echo "FAIL: --reconnect, never connected: exit $rc, want 3"; fail=1; }
grep -q "^error corrtex-display: never connected to unix:$tmp/none.sock (last: " "$tmp/e" ||
  { echo "FAIL: --reconnect, never connected: no error line naming the address"; fail=1; }
exit $fail
