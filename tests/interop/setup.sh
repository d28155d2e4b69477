#!/usr/bin/env bash
# Installs what the real-ROS-2-peer tests need, into target/ros/ (never system-wide,
# apart from Debian build tools that are missing), once per ROS 2 distribution:
#
#   kilted   ros-* wheels:       rclpy 9.1, rmw_fastrtps_cpp 9.3 (Fast DDS 3.2)
#            tests/interop/requirements.txt, pinned by requirements.lock
#   jazzy    ros-jazzy-* wheels: rclpy 7.1, rmw_fastrtps_cpp 8.4 (Fast DDS 2.14), the LTS
#            tests/interop/requirements-jazzy.txt, pinned by requirements-jazzy.lock
#
# and for each distribution D:
#   target/ros/D/venv/         rclpy + message wheels, rosbags, numpy, cmake -- from PyPI
#   target/ros/D/msgs_install/ msg/ (tracer_calib_msgs) built with cmake + rosidl
#   target/ros/D/fastdds_localhost.xml  Fast DDS profile: UDPv4 on 127.0.0.1 only
#   target/ros/D/ros_setup.sh  what `source /opt/ros/D/setup.bash` does, for the venv
#                              (the underlay of a colcon workspace: tests/interop/workspace.sh)
#   target/ros/D/env.sh        source it to use all of the above (ros_setup.sh + msgs_install)
# target/ros/venv and target/ros/env.sh point at kilted's (older callers, tests/bags.rs).
#
# Usage: tests/interop/setup.sh [--force] [kilted|jazzy|all]...   (default: all;
#        --force: redo every step)
#
# Idempotent and quick when up to date: each step is keyed on a stamp (hashes of its
# inputs) and skipped when the stamp matches. Prints one line per step with its time.
# Needs: Debian, Python 3.11 (`python3` or `python3.11`), PyPI. Environment knobs:
#   ROS_SETUP_PYTHON   interpreter for the venv (default: python3, else python3.11)
#   ROS_SETUP_JOBS     parallel compile jobs for msg/ (default 2; run under nice -n 10)
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$HERE/lib.sh"
ROS_TOP=$ROOT/target/ros
# Bump when the way the venv is made changes (the requirement files are hashed anyway).
VENV_RECIPE=1

FORCE=0
DISTROS=()
for a in "$@"; do
    case "$a" in
        --force) FORCE=1 ;;
        kilted|jazzy) DISTROS+=("$a") ;;
        all) DISTROS+=(kilted jazzy) ;;
        -h|--help) sed -n '2,27p' "$0"; exit 0 ;;
        *) echo "usage: $0 [--force] [kilted|jazzy|all]..." >&2; exit 2 ;;
    esac
done
[ "${#DISTROS[@]}" -gt 0 ] || DISTROS=(kilted jazzy)

# Work in a clean environment even when a target/ros/*/env.sh is sourced in this shell.
if [ -n "${TRACER_ROS_ENV:-}" ]; then
    PATH=$(printf '%s' "$PATH" | tr ':' '\n' | grep -vxF "$TRACER_ROS_ENV/venv/bin" | paste -sd: -)
    unset TRACER_ROS_ENV PYTHONPATH LD_LIBRARY_PATH AMENT_PREFIX_PATH CMAKE_PREFIX_PATH FASTDDS_DEFAULT_PROFILES_FILE
fi
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE VIRTUAL_ENV PYTHONHOME
export PATH

mkdir -p "$ROS_TOP"
# One setup at a time (a test run and a developer may start it together).
exec 9>"$ROS_TOP/.setup.lock"
if command -v flock >/dev/null 2>&1; then
    flock 9
fi

T_ALL=$(now_ms)
CHANGED=0
DISTRO=""
# step_done NAME STATUS T0_MS
step_done() {
    local ms=$(( $(now_ms) - $3 ))
    printf 'setup.sh: %-7s%-8s %-9s %4d.%01ds\n' "$DISTRO" "$1" "$2" $(( ms / 1000 )) $(( (ms % 1000) / 100 ))
}
die() { echo "setup.sh: error: $*" >&2; exit 1; }
# show_log FILE: last lines of a failed step's log
show_log() { echo "setup.sh: --- last lines of $1 ---" >&2; tail -n 40 "$1" >&2 || true; }
hash_stdin() { sha256sum | cut -c1-64; }
stamp_ok() { [ "$FORCE" = 0 ] && [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }

# ---------------------------------------------------------------------------------
# 1. tools: Python 3.11 with venv + headers, a C/C++ compiler, make, unshare, ip.
#    apt-get only for what is missing.
t0=$(now_ms)
# One interpreter call per candidate (pyenv shims are slow): version, path, venv, headers.
PY_PROBE='import importlib.util as u, os, sys, sysconfig
venv = all(u.find_spec(m) for m in ("venv", "ensurepip"))
dev = os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h"))
exe = getattr(sys, "_base_executable", "") or sys.executable  # never a venv'"'"'s own python
print(sys.version.split()[0], exe, int(venv), int(dev))'
PY="" PY_VERSION="" _venv=0 _dev=0
for cand in "${ROS_SETUP_PYTHON:-}" python3 python3.11; do
    [ -n "$cand" ] && command -v "$cand" >/dev/null 2>&1 || continue
    info=$("$cand" -c "$PY_PROBE" 2>/dev/null || true)
    case "$info" in
        3.11.*) read -r PY_VERSION PY _venv _dev <<<"$info"; break ;;
    esac
done
APT_PKGS=()
if [ -z "$PY" ]; then
    # The ROS wheels are cp311 only.
    APT_PKGS+=(python3.11 python3.11-venv python3.11-dev)
else
    [ "$_venv" = 1 ] || APT_PKGS+=(python3.11-venv)
    [ "$_dev" = 1 ] || APT_PKGS+=(python3.11-dev)
fi
{ command -v cc && command -v c++ && command -v make; } >/dev/null 2>&1 || APT_PKGS+=(build-essential)
command -v unshare >/dev/null 2>&1 || APT_PKGS+=(util-linux)
command -v ip >/dev/null 2>&1 || APT_PKGS+=(iproute2)
command -v sha256sum >/dev/null 2>&1 || APT_PKGS+=(coreutils)
if [ "${#APT_PKGS[@]}" -gt 0 ]; then
    [ "$(id -u)" -eq 0 ] || die "missing ${APT_PKGS[*]} and not root: apt-get install -y ${APT_PKGS[*]}"
    echo "setup.sh: apt-get install ${APT_PKGS[*]}"
    if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${APT_PKGS[@]}"; } \
        >"$ROS_TOP/apt.log" 2>&1; then
        show_log "$ROS_TOP/apt.log"
        die "apt-get install ${APT_PKGS[*]} failed"
    fi
    if [ -z "$PY" ]; then PY=/usr/bin/python3.11; PY_VERSION=$("$PY" -c 'import sys; print(sys.version.split()[0])'); fi
    step_done tools installed "$t0"
else
    step_done tools ok "$t0"
fi

# A venv whose python runs a ROS wheel re-execs itself through ros_wheels_bootstrapper
# unless this is set (env.sh sets LD_LIBRARY_PATH itself).
# setup_distro DISTRO: steps 2-5 for one distribution, in target/ros/DISTRO/.
setup_distro() {
DISTRO=$1
CHANGED=0
ROS_DIR=$ROS_TOP/$DISTRO
VENV=$ROS_DIR/venv
BUILD=$ROS_DIR/build/msgs
INSTALL=$ROS_DIR/msgs_install
STAMPS=$ROS_DIR/stamps
LOGS=$ROS_DIR/logs
PROFILE=$ROS_DIR/fastdds_localhost.xml
ENV_SH=$ROS_DIR/env.sh
ROS_SETUP_SH=$ROS_DIR/ros_setup.sh
case "$DISTRO" in
    kilted) REQ=$HERE/requirements.txt; LOCK=$HERE/requirements.lock ;;
    *) REQ=$HERE/requirements-$DISTRO.txt; LOCK=$HERE/requirements-$DISTRO.lock ;;
esac
mkdir -p "$ROS_DIR" "$STAMPS" "$LOGS"

# ---------------------------------------------------------------------------------
# 2. venv: made afresh whenever the requirements, the interpreter or the recipe change.
t0=$(now_ms)
VENV_KEY=$({ cat "$REQ" "$LOCK"
             echo "python=$PY $PY_VERSION recipe=$VENV_RECIPE"; } | hash_stdin)
if stamp_ok venv "$VENV_KEY" && "$VENV/bin/python" -S -c '' >/dev/null 2>&1; then
    step_done venv skipped "$t0"
else
    CHANGED=1
    rm -f "$STAMPS/venv" "$STAMPS/msgs"
    rm -rf "$VENV"
    "$PY" -m venv "$VENV"
    if ! "$VENV/bin/python" -m pip install --disable-pip-version-check --no-input \
            -r "$REQ" -c "$LOCK" >"$LOGS/pip.log" 2>&1; then
        show_log "$LOGS/pip.log"
        die "pip install into $VENV failed"
    fi
    # Fix: the wheels' exported CMake files name the wheel builder's Python and numpy
    # include directories (/opt/python/cp311-cp311/...); point them at this venv's.
    PYINC=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
    NPINC=$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')
    mapfile -t files < <(grep -rl --include='*.cmake' '/opt/python/cp3' "$VENV/share" "$VENV/lib/cmake" 2>/dev/null || true)
    if [ "${#files[@]}" -gt 0 ]; then
        sed -i \
            -e "s#/opt/python/cp3[0-9]*-cp3[0-9]*/lib/python3\.[0-9]*/site-packages/numpy/_core/include#$NPINC#g" \
            -e "s#/opt/python/cp3[0-9]*-cp3[0-9]*/include/python3\.[0-9]*#$PYINC#g" \
            "${files[@]}"
    fi
    if grep -rl --include='*.cmake' '/opt/python/' "$VENV/share" "$VENV/lib/cmake" 2>/dev/null | head -3 | grep -q .; then
        die "unpatched /opt/python paths remain in $VENV (see: grep -rl --include='*.cmake' /opt/python/ $VENV)"
    fi
    echo "$VENV_KEY" >"$STAMPS/venv"
    step_done venv installed "$t0"
fi

# ---------------------------------------------------------------------------------
# 3. msgs: msg/ built with plain cmake + rosidl, rebuilt from clean when msg/, the venv
#    or this script change.
t0=$(now_ms)
MSGS_KEY=$({ (cd "$ROOT/msg" && find . -type f -print0 | LC_ALL=C sort -z | xargs -0 sha256sum)
             echo "venv=$VENV_KEY distro=$DISTRO"; sha256sum <"$0"; } | hash_stdin)
if stamp_ok msgs "$MSGS_KEY" && [ -d "$INSTALL/lib/python3.11/site-packages/tracer_calib_msgs" ]; then
    step_done msgs skipped "$t0"
else
    CHANGED=1
    rm -f "$STAMPS/msgs"
    rm -rf "$BUILD" "$INSTALL"
    mkdir -p "$BUILD"
    # Fix: AMENT_PREFIX_PATH must name the venv while configuring, or rosidl finds no
    # type support ("No 'rosidl_typesupport_c' found").
    if ! ( export PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" _ROS_WHEELS_BOOTSTRAP_COMPLETE=
           nice -n 10 cmake -S "$ROOT/msg" -B "$BUILD" \
               -DCMAKE_PREFIX_PATH="$VENV" \
               -DPython3_EXECUTABLE="$VENV/bin/python" \
               -DBUILD_TESTING=OFF \
               -DCMAKE_INSTALL_PREFIX="$INSTALL"
           nice -n 10 cmake --build "$BUILD" -j "$JOBS"
           cmake --install "$BUILD"
         ) >"$LOGS/msgs-build.log" 2>&1; then
        show_log "$LOGS/msgs-build.log"
        die "building msg/ failed (full log: $LOGS/msgs-build.log)"
    fi
    echo "$MSGS_KEY" >"$STAMPS/msgs"
    step_done msgs built "$t0"
fi

# ---------------------------------------------------------------------------------
# 4. env: the Fast DDS profile and env.sh (rewritten only when their text changes).
t0=$(now_ms)
env_changed=0
write_if_changed "$PROFILE" env_changed <<'EOF'
<?xml version="1.0" encoding="UTF-8"?>
<!-- Written by tests/interop/setup.sh. Fast DDS (rclpy's rmw_fastrtps_cpp) on the loopback only:
     one UDPv4 transport allowed on 127.0.0.1 only, no shared-memory or other built-in transport,
     discovery by unicast to the initial peer 127.0.0.1 (participant ids 0..31). -->
<dds xmlns="http://www.eprosima.com">
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>udpv4_loopback</transport_id>
        <type>UDPv4</type>
        <maxInitialPeersRange>32</maxInitialPeersRange>
        <interfaceWhiteList>
          <address>127.0.0.1</address>
        </interfaceWhiteList>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="tracer_calib_loopback" is_default_profile="true">
      <rtps>
        <userTransports>
          <transport_id>udpv4_loopback</transport_id>
        </userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
        <builtin>
          <initialPeersList>
            <locator>
              <udpv4>
                <address>127.0.0.1</address>
              </udpv4>
            </locator>
          </initialPeersList>
        </builtin>
      </rtps>
    </participant>
  </profiles>
</dds>
EOF

LIBS_DIRS=$(cd "$VENV/lib/python3.11/site-packages" && for d in ros_*.libs; do [ -d "$d" ] && printf ':$TRACER_ROS_DIR/venv/lib/python3.11/site-packages/%s' "$d"; done; true)
write_if_changed "$ENV_SH" env_changed <<EOF
# Written by tests/interop/setup.sh -- do not edit. Source it:  . target/ros/$DISTRO/env.sh
# Sets this shell's environment for the real ROS 2 peer (rclpy, ROS 2 $DISTRO, Fast DDS) and
# the tracer_calib_msgs built from msg/. Activates nothing globally. Sourcing twice is harmless.
TRACER_ROS_DIR='$ROS_DIR'
export TRACER_ROS_DIR
if [ "\${TRACER_ROS_ENV:-}" != "\$TRACER_ROS_DIR" ]; then
    export TRACER_ROS_ENV="\$TRACER_ROS_DIR"
    export PATH="\$TRACER_ROS_DIR/venv/bin\${PATH:+:\$PATH}"
    export PYTHONPATH="\$TRACER_ROS_DIR/msgs_install/lib/python3.11/site-packages\${PYTHONPATH:+:\$PYTHONPATH}"
    export LD_LIBRARY_PATH="\$TRACER_ROS_DIR/msgs_install/lib:\$TRACER_ROS_DIR/venv/lib$LIBS_DIRS\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
fi
export AMENT_PREFIX_PATH="\$TRACER_ROS_DIR/msgs_install:\$TRACER_ROS_DIR/venv"
# The venv's ros_wheels_bootstrapper would re-exec every python to set LD_LIBRARY_PATH;
# it is set above already.
export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
# Keep DDS on this machine: rmw's localhost discovery (this release ignores
# ROS_LOCALHOST_ONLY) plus a Fast DDS profile allowing UDPv4 on 127.0.0.1 only.
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export FASTDDS_DEFAULT_PROFILES_FILE="\$TRACER_ROS_DIR/fastdds_localhost.xml"
EOF
write_if_changed "$ROS_SETUP_SH" env_changed <<EOF
# Written by tests/interop/setup.sh -- do not edit. Source it:  . target/ros/$DISTRO/ros_setup.sh
# What \`source /opt/ros/$DISTRO/setup.bash\` does, for ROS 2 $DISTRO installed from PyPI wheels
# into target/ros/$DISTRO/venv: the underlay of a colcon workspace (tests/interop/workspace.sh).
# (env.sh is this plus tracer_calib_msgs from target/ros/$DISTRO/msgs_install and the
# loopback-only DDS settings of the tests.)
_tracer_venv='$VENV'
export ROS_DISTRO=$DISTRO ROS_VERSION=2 ROS_PYTHON_VERSION=3
export AMENT_PREFIX_PATH="\$_tracer_venv\${AMENT_PREFIX_PATH:+:\$AMENT_PREFIX_PATH}"
export CMAKE_PREFIX_PATH="\$_tracer_venv\${CMAKE_PREFIX_PATH:+:\$CMAKE_PREFIX_PATH}"
export PATH="\$_tracer_venv/bin\${PATH:+:\$PATH}"
export LD_LIBRARY_PATH="\$_tracer_venv/lib${LIBS_DIRS//\$TRACER_ROS_DIR\/venv/\$_tracer_venv}\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
# cmake's FindPython3 prefers an active venv: the interpreter that has rosidl's modules.
export VIRTUAL_ENV="\$_tracer_venv"
export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
unset _tracer_venv
EOF
if [ "$env_changed" = 1 ]; then CHANGED=1; step_done env written "$t0"; else step_done env unchanged "$t0"; fi

# ---------------------------------------------------------------------------------
# 5. check: imports only (no DDS participant is created), after any change.
t0=$(now_ms)
if [ "$CHANGED" = 1 ] || [ ! -f "$STAMPS/check" ]; then
    rm -f "$STAMPS/check"
    if ! ( . "$ENV_SH"
           timeout -s KILL 60 python -c '
import rclpy, numpy, rosbags
from rclpy.serialization import serialize_message, deserialize_message
from tracer_calib_msgs.msg import RawScan, Contour
from tracer_calib_msgs.srv import Calibrate
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PolygonStamped
from rcl_interfaces.srv import GetParameters, SetParameters, ListParameters
m = RawScan(scan_id=7, step=[1, 2], counts=[-3, 4])
assert deserialize_message(serialize_message(m), RawScan) == m
' ) >"$LOGS/check.log" 2>&1; then
        show_log "$LOGS/check.log"
        die "the installed toolchain does not import (see $LOGS/check.log)"
    fi
    touch "$STAMPS/check"
    step_done check passed "$t0"
else
    step_done check skipped "$t0"
fi

}

for d in "${DISTROS[@]}"; do
    setup_distro "$d"
done
DISTRO=""
# Older callers (tests/bags.rs, fixtures scripts) know target/ros/venv and target/ros/env.sh:
# Kilted's. A tree set up by the single-distribution setup.sh had them as real
# directories and files: replaced by links (its other leftovers removed).
if [ -d "$ROS_TOP/kilted/venv" ]; then
    for old in venv msgs_install build stamps logs env.sh fastdds_localhost.xml; do
        if [ -e "$ROS_TOP/$old" ] && [ ! -L "$ROS_TOP/$old" ]; then rm -rf "${ROS_TOP:?}/$old"; fi
    done
    ln -sfn kilted/venv "$ROS_TOP/venv"
    ln -sfn kilted/env.sh "$ROS_TOP/env.sh"
fi
step_done total done "$T_ALL"

# Regenerating a lock file after changing its requirements file (kilted: requirements.txt
# -> requirements.lock; jazzy: requirements-jazzy.txt -> requirements-jazzy.lock):
#   python3.11 -m venv /tmp/v && /tmp/v/bin/pip install -r tests/interop/requirements-jazzy.txt
#   then list what pip installed (distributions whose INSTALLER is pip, less pip/setuptools)
#   as NAME==VERSION lines, e.g. with importlib.metadata, into the lock file; then
#   rm -rf target/ros/jazzy and run this script.
