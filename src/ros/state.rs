//! What the node does with each message, without DDS: the node's state and its three
//! handlers (a raw scan, a calibrate request, a diagnostics tick). The wiring in
//! [`super::node`] only moves messages between DDS and these functions, so everything
//! here is tested without a network.

use std::collections::VecDeque;
use std::path::Path;
use std::time::{Duration, Instant};

use ros2_client::builtin_interfaces::Time;

use super::msgs::{
    CalibrateRequest, CalibrateResponse, Contour, DiagnosticArray, DiagnosticStatus, Header, KeyValue, Point, Point32,
    Polygon, PolygonStamped, RawScan,
};
use crate::engine::calibrate::{Calibration, calibrate};
use crate::engine::correct::{Corrector, PolarContour, default_max_gap};
use crate::engine::geometry::Mounting;
use crate::engine::scan::Scan;
use crate::params::{Parameters, file as params_file};

/// Largest scan accepted, in samples: far above any tracer (400-1000 steps a turn),
/// far below what would hurt the node.
pub const MAX_SAMPLES: usize = 1 << 16;
/// Largest `steps_per_revolution` accepted.
pub const MAX_STEPS_PER_REV: u32 = 1 << 20;
/// Largest coordinate of a corrected point, metres: what a `Point32` of the polygon holds.
/// (Any contour of a real tracer is a few centimetres.)
pub const MAX_COORDINATE: f64 = f32::MAX as f64;
/// Calibration-plate scans kept for `/calibrate`.
pub const PLATE_SCANS_KEPT: usize = 16;

/// Counters reported on `/diagnostics`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stats {
    pub scans_received: u64,
    pub scans_rejected: u64,
    pub contours_published: u64,
    pub calibrations_applied: u64,
    pub calibrations_failed: u64,
    pub last_rejection: String,
    pub last_fit_rms: Option<f64>,
    pub last_fit_message: String,
}

/// A plate scan kept for calibration.
#[derive(Debug, Clone)]
struct PlateScan {
    scan_id: u32,
    scan: Scan,
}

/// The node's state.
#[derive(Debug)]
pub struct NodeState {
    /// The node's fully qualified name: its section in the params file.
    pub fqn: String,
    pub params: Parameters,
    pub stats: Stats,
    corrector: Option<Corrector>,
    plates: VecDeque<PlateScan>,
    calibrated_at: Option<Instant>,
}

/// A corrected scan, ready to publish.
#[derive(Debug, Clone, PartialEq)]
pub struct Corrected {
    pub contour: Contour,
    /// The same points as a `PolygonStamped`, when asked for (someone listens).
    pub polygon: Option<PolygonStamped>,
}

/// What a calibrate request did.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateOutcome {
    pub response: CalibrateResponse,
    /// The new calibration, if one was applied (the node mirrors it into its ROS
    /// parameters).
    pub applied: Option<Mounting>,
}

impl NodeState {
    pub fn new(fqn: String, params: Parameters) -> Self {
        let calibrated_at = params.calibration_valid.then(Instant::now);
        NodeState { fqn, params, stats: Stats::default(), corrector: None, plates: VecDeque::new(), calibrated_at }
    }

    /// The checks of a raw scan that need no pass over its samples.
    fn check_limits(msg: &RawScan) -> Result<(), String> {
        if msg.target > RawScan::TARGET_LENS {
            return Err(format!("target {} is not one of TARGET_UNKNOWN..TARGET_LENS (0..3)", msg.target));
        }
        if msg.steps_per_revolution > MAX_STEPS_PER_REV {
            return Err(format!(
                "steps_per_revolution {} is larger than the limit of {MAX_STEPS_PER_REV}",
                msg.steps_per_revolution
            ));
        }
        if msg.step.len() > MAX_SAMPLES || msg.counts.len() > MAX_SAMPLES {
            return Err(format!(
                "the scan has {} samples, more than the limit of {MAX_SAMPLES}",
                msg.step.len().max(msg.counts.len())
            ));
        }
        if msg.step.len() < 3 {
            return Err(format!("the scan has {} samples, at least 3 are needed for a contour", msg.step.len()));
        }
        Ok(())
    }

    /// Check a raw scan; the error says what is wrong.
    pub fn check(&self, msg: &RawScan) -> Result<(), String> {
        Self::check_limits(msg)?;
        Scan::check_counts(msg.steps_per_revolution, &msg.step, &msg.counts, self.params.meters_per_count)
            .map_err(|e| e.to_string())
    }

    /// Check a raw scan and turn it into an engine scan; the error says what is wrong.
    pub fn validate(&self, msg: &RawScan) -> Result<Scan, String> {
        Self::check_limits(msg)?;
        Scan::from_counts(msg.steps_per_revolution, &msg.step, &msg.counts, self.params.meters_per_count)
            .map_err(|e| e.to_string())
    }

    /// Handle one raw scan: check it, keep it if it is of the plate, correct it, and
    /// build the `PolygonStamped` too if `with_polygon`. An error is a rejected scan
    /// (counted).
    ///
    /// A lens scan is corrected straight from the message's arrays: each point goes into
    /// the `Contour` and into the polar form the radii are resampled from as it comes
    /// (no engine `Scan`, no array of points: less memory to bring into cache for every
    /// scan).
    pub fn on_raw_scan(&mut self, msg: &RawScan, with_polygon: bool) -> Result<Corrected, String> {
        self.stats.scans_received += 1;
        // A plate scan is kept as an engine scan (for /calibrate); any other is only
        // checked. Either way its samples are checked once.
        let checked = if msg.target == RawScan::TARGET_CALIBRATION_PLATE {
            self.validate(msg).map(Some)
        } else {
            self.check(msg).map(|()| None)
        };
        if let Some(scan) = checked.map_err(|e| self.reject(msg, e))? {
            self.plates.retain(|p| p.scan_id != msg.scan_id);
            if self.plates.len() == PLATE_SCANS_KEPT {
                self.plates.pop_front();
            }
            self.plates.push_back(PlateScan { scan_id: msg.scan_id, scan });
        }
        let calibration = self.params.calibration_in_force();
        let mounting = calibration.unwrap_or(Mounting::IDEAL);
        let steps_per_rev = msg.steps_per_revolution;
        let corrector = match &self.corrector {
            Some(c) if *c.mounting() == mounting && c.steps_per_rev() == steps_per_rev => c,
            _ => self.corrector.insert(Corrector::new(mounting, steps_per_rev)),
        };
        let n = msg.step.len();
        let mut points = Vec::with_capacity(n);
        let mut polar = (self.params.resample_points > 0).then(|| PolarContour::with_capacity(n));
        // Extreme but accepted parameters (encoder.meters_per_count, calibration.offset,
        // calibration.delta_l up to 1e308) can put points beyond what a float32 polygon or
        // a radius (sqrt(x² + y²)) can hold: refuse the scan rather than publish inf/NaN.
        // (A plate scan is kept above all the same: it is what a recalibration needs.)
        let mut out_of_range = None;
        corrector.correct_counts(&msg.step, &msg.counts, self.params.meters_per_count, |p| {
            if out_of_range.is_none() && !(p.x.abs() <= MAX_COORDINATE && p.y.abs() <= MAX_COORDINATE) {
                out_of_range = Some((points.len(), p));
            }
            points.push(Point { x: p.x, y: p.y, z: 0.0 });
            if let Some(polar) = polar.as_mut() {
                polar.push(p);
            }
        });
        if let Some((i, p)) = out_of_range {
            let e = format!(
                "sample {i}: the corrected point ({}, {}) m is out of range (check encoder.meters_per_count and the calibration)",
                p.x, p.y
            );
            return Err(self.reject(msg, e));
        }
        let radii = polar
            .and_then(|polar| polar.resample(self.params.resample_points, default_max_gap(steps_per_rev)))
            .unwrap_or_default();
        let header = Header { stamp: msg.header.stamp, frame_id: self.params.output_frame_id.clone() };
        let polygon = with_polygon.then(|| PolygonStamped {
            header: header.clone(),
            polygon: Polygon {
                points: points.iter().map(|p| Point32 { x: p.x as f32, y: p.y as f32, z: 0.0 }).collect(),
            },
        });
        let contour = Contour {
            header,
            scan_id: msg.scan_id,
            target: msg.target,
            calibrated: calibration.is_some(),
            points,
            radii,
        };
        self.stats.contours_published += 1;
        Ok(Corrected { contour, polygon })
    }

    /// Count a rejected scan; returns the error.
    fn reject(&mut self, msg: &RawScan, e: String) -> String {
        self.stats.scans_rejected += 1;
        self.stats.last_rejection = format!("scan {}: {e}", msg.scan_id);
        e
    }

    /// Handle a calibrate request: fit the requested plate scan; unless it is a dry
    /// run, apply the result and persist the parameters. A failed fit leaves the
    /// calibration in force untouched.
    pub fn on_calibrate(&mut self, req: &CalibrateRequest) -> CalibrateOutcome {
        let fail = |this: &mut Self, message: String| {
            this.stats.calibrations_failed += 1;
            this.stats.last_fit_message = message.clone();
            CalibrateOutcome {
                response: CalibrateResponse { success: false, message, ..Default::default() },
                applied: None,
            }
        };
        let plate =
            if req.scan_id == 0 { self.plates.back() } else { self.plates.iter().find(|p| p.scan_id == req.scan_id) };
        let Some(plate) = plate else {
            let have: Vec<String> = self.plates.iter().map(|p| p.scan_id.to_string()).collect();
            let message = if have.is_empty() {
                "no calibration-plate scan received yet (publish a RawScan with target TARGET_CALIBRATION_PLATE)"
                    .to_string()
            } else {
                format!("no calibration-plate scan with scan_id {} (kept: {})", req.scan_id, have.join(", "))
            };
            return fail(self, message);
        };
        let scan_id = plate.scan_id;
        let cal = match calibrate(&plate.scan, &self.params.plate, &self.params.calibration_options()) {
            Ok(cal) => cal,
            Err(e) => return fail(self, format!("calibration failed on scan {scan_id}: {e}")),
        };
        self.stats.last_fit_rms = Some(cal.rms_residual);
        let mut response = response_for(&cal, format!("scan {scan_id}: {}", cal.summary()));
        if req.dry_run {
            response.message = format!("dry run, not applied: {}", response.message);
            self.stats.last_fit_message = response.message.clone();
            return CalibrateOutcome { response, applied: None };
        }
        self.params.calibration = cal.mounting;
        self.params.calibration_valid = true;
        self.calibrated_at = Some(Instant::now());
        self.stats.calibrations_applied += 1;
        if let Err(e) = self.persist() {
            response.success = false;
            response.message = format!("calibration applied in memory but not persisted: {e}; {}", response.message);
        }
        self.stats.last_fit_message = response.message.clone();
        CalibrateOutcome { response, applied: Some(cal.mounting) }
    }

    /// Write every parameter to `params_file` (if set), atomically.
    pub fn persist(&self) -> Result<(), String> {
        if self.params.params_file.is_empty() {
            return Ok(());
        }
        let path = Path::new(&self.params.params_file);
        let text = params_file::render(
            &self.fqn,
            &self.params.to_list(),
            "Parameters of tracer_calib_node, written by the node after each change.\nLoad with: --ros-args --params-file THIS_FILE",
        );
        params_file::write_atomic(path, &text).map_err(|e| format!("cannot write {}: {e}", path.display()))
    }

    /// The node's diagnostics at time `now`.
    pub fn diagnostics(&self, now: Time) -> DiagnosticArray {
        let p = &self.params;
        let last_failed = self.stats.calibrations_failed > 0 && self.stats.last_fit_message.contains("failed");
        let (level, message) = if !p.calibration_valid && last_failed {
            (
                DiagnosticStatus::WARN,
                format!(
                    "not calibrated: contours are uncorrected; the last calibrate failed: {}",
                    self.stats.last_fit_message
                ),
            )
        } else if !p.calibration_valid {
            (DiagnosticStatus::WARN, "not calibrated: contours are uncorrected".to_string())
        } else if last_failed {
            (DiagnosticStatus::WARN, format!("calibrated; the last calibrate failed: {}", self.stats.last_fit_message))
        } else {
            (DiagnosticStatus::OK, "calibrated".to_string())
        };
        let kv = |k: &str, v: String| KeyValue { key: k.to_string(), value: v };
        let age = self.calibrated_at.map(|t| t.elapsed()).unwrap_or(Duration::ZERO);
        let s = &self.stats;
        DiagnosticArray {
            header: Header { stamp: now, frame_id: String::new() },
            status: vec![DiagnosticStatus {
                level,
                name: format!("tracer_calib: {}", self.fqn),
                message,
                hardware_id: p.output_frame_id.clone(),
                values: vec![
                    kv("calibrated", p.calibration_valid.to_string()),
                    kv(
                        "calibration_age_s",
                        if p.calibration_valid { format!("{:.1}", age.as_secs_f64()) } else { "".into() },
                    ),
                    kv("alpha0_deg", format!("{:.5}", p.calibration.alpha0.to_degrees())),
                    kv("offset_mm", format!("{:.5}", p.calibration.offset * 1e3)),
                    kv("delta_l_mm", format!("{:.5}", p.calibration.delta_l * 1e3)),
                    kv("scale", format!("{:.7}", p.calibration.scale)),
                    kv("model", p.model.to_string()),
                    kv(
                        "last_fit_rms_residual_mm",
                        s.last_fit_rms.map(|r| format!("{:.5}", r * 1e3)).unwrap_or_default(),
                    ),
                    kv("last_fit", s.last_fit_message.clone()),
                    kv("scans_received", s.scans_received.to_string()),
                    kv("scans_rejected", s.scans_rejected.to_string()),
                    kv("contours_published", s.contours_published.to_string()),
                    kv("calibrations_applied", s.calibrations_applied.to_string()),
                    kv("calibrations_failed", s.calibrations_failed.to_string()),
                    kv("last_rejection", s.last_rejection.clone()),
                    kv("plate_scans_kept", self.plates.len().to_string()),
                ],
            }],
        }
    }
}

/// The Calibrate response of a successful fit (the node's, and the offline tool's JSON):
/// `scale` and `scale_stddev` are the fitted ones, or 1 and 0 for a model that does not
/// fit the scale.
pub fn response_for(cal: &Calibration, message: String) -> CalibrateResponse {
    let (scale, scale_stddev) =
        if cal.model.fits_scale() { (cal.mounting.scale, cal.scale_stddev) } else { (1.0, 0.0) };
    CalibrateResponse {
        success: true,
        message,
        alpha0: cal.mounting.alpha0,
        offset: cal.mounting.offset,
        delta_l: cal.mounting.delta_l,
        stddev: cal.stddev.to_vec(),
        rms_residual: cal.rms_residual,
        iterations: cal.iterations as u32,
        samples_used: cal.samples_used as u32,
        scale,
        scale_stddev,
    }
}

/// Lets a warning through at most once per `period`, counting the ones held back.
#[derive(Debug)]
pub struct RateLimit {
    period: Duration,
    last: Option<Instant>,
    suppressed: u64,
}

impl RateLimit {
    pub fn new(period: Duration) -> Self {
        RateLimit { period, last: None, suppressed: 0 }
    }

    /// `Some(n)` if a message may go out now (`n` held back since the last one).
    pub fn allow(&mut self, now: Instant) -> Option<u64> {
        match self.last {
            Some(t) if now.duration_since(t) < self.period => {
                self.suppressed += 1;
                None
            }
            _ => {
                self.last = Some(now);
                Some(std::mem::take(&mut self.suppressed))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::model::PlateSpec;
    use crate::engine::simulate::{SimOptions, simulate};
    use nalgebra::Vector2;
    use rand::SeedableRng;

    fn plate_msg(scan_id: u32, m: &Mounting) -> RawScan {
        let mut rng = rand::rngs::StdRng::seed_from_u64(u64::from(scan_id));
        let sim = simulate(
            &PlateSpec::default().at(Vector2::new(0.0005, -0.0003)),
            m,
            &SimOptions { noise: 2e-6, ..SimOptions::default() },
            &mut rng,
        )
        .unwrap();
        RawScan {
            header: Header::default(),
            scan_id,
            target: RawScan::TARGET_CALIBRATION_PLATE,
            steps_per_revolution: 400,
            step: sim.scan.samples().iter().map(|s| s.step).collect(),
            counts: sim.scan.samples().iter().map(|s| (s.rho / 1e-6).round() as i32).collect(),
        }
    }

    #[test]
    fn scans_are_corrected_once_calibrated() {
        let m = Mounting::new(0.02, 0.004, 0.001);
        let mut st = NodeState::new("/tracer_calibrator".into(), Parameters::default());
        let before = st.on_raw_scan(&plate_msg(1, &m), true).unwrap();
        assert!(!before.contour.calibrated);
        assert_eq!(before.contour.points.len(), 400);
        assert_eq!(before.contour.radii.len(), 400);
        assert_eq!(before.polygon.as_ref().unwrap().polygon.points.len(), 400);
        let out = st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: false });
        assert!(out.response.success, "{}", out.response.message);
        assert!((out.response.offset - 0.004).abs() < 1e-5);
        assert_eq!(out.response.stddev.len(), 3);
        let after = st.on_raw_scan(&plate_msg(2, &m), true).unwrap();
        assert!(after.contour.calibrated);
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
            assert!(e.contains(want), "case {i}: {e}");
            assert_eq!(st.stats.scans_rejected, i as u64 + 1);
        }
        assert!(st.on_raw_scan(&good, true).is_ok());
        assert_eq!(st.stats.scans_received, cases.len() as u64 + 1);
    }

    #[test]
    fn a_failed_calibration_keeps_the_old_one() {
        let mut st = NodeState::new("/t".into(), Parameters::default());
        let out = st.on_calibrate(&CalibrateRequest::default());
        assert!(!out.response.success);
        assert!(out.response.message.starts_with("no calibration-plate scan received yet"), "{}", out.response.message);
        let m = Mounting::new(0.01, 0.003, 0.001);
        st.on_raw_scan(&plate_msg(5, &m), true).unwrap();
        assert!(st.on_calibrate(&CalibrateRequest::default()).response.success);
        let in_force = st.params.calibration;
        // A wrong plate size: the fit is refused, the calibration stays.
        st.params.plate.side = 0.05;
        let out = st.on_calibrate(&CalibrateRequest { scan_id: 5, dry_run: false });
        assert!(!out.response.success);
        assert!(out.response.message.contains("does not match the plate"), "{}", out.response.message);
        assert_eq!(st.params.calibration, in_force);
        let out = st.on_calibrate(&CalibrateRequest { scan_id: 77, dry_run: false });
        assert_eq!(out.response.message, "no calibration-plate scan with scan_id 77 (kept: 5)");
        assert_eq!(st.stats.calibrations_failed, 3);
    }

    #[test]
    fn dry_runs_change_nothing_and_persisting_failures_are_reported() {
        let m = Mounting::new(0.01, 0.003, 0.001);
        let mut st = NodeState::new("/t".into(), Parameters::default());
        st.on_raw_scan(&plate_msg(1, &m), true).unwrap();
        let out = st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: true });
        assert!(out.response.success && out.applied.is_none());
        assert!(!st.params.calibration_valid);
        st.params.params_file = "/nonexistent-dir/x/params.yaml".into();
        let out = st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: false });
        assert!(!out.response.success);
        assert!(
            out.response.message.starts_with("calibration applied in memory but not persisted"),
            "{}",
            out.response.message
        );
        assert!(st.params.calibration_valid);
    }

    /// A lens scan (noise-free ellipse) by a tracer with mounting `m`, and where each
    /// sample really touched.
    fn lens_msg(scan_id: u32, m: &Mounting) -> (RawScan, Vec<Vector2<f64>>) {
        use crate::engine::shape::Ellipse;
        let lens = Ellipse { center: Vector2::new(0.001, -0.002), a: 0.03, b: 0.018, angle: 0.3 };
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let sim = simulate(&lens, m, &SimOptions::default(), &mut rng).unwrap();
        let msg = RawScan {
            header: Header::default(),
            scan_id,
            target: RawScan::TARGET_LENS,
            steps_per_revolution: 400,
            step: sim.scan.samples().iter().map(|s| s.step).collect(),
            counts: sim.scan.samples().iter().map(|s| (s.rho / 1e-6).round() as i32).collect(),
        };
        (msg, sim.truth)
    }

    #[test]
    fn an_encoder_scale_error_is_refused_by_full_and_corrected_with_full_scale() {
        // The encoder reads 0.25 % long.
        let m = Mounting::new(0.02, 0.004, 0.001).with_scale(1.0 / 1.0025);
        let mut st = NodeState::new("/t".into(), Parameters::default());
        st.on_raw_scan(&plate_msg(3, &m), true).unwrap();
        let out = st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: false });
        assert!(!out.response.success);
        assert!(out.response.message.contains("encoder scale looks off"), "{}", out.response.message);
        assert!(!st.params.calibration_valid, "the failed fit applied nothing");
        let diag = st.diagnostics(Time::ZERO);
        assert_eq!(diag.status[0].level, DiagnosticStatus::WARN);
        assert!(diag.status[0].message.contains("encoder scale looks off"), "{}", diag.status[0].message);

        st.params.set("model", &crate::params::ParamValue::String("full_scale".into())).unwrap();
        let out = st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: false });
        assert!(out.response.success, "{}", out.response.message);
        let r = &out.response;
        assert!((r.scale - m.scale).abs() < 5.0 * r.scale_stddev && r.scale_stddev > 0.0, "{r:?}");
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

    #[test]
    fn rate_limit() {
        let mut r = RateLimit::new(Duration::from_secs(1));
        let t = Instant::now();
        assert_eq!(r.allow(t), Some(0));
        assert_eq!(r.allow(t + Duration::from_millis(10)), None);
        assert_eq!(r.allow(t + Duration::from_millis(20)), None);
        assert_eq!(r.allow(t + Duration::from_secs(2)), Some(2));
    }
}
