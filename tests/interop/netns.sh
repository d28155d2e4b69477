#!/usr/bin/env bash
# Run a command in a fresh, private network namespace whose only interface is
# the loopback `lo` (brought up here). Nothing the command sends can leave the
# machine; processes started inside the same call (children of CMD) share the
# namespace and can talk to each other over 127.0.0.1.
#
#   tests/interop/netns.sh CMD [ARGS...]
#   tests/interop/netns.sh bash -c 'peer_a & peer_b; wait'
#
# Root uses `unshare --net`; other users get a user namespace as well
# (`unshare --user --map-root-user --net`), where the kernel allows it.
# The exit status is CMD's. Only the network is private: the filesystem,
# /dev/shm and process ids are shared with the host.
set -euo pipefail

if [ "$#" -eq 0 ]; then
    echo "usage: $0 CMD [ARGS...]" >&2
    exit 2
fi

if [ "$(id -u)" -eq 0 ]; then
    unshare_args=(--net)
else
    unshare_args=(--user --map-root-user --net)
fi

# Inside: bring lo up, refuse to run if any other interface exists, then exec CMD.
# shellcheck disable=SC2016
exec unshare "${unshare_args[@]}" -- bash -c '
    set -euo pipefail
    if command -v ip >/dev/null 2>&1; then
        ip link set lo up
    else
        python3 - <<"EOF"
import fcntl, socket, struct
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
req = struct.pack("16sH22x", b"lo", 0)
flags = struct.unpack("16sH22x", fcntl.ioctl(s, 0x8913, req))[1]  # SIOCGIFFLAGS
fcntl.ioctl(s, 0x8914, struct.pack("16sH22x", b"lo", flags | 1))  # SIOCSIFFLAGS, IFF_UP
EOF
    fi
    # /proc/net/dev is per network namespace (/sys/class/net is not, without a remount).
    ifaces=$(awk -F: "NR > 2 { gsub(/ /, \"\", \$1); print \$1 }" /proc/net/dev)
    if [ "$ifaces" != lo ]; then
        echo "netns.sh: expected only lo in the private namespace, found: $ifaces" >&2
        exit 125
    fi
    export TRACER_NETNS=1
    exec "$@"
' netns.sh "$@"
