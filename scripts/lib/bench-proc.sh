# scripts/lib/bench-proc.sh: what the live benchmarks (bench-interactive,
# bench-walk, bench-refine) read about a scene and a process (sourced, not
# run).
#   scene_camera JSON    the name of the scene's first camera
#   cpu_ticks PID...     user + system clock ticks of the processes (all
#                        threads); fails when one is gone
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
