//! `tracer_calib demo`: a tracer with realistic mounting errors, simulated end to end:
//! trace the calibration plate, calibrate, then trace lens and frame shapes and show
//! how far their contours are off before and after correction.

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;

use super::exit;
use crate::engine::calibrate::{Options, calibrate};
use crate::engine::correct::{correct, default_max_gap, resample_radii};
use crate::engine::geometry::Mounting;
use crate::engine::model::{ModelKind, PlateSpec};
use crate::engine::shape::{Ellipse, RoundedRect, Shape};
use crate::engine::simulate::{SimOptions, simulate};

/// Simulate a miscalibrated tracer, calibrate it on the plate, correct lens scans.
///
/// Example:
///   tracer_calib demo --seed 7
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// Random seed of the simulated noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Encoder noise, metres.
    #[arg(long, default_value_t = 5e-6)]
    pub noise: f64,
}

pub fn run(args: &Args) -> i32 {
    match demo(args) {
        Ok(()) => exit::OK,
        Err(e) => {
            eprintln!("tracer_calib demo: {e}");
            exit::FIT_FAILED
        }
    }
}

fn demo(args: &Args) -> Result<(), String> {
    let mut rng = StdRng::seed_from_u64(args.seed);
    let truth = Mounting { alpha0: 1.7f64.to_radians(), offset: 4.2e-3, delta_l: 1.3e-3 };
    let plate = PlateSpec::default();
    let sim = SimOptions { noise: args.noise, quantum: 1e-6, start_step: 57, spikes: 2, ..SimOptions::default() };
    println!("A tracer with mounting errors alpha0 = 1.7°, d = 4.2 mm, dL = 1.3 mm,");
    println!(
        "400 steps a turn, encoder noise {:.3} mm, 1 µm counts, 2 dust spikes of 0.5 mm on the plate scan.",
        args.noise * 1e3
    );
    println!();
    let plate_scan =
        simulate(&plate.at(Vector2::new(0.6e-3, -0.4e-3)), &truth, &sim, &mut rng).map_err(|e| e.to_string())?;
    println!("{:<7} {:>16} {:>16} {:>16}", "", "alpha0 [deg]", "d [mm]", "dL [mm]");
    println!(
        "{:<7} {:>16.4} {:>16.4} {:>16.4}",
        "truth",
        truth.alpha0.to_degrees(),
        truth.offset * 1e3,
        truth.delta_l * 1e3
    );
    let mut fitted = None;
    for model in [ModelKind::Full, ModelKind::Paper] {
        let cal =
            calibrate(&plate_scan.scan, &plate, &Options { model, ..Options::default() }).map_err(|e| e.to_string())?;
        let m = cal.mounting;
        println!(
            "{:<7} {:>8.4} ± {:<6.4} {:>8.4} ± {:<6.4} {:>8.4} ± {:<6.4}  ({} samples, {} rejected, rms {:.4} mm, {} iterations)",
            model.as_str(),
            m.alpha0.to_degrees(),
            cal.stddev[0].to_degrees(),
            m.offset * 1e3,
            cal.stddev[1] * 1e3,
            m.delta_l * 1e3,
            cal.stddev[2] * 1e3,
            cal.samples_used,
            cal.samples_rejected,
            cal.rms_residual * 1e3,
            cal.iterations
        );
        if model == ModelKind::Full {
            fitted = Some(m);
        }
    }
    let fitted = fitted.expect("the full model ran");
    println!();
    println!("Contours traced by the same tracer, RMS distance to where the probe really was:");
    println!("{:<34} {:>14} {:>14} {:>16}", "shape", "raw [mm]", "corrected [mm]", "radii max [mm]");
    let lens_sim = SimOptions { noise: args.noise, quantum: 1e-6, ..SimOptions::default() };
    let ellipse = Ellipse { center: Vector2::new(0.5e-3, -0.3e-3), a: 25e-3, b: 15e-3, angle: 0.1 };
    let frame = RoundedRect { center: Vector2::new(-0.4e-3, 0.2e-3), half_w: 26e-3, half_h: 16e-3, radius: 8e-3 };
    show("lens: ellipse 50 x 30 mm", &ellipse, &truth, &fitted, &lens_sim, &mut rng)?;
    show("frame: rounded rectangle 52 x 32 mm", &frame, &truth, &fitted, &lens_sim, &mut rng)?;
    println!();
    println!("(radii max: largest error of the 400 equal-angle radii published in Contour.radii)");
    Ok(())
}

fn show(
    name: &str,
    shape: &impl Shape,
    truth: &Mounting,
    fitted: &Mounting,
    opt: &SimOptions,
    rng: &mut StdRng,
) -> Result<(), String> {
    let sim = simulate(shape, truth, opt, rng).map_err(|e| e.to_string())?;
    let rms = |m: &Mounting| {
        let pts = correct(&sim.scan, m);
        (pts.iter().zip(&sim.truth).map(|(p, t)| (p - t).norm_squared()).sum::<f64>() / pts.len() as f64).sqrt()
    };
    let pts = correct(&sim.scan, fitted);
    let radii = resample_radii(&pts, 400, default_max_gap(400)).ok_or("the contour does not go all the way round")?;
    let radii_err = radii
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let phi = std::f64::consts::TAU * k as f64 / radii.len() as f64;
            let u = Vector2::new(phi.cos(), phi.sin());
            shape.exit(Vector2::zeros(), u).map_or(f64::INFINITY, |h| (h.t - r).abs())
        })
        .fold(0.0, f64::max);
    println!(
        "{:<34} {:>14.4} {:>14.4} {:>16.4}",
        name,
        rms(&Mounting::IDEAL) * 1e3,
        rms(fitted) * 1e3,
        radii_err * 1e3
    );
    Ok(())
}
