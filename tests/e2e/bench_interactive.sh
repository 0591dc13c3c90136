#!/usr/bin/env bash
# scripts/bench-interactive --quick (table at 128x128, one tracer rank, 4 s
# still, the walk and its hold): the benchmark of the interactive goals
# still reads what the programs print. Its row has figures, not "-", where
# every run has them: samples/s of the run and of the tracer alone and
# their ratio, the CPU shares, the lag, the final PSNR and the display's
# frame with and without the stream (a change to a stats or summary line
# the script parses shows here, not at the next benchmark run); --quick
# writes nothing (the documents' checksums stay).
source "$(dirname "$0")/lib/common.sh"
cd "$root" || exit 1
printf '# Benchmarks\n\n## Interactive\n\nold\n' > "$tmp/b.md"
CORRTEX_BIN=$bin CORRTEX_BENCH_DOC=$tmp/b.md CORRTEX_BENCH_IMAGES=$tmp/img CORRTEX_BENCH_CACHE=$tmp/cache \
    scripts/bench-interactive --quick >"$tmp/log" 2>&1 || { cat "$tmp/log"; fail "bench-interactive --quick failed"; }
row=$(grep -m1 '^| table | 128 | 1 |' "$tmp/log") || { cat "$tmp/log"; fail "no table row"; }
echo "$row"
num='[0-9]+(\.[0-9]+)?'
IFS='|' read -r _ _ _ _ first run alone ratio cpus _ lag _ covered _ final frame _ <<<"$row"
check() {  # NAME VALUE REGEX
  [[ $(echo "$2" | xargs) =~ ^$3$ ]] || fail "$1: '$(echo "$2" | xargs)' is not a figure"
}
check run "$run" "$num"
check alone "$alone" "$num"
check ratio "$ratio" "$num"
check "CPU shares" "$cpus" "$num / $num / $num"
check lag "$lag" "$num / $num"
check "final dB" "$final" "$num"
check "frame ms" "$frame" "$num / $num \\($num\\)"
# Under the sanitizers the tracer may not cover the view in the 4 s.
if [[ -z ${ASAN_OPTIONS:-} ]]; then
  check "first pass" "$first" "$num"
  check covered "$covered" "$num"
fi
grep -q '^old$' "$tmp/b.md" || fail "--quick wrote the document"
[[ -e $tmp/img ]] && [[ -n $(ls -A "$tmp/img") ]] && fail "--quick wrote images"
exit $((fails > 0))
