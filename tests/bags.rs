//! rosbag2 bags: our writer and reader against each other, and against a foreign tool (the
//! Python `rosbags` package) in both directions.
//!
//! - Fixtures written by rosbags (MCAP and sqlite3; `tests/fixtures/make_bags.py`, truth in
//!   `tests/fixtures/rosbags_truth.json`) are read and checked field by field, and the scans are
//!   checked against the geometry they were made from with the calibration engine.
//! - Bags written here are read by rosbags (`tests/fixtures/check_with_rosbags.py`, in the venv
//!   `tests/interop/setup.sh` makes: `target/ros/venv`). That test is ignored by a plain
//!   `cargo test` (it says why); `scripts/test.sh` runs it (`--include-ignored`), and there it
//!   fails if the venv is missing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde::{Deserialize, Serialize};
use serde_json::Value;
use tracer_calib::engine::{self, Mounting, PlateSpec, Scan};
use tracer_calib::interfaces::definition;
use tracer_calib::interfaces::{
    Contour, Definition, Header, InterfaceName, Point, Point32, Polygon, PolygonStamped, RawScan, RosMsg, Time,
};
use tracer_calib::io::bag::{Bag, BagError, BagWriter, StorageFormat};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn fixture(rel: &str) -> PathBuf {
    Path::new(ROOT).join("tests/fixtures").join(rel)
}

/// A fresh, empty scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bags").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `std_msgs/msg/String`, which the crate has no mirror of: the fixtures' foreign topic.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct StdString {
    data: String,
}

impl RosMsg for StdString {
    const NAME: InterfaceName = InterfaceName::msg("std_msgs", "String");
    const DEFINITION: Definition = Definition::Msg("string data\n");
}

/// `tf2_msgs/msg/TFMessage`, whose dependency (`geometry_msgs/TransformStamped`) the crate
/// has no definition of: a type that cannot be written to a bag.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct TfMessage {
    transforms: Vec<u8>,
}

impl RosMsg for TfMessage {
    const NAME: InterfaceName = InterfaceName::msg("tf2_msgs", "TFMessage");
    const DEFINITION: Definition = Definition::Msg("geometry_msgs/TransformStamped[] transforms\n");
}

// ------------------------------------------------------------------------------ samples

fn stamp(ns: u64) -> Time {
    Time::new((ns / 1_000_000_000) as i32, (ns % 1_000_000_000) as u32)
}

fn raw_scan(scan_id: u32, stamp_ns: u64) -> RawScan {
    let steps: Vec<u32> = (0..400).filter(|k| k % 50 != 7 || scan_id == 1).collect();
    RawScan {
        header: Header { stamp: stamp(stamp_ns), frame_id: "tracer".into() },
        scan_id,
        target: if scan_id == 2 { RawScan::TARGET_LENS } else { RawScan::TARGET_CALIBRATION_PLATE },
        steps_per_revolution: 400,
        counts: steps.iter().map(|&k| 24_000 + (k as i32 * 37 + scan_id as i32 * 11) % 900 - 450).collect(),
        height_counts: Vec::new(),
        step: steps,
    }
}

fn contour(scan_id: u32, stamp_ns: u64) -> Contour {
    let n = 400;
    let angle = |k: usize| std::f64::consts::TAU * k as f64 / n as f64;
    Contour {
        header: Header { stamp: stamp(stamp_ns), frame_id: "tracer_axis".into() },
        scan_id,
        target: RawScan::TARGET_LENS,
        calibrated: scan_id.is_multiple_of(2),
        points: (0..n).map(|k| Point { x: 0.025 * angle(k).cos(), y: 0.015 * angle(k).sin(), z: 0.0 }).collect(),
        radii: (0..n).map(|k| 0.02 + 0.001 * angle(k).sin()).collect(),
        circumference: 0.12763,
        box_width: 0.05,
        box_height: 0.03,
        effective_diameter: 0.0501,
        size_u95: [4e-6, 3e-6, 5e-6, 6e-6],
        radii_u95: vec![2e-6; n],
        calibration_stamp: if scan_id.is_multiple_of(2) { stamp(1_700_000_000_000_000_000) } else { stamp(0) },
        calibration_scan_id: if scan_id.is_multiple_of(2) { 1 } else { 0 },
        circumference_3d: 0.12813 + scan_id as f64 * 1e-6,
        circumference_3d_u95: 5e-6,
        frame_curve: 4.25,
    }
}

fn polygon(stamp_ns: u64) -> PolygonStamped {
    PolygonStamped {
        header: Header { stamp: stamp(stamp_ns), frame_id: "tracer_axis".into() },
        polygon: Polygon {
            points: vec![
                Point32 { x: 0.01, y: 0.0, z: 0.0 },
                Point32 { x: 0.0, y: 0.02, z: 0.0 },
                Point32 { x: -0.01, y: -0.005, z: 0.0 },
            ],
        },
    }
}

const T0: u64 = 1_731_000_000_000_000_000;

/// What [`write_sample_bag`] writes: raw scans at T0 + 1, 2, 3 s (written 1, 3, 2), contours
/// at T0 + 1.5, 2.5 s, one polygon at T0 + 2.6 s.
struct Sample {
    scans: Vec<(u64, RawScan)>,
    contours: Vec<(u64, Contour)>,
    polygons: Vec<(u64, PolygonStamped)>,
}

fn sample() -> Sample {
    let s = 1_000_000_000;
    Sample {
        scans: (1..=3).map(|i| (T0 + i as u64 * s, raw_scan(i, T0 + i as u64 * s - 200_000_000))).collect(),
        contours: (1..=2).map(|i| (T0 + i as u64 * s + s / 2, contour(i, T0 + i as u64 * s - 200_000_000))).collect(),
        polygons: vec![(T0 + 2 * s + 600_000_000, polygon(T0 + 2 * s))],
    }
}

fn write_sample_bag(path: &Path) -> (Sample, PathBuf) {
    let sample = sample();
    let mut w = BagWriter::create(path).unwrap();
    w.add_topic::<RawScan>("/raw_scan").unwrap();
    w.add_topic::<RawScan>("/raw_scan_unused").unwrap();
    for i in [0, 2, 1] {
        let (t, m) = &sample.scans[i];
        w.write("/raw_scan", *t, m).unwrap();
    }
    for (t, m) in &sample.contours {
        w.write("/contour", *t, m).unwrap();
    }
    for (t, m) in &sample.polygons {
        w.write("/contour_polygon", *t, m).unwrap();
    }
    let written = w.finish().unwrap();
    (sample, written)
}

// ------------------------------------------------------------------------------ round trip

fn check_round_trip(bag: &Bag, sample: &Sample) {
    let topics: Vec<(&str, &str, u64)> =
        bag.topics().iter().map(|t| (t.name.as_str(), t.type_name.as_str(), t.count)).collect();
    assert_eq!(
        topics,
        [
            ("/contour", "tracer_calib_msgs/msg/Contour", 2),
            ("/contour_polygon", "geometry_msgs/msg/PolygonStamped", 1),
            ("/raw_scan", "tracer_calib_msgs/msg/RawScan", 3),
            ("/raw_scan_unused", "tracer_calib_msgs/msg/RawScan", 0),
        ]
    );
    assert!(bag.topics().iter().all(|t| t.serialization_format == "cdr"));
    assert_eq!(bag.read::<RawScan>("/raw_scan").unwrap(), sample.scans, "raw scans, in log-time order");
    assert_eq!(bag.read::<Contour>("/contour").unwrap(), sample.contours);
    assert_eq!(bag.read::<PolygonStamped>("/contour_polygon").unwrap(), sample.polygons);
    assert_eq!(bag.read::<RawScan>("/raw_scan_unused").unwrap(), []);
    let raw = bag.messages("/raw_scan").unwrap();
    assert_eq!(raw.len(), 3);
    assert!(raw.iter().all(|m| m.topic == "/raw_scan" && m.type_name == "tracer_calib_msgs/msg/RawScan"));
    assert!(raw.iter().all(|m| m.data.starts_with(&[0, 1, 0, 0])), "little-endian CDR with its header");
    let names: Vec<_> = bag.topics_of_type("tracer_calib_msgs/msg/RawScan").map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["/raw_scan", "/raw_scan_unused"]);
}

/// The records of an MCAP file that rosbag2 tools rely on.
fn check_mcap_records(file: &Path) {
    use mcap::records::Record;
    let bytes = std::fs::read(file).unwrap();
    let mut profile = None;
    let mut schemas = BTreeMap::new();
    let mut channels = BTreeMap::new();
    let mut rosbag2_metadata = None;
    for record in mcap::read::ChunkFlattener::new(&bytes).unwrap() {
        match record.unwrap() {
            Record::Header(h) => profile = Some(h.profile),
            Record::Schema { header, data } => {
                assert_eq!(header.encoding, "ros2msg");
                schemas.insert(header.name.clone(), String::from_utf8(data.into_owned()).unwrap());
            }
            Record::Channel(c) => {
                assert_eq!(c.message_encoding, "cdr", "{}", c.topic);
                let qos = c.metadata.get("offered_qos_profiles").expect("offered_qos_profiles");
                assert!(qos.contains("reliability: reliable") && qos.contains("depth: 10"), "{qos}");
                channels.insert(c.topic.clone(), c.schema_id);
            }
            Record::Metadata(m) if m.name == "rosbag2" => rosbag2_metadata = Some(m.metadata),
            _ => {}
        }
    }
    assert_eq!(profile.as_deref(), Some("ros2"));
    assert_eq!(channels.len(), 4);
    for ty in ["tracer_calib_msgs/msg/RawScan", "tracer_calib_msgs/msg/Contour", "geometry_msgs/msg/PolygonStamped"] {
        assert_eq!(schemas.get(ty), definition::full_definition(ty).as_ref(), "{ty}");
    }
    let raw_scan = &schemas["tracer_calib_msgs/msg/RawScan"];
    assert!(raw_scan.starts_with("# One revolution of a contact contour tracer"));
    let sep = "=".repeat(80);
    assert!(raw_scan.contains(&format!("\n{sep}\nMSG: std_msgs/msg/Header\n")));
    assert!(raw_scan.contains(&format!("\n{sep}\nMSG: builtin_interfaces/msg/Time\n")));
    let info = rosbag2_metadata.expect("a rosbag2 metadata record");
    assert!(info["serialized_metadata"].contains("storage_identifier: mcap"), "{info:?}");
}

#[test]
fn round_trip_as_bag_directory() {
    let dir = scratch("round_trip_dir").join("scans");
    let (sample, written) = write_sample_bag(&dir);
    assert_eq!(written, dir);
    let mut files: Vec<String> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    files.sort();
    assert_eq!(files, ["metadata.yaml", "scans_0.mcap"]);

    let yaml = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    let doc = &yaml_rust2::YamlLoader::load_from_str(&yaml).unwrap()[0]["rosbag2_bagfile_information"];
    assert_eq!(doc["version"].as_i64(), Some(9));
    assert_eq!(doc["storage_identifier"].as_str(), Some("mcap"));
    assert_eq!(doc["relative_file_paths"][0].as_str(), Some("scans_0.mcap"));
    assert_eq!(doc["message_count"].as_i64(), Some(6));
    assert_eq!(doc["starting_time"]["nanoseconds_since_epoch"].as_i64(), Some((T0 + 1_000_000_000) as i64));
    assert_eq!(doc["duration"]["nanoseconds"].as_i64(), Some(2_000_000_000));
    let topics = doc["topics_with_message_count"].as_vec().unwrap();
    assert_eq!(topics.len(), 4);
    let raw = topics.iter().find(|t| t["topic_metadata"]["name"].as_str() == Some("/raw_scan")).unwrap();
    assert_eq!(raw["message_count"].as_i64(), Some(3));
    assert_eq!(raw["topic_metadata"]["type"].as_str(), Some("tracer_calib_msgs/msg/RawScan"));
    assert_eq!(raw["topic_metadata"]["serialization_format"].as_str(), Some("cdr"));
    assert_eq!(raw["topic_metadata"]["offered_qos_profiles"][0]["history"].as_str(), Some("keep_last"));
    assert_eq!(raw["topic_metadata"]["type_description_hash"].as_str(), Some(""));
    check_mcap_records(&dir.join("scans_0.mcap"));

    let bag = Bag::open(&dir).unwrap();
    assert_eq!(bag.format(), StorageFormat::Mcap);
    assert_eq!(bag.storage_files(), [dir.join("scans_0.mcap")]);
    check_round_trip(&bag, &sample);
    // The same bag through its metadata.yaml, and its storage file alone.
    check_round_trip(&Bag::open(&dir.join("metadata.yaml")).unwrap(), &sample);
    check_round_trip(&Bag::open(&dir.join("scans_0.mcap")).unwrap(), &sample);
}

#[test]
fn round_trip_as_bare_mcap() {
    let file = scratch("round_trip_bare").join("scans.mcap");
    let (sample, _) = write_sample_bag(&file);
    check_mcap_records(&file);
    let bag = Bag::open(&file).unwrap();
    assert_eq!(bag.storage_files(), std::slice::from_ref(&file));
    check_round_trip(&bag, &sample);
    // A directory without metadata.yaml is read from its storage files.
    let dir = file.parent().unwrap();
    check_round_trip(&Bag::open(dir).unwrap(), &sample);
}

#[test]
fn dropped_writer_still_finishes_the_bag() {
    let dir = scratch("dropped_writer").join("bag");
    {
        let mut w = BagWriter::create(&dir).unwrap();
        w.write("/raw_scan", 5, &raw_scan(1, 4)).unwrap();
    }
    let bag = Bag::open(&dir).unwrap();
    assert_eq!(bag.read::<RawScan>("/raw_scan").unwrap(), [(5, raw_scan(1, 4))]);
    assert!(dir.join("metadata.yaml").is_file());
}

// ------------------------------------------------------------------------------ rosbags fixtures

fn truth() -> Value {
    serde_json::from_str(&std::fs::read_to_string(fixture("rosbags_truth.json")).unwrap()).unwrap()
}

fn u64_of(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("not a u64: {v}"))
}

fn check_rosbags_fixture(bag: &Bag) {
    let truth = truth();
    let topics: Vec<(String, String, u64)> =
        bag.topics().iter().map(|t| (t.name.clone(), t.type_name.clone(), t.count)).collect();
    let expected: Vec<(String, String, u64)> = truth["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| (t["name"].as_str().unwrap().into(), t["type"].as_str().unwrap().into(), u64_of(&t["count"])))
        .collect();
    assert_eq!(topics, expected);

    // Raw scans: every field, in log-time order although written out of order.
    let scans = bag.read::<RawScan>("/raw_scan").unwrap();
    let want = truth["raw_scans"].as_array().unwrap();
    assert_eq!(scans.len(), want.len());
    for ((t, scan), w) in scans.iter().zip(want) {
        assert_eq!(*t, u64_of(&w["log_time_ns"]));
        let ns = scan.header.stamp.to_nanos() as u64;
        assert_eq!(ns / 1_000_000_000, u64_of(&w["stamp"]["sec"]));
        assert_eq!(ns % 1_000_000_000, u64_of(&w["stamp"]["nanosec"]));
        assert_eq!(scan.header.frame_id, w["frame_id"].as_str().unwrap());
        assert_eq!(u64::from(scan.scan_id), u64_of(&w["scan_id"]));
        assert_eq!(u64::from(scan.target), u64_of(&w["target"]));
        assert_eq!(u64::from(scan.steps_per_revolution), u64_of(&w["steps_per_revolution"]));
        let step: Vec<u32> = serde_json::from_value(w["step"].clone()).unwrap();
        let counts: Vec<i32> = serde_json::from_value(w["counts"].clone()).unwrap();
        assert_eq!(scan.step, step, "scan {}", scan.scan_id);
        assert_eq!(scan.counts, counts, "scan {}", scan.scan_id);
    }
    assert_eq!(scans.iter().map(|(_, s)| s.scan_id).collect::<Vec<_>>(), [1, 2, 3]);
    assert_eq!(scans[0].1.step.len(), 400);
    assert_eq!(scans[2].1.step.len(), 389);
    assert_eq!(scans[2].1.step[0], 150);

    // The contour: nested points, float64 array, bool.
    let c = &truth["contour"];
    let contours = bag.read::<Contour>("/contour").unwrap();
    assert_eq!(contours.len(), 1);
    let (t, contour) = &contours[0];
    assert_eq!(*t, u64_of(&c["log_time_ns"]));
    assert_eq!(contour.header.frame_id, c["frame_id"].as_str().unwrap());
    assert_eq!(u64::from(contour.scan_id), u64_of(&c["scan_id"]));
    assert_eq!(contour.target, RawScan::TARGET_LENS);
    assert!(contour.calibrated);
    // Written by an earlier version of the message: the calibration it was corrected with
    // is absent, read as zero.
    assert_eq!((contour.calibration_stamp, contour.calibration_scan_id), (Time::ZERO, 0));
    assert_eq!((contour.circumference_3d, contour.frame_curve), (0.0, 0.0));
    assert_eq!(contour.points.len() as u64, u64_of(&c["points"]));
    assert_eq!(contour.points[0].x, c["first_point"][0].as_f64().unwrap());
    assert_eq!(contour.points[0].y, c["first_point"][1].as_f64().unwrap());
    assert_eq!(contour.radii.len() as u64, u64_of(&c["radii"]));
    assert_eq!(contour.radii[0], c["radius_0"].as_f64().unwrap());
    assert_eq!(contour.radii[100], c["radius_100"].as_f64().unwrap());
    // The size figures appended to Contour.
    assert_eq!(contour.circumference, c["circumference"].as_f64().unwrap());
    let u95: Vec<f64> = c["size_u95"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert_eq!(contour.size_u95.to_vec(), u95);
    assert_eq!(contour.radii_u95, vec![c["radius_u95"].as_f64().unwrap(); contour.radii.len()]);
    assert_eq!((contour.box_width, contour.box_height), (0.05, 0.03));
    let (a, b) =
        (truth["ellipse"]["width"].as_f64().unwrap() / 2.0, truth["ellipse"]["height"].as_f64().unwrap() / 2.0);
    for p in &contour.points {
        let on = (p.x / a).hypot(p.y / b);
        assert!((on - 1.0).abs() < 1e-4, "contour point ({}, {}) is off the ellipse", p.x, p.y);
        assert_eq!(p.z, 0.0);
    }

    // A type we have no mirror of, the second message as big-endian CDR.
    let status = bag.read::<StdString>("/tracer/status").unwrap();
    let want: Vec<(u64, StdString)> = truth["status"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (u64_of(&s["log_time_ns"]), StdString { data: s["data"].as_str().unwrap().into() }))
        .collect();
    assert_eq!(status, want);
    let raw = bag.messages("/tracer/status").unwrap();
    assert_eq!(raw[0].data[..2], [0, 1], "little-endian");
    assert_eq!(raw[1].data[..2], [0, 0], "big-endian");
}

#[test]
fn reads_mcap_bag_written_by_rosbags() {
    let dir = fixture("rosbags_mcap");
    let bag = Bag::open(&dir).unwrap();
    assert_eq!(bag.format(), StorageFormat::Mcap);
    assert_eq!(bag.storage_files(), [dir.join("rosbags_mcap.mcap")]);
    check_rosbags_fixture(&bag);
    check_rosbags_fixture(&Bag::open(&dir.join("rosbags_mcap.mcap")).unwrap());
}

#[test]
fn reads_sqlite3_bag_written_by_rosbags() {
    let dir = fixture("rosbags_sqlite3");
    let bag = Bag::open(&dir).unwrap();
    assert_eq!(bag.format(), StorageFormat::Sqlite3);
    assert_eq!(bag.storage_files(), [dir.join("rosbags_sqlite3.db3")]);
    check_rosbags_fixture(&bag);
    check_rosbags_fixture(&Bag::open(&dir.join("rosbags_sqlite3.db3")).unwrap());
}

/// The fixture scans are what the truth says: the engine recovers the mounting from the plate
/// scans, and the lens scan corrected with the true mounting lies on the ellipse.
#[test]
fn rosbags_fixture_scans_match_their_geometry() {
    let truth = truth();
    let m = &truth["mounting"];
    let true_mounting =
        Mounting::new(m["alpha0"].as_f64().unwrap(), m["offset"].as_f64().unwrap(), m["delta_l"].as_f64().unwrap());
    let mpc = truth["meters_per_count"].as_f64().unwrap();
    let plate = PlateSpec {
        side: truth["plate"]["side"].as_f64().unwrap(),
        corner_radius: truth["plate"]["corner_radius"].as_f64().unwrap(),
    };
    let bag = Bag::open(&fixture("rosbags_sqlite3")).unwrap();
    for (_, scan) in bag.read::<RawScan>("/raw_scan").unwrap() {
        let s = Scan::from_counts(scan.steps_per_revolution, &scan.step, &scan.counts, mpc).unwrap();
        match scan.target {
            RawScan::TARGET_CALIBRATION_PLATE => {
                let fit = engine::calibrate(&s, &plate, &engine::Options::default()).unwrap();
                let got = fit.mounting;
                assert!((got.alpha0 - true_mounting.alpha0).abs() < 1e-4, "scan {}: {}", scan.scan_id, fit.summary());
                assert!((got.offset - true_mounting.offset).abs() < 3e-6, "scan {}: {}", scan.scan_id, fit.summary());
                assert!((got.delta_l - true_mounting.delta_l).abs() < 3e-6, "scan {}: {}", scan.scan_id, fit.summary());
                let center = &truth["plate"]["center"];
                let c = (center[0].as_f64().unwrap(), center[1].as_f64().unwrap());
                assert!((fit.plate_center.x - c.0).hypot(fit.plate_center.y - c.1) < 5e-6, "{:?}", fit.plate_center);
                assert!(fit.rms_residual < 1e-6, "{}", fit.summary());
            }
            RawScan::TARGET_LENS => {
                let (a, b) = (
                    truth["ellipse"]["width"].as_f64().unwrap() / 2.0,
                    truth["ellipse"]["height"].as_f64().unwrap() / 2.0,
                );
                for p in engine::correct(&s, &true_mounting) {
                    // Distance to the ellipse, to first order: (f - 1) / |grad f| with f = (x/a)² + (y/b)².
                    let f = (p.x / a).powi(2) + (p.y / b).powi(2);
                    let grad = (2.0 * p.x / (a * a)).hypot(2.0 * p.y / (b * b));
                    assert!(((f - 1.0) / grad).abs() < 0.6e-6, "lens point ({}, {}) off the ellipse", p.x, p.y);
                }
            }
            other => panic!("unexpected target {other}"),
        }
    }
}

// ------------------------------------------------------------------------------ rosbags reads ours

/// The venv with rosbags that `tests/interop/setup.sh` makes.
fn rosbags_python() -> PathBuf {
    let python = Path::new(ROOT).join("target/ros/venv/bin/python");
    assert!(
        python.is_file(),
        "{} is missing: run tests/interop/setup.sh first (it installs rosbags 0.11.9 into target/ros/venv)",
        python.display()
    );
    python
}

/// Runs `tests/fixtures/check_with_rosbags.py` on `bag` and returns its JSON.
fn read_with_rosbags(bag: &Path) -> Value {
    let script = fixture("check_with_rosbags.py");
    let out = Command::new(rosbags_python())
        .arg(&script)
        .arg(bag)
        // Skip the ROS wheels' bootstrap re-exec: rosbags needs no ROS libraries.
        .env("_ROS_WHEELS_BOOTSTRAP_COMPLETE", "1")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "rosbags could not read {}:\n{}{}",
        bag.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn close(a: f64, b: &Value) -> bool {
    let b = b.as_f64().unwrap();
    (a - b).abs() <= 1e-15 * a.abs().max(1.0)
}

fn check_header(h: &Header, v: &Value) {
    let ns = h.stamp.to_nanos() as u64;
    assert_eq!(u64_of(&v["stamp"]["sec"]), ns / 1_000_000_000);
    assert_eq!(u64_of(&v["stamp"]["nanosec"]), ns % 1_000_000_000);
    assert_eq!(v["frame_id"].as_str(), Some(h.frame_id.as_str()));
}

fn check_rosbags_view(seen: &Value, sample: &Sample) {
    // Topics as rosbags sees them.
    let conns = seen["connections"].as_array().unwrap();
    let mut topics: Vec<(&str, &str, u64)> = conns
        .iter()
        .map(|c| (c["topic"].as_str().unwrap(), c["msgtype"].as_str().unwrap(), u64_of(&c["msgcount"])))
        .collect();
    topics.sort();
    assert_eq!(
        topics,
        [
            ("/contour", "tracer_calib_msgs/msg/Contour", 2),
            ("/contour_polygon", "geometry_msgs/msg/PolygonStamped", 1),
            ("/raw_scan", "tracer_calib_msgs/msg/RawScan", 3),
            ("/raw_scan_unused", "tracer_calib_msgs/msg/RawScan", 0),
        ]
    );
    for c in conns {
        assert_eq!(c["serialization_format"], "cdr");
        assert_eq!(c["definition_format"], "MSG");
        assert_eq!(
            c["qos"],
            serde_json::json!([
                {"history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile"}
            ])
        );
    }
    assert_eq!(u64_of(&seen["message_count"]), 6);
    assert_eq!(u64_of(&seen["start_time"]), sample.scans[0].0);
    assert_eq!(u64_of(&seen["end_time"]), sample.scans[2].0 + 1);
    assert_eq!(u64_of(&seen["anyreader_messages"]), 6);

    // The types rosbags built from our message definitions.
    let raw_scan = &seen["types"]["tracer_calib_msgs/msg/RawScan"];
    assert_eq!(
        raw_scan["fields"],
        serde_json::json!(["header", "scan_id", "target", "steps_per_revolution", "step", "counts", "height_counts"])
    );
    assert_eq!(
        raw_scan["constants"],
        serde_json::json!([
            ["TARGET_UNKNOWN", "uint8", 0],
            ["TARGET_CALIBRATION_PLATE", "uint8", 1],
            ["TARGET_FRAME", "uint8", 2],
            ["TARGET_LENS", "uint8", 3],
            ["TARGET_RING_GAUGE", "uint8", 4]
        ])
    );
    assert_eq!(
        seen["types"]["tracer_calib_msgs/msg/Contour"]["fields"],
        serde_json::json!([
            "header",
            "scan_id",
            "target",
            "calibrated",
            "points",
            "radii",
            "circumference",
            "box_width",
            "box_height",
            "effective_diameter",
            "size_u95",
            "radii_u95",
            "calibration_stamp",
            "calibration_scan_id",
            "circumference_3d",
            "circumference_3d_u95",
            "frame_curve"
        ])
    );
    for ty in
        ["std_msgs/msg/Header", "builtin_interfaces/msg/Time", "geometry_msgs/msg/Point", "geometry_msgs/msg/Polygon"]
    {
        assert!(seen["types"].get(ty).is_some(), "rosbags did not get {ty} from the bag");
    }

    // Every message, as rosbags deserialized it.
    let msgs = seen["messages"].as_array().unwrap();
    let of = |topic: &str| msgs.iter().filter(move |m| m["topic"] == topic).collect::<Vec<_>>();
    let scans = of("/raw_scan");
    assert_eq!(scans.len(), 3);
    for ((t, want), got) in sample.scans.iter().zip(&scans) {
        assert_eq!(u64_of(&got["timestamp"]), *t);
        let m = &got["message"];
        check_header(&want.header, &m["header"]);
        assert_eq!(u64_of(&m["scan_id"]), u64::from(want.scan_id));
        assert_eq!(u64_of(&m["target"]), u64::from(want.target));
        assert_eq!(u64_of(&m["steps_per_revolution"]), 400);
        assert_eq!(serde_json::from_value::<Vec<u32>>(m["step"].clone()).unwrap(), want.step);
        assert_eq!(serde_json::from_value::<Vec<i32>>(m["counts"].clone()).unwrap(), want.counts);
    }
    let contours = of("/contour");
    assert_eq!(contours.len(), 2);
    for ((t, want), got) in sample.contours.iter().zip(&contours) {
        assert_eq!(u64_of(&got["timestamp"]), *t);
        let m = &got["message"];
        check_header(&want.header, &m["header"]);
        assert_eq!(m["calibrated"].as_bool(), Some(want.calibrated));
        let points = m["points"].as_array().unwrap();
        assert_eq!(points.len(), want.points.len());
        for (p, q) in want.points.iter().zip(points) {
            assert!(close(p.x, &q["x"]) && close(p.y, &q["y"]) && close(p.z, &q["z"]), "{p:?} vs {q}");
        }
        let radii = m["radii"].as_array().unwrap();
        assert_eq!(radii.len(), want.radii.len());
        assert!(want.radii.iter().zip(radii).all(|(a, b)| close(*a, b)));
        // The calibration it was corrected with, as a foreign reader sees it.
        let stamp = &m["calibration_stamp"];
        assert_eq!(
            stamp["sec"].as_i64(),
            Some(i64::from(want.calibration_stamp.to_nanos().div_euclid(1_000_000_000) as i32))
        );
        assert_eq!(u64_of(&m["calibration_scan_id"]), u64::from(want.calibration_scan_id));
        // The frame's 3-D figures.
        assert!(close(want.circumference_3d, &m["circumference_3d"]), "{}", m["circumference_3d"]);
        assert!(close(want.frame_curve, &m["frame_curve"]), "{}", m["frame_curve"]);
    }
    let polys = of("/contour_polygon");
    assert_eq!(polys.len(), 1);
    let got = &polys[0]["message"];
    check_header(&sample.polygons[0].1.header, &got["header"]);
    let pts = got["polygon"]["points"].as_array().unwrap();
    let want = &sample.polygons[0].1.polygon.points;
    assert_eq!(pts.len(), want.len());
    for (p, q) in want.iter().zip(pts) {
        // float32 on the wire: exactly representable in f64.
        assert_eq!(f64::from(p.x), q["x"].as_f64().unwrap());
        assert_eq!(f64::from(p.y), q["y"].as_f64().unwrap());
    }
}

/// Needs the venv of `tests/interop/setup.sh` (fails, saying so, without it).
#[test]
#[ignore = "needs rosbags (target/ros/venv, made by tests/interop/setup.sh); scripts/test.sh runs it"]
fn rosbags_reads_our_bags() {
    let base = scratch("rosbags_reads_ours");
    let dir = base.join("ours");
    let (sample, _) = write_sample_bag(&dir);
    check_rosbags_view(&read_with_rosbags(&dir), &sample);
    let file = base.join("ours.mcap");
    let (sample, _) = write_sample_bag(&file);
    check_rosbags_view(&read_with_rosbags(&file), &sample);
}

// ------------------------------------------------------------------------------ errors

fn open_err(path: &Path) -> String {
    match Bag::open(path) {
        Ok(bag) => panic!("{} opened: {:?}", path.display(), bag.topics()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn missing_topic_lists_the_topics() {
    let path = fixture("rosbags_mcap/rosbags_mcap.mcap");
    let bag = Bag::open(&path).unwrap();
    let err = bag.read::<RawScan>("/x").unwrap_err();
    assert!(matches!(err, BagError::TopicNotFound { .. }));
    assert_eq!(
        err.to_string(),
        format!(
            "topic /x not in {}; topics: /contour (tracer_calib_msgs/msg/Contour, 1 message), \
             /raw_scan (tracer_calib_msgs/msg/RawScan, 3 messages), /tracer/status (std_msgs/msg/String, 2 messages)",
            path.display()
        )
    );
    assert_eq!(bag.messages("/x").unwrap_err().to_string(), err.to_string());
}

#[test]
fn foreign_type_is_refused() {
    let dir = fixture("rosbags_sqlite3");
    let bag = Bag::open(&dir).unwrap();
    let err = bag.read::<RawScan>("/tracer/status").unwrap_err().to_string();
    assert_eq!(
        err,
        format!(
            "topic /tracer/status in {} has type std_msgs/msg/String, expected tracer_calib_msgs/msg/RawScan",
            dir.display()
        )
    );
}

#[test]
fn truncated_mcap_is_an_error() {
    let bytes = std::fs::read(fixture("rosbags_mcap/rosbags_mcap.mcap")).unwrap();
    let path = scratch("truncated_mcap").join("half.mcap");
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let err = open_err(&path);
    assert!(err.starts_with(&format!("{}: truncated or corrupt MCAP file: ", path.display())), "{err}");
    // Cut just before the end magic: still refused.
    std::fs::write(&path, &bytes[..bytes.len() - 8]).unwrap();
    let err = open_err(&path);
    assert!(err.starts_with(&format!("{}: truncated or corrupt MCAP file: ", path.display())), "{err}");
}

#[test]
fn corrupt_db3_is_an_error() {
    let path = scratch("corrupt_db3").join("noise.db3");
    let mut x: u64 = 0x2545_f491_4f6c_dd1d;
    let noise: Vec<u8> = (0..8192)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect();
    std::fs::write(&path, noise).unwrap();
    let err = open_err(&path);
    assert_eq!(err, format!("{}: unreadable sqlite3 bag: file is not a database", path.display()));
}

#[test]
fn sqlite_database_without_rosbag2_tables_is_not_a_bag() {
    let path = scratch("other_db3").join("other.db3");
    let conn = rusqlite::Connection::open(&path).unwrap();
    conn.execute_batch("CREATE TABLE things(id INTEGER PRIMARY KEY, name TEXT);").unwrap();
    drop(conn);
    assert_eq!(
        open_err(&path),
        format!(
            "{} is not a rosbag2 bag: an sqlite3 database without the rosbag2 table(s) topics, messages",
            path.display()
        )
    );
}

#[test]
fn directory_without_metadata_or_storage_files_is_not_a_bag() {
    let dir = scratch("empty_dir");
    std::fs::write(dir.join("notes.txt"), "not a bag").unwrap();
    assert_eq!(
        open_err(&dir),
        format!(
            "{} is not a rosbag2 bag: a directory without metadata.yaml and without .mcap or .db3 files",
            dir.display()
        )
    );
}

#[test]
fn nonexistent_path_is_an_error() {
    let path = scratch("nonexistent").join("no_such_bag");
    assert_eq!(open_err(&path), format!("{}: no such file or directory", path.display()));
}

#[test]
fn other_file_is_not_a_bag() {
    let path = scratch("other_file").join("scan.csv");
    std::fs::write(&path, "step,counts\n0,24000\n").unwrap();
    assert_eq!(
        open_err(&path),
        format!(
            "{} is not a rosbag2 bag: expected a bag directory, its metadata.yaml, an .mcap or a .db3 file",
            path.display()
        )
    );
}

#[test]
fn bad_metadata_is_an_error() {
    let dir = scratch("bad_metadata");
    let meta = dir.join("metadata.yaml");
    std::fs::write(&meta, "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n").unwrap();
    assert_eq!(open_err(&dir), format!("{}: bad rosbag2 metadata: no relative_file_paths", meta.display()));
    std::fs::write(
        &meta,
        "rosbag2_bagfile_information:\n  storage_identifier: mcap\n  relative_file_paths: [gone_0.mcap]\n",
    )
    .unwrap();
    assert_eq!(
        open_err(&dir),
        format!("{}: bad rosbag2 metadata: lists storage file gone_0.mcap, which does not exist", meta.display())
    );
    std::fs::write(
        &meta,
        "rosbag2_bagfile_information:\n  storage_identifier: mcap\n  relative_file_paths: [b_0.mcap.zstd]\n  \
         compression_mode: FILE\n  compression_format: zstd\n",
    )
    .unwrap();
    let err = open_err(&dir);
    assert!(
        err.starts_with(&format!(
            "{}: unsupported bag: compressed bag (compression_mode FILE, compression_format zstd)",
            meta.display()
        )),
        "{err}"
    );
}

#[test]
fn undecodable_message_names_topic_index_and_time() {
    // A RawScan topic whose second message is cut short, written with the mcap crate directly.
    let path = scratch("undecodable").join("bad.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(std::io::BufWriter::new(std::fs::File::create(&path).unwrap()))
        .unwrap();
    let def = definition::full_definition("tracer_calib_msgs/msg/RawScan").unwrap();
    let schema = w.add_schema("tracer_calib_msgs/msg/RawScan", "ros2msg", def.as_bytes()).unwrap();
    let channel = w.add_channel(schema, "/raw_scan", "cdr", &BTreeMap::new()).unwrap();
    let good = tracer_calib::interfaces::to_cdr(&raw_scan(1, 0)).unwrap();
    for (seq, (t, data)) in [(100u64, &good[..]), (200, &good[..40])].into_iter().enumerate() {
        let header =
            mcap::records::MessageHeader { channel_id: channel, sequence: seq as u32, log_time: t, publish_time: t };
        w.write_to_known_channel(&header, data).unwrap();
    }
    w.finish().unwrap();
    drop(w);
    let bag = Bag::open(&path).unwrap();
    assert_eq!(bag.messages("/raw_scan").unwrap().len(), 2);
    let err = bag.read::<RawScan>("/raw_scan").unwrap_err();
    assert!(matches!(err, BagError::Decode { index: 1, log_time_ns: 200, .. }), "{err:?}");
    let err = err.to_string();
    assert!(
        err.starts_with(&format!(
            "{}: message 1 of topic /raw_scan (log time 200 ns) does not decode as tracer_calib_msgs/msg/RawScan: ",
            path.display()
        )),
        "{err}"
    );
}

#[test]
fn writer_errors() {
    let base = scratch("writer_errors");
    // A non-empty directory is not overwritten.
    let busy = base.join("busy");
    std::fs::create_dir_all(&busy).unwrap();
    std::fs::write(busy.join("keep.txt"), "mine").unwrap();
    let err = BagWriter::create(&busy).err().expect("created a bag in a non-empty directory").to_string();
    assert_eq!(err, format!("{}: exists already and is not an empty directory; not overwriting", busy.display()));

    let path = base.join("w.mcap");
    let mut w = BagWriter::create(&path).unwrap();
    w.write("/raw_scan", 1, &raw_scan(1, 0)).unwrap();
    // One type per topic.
    let err = w.write("/raw_scan", 2, &contour(1, 0)).unwrap_err().to_string();
    assert_eq!(
        err,
        format!(
            "topic /raw_scan in {} has type tracer_calib_msgs/msg/RawScan, expected tracer_calib_msgs/msg/Contour",
            path.display()
        )
    );
    // Only types whose complete definitions are known can be written.
    let err = w.add_topic::<TfMessage>("/tf").unwrap_err().to_string();
    assert!(
        err.starts_with("cannot write tf2_msgs/msg/TFMessage to a bag: its message definition is unknown"),
        "{err}"
    );
    w.finish().unwrap();
    assert_eq!(Bag::open(&path).unwrap().read::<RawScan>("/raw_scan").unwrap().len(), 1);
}
