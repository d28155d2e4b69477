#!/usr/bin/env bash
# The real `ros2 bag` (rosbag2, Jazzy) built from source for the Jazzy wheel venv: record,
# play, info, list and the MCAP and sqlite3 storage plugins, as a stock ROS 2 user has them.
#
#   tests/interop/rosbag2.sh [--force] jazzy     (after setup.sh jazzy and ros2cli.sh jazzy)
#
# Sources (../shared/ros2-src/ or $TRACER_ROS2_SRC, checked against ros2-sources.lock): rosbag2,
# rclcpp, rcl_interfaces (statistics_msgs), class_loader, pluginlib, libstatistics_collector,
# keyboard_handler, yaml_cpp_vendor, console_bridge_vendor, tinyxml2_vendor, yaml-cpp 0.8.0,
# mcap (C++ 1.3.0), readerwriterqueue. No wheels exist for rclcpp or rosbag2: each package is
# configured, built and installed with plain cmake (no colcon) into one prefix, in the order
# below, against target/ros/jazzy/venv, as docs/ros2-peer.md ("The real `ros2 bag`") measured:
#   - apt (installed here when missing, log in the cache's parent): liblttng-ust-dev
#     libtinyxml2-dev libconsole-bridge-dev liblz4-dev libzstd-dev libsqlite3-dev (they satisfy
#     the vendor packages: nothing is downloaded by cmake; the build runs in a private network
#     namespace, tests/interop/netns.sh, so an attempt would fail, not fetch);
#   - pip into the venv (tests/interop/requirements-rosbag2.txt, pinned): ament_cmake_vendor_package,
#     pybind11_vendor, pybind11; then `ros2bag` (the `ros2 bag` verbs, pure Python) from the
#     rosbag2 tarball with --no-deps;
#   - fixes: the Fast DDS wheel's cmake targets name the wheel builder's /usr/lib64/libtinyxml2.so:
#     a corrected copy of share/fastrtps/cmake is used (fastrtps_DIR; the venv is not touched);
#     links with -Wl,--allow-shlib-undefined (the wheels' librcl needs Python symbols that
#     exist only in a Python process) and -Wl,--as-needed; mcap_vendor from the unpacked mcap
#     (FETCHCONTENT_SOURCE_DIR_MCAP); shared_queues_vendor's URL pointed at the
#     readerwriterqueue tarball; CMAKE_POLICY_VERSION_MINIMUM=3.5 for the venv's cmake 4.
# Everything lands in a cache outside the clone:
#
#   ${TRACER_CACHE:-~/.cache/tracer_calib}/rosbag2-<KEY>-jazzy/
#       install/                    the prefix: lib/librosbag2_*.so, the storage plugins,
#                                   lib/python3.11/site-packages/rosbag2_py, share/ (ament index)
#       build-times.txt             seconds per package of the build that made it
#       key                         what it was built from
#
# KEY: the sha256 of the tarballs' sha256s, the venv's lock file (requirements-jazzy.lock),
# requirements-rosbag2.txt, the Debian packages' versions and the recipe (RECIPE below). A fresh
# build takes minutes (BENCHMARKS.md; `nice -n 10`, -j2, or $ROS_SETUP_JOBS); a rerun with
# all of those unchanged reuses it (a fraction of a second); `--force` rebuilds. The build runs
# in a temporary directory beside the cache and is moved into place when complete: an
# interrupted build leaves no half cache. Then it writes
#
#   target/ros/jazzy/rosbag2_env.sh   source it AFTER target/ros/jazzy/env.sh: puts the prefix on
#                                     PYTHONPATH, LD_LIBRARY_PATH, AMENT_PREFIX_PATH (pluginlib
#                                     finds the storage plugins there) and sets ROS_DISTRO
#
# Jazzy only: the sources are Jazzy's branches; `rosbag2.sh kilted` says it is skipped. Only
# Fast DDS was tried (librosbag2_cpp links librmw_fastrtps_cpp as the wheels' librcl does).
# Prints one line with its time. Exit status 0 when the build works; a failed build says why
# (log kept in the cache's parent).
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$HERE/lib.sh"
REQ=$HERE/requirements-rosbag2.txt
# Bump when the way it is built changes (the cache key says which recipe built it).
RECIPE=1

parse_peer_args 48 "$@"
T_START=$(now_ms)

# The sources, checked against ros2-sources.lock (downloaded by their hash if absent).
SOURCES=(rosbag2 rclcpp rcl_interfaces class_loader pluginlib libstatistics_collector keyboard_handler
    yaml_cpp_vendor console_bridge_vendor tinyxml2_vendor yaml-cpp mcap readerwriterqueue)
APT=(liblttng-ust-dev libtinyxml2-dev libconsole-bridge-dev liblz4-dev libzstd-dev libsqlite3-dev)
# The packages, in build order: NAME SOURCE-FOLDER (below the unpacked tarballs).
PACKAGES=(
    statistics_msgs rcl_interfaces/statistics_msgs
    console_bridge_vendor console_bridge_vendor
    tinyxml2_vendor tinyxml2_vendor
    yaml-cpp yaml-cpp
    yaml_cpp_vendor yaml_cpp_vendor
    class_loader class_loader
    pluginlib pluginlib/pluginlib
    libstatistics_collector libstatistics_collector
    rclcpp rclcpp/rclcpp
    rclcpp_components rclcpp/rclcpp_components
    keyboard_handler keyboard_handler/keyboard_handler
    liblz4_vendor rosbag2/liblz4_vendor
    zstd_vendor rosbag2/zstd_vendor
    sqlite3_vendor rosbag2/sqlite3_vendor
    shared_queues_vendor rosbag2/shared_queues_vendor
    mcap_vendor rosbag2/mcap_vendor
    rosbag2_interfaces rosbag2/rosbag2_interfaces
    rosbag2_storage rosbag2/rosbag2_storage
    rosbag2_storage_mcap rosbag2/rosbag2_storage_mcap
    rosbag2_storage_sqlite3 rosbag2/rosbag2_storage_sqlite3
    rosbag2_storage_default_plugins rosbag2/rosbag2_storage_default_plugins
    rosbag2_cpp rosbag2/rosbag2_cpp
    rosbag2_compression rosbag2/rosbag2_compression
    rosbag2_compression_zstd rosbag2/rosbag2_compression_zstd
    rosbag2_transport rosbag2/rosbag2_transport
    rosbag2_py rosbag2/rosbag2_py
)

# rosbag2_build SRC PREFIX VENV OVERLAY JOBS TIMES NAME FOLDER...: the cmake steps (run inside
# netns.sh: no network). Each package configured against PREFIX and VENV, built, installed.
rosbag2_build() {
    local src=$1 P=$2 V=$3 overlay=$4 jobs=$5 times=$6 name dir t pyb
    shift 6
    pyb=$("$V/bin/python" -m pybind11 --cmakedir) || return
    local flags="-Wl,--allow-shlib-undefined -Wl,--as-needed"
    while [ "$#" -gt 0 ]; do
        name=$1 dir=$2
        shift 2
        t=$(date +%s)
        echo "=== $name ($dir)"
        local extra=()
        case "$name" in
            yaml-cpp) extra=(-DYAML_BUILD_SHARED_LIBS=ON -DYAML_CPP_BUILD_TESTS=OFF
                -DYAML_CPP_BUILD_TOOLS=OFF -DYAML_CPP_BUILD_CONTRIB=OFF) ;;
            mcap_vendor) extra=(-DFETCHCONTENT_SOURCE_DIR_MCAP="$src/mcap" -DFETCHCONTENT_FULLY_DISCONNECTED=ON) ;;
            rosbag2_py) extra=(-Dpybind11_DIR="$pyb") ;;
        esac
        nice -n 10 cmake -S "$src/$dir" -B "$src/../build/$name" \
            -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
            -DCMAKE_PREFIX_PATH="$P;$V" -DCMAKE_INSTALL_PREFIX="$P" \
            -DPython3_EXECUTABLE="$V/bin/python" \
            -DCMAKE_POLICY_VERSION_MINIMUM=3.5 \
            -Dfastrtps_DIR="$overlay" \
            -DCMAKE_SHARED_LINKER_FLAGS="$flags" -DCMAKE_MODULE_LINKER_FLAGS="$flags" \
            -DCMAKE_EXE_LINKER_FLAGS="$flags" \
            ${extra[@]+"${extra[@]}"} || return
        nice -n 10 cmake --build "$src/../build/$name" -j "$jobs" || return
        cmake --install "$src/../build/$name" || return
        rm -rf "$src/../build/$name"
        echo "$name $(( $(date +%s) - t ))" >>"$times"
    done
}

# build_rosbag2 WORK: PACKAGES from TARBALLS (in a network namespace of their own: the build
# downloads nothing) against VENV into WORK/install; each package's build time in
# WORK/build-times.txt (cached_build's BUILD).
build_rosbag2() {
    local work=$1 t overlay libdirs
    mkdir -p "$work/src" "$work/build" || return
    for t in "${TARBALLS[@]}"; do tar -xzf "$t" -C "$work/src" || return; done
    # The Fast DDS wheel's cmake files, corrected: its targets name the wheel builder's
    # /usr/lib64/libtinyxml2.so ("No rule to make target" on every link of rcl/rclcpp).
    # The copy computes its prefix as the venv, as the original does from its place.
    overlay=$work/build/fastrtps-cmake
    cp -r "$VENV/share/fastrtps/cmake" "$overlay" || return
    # shellcheck disable=SC2016
    sed -i 's#get_filename_component(PACKAGE_PREFIX_DIR "${CMAKE_CURRENT_LIST_DIR}/../../../" ABSOLUTE)#set(PACKAGE_PREFIX_DIR "'"$VENV"'")#' \
        "$overlay/fastrtps-config.cmake" || return
    # shellcheck disable=SC2016
    sed -i -e 's#get_filename_component(_IMPORT_PREFIX "${CMAKE_CURRENT_LIST_FILE}" PATH)#set(_IMPORT_PREFIX "'"$VENV"'/share/fastrtps/cmake")#' \
        -e 's#/usr/lib64/libtinyxml2.so;##' "$overlay"/*-targets.cmake || return
    # shared_queues_vendor downloads readerwriterqueue's zip (URL + MD5): the tarball instead.
    sed -i -e 's#URL https://github.com/cameron314/readerwriterqueue/archive/.*#URL '"${TARBALL[readerwriterqueue]}"'#' \
        -e '/URL_MD5/d' "$work/src/rosbag2/shared_queues_vendor/CMakeLists.txt" || return
    libdirs=$work/install/lib:$(venv_libdirs "$VENV")
    export -f rosbag2_build
    : >"$work/build-times.txt"
    # shellcheck disable=SC2016
    ( export PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$work/install:$VENV" LD_LIBRARY_PATH="$libdirs" \
             _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
      "$HERE/netns.sh" bash -c 'set -uo pipefail; rosbag2_build "$@"' rosbag2_build \
          "$work/src" "$work/install" "$VENV" "$overlay" "$JOBS" "$work/build-times.txt" "${PACKAGES[@]}"
    )
}

failed=()
for d in "${DISTROS[@]}"; do
    if [ "$d" != jazzy ]; then
        echo "rosbag2.sh: $d: skipped (rosbag2 is built for jazzy only: its sources are Jazzy's branches)"
        continue
    fi
    t0=$T_START
    ROS_DIR=$ROOT/target/ros/$d
    VENV=$ROS_DIR/venv
    if [ ! -x "$VENV/bin/ros2" ] || [ ! -f "$ROS_DIR/env.sh" ]; then
        echo "rosbag2.sh: $d: no ros2 CLI in $VENV: run tests/interop/setup.sh $d and ros2cli.sh $d first" >&2
        failed+=("$d")
        continue
    fi
    list=$(python3 "$ROOT/scripts/ros2_sources.py" path "${SOURCES[@]}") || exit 1
    mapfile -t TARBALLS <<<"$list"
    declare -A TARBALL
    for i in "${!SOURCES[@]}"; do TARBALL[${SOURCES[$i]}]=${TARBALLS[$i]}; done
    # Work in a clean environment even when a target/ros/*/env.sh is sourced in this shell.
    clean_ros_env
    apt_install_missing rosbag2.sh "$CACHE_TOP/rosbag2-apt.log" "${APT[@]}"
    LOCK=$HERE/requirements-$d.lock
    sums=$(sha256sum "${TARBALLS[@]}" | cut -c1-64)
    KEY_TEXT="sources=$(sha256sum <<<"$sums" | cut -c1-64) distro=$d lock=$(sha256sum "$LOCK" | cut -c1-64)"
    KEY_TEXT+=" req=$(sha256sum "$REQ" | cut -c1-64) apt=$(dpkg-query -W -f='${Package}=${Version} ' "${APT[@]}" | sha256sum | cut -c1-64)"
    KEY_TEXT+=" recipe=$RECIPE"
    KEY=$(printf '%s' "$KEY_TEXT" | sha256sum | cut -c1-16)
    CACHE=$CACHE_TOP/rosbag2-$KEY-$d
    mkdir -p "$CACHE_TOP" "$ROS_DIR/stamps" "$ROS_DIR/logs"

    # 1. The venv: the extra wheels and ros2bag (not while setup.sh remakes the venv: its lock).
    exec 9>"$ROOT/target/ros/.setup.lock"
    flock 9
    VKEY=$({ sha256sum <"${TARBALL[rosbag2]}"; cat "$REQ"; echo "recipe=$RECIPE"; stat -c 'venv %i %Y' "$VENV/pyvenv.cfg"; } \
        | sha256sum | cut -c1-64)
    STAMP=$ROS_DIR/stamps/rosbag2
    if [ "$FORCE" = 1 ] || [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$VKEY" ]; then
        rm -f "$STAMP"
        plog=$ROS_DIR/logs/rosbag2-pip.log
        pwork=$(mktemp -d)
        tar -xzf "${TARBALL[rosbag2]}" -C "$pwork" rosbag2/ros2bag
        pip=("$VENV/bin/python" -m pip install --disable-pip-version-check --no-input)
        if ! { _ROS_WHEELS_BOOTSTRAP_COMPLETE=1 "${pip[@]}" -r "$REQ" \
               && _ROS_WHEELS_BOOTSTRAP_COMPLETE=1 "${pip[@]}" --no-deps --no-build-isolation "$pwork/rosbag2/ros2bag"
             } >"$plog" 2>&1; then
            rm -rf "$pwork"
            exec 9>&-
            echo "rosbag2.sh: $d: pip install into $VENV failed; last lines of $plog:" >&2
            tail -n 25 "$plog" >&2
            failed+=("$d")
            continue
        fi
        rm -rf "$pwork"
        echo "$VKEY" >"$STAMP"
    fi
    exec 9>&-

    # 2. The cmake build into the cache.
    if ! cached_build "rosbag2.sh: $d" rosbag2 "$CACHE" "$KEY_TEXT" "$CACHE_TOP/rosbag2-$d.log" build_rosbag2 \
        install/lib/python3.11/site-packages/rosbag2_py/__init__.py \
        install/share/rosbag2_storage_mcap/plugin_description.xml; then
        failed+=("$d")
        continue
    fi
    if [ "$BUILT" = 1 ]; then status=built; else status="up to date"; fi

    # The environment file (rewritten only when its text changes).
    env_sh=$ROS_DIR/rosbag2_env.sh
    {
        cat <<EOF
# Written by tests/interop/rosbag2.sh -- do not edit. Source it AFTER target/ros/$d/env.sh:
#   . target/ros/$d/env.sh; . target/ros/$d/rosbag2_env.sh
# The stock \`ros2 bag\` (rosbag2 0.26.5, Jazzy; MCAP and sqlite3 storage, zstd compression)
# built from ../shared/ros2-src/ with plain cmake; ros2bag itself is in the venv.
TRACER_ROSBAG2_DIR='$CACHE'
export TRACER_ROSBAG2_DIR
export ROS_DISTRO=$d
EOF
        prefix_env_lines TRACER_ROSBAG2_DIR
    } | write_if_changed "$env_sh"

    # Check (after a build only; a rerun trusts the key): `ros2 bag list storage` names both
    # storage plugins and rosbag2_py imports (no participant is created).
    if [ "$status" = built ]; then
        # shellcheck source=/dev/null
        if ! out=$(. "$ROS_DIR/env.sh" && . "$env_sh" && timeout -s KILL 120 bash -c '
                python -c "import rosbag2_py" && ros2 bag list storage' 2>&1) \
            || ! grep -qw mcap <<<"$out" || ! grep -qw sqlite3 <<<"$out"; then
            echo "rosbag2.sh: $d: the built ros2 bag does not run with $env_sh: $out" >&2
            failed+=("$d")
            continue
        fi
    fi
    if [ "$status" = built ]; then
        status="built in"
        cp "$CACHE/build-times.txt" "$ROS_DIR/logs/rosbag2-build-times.txt"
    fi
    echo "rosbag2.sh: $d: ros2 bag (rosbag2) $status $(took "$t0") ($CACHE)"
done
if [ "${#failed[@]}" -gt 0 ]; then
    echo "rosbag2.sh: failed: ${failed[*]}" >&2
    exit 1
fi
