//! Writes the seed corpora under `fuzz/corpus/<target>/`: a few real inputs of each kind.
//!
//! `cargo run --manifest-path fuzz/Cargo.toml --example make_seeds` (from the repository
//! root). Deterministic: the same files every time. Also copies `config/*.yaml` and
//! `tests/fixtures/hand_made.oma`. (`scripts/fuzz.sh` does not need it: the corpora are
//! committed.)

use std::fs;
use std::path::{Path, PathBuf};

use nalgebra::Vector2;
use rand::SeedableRng;
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::engine::model::PlateSpec;
use tracer_calib::engine::shape::{Ellipse, Shape};
use tracer_calib::engine::simulate::{SimOptions, simulate};
use tracer_calib::interfaces::{Header, RawScan, Time, to_cdr};
use tracer_calib::io::{csv, oma};
use tracer_calib::params::Parameters;
use tracer_calib::params::file as params_file;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

fn put(target: &str, name: &str, bytes: &[u8]) {
    let dir = root().join("fuzz/corpus").join(target);
    fs::create_dir_all(&dir).unwrap();
    fs::write(dir.join(name), bytes).unwrap();
}

fn scan_msg(shape: &impl Shape, m: &Mounting, opt: &SimOptions, seed: u64, scan_id: u32, target: u8) -> RawScan {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let sim = simulate(shape, m, opt, &mut rng).unwrap();
    RawScan {
        header: Header { stamp: Time::new(1_700_000_000, 5_000), frame_id: "tracer".into() },
        scan_id,
        target,
        steps_per_revolution: opt.steps_per_rev,
        step: sim.scan.samples().iter().map(|s| s.step).collect(),
        counts: sim.scan.samples().iter().map(|s| (s.rho / 1e-6).round() as i32).collect(),
        height_counts: Vec::new(),
    }
}

fn main() {
    let plate = PlateSpec::default().at(Vector2::new(0.0005, -0.0003));
    let m = Mounting::new(0.035, 0.004, 0.0015);
    let noisy = SimOptions { noise: 2e-6, ..SimOptions::default() };

    // raw_scan: CDR bytes of RawScans, as a DDS reader hands them over.
    let scans = [
        ("plate_full", scan_msg(&plate, &m, &noisy, 1, 2, RawScan::TARGET_CALIBRATION_PLATE)),
        ("plate_paper", scan_msg(&plate, &m, &noisy, 2, 3, RawScan::TARGET_CALIBRATION_PLATE)),
        (
            "plate_gaps_spikes",
            scan_msg(
                &plate,
                &Mounting::new(-0.6, -0.003, 0.0),
                &SimOptions {
                    steps_per_rev: 200,
                    noise: 1e-6,
                    start_step: 37,
                    missing: 0.2,
                    spikes: 3,
                    ..SimOptions::default()
                },
                3,
                4,
                RawScan::TARGET_CALIBRATION_PLATE,
            ),
        ),
        (
            "lens",
            scan_msg(
                &Ellipse { center: Vector2::new(0.001, 0.0), a: 0.025, b: 0.018, angle: 0.2 },
                &m,
                &noisy,
                4,
                5,
                RawScan::TARGET_LENS,
            ),
        ),
        (
            "tiny_frame",
            RawScan {
                header: Header::default(),
                scan_id: 6,
                target: RawScan::TARGET_FRAME,
                steps_per_revolution: 4,
                step: vec![0, 1, 3],
                counts: vec![20_000, 21_000, -5],
                height_counts: Vec::new(),
            },
        ),
    ];
    // The fuzz target reads parameters for a third node from frame_id:
    // "meters_per_count[,alpha0,offset,delta_l]"; resample_points from scan_id / 2.
    let mut tuned = scan_msg(&plate, &m, &noisy, 5, 720, RawScan::TARGET_CALIBRATION_PLATE);
    tuned.header.frame_id = "1e-6,0.035,0.004,0.0015".into();
    let mut coarse = scan_msg(&plate, &m, &noisy, 6, 2 * 360 + 1, RawScan::TARGET_CALIBRATION_PLATE);
    coarse.counts.iter_mut().for_each(|c| *c /= 10);
    coarse.header.frame_id = "1e-05".into();
    let scans: Vec<(&str, RawScan)> =
        scans.into_iter().chain([("plate_tuned", tuned), ("plate_coarse", coarse)]).collect();
    for (name, msg) in &scans {
        put("raw_scan", &format!("{name}.cdr"), &to_cdr(msg).unwrap());
    }

    // csv: a revolution as the offline tool reads it.
    let rev = csv::RawRevolution { step: scans[2].1.step.clone(), counts: scans[2].1.counts.clone() };
    put("csv", "plate_gaps.csv", csv::render(&rev).as_bytes());
    put("csv", "commented.csv", b"# tracer 7\r\nstep, counts\n\n0,24512\n1,24498\n  2 , -3 \n");

    // params_file: the config files, and what the node persists.
    for entry in fs::read_dir(root().join("config")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "yaml") {
            put("params_file", path.file_name().unwrap().to_str().unwrap(), &fs::read(&path).unwrap());
        }
    }
    let p = Parameters {
        calibration: m,
        calibration_valid: true,
        output_frame_id: "cell 1: axis # 'x'".into(),
        params_file: "/var/lib/tracer/params.yaml".into(),
        ..Parameters::default()
    };
    put(
        "params_file",
        "persisted.yaml",
        params_file::render("/cell1/tracer", &p.to_list(), "written by the node").as_bytes(),
    );
    put(
        "params_file",
        "types.yaml",
        b"/**:\n  ros__parameters:\n    use_sim_time: false\n    tags: [a, \"b c\", 'd']\n    ints: [1, 0x1F, 010]\n    doubles: [1.0, .inf, -.nan, 1e-6]\n    flags: [yes, Off]\ntracer_calibrator:\n  ros__parameters:\n    plate: {side: 0.05, corner_radius: 0.004}\n    model: paper\n    resample_points: 720\n    calibration.alpha0: -0.01\n",
    );

    // oma: the hand-made fixture and a rendered file with both kinds of trace.
    put("oma", "hand_made.oma", &fs::read(root().join("tests/fixtures/hand_made.oma")).unwrap());
    let radii: Vec<f64> = (0..36).map(|k| 0.02 + 0.002 * (k as f64 * 0.3).sin()).collect();
    let angles: Vec<f64> = (0..36).map(|k| k as f64 * 0.17).collect();
    let file = oma::OmaFile {
        job: Some("4711".into()),
        traces: vec![
            oma::Trace::equiangular(oma::Eye::Right, oma::TraceType::Frame, radii.clone()),
            oma::Trace { eye: oma::Eye::Left, trace_type: oma::TraceType::Lens, radii, angles: Some(angles) },
        ],
        other: vec![("DO".into(), "B".into()), ("ZFMT".into(), "1;36;E;R;F".into())],
        warnings: Vec::new(),
    };
    put("oma", "two_traces.oma", oma::render(&file).unwrap().as_bytes());

    // ros_args: argv joined with NUL bytes.
    let argvs: [&[&str]; 3] = [
        &[
            "tracer_calib_node",
            "--ros-args",
            "-r",
            "__node:=tracer",
            "-r",
            "__ns:=/cell1",
            "-p",
            "plate.side:=0.05",
            "-p",
            "tracer:output_frame_id:='axis 1'",
            "--params-file",
            "config/cell1_tracer.yaml",
            "-r",
            "raw_scan:=/scanner/raw",
            "-r",
            "tracer:rosservice://calibrate:=~/cal",
            "--log-level",
            "debug",
            "--",
            "extra",
        ],
        &[
            "node",
            "--ros-args",
            "--log-level",
            "rcl:=warn",
            "-p",
            "resample_points:=[1, 2]",
            "-p",
            "model:=!!str full # c",
            "-r",
            "rostopic://contour:={ns}/{node}/out",
            "--disable-rosout-logs",
            "-e",
            "/enclave",
        ],
        &[
            "node",
            "plain",
            "--ros-args",
            "-p",
            "calibration.valid:=\"yes\"",
            "--ros-args",
            "-p",
            "calibration.alpha0:=0x1p-3",
        ],
    ];
    for (i, argv) in argvs.iter().enumerate() {
        put("ros_args", &format!("argv{i}"), argv.join("\0").as_bytes());
    }
    println!("seeds written under {}", root().join("fuzz/corpus").display());
}
