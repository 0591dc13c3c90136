# bench-master-saturation.sh: the "saturation" part of scripts/bench-master,
# sourced by it (it uses that script's BUILD, machine and run): a file of
# its own because the replay's runs, fit and tables are as long as the
# three other parts together.
# --- part saturation: the whole master as fast as it takes samples ---------
# SAT_RUNS (runs per thread count, interleaved; default 5) and SAT_BENCH_DIR
# change the runs. Two cores: the runs are pinned to CPUs 0 and 1.
part_saturation() {
  local corrtex=bin/corrtex bench=$BUILD/bench/bench_master work=${SAT_BENCH_DIR:-$BUILD/bench-saturation}
  make --no-print-directory -s "$corrtex" "$bench" >&2
  mkdir -p "$work"
  local load runs=${SAT_RUNS:-5} pin2=()
  command -v taskset >/dev/null 2>&1 && pin2=(taskset -c 0,1)
  load=$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?')
  local view=(scenes/office/office.json --camera office --width 1024 --height 1024)
  # One tracer rank's rate (one core) for the same kind of samples.
  local ratecmd=("${PIN[@]}" "$corrtex" reference "${view[@]}" --spp 1 --mode drt --stand-in-radiosity 0.3
                 --threads 1 -o "$work/rank.exr")
  local rate
  rate=$(run "${ratecmd[@]}" 2>/dev/null | sed -n 's/^stats: .*samples_per_s=\([0-9.]*\).*/\1/p')
  [[ -n $rate ]] || { echo "bench-master: no samples_per_s from the tracer run" >&2; exit 1; }
  local cmds=("${ratecmd[*]}") out="" B
  # Rounds of 256 (lockstep frames' rounds) and of 4,096 (the largest
  # free-running batch, --batch-max: what a master saturated by many
  # tracers gets from each).
  # Rounds of 4,096 twice: in the exact order (each round popped after
  # the last one's reports, as lockstep frames are) and with each round
  # popped ahead of the last one's reports (--pop-ahead: how a free-running
  # master pops a lane's next batch, beside the splats on 2+ threads).
  # Rounds of 4,096 past full coverage (4096r): the pixels, then twice as
  # many refinement samples (corrtex-render's --refine-error), which is
  # what a master fed by many tracers does from the first second of a
  # still view on (docs/sampling.md, "Refinement").
  local cfg B ahead tag refine samples
  for cfg in 256 4096 4096a 4096r; do
    B=${cfg%[ar]} ahead=() tag=$cfg refine=() samples=all
    [[ $cfg == *a ]] && ahead=(--pop-ahead)
    [[ $cfg == *r ]] && refine=(--refine-error 0.002) samples=3145728
    # The recording: every sample of a still view until every pixel has one
    # (or the samples past it), as corrtex converge takes them (rounds of B).
    local reccmd=("$corrtex" converge "${view[@]}" --samples "$samples" --mode drt --stand-in 0.3 --threads 2 --batch "$B"
                  "${ahead[@]}" "${refine[@]}" --record "$work/office-$tag.srec" --quiet --out "$work/record-$tag")
    run "${reccmd[@]}" >"$work/record-$tag.log"
    cmds+=("${reccmd[*]}")
    local rows="" pass t row
    for ((pass = 1; pass <= runs; pass++)); do
      for t in 1 2; do
        local cmd=("${pin2[@]}" "$bench" "${view[@]}" --stand-in 0.3 --record "$work/office-$tag.srec" --batch "$B"
                   "${ahead[@]}" "${refine[@]}" --master-threads "$t")
        ((pass == 1)) && cmds+=("${cmd[*]}")
        row=$(run "${cmd[@]}") || { echo "bench-master: bench_master failed" >&2; exit 1; }
        rows+="$row"$'\n'
      done
    done
    # medians of the wall-clock rates per thread count, and the model
    local summary
    local what="Rounds of $B"
    ((${#ahead[@]})) && what="Rounds of $B, each popped ahead of the last one's reports (--pop-ahead)"
    ((${#refine[@]})) && what="Rounds of $B past full coverage (1,048,576 pixels, then 2,097,152 refinement samples, --refine-error 0.002)"
    summary=$(printf '%s' "$rows" | awk -F'|' -v r="$rate" -v B="$B" -v what="$what" '
      { t = $2 + 0; n[t]++; rate[t, n[t]] = $6 + 0; cpu[t, n[t]] = $5 + 0 }
      function med(t, a,   i, j, k, x, v) { k = n[t]; for (i = 1; i <= k; i++) v[i] = a[t, i];
        for (i = 2; i <= k; i++) { x = v[i]; for (j = i - 1; j >= 1 && v[j] > x; j--) v[j + 1] = v[j]; v[j + 1] = x }
        return k % 2 ? v[(k + 1) / 2] : (v[k / 2] + v[k / 2 + 1]) / 2 }
      END {
        m1 = med(1, rate); m2 = med(2, rate); c1 = med(1, cpu); c2 = med(2, cpu); s2 = m2 / m1
        printf "%s, median of %d runs each: **1 master thread %.0f samples/s, 2 master threads %.0f samples/s (%.2fx)**; CPU seconds per run %.2f and %.2f.\n\n", what, n[1], m1, m2, s2, c1, c2
        # Amdahl: a serial share s fitted to the 2-thread speedup
        s = 2 / s2 - 1; if (s < 0) s = 0; if (s > 1) s = 1
        printf "Serial share fitted to the 2-thread speedup (Amdahl): s = %.2f.\n\n", s
        printf "| master threads N | master samples/s M(N) | tracer ranks kept busy M(N) / rank rate |\n| ---: | ---: | ---: |\n"
        for (N = 1; N <= 64; N *= 2) {
          m = N == 1 ? m1 : N == 2 ? m2 : m1 / (s + (1 - s) / N)
          printf "| %d%s | %.0f | %.1f |\n", N, (N > 2 ? " (model)" : ""), m, m / r }
        need = m1 / (64 * r)
        if (s >= need) printf "\nOne master keeps 64 tracer ranks busy with **no thread count** under this model: its limit for N -> infinity is M(1) / s = %.0f samples/s, %.1f ranks; 64 ranks need %.0f samples/s.\n", (s > 0 ? m1 / s : 0), (s > 0 ? m1 / s / r : 0), 64 * r
        else printf "\nOne master keeps 64 tracer ranks busy from **N = %d** threads (64 ranks need %.0f samples/s).\n", int((1 - s) / (need - s)) + 1, 64 * r
      }')
    out+="$summary"$'\n\n'"Runs (in the order they ran):"$'\n\n'
    out+="| master threads | samples | wall s | CPU s | samples/s | display updates | display MB | insertion s | pops ahead s | requests s | port s | display s |"$'\n'
    out+="| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"$'\n'
    out+="$rows"$'\n'
  done
  cat <<EOT
The whole master as fast as it takes samples: \`corrtex converge\` records
every sample of a real run (office, camera \`office\`, 1024x1024, drt
samples with the radiosity stand-in, from the first request until every
pixel has a sample: 1,048,576 samples), and \`tests/bench/bench_master\`
replays them into the master's session (master/session.h) through its loop
(master/drive.h) over the replay port (master/tport_replay.h), which answers
every request at once, in the recording run's lockstep rounds, so the
master hands out the very requests it recorded. Four recordings: rounds of
256 requests (a lockstep frame's rounds) and of 4,096 (the largest
free-running batch, \`--batch-max\`: a master saturated by many tracer ranks
gets batches of that size from each, as each asks for \`--batch-ms\` of its
rate), the latter three times: in the exact order, with each round popped
ahead of the last one's reports (\`--pop-ahead\`, corrtex-render's option
for a master that many tracers saturate: docs/distributed.md, "The
master's threads"), and past full coverage: the pixels, then twice as many
refinement samples (docs/sampling.md, "Refinement"; a master fed by many
tracer ranks refines from the first second of a still view on, so this is
most of what it does). Every sample goes through
the request queue (pop, report, children, the node-mismatch check against
the shown-node map), the textures (lookup, error, splat, resolution
changes) and out to a display: a child process connected over a UNIX
socket that takes every message, copies every texture patch into its
textures as corrtex-display's inbox does, and acknowledges every update, so
the texture updates are paced by it as in \`corrtex-render\` (free running,
every 10 ms at most and within a quarter of the master's time,
\`--patch-share\`). *samples/s* = samples / wall time of the replay;
*CPU s* = the master's CPU time (all its threads), not the display's. The
stages (wall seconds, tests/bench/bench_master.c): *insertion* = in the
session's insertion (splats, reports, and the pops ahead where they were
not hidden), *pops ahead* = the pops' own time inside it (beside the splats
on two threads), *requests* = pops outside it, *port* = the rest of the
loop (the replay port, sorting rounds), *display* = the display server and
the texture updates.

The master's threads (\`--master-threads\`) split the splatting by texture
and a resolution change by rows; a chunk's reports to the queue and the
pops ahead run on one of them beside the next chunk's splats (a side job of
the pool), and past full coverage a chunk's refinement reports beside the
texel writes of the chunk before; the texture updates to the display and
the socket are the main thread's work (docs/distributed.md, "The master's
threads").
The model extrapolates the measured speedup by Amdahl's law and divides by
one tracer rank's rate to tell how many ranks one master keeps busy (on a
16-core machine the replay was measured up to 12 threads: it stops at about
1.3 million samples a second from 2-4 threads on; "Interactive: 16 cores
and a GPU display"). The same live, the master beside a tracer and a
display, while a still view refines: "Master: refinement (live)"
(scripts/bench-refine). Goals:
at least 2,000,000 samples/s with one thread, 2 threads at least 1.8 times
one.

Where the time goes (perf with call graphs of the 1-thread run, the master
process, rounds of 4,096, before the texel memory pool): the kernel faulting
in and zeroing texture memory 17-25 % (resolution changes allocate 186 MiB
of which 109 MiB are the final textures; the pool, docs/textures.md "Texel
memory", now serves part of it), the request queue's pops 15 % (2.6 million
pops for 1 million requests: most are for pixels handed out since they were
queued), the splats 12 %, the node check 6 %, the queue's reports and
children 9 %, the replay port and sorting the rounds 8 %. In rounds of 256
the texture updates to the display are the largest share (some 530 MB to
the display per run, against 57 MB in rounds of 4,096: more updates, each
re-sending tiles the splats touched since the last). Only the splats were
split over the master's threads then, and on the office view the largest
texture takes 44 % of a chunk's samples, which alone bounds their speed-up
on two threads at 1.8. The runs share two cores with the display child and,
on this machine, with other processes (see the load average): the CPU
seconds are the steadier figure.

Profile again on 2026-11-28 (session 29, with the pool, on a host whose
tracer rank traced 148,000 samples/s against 355,000 the day before):
the queue's pops 20 %, the kernel zeroing new texture pages 9 % (20 % with
the faults), the splats 9 %. A pop's sift-down now asks for the next
level's four candidate cache lines before choosing among the children, so
their misses overlap: pops 20 -> 15 %, three interleaved pairs of runs
1.34-1.84 s against 2.00-2.32 s. Compare days by the ranks kept busy (the
master's rate over the rank's on the same host), not by samples/s.

The doubling's slack (2026-11-29, session 32; docs/textures.md,
"Resolution") made splats cover their whole Voronoi cells after a texture
doubles, where ties with the doubled texels had stopped them: the
corrected image's 32-pixel blocks went from 432 of 992 more than 2 % off
drt's converged image to 26 (table, 1024x1024), at about twice the texels
written per sample. Interleaved replays of the office view in rounds of
4,096, one master thread, the same host: 1.14-1.39 million samples/s
before, 0.50-0.82 after (two interleaved pairs; each against its own
recording: the requests follow the errors). The replay port now finds a
request's sample by index instead of a binary search, a cost of the
benchmark, not of the master (0.63-0.66 -> 0.67-0.81 million samples/s in
three interleaved pairs); the runs below have it. The splats are now the largest share (17 % of the
converge run's profile against 5 %), and they are the part the master's
threads split. The ranks one master keeps busy fell from about 5 to 3
on this host.

Session 33 (2026-11-29; docs/textures.md, "Resolution"): every change
of a texture's resolution needs the mean of every splat radius since its
last change past the threshold, not only the running mean: the office
view's floor and walls had doubled early on a dip of the running mean and
gone 1024² -> 2048² -> 1024² up to three times in one first pass. First
step (reversals only), three interleaved pairs each against its own
recording: rounds of 256 0.52-0.59 -> 0.72-0.76 million samples/s and
930-970 -> 680-710 MB to the display; rounds of 4,096 within the spread.
Resolution changes now run on the master's threads as well (bands of
rows): two threads in rounds of 4,096 went from 1.18 to 1.45 times one in
that step's run. Second step (every change), the runs below: one thread
in rounds of 4,096 0.75 -> 1.08 million samples/s (median; single runs
0.88-1.19), rounds of 256 0.75 -> 0.78; the textures hold fewer texels
while the samples are sparse (office ends at 11.0 million instead of
14.2, docs/benchmarks.md "Master: corrective textures"), so the texture
work shrank and two threads gain little over one (1.04x, single runs
0.99-1.22 million). Profile of a 1-thread run in rounds of 4,096 after it
(perf with call graphs, shares of the replay loop, a run at 0.76 million
samples/s): the splats 29 %, resolution changes 28 % (most of it the
kernel zeroing fresh pages on first touch: on this project's virtual
machines that runs at 0.4-10 GB/s from run to run, and it makes most of
the spread between runs), the request queue 27 % (its pops 17 %), the
samples' lookup, prefetch and error 8 %. With whole Voronoi cells at the
default \`--tex-rate\` and fresh memory for every texture one thread stays
under 2 million samples/s; only the texture work was split over threads.

Session 36 (2026-11-29): the queue's work beside the texture work. Per-stage
timers in the replay (the runs' last columns) showed, one thread, rounds of
4,096: insertion 0.58-0.85 s (splats, resolution changes, reports),
requests 0.19-0.23 s, the port 0.04-0.07 s, the display 0.03-0.05 s; on two
threads insertion fell to 0.43-0.49 s while the requests stayed, the largest
serial part. Three changes, each keeping one order of the queue's and the
textures' operations for any thread count: (1) a chunk's reports run on the
second thread (a side job of the pool, common/pool.h) while the next chunk
is splatted: insertion on two threads 0.457 -> 0.431 s median of 5
interleaved pairs; (2) a popped request for a pixel handed out since it was
queued is dropped by the pixel kept in its heap entry, its payload unread:
within the spread (a purge of such requests from the whole queue before each
batch was tried and dropped: only 10 % of the queue was stale at any time,
most stale requests reach the top soon after going stale); (3) with
\`--pop-ahead\` (off by default: it costs sampling quality, docs/sampling.md),
a lane's next batch is popped while its answer goes in, ahead of that
answer's reports, in one portion per chunk beside the splats (master/drive.h;
the third recording): two threads, 6 interleaved runs, 0.82 s median in the
exact order against 0.71 s popped ahead (1 thread 0.94 against 1.08 s: the
same work in another order, within this host's spread); (4) the queue's
entries in buckets by priority (master/rq_heap.h: a pop sifts down in the
top bucket, a few thousand entries, not in one heap of half a million):
the requests stage 0.16-0.19 -> 0.10-0.13 s, 5 interleaved pairs, the same
requests in the same order. The goals stay
unmet: one thread is
bound by the texture work and the kernel's page zeroing, and two threads
share the two cores with the display child, whose patch copies and socket
reads the replay's display stage waits for. Session 39 timed the splats
by size (docs/textures.md, "Insertion speed"): 0.33 s of a 1-thread
replay, over half of it in splats of 25-1,000 texels that miss the cache
on every few texels; the floods of large empty regions are half the
texel writes but a quarter of that time.

Session 44 (2026-11-30): the texture updates keep to a share of the
master's time (\`--patch-share\`, default 0.25; docs/protocol.md, "Flow
control"). Before, an update went every 10 ms as the ACKs allowed, and in
rounds of 256 the master re-sent, every few milliseconds, the tiles its
splats kept touching: 480-556 MB to the display and 0.61-0.79 s of a
1.7-2.3 s replay in the display stage. Now an update that cost t (the CPU
time of its encoding and of the socket writes since the one before) holds
the next until t / 0.25 after its start. Three interleaved pairs, one
thread, rounds of 256 (\`bench_master ... --patch-share 1\` against the
default): 532,614 / 547,625 / 521,285 -> 614,478 / 592,101 / 523,080
samples/s, 179-333 MB to the display, its stage 0.39-0.53 s; rounds of
4,096 within the spread (their updates cost little). \`--patch-share 0.1\`
went further (0.60-0.89 million samples/s in four runs of a first
version, 72-292 MB, 9-35 updates: one every 40-130 ms); the default stays
at a quarter, as for camera changes. Why CPU time: a first version timed
the updates by the wall clock, which on this host also counts the waits
for a core. Live (bench-refine's cheap tracer on table 1024², with a
display drawing every frame, \`--display-args "--texel-fps 0"\`) an update
then cost 6-7 ms, three in four were held 22 ms longer, and the lag
median rose from 154-167 to 176-184 ms against \`--patch-share 1\`; by CPU
time an update costs about 2 ms, one in five is held about 4 ms longer,
and two interleaved pairs gave the same refinement rate (250,218 /
266,394 against 253,022 / 260,797 samples/s) and lag median / p99 (179 /
2,417 and 163 / 1,776 against 184 / 1,659 and 171 / 1,641 ms). With the
display at \`--texel-fps 2\` (bench-refine's default) and in
bench-interactive's table 1024² row, the first version moved nothing
beyond the spread either.

One tracer rank (one core, the same drt samples): ${rate} samples/s.

${out}
Machine: $(machine); load average before the runs: ${load}.
Date: $(date -u '+%Y-%m-%d %H:%M UTC').
Commands (\`scripts/bench-master --part saturation\`):
$(for c in "${cmds[@]}"; do echo "    $c"; done)
EOT
}
