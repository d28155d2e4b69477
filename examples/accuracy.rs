//! Monte-Carlo accuracy of the calibration against the Cramér-Rao bound.
//!
//! ```text
//! cargo run --release --example accuracy -- [TRIALS]      (default 2000)
//! ```
//!
//! Truth as in `docs/model.md`: alpha0 = 2°, d = 5 mm, dL = 2 mm, plate 45 mm with
//! 3 mm corners centred at (0.8, -0.5) mm, 400 steps. Three parts:
//!
//! 1. For encoder noise σ = 0.1, 0.01 and 0.001 mm, the RMS error of alpha0, d, dL (and
//!    the encoder scale k) for the full, paper and full_scale models next to each
//!    model's Cramér-Rao bound `σ² (JᵀJ)⁻¹` at the truth (the same Jacobian the fit
//!    uses: five parameters for full and paper, six for full_scale), the mean reported
//!    standard uncertainty, and the RMS error of a 50×30 mm ellipse corrected with each
//!    fit (noise-free ellipse scan, so the figure is the calibration's own error).
//! 2. A tracer whose encoder scale is off (k = 0.9975 .. 1.01): full_scale recovers
//!    k, alpha0, d and dL at its bound; the ellipse comes out true.
//! 3. The scale check of the models that do not fit k: how often a correct tracer fails
//!    it (false alarms) and how often a wrong scale (0.05, 0.1, 0.25 %) is caught, for
//!    σ from 1 to 100 µm (half the trials a cell).
//! 4. A tracer with a ball tip of radius ρ = 0 .. 1 mm, fitted with full_tip and
//!    full_scale_tip from the plate and a Ø 40 mm ring gauge (a quarter of the trials a
//!    row): the RMS error of ρ and dL next to their bound (the tip models' own Jacobian
//!    at the truth), the mean reported uncertainty of ρ, and the error of the
//!    circumference of a 50×30 mm frame (8 mm corners) traced from inside with the same
//!    tip (noise-free) and corrected to the surface the tip touched.
//! 5. The size figures of a lens (outside, `full`) and a 50×30 mm frame with 8 mm corners
//!    (inside, a 0.5 mm tip, `full_tip`), each trial calibrated from its own scans: how
//!    often the reported U95 of circumference, A, B and FED covers the exact figure, the
//!    mean U95 and the mean error, at σ = 1, 5 and 10 µm.
//! 6. The third dimension: a tracer with a height channel (the engine's simulator,
//!    `simulate_heights`), the holder tilted 0.1° against the axis, σ = 5 µm radial and in
//!    height, a 0.5 mm ball; through the cell (`NodeState`: the plate and a flat 110° ring
//!    gauge with heights, `/calibrate` with `full_tip`, then a 52×32 mm frame in a 110°
//!    groove on a sphere of base 2, 4, 6, 8; a quarter of the trials a base): the 3-D
//!    length's mean error, spread and U95 coverage, the frame curve's worst error, and the
//!    axis tilt's spread against what the calibration states.

#[path = "../crates/tracer_calib_engine/tests/common/size_coverage.rs"]
#[allow(dead_code)]
// shared with crates/tracer_calib_engine/tests/sizes.rs and crates/tracer_calib_engine/tests/stylus_tip.rs
mod size_coverage;

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use tracer_calib::engine::calibrate::{CalibrationError, Options, Ring, calibrate, calibrate_with_ring};
use tracer_calib::engine::correct::correct;
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::engine::lm::normal_equations;
use tracer_calib::engine::model::full::{self, FullModel, TableSample};
use tracer_calib::engine::model::full_scale::{self, FullScaleModel};
use tracer_calib::engine::model::tip::{self, RingSpec, TipModel, TipScaleModel};
use tracer_calib::engine::model::{ModelKind, PlateSpec};
use tracer_calib::engine::shape::Ellipse;
use tracer_calib::engine::shape::RoundedRect;
use tracer_calib::engine::simulate::{SimOptions, simulate};
use tracer_calib::engine::stylus::{Traced, touched_surface};

#[derive(Default)]
struct Tally {
    /// Squared errors of alpha0, d, dL, k.
    sq: [f64; 4],
    reported: [f64; 4],
    ellipse_sq: f64,
    n: usize,
    failures: usize,
    /// Failures by the scale check.
    scale_off: usize,
}

impl Tally {
    fn rms(&self) -> [f64; 4] {
        self.sq.map(|s| (s / self.n.max(1) as f64).sqrt())
    }
    fn mean_reported(&self) -> [f64; 4] {
        self.reported.map(|s| s / self.n.max(1) as f64)
    }
    fn ellipse_rms(&self) -> f64 {
        (self.ellipse_sq / self.n.max(1) as f64).sqrt()
    }
}

/// The set-up every trial shares.
struct Bench {
    plate: PlateSpec,
    truth: Mounting,
    center: Vector2<f64>,
    /// A noise-free scan of the 50×30 mm ellipse, per true encoder scale, and its truth.
    lens: Ellipse,
}

impl Bench {
    /// `trials` calibrations with model `kind` of plate scans with noise `sigma` by a
    /// tracer with encoder scale `k`.
    fn run(&self, kind: ModelKind, sigma: f64, k: f64, trials: usize, seed: u64) -> Tally {
        let truth = self.truth.with_scale(k);
        let opts = Options { model: kind, ..Options::default() };
        let ellipse = simulate(&self.lens, &truth, &SimOptions::default(), &mut StdRng::seed_from_u64(1)).unwrap();
        let mut t = Tally::default();
        let mut rng = StdRng::seed_from_u64(seed);
        for _ in 0..trials {
            let sim = simulate(
                &self.plate.at(self.center),
                &truth,
                &SimOptions { noise: sigma, ..SimOptions::default() },
                &mut rng,
            )
            .unwrap();
            match calibrate(&sim.scan, &self.plate, &opts) {
                Ok(cal) => {
                    let m = cal.mounting;
                    let err =
                        [m.alpha0 - truth.alpha0, m.offset - truth.offset, m.delta_l - truth.delta_l, m.scale - k];
                    let reported = [cal.stddev[0], cal.stddev[1], cal.stddev[2], cal.scale_stddev];
                    for i in 0..4 {
                        t.sq[i] += err[i] * err[i];
                        t.reported[i] += reported[i];
                    }
                    let pts = correct(&ellipse.scan, &m);
                    t.ellipse_sq += pts.iter().zip(&ellipse.truth).map(|(p, q)| (p - q).norm_squared()).sum::<f64>()
                        / pts.len() as f64;
                    t.n += 1;
                }
                Err(e) => {
                    t.failures += 1;
                    if matches!(e, CalibrationError::ScaleOff { .. }) {
                        t.scale_off += 1;
                    }
                }
            }
        }
        t
    }

    /// Cramér-Rao bound per unit σ, sqrt(diag((JᵀJ)⁻¹)) at the truth, of alpha0, d, dL
    /// (and k, for full_scale; 0 otherwise).
    fn crlb_unit(&self, kind: ModelKind) -> [f64; 4] {
        let table: Vec<TableSample> = (0..400).map(|k| TableSample::new(k, 400, 0.0)).collect();
        let x_true = full::params(&self.truth, self.center);
        let model = FullModel::new(&self.plate, table);
        let rho = model.predict(&x_true).unwrap();
        let model = FullModel::new(
            &self.plate,
            model.samples().iter().zip(rho).map(|(s, rho)| TableSample { rho, ..*s }).collect(),
        );
        if kind.fits_scale() {
            let inv = normal_equations(&FullScaleModel::new(model), &full_scale::from_full(&x_true, 1.0))
                .unwrap()
                .jtj
                .try_inverse()
                .unwrap();
            [0, 1, 2, full_scale::SCALE].map(|i| inv[(i, i)].sqrt())
        } else {
            let inv = normal_equations(&model, &x_true).unwrap().jtj.try_inverse().unwrap();
            [inv[(0, 0)].sqrt(), inv[(1, 1)].sqrt(), inv[(2, 2)].sqrt(), 0.0]
        }
    }
}

fn main() {
    let trials: usize = std::env::args().nth(1).map_or(2000, |s| s.parse().expect("TRIALS must be a whole number"));
    let bench = Bench {
        plate: PlateSpec { side: 0.045, corner_radius: 0.003 },
        truth: Mounting::new(2f64.to_radians(), 0.005, 0.002),
        center: Vector2::new(0.0008, -0.0005),
        lens: Ellipse { center: Vector2::zeros(), a: 0.025, b: 0.015, angle: 0.0 },
    };

    println!(
        "Monte-Carlo accuracy, {trials} trials per row; truth alpha0 = 2°, d = 5 mm, dL = 2 mm, c = (0.8, -0.5) mm"
    );
    println!(
        "errors are RMS over the trials: alpha0 in degrees, d, dL and the corrected 50x30 mm ellipse in mm, k in ppm"
    );
    println!();
    println!("1. A tracer with a true encoder scale (k = 1)");
    header();
    for sigma in [100e-6, 10e-6, 1e-6] {
        for kind in ModelKind::ALL.into_iter().filter(|k| !k.fits_tip()) {
            let t = bench.run(kind, sigma, 1.0, trials, 7 + (sigma * 1e9) as u64);
            row(sigma, kind.as_str(), &t, &bench.crlb_unit(kind).map(|c| c * sigma));
        }
        for kind in [ModelKind::Full, ModelKind::FullScale] {
            let c = bench.crlb_unit(kind).map(|c| c * sigma);
            let name = if kind.fits_scale() { "CRLB6" } else { "CRLB" };
            println!(
                "{:>6.3} mm  {:<10} {:>10.5} {:>10.5} {:>10.5} {:>8.0}",
                sigma * 1e3,
                name,
                c[0].to_degrees(),
                c[1] * 1e3,
                c[2] * 1e3,
                c[3] * 1e6
            );
        }
        println!();
    }

    println!("2. A tracer whose encoder scale is off, fitted with full_scale (sigma = 0.01 mm)");
    header();
    let sigma = 10e-6;
    let crlb = bench.crlb_unit(ModelKind::FullScale).map(|c| c * sigma);
    for k in [0.9975, 0.9995, 1.0005, 1.0025, 1.01, 0.99] {
        let t = bench.run(ModelKind::FullScale, sigma, k, trials, 99);
        row(sigma, &format!("k={k}"), &t, &crlb);
    }
    println!();

    println!("3. The scale check of full and paper: share of calibrations refused for the encoder scale");
    println!("   (k = 1: false alarms; otherwise detections), {} trials a cell", trials / 2);
    let errors = [0.0, 0.0005, 0.001, 0.0025];
    print!("{:>9}  {:<6}", "noise", "model");
    for e in errors {
        print!(" {:>12}", if e == 0.0 { "k=1".to_string() } else { format!("{:.2} % long", e * 100.0) });
    }
    println!();
    for sigma in [1e-6, 3e-6, 10e-6, 30e-6, 100e-6] {
        for kind in [ModelKind::Full, ModelKind::Paper] {
            print!("{:>6.3} mm  {:<6}", sigma * 1e3, kind.as_str());
            for (i, e) in errors.iter().enumerate() {
                // An encoder reading e long: true length = rho / (1 + e).
                let t = bench.run(kind, sigma, 1.0 / (1.0 + e), trials / 2, 500 + i as u64 + (sigma * 1e9) as u64);
                print!(" {:>11.2}%", 100.0 * t.scale_off as f64 / (trials / 2).max(1) as f64);
            }
            println!();
        }
    }
    println!();

    println!("4. A tracer with a ball tip of radius ρ, from the plate and a Ø 40 mm ring gauge");
    println!("   (errors RMS in µm, {} trials a row; circ.: a 50x30 mm frame traced from inside)", trials.max(4) / 4);
    tip_part(&bench, trials);
    println!();

    println!("5. Size figures: share of trials whose U95 covers the exact [C, A, B, FED], {trials} a row");
    size_part(trials);
    println!();

    println!("6. The third dimension: frames on a sphere, a height channel, {} trials a base", trials.max(4) / 4);
    height_part(trials.max(4) / 4);
}

/// Part 6 (module docs).
fn height_part(trials: usize) {
    use tracer_calib::cell::NodeState;
    use tracer_calib::engine::shape::Shape;
    use tracer_calib::engine::simulate::{HeightOptions, on_sphere, simulate_heights};
    use tracer_calib::engine::stylus::Groove;
    use tracer_calib::interfaces::{CalibrateRequest, Header, RawScan};
    use tracer_calib::params::Parameters;
    let groove = 110f64.to_radians();
    let truth = Mounting::new(2f64.to_radians(), 0.005, 0.002);
    let plate = PlateSpec::default();
    let ring = Ellipse { center: Vector2::new(-0.0006, 0.0004), a: 0.020, b: 0.020, angle: 0.0 };
    let frame = RoundedRect { center: Vector2::new(0.001, -0.0005), half_w: 0.026, half_h: 0.016, radius: 0.005 };
    let tilt = [0.1f64.to_radians(), 0.0];
    let heights = HeightOptions { zero: 0.0, tilt, noise: 5e-6, quantum: 1e-7 };
    let scan = |sim: &tracer_calib::engine::simulate::SimScan, id: u32, target: u8, z: &[f64]| RawScan {
        header: Header::default(),
        scan_id: id,
        target,
        steps_per_revolution: 400,
        step: sim.scan.samples().iter().map(|s| s.step).collect(),
        counts: sim.scan.samples().iter().map(|s| (s.rho / 1e-6).round() as i32).collect(),
        height_counts: z.iter().map(|h| (h / 1e-7).round() as i32).collect(),
    };
    println!(
        "{:>6} {:>14} {:>16} {:>9} {:>12} {:>16} {:>18}",
        "base", "L3 - C [mm]", "mean error µm", "sd µm", "U95 covers", "curve worst D", "tilt sd / stated"
    );
    let mut rng = StdRng::seed_from_u64(90);
    for base in [2.0, 4.0, 6.0, 8.0] {
        let surface = on_sphere(base, frame.center + Vector2::new(0.004, 0.0015), 0.002);
        // The true 3-D length: 20 000 points round the frame, each at its height.
        let n = 20_000;
        let at = |i: usize| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            let u = Vector2::new(t.cos(), t.sin());
            let p = frame.exit(frame.center, u).map_or(frame.center, |hit| frame.center + u * hit.t);
            nalgebra::Vector3::new(p.x, p.y, surface(p))
        };
        let length: f64 = (0..n).map(|i| (at(i + 1) - at(i)).norm()).sum();
        let (mut err, mut err2, mut covered, mut worst, mut tilts, mut stated) = (0.0, 0.0, 0, 0.0f64, Vec::new(), 0.0);
        for _ in 0..trials {
            let mut params = Parameters { model: ModelKind::FullTip, ..Parameters::default() };
            params.ring_diameter = 0.040;
            params.ring_groove_angle = groove;
            params.frame_groove = Groove::new(groove, 0.0);
            params.height_meters_per_count = 1e-7;
            let mut st = NodeState::new("/tracer_calibrator".into(), params);
            let opt = |inside| SimOptions {
                noise: 5e-6,
                quantum: 1e-6,
                tip_radius: 0.0005,
                inside,
                groove_angle: if inside { groove } else { std::f64::consts::PI },
                ..SimOptions::default()
            };
            let p = simulate(&plate.at(Vector2::new(0.0008, -0.0005)), &truth, &opt(false), &mut rng).unwrap();
            let r = simulate(&ring, &truth, &opt(true), &mut rng).unwrap();
            let f = simulate(&frame, &truth, &opt(true), &mut rng).unwrap();
            let zp = simulate_heights(&p, |_| 0.0, &heights, &mut rng).unwrap();
            let zr = simulate_heights(&r, |_| -0.0015, &heights, &mut rng).unwrap();
            let zf = simulate_heights(&f, &surface, &heights, &mut rng).unwrap();
            st.on_raw_scan(&scan(&p, 1, RawScan::TARGET_CALIBRATION_PLATE, &zp), false).unwrap();
            st.on_raw_scan(&scan(&r, 2, RawScan::TARGET_RING_GAUGE, &zr), false).unwrap();
            let out = st.on_calibrate(&CalibrateRequest { scan_id: 1, ring_scan_id: 2, ..CalibrateRequest::default() });
            if !out.response.success {
                continue;
            }
            tilts.push(st.params.axis_tilt.angles[0]);
            stated += st.params.axis_tilt.covariance[0].sqrt();
            let c = st.on_raw_scan(&scan(&f, 3, RawScan::TARGET_FRAME, &zf), false).unwrap().contour;
            let e = c.circumference_3d - length;
            err += e;
            err2 += e * e;
            covered += usize::from(e.abs() <= c.circumference_3d_u95);
            worst = worst.max((c.frame_curve - base).abs());
        }
        let k = tilts.len().max(1) as f64;
        let mean_tilt = tilts.iter().sum::<f64>() / k;
        let tilt_sd = (tilts.iter().map(|t| (t - mean_tilt).powi(2)).sum::<f64>() / (k - 1.0).max(1.0)).sqrt();
        println!(
            "{:>6.0} {:>14.3} {:>16.2} {:>9.2} {:>11.1}% {:>16.4} {:>18.3}",
            base,
            (length - frame.exact_sizes()[0]) * 1e3,
            err / k * 1e6,
            (err2 / k - (err / k).powi(2)).max(0.0).sqrt() * 1e6,
            covered as f64 / k * 100.0,
            worst,
            tilt_sd / (stated / k)
        );
    }
}

/// Part 5 (module docs).
fn size_part(trials: usize) {
    use tracer_calib::engine::shape::RoundedRect;
    let lens = Ellipse { center: Vector2::new(0.0005, -0.0003), a: 0.026, b: 0.016, angle: 0.3 };
    let frame = RoundedRect { center: Vector2::new(0.001, -0.0005), half_w: 0.025, half_h: 0.015, radius: 0.008 };
    println!(
        "{:>9}  {:<28} {:>28} {:>26} {:>26} {:>9} {:>8}",
        "noise", "contour", "covered [C, A, B, FED] %", "mean U95 µm", "mean error µm", "radii %", "refused"
    );
    for (i, sigma) in [1e-6, 5e-6, 10e-6].into_iter().enumerate() {
        let rows = [
            (
                "lens 52x34, full",
                size_coverage::run(
                    &lens,
                    lens.exact_sizes(),
                    Traced::Outside,
                    ModelKind::Full,
                    0.0,
                    sigma,
                    trials,
                    70 + i as u64,
                ),
            ),
            (
                "frame 50x30, full_tip 0.5 mm",
                size_coverage::run(
                    &frame,
                    frame.exact_sizes(),
                    Traced::Inside,
                    ModelKind::FullTip,
                    0.0005,
                    sigma,
                    trials,
                    80 + i as u64,
                ),
            ),
        ];
        for (name, c) in rows {
            let f = |v: [f64; 4], scale: f64| v.map(|x| format!("{:.1}", x * scale)).join(" ");
            println!(
                "{:>6.3} mm  {:<28} {:>28} {:>26} {:>26} {:>9.1} {:>8}",
                sigma * 1e3,
                name,
                f(c.covered.map(|k| k as f64 / c.n as f64), 100.0),
                f(c.u95, 1e6),
                f(c.bias, 1e6),
                c.radii_covered * 100.0,
                c.refused
            );
        }
    }
}

/// Part 4: the stylus tip (module docs).
fn tip_part(bench: &Bench, trials: usize) {
    let ring = RingSpec::plain(0.040);
    let ring_shape = Ellipse { center: Vector2::new(-0.0006, 0.0004), a: 0.020, b: 0.020, angle: 0.0 };
    let frame = RoundedRect { center: Vector2::new(0.001, -0.0005), half_w: 0.025, half_h: 0.015, radius: 0.008 };
    println!(
        "{:>9}  {:<15} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>12} {:>10} {:>7}",
        "noise",
        "model",
        "ρ mm",
        "ρ err µm",
        "bound",
        "reported",
        "dL err",
        "bound",
        "circ. err µm",
        "circ. bias",
        "failed"
    );
    for sigma in [10e-6, 1e-6] {
        for kind in [ModelKind::FullTip, ModelKind::FullScaleTip] {
            for rho in [0.0, 0.25e-3, 0.5e-3, 1e-3] {
                let sim = |shape: &dyn Fn(&SimOptions, &mut StdRng) -> tracer_calib::engine::simulate::SimScan,
                           noise: f64,
                           inside: bool,
                           rng: &mut StdRng| {
                    shape(&SimOptions { noise, tip_radius: rho, inside, ..SimOptions::default() }, rng)
                };
                let plate = |o: &SimOptions, r: &mut StdRng| {
                    simulate(&bench.plate.at(bench.center), &bench.truth, o, r).unwrap()
                };
                let gauge = |o: &SimOptions, r: &mut StdRng| simulate(&ring_shape, &bench.truth, o, r).unwrap();
                let framed = |o: &SimOptions, r: &mut StdRng| simulate(&frame, &bench.truth, o, r).unwrap();
                let mut rng = StdRng::seed_from_u64(4000 + (rho * 1e6) as u64 + (sigma * 1e9) as u64);
                // The bound: σ² (JᵀJ)⁻¹ of the tip model at the truth.
                let (p0, g0) = (sim(&plate, 0.0, false, &mut rng), sim(&gauge, 0.0, true, &mut rng));
                let model = TipModel::from_scans(FullModel::from_scan(&bench.plate, &p0.scan), &ring, &g0.scan);
                let x = tip::from_full(&full::params(&bench.truth, bench.center), rho, ring_shape.center);
                let (b_rho, b_dl) = if kind.fits_scale() {
                    let inv = normal_equations(&TipScaleModel::new(model), &tip::with_scale(&x, 1.0))
                        .unwrap()
                        .jtj
                        .try_inverse()
                        .unwrap();
                    (inv[(tip::TIP_RADIUS, tip::TIP_RADIUS)].sqrt(), inv[(tip::DELTA_L, tip::DELTA_L)].sqrt())
                } else {
                    let inv = normal_equations(&model, &x).unwrap().jtj.try_inverse().unwrap();
                    (inv[(tip::TIP_RADIUS, tip::TIP_RADIUS)].sqrt(), inv[(tip::DELTA_L, tip::DELTA_L)].sqrt())
                };
                let traced = sim(&framed, 0.0, true, &mut rng);
                let true_circ = size_coverage::polygon_circumference(&traced.truth);
                let (mut sq_rho, mut sq_dl, mut reported, mut sq_circ, mut sum_circ, mut n, mut failed) =
                    (0.0, 0.0, 0.0, 0.0, 0.0, 0, 0);
                for _ in 0..trials.max(4) / 4 {
                    let (p, g) = (sim(&plate, sigma, false, &mut rng), sim(&gauge, sigma, true, &mut rng));
                    let opts = Options { model: kind, ..Options::default() };
                    match calibrate_with_ring(&p.scan, Some(Ring { scan: &g.scan, spec: ring }), &bench.plate, &opts) {
                        Ok(cal) => {
                            sq_rho += (cal.tip_radius - rho).powi(2);
                            sq_dl += (cal.mounting.delta_l - bench.truth.delta_l).powi(2);
                            reported += cal.tip_radius_stddev;
                            let mut pts = correct(&traced.scan, &cal.mounting);
                            touched_surface(&mut pts, cal.tip_radius, Traced::Inside, true);
                            let e = size_coverage::polygon_circumference(&pts) - true_circ;
                            sq_circ += e * e;
                            sum_circ += e;
                            n += 1;
                        }
                        Err(_) => failed += 1,
                    }
                }
                let rms = |s: f64| (s / n.max(1) as f64).sqrt();
                println!(
                    "{:>6.3} mm  {:<15} {:>6.2} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>12.2} {:>+10.2} {:>7}",
                    sigma * 1e3,
                    kind.as_str(),
                    rho * 1e3,
                    rms(sq_rho) * 1e6,
                    b_rho * sigma * 1e6,
                    reported / n.max(1) as f64 * 1e6,
                    rms(sq_dl) * 1e6,
                    b_dl * sigma * 1e6,
                    rms(sq_circ) * 1e6,
                    sum_circ / n.max(1) as f64 * 1e6,
                    failed
                );
            }
        }
    }
}

fn header() {
    println!(
        "{:>9}  {:<10} {:>10} {:>10} {:>10} {:>8} {:>10} {:>7}   {:>29}",
        "noise", "model", "alpha0", "d", "dL", "k", "ellipse", "failed", "RMS / CRLB (a0, d, dL, k)"
    );
}

fn row(sigma: f64, name: &str, t: &Tally, crlb: &[f64; 4]) {
    let rms = t.rms();
    let rep = t.mean_reported();
    let ratio = |i: usize| if crlb[i] > 0.0 { format!("{:>6.2}", rms[i] / crlb[i]) } else { format!("{:>6}", "-") };
    println!(
        "{:>6.3} mm  {:<10} {:>10.5} {:>10.5} {:>10.5} {:>8.0} {:>10.5} {:>7}   {} {} {} {}",
        sigma * 1e3,
        name,
        rms[0].to_degrees(),
        rms[1] * 1e3,
        rms[2] * 1e3,
        rms[3] * 1e6,
        t.ellipse_rms() * 1e3,
        t.failures,
        ratio(0),
        ratio(1),
        ratio(2),
        ratio(3)
    );
    println!(
        "{:>9}  {:<10} {:>10.5} {:>10.5} {:>10.5} {:>8.0}   (mean reported standard uncertainty)",
        "",
        "",
        rep[0].to_degrees(),
        rep[1] * 1e3,
        rep[2] * 1e3,
        rep[3] * 1e6
    );
}
