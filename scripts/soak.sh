#!/usr/bin/env bash
# Soak: 10^5 scans through the node at the rate it sustains, calibrate calls
# interleaved; RSS, throughput, every scan accounted for (BENCHMARKS.md).
# Runs in a private network namespace: nothing leaves the machine. Bounded: the
# harness stops by itself (at most a few minutes on this machine).
#   bash scripts/soak.sh [SCANS] [WINDOW] [RATE]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --bins --example soak
. scripts/target_dir.sh
TRACER_CALIB_NODE=$TRACER_RELEASE_DIR/tracer_calib_node timeout -s KILL 1200 tests/interop/netns.sh "$TRACER_RELEASE_DIR/examples/soak" "$@"
