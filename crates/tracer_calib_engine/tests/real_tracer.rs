//! Proof against a simulator the engine did not write (issue: an uncertainty that holds on
//! a real tracer, item 6): a tracer with the errors real ones have (its angle encoder off
//! once, twice and four times a turn, noise correlated along the trace, a ball stylus,
//! artefacts and a seating known only to their certificates) is simulated by ray tracing
//! signed distance functions (`common/raytrace.rs`, no engine geometry); the engine
//! calibrates it from two plate placements and a ring gauge (`full_tip`, h = {1, 2, 4}) and
//! measures a 52 × 32 mm frame traced from inside. 1000 trials a row at σ = 10 µm: how often
//! each figure's stated U95 covers the frame's true C, A, B and FED, the mean error, how
//! often a clean tracer is refused, and how often each fitted angle coefficient lies within
//! 3 of its stated standard uncertainties of the truth. Figures printed (BENCHMARKS.md).

#[path = "common/raytrace.rs"]
mod raytrace;

use nalgebra::DMatrix;
use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use raytrace::{Circle, RoundedBox, Tracer};
use tracer_calib_engine::angle::{AngleError, HarmonicOrders};
use tracer_calib_engine::calibrate::{Options, Ring, calibrate_placements};
use tracer_calib_engine::correct::{Corrector, resample_radii_with_gain};
use tracer_calib_engine::geometry::Mounting;
use tracer_calib_engine::model::tip::RingSpec;
use tracer_calib_engine::model::{ModelKind, PlateSpec};
use tracer_calib_engine::scan::Scan;
use tracer_calib_engine::size::{Correction, SizeReport, TraceNoise, uncertainty};
use tracer_calib_engine::stylus::{Traced, touched_surface};

const SIDE: f64 = 0.045;
const CORNER: f64 = 0.003;
const DIAMETER: f64 = 0.040;
const BALL: f64 = 0.0005;
/// The turntable's angle error: 0.05° once a turn, 0.02° twice, 0.01° four times.
const ANGLE: [(u32, f64, f64); 3] = [(1, 6.0e-4, 5.0e-4), (2, -2.5e-4, 2.0e-4), (4, 1.2e-4, -1.0e-4)];

/// The inputs' standard uncertainties, as certificates state them (u = U/k).
#[derive(Debug, Clone, Copy, Default)]
struct Inputs {
    side: f64,
    corner: f64,
    diameter: f64,
    seating: f64,
}

#[derive(Debug, Default)]
struct Tally {
    trials: usize,
    refused: usize,
    covered: [usize; 4],
    error: [f64; 4],
    u95: [f64; 4],
    coefficients: usize,
    coefficients_within: usize,
    /// The last trial's error with the true calibration (the chain's own).
    chain: [f64; 4],
    /// Each calibrated trial's `alpha0` error, B's error and B's U95.
    turned: Vec<(f64, f64, f64)>,
}

fn normal(rng: &mut StdRng) -> f64 {
    StandardNormal.sample(rng)
}

fn run(sigma: f64, lag1: f64, inputs: Inputs, trials: usize, seed: u64) -> Tally {
    let mut rng = StdRng::seed_from_u64(seed);
    let tracer = Tracer { angle: ANGLE.to_vec(), lag1, ..Tracer::typical(BALL, sigma, 0.0) };
    let frame = RoundedBox { c: Vector2::new(0.001, -0.0005), hw: 0.026, hh: 0.016, r: 0.005, turn: 0.0 };
    let truth = frame.figures();
    let orders = HarmonicOrders::new(&[1, 2, 4]).unwrap();
    let opt = Options {
        model: ModelKind::FullTip,
        angle_harmonics: orders,
        plate_side_uncertainty: inputs.side,
        corner_radius_uncertainty: inputs.corner,
        ring_diameter_uncertainty: inputs.diameter,
        seating_uncertainty: inputs.seating,
        ..Options::default()
    };
    let mut t = Tally::default();
    for _ in 0..trials {
        // This trial's artefacts as they are, within their certificates, and the plate's
        // seating against the datum the frame is held to.
        let side = SIDE + inputs.side * normal(&mut rng);
        let corner = CORNER + inputs.corner * normal(&mut rng);
        let diameter = DIAMETER + inputs.diameter * normal(&mut rng);
        let seat = inputs.seating * normal(&mut rng);
        let plate = |c: Vector2<f64>, turn: f64| RoundedBox { c, hw: side / 2.0, hh: side / 2.0, r: corner, turn };
        let first = tracer.trace(&plate(Vector2::new(0.0008, -0.0005), seat), false, &mut rng);
        let second = tracer.trace(&plate(Vector2::new(-0.0006, 0.0009), seat + 22.5f64.to_radians()), false, &mut rng);
        let ring = tracer.trace(&Circle { c: Vector2::new(-0.0006, 0.0004), r: diameter / 2.0 }, true, &mut rng);
        let traced = tracer.trace(&frame, true, &mut rng);
        t.trials += 1;
        let cal = match calibrate_placements(
            &[&first, &second],
            Some(Ring { scan: &ring, spec: RingSpec::plain(DIAMETER) }),
            &PlateSpec { side: SIDE, corner_radius: CORNER },
            &opt,
        ) {
            Ok(cal) => cal,
            Err(e) => {
                eprintln!("refused: {e}");
                t.refused += 1;
                continue;
            }
        };
        for (i, (_, c, s)) in ANGLE.iter().enumerate() {
            for (j, truth) in [c, s].into_iter().enumerate() {
                let row = 5 + 2 * i + j;
                let got = cal.angle.coefficients()[2 * i + j];
                let sd = cal.named_covariance[(row, row)].sqrt();
                t.coefficients += 1;
                t.coefficients_within += usize::from((got - truth).abs() <= 3.0 * sd);
            }
        }
        let report = measure(&traced, cal.mounting, &cal.angle, cal.tip_radius, &cal.named_covariance, cal.noise_lag1);
        let coefficients = ANGLE.iter().flat_map(|(_, c, s)| [*c, *s]).collect();
        let true_angle = AngleError::new(orders, coefficients).unwrap();
        let true_mounting = Mounting::new(tracer.alpha0, tracer.d, tracer.dl);
        let chain = measure(&traced, true_mounting, &true_angle, BALL, &cal.named_covariance, 0.0);
        t.chain = [0, 1, 2, 3].map(|f| chain.sizes.figures()[f] - truth[f]);
        let b = report.sizes.figures()[2] - truth[2];
        t.turned.push((cal.mounting.alpha0 - tracer.alpha0, b, report.u95[2]));
        for (f, got) in report.sizes.figures().iter().enumerate() {
            let e = got - truth[f];
            t.error[f] += e;
            t.u95[f] += report.u95[f];
            t.covered[f] += usize::from(e.abs() <= report.u95[f]);
        }
    }
    t
}

/// The frame's sizes and their U95 as the chain measures them with a calibration.
fn measure(
    traced: &Scan,
    mounting: Mounting,
    angle: &AngleError,
    tip: f64,
    cov: &DMatrix<f64>,
    lag1: f64,
) -> SizeReport {
    let mut points = Corrector::with_angle(mounting, angle, 400).correct(traced);
    touched_surface(&mut points, tip, Traced::Inside, true);
    let (radii, gain) = resample_radii_with_gain(&points, 400, 0.2).unwrap();
    let correction = Correction {
        mounting,
        tip_radius: tip,
        traced: Traced::Inside,
        groove: Default::default(),
        angle_orders: angle.orders(),
        noise: TraceNoise { lag1, ..TraceNoise::default() },
    };
    uncertainty(&points, &radii, &gain, &correction, Some(cov)).unwrap()
}

fn report(name: &str, t: &Tally) -> ([f64; 4], [f64; 4]) {
    let n = (t.trials - t.refused) as f64;
    let share = t.covered.map(|c| c as f64 / n);
    let bias = t.error.map(|e| e / n);
    println!(
        "{name}: {} trials, {} refused; U95 covers [C, A, B, FED] {:.3?}, mean error {:.2?} µm, mean U95 {:.1?} µm; angle coefficients within 3σ {:.4}",
        t.trials,
        t.refused,
        share,
        bias.map(|b| b * 1e6),
        t.u95.map(|u| u / n * 1e6),
        t.coefficients_within as f64 / t.coefficients.max(1) as f64
    );
    (share, bias)
}

/// What a row must show. The targets: U95 covering 93-97 % of C, A, B and FED
/// (1000 trials: a standard error of 0.7 %), mean error of C, A, B, FED under 2 µm, fitted
/// coefficients within 3σ in ≥ 99 %, false refusals ≤ 1 %. Where the engine does not meet
/// one yet, the row says so (`short`) and holds it to what it measures today, so that the
/// gap is printed, cannot grow unseen, and is closed by tightening it here
/// (docs/engine.md, *against a ray-traced tracer*).
struct Bounds {
    /// The least coverage of C, A, B, FED.
    covered: [f64; 4],
    /// The largest mean error of C, A, B, FED.
    bias: [f64; 4],
    /// The most refusals in 1000.
    refused: usize,
    short: &'static str,
}

const TARGETS: Bounds = Bounds { covered: [0.93, 0.93, 0.93, 0.93], bias: [2e-6; 4], refused: 10, short: "" };

fn check(name: &str, t: &Tally, b: Bounds) {
    let (share, bias) = report(name, t);
    if !b.short.is_empty() {
        println!("{name}: short of the targets: {}", b.short);
    }
    assert!(t.refused * 1000 <= b.refused * t.trials, "{name}: {} of {} refused", t.refused, t.trials);
    for (f, s) in share.iter().enumerate() {
        assert!((b.covered[f]..=0.975).contains(s), "{name}: figure {f} covered in {s}");
    }
    for (f, e) in bias.iter().enumerate() {
        assert!(e.abs() < b.bias[f], "{name}: figure {f} biased by {} µm", e * 1e6);
    }
    assert!(t.coefficients_within * 100 >= 99 * t.coefficients, "{name}: coefficients within 3σ");
}

#[test]
fn angle_harmonics_white_noise() {
    check("h = {1, 2, 4}, σ 10 µm, white", &run(10e-6, 0.0, Inputs::default(), 1000, 1), TARGETS);
}

#[test]
fn angle_harmonics_noise_correlated_lag_0_5() {
    check("h = {1, 2, 4}, σ 10 µm, lag-1 0.5", &run(10e-6, 0.5, Inputs::default(), 1000, 2), TARGETS);
}

#[test]
fn angle_harmonics_noise_correlated_lag_0_8() {
    let t = run(10e-6, 0.8, Inputs::default(), 1000, 3);
    // B by how far the calibration's `alpha0` is off: where a flat side's tilt is read
    // only when significant, the far-off calibrations no longer miss (docs/engine.md,
    // *noise correlated 0.8*).
    for (lo, hi, label) in [(0.0, 0.5e-3, "< 0.5"), (0.5e-3, 1.2e-3, "0.5-1.2"), (1.2e-3, f64::INFINITY, "≥ 1.2")] {
        let rows: Vec<_> = t.turned.iter().filter(|(d, _, _)| (lo..hi).contains(&d.abs())).collect();
        let n = rows.len().max(1) as f64;
        println!(
            "lag-1 0.8, |δalpha0| {label} mrad: {} calibrations, B's mean error {:+.1} µm, covered {:.1} %",
            rows.len(),
            rows.iter().map(|r| r.1).sum::<f64>() / n * 1e6,
            rows.iter().filter(|r| r.1.abs() <= r.2).count() as f64 / n * 100.0
        );
    }
    check("h = {1, 2, 4}, σ 10 µm, lag-1 0.8", &t, TARGETS);
}

/// A frame with flat sides measured with the true calibration turned by `δ`: its box grows
/// by `2a|δ|` whichever way it turns (`a` the flat's half-length), which a budget linear in
/// `alpha0` does not carry; the raw side reads a flat at its centroid while its tilt stays
/// within its band, so B jumps from about 0 to the whole `2a|δ|` between 0.5 and 1 mrad at
/// σ 10 µm (docs/engine.md, *noise correlated 0.8*: what B's shortfall there was, and
/// the seating's, and how a tilt taken only when significant closed it).
#[test]
fn a_turned_frames_box_grows_whichever_way_it_turns() {
    let frame = RoundedBox { c: Vector2::new(0.001, -0.0005), hw: 0.026, hh: 0.016, r: 0.005, turn: 0.0 };
    let truth = frame.figures();
    let a = frame.hw - frame.r;
    let none = AngleError::new(HarmonicOrders::NONE, vec![]).unwrap();
    for sigma in [10e-6, 1e-6] {
        let tracer = Tracer::typical(BALL, sigma, 0.0);
        let mut rng = StdRng::seed_from_u64(9);
        let traces: Vec<Scan> = (0..100).map(|_| tracer.trace(&frame, true, &mut rng)).collect();
        let mut row = Vec::new();
        for delta in [-2e-3, -1e-3, -0.5e-3, 0.0, 0.5e-3, 1e-3, 2e-3] {
            let m = Mounting::new(tracer.alpha0 + delta, tracer.d, tracer.dl);
            let b: f64 = traces
                .iter()
                .map(|s| measure(s, m, &none, BALL, &DMatrix::zeros(5, 5), 0.0).sizes.figures()[2] - truth[2])
                .sum::<f64>()
                / traces.len() as f64;
            row.push(format!("{:+.1} mrad {:+.1}", delta * 1e3, b * 1e6));
            if delta.abs() >= 1e-3 {
                // The rotated box's own growth, to the noise's bias on it.
                assert!((b - 2.0 * a * delta.abs()).abs() < 0.1 * 2.0 * a * delta.abs(), "δ {delta}: B {b}");
            }
            if delta == 0.0 {
                assert!(b.abs() < 1e-6, "B's error unturned: {b}");
            }
        }
        println!("σ {:.0} µm, the calibration turned: B's mean error (µm) {}", sigma * 1e6, row.join(", "));
    }
}

#[test]
fn every_input_uncertain() {
    // Certificates of 2 µm (side, ring), 5 µm (corner) and a seating known to 0.02°.
    let inputs = Inputs { side: 2e-6, corner: 5e-6, diameter: 2e-6, seating: 0.02f64.to_radians() };
    // Seed 4 is this row's since it was written: C's mean error -1.9 µm on it (-2.3 µm
    // before the circumference's series was fitted at the points' own angles); over seeds
    // 10-25 (16 000 trials) -0.14 µm (-0.74 to +0.52 a seed), B's +0.23, every coverage
    // 94.5-97.6 % (docs/engine.md).
    check("h = {1, 2, 4}, σ 10 µm, every input uncertain", &run(10e-6, 0.0, inputs, 1000, 4), TARGETS);
}

/// Noise-free (1 nm), h = {1, 2, 4} from two placements: the frame's C, A, B as the
/// calibration measures them within 0.5 µm of what the true calibration measures; the
/// chain's own error (400 samples, the ball's offset, the smooth) printed apart, A, B and
/// FED within 0.5 µm of the truth, C within 1 µm (-0.7 µm: what 400 samples of a frame
/// with 5 mm corners hold, the series' truncation at 127 harmonics -0.33 µm, where the
/// samples fall and how unevenly, the ball's offset -0.13 µm; docs/engine.md, *The
/// noise-free chain's C, taken apart*). The 0.5 µm is the calibration's part, as
/// the study behind it measured it.
#[test]
fn noise_free_frame_within_half_a_micrometre() {
    let t = run(1e-9, 0.0, Inputs::default(), 1, 5);
    let (_, error) = report("h = {1, 2, 4}, noise-free", &t);
    assert_eq!(t.refused, 0);
    let chain = t.chain.map(|e| e * 1e6);
    println!(
        "noise-free: the calibration's part {:.3?} µm, the chain's own (true calibration) {chain:.3?} µm",
        [0, 1, 2, 3].map(|f| error[f] * 1e6 - chain[f])
    );
    for f in 0..3 {
        assert!((error[f] * 1e6 - chain[f]).abs() < 0.5, "figure {f}: {} µm", error[f] * 1e6 - chain[f]);
    }
    for (f, bound) in [1.0, 0.5, 0.5, 0.5].into_iter().enumerate() {
        assert!(chain[f].abs() < bound, "the chain's own error, figure {f}: {} µm", chain[f]);
    }
}

/// C's noise part as stated against what it is, on the frame measured with the true
/// calibration (σ 10 µm, white, 400 traces): each frame traced again with its noise
/// negated, the half-difference of the two C is the noise's first-order part, the half-sum
/// its second-order part (the lengthening the noise made less the one taken off): 7.9 and
/// 6.4 µm, together 10.2 µm; stated 9.6 µm. The stated total was within 6 % before too
/// (10.8 µm), from two errors that offset each other (the first-order part stated 29 %
/// high, the second-order 23 % low; docs/engine.md, *C's stated noise part*): this holds
/// the total, the rows above the coverage.
#[test]
fn c_noise_part_as_stated() {
    let mut rng = StdRng::seed_from_u64(6);
    let tracer = Tracer { angle: ANGLE.to_vec(), ..Tracer::typical(BALL, 10e-6, 0.0) };
    let negated = Tracer { sigma: -tracer.sigma, ..tracer.clone() };
    let frame = RoundedBox { c: Vector2::new(0.001, -0.0005), hw: 0.026, hh: 0.016, r: 0.005, turn: 0.0 };
    let orders = HarmonicOrders::new(&[1, 2, 4]).unwrap();
    let angle = AngleError::new(orders, ANGLE.iter().flat_map(|(_, c, s)| [*c, *s]).collect()).unwrap();
    let mounting = Mounting::new(tracer.alpha0, tracer.d, tracer.dl);
    // No calibration's part: the five of the fixed layout and h = {1, 2, 4}'s six, zero.
    let quiet = DMatrix::zeros(11, 11);
    let (mut first, mut second, mut stated) = (Vec::new(), Vec::new(), 0.0);
    for _ in 0..400 {
        let mut again = rng.clone();
        let a = measure(&tracer.trace(&frame, true, &mut rng), mounting, &angle, BALL, &quiet, 0.0);
        let b = measure(&negated.trace(&frame, true, &mut again), mounting, &angle, BALL, &quiet, 0.0);
        let (ca, cb) = (a.sizes.figures()[0], b.sizes.figures()[0]);
        first.push((ca - cb) / 2.0);
        second.push((ca + cb) / 2.0);
        stated += (a.u95[0] / 2.0).powi(2);
    }
    let sd = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    };
    let measured = (sd(&first).powi(2) + sd(&second).powi(2)).sqrt();
    let stated = (stated / 400.0).sqrt();
    println!(
        "C's noise part: first order {:.2} µm, second order {:.2} µm, together {:.2} µm; stated {:.2} µm",
        sd(&first) * 1e6,
        sd(&second) * 1e6,
        measured * 1e6,
        stated * 1e6
    );
    assert!((stated / measured - 1.0).abs() < 0.08, "stated {stated}, measured {measured}");
}
