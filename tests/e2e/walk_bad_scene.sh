#!/usr/bin/env bash
# corrtex-walk with a broken scene: a missing file, an unknown scene name and
# a malformed scene file each give exactly one error line naming the
# problem, exit status 2, and start nothing (no process, no socket file); so
# do integer options out of range, also past what bash's arithmetic holds.
set -u
source "$(dirname "$0")/lib/walk-common.bash"
[[ -x $bin/corrtex ]] || { echo "error: $bin/corrtex not built"; exit 1; }
printf '{"meshes":[{"file":"ok.obj"}],\n "oops" }\n' >"$tmp/syntax.json"
printf '{"meshes":[{"file":"absent.obj"}]}\n' >"$tmp/nomesh.json"

check() {  # check WANT-IN-MESSAGE ARGS...: one error line containing WANT, exit 2
  local want=$1; shift
  log_cmd "$walk" "$@"
  "$walk" "$@" >"$tmp/out" 2>"$tmp/err"; local rc=$?
  sed 's/^/  stderr: /' "$tmp/err"; sed 's/^/  stdout: /' "$tmp/out"
  ((rc == 2)) || fail "exit status $rc, want 2: $*"
  [[ $(wc -l <"$tmp/err") -eq 1 ]] || fail "want exactly one line on stderr: $*"
  grep -q '^error corrtex-walk: ' "$tmp/err" || fail "the line does not start with 'error corrtex-walk: ': $*"
  grep -qF -- "$want" "$tmp/err" || fail "the message lacks '$want': $*"
  no_strays "$*"
  no_sockets "$*"
}
common=(--listen "unix:$tmp/walk.sock" --out "$tmp/out-dir" --radiosity-cache "$tmp/cache.ctmesh" --width 32 --height 32)
check "$tmp/missing/scene.json" "$tmp/missing/scene.json" "${common[@]}"
check "no_such_scene_xyz" no_such_scene_xyz "${common[@]}"
check "syntax.json:2:" "$tmp/syntax.json" "${common[@]}"
check "absent.obj" "$tmp/nomesh.json" "${common[@]}"
check "--ranks" "$root/tests/data/scenes/mini.json" --ranks 1 "${common[@]}"
check "--width: '100000' is not an integer in [1, 16384]" "$root/tests/data/scenes/mini.json" "${common[@]}" --width=100000
# past bash's 2^63 (it wrapped, passed, and the display refused it once the job ran)
check "--frames: '99999999999999999999' is not an integer in [0, 10000000]" "$root/tests/data/scenes/mini.json" \
  "${common[@]}" --frames 99999999999999999999
check "--samples-per-frame: '16777217' is not an integer in [0, 16777216]" "$root/tests/data/scenes/mini.json" \
  "${common[@]}" --samples-per-frame 16777217
check "--ranks: '08x' is not an integer" "$root/tests/data/scenes/mini.json" "${common[@]}" --ranks 08x
check "option --dry-run takes no value" "$root/tests/data/scenes/mini.json" "${common[@]}" --dry-run=1
[[ ! -e $tmp/out-dir ]] || fail "an output folder was created for a broken scene"
[[ ! -e $tmp/cache.ctmesh ]] || fail "a radiosity cache was written for a broken scene"
((fails == 0)) || { echo "$fails failure(s)"; exit 1; }
echo "ok: broken scenes give one clear line and start nothing"
