#!/usr/bin/env bash
# Node latency against a bare rustdds relay, and the node's RSS (BENCHMARKS.md).
# Runs in a private network namespace: nothing leaves the machine.
#   bash scripts/bench_latency.sh [ITERATIONS]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --bins --example latency
. scripts/target_dir.sh
TRACER_CALIB_NODE=$TRACER_RELEASE_DIR/tracer_calib_node tests/interop/netns.sh "$TRACER_RELEASE_DIR/examples/latency" "$@"
