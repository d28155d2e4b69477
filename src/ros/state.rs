//! What the node does with each message, without DDS: the node's state and its three
//! handlers (a raw scan, a calibrate request, a diagnostics tick). The wiring in
//! [`super::node`] only moves messages between DDS and these functions, so everything
//! here is tested without a network.

use std::collections::VecDeque;
use std::path::Path;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use ros2_client::builtin_interfaces::Time;

use super::msgs::{
    CalibrateRequest, CalibrateResponse, Calibration as CalibrationMsg, Contour, DiagnosticArray, DiagnosticStatus,
    Header, KeyValue, Point, Point32, Polygon, PolygonStamped, RawScan,
};
use crate::engine::calibrate::{Calibration, calibrate};
use crate::engine::correct::{Corrector, PolarContour, default_max_gap};
use crate::engine::geometry::Mounting;
use crate::engine::scan::Scan;
use crate::params::{Parameters, file as params_file};
use crate::records::{self, Drift, History, Previous, Record};

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

/// What is known of the calibration in force beyond its parameters: when it was applied
/// and how it was fitted (what the `calibration` topic publishes).
#[derive(Debug, Clone, PartialEq)]
pub struct InForce {
    /// When it was applied: by `/calibrate`, a parameter set, or, for a calibration
    /// loaded from the parameters, the time of its history record (the node's start when
    /// the history has none).
    pub applied_at: SystemTime,
    /// The model that fitted it (for one set by parameters: the `model` parameter).
    pub model: String,
    /// The plate scan it was fitted to; 0 if set by parameters.
    pub scan_id: u32,
    /// `[alpha0, offset, delta_l(, scale)]`; empty if unknown.
    pub stddev: Vec<f64>,
    /// Metres; 0 if unknown.
    pub rms_residual: f64,
    pub samples_used: u32,
    /// Where this comes from: "calibrate", "history" (the history's last record matches
    /// the parameters), "parameters".
    pub source: &'static str,
}

impl InForce {
    fn by_parameters(params: &Parameters, at: SystemTime) -> Self {
        InForce {
            applied_at: at,
            model: params.model.as_str().to_string(),
            scan_id: 0,
            stddev: Vec::new(),
            rms_residual: 0.0,
            samples_used: 0,
            source: "parameters",
        }
    }

    fn from_record(r: &Record, at: SystemTime) -> Self {
        InForce {
            applied_at: at,
            model: r.model.clone(),
            scan_id: r.scan_id,
            stddev: r.stddev.clone(),
            rms_residual: r.rms_residual,
            samples_used: r.samples_used,
            source: "history",
        }
    }
}

/// The node's state.
#[derive(Debug)]
pub struct NodeState {
    /// The node's fully qualified name: its section in the params file.
    pub fqn: String,
    pub params: Parameters,
    pub stats: Stats,
    /// The calibration in force: when and how.
    pub in_force: InForce,
    /// How far the last applied calibration moved from the one before it.
    pub drift: Option<Drift>,
    /// Records in the history file (read at start, then appended).
    pub history_records: usize,
    /// What is wrong with the history file (skipped lines, unreadable), for /diagnostics.
    pub history_problem: String,
    corrector: Option<Corrector>,
    plates: VecDeque<PlateScan>,
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
    /// The state at start-up (`now`), with the calibration of `params` in force.
    pub fn new(fqn: String, params: Parameters) -> Self {
        let in_force = InForce::by_parameters(&params, SystemTime::now());
        NodeState {
            fqn,
            params,
            stats: Stats::default(),
            in_force,
            drift: None,
            history_records: 0,
            history_problem: String::new(),
            corrector: None,
            plates: VecDeque::new(),
        }
    }

    /// Take what the history file says about the calibration in force: when its last
    /// record is the calibration of the parameters, that record's time, fit and drift.
    pub fn adopt_history(&mut self, history: &History) {
        self.history_records = history.records.len();
        self.history_problem = history.skipped.join("; ");
        let Some(last) = history.records.last() else { return };
        let Some(in_force) = self.params.calibration_in_force() else { return };
        if !records::same_calibration(&in_force, &last.mounting()) {
            return;
        }
        let Some(at) = last.applied_at() else { return };
        self.in_force = InForce::from_record(last, at);
        self.drift = records::record_drift(&history.records, history.records.len() - 1);
    }

    /// A parameter set changed the calibration in force (`calibration.*`): it was applied
    /// now, and nothing is known of its fit.
    pub fn calibration_set_by_parameters(&mut self, now: SystemTime) {
        self.in_force = InForce::by_parameters(&self.params, now);
    }

    /// The `calibration` message: the calibration in force.
    pub fn calibration_msg(&self) -> CalibrationMsg {
        let p = &self.params;
        let since = self.in_force.applied_at.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO);
        let stamp = Time::from_nanos(i64::try_from(since.as_nanos()).unwrap_or(i64::MAX));
        CalibrationMsg {
            header: Header { stamp, frame_id: p.output_frame_id.clone() },
            valid: p.calibration_valid,
            model: self.in_force.model.clone(),
            scan_id: self.in_force.scan_id,
            alpha0: p.calibration.alpha0,
            offset: p.calibration.offset,
            delta_l: p.calibration.delta_l,
            scale: p.calibration.scale,
            stddev: self.in_force.stddev.clone(),
            rms_residual: self.in_force.rms_residual,
            samples_used: self.in_force.samples_used,
        }
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
        let mut stddev = cal.stddev.to_vec();
        if cal.model.fits_scale() {
            stddev.push(cal.scale_stddev);
        }
        let previous = self.params.calibration_in_force();
        let drift = previous.and_then(|prev| {
            let prev_sd = (self.in_force.stddev.len() >= 3).then_some(self.in_force.stddev.as_slice());
            records::drift(&cal.mounting, &stddev, &prev, prev_sd)
        });
        if let Some(d) = &drift {
            response.message = format!("{}; moved since the previous calibration: {}", response.message, d.describe());
            if d.exceeds(self.params.drift_warn_sigma) {
                response.message = format!(
                    "{} — more than calibration.drift_warn_sigma = {}: check the tracer",
                    response.message, self.params.drift_warn_sigma
                );
            }
        }
        if req.dry_run {
            response.message = format!("dry run, not applied: {}", response.message);
            self.stats.last_fit_message = response.message.clone();
            return CalibrateOutcome { response, applied: None };
        }
        let now = SystemTime::now();
        let record = Record {
            time: records::format_utc(now),
            node: self.fqn.clone(),
            scan_id,
            model: cal.model.as_str().to_string(),
            alpha0: cal.mounting.alpha0,
            offset: cal.mounting.offset,
            delta_l: cal.mounting.delta_l,
            scale: cal.mounting.scale,
            stddev: stddev.clone(),
            rms_residual: cal.rms_residual,
            samples_used: cal.samples_used as u32,
            iterations: cal.iterations as u32,
            previous: previous.map(Previous::from),
        };
        self.params.calibration = cal.mounting;
        self.params.calibration_valid = true;
        // The time the record gives, to the millisecond: what a restart reads back.
        self.in_force = InForce {
            applied_at: record.applied_at().unwrap_or(now),
            model: record.model.clone(),
            scan_id,
            stddev,
            rms_residual: cal.rms_residual,
            samples_used: record.samples_used,
            source: "calibrate",
        };
        self.drift = drift;
        self.stats.calibrations_applied += 1;
        // The record first: a calibration the history cannot show is not persisted
        // either (a restart goes back to the last recorded one).
        if let Err(e) = self.append_history(&record).and_then(|()| self.persist()) {
            response.success = false;
            response.message = format!("calibration applied in memory but not persisted: {e}; {}", response.message);
        }
        self.stats.last_fit_message = response.message.clone();
        CalibrateOutcome { response, applied: Some(cal.mounting) }
    }

    /// Append `record` to `history_file` (if set), durably.
    fn append_history(&mut self, record: &Record) -> Result<(), String> {
        if self.params.history_file.is_empty() {
            return Ok(());
        }
        let path = Path::new(&self.params.history_file);
        records::file::append(path, record).map_err(|e| format!("cannot append to {}: {e}", path.display()))?;
        self.history_records += 1;
        Ok(())
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
        let now_sys = UNIX_EPOCH + Duration::from_nanos(u64::try_from(now.to_nanos()).unwrap_or(0));
        let age = now_sys.duration_since(self.in_force.applied_at).unwrap_or(Duration::ZERO);
        let age_days = age.as_secs_f64() / 86_400.0;
        let mut warnings = Vec::new();
        if p.calibration_valid && p.max_age_days > 0.0 && age_days > p.max_age_days {
            warnings.push(format!(
                "calibration overdue: applied {} ({age_days:.2} days ago), calibration.max_age_days is {}",
                records::format_utc(self.in_force.applied_at),
                p.max_age_days
            ));
        }
        if let Some(d) = self.drift.filter(|d| d.exceeds(p.drift_warn_sigma)) {
            let (i, sigmas) = d.worst();
            warnings.push(format!(
                "the last calibration moved {} by {sigmas:.1}σ from the one before (calibration.drift_warn_sigma is {}): check the tracer; {}",
                records::DRIFT_NAMES[i],
                p.drift_warn_sigma,
                d.describe()
            ));
        }
        let (level, message) = if warnings.is_empty() {
            (level, message)
        } else {
            (level.max(DiagnosticStatus::WARN), format!("{message}; {}", warnings.join("; ")))
        };
        let kv = |k: &str, v: String| KeyValue { key: k.to_string(), value: v };
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
                    kv(
                        "calibration_time",
                        if p.calibration_valid { records::format_utc(self.in_force.applied_at) } else { "".into() },
                    ),
                    kv("calibration_age_days", if p.calibration_valid { format!("{age_days:.3}") } else { "".into() }),
                    kv("calibration_source", self.in_force.source.to_string()),
                    kv("calibration_scan_id", self.in_force.scan_id.to_string()),
                    kv("max_age_days", p.max_age_days.to_string()),
                    kv("drift_sigma", self.drift.map(|d| format!("{:.2}", d.worst().1)).unwrap_or_default()),
                    kv("drift", self.drift.map(|d| d.describe()).unwrap_or_default()),
                    kv("drift_warn_sigma", p.drift_warn_sigma.to_string()),
                    kv("history_file", p.history_file.clone()),
                    kv("history_records", self.history_records.to_string()),
                    kv("history_problem", self.history_problem.clone()),
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
        let dry = st.on_calibrate(&CalibrateRequest { scan_id: 1, dry_run: true });
        assert!(dry.response.success);
        assert!(!history.exists(), "a dry run is not recorded");
        let first = st.on_calibrate(&CalibrateRequest { scan_id: 1, dry_run: false });
        assert!(first.response.success, "{}", first.response.message);
        assert!(!first.response.message.contains("moved"), "nothing to move from: {}", first.response.message);
        st.on_raw_scan(&plate_msg(2, &m), true).unwrap();
        let second = st.on_calibrate(&CalibrateRequest { scan_id: 2, dry_run: false });
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
        // The calibration message is the second, to the millisecond of its record.
        let msg = st.calibration_msg();
        assert!(msg.valid && msg.scan_id == 2 && msg.alpha0 == b.alpha0 && msg.stddev == b.stddev);
        assert_eq!(msg.header.frame_id, "tracer_axis");
        assert_eq!(Some(UNIX_EPOCH + Duration::from_nanos(msg.header.stamp.to_nanos() as u64)), b.applied_at());

        // A restart with the parameters the node persisted: the history supplies the fit.
        let file = params_file::read(Path::new(&params.params_file)).unwrap();
        let mut reloaded = Parameters::default();
        reloaded.apply_file(&file, "/cell1/tracer", "p.yaml").unwrap();
        assert_eq!(reloaded.history_file, params.history_file);
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
        let out = st.on_calibrate(&CalibrateRequest { scan_id: 1, dry_run: false });
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
        assert!(st.on_calibrate(&CalibrateRequest { scan_id: 1, dry_run: false }).response.success);
        let applied = st.in_force.applied_at;
        let at = |days: f64| {
            let t = applied + Duration::from_secs_f64(days * 86_400.0);
            Time::from_nanos(t.duration_since(UNIX_EPOCH).unwrap().as_nanos() as i64)
        };
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
        let out = st.on_calibrate(&CalibrateRequest { scan_id: 2, dry_run: false });
        assert!(out.response.success, "{}", out.response.message);
        assert!(
            out.response.message.contains("more than calibration.drift_warn_sigma = 10"),
            "{}",
            out.response.message
        );
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
        st.calibration_set_by_parameters(t);
        let msg = st.calibration_msg();
        assert!(msg.valid && msg.alpha0 == 0.01 && msg.scan_id == 0 && msg.stddev.is_empty());
        assert_eq!(
            (msg.header.stamp.to_nanos(), msg.model.as_str(), msg.scale),
            (1_800_000_000_000_000_000, "full", 1.0)
        );
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
