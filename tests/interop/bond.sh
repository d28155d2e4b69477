#!/usr/bin/env bash
# The stock bond (bond_core: the `bond` messages, smclib's Python part, bondpy) for a
# distribution's wheel venv: nav2's lifecycle manager forms a bond (bond/msg/Status
# heartbeats on the `bond` topic) with every node it manages; an rclpy process with this
# environment can play either side of it with the stock bondpy.
#
#   tests/interop/bond.sh [--force] DISTRO...     (after tests/interop/setup.sh DISTRO)
#
# From ../shared/ros2-src/bond_core.tar.gz (or $TRACER_ROS2_SRC; ros/bond_core at
# e6d0fc2c, 4.0.0 + bondpy's ROS 2 port), checked against ros2-sources.lock:
#   - bond_core/bond (ROS 2 package `bond`: msg/Status, msg/Constants) built with plain
#     cmake + rosidl against target/ros/DISTRO/venv, the way setup.sh builds msg/
#     (AMENT_PREFIX_PATH and CMAKE_PREFIX_PATH = the venv, Python3_EXECUTABLE = its python,
#     BUILD_TESTING=OFF: no linters);
#   - bond_core/smclib/smclib/*.py and bond_core/bondpy/bondpy/*.py copied (no pip, no
#     network) into the same prefix's site-packages, with their ament index entries
#     (smclib's C++ header and bondcpp are not built: nothing here needs them).
# apt: nothing (what setup.sh installs is enough). Everything lands in a cache outside
# the clone:
#
#   ${TRACER_CACHE:-~/.cache/tracer_calib}/bond-<KEY>-DISTRO/
#       install/lib/libbond__rosidl_*.so                 the message libraries
#       install/lib/python3.11/site-packages/bond/       bond.msg (Status, Constants)
#       install/lib/python3.11/site-packages/smclib/     smclib.statemap
#       install/lib/python3.11/site-packages/bondpy/     bondpy.bondpy.Bond
#       install/share/bond/msg/Status.json               its type description (type hash)
#       key                                              what it was built from
#
# KEY: the sha256 of the tarball's sha256, the venv's lock file (kilted:
# requirements.lock, jazzy: requirements-jazzy.lock), the recipe (RECIPE below) and the distribution.
# A fresh build takes well under a minute on 2 cores; a rerun with all of those unchanged
# reuses it (a fraction of a second); `--force` rebuilds. The build runs in a temporary
# directory beside the cache and is moved into place when complete: an interrupted build
# leaves no half cache. Then it writes
#
#   target/ros/DISTRO/bond_env.sh   source it AFTER target/ros/DISTRO/env.sh: puts the
#                                   prefix on PYTHONPATH, LD_LIBRARY_PATH and
#                                   AMENT_PREFIX_PATH (`from bondpy.bondpy import Bond`)
#
# Prints one line per distribution with its time. Exit status 0 when every distribution
# given has a working build; a failed build says why (log kept in the cache's parent).
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$HERE/lib.sh"

parse_peer_args 40 "$@"
T_START=$(now_ms)
# The source, checked against ros2-sources.lock (downloaded by its hash if absent).
TARBALL=$(python3 "$ROOT/scripts/ros2_sources.py" path bond_core) || exit

# Work in a clean environment even when a target/ros/*/env.sh is sourced in this shell.
clean_ros_env

TAR_SHA=$(sha256sum "$TARBALL" | cut -c1-64)
# Bump when the way it is built changes (the cache key says which recipe built it).
RECIPE=1

# build_bond WORK: bond_core's bond messages (rosidl, cmake, against VENV), smclib and bondpy
# (plain copies, as ament_python would) from TARBALL into WORK/install, configured for
# their place in the cache, CACHE/install (cached_build's BUILD). Not while setup.sh
# remakes the venv (the lock it takes).
build_bond() (
    work=$1
    P=$CACHE/install
    exec 9>"$ROOT/target/ros/.setup.lock"
    flock 9
    mkdir -p "$work/src" && tar -xzf "$TARBALL" -C "$work/src" || exit
    S=$work/src/bond_core
    # Configured for the final prefix, installed under DESTDIR: the files ament writes
    # with the prefix in them name the place they end up in.
    D=$work/destdir
    # As setup.sh builds msg/. Fix: AMENT_PREFIX_PATH must name the venv while
    # configuring, or rosidl finds no type support ("No 'rosidl_typesupport_c' found").
    export PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" _ROS_WHEELS_BOOTSTRAP_COMPLETE=
    set -x
    nice -n 10 cmake -S "$S/bond" -B "$work/build" \
        -DCMAKE_PREFIX_PATH="$VENV" \
        -DPython3_EXECUTABLE="$VENV/bin/python" \
        -DBUILD_TESTING=OFF \
        -DCMAKE_INSTALL_PREFIX="$P" || exit
    nice -n 10 cmake --build "$work/build" -j "$JOBS" || exit
    DESTDIR=$D cmake --install "$work/build" || exit
    I=$D$P
    SP=$I/lib/python3.11/site-packages
    [ -d "$SP/bond/msg" ] || { echo "bond.sh: no $SP/bond/msg after the install"; exit 1; }
    mkdir -p "$SP/smclib" "$SP/bondpy" "$I/share/ament_index/resource_index/packages" \
        "$I/share/smclib" "$I/share/bondpy" || exit
    cp "$S"/smclib/smclib/*.py "$SP/smclib/" || exit
    cp "$S"/bondpy/bondpy/*.py "$SP/bondpy/" || exit
    cp "$S/smclib/package.xml" "$I/share/smclib/" || exit
    cp "$S/bondpy/package.xml" "$I/share/bondpy/" || exit
    : >"$I/share/ament_index/resource_index/packages/smclib"
    : >"$I/share/ament_index/resource_index/packages/bondpy"
    "$VENV/bin/python" -m compileall -q -s "$D" "$SP/smclib" "$SP/bondpy" || exit
    mv "$I" "$work/install" && rm -rf "$D"
)

failed=()
first=1
for d in "${DISTROS[@]}"; do
    # (the first distribution's time includes checking and hashing the tarball)
    if [ "$first" = 1 ]; then t0=$T_START; first=0; else t0=$(now_ms); fi
    ROS_DIR=$ROOT/target/ros/$d
    VENV=$ROS_DIR/venv
    if [ ! -x "$VENV/bin/python" ] || [ ! -f "$ROS_DIR/env.sh" ]; then
        echo "bond.sh: $d: no $VENV or $ROS_DIR/env.sh: run tests/interop/setup.sh $d first" >&2
        failed+=("$d")
        continue
    fi
    case "$d" in
        kilted) LOCK=$HERE/requirements.lock ;;
        *) LOCK=$HERE/requirements-$d.lock ;;
    esac
    KEY_TEXT="tarball=$TAR_SHA distro=$d lock=$(sha256sum "$LOCK" | cut -c1-64) recipe=$RECIPE"
    KEY=$(printf '%s' "$KEY_TEXT" | sha256sum | cut -c1-16)
    CACHE=$CACHE_TOP/bond-$KEY-$d
    if ! cached_build "bond.sh: $d" bond_core "$CACHE" "$KEY_TEXT" "$CACHE_TOP/bond-$d.log" build_bond \
        install/share/bond/msg/Status.json install/lib/python3.11/site-packages/bondpy/bondpy.py; then
        failed+=("$d")
        continue
    fi
    if [ "$BUILT" = 1 ]; then status=built; else status="up to date"; fi

    # The environment file (rewritten only when its text changes).
    env_sh=$ROS_DIR/bond_env.sh
    {
        cat <<EOF
# Written by tests/interop/bond.sh -- do not edit. Source it AFTER target/ros/$d/env.sh:
#   . target/ros/$d/env.sh; . target/ros/$d/bond_env.sh
# The stock bond_core (ros/bond_core e6d0fc2c, 4.0.0): the \`bond\` messages (bond/msg/Status,
# Constants; built with rosidl), smclib and bondpy (from bondpy.bondpy import Bond), from
# bond_core.tar.gz (sha256 $TAR_SHA).
TRACER_BOND_DIR='$CACHE'
export TRACER_BOND_DIR
EOF
        prefix_env_lines TRACER_BOND_DIR
    } | write_if_changed "$env_sh"
    # The install where the Rust tests look for rosidl's type descriptions
    # (src/interfaces/type_hash.rs, hashes_equal_rosidls): target/ros/DISTRO/bond_install.
    ln -sfn "$CACHE/install" "$ROS_DIR/bond_install"

    # Check (after a build only; a rerun trusts the key): the messages and bondpy import and
    # a Status round-trips through the type support (no participant is created).
    # shellcheck source=/dev/null
    if [ "$status" = built ] && ! out=$(. "$ROS_DIR/env.sh" && . "$env_sh" && timeout -s KILL 60 python -c '
from rclpy.serialization import serialize_message, deserialize_message
from bond.msg import Status, Constants
from bondpy.bondpy import Bond
from smclib import statemap
m = Status(id="tracer", instance_id="x", active=True, heartbeat_timeout=4.0, heartbeat_period=1.0)
assert deserialize_message(serialize_message(m), Status) == m
assert Constants.DEFAULT_HEARTBEAT_PERIOD == 1.0
' 2>&1); then
        echo "bond.sh: $d: the built bond/bondpy do not import with $env_sh: $out" >&2
        failed+=("$d")
        continue
    fi
    if [ "$status" = built ]; then status="built in"; fi
    echo "bond.sh: $d: bond, smclib, bondpy $status $(took "$t0") ($CACHE)"
done
if [ "${#failed[@]}" -gt 0 ]; then
    echo "bond.sh: failed: ${failed[*]}" >&2
    exit 1
fi
