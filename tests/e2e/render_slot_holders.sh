#!/usr/bin/env bash
# A client that holds the master's handshake slots: 16 idle TCP connections
# (bash's /dev/tcp), each re-opened as soon as the master drops it. They used
# to fill the table of connections in handshake (16, each kept for
# --handshake-ms) and every display was refused. Now one address holds at
# most 4 of them and a newcomer replaces the oldest one that sent nothing:
# a display with the token gets in at once and draws its frame, and the
# master logs the dropped connections.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
head -c 32 /dev/urandom | base64 >"$tmp/token"; chmod 600 "$tmp/token"
master_start job 2 "${CORNELL[@]}" --listen tcp:127.0.0.1:0 --token-file "$tmp/token"
master_wait_listen job || finish
port=${ADDR##*:}

# hold: one slot, re-opened whenever the master closes it (the read loop
# ends at EOF), until $tmp/stop exists.
hold() {
  while [[ ! -e $tmp/stop ]]; do
    exec 5<>"/dev/tcp/127.0.0.1/$port" 2>/dev/null || { sleep 0.1; continue; }
    while read -r -u 5 -d '' _ 2>/dev/null; do :; done
    exec 5<&-
    sleep 0.05
  done
}
echo "+ 16 connections to tcp:127.0.0.1:$port that send nothing, each re-opened when dropped"
holders=()
for i in $(seq 16); do hold & holders+=($!); done
sleep 1

display_run display --connect "$ADDR" --token-file "$tmp/token" "${HEADLESS[@]}" \
  --camera 278,273,-800,278,273,0,39.3 --samples-per-frame 500 --frames 1 --out "$tmp/out"
((DISPLAY_RC == 0)) || fail "display exit status $DISPLAY_RC next to the slot holders"
[[ -s $tmp/out/frame_00000.exr ]] || fail "no frame next to the slot holders"

touch "$tmp/stop"
kill "${holders[@]}" 2>/dev/null
wait "${holders[@]}" 2>/dev/null
master_term job
grep -q 'connections\? that had not authenticated, to make room for newer ones' "$tmp/job.log" ||
  fail "the master did not log the connections it dropped"
finish
