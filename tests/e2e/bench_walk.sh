#!/usr/bin/env bash
# scripts/bench-walk end to end on cornell at 64x64 (one run, three probe
# frames at 32x32): the walk's row goes into the "Walk (free running)"
# section without touching the others; its ratio is taken against the
# tracer alone on the walk's own views (the first camera's rate times the
# time-weighted probe rates over the first camera's probe, computed here
# again from the figures the section prints); bad probe options -> exit 2
# with one error line.
source "$(dirname "$0")/lib/common.sh"
cd "$root" || exit 1
printf '# Benchmarks\n\n## Other\n\nkept\n\n## Walk (free running)\n\nold\n' > "$tmp/b.md"
CORRTEX_BIN=$bin CORRTEX_BENCH_DOC=$tmp/b.md CORRTEX_BENCH_CACHE=$tmp/cache \
    scripts/bench-walk --scenes cornell --size 64 --runs 1 --probe-frames 3 --probe-size 32 \
    >"$tmp/log" 2>&1 || { cat "$tmp/log"; fail "bench-walk failed"; }
sed -n '/^| scene/,/^Machine/p' "$tmp/b.md"
grep -q '^kept$' "$tmp/b.md" || fail "another section was lost"
grep -q '^old$' "$tmp/b.md" && fail "the old section stayed"
row=$(grep '^| cornell | 64 | 1 |' "$tmp/b.md") || fail "no cornell row"
probe=$(grep '^- cornell, 1 rank(s): ' "$tmp/b.md") || fail "no probe line"
# | ... | inserted/s | alone first | alone walk | ratio |
read -r ins first walk ratio <<<"$(awk -F' *\\| *' '{ print $(NF-4), $(NF-3), $(NF-2), $(NF-1) }' <<<"$row")"
# - cornell, 1 rank(s): P0 P1 P2 against F (x X)
read -r p0 p1 p2 pf <<<"$(sed 's/.*rank(s): \([0-9]*\) \([0-9]*\) \([0-9]*\) against \([0-9]*\) .*/\1 \2 \3 \4/' <<<"$probe")"
echo "inserted/s $ins, alone $first (first camera), $walk (walk), ratio $ratio; probes $p0 $p1 $p2 against $pf"
awk -v a="$first" -v w="$walk" -v r="$ratio" -v i="$ins" -v p0="$p0" -v p1="$p1" -v p2="$p2" -v f="$pf" 'BEGIN {
  want = a * (0.5 * p0 + p1 + 0.5 * p2) / 2 / f     # the trapezoid rule over the three frames
  if (!(a > 0 && w > 0 && i > 0 && f > 0)) exit 1
  if (w < want * 0.99 || w > want * 1.01) exit 1   # the probes are printed rounded
  if (r < i / w - 0.011 || r > i / w + 0.011) exit 1
}' || fail "the walk's alone/s or the ratio does not follow from the figures printed"
for bad in "--probe-frames 1" "--probe-size x"; do
  # shellcheck disable=SC2086
  CORRTEX_BIN=$bin CORRTEX_BENCH_DOC=$tmp/c.md scripts/bench-walk $bad >/dev/null 2>"$tmp/err"
  rc=$?
  [[ $rc == 2 && $(wc -l <"$tmp/err") == 1 && ! -e $tmp/c.md ]] || { cat "$tmp/err"; fail "$bad exited $rc"; }
done
exit $((fails > 0))
