#!/usr/bin/env bash
# The real-ROS-2-peer tests: sets up rclpy + tracer_calib_msgs (tests/interop/setup.sh,
# quick when up to date), then runs against the release binaries:
#   - tests/interop/test_node.py inside a private network namespace (nothing leaves
#     the machine);
#   - tests/interop/test_graph.py, the node in the ROS graph (leaving it, matching, QoS),
#     in a private network namespace too;
#   - tests/interop/test_two_hosts.py on two "hosts", network namespaces joined by a
#     veth pair with multicast off (tests/interop/two_hosts.sh; root only).
#   tests/interop/run.sh [TEST_NAME...]
# Names starting with graph select test_graph.py's tests (graph: all), two_hosts
# test_two_hosts.py's scenarios (two_hosts: all); the others, test_node.py's tests.
# No names: everything.
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
node_tests=() graph=() two_hosts=()
for a in "$@"; do
    case "$a" in
        graph*) graph+=("$a") ;;
        two_hosts*) two_hosts+=("$a") ;;
        *) node_tests+=("$a") ;;
    esac
done
if [ "$#" -eq 0 ] || [ "${#node_tests[@]}" -gt 0 ]; then
    # shellcheck disable=SC2016
    "$HERE/netns.sh" bash -c '
        . "$1/target/ros/env.sh"
        shift
        exec timeout -s KILL 600 python "$0" "$@"
    ' "$HERE/test_node.py" "$ROOT" ${node_tests[@]+"${node_tests[@]}"}
fi
if [ "$#" -eq 0 ] || [ "${#graph[@]}" -gt 0 ]; then
    # shellcheck disable=SC2016
    "$HERE/netns.sh" bash -c '
        . "$1/target/ros/env.sh"
        shift
        exec timeout -s KILL 600 python "$0" "$@"
    ' "$HERE/test_graph.py" "$ROOT" ${graph[@]+"${graph[@]}"}
fi
if [ "$#" -eq 0 ] || [ "${#two_hosts[@]}" -gt 0 ]; then
    if [ "$(id -u)" -ne 0 ]; then
        echo "interop: two_hosts skipped (needs root for ip netns)"
    else
        # shellcheck disable=SC2016
        "$HERE/two_hosts.sh" bash -c '
            . "$1/target/ros/env.sh"
            shift
            exec timeout -s KILL 600 python "$0" "$@"
        ' "$HERE/test_two_hosts.py" "$ROOT" ${two_hosts[@]+"${two_hosts[@]}"}
    fi
fi
