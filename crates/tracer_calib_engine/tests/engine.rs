//! The calibration engine end to end on simulated scans: exact recovery, the
//! convergence region, spikes, gaps, and the errors of a failed fit.

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use tracer_calib_engine::calibrate::{CalibrationError, Options, calibrate};
use tracer_calib_engine::correct::{correct, default_max_gap, resample_radii};
use tracer_calib_engine::geometry::Mounting;
use tracer_calib_engine::model::{ModelKind, PlateSpec};
use tracer_calib_engine::scan::Scan;
use tracer_calib_engine::shape::{Ellipse, Shape};
use tracer_calib_engine::simulate::{SimOptions, simulate};

const PLATE: PlateSpec = PlateSpec { side: 0.045, corner_radius: 0.003 };

fn paper_truth() -> (Mounting, Vector2<f64>) {
    (Mounting::new(2f64.to_radians(), 0.005, 0.002), Vector2::new(0.0008, -0.0005))
}

fn plate_scan(m: &Mounting, c: Vector2<f64>, opt: &SimOptions, seed: u64) -> Scan {
    let mut rng = StdRng::seed_from_u64(seed);
    simulate(&PLATE.at(c), m, opt, &mut rng).unwrap().scan
}

fn options(model: ModelKind) -> Options {
    Options { model, ..Options::default() }
}

#[test]
fn exact_recovery_on_noise_free_scans() {
    let (m, c) = paper_truth();
    let scan = plate_scan(&m, c, &SimOptions::default(), 1);
    for model in [ModelKind::Full, ModelKind::Paper] {
        let cal = calibrate(&scan, &PLATE, &options(model)).unwrap();
        assert!((cal.mounting.alpha0 - m.alpha0).abs() < 1e-11, "{model}: {:?}", cal.mounting);
        assert!((cal.mounting.offset - m.offset).abs() < 1e-12, "{model}: {:?}", cal.mounting);
        assert!((cal.mounting.delta_l - m.delta_l).abs() < 1e-12, "{model}: {:?}", cal.mounting);
        assert!((cal.plate_center - c).norm() < 1e-12, "{model}: {:?}", cal.plate_center);
        assert!(cal.rms_residual < 1e-12);
        assert_eq!(cal.samples_rejected, 0, "{model}");
    }
}

/// Every alpha0 in (-45°, 45°] on a 3° grid (plus the edges) and |d| up to 20 mm,
/// with the plate off centre and realistic noise: the fit lands within 6 σ of the
/// truth, with alpha0 reported in (-45°, 45°].
#[test]
fn converges_across_the_whole_region() {
    let opt = SimOptions { noise: 10e-6, ..SimOptions::default() };
    let mut alphas: Vec<f64> = (-14..=15).map(|k| 3.0 * k as f64).collect();
    alphas.extend([-44.9, 44.9, 45.0]);
    let mut failures = Vec::new();
    let mut cases = 0;
    for (i, &alpha_deg) in alphas.iter().enumerate() {
        for (j, &d_mm) in [-20.0, -12.5, -5.0, 0.0, 2.5, 10.0, 17.5, 20.0].iter().enumerate() {
            cases += 1;
            let m = Mounting::new(f64::to_radians(alpha_deg), d_mm * 1e-3, 1.5e-3 * (j as f64 - 3.0));
            let c = Vector2::new(0.002 * ((i % 5) as f64 - 2.0) / 2.0, -0.0015 * ((j % 3) as f64 - 1.0));
            let scan = plate_scan(&m, c, &opt, (i * 100 + j) as u64);
            match calibrate(&scan, &PLATE, &options(ModelKind::Full)) {
                Ok(cal) => {
                    let mut da = cal.mounting.alpha0 - m.alpha0;
                    // 45° and -45° are the same plate orientation.
                    if da.abs() > 1.0 {
                        da -= da.signum() * std::f64::consts::FRAC_PI_2;
                    }
                    let ok = da.abs() < 6.0 * cal.stddev[0]
                        && (cal.mounting.offset - m.offset).abs() < 6.0 * cal.stddev[1]
                        && (cal.mounting.delta_l - m.delta_l).abs() < 6.0 * cal.stddev[2]
                        && cal.mounting.alpha0 > -std::f64::consts::FRAC_PI_4
                        && cal.mounting.alpha0 <= std::f64::consts::FRAC_PI_4;
                    if !ok {
                        failures.push(format!("alpha0 {alpha_deg}° d {d_mm} mm: got {:?}", cal.mounting));
                    }
                }
                Err(e) => failures.push(format!("alpha0 {alpha_deg}° d {d_mm} mm: {e}")),
            }
        }
    }
    assert!(failures.is_empty(), "{} of {cases} failed:\n{}", failures.len(), failures.join("\n"));
}

#[test]
fn spikes_are_rejected() {
    let (m, c) = paper_truth();
    for (noise, seed) in [(10e-6, 3), (100e-6, 4)] {
        let opt = SimOptions { noise, spikes: 6, spike_height: 0.5e-3, ..SimOptions::default() };
        let mut rng = StdRng::seed_from_u64(seed);
        let sim = simulate(&PLATE.at(c), &m, &opt, &mut rng).unwrap();
        let clean = {
            let mut rng = StdRng::seed_from_u64(seed);
            simulate(&PLATE.at(c), &m, &SimOptions { spikes: 0, ..opt }, &mut rng).unwrap()
        };
        for model in [ModelKind::Full, ModelKind::Paper] {
            let cal = calibrate(&sim.scan, &PLATE, &options(model)).unwrap();
            // Every spiked sample the model used is rejected.
            for (k, (&(_, used), &spiked)) in cal.residuals.iter().zip(&sim.spiked).enumerate() {
                assert!(!(spiked && used), "{model} σ={noise}: spiked sample {k} used");
            }
            let reference = calibrate(&clean.scan, &PLATE, &options(model)).unwrap();
            for i in 0..3 {
                let got = [cal.mounting.alpha0, cal.mounting.offset, cal.mounting.delta_l][i];
                let want = [reference.mounting.alpha0, reference.mounting.offset, reference.mounting.delta_l][i];
                assert!((got - want).abs() < 0.5 * reference.stddev[i], "{model} σ={noise} param {i}: {got} vs {want}");
            }
        }
    }
}

#[test]
fn gaps_and_an_odd_start_step_are_normal_input() {
    let (m, c) = paper_truth();
    let opt = SimOptions { noise: 10e-6, start_step: 137, missing: 0.15, ..SimOptions::default() };
    let scan = plate_scan(&m, c, &opt, 9);
    assert_eq!(scan.samples()[0].step, 137);
    assert!(scan.len() < 380);
    for model in [ModelKind::Full, ModelKind::Paper] {
        let cal = calibrate(&scan, &PLATE, &options(model)).unwrap();
        assert!((cal.mounting.alpha0 - m.alpha0).abs() < 6.0 * cal.stddev[0], "{model} {:?}", cal.mounting);
        assert!((cal.mounting.offset - m.offset).abs() < 6.0 * cal.stddev[1], "{model} {:?}", cal.mounting);
        if model == ModelKind::Full {
            assert_eq!(cal.samples_used + cal.samples_rejected, scan.len());
        } else {
            // The reduced model uses only opposite flat samples.
            assert!(cal.samples_used > 150 && cal.samples_used < scan.len(), "{}", cal.samples_used);
        }
    }
    // Another steps_per_revolution.
    let scan = plate_scan(&m, c, &SimOptions { steps_per_rev: 1000, noise: 10e-6, ..SimOptions::default() }, 10);
    let cal = calibrate(&scan, &PLATE, &options(ModelKind::Full)).unwrap();
    assert!((cal.mounting.offset - m.offset).abs() < 6.0 * cal.stddev[1]);
}

#[test]
fn failed_fits_say_why() {
    let (m, c) = paper_truth();
    let scan = plate_scan(&m, c, &SimOptions::default(), 1);
    let few = Scan::from_samples(400, scan.samples()[..10].to_vec()).unwrap();
    let e = calibrate(&few, &PLATE, &Options::default()).unwrap_err();
    assert_eq!(e, CalibrationError::TooFewSamples { got: 10, need: 24 });
    assert_eq!(e.to_string(), "too few samples: 10 usable, at least 24 needed");

    // A 50 mm plate told to be 45 mm: the residual gives it away.
    let wrong = PlateSpec { side: 0.050, corner_radius: 0.003 };
    let scan = plate_scan(&m, c, &SimOptions::default(), 1);
    let e = calibrate(&scan, &wrong, &Options::default()).unwrap_err();
    assert!(matches!(e, CalibrationError::SystematicResidual { .. }), "{e:?}");
    assert!(e.to_string().contains("check plate.side"), "{e}");

    // The paper model needs opposite samples.
    let odd = plate_scan(&m, c, &SimOptions { steps_per_rev: 401, ..SimOptions::default() }, 1);
    let e = calibrate(&odd, &PLATE, &options(ModelKind::Paper)).unwrap_err();
    assert!(e.to_string().contains("even steps_per_revolution"), "{e}");

    let e = calibrate(&scan, &PlateSpec { side: -1.0, corner_radius: 0.0 }, &Options::default()).unwrap_err();
    assert!(e.to_string().starts_with("invalid plate: plate side must be a positive"), "{e}");
}

/// The correction end to end: calibrate on the plate, correct an ellipse traced by
/// the same tracer, compare with where the probe really was.
#[test]
fn corrected_ellipse_matches_the_truth() {
    let (m, c) = paper_truth();
    let plate = plate_scan(&m, c, &SimOptions { noise: 10e-6, ..SimOptions::default() }, 21);
    let cal = calibrate(&plate, &PLATE, &Options::default()).unwrap();
    let lens = Ellipse { center: Vector2::new(0.0005, 0.001), a: 0.025, b: 0.015, angle: 0.0 };
    let mut rng = StdRng::seed_from_u64(5);
    let sim = simulate(&lens, &m, &SimOptions::default(), &mut rng).unwrap();
    let naive = correct(&sim.scan, &Mounting::IDEAL);
    let fixed = correct(&sim.scan, &cal.mounting);
    let rms = |pts: &[Vector2<f64>]| {
        (pts.iter().zip(&sim.truth).map(|(p, t)| (p - t).norm_squared()).sum::<f64>() / pts.len() as f64).sqrt()
    };
    assert!(rms(&naive) > 2e-3, "uncorrected error {}", rms(&naive));
    assert!(rms(&fixed) < 10e-6, "corrected error {}", rms(&fixed));
    let radii = resample_radii(&fixed, 400, default_max_gap(400)).unwrap();
    for (k, r) in radii.iter().enumerate() {
        let phi = std::f64::consts::TAU * k as f64 / 400.0;
        let u = Vector2::new(phi.cos(), phi.sin());
        let want = lens.exit(Vector2::zeros(), u).unwrap().t;
        assert!((r - want).abs() < 10e-6, "radius {k}: {r} vs {want}");
    }
}

/// The start search ranks its seeds by their first solve and refines only the best
/// (`start::REFINED`): every alpha0 in (-45°, 45°] on a 1° grid, |d| up to 20 mm on a
/// 2.5 mm grid, at σ = 1, 10 and 100 µm, with and without spikes, 5 % of the samples
/// missing and an odd start step (9180 scans): every fit lands within 6 σ.
#[test]
fn converges_on_a_dense_grid_at_every_noise_level() {
    let mut failures = Vec::new();
    let mut cases = 0;
    for (si, sigma) in [1e-6, 10e-6, 100e-6].into_iter().enumerate() {
        for spikes in [0usize, 4] {
            for a in -44..=45 {
                for di in -8..=8 {
                    let d = di as f64 * 2.5e-3;
                    let m = Mounting::new(f64::from(a).to_radians(), d, 1e-3 * f64::from((a + di) % 5));
                    let c = Vector2::new(0.0007 * f64::from(a % 3), -0.0006 * f64::from(di % 3));
                    let opt =
                        SimOptions { noise: sigma, spikes, missing: 0.05, start_step: 17, ..SimOptions::default() };
                    let seed = (si * 100_000 + spikes * 1000 + (a + 50) as usize * 20 + (di + 10) as usize) as u64;
                    let scan = plate_scan(&m, c, &opt, seed);
                    cases += 1;
                    match calibrate(&scan, &PLATE, &options(ModelKind::Full)) {
                        Ok(cal) => {
                            let mut da = cal.mounting.alpha0 - m.alpha0;
                            if da.abs() > 1.0 {
                                da -= da.signum() * std::f64::consts::FRAC_PI_2;
                            }
                            if !(da.abs() < 6.0 * cal.stddev[0]
                                && (cal.mounting.offset - d).abs() < 6.0 * cal.stddev[1])
                            {
                                failures
                                    .push(format!("alpha0 {a}° d {d} σ {sigma} spikes {spikes}: {:?}", cal.mounting));
                            }
                        }
                        Err(e) => failures.push(format!("alpha0 {a}° d {d} σ {sigma} spikes {spikes}: {e}")),
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{} of {cases} failed:\n{}", failures.len(), failures.join("\n"));
}
