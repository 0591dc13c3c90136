#!/usr/bin/env bash
# The radiosity solution of a diffuse-only Cornell box (every material of
# scenes/cornell replaced by a diffuse one, tests/data/radiosity/
# cornell_diffuse.json) against a path-traced reference of the same scene,
# 128 x 128, camera "front". (Region by region: radiosity_regions.sh.)
#
# Threshold, calibrated by the test itself: a second reference with another
# seed measures the reference's noise, rmse(ref, ref2) = sqrt(2) * sigma. The
# radiosity image (256 samples per pixel of the Gouraud mesh, so its edges
# are as converged as the reference's) differs from the reference by
# sqrt(b^2 + sigma^2), b being the radiosity's own error. We require
# rmse(radiosity, ref) <= 1.2 * rmse(ref, ref2), i.e. b <= 1.37 sigma, with
# 1024-sample references (sigma about 0.0085): the interactive solution is
# about as close to the truth as a 1024-sample path-traced image is. Solver
# version 16: 0.0098 against a noise of 0.0120 (b about 0.005); with
# 256-sample references (before) 0.0166 against 0.0215.
# Needs `corrtex reference` (the tracer); skips when this build lacks it.
set -u
BIN=${CORRTEX_BIN:-bin}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
exec 3>&1   # commands are logged to the original stdout even when output is redirected
run() { echo "+ $*" >&3; "$@"; }
if ! "$BIN/corrtex" reference --help >/dev/null 2>&1; then
  echo "skip: corrtex reference is not in this build (the tracer); radiosity vs path not compared"
  exit 0
fi
[[ -f scenes/cornell/cornell.obj ]] || { echo "missing scenes/cornell meshes (run make scenes)"; exit 1; }
diffuse=tests/data/radiosity/cornell_diffuse.json
size=(--width 128 --height 128)
run "$BIN/corrtex" radiosity "$diffuse" -o "$tmp/d.ctmesh" --image "$tmp/rad.exr" --camera front \
  "${size[@]}" --spp 256 --quiet >/dev/null || { echo "FAIL: radiosity"; exit 1; }
run "$BIN/corrtex" reference "$diffuse" --camera front "${size[@]}" --spp 1024 --mode path --seed 1 \
  -o "$tmp/ref.exr" >/dev/null 2>&1 || { echo "FAIL: reference"; exit 1; }
run "$BIN/corrtex" reference "$diffuse" --camera front "${size[@]}" --spp 1024 --mode path --seed 2 \
  -o "$tmp/ref2.exr" >/dev/null 2>&1 || { echo "FAIL: second reference"; exit 1; }
noise=$("$BIN/corrtex" compare "$tmp/ref2.exr" "$tmp/ref.exr" | awk '$1 == "rmse" { print $2 }')
rad=$("$BIN/corrtex" compare "$tmp/rad.exr" "$tmp/ref.exr" | awk '$1 == "rmse" { print $2 }')
limit=$(awk -v n="$noise" 'BEGIN { printf "%.6g", 1.2 * n }')
echo "metric: radiosity_vs_path_rmse=$rad reference_noise_rmse=$noise limit=$limit"
run "$BIN/corrtex" compare "$tmp/rad.exr" "$tmp/ref.exr" --max-rmse "$limit" || { echo "FAIL: rmse $rad above $limit"; exit 1; }
exit 0
