#!/usr/bin/env bash
# The vendored rustdds' own unit tests (vendor/rustdds/PATCHES.md: each patch's tests sit
# beside the crate's). The copy the build uses is no workspace member and has no
# dev-dependencies, so cargo cannot test it in place: this tests a scratch copy of it,
# under cargo's target directory, with the dev-dependencies its tests use and the
# versions of vendor/rustdds/tests.Cargo.lock. The crates are fetched first; the tests
# then run offline, in a private network namespace whose loopback carries multicast (some
# tests open sockets and send SPDP). Built with the feature `security`, as the node's
# secure build uses the crate: its security tests run too (722 tests, 2026-11-26).
#   bash scripts/test_vendored.sh [TESTNAME_FILTER]
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/target_dir.sh
work=$TRACER_TARGET_DIR/vendored-tests/rustdds
mkdir -p "$work"
rm -rf "$work/src"
cp -r vendor/rustdds/src "$work/src"
cp vendor/rustdds/tests.Cargo.lock "$work/Cargo.lock"
{
    cat vendor/rustdds/Cargo.toml
    cat <<'TOML'

# Added by scripts/test_vendored.sh: what the crate's unit tests use.
[dev-dependencies]
anyhow = "1"
env_logger = "0.11"
hex-literal = "0.4"
test-case = "3"
test-log = "0.2"

[workspace]
TOML
} >"$work/Cargo.toml"
export CARGO_TARGET_DIR=$TRACER_TARGET_DIR/vendored-tests/target
(cd "$work" && cargo fetch --locked)
(cd "$work" && cargo test --locked --lib --features security --no-run)
# Multicast on the namespace's loopback (the crate's discovery and socket tests use it).
tests/interop/netns.sh bash -c "ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo &&
    cd '$work' && cargo test --locked --offline --lib --features security -- ${1:-}"
