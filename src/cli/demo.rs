//! `tracer_calib demo`: the whole product on a simulated cell, no ROS install needed.
//!
//! A tracer with realistic mounting errors is simulated; `tracer_calib_node` runs as a
//! separate process, and this process talks to it over DDS (localhost only, its own
//! domain) as an edging cell would: it publishes a lens scan (uncorrected), the plate
//! scan, calls `/calibrate`, publishes lens and frame scans, and compares the contours
//! that come back with where the probe really was. Then the same plate scan is fitted
//! with every model offline, and a picture of the fit is written.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures::StreamExt;
use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use ros2_client::dds::ServiceMapping;
use ros2_client::{Name, NodeName, NodeOptions, QosProfile, qos::*};

use super::exit;
use crate::engine::calibrate::{Options, Ring, calibrate_with_ring};
use crate::engine::correct::correct;
use crate::engine::geometry::Mounting;
use crate::engine::model::tip::RingSpec;
use crate::engine::model::{ModelKind, PlateSpec};
use crate::engine::shape::{Ellipse, RoundedRect, Shape};
use crate::engine::simulate::{HeightOptions, SimOptions, SimScan, on_sphere, simulate, simulate_heights};
use crate::interfaces::{Calibrate, CalibrateRequest, Contour, Header, RawScan, RosMsg, RosService};

/// Simulate a miscalibrated tracer, run the node, calibrate it over DDS, correct scans.
///
/// Example:
///   tracer_calib demo --seed 7 --plot demo.svg
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// Random seed of the simulated noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Encoder noise, metres.
    #[arg(long, default_value_t = 5e-6)]
    pub noise: f64,
    /// DDS domain of the demo's graph (its own, so a cell on this machine is not disturbed).
    #[arg(long, default_value_t = 77)]
    pub domain_id: u16,
    /// Where to write the picture of the plate fit (SVG).
    #[arg(long, default_value = "demo_calibration.svg")]
    pub plot: PathBuf,
    /// The node binary (default: tracer_calib_node beside this program).
    #[arg(long)]
    pub node: Option<PathBuf>,
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

/// The simulated cell: its true mounting errors and the shapes it traces.
struct Cell {
    truth: Mounting,
    plate: PlateSpec,
    plate_center: Vector2<f64>,
    /// Radius of the probe's ball tip, metres.
    tip: f64,
    /// The ring gauge's certified inner diameter, metres.
    ring_diameter: f64,
    rng: StdRng,
    noise: f64,
    /// The height channel's noise, from a stream of its own (the scans stay as they were).
    height_rng: StdRng,
}

impl Cell {
    /// A turn round `shape`, traced from inside (a frame, the ring gauge) or outside.
    fn scan(&mut self, shape: &impl Shape, spikes: usize, inside: bool) -> Result<SimScan, String> {
        let opt = SimOptions {
            noise: self.noise,
            quantum: 1e-6,
            start_step: 57,
            spikes,
            tip_radius: self.tip,
            inside,
            ..SimOptions::default()
        };
        simulate(shape, &self.truth, &opt, &mut self.rng).map_err(|e| e.to_string())
    }

    /// The height channel's readings of `sim` over an artefact at `surface`, the holder
    /// tilted 0.1° about y against the axis.
    fn heights(&mut self, sim: &SimScan, surface: impl Fn(Vector2<f64>) -> f64) -> Result<Vec<f64>, String> {
        let opt = HeightOptions { zero: 0.0, tilt: [DEMO_TILT, 0.0], noise: self.noise, quantum: 1e-6 };
        simulate_heights(sim, surface, &opt, &mut self.height_rng).map_err(|e| e.to_string())
    }
}

/// The demo's holder tilt against the turntable's axis: 0.1°.
const DEMO_TILT: f64 = 0.1 * std::f64::consts::PI / 180.0;
/// The demo frame's base curve, dioptres.
const DEMO_BASE: f64 = 6.0;

/// A shape's groove length in 3-D over `surface`: 20 000 points round its centre, each
/// where the ray from the centre leaves the shape, at its height.
fn length_3d(shape: &impl Shape, center: Vector2<f64>, surface: impl Fn(Vector2<f64>) -> f64) -> f64 {
    let n = 20_000;
    let at = |i: usize| {
        let t = std::f64::consts::TAU * i as f64 / n as f64;
        let u = Vector2::new(t.cos(), t.sin());
        let p = shape.exit(center, u).map_or(center, |hit| center + u * hit.t);
        nalgebra::Vector3::new(p.x, p.y, surface(p))
    };
    (0..n).map(|i| (at(i + 1) - at(i)).norm()).sum()
}

fn raw_msg(scan_id: u32, target: u8, sim: &SimScan) -> RawScan {
    RawScan {
        header: Header { frame_id: "tracer".into(), ..Header::default() },
        ..RawScan::of_simulation(scan_id, target, sim, 1e-6)
    }
}

/// [`raw_msg`] with the height channel's readings `heights` (1 µm counts).
fn raw_msg_3d(scan_id: u32, target: u8, sim: &SimScan, heights: &[f64]) -> RawScan {
    RawScan {
        height_counts: heights.iter().map(|h| (h / 1e-6).round() as i32).collect(),
        ..raw_msg(scan_id, target, sim)
    }
}

/// RMS distance between a contour's points and the true touch points, metres.
fn rms_error(contour: &Contour, truth: &[Vector2<f64>]) -> f64 {
    let ss: f64 = contour.points.iter().zip(truth).map(|(p, t)| (p.x - t.x).powi(2) + (p.y - t.y).powi(2)).sum();
    (ss / truth.len().max(1) as f64).sqrt()
}

/// Largest error of the equal-angle radii against the shape's true radii, metres.
fn radii_error(contour: &Contour, shape: &dyn Shape) -> f64 {
    let n = contour.radii.len();
    contour
        .radii
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let phi = std::f64::consts::TAU * k as f64 / n as f64;
            shape.exit(Vector2::zeros(), Vector2::new(phi.cos(), phi.sin())).map_or(f64::INFINITY, |h| (h.t - r).abs())
        })
        .fold(0.0, f64::max)
}

struct NodeProcess(Child);
impl Drop for NodeProcess {
    fn drop(&mut self) {
        let _ = Command::new("kill").arg("-TERM").arg(self.0.id().to_string()).status();
        let _ = self.0.wait();
    }
}

/// The demo node's own state directory (its params and history files, left for the user to
/// read): made empty at the start, so a directory left by an earlier demo whose process id
/// this one reuses cannot start the node calibrated.
struct StateDir(std::path::PathBuf);
impl StateDir {
    fn new() -> Result<Self, String> {
        let dir = std::env::temp_dir().join(format!("tracer_calib_demo_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        Ok(StateDir(dir))
    }
}

fn qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

/// Wait for `fut` at most `secs` seconds.
async fn within<T>(secs: u64, what: &str, fut: impl std::future::Future<Output = T>) -> Result<T, String> {
    let timeout = smol::Timer::after(Duration::from_secs(secs));
    match futures::future::select(std::pin::pin!(fut), timeout).await {
        futures::future::Either::Left((v, _)) => Ok(v),
        futures::future::Either::Right(_) => Err(format!("no {what} within {secs} s")),
    }
}

fn demo(args: &Args) -> Result<(), String> {
    let mut cell = Cell::new(args.seed, args.noise);
    cell.describe();
    let node = NodeRun::start(args, &cell)?;
    let edger = Edger::join(args.domain_id)?;
    let traces = Traces::take(&mut cell)?;
    let got = smol::block_on(edger.exchange(&cell, &traces, node.started))?;
    report_accuracy(&traces, &got);
    report_sizes(&traces, &got);
    node.stop(edger);
    fit_every_model(&cell, &traces, got.tip_radius, &args.plot)
}

impl Cell {
    /// The demo's tracer: its mounting errors, plate, tip and ring gauge; noise from `seed`.
    fn new(seed: u64, noise: f64) -> Cell {
        Cell {
            truth: Mounting::new(1.7f64.to_radians(), 4.2e-3, 1.3e-3),
            plate: PlateSpec::default(),
            plate_center: Vector2::new(0.6e-3, -0.4e-3),
            tip: 0.4e-3,
            ring_diameter: 40e-3,
            rng: StdRng::seed_from_u64(seed),
            noise,
            height_rng: StdRng::seed_from_u64(seed ^ 0x4845_4947_4854),
        }
    }

    fn describe(&self) {
        let t = self.truth;
        println!(
            "Simulated tracer: alpha0 = {:.3}°, d = {:.3} mm, dL = {:.3} mm, a ball tip of radius {:.2} mm; 400 steps a turn, encoder noise {:.3} mm, 1 µm counts.",
            t.alpha0.to_degrees(),
            t.offset * 1e3,
            t.delta_l * 1e3,
            self.tip * 1e3,
            self.noise * 1e3
        );
    }
}

/// The node's process, its state directory and when it was started.
struct NodeRun {
    process: NodeProcess,
    params_path: PathBuf,
    started: Instant,
    _state_dir: StateDir,
}

impl NodeRun {
    /// `tracer_calib_node` (beside this program, or `--node`) on the demo's domain,
    /// localhost only, with a params file of its own, fitting `full_tip`.
    fn start(args: &Args, cell: &Cell) -> Result<NodeRun, String> {
        let node_bin = match &args.node {
            Some(p) => p.clone(),
            None => std::env::current_exe().map_err(|e| e.to_string())?.with_file_name("tracer_calib_node"),
        };
        if !node_bin.exists() {
            return Err(format!("{} not found: build it first (cargo build --release --bins)", node_bin.display()));
        }
        let state_dir = StateDir::new()?;
        let params_path = state_dir.0.join("tracer_calibrator.yaml");
        let started = Instant::now();
        let node = Command::new(&node_bin)
            .args(["--ros-args", "-p"])
            .arg(format!("params_file:={}", params_path.display()))
            .args(["-p", "model:=full_tip", "-p"])
            .arg(format!("ring.diameter:={}", cell.ring_diameter))
            // The demo tells what happens; the node's INFO records would say it twice.
            .args(["--log-level", "warn"])
            .env("ROS_DOMAIN_ID", args.domain_id.to_string())
            .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            .stdin(Stdio::null())
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", node_bin.display()))?;
        let process = NodeProcess(node);
        println!(
            "Started {} (pid {}) on DDS domain {}, localhost only.",
            node_bin.file_name().unwrap_or_default().to_string_lossy(),
            process.0.id(),
            args.domain_id
        );
        Ok(NodeRun { process, params_path, started, _state_dir: state_dir })
    }

    /// Step 5: where the node kept what it did; the edger leaves the graph, then the node
    /// is stopped by SIGTERM, timed.
    fn stop(self, edger: Edger) {
        println!("5. The node persisted its parameters to {}", self.params_path.display());
        println!(
            "   and recorded the calibration in {} (tracer_calib history --input FILE)",
            crate::records::file::default_path(&self.params_path.display().to_string())
        );
        drop(edger);
        let stop = Instant::now();
        drop(self.process);
        println!("   and stopped on SIGTERM in {:.0} ms.", stop.elapsed().as_secs_f64() * 1e3);
    }
}

/// This process as the edging cell: a ROS 2 participant on 127.0.0.1 only, publishing raw
/// scans, taking contours, calling `/calibrate`.
struct Edger {
    node: ros2_client::dds::Node,
    scans: ros2_client::dds::Publisher<RawScan>,
    contours: ros2_client::dds::Subscription<Contour>,
    calibrate: ros2_client::dds::Client<CalibrateRequest, <Calibrate as RosService>::Response>,
    _spinner: smol::Task<Result<(), ros2_client::CreateError>>,
}

impl Edger {
    fn join(domain_id: u16) -> Result<Edger, String> {
        let participant = rustdds::DomainParticipantBuilder::new(domain_id)
            .with_only_networks([std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST)])
            .build()
            .map_err(|e| format!("cannot create a DDS participant: {e:?}"))?;
        let (ctx, _) = crate::rmw::dds::context(participant)?;
        let mut node = ctx
            .new_node(NodeName::new("/", "edging_cell_demo").unwrap(), NodeOptions::new().enable_rosout(false))
            .map_err(|e| format!("{e:?}"))?;
        let mk = |e: ros2_client::CreateError| format!("cannot create a DDS entity: {e:?}");
        let raw_t = node
            .create_topic(&Name::new("/", "raw_scan").unwrap(), RawScan::NAME.message_type_name(), &qos())
            .map_err(mk)?;
        let contour_t = node
            .create_topic(&Name::new("/", "contour").unwrap(), Contour::NAME.message_type_name(), &qos())
            .map_err(mk)?;
        let scans = node.create_publisher::<RawScan>(&raw_t, None).map_err(mk)?;
        let contours = node.create_subscription::<Contour>(&contour_t, None).map_err(mk)?;
        let calibrate = node
            .create_client::<CalibrateRequest, <Calibrate as RosService>::Response>(
                ServiceMapping::Enhanced,
                &Name::new("/", "calibrate").unwrap(),
                &Calibrate::type_name(),
                qos(),
                qos(),
            )
            .map_err(mk)?;
        let spinner = smol::spawn(node.spinner().map_err(mk)?.spin());
        Ok(Edger { node, scans, contours, calibrate, _spinner: spinner })
    }

    /// Steps 1-3 and the scans after: a lens scan before calibration, the plate and the
    /// ring gauge, `/calibrate` (its fit against the truth printed), then a lens and a frame.
    async fn exchange(&self, cell: &Cell, traces: &Traces, started: Instant) -> Result<Contours, String> {
        let mut stream = std::pin::pin!(self.contours.async_stream());
        within(15, "answer from the node's /calibrate service", self.calibrate.wait_for_service(&self.node)).await?;
        println!("Connected to /calibrate after {:.1} s.", started.elapsed().as_secs_f64());
        // Publish a scan until its contour comes back (the first may go out before the
        // node's subscription has matched ours).
        let mut exchange = async |msg: RawScan| -> Result<Contour, String> {
            for _attempt in 0..10 {
                self.scans.async_publish(msg.clone()).await.map_err(|e| format!("cannot publish: {e:?}"))?;
                let wait = async {
                    while let Some(item) = stream.next().await {
                        if let Ok((c, _)) = item
                            && c.scan_id == msg.scan_id
                        {
                            return Some(c);
                        }
                    }
                    None
                };
                if let Ok(Some(c)) = within(1, "contour", wait).await {
                    return Ok(c);
                }
            }
            Err(format!("no contour for scan {} from the node", msg.scan_id))
        };
        let before = exchange(raw_msg(1, RawScan::TARGET_LENS, &traces.lens_before)).await?;
        println!();
        println!(
            "1. Lens scan before calibration: contour calibrated = {}, RMS error {:.3} mm.",
            before.calibrated,
            rms_error(&before, &traces.lens_before.truth) * 1e3
        );
        exchange(raw_msg_3d(2, RawScan::TARGET_CALIBRATION_PLATE, &traces.plate, &traces.plate_heights)).await?;
        exchange(raw_msg_3d(3, RawScan::TARGET_RING_GAUGE, &traces.ring, &traces.ring_heights)).await?;
        println!(
            "2. Calibration plate traced (scan 2, two dust spikes on it), then the ring gauge, Ø {:.0} mm (scan 3).",
            cell.ring_diameter * 1e3
        );
        let request = CalibrateRequest { scan_id: 0, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] };
        let response = within(10, "calibrate response", self.calibrate.async_call_service(request))
            .await?
            .map_err(|e| format!("calibrate call failed: {e:?}"))?;
        if !response.success {
            return Err(format!("calibrate failed: {}", response.message));
        }
        println!("3. ros2 service call /calibrate tracer_calib_msgs/srv/Calibrate \"{{}}\" (model full_tip):");
        println!("   {}", response.message);
        println!("{:>14} {:>12} {:>22}", "", "truth", "fit ± standard unc.");
        let t = cell.truth;
        for (name, truth, fit, sd, scale, unit) in [
            ("alpha0", t.alpha0, response.alpha0, response.stddev[0], 180.0 / std::f64::consts::PI, "°"),
            ("offset d", t.offset, response.offset, response.stddev[1], 1e3, " mm"),
            ("delta_l dL", t.delta_l, response.delta_l, response.stddev[2], 1e3, " mm"),
            ("tip radius", cell.tip, response.tip_radius, response.tip_radius_stddev, 1e3, " mm"),
        ] {
            println!("{name:>14} {:>10.4}{unit:<3} {:>10.4} ± {:.4}{unit}", truth * scale, fit * scale, sd * scale);
        }
        let lens = exchange(raw_msg(4, RawScan::TARGET_LENS, &traces.lens_after)).await?;
        let frame = exchange(raw_msg_3d(5, RawScan::TARGET_FRAME, &traces.frame, &traces.frame_heights)).await?;
        Ok(Contours { before, lens, frame, tip_radius: response.tip_radius })
    }
}

/// What the demo's tracer traces: the shapes, their simulated scans and heights.
struct Traces {
    lens_shape: Ellipse,
    frame_shape: RoundedRect,
    lens_before: SimScan,
    plate: SimScan,
    ring: SimScan,
    lens_after: SimScan,
    frame: SimScan,
    plate_heights: Vec<f64>,
    ring_heights: Vec<f64>,
    frame_heights: Vec<f64>,
    /// The frame's groove length in 3-D, exact.
    frame_3d: f64,
}

impl Traces {
    fn take(cell: &mut Cell) -> Result<Traces, String> {
        let plate_shape = cell.plate.at(cell.plate_center);
        let lens = Ellipse { center: Vector2::new(0.5e-3, -0.3e-3), a: 25e-3, b: 15e-3, angle: 0.1 };
        let frame = RoundedRect { center: Vector2::new(-0.4e-3, 0.2e-3), half_w: 26e-3, half_h: 16e-3, radius: 8e-3 };
        let ring = Ellipse {
            center: Vector2::new(-0.3e-3, 0.5e-3),
            a: cell.ring_diameter / 2.0,
            b: cell.ring_diameter / 2.0,
            angle: 0.0,
        };
        let lens_before = cell.scan(&lens, 0, false)?;
        let plate_scan = cell.scan(&plate_shape, 2, false)?;
        let ring_scan = cell.scan(&ring, 0, true)?;
        let lens_after = cell.scan(&lens, 0, false)?;
        let frame_after = cell.scan(&frame, 0, true)?;
        // The tracer reads heights too: the plate on the holder's datum, the ring 1.5 mm
        // below, the frame's groove on a base-6 sphere whose apex is at its centre, 2 mm above.
        let frame_surface = on_sphere(DEMO_BASE, frame.center, 2e-3);
        let plate_heights = cell.heights(&plate_scan, |_| 0.0)?;
        let ring_heights = cell.heights(&ring_scan, |_| -1.5e-3)?;
        let frame_heights = cell.heights(&frame_after, &frame_surface)?;
        let frame_3d = length_3d(&frame, frame.center, &frame_surface);
        Ok(Traces {
            lens_shape: lens,
            frame_shape: frame,
            lens_before,
            plate: plate_scan,
            ring: ring_scan,
            lens_after,
            frame: frame_after,
            plate_heights,
            ring_heights,
            frame_heights,
            frame_3d,
        })
    }
}

/// The contours the node sent back, and the tip radius it fitted.
struct Contours {
    before: Contour,
    lens: Contour,
    frame: Contour,
    tip_radius: f64,
}

/// Step 4: the corrected scans against where the tip really was.
fn report_accuracy(traces: &Traces, got: &Contours) {
    println!("4. Scans after calibration, RMS distance to the surface the tip touched:");
    println!("{:>38} {:>12} {:>14} {:>18}", "", "raw [mm]", "corrected [mm]", "radii max [mm]");
    let raw_frame = correct(&traces.frame.scan, &Mounting::IDEAL);
    let raw_frame_rms = (raw_frame.iter().zip(&traces.frame.truth).map(|(p, q)| (p - q).norm_squared()).sum::<f64>()
        / raw_frame.len() as f64)
        .sqrt();
    for (name, raw_rms, contour, truth, shape) in [
        (
            "lens, ellipse 50 x 30 mm",
            rms_error(&got.before, &traces.lens_before.truth),
            &got.lens,
            &traces.lens_after.truth,
            &traces.lens_shape as &dyn Shape,
        ),
        (
            "frame, rounded rectangle 52 x 32 mm",
            raw_frame_rms,
            &got.frame,
            &traces.frame.truth,
            &traces.frame_shape as &dyn Shape,
        ),
    ] {
        println!(
            "{:>38} {:>12.4} {:>14.4} {:>18.4}",
            name,
            raw_rms * 1e3,
            rms_error(contour, truth) * 1e3,
            radii_error(contour, shape) * 1e3
        );
    }
    println!("   (raw: the tip's centre, uncorrected; corrected errors are the encoder noise; radii: the 400");
    println!("   equal-angle radii of Contour.radii)");
}

/// The size figures the node put in each Contour, against the shapes' exact ones, and the
/// frame's groove in 3-D.
fn report_sizes(traces: &Traces, got: &Contours) {
    println!("   Size figures in each Contour (mm, ± U95), and the shapes' exact ones:");
    for (name, c, truth) in
        [("lens", &got.lens, traces.lens_shape.exact_sizes()), ("frame", &got.frame, traces.frame_shape.exact_sizes())]
    {
        let figures = [c.circumference, c.box_width, c.box_height, c.effective_diameter];
        let shown: Vec<String> = ["circumference", "A", "B", "FED"]
            .iter()
            .enumerate()
            .map(|(i, n)| format!("{n} {:.3} ± {:.3} ({:.3})", figures[i] * 1e3, c.size_u95[i] * 1e3, truth[i] * 1e3))
            .collect();
        println!("   {name:>6}: {}", shown.join(", "));
    }
    println!(
        "   The frame's groove on a base-{DEMO_BASE} sphere, from the tracer's heights (the holder tilted {:.2}° against the axis, removed):",
        DEMO_TILT.to_degrees()
    );
    let frame = &got.frame;
    println!(
        "   circumference in the plane {:.3} mm, along the groove in 3-D {:.3} ± {:.3} mm ({:.3}), frame curve {:.2} D ({DEMO_BASE:.2})",
        frame.circumference * 1e3,
        frame.circumference_3d * 1e3,
        frame.circumference_3d_u95 * 1e3,
        traces.frame_3d * 1e3,
        frame.frame_curve
    );
}

/// The same plate scan with every model, offline: the tip models with the ring gauge, the
/// others told the tip radius the node fitted; the picture of the `full_tip` fit.
fn fit_every_model(cell: &Cell, traces: &Traces, tip: f64, plot: &std::path::Path) -> Result<(), String> {
    println!();
    println!("The plate scan fitted offline with every model (the others told the fitted tip radius):");
    let ring_gauge = Ring { scan: &traces.ring.scan, spec: RingSpec::plain(cell.ring_diameter) };
    let mut tip_cal = None;
    for model in ModelKind::ALL {
        let opt = Options { model, tip_radius: if model.fits_tip() { 0.0 } else { tip }, ..Options::default() };
        let cal =
            calibrate_with_ring(&traces.plate.scan, Some(ring_gauge), &cell.plate, &opt).map_err(|e| e.to_string())?;
        println!("   {}", cal.summary());
        if model == ModelKind::FullTip {
            tip_cal = Some(cal);
        }
    }
    let cal = tip_cal.expect("the full_tip model ran");
    super::plot::write_calibration_plot(plot, &traces.plate.scan, &cell.plate, &cal)?;
    println!("Picture of the fit: {}", plot.display());
    Ok(())
}
