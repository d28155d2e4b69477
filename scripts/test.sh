#!/usr/bin/env bash
# The test command (README, .ci/run). One release build, reused by every step:
#   1. the Rust tests (unit, engine, node over DDS), inside a private network namespace;
#   2. the real ROS 2 peer: rclpy (Kilted, Fast DDS) from PyPI wheels and the message
#      package built by rosidl (tests/interop/setup.sh installs both), against the node.
# Nothing sends a packet off this machine: every DDS participant runs in a network
# namespace whose only interface is loopback (tests/interop/netns.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
cargo build --release --locked --bins
cargo test --release --locked --no-run
# The Python peer (rclpy, rosbags) from PyPI: before the Rust tests, which use rosbags
# to read the bags we write. Needs the package registries, so outside the namespace.
tests/interop/setup.sh
tests/interop/netns.sh cargo test --release --locked --offline
bash tests/interop/run.sh
