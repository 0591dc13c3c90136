#!/usr/bin/env bash
# The master's saturation replay past full coverage, end to end on a tiny
# scene: corrtex converge records the pixels and then refinement samples
# (--refine-error), tests/bench/bench_master replays every one of them
# (its row counts them all; the replay fails if the master hands out a
# request the recording lacks); tests/bench/bench_late prints its row; bad
# options of bench_master, bench_late and scripts/bench-refine exit 2 with
# one error line.
source "$(dirname "$0")/lib/common.sh"
cd "$root" || exit 1
bench=${CORRTEX_BUILD:-build/release}/bench/bench_master
[[ -x $bench ]] || { echo "FAIL: $bench missing (make unit-bins)"; exit 1; }
view=(tests/data/scenes/mini.json --camera front --width 32 --height 32)

run_corrtex 0 converge "${view[@]}" --samples 3072 --mode drt --stand-in 0.3 --threads 1 --batch 256 \
  --refine-error 0.002 --record "$tmp/rec.srec" --quiet --out "$tmp/conv"
for t in 1 2; do
  echo "+ $bench ${view[*]} --stand-in 0.3 --batch 256 --refine-error 0.002 --record $tmp/rec.srec --master-threads $t"
  row=$("$bench" "${view[@]}" --stand-in 0.3 --batch 256 --refine-error 0.002 --record "$tmp/rec.srec" \
    --master-threads "$t" 2>"$tmp/berr") || { cat "$tmp/berr"; fail "the replay on $t threads failed"; }
  echo "  $row"
  # (the scene's own warning aside: mini.obj has a degenerate triangle)
  grep -v '^warn scene' "$tmp/berr" | grep . && fail "the replay on $t threads complained"
  [[ $row =~ ^\|\ $t\ \|\ 3072\ \| ]] || fail "the replay on $t threads did not insert the 3072 recorded samples"
done

# bad WANT CMD...: exit 2 and exactly one error line mentioning WANT
bad() {
  local want=$1; shift
  "$@" >"$tmp/o" 2>"$tmp/e"; local rc=$?
  echo "+ $*  -> exit $rc: $(cat "$tmp/e")"
  ((rc == 2)) || fail "exit $rc, want 2: $*"
  [[ $(grep -c . "$tmp/e") == 1 ]] || fail "want exactly one error line: $*"
  grep -q -- "$want" "$tmp/e" || fail "the error does not mention '$want': $*"
}
bad "refine-error" "$bench" "${view[@]}" --record "$tmp/rec.srec" --refine-error -1
bad "refine-error" "$bench" "${view[@]}" --record "$tmp/rec.srec" --refine-error often
bad "patch-share" "$bench" "${view[@]}" --record "$tmp/rec.srec" --patch-share 0
# tests/bench/bench_late (docs/textures.md, "Late samples"): one row a step,
# and its bad arguments
late=${CORRTEX_BUILD:-build/release}/bench/bench_late
echo "+ $late tests/data/scenes/mini.json front - --size 16 --ref-spp 1 --steps 0.01"
out=$("$late" tests/data/scenes/mini.json front - --size 16 --ref-spp 1 --steps 0.01 2>"$tmp/lerr") ||
  { cat "$tmp/lerr"; fail "bench_late failed"; }
echo "$out" | tail -n 1
[[ $(grep -c '^| 0.01 |' <<<"$out") == 1 ]] || fail "bench_late printed no row for its step"
bad "--size" "$late" tests/data/scenes/mini.json front - --size big
bad "--size" "$late" tests/data/scenes/mini.json front - --size 8
bad "--steps" "$late" tests/data/scenes/mini.json front - --steps "0.01 -1"
bad "--late-deg" "$late" tests/data/scenes/mini.json front - --late-deg 200
bad "usage" "$late" tests/data/scenes/mini.json front
bad "--bogus" scripts/bench-refine --bogus
bad "--size" scripts/bench-refine --size big
((fails)) && exit 1
echo "bench_master_cli: ok"
