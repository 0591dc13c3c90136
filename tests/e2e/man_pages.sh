#!/usr/bin/env bash
# docs/man is what `make man` makes from the programs' --help: regenerated
# into a temporary folder it must be the same, page for page (a stale page
# documents options the programs no longer have).
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
for f in "$tmp"/man/*.1; do
    diff -u "docs/man/${f##*/}" "$f" || fail "docs/man/${f##*/} is stale: run make man"
done
exit $((fails > 0))
