#!/usr/bin/env bash
# The main job: build once (release) and run the demo, a simulated edging cell talking to
# tracer_calib_node over DDS (localhost only, its own domain). Arguments go to
# `tracer_calib demo` (see --help), e.g. --seed 7 --plot fit.svg.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --bins --quiet
. scripts/target_dir.sh
exec "$TRACER_RELEASE_DIR/tracer_calib" demo "$@"
