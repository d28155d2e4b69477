#!/usr/bin/env bash
# The real `ros2 security` (sros2), installed from source into a distribution's wheel venv
# that already has the ros2 CLI (tests/interop/ros2cli.sh):
#
#   tests/interop/sros2.sh [--force] DISTRO...     (after setup.sh DISTRO and ros2cli.sh DISTRO)
#
# From ../shared/ros2-src/sros2.tar.gz (or $TRACER_ROS2_SRC), the `sros2/sros2` package,
# with `pip install --no-deps --no-build-isolation` after what it needs
# (tests/interop/requirements-sros2.txt, pinned: cryptography < 42 and lxml). Then, with
# target/ros/DISTRO/env.sh sourced, `ros2 security create_keystore / create_enclave /
# create_permission / generate_artifacts` are the stock commands.
#
# Idempotent: keyed on the tarball, the requirements, this script and the venv itself.
# Prints one line per distribution.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$HERE/lib.sh"
REQ=$HERE/requirements-sros2.txt

parse_peer_args 14 "$@"
# The source, checked against ros2-sources.lock (downloaded by its hash if absent).
TARBALL=$(python3 "$ROOT/scripts/ros2_sources.py" path sros2) || exit 1

clean_ros_env


failed=()
for d in "${DISTROS[@]}"; do
    t0=$(now_ms)
    ROS_DIR=$ROOT/target/ros/$d
    VENV=$ROS_DIR/venv
    [ -x "$VENV/bin/ros2" ] || { echo "sros2.sh: $d: no ros2 CLI in $VENV: run tests/interop/ros2cli.sh $d first" >&2; failed+=("$d"); continue; }
    mkdir -p "$ROS_DIR/stamps" "$ROS_DIR/logs"
    exec 9>"$ROOT/target/ros/.setup.lock"   # the lock setup.sh takes: not while it remakes the venv
    flock 9
    KEY=$({ sha256sum <"$TARBALL"; cat "$REQ" "$0"; stat -c 'venv %i %Y' "$VENV/pyvenv.cfg"; } | sha256sum | cut -c1-64)
    STAMP=$ROS_DIR/stamps/sros2
    if [ "$FORCE" = 0 ] && [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$KEY" ]; then
        exec 9>&-
        echo "sros2.sh: $d: ros2 security up to date $(took "$t0")"
        continue
    fi
    rm -f "$STAMP"
    log=$ROS_DIR/logs/sros2.log
    work=$ROS_DIR/build/sros2
    rm -rf "$work"
    mkdir -p "$work/src"
    tar -xzf "$TARBALL" -C "$work/src"
    if ! ( export PATH="$VENV/bin:$PATH" _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
           set -x
           pip install --disable-pip-version-check --no-input -r "$REQ" || exit
           pip install --disable-pip-version-check --no-input --no-deps --no-build-isolation \
               "$work/src/sros2/sros2" || exit
         ) >"$log" 2>&1; then
        exec 9>&-
        echo "sros2.sh: $d: installing sros2 failed; last lines of $log:" >&2
        tail -n 25 "$log" >&2
        failed+=("$d")
        continue
    fi
    rm -rf "$work"
    # Check: a keystore and an enclave, made in a scratch folder (no DDS participant).
    scratch=$(mktemp -d)
    if ! out=$(. "$ROS_DIR/env.sh" && cd "$scratch" && timeout -s KILL 120 bash -c '
            set -e
            ros2 security create_keystore ks >/dev/null
            ros2 security create_enclave ks /check >/dev/null
            for f in identity_ca.cert.pem cert.pem key.pem permissions_ca.cert.pem governance.p7s permissions.p7s; do
                [ -f ks/enclaves/check/$f ] || { echo "no ks/enclaves/check/$f"; exit 1; }
            done
        ' 2>&1); then
        rm -rf "$scratch"
        exec 9>&-
        echo "sros2.sh: $d: the installed ros2 security does not run: $out" >&2
        failed+=("$d")
        continue
    fi
    rm -rf "$scratch"
    echo "$KEY" >"$STAMP"
    exec 9>&-
    echo "sros2.sh: $d: ros2 security installed $(took "$t0")"
done
if [ "${#failed[@]}" -gt 0 ]; then
    echo "sros2.sh: failed: ${failed[*]}" >&2
    exit 1
fi
