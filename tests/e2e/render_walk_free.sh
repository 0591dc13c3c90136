#!/usr/bin/env bash
# A free-running walk reaches the textures: a display walks a 4 s path into
# the Cornell box at 256x256 (one tracer rank) while the master streams
# corrections; samples traced for a view the camera already left must not
# be most of what the tracer traced. Before the walk work (textures keeping
# their projector, the shown-node map waiting for a resting camera, tracers
# answering between slices of a batch, samples taken in before a camera)
# most samples of such a walk came back stale: this test's walk with the
# programs of that commit ended at 122,880 inserted against 565,296 stale;
# on table and office at 1024x1024 every or nearly every sample
# (docs/benchmarks.md, "Walk (free running)").
# Checks: samples went in while walking, stale samples (dropped) are under
# half of those traced, and some views were set quickly (the stats line's
# view time over its view count).
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
path=$(slow_path)
master_start job 2 "${CORNELL[@]}" --listen "unix:$tmp/r.sock" --stats-s 0.25
master_wait_listen job 120 || finish
display_run walk --connect "$ADDR" --backend egl --width 256 --height 256 --quiet --path "$path" --hold 0 \
  --no-images --out "$tmp/walk"
((DISPLAY_RC == 0)) || fail "display exit status $DISPLAY_RC"
sleep 0.5
line=$(grep 'stats:' "$tmp/job.log" | tail -n 1)
kill -TERM "$(rank_pid job 0)"
master_wait job 20 || fail "the job did not end"
((MASTER_RC == 0)) || fail "job exit status $MASTER_RC"
read -r ins late stale views ms <<<"$(sed -n 's/.*total \([0-9]*\) ([0-9]* without texture, \([0-9]*\) late), \([0-9]*\) stale.* views \([0-9]*\) (\([0-9.]*\) ms in all.*/\1 \2 \3 \4 \5/p' <<<"$line")"
[[ -n ${ins:-} ]] || { fail "no stats line with totals: $line"; finish; }
echo "metric: walk 4 s at 256x256: inserted $ins (late $late), stale $stale, $views views in $ms ms"
((ins > 0)) || fail "nothing went into the textures while walking"
((2 * stale < ins + stale)) || fail "$stale of $((ins + stale)) samples traced were stale"
((views >= 2)) || fail "the walk set $views views"
finish
