//! `tracer_calib calibrate`: fit the mounting errors to a recorded plate scan.

use std::path::{Path, PathBuf};

use super::exit;
use crate::cell::{intake, response_for};
use crate::engine::calibrate::{Options, calibrate};
use crate::engine::model::ModelKind;
use crate::engine::scan::Scan;
use crate::interfaces::{CalibrateResponse, RawScan};
use crate::io::bag::Bag;
use crate::io::csv;
use crate::params::{Parameters, ParamsFile, file as params_file};

/// Fit alpha0, d and dL to a scan of the calibration plate.
///
/// Example:
///   tracer_calib calibrate --input plate.csv --plate-side 0.045 --corner-radius 0.003 --json
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The scan: a CSV file with the header 'step,counts' (one revolution), or a
    /// rosbag2 bag (directory with metadata.yaml, .mcap or .db3).
    #[arg(long, value_name = "PATH")]
    pub input: PathBuf,
    /// Topic of the RawScan messages in a bag.
    #[arg(long, default_value = "/raw_scan")]
    pub topic: String,
    /// Which plate scan of a bag; 0 = the latest.
    #[arg(long, default_value_t = 0)]
    pub scan_id: u32,
    /// A ROS 2 params file (plate, encoder scale, model), as the node persists it.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Node name whose section of --params applies (default: the file's only section,
    /// else /tracer_calibrator).
    #[arg(long, value_name = "FQN")]
    pub node: Option<String>,
    /// Fitting model: 'full' (every sample, the default), 'paper' (the seed paper's
    /// reduced model) or 'full_scale' (full, and the encoder scale).
    #[arg(long)]
    pub model: Option<ModelKind>,
    /// Steps per revolution of a CSV scan.
    #[arg(long, default_value_t = 400)]
    pub steps_per_rev: u32,
    /// Side of the square calibration plate, metres.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub plate_side: Option<f64>,
    /// Corner radius of the plate, metres.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub corner_radius: Option<f64>,
    /// Encoder scale, metres per count.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub meters_per_count: Option<f64>,
    /// Print exactly one JSON object with the fields of the Calibrate response.
    #[arg(long)]
    pub json: bool,
}

impl clap::ValueEnum for ModelKind {
    fn value_variants<'a>() -> &'a [Self] {
        &ModelKind::ALL
    }
    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.as_str()))
    }
}

/// The Calibrate response (docs/CONTRACT.md): its fields, in its order, are the JSON output.
pub type Response = CalibrateResponse;

fn failure(message: impl Into<String>) -> Response {
    Response { success: false, message: message.into(), ..Response::default() }
}

/// Settings from defaults, then --params, then the explicit flags.
pub fn settings(args: &Args) -> Result<Parameters, String> {
    let mut p = Parameters::default();
    if let Some(path) = &args.params {
        let file = params_file::read(path).map_err(|e| e.to_string())?;
        let fqn = args.node.clone().unwrap_or_else(|| default_section(&file));
        p.apply_file(&file, &fqn, &path.display().to_string()).map_err(|e| e.to_string())?;
    }
    let mut set = |name: &str, v: Option<f64>| -> Result<(), String> {
        match v {
            Some(v) => p.set(name, &crate::params::ParamValue::Double(v)).map_err(|e| format!("--{}: {e}", flag(name))),
            None => Ok(()),
        }
    };
    set("plate.side", args.plate_side)?;
    set("plate.corner_radius", args.corner_radius)?;
    set("encoder.meters_per_count", args.meters_per_count)?;
    if let Some(m) = args.model {
        p.model = m;
    }
    Ok(p)
}

fn flag(name: &str) -> &'static str {
    match name {
        "plate.side" => "plate-side",
        "plate.corner_radius" => "corner-radius",
        _ => "meters-per-count",
    }
}

/// The only section's node name, else the default node's.
pub fn default_section(file: &ParamsFile) -> String {
    match file.sections.as_slice() {
        [only] if !only.node.contains('*') => format!("/{}", only.node.trim_start_matches('/')),
        _ => "/tracer_calibrator".to_string(),
    }
}

/// Read the plate scan named by the arguments.
pub fn load_scan(args: &Args, p: &Parameters) -> Result<Scan, String> {
    let path = &args.input;
    let scan = if is_bag(path) {
        let msg = plate_scan_from_bag(path, &args.topic, args.scan_id)?;
        intake::to_scan(&msg, p.meters_per_count)
            .map_err(|e| format!("{}: scan {} on {}: {e}", path.display(), msg.scan_id, args.topic))?
    } else {
        let rev = csv::read(path)?;
        Scan::from_counts(args.steps_per_rev, &rev.step, &rev.counts, p.meters_per_count)
            .map_err(|e| format!("{}: {e}", path.display()))?
    };
    let need = Options::default().min_samples;
    if scan.len() < need {
        return Err(format!(
            "{}: too few samples: {} (a plate scan needs at least {need})",
            path.display(),
            scan.len()
        ));
    }
    Ok(scan)
}

/// Is `path` a rosbag2 bag (a directory, `.mcap` or `.db3`) rather than a CSV file?
pub fn is_bag(path: &Path) -> bool {
    path.is_dir() || matches!(path.extension().and_then(|e| e.to_str()), Some("mcap" | "db3"))
}

/// The calibration-plate scan `scan_id` (0 = the latest plate scan) on `topic` of a bag.
pub fn plate_scan_from_bag(path: &Path, topic: &str, scan_id: u32) -> Result<RawScan, String> {
    let bag = Bag::open(path).map_err(|e| e.to_string())?;
    let scans = bag.read::<RawScan>(topic).map_err(|e| e.to_string())?;
    let shown = path.display();
    if scan_id == 0 {
        let mut plates = scans.into_iter().filter(|(_, m)| m.target == RawScan::TARGET_CALIBRATION_PLATE);
        plates.next_back().map(|(_, m)| m).ok_or_else(|| {
            format!("{shown}: no calibration-plate scan (target {}) on {topic}", RawScan::TARGET_CALIBRATION_PLATE)
        })
    } else {
        let (_, msg) = scans
            .into_iter()
            .rev()
            .find(|(_, m)| m.scan_id == scan_id)
            .ok_or_else(|| format!("{shown}: no scan with scan_id {scan_id} on {topic}"))?;
        if msg.target != RawScan::TARGET_CALIBRATION_PLATE {
            return Err(format!(
                "{shown}: scan {scan_id} on {topic} has target {}, not a calibration-plate scan ({})",
                msg.target,
                RawScan::TARGET_CALIBRATION_PLATE
            ));
        }
        Ok(msg)
    }
}

pub fn run(args: &Args) -> i32 {
    let outcome = settings(args).and_then(|p| load_scan(args, &p).map(|scan| (p, scan)));
    let (p, scan) = match outcome {
        Ok(v) => v,
        Err(e) => return report(args, &failure(e), args.model.is_some_and(ModelKind::fits_scale), exit::BAD_INPUT),
    };
    let opts = p.calibration_options();
    let with_scale = p.model.fits_scale();
    match calibrate(&scan, &p.plate, &opts) {
        Ok(cal) => report(args, &response_for(&cal, cal.summary()), with_scale, exit::OK),
        Err(e) => report(args, &failure(format!("calibration failed: {e}")), with_scale, exit::FIT_FAILED),
    }
}

/// The response as the `--json` object: the Calibrate response's fields in order,
/// `scale` and `scale_stddev` only for a model that fits the scale, `tip_radius` and
/// `tip_radius_stddev` only for one that fits the tip radius (none yet), `covariance`
/// always (docs/CONTRACT.md).
fn json_of(r: &Response, with_scale: bool) -> String {
    let mut v = serde_json::to_value(r).expect("a response serialises");
    if let Some(o) = v.as_object_mut() {
        if !with_scale {
            o.remove("scale");
            o.remove("scale_stddev");
        }
        o.remove("tip_radius");
        o.remove("tip_radius_stddev");
    }
    v.to_string()
}

fn report(args: &Args, r: &Response, with_scale: bool, status: i32) -> i32 {
    if args.json {
        println!("{}", json_of(r, with_scale));
    }
    if status == exit::OK {
        if !args.json {
            println!("{}", r.message);
            println!(
                "alpha0 = {:.9} rad, offset = {:.9} m, delta_l = {:.9} m, stddev = [{:.3e}, {:.3e}, {:.3e}], scale = {:.7} ± {:.1e}",
                r.alpha0, r.offset, r.delta_l, r.stddev[0], r.stddev[1], r.stddev[2], r.scale, r.scale_stddev
            );
        }
    } else {
        eprintln!("tracer_calib calibrate: {}", r.message);
    }
    status
}
