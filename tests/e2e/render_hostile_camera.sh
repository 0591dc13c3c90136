#!/usr/bin/env bash
# CAMERA messages a real display never sends, from a connected display
# (tests/tools/raw_camera writes the floats byte by byte): an eye at
# z = -1e19 (a tracer used to abort inside Embree and take the job with it)
# and a zero orientation quaternion (NaN rays) are refused with ERROR
# PROTOCOL naming the problem; an eye at the edge of the range (-1e9) is
# traced. A camera of the protocol's largest image (16384 x 16384), whose
# per-pixel state would take some 30 GiB, is refused with ERROR LIMIT naming
# what it needs and --view-mem-mb before anything is allocated (the master
# used to take it and grow towards the host's memory). A field of view of
# 1e-33 radians (inside the old (0, pi)) is refused with ERROR PROTOCOL: it
# made the master's texture matrices infinite, and every display after it was
# dropped without a word. The job goes on: a display then gets its frame, and SIGTERM ends
# the job with status 0.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
raw="$root/${CORRTEX_BUILD:-build/release}/tools/raw_camera"
[[ -x $raw ]] || { fail "missing $raw (make unit-bins)"; finish; }
cornell_args
master_start job 2 "${CORNELL[@]}" --listen "unix:$tmp/r.sock"
master_wait_listen job || finish

# raw_camera NAME WANT_RC EX EY EZ QW QX QY QZ FOV [W H]: logged, output in $tmp/NAME.out.
raw_camera() {
  local name=$1 want=$2; shift 2
  log_cmd "$raw" "$ADDR" - "$@"
  timeout 60 "$raw" "$ADDR" - "$@" >"$tmp/$name.out" 2>&1
  local rc=$?
  sed "s/^/  $name: /" "$tmp/$name.out"
  ((rc == want)) || fail "$name: exit status $rc, expected $want"
}
# Looking down +z from far in front of the box: a half turn about y.
raw_camera far 0 278 273 -1e19 0 0 1 0 0.7
grep -q '^ERROR 1: .*CAMERA eye coordinate -1e+19 outside' "$tmp/far.out" || fail "no ERROR PROTOCOL naming the eye"
raw_camera zero_quat 0 278 273 -800 0 0 0 0 0.7
grep -q '^ERROR 1: .*CAMERA orientation is not a unit quaternion' "$tmp/zero_quat.out" ||
  fail "no ERROR PROTOCOL naming the orientation"
raw_camera huge 0 278 273 -800 0 0 1 0 0.7 16384 16384
grep -q '^ERROR 6: camera refused: a 16384x16384 view needs up to [0-9]* MiB .*over --view-mem-mb 4096' "$tmp/huge.out" ||
  fail "no ERROR LIMIT naming the view's memory"
raw_camera tiny_fov 0 278 273 -800 0 0 1 0 1e-33 1 16384
grep -q '^ERROR 1: .*CAMERA field of view 1e-33 out of range' "$tmp/tiny_fov.out" ||
  fail "no ERROR PROTOCOL naming the field of view"
raw_camera edge 1 278 273 -1e9 0 0 1 0 0.7
grep -qx 'FRAME' "$tmp/edge.out" || fail "a camera at the edge of the range was not traced"

kill -0 "${MASTER_PID[job]}" 2>/dev/null || fail "the job ended after the hostile cameras"
display_run display --connect "$ADDR" "${HEADLESS[@]}" --camera 278,273,-800,278,273,0,39.3 \
  --samples-per-frame 500 --frames 1 --out "$tmp/out"
((DISPLAY_RC == 0)) || fail "display exit status $DISPLAY_RC after the hostile cameras"
[[ -s $tmp/out/frame_00000.exr ]] || fail "no frame after the hostile cameras"
master_term job
grep -q 'CAMERA eye coordinate -1e+19' "$tmp/job.log" || fail "the master did not log the refused camera"
finish
