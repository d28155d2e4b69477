//! `tracer_calib correct`: every raw scan of a bag corrected, as the node would.

use std::path::{Path, PathBuf};

use super::calibrate::default_section;
use super::exit;
use crate::cell::NodeState;
use crate::interfaces::{Contour, PolygonStamped, RawScan};
use crate::io::bag::{Bag, BagWriter};
use crate::io::oma::{self, Eye, OmaFile, Trace, TraceType};
use crate::params::{Parameters, file as params_file};

/// Correct every RawScan of a bag with a calibration, into a bag of Contour and
/// PolygonStamped messages (and optionally VCA/OMA trace files).
///
/// Example:
///   tracer_calib correct --input scans.mcap --params cell1.yaml --out corrected \
///       --oma lens.oma --eye R
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The bag: a directory with metadata.yaml, a .mcap or a .db3 file.
    #[arg(long, value_name = "BAG")]
    pub input: PathBuf,
    /// The params file with the calibration (as the node persists it).
    #[arg(long, value_name = "FILE")]
    pub params: PathBuf,
    /// Node name whose section of --params applies (default: the file's only section,
    /// else /tracer_calibrator); also the frame of the written contours' settings.
    #[arg(long, value_name = "FQN")]
    pub node: Option<String>,
    /// Topic of the RawScan messages.
    #[arg(long, default_value = "/raw_scan")]
    pub topic: String,
    /// The bag to write (a directory, or a file ending in .mcap); optional with --json.
    #[arg(long, value_name = "BAG", required_unless_present = "json")]
    pub out: Option<PathBuf>,
    /// Also write the corrected lens and frame traces as VCA/OMA trace records: one file,
    /// or FILE_<scan_id>.oma per scan when there are several.
    #[arg(long, value_name = "FILE")]
    pub oma: Option<PathBuf>,
    /// The eye the OMA traces are labelled with.
    #[arg(long, default_value = "R", value_parser = ["R", "L", "B"])]
    pub eye: String,
    /// Print one JSON object a line per corrected scan: scan_id, target, calibrated,
    /// circumference, box_width, box_height, effective_diameter, size_u95 (metres), and
    /// circumference_3d, circumference_3d_u95 (metres), frame_curve (dioptres).
    #[arg(long)]
    pub json: bool,
}

/// A corrected scan's line of `--json` (the Contour's fields, metres).
#[derive(serde::Serialize)]
struct SizeLine {
    scan_id: u32,
    target: u8,
    calibrated: bool,
    circumference: f64,
    box_width: f64,
    box_height: f64,
    effective_diameter: f64,
    size_u95: [f64; 4],
    circumference_3d: f64,
    circumference_3d_u95: f64,
    frame_curve: f64,
}

/// A lens or frame scan for the OMA export.
struct Traced {
    scan_id: u32,
    target: u8,
    radii: Vec<f64>,
    /// `[C, A, B, FED]`, if it has them.
    sizes: Option<[f64; 4]>,
    /// With a height channel: the heights at the radii's angles, the 3-D length and the
    /// frame curve.
    third: Option<(Vec<f64>, f64, f64)>,
}

pub fn run(args: &Args) -> i32 {
    match correct_bag(args) {
        Ok(summary) => {
            // With --json, stdout holds the JSON lines only.
            if args.json {
                eprintln!("{summary}");
            } else {
                println!("{summary}");
            }
            exit::OK
        }
        Err(e) => {
            eprintln!("tracer_calib correct: {e}");
            exit::BAD_INPUT
        }
    }
}

fn correct_bag(args: &Args) -> Result<String, String> {
    let file = params_file::read(&args.params).map_err(|e| e.to_string())?;
    let fqn = args.node.clone().unwrap_or_else(|| default_section(&file));
    let mut params = Parameters::default();
    params.apply_file(&file, &fqn, &args.params.display().to_string()).map_err(|e| e.to_string())?;
    let bag = Bag::open(&args.input).map_err(|e| e.to_string())?;
    let scans = bag.read::<RawScan>(&args.topic).map_err(|e| e.to_string())?;
    if !params.calibration_valid {
        eprintln!(
            "tracer_calib correct: warning: {} has no valid calibration for {fqn} (calibration.valid is false): contours are uncorrected",
            args.params.display()
        );
    }
    let mut state = NodeState::new(fqn, params);
    let mut writer = match &args.out {
        Some(out) => {
            let mut w = BagWriter::create(out).map_err(|e| e.to_string())?;
            w.add_topic::<Contour>("/contour").map_err(|e| e.to_string())?;
            w.add_topic::<PolygonStamped>("/contour_polygon").map_err(|e| e.to_string())?;
            Some(w)
        }
        None => None,
    };
    let mut traces = Vec::new();
    let (mut corrected, mut rejected) = (0, 0);
    for (t, msg) in &scans {
        match state.on_raw_scan(msg, true) {
            Ok(out) => {
                corrected += 1;
                let c = &out.contour;
                if msg.target == RawScan::TARGET_LENS || msg.target == RawScan::TARGET_FRAME {
                    let third = (!msg.height_counts.is_empty())
                        .then(|| heights_at_radii(&c.points, c.radii.len()))
                        .flatten()
                        .map(|z| (z, c.circumference_3d, c.frame_curve));
                    traces.push(Traced {
                        scan_id: msg.scan_id,
                        target: msg.target,
                        radii: c.radii.clone(),
                        sizes: sizes_of(c),
                        third,
                    });
                }
                if args.json {
                    let line = SizeLine {
                        scan_id: c.scan_id,
                        target: c.target,
                        calibrated: c.calibrated,
                        circumference: c.circumference,
                        box_width: c.box_width,
                        box_height: c.box_height,
                        effective_diameter: c.effective_diameter,
                        size_u95: c.size_u95,
                        circumference_3d: c.circumference_3d,
                        circumference_3d_u95: c.circumference_3d_u95,
                        frame_curve: c.frame_curve,
                    };
                    println!("{}", serde_json::to_string(&line).expect("a size line serialises"));
                }
                if let Some(writer) = writer.as_mut() {
                    writer.write("/contour", *t, c).map_err(|e| e.to_string())?;
                    if let Some(polygon) = &out.polygon {
                        writer.write("/contour_polygon", *t, polygon).map_err(|e| e.to_string())?;
                    }
                }
            }
            Err(e) => {
                rejected += 1;
                eprintln!("tracer_calib correct: scan {} rejected: {e}", msg.scan_id);
            }
        }
    }
    let wrote = match writer {
        Some(w) => format!("; wrote {}", w.finish().map_err(|e| e.to_string())?.display()),
        None => String::new(),
    };
    let mut summary = format!(
        "{corrected} scans corrected ({}), {rejected} rejected{wrote}",
        if state.params.calibration_valid { "calibrated" } else { "uncalibrated" },
    );
    if let Some(oma_path) = &args.oma {
        let written = write_oma(oma_path, &args.eye, &traces)?;
        summary.push_str(&format!("; OMA: {}", written.join(", ")));
    }
    Ok(summary)
}

/// `[C, A, B, FED]` of a contour, if it has them.
fn sizes_of(c: &Contour) -> Option<[f64; 4]> {
    (c.circumference > 0.0).then_some([c.circumference, c.box_width, c.box_height, c.effective_diameter])
}

/// The heights of a contour's `points` (in sample order round the axis) at the `m` equal
/// angles of its radii, `2πk/m` counter-clockwise from +x: linear between the two points
/// about each angle, round the turn. `None` for fewer than 3 points or none.
fn heights_at_radii(points: &[crate::interfaces::Point], m: usize) -> Option<Vec<f64>> {
    if points.len() < 3 || m == 0 {
        return None;
    }
    let tau = std::f64::consts::TAU;
    let mut polar: Vec<(f64, f64)> = points.iter().map(|p| (p.y.atan2(p.x).rem_euclid(tau), p.z)).collect();
    polar.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = polar.len();
    let mut j = 0;
    let heights = (0..m)
        .map(|k| {
            let t = tau * k as f64 / m as f64;
            while j < n && polar[j].0 < t {
                j += 1;
            }
            // Between the point before `t` and the one at or after it, round the turn.
            let (a, b) = (polar[(j + n - 1) % n], polar[j % n]);
            let (ta, tb) = (if j == 0 { a.0 - tau } else { a.0 }, if j == n { b.0 + tau } else { b.0 });
            if tb > ta { a.1 + (b.1 - a.1) * (t - ta) / (tb - ta) } else { a.1 }
        })
        .collect();
    Some(heights)
}

/// A scan's size records for the OMA file: `CIRC` (the circumference in the plane, 2-D),
/// `HBOX`, `VBOX`, `FED` in millimetres (1/100 mm), and with heights `CIRC3D` (the
/// groove's length in 3-D) and `FCRV` (the frame curve, dioptres), chiral as the VCA
/// standard lays them out (`right;left`: the eye's side filled, both for `B`).
fn size_records(eye: Eye, sizes: [f64; 4], third: Option<(f64, f64)>) -> Vec<(String, String)> {
    let mut records: Vec<(&str, String)> =
        ["CIRC", "HBOX", "VBOX", "FED"].iter().zip(sizes).map(|(l, v)| (*l, format!("{:.2}", v * 1e3))).collect();
    if let Some((c3, curve)) = third {
        records.push(("CIRC3D", format!("{:.2}", c3 * 1e3)));
        records.push(("FCRV", format!("{curve:.2}")));
    }
    records
        .into_iter()
        .map(|(label, mm)| {
            let value = match eye {
                Eye::Right => format!("{mm};"),
                Eye::Left => format!(";{mm}"),
                Eye::Both => format!("{mm};{mm}"),
            };
            (label.to_string(), value)
        })
        .collect()
}

/// One OMA file per traced lens or frame (radii present), named after `path`.
fn write_oma(path: &Path, eye: &str, traces: &[Traced]) -> Result<Vec<String>, String> {
    let eye = Eye::from_code(eye).ok_or_else(|| format!("--eye: unknown eye '{eye}'"))?;
    let usable: Vec<_> = traces.iter().filter(|t| !t.radii.is_empty()).collect();
    if usable.is_empty() {
        return Err("--oma: no lens or frame scan in the bag goes all the way round: no trace to write".into());
    }
    let mut written = Vec::new();
    for t in &usable {
        let scan_id = t.scan_id;
        let trace_type = if t.target == RawScan::TARGET_FRAME { TraceType::Frame } else { TraceType::Lens };
        let mut trace = Trace::equiangular(eye, trace_type, t.radii.clone());
        trace.heights = t.third.as_ref().map(|(z, _, _)| z.clone());
        let file = OmaFile {
            job: Some(scan_id.to_string()),
            traces: vec![trace],
            other: t
                .sizes
                .map(|s| size_records(eye, s, t.third.as_ref().map(|(_, c, f)| (*c, *f))))
                .unwrap_or_default(),
            warnings: Vec::new(),
        };
        let target_path = if usable.len() == 1 {
            path.to_path_buf()
        } else {
            let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "trace".into());
            path.with_file_name(format!("{stem}_{scan_id}.oma"))
        };
        oma::write(&target_path, &file).map_err(|e| e.to_string())?;
        written.push(target_path.display().to_string());
    }
    Ok(written)
}
