//! The `calibrate` service: one fit at a time, the result mirrored into the parameters,
//! logged to rosout, and answered.

use futures::StreamExt;
use log::{debug, info, warn};

use super::{Shared, Wire, parameters};

/// Each request through the cell ([`crate::cell::NodeState::on_calibrate`]), to the end
/// before the next. Ends when the server's request stream does.
pub(super) async fn run(e: &impl Wire, shared: &Shared) {
    let mut requests = std::pin::pin!(e.calibrate_requests());
    while let Some(item) = requests.next().await {
        let (id, req) = match item {
            Ok(r) => r,
            Err(err) => {
                // A request in no client layout: the server counted it and warned (once a
                // minute per client at most); the count goes on /diagnostics.
                let unreadable = e.calibrate_unreadable();
                let mut st = shared.state.lock().expect("state lock");
                if unreadable > st.stats.requests_unreadable {
                    st.stats.requests_unreadable = unreadable;
                    debug!("unreadable calibrate request: {err}");
                } else {
                    warn!("cannot read a calibrate request: {err}");
                }
                continue;
            }
        };
        debug!("calibrate request {id:?}: scan_id {}, dry_run {}", req.scan_id, req.dry_run);
        let outcome = {
            let mut st = shared.state.lock().expect("state lock");
            match st.calibrate_refused() {
                // A managed node that is not active: refused, naming its state.
                Some(response) => crate::cell::CalibrateOutcome { response, applied: None },
                None => st.on_calibrate_at(&req, shared.now()),
            }
        };
        if let Some(m) = &outcome.applied {
            parameters::mirror_calibration(e, m, &outcome.response.covariance, outcome.response.tip_radius);
            let _ = shared.calibration_changed.try_send(());
        }
        let r = &outcome.response;
        // On stderr and /rosout ([`crate::ros::logging`]).
        if r.success {
            info!("calibrate: {}", r.message);
        } else {
            warn!("calibrate: {}", r.message);
        }
        match e.answer_calibrate(id, outcome.response).await {
            Ok(()) => debug!("calibrate response {id:?} sent"),
            Err(err) => warn!("cannot send a calibrate response: {err}"),
        }
    }
}
