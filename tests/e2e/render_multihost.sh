#!/usr/bin/env bash
# Two "hosts" of one mpirun: network namespaces h1 (10.77.0.1: mpirun and the
# master) and h2 (10.77.0.2: both tracers), each with its own host name, joined
# by a bridge; Open MPI starts the remote daemon through an rsh agent that runs
# the command inside h2's namespace (`ip netns exec`), and ranks talk over TCP
# only (--mca btl tcp,self). The display runs in a third namespace
# (10.77.0.3) and connects over TCP with a token. Its lockstep frames must be
# bit-identical to those of the same job on one host. Skips, saying why, when
# namespaces cannot be made (not root, no `ip netns`, no `unshare`).
source "$(dirname "$0")/lib/mpi.sh"
need_programs
command -v ip >/dev/null || skip "multi-host test: the ip command (iproute2) is not installed"
command -v unshare >/dev/null || skip "multi-host test: unshare (util-linux) is not installed"
[[ $(id -u) == 0 ]] || skip "multi-host test: network namespaces need root"
S=$$
NS_SW=ct-sw-$S
ns_of() { echo "ct-$1-$S"; }
teardown() {
  local n
  for n in h1 h2 d; do ip netns del "$(ns_of $n)" 2>/dev/null; done
  ip netns del "$NS_SW" 2>/dev/null
}
setup() {
  ip netns add "$NS_SW" && ip netns exec "$NS_SW" ip link set lo up &&
    ip netns exec "$NS_SW" ip link add br0 type bridge && ip netns exec "$NS_SW" ip link set br0 up || return 1
  local i=1 n ns
  for n in h1 h2 d; do
    ns=$(ns_of $n)
    ip netns add "$ns" &&
      ip link add "ct$n$S" type veth peer name "cp$n$S" &&
      ip link set "ct$n$S" netns "$ns" && ip link set "cp$n$S" netns "$NS_SW" &&
      ip netns exec "$NS_SW" ip link set "cp$n$S" master br0 && ip netns exec "$NS_SW" ip link set "cp$n$S" up &&
      ip netns exec "$ns" ip link set lo up &&
      ip netns exec "$ns" ip addr add "10.77.0.$i/24" dev "ct$n$S" &&
      ip netns exec "$ns" ip link set "ct$n$S" up || return 1
    i=$((i + 1))
  done
}
echo "+ (network namespaces $NS_SW, $(ns_of h1), $(ns_of h2), $(ns_of d); bridge br0; 10.77.0.1-3/24)"
if ! setup 2>"$tmp/netns.err"; then
  teardown
  skip "multi-host test: cannot create network namespaces ($(head -n 1 "$tmp/netns.err"))"
fi
trap 'teardown; cleanup' EXIT

# The rsh agent: "agent [options] HOST COMMAND..." runs COMMAND in HOST's namespace.
cat >"$tmp/agent" <<AGENT
#!/bin/bash
while [[ \$1 == -* ]]; do shift; done
host=\$1; shift
case \$host in
  10.77.0.1) ns=$(ns_of h1); hn=h1 ;;
  10.77.0.2) ns=$(ns_of h2); hn=h2 ;;
  *) echo "agent: unknown host \$host" >&2; exit 1 ;;
esac
exec ip netns exec \$ns unshare --uts /bin/sh -c "hostname \$hn; \$*"
AGENT
chmod +x "$tmp/agent"
echo "+ cat $tmp/agent"; sed 's/^/  /' "$tmp/agent"

cornell_args
head -c 32 /dev/urandom | base64 >"$tmp/token"; chmod 600 "$tmp/token"
K=1000
PATHF=(--path "$root/scenes/cornell/walk.path" --frames 5)

# One host: the comparison frames.
# Both jobs send the display at most one texel a pixel (TCP's default, not
# a UNIX socket's): the display's textures must be the same to compare.
master_start local 3 "${CORNELL[@]}" --listen "unix:$tmp/local.sock" --exit-when-display-leaves --display-texels screen
master_wait_listen local || finish
display_run local_display --connect "$ADDR" "${HEADLESS[@]}" --samples-per-frame $K "${PATHF[@]}" --out "$tmp/local"
master_wait local 20 || fail "the one-host job did not end"

# Two hosts. mpirun runs inside h1 (as the head node), the display inside d.
MPIRUN_EXTRA="--host 10.77.0.1:1,10.77.0.2:2 --mca plm_rsh_agent $tmp/agent --mca btl tcp,self \
--mca btl_tcp_if_include 10.77.0.0/24 --mca oob_tcp_if_include 10.77.0.0/24"
mpi_cmd 3 "${CORNELL[@]}" --listen tcp:10.77.0.1:0 --token-file "$tmp/token" --exit-when-display-leaves --verbose \
  --display-texels screen
cmd=(ip netns exec "$(ns_of h1)" unshare --uts /bin/sh -c 'hostname h1; exec "$@"' sh env "${MPI_ENV[@]}" "${MPI_CMD[@]}")
log_cmd "${cmd[@]}"
"${cmd[@]}" >"$tmp/job.log" 2>&1 &
MASTER_PID[job]=$!
master_wait_listen job || finish
[[ $ADDR == tcp:10.77.0.1:* ]] || fail "listening on $ADDR"
log_cmd ip netns exec "$(ns_of d)" "$display" --connect "$ADDR" --token-file "$tmp/token" "${HEADLESS[@]}" \
  --samples-per-frame $K "${PATHF[@]}" --out "$tmp/out"
timeout 60 ip netns exec "$(ns_of d)" "$display" --connect "$ADDR" --token-file "$tmp/token" "${HEADLESS[@]}" \
  --samples-per-frame $K "${PATHF[@]}" --out "$tmp/out" >"$tmp/display.log" 2>&1 || fail "display exit status $?"
sed 's/^/  display: /' "$tmp/display.log" | tail -n 5
master_wait job 30 || fail "the two-host job did not end"
((MASTER_RC == 0)) || fail "two-host job exit status $MASTER_RC"
master_log job | grep -v -e progress -e 'debug ctex' -e 'debug master: camera' | tail -n 14
grep -q 'tracer rank 1 on h2 ready' "$tmp/job.log" && grep -q 'tracer rank 2 on h2 ready' "$tmp/job.log" ||
  fail "the tracers did not run on host h2"
grep -q 'display tcp:10.77.0.3:[0-9]* connected' "$tmp/job.log" || fail "the display did not connect from 10.77.0.3"
same_frames local out "between one and two hosts"
echo "metric: $same of 5 frames bit-identical on one host and on two (namespaces, TCP)"
finish
