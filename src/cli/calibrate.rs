//! `tracer_calib calibrate`: fit the mounting errors to a recorded plate scan.

use std::path::{Path, PathBuf};

use super::exit;
use crate::cell::{error_code, intake, response_for};
use crate::engine::calibrate::{Options, Ring, calibrate_placements};
use crate::engine::model::ModelKind;
use crate::engine::scan::Scan;
use crate::interfaces::{CalibrateResponse, RawScan};
use crate::io::bag::Bag;
use crate::io::csv;
use crate::params::{Parameters, ParamsFile, file as params_file};

/// Fit alpha0, d and dL to a scan of the calibration plate (and the stylus tip's radius
/// to it and a ring-gauge scan, with --model full_tip or full_scale_tip).
///
/// Examples:
///   tracer_calib calibrate --input plate.csv --plate-side 0.045 --corner-radius 0.003 --json
///   tracer_calib calibrate --input plate.csv --model full_tip --ring ring.csv --ring-diameter 0.04
///   tracer_calib calibrate --input cell.mcap --model full_tip --ring-diameter 0.04
///   tracer_calib calibrate --input a.csv --input b.csv --angle-harmonics 1,2,4 --json
///   tracer_calib calibrate --input cell.mcap --plate-scans 1,5 --angle-harmonics 1,2,4
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The scan: a CSV file with the header 'step,counts' (one revolution), or a
    /// rosbag2 bag (directory with metadata.yaml, .mcap or .db3). Given again, each is
    /// another placement of the plate (its own centre and turn), fitted together.
    #[arg(long, value_name = "PATH", required = true)]
    pub input: Vec<PathBuf>,
    /// Topic of the RawScan messages in a bag.
    #[arg(long, default_value = "/raw_scan")]
    pub topic: String,
    /// Which plate scan of a bag; 0 = the latest (with --angle-harmonics: every one).
    #[arg(long, default_value_t = 0)]
    pub scan_id: u32,
    /// The plate scans of a bag fitted together, each a placement with its own centre and
    /// turn (scan ids, comma-separated).
    #[arg(long, value_name = "ID,ID", value_delimiter = ',')]
    pub plate_scans: Vec<u32>,
    /// Orders of the turntable's angle error fitted with the model
    /// (calibration.angle_harmonics; comma-separated, e.g. 1,2 or 1,2,4). Orders 4 and 8
    /// need a second placement turned 22.5°.
    #[arg(long, value_name = "H,H", value_delimiter = ',')]
    pub angle_harmonics: Vec<i64>,
    /// A ROS 2 params file (plate, encoder scale, model), as the node persists it.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Node name whose section of --params applies (default: the file's only section,
    /// else /tracer_calibrator).
    #[arg(long, value_name = "FQN")]
    pub node: Option<String>,
    /// Fitting model: 'full' (every sample, the default), 'paper' (the seed paper's
    /// reduced model), 'full_scale' (full, and the encoder scale), 'full_tip' (full, and
    /// the stylus tip's radius from a ring-gauge scan) or 'full_scale_tip' (both).
    #[arg(long, value_parser = model_parser())]
    pub model: Option<ModelKind>,
    /// The ring-gauge scan of the tip models: a CSV file as --input, or a bag (its
    /// latest ring-gauge scan, or --ring-scan-id). Default: the --input bag.
    #[arg(long, value_name = "PATH")]
    pub ring: Option<PathBuf>,
    /// Which ring-gauge scan of the --ring bag; 0 = the latest.
    #[arg(long, default_value_t = 0)]
    pub ring_scan_id: u32,
    /// Certified inner diameter of the ring gauge, metres (ring.diameter).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub ring_diameter: Option<f64>,
    /// Included angle of the ring gauge's V-groove, radians (ring.groove_angle): the
    /// ball's centre sits tip / sin(angle/2) from the groove's bottom, whose diameter
    /// --ring-diameter gives; π = a plain bore.
    #[arg(long, value_name = "RAD", allow_hyphen_values = true)]
    pub ring_groove_angle: Option<f64>,
    /// Standard uncertainty of the plate's side from its certificate, metres
    /// (plate.side_uncertainty): a type B part of the covariance.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub plate_side_uncertainty: Option<f64>,
    /// Standard uncertainty of the ring gauge's diameter from its certificate, metres
    /// (ring.diameter_uncertainty).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub ring_diameter_uncertainty: Option<f64>,
    /// The stylus tip's radius, metres (stylus.tip_radius): known, for the models that do
    /// not fit it.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub tip_radius: Option<f64>,
    /// Standard uncertainty of the plate's corner radius from its certificate, metres
    /// (plate.corner_radius_uncertainty).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub corner_radius_uncertainty: Option<f64>,
    /// Standard uncertainty of the known tip radius, metres (stylus.tip_radius_uncertainty;
    /// for the models that do not fit it).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub tip_radius_uncertainty: Option<f64>,
    /// Standard uncertainty of the plate's seating angle against the frame holder's datum,
    /// radians (plate.seating_uncertainty).
    #[arg(long, value_name = "RAD", allow_hyphen_values = true)]
    pub seating_uncertainty: Option<f64>,
    /// Significance level of the harmonic lack-of-fit test of the plate's residuals
    /// (calibration.lack_of_fit_alpha, default 0.001): a fit whose residuals show structure
    /// at this level fails, naming the harmonics; 0 = no test.
    #[arg(long, value_name = "ALPHA")]
    pub lack_of_fit_alpha: Option<f64>,
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

/// `--model`'s parser: one of [`ModelKind::ALL`] by name, the names listed in `--help`
/// and in the error. (The engine's crate knows no clap; the names are its `as_str`.)
fn model_parser() -> impl clap::builder::TypedValueParser<Value = ModelKind> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(ModelKind::ALL.map(ModelKind::as_str))
        .map(|name| name.parse::<ModelKind>().expect("a name of ModelKind::ALL parses"))
}

/// The Calibrate response (docs/CONTRACT.md): its fields, in its order, are the JSON output.
pub type Response = CalibrateResponse;

fn failure(error_code: u16, message: impl Into<String>) -> Response {
    Response { success: false, message: message.into(), error_code, ..Response::default() }
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
    set("ring.diameter", args.ring_diameter)?;
    set("ring.groove_angle", args.ring_groove_angle)?;
    set("stylus.tip_radius", args.tip_radius)?;
    set("plate.side_uncertainty", args.plate_side_uncertainty)?;
    set("ring.diameter_uncertainty", args.ring_diameter_uncertainty)?;
    set("plate.corner_radius_uncertainty", args.corner_radius_uncertainty)?;
    set("stylus.tip_radius_uncertainty", args.tip_radius_uncertainty)?;
    set("plate.seating_uncertainty", args.seating_uncertainty)?;
    set("calibration.lack_of_fit_alpha", args.lack_of_fit_alpha)?;
    if let Some(m) = args.model {
        p.model = m;
    }
    if !args.angle_harmonics.is_empty() {
        // What to fit; the coefficients a --params file holds are not used here.
        p.angle_harmonics = crate::engine::angle::HarmonicOrders::new(&args.angle_harmonics)
            .map_err(|e| format!("--angle-harmonics: {e}"))?;
        p.angle_coefficients.clear();
    }
    Ok(p)
}

fn flag(name: &str) -> &'static str {
    match name {
        "plate.side" => "plate-side",
        "plate.corner_radius" => "corner-radius",
        "ring.diameter" => "ring-diameter",
        "ring.groove_angle" => "ring-groove-angle",
        "stylus.tip_radius" => "tip-radius",
        "plate.side_uncertainty" => "plate-side-uncertainty",
        "calibration.lack_of_fit_alpha" => "lack-of-fit-alpha",
        "ring.diameter_uncertainty" => "ring-diameter-uncertainty",
        "plate.corner_radius_uncertainty" => "corner-radius-uncertainty",
        "stylus.tip_radius_uncertainty" => "tip-radius-uncertainty",
        "plate.seating_uncertainty" => "seating-uncertainty",
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

/// Read the plate scans named by the arguments, each a placement: every CSV input; of a
/// bag, those of --plate-scans, else --scan-id's (0: the latest; with angle harmonics and
/// no --scan-id, every plate scan of the bag).
pub fn load_scans(args: &Args, p: &Parameters) -> Result<Vec<Scan>, String> {
    let plate = RawScan::TARGET_CALIBRATION_PLATE;
    let mut scans = Vec::new();
    for path in &args.input {
        if !is_bag(path) {
            scans.push(read_scan(path, args, 0, plate, p)?);
            continue;
        }
        let ids = if !args.plate_scans.is_empty() {
            args.plate_scans.clone()
        } else if args.scan_id == 0 && !p.angle_harmonics.is_empty() {
            plate_scan_ids(path, &args.topic)?
        } else {
            vec![args.scan_id]
        };
        for id in ids {
            scans.push(read_scan(path, args, id, plate, p)?);
        }
    }
    Ok(scans)
}

/// The ids of every plate scan on `topic` of a bag, in the order recorded (each once).
fn plate_scan_ids(path: &Path, topic: &str) -> Result<Vec<u32>, String> {
    let bag = Bag::open(path).map_err(|e| e.to_string())?;
    let mut ids: Vec<u32> = Vec::new();
    for (_, m) in bag.read::<RawScan>(topic).map_err(|e| e.to_string())? {
        if m.target == RawScan::TARGET_CALIBRATION_PLATE && !ids.contains(&m.scan_id) {
            ids.push(m.scan_id);
        }
    }
    if ids.is_empty() {
        return Err(format!("{}: no calibration-plate scan on {topic}", path.display()));
    }
    Ok(ids)
}

/// Read the ring-gauge scan a tip model needs (`--ring`, else the `--input` bag), or
/// `None` for the other models.
pub fn load_ring(args: &Args, p: &Parameters) -> Result<Option<Scan>, String> {
    if !p.model.fits_tip() {
        return Ok(None);
    }
    if p.ring().is_none() {
        return Err(format!(
            "model {} needs the ring gauge's diameter: --ring-diameter M (or ring.diameter in --params)",
            p.model
        ));
    }
    let path = match (&args.ring, args.input.iter().find(|p| is_bag(p))) {
        (Some(path), _) => path,
        (None, Some(bag)) => bag,
        (None, None) => {
            return Err(format!("model {} needs a ring-gauge scan: --ring PATH (a CSV file or a bag)", p.model));
        }
    };
    read_scan(path, args, args.ring_scan_id, RawScan::TARGET_RING_GAUGE, p).map(Some)
}

/// The scan of `target` at `path`: a CSV file's revolution, or the bag's scan
/// `scan_id` (0 = its latest of that target).
fn read_scan(path: &Path, args: &Args, scan_id: u32, target: u8, p: &Parameters) -> Result<Scan, String> {
    let scan = if is_bag(path) {
        let msg = scan_from_bag(path, &args.topic, scan_id, target)?;
        intake::to_scan(&msg, p.meters_per_count)
            .map_err(|e| format!("{}: scan {} on {}: {e}", path.display(), msg.scan_id, args.topic))?
    } else {
        let rev = csv::read(path).map_err(|e| e.to_string())?;
        Scan::from_counts(args.steps_per_rev, &rev.step, &rev.counts, p.meters_per_count)
            .map_err(|e| format!("{}: {e}", path.display()))?
    };
    let need = Options::default().min_samples;
    if scan.len() < need {
        return Err(format!(
            "{}: too few samples: {} (a {} scan needs at least {need})",
            path.display(),
            scan.len(),
            if target == RawScan::TARGET_RING_GAUGE { "ring-gauge" } else { "plate" }
        ));
    }
    Ok(scan)
}

fn target_name(target: u8) -> &'static str {
    if target == RawScan::TARGET_RING_GAUGE { "ring-gauge" } else { "calibration-plate" }
}

/// Is `path` a rosbag2 bag (a directory, `.mcap` or `.db3`) rather than a CSV file?
pub fn is_bag(path: &Path) -> bool {
    path.is_dir() || matches!(path.extension().and_then(|e| e.to_str()), Some("mcap" | "db3"))
}

/// The calibration-plate scan `scan_id` (0 = the latest plate scan) on `topic` of a bag.
pub fn plate_scan_from_bag(path: &Path, topic: &str, scan_id: u32) -> Result<RawScan, String> {
    scan_from_bag(path, topic, scan_id, RawScan::TARGET_CALIBRATION_PLATE)
}

/// The scan `scan_id` of `target` (0 = the latest of that target) on `topic` of a bag.
pub fn scan_from_bag(path: &Path, topic: &str, scan_id: u32, target: u8) -> Result<RawScan, String> {
    let bag = Bag::open(path).map_err(|e| e.to_string())?;
    let scans = bag.read::<RawScan>(topic).map_err(|e| e.to_string())?;
    let shown = path.display();
    let what = target_name(target);
    if scan_id == 0 {
        let mut of_target = scans.into_iter().filter(|(_, m)| m.target == target);
        of_target
            .next_back()
            .map(|(_, m)| m)
            .ok_or_else(|| format!("{shown}: no {what} scan (target {target}) on {topic}"))
    } else {
        let (_, msg) = scans
            .into_iter()
            .rev()
            .find(|(_, m)| m.scan_id == scan_id)
            .ok_or_else(|| format!("{shown}: no scan with scan_id {scan_id} on {topic}"))?;
        if msg.target != target {
            return Err(format!(
                "{shown}: scan {scan_id} on {topic} has target {}, not a {what} scan ({target})",
                msg.target
            ));
        }
        Ok(msg)
    }
}

pub fn run(args: &Args) -> i32 {
    let model = args.model.unwrap_or_default();
    let outcome = settings(args).and_then(|p| {
        let scans = load_scans(args, &p)?;
        let ring = load_ring(args, &p)?;
        Ok((p, scans, ring))
    });
    let (p, scans, ring) = match outcome {
        Ok(v) => v,
        Err(e) => return report(args, &failure(Response::ERROR_BAD_REQUEST, e), model, exit::BAD_INPUT),
    };
    let opts = p.calibration_options();
    let ring = ring.as_ref().zip(p.ring()).map(|(scan, spec)| Ring { scan, spec });
    let plates: Vec<&Scan> = scans.iter().collect();
    match calibrate_placements(&plates, ring, &p.plate, &opts) {
        Ok(cal) => report(args, &response_for(&cal, cal.summary()), p.model, exit::OK),
        Err(e) => report(args, &failure(error_code(&e), format!("calibration failed: {e}")), p.model, exit::FIT_FAILED),
    }
}

/// The response as the `--json` object: the Calibrate response's fields in order,
/// `scale` and `scale_stddev` only for a model that fits the scale, `tip_radius` and
/// `tip_radius_stddev` only for one that fits the tip radius, `covariance` and
/// `covariance_names` always, `angle_harmonics` and `angle_coefficients` only when
/// harmonics were fitted (docs/CONTRACT.md).
fn json_of(r: &Response, model: ModelKind) -> String {
    let mut v = serde_json::to_value(r).expect("a response serialises");
    if let Some(o) = v.as_object_mut() {
        if r.angle_harmonics.is_empty() {
            o.shift_remove("angle_harmonics");
            o.shift_remove("angle_coefficients");
        }
        if !model.fits_scale() {
            o.shift_remove("scale");
            o.shift_remove("scale_stddev");
        }
        if !model.fits_tip() {
            o.shift_remove("tip_radius");
            o.shift_remove("tip_radius_stddev");
        }
    }
    v.to_string()
}

fn report(args: &Args, r: &Response, model: ModelKind, status: i32) -> i32 {
    if args.json {
        println!("{}", json_of(r, model));
    }
    if status == exit::OK {
        if !args.json {
            println!("{}", r.message);
            println!(
                "alpha0 = {:.9} rad, offset = {:.9} m, delta_l = {:.9} m, stddev = [{:.3e}, {:.3e}, {:.3e}], scale = {:.7} ± {:.1e}",
                r.alpha0, r.offset, r.delta_l, r.stddev[0], r.stddev[1], r.stddev[2], r.scale, r.scale_stddev
            );
            if model.fits_tip() {
                println!("tip_radius = {:.9} m ± {:.1e}", r.tip_radius, r.tip_radius_stddev);
            }
        }
    } else {
        eprintln!("tracer_calib calibrate: {}", r.message);
    }
    status
}
