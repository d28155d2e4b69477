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
#    3b. ours on the CSV itself: a small program (written to target/bench/ours_csv,
#    built against this working tree's library, not part of the crate) reads the CSV
#    and times `lm::minimize` on the full model and on the paper model (the same
#    start points and sample selection as the Python side), median of 5000 fits;
# 4. benches/scipy_fit.py: both models in numpy with analytic Jacobians,
#    least_squares(method='lm') (MINPACK) and 'trf', median of REPEATS fits; it checks
#    the solutions against the truth and against `tracer_calib calibrate` on the CSV;
# 5. a table of medians and ratios, with the load average before and after.
#
# Everything lands in target/bench/ (criterion.txt, ours_csv.json, scipy.json, table.md).

set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD

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
target/release/tracer_calib simulate --shape plate --noise 1e-5 --seed 1 --out "$OUT/plate.csv"
target/release/tracer_calib calibrate --input "$OUT/plate.csv" --json >"$OUT/ours_full.json"
target/release/tracer_calib calibrate --input "$OUT/plate.csv" --json --model paper >"$OUT/ours_paper.json"

# 3b's program (built now, so that no compiler runs during the measurements).
mkdir -p "$OUT/ours_csv/src"
cat >"$OUT/ours_csv/Cargo.toml" <<'EOF'
[package]
name = "ours_csv"
version = "0.0.0"
edition = "2024"
publish = false

[dependencies]
tracer_calib = { path = "../../.." }
nalgebra = "0.34"
rand = "0.9"

[profile.release]
debug = "line-tables-only"

[workspace]
EOF
cp Cargo.lock "$OUT/ours_csv/Cargo.lock" # the crate's own dependency versions
cat >"$OUT/ours_csv/src/main.rs" <<'EOF'
//! Time our LM fits on a plate scan CSV (written by scripts/bench_scipy.sh).
use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use std::hint::black_box;
use std::time::Instant;
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::engine::lm;
use tracer_calib::engine::model::PlateSpec;
use tracer_calib::engine::model::full::{self, FullModel};
use tracer_calib::engine::model::paper::{self, PaperModel};
use tracer_calib::engine::scan::Scan;
use tracer_calib::engine::simulate::{SimOptions, simulate};

/// Median and minimum, µs.
fn timings(mut f: impl FnMut(), reps: usize) -> (f64, f64) {
    for _ in 0..500 {
        f();
    }
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[reps / 2], t[0])
}

fn main() {
    let path = std::env::args().nth(1).expect("usage: ours_csv PLATE.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let (mut steps, mut rho) = (vec![], vec![]);
    for line in text.lines().skip(1) {
        let (s, c) = line.split_once(',').unwrap();
        steps.push(s.trim().parse::<u32>().unwrap());
        rho.push(f64::from(c.trim().parse::<i32>().unwrap()) * 1e-6);
    }
    let scan = Scan::new(400, &steps, &rho).unwrap();
    // The truth of `tracer_calib simulate`'s defaults, which is benches/fit.rs's.
    let plate = PlateSpec { side: 0.045, corner_radius: 0.003 };
    let m = Mounting { alpha0: 2f64.to_radians(), offset: 0.005, delta_l: 0.002 };
    let c = Vector2::new(0.0008, -0.0005);
    let truth = full::params(&m, c);

    // benches/fit.rs's scan, to compare with the CSV.
    let mut rng = StdRng::seed_from_u64(1);
    let bench = simulate(&plate.at(c), &m, &SimOptions { noise: 10e-6, ..SimOptions::default() }, &mut rng)
        .unwrap()
        .scan;
    let same_steps = bench.len() == scan.len() && bench.samples().iter().zip(scan.samples()).all(|(a, b)| a.step == b.step);
    let max_diff = bench.samples().iter().zip(scan.samples()).map(|(a, b)| (a.rho - b.rho).abs()).fold(0.0, f64::max);
    let counts_equal = bench.samples().iter().zip(scan.samples()).all(|(a, b)| (a.rho / 1e-6).round() * 1e-6 == b.rho);

    let start = truth + full::Params::from([1f64.to_radians(), 0.5e-3, -0.5e-3, 0.2e-3, 0.2e-3]);
    let opt = lm::Options::default();
    let full_model = FullModel::from_scan(&plate, &scan);
    let rf = lm::minimize(&full_model, start, &opt);
    let (tf, tf_min) = timings(|| drop(black_box(lm::minimize(black_box(&full_model), start, &opt))), 5000);
    // The paper model: sums selected at the truth (calibrate.rs's margin), start 1° and
    // 0.5 mm off.
    let margin = (1e-3f64).min(0.05 * (plate.side / 2.0 - plate.corner_radius));
    let paper_model = PaperModel::select(&plate, &scan, &truth, margin, &vec![true; scan.len()]).unwrap();
    let p0 = paper::Params::new(start[0], start[1]);
    let rp = lm::minimize(&paper_model, p0, &opt);
    let (tp, tp_min) = timings(|| drop(black_box(lm::minimize(black_box(&paper_model), p0, &opt))), 5000);
    let bench_full = FullModel::from_scan(&plate, &bench);
    let (tb, _) = timings(|| drop(black_box(lm::minimize(black_box(&bench_full), start, &opt))), 5000);
    println!(
        "{{\"full_us\": {tf:.2}, \"full_min_us\": {tf_min:.2}, \"full_iterations\": {}, \"full_evaluations\": {}, \"full_termination\": \"{:?}\", \"full_x\": {:?}, \
\"paper_us\": {tp:.2}, \"paper_min_us\": {tp_min:.2}, \"paper_iterations\": {}, \"paper_evaluations\": {}, \"paper_termination\": \"{:?}\", \"paper_pairs\": {}, \"paper_x\": {:?}, \
\"full_us_on_bench_scan\": {tb:.2}, \"bench_scan_same_steps\": {same_steps}, \"bench_scan_max_abs_diff_m\": {max_diff:e}, \"bench_scan_rounded_equals_csv\": {counts_equal}}}",
        rf.iterations,
        rf.evaluations,
        rf.termination,
        rf.x.as_slice(),
        rp.iterations,
        rp.evaluations,
        rp.termination,
        paper_model.pair_count(),
        rp.x.as_slice(),
    );
}
EOF
echo "== building target/bench/ours_csv (against this working tree)"
CARGO_TARGET_DIR="$ROOT/target" cargo build --release --quiet --manifest-path "$OUT/ours_csv/Cargo.toml"
# Build the bench too, before measuring.
cargo bench --bench fit --no-run --quiet

# 3. Ours, by criterion.
load_before=$(load)
echo "== cargo bench --bench fit (load average before: $load_before)"
cargo bench --bench fit -- 'fit/|calibrate/' --warm-up-time 1 --measurement-time 3 2>&1 | tee "$OUT/criterion.txt"

# 3b. Ours, on the CSV.
echo "== ours on $OUT/plate.csv"
target/release/ours_csv "$OUT/plate.csv" | tee "$OUT/ours_csv.json"

# 4. scipy, on the CSV.
echo "== benches/scipy_fit.py ($REPEATS fits per method)"
"$VENV/bin/python" benches/scipy_fit.py "$OUT/plate.csv" --repeats "$REPEATS" \
    --ours-json "$OUT/ours_full.json,$OUT/ours_paper.json" | tee "$OUT/scipy.json"
load_after=$(load)

# 5. The table.
echo
"$VENV/bin/python" - "$OUT" "$load_before" "$load_after" <<'EOF' | tee "$OUT/table.md"
import json, re, sys

out, load_before, load_after = sys.argv[1:4]
text = open(f"{out}/criterion.txt").read()
units = {"ps": 1e-6, "ns": 1e-3, "µs": 1.0, "us": 1.0, "ms": 1e3, "s": 1e6}
# criterion: "<name>  time:   [low unit median unit high unit]"; a long name stands on
# a line of its own, the times on the next.
medians, name = {}, None
for line in text.splitlines():
    if line and not line[0].isspace() and not line.startswith(("Benchmarking", "Found", "Warning", "ours:", "Gnuplot")):
        name = line.split("time:")[0].strip()
    t = re.search(r"time:\s*\[\s*\S+ \S+ (\S+) (\S+) \S+ \S+\]", line)
    if t and name:
        medians[name] = float(t.group(1)) * units[t.group(2)]
        name = None
bench_line = next((l for l in text.splitlines() if l.startswith("ours:")), "")
ours = json.load(open(f"{out}/ours_csv.json"))
s = json.load(open(f"{out}/scipy.json"))

def crit(prefix):
    for k, v in medians.items():
        if k.startswith(prefix):
            return v
    sys.exit(f"no criterion result for '{prefix}' in {out}/criterion.txt")

of, op = ours["full_us"], ours["paper_us"]
def cell(us, ref):
    return ("–", "") if us is None else (f"{us:.1f} µs", f"{us / ref:.1f}×")

rows = [
    ("ours, `lm::minimize`, on the CSV (median of 5000)",
     of, op, f"{ours['full_evaluations']} / {ours['paper_evaluations']} passes"),
    ("ours, criterion `fit/full_lm_400 (ours)` (bench's own scan)", crit("fit/full_lm_400 (ours)"), None, ""),
    ("`levenberg-marquardt` 0.15 crate, criterion (bench's own scan)",
     crit("fit/full_lm_400 (levenberg-marquardt crate)"), None, ""),
    ("scipy `least_squares(method='lm')` (MINPACK)", s["full_lm_median_us"], s["paper_lm_median_us"],
     f"{s['full_lm_nfev']} f + {s['full_lm_njev']} J / {s['paper_lm_nfev']} f + {s['paper_lm_njev']} J"),
    ("scipy `least_squares(method='trf')`", s["full_trf_median_us"], s["paper_trf_median_us"],
     f"{s['full_trf_nfev']} f + {s['full_trf_njev']} J / {s['paper_trf_nfev']} f + {s['paper_trf_njev']} J"),
]
print(f"Scan: {s['scan']} ({s['samples']} samples; paper model: {s['paper_samples_used']} samples, "
      f"{s['paper_pairs']} pairs). Python {s['python']}, numpy {s['numpy']}, scipy {s['scipy']}; "
      f"scipy: median of {s['repeats']} fits.")
print(f"Load average (1, 5, 15 min): {load_before} before criterion, {load_after} after scipy.")
print()
print("| fit from truth + (1°, 0.5 mm, ...) | full model | ratio | paper model | ratio | evaluations (full / paper) |")
print("|---|---|---|---|---|---|")
for label, f, p, ev in rows:
    fc, fr = cell(f, of)
    pc, pr = cell(p, op)
    print(f"| {label} | {fc} | {fr} | {pc} | {pr} | {ev} |")
mins = [("ours", ours["full_min_us"], ours["paper_min_us"])] + [
    (f"scipy {m}", s[f"full_{m}_min_us"], s[f"paper_{m}_min_us"]) for m in ("lm", "trf")]
print()
print("Fastest single fit (less sensitive to the load): " + "; ".join(
    f"{n} {f:.1f} µs full ({f / ours['full_min_us']:.1f}×), {p:.1f} µs paper ({p / ours['paper_min_us']:.1f}×)"
    for n, f, p in mins) + ".")
print()
print("| other | median |")
print("|---|---|")
print(f"| whole calibration, ours, full model (start search + fit + outlier test), criterion | {crit('calibrate/full_400'):.1f} µs |")
print(f"| whole calibration, ours, paper model, criterion | {crit('calibrate/paper_400'):.1f} µs |")
print(f"| one residual + normal-equations pass, ours (full model), criterion | {crit('fit/normal_equations_pass_400'):.1f} µs |")
print(f"| one residual + Jacobian evaluation, numpy (full model) | {s['full_eval_us']:.1f} µs |")
print()
print(f"Same data: the CSV is benches/fit.rs's scan rounded to 1 µm counts "
      f"({'checked' if ours['bench_scan_rounded_equals_csv'] and ours['bench_scan_same_steps'] else 'CHECK FAILED'}: "
      f"max |Δrho| {ours['bench_scan_max_abs_diff_m'] * 1e6:.2f} µm); our full fit on the bench's scan "
      f"{ours['full_us_on_bench_scan']:.1f} µs. Criterion: {bench_line}")
print(f"Solutions: scipy vs truth in standard errors, full lm {s['full_lm_z']}, paper lm {s['paper_lm_z']}; "
      f"scipy vs `tracer_calib calibrate` on the CSV: full {s['full_ours_vs_scipy_max_sigmas']:.1e} σ, "
      f"paper {s['paper_ours_vs_scipy_max_sigmas']:.1e} σ (max over parameters); "
      f"checks {'passed' if s['ok'] else 'FAILED'}.")
dist = lambda a, b, se: max(abs(x - y) / e for x, y, e in zip(a, b, se))
print(f"Our fits on the CSV vs scipy lm: full {dist(ours['full_x'], s['full_lm_x'], s['full_stderr']):.1e} σ, "
      f"paper {dist(ours['paper_x'], s['paper_lm_x'], s['paper_stderr']):.1e} σ (max over parameters).")
EOF
