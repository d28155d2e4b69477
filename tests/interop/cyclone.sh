#!/usr/bin/env bash
# A stock Cyclone DDS peer: rmw_cyclonedds_cpp built from source for a distribution's
# wheel venv, and an environment file that puts an rclpy process on it.
#
#   tests/interop/cyclone.sh [--force] DISTRO...     (after tests/interop/setup.sh DISTRO)
#
# rmw_cyclonedds_cpp (../shared/ros2-src/rmw_cyclonedds.tar.gz, or $TRACER_ROS2_SRC) is
# built with cmake against Debian's Cyclone DDS (apt: cyclonedds-dev,
# libiceoryx-binding-c-dev, liblttng-ust-dev, patchelf; installed here when missing) and
# the distribution's wheels (target/ros/DISTRO/venv), into a cache outside the clone:
#
#   ${TRACER_CACHE:-~/.cache/tracer_calib}/cyclone-<sha256 of the tarball>-DISTRO/
#       install/lib/librmw_cyclonedds_cpp.so     the RMW
#       shim/librmw_fastrtps_cpp.so              a copy of it under rmw_fastrtps_cpp's SONAME
#       key                                      what it was built from (see KEY below)
#
# A fresh machine builds it (about a minute), a rerun reuses it; it is rebuilt when the
# tarball, the venv's pinned wheels (the lock file), Debian's Cyclone DDS or this recipe
# change. Then it writes
#
#   target/ros/DISTRO/cyclone_env.sh   source it AFTER target/ros/DISTRO/env.sh: the
#                                      process (and everything it starts) is on Cyclone DDS
#
# Why the shim: the wheels' librcl*.so and rclpy's extension link librmw_fastrtps_cpp.so
# directly (no run-time RMW selection), so RMW_IMPLEMENTATION alone fails. A copy of
# librmw_cyclonedds_cpp.so given the SONAME librmw_fastrtps_cpp.so and LD_PRELOADed
# takes its place; RMW_IMPLEMENTATION=rmw_cyclonedds_cpp makes rmw's identifier checks
# agree. LD_PRELOAD applies to every program the shell starts, so LD_LIBRARY_PATH must
# hold the venv's libraries (env.sh sets it).
#
# Jazzy only, today: the tarball is rmw_cyclonedds' Jazzy branch (2.2.2), which does not
# compile against Kilted's wheels (rmw_dds_common 4.0 no longer has security.hpp, moved to
# rmw_security_common); Kilted needs rmw_cyclonedds' kilted branch. `cyclone.sh kilted`
# says so (the build's error) and fails.
#
# Prints one line per distribution with its time. Exit status 0 when every distribution
# given has a working build; a distribution whose build fails says why (log kept).
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$HERE/lib.sh"
# Bump when the way it is built changes.
RECIPE=1

parse_peer_args 37 "$@"
# The source, checked against ros2-sources.lock (downloaded by its hash if absent).
TARBALL=$(python3 "$ROOT/scripts/ros2_sources.py" path rmw_cyclonedds) || exit 1

# Work in a clean environment even when a target/ros/*/env.sh is sourced in this shell.
clean_ros_env


# Debian build dependencies, apt-get only for what is missing.
apt_install_missing cyclone.sh "$CACHE_TOP/apt.log" cyclonedds-dev libiceoryx-binding-c-dev liblttng-ust-dev patchelf
CYCLONE_DEB=$(dpkg-query -W -f='${Version}' cyclonedds-dev)
TAR_SHA=$(sha256sum "$TARBALL" | cut -c1-64)

# build_rmw_cyclonedds WORK: rmw_cyclonedds_cpp from TARBALL, built with cmake against VENV
# and Debian's Cyclone DDS, into WORK/install, and its shim (cached_build's BUILD).
build_rmw_cyclonedds() {
    local work=$1 v libdirs
    mkdir -p "$work/src" && tar -xzf "$TARBALL" -C "$work/src" || return
    # ament_cmake_ros' cmake extras find_package() gmock, gtest and pytest: Jazzy's
    # requirements have them (for msg/), Kilted's venv not; the wheels of the venv's
    # own ament_cmake version.
    if [ ! -d "$VENV/share/ament_cmake_gmock" ]; then
        v=$("$VENV/bin/python" -S -c 'import sys; sys.path.append(sys.argv[1]); import importlib.metadata as m; print(m.version("ros-ament-cmake"))' \
            "$VENV/lib/python3.11/site-packages") || return
        "$VENV/bin/python" -m pip install --disable-pip-version-check --no-input -q \
            "ros-ament-cmake-gmock==$v" "ros-ament-cmake-gtest==$v" "ros-ament-cmake-pytest==$v" || return
    fi
    libdirs=$(venv_libdirs "$VENV")
    ( export PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" LD_LIBRARY_PATH="$libdirs" \
             _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
      nice -n 10 cmake -S "$work/src/rmw_cyclonedds/rmw_cyclonedds_cpp" -B "$work/build" \
          -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
          -DCMAKE_PREFIX_PATH="$VENV;/usr" \
          -DPython3_EXECUTABLE="$VENV/bin/python" \
          -DCMAKE_INSTALL_PREFIX="$work/install" || exit
      nice -n 10 cmake --build "$work/build" -j "$JOBS" || exit
      cmake --install "$work/build" || exit
    ) || return
    soname_shim "$work" librmw_cyclonedds_cpp.so
}

failed=()
for d in "${DISTROS[@]}"; do
    t0=$(now_ms)
    ROS_DIR=$ROOT/target/ros/$d
    VENV=$ROS_DIR/venv
    [ -x "$VENV/bin/python" ] || { echo "cyclone.sh: $d: no $VENV: run tests/interop/setup.sh $d first" >&2; failed+=("$d"); continue; }
    case "$d" in
        kilted) LOCK=$HERE/requirements.lock ;;
        *) LOCK=$HERE/requirements-$d.lock ;;
    esac
    CACHE=$CACHE_TOP/cyclone-$TAR_SHA-$d
    KEY="tarball=$TAR_SHA distro=$d lock=$(sha256sum "$LOCK" | cut -c1-64) cyclonedds=$CYCLONE_DEB recipe=$RECIPE"
    if ! cached_build "cyclone.sh: $d" rmw_cyclonedds_cpp "$CACHE" "$KEY" "$CACHE_TOP/cyclone-$d.log" \
        build_rmw_cyclonedds shim/librmw_fastrtps_cpp.so; then
        failed+=("$d")
        continue
    fi
    if [ "$BUILT" = 1 ]; then status=built; else status=cached; fi

    # The environment file (rewritten only when its text changes).
    env_sh=$ROS_DIR/cyclone_env.sh
    write_if_changed "$env_sh" <<EOF
# Written by tests/interop/cyclone.sh -- do not edit. Source it AFTER target/ros/$d/env.sh:
#   . target/ros/$d/env.sh; . target/ros/$d/cyclone_env.sh
# Puts this shell's ROS 2 processes on Cyclone DDS (rmw_cyclonedds_cpp, Debian's Cyclone DDS
# $CYCLONE_DEB) instead of Fast DDS: the RMW built from rmw_cyclonedds.tar.gz (sha256
# $TAR_SHA), preloaded under rmw_fastrtps_cpp's SONAME, which the wheels link.
TRACER_CYCLONE_DIR='$CACHE'
export TRACER_CYCLONE_DIR
export LD_LIBRARY_PATH="\$TRACER_CYCLONE_DIR/install/lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
export LD_PRELOAD="\$TRACER_CYCLONE_DIR/shim/librmw_fastrtps_cpp.so"
export RMW_IMPLEMENTATION=rmw_cyclonedds_cpp
export AMENT_PREFIX_PATH="\$TRACER_CYCLONE_DIR/install\${AMENT_PREFIX_PATH:+:\$AMENT_PREFIX_PATH}"
# Keep DDS on this machine: rmw's LOCALHOST range (no multicast, localhost as the peer),
# and Cyclone on the loopback interface only.
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export CYCLONEDDS_URI='<CycloneDDS><Domain><General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces></General></Domain></CycloneDDS>'
unset FASTDDS_DEFAULT_PROFILES_FILE
EOF

    # Check: an rclpy process on it says it is on Cyclone (no participant is created).
    if ! out=$(. "$ROS_DIR/env.sh" && . "$env_sh" && timeout -s KILL 60 python -c '
from rclpy.utilities import get_rmw_implementation_identifier as rmw
print(rmw())' 2>&1) || [ "$out" != rmw_cyclonedds_cpp ]; then
        echo "cyclone.sh: $d: rclpy is not on rmw_cyclonedds_cpp with $env_sh: $out" >&2
        failed+=("$d")
        continue
    fi
    echo "cyclone.sh: $d: rmw_cyclonedds_cpp $status ($CACHE) $(took "$t0")"
done
if [ "${#failed[@]}" -gt 0 ]; then
    echo "cyclone.sh: failed: ${failed[*]}" >&2
    exit 1
fi
