//! `tracer_calib simulate`: scans of known shapes by a tracer with known mounting errors.

use std::path::PathBuf;

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;

use super::exit;
use crate::engine::geometry::Mounting;
use crate::engine::model::PlateSpec;
use crate::engine::shape::{Ellipse, RoundedRect};
use crate::engine::simulate::{HeightOptions, SimOptions, SimScan, on_sphere, simulate, simulate_heights};
use crate::interfaces::{Header, RawScan, Time};
use crate::io::bag::BagWriter;
use crate::io::csv::{self, RawRevolution};

/// The shapes the simulator traces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ShapeKind {
    /// The calibration plate (--plate-side, --corner-radius).
    Plate,
    /// An ellipse (--width, --height), a lens outline.
    Ellipse,
    /// A rounded rectangle (--width, --height, --corner-radius), a frame outline, traced
    /// from inside.
    Rect,
    /// A ring gauge (--ring-diameter), traced from inside.
    Ring,
}

/// Simulate revolutions of a miscalibrated tracer around known shapes, into a CSV file
/// (one revolution) or a rosbag2 bag of RawScan messages on /raw_scan (MCAP; a
/// directory, or a file ending in .mcap).
///
/// Examples:
///   tracer_calib simulate --shape plate --alpha0-deg 2 --offset 0.005 --delta-l 0.002 \
///       --noise 1e-5 --out plate.csv
///   tracer_calib simulate --shape plate --shape ellipse --shape rect --repeat 2 --out scans.mcap
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The shape traced (repeatable: a bag gets one scan per shape, in order). Targets:
    /// plate = TARGET_CALIBRATION_PLATE, ellipse = TARGET_LENS, rect = TARGET_FRAME,
    /// ring = TARGET_RING_GAUGE.
    #[arg(long = "shape", value_enum, default_values_t = [ShapeKind::Plate])]
    pub shapes: Vec<ShapeKind>,
    /// Repeat the sequence of shapes this many times (bags only).
    #[arg(long, default_value_t = 1)]
    pub repeat: u32,
    /// Seconds between scans in a bag.
    #[arg(long, default_value_t = 1.0)]
    pub period: f64,
    /// Rail angle error alpha0, degrees.
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    pub alpha0_deg: f64,
    /// Rail offset d, metres.
    #[arg(long, default_value_t = 0.005, allow_hyphen_values = true)]
    pub offset: f64,
    /// Encoder zero offset dL, metres.
    #[arg(long, default_value_t = 0.002, allow_hyphen_values = true)]
    pub delta_l: f64,
    /// Encoder scale k of the simulated tracer: it reads lengths 1/k of the true ones
    /// (1.0025: a true 25 mm reads 24.94 mm).
    #[arg(long, default_value_t = 1.0, value_parser = positive_scale)]
    pub scale: f64,
    /// Shape centre x, metres.
    #[arg(long, default_value_t = 0.0008, allow_hyphen_values = true)]
    pub center_x: f64,
    /// Shape centre y, metres.
    #[arg(long, default_value_t = -0.0005, allow_hyphen_values = true)]
    pub center_y: f64,
    /// Plate side, metres.
    #[arg(long, default_value_t = 0.045)]
    pub plate_side: f64,
    /// Corner radius of the plate or the rectangle, metres.
    #[arg(long, default_value_t = 0.003)]
    pub corner_radius: f64,
    /// Width of the ellipse or rectangle, metres.
    #[arg(long, default_value_t = 0.050)]
    pub width: f64,
    /// Height of the ellipse or rectangle, metres.
    #[arg(long, default_value_t = 0.030)]
    pub height: f64,
    /// Inner diameter of the ring gauge, metres.
    #[arg(long, default_value_t = 0.040)]
    pub ring_diameter: f64,
    /// Radius of the probe's ball tip, metres: the encoder reads where its centre is.
    #[arg(long, default_value_t = 0.0)]
    pub tip_radius: f64,
    /// Included angle of the V-groove a frame (rect) or ring gauge is traced in, radians:
    /// the ball touches both flanks, its centre tip / sin(angle/2) from the groove's
    /// bottom, which is the shape; π = a plain bore.
    #[arg(long, default_value_t = std::f64::consts::PI, allow_hyphen_values = true)]
    pub groove_angle: f64,
    /// Encoder noise (standard deviation), metres.
    #[arg(long, default_value_t = 0.0)]
    pub noise: f64,
    /// Encoder scale, metres per count.
    #[arg(long, default_value_t = 1e-6)]
    pub meters_per_count: f64,
    #[arg(long, default_value_t = 400)]
    pub steps_per_rev: u32,
    /// First step of the revolution.
    #[arg(long, default_value_t = 0)]
    pub start_step: u32,
    /// Fraction of samples missing.
    #[arg(long, default_value_t = 0.0)]
    pub missing: f64,
    /// Samples spiked by 0.5 mm.
    #[arg(long, default_value_t = 0)]
    pub spikes: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The turntable's angle error: order, cosine and sine amplitude in degrees, as
    /// `H:C:S` (e.g. 1:0.05:0, a disc off centre); repeatable, three at most.
    #[arg(long = "angle-harmonic", value_name = "H:C:S", value_parser = parse_harmonic, allow_hyphen_values = true)]
    pub angle_harmonics: Vec<(u32, f64, f64)>,
    /// The plate turned by this angle (degrees, counter-clockwise): a second placement.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub plate_turn_deg: f64,
    /// A height channel: every scan of a bag carries height_counts. The plate lies on the
    /// holder's datum, the ring gauge 1.5 mm below it, a frame (rect) or lens (ellipse) on
    /// a sphere of --base-curve whose apex is at the shape's centre, 2 mm above.
    #[arg(long)]
    pub heights: bool,
    /// Frame curve of the frames and lenses traced with --heights, dioptres (530 mm / the
    /// sphere's radius); 0 = flat.
    #[arg(long, default_value_t = 6.0)]
    pub base_curve: f64,
    /// The holder's tilt against the turntable's axis with --heights: `X,Y` degrees.
    #[arg(long, value_name = "X,Y", value_delimiter = ',', default_values_t = [0.1, 0.0], allow_hyphen_values = true)]
    pub axis_tilt_deg: Vec<f64>,
    /// Height noise (standard deviation) with --heights, metres.
    #[arg(long, default_value_t = 0.0)]
    pub height_noise: f64,
    /// Height encoder, metres per count.
    #[arg(long, default_value_t = 1e-6)]
    pub height_meters_per_count: f64,
    /// Output: a CSV file ('step,counts', one revolution), or a bag (a directory, or a
    /// file ending in .mcap).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

pub fn run(args: &Args) -> i32 {
    match simulate_to_file(args) {
        Ok(()) => exit::OK,
        Err(e) => {
            eprintln!("tracer_calib simulate: {e}");
            exit::BAD_INPUT
        }
    }
}

fn simulate_to_file(a: &Args) -> Result<(), String> {
    if a.meters_per_count.is_nan() || a.meters_per_count <= 0.0 {
        return Err(format!("--meters-per-count must be positive, got {}", a.meters_per_count));
    }
    let to_csv = a.out.extension().is_some_and(|e| e == "csv");
    let sequence: Vec<ShapeKind> = (0..a.repeat).flat_map(|_| a.shapes.iter().copied()).collect();
    if to_csv && sequence.len() != 1 {
        return Err(format!(
            "{}: a CSV file holds one revolution; write {} scans to a bag (.mcap or a directory)",
            a.out.display(),
            sequence.len()
        ));
    }
    if a.heights && to_csv {
        return Err(format!(
            "{}: --heights writes a bag (.mcap or a directory); a CSV file has no heights",
            a.out.display()
        ));
    }
    let sound =
        a.height_meters_per_count > 0.0 && a.height_noise >= 0.0 && a.base_curve.is_finite() && a.base_curve >= 0.0;
    if !sound {
        return Err(format!(
            "--height-meters-per-count must be positive, --height-noise and --base-curve at least 0; got {}, {}, {}",
            a.height_meters_per_count, a.height_noise, a.base_curve
        ));
    }
    if a.axis_tilt_deg.len() != 2 || a.axis_tilt_deg.iter().any(|t| !t.is_finite()) {
        return Err(format!("--axis-tilt-deg takes two angles X,Y in degrees, got {:?}", a.axis_tilt_deg));
    }
    let mut rng = StdRng::seed_from_u64(a.seed);
    // The heights' noise from a stream of its own: the scans stay as without --heights.
    let mut height_rng = StdRng::seed_from_u64(a.seed ^ 0x4845_4947_4854);
    let mut revolutions = Vec::with_capacity(sequence.len());
    for kind in &sequence {
        let sim = simulate_one(a, *kind, &mut rng)?;
        let heights = if a.heights { Some(heights_of(a, *kind, &sim, &mut height_rng)?) } else { None };
        let rev = RawRevolution {
            step: sim.scan.samples().iter().map(|s| s.step).collect(),
            counts: sim.scan.samples().iter().map(|s| (s.rho / a.meters_per_count).round() as i32).collect(),
        };
        revolutions.push((*kind, rev, heights));
    }
    if to_csv {
        return std::fs::write(&a.out, csv::render(&revolutions[0].1))
            .map_err(|e| format!("{}: cannot write: {e}", a.out.display()));
    }
    let mut writer = BagWriter::create(&a.out).map_err(|e| e.to_string())?;
    writer.add_topic::<RawScan>("/raw_scan").map_err(|e| e.to_string())?;
    let start_ns: u64 = 1_700_000_000_000_000_000;
    for (i, (kind, rev, heights)) in revolutions.into_iter().enumerate() {
        let t = start_ns + (i as f64 * a.period * 1e9) as u64;
        let msg = RawScan {
            header: Header { stamp: Time::from_nanos(t as i64), frame_id: "tracer".into() },
            scan_id: i as u32 + 1,
            target: match kind {
                ShapeKind::Plate => RawScan::TARGET_CALIBRATION_PLATE,
                ShapeKind::Ellipse => RawScan::TARGET_LENS,
                ShapeKind::Rect => RawScan::TARGET_FRAME,
                ShapeKind::Ring => RawScan::TARGET_RING_GAUGE,
            },
            steps_per_revolution: a.steps_per_rev,
            step: rev.step,
            counts: rev.counts,
            height_counts: heights
                .map(|h| h.iter().map(|z| (z / a.height_meters_per_count).round() as i32).collect())
                .unwrap_or_default(),
        };
        writer.write("/raw_scan", t, &msg).map_err(|e| e.to_string())?;
    }
    writer.finish().map_err(|e| e.to_string())?;
    Ok(())
}

/// `H:C:S` of `--angle-harmonic`: the order and the amplitudes in degrees, as radians.
fn parse_harmonic(s: &str) -> Result<(u32, f64, f64), String> {
    let parts: Vec<&str> = s.split(':').collect();
    let bad = || format!("expected H:C:S (order 1-63, cosine and sine amplitudes in degrees), got '{s}'");
    let [h, c, sn] = parts.as_slice() else { return Err(bad()) };
    let h: u32 = h.parse().map_err(|_| bad())?;
    let (c, sn): (f64, f64) = (c.parse().map_err(|_| bad())?, sn.parse().map_err(|_| bad())?);
    if !(1..=63).contains(&h) || !c.is_finite() || !sn.is_finite() {
        return Err(bad());
    }
    Ok((h, c.to_radians(), sn.to_radians()))
}

/// The height readings of a scan (`--heights`): the artefact's surface as `--heights`
/// says, the holder tilted by `--axis-tilt-deg`.
fn heights_of(a: &Args, kind: ShapeKind, sim: &SimScan, rng: &mut StdRng) -> Result<Vec<f64>, String> {
    let center = Vector2::new(a.center_x, a.center_y);
    let (base, level) = match kind {
        ShapeKind::Plate => (0.0, 0.0),
        ShapeKind::Ring => (0.0, -1.5e-3),
        ShapeKind::Rect | ShapeKind::Ellipse => (a.base_curve, 2e-3),
    };
    let opt = HeightOptions {
        zero: 0.0,
        tilt: [a.axis_tilt_deg[0].to_radians(), a.axis_tilt_deg[1].to_radians()],
        noise: a.height_noise,
        quantum: a.height_meters_per_count,
    };
    simulate_heights(sim, on_sphere(base, center, level), &opt, rng).map_err(|e| e.to_string())
}

fn simulate_one(a: &Args, kind: ShapeKind, rng: &mut StdRng) -> Result<SimScan, String> {
    // A plate turned by θ meets the rail θ earlier.
    let turn = if matches!(kind, ShapeKind::Plate) { a.plate_turn_deg.to_radians() } else { 0.0 };
    let m = Mounting::new(a.alpha0_deg.to_radians() - turn, a.offset, a.delta_l).with_scale(a.scale);
    let center = Vector2::new(a.center_x, a.center_y);
    if a.angle_harmonics.len() > 3 {
        return Err(format!("--angle-harmonic: at most 3, got {}", a.angle_harmonics.len()));
    }
    let mut angle_harmonics = [(0, 0.0, 0.0); 3];
    angle_harmonics[..a.angle_harmonics.len()].copy_from_slice(&a.angle_harmonics);
    let opt = SimOptions {
        angle_harmonics,
        steps_per_rev: a.steps_per_rev,
        noise: a.noise,
        quantum: a.meters_per_count,
        start_step: a.start_step,
        missing: a.missing,
        spikes: a.spikes,
        tip_radius: a.tip_radius,
        inside: matches!(kind, ShapeKind::Rect | ShapeKind::Ring),
        groove_angle: a.groove_angle,
        ..SimOptions::default()
    };
    if !(a.tip_radius.is_finite() && a.tip_radius >= 0.0) {
        return Err(format!("--tip-radius must be a length of at least 0 m, got {}", a.tip_radius));
    }
    if !crate::engine::stylus::valid_groove_angle(a.groove_angle) {
        return Err(format!("--groove-angle must be an included angle in (0, π] rad, got {}", a.groove_angle));
    }
    let sim = match kind {
        ShapeKind::Plate => {
            let plate = PlateSpec { side: a.plate_side, corner_radius: a.corner_radius };
            plate.validate().map_err(|e| e.to_string())?;
            simulate(&plate.at(center), &m, &opt, rng)
        }
        ShapeKind::Ellipse => {
            simulate(&Ellipse { center, a: a.width / 2.0, b: a.height / 2.0, angle: 0.0 }, &m, &opt, rng)
        }
        ShapeKind::Ring => {
            let r = a.ring_diameter / 2.0;
            if !(r.is_finite() && r > crate::engine::stylus::contact_offset(a.tip_radius, a.groove_angle)) {
                return Err(format!("--ring-diameter must be larger than the tip's diameter, got {}", a.ring_diameter));
            }
            simulate(&Ellipse { center, a: r, b: r, angle: 0.0 }, &m, &opt, rng)
        }
        ShapeKind::Rect => simulate(
            &RoundedRect { center, half_w: a.width / 2.0, half_h: a.height / 2.0, radius: a.corner_radius },
            &m,
            &opt,
            rng,
        ),
    };
    sim.map_err(|e| e.to_string())
}

fn positive_scale(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(k) if k.is_finite() && k > 0.0 => Ok(k),
        _ => Err(format!("'{s}' is not a positive number")),
    }
}
