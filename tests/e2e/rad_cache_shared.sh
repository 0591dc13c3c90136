#!/usr/bin/env bash
# One radiosity cache for every program: `corrtex radiosity SCENE` without -o
# writes the file corrtex-render reads when given no --mesh or --rad-cache
# (HASH.ctmesh in $XDG_CACHE_HOME/corrtex), prints it (`file`), keeps it when
# up to date; `--cache-path` names it without solving; corrtex-render then
# starts from it without solving, and corrtex-walk uses the same file (it had
# a cache of its own, so a scene was solved twice). A cache folder that
# cannot be made: corrtex radiosity fails with one line naming it, and
# corrtex-render solves without a cache and says so.
source "$(dirname "$0")/lib/mpi.sh"
need_programs "$corrtex"
export XDG_CACHE_HOME="$tmp/xdg"
scene=$root/scenes/cornell/cornell.json
opts=(--max-triangles 20000)

# 1. corrtex radiosity without -o: the default cache, made and then kept.
log_cmd "$corrtex" radiosity "$scene" "${opts[@]}" --quiet
"$corrtex" radiosity "$scene" "${opts[@]}" --quiet >"$tmp/r1.out" 2>"$tmp/r1.err" ||
  { fail "corrtex radiosity without -o failed"; cat "$tmp/r1.err"; finish; }
file=$(awk '$1 == "file" { print $2 }' "$tmp/r1.out")
echo "  file: $file"
[[ $file =~ ^$tmp/xdg/corrtex/[0-9a-f]{16}\.ctmesh$ ]] || fail "the default cache is '$file', not HASH.ctmesh in $tmp/xdg/corrtex"
[[ -s $file ]] || fail "no cache written at '$file'"
grep -q '^cached 1' "$tmp/r1.out" && fail "a first run says it kept a cache"
"$corrtex" radiosity "$scene" "${opts[@]}" --quiet >"$tmp/r2.out" || fail "the second run failed"
grep -q '^cached 1' "$tmp/r2.out" || fail "the second run without -o solved again (want the cache kept)"
[[ $(awk '$1 == "file" { print $2 }' "$tmp/r2.out") == "$file" ]] || fail "the second run named another file"
# --cache-path: the same name, another one for other parameters, nothing written
path=$("$corrtex" radiosity "$scene" "${opts[@]}" --cache-path) || fail "--cache-path failed"
[[ $path == "$file" ]] || fail "--cache-path prints '$path', the run wrote '$file'"
other=$("$corrtex" radiosity "$scene" --max-triangles 30000 --cache-path)
[[ -n $other && $other != "$file" && ! -e $other ]] ||
  fail "--cache-path for other parameters: '$other' (want another name, not written)"
"$corrtex" radiosity "$scene" --cache-path -o "$tmp/x.ctmesh" 2>"$tmp/both.err"; rc=$?
((rc == 2)) && grep -q 'not with -o' "$tmp/both.err" || fail "--cache-path with -o: exit $rc, want 2 with a reason"

# 2. corrtex-render with the same parameters reads that file, solves nothing.
master_start job 2 "$scene" --rad-max-triangles 20000 --listen "unix:$tmp/r.sock"
master_wait_listen job || { master_log job; finish; }
grep -qF "radiosity mesh from the cache $file" "$tmp/job.log" ||
  { fail "corrtex-render did not start from $file"; master_log job; }
grep -q 'solving' "$tmp/job.log" && fail "corrtex-render solved again"
master_term job

# 3. corrtex-walk names the same file (its dry run prints the commands).
walk=$root/scripts/corrtex-walk
log_cmd "$walk" "$scene" --radiosity-options "--max-triangles 20000" --dry-run
CORRTEX_BIN=$bin "$walk" "$scene" --radiosity-options "--max-triangles 20000" --dry-run >"$tmp/walk.out" 2>&1 ||
  { fail "corrtex-walk --dry-run failed"; cat "$tmp/walk.out"; }
grep -qF -- "-o $file --reuse" "$tmp/walk.out" || { fail "corrtex-walk does not solve into $file"; cat "$tmp/walk.out"; }
grep -qF -- "--mesh $file" "$tmp/walk.out" || fail "corrtex-walk's job does not read $file"

# 4. A cache folder that cannot be made (XDG_CACHE_HOME is a file).
: >"$tmp/plain-file"
XDG_CACHE_HOME=$tmp/plain-file "$corrtex" radiosity "$scene" "${opts[@]}" --quiet >/dev/null 2>"$tmp/nodir.err"
rc=$?
sed 's/^/  stderr: /' "$tmp/nodir.err"
((rc == 2)) || fail "corrtex radiosity with an unmakeable cache folder: exit $rc, want 2"
[[ $(wc -l <"$tmp/nodir.err") -eq 1 ]] && grep -qF "$tmp/plain-file/corrtex" "$tmp/nodir.err" ||
  fail "want one error line naming $tmp/plain-file/corrtex"
XDG_CACHE_HOME=$tmp/plain-file master_start nocache 2 "$scene" --rad-max-triangles 20000 --listen "unix:$tmp/n.sock"
master_wait_listen nocache 120 || { master_log nocache; finish; }
grep -q "warn.*no radiosity cache: .*$tmp/plain-file/corrtex" "$tmp/nocache.log" ||
  { fail "corrtex-render did not say it has no cache"; master_log nocache; }
master_term nocache
finish
