# tests/e2e/lib/mpi.sh: shared helpers of the distributed end-to-end tests
# (sourced, not run). The one place that builds an mpirun command line (IOR
# style): every test logs the exact command it ran, with the environment it
# needs (root, oversubscription), so a failure can be replayed by hand.
#
#   source "$(dirname "$0")/lib/mpi.sh"      sets root, bin, tmp, fail(), ...
#   master_start NAME NP ARGS...             mpirun -np NP corrtex-render ARGS in the background
#   master_wait_listen NAME                  waits for "listening on ADDR"; sets ADDR
#   master_wait NAME SECONDS                 waits for the job to end; sets MASTER_RC
#   master_term NAME                         SIGTERM to rank 0; the job must end with status 0
#   display_run NAME ARGS...                 corrtex-display ARGS (foreground, logged)
#   cornell_args                             scene + a small radiosity mesh in $tmp
#   job_with_walker NP                       job + a walking display connected; VICTIM = rank 1's pid
#   display_gone                             waits for the display to exit; DISPLAY_RC
#   same_frames A B WHAT                     counts identical frames 0..4 of $tmp/A and $tmp/B into same
set -u
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)
bin=${CORRTEX_BIN:-bin}
[[ $bin == /* ]] || bin="$root/$bin"
render="$bin/corrtex-render"
display="$bin/corrtex-display"
corrtex="$bin/corrtex"
test_name=$(basename "$0" .sh)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ct-e2e-$test_name-XXXXXX")
fails=0
declare -A MASTER_PID=()

fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
skip() { echo "skip: $*"; cleanup; exit 0; }

# Ends every job this test started (by its own pid) and removes $tmp.
cleanup() {
  local n
  for n in "${!MASTER_PID[@]}"; do
    if kill -0 "${MASTER_PID[$n]}" 2>/dev/null; then
      kill -TERM "${MASTER_PID[$n]}" 2>/dev/null
      sleep 1
      kill -KILL "${MASTER_PID[$n]}" 2>/dev/null
    fi
  done
  if [[ ${KEEP_TMP:-0} == 1 ]]; then echo "kept $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT

# Prints a command the way it can be pasted into a shell.
log_cmd() {
  local s="+" a
  for a in "$@"; do s+=" $(printf '%q' "$a")"; done
  echo "$s"
}

# The mpirun command for NP ranks of corrtex-render with ARGS, in MPI_CMD.
# Root needs Open MPI's two consent variables; a small machine needs
# --oversubscribe to start more ranks than cores. MPIRUN_EXTRA adds options
# (e.g. a host list).
mpi_cmd() {
  local np=$1; shift
  MPI_CMD=(mpirun --oversubscribe ${MPIRUN_EXTRA:-} -np "$np" "$render" "$@")
  MPI_ENV=()
  if [[ $(id -u) == 0 ]]; then MPI_ENV=(OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1); fi
  # Sanitizer builds: Open MPI's own allocations live until exit (lsan-mpi.supp).
  # Open MPI is built without frame pointers: only the slow unwinder finds
  # the MPI frames the suppressions match.
  if [[ -n ${ASAN_OPTIONS:-} ]]; then
    MPI_ENV+=("LSAN_OPTIONS=${LSAN_OPTIONS:+$LSAN_OPTIONS:}suppressions=$root/tests/e2e/lib/lsan-mpi.supp:print_suppressions=0"
      "ASAN_OPTIONS=$ASAN_OPTIONS:fast_unwind_on_malloc=0")
  fi
}

# master_start NAME NP ARGS...: the job in the background, output in $tmp/NAME.log.
master_start() {
  local name=$1 np=$2; shift 2
  mpi_cmd "$np" "$@"
  log_cmd env "${MPI_ENV[@]}" "${MPI_CMD[@]}"
  env "${MPI_ENV[@]}" "${MPI_CMD[@]}" >"$tmp/$name.log" 2>&1 &
  MASTER_PID[$name]=$!
}

# master_wait_listen NAME [SECONDS]: waits for the master's listening line; ADDR.
master_wait_listen() {
  local name=$1 limit=${2:-60} i
  ADDR=
  for ((i = 0; i < limit * 10; i++)); do
    ADDR=$(sed -n 's/^corrtex-render: listening on //p' "$tmp/$name.log" | head -n 1)
    [[ -n $ADDR ]] && return 0
    kill -0 "${MASTER_PID[$name]}" 2>/dev/null || break
    sleep 0.1
  done
  fail "$name: the master did not start listening"
  sed 's/^/  master: /' "$tmp/$name.log" | tail -n 30
  return 1
}

# master_wait NAME SECONDS: waits for the job; MASTER_RC (124 after SECONDS).
master_wait() {
  local name=$1 limit=$2 pid=${MASTER_PID[$1]} i
  for ((i = 0; i < limit * 10; i++)); do
    if ! kill -0 "$pid" 2>/dev/null; then
      wait "$pid"; MASTER_RC=$?
      unset "MASTER_PID[$name]"
      return 0
    fi
    sleep 0.1
  done
  MASTER_RC=124
  return 1
}

# master_term NAME: SIGTERM to rank 0 ends the job in order (status 0) and
# soon: every rank's sends complete (a tracer's last large sample message
# too, which only the master's receive completes), so no rank waits out a
# drain timeout (5 s); its last log lines are printed.
master_term() {
  echo "+ kill -TERM <rank 0>"
  local t0=$EPOCHREALTIME pid
  pid=$(rank_pid "$1" 0)
  if [[ -z $pid ]]; then
    # rank 0 ended before it was asked to: its log says why (on stderr,
    # which a benchmark that hides this function's output still shows),
    # and mpirun's children whether it is a zombie mpirun has not reaped
    # (seen twice under the sanitizers, mpirun then alive 20 s more) or
    # alive but not found (once in CI: both ranks running; their
    # environments are listed to tell why)
    master_log "$1" | tail -n 20 >&2
    echo "  mpirun ${MASTER_PID[$1]}'s children:" >&2
    ps -o pid=,stat=,etime=,args= --ppid "${MASTER_PID[$1]}" 2>/dev/null | cut -c1-160 | sed 's/^/    /' >&2
    local c
    for c in $(pgrep -P "${MASTER_PID[$1]}"); do
      echo "    $c: environ $(wc -c <"/proc/$c/environ" 2>&1) bytes," \
        "$(tr '\0' '\n' <"/proc/$c/environ" 2>&1 | grep -a -e OMPI_COMM_WORLD_RANK= -e 'No such' -e denied)" >&2
    done
    master_wait "$1" 20 || true
    fail "$1: rank 0 ended before SIGTERM (the job's exit status $MASTER_RC)" >&2
    return 1
  fi
  kill -TERM "$pid"
  master_wait "$1" 20 || fail "$1: the job did not end"
  local dt
  dt=$(awk -v a="$t0" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f", b - a }')
  echo "metric: $1 ended $dt s after SIGTERM"
  awk -v t="$dt" 'BEGIN { exit !(t < 4.5) }' || fail "$1: the job took $dt s to end after SIGTERM (want < 4.5 s)"
  ((MASTER_RC == 0)) || fail "$1: job exit status $MASTER_RC"
  master_log "$1" | grep -v -e progress -e stats | tail -n 12
}

# rank_pid NAME RANK: the pid of one rank of job NAME (a child of its mpirun
# whose environment says OMPI_COMM_WORLD_RANK=RANK); empty when not found.
# Looked for up to ten times a tenth of a second apart: once in a few
# hundred jobs under a full load the lookup came back empty while both
# ranks were alive and running (mpirun's children listed right after), and
# the job, never told to end, was counted as one that ended by itself.
rank_pid() {
  local mp=${MASTER_PID[$1]} p try env
  for ((try = 0; try < 10; try++)); do
    for p in $(pgrep -P "$mp"); do
      env=$(tr '\0' '\n' <"/proc/$p/environ" 2>/dev/null) || continue
      if grep -qx "OMPI_COMM_WORLD_RANK=$2" <<<"$env"; then
        echo "$p"; return 0
      fi
    done
    kill -0 "$mp" 2>/dev/null || return 0
    sleep 0.1
  done
}

# Prints the master's log indented (for the test log).
master_log() { sed "s/^/  $1: /" "$tmp/$1.log"; }

# display_run NAME ARGS...: the display in the foreground (60 s at most),
# output in $tmp/NAME.log; DISPLAY_RC.
display_run() {
  local name=$1; shift
  log_cmd timeout 60 "$display" "$@"
  timeout 60 "$display" "$@" >"$tmp/$name.log" 2>&1
  DISPLAY_RC=$?
  sed "s/^/  $name: /" "$tmp/$name.log" | tail -n 15
}

# display_start NAME ARGS...: the display in the background; DISPLAY_PID.
display_start() {
  local name=$1; shift
  log_cmd "$display" "$@"
  "$display" "$@" >"$tmp/$name.log" 2>&1 &
  DISPLAY_PID=$!
}

# job_with_walker NP: job "job" (mpirun -np NP, the Cornell box) with a
# free-running display "display" walking its path (30 s at most), connected;
# VICTIM is tracer rank 1's pid. The start of the tests that hurt a tracer.
job_with_walker() {
  cornell_args
  master_start job "$1" "${CORNELL[@]}" --listen "unix:$tmp/r.sock"
  master_wait_listen job || finish
  display_start display --connect "$ADDR" "${HEADLESS[@]}" --path "$root/scenes/cornell/walk.path" --seconds 30
  for ((i = 0; i < 100; i++)); do grep -q 'display .* connected' "$tmp/job.log" && break; sleep 0.1; done
  grep -q 'display .* connected' "$tmp/job.log" || fail "the display did not connect"
  sleep 0.5
  VICTIM=$(rank_pid job 1)
  [[ -n $VICTIM ]] || { fail "tracer rank 1 not found"; finish; }
}

# signal_victim SIG LIMIT: sends SIG to tracer rank 1 ($VICTIM, from
# job_with_walker) alone; the job must end within LIMIT seconds with a
# non-zero status, and then the display (DISPLAY_RC, display_gone).
signal_victim() {
  local sig=$1 limit=$2 t0 secs
  echo "+ kill -$sig $VICTIM   (tracer rank 1 alone)"
  t0=$EPOCHREALTIME
  kill -"$sig" "$VICTIM"
  master_wait job 15 || fail "the job did not end within 15 s"
  secs=$(awk -v a="$t0" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f", b - a }')
  echo "metric: job ended ${secs} s after SIG$sig to tracer rank 1"
  awk -v s="$secs" -v l="$limit" 'BEGIN { exit !(s < l) }' || fail "the job took ${secs} s to end (limit $limit s)"
  ((MASTER_RC != 0)) || fail "mpirun exit status 0 after a tracer left"
  display_gone
}

# no_job_left: no process of the job (its socket in the command line) runs.
no_job_left() {
  local left
  left=$(pgrep -f "$tmp/r.sock" | wc -l)
  ((left == 0)) || fail "$left processes of the job are left"
}

# display_gone: waits up to 5 s for the display to exit (killing it if it
# does not, a failure); DISPLAY_RC.
display_gone() {
  for ((i = 0; i < 50; i++)); do kill -0 "$DISPLAY_PID" 2>/dev/null || break; sleep 0.1; done
  if kill -0 "$DISPLAY_PID" 2>/dev/null; then fail "the display is still running"; kill -9 "$DISPLAY_PID"; fi
  wait "$DISPLAY_PID"; DISPLAY_RC=$?
}

# The scene and a small radiosity mesh (cached in $tmp: the first job solves
# it in a fraction of a second, later ones load it).
cornell_args() {
  CORNELL=("$root/scenes/cornell/cornell.json" --rad-cache "$tmp/cornell.ctmesh" --rad-max-triangles 20000)
}

# Headless display options every test uses.
HEADLESS=(--backend egl --width 64 --height 64 --quiet)

# A 5-frame camera path that moves slowly into the Cornell box (t, eye, target, fov).
slow_path() {
  cat >"$tmp/slow.path" <<'EOF'
up 0 1 0
0   278 273 -800   278 273 0   39.3
4   278 263 -700   278 260 0   39.3
EOF
  echo "$tmp/slow.path"
}

# Needs the programs this test runs; skips when MPI cannot start at all.
need_programs() {
  local p
  for p in "$render" "$display" "$@"; do
    [[ -x $p ]] || { fail "missing program $p (run make)"; exit 1; }
  done
  command -v mpirun >/dev/null || skip "mpirun not found (install openmpi-bin)"
}

# same_frames A B WHAT: compares frame_00000.exr .. frame_00004.exr of the
# folders $tmp/A and $tmp/B; fails naming each frame that differs ("FRAME
# differs WHAT"); sets same to the number of identical frames.
same_frames() {
  local k f
  same=0
  for k in 0 1 2 3 4; do
    f=$(printf 'frame_%05d.exr' $k)
    if cmp -s "$tmp/$1/$f" "$tmp/$2/$f"; then same=$((same + 1)); else fail "$f differs $3"; fi
  done
}

finish() {
  if ((fails)); then
    echo "$test_name: $fails failure(s)"
    KEEP_TMP=${KEEP_TMP:-0}
    exit 1
  fi
  echo "$test_name: ok"
  exit 0
}
