#!/usr/bin/env bash
# Builds this repository as a ROS 2 colcon workspace, the way an integrator does
# (README, "In a cell, quickly"; docs/workspace.md), for one ROS 2 distribution, and checks what it installs:
#
#   target/tools/colcon/              colcon + colcon-ros-cargo (+ the cargo-ament-build wheel)
#                                     from PyPI, pinned by requirements-colcon.lock
#   target/colcon_ws/DISTRO/src/tracer_calib  the repository: for jazzy a copy of its files
#                                     (as an integrator's clone: cargo then sees the
#                                     workspace's .cargo/config.toml that colcon-ros-cargo
#                                     writes), for kilted a symlink
#   target/colcon_ws/DISTRO/install/  what the README's `colcon build` line installs
#
# The underlay, in place of `source /opt/ros/DISTRO/setup.bash`, is the PyPI wheels' venv
# (target/ros/DISTRO/ros_setup.sh, written by tests/interop/setup.sh, which this runs).
# The `colcon build` line is read from README.md (the first line starting with
# `colcon build`) and run as it stands, in the workspace.
#
# The cargo build of tracer_calib reuses the repository's release build: the package's
# colcon build directory (build/tracer_calib, which colcon-ros-cargo passes to cargo as
# --target-dir) is a symlink to cargo's target directory of the repository (target/, or
# wherever CARGO_TARGET_DIR or a cargo config puts it: scripts/target_dir.sh), so
# `cargo build --release` finds the dependencies built already (CI builds them once; from a copy, cargo compiles
# the repository's own crates, tracer_calib and vendor/, again, once per copy).
# TRACER_WS_FRESH_TARGET=1 builds into a directory of its own instead, as an integrator's
# workspace does.
#
# Also checks the bad input: the same build with no ROS sourced fails with one line that
# says what to do.
#
#   tests/interop/workspace.sh DISTRO     (kilted or jazzy)
# Prints one line per step with its time; logs in target/colcon_ws/DISTRO/*.log.
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$HERE/lib.sh"
DISTRO=${1:?usage: $0 kilted|jazzy}
case "$DISTRO" in kilted|jazzy) ;; *) echo "usage: $0 kilted|jazzy" >&2; exit 2 ;; esac
TOOLS=$ROOT/target/tools
COLCON_VENV=$TOOLS/colcon
WS=$ROOT/target/colcon_ws/$DISTRO
ROS_SETUP=$ROOT/target/ros/$DISTRO/ros_setup.sh
. "$ROOT/scripts/target_dir.sh"

step_done() {
    local ms=$(( $(now_ms) - $3 ))
    printf 'workspace.sh: %-7s%-12s %-9s %4d.%01ds\n' "$DISTRO" "$1" "$2" $(( ms / 1000 )) $(( (ms % 1000) / 100 ))
}
die() { echo "workspace.sh: $DISTRO: error: $*" >&2; exit 1; }
show_log() { echo "workspace.sh: --- last lines of $1 ---" >&2; tail -n 40 "$1" >&2 || true; }

"$HERE/setup.sh" "$DISTRO" >/dev/null
mkdir -p "$TOOLS" "$WS/src"

# 1. colcon: its own venv, shared by the distributions; remade when its pins change.
t0=$(now_ms)
exec 8>"$TOOLS/.colcon.lock"
command -v flock >/dev/null 2>&1 && flock 8
PY=$(command -v python3.11 || command -v python3)
KEY=$({ cat "$HERE/requirements-colcon.txt" "$HERE/requirements-colcon.lock"; "$PY" --version; } | sha256sum | cut -c1-64)
if [ -f "$COLCON_VENV/.stamp" ] && [ "$(cat "$COLCON_VENV/.stamp")" = "$KEY" ] && [ -x "$COLCON_VENV/bin/colcon" ]; then
    step_done colcon skipped "$t0"
else
    rm -rf "$COLCON_VENV"
    "$PY" -m venv "$COLCON_VENV"
    if ! "$COLCON_VENV/bin/python" -m pip install --disable-pip-version-check --no-input \
            -r "$HERE/requirements-colcon.txt" -c "$HERE/requirements-colcon.lock" >"$TOOLS/colcon-pip.log" 2>&1; then
        show_log "$TOOLS/colcon-pip.log"
        die "pip install of colcon into $COLCON_VENV failed"
    fi
    echo "$KEY" >"$COLCON_VENV/.stamp"
    step_done colcon installed "$t0"
fi
exec 8>&-

# 2. the workspace: src/tracer_calib is this repository (its files as they are now, less
#    target/ (and cargo's target directory, if it is in the repository elsewhere) and .git/;
#    modification times kept, so an unchanged copy builds nothing).
if [ "$DISTRO" = jazzy ]; then
    excludes=(--exclude=./target --exclude=./.git --exclude=./fuzz/target --exclude=__pycache__)
    case "$TRACER_TARGET_DIR" in "$ROOT"/*) excludes+=("--exclude=./${TRACER_TARGET_DIR#"$ROOT"/}") ;; esac
    tar -C "$ROOT" "${excludes[@]}" -cf "$WS/src.tar" .
    key=$(sha256sum <"$WS/src.tar" | cut -c1-64)
    if [ -L "$WS/src/tracer_calib" ] || [ "$(cat "$WS/src.stamp" 2>/dev/null)" != "$key" ]; then
        rm -rf "$WS/src/tracer_calib" "$WS/src.stamp"
        mkdir -p "$WS/src/tracer_calib"
        tar -C "$WS/src/tracer_calib" -xf "$WS/src.tar"
        echo "$key" >"$WS/src.stamp"
    fi
    rm -f "$WS/src.tar"
else
    [ -L "$WS/src/tracer_calib" ] || rm -rf "$WS/src/tracer_calib"
    ln -sfn "$ROOT" "$WS/src/tracer_calib"
fi
if [ "${TRACER_WS_FRESH_TARGET:-0}" = 1 ]; then
    [ -L "$WS/build/tracer_calib" ] && rm -f "$WS/build/tracer_calib"
else
    mkdir -p "$WS/build"
    [ -e "$WS/build/tracer_calib" ] && [ ! -L "$WS/build/tracer_calib" ] && rm -rf "$WS/build/tracer_calib"
    ln -sfn "$TRACER_TARGET_DIR" "$WS/build/tracer_calib"
fi
LINE=$(grep -m 1 '^colcon build' "$ROOT/README.md") || die "README.md has no line starting with 'colcon build'"

# The environment of a shell that sourced the ROS 2 setup: ros_setup.sh, colcon on PATH.
in_ros_env() {
    env -i HOME="$HOME" PATH="$COLCON_VENV/bin:$PATH" TERM=dumb ${CARGO_HOME:+CARGO_HOME="$CARGO_HOME"} \
        ${RUSTUP_HOME:+RUSTUP_HOME="$RUSTUP_HOME"} ${RUSTUP_TOOLCHAIN:+RUSTUP_TOOLCHAIN="$RUSTUP_TOOLCHAIN"} \
        bash -c '. "$1"; shift; cd "$1"; shift; eval "$*"' in_ros_env "$ROS_SETUP" "$@"
}

# 3. bad input: no ROS sourced (cmake on PATH, as on any build machine: the one the pip
#    cmake wheel ships). colcon only configures msg/, so it is quick.
t0=$(now_ms)
rm -rf "$WS/noros"
mkdir -p "$WS/noros"
CMAKE_BIN=$ROOT/target/ros/$DISTRO/venv/lib/python3.11/site-packages/cmake/data/bin
set +e
env -i HOME="$HOME" PATH="$COLCON_VENV/bin:$CMAKE_BIN:$PATH" TERM=dumb bash -c \
    'cd "$1" && colcon --log-base noros/log build --base-paths src/tracer_calib/msg --build-base noros/build --install-base noros/install' \
    noros "$WS" >"$WS/noros.log" 2>&1
rc=$?
set -e
want="tracer_calib_msgs: no ROS 2 environment (AMENT_PREFIX_PATH is empty): source your ROS 2 installation first"
[ "$rc" != 0 ] || { show_log "$WS/noros.log"; die "the build without a sourced ROS succeeded"; }
n=$(grep -c -F "$want" "$WS/noros.log" || true)
[ "$n" -ge 1 ] || { show_log "$WS/noros.log"; die "the build without a sourced ROS did not say: $want"; }
# Other cmake errors than ours (find_package, rosidl) would show as more 'CMake Error' lines.
[ "$(grep -c 'CMake Error' "$WS/noros.log")" = 1 ] || { show_log "$WS/noros.log"; die "more than one CMake error without a sourced ROS"; }
rm -rf "$WS/noros"
step_done no-ros "failed ok" "$t0"

# 4. the README's colcon build line, in the workspace, with the ROS underlay sourced.
t0=$(now_ms)
if ! in_ros_env "$WS" "nice -n 10 $LINE" >"$WS/build.log" 2>&1; then
    show_log "$WS/build.log"
    die "'$LINE' failed in $WS (log: $WS/build.log)"
fi
# colcon leaves its bookkeeping in each package's build directory: here cargo's target
# directory (the symlink), where it has no business.
rm -f "$TRACER_TARGET_DIR/colcon_build.rc" "$TRACER_TARGET_DIR/colcon_command_prefix_build.sh" \
    "$TRACER_TARGET_DIR/colcon_command_prefix_build.sh.env"
step_done "colcon build" built "$t0"

# 4b. the same line again, in a shell where the workspace is sourced as well (what an
#     integrator does after a change): builds nothing new, changes nothing in the sources.
t0=$(now_ms)
if ! in_ros_env "$WS" ". install/setup.bash; $LINE" >"$WS/rebuild.log" 2>&1; then
    show_log "$WS/rebuild.log"
    die "'$LINE' failed the second time, with install/setup.bash sourced (log: $WS/rebuild.log)"
fi
if [ ! -L "$WS/src/tracer_calib" ] && ! cmp -s "$ROOT/Cargo.lock" "$WS/src/tracer_calib/Cargo.lock"; then
    die "the rebuild changed src/tracer_calib/Cargo.lock"
fi
rm -f "$TRACER_TARGET_DIR/colcon_build.rc" "$TRACER_TARGET_DIR/colcon_command_prefix_build.sh" \
    "$TRACER_TARGET_DIR/colcon_command_prefix_build.sh.env"
step_done rebuild built "$t0"

# 5. what it installed: as the README and CONTRACT say, and found through the ament index
#    the way `ros2 run` / `ros2 launch` find them.
t0=$(now_ms)
I=$WS/install
for f in tracer_calib/lib/tracer_calib/tracer_calib_node tracer_calib/lib/tracer_calib/tracer_calib; do
    [ -x "$I/$f" ] || die "not installed: $I/$f"
done
for f in tracer_calib/share/tracer_calib/package.xml tracer_calib/share/tracer_calib/config/tracer_calib.yaml \
         tracer_calib/share/tracer_calib/config/cell1_tracer.yaml tracer_calib/share/tracer_calib/config/cell2_tracer.yaml \
         tracer_calib/share/tracer_calib/config/tracer_calib_analyzers.yaml tracer_calib/share/tracer_calib/config/tracer_calib.rviz \
         tracer_calib/share/tracer_calib/launch/tracer_calib.launch.xml tracer_calib/share/tracer_calib/launch/edging_cell.launch.xml \
         tracer_calib/share/tracer_calib/launch/tracer_calib_managed.launch.xml \
         tracer_calib/share/ament_index/resource_index/packages/tracer_calib \
         tracer_calib_msgs/share/ament_index/resource_index/packages/tracer_calib_msgs \
         tracer_calib_msgs/share/tracer_calib_msgs/srv/Calibrate.srv \
         setup.bash; do
    [ -e "$I/$f" ] || die "not installed: $I/$f"
done
# (`ros2 run` and `ros2 launch` themselves: test_launch.py.)
out=$(in_ros_env "$WS" ". install/setup.bash; python -c 'from ament_index_python.packages import get_package_prefix as p; print(p(\"tracer_calib\"))'" 2>&1) ||
    die "the ament index does not find tracer_calib: $out"
[ "$out" = "$I/tracer_calib" ] || die "the ament index finds tracer_calib at $out"
# The crate's [patch.crates-io] path entries (vendor/...) were honoured: the node was built
# from the workspace copy's vendor/ sources (cargo's dep-info lists every source file).
if [ ! -L "$WS/src/tracer_calib" ]; then
    while read -r dir; do
        grep -q -F "$WS/src/tracer_calib/$dir/" "$WS/build/tracer_calib/release/tracer_calib_node.d" ||
            die "the node was not built from src/tracer_calib/$dir ([patch.crates-io] not honoured)"
    done < <(sed -n '/^\[patch\.crates-io\]/,/^\[/s/.*path *= *"\(vendor\/[^"]*\)".*/\1/p' "$ROOT/Cargo.toml")
fi
step_done installed checked "$t0"
