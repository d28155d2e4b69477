//! The stylus tip end to end on simulated scans: a tracer touching with a
//! ball of radius ρ, its tip fitted from a plate and a ring gauge (`full_tip`,
//! `full_scale_tip`), a known tip in force for the other models, frames and lenses
//! corrected to the surface the tip touched, and the scans that do not fit refused.

#[path = "common/size_coverage.rs"]
#[allow(dead_code)] // shared with tests/sizes.rs and the accuracy example
mod size_coverage;

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use size_coverage::polygon_circumference;
use tracer_calib_engine::calibrate::{CalibrationError, Options, Ring, calibrate, calibrate_with_ring};
use tracer_calib_engine::correct::{correct, resample_radii};
use tracer_calib_engine::geometry::Mounting;
use tracer_calib_engine::model::tip::RingSpec;
use tracer_calib_engine::model::{ModelKind, PlateSpec};
use tracer_calib_engine::scan::Scan;
use tracer_calib_engine::shape::{Ellipse, RoundedRect, Shape};
use tracer_calib_engine::simulate::{SimOptions, SimScan, simulate};
use tracer_calib_engine::stylus::{Traced, touched_surface};

const PLATE: PlateSpec = PlateSpec { side: 0.045, corner_radius: 0.003 };
const RING: RingSpec = RingSpec::plain(0.040);

fn truth() -> Mounting {
    Mounting::new(2f64.to_radians(), 0.005, 0.002)
}

fn ring_shape() -> Ellipse {
    Ellipse { center: Vector2::new(-0.0006, 0.0004), a: RING.diameter / 2.0, b: RING.diameter / 2.0, angle: 0.0 }
}

fn trace(shape: &impl Shape, m: &Mounting, tip: f64, inside: bool, noise: f64, seed: u64) -> SimScan {
    let opt = SimOptions { noise, tip_radius: tip, inside, ..SimOptions::default() };
    simulate(shape, m, &opt, &mut StdRng::seed_from_u64(seed)).unwrap()
}

fn plate_and_ring(m: &Mounting, tip: f64, noise: f64, seed: u64) -> (Scan, Scan) {
    let plate = trace(&PLATE.at(Vector2::new(0.0008, -0.0005)), m, tip, false, noise, seed).scan;
    let ring = trace(&ring_shape(), m, tip, true, noise, seed + 1000).scan;
    (plate, ring)
}

fn options(model: ModelKind) -> Options {
    Options { model, ..Options::default() }
}

#[test]
fn the_tip_models_recover_the_tip_exactly_from_noise_free_scans() {
    let m = truth();
    for tip in [0.0, 1e-4, 5e-4, 1e-3] {
        let (plate, ring) = plate_and_ring(&m, tip, 0.0, 1);
        for model in [ModelKind::FullTip, ModelKind::FullScaleTip] {
            let cal = calibrate_with_ring(&plate, Some(Ring { scan: &ring, spec: RING }), &PLATE, &options(model))
                .unwrap_or_else(|e| panic!("{model}, tip {tip}: {e}"));
            assert!((cal.tip_radius - tip).abs() < 1e-10, "{model}: tip {} for {tip}", cal.tip_radius);
            assert!((cal.mounting.delta_l - m.delta_l).abs() < 1e-10, "{model}: {:?}", cal.mounting);
            assert!((cal.mounting.offset - m.offset).abs() < 1e-10, "{model}: {:?}", cal.mounting);
            assert!((cal.mounting.alpha0 - m.alpha0).abs() < 1e-9, "{model}: {:?}", cal.mounting);
            assert!((cal.mounting.scale - 1.0).abs() < 1e-9, "{model}: {:?}", cal.mounting);
            let ring_fit = cal.ring.as_ref().unwrap();
            assert!((ring_fit.center - ring_shape().center).norm() < 1e-10, "{:?}", ring_fit.center);
            assert!(cal.tip_radius_stddev > 0.0 && cal.covariance[(4, 4)] > 0.0);
        }
    }
}

#[test]
fn a_known_tip_in_force_keeps_the_other_models_true() {
    let m = truth();
    let tip = 5e-4;
    let (plate, _) = plate_and_ring(&m, tip, 0.0, 2);
    for model in [ModelKind::Full, ModelKind::FullScale, ModelKind::Paper] {
        let told = calibrate(&plate, &PLATE, &Options { tip_radius: tip, ..options(model) }).unwrap();
        assert!((told.mounting.delta_l - m.delta_l).abs() < 1e-9, "{model}: {:?}", told.mounting);
        assert_eq!((told.tip_radius, told.tip_radius_stddev), (tip, 0.0));
    }
    // Not told, the full model hides a small tip in dL: the fit looks perfect and is
    // wrong by the tip's radius...
    // (On a noise-free scan the scale check sees it: -262 ppm of scale per 10 µm.)
    let small = 10e-6;
    let (plate, _) = plate_and_ring(&m, small, 10e-6, 2);
    let blind = calibrate(&plate, &PLATE, &options(ModelKind::Full)).unwrap();
    assert!(blind.rms_residual < 12e-6, "{}", blind.rms_residual);
    let error = blind.mounting.delta_l - m.delta_l;
    assert!((error - small).abs() < 4.0 * blind.stddev[2], "dL off by {error} ± {}", blind.stddev[2]);
    // ... and a large one leaves the corners' radii wrong by it: refused as systematic.
    let (plate, _) = plate_and_ring(&m, tip, 0.0, 2);
    let e = calibrate(&plate, &PLATE, &options(ModelKind::Full)).unwrap_err();
    assert!(matches!(e, CalibrationError::SystematicResidual { .. }), "{e}");
}

/// After a tip calibration from noisy scans, a frame traced from inside by a tip of up
/// to 1 mm keeps its circumference within 5 µm of the truth (the figure).
#[test]
fn frames_keep_their_circumference_for_any_tip_up_to_a_millimetre() {
    let m = truth();
    let frame = RoundedRect { center: Vector2::new(0.001, -0.0005), half_w: 0.025, half_h: 0.015, radius: 0.008 };
    for (i, tip) in [0.0, 2.5e-4, 5e-4, 1e-3].into_iter().enumerate() {
        let (plate, ring) = plate_and_ring(&m, tip, 5e-6, 10 + i as u64);
        let cal =
            calibrate_with_ring(&plate, Some(Ring { scan: &ring, spec: RING }), &PLATE, &options(ModelKind::FullTip))
                .unwrap();
        assert!(
            (cal.tip_radius - tip).abs() < 4.0 * cal.tip_radius_stddev + 1e-9,
            "tip {} ± {} for {tip}",
            cal.tip_radius,
            cal.tip_radius_stddev
        );
        let traced = trace(&frame, &m, tip, true, 0.0, 20 + i as u64);
        let mut points = correct(&traced.scan, &cal.mounting);
        touched_surface(&mut points, cal.tip_radius, Traced::Inside, true);
        let error = polygon_circumference(&points) - polygon_circumference(&traced.truth);
        assert!(error.abs() < 5e-6, "tip {tip}: circumference off by {:.2} µm", error * 1e6);
        // And radius by radius, to the surface the tip touched.
        let radii = resample_radii(&points, 400, 0.2).unwrap();
        let truth = resample_radii(&traced.truth, 400, 0.2).unwrap();
        let worst = radii.iter().zip(&truth).map(|(r, t)| (r - t).abs()).fold(0.0, f64::max);
        eprintln!("tip {tip}: circumference {:+.2} µm, worst radius {:.2} µm", error * 1e6, worst * 1e6);
        assert!(worst < 10e-6, "tip {tip}: a radius {:.2} µm off", worst * 1e6);
    }
}

#[test]
fn a_ring_that_does_not_fit_is_refused_with_the_reason() {
    let m = truth();
    let (plate, ring) = plate_and_ring(&m, 5e-4, 5e-6, 3);
    let opt = options(ModelKind::FullTip);
    // No ring at all.
    let e = calibrate_with_ring(&plate, None, &PLATE, &opt).unwrap_err();
    assert!(matches!(e, CalibrationError::Ring(_)) && e.to_string().contains("ring.diameter"), "{e}");
    // The plate scan given as the ring.
    let e = calibrate_with_ring(&plate, Some(Ring { scan: &plate, spec: RING }), &PLATE, &opt).unwrap_err();
    assert!(e.to_string().contains("ring"), "{e}");
    // A ring gauge of another diameter than the one set.
    // (A diameter off by a tenth of a millimetre mostly moves the fitted tip: ring and
    // tip are one length on the ring, and the plate tells the tip from dL only weakly,
    // by its corners' radii.)
    for wrong in [0.039, 0.041, 0.045] {
        let e = calibrate_with_ring(&plate, Some(Ring { scan: &ring, spec: RingSpec::plain(wrong) }), &PLATE, &opt)
            .map(|c| format!("{} tip {} ring rms {:?}", c.summary(), c.tip_radius, c.ring.map(|r| r.rms_residual)))
            .expect_err(&format!("diameter {wrong} accepted"));
        assert!(e.to_string().contains("ring") || e.to_string().contains("plate"), "{e}");
    }
    // An invalid diameter.
    let e =
        calibrate_with_ring(&plate, Some(Ring { scan: &ring, spec: RingSpec::plain(-1.0) }), &PLATE, &opt).unwrap_err();
    assert!(e.to_string().contains("diameter"), "{e}");
}
