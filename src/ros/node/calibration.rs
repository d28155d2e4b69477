//! The calibration in force, latched on `calibration`.

use log::{debug, warn};

use super::{Shared, Wire};

/// Publishes the calibration in force at start-up, then at every change (several changes
/// queued by one parameter set go out as one message). Ends when every sender of `changes`
/// is gone.
pub(super) async fn run(e: &impl Wire, shared: &Shared, changes: smol::channel::Receiver<()>) {
    loop {
        let msg = shared.state.lock().expect("state lock").calibration_msg();
        debug!("publishing the calibration in force: {msg:?}");
        if let Err(err) = e.publish_calibration(msg).await {
            warn!("cannot publish the calibration in force: {err}");
        }
        if changes.recv().await.is_err() {
            break;
        }
        while changes.try_recv().is_ok() {}
    }
}
