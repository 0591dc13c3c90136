#!/usr/bin/env bash
# corrtex-walk end to end on cornell at 64x64: computes the radiosity cache,
# starts the MPI job (1 master + 1 tracer) and a headless display over a UNIX
# socket, walks 4 lockstep frames of the camera path against references, and
# writes the report. Checks: exit 0, both programs started and ended, one
# frames.csv row and one PNG/EXR per frame, the samples per frame, report.md
# with its plots and contact sheet, and nothing left behind (processes,
# socket file); a second walk on a path defined inline in the scene; a path
# file the display refuses and an option the MPI job refuses both end the
# walk at once with status 2 and the reason.
set -u
source "$(dirname "$0")/lib/walk-common.bash"
need_programs
need_scene cornell
n=4; spf=200; w=64
out="$tmp/walk"; sock="$tmp/walk.sock"

# references for the error column (path tracing, 4 spp: the check is that
# the column exists and is finite, not its value)
cmd=("$bin/corrtex" reference "$scene" --path "$root/scenes/cornell/walk.path" --frames $n
     --width $w --height $w --spp 4 --mode path --threads 2 --quiet -o "$tmp/ref")
log_cmd "${cmd[@]}"; "${cmd[@]}" >/dev/null || { echo "FAIL: references"; exit 1; }

cmd=("$walk" cornell --path walk --frames $n --samples-per-frame $spf --width $w --height $w --ranks 2
     --listen "unix:$sock" --out "$out" --reference "$tmp/ref" --radiosity-cache "$tmp/cornell.ctmesh"
     --radiosity-options "$walk_rad_opts" --display local --backend egl --timeout 240)
log_cmd "${cmd[@]}"
(cd "$root" && env -u DISPLAY XDG_CACHE_HOME="$tmp/xdg" "${cmd[@]}") >"$tmp/walk.out" 2>&1; rc=$?
sed 's/^/  /' "$tmp/walk.out"
((rc == 0)) || fail "corrtex-walk exit status $rc"
no_strays "after the walk"
no_sockets "after the walk"
[[ -f $tmp/cornell.ctmesh ]] || fail "no radiosity cache written"
# the display kept the scene by its hash, indexed by the master's address
sc=("$tmp"/xdg/corrtex/*.ctscene)
[[ ${#sc[@]} -eq 1 && -s ${sc[0]} ]] || fail "want one cached scene, got: ${sc[*]}"
ix=("$tmp"/xdg/corrtex/addr-*.last)
[[ -s $tmp/xdg/corrtex/last && ${#ix[@]} -eq 1 && -s ${ix[0]} ]] || fail "no scene cache index files"
grep -q "radiosity: computing" "$tmp/walk.out" || fail "no line announcing the radiosity step"
grep -q "progress radiosity" "$tmp/walk.out" || fail "no progress line of the radiosity solver"
grep -q "MPI job: 2 ranks" "$tmp/walk.out" || fail "no line announcing the MPI job"
grep -q "display: headless" "$tmp/walk.out" || fail "no line announcing the headless display"
csv="$out/frames.csv"
if [[ -f $csv ]]; then
  rows=$(($(wc -l <"$csv") - 1))
  ((rows == n)) || fail "frames.csv has $rows rows, want $n"
  sc=$(head -n1 "$csv" | tr ',' '\n' | grep -n '^samples$' | cut -d: -f1)
  rc_=$(head -n1 "$csv" | tr ',' '\n' | grep -n '^rmse$' | cut -d: -f1)
  [[ -n $sc && -n $rc_ ]] || fail "frames.csv lacks the samples or rmse column: $(head -n1 "$csv")"
  if [[ -n $sc ]]; then
    bad=$(awk -F, -v c="$sc" -v k=$spf 'NR > 1 && $c != k' "$csv")
    [[ -z $bad ]] || fail "frames with other than $spf samples (lockstep): $bad"
  fi
  if [[ -n $rc_ ]]; then
    awk -F, -v c="$rc_" 'NR > 1 { printf "metric: frame %d rmse %s\n", NR - 2, $c }' "$csv"
    awk -F, -v c="$rc_" 'NR > 1 && !($c + 0 >= 0 && $c + 0 < 100) { exit 1 }' "$csv" || fail "rmse not finite"
  fi
else
  fail "no $csv"
fi
for ((k = 0; k < n; k++)); do
  f=$(printf '%s/frame_%05d' "$out" $k)
  [[ -s $f.png && -s $f.exr ]] || fail "missing $f.png or $f.exr"
done
for f in report.md run.env render.log display.log contact.png error.png; do
  [[ -s $out/$f ]] || fail "missing $out/$f"
done
grep -q "report written to $out/report.md" "$tmp/walk.out" || fail "the report's place is not printed"
if [[ -f $out/report.md ]]; then
  for want in "## Settings" "## Results" "samples/s" "frames/s" "![error](error.png)" "contact.png" "mpirun -np 2"; do
    grep -qF -- "$want" "$out/report.md" || fail "report.md lacks '$want'"
  done
  grep -q '^| radiosity_s | [0-9.]* |$' "$out/report.md" || fail "report.md lacks the radiosity's seconds: $(grep radiosity_s "$out/report.md")"
fi
# Again with the cache current: the report says so instead of a bare 0.0 s.
# The path is pan, defined inline in cornell.json (keys, no file): the
# launcher used to refuse it ("neither a file nor .../pan.path"); it writes
# it out beside the frames for the display, which has no scene file.
out2="$tmp/walk2"
cmd=("$walk" cornell --path pan --frames 2 --samples-per-frame $spf --width $w --height $w --ranks 2
     --listen "unix:$sock" --out "$out2" --radiosity-cache "$tmp/cornell.ctmesh"
     --radiosity-options "$walk_rad_opts" --display local --backend egl --timeout 240)
log_cmd "${cmd[@]}"
(cd "$root" && env -u DISPLAY XDG_CACHE_HOME="$tmp/xdg" "${cmd[@]}") >"$tmp/walk2.out" 2>&1 || fail "second walk (cache current): exit status $?"
grep -q "radiosity: checking the cache" "$tmp/walk2.out" || fail "the second walk did not announce the cache check"
[[ -s $out2/pan.path ]] && cmp -s "$out2/pan.path" <("$bin/corrtex" info "$scene" --path pan) ||
  fail "the path pan of the scene was not written to $out2/pan.path"
grep -q -- "--path $out2/pan.path" "$out2/run.env" 2>/dev/null || fail "the display was not given $out2/pan.path"
grep -q '^| radiosity_s | [0-9.]* (the cache was up to date) |$' "$out2/report.md" 2>/dev/null ||
  fail "the second report does not say the cache was up to date: $(grep radiosity_s "$out2/report.md" 2>/dev/null)"
no_strays "after the second walk"
# A path file the display refuses (a word where the fov goes): the launcher
# says so at once and exits 2; it used to wait 15 s for the job and report
# the job's end before the display's reason.
printf '0 278 273 -800 278 273 0 39.3\n1 278 273 -700 278 273 0 abc\n' >"$tmp/bad.path"
cmd=("$walk" cornell --path "$tmp/bad.path" --frames 2 --samples-per-frame $spf --width $w --height $w --ranks 2
     --listen "unix:$sock" --out "$tmp/walk3" --radiosity-cache "$tmp/cornell.ctmesh"
     --radiosity-options "$walk_rad_opts" --display local --backend egl --timeout 240)
log_cmd "${cmd[@]}"
t0=$(date +%s)
(cd "$root" && env -u DISPLAY XDG_CACHE_HOME="$tmp/xdg" "${cmd[@]}") >"$tmp/walk3.out" 2>&1; rc=$?
sed 's/^/  walk3: /' "$tmp/walk3.out" | tail -n 6
((rc == 2)) || fail "a path file the display refuses: exit status $rc, want 2"
grep -q "the display refused its input: error .*bad.path:2: expected 't ex ey ez tx ty tz \[fov\]'" "$tmp/walk3.out" ||
  fail "the launcher did not name the display's reason"
(($(date +%s) - t0 < 15)) || fail "the launcher took $(($(date +%s) - t0)) s to give up"
no_strays "after the refused path"
# An option the MPI job refuses, passed through: exit 2 with the job's line
# (mpirun passes its status 2 on; the launcher used to call it a failure, 1).
cmd=("$walk" cornell --frames 2 --samples-per-frame $spf --width $w --height $w --ranks 2
     --listen "unix:$sock" --out "$tmp/walk4" --radiosity-cache "$tmp/cornell.ctmesh"
     --radiosity-options "$walk_rad_opts" --display local --backend egl --timeout 240 --render-options "--bogus")
log_cmd "${cmd[@]}"
(cd "$root" && env -u DISPLAY XDG_CACHE_HOME="$tmp/xdg" "${cmd[@]}") >"$tmp/walk4.out" 2>&1; rc=$?
sed 's/^/  walk4: /' "$tmp/walk4.out" | tail -n 4
((rc == 2)) || fail "an option the job refuses: exit status $rc, want 2"
grep -q "the MPI job refused its input: error corrtex-render: unknown option '--bogus'" "$tmp/walk4.out" ||
  fail "the launcher did not name the job's reason"
no_strays "after the refused option"
# An option the radiosity solver refuses, and a cache path that is not a
# .ctmesh (a document: corrtex radiosity used to replace it): exit 2 with
# the solver's line, before any MPI job (both exited 1).
echo "notes" >"$tmp/notes.txt"
for case in "--radiosity-options --bogus|unknown option '--bogus'" \
            "--radiosity-cache $tmp/notes.txt|notes.txt: exists and is not a corrtex mesh"; do
  IFS='|' read -r opts want <<<"$case"
  read -r o1 o2 <<<"$opts"
  cmd=("$walk" cornell --frames 2 --samples-per-frame $spf --width $w --height $w --ranks 2
       --listen "unix:$sock" --out "$tmp/walk5" --radiosity-cache "$tmp/cornell.ctmesh"
       --radiosity-options "$walk_rad_opts" --display local --backend egl --timeout 240 "$o1" "$o2")
  log_cmd "${cmd[@]}"
  (cd "$root" && env -u DISPLAY XDG_CACHE_HOME="$tmp/xdg" "${cmd[@]}") >"$tmp/walk5.out" 2>&1; rc=$?
  sed 's/^/  walk5: /' "$tmp/walk5.out" | tail -n 3
  ((rc == 2)) || fail "$o1 $o2: exit status $rc, want 2"
  grep -q "error corrtex radiosity: .*$want" "$tmp/walk5.out" || fail "$o1 $o2: the solver's line is missing"
done
[[ $(cat "$tmp/notes.txt") == notes ]] || fail "the launcher's radiosity replaced a document"
no_strays "after the refused solver input"
((fails == 0)) || { echo "$fails failure(s)"; exit 1; }
echo "ok: walk of $n frames with report; nothing left behind"
