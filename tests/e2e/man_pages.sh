#!/usr/bin/env bash
# docs/man is what `make man` makes from the programs' --help: regenerated
# into a temporary folder it must be the same, page for page but for the
# date line (a stale page documents options the programs no longer have).
source "$(dirname "$0")/lib/common.sh"
cd "$root" || exit 1
# corrtex-render starts MPI even for --help, and Open MPI's allocations live
# until exit: this test checks documents, not leaks (the MPI tests do).
[[ -n ${ASAN_OPTIONS:-} ]] && export ASAN_OPTIONS=$ASAN_OPTIONS:detect_leaks=0
scripts/gen-man "$tmp/man" "$bin/corrtex" "$bin/corrtex-render" "$bin/corrtex-display" scripts/corrtex-walk \
    >/dev/null || fail "gen-man failed"
for f in docs/man/*.1; do
    [[ -f $tmp/man/${f##*/} ]] || fail "$f: no such page is made any more"
done
# The first line carries the date a page was made: pages made from the same
# programs on another day are the same pages.
for f in "$tmp"/man/*.1; do
    diff -u <(tail -n +2 "docs/man/${f##*/}") <(tail -n +2 "$f") || fail "docs/man/${f##*/} is stale: run make man"
done
exit $((fails > 0))
