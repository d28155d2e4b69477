#!/usr/bin/env bash
# The node and a stock rclpy node in its place, side by side under UDP loss
# (BENCHMARKS.md, "A lossy network"): each scenario of tests/interop/test_lossy.py in a
# network namespace of its own whose loopback drops LOSS % of the UDP datagrams (nftables);
# nothing leaves the machine. Needs the release binaries and the peers of the test command
# (tests/interop/setup.sh DISTRO; tests/interop/cyclone.sh jazzy for the Cyclone DDS peers).
#   bash scripts/bench_lossy.sh [DISTRO [SCANS [RMWS [LOSSES [VARIANT]]]]]
#   defaults: jazzy, 200 scans, "fastdds cyclone", "0 5 10 25", none
#   VARIANT: delay, mtu1500 (DDS), keepall (keep all on both sides; zenoh: Block, not Drop),
#   rtomax1s (zenoh: TCP's retransmission timeout at most 1 s, net.ipv4.tcp_rto_max_ms)
# Prints one line per scenario (contours back, latency p50/p99/max, calls, parameter
# requests, the latched calibration, discovery, datagrams dropped).
# REPEAT=N runs each scenario N times (stock node and node in turn) and ends with a tally
# per scenario and server: runs with every contour, call, parameter request and the latched
# calibration through; contours lost and calls unanswered per failed run; p50 and max
# latency over the runs; TCP retransmission timeouts (Zenoh).
set -euo pipefail
cd "$(dirname "$0")/.."
DISTRO=${1:-jazzy}
export LOSSY_SCANS=${2:-200}
RMWS=${3:-fastdds cyclone}
LOSSES=${4:-0 5 10 25}
VARIANT=${5:-}
. scripts/target_dir.sh
export TRACER_CALIB_NODE="$TRACER_RELEASE_DIR/tracer_calib_node" TRACER_CALIB="$TRACER_RELEASE_DIR/tracer_calib"
[ -x "$TRACER_CALIB_NODE" ] || { echo "bench_lossy.sh: build first: cargo build --release --features security --bins" >&2; exit 2; }
command -v nft >/dev/null || { echo "bench_lossy.sh: needs nft (apt-get install nftables)" >&2; exit 2; }
# shellcheck disable=SC1090
. "target/ros/$DISTRO/env.sh"
RESULTS=$(mktemp)
trap 'rm -f "$RESULTS"' EXIT
for rmw in $RMWS; do
    for loss in $LOSSES; do
        for _ in $(seq "${REPEAT:-1}"); do
            for server in stock node; do
                if out=$(LOSSY_RUN="$server $rmw $loss $VARIANT" timeout -s KILL 600 python3 tests/interop/test_lossy.py); then
                    grep -v '^{' <<<"$out" || true
                    grep '^{' <<<"$out" | sed "s/^{/{\"rmw\": \"$rmw\", \"variant\": \"$VARIANT\", /" >>"$RESULTS" || true
                else
                    echo "$server $rmw $loss % $VARIANT: failed"
                    echo "{\"rmw\": \"$rmw\", \"variant\": \"$VARIANT\", \"server\": \"$server\", \"loss\": $loss, \"failed\": true}" >>"$RESULTS"
                fi
            done
        done
    done
done
[ "${REPEAT:-1}" -gt 1 ] && python3 scripts/lossy_tally.py "$RESULTS"
exit 0
