#!/usr/bin/env bash
# Displays that stay within the protocol and still used to stall the master
# or hold its one display slot (tests/tools/stuck_display):
# - a burst of 100 CAMERAs written with SETTINGS: the master's event ring
#   (64) used to drop the display's CONNECTED event, so it never got the
#   scene; now it does;
# - a display that reads nothing after its CAMERA: flow control sends it
#   nothing more, so the full send queue that drops a stuck display never
#   came and it held the slot for good; now it is dropped after
#   --send-timeout-ms with a log line naming it (and ERROR LIMIT, when the
#   socket has room for it);
# - a display that floods PINGs and reads nothing: the PONGs used to fill
#   the send queue until the next STATS waited --send-timeout-ms for room,
#   the whole loop with it; now the master answers no PING behind a quarter
#   of its queue (tests/unit/test_dsrv.c) and drops the display the same way;
# - a lockstep display that reads everything and sends nothing, not even its
#   PING a second (a stopped process, a host gone without a FIN): nothing is
#   queued for it and every update is acknowledged, so only its silence
#   tells; it used to hold the slot for good, now it is dropped after
#   --send-timeout-ms (at least 3 s).
# A real display refused meanwhile says the master serves another. Then a
# real display gets its frame, and SIGTERM ends the job with status 0.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
stuck="$root/${CORRTEX_BUILD:-build/release}/tools/stuck_display"
[[ -x $stuck ]] || { fail "missing $stuck (make unit-bins)"; finish; }
cornell_args
master_start job 2 "${CORNELL[@]}" --listen "unix:$tmp/s.sock" --send-timeout-ms 1500
master_wait_listen job || finish

# stuck NAME WANT_RC ARGS...: logged, output in $tmp/NAME.out.
stuck() {
  local name=$1 want=$2; shift 2
  log_cmd "$stuck" "$ADDR" - "$@"
  timeout 60 "$stuck" "$ADDR" - "$@" >"$tmp/$name.out" 2>&1
  local rc=$?
  sed "s/^/  $name: /" "$tmp/$name.out"
  ((rc == want)) || fail "$name: exit status $rc, expected $want"
}
stuck burst 0 burst 100
grep -qx 'scene after 100 cameras' "$tmp/burst.out" || fail "a display that sent 100 cameras at once got no scene"

stuck noread 0 noread 4
# (its ERROR may not get through: the scene's frames fill its socket)
grep -q '^closed: ' "$tmp/noread.out" || fail "a display that read nothing was not dropped"
# (silent as well: either rule may come first)
grep -Eq 'dropped display .*(took nothing and acknowledged nothing|sent nothing, not even its PING a second) for [0-9.]* s' "$tmp/job.log" ||
  fail "the master did not log the dropped display"

stuck pingflood 0 pingflood 4
(($(grep -c 'dropped display' "$tmp/job.log") >= 2)) && grep -q 'took nothing and acknowledged nothing' "$tmp/job.log" ||
  fail "the PING-flooding display was not dropped"

# Within 8 s: silence counts from --send-timeout-ms, 1.5 s here, but at
# least 3 s (a display PINGs once a second); the master's 1 s stats lines
# go on meanwhile.
# Meanwhile (it holds the slot for 3 s) a real display is refused and
# says why: ERROR BUSY came right after the handshake and its SETTINGS met
# a closed socket ("the peer closed the connection" hid the reason).
log_cmd "$stuck" "$ADDR" - silent 8
timeout 60 "$stuck" "$ADDR" - silent 8 >"$tmp/silent.out" 2>&1 &
silent_pid=$!
for ((i = 0; i < 50; i++)); do (($(grep -c 'connected (lockstep)' "$tmp/job.log") >= 1)) && break; sleep 0.1; done
# And one that retries (--reconnect) for a second and is refused each time:
# never served, status 3 (it was 0: the handshake had got through).
display_start busy_retry --connect "$ADDR" "${HEADLESS[@]}" --camera 278,273,-800,278,273,0,39.3 --reconnect --seconds 1
retry_pid=$DISPLAY_PID
display_run busy --connect "$ADDR" "${HEADLESS[@]}" --camera 278,273,-800,278,273,0,39.3 --samples-per-frame 500 --frames 1
((DISPLAY_RC == 3)) || fail "a display refused while another is served: exit status $DISPLAY_RC, want 3"
grep -q 'master reports an error: the master already serves a display' "$tmp/busy.log" ||
  fail "the refused display did not say the master serves another"
wait "$retry_pid"; rc=$?
sed 's/^/  busy_retry: /' "$tmp/busy_retry.log" | tail -n 3
((rc == 3)) || fail "a retrying display refused every time: exit status $rc, want 3"
grep -q 'never connected to .*(last: .*already serves a display' "$tmp/busy_retry.log" ||
  fail "the retrying display did not say it was never served, and why"
wait "$silent_pid"; rc=$?
sed 's/^/  silent: /' "$tmp/silent.out"
((rc == 0)) || fail "silent: exit status $rc, expected 0"
grep -q '^closed: ' "$tmp/silent.out" || fail "a silent lockstep display was not dropped"
grep -q 'dropped display .*sent nothing, not even its PING a second, for [0-9.]* s' "$tmp/job.log" ||
  fail "the master did not say why it dropped the silent display"

display_run display --connect "$ADDR" "${HEADLESS[@]}" --camera 278,273,-800,278,273,0,39.3 \
  --samples-per-frame 500 --frames 1 --out "$tmp/out"
((DISPLAY_RC == 0)) || fail "display exit status $DISPLAY_RC after the stuck displays"
[[ -s $tmp/out/frame_00000.exr ]] || fail "no frame after the stuck displays"
master_term job
finish
