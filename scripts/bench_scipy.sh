#!/usr/bin/env bash
# Fit time of our solver against scipy.optimize.least_squares, on the same plate scan,
# in the same run, as ratios.
#
#   bash scripts/bench_scipy.sh            # REPEATS=200 scipy fits per method
#
# 1. a Python venv in target/bench/venv with pinned numpy and scipy;
# 2. `tracer_calib simulate` writes the plate scan target/bench/plate.csv: 45 mm plate,
#    r = 3 mm, alpha0 = 2°, d = 5 mm, dL = 2 mm, c = (0.8, -0.5) mm, σ = 0.01 mm,
#    400 steps, seed 1. It is the scan benches/fit.rs simulates (same simulator, StdRng
#    seed 1, same noise draws) rounded to whole encoder counts of 1 µm: the bench's
#    scan is not quantised (at most 0.5 µm = 0.05 σ a sample; step 3b checks this);
# 3. criterion (benches/fit.rs, short run: 1 s warm-up, 3 s measurement): our
#    full-model LM fit, the same residuals under the `levenberg-marquardt` crate, one
#    normal-equations pass, the whole calibrations;
#    3b. ours on the CSV itself: examples/bench_scipy_ours.rs reads the CSV and times
#    `lm::minimize` on the full model and on the paper model (the same start points
#    and sample selection as the Python side), median of 5000 fits;
# 4. benches/scipy_fit.py: both models in numpy with analytic Jacobians,
#    least_squares(method='lm') (MINPACK) and 'trf', median of REPEATS fits; it checks
#    the solutions against the truth and against `tracer_calib calibrate` on the CSV;
# 5. benches/scipy_table.py: a table of medians and ratios, with the load average
#    before and after.
#
# Everything lands in target/bench/ (criterion.txt, ours_csv.json, scipy.json, table.md);
# the Rust builds go to cargo's target directory (scripts/target_dir.sh).

set -euo pipefail
cd "$(dirname "$0")/.."

NUMPY_VERSION=2.4.6
SCIPY_VERSION=1.17.1
REPEATS=${REPEATS:-200}
OUT=target/bench
VENV=$OUT/venv
mkdir -p "$OUT"
load() { uptime | sed 's/.*load average: //'; }

# 1. The venv (kept between runs; rebuilt if the pins changed).
if ! "$VENV/bin/python" -c "import numpy, scipy, sys; sys.exit(not (numpy.__version__ == '$NUMPY_VERSION' and scipy.__version__ == '$SCIPY_VERSION'))" 2>/dev/null; then
    echo "== creating $VENV (numpy $NUMPY_VERSION, scipy $SCIPY_VERSION)"
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install --quiet --disable-pip-version-check "numpy==$NUMPY_VERSION" "scipy==$SCIPY_VERSION"
fi

# 2. Our tools (another build may hold the cargo lock: cargo waits for it), the scan,
#    and our own calibration of it (for the cross-check of the solutions).
echo "== cargo build --release --bins"
cargo build --release --bins --quiet
. scripts/target_dir.sh
TOOL=$TRACER_RELEASE_DIR/tracer_calib
"$TOOL" simulate --shape plate --noise 1e-5 --seed 1 --out "$OUT/plate.csv"
"$TOOL" calibrate --input "$OUT/plate.csv" --json >"$OUT/ours_full.json"
"$TOOL" calibrate --input "$OUT/plate.csv" --json --model paper >"$OUT/ours_paper.json"

# 3b's program (built now, so that no compiler runs during the measurements).
echo "== cargo build --release --example bench_scipy_ours"
cargo build --release --quiet --example bench_scipy_ours
# Build the bench too, before measuring.
cargo bench --bench fit --no-run --quiet

# 3. Ours, by criterion.
load_before=$(load)
echo "== cargo bench --bench fit (load average before: $load_before)"
cargo bench --bench fit -- 'fit/|calibrate/' --warm-up-time 1 --measurement-time 3 2>&1 | tee "$OUT/criterion.txt"

# 3b. Ours, on the CSV.
echo "== ours on $OUT/plate.csv"
"$TRACER_RELEASE_DIR/examples/bench_scipy_ours" "$OUT/plate.csv" | tee "$OUT/ours_csv.json"

# 4. scipy, on the CSV.
echo "== benches/scipy_fit.py ($REPEATS fits per method)"
"$VENV/bin/python" benches/scipy_fit.py "$OUT/plate.csv" --repeats "$REPEATS" \
    --ours-json "$OUT/ours_full.json,$OUT/ours_paper.json" | tee "$OUT/scipy.json"
load_after=$(load)

# 5. The table.
echo
"$VENV/bin/python" benches/scipy_table.py "$OUT" "$load_before" "$load_after" | tee "$OUT/table.md"
