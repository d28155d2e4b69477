# shellcheck shell=bash
# Sourced, not run, by scripts/*.sh and tests/interop/*.sh:  . scripts/target_dir.sh
# Sets and exports where cargo puts this repository's builds, as cargo itself resolves it
# (CARGO_TARGET_DIR, else build.target-dir of a cargo config, else target/):
#   TRACER_TARGET_DIR   cargo's target directory (absolute)
#   TRACER_RELEASE_DIR  $TRACER_TARGET_DIR/release: the release binaries, examples/ below
# What the scripts make themselves is not cargo's and stays in this repository's own
# target/, whatever cargo's is: the ROS 2 peers (target/ros), colcon (target/tools), the
# colcon workspaces (target/colcon_ws), the scipy venv and results (target/bench).
_tracer_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
TRACER_TARGET_DIR=$(cd "$_tracer_root" && cargo metadata --format-version 1 --no-deps --offline |
    sed -n 's/.*"target_directory":"\([^"\\]*\)".*/\1/p')
if [ -z "$TRACER_TARGET_DIR" ]; then
    echo "target_dir.sh: cargo metadata gave no target directory for $_tracer_root" >&2
    exit 2
fi
TRACER_RELEASE_DIR=$TRACER_TARGET_DIR/release
export TRACER_TARGET_DIR TRACER_RELEASE_DIR
unset _tracer_root
