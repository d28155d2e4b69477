//! Monte-Carlo accuracy of the calibration against the Cramér-Rao bound.
//!
//! ```text
//! cargo run --release --example accuracy -- [TRIALS]      (default 2000)
//! ```
//!
//! Truth as in `notes/model.md`: alpha0 = 2°, d = 5 mm, dL = 2 mm, plate 45 mm with
//! 3 mm corners centred at (0.8, -0.5) mm, 400 steps. For encoder noise σ = 0.1, 0.01
//! and 0.001 mm it prints the RMS error of alpha0, d, dL for the full and the paper
//! model next to the Cramér-Rao bound `σ² (JᵀJ)⁻¹` of the full model at the truth (the
//! same Jacobian the fit uses), the mean reported standard uncertainty, and the RMS
//! error of a 50×30 mm ellipse corrected with each fit (noise-free ellipse scan, so
//! the figure is the calibration's own error).

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use tracer_calib::engine::calibrate::{Options, calibrate};
use tracer_calib::engine::correct::correct;
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::engine::lm::normal_equations;
use tracer_calib::engine::model::full::{self, FullModel, TableSample};
use tracer_calib::engine::model::{ModelKind, PlateSpec};
use tracer_calib::engine::shape::Ellipse;
use tracer_calib::engine::simulate::{SimOptions, simulate};

#[derive(Default)]
struct Tally {
    sq: [f64; 3],
    reported: [f64; 3],
    ellipse_sq: f64,
    n: usize,
    failures: usize,
}

fn main() {
    let trials: usize = std::env::args().nth(1).map_or(2000, |s| s.parse().expect("TRIALS must be a whole number"));
    let plate = PlateSpec { side: 0.045, corner_radius: 0.003 };
    let truth = Mounting { alpha0: 2f64.to_radians(), offset: 0.005, delta_l: 0.002 };
    let center = Vector2::new(0.0008, -0.0005);
    let lens = Ellipse { center: Vector2::zeros(), a: 0.025, b: 0.015, angle: 0.0 };
    let mut rng = StdRng::seed_from_u64(2026);
    let ellipse = simulate(&lens, &truth, &SimOptions::default(), &mut rng).unwrap();

    // Cramér-Rao bound per unit σ: sqrt(diag((JᵀJ)⁻¹)) at the truth.
    let table: Vec<TableSample> = (0..400).map(|k| TableSample::new(k, 400, 0.0)).collect();
    let x_true = full::params(&truth, center);
    let model = FullModel::new(&plate, table);
    let rho = model.predict(&x_true).unwrap();
    let model =
        FullModel::new(&plate, model.samples().iter().zip(rho).map(|(s, rho)| TableSample { rho, ..*s }).collect());
    let jtj_inv = normal_equations(&model, &x_true).unwrap().jtj.try_inverse().unwrap();
    let crlb_unit = [0, 1, 2].map(|i| jtj_inv[(i, i)].sqrt());

    println!(
        "Monte-Carlo accuracy, {trials} trials per row; truth alpha0 = 2°, d = 5 mm, dL = 2 mm, c = (0.8, -0.5) mm"
    );
    println!("errors are RMS over the trials: alpha0 in degrees, d, dL and the corrected 50x30 mm ellipse in mm");
    println!();
    println!(
        "{:>9}  {:<6} {:>10} {:>10} {:>10} {:>12} {:>8}   {:>22}",
        "noise", "model", "alpha0", "d", "dL", "ellipse", "failed", "RMS / CRLB (a0, d, dL)"
    );
    for sigma in [100e-6, 10e-6, 1e-6] {
        let crlb = crlb_unit.map(|c| c * sigma);
        for kind in [ModelKind::Full, ModelKind::Paper] {
            let opts = Options { model: kind, ..Options::default() };
            let mut t = Tally::default();
            let mut rng = StdRng::seed_from_u64(7 + (sigma * 1e9) as u64);
            for _ in 0..trials {
                let sim = simulate(
                    &plate.at(center),
                    &truth,
                    &SimOptions { noise: sigma, ..SimOptions::default() },
                    &mut rng,
                )
                .unwrap();
                match calibrate(&sim.scan, &plate, &opts) {
                    Ok(cal) => {
                        let m = cal.mounting;
                        let err = [m.alpha0 - truth.alpha0, m.offset - truth.offset, m.delta_l - truth.delta_l];
                        for (i, e) in err.iter().enumerate() {
                            t.sq[i] += e * e;
                            t.reported[i] += cal.stddev[i];
                        }
                        let pts = correct(&ellipse.scan, &m);
                        t.ellipse_sq +=
                            pts.iter().zip(&ellipse.truth).map(|(p, q)| (p - q).norm_squared()).sum::<f64>()
                                / pts.len() as f64;
                        t.n += 1;
                    }
                    Err(_) => t.failures += 1,
                }
            }
            let n = t.n.max(1) as f64;
            let rms = t.sq.map(|s| (s / n).sqrt());
            println!(
                "{:>6.3} mm  {:<6} {:>10.5} {:>10.5} {:>10.5} {:>12.5} {:>8}   {:>6.2} {:>6.2} {:>6.2}",
                sigma * 1e3,
                kind.as_str(),
                rms[0].to_degrees(),
                rms[1] * 1e3,
                rms[2] * 1e3,
                (t.ellipse_sq / n).sqrt() * 1e3,
                t.failures,
                rms[0] / crlb[0],
                rms[1] / crlb[1],
                rms[2] / crlb[2]
            );
            println!(
                "{:>9}  {:<6} {:>10.5} {:>10.5} {:>10.5}   (mean reported standard uncertainty)",
                "",
                "",
                (t.reported[0] / n).to_degrees(),
                t.reported[1] / n * 1e3,
                t.reported[2] / n * 1e3
            );
        }
        println!(
            "{:>6.3} mm  {:<6} {:>10.5} {:>10.5} {:>10.5}",
            sigma * 1e3,
            "CRLB",
            crlb[0].to_degrees(),
            crlb[1] * 1e3,
            crlb[2] * 1e3
        );
        println!();
    }
}
