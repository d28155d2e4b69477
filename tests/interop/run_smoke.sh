#!/usr/bin/env bash
# Smoke test of the real ROS 2 peer: runs tests/interop/setup.sh (quick when up to date),
# then, inside one private network namespace (tests/interop/netns.sh), smoke.py in one
# process and then as pub + sub and server + client in four processes. Every peer runs
# under `timeout -s KILL`; stale /dev/shm/fastdds_* are cleaned afterwards.
# Exit status 0 when all pass. Prints `N passed, N failed`.
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
"$HERE/setup.sh"
trap '"$HERE/shm_clean.sh" || true' EXIT
# shellcheck disable=SC2016
"$HERE/netns.sh" bash -c '
    set -u
    . "$1/target/ros/env.sh"
    S=$1/tests/interop/smoke.py
    K="timeout -s KILL 40"
    pass=0 fail=0
    count() { if [ "$1" = 0 ]; then pass=$((pass + 1)); else fail=$((fail + 1)); fi; }
    $K python "$S" self; count $?
    $K python "$S" sub & a=$!
    $K python "$S" pub & b=$!
    $K python "$S" server & c=$!
    $K python "$S" client & d=$!
    for p in $a $b $c $d; do wait $p; count $?; done
    echo "$pass passed, $fail failed"
    [ "$fail" = 0 ]
' run_smoke "$ROOT"
