# tests/e2e/lib/common.sh: the preamble shared by the end-to-end tests of
# bin/corrtex (sourced, not a test itself): the repository root, the programs'
# folder ($CORRTEX_BIN, default bin) and corrtex in it, a temporary folder
# named after the test and removed at exit, and fail() counting failures.
#
#   source "$(dirname "$0")/lib/common.sh"   sets root, bin, corrtex, tmp, fails, fail()
set -u
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)
bin=${CORRTEX_BIN:-bin}
[[ $bin == /* ]] || bin="$root/$bin"
corrtex="$bin/corrtex"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ct-e2e-$(basename "$0" .sh)-XXXXXX")
trap 'rm -rf "$tmp"' EXIT

fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
