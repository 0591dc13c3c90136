#!/usr/bin/env bash
# --version of every program: corrtex, corrtex-render, corrtex-display and
# corrtex-walk print one line "PROGRAM 0.1.0 (git HASH)", the number of
# common/version.h and the commit the build came from ("unknown" outside a
# git checkout), exit 0 and start nothing; the help texts name the option.
# A tree without .git (a tarball) builds the version with commit "unknown".
source "$(dirname "$0")/lib/common.sh"
cd "$root" || exit 1
# corrtex-render starts MPI even for --version, and Open MPI's allocations
# live until exit: this test checks a line, not leaks (the MPI tests do).
[[ -n ${ASAN_OPTIONS:-} ]] && export ASAN_OPTIONS=$ASAN_OPTIONS:detect_leaks=0
number=$(sed -nE 's/^#define CT_VERSION "([^"]+)"$/\1/p' common/version.h)
[[ $number =~ ^[0-9]+\.[0-9]+\.[0-9]+$ ]] || fail "common/version.h: no CT_VERSION \"N.N.N\" ('$number')"

hash=
for p in "$bin/corrtex" "$bin/corrtex-render" "$bin/corrtex-display" scripts/corrtex-walk; do
  name=$(basename "$p")
  echo "+ $p --version"
  CORRTEX_BIN=$bin "$p" --version >"$tmp/out" 2>"$tmp/err"; rc=$?
  sed 's/^/  stdout: /' "$tmp/out"; sed 's/^/  stderr: /' "$tmp/err"
  ((rc == 0)) || fail "$name --version: exit $rc, want 0"
  [[ ! -s $tmp/err ]] || fail "$name --version: something on stderr"
  [[ $(wc -l <"$tmp/out") -eq 1 ]] || fail "$name --version: want one line"
  line=$(cat "$tmp/out")
  [[ $line =~ ^$name\ ([^ ]+)\ \(git\ ([0-9a-f]{7,40}|unknown)\)$ ]] ||
    { fail "$name --version: '$line' is not '$name N.N.N (git HASH)'"; continue; }
  [[ ${BASH_REMATCH[1]} == "$number" ]] || fail "$name --version: ${BASH_REMATCH[1]}, not common/version.h's $number"
  # one build: every program says the same commit
  [[ -z $hash || ${BASH_REMATCH[2]} == "$hash" ]] || fail "$name --version: commit ${BASH_REMATCH[2]}, not $hash"
  hash=${BASH_REMATCH[2]}
  CORRTEX_BIN=$bin "$p" --help 2>/dev/null | grep -q -- '--version' || fail "$name --help does not name --version"
done
# In a git checkout the commit is one of this repository's (the build may
# be older than HEAD).
if [[ -e .git && $hash != unknown ]] && command -v git >/dev/null; then
  git cat-file -e "$hash^{commit}" 2>/dev/null || fail "commit $hash of --version is not in this repository"
fi
scripts/corrtex-walk --version=yes >/dev/null 2>"$tmp/err"; rc=$?
((rc == 2)) && grep -qx 'error corrtex-walk: option --version takes no value' "$tmp/err" ||
  fail "corrtex-walk --version=yes: exit $rc, $(cat "$tmp/err")"
# bin/corrtex help lists it; a subcommand does not take it.
run_corrtex 0 help
grep -q '^       corrtex --version ' "$tmp/out" || fail "corrtex help does not name corrtex --version"
run_corrtex 2 info --version
# The build outside a git checkout: the Makefile, common/version.[ch] in a
# folder without .git make the object with "unknown" (the commit header
# used to need git).
mkdir -p "$tmp/tarball/common"
cp Makefile "$tmp/tarball/"; cp common/version.c common/version.h "$tmp/tarball/common/"
# (a release build whatever this suite's: make test-asan passes SANITIZE on
# to every make below it through MAKEFLAGS)
echo "+ make -C $tmp/tarball SANITIZE= build/release/common/version.o"
env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s -C "$tmp/tarball" SANITIZE= build/release/common/version.o \
  >"$tmp/make.log" 2>&1 ||
  { fail "the version object does not build without .git"; cat "$tmp/make.log"; }
grep -qx '#define CT_GIT_COMMIT "unknown"' "$tmp/tarball/build/release/version/ct_commit.h" 2>/dev/null ||
  fail "without .git the commit is not 'unknown': $(cat "$tmp/tarball/build/release/version/ct_commit.h" 2>&1)"
nm "$tmp/tarball/build/release/common/version.o" 2>/dev/null | grep -q ' T ct_version_print$' ||
  fail "the object built without .git lacks ct_version_print"
exit $((fails > 0))
