//! What is known of the calibration in force beyond its parameters.

use std::time::SystemTime;

use super::Now;
use crate::interfaces::Time;
use crate::params::Parameters;
use crate::records::Record;

/// What is known of the calibration in force beyond its parameters: when it was applied
/// and how it was fitted (what the `calibration` topic publishes).
#[derive(Debug, Clone, PartialEq)]
pub struct InForce {
    /// When it was applied: by `/calibrate`, a parameter set, or, for a calibration
    /// loaded from the parameters, the time of its history record (the node's start when
    /// the history has none).
    pub applied_at: SystemTime,
    /// The node's ROS time then (simulated under `use_sim_time`): the `calibration`
    /// message's stamp.
    pub ros_time: Time,
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
    pub(super) fn by_parameters(params: &Parameters, at: Now) -> Self {
        InForce {
            applied_at: at.wall,
            ros_time: at.ros,
            model: params.model.as_str().to_string(),
            scan_id: 0,
            stddev: Vec::new(),
            rms_residual: 0.0,
            samples_used: 0,
            source: "parameters",
        }
    }

    /// `at`: the record's time; its ROS time is the record's, or else that time.
    pub(super) fn from_record(r: &Record, at: SystemTime) -> Self {
        InForce {
            applied_at: at,
            ros_time: r.ros_time.map_or_else(|| Now::at(at).ros, |t| Time::from_nanos(t.to_nanos())),
            model: r.model.clone(),
            scan_id: r.scan_id,
            stddev: r.stddev.clone(),
            rms_residual: r.rms_residual,
            samples_used: r.samples_used,
            source: "history",
        }
    }
}
