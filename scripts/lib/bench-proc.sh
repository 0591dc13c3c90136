# scripts/lib/bench-proc.sh: what the live benchmarks (bench-interactive,
# bench-walk, bench-refine, bench-camera-rate) read about a scene, a process
# and the programs' logs (sourced, not run).
#   scene_camera JSON    the name of the scene's first camera
#   cpu_ticks PID...     user + system clock ticks of the processes (all
#                        threads); fails when one is gone
#   tracer_rate LOG      the samples/s of a `corrtex reference` log (its
#                        summary line "..., N samples/s; ..."); empty if none
#   display_lag LOG      "median / p99" ms of the last lag line of a
#                        corrtex-display log; empty if none
scene_camera() {
  sed -n 's/.*"name": *"\([^"]*\)", *"eye".*/\1/p' "$1" | head -n 1
}
cpu_ticks() {
  local p sum=0 t
  for p in "$@"; do
    t=$(awk '{ print $14 + $15 }' "/proc/$p/stat" 2>/dev/null) || return 1
    sum=$((sum + t))
  done
  echo "$sum"
}
tracer_rate() {
  sed -n 's/.* \([0-9][0-9]*\) samples\/s.*/\1/p' "$1" | head -n 1
}
display_lag() {
  sed -n 's/.*median \([0-9]*\) ms, p90 [0-9]* ms, p99 \([0-9]*\) ms.*/\1 \/ \2/p' "$1" | tail -n 1
}
