#!/usr/bin/env bash
# Ctrl-C on corrtex-walk: SIGINT to the launcher (only to it, as `kill -INT`
# does; a terminal would signal the whole group) while the MPI job and the
# display run a long walk. The launcher must stop both, exit 130, and leave
# no process and no socket file behind. The same for SIGTERM.
set -u
source "$(dirname "$0")/lib/walk-common.bash"
need_programs
need_scene cornell

# Job control: without it bash starts background commands with SIGINT
# ignored, and a shell cannot trap a signal ignored on entry; a launcher
# started from a terminal (the real Ctrl-C case) has SIGINT at its default.
set -m

one() {  # one SIGNAL
  local sig=$1 out="$tmp/walk-$1" sock="$tmp/w-$1.sock"
  local cmd=("$walk" cornell --path walk --frames 100000 --samples-per-frame 100 --width 32 --height 32
             --ranks 2 --listen "unix:$sock" --out "$out" --radiosity-cache "$tmp/cornell.ctmesh"
             --radiosity-options "$walk_rad_opts" --display local --backend egl)
  log_cmd "${cmd[@]}"
  (cd "$root" && exec env -u DISPLAY "${cmd[@]}") >"$tmp/walk-$sig.out" 2>&1 &
  local pid=$! i started=0
  # wait until the display is running (its log exists and the socket is up)
  for ((i = 0; i < 1200; i++)); do
    if [[ -S $sock && -s $out/display.log ]] && grep -q 'frame' "$out/display.log" 2>/dev/null; then started=1; break; fi
    kill -0 $pid 2>/dev/null || break
    sleep 0.1
  done
  ((started)) || { fail "$sig: the walk did not get going"; sed 's/^/  /' "$tmp/walk-$sig.out"; kill -TERM $pid 2>/dev/null; wait $pid; return; }
  echo "+ kill -$sig $pid   # the launcher only"
  kill -"$sig" $pid
  local t0=$SECONDS
  for ((i = 0; i < 300; i++)); do kill -0 $pid 2>/dev/null || break; sleep 0.1; done
  if kill -0 $pid 2>/dev/null; then fail "$sig: the launcher still runs 30 s after the signal"; kill -KILL $pid; fi
  wait $pid; local rc=$?
  echo "  launcher ended after $((SECONDS - t0)) s with exit status $rc"
  sed 's/^/  /' "$tmp/walk-$sig.out" | tail -n 12
  ((rc == 130)) || fail "$sig: exit status $rc, want 130"
  grep -q "interrupted: stopping" "$tmp/walk-$sig.out" || fail "$sig: no line saying what the launcher does"
  no_strays "after SIG$sig"
  no_sockets "after SIG$sig"
  [[ ! -e $sock ]] || fail "$sig: $sock left behind"
}
one INT
one TERM
((fails == 0)) || { echo "$fails failure(s)"; exit 1; }
echo "ok: SIGINT and SIGTERM stop everything and leave nothing behind"
