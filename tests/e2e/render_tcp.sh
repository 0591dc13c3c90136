#!/usr/bin/env bash
# The display socket over TCP: the master refuses to listen on TCP without a
# token; with one (--token-file, mode 0600), a display with the token gets 3
# lockstep frames; a display without a token and one with a wrong token are
# refused with a message that says so, and the job goes on.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
cornell_args
head -c 32 /dev/urandom | base64 >"$tmp/token"; chmod 600 "$tmp/token"
head -c 32 /dev/urandom | base64 >"$tmp/wrong"; chmod 600 "$tmp/wrong"

# No token: refused at start, before the radiosity solve (it used to come
# after it and the mesh broadcast), exit status 2, with the reason.
master_start notoken 2 "${CORNELL[@]}" --listen tcp:127.0.0.1:0 --rad-cache "$tmp/notoken.ctmesh"
master_wait notoken 30 || fail "the job without a token did not end"
((MASTER_RC == 2)) || fail "exit status $MASTER_RC without a token, expected 2"
grep -q 'TCP needs a token' "$tmp/notoken.log" || { fail "no reason given"; master_log notoken; }
[[ ! -e $tmp/notoken.ctmesh ]] || fail "the radiosity was solved before the token was checked"
# A UNIX socket in a folder that does not exist: one line and status 2
# before the solve (it used to abort the job after it, under Open MPI's banner).
master_start nodir 2 "${CORNELL[@]}" --listen "unix:$tmp/no/such/dir/s.sock" --rad-cache "$tmp/nodir.ctmesh"
master_wait nodir 30 || fail "the job with a bad --listen did not end"
((MASTER_RC == 2)) || fail "exit status $MASTER_RC with a bad --listen, expected 2"
grep -q "cannot create the socket in $tmp/no/such/dir" "$tmp/nodir.log" || { fail "no reason given"; master_log nodir; }
[[ ! -e $tmp/nodir.ctmesh ]] || fail "the radiosity was solved before --listen was checked"
# A --rad-cache in a folder that does not exist: an output file, refused
# before the solve with one line and status 2 (it was found after the
# solve, as a warning that nothing was cached).
master_start nocache 2 "${CORNELL[@]}" --rad-cache "$tmp/no/dir/c.ctmesh"
master_wait nocache 30 || fail "the job with a --rad-cache in a missing folder did not end"
((MASTER_RC == 2)) || fail "exit status $MASTER_RC with a --rad-cache in a missing folder, expected 2"
grep -q "$tmp/no/dir/c.ctmesh: cannot create: its folder $tmp/no/dir does not exist" "$tmp/nocache.log" ||
  { fail "the missing folder of --rad-cache not named"; master_log nocache; }
grep -q ": solving" "$tmp/nocache.log" && fail "the radiosity was solved before --rad-cache was checked"
# --rad-cache with --mesh: a given mesh is used as it is, so the cache was
# neither read nor written, without a word. Refused at once (the mesh named
# is missing: the refusal comes before it is read).
master_start meshcache 2 "${CORNELL[@]}" --mesh "$tmp/none.ctmesh"
master_wait meshcache 30 || fail "the job with --rad-cache and --mesh did not end"
((MASTER_RC == 2)) || fail "exit status $MASTER_RC with --rad-cache and --mesh, expected 2"
grep -q -- "--rad-cache is the cache of the radiosity solve: not with --mesh" "$tmp/meshcache.log" ||
  { fail "--rad-cache with --mesh not refused"; master_log meshcache; }
# The solver's parameters with --mesh: dropped without a word too.
master_start meshrad 2 "$root/scenes/cornell/cornell.json" --mesh "$tmp/none.ctmesh" --rad-error 1e-4
master_wait meshrad 30 || fail "the job with --rad-error and --mesh did not end"
((MASTER_RC == 2)) || fail "exit status $MASTER_RC with --rad-error and --mesh, expected 2"
grep -q -- "--rad-error is a parameter of the radiosity solve: not with --mesh" "$tmp/meshrad.log" ||
  { fail "--rad-error with --mesh not refused"; master_log meshrad; }
# The refracted glass light is path tracing's and drt's: with reuse-diffuse,
# refused before the solve (it was found by the tracer ranks once the mesh
# had been sent).
master_start glasslight 2 "$root/scenes/cornell/cornell.json" --mesh "$tmp/none.ctmesh" --mode reuse-diffuse \
  --glass-light refracted
master_wait glasslight 30 || fail "the job with --glass-light refracted in reuse-diffuse did not end"
((MASTER_RC == 2)) || fail "exit status $MASTER_RC with --glass-light refracted in reuse-diffuse, expected 2"
grep -q -- 'glass light "refracted" is for path tracing and drt only (mode reuse-diffuse)' "$tmp/glasslight.log" ||
  { fail "--glass-light refracted with reuse-diffuse not refused"; master_log glasslight; }
# An unknown option given last is unknown, not missing its value.
master_start lastopt 2 "${CORNELL[@]}" --bogus
master_wait lastopt 30 || fail "the job with an unknown option did not end"
((MASTER_RC == 2)) || fail "exit status $MASTER_RC with an unknown option, expected 2"
grep -q "unknown option '--bogus'" "$tmp/lastopt.log" || { fail "unknown option not named"; master_log lastopt; }
# A bad value of the tracer's options: one line naming it, before any work.
master_start badind 2 "${CORNELL[@]}" --indirect photons
master_wait badind 30 || fail "the job with a bad --indirect did not end"
((MASTER_RC == 2)) || fail "exit status $MASTER_RC with --indirect photons, expected 2"
grep -q -- "--indirect: 'photons' is not one of mesh|gather" "$tmp/badind.log" || { fail "bad --indirect not named"; master_log badind; }
# The same for the display side's options.
master_start badtex 2 "${CORNELL[@]}" --display-texels half
master_wait badtex 30 || fail "the job with a bad --display-texels did not end"
((MASTER_RC == 2)) || fail "exit status $MASTER_RC with --display-texels half, expected 2"
grep -q -- "--display-texels: 'half' is not one of all|screen|auto" "$tmp/badtex.log" ||
  { fail "bad --display-texels not named"; master_log badtex; }

master_start job 3 "${CORNELL[@]}" --listen tcp:127.0.0.1:0 --token-file "$tmp/token" --exit-when-display-leaves
master_wait_listen job || finish
[[ $ADDR == tcp:127.0.0.1:* ]] || fail "listening on $ADDR"

display_run bad --connect "$ADDR" "${HEADLESS[@]}" --samples-per-frame 500 --frames 1 --out "$tmp/bad"
((DISPLAY_RC != 0)) || fail "a display without the token was served"
grep -qi 'token\|auth' "$tmp/bad.log" || fail "the refused display does not say why"
display_run wrong --connect "$ADDR" --token-file "$tmp/wrong" "${HEADLESS[@]}" --samples-per-frame 500 --frames 1 \
  --out "$tmp/wrong-out"
((DISPLAY_RC != 0)) || fail "a display with a wrong token was served"
grep -qi 'auth\|token\|proof' "$tmp/wrong.log" || fail "the display with a wrong token does not say why"

display_run good --connect "$ADDR" --token-file "$tmp/token" "${HEADLESS[@]}" --samples-per-frame 800 \
  --path "$(slow_path)" --frames 3 --out "$tmp/out"
((DISPLAY_RC == 0)) || fail "display with the token: exit status $DISPLAY_RC"
for k in 0 1 2; do [[ -f $tmp/out/$(printf 'frame_%05d.exr' $k) ]] || fail "frame $k missing"; done
master_wait job 20 || fail "the job did not end after the display left"
((MASTER_RC == 0)) || fail "job exit status $MASTER_RC"
master_log job | grep -v progress | tail -n 12
grep -q 'dropped a peer: .*auth' "$tmp/job.log" || fail "the master did not log the refused peers"
finish
