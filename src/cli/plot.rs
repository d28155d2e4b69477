//! `tracer_calib plot`: a picture of a plate fit (raw vs corrected contour, residuals).

use std::path::{Path, PathBuf};

use nalgebra::Vector2;

use super::calibrate::{Args as CalibrateArgs, load_scans, settings};
use super::exit;
use crate::engine::calibrate::{Calibration, calibrate_placements};
use crate::engine::correct::{Corrector, correct};
use crate::engine::geometry::{Mounting, step_angle};
use crate::engine::model::PlateSpec;
use crate::engine::scan::Scan;
use crate::engine::shape::Shape;
use crate::io::plot::{CalibrationReport, ContourPlot, Outline, ResidualPlot, ResidualSample, calibration_report_svg};

/// Fit a plate scan and draw the fit: raw vs corrected contour over the fitted plate,
/// and every sample's residual (outliers marked).
///
/// Example:
///   tracer_calib plot --input plate.csv --out plate_fit.svg
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
// Its own argument group id: the flattened `calibrate` arguments' struct is also named
// `Args`, and two groups of one id fail clap's check (in debug builds: a panic at start).
#[group(id = "PlotArgs")]
pub struct Args {
    #[command(flatten)]
    pub input: CalibrateArgs,
    /// The SVG file to write.
    #[arg(long, value_name = "FILE.svg")]
    pub out: PathBuf,
}

pub fn run(args: &Args) -> i32 {
    let loaded = settings(&args.input).and_then(|p| load_scans(&args.input, &p).map(|s| (p, s)));
    let (p, scans) = match loaded {
        Ok(v) => v,
        Err(e) => {
            eprintln!("tracer_calib plot: {e}");
            return exit::BAD_INPUT;
        }
    };
    // The first placement is drawn; the others are fitted with it.
    let scan = &scans[0];
    let plates: Vec<&Scan> = scans.iter().collect();
    let cal = match calibrate_placements(&plates, None, &p.plate, &p.calibration_options()) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("tracer_calib plot: calibration failed: {e}");
            return exit::FIT_FAILED;
        }
    };
    match write_calibration_plot(&args.out, scan, &p.plate, &cal) {
        Ok(()) => {
            println!("{}", cal.summary());
            println!("wrote {}", args.out.display());
            exit::OK
        }
        Err(e) => {
            eprintln!("tracer_calib plot: {e}");
            exit::BAD_INPUT
        }
    }
}

/// The fitted plate's outline, as the rays from its centre see it.
fn plate_outline(plate: &PlateSpec, center: Vector2<f64>) -> Vec<Vector2<f64>> {
    let shape = plate.at(center);
    (0..720)
        .filter_map(|k| {
            let phi = std::f64::consts::TAU * k as f64 / 720.0;
            let u = Vector2::new(phi.cos(), phi.sin());
            shape.exit(center, u).map(|h| center + u * h.t)
        })
        .collect()
}

/// Write the SVG picture of a calibration of `scan`.
pub fn write_calibration_plot(path: &Path, scan: &Scan, plate: &PlateSpec, cal: &Calibration) -> Result<(), String> {
    let raw = correct(scan, &Mounting::IDEAL);
    // The surface the tip touched (engine::stylus), which is the plate's.
    let mut corrected = Corrector::with_angle(cal.mounting, &cal.angle, scan.steps_per_rev()).correct(scan);
    crate::engine::stylus::touched_surface(&mut corrected, cal.tip_radius, crate::engine::Traced::Outside, true);
    let outline = plate_outline(plate, cal.plate_center);
    let residuals: Vec<ResidualSample> = scan
        .samples()
        .iter()
        .zip(&cal.residuals)
        .map(|(s, &(residual, used))| ResidualSample {
            angle: cal.mounting.alpha0 + step_angle(s.step, scan.steps_per_rev()),
            residual,
            used,
        })
        .collect();
    let summary = format!(
        "{}\nalpha0 = {:.9} rad, offset = {:.9} m, delta_l = {:.9} m; plate centre ({:.4}, {:.4}) mm",
        cal.summary(),
        cal.mounting.alpha0,
        cal.mounting.offset,
        cal.mounting.delta_l,
        cal.plate_center.x * 1e3,
        cal.plate_center.y * 1e3
    );
    let svg = calibration_report_svg(&CalibrationReport {
        title: "Calibration plate fit",
        contours: ContourPlot {
            title: "Plate contour: raw vs corrected",
            raw: &raw,
            corrected: &corrected,
            reference: Some(Outline { label: "fitted plate", points: &outline, closed: true }),
        },
        residuals: ResidualPlot { title: "Fit residuals", samples: &residuals },
        summary: &summary,
    });
    std::fs::write(path, svg).map_err(|e| format!("{}: cannot write: {e}", path.display()))
}
