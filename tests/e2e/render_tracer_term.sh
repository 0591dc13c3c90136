#!/usr/bin/env bash
# A tracer rank that is sent SIGTERM alone (not by mpirun, which signals
# every rank at once) leaves in order: it sends its last samples and BYE
# (docs/protocol.md, "Leaving in order"); the master, whose own signal does
# not follow, ends the job within a second or two naming the rank, tells
# the display, and every rank finalizes (no drain timeout, no abort).
# Checks: the job ends in under 5 s with a non-zero status, the master names
# rank 1, the display shows the master's message and exits 3, no process is
# left.
source "$(dirname "$0")/lib/mpi.sh"
need_programs
job_with_walker 3
signal_victim TERM 5
drc=$DISPLAY_RC
master_log job | grep -v progress | tail -n 8
sed 's/^/  display: /' "$tmp/display.log" | tail -n 3
grep -q 'tracer rank 1 left the job (it got a signal)' "$tmp/job.log" || fail "the master did not name the rank that left"
grep -q 'tracer rank 1 left the job' "$tmp/display.log" || fail "the display did not show the master's message"
((drc == 3)) || fail "display exit status $drc, expected 3"
no_job_left
finish
