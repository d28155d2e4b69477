//! The cell's handlers, without a network.

use super::intake::MAX_SAMPLES;
use super::*;
use crate::engine::geometry::Mounting;
use crate::engine::model::PlateSpec;
use crate::engine::shape::Shape;
use crate::engine::simulate::{SimOptions, simulate};
use crate::interfaces::{
    CalibrateRequest, CalibrateResponse, DiagnosticArray, DiagnosticStatus, RawScan, RosMsg, Time,
};
use crate::params::Parameters;
use crate::params::file as params_file;
use crate::records::Previous;
use nalgebra::Vector2;
use rand::SeedableRng;
use std::time::{Duration, UNIX_EPOCH};

fn plate_msg(scan_id: u32, m: &Mounting) -> RawScan {
    plate_msg_with(scan_id, m, &SimOptions { noise: 2e-6, ..SimOptions::default() })
}

/// A plate scan of a tracer with mounting `m` and the errors of `opt`, 1 µm counts.
fn plate_msg_with(scan_id: u32, m: &Mounting, opt: &SimOptions) -> RawScan {
    let mut rng = rand::rngs::StdRng::seed_from_u64(u64::from(scan_id));
    let sim = simulate(&PlateSpec::default().at(Vector2::new(0.0005, -0.0003)), m, opt, &mut rng).unwrap();
    RawScan::of_simulation(scan_id, RawScan::TARGET_CALIBRATION_PLATE, &sim, 1e-6)
}

#[test]
fn scans_are_corrected_once_calibrated() {
    let m = Mounting::new(0.02, 0.004, 0.001);
    let mut st = NodeState::new("/tracer_calibrator".into(), Parameters::default());
    let before = st.on_raw_scan(&plate_msg(1, &m), true).unwrap();
    assert!(!before.contour.calibrated);
    assert_eq!((before.contour.calibration_stamp, before.contour.calibration_scan_id), (Time::ZERO, 0));
    assert_eq!(before.contour.points.len(), 400);
    assert_eq!(before.contour.radii.len(), 400);
    assert_eq!(before.polygon.as_ref().unwrap().polygon.points.len(), 400);
    let out =
        st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(out.response.success, "{}", out.response.message);
    assert!((out.response.offset - 0.004).abs() < 1e-5);
    assert_eq!(out.response.stddev.len(), 3);
    // One owner: the parameters the node tells its parameter server are what the cell holds.
    assert_eq!(out.parameters.len(), 10, "no heights, no tilt: {:?}", out.parameters);
    for (name, value) in &out.parameters {
        assert_eq!(st.params.get(name).as_ref(), Some(value), "{name}");
    }
    // The covariance in the contract's layout: the variances are the stddevs squared, the
    // scale's and the tip radius's rows zero (the full model fits neither).
    let c = crate::engine::calibrate::covariance_from_values(&out.response.covariance).unwrap();
    for i in 0..3 {
        assert_eq!(c[(i, i)].sqrt(), out.response.stddev[i]);
    }
    assert_eq!(c.rows(3, 2).norm(), 0.0);
    assert!(c[(0, 1)] != 0.0 && c[(1, 2)] != 0.0, "correlations kept: {c}");
    assert_eq!((out.response.tip_radius, out.response.tip_radius_stddev), (0.0, 0.0));
    let after = st.on_raw_scan(&plate_msg(2, &m), true).unwrap();
    assert!(after.contour.calibrated);
    // Traced to the calibration that corrected it: the calibration message's stamp and scan.
    let cal = st.calibration_msg();
    assert_eq!((after.contour.calibration_stamp, after.contour.calibration_scan_id), (cal.header.stamp, 1));
    assert_ne!(cal.header.stamp, Time::ZERO);
    assert_eq!(st.stats.calibrations_applied, 1);
}

#[test]
fn malformed_scans_are_rejected_and_counted() {
    let mut st = NodeState::new("/t".into(), Parameters::default());
    let good = plate_msg(1, &Mounting::IDEAL);
    let cases: Vec<(RawScan, &str)> = vec![
        (RawScan { steps_per_revolution: 0, ..good.clone() }, "steps_per_revolution is 0"),
        (RawScan { counts: good.counts[..10].to_vec(), ..good.clone() }, "step has 400 entries but counts has 10"),
        (RawScan { step: vec![1, 2], counts: vec![1, 2], ..good.clone() }, "at least 3 are needed"),
        (RawScan { target: 9, ..good.clone() }, "target 9"),
        (RawScan { steps_per_revolution: u32::MAX, ..good.clone() }, "larger than the limit"),
        (
            RawScan { step: vec![0; MAX_SAMPLES + 1], counts: vec![0; MAX_SAMPLES + 1], ..good.clone() },
            "more than the limit",
        ),
        (RawScan { step: good.step.iter().map(|s| s + 400).collect(), ..good.clone() }, "is out of range"),
    ];
    for (i, (msg, want)) in cases.iter().enumerate() {
        let e = st.on_raw_scan(msg, true).unwrap_err();
        assert!(e.to_string().contains(want), "case {i}: {e}");
        assert_eq!(st.stats.scans_rejected, i as u64 + 1);
    }
    // A caller can tell the reasons apart.
    use crate::cell::intake::ScanRejected;
    let small = RawScan { step: vec![1, 2], counts: vec![1, 2], ..good.clone() };
    assert_eq!(st.on_raw_scan(&small, true).unwrap_err(), ScanRejected::TooSmall(2));
    assert!(matches!(
        st.on_raw_scan(&RawScan { steps_per_revolution: 0, ..good.clone() }, true),
        Err(ScanRejected::Samples(_))
    ));
    assert_eq!(st.stats.scans_rejected, cases.len() as u64 + 2);
    assert!(st.on_raw_scan(&good, true).is_ok());
    assert_eq!(st.stats.scans_received, cases.len() as u64 + 3);
}

#[test]
fn a_failed_calibration_keeps_the_old_one() {
    let mut st = NodeState::new("/t".into(), Parameters::default());
    let out = st.on_calibrate(&CalibrateRequest::default());
    assert!(!out.response.success);
    assert!(out.response.message.starts_with("no calibration-plate scan received yet"), "{}", out.response.message);
    assert_eq!(out.response.error_code, CalibrateResponse::ERROR_NO_PLATE_SCAN);
    let m = Mounting::new(0.01, 0.003, 0.001);
    st.on_raw_scan(&plate_msg(5, &m), true).unwrap();
    let ok = st.on_calibrate(&CalibrateRequest::default()).response;
    assert!(ok.success);
    assert_eq!(ok.error_code, CalibrateResponse::ERROR_NONE);
    assert_eq!(st.stats.last_fit_error, CalibrateResponse::ERROR_NONE);
    let in_force = st.params.calibration;
    // A wrong plate size: the fit is refused, the calibration stays.
    st.params.plate.side = 0.05;
    let out =
        st.on_calibrate(&CalibrateRequest { scan_id: 5, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(!out.response.success);
    assert!(out.response.message.contains("does not match the plate"), "{}", out.response.message);
    assert_eq!(out.response.error_code, CalibrateResponse::ERROR_RESIDUALS);
    assert_eq!(st.params.calibration, in_force);
    // The calibration status says the last calibrate failed, and why, by name.
    let diag = st.diagnostics(Now::system());
    let status = &diag.status[0];
    assert_eq!(status.level, DiagnosticStatus::WARN);
    assert!(status.message.starts_with("calibrated; the last calibrate failed: "), "{}", status.message);
    let value = |k: &str| status.values.iter().find(|kv| kv.key == k).map(|kv| kv.value.clone());
    assert_eq!(value("last_fit_error").as_deref(), Some("ERROR_RESIDUALS"));
    let out =
        st.on_calibrate(&CalibrateRequest { scan_id: 77, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert_eq!(out.response.message, "no calibration-plate scan with scan_id 77 (kept: 5)");
    assert_eq!(out.response.error_code, CalibrateResponse::ERROR_NO_PLATE_SCAN);
    let out = st.on_calibrate(&CalibrateRequest { plate_scan_ids: vec![5, 5], ..Default::default() });
    assert_eq!(out.response.error_code, CalibrateResponse::ERROR_BAD_REQUEST, "{}", out.response.message);
    assert_eq!(st.stats.calibrations_failed, 4);
}

/// Every `ERROR_*` constant the `.srv` declares has its name in the diagnostics, and the
/// codes are 0, 1, 2, ... in the order declared.
#[test]
fn error_codes_are_the_srvs() {
    let text = CalibrateResponse::DEFINITION.text();
    let declared: Vec<(String, String, String)> = crate::interfaces::definition::constants(text)
        .unwrap()
        .into_iter()
        .filter(|(_, name, _)| name.starts_with("ERROR_"))
        .collect();
    assert!(declared.len() >= 14, "{declared:?}");
    for (i, (ty, name, value)) in declared.iter().enumerate() {
        assert_eq!(ty, "uint16");
        assert_eq!(value.parse::<u16>().unwrap(), i as u16, "{name}");
        assert_eq!(super::calibrate::error_name(i as u16), name.as_str());
    }
    assert_eq!(super::calibrate::error_name(999), "ERROR_999");
}

#[test]
fn dry_runs_change_nothing_and_persisting_failures_are_reported() {
    let m = Mounting::new(0.01, 0.003, 0.001);
    let mut st = NodeState::new("/t".into(), Parameters::default());
    st.on_raw_scan(&plate_msg(1, &m), true).unwrap();
    let out = st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: true, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(out.response.success && out.applied.is_none());
    assert!(!st.params.calibration_valid);
    st.params.params_file = "/nonexistent-dir/x/params.yaml".into();
    let out =
        st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(!out.response.success);
    assert_eq!(out.response.error_code, CalibrateResponse::ERROR_NOT_PERSISTED);
    assert!(
        out.response.message.starts_with(
            "calibration applied in memory but not persisted: cannot write /nonexistent-dir/x/params.yaml: "
        ),
        "{}",
        out.response.message
    );
    assert!(st.params.calibration_valid);
    let e = st.persist().unwrap_err();
    assert!(
        matches!(&e, PersistError::Params { path, source }
            if path == "/nonexistent-dir/x/params.yaml" && source.kind() == std::io::ErrorKind::NotFound),
        "{e:?}"
    );
}

/// A lens scan (noise-free ellipse) by a tracer with mounting `m`, and where each
/// sample really touched.
fn lens_msg(scan_id: u32, m: &Mounting) -> (RawScan, Vec<Vector2<f64>>) {
    use crate::engine::shape::Ellipse;
    let lens = Ellipse { center: Vector2::new(0.001, -0.002), a: 0.03, b: 0.018, angle: 0.3 };
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    let sim = simulate(&lens, m, &SimOptions::default(), &mut rng).unwrap();
    let msg = RawScan::of_simulation(scan_id, RawScan::TARGET_LENS, &sim, 1e-6);
    (msg, sim.truth)
}

#[test]
fn an_encoder_scale_error_is_refused_by_full_and_corrected_with_full_scale() {
    // The encoder reads 0.25 % long.
    let m = Mounting::new(0.02, 0.004, 0.001).with_scale(1.0 / 1.0025);
    let mut st = NodeState::new("/t".into(), Parameters::default());
    st.on_raw_scan(&plate_msg(3, &m), true).unwrap();
    let out =
        st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(!out.response.success);
    assert!(out.response.message.contains("encoder scale looks off"), "{}", out.response.message);
    assert!(!st.params.calibration_valid, "the failed fit applied nothing");
    let diag = st.diagnostics(Now::at(UNIX_EPOCH));
    assert_eq!(diag.status[0].level, DiagnosticStatus::WARN);
    assert!(diag.status[0].message.contains("encoder scale looks off"), "{}", diag.status[0].message);

    st.params.set("model", &crate::params::ParamValue::String("full_scale".into())).unwrap();
    let out =
        st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(out.response.success, "{}", out.response.message);
    let r = &out.response;
    assert!((r.scale - m.scale).abs() < 5.0 * r.scale_stddev && r.scale_stddev > 0.0, "{r:?}");
    // The whole covariance: the scale's row is there, and dL and the scale move together
    // (a longer encoder reading or a larger zero error look alike at the plate's radius).
    let c = crate::engine::calibrate::covariance_from_values(&r.covariance).unwrap();
    assert_eq!(c[(3, 3)].sqrt(), r.scale_stddev);
    assert!(c[(2, 3)].abs() / (c[(2, 2)] * c[(3, 3)]).sqrt() > 0.9, "{c}");
    assert_eq!(c.row(4).norm(), 0.0, "no tip radius fitted");
    assert_eq!(st.params.calibration.scale, r.scale);
    assert_eq!(out.applied.unwrap().scale, r.scale);

    // A lens traced by the same tracer comes out true to within the counts' rounding
    // (1 µm) and the calibration's noise (2 µm on the plate).
    let (lens, truth) = lens_msg(4, &m);
    let rms_off_truth = |st: &mut NodeState| {
        let c = st.on_raw_scan(&lens, false).unwrap().contour;
        assert!(c.calibrated);
        let ss: f64 = c.points.iter().zip(&truth).map(|(p, q)| (p.x - q.x).powi(2) + (p.y - q.y).powi(2)).sum();
        (ss / truth.len() as f64).sqrt()
    };
    let rms = rms_off_truth(&mut st);
    assert!(rms < 3e-6, "{rms:e}");
    // With the scale left out the same lens is tens of µm off.
    st.params.set("calibration.scale", &crate::params::ParamValue::Double(1.0)).unwrap();
    let rms = rms_off_truth(&mut st);
    assert!(rms > 30e-6, "{rms:e}");
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("tracer_calib_state_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn applied_calibrations_are_recorded_naming_the_one_they_replaced() {
    let dir = temp_dir("records");
    let history = dir.join("p.history.jsonl");
    let params = Parameters {
        params_file: dir.join("p.yaml").display().to_string(),
        history_file: history.display().to_string(),
        ..Parameters::default()
    };
    let mut st = NodeState::new("/cell1/tracer".into(), params.clone());
    assert!(!st.calibration_msg().valid);
    let m = Mounting::new(0.02, 0.004, 0.001);
    st.on_raw_scan(&plate_msg(1, &m), true).unwrap();
    let dry = st.on_calibrate(&CalibrateRequest { scan_id: 1, dry_run: true, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(dry.response.success);
    assert!(!history.exists(), "a dry run is not recorded");
    let first =
        st.on_calibrate(&CalibrateRequest { scan_id: 1, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(first.response.success, "{}", first.response.message);
    assert!(!first.response.message.contains("moved"), "nothing to move from: {}", first.response.message);
    st.on_raw_scan(&plate_msg(2, &m), true).unwrap();
    let second =
        st.on_calibrate(&CalibrateRequest { scan_id: 2, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(second.response.success);
    assert!(
        second.response.message.contains("moved since the previous calibration: alpha0"),
        "{}",
        second.response.message
    );
    let h = records::file::read(&history).unwrap();
    assert_eq!(h.records.len(), 2);
    let (a, b) = (&h.records[0], &h.records[1]);
    assert_eq!((a.scan_id, b.scan_id), (1, 2));
    assert_eq!(a.node, "/cell1/tracer");
    assert_eq!(a.model, "full");
    assert_eq!(a.previous, None);
    assert_eq!(b.previous, Some(Previous::from(a.mounting())));
    assert_eq!(b.alpha0, second.response.alpha0);
    assert_eq!(b.stddev, second.response.stddev);
    assert_eq!(b.iterations, second.response.iterations);
    assert_eq!((b.covariance.len(), b.tip_radius), (25, 0.0));
    assert_eq!(b.covariance, second.response.covariance);
    assert_eq!(st.params.covariance, b.covariance, "the covariance in force is a parameter");
    // The calibration message is the second, stamped with its record's ROS time (the
    // system time here: within the millisecond of its `time`).
    let msg = st.calibration_msg();
    assert!(msg.valid && msg.scan_id == 2 && msg.alpha0 == b.alpha0 && msg.stddev == b.stddev);
    assert_eq!(msg.covariance, b.covariance);
    assert_eq!(msg.header.frame_id, "tracer_axis");
    assert_eq!(Some(msg.header.stamp.to_nanos()), b.ros_time.map(records::RosTime::to_nanos));
    let stamp = UNIX_EPOCH + Duration::from_nanos(msg.header.stamp.to_nanos() as u64);
    assert!(stamp.duration_since(b.applied_at().unwrap()).unwrap() < Duration::from_millis(1));
    // A contour corrected now joins the message and the record on stamp and scan id.
    let traced = st.on_raw_scan(&plate_msg(3, &m), false).unwrap().contour;
    assert_eq!((traced.calibration_stamp, traced.calibration_scan_id), (msg.header.stamp, b.scan_id));
    assert_eq!(Some(traced.calibration_stamp.to_nanos()), b.ros_time.map(records::RosTime::to_nanos));

    // A restart with the parameters the node persisted: the history supplies the fit.
    let file = params_file::read(Path::new(&params.params_file)).unwrap();
    let mut reloaded = Parameters::default();
    reloaded.apply_file(&file, "/cell1/tracer", "p.yaml").unwrap();
    assert_eq!(reloaded.history_file, "", "at its default, beside the params file: not written");
    assert_eq!(reloaded.covariance, b.covariance, "persisted, read back to the bit");
    let mut again = NodeState::new("/cell1/tracer".into(), reloaded.clone());
    again.adopt_history(&h);
    assert_eq!(again.calibration_msg(), msg);
    assert_eq!(again.in_force.source, "history");
    assert!(again.drift.is_some());
    // Parameters that do not match the last record: it supplies nothing.
    reloaded.calibration.alpha0 += 1e-3;
    let mut other = NodeState::new("/cell1/tracer".into(), reloaded);
    other.adopt_history(&h);
    let m = other.calibration_msg();
    assert_eq!((m.scan_id, m.stddev.len(), m.rms_residual, other.in_force.source), (0, 0, 0.0, "parameters"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_history_that_cannot_be_written_fails_the_call_and_persists_nothing() {
    let dir = temp_dir("nohistory");
    let params_path = dir.join("p.yaml");
    let params = Parameters {
        params_file: params_path.display().to_string(),
        history_file: dir.join("missing/dir/h.jsonl").display().to_string(),
        ..Parameters::default()
    };
    let mut st = NodeState::new("/t".into(), params);
    st.on_raw_scan(&plate_msg(1, &Mounting::new(0.01, 0.003, 0.001)), true).unwrap();
    let out =
        st.on_calibrate(&CalibrateRequest { scan_id: 1, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(!out.response.success);
    assert!(
        out.response.message.starts_with("calibration applied in memory but not persisted: cannot append to"),
        "{}",
        out.response.message
    );
    assert!(out.response.message.contains("missing/dir/h.jsonl"), "{}", out.response.message);
    assert!(st.params.calibration_valid && out.applied.is_some(), "in force in memory");
    assert!(!params_path.exists(), "the parameters are not persisted without their record");
    assert!(st.calibration_msg().valid);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn diag_value(d: &DiagnosticArray, key: &str) -> String {
    d.status[0].values.iter().find(|kv| kv.key == key).map(|kv| kv.value.clone()).unwrap()
}

#[test]
fn overdue_and_drifted_calibrations_warn_on_diagnostics() {
    let m = Mounting::new(0.02, 0.004, 0.001);
    let mut st = NodeState::new("/t".into(), Parameters::default());
    st.on_raw_scan(&plate_msg(1, &m), true).unwrap();
    assert!(
        st.on_calibrate(&CalibrateRequest { scan_id: 1, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] })
            .response
            .success
    );
    let applied = st.in_force.applied_at;
    let at = |days: f64| Now::at(applied + Duration::from_secs_f64(days * 86_400.0));
    let d = st.diagnostics(at(40.0));
    assert_eq!(d.status[0].level, DiagnosticStatus::OK, "no limit by default: {}", d.status[0].message);
    assert_eq!(diag_value(&d, "calibration_age_days"), "40.000");
    assert_eq!(diag_value(&d, "calibration_time"), records::format_utc(applied));
    st.params.max_age_days = 30.0;
    assert_eq!(st.diagnostics(at(29.9)).status[0].level, DiagnosticStatus::OK);
    let d = st.diagnostics(at(30.5));
    assert_eq!(d.status[0].level, DiagnosticStatus::WARN);
    assert!(d.status[0].message.contains("calibration overdue: applied"), "{}", d.status[0].message);
    assert!(d.status[0].message.contains("calibration.max_age_days is 30"), "{}", d.status[0].message);
    st.params.max_age_days = 0.0;

    // The tracer knocked: d moved by 0.1 mm, far beyond its few-µm uncertainty.
    let knocked = Mounting::new(0.02, 0.0041, 0.001);
    st.on_raw_scan(&plate_msg(2, &knocked), true).unwrap();
    let out =
        st.on_calibrate(&CalibrateRequest { scan_id: 2, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] });
    assert!(out.response.success, "{}", out.response.message);
    assert!(out.response.message.contains("more than calibration.drift_warn_sigma = 10"), "{}", out.response.message);
    let d = st.diagnostics(at(0.0));
    assert_eq!(d.status[0].level, DiagnosticStatus::WARN);
    assert!(d.status[0].message.contains("the last calibration moved d by"), "{}", d.status[0].message);
    assert!(diag_value(&d, "drift_sigma").parse::<f64>().unwrap() > 10.0);
    // A limit of 0: no drift warning.
    st.params.drift_warn_sigma = 0.0;
    assert_eq!(st.diagnostics(at(0.0)).status[0].level, DiagnosticStatus::OK);
}

#[test]
fn a_calibration_set_by_parameters_is_published_as_such() {
    let mut st = NodeState::new("/t".into(), Parameters::default());
    st.params.set("calibration.alpha0", &crate::params::ParamValue::Double(0.01)).unwrap();
    st.params.set("calibration.valid", &crate::params::ParamValue::Bool(true)).unwrap();
    let t = UNIX_EPOCH + Duration::from_secs(1_800_000_000);
    st.calibration_set_by_parameters(Now::at(t));
    let msg = st.calibration_msg();
    assert!(msg.valid && msg.alpha0 == 0.01 && msg.scan_id == 0 && msg.stddev.is_empty());
    assert_eq!((msg.header.stamp.to_nanos(), msg.model.as_str(), msg.scale), (1_800_000_000_000_000_000, "full", 1.0));
}

/// Under simulated time the stamps are the ROS clock's, the record keeps both clocks, and
/// the calibration's age is system time.
#[test]
fn sim_time_stamps_and_records() {
    let dir = std::env::temp_dir().join(format!("tracer_calib_cell_sim_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let history = dir.join("h.jsonl");
    let _ = std::fs::remove_file(&history);
    let params =
        Parameters { history_file: history.display().to_string(), use_sim_time: true, ..Parameters::default() };
    let mut st = NodeState::new("/t".into(), params);
    assert_eq!(st.calibration_msg().header.stamp.to_nanos(), 0, "no /clock yet: ROS time 0");
    let m = Mounting::new(0.02, 0.004, 0.001);
    st.on_raw_scan(&plate_msg(1, &m), true).unwrap();
    let wall = UNIX_EPOCH + Duration::from_secs(1_800_000_000);
    let sim = Time::from_nanos(5_003_250_000_000);
    assert!(
        st.on_calibrate_at(
            &CalibrateRequest { scan_id: 1, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] },
            Now { wall, ros: sim }
        )
        .response
        .success
    );
    assert_eq!(st.calibration_msg().header.stamp, sim);
    let r = &records::file::read(&history).unwrap().records[0];
    assert_eq!((r.applied_at(), r.ros_time), (Some(wall), Some(records::RosTime { sec: 5003, nanosec: 250_000_000 })));
    let later = Now { wall: wall + Duration::from_secs(86_400), ros: Time::from_nanos(5_010_000_000_000) };
    let d = st.diagnostics(later);
    assert_eq!(d.header.stamp, later.ros);
    assert_eq!(diag_value(&d, "calibration_age_days"), "1.000");
    assert_eq!(diag_value(&d, "ros_time"), "5010.000");
    // A restart reads the ROS time back from the record.
    let mut again = NodeState::new("/t".into(), st.params.clone());
    again.adopt_history(&records::file::read(&history).unwrap());
    assert_eq!(again.calibration_msg().header.stamp, sim);
    // No /clock for a while: the node says so.
    st.clock_problem = "use_sim_time is true and no /clock ...".into();
    let d = st.diagnostics(later);
    assert_eq!(d.status[0].level, DiagnosticStatus::WARN);
    assert!(d.status[0].message.contains("no /clock"), "{}", d.status[0].message);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_managed_node_holds_scans_until_active_and_reads_its_history_when_configured() {
    use super::lifecycle::{Lifecycle, Request, State};
    let dir = temp_dir("managed");
    let history = dir.join("m.history.jsonl");
    let params = Parameters {
        params_file: dir.join("m.yaml").display().to_string(),
        history_file: history.display().to_string(),
        ..Parameters::default()
    };
    // An unmanaged node records a calibration; its parameters are the managed node's.
    let m = Mounting::new(0.02, 0.004, 0.001);
    let mut first = NodeState::new("/m".into(), params.clone());
    first.on_raw_scan(&plate_msg(1, &m), true).unwrap();
    assert!(
        first
            .on_calibrate(&CalibrateRequest { scan_id: 1, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] })
            .response
            .success
    );
    assert!(first.is_active() && first.calibrate_refused().is_none());
    let params = first.params.clone();

    let mut st = NodeState::new("/m".into(), params);
    st.lifecycle = Some(Lifecycle::new());
    assert!(!st.is_active());
    assert_eq!(st.in_force.source, "parameters", "unconfigured: the history is not read yet");
    st.hold_raw_scan();
    assert_eq!((st.stats.scans_received, st.stats.scans_held, st.stats.contours_published), (1, 1, 0));
    let refused = st.calibrate_refused().unwrap();
    assert!(!refused.success && refused.message.contains("the node is unconfigured (managed)"), "{}", refused.message);
    assert_eq!(refused.error_code, CalibrateResponse::ERROR_NOT_ACTIVE);
    let d = st.diagnostics(Now::system());
    assert_eq!(diag_value(&d, "lifecycle_state"), "unconfigured");
    assert_eq!(diag_value(&d, "scans_held"), "1");
    assert!(d.status[0].message.contains("lifecycle state unconfigured: scans are taken"), "{}", d.status[0].message);

    let label = |l: &'static str| Request { id: 0, label: l };
    let mut read = None;
    let walk = st.change_lifecycle(&label("configure"), Now::system(), &mut read).unwrap();
    assert!(walk.success);
    assert!(read.unwrap().note.contains("1 calibration record(s)"));
    assert_eq!((st.in_force.source, st.history_records), ("history", 1), "configure read the history");
    // Not offered from inactive: refused, nothing changes.
    let e = st.change_lifecycle(&label("configure"), Now::system(), &mut None).unwrap_err();
    assert!(matches!(&e, LifecycleError::NotRegistered(n) if n.current == State::INACTIVE), "{e:?}");
    assert!(e.to_string().contains("from current state inactive"), "{e}");
    assert_eq!(st.lifecycle.as_ref().unwrap().current(), State::INACTIVE);
    st.change_lifecycle(&label("activate"), Now::system(), &mut None).unwrap();
    assert!(st.is_active() && st.calibrate_refused().is_none());
    assert_eq!(st.on_raw_scan(&plate_msg(2, &m), true).unwrap().contour.scan_id, 2);
    st.change_lifecycle(&label("deactivate"), Now::system(), &mut None).unwrap();
    st.change_lifecycle(&label("cleanup"), Now::system(), &mut None).unwrap();
    assert_eq!((st.in_force.source, st.history_records), ("parameters", 0), "cleanup forgot what configure read");
    assert!(st.calibrate_refused().unwrap().message.contains("unconfigured"));
    st.change_lifecycle(&label("shutdown"), Now::system(), &mut None).unwrap();
    assert_eq!(st.lifecycle_label(), "finalized");
    assert!(st.calibrate_refused().unwrap().message.contains("restart it"));
    // An unmanaged node has no life cycle to change.
    let e = first.change_lifecycle(&label("configure"), Now::system(), &mut None).unwrap_err();
    assert_eq!(e, LifecycleError::NotManaged);
    assert_eq!(e.to_string(), "the node is not managed (managed: false)");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn peers_refused_authentication_are_reported_only_when_secure() {
    let mut st = NodeState::new("/t".into(), Parameters::default());
    let now = Now::at(UNIX_EPOCH);
    let d = st.diagnostics(now);
    assert!(d.status[0].values.iter().all(|kv| kv.key != "peers_refused_authentication"), "security off: no key");
    st.stats.peers_refused_authentication = Some(0);
    let d = st.diagnostics(now);
    assert_eq!(diag_value(&d, "peers_refused_authentication"), "0");
    assert!(!d.status[0].message.contains("refused"), "{}", d.status[0].message);
    st.stats.peers_refused_authentication = Some(2);
    let d = st.diagnostics(now);
    assert_eq!(diag_value(&d, "peers_refused_authentication"), "2");
    assert_eq!(d.status[0].level, DiagnosticStatus::WARN);
    assert!(d.status[0].message.contains("2 peer(s) refused authentication"), "{}", d.status[0].message);
}

/// A scan of `shape` by a tracer with mounting `m` and a tip of radius `tip`, as the
/// driver would publish it, with the surface it touched.
fn traced_msg(
    scan_id: u32,
    target: u8,
    shape: &impl crate::engine::shape::Shape,
    m: &Mounting,
    tip: f64,
) -> (RawScan, Vec<Vector2<f64>>) {
    traced_in_groove(scan_id, target, shape, m, tip, crate::engine::stylus::PLAIN_BORE)
}

/// [`traced_msg`], from inside in a V-groove of included angle `groove` (rad).
fn traced_in_groove(
    scan_id: u32,
    target: u8,
    shape: &impl crate::engine::shape::Shape,
    m: &Mounting,
    tip: f64,
    groove: f64,
) -> (RawScan, Vec<Vector2<f64>>) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(u64::from(scan_id));
    let inside = matches!(target, RawScan::TARGET_FRAME | RawScan::TARGET_RING_GAUGE);
    let opt = SimOptions { noise: 2e-6, tip_radius: tip, inside, groove_angle: groove, ..SimOptions::default() };
    let sim = simulate(shape, m, &opt, &mut rng).unwrap();
    let msg = RawScan::of_simulation(scan_id, target, &sim, 1e-6);
    (msg, sim.truth)
}

fn ring_gauge() -> crate::engine::shape::Ellipse {
    crate::engine::shape::Ellipse { center: Vector2::new(-0.0004, 0.0002), a: 0.020, b: 0.020, angle: 0.0 }
}

/// `full_tip` through the cell: the most recent ring-gauge scan (or the one named)
/// with the plate; the tip radius fitted, in force, in the response, the record and the
/// `Calibration` message; frames and lenses then corrected to the surface the tip touched.
#[test]
fn the_tip_is_fitted_from_a_ring_gauge_and_contours_are_of_the_touched_surface() {
    let m = Mounting::new(0.02, 0.004, 0.001);
    let tip = 0.0005;
    let mut p = Parameters { model: crate::engine::ModelKind::FullTip, ..Parameters::default() };
    let mut st = NodeState::new("/cell1/tracer".into(), p.clone());
    let plate = PlateSpec::default().at(Vector2::new(0.0005, -0.0003));
    st.on_raw_scan(&traced_msg(1, RawScan::TARGET_CALIBRATION_PLATE, &plate, &m, tip).0, false).unwrap();
    let req = CalibrateRequest { scan_id: 0, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] };
    // No ring.diameter, then no ring-gauge scan: refused, naming what is missing.
    let out = st.on_calibrate(&req);
    assert!(!out.response.success && out.response.message.contains("ring.diameter"), "{}", out.response.message);
    p.ring_diameter = 0.040;
    st.params.ring_diameter = 0.040;
    let out = st.on_calibrate(&req);
    assert!(!out.response.success && out.response.message.contains("TARGET_RING_GAUGE"), "{}", out.response.message);
    assert!(!st.params.calibration_valid);
    // A ring-gauge scan, and a second one of a wrong ring (a plate) named by ring_scan_id.
    st.on_raw_scan(&traced_msg(2, RawScan::TARGET_RING_GAUGE, &ring_gauge(), &m, tip).0, false).unwrap();
    st.on_raw_scan(&traced_msg(3, RawScan::TARGET_RING_GAUGE, &plate, &m, tip).0, false).unwrap();
    let out = st.on_calibrate(&CalibrateRequest { ring_scan_id: 3, ..req.clone() });
    assert!(!out.response.success && out.response.message.contains("ring"), "{}", out.response.message);
    assert!(!st.params.calibration_valid, "a failed fit applies nothing");
    let out = st.on_calibrate(&CalibrateRequest { ring_scan_id: 2, ..req });
    let r = &out.response;
    assert!(r.success, "{}", r.message);
    assert!(r.message.contains("scans 1 and 2 (ring gauge)"), "{}", r.message);
    assert!(
        (r.tip_radius - tip).abs() < 4.0 * r.tip_radius_stddev + 1e-7,
        "{} ± {}",
        r.tip_radius,
        r.tip_radius_stddev
    );
    assert!(r.tip_radius_stddev > 0.0 && r.tip_radius_stddev < 5e-6);
    let c = crate::engine::calibrate::covariance_from_values(&r.covariance).unwrap();
    assert_eq!(c[(4, 4)].sqrt(), r.tip_radius_stddev);
    assert!((r.delta_l - m.delta_l).abs() < 1e-5, "dL {} for {}", r.delta_l, m.delta_l);
    assert_eq!(st.params.tip_radius, r.tip_radius);
    assert_eq!(st.calibration_msg().tip_radius, r.tip_radius);
    // A frame and a lens, traced with the tip: their contours are of the touched surface.
    let frame = crate::engine::shape::RoundedRect {
        center: Vector2::new(0.001, 0.0),
        half_w: 0.025,
        half_h: 0.015,
        radius: 0.008,
    };
    let lens = crate::engine::shape::Ellipse { center: Vector2::new(0.0, 0.001), a: 0.026, b: 0.017, angle: 0.3 };
    let (frame_msg, frame_truth) = traced_msg(4, RawScan::TARGET_FRAME, &frame, &m, tip);
    let (lens_msg, lens_truth) = traced_msg(5, RawScan::TARGET_LENS, &lens, &m, tip);
    for (msg, truth) in [(frame_msg, frame_truth), (lens_msg, lens_truth)] {
        let c = st.on_raw_scan(&msg, false).unwrap().contour;
        let worst = c.points.iter().zip(&truth).map(|(p, t)| (Vector2::new(p.x, p.y) - t).norm()).fold(0.0, f64::max);
        assert!(worst < 30e-6, "target {}: a point {:.1} µm from the surface touched", msg.target, worst * 1e6);
        // Its size figures (engine::size), within their U95 of the exact ones.
        let want = if msg.target == RawScan::TARGET_FRAME { frame.exact_sizes() } else { lens.exact_sizes() };
        let got = [c.circumference, c.box_width, c.box_height, c.effective_diameter];
        for f in 0..4 {
            assert!(c.size_u95[f] > 0.0 && c.size_u95[f] < 30e-6, "target {}: U95 {:?}", msg.target, c.size_u95);
            assert!(
                (got[f] - want[f]).abs() <= c.size_u95[f],
                "target {}: figure {f} {} for {} ± {}",
                msg.target,
                got[f],
                want[f],
                c.size_u95[f]
            );
        }
        assert_eq!(c.radii_u95.len(), c.radii.len());
    }
    // A scan that does not go all the way round has no size figures.
    let (mut half, _) = traced_msg(6, RawScan::TARGET_LENS, &lens, &m, tip);
    half.step.truncate(200);
    half.counts.truncate(200);
    let c = st.on_raw_scan(&half, false).unwrap().contour;
    assert_eq!((c.circumference, c.size_u95, c.radii_u95.len()), (0.0, [0.0; 4], 0));
}

/// A plate scan of a turntable whose angle is off once and twice a turn, the plate turned
/// by `turn` (counter-clockwise).
fn turned_plate_msg(scan_id: u32, m: &Mounting, turn: f64) -> RawScan {
    let deg = 1f64.to_radians();
    let opt = SimOptions {
        noise: 2e-6,
        angle_harmonics: [(1, 0.05 * deg, 0.0), (2, 0.0, 0.02 * deg), (0, 0.0, 0.0)],
        ..SimOptions::default()
    };
    plate_msg_with(scan_id, &Mounting { alpha0: m.alpha0 - turn, ..*m }, &opt)
}

#[test]
fn two_placements_fit_the_angle_harmonics_and_every_layer_carries_them() {
    let dir = std::env::temp_dir().join(format!("tracer_calib_cell_angle_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let params = Parameters {
        params_file: dir.join("p.yaml").display().to_string(),
        history_file: dir.join("h.jsonl").display().to_string(),
        angle_harmonics: crate::engine::angle::HarmonicOrders::new(&[1, 2, 4]).unwrap(),
        ..Parameters::default()
    };
    let mut st = NodeState::new("/cell1/tracer".into(), params.clone());
    let m = Mounting::new(0.02, 0.004, 0.001);
    st.on_raw_scan(&turned_plate_msg(1, &m, 0.0), false).unwrap();
    st.on_raw_scan(&turned_plate_msg(2, &m, 22.5f64.to_radians()), false).unwrap();
    // One placement cannot tell order 4: refused, saying what to add; nothing applied.
    let one = st.on_calibrate(&CalibrateRequest { scan_id: 1, ..CalibrateRequest::default() });
    assert!(!one.response.success && one.response.message.contains("22.5°"), "{}", one.response.message);
    assert!(!st.params.calibration_valid);
    let twice = st.on_calibrate(&CalibrateRequest { plate_scan_ids: vec![1, 1], ..CalibrateRequest::default() });
    assert!(twice.response.message.contains("twice"), "{}", twice.response.message);
    let out = st.on_calibrate(&CalibrateRequest { plate_scan_ids: vec![1, 2], ..CalibrateRequest::default() });
    let r = &out.response;
    assert!(r.success, "{}", r.message);
    assert!(r.message.contains("scans 1, 2") && r.message.contains("2 placements"), "{}", r.message);
    assert_eq!(r.angle_harmonics, [1, 2, 4]);
    assert_eq!(r.covariance_names.len(), 11);
    assert_eq!(r.covariance_names[5..7], ["angle_c1".to_string(), "angle_s1".to_string()]);
    assert_eq!(r.covariance.len(), 121);
    let c1 = r.angle_coefficients[0];
    let u1 = r.covariance[5 * 11 + 5].sqrt();
    assert!((c1 - 0.05f64.to_radians()).abs() < 4.0 * u1, "{c1} ± {u1}");
    // In force: the parameters, the calibration message, the history (format 3).
    assert_eq!(st.params.angle_coefficients, r.angle_coefficients);
    assert_eq!(st.params.covariance_names, r.covariance_names);
    let msg = st.calibration_msg();
    assert_eq!(
        (msg.angle_harmonics.clone(), msg.angle_coefficients.clone()),
        (vec![1, 2, 4], r.angle_coefficients.clone())
    );
    assert_eq!(msg.covariance_names, r.covariance_names);
    let h = records::file::read(&dir.join("h.jsonl")).unwrap();
    let rec = h.records.last().unwrap();
    assert_eq!((rec.format, rec.plate_scan_ids.clone()), (3, vec![2]));
    assert_eq!(rec.angle_coefficients, r.angle_coefficients);
    // Persisted, and read back whole.
    let file = params_file::read(Path::new(&params.params_file)).unwrap();
    let mut reloaded = Parameters::default();
    reloaded.apply_file(&file, "/cell1/tracer", "p.yaml").unwrap();
    assert_eq!(reloaded.angle_in_force(), st.params.angle_in_force());
    assert_eq!(reloaded.covariance, st.params.covariance);
    // A plate scan corrected with the angle in force is the plate: its points within a
    // few micrometres of the plate's outline.
    let contour = st.on_raw_scan(&turned_plate_msg(3, &m, 0.0), false).unwrap().contour;
    let plate = PlateSpec::default().at(Vector2::new(0.0005, -0.0003));
    let worst = contour
        .points
        .iter()
        .map(|p| {
            let q = Vector2::new(p.x, p.y);
            let centre = plate.center;
            let hit = plate.exit(centre, (q - centre).normalize()).unwrap();
            ((q - centre).norm() - hit.t).abs()
        })
        .fold(0.0, f64::max);
    assert!(worst < 15e-6, "worst point {worst}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The stylus in a V-groove (engine::stylus): calibrated on the plate and a grooved ring
/// gauge whose groove is entered, the cell corrects a frame traced in a groove of another
/// angle to its groove's bottom, and states the groove angle's uncertainty in its U95.
/// A grooved ring entered as a plain bore is refused as that.
#[test]
fn a_frame_traced_in_its_groove_is_its_groove_bottom() {
    let m = Mounting::new(0.02, 0.004, 0.001);
    let tip = 0.0005;
    let (ring_groove, frame_groove) = (110f64.to_radians(), 116f64.to_radians());
    let plate = PlateSpec::default().at(Vector2::new(0.0005, -0.0003));
    let frame = crate::engine::shape::RoundedRect {
        center: Vector2::new(0.001, 0.0),
        half_w: 0.026,
        half_h: 0.016,
        radius: 0.006,
    };
    let p = Parameters { model: crate::engine::ModelKind::FullTip, ring_diameter: 0.040, ..Parameters::default() };
    let mut st = NodeState::new("/cell1/tracer".into(), p);
    st.on_raw_scan(&traced_msg(1, RawScan::TARGET_CALIBRATION_PLATE, &plate, &m, tip).0, false).unwrap();
    st.on_raw_scan(&traced_in_groove(2, RawScan::TARGET_RING_GAUGE, &ring_gauge(), &m, tip, ring_groove).0, false)
        .unwrap();
    let req = CalibrateRequest { scan_id: 0, dry_run: false, ring_scan_id: 0, plate_scan_ids: vec![] };
    // Entered as a plain bore: refused, naming the groove the scans agree with.
    let out = st.on_calibrate(&req);
    assert!(!out.response.success, "{}", out.response.message);
    assert!(out.response.message.contains("ring.groove_angle is 180.0° (a plain bore)"), "{}", out.response.message);
    assert!(!st.params.calibration_valid);
    st.params.ring_groove_angle = ring_groove;
    let out = st.on_calibrate(&req);
    assert!(out.response.success, "{}", out.response.message);
    let r = &out.response;
    assert!(
        (r.tip_radius - tip).abs() < 4.0 * r.tip_radius_stddev + 1e-7,
        "{} ± {}",
        r.tip_radius,
        r.tip_radius_stddev
    );
    let (msg, truth) = traced_in_groove(3, RawScan::TARGET_FRAME, &frame, &m, tip, frame_groove);
    // How far each point is from the groove's bottom (the polygon of the points touched;
    // a chord's normal slides a point along the contour where its curvature changes).
    let worst = |c: &crate::interfaces::Contour| {
        let from_truth = |p: Vector2<f64>| {
            (0..truth.len())
                .map(|i| {
                    let (a, b) = (truth[i], truth[(i + 1) % truth.len()]);
                    let f = ((p - a).dot(&(b - a)) / (b - a).norm_squared()).clamp(0.0, 1.0);
                    (a + (b - a) * f - p).norm()
                })
                .fold(f64::INFINITY, f64::min)
        };
        c.points.iter().map(|p| from_truth(Vector2::new(p.x, p.y))).fold(0.0, f64::max)
    };
    // The frames' groove taken as a plain bore: the contour is the ball's wall, 90 µm in.
    let plain = st.on_raw_scan(&msg, false).unwrap().contour;
    assert!(worst(&plain) > 80e-6, "{}", worst(&plain));
    st.params.frame_groove = crate::engine::Groove::new(frame_groove, 0.0);
    let exact = st.on_raw_scan(&msg, false).unwrap().contour;
    assert!(worst(&exact) < 30e-6, "a point {:.1} µm from the groove's bottom", worst(&exact) * 1e6);
    let want = frame.exact_sizes();
    let got = [exact.circumference, exact.box_width, exact.box_height, exact.effective_diameter];
    for f in 0..4 {
        assert!(
            (got[f] - want[f]).abs() <= exact.size_u95[f],
            "figure {f}: {} for {} ± {}",
            got[f],
            want[f],
            exact.size_u95[f]
        );
    }
    // Known to a degree: 3.2 µm of radius a degree at 116°, 2 × 2π × 3.2 = 40 µm of C's U95.
    st.params.frame_groove = crate::engine::Groove::new(frame_groove, 1f64.to_radians());
    let wider = st.on_raw_scan(&msg, false).unwrap().contour;
    assert_eq!(wider.circumference, exact.circumference);
    let u =
        crate::engine::stylus::contact_offset_per_groove_angle(r.tip_radius, frame_groove).abs() * 1f64.to_radians();
    let alone = 2.0 * std::f64::consts::TAU * u;
    let c_u95 = (exact.size_u95[0].powi(2) + alone * alone).sqrt();
    assert!((wider.size_u95[0] - c_u95).abs() < 0.02 * c_u95, "{} for {}", wider.size_u95[0], c_u95);
    assert!(wider.radii_u95.iter().zip(&exact.radii_u95).all(|(w, e)| w > e));
}
