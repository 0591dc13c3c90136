#!/usr/bin/env bash
# corrtex info on good and broken scenes: exit 0 / 2, and for each broken one
# exactly one error line on stderr that names the offending file.
set -u
BIN=${CORRTEX_BIN:-bin}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail=0
run() { echo "+ $*"; "$@"; }

run "$BIN/corrtex" info tests/data/scenes/mini.json --json >"$tmp/out.json" 2>"$tmp/err" || { echo "mini failed"; cat "$tmp/err"; exit 1; }
for key in nodes primitives triangles materials emitters cameras paths bounds; do
  grep -q "\"$key\"" "$tmp/out.json" || { echo "missing key $key in --json output"; fail=1; }
done

printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > "$tmp/ok.obj"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n' > "$tmp/range.obj"
printf 'v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n' > "$tmp/nan.obj"
printf 'v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n' > "$tmp/degen.obj"
printf '{"meshes":[{"file":"ok.obj"}],\n "oops" }\n' > "$tmp/syntax.json"
printf '{"meshes":[{"file":"range.obj"}]}' > "$tmp/range.json"
printf '{"meshes":[{"file":"nan.obj"}]}' > "$tmp/nan.json"
printf '{"meshes":[{"file":"degen.obj"}]}' > "$tmp/degen.json"
printf '{"meshes":[{"file":"ok.obj"}],"materials":{"m":{"shiny":1}}}' > "$tmp/key.json"
printf '{}' > "$tmp/empty.json"

check() { # file expected-substring
  local f=$1 want=$2
  "$BIN/corrtex" info "$f" >"$tmp/o" 2>"$tmp/e"; rc=$?
  echo "+ $BIN/corrtex info $f  -> exit $rc: $(cat "$tmp/e")"
  [[ $rc -eq 2 ]] || { echo "FAIL: $f: exit $rc, want 2"; fail=1; }
  [[ $(grep -c '^error ' "$tmp/e") -eq 1 ]] || { echo "FAIL: $f: want exactly one error line"; fail=1; }
  grep -q -- "$want" "$tmp/e" || { echo "FAIL: $f: message lacks '$want'"; fail=1; }
}
check "$tmp/missing.json" "missing.json"
check "$tmp/syntax.json" "syntax.json:2:"
check "$tmp/range.json" "range.obj"
check "$tmp/nan.json" "nan.obj"
check "$tmp/degen.json" "no triangles"
check "$tmp/key.json" "unknown key 'shiny'"
check "$tmp/empty.json" "empty.json"
"$BIN/corrtex" info >/dev/null 2>&1; [[ $? -eq 2 ]] || { echo "FAIL: no argument must exit 2"; fail=1; }
"$BIN/corrtex" info --bogus x >/dev/null 2>&1; [[ $? -eq 2 ]] || { echo "FAIL: unknown option must exit 2"; fail=1; }
"$BIN/corrtex" frobnicate >/dev/null 2>&1; [[ $? -eq 2 ]] || { echo "FAIL: unknown command must exit 2"; fail=1; }
exit $fail
