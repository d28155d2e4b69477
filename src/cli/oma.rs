//! `tracer_calib oma`: read VCA/OMA trace records back.

use std::path::PathBuf;

use super::exit;
use crate::io::oma;

/// Read an OMA file's trace records and print them (one line a trace, or JSON).
///
/// Example:
///   tracer_calib oma --input lens.oma --json
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The OMA file.
    #[arg(long, value_name = "FILE")]
    pub input: PathBuf,
    /// Print JSON: job, and per trace eye, type, n and the radii in metres.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &Args) -> i32 {
    let file = match oma::read(&args.input) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("tracer_calib oma: {e}");
            return exit::BAD_INPUT;
        }
    };
    if args.json {
        let traces: Vec<serde_json::Value> = file
            .traces
            .iter()
            .map(|t| {
                serde_json::json!({
                    "eye": t.eye.code(), "type": t.trace_type.code(), "n": t.n(),
                    "equiangular": t.is_equiangular(), "radii": t.radii,
                })
            })
            .collect();
        println!("{}", serde_json::json!({ "job": file.job, "traces": traces }));
    } else {
        println!("{}: job {}", args.input.display(), file.job.as_deref().unwrap_or("-"));
        for t in &file.traces {
            let (lo, hi) = t.radii.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| (lo.min(*r), hi.max(*r)));
            println!(
                "  eye {} type {}: {} points{}, radius {:.2} to {:.2} mm",
                t.eye,
                t.trace_type,
                t.n(),
                if t.is_equiangular() { " equiangular" } else { "" },
                lo * 1e3,
                hi * 1e3
            );
        }
    }
    exit::OK
}
