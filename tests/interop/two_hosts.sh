#!/usr/bin/env bash
# Two "hosts" on one machine: two network namespaces this script creates, joined by a
# veth pair with multicast off (a factory network that blocks it), 10.213.0.1/24 in
# host A and 10.213.0.2/24 in host B. The addresses exist only on the veth ends inside
# the namespaces; there is no route anywhere else, so nothing leaves the machine. Both
# namespaces (and with them the veth pair) are removed on exit, whatever happens.
#
#   tests/interop/two_hosts.sh CMD [ARGS...]
#
# CMD runs in the caller's namespace with TRACER_HOST_A / TRACER_HOST_B set to the
# namespace names and TRACER_ADDR_A / TRACER_ADDR_B to the addresses; it starts
# processes in a host with `ip netns exec "$TRACER_HOST_A" ...`. Needs root.
set -euo pipefail
if [ "$#" -eq 0 ]; then
    echo "usage: $0 CMD [ARGS...]" >&2
    exit 2
fi
if [ "$(id -u)" -ne 0 ]; then
    echo "two_hosts.sh: needs root (ip netns)" >&2
    exit 77
fi
A="tc13a_$$"
B="tc13b_$$"
cleanup() {
    ip netns del "$A" 2>/dev/null || true
    ip netns del "$B" 2>/dev/null || true
}
trap cleanup EXIT
ip netns add "$A"
ip netns add "$B"
ip link add "vA$$" netns "$A" type veth peer name "vB$$" netns "$B"
ip -n "$A" link set lo up
ip -n "$B" link set lo up
ip -n "$A" link set "vA$$" multicast off
ip -n "$B" link set "vB$$" multicast off
ip -n "$A" addr add 10.213.0.1/24 dev "vA$$"
ip -n "$B" addr add 10.213.0.2/24 dev "vB$$"
ip -n "$A" link set "vA$$" up
ip -n "$B" link set "vB$$" up
# Only lo and the veth end in each host, and no route beyond 10.213.0.0/24.
for ns in "$A" "$B"; do
    if ip -n "$ns" route show | grep -v '^10\.213\.0\.0/24 ' | grep -q .; then
        echo "two_hosts.sh: unexpected route in $ns:" >&2
        ip -n "$ns" route show >&2
        exit 125
    fi
done
export TRACER_HOST_A="$A" TRACER_HOST_B="$B" TRACER_ADDR_A=10.213.0.1 TRACER_ADDR_B=10.213.0.2
"$@"
