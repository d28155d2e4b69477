//! The managed node (`managed: true`): what each lifecycle state lets through, and the
//! node's callbacks for each transition ([`lifecycle`]).
//!
//! - unconfigured, inactive, finalized: raw scans are taken (and counted, `scans_held`) but
//!   not corrected, no contour or polygon is published; `/calibrate` answers
//!   `success=False` naming the state;
//! - configuring: the calibration in force from the parameters, and what the history file
//!   says of it (read now, not at start-up);
//! - activating: the node corrects and publishes, and calibrates;
//! - deactivating: back to holding;
//! - cleaningup: the plate scans and what configure read are dropped (as when created);
//! - shuttingdown: the plate scans dropped; finalized holds for good.
//!
//! Every callback succeeds: reading the history file can find problems, but they are
//! reported on /diagnostics (`history_problem`) as for an unmanaged node, not a reason to
//! stay unconfigured. An unmanaged node ([`NodeState::lifecycle`] `None`) is always active.

use super::lifecycle::{self, CallbackReturn, NotRegistered, State, Walk};
use super::{InForce, NodeState, Now};
use crate::interfaces::CalibrateResponse;
use crate::records;

/// Why a requested transition was not walked ([`NodeState::change_lifecycle`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LifecycleError {
    /// An unmanaged node has no life cycle.
    #[error("the node is not managed (managed: false)")]
    NotManaged,
    /// The current state does not offer the transition; nothing changed.
    #[error(transparent)]
    NotRegistered(#[from] NotRegistered),
}

/// What reading the history file gave: a line to log (empty: no history file), and the
/// problems to warn about.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HistoryRead {
    pub note: String,
    pub warnings: Vec<String>,
}

impl NodeState {
    /// Whether the node corrects scans and calibrates: unmanaged, or active.
    pub fn is_active(&self) -> bool {
        self.lifecycle.as_ref().is_none_or(|l| l.current() == State::ACTIVE)
    }

    /// The lifecycle state: its label, or `unmanaged`.
    pub fn lifecycle_label(&self) -> &'static str {
        self.lifecycle.as_ref().map_or("unmanaged", |l| l.current().label)
    }

    /// A raw scan taken while the node is not active: counted, nothing else.
    pub fn hold_raw_scan(&mut self) {
        self.stats.scans_received += 1;
        self.stats.scans_held += 1;
    }

    /// The answer to a calibrate request while the node is not active (`None` when it is):
    /// `success=False`, naming the state and the way out. Not a failed calibration: nothing
    /// was fitted, nothing is counted.
    pub fn calibrate_refused(&self) -> Option<CalibrateResponse> {
        if self.is_active() {
            return None;
        }
        let state = self.lifecycle_label();
        let fqn = &self.fqn;
        let how = match state {
            "unconfigured" => format!("ros2 lifecycle set {fqn} configure, then activate"),
            "inactive" => format!("ros2 lifecycle set {fqn} activate"),
            _ => "a finalized node does not come back: restart it".to_string(),
        };
        Some(CalibrateResponse {
            success: false,
            message: format!("the node is {state} (managed): /calibrate is served only when it is active ({how})"),
            error_code: CalibrateResponse::ERROR_NOT_ACTIVE,
            ..Default::default()
        })
    }

    /// Walk a requested transition with the node's callbacks (see the module's text). An
    /// unmanaged node has no life cycle: an error. `history` gets what configure read.
    pub fn change_lifecycle(
        &mut self,
        request: &lifecycle::Request,
        now: Now,
        history: &mut Option<HistoryRead>,
    ) -> Result<Walk, LifecycleError> {
        let mut lc = self.lifecycle.take().ok_or(LifecycleError::NotManaged)?;
        let walked = lc.change(request, |state| self.on_transition(state, now, history));
        self.lifecycle = Some(lc);
        Ok(walked?)
    }

    /// The callback of transition state `state`.
    fn on_transition(&mut self, state: State, now: Now, history: &mut Option<HistoryRead>) -> CallbackReturn {
        match state {
            State::CONFIGURING => {
                self.forget_configuration(now);
                *history = Some(self.read_history());
            }
            State::CLEANINGUP => {
                self.forget_configuration(now);
                self.plates.clear();
                self.rings.clear();
            }
            State::SHUTTINGDOWN => {
                self.plates.clear();
                self.rings.clear();
            }
            _ => {}
        }
        CallbackReturn::Success
    }

    /// Back to what the parameters alone say of the calibration in force.
    fn forget_configuration(&mut self, now: Now) {
        self.in_force = InForce::by_parameters(&self.params, now);
        self.drift = None;
        self.history_records = 0;
        self.history_problem.clear();
        self.corrector = None;
    }

    /// Read the history file (`history_file`, if set) and take what it says of the
    /// calibration in force ([`NodeState::adopt_history`]). A file that cannot be read is
    /// a problem reported on /diagnostics, not an error.
    pub fn read_history(&mut self) -> HistoryRead {
        let file = self.params.history_file.clone();
        if file.is_empty() {
            return HistoryRead::default();
        }
        match records::file::read(std::path::Path::new(&file)) {
            Ok(history) => {
                self.adopt_history(&history);
                HistoryRead {
                    note: format!(
                        "{file}: {} calibration record(s); the calibration in force comes from the {}",
                        history.records.len(),
                        self.in_force.source
                    ),
                    warnings: history.skipped.clone(),
                }
            }
            Err(e) => {
                self.history_problem = e.to_string();
                HistoryRead { note: format!("{file}: not read"), warnings: vec![e.to_string()] }
            }
        }
    }
}
