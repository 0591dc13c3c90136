#!/usr/bin/env bash
# Lockstep frames depend neither on the number of tracer ranks nor on the
# number of master threads: the same 5 frames of cornell's walk path
# (K samples per frame) with one tracer (mpirun -np 2) and with two
# (mpirun -np 3), each with one and with two master threads
# (--master-threads), must give bit-identical EXR frames: every sample's
# randomness is a function of its request, each fixed-size round is inserted
# in request-id order, and the master's threads split the insertion by
# texture, each texture's samples in that order. The single tracer uses two
# threads (--threads 2), so the split of a batch over threads is covered too.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
K=1000
for np in 2 3; do
  for mt in 1 2; do
    job=np${np}_mt$mt
    threads=$((np == 2 ? 2 : 1))
    master_start "$job" $np "${CORNELL[@]}" --listen "unix:$tmp/$job.sock" --exit-when-display-leaves \
      --threads $threads --master-threads $mt
    master_wait_listen "$job" || finish
    grep -q "$mt master thread" "$tmp/$job.log" || fail "$job: the master does not say it runs $mt thread(s)"
    display_run "display_$job" --connect "$ADDR" "${HEADLESS[@]}" --samples-per-frame $K \
      --path "$root/scenes/cornell/walk.path" --frames 5 --out "$tmp/out_$job"
    ((DISPLAY_RC == 0)) || fail "display ($job) exit status $DISPLAY_RC"
    master_wait "$job" 20 || fail "job $job did not end"
    ((MASTER_RC == 0)) || { fail "job $job exit status $MASTER_RC"; master_log "$job" | tail -n 20; }
  done
done
total=0
for other in np2_mt2 np3_mt1 np3_mt2; do
  same_frames out_np2_mt1 "out_$other" "between 1 tracer, 1 master thread and ${other/_/, }"
  total=$((total + same))
done
# Not a trivially equal pair: the frames change along the path.
cmp -s "$tmp/out_np2_mt1/frame_00000.exr" "$tmp/out_np2_mt1/frame_00004.exr" && fail "frames 0 and 4 are identical"
echo "metric: $total of 15 lockstep frames bit-identical to 1 tracer (2 threads), 1 master thread: with 2 master threads, 2 tracers (1 thread each), and both"
# Rounds of three chunks, each popped ahead of the last one's reports
# (--pop-ahead): a chunk's report and the pops run beside the next chunk's
# splats on two master threads; the frames stay the same for 1 tracer and
# 1 master thread and for 2 tracers and 2 master threads.
for job in ahead_np2_mt1 ahead_np3_mt2; do
  np=${job#ahead_np}; np=${np%%_*}; mt=${job##*_mt}
  master_start "$job" "$np" "${CORNELL[@]}" --listen "unix:$tmp/$job.sock" --exit-when-display-leaves \
    --threads 1 --master-threads "$mt" --round 3000 --pop-ahead
  master_wait_listen "$job" || finish
  display_run "display_$job" --connect "$ADDR" "${HEADLESS[@]}" --samples-per-frame 3000 \
    --path "$root/scenes/cornell/walk.path" --frames 5 --out "$tmp/out_$job"
  ((DISPLAY_RC == 0)) || fail "display ($job) exit status $DISPLAY_RC"
  master_wait "$job" 20 || fail "job $job did not end"
  ((MASTER_RC == 0)) || { fail "job $job exit status $MASTER_RC"; master_log "$job" | tail -n 20; }
done
same_frames out_ahead_np2_mt1 out_ahead_np3_mt2 "popped ahead: between 1 tracer, 1 master thread and 2 tracers, 2 master threads"
echo "metric: popped ahead, rounds of 3000: $same of 5 frames bit-identical for 1 tracer, 1 master thread and 2 tracers, 2 master threads"
finish
