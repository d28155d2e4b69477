//! Time our LM fits on a plate scan CSV: step 3b of `scripts/bench_scipy.sh`, which
//! builds and runs it (the CSV is written there by `tracer_calib simulate`).
//!
//! ```text
//! cargo run --release --example bench_scipy_ours -- PLATE.csv
//! ```
//!
//! Reads the scan and times `lm::minimize` on the full model and on the paper model, from
//! the start points and with the sample selection of `benches/scipy_fit.py`, median (and
//! minimum) of 5000 fits each; also fits `benches/fit.rs`'s own scan (the same simulator
//! and seed, not rounded to counts) and checks that the CSV is that scan rounded to 1 µm
//! counts. Prints one JSON line.

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

/// Median and minimum of `reps` calls of `f` (after 500 unmeasured), µs; what `f`
/// returns goes through `black_box`.
fn timings<T>(mut f: impl FnMut() -> T, reps: usize) -> (f64, f64) {
    for _ in 0..500 {
        black_box(f());
    }
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            black_box(f());
            s.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[reps / 2], t[0])
}

fn main() {
    let path = std::env::args().nth(1).expect("usage: bench_scipy_ours PLATE.csv");
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
    let m = Mounting::new(2f64.to_radians(), 0.005, 0.002);
    let c = Vector2::new(0.0008, -0.0005);
    let truth = full::params(&m, c);

    // benches/fit.rs's scan, to compare with the CSV.
    let mut rng = StdRng::seed_from_u64(1);
    let bench =
        simulate(&plate.at(c), &m, &SimOptions { noise: 10e-6, ..SimOptions::default() }, &mut rng).unwrap().scan;
    let same_steps =
        bench.len() == scan.len() && bench.samples().iter().zip(scan.samples()).all(|(a, b)| a.step == b.step);
    let max_diff = bench.samples().iter().zip(scan.samples()).map(|(a, b)| (a.rho - b.rho).abs()).fold(0.0, f64::max);
    let counts_equal = bench.samples().iter().zip(scan.samples()).all(|(a, b)| (a.rho / 1e-6).round() * 1e-6 == b.rho);

    let start = truth + full::Params::from([1f64.to_radians(), 0.5e-3, -0.5e-3, 0.2e-3, 0.2e-3]);
    let opt = lm::Options::default();
    let full_model = FullModel::from_scan(&plate, &scan);
    let rf = lm::minimize(&full_model, start, &opt);
    let (tf, tf_min) = timings(|| lm::minimize(black_box(&full_model), start, &opt), 5000);
    // The paper model: sums selected at the truth (calibrate.rs's margin), start 1° and
    // 0.5 mm off.
    let margin = (1e-3f64).min(0.05 * (plate.side / 2.0 - plate.corner_radius));
    let paper_model = PaperModel::select(&plate, &scan, &truth, margin, &vec![true; scan.len()]).unwrap();
    let p0 = paper::Params::new(start[0], start[1]);
    let rp = lm::minimize(&paper_model, p0, &opt);
    let (tp, tp_min) = timings(|| lm::minimize(black_box(&paper_model), p0, &opt), 5000);
    let bench_full = FullModel::from_scan(&plate, &bench);
    let (tb, _) = timings(|| lm::minimize(black_box(&bench_full), start, &opt), 5000);
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
