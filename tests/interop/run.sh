#!/usr/bin/env bash
# The real-ROS-2-peer tests: sets up rclpy + tracer_calib_msgs (tests/interop/setup.sh,
# quick when up to date), then runs tests/interop/test_node.py against the release
# binaries inside a private network namespace (nothing leaves the machine).
#   tests/interop/run.sh [TEST_NAME...]
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
"$HERE/setup.sh" >/dev/null
trap '"$HERE/shm_clean.sh" >/dev/null 2>&1 || true' EXIT
export TRACER_CALIB_NODE="$ROOT/target/release/tracer_calib_node"
export TRACER_CALIB="$ROOT/target/release/tracer_calib"
for b in "$TRACER_CALIB_NODE" "$TRACER_CALIB"; do
    [ -x "$b" ] || { echo "missing $b: run 'cargo build --release' first" >&2; exit 2; }
done
# shellcheck disable=SC2016
"$HERE/netns.sh" bash -c '
    . "$1/target/ros/env.sh"
    shift
    exec timeout -s KILL 600 python "$0" "$@"
' "$HERE/test_node.py" "$ROOT" "$@"
