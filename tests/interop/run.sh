#!/usr/bin/env bash
# The real-ROS-2-peer tests, once per ROS 2 distribution (Kilted, then Jazzy, the LTS):
#   1. tests/interop/setup.sh DISTRO: rclpy + tracer_calib_msgs (quick when up to date),
#      then tests/interop/ros2cli.sh DISTRO: the stock `ros2` command line (ros2cli: node,
#      topic, service, param, interface, pkg, run, lifecycle) and launch runtime (launch,
#      launch_xml, launch_yaml, launch_ros, ros2launch), from ../shared/ros2-src/, into the
#      distribution's venv (quick when installed);
#   2. against the release binaries (in cargo's target directory: scripts/target_dir.sh),
#      with the peer's environment target/ros/DISTRO/env.sh:
#      every suite with pytest (tests/interop/conftest.py; pytest installed into the venv
#      from requirements-pytest.txt; a JUnit report a suite in target/interop-junit/):
#      - test_node.py's tests, then test_records.py's, in a private network namespace;
#      - test_graph.py, the node in the ROS graph (leaving it, matching, QoS), in a private
#        network namespace too;
#      - test_type_hash.py, type hashes and ~/get_type_description (REP-2016), likewise;
#      - test_runtime.py, sim time, parameter descriptors, the managed (lifecycle) node,
#        `-p` rules as rcl reads them;
#      - test_first_scan.py, a new driver's first scan reaches the node at once (50 fresh
#        rclpy peers on Fast DDS; for Jazzy also on Cyclone DDS, after cyclone.sh), and a
#        new client's first call is answered at once (20 fresh clients), likewise;
#      - test_lossy.py, under 10 and 25 % UDP loss: the node and a stock rclpy node in its
#        place side by side (contours lost, latency, calls, parameters, the latched
#        calibration), with Fast DDS peers and (Jazzy) Cyclone DDS peers;
#      - test_two_hosts.py on two "hosts", network namespaces joined by a veth pair with
#        multicast off (tests/interop/two_hosts.sh; root only);
#   3. tests/interop/workspace.sh DISTRO: the README's `colcon build` in a workspace over
#      the distribution's wheels, and what it installs;
#   4. test_launch.py against that workspace, in a private network namespace, in the
#      environment of a shell that sourced ROS 2 and the workspace's install/setup.bash:
#      the real `ros2 launch` of each launch file, `ros2 run`, `ros2 service call`,
#      `ros2 param`, `ros2 topic`, `ros2 node`, Ctrl-C of a launch; no `ros2 daemon` left.
#      Whatever is still running in that namespace after it (a launch, a node, a daemon)
#      is listed, killed, and fails the step.
# Nothing leaves the machine. Prints each part's time. The set-ups (1, 3 and the stock
# peers below) run first, one distribution after the other; then the suites (2, 4) in two
# lanes side by side, each lane's output printed whole when it ends (TRACER_INTEROP_LANES=1:
# one lane after the other, as they come).
#   tests/interop/run.sh [TEST_NAME...]
# Names starting with graph select test_graph.py's tests (graph: all), type_hash
# test_type_hash.py's (type_hash: all), runtime or sim_time, replay_clock, describe,
# lifecycle, bond, rcl_param_rules test_runtime.py's (runtime: all), first_scan test_first_scan.py's
# (first_scan: all; first_scan_fastdds, first_scan_cyclone, first_scan_call_fastdds,
# first_scan_call_cyclone), lossy test_lossy.py's (lossy: all; lossy_fastdds_10, ...), two_hosts test_two_hosts.py's scenarios (two_hosts:
# all), cyclone or mixed test_cyclone.py's (cyclone: all), security or secure_* or
# insecure_* or hmi_* or capture_* or foreign_* or *_missing_enclave or
# *_bad_credentials test_security.py's (security: all), launch test_launch.py's
# (launch_NAME: its test NAME; launch: all, with 3 before it); the others, test_node.py's
# and test_records.py's tests (conftest.py: a parametrized test's name is its function's
# and its parameters', e.g. lossy_fastdds_10_delay, first_scan_call_cyclone). With names, 3 and 4 run only for launch names. No names: everything.
# Also: after 1, tests/interop/ros2cli.sh installs the stock ros2 CLI and launch into the
# venv; (2b, after 2, Jazzy) tests/interop/cyclone.sh builds rmw_cyclonedds_cpp (cached
# outside the clone), and test_cyclone.py runs with the node's peers on Cyclone DDS, and
# on both DDS at once; (2c, Jazzy) test_security.py, SROS2 with a secure Cyclone DDS peer
# (tests/interop/sros2.sh installs `ros2 security`), against the release node, which
# scripts/test.sh builds with the cargo feature `security` (a node built without it
# fails these tests: it cannot be secure).
# (2d, Jazzy; zenoh or zenoh_NAME) tests/interop/zenoh.sh builds rmw_zenoh_cpp and its
# router rmw_zenohd (cached outside the clone: built the first time, BENCHMARKS.md; reused
# after), and test_zenoh.py runs the node on Zenoh (RMW_IMPLEMENTATION=
# rmw_zenoh_cpp) with stock rclpy peers on rmw_zenoh_cpp and the stock ros2 CLI through the
# router, in a private network namespace.
# (2e, Jazzy; rosbag2 or rosbag2_NAME, e.g. rosbag2_record_mcap) tests/interop/rosbag2.sh
# builds the stock `ros2 bag` (rosbag2 from ../shared/ros2-src/, cached outside the clone;
# built the first time, BENCHMARKS.md; reused after), and test_rosbag2.py runs `ros2 bag
# record` (MCAP, sqlite3, service events), `info` and `play --clock` against the node and
# `tracer_calib calibrate`/`correct` on what it recorded, peers on Fast DDS, in a private
# network namespace.
#   TRACER_ROS_DISTROS="jazzy" tests/interop/run.sh    (default: "kilted jazzy")
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$HERE/lib.sh"
DISTROS=${TRACER_ROS_DISTROS:-kilted jazzy}
trap '"$HERE/shm_clean.sh" >/dev/null 2>&1 || true' EXIT
. "$ROOT/scripts/target_dir.sh"
# (TRACER_CALIB_NODE and TRACER_CALIB, when set, name other release binaries: a worktree's
# run against a checkout's build.)
export TRACER_CALIB_NODE="${TRACER_CALIB_NODE:-$TRACER_RELEASE_DIR/tracer_calib_node}"
export TRACER_CALIB="${TRACER_CALIB:-$TRACER_RELEASE_DIR/tracer_calib}"
node_tests=() graph=() type_hash=() runtime=() first_scan=() lossy=() two_hosts=() cyclone=() security=() zenoh=() rosbag2=() launch=()
for a in "$@"; do
    case "$a" in
        launch) launch+=(all) ;;
        launch_*) launch+=("${a#launch_}") ;;
        graph*) graph+=("$a") ;;
        type_hash*) type_hash+=("$a") ;;
        runtime | sim_time* | replay_clock | describe | lifecycle | bond | rcl_param_rules) runtime+=("$a") ;;
        first_scan*) first_scan+=("$a") ;;
        lossy*) lossy+=("$a") ;;
        two_hosts*) two_hosts+=("$a") ;;
        cyclone*|mixed*) cyclone+=("$a") ;;
        security|secure_*|insecure_*|hmi_*|capture_*|foreign_*|*_missing_enclave|*_bad_credentials) security+=("$a") ;;
        zenoh*) zenoh+=("$a") ;;
        rosbag2) rosbag2+=(rosbag2) ;;
        rosbag2_*) rosbag2+=("${a#rosbag2_}") ;;
        *) node_tests+=("$a") ;;
    esac
done
# The release binaries.
for b in "$TRACER_CALIB_NODE" "$TRACER_CALIB"; do
    [ -x "$b" ] || { echo "missing $b: run 'cargo build --release' first" >&2; exit 2; }
done
# Each suite's JUnit report: target/interop-junit/DISTRO-SUITE.xml.
JUNIT=$ROOT/target/interop-junit
rm -rf "$JUNIT"
mkdir -p "$JUNIT"
# peer_run WRAPPER SCRIPTS DISTRO RMW_ENV REPORT [NAME...]: pytest on SCRIPTS (test files,
# space-separated; tests/interop/conftest.py) under WRAPPER (netns.sh, two_hosts.sh) in the
# peer's environment (target/ros/DISTRO/env.sh), and with RMW_ENV (cyclone_env.sh,
# zenoh_env.sh; empty: Fast DDS) sourced after it; the tests the NAMEs select (all if
# none), the JUnit report $JUNIT/DISTRO-REPORT.xml. Killed after SUITE_LIMIT seconds (600
# unless set for it: a hang fails, it does not stop CI).
peer_run() {
    local wrapper=$1 scripts=$2 d=$3 rmw_env=$4 report=$5 args=() f n
    shift 5
    for f in $scripts; do args+=("$HERE/$f"); done
    for n in "$@"; do args+=(--name "$n"); done
    # shellcheck disable=SC2016
    "$HERE/$wrapper" bash -c '
        . "$0/target/ros/$1/env.sh"
        [ ! -f "$0/target/ros/$1/bond_env.sh" ] || . "$0/target/ros/$1/bond_env.sh"
        [ -z "$2" ] || . "$0/target/ros/$1/$2"
        limit=$3
        shift 3
        exec timeout -s KILL "$limit" python -m pytest "$@"
    ' "$ROOT" "$d" "$rmw_env" "${SUITE_LIMIT:-600}" -c "$HERE/pytest.ini" --rootdir "$HERE" \
        --junitxml "$JUNIT/$d-$report.xml" "${args[@]}"
}
# Failures, one `DISTRO:WHAT` a line: the lanes below run in subshells of their own.
FAILS=$(mktemp)
LANES=$(mktemp -d)
trap '"$HERE/shm_clean.sh" >/dev/null 2>&1 || true; rm -rf "$FAILS" "$LANES"' EXIT
fail() { echo "$1" >>"$FAILS"; }
all=$(( $# == 0 ))
# wanted ARRAY_LENGTH: whether a suite runs (everything with no names, else its own names).
wanted() { [ "$all" -eq 1 ] || [ "$1" -gt 0 ]; }
# suite_in WRAPPER RMW_ENV SCRIPTS DISTRO WHAT FAILURE [NAME...]: a suite's test files
# through WRAPPER (netns.sh: a private network namespace; two_hosts.sh) with RMW_ENV
# (peer_run), with the NAMEs selected for it; skipped when names were given to run.sh and
# none is its own. Prints its time; a failure is recorded as DISTRO:FAILURE, its JUnit
# report is $JUNIT/DISTRO-FAILURE.xml.
suite_in() {
    local wrapper=$1 rmw_env=$2 scripts=$3 d=$4 what=$5 failure=$6
    shift 6
    [ "$all" -eq 1 ] || [ "$#" -gt 0 ] || return 0
    local t0
    t0=$(now_ms)
    echo "run.sh: $d: $scripts ($what)"
    peer_run "$wrapper" "$scripts" "$d" "$rmw_env" "$failure" "$@" || fail "$d:$failure"
    echo "run.sh: $d: $scripts $(took "$t0")"
}
# suite SCRIPT DISTRO WHAT FAILURE [NAME...]: suite_in a private network namespace, Fast DDS.
suite() { suite_in netns.sh "" "$@"; }
# built WHAT DISTRO CMD...: a set-up step; prints its time if it succeeded, and its status.
built() {
    local what=$1 d=$2 t0
    shift 2
    t0=$(now_ms)
    "$@" || return 1
    echo "run.sh: $d: $what $(took "$t0")"
}

# pytest_in_venv DISTRO: the suites' runner (requirements-pytest.txt) in the distribution's
# venv, on top of setup.sh's (quick when installed: keyed on the file and the venv's stamp,
# so a venv made afresh gets it again).
pytest_in_venv() {
    local ros=$ROOT/target/ros/$1 key
    key=$(cat "$HERE/requirements-pytest.txt" "$ros/stamps/venv" | sha256sum | cut -c1-64)
    [ "$(cat "$ros/stamps/pytest" 2>/dev/null)" != "$key" ] || return 0
    if ! "$ros/venv/bin/python" -m pip install -q --disable-pip-version-check --no-input --no-deps \
            --require-hashes -r "$HERE/requirements-pytest.txt" >"$ros/logs/pytest.log" 2>&1; then
        tail -n 20 "$ros/logs/pytest.log" >&2
        return 1
    fi
    echo "$key" >"$ros/stamps/pytest"
    echo "run.sh: $1: pytest installed in its venv"
}

# 1. Everything the suites need, one distribution after the other (builds and installs,
# quick when cached): the suites below only run.
cyclone_ok=0 zenoh_ok=0 sros2_ok=0
declare -A workspace_ok=()
for d in $DISTROS; do
    t0=$(now_ms)
    "$HERE/setup.sh" "$d" >/dev/null
    pytest_in_venv "$d"
    # The stock ros2 CLI and launch in the venv (quick when installed): test_cyclone.py's
    # and test_launch.py's.
    "$HERE/ros2cli.sh" "$d"
    # The stock bond packages (bond, smclib, bondpy; quick when built): test_runtime.py's bond.
    "$HERE/bond.sh" "$d"
    # The stock ros2 bag (rosbag2; Jazzy only; quick when built): test_rosbag2.py's.
    if [ "$d" = jazzy ] && wanted "${#rosbag2[@]}" && ! "$HERE/rosbag2.sh" "$d"; then
        fail "$d:rosbag2_setup"
    fi
    # rmw_cyclonedds_cpp, `ros2 security` and rmw_zenoh_cpp (Jazzy only: see 2b-2d), for
    # test_first_scan.py's and test_lossy.py's peers on them and their own suites.
    if [ "$d" = jazzy ]; then
        if wanted $(( ${#first_scan[@]} + ${#lossy[@]} + ${#cyclone[@]} + ${#security[@]} )); then
            if built rmw_cyclonedds_cpp "$d" "$HERE/cyclone.sh" "$d"; then cyclone_ok=1; else fail "$d:cyclone_setup"; fi
        fi
        if [ "$cyclone_ok" -eq 1 ] && wanted "${#security[@]}"; then
            if "$HERE/sros2.sh" "$d"; then sros2_ok=1; else fail "$d:security_setup"; fi
        fi
        if wanted $(( ${#lossy[@]} + ${#zenoh[@]} )); then
            if built rmw_zenoh_cpp "$d" "$HERE/zenoh.sh" "$d"; then zenoh_ok=1; else fail "$d:zenoh_setup"; fi
        fi
    fi
    # 3. The README's `colcon build` (test_launch.py's workspace). One at a time: the
    # workspaces share cargo's target directory.
    if [ "$#" -eq 0 ] || [ "${#launch[@]}" -gt 0 ]; then
        if built workspace "$d" "$HERE/workspace.sh" "$d"; then workspace_ok[$d]=1; else fail "$d:workspace"; fi
    fi
    echo "run.sh: $d: setup $(took "$t0")"
done
if wanted "${#lossy[@]}"; then
    # iptables' NFQUEUE and a venv with NetfilterQueue (built against
    # libnetfilter-queue): tests/interop/netdelay.py, the *_delay scenarios' delay.
    apt_install_missing run.sh "$ROOT/target/lossy_deps.log" nftables iptables libnetfilter-queue-dev
    if [ ! -x "$ROOT/target/tools/netdelay/bin/python" ] \
        || ! "$ROOT/target/tools/netdelay/bin/python" -c 'import netfilterqueue' 2>/dev/null; then
        rm -rf "$ROOT/target/tools/netdelay"
        python3 -m venv "$ROOT/target/tools/netdelay" \
            && "$ROOT/target/tools/netdelay/bin/pip" install -q NetfilterQueue==1.1.0 \
                >"$ROOT/target/netdelay_setup.log" 2>&1 \
            || { tail -n 20 "$ROOT/target/netdelay_setup.log" >&2; fail "netdelay_setup"; }
    fi
    export TRACER_NETDELAY_PYTHON=$ROOT/target/tools/netdelay/bin/python
fi

# 2. The suites, in two lanes side by side (each suite in network namespaces of its own,
# which share nothing with the other lane's; TRACER_INTEROP_LANES=1: one after the other).
# Most of a suite's time is waiting (discovery, loss, timeouts), not computing: the lanes
# are balanced by time, one the DDS graph, the CLI and launch, the other loss and the
# other middleware.
lane_dds() {
    local d
    for d in $DISTROS; do
        suite "test_node.py test_records.py" "$d" "ROS 2 $d rclpy, release binaries" node_suite \
            ${node_tests[@]+"${node_tests[@]}"}
        suite test_graph.py "$d" "ROS 2 $d rclpy, release binaries" test_graph ${graph[@]+"${graph[@]}"}
        suite test_type_hash.py "$d" "ROS 2 $d rclpy, release binaries" test_type_hash ${type_hash[@]+"${type_hash[@]}"}
        suite test_runtime.py "$d" "ROS 2 $d rclpy, release binaries" test_runtime ${runtime[@]+"${runtime[@]}"}
        # test_first_scan.py's Cyclone DDS peers need rmw_cyclonedds_cpp (Jazzy only: see
        # 2b); without it first_scan_cyclone says it is skipped.
        suite test_first_scan.py "$d" "ROS 2 $d rclpy, release binaries" test_first_scan \
            ${first_scan[@]+"${first_scan[@]}"}
        if wanted "${#two_hosts[@]}" && [ "$(id -u)" -ne 0 ]; then
            echo "run.sh: $d: two_hosts skipped (needs root for ip netns)"
        elif [ "$(id -u)" -eq 0 ]; then
            suite_in two_hosts.sh "" test_two_hosts.py "$d" "ROS 2 $d rclpy, release binaries" two_hosts \
                ${two_hosts[@]+"${two_hosts[@]}"}
        fi
        # 2b. Cyclone DDS peers (test_cyclone.py), with the stock ros2 CLI. Jazzy only: the
        # rmw_cyclonedds tarball is its Jazzy branch, which does not build against Kilted's
        # wheels (rmw_dds_common 4.0 has no security.hpp any more).
        if [ "$d" != jazzy ] && wanted "${#cyclone[@]}"; then
            echo "run.sh: $d: test_cyclone.py skipped (rmw_cyclonedds_cpp is built for jazzy only)"
        elif [ "$cyclone_ok" -eq 1 ]; then
            suite_in netns.sh cyclone_env.sh test_cyclone.py "$d" \
                "ROS 2 $d rclpy on Cyclone DDS and Fast DDS, release binaries" test_cyclone ${cyclone[@]+"${cyclone[@]}"}
        fi
        # 4. test_launch.py in the installed workspace.
        [ "$#" -eq 0 ] || [ "${#launch[@]}" -gt 0 ] || continue
        [ "${workspace_ok[$d]:-0}" -eq 1 ] || continue
        launch_suite "$d"
    done
}
lane_loss() {
    local d
    for d in $DISTROS; do
        # test_lossy.py: the node and a stock rclpy node in its place under 10 and 25 % UDP
        # loss (nftables, in a network namespace of each scenario's own), and under 10 % loss
        # with datagrams delayed and reordered, with Fast DDS peers and, on Jazzy, Cyclone DDS
        # and Zenoh peers (cyclone_env.sh, zenoh_env.sh; Kilted's lossy_cyclone_* and
        # lossy_zenoh_* say they are skipped; Zenoh under 25 % loss also with TCP's
        # retransmission timeout capped at 1 s); ten cells started at once under 10 % (Fast
        # DDS planner) and 25 % loss (Cyclone DDS planner). 14 scenarios of 30-60 s, each
        # bounded at 300 s by test_lossy.py itself.
        SUITE_LIMIT=1200 suite test_lossy.py "$d" "ROS 2 $d rclpy under packet loss, release binaries" test_lossy \
            ${lossy[@]+"${lossy[@]}"}
        # 2c. SROS2 (test_security.py): the release node (built with `security`), `ros2
        # security`, and a secure Cyclone DDS peer (Debian's Cyclone security plugins). Jazzy
        # only, as 2b.
        if [ "$d" != jazzy ] && wanted "${#security[@]}"; then
            echo "run.sh: $d: test_security.py skipped (rmw_cyclonedds_cpp is built for jazzy only)"
        elif [ "$sros2_ok" -eq 1 ]; then
            # test_security.py runs each test in a process of its own and reruns one whose
            # rclpy peer segfaulted (Cyclone DDS 0.10.2; eclipse-cyclonedds/cyclonedds#1548).
            TRACER_CALIB_NODE_SECURE="$TRACER_CALIB_NODE" suite_in netns.sh cyclone_env.sh test_security.py "$d" \
                "secure node, ROS 2 $d rclpy on Cyclone DDS with security" test_security ${security[@]+"${security[@]}"}
        fi
        # 2d. The node in a Zenoh cell with stock rmw_zenoh peers (test_zenoh.py). Jazzy
        # only: the rmw_zenoh tarball is Jazzy's release (0.2.10).
        if [ "$d" != jazzy ] && wanted "${#zenoh[@]}"; then
            echo "run.sh: $d: test_zenoh.py skipped (rmw_zenoh_cpp is built for jazzy only)"
        elif [ "$d" = jazzy ] && [ "$zenoh_ok" -eq 1 ]; then
            suite_in netns.sh zenoh_env.sh test_zenoh.py "$d" "ROS 2 $d rclpy on rmw_zenoh_cpp through rmw_zenohd" \
                test_zenoh ${zenoh[@]+"${zenoh[@]}"}
        fi
        # 2e. The stock `ros2 bag` (test_rosbag2.py) against the node, peers on Fast DDS,
        # with target/ros/jazzy/rosbag2_env.sh. Jazzy only: rosbag2.sh builds Jazzy's rosbag2.
        if [ "$d" != jazzy ] && wanted "${#rosbag2[@]}"; then
            echo "run.sh: $d: test_rosbag2.py skipped (rosbag2 is built for jazzy only)"
        elif wanted "${#rosbag2[@]}"; then
            if [ -f "$ROOT/target/ros/$d/rosbag2_env.sh" ]; then
                suite_in netns.sh rosbag2_env.sh test_rosbag2.py "$d" \
                    "the stock ros2 bag, ROS 2 $d rclpy, release binaries" test_rosbag2 ${rosbag2[@]+"${rosbag2[@]}"}
            else
                fail "$d:rosbag2_setup"
            fi
        fi
    done
}
# 4. test_launch.py DISTRO: the installed workspace, the stock ros2 CLI and launch.
launch_suite() {
    local d=$1 t0 names=() n
    t0=$(now_ms)
    echo "run.sh: $d: test_launch.py (installed workspace; the stock ros2 CLI and launch, ROS 2 $d)"
    for n in ${launch[@]+"${launch[@]}"}; do [ "$n" = all ] || names+=(--name "$n"); done
    # The environment of a shell that sourced ROS 2 and the workspace, plus the loopback-only
    # DDS settings of the tests. Then whatever is left running in the namespace.
    # shellcheck disable=SC2016
    if ! "$HERE/netns.sh" env -i HOME="$HOME" PATH="$PATH" bash -c '
        . "$1/target/ros/$2/ros_setup.sh"
        . "$1/target/colcon_ws/$2/install/setup.bash"
        export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
        export FASTDDS_DEFAULT_PROFILES_FILE="$1/target/ros/$2/fastdds_localhost.xml"
        script=$0 here=$3 report=$4
        shift 4
        rc=0
        timeout -s KILL 600 python -m pytest -c "$here/pytest.ini" --rootdir "$here" --junitxml "$report" \
            "$script" "$@" || rc=$?
        me=$(readlink /proc/$$/ns/net)
        left=()
        for p in /proc/[0-9]*; do
            pid=${p#/proc/}
            [ "$pid" != $$ ] && [ "$(readlink "$p/ns/net" 2>/dev/null)" = "$me" ] || continue
            cmd=$(tr "\0" " " <"$p/cmdline" 2>/dev/null) && [ -n "$cmd" ] || continue
            echo "run.sh: left running in the test namespace: $pid $cmd" >&2
            left+=("$pid")
        done
        [ "${#left[@]}" -eq 0 ] || { kill -KILL "${left[@]}" 2>/dev/null; rc=1; }
        exit "$rc"
    ' "$HERE/test_launch.py" "$ROOT" "$d" "$HERE" "$JUNIT/$d-test_launch.xml" ${names[@]+"${names[@]}"}; then
        fail "$d:test_launch"
    fi
    echo "run.sh: $d: test_launch.py $(took "$t0")"
}
if [ "${TRACER_INTEROP_LANES:-2}" = 1 ]; then
    lane_dds "$@"
    lane_loss "$@"
else
    # Each lane's output whole, when it ends (first ended, first printed).
    declare -A lane_of=()
    for lane in dds loss; do
        ( t0=$(now_ms); rc=0; "lane_$lane" "$@" || rc=$?; echo "run.sh: lane $lane $(took "$t0")"
          [ "$rc" -eq 0 ] || fail "lane_$lane:exit_$rc" ) >"$LANES/$lane.log" 2>&1 &
        lane_of[$!]=$lane
        echo "run.sh: lane $lane started (its output when it ends)"
    done
    while [ "${#lane_of[@]}" -gt 0 ]; do
        ended=
        wait -n -p ended "${!lane_of[@]}" || true
        [ -n "$ended" ] || break
        cat "$LANES/${lane_of[$ended]}.log"
        unset "lane_of[$ended]"
    done
fi
if [ -s "$FAILS" ]; then
    echo "run.sh: failed: $(tr '\n' ' ' <"$FAILS")" >&2
    exit 1
fi
