//! `tracer_calib_node` (the binary, on Zenoh: `RMW_IMPLEMENTATION=rmw_zenoh_cpp`) given raw
//! scan samples that are malformed as rmw_zenoh samples: a payload that is no `RawScan`, and
//! a good payload with an attachment that is no (sequence, timestamp, GID). Each is dropped
//! and counted on `/diagnostics` (`scans_rejected`), and the node goes on serving: the next
//! good scan's contour comes back. The same for `calibrate` queries (a payload that is no
//! request, a request without attachment): not answered, counted (`requests_unreadable`).
//!
//! The test's own Zenoh session listens on loopback and the node connects to it directly
//! (`ZENOH_ROUTER_CHECK_ATTEMPTS=-1`: no router). Run inside a private network namespace,
//! as `scripts/test.sh` runs `cargo test`.
#![cfg(feature = "zenoh")]

use std::time::{Duration, Instant};

use futures::{FutureExt, StreamExt, future};
use ros2_client::{Name, NodeName, NodeOptions};
use tracer_calib::interfaces::cdr::to_cdr;
use tracer_calib::interfaces::{Contour, DiagnosticArray, RawScan, RosMsg};
use zenoh::Wait;

mod common;
use common::on_zenoh::{lens_scan, listening_context, node_connecting_to};
use common::{reliable, value, within};

const PORT: u16 = 7461;
const DOMAIN: u16 = 0;

/// An rmw_zenoh attachment: sequence number and timestamp (i64 LE), then the GID with its
/// length as a one-byte varint.
fn attachment(seq: i64) -> Vec<u8> {
    let mut a = Vec::with_capacity(33);
    a.extend_from_slice(&seq.to_le_bytes());
    a.extend_from_slice(&0i64.to_le_bytes());
    a.push(16);
    a.extend_from_slice(&[7u8; 16]);
    a
}

#[test]
fn malformed_samples_are_counted_and_dropped_and_the_node_keeps_serving() {
    let ctx = listening_context(PORT, DOMAIN);
    let _node = node_connecting_to(PORT);
    let peer = ctx
        .new_node(NodeName::new("/", "malformed_samples_test").unwrap(), NodeOptions::new().enable_rosout(false))
        .unwrap();
    let topic = |name: &str, ty| peer.create_topic(&Name::new("/", name).unwrap(), ty, &reliable(10));
    let scans = peer.create_publisher::<RawScan>(&topic("raw_scan", RawScan::NAME.message_type_name()), None).unwrap();
    let contours =
        peer.create_subscription::<Contour>(&topic("contour", Contour::NAME.message_type_name()), None).unwrap();
    let diagnostics = peer
        .create_subscription::<DiagnosticArray>(&topic("diagnostics", DiagnosticArray::NAME.message_type_name()), None)
        .unwrap();
    let hash = tracer_calib::interfaces::type_hash::type_hash("tracer_calib_msgs/msg/RawScan").unwrap();
    let key = format!("{DOMAIN}/raw_scan/{}/{hash}", RawScan::NAME.dds_type_name());
    let raw = ctx.session().declare_publisher(key).wait().unwrap();

    smol::block_on(async {
        within(30, "the node's raw_scan subscription", peer.wait_for_subscription("/raw_scan")).await;
        within(10, "the node's contour publisher", peer.wait_for_publisher("/contour")).await;
        let mut contours = std::pin::pin!(contours.async_stream());
        // A good scan first (until one comes back: the node may need a moment for its
        // subscriber to reach this session).
        let first = within(20, "a first contour", async {
            loop {
                scans.publish(lens_scan(1)).unwrap();
                let next = FutureExt::map(smol::Timer::after(Duration::from_millis(300)), |_| None);
                let got = future::select(Box::pin(contours.next().map(Some)), Box::pin(next)).await.factor_first().0;
                if let Some(Some(Ok((c, _)))) = got {
                    return c;
                }
            }
        })
        .await;
        assert_eq!(first.scan_id, 1);

        // A payload that is no RawScan, with a good attachment; a good payload with a
        // 5-byte attachment.
        raw.put(vec![0u8, 1, 0, 0, 9, 9, 9]).attachment(attachment(1)).wait().unwrap();
        let good = to_cdr(&lens_scan(2)).unwrap();
        raw.put(good).attachment(vec![1u8, 2, 3, 4, 5]).wait().unwrap();

        // Two calibrate queries the node cannot read: a payload of no request, and a good
        // request without its attachment. Neither is answered.
        let hash = tracer_calib::interfaces::type_hash::type_hash("tracer_calib_msgs/srv/Calibrate").unwrap();
        let service_key = format!("{DOMAIN}/calibrate/tracer_calib_msgs::srv::dds_::Calibrate_/{hash}");
        let timeout = Duration::from_millis(500);
        let bad = ctx.session().get(&service_key).payload(vec![0u8, 1, 0, 0]).attachment(attachment(1));
        let replies = bad.timeout(timeout).wait().unwrap();
        let request = to_cdr(&tracer_calib::interfaces::CalibrateRequest::default()).unwrap();
        let no_attachment = ctx.session().get(&service_key).payload(request).timeout(timeout).wait().unwrap();

        let mut stream = std::pin::pin!(diagnostics.async_stream());
        let deadline = Instant::now() + Duration::from_secs(15);
        let counted = within(20, "scans_rejected 2 and requests_unreadable 2 on /diagnostics", async {
            while let Some(Ok((d, _))) = stream.next().await {
                let both = value(&d, "scans_rejected").as_deref() == Some("2")
                    && value(&d, "requests_unreadable").as_deref() == Some("2");
                if both || Instant::now() > deadline {
                    return (
                        value(&d, "scans_rejected"),
                        value(&d, "requests_unreadable"),
                        value(&d, "last_rejection"),
                    );
                }
            }
            (None, None, None)
        })
        .await;
        assert_eq!(counted.0.as_deref(), Some("2"), "last rejection: {:?}", counted.2);
        assert_eq!(counted.1.as_deref(), Some("2"));
        for (what, r) in [("a bad payload", replies), ("no attachment", no_attachment)] {
            let answered = r.recv_async().await.ok().and_then(|reply| reply.into_result().ok());
            assert!(answered.is_none(), "a calibrate query with {what} was answered");
        }

        // And the node serves the next good scan.
        scans.publish(lens_scan(3)).unwrap();
        let next = within(10, "a contour after the bad samples", async {
            loop {
                if let Some(Ok((c, _))) = contours.next().await
                    && c.scan_id == 3
                {
                    return c;
                }
            }
        })
        .await;
        assert_eq!(next.points.len(), 400);
    });
}
