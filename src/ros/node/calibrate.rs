//! The `calibrate` service: one fit at a time, the result mirrored into the parameters,
//! logged to rosout, and answered; with its introspection on (`calibrate.introspection`),
//! each request received and response sent also published on `calibrate/_service_event`,
//! as rclcpp's service does after `configure_introspection`: what `ros2 service echo
//! /calibrate` shows, and `ros2 bag record --all-services` records.

use futures::StreamExt;
use log::{debug, info, warn};

use super::{Shared, Wire, parameters};
use crate::interfaces::{CalibrateEvent, CalibrateRequest, CalibrateResponse, ServiceEventInfo, Time};
use crate::params::Introspection;

/// The event of one request or response (rclcpp's `ServiceIntrospection`): its kind, the
/// time, the client's GID and the request's sequence number; with `Contents`, the request
/// or response itself.
fn event(
    kind: u8,
    stamp: Time,
    id: ros2_client::RmwRequestId,
    show: Introspection,
    request: Option<&CalibrateRequest>,
    response: Option<&CalibrateResponse>,
) -> CalibrateEvent {
    let mut client_gid = [0u8; 16];
    let gid = id.writer_gid.as_bytes();
    let n = gid.len().min(16);
    client_gid[..n].copy_from_slice(&gid[..n]);
    let contents = show == Introspection::Contents;
    CalibrateEvent {
        info: ServiceEventInfo { event_type: kind, stamp, client_gid, sequence_number: id.sequence_number },
        request: request.filter(|_| contents).cloned().into_iter().collect(),
        response: response.filter(|_| contents).cloned().into_iter().collect(),
    }
}

/// Publish an introspection event, unless introspection is off; a failure is logged.
async fn introspect(e: &impl Wire, show: Introspection, msg: impl FnOnce() -> CalibrateEvent) {
    if show == Introspection::Off {
        return;
    }
    if let Err(err) = e.publish_calibrate_event(msg()).await {
        warn!("cannot publish a calibrate service event: {err}");
    }
}

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
        let show = shared.state.lock().expect("state lock").params.introspection;
        let rid: ros2_client::RmwRequestId = id.into();
        let received = shared.now().ros;
        introspect(e, show, || event(ServiceEventInfo::REQUEST_RECEIVED, received, rid, show, Some(&req), None)).await;
        let outcome = {
            let mut st = shared.state.lock().expect("state lock");
            match st.calibrate_refused() {
                // A managed node that is not active: refused, naming its state.
                Some(response) => crate::cell::CalibrateOutcome { response, ..Default::default() },
                None => st.on_calibrate_at(&req, shared.now()),
            }
        };
        if outcome.applied.is_some() {
            parameters::mirror_calibration(e, &outcome.parameters);
            let _ = shared.calibration_changed.try_send(());
        }
        let r = &outcome.response;
        // On stderr and /rosout ([`crate::ros::logging`]).
        if r.success {
            info!("calibrate: {}", r.message);
        } else {
            warn!("calibrate: {}", r.message);
        }
        let response = (show == Introspection::Contents).then(|| outcome.response.clone());
        match e.answer_calibrate(id, outcome.response).await {
            Ok(()) => {
                debug!("calibrate response {id:?} sent");
                let sent = shared.now().ros;
                introspect(e, show, || {
                    event(ServiceEventInfo::RESPONSE_SENT, sent, rid, show, None, response.as_ref())
                })
                .await;
            }
            Err(err) => warn!("cannot send a calibrate response: {err}"),
        }
    }
}
