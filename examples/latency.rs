//! Raw scan in → corrected contour out: the node's latency against a bare relay.
//!
//! ```text
//! bash scripts/bench_latency.sh [ITERATIONS]        (runs this in a private netns)
//! ```
//!
//! Round trips are timed in the same run, one message in flight, every path once per
//! round in a fresh random order (so that no path always comes first after the pause):
//! - **node**: this process publishes a 400-sample `RawScan` on `/raw_scan`;
//!   `tracer_calib_node` (a separate process) corrects it and publishes a `Contour`,
//!   which this process receives;
//! - **bare**: the same `RawScan` goes to a relay process that answers with rustdds
//!   alone, no computation: one (`--relay echo`) with the `RawScan` itself, one
//!   (`--relay relay`) with a ready-made `Contour` of the node's size (400 points, 400
//!   radii) carrying the scan's id;
//! - **control**: a second, identical Contour relay (`--relay control`). The two run the
//!   same code, so their difference is the resolution of the comparison on this
//!   machine (process placement, wake-ups).
//!
//! Every relay is this example run from a copy of its own, and handles one path: like
//! the node, each process runs code of its own and handles one message a round (see
//! `main` for what sharing either did to the figures).
//!
//! All paths cross two processes and two DDS hops. Against the Contour relay, the
//! difference is what the node itself adds: checking, correcting and resampling the
//! scan, building the message (the node builds and publishes the polygon only for a
//! subscriber, and there is none here). Against the RawScan relay it also includes
//! carrying a 13 kB answer instead of a 3 kB one. The node's resident memory and every
//! process's minor page faults are read from `/proc` when the timed part begins (after
//! [`WARMUP`]) and at the end.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures::StreamExt;
use nalgebra::Vector2;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use ros2_client::dds::Context;
use ros2_client::{Name, NodeName, NodeOptions, QosProfile, qos::*};
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::engine::shape::Ellipse;
use tracer_calib::engine::simulate::{SimOptions, simulate};
use tracer_calib::interfaces::{Contour, Header, RawScan, RosMsg};

/// Round trips in the first 20 s are not timed. Every process's heap grows while
/// rustdds' reader and writer caches fill up to their steady state (samples are freed
/// in batches every few seconds): at this rate the node and the relays fault in fresh
/// pages, ~3 a round trip, for 12-15 s, then hardly any. The figures are the steady
/// state a node running for hours is in.
const WARMUP: Duration = Duration::from_secs(20);

/// The timed paths.
const NODE: usize = 0;
const RELAY_ECHO: usize = 1;
const RELAY: usize = 2;
const CONTROL: usize = 3;
const PATHS: usize = 4;

fn qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

fn context() -> Context {
    let dp = rustdds::DomainParticipantBuilder::new(0)
        .with_only_networks([std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST)])
        .build()
        .expect("participant");
    Context::from_domain_participant(dp).expect("context")
}

/// `--relay PREFIX`: answer every RawScan from /PREFIX_in on /PREFIX_out (the scan
/// itself, for a lens scan) or /PREFIX_contour (a fixed Contour of the node's size with
/// the scan's id, for a plate scan).
fn relay(prefix: &str) {
    let ctx = context();
    let mut node = ctx.new_node(NodeName::new("/", prefix).unwrap(), NodeOptions::new().enable_rosout(false)).unwrap();
    let name = |suffix: &str| Name::new("/", &format!("{prefix}_{suffix}")).unwrap();
    let t_in = node.create_topic(&name("in"), RawScan::NAME.message_type_name(), &qos()).unwrap();
    let t_out = node.create_topic(&name("out"), RawScan::NAME.message_type_name(), &qos()).unwrap();
    let t_contour = node.create_topic(&name("contour"), Contour::NAME.message_type_name(), &qos()).unwrap();
    let sub = node.create_subscription::<RawScan>(&t_in, None).unwrap();
    let publisher = node.create_publisher::<RawScan>(&t_out, None).unwrap();
    let contour_pub = node.create_publisher::<Contour>(&t_contour, None).unwrap();
    let t_polygon = node
        .create_topic(&name("polygon"), tracer_calib::interfaces::PolygonStamped::NAME.message_type_name(), &qos())
        .unwrap();
    let polygon_pub = node.create_publisher::<tracer_calib::interfaces::PolygonStamped>(&t_polygon, None).unwrap();
    let polygon = tracer_calib::interfaces::PolygonStamped {
        header: Header::default(),
        polygon: tracer_calib::interfaces::Polygon {
            points: (0..400).map(|k| tracer_calib::interfaces::Point32 { x: k as f32, y: 0.0, z: 0.0 }).collect(),
        },
    };
    let contour = Contour {
        header: Header::default(),
        scan_id: 0,
        target: RawScan::TARGET_LENS,
        calibrated: true,
        points: (0..400)
            .map(|k| tracer_calib::interfaces::Point { x: 0.02 + k as f64 * 1e-6, y: 0.01, z: 0.0 })
            .collect(),
        radii: (0..400).map(|k| 0.02 + k as f64 * 1e-6).collect(),
        circumference: 0.127,
        box_width: 0.05,
        box_height: 0.03,
        effective_diameter: 0.05,
        size_u95: [4e-6; 4],
        radii_u95: vec![2e-6; 400],
        calibration_stamp: tracer_calib::interfaces::Time::from_nanos(1_700_000_000_000_000_000),
        calibration_scan_id: 1,
        circumference_3d: 0.128,
        circumference_3d_u95: 5e-6,
        frame_curve: 6.0,
    };
    smol::block_on(async {
        let mut stream = std::pin::pin!(sub.async_stream());
        while let Some(Ok((msg, _))) = stream.next().await {
            if msg.target == RawScan::TARGET_CALIBRATION_PLATE {
                // Asked for the Contour-sized answer.
                let _ = contour_pub.async_publish(Contour { scan_id: msg.scan_id, ..contour.clone() }).await;
                if std::env::var_os("RELAY_POLYGON").is_some() {
                    let _ = polygon_pub.async_publish(polygon.clone()).await;
                }
            } else {
                let _ = publisher.async_publish(msg).await;
            }
        }
    });
}

fn rss_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status.lines().find(|l| l.starts_with("VmRSS:"))?.split_whitespace().nth(1)?.parse().ok()
}

/// Minor page faults of a process so far (`/proc/PID/stat`, field 10).
fn minor_faults(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name (in parentheses, which may hold spaces).
    stat.rsplit_once(')')?.1.split_whitespace().nth(7)?.parse().ok()
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

struct Children(Vec<Child>);
impl Drop for Children {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = Command::new("kill").arg("-TERM").arg(c.id().to_string()).status();
            let _ = c.wait();
        }
    }
}

/// Copies of this program, one per relay, removed at the end.
struct RelayCopies(Vec<std::path::PathBuf>);
impl RelayCopies {
    fn new(me: &std::path::Path, names: &[&str]) -> Self {
        let copies = names
            .iter()
            .map(|name| {
                let path = std::env::temp_dir().join(format!("tracer_calib_latency_{}_{name}", std::process::id()));
                std::fs::copy(me, &path)
                    .unwrap_or_else(|e| panic!("cannot copy {} to {}: {e}", me.display(), path.display()));
                path
            })
            .collect();
        RelayCopies(copies)
    }

    /// Start copy `i` as the relay `name` (`--relay name`).
    fn spawn(&self, i: usize, name: &str) -> Child {
        Command::new(&self.0[i]).args(["--relay", name]).spawn().unwrap()
    }
}
impl Drop for RelayCopies {
    fn drop(&mut self) {
        for path in &self.0 {
            let _ = std::fs::remove_file(path);
        }
    }
}

fn main() {
    let argv: Vec<String> = std::env::args().collect();
    if argv.get(1).map(String::as_str) == Some("--relay") {
        return relay(&argv[2]);
    }
    let iterations: usize = std::env::args().nth(1).map_or(2000, |s| s.parse().expect("ITERATIONS"));
    // By default the node built beside this example: <target>/release/examples/ -> <target>/release/.
    let node_bin = std::env::var("TRACER_CALIB_NODE").unwrap_or_else(|_| {
        let exe = std::env::current_exe().unwrap();
        exe.parent().and_then(std::path::Path::parent).unwrap().join("tracer_calib_node").display().to_string()
    });
    let me = std::env::current_exe().unwrap();
    let node = Command::new(&node_bin)
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {node_bin}: {e}"));
    // Each relay runs from its own copy of this program. Two processes running one
    // executable file share its code pages, and so the CPU caches' copies of it: a relay
    // started from this very file ran the DDS code warm from this process, and came out
    // 30-50 µs faster than the same relay from a copy (or the node, a program of its
    // own). Every process of the bench now has code of its own, as the programs of an
    // edging cell do.
    // One process a path, so that each, like the node, handles one message a round (a
    // relay serving two paths ran warmer, and ~25 µs faster, than one serving one).
    let relays = ["echo", "relay", "control"];
    let copies = RelayCopies::new(&me, &relays);
    let node_pid = node.id();
    let mut children = vec![node];
    children.extend(relays.iter().enumerate().map(|(i, name)| copies.spawn(i, name)));
    // Processes in the order of the paths (NODE, RELAY_ECHO, RELAY, CONTROL).
    let pids: Vec<u32> = children.iter().map(Child::id).collect();
    let _children = Children(children);

    // The scan: a 50 x 30 mm lens traced by a miscalibrated tracer.
    let m = Mounting::new(0.03, 0.004, 0.0015);
    let lens = Ellipse { center: Vector2::zeros(), a: 0.025, b: 0.015, angle: 0.0 };
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let sim = simulate(&lens, &m, &SimOptions { noise: 2e-6, ..SimOptions::default() }, &mut rng).unwrap();
    let template = RawScan {
        header: Header::default(),
        scan_id: 0,
        target: RawScan::TARGET_LENS,
        steps_per_revolution: 400,
        step: sim.scan.samples().iter().map(|s| s.step).collect(),
        counts: sim.scan.samples().iter().map(|s| (s.rho * 1e6).round() as i32).collect(),
        height_counts: Vec::new(),
    };

    let ctx = context();
    let mut n =
        ctx.new_node(NodeName::new("/", "latency_bench").unwrap(), NodeOptions::new().enable_rosout(false)).unwrap();
    let topic = |n: &mut ros2_client::dds::Node, name: &str, ty| {
        n.create_topic(&Name::new("/", name).unwrap(), ty, &qos()).unwrap()
    };
    let raw_t = topic(&mut n, "raw_scan", RawScan::NAME.message_type_name());
    let contour_t = topic(&mut n, "contour", Contour::NAME.message_type_name());
    let echo_in_t = topic(&mut n, "echo_in", RawScan::NAME.message_type_name());
    let echo_out_t = topic(&mut n, "echo_out", RawScan::NAME.message_type_name());
    let relay_in_t = topic(&mut n, "relay_in", RawScan::NAME.message_type_name());
    let relay_contour_t = topic(&mut n, "relay_contour", Contour::NAME.message_type_name());
    let control_in_t = topic(&mut n, "control_in", RawScan::NAME.message_type_name());
    let control_contour_t = topic(&mut n, "control_contour", Contour::NAME.message_type_name());
    let to_node = n.create_publisher::<RawScan>(&raw_t, None).unwrap();
    let from_node = n.create_subscription::<Contour>(&contour_t, None).unwrap();
    let to_echo = n.create_publisher::<RawScan>(&echo_in_t, None).unwrap();
    let from_echo = n.create_subscription::<RawScan>(&echo_out_t, None).unwrap();
    let to_relay = n.create_publisher::<RawScan>(&relay_in_t, None).unwrap();
    let from_relay_contour = n.create_subscription::<Contour>(&relay_contour_t, None).unwrap();
    let to_control = n.create_publisher::<RawScan>(&control_in_t, None).unwrap();
    let from_control = n.create_subscription::<Contour>(&control_contour_t, None).unwrap();
    let spinner = smol::spawn(n.spinner().unwrap().spin());

    let mut rss_start = None;
    let mut faults_start = vec![None; PATHS];
    let (lat, measured_for) = smol::block_on(async {
        let mut contours = std::pin::pin!(from_node.async_stream());
        let mut relayed = std::pin::pin!(from_echo.async_stream());
        let mut relayed_contours = std::pin::pin!(from_relay_contour.async_stream());
        let mut controlled = std::pin::pin!(from_control.async_stream());
        let mut lat: [Vec<f64>; PATHS] = Default::default();
        let mut lost = 0;
        let mut id = 0u32;
        let mut order: [usize; PATHS] = std::array::from_fn(|p| p);
        let start = Instant::now();
        let mut measured = 0;
        let mut measuring_since = None;
        while measured < iterations {
            let warm = start.elapsed() >= WARMUP;
            if warm && measuring_since.is_none() {
                measuring_since = Some(Instant::now());
                rss_start = rss_kib(node_pid);
                faults_start = pids.iter().map(|&p| minor_faults(p)).collect();
            }
            measured += usize::from(warm);
            // Every path once a round, in a fresh random order: no path always goes first.
            order.shuffle(&mut rng);
            for &path in &order {
                id += 1;
                // The relays answer a TARGET_CALIBRATION_PLATE scan with the Contour.
                let target = if path == RELAY_ECHO { RawScan::TARGET_LENS } else { RawScan::TARGET_CALIBRATION_PLATE };
                let msg = RawScan { scan_id: id, target, ..template.clone() };
                let t0 = Instant::now();
                match path {
                    NODE => to_node.async_publish(RawScan { target: RawScan::TARGET_LENS, ..msg }).await,
                    CONTROL => to_control.async_publish(msg).await,
                    RELAY_ECHO => to_echo.async_publish(msg).await,
                    _ => to_relay.async_publish(msg).await,
                }
                .expect("publish");
                let got = async {
                    loop {
                        let back = match path {
                            NODE => contours.next().await.and_then(|r| r.ok()).map(|(c, _)| c.scan_id),
                            RELAY_ECHO => relayed.next().await.and_then(|r| r.ok()).map(|(r, _)| r.scan_id),
                            RELAY => relayed_contours.next().await.and_then(|r| r.ok()).map(|(c, _)| c.scan_id),
                            _ => controlled.next().await.and_then(|r| r.ok()).map(|(c, _)| c.scan_id),
                        };
                        if back == Some(id) {
                            return;
                        }
                    }
                };
                let timeout = smol::Timer::after(Duration::from_secs(if warm { 1 } else { 5 }));
                match futures::future::select(std::pin::pin!(got), timeout).await {
                    futures::future::Either::Left(_) if warm => lat[path].push(t0.elapsed().as_secs_f64() * 1e6),
                    futures::future::Either::Left(_) => {}
                    futures::future::Either::Right(_) => lost += 1,
                }
                smol::Timer::after(Duration::from_millis(2)).await;
            }
        }
        if lost > 0 {
            println!("{lost} round trips timed out (discovery warm-up included)");
        }
        (lat, measuring_since.map_or(Duration::ZERO, |t| t.elapsed()))
    });
    let rss_end = rss_kib(node_pid);
    let faults: Vec<Option<u64>> =
        pids.iter().zip(&faults_start).map(|(&p, &f0)| Some(minor_faults(p)? - f0?)).collect();
    drop(spinner);

    let report = |name: &str, v: &[f64]| {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        if s.is_empty() {
            println!("{name:<42} no samples");
            return f64::NAN;
        }
        let med = percentile(&s, 0.5);
        println!(
            "{name:<42} n = {:>5}   median {:>7.1} µs   p90 {:>7.1} µs   p99 {:>7.1} µs",
            s.len(),
            med,
            percentile(&s, 0.9),
            percentile(&s, 0.99)
        );
        med
    };
    println!("round trip, 400-sample RawScan, loopback, reliable, one message in flight, paths in random order:");
    let node_med = report("via tracer_calib_node (Contour back)", &lat[NODE]);
    let bare_med = report("via a bare relay (RawScan back)", &lat[RELAY_ECHO]);
    let sized_med = report("via a bare relay (same-size Contour back)", &lat[RELAY]);
    let control_med = report("via a second bare relay (control)", &lat[CONTROL]);
    println!(
        "the node adds {:.1} µs ({:+.1} %) to the same-size bare median; {:.1} µs ({:+.1} %) to the RawScan echo",
        node_med - sized_med,
        100.0 * (node_med / sized_med - 1.0),
        node_med - bare_med,
        100.0 * (node_med / bare_med - 1.0)
    );
    println!(
        "control: two identical bare relays (separate processes) differ by {:.1} µs ({:+.1} %)",
        control_med - sized_med,
        100.0 * (control_med / sized_med - 1.0)
    );
    let per_trip = |p: usize| faults[p].map_or("?".into(), |f| format!("{:.2}", f as f64 / lat[p].len().max(1) as f64));
    println!(
        "minor page faults a round trip while measured: node {}, relay {}, control {}, echo {}",
        per_trip(NODE),
        per_trip(RELAY),
        per_trip(CONTROL),
        per_trip(RELAY_ECHO)
    );
    println!(
        "node RSS: {} KiB when the measured part began, {} KiB {:.0} s and {} round trips later",
        rss_start.map_or("?".into(), |v| v.to_string()),
        rss_end.map_or("?".into(), |v| v.to_string()),
        measured_for.as_secs_f64(),
        lat.iter().map(Vec::len).sum::<usize>()
    );
}
