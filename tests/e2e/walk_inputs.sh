#!/usr/bin/env bash
# corrtex-walk's inputs, checked without an MPI job: --path takes a path of
# the scene by name (one defined inline, by keys, too), written out for the
# display by `corrtex info --path`; a --reference folder of another frame
# count and a --radiosity-cache in a missing folder are refused before
# anything starts; --timeout covers the radiosity solve (a
# stand-in solver that never ends, so the test costs no CPU).
set -u
source "$(dirname "$0")/lib/walk-common.bash"
[[ -x $bin/corrtex ]] || { echo "error: $bin/corrtex not built"; exit 1; }
need_scene cornell

# corrtex info --path: the path in the path file format, and one line for
# a name the scene lacks or a combination it cannot print.
cmd=("$bin/corrtex" info "$scene" --path pan)
log_cmd "${cmd[@]}"
"${cmd[@]}" >"$tmp/pan.path" 2>"$tmp/err" || fail "corrtex info --path pan: exit $?: $(cat "$tmp/err")"
grep -q "^0  278 273 -800  278 273 0  39.2999992$" "$tmp/pan.path" || fail "pan.path lacks pan's first keyframe"
[[ $(grep -c '^[0-9]' "$tmp/pan.path") -eq 4 ]] || fail "pan.path has not pan's 4 keyframes"
for case in "nope|--path nope: $scene has no camera path of that name (its paths: walk, pan)" \
            "pan --json|--path prints a path file: not with --json"; do
  IFS='|' read -r args want <<<"$case"
  read -r -a a <<<"$args"
  log_cmd "$bin/corrtex" info "$scene" --path "${a[@]}"
  "$bin/corrtex" info "$scene" --path "${a[@]}" >/dev/null 2>"$tmp/err"; rc=$?
  sed 's/^/  stderr: /' "$tmp/err"
  ((rc == 2)) && [[ $(wc -l <"$tmp/err") -eq 1 ]] && grep -qF -- "$want" "$tmp/err" ||
    fail "corrtex info --path $args: exit $rc, want 2 and one line with '$want'"
done

common=(--listen "unix:$tmp/walk.sock" --radiosity-cache "$tmp/cache.ctmesh" --width 32 --height 32
        --ranks 2 --display local --backend egl)
# check WANT ARGS...: the launcher refuses with one error line holding WANT,
# exit 2, and starts nothing.
check() {
  local want=$1; shift
  log_cmd "$walk" "$@"
  "$walk" "$@" >"$tmp/out" 2>"$tmp/err"; local rc=$?
  sed 's/^/  stderr: /' "$tmp/err"
  ((rc == 2)) || fail "exit status $rc, want 2: $*"
  [[ $(wc -l <"$tmp/err") -eq 1 ]] || fail "want exactly one line on stderr: $*"
  grep -qF -- "$want" "$tmp/err" || fail "the message lacks '$want': $*"
  no_strays "$*"
}

# A path of the scene by name: it was looked up as a file and as
# SCENE_DIR/pan.path only ("neither a file nor ..."). The dry run shows the
# path written out beside the frames and handed to the display.
cmd=("$walk" cornell --path pan --out "$tmp/o1" --frames 3 "${common[@]}" --dry-run)
log_cmd "${cmd[@]}"
(cd "$root" && "${cmd[@]}") >"$tmp/dry" 2>"$tmp/err"; rc=$?
sed 's/^/  /' "$tmp/dry" "$tmp/err"
((rc == 0)) || fail "--path pan --dry-run: exit $rc"
grep -qE "/corrtex info $scene --path pan > $tmp/o1/pan.path\$" "$tmp/dry" || fail "the dry run does not write pan out"
grep -qE "/corrtex-display .* --path $tmp/o1/pan.path " "$tmp/dry" || fail "the display is not given pan.path"
[[ ! -e $tmp/o1 ]] || fail "the dry run created the output folder"
# a path file as before
cmd=("$walk" cornell --path "$tmp/pan.path" --frames 3 "${common[@]}" --dry-run)
log_cmd "${cmd[@]}"
(cd "$root" && "${cmd[@]}") >"$tmp/dry" 2>&1 || fail "--path FILE --dry-run: exit $?"
grep -qE "/corrtex-display .* --path $tmp/pan.path " "$tmp/dry" || fail "the display is not given the path file"
check "--path nope: not a path of cornell (its paths: walk, pan), nor a file, nor $root/scenes/cornell/nope.path" \
  cornell --path nope "${common[@]}"

# References of another frame count: refused before the radiosity solve
# (the display refuses them too, but only once the job has started).
mkdir -p "$tmp/ref"
for k in 0 1 2; do : >"$tmp/ref/$(printf 'frame_%05d.exr' "$k")"; done
check "--reference $tmp/ref: frame_00003.exr missing: 3 reference frames there, --frames 5 needs 5" \
  cornell --frames 5 --reference "$tmp/ref" --out "$tmp/o2" "${common[@]}"
check "--reference $tmp/ref: 3 reference frames there, made for --frames 3, not 2" \
  cornell --frames 2 --reference "$tmp/ref" --out "$tmp/o2" "${common[@]}"
[[ ! -e $tmp/o2 && ! -e $tmp/cache.ctmesh ]] || fail "refused references: the walk started"
cmd=("$walk" cornell --frames 3 --reference "$tmp/ref" --out "$tmp/o2" "${common[@]}" --dry-run)
log_cmd "${cmd[@]}"
"${cmd[@]}" >/dev/null 2>"$tmp/err" || fail "3 references for --frames 3: exit $?: $(cat "$tmp/err")"

# A cache file named on the command line is an output file: its folder must
# exist, as for the programs' output files (it was made, where corrtex
# radiosity refuses a missing one); the default cache's folder is made.
check "--radiosity-cache $tmp/no/dir/c.ctmesh: its folder $tmp/no/dir does not exist" \
  cornell --frames 2 --out "$tmp/o4" "${common[@]}" --radiosity-cache "$tmp/no/dir/c.ctmesh"
[[ ! -e $tmp/no && ! -e $tmp/o4 ]] || fail "a --radiosity-cache in a missing folder: something was made"

# --timeout during the radiosity solve: the clock used to start with the MPI
# job. A stand-in solver that never ends (named after $tmp, so a survivor
# is found as a stray); the other programs are never reached.
mkdir -p "$tmp/bin"
printf '#!/usr/bin/env bash\n[[ $1 == radiosity ]] && exec -a "$0 radiosity" sleep 300\nexec %q "$@"\n' \
  "$bin/corrtex" >"$tmp/bin/corrtex"
printf '#!/bin/sh\nexit 1\n' >"$tmp/bin/corrtex-render"
cp "$tmp/bin/corrtex-render" "$tmp/bin/corrtex-display"
chmod +x "$tmp/bin"/*
cmd=("$walk" cornell --frames 2 --out "$tmp/o3" "${common[@]}" --timeout 2)
log_cmd "${cmd[@]}"
t0=$(date +%s)
(cd "$root" && CORRTEX_BIN="$tmp/bin" MPIRUN=true "${cmd[@]}") >"$tmp/out" 2>"$tmp/err"; rc=$?
took=$(($(date +%s) - t0))
sed 's/^/  /' "$tmp/out" "$tmp/err"
((rc == 1)) || fail "--timeout 2 during the radiosity solve: exit $rc, want 1"
grep -q "error corrtex-walk: --timeout 2 s reached during the radiosity solve: stopping" "$tmp/err" ||
  fail "no line saying the timeout was reached during the radiosity solve"
grep -q "MPI job:" "$tmp/out" && fail "the MPI job was started after the timeout"
((took <= 8)) || fail "the launcher took $took s to stop at --timeout 2"
no_strays "after the timeout"

((fails == 0)) || { echo "$fails failure(s)"; exit 1; }
echo "ok: scene paths by name, reference counts and the timeout checked before and during the radiosity step"
