#!/usr/bin/env bash
# Fuzz every target in fuzz/ for a bounded time, one after the other:
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET]      (default 60)
#   FUZZ_TARGETS="oma csv" scripts/fuzz.sh 30 (a subset)
#
# Engine: libFuzzer through cargo-fuzz (`cargo install cargo-fuzz`; installed here if
# missing), with AddressSanitizer, on the *stable* toolchain: cargo-fuzz needs nightly
# flags (-Zsanitizer, sancov passes), which RUSTC_BOOTSTRAP=1 unlocks on stable.
#
# Seeds are read from fuzz/corpus/<target>/ (small, committed; regenerate with
# `cargo run --manifest-path fuzz/Cargo.toml --example make_seeds`); what the fuzzer
# learns goes to fuzz/corpus-work/<target>/ (not committed), so later runs start from
# there. A crash, panic, broken invariant, timeout or out-of-memory leaves its input
# under fuzz/artifacts/<target>/, and the script exits non-zero once every target ran.
# Replay one: cargo fuzz run <target> fuzz/artifacts/<target>/<file>
#
# Builds go to $CARGO_TARGET_DIR if set (else fuzz/target). Everything runs under nice,
# one fuzzing process at a time.
set -uo pipefail
cd "$(dirname "$0")/.."

SECONDS_PER_TARGET="${1:-60}"
if ! [[ "$SECONDS_PER_TARGET" =~ ^[1-9][0-9]*$ ]]; then
    echo "usage: $0 [SECONDS_PER_TARGET]   (a whole number of seconds, default 60)" >&2
    exit 2
fi
TARGETS="${FUZZ_TARGETS:-raw_scan params_file csv oma ros_args}"

export RUSTC_BOOTSTRAP=1
export CARGO_TERM_COLOR=never
# AddressSanitizer's ODR check trips on the bundled sqlite3 (two copies of a static
# table); cargo-fuzz sets this too.
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_odr_violation=0}"

if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "== installing cargo-fuzz"
    nice cargo install --locked cargo-fuzz || exit 2
fi

echo "== building the fuzz targets"
nice cargo fuzz build -O || exit 2

# Per-target libFuzzer options: raw_scan inputs up to ~2400 samples (the fit runs on
# scans of at most 2000); text targets use a dictionary of their tokens.
options_for() {
    case "$1" in
        raw_scan) echo "-max_len=20000" ;;
        *) [[ -f "fuzz/dicts/$1.dict" ]] && echo "-dict=fuzz/dicts/$1.dict" ;;
    esac
}

failed=()
summary=()
for target in $TARGETS; do
    work="fuzz/corpus-work/$target"
    seeds="fuzz/corpus/$target"
    mkdir -p "$work" "fuzz/artifacts/$target"
    log="fuzz/artifacts/$target/last-run.log"
    echo "== fuzzing $target for ${SECONDS_PER_TARGET}s (log: $log)"
    # shellcheck disable=SC2046
    nice cargo fuzz run -O "$target" "$work" "$seeds" -- \
        -max_total_time="$SECONDS_PER_TARGET" -timeout=30 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
        -print_final_stats=1 $(options_for "$target") >"$log" 2>&1
    rc=$?
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
    cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -1)
    if [[ $rc -ne 0 ]]; then
        failed+=("$target")
        echo "!! $target FAILED (exit $rc); the input is under fuzz/artifacts/$target/:"
        grep -E 'panicked at|SUMMARY|ERROR: libFuzzer|Test unit written to|deadly signal|timeout|out-of-memory' "$log" | head -8
        summary+=("$target: FAILED after ${runs:-?} runs")
    else
        summary+=("$target: ok, ${runs:-?} runs, ${rate:-?} exec/s, ${cov:-cov: ?}")
    fi
done

echo "== summary (${SECONDS_PER_TARGET}s per target)"
printf '   %s\n' "${summary[@]}"
if [[ ${#failed[@]} -gt 0 ]]; then
    echo "fuzzing found problems in: ${failed[*]}" >&2
    exit 1
fi
echo "no crash found"
