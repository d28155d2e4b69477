//! The cell's logic: what the node does with each message, without any middleware. The
//! node's state ([`NodeState`]) and its handlers: a raw scan ([`NodeState::on_raw_scan`]),
//! a calibrate request ([`NodeState::on_calibrate`]), a diagnostics tick
//! ([`NodeState::diagnostics`]), and the calibration in force ([`NodeState::calibration_msg`]).
//!
//! It speaks the interface layer's message types ([`crate::interfaces`]) and calls the engine,
//! the parameters and the records; it knows nothing of DDS or of any other middleware. The
//! node shell ([`crate::ros`]) moves messages between the wire and these functions, and the
//! offline tools ([`crate::cli`]) call the same functions on files, so everything here is
//! tested without a network.
//!
//! - [`intake`]: the checks of a raw scan and the one `RawScan` -> engine `Scan` conversion;
//! - [`scans`]: a raw scan corrected into a `Contour` (and a `PolygonStamped`);
//! - [`calibrate`]: a calibrate request fitted, applied, recorded and persisted;
//! - [`diagnostics`]: the `/diagnostics` report;
//! - [`stats`]: the counts it reports (every rejection counted in one place);
//! - [`in_force`]: what is known of the calibration in force;
//! - [`lifecycle`]: the managed node's state machine (rcl_lifecycle's), and [`managed`]: what
//!   each state lets through, and the node's callbacks; [`bond`]: the heartbeat nav2's
//!   lifecycle manager keeps with a managed node.

use std::collections::VecDeque;
use std::path::Path;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crate::engine::angle::HarmonicOrders;
use crate::engine::calibrate::covariance_names;
use crate::engine::correct::Corrector;
use crate::interfaces::{Header, Time, tracer_calib_msgs as msgs};
use crate::params::{Parameters, names, persist as params_persist};
use crate::records::{self, Drift, History, Record};

pub mod bond;
pub mod calibrate;
pub mod diagnostics;
pub mod driver;
pub mod in_force;
pub mod intake;
pub mod lifecycle;
pub mod managed;
pub mod scans;
pub mod stats;

#[cfg(test)]
mod tests;

pub use calibrate::{CalibrateOutcome, error_code, response_for};
pub use in_force::InForce;
pub use managed::{HistoryRead, LifecycleError};
pub use scans::{Corrected, PLATE_SCANS_KEPT};
pub use stats::Stats;

/// The time of an event, on both of the node's clocks: the system's (when a calibration
/// really happened, how old it is) and the node's ROS clock (stamps; simulated time under
/// `use_sim_time`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Now {
    pub wall: SystemTime,
    pub ros: Time,
}

impl Now {
    /// `wall`, with the ROS clock on the system time.
    pub fn at(wall: SystemTime) -> Now {
        let since = wall.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO);
        Now { wall, ros: Time::from_nanos(i64::try_from(since.as_nanos()).unwrap_or(i64::MAX)) }
    }

    /// The system time now, on both clocks.
    pub fn system() -> Now {
        Now::at(SystemTime::now())
    }
}

/// Why a change was not persisted: the history file not appended to (a calibration's
/// record), or the params file not written ([`NodeState::persist`]).
#[derive(Debug, thiserror::Error)]
pub enum PersistError {
    /// The record could not be appended to `history_file` (nothing of it was left there).
    #[error("cannot append to {path}: {source}")]
    History {
        /// The history file.
        path: String,
        /// The system's reason.
        #[source]
        source: std::io::Error,
    },
    /// `params_file` could not be written (it is as it was).
    #[error("cannot write {path}: {source}")]
    Params {
        /// The params file.
        path: String,
        /// The system's reason.
        #[source]
        source: std::io::Error,
    },
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
    /// Where the last persist went when the params file could not be edited safely (the
    /// sibling file, and why), for /diagnostics; empty if it was edited.
    pub persist_problem: String,
    /// Parameters persisted beside [`Parameters`]: the QoS overrides in force.
    pub extra_params: Vec<(String, crate::params::ParamValue)>,
    /// What is wrong with the node's clock (simulated time with no `/clock`), for
    /// /diagnostics; empty if nothing.
    pub clock_problem: String,
    /// The tracer driver's health ([`driver`]).
    pub driver: driver::DriverWatch,
    /// A managed node's life cycle (`managed: true`); `None`: unmanaged, always active.
    pub lifecycle: Option<lifecycle::Lifecycle>,
    corrector: Option<Corrector>,
    plates: VecDeque<scans::KeptScan>,
    /// Ring-gauge scans kept for the tip models.
    rings: VecDeque<scans::KeptScan>,
}

impl NodeState {
    /// The state at start-up (now), with the calibration of `params` in force. Under
    /// `use_sim_time` the ROS clock stands at 0 until a `/clock` arrives, as rclcpp's.
    pub fn new(fqn: String, params: Parameters) -> Self {
        let now = Now::system();
        let now = if params.use_sim_time { Now { ros: Time::ZERO, ..now } } else { now };
        let in_force = InForce::by_parameters(&params, now);
        NodeState {
            fqn,
            params,
            stats: Stats::default(),
            in_force,
            drift: None,
            history_records: 0,
            history_problem: String::new(),
            persist_problem: String::new(),
            extra_params: Vec::new(),
            clock_problem: String::new(),
            driver: driver::DriverWatch::new(std::time::Instant::now()),
            lifecycle: None,
            corrector: None,
            plates: VecDeque::new(),
            rings: VecDeque::new(),
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
    pub fn calibration_set_by_parameters(&mut self, now: Now) {
        self.in_force = InForce::by_parameters(&self.params, now);
    }

    /// The `calibration` message: the calibration in force.
    pub fn calibration_msg(&self) -> msgs::Calibration {
        let p = &self.params;
        let angle = p.angle_in_force();
        msgs::Calibration {
            header: Header { stamp: self.in_force.ros_time, frame_id: p.output_frame_id.clone() },
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
            tip_radius: p.tip_radius,
            covariance: if p.calibration_valid { p.covariance.clone() } else { Vec::new() },
            covariance_names: match (p.calibration_valid && !p.covariance.is_empty(), p.covariance_names.is_empty()) {
                (false, _) => Vec::new(),
                (true, true) => covariance_names(HarmonicOrders::NONE),
                (true, false) => p.covariance_names.clone(),
            },
            angle_harmonics: if angle.coefficients().is_empty() {
                Vec::new()
            } else {
                angle.orders().iter().map(|h| h as i32).collect()
            },
            angle_coefficients: if angle.coefficients().is_empty() {
                Vec::new()
            } else {
                angle.coefficients().to_vec()
            },
        }
    }

    /// Append `record` to `history_file` (if set), durably.
    fn append_history(&mut self, record: &Record) -> Result<(), PersistError> {
        if self.params.history_file.is_empty() {
            return Ok(());
        }
        let path = Path::new(&self.params.history_file);
        records::file::append(path, record)
            .map_err(|source| PersistError::History { path: path.display().to_string(), source })?;
        self.history_records += 1;
        Ok(())
    }

    /// The parameters a persist writes: every one but the start-up settings a launch
    /// gives each time (`params_file`, `managed`, `use_sim_time`) and a `history_file`
    /// that is its default (beside `params_file`), and the QoS overrides in force.
    pub fn persisted_params(&self) -> Vec<(String, crate::params::ParamValue)> {
        let derived_history = records::file::default_path(&self.params.params_file);
        let mut list: Vec<_> = self
            .params
            .to_list()
            .into_iter()
            .filter(|(name, value)| match name.as_str() {
                names::PARAMS_FILE | names::MANAGED | names::USE_SIM_TIME => false,
                names::HISTORY_FILE => *value != crate::params::ParamValue::String(derived_history.clone()),
                _ => true,
            })
            .collect();
        list.extend(self.extra_params.iter().cloned());
        list
    }

    /// Write the parameters to `params_file` (if set): what differs from what the file
    /// gives this node, in this node's own section, the rest of the file kept
    /// ([`params_persist`]); to the sibling file when the file cannot be edited safely,
    /// with a warning, and said on /diagnostics (`persist_problem`). The error is
    /// [`PersistError::Params`].
    pub fn persist(&mut self) -> Result<(), PersistError> {
        if self.params.params_file.is_empty() {
            return Ok(());
        }
        let path = Path::new(&self.params.params_file);
        let wanted = self.persisted_params();
        let comment = "Parameters of tracer_calib_node: it edits only its own section after each change.\nLoad with: --ros-args --params-file THIS_FILE";
        match params_persist::persist(path, &self.fqn, &wanted, comment) {
            Ok(params_persist::Persisted::Sibling { path: sibling, why }) => {
                let problem = format!(
                    "{} cannot be edited safely ({why}): it is left as it was, and the parameters are persisted to {} (read after it at start)",
                    path.display(),
                    sibling.display()
                );
                if problem != self.persist_problem {
                    log::warn!("{problem}");
                }
                self.persist_problem = problem;
                Ok(())
            }
            Ok(_) => {
                self.persist_problem.clear();
                Ok(())
            }
            Err(source) => Err(PersistError::Params { path: path.display().to_string(), source }),
        }
    }
}
