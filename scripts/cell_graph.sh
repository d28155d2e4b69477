#!/usr/bin/env bash
# A cell graph of N tracers (BENCHMARKS.md): N tracer_calib_node processes in
# /cell1 ... /cellN and one rclpy planner calling every /cellK/calibrate and taking every
# /cellK/contour; discovery time, CPU and RSS per node, every scan and call answered.
# Runs in a private network namespace: nothing leaves the machine.
#   bash scripts/cell_graph.sh [N...]          (default: 1 5 10)
# SCANS (default 50) lens scans per cell at RATE (default 5) Hz each, all cells at once;
# CELL_STAGGER=S starts the nodes S seconds apart (default 0: all at once);
# CELL_PLANNER_HEAD_START=S starts the planner S seconds before them (default 1; 0: together).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --bins
. scripts/target_dir.sh
tests/interop/setup.sh >/dev/null
trap 'tests/interop/shm_clean.sh >/dev/null 2>&1 || true' EXIT
export TRACER_CALIB_NODE="$TRACER_RELEASE_DIR/tracer_calib_node" TRACER_CALIB="$TRACER_RELEASE_DIR/tracer_calib"
status=0
for n in "${@:-1 5 10}"; do
    for k in $n; do
        # shellcheck disable=SC2016
        tests/interop/netns.sh bash -c '. target/ros/env.sh; exec timeout -s KILL 600 python tests/interop/cell_graph.py "$@"' \
            cell_graph "$k" "${SCANS:-50}" "${RATE:-5}" || status=1
    done
done
exit $status
