//! Frames in three dimensions (the height channel): a tracer simulated apart from the engine
//! (`common/raytrace.rs`: the ball pushed into the groove, its height the groove bottom's on
//! the artefact's surface, the holder tilted against the axis) sends `RawScan`s with
//! `height_counts` to the cell, which calibrates on a flat plate and a flat grooved ring
//! gauge (`full_tip`), fits the axis's tilt from their heights, and corrects frames on a
//! sphere of base 2-8 (ring and frames 100-120°, up to 10° apart, balls of 0.25-1 mm). At
//! σ = 5 µm radial and 5 µm in height: the tilt at its Cramér-Rao
//! bound; the groove's 3-D length within 10 µm, its U95 covering; the frame curve within
//! 0.1 D. A tracer without a height channel: the 3-D figures are the 2-D ones. Figures
//! printed (BENCHMARKS.md).

#[path = "../crates/tracer_calib_engine/tests/common/raytrace.rs"]
mod raytrace;

use nalgebra::{DMatrix, Vector2, Vector3};
use rand::SeedableRng;
use rand::rngs::StdRng;
use raytrace::{Circle, HeightChannel, RoundedBox, Sdf, Tracer};
use tracer_calib::cell::NodeState;
use tracer_calib::engine::model::{ModelKind, PlateSpec};
use tracer_calib::engine::scan::Scan;
use tracer_calib::engine::stylus::Groove;
use tracer_calib::interfaces::{CalibrateRequest, Contour, Header, RawScan};
use tracer_calib::params::Parameters;

const SIDE: f64 = 0.045;
const CORNER: f64 = 0.003;
const DIAMETER: f64 = 0.040;
const COUNT: f64 = 1e-6;
const HEIGHT_COUNT: f64 = 1e-7;
const SIGMA: f64 = 5e-6;
const SIGMA_H: f64 = 5e-6;
/// The holder's tilt against the axis: 0.1° and -0.05°.
const TILT: [f64; 2] = [1.745e-3, -0.873e-3];

/// The ring's and the frames' groove (degrees) and the ball's radius (m).
#[derive(Debug, Clone, Copy)]
struct Grooves {
    ring: f64,
    frame: f64,
    ball: f64,
}

const PLAIN: Grooves = Grooves { ring: 110.0, frame: 110.0, ball: 0.0005 };

fn tracer(ball: f64) -> Tracer {
    Tracer::typical(ball, SIGMA, COUNT)
}

fn channel() -> HeightChannel {
    HeightChannel { zero: 0.0012, tilt: TILT, sigma: SIGMA_H, count: HEIGHT_COUNT }
}

fn message(scan_id: u32, target: u8, scan: &Scan, heights: Option<&[f64]>) -> RawScan {
    RawScan {
        header: Header::default(),
        scan_id,
        target,
        steps_per_revolution: 400,
        step: scan.samples().iter().map(|s| s.step).collect(),
        counts: scan.samples().iter().map(|s| (s.rho / COUNT).round() as i32).collect(),
        height_counts: heights.map_or_else(Vec::new, |h| h.iter().map(|h| (h / HEIGHT_COUNT).round() as i32).collect()),
    }
}

fn cell(g: Grooves) -> NodeState {
    let mut p = Parameters { model: ModelKind::FullTip, ..Parameters::default() };
    p.plate = PlateSpec { side: SIDE, corner_radius: CORNER };
    p.ring_diameter = DIAMETER;
    p.ring_groove_angle = g.ring.to_radians();
    p.frame_groove = Groove::new(g.frame.to_radians(), 0.0);
    p.meters_per_count = COUNT;
    p.height_meters_per_count = HEIGHT_COUNT;
    NodeState::new("/tracer_calibrator".into(), p)
}

/// The plate (flat, at the holder's datum) and a flat grooved ring 1.5 mm below, traced
/// with heights; calibrated. The artefacts' ball centres, for the bound.
fn calibrate(st: &mut NodeState, rng: &mut StdRng, ids: (u32, u32), g: Grooves) -> Vec<Vec<Vector2<f64>>> {
    let t = tracer(g.ball);
    let plate = RoundedBox { c: Vector2::new(0.0008, -0.0005), hw: SIDE / 2.0, hh: SIDE / 2.0, r: CORNER, turn: 0.0 };
    let ring = Circle { c: Vector2::new(-0.0006, 0.0004), r: DIAMETER / 2.0 };
    let (ps, ph, pc) = t.trace_3d(&plate, false, std::f64::consts::PI, |_| 0.0, &channel(), rng);
    let (rs, rh, rc) = t.trace_3d(&ring, true, g.ring.to_radians(), |_| -0.0015, &channel(), rng);
    st.on_raw_scan(&message(ids.0, RawScan::TARGET_CALIBRATION_PLATE, &ps, Some(&ph)), false).unwrap();
    st.on_raw_scan(&message(ids.1, RawScan::TARGET_RING_GAUGE, &rs, Some(&rh)), false).unwrap();
    let out = st.on_calibrate(&CalibrateRequest {
        scan_id: ids.0,
        dry_run: false,
        ring_scan_id: ids.1,
        plate_scan_ids: vec![],
    });
    assert!(out.response.success, "{}", out.response.message);
    assert!(out.response.message.contains("axis tilt"), "{}", out.response.message);
    vec![pc, rc]
}

#[test]
fn the_axis_tilt_at_its_cramer_rao_bound() {
    let mut rng = StdRng::seed_from_u64(21);
    let trials = 400;
    let mut fitted = Vec::with_capacity(trials);
    let mut stated = [0.0; 2];
    let mut centres = Vec::new();
    for i in 0..trials {
        let mut st = cell(PLAIN);
        centres = calibrate(&mut st, &mut rng, (2 * i as u32 + 1, 2 * i as u32 + 2), PLAIN);
        let tilt = st.params.axis_tilt;
        fitted.push(tilt.angles);
        stated[0] += tilt.covariance[0].sqrt() / trials as f64;
        stated[1] += tilt.covariance[3].sqrt() / trials as f64;
    }
    // The bound of white height noise σ_h: σ_h² (AᵀA)⁻¹ over the true ball centres, rows
    // (x, y, one an artefact).
    let n: usize = centres.iter().map(Vec::len).sum();
    let mut a = DMatrix::<f64>::zeros(n, 4);
    for (row, (k, p)) in centres.iter().enumerate().flat_map(|(k, c)| c.iter().map(move |p| (k, p))).enumerate() {
        a[(row, 0)] = p.x;
        a[(row, 1)] = p.y;
        a[(row, 2 + k)] = 1.0;
    }
    let crb = (a.transpose() * &a).try_inverse().unwrap() * SIGMA_H * SIGMA_H;
    for axis in 0..2 {
        let mean = fitted.iter().map(|t| t[axis]).sum::<f64>() / trials as f64;
        let var = fitted.iter().map(|t| (t[axis] - mean).powi(2)).sum::<f64>() / (trials - 1) as f64;
        let bound = crb[(axis, axis)].sqrt();
        println!(
            "axis tilt {axis}: mean error {:.2} µrad, sd {:.2} µrad, Cramér-Rao {:.2} µrad (ratio {:.3}), stated {:.2} µrad",
            (mean - TILT[axis]) * 1e6,
            var.sqrt() * 1e6,
            bound * 1e6,
            var.sqrt() / bound,
            stated[axis] * 1e6
        );
        assert!((mean - TILT[axis]).abs() < 3.0 * bound / (trials as f64).sqrt(), "axis {axis}: biased");
        assert!((0.88..1.12).contains(&(var.sqrt() / bound)), "axis {axis}: sd {} vs bound {bound}", var.sqrt());
        assert!(
            (0.95..1.05).contains(&(stated[axis] / bound)),
            "axis {axis}: stated {} vs bound {bound}",
            stated[axis]
        );
    }
}

/// A frame's groove bottom on a sphere of `base` dioptres whose apex is decentred from the
/// box centre (the lens's optical centre), 2 mm above the datum.
struct Frame {
    shape: RoundedBox,
    apex: Vector2<f64>,
    radius: f64,
}

impl Frame {
    fn new(base: f64) -> Frame {
        Frame {
            shape: RoundedBox { c: Vector2::new(0.001, -0.0005), hw: 0.026, hh: 0.016, r: 0.005, turn: 0.0 },
            apex: Vector2::new(0.004, 0.0015),
            radius: 0.530 / base,
        }
    }

    fn height(&self, p: Vector2<f64>) -> f64 {
        0.002 + self.radius - (self.radius * self.radius - (p - self.apex).norm_squared()).sqrt()
    }

    /// The groove bottom's length in 3-D, by a fine polygon: 20 000 points on the contour
    /// about the box centre (bisection on the distance function), each at its height.
    fn length_3d(&self) -> f64 {
        let n = 20_000;
        let at = |i: usize| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            let u = Vector2::new(t.cos(), t.sin());
            let (mut lo, mut hi) = (0.0, 0.1);
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if self.shape.sdf(self.shape.c + u * mid) < 0.0 { lo = mid } else { hi = mid }
            }
            let p = self.shape.c + u * 0.5 * (lo + hi);
            Vector3::new(p.x, p.y, self.height(p))
        };
        (0..n).map(|i| (at(i + 1) - at(i)).norm()).sum()
    }
}

#[derive(Debug, Default)]
struct Tally {
    trials: usize,
    covered: usize,
    error: f64,
    error2: f64,
    u95: f64,
    curve_error: f64,
    worst_curve: f64,
    c2_error: f64,
    c2_covered: usize,
}

fn frames(base: f64, g: Grooves, trials: usize, seed: u64) -> Tally {
    let mut rng = StdRng::seed_from_u64(seed);
    let frame = Frame::new(base);
    let truth = frame.length_3d();
    let t = tracer(g.ball);
    let mut tally = Tally::default();
    for i in 0..trials {
        let mut st = cell(g);
        let id = 3 * i as u32;
        calibrate(&mut st, &mut rng, (id + 1, id + 2), g);
        let (fs, fh, _) =
            t.trace_3d(&frame.shape, true, g.frame.to_radians(), |p| frame.height(p), &channel(), &mut rng);
        let c: Contour =
            st.on_raw_scan(&message(id + 3, RawScan::TARGET_FRAME, &fs, Some(&fh)), false).unwrap().contour;
        let e = c.circumference_3d - truth;
        tally.trials += 1;
        tally.error += e;
        tally.error2 += e * e;
        tally.u95 += c.circumference_3d_u95;
        tally.covered += usize::from(e.abs() <= c.circumference_3d_u95);
        tally.curve_error += c.frame_curve - base;
        tally.worst_curve = tally.worst_curve.max((c.frame_curve - base).abs());
        tally.c2_error += c.circumference - frame.shape.figures()[0];
        tally.c2_covered += usize::from((c.circumference - frame.shape.figures()[0]).abs() <= c.size_u95[0]);
    }
    let n = tally.trials as f64;
    println!(
        "base {base}, ring {}°, frames {}°, ball {} mm: 3-D length {:.3} mm (+{:.3} mm over C): mean error {:.2} µm, sd {:.2} µm, U95 covers {:.1} % (mean {:.2} µm); \
         C's mean error {:.2} µm, its U95 covers {:.1} %; frame curve mean error {:+.4} D, worst {:.4} D",
        g.ring,
        g.frame,
        g.ball * 1e3,
        truth * 1e3,
        (truth - frame.shape.figures()[0]) * 1e3,
        tally.error / n * 1e6,
        (tally.error2 / n - (tally.error / n).powi(2)).max(0.0).sqrt() * 1e6,
        tally.covered as f64 / n * 100.0,
        tally.u95 / n * 1e6,
        tally.c2_error / n * 1e6,
        tally.c2_covered as f64 / n * 100.0,
        tally.curve_error / n,
        tally.worst_curve,
    );
    tally
}

fn check_base(base: f64, g: Grooves, seed: u64) {
    let t = frames(base, g, 1000, seed);
    let n = t.trials as f64;
    assert!((t.error / n).abs() < 10e-6, "base {base}: 3-D length off by {} µm", t.error / n * 1e6);
    let covered = t.covered as f64 / n;
    // The 3-D length's U95 covers about as the plane's C's does (1000 trials: a standard
    // error of 0.7 % on each share; a 1 mm ball at base 8 costs 1.3 %), within the target
    // of 93-97 %; where C's falls short of 93 % (C under noise, docs/engine.md), so does
    // the 3-D length's, said so.
    let covered_c = t.c2_covered as f64 / n;
    assert!(covered >= covered_c - 0.02, "base {base}: U95 covers {covered}, C's {covered_c}");
    assert!((0.92..=0.98).contains(&covered), "base {base}: U95 covers {covered}");
    if covered < 0.93 {
        println!("base {base}: short of the target: the 3-D length's U95 covers {covered}, as C's covers {covered_c}");
    }
    assert!(t.worst_curve < 0.1, "base {base}: frame curve off by {} D", t.worst_curve);
}

#[test]
fn base_2_frames_in_3d() {
    check_base(2.0, Grooves { ring: 100.0, frame: 110.0, ball: 0.00025 }, 31);
}

#[test]
fn base_4_frames_in_3d() {
    check_base(4.0, Grooves { ring: 120.0, frame: 110.0, ball: 0.0005 }, 32);
}

#[test]
fn base_6_frames_in_3d() {
    check_base(6.0, PLAIN, 33);
}

#[test]
fn base_8_frames_in_3d() {
    check_base(8.0, Grooves { ring: 110.0, frame: 100.0, ball: 0.001 }, 34);
}

/// A tracer without a height channel (and one whose driver predates it) works as before:
/// the 3-D figures are the 2-D ones, the frame curve 0, every z 0.
#[test]
fn without_heights_the_3d_figures_are_the_2d_ones() {
    let mut rng = StdRng::seed_from_u64(41);
    let mut st = cell(PLAIN);
    let history = std::env::temp_dir().join(format!("tracer_calib_height_{}.jsonl", std::process::id()));
    let _ = std::fs::remove_file(&history);
    st.params.history_file = history.display().to_string();
    calibrate(&mut st, &mut rng, (1, 2), PLAIN);
    // The history record carries the tilt fitted with the calibration.
    let record: serde_json::Value =
        serde_json::from_str(std::fs::read_to_string(&history).unwrap().lines().last().unwrap()).unwrap();
    let _ = std::fs::remove_file(&history);
    let fitted = st.params.axis_tilt;
    assert_eq!(record["axis_tilt"], serde_json::json!(fitted.angles), "{record}");
    assert_eq!(record["axis_tilt_covariance"].as_array().map(Vec::len), Some(4));
    assert!((fitted.angles[0] - TILT[0]).abs() < 5e-5, "{:?}", fitted.angles);
    let frame = Frame::new(6.0);
    let (fs, _, _) =
        tracer(PLAIN.ball).trace_3d(&frame.shape, true, 110f64.to_radians(), |p| frame.height(p), &channel(), &mut rng);
    let c = st.on_raw_scan(&message(3, RawScan::TARGET_FRAME, &fs, None), true).unwrap();
    let contour = c.contour;
    assert!(contour.circumference > 0.15);
    assert_eq!(contour.circumference_3d, contour.circumference);
    assert_eq!(contour.circumference_3d_u95, contour.size_u95[0]);
    assert_eq!(contour.frame_curve, 0.0);
    assert!(contour.points.iter().all(|p| p.z == 0.0));
    assert!(c.polygon.unwrap().polygon.points.iter().all(|p| p.z == 0.0));
    // Heights of another length than the samples: refused, named.
    let mut bad = message(4, RawScan::TARGET_FRAME, &fs, None);
    bad.height_counts = vec![0; 10];
    let e = st.on_raw_scan(&bad, false).unwrap_err().to_string();
    assert!(e.contains("height_counts has 10"), "{e}");
}
