#!/usr/bin/env bash
# A stock rmw_zenoh peer: zenoh-c, zenoh-cpp, rmw_zenoh_cpp 0.2.10 and its router rmw_zenohd
# built from source for the Jazzy wheel venv, and an environment file that puts an rclpy
# process on rmw_zenoh_cpp.
#
#   tests/interop/zenoh.sh [--force] jazzy     (after tests/interop/setup.sh jazzy)
#
# Sources (../shared/ros2-src/, or $TRACER_ROS2_SRC): rmw_zenoh.tar.gz (rmw_zenoh_cpp
# 0.2.10, Jazzy's release), zenoh-c.tar.gz and zenoh-cpp.tar.gz (the commits it pins). The
# recipe is docs/ros2-peer.md, "A stock rmw_zenoh peer":
#   - zenoh-c (Rust, cargo through its CMake) with the published zenoh 1.8.0 crates from the
#     Rust registry instead of zenoh's git main (`cargo update -w`, also for the
#     opaque-types crate its build.rs builds offline), thin LTO off (codegen units 16), the
#     stable toolchain (cargo >= 1.88), features shared-memory + zenoh/transport_serial;
#   - zenoh-cpp, header only, installed with CMake;
#   - a stand-in zenoh_cpp_vendorConfig.cmake (the vendor package would download both);
#   - rmw_zenoh_cpp with CMake against the venv (needs ros-jazzy-ament-cmake-include-
#     directories, pinned in requirements-jazzy.txt).
# apt: g++ make patchelf liblttng-ust-dev (installed here when missing; cmake is the venv's).
# Crates are downloaded by cargo into its usual CARGO_HOME (~/.cargo, ~0.26 GB) the first time.
# Everything lands in a cache outside the clone:
#
#   ${TRACER_CACHE:-~/.cache/tracer_calib}/zenoh-<sha256 of the three tarballs' sha256s>-jazzy/
#       install/lib/librmw_zenoh_cpp.so, libzenohc.so     the RMW and zenoh-c
#       install/lib/rmw_zenoh_cpp/rmw_zenohd              the router
#       install/share/rmw_zenoh_cpp/config/*.json5         its default configurations
#       shim/librmw_fastrtps_cpp.so                        the RMW under rmw_fastrtps_cpp's SONAME
#       key                                                what it was built from (KEY below)
#
# A fresh machine builds it (BENCHMARKS.md; 3.5 GB of build tree removed afterwards),
# a rerun reuses it; it is rebuilt when a tarball, the venv's pinned wheels (the lock file)
# or this recipe change (`--force`: always). The cargo that built it is recorded beside the
# key (cargo-version), not compared (that would start rustup: not "well under a second").
# Then it writes
#
#   target/ros/jazzy/zenoh_env.sh   source it AFTER target/ros/jazzy/env.sh: the process (and
#                                   everything it starts) is on rmw_zenoh_cpp; it puts
#                                   `tracer_zenoh_router [ARGS]` on PATH (below) and exports
#                                   TRACER_ZENOHD (rmw_zenohd's path)
#   target/ros/jazzy/zenoh_bin/tracer_zenoh_router
#                                   execs rmw_zenohd listening on tcp/127.0.0.1:7447 only
#                                   (its default is tcp/[::]:7447); a script, not a shell
#                                   function, so that `tracer_zenoh_router & kill $!` stops
#                                   the router itself
#
# Sessions (rmw_zenoh's default session config) connect to tcp/localhost:7447, listen on
# tcp/localhost:0 and do no multicast scouting: nothing leaves the loopback. Run peers and
# router inside tests/interop/netns.sh all the same.
#
# Why the shim: as for Cyclone DDS (tests/interop/cyclone.sh), the wheels' librcl*.so and
# rclpy link librmw_fastrtps_cpp.so directly; a copy of librmw_zenoh_cpp.so with that SONAME,
# LD_PRELOADed, with RMW_IMPLEMENTATION=rmw_zenoh_cpp, takes its place.
#
# Jazzy only: rmw_zenoh.tar.gz is Jazzy's release. Prints one line with its time. Exit
# status 0 when the build works (an rclpy process on it says rmw_zenoh_cpp); a failed build
# says why (log kept in the cache directory's parent).
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$HERE/lib.sh"
# Bump when the way it is built changes.
RECIPE=1

FORCE=0
DISTROS=()
for a in "$@"; do
    case "$a" in
        --force) FORCE=1 ;;
        jazzy) DISTROS+=("$a") ;;
        kilted) echo "zenoh.sh: kilted: rmw_zenoh.tar.gz is Jazzy's release (0.2.10); only jazzy is built" >&2; exit 2 ;;
        -h|--help) sed -n '2,56p' "$0"; exit 0 ;;
        *) echo "usage: $0 [--force] jazzy" >&2; exit 2 ;;
    esac
done
[ "${#DISTROS[@]}" -gt 0 ] || { echo "usage: $0 [--force] jazzy" >&2; exit 2; }
# The sources, checked against ros2-sources.lock (downloaded by their hashes if absent).
paths=$(python3 "$ROOT/scripts/ros2_sources.py" path rmw_zenoh zenoh-c zenoh-cpp) || exit 1
mapfile -t TARBALLS <<<"$paths"

# Work in a clean environment even when a target/ros/*/env.sh is sourced in this shell.
clean_ros_env
unset ZENOH_CONFIG_OVERRIDE ZENOH_SESSION_CONFIG_URI ZENOH_ROUTER_CONFIG_URI


T_START=$(now_ms)
# The key is computed first: a cached build needs neither apt nor cargo to be looked at.
sums=""
for t in "${TARBALLS[@]}"; do sums+="$(basename "$t")=$(sha256sum "$t" | cut -c1-64) "; done
TAR_SHA=$(printf '%s' "$sums" | sha256sum | cut -c1-64)

# build_rmw_zenoh WORK: zenoh-c, zenoh-cpp and rmw_zenoh_cpp from TARBALLS, built against
# VENV into WORK/install, and rmw_zenoh_cpp's shim (cached_build's BUILD). The cargo that
# built it goes to WORK/cargo-version.
build_rmw_zenoh() {
    local work=$1 t libdirs P=$1/install
    RUSTUP_TOOLCHAIN=stable cargo --version >"$work/cargo-version" || return
    mkdir -p "$work/src" || return
    for t in "${TARBALLS[@]}"; do tar -xzf "$t" -C "$work/src" || return; done
    libdirs=$(venv_libdirs "$VENV")
    ( export PATH="$VENV/bin:$PATH" _ROS_WHEELS_BOOTSTRAP_COMPLETE=1 LD_LIBRARY_PATH="$libdirs"
      export RUSTUP_TOOLCHAIN=stable CARGO_PROFILE_RELEASE_LTO=off CARGO_PROFILE_RELEASE_CODEGEN_UNITS=16 CARGO_BUILD_JOBS="$JOBS"
      cd "$work/src/zenoh-c" || exit
      # zenoh from the registry (1.8.0), not git main ("1.8.0 plus fixes").
      files=(Cargo.toml Cargo.toml.in build-resources/opaque-types/Cargo.toml)
      sed -i 's#version = "1.8.0", git = "https://github.com/eclipse-zenoh/zenoh.git", branch = "main"#version = "=1.8.0"#' "${files[@]}" || exit
      if grep -n '^[^#]*git = "https://github.com/eclipse-zenoh' "${files[@]}"; then
          echo "zenoh.sh: zenoh-c still names zenoh's git (recipe out of date)"; exit 1
      fi
      nice -n 10 cargo update -w || exit
      (cd build-resources/opaque-types && cp ../../Cargo.lock . && nice -n 10 cargo update -w) || exit
      cd "$work" || exit
      nice -n 10 cmake -S src/zenoh-c -B build/zc -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$P" \
          -DZENOHC_BUILD_WITH_UNSTABLE_API=TRUE \
          "-DZENOHC_CARGO_FLAGS=--features=shared-memory zenoh/transport_serial" || exit
      nice -n 10 cmake --build build/zc -j "$JOBS" || exit
      cmake --install build/zc || exit
      nice -n 10 cmake -S src/zenoh-cpp -B build/zcxx -DCMAKE_INSTALL_PREFIX="$P" \
          -DZENOHCXX_ZENOHC=OFF -DZENOHCXX_ENABLE_TESTS=OFF -DZENOHCXX_ENABLE_EXAMPLES=OFF || exit
      cmake --install build/zcxx || exit
      # Stand-in for the zenoh_cpp_vendor package (which would download and build both).
      mkdir -p "$P/share/zenoh_cpp_vendor/cmake" || exit
      printf '%s\n' 'include(CMakeFindDependencyMacro)' 'find_dependency(zenohc)' \
          'find_dependency(zenohcxx)' 'set(zenoh_cpp_vendor_FOUND TRUE)' \
          >"$P/share/zenoh_cpp_vendor/cmake/zenoh_cpp_vendorConfig.cmake" || exit
      AMENT_PREFIX_PATH="$VENV" nice -n 10 cmake -S src/rmw_zenoh/rmw_zenoh_cpp -B build/rmw \
          -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
          -DCMAKE_PREFIX_PATH="$P;$VENV" -DCMAKE_INSTALL_PREFIX="$P" \
          -DPython3_EXECUTABLE="$VENV/bin/python" || exit
      nice -n 10 cmake --build build/rmw -j "$JOBS" || exit
      cmake --install build/rmw || exit
    ) || return
    soname_shim "$work" librmw_zenoh_cpp.so
}

failed=()
for d in "${DISTROS[@]}"; do
    t0=$T_START  # (one distribution: its time includes hashing the tarballs)
    ROS_DIR=$ROOT/target/ros/$d
    VENV=$ROS_DIR/venv
    [ -x "$VENV/bin/python" ] || { echo "zenoh.sh: $d: no $VENV: run tests/interop/setup.sh $d first" >&2; failed+=("$d"); continue; }
    LOCK=$HERE/requirements-$d.lock
    CACHE=$CACHE_TOP/zenoh-$TAR_SHA-$d
    KEY="tarballs=$sums distro=$d lock=$(sha256sum "$LOCK" | cut -c1-64) recipe=$RECIPE"
    log=$CACHE_TOP/zenoh-$d.log
    if [ "$FORCE" = 1 ] || [ ! -f "$CACHE/key" ] || [ "$(cat "$CACHE/key")" != "$KEY" ]; then
        # Debian build dependencies, apt-get only for what is missing; and a cargo.
        apt_install_missing zenoh.sh "$CACHE_TOP/apt.log" g++ make patchelf liblttng-ust-dev
        RUSTUP_TOOLCHAIN=stable cargo --version >/dev/null 2>&1 \
            || { echo "zenoh.sh: no cargo (rustup's stable, >= 1.88, builds zenoh-c)" >&2; exit 1; }
        echo "zenoh.sh: $d: building zenoh-c, zenoh-cpp, rmw_zenoh_cpp (several minutes; log: $log)"
    fi
    if ! cached_build "zenoh.sh: $d" "zenoh-c/zenoh-cpp/rmw_zenoh_cpp" "$CACHE" "$KEY" "$log" build_rmw_zenoh \
        shim/librmw_fastrtps_cpp.so install/lib/rmw_zenoh_cpp/rmw_zenohd; then
        failed+=("$d")
        continue
    fi
    if [ "$BUILT" = 1 ]; then status="built in $(took "$t0")"; else status=cached; fi

    # The environment file (rewritten only when its text changes).
    env_sh=$ROS_DIR/zenoh_env.sh
    write_if_changed "$env_sh" <<EOF
# Written by tests/interop/zenoh.sh -- do not edit. Source it AFTER target/ros/$d/env.sh:
#   . target/ros/$d/env.sh; . target/ros/$d/zenoh_env.sh
# Puts this shell's ROS 2 processes on Zenoh (rmw_zenoh_cpp 0.2.10, zenoh-c 1.8.0) instead of
# Fast DDS: the RMW built from rmw_zenoh.tar.gz, zenoh-c.tar.gz, zenoh-cpp.tar.gz, preloaded
# under rmw_fastrtps_cpp's SONAME, which the wheels link. Peers need a router:
#   tracer_zenoh_router &        # rmw_zenohd on tcp/127.0.0.1:7447 (run inside netns.sh;
#                                # target/ros/$d/zenoh_bin/, put on PATH here)
# or, from another program: ZENOH_CONFIG_OVERRIDE='listen/endpoints=["tcp/127.0.0.1:7447"]' \$TRACER_ZENOHD
TRACER_ZENOH_DIR='$CACHE'
export TRACER_ZENOH_DIR
case ":\$PATH:" in *":$ROS_DIR/zenoh_bin:"*) ;; *) export PATH="$ROS_DIR/zenoh_bin:\$PATH" ;; esac
export TRACER_ZENOHD="\$TRACER_ZENOH_DIR/install/lib/rmw_zenoh_cpp/rmw_zenohd"
export LD_LIBRARY_PATH="\$TRACER_ZENOH_DIR/install/lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
export LD_PRELOAD="\$TRACER_ZENOH_DIR/shim/librmw_fastrtps_cpp.so"
export RMW_IMPLEMENTATION=rmw_zenoh_cpp
# rmw_zenoh finds its config/*.json5 through AMENT_PREFIX_PATH.
export AMENT_PREFIX_PATH="\$TRACER_ZENOH_DIR/install\${AMENT_PREFIX_PATH:+:\$AMENT_PREFIX_PATH}"
unset FASTDDS_DEFAULT_PROFILES_FILE
EOF
    # The router command (rewritten only when its text changes).
    mkdir -p "$ROS_DIR/zenoh_bin"
    router_sh=$ROS_DIR/zenoh_bin/tracer_zenoh_router
    write_if_changed "$router_sh" <<EOF
#!/bin/sh
# Written by tests/interop/zenoh.sh -- do not edit. On PATH after target/ros/$d/zenoh_env.sh.
# rmw_zenohd (the router of rmw_zenoh_cpp 0.2.10) in the foreground, listening on
# tcp/127.0.0.1:7447 only (its default: tcp/[::]:7447); run it inside tests/interop/netns.sh.
# More overrides: ZENOH_CONFIG_OVERRIDE='key=value;...' tracer_zenoh_router (appended).
ZENOH_CONFIG_OVERRIDE='listen/endpoints=["tcp/127.0.0.1:7447"]'\${ZENOH_CONFIG_OVERRIDE:+";\$ZENOH_CONFIG_OVERRIDE"}
export ZENOH_CONFIG_OVERRIDE
exec '$CACHE/install/lib/rmw_zenoh_cpp/rmw_zenohd' "\$@"
EOF
    chmod 755 "$router_sh"

    # Check (after a build only; a rerun trusts the key): an rclpy process on it says it is
    # on rmw_zenoh_cpp (no session is opened).
    if [ "$status" != cached ] && { ! out=$(. "$ROS_DIR/env.sh" && . "$env_sh" && timeout -s KILL 60 python -c '
from rclpy.utilities import get_rmw_implementation_identifier as rmw
print(rmw())' 2>&1) || [ "$out" != rmw_zenoh_cpp ]; }; then
        echo "zenoh.sh: $d: rclpy is not on rmw_zenoh_cpp with $env_sh: $out" >&2
        failed+=("$d")
        continue
    fi
    echo "zenoh.sh: $d: rmw_zenoh_cpp $status ($CACHE) $(took "$t0")"
done
if [ "${#failed[@]}" -gt 0 ]; then
    echo "zenoh.sh: failed: ${failed[*]}" >&2
    exit 1
fi
