#!/usr/bin/env bash
# Lockstep frames do not depend on the number of tracer ranks: the same
# 5 frames of cornell's walk path (K samples per frame) with one tracer
# (mpirun -np 2) and with two (mpirun -np 3) must give bit-identical EXR
# frames, because every sample's randomness is a function of its request and
# each fixed-size round is inserted in request-id order. The single tracer
# uses two threads (--threads 2), so the split of a batch over threads is
# covered too.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
K=1000
for np in 2 3; do
  threads=$((np == 2 ? 2 : 1))
  master_start "job$np" $np "${CORNELL[@]}" --listen "unix:$tmp/r$np.sock" --exit-when-display-leaves --threads $threads
  master_wait_listen "job$np" || finish
  display_run "display$np" --connect "$ADDR" "${HEADLESS[@]}" --samples-per-frame $K \
    --path "$root/scenes/cornell/walk.path" --frames 5 --out "$tmp/out$np"
  ((DISPLAY_RC == 0)) || fail "display (np $np) exit status $DISPLAY_RC"
  master_wait "job$np" 20 || fail "job np $np did not end"
  ((MASTER_RC == 0)) || { fail "job np $np exit status $MASTER_RC"; master_log "job$np" | tail -n 20; }
done
same_frames out2 out3 "between 1 and 2 tracers"
# Not a trivially equal pair: the frames change along the path.
cmp -s "$tmp/out2/frame_00000.exr" "$tmp/out2/frame_00004.exr" && fail "frames 0 and 4 are identical"
echo "metric: $same of 5 lockstep frames bit-identical with 1 tracer (2 threads) and 2 tracers (1 thread)"
finish
