//! The turntable's angle harmonics fitted with the calibration: one or several placements
//! of the plate, each with its own centre and turn (issue: an uncertainty that holds on a
//! real tracer, item 1). Figures printed.

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use tracer_calib::engine::angle::HarmonicOrders;
use tracer_calib::engine::calibrate::{Calibration, CalibrationError, Options, calibrate_placements};
use tracer_calib::engine::correct::Corrector;
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::engine::model::{ModelKind, PlateSpec};
use tracer_calib::engine::scan::Scan;
use tracer_calib::engine::simulate::{SimOptions, simulate};

const PLATE: PlateSpec = PlateSpec { side: 0.045, corner_radius: 0.003 };

fn deg(d: f64) -> f64 {
    d.to_radians()
}

/// The tracer: 2°, 5 mm, 2 mm, its angle 0.05° off once a turn and 0.02° twice.
const TRUTH: Mounting = Mounting::new(0.0349066, 0.005, 0.002);

fn tracer(noise: f64) -> SimOptions {
    SimOptions {
        noise,
        angle_harmonics: [(1, deg(0.05), deg(-0.01)), (2, 0.0, deg(0.02)), (0, 0.0, 0.0)],
        ..SimOptions::default()
    }
}

/// A plate scan with the plate turned by `turn` (the rail then meets it `turn` earlier)
/// and centred at `c` in its own frame.
fn placement(turn: f64, c: Vector2<f64>, sim: &SimOptions, rng: &mut StdRng) -> Scan {
    let m = Mounting { alpha0: TRUTH.alpha0 - turn, ..TRUTH };
    simulate(&PLATE.at(c), &m, sim, rng).unwrap().scan
}

fn options(orders: &[i64]) -> Options {
    Options { angle_harmonics: HarmonicOrders::new(orders).unwrap(), ..Options::default() }
}

fn coefficient(cal: &Calibration, name: &str) -> (f64, f64) {
    let names = cal.covariance_names();
    let i = names.iter().position(|n| n == name).unwrap();
    (cal.angle.coefficients()[i - 5], cal.named_covariance[(i, i)].sqrt())
}

#[test]
fn two_placements_find_orders_one_two_and_four_noise_free() {
    let mut rng = StdRng::seed_from_u64(1);
    let sim = tracer(0.0);
    let a = placement(0.0, Vector2::new(0.0008, -0.0005), &sim, &mut rng);
    let b = placement(deg(22.5), Vector2::new(-0.0003, 0.0006), &sim, &mut rng);
    let cal = calibrate_placements(&[&a, &b], None, &PLATE, &options(&[1, 2, 4])).unwrap();
    println!("{}", cal.summary());
    assert!((cal.mounting.alpha0 - TRUTH.alpha0).abs() < 1e-9, "{}", cal.mounting.alpha0);
    assert!((cal.mounting.offset - TRUTH.offset).abs() < 1e-9);
    assert!((cal.mounting.delta_l - TRUTH.delta_l).abs() < 1e-9);
    for (name, want) in [
        ("angle_c1", deg(0.05)),
        ("angle_s1", deg(-0.01)),
        ("angle_c2", 0.0),
        ("angle_s2", deg(0.02)),
        ("angle_c4", 0.0),
    ] {
        let (got, _) = coefficient(&cal, name);
        assert!((got - want).abs() < 1e-9, "{name}: {got} against {want}");
    }
    assert_eq!(cal.placements.len(), 1);
    assert!((cal.placements[0].turn - deg(22.5)).abs() < 1e-9, "{}", cal.placements[0].turn);
    assert_eq!(cal.covariance_names().len(), 11);
    assert_eq!(cal.named_covariance.shape(), (11, 11));
    // The correction with the fitted angle puts every sample where it was touched.
    let corrector = Corrector::with_angle(cal.mounting, &cal.angle, 400);
    let truth = simulate(&PLATE.at(Vector2::new(0.0008, -0.0005)), &TRUTH, &sim, &mut rng).unwrap();
    let worst = truth
        .scan
        .samples()
        .iter()
        .zip(&truth.truth)
        .map(|(s, t)| (corrector.point(s.step, s.rho) - t).norm())
        .fold(0.0, f64::max);
    println!("noise-free, h = 1, 2, 4, two placements: worst corrected point {:.2e} m", worst);
    assert!(worst < 1e-9, "{worst}");
}

#[test]
fn one_placement_refuses_order_four_and_says_what_to_add() {
    let mut rng = StdRng::seed_from_u64(2);
    let a = placement(0.0, Vector2::new(0.0008, -0.0005), &tracer(5e-6), &mut rng);
    let e = calibrate_placements(&[&a], None, &PLATE, &options(&[1, 2, 4])).unwrap_err();
    assert!(matches!(e, CalibrationError::HarmonicInseparable { order: 4, placements: 1, .. }), "{e:?}");
    let text = e.to_string();
    println!("{text}");
    assert!(text.contains("22.5°") && text.contains("plate_scan_ids"), "{text}");
    // Orders 1 and 2 alone, one placement: accepted, the lack-of-fit test content.
    let cal = calibrate_placements(&[&a], None, &PLATE, &options(&[1, 2])).unwrap();
    let (c1, u) = coefficient(&cal, "angle_c1");
    assert!((c1 - deg(0.05)).abs() < 4.0 * u, "{c1} ± {u}");
}

/// σ = 5 µm, one placement, h = 1, 2: the fitted coefficients within 3 of their stated
/// standard uncertainties (99.7 % if the covariance is right), none refused.
#[test]
fn fitted_harmonics_sit_within_their_uncertainty() {
    let trials = 200;
    let (mut within, mut refused) = (0, 0);
    let want = [deg(0.05), deg(-0.01), 0.0, deg(0.02)];
    let names = ["angle_c1", "angle_s1", "angle_c2", "angle_s2"];
    let mut z2 = 0.0;
    for seed in 0..trials {
        let mut rng = StdRng::seed_from_u64(100 + seed);
        let a = placement(0.0, Vector2::new(0.0008, -0.0005), &tracer(5e-6), &mut rng);
        match calibrate_placements(&[&a], None, &PLATE, &options(&[1, 2])) {
            Ok(cal) => {
                let z: Vec<f64> = names
                    .iter()
                    .zip(want)
                    .map(|(n, w)| {
                        let (got, u) = coefficient(&cal, n);
                        (got - w) / u
                    })
                    .collect();
                z2 += z.iter().map(|z| z * z).sum::<f64>() / 4.0;
                within += z.iter().filter(|z| z.abs() <= 3.0).count();
            }
            Err(e) => {
                refused += 1;
                println!("seed {seed}: {e}");
            }
        }
    }
    let accepted = (trials - refused) as usize;
    println!(
        "σ 5 µm, h = 1, 2, {trials} scans: {refused} refused; coefficients within 3 σ: {within} of {}; mean z² {:.2}",
        4 * accepted,
        z2 / accepted as f64
    );
    assert!(refused * 100 <= 2 * trials, "{refused} refused");
    assert!(within * 100 >= 99 * 4 * accepted, "{within} of {}", 4 * accepted);
}

#[test]
fn the_tip_models_fit_harmonics_with_a_ring_gauge_too() {
    use tracer_calib::engine::calibrate::Ring;
    use tracer_calib::engine::model::tip::RingSpec;
    use tracer_calib::engine::shape::Ellipse;
    let mut rng = StdRng::seed_from_u64(3);
    let sim = SimOptions { tip_radius: 0.0005, ..tracer(0.0) };
    let a = placement(0.0, Vector2::new(0.0008, -0.0005), &sim, &mut rng);
    let b = placement(deg(22.5), Vector2::new(-0.0003, 0.0006), &sim, &mut rng);
    let ring_sim = SimOptions { inside: true, ..sim };
    let ring = simulate(
        &Ellipse { center: Vector2::new(-0.0006, 0.0004), a: 0.02, b: 0.02, angle: 0.0 },
        &TRUTH,
        &ring_sim,
        &mut rng,
    )
    .unwrap()
    .scan;
    for model in [ModelKind::FullTip, ModelKind::FullScaleTip] {
        let opt = Options { model, ..options(&[1, 2, 4]) };
        let ring = Ring { scan: &ring, spec: RingSpec { diameter: 0.04 } };
        let cal = calibrate_placements(&[&a, &b], Some(ring), &PLATE, &opt).unwrap();
        println!("{}", cal.summary());
        assert!((cal.tip_radius - 0.0005).abs() < 1e-9, "{model}: tip {}", cal.tip_radius);
        let (c1, _) = coefficient(&cal, "angle_c1");
        assert!((c1 - deg(0.05)).abs() < 1e-9, "{model}: {c1}");
        assert!((cal.mounting.delta_l - TRUTH.delta_l).abs() < 1e-9);
    }
}
