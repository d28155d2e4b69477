//! `tracer_calib_node` on Zenoh meets a peer that announces itself as rmw_zenoh_cpp of ROS 2
//! Lyrical does (0.10.x, ros2/rmw_zenoh `liveliness_utils.cpp`): an endpoint's liveliness
//! token may end in one more, optional chunk after the QoS, `backends:<name>:<metadata>;...`
//! (for Buffer message types; names and metadata escaped `%25`, `%3B`, `%3A`, `%2F`). Jazzy's
//! 0.2.x and Kilted's 0.6.x tokens end at the QoS. Lyrical's zenoh-c is the same commit as
//! Jazzy's 0.2.10 (1.8.0 + fixes), so the transport is the one the node speaks already; what
//! a Lyrical peer adds is that chunk, and a node that refused it would not see the peer.
//!
//! The test's own Zenoh session (a listener on loopback; the node connects to it, no router)
//! declares a Lyrical edger's tokens, its node and a subscription on `/contour_polygon` with
//! a `backends:` chunk, and listens on the polygon topic's key itself. The node publishes a
//! scan's polygon only while it sees a subscriber on the graph: before the tokens, a scan's
//! contour comes back and no polygon; after them, the polygons flow (the node saw the
//! Lyrical subscription); after the tokens are undeclared, they stop again. The test's own
//! graph (the same vendored parser) sees the Lyrical node by name. Run inside a private
//! network namespace, as `scripts/test.sh` runs `cargo test`.
#![cfg(feature = "zenoh")]

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use futures::{FutureExt, StreamExt, future};
use ros2_client::{Name, NodeName, NodeOptions};
use tracer_calib::interfaces::{Contour, PolygonStamped, RawScan, RosMsg};
use zenoh::Wait;

mod common;
use common::on_zenoh::{lens_scan, listening_context, node_connecting_to};
use common::{reliable, within};

const PORT: u16 = 7462;
const DOMAIN: u16 = 0;

/// Lyrical's liveliness tokens for a node `/lyrical_edger` (session `zid`) and its
/// subscription on `/contour_polygon`: `@ros2_lv/<domain>/<zid>/<nid>/<id>/<kind>/<enclave>/
/// <namespace>/<node>[/<topic>/<type>/<hash>/<qos>[/<backends>]]`, names mangled (`/` as
/// `%`), the QoS reliable, volatile, keep last 10 (rmw_zenoh's defaults left empty).
fn lyrical_tokens(zid: &str, polygon_hash: &str) -> [String; 2] {
    let node = format!("@ros2_lv/{DOMAIN}/{zid}/7/7/NN/%/%/lyrical_edger");
    let subscription = format!(
        "@ros2_lv/{DOMAIN}/{zid}/7/8/MS/%/%/lyrical_edger/%contour_polygon/{}/{polygon_hash}/\
         ::,10:,:,:,,/backends:cuda:device%3A0%3Bpinned;cpu:",
        PolygonStamped::NAME.dds_type_name()
    );
    [node, subscription]
}

#[test]
fn a_lyrical_peers_tokens_with_their_optional_chunk_are_seen() {
    let ctx = listening_context(PORT, DOMAIN);
    let _node = node_connecting_to(PORT);
    let peer = ctx
        .new_node(NodeName::new("/", "lyrical_tokens_test").unwrap(), NodeOptions::new().enable_rosout(false))
        .unwrap();
    let topic = |name: &str, ty| peer.create_topic(&Name::new("/", name).unwrap(), ty, &reliable(10));
    let scans = peer.create_publisher::<RawScan>(&topic("raw_scan", RawScan::NAME.message_type_name()), None).unwrap();
    let contours =
        peer.create_subscription::<Contour>(&topic("contour", Contour::NAME.message_type_name()), None).unwrap();

    // The polygons the node puts on their topic's key, counted by a plain Zenoh subscriber
    // (no token of its own: the node cannot see it on the graph).
    let polygons = Arc::new(AtomicUsize::new(0));
    let counted = polygons.clone();
    let _listener = ctx
        .session()
        .declare_subscriber(format!("{DOMAIN}/contour_polygon/**"))
        .callback(move |_| {
            counted.fetch_add(1, Ordering::SeqCst);
        })
        .wait()
        .unwrap();
    let zid = ctx.session().zid().to_string();
    let hash = tracer_calib::interfaces::type_hash::type_hash("geometry_msgs/msg/PolygonStamped").unwrap();

    smol::block_on(async {
        within(30, "the node's raw_scan subscription", peer.wait_for_subscription("/raw_scan")).await;
        let mut contours = std::pin::pin!(contours.async_stream());
        let mut next_id = 1;
        // A scan in, its contour back (published until one comes: the node may need a
        // moment for its subscriber to reach this session); the polygons counted meanwhile.
        let mut round = async |what: &str| {
            let before = polygons.load(Ordering::SeqCst);
            let id = next_id;
            next_id += 1;
            within(20, what, async {
                loop {
                    scans.publish(lens_scan(id)).unwrap();
                    let wait = FutureExt::map(smol::Timer::after(Duration::from_millis(300)), |_| None);
                    let got =
                        future::select(Box::pin(contours.next().map(Some)), Box::pin(wait)).await.factor_first().0;
                    if let Some(Some(Ok((c, _)))) = got
                        && c.scan_id == id
                    {
                        return;
                    }
                }
            })
            .await;
            smol::Timer::after(Duration::from_millis(500)).await;
            polygons.load(Ordering::SeqCst) - before
        };

        // No subscriber on the graph: a contour, no polygon.
        assert_eq!(round("a contour before the Lyrical peer").await, 0, "a polygon with no subscriber");

        // The Lyrical edger's tokens, the subscription's with its `backends:` chunk.
        let [node_key, subscription_key] = lyrical_tokens(&zid, &hash);
        let liveliness = ctx.session().liveliness();
        let node_token = liveliness.declare_token(node_key.as_str()).wait().expect("a node token Zenoh accepts");
        let subscription_token =
            liveliness.declare_token(subscription_key.as_str()).wait().expect("a Lyrical token Zenoh accepts");
        within(10, "the Lyrical subscription on this session's graph", peer.wait_for_subscription("/contour_polygon"))
            .await;
        let names = ctx.node_names();
        assert!(names.iter().any(|n| n == "/lyrical_edger"), "the Lyrical node is not on the graph: {names:?}");

        // The node sees it too: a scan now has its polygon (tried a few times: the token
        // reaches the node's session a moment after this one's).
        let mut seen = 0;
        for attempt in 0..10 {
            seen = round(&format!("a contour with the Lyrical peer, attempt {attempt}")).await;
            if seen > 0 {
                break;
            }
        }
        assert!(seen > 0, "the node never published a polygon for the Lyrical subscription: it did not see its token");

        // The tokens gone: the polygons stop.
        subscription_token.undeclare().wait().unwrap();
        node_token.undeclare().wait().unwrap();
        let mut after = usize::MAX;
        for attempt in 0..10 {
            after = round(&format!("a contour after the Lyrical peer left, attempt {attempt}")).await;
            if after == 0 {
                break;
            }
        }
        assert_eq!(after, 0, "polygons still published after the Lyrical subscription left");
    });
}
