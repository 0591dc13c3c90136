# Shared by tests/e2e/walk_*.sh (sourced, not a test itself): paths, the
# temporary folder (removed at exit), a command logger, the checks for stray
# processes and socket files, and the scene and program checks.
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)
bin=${CORRTEX_BIN:-bin}
[[ $bin == /* ]] || bin="$root/$bin"
walk="$root/scripts/corrtex-walk"
export CORRTEX_BIN="$bin"
# Every file and process of a test carries this folder's name, so strays are
# found by it (and only the test's own are considered).
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ct-e2e-walk-XXXXXX")
trap 'rm -rf "$tmp"' EXIT
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }

# log_cmd ARGS...: prints the exact command line before it runs.
log_cmd() { local s="+"; for a in "$@"; do s+=" $(printf '%q' "$a")"; done; echo "$s"; }

# strays: pids (and command lines) of processes whose command line names $tmp.
strays() { pgrep -a -f -- "$tmp" 2>/dev/null | grep -v -E '^[0-9]+ (pgrep|grep) ' || true; }

# no_strays WHAT: fails when a process of this test outlives the launcher
# (waits up to 5 s for processes that are just ending).
no_strays() {
  local i s
  for ((i = 0; i < 50; i++)); do s=$(strays); [[ -z $s ]] && return 0; sleep 0.1; done
  fail "$1: processes left behind:"; echo "$s" | sed 's/^/  /'
  # ours to end: they were started by this test (by pid, never by name)
  awk '{ print $1 }' <<<"$s" | xargs -r kill -KILL 2>/dev/null
}

# no_sockets WHAT: fails when a socket file is left under $tmp.
no_sockets() {
  local s; s=$(find "$tmp" -type s 2>/dev/null)
  [[ -z $s ]] || fail "$1: socket file(s) left behind: $s"
}

# need_programs: exits 0 with a skip line when the MPI job or the display is
# not built (they are built only once their mains exist).
need_programs() {
  local p
  for p in corrtex-render corrtex-display; do
    if [[ ! -x $bin/$p ]]; then echo "skip: $bin/$p is not built"; rm -rf "$tmp"; exit 0; fi
  done
  command -v mpirun >/dev/null || { echo "skip: mpirun not installed"; rm -rf "$tmp"; exit 0; }
}

# need_scene NAME: sets scene to scenes/NAME/NAME.json; exits 1 when its
# meshes have not been generated.
need_scene() {
  scene="$root/scenes/$1/$1.json"
  [[ -f $scene ]] || { echo "error: $scene missing (make scenes)"; exit 1; }
}

# The radiosity options that keep cornell's cache small for tests.
walk_rad_opts="--max-triangles 20000"

source "$root/tests/e2e/lib/walk-san-env.bash"
