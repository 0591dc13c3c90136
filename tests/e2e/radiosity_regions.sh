#!/usr/bin/env bash
# The radiosity solution, region by region, against path-traced references
# of three diffuse scenes (tests/data/radiosity/): the Cornell box with every
# material diffuse (camera front), a closed room lit by a small one-sided
# quad light 1 mm under its ceiling, and an L-shaped room with a box between
# its light and the corner (the far arm lit only indirectly). The solution
# at the default settings, drawn as the display draws it (64 x 64, 64
# samples per pixel, so edges are as converged as the reference's), is
# compared with the reference in 4 x 4 pixel blocks: every block on one flat
# surface and a pixel away from its edges (--planes, --planes-margin; the
# contact shadows at the edges are docs/radiosity.md's separate table), and
# without a shadow boundary (--flat: the direct light varies over it by at
# most half the block's mean), must be within 5 % of the reference, and
# the blocks' rms within 5 % too. The L room's worst block (the floor in
# the occluding box's shadow, lit only past the box: its vertices' sampled
# visibility) was 4-7 % over seeds 1-3 in version 11, 4-5.7 % up to
# version 15, and held to 7 % until solver version 16 (vertices look at
# links whose rays were all blocked) met 5 % for every seed: 4.7 / 3.8 /
# 4.7 % (docs/radiosity.md, Accuracy; the solver before this test had 43 %,
# solver version 8 18.4 %, version 10 10.7 %, its far arm's end wall too
# bright along its edges, which dim receivers refined further took to 4 %
# in version 11).
#
# The references are committed (scripts/make-radiosity-refs renders them:
# 32768 samples per pixel, path tracing; regenerating takes minutes per
# scene, far too long for the suite). Their noise, measured there as the
# region means of two seeds against each other (all blocks, no masks): the
# Cornell box worst 1.73 % rms 0.32 %, the room worst 0.37 % rms 0.12 %, the
# L room worst 1.69 % rms 0.40 % -- a reference's own noise is that over
# sqrt(2), a small fraction of the 5 % bound. Every block's ratio is printed
# (--region-table).
source "$(dirname "$0")/lib/common.sh"
data="$root/tests/data/radiosity"
[[ -f $root/scenes/cornell/cornell.obj ]] || { echo "missing scenes/cornell meshes (run make scenes)"; exit 1; }
run_tail=40
for sc_bound in cornell_diffuse:0.05 boxroom:0.05 lroom:0.05; do
  sc=${sc_bound%:*} bound=${sc_bound#*:}
  echo "== $sc"
  [[ -f $data/$sc-ref.exr ]] || { fail "missing $data/$sc-ref.exr (scripts/make-radiosity-refs)"; continue; }
  opts=(--width 64 --height 64 --spp 64 --quiet)
  run_corrtex 0 radiosity "$data/$sc.json" -o "$tmp/$sc.ctmesh" --image "$tmp/$sc.exr" --image-planes "$tmp/$sc-planes.exr" "${opts[@]}"
  run_corrtex 0 radiosity "$data/$sc.json" -o "$tmp/$sc.ctmesh" --reuse --image "$tmp/$sc-direct.exr" --image-direct "${opts[@]}"
  run_corrtex 0 compare "$tmp/$sc.exr" "$data/$sc-ref.exr" --regions 4 --planes "$tmp/$sc-planes.exr" --planes-margin 1 \
      --flat "$tmp/$sc-direct.exr" --flat-ratio 1.5 --region-table
  n=$(awk '$1 == "regions" { print $2 }' <<<"$out")
  worst=$(awk '$1 == "region_worst" { print $2 }' <<<"$out")
  rms=$(awk '$1 == "region_rms" { print $2 }' <<<"$out")
  echo "metric: ${sc}_regions=$n ${sc}_region_worst=$worst ${sc}_region_rms=$rms (bounds: worst $bound, rms 0.05)"
  ((n >= 40)) || fail "$sc: only $n regions counted (the masks left too little to test)"
  awk -v w="$worst" -v b="$bound" 'BEGIN { exit !(w <= b) }' || fail "$sc: a region mean is off by $worst (more than $bound)"
  awk -v r="$rms" 'BEGIN { exit !(r <= 0.05) }' || fail "$sc: the region means' rms error is $rms (more than 0.05)"
done
# Where the Cornell box's floor sphere stands (every block, no masks): the
# 4 x 4 block at column 4, row 14 holds its lowest rim and the floor in its
# contact shadow. The floor leaves there inherited their ancestors' links
# with the visible share their ancestors saw, and the sphere's lowest
# vertices gathered from them: the block is 1.62-1.74 times the reference
# over seeds 1-4 with the links' values (the default, --gather-passes 0),
# and 1.25-1.30 after two steps of the final gather at the leaves
# (docs/radiosity.md, "Where a curved object touches a surface"). Checked:
# with two steps at most 1.45; by default at least 1.45, so that a change
# of the default or of the solver's contact light shows here.
echo "== cornell_diffuse: the floor sphere's foot"
sc=cornell_diffuse
foot_ratio() {  # IMAGE: the block's ratio to the reference, into $foot
  run_corrtex 0 compare "$1" "$data/$sc-ref.exr" --regions 4 --region-table
  foot=$(grep -E '^ +[0-9. ]+$' <<<"$out" | awk 'NR == 15 { print $5 }')
}
# Past the floor sphere's terminator (where its shading normals turn away
# from the lamp while its facets' planes still face it): the 4 x 4 block at
# column 5, row 12. Gouraud shading ramps from the last lit vertex to the
# first unlit one, and with leaves as large as the planes' error allowed
# the ramp reached far into the dark side: 1.13 times the reference (1.13
# over seeds 1-4). Receivers split along the terminator (solver version
# 26, radiosity/rad_ff.c rad_ff_elem): 1.02-1.04 over seeds 1-4. At most 1.07.
echo "== cornell_diffuse: past the floor sphere's terminator"
sc=cornell_diffuse
if [[ -f $tmp/$sc.exr && -f $data/$sc-ref.exr ]]; then
  run_corrtex 0 compare "$tmp/$sc.exr" "$data/$sc-ref.exr" --regions 4 --region-table
  term=$(grep -E '^ +[0-9. ]+$' <<<"$out" | awk 'NR == 13 { print $6 }')
  echo "metric: cornell_diffuse_terminator_ratio=$term (bounds 0.93-1.07)"
  [[ $term =~ ^[0-9.]+$ ]] || fail "$sc: no block at column 5, row 12 in the region table"
  awk -v f="$term" 'BEGIN { exit !(f <= 1.07 && f >= 0.93) }' ||
    fail "$sc: past the floor sphere's terminator the block is $term times the reference (bounds 0.93-1.07)"
fi
if [[ -f $tmp/$sc.exr && -f $data/$sc-ref.exr ]]; then
  run_corrtex 0 radiosity "$data/$sc.json" -o "$tmp/$sc-g2.ctmesh" --gather-passes 2 --image "$tmp/$sc-g2.exr" \
      --width 64 --height 64 --spp 64 --quiet
  foot_ratio "$tmp/$sc.exr"; foot0=$foot
  foot_ratio "$tmp/$sc-g2.exr"; foot2=$foot
  echo "metric: cornell_diffuse_sphere_foot_ratio default=$foot0 gather_passes_2=$foot2 (bound 1.45)"
  [[ $foot0 =~ ^[0-9.]+$ && $foot2 =~ ^[0-9.]+$ ]] || fail "$sc: no block at column 4, row 14 in the region table"
  awk -v f="$foot2" 'BEGIN { exit !(f <= 1.45 && f >= 0.7) }' ||
    fail "$sc: with --gather-passes 2 the block at the floor sphere's foot is $foot2 times the reference (bounds 0.7-1.45)"
  awk -v f="$foot0" 'BEGIN { exit !(f > 1.45) }' ||
    fail "$sc: by default the block at the floor sphere's foot is $foot0 times the reference, no longer over 1.45: update this test and docs/radiosity.md"
fi
# The L room's box foot from 40 cm (lroom_foot.json, same room): the
# floor in the box's shadow, lit only past it, and the line where the box
# stands, as a walkthrough sees them up close. Every block counts (no
# masks). Solver version 11 was 15-20 % off in its worst block and 4.6-6.0 %
# rms over seeds 1-3: blotches of the vertices' sampled visibility in the
# shadow, and floor corners hidden under the box darkening the elements
# that reach out from under it; version 12 (more single rays where the
# partly hidden light is a large share, hidden corners given the light at
# the contact line) 8.5-11.2 % and 2.7-4.1 %, version 13 8.3-11.4 % and
# 2.7-4.6 %, version 16 (links whose rays were all blocked looked at too)
# 6.7-9.2 % and 2.1-3.5 % (bounds 10 % and 4 %). Reference noise: two seeds
# of it differ by 1.5 % at worst, 0.49 % rms (32768 spp).
echo "== lroom_foot"
sc=lroom_foot
if [[ -f $data/$sc-ref.exr ]]; then
  run_corrtex 0 radiosity "$data/$sc.json" -o "$tmp/$sc.ctmesh" --image "$tmp/$sc.exr" --width 64 --height 64 --spp 64 --quiet
  run_corrtex 0 compare "$tmp/$sc.exr" "$data/$sc-ref.exr" --regions 4 --region-table
  worst=$(awk '$1 == "region_worst" { print $2 }' <<<"$out")
  rms=$(awk '$1 == "region_rms" { print $2 }' <<<"$out")
  echo "metric: ${sc}_region_worst=$worst ${sc}_region_rms=$rms (bounds: worst 0.10, rms 0.04)"
  awk -v w="$worst" 'BEGIN { exit !(w <= 0.10) }' || fail "$sc: a region mean is off by $worst (more than 0.10)"
  awk -v r="$rms" 'BEGIN { exit !(r <= 0.04) }' || fail "$sc: the region means' rms error is $rms (more than 0.04)"
else
  fail "missing $data/$sc-ref.exr (scripts/make-radiosity-refs)"
fi
exit $((fails > 0))
