#!/usr/bin/env bash
# Hostile clients next to a legitimate display, over TCP with a token:
# garbage (an HTTP request), a valid HELLO followed by a frame announcing
# 2 GiB, a display with the wrong token, a slow writer (one HELLO byte every
# 0.4 s) and a silent peer connect while the display runs 5 lockstep frames.
# Each is dropped with a log line; the display's frames are bit-identical to
# those of a clean run without them (it saw no disturbance).
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
head -c 32 /dev/urandom | base64 >"$tmp/token"; chmod 600 "$tmp/token"
head -c 32 /dev/urandom | base64 >"$tmp/wrong"; chmod 600 "$tmp/wrong"
K=800
PATHF=(--path "$root/scenes/cornell/walk.path" --frames 5)
JOB=("${CORNELL[@]}" --listen tcp:127.0.0.1:0 --token-file "$tmp/token" --handshake-ms 400)

# The clean run.
master_start clean 2 "${JOB[@]}"
master_wait_listen clean || finish
display_run clean_display --connect "$ADDR" --token-file "$tmp/token" "${HEADLESS[@]}" --samples-per-frame $K \
  "${PATHF[@]}" --out "$tmp/clean"
((DISPLAY_RC == 0)) || fail "clean display exit status $DISPLAY_RC"
kill -TERM "$(rank_pid clean 0)"
master_wait clean 20 || fail "the clean job did not end"

# The same with company.
master_start job 2 "${JOB[@]}"
master_wait_listen job || finish
port=${ADDR##*:}
hostile() {   # NAME: one hostile peer over bash's /dev/tcp
  case $1 in
    garbage) exec 5<>"/dev/tcp/127.0.0.1/$port"; printf 'GET / HTTP/1.1\r\nHost: corrtex\r\n\r\n' >&5; sleep 3 ;;
    oversize)
      exec 5<>"/dev/tcp/127.0.0.1/$port"
      printf '\x89CTX\r\n\x1a\n\x05\x00\x02\x00corrtex-proto-1\x00\x00\x00\x00\x00AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA' >&5
      printf '\x01\x00\x00\x00\xff\xff\xff\x7f' >&5; sleep 3 ;;
    slow)
      exec 5<>"/dev/tcp/127.0.0.1/$port"
      for b in '\x89' C T X '\r' '\n' '\x1a' '\n' '\x01' '\x00'; do printf "$b" >&5 2>/dev/null || break; sleep 0.4; done ;;
    silent) exec 5<>"/dev/tcp/127.0.0.1/$port"; sleep 3 ;;
  esac
}
pids=()
for h in slow silent garbage oversize; do
  echo "+ hostile peer '$h' on tcp:127.0.0.1:$port"
  hostile $h 2>/dev/null &
  pids+=($!)
done
display_start wrong_token --connect "$ADDR" --token-file "$tmp/wrong" "${HEADLESS[@]}" --samples-per-frame $K \
  --frames 1 --out "$tmp/wrong-out"
pids+=($DISPLAY_PID)
display_run display --connect "$ADDR" --token-file "$tmp/token" "${HEADLESS[@]}" --samples-per-frame $K \
  "${PATHF[@]}" --out "$tmp/out"
((DISPLAY_RC == 0)) || fail "display exit status $DISPLAY_RC next to hostile peers"
for ((i = 0; i < 40; i++)); do (($(grep -c 'handshake not completed' "$tmp/job.log") >= 2)) && break; sleep 0.1; done
wait "${pids[@]}"
echo "+ kill -TERM <rank 0>"
kill -TERM "$(rank_pid job 0)"
master_wait job 20 || fail "the job did not end"
((MASTER_RC == 0)) || fail "job exit status $MASTER_RC"
master_log job | grep -v progress | tail -n 14
grep -q 'dropped a peer: .*bad magic' "$tmp/job.log" || fail "garbage peer not logged"
grep -q 'dropped a peer: .*2147483647' "$tmp/job.log" || fail "oversized peer not logged"
grep -q 'dropped a peer: .*authentication failed' "$tmp/job.log" || fail "wrong token not logged"
n=$(grep -c 'handshake not completed' "$tmp/job.log")
((n >= 2)) || fail "$n handshake timeouts logged, expected the slow and the silent peer"
same_frames clean out "from the clean run"
echo "metric: $same of 5 frames identical to the clean run with 5 hostile peers connected"
finish
