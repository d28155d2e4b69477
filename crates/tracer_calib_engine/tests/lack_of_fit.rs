//! The harmonic lack-of-fit test on simulated plate scans: a tracer whose turntable angle
//! is off once or twice a turn is refused, naming the harmonics, and a clean one is not
//! (issue: an uncertainty that holds on a real tracer, item 3). Figures printed.

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use tracer_calib_engine::calibrate::{CalibrationError, Options, calibrate};
use tracer_calib_engine::geometry::Mounting;
use tracer_calib_engine::model::{ModelKind, PlateSpec};
use tracer_calib_engine::simulate::{SimOptions, simulate};

const PLATE: PlateSpec = PlateSpec { side: 0.045, corner_radius: 0.003 };
const TRIALS: u64 = 200;

/// How many of `TRIALS` plate scans of a tracer with `opt`'s errors the `model` refuses
/// for structure, and the first refusal's message. (Refusals for other reasons are
/// printed: the scale check's uncertainty takes the noise as white, which correlated noise
/// is not, a later item of the same issue.)
fn refusals(model: ModelKind, opt: &SimOptions) -> (usize, Option<String>) {
    let truth = Mounting::new(2f64.to_radians(), 0.005, 0.002);
    let mut refused = 0;
    let mut first = None;
    let mut other = 0;
    for seed in 0..TRIALS {
        let mut rng = StdRng::seed_from_u64(1000 + seed);
        let c = Vector2::new(0.0008, -0.0005);
        let scan = simulate(&PLATE.at(c), &truth, opt, &mut rng).unwrap().scan;
        match calibrate(&scan, &PLATE, &Options { model, ..Options::default() }) {
            Err(e @ CalibrationError::Structure { .. }) => {
                refused += 1;
                first.get_or_insert(e.to_string());
            }
            Err(CalibrationError::ScaleOff { .. }) => other += 1,
            Err(e) => panic!("seed {seed}: {e}"),
            Ok(_) => {}
        }
    }
    if other > 0 {
        println!("  ({other} of {TRIALS} refused by the encoder-scale check)");
    }
    (refused, first)
}

fn tracer(noise: f64, lag1: f64, harmonics: [(u32, f64, f64); 3]) -> SimOptions {
    SimOptions { noise, quantum: 1e-6, noise_lag1: lag1, angle_harmonics: harmonics, ..SimOptions::default() }
}

const NONE: [(u32, f64, f64); 3] = [(0, 0.0, 0.0); 3];

#[test]
fn a_clean_tracer_passes_and_an_angle_error_is_refused_naming_it() {
    let deg = 1f64.to_radians();
    for model in [ModelKind::Full, ModelKind::FullScale] {
        for (noise, lag1) in [(5e-6, 0.0), (10e-6, 0.0), (5e-6, 0.5), (5e-6, 0.8)] {
            let (n, first) = refusals(model, &tracer(noise, lag1, NONE));
            println!("{model}: clean, σ {:.0} µm, lag-1 {lag1}: {n} of {TRIALS} refused", noise * 1e6);
            assert!(n * 100 <= 2 * TRIALS as usize, "{model}, σ {noise}, lag-1 {lag1}: {n} refused: {first:?}");
        }
        let once = [(1, 0.05 * deg, 0.0), (0, 0.0, 0.0), (0, 0.0, 0.0)];
        let twice = [(2, 0.0, 0.02 * deg), (0, 0.0, 0.0), (0, 0.0, 0.0)];
        for (what, harmonics, noise) in
            [("0.05° once", once, 5e-6), ("0.05° once", once, 10e-6), ("0.02° twice", twice, 5e-6)]
        {
            let (n, first) = refusals(model, &tracer(noise, 0.0, harmonics));
            println!(
                "{model}: {what} a turn, σ {:.0} µm: {n} of {TRIALS} refused; {}",
                noise * 1e6,
                first.clone().unwrap_or_default()
            );
            assert!(n * 100 >= 95 * TRIALS as usize, "{model}: {what}: only {n} refused");
            let first = first.unwrap();
            let named =
                if what.contains("once") { "turntable's angle off once a turn" } else { "angle off twice a turn" };
            assert!(first.contains(named), "{first}");
        }
    }
}
