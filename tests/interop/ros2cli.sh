#!/usr/bin/env bash
# The real `ros2` command line and launch runtime, installed from source into a
# distribution's wheel venv (no registry ships them as wheels):
#
#   tests/interop/ros2cli.sh [--force] DISTRO...     (after tests/interop/setup.sh DISTRO)
#
# From ../shared/ros2-src/ (or $TRACER_ROS2_SRC), into target/ros/DISTRO/venv:
#   ros2cli.tar.gz            ros2cli, ros2node, ros2topic, ros2service, ros2param,
#                             ros2interface, ros2pkg, ros2run, ros2lifecycle
#   launch.tar.gz             launch, launch_xml, launch_yaml
#   launch_ros.tar.gz         launch_ros, ros2launch (`ros2 launch`)
#   rosidl_runtime_py.tar.gz  rosidl_runtime_py (YAML <-> messages, for the CLI)
#   rcl_interfaces.tar.gz     composition_interfaces (launch_ros imports it), built with
#                             cmake + rosidl like msg/
# with `pip install --no-deps --no-build-isolation` after the pure-Python packages they
# need (tests/interop/requirements-cli.txt, pinned). Then, with target/ros/DISTRO/env.sh
# sourced, `ros2 ...` and `ros2 launch ...` are the stock commands. The CLI starts a
# `ros2 daemon` that outlives a command: pass --no-daemon to every verb that has it (this
# ros2cli reads no environment variable for it; a verb without the flag that asks the
# graph, e.g. `ros2 service type`, starts one), or `ros2 daemon stop` afterwards.
#
# The sources are the Jazzy branches; the same install works in Kilted's venv
# (test_launch.py runs them against the installed package for both distributions; with
# Kilted's rclpy, `ros2 param load` sets the parameters but then fails to list them).
#
# Idempotent: keyed on the tarballs, the requirements, this script and the venv itself
# (a venv made afresh by setup.sh gets it again). Prints one line per distribution.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$HERE/lib.sh"
REQ=$HERE/requirements-cli.txt
SOURCES=(ros2cli launch launch_ros rosidl_runtime_py rcl_interfaces)
# The Python packages, in dependency order: folder in the unpacked sources.
PY_PKGS=(
    rosidl_runtime_py
    ros2cli/ros2cli
    ros2cli/ros2node ros2cli/ros2topic ros2cli/ros2service ros2cli/ros2param
    ros2cli/ros2interface ros2cli/ros2pkg ros2cli/ros2run ros2cli/ros2lifecycle
    launch/launch launch/launch_xml launch/launch_yaml
    launch_ros/launch_ros launch_ros/ros2launch
)

parse_peer_args 27 "$@"
# The sources, checked against ros2-sources.lock (downloaded by their hashes if absent).
paths=$(python3 "$ROOT/scripts/ros2_sources.py" path "${SOURCES[@]}") || exit 1
mapfile -t TARBALLS <<<"$paths"

clean_ros_env


failed=()
for d in "${DISTROS[@]}"; do
    t0=$(now_ms)
    ROS_DIR=$ROOT/target/ros/$d
    VENV=$ROS_DIR/venv
    [ -x "$VENV/bin/python" ] || { echo "ros2cli.sh: $d: no $VENV: run tests/interop/setup.sh $d first" >&2; failed+=("$d"); continue; }
    mkdir -p "$ROS_DIR/stamps" "$ROS_DIR/logs"
    exec 9>"$ROOT/target/ros/.setup.lock"   # the lock setup.sh takes: not while it remakes the venv
    flock 9
    KEY=$({ for t in "${TARBALLS[@]}"; do sha256sum <"$t"; done
            cat "$REQ" "$0"; stat -c 'venv %i %Y' "$VENV/pyvenv.cfg"; } | sha256sum | cut -c1-64)
    STAMP=$ROS_DIR/stamps/cli
    if [ "$FORCE" = 0 ] && [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$KEY" ] && [ -x "$VENV/bin/ros2" ]; then
        exec 9>&-
        echo "ros2cli.sh: $d: ros2 CLI and launch up to date $(took "$t0")"
        continue
    fi
    rm -f "$STAMP"
    log=$ROS_DIR/logs/ros2cli.log
    work=$ROS_DIR/build/ros2cli
    rm -rf "$work"
    mkdir -p "$work/src"
    for t in "${TARBALLS[@]}"; do tar -xzf "$t" -C "$work/src"; done
    if ! ( export PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
           libdirs=$VENV/lib$(cd "$VENV/lib/python3.11/site-packages" && for x in ros_*.libs; do [ -d "$x" ] && printf ':%s' "$PWD/$x"; done; true)
           export LD_LIBRARY_PATH=$libdirs
           set -x   # (set -e does not apply inside `if`: each step says `|| exit`)
           pip install --disable-pip-version-check --no-input -r "$REQ" || exit
           # composition_interfaces: rosidl, like msg/ (setup.sh), installed into the venv.
           nice -n 10 cmake -S "$work/src/rcl_interfaces/composition_interfaces" -B "$work/build" \
               -DCMAKE_PREFIX_PATH="$VENV" -DPython3_EXECUTABLE="$VENV/bin/python" \
               -DBUILD_TESTING=OFF -DCMAKE_INSTALL_PREFIX="$VENV" || exit
           nice -n 10 cmake --build "$work/build" -j "$JOBS" || exit
           cmake --install "$work/build" || exit
           for p in "${PY_PKGS[@]}"; do
               pip install --disable-pip-version-check --no-input --no-deps --no-build-isolation \
                   "$work/src/$p" || exit
           done
         ) >"$log" 2>&1; then
        exec 9>&-
        echo "ros2cli.sh: $d: installing the ros2 CLI failed; last lines of $log:" >&2
        tail -n 25 "$log" >&2
        failed+=("$d")
        continue
    fi
    rm -rf "$work"
    # Check: the commands load (no DDS participant: --help and the ament index only).
    if ! out=$(. "$ROS_DIR/env.sh" && timeout -s KILL 120 bash -c '
            set -e
            verbs=$(ros2 --help | awk "/^Commands:/ { on = 1; next } on && /^  [a-z]/ { print \$1 }" | tr "\n" " ")
            # Every verb installed here (others may be there too: security, from sros2.sh).
            for v in daemon interface launch lifecycle node param pkg run service topic; do
                case " $verbs" in *" $v "*) ;; *) echo "ros2 verbs: $verbs(no $v)"; exit 1 ;; esac
            done
            ros2 pkg prefix rcl_interfaces >/dev/null
            ros2 interface show rcl_interfaces/srv/GetParameters >/dev/null
            ros2 launch --help >/dev/null
            ros2 lifecycle --help >/dev/null
            python -c "import composition_interfaces.srv, launch_ros, launch_xml, launch_yaml"
        ' 2>&1); then
        exec 9>&-
        echo "ros2cli.sh: $d: the installed ros2 CLI does not run: $out" >&2
        failed+=("$d")
        continue
    fi
    echo "$KEY" >"$STAMP"
    exec 9>&-
    echo "ros2cli.sh: $d: ros2 CLI and launch installed $(took "$t0")"
done
if [ "${#failed[@]}" -gt 0 ]; then
    echo "ros2cli.sh: failed: ${failed[*]}" >&2
    exit 1
fi
