//! `tracer_calib oma`: read VCA/OMA trace records back, and state each trace's sizes as the
//! standard defines its `CIRC`, `HBOX`, `VBOX` and `FED` records, beside the file's own.

use std::path::PathBuf;

use nalgebra::Vector2;

use super::exit;
use crate::engine::size;
use crate::io::oma::{self, OmaFile, Trace};

/// Read an OMA file's trace records and print them (one line a trace, or JSON), each
/// trace's circumference, box and FED computed from its points, and where the file states
/// them (`CIRC`, `HBOX`, `VBOX`, `FED`) a warning for any that differs beyond the record's
/// rounding.
///
/// Example:
///   tracer_calib oma --input lens.oma --json
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The OMA file.
    #[arg(long, value_name = "FILE")]
    pub input: PathBuf,
    /// Print JSON: job; per trace eye, type, n, the radii, its sizes and the file's records
    /// of them (metres); warnings.
    #[arg(long)]
    pub json: bool,
}

/// The size records of the standard, in the order of `[C, A, B, FED]`.
const RECORDS: [&str; 4] = ["CIRC", "HBOX", "VBOX", "FED"];
/// The JSON names of the figures, as `Contour` names them.
const NAMES: [&str; 4] = ["circumference", "box_width", "box_height", "effective_diameter"];
/// A file's radius unit, metres (1/100 mm): the trace's own rounding.
const UNIT: f64 = 1e-5;

/// A trace's sizes and the file's records of them.
struct Sized {
    /// `[C, A, B, FED]` and their U95 (the points' rounding), metres.
    figures: Option<([f64; 4], [f64; 4])>,
    /// The file's record of each, metres, if it has it.
    records: [Option<f64>; 4],
    warnings: Vec<String>,
}

/// The points of a trace, in the output frame.
fn points_of(t: &Trace) -> Vec<Vector2<f64>> {
    (0..t.n()).map(|i| Vector2::new(t.angle(i).cos(), t.angle(i).sin()) * t.radii[i]).collect()
}

/// Decimals of a number as written (`52.00` → 2).
fn decimals(text: &str) -> i32 {
    text.split_once('.').map_or(0, |(_, d)| d.chars().take_while(char::is_ascii_digit).count() as i32)
}

/// The sizes of trace `index` of `file`, and the file's own records compared with them: a
/// record differs when it is further from the computed figure than half a unit of its last
/// decimal plus the radii's own rounding (a box or a FED spans two radii of 1/100 mm each).
fn sized(file: &OmaFile, index: usize) -> Sized {
    let t = &file.traces[index];
    let name = format!("trace {} ({} eye)", index + 1, t.eye);
    let mut warnings = Vec::new();
    let figures = size::of_contour(&points_of(t), t.n(), UNIT).map(|r| (r.sizes.figures(), r.u95));
    if figures.is_none() {
        warnings.push(format!("{name}: its points do not go round the axis: no sizes"));
    }
    let mut records = [None; 4];
    for (k, label) in RECORDS.iter().enumerate() {
        let Some(text) = file.chiral(label, t.eye) else { continue };
        let Ok(mm) = text.parse::<f64>() else {
            warnings.push(format!("{name}: {label} '{text}' is not a number"));
            continue;
        };
        records[k] = Some(mm * 1e-3);
        if let Some((f, u95)) = figures {
            // Half a unit of the record, the two radii's half a unit each, the points' own U95.
            let tolerance = 0.5 * 10f64.powi(-decimals(text)) * 1e-3 + UNIT + u95[k];
            let apart = f[k] - mm * 1e-3;
            if apart.abs() > tolerance {
                warnings.push(format!(
                    "{name}: {label} {text} mm in the file, {:.3} mm from its points: {:+.3} mm apart, beyond the record's rounding ({:.3} mm)",
                    f[k] * 1e3,
                    apart * 1e3,
                    tolerance * 1e3
                ));
            }
        }
    }
    Sized { figures, records, warnings }
}

pub fn run(args: &Args) -> i32 {
    let file = match oma::read(&args.input) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("tracer_calib oma: {e}");
            return exit::BAD_INPUT;
        }
    };
    let sized: Vec<Sized> = (0..file.traces.len()).map(|i| sized(&file, i)).collect();
    let warnings: Vec<&String> = file.warnings.iter().chain(sized.iter().flat_map(|s| &s.warnings)).collect();
    if args.json {
        let traces: Vec<serde_json::Value> = file
            .traces
            .iter()
            .zip(&sized)
            .map(|(t, s)| {
                let mut row = serde_json::json!({
                    "eye": t.eye.code(), "type": t.trace_type.code(), "n": t.n(),
                    "equiangular": t.is_equiangular(), "radii": t.radii,
                });
                if let Some((f, u95)) = s.figures {
                    for (k, name) in NAMES.iter().enumerate() {
                        row[*name] = f[k].into();
                        row[format!("{name}_u95")] = u95[k].into();
                    }
                }
                let records: serde_json::Map<String, serde_json::Value> = NAMES
                    .iter()
                    .zip(s.records)
                    .filter_map(|(name, r)| r.map(|r| (name.to_string(), r.into())))
                    .collect();
                row["records"] = records.into();
                row
            })
            .collect();
        println!("{}", serde_json::json!({ "job": file.job, "traces": traces, "warnings": warnings }));
    } else {
        println!("{}: job {}", args.input.display(), file.job.as_deref().unwrap_or("-"));
        for (t, s) in file.traces.iter().zip(&sized) {
            let (lo, hi) = t.radii.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| (lo.min(*r), hi.max(*r)));
            print!(
                "  eye {} type {}: {} points{}, radius {:.2} to {:.2} mm",
                t.eye,
                t.trace_type,
                t.n(),
                if t.is_equiangular() { " equiangular" } else { "" },
                lo * 1e3,
                hi * 1e3
            );
            match s.figures {
                Some((f, _)) => println!(
                    "; C {:.2}, A {:.2}, B {:.2}, FED {:.2} mm",
                    f[0] * 1e3,
                    f[1] * 1e3,
                    f[2] * 1e3,
                    f[3] * 1e3
                ),
                None => println!(),
            }
        }
        for w in &warnings {
            eprintln!("tracer_calib oma: warning: {w}");
        }
    }
    exit::OK
}
