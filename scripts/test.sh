#!/usr/bin/env bash
# The test command (README, .ci/run): one release build, reused by every test.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
cargo test --release --locked
