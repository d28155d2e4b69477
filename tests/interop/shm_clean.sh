#!/usr/bin/env bash
# Remove stale Fast DDS shared-memory files (/dev/shm/fastdds_*) left by killed peers.
# Only files whose lock is no longer held are removed (`fastdds shm clean`), so Fast DDS
# processes still running, e.g. another test run, are not disturbed. Quiet unless
# something was cleaned. With the loopback profile of target/ros/env.sh (UDPv4 only) the
# peers make no such files; a peer run without that profile uses shared memory.
set -euo pipefail
ROS_DIR=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)/target/ros
compgen -G '/dev/shm/fastdds_*' >/dev/null || exit 0
[ -f "$ROS_DIR/env.sh" ] || { echo "shm_clean.sh: run tests/interop/setup.sh first" >&2; exit 1; }
# shellcheck disable=SC1091
. "$ROS_DIR/env.sh"
out=$(timeout -s KILL 30 fastdds shm clean 2>&1) || { echo "$out" >&2; exit 1; }
echo "$out" | grep -E '[1-9][0-9]* zombie' | sed 's/^/shm_clean.sh: /' || true
