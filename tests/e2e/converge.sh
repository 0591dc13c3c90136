#!/usr/bin/env bash
# End-to-end test of `corrtex converge` (master engine + tracer in one
# process) on cornell at 48x48 with the constant radiosity stand-in and drt
# samples against a 128-spp drt reference over the same stand-in (what the
# corrections converge to, so the samples are unbiased against it; 1-spp
# path samples were tried: their caustics through the glass sphere made each
# checkpoint's PSNR swing by a dB from seed to seed, more than the rises
# checked here, while drt's rise by 1-3 dB on every seed tried): the
# output files, convergence.csv rows, PSNR against the reference
# rising with the samples, the --move-to phase (Fig. 7), the insertion timer,
# and exit status 2 with one error line on bad input, before the output
# folder is made.
source "$(dirname "$0")/lib/common.sh"
scene="$root/scenes/cornell/cornell.json"

run_tail=20   # run_corrtex prints the last 20 lines of each output

# csv_col ROW_PREFIX COLUMN_NAME: the value of a column in the first row
# whose "phase,samples" starts with ROW_PREFIX.
csv_col() {
  awk -F, -v pre="$1" -v col="$2" '
    NR == 1 { for (i = 1; i <= NF; i++) if ($i == col) c = i; next }
    index($1 "," $2, pre) == 1 { print $c; exit }' "$tmp/out1/convergence.csv"
}

for cam_out in front:ref spheres:ref2; do
  run_corrtex 0 reference "$scene" --camera "${cam_out%%:*}" --width 48 --height 48 --spp 128 --mode drt \
    --stand-in-radiosity 0.3 --seed 7 -o "$tmp/${cam_out#*:}.exr"
done

run_corrtex 0 converge "$scene" --camera front --samples 100,800,all --width 48 --height 48 --stand-in 0.3 --mode drt \
  --reference "$tmp/ref.exr" --move-to spheres --samples-after 600 --reference-after "$tmp/ref2.exr" \
  --time-insert --insert-runs 3 --out "$tmp/out1"
for f in convergence.csv radiosity.exr radiosity.png assignment.png corrected_100.exr corrected_100.png \
         samples_100.png corrected_800.exr corrected_2304.exr samples_2304.png hq_samples.exr \
         moved.exr moved.png after_assignment.png after_corrected_600.exr after_samples_600.png \
         after_hq_samples.exr; do
  [[ -s $tmp/out1/$f ]] || fail "missing output $f"
done
cat "$tmp/out1/convergence.csv"
rows=$(($(wc -l <"$tmp/out1/convergence.csv") - 1))
((rows == 6)) || fail "expected 6 rows (radiosity, 3 still, moved, after), got $rows"
p0=$(csv_col "radiosity,0" psnr); p1=$(csv_col "still,100" psnr)
p2=$(csv_col "still,800" psnr); p3=$(csv_col "still,2304" psnr)
pm=$(csv_col "moved,0" psnr); pa=$(csv_col "after,600" psnr)
cov=$(csv_col "still,2304" coverage)
echo "metric: converge_psnr_radiosity=$p0"
echo "metric: converge_psnr_100=$p1"
echo "metric: converge_psnr_800=$p2"
echo "metric: converge_psnr_all=$p3"
echo "metric: converge_psnr_moved=$pm"
echo "metric: converge_psnr_after600=$pa"
# single samples are noisy: from 800 samples on, more samples replace
# interpolated corrections by single noisy ones, so the last step may lose a
# little (at most 1 dB here; seeds 1-5 gained 0.1-2.4 dB); the gain over
# radiosity alone is large (16.3 -> 24-25.7 dB on seeds 1-5)
awk -v a="$p0" -v b="$p1" -v c="$p2" -v d="$p3" 'BEGIN { exit !(a < b && b < c && d > c - 1 && d > a + 3) }' ||
  fail "PSNR does not rise with the samples: $p0 $p1 $p2 $p3"
awk -v m="$pm" -v a="$pa" 'BEGIN { exit !(a > m) }' || fail "PSNR after the move does not rise: $pm -> $pa"
[[ $cov == 100 ]] || fail "coverage at 'all' is $cov, expected 100"
grep -q '^metric: insert_rate=' "$tmp/out" || fail "--time-insert printed no insert_rate"
grep -q '^metric: insert_runs=3$' "$tmp/out" || fail "--insert-runs 3 did not replay three times"

# bad input: exit 2 and one error line naming the problem
expect_error() {
  local lines
  lines=$(wc -l <"$tmp/err")
  ((lines == 1)) || fail "expected one error line, got $lines"
  grep -q "^error corrtex converge: .*$1" "$tmp/err" || fail "error line does not mention '$1'"
}
run_corrtex 2 converge "$scene" --out "$tmp/bad" --quiet
expect_error "--samples"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --camera nope --stand-in 0.3 --quiet
expect_error "nope"
run_corrtex 2 converge "$scene" --samples 100,50 --out "$tmp/bad" --quiet
expect_error "increase"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --eps abc --quiet
expect_error "--eps"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --insert-runs 0 --quiet
expect_error "--insert-runs"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --keep-projector-deg 91 --quiet
expect_error "--keep-projector-deg: '91' is not a number in \[0, 90\]"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --shown-rest-ms -1 --quiet
expect_error "--shown-rest-ms: '-1' is not a number in \[0, 60000\]"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --view-mem-mb -5 --quiet
expect_error "--view-mem-mb: '-5' is not a number in \[0, 1e+09\]"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --frobnicate 1 --quiet
expect_error "frobnicate"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --mode reuse-diffuse --glass-light refracted --quiet
expect_error 'glass light "refracted" is for path tracing and drt only (mode reuse-diffuse)'
# --reference-after is the moved camera's: without --move-to it was dropped
# without a word.
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --reference-after "$tmp/none.exr" --quiet
expect_error "--reference-after needs --move-to"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --aa 5 --quiet
expect_error "--aa: '5' is not an integer in \[1, 4\]"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --aa 0 --quiet
expect_error "--aa"
run_corrtex 2 converge "$tmp/missing.json" --samples 10 --out "$tmp/bad" --stand-in 0.3 --quiet
expect_error "missing.json"
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/bad" --stand-in 0.3 --width 32 --height 32 --reference "$tmp/ref.exr" --quiet
expect_error "48x48"
# Every input is checked before --out is made: a reference of another
# size left the folder behind (read in its phase, after the solve), a
# missing --reference-after the folder with the first phase's images.
[[ ! -e $tmp/bad ]] || fail "a refused run made its output folder $tmp/bad"
run_corrtex 2 converge "$scene" --camera front --samples 10 --width 48 --height 48 --stand-in 0.3 \
  --reference "$tmp/ref.exr" --move-to spheres --samples-after 10 --reference-after "$tmp/missing.exr" \
  --out "$tmp/after" --quiet
expect_error "$tmp/missing.exr"
[[ ! -e $tmp/after ]] || fail "a missing --reference-after: the output folder was made"
# An --out that is a file: found only when convergence.csv could not be
# made in it, after the solve.
echo notes >"$tmp/notes.txt"
run_corrtex 2 converge "$scene" --samples 10 --width 8 --height 8 --stand-in 0.3 --out "$tmp/notes.txt" --quiet
expect_error "--out $tmp/notes.txt: not a folder"
[[ $(cat "$tmp/notes.txt") == notes ]] || fail "--out a file changed it"

run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/both" --stand-in 0.3 --mesh "$tmp/m.ctmesh" --quiet
expect_error "not both"
[[ ! -e $tmp/both ]] || fail "--mesh with --stand-in: the output folder was made before the refusal"
# --record is written at the end: a missing folder is found before the run.
run_corrtex 2 converge "$scene" --samples 10 --out "$tmp/rec" --stand-in 0.3 --record "$tmp/no/dir/s.srec" --quiet
expect_error "--record $tmp/no/dir/s.srec: cannot create: its folder $tmp/no/dir does not exist"
[[ ! -e $tmp/rec && ! -e $tmp/no ]] || fail "--record in a missing folder: something was made"

# The real interactive solution: radiosity solved once into the cache, then
# loaded from it (the log says which).
run_corrtex 0 converge "$scene" --camera front --samples 200 --width 32 --height 32 --mesh "$tmp/m.ctmesh" --out "$tmp/rad1"
grep -q "written to" "$tmp/err" || fail "first --mesh run did not solve and write the cache"
[[ -s $tmp/m.ctmesh ]] || fail "no cache file written"
run_corrtex 0 converge "$scene" --camera front --samples 200 --width 32 --height 32 --mesh "$tmp/m.ctmesh" --out "$tmp/rad2"
grep -q "cached" "$tmp/err" || fail "second --mesh run did not use the cache"
cmp -s "$tmp/rad1/corrected_200.exr" "$tmp/rad2/corrected_200.exr" || fail "cached and solved runs differ"

# A --mesh file that holds another scene's mesh (or this one's before its
# meshes changed) is a cache all the same: solved over, with a warning
# naming it (it was an info line), and the run's images are those of the
# solved run above.
run_corrtex 0 radiosity "$root/tests/data/scenes/mini.json" -o "$tmp/other.ctmesh" --error 0.1 --min-area 0.1 --quiet
cp "$tmp/other.ctmesh" "$tmp/other.copy"
run_corrtex 0 converge "$scene" --camera front --samples 200 --width 32 --height 32 --mesh "$tmp/other.ctmesh" \
  --out "$tmp/rad3" --quiet
grep -q "warn.*other.ctmesh: the radiosity mesh of another scene, or of this one before its meshes changed (radiosity mesh has [0-9]* nodes, the scene [0-9]*): solving over it" "$tmp/err" ||
  fail "no warning naming another scene's mesh"
cmp -s "$tmp/other.ctmesh" "$tmp/other.copy" && fail "another scene's mesh was not solved over"
cmp -s "$tmp/rad1/corrected_200.exr" "$tmp/rad3/corrected_200.exr" || fail "the run over another scene's mesh differs from the solved run"

if ((fails)); then echo "converge e2e: $fails failure(s)"; exit 1; fi
echo "converge e2e: ok"
