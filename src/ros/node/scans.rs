//! Raw scans in, contours (and polygons, when someone listens) out.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use futures::StreamExt;
use log::warn;

use super::{RateLimit, Shared, Wire};

/// Each raw scan through the cell ([`crate::cell::NodeState::on_raw_scan`]): the contour
/// published, or the rejection counted and warned about (rate-limited). A message that does
/// not even decode is counted like a malformed scan. A managed node that is not active takes
/// each scan and only counts it ([`crate::cell::NodeState::hold_raw_scan`]). Ends when the
/// subscription's stream does.
pub(super) async fn run(e: &impl Wire, shared: &Shared) {
    let mut stream = std::pin::pin!(e.raw_scans());
    let mut limit = RateLimit::new(Duration::from_secs(1));
    while let Some(item) = stream.next().await {
        let msg = match item {
            Ok(msg) => msg,
            Err(err) => {
                {
                    let mut st = shared.state.lock().expect("state lock");
                    st.driver.scan_arrived(Instant::now());
                    st.reject_undecodable(&err);
                }
                if let Some(held) = limit.allow(Instant::now()) {
                    warn!("rejected an undecodable raw scan: {err} ({held} more rejections not shown)");
                }
                continue;
            }
        };
        // The polygon (for RViz) only when someone listens to it.
        let with_polygon = shared.polygon_wanted.load(Ordering::Relaxed);
        let outcome = {
            let mut st = shared.state.lock().expect("state lock");
            // Anything that comes is the tracer driver alive (/diagnostics).
            st.driver.scan_arrived(Instant::now());
            if !st.is_active() {
                // A managed node not active: taken and counted, nothing published.
                st.hold_raw_scan();
                continue;
            }
            st.on_raw_scan(&msg, with_polygon)
        };
        match outcome {
            Ok(out) => {
                if let Err(err) = e.publish_contour(out.contour).await {
                    warn!("cannot publish a contour: {err}");
                }
                if let Some(polygon) = out.polygon
                    && let Err(err) = e.publish_polygon(polygon).await
                {
                    warn!("cannot publish a polygon: {err}");
                }
            }
            Err(err) => {
                if let Some(held) = limit.allow(Instant::now()) {
                    let total = shared.state.lock().expect("state lock").stats.scans_rejected;
                    warn!("rejected raw scan {}: {err} ({total} rejected so far, {held} not shown)", msg.scan_id);
                }
            }
        }
    }
}
