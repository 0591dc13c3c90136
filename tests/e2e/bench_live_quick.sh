#!/usr/bin/env bash
# scripts/bench-refine --quick and scripts/bench-camera-rate --quick (table
# at 256x256 and 128x128, one tracer rank): the live benchmarks of the
# master still read what the programs print. Their rows have figures, not
# "-", in the columns every run fills (refinement samples/s, cores, MB/s, lag, the
# tracers alone; cameras and views a second, inserted/s and its ratio), and
# bench-camera-rate has its four rows (turn and walk, every camera and the
# default). --quick writes nothing.
source "$(dirname "$0")/lib/common.sh"
cd "$root" || exit 1
printf '# Benchmarks\n\nold\n' > "$tmp/b.md"
export CORRTEX_BIN=$bin CORRTEX_BENCH_DOC=$tmp/b.md CORRTEX_BENCH_CACHE=$tmp/cache
num='[0-9]+(\.[0-9]+)?'
check() {  # NAME VALUE REGEX
  [[ $(echo "$2" | xargs) =~ ^$3$ ]] || fail "$1: '$(echo "$2" | xargs)' is not a figure"
}

scripts/bench-refine --quick >"$tmp/refine.log" 2>&1 || { cat "$tmp/refine.log"; fail "bench-refine --quick failed"; }
row=$(grep -m1 '^| table | 256 | 1 |' "$tmp/refine.log") || { cat "$tmp/refine.log"; fail "no bench-refine row"; }
echo "$row"
IFS='|' read -r _ _ _ _ first _ refine _ cores mbs whole _ lag cheap drt _ <<<"$row"
# (the first pass may be "-": at 256x256 the cheap tracer can cover the
# view before the master's first stats line, and then it has no span)
check "first pass samples/s" "$first" "($num|-)"
check "refinement samples/s" "$refine" "$num"
check "cores master / tracer" "$cores" "$num / $num"
check "MB/s" "$mbs" "$num"
check "whole / part" "$whole" "$num"
check "lag ms" "$lag" "$num / $num"
check "cheap tracer alone" "$cheap" "$num"
check "drt tracer alone" "$drt" "$num"

scripts/bench-camera-rate --quick >"$tmp/rate.log" 2>&1 || { cat "$tmp/rate.log"; fail "bench-camera-rate --quick failed"; }
for m in "turn | every" "turn | default" "walk | every" "walk | default"; do
  row=$(grep -m1 "^| table | 128 | 200 | $m |" "$tmp/rate.log") || { fail "no bench-camera-rate row for $m"; continue; }
  echo "$row"
  IFS='|' read -r _ _ _ _ _ _ cams views ins ratio _ _ _ _ mbs _ <<<"$row"
  check "$m: cameras/s" "$cams" "$num"
  check "$m: views/s" "$views" "$num"
  check "$m: inserted/s" "$ins" "$num"
  check "$m: whole / part" "$ratio" "$num"
  check "$m: MB/s to the display" "$mbs" "$num"
done
grep -q '^old$' "$tmp/b.md" || fail "--quick wrote the document"
exit $((fails > 0))
