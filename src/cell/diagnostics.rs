//! The node's `/diagnostics` report: one status with the calibration in force, its age and
//! drift, the history file, the last fit, and every count.

use std::time::Duration;

use super::{NodeState, Now};
use crate::interfaces::{CalibrateResponse, DiagnosticArray, DiagnosticStatus, Header, KeyValue};
use crate::records;

impl NodeState {
    /// The node's diagnostics at `now`: stamped with its ROS time; the calibration's age
    /// is system time. Two statuses: the calibration's (first), and the tracer driver's
    /// ([`super::driver`]), at the monotonic time of the call.
    pub fn diagnostics(&self, now: Now) -> DiagnosticArray {
        self.diagnostics_at(now, std::time::Instant::now())
    }

    /// [`Self::diagnostics`] with the driver's status at `instant`.
    pub fn diagnostics_at(&self, now: Now, instant: std::time::Instant) -> DiagnosticArray {
        let p = &self.params;
        let last_failed = self.stats.last_fit_error != CalibrateResponse::ERROR_NONE;
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
        let age = now.wall.duration_since(self.in_force.applied_at).unwrap_or(Duration::ZERO);
        let age_days = age.as_secs_f64() / 86_400.0;
        let mut warnings = Vec::new();
        // Said in the message without raising the level.
        let mut notes = Vec::new();
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
        if !self.clock_problem.is_empty() {
            warnings.push(self.clock_problem.clone());
        }
        if !self.persist_problem.is_empty() {
            warnings.push(self.persist_problem.clone());
        }
        if !self.is_active() {
            notes.push(format!(
                "lifecycle state {}: scans are taken, no contour is published, /calibrate is refused",
                self.lifecycle_label()
            ));
        }
        if self.stats.qos_incompatible > 0 {
            warnings.push(format!(
                "{} endpoint(s) with incompatible QoS, last: {}",
                self.stats.qos_incompatible, self.stats.last_qos_incompatible
            ));
        }
        if let Some(n @ 1..) = self.stats.peers_refused_authentication {
            warnings.push(format!("{n} peer(s) refused authentication (DDS Security)"));
        }
        let level = if warnings.is_empty() { level } else { level.max(DiagnosticStatus::WARN) };
        let message = std::iter::once(message).chain(notes).chain(warnings).collect::<Vec<_>>().join("; ");
        let kv = |k: &str, v: String| KeyValue { key: k.to_string(), value: v };
        let s = &self.stats;
        DiagnosticArray {
            header: Header { stamp: now.ros, frame_id: String::new() },
            status: vec![
                DiagnosticStatus {
                    level,
                    name: format!("tracer_calib: {}", self.fqn),
                    message,
                    hardware_id: self.hardware_id().to_string(),
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
                        kv(
                            "calibration_age_days",
                            if p.calibration_valid { format!("{age_days:.3}") } else { "".into() },
                        ),
                        kv("calibration_source", self.in_force.source.to_string()),
                        kv("calibration_scan_id", self.in_force.scan_id.to_string()),
                        kv("max_age_days", p.max_age_days.to_string()),
                        kv("drift_sigma", self.drift.map(|d| format!("{:.2}", d.worst().1)).unwrap_or_default()),
                        kv("drift", self.drift.map(|d| d.describe()).unwrap_or_default()),
                        kv("drift_warn_sigma", p.drift_warn_sigma.to_string()),
                        kv("history_file", p.history_file.clone()),
                        kv("history_records", self.history_records.to_string()),
                        kv("history_problem", self.history_problem.clone()),
                        kv("persist_problem", self.persist_problem.clone()),
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
                        kv("last_fit_error", super::calibrate::error_name(s.last_fit_error).to_string()),
                        kv("scans_received", s.scans_received.to_string()),
                        kv("scans_rejected", s.scans_rejected.to_string()),
                        kv("scans_held", s.scans_held.to_string()),
                        kv("contours_published", s.contours_published.to_string()),
                        kv("calibrations_applied", s.calibrations_applied.to_string()),
                        kv("calibrations_failed", s.calibrations_failed.to_string()),
                        kv("last_rejection", s.last_rejection.clone()),
                        kv("plate_scans_kept", self.plates.len().to_string()),
                        kv("qos_incompatible", s.qos_incompatible.to_string()),
                        kv("requests_unreadable", s.requests_unreadable.to_string()),
                        kv("last_qos_incompatible", s.last_qos_incompatible.clone()),
                        kv("use_sim_time", p.use_sim_time.to_string()),
                        kv("lifecycle_state", self.lifecycle_label().to_string()),
                        kv("ros_time", format!("{:.3}", now.ros.to_nanos() as f64 * 1e-9)),
                    ]
                    .into_iter()
                    .chain(s.peers_refused_authentication.map(|n| kv("peers_refused_authentication", n.to_string())))
                    .collect(),
                },
                self.driver.status(instant, &self.fqn, self.hardware_id(), p.scan_timeout, s.scans_received),
            ],
        }
    }

    /// The `hardware_id` of the node's statuses: the parameter, else `output_frame_id`.
    fn hardware_id(&self) -> &str {
        if self.params.hardware_id.is_empty() { &self.params.output_frame_id } else { &self.params.hardware_id }
    }
}
