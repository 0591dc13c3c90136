#!/usr/bin/env bash
# scripts/bench-tracer end to end on a tiny scene: two passes over two rows,
# one table row per (scene, mode, threads) with the medians, the ratio's range
# over the passes and the goal verdict, written into the Tracer section of the
# output file without touching its other sections; bad --passes -> exit 2
# with one error line and no output file.
source "$(dirname "$0")/lib/common.sh"
cd "$root" || exit 1
mkdir -p "$tmp/scenes/mini"
cp tests/data/scenes/mini.* "$tmp/scenes/mini/"
printf '# Benchmarks\n\n## Other\n\nkept\n\n## Tracer\n\nold\n' > "$tmp/b.md"
CORRTEX_BIN=$bin scripts/bench-tracer --size 16 --scenes mini --scene-dir "$tmp/scenes" --modes "path drt" \
    --threads 1 --passes 2 --runs 1 --raw-cap 1000 --out "$tmp/b.md" >"$tmp/log" 2>&1 \
    || { cat "$tmp/log"; fail "bench-tracer failed"; }
cat "$tmp/b.md"
[[ $(grep -c '^+ pass [12]/2: ' "$tmp/log") == 4 ]] || fail "not 2 passes over 2 rows"
grep -q '^kept$' "$tmp/b.md" || fail "another section was lost"
grep -q '^old$' "$tmp/b.md" && fail "the old Tracer section stayed"
rows=$(grep -cE '^\| mini \| [0-9]+ \| (path|drt[^|]*) \| 1 \| [0-9.]+ \|.* [0-9]+\.[0-9] % \| [0-9]+\.[0-9]-[0-9]+\.[0-9] % \| [0-9]+\.[0-9] % \| (yes|no) \|$' "$tmp/b.md")
[[ $rows == 2 ]] || fail "$rows well-formed table rows, want 2"
grep -q 'met in [0-2] of 2 rows' "$tmp/b.md" || fail "no goal summary"
CORRTEX_BIN=$bin scripts/bench-tracer --passes 0 --out "$tmp/c.md" >/dev/null 2>"$tmp/err"
rc=$?
[[ $rc == 2 && $(wc -l <"$tmp/err") == 1 && ! -e $tmp/c.md ]] || { cat "$tmp/err"; fail "--passes 0 exited $rc"; }
exit $((fails > 0))
