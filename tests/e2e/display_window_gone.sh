#!/usr/bin/env bash
# A window whose X server goes away under it: Xlib's default handler printed
# its own line and called exit() (status 1, no BYE to a master, frames.csv
# not completed). Now the display says why in one line and ends as if the
# window were closed: status 0, frames.csv complete.
set -u
BIN=${CORRTEX_BIN:-bin}
tmp=$(mktemp -d); xpid=
trap '[[ -n $xpid ]] && kill "$xpid" 2>/dev/null; rm -rf "$tmp"' EXIT
command -v Xvfb >/dev/null || { echo "skip: no Xvfb"; exit 0; }
scene=tests/data/scenes/mini.json
# Xvfb on a free display number (it writes the number to fd 3 when ready).
exec 3>"$tmp/dpy"
Xvfb -displayfd 3 -screen 0 320x240x24 -nolisten tcp >/dev/null 2>&1 &
xpid=$!
for ((i = 0; i < 100; i++)); do [[ -s $tmp/dpy ]] && break; sleep 0.1; done
[[ -s $tmp/dpy ]] || { echo "FAIL: Xvfb did not start"; exit 1; }
dpy=":$(head -n 1 "$tmp/dpy")"
echo "+ DISPLAY=$dpy $BIN/corrtex-display --scene $scene --backend glfw --width 64 --height 64 --seconds 30 --out $tmp/o --no-images"
DISPLAY=$dpy "$BIN/corrtex-display" --scene "$scene" --backend glfw --width 64 --height 64 --seconds 30 \
  --out "$tmp/o" --no-images >"$tmp/log" 2>&1 &
dpid=$!
# (frames.csv is written whole at the end; the backend's line comes with the window)
for ((i = 0; i < 200; i++)); do grep -q 'backend glfw:' "$tmp/log" && break; sleep 0.1; done
sleep 1.5
echo "+ kill $xpid   (Xvfb)"
kill "$xpid"; xpid=
t0=$EPOCHREALTIME
for ((i = 0; i < 100; i++)); do kill -0 "$dpid" 2>/dev/null || break; sleep 0.1; done
if kill -0 "$dpid" 2>/dev/null; then
  kill -9 "$dpid"; cat "$tmp/log"; echo "FAIL: the display still runs 10 s after its X server went away"; exit 1
fi
wait "$dpid"; rc=$?
dt=$(awk -v a="$t0" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f", b - a }')
grep -v '^progress' "$tmp/log" | sed 's/^/  display: /' | tail -n 6
echo "metric: the display ended $dt s after its X server, status $rc"
fail=0
((rc == 0)) || { echo "FAIL: status $rc, want 0 (ended as if closed)"; fail=1; }
grep -q '^warn display: the window is gone: the connection to the X server broke' "$tmp/log" \
  || { echo "FAIL: no line saying the window is gone"; fail=1; }
grep -qi 'X connection to .* broken' "$tmp/log" && { echo "FAIL: Xlib's own message (its exit())"; fail=1; }
rows=$(($(wc -l <"$tmp/o/frames.csv") - 1))
frames=$(sed -n 's/^display: \([0-9]*\) frames in.*/\1/p' "$tmp/log")
echo "metric: frames.csv has $rows rows, the display drew ${frames:-?} frames"
[[ -n $frames && $rows -eq $frames ]] || { echo "FAIL: frames.csv incomplete"; fail=1; }
exit $fail
