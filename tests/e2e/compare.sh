#!/usr/bin/env bash
# End-to-end test of `corrtex compare`: metrics, --json keys and exit codes
# 0 (ok), 1 (--max-rmse exceeded) and 2 (bad input or usage), on the tiny
# EXR files in tests/data/ (written and checked by tests/unit/test_image.c:
# compare-test.exr is compare-ref.exr with +-0.05 on every value).
source "$(dirname "$0")/lib/common.sh"
data="$root/tests/data"

# expect_error FILE_OR_TEXT: stderr is exactly one line
# "error corrtex compare: <text>..."
expect_error() {
  local lines
  lines=$(wc -l <"$tmp/err")
  ((lines == 1)) || fail "expected one error line, got $lines"
  [[ $err == "error corrtex compare: $1"* ]] || fail "error line does not start with 'error corrtex compare: $1': $err"
}

# json_get KEY: the number (or null) after "KEY": in $out.
json_get() { sed -nE "s/.*\"$1\":(null|[-+0-9.eE]+).*/\1/p" <<<"$out"; }

# near A B TOL: |A - B| <= TOL
near() { awk -v a="$1" -v b="$2" -v t="$3" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(d <= t) }'; }

[[ -x $corrtex ]] || { echo "error: $corrtex not built"; exit 1; }
ref="$data/compare-ref.exr"; test="$data/compare-test.exr"
for f in "$ref" "$test" "$data/compare-small.exr" "$data/compare-luminance.exr"; do
  [[ -f $f ]] || { echo "error: missing test data $f"; exit 1; }
done

echo "== identical images"
run_corrtex 0 compare "$ref" "$ref"
grep -qx 'rmse 0' <<<"$out" || fail "rmse of identical images is not 0"
grep -qx 'psnr inf dB' <<<"$out" || fail "psnr of identical images is not inf"
grep -qx 'ssim 1.000000' <<<"$out" || fail "ssim of identical images is not 1"

echo "== --json"
run_corrtex 0 compare "$test" "$ref" --json
for k in rmse rel_mse psnr ssim width height; do
  grep -q "\"$k\":" <<<"$out" || fail "JSON lacks key $k"
done
if command -v python3 >/dev/null; then
  echo "+ python3 -m json.tool (validates the JSON)"
  python3 -m json.tool <<<"$out" >/dev/null || fail "output is not valid JSON"
fi
rmse=$(json_get rmse); psnr=$(json_get psnr); ssim=$(json_get ssim); rel=$(json_get rel_mse)
echo "metric: rmse=$rmse rel_mse=$rel psnr=$psnr ssim=$ssim (compare-test vs compare-ref)"
near "$rmse" 0.05 1e-6 || fail "rmse $rmse, expected 0.05"
[[ $(json_get width) == 16 && $(json_get height) == 16 ]] || fail "size is not 16x16"
awk -v s="$ssim" 'BEGIN { exit !(s > 0 && s < 1) }' || fail "ssim $ssim not in (0, 1)"
awk -v p="$psnr" 'BEGIN { exit !(p > 10 && p < 60) }' || fail "psnr $psnr implausible"
run_corrtex 0 compare --json "$ref" "$ref"
[[ $(json_get psnr) == null ]] || fail "psnr of identical images should be null in JSON"

echo "== --max-rmse"
run_corrtex 0 compare "$test" "$ref" --max-rmse 0.06
run_corrtex 1 compare "$test" "$ref" --max-rmse 0.04
grep -q "exceeds --max-rmse 0.04" <<<"$err" || fail "exit 1 without the limit in the message"
grep -q "rmse 0.05" <<<"$err" || fail "exit 1 without the rmse in the message"
run_corrtex 0 compare "$ref" "$ref" --max-rmse 0

echo "== --regions"
run_corrtex 0 compare "$ref" "$ref" --regions 4 --flat "$ref" --flat-ratio 100 --region-table
grep -qx 'regions 16' <<<"$out" || fail "16 blocks of 4 x 4 expected: $out"
grep -qx 'region_worst 0' <<<"$out" || fail "region_worst of identical images is not 0"
(( $(grep -c '^ [ 0-9.]*$' <<<"$out") == 4 )) || fail "--region-table did not print 4 rows"
run_corrtex 0 compare "$test" "$ref" --regions 8 --json
grep -q '"regions":4,' <<<"$out" || fail "JSON lacks regions 4: $out"
worst=$(json_get region_worst)
echo "metric: region_worst=$worst (compare-test vs compare-ref, 8 x 8 blocks)"
run_corrtex 1 compare "$test" "$ref" --regions 8 --max-region-error 0
grep -q "above --max-region-error 0" <<<"$err" || fail "exit 1 without the limit in the message"
run_corrtex 0 compare "$test" "$ref" --regions 8 --max-region-error 1
run_corrtex 2 compare "$ref" "$ref" --planes "$ref"
expect_error "--planes, --flat, --max-region-error, --region-table and the repeats need --regions"
run_corrtex 2 compare "$ref" "$ref" --regions 17
expect_error "region size 17 outside [1, 16]"
run_corrtex 2 compare "$ref" "$ref" --regions 4 --planes "$data/compare-small.exr"
expect_error "image sizes differ"
run_corrtex 2 compare "$ref" "$ref" --regions 4 --flat-ratio 0.5
expect_error "--flat-ratio"

echo "== --repeat-a / --repeat-b: each block in its own standard errors"
# compare-test is compare-ref +-0.05 on every value: taken as A's repeat,
# the reference gives A a pixel noise of 0.05 / sqrt(2) per value.
run_corrtex 0 compare "$test" "$ref" --regions 8 --repeat-a "$ref" --z-table
for k in region_sigma_rms region_z_worst region_z_worst_at region_beyond; do
  grep -q "^$k " <<<"$out" || fail "no $k line: $out"
done
(( $(grep -c '^ [ 0-9.-]*$' <<<"$out") == 2 )) || fail "--z-table did not print 2 rows"
sig=$(sed -nE 's/^region_sigma_rms (.*)/\1/p' <<<"$out"); zw=$(sed -nE 's/^region_z_worst (.*)/\1/p' <<<"$out")
echo "metric: region_sigma_rms=$sig region_z_worst=$zw (compare-test vs compare-ref, its repeat compare-ref)"
awk -v s="$sig" 'BEGIN { exit !(s > 0) }' || fail "region_sigma_rms $sig is not positive"
run_corrtex 0 compare "$test" "$ref" --regions 8 --repeat-b "$test" --json
for k in region_sigma_rms region_z_worst region_beyond; do
  grep -q "\"$k\":" <<<"$out" || fail "JSON lacks key $k"
done
# Real renders (path tracing of tests/data/scenes/mini.json, 64x64, 64 spp,
# four seeds): two unbiased images agree within their noise; the direct
# light alone (--depth 1) is a bias that the whole image's rmse hides
# under the noise, and the blocks show it.
for s in 1 2 3 4; do
  run_corrtex 0 reference "$data/scenes/mini.json" --width 64 --height 64 --spp 64 --mode path --seed "$s" --quiet \
    -o "$tmp/p$s.exr"
done
run_corrtex 0 reference "$data/scenes/mini.json" --width 64 --height 64 --spp 64 --mode path --depth 1 --seed 1 \
  --quiet -o "$tmp/d1.exr"
run_corrtex 0 reference "$data/scenes/mini.json" --width 64 --height 64 --spp 64 --mode path --depth 1 --seed 2 \
  --quiet -o "$tmp/d2.exr"
run_corrtex 0 compare "$tmp/p1.exr" "$tmp/p3.exr" --regions 16 --repeat-a "$tmp/p2.exr" --repeat-b "$tmp/p4.exr" \
  --max-region-sigma 5
echo "metric: two seeds of path tracing: $(grep -E '^region_(rms|sigma_rms|z_worst|beyond) ' <<<"$out" | tr '\n' ' ')"
run_corrtex 1 compare "$tmp/d1.exr" "$tmp/p3.exr" --regions 16 --repeat-a "$tmp/d2.exr" --repeat-b "$tmp/p4.exr" \
  --max-region-sigma 5
echo "metric: direct light alone against path tracing: $(grep -E '^region_(rms|sigma_rms|z_worst|beyond) ' <<<"$out" |
  tr '\n' ' ')"
grep -q "standard errors (block [0-9]* [0-9]*) above --max-region-sigma 5" <<<"$err" ||
  fail "exit 1 without the bound in the message: $err"
run_corrtex 2 compare "$test" "$ref" --repeat-a "$ref"
expect_error "--planes, --flat, --max-region-error, --region-table and the repeats need --regions"
run_corrtex 2 compare "$test" "$ref" --regions 8 --max-region-sigma 3
expect_error "--sigmas, --max-region-sigma and --z-table need --repeat-a or --repeat-b"
run_corrtex 2 compare "$test" "$ref" --regions 8 --sigmas 3
expect_error "--sigmas, --max-region-sigma and --z-table need --repeat-a or --repeat-b"
run_corrtex 2 compare "$test" "$ref" --regions 8 --repeat-b "$data/compare-small.exr"
expect_error "$data/compare-small.exr: image sizes differ"
run_corrtex 2 compare "$test" "$ref" --regions 8 --repeat-b "$tmp/missing.exr"
expect_error "$tmp/missing.exr: cannot open"

echo "== bad input"
head -c 300 "$test" >"$tmp/truncated.exr"
run_corrtex 2 compare "$tmp/truncated.exr" "$ref"
expect_error "$tmp/truncated.exr: "
head -c 600 "$test" >"$tmp/cut.exr"
run_corrtex 2 compare "$ref" "$tmp/cut.exr"
expect_error "$tmp/cut.exr: "
run_corrtex 2 compare "$tmp/missing.exr" "$ref"
expect_error "$tmp/missing.exr: cannot open"
run_corrtex 2 compare "$data/compare-luminance.exr" "$ref"
expect_error "$data/compare-luminance.exr: EXR has no channel R, G, B"
run_corrtex 2 compare "$data/compare-small.exr" "$ref"
expect_error "$data/compare-small.exr: image sizes differ"
echo "not an image" >"$tmp/text.exr"
run_corrtex 2 compare "$tmp/text.exr" "$ref"
expect_error "$tmp/text.exr: "

echo "== usage"
run_corrtex 2 compare "$ref"
expect_error "expected two images"
run_corrtex 2 compare "$ref" "$ref" "$ref"
run_corrtex 2 compare "$ref" "$ref" --max-rmse abc
expect_error "--max-rmse"
run_corrtex 2 compare "$ref" "$ref" --max-rmse -1
run_corrtex 2 compare "$ref" "$ref" --frobnicate
run_corrtex 0 compare --help
grep -q "default" <<<"$out" || fail "--help prints no defaults"

if ((fails)); then echo "compare.sh: $fails check(s) failed"; exit 1; fi
echo "compare.sh: all checks passed"
