//! The size figures' Monte Carlo, shared by `tests/sizes.rs` (400 trials a row)
//! and the accuracy example's part 5 (2000): a tracer calibrated from its own noisy plate
//! (and ring gauge) scans each trial traces a lens or a frame; how often the reported U95
//! covers the exact figures, and their mean error.

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use tracer_calib_engine::calibrate::{CalibrationError, Options, Ring, calibrate_with_ring};
use tracer_calib_engine::correct::{correct, resample_radii, resample_radii_with_gain};
use tracer_calib_engine::geometry::Mounting;
use tracer_calib_engine::model::tip::RingSpec;
use tracer_calib_engine::model::{ModelKind, PlateSpec};
use tracer_calib_engine::shape::{Ellipse, Shape};
use tracer_calib_engine::simulate::{SimOptions, simulate};
use tracer_calib_engine::size::{Correction, uncertainty};
use tracer_calib_engine::stylus::{Traced, touched_surface};

const PLATE: PlateSpec = PlateSpec { side: 0.045, corner_radius: 0.003 };
const RING: RingSpec = RingSpec::plain(0.040);

pub struct Coverage {
    pub covered: [usize; 4],
    pub bias: [f64; 4],
    pub u95: [f64; 4],
    pub n: usize,
    /// Share of the resampled radii (all trials) whose U95 covers the noise-free chain's.
    pub radii_covered: f64,
    /// Trials whose calibration the lack-of-fit test refused (a clean tracer, at the test's
    /// level: a cell traces the plate again); they are left out of the figures.
    pub refused: usize,
}

/// The circumference of a closed contour given as points, from 3600 resampled radii (a
/// polygon fine enough that its own error is far below the figures compared with it).
pub fn polygon_circumference(points: &[Vector2<f64>]) -> f64 {
    let r = resample_radii(points, 3600, 0.2).expect("all the way round");
    let p: Vec<Vector2<f64>> = r
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let a = std::f64::consts::TAU * k as f64 / 3600.0;
            Vector2::new(r * a.cos(), r * a.sin())
        })
        .collect();
    (0..p.len()).map(|i| (p[(i + 1) % p.len()] - p[i]).norm()).sum()
}

/// `trials` calibrations and traces of `shape` (true figures `truth`) at noise `sigma`
/// with a tip `tip`.
#[allow(clippy::too_many_arguments)]
pub fn run(
    shape: &impl Shape,
    truth: [f64; 4],
    traced: Traced,
    model: ModelKind,
    tip: f64,
    sigma: f64,
    trials: usize,
    seed: u64,
) -> Coverage {
    let m = Mounting::new(2f64.to_radians(), 0.005, 0.002);
    let mut rng = StdRng::seed_from_u64(seed);
    let inside = traced == Traced::Inside;
    let opt = |noise: f64, inside: bool| SimOptions { noise, tip_radius: tip, inside, ..SimOptions::default() };
    // The truth: the surface touched, noise-free, through the same smooth fit.
    let gauge = Ellipse { center: Vector2::new(-0.0006, 0.0004), a: 0.02, b: 0.02, angle: 0.0 };
    let mut c = Coverage { covered: [0; 4], bias: [0.0; 4], u95: [0.0; 4], n: 0, radii_covered: 0.0, refused: 0 };
    // Each radius' truth: the noise-free trace through the same chain, at the truth.
    let true_radii = {
        let scan = simulate(shape, &m, &opt(0.0, inside), &mut rng).unwrap().scan;
        let mut points = correct(&scan, &m);
        touched_surface(&mut points, tip, traced, true);
        resample_radii(&points, 400, 0.2).unwrap()
    };
    let (mut radii_in, mut radii_all) = (0usize, 0usize);
    for _ in 0..trials {
        let plate = simulate(&PLATE.at(Vector2::new(0.0008, -0.0005)), &m, &opt(sigma, false), &mut rng).unwrap();
        let ring = simulate(&gauge, &m, &opt(sigma, true), &mut rng).unwrap();
        let o = Options { model, tip_radius: if model.fits_tip() { 0.0 } else { tip }, ..Options::default() };
        let cal = match calibrate_with_ring(&plate.scan, Some(Ring { scan: &ring.scan, spec: RING }), &PLATE, &o) {
            Ok(cal) => cal,
            Err(CalibrationError::Structure { .. }) => {
                c.refused += 1;
                // The trial's lens or frame is drawn all the same: the next trials' noise
                // stays as it was.
                let _ = simulate(shape, &m, &opt(sigma, inside), &mut rng).unwrap();
                continue;
            }
            Err(e) => panic!("{e}"),
        };
        let scan = simulate(shape, &m, &opt(sigma, inside), &mut rng).unwrap().scan;
        let mut points = correct(&scan, &cal.mounting);
        touched_surface(&mut points, cal.tip_radius, traced, true);
        let (radii, gain) = resample_radii_with_gain(&points, 400, 0.2).unwrap();
        let correction = Correction {
            mounting: cal.mounting,
            tip_radius: cal.tip_radius,
            traced,
            groove: Default::default(),
            angle_orders: cal.angle.orders(),
            noise: Default::default(),
        };
        let report = uncertainty(&points, &radii, &gain, &correction, Some(&cal.named_covariance)).unwrap();
        let got = report.sizes.figures();
        for f in 0..4 {
            let e = got[f] - truth[f];
            c.bias[f] += e;
            c.u95[f] += report.u95[f];
            if e.abs() <= report.u95[f] {
                c.covered[f] += 1;
            }
        }
        c.n += 1;
        for ((r, t), u) in radii.iter().zip(&true_radii).zip(&report.radii_u95) {
            radii_in += usize::from((r - t).abs() <= *u);
            radii_all += 1;
        }
    }
    c.radii_covered = radii_in as f64 / radii_all.max(1) as f64;
    c.bias = c.bias.map(|b| b / c.n as f64);
    c.u95 = c.u95.map(|u| u / c.n as f64);
    c
}
