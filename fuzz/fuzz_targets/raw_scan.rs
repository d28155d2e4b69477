//! The node's whole handling of one raw scan, from the CDR bytes a DDS reader hands over:
//! decode, `NodeState::on_raw_scan` (validate, keep plate scans, correct, resample), and
//! for scans that validate (and are small enough) the calibration fit.
//!
//! Invariants besides "no panic":
//! - a published contour has one finite point per sample, `z = 0`, and its radii are
//!   either empty or `resample_points` finite, non-negative numbers; the polygon (when
//!   asked for) matches;
//! - a rejected scan is counted and leaves a message;
//! - a successful calibration has finite numbers and `alpha0` in `(-pi/4, pi/4]`; applied,
//!   it corrects the same scan to a finite contour, and the parameters the node would
//!   persist load back to the same values.
#![no_main]

use std::f64::consts::FRAC_PI_4;

use libfuzzer_sys::fuzz_target;
use tracer_calib::cell::{NodeState, intake};
use tracer_calib::engine::ModelKind;
use tracer_calib::engine::calibrate::{Calibration, Options, calibrate};
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::interfaces::{RawScan, from_cdr};
use tracer_calib::params::file as params_file;
use tracer_calib::params::{ParamValue, Parameters, names};

/// The fit is the expensive part: only scans up to this many samples are fitted.
const MAX_FIT_SAMPLES: usize = 2000;

fuzz_target!(|data: &[u8]| {
    let Ok(msg) = from_cdr::<RawScan>(data) else { return };

    // An uncalibrated node with the defaults, and a calibrated one.
    let mut plain = NodeState::new("/tracer_calibrator".into(), Parameters::default());
    handle(&mut plain, &msg, true);
    let params = Parameters {
        calibration: Mounting::new(0.03, 0.004, -0.001),
        calibration_valid: true,
        resample_points: 360,
        ..Parameters::default()
    };
    let mut calibrated = NodeState::new("/cell1/tracer".into(), params);
    let accepted = handle(&mut calibrated, &msg, false);
    assert_eq!(accepted, plain.stats.scans_rejected == 0, "the calibration changed whether a scan is accepted");

    // A node with parameters taken from fields the node only copies or ignores: `frame_id`
    // as "meters_per_count[,alpha0,offset,delta_l]", `resample_points` from `scan_id`.
    // Each goes through `Parameters::set`: only values the node would accept are used.
    let mut fitter = plain;
    if let Some(params) = tuned_params(&msg) {
        let mut tuned = NodeState::new("/tuned".into(), params);
        handle(&mut tuned, &msg, true);
        fitter = tuned;
    }

    // The fit (with the tuned node's encoder scale, if any), on scans that validate.
    let Ok(scan) = intake::to_scan(&msg, fitter.params.meters_per_count) else { return };
    if scan.len() > MAX_FIT_SAMPLES {
        return;
    }
    let model = if msg.scan_id & 1 == 0 { ModelKind::Full } else { ModelKind::Paper };
    let opts = Options { model, ..Options::default() };
    if let Ok(cal) = calibrate(&scan, &fitter.params.plate, &opts) {
        check_calibration(&cal, scan.len());
        // Applied as `/calibrate` does: the scans it corrects stay finite, and the
        // parameters it persists load back.
        fitter.params.calibration = cal.mounting;
        fitter.params.calibration_valid = true;
        handle(&mut fitter, &msg, true);
        let text = params_file::render(&fitter.fqn, &fitter.params.to_list(), "fuzz");
        let file = params_file::parse(&text, "fuzz").unwrap_or_else(|e| panic!("{e}\n{text}"));
        let mut back = Parameters::default();
        back.apply_file(&file, &fitter.fqn, "fuzz").unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(back, fitter.params, "the persisted calibration loads back differently:\n{text}");
    }
});

/// Parameters from `frame_id`, "meters_per_count[,alpha0,offset,delta_l]" (with the
/// calibration in force if it is given), and `resample_points` from `scan_id`.
fn tuned_params(msg: &RawScan) -> Option<Parameters> {
    let mut p = Parameters::default();
    let mut fields = msg.header.frame_id.split(',').map(|f| f.trim().parse::<f64>());
    let mpc = fields.next()?.ok()?;
    p.set(names::METERS_PER_COUNT, &ParamValue::Double(mpc)).ok()?;
    for name in [names::ALPHA0, names::OFFSET, names::DELTA_L] {
        match fields.next() {
            None => break,
            Some(v) => p.set(name, &ParamValue::Double(v.ok()?)).ok()?,
        }
        p.calibration_valid = true;
    }
    p.set(names::RESAMPLE_POINTS, &ParamValue::Integer(i64::from(msg.scan_id >> 1) % 4097)).ok()?;
    Some(p)
}

/// `on_raw_scan` and its invariants; whether the scan was accepted.
fn handle(st: &mut NodeState, msg: &RawScan, with_polygon: bool) -> bool {
    let before = st.stats.clone();
    match st.on_raw_scan(msg, with_polygon) {
        Ok(out) => {
            assert_eq!(st.stats.contours_published, before.contours_published + 1);
            let c = &out.contour;
            assert_eq!(c.points.len(), msg.step.len(), "one point per sample");
            assert_eq!(c.scan_id, msg.scan_id);
            assert_eq!(c.target, msg.target);
            assert_eq!(c.calibrated, st.params.calibration_valid);
            for p in &c.points {
                assert!(p.x.is_finite() && p.y.is_finite() && p.z == 0.0, "contour point {p:?}");
            }
            assert!(
                c.radii.is_empty() || c.radii.len() == st.params.resample_points,
                "{} radii, resample_points = {}",
                c.radii.len(),
                st.params.resample_points
            );
            for r in &c.radii {
                assert!(r.is_finite() && *r >= 0.0, "radius {r}");
            }
            assert_eq!(out.polygon.is_some(), with_polygon);
            if let Some(polygon) = &out.polygon {
                let poly = &polygon.polygon.points;
                assert_eq!(poly.len(), c.points.len());
                for p in poly {
                    assert!(p.x.is_finite() && p.y.is_finite() && p.z == 0.0, "polygon point {p:?}");
                }
                assert_eq!(polygon.header, c.header);
            }
            assert_eq!(c.header.frame_id, st.params.output_frame_id);
            true
        }
        Err(e) => {
            assert!(!e.is_empty());
            assert_eq!(st.stats.scans_rejected, before.scans_rejected + 1);
            assert!(st.stats.last_rejection.contains(&e));
            false
        }
    }
}

fn check_calibration(cal: &Calibration, n: usize) {
    let m = &cal.mounting;
    assert!(m.alpha0.is_finite() && m.offset.is_finite() && m.delta_l.is_finite(), "{m:?}");
    assert!(m.alpha0 > -FRAC_PI_4 && m.alpha0 <= FRAC_PI_4, "alpha0 {} outside (-pi/4, pi/4]", m.alpha0);
    assert!(cal.plate_center.iter().all(|v| v.is_finite()), "plate centre {:?}", cal.plate_center);
    assert!(cal.stddev.iter().all(|s| s.is_finite() && *s >= 0.0), "stddev {:?}", cal.stddev);
    assert!(cal.covariance.iter().all(|v| v.is_finite()), "covariance {:?}", cal.covariance);
    assert!(cal.rms_residual.is_finite() && cal.rms_residual >= 0.0, "rms {}", cal.rms_residual);
    assert!(cal.residuals.iter().all(|(r, _)| r.is_finite()), "a residual is not finite");
    assert_eq!(cal.residuals.len(), n);
    assert!(cal.samples_used <= n);
    assert_eq!(cal.residuals.iter().filter(|(_, used)| *used).count(), cal.samples_used);
    let _ = cal.summary();
}
