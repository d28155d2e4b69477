//! Soak: 10^5 scans through `tracer_calib_node` as fast as it sustains, with calibrate
//! calls interleaved; memory, throughput and the fate of every scan.
//!
//! ```text
//! bash scripts/soak.sh [SCANS] [WINDOW] [RATE]        (runs this in a private netns)
//! ```
//!
//! This process publishes 400-sample RawScans (lens, frame and plate scans in turn, one
//! in 50 malformed on purpose) keeping at most WINDOW scans in flight, so the rate is
//! the node's own pace; every 2000 scans it calls `/calibrate` on the latest plate scan.
//! At the end it compares what it sent with what came back and with the node's
//! `/diagnostics` counters: every scan must be either corrected or counted as rejected.
//! The node's RSS is read from `/proc` at the start, at each tenth, and at the end, and
//! its peak RSS (`VmHWM`, the kernel's high-water mark) at the end of the burst and of
//! the run.

use std::collections::HashSet;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures::StreamExt;
use nalgebra::Vector2;
use rand::SeedableRng;
use ros2_client::dds::{Context, ServiceMapping};
use ros2_client::{Name, NodeName, NodeOptions, QosProfile, qos::*};
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::engine::model::PlateSpec;
use tracer_calib::engine::shape::{Ellipse, RoundedRect, Shape};
use tracer_calib::engine::simulate::{SimOptions, simulate};
use tracer_calib::interfaces::{
    Calibrate, CalibrateRequest, Contour, DiagnosticArray, Header, RawScan, RosMsg, RosService,
};

fn qos(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// A field of `/proc/PID/status` in KiB (`VmRSS`, resident now; `VmHWM`, the peak).
fn status_kib(pid: u32, field: &str) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with(field))?.split_whitespace().nth(1)?.parse().ok())
        .unwrap_or(0)
}

fn rss_kib(pid: u32) -> u64 {
    status_kib(pid, "VmRSS:")
}

/// The node's peak resident set since it started (the kernel's high-water mark).
fn peak_rss_kib(pid: u32) -> u64 {
    status_kib(pid, "VmHWM:")
}

struct Node(Child);
impl Drop for Node {
    fn drop(&mut self) {
        let _ = Command::new("kill").arg("-TERM").arg(self.0.id().to_string()).status();
        let _ = self.0.wait();
    }
}

fn scan(shape: &impl Shape, target: u8, seed: u64) -> RawScan {
    let m = Mounting::new(0.03, 0.004, 0.0015);
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let sim = simulate(shape, &m, &SimOptions { noise: 3e-6, ..SimOptions::default() }, &mut rng).unwrap();
    RawScan {
        header: Header::default(),
        scan_id: 0,
        target,
        steps_per_revolution: 400,
        step: sim.scan.samples().iter().map(|s| s.step).collect(),
        counts: sim.scan.samples().iter().map(|s| (s.rho * 1e6).round() as i32).collect(),
        height_counts: Vec::new(),
    }
}

fn main() {
    let total: u32 = std::env::args().nth(1).map_or(100_000, |s| s.parse().expect("SCANS"));
    let window: u32 = std::env::args().nth(2).map_or(16, |s| s.parse().expect("WINDOW"));
    let rate: f64 = std::env::args().nth(3).map_or(0.0, |s| s.parse().expect("RATE"));
    // By default the node built beside this example: <target>/release/examples/ -> <target>/release/.
    let node_bin = std::env::var("TRACER_CALIB_NODE").unwrap_or_else(|_| {
        let exe = std::env::current_exe().unwrap();
        exe.parent().and_then(std::path::Path::parent).unwrap().join("tracer_calib_node").display().to_string()
    });
    let node = Node(
        Command::new(&node_bin)
            .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {node_bin}: {e}")),
    );
    let pid = node.0.id();
    let kinds = [
        scan(&Ellipse { center: Vector2::zeros(), a: 0.025, b: 0.015, angle: 0.0 }, RawScan::TARGET_LENS, 1),
        scan(
            &RoundedRect { center: Vector2::zeros(), half_w: 0.026, half_h: 0.016, radius: 0.008 },
            RawScan::TARGET_FRAME,
            2,
        ),
        scan(&PlateSpec::default().at(Vector2::new(0.0005, -0.0003)), RawScan::TARGET_CALIBRATION_PLATE, 3),
    ];
    let malformed = RawScan { counts: vec![1, 2, 3], ..kinds[0].clone() };

    let dp = rustdds::DomainParticipantBuilder::new(0)
        .with_only_networks([std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST)])
        .build()
        .unwrap();
    let ctx = Context::from_domain_participant(dp).unwrap();
    let mut n = ctx.new_node(NodeName::new("/", "soak").unwrap(), NodeOptions::new().enable_rosout(false)).unwrap();
    let t_raw =
        n.create_topic(&Name::new("/", "raw_scan").unwrap(), RawScan::NAME.message_type_name(), &qos(100)).unwrap();
    let t_contour =
        n.create_topic(&Name::new("/", "contour").unwrap(), Contour::NAME.message_type_name(), &qos(100)).unwrap();
    let t_diag = n
        .create_topic(&Name::new("/", "diagnostics").unwrap(), DiagnosticArray::NAME.message_type_name(), &qos(10))
        .unwrap();
    let publisher = n.create_publisher::<RawScan>(&t_raw, None).unwrap();
    let contours = n.create_subscription::<Contour>(&t_contour, None).unwrap();
    let diags = n.create_subscription::<DiagnosticArray>(&t_diag, None).unwrap();
    let client = n
        .create_client::<CalibrateRequest, <Calibrate as RosService>::Response>(
            ServiceMapping::Enhanced,
            &Name::new("/", "calibrate").unwrap(),
            &Calibrate::type_name(),
            qos(10),
            qos(10),
        )
        .unwrap();
    let spinner = smol::spawn(n.spinner().unwrap().spin());

    smol::block_on(async {
        let mut stream = std::pin::pin!(contours.async_stream());
        let mut diag_stream = std::pin::pin!(diags.async_stream());
        // Discovery: wait until a probe scan comes back.
        let probe_deadline = Instant::now() + Duration::from_secs(20);
        loop {
            publisher.async_publish(RawScan { scan_id: u32::MAX, ..kinds[0].clone() }).await.unwrap();
            let got = futures::future::select(stream.next(), smol::Timer::after(Duration::from_millis(500))).await;
            if let futures::future::Either::Left((Some(Ok((c, _))), _)) = got
                && c.scan_id == u32::MAX
            {
                break;
            }
            assert!(Instant::now() < probe_deadline, "the node does not answer");
        }
        let rss_start = rss_kib(pid);
        println!("node RSS at start: {rss_start} KiB");
        let (mut sent, mut received, mut malformed_sent) = (0u32, 0u64, 0u32);
        let mut outstanding: HashSet<u32> = HashSet::new();
        let (mut calls, mut calls_ok) = (0, 0);
        let started = Instant::now();
        let mut last_progress = Instant::now();
        while received + u64::from(malformed_sent) < u64::from(total) {
            while sent < total && outstanding.len() < window as usize {
                if rate > 0.0 {
                    let due = Duration::from_secs_f64(f64::from(sent) / rate);
                    if let Some(wait) = due.checked_sub(started.elapsed()) {
                        smol::Timer::after(wait).await;
                    }
                }
                sent += 1;
                let msg = if sent % 50 == 0 {
                    malformed_sent += 1;
                    RawScan { scan_id: sent, ..malformed.clone() }
                } else {
                    outstanding.insert(sent);
                    RawScan { scan_id: sent, ..kinds[sent as usize % 3].clone() }
                };
                publisher.async_publish(msg).await.unwrap();
                if sent % 2000 == 0 {
                    calls += 1;
                    let call = client.async_call_service(CalibrateRequest {
                        scan_id: 0,
                        dry_run: sent % 4000 == 0,
                        ring_scan_id: 0,
                        plate_scan_ids: Vec::new(),
                    });
                    if let futures::future::Either::Left((Ok(r), _)) =
                        futures::future::select(std::pin::pin!(call), smol::Timer::after(Duration::from_secs(5))).await
                        && r.success
                    {
                        calls_ok += 1;
                    }
                }
                if sent % (total / 10).max(1) == 0 {
                    println!(
                        "  {sent:>7} sent, {received:>7} corrected back, {:>6.0} scans/s, node RSS {} KiB",
                        f64::from(sent) / started.elapsed().as_secs_f64(),
                        rss_kib(pid)
                    );
                }
            }
            match futures::future::select(stream.next(), smol::Timer::after(Duration::from_secs(2))).await {
                futures::future::Either::Left((Some(Ok((c, _))), _)) => {
                    if outstanding.remove(&c.scan_id) {
                        received += 1;
                        last_progress = Instant::now();
                    }
                }
                _ => {
                    if last_progress.elapsed() > Duration::from_secs(10) {
                        println!("no progress for 10 s: {} scans outstanding", outstanding.len());
                        break;
                    }
                    // Re-send what may have been lost before matching (not counted twice).
                    for id in outstanding.clone() {
                        publisher
                            .async_publish(RawScan { scan_id: id, ..kinds[id as usize % 3].clone() })
                            .await
                            .unwrap();
                    }
                }
            }
        }
        let secs = started.elapsed().as_secs_f64();
        let rss_end = rss_kib(pid);
        // The node's own account, from /diagnostics.
        let mut counters = None;
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let futures::future::Either::Left((Some(Ok((d, _))), _)) =
                futures::future::select(diag_stream.next(), smol::Timer::after(Duration::from_millis(500))).await
                && let Some(st) = d.status.first()
            {
                let get = |k: &str| st.values.iter().find(|v| v.key == k).map(|v| v.value.clone()).unwrap_or_default();
                counters = Some((get("scans_received"), get("contours_published"), get("scans_rejected")));
                if counters.as_ref().is_some_and(|c| c.0.parse::<u64>().unwrap_or(0) >= u64::from(total)) {
                    break;
                }
            }
        }
        println!(
            "sent {sent} scans ({malformed_sent} malformed on purpose) in {secs:.1} s: {:.0} scans/s sustained",
            f64::from(sent) / secs
        );
        println!("corrected contours received: {received}; outstanding (lost): {}", outstanding.len());
        if let Some((rx, published, rejected)) = counters {
            println!(
                "node's diagnostics: scans_received {rx}, contours_published {published}, scans_rejected {rejected} (the probe included)"
            );
        }
        println!("calibrate calls interleaved: {calls}, answered with success: {calls_ok}");
        println!("node RSS: {rss_start} KiB at start, {rss_end} KiB at the end of the burst");
        println!("node peak RSS (VmHWM): {} KiB", peak_rss_kib(pid));
        // What the node holds once the burst is over (its DDS caches hold at most their
        // depths; before the patch they were freed only every 4-6 s).
        for wait in [5, 10, 15] {
            smol::Timer::after(Duration::from_secs(5)).await;
            println!("node RSS {wait} s after the last scan: {} KiB", rss_kib(pid));
        }
        println!("node peak RSS (VmHWM) over the whole run: {} KiB", peak_rss_kib(pid));
    });
    drop(spinner);
    drop(node);
}
