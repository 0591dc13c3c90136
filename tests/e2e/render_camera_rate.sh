#!/usr/bin/env bash
# A display that moves its camera faster than any screen refreshes
# (tests/tools/camera_flood: 1000 cameras a second for 3 s, every texture
# update acknowledged) against the Cornell box with one tracer rank
# (docs/distributed.md, "Camera changes"):
# - by default the master takes a new camera at most every --view-ms (50):
#   at most 3 / 0.05 + 2 views, and the job still inserts samples (before,
#   every camera was a view change, each stopping the tracer's batch, and
#   the job inserted next to nothing: table 1024^2 at 60 cameras a second,
#   411-1,492 samples a second against 52,000-58,000 now);
# - with --view-ms 0 --view-share 1 (200 cameras a second) it takes nearly
#   every camera, and the tracer answers each stopped batch with the
#   samples it traced, which go in where their surface is diffuse (late
#   samples: the whole box is);
# - with the eye swaying as well, glossy samples of the views left go in
#   aged, where --late-deg 0 drops them (stale);
# - with --view-ms 0 --view-share 0.01 (views of 1024 x 1024) camera
#   changes take about 1 % of the master's time (at most 1.5 % of the
#   flood, plus one change) and it takes at most half of the cameras;
# - a new image size with every other camera is paced the same, and a
#   costly change holds the next for a second at most;
# - the job then still serves a display (a frame of the still view), and
#   bad values of both options (and of --late-deg and --patch-share, the
#   texture updates' share) end the job with status 2 and one line naming
#   the option, as scripts/bench-camera-rate's bad arguments do.
source "$(dirname "$0")/lib/mpi.sh"
flood="$root/${CORRTEX_BUILD:-build/release}/tools/camera_flood"
need_programs "$flood"
cornell_args
CAM=(278 273 -800 278 273 0 39.3)
T=3 RATE=1000

# flood NAME SIZE ALT ARGS...: a job with ARGS, flooded for T s at RATE
# cameras a second with SIZE x SIZE views (every other one ALT wide when
# ALT > 0; the eye swaying sideways by up to SWING scene units, default 0);
# sets VIEWS, VIEW_MS, INSERTED, LATE, STALE (the master's stats-line
# differences over the flood) and CAMERAS (sent).
flood() {
  local name=$1 size=$2 alt=$3; shift 3
  local extra=()
  ((${SWING:-0} > 0)) && extra=("$SWING")
  ((alt > 0)) && extra=("${SWING:-0}" "$alt")
  master_start "$name" 2 "${CORNELL[@]}" --listen "unix:$tmp/$name.sock" --stats-s 0.25 "$@"
  master_wait_listen "$name" || return 1
  sleep 0.6
  local before after
  before=$(grep 'master: stats:' "$tmp/$name.log" | tail -n 1)
  log_cmd "$flood" "$ADDR" - "$size" "$size" "$RATE" "$T" "${CAM[@]}" "${extra[@]}"
  "$flood" "$ADDR" - "$size" "$size" "$RATE" "$T" "${CAM[@]}" "${extra[@]}" >"$tmp/$name-flood.out" 2>&1 ||
    { fail "$name: camera_flood: $(cat "$tmp/$name-flood.out")"; return 1; }
  after=$(grep 'master: stats:' "$tmp/$name.log" | tail -n 1)
  CAMERAS=$(sed -n 's/^cameras \([0-9]*\) .*/\1/p' "$tmp/$name-flood.out")
  # "total N (... L late), S stale, ... views V (X ms in all"
  local re='s/.*, total \([0-9]*\) ([^)]* \([0-9]*\) late), \([0-9]*\) stale,.* views \([0-9]*\) (\([0-9.]*\) ms in all.*/\1 \2 \3 \4 \5/p'
  local n0 l0 s0 v0 m0 n1 l1 s1 v1 m1
  read -r n0 l0 s0 v0 m0 <<<"$(sed -n "$re" <<<"$before")"
  read -r n1 l1 s1 v1 m1 <<<"$(sed -n "$re" <<<"$after")"
  [[ -n ${n1:-} ]] || { fail "$name: no stats line after the flood"; return 1; }
  INSERTED=$((n1 - ${n0:-0})) LATE=$((l1 - ${l0:-0})) STALE=$((s1 - ${s0:-0})) VIEWS=$((v1 - ${v0:-0}))
  VIEW_MS=$(awk -v a="${m0:-0}" -v b="$m1" 'BEGIN { printf "%.1f", b - a }')
  # of the stale, the glossy ones whose viewing direction turned too far
  local tre='s/.* stale, \([0-9]*\) of them turned past --late-deg,.*/\1/p' t0 t1
  t0=$(sed -n "$tre" <<<"$before") t1=$(sed -n "$tre" <<<"$after")
  [[ -n $t1 ]] || { fail "$name: no turned count in the stats line"; return 1; }
  TURNED=$((t1 - ${t0:-0}))
  echo "metric: $name: $CAMERAS cameras in $T s ($RATE a second), the master took $VIEWS ($VIEW_MS ms in all), inserted $INSERTED samples ($LATE late), $STALE stale ($TURNED turned)"
}

if flood paced 128 0; then
  ((CAMERAS >= 1000)) || fail "paced: the flood sent only $CAMERAS cameras in $T s"
  ((VIEWS <= T * 20 + 2)) || fail "paced: the master took $VIEWS camera changes in $T s (--view-ms 50: at most $((T * 20 + 2)))"
  ((VIEWS >= 10)) || fail "paced: the master took only $VIEWS camera changes in $T s (it must follow the camera)"
  ((INSERTED >= 1000)) || fail "paced: only $INSERTED samples inserted while the camera moved"
  # The job goes on and serves a still view.
  display_run still --connect "$ADDR" "${HEADLESS[@]}" --camera 278,273,-800,278,273,0,39.3 --frames 1 --out "$tmp/still"
  ((DISPLAY_RC == 0)) || fail "paced: a display after the flood exited $DISPLAY_RC"
  [[ -f $tmp/still/frame_00000.exr ]] || fail "paced: no frame after the flood"
  master_term paced
fi

# 200 cameras a second: a view every 5 ms, shorter than a batch (20 ms), so
# every batch is stopped part way.
if RATE=200 flood every 128 0 --view-ms 0 --view-share 1; then
  ((VIEWS * 2 >= CAMERAS)) || fail "every: the master took $VIEWS of $CAMERAS cameras (at least half)"
  # 286,000-320,000 here, 171,000-179,000 under the sanitizers; 1,300 when
  # a stopped batch was answered empty; 76,000-105,000 (36,000 under the
  # sanitizers, and now and then a few hundred) while a tracer waited idle
  # between a camera and the new view's first batch (docs/distributed.md,
  # "A tracer never waits with requests in hand")
  ((LATE >= 15000)) || fail "every: only $LATE samples of views left went in (a stopped batch answers with what it traced)"
  master_term every
fi

# The eye sways by up to 10 mm while it takes every camera: the samples of
# the views it left that lie on the mirror and glass spheres go in aged
# (docs/textures.md, "Late samples") where --late-deg 0 drops them as
# stale, as the builds before session 43 did.
if RATE=200 SWING=10 flood aged 128 0 --view-ms 0 --view-share 1; then
  aged_late=$LATE aged_stale=$STALE aged_turned=$TURNED
  master_term aged
  if RATE=200 SWING=10 flood dropped 128 0 --view-ms 0 --view-share 1 --late-deg 0; then
    echo "metric: a swaying eye: stale $aged_stale of $((aged_late + aged_stale)) late samples aged, $STALE of $((LATE + STALE)) with --late-deg 0"
    ((STALE >= 1000)) || fail "dropped: only $STALE stale samples with --late-deg 0 (no glossy samples from a moved eye to test)"
    # Both keep the stale samples of parts the turned view does not texture
    # (about 9 % of those traced, as "every" shows with a fixed eye); with
    # --late-deg 0 the spheres' samples add about as many (15 % here), aged
    # they go in (9 %): at most three quarters as many stale per sample.
    ((aged_stale * 4 * (LATE + STALE) <= 3 * STALE * (aged_late + aged_stale))) ||
      fail "aged: $aged_stale of $((aged_late + aged_stale)) late samples stale, $STALE of $((LATE + STALE)) with --late-deg 0"
    # The difference is the glossy samples: turned past --late-deg 0, and
    # (a sway of a few hundredths of a degree) next to none past 10.
    ((TURNED >= 500)) || fail "dropped: only $TURNED of $STALE stale samples counted as turned with --late-deg 0"
    ((aged_turned * 20 <= TURNED)) || fail "aged: $aged_turned samples turned past --late-deg 10, $TURNED past 0"
    master_term dropped
  fi
fi

# Views of 1024 x 1024, whose changes cost the master some 40 us here (its
# queue is per pixel), 3-4 % of its time when it takes every camera: at 1 %
# it takes about every third.
if flood share 1024 0 --view-ms 0 --view-share 0.01; then
  awk -v ms="$VIEW_MS" -v v="$VIEWS" -v T="$T" 'BEGIN { exit !(v > 0 && ms <= 0.015 * T * 1000 + ms / v) }' ||
    fail "share: camera changes took $VIEW_MS ms of $T s in $VIEWS changes (--view-share 0.01)"
  ((VIEWS * 2 <= CAMERAS)) || fail "share: the master took $VIEWS of $CAMERAS cameras (--view-share 0.01 paces them)"
  master_term share
fi

# A new image size with every other camera (each a new per-pixel queue
# and shown-node map): paced the same, and the job goes on inserting.
if flood sizes 256 128; then
  ((VIEWS <= T * 20 + 2)) || fail "sizes: the master took $VIEWS camera changes in $T s (at most $((T * 20 + 2)))"
  ((INSERTED >= 1000)) || fail "sizes: only $INSERTED samples inserted while the image size kept changing"
  master_term sizes
fi

# A costly change holds the next for a second at most: at 0.01 % of the
# master's time a change to a 2048 x 2048 view (0.7-3 ms here, more under
# the sanitizers) would hold the camera for 7-30 s; a view every second or
# so instead: 5 in 5 s (without the bound: 2 in 3 s).
if T=5 flood capped 2048 64 --view-ms 0 --view-share 0.0001; then
  ((VIEWS >= 4)) || fail "capped: the master took $VIEWS camera changes in 5 s (a costly change holds the next 1 s at most)"
  master_term capped
fi

# Bad values (the master's pacing of camera changes and of texture
# updates): one line naming the option, exit 2, before any work.
i=0
for bad in "--view-ms -1" "--view-ms soon" "--view-share 0" "--view-share 1.5" "--late-deg 181" "--patch-share 0" \
  "--patch-share 2"; do
  i=$((i + 1))
  # shellcheck disable=SC2086
  master_start "bad$i" 2 "${CORNELL[@]}" $bad
  master_wait "bad$i" 30 || fail "$bad: the job did not end"
  echo "  $bad: exit $MASTER_RC: $(grep -m 1 '^error' "$tmp/bad$i.log")"
  ((MASTER_RC == 2)) || fail "$bad: exit status $MASTER_RC, expected 2"
  (($(grep -c -- "${bad%% *}" "$tmp/bad$i.log") == 1)) || { fail "$bad: not one line naming the option"; master_log "bad$i"; }
done
# The benchmark's own bad arguments: one line, exit 2, nothing run.
for bad in "--motions run" "--rates fast" "--settings fast" "--bogus"; do
  # shellcheck disable=SC2086
  "$root/scripts/bench-camera-rate" $bad >"$tmp/badb.out" 2>&1
  rc=$?
  echo "  bench-camera-rate $bad: exit $rc: $(head -n 1 "$tmp/badb.out")"
  ((rc == 2)) || fail "bench-camera-rate $bad: exit status $rc, expected 2"
  (($(wc -l <"$tmp/badb.out") == 1)) || fail "bench-camera-rate $bad: $(wc -l <"$tmp/badb.out") lines of output, expected 1"
done
finish
