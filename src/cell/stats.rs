//! The counts the node reports on `/diagnostics`, and the one place a rejected scan is
//! counted.

use super::NodeState;
use super::intake::ScanRejected;
use crate::interfaces::RawScan;

/// Counters reported on `/diagnostics`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stats {
    pub scans_received: u64,
    pub scans_rejected: u64,
    /// Scans taken while a managed node was not active: not corrected, nothing published.
    pub scans_held: u64,
    pub contours_published: u64,
    pub calibrations_applied: u64,
    pub calibrations_failed: u64,
    pub last_rejection: String,
    pub last_fit_rms: Option<f64>,
    pub last_fit_message: String,
    /// The last calibrate request's `error_code` (`CalibrateResponse::ERROR_*`;
    /// `ERROR_NONE` when it succeeded, or before any).
    pub last_fit_error: u16,
    /// Remote publishers and subscriptions discovered with a QoS incompatible with the
    /// node's endpoint on their topic (no data flows), and the last one.
    pub qos_incompatible: u64,
    pub last_qos_incompatible: String,
    /// `calibrate` requests in no client layout (not answered; the server logs them).
    pub requests_unreadable: u64,
    /// With a secure participant: remote participants refused authentication (another
    /// CA's or an expired certificate, a bad handshake signature), each once. `None`
    /// (security off): not reported.
    pub peers_refused_authentication: Option<u64>,
}

impl NodeState {
    /// Count a rejected scan; returns the error.
    pub(super) fn reject(&mut self, msg: &RawScan, e: ScanRejected) -> ScanRejected {
        self.stats.scans_rejected += 1;
        self.stats.last_rejection = format!("scan {}: {e}", msg.scan_id);
        e
    }

    /// Count a message on the raw scan topic that does not even decode (the middleware
    /// could not deserialize it): a received and rejected scan like a malformed one.
    pub fn reject_undecodable(&mut self, what: &str) {
        self.stats.scans_received += 1;
        self.stats.scans_rejected += 1;
        self.stats.last_rejection = format!("undecodable message: {what}");
    }
}
