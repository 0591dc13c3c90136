#!/usr/bin/env bash
# scripts/bench-walkthrough end to end at 32x32 on cornell (one K, two
# frames): the table rows of the three methods go into the Walkthrough
# section without touching the others; the corrective texturing walk runs on
# the very radiosity mesh its references and baselines used (the walk's
# radiosity step reuses the benchmark's cache instead of solving it again
# with other options); recorded commands are copy-pastable; the caches stay
# under --work; a bad option -> exit 2 with one error line.
source "$(dirname "$0")/lib/common.sh"
source "$root/tests/e2e/lib/walk-san-env.bash"
cd "$root" || exit 1
w=$tmp/w
printf '# Benchmarks\n\n## Other\n\nkept\n\n## Walkthrough\n\nold\n' > "$tmp/b.md"
CORRTEX_BIN=$bin scripts/bench-walkthrough --scenes cornell --size 32 --frames 2 --spf 100 --ref-spp 1 \
    --no-scaling --no-figures --no-sustained --threads 1 --max-tracers 1 \
    --radiosity-options "--max-triangles 4000" --work "$w" --doc "$tmp/b.md" --images "$tmp/img" \
    >"$tmp/log" 2>&1 || { cat "$tmp/log"; fail "bench-walkthrough failed"; }
sed -n '/^| scene/,/^$/p' "$tmp/b.md"
grep -q '^kept$' "$tmp/b.md" || fail "another section was lost"
grep -q '^old$' "$tmp/b.md" && fail "the old Walkthrough section stayed"
for m in 'radiosity alone' 'naive point display' 'corrective texturing'; do
    grep -qE "^\| cornell \| $m \| [0-9]+ \| 2 \|.*\| [0-9.]+ \| [0-9.]+ \|" "$tmp/b.md" || fail "no row for $m"
done
[[ -f $w/cache/cornell.ctmesh ]] || fail "the radiosity cache is not under --work"
sum=$(sha256sum "$w/cache/cornell.ctmesh" | cut -c1-12)
ls -d "$w"/ref-cornell-32-f2-drt-s1-m"$sum"-r* >/dev/null 2>&1 || fail "no references for the cache's mesh $sum"
n=0
for r in "$w"/cornell/ct-*/radiosity.out; do
    [[ -f $r ]] || continue
    n=$((n + 1))
    grep -q '^cached 1$' "$r" || { cat "$r"; fail "$r: the walk solved the radiosity again"; }
done
((n >= 1)) || fail "no corrective texturing run"
grep -qF -- '--radiosity-options --max-triangles\ 4000' "$tmp/b.md" || fail "recorded walk command not quoted"
[[ -f $tmp/img/error_vs_samples.png ]] || fail "no error-vs-samples plot"
CORRTEX_BIN=$bin scripts/bench-walkthrough --frames 0 --work "$tmp/x" --doc "$tmp/c.md" >/dev/null 2>"$tmp/err"
rc=$?
[[ $rc == 2 && $(wc -l <"$tmp/err") == 1 && ! -e $tmp/c.md ]] || { cat "$tmp/err"; fail "--frames 0 exited $rc"; }
exit $((fails > 0))
