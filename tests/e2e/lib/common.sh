# tests/e2e/lib/common.sh: the preamble shared by the end-to-end tests of
# bin/corrtex (sourced, not a test itself): the repository root, the programs'
# folder ($CORRTEX_BIN, default bin) and corrtex in it, a temporary folder
# named after the test and removed at exit, and fail() counting failures.
#
#   source "$(dirname "$0")/lib/common.sh"   sets root, bin, corrtex, tmp, fails, fail()
#   run_corrtex WANT ARGS...                  runs corrtex ARGS, logged; fails unless it exits WANT
set -u
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)
bin=${CORRTEX_BIN:-bin}
[[ $bin == /* ]] || bin="$root/$bin"
corrtex="$bin/corrtex"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ct-e2e-$(basename "$0" .sh)-XXXXXX")
trap 'rm -rf "$tmp"' EXIT

fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }

# run_corrtex WANT ARGS...: runs corrtex ARGS, logs the command, keeps its
# stdout in $out and $tmp/out, its stderr in $err and $tmp/err, prints both
# (their last $run_tail lines when run_tail is set) and fails unless the
# exit status (in rc) is WANT.
run_corrtex() {
  local want=$1; shift
  echo "+ $corrtex $*"
  "$corrtex" "$@" >"$tmp/out" 2>"$tmp/err"
  rc=$?
  out=$(cat "$tmp/out"); err=$(cat "$tmp/err")
  sed 's/^/  stdout: /' "$tmp/out" | tail -n "${run_tail:-+1}"
  sed 's/^/  stderr: /' "$tmp/err" | tail -n "${run_tail:-+1}"
  if ((rc != want)); then fail "exit status $rc, expected $want: corrtex $*"; fi
}
