//! `tracer_calib history`: read a calibration history file (the node's `history_file`).

use std::path::PathBuf;

use super::exit;
use crate::io::plot::{HistoryPlot, HistoryPoint, history_svg};
use crate::params::Parameters;
use crate::records::{self, DRIFT_NAMES, Drift, History, Record};

/// Show a tracer's calibration history: one row a calibration (time, scan, model,
/// parameters ± standard uncertainty, RMS residual, how far it moved from the one
/// before in combined standard uncertainties σ). Lines torn by a crash are skipped with
/// a warning.
///
/// Example:
///   tracer_calib history --input /var/lib/cell1/tracer.history.jsonl --svg history.svg
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The history file (JSON Lines, one record a calibration).
    #[arg(long, value_name = "FILE")]
    pub input: PathBuf,
    /// Print one JSON array of the records (as in the file) instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Also draw alpha0, d and dL over time with their error bars (±2σ) into this SVG file.
    #[arg(long, value_name = "OUT.svg")]
    pub svg: Option<PathBuf>,
}

/// Moves beyond this many σ are marked (the node's default `calibration.drift_warn_sigma`).
fn drift_limit() -> f64 {
    Parameters::default().drift_warn_sigma
}

pub fn run(args: &Args) -> i32 {
    if !args.input.is_file() {
        let why = if args.input.exists() { "not a file" } else { "no such file" };
        eprintln!("tracer_calib history: {}: {why}", args.input.display());
        return exit::BAD_INPUT;
    }
    let history = match records::file::read(&args.input) {
        Ok(h) => h,
        Err(e) => {
            eprintln!("tracer_calib history: {e}");
            return exit::BAD_INPUT;
        }
    };
    for s in &history.skipped {
        eprintln!("tracer_calib history: warning: {s}");
    }
    // Only skipped lines, and not just a torn last one: not a history file.
    if history.records.is_empty() && history.skipped.iter().any(|s| !s.contains("torn last line")) {
        eprintln!(
            "tracer_calib history: {}: not a calibration history file (no line is a record)",
            args.input.display()
        );
        return exit::BAD_INPUT;
    }
    let drifts: Vec<Option<Drift>> =
        (0..history.records.len()).map(|i| records::record_drift(&history.records, i)).collect();
    if args.json {
        println!("{}", serde_json::to_string(&history.records).expect("records serialize"));
    } else {
        print!("{}", table(&args.input.display().to_string(), &history, &drifts));
    }
    if let Some(out) = &args.svg {
        let svg = picture(&args.input.display().to_string(), &history.records, &drifts);
        if let Err(e) = std::fs::write(out, svg) {
            eprintln!("tracer_calib history: {}: cannot write: {e}", out.display());
            return exit::BAD_INPUT;
        }
        if args.json {
            eprintln!("wrote {}", out.display());
        } else {
            println!("wrote {}", out.display());
        }
    }
    exit::OK
}

/// `value ± u` with `decimals`, or the value alone when `u` is unknown.
fn pm(value: f64, u: Option<f64>, decimals: usize) -> String {
    match u {
        Some(u) => format!("{value:.decimals$} ± {u:.decimals$}"),
        None => format!("{value:.decimals$} ± ?"),
    }
}

fn moved(d: Option<&Drift>) -> String {
    match d {
        None => "-".into(),
        Some(d) => {
            let (i, s) = d.worst();
            let mark = if d.exceeds(drift_limit()) { " !" } else { "" };
            format!("{s:.1}σ {}{mark}", DRIFT_NAMES[i])
        }
    }
}

/// The table: a header line, then one row a calibration.
fn table(path: &str, h: &History, drifts: &[Option<Drift>]) -> String {
    let mut out = format!("{path}: {} calibration(s)", h.records.len());
    if !h.skipped.is_empty() {
        out.push_str(&format!(", {} line(s) skipped", h.skipped.len()));
    }
    out.push('\n');
    if h.records.is_empty() {
        return out;
    }
    out.push_str(&format!(
        "{:<24}  {:>6}  {:<10}  {:>19}  {:>19}  {:>19}  {:>9}  {:>8}  {}\n",
        "time (UTC)", "scan", "model", "alpha0 [°]", "d [mm]", "dL [mm]", "scale", "RMS [µm]", "moved (largest)"
    ));
    for (r, d) in h.records.iter().zip(drifts) {
        let u = |i: usize| r.stddev.get(i).copied();
        out.push_str(&format!(
            "{:<24}  {:>6}  {:<10}  {:>19}  {:>19}  {:>19}  {:>9}  {:>8.2}  {}\n",
            r.time,
            r.scan_id,
            r.model,
            pm(r.alpha0.to_degrees(), u(0).map(f64::to_degrees), 5),
            pm(r.offset * 1e3, u(1).map(|s| s * 1e3), 5),
            pm(r.delta_l * 1e3, u(2).map(|s| s * 1e3), 5),
            match u(3) {
                Some(s) => pm(r.scale, Some(s), 7),
                None => format!("{:.7}", r.scale),
            },
            r.rms_residual * 1e6,
            moved(d.as_ref())
        ));
    }
    if drifts.iter().flatten().any(|d| d.exceeds(drift_limit())) {
        out.push_str(&format!(
            "! moved more than {} combined standard uncertainties from the calibration before: check the tracer\n",
            drift_limit()
        ));
    }
    out
}

/// The SVG picture of a history.
fn picture(path: &str, records: &[Record], drifts: &[Option<Drift>]) -> String {
    let points: Vec<HistoryPoint> = records
        .iter()
        .zip(drifts)
        .map(|(r, d)| HistoryPoint {
            time: r
                .applied_at()
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(f64::NAN, |t| t.as_secs_f64()),
            values: [r.alpha0, r.offset, r.delta_l],
            stddev: (r.stddev.len() >= 3).then(|| [r.stddev[0], r.stddev[1], r.stddev[2]]),
            flagged: d.map_or([false; 3], |d| d.sigmas.map(|s| s > drift_limit())),
        })
        .collect();
    let node = records.last().map(|r| r.node.as_str()).unwrap_or("");
    let title =
        if node.is_empty() { "Calibration history".to_string() } else { format!("Calibration history of {node}") };
    let mut summary = format!("{path}: {} calibration(s)", records.len());
    if let (Some(first), Some(last)) = (records.first(), records.last()) {
        summary.push_str(&format!(", {} to {}", first.time, last.time));
        let u = |i: usize| last.stddev.get(i).copied();
        summary.push_str(&format!(
            "\nlast (scan {}, {}): alpha0 = {}°, d = {} mm, dL = {} mm, scale {:.7}, RMS residual {:.2} µm",
            last.scan_id,
            last.model,
            pm(last.alpha0.to_degrees(), u(0).map(f64::to_degrees), 5),
            pm(last.offset * 1e3, u(1).map(|s| s * 1e3), 5),
            pm(last.delta_l * 1e3, u(2).map(|s| s * 1e3), 5),
            last.scale,
            last.rms_residual * 1e6
        ));
        if let Some((i, d)) = drifts
            .iter()
            .enumerate()
            .filter_map(|(i, d)| d.map(|d| (i, d)))
            .max_by(|a, b| a.1.worst().1.total_cmp(&b.1.worst().1))
        {
            summary.push_str(&format!(
                "\nlargest move: {:.1}σ ({}) on {} (scan {}): {}",
                d.worst().1,
                DRIFT_NAMES[d.worst().0],
                records[i].time,
                records[i].scan_id,
                d.describe()
            ));
        }
    }
    history_svg(&HistoryPlot {
        title: &title,
        points: &points,
        coverage: 2.0,
        flagged_label: &format!("moved more than {}σ from the one before", drift_limit()),
        summary: &summary,
    })
}
