//! The encoder scale end to end on simulated scans: model `full_scale` recovers the scale
//! and the mounting errors from scale errors of ±0.05 to ±1 %, its reported uncertainty
//! is honest, and the models that do not fit the scale refuse a wrong-size tracer
//! while passing correct ones.

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use tracer_calib_engine::calibrate::{CalibrationError, Options, calibrate};
use tracer_calib_engine::correct::correct;
use tracer_calib_engine::geometry::Mounting;
use tracer_calib_engine::model::{ModelKind, PlateSpec};
use tracer_calib_engine::scan::Scan;
use tracer_calib_engine::shape::Ellipse;
use tracer_calib_engine::simulate::{SimOptions, simulate};

const PLATE: PlateSpec = PlateSpec { side: 0.045, corner_radius: 0.003 };
const CENTER: Vector2<f64> = Vector2::new(0.0008, -0.0005);

fn truth(k: f64) -> Mounting {
    Mounting::new(2f64.to_radians(), 0.005, 0.002).with_scale(k)
}

fn plate_scan(m: &Mounting, noise: f64, seed: u64) -> Scan {
    let mut rng = StdRng::seed_from_u64(seed);
    simulate(&PLATE.at(CENTER), m, &SimOptions { noise, ..SimOptions::default() }, &mut rng).unwrap().scan
}

fn options(model: ModelKind) -> Options {
    Options { model, ..Options::default() }
}

#[test]
fn exact_recovery_of_the_scale_on_noise_free_scans() {
    for k in [0.99, 0.9975, 1.0, 1.0005, 1.01] {
        let m = truth(k);
        let cal = calibrate(&plate_scan(&m, 0.0, 1), &PLATE, &options(ModelKind::FullScale)).unwrap();
        // The fit stops once the remaining step is a thousandth of its (here tiny)
        // uncertainty: exact to ~1e-10 relative.
        assert!((cal.mounting.scale - k).abs() < 1e-10, "k = {k}: {:?}", cal.mounting);
        assert!((cal.mounting.alpha0 - m.alpha0).abs() < 1e-10, "k = {k}: {:?}", cal.mounting);
        assert!((cal.mounting.offset - m.offset).abs() < 1e-11, "k = {k}: {:?}", cal.mounting);
        assert!((cal.mounting.delta_l - m.delta_l).abs() < 1e-11, "k = {k}: {:?}", cal.mounting);
        assert!((cal.plate_center - CENTER).norm() < 1e-11);
        assert_eq!(cal.scale_check, None, "full_scale has no scale check");
    }
}

/// Scale errors of ±0.05 to ±1 % (both ways), mounting errors across the convergence
/// region, σ = 10 µm: every parameter within 5 of its reported standard uncertainties.
#[test]
fn full_scale_recovers_scale_and_mounting_within_a_few_sigma() {
    let mut seed = 0;
    for k in [0.99, 0.995, 0.9975, 0.999, 0.9995, 1.0005, 1.001, 1.0025, 1.005, 1.01] {
        for (alpha_deg, d) in [(2.0, 0.005), (-41.0, -0.018), (30.0, 0.012), (44.0, 0.0)] {
            seed += 1;
            let m = Mounting::new(f64::to_radians(alpha_deg), d, -0.0015).with_scale(k);
            let cal = calibrate(&plate_scan(&m, 10e-6, seed), &PLATE, &options(ModelKind::FullScale))
                .unwrap_or_else(|e| panic!("k = {k}, alpha0 = {alpha_deg}°, d = {d}: {e}"));
            let z = [
                (cal.mounting.scale - k) / cal.scale_stddev,
                (cal.mounting.alpha0 - m.alpha0) / cal.stddev[0],
                (cal.mounting.offset - m.offset) / cal.stddev[1],
                (cal.mounting.delta_l - m.delta_l) / cal.stddev[2],
            ];
            assert!(z.iter().all(|z| z.abs() < 5.0), "k = {k}, alpha0 = {alpha_deg}°, d = {d}: z = {z:?}");
            // At σ = 10 µm the bound on k is about 2.1e-4.
            assert!(cal.scale_stddev > 1.5e-4 && cal.scale_stddev < 3e-4, "{}", cal.scale_stddev);
        }
    }
}

/// The reported scale_stddev matches the spread of the estimates (within a factor of 2;
/// measured: within a few per cent), and the estimates are unbiased.
#[test]
fn reported_scale_uncertainty_is_honest() {
    let k = 1.0025;
    let (mut sum, mut sq, mut reported) = (0.0, 0.0, 0.0);
    let n = 300;
    for seed in 0..n {
        let cal =
            calibrate(&plate_scan(&truth(k), 10e-6, 1000 + seed), &PLATE, &options(ModelKind::FullScale)).unwrap();
        let e = cal.mounting.scale - k;
        sum += e;
        sq += e * e;
        reported += cal.scale_stddev;
    }
    let n = n as f64;
    let spread = (sq / n - (sum / n).powi(2)).sqrt();
    let reported = reported / n;
    let ratio = spread / reported;
    assert!((0.5..2.0).contains(&ratio), "observed {spread:e} vs reported {reported:e}");
    assert!((0.8..1.25).contains(&ratio), "observed {spread:e} vs reported {reported:e} (ratio {ratio})");
    assert!((sum / n).abs() < 4.0 * spread / n.sqrt(), "bias {:e}", sum / n);
}

/// The case: an encoder reading 0.25 % long, σ = 3 µm. The models that do not fit
/// the scale refuse it and say what the scan shows; full_scale takes it.
#[test]
fn a_wrong_size_tracer_is_not_a_silent_success() {
    let k = 1.0 / 1.0025;
    let scan = plate_scan(&truth(k), 3e-6, 7);
    for model in [ModelKind::Full, ModelKind::Paper] {
        match calibrate(&scan, &PLATE, &options(model)) {
            Err(e @ CalibrationError::ScaleOff { estimate, k0 }) => {
                assert_eq!(k0, 1.0);
                assert!((estimate.scale - k).abs() < 5.0 * estimate.stddev, "{model}: {estimate:?}");
                let text = e.to_string();
                assert!(text.contains("encoder scale looks off") && text.contains("full_scale"), "{text}");
                assert!(text.contains("too long"), "{text}");
            }
            other => panic!("{model}: {other:?}"),
        }
    }
    let cal = calibrate(&scan, &PLATE, &options(ModelKind::FullScale)).unwrap();
    assert!((cal.mounting.scale - k).abs() < 5.0 * cal.scale_stddev);
    // The same scan with the scale in force: full passes, and finds the same mounting.
    let known = Options { scale: k, ..options(ModelKind::Full) };
    let cal_known = calibrate(&scan, &PLATE, &known).unwrap();
    assert_eq!(cal_known.mounting.scale, k);
    let check = cal_known.scale_check.unwrap();
    assert!(check.sigmas_from(k) < 5.0, "{check:?}");
    assert!((cal_known.mounting.offset - cal.mounting.offset).abs() < 3.0 * cal.stddev[1]);
}

/// Correct tracers at every noise level keep passing with every model.
#[test]
fn correct_tracers_pass_the_scale_check_at_every_noise_level() {
    for (i, sigma) in [1e-6, 3e-6, 10e-6, 30e-6, 100e-6].into_iter().enumerate() {
        for seed in 0..40 {
            let scan = plate_scan(&truth(1.0), sigma, 100 * i as u64 + seed);
            for model in [ModelKind::Full, ModelKind::Paper] {
                let cal = calibrate(&scan, &PLATE, &options(model))
                    .unwrap_or_else(|e| panic!("σ = {sigma}, seed {seed}, {model}: {e}"));
                let check = cal.scale_check.expect("full and paper check the scale");
                assert!(check.sigmas_from(1.0) < 5.0, "{check:?}");
            }
        }
    }
}

/// A lens traced by a tracer whose encoder reads 0.25 % long, corrected with a
/// full_scale calibration, comes out true to within the calibration's noise; corrected
/// with the scale ignored, it is tens of µm off.
#[test]
fn a_lens_corrected_with_the_fitted_scale_is_true() {
    let k = 1.0 / 1.0025;
    let m = truth(k);
    let cal = calibrate(&plate_scan(&m, 3e-6, 3), &PLATE, &options(ModelKind::FullScale)).unwrap();
    let mut rng = StdRng::seed_from_u64(4);
    let lens = Ellipse { center: Vector2::new(0.001, -0.002), a: 0.03, b: 0.018, angle: 0.3 };
    let sim = simulate(&lens, &m, &SimOptions::default(), &mut rng).unwrap();
    let rms = |mounting: &Mounting| {
        let pts = correct(&sim.scan, mounting);
        (pts.iter().zip(&sim.truth).map(|(p, q)| (p - q).norm_squared()).sum::<f64>() / pts.len() as f64).sqrt()
    };
    let fitted = rms(&cal.mounting);
    assert!(fitted < 3e-6, "{fitted:e}");
    let ignored = rms(&cal.mounting.with_scale(1.0));
    assert!(ignored > 30e-6, "{ignored:e}");
}
