#!/usr/bin/env bash
# The main job: build once (release) and run the demo, a simulated edging cell talking to
# tracer_calib_node over DDS (localhost only, its own domain). Arguments go to
# `tracer_calib demo` (see --help), e.g. --seed 7 --plot fit.svg.
set -euo pipefail
cd "$(dirname "$0")/.."
# Cargo's own progress line shows what is being built: a first build compiles several hundred
# crates (BENCHMARKS.md, "Release build from empty"), later ones reuse them (seconds).
echo "demo.sh: building tracer_calib and tracer_calib_node (release)..." >&2
cargo build --release --bins
. scripts/target_dir.sh
exec "$TRACER_RELEASE_DIR/tracer_calib" demo "$@"
