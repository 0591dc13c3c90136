#!/usr/bin/env bash
# The whole pipeline against the truth, region by region: mpirun with one
# tracer rank, the master and a headless display on the three diffuse
# scenes of tests/data/radiosity (the Cornell box with every material
# diffuse, a closed room lit by a small quad light, an L-shaped room with an
# occluder), a still camera left until the master has refined every pixel
# it will and gone idle; the display's last frame (radiosity + corrections,
# as drawn) is compared with the committed path-traced reference (32768
# samples per pixel) in 4 x 4 pixel blocks on one flat surface a pixel away
# from its edges and without a shadow boundary (the masks of
# tests/e2e/radiosity_regions.sh), and the blocks' rms must be within 3 %.
# Worst-block bounds: the room 5 % (measured 1.3-2.1 %), the L room 7 %
# (2.3-3.3 %), the Cornell box 10 % (2.0-3.9 %; 5.0 % under the sanitizers,
# the top row of the short box's front face, where drt itself is up to 5 %
# bright) over eight runs of 2026-11-28; the refined means move a block by
# about 2 % from run to run (free running, the samples arrive in a
# different order). Since radiosity solver version 16 (2026-11-29, 13 runs:
# 2.9-8.4 %, median 4.4 %; one over the old 8 % bound) the worst block is
# nearly always on the short box's dark front face and usually too dark,
# while the radiosity alone is within 2 % there. That is noise, not a bias:
# over 8 runs of this pipeline the face's blocks average 0.990-1.012 of the
# reference, its mean 1.0005; about half of drt's samples there are 0, and
# the mean of such skewed samples falls short more often than it overshoots
# (docs/sampling.md "Refinement"). Before a pixel's
# variance was shrunk towards its neighbours' (master/rq_refine.c), one
# pixel in 16 of the short box's dark front face, whose drt samples are 0
# about half of the time, stopped after four zeros at a third of the truth:
# Cornell's worst block was 2.7-7.3 % in ten runs and 12.5 % in one that
# failed CI's 10 % bound. While the gather read the lamps' light where its
# rays land from the mesh, whose shadows are blurred, the same face
# converged 10 % too bright (docs/tracer.md, "Indirect light"). Before
# refinement weighed a pixel's uncertainty as displayed (sRGB), it kept one
# sample's noise: 20 % off in its worst block. The references' noise is
# 0.1-1.2 % (docs/radiosity.md). The radiosity alone is printed beside.
# Every block's ratio is printed.
source "$(dirname "$0")/lib/mpi.sh"
need_programs "$corrtex"
data="$root/tests/data/radiosity"
[[ -f $root/scenes/cornell/cornell.obj ]] || { fail "missing scenes/cornell meshes (run make scenes)"; finish; }
# run_ct ARGS...: corrtex ARGS, its stdout in $out; a failure ends the test.
run_ct() {
  log_cmd "$corrtex" "$@"
  out=$("$corrtex" "$@" 2>"$tmp/ct.err") || { fail "corrtex $1 failed: $(tail -n 3 "$tmp/ct.err")"; finish; }
}
img=(--width 64 --height 64 --spp 16 --quiet)
for sc_bound in cornell_diffuse:0.10 boxroom:0.05 lroom:0.07; do
  sc=${sc_bound%:*} bound=${sc_bound#*:} scene="$data/${sc_bound%:*}.json" ref="$data/${sc_bound%:*}-ref.exr"
  echo "== $sc"
  [[ -f $ref ]] || { fail "missing $ref"; continue; }
  run_ct radiosity "$scene" -o "$tmp/$sc.ctmesh" --image-planes "$tmp/$sc-planes.exr" --image "$tmp/$sc-rad.exr" "${img[@]}"
  run_ct radiosity "$scene" -o "$tmp/$sc.ctmesh" --reuse --image "$tmp/$sc-direct.exr" --image-direct "${img[@]}"
  master_start "$sc" 2 "$scene" --mesh "$tmp/$sc.ctmesh" --listen "unix:$tmp/$sc.sock" --stats-s 0.25
  master_wait_listen "$sc" || finish
  display_start "$sc-still" --connect "$ADDR" "${HEADLESS[@]}" --out "$tmp/$sc-still" --out-every 0.5
  # Idle: refinement started, then a stats line with nothing sampled.
  idle=0
  for ((i = 0; i < 1200; i++)); do
    if grep '(refining:' "$tmp/$sc.log" | tail -n 1 | grep -q ' 0 samples/s'; then
      idle=1
      break
    fi
    kill -0 "$DISPLAY_PID" 2>/dev/null || break
    sleep 0.1
  done
  sleep 1   # the last texels to the screen, and a capture of them
  echo "+ kill -TERM <display>"
  kill -TERM "$DISPLAY_PID" 2>/dev/null
  wait "$DISPLAY_PID"; rc=$?
  sed 's/^/  still: /' "$tmp/$sc-still.log" | tail -n 4
  grep '(refining:' "$tmp/$sc.log" | tail -n 1 | sed 's/^/  master: /'
  master_term "$sc"
  ((idle)) || fail "$sc: the master did not go idle within 120 s"
  ((rc == 0)) || fail "$sc: the display ended with status $rc after SIGTERM (want 0)"
  last=$(ls "$tmp/$sc-still"/frame_*.exr 2>/dev/null | tail -n 1)
  [[ -n $last ]] || { fail "$sc: the display wrote no frame"; continue; }
  masks=(--regions 4 --planes "$tmp/$sc-planes.exr" --planes-margin 1 --flat "$tmp/$sc-direct.exr" --flat-ratio 1.5)
  run_ct compare "$last" "$ref" "${masks[@]}" --region-table
  sed 's/^/  /' <<<"$out"
  n=$(awk '$1 == "regions" { print $2 }' <<<"$out")
  worst=$(awk '$1 == "region_worst" { print $2 }' <<<"$out")
  rms=$(awk '$1 == "region_rms" { print $2 }' <<<"$out")
  run_ct compare "$tmp/$sc-rad.exr" "$ref" "${masks[@]}"
  rworst=$(awk '$1 == "region_worst" { print $2 }' <<<"$out")
  rrms=$(awk '$1 == "region_rms" { print $2 }' <<<"$out")
  echo "metric: ${sc}_regions=$n ${sc}_corrected_worst=$worst ${sc}_corrected_rms=$rms (bounds $bound, 0.03);" \
    "radiosity alone worst=$rworst rms=$rrms"
  ((n >= 40)) || fail "$sc: only $n regions counted (the masks left too little to test)"
  awk -v w="$worst" -v b="$bound" 'BEGIN { exit !(w <= b) }' ||
    fail "$sc: a region of the corrected image is off by $worst (more than $bound)"
  awk -v r="$rms" 'BEGIN { exit !(r <= 0.03) }' || fail "$sc: the corrected regions' rms error is $rms (more than 0.03)"
done
finish
